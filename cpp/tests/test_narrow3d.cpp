// collide/narrow3d.cpp: 3D contact manifolds of each kind pair on configurations whose
// answer is known by hand (normal from b towards a, points midway between the surfaces,
// signed separations with the radii included, at most four points, feature ids stable
// while the same features touch), the mirrored dispatch, determinism, degenerate input,
// and the box–box cost per call.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "check.hpp"
#include "rbsim/hull3d.hpp"
#include "collide/narrow3d.hpp"
#include "rbsim/constants.hpp"

using namespace rbsim;

namespace {

constexpr double SPEC = constants::SPECULATIVE_DISTANCE;  // m
constexpr double EPS = 1e-12;  // m, round-off of O(1) lengths
// m: a reference face's side planes are moved out by the clip skin (narrow3d.cpp), so a
// larger incident face is cut this far outside the reference face
constexpr double SKIN = constants::REFERENCE_FACE_TOLERANCE;
const double S2 = std::sqrt(0.5);

Quat axis_angle(Vec3 axis, double angle) {
  const Vec3 u = (1.0 / length(axis)) * axis;
  const double s = std::sin(0.5 * angle);
  return {std::cos(0.5 * angle), s * u.x, s * u.y, s * u.z};
}

struct Result {
  int n = 0;
  Manifold3 m{};
};
Result collide(const ShapeRef3& a, const ShapeRef3& b, double spec = SPEC) {
  Result r;
  r.n = collide3d(a, b, spec, r.m);
  return r;
}

void check_vec(const char* file, int line, Vec3 got, Vec3 want, double tol, const char* what) {
  if (!(std::fabs(got.x - want.x) <= tol && std::fabs(got.y - want.y) <= tol &&
        std::fabs(got.z - want.z) <= tol))
    ::rbsim::test::fail(file, line,
                        std::string(what) + ": (" + std::to_string(got.x) + ", " +
                            std::to_string(got.y) + ", " + std::to_string(got.z) + ") != (" +
                            std::to_string(want.x) + ", " + std::to_string(want.y) + ", " +
                            std::to_string(want.z) + ")");
}
#define CHECK_VEC(...) check_vec(__FILE__, __LINE__, __VA_ARGS__)

// Whether the manifold has a point within tol of p (any order).
bool has_point(const Result& r, Vec3 p, double tol) {
  for (int k = 0; k < r.n; ++k)
    if (length(r.m.point[k] - p) <= tol) return true;
  return false;
}

// The index of r's first point of feature kind `kind` (-1: none).
int point_of_kind(const Result& r, FeatureKind kind) {
  for (int k = 0; k < r.n; ++k)
    if ((r.m.id[k] >> 60) == static_cast<std::int64_t>(kind)) return k;
  return -1;
}

bool all_finite(const Result& r) {
  bool ok = std::isfinite(r.m.normal.x) && std::isfinite(r.m.normal.y) && std::isfinite(r.m.normal.z);
  for (int k = 0; k < r.n; ++k)
    ok = ok && std::isfinite(r.m.point[k].x) && std::isfinite(r.m.point[k].y) &&
         std::isfinite(r.m.point[k].z) && std::isfinite(r.m.separation[k]);
  return ok && (r.n == 0 || std::fabs(length(r.m.normal) - 1.0) < 1e-12);
}

// The same manifold, bit for bit (normal, points, separations, ids).
bool same_bits(const Result& x, const Result& y) {
  if (x.n != y.n) return false;
  if (x.n == 0) return true;
  bool same = std::memcmp(&x.m.normal, &y.m.normal, sizeof(Vec3)) == 0;
  for (int k = 0; k < x.n; ++k)
    same = same && std::memcmp(&x.m.point[k], &y.m.point[k], sizeof(Vec3)) == 0 &&
           std::memcmp(&x.m.separation[k], &y.m.separation[k], sizeof(double)) == 0 &&
           x.m.id[k] == y.m.id[k];
  return same;
}

// The same points (as sets, within tol), separations and normal.
bool same_manifold(const Result& x, const Result& y, double tol) {
  if (x.n != y.n || length(x.m.normal - y.m.normal) > tol) return false;
  for (int k = 0; k < x.n; ++k) {
    bool found = false;
    for (int j = 0; j < y.n; ++j)
      found = found || (length(x.m.point[k] - y.m.point[j]) <= tol &&
                        std::fabs(x.m.separation[k] - y.m.separation[j]) <= tol);
    if (!found) return false;
  }
  return true;
}

// The ids as a sorted list, to compare manifolds whose point order may differ.
std::vector<std::int64_t> ids(const Result& r) {
  std::vector<std::int64_t> v(r.m.id.begin(), r.m.id.begin() + r.n);
  std::sort(v.begin(), v.end());
  return v;
}

// Numbers in [-1, 1) from a fixed seed (a 64-bit linear congruential generator), so
// that the random tests meet the same poses on every machine.
struct Uniform {
  std::uint64_t seed;
  double operator()() {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(seed >> 11) * (2.0 / 9007199254740992.0) - 1.0;
  }
};

// A convex hull in the world: built once in its body frame from vertices and triangles,
// its vertices and face normals moved to pose (c, q).
struct WorldHull {
  Hull3 hull;
  std::vector<Vec3> v, n;
  WorldHull(const std::vector<Vec3>& verts, const std::vector<std::array<std::int32_t, 3>>& tris) {
    std::string error;
    if (!build_hull(verts, tris, hull, &error)) std::printf("build_hull: %s\n", error.c_str());
  }
  ShapeRef3 at(Vec3 c, Quat q = {}) {
    v.clear();
    n.clear();
    for (const Vec3& p : hull.vertex) v.push_back(c + rotate(q, p));
    for (const Vec3& m : hull.face_normal) n.push_back(rotate(q, m));
    return convex_ref(v.data(), n.data(), hull.view());
  }
};

WorldHull box_as_hull(Vec3 half) {
  std::vector<Vec3> c;
  for (int k = 0; k < 8; ++k)
    c.push_back({k & 1 ? half.x : -half.x, k & 2 ? half.y : -half.y, k & 4 ? half.z : -half.z});
  // triangles in another order and split than box_hull()'s, as qhull might give them
  return WorldHull(c, {{1, 3, 7}, {1, 7, 5}, {0, 4, 6}, {0, 6, 2}, {2, 6, 7}, {2, 7, 3},
                       {0, 1, 5}, {0, 5, 4}, {4, 5, 7}, {4, 7, 6}, {0, 2, 3}, {0, 3, 1}});
}

WorldHull tetrahedron() {
  return WorldHull({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}},
                   {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}});
}

const ShapeRef3 GROUND = plane_ref({0, 1, 0}, 0.0);  // y <= 0 is solid

}  // namespace

// ---- spheres -----------------------------------------------------------------------------

// Two balls stacked exactly touching, apart within and beyond the speculative distance,
// and deep: the separation along the line of centres, the point midway.
TEST(spheres_touching_apart_and_deep) {
  const auto b = sphere_ref({0, 0, 0}, 0.5);
  auto r = collide(sphere_ref({0, 1, 0}, 0.5), b);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 0.0, "normal b -> a");
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  CHECK_VEC(r.m.point[0], {0, 0.5, 0}, EPS, "point");
  CHECK(r.m.id[0] == 0);
  r = collide(sphere_ref({0, 0, 1 + 0.5 * SPEC}, 0.5), b);
  CHECK(r.n == 1);
  CHECK_NEAR(r.m.separation[0], 0.5 * SPEC, EPS);
  CHECK_VEC(r.m.point[0], {0, 0, 0.5 + 0.25 * SPEC}, EPS, "mid-gap");
  CHECK(collide(sphere_ref({0, 0, 1 + 1.5 * SPEC}, 0.5), b).n == 0);
  r = collide(sphere_ref({0.6, 0.0, 0.8}, 0.5), b);  // centres 1 apart along (0.6, 0, 0.8)
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0.6, 0, 0.8}, EPS, "line of centres");
  r = collide(sphere_ref({0.3, 0.0, 0.4}, 0.5), b);  // 0.5 apart
  CHECK_NEAR(r.m.separation[0], -0.5, EPS);
  CHECK_VEC(r.m.point[0], 0.25 * Vec3{0.6, 0, 0.8}, EPS, "midway in the overlap");
}

// A ball on the ground plane: touching, apart, deep; the plane first gives the negated
// normal and the same point.
TEST(sphere_on_a_plane) {
  auto r = collide(sphere_ref({1, 0.5, 2}, 0.5), GROUND);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 0.0, "plane normal");
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  CHECK_VEC(r.m.point[0], {1, 0, 2}, EPS, "on the plane");
  r = collide(sphere_ref({1, 0.4, 2}, 0.5), GROUND);
  CHECK_NEAR(r.m.separation[0], -0.1, EPS);
  CHECK_VEC(r.m.point[0], {1, -0.05, 2}, EPS, "midway");
  CHECK(collide(sphere_ref({1, 0.5 + 0.5 * SPEC, 2}, 0.5), GROUND).n == 1);
  CHECK(collide(sphere_ref({1, 0.5 + 1.5 * SPEC, 2}, 0.5), GROUND).n == 0);
  // a tilted plane through (0, 1, 0)
  const Vec3 n{0.0, 0.8, 0.6};
  const auto tilted = plane_ref(n, dot(n, Vec3{0, 1, 0}));
  r = collide(sphere_ref(Vec3{0, 1, 0} + 0.49 * n, 0.5), tilted);
  CHECK_VEC(r.m.normal, n, 0.0, "the plane's normal");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  const auto q = collide(tilted, sphere_ref(Vec3{0, 1, 0} + 0.49 * n, 0.5));
  CHECK(q.n == 1);
  CHECK_VEC(q.m.normal, -n, 0.0, "mirrored: negated");
  CHECK_VEC(q.m.point[0], r.m.point[0], 0.0, "mirrored: same point");
}

