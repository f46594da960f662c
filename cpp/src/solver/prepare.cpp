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
//
// In 3D, with the world inverse inertia tensors I⁻¹ = R I_b⁻¹ Rᵀ at the step's start,
//
//     K = 1/m_a + 1/m_b + n·((I_a⁻¹(r_a×n))×r_a) + n·((I_b⁻¹(r_b×n))×r_b)
//       = 1/m_a + 1/m_b + (r_a×n)·I_a⁻¹(r_a×n) + (r_b×n)·I_b⁻¹(r_b×n),
//
// and friction acts along two tangents t1, t2 (tangent_basis) as one 2×2 block per point,
// K_t[i][j] = (1/m_a + 1/m_b) δ_ij + (r_a×t_i)·I_a⁻¹(r_a×t_j) + (r_b×t_i)·I_b⁻¹(r_b×t_j),
// whose inverse the row keeps.
#include <algorithm>
#include <cmath>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace {

// Point k of manifold m's approach velocity (m/s) and separation (m) at the start of the
// step, from arms ra, rb (m), its separation anchors sa, sb (m) and the normal n. (The
// normal velocity is the same at either: they differ along n, or, for a manifold moved
// to a time of impact, by the turn of bodies that are not still.)
template <int D>
inline void approach_point(const State<D>& st, Contacts<D>& c, std::int64_t m, int k, int a,
                           int b, typename Dim<D>::Vec ra, typename Dim<D>::Vec rb,
                           typename Dim<D>::Vec sa, typename Dim<D>::Vec sb,
                           typename Dim<D>::Vec n) {
  c.approach_velocity[m][k] = normal_velocity(st, a, b, ra, rb, n);
  c.approach_separation[m][k] = c.base_separation[m][k] + dot(n, sa - sb);
}

