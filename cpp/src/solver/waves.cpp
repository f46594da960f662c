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
// at a time, or on several threads). The lanes are filled across waves too: a batch also
// takes manifolds of later waves, where none of their bodies' earlier manifolds comes
// after it (schedule_units: a pyramid's waves of 4 or 5 filled three lanes in four), and
// each batch is then a wave of its own. In 3D one-point manifolds go into lanes, and faces
// of two to four points that hold an impulse, LANES of one count at a time; the others
// are left to the solve of one manifold at a time (pack_waves_3d).
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <utility>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// 2D: batch w from the rows of manifolds ms (−1: an empty lane: zeros, K 1, body 0, never
// written), all of one point count (`two`). A row (SolverRow<2>, 32 doubles) holds its
// fields in the order of the batch's lane vectors, so each four consecutive doubles of the
// four rows are loaded at once and transposed into four lane vectors, instead of a store
// per field and lane. A one-point batch's second point is written too (never read), and
// the rows' max_push, deep and touch (not read where every shape is of unit scale).
void pack_batch(const Model<2>& model, const Contacts<2>& c, WideBatch& w,
                const std::int32_t (&ms)[LANES], bool two) {
  using Row = SolverRow<2>;
  using Pt = Row::Point;
  static_assert(sizeof(Row) == 32 * sizeof(double) && sizeof(Pt) == 11 * sizeof(double));
  static_assert(offsetof(Row, normal) == 0 && offsetof(Row, k01) == 16 &&
                offsetof(Row, gamma) == 24 && offsetof(Row, bias_rate) == 32 &&
                offsetof(Row, friction) == 40 && offsetof(Row, point) == 48 &&
                offsetof(Row, max_push) == 224 && offsetof(Row, deep) == 232 &&
                offsetof(Row, touch) == 240 && offsetof(Row, friction_load) == 248);
  static_assert(offsetof(Pt, rna) == 0 && offsetof(Pt, rnb) == 8 && offsetof(Pt, rta) == 16 &&
                offsetof(Pt, rtb) == 24 && offsetof(Pt, kn) == 32 &&
                offsetof(Pt, tangent_mass) == 40 && offsetof(Pt, ra) == 48 &&
                offsetof(Pt, rb) == 64 && offsetof(Pt, base) == 80);
  // an empty lane's row: zeros, but K = 1 (no division by zero)
  static const Row empty = [] {
    Row r{};
    r.point[0].kn = r.point[1].kn = 1.0;
    return r;
  }();
  const double* row[LANES];
  for (int l = 0; l < LANES; ++l)
    row[l] = reinterpret_cast<const double*>(ms[l] >= 0 ? &c.solver_row[ms[l]] : &empty);
  auto part = [&row](int k, Lanes& f0, Lanes& f1, Lanes& f2, Lanes& f3) {
    gather_quads(row[0] + 4 * k, row[1] + 4 * k, row[2] + 4 * k, row[3] + 4 * k, f0, f1, f2, f3);
  };
  WidePoint& p = w.p0;
  WidePoint& q = w.p1;
  part(0, w.nx, w.ny, w.k01, w.gamma);
  part(1, w.bias_rate, w.friction, p.rna, p.rnb);
  part(2, p.rta, p.rtb, p.kn, p.tangent_mass);
  part(3, p.rax, p.ray, p.rbx, p.rby);
  part(4, p.base, q.rna, q.rnb, q.rta);
  if (two) {
    part(5, q.rtb, q.kn, q.tangent_mass, q.rax);
    part(6, q.ray, q.rbx, q.rby, q.base);
  }
  part(7, w.max_push, w.deep, w.touch, w.load);
  const double* im = model.body_inv_mass.data();
  const double* ii = model.body_inv_inertia.data();
  std::uint32_t writes = 0;
  for (int l = 0; l < LANES; ++l) {
    const std::int32_t m = ms[l];
    w.m[l] = m;
    const int a = m >= 0 ? c.body_a[m] : 0, b = m >= 0 ? c.body_b[m] : 0;
    w.a[l] = a;
    w.b[l] = b;
    w.live[l] = m >= 0 ? -1 : 0;
    w.two[l] = m >= 0 && two ? 1.0 : 0.0;
    const double ma = m >= 0 ? im[a] : 0.0, mb = m >= 0 ? im[b] : 0.0;
    const double ia = m >= 0 ? ii[a] : 0.0, ib = m >= 0 ? ii[b] : 0.0;
    w.ma[l] = ma;
    w.mb[l] = mb;
    w.ia[l] = ia;
    w.ib[l] = ib;
    // (a static or kinematic body's velocity is not written back: see solve_contacts)
    if (ma != 0.0 || ia != 0.0) writes |= 1u << l;
    if (mb != 0.0 || ib != 0.0) writes |= 1u << (LANES + l);
  }
  w.writes = writes;
}

