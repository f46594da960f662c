// solver/shock.cpp: support levels through the contact graph, the solve order, and the
// shock pass that holds the supporter still.
#include <algorithm>
#include <array>
#include <cmath>

#include "check.hpp"
#include "scene_builder.hpp"
#include "scene_builder3d.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;
using rbsim::test::SceneBuilder3;

namespace {

// Ground, then boxes 1 kg, 10 kg, 1 kg stacked, and a box floating to the side.
World<2>& stack(SceneBuilder& s) {
  s.ground();
  s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
  s.box({0.0, 1.5}, 0.5, 0.5, 10.0);
  s.box({0.0, 2.5}, 0.5, 0.5, 1.0);
  s.box({5.0, 5.0}, 0.5, 0.5, 1.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  return w;
}

// The manifold between bodies i and j (-1 if none).
int manifold_of(const World<2>& w, int i, int j) {
  const auto& c = w.contacts;
  for (int m = 0; m < c.count.manifolds; ++m)
    if ((c.body_a[m] == i && c.body_b[m] == j) || (c.body_a[m] == j && c.body_b[m] == i)) return m;
  return -1;
}

}  // namespace

// Levels count contacts down to the ground; each supported contact is in the shock order,
// lowest supporter first, with the side that supports; the solve order is ground first.
TEST(stack_support_levels_count_up_from_the_ground) {
  SceneBuilder s;
  World<2>& w = stack(s);
  const auto& c = w.contacts;
  CHECK(c.body_level[0] == 0 && c.body_level[1] == 1 && c.body_level[2] == 2 && c.body_level[3] == 3);
  CHECK(c.body_level[4] > 1000);  // not connected to the ground
  CHECK(c.count.shock_count == 3);
  for (int lv = 0; lv < 3; ++lv) {
    const int m = c.shock_order[lv];
    CHECK(m == manifold_of(w, lv, lv + 1));
    // the lower body supports: side 1 when it is body a, 2 when it is body b
    CHECK(c.shock_side[m] == (c.body_a[m] == lv ? 1 : 2));
    CHECK(c.solve_order[lv] == m);
  }
}

// The heavy middle box falls onto the light one at 2 m/s: the pass stops the approach
// against the light box held still, and the light box is not pushed into the ground.
TEST(shock_pass_removes_supported_approach_and_holds_supporter) {
  SceneBuilder s;
  World<2>& w = stack(s);
  w.state.body_v[2] = {0.0, -2.0};
  w.state.body_v[3] = {0.0, -2.0};
  const double h = rbsim::test::substep(w);
  propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 1.0 / h, 1.0);
  CHECK(w.state.body_v[1].y == 0.0 && w.state.body_w[1] == 0.0);  // the supporter, untouched
  const int m = manifold_of(w, 1, 2);
  for (int k = 0; k < 2; ++k)
    CHECK(rbsim::test::point_normal_velocity(w, m, k) >= -constants::SHOCK_MIN_APPROACH);
  CHECK_NEAR(w.state.body_v[2].y, 0.0, 1e-12);  // m/s: touching (gap ~1e-16 m)
  CHECK_NEAR(w.state.body_v[3].y, 0.0, 1e-12);  // carried up the stack in the same pass
  CHECK_NEAR(w.state.body_w[2], 0.0, 1e-12);    // flat faces: no spin
}

