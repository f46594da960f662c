// This step's manifolds become last step's: the warm-start source of the next step's
// matching, and the manifolds it may carry forward. Counts the touching points.
#include "rbsim/stages.hpp"

namespace rbsim {

template <int D>
void store_impulses(Contacts<D>& c) {
  const std::int64_t m = c.count.manifolds;
  std::int64_t touching = 0;  // points that pushed (max normal impulse > 0) this step
  for (std::int64_t i = 0; i < m; ++i) {
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
  c.count.manifolds_prev = m;
  c.count.points_touching = touching;
}

template void store_impulses(Contacts<2>&);
template void store_impulses(Contacts<3>&);

}  // namespace rbsim
