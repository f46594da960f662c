// contact/manifold.cpp: warm-start matching by feature id, carried manifolds of still
// bodies, and the pair's mixed coefficients.
#include <cmath>
#include <utility>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <cstring>
#include <set>
#include <type_traits>

#include "check.hpp"
#include "contact/pair.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

// A unit box of 1 kg resting on the ground plane y = 0 (3D): the world, its body in `box`.
inline World<3>& box_on_plane(SceneBuilder3& s, int& box) {
  s.plane({0.0, 1.0, 0.0}, 0.0);
  box = s.box({0.0, 0.5, 0.0}, {0.5, 0.5, 0.5}, 1.0);
  return s.finish();
}

// A box on the ground, its last step's points listed in the other order and one id
// unknown: each point takes the impulses of last step's point with its feature id, and
// a point whose id was not there starts from zero.
TEST(warm_start_matches_points_by_feature_id) {
  SceneBuilder s;
  s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  CHECK(c.count.manifolds == 1 && c.points[0] == 2);
  const std::int64_t id0 = c.feature[0][0], id1 = c.feature[0][1];
  CHECK(id0 != id1);
  c.normal_impulse[0] = {1.0, 2.0};
  c.tangent_impulse[0] = {0.1, 0.2};
  store_impulses(c);
  // last step's points in the other order
  std::swap(c.prev_feature[0][0], c.prev_feature[0][1]);
  std::swap(c.prev_normal_impulse[0][0], c.prev_normal_impulse[0][1]);
  std::swap(c.prev_tangent_impulse[0][0], c.prev_tangent_impulse[0][1]);
  w.state.body_x[box].x += 1e-3;  // moved: the narrowphase runs again, same features
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 0);
  CHECK(c.feature[0][0] == id0 && c.feature[0][1] == id1);
  CHECK(c.normal_impulse[0][0] == 1.0 && c.normal_impulse[0][1] == 2.0);
  CHECK(c.tangent_impulse[0][0] == 0.1 && c.tangent_impulse[0][1] == 0.2);
  CHECK(c.start_impulse[0][0] == 1.0);
  // an id last step did not have
  store_impulses(c);
  c.prev_feature[0][1] = -5;
  w.state.body_x[box].x += 1e-3;
  rbsim::test::collide(w);
  CHECK(c.normal_impulse[0][0] == 1.0);
  CHECK(c.normal_impulse[0][1] == 0.0 && c.tangent_impulse[0][1] == 0.0);
}

// A pair of bodies that has moved less than STILL_DISTANCE one against the other since its
// manifold was found, neither turned, keeps last step's manifold: the same points and
// impulses, marked carried, the separation moved by their relative motion.
TEST(still_bodies_carry_their_manifold_with_separation_moved) {
  SceneBuilder s;
  s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);  // finds the manifold: its offset and rotations
  c.normal_impulse[0] = {1.0, 2.0};
  store_impulses(c);
  auto separation = [&](int k) {
    return c.base_separation[0][k] + dot(c.normal[0], c.anchor_a[0][k] - c.anchor_b[0][k]);
  };
  const double sep0 = separation(0), sep1 = separation(1);
  const Vec2 n0 = c.normal[0];
  const double dy = -0.5 * constants::STILL_DISTANCE;  // m: sinks a little
  w.state.body_x[box].y += dy;
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 1);
  CHECK(c.normal[0].x == n0.x && c.normal[0].y == n0.y);
  CHECK(c.normal_impulse[0][0] == 1.0 && c.start_impulse[0][1] == 2.0);
  // the box is shape... body a or b: the normal from b to a is +y when the box is a
  const double sign = c.body_a[0] == box ? 1.0 : -1.0;
  CHECK_NEAR(separation(0), sep0 + sign * dy * n0.y, 1e-15);
  CHECK_NEAR(separation(1), sep1 + sign * dy * n0.y, 1e-15);
  CHECK(c.count.graph_unchanged == 1);
  // a move past STILL_DISTANCE runs the narrowphase again
  store_impulses(c);
  w.state.body_x[box].y += 2.0 * constants::STILL_DISTANCE;
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 0);
  CHECK(c.normal_impulse[0][0] == 1.0);  // still warm-started, by id
  // a turn past STILL_ANGLE since the manifold was found runs it again too, however
  // little the box moved, in two turns of 0.6 STILL_ANGLE as in one
  auto turn_box = [&](double by) {
    w.state.body_angle[box] += by;
    w.state.body_q[box] = {std::cos(w.state.body_angle[box]), std::sin(w.state.body_angle[box])};
  };
  store_impulses(c);
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 1);
  store_impulses(c);
  turn_box(0.6 * constants::STILL_ANGLE);
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 1);
  CHECK(c.ref_turn_a[0] + c.ref_turn_b[0] == 0.0);  // (the box's and the ground's when found)
  store_impulses(c);
  turn_box(0.6 * constants::STILL_ANGLE);
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 0);
  const double now = w.state.body_angle[box];
  CHECK((c.body_a[0] == box ? c.ref_turn_a[0] : c.ref_turn_b[0]) == now);  // taken anew
  store_impulses(c);
  turn_box(0.6 * constants::STILL_ANGLE);
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 1);
}

