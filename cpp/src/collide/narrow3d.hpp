// 3D narrowphase: the contact manifold between two shapes (one pure function per kind
// pair, dispatched from a [kind][kind] table in narrow3d.cpp).
//
// Shapes are given in the WORLD frame for this step (ShapeRef3): a sphere by its centre
// and radius, a capsule by its segment p-q and radius, a box by its centre, axes and half
// extents, a convex hull by its world vertices and face normals plus its topology
// (HullView, built once in the body frame by build_hull), a plane by its unit normal and
// offset (the solid is the half-space n·x <= offset).
//
// A manifold is one normal and up to four points, as in 2D: the unit normal points FROM
// shape b TOWARDS shape a (the impulse +λn acts on a, −λn on b); each point lies midway
// between the two surfaces; its separation (m) is the signed distance between the surfaces
// along the normal (radii included), negative = overlap. Points whose separation exceeds
// `speculative` are dropped.
//
// Feature ids stay the same while the same features touch (warm starting). An id is
//   kind << 60 | ref_is_b << 59 | face << 40 | f1 << 20 | f2
// with kind (FeatureKind below), ref_is_b (the reference face is on the pair function's b),
// face the reference face (box: 2 axis + (outward normal positive), hull: its face index),
// and f1, f2 (each < 2^20) as the kind says. Indices are local to their shape; "a" and "b"
// are the pair function's own arguments (a mirrored pair keeps the ids of the function
// it calls, as in 2D). Sphere cases are 0: one point, nothing to tell apart.
#pragma once

#include <array>
#include <cstdint>

#include "rbsim/hull3d.hpp"
#include "rbsim/math.hpp"
#include "rbsim/types.hpp"

