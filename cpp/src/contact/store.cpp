// This step's manifolds become last step's: the warm-start source of the next step's
// matching, and the manifolds it may carry forward. Counts the touching points.
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
  std::int64_t touching = 0;  // points that pushed (max normal impulse > 0) this step
  for (std::int64_t i = manifolds.first; i < manifolds.last; ++i) {
    c.prev_support[i] = c.support[i];
    if (c.carried[i]) {  // the slot's prev_* already hold all but the impulses
      for (int k = 0; k < c.points[i]; ++k) {
        c.prev_normal_impulse[i][k] = c.normal_impulse[i][k];
        c.prev_tangent_impulse[i][k] = c.tangent_impulse[i][k];
        if (c.max_normal_impulse[i][k] > 0.0) ++touching;
      }
      continue;
    }
    c.prev_key[i] = c.key[i];
    c.prev_points[i] = c.points[i];
    c.prev_normal[i] = c.normal[i];
    for (int k = 0; k < c.points[i]; ++k) {
      c.prev_anchor_a[i][k] = c.anchor_a[i][k];
      c.prev_anchor_b[i][k] = c.anchor_b[i][k];
      c.prev_sep_anchor_a[i][k] = c.sep_anchor_a[i][k];
      c.prev_sep_anchor_b[i][k] = c.sep_anchor_b[i][k];
      c.prev_ref_separation[i][k] = c.ref_separation[i][k];
      c.prev_feature[i][k] = c.feature[i][k];
      c.prev_normal_impulse[i][k] = c.normal_impulse[i][k];
      c.prev_tangent_impulse[i][k] = c.tangent_impulse[i][k];
      if (c.max_normal_impulse[i][k] > 0.0) ++touching;
    }
  }
  return touching;
}

template void store_impulses(Contacts<2>&);
template void store_impulses(Contacts<3>&);
template std::int64_t store_impulses(Contacts<2>&, Span);
template std::int64_t store_impulses(Contacts<3>&, Span);

}  // namespace rbsim
