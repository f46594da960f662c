// collide/narrow2d.cpp: contact manifolds of each kind pair on configurations whose answer
// is known by hand (normal from b towards a, points midway between the surfaces, signed
// separations with the radii included, feature ids stable while the same features touch).
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "check.hpp"
#include "collide/narrow2d.hpp"
#include "rbsim/constants.hpp"

using namespace rbsim;

namespace {

constexpr double SPEC = constants::SPECULATIVE_DISTANCE;  // m
constexpr double EPS = 1e-12;                              // m, round-off of O(1) lengths

// Shapes laid out as the narrowphase reads them: world-frame cores in one verts array, the
// outward unit normal of edge i (vertex i -> i+1, cyclic) in norms[i].
struct Shapes {
  std::vector<Vec2> verts, norms;

  ShapeRef2 circle(Vec2 c, double r) {
    const int start = static_cast<int>(verts.size());
    verts.push_back(c);
    norms.push_back({0.0, 0.0});  // unused
    return {ShapeKind::Circle, start, 1, r};
  }
  // A convex CCW core; 2 vertices make a segment whose edges are p->q and q->p.
  ShapeRef2 core(ShapeKind kind, const std::vector<Vec2>& pts, double r) {
    const int start = static_cast<int>(verts.size());
    const int n = static_cast<int>(pts.size());
    for (int i = 0; i < n; ++i) {
      const Vec2 e = pts[(i + 1) % n] - pts[i];
      verts.push_back(pts[i]);
      norms.push_back((1.0 / length(e)) * Vec2{e.y, -e.x});  // the edge turned clockwise
    }
    return {kind, start, n, r};
  }
  ShapeRef2 segment(Vec2 p, Vec2 q, double r) { return core(ShapeKind::Segment, {p, q}, r); }
  // A box of half extents (hw, hh) m centred at c, turned by angle rad.
  ShapeRef2 box(Vec2 c, double hw, double hh, double angle = 0.0, double r = 0.0) {
    const Rot2 q{std::cos(angle), std::sin(angle)};
    std::vector<Vec2> pts;
    for (Vec2 p : {Vec2{-hw, -hh}, Vec2{hw, -hh}, Vec2{hw, hh}, Vec2{-hw, hh}})
      pts.push_back(c + rotate(q, p));
    return core(ShapeKind::Polygon, pts, r);
  }
};

struct Result {
  int n;
  Manifold2 m;
};

Result collide(const Shapes& s, const ShapeRef2& a, const ShapeRef2& b, double spec = SPEC) {
  Result r{};
  r.n = collide2d(a, b, s.verts.data(), s.norms.data(), spec, r.m);
  return r;
}

void check_vec(const char* file, int line, Vec2 got, Vec2 want, double tol, const char* what) {
  if (!(std::fabs(got.x - want.x) <= tol && std::fabs(got.y - want.y) <= tol))
    ::rbsim::test::fail(file, line,
                        std::string(what) + ": (" + std::to_string(got.x) + ", " +
                            std::to_string(got.y) + ") != (" + std::to_string(want.x) + ", " +
                            std::to_string(want.y) + ")");
}
// CHECK_NEAR for both components of a vector, reported at the caller's line (variadic:
// a braced {x, y} argument holds a comma).
#define CHECK_VEC(...) check_vec(__FILE__, __LINE__, __VA_ARGS__)

}  // namespace

// Two balls stacked exactly touching: zero separation on the line of centres, the point
// where the surfaces meet; overlapping sideways: the overlap, the point halfway inside.
TEST(circles_touching_and_overlapping) {
  Shapes s;
  const auto a = s.circle({0.0, 1.0}, 0.5);
  const auto b = s.circle({0.0, 0.0}, 0.5);
  const auto c = s.circle({0.8, 0.0}, 0.5);
  auto r = collide(s, a, b);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, 0.0, "normal b -> a");
  CHECK_VEC(r.m.point[0], {0.0, 0.5}, EPS, "point");
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  CHECK(r.m.id[0] == 0);
  r = collide(s, c, b);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {1.0, 0.0}, EPS, "normal");
  CHECK_NEAR(r.m.separation[0], -0.2, EPS);
  CHECK_VEC(r.m.point[0], {0.4, 0.0}, EPS, "point midway between the surfaces 0.3 and 0.5");
}

