// Shock propagation: contacts solved from the ground up, the supporting body held still.
//
// Sequential impulses converge slowly when a heavy body presses on light ones: each pass
// over a slab resting on a small box hands the box the slab's whole approach speed and
// takes back only a mass ratio's worth of it from the slab, so a 400 kg slab falling on
// 1 kg boxes needs hundreds of passes to stop and, in a few, crushes them into the ground.
// After the relax pass of every substep this stage makes one more pass over the contacts,
// ordered by how far each body is from a static or kinematic body through the contact
// graph (its support level, found once per step), and solves each contact between a
// supporting body (lower level, underneath with respect to gravity) and a supported one
// (higher level) as if the supporter had infinite mass: only the supported body's approach
// is removed. A rigidly supported body cannot be pushed into what holds it, so for
// vertical support this is what the converged solve would give; the impulse goes into
// the ground through the chain, as it physically does.
//
// The pass only removes approach velocity (it never pushes apart and never adds energy)
// and keeps no accumulated impulse, so warm starting and the resting equilibrium of the
// soft contacts are unchanged. It needs gravity to say what is underneath: a scene
// without gravity, or a contact whose normal is closer to horizontal than SHOCK_COS,
// is left to the ordinary solve. (Guendelman, Bridson and Fedkiw 2003 introduced shock
// propagation for stacking; this is a velocity-level variant of it.)
//
// Lifting: while a heavy body rests on a light one (heavy_on_light), a dynamic
// supporter's turn towards the body it supports is not handed on, only the supported
// body's approach and the supporter's own travel are taken out: held still, a 1 kg plate
// tipping under a 100 kg box (the load's friction on its top face and the ground's on its
// bottom turn it) lifted the box at the speed of its rising edge, energy from nowhere (a
// 100 kg box sliding on two such plates reached 1.7 times its kinetic energy, and 3
// times once friction carried the load). The turn is left to the ordinary solve, which
// weighs the plate as it is. Its travel is handed on (a plate carried up by a kinematic
// lift lifts what rests on it), and so is all of a static or kinematic supporter's move.
//
// Striking supporters (2D): a dynamic supporter travelling towards the body it supports
// faster than an impact (the restitution threshold) does not hold it up but strikes it,
// and none of its motion is handed on, whatever the loads (as in 3D below): the strike is
// the next substep's solve and bounce. Handed on, a 50 g capsule bounced off the floor at
// 88 m/s into a 16 kg slab resting on it threw the slab up at 80 m/s.
//
// Rising supporters (3D): no motion of a dynamic supporter towards the body it supports,
// travel or turn, is handed on, whatever the loads: the pass keeps the supported body
// from approaching its supporter as if that stood still, and leaves the lifting to the
// ordinary solve (while a heavy body rests on a light one, the supporter's turn towards
// it is taken off what is asked as well, as above: a 100 kg crate riding light plates on
// a belt then never outruns the belt). A body on several supporters
// is kept off each in turn, and handed every one's rise it rose with the fastest point of
// any: up a Jenga tower (three blocks a layer, each on three below) a few millimetres a
// second of rise at its foot, from the solve's blocks, came out at the top as 0.2 m/s in
// the first step, and the tower fell. A static or kinematic supporter's move is handed on
// (a lift).
//
// The same file finds the solve order of the solver's passes (support level first) and
// the region around a deep overlap that the relax stage gives extra passes.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// The level of a body not connected to a static or kinematic body.
constexpr std::int64_t UNREACHED = std::int64_t{1} << 30;

// Whether every component of v is exactly zero (a scene without gravity).
inline bool all_zero(Vec2 v) { return v.x == 0.0 && v.y == 0.0; }
inline bool all_zero(Vec3 v) { return v.x == 0.0 && v.y == 0.0 && v.z == 0.0; }
inline bool all_zero(double w) { return w == 0.0; }

// contacts.body_level (N,): 0 for static and kinematic bodies, 1 for the bodies they
// touch, ..., UNREACHED for bodies not connected to one (breadth first over the manifolds
// that touch, contacts.support: a point within SUPPORT_GAP at the step's start, found by
// update_manifolds). Only such contacts hold bodies up: a ball resting on a 1 cm plate
// has the ground within its speculative distance, and counted as standing on it (level
// 1, as the plate) it was no load of the plate's in the shock pass, and a 100 kg ball
// pushed a 1 kg plate through the ground. Builds the contact graph's adjacency
// (compressed rows in adj_start, adj; deep_region walks it too) and uses contacts.queue
// as scratch.
template <int D>
void contact_levels(const Model<D>& model, Contacts<D>& c) {
  auto& level = c.body_level;
  auto& adj_start = c.adj_start;
  auto& adj = c.adj;
  auto& queue = c.queue;
  const std::int64_t n_bodies = static_cast<std::int64_t>(level.size());
  const std::int64_t n_man = c.count.manifolds;
  // adjacency of the contact graph (compressed rows, manifolds with points only)
  for (std::int64_t i = 0; i <= n_bodies; ++i) adj_start[i] = 0;
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (c.support[m]) {
      adj_start[c.body_a[m] + 1] += 1;
      adj_start[c.body_b[m] + 1] += 1;
    }
  }
  for (std::int64_t i = 0; i < n_bodies; ++i) adj_start[i + 1] += adj_start[i];
  for (std::int64_t i = 0; i < n_bodies; ++i) queue[i] = adj_start[i];  // fill cursor
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (c.support[m]) {
      const int a = c.body_a[m], b = c.body_b[m];
      adj[queue[a]++] = b;
      adj[queue[b]++] = a;
    }
  }
  // breadth-first levels from every static or kinematic body
  std::int64_t head = 0, tail = 0;
  for (std::int64_t i = 0; i < n_bodies; ++i) {
    if (model.body_type[i] != BodyType::Dynamic) {
      level[i] = 0;
      queue[tail++] = i;
    } else {
      level[i] = UNREACHED;
    }
  }
  while (head < tail) {
    const std::int64_t i = queue[head++];
    for (std::int64_t e = adj_start[i]; e < adj_start[i + 1]; ++e) {
      const int j = adj[e];
      if (level[j] == UNREACHED) {
        level[j] = level[i] + 1;
        queue[tail++] = j;
      }
    }
  }
}

// ω · (r × n) for a point's angular lever (2D: scalars; 3D: vectors).
inline double angular_along(double w, double r) { return w * r; }

// Solve A x = r for the n <= 4 points of `idx` (A: K's rows and columns idx, K packed as
// SolverRow<3>::k, 1/kg) by LDLᵀ, unregularised; false when a pivot is below 1e-9 of its
// diagonal (the points' rows are dependent: four corners of a face, for one rigid body).

bool solve_exact(const std::array<double, 10>& k, const int* idx, const double* r, int n,
                 double* x) {
  double A[4][4];  // (only its first n rows and columns are read)
  block_of(k, idx, n, A);
  return ldlt_solve(A, n, r, x, 1e-9);
}

// The sets of n points (n <= 4) shock_block tries, as bit masks: of three points at
// most (four of one face are dependent, see below), largest first, then by mask from
// the highest (the order of a count down over the masks of each size).
struct SubsetOrder {
  int count;
  unsigned set[14];
};
constexpr std::array<SubsetOrder, 5> make_subset_orders() {
  std::array<SubsetOrder, 5> orders{};
  for (int n = 0; n <= 4; ++n) {
    SubsetOrder o{};
    for (int size = n < 3 ? n : 3; size >= 1; --size)
      for (unsigned set = (1u << n) - 1; set > 0; --set)
        if (std::popcount(set) == size) o.set[o.count++] = set;
    orders[n] = o;
  }
  return orders;
}
constexpr std::array<SubsetOrder, 5> SUBSET_ORDER = make_subset_orders();

