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
// keeps L exactly while its ω precesses. `split` (3D) turns the body by the free rigid
// body's own flow, split about its principal axes (turn_split). A kinematic body's
// motion is given: it turns by exactly h ω under every update.
#include <cmath>
#include <cstring>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"

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
    const double inv = 1.0 / std::sqrt(n.w * n.w + n.x * n.x + n.y * n.y + n.z * n.z);
    q = {n.w * inv, n.x * inv, n.y * inv, n.z * inv};
    // the rotation applied, q_new q_old⁻¹ = (1 + (h/2) ω) / |q + (h/2) ω q| (q_old a unit
    // quaternion, to rounding)
    const double k = s * inv;
    r = {inv, k * w.x, k * w.y, k * w.z};
  }
  return r;
}

// sin x and cos x (x in rad) from their Taylor series: to x⁹ and x¹⁰ for |x| <=
// SINCOS_SHORT_MAX, to x¹⁵ and x¹⁶ for |x| <= SINCOS_SERIES_MAX (the next terms are
// below 1e-18 of the value there, under its last bit), else the library's: a few
// multiply-adds for the turns of the split update below, up to four a body and substep,
// whose angles are small (a body at 10 rad/s turns 0.005 rad a substep at dt 1/240; at
// most MAX_ROTATION at the ω cap). Which series a body takes is its own angle's alone
// (each lane its own, in a Lanes), so that a body gets the same bits beside any others
// and on the one-body path.
inline constexpr double SINCOS_SHORT_MAX = 0.1;
inline constexpr double SINCOS_SERIES_MAX = 0.5;
// the series' coefficients from the highest power down: sin x = x + x³ (−1/3! + x² (1/5!
// − ...)), cos x = 1 + x² (−1/2! + x² (1/4! − ...))
constexpr double SIN_SERIES[] = {-1.0 / 1307674368000.0, 1.0 / 6227020800.0, -1.0 / 39916800.0,
                                 1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0};
constexpr double COS_SERIES[] = {1.0 / 20922789888000.0, -1.0 / 87178291200.0, 1.0 / 479001600.0,
                                 -1.0 / 3628800.0, 1.0 / 40320.0, -1.0 / 720.0, 1.0 / 24.0,
                                 -1.0 / 2.0};
constexpr double SIN_SHORT[] = {1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0};
constexpr double COS_SHORT[] = {-1.0 / 3628800.0, 1.0 / 40320.0, -1.0 / 720.0, 1.0 / 24.0,
                                -1.0 / 2.0};
// Σ c_k y^k by Horner's rule, c from the highest power down
template <class T, std::size_t K>
inline T horner(T y, const double (&c)[K]) {
  T p = T{} + c[0];
  for (std::size_t k = 1; k < K; ++k) p = c[k] + y * p;
  return p;
}
template <class T, std::size_t KS, std::size_t KC>
inline void sincos_series(T x, T& s, T& c, const double (&sin_c)[KS], const double (&cos_c)[KC]) {
  const T x2 = x * x;
  s = x + (x * x2) * horner(x2, sin_c);
  c = 1.0 + x2 * horner(x2, cos_c);
}
inline void sincos_small(double x, double& s, double& c) {
  const double size = std::fabs(x);
  if (size <= SINCOS_SHORT_MAX) {
    sincos_series(x, s, c, SIN_SHORT, COS_SHORT);
  } else if (size <= SINCOS_SERIES_MAX) {
    sincos_series(x, s, c, SIN_SERIES, COS_SERIES);
  } else {
    s = std::sin(x);
    c = std::cos(x);
  }
}
inline void sincos_small(Lanes x, Lanes& s, Lanes& c) {
  sincos_series(x, s, c, SIN_SHORT, COS_SHORT);
  const Lanes size = vmax(x, -x);
  const LaneMask longer = size > splat(SINCOS_SHORT_MAX);
  if (!any(longer)) return;
  Lanes sl, cl;
  sincos_series(x, sl, cl, SIN_SERIES, COS_SERIES);
  s = select(longer, sl, s);
  c = select(longer, cl, c);
  const LaneMask big = size > splat(SINCOS_SERIES_MAX);
  for (int l = 0; any(big) && l < LANES; ++l) {
    if (big[l]) {
      s[l] = std::sin(x[l]);
      c[l] = std::cos(x[l]);
    }
  }
}

// √x, correctly rounded on either type.
inline double root(double x) { return std::sqrt(x); }
inline Lanes root(Lanes x) { return vsqrt(x); }

// Quaternion products a b and a b⁻¹ (b a unit quaternion) component by component, w x y z,
// for a double or Lanes.
template <class T>
inline void quat_mul(const T (&a)[4], const T (&b)[4], T (&out)[4]) {
  out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}
template <class T>
inline void quat_mul_conj(const T (&a)[4], const T (&b)[4], T (&out)[4]) {
  const T bc[4] = {b[0], -b[1], -b[2], -b[3]};
  quat_mul(a, bc, out);
}

