// collide/transform.cpp: world geometry of every shape, its speculative reach, and which
// bodies are still near their reference pose.
#include <cmath>

#include "check.hpp"
#include "rbsim/constants.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {
constexpr double EPS = 1e-14;  // m: round-off of O(1) coordinates
}

// A turned, moved box: each world vertex is x + R(θ) l, each world normal R(θ) n.
TEST(world_vertices_are_body_vertices_turned_and_moved) {
  SceneBuilder s;
  s.ground();
  const double angle = 0.3;
  const int b = s.box({1.5, 2.0}, 0.5, 0.25, 1.0, {}, angle);
  World<2>& w = s.finish();
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  const Rot2 q{std::cos(angle), std::sin(angle)};
  const int k0 = w.model.shape_vstart[b];
  for (int k = k0; k < k0 + 4; ++k) {
    const Vec2 want = Vec2{1.5, 2.0} + rotate(q, w.model.vertex_local[k]);
    CHECK_NEAR(w.contacts.vert_world[k].x, want.x, EPS);
    CHECK_NEAR(w.contacts.vert_world[k].y, want.y, EPS);
    const Vec2 n = rotate(q, w.model.normal_local[k]);
    CHECK_NEAR(w.contacts.norm_world[k].x, n.x, EPS);
    CHECK_NEAR(w.contacts.norm_world[k].y, n.y, EPS);
  }
  // the first edge's normal is the bottom face's, -y turned by θ
  CHECK_NEAR(w.contacts.norm_world[k0].x, std::sin(angle), EPS);
  CHECK_NEAR(w.contacts.norm_world[k0].y, -std::cos(angle), EPS);
}

// The reach is how far the surface can move in a step, dt (|v| + |ω| r_max), r_max the
// farthest core vertex: a circle turning about its centre moves its surface by its
// centre's motion only; a static shape has none.
TEST(speculative_reach_is_dt_times_surface_speed) {
  SceneBuilder s;
  const int g = s.ground();
  const int ball = s.circle({0, 3}, 0.25, 1.0, {}, {3.0, -4.0}, 2.0);
  const int box = s.box({2, 3}, 0.3, 0.4, 1.0, {}, 0.0, {0.0, 1.0}, -10.0);
  World<2>& w = s.finish(0.01);
  transform_shapes(w.model, w.state, w.contacts, w.config.dt);
  CHECK(w.contacts.shape_margin[g] == 0.0);
  CHECK_NEAR(w.contacts.shape_margin[ball], 0.01 * 5.0, EPS);  // its spin moves no surface
  CHECK_NEAR(w.contacts.shape_margin[box], 0.01 * (1.0 + 10.0 * 0.5), EPS);  // corner at 0.5 m
}

// A body is still while within STILL_DISTANCE and STILL_ANGLE of the pose it had when it
// last moved; one that leaves it takes its new pose as the reference.
TEST(body_is_still_only_near_its_reference_pose) {
  SceneBuilder s;
  s.ground();
  const int b = s.box({0, 0.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(!c.body_still[b]);  // no reference pose yet (NaN)
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(c.body_still[b]);
  w.state.body_x[b].x += 0.5 * constants::STILL_DISTANCE;
  w.state.body_angle[b] += 0.5 * constants::STILL_ANGLE;
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(c.body_still[b]);
  CHECK(c.body_ref[b].x.x == 0.0);  // the reference did not follow
  w.state.body_x[b].x += constants::STILL_DISTANCE;  // 1.5 STILL_DISTANCE from it
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(!c.body_still[b]);
  CHECK(c.body_ref[b].x.x == w.state.body_x[b].x);  // re-taken
  w.state.body_angle[b] += 2.0 * constants::STILL_ANGLE;  // turning alone also counts
  transform_shapes(w.model, w.state, c, w.config.dt);
  CHECK(!c.body_still[b]);
}

RBSIM_TEST_MAIN