// A ball against a turned box: on a face (the face normal), off an edge (the normal from
// the edge to the centre), off a corner (from the corner), and with its centre inside
// (out through the nearest face).
TEST(sphere_on_a_box_face_edge_and_corner) {
  const Quat q = axis_angle({1, 2, 3}, 0.7);
  const Vec3 c{0.5, -1.0, 2.0}, half{0.5, 0.3, 0.2};
  const auto box = box_ref(c, q, half);
  const Vec3 ex = rotate(q, {1, 0, 0}), ey = rotate(q, {0, 1, 0}), ez = rotate(q, {0, 0, 1});
  // face +y, 1 cm deep, off the face's centre
  auto r = collide(sphere_ref(c + 0.1 * ex + (0.3 + 0.25 - 0.01) * ey, 0.25), box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, ey, 1e-12, "face normal");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  CHECK_VEC(r.m.point[0], c + 0.1 * ex + 0.295 * ey, EPS, "midway below the face");
  // edge +x +y (along z), 1 cm gap along the diagonal
  const Vec3 edge = c + 0.5 * ex + 0.3 * ey + 0.05 * ez;
  const Vec3 diag = S2 * (ex + ey);
  r = collide(sphere_ref(edge + 0.26 * diag, 0.25), box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, diag, 1e-12, "edge to centre");
  CHECK_NEAR(r.m.separation[0], 0.01, EPS);
  CHECK_VEC(r.m.point[0], edge + 0.005 * diag, EPS, "mid-gap");
  // corner +x +y +z
  const Vec3 corner = c + 0.5 * ex + 0.3 * ey + 0.2 * ez;
  const Vec3 dir = (1.0 / std::sqrt(3.0)) * (ex + ey + ez);
  r = collide(sphere_ref(corner + 0.24 * dir, 0.25), box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, dir, 1e-12, "corner to centre");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  // 3 cm off the corner is beyond reach (a face's SAT would say less)
  CHECK(collide(sphere_ref(corner + 0.28 * dir, 0.25), box).n == 0);
  // centre inside, nearest the -z face (0.05 in)
  r = collide(sphere_ref(c - 0.15 * ez, 0.1), box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, -ez, 1e-12, "out through the nearest face");
  CHECK_NEAR(r.m.separation[0], -0.15, EPS);
}

// A ball against a capsule's side and beyond its end; against a hull's face, edge, vertex.
TEST(sphere_on_a_capsule_and_a_hull) {
  const auto cap = capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.2);
  auto r = collide(sphere_ref({0.3, 0.0, 0.49}, 0.3), cap);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, 0, 1}, EPS, "across the side");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  CHECK_VEC(r.m.point[0], {0.3, 0.0, 0.195}, EPS, "midway");
  r = collide(sphere_ref({1.5, 0, 0}, 0.3), cap);
  CHECK_VEC(r.m.normal, {1, 0, 0}, 0.0, "off the end");
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  const auto q = collide(cap, sphere_ref({1.5, 0, 0}, 0.3));
  CHECK_VEC(q.m.normal, {-1, 0, 0}, 0.0, "mirrored");

  auto tet = tetrahedron();
  const auto hull = tet.at({0, 0, 0});
  r = collide(sphere_ref({0.2, -0.1, 0.2}, 0.11), hull);  // below face y = 0
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, -1, 0}, EPS, "face");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  r = collide(sphere_ref({-0.1, -0.1, 0.5}, 0.13), hull);  // off the edge along z
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, S2 * Vec3{-1, -1, 0}, EPS, "edge");
  CHECK_NEAR(r.m.separation[0], std::sqrt(0.02) - 0.13, EPS);
  r = collide(sphere_ref({-0.1, -0.1, -0.1}, 0.2), hull);  // off the origin vertex
  CHECK_VEC(r.m.normal, (-1.0 / std::sqrt(3.0)) * Vec3{1, 1, 1}, EPS, "vertex");
  CHECK_NEAR(r.m.separation[0], std::sqrt(0.03) - 0.2, EPS);
}

// ---- capsules ----------------------------------------------------------------------------

// Parallel capsules, one on the other: two points at the ends of their common stretch;
// crossed: one point where they cross; apart beyond reach: none.
TEST(capsules_parallel_two_points_crossed_one) {
  const auto b = capsule_ref({0, 0, 0}, {2, 0, 0}, 0.1);
  auto r = collide(capsule_ref({-1, 0.2, 0}, {1, 0.2, 0}, 0.1), b);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0, 1, 0}, EPS, "across both");
  CHECK(has_point(r, {0, 0.1, 0}, EPS) && has_point(r, {1, 0.1, 0}, EPS));
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  CHECK_NEAR(r.m.separation[1], 0.0, EPS);
  CHECK(r.m.id[0] != r.m.id[1]);
  // moved a little along and down: the same ends make the stretch, the same ids
  auto moved = collide(capsule_ref({-0.99, 0.199, 0.001}, {1.01, 0.199, 0.001}, 0.1), b);
  CHECK(moved.n == 2);
  CHECK(ids(moved) == ids(r));
  // the lines 0.199 apart vertically and 0.001 sideways
  CHECK_NEAR(moved.m.separation[0], std::sqrt(0.199 * 0.199 + 1e-6) - 0.2, EPS);

  r = collide(capsule_ref({0.5, 0.19, -1}, {0.5, 0.19, 1}, 0.1), b);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, 1, 0}, EPS, "across both");
  CHECK_VEC(r.m.point[0], {0.5, 0.095, 0}, EPS, "where they cross");
  CHECK_NEAR(r.m.separation[0], -0.01, EPS);
  CHECK(collide(capsule_ref({0.5, 0.2 + 1.5 * SPEC, -1}, {0.5, 0.2 + 1.5 * SPEC, 1}, 0.1), b).n == 0);
}

// A capsule across another at 5°, its low end 0.5 mm above the other's core and its other
// end 1 cm higher: the closest points, and the end of the two cores' common stretch under
// its high end, within reach (12 mm), at its own distance. A capsule falling across
// another near one end had only that point, and brought its other end down 11 mm into the
// other within the step.
TEST(capsule_across_another_keeps_the_far_end_of_their_stretch) {
  const auto a = capsule_ref({-0.2, 0, 0}, {0.2, 0, 0}, 0.1);
  const double turn = 5.0 * M_PI / 180.0;
  const Vec3 dir{std::cos(turn), 0.0, std::sin(turn)};
  const Vec3 low = Vec3{-0.15, 0.2005, 0.0}, high = low + 0.3 * dir + Vec3{0, 0.01, 0};
  for (int order = 0; order < 2; ++order) {
    const auto b = capsule_ref(order == 0 ? low : high, order == 0 ? high : low, 0.1);
    const auto r = collide(b, a);
    CHECK(r.n == 2);
    CHECK_NEAR(r.m.separation[0], 0.0005, 1e-9);  // the closest points: the low end's
    // the stretch's far end: b's high end (the whole of b's core lies over a's), at its
    // distance from a's core
    const double gap = length(high - Vec3{std::min(high.x, 0.2), 0.0, 0.0}) - 0.2;  // m, 12 mm
    const int k = point_of_kind(r, FeatureKind::CapsuleEnd);
    CHECK(k >= 0);
    CHECK(k < 0 || std::fabs(r.m.separation[k] - gap) < 1e-12);
    CHECK(gap > 0.01 && gap < SPEC);
  }
  // at 90° the stretch is a point: the closest points alone (capsules_parallel_...)
}

// A capsule lying on the ground: two points at its ends; standing on end: one; a
// point-like capsule: one.
TEST(capsule_on_a_plane) {
  auto r = collide(capsule_ref({-0.5, 0.099, 0}, {0.5, 0.099, 0.2}, 0.1), GROUND);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 0.0, "plane normal");
  CHECK_VEC(r.m.point[0], {-0.5, -0.0005, 0}, EPS, "end p");
  CHECK_VEC(r.m.point[1], {0.5, -0.0005, 0.2}, EPS, "end q");
  CHECK_NEAR(r.m.separation[0], -0.001, EPS);
  r = collide(capsule_ref({0, 0.1, 0}, {0, 1.1, 0}, 0.1), GROUND);
  CHECK(r.n == 1);
  CHECK_NEAR(r.m.separation[0], 0.0, EPS);
  r = collide(capsule_ref({0, 0.05, 0}, {0, 0.05, 0}, 0.1), GROUND);
  CHECK(r.n == 1);
  CHECK_NEAR(r.m.separation[0], -0.05, EPS);
  const auto q = collide(GROUND, capsule_ref({-0.5, 0.099, 0}, {0.5, 0.099, 0.2}, 0.1));
  CHECK(q.n == 2);
  CHECK_VEC(q.m.normal, {0, -1, 0}, 0.0, "mirrored");
}

