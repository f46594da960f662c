// Waves of the solve order: groups of manifolds that can be solved at once, LANES at a
// time, with exactly the result of solving them one after the other.
//
// The solver's passes take the manifolds in solve order (support_order: ground first,
// level by level), and that order matters: a pass carries a push up a stack within one
// sweep (solved colour by colour over the whole scene instead, a base-40 pyramid drifted
// 5 cm in 10 s and a card house fell; colour by colour within each level, the pyramid
// still drifted 8 cm). But two manifolds that share no dynamic body can be swapped
// without changing anything: neither reads what the other writes (the solver never
// changes a static or kinematic body's velocity). So each manifold goes in the wave after
// the last wave of the manifolds before it that share one of its dynamic bodies; the
// manifolds of a wave are independent, and solving the waves in turn is solving the
// solve order, one manifold after another, reordered only where that changes nothing. A
// wave's manifolds are packed LANES at a time for solve.cpp, which solves them in vector
// registers; a pass gives the same result however a wave is split (one by one, several
// at a time, or on several threads).
#include <algorithm>
#include <array>
#include <cstdint>

#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"

namespace rbsim {

namespace {

// Fill lane l of batch w with manifold m's row, or leave it empty (m < 0: zero rows,
// body 0, never written).
template <int D>
void pack_lane(const Model<D>& model, const Contacts<D>& c, WideBatch& w, int l, std::int32_t m) {
  const std::uint32_t bits = (1u << l) | (1u << (LANES + l));
  if (m < 0) {
    w.m[l] = -1;
    w.live[l] = 0;
    w.writes &= ~bits;
    w.a[l] = w.b[l] = 0;
    w.nx[l] = w.ny[l] = w.k01[l] = w.gamma[l] = w.bias_rate[l] = w.friction[l] = 0.0;
    w.max_push[l] = w.deep[l] = 0.0;
    w.ma[l] = w.mb[l] = w.ia[l] = w.ib[l] = w.two[l] = 0.0;
    for (WidePoint* p : {&w.p0, &w.p1}) {
      p->rna[l] = p->rnb[l] = p->rta[l] = p->rtb[l] = 0.0;
      p->kn[l] = 1.0;  // no division by zero in an empty lane
      p->tangent_mass[l] = p->rax[l] = p->ray[l] = p->rbx[l] = p->rby[l] = p->base[l] = 0.0;
    }
    return;
  }
  const SolverRow<2>& row = c.solver_row[m];
  const int a = c.body_a[m], b = c.body_b[m];
  w.m[l] = m;
  w.live[l] = -1;
  w.a[l] = a;
  w.b[l] = b;
  w.nx[l] = row.normal.x;
  w.ny[l] = row.normal.y;
  w.k01[l] = row.k01;
  w.gamma[l] = row.gamma;
  w.bias_rate[l] = row.bias_rate;
  w.friction[l] = row.friction;
  if (!c.unit_scale) {  // (else the solve takes the constants: solve_batch)
    w.max_push[l] = row.max_push;
    w.deep[l] = row.deep;
  }
  w.ma[l] = model.body_inv_mass[a];
  w.mb[l] = model.body_inv_mass[b];
  w.ia[l] = model.body_inv_inertia[a];
  w.ib[l] = model.body_inv_inertia[b];
  // (a static or kinematic body's velocity is not written back: see solve_contacts)
  w.writes &= ~bits;
  if (w.ma[l] != 0.0 || w.ia[l] != 0.0) w.writes |= 1u << l;
  if (w.mb[l] != 0.0 || w.ib[l] != 0.0) w.writes |= 1u << (LANES + l);
  const bool two = c.points[m] == 2;
  w.two[l] = two ? 1.0 : 0.0;
  // a batch holds manifolds of one point count (find_waves): a one-point batch's second
  // point is never read, and is not written
  for (int k = 0; k < (two ? 2 : 1); ++k) {
    WidePoint& p = k == 0 ? w.p0 : w.p1;
    const auto& pt = row.point[k];
    p.rna[l] = pt.rna;
    p.rnb[l] = pt.rnb;
    p.rta[l] = pt.rta;
    p.rtb[l] = pt.rtb;
    p.kn[l] = pt.kn;
    p.tangent_mass[l] = pt.tangent_mass;
    p.rax[l] = pt.ra.x;
    p.ray[l] = pt.ra.y;
    p.rbx[l] = pt.rb.x;
    p.rby[l] = pt.rb.y;
    p.base[l] = pt.base;
  }
}

}  // namespace

template <int D>
std::int64_t find_waves(const Model<D>& model, Contacts<D>& c) {
  if constexpr (D == 3) {
    // 3D rows are solved one manifold after another in solve order (solve_waves<3>):
    // the batches hold 2D rows
    c.wave_count = 0;
    c.waves_valid = false;
    return 0;
  } else {
  const std::int64_t n_man = c.count.manifolds;
  if (c.count.graph_unchanged == 1 && c.waves_valid) {
    // last step's manifolds in the same slots and the same solve order (support_order
    // keeps it): the waves hold, and only the rows that prepare wrote again are packed
    // again (a carried manifold's row changes in its base separations only), unless a
    // manifold's point count changed (it belongs in a batch of the other kind)
    bool same_kinds = true;
    for (std::int64_t i = 0; same_kinds && i < c.wave_batch[c.wave_count]; ++i) {
      WideBatch& w = c.batches[i];
      for (int l = 0; l < LANES; ++l) {
        const std::int32_t m = w.m[l];
        if (m < 0) continue;
        if (c.carried[m]) {
          w.p0.base[l] = c.solver_row[m].point[0].base;
          if (w.two[l] != 0.0) w.p1.base[l] = c.solver_row[m].point[1].base;
        } else if ((c.points[m] == 2) == (w.two[l] != 0.0)) {
          pack_lane(model, c, w, l, m);
        } else {
          same_kinds = false;
          break;
        }
      }
    }
    if (same_kinds) return c.wave_count;
  }
  auto& last = c.body_wave;
  auto& wave = c.manifold_wave;
  for (auto& w : last) w = 0;
  std::int32_t n_waves = 0;
  // segment by segment (regions.cpp: the regions of the threaded passes), each in waves
  // of its own after the last segment's
  const int n_segments = segment_count(static_cast<int>(c.region_count));
  if (c.region_count == 1) {  // one region: the whole solve order
    c.segment_order[0] = 0;
    for (int g = 1; g <= n_segments; ++g) c.segment_order[g] = n_man;
  }
  for (int g = 0; g < n_segments; ++g) {
    const std::int32_t first = n_waves;
    c.segment_wave[g] = first;
    for (std::int64_t o = c.segment_order[g]; o < c.segment_order[g + 1]; ++o) {
      const std::int32_t m = c.solve_order[o];
      const int a = c.body_a[m], b = c.body_b[m];
      const bool da = model.is_dynamic(a), db = model.is_dynamic(b);
      // waves are 0-based
      const std::int32_t k = std::max({first, da ? last[a] : 0, db ? last[b] : 0});
      wave[m] = k;
      if (da) last[a] = k + 1;
      if (db) last[b] = k + 1;
      n_waves = std::max(n_waves, k + 1);
    }
  }
  c.segment_wave[n_segments] = n_waves;
  // a counting sort by wave, in solve order within a wave
  auto& start = c.wave_start;
  for (std::int32_t k = 0; k <= n_waves; ++k) start[k] = 0;
  for (std::int64_t m = 0; m < n_man; ++m) start[wave[m] + 1] += 1;
  for (std::int32_t k = 0; k < n_waves; ++k) start[k + 1] += start[k];
  auto& fill = c.wave_batch;  // scratch cursors first, the batch ranges after
  for (std::int32_t k = 0; k <= n_waves; ++k) fill[k] = start[k];
  // within a wave the two-point manifolds first, then the one-point ones (circles,
  // capsule ends), each in solve order and in batches of their own (a one-point batch
  // skips the second point's work)
  for (int pass = 2; pass >= 1; --pass) {
    for (std::int64_t o = 0; o < n_man; ++o) {
      const std::int32_t m = c.solve_order[o];
      if ((c.points[m] == 2) == (pass == 2)) c.wave_order[fill[wave[m]]++] = m;
    }
    if (pass == 2)
      for (std::int32_t k = 0; k < n_waves; ++k) c.wave_single[k] = fill[k];
  }
  // the batches' room: made here, for what this step packs (every batch holds 1 to
  // LANES manifolds, so up to M of them; most steps need about M / LANES plus a few per
  // wave, and room for M, about 1 KB each, took seconds to make in a large pile)
  std::int64_t needed = 0;
  for (std::int32_t k = 0; k < n_waves; ++k)
    needed += (c.wave_single[k] - start[k] + LANES - 1) / LANES +
              (start[k + 1] - c.wave_single[k] + LANES - 1) / LANES;
  if (static_cast<std::int64_t>(c.batches.size()) < needed)
    c.batches.resize(static_cast<std::size_t>(needed + needed / 4));
  std::int64_t n_batches = 0;
  for (std::int32_t k = 0; k < n_waves; ++k) {
    c.wave_batch[k] = n_batches;
    for (int part = 0; part < 2; ++part) {  // the two-point batches, then the one-point ones
      const std::int64_t from = part == 0 ? start[k] : c.wave_single[k];
      const std::int64_t end = part == 0 ? c.wave_single[k] : start[k + 1];
      if (part == 1) c.wave_single_batch[k] = n_batches;
      for (std::int64_t i = from; i < end; i += LANES) {
        WideBatch& w = c.batches[n_batches++];
        for (int l = 0; l < LANES; ++l)
          pack_lane(model, c, w, l, i + l < end ? c.wave_order[i + l] : -1);
      }
    }
  }
  c.wave_batch[n_waves] = n_batches;
  c.wave_count = n_waves;
  c.waves_valid = true;
  return n_waves;
  }
}

template std::int64_t find_waves(const Model<2>&, Contacts<2>&);
template std::int64_t find_waves(const Model<3>&, Contacts<3>&);

}  // namespace rbsim
