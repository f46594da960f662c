// Broadphase: candidate shape pairs whose bounding boxes overlap, in O(N).
//
// Every shape has a tight box (its geometry, radius and speculative reach) and a fat box
// that contains it with AABB_MARGIN to spare. Pairs are found between fat boxes and kept
// from step to step; only a shape whose tight box has left its fat box ("moved") is
// queried again. A resting stack therefore costs one containment test per shape.
//
// Queries use a loose uniform grid: each shape is entered once, in the cell that holds
// its fat box's min corner, and a query looks at every cell where the min corner of an
// overlapping box can lie, which the widest and tallest box in the grid bound. One entry
// per shape keeps the fill cheap and finds each pair once per query. When the occupied
// cells fit in a rectangle of at most as many cells as the table has buckets, each cell
// is its own bucket, numbered row by row, so a query reads one run of entries per row
// and needs no check that an entry is in the cell it looks at; otherwise (shapes far
// apart) cells are hashed into the table. Shapes wider or taller than a cell (a long
// ground, a very fast body) are "big": they are tested against every other shape
// directly, cheap while they are few. When more than BIG_MAX shapes are that wide (a
// fast gas), the cut is raised to 2, 4, ... cells until few are left above it.
//
// Pairs are kept sorted by (shape a, shape b) with a < b, so the order is deterministic
// and the contact stage matches them against the previous step in one merge pass.
// Pairs within one body, and pairs where neither body is dynamic, are skipped.
//
// Boxes, the fill and the sort are written for any D; the query's walk over the cells
// is written per dimension (rows of cells in the plane; rows within layers in space, x
// fastest in both). In 3D a plane (a half-space) is big: its box is unbounded but along
// an axis its normal lies on, so it is tested against every other shape.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <utility>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// Component-wise helpers over the vector types (the boxes' arithmetic). min and max keep
// the first argument on a tie, as the numba kernel's min/max do.
inline Vec2 vmin(Vec2 a, Vec2 b) { return {std::min(a.x, b.x), std::min(a.y, b.y)}; }
inline Vec2 vmax(Vec2 a, Vec2 b) { return {std::max(a.x, b.x), std::max(a.y, b.y)}; }
inline Vec3 vmin(Vec3 a, Vec3 b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 vmax(Vec3 a, Vec3 b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
// Whether some component of a is below b's.
inline bool any_less(Vec2 a, Vec2 b) { return a.x < b.x || a.y < b.y; }
inline bool any_less(Vec3 a, Vec3 b) { return a.x < b.x || a.y < b.y || a.z < b.z; }
inline Vec2 splat(Vec2, double r) { return {r, r}; }
inline Vec3 splat(Vec3, double r) { return {r, r, r}; }

// floor(x) as an integer, for |x| < 2^63: truncate, then step down below a negative
// non-integer. The same value as the library's floor, without its call (the build
// targets baseline x86-64, which has no rounding instruction).
inline std::int64_t floor_int(double x) {
  const std::int64_t t = static_cast<std::int64_t>(x);
  return t - (x < static_cast<double>(t));
}

// The cell that holds point p: floor(p / cell) per axis.
inline Cell<2> cell_of(Vec2 p, double inv) { return {floor_int(p.x * inv), floor_int(p.y * inv)}; }
inline Cell<3> cell_of(Vec3 p, double inv) {
  return {floor_int(p.x * inv), floor_int(p.y * inv), floor_int(p.z * inv)};
}

// The hashed table's bucket of a cell: (ix·73856093 ^ iy·19349663 [^ iz·83492791]) & mask,
// the products wrapping as the numba kernel's int64 ones do (unsigned: no overflow UB).
template <int D>
inline std::int64_t hash_bucket(const Cell<D>& c, std::int64_t mask) {
  constexpr std::uint64_t prime[3] = {73856093u, 19349663u, 83492791u};
  std::uint64_t h = 0;
  for (int d = 0; d < D; ++d) h ^= static_cast<std::uint64_t>(c[d]) * prime[d];
  return static_cast<std::int64_t>(h & static_cast<std::uint64_t>(mask));
}

// How far from the origin a shape's box may reach to be entered in the grid's cells, m:
// twice the position limit of the bodies (world.hpp, POSITION_LIMIT = 1e9 m), beyond which
// the cell indices could overflow. A box beyond it, or not finite (a state made bad and
// passed to a stage directly), is kept among the big shapes, whose cells are never taken.
inline constexpr double CELL_REACH = 2.0e9;

// Whether box fits the grid: every side at most `width` (m) and its min corner within
// CELL_REACH (false for a NaN anywhere in it).
template <int D>
inline bool fits_cells(const Aabb<D>& box, double width) {
  const double* lo = reinterpret_cast<const double*>(&box.lo);
  const double* hi = reinterpret_cast<const double*>(&box.hi);
  bool fits = true;
  for (int d = 0; d < D; ++d)
    fits = fits && hi[d] - lo[d] <= width && std::abs(lo[d]) <= CELL_REACH;
  return fits;
}

// The pair key a·S + b of shapes a, b in either order.
inline std::int64_t pair_key(std::int32_t a, std::int32_t b, std::int64_t n) {
  return static_cast<std::int64_t>(std::min(a, b)) * n + std::max(a, b);
}

// The box of a plane's solid n·x <= n·p from the box [lo, hi] around its point p (m):
// unbounded on every side but the one an axis-aligned normal faces (a ground y <= 0 is
// bounded above by its point's box), infinite along an oblique normal.
inline void plane_box(Vec3 n, Vec3& lo, Vec3& hi) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const double nn[3] = {n.x, n.y, n.z};
  double* l = &lo.x;
  double* h = &hi.x;
  bool aligned = false;
  for (int d = 0; d < 3; ++d) aligned = aligned || std::fabs(nn[d]) == 1.0;
  for (int d = 0; d < 3; ++d) {
    const bool faces = aligned && std::fabs(nn[d]) == 1.0;
    if (!(faces && nn[d] > 0.0)) h[d] = inf;   // the solid reaches up along d
    if (!(faces && nn[d] < 0.0)) l[d] = -inf;  // ... and down
  }
}

// Tight boxes from world vertices, radius and speculative reach (m); fat boxes for the
// shapes whose tight box left theirs. Returns how many shapes moved.
template <int D>
std::int64_t update_aabbs(const Model<D>& model, Grid<D>& grid, const Contacts<D>& contacts,
                          Span shapes) {
  using Vec = typename Dim<D>::Vec;
  const Vec* vw = contacts.vert_world.data();
  // half a pair's speculative distance on each side, at each shape's own scale (a pair
  // takes the smaller of its two: the boxes reach at least that far)
  const double reach = 0.5 * C::SPECULATIVE_DISTANCE;
  const bool fresh = grid.meta.pairs_valid == 0;
  const Vec shift = grid.frame_offset;  // m
  Aabb<D>* box = grid.shape_aabb.data();
  Aabb<D>* fat = grid.shape_fat.data();
  std::int64_t moved = 0;
  for (int s = static_cast<int>(shapes.first); s < static_cast<int>(shapes.last); ++s) {
    const int start = model.shape_vstart[s], end = start + model.shape_vcount[s];
    Vec lo = vw[start], hi = lo;
    for (int k = start + 1; k < end; ++k) {
      lo = vmin(lo, vw[k]);
      hi = vmax(hi, vw[k]);
    }
    const double scale = contacts.unit_scale ? 1.0 : contacts.shape_scale[s];
    const Vec r = splat(lo, model.shape_radius[s] + contacts.shape_margin[s] + scale * reach);
    lo = lo - r;
    hi = hi + r;
    if constexpr (D == 3) {
      if (model.shape_kind[s] == ShapeKind::Plane) plane_box(contacts.norm_world[start], lo, hi);
    }
    lo = lo - shift;  // into the moving frame (an unbounded side stays so)
    hi = hi - shift;
    const Aabb<D> last = box[s];  // last step's tight box
    box[s] = {lo, hi};
    const double margin = scale * C::AABB_MARGIN;  // m
    // the shape's displacement since last step (m) and the room its fat box leaves
    // around it beyond the margins (m, summed over both sides of every axis)
    const double* now_lo = &lo.x;
    const double* now_hi = &hi.x;
    const double* was_lo = &last.lo.x;
    const double* was_hi = &last.hi.x;
    const double* fat_lo = &fat[s].lo.x;
    const double* fat_hi = &fat[s].hi.x;
    double step[D], slack = 0.0;
    bool slow = true;
    for (int d = 0; d < D; ++d) {
      // (a plane's box is unbounded on one side: its other side moves; on both: none)
      step[d] = std::isfinite(now_lo[d])   ? now_lo[d] - was_lo[d]
                : std::isfinite(now_hi[d]) ? now_hi[d] - was_hi[d]
                                           : 0.0;
      slow = slow && std::fabs(step[d]) < C::FAT_REST * margin;
      slack += (fat_hi[d] - now_hi[d]) + (now_lo[d] - fat_lo[d]) - 2.0 * margin;
    }
    bool out = fresh || any_less(lo, fat[s].lo) || any_less(fat[s].hi, hi);
    // a shape that has come to rest in a fat box stretched ahead of it is queried again
    // with a plain one, so that a settled pile does not keep its fall's extra pairs
    out = out || (slow && slack > margin);
    grid.shape_moved[s] = out;
    if (out) {
      const Vec m = splat(lo, margin);
      Vec ahead_lo = lo - m, ahead_hi = hi + m;
      if (!fresh && !slow) {
        // a shape on the move keeps moving: the fat box reaches FAT_AHEAD_STEPS of its
        // last step's displacement ahead along each axis (at most FAT_AHEAD_SIZE of its
        // width there), so that a falling or flying shape is queried again every few
        // steps instead of every step
        double* ahead_l = &ahead_lo.x;
        double* ahead_h = &ahead_hi.x;
        for (int d = 0; d < D; ++d) {
          const double cap = C::FAT_AHEAD_SIZE * (now_hi[d] - now_lo[d]);
          const double ahead = std::min(C::FAT_AHEAD_STEPS * std::fabs(step[d]), cap);
          if (step[d] > 0.0) ahead_h[d] += ahead;
          if (step[d] < 0.0) ahead_l[d] -= ahead;
        }
      }
      fat[s] = {ahead_lo, ahead_hi};
      ++moved;
    }
  }
  return moved;
}

// Enter every small shape in the cell of its fat box's min corner (counting sort by
// bucket), with a copy of the shape data the pair tests read.
template <int D>
void fill_grid(const Model<D>& model, Grid<D>& grid) {
  using Vec = typename Dim<D>::Vec;
  const Aabb<D>* fat = grid.shape_fat.data();
  std::uint8_t* big = grid.shape_big.data();
  Cell<D>* shape_cell = grid.shape_cell.data();
  std::int64_t* shape_bucket = grid.shape_bucket.data();
  std::int64_t* starts = grid.bucket_start.data();
  const int n = static_cast<int>(grid.shape_fat.size());
  const std::int64_t table = static_cast<std::int64_t>(grid.bucket_start.size()) - 1;  // 2^k
  const double inv = grid.inv_cell;
  const double cell = 1.0 / inv;  // m
  // the width (in cells) above which a shape is big: the smallest of 1, 2, 4, ...,
  // BIG_CELLS_MAX that leaves at most BIG_MAX shapes big. A few long walls or fast
  // bodies are cheaper tested against every shape; many wide ones (a fast gas whose
  // speculative reach spans more than a cell) are cheaper kept in the grid, where
  // they widen every query a little, than tested against every shape each
  double cut = 1.0;
  while (cut < C::BIG_CELLS_MAX) {
    int over = 0;
    for (int s = 0; s < n; ++s) over += !fits_cells(fat[s], cut * cell);
    if (over <= C::BIG_MAX) break;
    cut *= 2.0;
  }
  std::int64_t nbig = 0;
  Vec span{};  // m: the widest and tallest small fat box
  Cell<D> g0{}, g1{};  // the occupied rectangle's first and last cells; empty: g1 < g0
  g1.fill(-1);
  for (int s = 0; s < n; ++s) {
    const Vec w = fat[s].hi - fat[s].lo;
    const bool is_big = !fits_cells(fat[s], cut * cell);
    big[s] = is_big;
    if (is_big) {
      grid.big_list[nbig++] = s;
      continue;
    }
    span = vmax(span, w);
    const Cell<D> c = cell_of(fat[s].lo, inv);
    shape_cell[s] = c;
    if (g1[0] < g0[0]) g0 = g1 = c;
    for (int d = 0; d < D; ++d) {
      g0[d] = std::min(g0[d], c[d]);
      g1[d] = std::max(g1[d], c[d]);
    }
  }
  grid.meta.big_count = nbig;
  grid.span = span * (1.0 + 1e-12);  // padded up so that rounding cannot hide a pair
  // direct buckets when the rectangle has no more cells than the table has buckets
  // (each extent is checked first, so that the product cannot overflow)
  Cell<D> extent{}, stride{};
  bool dense = true;
  std::int64_t used = 1;
  for (int d = 0; d < D; ++d) {
    extent[d] = g1[d] - g0[d] + 1;
    stride[d] = used;
    if (dense && extent[d] <= table && used * extent[d] <= table) {
      used *= extent[d];
    } else {
      dense = false;
    }
  }
  grid.meta.direct_buckets = dense;
  grid.meta.first_cell = g0;
  grid.meta.extent = extent;
  if (!dense) used = table;
  const std::int64_t mask = table - 1;
  for (std::int64_t b = 0; b <= used; ++b) starts[b] = 0;
  for (int s = 0; s < n; ++s) {
    if (big[s]) continue;
    const Cell<D>& c = shape_cell[s];
    std::int64_t b = 0;
    if (dense) {  // row by row: x fastest
      for (int d = 0; d < D; ++d) b += (c[d] - g0[d]) * stride[d];
    } else {
      b = hash_bucket<D>(c, mask);
    }
    shape_bucket[s] = b;
    ++starts[b];
  }
  // starts[b] becomes the end of bucket b; placing the shapes from the last one back
  // moves it down to the bucket's beginning, so no pass is needed to restore it
  for (std::int64_t b = 0; b + 1 < used; ++b) starts[b + 1] += starts[b];
  starts[used] = n - nbig;
  for (int s = n - 1; s >= 0; --s) {
    if (big[s]) continue;
    const std::int64_t k = --starts[shape_bucket[s]];
    const int body = model.shape_body[s];
    grid.entry_shape[k] = s;
    if (!dense) grid.entry_cell[k] = shape_cell[s];
    grid.entry_fat[k] = fat[s];
    grid.entry_tag[k] = model.is_dynamic(body) ? body : -1 - body;
  }
}

// The pairs of moved shape a with the big shapes (with every shape when a is big itself),
// each emitted (emit(key)) as query_moved records them.
template <int D, class Emit>
inline void pair_with_big(const Model<D>& model, const Grid<D>& grid, std::int32_t a, Emit& emit) {
  const std::int32_t n = static_cast<std::int32_t>(grid.shape_fat.size());
  const std::uint8_t* moved = grid.shape_moved.data();
  const bool a_big = grid.shape_big[a] != 0;
  const std::int64_t n_cand = a_big ? n : grid.meta.big_count;
  const std::int32_t body_a = model.shape_body[a];
  const bool dyn_a = model.body_type[body_a] == BodyType::Dynamic;
  const Aabb<D>& box = grid.shape_fat[a];
  for (std::int64_t g = 0; g < n_cand; ++g) {
    const std::int32_t b = a_big ? static_cast<std::int32_t>(g) : grid.big_list[g];
    if (b == a || (moved[b] && b < a)) continue;
    if (disjoint<D>(box, grid.shape_fat[b])) continue;
    const std::int32_t body_b = model.shape_body[b];
    if (body_b == body_a || !(dyn_a || model.body_type[body_b] == BodyType::Dynamic)) continue;
    emit(pair_key(a, b, n));
  }
}

// emit(key) for the keys a·S + b of the pairs that involve a moved shape a of `shapes`,
// in no particular order.
//
// A pair is recorded by a's query, except when b moved too and comes first (then b's
// query records it). The tests are written out in the loops: this is the hottest loop
// of a falling pile. 2D-specific: the walk over the cells is by rows iy of cells ix.
constexpr int FOUND_BUFFER = 32;
template <int D, class Emit>
void query_moved(const Model<D>& model, const Grid<D>& grid, Span shapes, Emit& emit) {
  static_assert(D == 2, "query_moved: the walk over the cells is written for the plane");
  static_assert(sizeof(Aabb<D>) == 4 * sizeof(double), "lo.x, lo.y, hi.x, hi.y");
  const Lanes sign = {1.0, 1.0, -1.0, -1.0};
  const std::int32_t* shape_body = model.shape_body.data();
  const BodyType* body_type = model.body_type.data();
  const std::int64_t* bucket_start = grid.bucket_start.data();
  const std::int32_t* entry_shape = grid.entry_shape.data();
  const Cell<D>* entry_cell = grid.entry_cell.data();
  const Aabb<D>* entry_fat = grid.entry_fat.data();
  const std::int32_t* entry_tag = grid.entry_tag.data();
  const Aabb<D>* fat = grid.shape_fat.data();
  const std::uint8_t* moved = grid.shape_moved.data();
  const std::uint8_t* big = grid.shape_big.data();
  const double wide = grid.span.x, tall = grid.span.y;  // m
  const bool dense = grid.meta.direct_buckets != 0;
  const std::int64_t gx0 = grid.meta.first_cell[0], gy0 = grid.meta.first_cell[1];
  const std::int64_t nx = grid.meta.extent[0], ny = grid.meta.extent[1];
  const std::int32_t n = static_cast<std::int32_t>(grid.shape_fat.size());
  const std::int64_t mask = static_cast<std::int64_t>(grid.bucket_start.size()) - 2;
  const double inv = grid.inv_cell;
  for (auto a = static_cast<std::int32_t>(shapes.first); a < static_cast<std::int32_t>(shapes.last);
       ++a) {
    if (!moved[a]) continue;
    const std::int32_t body_a = shape_body[a];
    const bool dyn_a = body_type[body_a] == BodyType::Dynamic;
    const std::int32_t tag_a = dyn_a ? body_a : -1 - body_a;
    const Aabb<D> box = fat[a];
    const double ax0 = box.lo.x, ay0 = box.lo.y, ax1 = box.hi.x, ay1 = box.hi.y;
    // a box (lo.x, lo.y, hi.x, hi.y) times sign is at most this where it overlaps a's
    const Lanes reach = {ax1, ay1, -ax0, -ay0};
    std::int64_t found[FOUND_BUFFER];  // keys found, not yet emitted
    int count = 0;
    // candidates: every shape for a big shape; else the grid cells, then big shapes
    std::int64_t ix0 = 0, ix1 = -1, iy0 = 0, iy1 = -1;
    if (!big[a]) {
      // a box overlapping a's has its min corner in [a's min - span, a's max]
      ix0 = floor_int((ax0 - wide) * inv);
      ix1 = floor_int(ax1 * inv);
      iy0 = floor_int((ay0 - tall) * inv);
      iy1 = floor_int(ay1 * inv);
      if (dense) {  // clip to the occupied rectangle; one run of entries per row
        ix0 = std::max(ix0, gx0);
        ix1 = std::min(ix1, gx0 + nx - 1);
        iy0 = std::max(iy0, gy0);
        iy1 = std::min(iy1, gy0 + ny - 1);
      }
    }
    for (std::int64_t iy = iy0; iy <= iy1; ++iy) {
      // hashed: one bucket per cell; dense: a single pass reads the row's whole run
      const std::int64_t ix_end = dense ? std::min(ix0, ix1) : ix1;
      for (std::int64_t ix = ix0; ix <= ix_end; ++ix) {
        std::int64_t k0, k1;
        if (dense) {
          const std::int64_t row = (iy - gy0) * nx - gx0;
          k0 = bucket_start[row + ix0];
          k1 = bucket_start[row + ix1 + 1];
        } else {
          const std::int64_t bk = hash_bucket<D>(Cell<D>{ix, iy}, mask);
          k0 = bucket_start[bk];
          k1 = bucket_start[bk + 1];
        }
        for (std::int64_t k = k0; k < k1; ++k) {
          // every test made and the key written, the count advanced only for a pair (the
          // tests' outcomes follow no pattern: as branches, many were mispredicted). A hashed
          // bucket also holds other cells' entries
          const bool here = dense || (entry_cell[k][0] == ix && entry_cell[k][1] == iy);
          // the boxes overlap: lo <= a's hi and hi >= a's lo, both as <= (sign)
          const bool near = all(load_lanes(&entry_fat[k].lo.x) * sign <= reach);
          // not the same body, and one of the two dynamic (not both tags below zero)
          const std::int32_t tag = entry_tag[k], b = entry_shape[k];
          const bool other = (tag != tag_a) & ((tag_a & tag) >= 0);
          // (a pair of two moved shapes is the lower one's)
          const bool own = (b != a) & !(moved[b] & (b < a));
          found[count] = pair_key(a, b, n);
          count += here & near & other & own;
          if (count == FOUND_BUFFER) {
            for (int f = 0; f < count; ++f) emit(found[f]);
            count = 0;
          }
        }
      }
    }
    for (int f = 0; f < count; ++f) emit(found[f]);
    pair_with_big(model, grid, a, emit);
  }
}

// query_moved for shapes in space: the walk over the cells is by layers iz of rows iy of
// cells ix (in the direct buckets x is fastest, so a row's cells are one run of entries).
template <class Emit>
void query_moved(const Model<3>& model, const Grid<3>& grid, Span shapes, Emit& emit) {
  constexpr int D = 3;
  const std::int32_t* shape_body = model.shape_body.data();
  const BodyType* body_type = model.body_type.data();
  const std::int64_t* bucket_start = grid.bucket_start.data();
  const std::int32_t* entry_shape = grid.entry_shape.data();
  const Cell<D>* entry_cell = grid.entry_cell.data();
  const Aabb<D>* entry_fat = grid.entry_fat.data();
  const std::int32_t* entry_tag = grid.entry_tag.data();
  const Aabb<D>* fat = grid.shape_fat.data();
  const std::uint8_t* moved = grid.shape_moved.data();
  const std::uint8_t* big = grid.shape_big.data();
  const Vec3 span = grid.span;  // m
  const bool dense = grid.meta.direct_buckets != 0;
  const Cell<D> g0 = grid.meta.first_cell, ext = grid.meta.extent;
  const std::int32_t n = static_cast<std::int32_t>(grid.shape_fat.size());
  const std::int64_t mask = static_cast<std::int64_t>(grid.bucket_start.size()) - 2;
  const double inv = grid.inv_cell;
  for (auto a = static_cast<std::int32_t>(shapes.first); a < static_cast<std::int32_t>(shapes.last);
       ++a) {
    if (!moved[a]) continue;
    const std::int32_t body_a = shape_body[a];
    const bool dyn_a = body_type[body_a] == BodyType::Dynamic;
    const std::int32_t tag_a = dyn_a ? body_a : -1 - body_a;
    const Aabb<D> box = fat[a];
    // candidates: every shape for a big shape; else the grid cells, then big shapes
    Cell<D> i0{}, i1{};
    i1.fill(-1);
    if (!big[a]) {
      // a box overlapping a's has its min corner in [a's min - span, a's max]
      i0 = cell_of(box.lo - span, inv);
      i1 = cell_of(box.hi, inv);
      if (dense) {  // clip to the occupied block
        for (int d = 0; d < D; ++d) {
          i0[d] = std::max(i0[d], g0[d]);
          i1[d] = std::min(i1[d], g0[d] + ext[d] - 1);
        }
      }
    }
    for (std::int64_t iz = i0[2]; iz <= i1[2]; ++iz) {
      for (std::int64_t iy = i0[1]; iy <= i1[1]; ++iy) {
        // hashed: one bucket per cell; dense: a single pass reads the row's whole run
        const std::int64_t ix_end = dense ? std::min(i0[0], i1[0]) : i1[0];
        for (std::int64_t ix = i0[0]; ix <= ix_end; ++ix) {
          std::int64_t k0, k1;
          if (dense) {
            const std::int64_t row = ((iz - g0[2]) * ext[1] + (iy - g0[1])) * ext[0] - g0[0];
            k0 = bucket_start[row + i0[0]];
            k1 = bucket_start[row + i1[0] + 1];
          } else {
            const std::int64_t bk = hash_bucket<D>(Cell<D>{ix, iy, iz}, mask);
            k0 = bucket_start[bk];
            k1 = bucket_start[bk + 1];
          }
          for (std::int64_t k = k0; k < k1; ++k) {
            // a hashed bucket also holds other cells' entries
            if (!dense && (entry_cell[k][0] != ix || entry_cell[k][1] != iy ||
                           entry_cell[k][2] != iz))
              continue;
            if (disjoint<D>(box, entry_fat[k])) continue;
            // the same body, or neither body dynamic (both tags below zero)
            if (entry_tag[k] == tag_a || (tag_a & entry_tag[k]) < 0) continue;
            const std::int32_t b = entry_shape[k];
            if (b == a || (moved[b] && b < a)) continue;
            emit(pair_key(a, b, n));
          }
        }
      }
    }
    pair_with_big(model, grid, a, emit);
  }
}

// Sort the non-negative keys[0..n) in place: a few keys by insertion; more by a
// least-significant-digit radix sort, RADIX_BITS per pass, through scratch (at least n
// long) and count (2^RADIX_BITS + 1).
void sort_prefix(std::int64_t* keys, std::int64_t n, std::int64_t* scratch,
                 std::int64_t* count) {
  if (n <= C::INSERTION_SORT_MAX) {
    for (std::int64_t i = 1; i < n; ++i) {
      const std::int64_t key = keys[i];
      std::int64_t j = i - 1;
      while (j >= 0 && keys[j] > key) {
        keys[j + 1] = keys[j];
        --j;
      }
      keys[j + 1] = key;
    }
    return;
  }
  std::int64_t top = keys[0];
  for (std::int64_t i = 1; i < n; ++i) top = std::max(top, keys[i]);
  constexpr std::int64_t mask = (std::int64_t{1} << C::RADIX_BITS) - 1;
  std::int64_t* src = keys;
  std::int64_t* dst = scratch;
  bool in_scratch = false;
  int shift = 0;
  while ((top >> shift) > 0) {
    for (std::int64_t d = 0; d < mask + 2; ++d) count[d] = 0;
    for (std::int64_t i = 0; i < n; ++i) ++count[((src[i] >> shift) & mask) + 1];
    for (std::int64_t d = 0; d < mask + 1; ++d) count[d + 1] += count[d];
    for (std::int64_t i = 0; i < n; ++i) {  // stable: keeps the order of the lower digits
      const std::int64_t d = (src[i] >> shift) & mask;
      dst[count[d]++] = src[i];
    }
    std::swap(src, dst);
    in_scratch = !in_scratch;
    shift += C::RADIX_BITS;
  }
  if (in_scratch) std::copy(scratch, scratch + n, keys);
}

}  // namespace