// 3D: impulses λ >= 0 (N·s) at the n points (n <= 4) of a supported body that bring every
// point to at least its target, λ_k = 0 wherever a point is left beyond it: the linear
// complementarity problem w = K λ − need >= 0, λ >= 0, λ·w = 0, with K (1/kg, packed as
// SolverRow<3>::k) the supported body's own block and need (m/s) each point's shortfall.
// Its solutions all give the body the same velocity (K λ is the same for all: it is the
// minimum of a convex quadratic), so the first found serves: sets of points are tried,
// each solved exactly, until one has λ >= 0 and leaves no point short (beyond rounding).
// The sets tried first are the short points and their subsets (the usual answer: the
// points that need a push get one), largest first, then the sets that also hold points
// not short. Four points of one manifold are never tried together: K_ij = 1/m + (r_i ×
// n)·I⁻¹(r_j × n), and the levers r × n all lie in the plane normal to n, so K has rank 3
// at most (a face rests on three of its corners here; the velocity is the four's). false
// when no set does (K singular on every set).
bool shock_block(const std::array<double, 10>& k, const double* need, int n, double* lam) {
  double scale = 0.0;  // m/s: the largest shortfall
  unsigned short_set = 0;  // bit i: point i is short
  for (int i = 0; i < n; ++i) {
    scale = std::max(scale, std::fabs(need[i]));
    if (need[i] > 0.0) short_set |= 1u << i;
    lam[i] = 0.0;
  }
  if (short_set == 0) return true;  // no point short at all: nothing to do
  auto at = [&](int i, int j) { return k[PACKED_K[i][j]]; };
  const SubsetOrder& order = SUBSET_ORDER[n];
  for (int pass = 0; pass < 2; ++pass) {  // subsets of the short points, then the rest
    for (int t = 0; t < order.count; ++t) {
      const unsigned set = order.set[t];
      if ((set & short_set) == 0) continue;
      if (((set & ~short_set) == 0) != (pass == 0)) continue;
      int idx[4], na = 0;
      double rhs[4], x[4];
      for (int i = 0; i < n; ++i) {
        if (!(set >> i & 1)) continue;
        rhs[na] = need[i];
        idx[na++] = i;
      }
      if (!solve_exact(k, idx, rhs, na, x)) continue;
      bool ok = true;
      for (int i = 0; i < na; ++i) ok = ok && x[i] >= 0.0;
      if (!ok) continue;
      for (int i = 0; i < n; ++i) lam[i] = 0.0;
      for (int i = 0; i < na; ++i) lam[idx[i]] = x[i];
      for (int i = 0; i < n && ok; ++i) {
        if (set >> i & 1) continue;
        double w = -need[i];
        for (int j = 0; j < n; ++j) w += at(i, j) * lam[j];
        ok = w >= -1e-9 * scale;
      }
      if (ok) return true;
    }
  }
  for (int i = 0; i < n; ++i) lam[i] = 0.0;
  return false;
}

// The supported body and its supporter in shock-order manifold m (shock_side 2: body b
// supports body a; 1: a supports b).
struct Support {
  int supported, supporter;
};
template <int D>
inline Support support_of(const Contacts<D>& c, std::int32_t m) {
  if (c.shock_side[m] == 2) return {c.body_a[m], c.body_b[m]};
  return {c.body_b[m], c.body_a[m]};
}

// Whether manifold m's supported body bears a load (contacts.body_load, known while
// heavy_on_light) CRUSH_RATIO or more times the mass of the lighter of it and its
// (dynamic) supporter: a slab on a box, or the box under it on the ground.
template <int D>
inline bool crushing(const Model<D>& model, const Contacts<D>& c, std::int32_t m) {
  if (!c.heavy_on_light) return false;
  const auto [u, s] = support_of(c, m);
  const double lighter = std::max(model.body_inv_mass[u], model.body_inv_mass[s]);  // 1/kg
  return c.body_load[u] * lighter >= C::CRUSH_RATIO;
}

// The fraction of manifold m's load whose friction is the shock pass's (shock friction):
// while a heavy body rests on a light one, what the supported body bears beyond
// FRICTION_LOAD_RATIO times the lighter of it and its supporter (friction_loads bounds
// the passes' friction by the rest), 1 − FRICTION_LOAD_RATIO / ratio; 0 below it.
template <int D>
inline double shock_friction_share(const Model<D>& model, const Contacts<D>& c, std::int32_t m) {
  if (!c.heavy_on_light || !(c.friction[m] > 0.0)) return 0.0;
  const auto [u, s] = support_of(c, m);
  const double ratio =
      c.body_load[u] * std::max(model.body_inv_mass[u], model.body_inv_mass[s]);
  return ratio > C::FRICTION_LOAD_RATIO ? 1.0 - C::FRICTION_LOAD_RATIO / ratio : 0.0;
}

// The largest speed (m/s) the shock pass's friction may give a supported body's point at
// p (m) in the tangent plane of normal n: its own speed there (`own`, m/s, its velocity
// along the plane), or, on a supporter that a moving kinematic body carries
// (body_carried: -1 none), that body's speed at p along the plane, if larger.
template <int D>
inline double reach_speed(const State<D>& st, const Contacts<D>& c, int supporter,
                          typename Dim<D>::Vec p, typename Dim<D>::Vec n, double own) {
  const std::int32_t k = c.body_carried[supporter];
  if (k < 0) return own;
  const auto vk = st.body_v[k] + cross(st.body_w[k], p - st.body_x[k]);  // m/s
  const auto across = vk - dot(vk, n) * n;
  return std::max(own, std::sqrt(dot(across, across)));
}