// A capsule lying on a box's top face: two points at its ends; hanging over the box's
// edge: clipped at the edge; over the edge's outside: one point at the edge; tilted on a
// turned box: the same manifold turned.
TEST(capsule_lying_on_a_box) {
  const auto box = box_ref({0, 0, 0}, {}, {1, 0.5, 1});
  auto r = collide(capsule_ref({-0.5, 0.598, 0.3}, {0.7, 0.598, 0.3}, 0.1), box);
  CHECK(r.n == 2);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 0.0, "face normal");
  CHECK_VEC(r.m.point[0], {-0.5, 0.499, 0.3}, EPS, "end p");
  CHECK_VEC(r.m.point[1], {0.7, 0.499, 0.3}, EPS, "end q");
  CHECK_NEAR(r.m.separation[0], -0.002, EPS);
  CHECK_NEAR(r.m.separation[1], -0.002, EPS);
  // moved by 0.1 mm and turned by 0.1 mrad: the same ends, the same ids
  const auto moved = collide(capsule_ref({-0.4999, 0.5981, 0.3}, {0.7001, 0.5980, 0.3001}, 0.1), box);
  CHECK(moved.n == 2);
  CHECK(moved.m.id == r.m.id);
  // touching, and beyond reach
  auto t0 = collide(capsule_ref({-0.5, 0.6, 0.3}, {0.7, 0.6, 0.3}, 0.1), box);
  CHECK(t0.n == 2);
  CHECK_NEAR(t0.m.separation[0], 0.0, EPS);
  CHECK(collide(capsule_ref({-0.5, 0.6 + 1.5 * SPEC, 0.3}, {0.7, 0.6 + 1.5 * SPEC, 0.3}, 0.1), box).n == 0);
  // overlapping core (10 cm deep): still the face, two points
  r = collide(capsule_ref({-0.5, 0.5, 0.3}, {0.7, 0.5, 0.3}, 0.1), box);
  CHECK(r.n == 2);
  CHECK_NEAR(r.m.separation[0], -0.1, EPS);
  // hanging over the +x edge: the part over the face, from x = 0.5 to the edge
  r = collide(capsule_ref({0.5, 0.6, 0}, {1.5, 0.6, 0}, 0.1), box);
  CHECK(r.n == 2);
  CHECK(has_point(r, {0.5, 0.5, 0}, EPS) && has_point(r, {1.0, 0.5, 0}, EPS));
  // beyond the edge, diagonally above it: one point on the edge
  const Vec3 dir = S2 * Vec3{1, 1, 0};
  r = collide(capsule_ref(Vec3{1, 0.5, -0.5} + 0.105 * dir, Vec3{1, 0.5, 0.5} + 0.105 * dir, 0.1), box);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, dir, EPS, "edge to segment");
  CHECK_NEAR(r.m.separation[0], 0.005, EPS);
  // the core dug 7 cm into the box across its top +z edge (along x): the edge's axis, one
  // point between the core and that edge (not another edge along x)
  // (through the box and through its hull)
  auto cube_hull = box_as_hull({0.5, 0.5, 0.5});
  const ShapeRef3 cubes[] = {box_ref({0, 0, 0}, {}, {0.5, 0.5, 0.5}), cube_hull.at({0, 0, 0})};
  const Vec3 w = 0.3 * S2 * Vec3{0, 1, -1};
  for (const ShapeRef3& cube : cubes) {
    for (const Vec3 e : {Vec3{0, 1, 1}, Vec3{0, -1, 1}, Vec3{0, 1, -1}, Vec3{0, -1, -1}}) {
      const Vec3 mid{0.2, 0.45 * e.y, 0.45 * e.z};
      const Vec3 ww{0, w.y * e.y, w.z * e.z};
      const auto dug = collide(capsule_ref(mid - ww, mid + ww, 0.1), cube);
      CHECK(dug.n == 1);
      CHECK_VEC(dug.m.normal, S2 * e, EPS, "the edge's diagonal");
      CHECK_NEAR(dug.m.separation[0], -0.05 * std::sqrt(2.0) - 0.1, EPS);
      CHECK_VEC(dug.m.point[0], 0.5 * ((mid - 0.1 * S2 * e) + Vec3{0.2, 0.5 * e.y, 0.5 * e.z}), EPS,
                "midway between the core's surface and the edge");
    }
  }
  // the first case on a turned box, turned: the same manifold, turned
  const Quat q = axis_angle({1, -1, 2}, 0.9);
  const Vec3 c{3, 1, -2};
  const auto tb = box_ref(c, q, {1, 0.5, 1});
  const auto t = collide(capsule_ref(c + rotate(q, {-0.5, 0.598, 0.3}), c + rotate(q, {0.7, 0.598, 0.3}), 0.1), tb);
  CHECK(t.n == 2);
  CHECK_VEC(t.m.normal, rotate(q, {0, 1, 0}), 1e-12, "turned normal");
  CHECK(has_point(t, c + rotate(q, {-0.5, 0.499, 0.3}), 1e-12));
  CHECK(has_point(t, c + rotate(q, {0.7, 0.499, 0.3}), 1e-12));
  CHECK_NEAR(t.m.separation[0], -0.002, 1e-12);
  // mirrored: the box first
  const auto m = collide(box, capsule_ref({-0.5, 0.598, 0.3}, {0.7, 0.598, 0.3}, 0.1));
  CHECK(m.n == 2);
  CHECK_VEC(m.m.normal, {0, -1, 0}, 0.0, "mirrored");
}

// ---- boxes -------------------------------------------------------------------------------

// A capsule tipping over a box's top edge onto its face: the core's closest point is
// just past the edge (it runs down towards it), the face's separation at the edge a
// little more. The manifold is the face's two points (the part of the core over the
// face: at the edge and at the inner end), normal up, their separations lowered so that
// the least is the true distance less the radius; one point at the closest points let
// the inner end sink into the box before the next step.
TEST(capsule_tipping_over_a_box_edge_gets_the_faces_two_points) {
  const auto box = box_ref({0, 0, 0}, {}, {0.5, 0.5, 0.5});  // top face y = 0.5, edge x = 0.5
  const double r = 0.1;
  const Vec3 p{0.0, 0.62, 0.0}, q{0.6, 0.60, 0.0};  // 12 and 10 cm over the face's plane
  const auto m = collide(capsule_ref(p, q, r), box);
  // the true distance: past the edge the core runs down at slope k from height h over it
  const double k = 0.02 / 0.6, h = 0.62 - k * 0.5 - 0.5;
  const double dist = h / std::sqrt(1.0 + k * k);
  CHECK(m.n == 2);
  CHECK_VEC(m.m.normal, {0, 1, 0}, 1e-12, "the face's normal");
  const double lower = (h - r) - (dist - r);  // the face's least overstated it by this
  CHECK(lower > 1e-5);  // (the case: the closest point is off the face)
  CHECK(has_point(m, {0.5, 0.5 + 0.5 * (h - r), 0.0}, 1e-12));  // at the edge, midway
  double least = INFINITY, most = -INFINITY;
  for (int k2 = 0; k2 < m.n; ++k2) {
    least = std::min(least, m.m.separation[k2]);
    most = std::max(most, m.m.separation[k2]);
  }
  CHECK_NEAR(least, dist - r, 1e-12);       // the true distance, less the radius
  CHECK_NEAR(most, (0.12 - r) - lower, 1e-12);  // the inner end's height, lowered alike
}

// A box from its 8 corners in the model's order is the box they came from.
TEST(box_from_its_corners) {
  const Quat q = axis_angle({1, 2, -1}, 0.8);
  const auto box = box_ref({0.3, -0.2, 1.0}, q, {0.5, 0.25, 0.1});
  Vec3 corners[8], normals[6];
  box_geometry(box, corners, normals);
  const auto again = box_ref_from_corners(corners);
  CHECK_VEC(again.center, box.center, EPS, "centre");
  CHECK_VEC(again.half, box.half, EPS, "half extents");
  for (int k = 0; k < 3; ++k) CHECK_VEC(again.axes[k], box.axes[k], EPS, "axis");
  // corner k's sign on axis j is bit j of k
  for (int k = 0; k < 8; ++k)
    for (int j = 0; j < 3; ++j) CHECK((dot(corners[k] - box.center, box.axes[j]) > 0.0) == (((k >> j) & 1) == 1));
}

// A unit box resting flat on the ground plane 1 mm deep: its four bottom corners; tilted
// about z so that one edge is lowest: the two corners of that edge; apart beyond reach: none.
TEST(box_on_a_plane_flat_and_tilted) {
  auto r = collide(box_ref({0.2, 0.499, -0.1}, {}, {0.5, 0.5, 0.5}), GROUND);
  CHECK(r.n == 4);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 0.0, "plane normal");
  for (int k = 0; k < 4; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.001, EPS);
    CHECK_NEAR(r.m.point[k].y, -0.0005, EPS);
  }
  CHECK(has_point(r, {-0.3, -0.0005, -0.6}, EPS) && has_point(r, {0.7, -0.0005, 0.4}, EPS));
  const double th = 0.3;
  const Quat q = axis_angle({0, 0, 1}, th);
  // lowest corner: local (-0.5, -0.5) turned by th has y = -0.5 (cos + sin)... the corner
  // (+0.5, -0.5) turned by +th: y = 0.5 sin − 0.5 cos; (−0.5, −0.5): y = −0.5 sin − 0.5 cos
  const double low = 0.5 * (std::sin(th) + std::cos(th));
  const Vec3 c{0, low - 0.001, 0};
  r = collide(box_ref(c, q, {0.5, 0.5, 0.5}), GROUND);
  CHECK(r.n == 2);
  for (int z = 0; z < 2; ++z) {
    const Vec3 corner = c + rotate(q, {-0.5, -0.5, z ? 0.5 : -0.5});
    CHECK(has_point(r, corner - 0.5 * (corner.y) * Vec3{0, 1, 0}, EPS));
  }
  CHECK_NEAR(r.m.separation[0], -0.001, EPS);
  // tilted further by 1 µrad: the same corners, the same ids
  const auto t = collide(box_ref(c, axis_angle({0, 0, 1}, th + 1e-6), {0.5, 0.5, 0.5}), GROUND);
  CHECK(ids(t) == ids(r));
  // touching, within and beyond reach
  auto t0 = collide(box_ref({0, 0.5, 0}, {}, {0.5, 0.5, 0.5}), GROUND);
  CHECK(t0.n == 4);
  CHECK_NEAR(t0.m.separation[0], 0.0, EPS);
  t0 = collide(box_ref({0, 0.5 + 0.5 * SPEC, 0}, {}, {0.5, 0.5, 0.5}), GROUND);
  CHECK(t0.n == 4);
  CHECK_NEAR(t0.m.separation[3], 0.5 * SPEC, EPS);
  CHECK(collide(box_ref({0, 0.5 + 1.5 * SPEC, 0}, {}, {0.5, 0.5, 0.5}), GROUND).n == 0);
  const auto m = collide(GROUND, box_ref({0.2, 0.499, -0.1}, {}, {0.5, 0.5, 0.5}));
  CHECK(m.n == 4);
  CHECK_VEC(m.m.normal, {0, -1, 0}, 0.0, "mirrored");
}

