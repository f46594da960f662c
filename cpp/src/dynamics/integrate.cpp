// Integration stages: velocities from forces, positions from velocities; one source for
// both dimensions.
//
// Symplectic (semi-implicit) Euler integrates velocities first and moves bodies with the
// new velocity; explicit Euler moves them with the old velocity first. Both are first
// order: a projectile's height error after time t is ∓ g h t / 2 for step h.
//
// Rotation. In 2D q = (cos θ, sin θ): `normalize` is the notes' q <- normalize(q + h ω×q),
// which turns by atan(h ω) per step; `exact` turns by h ω. The unwrapped angle advances
// by the same amount, so it stays equal to q's angle. In 3D q is a unit quaternion:
// `normalize` is q <- normalize(q + (h/2) ω q), `exact` is q <- exp(h ω / 2) q. The 3D
// angular state is the angular momentum L (world frame, about the COM), changed by
// torques only, with ω = R I_b⁻¹ Rᵀ L recomputed after each rotation: a torque-free body
// keeps L exactly while its ω precesses.
#include <cmath>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// atan(x) (rad) for |x| < ATAN_SERIES_MAX from its Taylor series to x^17: a few
// multiply-adds instead of a library call, for the rotation of a slow body.
inline double atan_small(double x) {
  const double x2 = x * x;
  double p = 1.0 / 17.0;
  p = 1.0 / 15.0 - x2 * p;
  p = 1.0 / 13.0 - x2 * p;
  p = 1.0 / 11.0 - x2 * p;
  p = 1.0 / 9.0 - x2 * p;
  p = 1.0 / 7.0 - x2 * p;
  p = 1.0 / 5.0 - x2 * p;
  p = 1.0 / 3.0 - x2 * p;
  return x - x * x2 * p;
}

// Turn q by the angular velocity w over h; returns the rotation applied (for the
// body's delta) and advances the unwrapped angle (2D).
inline Rot2 turn(Rot2& q, double& angle, double w, double h, bool exact) {
  const double hw = h * w;
  Rot2 r;
  if (exact) {
    r = {std::cos(hw), std::sin(hw)};
    angle += hw;
    // renormalise: rounding drift is kept at the 1e-16 level over any run
    q = normalize(mul(r, q));
  } else {
    Rot2 n{q.c - hw * q.s, q.s + hw * q.c};
    const double inv = 1.0 / std::sqrt(n.c * n.c + n.s * n.s);
    q = {n.c * inv, n.s * inv};
    r = {inv, hw * inv};  // the rotation applied: by atan(h ω)
    angle += std::fabs(hw) < C::ATAN_SERIES_MAX ? atan_small(hw) : std::atan(hw);
  }
  return r;
}

inline Quat turn(Quat& q, double&, Vec3 w, double h, bool exact) {
  Quat r;
  if (exact) {
    const double wl = length(w);
    const double half = 0.5 * h * wl;
    // sin(half)/wl, by its series where wl is tiny
    const double k = wl > 1e-12 ? std::sin(half) / wl : 0.5 * h;
    r = {std::cos(half), k * w.x, k * w.y, k * w.z};
    q = normalize(mul(r, q));
  } else {
    Quat wq{0.0, w.x, w.y, w.z};
    Quat dq = mul(wq, q);
    const double s = 0.5 * h;
    Quat n{q.w + s * dq.w, q.x + s * dq.x, q.y + s * dq.y, q.z + s * dq.z};
    Quat before = q;
    q = normalize(n);
    // the rotation applied: q_new q_old⁻¹
    r = mul(q, Quat{before.w, -before.x, -before.y, -before.z});
  }
  return r;
}

// ω from the angular state after the body turned (3D: from L; 2D: ω is the state).
inline void refresh_angular(const Model<2>&, State<2>&, int) {}
inline void refresh_angular(const Model<3>& model, State<3>& st, int i) {
  st.body_w[i] = Dim<3>::apply_inv_inertia(model.body_inv_inertia[i], st.body_q[i], st.body_l[i]);
}

}  // namespace

template <int D>
void integrate_velocities(const Model<D>& model, State<D>& st, double h) {
  using Vec = typename Dim<D>::Vec;
  using Ang = typename Dim<D>::Ang;
  const Vec g = model.gravity;
  const double lin = 1.0 / (1.0 + h * model.linear_damping);
  const double ang = 1.0 / (1.0 + h * model.angular_damping);
  const int n = model.body_count();
  for (int i = 0; i < n; ++i) {
    if (!model.is_dynamic(i)) continue;
    Vec a = g;
    Ang torque = Dim<D>::angular_zero();
    if (model.has_forces) {
      const Vec f = model.body_force[i];
      const Vec r = rotate(st.body_q[i], model.body_force_arm[i]);
      a += model.body_inv_mass[i] * f;
      torque = model.body_torque[i] + cross(r, f);
    }
    st.body_v[i] = (st.body_v[i] + h * a) * lin;
    if constexpr (D == 2) {
      const double alpha = model.body_inv_inertia[i] * torque;
      st.body_w[i] = (st.body_w[i] + h * alpha) * ang;
    } else {
      st.body_l[i] = (st.body_l[i] + h * torque) * ang;
      refresh_angular(model, st, i);
    }
  }
}

template <int D>
void integrate_positions(const Model<D>& model, State<D>& st, std::vector<BodyDelta<D>>& delta,
                         double h, bool exact) {
  const int n = model.body_count();
  double unused_angle = 0.0;
  for (int i = 0; i < n; ++i) {
    if (model.body_type[i] == BodyType::Static) continue;
    const auto dx = h * st.body_v[i];
    st.body_x[i] += dx;
    double& angle = D == 2 ? st.body_angle[i] : unused_angle;
    const auto r = turn(st.body_q[i], angle, st.body_w[i], h, exact);
    if (model.is_dynamic(i)) refresh_angular(model, st, i);
    delta[i].dx += dx;
    delta[i].dq = mul(r, delta[i].dq);
  }
}

template void integrate_velocities(const Model<2>&, State<2>&, double);
template void integrate_positions(const Model<2>&, State<2>&, std::vector<BodyDelta<2>>&, double, bool);
template void integrate_velocities(const Model<3>&, State<3>&, double);
template void integrate_positions(const Model<3>&, State<3>&, std::vector<BodyDelta<3>>&, double, bool);

}  // namespace rbsim