// A still pair whose bodies now move towards each other faster than LINEAR_SLOP in a step
// (a velocity given at the end of the last step, by a bounce or the continuous sweep
// putting a body back) runs the narrowphase again: its manifold, found while they were
// slower, may lack a point they now reach. A plank resting tilted on one corner, its other
// bottom corner 5 cm up, is found with one point; turning at 30 rad/s now (half a radian in
// the step, that corner's way down), it is found again with both.
TEST(a_still_pair_moving_fast_now_is_found_again) {
  SceneBuilder s;
  s.ground();
  const double tilt = 0.06;  // rad: the right bottom corner 0.8 sin(tilt) = 4.8 cm up
  const double y = 0.4 * std::sin(tilt) + 0.05 * std::cos(tilt);  // m: the left corner on y = 0
  const int plank = s.box({0.0, y}, 0.4, 0.05, 1.0, {}, tilt);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  CHECK(c.count.manifolds == 1 && c.points[0] == 1);
  store_impulses(c);
  rbsim::test::collide(w);  // still and slow: carried, the same one point
  CHECK(c.carried[0] == 1 && c.points[0] == 1);
  store_impulses(c);
  w.state.body_w[plank] = -30.0;  // rad/s
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 0);
  CHECK(c.points[0] == 2);
}

// In space as in the plane: a box resting on the ground keeps its manifold through a turn
// of 0.6 STILL_ANGLE (about any axis) and finds it again once it has turned 1.2 since it
// was found; q and −q are one rotation.
TEST(a_manifold_in_space_is_found_again_after_a_turn_past_still_angle) {
  SceneBuilder3 s;
  int box = 0;
  World<3>& w = box_on_plane(s, box);
  auto& c = w.contacts;
  auto step = [&] {
    rbsim::test::collide3(w);
    store_impulses(c);
  };
  // the rotation by `angle` (rad) about the unit axis (1, 2, 0.5) / |.|
  auto turned = [](double angle) {
    const double k = 1.0 / std::sqrt(1.0 + 4.0 + 0.25), h = 0.5 * angle;
    return Quat{std::cos(h), std::sin(h) * k, std::sin(h) * 2.0 * k, std::sin(h) * 0.5 * k};
  };
  step();
  CHECK(c.count.manifolds == 1 && c.carried[0] == 0);
  step();
  CHECK(c.carried[0] == 1);
  w.state.body_q[box] = turned(0.6 * constants::STILL_ANGLE);
  step();
  CHECK(c.carried[0] == 1);
  w.state.body_q[box] = turned(1.2 * constants::STILL_ANGLE);
  step();
  CHECK(c.carried[0] == 0);
  const Quat q = w.state.body_q[box];
  w.state.body_q[box] = Quat{-q.w, -q.x, -q.y, -q.z};  // the same rotation
  step();
  CHECK(c.carried[0] == 1);
}