// At least `needed` batches in v. A batch is large (a WideFace3 holds 6.5 kB) and a heap's
// first steps need more of them step after step: v's memory is taken for twice what is
// needed, so that it is not moved (and its new pages touched again) at every step that
// needs a few more.
template <class Batch>
void fit(std::vector<Batch>& v, std::int64_t needed) {
  const auto n = static_cast<std::size_t>(needed);
  if (v.size() >= n) return;
  if (v.capacity() < n + n / 4) v.reserve(2 * n);
  v.resize(n + n / 4);
}

// 3D: v's components into lane l of x, y, z.
inline void put3(Lanes& x, Lanes& y, Lanes& z, int l, Vec3 v) {
  x[l] = v.x;
  y[l] = v.y;
  z[l] = v.z;
}

// 3D: lane l of a batch's rows and lanes (row, point fields, ids) from manifold m's row,
// or empty (m < 0: every Lanes member of the batch before `lanes` zeroed, kn 1 (no
// division by zero), body 0, never written). Returns the row (null for m < 0).
template <class Batch>
const SolverRow<3>* pack_row3(const Model<3>& model, const Contacts<3>& c, Batch& w, int l,
                              std::int32_t m) {
  WideLanes3& L = w.lanes;
  L.writes &= ~((1u << l) | (1u << (LANES + l)));
  if (m < 0) {
    for (Lanes* f = &w.nx; f < reinterpret_cast<Lanes*>(&L); ++f) (*f)[l] = 0.0;
    L.live[l] = 0;
    L.m[l] = -1;
    L.a[l] = L.b[l] = 0;
    return nullptr;
  }
  const SolverRow<3>& row = c.solver_row[m];
  const int a = c.body_a[m], b = c.body_b[m];
  put3(w.nx, w.ny, w.nz, l, row.normal);
  put3(w.t1x, w.t1y, w.t1z, l, row.t1);
  put3(w.t2x, w.t2y, w.t2z, l, row.t2);
  w.ma[l] = model.body_inv_mass[a];
  w.mb[l] = model.body_inv_mass[b];
  w.gamma[l] = row.gamma;
  w.bias_rate[l] = row.bias_rate;
  w.friction[l] = row.friction;
  w.load[l] = row.friction_load;
  w.max_push[l] = row.max_push;
  w.deep[l] = row.deep;
  w.touch[l] = row.touch;
  L.live[l] = -1;
  L.m[l] = m;
  L.a[l] = a;
  L.b[l] = b;
  if (w.ma[l] != 0.0) L.writes |= 1u << l;
  if (w.mb[l] != 0.0) L.writes |= 1u << (LANES + l);
  return &row;
}

// 3D: lane l of q from point k of row P (a point past the row's count: zeros, as there).
void pack_point3(WidePoint3& q, int l, const SolverRow<3>::Points& P, int k) {
  put3(q.rax, q.ray, q.raz, l, P.ra[k]);
  put3(q.rbx, q.rby, q.rbz, l, P.rb[k]);
  put3(q.rnax, q.rnay, q.rnaz, l, P.rna[k]);
  put3(q.rnbx, q.rnby, q.rnbz, l, P.rnb[k]);
  put3(q.rt1ax, q.rt1ay, q.rt1az, l, P.rt1a[k]);
  put3(q.rt2ax, q.rt2ay, q.rt2az, l, P.rt2a[k]);
  put3(q.rt1bx, q.rt1by, q.rt1bz, l, P.rt1b[k]);
  put3(q.rt2bx, q.rt2by, q.rt2bz, l, P.rt2b[k]);
  q.kn[l] = P.kn[k];
  q.base[l] = P.base[k];
  q.tm11[l] = P.tm11[k];
  q.tm12[l] = P.tm12[k];
  q.tm22[l] = P.tm22[k];
  q.tangent_mass[l] = P.tangent_mass[k];
}