// The 3D pass: the supported body's approach taken out at a face's up to four points at
// once (shock_block), the supporter held still; the body's v, L and ω changed
// (add_momentum). Where no set of points is found, the points are taken one after the other
// (each impulse λ >= 0 against the velocity it meets).
void propagate_shock_3d(const Model<3>& model, State<3>& st, Contacts<3>& c,
                        std::int64_t first, std::int64_t last, double inv_h, double threshold,
                        double min_approach) {
  for (std::int64_t o = first; o < last; ++o) {
    const std::int32_t m = c.shock_order[o];
    const int a = c.body_a[m], b = c.body_b[m];
    const SolverRow<3>& row = c.solver_row[m];
    const Vec3 n = row.normal;
    const int npts = c.points[m];
    const Vec3 va = st.body_v[a], vb = st.body_v[b], wa = st.body_w[a], wb = st.body_w[b];
    const SolverRow<3>::Points& P = row.point;
    // each point's normal velocity (m/s), the points in lanes: (ω × r) · n = ω · (r × n)
    Lanes vel_l = dot(n, va - vb) + (dot_lanes(wa, P.rna) - dot_lanes(wb, P.rnb));
    // the supported body moves; the sign turns its push along +n (a) or -n (b)
    const bool a_moves = c.shock_side[m] == 2;
    if (model.is_dynamic(a_moves ? b : a)) {
      // a dynamic supporter's motion towards u at each point is not handed on (rising
      // supporters, the file's head): u is only kept from approaching it as if it stood
      const Lanes toward = a_moves ? splat(dot(n, vb)) + dot_lanes(wb, P.rnb)
                                   : splat(0.0) - (splat(dot(n, va)) + dot_lanes(wa, P.rna));
      vel_l = vel_l + vmax(toward, splat(0.0));
    }
    // most supported points are not approaching: skip them before any other work, at
    // min_approach, or at any speed for a body held by several supporters high in a tall
    // structure (SHOCK_TALL_LEVEL). A load that would crush its supporter is taken out
    // however slowly it approaches: the soft contacts do not carry it (CRUSH_RATIO)
    const LaneMask live = first_lanes(npts);
    const int held = a_moves ? a : b;
    const bool tall = c.body_level[held] >= C::SHOCK_TALL_LEVEL && c.body_supporters[held] >= 2;
    const double least = tall ? C::SHOCK_MIN_APPROACH : min_approach;  // m/s
    if (!any((vel_l < -least) & live) &&
        !(min_approach > C::SHOCK_MIN_APPROACH && any((vel_l < -C::SHOCK_MIN_APPROACH) & live) &&
          crushing(model, c, m)))
      continue;
    double vel[4];
    std::memcpy(vel, &vel_l, sizeof vel);
    double slowest = 0.0;  // m/s: the fastest approach among the points
    for (int k = 0; k < npts; ++k) slowest = std::min(slowest, vel[k]);
    // an impact (faster than the threshold) that does not crush: the restitution stage's
    // when elastic, and left alone while apart (below)
    const bool impact = slowest < -threshold && !crushing(model, c, m);
    if (impact && c.restitution[m] > 0.0) continue;
    const BodyDelta<3>& da = c.body_delta[a];
    const BodyDelta<3>& db = c.body_delta[b];
    const double moved = dot(n, da.dx - db.dx);  // m
    const Vec3 na = inv_rotate(da.dq, n);
    const Vec3 nb = inv_rotate(db.dq, n);
    const int u = a_moves ? a : b;
    const double sgn = a_moves ? 1.0 : -1.0;
    const double mu = model.body_inv_mass[u];
    // how far each point is from allowed (m/s): a gap may close within the substep
    double need[4];
    double nearest = std::numeric_limits<double>::infinity();  // m: the least separation
    for (int k = 0; k < npts; ++k) {
      const double sep = row_separation(P, k, moved, na, nb);
      nearest = std::min(nearest, sep);
      need[k] = (sep > 0.0 ? -sep * inv_h : 0.0) - vel[k];
    }
    // an impact still apart waits for its bodies to meet (restitution.cpp), elastic or
    // not, and gets its friction when they do: pushed here, it would close without any
    if (impact && nearest > row.touch) continue;
    if (c.heavy_on_light && model.is_dynamic(a_moves ? b : a)) {
      // a dynamic supporter's turn towards u is not handed on (lifting, the file's head)
      const Vec3 ws = a_moves ? wb : wa;
      for (int k = 0; k < npts; ++k) {
        const double turn = sgn * dot(ws, a_moves ? P.rnb[k] : P.rna[k]);
        need[k] -= std::max(turn, 0.0);
      }
    }
    // the supported body's block: K_ij = 1/m + (r_i × n)·I⁻¹(r_j × n) (1/kg)
    std::array<double, 10> kb{};
    int e = 0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i; j < 4; ++j, ++e) {
        if (j >= npts) continue;
        kb[e] = mu + (a_moves ? dot(P.rna[i], P.wna[j]) : dot(P.rnb[i], P.wnb[j]));
      }
    }
    double lam[4] = {0.0, 0.0, 0.0, 0.0};
    Vec3 vu = st.body_v[u], wu = st.body_w[u], dl{};
    bool pushed = false;
    if (shock_block(kb, need, npts, lam)) {
      for (int k = 0; k < npts; ++k) {
        if (lam[k] == 0.0) continue;
        const Vec3 rn = a_moves ? P.rna[k] : P.rnb[k];  // m: the supported body's lever
        const Vec3 wn = a_moves ? P.wna[k] : P.wnb[k];
        vu += (sgn * mu * lam[k]) * n;
        wu += (sgn * lam[k]) * wn;
        dl += (sgn * lam[k]) * rn;
        pushed = true;
      }
    } else {
      for (int k = 0; k < npts; ++k) {
        const auto pt = P[k];
        const Vec3 pa = a_moves ? vu + cross(wu, pt.arm_a) : va + cross(wa, pt.arm_a);
        const Vec3 pb = a_moves ? vb + cross(wb, pt.arm_b) : vu + cross(wu, pt.arm_b);
        const double sep = row_separation(pt, moved, na, nb);
        const double short_k = (sep > 0.0 ? -sep * inv_h : 0.0) - dot(n, pa - pb);
        const Vec3 rn = a_moves ? pt.rna : pt.rnb;
        const Vec3 wn = a_moves ? pt.wna : pt.wnb;
        const double k_u = mu + dot(rn, wn);  // 1/kg
        if (!(short_k > 0.0 && k_u > 0.0)) continue;
        const double l = short_k / k_u;  // N·s along the supported body's push direction
        lam[k] = l;
        vu += (sgn * mu * l) * n;
        wu += (sgn * l) * wn;
        dl += (sgn * l) * rn;
        pushed = true;
      }
    }
    if (!pushed) continue;
    for (int k = 0; k < npts; ++k)
      if (lam[k] > 0.0) c.shock_points[m] |= static_cast<std::uint8_t>(1u << k);
    if (c.record_impulses) {  // (pushes that no contact's accumulated impulse holds)
      for (int k = 0; k < npts; ++k) c.step_impulse[m][k] += lam[k];
      c.shock_impulse[m] += (lam[0] + lam[1]) + (lam[2] + lam[3]);
    }
    st.body_v[u] = vu;
    add_momentum(st, u, a_moves ? row.inv_ia : row.inv_ib, dl);
    // shock friction: the slip of the supported body on its supporter taken out as well,
    // the supporter held still, within μ times the share of each point's push here that
    // the passes' friction does not bound (shock_friction_share): a 1 kg pallet under
    // 1000 kg slid 4.6 m down a 20° ramp of μ = 0.8 with its crate, bounded in the passes
    // by what they can carry, and without that bound it was thrown about
    const double share = shock_friction_share(model, c, m);
    if (share > 0.0) {
      // at the points' centre by their pushes (as in 2D): the slip there and the
      // supported body's levers r × t1, r × t2 there, each the pushes' mean of the points'
      const Sym3& inv_i = a_moves ? row.inv_ia : row.inv_ib;
      double total = 0.0;  // N·s
      Vec3 rel{}, r1{}, r2{}, arm{};
      for (int k = 0; k < npts; ++k) {
        if (!(lam[k] > 0.0)) continue;
        const auto pt = P[k];
        const Vec3 point_rel = (st.body_v[a] + cross(st.body_w[a], pt.arm_a)) -
                               (st.body_v[b] + cross(st.body_w[b], pt.arm_b));  // m/s
        total += lam[k];
        rel += lam[k] * point_rel;
        arm += lam[k] * (a_moves ? pt.arm_a : pt.arm_b);
        r1 += lam[k] * (a_moves ? pt.rt1a : pt.rt1b);
        r2 += lam[k] * (a_moves ? pt.rt2a : pt.rt2b);
      }
      if (total > 0.0) {
        const double inv_total = 1.0 / total;
        rel = inv_total * rel, arm = inv_total * arm, r1 = inv_total * r1, r2 = inv_total * r2;
        const double v1 = dot(rel, row.t1), v2 = dot(rel, row.t2);
        // the supported body's own 2×2 tangent block there (1/kg)
        const Vec3 i1 = inv_i * r1, i2 = inv_i * r2;
        const double k11 = mu + dot(r1, i1), k22 = mu + dot(r2, i2), k12 = dot(r1, i2);
        const double det = k11 * k22 - k12 * k12;
        if (det > 1e-12 * k11 * k22) {
          // N·s: the impulse along t1, t2 that stops the slip, within Coulomb's circle
          double p1 = -(k22 * v1 - k12 * v2) / det, p2 = -(k11 * v2 - k12 * v1) / det;
          const double bound = row.friction * total * share, len = std::hypot(p1, p2);
          if (len > bound) p1 *= bound / len, p2 *= bound / len;
          // never faster in the tangent plane than u goes there (as in 2D): the change
          // sgn K p of u's point scaled down until |own + change| <= |own|, or up to the
          // speed of the moving kinematic body that carries the supporter (reach_speed)
          const Vec3 own = st.body_v[u] + cross(st.body_w[u], arm);  // m/s
          const double o1 = dot(own, row.t1), o2 = dot(own, row.t2);
          const double c1 = sgn * (k11 * p1 + k12 * p2), c2 = sgn * (k12 * p1 + k22 * p2);
          const double along = o1 * c1 + o2 * c2, change2 = c1 * c1 + c2 * c2;  // m²/s²
          if (change2 > 0.0) {
            double scale = std::clamp(-2.0 * along / change2, 0.0, 1.0);
            if (c.body_carried[a_moves ? b : a] >= 0) {
              const double own2 = o1 * o1 + o2 * o2;  // m²/s²
              const double reach = reach_speed(st, c, a_moves ? b : a, st.body_x[u] + arm, n,
                                               std::sqrt(own2));
              // the largest scale in [0, 1] with |own + scale change|² <= reach²
              const double room = std::max(along * along - change2 * (own2 - reach * reach), 0.0);
              scale = std::clamp((-along + std::sqrt(room)) / change2, 0.0, 1.0);
            }
            p1 *= scale, p2 *= scale;
          }
          st.body_v[u] += (sgn * mu) * (p1 * row.t1 + p2 * row.t2);
          add_momentum(st, u, inv_i, sgn * (p1 * r1 + p2 * r2));
        }
      }
    }
  }
}

}  // namespace

