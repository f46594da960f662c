// collide/toi.cpp: conservative advancement to the moment of impact.
#include <cmath>

#include "check.hpp"
#include "collide/toi.hpp"
#include "rbsim/constants.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {

// time_of_impact with room of its own (ToiRoom)
template <int D, class Manifold>
Impact toi(const Model<D>& m, const State<D>& st, int a, int b, int npts, double dt,
           double spec, double scale, Manifold& out, bool bounded = D == 3) {
  ToiRoom<D> room(m.vertex_count());
  return time_of_impact(m, st, a, b, npts, dt, spec, scale, room.verts.data(),
                        room.norms.data(), out, bounded);
}

struct Hit {
  Impact impact;
  Manifold2 m;
  int start_points;
};

// The speculative manifold of shapes a < b at the step's start, moved to the impact
// (bounded: by the bound on any point's approach, as the engine's narrowphase and sweep).
Hit search(World<2>& w, int a, int b, bool bounded = false) {
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  const auto& m = w.model;
  const double spec = constants::SPECULATIVE_DISTANCE + c.shape_margin[a] + c.shape_margin[b];
  const ShapeRef2 sa{m.shape_kind[a], m.shape_vstart[a], m.shape_vcount[a], m.shape_radius[a]};
  const ShapeRef2 sb{m.shape_kind[b], m.shape_vstart[b], m.shape_vcount[b], m.shape_radius[b]};
  Hit h{};
  h.start_points = collide2d(sa, sb, c.vert_world.data(), c.norm_world.data(), spec, h.m);
  h.impact = toi(m, w.state, a, b, h.start_points, w.config.dt, spec, 1.0, h.m, bounded);
  return h;
}

}  // namespace

// A ball falling at 60 m/s, 0.5 m above a static box: it meets the face after 0.5/60 s,
// where the manifold has zero separation.
TEST(fast_ball_meets_box_at_gap_over_speed) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0.0, -0.5}, 2.0, 0.5, 0.0);
  s.circle({0.0, 0.75}, 0.25, 1.0, {}, {0.0, -60.0});
  World<2>& w = s.finish();
  const Hit h = search(w, 0, 1);
  CHECK(h.start_points == 1);
  CHECK(h.impact.points == 1);
  CHECK_NEAR(h.impact.t, 0.5 / 60.0, 1e-9 / 60.0);  // s: to TOI_TOLERANCE over the speed
  CHECK(std::fabs(h.m.separation[0]) <= 1e-9);
  CHECK_NEAR(h.m.normal.y, -1.0, 1e-15);  // from the ball (b) to the box (a)
}

// A glancing approach: ball a at 60 m/s passes 15 cm off ball b's centre (radii 0.1 m).
// The normal at the impact is the line of centres then, not at the step's start.
TEST(glancing_impact_takes_the_normal_at_impact) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.circle({0.0, 0.0}, 0.1, 1.0, {}, {60.0, 0.0});
  s.circle({0.5, 0.15}, 0.1, 1.0);
  World<2>& w = s.finish();
  const Hit h = search(w, 0, 1);
  CHECK(h.impact.points == 1);
  const double dx = std::sqrt(0.2 * 0.2 - 0.15 * 0.15);  // m: centres' x distance at impact
  const double t = (0.5 - dx) / 60.0;
  CHECK_NEAR(h.impact.t, t, 1e-9);  // s: the search stops within 1e-9 m
  CHECK_NEAR(h.m.normal.x, -dx / 0.2, 1e-7);  // from b towards a
  CHECK_NEAR(h.m.normal.y, -0.15 / 0.2, 1e-7);
}

