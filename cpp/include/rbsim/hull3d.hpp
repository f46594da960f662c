// Convex hull topology for the 3D narrowphase: polygon faces (coplanar triangles merged),
// their outward normals and the hull's unique edges, built once per convex shape in its
// body frame from the vertices and triangles the Python front provides (the resolved
// Shape.vertices and Shape.faces: triangles counter-clockwise seen from outside).
//
// Storage is flat (one face's loop is face_vertex[face_start[f] .. face_start[f+1])), so
// that the engine can keep every hull of a model in a few arrays; HullView is the
// non-owning view the narrowphase reads. Vertex, face and edge indices are local to the
// hull (0 .. count-1).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "rbsim/math.hpp"

namespace rbsim {

// The most vertices one face may have (the narrowphase's clipping buffers are sized by
// it, so that no call allocates). A 32-sided cylinder's cap has 32.
inline constexpr int HULL_MAX_FACE_VERTICES = 64;

// An edge of a hull: its two vertices, and the face on either side: f0 holds it as
// v0 -> v1 in its counter-clockwise loop, f1 as v1 -> v0.
struct HullEdge {
  std::int32_t v0 = 0, v1 = 0;
  std::int32_t f0 = 0, f1 = 0;
};

// What the narrowphase reads of a hull's topology (pointers into a Hull3 or the model's
// flat arrays; nothing is owned).
struct HullView {
  int vertex_count = 0;
  int face_count = 0;
  int edge_count = 0;
  const std::int32_t* face_start = nullptr;   // (F+1,) loop of face f: [start[f], start[f+1])
  const std::int32_t* face_vertex = nullptr;  // loops: vertex indices, CCW seen from outside
  const std::int32_t* face_edge = nullptr;    // parallel to face_vertex: the edge index of
                                              // loop edge k (vertex k -> vertex k+1)
  const std::int32_t* face_first = nullptr;   // (F,) each loop's first vertex
  const HullEdge* edge = nullptr;             // (E,)
  // m: the most a face's vertex lies off the plane of its normal through its loop's first
  // vertex (coplanar triangles are merged within a tolerance, and a face's normal is
  // their area-weighted mean)
  double flatness = 0.0;
};

// What the narrowphase's bounds read of a hull's world vertices (made once per step by
// the transform stage, for every pair the hull is in; hull_spread): their mean (m, a
// point inside the hull) and the largest |v|_1 of them (m, for the round-off allowed
// a bound against the hull's face planes).
struct HullSpread {
  Vec3 mean{};
  double extent = 0.0;
};
// The HullSpread of the points v[0 .. count) (count >= 1), summed in order.
inline HullSpread hull_spread(const Vec3* v, int count) {
  Vec3 sum{};
  double extent = 0.0;
  for (int j = 0; j < count; ++j) {
    sum += v[j];
    extent = std::max(extent, std::fabs(v[j].x) + std::fabs(v[j].y) + std::fabs(v[j].z));
  }
  return {(1.0 / count) * sum, extent};
}
// Each face's plane offset n_f · o_f (m) into offset[0 .. F): n_f its world normal (fn), o_f
// the first vertex of its loop (v, world).
inline void hull_face_offsets(const HullView& h, const Vec3* v, const Vec3* fn, double* offset) {
  for (int f = 0; f < h.face_count; ++f) offset[f] = dot(fn[f], v[h.face_first[f]]);
}

// A hull's topology and body-frame geometry, owning its arrays.
struct Hull3 {
  std::vector<Vec3> vertex;             // (V,) m, body frame
  std::vector<Vec3> face_normal;        // (F,) outward unit normals, body frame
  std::vector<std::int32_t> face_start;  // (F+1,)
  std::vector<std::int32_t> face_vertex;
  std::vector<std::int32_t> face_edge;
  std::vector<std::int32_t> face_first;  // (F,)
  std::vector<HullEdge> edge;           // (E,)
  double flatness = 0.0;                // m (HullView::flatness)

  int face_count() const { return static_cast<int>(face_normal.size()); }
  HullView view() const {
    return {static_cast<int>(vertex.size()), face_count(), static_cast<int>(edge.size()),
            face_start.data(), face_vertex.data(), face_edge.data(), face_first.data(), edge.data(),
            flatness};
  }
};

// The topology of a convex hull from its vertices (m, body frame) and its triangles
// (indices into vertices, counter-clockwise seen from outside). Adjacent triangles whose
// vertices lie within a plane tolerance (1e-9 of the hull's size) of the first one's plane
// are one polygon face; each face's loop starts at its smallest vertex index, so the
// result depends only on the input. Returns false, with a message in *error, when the
// triangles do not close a convex surface (an edge not shared by exactly two triangles
// in opposite directions, a face with more than HULL_MAX_FACE_VERTICES vertices, a
// degenerate triangle).
bool build_hull(const std::vector<Vec3>& vertices,
                const std::vector<std::array<std::int32_t, 3>>& triangles, Hull3& hull,
                std::string* error = nullptr);

}  // namespace rbsim