// Two boxes that move together, one resting on the other (a stack riding a belt, or
// swaying as one), keep their manifold however far they go, its separations unchanged;
// once they move one against the other by more than STILL_DISTANCE it is found again.
TEST(a_pair_moving_as_one_carries_its_manifold) {
  SceneBuilder s;
  const int low = s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  const int top = s.box({0.0, 1.5}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  CHECK(c.count.manifolds == 1 && c.points[0] == 2);
  c.normal_impulse[0] = {1.0, 2.0};
  store_impulses(c);
  auto separation = [&](int k) {
    return c.base_separation[0][k] + dot(c.normal[0], c.anchor_a[0][k] - c.anchor_b[0][k]);
  };
  const double sep0 = separation(0), sep1 = separation(1);
  for (int step = 0; step < 3; ++step) {
    // 0.01 m a step, a hundred times STILL_DISTANCE, both boxes alike
    for (const int b : {low, top}) w.state.body_x[b] = w.state.body_x[b] + Vec2{0.01, -0.004};
    rbsim::test::collide(w);
    CHECK(c.carried[0] == 1);
    CHECK(c.normal_impulse[0][0] == 1.0 && c.normal_impulse[0][1] == 2.0);
    CHECK_NEAR(separation(0), sep0, 1e-15);  // (the offset's rounding)
    CHECK_NEAR(separation(1), sep1, 1e-15);
    store_impulses(c);
  }
  // the top box lifted by half STILL_DISTANCE against the other: still carried, the
  // separations opened by that much
  w.state.body_x[top].y += 0.5 * constants::STILL_DISTANCE;
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 1);
  CHECK_NEAR(separation(0), sep0 + 0.5 * constants::STILL_DISTANCE, 1e-15);
  store_impulses(c);
  // and by as much again: found anew (the two together have moved a full STILL_DISTANCE
  // apart since it was found)
  w.state.body_x[top].y += 0.5 * constants::STILL_DISTANCE;
  rbsim::test::collide(w);
  CHECK(c.carried[0] == 0);
  CHECK_NEAR(separation(0), sep0 + constants::STILL_DISTANCE, 1e-12);
  CHECK(c.normal_impulse[0][0] == 1.0);  // warm-started by id
}

// The contact's friction and restitution mix the two shapes' by the scene's rule.
TEST(coefficients_mix_by_the_rule) {
  for (const MixRule rule : {MixRule::Sqrt, MixRule::Multiply, MixRule::Min, MixRule::Max}) {
    SceneBuilder s;
    s.ground(-10, 10, {0.4, 0.1});
    s.box({0.0, 0.5}, 0.5, 0.5, 1.0, {0.9, 0.6});
    s.world.config.friction_rule = rule;
    s.world.config.restitution_rule = rule;
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    const double f = w.contacts.friction[0], e = w.contacts.restitution[0];
    switch (rule) {
      case MixRule::Sqrt: CHECK_NEAR(f, 0.6, 1e-15); CHECK_NEAR(e, std::sqrt(0.06), 1e-15); break;
      case MixRule::Multiply: CHECK_NEAR(f, 0.36, 1e-15); CHECK_NEAR(e, 0.06, 1e-15); break;
      case MixRule::Min: CHECK(f == 0.4 && e == 0.1); break;
      case MixRule::Max: CHECK(f == 0.9 && e == 0.6); break;
    }
  }
}

// A circle's separation follows its centre (the core), not the contact point: the lever
// arm reaches the surface, the separation anchor is the centre, and a turn of the ball
// leaves the separation as it is (its surface does not move).
TEST(circle_separation_follows_its_centre_not_its_turning_surface) {
  SceneBuilder s;
  s.ground();
  const int ball = s.circle({0.0, 0.5 + 0.01}, 0.5, 1.0);  // 1 cm above the ground
  World<2>& w = s.finish();
  auto& c = w.contacts;
  rbsim::test::collide(w);
  CHECK(c.count.manifolds == 1 && c.points[0] == 1);
  const bool a = c.body_a[0] == ball;
  const Vec2 sep_anchor = a ? c.sep_anchor_a[0][0] : c.sep_anchor_b[0][0];
  const Vec2 lever = a ? c.anchor_a[0][0] : c.anchor_b[0][0];
  CHECK_NEAR(length(sep_anchor), 0.0, 1e-12);
  CHECK_NEAR(lever.y, -0.5, 1e-12);  // to its surface, where it will touch the ground
  CHECK_NEAR(lever.x, 0.0, 1e-12);
  // the ball turned by a quarter since the step began: still 1 cm above the ground
  c.body_delta[ball].dq = {0.0, 1.0};
  const double sep = c.base_separation[0][0] +
                     dot(c.normal[0], rotate(c.body_delta[c.body_a[0]].dq, c.sep_anchor_a[0][0]) -
                                          rotate(c.body_delta[c.body_b[0]].dq, c.sep_anchor_b[0][0]));
  CHECK_NEAR(sep, 0.01, 1e-12);
}