// The points of a 3D row: inverse masses ma, mb (1/kg), world inverse inertia tensors
// ia, ib (1/(kg·m²)) at the step's start.
void prepare_points_3d(const State<3>& st, Contacts<3>& c, std::int64_t m, int a, int b,
                       double ma, double mb, const Sym3& ia, const Sym3& ib) {
  auto& row = c.solver_row[m];
  const Vec3 n = row.normal;
  tangent_basis(n, row.t1, row.t2);
  row.inv_ia = ia;
  row.inv_ib = ib;
  const Vec3 t1 = row.t1, t2 = row.t2;
  Vec3 inv_rt[4][4];  // 1/(kg·m): each point's I_a⁻¹(r_a × t1), I_a⁻¹(r_a × t2), I_b⁻¹ alike
  row.point = {};  // (the points past the count stay zero)
  for (int k = 0; k < c.points[m]; ++k) {
    SolverRow<3>::Point pt;
    const Vec3 ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
    pt.arm_a = ra;
    pt.arm_b = rb;
    pt.rna = cross(ra, n);
    pt.rnb = cross(rb, n);
    pt.wna = ia * pt.rna;
    pt.wnb = ib * pt.rnb;
    const double kn = ma + mb + dot(pt.rna, pt.wna) + dot(pt.rnb, pt.wnb);
    pt.kn = kn;
    c.normal_mass[m][k] = kn > 0.0 ? 1.0 / kn : 0.0;
    // the tangent block and its inverse (kg)
    const Vec3 a1 = cross(ra, t1), a2 = cross(ra, t2), b1 = cross(rb, t1), b2 = cross(rb, t2);
    const Vec3 ia1 = ia * a1, ia2 = ia * a2, ib1 = ib * b1, ib2 = ib * b2;
    pt.rt1a = a1, pt.rt2a = a2, pt.rt1b = b1, pt.rt2b = b2;
    inv_rt[k][0] = ia1, inv_rt[k][1] = ia2, inv_rt[k][2] = ib1, inv_rt[k][3] = ib2;
    const double k11 = ma + mb + dot(a1, ia1) + dot(b1, ib1);
    const double k22 = ma + mb + dot(a2, ia2) + dot(b2, ib2);
    const double k12 = dot(a1, ia2) + dot(b1, ib2);
    const double det = k11 * k22 - k12 * k12;
    if (det > 1.0e-12 * k11 * k22 && det > 0.0) {
      const double inv = 1.0 / det;
      pt.tm11 = k22 * inv;
      pt.tm12 = -k12 * inv;
      pt.tm22 = k11 * inv;
    } else {
      pt.tm11 = pt.tm12 = pt.tm22 = 0.0;  // two fixed bodies: no friction
    }
    pt.tangent_mass = k11 + k22 > 0.0 ? 2.0 / (k11 + k22) : 0.0;
    pt.ra = c.sep_anchor_a[m][k];
    pt.rb = c.sep_anchor_b[m][k];
    pt.base = c.base_separation[m][k];
    approach_point(st, c, m, k, a, b, ra, rb, pt.ra, pt.rb, n);
    row.point.set(k, pt);
  }
  // friction's coupling between points i > j: δ_ab (1/m_a + 1/m_b) + (r_a,i × t_a)·
  // I_a⁻¹(r_a,j × t_b) + (b likewise), for the directions a, b of t1, t2
  for (int i = 1; i < c.points[m]; ++i) {
    for (int j = 0; j < i; ++j) {
      const auto& pi = row.point[i];
      auto& cp = row.tangent_coupling[i * (i - 1) / 2 + j];
      const Vec3 ja1 = inv_rt[j][0], ja2 = inv_rt[j][1], jb1 = inv_rt[j][2], jb2 = inv_rt[j][3];
      cp[0] = ma + mb + dot(pi.rt1a, ja1) + dot(pi.rt1b, jb1);
      cp[1] = dot(pi.rt1a, ja2) + dot(pi.rt1b, jb2);
      cp[2] = dot(pi.rt2a, ja1) + dot(pi.rt2b, jb1);
      cp[3] = ma + mb + dot(pi.rt2a, ja2) + dot(pi.rt2b, jb2);
    }
  }
  // the normal block: K_ij = 1/m_a + 1/m_b + (r_a,i × n)·I_a⁻¹(r_a,j × n) + (b likewise)
  int e = 0;
  for (int i = 0; i < 4; ++i) {
    for (int j = i; j < 4; ++j, ++e) {
      if (i >= c.points[m] || j >= c.points[m]) {
        row.k[e] = 0.0;
        continue;
      }
      const auto& pi = row.point[i];
      const auto& pj = row.point[j];
      row.k[e] = i == j ? pi.kn : ma + mb + dot(pi.rna, pj.wna) + dot(pi.rnb, pj.wnb);
    }
  }
}

// The factors of a 3D row's normal block for the passes' two usual cases (SolverRow<3>:
// rigid and soft), once its γ is final.
void prepare_blocks_3d(SolverRow<3>& row, int npts) {
  if (npts < 2) return;
  const double none[4] = {0.0, 0.0, 0.0, 0.0};
  double all[4];
  // every point pushed out: soft_target's γ (kn times the row's γ/K) at each
  for (int k = 0; k < npts; ++k) all[k] = row.point.kn[k] * row.gamma;
  factor_block(row.k, none, npts, row.rigid);
  factor_block(row.k, all, npts, row.soft);
}

}  // namespace

// config's soft and soft_static: (mass scale, impulse scale, bias rate) for contacts
// between two dynamic bodies and for contacts with a static or kinematic body (stiffer),
// both for shapes of STIFFNESS_LENGTH and larger; a contact between smaller shapes is
// stiffer by sqrt(STIFFNESS_LENGTH / size) (the smaller shape's size), capped at a quarter
// of the substep rate as config's are. The contact's scale (SCALE_LENGTH) sets its
// fastest push-out and the depth of a deep overlap.
template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& st, Contacts<D>& c,
                      const Config& config) {
  prepare_contacts(model, st, c, config, Span{0, c.count.manifolds});
}

