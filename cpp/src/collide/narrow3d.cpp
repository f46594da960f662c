// 3D narrowphase: the contact manifold between two shapes (see narrow3d.hpp for the
// shapes, the manifold's conventions and the feature ids).
//
// One pure function per kind pair, dispatched from a [kind][kind] table at the end. A
// pair that comes in the other order than its function's is swapped and its normal
// negated back (the points and separations are the same; the ids are the function's).
//
// Polytopes (boxes and hulls) go through separating axes: the face normals of both and
// the cross products of their edge directions. The reference face is a's best face
// unless b's separates more by the face tolerance, and an edge pair wins only when it
// separates more than that face by a relative margin, so that a resting contact keeps
// its face (and its four points) instead of flickering to an edge; a winning edge pair
// takes the face contact's points too where that face is near its normal
// (edge_with_face). A face contact clips the incident face (the other shape's face most
// anti-parallel to the reference normal) against the reference face's side planes
// (Sutherland–Hodgman), keeps the points within reach and reduces them to at most four:
// the deepest, the one farthest from it, the one spanning the largest triangle with
// those, and the one adding the most area. An edge contact is one point at the closest
// points of the two edges. Box–box runs the same
// steps on the boxes' 15 axes directly (3 + 3 face normals, 9 edge cross products);
// box–convex takes the box as a hull (box_hull()).
//
// Nothing here allocates: polygons are clipped in fixed arrays sized by the largest face
// (HULL_MAX_FACE_VERTICES), and plane contacts reduce the vertices without storing them.
#include "narrow3d.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "collide/segment_closest.hpp"
#include "rbsim/constants.hpp"
#include "rbsim/wide.hpp"