// a where `where` holds, else b (a double's or each lane's)
inline double pick(bool where, double a, double b) { return where ? a : b; }
inline Lanes pick(LaneMask where, Lanes a, Lanes b) { return select(where, a, b); }

// The free rigid body's flow over h, split into exact rotations. With m = Pᵀ L the body's
// angular momentum in its principal frame P (world from principal; moments I_x, I_y,
// I_z, the middle one on y as compile.py orders them), the energy is
//   H = |m|² / (2 I_y) + m_x² (1/I_x − 1/I_y) / 2 + m_z² (1/I_z − 1/I_y) / 2.
// The flow of each term is a rotation: of the last two, about principal axis x or z at
// the rate m_k (1/I_k − 1/I_y), which leaves m_k as it is; of the first (|m|² does not
// change under any of them), about L itself at |L| / I_y, which leaves m as it is and so
// commutes with the others. The symmetric sequence x(h/2) z(h) x(h/2), then about L by
// h |L| / I_y, is second order, symplectic and time-reversible, and exact for a body
// symmetric about an axis (a stick's or a disc's two equal moments: one of the axis terms
// is zero, and the other commutes with the rest); L is not touched, so a torque-free body
// keeps it to the bit. (The split into the three axes' own terms, m_k² / (2 I_k), is not
// exact there: a stick 25 times longer than thick, tumbling at 150 rad/s, gained 37 J of
// spin about its axis in one step from the order of its turns.) p (the frame P as a
// quaternion, w x y z) is turned in place; moment: I_k (kg·m²);
// l: L (world, kg·m²/s). T is double or Lanes (one body per lane). A turn by θ about axis
// k takes p to p (cos θ/2, sin θ/2 e_k) and m to R_k(−θ) m: its other two components
// turned, by cos θ = c² − s², sin θ = 2 s c.
//
// An axis whose moment equals the middle one to rounding (1e-12) has no term: a cube's or
// a sphere's three, a stick's or a disc's one. Where no body of the lanes has an axis's
// term its turns are left out (they would turn by exactly zero): a heap of cubes falling
// free costs a turn about L a substep, as `normalize` does.
inline bool any_set(bool m) { return m; }
inline bool any_set(LaneMask m) { return any(m); }

template <class T>
inline void split_flow(T (&p)[4], const T (&moment)[3], const T (&l)[3], double h) {
  const T inv_mid = 1.0 / moment[1];  // 1/(kg·m²)
  T rate[3];                          // 1/(kg·m²): 1/I_k − 1/I_y, zero within rounding
  T m[3];                             // kg·m²/s: Pᵀ L, made where an axis turns
  for (int k = 0; k < 3; k += 2) {
    const T r = 1.0 / moment[k] - inv_mid;
    rate[k] = pick(r * r > (1e-24 * inv_mid) * inv_mid, r, T{});
  }
  auto about = [&](int k, double tau) {
    const T half = ((0.5 * tau) * m[k]) * rate[k];  // rad
    T s, c;
    sincos_small(half, s, c);
    const T pw = p[0], px = p[1], py = p[2], pz = p[3];
    if (k == 0) {
      p[0] = pw * c - px * s, p[1] = pw * s + px * c, p[2] = py * c + pz * s, p[3] = pz * c - py * s;
    } else {
      p[0] = pw * c - pz * s, p[1] = px * c + py * s, p[2] = py * c - px * s, p[3] = pw * s + pz * c;
    }
    const T cos_t = c * c - s * s, sin_t = (2.0 * s) * c;
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    const T mi = m[i], mj = m[j];
    m[i] = cos_t * mi + sin_t * mj;
    m[j] = cos_t * mj - sin_t * mi;
  };
  const bool turns_x = any_set(rate[0] != 0.0), turns_z = any_set(rate[2] != 0.0);
  if (turns_x || turns_z) {
    // m = Pᵀ l: l turned by p's conjugate, l − w t + u × t with t = 2 u × l (u: p's vector)
    const T tx = 2.0 * (p[2] * l[2] - p[3] * l[1]);
    const T ty = 2.0 * (p[3] * l[0] - p[1] * l[2]);
    const T tz = 2.0 * (p[1] * l[1] - p[2] * l[0]);
    m[0] = (l[0] - p[0] * tx) + (p[2] * tz - p[3] * ty);
    m[1] = (l[1] - p[0] * ty) + (p[3] * tx - p[1] * tz);
    m[2] = (l[2] - p[0] * tz) + (p[1] * ty - p[2] * tx);
  }
  if (turns_x) about(0, 0.5 * h);
  if (turns_z) about(2, h);
  if (turns_x) about(0, 0.5 * h);
  // about L (world) by h |L| / I_y: p <- (cos θ/2, sin θ/2 L/|L|) p, the quaternion
  // (sin θ/2) / |L| taken as its limit h / (2 I_y) where L is zero
  const T size = root(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);  // kg·m²/s
  const T half = (0.5 * h) * size * inv_mid;                       // rad
  T s, c;
  sincos_small(half, s, c);
  const T k = pick(size > 0.0, s / size, (0.5 * h) * inv_mid);
  const T r[4] = {c, k * l[0], k * l[1], k * l[2]};
  const T turned[4] = {p[0], p[1], p[2], p[3]};
  quat_mul(r, turned, p);
}