// A unit box resting face to face on a wide box, 1 mm deep: four points at its bottom
// corners, midway, each 1 mm deep; the normal is exactly the face normal; the ids stay
// the same while it is moved slightly; exactly touching is separation 0.
TEST(box_resting_on_a_box_four_points_stable_ids) {
  const auto ground = box_ref({0, -0.5, 0}, {}, {3, 0.5, 3});  // top face y = 0
  const auto r = collide(box_ref({0.1, 0.499, 0.2}, {}, {0.5, 0.5, 0.5}), ground);
  CHECK(r.n == 4);
  CHECK(r.m.normal.x == 0.0 && r.m.normal.y == 1.0 && r.m.normal.z == 0.0);
  for (int k = 0; k < 4; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.001, EPS);
    CHECK_NEAR(r.m.point[k].y, -0.0005, EPS);
  }
  // the wide box's face cut at the unit box's sides, moved out by the skin
  for (double x : {-0.4 - SKIN, 0.6 + SKIN})
    for (double z : {-0.3 - SKIN, 0.7 + SKIN}) CHECK(has_point(r, {x, -0.0005, z}, EPS));
  for (int k = 0; k < 4; ++k)
    for (int j = k + 1; j < 4; ++j) CHECK(r.m.id[k] != r.m.id[j]);
  // moved by 0.1 mm in each direction: the same features, the same ids
  for (const Vec3 d : {Vec3{1e-4, 0, 0}, Vec3{0, 1e-4, 0}, Vec3{0, -1e-4, 1e-4}, Vec3{-1e-4, 0, -1e-4}}) {
    const auto m = collide(box_ref(Vec3{0.1, 0.499, 0.2} + d, {}, {0.5, 0.5, 0.5}), ground);
    CHECK(m.n == 4);
    CHECK(m.m.id == r.m.id);
  }
  // exactly touching; within and beyond reach
  auto t = collide(box_ref({0.1, 0.5, 0.2}, {}, {0.5, 0.5, 0.5}), ground);
  CHECK(t.n == 4);
  CHECK_NEAR(t.m.separation[2], 0.0, EPS);
  t = collide(box_ref({0.1, 0.5 + 0.5 * SPEC, 0.2}, {}, {0.5, 0.5, 0.5}), ground);
  CHECK(t.n == 4);
  CHECK_NEAR(t.m.separation[0], 0.5 * SPEC, EPS);
  CHECK(collide(box_ref({0.1, 0.5 + 1.5 * SPEC, 0.2}, {}, {0.5, 0.5, 0.5}), ground).n == 0);
  // deep: 0.3 m in, still the face
  t = collide(box_ref({0.1, 0.2, 0.2}, {}, {0.5, 0.5, 0.5}), ground);
  CHECK(t.n == 4);
  CHECK_VEC(t.m.normal, {0, 1, 0}, 0.0, "face normal");
  CHECK_NEAR(t.m.separation[1], -0.3, EPS);
  // the pair the other way round: the negated normal and the same points
  const auto m = collide(ground, box_ref({0.1, 0.499, 0.2}, {}, {0.5, 0.5, 0.5}));
  CHECK(m.n == 4);
  CHECK_VEC(m.m.normal, {0, -1, 0}, 0.0, "b -> a");
  // the same corners, but for the skin: the other order takes the wide face as the
  // reference (the tie goes to a), and the unit box's corners are its points as they are
  for (int k = 0; k < 4; ++k) CHECK(has_point(r, m.m.point[k], 1.5 * SKIN));
}

// A box hanging over the ground box's edge: the overlap of the two faces (the part over
// the ground), its four corners; rocked by 1 mrad about an axis: the ids stay.
TEST(box_over_an_edge_and_rocking) {
  const auto ground = box_ref({0, -0.5, 0}, {}, {1, 0.5, 1});
  const auto r = collide(box_ref({1.0, 0.499, 0}, {}, {0.5, 0.5, 0.5}), ground);
  CHECK(r.n == 4);
  // the ground's face cut at the box's sides moved out by the skin, and at its own edge
  for (double x : {0.5 - SKIN, 1.0})
    for (double z : {-0.5 - SKIN, 0.5 + SKIN}) CHECK(has_point(r, {x, -0.0005, z}, EPS));
  // rocking: the ground's face becomes the reference (the box's bottom corners dip),
  // and stays it while the box rocks on
  const auto a = collide(box_ref({0.2, 0.499, 0}, axis_angle({1, 0, 1}, 1e-3), {0.5, 0.5, 0.5}), ground);
  const auto b = collide(box_ref({0.2, 0.499, 0}, axis_angle({1, 0, 1}, 1.1e-3), {0.5, 0.5, 0.5}), ground);
  CHECK(a.n == 4 && b.n == 4);
  CHECK(ids(a) == ids(b));
  CHECK_NEAR(a.m.normal.y, 1.0, 1e-6);  // a face normal, tilted by at most 1 mrad
}

// A box turned 45° about the vertical on an equal box: the faces overlap in an octagon,
// whose 8 corners are reduced to 4, spanning at least the inscribed square's area.
TEST(box_on_a_box_turned_reduces_an_octagon_to_four) {
  const auto lower = box_ref({0, -0.5, 0}, {}, {0.5, 0.5, 0.5});
  const auto r = collide(box_ref({0, 0.499, 0}, axis_angle({0, 1, 0}, M_PI / 4), {0.5, 0.5, 0.5}), lower);
  CHECK(r.n == 4);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 1e-15, "face normal");
  double area = 0.0;  // the quad's area (points in order around it)
  for (int k = 0; k < 4; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.001, EPS);
    const Vec3 p = r.m.point[k], q = r.m.point[(k + 1) % 4];
    area += 0.5 * (p.z * q.x - p.x * q.z);
    CHECK_NEAR(std::max(std::fabs(p.x), std::fabs(p.z)), 0.5, 1e-12);  // on the octagon's rim
  }
  // the octagon's area is 8 (√2 − 1) / 2 · ... ≈ 0.828; 4 of its corners span at least 0.5
  CHECK(std::fabs(area) >= 0.5);
}

// Two boxes crossed at 90°, touching edge to edge: the lower turned 45° about z (its top
// an edge along z), the upper 45° about x (its bottom an edge along x): one point where
// the edges cross, the normal vertical.
TEST(boxes_crossed_edge_to_edge_one_point) {
  const double h = S2;  // a unit box's half diagonal
  const auto lower = box_ref({0, 0, 0}, axis_angle({0, 0, 1}, M_PI / 4), {0.5, 0.5, 0.5});
  for (double overlap : {0.0, 0.002, -0.5 * SPEC}) {
    const auto r = collide(box_ref({0.1, 2 * h - overlap, -0.05}, axis_angle({1, 0, 0}, M_PI / 4), {0.5, 0.5, 0.5}), lower);
    CHECK(r.n == 1);
    CHECK_VEC(r.m.normal, {0, 1, 0}, 1e-12, "vertical");
    CHECK_NEAR(r.m.separation[0], -overlap, 1e-12);
    CHECK_VEC(r.m.point[0], {0, h - 0.5 * overlap, -0.05}, 1e-12, "where the edges cross");
    CHECK((r.m.id[0] >> 60) == static_cast<std::int64_t>(FeatureKind::EdgeEdge));
  }
  // beyond reach
  CHECK(collide(box_ref({0.1, 2 * h + 1.5 * SPEC, 0}, axis_angle({1, 0, 0}, M_PI / 4), {0.5, 0.5, 0.5}), lower).n == 0);
  // after a tiny motion: the same edges, the same id
  const auto a = collide(box_ref({0.1, 2 * h - 0.002, -0.05}, axis_angle({1, 0, 0}, M_PI / 4), {0.5, 0.5, 0.5}), lower);
  const auto b = collide(box_ref({0.1001, 2 * h - 0.0021, -0.0501}, axis_angle({1, 0.1, 0}, M_PI / 4 + 1e-4), {0.5, 0.5, 0.5}), lower);
  CHECK(a.n == 1 && b.n == 1 && a.m.id[0] == b.m.id[0]);
}

// ---- convex hulls ------------------------------------------------------------------------

// A tetrahedron on the ground: face down, its three corners; vertex down (turned), one.
TEST(tetrahedron_on_a_plane) {
  auto tet = tetrahedron();
  // the face y = 0 down, 1 mm in
  auto r = collide(tet.at({0, -0.001, 0}), GROUND);
  CHECK(r.n == 3);
  CHECK(has_point(r, {0, -0.0005, 0}, EPS) && has_point(r, {1, -0.0005, 0}, EPS) &&
        has_point(r, {0, -0.0005, 1}, EPS));
  // within and beyond reach; moved by 0.1 mm: the same corners, the same ids
  CHECK(collide(tet.at({0, 0.5 * SPEC, 0}), GROUND).n == 3);
  CHECK(collide(tet.at({0, 1.5 * SPEC, 0}), GROUND).n == 0);
  const auto moved = collide(tet.at({1e-4, -0.0011, 1e-4}), GROUND);
  CHECK(moved.n == 3);
  CHECK(moved.m.id == r.m.id);
  // the face x + y + z = 1 turned to face down: the origin vertex is up, the others down
  const Quat q = axis_angle(cross(Vec3{1, 1, 1}, Vec3{0, -1, 0}), std::acos(-1.0 / std::sqrt(3.0)));
  const Vec3 n = rotate(q, (1.0 / std::sqrt(3.0)) * Vec3{1, 1, 1});
  CHECK_VEC(n, {0, -1, 0}, 1e-12, "the slanted face turned down");
  r = collide(tet.at({0, 1.0 / std::sqrt(3.0), 0}, q), GROUND);
  CHECK(r.n == 3);
  for (int k = 0; k < 3; ++k) CHECK_NEAR(r.m.separation[k], 0.0, 1e-12);
  // turned over: standing on its origin vertex, 1 mm in
  const auto up = collide(tet.at({0, -0.001, 0}, mul(axis_angle({1, 0, 0}, M_PI), q)), GROUND);
  CHECK(up.n == 1);
  CHECK_NEAR(up.m.separation[0], -0.001, 1e-12);
}

