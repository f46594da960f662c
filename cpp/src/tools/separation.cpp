// The separation of pairs of shapes from their world vertices (the numba kernels
// _core_separation, _point_core_distance and _min_separation of rbsim/reference.py).
// Same operations in the same order, so the results are bit-identical to numba's (its
// kernels are compiled without fastmath).
#include "tools/separation.hpp"

#include <cmath>
#include <limits>

namespace rbsim {

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();

// Python's min(x, y) and max(x, y): the first argument unless the second is smaller
// (larger).
inline double py_min(double x, double y) { return y < x ? y : x; }
inline double py_max(double x, double y) { return y > x ? y : x; }

// Largest separation (m) of core b's vertices along the outward edge normals of core a
// (a polygon, or a segment with both of its normals).
double core_separation(const Vec2* verts, int sa, int na, int sb, int nb) {
  double best = -inf;
  const int edges = na > 2 ? na : 1;
  const int signs = na == 2 ? 2 : 1;
  for (int k = 0; k < edges; ++k) {
    const Vec2 p = verts[sa + k];
    const Vec2 q = verts[sa + (k + 1) % na];
    const Vec2 e = q - p;
    const double length = std::sqrt(e.x * e.x + e.y * e.y);
    for (int si = 0; si < signs; ++si) {
      const double sign = 1.0 - 2.0 * si;
      // the edge's outward normal (the right perpendicular of a counter-clockwise edge)
      const Vec2 n{sign * e.y / length, -sign * e.x / length};
      double low = inf;
      for (int j = 0; j < nb; ++j) {
        const Vec2 v = verts[sb + j];
        const double d = (v.x - p.x) * n.x + (v.y - p.y) * n.y;
        low = py_min(low, d);
      }
      best = py_max(best, low);
    }
  }
  return best;
}

// Signed distance (m) from vertex c to core a (a polygon or a segment): the distance to
// the nearest edge outside a polygon, minus the depth of the nearest face inside.
double point_core_distance(const Vec2* verts, int c, int sa, int na) {
  if (na > 2) {
    const double depth = core_separation(verts, sa, na, c, 1);
    if (depth <= 0.0) return depth;
  }
  double best = inf;
  const int edges = na > 2 ? na : 1;
  const Vec2 pt = verts[c];
  for (int k = 0; k < edges; ++k) {
    const Vec2 p = verts[sa + k];
    const double ex = verts[sa + (k + 1) % na].x - p.x;
    const double ey = verts[sa + (k + 1) % na].y - p.y;
    // the nearest point of the edge, as its fraction s along it
    double s = ((pt.x - p.x) * ex + (pt.y - p.y) * ey) / (ex * ex + ey * ey);
    s = py_min(py_max(s, 0.0), 1.0);
    const double dx = pt.x - p.x - s * ex, dy = pt.y - p.y - s * ey;
    best = py_min(best, std::sqrt(dx * dx + dy * dy));
  }
  return best;
}

}  // namespace

double pair_separation(const Vec2* verts, const std::int32_t* vstart, const std::int32_t* vcount,
                       const double* radius, std::int32_t a, std::int32_t b) {
  const int sa = vstart[a], na = vcount[a], sb = vstart[b], nb = vcount[b];
  double sep;
  if (na == 1 && nb == 1) {
    const double dx = verts[sb].x - verts[sa].x;
    const double dy = verts[sb].y - verts[sa].y;
    sep = std::sqrt(dx * dx + dy * dy);
  } else if (na == 1) {
    sep = point_core_distance(verts, sa, sb, nb);
  } else if (nb == 1) {
    sep = point_core_distance(verts, sb, sa, na);
  } else {
    sep = py_max(core_separation(verts, sa, na, sb, nb), core_separation(verts, sb, nb, sa, na));
  }
  return sep - radius[a] - radius[b];
}

void min_separation(const Vec2* verts, const std::int32_t* vstart, const std::int32_t* vcount,
                    const double* radius, const std::array<std::int32_t, 2>* pairs,
                    std::int64_t n_pairs, double* out) {
  for (std::int64_t p = 0; p < n_pairs; ++p)
    out[p] = pair_separation(verts, vstart, vcount, radius, pairs[p][0], pairs[p][1]);
}

}  // namespace rbsim