template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& st, Contacts<D>& c,
                      const Config& config, Span manifolds) {
  namespace C = constants;
  using Vec = typename Dim<D>::Vec;
  const auto& im = model.body_inv_mass;
  const auto& ii = model.body_inv_inertia;
  const Soft soft = config.soft, soft_static = config.soft_static;
  // γ/K of each soft constraint: mass scale K/(K+γ), impulse scale γ/(K+γ)
  auto gamma_of = [](Soft s) { return s.mass_scale > 0.0 ? s.impulse_scale / s.mass_scale : 0.0; };
  const double gamma = gamma_of(soft), gamma_static = gamma_of(soft_static);
  const double h = config.dt / config.substeps;            // s
  const double hertz_cap = 0.25 / h;                       // Hz
  const double hertz = std::min(C::CONTACT_HERTZ, hertz_cap);  // config's (step.cpp)
  // whether the cap leaves room for a stiffer small pair (at dt 1/60 with 4 substeps it
  // is the scene's 60 Hz itself, to rounding: none)
  const bool stiffer = hertz < hertz_cap * (1.0 - 1e-9);
  for (std::int64_t m = manifolds.first; m < manifolds.last; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const Vec n = c.normal[m];
    auto& row = c.solver_row[m];
    const int npts = c.points[m];
    if (c.carried[m]) {
      // last step's manifold in the same slot: its row holds all but the separation
      for (int k = 0; k < npts; ++k) {
        if constexpr (D == 3) {
          row.point.base[k] = c.base_separation[m][k];
          const Vec ra = row.point.ra[k], rb = row.point.rb[k];
          approach_point(st, c, m, k, a, b, ra, rb, ra, rb, n);
        } else {
          auto& pt = row.point[k];
          pt.base = c.base_separation[m][k];
          approach_point(st, c, m, k, a, b, pt.ra, pt.rb, pt.ra, pt.rb, n);
        }
      }
      continue;
    }
    const double ma = im[a], mb = im[b];
    row.normal = n;
    const bool fixed = ma == 0.0 || mb == 0.0;
    row.gamma = fixed ? gamma_static : gamma;
    row.bias_rate = fixed ? soft_static.bias_rate : soft.bias_rate;
    double row_hertz = fixed ? 2.0 * hertz : hertz;  // Hz: config's soft or soft_static
    bool own = false;  // the row's own soft constraint (rare): a small pair
    const double size = std::min(c.shape_size[c.shape_a[m]], c.shape_size[c.shape_b[m]]);  // m
    if (size < C::STIFFNESS_LENGTH && stiffer) {
      // a small pair, and room under the cap: stiffer
      const double stiff = std::min(hertz * std::sqrt(C::STIFFNESS_LENGTH / size), hertz_cap);
      row_hertz = fixed ? 2.0 * stiff : stiff;
      own = true;
    }
    const double scale = c.scale[m];
    row.max_push = -C::CONTACT_PUSH_MAX_VELOCITY * (scale < 1.0 ? std::sqrt(scale) : 1.0);
    row.deep = -scale * C::DEEP_OVERLAP;
    row.friction = c.friction[m];
    if constexpr (D == 3) {
      // the world tensors at the step's start, as transform_shapes made them
      prepare_points_3d(st, c, m, a, b, ma, mb, c.body_inv_inertia_world[a],
                        c.body_inv_inertia_world[b]);
    } else {
    const double ia = ii[a], ib = ii[b];
    const Vec t = cross(n, 1.0);  // (n_y, −n_x)
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
      pt.ra = c.sep_anchor_a[m][k];
      pt.rb = c.sep_anchor_b[m][k];
      pt.base = c.base_separation[m][k];
      approach_point(st, c, m, k, a, b, ra, rb, pt.ra, pt.rb, n);
    }
    if (npts == 2) {
      // the off-diagonal of the two points' normal block (1/kg)
      const auto& p0 = row.point[0];
      const auto& p1 = row.point[1];
      const double k01 = ma + mb + ia * p0.rna * p1.rna;
      row.k01 = k01 + ib * p0.rnb * p1.rnb;
    }
    }
    if (own) {
      const Soft s = soft_parameters(row_hertz, C::CONTACT_DAMPING_RATIO, h);
      row.gamma = gamma_of(s);
      row.bias_rate = s.bias_rate;
    }
    if constexpr (D == 3) prepare_blocks_3d(row, npts);
  }
}

template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, const Config&);
template void prepare_contacts(const Model<3>&, const State<3>&, Contacts<3>&, const Config&);
template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, const Config&, Span);
template void prepare_contacts(const Model<3>&, const State<3>&, Contacts<3>&, const Config&, Span);

}  // namespace rbsim