// A capsule near a box, apart from it or touching, at random poses around all of its
// faces, edges and corners: the box's closest points in closed form (segment_box_closest)
// give the manifold that the same box as a hull gives, where the closest points are
// found by trying the segment's ends and every edge. 3000 poses (a fixed sequence).
TEST(capsule_near_a_box_matches_the_box_as_a_hull) {
  const Vec3 half{0.6, 0.35, 0.45};
  auto hull = box_as_hull(half);
  std::uint64_t state = 12345;
  auto uniform = [&state](double lo, double hi) {  // (a 64-bit LCG: the same sequence anywhere)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  int compared = 0, apart = 0;
  for (int k = 0; k < 3000; ++k) {
    const Quat q = axis_angle({uniform(-1, 1), uniform(-1, 1), uniform(-1, 1) + 1e-3}, uniform(0, 3));
    const Vec3 c{uniform(-2, 2), uniform(-2, 2), uniform(-2, 2)};
    const ShapeRef3 box = box_ref(c, q, half);
    const ShapeRef3 as_hull = hull.at(c, q);
    // the capsule's middle within 1 m of the box's surface, any direction, any length
    const Vec3 mid = c + Vec3{uniform(-1.3, 1.3), uniform(-1.0, 1.0), uniform(-1.1, 1.1)};
    const Vec3 dir{uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)};
    const Vec3 half_len = (uniform(0.05, 0.6) / (length(dir) + 1e-12)) * dir;
    const double radius = uniform(0.02, 0.2);
    const ShapeRef3 cap = capsule_ref(mid - half_len, mid + half_len, radius);
    const double spec = 0.3;  // m: wide, so that apart pairs make manifolds too
    const auto a = collide(cap, box, spec), b = collide(cap, as_hull, spec);
    CHECK(a.n == b.n);
    if (a.n != b.n || a.n == 0) continue;
    ++compared;
    apart += a.m.separation[0] > 0.0 ? 1 : 0;
    // 1e-9 (m, and of a unit normal): two exact methods' round-off, far above it
    CHECK_VEC(a.m.normal, b.m.normal, 1e-9, "normal");
    for (int i = 0; i < a.n; ++i) {
      CHECK_VEC(a.m.point[i], b.m.point[i], 1e-9, "point");
      CHECK_NEAR(a.m.separation[i], b.m.separation[i], 1e-9);
    }
  }
  CHECK(compared > 300);  // the poses reach the pairs that make manifolds
  CHECK(apart > 100);     // and among them, pairs apart
}

// A hull of a box's corners (triangulated as qhull might) against a box gives the box–box
// manifold: resting face to face, turned, edge to edge, and the box first.
TEST(hull_of_a_box_matches_box_box) {
  auto hull = box_as_hull({0.5, 0.5, 0.5});
  const auto ground = box_ref({0, -0.5, 0}, {}, {3, 0.5, 3});
  const auto lower = box_ref({0, 0, 0}, axis_angle({0, 0, 1}, M_PI / 4), {0.5, 0.5, 0.5});
  struct Pose {
    Vec3 c;
    Quat q;
    const ShapeRef3* other;
  };
  const Pose poses[] = {
      {{0.1, 0.499, 0.2}, {}, &ground},
      {{0.1, 0.49, 0.2}, axis_angle({0, 1, 0}, 0.3), &ground},
      {{0.1, 0.48, 0.2}, axis_angle({1, 0, 0.2}, 0.05), &ground},
      {{0.1, 2 * S2 - 0.002, -0.05}, axis_angle({1, 0, 0}, M_PI / 4), &lower},
  };
  for (const Pose& p : poses) {
    const auto box = collide(box_ref(p.c, p.q, {0.5, 0.5, 0.5}), *p.other);
    const auto conv = collide(hull.at(p.c, p.q), *p.other);
    CHECK(box.n > 0);
    CHECK(same_manifold(box, conv, 1e-12));  // same arithmetic up to the order of sums
    const auto box2 = collide(*p.other, box_ref(p.c, p.q, {0.5, 0.5, 0.5}));
    const auto conv2 = collide(*p.other, hull.at(p.c, p.q));
    CHECK(same_manifold(box2, conv2, 1e-12));
  }
  // hull against hull: the same again
  auto base = box_as_hull({3, 0.5, 3});
  const auto hh = collide(hull.at({0.1, 0.499, 0.2}), base.at({0, -0.5, 0}));
  CHECK(same_manifold(hh, collide(box_ref({0.1, 0.499, 0.2}, {}, {0.5, 0.5, 0.5}), ground), 1e-12));
}

// Two tetrahedra edge to edge (one's top edge against the other's bottom edge, crossed):
// one point; a tetrahedron on a box face down: three points.
TEST(hulls_edge_to_edge_and_face_on_box) {
  // a tetrahedron with a bottom edge along x and a top edge along z
  WorldHull t({{-1, 0, 0}, {1, 0, 0}, {0, 1, -1}, {0, 1, 1}}, {{0, 1, 3}, {0, 3, 2}, {0, 2, 1}, {1, 2, 3}});
  // the lower one is t (top edge along z at y = 1); the upper one t moved up: its bottom
  // edge along x crosses the lower's top edge 1 mm deep
  WorldHull u = t;
  const auto lower = t.at({0, 0, 0});
  const auto upper = u.at({0.2, 0.999, 0.1});
  const auto r = collide(upper, lower);
  CHECK(r.n == 1);
  CHECK_VEC(r.m.normal, {0, 1, 0}, 1e-12, "vertical");
  CHECK_NEAR(r.m.separation[0], -0.001, 1e-12);
  CHECK_VEC(r.m.point[0], {0.0, 0.9995, 0.1}, 1e-12, "where the edges cross");
  const auto m = collide(lower, upper);
  CHECK(m.n == 1);
  CHECK_VEC(m.m.normal, {0, -1, 0}, 1e-12, "the other order");
  CHECK_VEC(m.m.point[0], r.m.point[0], 1e-12, "same point");
  // a tetrahedron face down on a box
  auto tet = tetrahedron();
  const auto box = box_ref({0, -0.5, 0}, {}, {2, 0.5, 2});
  const auto f = collide(tet.at({0.1, -0.001, 0.1}), box);
  CHECK(f.n == 3);
  for (int k = 0; k < 3; ++k) CHECK_NEAR(f.m.separation[k], -0.001, EPS);
  // a corner of the tetrahedron's face (legs along x and z, hypotenuse at 45°), its sides
  // moved out by the skin: the leg z = 0.1 − s meets the hypotenuse s further out
  CHECK(has_point(f, {1.1 + SKIN * (1.0 + std::sqrt(2.0)), -0.0005, 0.1 - SKIN}, EPS));
}

// A prism of `sides` sides about the x axis (radius r, length 2 hx): vertex k of each
// cap ring at angle 2πk/sides in the y-z plane; caps fanned from their first vertex.
WorldHull prism(int sides, double r, double hx) {
  std::vector<Vec3> v;
  for (const double x : {-hx, hx})
    for (int k = 0; k < sides; ++k) {
      const double t = 2.0 * M_PI * k / sides;
      v.push_back({x, r * std::cos(t), r * std::sin(t)});
    }
  std::vector<std::array<std::int32_t, 3>> tris;
  for (int k = 0; k < sides; ++k) {  // the sides, outward
    const int k1 = (k + 1) % sides;
    tris.push_back({k, k1, sides + k1});
    tris.push_back({k, sides + k1, sides + k});
  }
  for (int k = 1; k + 1 < sides; ++k) {  // the caps: −x then +x
    tris.push_back({0, k + 1, k});
    tris.push_back({sides, sides + k, sides + k + 1});
  }
  return WorldHull(v, tris);
}

