// solver/overlap_limit.cpp: a body deeper than the limit in a static one is moved out
// along the normal to the limit, its velocity untouched; shallower overlaps and overlaps
// between dynamic bodies are left to the solver. Two dynamic bodies deeper than their own
// limit are moved apart to it, each by its share of the inverse mass.
#include "check.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {
constexpr double LIMIT = 0.02;  // m
}

TEST(deep_box_in_static_ground_moves_out_to_the_limit) {
  SceneBuilder s;
  s.ground();
  const int deep = s.box({-3.0, 0.5 - 0.05}, 0.5, 0.5, 1.0, {}, 0.0, {0.0, -1.0});  // 5 cm in
  const int shallow = s.box({3.0, 0.5 - 0.01}, 0.5, 0.5, 1.0);                      // 1 cm in
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  CHECK_NEAR(w.state.body_x[deep].y, 0.5 - LIMIT, 1e-12);
  CHECK_NEAR(w.contacts.body_delta[deep].dx.y, 0.05 - LIMIT, 1e-12);
  CHECK(w.state.body_v[deep].y == -1.0);
  CHECK(w.state.body_x[shallow].y == 0.5 - 0.01);
}

// Under a static ceiling (the static body is shape a) the box is pushed down, along −n.
TEST(box_deep_in_static_ceiling_moves_down) {
  SceneBuilder s;
  s.box({0.0, 1.5}, 2.0, 0.5, 0.0);                       // ceiling from y = 1
  const int box = s.box({0.0, 0.5 + 0.06}, 0.5, 0.5, 1.0);  // 6 cm into it
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.body_a[0] != box);
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  CHECK_NEAR(w.state.body_x[box].y, 0.5 + LIMIT, 1e-12);
}

TEST(overlap_between_dynamic_bodies_is_left_to_the_solver) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  const int a = s.box({0.0, 0.0}, 0.5, 0.5, 1.0);
  const int b = s.box({0.0, 0.9}, 0.5, 0.5, 1.0);  // 10 cm into a
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  CHECK(w.state.body_x[a].y == 0.0 && w.state.body_x[b].y == 0.9);
}