// Balls apart: a gap within the speculative distance is a contact with positive
// separation (so the solver can stop them closing it); a wider gap is no contact.
TEST(circles_apart_within_and_beyond_the_speculative_distance) {
  Shapes s;
  const auto b = s.circle({0.0, 0.0}, 0.5);
  const auto near = s.circle({0.0, 1.0 + 0.5 * SPEC}, 0.5);
  const auto far = s.circle({0.0, 1.0 + 1.5 * SPEC}, 0.5);
  const auto r = collide(s, near, b);
  CHECK(r.n == 1);
  CHECK_NEAR(r.m.separation[0], 0.5 * SPEC, EPS);
  CHECK_VEC(r.m.point[0], {0.0, 0.5 + 0.25 * SPEC}, EPS, "point mid-gap");
  CHECK(collide(s, far, b).n == 0);
}

// Concentric balls have no line of centres: the normal defaults to +y and the overlap is
// the sum of the radii.
TEST(concentric_circles_push_apart_along_y) {
  Shapes s;
  const auto a = s.circle({2.0, 3.0}, 0.3);
  const auto b = s.circle({2.0, 3.0}, 0.5);
  const auto r = collide(s, a, b);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, 0.0, "default normal");
  CHECK_NEAR(r.m.separation[0], -0.8, EPS);
  // midway between a's surface below (3 - 0.3) and b's above (3 + 0.5)
  CHECK_VEC(r.m.point[0], {2.0, 3.1}, EPS, "point");
}

// A ball resting on a box's top face: the face normal, whatever the order of the pair
// (the box first gives the negated normal and the same point).
TEST(circle_on_a_box_face) {
  Shapes s;
  const auto box = s.box({0.0, 0.0}, 1.0, 0.5);
  const auto ball = s.circle({0.3, 0.5 + 0.25 - 0.01}, 0.25);  // 1 cm into the face
  auto r = collide(s, ball, box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, EPS, "face normal");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  CHECK_VEC(r.m.point[0], {0.3, 0.495}, EPS, "between the ball's bottom 0.49 and the face 0.5");
  CHECK(r.m.id[0] == 0);
  const auto q = collide(s, box, ball);
  CHECK(q.n == 1);
  CHECK_VEC(q.m.normal, {0.0, -1.0}, EPS, "box first: normal negated");
  CHECK_VEC(q.m.point[0], r.m.point[0], 0.0, "same point");
  CHECK(q.m.separation[0] == r.m.separation[0]);
}

// A ball off a box's corner (in the corner's vertex region): the normal runs from the
// corner to the centre, not along either face.
TEST(circle_at_a_box_corner) {
  Shapes s;
  const auto box = s.box({0.0, 0.0}, 1.0, 0.5);
  const Vec2 corner{1.0, 0.5};
  const Vec2 dir{std::sqrt(0.5), std::sqrt(0.5)};
  const auto ball = s.circle(corner + 0.3 * dir, 0.29);  // 1 cm gap, diagonally
  const auto r = collide(s, ball, box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, dir, EPS, "corner-to-centre normal");
  CHECK_NEAR(r.m.separation[0], 0.01, EPS);
  CHECK_VEC(r.m.point[0], corner + 0.005 * dir, EPS, "mid-gap");
  // 3 cm away the corner is beyond the speculative distance (a face's SAT would say 2.1 cm)
  Shapes t;
  const auto box2 = t.box({0.0, 0.0}, 1.0, 0.5);
  const auto ball2 = t.circle(corner + 0.32 * dir, 0.29);
  CHECK(collide(t, ball2, box2).n == 0);
}