// A plank 60 cm long at 50 m/s, turning at 106 rad/s (1.8 rad in the step), 0.5 m from a
// static wall 5 cm thick: by the bound on any point's approach (|ω| times the plank's
// reach) the search stops where a corner touches the near face, from the plank's side.
// By the nearest point's own approach it passed the impact, and a capsule so thrown was
// found on the far side of the wall (tests/test_continuous.py).
TEST(plank_turning_fast_meets_a_thin_wall_from_its_own_side) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0.8, 0.0}, 0.025, 2.0, 0.0);  // near face x = 0.775
  s.box({0.0, 0.0}, 0.3, 0.02, 1.0, {}, 2.0, {50.0, 0.0}, -105.8);
  World<2>& w = s.finish();
  w.contacts.shape_margin[1] = 1.0;  // (the speculative reach of a fast body)
  const Hit h = search(w, 0, 1, true);
  CHECK(h.start_points > 0);
  CHECK(h.impact.points > 0 && h.impact.t < w.config.dt);
  CHECK(h.m.normal.x > 0.99);  // from the plank (b) towards the wall (a)
  CHECK(std::fabs(h.m.separation[nearest_point(h.m, h.impact.points)]) < 1e-6);  // m
  // the plank's corners at t, none past the near face
  const double t = h.impact.t;
  const double angle = 2.0 - 105.8 * t;
  const double reach = std::fabs(0.3 * std::cos(angle)) + std::fabs(0.02 * std::sin(angle));
  CHECK(50.0 * t + reach <= 0.775 + 1e-6);  // m
  CHECK(50.0 * t + reach >= 0.775 - 1e-6);  // and one on it
}

// A separating pair, or one that will not meet within the step, stays at t = 0.
TEST(separating_or_slow_pair_stays_at_start) {
  for (const double vy : {+5.0, -1.0}) {  // leaving; closing 0.5 m at 1 m/s: not this step
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    s.box({0.0, -0.5}, 2.0, 0.5, 0.0);
    s.circle({0.0, 0.75}, 0.25, 1.0, {}, {0.0, vy});
    World<2>& w = s.finish(1.0 / 60.0, 4);
    // a speculative distance long enough for the pair to have a manifold at all
    w.contacts.shape_margin[1] = 1.0;
    auto& c = w.contacts;
    transform_shapes(w.model, w.state, c, w.config.dt);
    const auto& m = w.model;
    Manifold2 out{};
    const ShapeRef2 sa{m.shape_kind[0], m.shape_vstart[0], m.shape_vcount[0], 0.0};
    const ShapeRef2 sb{m.shape_kind[1], m.shape_vstart[1], 1, 0.25};
    CHECK(collide2d(sa, sb, c.vert_world.data(), c.norm_world.data(), 1.0, out) == 1);
    const Impact hit = toi(m, w.state, 0, 1, 1, w.config.dt, 1.0, 1.0, out);
    CHECK(hit.t == 0.0 && hit.points == 1);
    CHECK_NEAR(out.separation[0], 0.5, 1e-15);
  }
}

// Two balls whose free paths pass 1.06 m apart (1.26 m between centres): a at 500 m/s
// along x, b 4 m above it at (400, −300) m/s. At the step's start b closes on a at
// 300 m/s, 4 m in 13 ms, so the search runs; it finds them separating where they pass,
// far clear of each other: no manifold. (The manifold where they pass, its plane running
// through both starts, held a ball stopped by a wall to the other body's x; the one of
// the step's start, normal along y and 3.8 m apart, is a plane b's free path crosses
// 13 ms on, 1.06 m from a, where the solver stopped it.)
TEST(pair_whose_paths_pass_clear_has_no_manifold) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.circle({0.0, 0.0}, 0.1, 1.0, {}, {500.0, 0.0});
  s.circle({0.0, 4.0}, 0.1, 1.0, {}, {400.0, -300.0});
  World<2>& w = s.finish(1.0 / 60.0, 4);
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  const auto& m = w.model;
  const double spec = 6.0;  // m: the pair's relative move in the step, 5.3 m, and more
  const ShapeRef2 sa{m.shape_kind[0], m.shape_vstart[0], 1, 0.1};
  const ShapeRef2 sb{m.shape_kind[1], m.shape_vstart[1], 1, 0.1};
  Manifold2 out{};
  CHECK(collide2d(sa, sb, c.vert_world.data(), c.norm_world.data(), spec, out) == 1);
  CHECK(meets_within(out, 1, 0, 1, w.config.dt, constants::LINEAR_SLOP, w.state));
  const Impact hit = toi(m, w.state, 0, 1, 1, w.config.dt, spec, 1.0, out);
  CHECK(hit.points == 0);
  // and stepped, neither ball is touched
  w.step();
  CHECK(w.state.body_v[0].x == 500.0 && w.state.body_v[0].y == 0.0);
  CHECK(w.state.body_v[1].x == 400.0 && w.state.body_v[1].y == -300.0);
}