// Each dynamic body's load (kg) into `load` (N,), 0 for the others: its own mass and what
// the bodies resting on it hand down, each of those split evenly over its supporters (the
// shock order's contacts that touch, contacts.support: a speculative one, as the ground
// 1 cm under a box resting on a 2 cm plate, holds none of the load up, and counted, it
// halved what the plate bore; their count per body into `supports`), a body u's share to
// its supporter s taken up to most(u, s) kg. shock_order lists the supports by the
// supporter's level, and a supported body's level is above its supporter's, so taken from
// the end the load of each supported body is complete before it is handed down.
template <int D, class Most>
void hand_down_loads(const Model<D>& model, const Contacts<D>& c, std::int64_t n_order,
                     std::vector<double>& load, std::vector<std::int64_t>& supports,
                     Most most) {
  const std::int64_t n_bodies = model.body_count();
  for (std::int64_t i = 0; i < n_bodies; ++i) {
    load[i] = model.is_dynamic(static_cast<int>(i)) ? 1.0 / model.body_inv_mass[i] : 0.0;
    supports[i] = 0;
  }
  for (std::int64_t o = 0; o < n_order; ++o)
    if (c.support[c.shock_order[o]]) supports[support_of(c, c.shock_order[o]).supported] += 1;
  for (std::int64_t o = n_order - 1; o >= 0; --o) {
    if (!c.support[c.shock_order[o]]) continue;  // (a speculative contact holds nothing up)
    const auto [u, s] = support_of(c, c.shock_order[o]);
    if (model.is_dynamic(s))
      load[s] += std::min(load[u], most(u, s)) / static_cast<double>(supports[u]);
  }
}

// contacts.body_load (N,): the mass (kg) each dynamic body bears, its own and all that
// rests on it (hand_down_loads, no share bounded). Uses contacts.queue.
template <int D>
void borne_loads(const Model<D>& model, Contacts<D>& c, std::int64_t n_order) {
  constexpr double all = std::numeric_limits<double>::infinity();
  hand_down_loads(model, c, n_order, c.body_load, c.queue, [](int, int) { return all; });
}

template <int D>
void hand_down_shock_impulses(const Model<D>& model, Contacts<D>& c) {
  using Vec = typename Dim<D>::Vec;
  const std::int64_t n_order = c.count.shock_count;
  const std::int64_t n_bodies = model.body_count();
  // the supports whose points pushed (those recorded: pushed_in_step), by shock order
  std::vector<std::uint8_t> pushed(n_order, 0);
  for (std::int64_t o = 0; o < n_order; ++o)
    for (int k = 0, m = c.shock_order[o]; k < c.points[m] && !pushed[o]; ++k)
      pushed[o] = pushed_in_step(c, m, k) ? 1 : 0;
  // the direction (unit) in which manifold m pushes its supported body u
  auto push_of = [&](std::int32_t m, int u) { return u == c.body_a[m] ? c.normal[m] : -c.normal[m]; };
  // each body's supports that pushed, as compressed rows (first[u] .. first[u + 1])
  std::vector<std::int64_t> first(n_bodies + 1, 0);
  std::vector<std::int32_t> rows(n_order);
  for (std::int64_t o = 0; o < n_order; ++o)
    if (pushed[o]) first[support_of(c, c.shock_order[o]).supported + 1] += 1;
  for (std::int64_t i = 0; i < n_bodies; ++i) first[i + 1] += first[i];
  std::vector<std::int64_t> fill(first.begin(), first.end() - 1);
  for (std::int64_t o = 0; o < n_order; ++o)
    if (pushed[o])
      rows[fill[support_of(c, c.shock_order[o]).supported]++] = c.shock_order[o];
  // what each body is pushed with from above (N·s) and not yet handed on, and over how
  // many of its supports it goes (-1: not counted yet)
  std::vector<Vec> handed(n_bodies, Vec{});
  std::vector<int> sharing(n_bodies, -1);
  // the shock order by its supporters' levels (the regions regrouped it, region by
  // region, after the step's start): taken from the top, every load on a body is handed
  // to it before its own supports are met
  std::int64_t top = 0;
  for (std::int64_t o = 0; o < n_order; ++o)
    top = std::max(top, c.body_level[support_of(c, c.shock_order[o]).supporter]);
  std::vector<std::int64_t> at(top + 2, 0);
  for (std::int64_t o = 0; o < n_order; ++o)
    at[c.body_level[support_of(c, c.shock_order[o]).supporter] + 1] += 1;
  for (std::int64_t k = 0; k <= top; ++k) at[k + 1] += at[k];
  std::vector<std::int64_t> by_level(n_order);  // (places in the shock order)
  for (std::int64_t o = 0; o < n_order; ++o)
    by_level[at[c.body_level[support_of(c, c.shock_order[o]).supporter]]++] = o;
  for (std::int64_t j = n_order - 1; j >= 0; --j) {
    const std::int64_t o = by_level[j];
    const std::int32_t m = c.shock_order[o];
    const auto [u, s] = support_of(c, m);
    const Vec push = push_of(m, u);
    double portion = 0.0;  // N·s: m's share of what u hands down, along m's normal
    if (pushed[o]) {
      if (sharing[u] < 0) {  // the supports that can take part of it: it presses on them
        sharing[u] = 0;
        for (std::int64_t r = first[u]; r < first[u + 1]; ++r)
          sharing[u] += dot(handed[u], push_of(rows[r], u)) < 0.0 ? 1 : 0;
      }
      const double along = -dot(handed[u], push);  // N·s
      // (m is among the supports counted whenever along > 0: the same product)
      if (along > 0.0 && sharing[u] > 0) portion = along / static_cast<double>(sharing[u]);
    }
    if (portion > 0.0) {
      // over the points that pushed, by what each carried (evenly where none did)
      double total = 0.0;  // N·s
      int count = 0;
      for (int k = 0; k < c.points[m]; ++k) {
        if (!pushed_in_step(c, m, k)) continue;
        total += c.step_impulse[m][k];
        ++count;
      }
      for (int k = 0; k < c.points[m]; ++k) {
        if (!pushed_in_step(c, m, k)) continue;
        const double part = total > 0.0 ? c.step_impulse[m][k] / total : 1.0 / count;
        c.step_impulse[m][k] += portion * part;
      }
    }
    // the supporter is pushed the other way: by the share handed on, and by the shock
    // pass's own pushes here
    if (model.is_dynamic(s)) handed[s] -= (portion + c.shock_impulse[m]) * push;
  }
}