// The split update of a body at rotation q (world from body) with principal axes `axes`
// (body from principal), principal moments `moment` (kg·m²) and angular momentum l (world,
// kg·m²/s) over h: q is turned in place (and normalised), and the rotation applied,
// q_new q_old⁻¹, is returned in r.
template <class T>
inline void turn_split(T (&q)[4], const T (&axes)[4], const T (&moment)[3], const T (&l)[3],
                       double h, T (&r)[4]) {
  T p[4];
  quat_mul(q, axes, p);
  split_flow(p, moment, l, h);
  T n[4];
  quat_mul_conj(p, axes, n);
  const T inv = 1.0 / root(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] + n[3] * n[3]);
  const T turned[4] = {n[0] * inv, n[1] * inv, n[2] * inv, n[3] * inv};
  quat_mul_conj(turned, q, r);
  for (int k = 0; k < 4; ++k) q[k] = turned[k];
}

// One body through turn_split (a double per component). Returns the rotation applied.
inline Quat turn_split(Quat& q, const Quat& axes, Vec3 moments, Vec3 l, double h) {
  double qq[4] = {q.w, q.x, q.y, q.z}, r[4];
  const double a[4] = {axes.w, axes.x, axes.y, axes.z};
  const double mo[3] = {moments.x, moments.y, moments.z}, ll[3] = {l.x, l.y, l.z};
  turn_split(qq, a, mo, ll, h, r);
  q = {qq[0], qq[1], qq[2], qq[3]};
  return {r[0], r[1], r[2], r[3]};
}

// ω from the angular state after the body turned (3D: from L; 2D: ω is the state).
inline void refresh_angular(const Model<2>&, State<2>&, int) {}
inline void refresh_angular(const Model<3>& model, State<3>& st, int i) {
  st.body_w[i] = Dim<3>::apply_inv_inertia(model.body_inv_inertia[i], st.body_q[i], st.body_l[i]);
}

// 2D without forces: bodies i..i+LANES-1 (all dynamic) accelerated by gravity g (m/s²)
// over h (s) and damped (lin, ang), as integrate_velocities takes each: v = (v + h g) lin,
// ω = (ω + h α) ang with α the inverse inertia times a zero torque.
inline void accelerate_lanes_2d(State<2>& st, int i, double h, Vec2 g, double lin, double ang,
                                const double* inv_inertia) {
  static_assert(sizeof(Vec2) == 2 * sizeof(double));
  const Lanes hv = splat(h), hg = hv * Lanes{g.x, g.y, g.x, g.y};
  double* v = &st.body_v[i].x;
  const Lanes v01 = (load_lanes(v) + hg) * splat(lin), v23 = (load_lanes(v + 4) + hg) * splat(lin);
  std::memcpy(v, &v01, sizeof v01);
  std::memcpy(v + 4, &v23, sizeof v23);
  const Lanes alpha = load_lanes(inv_inertia) * splat(0.0);  // 1/s²
  const Lanes w = (load_lanes(&st.body_w[i]) + hv * alpha) * splat(ang);
  std::memcpy(&st.body_w[i], &w, sizeof w);
}

}  // namespace

template <int D>
void integrate_velocities(const Model<D>& model, State<D>& st, double h) {
  integrate_velocities(model, st, h, Span{0, model.body_count()});
}

template <int D>
void integrate_velocities(const Model<D>& model, State<D>& st, double h, Span bodies) {
  using Vec = typename Dim<D>::Vec;
  using Ang = typename Dim<D>::Ang;
  const Vec g = model.gravity;
  const double lin = 1.0 / (1.0 + h * model.linear_damping);
  const double ang = 1.0 / (1.0 + h * model.angular_damping);
  // 2D without forces: LANES bodies at a time where all of them are dynamic, the same
  // operations on each component (this file rounds every one), so the same bits as one
  // by one
  const bool in_lanes = D == 2 && !model.has_forces;
  for (int i = static_cast<int>(bodies.first); i < bodies.last; ++i) {
    if constexpr (D == 2) {
      if (in_lanes && i + LANES <= bodies.last) {
        bool moving = true;
        for (int l = 0; l < LANES; ++l) moving = moving && model.is_dynamic(i + l);
        if (moving) {
          accelerate_lanes_2d(st, i, h, g, lin, ang, &model.body_inv_inertia[i]);
          i += LANES - 1;
          continue;
        }
      }
    }
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
      if (model.has_forces || ang != 1.0) {
        // (without torque or damping L, and so ω, stays as it is)
        st.body_l[i] = (st.body_l[i] + h * torque) * ang;
        refresh_angular(model, st, i);
      }
      // at most MAX_ROTATION a substep: ω and L scaled down together
      const double w2 = dot(st.body_w[i], st.body_w[i]);  // (rad/s)²
      const double w_max = C::MAX_ROTATION / h;           // rad/s
      if (w2 > w_max * w_max) {
        const double s = w_max / std::sqrt(w2);
        st.body_w[i] = s * st.body_w[i];
        st.body_l[i] = s * st.body_l[i];
      }
    }
  }
}