// 3D: lane l of batch w from one-point manifold m (or empty).
void pack_lane3(const Model<3>& model, const Contacts<3>& c, WideBatch3& w, int l,
                std::int32_t m) {
  const SolverRow<3>* row = pack_row3(model, c, w, l, m);
  if (!row) {
    w.p.kn[l] = 1.0;
    return;
  }
  pack_point3(w.p, l, row->point, 0);
  put3(w.wnax, w.wnay, w.wnaz, l, row->point.wna[0]);
  put3(w.wnbx, w.wnby, w.wnbz, l, row->point.wnb[0]);
}

// 3D: lane l of face batch w from manifold m of 2 to 4 points (or empty: not ok).
void pack_face3(const Model<3>& model, const Contacts<3>& c, WideFace3& w, int l,
                std::int32_t m) {
  const SolverRow<3>* row = pack_row3(model, c, w, l, m);
  if (!row) {
    for (auto& q : w.p) q.kn[l] = 1.0;
    return;
  }
  auto put_sym = [l](Lanes* f, const Sym3& s) {  // xx yy zz xy xz yz
    f[0][l] = s.xx, f[1][l] = s.yy, f[2][l] = s.zz, f[3][l] = s.xy, f[4][l] = s.xz, f[5][l] = s.yz;
  };
  auto put_factor = [l](WideFace3::Factor& f, const BlockFactor& b) {
    for (int i = 0; i < 6; ++i) f.l[i][l] = b.l[i];
    for (int i = 0; i < 4; ++i) f.inv_d[i][l] = b.inv_d[i];
    f.ok[l] = b.ok;
  };
  put_sym(&w.iaxx, row->inv_ia);
  put_sym(&w.ibxx, row->inv_ib);
  for (int i = 0; i < 10; ++i) w.k[i][l] = row->k[i];
  put_factor(w.rigid, row->rigid);
  put_factor(w.soft, row->soft);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 4; ++j) w.coupling[i][j][l] = row->tangent_coupling[i][j];
  for (int k = 0; k < 4; ++k) pack_point3(w.p[k], l, row->point, k);
}

// The manifolds wave by wave (contacts.manifold_wave, n_waves waves) and within a wave
// by kind(m) (0 to KINDS - 1), each kind in solve order, into contacts.wave_order (a
// counting sort); each wave's first manifold into contacts.wave_start (and the end of
// the last), its first of kind `single` or later into contacts.wave_single, and, when
// idle < KINDS, its first of kind `idle` or later into contacts.wave_idle.
template <int D, int KINDS, class Kind>
void order_by_kind(Contacts<D>& c, std::int32_t n_waves, Kind kind_of, int single,
                   int idle = KINDS) {
  const std::int64_t n_man = c.count.manifolds;
  std::vector<std::int8_t> kind(static_cast<std::size_t>(n_man));
  std::vector<std::int64_t> cursor(static_cast<std::size_t>(KINDS) * n_waves, 0);
  for (std::int64_t m = 0; m < n_man; ++m) {
    kind[m] = static_cast<std::int8_t>(kind_of(m));
    ++cursor[KINDS * c.manifold_wave[m] + kind[m]];
  }
  std::int64_t at = 0;
  for (std::int32_t g = 0; g < n_waves; ++g) {
    c.wave_start[g] = at;
    for (int k = 0; k < KINDS; ++k) {
      if (k == single) c.wave_single[g] = at;
      if (k == idle) c.wave_idle[g] = at;
      const std::int64_t n = cursor[KINDS * g + k];
      cursor[KINDS * g + k] = at;
      at += n;
    }
  }
  c.wave_start[n_waves] = at;
  for (std::int64_t o = 0; o < n_man; ++o) {
    const std::int32_t m = c.solve_order[o];
    c.wave_order[cursor[KINDS * c.manifold_wave[m] + kind[m]]++] = m;
  }
}