namespace rbsim {
namespace {

using constants::LINEAR_EPSILON;
using constants::REFERENCE_FACE_TOLERANCE;

constexpr double INF = std::numeric_limits<double>::infinity();

// An edge pair becomes the contact only if it separates more than the best face by this
// fraction of the face's |separation| (plus the face tolerance): a box resting face to
// face keeps its four points although, rocking, an edge axis comes within round-off of
// the face's. Dimensionless; larger prefers faces more (a true edge-edge crossing
// separates far more than any face, so it still wins).
constexpr double EDGE_RELATIVE_TOLERANCE = 0.05;

// Edge directions whose cross product has a sine below this are parallel: their axis is
// (up to round-off) a face normal already tested, and its length too small to normalise.
constexpr double EDGE_PARALLEL_SIN = 1.0e-6;

// Capsule segments within this sine of parallel touch along a line: two points at the
// ends of their common stretch. Dimensionless; at 0.01 a 1 m capsule's ends drift 5 mm
// sideways, and the separation error of the line contact is under 0.1 mm for r >= 0.1 m.
constexpr double CAPSULE_PARALLEL_SIN = 1.0e-2;

constexpr Vec3 UP{0.0, 1.0, 0.0};  // the normal when nothing else tells the direction

using FK = FeatureKind;

inline double clamp01(double x) { return std::min(std::max(x, 0.0), 1.0); }

// A unit vector perpendicular to v (v need not be unit; zero gives UP's perpendicular).
inline Vec3 perpendicular(Vec3 v) {
  const double ax = std::fabs(v.x), ay = std::fabs(v.y), az = std::fabs(v.z);
  // cross with the axis v is least aligned with
  const Vec3 axis = ax <= ay && ax <= az ? Vec3{1, 0, 0} : (ay <= az ? Vec3{0, 1, 0} : Vec3{0, 0, 1});
  const Vec3 c = cross(v, axis);
  const double l = length(c);
  return l > 0.0 ? (1.0 / l) * c : Vec3{1.0, 0.0, 0.0};
}

// One contact point between core points a and b (m) with unit normal n (b -> a). 0 or 1.
inline int single_point(Vec3 a, double radius_a, Vec3 b, double radius_b, Vec3 n,
                        std::int64_t fid, double speculative, Manifold3& out) {
  const double sep = dot(a - b, n) - radius_a - radius_b;
  if (sep > speculative) return 0;
  out.normal = n;
  out.point[0] = 0.5 * ((a - radius_a * n) + (b + radius_b * n));
  out.separation[0] = sep;
  out.id[0] = fid;
  return 1;
}

inline Vec3 closest_on_segment(Vec3 x, Vec3 p, Vec3 q) {
  const Vec3 d = q - p;
  const double dd = dot(d, d);
  const double t = dd > LINEAR_EPSILON * LINEAR_EPSILON ? clamp01(dot(x - p, d) / dd) : 0.0;
  return p + t * d;
}

// ---------------------------------------------------------------------------------------
// Reduction to four points

// The manifold from n candidate points: get(i, point, separation, id) fills candidate i
// and returns whether it is within reach. At most four are kept: the deepest, the one
// farthest from it, the one spanning the largest triangle with those two (area seen
// along the normal), and the one that adds most area to that triangle; they are written
// in candidate order. Ties go to the lower index, also ties that round-off decides (a
// box's face is a rectangle: its corners tie in depth, its opposite sides in area), so
// that the same four are kept from step to step (REDUCE_TIE). Returns the point count.
// Relative margin by which a candidate must beat the current pick in reduce_to_four (and
// depth by LINEAR_EPSILON, m): far above the round-off of the same point computed along
// another path (1e-16), far below any difference that matters.
constexpr double REDUCE_TIE = 1.0e-9;

template <class Get>
int reduce_to_four(int n, const Get& get, Vec3 normal, Manifold3& out) {
  Vec3 p;
  double s;
  std::int64_t id;
  int kept = 0;
  int deepest = -1;
  double min_sep = INF;
  for (int i = 0; i < n; ++i) {
    if (!get(i, p, s, id)) continue;
    if (kept < 4) {
      out.point[kept] = p;
      out.separation[kept] = s;
      out.id[kept] = id;
    }
    ++kept;
    if (s < min_sep - LINEAR_EPSILON) {
      min_sep = s;
      deepest = i;
    }
  }
  out.normal = normal;
  if (kept <= 4) return kept;

  std::array<int, 4> pick{deepest, -1, -1, -1};
  Vec3 p0;
  get(deepest, p0, s, id);
  double best = -1.0;
  Vec3 p1;
  for (int i = 0; i < n; ++i) {
    if (!get(i, p, s, id)) continue;
    const double d2 = length_squared(p - p0);
    if (d2 > best * (1.0 + REDUCE_TIE)) {
      best = d2;
      pick[1] = i;
      p1 = p;
    }
  }
  int count = 1;
  const double d01 = std::sqrt(best);  // m
  if (d01 > LINEAR_EPSILON) count = 2;
  best = -1.0;
  Vec3 p2;
  double orient = 1.0;
  for (int i = 0; i < n; ++i) {
    if (!get(i, p, s, id)) continue;
    const double area = dot(cross(p1 - p0, p - p0), normal);
    if (std::fabs(area) > best * (1.0 + REDUCE_TIE)) {
      best = std::fabs(area);
      pick[2] = i;
      p2 = p;
      orient = area >= 0.0 ? 1.0 : -1.0;
    }
  }
  // a triangle of height LINEAR_EPSILON (m) or less: the points are on one line
  if (count == 2 && best > LINEAR_EPSILON * d01) count = 3;
  // the area a point adds outside the triangle: the most negative of its (oriented)
  // areas against the triangle's three edges
  const double tie = REDUCE_TIE * best;  // best: twice the triangle's area
  best = tie;
  for (int i = 0; i < n; ++i) {
    if (!get(i, p, s, id)) continue;
    const double a01 = orient * dot(cross(p1 - p0, p - p0), normal);
    const double a12 = orient * dot(cross(p2 - p1, p - p1), normal);
    const double a20 = orient * dot(cross(p0 - p2, p - p2), normal);
    const double added = -std::min(a01, std::min(a12, a20));
    if (added > best + tie) {
      best = added;
      pick[3] = i;
    }
  }
  if (count == 3 && pick[3] >= 0) count = 4;
  std::sort(pick.begin(), pick.begin() + count);
  for (int k = 0; k < count; ++k) {
    get(pick[k], out.point[k], out.separation[k], out.id[k]);
  }
  return count;
}

// ---------------------------------------------------------------------------------------
// Face clipping
//
// The reference face's side planes are moved out by the pair's face tolerance (the clip
// skin): an incident corner on a side plane, as where two equal faces lie flush, is kept
// as a corner (its vertex id) rather than cut, at rounding's whim, into two clipped
// points with other ids, which lost the face's warm start from one step to the next (a
// 100 t box on a 1 m box popped up 12 cm/s). A corner up to the skin outside the face
// (0.5 mm) is a contact point there.

// Room for N values of T, left unset: only those written are read. (A Vec3 starts at
// zero, and the 128 points of a hull's clip polygon set to zero at every clip, twice, with
// the face loop's 64, took a seventh of a pile of 8-to-12-point pebbles' step.)
template <class T, int N>
struct Unset {
  union {
    T v[N];
  };
  Unset() {}  // v left unset
  T& operator[](int i) { return v[i]; }
  const T& operator[](int i) const { return v[i]; }
  T* data() { return v; }
};

// A polygon being clipped: its points (m), each point's feature id (kind, f1, f2; the
// reference part is added at the end) and the tag of the side from point i to i+1: an
// incident edge (>= 0) or a side plane of the reference face (−1 − side).
template <int N>
struct ClipPolygon {
  int n = 0;
  Unset<Vec3, N> p;
  std::array<std::int64_t, N> id;
  std::array<int, N> tag;
  void push(Vec3 point, std::int64_t fid, int side_tag) {
    p[n] = point;
    id[n] = fid;
    tag[n] = side_tag;
    ++n;
  }
};

// Keep the part of `in` on the inner side of a plane, dist(x) <= 0 (reference side
// `side`; dist is affine in x). A convex polygon gains at most one point.
template <int N, class Dist>
void clip_polygon(const ClipPolygon<N>& in, const Dist& dist, int side, ClipPolygon<N>& out) {
  out.n = 0;
  if (in.n == 0) return;
  Vec3 P = in.p[0];
  double dP = dist(P);
  for (int i = 0; i < in.n; ++i) {
    const int j = i + 1 < in.n ? i + 1 : 0;
    const Vec3 Q = in.p[j];
    const double dQ = dist(Q);
    const bool inP = dP <= 0.0, inQ = dQ <= 0.0;
    const int tag = in.tag[i];
    if (inP) out.push(P, in.id[i], tag);
    if (inP != inQ) {
      const double t = dP / (dP - dQ);
      const Vec3 I = P + t * (Q - P);
      std::int64_t fid;
      if (tag >= 0) {
        fid = feature_id(FK::EdgeSide, 0, 0, tag, side);
      } else {
        const int other = -1 - tag;
        fid = feature_id(FK::SideSide, 0, 0, std::min(other, side), std::max(other, side));
      }
      out.push(I, fid, inP ? -1 - side : tag);
    }
    P = Q;
    dP = dQ;
  }
}

// Face contact: the incident polygon `inc` clipped against the reference face (its loop
// `ref` of ref_n world points, CCW seen from outside, outward unit normal n_ref); each
// surviving point's separation is its depth below the reference plane. ref_is_b and
// ref_face make the ids' reference part. An incident point up to `skin` (m) outside a side
// plane is kept where it is (the clip skin). `inc` is used as scratch.
template <int N>
int face_contact(const Vec3* ref, int ref_n, Vec3 n_ref, ClipPolygon<N>& inc, int ref_is_b,
                 int ref_face, double skin, double speculative, Manifold3& out) {
  ClipPolygon<N> tmp;
  ClipPolygon<N>* cur = &inc;
  ClipPolygon<N>* nxt = &tmp;
  for (int k = 0; k < ref_n && cur->n > 0; ++k) {
    const Vec3 v0 = ref[k];
    const Vec3 v1 = ref[k + 1 < ref_n ? k + 1 : 0];
    const Vec3 side = cross(v1 - v0, n_ref);  // outward, of the edge's length (n_ref unit)
    const double reach = skin * length(v1 - v0);
    clip_polygon(*cur, [&](Vec3 x) { return dot(side, x - v0) - reach; }, k, *nxt);
    std::swap(cur, nxt);
  }
  const ClipPolygon<N>& poly = *cur;
  const Vec3 origin = ref[0];
  const std::int64_t ref_part = feature_id(FK::Single, ref_is_b, ref_face, 0, 0);
  const auto get = [&](int i, Vec3& p, double& s, std::int64_t& id) {
    s = dot(n_ref, poly.p[i] - origin);
    p = poly.p[i] - (0.5 * s) * n_ref;
    id = ref_part | poly.id[i];
    return s <= speculative;
  };
  return reduce_to_four(poly.n, get, ref_is_b ? n_ref : -n_ref, out);
}

// ---------------------------------------------------------------------------------------
// Boxes and hulls as polytopes

// The box's topology (box_hull()): corners by sign bits, faces 2 axis + (positive).
constexpr std::int32_t BOX_LOOP[6][4] = {
    {0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6},
};

// The axis of a box edge from the xor of its corners' indices (one bit set).
constexpr int BIT_AXIS[5] = {0, 0, 1, 0, 2};

const Hull3& box_hull3() {
  static const Hull3 hull = [] {
    std::vector<Vec3> corners;
    for (int k = 0; k < 8; ++k)
      corners.push_back({k & 1 ? 1.0 : -1.0, k & 2 ? 1.0 : -1.0, k & 4 ? 1.0 : -1.0});
    std::vector<std::array<std::int32_t, 3>> triangles;
    for (const auto& l : BOX_LOOP) {
      triangles.push_back({l[0], l[1], l[2]});
      triangles.push_back({l[0], l[2], l[3]});
    }
    Hull3 h;
    build_hull(corners, triangles, h);
    return h;
  }();
  return hull;
}

// A box's centre and half-extent vectors (m), for its corners.
struct BoxCorners {
  Vec3 c, ex, ey, ez;
  explicit BoxCorners(const ShapeRef3& box)
      : c(box.center), ex(box.half.x * box.axes[0]), ey(box.half.y * box.axes[1]),
        ez(box.half.z * box.axes[2]) {}
  // corner k: the signs of bits 0, 1, 2 of k along x, y, z
  Vec3 operator[](int k) const { return c + (k & 1 ? ex : -ex) + (k & 2 ? ey : -ey) + (k & 4 ? ez : -ez); }
};
inline Vec3 box_corner(const ShapeRef3& box, int k) { return BoxCorners(box)[k]; }

// A polytope as the hull code reads it: world vertices, world face normals, topology;
// and where made already this step, its faces' plane offsets (m) and its HullSpread.
struct Polytope {
  const Vec3* v;
  const Vec3* fn;
  const HullView* h;
  const double* d = nullptr;
  const HullSpread* spread = nullptr;
};

// The hull's face f: its loop's first vertex.
inline Vec3 face_origin(const Polytope& P, int f) { return P.v[P.h->face_first[f]]; }

// Whether x (on face f's plane) lies within face f's polygon.
inline bool inside_face(const Polytope& P, int f, Vec3 x) {
  const int s = P.h->face_start[f], e = P.h->face_start[f + 1];
  const Vec3 n = P.fn[f];
  for (int k = s; k < e; ++k) {
    const Vec3 v0 = P.v[P.h->face_vertex[k]];
    const Vec3 v1 = P.v[P.h->face_vertex[k + 1 < e ? k + 1 : s]];
    if (dot(cross(v1 - v0, n), x - v0) > 0.0) return false;
  }
  return true;
}

// The closest point of a hull's surface to x: its point, the unit normal (out of the
// hull towards x) and the signed distance (negative inside, then along the least deep face).
struct SurfacePoint {
  Vec3 point;
  Vec3 normal;
  double distance;
};
inline SurfacePoint closest_on_hull(const Polytope& P, Vec3 x) {
  double best = -INF;
  int face = 0;
  for (int f = 0; f < P.h->face_count; ++f) {
    const double s = dot(P.fn[f], x - face_origin(P, f));
    if (s > best) {
      best = s;
      face = f;
    }
  }
  const Vec3 n = P.fn[face];
  const Vec3 y = x - best * n;
  if (best <= 0.0 || inside_face(P, face, y)) return {y, n, best};
  // outside, beyond the face's polygon: the closest point is on an edge (or a vertex)
  double d2 = INF;
  Vec3 c = y;
  for (int e = 0; e < P.h->edge_count; ++e) {
    const Vec3 k = closest_on_segment(x, P.v[P.h->edge[e].v0], P.v[P.h->edge[e].v1]);
    const double dd = length_squared(x - k);
    if (dd < d2) {
      d2 = dd;
      c = k;
    }
  }
  const double dist = std::sqrt(d2);
  // dist >= best > 0: the direction is defined
  return {c, (1.0 / dist) * (x - c), dist};
}

// The incident polygon: face f of P as a ClipPolygon (vertex ids, edge tags).
template <int N>
inline void incident_polygon(const Polytope& P, int f, ClipPolygon<N>& poly) {
  poly.n = 0;
  for (int k = P.h->face_start[f]; k < P.h->face_start[f + 1]; ++k) {
    const int v = P.h->face_vertex[k];
    poly.push(P.v[v], feature_id(FK::Vertex, 0, 0, v, 0), P.h->face_edge[k]);
  }
}


// The Minkowski-face test of A's edge against four of B's edges at once, lane by lane.
// An edge pair makes a face of the Minkowski difference A − B, and so a candidate
// separating axis, when their arcs on the Gauss map cross: A's arc a-b (a, b: the normals
// of the edge's two faces, bxa = b × a, along the edge) and B's arc c-d (its faces'
// normals negated, dxc = d × c).
struct EdgeArcs {
  LanesXYZ c, d, e;  // c, d and e = d × c of four edges of B
};
// B's edges idx[0 .. n) (n <= LANES) as arcs; a lane past them is zeros, which no test
// passes.
inline EdgeArcs edge_arcs(const Polytope& B, const int* idx, int n) {
  EdgeArcs g{};
  for (int l = 0; l < n; ++l) {
    const HullEdge& e = B.h->edge[idx[l]];
    const Vec3 c = -B.fn[e.f0], d = -B.fn[e.f1], dxc = cross(d, c);
    g.c.x[l] = c.x, g.c.y[l] = c.y, g.c.z[l] = c.z;
    g.d.x[l] = d.x, g.d.y[l] = d.y, g.d.z[l] = d.z;
    g.e.x[l] = dxc.x, g.e.y[l] = dxc.y, g.e.z[l] = dxc.z;
  }
  return g;
}
inline unsigned minkowski_faces(Vec3 a, Vec3 b, Vec3 bxa, const EdgeArcs& g) {
  const Lanes cba = dot(bxa, g.c), dba = dot(bxa, g.d);
  const Lanes adc = dot(a, g.e), bdc = dot(b, g.e);
  const Lanes zero = splat(0.0);
  return lane_bits((cba * dba < zero) & (adc * bdc < zero) & (cba * bdc > zero));
}

// The tolerances of a pair: the face tolerance (m) at the smaller scale.
inline double face_tolerance(const ShapeRef3& a, const ShapeRef3& b) {
  return std::min(a.scale, b.scale) * REFERENCE_FACE_TOLERANCE;
}
inline bool edge_wins(double edge_sep, double face_sep, double tol) {
  return edge_sep > face_sep + EDGE_RELATIVE_TOLERANCE * std::fabs(face_sep) + tol;
}

// An edge pair whose axis lies within EDGE_FACE_COS of the reference face's normal takes
// that face's clipped points into its manifold (edge_with_face), and within
// EDGE_FACE_SAME the face contact is the manifold when it agrees with the edge pair.
// Dimensionless cosines: 0.9 is 26°: a face turned further from the edge pair's normal is
// not about to lie on the other shape's face within a step; 1 − 1.5e-4 is 1°: a face that
// near is the contact, only the edge pair's axis passed over a part of the other shape
// beyond its rim.
constexpr double EDGE_FACE_COS = 0.9;
constexpr double EDGE_FACE_SAME = 1.0 - 1.5e-4;

// The manifold where an edge pair wins: its point (n_edge, 0 or 1, in `edge`: the normal
// is the edge pair's, sep_e its separation, m) and the face contact's points (n_face in
// `face`: the incident face clipped to the reference face; the caller clips only a face
// whose normal is within EDGE_FACE_COS of the edge pair's). A box tilted a few degrees
// over another, its corners hanging over the rim, touches it edge on edge; turning at 10
// rad/s it laid its face down within the step and landed 18 mm deep, that face's points
// not in the one-point manifold of the edge pair.
//
// Where the face's normal is within EDGE_FACE_SAME of the edge pair's and its deepest
// point lies at the edge pair's separation (within the face tolerance tol, m), the face
// contact is the manifold as it is: the face axis lost only to a part of the other shape
// beyond the face's rim (a box of a pyramid's second layer on one of the four below it,
// its corner sagging past that box's top over the next one), and the face's points are
// all of the contact. Otherwise the face's points and the edge pair's, the face's first
// (they keep their corners when the edge pair's point lies on one), each at its
// separation from the reference face's plane but no deeper than the edge pair's (along
// its normal, the separating axis, no point of the two lies deeper), reduced to four
// along the edge pair's normal.
int edge_with_face(const Manifold3& edge, int n_edge, double sep_e, const Manifold3& face,
                   int n_face, double tol, Manifold3& out) {
  // (the edge pair beyond reach, as its separation rounds: so is every point, none being
  // nearer along the separating axis; and `edge` has no normal)
  if (n_edge == 0) return 0;
  if (n_face == 0) {
    out = edge;
    return n_edge;
  }
  double deepest = INF;  // m
  for (int k = 0; k < n_face; ++k) deepest = std::min(deepest, face.separation[k]);
  if (dot(edge.normal, face.normal) >= EDGE_FACE_SAME && std::fabs(deepest - sep_e) <= tol) {
    out = face;
    return n_face;
  }
  const auto get = [&](int i, Vec3& p, double& s, std::int64_t& id) {
    const Manifold3& m = i < n_face ? face : edge;
    const int k = i < n_face ? i : i - n_face;
    p = m.point[k];
    s = std::max(m.separation[k], sep_e);
    id = m.id[k];
    return true;
  };
  return reduce_to_four(n_face + n_edge, get, edge.normal, out);
}

// One point at the closest points of edges p1-q1 (of a) and p2-q2 (of b), normal n (b -> a).
inline int edge_contact(Vec3 p1, Vec3 q1, Vec3 p2, Vec3 q2, Vec3 n, std::int64_t fid,
                        double speculative, Manifold3& out) {
  const auto [s, t] = segment_closest_fractions(p1, q1, p2, q2);
  const Vec3 ca = p1 + s * (q1 - p1), cb = p2 + t * (q2 - p2);
  return single_point(ca, 0.0, cb, 0.0, n, fid, speculative, out);
}

// The least of n · (v − o) over the points v[0 .. count) (m) and the first point that
// gives it, four at a time in lanes (each as dot() rounds it). With o = 0 it is the point
// least along n; over a hull's face normals with n = −t, the face most along t.
struct Least {
  double value = INF;
  int index = 0;
};
inline Least least_along(Vec3 n, Vec3 o, const Vec3* v, int count) {
  Least out;
  int j = 0;
  if (count >= LANES) {
    const Lanes ox = splat(o.x), oy = splat(o.y), oz = splat(o.z);
    Lanes least = splat(INF), at = splat(0.0), lane = Lanes{0.0, 1.0, 2.0, 3.0};
    for (; j + LANES <= count; j += LANES, lane += splat(LANES)) {
      const LanesXYZ p = load_xyz(v + j);
      const Lanes d = dot(n, LanesXYZ{p.x - ox, p.y - oy, p.z - oz});
      const LaneMask lower = d < least;  // (a lane keeps its first least)
      least = select(lower, d, least);
      at = select(lower, lane, at);
    }
    // the least of the lanes, and the first of the lanes that hold it
    const Lanes half = vmin(least, __builtin_shufflevector(least, least, 2, 3, 0, 1));
    const Lanes all = vmin(half, __builtin_shufflevector(half, half, 1, 0, 3, 2));
    const Lanes firsts = select(least == all, at, splat(INF));
    const Lanes half_at = vmin(firsts, __builtin_shufflevector(firsts, firsts, 2, 3, 0, 1));
    out.value = all[0];
    out.index = static_cast<int>(std::min(half_at[0], half_at[1]));
  }
  for (; j < count; ++j) {
    const double d = dot(n, v[j] - o);
    if (d < out.value) out = {d, j};
  }
  return out;
}

// The face of P most anti-parallel to n (first on ties).
inline int incident_face(const Polytope& P, Vec3 n) {
  return least_along(n, Vec3{}, P.fn, P.h->face_count).index;
}

// A polytope's face planes, for the bounds that pass over its faces and edges: each
// face's offset d_f = n_f · o_f (m; o_f its loop's first vertex), for its first
// PLANE_TABLE faces (a face past them is never passed over), and what a bound
// n_f · x − d_f allows (m) for round-off (of the product and the offset: far above 1e-16
// of the coordinates, far below any separation that matters) and for a face's vertices
// off its plane (HullView::flatness).
constexpr int PLANE_TABLE = 256;
struct FacePlanes {
  int count = 0;        // faces with an offset: min(F, PLANE_TABLE)
  double extent = 0.0;  // m: the largest |v|_1 of the polytope's vertices
  double flatness = 0.0;
  const double* d = nullptr;  // the offsets: the polytope's own (Polytope::d), else `made`
  double made[PLANE_TABLE];
  double allowance(Vec3 x) const {
    return 1e-9 * (1.0 + std::fabs(x.x) + std::fabs(x.y) + std::fabs(x.z) + extent) + flatness;
  }
};
// (extent: HullSpread's, m)
inline void face_planes(const Polytope& P, double extent, FacePlanes& out) {
  out.count = std::min(P.h->face_count, PLANE_TABLE);
  out.flatness = P.h->flatness;
  out.extent = extent;
  if (P.d) {
    out.d = P.d;
    return;
  }
  for (int f = 0; f < out.count; ++f) out.made[f] = dot(P.fn[f], face_origin(P, f));
  out.d = out.made;
}

// Which of P's faces first .. first + LANES may rise to `level` (m) over the point x: bit
// l for face first + l, clear where n_f · x − d_f plus the allowance is below `level`
// (every bit set past the table; lanes past the faces are left to the caller).
inline unsigned faces_reaching(const Polytope& P, const FacePlanes& planes, int first, Vec3 x,
                               double level) {
  if (first + LANES > planes.count) {
    unsigned bits = 0;
    for (int l = 0; l < LANES; ++l) {
      const int f = first + l;
      if (f >= planes.count || dot(P.fn[f], x) - planes.d[f] + planes.allowance(x) >= level)
        bits |= 1u << l;
    }
    return bits;
  }
  const LanesXYZ n = load_xyz(P.fn + first);
  Lanes d;
  std::memcpy(&d, planes.d + first, sizeof d);
  return lane_bits(dot(x, n) - d + splat(planes.allowance(x)) >= splat(level));
}

// The face of P that separates Q most (its deepest vertex below the face): separation
// (m), face and that vertex of Q (the first that gives the separation). False as soon as
// one face separates them by more than `speculative`.
// The face most along `toward` (from P towards Q) is measured first, and the vertex x of
// Q deepest below it kept: another face's separation is at most n · (x − o), and a face
// whose bound is below the first face's separation is passed over, its vertices not
// visited (it can neither be the deepest nor tie with it; most faces, those whose planes
// pass far from where the two touch). The others are measured in order, so that the
// result is that of measuring every face (ties to the lower index).
inline bool deepest_face(const Polytope& P, const FacePlanes& planes, const Polytope& Q,
                         Vec3 toward, double speculative, double& sep, int& face, int& vertex) {
  const int first = least_along(-toward, Vec3{}, P.fn, P.h->face_count).index;
  // the first face's separation and the vertex that gives it
  const Least deepest = least_along(P.fn[first], face_origin(P, first), Q.v, Q.h->vertex_count);
  const double reached = deepest.value;
  const Vec3 x = Q.v[deepest.index];
  if (reached > speculative) return false;
  sep = -INF;
  face = 0;
  vertex = 0;
  const int count = P.h->face_count;
  for (int f0 = 0; f0 < count; f0 += LANES) {
    unsigned bits = faces_reaching(P, planes, f0, x, reached);
    if (first >= f0 && first < f0 + LANES) bits |= 1u << (first - f0);
    bits &= (1u << std::min(LANES, count - f0)) - 1;
    for (; bits; bits &= bits - 1) {
      const int f = f0 + std::countr_zero(bits);
      const Least at =
          f == first ? deepest : least_along(P.fn[f], face_origin(P, f), Q.v, Q.h->vertex_count);
      if (at.value > speculative) return false;
      if (at.value > sep) {
        sep = at.value;
        face = f;
        vertex = at.index;
      }
    }
  }
  return true;
}

// The mean of a polytope's vertices (m): a point inside it; and the largest |v|_1 of
// them (m), for the round-off of the bounds against its face planes (FacePlanes): the
// transform stage's where it made them.
inline HullSpread vertex_spread(const Polytope& P) {
  return P.spread ? *P.spread : hull_spread(P.v, P.h->vertex_count);
}

// Which of P's edges may be in an edge pair that separates more than `least` (m, <= 0)
// from a convex body holding the points x[0] and x[1]. Along any direction L of an edge's
// Gauss-map arc the edge supports its hull, and the other body reaches no further than
// L · (x − p) (p on the edge); over the arc that is at most the larger of its two faces'
// n · (x − p) when that is negative (L a positive combination of the two normals, no
// longer than their sum), and n · (x − p) is at most the face's bound n · x − d (p lies
// on both faces' planes, up to their flatness). So an edge is out of reach when, for one
// of the points, both its faces' bounds are below `least`: bit k of mark[f] is set where
// face f's bound over x[k] is below it (none past the plane table), and an edge whose two
// faces' marks share a bit is passed over. Any point of the body gives a bound: its vertex mean
// passes over the edges that face away from it, the vertex deepest below the hull's best
// face those away from where the two touch.
inline void edge_marks(const Polytope& P, const FacePlanes& planes, const Vec3* x, double least,
                       std::uint8_t* mark) {
  // the four bits of a group of faces, each to its own byte
  constexpr auto spread = [](unsigned bits) {
    return (bits & 1u) | (bits & 2u) << 7 | (bits & 4u) << 14 | (bits & 8u) << 21;
  };
  for (int f0 = 0; f0 < planes.count; f0 += LANES) {
    const unsigned below0 = ~faces_reaching(P, planes, f0, x[0], least) & 15u;
    const unsigned below1 = ~faces_reaching(P, planes, f0, x[1], least) & 15u;
    const std::uint32_t bytes = spread(below0) | spread(below1) << 1;
    std::memcpy(mark + f0, &bytes, sizeof bytes);  // (the table has room for a whole group)
  }
  mark[PLANE_TABLE] = 0;  // a face past the table: no bound
}
// Bit l of the result for P's edge first + l (l < n <= 64): whether it is in reach
// (edge_marks).
inline std::uint64_t edges_in_reach(const Polytope& P, int first, int n, const std::uint8_t* mark) {
  std::uint64_t bits = 0;
  for (int l = 0; l < n; ++l) {
    const HullEdge& e = P.h->edge[first + l];
    const unsigned out = mark[std::min(e.f0, PLANE_TABLE)] & mark[std::min(e.f1, PLANE_TABLE)];
    bits |= std::uint64_t{out == 0} << l;
  }
  return bits;
}

// Two hulls (or boxes taken as hulls): SAT over both hulls' faces and their edge pairs.
// The edge pairs are tested a group of B's edges against every edge of A at a time, B's
// edges made arcs once per group (EDGE_GROUP of them: a few kilobytes on the stack); of
// pairs that separate equally the first in (A's edge, B's edge) order is kept. An edge
// pair counts only if it separates more than both hulls' faces (it must, to be the
// contact or to part the hulls beyond reach), so an edge that faces away from the other
// hull or lies away from where the two touch (edge_marks) is left out of the pairs.
constexpr int HULL_CLIP = 2 * HULL_MAX_FACE_VERTICES;
constexpr int EDGE_GROUP = 16 * LANES;
// The incident face clipped to nothing, though the axes found the two within reach: on
// hulls of many small faces the one most anti-parallel to the reference normal need not
// lie over the reference face (two rocks of 30 points, 12 cm into each other, had no
// point, so no manifold, and went on through each other for 15 steps). One point then,
// at inc's vertex deepest below the reference face (reference face rf, outward unit
// normal n_ref, through origin), its separation the face's.
int deepest_below(const Polytope& inc, Vec3 n_ref, Vec3 origin, int ref_is_b, int rf,
                  double speculative, Manifold3& out) {
  const Least deepest = least_along(n_ref, origin, inc.v, inc.h->vertex_count);
  const Vec3 x = inc.v[deepest.index];
  out.normal = ref_is_b ? n_ref : -n_ref;
  out.point[0] = x - (0.5 * deepest.value) * n_ref;
  out.separation[0] = deepest.value;
  out.id[0] = feature_id(FK::Single, ref_is_b, rf, 0, 0) | feature_id(FK::Vertex, 0, 0, deepest.index, 0);
  return deepest.value <= speculative ? 1 : 0;
}

int collide_polytopes(const Polytope& A, const Polytope& B, double tol, double speculative,
                      Manifold3& out) {
  const HullSpread spread_a = vertex_spread(A), spread_b = vertex_spread(B);
  const Vec3 mean_a = spread_a.mean, mean_b = spread_b.mean;
  FacePlanes planes_a, planes_b;
  face_planes(A, spread_a.extent, planes_a);
  double sep_a, sep_b;
  int face_a, face_b, deep_a, deep_b;  // (deep_b: B's vertex deepest below face_a)
  if (!deepest_face(A, planes_a, B, mean_b - mean_a, speculative, sep_a, face_a, deep_b)) return 0;
  face_planes(B, spread_b.extent, planes_b);
  if (!deepest_face(B, planes_b, A, mean_a - mean_b, speculative, sep_b, face_b, deep_a)) return 0;
  // an edge pair must separate more than this to matter (m)
  const double least = std::min(std::max(sep_a, sep_b), 0.0);
  // the edges in reach (edge_marks) of each hull from two points of the other: its vertex
  // mean, and its vertex deepest below the first's best face (any point of it bounds them)
  std::uint8_t mark_a[PLANE_TABLE + LANES], mark_b[PLANE_TABLE + LANES];
  {
    const Vec3 in_a[2] = {mean_a, A.v[deep_a]}, in_b[2] = {mean_b, B.v[deep_b]};
    edge_marks(A, planes_a, in_b, least, mark_a);
    edge_marks(B, planes_b, in_a, least, mark_b);
  }
  // edge pairs that make a face of the Minkowski difference
  double sep_e = -INF;
  int edge_a = -1, edge_b = -1;
  Vec3 axis_e{};
  const int n_b = B.h->edge_count;
  EdgeArcs arcs[EDGE_GROUP / LANES];
  int group[EDGE_GROUP];  // B's edges of the group (in order)
  for (int j = 0; j < n_b;) {
    int n_group = 0;
    while (j < n_b && n_group < EDGE_GROUP) {
      const int n = std::min({64, n_b - j, EDGE_GROUP - n_group});
      for (std::uint64_t bits = edges_in_reach(B, j, n, mark_b); bits; bits &= bits - 1)
        group[n_group++] = j + std::countr_zero(bits);
      j += n;
    }
    for (int k = 0; k < n_group; k += LANES)
      arcs[k / LANES] = edge_arcs(B, group + k, std::min(LANES, n_group - k));
    const int n_a = A.h->edge_count;
    for (int i0 = 0; i0 < n_a; i0 += 64) {
      const std::uint64_t reach = edges_in_reach(A, i0, std::min(64, n_a - i0), mark_a);
      for (std::uint64_t left = reach; left; left &= left - 1) {
        const int i = i0 + std::countr_zero(left);
        const HullEdge& ea = A.h->edge[i];
        const Vec3 pa = A.v[ea.v0], da = A.v[ea.v1] - pa;
        const Vec3 na0 = A.fn[ea.f0], na1 = A.fn[ea.f1];
        const Vec3 bxa = cross(na1, na0);
        for (int k = 0; k < n_group; k += LANES) {
          for (unsigned bits = minkowski_faces(na0, na1, bxa, arcs[k / LANES]); bits; bits &= bits - 1) {
            const int jb = group[k + std::countr_zero(bits)];
            const HullEdge& eb = B.h->edge[jb];
            const Vec3 pb = B.v[eb.v0], db = B.v[eb.v1] - pb;
            Vec3 L = cross(da, db);
            const double len = length(L);
            if (len <= EDGE_PARALLEL_SIN * length(da) * length(db)) continue;
            if (dot(L, pa - mean_a) < 0.0) L = -L;  // out of A
            const double s = dot(L, pb - pa) / len;
            if (s > speculative) return 0;
            // (a later group's pair comes after an earlier group's only if its A edge does)
            if (s > sep_e || (s == sep_e && i < edge_a)) {
              sep_e = s;
              edge_a = i;
              edge_b = jb;
              axis_e = (1.0 / len) * L;
            }
          }
        }
      }
    }
  }

  const int ref_is_b = sep_b > sep_a + tol ? 1 : 0;
  const double face_sep = ref_is_b ? sep_b : sep_a;
  const Polytope& ref = ref_is_b ? B : A;
  const Polytope& inc = ref_is_b ? A : B;
  const int rf = ref_is_b ? face_b : face_a;
  const Vec3 n_ref = ref.fn[rf];
  Unset<Vec3, HULL_MAX_FACE_VERTICES> loop;
  const int s = ref.h->face_start[rf], e = ref.h->face_start[rf + 1];
  const auto clip = [&](Manifold3& m) {
    ClipPolygon<HULL_CLIP> poly;
    incident_polygon(inc, incident_face(inc, n_ref), poly);
    for (int k = s; k < e; ++k) loop[k - s] = ref.v[ref.h->face_vertex[k]];
    return face_contact(loop.data(), e - s, n_ref, poly, ref_is_b, rf, tol, speculative, m);
  };
  if (edge_a >= 0 && edge_wins(sep_e, face_sep, tol)) {
    const HullEdge& ea = A.h->edge[edge_a];
    const HullEdge& eb = B.h->edge[edge_b];
    Manifold3 m, face;
    const int n_edge = edge_contact(A.v[ea.v0], A.v[ea.v1], B.v[eb.v0], B.v[eb.v1], -axis_e,
                                    feature_id(FK::EdgeEdge, 0, 0, edge_a, edge_b), speculative, m);
    // (both normals from b towards a)
    const bool near = dot(axis_e, ref_is_b ? -n_ref : n_ref) >= EDGE_FACE_COS;
    return edge_with_face(m, n_edge, sep_e, face, near ? clip(face) : 0, tol, out);
  }
  const int n = clip(out);
  if (n > 0) return n;
  return deepest_below(inc, n_ref, loop[0], ref_is_b, rf, speculative, out);
}

// A box as a polytope: its corners and face normals in the caller's arrays.
inline Polytope box_polytope(const ShapeRef3& box, Vec3* corners, Vec3* normals) {
  box_geometry(box, corners, normals);
  return {corners, normals, &box_hull()};
}
inline Polytope hull_polytope(const ShapeRef3& s) {
  return {s.verts, s.face_normals, &s.hull, s.face_offsets, s.spread};
}

// The corners of a polytope within reach of a plane (b): up to four, reduced. The plane is
// the reference face, and the corners are the incident face's (the polytope's face most
// anti-parallel to the plane's normal), as in a face contact between polytopes, with the
// deepest corner should it lie off that face (a hull's face most anti-parallel need not
// hold it; a box's always does). Taken from all the corners within reach, a plate
// thinner than the speculative distance (1 cm against 2 cm) had its upper face's corners
// too, which the reduction, keeping the corners that reach furthest out, chose over the
// lower ones they stand over: tilted by 1e-3 rad, a 1 m steel plate rested on two
// corners and two points 1 cm above the ground, sank 3 mm into it and rocked for ever;
// and a hull's corners just off its resting face, on the bevels or the next sides, won
// the reduction (a brick with 2 cm bevels rested on one corner and three gaps, a 64-sided
// prism lying on a side rocked at 0.06 rad/s). Every corner of the incident face within
// reach is a candidate, however high: where only those within the face tolerance of the
// deepest were kept (they were, for the bevels, before the incident face was), a coin (a
// 16-sided hull 2 mm thick) landing tilted by a few hundredths of a radian was held at its
// low side alone, while its high side, left out, went through the plane within the step,
// and it sank below the ground step after step.
int polytope_plane(const Polytope& P, const ShapeRef3& plane, double speculative, Manifold3& out) {
  const Vec3 n = plane.normal;
  std::array<int, HULL_MAX_FACE_VERTICES + 1> corner;  // the candidates' vertex indices
  const int f = incident_face(P, n);
  int count = 0;
  for (int k = P.h->face_start[f]; k < P.h->face_start[f + 1]; ++k)
    corner[count++] = P.h->face_vertex[k];
  const int deepest_vertex = least_along(n, Vec3{}, P.v, P.h->vertex_count).index;
  if (std::find(corner.begin(), corner.begin() + count, deepest_vertex) == corner.begin() + count)
    corner[count++] = deepest_vertex;
  // in vertex order, as when every corner was a candidate: where those within reach are
  // the incident face's (any box thicker than the reach), the same points in the same order
  std::sort(corner.begin(), corner.begin() + count);
  auto separation = [&](int i) { return dot(n, P.v[corner[i]]) - plane.offset; };  // m
  const auto get = [&](int i, Vec3& p, double& s, std::int64_t& id) {
    s = separation(i);
    p = P.v[corner[i]] - (0.5 * s) * n;
    id = feature_id(FK::Vertex, 0, 0, corner[i], 0);
    return s <= speculative;
  };
  return reduce_to_four(count, get, n, out);
}

// ---------------------------------------------------------------------------------------
// Pair functions (a, b): the normal from b towards a

int collide_sphere_sphere(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 d = a.center - b.center;
  const double dist = length(d);
  if (dist - a.radius - b.radius > speculative) return 0;
  // concentric: any direction separates them equally well
  const Vec3 n = dist > LINEAR_EPSILON ? (1.0 / dist) * d : UP;
  return single_point(a.center, a.radius, b.center, b.radius, n, 0, speculative, out);
}

int collide_sphere_plane(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 n = b.normal;
  const double sep = dot(n, a.center) - b.offset - a.radius;
  if (sep > speculative) return 0;
  out.normal = n;
  out.point[0] = a.center - (a.radius + 0.5 * sep) * n;
  out.separation[0] = sep;
  out.id[0] = 0;
  return 1;
}

// Sphere a against box b: the closest point of the box to the centre; a centre inside
// pushes out through the nearest face.
int collide_sphere_box(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 r = a.center - b.center;
  const double local[3] = {dot(r, b.axes[0]), dot(r, b.axes[1]), dot(r, b.axes[2])};
  const double half[3] = {b.half.x, b.half.y, b.half.z};
  double clamped[3];
  bool outside = false;
  for (int k = 0; k < 3; ++k) {
    clamped[k] = std::min(std::max(local[k], -half[k]), half[k]);
    outside = outside || clamped[k] != local[k];
  }
  if (outside) {
    const Vec3 p = b.center + clamped[0] * b.axes[0] + clamped[1] * b.axes[1] + clamped[2] * b.axes[2];
    const Vec3 d = a.center - p;
    const double dist = length(d);
    if (dist - a.radius > speculative) return 0;
    // dist > 0 (some coordinate was clamped); at round-off size the face normal is as good
    const int k = std::fabs(local[0]) - half[0] >= std::fabs(local[1]) - half[1]
                      ? (std::fabs(local[0]) - half[0] >= std::fabs(local[2]) - half[2] ? 0 : 2)
                      : (std::fabs(local[1]) - half[1] >= std::fabs(local[2]) - half[2] ? 1 : 2);
    const Vec3 n = dist > LINEAR_EPSILON ? (1.0 / dist) * d
                                         : (local[k] >= 0.0 ? b.axes[k] : -b.axes[k]);
    return single_point(a.center, a.radius, p, 0.0, n, 0, speculative, out);
  }
  int k = 0;
  double depth = INF;
  for (int j = 0; j < 3; ++j) {
    const double dj = half[j] - std::fabs(local[j]);
    if (dj < depth) {
      depth = dj;
      k = j;
    }
  }
  const Vec3 n = local[k] >= 0.0 ? b.axes[k] : -b.axes[k];
  const Vec3 p = a.center + depth * n;  // on the face
  return single_point(a.center, a.radius, p, 0.0, n, 0, speculative, out);
}

int collide_sphere_capsule(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 p = closest_on_segment(a.center, b.p, b.q);
  const Vec3 d = a.center - p;
  const double dist = length(d);
  if (dist - a.radius - b.radius > speculative) return 0;
  // centre on the core: any direction across the segment
  const Vec3 n = dist > LINEAR_EPSILON ? (1.0 / dist) * d : perpendicular(b.q - b.p);
  return single_point(a.center, a.radius, p, b.radius, n, 0, speculative, out);
}

int collide_sphere_convex(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const SurfacePoint c = closest_on_hull(hull_polytope(b), a.center);
  if (c.distance - a.radius > speculative) return 0;
  return single_point(a.center, a.radius, c.point, 0.0, c.normal, 0, speculative, out);
}

// Capsule a against capsule b: two points at the ends of their common stretch when they
// lie parallel; else one at the segments' closest points, with the stretch's ends within
// reach.
int collide_capsule_capsule(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 d1 = a.q - a.p, d2 = b.q - b.p;
  const auto [s, t] = segment_closest_fractions(a.p, a.q, b.p, b.q);
  const Vec3 ca = a.p + s * d1, cb = b.p + t * d2;
  const Vec3 d = ca - cb;
  const double dist = length(d);
  const double radius = a.radius + b.radius;
  if (dist - radius > speculative) return 0;
  const double l1 = dot(d1, d1), l2 = dot(d2, d2);
  constexpr double tiny = LINEAR_EPSILON * LINEAR_EPSILON;
  // the cores cross (or a core is a point on the other): across both, or across one
  Vec3 n;
  if (dist > LINEAR_EPSILON) {
    n = (1.0 / dist) * d;
  } else {
    const Vec3 c = cross(d1, d2);
    const double lc = length(c);
    if (lc > LINEAR_EPSILON * LINEAR_EPSILON) {
      n = (1.0 / lc) * c;
      if (dot(n, (a.p + a.q) - (b.p + b.q)) < 0.0) n = -n;
    } else {
      n = perpendicular(l1 >= l2 ? d1 : d2);
    }
  }
  if (l1 <= tiny || l2 <= tiny) return single_point(ca, a.radius, cb, b.radius, n, 0, speculative, out);
  // b's ends on a's line (fractions of a), their common stretch [lo, hi]
  const double u0 = dot(b.p - a.p, d1) / l1, u1 = dot(b.q - a.p, d1) / l1;
  const bool b_reversed = u1 < u0;
  const double b_lo = b_reversed ? u1 : u0, b_hi = b_reversed ? u0 : u1;
  const double lo = std::max(0.0, b_lo), hi = std::min(1.0, b_hi);
  const Vec3 c12 = cross(d1, d2);
  if (dot(c12, c12) <= CAPSULE_PARALLEL_SIN * CAPSULE_PARALLEL_SIN * l1 * l2 &&
      (hi - lo) * std::sqrt(l1) > LINEAR_EPSILON) {
    int count = 0;
    for (int k = 0; k < 2; ++k) {
      const double u = k == 0 ? lo : hi;
      const Vec3 xa = a.p + u * d1;
      const Vec3 xb = closest_on_segment(xa, b.p, b.q);
      const double sep = dot(xa - xb, n) - radius;
      if (sep > speculative) continue;
      // which end made this end of the stretch: a's own (1, 2) or b's (1, 2)
      int end_a = 0, end_b = 0;
      if (k == 0) {
        if (lo == 0.0 && b_lo <= 0.0) end_a = 1;
        else end_b = b_reversed ? 2 : 1;
      } else {
        if (hi == 1.0 && b_hi >= 1.0) end_a = 2;
        else end_b = b_reversed ? 1 : 2;
      }
      out.point[count] = 0.5 * ((xa - a.radius * n) + (xb + b.radius * n));
      out.separation[count] = sep;
      out.id[count] = feature_id(FK::CapsuleEnd, 0, 0, end_a, end_b);
      ++count;
    }
    out.normal = n;
    return count;
  }
  // Crossing: the closest points, and the ends of the common stretch where they are
  // within reach, each at its own distance (never less than the closest points'), along
  // the closest points' normal. A capsule falling across another at 14°, touching near
  // one end, brought its other end down within the step, 11 mm into the other, while its
  // one point lifted off (capsules200). An end within the radii's half of the closest
  // point along a adds nothing and is left out.
  int count = single_point(ca, a.radius, cb, b.radius, n, 0, speculative, out);
  const double apart = 0.5 * radius / std::sqrt(l1);  // fraction of a
  for (int k = 0; k < 2 && count > 0; ++k) {
    const double u = k == 0 ? lo : hi;
    if (std::fabs(u - s) <= apart) continue;
    const Vec3 xa = a.p + u * d1;
    const Vec3 xb = closest_on_segment(xa, b.p, b.q);
    const double sep = length(xa - xb) - radius;
    if (sep > speculative) continue;
    out.point[count] = 0.5 * ((xa - a.radius * n) + (xb + b.radius * n));
    out.separation[count] = std::max(sep, out.separation[0]);
    out.id[count] = feature_id(FK::CapsuleEnd, 0, 0, k + 1, 3);
    ++count;
  }
  return count;
}

int collide_capsule_plane(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 n = b.normal;
  // a point-like capsule is a sphere: one point
  const int ends = length_squared(a.q - a.p) > LINEAR_EPSILON * LINEAR_EPSILON ? 2 : 1;
  int count = 0;
  for (int k = 0; k < ends; ++k) {
    const Vec3 x = k == 0 ? a.p : a.q;
    const double sep = dot(n, x) - b.offset - a.radius;
    if (sep > speculative) continue;
    out.point[count] = x - (a.radius + 0.5 * sep) * n;
    out.separation[count] = sep;
    out.id[count] = feature_id(FK::Vertex, 0, 0, k, 0);
    ++count;
  }
  out.normal = n;
  return count;
}

// Capsule a lying on face f of polytope B: its segment clipped to the face's side
// planes, a point at each end of what is left (Cyrus–Beck). Returns -1 when nothing is
// left (the segment is not over the face).
int capsule_on_face(const ShapeRef3& a, const Polytope& B, int f, double speculative,
                    Manifold3& out) {
  const Vec3 d = a.q - a.p;
  const Vec3 n = B.fn[f];
  double lo = 0.0, hi = 1.0;
  int side_lo = -1, side_hi = -1;  // the side plane that cut each end (-1: the segment's end)
  const int s = B.h->face_start[f], e = B.h->face_start[f + 1];
  for (int k = s; k < e; ++k) {
    const Vec3 v0 = B.v[B.h->face_vertex[k]];
    const Vec3 v1 = B.v[B.h->face_vertex[k + 1 < e ? k + 1 : s]];
    const Vec3 side = cross(v1 - v0, n);
    const double g0 = dot(side, a.p - v0), dg = dot(side, d);  // g(t) = g0 + t dg <= 0
    if (dg == 0.0) {
      if (g0 > 0.0) return -1;
      continue;
    }
    const double t = -g0 / dg;
    if (dg > 0.0) {
      if (t < hi) { hi = t; side_hi = k - s; }
    } else {
      if (t > lo) { lo = t; side_lo = k - s; }
    }
  }
  if (lo > hi) return -1;
  const Vec3 o = B.v[B.h->face_vertex[s]];
  const int ends = (hi - lo) * length(d) > LINEAR_EPSILON ? 2 : 1;
  int count = 0;
  for (int k = 0; k < ends; ++k) {
    const double t = k == 0 ? lo : hi;
    const int side = k == 0 ? side_lo : side_hi;
    const Vec3 x = a.p + t * d;
    const double depth = dot(n, x - o);
    const double sep = depth - a.radius;
    if (sep > speculative) continue;
    out.point[count] = x - (0.5 * (a.radius + depth)) * n;
    out.separation[count] = sep;
    out.id[count] = side < 0 ? feature_id(FK::Vertex, 1, f, k, 0)
                             : feature_id(FK::EdgeSide, 1, f, 0, side);
    ++count;
  }
  out.normal = n;
  return count;
}

// The closest points of the segment p + s (q − p), s in [0, 1], and the box (a segment
// apart from it): xs on the segment and xh on the box (m), and their distance. In the
// box's frame the squared distance of a point from the box is the sum over the axes of
// (|x_i| − h_i)² where |x_i| > h_i; along the segment it is a convex piecewise quadratic
// in s, its pieces split where a coordinate crosses ±h_i. The pieces' minima (each a
// quadratic's, held to its interval) give the least; a tie keeps the smaller s. The box
// point is the segment point's coordinates held to the box.
double segment_box_closest(Vec3 p, Vec3 q, const ShapeRef3& box, Vec3& xs, Vec3& xh) {
  const Vec3 c = box.center;
  const double h[3] = {box.half.x, box.half.y, box.half.z};
  double p0[3], dd[3];
  for (int i = 0; i < 3; ++i) {
    p0[i] = dot(p - c, box.axes[i]);
    dd[i] = dot(q - p, box.axes[i]);
  }
  // the pieces' ends: 0, 1 and every crossing of a face's plane in between
  double cut[8] = {0.0, 1.0};
  int n = 2;
  for (int i = 0; i < 3; ++i) {
    if (dd[i] == 0.0) continue;
    for (const double side : {-h[i], h[i]}) {
      const double t = (side - p0[i]) / dd[i];
      if (t > 0.0 && t < 1.0) cut[n++] = t;
    }
  }
  std::sort(cut, cut + n);
  double best = INF, best_s = 0.0;
  for (int k = 0; k + 1 < n; ++k) {
    const double lo = cut[k], hi = cut[k + 1];
    const double mid = 0.5 * (lo + hi);
    // the piece's quadratic a s² + b s (+ const): the axes outside the box there
    double a2 = 0.0, b1 = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double x = p0[i] + mid * dd[i];
      const double edge = x > h[i] ? h[i] : (x < -h[i] ? -h[i] : x);
      if (edge == x) continue;  // inside the slab: no term
      a2 += dd[i] * dd[i];
      b1 += 2.0 * dd[i] * (p0[i] - edge);
    }
    const double s = a2 > 0.0 ? std::clamp(-b1 / (2.0 * a2), lo, hi) : lo;
    double f = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double x = p0[i] + s * dd[i];
      const double out = x > h[i] ? x - h[i] : (x < -h[i] ? x + h[i] : 0.0);
      f += out * out;
    }
    if (f < best) {
      best = f;
      best_s = s;
    }
  }
  Vec3 local{};
  double* l = &local.x;
  for (int i = 0; i < 3; ++i) l[i] = std::clamp(p0[i] + best_s * dd[i], -h[i], h[i]);
  xs = p + best_s * (q - p);
  xh = c + (local.x * box.axes[0] + local.y * box.axes[1]) + local.z * box.axes[2];
  return length(xs - xh);
}

