// Convex hull topology: triangles merged into polygon faces, face loops, unique edges
// (see hull3d.hpp). Runs once per convex shape when a model is built; it allocates.
#include "rbsim/hull3d.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

namespace rbsim {
namespace {

// Vertices within this fraction of the hull's size (its bounding box diagonal) of a
// face's plane are on that face: far above double round-off of coplanar input (1e-16),
// far below any facet qhull keeps apart.
constexpr double PLANE_TOLERANCE = 1.0e-9;

bool fail(std::string* error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

}  // namespace

bool build_hull(const std::vector<Vec3>& vertices,
                const std::vector<std::array<std::int32_t, 3>>& triangles, Hull3& hull,
                std::string* error) {
  hull = Hull3{};
  const int nv = static_cast<int>(vertices.size());
  const int nt = static_cast<int>(triangles.size());
  if (nv < 4 || nt < 4) return fail(error, "a hull needs at least 4 vertices and 4 triangles");
  Vec3 lo = vertices[0], hi = vertices[0];
  for (const Vec3& v : vertices) {
    lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
    hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
  }
  const double size = length(hi - lo);  // m
  const double tol = PLANE_TOLERANCE * size;

  // directed edge (u, v) -> the triangle holding it
  std::map<std::pair<int, int>, int> owner;
  std::vector<Vec3> tri_normal(nt);
  for (int t = 0; t < nt; ++t) {
    const auto& tri = triangles[t];
    for (int k = 0; k < 3; ++k)
      if (tri[k] < 0 || tri[k] >= nv) return fail(error, "triangle index out of range");
    const Vec3 c = cross(vertices[tri[1]] - vertices[tri[0]], vertices[tri[2]] - vertices[tri[0]]);
    const double area2 = length(c);
    if (!(area2 > tol * size)) return fail(error, "degenerate triangle " + std::to_string(t));
    tri_normal[t] = (1.0 / area2) * c;
    for (int k = 0; k < 3; ++k) {
      const auto key = std::make_pair(tri[k], tri[(k + 1) % 3]);
      if (!owner.emplace(key, t).second)
        return fail(error, "edge " + std::to_string(key.first) + "-" + std::to_string(key.second) +
                               " is used twice in the same direction");
    }
  }
  for (const auto& [key, t] : owner)
    if (!owner.count({key.second, key.first}))
      return fail(error, "the triangles do not close: edge " + std::to_string(key.first) + "-" +
                             std::to_string(key.second) + " has no opposite");

  // flood fill: triangles across an edge that lie in the seed triangle's plane
  std::vector<int> face_of(nt, -1);
  std::vector<std::vector<int>> groups;
  for (int seed = 0; seed < nt; ++seed) {
    if (face_of[seed] >= 0) continue;
    const int f = static_cast<int>(groups.size());
    const Vec3 n = tri_normal[seed];
    const double d = dot(n, vertices[triangles[seed][0]]);
    groups.push_back({seed});
    face_of[seed] = f;
    for (std::size_t i = 0; i < groups[f].size(); ++i) {
      const auto& tri = triangles[groups[f][i]];
      for (int k = 0; k < 3; ++k) {
        const int u = tri[(k + 1) % 3], v = tri[k];
        const int t = owner.at({u, v});
        if (face_of[t] >= 0 || dot(tri_normal[t], n) <= 0.0) continue;
        bool flat = true;
        for (int j = 0; j < 3; ++j) flat = flat && std::fabs(dot(n, vertices[triangles[t][j]]) - d) <= tol;
        if (!flat) continue;
        face_of[t] = f;
        groups[f].push_back(t);
      }
    }
  }

  // each face's boundary: the directed edges whose opposite lies in another face
  hull.vertex = vertices;
  hull.face_start.push_back(0);
  std::map<std::pair<int, int>, int> edge_face;  // directed boundary edge -> face
  for (int f = 0; f < static_cast<int>(groups.size()); ++f) {
    std::map<int, int> next;
    Vec3 area{};
    for (int t : groups[f]) {
      const auto& tri = triangles[t];
      area += cross(vertices[tri[1]] - vertices[tri[0]], vertices[tri[2]] - vertices[tri[0]]);
      for (int k = 0; k < 3; ++k) {
        const int u = tri[k], v = tri[(k + 1) % 3];
        if (face_of[owner.at({v, u})] == f) continue;
        if (!next.emplace(u, v).second)
          return fail(error, "face " + std::to_string(f) + " is not a simple polygon");
      }
    }
    const int start = next.begin()->first;  // smallest vertex index
    int u = start, count = 0;
    do {
      hull.face_vertex.push_back(u);
      edge_face[{u, next.at(u)}] = f;
      u = next.at(u);
      ++count;
    } while (u != start && count <= static_cast<int>(next.size()));
    if (u != start || count != static_cast<int>(next.size()))
      return fail(error, "face " + std::to_string(f) + "'s boundary is not one loop");
    if (count > HULL_MAX_FACE_VERTICES)
      return fail(error, "face " + std::to_string(f) + " has more than " +
                             std::to_string(HULL_MAX_FACE_VERTICES) + " vertices");
    hull.face_start.push_back(static_cast<std::int32_t>(hull.face_vertex.size()));
    hull.face_first.push_back(start);
    const Vec3 n = (1.0 / length(area)) * area;
    hull.face_normal.push_back(n);
    const int s = hull.face_start[f], e = hull.face_start[f + 1];
    for (int k = s + 1; k < e; ++k)
      hull.flatness = std::max(hull.flatness, std::fabs(dot(n, vertices[hull.face_vertex[k]] - vertices[hull.face_vertex[s]])));
  }

  // outward: the vertices' centroid lies inside every face (triangles given clockwise
  // would turn every normal inwards and still close)
  Vec3 centroid{};
  for (const Vec3& v : vertices) centroid += v;
  centroid = (1.0 / nv) * centroid;
  for (int f = 0; f < hull.face_count(); ++f)
    if (!(dot(hull.face_normal[f], centroid - vertices[hull.face_vertex[hull.face_start[f]]]) < 0.0))
      return fail(error, "face " + std::to_string(f) + " faces inwards (triangles not counter-clockwise from outside)");

  // unique edges, numbered in the order the face loops first meet them
  std::map<std::pair<int, int>, int> edge_index;  // (min, max) -> edge
  hull.face_edge.resize(hull.face_vertex.size());
  for (int f = 0; f < hull.face_count(); ++f) {
    const int s = hull.face_start[f], e = hull.face_start[f + 1];
    for (int k = s; k < e; ++k) {
      const int u = hull.face_vertex[k];
      const int v = hull.face_vertex[k + 1 < e ? k + 1 : s];
      const auto key = std::minmax(u, v);
      auto it = edge_index.find(key);
      if (it == edge_index.end()) {
        const auto other = edge_face.find({v, u});
        if (other == edge_face.end())
          return fail(error, "edge " + std::to_string(u) + "-" + std::to_string(v) +
                                 " borders only one face");
        it = edge_index.emplace(key, static_cast<int>(hull.edge.size())).first;
        hull.edge.push_back({u, v, f, other->second});
      }
      hull.face_edge[k] = it->second;
    }
  }
  return true;
}

}  // namespace rbsim
