// solver/prepare.cpp: each point's effective masses, lever arms, approach and softness,
// against the formulas written out by hand; in 3D, the rows of a body turned far within
// the step made again at its rotation now.
#include <cmath>

#include "check.hpp"
#include "contacts3d_builder.hpp"
#include "scene_builder.hpp"

using namespace rbsim;
using rbsim::test::Builder3;
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

// 3D: a needle (axial moment 1/1000 of the others) and a ball, each on the ground at one
// point, both turned within the step. The needle, turned 0.5 rad about an axis across it,
// is past ROW_TURN_MAX: its row is made again with its world tensor at its rotation now
// (K = 1/m + (r × n)·I⁻¹(r × n) there, the tangent block's trace likewise) and packed again
// into its lane, its arm, normal and approach velocity those of the step's start; turned
// 0.1 rad (a weighted turn of 0.1) it is not. The ball, round, is never watched and keeps
// its row whatever its turn.
TEST(rows_of_a_body_turned_far_are_made_again_at_its_rotation_now) {
  for (const double angle : {0.5, 0.1}) {  // rad
    Builder3 s;
    const Sym3 needle_inertia{0.001, 1.0, 1.0, 0.0, 0.0, 0.0};  // kg·m²
    const Sym3 ball_inertia{0.4, 0.4, 0.4, 0.0, 0.0, 0.0};
    const Quat tilt = rbsim::test::about({0.0, 0.0, 1.0}, 0.7);
    const int needle =
        s.body({0.0, 1.0, 0.0}, 2.0, needle_inertia, tilt, {0.0, -1.0, 0.0}, {3.0, 1.0, 0.0});
    const int ball = s.body({3.0, 0.5, 0.0}, 1.0, ball_inertia, {}, {0.0, -1.0, 0.0});
    const int ground = s.fixed({0.0, 0.0, 0.0});
    World<3>& w = s.finish();
    w.model.body_moments[needle] = {0.001, 1.0, 1.0};
    w.model.body_moments[ball] = {0.4, 0.4, 0.4};
    auto& c = w.contacts;
    c.turn_watch = turn_watch(w.model);
    CHECK(c.turn_watch.size() == 1 && c.turn_watch[0].body == needle);
    const std::int64_t m_needle =
        s.manifold(needle, ground, {0, 1, 0}, {{0.3, 0.0, 0.1}}, 0.5, 0.0);
    const std::int64_t m_ball = s.manifold(ball, ground, {0, 1, 0}, {{3.0, 0.0, 0.0}}, 0.5, 0.0);
    s.prepare();
    find_waves(w.model, c);
    begin_turn_watch(w.state, c);
    const auto before_needle = c.solver_row[m_needle];
    const auto before_ball = c.solver_row[m_ball];
    const double approach = c.approach_velocity[m_needle][0];
    // both turned about z, as the position update leaves them (rotation, world tensor)
    const Quat turn = rbsim::test::about({0.0, 0.0, 1.0}, angle);
    for (const int i : {needle, ball}) {
      w.state.body_q[i] = mul(turn, w.state.body_q[i]);
      c.body_inv_inertia_world[i] = world_tensor(w.state.body_q[i], w.model.body_inv_inertia[i]);
    }
    const bool far = angle > constants::ROW_TURN_MAX;
    CHECK(mark_turned_bodies(w.state, c) == far);
    CHECK(c.body_row_remade[needle] == far && c.body_row_remade[ball] == 0);
    refresh_turned_rows(w.model, w.state, c, w.config, Span{0, c.count.manifolds});
    repack_turned_rows(w.model, c);
    const auto& row = c.solver_row[m_needle];
    const Vec3 ra = c.anchor_a[m_needle][0], n{0.0, 1.0, 0.0};
    const Quat q_rows = far ? w.state.body_q[needle] : tilt;  // the rotation its row is of
    const Vec3 rn = cross(ra, n), t1 = row.t1, t2 = row.t2;
    // 1/m + (r × u)·I⁻¹(r × u) at the rotation q_rows (1/kg)
    auto k_along = [&](Vec3 ru) {
      return 0.5 + dot(ru, rbsim::test::world_apply(q_rows, w.model.body_inv_inertia[needle], ru));
    };
    const double kn = k_along(rn), k11 = k_along(cross(ra, t1)), k22 = k_along(cross(ra, t2));
    CHECK_NEAR(row.point.kn[0], kn, 1e-12 * kn);
    CHECK_NEAR(c.normal_mass[m_needle][0], 1.0 / kn, 1e-12 / kn);
    CHECK_NEAR(row.point.tangent_mass[0], 2.0 / (k11 + k22), 1e-12 / (k11 + k22));
    CHECK((row.point.kn[0] != before_needle.point.kn[0]) == far);
    // the point, the normal and the approach are the step's start's
    const Vec3 arm = row.point.arm_a[0];
    CHECK(arm.x == ra.x && arm.y == ra.y && arm.z == ra.z);
    CHECK(row.normal.y == 1.0 && c.approach_velocity[m_needle][0] == approach);
    // the lane holds the row
    bool packed = false;
    for (std::int64_t i = 0; i < c.wave_batch[c.wave_count]; ++i)
      for (int l = 0; l < LANES; ++l)
        if (c.batches3[i].lanes.m[l] == m_needle) {
          packed = true;
          CHECK(c.batches3[i].p.kn[l] == row.point.kn[0]);
          const Vec3 wna = row.point.wna[0];
          CHECK(c.batches3[i].wnax[l] == wna.x && c.batches3[i].wnay[l] == wna.y);
        }
    CHECK(packed);
    // the ball's row is as it was
    CHECK(c.solver_row[m_ball].point.kn[0] == before_ball.point.kn[0]);
    CHECK(c.solver_row[m_ball].inv_ia.xx == before_ball.inv_ia.xx);
  }
}

RBSIM_TEST_MAIN