// Capsule a against polytope B (a hull, or a box taken as one).
//
// Separating axes of the core: B's face normals and the cross products of the segment
// with B's edges. A core apart from B is measured exactly (the closest points of segment
// and hull); lying over a face (its closest point in the face's interior) it is clipped
// to that face for up to two points, else one point at the closest points. A core in B
// takes the axis that separates it least: a face (clipped) or an edge (one point).
// The edge axes are those of axis_edges[0 .. count) (nullptr: edges 0 .. count), one
// edge per direction being enough (a box: one per axis).
int capsule_polytope(const ShapeRef3& a, const Polytope& B, const std::int32_t* axis_edges,
                     int axis_edge_count, double tol, double speculative, Manifold3& out,
                     const ShapeRef3* box = nullptr) {
  const Vec3 p = a.p, q = a.q, d = q - p;
  const double r = a.radius;
  double sep_f = -INF;
  int face = 0;
  for (int f = 0; f < B.h->face_count; ++f) {
    const Vec3 o = face_origin(B, f);
    const double s = std::min(dot(B.fn[f], p - o), dot(B.fn[f], q - o));
    if (s - r > speculative) return 0;
    if (s > sep_f) {
      sep_f = s;
      face = f;
    }
  }
  double sep_e = -INF;
  int edge = -1;
  Vec3 axis_e{};
  const double ld = length(d);
  for (int k = 0; k < axis_edge_count; ++k) {
    const int i = axis_edges ? axis_edges[k] : k;
    const Vec3 de = B.v[B.h->edge[i].v1] - B.v[B.h->edge[i].v0];
    const Vec3 L = cross(d, de);
    const double len = length(L);
    if (len <= EDGE_PARALLEL_SIN * ld * length(de)) continue;
    double hmin = INF, hmax = -INF;
    for (int j = 0; j < B.h->vertex_count; ++j) {
      const double h = dot(L, B.v[j]);
      hmin = std::min(hmin, h);
      hmax = std::max(hmax, h);
    }
    const double sp = dot(L, p), sq = dot(L, q);
    const double above = std::min(sp, sq) - hmax;  // the capsule on B's +L side
    const double below = hmin - std::max(sp, sq);  // on its −L side
    const double s = std::max(above, below) / len;
    if (s - r > speculative) return 0;
    if (s > sep_e) {
      sep_e = s;
      edge = i;
      axis_e = (above >= below ? 1.0 / len : -1.0 / len) * L;
    }
  }

  if (std::max(sep_f, sep_e) > 0.0) {
    // apart: the exact closest points (a box: segment_box_closest; a hull: an end against
    // the hull, or the segment against an edge)
    double best = INF;
    Vec3 xs{}, xh{};
    if (box) {
      best = segment_box_closest(p, q, *box, xs, xh);
    } else {
      for (int k = 0; k < 2; ++k) {
        const Vec3 x = k == 0 ? p : q;
        const SurfacePoint c = closest_on_hull(B, x);
        if (c.distance < best) {
          best = c.distance;
          xs = x;
          xh = c.point;
        }
      }
      for (int i = 0; i < B.h->edge_count; ++i) {
        const Vec3 e0 = B.v[B.h->edge[i].v0], e1 = B.v[B.h->edge[i].v1];
        const auto [s, t] = segment_closest_fractions(p, q, e0, e1);
        const Vec3 cs = p + s * d, ch = e0 + t * (e1 - e0);
        const double dist = length(cs - ch);
        if (dist < best) {
          best = dist;
          xs = cs;
          xh = ch;
        }
      }
    }
    if (best - r > speculative) return 0;
    // over the face's interior the face's separation is the distance. Nearly over it (the
    // core's closest point off the face by up to LINEAR_SLOP's worth of distance) the
    // face's points serve too, their separations lowered together so that the least is
    // the true distance (it is never overstated): with the one point there, a capsule
    // tipping over a box's edge onto its face put its other end up to 7 mm into the box
    // within the step, and the deep overlap cost a heap's landing extra relax passes
    if (best <= sep_f + a.scale * constants::LINEAR_SLOP) {
      Manifold3 on_face;
      const int n = capsule_on_face(a, B, face, INF, on_face);
      if (n > 0) {
        double least = INF;
        for (int k = 0; k < n; ++k) least = std::min(least, on_face.separation[k]);
        const double over = least - (best - r);  // m: how far the face's points overstate it
        const double lower = over > LINEAR_EPSILON ? over : 0.0;
        int count = 0;
        for (int k = 0; k < n; ++k) {
          const double sep = on_face.separation[k] - lower;
          if (sep > speculative) continue;
          out.point[count] = on_face.point[k];
          out.separation[count] = sep;
          out.id[count] = on_face.id[k];
          ++count;
        }
        out.normal = on_face.normal;
        return count;
      }
    }
    const Vec3 dv = xs - xh;
    const double dist = length(dv);
    const Vec3 n = dist > LINEAR_EPSILON ? (1.0 / dist) * dv : B.fn[face];
    return single_point(xs, r, xh, 0.0, n, 0, speculative, out);
  }
  if (edge >= 0 && edge_wins(sep_e, sep_f, tol)) {
    // the edge along the axis's direction that supports B towards the capsule (its
    // parallel edges give the same axis)
    const Vec3 de = B.v[B.h->edge[edge].v1] - B.v[B.h->edge[edge].v0];
    double support = -INF;
    for (int i = 0; i < B.h->edge_count; ++i) {
      const Vec3 v0 = B.v[B.h->edge[i].v0], v1 = B.v[B.h->edge[i].v1];
      const Vec3 c = cross(v1 - v0, de);
      if (dot(c, c) > EDGE_PARALLEL_SIN * EDGE_PARALLEL_SIN * length_squared(v1 - v0) * dot(de, de)) continue;
      const double h = dot(axis_e, v0 + v1);
      if (h > support) {
        support = h;
        edge = i;
      }
    }
    const Vec3 e0 = B.v[B.h->edge[edge].v0], e1 = B.v[B.h->edge[edge].v1];
    const auto [s, t] = segment_closest_fractions(p, q, e0, e1);
    return single_point(p + s * d, r, e0 + t * (e1 - e0), 0.0, axis_e,
                        feature_id(FK::EdgeEdge, 0, 0, 0, edge), speculative, out);
  }
  const int n = capsule_on_face(a, B, face, speculative, out);
  if (n >= 0) return n;
  // the core dips into the face's plane outside the face: its deeper end
  const Vec3 o = face_origin(B, face);
  const Vec3 nf = B.fn[face];
  const int k = dot(nf, q - o) < dot(nf, p - o) ? 1 : 0;
  const Vec3 x = k ? q : p;
  return single_point(x, r, x - dot(nf, x - o) * nf, 0.0, nf,
                      feature_id(FK::Vertex, 1, face, k, 0), speculative, out);
}

