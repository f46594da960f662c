// Worlds built in C++ for the stage tests: bodies with one shape each (circle, box
// polygon, segment), their mass and inertia, the run's settings as the Python front
// makes them (rbsim/config.py), and the collision stages of a step (World::collide) for
// tests that run the later stages one by one.
//
//   SceneBuilder s;
//   s.ground(-5, 5);                          // a static segment along y = 0
//   int box = s.box({0, 0.5}, 0.5, 0.5, 1.0); // a 1 m box of 1 kg resting on it
//   World<2>& w = s.finish();                 // dt 1/60 s, 4 substeps, gravity −9.81
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/world.hpp"

namespace rbsim::test {

struct Material {
  double friction = 0.6;
  double restitution = 0.0;
};

class SceneBuilder {
 public:
  World<2> world;

  SceneBuilder() { world.model.gravity = {0.0, -9.81}; }

  // A body at COM x (m), turned by angle (rad), of mass (kg) and inertia (kg·m²) about
  // its COM; mass 0 makes it static. Returns its index.
  int body(Vec2 x, double mass, double inertia, double angle = 0.0, Vec2 v = {}, double w = 0.0) {
    Model<2>& m = world.model;
    State<2>& s = world.state;
    const bool dynamic = mass > 0.0;
    constexpr double inf = std::numeric_limits<double>::infinity();
    m.body_type.push_back(dynamic ? BodyType::Dynamic : BodyType::Static);
    m.body_mass.push_back(dynamic ? mass : inf);
    m.body_inertia.push_back(dynamic ? inertia : inf);
    m.body_inv_mass.push_back(dynamic ? 1.0 / mass : 0.0);
    m.body_inv_inertia.push_back(dynamic ? 1.0 / inertia : 0.0);
    m.body_com.push_back({});
    m.body_force.push_back({});
    m.body_force_arm.push_back({});
    m.body_torque.push_back(0.0);
    s.body_x.push_back(x);
    s.body_q.push_back({std::cos(angle), std::sin(angle)});
    s.body_angle.push_back(angle);
    s.body_v.push_back(dynamic ? v : Vec2{});
    s.body_w.push_back(dynamic ? w : 0.0);
    return m.body_count() - 1;
  }

  // A ball of radius r (m) and mass (kg; 0: static), I = m r² / 2.
  int circle(Vec2 x, double r, double mass, Material mat = {}, Vec2 v = {}, double w = 0.0) {
    const int i = body(x, mass, 0.5 * mass * r * r, 0.0, v, w);
    shape(i, ShapeKind::Circle, {Vec2{}}, r, mat);
    return i;
  }

  // A box of half extents hw, hh (m) and mass (kg; 0: static), I = m (w² + h²) / 12.
  int box(Vec2 x, double hw, double hh, double mass, Material mat = {}, double angle = 0.0,
          Vec2 v = {}, double w = 0.0) {
    const double inertia = mass * (4.0 * hw * hw + 4.0 * hh * hh) / 12.0;
    const int i = body(x, mass, inertia, angle, v, w);
    shape(i, ShapeKind::Polygon, {{-hw, -hh}, {hw, -hh}, {hw, hh}, {-hw, hh}}, 0.0, mat);
    return i;
  }

  // A static segment from a to b (m), its body at the midpoint.
  int segment(Vec2 a, Vec2 b, Material mat = {}, double radius = 0.0) {
    const Vec2 mid = 0.5 * (a + b);
    const int i = body(mid, 0.0, 0.0);
    shape(i, ShapeKind::Segment, {a - mid, b - mid}, radius, mat);
    return i;
  }

  // A dynamic capsule along x about its COM x: core half length `half`, radius r (m), of
  // mass (kg) and inertia (kg·m²).
  int capsule(Vec2 x, double half, double r, double mass, double inertia, Material mat = {}) {
    const int i = body(x, mass, inertia);
    shape(i, ShapeKind::Segment, {{-half, 0.0}, {half, 0.0}}, r, mat);
    return i;
  }

  // Static ground: the segment y = 0 from x0 to x1 (m).
  int ground(double x0 = -10.0, double x1 = 10.0, Material mat = {}) {
    return segment({x0, 0.0}, {x1, 0.0}, mat);
  }

