// Point-level helpers shared by the solver's passes (solve, restitution, shock, overlap
// limit): relative normal velocity, a normal impulse at a point, a point's separation
// from its solver row or from its anchors. Header-only so that each pass inlines them.
#pragma once

#include <array>
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

// Add the angular impulse dl (N·m·s, about the COM, world frame) to body i. 2D: ω += dl/I.
// 3D: the angular momentum L is the state (integrate.cpp), so L += dl and ω is found
// from it again, ω = R I_b⁻¹ Rᵀ L, at the body's rotation now: ω and L never disagree.
// A static or kinematic body (zero inverse mass) is left alone.
inline void add_angular(const Model<2>& model, State<2>& st, int i, double dl) {
  st.body_w[i] += model.body_inv_inertia[i] * dl;
}
inline void add_angular(const Model<3>& model, State<3>& st, int i, Vec3 dl) {
  if (model.body_inv_mass[i] == 0.0) return;
  st.body_l[i] += dl;
  st.body_w[i] = Dim<3>::apply_inv_inertia(model.body_inv_inertia[i], st.body_q[i], st.body_l[i]);
}
// 3D: a row's impulses changed body i's angular momentum by dl (N·m·s): L += dl, and ω by
// the row's inverse inertia tensor inv_i (world axes, the step's start: the tensor its
// effective masses were made with), so that every pass of the step sees the response its
// rows expect; the position update makes ω from L again at the body's new rotation. Taken
// through the tensor at the rotation now, the response drifted from the rows' as the body
// turned within the step, and for a body that turns fast and whose inertia is far from
// round the passes overshot, more each pass: a 2.5 cm capsule falling on one end spun up
// to 1000 rad/s in a step, and the next step's passes threw it 1e9 m.
inline void add_momentum(State<3>& st, int i, const Sym3& inv_i, Vec3 dl) {
  st.body_l[i] += dl;
  st.body_w[i] += inv_i * dl;
}

// Whether point k of manifold m holds an impulse (normal or friction).
inline bool holds_impulse(const Contacts<3>& c, std::int64_t m, int k) {
  const Vec3 jt = c.tangent_impulse[m][k];
  return c.normal_impulse[m][k] != 0.0 || jt.x != 0.0 || jt.y != 0.0 || jt.z != 0.0;
}
inline bool holds_impulse(const Contacts<2>& c, std::int64_t m, int k) {
  return c.normal_impulse[m][k] != 0.0 || c.tangent_impulse[m][k] != 0.0;
}
// Whether any point of manifold m holds an impulse.
template <int D>
inline bool holds_any(const Contacts<D>& c, std::int64_t m) {
  bool holds = false;
  for (int k = 0; k < c.points[m]; ++k) holds = holds || holds_impulse(c, m, k);
  return holds;
}

// Apply the impulse p (N·s) at a point with arms ra, rb (m): +p on a, −p on b.
template <int D>
inline void push_impulse(const Model<D>& model, State<D>& st, int a, int b,
                         typename Dim<D>::Vec ra, typename Dim<D>::Vec rb, typename Dim<D>::Vec p) {
  st.body_v[a] += model.body_inv_mass[a] * p;
  add_angular(model, st, a, cross(ra, p));
  st.body_v[b] -= model.body_inv_mass[b] * p;
  add_angular(model, st, b, -cross(rb, p));
}

// 3D: I⁻¹ x (world axes) for body i at its rotation now, the tensor add_angular pushes
// through; zero for a static or kinematic body.
inline Vec3 inv_inertia_now(const Model<3>& model, const State<3>& st, int i, Vec3 x) {
  if (model.body_inv_mass[i] == 0.0) return Vec3{};
  return Dim<3>::apply_inv_inertia(model.body_inv_inertia[i], st.body_q[i], x);
}