// One box edge along each axis (edges of box_hull(), whose 12 edges come 4 to a direction).
const std::array<std::int32_t, 3> BOX_AXIS_EDGES = [] {
  std::array<std::int32_t, 3> first{-1, -1, -1};
  const HullView& h = box_hull();
  for (int e = 0; e < h.edge_count; ++e) {
    const int axis = BIT_AXIS[h.edge[e].v0 ^ h.edge[e].v1];
    if (first[axis] < 0) first[axis] = e;
  }
  return first;
}();

int collide_capsule_box(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  Vec3 corners[8], normals[6];
  return capsule_polytope(a, box_polytope(b, corners, normals), BOX_AXIS_EDGES.data(), 3,
                          face_tolerance(a, b), speculative, out, &b);
}

int collide_capsule_convex(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  return capsule_polytope(a, hull_polytope(b), nullptr, b.hull.edge_count, face_tolerance(a, b),
                          speculative, out);
}

// Box a against box b, the face contact: the reference face (of b if ref_is_b, else of a)
// is the one along the reference box's axis ri, on its positive side if ref_positive; the
// other box's face most anti-parallel to it is clipped to it. tol (m): the face tolerance.
int box_face_contact(const ShapeRef3& a, const ShapeRef3& b, int ref_is_b, int ri,
                     bool ref_positive, double tol, double speculative, Manifold3& out) {
  const ShapeRef3& ref = ref_is_b ? b : a;
  const ShapeRef3& inc = ref_is_b ? a : b;
  const Vec3 n_ref = ref_positive ? ref.axes[ri] : -ref.axes[ri];
  const int ref_face = 2 * ri + (ref_positive ? 1 : 0);
  // the incident face: the other box's face most anti-parallel to n_ref
  int ii = 0;
  double best = -1.0;
  for (int k = 0; k < 3; ++k) {
    const double c = std::fabs(dot(n_ref, inc.axes[k]));
    if (c > best) {
      best = c;
      ii = k;
    }
  }
  const bool inc_positive = dot(n_ref, inc.axes[ii]) < 0.0;
  const int inc_face = 2 * ii + (inc_positive ? 1 : 0);
  // Clip in the reference box's frame: the incident corners' coordinates along its axes,
  // so that each side plane is one coordinate against a half extent. Side k of the
  // reference face's loop (corner k to k+1) is the plane of the axis both corners'
  // other bit does not change: outward along that axis, with their sign on it.
  const HullView& topo = box_hull();
  const BoxCorners inc_corner(inc);
  const double hr[3] = {ref.half.x, ref.half.y, ref.half.z};
  ClipPolygon<8> poly;
  for (int k = 0; k < 4; ++k) {
    const int v = BOX_LOOP[inc_face][k];
    const Vec3 r = inc_corner[v] - ref.center;
    poly.push({dot(r, ref.axes[0]), dot(r, ref.axes[1]), dot(r, ref.axes[2])},
              feature_id(FK::Vertex, 0, 0, v, 0), topo.face_edge[topo.face_start[inc_face] + k]);
  }
  ClipPolygon<8> tmp;
  ClipPolygon<8>* cur = &poly;
  ClipPolygon<8>* nxt = &tmp;
  for (int k = 0; k < 4 && cur->n > 0; ++k) {
    const int c0 = BOX_LOOP[ref_face][k], c1 = BOX_LOOP[ref_face][(k + 1) & 3];
    const int m = 3 - ri - BIT_AXIS[c0 ^ c1];  // neither the face's axis nor the edge's
    const bool positive = (c0 >> m) & 1;
    const double h = hr[m] + tol;  // m: the side plane, moved out by the clip skin
    const auto dist = [m, positive, h](Vec3 x) {
      const double u = m == 0 ? x.x : (m == 1 ? x.y : x.z);
      return (positive ? u : -u) - h;
    };
    clip_polygon(*cur, dist, k, *nxt);
    std::swap(cur, nxt);
  }
  const ClipPolygon<8>& clipped = *cur;
  const std::int64_t ref_part = feature_id(FK::Single, ref_is_b, ref_face, 0, 0);
  const double h_face = hr[ri];
  const auto get = [&](int i, Vec3& p, double& s, std::int64_t& id) {
    const Vec3 l = clipped.p[i];
    const double along = ri == 0 ? l.x : (ri == 1 ? l.y : l.z);
    s = (ref_positive ? along : -along) - h_face;
    p = ref.center + l.x * ref.axes[0] + l.y * ref.axes[1] + l.z * ref.axes[2] - (0.5 * s) * n_ref;
    id = ref_part | clipped.id[i];
    return s <= speculative;
  };
  return reduce_to_four(clipped.n, get, ref_is_b ? n_ref : -n_ref, out);
}

