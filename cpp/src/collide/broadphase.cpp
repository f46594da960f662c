// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <algorithm>
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> std::int64_t find_pairs(const Model<D>&, Grid<D>&, Contacts<D>&) { throw std::logic_error("find_pairs: not ported"); }
template std::int64_t find_pairs(const Model<2>&, Grid<2>&, Contacts<2>&);
// The cell size is CELL_SIZES times the median half-diagonal (m) of the dynamic shapes
// plus twice the fat margin, so a typical fat box fits in one cell with room to spare;
// the table has at least TABLE_PER_SHAPE buckets per shape.
template <int D>
void Grid<D>::allocate(const std::vector<double>& shape_size, const std::vector<std::uint8_t>& dynamic,
                       std::int64_t capacity) {
  namespace C = constants;
  const std::size_t s = shape_size.size();
  std::vector<double> dyn;
  for (std::size_t i = 0; i < s; ++i)
    if (dynamic[i]) dyn.push_back(shape_size[i]);
  double size = 1.0;
  if (!dyn.empty()) {  // the median as numpy takes it: the mean of the middle two
    std::sort(dyn.begin(), dyn.end());
    const std::size_t k = dyn.size();
    const double median = k % 2 ? dyn[k / 2] : 0.5 * (dyn[k / 2 - 1] + dyn[k / 2]);
    size = C::CELL_SIZES * median;
  }
  const double cell = std::max(size, 1e-3) + 2.0 * C::AABB_MARGIN;
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
}  // namespace rbsim