// Support level of every body, and the orders of the solver's and the shock pass.
//
// Writes contacts.solve_order (M,): every manifold, lowest supporter level first (the
// order of the solver's passes; the manifolds' own order without gravity);
// contacts.body_level (N,): 0 for static and kinematic bodies, 1 for bodies they touch,
// ...; UNREACHED otherwise; contacts.shock_order: the manifolds with a supporter, lowest
// supporter first; contacts.shock_side (M,): 1 when body a supports body b, 2 when body b
// supports body a, 0 when neither. Returns the number of manifolds in shock_order. When
// the manifolds are last step's (count.graph_unchanged), the levels and the solve order
// are kept and only the shock pass's side and order are found again (a normal may have
// turned). Uses contacts.queue as scratch.
template <int D>
std::int64_t support_order(const Model<D>& model, Contacts<D>& c) {
  using Vec = typename Dim<D>::Vec;
  auto& level = c.body_level;
  auto& side = c.shock_side;
  auto& order = c.shock_order;
  auto& solve_order = c.solve_order;
  const std::int64_t n_bodies = static_cast<std::int64_t>(level.size());
  const std::int64_t n_man = c.count.manifolds;
  const Vec gravity = model.gravity;
  const double g = std::sqrt(dot(gravity, gravity));  // m/s²
  // the same manifolds as last step, in the same slots: its levels and solve order hold,
  // unless one of them touches where it did not, or no longer, and the levels change
  bool same = c.count.graph_unchanged == 1;
  for (std::int64_t m = 0; m < n_man; ++m) {
    side[m] = 0;
    if (!same) solve_order[m] = static_cast<std::int32_t>(m);
  }
  c.heavy_on_light = false;
  if (g == 0.0 || n_man == 0) return 0;
  const Vec up = (-1.0 / g) * gravity;
  if (!same) {
    contact_levels(model, c);
  } else if (c.count.support_changed) {
    // (a side contact flickering about the gap in a settled pyramid moves no level: its
    // solve order and waves are kept)
    auto& before = c.body_reach;  // (deep_region's scratch)
    std::copy(level.begin(), level.end(), before.begin());
    contact_levels(model, c);
    if (!std::equal(level.begin(), level.end(), before.begin())) {
      same = false;
      c.count.graph_unchanged = 0;  // the regions and waves are made anew too
    }
  }
  // which side supports, and a counting sort by the supporter's level; whether a body
  // rests on a far lighter dynamic one (the supported body's inverse mass HEAVY_RATIO
  // times the supporter's, or less)
  std::int64_t max_level = 0;
  bool heavy = false;
  const auto& im = model.body_inv_mass;
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (c.points[m] == 0) continue;
    const int a = c.body_a[m], b = c.body_b[m];
    const double u = dot(c.normal[m], up);  // the normal points from b to a
    if (level[b] < level[a] && u >= C::SHOCK_COS && model.is_dynamic(a)) {
      side[m] = 2;
      max_level = std::max(max_level, level[b]);
      heavy = heavy || C::HEAVY_RATIO * im[a] <= im[b];
    } else if (level[a] < level[b] && u <= -C::SHOCK_COS && model.is_dynamic(b)) {
      side[m] = 1;
      max_level = std::max(max_level, level[a]);
      heavy = heavy || C::HEAVY_RATIO * im[b] <= im[a];
    }
  }
  c.heavy_on_light = heavy;
  if constexpr (D == 3) {
    // how many manifolds support each body (the shock pass's rule for tall structures)
    auto& held = c.body_supporters;  // (sized here: a checkpoint does not keep it)
    held.assign(static_cast<std::size_t>(n_bodies), 0);
    for (std::int64_t m = 0; m < n_man; ++m)
      if (side[m] != 0) ++held[side[m] == 2 ? c.body_a[m] : c.body_b[m]];
  }
  // every manifold, ordered by the lower of its two bodies' levels (ground first, bodies
  // not connected to the ground last): the order of the solver's passes, in which a pass
  // carries a push or a correction up a stack within one sweep
  auto& count = c.queue;  // reused as bucket counts (the levels are known now)
  if (!same) {
    std::int64_t top = 0;
    for (std::int64_t i = 0; i < n_bodies; ++i)
      if (level[i] != UNREACHED && level[i] > top) top = level[i];
    for (std::int64_t k = 0; k < top + 3; ++k) count[k] = 0;
    for (std::int64_t m = 0; m < n_man; ++m) {
      const std::int64_t lv = std::min(std::min(level[c.body_a[m]], level[c.body_b[m]]), top + 1);
      count[lv + 1] += 1;
    }
    for (std::int64_t k = 0; k < top + 2; ++k) count[k + 1] += count[k];
    for (std::int64_t m = 0; m < n_man; ++m) {
      const std::int64_t lv = std::min(std::min(level[c.body_a[m]], level[c.body_b[m]]), top + 1);
      solve_order[count[lv]++] = static_cast<std::int32_t>(m);
    }
  }
  for (std::int64_t k = 0; k < max_level + 2; ++k) count[k] = 0;
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (side[m] == 2)
      count[level[c.body_b[m]] + 1] += 1;
    else if (side[m] == 1)
      count[level[c.body_a[m]] + 1] += 1;
  }
  for (std::int64_t k = 0; k < max_level + 1; ++k) count[k + 1] += count[k];
  const std::int64_t total = count[max_level + 1];
  for (std::int64_t m = 0; m < n_man; ++m) {
    std::int64_t lv;
    if (side[m] == 2)
      lv = level[c.body_b[m]];
    else if (side[m] == 1)
      lv = level[c.body_a[m]];
    else
      continue;
    order[count[lv]++] = static_cast<std::int32_t>(m);
  }
  if (heavy) borne_loads(model, c, total);  // (crushing reads them)
  return total;
}