// The limit is the contact's, scaled to its smaller shape (SCALE_LENGTH): a box of 2 mm
// 0.5 mm into the ground is moved out to 2 cm times its scale, a 1 m box 0.5 mm in is not.
TEST(limit_follows_the_size_of_the_shapes) {
  SceneBuilder s;
  s.ground();
  const int small = s.box({-3.0, 0.001 - 0.0005}, 0.001, 0.001, 1e-6);
  const int big = s.box({3.0, 0.5 - 0.0005}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  const double scale = std::hypot(0.001, 0.001) / constants::SCALE_LENGTH;
  CHECK_NEAR(w.state.body_x[small].y, 0.001 - scale * LIMIT, 1e-12);
  CHECK(w.state.body_x[big].y == 0.5 - 0.0005);
}

// Move body i by d (m) as the step before the limit would have: its state and its
// motion since the step's start.
template <int D>
void drive(World<D>& w, int i, typename Dim<D>::Vec d) {
  w.state.body_x[i] += d;
  w.contacts.body_delta[i].dx += d;
}

// A thin shape that the step drives in deeper than half its depth, where that is less
// than the scaled limit, is moved back out to it, so that its core never reaches the
// static surface: a capsule 3 cm thick and 15.5 cm long (scale 0.77: a limit of 1.5 cm,
// its whole radius) driven 1.4 cm into the ground is moved out to 7.5 mm; a plank 2 cm
// thick and 1 m long (scale 1: 2 cm) driven 9 mm in, to 5 mm. One placed as deep is left
// where it is (the scaled limit's, and the soft contacts').
TEST(thin_shapes_driven_in_are_held_to_half_their_depth) {
  SceneBuilder s;
  s.ground();
  const double r = 0.015, half = 0.0624;  // m
  const int capsule = s.capsule({-3.0, r}, half, r, 0.03, 1e-4);
  const int plank = s.box({3.0, 0.01}, 0.5, 0.01, 1.0);
  const int placed = s.box({6.0, 0.01 - 0.009}, 0.5, 0.01, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK_NEAR(w.model.shape_depth[capsule], r, 1e-15);
  CHECK_NEAR(w.model.shape_depth[plank], 0.01, 1e-15);
  const double scale = (half + r) / constants::SCALE_LENGTH;
  CHECK(scale * LIMIT > 0.014);  // (the scaled limit alone leaves the capsule where it is)
  drive(w, capsule, {0.0, -0.014});
  drive(w, plank, {0.0, -0.009});
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  const double f = constants::OVERLAP_DEPTH_FRACTION;
  CHECK_NEAR(w.state.body_x[capsule].y, r - f * r, 1e-12);
  CHECK_NEAR(w.state.body_x[plank].y, 0.01 - f * 0.01, 1e-12);
  CHECK(w.state.body_x[placed].y == 0.01 - 0.009);
}

// A thin shape already deeper than half its depth and driven further is moved back by
// what the step drove it, no more: a plank 2 cm thick placed 8 mm in (its limit 5 mm)
// and driven 2 mm further is back at 8 mm.
TEST(a_thin_shape_is_moved_back_by_no_more_than_the_step_drove_it) {
  SceneBuilder s;
  s.ground();
  const int plank = s.box({0.0, 0.01 - 0.008}, 0.5, 0.01, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  drive(w, plank, {0.0, -0.002});
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  CHECK_NEAR(w.state.body_x[plank].y, 0.01 - 0.008, 1e-12);
}

// In space: a plate 2 cm thick (scale 1) driven 9 mm into the ground plane is moved out
// to 5 mm; a convex prism's depth is its cross-section's inradius, a box's its shortest
// half edge.
TEST(thin_shapes_in_space_are_held_to_half_their_depth) {
  SceneBuilder3 s;
  s.plane({0.0, 1.0, 0.0}, 0.0);
  const int plate = s.box({0.0, 0.01, 0.0}, {0.5, 0.01, 0.3}, 1.0);
  // a square prism along x, its cross-section's corners 3 cm from the axis (inradius
  // 3 cm / sqrt 2), far from the ground
  std::vector<Vec3> v;
  for (const double x : {-0.5, 0.5})
    for (int k = 0; k < 4; ++k)
      v.push_back({x, 0.03 * std::cos(0.5 * M_PI * k), 0.03 * std::sin(0.5 * M_PI * k)});
  std::vector<std::array<std::int32_t, 3>> tris;
  for (int k = 0; k < 4; ++k) {
    const int k1 = (k + 1) % 4;
    tris.push_back({k, k1, 4 + k1});
    tris.push_back({k, 4 + k1, 4 + k});
  }
  tris.push_back({0, 2, 1}), tris.push_back({0, 3, 2});
  tris.push_back({4, 5, 6}), tris.push_back({4, 6, 7});
  const int prism = s.convex({3.0, 2.0, 0.0}, v, tris, 1.0);
  World<3>& w = s.finish();
  CHECK_NEAR(w.model.shape_depth[plate], 0.01, 1e-15);
  CHECK_NEAR(w.model.shape_depth[prism], 0.03 / std::sqrt(2.0), 1e-15);
  rbsim::test::collide3(w);
  drive(w, plate, {0.0, -0.009, 0.0});
  limit_static_overlap(w.model, w.state, w.contacts, LIMIT);
  CHECK_NEAR(w.state.body_x[plate].y, 0.01 - constants::OVERLAP_DEPTH_FRACTION * 0.01, 1e-12);
}

// Box b (three times as dense) 10 cm into box a: moved apart to the limit along the
// normal, a by three quarters of the 9 cm, b by a quarter; velocities untouched.
TEST(dynamic_pair_moves_apart_by_inverse_mass) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  const int a = s.box({0.0, 0.0}, 0.5, 0.5, 1.0, {}, 0.0, {0.5, 0.0});
  const int b = s.box({0.0, 0.9}, 0.5, 0.5, 3.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const double limit = constants::DYNAMIC_OVERLAP_LIMIT;  // (the boxes' scale is 1)
  CHECK(limit_dynamic_overlap(w.model, w.state, w.contacts, limit, 4) == 1);
  const double excess = 0.1 - limit;  // m
  CHECK_NEAR(w.state.body_x[a].y, -0.75 * excess, 1e-12);
  CHECK_NEAR(w.state.body_x[b].y, 0.9 + 0.25 * excess, 1e-12);
  CHECK_NEAR(w.state.body_x[b].y - w.state.body_x[a].y, 1.0 - limit, 1e-12);
  CHECK_NEAR(w.contacts.body_delta[a].dx.y, -0.75 * excess, 1e-12);
  CHECK(w.state.body_v[a].x == 0.5 && w.state.body_v[a].y == 0.0 && w.state.body_v[b].y == 0.0);
  CHECK(w.state.body_x[a].x == 0.0 && w.state.body_x[b].x == 0.0);
}

// Within the limit nothing moves; and a pair with a static body is the static limit's.
TEST(shallow_dynamic_pair_and_static_pair_are_left) {
  SceneBuilder s;
  s.ground();
  const int a = s.box({-3.0, 0.5 - 0.05}, 0.5, 0.5, 1.0);  // 5 cm into the ground
  const int b = s.box({3.0, 0.5}, 0.5, 0.5, 1.0);
  const int c = s.box({3.0, 1.5 - 0.005}, 0.5, 0.5, 1.0);  // 5 mm into b
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const double limit = constants::DYNAMIC_OVERLAP_LIMIT;
  CHECK(limit_dynamic_overlap(w.model, w.state, w.contacts, limit, 4) == 0);
  CHECK(w.state.body_x[a].y == 0.5 - 0.05 && w.state.body_x[b].y == 0.5);
  CHECK(w.state.body_x[c].y == 1.5 - 0.005);
}

// A box wedged between two others, 4 cm into each, in a row: the passes take both
// overlaps to the limit (one pass moves the middle box back into the first pair).
TEST(wedge_of_three_settles_at_the_limit) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  const int left = s.box({-0.96, 0.0}, 0.5, 0.5, 1.0);
  const int mid = s.box({0.0, 0.0}, 0.5, 0.5, 1.0);
  const int right = s.box({0.96, 0.0}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const double limit = constants::DYNAMIC_OVERLAP_LIMIT;
  limit_dynamic_overlap(w.model, w.state, w.contacts, limit, 16);
  const auto& x = w.state.body_x;
  CHECK(x[mid].x - x[left].x >= 1.0 - limit - 1e-5);  // m: the two overlaps, at the
  CHECK(x[right].x - x[mid].x >= 1.0 - limit - 1e-5);  // limit, less what 16 passes,
  // each halving the other's excess, leave (4 cm / 2^16)
  CHECK_NEAR(x[left].x + x[mid].x + x[right].x, 0.0, 1e-12);  // equal masses: no drift
}

RBSIM_TEST_MAIN