// The units of the passes, from the waves (wave_order, by wave and kind): each unit up to
// LANES manifolds of one type (type_of(m), 0 .. TYPES - 1), sharing no dynamic body. A
// wave of a few manifolds fills its batches poorly (a pyramid's waves hold 4 or 5, and
// packed wave by wave three lanes in four were used), so a manifold is not held to its
// wave's units: it goes into the first unit of its type with room that comes after the
// last unit of every manifold before it (in solve order) that shares one of its dynamic
// bodies, and into a unit of its own where none has room. Every body's manifolds are
// still solved in solve order and a unit's manifolds share no dynamic body, so the passes
// give the solve order's result as the waves did. The manifolds are placed wave by wave,
// each wave's in order_by_kind's order, so that a unit fills before another of its type
// is begun: there are never more units of a type than packing each wave's on their own
// would make. Up to OPEN_UNITS units of each type are kept open, the oldest closed when
// another is begun. Segment by segment, each segment's units after the last's
// (segment_wave: the first unit of each; in 2D a cut's manifolds first try the spare
// lanes of a region's units: below). Each unit is then a wave of its own (finish_units).
struct Unit {
  std::int8_t type;
  std::int8_t fill;  // lanes filled
  std::int32_t m[LANES];
  std::uint8_t cut = 0;  // bit l: lane l holds a cut's manifold (2D: see below)
};
constexpr int OPEN_UNITS = 8;
template <int D, int TYPES, class Type>
std::vector<Unit> schedule_units(const Model<D>& model, Contacts<D>& c, int n_segments,
                                 Type type_of) {
  const std::int64_t n_man = c.count.manifolds;
  // (copies: the waves' lists are written over with the units')
  const std::vector<std::int32_t> order(c.wave_order.begin(), c.wave_order.begin() + n_man);
  std::vector<std::int64_t> segment_start(static_cast<std::size_t>(n_segments) + 1);
  for (int g = 0; g <= n_segments; ++g) segment_start[g] = c.wave_start[c.segment_wave[g]];
  auto& next = c.body_wave;  // each body's first unit its next manifold may go in
  std::fill(next.begin(), next.end(), 0);
  std::vector<Unit> units;
  units.reserve(static_cast<std::size_t>(n_man / 2 + 8));
  std::int32_t open[TYPES][OPEN_UNITS];  // each type's open units, oldest first
  int n_open[TYPES] = {};
  const int regions = static_cast<int>(c.region_count);
  std::vector<std::int32_t> region_units(static_cast<std::size_t>(regions) + 1, 0);
  c.cut_lanes = false;
  for (int g = 0; g < n_segments; ++g) {
    const auto first = static_cast<std::int32_t>(units.size());
    c.segment_wave[g] = first;
    if (g <= regions) region_units[g] = first;  // (the regions', and where they end)
    // 2D, a cut between regions 2k and 2k + 1 (regions.cpp): each of its manifolds goes
    // into a spare lane of region 2k + 1's units where one of its type comes after its
    // bodies' last units there (and after the cut's manifolds before it that share a
    // body), else into the cut's own units, as below. Every body's manifolds keep their
    // order (a region's before the cut's, the cut's in its order), so the passes give the
    // same result as with the cut's units after the regions; on one thread the cut's
    // manifolds then fill lanes the region leaves empty (a pyramid's cut, its centre
    // column, is a chain: one manifold a unit of its own), and on threads the region's
    // task leaves these lanes (WideBatch::cut) and the cut's pass takes them after.
    const int host = D == 2 ? cut_host(regions, g) : -1;
    const bool cut = host >= 0;
    const std::int32_t host_first = cut ? region_units[host] : 0;
    const std::int32_t host_end = cut ? region_units[host + 1] : 0;
    for (std::int64_t o = segment_start[g]; o < segment_start[g + 1]; ++o) {
      const std::int32_t m = order[o];
      const int a = c.body_a[m], b = c.body_b[m];
      const bool da = model.is_dynamic(a), db = model.is_dynamic(b);
      const int t = type_of(m);
      if (cut) {
        std::int32_t u = std::max({host_first, da ? next[a] : 0, db ? next[b] : 0});
        while (u < host_end && (units[u].type != t || units[u].fill == LANES)) ++u;
        if (u < host_end) {
          Unit& unit = units[u];
          unit.cut |= static_cast<std::uint8_t>(1u << unit.fill);
          unit.m[unit.fill++] = m;
          if (da) next[a] = u + 1;
          if (db) next[b] = u + 1;
          c.cut_lanes = true;
          continue;
        }
      }
      const std::int32_t earliest = std::max({first, da ? next[a] : 0, db ? next[b] : 0});
      std::int32_t* list = open[t];
      int i = 0;
      while (i < n_open[t] && list[i] < earliest) ++i;
      std::int32_t u;
      if (i < n_open[t]) {
        u = list[i];
        Unit& unit = units[u];
        unit.m[unit.fill++] = m;
        if (unit.fill == LANES) {  // full: no longer open
          std::copy(list + i + 1, list + n_open[t], list + i);
          --n_open[t];
        }
      } else {
        u = static_cast<std::int32_t>(units.size());
        units.push_back({static_cast<std::int8_t>(t), 1, {m, -1, -1, -1}});
        if (n_open[t] == OPEN_UNITS) {  // the oldest is closed
          std::copy(list + 1, list + n_open[t], list);
          --n_open[t];
        }
        list[n_open[t]++] = u;
      }
      if (da) next[a] = u + 1;
      if (db) next[b] = u + 1;
    }
    std::fill_n(n_open, TYPES, 0);
  }
  c.segment_wave[n_segments] = static_cast<std::int64_t>(units.size());
  return units;
}

