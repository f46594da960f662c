// Worlds in space built in C++ for the 3D collision tests: bodies with one shape each
// (sphere, box, capsule, convex hull, plane), their mass and inertia, the run's settings
// as the Python front makes them, and the collision stages of a step (transform, pairs,
// manifolds) as World::collide runs them.
//
//   SceneBuilder3 s;
//   s.plane({0, 1, 0}, 0.0);                          // the static ground y <= 0
//   int box = s.box({0, 0.5, 0}, {0.5, 0.5, 0.5}, 1.0);  // a 1 m box of 1 kg on it
//   World<3>& w = s.finish();                         // dt 1/60 s, 4 substeps
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/world.hpp"

namespace rbsim::test {

struct Material3 {
  double friction = 0.6;
  double restitution = 0.0;
};

class SceneBuilder3 {
 public:
  World<3> world;

  SceneBuilder3() { world.model.gravity = {0.0, -9.81, 0.0}; }

  // A body at COM x (m), turned by q, of mass (kg) with principal moments (kg·m²) along
  // its body axes; mass 0 makes it static. Returns its index.
  int body(Vec3 x, double mass, Vec3 moments, Quat q = {}, Vec3 v = {}, Vec3 w = {}) {
    Model<3>& m = world.model;
    State<3>& s = world.state;
    const bool dynamic = mass > 0.0;
    constexpr double inf = std::numeric_limits<double>::infinity();
    m.body_type.push_back(dynamic ? BodyType::Dynamic : BodyType::Static);
    m.body_mass.push_back(dynamic ? mass : inf);
    m.body_inertia.push_back(dynamic ? Sym3{moments.x, moments.y, moments.z} : Sym3{inf, inf, inf});
    m.body_inv_mass.push_back(dynamic ? 1.0 / mass : 0.0);
    m.body_inv_inertia.push_back(dynamic ? Sym3{1.0 / moments.x, 1.0 / moments.y, 1.0 / moments.z}
                                         : Sym3{});
    m.body_com.push_back({});
    m.body_axes.push_back({});
    m.body_moments.push_back(dynamic ? moments : Vec3{inf, inf, inf});
    m.body_force.push_back({});
    m.body_force_arm.push_back({});
    m.body_torque.push_back({});
    s.body_x.push_back(x);
    s.body_q.push_back(q);
    s.body_v.push_back(dynamic ? v : Vec3{});
    s.body_w.push_back(dynamic ? w : Vec3{});
    const Vec3 l = dynamic ? rotate(q, Sym3{moments.x, moments.y, moments.z} * inv_rotate(q, w))
                           : Vec3{};
    s.body_l.push_back(l);
    return m.body_count() - 1;
  }

  // A ball of radius r (m) and mass (kg; 0: static).
  int sphere(Vec3 x, double r, double mass, Material3 mat = {}, Vec3 v = {}) {
    const double k = 0.4 * mass * r * r;
    const int i = body(x, mass, {k, k, k}, {}, v);
    shape(i, ShapeKind::Sphere, {Vec3{}}, r, mat);
    return i;
  }

  // A box of half extents h (m) and mass (kg; 0: static), turned by q; its corners in
  // BOX_SIGNS order (corner k has the sign of bit 0, 1, 2 of k along x, y, z).
  int box(Vec3 x, Vec3 h, double mass, Material3 mat = {}, Quat q = {}, Vec3 v = {},
          Vec3 w = {}) {
    const double f = mass / 3.0;
    const int i = body(x, mass,
                       {f * (h.y * h.y + h.z * h.z), f * (h.x * h.x + h.z * h.z),
                        f * (h.x * h.x + h.y * h.y)},
                       q, v, w);
    std::vector<Vec3> corners;
    for (int k = 0; k < 8; ++k)
      corners.push_back({k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z});
    shape(i, ShapeKind::Box, corners, 0.0, mat);
    return i;
  }