namespace {

// 2D, Rotation::Normalize: bodies i..i+LANES-1 (none static) moved as turn() and
// integrate_positions move each, one body in each lane. The same operations in the same
// order (this file rounds every operation: no multiply-adds), so the same bits.
void move_lanes_2d(State<2>& st, std::vector<BodyDelta<2>>& delta, int i, double h) {
  static_assert(LANES == 4 && sizeof(BodyDelta<2>) == 4 * sizeof(double));
  double* x = &st.body_x[i].x;
  double* q = &st.body_q[i].c;
  const double* v = &st.body_v[i].x;
  double* d = &delta[i].dx.x;
  const Lanes hv = splat(h);
  // x += h v, interleaved (x0 y0 x1 y1 | x2 y2 x3 y3): the same products and sums
  const Lanes dx01 = hv * load_lanes(v), dx23 = hv * load_lanes(v + 4);
  const Lanes x01 = load_lanes(x) + dx01, x23 = load_lanes(x + 4) + dx23;
  std::memcpy(x, &x01, sizeof x01);
  std::memcpy(x + 4, &x23, sizeof x23);
  const Lanes dxx = __builtin_shufflevector(dx01, dx23, 0, 2, 4, 6);
  const Lanes dxy = __builtin_shufflevector(dx01, dx23, 1, 3, 5, 7);
  // the turn by h ω, normalised
  const Lanes q01 = load_lanes(q), q23 = load_lanes(q + 4);
  const Lanes qc = __builtin_shufflevector(q01, q23, 0, 2, 4, 6);
  const Lanes qs = __builtin_shufflevector(q01, q23, 1, 3, 5, 7);
  const Lanes hw = hv * load_lanes(&st.body_w[i]);
  const Lanes nc = qc - hw * qs, ns = qs + hw * qc;
  const Lanes inv = splat(1.0) / vsqrt(nc * nc + ns * ns);
  const Lanes c = nc * inv, s = ns * inv;
  const Lanes n01 = __builtin_shufflevector(c, s, 0, 4, 1, 5);
  const Lanes n23 = __builtin_shufflevector(c, s, 2, 6, 3, 7);
  std::memcpy(q, &n01, sizeof n01);
  std::memcpy(q + 4, &n23, sizeof n23);
  const Lanes rc = inv, rs = hw * inv;  // the rotation applied
  // the angle: atan_small's series where |h ω| allows it (every lane, as a rule)
  const Lanes x2 = hw * hw;
  Lanes p = splat(1.0 / 17.0);
  p = splat(1.0 / 15.0) - x2 * p;
  p = splat(1.0 / 13.0) - x2 * p;
  p = splat(1.0 / 11.0) - x2 * p;
  p = splat(1.0 / 9.0) - x2 * p;
  p = splat(1.0 / 7.0) - x2 * p;
  p = splat(1.0 / 5.0) - x2 * p;
  p = splat(1.0 / 3.0) - x2 * p;
  Lanes turned = hw - hw * x2 * p;
  const LaneMask series = vmax(hw, -hw) < splat(C::ATAN_SERIES_MAX);
  if (!all(series))
    for (int l = 0; l < LANES; ++l)
      if (!series[l]) turned[l] = std::atan(hw[l]);
  const Lanes angle = load_lanes(&st.body_angle[i]) + turned;
  std::memcpy(&st.body_angle[i], &angle, sizeof angle);
  // the motion since the step's start
  Lanes ddx, ddy, dc, ds;
  gather_quads(d, d + 4, d + 8, d + 12, ddx, ddy, dc, ds);
  ddx += dxx;
  ddy += dxy;
  const Lanes mc = rc * dc - rs * ds, ms = rs * dc + rc * ds;  // mul(r, dq)
  const Lanes t0 = __builtin_shufflevector(ddx, ddy, 0, 4, 2, 6);  // dx.x dx.y of 0, of 2
  const Lanes t1 = __builtin_shufflevector(ddx, ddy, 1, 5, 3, 7);  // of 1, of 3
  const Lanes u0 = __builtin_shufflevector(mc, ms, 0, 4, 2, 6);    // c s of 0, of 2
  const Lanes u1 = __builtin_shufflevector(mc, ms, 1, 5, 3, 7);    // of 1, of 3
  const Lanes r0 = __builtin_shufflevector(t0, u0, 0, 1, 4, 5);
  const Lanes r1 = __builtin_shufflevector(t1, u1, 0, 1, 4, 5);
  const Lanes r2 = __builtin_shufflevector(t0, u0, 2, 3, 6, 7);
  const Lanes r3 = __builtin_shufflevector(t1, u1, 2, 3, 6, 7);
  std::memcpy(d, &r0, sizeof r0);
  std::memcpy(d + 4, &r1, sizeof r1);
  std::memcpy(d + 8, &r2, sizeof r2);
  std::memcpy(d + 12, &r3, sizeof r3);
}

// The 4×4 transpose: four records of four doubles at p0..p3 to lanes, or lanes back.
inline void store_quads(double* p0, double* p1, double* p2, double* p3, Lanes f0, Lanes f1,
                        Lanes f2, Lanes f3) {
  Lanes r0, r1, r2, r3;
  transpose_quads(f0, f1, f2, f3, r0, r1, r2, r3);  // (the transpose is its own inverse)
  std::memcpy(p0, &r0, sizeof r0);
  std::memcpy(p1, &r1, sizeof r1);
  std::memcpy(p2, &r2, sizeof r2);
  std::memcpy(p3, &r3, sizeof r3);
}

// 3D, Rotation::Normalize, the world tensors wanted: LANES dynamic bodies moved at once,
// one in each lane, by the operations and in the order that turn(), rotation_matrix,
// world_tensor's general case and ω = I⁻¹ L take for one body (no multiply-adds in this
// file; for a diagonal body tensor the general case's sums add exact zeros, and so give
// its diagonal case's values). A body gets the same bits in any lane and beside any
// others, so that the result does not depend on how the bodies are split between
// threads: every such body moves here, by whole runs of LANES where they are next to each
// other (load_xyz, gather_quads), else LANES at a time picked out one by one. (The
// one-body path is not the same to the bit: GCC fuses a product and a sum of its
// quaternion product, mul(r, dq), into one vfmsubadd in spite of -ffp-contract=off.)
struct Move3 {
  LanesXYZ x, v, w, l;    // m, m/s, rad/s, kg·m²/s
  Lanes qw, qx, qy, qz;   // the rotation
  Lanes ixx, iyy, izz, ixy, ixz, iyz;  // 1/(kg·m²): the body tensor
  LanesXYZ dx;            // m: the step's motion so far
  Lanes ew, ex, ey, ez;   // its rotation so far
  Lanes txx, tyy, tzz, txy, txz, tyz;  // out: the world tensor
  Lanes aw, ax, ay, az;   // Rotation::Split: the principal axes (body from principal)
  LanesXYZ moment;        // and the principal moments, kg·m²
};

// The principal axes and moments of bodies i..i+LANES-1, next to each other, into b's
// lanes as whole records (Split only; the same values as load_principal's, without its
// inserts one double at a time, which were a twentieth of a falling heap's step).
inline void load_principal_run(const Model<3>& model, int i, Move3& b) {
  static_assert(sizeof(Quat) == 4 * sizeof(double) && sizeof(Vec3) == 3 * sizeof(double));
  const Quat* a = &model.body_axes[i];
  gather_quads(&a[0].w, &a[1].w, &a[2].w, &a[3].w, b.aw, b.ax, b.ay, b.az);
  b.moment = load_xyz(&model.body_moments[i]);
}

// The principal axes and moments of the bodies at[l] into b's lanes (Split only).
inline void load_principal(const Model<3>& model, const int (&at)[LANES], Move3& b) {
  for (int l = 0; l < LANES; ++l) {
    const Quat& a = model.body_axes[at[l]];
    const Vec3& m = model.body_moments[at[l]];
    b.aw[l] = a.w, b.ax[l] = a.x, b.ay[l] = a.y, b.az[l] = a.z;
    b.moment.x[l] = m.x, b.moment.y[l] = m.y, b.moment.z[l] = m.z;
  }
}

template <bool SPLIT>
[[gnu::always_inline]] inline void move_3d(Move3& b, double h) {
  const Lanes hv = splat(h);
  // x += h v
  const LanesXYZ step{hv * b.v.x, hv * b.v.y, hv * b.v.z};
  b.x.x += step.x;
  b.x.y += step.y;
  b.x.z += step.z;
  Lanes rw, rx, ry, rz;  // the rotation applied
  if constexpr (SPLIT) {
    // the free body's flow, split about its principal axes (turn_split)
    Lanes q[4] = {b.qw, b.qx, b.qy, b.qz}, r[4];
    const Lanes axes[4] = {b.aw, b.ax, b.ay, b.az};
    const Lanes moment[3] = {b.moment.x, b.moment.y, b.moment.z};
    const Lanes l[3] = {b.l.x, b.l.y, b.l.z};
    turn_split(q, axes, moment, l, h, r);
    b.qw = q[0], b.qx = q[1], b.qy = q[2], b.qz = q[3];
    rw = r[0], rx = r[1], ry = r[2], rz = r[3];
  } else {
    // the turn: q <- normalize(q + (h/2) ω q), mul({0, ω}, q) written out
    const Lanes zero = splat(0.0);
    const LanesXYZ w = b.w;
    const Lanes dw = zero * b.qw - w.x * b.qx - w.y * b.qy - w.z * b.qz;
    const Lanes dqx = zero * b.qx + w.x * b.qw + w.y * b.qz - w.z * b.qy;
    const Lanes dqy = zero * b.qy - w.x * b.qz + w.y * b.qw + w.z * b.qx;
    const Lanes dqz = zero * b.qz + w.x * b.qy - w.y * b.qx + w.z * b.qw;
    const Lanes s = splat(0.5 * h);
    const Lanes nw = b.qw + s * dw, nx = b.qx + s * dqx, ny = b.qy + s * dqy, nz = b.qz + s * dqz;
    const Lanes inv = splat(1.0) / vsqrt(nw * nw + nx * nx + ny * ny + nz * nz);
    b.qw = nw * inv, b.qx = nx * inv, b.qy = ny * inv, b.qz = nz * inv;
    const Lanes k = s * inv;
    rw = inv, rx = k * w.x, ry = k * w.y, rz = k * w.z;
  }
  const Lanes qw = b.qw, qx = b.qx, qy = b.qy, qz = b.qz;
  // the world tensor R M Rᵀ at the new rotation
  const Lanes xx = qx * qx, yy = qy * qy, zz = qz * qz;
  const Lanes xy = qx * qy, xz = qx * qz, yz = qy * qz;
  const Lanes wx = qw * qx, wy = qw * qy, wz = qw * qz;
  const Lanes one = splat(1.0), two = splat(2.0);
  const Lanes r[3][3] = {{one - two * (yy + zz), two * (xy - wz), two * (xz + wy)},
                         {two * (xy + wz), one - two * (xx + zz), two * (yz - wx)},
                         {two * (xz - wy), two * (yz + wx), one - two * (xx + yy)}};
  const Lanes m[3][3] = {{b.ixx, b.ixy, b.ixz}, {b.ixy, b.iyy, b.iyz}, {b.ixz, b.iyz, b.izz}};
  Lanes a[3][3];  // R M
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a[i][j] = r[i][0] * m[0][j] + r[i][1] * m[1][j] + r[i][2] * m[2][j];
  auto at = [&](int i, int j) { return a[i][0] * r[j][0] + a[i][1] * r[j][1] + a[i][2] * r[j][2]; };
  b.txx = at(0, 0), b.tyy = at(1, 1), b.tzz = at(2, 2);
  b.txy = at(0, 1), b.txz = at(0, 2), b.tyz = at(1, 2);
  // ω = I⁻¹ L
  const LanesXYZ L = b.l;
  b.w = {b.txx * L.x + b.txy * L.y + b.txz * L.z, b.txy * L.x + b.tyy * L.y + b.tyz * L.z,
         b.txz * L.x + b.tyz * L.y + b.tzz * L.z};
  // the step's motion: dx summed, dq <- r dq
  b.dx.x += step.x;
  b.dx.y += step.y;
  b.dx.z += step.z;
  const Lanes ew = b.ew, ex = b.ex, ey = b.ey, ez = b.ez;
  b.ew = rw * ew - rx * ex - ry * ey - rz * ez;
  b.ex = rw * ex + rx * ew + ry * ez - rz * ey;
  b.ey = rw * ey - rx * ez + ry * ew + rz * ex;
  b.ez = rw * ez + rx * ey - ry * ex + rz * ew;
}

// Lane l's world tensor and step's motion, written for body i.
inline void store_lane_3d(const Move3& b, int l, int i, std::vector<BodyDelta<3>>& delta,
                          Sym3* inv_inertia_world) {
  inv_inertia_world[i] = {b.txx[l], b.tyy[l], b.tzz[l], b.txy[l], b.txz[l], b.tyz[l]};
  delta[i].dx = {b.dx.x[l], b.dx.y[l], b.dx.z[l]};
  delta[i].dq = {b.ew[l], b.ex[l], b.ey[l], b.ez[l]};
}

// Bodies i..i+LANES-1 through move_3d, their records loaded and stored as whole vectors.
void move_run_3d(const Model<3>& model, State<3>& st, std::vector<BodyDelta<3>>& delta, int i,
                 double h, bool split, Sym3* inv_inertia_world) {
  Move3 b;
  b.x = load_xyz(&st.body_x[i]);
  b.v = load_xyz(&st.body_v[i]);
  b.w = load_xyz(&st.body_w[i]);
  b.l = load_xyz(&st.body_l[i]);
  gather_quads(&st.body_q[i].w, &st.body_q[i + 1].w, &st.body_q[i + 2].w, &st.body_q[i + 3].w,
               b.qw, b.qx, b.qy, b.qz);
  const Sym3* m = &model.body_inv_inertia[i];
  gather_quads(&m[0].xx, &m[1].xx, &m[2].xx, &m[3].xx, b.ixx, b.iyy, b.izz, b.ixy);
  gather_pairs(&m[0].xz, &m[1].xz, &m[2].xz, &m[3].xz, b.ixz, b.iyz);
  const BodyDelta<3>* d = &delta[i];
  b.dx = {Lanes{d[0].dx.x, d[1].dx.x, d[2].dx.x, d[3].dx.x},
          Lanes{d[0].dx.y, d[1].dx.y, d[2].dx.y, d[3].dx.y},
          Lanes{d[0].dx.z, d[1].dx.z, d[2].dx.z, d[3].dx.z}};
  gather_quads(&d[0].dq.w, &d[1].dq.w, &d[2].dq.w, &d[3].dq.w, b.ew, b.ex, b.ey, b.ez);
  if (split) {
    load_principal_run(model, i, b);
    move_3d<true>(b, h);
  } else {
    move_3d<false>(b, h);
  }
  store_xyz(&st.body_x[i], b.x);
  store_xyz(&st.body_w[i], b.w);
  store_quads(&st.body_q[i].w, &st.body_q[i + 1].w, &st.body_q[i + 2].w, &st.body_q[i + 3].w, b.qw,
              b.qx, b.qy, b.qz);
  // the world tensors (xx yy zz xy | xz yz) and the step's motion (dx | dq), transposed
  // in registers: whole records instead of one double at a time
  static_assert(sizeof(Sym3) == 6 * sizeof(double) && sizeof(BodyDelta<3>) == 7 * sizeof(double));
  Sym3* t = inv_inertia_world + i;
  store_quads(&t[0].xx, &t[1].xx, &t[2].xx, &t[3].xx, b.txx, b.tyy, b.tzz, b.txy);
  scatter_pairs(&t[0].xz, &t[1].xz, &t[2].xz, &t[3].xz, b.txz, b.tyz);
  BodyDelta<3>* e = &delta[i];
  store_quads(&e[0].dq.w, &e[1].dq.w, &e[2].dq.w, &e[3].dq.w, b.ew, b.ex, b.ey, b.ez);
  scatter_pairs(&e[0].dx.x, &e[1].dx.x, &e[2].dx.x, &e[3].dx.x, b.dx.x, b.dx.y);
  scatter_scalars(&e[0].dx.z, &e[1].dx.z, &e[2].dx.z, &e[3].dx.z, b.dx.z);
}

// The bodies idx[0..count-1] (count <= LANES) through move_3d, picked out one by one (a
// lane past count repeats the last body and is not written back).
void move_picked_3d(const Model<3>& model, State<3>& st, std::vector<BodyDelta<3>>& delta,
                    const int* idx, int count, double h, bool split, Sym3* inv_inertia_world) {
  int at[LANES];
  for (int l = 0; l < LANES; ++l) at[l] = idx[l < count ? l : count - 1];
  Move3 b;
  for (int l = 0; l < LANES; ++l) {
    const int i = at[l];
    const Vec3 x = st.body_x[i], v = st.body_v[i], w = st.body_w[i], L = st.body_l[i];
    const Quat q = st.body_q[i];
    const Sym3& m = model.body_inv_inertia[i];
    const BodyDelta<3>& d = delta[i];
    b.x.x[l] = x.x, b.x.y[l] = x.y, b.x.z[l] = x.z;
    b.v.x[l] = v.x, b.v.y[l] = v.y, b.v.z[l] = v.z;
    b.w.x[l] = w.x, b.w.y[l] = w.y, b.w.z[l] = w.z;
    b.l.x[l] = L.x, b.l.y[l] = L.y, b.l.z[l] = L.z;
    b.qw[l] = q.w, b.qx[l] = q.x, b.qy[l] = q.y, b.qz[l] = q.z;
    b.ixx[l] = m.xx, b.iyy[l] = m.yy, b.izz[l] = m.zz;
    b.ixy[l] = m.xy, b.ixz[l] = m.xz, b.iyz[l] = m.yz;
    b.dx.x[l] = d.dx.x, b.dx.y[l] = d.dx.y, b.dx.z[l] = d.dx.z;
    b.ew[l] = d.dq.w, b.ex[l] = d.dq.x, b.ey[l] = d.dq.y, b.ez[l] = d.dq.z;
  }
  if (split) {
    load_principal(model, at, b);
    move_3d<true>(b, h);
  } else {
    move_3d<false>(b, h);
  }
  for (int l = 0; l < count; ++l) {
    const int i = at[l];
    st.body_x[i] = {b.x.x[l], b.x.y[l], b.x.z[l]};
    st.body_w[i] = {b.w.x[l], b.w.y[l], b.w.z[l]};
    st.body_q[i] = {b.qw[l], b.qx[l], b.qy[l], b.qz[l]};
    store_lane_3d(b, l, i, delta, inv_inertia_world);
  }
}

// Whether body i moves through move_3d: a dynamic body.
inline bool moves_in_lanes(const Model<3>& model, int i) { return model.is_dynamic(i); }

}  // namespace

