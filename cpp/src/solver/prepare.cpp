// The solver's rows: effective masses, approach velocities and softness of every contact
// point, written once per step into contacts.solver_row, which the solver's passes then
// read as one record per manifold.
//
// For a point with anchors r_a, r_b (m) from the centres of mass and normal n (from b
// towards a), an impulse λ n on a (−λ n on b) changes the normal velocity by K λ with
//
//     K = 1/m_a + 1/m_b + (r_a × n)²/I_a + (r_b × n)²/I_b     (1/kg),
//
// and likewise along the tangent t. In 2D t = (n_y, −n_x) (the numba engine's convention:
// −perp(n), the normal turned a quarter clockwise); cross(n, 1.0) is that vector.
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace {

// Point k of manifold m's approach velocity (m/s) and separation (m) at the start of the
// step, from its anchors ra, rb (m) and normal n.
template <int D>
inline void approach_point(const State<D>& st, Contacts<D>& c, std::int64_t m, int k, int a,
                           int b, typename Dim<D>::Vec ra, typename Dim<D>::Vec rb,
                           typename Dim<D>::Vec n) {
  c.approach_velocity[m][k] = normal_velocity(st, a, b, ra, rb, n);
  c.approach_separation[m][k] = c.base_separation[m][k] + dot(n, ra - rb);
}

}  // namespace

// soft, soft_static: (mass scale, impulse scale, bias rate) for contacts between two
// dynamic bodies and for contacts with a static or kinematic body (stiffer).
template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& st, Contacts<D>& c, Soft soft,
                      Soft soft_static) {
  static_assert(D == 2, "the solver row is 2D (SolverRow<2>)");
  using Vec = typename Dim<D>::Vec;
  const auto& im = model.body_inv_mass;
  const auto& ii = model.body_inv_inertia;
  // γ/K of each soft constraint: mass scale K/(K+γ), impulse scale γ/(K+γ)
  const double gamma = soft.mass_scale > 0.0 ? soft.impulse_scale / soft.mass_scale : 0.0;
  const double gamma_static =
      soft_static.mass_scale > 0.0 ? soft_static.impulse_scale / soft_static.mass_scale : 0.0;
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const Vec n = c.normal[m];
    auto& row = c.solver_row[m];
    const int npts = c.points[m];
    if (c.carried[m]) {
      // last step's manifold in the same slot: its row holds all but the separation
      for (int k = 0; k < npts; ++k) {
        auto& pt = row.point[k];
        pt.base = c.base_separation[m][k];
        approach_point(st, c, m, k, a, b, pt.ra, pt.rb, n);
      }
      continue;
    }
    const double ma = im[a], mb = im[b], ia = ii[a], ib = ii[b];
    const Vec t = cross(n, 1.0);  // (n_y, −n_x)
    row.normal = n;
    if (ma == 0.0 || mb == 0.0) {
      row.gamma = gamma_static;
      row.bias_rate = soft_static.bias_rate;
    } else {
      row.gamma = gamma;
      row.bias_rate = soft.bias_rate;
    }
    row.friction = c.friction[m];
    for (int k = 0; k < npts; ++k) {
      auto& pt = row.point[k];
      const Vec ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
      const double rna = cross(ra, n), rnb = cross(rb, n);
      const double kn = ma + mb + ia * rna * rna + ib * rnb * rnb;
      c.normal_mass[m][k] = kn > 0.0 ? 1.0 / kn : 0.0;
      const double rta = cross(ra, t), rtb = cross(rb, t);
      const double kt = ma + mb + ia * rta * rta + ib * rtb * rtb;
      pt.rna = rna;
      pt.rnb = rnb;
      pt.rta = rta;
      pt.rtb = rtb;
      pt.kn = kn;
      pt.tangent_mass = kt > 0.0 ? 1.0 / kt : 0.0;
      pt.ra = ra;
      pt.rb = rb;
      pt.base = c.base_separation[m][k];
      approach_point(st, c, m, k, a, b, ra, rb, n);
    }
    if (npts == 2) {
      // the off-diagonal of the two points' normal block (1/kg)
      const auto& p0 = row.point[0];
      const auto& p1 = row.point[1];
      const double k01 = ma + mb + ia * p0.rna * p1.rna;
      row.k01 = k01 + ib * p0.rnb * p1.rnb;
    }
  }
}

template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, Soft, Soft);

}  // namespace rbsim