// Two 40-sided prisms crossed, the upper one's lowest edge on the lower one's highest
// edge, 1 mm deep: the normal vertical (the edge pair's), the deepest point 1 mm deep
// where the edges cross (the face beside the edge, 4.5° off, clipped, gives it and its
// other points within reach: edge_with_face), no point deeper. Each has 120 edges, more
// than the edge pairs' test takes in one group (narrow3d.cpp, EDGE_GROUP), and the
// winning pair lies past the first group (a face normal wins otherwise, 4.5° off); the
// other order and a turn about the vertical that keeps the edges crossing give it again.
TEST(many_edged_hulls_crossed_edge_to_edge) {
  const double r = 0.3, depth = 0.001;
  auto lower = prism(40, r, 1.0), upper = prism(40, r, 1.0);
  CHECK(lower.hull.edge.size() > 64);
  // both turned by −90° about x: vertex 10 (at 90°) on top, vertex 30 at the bottom; the
  // lower prism along x, its top edge up; the upper one along z (turned by 90° about y),
  // its bottom edge down, across the lower's
  const Quat roll = axis_angle({1, 0, 0}, -M_PI / 2);
  const Quat across = mul(axis_angle({0, 1, 0}, M_PI / 2), roll);
  const auto lo = lower.at({0, 0, 0}, roll);
  const Vec3 c{0.05, 2 * r - depth, -0.02};
  const auto up = upper.at(c, across);
  // the deepest point (1e-12: round-off of the clip), no deeper than the edges' crossing
  const auto deepest = [](const Result& x) {
    int k = 0;
    for (int j = 1; j < x.n; ++j)
      if (x.m.separation[j] < x.m.separation[k]) k = j;
    return k;
  };
  const auto m = collide(up, lo);
  CHECK(m.n >= 1);
  CHECK_VEC(m.m.normal, {0, 1, 0}, 1e-12, "vertical");
  const int k = deepest(m);
  CHECK_NEAR(m.m.separation[k], -depth, 1e-12);
  // the upper edge at x = 0.05, the lower at z = 0 (within the clip skin, 0.5 mm)
  CHECK_VEC(m.m.point[k], {0.05, r - 0.5 * depth, 0.0}, 1e-3, "where the edges cross");
  const auto w = collide(lo, up);
  CHECK(w.n == m.n);
  CHECK_VEC(w.m.normal, {0, -1, 0}, 1e-12, "the other order");
  CHECK_NEAR(w.m.separation[deepest(w)], -depth, 1e-12);
  CHECK_VEC(w.m.point[deepest(w)], m.m.point[k], 1e-3, "same point");
  const auto t = collide(upper.at(c, mul(axis_angle({0, 1, 0}, 0.3), across)), lo);
  CHECK(t.n >= 1);
  CHECK_VEC(t.m.normal, {0, 1, 0}, 1e-12, "turned: vertical");
  CHECK_NEAR(t.m.separation[deepest(t)], -depth, 1e-12);
}

// A unit box turned 45° about the vertical and tipped 5° on another, down towards +x and a
// little towards +z, 0.2 mm above it where its bottom edge from its +x corner to its +z
// corner crosses the lower box's rim x = 0.5: its +x corner hangs over that rim, below
// the lower box's top, and the lower box's corner (0.5, 0.5) rises above the tipped box's
// bottom plane beside its face, so an edge pair wins the axes. Its manifold also has
// where the other bottom edge from the +x corner crosses the rim, 10 mm up: the bottom
// face the box is about to lie on (a box tumbling like this at 10 rad/s laid its face 18
// mm into the box below within a step when the manifold had the edge pair's point only).
// The same through the hull path.
TEST(box_tipped_over_a_box_rim_keeps_its_face_points) {
  const double gap = 0.0002, tip = 5.0 * M_PI / 180.0, toward = 20.0 * M_PI / 180.0;
  const Vec3 half{0.5, 0.5, 0.5};
  const auto lower = box_ref({0, 0, 0}, {}, half);
  const Vec3 down{std::cos(toward), 0.0, std::sin(toward)};  // the tip lowers this side
  const Quat q = mul(axis_angle(cross(Vec3{0, 1, 0}, down), tip), axis_angle({0, 1, 0}, M_PI / 4));
  // the bottom corners at +x, +z and −z (body corners turned by the 45° about y)
  const Vec3 px = rotate(q, {0.5, -0.5, 0.5}), pz = rotate(q, {-0.5, -0.5, 0.5}),
             mz = rotate(q, {0.5, -0.5, -0.5});
  CHECK(px.x > 0.6 && pz.z > 0.6 && mz.z < -0.6);
  // where the edges from the +x corner cross the rim's plane x = 0.5 (centre at the origin)
  const auto crossing = [&](Vec3 to) { return px + ((0.5 - px.x) / (to.x - px.x)) * (to - px); };
  const Vec3 c_low = crossing(pz), c_high = crossing(mz);
  const Vec3 centre{0, 0.5 + gap - c_low.y, 0};
  CHECK(c_high.y - c_low.y > 0.005 && c_high.y - c_low.y < 0.5 * SPEC);  // within reach
  const auto tipped = box_ref(centre, q, half);
  auto lower_hull = box_as_hull(half);
  for (int path = 0; path < 2; ++path) {
    const auto r = path == 0 ? collide(tipped, lower) : collide(tipped, lower_hull.at({0, 0, 0}, {}));
    const int k = point_of_kind(r, FeatureKind::EdgeEdge);
    CHECK(k >= 0);
    CHECK(k >= 0 && r.m.separation[k] > 0.0 && r.m.separation[k] <= gap);
    CHECK(r.m.normal.y > std::cos(tip));  // the edge pair's: between the faces' normals
    // a point where the other edge crosses the rim, midway between the surfaces (within 1
    // mm: the clip skin moves it 0.5 mm out), and none deeper than the edge pair's (1e-12:
    // its separation from the axes and from its closest points differ by round-off)
    const Vec3 mid = centre + c_high - Vec3{0, 0.5 * (centre.y + c_high.y - 0.5), 0};
    bool other = false;
    for (int j = 0; j < r.n; ++j) {
      other = other || (j != k && length(r.m.point[j] - mid) < 0.001);
      CHECK(k >= 0 && r.m.separation[j] >= r.m.separation[k] - 1e-12);
    }
    CHECK(other);
  }
}

// A hull with more faces than the narrowphase keeps plane offsets for (narrow3d.cpp,
// PLANE_TABLE = 256: a face past them is never passed over): a ball of 24 meridians and
// 13 parallels (264 quads and 48 triangles), each of several faces past the table turned
// to lie face down on a box 1 mm deep. The face is the contact's reference face (the
// ball is a, and a face flush on another keeps a's), with its four corners; a face past
// the table skipped by mistake would leave another face, or an edge, to be the contact.
TEST(hull_with_faces_past_the_plane_table_lies_on_any_face) {
  const int meridians = 24, parallels = 13;
  std::vector<Vec3> v{{0, -0.5, 0}};
  for (int i = 1; i <= parallels; ++i)
    for (int k = 0; k < meridians; ++k) {
      const double lat = M_PI * i / (parallels + 1) - M_PI / 2, lon = 2 * M_PI * k / meridians;
      const double r = 0.5 * std::cos(lat);  // m
      v.push_back({r * std::cos(lon), 0.5 * std::sin(lat), r * std::sin(lon)});
    }
  v.push_back({0, 0.5, 0});
  const int top = static_cast<int>(v.size()) - 1;
  const auto at = [&](int i, int k) { return 1 + (i - 1) * meridians + (k % meridians); };
  std::vector<std::array<std::int32_t, 3>> tris;
  for (int k = 0; k < meridians; ++k) {
    tris.push_back({0, at(1, k), at(1, k + 1)});
    tris.push_back({top, at(parallels, k + 1), at(parallels, k)});
    for (int i = 1; i < parallels; ++i) {
      tris.push_back({at(i, k), at(i + 1, k), at(i + 1, k + 1)});
      tris.push_back({at(i, k), at(i + 1, k + 1), at(i, k + 1)});
    }
  }
  WorldHull ball(v, tris);
  CHECK(ball.hull.face_count() == meridians * (parallels - 1) + 2 * meridians);
  auto slab = box_as_hull({2.0, 0.25, 2.0});
  const double depth = 0.001;  // m
  int tried = 0;
  for (int f = 257; f < ball.hull.face_count(); f += 9) {
    const Vec3 n = ball.hull.face_normal[f];
    if (ball.hull.face_start[f + 1] - ball.hull.face_start[f] != 4) continue;  // a quad
    ++tried;
    // turned so that face f looks straight down (−y)
    const Vec3 axis = cross(n, {0, -1, 0});
    const Quat q = axis_angle((1.0 / length(axis)) * axis, std::acos(-n.y));
    const double below = dot(n, ball.hull.vertex[ball.hull.face_vertex[ball.hull.face_start[f]]]);  // m
    const auto m = collide(ball.at({0.1, 0.25 + below - depth, -0.2}, q), slab.at({0, 0, 0}));
    CHECK(m.n == 4);
    CHECK_VEC(m.m.normal, {0, 1, 0}, 1e-12, "up");
    for (int k = 0; k < m.n; ++k) CHECK_NEAR(m.m.separation[k], -depth, 1e-9);
    CHECK(((m.m.id[0] >> 40) & 0x7FFFF) == f);  // the reference face
  }
  CHECK(tried >= 4);
}