// A box resting on a wide ground box, 1 mm deep: two points at the box's bottom corners,
// each 1 mm deep, midway between the two faces; the ids of the two points stay the same
// while the box rocks slightly (warm starting carries their impulses over).
TEST(box_resting_on_a_box_two_points_ids_stable_under_tilt) {
  Shapes s;
  const auto ground = s.box({0.0, -0.5}, 5.0, 0.5);  // top face at y = 0
  const auto box = s.box({0.1, 0.5 - 0.001}, 0.5, 0.5);
  const auto r = collide(s, box, ground);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, EPS, "up, from the ground to the box");
  std::vector<double> xs;
  for (int k = 0; k < r.n; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.001, EPS);
    CHECK_NEAR(r.m.point[k].y, -0.0005, EPS);
    xs.push_back(r.m.point[k].x);
  }
  std::sort(xs.begin(), xs.end());
  CHECK_NEAR(xs[0], -0.4, EPS);
  CHECK_NEAR(xs[1], 0.6, EPS);
  CHECK(r.m.id[0] != r.m.id[1]);

  // rocking by ±2 mrad about its centre (corners move 1 mm up and down): the same two
  // features touch, so the same ids in the same order. (Exactly flat is a SAT tie that
  // goes to a, the box's own bottom face; once tilted by more than ~1e-4 rad the ground's
  // far corners make the ground's top face the reference, so the flat ids differ from
  // these: the numba narrowphase does the same.)
  std::array<std::int64_t, 2> ids{};
  for (int k = 0; k < 4; ++k) {
    const double angle = std::array{0.002, -0.002, 0.001, -0.001}[k];
    Shapes t;
    const auto g = t.box({0.0, -0.5}, 5.0, 0.5);
    const auto b = t.box({0.1, 0.5 - 0.001}, 0.5, 0.5, angle);
    const auto q = collide(t, b, g);
    CHECK(q.n == 2);
    CHECK_NEAR(q.m.normal.y, 1.0, 1e-5);  // the ground's face normal (or the box's, tilted)
    if (k == 0) ids = q.m.id;
    CHECK(q.m.id[0] == ids[0] && q.m.id[1] == ids[1]);
    // the corner that rocked down is deeper by half the box's width times the angle
    CHECK_NEAR(std::fabs(q.m.separation[0] - q.m.separation[1]), std::sin(std::fabs(angle)), 1e-6);
  }
}

// Two capsules lying side by side, just touching: two points at the ends of the overlap
// of their cores, on the line where the surfaces meet.
TEST(parallel_capsules_two_points_over_the_overlap) {
  Shapes s;
  const auto a = s.segment({-1.0, 0.2}, {1.0, 0.2}, 0.1);
  const auto b = s.segment({-0.5, 0.0}, {1.5, 0.0}, 0.1);
  const auto r = collide(s, a, b);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, EPS, "from the lower capsule up");
  std::vector<double> xs;
  for (int k = 0; k < r.n; ++k) {
    CHECK_NEAR(r.m.separation[k], 0.0, EPS);
    CHECK_NEAR(r.m.point[k].y, 0.1, EPS);
    xs.push_back(r.m.point[k].x);
  }
  std::sort(xs.begin(), xs.end());
  CHECK_NEAR(xs[0], -0.5, EPS);
  CHECK_NEAR(xs[1], 1.0, EPS);
}

// A capsule standing upright on a lying one: its rounded end touches the side, one point
// under the end cap; capsules crossing like an X are deep and pushed out along one core's
// normal by the depth of the other's half-length across it.
TEST(crossing_capsules) {
  Shapes s;
  const auto lying = s.segment({-1.0, 0.0}, {1.0, 0.0}, 0.1);
  const auto upright = s.segment({0.0, 0.15}, {0.0, 1.0}, 0.1);
  auto r = collide(s, upright, lying);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, EPS, "up");
  CHECK_NEAR(r.m.separation[0], -0.05, EPS);
  CHECK_VEC(r.m.point[0], {0.0, 0.075}, EPS, "between the cap 0.05 and the side 0.1");

  Shapes t;
  const auto x1 = t.segment({-1.0, -1.0}, {1.0, 1.0}, 0.05);
  const auto x2 = t.segment({-1.0, 1.0}, {1.0, -1.0}, 0.05);
  r = collide(t, x1, x2);
  CHECK(r.n >= 1);
  CHECK_NEAR(length(r.m.normal), 1.0, EPS);
  // along a diagonal normal; x2's ends lie √2 across x1's core, plus the two radii
  CHECK_NEAR(std::fabs(r.m.normal.x), std::sqrt(0.5), EPS);
  CHECK_NEAR(std::fabs(r.m.normal.y), std::sqrt(0.5), EPS);
  double deepest = 0.0;
  for (int k = 0; k < r.n; ++k) deepest = std::min(deepest, r.m.separation[k]);
  CHECK_NEAR(deepest, -std::sqrt(2.0) - 0.1, EPS);
}