// Box a against box b: SAT over the 15 axes (3 + 3 face normals, 9 edge cross products),
// then a face contact (the incident face clipped to the reference face) or, where an edge
// pair wins, its point with that face contact's (edge_with_face).
int collide_box_box(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const Vec3 d = a.center - b.center;  // b -> a
  const double ha[3] = {a.half.x, a.half.y, a.half.z};
  const double hb[3] = {b.half.x, b.half.y, b.half.z};
  // R[i][j] = a_i · b_j: b's axes in a's frame (its columns); t: d in a's frame
  double rot[3][3], abs_r[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      rot[i][j] = dot(a.axes[i], b.axes[j]);
      abs_r[i][j] = std::fabs(rot[i][j]);
    }
  const double t[3] = {dot(d, a.axes[0]), dot(d, a.axes[1]), dot(d, a.axes[2])};

  double sep_a = -INF, sep_b = -INF, sep_e = -INF;
  int axis_a = 0, axis_b = 0, edge_i = -1, edge_j = -1;
  for (int i = 0; i < 3; ++i) {
    const double s = std::fabs(t[i]) - ha[i] -
                     (hb[0] * abs_r[i][0] + hb[1] * abs_r[i][1] + hb[2] * abs_r[i][2]);
    if (s > speculative) return 0;
    if (s > sep_a) {
      sep_a = s;
      axis_a = i;
    }
  }
  double proj_b[3];
  for (int j = 0; j < 3; ++j) {
    proj_b[j] = dot(d, b.axes[j]);
    const double s = std::fabs(proj_b[j]) - hb[j] -
                     (ha[0] * abs_r[0][j] + ha[1] * abs_r[1][j] + ha[2] * abs_r[2][j]);
    if (s > speculative) return 0;
    if (s > sep_b) {
      sep_b = s;
      axis_b = j;
    }
  }
  // L = a_i × b_j in a's frame (i, i1, i2 and j, j1, j2 cyclic): |L|² = R[i1][j]² + R[i2][j]²,
  // d · L = t[i2] R[i1][j] − t[i1] R[i2][j]; a's extent along L is
  // ha[i1] |R[i2][j]| + ha[i2] |R[i1][j]|, b's hb[j1] |R[i][j2]| + hb[j2] |R[i][j1]|
  double proj_e = 0.0, len_e = 1.0;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const double len2 = rot[i1][j] * rot[i1][j] + rot[i2][j] * rot[i2][j];
      if (len2 <= EDGE_PARALLEL_SIN * EDGE_PARALLEL_SIN) continue;
      const double len = std::sqrt(len2);
      const double ra = ha[i1] * abs_r[i2][j] + ha[i2] * abs_r[i1][j];
      const double rb = hb[j1] * abs_r[i][j2] + hb[j2] * abs_r[i][j1];
      const double proj = t[i2] * rot[i1][j] - t[i1] * rot[i2][j];
      const double s = (std::fabs(proj) - ra - rb) / len;
      if (s > speculative) return 0;
      if (s > sep_e) {
        sep_e = s;
        edge_i = i;
        edge_j = j;
        proj_e = proj;
        len_e = len;
      }
    }
  }
  const double proj_a = t[axis_a];

  const double tol = face_tolerance(a, b);
  const int ref_is_b = sep_b > sep_a + tol ? 1 : 0;
  const double face_sep = ref_is_b ? sep_b : sep_a;
  // the reference face faces the other box: on a, against d; on b, along d
  const int ri = ref_is_b ? axis_b : axis_a;
  const bool ref_positive = ref_is_b ? proj_b[axis_b] >= 0.0 : proj_a < 0.0;
  if (edge_i < 0 || !edge_wins(sep_e, face_sep, tol))
    return box_face_contact(a, b, ref_is_b, ri, ref_positive, tol, speculative, out);
  // an edge pair wins: its point, and the face contact's (edge_with_face)
  // a's edge along axis i nearest b (towards −n), b's edge along axis j nearest a (+n)
  const Vec3 n = (proj_e >= 0.0 ? 1.0 / len_e : -1.0 / len_e) * cross(a.axes[edge_i], b.axes[edge_j]);
  int corner_a = 0, corner_b = 0;  // the edges' lower corners (sign bits)
  for (int k = 0; k < 3; ++k) {
    if (k != edge_i && dot(n, a.axes[k]) < 0.0) corner_a |= 1 << k;
    if (k != edge_j && dot(n, b.axes[k]) > 0.0) corner_b |= 1 << k;
  }
  const int upper_a = corner_a | 1 << edge_i, upper_b = corner_b | 1 << edge_j;
  Manifold3 m, face;
  const int n_edge =
      edge_contact(box_corner(a, corner_a), box_corner(a, upper_a), box_corner(b, corner_b),
                   box_corner(b, upper_b), n,
                   feature_id(FK::EdgeEdge, 0, 0, corner_a * 8 + upper_a, corner_b * 8 + upper_b),
                   speculative, m);
  // the reference face's normal, from b towards a (box_face_contact's manifold normal)
  const Vec3 n_face = (ref_is_b == (ref_positive ? 1 : 0) ? 1.0 : -1.0) * (ref_is_b ? b : a).axes[ri];
  const bool near = dot(n, n_face) >= EDGE_FACE_COS;
  return edge_with_face(
      m, n_edge, sep_e, face,
      near ? box_face_contact(a, b, ref_is_b, ri, ref_positive, tol, speculative, face) : 0, tol,
      out);
}