// Each unit a wave of its own: wave_start, wave_order, manifold_wave (what the passes and
// the tests read); wave_single from where each unit's type ends its first part (`single`:
// the types before it; the unit's manifolds count as before or after it whole).
template <int D>
void finish_units(Contacts<D>& c, const std::vector<Unit>& units, int single) {
  std::int64_t at = 0;
  for (std::size_t k = 0; k < units.size(); ++k) {
    c.wave_start[k] = at;
    for (int l = 0; l < units[k].fill; ++l) {
      c.wave_order[at++] = units[k].m[l];
      c.manifold_wave[units[k].m[l]] = static_cast<std::int32_t>(k);
    }
    c.wave_single[k] = units[k].type < single ? at : c.wave_start[k];
  }
  c.wave_start[units.size()] = at;
  c.wave_count = static_cast<std::int64_t>(units.size());
  c.waves_valid = true;
}

// 3D: the units (scheduled as in 2D: schedule_units) packed for the passes, each a wave
// of its own: a unit of one-point manifolds into a batch of batches3; a unit of faces of
// two, three or four points that hold an impulse, of one count, into a batch of faces3
// (one of fewer than FACE_LANES_MIN faces by index only, for the solve of one at a time:
// WideFace3::count 0); a unit of faces that hold none, to the solve of one at a time
// (from wave_idle). The waves' order within each wave (order_by_kind): the one-point
// manifolds that hold an impulse, those that hold none, the faces that hold one by point
// count, those that hold none (any order of a wave's manifolds gives the solve order's
// result).
void pack_waves_3d(const Model<3>& model, Contacts<3>& c, std::int32_t n_waves, int n_segments) {
  // each manifold's kind: 0 one point holding an impulse, 1 one point holding none, 2 to 4
  // a face holding one, by its point count, 5 a face holding none (mostly neighbours side
  // by side, or a heap's speculative contacts: idle in most passes, and cheaper to leave
  // to the solve of one at a time, which returns at once, than to pack)
  constexpr int IDLE_FACE = 5;
  auto kind_of = [&c](std::int64_t m) {
    const int count = c.points[m];
    const bool holds = holds_any(c, m);
    return count == 1 ? (holds ? 0 : 1) : holds ? count : IDLE_FACE;
  };
  order_by_kind<3, IDLE_FACE + 1>(c, n_waves, kind_of, 2, IDLE_FACE);
  // each unit's type: 0 one point, 1 to 3 faces of 2 to 4 points that hold an impulse,
  // 4 faces that hold none
  constexpr int IDLE_UNIT = 4;
  const std::vector<Unit> units =
      schedule_units<3, IDLE_UNIT + 1>(model, c, n_segments, [&kind_of](std::int32_t m) {
        const int kind = kind_of(m);
        return kind <= 1 ? 0 : kind == IDLE_FACE ? IDLE_UNIT : kind - 1;
      });
  std::int64_t n_single = 0, n_faces = 0;
  for (const Unit& unit : units) {
    n_single += unit.type == 0;
    n_faces += unit.type != 0 && unit.type != IDLE_UNIT;
  }
  fit(c.batches3, n_single);
  fit(c.faces3, n_faces);
  const auto n = static_cast<std::int64_t>(units.size());
  std::int64_t n_batches = 0, n_face_batches = 0, at = 0;
  for (std::int64_t k = 0; k < n; ++k) {
    const Unit& unit = units[k];
    c.wave_batch[k] = n_batches;
    c.wave_single_batch[k] = n_face_batches;
    if (unit.type == 0) {
      WideBatch3& w = c.batches3[n_batches++];
      for (int l = 0; l < LANES; ++l) pack_lane3(model, c, w, l, unit.m[l]);
    } else if (unit.type != IDLE_UNIT) {
      WideFace3& w = c.faces3[n_face_batches++];
      w.count = unit.fill >= C::FACE_LANES_MIN ? unit.type + 1 : 0;
      for (int l = 0; l < LANES; ++l) {
        if (w.count != 0) pack_face3(model, c, w, l, unit.m[l]);
        else w.lanes.m[l] = unit.m[l];
      }
    }
    // (the faces that hold none: from wave_idle, the whole unit)
    at += unit.fill;
    c.wave_idle[k] = unit.type == IDLE_UNIT ? at - unit.fill : at;
  }
  c.wave_batch[n] = n_batches;
  c.wave_single_batch[n] = n_face_batches;
  finish_units(c, units, 1);
}

