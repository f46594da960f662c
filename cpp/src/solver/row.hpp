// Point-level helpers shared by the solver's passes (solve, restitution, shock, overlap
// limit): relative normal velocity, a normal impulse at a point, a point's separation
// from its solver row or from its anchors. Header-only so that each pass inlines them.
#pragma once

#include <cmath>
#include <cstdint>

#include "rbsim/contacts.hpp"
#include "rbsim/model.hpp"
#include "rbsim/state.hpp"

namespace rbsim {

// Velocity (m/s) of the point at arm r (m) from the COM of a body moving at v, ω.
template <class Vec, class Ang>
inline Vec point_velocity(Vec v, Ang w, Vec r) {
  return v + cross(w, r);
}

// Relative normal velocity (m/s) of a's point at arm ra against b's at arm rb, along n
// from b towards a; < 0 approaching.
template <int D>
inline double normal_velocity(const State<D>& st, int a, int b, typename Dim<D>::Vec ra,
                              typename Dim<D>::Vec rb, typename Dim<D>::Vec n) {
  auto dv = point_velocity(st.body_v[a], st.body_w[a], ra) -
            point_velocity(st.body_v[b], st.body_w[b], rb);
  return dot(dv, n);
}

// Apply the normal impulse j (N·s) at a point with arms ra, rb (m): +j n on a, −j n on b.
template <int D>
inline void push_point(const Model<D>& model, State<D>& st, int a, int b,
                       typename Dim<D>::Vec ra, typename Dim<D>::Vec rb,
                       typename Dim<D>::Vec n, double j) {
  auto p = j * n;
  st.body_v[a] += model.body_inv_mass[a] * p;
  st.body_w[a] += Dim<D>::apply_inv_inertia(model.body_inv_inertia[a], st.body_q[a], cross(ra, p));
  st.body_v[b] -= model.body_inv_mass[b] * p;
  st.body_w[b] -= Dim<D>::apply_inv_inertia(model.body_inv_inertia[b], st.body_q[b], cross(rb, p));
}

// Separation now (m) of a point of a solver row: n · (d_a − d_b + R_a r_a − R_b r_b) + base,
// with the normal turned back into each body's start frame (na, nb) instead of each anchor
// forward, and moved = n · (d_a − d_b) (m).
template <class Point, class Vec>
inline double row_separation(const Point& pt, double moved, Vec na, Vec nb) {
  return moved + pt.base + dot(na, pt.ra) - dot(nb, pt.rb);
}

// Separation now (m) of point k of manifold m between bodies a and b: its separation
// anchors moved by each body's motion since the step began (contacts.body_delta).
template <int D>
inline double point_separation(const Contacts<D>& c, std::int64_t m, int k, int a, int b,
                               typename Dim<D>::Vec n) {
  const auto& da = c.body_delta[a];
  const auto& db = c.body_delta[b];
  auto pa = rotate(da.dq, c.sep_anchor_a[m][k]);
  auto pb = rotate(db.dq, c.sep_anchor_b[m][k]);
  return dot(da.dx - db.dx + pa - pb, n) + c.base_separation[m][k];
}

// (bias m/s, γ 1/kg) of a point at separation s (m) with normal row K = kn (1/kg). A gap
// (s > 0) may close in the substep, no more (speculative); an overlap is pushed out softly
// in the solve stage (use_bias) as the regularised constraint (K + γ) Δλ = −(vn + b) − γλ
// with b = max(bias_rate s, max_push), γ = soft_gamma K, and not at all in the relax
// stage. Written as selects: whether a resting point's s is just above or below zero is a
// coin toss a branch predictor would often get wrong.
struct SoftTarget {
  double bias, gamma;
};
inline SoftTarget soft_target(double s, bool use_bias, double inv_h, double bias_rate,
                              double max_push, double kn, double soft_gamma) {
  bool push = use_bias && s <= 0.0;
  double bias = s > 0.0 ? s * inv_h : 0.0;
  bias = push ? std::fmax(bias_rate * s, max_push) : bias;
  double gamma = push ? kn * soft_gamma : 0.0;
  return {bias, gamma};
}

}  // namespace rbsim
