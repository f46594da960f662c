// One sequential-impulse pass (normal, then friction) over the manifolds order[0..n):
// contacts.solve_order (ground first, shock.support_order) or a part of it.
//
// inv_h: 1 / substep length (1/s). use_bias: true in the solve stage (soft position
// correction), false in the relax stage (rigid, no push-out). shift (s): how far back
// the separation is to be taken when a point engages, so that the recorded (separation,
// velocity) is the state before this substep's position update: the substep length in
// the relax stage of symplectic Euler, else 0. threshold (m/s): the restitution
// threshold; a point that engages faster than it enters its manifold in bounce_list
// (count.bounce_count entries), which the restitution stage works through. A manifold
// with a point that overlaps deeper than DEEP_OVERLAP in the solve stage enters
// relax_list (count.deep_count entries).
//
// Every manifold has one or two points, and each count has its own straight-line code
// (no loop over points with selects of point 0 or 1). The body velocities are read once
// per manifold, the impulses' effect on each point's velocity is followed through the
// coupling of their rows, and the velocities are written once at the end: a shorter
// chain of dependent arithmetic than updating them after each impulse.
//
// In 2D the tangent is t = (n_y, −n_x) = cross(n, 1.0), the numba engine's convention.
#include <algorithm>
#include <cmath>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// Apply the clamp λ >= 0 to point k of manifold m, whose accumulated normal impulse is
// lam (N·s) and whose solve asks for `impulse` (N·s) at normal velocity vn (m/s) and
// separation s (m); returns the impulse applied. A point that engages (its first push
// this step, or the first after a bounce) records its approach.
template <int D>
inline double clamp_normal(Contacts<D>& c, std::int64_t m, int k, double lam, double impulse,
                           double vn, double s, double shift, double threshold) {
  // (the rarely true test first: whether a resting point's impulse is positive is a coin
  // toss, and a branch on it would often be mispredicted)
  const bool engaged = c.max_normal_impulse[m][k] > 0.0;
  if ((!engaged || c.approach_velocity[m][k] == std::numeric_limits<double>::infinity()) &&
      impulse > 0.0) {
    // the point engages: its approach speed at impact, which gravity may have raised
    // since the start of the step. Later approaches of an engaged point are the solver's
    // own doing (a warm start re-applying an impact impulse) and are not recorded; after
    // a bounce (approach set to inf) a new impact is
    c.approach_velocity[m][k] = vn;
    c.approach_separation[m][k] = s - shift * vn;
    if (vn < -threshold) {  // a bounce for the restitution stage's list
      c.bounce_list[c.count.bounce_count] = static_cast<std::int32_t>(m);
      c.count.bounce_count += 1;
    }
  }
  const double next = std::max(lam + impulse, 0.0);  // clamp the accumulated impulse
  impulse = next - lam;
  c.normal_impulse[m][k] = next;
  c.max_normal_impulse[m][k] = std::max(c.max_normal_impulse[m][k], impulse);
  return impulse;
}

// List manifold m in relax_list as having a deep overlap (count.deep_count entries; once
// the list is full it stays at its length, which means every manifold).
template <int D>
inline void mark_deep(Contacts<D>& c, std::int64_t m) {
  if (c.count.deep_count < static_cast<std::int64_t>(c.relax_list.size())) {
    c.relax_list[c.count.deep_count] = static_cast<std::int32_t>(m);
    c.count.deep_count += 1;
  }
}

}  // namespace