int collide_box_plane(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  Vec3 corners[8], normals[6];
  return polytope_plane(box_polytope(a, corners, normals), b, speculative, out);
}

int collide_box_convex(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  Vec3 corners[8], normals[6];
  return collide_polytopes(box_polytope(a, corners, normals), hull_polytope(b),
                           face_tolerance(a, b), speculative, out);
}

int collide_convex_box(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  Vec3 corners[8], normals[6];
  return collide_polytopes(hull_polytope(a), box_polytope(b, corners, normals),
                           face_tolerance(a, b), speculative, out);
}

int collide_convex_convex(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  return collide_polytopes(hull_polytope(a), hull_polytope(b), face_tolerance(a, b),
                           speculative, out);
}

int collide_convex_plane(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  return polytope_plane(hull_polytope(a), b, speculative, out);
}

// Two half-spaces: no manifold (planes are static ground).
int collide_none(const ShapeRef3&, const ShapeRef3&, double, Manifold3&) { return 0; }

using PairFn = int (*)(const ShapeRef3&, const ShapeRef3&, double, Manifold3&);

// A pair in the other order than its function's: the function with a and b swapped, the
// normal negated back (b -> a of the caller's order).
template <PairFn F>
int swapped(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const int n = F(b, a, speculative, out);
  out.normal = -out.normal;
  return n;
}

