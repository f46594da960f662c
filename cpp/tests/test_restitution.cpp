// solver/restitution.cpp: bounces by the restitution hypothesis, v_n⁺ = −e v_n⁻, through
// whole steps of worlds without gravity.
#include <cmath>

#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::Material;
using rbsim::test::SceneBuilder;

// Two balls, 1 kg at +3 m/s and 2 kg at −1 m/s, 1 cm apart: after the impact (within the
// first step) v1' = (m1 v1 + m2 v2 − m2 e (v1 − v2)) / (m1 + m2), and v2' likewise, to
// round-off, for e = 1 and e = 0.5.
TEST(isolated_collision_matches_restitution_formula) {
  for (const double e : {1.0, 0.5}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material mat{0.0, e};
    const int b1 = s.circle({-0.255, 0.0}, 0.25, 1.0, mat, {3.0, 0.0});
    const int b2 = s.circle({0.255, 0.0}, 0.25, 2.0, mat, {-1.0, 0.0});
    World<2>& w = s.finish();
    for (int k = 0; k < 10; ++k) CHECK(w.step());
    const double m1 = 1.0, m2 = 2.0, v1 = 3.0, v2 = -1.0;
    const double p = m1 * v1 + m2 * v2;
    CHECK_NEAR(w.state.body_v[b1].x, (p - m2 * e * (v1 - v2)) / (m1 + m2), 1e-12);
    CHECK_NEAR(w.state.body_v[b2].x, (p + m1 * e * (v1 - v2)) / (m1 + m2), 1e-12);
    CHECK(w.state.body_v[b1].y == 0.0 && w.state.body_v[b2].y == 0.0);
  }
}

// Newton's cradle: a ball strikes a touching row of four equal balls (e = 1) 1 cm away at
// 2 m/s, within the first step: the struck end passes the momentum along the row and the
// far ball leaves with the striker's speed, all within that step. Struck from the left by
// the first shape the impacts run in the manifolds' order; struck from the right by the
// last shape against it, so the row is resolved over several passes of the restitution
// stage within one substep.
TEST(newtons_cradle_row_passes_its_momentum_on) {
  for (const bool from_left : {true, false}) {
    SceneBuilder s;
    s.world.model.gravity = {0.0, 0.0};
    const Material steel{0.0, 1.0};
    const double r = 0.1;
    if (from_left) s.circle({-0.21, 0.0}, r, 1.0, steel, {2.0, 0.0});  // the striker
    for (int i = 0; i < 4; ++i) s.circle({2.0 * r * i, 0.0}, r, 1.0, steel);
    if (!from_left) s.circle({6.0 * r + 0.21, 0.0}, r, 1.0, steel, {-2.0, 0.0});
    const int n = s.world.model.body_count();
    const int far = from_left ? n - 1 : 0;
    World<2>& w = s.finish();
    CHECK(w.step());
    // exact but for round-off of the passes (1e-15 measured)
    for (int i = 0; i < n; ++i)
      if (i != far) CHECK_NEAR(w.state.body_v[i].x, 0.0, 1e-12);
    CHECK_NEAR(w.state.body_v[far].x, from_left ? 2.0 : -2.0, 1e-12);
    double energy = 0.0;
    for (int i = 0; i < n; ++i) energy += 0.5 * length_squared(w.state.body_v[i]);
    CHECK_NEAR(energy, 2.0, 1e-12);  // J: e = 1 keeps the kinetic energy
  }
}

// Below the restitution threshold an elastic impact is only stopped (a ball does not
// jitter at rest): 0.5 m/s < 1 m/s ends with both balls at the common velocity.
TEST(impact_below_threshold_is_inelastic) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  const Material mat{0.0, 1.0};
  const int b1 = s.circle({-0.251, 0.0}, 0.25, 1.0, mat, {0.5, 0.0});
  const int b2 = s.circle({0.251, 0.0}, 0.25, 1.0, mat);
  World<2>& w = s.finish();
  for (int k = 0; k < 10; ++k) CHECK(w.step());
  CHECK_NEAR(w.state.body_v[b1].x, 0.25, 1e-9);
  CHECK_NEAR(w.state.body_v[b2].x, 0.25, 1e-9);
}

RBSIM_TEST_MAIN