// The speculative distance is the pair's, scaled to its smaller shape: 2 mm boxes 1 mm
// apart (at rest) are beyond their SPECULATIVE_DISTANCE times the scale (0.28 mm); 1 m
// boxes 1 mm apart are within 2 cm. The manifold keeps the scale for the later stages.
TEST(speculative_distance_follows_the_size_of_the_shapes) {
  for (const double half : {0.001, 0.5}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    s.box({0.0, 0.0}, half, half, 1.0);
    s.box({0.0, 2.0 * half + 0.001}, half, half, 1.0);
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    const double scale = std::min(1.0, std::hypot(half, half) / constants::SCALE_LENGTH);
    CHECK(w.contacts.count.manifolds == (half == 0.5 ? 1 : 0));
    if (half == 0.5) CHECK(w.contacts.scale[0] == scale);
  }
}

// ---- 3D ------------------------------------------------------------------------------

namespace {
// Write `value` into every double of a point's tangent impulse (one direction or two:
// the 3D solver chooses; the manifold stage copies the whole record).
template <class T>
void set_tangent(T& t, double value) {
  static_assert(sizeof(T) % sizeof(double) == 0);
  double* p = reinterpret_cast<double*>(&t);
  for (std::size_t k = 0; k < sizeof(T) / sizeof(double); ++k) p[k] = value + 0.01 * k;
}
template <class T>
bool same_tangent(const T& a, const T& b) { return std::memcmp(&a, &b, sizeof(T)) == 0; }
}  // namespace