  // A capsule from a to b (m, body frame about the COM) of radius r.
  int capsule(Vec3 x, Vec3 a, Vec3 b, double r, double mass, Material3 mat = {}, Quat q = {}) {
    const double k = 0.4 * mass * r * r + mass * dot(b - a, b - a) / 12.0;
    const int i = body(x, mass, {k, k, k}, q);
    shape(i, ShapeKind::Capsule, {a, b}, r, mat);
    return i;
  }

  // A convex hull of `verts` (m, body frame about the COM) with its triangles
  // (counter-clockwise seen from outside); inertia that of a ball of its size (tests of
  // collision only).
  int convex(Vec3 x, const std::vector<Vec3>& verts,
             const std::vector<std::array<std::int32_t, 3>>& tris, double mass,
             Material3 mat = {}, Quat q = {}) {
    double r2 = 0.0;
    for (const Vec3& p : verts) r2 = std::max(r2, dot(p, p));
    const double k = 0.4 * mass * r2;
    const int i = body(x, mass, {k, k, k}, q);
    shape(i, ShapeKind::Convex, verts, 0.0, mat, tris);
    return i;
  }

  // A static plane: the solid n·x <= offset (n unit), its body at the origin.
  int plane(Vec3 n, double offset, Material3 mat = {}) {
    const int i = body({}, 0.0, {});
    shape(i, ShapeKind::Plane, {offset * n}, 0.0, mat);
    world.model.normal_local.back() = n;
    return i;
  }

  // Settings as the front makes them, hulls built, storage allocated.
  World<3>& finish(double dt = 1.0 / 60.0, int substeps = 4) {
    Model<3>& m = world.model;
    Config& cfg = world.config;
    cfg.dt = dt;
    cfg.substeps = substeps;
    set_contact_softness(cfg);
    cfg.elastic = std::any_of(m.shape_restitution.begin(), m.shape_restitution.end(),
                              [](double e) { return e > 0.0; });
    m.has_shapes = m.shape_count() >= 2 &&
                   std::any_of(m.body_type.begin(), m.body_type.end(),
                               [](BodyType t) { return t == BodyType::Dynamic; });
    std::string error;
    if (!build_shape_hulls(m, &error)) throw std::runtime_error(error);
    world.allocate();
    return world;
  }

 private:
  void shape(int i, ShapeKind kind, const std::vector<Vec3>& core, double radius, Material3 mat,
             const std::vector<std::array<std::int32_t, 3>>& tris = {}) {
    Model<3>& m = world.model;
    m.shape_body.push_back(i);
    m.shape_kind.push_back(kind);
    m.shape_radius.push_back(radius);
    m.shape_vstart.push_back(m.vertex_count());
    m.shape_vcount.push_back(static_cast<std::int32_t>(core.size()));
    m.shape_fstart.push_back(static_cast<std::int32_t>(m.face_local.size()));
    m.shape_fcount.push_back(static_cast<std::int32_t>(tris.size()));
    m.shape_friction.push_back(mat.friction);
    m.shape_restitution.push_back(mat.restitution);
    for (const Vec3& p : core) {
      m.vertex_local.push_back(p);
      m.normal_local.push_back({});
    }
    m.face_local.insert(m.face_local.end(), tris.begin(), tris.end());
  }
};

// The collision stages of a step in 3D: transform, pairs (growing the store as the step
// does), manifolds. Returns the manifold count.
inline std::int64_t collide3(World<3>& w) {
  const Config& cfg = w.config;
  transform_shapes(w.model, w.state, w.contacts, cfg.dt);
  std::int64_t n_pairs = find_pairs(w.model, w.grid, w.contacts);
  while (n_pairs > w.contacts.capacity()) {
    w.grow(2 * n_pairs);  // the store is made anew: the world geometry too, as in the step
    transform_shapes(w.model, w.state, w.contacts, cfg.dt);
    n_pairs = find_pairs(w.model, w.grid, w.contacts);
  }
  w.contacts.count.pairs = n_pairs;
  update_manifolds(w.model, w.state, w.contacts, w.grid, n_pairs, cfg.friction_rule,
                   cfg.restitution_rule, cfg.dt);
  return w.contacts.count.manifolds;
}

}  // namespace rbsim::test