// 2D: the units (two-point manifolds, one-point) packed into batches, one per wave.
std::int64_t pack_batches_2d(const Model<2>& model, Contacts<2>& c, int n_segments,
                             const InParts* parts) {
  const std::vector<Unit> units = schedule_units<2, 2>(
      model, c, n_segments, [&c](std::int32_t m) { return c.points[m] == 2 ? 0 : 1; });
  const auto n = static_cast<std::int64_t>(units.size());
  // the batches' room: made here, for what this step packs (every batch holds 1 to
  // LANES manifolds, so up to M of them; most steps need about M / LANES plus a few, and
  // room for M, about 1 KB each, took seconds to make in a large pile)
  fit(c.batches, n);
  in_parts(parts, n, [&](Span part) {
    for (std::int64_t k = part.first; k < part.last; ++k) {
      const Unit& unit = units[k];
      WideBatch& w = c.batches[k];
      w.idle = true;
      w.cut = unit.cut;
      pack_batch(model, c, w, unit.m, unit.type == 0);
      for (int l = 0; l < LANES; ++l)
        if (unit.m[l] >= 0) w.idle = w.idle && !holds_any(c, unit.m[l]);
      c.wave_batch[k] = k;
      c.wave_single_batch[k] = unit.type == 0 ? k + 1 : k;
    }
  });
  c.wave_batch[n] = c.wave_single_batch[n] = n;
  finish_units(c, units, 1);
  return n;
}

// Lane l of batch w takes manifold m's impulses from the store, or gives them back
// (the approach speeds are written to the store where a point engages, and stay there).
inline void take_lane(WideBatch& w, int l, const Contacts<2>& c, std::int32_t m) {
  w.n0[l] = c.normal_impulse[m][0];
  w.t0[l] = c.tangent_impulse[m][0];
  w.x0[l] = c.max_normal_impulse[m][0];
  w.ap0[l] = c.approach_velocity[m][0];
  if (w.two[l] == 0.0) return;
  w.n1[l] = c.normal_impulse[m][1];
  w.t1[l] = c.tangent_impulse[m][1];
  w.x1[l] = c.max_normal_impulse[m][1];
  w.ap1[l] = c.approach_velocity[m][1];
}
inline void give_lane(const WideBatch& w, int l, Contacts<2>& c, std::int32_t m) {
  c.normal_impulse[m][0] = w.n0[l];
  c.tangent_impulse[m][0] = w.t0[l];
  c.max_normal_impulse[m][0] = w.x0[l];
  if (w.two[l] == 0.0) return;
  c.normal_impulse[m][1] = w.n1[l];
  c.tangent_impulse[m][1] = w.t1[l];
  c.max_normal_impulse[m][1] = w.x1[l];
}