  // Settings as the front makes them, storage allocated: the world ready to step.
  World<2>& finish(double dt = 1.0 / 60.0, int substeps = 4) {
    Model<2>& m = world.model;
    Config& cfg = world.config;
    cfg.dt = dt;
    cfg.substeps = substeps;
    set_contact_softness(cfg);
    cfg.elastic = std::any_of(m.shape_restitution.begin(), m.shape_restitution.end(),
                              [](double e) { return e > 0.0; });
    const bool any_dynamic =
        std::any_of(m.body_type.begin(), m.body_type.end(),
                    [](BodyType t) { return t == BodyType::Dynamic; });
    m.has_shapes = m.shape_count() >= 2 && any_dynamic;
    m.has_forces = false;
    for (int i = 0; i < m.body_count(); ++i)
      if (m.body_force[i].x != 0.0 || m.body_force[i].y != 0.0 || m.body_torque[i] != 0.0)
        m.has_forces = true;
    world.allocate();
    return world;
  }

 private:
  // One shape on body i: its core in the body frame about the COM and the outward
  // normal of each edge (i -> i+1; a segment's two edges are a->b and b->a).
  void shape(int i, ShapeKind kind, const std::vector<Vec2>& core, double radius, Material mat) {
    Model<2>& m = world.model;
    m.shape_body.push_back(i);
    m.shape_kind.push_back(kind);
    m.shape_radius.push_back(radius);
    m.shape_vstart.push_back(m.vertex_count());
    m.shape_vcount.push_back(static_cast<std::int32_t>(core.size()));
    m.shape_friction.push_back(mat.friction);
    m.shape_restitution.push_back(mat.restitution);
    const int n = static_cast<int>(core.size());
    for (int k = 0; k < n; ++k) {
      m.vertex_local.push_back(core[k]);
      if (n == 1) {
        m.normal_local.push_back({});
        continue;
      }
      const Vec2 e = core[(k + 1) % n] - core[k];
      m.normal_local.push_back((1.0 / length(e)) * Vec2{e.y, -e.x});
    }
  }
};

// The collision stages of a step (World::collide): transform, pairs, manifolds, rows,
// support order and friction loads. Returns the manifold count.
inline std::int64_t collide(World<2>& w) {
  const Config& cfg = w.config;
  transform_shapes(w.model, w.state, w.contacts, cfg.dt);
  const std::int64_t n_pairs = find_pairs(w.model, w.grid, w.contacts);
  w.contacts.count.pairs = n_pairs;
  update_manifolds(w.model, w.state, w.contacts, w.grid, n_pairs, cfg.friction_rule,
                   cfg.restitution_rule, cfg.dt);
  prepare_contacts(w.model, w.state, w.contacts, cfg);
  w.contacts.count.shock_count = support_order(w.model, w.contacts);
  friction_loads(w.model, w.state, w.contacts, w.contacts.count.shock_count, cfg.dt / cfg.substeps);
  for (auto& d : w.contacts.body_delta) d = BodyDelta<2>{};
  return w.contacts.count.manifolds;
}

// The substep length (s) of the world's settings.
inline double substep(const World<2>& w) { return w.config.dt / w.config.substeps; }

// Relative normal velocity (m/s) at point k of manifold m, < 0 approaching.
inline double point_normal_velocity(const World<2>& w, std::int64_t m, int k) {
  const auto& c = w.contacts;
  const int a = c.body_a[m], b = c.body_b[m];
  const Vec2 va = w.state.body_v[a] + cross(w.state.body_w[a], c.anchor_a[m][k]);
  const Vec2 vb = w.state.body_v[b] + cross(w.state.body_w[b], c.anchor_b[m][k]);
  return dot(va - vb, c.normal[m]);
}

// Whether two states are the same to the bit.
inline bool same_bits(const State<2>& a, const State<2>& b) {
  auto eq = [](const auto& x, const auto& y) {
    return x.size() == y.size() &&
           std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0;
  };
  return eq(a.body_x, b.body_x) && eq(a.body_q, b.body_q) && eq(a.body_angle, b.body_angle) &&
         eq(a.body_v, b.body_v) && eq(a.body_w, b.body_w);
}

}  // namespace rbsim::test