template <int D>
void integrate_positions(const Model<D>& model, State<D>& st, std::vector<BodyDelta<D>>& delta,
                         double h, Rotation rotation) {
  integrate_positions(model, st, delta, h, rotation, Span{0, model.body_count()});
}

template <int D>
void integrate_positions(const Model<D>& model, State<D>& st, std::vector<BodyDelta<D>>& delta,
                         double h, Rotation rotation, Span bodies,
                         typename Dim<D>::Inertia* inv_inertia_world) {
  double unused_angle = 0.0;
  const bool exact = rotation != Rotation::Normalize;
  const int n = static_cast<int>(bodies.last);
  // 3D: the bodies that move in lanes (normalize and split), not in a whole run,
  // gathered LANES at a time
  const bool split = rotation == Rotation::Split;
  const bool picking = D == 3 && (!exact || split) && inv_inertia_world != nullptr;
  int picked[LANES];
  int n_picked = 0;
  for (int i = static_cast<int>(bodies.first); i < n; ++i) {
    if constexpr (D == 2) {
      // LANES bodies at once where all of them are dynamic (2D refresh_angular: nothing)
      if (!exact && i % LANES == 0 && i + LANES <= n) {
        bool moving = true;
        for (int l = 0; l < LANES; ++l) moving = moving && model.is_dynamic(i + l);
        if (moving) {
          move_lanes_2d(st, delta, i, h);
          i += LANES - 1;
          continue;
        }
      }
    }
    if constexpr (D == 3) {
      if (picking && moves_in_lanes(model, i)) {
        const bool run = i % LANES == 0 && i + LANES <= n && moves_in_lanes(model, i + 1) &&
                         moves_in_lanes(model, i + 2) && moves_in_lanes(model, i + 3);
        if (run) {
          move_run_3d(model, st, delta, i, h, split, inv_inertia_world);
          i += LANES - 1;
        } else {
          picked[n_picked++] = i;
          if (n_picked == LANES) {
            move_picked_3d(model, st, delta, picked, n_picked, h, split, inv_inertia_world);
            n_picked = 0;
          }
        }
        continue;
      }
    }
    if (model.body_type[i] == BodyType::Static) continue;
    const auto dx = h * st.body_v[i];
    st.body_x[i] += dx;
    double& angle = D == 2 ? st.body_angle[i] : unused_angle;
    // a kinematic body's motion is given: it turns by exactly h ω, whatever the update
    // (normalize turned a bar at 20 rad/s, dt 1/30, by atan(h ω): 12% short)
    const bool given = !model.is_dynamic(i);
    typename Dim<D>::Rot r;
    if constexpr (D == 3) {
      if (rotation == Rotation::Split && !given)
        r = turn_split(st.body_q[i], model.body_axes[i], model.body_moments[i], st.body_l[i], h);
      else
        r = turn(st.body_q[i], angle, st.body_w[i], h, exact || given);
    } else {
      r = turn(st.body_q[i], angle, st.body_w[i], h, exact || given);
    }
    if constexpr (D == 3) {
      if (inv_inertia_world) {
        // the tensor at the new rotation, and ω through it
        inv_inertia_world[i] = world_tensor(st.body_q[i], model.body_inv_inertia[i]);
        if (model.is_dynamic(i)) st.body_w[i] = inv_inertia_world[i] * st.body_l[i];
      } else if (model.is_dynamic(i)) {
        refresh_angular(model, st, i);
      }
    } else if (model.is_dynamic(i)) {
      refresh_angular(model, st, i);
    }
    delta[i].dx += dx;
    delta[i].dq = mul(r, delta[i].dq);
  }
  if constexpr (D == 3) {
    if (n_picked > 0) move_picked_3d(model, st, delta, picked, n_picked, h, split, inv_inertia_world);
  }
}

template void integrate_velocities(const Model<2>&, State<2>&, double);
template void integrate_velocities(const Model<2>&, State<2>&, double, Span);
template void integrate_velocities(const Model<3>&, State<3>&, double, Span);
template void integrate_positions(const Model<2>&, State<2>&, std::vector<BodyDelta<2>>&, double, Rotation, Span, double*);
template void integrate_positions(const Model<3>&, State<3>&, std::vector<BodyDelta<3>>&, double, Rotation, Span, Sym3*);
template void integrate_positions(const Model<2>&, State<2>&, std::vector<BodyDelta<2>>&, double, Rotation);
template void integrate_velocities(const Model<3>&, State<3>&, double);
template void integrate_positions(const Model<3>&, State<3>&, std::vector<BodyDelta<3>>&, double, Rotation);

}  // namespace rbsim
