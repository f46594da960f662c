// The model: what does not change while a scene runs (MuJoCo's mjModel). N bodies, S
// shapes, V shape vertices. Body quantities are about the centre of mass; shape geometry
// is in the body frame relative to the centre of mass, so a shape's world vertex is
// x + R(q) vertex_local. A static or kinematic body has zero inverse mass and inertia,
// so the solver treats every body alike.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "hull3d.hpp"
#include "math.hpp"
#include "types.hpp"

namespace rbsim {

template <int D>
struct Model {
  using Vec = typename Dim<D>::Vec;
  using Ang = typename Dim<D>::Ang;
  using Inertia = typename Dim<D>::Inertia;

  std::vector<BodyType> body_type;        // (N,)
  std::vector<double> body_mass;          // (N,) kg; inf if not dynamic
  std::vector<Inertia> body_inertia;      // (N,) kg·m², body frame about the COM
  std::vector<double> body_inv_mass;      // (N,) 1/kg; 0 if not dynamic
  std::vector<Inertia> body_inv_inertia;  // (N,) 1/(kg·m²); 0 if not dynamic
  std::vector<Vec> body_com;              // (N,) m: the COM in the body frame, from the origin
  // 3D only: each body's principal axes (the rotation P from principal to body frame,
  // I_b = P diag(moments) Pᵀ) and principal moments (kg·m²; inf if not dynamic), for the
  // split rotation update
  std::vector<Quat> body_axes;
  std::vector<Vec3> body_moments;
  std::vector<Vec> body_force;            // (N,) N, world frame
  std::vector<Vec> body_force_arm;        // (N,) m, body frame, from the COM
  std::vector<Ang> body_torque;           // (N,) N·m, world frame
  std::vector<std::int32_t> shape_body;   // (S,)
  std::vector<ShapeKind> shape_kind;      // (S,)
  std::vector<double> shape_radius;       // (S,) m (a segment with a radius is a capsule)
  std::vector<std::int32_t> shape_vstart; // (S,) first vertex in vertex_local
  std::vector<std::int32_t> shape_vcount; // (S,) its vertex count
  std::vector<double> shape_friction;     // (S,)
  std::vector<double> shape_restitution;  // (S,)
  std::vector<Vec> vertex_local;          // (V,) m, body frame about the COM
  std::vector<double> shape_reach;        // (S,) m: its farthest vertex from the COM
                                          // (World::allocate, from vertex_local)
  std::vector<double> shape_depth;        // (S,) m: how far in its surface lies from its
                                          // middle, at its thinnest (shape_depth, step.cpp)
  std::vector<Vec> normal_local;          // (V,) outward edge normals (polygons, segments);
                                          // 3D: a plane's outward normal on its one row
  // 3D: box and convex shapes' triangles as the front gives them (indices local to the
  // shape's vertex rows, counter-clockwise seen from outside); empty in 2D
  std::vector<std::array<std::int32_t, 3>> face_local;  // (F,)
  std::vector<std::int32_t> shape_fstart;  // (S,) first triangle in face_local
  std::vector<std::int32_t> shape_fcount;  // (S,) its triangle count (0: none)
  // 3D: built once from them (build_shape_hulls, collide/transform.cpp): a convex shape's
  // topology (polygon faces, unique edges) and body-frame face normals; empty for the
  // other kinds (a box's is box_hull()). shape_hface: first row of its face normals in
  // Contacts::face_world; hull_face_count: the rows of all of them
  std::vector<Hull3> shape_hull;           // (S,)
  std::vector<std::int32_t> shape_hface;   // (S,)
  int hull_face_count = 0;
  // 2D: for a static segment whose end another static segment continues (the two share
  // that end point, and no third does), that neighbour's far end, per end of the segment
  // (world frame, m; NaN where none): a floor or a wall of pieces (World::allocate,
  // find_segment_neighbours). Empty when there are none, and in 3D.
  std::vector<std::array<Vec, 2>> segment_ghost;  // (S,) or empty
  // Faces of static polytopes (2D: polygons without a radius; 3D: boxes and convex hulls)
  // that lie flush against a face of another static shape that covers them wholly (tiles
  // side by side, bricks in a wall), or in 3D lie in a static plane, turned down into it
  // (a wall standing on the ground): inside the solid the two make. Bit f of a shape's
  // mask is its face f (2D: edge f, vertex f to f + 1; 3D: hull face f, a box's in
  // box_hull()'s order; faces past the 64th are never marked). World::allocate,
  // find_covered_faces; empty when no face is covered.
  std::vector<std::uint64_t> shape_covered;  // (S,) or empty
  // And near which corners: where static faces lie flush against a face near one of its
  // corners (a tile beside a deeper one: the deeper one's side, near its top), face f of
  // shape s has bit i of corner_covered[corner_start[s] + f] for the i-th corner of its
  // loop (2D: 0 its edge's first end, 1 its second); a wholly covered face, every one.
  // Shapes with none have no rows (corner_start[s] == corner_start[s + 1]); empty when
  // no face of any shape is covered anywhere.
  std::vector<std::int32_t> corner_start;  // (S + 1,) or empty
  std::vector<std::uint64_t> corner_covered;
  // Who covers them: shape s's neighbours cover[cover_start[s] .. cover_start[s + 1]),
  // each a static shape (a polytope or a plane) and the mask of s's faces it lies against
  // (empty with corner_covered)
  struct Cover {
    std::int32_t shape;
    std::uint64_t faces;
  };
  std::vector<std::int32_t> cover_start;  // (S + 1,) or empty
  std::vector<Cover> cover;
  Vec gravity{};                          // m/s²
  double linear_damping = 0.0;            // 1/s
  double angular_damping = 0.0;           // 1/s
  bool has_forces = false;  // some body carries a constant force or torque
  bool has_shapes = false;  // two bodies have shapes and one is dynamic: contacts are possible

  int body_count() const { return static_cast<int>(body_type.size()); }
  int shape_count() const { return static_cast<int>(shape_body.size()); }
  int vertex_count() const { return static_cast<int>(vertex_local.size()); }
  bool is_dynamic(int i) const { return body_type[i] == BodyType::Dynamic; }
  // m/s²: body i's acceleration from gravity and its constant force (zero for a static
  // or kinematic body), as the integrator gives it
  Vec acceleration(int i) const {
    if (!is_dynamic(i)) return Vec{};
    if (!has_forces) return gravity;
    return gravity + body_inv_mass[i] * body_force[i];
  }
  // m: the least of n · p over shape s's surface with its body at x (m), rotation q: its
  // core's vertices less its radius (the continuous sweep: how far a shape went past an
  // impact; the restitution stage: how far apart two shapes are along a normal)
  double lowest_along(int s, const Vec& x, const typename Dim<D>::Rot& q, const Vec& n) const {
    const int v0 = shape_vstart[s], count = shape_vcount[s];
    double least = count == 0 ? dot(n, x) : std::numeric_limits<double>::infinity();
    for (int k = v0; k < v0 + count; ++k)
      least = std::min(least, dot(n, x + rotate(q, vertex_local[k])));
    return least - shape_radius[s];
  }
};

}  // namespace rbsim