// A unit box resting on the ground plane: one manifold of four points at its bottom
// corners, normal from the box (b) towards the plane (a), separations 0; after a move
// that recomputes it the same four feature ids come back, and each point takes the
// impulses of last step's point with its id (listed in another order).
TEST(box_on_plane_has_four_points_with_stable_ids_and_carried_impulses) {
  SceneBuilder3 s;
  int box = 0;
  World<3>& w = box_on_plane(s, box);
  auto& c = w.contacts;
  CHECK(test::collide3(w) == 1);
  CHECK(c.points[0] == 4 && c.shape_a[0] == 0 && c.shape_b[0] == 1);
  CHECK(c.normal[0].x == 0.0 && c.normal[0].y == -1.0 && c.normal[0].z == 0.0);
  std::set<std::int64_t> ids;
  for (int k = 0; k < 4; ++k) {
    const double sep = c.base_separation[0][k] + dot(c.normal[0], c.sep_anchor_a[0][k] - c.sep_anchor_b[0][k]);
    CHECK(std::fabs(sep) < 1e-12);  // m: round-off of the unit box's corners
    CHECK(std::fabs(std::fabs(c.anchor_b[0][k].x) - 0.5) < 1e-12 && std::fabs(c.anchor_b[0][k].y + 0.5) < 1e-12);
    ids.insert(c.feature[0][k]);
  }
  CHECK(ids.size() == 4);
  CHECK(c.friction[0] == 0.6 && c.scale[0] == 1.0);
  const auto first = c.feature[0];
  for (int k = 0; k < 4; ++k) {
    c.normal_impulse[0][k] = 1.0 + k;
    set_tangent(c.tangent_impulse[0][k], 0.1 * (k + 1));
  }
  const auto tangents = c.tangent_impulse[0];
  store_impulses(c);
  std::reverse(c.prev_feature[0].begin(), c.prev_feature[0].end());
  std::reverse(c.prev_normal_impulse[0].begin(), c.prev_normal_impulse[0].end());
  std::reverse(c.prev_tangent_impulse[0].begin(), c.prev_tangent_impulse[0].end());
  for (int step = 0; step < 3; ++step) {
    w.state.body_x[box].x += 1e-3;  // moved: the narrowphase runs again
    CHECK(test::collide3(w) == 1);
    CHECK(c.carried[0] == 0 && c.points[0] == 4);
    CHECK(c.feature[0] == first);
    for (int k = 0; k < 4; ++k) {
      CHECK(c.normal_impulse[0][k] == 1.0 + k && c.start_impulse[0][k] == 1.0 + k);
      CHECK(same_tangent(c.tangent_impulse[0][k], tangents[k]));
    }
    store_impulses(c);
  }
  // a point whose id last step did not have takes the impulse of the old point nearest
  // it that no id matched (within WARM_MATCH_DISTANCE: here 1 mm away)
  c.prev_feature[0][2] = -5;
  w.state.body_x[box].x += 1e-3;
  test::collide3(w);
  CHECK(c.normal_impulse[0][2] == 3.0 && c.normal_impulse[0][0] == 1.0);
  CHECK(c.start_impulse[0][2] == 3.0);
  store_impulses(c);
  // two such points with no old point near: what the unmatched old points held (3 + 4
  // N·s) is shared out between them, the manifold keeps its total
  c.prev_feature[0][2] = -5;
  c.prev_feature[0][3] = -6;
  c.prev_anchor_a[0][2] += Vec3{0.0, 1.0, 0.0};  // 1 m off: out of reach
  c.prev_anchor_a[0][3] += Vec3{0.0, 1.0, 0.0};
  w.state.body_x[box].x += 1e-3;
  test::collide3(w);
  CHECK(c.normal_impulse[0][0] == 1.0 && c.normal_impulse[0][1] == 2.0);
  CHECK(c.normal_impulse[0][2] == 3.5 && c.normal_impulse[0][3] == 3.5);
}

// A ball resting 1 cm above the ground is one speculative point with that separation;
// one 5 cm above it is out of reach; one sunk 1 cm in overlaps by 1 cm.
TEST(sphere_over_plane_has_one_point_at_its_gap) {
  for (double gap : {0.01, 0.05, -0.01}) {
    SceneBuilder3 s;
    s.plane({0.0, 1.0, 0.0}, 0.0);
    s.sphere({0.3, 0.5 + gap, -0.2}, 0.5, 1.0);
    World<3>& w = s.finish();
    auto& c = w.contacts;
    const std::int64_t n = test::collide3(w);
    if (gap > constants::SPECULATIVE_DISTANCE) {
      CHECK(n == 0);
      continue;
    }
    CHECK(n == 1 && c.points[0] == 1);
    const double sep = c.base_separation[0][0] + dot(c.normal[0], c.sep_anchor_a[0][0] - c.sep_anchor_b[0][0]);
    CHECK(std::fabs(sep - gap) < 1e-12);
    // apart, the ball's lever arm reaches its own surface and its separation anchor is
    // its centre; overlapping, both are at the midpoint of the overlap (and one radius in)
    const double arm = gap > 0.0 ? -0.5 : -0.5 - 0.5 * gap;  // m
    CHECK(std::fabs(c.anchor_b[0][0].y - arm) < 1e-12 && std::fabs(c.anchor_b[0][0].x) < 1e-12);
    CHECK(length(c.sep_anchor_b[0][0] - Vec3{0.0, arm + 0.5, 0.0}) < 1e-12);
  }
}