// Update the sorted pair list contacts.pairs, which holds contacts.count.pairs pairs;
// returns the new count. When more pairs exist than the list holds, the count returned
// is the number needed and the list is invalid: the caller grows the storage and calls
// again.
template <int D>
std::int64_t find_pairs(const Model<D>& model, Grid<D>& grid, Contacts<D>& contacts,
                        const InParts* parts) {
  const std::int64_t n_pairs = contacts.count.pairs;
  const std::int64_t n = static_cast<std::int64_t>(grid.shape_fat.size());  // shapes
  std::atomic<std::int64_t> moved_shapes{0};  // (an integer sum: the same in any order)
  in_parts(parts, n, [&](Span part) {
    moved_shapes += update_aabbs(model, grid, contacts, part);
  });
  if (moved_shapes == 0) return n_pairs;
  const bool fresh = grid.meta.pairs_valid == 0;
  grid.meta.pairs_valid = 0;  // invalid until this update completes
  fill_grid(model, grid);
  auto* pairs = contacts.pairs.data();
  auto* kept_list = grid.kept.data();
  const std::uint8_t* moved = grid.shape_moved.data();
  const std::int64_t capacity = static_cast<std::int64_t>(contacts.pairs.size());
  // keep the old pairs between shapes that did not move (already sorted)
  std::int64_t kept = 0;
  if (!fresh) {
    for (std::int64_t p = 0; p < n_pairs; ++p) {  // (written, then counted if kept: no branch)
      const auto ab = pairs[p];
      kept_list[kept] = ab;
      kept += (moved[ab[0]] | moved[ab[1]]) == 0;
    }
  }
  // the moved shapes' pairs, unsorted, into new_keys (counted past its room, which the
  // caller then grows); in parts, each part's into a list of its own, the lists then one
  // after the other (sorted next, the keys' order does not matter)
  std::int64_t n_new = 0;
  std::int64_t* new_keys = grid.new_keys.data();
  const auto room = static_cast<std::int64_t>(grid.new_keys.size());
  auto emit = [&](std::int64_t key) {
    if (n_new < room) new_keys[n_new] = key;
    ++n_new;
  };
  if (parts == nullptr) {
    query_moved(model, grid, Span{0, n}, emit);
  } else {
    std::mutex lists_lock;
    std::vector<std::pair<std::int64_t, std::vector<std::int64_t>>> lists;  // (part's first shape, keys)
    (*parts)(n, [&](Span part) {
      if (part.first == 0 && part.last == n) {  // one part (one thread): no list
        query_moved(model, grid, part, emit);
        return;
      }
      std::vector<std::int64_t> mine;
      auto add = [&mine](std::int64_t key) { mine.push_back(key); };
      query_moved(model, grid, part, add);
      const std::lock_guard<std::mutex> hold(lists_lock);
      lists.emplace_back(part.first, std::move(mine));
    });
    std::sort(lists.begin(), lists.end(),
              [](const auto& x, const auto& y) { return x.first < y.first; });
    for (const auto& list : lists)
      for (const std::int64_t key : list.second) emit(key);
  }
  if (kept + n_new > capacity) return kept + n_new;
  const std::int64_t* keys = grid.new_keys.data();
  sort_prefix(grid.new_keys.data(), n_new, grid.sort_scratch.data(), grid.sort_count.data());
  // merge the two sorted lists
  std::int64_t i = 0, j = 0, out = 0;
  while (i < kept || j < n_new) {
    const bool take_kept =
        j >= n_new || (i < kept && static_cast<std::int64_t>(kept_list[i][0]) * n +
                                           kept_list[i][1] < keys[j]);
    if (take_kept) {
      pairs[out] = kept_list[i++];
    } else {
      pairs[out] = {static_cast<std::int32_t>(keys[j] / n), static_cast<std::int32_t>(keys[j] % n)};
      ++j;
    }
    ++out;
  }
  grid.meta.pairs_valid = 1;
  return out;
}

