// This step's manifolds become last step's: the warm-start source of the next step's
// matching, and the manifolds it may carry forward. Counts the touching points. And,
// for a run that records its contact points, each point's normal impulse over the step.
#include <algorithm>

#include "rbsim/stages.hpp"

namespace rbsim {

template <int D>
void store_impulses(Contacts<D>& c) {
  const std::int64_t m = c.count.manifolds;
  const std::int64_t touching = store_impulses(c, Span{0, m});
  c.count.manifolds_prev = m;
  c.count.points_touching = touching;
}

template <int D>
std::int64_t store_impulses(Contacts<D>& c, Span manifolds) {
  std::int64_t touching = 0;  // points that pushed this step (pushed_in_step)
  for (std::int64_t i = manifolds.first; i < manifolds.last; ++i) {
    c.prev_support[i] = c.support[i];
    if (c.carried[i]) {  // the slot's prev_* already hold all but the impulses
      for (int k = 0; k < c.points[i]; ++k) {
        c.prev_normal_impulse[i][k] = c.normal_impulse[i][k];
        c.prev_tangent_impulse[i][k] = c.tangent_impulse[i][k];
        if (pushed_in_step(c, i, k)) ++touching;
      }
      continue;
    }
    c.prev_key[i] = c.key[i];
    c.prev_points[i] = c.points[i];
    c.prev_normal[i] = c.normal[i];
    c.prev_ref_offset[i] = c.ref_offset[i];
    c.prev_ref_turn_a[i] = c.ref_turn_a[i];
    c.prev_ref_turn_b[i] = c.ref_turn_b[i];
    for (int k = 0; k < c.points[i]; ++k) {
      c.prev_anchor_a[i][k] = c.anchor_a[i][k];
      c.prev_anchor_b[i][k] = c.anchor_b[i][k];
      c.prev_sep_anchor_a[i][k] = c.sep_anchor_a[i][k];
      c.prev_sep_anchor_b[i][k] = c.sep_anchor_b[i][k];
      c.prev_ref_separation[i][k] = c.ref_separation[i][k];
      c.prev_feature[i][k] = c.feature[i][k];
      c.prev_normal_impulse[i][k] = c.normal_impulse[i][k];
      c.prev_tangent_impulse[i][k] = c.tangent_impulse[i][k];
      if (pushed_in_step(c, i, k)) ++touching;
    }
  }
  return touching;
}

template <int D>
std::int64_t store_touching(Contacts<D>& c, Span manifolds) {
  std::int64_t touching = 0;
  for (std::int64_t i = manifolds.first; i < manifolds.last; ++i) {
    c.prev_support[i] = c.support[i];
    for (int k = 0; k < c.points[i]; ++k)
      if (pushed_in_step(c, i, k)) ++touching;
  }
  return touching;
}

namespace {

// f(current, prev) for each manifold array the store hands over, but the keys.
template <int D, class F>
void each_handed_over(Contacts<D>& c, F&& f) {
  f(c.points, c.prev_points), f(c.normal, c.prev_normal), f(c.ref_offset, c.prev_ref_offset);
  f(c.ref_turn_a, c.prev_ref_turn_a), f(c.ref_turn_b, c.prev_ref_turn_b);
  f(c.anchor_a, c.prev_anchor_a), f(c.anchor_b, c.prev_anchor_b);
  f(c.sep_anchor_a, c.prev_sep_anchor_a), f(c.sep_anchor_b, c.prev_sep_anchor_b);
  f(c.ref_separation, c.prev_ref_separation), f(c.feature, c.prev_feature);
  f(c.normal_impulse, c.prev_normal_impulse), f(c.tangent_impulse, c.prev_tangent_impulse);
}

}  // namespace

template <int D>
void take_prev(Contacts<D>& c) {
  if (!c.prev_pending) return;
  each_handed_over(c, [](auto& now, auto& prev) { now.swap(prev); });
  // (the keys copied: the merge finds a manifold still in its slot by them)
  std::copy_n(c.key.begin(), c.count.manifolds_prev, c.prev_key.begin());
  c.prev_pending = false;
  c.prev_swapped = true;
}

template <int D>
void settle_prev(Contacts<D>& c) {
  if (!c.prev_pending) return;
  const std::int64_t n = c.count.manifolds_prev;
  each_handed_over(c, [n](auto& now, auto& prev) { std::copy_n(now.begin(), n, prev.begin()); });
  std::copy_n(c.key.begin(), n, c.prev_key.begin());
  c.prev_pending = false;
}

template <int D>
void begin_step_impulses(Contacts<D>& c) {
  const std::int64_t m = c.count.manifolds;
  std::fill_n(c.shock_points.begin(), m, std::uint8_t{0});
  if (!c.record_impulses) return;
  using Impulses = typename Contacts<D>::template PerPoint<double>;
  std::fill_n(c.step_impulse.begin(), m, Impulses{});
  std::fill_n(c.shock_impulse.begin(), m, 0.0);
}

template <int D>
void add_step_impulses(Contacts<D>& c) {
  give_impulses(c);  // (2D: the next pass takes them into the batches again)
  for (std::int64_t i = 0; i < c.count.manifolds; ++i)
    for (int k = 0; k < c.points[i]; ++k) c.step_impulse[i][k] += c.normal_impulse[i][k];
}

template void store_impulses(Contacts<2>&);
template std::int64_t store_touching(Contacts<2>&, Span);
template std::int64_t store_touching(Contacts<3>&, Span);
template void take_prev(Contacts<2>&);
template void take_prev(Contacts<3>&);
template void settle_prev(Contacts<2>&);
template void settle_prev(Contacts<3>&);
template void store_impulses(Contacts<3>&);
template std::int64_t store_impulses(Contacts<2>&, Span);
template std::int64_t store_impulses(Contacts<3>&, Span);
template void begin_step_impulses(Contacts<2>&);
template void begin_step_impulses(Contacts<3>&);
template void add_step_impulses(Contacts<2>&);
template void add_step_impulses(Contacts<3>&);

}  // namespace rbsim