// The effective mass (kg) along n of a point with arms ra, rb (m), as push_point pushes
// it: 2D through the bodies' inverse inertias; 3D through the tensors at the bodies'
// rotations now, which add_angular pushes through (a row's normal_mass is the step's
// start's: a pass that pushes through the tensors now and steps by the start's overshot
// on a body that turned far within the step).
inline double point_mass_now(const Model<2>& model, const State<2>&, int a, int b, Vec2 ra,
                             Vec2 rb, Vec2 n) {
  const double rna = cross(ra, n), rnb = cross(rb, n);
  const double k = model.body_inv_mass[a] + model.body_inv_mass[b] +
                   model.body_inv_inertia[a] * rna * rna + model.body_inv_inertia[b] * rnb * rnb;
  return k > 0.0 ? 1.0 / k : 0.0;
}
inline double point_mass_now(const Model<3>& model, const State<3>& st, int a, int b, Vec3 ra,
                             Vec3 rb, Vec3 n) {
  double k = model.body_inv_mass[a] + model.body_inv_mass[b];  // 1/kg
  const Vec3 ca = cross(ra, n), cb = cross(rb, n);
  if (model.body_inv_mass[a] != 0.0) k += dot(ca, inv_inertia_now(model, st, a, ca));
  if (model.body_inv_mass[b] != 0.0) k += dot(cb, inv_inertia_now(model, st, b, cb));
  return k > 0.0 ? 1.0 / k : 0.0;
}

// Apply the normal impulse j (N·s) at a point with arms ra, rb (m): +j n on a, −j n on b.
template <int D>
inline void push_point(const Model<D>& model, State<D>& st, int a, int b,
                       typename Dim<D>::Vec ra, typename Dim<D>::Vec rb,
                       typename Dim<D>::Vec n, double j) {
  auto p = j * n;
  if constexpr (D == 2) {
    st.body_v[a] += model.body_inv_mass[a] * p;
    st.body_w[a] += model.body_inv_inertia[a] * cross(ra, p);
    st.body_v[b] -= model.body_inv_mass[b] * p;
    st.body_w[b] -= model.body_inv_inertia[b] * cross(rb, p);
  } else {
    push_impulse(model, st, a, b, ra, rb, p);
  }
}

// 3D: w · r_k for the four points' vectors r (lane k: point k).
inline Lanes dot_lanes(Vec3 w, const Vec3x4& r) {
  return dot(w, LanesXYZ{load_lanes(r.x), load_lanes(r.y), load_lanes(r.z)});
}

// 3D: an orthonormal tangent basis t1, t2 of the plane normal to the unit vector n, with
// t1 × t2 = n: t1 across n from the world axis least along n (the lowest such axis on a
// tie), so that the basis is a fixed function of n.
inline void tangent_basis(Vec3 n, Vec3& t1, Vec3& t2) {
  const double ax = std::fabs(n.x), ay = std::fabs(n.y), az = std::fabs(n.z);
  Vec3 e{0.0, 0.0, 1.0};
  if (ax <= ay && ax <= az)
    e = {1.0, 0.0, 0.0};
  else if (ay <= az)
    e = {0.0, 1.0, 0.0};
  Vec3 t = cross(n, e);
  t1 = (1.0 / length(t)) * t;
  t2 = cross(n, t1);
}

// The sliding step of friction_circle: the impulse (n1, n2) (N·s) against the slip with
// the mean mass m (kg), scaled back onto the circle of radius `limit` (N·s).
inline void friction_slide(double l1, double l2, double vt1, double vt2, double m, double limit,
                           double& n1, double& n2) {
  n1 = l1 - m * vt1;
  n2 = l2 - m * vt2;
  const double sq = n1 * n1 + n2 * n2;
  if (sq > limit * limit) {
    const double k = sq > 0.0 ? limit / std::sqrt(sq) : 0.0;
    n1 *= k;
    n2 *= k;
  }
}