// Each manifold's friction load (SolverRow::friction_load, N·s), for the passes' friction
// bounds: μ times the larger of it and the manifold's normal impulses. While a heavy body
// rests on a light one (heavy_on_light) the shock pass carries the loads the soft
// contacts do not (in 2D every approach it meets, not only at the heavy body), and its
// impulses are in no contact's normal impulse (there they would starve the warm start: a
// 100 t box on 1 t ones jittered), so friction bounded by those alone was too weak: a
// 100 kg crate on a 1 kg pallet slid 3 m down a 20° ramp of μ = 0.8, a plate under 30
// times its mass, sliding, stopped in twice Coulomb's time, and a 1 kg box sliding on a
// plank that carried a heavy one went 1.7 m where Coulomb stops it in 0.46. So each
// supporting manifold (shock_order, touching) gets the load its supported body u passes
// on through the passes' friction along its normal for a substep, |g·n| h / (u's
// supports that touch), h the substep (s): u's own mass and what the bodies resting on it
// pass on (hand_down_loads), each body's share, u's too, up to FRICTION_LOAD_RATIO times
// the lighter of its pair. The shock pass's friction takes the rest of a load into the
// ground (shock_friction_share): counted here, a 10 t box on a 1 kg plate on a 10 t one,
// sliding, gave the lower box the ground's friction for 20 t, and it stopped at 0.57 m
// where all three stop at 1.15. The passes share the load over the manifold's touching
// points (solve.cpp, bounding_impulses). Without a heavy body on a light one every
// manifold gets 0 (the rows prepare_contacts did not write again are cleared here when a
// step before set any). Uses contacts.queue and body_motion (as scratch: the overlap
// limit makes it anew at the step's end).
template <int D>
void friction_loads(const Model<D>& model, const State<D>& st, Contacts<D>& c, std::int64_t n_order,
                    double h) {
  const std::int64_t n_man = c.count.manifolds;
  if (c.count.friction_loaded)
    for (std::int64_t m = 0; m < n_man; ++m) c.solver_row[m].friction_load = 0.0;
  c.count.friction_loaded = c.heavy_on_light;
  if (!c.heavy_on_light) return;
  const auto& im = model.body_inv_mass;
  auto most = [&](int u, int s) { return C::FRICTION_LOAD_RATIO / std::max(im[u], im[s]); };
  auto& passed = c.body_motion;  // kg
  auto& supports = c.queue;
  hand_down_loads(model, c, n_order, passed, supports, most);
  for (std::int64_t o = 0; o < n_order; ++o) {
    const std::int32_t m = c.shock_order[o];
    if (!c.support[m]) continue;  // (a speculative contact holds nothing up)
    const auto [u, s] = support_of(c, m);
    const double borne = std::min(passed[u], most(u, s));  // kg
    const double weight = borne * std::fabs(dot(model.gravity, c.normal[m])) * h;  // N·s
    c.solver_row[m].friction_load = weight / static_cast<double>(supports[u]);
  }
  // the bodies a moving kinematic body carries, through the touching supports from below
  // (the shock order lists a supporter's own supports first)
  const std::int64_t n_bodies = model.body_count();
  for (std::int64_t i = 0; i < n_bodies; ++i) {
    const bool moving = model.body_type[i] == BodyType::Kinematic &&
                        !(all_zero(st.body_v[i]) && all_zero(st.body_w[i]));
    c.body_carried[i] = moving ? static_cast<std::int32_t>(i) : -1;
  }
  for (std::int64_t o = 0; o < n_order; ++o) {
    const std::int32_t m = c.shock_order[o];
    if (!c.support[m]) continue;
    const auto [u, s] = support_of(c, m);
    if (c.body_carried[s] >= 0 && c.body_carried[u] < 0) c.body_carried[u] = c.body_carried[s];
  }
}

namespace {

// What reach_deep found around the deep overlaps: nothing (none seeds), the dynamic
// bodies within reach (contacts.body_reach >= 0), or every manifold.
enum class Reach { None, Bodies, Everything };

// The seeds and the walk of deep_region: the overlaps of
// contacts.relax_list[:count.deep_count] whose bodies have moved (kept, in order, at the
// list's head), and the dynamic bodies within `reach` contacts of theirs, breadth first
// (contacts.body_reach: how many contacts away, -1 beyond; uses contacts.queue).
template <int D>
Reach reach_deep(const Model<D>& model, Contacts<D>& c, int reach) {
  auto& queue = c.queue;
  auto& dist = c.body_reach;
  auto& relax_list = c.relax_list;
  // whether body i has moved this step so far (body_delta) by STILL_DISTANCE (m, times its
  // scale) or turned by STILL_ANGLE (rad)
  auto moving = [&](int i) {
    const BodyDelta<D>& d = c.body_delta[i];
    const double still = c.body_scale[i] * C::STILL_DISTANCE;  // m
    double turn2;  // about the turn² (rad²): sin² of the turn (2D), 4 sin² of its half (3D)
    if constexpr (D == 2)
      turn2 = d.dq.s * d.dq.s;
    else
      turn2 = 4.0 * (d.dq.x * d.dq.x + d.dq.y * d.dq.y + d.dq.z * d.dq.z);
    return dot(d.dx, d.dx) >= still * still || turn2 >= C::STILL_ANGLE * C::STILL_ANGLE;
  };
  std::int64_t n_seeds = 0;
  for (std::int64_t k = 0; k < c.count.deep_count; ++k) {
    const std::int32_t m = relax_list[k];
    if (moving(c.body_a[m]) || moving(c.body_b[m])) relax_list[n_seeds++] = m;
  }
  if (n_seeds == 0) return Reach::None;
  if (n_seeds >= static_cast<std::int64_t>(relax_list.size()) || all_zero(model.gravity))
    return Reach::Everything;
  for (auto& d : dist) d = -1;
  // breadth first from the deep manifolds' bodies; static and kinematic bodies are not
  // passed through (a push does not travel through the ground)
  std::int64_t tail = 0;
  for (std::int64_t k = 0; k < n_seeds; ++k) {
    const std::int32_t m = relax_list[k];
    for (const int i : {c.body_a[m], c.body_b[m]}) {
      if (model.is_dynamic(i) && dist[i] < 0) {
        dist[i] = 0;
        queue[tail++] = i;
      }
    }
  }
  std::int64_t head = 0;
  while (head < tail) {
    const std::int64_t i = queue[head++];
    if (dist[i] >= reach) continue;
    for (std::int64_t e = c.adj_start[i]; e < c.adj_start[i + 1]; ++e) {
      const int j = c.adj[e];
      if (model.is_dynamic(j) && dist[j] < 0) {
        dist[j] = dist[i] + 1;
        queue[tail++] = j;
      }
    }
  }
  return Reach::Bodies;
}

}  // namespace

// The manifolds near a deep overlap, for the relax stage's extra passes: those of the
// dynamic bodies within `reach` contacts of a body in a manifold of
// contacts.relax_list[:count.deep_count], written in solve order over that list; returns
// their count. Every manifold when the list is full or the scene has no gravity (the
// contact graph, contact_levels' adjacency, is built only for the shock pass). A deep
// overlap between two bodies that have not moved in the step so far (contacts.body_delta:
// each within STILL_DISTANCE, times its scale, and STILL_ANGLE of its pose at the step's
// start) is not being pushed out, and seeds nothing: a circle wedged deep between two
// others at the foot of a settled pile stays so for thousands of steps, and its extra
// passes cost a pile of 800 circles a quarter of its step. None when no overlap seeds
// any. Uses contacts.queue and body_reach as scratch.
template <int D>
std::int64_t deep_region(const Model<D>& model, Contacts<D>& c, int reach) {
  const Reach found = reach_deep(model, c, reach);
  if (found == Reach::None) return 0;
  const auto& order = c.solve_order;
  const std::int64_t n_man = c.count.manifolds;
  if (found == Reach::Everything) {
    for (std::int64_t o = 0; o < n_man; ++o) c.relax_list[o] = order[o];
    return n_man;
  }
  const auto& dist = c.body_reach;
  std::int64_t count = 0;
  for (std::int64_t o = 0; o < n_man; ++o) {
    const std::int32_t m = order[o];
    if (dist[c.body_a[m]] >= 0 || dist[c.body_b[m]] >= 0) c.relax_list[count++] = m;
  }
  return count;
}