// Two bare segments (no radius) have no inside, so a skin keeps them SEGMENT_SKIN apart:
// 3 mm apart they already overlap by SEGMENT_SKIN − 3 mm, the point midway between the
// skins (half the skin on each). Capsules whose radii exceed the skin get none.
TEST(bare_segments_kept_apart_by_the_skin) {
  Shapes s;
  const double gap = 0.003;  // m
  const auto a = s.segment({-1.0, gap}, {1.0, gap}, 0.0);
  const auto b = s.segment({-1.0, 0.0}, {1.0, 0.0}, 0.0);
  const auto r = collide(s, a, b);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0.0, 1.0}, EPS, "up");
  const double skin = constants::SEGMENT_SKIN;
  for (int k = 0; k < r.n; ++k) {
    CHECK_NEAR(r.m.separation[k], gap - skin, EPS);
    CHECK_NEAR(r.m.point[k].y, 0.5 * gap, EPS);  // (gap − skin/2 + skin/2) / 2
  }
  // a thin capsule pair tops the skin up to SEGMENT_SKIN in total
  Shapes t;
  const auto c = t.segment({-1.0, gap}, {1.0, gap}, 0.001);
  const auto d = t.segment({-1.0, 0.0}, {1.0, 0.0}, 0.001);
  CHECK_NEAR(collide(t, c, d).m.separation[0], gap - skin, EPS);
  // radii of 1 cm each: no skin, the gap minus the radii
  Shapes u;
  const auto e = u.segment({-1.0, 0.025}, {1.0, 0.025}, 0.01);
  const auto f = u.segment({-1.0, 0.0}, {1.0, 0.0}, 0.01);
  CHECK_NEAR(collide(u, e, f).m.separation[0], 0.005, EPS);
}

// A box tilted on the ground with one corner touching and the other lifted beyond the
// speculative distance: only the touching corner is reported, with its own id.
TEST(point_beyond_the_speculative_distance_is_dropped) {
  const double angle = 0.05;  // rad: the far corner is 1 m sin(0.05) ≈ 5 cm up
  Shapes s;
  const auto ground = s.box({0.0, -0.5}, 5.0, 0.5);
  const Rot2 q{std::cos(angle), std::sin(angle)};
  const Vec2 low = rotate(q, Vec2{-0.5, -0.5});  // the low corner, relative to the centre
  const Vec2 centre{0.0, -0.001 - low.y};       // low corner 1 mm into the ground
  const auto box = s.box(centre, 0.5, 0.5, angle);
  const auto r = collide(s, box, ground);
  CHECK(r.n == 1);
  CHECK_NEAR(r.m.separation[0], -0.001, 1e-9);
  CHECK_NEAR(r.m.point[0].x, centre.x + low.x, 1e-6);
  // with a larger speculative distance both corners come back, the low one with the same id
  const auto wide = collide(s, box, ground, 0.1);
  CHECK(wide.n == 2);
  CHECK(wide.m.id[0] == r.m.id[0] || wide.m.id[1] == r.m.id[0]);
  // and nothing at all once the whole box is lifted beyond it
  Shapes t;
  const auto g = t.box({0.0, -0.5}, 5.0, 0.5);
  const auto lifted = t.box({0.0, 0.5 + 1.5 * SPEC}, 0.5, 0.5);
  CHECK(collide(t, lifted, g).n == 0);
}

