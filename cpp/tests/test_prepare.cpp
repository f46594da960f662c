// solver/prepare.cpp: each point's effective masses, lever arms, approach and softness,
// against the formulas written out by hand.
#include <cmath>

#include "check.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::SceneBuilder;

// A small box resting off-centre on a big dynamic one, moving and turning: every row field
// matches K = 1/m_a + 1/m_b + (r_a × n)²/I_a + (r_b × n)²/I_b, the tangent's likewise, and
// the approach is the relative normal velocity at the anchors.
TEST(rows_hold_effective_masses_and_approach_velocities) {
  SceneBuilder s;
  s.world.model.gravity = {0.0, 0.0};
  s.box({0.0, 0.0}, 1.0, 0.5, 4.0, {}, 0.0, {0.1, 0.2}, 0.3);
  s.box({0.3, 0.75}, 0.25, 0.25, 1.0, {}, 0.0, {-0.2, -0.5}, 0.7);
  World<2>& w = s.finish();
  rbsim::test::collide(w);
  const auto& c = w.contacts;
  CHECK(c.count.manifolds == 1 && c.points[0] == 2);
  const int a = c.body_a[0], b = c.body_b[0];
  const auto& im = w.model.body_inv_mass;
  const auto& ii = w.model.body_inv_inertia;
  const Vec2 n = c.normal[0];
  const Vec2 t{n.y, -n.x};
  const auto& row = c.solver_row[0];
  CHECK(row.normal.x == n.x && row.normal.y == n.y);
  for (int k = 0; k < 2; ++k) {
    const Vec2 ra = c.anchor_a[0][k], rb = c.anchor_b[0][k];
    const double kn = im[a] + im[b] + ii[a] * std::pow(cross(ra, n), 2) + ii[b] * std::pow(cross(rb, n), 2);
    const double kt = im[a] + im[b] + ii[a] * std::pow(cross(ra, t), 2) + ii[b] * std::pow(cross(rb, t), 2);
    CHECK_NEAR(row.point[k].kn, kn, 1e-15);
    CHECK_NEAR(c.normal_mass[0][k], 1.0 / kn, 1e-15);
    CHECK_NEAR(row.point[k].tangent_mass, 1.0 / kt, 1e-15);
    CHECK_NEAR(row.point[k].rna, cross(ra, n), 1e-15);
    CHECK_NEAR(row.point[k].rtb, cross(rb, t), 1e-15);
    CHECK_NEAR(c.approach_velocity[0][k], rbsim::test::point_normal_velocity(w, 0, k), 1e-15);
  }
  const double k01 = im[a] + im[b] + ii[a] * cross(c.anchor_a[0][0], n) * cross(c.anchor_a[0][1], n) +
                     ii[b] * cross(c.anchor_b[0][0], n) * cross(c.anchor_b[0][1], n);
  CHECK_NEAR(row.k01, k01, 1e-15);
  // the approach differs between the points: the bodies turn
  CHECK(std::fabs(c.approach_velocity[0][0] - c.approach_velocity[0][1]) > 0.1);
}

// Contacts between two dynamic bodies take the scene's softness; contacts with a static
// body the stiffer one: twice the hertz, within the same cap of a quarter of the substep
// rate. At dt 1/60 and 4 substeps the scene's 60 Hz is the cap, and both are 60 Hz; with
// 8 substeps the cap is 120 Hz, and a static contact is twice as stiff.
TEST(static_contacts_take_the_stiffer_softness) {
  for (const int substeps : {4, 8}) {
    SceneBuilder s;
    s.ground();
    s.box({0.0, 0.5}, 0.5, 0.5, 1.0);
    s.box({0.0, 1.5}, 0.5, 0.5, 1.0);
    World<2>& w = s.finish(1.0 / 60.0, substeps);
    rbsim::test::collide(w);
    const auto& c = w.contacts;
    CHECK(c.count.manifolds == 2);
    const double h = rbsim::test::substep(w), cap = 0.25 / h;  // s, Hz
    const double hertz = std::min(constants::CONTACT_HERTZ, cap);
    const Soft soft = w.config.soft, hard = w.config.soft_static;
    const Soft want_hard = soft_parameters(std::min(2.0 * hertz, cap), constants::CONTACT_DAMPING_RATIO, h);
    CHECK(hard.bias_rate == want_hard.bias_rate && hard.mass_scale == want_hard.mass_scale);
    CHECK((hard.bias_rate != soft.bias_rate) == (substeps == 8));
    for (std::int64_t m = 0; m < 2; ++m) {
      const bool on_ground = !w.model.is_dynamic(c.body_a[m]) || !w.model.is_dynamic(c.body_b[m]);
      const Soft want = on_ground ? hard : soft;
      CHECK_NEAR(c.solver_row[m].gamma, want.impulse_scale / want.mass_scale, 1e-15);
      CHECK(c.solver_row[m].bias_rate == want.bias_rate);
    }
  }
}

// At dt 1/60 (4 substeps) the quarter-of-the-substep-rate cap holds every contact at the
// scene's softness, whatever its size; at a finer step a pair of 2 mm boxes is stiffer by
// sqrt(STIFFNESS_LENGTH / size) (so that it sinks, relative to its size, as 1 m boxes do),
// and a pair of 1 m boxes is not.
TEST(small_shapes_are_stiffer_where_the_step_allows) {
  for (const double dt : {1.0 / 60.0, 1e-4}) {
    for (const double half : {0.001, 0.5}) {  // m: 2 mm and 1 m boxes
      SceneBuilder s;
      s.world.model.gravity = {0.0, 0.0};
      s.box({0.0, 0.0}, half, half, 1.0);
      s.box({0.0, 2.0 * half}, half, half, 1.0);
      World<2>& w = s.finish(dt);
      rbsim::test::collide(w);
      const auto& row = w.contacts.solver_row[0];
      const double h = dt / 4.0, cap = 0.25 / h;
      const double size = std::hypot(half, half);  // the half diagonal
      double hertz = std::min(constants::CONTACT_HERTZ, cap);
      if (size < constants::STIFFNESS_LENGTH)
        hertz = std::min(hertz * std::sqrt(constants::STIFFNESS_LENGTH / size), cap);
      const Soft want = soft_parameters(hertz, constants::CONTACT_DAMPING_RATIO, h);
      CHECK_NEAR(row.gamma, want.impulse_scale / want.mass_scale, 1e-15);
      CHECK_NEAR(row.bias_rate, want.bias_rate, 1e-12 * want.bias_rate);
      if (dt > 1e-3 || half == 0.5) CHECK(row.bias_rate == w.config.soft.bias_rate);
      if (dt < 1e-3 && half == 0.001) CHECK(row.bias_rate > 10.0 * w.config.soft.bias_rate);
    }
  }
}

RBSIM_TEST_MAIN