// A run that records its contact points: the pushes of the shock pass are in the step
// impulses of the contacts where it pushed, and each supporter's reaction is handed down
// to the ground's contact, so that every box's recorded forces add up.
TEST(shock_pushes_are_recorded_and_handed_down_to_the_ground) {
  SceneBuilder s;
  World<2>& w = stack(s);
  auto& c = w.contacts;
  c.record_impulses = true;
  begin_step_impulses(c);
  const int m01 = manifold_of(w, 0, 1), m12 = manifold_of(w, 1, 2), m23 = manifold_of(w, 2, 3);
  // the ground's contact pushed in the passes (a support that did not is handed nothing)
  c.max_normal_impulse[m01] = {1e-3, 1e-3};
  w.state.body_v[2] = {0.0, -2.0};
  w.state.body_v[3] = {0.0, -2.0};
  const double h = rbsim::test::substep(w);
  propagate_shock(w.model, w.state, c, c.count.shock_count, 1.0 / h, 1.0);
  hand_down_shock_impulses(w.model, c);
  auto total = [&](int m) { return c.step_impulse[m][0] + c.step_impulse[m][1]; };  // N·s
  // the pass stopped the 10 kg box (20 N·s) and the 1 kg box on it (2 N·s, once the
  // 10 kg box was still), pushing at both points of each
  CHECK_NEAR(c.shock_impulse[m12], 20.0, 1e-12);
  CHECK_NEAR(c.shock_impulse[m23], 2.0, 1e-12);
  CHECK(c.shock_points[m12] == 3 && c.shock_points[m23] == 3 && c.shock_points[m01] == 0);
  CHECK_NEAR(total(m23), 2.0, 1e-12);
  CHECK_NEAR(total(m12), 22.0, 1e-12);  // its own push and the top box's, handed on
  CHECK_NEAR(total(m01), 22.0, 1e-12);  // the bottom box, held still, handed it all on
  CHECK_NEAR(c.step_impulse[m01][0], 11.0, 1e-12);  // over its points evenly: none carried
}

// The pass never pulls: bodies moving apart, or closing a gap slower than it allows, keep
// their velocities.
TEST(shock_pass_never_pushes_apart) {
  SceneBuilder s;
  World<2>& w = stack(s);
  w.state.body_v[2] = {0.0, 1.0};   // leaving the light box
  w.state.body_v[3] = {0.3, 2.0};   // leaving the middle one faster
  const State<2> before = w.state;
  const double h = rbsim::test::substep(w);
  propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 1.0 / h, 1.0);
  CHECK(rbsim::test::same_bits(w.state, before));
}

// Without gravity nothing supports anything: no levels are needed and the pass is empty.
TEST(no_gravity_no_shock_pass) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.ground();
  s.box({0.0, 0.5}, 0.5, 0.5, 1.0, {}, 0.0, {0.0, -2.0});
  s.box({0.0, 1.5}, 0.5, 0.5, 1.0, {}, 0.0, {0.0, -3.0});
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.count.manifolds == 2);
  CHECK(w.contacts.count.shock_count == 0);
  const State<2> before = w.state;
  propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 240.0, 1.0);
  CHECK(rbsim::test::same_bits(w.state, before));
}

// A body HEAVY_RATIO times heavier than the dynamic body it rests on marks the contact
// store (the step then runs the shock pass before the positions move too); equal boxes,
// and a heavy box on static ground, do not.
TEST(heavy_body_on_a_light_one_is_found) {
  for (const double top : {1.0, 5.0, 100.0}) {  // kg, on a 1 kg box on the ground
    SceneBuilder s;
    s.ground();
    s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
    s.box({0.0, 1.5}, 0.5, 0.5, top);
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    CHECK(w.contacts.heavy_on_light == (top >= constants::HEAVY_RATIO));
  }
}

