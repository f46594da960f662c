// 3D worlds built in C++ for the solver's stage tests, without the collision side: bodies
// with full inertia tensors, and manifolds written by hand into the contact store
// (normal, points, lever arms, separation), as update_manifolds<3> would leave them.
//
//   Builder3 s;
//   int a = s.body({0, 1, 0}, 2.0, Sym3{...}, q, v, w);   // dynamic: mass, body-frame tensor
//   int g = s.fixed({0, 0, 0});                           // static
//   World<3>& w = s.finish();                             // dt 1/60 s, 4 substeps
//   s.manifold(a, g, {0, 1, 0}, {contact points, world frame}, friction, restitution);
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include "rbsim/world.hpp"

namespace rbsim::test {

// The inverse of a symmetric 3×3 matrix (by its cofactors).
inline Sym3 inverse(const Sym3& m) {
  const double c_xx = m.yy * m.zz - m.yz * m.yz;
  const double c_xy = m.xz * m.yz - m.xy * m.zz;
  const double c_xz = m.xy * m.yz - m.xz * m.yy;
  const double det = m.xx * c_xx + m.xy * c_xy + m.xz * c_xz;
  const double c_yy = m.xx * m.zz - m.xz * m.xz;
  const double c_yz = m.xy * m.xz - m.xx * m.yz;
  const double c_zz = m.xx * m.yy - m.xy * m.xy;
  const double k = 1.0 / det;
  return {k * c_xx, k * c_yy, k * c_zz, k * c_xy, k * c_xz, k * c_yz};
}

// The rotation matrix of a unit quaternion, rows R[i][j].
struct Mat3 {
  double r[3][3];
};
inline Mat3 matrix(Quat q) {
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  return {{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
           {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
           {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
}
// R M Rᵀ v, written out with the matrix (independent of math.hpp's world_tensor).
inline Vec3 world_apply(Quat q, const Sym3& m, Vec3 v) {
  const Mat3 R = matrix(q);
  const double u[3] = {v.x, v.y, v.z};
  double b[3], c[3], out[3];
  for (int i = 0; i < 3; ++i) b[i] = R.r[0][i] * u[0] + R.r[1][i] * u[1] + R.r[2][i] * u[2];
  const double M[3][3] = {{m.xx, m.xy, m.xz}, {m.xy, m.yy, m.yz}, {m.xz, m.yz, m.zz}};
  for (int i = 0; i < 3; ++i) c[i] = M[i][0] * b[0] + M[i][1] * b[1] + M[i][2] * b[2];
  for (int i = 0; i < 3; ++i) out[i] = R.r[i][0] * c[0] + R.r[i][1] * c[1] + R.r[i][2] * c[2];
  return {out[0], out[1], out[2]};
}

// A unit quaternion turning by angle (rad) about axis.
inline Quat about(Vec3 axis, double angle) {
  const Vec3 u = (1.0 / length(axis)) * axis;
  const double s = std::sin(0.5 * angle);
  return {std::cos(0.5 * angle), s * u.x, s * u.y, s * u.z};
}

class Builder3 {
 public:
  World<3> world;

  Builder3() { world.model.gravity = {0.0, 0.0, 0.0}; }

  // A dynamic body at COM x (m) of mass (kg) and body-frame inertia tensor (kg·m²),
  // turned by q, moving at v (m/s) and ω (rad/s, world). Its L = R I_b Rᵀ ω.
  int body(Vec3 x, double mass, const Sym3& inertia, Quat q = {}, Vec3 v = {}, Vec3 w = {}) {
    Model<3>& m = world.model;
    m.body_type.push_back(BodyType::Dynamic);
    m.body_mass.push_back(mass);
    m.body_inertia.push_back(inertia);
    m.body_inv_mass.push_back(1.0 / mass);
    m.body_inv_inertia.push_back(inverse(inertia));
    push_common(x, q, v);
    State<3>& s = world.state;
    s.body_l.push_back(world_apply(q, inertia, w));
    s.body_w.push_back(Dim<3>::apply_inv_inertia(m.body_inv_inertia.back(), q, s.body_l.back()));
    return m.body_count() - 1;
  }

  // A static body at x (m).
  int fixed(Vec3 x) {
    Model<3>& m = world.model;
    constexpr double inf = std::numeric_limits<double>::infinity();
    m.body_type.push_back(BodyType::Static);
    m.body_mass.push_back(inf);
    m.body_inertia.push_back(Sym3{inf, inf, inf, 0, 0, 0});
    m.body_inv_mass.push_back(0.0);
    m.body_inv_inertia.push_back(Sym3{});
    push_common(x, Quat{}, {});
    world.state.body_l.push_back({});
    world.state.body_w.push_back({});
    return m.body_count() - 1;
  }

  // Settings as the front makes them, storage for 16 manifolds.
  World<3>& finish(double dt = 1.0 / 60.0, int substeps = 4) {
    Config& cfg = world.config;
    cfg.dt = dt;
    cfg.substeps = substeps;
    set_contact_softness(cfg);
    world.model.has_shapes = true;
    world.contacts.allocate(world.model.body_count(), 1, 1, 16);
    return world;
  }

  // A manifold between bodies a and b with normal n (from b towards a) and contact points
  // p (world, m) at separation sep (m), as the narrowphase would leave it. Returns its index.
  std::int64_t manifold(int a, int b, Vec3 n, const std::vector<Vec3>& p, double friction,
                        double restitution, double sep = 0.0) {
    Contacts<3>& c = world.contacts;
    const std::int64_t m = c.count.manifolds++;
    c.body_a[m] = a;
    c.body_b[m] = b;
    c.shape_a[m] = c.shape_b[m] = 0;
    c.key[m] = m;
    c.normal[m] = n;
    c.points[m] = static_cast<std::int32_t>(p.size());
    c.friction[m] = friction;
    c.restitution[m] = restitution;
    c.scale[m] = 1.0;
    c.carried[m] = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
      const Vec3 ra = p[k] - world.state.body_x[a], rb = p[k] - world.state.body_x[b];
      c.anchor_a[m][k] = c.sep_anchor_a[m][k] = ra;
      c.anchor_b[m][k] = c.sep_anchor_b[m][k] = rb;
      c.base_separation[m][k] = sep - dot(n, ra - rb);
      c.ref_separation[m][k] = sep;
      c.feature[m][k] = static_cast<std::int64_t>(k);
    }
    return m;
  }

  // The rows, the solve order, the friction loads and zero body motion: what a step's
  // collide leaves.
  void prepare() {
    World<3>& w = world;
    world_inertia(w.model, w.state, w.contacts, Span{0, w.model.body_count()});
    prepare_contacts(w.model, w.state, w.contacts, w.config);
    w.contacts.count.shock_count = support_order(w.model, w.contacts);
    friction_loads(w.model, w.state, w.contacts, w.contacts.count.shock_count,
                   w.config.dt / w.config.substeps);
    for (auto& d : w.contacts.body_delta) d = BodyDelta<3>{};
  }

 private:
  void push_common(Vec3 x, Quat q, Vec3 v) {
    Model<3>& m = world.model;
    m.body_com.push_back({});
    m.body_axes.push_back({});
    m.body_moments.push_back({});
    m.body_force.push_back({});
    m.body_force_arm.push_back({});
    m.body_torque.push_back({});
    State<3>& s = world.state;
    s.body_x.push_back(x);
    s.body_q.push_back(q);
    s.body_v.push_back(v);
  }
};

// The substep length (s).
inline double substep(const World<3>& w) { return w.config.dt / w.config.substeps; }

// Relative velocity (m/s) of manifold m's point k: a's material point against b's.
inline Vec3 point_velocity3(const World<3>& w, std::int64_t m, int k) {
  const auto& c = w.contacts;
  const int a = c.body_a[m], b = c.body_b[m];
  const Vec3 va = w.state.body_v[a] + cross(w.state.body_w[a], c.anchor_a[m][k]);
  const Vec3 vb = w.state.body_v[b] + cross(w.state.body_w[b], c.anchor_b[m][k]);
  return va - vb;
}

}  // namespace rbsim::test