// ---- 3D ---------------------------------------------------------------------------------

namespace {

struct Hit3 {
  Impact impact;
  Manifold3 m;
  int start_points;
};

// The speculative manifold of shapes a < b at the step's start (their world geometry from
// the transform stage, as update_manifolds reads it), moved to the impact.
Hit3 search3(World<3>& w, int a, int b) {
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  const auto& m = w.model;
  const double spec = constants::SPECULATIVE_DISTANCE + c.shape_margin[a] + c.shape_margin[b];
  auto world = [&](int s) {
    const int k = m.shape_vstart[s];
    const Vec3* faces = m.shape_kind[s] == ShapeKind::Plane ? c.norm_world.data() + k
                                                            : c.face_world.data() + m.shape_hface[s];
    return shape_ref(m, s, c.vert_world.data() + k, faces, 1.0);
  };
  Hit3 h{};
  h.start_points = collide3d(world(a), world(b), spec, h.m);
  h.impact = toi(m, w.state, a, b, h.start_points, w.config.dt, spec, 1.0, h.m);
  return h;
}

double smallest_separation(const Hit3& h) {
  double s = h.m.separation[0];
  for (int k = 1; k < h.impact.points; ++k) s = std::min(s, h.m.separation[k]);
  return s;
}

Quat about(Vec3 axis, double angle) {
  const Vec3 u = (1.0 / length(axis)) * axis;
  const double s = std::sin(0.5 * angle);
  return {std::cos(0.5 * angle), s * u.x, s * u.y, s * u.z};
}

}  // namespace

// Every 3D kind that moves (sphere, capsule, box, convex hull), falling at 60 m/s with its
// lowest point 0.5 m above a static plane and above a static box: it touches after
// 0.5/60 s, where the manifold has zero separation and the face's normal.
TEST(each_3d_kind_meets_plane_and_box_at_gap_over_speed) {
  const std::vector<Vec3> octa{{0.3, 0, 0}, {-0.3, 0, 0}, {0, 0.3, 0},
                               {0, -0.3, 0}, {0, 0, 0.3}, {0, 0, -0.3}};
  const std::vector<std::array<std::int32_t, 3>> tris{{{0, 2, 4}}, {{2, 1, 4}}, {{1, 3, 4}},
                                                      {{3, 0, 4}}, {{2, 0, 5}}, {{1, 2, 5}},
                                                      {{3, 1, 5}}, {{0, 3, 5}}};
  for (const bool onto_box : {false, true}) {
    for (int kind = 0; kind < 4; ++kind) {
      SceneBuilder3 s;
      s.world.model.gravity = {0.0, 0.0, 0.0};
      if (onto_box)
        s.box({0.0, -1.0, 0.0}, {2.0, 1.0, 2.0}, 0.0);  // its top face at y = 0
      else
        s.plane({0.0, 1.0, 0.0}, 0.0);
      int body = 0;
      switch (kind) {
        case 0: body = s.sphere({0.0, 0.75, 0.0}, 0.25, 1.0); break;  // lowest point 0.5
        case 1: body = s.capsule({0.0, 0.6, 0.0}, {-0.3, 0, 0}, {0.3, 0, 0}, 0.1, 1.0); break;
        case 2: body = s.box({0.0, 0.6, 0.0}, {0.3, 0.1, 0.2}, 1.0); break;
        default: body = s.convex({0.0, 0.8, 0.0}, octa, tris, 1.0); break;
      }
      World<3>& w = s.finish();
      w.state.body_v[body] = {0.0, -60.0, 0.0};
      const Hit3 h = search3(w, 0, 1);
      CHECK(h.start_points >= 1);
      CHECK(h.impact.points >= 1);
      CHECK_NEAR(h.impact.t, 0.5 / 60.0, 1e-9 / 60.0);  // s: to TOI_TOLERANCE over the speed
      CHECK(std::fabs(smallest_separation(h)) <= 1e-9);
      // from the falling shape (b) to the ground (a), which a plane or box face gives
      CHECK_NEAR(h.m.normal.y, -1.0, 1e-15);
    }
  }
}