// An ellipsoid of 80 triangles (an icosahedron split once, on the unit sphere, scaled by
// half axes s, m): a hull of many small faces.
WorldHull ellipsoid(Vec3 s) {
  const double p = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v{{-1, p, 0}, {1, p, 0},  {-1, -p, 0}, {1, -p, 0}, {0, -1, p},  {0, 1, p},
                      {0, -1, -p}, {0, 1, -p}, {p, 0, -1},  {p, 0, 1},  {-p, 0, -1}, {-p, 0, 1}};
  std::vector<std::array<std::int32_t, 3>> tris{
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (Vec3& x : v) x = (1.0 / length(x)) * x;
  std::map<std::pair<int, int>, int> middle;  // each edge's midpoint, pushed to the sphere
  const auto mid = [&](int a, int b) {
    const auto key = std::minmax(a, b);
    if (const auto it = middle.find(key); it != middle.end()) return it->second;
    const Vec3 m = 0.5 * (v[a] + v[b]);
    v.push_back((1.0 / length(m)) * m);
    return middle[key] = static_cast<int>(v.size()) - 1;
  };
  std::vector<std::array<std::int32_t, 3>> split;
  for (const auto& t : tris) {
    const int a = mid(t[0], t[1]), b = mid(t[1], t[2]), c = mid(t[2], t[0]);
    split.push_back({t[0], a, c});
    split.push_back({t[1], b, a});
    split.push_back({t[2], c, b});
    split.push_back({a, b, c});
  }
  for (Vec3& x : v) x = {s.x * x.x, s.y * x.y, s.z * x.z};
  return WorldHull(v, split);
}

// Random poses of two such ellipsoids deep in each other (fixed seed): whenever a vertex
// of one lies inside the other, there is a manifold and it overlaps. The face most
// anti-parallel to the reference face need not lie over it, and its clip can leave
// nothing: one pose in a thousand had no point (no manifold, so no contact: two rocks
// went through each other), before the hull path fell back to the incident hull's
// vertex deepest below the reference face.
TEST(deep_hull_pairs_always_have_a_manifold) {
  Uniform uniform{7};
  auto a = ellipsoid({0.3, 0.22, 0.26}), b = ellipsoid({0.3, 0.22, 0.26});
  CHECK(a.hull.face_count() == 80);
  const auto inside = [](const WorldHull& h, Vec3 x) {  // strictly, by every face's plane
    for (int f = 0; f < h.hull.face_count(); ++f)
      if (dot(h.n[f], x - h.v[h.hull.face_vertex[h.hull.face_start[f]]]) > -1e-9) return false;
    return true;
  };
  int deep = 0, missing = 0, apart = 0;
  for (int k = 0; k < 40000; ++k) {
    const Quat qa = normalize(Quat{uniform(), uniform(), uniform(), uniform()});
    const Quat qb = normalize(Quat{uniform(), uniform(), uniform(), uniform()});
    const Vec3 c{0.3 * uniform(), 0.3 * uniform(), 0.3 * uniform()};
    const ShapeRef3 sa = a.at(c, qa), sb = b.at({0, 0, 0}, qb);
    bool in = false;
    for (const Vec3& x : a.v) in = in || inside(b, x);
    for (const Vec3& x : b.v) in = in || inside(a, x);
    if (!in) continue;
    ++deep;
    const auto m = collide(sa, sb);
    double least = 0.0;  // m: the manifold's deepest point
    for (int p = 0; p < m.n; ++p) least = std::min(least, m.m.separation[p]);
    missing += m.n == 0;
    apart += m.n > 0 && least >= 0.0;
  }
  CHECK(deep > 20000);
  CHECK(missing == 0);
  CHECK(apart == 0);
}

// Random poses of two boxes (fixed seed): the box–box function and the hull code path
// (both boxes as hulls) find the same manifold, pose after pose: the same SAT over the
// same axes (the hull path tests only the edge pairs that make Minkowski faces, which
// hold the largest separation).
TEST(random_box_pairs_match_the_hull_path) {
  Uniform uniform{12345};
  const Vec3 ha{0.5, 0.3, 0.4}, hb{0.6, 0.5, 0.2};
  auto hull_a = box_as_hull(ha), hull_b = box_as_hull(hb);
  int contacts = 0, mismatches = 0;
  for (int k = 0; k < 2000; ++k) {
    const Quat qa = normalize(Quat{uniform(), uniform(), uniform(), uniform()});
    const Quat qb = normalize(Quat{uniform(), uniform(), uniform(), uniform()});
    const Vec3 ca{0.8 * uniform(), 0.8 * uniform(), 0.8 * uniform()};
    const auto box = collide(box_ref(ca, qa, ha), box_ref({0, 0, 0}, qb, hb));
    const auto hull = collide(hull_a.at(ca, qa), hull_b.at({0, 0, 0}, qb));
    contacts += box.n > 0;
    // 1e-9: the two paths sum the same terms in another order; a SAT tie within that
    // would pick another axis, which a random pose meets with probability ~1e-9 (ties
    // in the reduction to four go to the lower index on both paths)
    if (!same_manifold(box, hull, 1e-9)) ++mismatches;
  }
  CHECK(contacts > 1000);
  CHECK(mismatches == 0);
}

// Distance from x to a box (m, 0 inside): the clamped point, exact.
double box_distance(const ShapeRef3& box, Vec3 x) {
  const Vec3 r = x - box.center;
  const double h[3] = {box.half.x, box.half.y, box.half.z};
  double d2 = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double u = dot(r, box.axes[k]);
    const double e = std::fabs(u) - h[k];
    if (e > 0.0) d2 += e * e;
  }
  return std::sqrt(d2);
}

// Random capsules and spheres near a turned box, some apart, some touching (fixed seed):
// whenever the cores are apart, the deepest point's separation is the true distance
// less the radius (the distance by ternary search along the segment: the distance to a
// convex set is convex along a line), and there is a manifold exactly when that is within
// reach. Through both the box and its hull (capsule–box and capsule–convex share the code,
// sphere–box and sphere–convex do not).
TEST(random_rounded_shapes_measure_the_true_distance_to_a_box) {
  Uniform uniform{777};
  const Quat qb = normalize(Quat{0.3, -0.5, 0.7, 0.1});
  const Vec3 half{0.5, 0.3, 0.4};
  const auto box = box_ref({0.1, 0.2, -0.1}, qb, half);
  auto hull = box_as_hull(half);
  const auto convex = hull.at({0.1, 0.2, -0.1}, qb);
  int measured = 0, wrong = 0, wrong_count = 0;
  for (int k = 0; k < 3000; ++k) {
    const Vec3 c{1.0 * uniform(), 1.0 * uniform(), 1.0 * uniform()};
    const Vec3 dir{uniform(), uniform(), uniform()};
    const double len = k % 3 == 0 ? 0.0 : 0.8 * (uniform() + 1.0);  // every third a sphere
    const double r = 0.05 + 0.1 * (uniform() + 1.0);
    const Vec3 p = c - (0.5 * len) * dir, q = c + (0.5 * len) * dir;
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 200; ++it) {
      const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
      if (box_distance(box, p + m1 * (q - p)) <= box_distance(box, p + m2 * (q - p))) hi = m2;
      else lo = m1;
    }
    const double dist = box_distance(box, p + (0.5 * (lo + hi)) * (q - p));
    if (dist < 1e-3) continue;  // the cores touch or overlap: no distance to compare
    const ShapeRef3 shape = len == 0.0 ? sphere_ref(c, r) : capsule_ref(p, q, r);
    for (const ShapeRef3* other : {&box, &convex}) {
      const auto m = collide(shape, *other);
      const bool within = dist - r <= SPEC;
      if ((m.n > 0) != within) {
        ++wrong_count;
        continue;
      }
      if (m.n == 0) continue;
      ++measured;
      double deepest = INFINITY;
      for (int j = 0; j < m.n; ++j) deepest = std::min(deepest, m.m.separation[j]);
      if (std::fabs(deepest - (dist - r)) > 1e-9) ++wrong;  // the search's 1e-12 and round-off
    }
  }
  CHECK(measured > 300);
  CHECK(wrong_count == 0);
  CHECK(wrong == 0);
}

// ---- dispatch, determinism, degenerate input ---------------------------------------------

// Every mirrored pair (b, a) gives the negated normal and the same points and separations.
TEST(mirrored_pairs_negate_the_normal) {
  auto tet = tetrahedron();
  const ShapeRef3 shapes[] = {
      sphere_ref({0.2, 0.55, 0.1}, 0.6),
      box_ref({0.1, 0.45, 0.2}, axis_angle({1, 1, 0}, 0.2), {0.5, 0.3, 0.4}),
      capsule_ref({-0.3, 0.55, 0}, {0.4, 0.6, 0.1}, 0.2),
      tet.at({0.1, 0.3, 0.1}, axis_angle({0, 1, 1}, 0.4)),
      plane_ref({0, 1, 0}, 0.35),
  };
  const ShapeRef3 others[] = {
      sphere_ref({0, 0, 0}, 0.4),
      box_ref({0, -0.1, 0}, {}, {1, 0.5, 1}),
      capsule_ref({-1, 0.2, 0}, {1, 0.2, 0.2}, 0.2),
      box_ref({0, 0, 0}, {}, {0.6, 0.4, 0.6}),
      plane_ref({0, 1, 0}, 0.4),
  };
  int pairs = 0;
  for (const auto& a : shapes)
    for (const auto& b : others) {
      if (a.kind == ShapeKind::Plane && b.kind == ShapeKind::Plane) continue;
      if (a.kind == ShapeKind::Box && b.kind == ShapeKind::Box) continue;  // not swapped (ids by order)
      if (a.kind == b.kind) continue;
      const auto ab = collide(a, b), ba = collide(b, a);
      CHECK(ab.n > 0);
      CHECK(ab.n == ba.n);
      if (ab.n != ba.n) continue;
      CHECK_VEC(ba.m.normal, -ab.m.normal, 0.0, "negated");
      for (int k = 0; k < ab.n; ++k) {
        CHECK(has_point(ba, ab.m.point[k], 0.0));
        CHECK(ba.m.separation[k] == ab.m.separation[k]);
      }
      ++pairs;
    }
  CHECK(pairs == 20);  // 25 less the 5 pairs of one kind
}

// The same input gives the same manifold to the bit, whatever was computed between.
TEST(same_input_same_bits) {
  auto tet = tetrahedron();
  auto hull = box_as_hull({0.5, 0.5, 0.5});
  const ShapeRef3 pairs[][2] = {
      {box_ref({0.1, 0.35, 0.2}, axis_angle({1, 2, 3}, 0.1), {0.5, 0.4, 0.3}), box_ref({0, -0.5, 0}, {}, {3, 0.5, 3})},
      {box_ref({0.1, 1.39, -0.05}, axis_angle({1, 0, 0}, M_PI / 4), {0.5, 0.5, 0.5}), box_ref({0, 0, 0}, axis_angle({0, 0, 1}, M_PI / 4), {0.5, 0.5, 0.5})},
      {capsule_ref({-0.5, 0.59, 0.3}, {0.7, 0.6, 0.3}, 0.1), box_ref({0, 0, 0}, {}, {1, 0.5, 1})},
      {tet.at({0, 0.01, 0}, axis_angle({1, 0, 0}, 0.3)), GROUND},
      {hull.at({0, 0.45, 0}, axis_angle({1, 1, 1}, 0.2)), box_ref({0, -0.5, 0}, {}, {3, 0.5, 3})},
      {sphere_ref({0.3, 0.6, 0.1}, 0.3), capsule_ref({-1, 0.3, 0}, {1, 0.3, 0}, 0.1)},
  };
  std::vector<Result> first;
  for (const auto& p : pairs) first.push_back(collide(p[0], p[1]));
  for (int round = 0; round < 3; ++round)
    for (std::size_t i = 0; i < first.size(); ++i) {
      const auto r = collide(pairs[i][0], pairs[i][1]);
      CHECK(r.n > 0);
      CHECK(same_bits(r, first[i]));
    }
}

