// collide/hull3d.cpp: hull topology from triangles (coplanar triangles merged into
// polygon faces, loops counter-clockwise from outside, unique edges with their two faces).
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "check.hpp"
#include "rbsim/hull3d.hpp"
#include "collide/narrow3d.hpp"

using namespace rbsim;

namespace {

constexpr double EPS = 1e-12;  // round-off of O(1) lengths

std::vector<Vec3> box_corners(double hx, double hy, double hz) {
  std::vector<Vec3> c;
  for (int k = 0; k < 8; ++k) c.push_back({k & 1 ? hx : -hx, k & 2 ? hy : -hy, k & 4 ? hz : -hz});
  return c;
}

// A box's 12 triangles in an order and split unlike box_hull()'s (as qhull might give).
std::vector<std::array<std::int32_t, 3>> box_triangles() {
  return {{1, 3, 7}, {1, 7, 5}, {0, 4, 6}, {0, 6, 2}, {2, 6, 7}, {2, 7, 3},
          {0, 1, 5}, {0, 5, 4}, {4, 5, 7}, {4, 7, 6}, {0, 2, 3}, {0, 3, 1}};
}

// Newell normal of a loop (its area vector / 2A), to check loops are CCW from outside.
Vec3 loop_normal(const Hull3& h, int f) {
  Vec3 a{};
  const int s = h.face_start[f], e = h.face_start[f + 1];
  for (int k = s + 1; k + 1 < e; ++k)
    a += cross(h.vertex[h.face_vertex[k]] - h.vertex[h.face_vertex[s]],
               h.vertex[h.face_vertex[k + 1]] - h.vertex[h.face_vertex[s]]);
  return (1.0 / length(a)) * a;
}

void check_topology(const Hull3& h) {
  const HullView v = h.view();
  for (int f = 0; f < v.face_count; ++f) {
    const Vec3 n = loop_normal(h, f);
    CHECK_NEAR(dot(n, h.face_normal[f]), 1.0, EPS);  // CCW seen from outside
  }
  for (int e = 0; e < v.edge_count; ++e) {
    const HullEdge& ed = v.edge[e];
    // f0 holds v0 -> v1, f1 holds v1 -> v0
    for (int side = 0; side < 2; ++side) {
      const int f = side == 0 ? ed.f0 : ed.f1;
      const int from = side == 0 ? ed.v0 : ed.v1, to = side == 0 ? ed.v1 : ed.v0;
      bool found = false;
      const int s = v.face_start[f], t = v.face_start[f + 1];
      for (int k = s; k < t; ++k)
        if (v.face_vertex[k] == from && v.face_vertex[k + 1 < t ? k + 1 : s] == to) {
          found = true;
          CHECK(v.face_edge[k] == e);
        }
      CHECK(found);
    }
  }
}

}  // namespace

// A box given as 12 triangles is 6 quads (its faces' two triangles merged), 12 edges,
// each face's loop counter-clockwise from outside, starting at its smallest vertex.
TEST(box_triangles_merge_into_six_quads) {
  Hull3 h;
  std::string error;
  CHECK(build_hull(box_corners(0.5, 1.0, 2.0), box_triangles(), h, &error));
  CHECK(error.empty());
  CHECK(h.face_count() == 6);
  CHECK(h.edge.size() == 12);
  for (int f = 0; f < 6; ++f) {
    CHECK(h.face_start[f + 1] - h.face_start[f] == 4);
    int smallest = 8;
    for (int k = h.face_start[f]; k < h.face_start[f + 1]; ++k) smallest = std::min(smallest, h.face_vertex[k]);
    CHECK(h.face_vertex[h.face_start[f]] == smallest);
    // an axis-aligned unit normal
    const Vec3 n = h.face_normal[f];
    CHECK_NEAR(std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z), 1.0, EPS);
  }
  check_topology(h);
}

// The narrowphase's box topology: faces 2 axis + (normal positive), in that order.
TEST(box_hull_faces_are_numbered_by_axis_and_sign) {
  const HullView& v = box_hull();
  CHECK(v.vertex_count == 8 && v.face_count == 6 && v.edge_count == 12);
  Hull3 h;
  CHECK(build_hull(box_corners(1, 1, 1), box_triangles(), h));
  for (int f = 0; f < 6; ++f) {
    Vec3 a{};
    const int s = v.face_start[f];
    for (int k = s; k < s + 4; ++k) a += h.vertex[v.face_vertex[k]];
    const int axis = f / 2;
    const double sign = f % 2 ? 1.0 : -1.0;
    const double c[3] = {a.x / 4, a.y / 4, a.z / 4};
    CHECK_NEAR(c[axis], sign, 0.0);  // the face's centre is on its axis, exactly
  }
}

// A tetrahedron: 4 triangles, 6 edges; a hull whose faces are all triangles keeps them.
TEST(tetrahedron_keeps_its_triangles) {
  const std::vector<Vec3> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Hull3 h;
  CHECK(build_hull(v, {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}, h));
  CHECK(h.face_count() == 4);
  CHECK(h.edge.size() == 6);
  check_topology(h);
}

// An octagonal prism (cap: 8 coplanar triangles fanned from its centre plus the ring,
// here 6 fan triangles of the octagon): its caps are single octagons.
TEST(prism_caps_merge_into_octagons) {
  std::vector<Vec3> v;
  for (int z = 0; z < 2; ++z)
    for (int k = 0; k < 8; ++k) v.push_back({std::cos(k * M_PI / 4), std::sin(k * M_PI / 4), z ? 1.0 : 0.0});
  std::vector<std::array<std::int32_t, 3>> t;
  for (int k = 1; k + 1 < 8; ++k) t.push_back({0, k + 1, k});           // bottom, seen from below
  for (int k = 1; k + 1 < 8; ++k) t.push_back({8, 8 + k, 8 + k + 1});   // top
  for (int k = 0; k < 8; ++k) {
    const int a = k, b = (k + 1) % 8;
    t.push_back({a, b, 8 + b});
    t.push_back({a, 8 + b, 8 + a});
  }
  Hull3 h;
  std::string error;
  CHECK(build_hull(v, t, h, &error));
  CHECK(h.face_count() == 10);
  CHECK(h.edge.size() == 24);
  int octagons = 0;
  for (int f = 0; f < h.face_count(); ++f) octagons += h.face_start[f + 1] - h.face_start[f] == 8;
  CHECK(octagons == 2);
  check_topology(h);
}

// Triangles that do not close a surface are an error with a message, not a hull.
TEST(open_surface_is_an_error) {
  auto t = box_triangles();
  t.pop_back();
  Hull3 h;
  std::string error;
  CHECK(!build_hull(box_corners(1, 1, 1), t, h, &error));
  CHECK(!error.empty());
  auto flipped = box_triangles();
  std::swap(flipped[0][1], flipped[0][2]);
  CHECK(!build_hull(box_corners(1, 1, 1), flipped, h, &error));
  // every triangle clockwise: closed, but inside out
  auto inverted = box_triangles();
  for (auto& tri : inverted) std::swap(tri[1], tri[2]);
  error.clear();
  CHECK(!build_hull(box_corners(1, 1, 1), inverted, h, &error));
  CHECK(error.find("inwards") != std::string::npos);
}

RBSIM_TEST_MAIN