// Two faces parallel: a box falling flat onto a static box meets it on its whole face,
// four points at the same zero separation, at gap / speed.
TEST(parallel_faces_meet_on_four_points_at_once) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  s.box({0.0, -0.5, 0.0}, {2.0, 0.5, 2.0}, 0.0);
  s.box({0.3, 0.9, -0.2}, {0.5, 0.5, 0.5}, 1.0, {}, {}, {0.0, -40.0, 0.0});  // 0.4 m above
  World<3>& w = s.finish();
  const Hit3 h = search3(w, 0, 1);
  CHECK(h.start_points == 4);
  CHECK(h.impact.points == 4);
  CHECK_NEAR(h.impact.t, 0.4 / 40.0, 1e-9 / 40.0);  // s
  for (int k = 0; k < 4; ++k) CHECK(std::fabs(h.m.separation[k]) <= 1e-9);
  CHECK_NEAR(h.m.normal.y, -1.0, 1e-15);
}

// A glancing approach in space: sphere a at 60 m/s along x passes 15 cm off sphere b's
// centre, along a line turned out of every axis plane (radii 0.1 m). The normal at the
// impact is the line of centres then, not at the step's start.
TEST(glancing_spheres_take_the_normal_at_impact) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  const Vec3 off = (0.15 / std::sqrt(2.0)) * Vec3{0.0, 1.0, 1.0};  // 15 cm off the line
  s.sphere({0.0, 0.0, 0.0}, 0.1, 1.0, {}, {60.0, 0.0, 0.0});
  s.sphere(Vec3{0.5, 0.0, 0.0} + off, 0.1, 1.0);
  World<3>& w = s.finish();
  const Hit3 h = search3(w, 0, 1);
  CHECK(h.impact.points == 1);
  const double dx = std::sqrt(0.2 * 0.2 - 0.15 * 0.15);  // m: centres' x distance at impact
  CHECK_NEAR(h.impact.t, (0.5 - dx) / 60.0, 1e-9);  // s: the search stops within 1e-9 m
  const Vec3 want = (1.0 / 0.2) * (Vec3{-dx, 0.0, 0.0} - off);  // from b towards a
  CHECK(length(h.m.normal - want) < 1e-7);  // the line of centres, to the search's 1e-9 m
}

// Grazing: a sphere that passes 1 cm clear of a box's edge never touches it; the search
// follows it to its closest approach and leaves it apart there (a positive separation,
// never an overlap), with the normal turned from the face's towards the edge's.
TEST(grazing_sphere_stays_apart_at_its_closest_approach) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  s.box({1.05, -1.0, 0.0}, {0.05, 1.0, 1.0}, 0.0);  // a wall, its top edge at y = 0, x = 1
  s.sphere({0.0, 0.06, 0.0}, 0.05, 1.0, {}, {120.0, 0.0, 0.0});  // its bottom 1 cm above
  World<3>& w = s.finish(1.0 / 60.0, 4);
  const Hit3 h = search3(w, 0, 1);
  CHECK(h.impact.points == 1);
  CHECK(smallest_separation(h) > 0.0099);  // m: never closer than its 1 cm of clearance
  CHECK(h.m.normal.y < -0.5);  // from the sphere (b) to the wall (a): turned to the edge's
  CHECK(h.impact.t > 0.0 && h.impact.t <= w.config.dt);
}