// Degenerate input gives finite manifolds: concentric spheres, a sphere centred on a
// capsule's core or at a box's centre, zero-length capsules, coincident parallel capsules,
// crossing capsule cores, a capsule core through a box's centre.
TEST(degenerate_input_gives_no_nan) {
  const auto box = box_ref({0, 0, 0}, {}, {0.5, 0.5, 0.5});
  const auto point_cap = capsule_ref({0.1, 0.1, 0.3}, {0.1, 0.1, 0.3}, 0.2);
  const std::pair<ShapeRef3, ShapeRef3> cases[] = {
      {sphere_ref({1, 2, 3}, 0.3), sphere_ref({1, 2, 3}, 0.5)},
      {sphere_ref({0.3, 0, 0}, 0.1), capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.1)},
      {sphere_ref({0, 0, 0}, 0.1), box},
      {sphere_ref({0.1, 0.1, 0.3}, 0.1), point_cap},
      {point_cap, capsule_ref({0.1, 0.1, 0.3}, {0.1, 0.1, 0.3}, 0.1)},
      {point_cap, capsule_ref({-1, 0.1, 0.3}, {1, 0.1, 0.3}, 0.1)},
      {point_cap, GROUND},
      {point_cap, box},
      {capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.1), capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.1)},
      {capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.1), capsule_ref({0, 0, -1}, {0, 0, 1}, 0.1)},
      {capsule_ref({-1, 0, 0}, {1, 0, 0}, 0.1), box},
      {capsule_ref({0, -1, 0}, {0, 1, 0}, 0.1), box},
      {box, box_ref({0, 0, 0}, {}, {0.5, 0.5, 0.5})},
  };
  // a 2D kind is no 3D shape: no manifold
  ShapeRef3 circle = sphere_ref({0, 0, 0}, 1.0);
  circle.kind = ShapeKind::Circle;
  CHECK(collide(circle, sphere_ref({0, 0, 0}, 1.0)).n == 0);
  CHECK(collide(sphere_ref({0, 0, 0}, 1.0), circle).n == 0);
  for (const auto& [a, b] : cases) {
    const auto r = collide(a, b);
    CHECK(r.n >= 1);
    CHECK(all_finite(r));
    for (int k = 0; k < r.n; ++k) CHECK(r.m.separation[k] < 0.0);
  }
}

// Cost per call (this thread's CPU time: the machine is shared, and wall time counts the
// others' turns): box–box on boxes resting face to face (4 points each, a stack's case)
// and on a pile's mix of tilts (faces, edges, corners), and the other pairs on the same
// tilted poses; each result is checked against the first, so the loop cannot be dropped.
TEST(calls_per_second) {
  const auto ground = box_ref({0, -0.5, 0}, {}, {3, 0.5, 3});
  auto ground_hull = box_as_hull({3, 0.5, 3});
  const auto ground_convex = ground_hull.at({0, -0.5, 0});
  std::vector<ShapeRef3> resting, tilted, spheres, capsules, convex;
  std::vector<WorldHull> hulls(64, box_as_hull({0.5, 0.5, 0.5}));
  for (int k = 0; k < 64; ++k) {
    resting.push_back(box_ref({0.01 * k, 0.499 - 1e-5 * k, -0.005 * k},
                              axis_angle({0, 1, 0}, 0.02 * k), {0.5, 0.5, 0.5}));
    const Vec3 c{0.01 * k, 0.45 + 0.001 * k, -0.005 * k};
    const Quat q = axis_angle({std::sin(k), 1.0, std::cos(k)}, 0.05 * k);
    tilted.push_back(box_ref(c, q, {0.5, 0.5, 0.5}));
    spheres.push_back(sphere_ref(c, 0.495));
    capsules.push_back(capsule_ref(c + rotate(q, {-0.3, -0.2, 0}), c + rotate(q, {0.3, -0.2, 0}), 0.3));
    convex.push_back(hulls[k].at(c, q));
  }
  const auto cpu_ns = [] {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return 1e9 * static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec);
  };
  const auto bench = [&](const std::vector<ShapeRef3>& shapes, const ShapeRef3& other, int rounds,
                         const char* what) {
    std::vector<Result> want;
    for (const auto& b : shapes) want.push_back(collide(b, other));
    int wrong = 0, points = 0;
    const double t0 = cpu_ns();
    for (int r = 0; r < rounds; ++r)
      for (std::size_t i = 0; i < shapes.size(); ++i) {
        Manifold3 m;
        const int n = collide3d(shapes[i], other, SPEC, m);
        points += n;
        wrong += n != want[i].n || (n > 0 && m.separation[0] != want[i].m.separation[0]);
      }
    const double ns = (cpu_ns() - t0) / (rounds * shapes.size());
    CHECK(wrong == 0);
    const double per_call = static_cast<double>(points) / (rounds * shapes.size());
    std::printf("%-22s %5.0f ns per call (%.2f points per call)\n", what, ns, per_call);
    return per_call;
  };
  CHECK(bench(resting, ground, 4000, "box-box resting:") == 4.0);
  CHECK(bench(tilted, ground, 4000, "box-box tilted:") > 1.0);
  CHECK(bench(tilted, GROUND, 4000, "box-plane tilted:") > 1.0);
  CHECK(bench(spheres, ground, 4000, "sphere-box:") > 0.5);
  CHECK(bench(capsules, ground, 1000, "capsule-box:") > 0.5);
  CHECK(bench(convex, ground, 1000, "convex-box (box hull):") > 1.0);
  CHECK(bench(convex, ground_convex, 1000, "convex-convex (boxes):") > 1.0);
}

RBSIM_TEST_MAIN

// A reference face given (3D): a wall (0.2 × 4 × 6 m, its foot at y = 0) and a chip
// 16 × 2 × 10 cm lying 6 cm under its foot and 1.2 cm down. The separating axes take the
// wall's bottom face (the least overlap, 8 mm: a push down); from its +x face (box face
// 1) the chip is pushed out sideways by its 6 cm under the wall, at the four corners of
// its -x end (clipped to the face: the two below the foot move up to it, within the clip
// skin). A sphere gets one point from its centre's foot on the face's plane; a capsule
// its ends' points under the face, or the deeper end beside it.
TEST(a_reference_face_given_pushes_from_it) {
  const auto wall = box_ref({-2.1, 2, 0}, Quat{1, 0, 0, 0}, {0.1, 2, 3});
  const auto chip = box_ref({-1.98, -0.002, 0}, Quat{1, 0, 0, 0}, {0.08, 0.01, 0.05});
  const Result sat = collide(wall, chip);
  CHECK(sat.n == 4);
  CHECK_VEC(sat.m.normal, {0, 1, 0}, EPS, "the axes' choice: the wall's bottom face");
  Result r;
  r.n = collide_on_face(wall, chip, 0, 1, SPEC, r.m);
  CHECK(r.n == 4);
  CHECK_VEC(r.m.normal, {-1, 0, 0}, EPS, "b -> a: the chip pushed along +x");
  for (int k = 0; k < r.n; ++k) {
    CHECK_NEAR(r.m.separation[k], -0.06, EPS);
    CHECK_NEAR(r.m.point[k].x, -2.03, EPS);
    CHECK(r.m.point[k].y > -SKIN - EPS && r.m.point[k].y < 0.008 + EPS);
  }
  Result q;
  q.n = collide_on_face(chip, wall, 1, 1, SPEC, q.m);
  CHECK(q.n == 4);
  CHECK_VEC(q.m.normal, {1, 0, 0}, EPS, "mirrored: negated");
  Result s;
  s.n = collide_on_face(sphere_ref({-1.96, 0.01, 0.5}, 0.03), wall, 1, 1, SPEC, s.m);
  CHECK(s.n == 1);
  CHECK_VEC(s.m.normal, {1, 0, 0}, EPS, "the face's normal");
  CHECK_NEAR(s.m.separation[0], 0.01, EPS);
  CHECK_VEC(s.m.point[0], {-1.995, 0.01, 0.5}, EPS, "midway in the gap");
  CHECK(collide_on_face(sphere_ref({-1.9, 0.01, 0.5}, 0.03), wall, 1, 1, SPEC, s.m) == 0);
  Result c;
  c.n = collide_on_face(capsule_ref({-2.05, 0.005, -0.05}, {-2.05, 0.005, 0.05}, 0.01), wall,
                        1, 1, SPEC, c.m);
  CHECK(c.n == 2);
  CHECK_VEC(c.m.normal, {1, 0, 0}, EPS, "the face's normal");
  CHECK_NEAR(c.m.separation[0], -0.06, EPS);
  CHECK_NEAR(c.m.separation[1], -0.06, EPS);
  Result e;  // (its segment beside the face, below the foot: the deeper end)
  e.n = collide_on_face(capsule_ref({-2.05, -0.02, 0}, {-1.95, -0.03, 0}, 0.01), wall, 1, 1,
                        SPEC, e.m);
  CHECK(e.n == 1);
  CHECK_VEC(e.m.normal, {1, 0, 0}, EPS, "the face's normal");
  CHECK_NEAR(e.m.separation[0], -0.06, EPS);
}
