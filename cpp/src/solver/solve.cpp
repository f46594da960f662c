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
// relax_list (count.deep_count entries). The depth and the push-out bound are each
// manifold's (its row's, prepare_contacts: scaled to the shapes' size).
//
// Every manifold has one or two points, and each count has its own straight-line code
// (no loop over points with selects of point 0 or 1). The body velocities are read once
// per manifold, the impulses' effect on each point's velocity is followed through the
// coupling of their rows, and the velocities are written once at the end: a shorter
// chain of dependent arithmetic than updating them after each impulse.
//
// In 2D the tangent is t = (n_y, −n_x) = cross(n, 1.0), the numba engine's convention.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// The face block's points where the whole block would pull (an impulse below zero: a face
// tipping, or a box meeting a wall by an edge, its far corners within reach but not
// touching), solved exactly: the linear complementarity problem x = λ + d >= 0,
// w = A d − r >= 0, x·w = 0, with A the block (K + diag(γ), 1/kg; four points in the set
// together regularised by BLOCK_EPS of the diagonal, as the whole block is: a face's four
// coplanar points are rank 3, fewer are not and are solved as they are), r
// each point's target (m/s) and λ its accumulated impulse (N·s). By active sets, from the
// whole block's signs (start): the points in the set are solved together, the others let
// go (x = 0, d = −λ); a point whose x comes out below zero leaves the set, and when none
// does, the first left out that is still short (w < 0 beyond rounding) comes in; at most
// 2 N sets. (The points one after the other, as the pass had them here, are not
// symmetric: a cube struck edge first into a wall at 30 m/s left it turning at 1.8 rad/s
// and sliding along its edge at 0.3 m/s, where the answer is neither.) A manifold in
// each lane of `live`, each lane's sets its own; returns the lanes where it found the
// answer, d set there. (The one-manifold pass calls it with its manifold in lane 0.)
template <int N>
LaneMask active_set_block(const Lanes (&A)[4][4], const Lanes (&r)[N], const Lanes (&lam)[N],
                          const LaneMask (&start)[N], LaneMask live, Lanes (&d)[N]) {
  const LaneMask none{};
  const Lanes zero = splat(0.0), one = splat(1.0);
  LaneMask active[N];
  LaneMask found = none, done = ~live;
  for (int k = 0; k < N; ++k) active[k] = start[k] & live;
  Lanes scale = vmax(r[0], -r[0]);  // m/s: the largest target, for rounding
  for (int k = 1; k < N; ++k) scale = vmax(scale, vmax(r[k], -r[k]));
  const Lanes tol = splat(1e-9) * scale;
  auto at = [](int i, int j) { return i * (i - 1) / 2 + j; };
  for (int pass = 0; pass < 2 * N; ++pass) {
    // the set's rows as they are; a point let go: d_k = −λ_k, its column moved right
    Lanes rhs[N], Ap[N][N];
    for (int i = 0; i < N; ++i) {
      rhs[i] = select(active[i], r[i], -lam[i]);
      for (int j = 0; j < N; ++j) {
        Ap[i][j] = select(active[i] & active[j], A[i][j], i == j ? one : zero);
        if (i != j) rhs[i] = select(active[i] & ~active[j], rhs[i] + A[i][j] * lam[j], rhs[i]);
      }
    }
    if constexpr (N == 4) {
      const LaneMask all4 = active[0] & active[1] & active[2] & active[3];
      for (int i = 0; i < N; ++i) Ap[i][i] = select(all4, Ap[i][i] + splat(BLOCK_EPS) * A[i][i], Ap[i][i]);
    }
    // L D Lᵀ (a pivot not above 1e-12 of its diagonal: dependent rows, no answer)
    Lanes l[6] = {}, piv[N], inv_d[N], dd[N];
    LaneMask ok = live;
    for (int j = 0; j < N; ++j) {
      Lanes x = Ap[j][j];
      for (int k = 0; k < j; ++k) x -= l[at(j, k)] * l[at(j, k)] * piv[k];
      const LaneMask fine = x > splat(1e-12) * Ap[j][j];
      ok &= fine;
      piv[j] = select(fine, x, one);
      inv_d[j] = one / piv[j];
      for (int i = j + 1; i < N; ++i) {
        Lanes y = Ap[i][j];
        for (int k = 0; k < j; ++k) y -= l[at(i, k)] * l[at(j, k)] * piv[k];
        l[at(i, j)] = y / piv[j];
      }
    }
    Lanes y[N];
    for (int i = 0; i < N; ++i) {
      y[i] = rhs[i];
      for (int k = 0; k < i; ++k) y[i] -= l[at(i, k)] * y[k];
    }
    for (int i = N - 1; i >= 0; --i) {
      dd[i] = y[i] * inv_d[i];
      for (int k = i + 1; k < N; ++k) dd[i] -= l[at(k, i)] * dd[k];
    }
    // who leaves (x < 0), who is short though let go (w < 0)
    LaneMask drop[N], add[N], any_drop = none, any_add = none;
    for (int i = 0; i < N; ++i) {
      Lanes w = -r[i];
      for (int j = 0; j < N; ++j) w += A[i][j] * dd[j];
      drop[i] = active[i] & (lam[i] + dd[i] < zero);
      add[i] = live & ~active[i] & (w < -tol);
      any_drop |= drop[i];
      any_add |= add[i];
    }
    const LaneMask settled = ok & ~any_drop & ~any_add;
    const LaneMask now = settled & ~done;
    for (int i = 0; i < N; ++i) d[i] = select(now, dd[i], d[i]);
    found |= now;
    done |= settled | (live & ~ok);
    if (all(done)) break;
    LaneMask taken = any_drop;  // (a lane that drops takes none in)
    for (int i = 0; i < N; ++i) {
      const LaneMask in = add[i] & ~taken;
      taken |= in;
      active[i] = (active[i] & ~drop[i]) | in;
    }
  }
  return found;
}

// Apply the clamp λ >= 0 to point k of manifold m, whose accumulated normal impulse is
// lam (N·s) and whose solve asks for `impulse` (N·s) at normal velocity vn (m/s) and
// separation s (m); returns the impulse applied. A point that engages (its first push
// this step, or the first after a bounce) records its approach.
template <int D>
inline double clamp_normal(Contacts<D>& c, std::int64_t m, int k, double lam, double impulse,
                           double vn, double s, double shift, double threshold, PassLog& log) {
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
    if (vn < -threshold) log.add_bounce(static_cast<std::int32_t>(m));  // for restitution
  }
  const double next = std::max(lam + impulse, 0.0);  // clamp the accumulated impulse
  impulse = next - lam;
  c.normal_impulse[m][k] = next;
  c.max_normal_impulse[m][k] = std::max(c.max_normal_impulse[m][k], impulse);
  return impulse;
}

// List manifold m in relax_list as having a deep overlap (count.deep_count entries; once
// the list is full it stays at its length, which means every manifold).
inline void mark_deep(PassLog& log, std::int64_t m) { log.add_deep(static_cast<std::int32_t>(m)); }

// 3D: the friction of a row's N points, each as one 2×2 block clamped to Coulomb's
// circle, in order (FORWARD: 0..N-1, the solve stage; else N-1..0, relax). vt1, vt2
// (m/s): every point's sliding velocity before any of them, carried from point to point
// through the row's couplings; jt (N·s): the points' accumulated friction impulses,
// updated; lam (N·s): their normal impulses, zero where a point is apart (no friction
// there); e1, e2 (N·s): each point's change along t1, t2 (left zero where none). Returns
// whether any point changed. (N and the order fixed at compile time: the loops over the
// points unrolled.)
template <int N, bool FORWARD>
inline bool friction_points(const SolverRow<3>& row, Vec3* jt, const double* lam, double mu,
                            double* vt1, double* vt2, double* e1, double* e2) {
  const SolverRow<3>::Points& P = row.point;
  const Vec3 t1 = row.t1, t2 = row.t2;
  bool any_change = false;
#pragma GCC unroll 4
  for (int i = 0; i < N; ++i) {
    const int k = FORWARD ? i : N - 1 - i;
    const double limit = mu * lam[k];
    if (limit == 0.0 && jt[k].x == 0.0 && jt[k].y == 0.0 && jt[k].z == 0.0) continue;
    const double l1 = dot(jt[k], t1), l2 = dot(jt[k], t2);
    double d1, d2;  // N·s: the impulse along t1, t2
    friction_change(l1, l2, vt1[k], vt2[k], P.tm11[k], P.tm12[k], P.tm22[k], P.tangent_mass[k],
                    limit, d1, d2);
    jt[k] = (l1 + d1) * t1 + (l2 + d2) * t2;
    // the points still to come: after k in the solve, before it in relax
    if constexpr (FORWARD) {
#pragma GCC unroll 4
      for (int j = k + 1; j < N; ++j) {
        const auto& cp = row.tangent_coupling[j * (j - 1) / 2 + k];
        vt1[j] += cp[0] * d1 + cp[1] * d2;
        vt2[j] += cp[2] * d1 + cp[3] * d2;
      }
    } else {
#pragma GCC unroll 4
      for (int j = 0; j < k; ++j) {
        const auto& cp = row.tangent_coupling[k * (k - 1) / 2 + j];
        vt1[j] += cp[0] * d1 + cp[2] * d2;
        vt2[j] += cp[1] * d1 + cp[3] * d2;
      }
    }
    e1[k] = d1;
    e2[k] = d2;
    any_change = true;
  }
  return any_change;
}

// Whether a manifold of N points is idle (IDLE_SPEED): each point's normal impulse lam
// and friction impulse jt (N·s) give less than that speed along its normal row K, and
// r (m/s, lane k: the speed point k's solve would remove) is at most that.
template <int N>
inline bool idle_manifold(const SolverRow<3>::Points& P, Lanes r, const double* lam,
                          const Vec3* jt) {
  constexpr double speed = C::IDLE_SPEED;
  if (any(first_lanes(N) & ((load_lanes(lam) * load_lanes(P.kn) > speed) | (r > speed))))
    return false;
  bool held = false;
#pragma GCC unroll 4
  for (int k = 0; k < N; ++k)
    held = held || length_squared(jt[k]) * (P.kn[k] * P.kn[k]) > speed * speed;
  return !held;
}

