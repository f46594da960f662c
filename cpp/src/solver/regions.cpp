// The regions of the solver's passes, for threads.
//
// A pass over the solve order is sequential by nature: it carries a push up a stack within
// one sweep, and the order matters (waves.cpp). Its waves give the exact sequential result
// on any number of threads, but a pyramid of base 40 has some 230 waves of a batch or two
// each: a barrier per wave costs more than the wave. So the threaded pass solves a
// slightly different, fixed order: the dynamic bodies are split into regions (strips of
// equal body count across gravity, found when the contact graph changes), each region's
// manifolds are solved in its own support order (the solve order restricted to the region:
// ground first, level by level), the regions at once since they share no dynamic body,
// and then the manifolds that join two regions. The partition depends on the state only:
// every thread count, one included, solves the same order and gets the same bits. A scene
// too small to split (REGION_MIN_BODIES) is one region, and its passes are exactly the
// sequential solve order's.
//
// A joining manifold belongs to the cut between its two regions. The cuts between
// regions 2k and 2k + 1 share no dynamic body with one another, so they too are solved at
// once, each in solve order; the other joining manifolds (the cuts between 2k + 1 and
// 2k + 2, and a manifold that spans more than one cut) come last, on one thread.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// The segment of a manifold between bodies in regions ra and rb (-1: static or kinematic).
inline int manifold_segment(int ra, int rb, int regions) {
  if (ra < 0) ra = rb;
  if (rb < 0) rb = ra;
  if (ra < 0) return 0;  // (no dynamic body: not solved, anywhere will do)
  if (ra == rb) return ra;
  const int lo = std::min(ra, rb), hi = std::max(ra, rb);
  if (hi == lo + 1 && lo % 2 == 0) return regions + lo / 2;
  return regions + regions / 2;
}

template <int D>
inline double component(const typename Dim<D>::Vec& v, int d) {
  return reinterpret_cast<const double*>(&v)[d];
}

// Each dynamic body's region: strips of equal count along the axis across gravity along
// which the bodies spread most (ties by body index).
template <int D>
void split_bodies(const Model<D>& model, const State<D>& st, Contacts<D>& c) {
  const int n = model.body_count();
  std::vector<std::pair<double, int>> key;
  key.reserve(n);
  for (int i = 0; i < n; ++i) {
    c.body_region[i] = -1;
    if (model.is_dynamic(i)) key.push_back({0.0, i});
  }
  const int n_dyn = static_cast<int>(key.size());
  const int regions = n_dyn >= C::SOLVER_REGIONS * C::REGION_MIN_BODIES ? C::SOLVER_REGIONS : 1;
  c.region_count = regions;
  if (regions == 1) {
    for (const auto& k : key) c.body_region[k.second] = 0;
    return;
  }
  // the axis: the widest spread, weighted by how far across gravity the axis lies
  const auto g = model.gravity;
  const double g2 = dot(g, g);
  int axis = 0;
  double best = -1.0;
  for (int d = 0; d < D; ++d) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& k : key) {
      const double x = component<D>(st.body_x[k.second], d);
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    const double gd = component<D>(g, d);
    const double across = g2 > 0.0 ? 1.0 - gd * gd / g2 : 1.0;
    const double score = (hi - lo) * across;
    if (score > best) {
      best = score;
      axis = d;
    }
  }
  for (auto& k : key) {
    const double x = component<D>(st.body_x[k.second], axis);
    k.first = std::isfinite(x) ? x : std::numeric_limits<double>::infinity();
  }
  // the strips' bounds: the bodies ranked by (coordinate, index), cut in equal counts
  auto from = key.begin();
  for (int r = 0; r < regions; ++r) {
    auto to = r + 1 == regions ? key.end() : key.begin() + static_cast<std::ptrdiff_t>(n_dyn) * (r + 1) / regions;
    if (to != key.end()) std::nth_element(from, to, key.end());
    for (auto it = from; it != to; ++it) c.body_region[it->second] = r;
    from = to;
  }
}

// Regroup order[0..n) stably by the manifolds' segments; bounds[g] .. bounds[g+1] is
// segment g (bounds has segments + 1 entries).
template <int D>
void regroup(const Contacts<D>& c, std::int32_t* order, std::int64_t n, std::int64_t* bounds,
             int segments, std::vector<std::int32_t>& scratch) {
  const int regions = static_cast<int>(c.region_count);
  for (int g = 0; g <= segments; ++g) bounds[g] = 0;
  if (regions == 1) {  // one region, no joints: the order as it is
    for (int g = 1; g <= segments; ++g) bounds[g] = n;
    return;
  }
  auto seg = [&](std::int32_t m) {
    return manifold_segment(c.body_region[c.body_a[m]], c.body_region[c.body_b[m]], regions);
  };
  for (std::int64_t o = 0; o < n; ++o) bounds[seg(order[o]) + 1] += 1;
  for (int g = 0; g < segments; ++g) bounds[g + 1] += bounds[g];
  scratch.assign(order, order + n);
  std::vector<std::int64_t> fill(bounds, bounds + segments);
  for (const std::int32_t m : scratch) order[fill[seg(m)]++] = m;
}

}  // namespace

template <int D>
void partition_regions(const Model<D>& model, const State<D>& st, Contacts<D>& c) {
  std::vector<std::int32_t> scratch;
  if (c.count.graph_unchanged != 1) {
    split_bodies(model, st, c);
    regroup(c, c.solve_order.data(), c.count.manifolds, c.segment_order.data(),
            segment_count(static_cast<int>(c.region_count)), scratch);
  }
  regroup(c, c.shock_order.data(), c.count.shock_count, c.segment_shock.data(),
          segment_count(static_cast<int>(c.region_count)), scratch);
}

template void partition_regions(const Model<2>&, const State<2>&, Contacts<2>&);
template void partition_regions(const Model<3>&, const State<3>&, Contacts<3>&);

}  // namespace rbsim
