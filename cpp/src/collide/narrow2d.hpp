// 2D narrowphase: the contact manifold between two shapes (one pure function per kind
// pair, dispatched from a [kind][kind] table in narrow2d.cpp).
//
// Every shape is a convex core with a radius: a circle is a point core, a segment
// (capsule) a 2-vertex core, a polygon a convex CCW core. Cores are given in world
// coordinates: shape s uses verts[start .. start+count), and norms[i] is the outward unit
// normal of edge i (vertex i to i+1, cyclic); a segment a-b is a 2-vertex polygon whose
// edges are a->b and b->a.
//
// Feature ids stay the same while the same features touch (warm starting). With S = 2^16:
//   clipped point:  (1 + ref_is_b) S² + reference_edge S + incident_vertex
//   vertex-vertex:  3 S² + vertex_of_a S + vertex_of_b
//   circle cases:   0
#pragma once

#include <array>
#include <cstdint>

#include "rbsim/math.hpp"
#include "rbsim/types.hpp"

namespace rbsim {

// A shape's core as the narrowphase sees it.
struct ShapeRef2 {
  ShapeKind kind;
  int start;      // first vertex in verts/norms
  int count;      // vertex count
  double radius;  // m
  // the pair's tolerance scale (constants.hpp, SCALE_LENGTH): the reference face's
  // tolerance and a segment's skin are taken times the smaller of the two shapes'
  double scale = 1.0;
};

struct Manifold2 {
  Vec2 normal;                        // unit, from shape b towards shape a
  std::array<Vec2, 2> point;          // m, midway between the two surfaces
  std::array<double, 2> separation;   // m, signed (negative = overlap), radii included
  std::array<std::int64_t, 2> id;     // feature ids
};

// Manifold between shapes a and b; returns the point count 0, 1 or 2 (only those rows of
// out are written). Points farther apart than `speculative` (m) are dropped.
int collide2d(const ShapeRef2& a, const ShapeRef2& b, const Vec2* verts, const Vec2* norms,
              double speculative, Manifold2& out);

// Manifold between shapes a and b with a given reference face: edge `face` of a polygon
// (b's if ref_is_b, else a's) against the other shape (any kind), whatever the separating
// axes say; 0, 1 or 2 points as collide2d gives them, with its feature ids. For a contact
// that must not take the axis the separating axes would (manifold.cpp: a static polygon's
// face that another static shape covers).
int collide_on_face(const ShapeRef2& a, const ShapeRef2& b, int ref_is_b, int face,
                    const Vec2* verts, const Vec2* norms, double speculative, Manifold2& out);

}  // namespace rbsim