// [kind_a − SHAPE_KIND_FIRST_3D][kind_b − SHAPE_KIND_FIRST_3D], kinds in ShapeKind order:
// Sphere, Box, Capsule, Convex, Plane.
constexpr int KINDS_3D = SHAPE_KIND_END_3D - SHAPE_KIND_FIRST_3D;
static_assert(static_cast<int>(ShapeKind::Sphere) == SHAPE_KIND_FIRST_3D &&
                  static_cast<int>(ShapeKind::Box) == SHAPE_KIND_FIRST_3D + 1 &&
                  static_cast<int>(ShapeKind::Capsule) == SHAPE_KIND_FIRST_3D + 2 &&
                  static_cast<int>(ShapeKind::Convex) == SHAPE_KIND_FIRST_3D + 3 &&
                  static_cast<int>(ShapeKind::Plane) == SHAPE_KIND_FIRST_3D + 4 && KINDS_3D == 5,
              "COLLIDE's rows and columns are the 3D kinds in ShapeKind order");
constexpr PairFn COLLIDE[KINDS_3D][KINDS_3D] = {
    {collide_sphere_sphere, collide_sphere_box, collide_sphere_capsule, collide_sphere_convex,
     collide_sphere_plane},
    {swapped<collide_sphere_box>, collide_box_box, swapped<collide_capsule_box>,
     collide_box_convex, collide_box_plane},
    {swapped<collide_sphere_capsule>, collide_capsule_box, collide_capsule_capsule,
     collide_capsule_convex, collide_capsule_plane},
    {swapped<collide_sphere_convex>, collide_convex_box, swapped<collide_capsule_convex>,
     collide_convex_convex, collide_convex_plane},
    {swapped<collide_sphere_plane>, swapped<collide_box_plane>, swapped<collide_capsule_plane>,
     swapped<collide_convex_plane>, collide_none},
};

}  // namespace