// A turning box: the plank of tunnel_plank_3d (4 m x 0.1 m x 0.5 m, 100 m/s, 50 rad/s
// about z) as it is 1.67 m from the wall, turned 4.17 rad. The corner nearest the wall
// at the step's start (0.56 m away, closing at 17 m/s) is not the one that hits: the far
// end swings in at 186 m/s from 2.7 m. The pair is taken to the search, which finds the
// first time any corner reaches the wall, as a fine scan of the corners' true (turning)
// paths does; the manifold there has that corner at zero separation.
TEST(rotating_box_meets_the_wall_with_the_corner_that_swings_in) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  const double wall = 1.0 / 0.6;  // m: the wall's near face, x
  s.box({wall + 0.05, 0.0, 0.0}, {0.05, 20.0, 20.0}, 0.0);
  const Vec3 h{2.0, 0.05, 0.25};
  const Quat q0 = about({0.0, 0.0, 1.0}, 50.0 * 5.0 / 60.0);
  const Vec3 v{100.0, 0.0, 0.0}, om{0.0, 0.0, 50.0};
  s.box({0.0, 0.0, 0.0}, h, 1.0, {}, q0, v, om);
  World<3>& w = s.finish(1.0 / 60.0, 4);
  // the corners' largest x at time t on their true paths: v t + R(ω t) R0 corner
  auto front = [&](double t) {
    const Quat q = mul(about(om, length(om) * t), q0);
    double x = -1e9;
    for (int k = 0; k < 8; ++k) {
      const Vec3 c{k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z};
      x = std::max(x, (t * v + rotate(q, c)).x);
    }
    return x;
  };
  double lo = 0.0, hi = w.config.dt;
  CHECK(front(hi) > wall);  // it does reach the wall within the step
  for (double t = 0.0; t < w.config.dt; t += 1e-6) {  // the first crossing, then bisect
    if (front(t) >= wall) {
      hi = t;
      break;
    }
    lo = t;
  }
  for (int i = 0; i < 60; ++i) (front(0.5 * (lo + hi)) >= wall ? hi : lo) = 0.5 * (lo + hi);
  const Hit3 hit = search3(w, 0, 1);
  CHECK(hit.start_points >= 2);
  CHECK(hit.impact.points >= 1);
  // the corners' speed along x is at most 100 + 50 · 2.02 m/s: a separation of 1e-6 m
  // (TOI_FINISH) is at most 5e-9 s
  CHECK_NEAR(hit.impact.t, hi, 5e-9);
  CHECK(std::fabs(smallest_separation(hit)) < 1e-6);
  CHECK_NEAR(hit.m.normal.x, 1.0, 1e-15);  // from the plank (b) to the wall (a)
}

// A cube spinning fast about the normal of the wall it drifts into (30 rad/s about x,
// 1 m/s along x, its face parallel to the wall's, 1 cm off): its turn moves no point
// towards the wall, and the search's bound on the closing speed is the drift alone, so
// that it reaches the impact, 1 cm / 1 m/s, to its tolerance. (Bounded by |ω| ρ, six
// times the drift, each advancement closed a sixth of the gap, and 12 of them left
// 1.2 mm.)
TEST(cube_spinning_about_the_normal_reaches_the_impact) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  s.box({0.2 + 0.05, 0.0, 0.0}, {0.05, 2.0, 2.0}, 0.0);  // the wall's face at x = 0.2
  s.box({0.09, 0.0, 0.0}, {0.1, 0.1, 0.1}, 1.0, {}, {}, {1.0, 0.0, 0.0}, {30.0, 0.0, 0.0});
  World<3>& w = s.finish(1.0 / 60.0, 4);
  const Hit3 hit = search3(w, 0, 1);
  CHECK(hit.start_points == 4);
  CHECK(hit.impact.points == 4);
  CHECK_NEAR(hit.impact.t, 0.01, 2e-9);  // s: the gap over the speed, to TOI_TOLERANCE
  CHECK(std::fabs(smallest_separation(hit)) <= 1e-9);
  CHECK_NEAR(hit.m.normal.x, 1.0, 1e-12);
}