namespace {

// How fast manifold m's fastest point closes (m/s, > 0 closing, < 0 all parting) at the
// bodies' velocities now, each point's lever arms those of its solver row (as the shock
// pass).
template <int D>
double closing_speed(const State<D>& st, const Contacts<D>& c, std::int32_t m) {
  const int a = c.body_a[m], b = c.body_b[m];
  const SolverRow<D>& row = c.solver_row[m];
  const double along = dot(row.normal, st.body_v[a] - st.body_v[b]);  // m/s
  double fastest = -std::numeric_limits<double>::infinity();
  for (int p = 0; p < c.points[m]; ++p) {
    double vel;  // m/s, > 0 parting
    if constexpr (D == 2)
      vel = along + (angular_along(st.body_w[a], row.point[p].rna) -
                     angular_along(st.body_w[b], row.point[p].rnb));
    else
      vel = along + (dot(st.body_w[a], row.point.rna[p]) - dot(st.body_w[b], row.point.rnb[p]));
    fastest = std::max(fastest, -vel);
  }
  return fastest;
}

}  // namespace

// Whether a manifold of contacts.relax_list[:count.deep_count] (the deep overlaps the
// solve pass met) has a point closing faster than min_approach (m/s).
template <int D>
bool deep_approaching(const State<D>& st, const Contacts<D>& c, double min_approach) {
  for (std::int64_t k = 0; k < c.count.deep_count; ++k)
    if (closing_speed(st, c, c.relax_list[k]) > min_approach) return true;
  return false;
}

// The manifolds of list[0..n) with a point closing faster than min_approach (m/s), moved
// to its front in their order; returns their count.
template <int D>
std::int64_t keep_closing(const State<D>& st, const Contacts<D>& c, std::int32_t* list,
                          std::int64_t n, double min_approach) {
  std::int64_t kept = 0;
  for (std::int64_t k = 0; k < n; ++k)
    if (closing_speed(st, c, list[k]) > min_approach) list[kept++] = list[k];
  return kept;
}

// 2D: deep_region's manifolds as lanes of the waves' batches, in the batches' order (the
// solve order, as the list: waves.cpp), with min_approach > 0 only those closing faster
// than it (keep_closing). Uses contacts.queue and body_reach as scratch.
std::int64_t deep_region_lanes(const Model<2>& model, const State<2>& st, Contacts<2>& c,
                               int reach, double min_approach, BatchLanes* out) {
  const Reach found = reach_deep(model, c, reach);
  if (found == Reach::None) return 0;
  const auto& dist = c.body_reach;
  const bool all = found == Reach::Everything;
  std::int64_t n = 0;
  for (std::int64_t g = 0; g < c.wave_count; ++g) {
    for (std::int64_t i = c.wave_batch[g]; i < c.wave_batch[g + 1]; ++i) {
      const WideBatch& w = c.batches[i];
      unsigned bits = 0;
      for (int l = 0; l < LANES; ++l) {
        const std::int32_t m = w.m[l];
        if (m < 0 || !(all || dist[w.a[l]] >= 0 || dist[w.b[l]] >= 0)) continue;
        if (min_approach > 0.0 && !(closing_speed(st, c, m) > min_approach)) continue;
        bits |= 1u << l;
      }
      if (bits != 0)
        out[n++] = {static_cast<std::int32_t>(i), static_cast<std::uint8_t>(bits),
                    i < c.wave_single_batch[g]};
    }
  }
  return n;
}

// One pass over the supported contacts, lowest first, that removes each supported body's
// approach towards its supporter (the supporter taken as infinitely heavy). A point with a
// gap (m) may still close it within the substep (1/inv_h s). An elastic contact
// (restitution > 0) approaching faster than `threshold` (m/s) is an impact, not a load: it
// is left to the next substep's solve and bounce (taken here, its energy would be lost: a
// ball struck down onto the floor stopped dead), unless its load crushes (CRUSH_RATIO: a
// 6 t slab landing on a 16 kg box knocked the box into the ground in the restitution
// stage, and went through it). A crushing load is taken however slowly it approaches.
template <int D>
void propagate_shock(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t n_order,
                     double inv_h, double threshold, double min_approach) {
  propagate_shock_range(model, st, c, 0, n_order, inv_h, threshold, min_approach);
}