// The normal impulses (N·s) that bound the friction at a manifold's N points: each
// touching point's own (lam; `touching`: within the row's touch distance, the others
// get none), and where those sum to less than the row's friction load (load, N·s: the
// weight a heavy body's support carries through the shock pass, friction_loads) the
// shortfall shared evenly over the touching points, so that the friction of the whole
// manifold is bounded by μ times the larger of the two (shared over all the points, a
// box pitched forward by its sliding, its trailing points lifted, kept half its load's
// friction). Without a load, the touching points' own to the bit. (The 2D passes and the
// 3D batches write the same in their own variables.)
template <int N>
inline Lanes bounding_impulses(Lanes lam, double load, LaneMask touching) {
  const LaneMask on = touching & first_lanes(N);
  const Lanes own = select(on, lam, splat(0.0));
  if (!(load > 0.0)) return own;
  double total = 0.0;
  int n = 0;
  for (int k = 0; k < N; ++k) {
    if (!on[k]) continue;
    total += lam[k];
    ++n;
  }
  if (n == 0 || !(load > total)) return own;
  return select(on, lam + splat((load - total) / n), own);
}

// bounding_impulses lane by lane, LANES manifolds of N points each: held[k] (N·s), point
// k's normal impulses lam[k], raised where the touching points' (on[k]) sum to less than
// the rows' friction load by the shortfall shared over those points.
template <int N>
inline void bounding_lanes(const Lanes (&lam)[N], const LaneMask (&on)[N], Lanes load,
                           Lanes (&held)[N]) {
  const Lanes zero = splat(0.0);
  Lanes sum = select(on[0], lam[0], zero), count = select(on[0], splat(1.0), zero);
  for (int k = 1; k < N; ++k) {
    sum += select(on[k], lam[k], zero);
    count += select(on[k], splat(1.0), zero);
  }
  const LaneMask short_of = (load > sum) & (count > zero);
  const Lanes spread = (load - sum) / select(count > zero, count, splat(1.0));
  for (int k = 0; k < N; ++k) held[k] = select(short_of & on[k], lam[k] + spread, lam[k]);
}

// One manifold m of N points (1..4) in the 3D pass below (N fixed at compile time: the
// loops over the points unrolled).
template <int N>
inline void solve_manifold_3d(const Model<3>& model, State<3>& st, Contacts<3>& c,
                              std::int64_t m, double inv_h, bool use_bias, double shift,
                              double threshold, PassLog& log) {
  const double* im = model.body_inv_mass.data();
  Vec3* v = st.body_v.data();
  Vec3* w = st.body_w.data();
  const BodyDelta<3>* delta = c.body_delta.data();
  const int a = c.body_a[m], b = c.body_b[m];
  const double ma = im[a], mb = im[b];
  const SolverRow<3>& row = c.solver_row[m];
  Vec3 va = v[a], vb = v[b], wa = w[a], wb = w[b];
  Vec3 dla{}, dlb{};  // N·m·s: the angular impulses on each body
  const Vec3 nrm = row.normal, t1 = row.t1, t2 = row.t2;
  const BodyDelta<3>& da = delta[a];
  const BodyDelta<3>& db = delta[b];
  const double moved = dot(nrm, da.dx - db.dx);
  const Vec3 na = inv_rotate(da.dq, nrm);
  const Vec3 nb = inv_rotate(db.dq, nrm);
  constexpr int npts = N;
  double* lam = c.normal_impulse[m].data();
  // a point's normal velocity (m/s): (v_a + ω_a × r_a − v_b − ω_b × r_b) · n, with
  // (ω × r) · n = ω · (r × n), the row's lever
  auto normal_speed = [&](const SolverRow<3>::Point& pt) {
    return dot(va - vb, nrm) + (dot(wa, pt.rna) - dot(wb, pt.rnb));
  };
  // the normal impulse jn (N·s) at a point, on the local velocities and L's change
  auto push = [&](const SolverRow<3>::Point& pt, double jn) {
    va += (ma * jn) * nrm;
    wa += jn * pt.wna;
    dla += jn * pt.rna;
    vb -= (mb * jn) * nrm;
    wb -= jn * pt.wnb;
    dlb -= jn * pt.rnb;
  };
  const SolverRow<3>::Points& P = row.point;  // (lanes past npts: zero)
  bool deep = false;
  bool block = false;
  if constexpr (N == 1) {
    // an idle contact is left as it is (idle_manifold; most are speculative: a heap's
    // neighbours not yet touching, which hold nothing and are asked nothing)
    const auto pt = P[0];
    const double s = row_separation(pt, moved, na, nb);
    const auto [bias, gamma] =
        soft_target(s, use_bias, inv_h, row.bias_rate, row.max_push, pt.kn, row.gamma);
    const double r = -normal_speed(pt) - (bias + gamma * lam[0]);
    if (row.friction_load == 0.0 &&
        idle_manifold<1>(P, Lanes{r, 0.0, 0.0, 0.0}, lam, c.tangent_impulse[m].data())) {
      if (use_bias && s < row.deep) mark_deep(log, m);
      return;
    }
  }
  if constexpr (N >= 2) {
    // every point's target from the same velocities, one block, the points in lanes
    const LaneMask live = first_lanes(npts);
    const Lanes sep_l = row_separation(P, moved, na, nb);
    // soft_target, lane by lane
    const LaneMask out = use_bias ? (sep_l <= 0.0) & live : LaneMask{};  // pushed out
    Lanes bias = select(sep_l > 0.0, sep_l * inv_h, splat(0.0));
    bias = select(out, vmax(row.bias_rate * sep_l, splat(row.max_push)), bias);
    const Lanes gam_l = select(out, load_lanes(P.kn) * row.gamma, splat(0.0));
    const int pushed = count_lanes(out);  // points pushed out (soft rows)
    deep = any((sep_l < row.deep) & live);
    const Lanes vn_l = dot(va - vb, nrm) + (dot_lanes(wa, P.rna) - dot_lanes(wb, P.rnb));
    const Lanes r_l = -vn_l - (bias + gam_l * load_lanes(lam));
    // an idle face is left as it is (idle_manifold: its points hold and are asked
    // less than that speed). Where they hold nothing and are asked nothing (r <= 0), the
    // solve's answer is exactly that: the block's is zero (K d = r <= 0 with d >= 0
    // gives dᵀK d <= 0: d = 0), and so is each point's one after the other; friction has
    // no load and holds none. (Most of a resting wall's manifolds between neighbours side
    // by side, which took the points one after the other: their block pulls.)
    if (row.friction_load == 0.0 && idle_manifold<N>(P, r_l, lam, c.tangent_impulse[m].data())) {
      if (use_bias && deep) mark_deep(log, m);
      return;
    }
    double sep[4], vn[4], gam[4], r[4], d[4] = {0.0, 0.0, 0.0, 0.0};
    std::memcpy(sep, &sep_l, sizeof sep);
    std::memcpy(vn, &vn_l, sizeof vn);
    std::memcpy(gam, &gam_l, sizeof gam);
    std::memcpy(r, &r_l, sizeof r);
    // the block's factor: the row's own when no point or every point is pushed out
    // (prepare_contacts made them), else made here
    BlockFactor own;
    const BlockFactor* f = &own;
    if (pushed == 0)
      f = &row.rigid;
    else if (pushed == npts)
      f = &row.soft;
    else
      factor_block(row.k, gam, npts, own);
    if (f->ok != 0.0) {
      ldlt_apply(*f, npts, r, d);
      block = true;
#pragma GCC unroll 4
      for (int k = 0; k < npts; ++k) block = block && lam[k] + d[k] >= 0.0;
    }
    bool impact = false;
    for (int k = 0; k < npts; ++k) impact = impact || vn[k] < -threshold;
    if (!block && impact) {
      // where the block would pull at an impact: its exact answer, as the lanes' pass
      // finds it (active_set_block, this manifold in lane 0)
      double K[4][4];
      block_of(row.k, FACE_POINTS, 4, K);
      Lanes A[4][4];
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) A[i][j] = splat(K[i][j]);
      LaneMask start[N];
      Lanes rl[N], laml[N], exact[N];
      for (int k = 0; k < N; ++k) {
        A[k][k] += splat(gam[k]);
        const bool in = f->ok == 0.0 || lam[k] + d[k] >= 0.0;
        start[k] = in ? ~LaneMask{} : LaneMask{};
        rl[k] = splat(r[k]);
        laml[k] = splat(lam[k]);
        exact[k] = splat(0.0);
      }
      const LaneMask solved = active_set_block<N>(A, rl, laml, start, first_lanes(1), exact);
      if (solved[0] != 0) {
        for (int k = 0; k < N; ++k) d[k] = exact[k][0];
        block = true;
      }
    }
    if (block) {
      // clamp_normal for every point at once (a point that engages is recorded one by
      // one: rare)
      const Lanes lam_l = load_lanes(lam), d_l = load_lanes(d), zero = splat(0.0);
      const Lanes mx_l = load_lanes(c.max_normal_impulse[m].data());
      const Lanes ap_l = load_lanes(c.approach_velocity[m].data());
      const LaneMask engages =
          live & ((mx_l <= zero) | (ap_l == splat(std::numeric_limits<double>::infinity()))) &
          (d_l > zero);
      for (int k = 0; any(engages) && k < npts; ++k) {
        if (!engages[k]) continue;
        c.approach_velocity[m][k] = vn[k];
        c.approach_separation[m][k] = sep[k] - shift * vn[k];
        if (vn[k] < -threshold) log.add_bounce(static_cast<std::int32_t>(m));
      }
      const Lanes next = vmax(lam_l + d_l, zero);
      const Lanes j = select(live, next - lam_l, zero);  // N·s: the impulses applied
      const Lanes lam_new = select(live, next, lam_l), mx_new = select(live, vmax(mx_l, j), mx_l);
      std::memcpy(lam, &lam_new, sizeof lam_new);
      std::memcpy(c.max_normal_impulse[m].data(), &mx_new, sizeof mx_new);
      // the impulses' sum and moments about each COM, summed over the lanes
      const Lanes sa = sum_lanes(j, j * load_lanes(P.rna.x), j * load_lanes(P.rna.y),
                                 j * load_lanes(P.rna.z));
      const Lanes sb = sum_lanes(j * load_lanes(P.rnb.x), j * load_lanes(P.rnb.y),
                                 j * load_lanes(P.rnb.z), splat(0.0));
      const Vec3 ta{sa[1], sa[2], sa[3]}, tb{sb[0], sb[1], sb[2]};  // N·m·s
      va += (ma * sa[0]) * nrm;
      vb -= (mb * sa[0]) * nrm;
      wa += row.inv_ia * ta;
      wb -= row.inv_ib * tb;
      dla += ta;
      dlb -= tb;
    }
  }
  // the block was not taken: rare for two or three points, but a face of four pulls in
  // most passes of a heap (solve_face_3d)
  for (int i = 0; i < (block ? 0 : npts); ++i) {
    const int k = use_bias ? i : npts - 1 - i;  // forward in the solve, backward in relax
    const auto pt = P[k];
    const double s = row_separation(pt, moved, na, nb);
    const auto [bias, gamma] =
        soft_target(s, use_bias, inv_h, row.bias_rate, row.max_push, pt.kn, row.gamma);
    deep = deep || s < row.deep;
    const double vn = normal_speed(pt);
    const double impulse = (-vn - (bias + gamma * lam[k])) * (1.0 / (pt.kn + gamma));
    const double jn = clamp_normal(c, m, k, lam[k], impulse, vn, s, shift, threshold, log);
    push(pt, jn);
  }
  if (use_bias && deep) mark_deep(log, m);
  const double mu = row.friction;
  if (mu > 0.0) {
    // each point's friction as one 2×2 block on the velocities after the points before
    // it: every point's sliding velocity found at once (in lanes), then carried from
    // point to point through the row's couplings (a short chain of arithmetic instead
    // of the bodies' velocities through every point), the bodies' changes summed at the
    // end
    const Vec3 dv = va - vb;
    const Lanes vt1_l = dot(dv, t1) + (dot_lanes(wa, P.rt1a) - dot_lanes(wb, P.rt1b));
    const Lanes vt2_l = dot(dv, t2) + (dot_lanes(wa, P.rt2a) - dot_lanes(wb, P.rt2b));
    double vt1[4], vt2[4];
    std::memcpy(vt1, &vt1_l, sizeof vt1);
    std::memcpy(vt2, &vt2_l, sizeof vt2);
    alignas(32) double e1[4] = {0.0, 0.0, 0.0, 0.0}, e2[4] = {0.0, 0.0, 0.0, 0.0};  // N·s
    Vec3* jt = c.tangent_impulse[m].data();
    // the normal impulses of the points that touch (within row.touch): a push while apart
    // is speculative, no contact force, and has no friction (solve_contacts)
    const Lanes sep_t = row_separation(P, moved, na, nb);
    const Lanes held_l =
        bounding_impulses<N>(load_lanes(lam), row.friction_load, sep_t <= splat(row.touch));
    alignas(32) double held[4];
    std::memcpy(held, &held_l, sizeof held);
    const bool any_change = use_bias
        ? friction_points<N, true>(row, jt, held, mu, vt1, vt2, e1, e2)
        : friction_points<N, false>(row, jt, held, mu, vt1, vt2, e1, e2);
    if (any_change) {
      // the impulse and its moments about each COM, summed over the lanes
      const Lanes g1 = load_lanes(e1), g2 = load_lanes(e2);
      const Lanes s0 = sum_lanes(g1, g2, g1 * load_lanes(P.rt1a.x) + g2 * load_lanes(P.rt2a.x),
                                 g1 * load_lanes(P.rt1a.y) + g2 * load_lanes(P.rt2a.y));
      const Lanes s1 = sum_lanes(g1 * load_lanes(P.rt1a.z) + g2 * load_lanes(P.rt2a.z),
                                 g1 * load_lanes(P.rt1b.x) + g2 * load_lanes(P.rt2b.x),
                                 g1 * load_lanes(P.rt1b.y) + g2 * load_lanes(P.rt2b.y),
                                 g1 * load_lanes(P.rt1b.z) + g2 * load_lanes(P.rt2b.z));
      const Vec3 p = s0[0] * t1 + s0[1] * t2;  // N·s
      const Vec3 la_t{s0[2], s0[3], s1[0]}, lb_t{s1[1], s1[2], s1[3]};  // N·m·s
      va += ma * p;
      vb -= mb * p;
      wa += row.inv_ia * la_t;
      wb -= row.inv_ib * lb_t;
      dla += la_t;
      dlb -= lb_t;
    }
  }
  // a static or kinematic body is not written (its velocity does not change)
  if (ma != 0.0) {
    v[a] = va;
    add_momentum(st, a, row.inv_ia, dla);
  }
  if (mb != 0.0) {
    v[b] = vb;
    add_momentum(st, b, row.inv_ib, dlb);
  }
}