// A box tumbling onto the ground (1 m/s down, 10 rad/s about z, a corner 1 cm up): the
// bound on the closing speed, 1 + 10 · 0.17 m/s, is about twice the corner's true one,
// and the advancements alone, each halving the gap, ran out 12 calls short of the
// tolerance. The trial steps reach the first time a corner touches, as a fine scan of
// the corners' true (turning) paths finds it, to the search's tolerance.
TEST(tumbling_box_reaches_the_impact_with_trial_steps) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  s.box({0.0, -0.5, 0.0}, {2.0, 0.5, 2.0}, 0.0);  // the ground's top at y = 0
  const Vec3 h{0.1, 0.1, 0.1}, v{0.0, -1.0, 0.0}, om{0.0, 0.0, 10.0};
  const Quat q0 = about({0.0, 0.0, 1.0}, 0.3);
  double low = 0.0;  // m: the lowest corner below the centre at the start
  for (int k = 0; k < 8; ++k)
    low = std::min(low, rotate(q0, {k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z}).y);
  const double y0 = 0.01 - low;  // m: the centre, its lowest corner 1 cm up
  s.box({0.0, y0, 0.0}, h, 1.0, {}, q0, v, om);
  World<3>& w = s.finish(1.0 / 60.0, 4);
  auto bottom = [&](double t) {  // the corners' lowest y at time t on their true paths
    const Quat q = mul(about(om, length(om) * t), q0);
    double y = 1e9;
    for (int k = 0; k < 8; ++k) {
      const Vec3 c{k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z};
      y = std::min(y, y0 + t * v.y + rotate(q, c).y);
    }
    return y;
  };
  double lo = 0.0, hi = w.config.dt;
  CHECK(bottom(hi) < 0.0);  // it lands within the step
  for (double t = 0.0; t < w.config.dt; t += 1e-6) {  // the first crossing, then bisect
    if (bottom(t) <= 0.0) {
      hi = t;
      break;
    }
    lo = t;
  }
  for (int i = 0; i < 60; ++i) (bottom(0.5 * (lo + hi)) <= 0.0 ? hi : lo) = 0.5 * (lo + hi);
  const Hit3 hit = search3(w, 0, 1);
  CHECK(hit.impact.points >= 1);
  CHECK(std::fabs(smallest_separation(hit)) <= 1e-9);
  // the corners close at most 1 + 10 · 0.17 m/s: 1e-9 m of gap is at most 1e-9 s
  CHECK_NEAR(hit.impact.t, hi, 2e-9);
}