// Only touching contacts hold bodies up: a 100 kg disc resting on a 1 cm plate has the
// ground within its speculative distance, and counted as standing on it (level 1, as the
// plate) it was no load of the plate's in the shock pass, and pushed the plate through
// the ground. The disc is the plate's load: level 2, its contact in the shock order.
TEST(a_speculative_contact_holds_nothing_up) {
  SceneBuilder s;
  s.ground();
  const int plate = s.box({0.0, 0.005}, 0.1, 0.005, 1.0);
  const int disc = s.circle({0.0, 0.31}, 0.3, 100.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const auto& c = w.contacts;
  CHECK(manifold_of(w, 0, disc) >= 0);  // the ground, 1 cm below the disc: speculative
  CHECK(!c.support[manifold_of(w, 0, disc)] && c.support[manifold_of(w, plate, disc)]);
  CHECK(c.body_level[plate] == 1 && c.body_level[disc] == 2);
  CHECK(c.shock_side[manifold_of(w, plate, disc)] != 0);
}

// The load a body bears: its own mass and, split over their supports, that of the
// bodies resting on it (a 100 kg box on two 1 kg boxes side by side on the ground).
TEST(borne_loads_come_down_the_supports) {
  SceneBuilder s;
  s.ground();
  const int left = s.box({-0.5, 0.5}, 0.5, 0.5, 1.0);
  const int right = s.box({0.5, 0.5}, 0.5, 0.5, 1.0);
  const int top = s.box({0.0, 1.5}, 1.0, 0.5, 100.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const auto& c = w.contacts;
  CHECK(c.heavy_on_light);
  CHECK_NEAR(c.body_load[top], 100.0, 1e-12);  // kg: exact sums of exact halves
  CHECK_NEAR(c.body_load[left], 51.0, 1e-12);
  CHECK_NEAR(c.body_load[right], 51.0, 1e-12);
}

// The friction loads: the weight each support passes on, shared over the supported body's
// supports, each body's up to FRICTION_LOAD_RATIO times the lighter body of its pair; none
// without a heavy body on a light one, and those of an earlier step cleared.
TEST(friction_loads_are_the_borne_weight_up_to_a_ratio) {
  for (const double top_mass : {100.0, 1000.0}) {
    SceneBuilder s;
    s.ground();
    const int left = s.box({-0.5, 0.5}, 0.5, 0.5, 1.0);
    s.box({0.5, 0.5}, 0.5, 0.5, 1.0);
    const int top = s.box({0.0, 1.5}, 1.0, 0.5, top_mass);
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    const auto& c = w.contacts;
    const double weight = 9.81 * rbsim::test::substep(w);  // N·s per kg in a substep
    const double most = constants::FRICTION_LOAD_RATIO;    // kg: 1 kg boxes
    const double on_top = std::min(top_mass, most) / 2.0;  // kg: two supports
    // kg: the left box passes on its own mass and what the top one passes to it
    const double under = std::min(1.0 + std::min(top_mass, most) / 2.0, most);
    CHECK_NEAR(c.solver_row[manifold_of(w, left, top)].friction_load, on_top * weight, 1e-12);
    CHECK_NEAR(c.solver_row[manifold_of(w, 0, left)].friction_load, under * weight, 1e-12);
  }
  SceneBuilder s;  // equal boxes: none
  World<2>& w = stack(s);
  auto& c = w.contacts;
  w.model.body_inv_mass[2] = 1.0;  // (the 10 kg box made 1 kg: no heavy body on a light one)
  rbsim::test::collide(w);
  CHECK(!c.heavy_on_light && c.count.friction_loaded == 0);
  for (int m = 0; m < c.count.manifolds; ++m) CHECK(c.solver_row[m].friction_load == 0.0);
  c.solver_row[0].friction_load = 1.0;  // as an earlier step left a carried row
  c.count.friction_loaded = 1;
  friction_loads(w.model, w.state, c, c.count.shock_count, rbsim::test::substep(w));
  CHECK(c.solver_row[0].friction_load == 0.0 && c.count.friction_loaded == 0);
}

// While a heavy body rests on a light one, a dynamic supporter's turn towards the body it
// supports is not handed on, its travel is. The 1 kg box under the 10 kg one rising at
// 1 m/s (as on a lift) lifts it at 1 m/s; rising at 1 m/s and turning at 2 rad/s too (its
// top right corner at 2 m/s, its top left one still, its bottom parting from the ground),
// it lifts the corner it pushes at 1 m/s, not 2: the turn is left to the ordinary solve.
TEST(a_light_supporter_hands_on_its_travel_not_its_turn) {
  for (const double turn : {0.0, 2.0}) {  // rad/s
    SceneBuilder s;
    World<2>& w = stack(s);
    CHECK(w.contacts.heavy_on_light);
    w.state.body_v[1] = {0.0, 1.0};
    w.state.body_w[1] = turn;
    const double h = rbsim::test::substep(w);
    propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 1.0 / h, 1.0);
    CHECK(w.state.body_v[1].y == 1.0 && w.state.body_w[1] == turn);  // the supporter
    // m/s: the 10 kg box's bottom right corner (0.5 m right of its centre) rises at the
    // supporter's travel, its bottom left one does not go into box 1's still corner
    CHECK_NEAR(w.state.body_v[2].y + 0.5 * w.state.body_w[2], 1.0, 1e-12);
    CHECK(w.state.body_v[2].y - 0.5 * w.state.body_w[2] >= -1e-12);
    if (turn == 0.0) CHECK_NEAR(w.state.body_w[2], 0.0, 1e-12);
  }
}


// A dynamic supporter travelling towards the body it supports faster than an impact (the
// restitution threshold, 1 m/s here) strikes it: none of its motion is handed on, the
// supported body is only kept from approaching it as if it stood still. The 1 kg box
// under the 10 kg one, flung up at 5 m/s (as by a bounce off the floor), leaves the box
// above at rest, and one coming down at 0.5 m/s is stopped, not thrown up at 5: handed
// on, a 50 g capsule bounced up at 88 m/s threw a 16 kg slab resting on it up at 80.
TEST(a_supporter_striking_at_impact_speed_hands_on_nothing) {
  for (const double above : {0.0, -0.5}) {  // m/s: the 10 kg box's own velocity
    SceneBuilder s;
    World<2>& w = stack(s);
    w.state.body_v[1] = {0.0, 5.0};
    w.state.body_v[2] = {0.0, above};
    const double h = rbsim::test::substep(w);
    propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 1.0 / h, 1.0);
    CHECK(w.state.body_v[1].y == 5.0);  // the supporter, held
    CHECK_NEAR(w.state.body_v[2].y, 0.0, 1e-12);
    CHECK_NEAR(w.state.body_w[2], 0.0, 1e-12);
  }
}