namespace rbsim {

// What a feature id's f1 and f2 name.
enum class FeatureKind : std::int64_t {
  Single = 0,       // one point of a smooth shape (sphere, capsule crossing): f1 = f2 = 0
  Vertex = 1,       // an incident vertex (hull/box corner, capsule end 0 or 1): f1 = vertex
  EdgeSide = 2,     // an incident edge cut by the reference face's side plane: f1 = edge,
                    // f2 = side (the reference loop's edge k, from vertex k to k+1)
  SideSide = 3,     // two side planes meeting on the incident face: f1 < f2 the sides
  EdgeEdge = 4,     // the closest points of an edge of a (f1) and an edge of b (f2)
  CapsuleEnd = 5,   // parallel capsules: f1 = 0/1 end of a, f2 = 0/1 end of b (+1; 0 = none)
};
inline constexpr std::int64_t feature_id(FeatureKind kind, int ref_is_b, int face, int f1,
                                         int f2) {
  return (static_cast<std::int64_t>(kind) << 60) | (static_cast<std::int64_t>(ref_is_b) << 59) |
         (static_cast<std::int64_t>(face) << 40) | (static_cast<std::int64_t>(f1) << 20) |
         static_cast<std::int64_t>(f2);
}

// One shape in the world frame this step. Only the fields of its kind are read.
struct ShapeRef3 {
  ShapeKind kind = ShapeKind::Sphere;  // Sphere .. Plane (the 3D kinds)
  double radius = 0.0;  // m: sphere, capsule (0 for the others)
  // the pair's tolerance scale (constants.hpp, SCALE_LENGTH): the reference face's
  // tolerance is taken times the smaller of the two shapes'
  double scale = 1.0;
  Vec3 center{};               // m: sphere's centre, box's centre
  std::array<Vec3, 3> axes{};  // box: its unit axes in the world (the columns of R)
  Vec3 half{};                 // m: box's half extents along axes
  Vec3 p{}, q{};               // m: capsule's segment ends
  Vec3 normal{};               // plane: unit outward normal (out of the solid)
  double offset = 0.0;         // m: plane: the solid is normal·x <= offset
  const Vec3* verts = nullptr;         // convex: (V,) m, world vertices (hull's order)
  const Vec3* face_normals = nullptr;  // convex: (F,) world outward unit normals
  HullView hull{};                     // convex: topology
  // convex, where the transform stage made them this step (else null, made per pair): its
  // faces' plane offsets (F,; m) and its HullSpread
  const double* face_offsets = nullptr;
  const HullSpread* spread = nullptr;
};

inline ShapeRef3 sphere_ref(Vec3 center, double radius) {
  return {.kind = ShapeKind::Sphere, .radius = radius, .center = center};
}
// A box centred at center (m), turned by the unit quaternion rotation, half extents (m).
inline ShapeRef3 box_ref(Vec3 center, Quat rotation, Vec3 half) {
  return {.kind = ShapeKind::Box,
          .center = center,
          .axes = {rotate(rotation, Vec3{1, 0, 0}), rotate(rotation, Vec3{0, 1, 0}),
                   rotate(rotation, Vec3{0, 0, 1})},
          .half = half};
}
// A box from its 8 world corners (m) in the model's order (corner k has the sign of bit
// 0, 1, 2 of k along the box's x, y, z: rbsim/scene/geometry3d.py BOX_SIGNS).
inline ShapeRef3 box_ref_from_corners(const Vec3* c) {
  const Vec3 e[3] = {0.5 * (c[1] - c[0]), 0.5 * (c[2] - c[0]), 0.5 * (c[4] - c[0])};
  const double h[3] = {length(e[0]), length(e[1]), length(e[2])};
  return {.kind = ShapeKind::Box,
          .center = 0.5 * (c[0] + c[7]),
          .axes = {(1.0 / h[0]) * e[0], (1.0 / h[1]) * e[1], (1.0 / h[2]) * e[2]},
          .half = {h[0], h[1], h[2]}};
}
inline ShapeRef3 capsule_ref(Vec3 p, Vec3 q, double radius) {
  return {.kind = ShapeKind::Capsule, .radius = radius, .p = p, .q = q};
}
inline ShapeRef3 plane_ref(Vec3 normal, double offset) {
  return {.kind = ShapeKind::Plane, .normal = normal, .offset = offset};
}
// verts and face_normals are the hull's, in the world frame, and must outlive the call.
inline ShapeRef3 convex_ref(const Vec3* verts, const Vec3* face_normals, HullView hull) {
  return {.kind = ShapeKind::Convex, .verts = verts, .face_normals = face_normals, .hull = hull};
}

struct Manifold3 {
  Vec3 normal;                       // unit, from shape b towards shape a
  std::array<Vec3, 4> point;         // m, midway between the two surfaces
  std::array<double, 4> separation;  // m, signed (negative = overlap), radii included
  std::array<std::int64_t, 4> id;    // feature ids
};

// Manifold between shapes a and b; returns the point count 0..4 (only those rows of out
// are written; the normal is written whenever a point is). Points farther apart than
// `speculative` (m) are dropped. 2D kinds and plane–plane give 0 points.
// Allocates nothing.
int collide3d(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out);

// Manifold between shapes a and b with a given reference face: face `face` of a box or
// convex hull (b's if ref_is_b, else a's; a box's faces in box_hull()'s order) against
// the other shape (a sphere, capsule, box or hull), whatever the separating axes say; up
// to four points, the normal from b towards a. For a contact that must not take the axis
// the separating axes would (manifold.cpp: a static polytope's face that another static
// shape covers).
int collide_on_face(const ShapeRef3& a, const ShapeRef3& b, int ref_is_b, int face,
                    double speculative, Manifold3& out);

// The box's hull topology (8 corners: corner k has the sign of bit 0, 1, 2 of k on the
// x, y, z axes; faces 2 axis + (normal positive); 12 edges), for boxes taken through
// the convex code path (box–convex) and for tests.
const HullView& box_hull();
// The box's 8 world corners (m) and 6 world face normals, in box_hull()'s order.
void box_geometry(const ShapeRef3& box, Vec3* corners, Vec3* face_normals);

}  // namespace rbsim