const HullView& box_hull() {
  static const HullView view = box_hull3().view();
  return view;
}

void box_geometry(const ShapeRef3& box, Vec3* corners, Vec3* face_normals) {
  const BoxCorners corner(box);
  for (int k = 0; k < 8; ++k) corners[k] = corner[k];
  for (int i = 0; i < 3; ++i) {
    face_normals[2 * i] = -box.axes[i];
    face_normals[2 * i + 1] = box.axes[i];
  }
}

int collide3d(const ShapeRef3& a, const ShapeRef3& b, double speculative, Manifold3& out) {
  const auto ka = static_cast<unsigned>(static_cast<int>(a.kind) - SHAPE_KIND_FIRST_3D);
  const auto kb = static_cast<unsigned>(static_cast<int>(b.kind) - SHAPE_KIND_FIRST_3D);
  if (ka >= static_cast<unsigned>(KINDS_3D) || kb >= static_cast<unsigned>(KINDS_3D)) return 0;
  return COLLIDE[ka][kb](a, b, speculative, out);
}

int collide_on_face(const ShapeRef3& a, const ShapeRef3& b, int ref_is_b, int face,
                    double speculative, Manifold3& out) {
  const ShapeRef3& r = ref_is_b ? b : a;
  const ShapeRef3& o = ref_is_b ? a : b;
  Vec3 corners[8], normals[6];
  const Polytope P = r.kind == ShapeKind::Box ? box_polytope(r, corners, normals) : hull_polytope(r);
  const Vec3 n = P.fn[face];  // out of the reference shape
  const int s = P.h->face_start[face], e = P.h->face_start[face + 1];
  const Vec3 origin = P.v[P.h->face_vertex[s]];
  if (o.kind == ShapeKind::Sphere) {  // its centre's foot on the face's plane
    const Vec3 p = o.center - dot(n, o.center - origin) * n;
    if (ref_is_b) return single_point(o.center, o.radius, p, 0.0, n, 0, speculative, out);
    return single_point(p, 0.0, o.center, o.radius, -n, 0, speculative, out);
  }
  if (o.kind == ShapeKind::Capsule) {
    int count = capsule_on_face(o, P, face, speculative, out);  // (normal n: to the capsule)
    if (count < 0) {  // the segment passes beside the face: its end deepest along n
      const int end = dot(n, o.p) <= dot(n, o.q) ? 0 : 1;
      const Vec3 x = end == 0 ? o.p : o.q;
      const double depth = dot(n, x - origin);  // m
      count = 0;
      if (depth - o.radius <= speculative) {
        out.point[0] = x - (0.5 * (o.radius + depth)) * n;
        out.separation[0] = depth - o.radius;
        out.id[0] = feature_id(FK::Vertex, 1, face, end, 0);
        out.normal = n;
        count = 1;
      }
    }
    if (!ref_is_b) out.normal = -out.normal;
    return count;
  }
  Vec3 o_corners[8], o_normals[6];
  const Polytope Q = o.kind == ShapeKind::Box ? box_polytope(o, o_corners, o_normals) : hull_polytope(o);
  Unset<Vec3, HULL_MAX_FACE_VERTICES> loop;
  for (int k = s; k < e; ++k) loop[k - s] = P.v[P.h->face_vertex[k]];
  ClipPolygon<HULL_CLIP> poly;
  incident_polygon(Q, incident_face(Q, n), poly);
  const int count = face_contact(loop.data(), e - s, n, poly, ref_is_b, face, face_tolerance(a, b),
                                 speculative, out);
  if (count > 0) return count;
  return deepest_below(Q, n, origin, ref_is_b, face, speculative, out);
}

}  // namespace rbsim