template <int D>
void solve_contacts(const Model<D>& model, State<D>& st, Contacts<D>& c, double inv_h,
                    bool use_bias, double shift, double threshold, const std::int32_t* order,
                    std::int64_t n) {
  static_assert(D == 2, "the solver row is 2D (SolverRow<2>)");
  using Vec = typename Dim<D>::Vec;
  const double* im = model.body_inv_mass.data();
  const double* ii = model.body_inv_inertia.data();
  Vec* v = st.body_v.data();
  double* w = st.body_w.data();
  const BodyDelta<D>* delta = c.body_delta.data();
  const SolverRow<D>* rows = c.solver_row.data();
  const double max_push = -C::CONTACT_PUSH_MAX_VELOCITY;  // m/s
  const double deep = -C::DEEP_OVERLAP;                   // m
  for (std::int64_t o = 0; o < n; ++o) {
    const std::int64_t m = order[o];
    const int a = c.body_a[m], b = c.body_b[m];
    const double ma = im[a], mb = im[b], ia = ii[a], ib = ii[b];
    Vec va = v[a], vb = v[b];
    double wa = w[a], wb = w[b];
    const SolverRow<D>& row = rows[m];
    const Vec nrm = row.normal;
    const Vec t = cross(nrm, 1.0);  // (n_y, −n_x)
    // body motion since the start of the step, for the current separation: the normal
    // turned back into each body's start frame, and the displacement along it (m)
    const BodyDelta<D>& da = delta[a];
    const BodyDelta<D>& db = delta[b];
    const double soft_gamma = row.gamma, bias_rate = row.bias_rate;
    const double moved = dot(nrm, da.dx - db.dx);
    const Vec na = inv_rotate(da.dq, nrm);
    const Vec nb = inv_rotate(db.dq, nrm);
    if (c.points[m] == 1) {
      // one point (circles, capsule ends): the two-point solve below with the second
      // point's terms dropped, so that it does not pay for them
      const auto& pt = row.point[0];
      const double s = row_separation(pt, moved, na, nb);
      const double kn = pt.kn;
      const auto [bias, gamma] =
          soft_target(s, use_bias, inv_h, bias_rate, max_push, kn, soft_gamma);
      if (use_bias && s < deep) mark_deep(c, m);
      const double rna = pt.rna, rnb = pt.rnb, rta = pt.rta, rtb = pt.rtb;
      const Vec dv = va - vb;
      const double vn = dot(dv, nrm) + (wa * rna - wb * rnb);
      double vt = dot(dv, t) + (wa * rta - wb * rtb);
      double lam = c.normal_impulse[m][0];
      const double impulse = (-vn - (bias + gamma * lam)) * (1.0 / (kn + gamma));
      const double jn = clamp_normal(c, m, 0, lam, impulse, vn, s, shift, threshold);
      double jt = 0.0;
      const double mu = row.friction;
      lam = c.tangent_impulse[m][0];
      const double limit = mu * c.normal_impulse[m][0];
      if (mu > 0.0 && !(limit == 0.0 && lam == 0.0)) {  // no normal force, no friction
        // the normal impulse turns the bodies (n · t = 0: it adds no sliding)
        vt += jn * (ia * rna * rta + ib * rnb * rtb);
        const double next = std::min(std::max(lam - pt.tangent_mass * vt, -limit), limit);
        jt = next - lam;
        c.tangent_impulse[m][0] = next;
      }
      const Vec p = jn * nrm + jt * t;
      // a static or kinematic body's velocity is unchanged: not written back, so that
      // the next manifold on it need not wait for this one
      if (ma != 0.0 || ia != 0.0) {
        v[a] = va + ma * p;
        w[a] = wa + ia * (jn * rna + jt * rta);
      }
      if (mb != 0.0 || ib != 0.0) {
        v[b] = vb - mb * p;
        w[b] = wb - ib * (jn * rnb + jt * rtb);
      }
      continue;
    }
    // two points (every manifold has one or two)
    const auto& p0 = row.point[0];
    const auto& p1 = row.point[1];
    const double s0 = row_separation(p0, moved, na, nb);
    const double s1 = row_separation(p1, moved, na, nb);
    const double kn0 = p0.kn, kn1 = p1.kn;
    const auto [b0, g0] = soft_target(s0, use_bias, inv_h, bias_rate, max_push, kn0, soft_gamma);
    const auto [b1, g1] = soft_target(s1, use_bias, inv_h, bias_rate, max_push, kn1, soft_gamma);
    if (use_bias && std::min(s0, s1) < deep) mark_deep(c, m);
    const double rna0 = p0.rna, rnb0 = p0.rnb, rta0 = p0.rta, rtb0 = p0.rtb;
    const double rna1 = p1.rna, rnb1 = p1.rnb, rta1 = p1.rta, rtb1 = p1.rtb;
    // sums grouped as two halves: each pass is one long chain of dependent arithmetic
    // through the body velocities, and a shallow sum shortens it
    const Vec dv = va - vb;
    const double dvn = dot(dv, nrm), dvt = dot(dv, t);
    const double vn0 = dvn + (wa * rna0 - wb * rnb0);
    double vn1 = dvn + (wa * rna1 - wb * rnb1);
    double vt0 = dvt + (wa * rta0 - wb * rtb0);
    double vt1 = dvt + (wa * rta1 - wb * rtb1);
    const double lam0 = c.normal_impulse[m][0], lam1 = c.normal_impulse[m][1];
    // both points as one 2x2 block, so that a face held at two points gets mirror-image
    // impulses (solved one after the other they would leave a spin that friction turns
    // into a sideways drift); one point at a time if a clamp is hit
    const double k00 = kn0 + g0, k11 = kn1 + g1, k01 = row.k01;
    const double det = k00 * k11 - k01 * k01;
    bool block = false;
    double d0 = 0.0, d1 = 0.0;
    if (det > 1.0e-9 * k00 * k11) {
      const double r0 = -vn0 - (b0 + g0 * lam0);  // the bracket is off the chain
      const double r1 = -vn1 - (b1 + g1 * lam1);
      const double inv_det = 1.0 / det;  // known before the velocities: a product on the chain
      d0 = (k11 * r0 - k01 * r1) * inv_det;
      d1 = (k00 * r1 - k01 * r0) * inv_det;
      block = lam0 + d0 >= 0.0 && lam1 + d1 >= 0.0;
    }
    // one point at a time: point 1's velocity is its value at the start plus what point
    // 0's impulse did to it through the coupling k01 of their rows. 1 / (K + γ) does not
    // wait for the velocities: a product on the chain
    if (!block) d0 = (-vn0 - (b0 + g0 * lam0)) * (1.0 / (kn0 + g0));
    const double j0 = clamp_normal(c, m, 0, lam0, d0, vn0, s0, shift, threshold);
    if (!block) {
      vn1 += j0 * k01;
      d1 = (-vn1 - (b1 + g1 * lam1)) * (1.0 / (kn1 + g1));
    }
    const double j1 = clamp_normal(c, m, 1, lam1, d1, vn1, s1, shift, threshold);
    double f0 = 0.0, f1 = 0.0;  // the friction impulses applied (N·s)
    const double mu = row.friction;
    if (mu > 0.0) {
      // the normal impulses turn the bodies (n · t = 0: they add no sliding)
      double lam = c.tangent_impulse[m][0];
      double limit = mu * c.normal_impulse[m][0];
      if (!(limit == 0.0 && lam == 0.0)) {  // no normal force, no friction
        vt0 += j0 * (ia * rna0 * rta0 + ib * rnb0 * rtb0);
        vt0 += j1 * (ia * rna1 * rta0 + ib * rnb1 * rtb0);
        const double next = std::min(std::max(lam - p0.tangent_mass * vt0, -limit), limit);
        f0 = next - lam;
        c.tangent_impulse[m][0] = next;
      }
      lam = c.tangent_impulse[m][1];
      limit = mu * c.normal_impulse[m][1];
      if (!(limit == 0.0 && lam == 0.0)) {
        vt1 += j0 * (ia * rna0 * rta1 + ib * rnb0 * rtb1);
        vt1 += j1 * (ia * rna1 * rta1 + ib * rnb1 * rtb1);
        vt1 += f0 * (ma + mb + ia * rta0 * rta1 + ib * rtb0 * rtb1);
        const double next = std::min(std::max(lam - p1.tangent_mass * vt1, -limit), limit);
        f1 = next - lam;
        c.tangent_impulse[m][1] = next;
      }
    }
    const double jn = j0 + j1, jt = f0 + f1;
    const Vec p = jn * nrm + jt * t;
    va += ma * p;
    wa += ia * ((j0 * rna0 + j1 * rna1) + (f0 * rta0 + f1 * rta1));
    vb -= mb * p;
    wb -= ib * ((j0 * rnb0 + j1 * rnb1) + (f0 * rtb0 + f1 * rtb1));
    // a static or kinematic body's velocity is unchanged: not written back, so that the
    // next manifold on it need not wait for this one
    if (ma != 0.0 || ia != 0.0) {
      v[a] = va;
      w[a] = wa;
    }
    if (mb != 0.0 || ib != 0.0) {
      v[b] = vb;
      w[b] = wb;
    }
  }
}

template void solve_contacts(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double,
                             double, const std::int32_t*, std::int64_t);

}  // namespace rbsim