namespace {

// The world's contacts found and made rows, the support order found: ready for the shock
// pass (3D).
World<3>& ready_for_shock(World<3>& w) {
  rbsim::test::collide3(w);
  auto& c = w.contacts;
  prepare_contacts(w.model, w.state, c, w.config);
  c.count.shock_count = support_order(w.model, c);
  for (auto& d : c.body_delta) d = BodyDelta<3>{};
  return w;
}

// In space: `n` unit boxes of 1 kg stacked on the ground plane (levels 1 .. n).
World<3>& stack3(SceneBuilder3& s, int n) {
  s.plane({0.0, 1.0, 0.0}, 0.0);
  for (int k = 0; k < n; ++k) s.box({0.0, 0.5 + k, 0.0}, {0.5, 0.5, 0.5}, 1.0);
  return ready_for_shock(s.finish());
}

}  // namespace

// A dynamic supporter's rise is not handed on in space: the box on one rising at 1 m/s
// (pushed from below, as by the solve) is left to the ordinary solve, not lifted with it.
TEST(a_rising_dynamic_supporter_is_not_handed_on_in_space) {
  SceneBuilder3 s;
  World<3>& w = stack3(s, 2);
  w.state.body_v[1] = {0.0, 1.0, 0.0};
  const double h = w.config.dt / w.config.substeps;
  propagate_shock(w.model, w.state, w.contacts, w.contacts.count.shock_count, 1.0 / h, 1.0);
  CHECK(w.state.body_v[1].y == 1.0);
  CHECK(w.state.body_v[2].y == 0.0);
  CHECK(w.state.body_w[2].x == 0.0 && w.state.body_w[2].z == 0.0);
}

// High in a tall structure (support level SHOCK_TALL_LEVEL and up) a body held by two
// supporters has every approach taken out; a lower one, or one held by a single supporter
// (a column's), approaching slower than min_approach is left to the soft contacts. Two
// columns of unit boxes 1.2 m apart and a plank across their tops.
TEST(high_on_several_supporters_even_a_slow_approach_is_taken_out) {
  SceneBuilder3 s;
  s.plane({0.0, 1.0, 0.0}, 0.0);
  const int n = constants::SHOCK_TALL_LEVEL;
  for (const double x : {-0.6, 0.6})
    for (int k = 0; k < n; ++k) s.box({x, 0.5 + k, 0.0}, {0.5, 0.5, 0.5}, 1.0);
  const int plank = s.box({0.0, n + 0.25, 0.0}, {1.5, 0.25, 0.5}, 1.0);
  World<3>& w = ready_for_shock(s.finish());
  auto& c = w.contacts;
  const int low = 2, top = n;  // the first column's second box and its top box
  CHECK(c.body_level[low] == 2 && c.body_level[top] == n && c.body_level[plank] == n + 1);
  CHECK(c.body_supporters[top] == 1 && c.body_supporters[plank] == 2);
  const double h = w.config.dt / w.config.substeps;
  const double slow = 0.5 * 9.81 * h;  // m/s: below min_approach, one substep of gravity
  for (const int i : {low, top, plank}) w.state.body_v[i] = {0.0, -slow, 0.0};
  w.state.body_v[2 * n] = {0.0, -slow, 0.0};  // the second column's top box: the plank rests
  propagate_shock(w.model, w.state, c, c.count.shock_count, 1.0 / h, 1.0, 9.81 * h);
  CHECK(w.state.body_v[low].y == -slow && w.state.body_v[top].y == -slow);
  // the plank on the two tops, falling with them, is not pushed; falling onto them, it is
  // stopped: no point of its underside over either top approaches it (each top's patch
  // taken in turn, the plank tilts a little between)
  CHECK(w.state.body_v[plank].y == -slow);
  w.state.body_v[top] = w.state.body_v[2 * n] = {};
  propagate_shock(w.model, w.state, c, c.count.shock_count, 1.0 / h, 1.0, 9.81 * h);
  for (const double x : {-1.1, -0.1, 0.1, 1.1}) {
    for (const double z : {-0.5, 0.5}) {
      const Vec3 r{x, -0.25, z};  // m: from the plank's centre to its underside
      CHECK((w.state.body_v[plank] + cross(w.state.body_w[plank], r)).y >= -1e-12);
    }
  }
}

