// dynamics/integrate.cpp: the same integrator in 2D and in 3D.
#include <cmath>

#include "check.hpp"
#include "rbsim/stages.hpp"

using namespace rbsim;

namespace {

template <int D>
void one_body(Model<D>& m, State<D>& s) {
  m.body_type = {BodyType::Dynamic};
  m.body_mass = {2.0};
  m.body_inv_mass = {0.5};
  m.body_com.resize(1);
  m.body_force.resize(1);
  m.body_force_arm.resize(1);
  m.body_torque.resize(1);
  s.body_x.resize(1);
  s.body_q.resize(1);
  s.body_v.resize(1);
  s.body_w.resize(1);
  if constexpr (D == 2) s.body_angle.resize(1);
  if constexpr (D == 3) s.body_l.resize(1);
}

}  // namespace

// Symplectic Euler: after n steps of h under gravity g from rest, y = -g h² n (n + 1) / 2.
TEST(projectile_matches_symplectic_euler_sum) {
  Model<2> m;
  State<2> s;
  one_body(m, s);
  m.body_inertia = {1.0};
  m.body_inv_inertia = {1.0};
  m.gravity = {0.0, -9.81};
  std::vector<BodyDelta<2>> delta(1);
  const double h = 0.01;
  const int n = 100;
  for (int k = 0; k < n; ++k) {
    integrate_velocities(m, s, h);
    integrate_positions(m, s, delta, h, false);
  }
  CHECK_NEAR(s.body_x[0].y, -9.81 * h * h * n * (n + 1) / 2.0, 1e-12);
  CHECK_NEAR(s.body_v[0].y, -9.81 * h * n, 1e-12);
  CHECK_NEAR(delta[0].dx.y, s.body_x[0].y, 1e-15);
}

// 2D `normalize` turns by atan(h ω) per step and keeps |q| = 1 and the unwrapped angle.
TEST(planar_rotation_turns_by_atan_h_omega) {
  Model<2> m;
  State<2> s;
  one_body(m, s);
  m.body_inertia = {1.0};
  m.body_inv_inertia = {1.0};
  s.body_w[0] = 50.0;
  std::vector<BodyDelta<2>> delta(1);
  const double h = 0.01;
  for (int k = 0; k < 1000; ++k) integrate_positions(m, s, delta, h, false);
  CHECK_NEAR(s.body_angle[0], 1000 * std::atan(h * 50.0), 1e-9);
  CHECK_NEAR(std::hypot(s.body_q[0].c, s.body_q[0].s), 1.0, 1e-15);
  CHECK_NEAR(std::atan2(s.body_q[0].s, s.body_q[0].c), std::remainder(s.body_angle[0], 2 * M_PI), 1e-9);
}

// A torque-free asymmetric body in 3D keeps its angular momentum L exactly (L is the
// state), while ω = R I⁻¹ Rᵀ L wanders; the same integrator that steps the plane.
TEST(free_body_in_3d_keeps_angular_momentum) {
  Model<3> m;
  State<3> s;
  one_body(m, s);
  const Sym3 inertia{1.0, 2.0, 3.0, 0.0, 0.0, 0.0};  // kg·m², principal axes
  m.body_inertia = {inertia};
  m.body_inv_inertia = {Sym3{1.0, 0.5, 1.0 / 3.0, 0.0, 0.0, 0.0}};
  s.body_l[0] = {0.1, 4.0, 0.2};  // near the intermediate axis: it tumbles
  s.body_w[0] = Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], s.body_q[0], s.body_l[0]);
  const Vec3 l0 = s.body_l[0];
  const Vec3 w0 = s.body_w[0];
  std::vector<BodyDelta<3>> delta(1);
  const double h = 1e-3;
  double w_change = 0.0;
  for (int k = 0; k < 20000; ++k) {  // 20 s: past the first flip
    integrate_velocities(m, s, h);
    integrate_positions(m, s, delta, h, true);
    w_change = std::fmax(w_change, length(s.body_w[0] - w0));
  }
  CHECK(s.body_l[0].x == l0.x && s.body_l[0].y == l0.y && s.body_l[0].z == l0.z);
  const Quat q = s.body_q[0];
  CHECK_NEAR(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z, 1.0, 1e-14);
  CHECK(w_change > 1.0);  // ω moved (the flip of the intermediate axis), L did not
  // ω stays consistent with L through the body's current orientation
  const Vec3 w = Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], q, l0);
  CHECK_NEAR(length(w - s.body_w[0]), 0.0, 1e-14);
}

// 3D `normalize` (q <- normalize(q + h/2 ω q)) and `exact` agree to first order for a
// steady spin about a principal axis, and `exact` turns by h ω exactly.
TEST(spin_about_a_principal_axis_in_3d) {
  Model<3> m;
  State<3> s;
  one_body(m, s);
  m.body_inertia = {Sym3{2.0, 2.0, 2.0, 0, 0, 0}};
  m.body_inv_inertia = {Sym3{0.5, 0.5, 0.5, 0, 0, 0}};
  s.body_l[0] = {0.0, 0.0, 2.0};  // ω = 1 rad/s about z
  s.body_w[0] = {0.0, 0.0, 1.0};
  std::vector<BodyDelta<3>> delta(1);
  for (int k = 0; k < 1000; ++k) integrate_positions(m, s, delta, 1e-3, true);
  const Quat q = s.body_q[0];
  CHECK_NEAR(2.0 * std::atan2(q.z, q.w), 1.0, 1e-12);  // turned by 1 rad about z
  CHECK_NEAR(delta[0].dq.z, q.z, 1e-12);  // the delta is not renormalised: round-off of 1000 products
}

RBSIM_TEST_MAIN
