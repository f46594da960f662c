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
#include <cstring>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"
#include "collide/toi.hpp"
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

// 3D vectors in lanes, one point of a row in each (wide.hpp's LanesXYZ, and its dot), and
// what prepare_points_3d does with them: the scalar operations of math.hpp in their
// order, lane by lane.
inline LanesXYZ cross(const LanesXYZ& a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline LanesXYZ times(const Sym3& m, const LanesXYZ& v) {
  return {m.xx * v.x + m.xy * v.y + m.xz * v.z, m.xy * v.x + m.yy * v.y + m.yz * v.z,
          m.xz * v.x + m.yz * v.y + m.zz * v.z};
}
// point k's vector of the manifold (m) in lane k, lanes past the count zero
inline LanesXYZ load_points(const std::array<Vec3, 4>& p, LaneMask live) {
  const LanesXYZ v = load_xyz(p.data());
  const Lanes zero = splat(0.0);
  return {select(live, v.x, zero), select(live, v.y, zero), select(live, v.z, zero)};
}
inline void store_points(Vec3x4& out, const LanesXYZ& v) {
  std::memcpy(out.x, &v.x, sizeof v.x);
  std::memcpy(out.y, &v.y, sizeof v.y);
  std::memcpy(out.z, &v.z, sizeof v.z);
}

// The rotation a static or kinematic body i's contact levers are turned by for their
// velocity, v + ω × r: half its turn over the step, ω dt / 2. The levers are the step's
// (as the rows are), while a turning kinematic body's surface turns under them: held at
// the step's start, a box riding a turntable at 2 rad/s was given the table's velocity
// there for the whole step and went on along that tangent, outward by r (ω dt)² / 2 a
// step (at r = 0.5 m and dt 1/60, 2.1 cm a second, slipping off in time); at the step's
// middle its path bends about the table's centre as the table's does. (Identity for a
// dynamic body, whose own turn the solve follows, and one that does not turn.)
template <int D>
inline typename Dim<D>::Rot kinematic_lever(const Model<D>& model, const State<D>& st, int i,
                                            double dt) {
  const auto w = st.body_w[i];  // rad/s
  bool turns;
  if constexpr (D == 2)
    turns = w != 0.0;
  else
    turns = w.x != 0.0 || w.y != 0.0 || w.z != 0.0;
  if (model.is_dynamic(i) || !turns) return typename Dim<D>::Rot{};
  return turn_by(0.5 * dt * w);
}

// The points of a 3D row: inverse masses ma, mb (1/kg), world inverse inertia tensors
// ia, ib (1/(kg·m²)) at the step's start. The points' own fields are made in lanes, one
// point in each (a lane past the count stays zero, as the passes expect); the couplings
// between points and the normal block from them.
// (approach: the points' approach velocities and separations too, at the step's start;
// not when the rows are made again within the step)
void prepare_points_3d(const State<3>& st, Contacts<3>& c, std::int64_t m, int a, int b,
                       double ma, double mb, const Sym3& ia, const Sym3& ib,
                       const Quat& turn_a, const Quat& turn_b, bool approach) {
  auto& row = c.solver_row[m];
  const Vec3 n = row.normal;
  tangent_basis(n, row.t1, row.t2);
  row.inv_ia = ia;
  row.inv_ib = ib;
  const Vec3 t1 = row.t1, t2 = row.t2;
  const int npts = c.points[m];
  const LaneMask live = first_lanes(npts);
  const Lanes zero = splat(0.0), mass = splat(ma + mb);
  auto& P = row.point;
  // (a turning kinematic body's levers turned on by half the step: kinematic_lever)
  std::array<Vec3, 4> arm_a = c.anchor_a[m], arm_b = c.anchor_b[m];
  for (int k = 0; k < npts; ++k) {
    if (ma == 0.0) arm_a[k] = rotate(turn_a, arm_a[k]);
    if (mb == 0.0) arm_b[k] = rotate(turn_b, arm_b[k]);
  }
  const LanesXYZ ra = load_points(arm_a, live), rb = load_points(arm_b, live);
  store_points(P.arm_a, ra);
  store_points(P.arm_b, rb);
  const LanesXYZ rna = cross(ra, n), rnb = cross(rb, n);
  const LanesXYZ wna = times(ia, rna), wnb = times(ib, rnb);
  store_points(P.rna, rna);
  store_points(P.rnb, rnb);
  store_points(P.wna, wna);
  store_points(P.wnb, wnb);
  const Lanes kn = (mass + dot(rna, wna)) + dot(rnb, wnb);  // 1/kg
  const Lanes normal_mass = select(kn > zero, splat(1.0) / select(kn > zero, kn, splat(1.0)), zero);
  // the tangent block and its inverse (kg)
  const LanesXYZ a1 = cross(ra, t1), a2 = cross(ra, t2), b1 = cross(rb, t1), b2 = cross(rb, t2);
  const LanesXYZ ia1 = times(ia, a1), ia2 = times(ia, a2), ib1 = times(ib, b1), ib2 = times(ib, b2);
  store_points(P.rt1a, a1);
  store_points(P.rt2a, a2);
  store_points(P.rt1b, b1);
  store_points(P.rt2b, b2);
  const Lanes k11 = (mass + dot(a1, ia1)) + dot(b1, ib1);
  const Lanes k22 = (mass + dot(a2, ia2)) + dot(b2, ib2);
  const Lanes k12 = dot(a1, ia2) + dot(b1, ib2);
  const Lanes det = k11 * k22 - k12 * k12;
  // two fixed bodies: no friction
  const LaneMask invertible = live & (det > splat(1.0e-12) * k11 * k22) & (det > zero);
  const Lanes inv = splat(1.0) / select(invertible, det, splat(1.0));
  const Lanes tm11 = select(invertible, k22 * inv, zero), tm12 = select(invertible, -k12 * inv, zero);
  const Lanes tm22 = select(invertible, k11 * inv, zero);
  const Lanes trace = k11 + k22;
  const LaneMask slides = live & (trace > zero);
  const Lanes tangent_mass = select(slides, splat(2.0) / select(slides, trace, splat(1.0)), zero);
  const Lanes kn_live = select(live, kn, zero);
  std::memcpy(P.kn, &kn_live, sizeof kn_live);
  std::memcpy(P.tm11, &tm11, sizeof tm11);
  std::memcpy(P.tm12, &tm12, sizeof tm12);
  std::memcpy(P.tm22, &tm22, sizeof tm22);
  std::memcpy(P.tangent_mass, &tangent_mass, sizeof tangent_mass);
  const Lanes base = select(live, load_lanes(c.base_separation[m].data()), zero);
  std::memcpy(P.base, &base, sizeof base);
  const LanesXYZ sa = load_points(c.sep_anchor_a[m], live), sb = load_points(c.sep_anchor_b[m], live);
  store_points(P.ra, sa);
  store_points(P.rb, sb);
  for (int k = 0; k < npts; ++k) {
    c.normal_mass[m][k] = normal_mass[k];
    if (approach) approach_point(st, c, m, k, a, b, P.arm_a[k], P.arm_b[k], P.ra[k], P.rb[k], n);
  }
  // I_a⁻¹(r_a × t1), I_a⁻¹(r_a × t2), I_b⁻¹ alike (1/(kg·m)), for the couplings
  alignas(32) double inv_rt[4][3][4];  // [which][axis][point]
  const LanesXYZ* rows[4] = {&ia1, &ia2, &ib1, &ib2};
  for (int q = 0; q < 4; ++q) {
    std::memcpy(inv_rt[q][0], &rows[q]->x, sizeof(Lanes));
    std::memcpy(inv_rt[q][1], &rows[q]->y, sizeof(Lanes));
    std::memcpy(inv_rt[q][2], &rows[q]->z, sizeof(Lanes));
  }
  auto inv_rt_at = [&](int q, int j) { return Vec3{inv_rt[q][0][j], inv_rt[q][1][j], inv_rt[q][2][j]}; };
  // friction's coupling between points i > j: δ_ab (1/m_a + 1/m_b) + (r_a,i × t_a)·
  // I_a⁻¹(r_a,j × t_b) + (b likewise), for the directions a, b of t1, t2
  for (int i = 1; i < c.points[m]; ++i) {
    for (int j = 0; j < i; ++j) {
      const auto& pi = row.point[i];
      auto& cp = row.tangent_coupling[i * (i - 1) / 2 + j];
      const Vec3 ja1 = inv_rt_at(0, j), ja2 = inv_rt_at(1, j), jb1 = inv_rt_at(2, j), jb2 = inv_rt_at(3, j);
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
// between two dynamic bodies and for contacts with a static or kinematic body (twice as
// stiff), both for shapes of STIFFNESS_LENGTH and larger; a contact between smaller shapes
// is stiffer by sqrt(STIFFNESS_LENGTH / size) (the smaller shape's size); every one capped
// at a quarter of the substep rate as config's are. The contact's scale (SCALE_LENGTH) sets its
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
    double row_hertz = fixed ? static_hertz(hertz, hertz_cap) : hertz;  // Hz: as config's
    bool own = false;  // the row's own soft constraint (rare): a small pair
    const double size = std::min(c.shape_size[c.shape_a[m]], c.shape_size[c.shape_b[m]]);  // m
    if (size < C::STIFFNESS_LENGTH && stiffer) {
      // a small pair, and room under the cap: stiffer
      const double stiff = std::min(hertz * std::sqrt(C::STIFFNESS_LENGTH / size), hertz_cap);
      row_hertz = fixed ? static_hertz(stiff, hertz_cap) : stiff;
      own = true;
    }
    const double scale = c.scale[m];
    row.max_push = -C::CONTACT_PUSH_MAX_VELOCITY * (scale < 1.0 ? std::sqrt(scale) : 1.0);
    row.deep = -scale * C::DEEP_OVERLAP;
    row.touch = scale * C::LINEAR_SLOP;
    row.friction = c.friction[m];
    row.friction_load = 0.0;  // (friction_loads: only while a heavy body rests on a light one)
    if constexpr (D == 3) {
      // the world tensors at the step's start, as transform_shapes made them (at a time of
      // impact's, the bodies turned by ω t, as the time of impact turns them, a slender
      // body spinning near the turn bound was far from where the substeps turn it: random
      // heaps of every shape kind blew up in 2 of 60, a capsule 27 times longer than thick
      // thrown to 40 km/s)
      prepare_points_3d(st, c, m, a, b, ma, mb, c.body_inv_inertia_world[a],
                        c.body_inv_inertia_world[b],
                        kinematic_lever(model, st, a, config.dt),
                        kinematic_lever(model, st, b, config.dt), true);
    } else {
    const double ia = ii[a], ib = ii[b];
    const Vec t = cross(n, 1.0);  // (n_y, −n_x)
    const auto turn_a = kinematic_lever(model, st, a, config.dt);
    const auto turn_b = kinematic_lever(model, st, b, config.dt);
    for (int k = 0; k < npts; ++k) {
      auto& pt = row.point[k];
      Vec ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
      if (ma == 0.0) ra = rotate(turn_a, ra);
      if (mb == 0.0) rb = rotate(turn_b, rb);
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

void begin_turn_watch(const State<3>& st, Contacts<3>& c) {
  for (TurnWatch& watch : c.turn_watch) watch.rows = st.body_q[watch.body];
}

bool mark_turned_bodies(const State<3>& st, Contacts<3>& c) {
  bool any = false;
  for (TurnWatch& watch : c.turn_watch) {
    const int i = watch.body;
    // sin²(φ/2) = 1 - (q·q_rows)² for the turn φ since the rows were made
    const Quat q = st.body_q[i], r = watch.rows;
    const double d = q.w * r.w + q.x * r.x + q.y * r.y + q.z * r.z;
    const bool far = 1.0 - d * d > watch.limit;
    c.body_row_remade[i] = far;
    if (far) watch.rows = q;
    any = any || far;
  }
  return any;
}

std::vector<TurnWatch> turn_watch(const Model<3>& model) {
  std::vector<TurnWatch> watch;
  for (int i = 0; i < model.body_count(); ++i) {
    if (!model.is_dynamic(i)) continue;
    // the weighted turn (1 - I_min / I_max) φ passes ROW_TURN_MAX where sin²(φ/2) passes
    // (ROW_TURN_MAX / (2 (1 - I_min / I_max)))², taking φ as 2 sin(φ/2) (a little early
    // for a large turn); never for a round body, or one within 1 - ROW_TURN_MAX / 2 of it
    const Vec3 I = model.body_moments[i];  // kg·m²
    const double spread = 1.0 - std::min({I.x, I.y, I.z}) / std::max({I.x, I.y, I.z});
    const double half = constants::ROW_TURN_MAX / (2.0 * spread);
    if (spread > 0.0 && half < 1.0) watch.push_back({i, half * half});
  }
  return watch;
}

void refresh_turned_rows(const Model<3>& model, const State<3>& st, Contacts<3>& c,
                         const Config& config, Span manifolds) {
  const auto& im = model.body_inv_mass;
  for (std::int64_t m = manifolds.first; m < manifolds.last; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    if (!(c.body_row_remade[a] || c.body_row_remade[b])) continue;
    // the same arms (the contact points stay where the step's start found them) and normal
    prepare_points_3d(st, c, m, a, b, im[a], im[b], c.body_inv_inertia_world[a],
                      c.body_inv_inertia_world[b], kinematic_lever(model, st, a, config.dt),
                      kinematic_lever(model, st, b, config.dt), false);
    prepare_blocks_3d(c.solver_row[m], c.points[m]);
  }
}

template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, const Config&);
template void prepare_contacts(const Model<3>&, const State<3>&, Contacts<3>&, const Config&);
template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, const Config&, Span);
template void prepare_contacts(const Model<3>&, const State<3>&, Contacts<3>&, const Config&, Span);

}  // namespace rbsim