// 3D: Coulomb friction at a point, as the accumulated impulse (l1, l2) (N·s, components
// along t1, t2) given the sliding velocity (vt1, vt2) (m/s) now. Sticking: the impulse
// that stops the sliding at once, through the inverse of the point's 2×2 tangent block
// (m11, m12, m22) (kg), if it lies within Coulomb's circle of radius `limit` (N·s).
// Sliding (it does not): the step against the slip with the block's mean mass m (kg: 2 /
// trace K_t), scaled back onto the circle. Clamping the block's own answer instead would
// point the friction along K_t⁻¹ v_t, not against the slip: at a point off the centre of
// mass K_t is anisotropic, and a box sliding on a slope on its four corners got friction
// splayed 20° sideways at each corner and slid 4% fast. Both steps, and the circle, are
// the same in any tangent basis.
inline void friction_circle(double& l1, double& l2, double vt1, double vt2, double m11,
                            double m12, double m22, double m, double limit) {
  double n1 = l1 - (m11 * vt1 + m12 * vt2);
  double n2 = l2 - (m12 * vt1 + m22 * vt2);
  if (n1 * n1 + n2 * n2 > limit * limit) friction_slide(l1, l2, vt1, vt2, m, limit, n1, n2);
  l1 = n1;
  l2 = n2;
}

// friction_circle as the change (d1, d2) (N·s) of the accumulated impulse (l1, l2): when
// sticking, the block's step itself, −K_t⁻¹ v_t (the new impulse less the old would put
// two more roundings and two more operations on the pass's chain of arithmetic); when
// sliding, friction_slide's impulse less (l1, l2).
inline void friction_change(double l1, double l2, double vt1, double vt2, double m11,
                            double m12, double m22, double m, double limit, double& d1,
                            double& d2) {
  d1 = -(m11 * vt1 + m12 * vt2);
  d2 = -(m12 * vt1 + m22 * vt2);
  const double n1 = l1 + d1, n2 = l2 + d2;
  if (n1 * n1 + n2 * n2 > limit * limit) {
    double s1, s2;
    friction_slide(l1, l2, vt1, vt2, m, limit, s1, s2);
    d1 = s1 - l1;
    d2 = s2 - l2;
  }
}

