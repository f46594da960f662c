// Move a dynamic body out of a static or kinematic one where it overlaps by more than
// max_overlap (m, times the contact's scale: SCALE_LENGTH), along the contact normal,
// without touching its velocity.
//
// The soft contacts push overlaps out at a bounded speed, which a pile under permanent
// pressure (more bodies than fit in their box) can outrun: bodies were squeezed into the
// walls until the wall's normal flipped and they left the box. A surface that cannot move
// is rigid, so here the overlap is taken off the position directly. Resting contacts
// overlap far less than max_overlap (a fraction of a millimetre on static ground), so
// this acts only in such overload.
#include <algorithm>

#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

template <int D>
void limit_static_overlap(const Model<D>& model, State<D>& st, Contacts<D>& c,
                          double max_overlap) {
  using Vec = typename Dim<D>::Vec;
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const bool a_fixed = !model.is_dynamic(a);
    const bool b_fixed = !model.is_dynamic(b);
    if (a_fixed == b_fixed) continue;  // two dynamic bodies (left to the solver) or two fixed
    const Vec n = c.normal[m];
    double deepest = 0.0;
    const int npts = c.points[m];
    for (int k = 0; k < npts; ++k) deepest = std::min(deepest, point_separation(c, m, k, a, b, n));
    const double push = -deepest - c.scale[m] * max_overlap;  // m
    if (push <= 0.0) continue;
    const Vec d = push * n;
    if (b_fixed) {  // the normal points from b to a: a moves along +n
      st.body_x[a] += d;
      c.body_delta[a].dx += d;
    } else {
      st.body_x[b] -= d;
      c.body_delta[b].dx -= d;
    }
  }
}

template void limit_static_overlap(const Model<2>&, State<2>&, Contacts<2>&, double);
template void limit_static_overlap(const Model<3>&, State<3>&, Contacts<3>&, double);

}  // namespace rbsim