// deep_approaching: whether a deep overlap the solve pass listed (relax_list[:deep_count])
// still closes at the bodies' velocities now (the lever arms of its solver row). The
// stack's middle box pressed into the bottom one: closing, then parting, then closing
// slower than the bound; a box closing that is not listed does not count.
TEST(deep_approaching_reads_the_listed_overlaps_only) {
  SceneBuilder s;
  World<2>& w = stack(s);
  auto& c = w.contacts;
  const int m = manifold_of(w, 1, 2);
  c.relax_list[0] = m;
  c.count.deep_count = 1;
  // (the normal points from body b to body a: a's velocity along it parts the two)
  const double sign = c.body_a[m] == 2 ? 1.0 : -1.0;
  w.state.body_v[2] = {0.0, -0.5 * sign * c.normal[m].y};  // m/s, body 2 into body 1
  CHECK(deep_approaching(w.state, c, 1e-4));
  w.state.body_v[2] = {0.0, 0.5 * sign * c.normal[m].y};  // parting
  CHECK(!deep_approaching(w.state, c, 1e-4));
  w.state.body_v[2] = {0.0, -1e-5 * sign * c.normal[m].y};  // closing, slower than the bound
  CHECK(!deep_approaching(w.state, c, 1e-4));
  w.state.body_v[2] = {0.0, 0.0};
  w.state.body_v[3] = {0.0, -2.0};  // box 3 into box 2, its manifold not listed
  CHECK(!deep_approaching(w.state, c, 1e-4));
  c.count.deep_count = 0;
  w.state.body_v[2] = {0.0, -0.5 * sign * c.normal[m].y};
  CHECK(!deep_approaching(w.state, c, 1e-4));  // nothing listed
}

// keep_closing: the listed manifolds with a point closing faster than the bound, moved to
// the list's front in their order (the deep solve's passes without the bias). The stack's
// two box-on-box manifolds listed; the middle box driven into the bottom one at 2 m/s.
TEST(keep_closing_keeps_the_manifolds_driven_in) {
  SceneBuilder s;
  World<2>& w = stack(s);
  auto& c = w.contacts;
  const int low = manifold_of(w, 1, 2), high = manifold_of(w, 2, 3);
  std::array<std::int32_t, 2> list{high, low};
  // (the normal points from body b to body a: a's velocity along it parts the two)
  const double sign = c.body_a[low] == 2 ? 1.0 : -1.0;
  w.state.body_v[2] = {0.0, -2.0 * sign * c.normal[low].y};  // m/s, body 2 into body 1
  w.state.body_v[3] = w.state.body_v[2];  // box 3 along with it: its manifold still
  CHECK(keep_closing(w.state, c, list.data(), 2, 1.0) == 1);
  CHECK(list[0] == low);
  list = {high, low};
  CHECK(keep_closing(w.state, c, list.data(), 2, 2.5) == 0);  // slower than that bound
  w.state.body_v[3] = {0.0, 0.0};  // box 2 now also parts from box 3 above it
  list = {high, low};
  CHECK(keep_closing(w.state, c, list.data(), 2, 1.0) == 1);
  CHECK(list[0] == low);
}

RBSIM_TEST_MAIN