// Where manifold m is among the batches (2D): its batch (each unit is a batch of its own:
// finish_units) and lane.
inline std::pair<WideBatch*, int> lane_of(Contacts<2>& c, std::int32_t m) {
  WideBatch& w = c.batches[c.manifold_wave[m]];
  int l = 0;
  while (l < LANES - 1 && w.m[l] != m) ++l;
  return {&w, l};
}

}  // namespace

template <int D>
void take_impulses(Contacts<D>& c) {
  if constexpr (D == 2) {
    if (c.impulses_in_lanes) return;
    const std::int64_t n = c.wave_count > 0 ? c.wave_batch[c.wave_count] : 0;
    const Lanes zero = splat(0.0);
    for (std::int64_t i = 0; i < n; ++i) {
      WideBatch& w = c.batches[i];
      w.n0 = w.n1 = w.t0 = w.t1 = w.x0 = w.x1 = w.ap0 = w.ap1 = zero;
      for (int l = 0; l < LANES; ++l)
        if (w.m[l] >= 0) take_lane(w, l, c, w.m[l]);
    }
    c.impulses_in_lanes = true;
  }
}

template <int D>
void give_impulses(Contacts<D>& c) {
  if constexpr (D == 2) {
    if (!c.impulses_in_lanes) return;
    const std::int64_t n = c.wave_count > 0 ? c.wave_batch[c.wave_count] : 0;
    for (std::int64_t i = 0; i < n; ++i) {
      const WideBatch& w = c.batches[i];
      for (int l = 0; l < LANES; ++l)
        if (w.m[l] >= 0) give_lane(w, l, c, w.m[l]);
    }
    c.impulses_in_lanes = false;
  }
}

template <int D>
void take_impulses(Contacts<D>& c, const std::int32_t* list, std::int64_t n) {
  if constexpr (D == 2) {
    if (!c.impulses_in_lanes) return;  // (taken in full by the next pass)
    for (std::int64_t i = 0; i < n; ++i) {
      const auto [w, l] = lane_of(c, list[i]);
      take_lane(*w, l, c, list[i]);
    }
  }
}

template <int D>
void give_impulses(Contacts<D>& c, const std::int32_t* list, std::int64_t n) {
  if constexpr (D == 2) {
    if (!c.impulses_in_lanes) return;
    if (n * C::HANDOVER_WHOLE > c.count.manifolds) {  // (then taken in full by the next pass)
      give_impulses(c);
      return;
    }
    for (std::int64_t i = 0; i < n; ++i) {
      const auto [w, l] = lane_of(c, list[i]);
      give_lane(*w, l, c, list[i]);
    }
  }
}

template void take_impulses(Contacts<2>&);
template void take_impulses(Contacts<3>&);
template void give_impulses(Contacts<2>&);
template void give_impulses(Contacts<3>&);
template void take_impulses(Contacts<2>&, const std::int32_t*, std::int64_t);
template void take_impulses(Contacts<3>&, const std::int32_t*, std::int64_t);
template void give_impulses(Contacts<2>&, const std::int32_t*, std::int64_t);
template void give_impulses(Contacts<3>&, const std::int32_t*, std::int64_t);