// Still bodies in space keep their manifold (carried), the separation moved by the
// bodies' relative motion since it was found.
TEST(still_bodies_in_space_carry_their_manifold) {
  SceneBuilder3 s;
  int box = 0;
  World<3>& w = box_on_plane(s, box);
  auto& c = w.contacts;
  test::collide3(w);  // finds the manifold: its offset and rotations
  c.normal_impulse[0] = {1.0, 2.0, 3.0, 4.0};
  store_impulses(c);
  w.state.body_x[box].y -= 0.5 * constants::STILL_DISTANCE;
  test::collide3(w);
  CHECK(c.carried[0] == 1 && c.points[0] == 4);
  for (int k = 0; k < 4; ++k) {
    CHECK(c.normal_impulse[0][k] == 1.0 + k);
    const double sep = c.base_separation[0][k] + dot(c.normal[0], c.sep_anchor_a[0][k] - c.sep_anchor_b[0][k]);
    CHECK(std::fabs(sep + 0.5 * constants::STILL_DISTANCE) < 1e-12);
  }
}

// Not a test of speed (none is asserted): update_manifolds for a stack of 10 unit boxes
// on the ground (10 manifolds of 4 points), recomputed each step (every box moved past
// STILL_DISTANCE) and carried (at rest).
TEST(measure_manifolds_of_a_10_box_stack) {
  SceneBuilder3 s;
  s.plane({0.0, 1.0, 0.0}, 0.0);
  for (int i = 0; i < 10; ++i) s.box({0.0, 0.5 + i, 0.0}, {0.5, 0.5, 0.5}, 1.0);
  World<3>& w = s.finish();
  auto& c = w.contacts;
  const Config& cfg = w.config;
  CHECK(test::collide3(w) == 10);
  for (std::int64_t m = 0; m < 10; ++m) CHECK(c.points[m] == 4);
  // µs of this thread's CPU time (the machine may be shared: wall time would count others)
  auto now = [] {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return 1e6 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_nsec);
  };
  const int reps = 2000;
  double moving = 0.0, still = 0.0;
  for (int r = 0; r < reps; ++r) {
    for (int i = 1; i <= 10; ++i) w.state.body_x[i].x += (r % 2 ? 1.0 : -1.0) * 2e-4;
    transform_shapes(w.model, w.state, c, cfg.dt);
    const double t0 = now();
    update_manifolds(w.model, w.state, c, w.grid, c.count.pairs, cfg.friction_rule,
                     cfg.restitution_rule, cfg.dt);
    moving += now() - t0;
    store_impulses(c);
  }
  for (int r = 0; r < reps; ++r) {
    transform_shapes(w.model, w.state, c, cfg.dt);
    const double t0 = now();
    update_manifolds(w.model, w.state, c, w.grid, c.count.pairs, cfg.friction_rule,
                     cfg.restitution_rule, cfg.dt);
    still += now() - t0;
    store_impulses(c);
  }
  std::printf("10-box stack (CPU time per step): update_manifolds %.2f us recomputed, %.2f us "
              "carried\n",
              moving / reps, still / reps);
  CHECK(c.count.manifolds == 10 && c.carried[5] == 1);
}

// The square-root mixing rule takes no root where both coefficients are equal (one
// material): the result is the root's, to the bit, over coefficients of every size a scene
// may hold, and the rule is the root's for unequal ones.
TEST(mixing_equal_coefficients_by_the_root_is_the_roots_result) {
  double a = 1e-140;
  int n = 0;
  while (a < 1e140) {
    const double r = std::sqrt(a * a);
    CHECK(std::memcmp(&r, &a, sizeof r) == 0);  // (the identity the rule relies on)
    const double m = mix(a, a, MixRule::Sqrt);
    CHECK(std::memcmp(&m, &r, sizeof m) == 0);
    const double b = std::nextafter(a, 2.0 * a);
    CHECK(mix(a, b, MixRule::Sqrt) == std::sqrt(a * b));
    a *= 1.0 + 1.0 / 3.0 + 1e-3 * (n % 7);  // (mantissas of every kind along the way)
    ++n;
  }
  CHECK(n > 1000);
  for (const double x : {0.0, 0.3, 0.6, 0.8, 1.0, 2.5}) {
    const double m = mix(x, x, MixRule::Sqrt), r = std::sqrt(x * x);
    CHECK(std::memcmp(&m, &r, sizeof m) == 0);
  }
}

RBSIM_TEST_MAIN
