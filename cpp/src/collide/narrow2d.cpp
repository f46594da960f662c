// 2D narrowphase: the contact manifold between two shapes (the port of rbsim/narrowphase.py).
//
// Every shape is a convex core with a radius around it: a circle is a point core, a
// segment (capsule) a 2-vertex core, a polygon a convex CCW core (radius 0, or rounded).
// The caller keeps all cores in WORLD coordinates: shape s uses verts[start .. start+count)
// (m), and norms[i] is the outward unit normal of edge i, from vertex i to vertex i+1
// (cyclic). A segment a-b has norms[start] = (a->b turned clockwise) and norms[start+1]
// its negative, so it is a 2-vertex polygon whose edges are a->b and b->a. A circle's
// norms row is unused.
//
// A manifold is one normal and one or two points: the unit normal points FROM shape b
// TOWARDS shape a (the impulse +λn acts on a, −λn on b); each point lies midway between
// the two surfaces; its separation (m) is the signed distance between the surfaces (radii
// included) along the normal, negative = overlap. Points farther apart than `speculative`
// are dropped.
//
// Feature ids stay the same while the same features touch, so the solver can carry
// impulses over from the last step (warm starting). With S = 2^16:
//   clipped point:  (1 + ref_is_b) S² + reference_edge S + incident_vertex
//   vertex-vertex:  3 S² + vertex_of_a S + vertex_of_b
//   circle cases:   0 (one point, nothing to tell apart)
// Indices are local to their shape (0..count-1); "a" and "b" are the pair function's own
// arguments, and the dispatcher keeps the ids of the pair function it calls.
//
// One pure function per kind pair, dispatched from a [kind][kind] table. A pair with a
// circle that comes in the other order is swapped (circle first) and its normal negated
// back. Polygons and segments share one routine (collide_cores): SAT over both shapes'
// edge normals, a reference face on the shape that is separated most, the incident edge
// clipped against the reference face's side planes, and a corner-to-corner correction for
// separated rounded shapes. Polygon/segment pairs are never swapped (as in the numba
// `collide`: the core routine takes either order, and the ids depend on the order).
//
// The arithmetic follows the numba code operation for operation (dot(a, b) is
// a.x b.x + a.y b.y, as written out there), so results agree to the last bit.
#include "narrow2d.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/wide.hpp"
#include "segment_closest.hpp"

