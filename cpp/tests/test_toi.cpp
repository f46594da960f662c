// collide/toi.cpp: conservative advancement to the moment of impact.
#include <cmath>

#include "check.hpp"
#include "collide/toi.hpp"
#include "rbsim/constants.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {

struct Hit {
  Impact impact;
  Manifold2 m;
  int start_points;
};

// The speculative manifold of shapes a < b at the step's start, moved to the impact.
Hit search(World<2>& w, int a, int b) {
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  const auto& m = w.model;
  const double spec = constants::SPECULATIVE_DISTANCE + c.shape_margin[a] + c.shape_margin[b];
  const ShapeRef2 sa{m.shape_kind[a], m.shape_vstart[a], m.shape_vcount[a], m.shape_radius[a]};
  const ShapeRef2 sb{m.shape_kind[b], m.shape_vstart[b], m.shape_vcount[b], m.shape_radius[b]};
  Hit h{};
  h.start_points = collide2d(sa, sb, c.vert_world.data(), c.norm_world.data(), spec, h.m);
  h.impact = time_of_impact(m, w.state, a, b, h.start_points, w.config.dt, spec, 1.0,
                            c.toi_verts.data(), c.toi_norms.data(), h.m);
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
    const Impact hit = time_of_impact(m, w.state, 0, 1, 1, w.config.dt, 1.0, 1.0, c.toi_verts.data(),
                                      c.toi_norms.data(), out);
    CHECK(hit.t == 0.0 && hit.points == 1);
    CHECK_NEAR(out.separation[0], 0.5, 1e-15);
  }
}

RBSIM_TEST_MAIN