// The 3D pass, one manifold after the other (solve_manifold_3d): its normal rows first,
// then each point's friction as one 2×2 block clamped to Coulomb's circle. The bodies'
// velocities are followed through the manifold in local copies, with the row's world
// inverse inertia tensors (the step's start); what the manifold changes is written back
// once, as momentum: v += Δp/m, L += ΔL, and ω += I⁻¹ ΔL through the row's tensor
// (add_momentum; the position update makes ω = R I_b⁻¹ Rᵀ L again after it turns the body).
//
// A face's points (two to four) are solved as one block, as 2D solves its two: one after
// the other, a box resting on four corners got unequal impulses and a slow spin (1e-8
// rad/s) that friction turned into a drift. Four coplanar points make a rigid block of
// rank 3 (a box on four corners is statically indeterminate): the soft rows' γ makes
// the solve stage's block regular, and the relax stage's is regularised by BLOCK_EPS of
// its diagonal, which picks the smallest change of the impulses (the right-hand side,
// the rigid bodies' own normal velocities, lies in K's range). When the block would pull
// (an impulse < 0: a face tipping) at an impact its exact answer is taken
// (active_set_block); elsewhere the points go one after the other, the solve stage
// forward and the relax stage backward. (factor_block, BLOCK_EPS: row.hpp) An idle face
// (idle_manifold, IDLE_SPEED) is left as it is.
void solve_contacts_3d(const Model<3>& model, State<3>& st, Contacts<3>& c, double inv_h,
                       bool use_bias, double shift, double threshold, const std::int32_t* order,
                       std::int64_t n, PassLog& log) {
  for (std::int64_t o = 0; o < n; ++o) {
    const std::int64_t m = order[o];
    switch (c.points[m]) {
      case 1: solve_manifold_3d<1>(model, st, c, m, inv_h, use_bias, shift, threshold, log); break;
      case 2: solve_manifold_3d<2>(model, st, c, m, inv_h, use_bias, shift, threshold, log); break;
      case 3: solve_manifold_3d<3>(model, st, c, m, inv_h, use_bias, shift, threshold, log); break;
      case 4: solve_manifold_3d<4>(model, st, c, m, inv_h, use_bias, shift, threshold, log); break;
      default: break;
    }
  }
}

}  // namespace

template <int D>
void solve_contacts(const Model<D>& model, State<D>& st, Contacts<D>& c, double inv_h,
                    bool use_bias, double shift, double threshold, const std::int32_t* order,
                    std::int64_t n) {
  PassLog log = PassLog::direct(c);
  solve_contacts(model, st, c, inv_h, use_bias, shift, threshold, order, n, log);
}