template <int D>
void propagate_shock_range(const Model<D>& model, State<D>& st, Contacts<D>& c,
                           std::int64_t first, std::int64_t last, double inv_h,
                           double threshold, double min_approach) {
  if constexpr (D == 3) {
    propagate_shock_3d(model, st, c, first, last, inv_h, threshold, min_approach);
  } else {
  using Vec = typename Dim<D>::Vec;
  auto& v = st.body_v;
  auto& w = st.body_w;
  for (std::int64_t o = first; o < last; ++o) {
    const std::int32_t m = c.shock_order[o];
    const int a = c.body_a[m], b = c.body_b[m];
    const SolverRow<D>& row = c.solver_row[m];
    const auto& pt0 = row.point[0];
    const auto& pt1 = row.point[1];
    const Vec n = row.normal;
    const int npts = c.points[m];
    // most supported points are not approaching: skip them before any other work
    const Vec dv = v[a] - v[b];
    const double dvn = dot(dv, n);
    double vel0 = dvn + angular_along(w[a], pt0.rna) - angular_along(w[b], pt0.rnb);
    double vel1 = 0.0;
    if (npts == 2) vel1 = dvn + angular_along(w[a], pt1.rna) - angular_along(w[b], pt1.rnb);
    // the supported body moves; the sign turns its push along +n (a) or -n (b)
    const bool a_moves = c.shock_side[m] == 2;
    const bool held_by_dynamic = model.is_dynamic(a_moves ? b : a);
    bool struck = false;  // by its dynamic supporter
    if (held_by_dynamic) {
      // a dynamic supporter travelling towards u faster than an impact strikes it (a
      // light body bounced off the floor into a heavy one above): none of its motion is
      // handed on, u is only kept from approaching it as if it stood (as in 3D, rising
      // supporters, the file's head), and the strike is the next substep's. Handed on, a
      // 50 g capsule bounced up at 88 m/s lifted the 16 kg polygon resting on it at 80.
      const double travel = a_moves ? dot(n, v[b]) : -dot(n, v[a]);  // m/s, towards u
      struck = travel > threshold;
      if (struck) {
        // m/s: the supporter's motion towards u at a point
        auto toward = [&](const auto& pt) {
          return travel + (a_moves ? angular_along(w[b], pt.rnb) : -angular_along(w[a], pt.rna));
        };
        vel0 += std::max(toward(pt0), 0.0);
        if (npts == 2) vel1 += std::max(toward(pt1), 0.0);
      }
    }
    if (!(vel0 < -min_approach || (npts == 2 && vel1 < -min_approach))) continue;
    // an impact that does not crush: as in the 3D pass
    const bool impact = std::min(vel0, vel1) < -threshold && !crushing(model, c, m);
    if (impact && c.restitution[m] > 0.0) continue;
    const BodyDelta<D>& da = c.body_delta[a];
    const BodyDelta<D>& db = c.body_delta[b];
    const double moved = dot(n, da.dx - db.dx);  // m
    // the normal turned back into each body's frame at the step's start
    const Vec na = inv_rotate(da.dq, n);
    const Vec nb = inv_rotate(db.dq, n);
    const int u = a_moves ? a : b;
    const double sgn = a_moves ? 1.0 : -1.0;
    const double mu = model.body_inv_mass[u], iu = model.body_inv_inertia[u];
    // how far each point is from allowed (m/s): a gap may close within the substep
    const double sep0 = row_separation(pt0, moved, na, nb);
    double need0 = (sep0 > 0.0 ? -sep0 * inv_h : 0.0) - vel0;
    const double r0 = a_moves ? pt0.rna : pt0.rnb;  // m: the supported body's lever
    double need1 = 0.0, r1 = 0.0, nearest = sep0;  // m: the least separation
    if (npts == 2) {
      const double sep1 = row_separation(pt1, moved, na, nb);
      need1 = (sep1 > 0.0 ? -sep1 * inv_h : 0.0) - vel1;
      r1 = a_moves ? pt1.rna : pt1.rnb;
      nearest = std::min(nearest, sep1);
    }
    // an impact still apart waits for its bodies to meet (restitution.cpp), elastic or
    // not, and gets its friction when they do: pushed here, it would close without any
    if (impact && nearest > row.touch) continue;
    if (c.heavy_on_light && held_by_dynamic && !struck) {
      // a dynamic supporter's turn towards u is not handed on (lifting, the file's head)
      const int s = a_moves ? b : a;
      const double rs0 = a_moves ? pt0.rnb : pt0.rna, rs1 = a_moves ? pt1.rnb : pt1.rna;
      need0 -= std::max(sgn * angular_along(w[s], rs0), 0.0);
      if (npts == 2) need1 -= std::max(sgn * angular_along(w[s], rs1), 0.0);
    }
    // impulses (N·s) along the supported body's push direction, λ >= 0, that bring every
    // point to at least its target: the two-point case is a 2x2 complementarity problem,
    // solved by trying both points, then each alone
    double l0 = 0.0, l1 = 0.0;
    const double k00 = mu + iu * r0 * r0;  // 1/kg
    if (npts == 1) {
      if (need0 > 0.0 && k00 > 0.0) l0 = need0 / k00;
    } else {
      const double k11 = mu + iu * r1 * r1;
      const double k01 = mu + iu * r0 * r1;
      const double det = k00 * k11 - k01 * k01;
      bool done = false;
      if (det > 1e-12 * k00 * k11) {
        l0 = (k11 * need0 - k01 * need1) / det;
        l1 = (k00 * need1 - k01 * need0) / det;
        done = l0 >= 0.0 && l1 >= 0.0;
      }
      if (!done) {
        l0 = l1 = 0.0;
        if (need0 > 0.0 && k00 > 0.0 && k01 * need0 / k00 >= need1) {
          l0 = need0 / k00;
        } else if (need1 > 0.0 && k11 > 0.0 && k01 * need1 / k11 >= need0) {
          l1 = need1 / k11;
        } else if (need0 > 0.0 || need1 > 0.0) {
          // parallel arms (singular K): one impulse at the neediest point
          if (need0 >= need1 && k00 > 0.0)
            l0 = need0 / k00;
          else if (k11 > 0.0)
            l1 = need1 / k11;
        }
      }
    }
    const double impulse = l0 + l1;
    if (impulse == 0.0) continue;
    c.shock_points[m] |= static_cast<std::uint8_t>((l0 > 0.0 ? 1u : 0u) | (l1 > 0.0 ? 2u : 0u));
    if (c.record_impulses) {
      c.step_impulse[m][0] += l0;
      if (npts == 2) c.step_impulse[m][1] += l1;
      c.shock_impulse[m] += impulse;
    }
    v[u] += (sgn * mu * impulse) * n;
    w[u] += sgn * iu * (l0 * r0 + l1 * r1);
    // shock friction (as in the 3D pass): the slip on the supporter, held still, taken out
    // within μ times the share of the push the passes' friction does not bound, as one
    // impulse at the points' centre by their pushes (a face's points alike, whatever
    // their order)
    const double share = shock_friction_share(model, c, m);
    if (share > 0.0) {
      const Vec t = cross(n, 1.0);
      const double rta = (l0 * pt0.rta + l1 * pt1.rta) / impulse;  // m: the levers there
      const double rtb = (l0 * pt0.rtb + l1 * pt1.rtb) / impulse;
      const double rtu = a_moves ? rta : rtb;  // m: the supported body's
      const double vt = dot(v[a] - v[b], t) + (w[a] * rta - w[b] * rtb);  // m/s
      const double kt = mu + iu * rtu * rtu;  // 1/kg
      if (kt > 0.0) {
        const double bound = row.friction * impulse * share;
        double f = std::clamp(-vt / kt, -bound, bound);  // N·s along t
        // never faster along t than u goes there (a light supporter's slip is not handed
        // on: followed, a 100 kg box on a 0.01 kg one took up the light box's rounding,
        // grown step by step to mm/s), but up to the speed of the moving kinematic body
        // that carries the supporter (reach_speed): a 10 t box on a 1 kg plate on a belt at
        // 1 m/s, μ 0.3, rode 0.07 m in 3 s where it rides 2.8 (and, with no bound, on
        // three 1 kg plates, it sped up past the belt to 3 m/s)
        const double own = dot(v[u], t) + w[u] * rtu;  // m/s: u's point along t
        const double change = sgn * f * kt;           // m/s: what f does to it
        if (change != 0.0) {
          double reach = std::fabs(own);  // m/s
          if (c.body_carried[a_moves ? b : a] >= 0) {  // (the points' centre, by their pushes)
            const auto& anchor = a_moves ? c.anchor_a[m] : c.anchor_b[m];
            const Vec arm = (1.0 / impulse) * (l0 * anchor[0] + l1 * anchor[npts == 2 ? 1 : 0]);
            reach = reach_speed(st, c, a_moves ? b : a, st.body_x[u] + arm, n, reach);
          }
          // the largest scale in [0, 1] with |own + scale change| <= reach
          const double limit = change > 0.0 ? reach - own : -reach - own;  // m/s
          f *= std::clamp(limit / change, 0.0, 1.0);
        }
        v[u] += (sgn * mu * f) * t;
        w[u] += sgn * iu * f * rtu;
      }
    }
  }
  }
}

template std::int64_t support_order(const Model<2>&, Contacts<2>&);
template std::int64_t deep_region(const Model<2>&, Contacts<2>&, int);
template void propagate_shock(const Model<2>&, State<2>&, Contacts<2>&, std::int64_t, double,
                              double, double);
template bool deep_approaching(const State<2>&, const Contacts<2>&, double);
template bool deep_approaching(const State<3>&, const Contacts<3>&, double);
template std::int64_t keep_closing(const State<2>&, const Contacts<2>&, std::int32_t*,
                                   std::int64_t, double);
template std::int64_t keep_closing(const State<3>&, const Contacts<3>&, std::int32_t*,
                                   std::int64_t, double);
template void propagate_shock_range(const Model<2>&, State<2>&, Contacts<2>&, std::int64_t,
                                    std::int64_t, double, double, double);
template void propagate_shock_range(const Model<3>&, State<3>&, Contacts<3>&, std::int64_t,
                                    std::int64_t, double, double, double);
template std::int64_t support_order(const Model<3>&, Contacts<3>&);
template void hand_down_shock_impulses(const Model<2>&, Contacts<2>&);
template void hand_down_shock_impulses(const Model<3>&, Contacts<3>&);
template void friction_loads(const Model<2>&, const State<2>&, Contacts<2>&, std::int64_t, double);
template void friction_loads(const Model<3>&, const State<3>&, Contacts<3>&, std::int64_t, double);
template std::int64_t deep_region(const Model<3>&, Contacts<3>&, int);
template void propagate_shock(const Model<3>&, State<3>&, Contacts<3>&, std::int64_t, double,
                              double, double);

}  // namespace rbsim
