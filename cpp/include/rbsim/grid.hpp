// The broadphase's storage: a loose uniform grid over fat boxes, and the pair update's
// scratch. S shapes, E = S entries, T table buckets, P pair capacity.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "constants.hpp"
#include "math.hpp"

namespace rbsim {

template <int D>
struct Aabb {
  typename Dim<D>::Vec lo, hi;  // m
};

// The boxes are apart along some axis (touching boxes overlap).
template <int D>
inline bool disjoint(const Aabb<D>& a, const Aabb<D>& b) {
  if constexpr (D == 2) {
    return b.lo.x > a.hi.x || a.lo.x > b.hi.x || b.lo.y > a.hi.y || a.lo.y > b.hi.y;
  } else {
    return b.lo.x > a.hi.x || a.lo.x > b.hi.x || b.lo.y > a.hi.y || a.lo.y > b.hi.y ||
           b.lo.z > a.hi.z || a.lo.z > b.hi.z;
  }
}

template <int D>
using Cell = std::array<std::int64_t, D>;

template <int D>
struct GridMeta {
  std::int64_t big_count = 0;       // shapes tested against every other shape
  std::int64_t pairs_valid = 0;     // 1 once the pair list has been found
  std::int64_t direct_buckets = 0;  // 1: the cells are their own buckets, row-major
  Cell<D> first_cell{};             // the occupied rectangle's first cell
  Cell<D> extent{};                 // and its size in cells
};

template <int D>
struct Grid {
  using Vec = typename Dim<D>::Vec;
  double inv_cell = 1.0;                  // 1/m
  std::vector<Aabb<D>> shape_aabb;        // (S,) tight boxes
  std::vector<Aabb<D>> shape_fat;         // (S,) fat boxes
  std::vector<std::uint8_t> shape_moved;  // (S,) tight box left its fat box this step
  std::vector<std::uint8_t> shape_big;    // (S,)
  std::vector<Cell<D>> shape_cell;        // (S,) cell of a small shape's fat min corner
  std::vector<std::int64_t> shape_bucket; // (S,)
  // the small shapes' entries, sorted by bucket, with copies of what a pair test reads
  std::vector<std::int32_t> entry_shape;  // (E,)
  std::vector<Cell<D>> entry_cell;        // (E,) (hashed table only)
  std::vector<Aabb<D>> entry_fat;         // (E,)
  std::vector<std::int32_t> entry_tag;    // (E,) body index if dynamic, else -1 - body index
  std::vector<std::int64_t> bucket_start; // (T+1,)
  std::vector<std::int32_t> big_list;     // (S,) big shapes in index order
  Vec span{};  // m: widest and tallest small fat box, padded up by a relative 1e-12
  // The boxes are kept in a frame that moves as the dynamic bodies do (each step by their
  // median move in the last, frame_move): box = world box - frame_offset. A heap falling
  // as one then stays inside its fat boxes, as a heap at rest does, and a static shape is
  // the one that moves. frame_offset is this step's, frame_origin the last completed
  // step's (a step begun again takes the same offset).
  Vec frame_origin{};  // m
  Vec frame_offset{};  // m
  GridMeta<D> meta;
  std::vector<std::int64_t> new_keys;     // (P,) scratch for the pair update
  std::vector<std::array<std::int32_t, 2>> kept;  // (P,)
  std::vector<std::int64_t> sort_scratch; // (P,)
  std::vector<std::int64_t> sort_count;   // (2^RADIX_BITS + 1,)

  // Storage for the shapes whose half-diagonals (m) are shape_size, `capacity` pairs.
  void allocate(const std::vector<double>& shape_size, const std::vector<std::uint8_t>& dynamic,
                std::int64_t capacity);
  // Room for `capacity` pairs; the pairs are found anew.
  void grow(std::int64_t capacity);
};

}  // namespace rbsim