// The normal points from b to a, so swapping the pair negates it; the contact itself (its
// points and separations) does not depend on the order. Every kind pair, off any tie.
TEST(swapping_a_and_b_negates_the_normal) {
  Shapes s;
  const ShapeRef2 shapes[] = {
      s.circle({0.45, 0.45}, 0.25),
      s.box({0.0, 0.0}, 0.5, 0.3, 0.1),
      s.segment({-0.6, -0.3}, {0.8, 0.4}, 0.05),
      s.core(ShapeKind::Polygon, {{-0.3, 0.2}, {0.5, 0.3}, {0.1, 0.8}}, 0.02),
  };
  int pairs = 0;
  for (const auto& a : shapes)
    for (const auto& b : shapes) {
      if (&a == &b) continue;
      const auto ab = collide(s, a, b);
      const auto ba = collide(s, b, a);
      CHECK(ab.n == ba.n);
      if (ab.n == 0 || ab.n != ba.n) continue;
      ++pairs;
      CHECK_VEC(ab.m.normal, -ba.m.normal, EPS, "normal(a, b) = -normal(b, a)");
      std::vector<double> sa(ab.m.separation.begin(), ab.m.separation.begin() + ab.n);
      std::vector<double> sb(ba.m.separation.begin(), ba.m.separation.begin() + ba.n);
      std::sort(sa.begin(), sa.end());
      std::sort(sb.begin(), sb.end());
      for (int k = 0; k < ab.n; ++k) CHECK_NEAR(sa[k], sb[k], EPS);
    }
  CHECK(pairs == 12);  // every ordered pair of the layout overlaps: the test is not vacuous
}

RBSIM_TEST_MAIN

// A reference face given: a wall (0.2 × 4 m, its foot at y = 0) and a chip 16 × 2 cm
// lying 6 cm under its foot and 1.2 cm down. The separating axes take the wall's bottom
// face (the least overlap, 8 mm: a push down); from its right face (edge 1, normal +x)
// the chip is pushed out sideways by its 6 cm under the wall, at its left end's corners
// (the incident edge, clipped to the face's extent: the corner below the foot moves up
// to it), the ids those of a clipped point; the mirrored call gives the negated normal
// and the same points. A circle gets one point from its centre's foot on the face's line,
// none beyond the speculative distance.
TEST(a_reference_face_given_pushes_from_it) {
  Shapes s;
  const ShapeRef2 wall = s.box({-2.1, 2.0}, 0.1, 2.0);
  const ShapeRef2 chip = s.box({-1.98, -0.002}, 0.08, 0.01);
  const Result sat = collide(s, wall, chip);
  CHECK(sat.n == 2);
  CHECK_VEC(sat.m.normal, {0, 1}, EPS, "the axes' choice: the wall's bottom face");
  Result r{};
  r.n = collide_on_face(wall, chip, 0, 1, s.verts.data(), s.norms.data(), SPEC, r.m);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {-1, 0}, EPS, "b -> a: the chip pushed along +x");
  for (int k = 0; k < r.n; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.06, EPS);
    constexpr std::int64_t S = std::int64_t{1} << 16;  // (narrow2d.hpp: the ids' S)
    CHECK(r.m.id[k] / (S * S) == 1);                   // a's face is the reference
    CHECK(r.m.id[k] / S % S == 1);                     // its edge 1
  }
  CHECK_VEC(r.m.point[0], {-2.03, 0.008}, EPS, "the upper corner");
  CHECK_VEC(r.m.point[1], {-2.03, 0.0}, EPS, "the lower corner, clipped to the foot");
  Result q{};
  q.n = collide_on_face(chip, wall, 1, 1, s.verts.data(), s.norms.data(), SPEC, q.m);
  CHECK(q.n == 2);
  CHECK_VEC(q.m.normal, {1, 0}, EPS, "mirrored: negated");
  CHECK_VEC(q.m.point[1], r.m.point[1], EPS, "mirrored: the same point");
  const ShapeRef2 ball = s.circle({-1.96, 0.01}, 0.03);
  Result c{};
  c.n = collide_on_face(ball, wall, 1, 1, s.verts.data(), s.norms.data(), SPEC, c.m);
  CHECK(c.n == 1);
  CHECK_VEC(c.m.normal, {1, 0}, EPS, "the face's normal");
  CHECK_NEAR(c.m.separation[0], 0.01, EPS);
  CHECK_VEC(c.m.point[0], {-1.995, 0.01}, EPS, "midway in the gap");
  const ShapeRef2 far = s.circle({-1.9, 0.01}, 0.03);
  CHECK(collide_on_face(far, wall, 1, 1, s.verts.data(), s.norms.data(), SPEC, c.m) == 0);
}