template std::int64_t find_pairs(const Model<2>&, Grid<2>&, Contacts<2>&, const InParts*);
template std::int64_t find_pairs(const Model<3>&, Grid<3>&, Contacts<3>&, const InParts*);

// The cell size is CELL_SIZES times the median half-diagonal (m) of the dynamic shapes
// plus twice the fat margin (at that median's scale, SCALE_LENGTH), so a typical fat box
// fits in one cell with room to spare; the table has at least TABLE_PER_SHAPE buckets
// per shape.
template <int D>
void Grid<D>::allocate(const std::vector<double>& shape_size, const std::vector<std::uint8_t>& dynamic,
                       std::int64_t capacity) {
  namespace C = constants;
  const std::size_t s = shape_size.size();
  std::vector<double> dyn;
  for (std::size_t i = 0; i < s; ++i)
    if (dynamic[i]) dyn.push_back(shape_size[i]);
  double size = 1.0, scale = 1.0;
  if (!dyn.empty()) {  // the median as numpy takes it: the mean of the middle two
    std::sort(dyn.begin(), dyn.end());
    const std::size_t k = dyn.size();
    const double median = k % 2 ? dyn[k / 2] : 0.5 * (dyn[k / 2 - 1] + dyn[k / 2]);
    size = (D == 2 ? C::CELL_SIZES : C::CELL_SIZES_3D) * median;
    scale = std::min(1.0, median / C::SCALE_LENGTH);
  }
  const double cell = std::max(size, 1e-3 * scale) + 2.0 * scale * C::AABB_MARGIN;
  std::size_t table = 64;
  while (table < static_cast<std::size_t>(C::TABLE_PER_SHAPE) * s) table *= 2;
  const std::size_t e = std::max<std::size_t>(s, 1);
  const std::size_t p = static_cast<std::size_t>(std::max<std::int64_t>(capacity, 1));
  inv_cell = 1.0 / cell;
  shape_aabb.assign(s, {});
  shape_fat.assign(s, {});
  shape_moved.assign(s, 0);
  shape_big.assign(s, 0);
  shape_cell.assign(s, {});
  shape_bucket.assign(s, 0);
  entry_shape.assign(e, 0);
  entry_cell.assign(e, {});
  entry_fat.assign(e, {});
  entry_tag.assign(e, 0);
  bucket_start.assign(table + 1, 0);
  big_list.assign(e, 0);
  span = {};
  meta = {};
  new_keys.assign(p, 0);
  kept.assign(p, {});
  sort_scratch.assign(p, 0);
  sort_count.assign((std::size_t{1} << C::RADIX_BITS) + 1, 0);
}

template <int D>
void Grid<D>::grow(std::int64_t capacity) {
  const std::size_t p = static_cast<std::size_t>(std::max<std::int64_t>(capacity, 1));
  new_keys.assign(p, 0);
  kept.assign(p, {});
  sort_scratch.assign(p, 0);
  meta.pairs_valid = 0;
}
template struct Grid<2>;
template struct Grid<3>;

}  // namespace rbsim