// Separation now (m) of a point of a solver row: n · (d_a − d_b + R_a r_a − R_b r_b) + base,
// with the normal turned back into each body's start frame (na, nb) instead of each anchor
// forward, and moved = n · (d_a − d_b) (m).
template <class Point, class Vec>
inline double row_separation(const Point& pt, double moved, Vec na, Vec nb) {
  return moved + pt.base + dot(na, pt.ra) - dot(nb, pt.rb);
}
// 3D: the same for point k of a row's points, read field by field.
inline double row_separation(const SolverRow<3>::Points& P, int k, double moved, Vec3 na,
                             Vec3 nb) {
  return moved + P.base[k] + dot(na, P.ra[k]) - dot(nb, P.rb[k]);
}
// 3D: the same for all four points at once (lane k: point k).
inline Lanes row_separation(const SolverRow<3>::Points& P, double moved, Vec3 na, Vec3 nb) {
  return splat(moved) + load_lanes(P.base) + dot_lanes(na, P.ra) - dot_lanes(nb, P.rb);
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

// 3D: a face's points (up to four) as one block. Four coplanar points make a rigid block
// of rank 3 (a box on four corners is statically indeterminate); BLOCK_EPS of the
// diagonal regularises it, which picks the smallest change of the impulses when the
// right-hand side lies in K's range (as the rigid bodies' own normal velocities do).
constexpr double BLOCK_EPS = 1e-9;

// PACKED_K[i][j]: where K_ij is in SolverRow<3>::k's upper triangle by rows.
constexpr int PACKED_K[4][4] = {{0, 1, 2, 3}, {1, 4, 5, 6}, {2, 5, 7, 8}, {3, 6, 8, 9}};
// a face's points in order: block_of over all of them
constexpr int FACE_POINTS[4] = {0, 1, 2, 3};

// K's rows and columns idx[0 .. n) (n <= 4) as the leading n × n block of A, K packed as
// SolverRow<3>::k (1/kg), or a batch's lanes of it (WideFace3::k).
template <class T, class Packed>
inline void block_of(const Packed& k, const int* idx, int n, T (&A)[4][4]) {
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A[i][j] = k[PACKED_K[idx[i]][idx[j]]];
}

// L D Lᵀ of the first N (<= 4) rows and columns of the symmetric A into f; false when a
// pivot is not above min_pivot of its diagonal (dependent rows). L_ij (i > j) is f.l[i (i
// − 1) / 2 + j].
template <int N>
inline bool ldlt_factor_n(const double (&A)[4][4], double min_pivot, BlockFactor& f) {
  auto L = [&f](int i, int j) -> double& { return f.l[i * (i - 1) / 2 + j]; };
  for (int j = 0; j < N; ++j) {
    double v = A[j][j];
    for (int p = 0; p < j; ++p) v -= L(j, p) * L(j, p) * f.d[p];
    if (!(v > min_pivot * A[j][j])) return false;
    f.d[j] = v;
    f.inv_d[j] = 1.0 / v;
    for (int i = j + 1; i < N; ++i) {
      double x = A[i][j];
      for (int p = 0; p < j; ++p) x -= L(i, p) * L(j, p) * f.d[p];
      L(i, j) = x / v;
    }
  }
  return true;
}

// The solution d of L D Lᵀ d = r for the first N rows of the factor f.
template <int N>
inline void ldlt_apply_n(const BlockFactor& f, const double* r, double* d) {
  auto L = [&f](int i, int j) { return f.l[i * (i - 1) / 2 + j]; };
  double y[4];
  for (int i = 0; i < N; ++i) {
    y[i] = r[i];
    for (int p = 0; p < i; ++p) y[i] -= L(i, p) * y[p];
  }
  for (int i = N - 1; i >= 0; --i) {
    d[i] = y[i] * f.inv_d[i];
    for (int p = i + 1; p < N; ++p) d[i] -= L(p, i) * d[p];
  }
}

// ldlt_factor_n and ldlt_apply_n for n (1..4) rows (each count its own unrolled code).
inline bool ldlt_factor(const double (&A)[4][4], int n, double min_pivot, BlockFactor& f) {
  switch (n) {
    case 1: return ldlt_factor_n<1>(A, min_pivot, f);
    case 2: return ldlt_factor_n<2>(A, min_pivot, f);
    case 3: return ldlt_factor_n<3>(A, min_pivot, f);
    default: return ldlt_factor_n<4>(A, min_pivot, f);
  }
}
inline void ldlt_apply(const BlockFactor& f, int n, const double* r, double* d) {
  switch (n) {
    case 1: ldlt_apply_n<1>(f, r, d); return;
    case 2: ldlt_apply_n<2>(f, r, d); return;
    case 3: ldlt_apply_n<3>(f, r, d); return;
    default: ldlt_apply_n<4>(f, r, d); return;
  }
}

// Solve A d = r for the first n (<= 4) rows and columns of the symmetric A by LDLᵀ; false
// when a pivot is not above min_pivot of its diagonal (dependent rows).
inline bool ldlt_solve(const double (&A)[4][4], int n, const double* r, double* d,
                       double min_pivot) {
  BlockFactor f;
  if (!ldlt_factor(A, n, min_pivot, f)) return false;
  ldlt_apply(f, n, r, d);
  return true;
}

// The factor of K + diag(g) + BLOCK_EPS diag(K) for the n points (n <= 4), K the
// symmetric 4×4 block given by its upper triangle by rows (K00 K01 K02 K03 K11 K12 K13
// K22 K23 K33; 1/kg), g (1/kg) per point; f.ok = 1 when every pivot is positive (else 0:
// the points are solved one after the other).
inline void factor_block(const std::array<double, 10>& k, const double* g, int n,
                         BlockFactor& f) {
  double A[4][4];
  block_of(k, FACE_POINTS, 4, A);
  for (int i = 0; i < n; ++i) A[i][i] += g[i] + BLOCK_EPS * A[i][i];
  f.ok = ldlt_factor(A, n, 1e-12, f) ? 1.0 : 0.0;
}

}  // namespace rbsim