template <int D>
void solve_contacts(const Model<D>& model, State<D>& st, Contacts<D>& c, double inv_h,
                    bool use_bias, double shift, double threshold, const std::int32_t* order,
                    std::int64_t n, PassLog& log) {
  if constexpr (D == 3) {
    solve_contacts_3d(model, st, c, inv_h, use_bias, shift, threshold, order, n, log);
  } else {
  using Vec = typename Dim<D>::Vec;
  const double* im = model.body_inv_mass.data();
  const double* ii = model.body_inv_inertia.data();
  Vec* v = st.body_v.data();
  double* w = st.body_w.data();
  const BodyDelta<D>* delta = c.body_delta.data();
  const SolverRow<D>* rows = c.solver_row.data();
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
    const double max_push = row.max_push, deep = row.deep;  // m/s, m
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
      if (use_bias && s < deep) mark_deep(log, m);
      const double rna = pt.rna, rnb = pt.rnb, rta = pt.rta, rtb = pt.rtb;
      const Vec dv = va - vb;
      const double vn = dot(dv, nrm) + (wa * rna - wb * rnb);
      double vt = dot(dv, t) + (wa * rta - wb * rtb);
      double lam = c.normal_impulse[m][0];
      const double impulse = (-vn - (bias + gamma * lam)) * (1.0 / (kn + gamma));
      const double jn = clamp_normal(c, m, 0, lam, impulse, vn, s, shift, threshold, log);
      double jt = 0.0;
      const double mu = row.friction;
      lam = c.tangent_impulse[m][0];
      // friction only where the point touches (within row.touch): a push while apart is
      // speculative, no contact force; it gets its friction in the relax pass once the
      // positions have brought the point to the surface (the limit is the substep's
      // accumulated normal impulse), or from the impact (restitution.cpp)
      // (or by a heavy body's load, which the shock pass carries: bounding_impulses)
      const double held = std::max(c.normal_impulse[m][0], row.friction_load);  // N·s
      const double limit = s <= row.touch ? mu * held : 0.0;
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
    if (use_bias && std::min(s0, s1) < deep) mark_deep(log, m);
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
    const double j0 = clamp_normal(c, m, 0, lam0, d0, vn0, s0, shift, threshold, log);
    if (!block) {
      vn1 += j0 * k01;
      d1 = (-vn1 - (b1 + g1 * lam1)) * (1.0 / (kn1 + g1));
    }
    const double j1 = clamp_normal(c, m, 1, lam1, d1, vn1, s1, shift, threshold, log);
    double f0 = 0.0, f1 = 0.0;  // the friction impulses applied (N·s)
    const double mu = row.friction;
    if (mu > 0.0) {
      // the normal impulses turn the bodies (n · t = 0: they add no sliding); friction
      // only where a point touches (as for one point)
      // N·s: the touching points' normal impulses, and their share of the row's friction
      // load beyond them (bounding_impulses)
      const bool on0 = s0 <= row.touch, on1 = s1 <= row.touch;
      double held0 = on0 ? c.normal_impulse[m][0] : 0.0;
      double held1 = on1 ? c.normal_impulse[m][1] : 0.0;
      const double load = row.friction_load, sum = held0 + held1;
      if (load > sum && (on0 || on1)) {
        const double share = (load - sum) / (on0 && on1 ? 2.0 : 1.0);
        if (on0) held0 += share;
        if (on1) held1 += share;
      }
      double lam = c.tangent_impulse[m][0];
      double limit = mu * held0;
      if (!(limit == 0.0 && lam == 0.0)) {  // no normal force, no friction
        vt0 += j0 * (ia * rna0 * rta0 + ib * rnb0 * rtb0);
        vt0 += j1 * (ia * rna1 * rta0 + ib * rnb1 * rtb0);
        const double next = std::min(std::max(lam - p0.tangent_mass * vt0, -limit), limit);
        f0 = next - lam;
        c.tangent_impulse[m][0] = next;
      }
      lam = c.tangent_impulse[m][1];
      limit = mu * held1;
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
}

template void solve_contacts(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double,
                             double, const std::int32_t*, std::int64_t);
template void solve_contacts(const Model<3>&, State<3>&, Contacts<3>&, double, bool, double,
                             double, const std::int32_t*, std::int64_t);
template void solve_contacts(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double,
                             double, const std::int32_t*, std::int64_t, PassLog&);
template void solve_contacts(const Model<3>&, State<3>&, Contacts<3>&, double, bool, double,
                             double, const std::int32_t*, std::int64_t, PassLog&);

namespace {

// The clamp λ >= 0 of point k in every lane of a batch where `on` (lane l: manifold ms[l]):
// what clamp_normal does for one manifold, lane by lane (2D and 3D). A point that engages
// is recorded lane by lane (rare: a resting point engaged in an earlier pass).
// `held`, when given, is the lanes' own copy of the approach speeds (2D: the batch's,
// take_impulses), written too.
template <int D>
inline Lanes clamp_lanes(Contacts<D>& c, const std::int32_t (&ms)[LANES], int k, LaneMask on,
                         Lanes lam, Lanes impulse, Lanes vn, Lanes s, Lanes& max_impulse,
                         Lanes approach, double shift, double threshold, Lanes& accumulated,
                         PassLog& log, Lanes* held = nullptr) {
  const Lanes zero = splat(0.0);
  const LaneMask engages =
      on & ((max_impulse <= zero) | (approach == splat(std::numeric_limits<double>::infinity()))) &
      (impulse > zero);
  for (int l = 0; any(engages) && l < LANES; ++l) {
    if (!engages[l]) continue;
    const std::int64_t m = ms[l];
    c.approach_velocity[m][k] = vn[l];
    if (held) (*held)[l] = vn[l];
    c.approach_separation[m][k] = s[l] - shift * vn[l];
    if (vn[l] < -threshold) log.add_bounce(static_cast<std::int32_t>(m));  // for restitution
  }
  const Lanes next = vmax(lam + impulse, zero);  // clamp the accumulated impulse
  const Lanes applied = select(on, next - lam, zero);
  accumulated = select(on, next, lam);
  max_impulse = select(on, vmax(max_impulse, applied), max_impulse);
  return applied;
}

// One batch of LANES manifolds of one wave, all with TWO points or all with one:
// solve_contacts' code for that count, lane by lane. The impulses are the batch's own
// (take_impulses).
// ONLY: solve only the lanes set in `only` (bit l: lane l), the others left as they are.
template <bool TWO, bool ONLY = false>
void solve_batch(State<2>& st, Contacts<2>& c, WideBatch& B, double inv_h, bool use_bias,
                 double shift, double threshold, PassLog& log, unsigned only = 0) {
  static_assert(LANES == 4, "the gathers below are written for four lanes");
  Vec2* v = st.body_v.data();
  double* w = st.body_w.data();
  const BodyDelta<2>* delta = c.body_delta.data();
  // the lanes' bodies and impulses, each vector built at once from its lanes' values (a
  // vector assembled lane by lane through memory would wait on store forwarding)
  const int a0 = B.a[0], a1 = B.a[1], a2 = B.a[2], a3 = B.a[3];
  const int b0i = B.b[0], b1i = B.b[1], b2i = B.b[2], b3i = B.b[3];
  Lanes vax, vay, vbx, vby;
  gather_pairs(&v[a0].x, &v[a1].x, &v[a2].x, &v[a3].x, vax, vay);
  gather_pairs(&v[b0i].x, &v[b1i].x, &v[b2i].x, &v[b3i].x, vbx, vby);
  Lanes wa = {w[a0], w[a1], w[a2], w[a3]};
  Lanes wb = {w[b0i], w[b1i], w[b2i], w[b3i]};
  static_assert(sizeof(BodyDelta<2>) == 4 * sizeof(double), "dx.x, dx.y, dq.c, dq.s");
  Lanes dax, day, dac, das, dbx, dby, dbc, dbs;
  gather_quads(&delta[a0].dx.x, &delta[a1].dx.x, &delta[a2].dx.x, &delta[a3].dx.x, dax, day, dac, das);
  gather_quads(&delta[b0i].dx.x, &delta[b1i].dx.x, &delta[b2i].dx.x, &delta[b3i].dx.x, dbx, dby, dbc,
               dbs);
  // (an empty lane's impulses are zero, as its rows: it changes nothing)
  const Lanes zero = splat(0.0);
  const Lanes lam0 = B.n0, ap0 = B.ap0;
  Lanes tl0 = B.t0, mx0 = B.x0;
  const Lanes lam1 = TWO ? B.n1 : zero, ap1 = TWO ? B.ap1 : zero;
  Lanes tl1 = TWO ? B.t1 : zero, mx1 = TWO ? B.x1 : zero;
  LaneMask active = B.live;
  std::uint32_t writes = B.writes;
  if constexpr (ONLY) {
    active &= lanes_of_bits(only);
    writes &= only | only << LANES;
  }
  const Lanes nx = B.nx, ny = B.ny;
  const Lanes tx = ny, ty = -nx;  // t = (n_y, −n_x)
  const Lanes ma = B.ma, mb = B.mb, ia = B.ia, ib = B.ib;
  // the separation now: the normal turned back into each body's start frame
  const Lanes moved = nx * (dax - dbx) + ny * (day - dby);
  const Lanes nax = dac * nx + das * ny, nay = -das * nx + dac * ny;
  const Lanes nbx = dbc * nx + dbs * ny, nby = -dbs * nx + dbc * ny;
  const WidePoint& p0 = B.p0;
  const WidePoint& p1 = B.p1;
  // each row's push-out bound and deep overlap, or, when every shape is of
  // SCALE_LENGTH or more, the constants (a batch's two lane vectors not loaded)
  const bool unit = c.unit_scale;
  const Lanes max_push = unit ? splat(-C::CONTACT_PUSH_MAX_VELOCITY) : B.max_push;
  const Lanes inv_hv = splat(inv_h);
  const LaneMask bias_on = use_bias ? LaneMask{} == LaneMask{} : LaneMask{} != LaneMask{};
  // a point's separation and soft target (soft_target's bias m/s and γ 1/kg)
  auto target = [&](const WidePoint& p, Lanes& s, Lanes& bias, Lanes& gamma) {
    s = ((moved + p.base) + (nax * p.rax + nay * p.ray)) - (nbx * p.rbx + nby * p.rby);
    const LaneMask push = bias_on & (s <= zero);
    bias = select(s > zero, s * inv_hv, zero);
    bias = select(push, vmax(B.bias_rate * s, max_push), bias);
    gamma = select(push, p.kn * B.gamma, zero);
  };
  Lanes s0, b0, g0, s1 = zero, b1 = zero, g1 = zero;
  target(p0, s0, b0, g0);
  if constexpr (TWO) target(p1, s1, b1, g1);
  if (use_bias) {  // a deep overlap: the manifold enters relax_list
    const Lanes deep = unit ? splat(-C::DEEP_OVERLAP) : B.deep;
    LaneMask is_deep = active & (s0 < deep);
    if constexpr (TWO) is_deep |= active & (s1 < deep);
    for (int l = 0; any(is_deep) && l < LANES; ++l) {
      if (is_deep[l]) log.add_deep(B.m[l]);
    }
  }
  // velocities along the normal and the tangent at the points
  const Lanes dvx = vax - vbx, dvy = vay - vby;
  const Lanes dvn = dvx * nx + dvy * ny, dvt = dvx * tx + dvy * ty;
  const Lanes vn0 = dvn + (wa * p0.rna - wb * p0.rnb);
  Lanes vt0 = dvt + (wa * p0.rta - wb * p0.rtb);
  // m/s: the normal speed each point's solve would remove
  const Lanes r0 = -vn0 - (b0 + g0 * lam0);
  Lanes vn1 = zero, r1 = zero;
  if constexpr (TWO) {
    vn1 = dvn + (wa * p1.rna - wb * p1.rnb);
    r1 = -vn1 - (b1 + g1 * lam1);
  }
  // a batch whose manifolds hold nothing and are asked nothing is left as it is: the
  // pass's answer there is exactly zero (for two points, K d = r <= 0 with d >= 0 gives
  // dᵀK d <= 0: d = 0), and friction has no load and holds none (find_waves packs such
  // manifolds, mostly speculative contacts, after those that hold an impulse)
  LaneMask busy = active & ((lam0 != zero) | (tl0 != zero) | (r0 > zero));
  // (friction_loads: a scene without a heavy body on a light one has none)
  const bool loaded = c.count.friction_loaded != 0;
  if (loaded) busy |= active & (B.load > zero);
  if constexpr (TWO) busy |= active & ((lam1 != zero) | (tl1 != zero) | (r1 > zero));
  if (!any(busy)) return;
  Lanes n0, n1 = zero;  // the accumulated normal impulses after the clamp
  Lanes j0, j1 = zero;  // the normal impulses applied (N·s)
  if constexpr (TWO) {
    // both points as one 2x2 block, else one at a time (solve_contacts says why)
    const Lanes k00 = p0.kn + g0, k11 = p1.kn + g1, k01 = B.k01;
    const Lanes det = k00 * k11 - k01 * k01;
    const LaneMask blockable = det > splat(1.0e-9) * k00 * k11;
    const Lanes inv_det = splat(1.0) / select(blockable, det, splat(1.0));
    const Lanes d0b = (k11 * r0 - k01 * r1) * inv_det;
    const Lanes d1b = (k00 * r1 - k01 * r0) * inv_det;
    const LaneMask block = blockable & (lam0 + d0b >= zero) & (lam1 + d1b >= zero);
    const Lanes d0 = select(block, d0b, (-vn0 - (b0 + g0 * lam0)) * (splat(1.0) / (p0.kn + g0)));
    j0 = clamp_lanes(c, B.m, 0, active, lam0, d0, vn0, s0, mx0, ap0, shift, threshold, n0, log,
                     &B.ap0);
    vn1 = select(block, vn1, vn1 + j0 * k01);
    const Lanes d1 = select(block, d1b, (-vn1 - (b1 + g1 * lam1)) * (splat(1.0) / (p1.kn + g1)));
    j1 = clamp_lanes(c, B.m, 1, active, lam1, d1, vn1, s1, mx1, ap1, shift, threshold, n1, log,
                     &B.ap1);
  } else {
    const Lanes d0 = (-vn0 - (b0 + g0 * lam0)) * (splat(1.0) / (p0.kn + g0));
    j0 = clamp_lanes(c, B.m, 0, active, lam0, d0, vn0, s0, mx0, ap0, shift, threshold, n0, log,
                     &B.ap0);
  }
  // friction, as solve_contacts (the normal impulses turn the bodies: n · t = 0), only
  // where a point touches
  const Lanes mu = B.friction;
  const Lanes touch = unit ? splat(C::LINEAR_SLOP) : B.touch;
  const LaneMask has_mu = active & (mu > zero);
  Lanes f0 = zero, f1 = zero;  // the friction impulses applied (N·s)
  Lanes held0 = n0, held1 = n1;  // N·s: what bounds the friction (bounding_impulses)
  const LaneMask on0 = s0 <= touch, on1 = s1 <= touch;  // the points that touch
  if (loaded && TWO) {
    Lanes held[2];
    bounding_lanes<2>({n0, n1}, {on0, on1}, B.load, held);
    held0 = held[0], held1 = held[1];
  } else if (loaded) {
    held0 = select(B.load > n0, B.load, n0);
  }
  {
    const Lanes lam = tl0, limit = select(on0, mu * held0, zero);
    const LaneMask on = has_mu & ~((limit == zero) & (lam == zero));
    vt0 += j0 * (ia * p0.rna * p0.rta + ib * p0.rnb * p0.rtb);
    if constexpr (TWO) vt0 += j1 * (ia * p1.rna * p0.rta + ib * p1.rnb * p0.rtb);
    const Lanes next = vmin(vmax(lam - p0.tangent_mass * vt0, -limit), limit);
    f0 = select(on, next - lam, zero);
    tl0 = select(on, next, lam);
  }
  if constexpr (TWO) {
    Lanes vt1 = dvt + (wa * p1.rta - wb * p1.rtb);
    const Lanes lam = tl1, limit = select(on1, mu * held1, zero);
    const LaneMask on = has_mu & ~((limit == zero) & (lam == zero));
    vt1 += j0 * (ia * p0.rna * p1.rta + ib * p0.rnb * p1.rtb);
    vt1 += j1 * (ia * p1.rna * p1.rta + ib * p1.rnb * p1.rtb);
    vt1 += f0 * (ma + mb + ia * p0.rta * p1.rta + ib * p0.rtb * p1.rtb);
    const Lanes next = vmin(vmax(lam - p1.tangent_mass * vt1, -limit), limit);
    f1 = select(on, next - lam, zero);
    tl1 = select(on, next, lam);
  }
  Lanes jn = j0, jt = f0, ta = j0 * p0.rna + f0 * p0.rta, tb = j0 * p0.rnb + f0 * p0.rtb;
  if constexpr (TWO) {
    jn = j0 + j1;
    jt = f0 + f1;
    ta = (j0 * p0.rna + j1 * p1.rna) + (f0 * p0.rta + f1 * p1.rta);
    tb = (j0 * p0.rnb + j1 * p1.rnb) + (f0 * p0.rtb + f1 * p1.rtb);
  }
  const Lanes px = jn * nx + jt * tx, py = jn * ny + jt * ty;
  vax += ma * px;
  vay += ma * py;
  wa += ia * ta;
  vbx -= mb * px;
  vby -= mb * py;
  wb -= ib * tb;
  // a static or kinematic body's velocity is unchanged: not written back (B.writes)
  if (writes == ALL_WRITES) {
    scatter_pairs(&v[a0].x, &v[a1].x, &v[a2].x, &v[a3].x, vax, vay);
    scatter_scalars(&w[a0], &w[a1], &w[a2], &w[a3], wa);
    scatter_pairs(&v[b0i].x, &v[b1i].x, &v[b2i].x, &v[b3i].x, vbx, vby);
    scatter_scalars(&w[b0i], &w[b1i], &w[b2i], &w[b3i], wb);
  } else {
    for (int l = 0; l < LANES; ++l) {
      if (writes & (1u << l)) {
        v[B.a[l]] = {vax[l], vay[l]};
        w[B.a[l]] = wa[l];
      }
      if (writes & (1u << (LANES + l))) {
        v[B.b[l]] = {vbx[l], vby[l]};
        w[B.b[l]] = wb[l];
      }
    }
  }
  B.n0 = n0;
  B.t0 = tl0;
  B.x0 = mx0;
  if constexpr (TWO) {
    B.n1 = n1;
    B.t1 = tl1;
    B.x1 = mx1;
  }
}

// 3D, in lanes (one manifold per lane, the lanes' manifolds sharing no dynamic body):
// solve_manifold_3d's code for LANES manifolds at once, each operation in the same order
// (built without fused multiply-adds the lanes agree with it to the bit; with them, to
// the rounding of the fused operations).

// The two bodies of each lane: velocities (m/s), ω (rad/s), and the rows' normal turned
// back into each body's start frame (na, nb) with moved = n · (d_a − d_b) (m), the parts
// of row_separation (inv_rotate: p + w t + u × t, t = 2 u × p, u the conjugate's vector).
struct Bodies3 {
  Lanes vax, vay, vaz, vbx, vby, vbz, wax, way, waz, wbx, wby, wbz;
  Lanes nax, nay, naz, nbx, nby, nbz, moved;
};

// The lanes' field f(record) of the records at rec[i] for the lanes' indices i.
template <class T, class F>
inline Lanes lanes_of(const T* rec, const std::int32_t (&i)[LANES], F f) {
  return Lanes{f(rec[i[0]]), f(rec[i[1]]), f(rec[i[2]]), f(rec[i[3]])};
}

Bodies3 gather_bodies_3d(const State<3>& st, const Contacts<3>& c, const WideRow3& R,
                         const WideLanes3& L) {
  static_assert(LANES == 4, "the gathers are written for four lanes");
  const Vec3* v = st.body_v.data();
  const Vec3* w = st.body_w.data();
  const BodyDelta<3>* d = c.body_delta.data();
  Bodies3 o;
  const auto &a = L.a, &b = L.b;
  gather_xyz(&v[a[0]], &v[a[1]], &v[a[2]], &v[a[3]], o.vax, o.vay, o.vaz);
  gather_xyz(&v[b[0]], &v[b[1]], &v[b[2]], &v[b[3]], o.vbx, o.vby, o.vbz);
  gather_xyz(&w[a[0]], &w[a[1]], &w[a[2]], &w[a[3]], o.wax, o.way, o.waz);
  gather_xyz(&w[b[0]], &w[b[1]], &w[b[2]], &w[b[3]], o.wbx, o.wby, o.wbz);
  // a body's step motion: dx (three doubles) and dq (four) in a row
  static_assert(sizeof(BodyDelta<3>) == 7 * sizeof(double));
  Lanes dax, day, daz, dbx, dby, dbz;
  gather_xyz(&d[a[0]].dx, &d[a[1]].dx, &d[a[2]].dx, &d[a[3]].dx, dax, day, daz);
  gather_xyz(&d[b[0]].dx, &d[b[1]].dx, &d[b[2]].dx, &d[b[3]].dx, dbx, dby, dbz);
  const Lanes nx = R.nx, ny = R.ny, nz = R.nz;
  o.moved = (nx * (dax - dbx) + ny * (day - dby)) + nz * (daz - dbz);
  auto turn_back = [&](const std::int32_t(&ids)[LANES], Lanes& ox, Lanes& oy, Lanes& oz) {
    Lanes qw, qx, qy, qz;
    gather_quads(&d[ids[0]].dq.w, &d[ids[1]].dq.w, &d[ids[2]].dq.w, &d[ids[3]].dq.w, qw, qx, qy,
                 qz);
    const Lanes ux = -qx, uy = -qy, uz = -qz;
    const Lanes tx = splat(2.0) * (uy * nz - uz * ny);
    const Lanes ty = splat(2.0) * (uz * nx - ux * nz);
    const Lanes tz = splat(2.0) * (ux * ny - uy * nx);
    ox = (nx + qw * tx) + (uy * tz - uz * ty);
    oy = (ny + qw * ty) + (uz * tx - ux * tz);
    oz = (nz + qw * tz) + (ux * ty - uy * tx);
  };
  turn_back(L.a, o.nax, o.nay, o.naz);
  turn_back(L.b, o.nbx, o.nby, o.nbz);
  return o;
}

// Point P's separation now (m), lane by lane (row_separation).
inline Lanes separation_lanes(const Bodies3& q, const WidePoint3& P) {
  return ((q.moved + P.base) + ((q.nax * P.rax + q.nay * P.ray) + q.naz * P.raz)) -
         ((q.nbx * P.rbx + q.nby * P.rby) + q.nbz * P.rbz);
}

// (ω_a · r_a) − (ω_b · r_b) for the levers (rx, ry, rz) on a and (sx, sy, sz) on b.
inline Lanes turn_lanes(const Bodies3& q, Lanes rx, Lanes ry, Lanes rz, Lanes sx, Lanes sy,
                        Lanes sz) {
  return ((q.wax * rx + q.way * ry) + q.waz * rz) - ((q.wbx * sx + q.wby * sy) + q.wbz * sz);
}

// The symmetric tensor s (its six Lanes members xx yy zz xy xz yz from s[0], as WideFace3
// keeps the rows' inverse inertia tensors) times (x, y, z), lane by lane, into out.
inline void sym_times(const Lanes* s, Lanes x, Lanes y, Lanes z, Lanes (&out)[3]) {
  out[0] = (s[0] * x + s[3] * y) + s[4] * z;
  out[1] = (s[3] * x + s[1] * y) + s[5] * z;
  out[2] = (s[4] * x + s[5] * y) + s[2] * z;
}

// The lanes' manifolds' impulses at point k (N·s; an empty lane reads manifold 0's).
struct PointImpulses {
  Lanes lam, max, approach, jtx, jty, jtz;
};
inline PointImpulses gather_impulses(const Contacts<3>& c, const WideLanes3& L, int k) {
  std::int32_t m[LANES];
  for (int l = 0; l < LANES; ++l) m[l] = L.m[l] < 0 ? 0 : L.m[l];
  const auto& ni = c.normal_impulse;
  const auto& ti = c.tangent_impulse;
  return {lanes_of(ni.data(), m, [k](const auto& r) { return r[k]; }),
          lanes_of(c.max_normal_impulse.data(), m, [k](const auto& r) { return r[k]; }),
          lanes_of(c.approach_velocity.data(), m, [k](const auto& r) { return r[k]; }),
          lanes_of(ti.data(), m, [k](const auto& r) { return r[k].x; }),
          lanes_of(ti.data(), m, [k](const auto& r) { return r[k].y; }),
          lanes_of(ti.data(), m, [k](const auto& r) { return r[k].z; })};
}

// friction_change for one point of every lane in `on`, with the sliding velocity (vt1,
// vt2) (m/s): the change (d1, d2) (N·s; zero where not on), p's accumulated friction
// updated. t1, t2: the rows' tangents.
inline void friction_lanes(const WidePoint3& P, const WideRow3& R, LaneMask on, Lanes limit,
                           Lanes vt1, Lanes vt2, PointImpulses& p, Lanes& d1, Lanes& d2) {
  const Lanes zero = splat(0.0);
  const Lanes l1 = (p.jtx * R.t1x + p.jty * R.t1y) + p.jtz * R.t1z;
  const Lanes l2 = (p.jtx * R.t2x + p.jty * R.t2y) + p.jtz * R.t2z;
  d1 = -(P.tm11 * vt1 + P.tm12 * vt2);
  d2 = -(P.tm12 * vt1 + P.tm22 * vt2);
  const Lanes n1 = l1 + d1, n2 = l2 + d2;
  const LaneMask outside = (n1 * n1 + n2 * n2) > limit * limit;
  if (any(outside & on)) {  // friction_slide
    Lanes s1 = l1 - P.tangent_mass * vt1, s2 = l2 - P.tangent_mass * vt2;
    const Lanes sq = s1 * s1 + s2 * s2;
    const Lanes k = select(sq > zero, limit / vsqrt(select(sq > zero, sq, splat(1.0))), zero);
    const LaneMask over = sq > limit * limit;
    s1 = select(over, s1 * k, s1);
    s2 = select(over, s2 * k, s2);
    d1 = select(outside, s1 - l1, d1);
    d2 = select(outside, s2 - l2, d2);
  }
  d1 = select(on, d1, zero);
  d2 = select(on, d2, zero);
  const Lanes u1 = l1 + d1, u2 = l2 + d2;
  p.jtx = select(on, u1 * R.t1x + u2 * R.t2x, p.jtx);
  p.jty = select(on, u1 * R.t1y + u2 * R.t2y, p.jty);
  p.jtz = select(on, u1 * R.t1z + u2 * R.t2z, p.jtz);
}

// The lanes in which a point is busy (not idle, idle_manifold): what it holds (p: its
// normal and friction impulses, N·s) or is asked (r, m/s) is worth more than IDLE_SPEED
// along its normal row K (kn, 1/kg).
inline LaneMask busy_point(Lanes kn, const PointImpulses& p, Lanes r) {
  const Lanes speed = splat(C::IDLE_SPEED);
  const Lanes jt2 = (p.jtx * p.jtx + p.jty * p.jty) + p.jtz * p.jtz;
  return (p.lam * kn > speed) | (r > speed) | (jt2 * (kn * kn) > speed * speed);
}

// Whether a point's friction is solved: friction and a load, or an impulse held.
inline LaneMask friction_on(LaneMask live, Lanes mu, Lanes limit, const PointImpulses& p) {
  const Lanes zero = splat(0.0);
  return live & (mu > zero) &
         ~((limit == zero) & (p.jtx == zero) & (p.jty == zero) & (p.jtz == zero));
}

// The lanes written back but those in `skip` (bits): each dynamic body's v, and L and ω by
// dl (add_momentum); the manifolds' impulses of points 0..n-1.
void write_back_3d(State<3>& st, Contacts<3>& c, const WideLanes3& L, unsigned skip,
                   const Bodies3& q, const Lanes (&dla)[3], const Lanes (&dlb)[3],
                   const PointImpulses* p, int n) {
  for (int l = 0; l < LANES; ++l) {
    const std::int64_t m = L.m[l];
    if (m < 0 || (skip & (1u << l))) continue;
    if (L.writes & (1u << l)) {
      const int i = L.a[l];
      st.body_v[i] = {q.vax[l], q.vay[l], q.vaz[l]};
      add_momentum(st, i, c.solver_row[m].inv_ia, Vec3{dla[0][l], dla[1][l], dla[2][l]});
    }
    if (L.writes & (1u << (LANES + l))) {
      const int i = L.b[l];
      st.body_v[i] = {q.vbx[l], q.vby[l], q.vbz[l]};
      add_momentum(st, i, c.solver_row[m].inv_ib, Vec3{dlb[0][l], dlb[1][l], dlb[2][l]});
    }
    for (int k = 0; k < n; ++k) {
      c.normal_impulse[m][k] = p[k].lam[l];
      c.max_normal_impulse[m][k] = p[k].max[l];
      c.tangent_impulse[m][k] = {p[k].jtx[l], p[k].jty[l], p[k].jtz[l]};
    }
  }
}

// A batch of LANES one-point manifolds (solve_manifold_3d<1>). The local ω is not turned
// by friction here: nothing reads it after, and ω is written back from dl.
void solve_batch_3d(State<3>& st, Contacts<3>& c, const WideBatch3& B, double inv_h,
                    bool use_bias, double shift, double threshold, PassLog& log) {
  const WideLanes3& L = B.lanes;
  const WidePoint3& P = B.p;
  Bodies3 q = gather_bodies_3d(st, c, B, L);
  PointImpulses p = gather_impulses(c, L, 0);
  const Lanes zero = splat(0.0);
  const Lanes s = separation_lanes(q, P);
  // soft_target
  const LaneMask push = (s <= zero) & (use_bias ? L.live : LaneMask{});
  Lanes bias = select(s > zero, s * splat(inv_h), zero);
  bias = select(push, vmax(B.bias_rate * s, B.max_push), bias);
  const Lanes gamma = select(push, P.kn * B.gamma, zero);
  if (use_bias) {  // a deep overlap: the manifold enters relax_list
    const LaneMask is_deep = L.live & (s < B.deep);
    for (int l = 0; any(is_deep) && l < LANES; ++l)
      if (is_deep[l]) log.add_deep(L.m[l]);
  }
  const Lanes vn = (((q.vax - q.vbx) * B.nx + (q.vay - q.vby) * B.ny) + (q.vaz - q.vbz) * B.nz) +
                   turn_lanes(q, P.rnax, P.rnay, P.rnaz, P.rnbx, P.rnby, P.rnbz);
  const Lanes r = -vn - (bias + gamma * p.lam);
  // idle lanes are left as they are (idle_manifold), and a batch of them at once
  // (find_waves packs the manifolds that hold nothing apart from those that do)
  const bool loaded = c.count.friction_loaded != 0;  // (friction_loads)
  const LaneMask busy = L.live & (loaded ? busy_point(P.kn, p, r) | (B.load > zero)
                                         : busy_point(P.kn, p, r));
  if (!any(busy)) return;
  const unsigned skip = lane_bits(L.live & ~busy);
  const Lanes impulse = r * (splat(1.0) / (P.kn + gamma));
  const Lanes jn = clamp_lanes(c, L.m, 0, busy, p.lam, impulse, vn, s, p.max, p.approach, shift,
                               threshold, p.lam, log);
  // the push: v += (m jn) n, ω += jn I⁻¹(r × n), L += jn r × n
  const Lanes pa = B.ma * jn, pb = B.mb * jn;
  q.vax += pa * B.nx, q.vay += pa * B.ny, q.vaz += pa * B.nz;
  q.vbx -= pb * B.nx, q.vby -= pb * B.ny, q.vbz -= pb * B.nz;
  q.wax += jn * B.wnax, q.way += jn * B.wnay, q.waz += jn * B.wnaz;
  q.wbx -= jn * B.wnbx, q.wby -= jn * B.wnby, q.wbz -= jn * B.wnbz;
  Lanes dla[3] = {zero + jn * P.rnax, zero + jn * P.rnay, zero + jn * P.rnaz};
  Lanes dlb[3] = {zero - jn * P.rnbx, zero - jn * P.rnby, zero - jn * P.rnbz};
  // friction: one 2×2 block clamped to Coulomb's circle, where the point touches
  const Lanes held = loaded ? select(B.load > p.lam, B.load, p.lam) : p.lam;  // N·s
  const Lanes limit = select(s <= B.touch, B.friction * held, zero);
  const LaneMask on = friction_on(busy, B.friction, limit, p);
  if (any(on)) {
    const Lanes ex = q.vax - q.vbx, ey = q.vay - q.vby, ez = q.vaz - q.vbz;
    const Lanes vt1 = ((ex * B.t1x + ey * B.t1y) + ez * B.t1z) +
                      turn_lanes(q, P.rt1ax, P.rt1ay, P.rt1az, P.rt1bx, P.rt1by, P.rt1bz);
    const Lanes vt2 = ((ex * B.t2x + ey * B.t2y) + ez * B.t2z) +
                      turn_lanes(q, P.rt2ax, P.rt2ay, P.rt2az, P.rt2bx, P.rt2by, P.rt2bz);
    Lanes d1, d2;
    friction_lanes(P, B, on, limit, vt1, vt2, p, d1, d2);
    const Lanes px = d1 * B.t1x + d2 * B.t2x, py = d1 * B.t1y + d2 * B.t2y,
                pz = d1 * B.t1z + d2 * B.t2z;
    q.vax += B.ma * px, q.vay += B.ma * py, q.vaz += B.ma * pz;
    q.vbx -= B.mb * px, q.vby -= B.mb * py, q.vbz -= B.mb * pz;
    dla[0] += d1 * P.rt1ax + d2 * P.rt2ax;
    dla[1] += d1 * P.rt1ay + d2 * P.rt2ay;
    dla[2] += d1 * P.rt1az + d2 * P.rt2az;
    dlb[0] -= d1 * P.rt1bx + d2 * P.rt2bx;
    dlb[1] -= d1 * P.rt1by + d2 * P.rt2by;
    dlb[2] -= d1 * P.rt1bz + d2 * P.rt2bz;
  }
  write_back_3d(st, c, L, skip, q, dla, dlb, &p, 1);
}

// A batch of LANES manifolds of N points (2 to 4): their points' block, or, in a lane
// whose block would pull or has no factor, the points one after the other (the solve
// stage forward, relax backward); then each point's friction in order with the row's
// couplings (solve_manifold_3d<N>, lane by lane). A face of four points pulls in most
// passes: its rigid block has rank 3, and the part of the right-hand side outside K's
// range (the soft targets' bias, round-off) comes back divided by BLOCK_EPS.
template <int N>
void solve_face_3d(State<3>& st, Contacts<3>& c, const WideFace3& B, double inv_h, bool use_bias,
                   double shift, double threshold, PassLog& log) {
  static_assert(N >= 2 && N <= 4);
  const WideLanes3& L = B.lanes;
  Bodies3 q = gather_bodies_3d(st, c, B, L);
  PointImpulses p[N];
  for (int k = 0; k < N; ++k) p[k] = gather_impulses(c, L, k);
  const Lanes zero = splat(0.0);
  // every point's target from the same velocities
  const Lanes dvn = ((q.vax - q.vbx) * B.nx + (q.vay - q.vby) * B.ny) + (q.vaz - q.vbz) * B.nz;
  Lanes sep[N], vn[N], bias[N], gam[N], r[N];
  Lanes pushed = zero;  // points pushed out (soft rows)
  LaneMask deep{};
  for (int k = 0; k < N; ++k) {
    const WidePoint3& P = B.p[k];
    sep[k] = separation_lanes(q, P);
    const LaneMask out = (sep[k] <= zero) & (use_bias ? L.live : LaneMask{});
    bias[k] = select(sep[k] > zero, sep[k] * splat(inv_h), zero);
    bias[k] = select(out, vmax(B.bias_rate * sep[k], B.max_push), bias[k]);
    gam[k] = select(out, P.kn * B.gamma, zero);
    pushed += select(out, splat(1.0), zero);
    deep |= sep[k] < B.deep;
    vn[k] = dvn + turn_lanes(q, P.rnax, P.rnay, P.rnaz, P.rnbx, P.rnby, P.rnbz);
    r[k] = -vn[k] - (bias[k] + gam[k] * p[k].lam);
  }
  // idle lanes are left as they are (idle_manifold, lane by lane); a batch whose lanes
  // all are, at once
  LaneMask busy{};
  for (int k = 0; k < N; ++k) busy |= busy_point(B.p[k].kn, p[k], r[k]);
  const bool loaded = c.count.friction_loaded != 0;  // (friction_loads)
  if (loaded) busy |= B.load > zero;
  const LaneMask idle = L.live & ~busy;
  if (use_bias) {  // a deep overlap: the manifold enters relax_list
    const LaneMask is_deep = L.live & deep;
    for (int l = 0; any(is_deep) && l < LANES; ++l)
      if (is_deep[l]) log.add_deep(L.m[l]);
  }
  if (!any(L.live & busy)) return;
  // the factor: the row's rigid one when no point is pushed out, its soft one when every
  // point is, else made here (factor_block, ldlt_factor_n)
  const LaneMask none_pushed = pushed == zero, all_pushed = pushed == splat(double(N));
  WideFace3::Factor f;
  for (int i = 0; i < 6; ++i) f.l[i] = select(none_pushed, B.rigid.l[i], B.soft.l[i]);
  for (int i = 0; i < 4; ++i) f.inv_d[i] = select(none_pushed, B.rigid.inv_d[i], B.soft.inv_d[i]);
  f.ok = select(none_pushed, B.rigid.ok, B.soft.ok);
  auto at = [](int i, int j) { return i * (i - 1) / 2 + j; };
  const LaneMask mixed = L.live & ~none_pushed & ~all_pushed;
  if (any(mixed)) {
    Lanes A[4][4];
    block_of(B.k, FACE_POINTS, 4, A);
    for (int i = 0; i < N; ++i) A[i][i] += gam[i] + splat(BLOCK_EPS) * A[i][i];
    Lanes l[6] = {}, d[4] = {}, inv_d[4] = {};
    LaneMask ok = ~LaneMask{};
    for (int j = 0; j < N; ++j) {
      Lanes x = A[j][j];
      for (int k = 0; k < j; ++k) x -= l[at(j, k)] * l[at(j, k)] * d[k];
      ok &= x > splat(1e-12) * A[j][j];
      d[j] = x;
      const Lanes safe = select(ok, x, splat(1.0));
      inv_d[j] = splat(1.0) / safe;
      for (int i = j + 1; i < N; ++i) {
        Lanes y = A[i][j];
        for (int k = 0; k < j; ++k) y -= l[at(i, k)] * l[at(j, k)] * d[k];
        l[at(i, j)] = y / safe;
      }
    }
    for (int i = 0; i < 6; ++i) f.l[i] = select(mixed, l[i], f.l[i]);
    for (int i = 0; i < 4; ++i) f.inv_d[i] = select(mixed, inv_d[i], f.inv_d[i]);
    f.ok = select(mixed, select(ok, splat(1.0), zero), f.ok);
  }
  // ldlt_apply_n
  Lanes dl[N], y[N];
  for (int i = 0; i < N; ++i) {
    y[i] = r[i];
    for (int k = 0; k < i; ++k) y[i] -= f.l[at(i, k)] * y[k];
  }
  for (int i = N - 1; i >= 0; --i) {
    dl[i] = y[i] * f.inv_d[i];
    for (int k = i + 1; k < N; ++k) dl[i] -= f.l[at(k, i)] * dl[k];
  }
  LaneMask block = L.live & busy & (f.ok != zero);
  for (int k = 0; k < N; ++k) block &= p[k].lam + dl[k] >= zero;
  LaneMask one_by_one = L.live & busy & ~block;
  // where the block would pull at an impact (a point approaching faster than the
  // restitution threshold): its exact answer (active_set_block), from the block's signs
  // (all the points where it has none). A resting face that pulls (most passes of a heap:
  // the four corners' block is rank 3) goes one point after the other, at a fraction of
  // the cost (the exact answer there cost a settled heap of tumbled boxes 30% of its
  // passes' time)
  LaneMask impact{};
  for (int k = 0; k < N; ++k) impact |= vn[k] < splat(-threshold);
  if (any(one_by_one & impact)) {
    Lanes A[4][4];
    block_of(B.k, FACE_POINTS, 4, A);
    for (int i = 0; i < N; ++i) A[i][i] += gam[i];
    LaneMask start[N];
    Lanes lam[N], exact[N];
    for (int k = 0; k < N; ++k) {
      start[k] = (p[k].lam + dl[k] >= zero) | (f.ok == zero);
      lam[k] = p[k].lam;
      exact[k] = zero;
    }
    const LaneMask solved = active_set_block<N>(A, r, lam, start, one_by_one & impact, exact);
    for (int k = 0; k < N; ++k) dl[k] = select(solved, exact[k], dl[k]);
    block |= solved;
    one_by_one &= ~solved;
  }
  Lanes jn[N];
  for (int k = 0; k < N; ++k)
    jn[k] = clamp_lanes(c, L.m, k, block, p[k].lam, dl[k], vn[k], sep[k], p[k].max, p[k].approach,
                        shift, threshold, p[k].lam, log);
  // the impulses' sum and moments about each COM, summed over the points as sum_lanes
  auto over_points = [&](auto term) {
    if constexpr (N == 2) return term(0) + term(1);
    else if constexpr (N == 3) return (term(0) + term(1)) + term(2);
    else return (term(0) + term(1)) + (term(2) + term(3));
  };
  const Lanes sj = over_points([&](int k) { return jn[k]; });
  const Lanes ta[3] = {over_points([&](int k) { return jn[k] * B.p[k].rnax; }),
                       over_points([&](int k) { return jn[k] * B.p[k].rnay; }),
                       over_points([&](int k) { return jn[k] * B.p[k].rnaz; })};
  const Lanes tb[3] = {over_points([&](int k) { return jn[k] * B.p[k].rnbx; }),
                       over_points([&](int k) { return jn[k] * B.p[k].rnby; }),
                       over_points([&](int k) { return jn[k] * B.p[k].rnbz; })};
  const Lanes pa = B.ma * sj, pb = B.mb * sj;
  q.vax += pa * B.nx, q.vay += pa * B.ny, q.vaz += pa * B.nz;
  q.vbx -= pb * B.nx, q.vby -= pb * B.ny, q.vbz -= pb * B.nz;
  // ω += I⁻¹ t (a Sym3 times a vector)
  Lanes dwa[3], dwb[3];
  sym_times(&B.iaxx, ta[0], ta[1], ta[2], dwa);
  sym_times(&B.ibxx, tb[0], tb[1], tb[2], dwb);
  q.wax += dwa[0], q.way += dwa[1], q.waz += dwa[2];
  q.wbx -= dwb[0], q.wby -= dwb[1], q.wbz -= dwb[2];
  Lanes dla[3] = {zero + ta[0], zero + ta[1], zero + ta[2]};
  Lanes dlb[3] = {zero - tb[0], zero - tb[1], zero - tb[2]};
  if (any(one_by_one)) {
    // the points one after the other on the velocities after those before (their lanes'
    // velocities untouched by the block above: its impulses there are zero)
    for (int i = 0; i < N; ++i) {
      const int k = use_bias ? i : N - 1 - i;
      const WidePoint3& P = B.p[k];
      const Lanes speed = ((q.vax - q.vbx) * B.nx + (q.vay - q.vby) * B.ny) + (q.vaz - q.vbz) * B.nz;
      const Lanes v_now = speed + turn_lanes(q, P.rnax, P.rnay, P.rnaz, P.rnbx, P.rnby, P.rnbz);
      const Lanes impulse = (-v_now - (bias[k] + gam[k] * p[k].lam)) * (splat(1.0) / (P.kn + gam[k]));
      const Lanes j = clamp_lanes(c, L.m, k, one_by_one, p[k].lam, impulse, v_now, sep[k],
                                  p[k].max, p[k].approach, shift, threshold, p[k].lam, log);
      // push: v += m⁻¹ j n, ω += j I⁻¹ (r × n), L += j (r × n)
      const Lanes ja = B.ma * j, jb = B.mb * j;
      q.vax += ja * B.nx, q.vay += ja * B.ny, q.vaz += ja * B.nz;
      q.vbx -= jb * B.nx, q.vby -= jb * B.ny, q.vbz -= jb * B.nz;
      Lanes wna[3], wnb[3];  // 1/(kg·m): I⁻¹ (r × n), as prepare makes the row's
      sym_times(&B.iaxx, P.rnax, P.rnay, P.rnaz, wna);
      sym_times(&B.ibxx, P.rnbx, P.rnby, P.rnbz, wnb);
      q.wax += j * wna[0], q.way += j * wna[1], q.waz += j * wna[2];
      q.wbx -= j * wnb[0], q.wby -= j * wnb[1], q.wbz -= j * wnb[2];
      dla[0] += j * P.rnax, dla[1] += j * P.rnay, dla[2] += j * P.rnaz;
      dlb[0] -= j * P.rnbx, dlb[1] -= j * P.rnby, dlb[2] -= j * P.rnbz;
    }
  }
  // friction: each point's 2×2 block, in order (forward in the solve, backward in relax),
  // the later points' sliding velocities carried through the row's couplings
  const LaneMask has_mu = L.live & busy & (B.friction > zero);
  if (any(has_mu)) {
    const Lanes ex = q.vax - q.vbx, ey = q.vay - q.vby, ez = q.vaz - q.vbz;
    const Lanes e1 = (ex * B.t1x + ey * B.t1y) + ez * B.t1z;
    const Lanes e2 = (ex * B.t2x + ey * B.t2y) + ez * B.t2z;
    Lanes vt1[N], vt2[N], g1[N], g2[N];
    for (int k = 0; k < N; ++k) {
      const WidePoint3& P = B.p[k];
      vt1[k] = e1 + turn_lanes(q, P.rt1ax, P.rt1ay, P.rt1az, P.rt1bx, P.rt1by, P.rt1bz);
      vt2[k] = e2 + turn_lanes(q, P.rt2ax, P.rt2ay, P.rt2az, P.rt2bx, P.rt2by, P.rt2bz);
      g1[k] = g2[k] = zero;
    }
    // N·s: what bounds each point's friction (bounding_impulses)
    Lanes held[N], lam[N];
    LaneMask on[N];
    for (int k = 0; k < N; ++k) held[k] = lam[k] = p[k].lam, on[k] = sep[k] <= B.touch;
    if (loaded) bounding_lanes<N>(lam, on, B.load, held);
    for (int i = 0; i < N; ++i) {
      const int k = use_bias ? i : N - 1 - i;
      const Lanes limit = select(sep[k] <= B.touch, B.friction * held[k], zero);
      const LaneMask on = friction_on(has_mu, B.friction, limit, p[k]);
      if (!any(on)) continue;
      Lanes d1, d2;
      friction_lanes(B.p[k], B, on, limit, vt1[k], vt2[k], p[k], d1, d2);
      if (use_bias) {
        for (int j = k + 1; j < N; ++j) {
          const Lanes* cp = B.coupling[at(j, k)];
          vt1[j] += cp[0] * d1 + cp[1] * d2;
          vt2[j] += cp[2] * d1 + cp[3] * d2;
        }
      } else {
        for (int j = 0; j < k; ++j) {
          const Lanes* cp = B.coupling[at(k, j)];
          vt1[j] += cp[0] * d1 + cp[2] * d2;
          vt2[j] += cp[1] * d1 + cp[3] * d2;
        }
      }
      g1[k] = d1;
      g2[k] = d2;
    }
    const Lanes s1 = over_points([&](int k) { return g1[k]; });
    const Lanes s2 = over_points([&](int k) { return g2[k]; });
    const Lanes px = s1 * B.t1x + s2 * B.t2x, py = s1 * B.t1y + s2 * B.t2y,
                pz = s1 * B.t1z + s2 * B.t2z;
    q.vax += B.ma * px, q.vay += B.ma * py, q.vaz += B.ma * pz;
    q.vbx -= B.mb * px, q.vby -= B.mb * py, q.vbz -= B.mb * pz;
    dla[0] += over_points([&](int k) { return g1[k] * B.p[k].rt1ax + g2[k] * B.p[k].rt2ax; });
    dla[1] += over_points([&](int k) { return g1[k] * B.p[k].rt1ay + g2[k] * B.p[k].rt2ay; });
    dla[2] += over_points([&](int k) { return g1[k] * B.p[k].rt1az + g2[k] * B.p[k].rt2az; });
    dlb[0] -= over_points([&](int k) { return g1[k] * B.p[k].rt1bx + g2[k] * B.p[k].rt2bx; });
    dlb[1] -= over_points([&](int k) { return g1[k] * B.p[k].rt1by + g2[k] * B.p[k].rt2by; });
    dlb[2] -= over_points([&](int k) { return g1[k] * B.p[k].rt1bz + g2[k] * B.p[k].rt2bz; });
  }
  write_back_3d(st, c, L, lane_bits(idle), q, dla, dlb, p, N);
}

}  // namespace

template <int D>
void solve_waves(const Model<D>& model, State<D>& st, Contacts<D>& c, double inv_h,
                   bool use_bias, double shift, double threshold) {
  PassLog log = PassLog::direct(c);
  take_impulses(c);
  solve_wave_range(model, st, c, inv_h, use_bias, shift, threshold, 0, c.wave_count, log);
  give_impulses(c);
}

void solve_batch_lanes(State<2>& st, Contacts<2>& c, double inv_h, bool use_bias, double shift,
                       double threshold, const BatchLanes* batches, std::int64_t n, PassLog& log) {
  for (std::int64_t k = 0; k < n; ++k) {
    const BatchLanes& b = batches[k];
    WideBatch& B = c.batches[b.batch];
    if (b.two)
      solve_batch<true, true>(st, c, B, inv_h, use_bias, shift, threshold, log, b.lanes);
    else
      solve_batch<false, true>(st, c, B, inv_h, use_bias, shift, threshold, log, b.lanes);
  }
}

template <int D>
void solve_wave_range(const Model<D>& model, State<D>& st, Contacts<D>& c, double inv_h,
                      bool use_bias, double shift, double threshold, std::int64_t first,
                      std::int64_t last, PassLog& log, CutLanes lanes) {
  if constexpr (D == 2) {
  for (std::int64_t g = first; g < last; ++g) {
    const std::int64_t single = c.wave_single_batch[g];  // the first batch of one-point ones
    for (std::int64_t i = c.wave_batch[g]; i < c.wave_batch[g + 1]; ++i) {
      WideBatch& B = c.batches[i];
      const bool two = i < single;
      const unsigned only = cut_lanes_taken(lanes, B.cut);
      if (only == 0) continue;
      if (only == ALL_LANES) {  // (one thread: a cut's lanes with the rest)
        if (two)
          solve_batch<true>(st, c, B, inv_h, use_bias, shift, threshold, log);
        else
          solve_batch<false>(st, c, B, inv_h, use_bias, shift, threshold, log);
        continue;
      }
      if (two)
        solve_batch<true, true>(st, c, B, inv_h, use_bias, shift, threshold, log, only);
      else
        solve_batch<false, true>(st, c, B, inv_h, use_bias, shift, threshold, log, only);
    }
  }
  } else {
  // 3D: a wave's one-point manifolds LANES at a time, then its faces (LANES at a time, or
  // one by one: pack_waves_3d)
  for (std::int64_t g = first; g < last; ++g) {
    for (std::int64_t i = c.wave_batch[g]; i < c.wave_batch[g + 1]; ++i)
      solve_batch_3d(st, c, c.batches3[i], inv_h, use_bias, shift, threshold, log);
    for (std::int64_t i = c.wave_single_batch[g]; i < c.wave_single_batch[g + 1]; ++i) {
      const WideFace3& F = c.faces3[i];
      switch (F.count) {
        case 2: solve_face_3d<2>(st, c, F, inv_h, use_bias, shift, threshold, log); break;
        case 3: solve_face_3d<3>(st, c, F, inv_h, use_bias, shift, threshold, log); break;
        case 4: solve_face_3d<4>(st, c, F, inv_h, use_bias, shift, threshold, log); break;
        default:  // a lone manifold: on its own
          for (int l = 0; l < LANES; ++l)
            if (F.lanes.m[l] >= 0)
              solve_contacts_3d(model, st, c, inv_h, use_bias, shift, threshold, &F.lanes.m[l], 1, log);
          break;
      }
    }
    const std::int64_t idle = c.wave_idle[g];  // the faces that hold no impulse
    if (idle < c.wave_start[g + 1])
      solve_contacts_3d(model, st, c, inv_h, use_bias, shift, threshold, &c.wave_order[idle],
                        c.wave_start[g + 1] - idle, log);
  }
  }
}

template void solve_waves(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double, double);
template void solve_waves(const Model<3>&, State<3>&, Contacts<3>&, double, bool, double, double);
template void solve_wave_range(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double,
                               double, std::int64_t, std::int64_t, PassLog&, CutLanes);
template void solve_wave_range(const Model<3>&, State<3>&, Contacts<3>&, double, bool, double,
                               double, std::int64_t, std::int64_t, PassLog&, CutLanes);


}  // namespace rbsim