void repack_turned_rows(const Model<3>& model, Contacts<3>& c) {
  const std::int64_t n_batches = c.wave_count > 0 ? c.wave_batch[c.wave_count] : 0;
  const std::int64_t n_faces = c.wave_count > 0 ? c.wave_single_batch[c.wave_count] : 0;
  auto remade = [&c](std::int32_t m) {
    return m >= 0 && (c.body_row_remade[c.body_a[m]] || c.body_row_remade[c.body_b[m]]);
  };
  for (std::int64_t i = 0; i < n_batches; ++i) {
    WideBatch3& w = c.batches3[i];
    for (int l = 0; l < LANES; ++l)
      if (remade(w.lanes.m[l])) pack_lane3(model, c, w, l, w.lanes.m[l]);
  }
  for (std::int64_t i = 0; i < n_faces; ++i) {
    WideFace3& w = c.faces3[i];
    if (w.count == 0) continue;  // (solved one at a time, from the rows)
    for (int l = 0; l < LANES; ++l)
      if (remade(w.lanes.m[l])) pack_face3(model, c, w, l, w.lanes.m[l]);
  }
}

template <int D>
std::int64_t find_waves(const Model<D>& model, Contacts<D>& c, const InParts* parts) {
  give_impulses(c);  // (the batches are packed again: the store holds the impulses)
  const std::int64_t n_man = c.count.manifolds;
  if (D == 2 && c.count.graph_unchanged == 1 && c.waves_valid) {
    // last step's manifolds in the same slots and the same solve order (support_order
    // keeps it): the waves hold, and only the batches holding a row that prepare wrote
    // again are packed again (a batch of carried manifolds takes their base separations
    // and friction loads, all a carried row changes in), unless a manifold's point count
    // changed (it belongs in a batch of the other kind) or more than one in IDLE_SPOILED
    // of the batches packed idle hold an impulse now (a new pile's first steps; in a
    // settled pyramid a few contacts a step start or stop holding one, and packing again
    // every step would cost more than it saves)
    bool same_kinds = true;
    std::int64_t idle = 0, spoiled = 0;  // batches
    for (std::int64_t i = 0; same_kinds && i < c.wave_batch[c.wave_count]; ++i) {
      WideBatch& w = c.batches[i];
      bool holds = false, carried = true, two = false;
      for (int l = 0; l < LANES; ++l) {
        const std::int32_t m = w.m[l];
        if (m < 0) continue;
        holds = holds || (w.idle && holds_any(c, m));
        carried = carried && c.carried[m];
        two = two || w.two[l] != 0.0;
        same_kinds = same_kinds && (c.points[m] == 2) == (w.two[l] != 0.0);
      }
      if (!same_kinds) break;
      if (carried) {
        for (int l = 0; l < LANES; ++l) {
          const std::int32_t m = w.m[l];
          if (m < 0) continue;
          w.p0.base[l] = c.solver_row[m].point[0].base;
          if (w.two[l] != 0.0) w.p1.base[l] = c.solver_row[m].point[1].base;
          w.load[l] = c.solver_row[m].friction_load;  // (friction_loads: written every step)
        }
      } else if constexpr (D == 2) {
        std::int32_t ms[LANES];  // (pack_batch writes w.m)
        std::copy(std::begin(w.m), std::end(w.m), ms);
        pack_batch(model, c, w, ms, two);
      }
      idle += w.idle;
      spoiled += holds;
    }
    if (same_kinds && spoiled * C::IDLE_SPOILED <= idle) return c.wave_count;
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
  if constexpr (D == 3) {
    pack_waves_3d(model, c, n_waves, n_segments);
    return c.wave_count;
  } else {
  // within a wave the two-point manifolds first, then the one-point ones (circles,
  // capsule ends), each in solve order, into batches of their own (a one-point batch
  // skips the second point's work); of each, those that hold an impulse before those
  // that hold none (mostly speculative contacts, idle in most passes: placed last, they
  // fill batches of their own where they can, which are left at once: solve_batch,
  // warm_start_batch). Each manifold's kind: 0 two points holding, 1 two points holding
  // none, 2 and 3 one point alike
  order_by_kind<2, 4>(c, n_waves, [&c](std::int64_t m) {
    return (c.points[m] == 2 ? 0 : 2) + (holds_any(c, m) ? 0 : 1);
  }, 2);
  return pack_batches_2d(model, c, n_segments, parts);
  }
}

template std::int64_t find_waves(const Model<2>&, Contacts<2>&, const InParts*);
template std::int64_t find_waves(const Model<3>&, Contacts<3>&, const InParts*);

}  // namespace rbsim
