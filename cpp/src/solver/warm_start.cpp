// Warm start: last substep's accumulated impulses applied again at the start of the
// substep's solve (they are impulses per substep, so the solver starts from the answer
// of the last one and only corrects it).
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

template <int D>
void warm_start(const Model<D>& model, State<D>& st, Contacts<D>& c) {
  static_assert(D == 2, "the solver row is 2D (SolverRow<2>)");
  using Vec = typename Dim<D>::Vec;
  const auto& im = model.body_inv_mass;
  const auto& ii = model.body_inv_inertia;
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const auto& row = c.solver_row[m];
    const Vec n = row.normal;
    const Vec t = cross(n, 1.0);  // (n_y, −n_x)
    // the manifold's impulse (N·s) and its moments on each body (N·m·s)
    Vec p{};
    double ta = 0.0, tb = 0.0;
    const int npts = c.points[m];
    for (int k = 0; k < npts; ++k) {
      const auto& pt = row.point[k];
      const double jn = c.normal_impulse[m][k], jt = c.tangent_impulse[m][k];
      p += jn * n + jt * t;
      ta += jn * pt.rna + jt * pt.rta;
      tb += jn * pt.rnb + jt * pt.rtb;
    }
    const double ma = im[a], mb = im[b], ia = ii[a], ib = ii[b];
    // a fixed body is not written (see solve_contacts)
    if (ma != 0.0 || ia != 0.0) {
      st.body_v[a] += ma * p;
      st.body_w[a] += ia * ta;
    }
    if (mb != 0.0 || ib != 0.0) {
      st.body_v[b] -= mb * p;
      st.body_w[b] -= ib * tb;
    }
  }
}

template void warm_start(const Model<2>&, State<2>&, Contacts<2>&);

}  // namespace rbsim
