// solver/solve.cpp: one sequential-impulse pass on contacts whose answer is known: an
// isolated impact, a closing gap, a resting box's face, Coulomb's cone.
#include <cmath>
#include <limits>

#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

namespace {

constexpr double NO_BOUNCE = std::numeric_limits<double>::infinity();  // m/s threshold

// One solver pass over every manifold: with the soft bias (the solve stage) or without (relax).
void solve_pass(World<2>& w, bool use_bias) {
  solve_contacts(w.model, w.state, w.contacts, 1.0 / rbsim::test::substep(w), use_bias, 0.0,
                 NO_BOUNCE, w.contacts.solve_order.data(), w.contacts.count.manifolds);
}

// Two balls approaching head-on, m1 = 1 kg at +2 m/s and m2 = 3 kg at -1 m/s, overlapping
// by 1 µm, no gravity.
World<2>& head_on(SceneBuilder& s) {
  s.world.model.gravity = {0.0, 0.0};
  s.circle({-0.25, 0.0}, 0.25 + 0.5e-6, 1.0, {0.0, 0.0}, {2.0, 0.0});
  s.circle({0.25, 0.0}, 0.25 + 0.5e-6, 3.0, {0.0, 0.0}, {-1.0, 0.0});
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  return w;
}

}  // namespace

// An isolated two-body impact with e = 0: the rigid pass (relax) applies
// γ = −(1 + e) m_eff v_n⁻ with m_eff = m1 m2 / (m1 + m2), which ends the approach and
// keeps the momentum.
TEST(isolated_collision_impulse_is_restitution_formula_for_e_zero) {
  SceneBuilder s;
  World<2>& w = head_on(s);
  CHECK(w.contacts.count.manifolds == 1);
  const double vn_before = rbsim::test::point_normal_velocity(w, 0, 0);
  CHECK_NEAR(vn_before, -3.0, 1e-15);
  solve_pass(w, false);
  const double m_eff = 1.0 * 3.0 / 4.0;  // kg
  CHECK_NEAR(w.contacts.normal_impulse[0][0], -m_eff * vn_before, 1e-14);
  CHECK_NEAR(rbsim::test::point_normal_velocity(w, 0, 0), 0.0, 1e-14);
  CHECK_NEAR(1.0 * w.state.body_v[0].x + 3.0 * w.state.body_v[1].x, -1.0, 1e-14);  // N·s
  CHECK_NEAR(w.state.body_v[0].x, -0.25, 1e-14);  // the common velocity, (2 − 3) / 4 m/s
}

// A gap closes within the substep and no further (speculative contact): after the solve
// stage the normal velocity is −gap / h.
TEST(speculative_gap_closes_exactly_in_one_substep) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0, -0.5}, 2.0, 0.5, 0.0);
  const double gap = 0.004;  // m
  const int ball = s.circle({0.0, 0.25 + gap}, 0.25, 1.0, {}, {0.0, -5.0});
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.count.manifolds == 1);
  solve_pass(w, true);
  const double h = rbsim::test::substep(w);
  CHECK_NEAR(w.state.body_v[ball].y, -gap / h, 1e-12);
  // a slow approach that cannot close the gap is left alone
  w.state.body_v[ball] = {0.0, -0.5 * gap / h};
  w.contacts.normal_impulse[0][0] = 0.0;
  solve_pass(w, true);
  CHECK(w.state.body_v[ball].y == -0.5 * gap / h);
}

// A box resting flat on the ground: the 2x2 block solve gives its two points mirror-image
// impulses, so gravity's step leaves no spin.
TEST(resting_box_points_get_mirror_image_impulses) {
  SceneBuilder s;
  s.ground();
  const int box = s.box({0.0, 0.5}, 0.5, 0.5, 2.0);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  CHECK(w.contacts.points[0] == 2);
  const double h = rbsim::test::substep(w);
  integrate_velocities(w.model, w.state, h);
  warm_start(w.model, w.state, w.contacts);
  solve_pass(w, true);
  const auto& lam = w.contacts.normal_impulse[0];
  CHECK(lam[0] > 0.0);
  CHECK_NEAR(lam[0], lam[1], 1e-15);           // N·s: round-off of ~0.05
  CHECK_NEAR(w.state.body_w[box], 0.0, 1e-14);  // rad/s
}

// Coulomb's law: a box sliding fast has each point's friction impulse at the cone,
// |λt| = μ λn, and slows; one barely creeping is stopped, inside the cone.
TEST(friction_impulse_is_clamped_to_coulomb_cone) {
  for (const double speed : {3.0, 1e-3}) {
    SceneBuilder s;
    s.ground(-10, 10, {0.3, 0.0});
    const int box = s.box({0.0, 0.5}, 0.5, 0.5, 1.0, {0.3, 0.0}, 0.0, {speed, 0.0});
    World<2>& w = s.finish();
    rbsim::test::collide(w);
    const double mu = w.contacts.friction[0];
    CHECK_NEAR(mu, 0.3, 1e-15);
    integrate_velocities(w.model, w.state, rbsim::test::substep(w));
    solve_pass(w, true);
    const auto& lt = w.contacts.tangent_impulse[0];
    const auto& ln = w.contacts.normal_impulse[0];
    for (int k = 0; k < 2; ++k) CHECK(std::fabs(lt[k]) <= mu * ln[k] * (1.0 + 1e-15));
    if (speed > 1.0) {
      for (int k = 0; k < 2; ++k) CHECK_NEAR(std::fabs(lt[k]), mu * ln[k], 1e-15);
      CHECK(w.state.body_v[box].x < speed && w.state.body_v[box].x > 0.0);
    } else {
      CHECK(std::fabs(lt[0]) + std::fabs(lt[1]) < mu * (ln[0] + ln[1]));  // inside the cone
      // Gauss-Seidel over the two points: each pass takes most of the creep away
      for (int it = 0; it < 30; ++it) solve_pass(w, false);
      CHECK_NEAR(w.state.body_v[box].x, 0.0, 1e-9);  // m/s: stuck
    }
  }
}

RBSIM_TEST_MAIN