// The same plank's speculative manifold at the step's start asks for the search, though
// its nearest point at its own speed would not meet within the step: the search's bound
// on the closing speed takes in the turn.
TEST(spinning_plank_meets_within_the_step_by_the_bound_on_its_turn) {
  SceneBuilder3 s;
  s.world.model.gravity = {0.0, 0.0, 0.0};
  const double wall = 1.0 / 0.6;  // m
  s.box({wall + 0.05, 0.0, 0.0}, {0.05, 20.0, 20.0}, 0.0);
  s.box({0.0, 0.0, 0.0}, {2.0, 0.05, 0.25}, 1.0, {}, about({0.0, 0.0, 1.0}, 50.0 * 5.0 / 60.0),
        {100.0, 0.0, 0.0}, {0.0, 0.0, 50.0});
  World<3>& w = s.finish(1.0 / 60.0, 4);
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  const auto& m = w.model;
  const double spec = constants::SPECULATIVE_DISTANCE + c.shape_margin[0] + c.shape_margin[1];
  Manifold3 out{};
  const int n = collide3d(shape_ref(m, 0, c.vert_world.data(), c.face_world.data(), 1.0),
                          shape_ref(m, 1, c.vert_world.data() + 8, c.face_world.data(), 1.0),
                          spec, out);
  CHECK(n == 4);
  const double dt = w.config.dt;
  const Approach nearest = point_approach(out, nearest_point(out, n), 0, 1, 0.0, w.state);
  CHECK(nearest.vn < 0.0 && nearest.sep / -nearest.vn > dt);  // by it: not this step
  const double reach = core_reach(m, 1);  // m: the plank's corners, 2.02 m out
  CHECK_NEAR(reach, std::sqrt(2.0 * 2.0 + 0.05 * 0.05 + 0.25 * 0.25), 1e-15);
  // the search's bound: 100 m/s along the normal and 50 rad/s over 2.02 m
  const Approach bound = search_approach(out, n, 0, 1, 0.0, w.state, 0.0, reach);
  CHECK_NEAR(-bound.vn, 100.0 + 50.0 * reach, 1e-12);
  CHECK(bound.sep == nearest.sep);  // it advances by the gap
  CHECK(meets_within(out, n, 0, 1, dt, constants::LINEAR_SLOP, w.state, 0.0, reach));
}

// A 3D pair that separates, or will not meet within the step, stays at t = 0.
TEST(separating_or_slow_3d_pair_stays_at_start) {
  for (const double vy : {+5.0, -1.0}) {  // leaving; closing 0.5 m at 1 m/s: not this step
    SceneBuilder3 s;
    s.world.model.gravity = {0.0, 0.0, 0.0};
    s.box({0.0, -0.5, 0.0}, {2.0, 0.5, 2.0}, 0.0);
    s.sphere({0.0, 0.75, 0.0}, 0.25, 1.0, {}, {0.0, vy, 0.0});
    World<3>& w = s.finish(1.0 / 60.0, 4);
    auto& c = w.contacts;
    transform_shapes(w.model, w.state, c, w.config.dt);
    const auto& m = w.model;
    Manifold3 out{};
    const ShapeRef3 box = shape_ref(m, 0, c.vert_world.data(), c.face_world.data(), 1.0);
    const ShapeRef3 ball = shape_ref(m, 1, c.vert_world.data() + 8, c.face_world.data(), 1.0);
    CHECK(collide3d(box, ball, 1.0, out) == 1);  // a speculative distance long enough
    CHECK(!meets_within(out, 1, 0, 1, w.config.dt, constants::LINEAR_SLOP, w.state));
    const Impact hit = toi(m, w.state, 0, 1, 1, w.config.dt, 1.0, 1.0, out);
    CHECK(hit.t == 0.0 && hit.points == 1);
    CHECK_NEAR(out.separation[0], 0.5, 1e-15);
  }
}

// The rotation by a rotation vector: |a| about a / |a|, and exactly the identity for 0.
TEST(turn_by_a_rotation_vector) {
  const Quat id = turn_by(Vec3{});
  CHECK(id.w == 1.0 && id.x == 0.0 && id.y == 0.0 && id.z == 0.0);
  const Vec3 a{0.3, -0.4, 1.2};  // rad
  const Quat q = turn_by(a);
  const Quat want = about(a, length(a));
  CHECK_NEAR(q.w, want.w, 1e-15);
  CHECK_NEAR(q.x, want.x, 1e-15);
  CHECK_NEAR(q.y, want.y, 1e-15);
  CHECK_NEAR(q.z, want.z, 1e-15);
}

RBSIM_TEST_MAIN