namespace rbsim {
namespace {

using constants::LINEAR_EPSILON;
using constants::REFERENCE_FACE_TOLERANCE;
using constants::SEGMENT_SKIN;

constexpr std::int64_t ID_SHIFT = std::int64_t{1} << 16;
constexpr std::int64_t ID_VERTEX_VERTEX = 3;
constexpr double INF = std::numeric_limits<double>::infinity();

// d / s component by component (a division, not a multiplication by 1/s, as numba does it).
inline Vec2 divide(Vec2 d, double s) { return {d.x / s, d.y / s}; }

// std::min/std::max keep the same operand on ties and NaN as Python's min/max.
inline double clamp01(double x) { return std::min(std::max(x, 0.0), 1.0); }

// One contact point between core points a and b with normal n (b -> a). Returns 0 or 1.
inline int single_point(Vec2 a, double radius_a, Vec2 b, double radius_b, Vec2 n,
                        std::int64_t fid, double speculative, Manifold2& out) {
  const double sep = dot(a - b, n) - radius_a - radius_b;
  if (sep > speculative) return 0;
  // a's surface faces b (along −n), b's surface faces a (along +n)
  out.normal = n;
  out.point[0] = 0.5 * ((a - radius_a * n) + (b + radius_b * n));
  out.separation[0] = sep;
  out.id[0] = fid;
  return 1;
}

// Circle a against circle b: one point on the line of centres.
int collide_circle_circle(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                          const Vec2* norms, double speculative, Manifold2& out) {
  const Vec2 a = verts[sa.start];
  const Vec2 b = verts[sb.start];
  const Vec2 d = a - b;
  const double dist = length(d);
  if (dist - sa.radius - sb.radius > speculative) return 0;
  // concentric: any direction separates them equally well
  const Vec2 n = dist > LINEAR_EPSILON ? divide(d, dist) : Vec2{0.0, 1.0};
  return single_point(a, sa.radius, b, sb.radius, n, 0, speculative, out);
}

// Circle a against (possibly rounded) convex polygon b, count >= 3.
//
// The face that separates the centre most decides: when the centre lies beyond one of that
// face's end points (vertex region) the normal runs from the vertex to the centre,
// otherwise it is the face normal (also when the centre is inside).
int collide_circle_polygon(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                           const Vec2* norms, double speculative, Manifold2& out) {
  const Vec2 c = verts[sa.start];
  const double radius = sa.radius + sb.radius;
  double best = -INF;
  int edge = 0;
  for (int i = 0; i < sb.count; ++i) {
    const int k = sb.start + i;
    const double s = dot(norms[k], c - verts[k]);
    if (s > best) {
      best = s;
      edge = i;
    }
  }
  if (best - radius > speculative) return 0;
  const int i1 = sb.start + edge;
  const int i2 = sb.start + (edge + 1) % sb.count;
  const Vec2 v1 = verts[i1];
  const Vec2 v2 = verts[i2];
  const Vec2 e = v2 - v1;
  const double u1 = dot(c - v1, e);
  const double u2 = dot(v2 - c, e);
  // vertex regions exist only outside the polygon (best > 0), so |c − v| >= best > 0
  Vec2 p;
  if (u1 < 0.0 && best > LINEAR_EPSILON) {
    p = v1;
  } else if (u2 < 0.0 && best > LINEAR_EPSILON) {
    p = v2;
  } else {
    const Vec2 n = norms[i1];
    p = c - best * n;
    return single_point(c, sa.radius, p, sb.radius, n, 0, speculative, out);
  }
  const Vec2 d = c - p;
  const double dist = length(d);
  return single_point(c, sa.radius, p, sb.radius, divide(d, dist), 0, speculative, out);
}

// Circle a against segment (capsule) b: one point from the closest point on the core.
int collide_circle_segment(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                           const Vec2* norms, double speculative, Manifold2& out) {
  const Vec2 c = verts[sa.start];
  const Vec2 p1 = verts[sb.start];
  const Vec2 e = verts[sb.start + 1] - p1;
  const double ee = dot(e, e);
  double t = 0.0;
  if (ee > LINEAR_EPSILON * LINEAR_EPSILON) t = clamp01(dot(c - p1, e) / ee);
  const Vec2 p = p1 + t * e;
  const Vec2 d = c - p;
  const double dist = length(d);
  if (dist - sa.radius - sb.radius > speculative) return 0;
  // centre on the core: push out along the segment's normal
  const Vec2 n = dist > LINEAR_EPSILON ? divide(d, dist) : norms[sb.start];
  return single_point(c, sa.radius, p, sb.radius, n, 0, speculative, out);
}

// The edge of core 1 whose normal separates core 2 most: separation (m) and local edge.
struct EdgeSeparation {
  double sep;
  int edge;
};
inline EdgeSeparation max_separation(int start1, int count1, int start2, int count2,
                                     const Vec2* verts, const Vec2* norms) {
  if (count1 == LANES) {
    // a quadrilateral core 1 (a box): its edges one in each lane, the same dots and the
    // same comparisons in the same order as below
    static_assert(LANES == 4);
    const double* np = &norms[start1].x;
    const double* vp = &verts[start1].x;
    const Lanes n01 = load_lanes(np), n23 = load_lanes(np + 4);
    const Lanes v01 = load_lanes(vp), v23 = load_lanes(vp + 4);
    const Lanes nx = __builtin_shufflevector(n01, n23, 0, 2, 4, 6);
    const Lanes ny = __builtin_shufflevector(n01, n23, 1, 3, 5, 7);
    const Lanes vx = __builtin_shufflevector(v01, v23, 0, 2, 4, 6);
    const Lanes vy = __builtin_shufflevector(v01, v23, 1, 3, 5, 7);
    Lanes s = splat(INF);
    for (int j = start2; j < start2 + count2; ++j) {
      const Lanes d = nx * (splat(verts[j].x) - vx) + ny * (splat(verts[j].y) - vy);
      s = d < s ? d : s;
    }
    double best = -INF;
    int best_edge = 0;
    for (int i = 0; i < LANES; ++i) {
      if (s[i] > best) {
        best = s[i];
        best_edge = i;
      }
    }
    return {best, best_edge};
  }
  double best = -INF;
  int best_edge = 0;
  for (int i = 0; i < count1; ++i) {
    const int k = start1 + i;
    const Vec2 n = norms[k];
    const Vec2 v = verts[k];
    double s = INF;
    for (int j = start2; j < start2 + count2; ++j) {
      const double d = dot(n, verts[j] - v);
      if (d < s) s = d;
    }
    if (s > best) {
      best = s;
      best_edge = i;
    }
  }
  return {best, best_edge};
}

// segment_closest_fractions (segment_closest.hpp) reports an end point exactly as 0.0 or
// 1.0 (by clamping): that is how the corner-to-corner case below recognises the
// vertex-vertex region.

// Clip the incident edge to the reference face's side planes; keep points within reach.
//
// In the reference face's frame (origin v1, tangent t along the face, normal n out of the
// reference shape) the incident edge w(λ) = w1 + λ (w2 − w1) is cut to the part with
// 0 <= t·(w − v1) <= face length; each end of that part is a point whose core separation
// is n·(w − v1).
inline int clip_incident_edge(int ref_is_b, int ref_start, int ref_count, int ref_edge,
                              double ref_radius, int inc_start, int inc_count, int inc_edge,
                              double inc_radius, const Vec2* verts, const Vec2* norms,
                              double speculative, Manifold2& out) {
  const int i1 = ref_start + ref_edge;
  const int i2 = ref_start + (ref_edge + 1) % ref_count;
  const Vec2 n = norms[i1];
  const Vec2 t = perp(n);  // n turned counter-clockwise = the face direction v1 -> v2
  const Vec2 v1 = verts[i1];
  const double length = dot(verts[i2] - v1, t);
  const int j1 = inc_start + inc_edge;
  const int j2 = inc_start + (inc_edge + 1) % inc_count;
  const Vec2 w1 = verts[j1];
  const Vec2 e = verts[j2] - w1;
  const double u1 = dot(w1 - v1, t);
  const double du = dot(e, t);
  double lo = 0.0, hi = 1.0;
  if (std::abs(du) > LINEAR_EPSILON) {
    const double la = -u1 / du;
    const double lb = (length - u1) / du;
    lo = std::max(0.0, std::min(la, lb));
    hi = std::min(1.0, std::max(la, lb));
    if (lo > hi) {  // the edge misses the face: keep its end nearest the face
      if (hi < 0.0)
        hi = lo;
      else
        lo = hi;
    }
  }
  out.normal = ref_is_b ? n : -n;
  const double radius = ref_radius + inc_radius;
  const std::int64_t id_ref = (1 + ref_is_b) * ID_SHIFT * ID_SHIFT + ref_edge * ID_SHIFT;
  int n_points = 0;
  for (int k = 0; k < 2; ++k) {
    double lam;
    int inc_vertex;
    if (k == 0) {
      lam = lo;
      inc_vertex = inc_edge;
    } else {
      if (hi <= lo) break;  // both ends clipped to one place: one point
      lam = hi;
      inc_vertex = (inc_edge + 1) % inc_count;
    }
    const Vec2 p = w1 + lam * e;
    const double depth = dot(p - v1, n);
    const double sep = depth - radius;
    if (sep > speculative) continue;
    // midway between the reference surface (p + (r_ref − depth) n) and the incident
    // surface (p − r_inc n)
    const double shift = 0.5 * (ref_radius - inc_radius - depth);
    out.point[n_points] = p + shift * n;
    out.separation[n_points] = sep;
    out.id[n_points] = id_ref + inc_vertex;
    ++n_points;
  }
  return n_points;
}

// The incident edge of a core against reference normal n: the one whose normal is most
// anti-parallel to it (local index).
inline int incident_edge(const ShapeRef2& inc, Vec2 n, const Vec2* norms) {
  int edge = 0;
  double min_dot = INF;
  for (int j = 0; j < inc.count; ++j) {
    const double d = dot(n, norms[inc.start + j]);
    if (d < min_dot) {
      min_dot = d;
      edge = j;
    }
  }
  return edge;
}

// Two convex cores with 2 or more vertices each (polygons and segments), rounded.
int collide_cores(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                  const Vec2* norms, double speculative, Manifold2& out) {
  const double radius_a = sa.radius, radius_b = sb.radius;
  const double radius = radius_a + radius_b;
  const auto [sep_a, edge_a] = max_separation(sa.start, sa.count, sb.start, sb.count, verts, norms);
  if (sep_a - radius > speculative) return 0;
  const auto [sep_b, edge_b] = max_separation(sb.start, sb.count, sa.start, sa.count, verts, norms);
  if (sep_b - radius > speculative) return 0;

  const double face_tolerance = std::min(sa.scale, sb.scale) * REFERENCE_FACE_TOLERANCE;
  const int ref_is_b = sep_b > sep_a + face_tolerance ? 1 : 0;
  const ShapeRef2& ref = ref_is_b ? sb : sa;
  const ShapeRef2& inc = ref_is_b ? sa : sb;
  const int ref_edge = ref_is_b ? edge_b : edge_a;

  // incident edge: the one whose normal is most anti-parallel to the reference normal
  const int i1 = ref.start + ref_edge;
  const int inc_edge = incident_edge(inc, norms[i1], norms);

  // Corner to corner: when the cores are apart and the closest points of the two edges
  // are end points of both, the true distance exceeds the SAT separation (face normals
  // miss the corner-to-corner axis; for segments they can miss the distance entirely,
  // e.g. two collinear capsules end to end). Report the true distance.
  const double sat_sep = std::max(sep_a, sep_b);
  if (sat_sep > -LINEAR_EPSILON) {
    const int r1 = ref.start + (ref_edge + 1) % ref.count;
    const int k1 = inc.start + inc_edge;
    const int k2 = inc.start + (inc_edge + 1) % inc.count;
    const Vec2 p1 = verts[i1], q1 = verts[r1];
    const Vec2 p2 = verts[k1], q2 = verts[k2];
    const auto [s, t] = segment_closest_fractions(p1, q1, p2, q2);
    if ((s == 0.0 || s == 1.0) && (t == 0.0 || t == 1.0)) {
      const Vec2 c1 = p1 + s * (q1 - p1);
      const Vec2 c2 = p2 + t * (q2 - p2);
      const Vec2 d = c2 - c1;
      const double dist = length(d);
      if (dist > sat_sep + LINEAR_EPSILON) {
        if (dist - radius > speculative) return 0;
        const std::int64_t ref_vertex = s == 0.0 ? ref_edge : (ref_edge + 1) % ref.count;
        const std::int64_t inc_vertex = t == 0.0 ? inc_edge : (inc_edge + 1) % inc.count;
        if (ref_is_b) {  // incident = a
          const std::int64_t fid = (ID_VERTEX_VERTEX * ID_SHIFT + inc_vertex) * ID_SHIFT + ref_vertex;
          return single_point(c2, radius_a, c1, radius_b, divide(d, dist), fid, speculative, out);
        }
        const std::int64_t fid = (ID_VERTEX_VERTEX * ID_SHIFT + ref_vertex) * ID_SHIFT + inc_vertex;
        return single_point(c1, radius_a, c2, radius_b, divide(-d, dist), fid, speculative, out);
      }
    }
  }

  return clip_incident_edge(ref_is_b, ref.start, ref.count, ref_edge, ref.radius, inc.start,
                            inc.count, inc_edge, inc.radius, verts, norms, speculative, out);
}

// Convex polygon a against convex polygon b (either may be rounded): 0, 1 or 2 points.
int collide_polygon_polygon(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                            const Vec2* norms, double speculative, Manifold2& out) {
  return collide_cores(sa, sb, verts, norms, speculative, out);
}

// Polygon a against segment (capsule) b, the segment as a 2-vertex rounded polygon.
int collide_polygon_segment(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                            const Vec2* norms, double speculative, Manifold2& out) {
  return collide_cores(sa, sb, verts, norms, speculative, out);
}

// Segment a against polygon b: the same core routine in this order (not swapped, so the
// ids are those of collide_cores(segment, polygon), as numba's `collide` gives them).
int collide_segment_polygon(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                            const Vec2* norms, double speculative, Manifold2& out) {
  return collide_cores(sa, sb, verts, norms, speculative, out);
}

// Segment (capsule) a against segment (capsule) b, both as 2-vertex rounded polygons.
//
// Two thin segments have no inside: once one dips below the other by a rounding error the
// normal flips and it falls through. A skin keeps them apart by SEGMENT_SKIN instead (as
// polygon radii did in Box2D v2): the combined radius is raised to at least SEGMENT_SKIN,
// half on each.
int collide_segment_segment(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts,
                            const Vec2* norms, double speculative, Manifold2& out) {
  const double skin_min = std::min(sa.scale, sb.scale) * SEGMENT_SKIN;  // m
  const double skin = 0.5 * std::max(skin_min - sa.radius - sb.radius, 0.0);
  const ShapeRef2 a{sa.kind, sa.start, sa.count, sa.radius + skin};
  const ShapeRef2 b{sb.kind, sb.start, sb.count, sb.radius + skin};
  return collide_cores(a, b, verts, norms, speculative, out);
}

using PairFn = int (*)(const ShapeRef2&, const ShapeRef2&, const Vec2*, const Vec2*, double,
                       Manifold2&);

// A circle pair that comes with the circle second: the pair function with the circle
// first, its normal negated back (b -> a of the caller's order; ids are 0 anyway). The
// normal is negated even when no point is written, as numba does (it is unused then).
template <PairFn F>
int swapped(const ShapeRef2& sa, const ShapeRef2& sb, const Vec2* verts, const Vec2* norms,
            double speculative, Manifold2& out) {
  const int n = F(sb, sa, verts, norms, speculative, out);
  out.normal = -out.normal;
  return n;
}

// [kind_a][kind_b], kinds in ShapeKind order: Circle, Polygon, Segment.
constexpr PairFn COLLIDE[SHAPE_KIND_COUNT][SHAPE_KIND_COUNT] = {
    {collide_circle_circle, collide_circle_polygon, collide_circle_segment},
    {swapped<collide_circle_polygon>, collide_polygon_polygon, collide_polygon_segment},
    {swapped<collide_circle_segment>, collide_segment_polygon, collide_segment_segment},
};

}  // namespace

int collide_on_face(const ShapeRef2& a, const ShapeRef2& b, int ref_is_b, int face,
                    const Vec2* verts, const Vec2* norms, double speculative, Manifold2& out) {
  const ShapeRef2& ref = ref_is_b ? b : a;
  const ShapeRef2& inc = ref_is_b ? a : b;
  const Vec2 n = norms[ref.start + face];  // out of the reference shape
  if (inc.count == 1) {  // a circle: its centre's foot on the face's line
    const Vec2 c = verts[inc.start];
    const Vec2 p = c - dot(n, c - verts[ref.start + face]) * n;
    if (ref_is_b) return single_point(c, inc.radius, p, ref.radius, n, 0, speculative, out);
    return single_point(p, ref.radius, c, inc.radius, -n, 0, speculative, out);
  }
  return clip_incident_edge(ref_is_b, ref.start, ref.count, face, ref.radius, inc.start,
                            inc.count, incident_edge(inc, n, norms), inc.radius, verts, norms,
                            speculative, out);
}

// Manifold between shape a and shape b; returns the point count 0, 1 or 2 (only the
// first `count` rows of out are written). Unknown kinds give 0 points.
int collide2d(const ShapeRef2& a, const ShapeRef2& b, const Vec2* verts, const Vec2* norms,
              double speculative, Manifold2& out) {
  const auto ka = static_cast<unsigned>(a.kind);
  const auto kb = static_cast<unsigned>(b.kind);
  if (ka >= SHAPE_KIND_COUNT || kb >= SHAPE_KIND_COUNT) return 0;
  return COLLIDE[ka][kb](a, b, verts, norms, speculative, out);
}

}  // namespace rbsim
