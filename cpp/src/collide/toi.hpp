// Time of impact by conservative advancement, for speculative manifolds of fast pairs.
//
// A manifold found before the shapes touch has the normal and points of the start of
// the step; for a glancing approach (two balls off centre) or a turning body (a spinning
// plank, whose nearest corner at the start is not the one that hits) those are not the
// normal and points of the impact. The search moves both bodies freely (x + v t, turned
// by ω t), collides again, and repeats, each time by t = separation / approach speed
// (search_approach: in space a bound on it, so that it never passes the impact; the gap
// shrinks by a large factor per advancement).
//
// The search is written once for both dimensions (advance_to_impact); what differs is
// how a shape is placed at t and which narrowphase collides it: in the plane the turn
// ω t is an angle and the shapes are polygons and rounded segments (narrow2d); in space
// it is the rotation by |ω| t about ω (a unit quaternion) and the shapes are the 3D
// kinds (narrow3d: sphere, capsule, box, convex hull, and a static plane).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "collide/narrow2d.hpp"
#include "collide/narrow3d.hpp"
#include "rbsim/math.hpp"
#include "rbsim/model.hpp"
#include "rbsim/state.hpp"

namespace rbsim {

// The rotation by an angle ω t (rad) in the plane.
inline Rot2 turn_by(double angle) { return {std::cos(angle), std::sin(angle)}; }
// The rotation by the rotation vector ω t (rad) in space: |ω t| about its direction
// (the identity, exactly, for a zero vector).
inline Quat turn_by(Vec3 angle) {
  const double theta = length(angle);  // rad
  if (theta == 0.0) return {};
  const double s = std::sin(0.5 * theta) / theta;
  return {std::cos(0.5 * theta), s * angle.x, s * angle.y, s * angle.z};
}

struct Approach {
  double sep;  // m: the point's separation
  double vn;   // m/s: its normal velocity, < 0 approaching
  double gap;  // m: the manifold's smallest separation (its nearest point's)
};

// The manifold's point of smallest separation among its npts (the first on a tie).
template <class Manifold>
inline int nearest_point(const Manifold& out, int npts) {
  int k = 0;
  for (int i = 1; i < npts; ++i)
    if (out.separation[i] < out.separation[k]) k = i;
  return k;
}

// Point k of the manifold `out` between bodies ba and bb, both moved freely by t (s):
// its separation and normal velocity, with the lever arms taken from the moved centres.
template <int D, class Manifold>
inline Approach point_approach(const Manifold& out, int k, int ba, int bb, double t,
                               const State<D>& st) {
  const auto ra = out.point[k] - st.body_x[ba] - t * st.body_v[ba];
  const auto rb = out.point[k] - st.body_x[bb] - t * st.body_v[bb];
  // relative velocity of the point on a and on b: (v_a + ω_a × r_a) − (v_b + ω_b × r_b)
  const auto dv = st.body_v[ba] + cross(st.body_w[ba], ra) - st.body_v[bb] -
                  cross(st.body_w[bb], rb);
  return {out.separation[k], dot(dv, out.normal), out.separation[k]};
}

// How the search advances, with both bodies moved freely by t (s). In the plane: by the
// manifold's nearest point, at its own normal velocity (sep, vn), unless reaches are
// given (the continuous sweep's search, and a pair turning by more than TOI_FAST_TURN in
// the step: then by the bound below, |ω| ρ for a turn in the plane). In space: by the
// manifold's gap (its smallest separation) at a bound on how fast any point of the two
// shapes can close it along the normal n, vn = (v_a − v_b)·n − |n × ω_a| ρ_a −
// |n × ω_b| ρ_b (Mirtich's conservative advancement; reach_a, reach_b = ρ, m, the
// farthest core vertex of each shape from its body's centre of mass; a point at r moves
// along n at (ω × r)·n = r·(n × ω), at most ρ |n × ω|), so that the search never passes
// the impact: a manifold there spans a face, up to four corners, and a turning body's
// far corner swings in faster than its near one, and faster as it turns (the plank of
// tunnel_plank_3d, its near corner 0.56 m from the wall at 17 m/s, its far one 2.7 m
// away at 186 m/s and rising: by the nearest point's estimate the pair did not meet
// within the step; by the far corner's own speed the search went 0.7 ms, 13 cm, past the
// impact). The turn about n itself moves no point along n: with |ω| ρ instead, a cube
// spinning at 30 rad/s about the normal of the wall it drifts into at 1 m/s was closed
// on a sixth of its gap at a time, and the search ran out of advancements 1.2 mm short.
// |n × ω| (1/s): how fast a turn ω moves a point at unit distance along the normal n at
// most (in the plane every turn is about the axis across the plane: |ω|)
inline double turn_across(Vec2, double w) { return std::fabs(w); }
inline double turn_across(Vec3 n, Vec3 w) { return length(cross(n, w)); }

template <int D, class Manifold>
inline Approach search_approach(const Manifold& out, int npts, int ba, int bb, double t,
                                const State<D>& st, double reach_a = 0.0, double reach_b = 0.0) {
  const int near = nearest_point(out, npts);
  if (D == 2 && reach_a == 0.0 && reach_b == 0.0) return point_approach(out, near, ba, bb, t, st);
  const double gap = out.separation[near];
  const auto n = out.normal;
  const double vn = dot(st.body_v[ba] - st.body_v[bb], n) -
                    turn_across(n, st.body_w[ba]) * reach_a - turn_across(n, st.body_w[bb]) * reach_b;
  return {gap, vn, gap};
}

// Whether the speculative manifold `out` (npts points, at the step's start) asks for a
// time of impact: its nearest point is clearly apart (more than `slop`, m) and, at the
// search's approach speed (search_approach; reach_a, reach_b as there), it meets within
// dt (s). Most
// speculative pairs do not (two balls falling side by side, a box resting on another);
// this test, the search's first, lets them skip it.
template <int D, class Manifold>
inline bool meets_within(const Manifold& out, int npts, int ba, int bb, double dt, double slop,
                         const State<D>& st, double reach_a = 0.0, double reach_b = 0.0) {
  if (npts == 0 || out.separation[nearest_point(out, npts)] <= slop) return false;
  const Approach ap = search_approach(out, npts, ba, bb, 0.0, st, reach_a, reach_b);
  return ap.vn < 0.0 && ap.sep / -ap.vn < dt;
}

// Shape s's world vertices and normals as its body will be after t (s) of free motion,
// into rows start.. of verts and norms.
void place_shape(const Model<2>& model, const State<2>& st, int s, double t, int start,
                 Vec2* verts, Vec2* norms);

// A 3D shape as the narrowphase reads it (ShapeRef3) from its world rows: verts, its
// vertex rows (a sphere's centre, a capsule's two ends, a box's 8 corners, a hull's
// vertices, a point of a plane); faces, a hull's face normals or a plane's normal (its
// one row); scale, the pair's tolerance scale. The pointers must outlive the ref.
inline ShapeRef3 shape_ref(const Model<3>& model, int s, const Vec3* verts, const Vec3* faces,
                           double scale) {
  const double radius = model.shape_radius[s];  // m
  // (made in place: a ShapeRef3 is about 300 bytes, and this runs twice per pair)
  ShapeRef3 r = [&] {
    switch (model.shape_kind[s]) {
      case ShapeKind::Sphere: return sphere_ref(verts[0], radius);
      case ShapeKind::Capsule: return capsule_ref(verts[0], verts[1], radius);
      case ShapeKind::Box: return box_ref_from_corners(verts);
      case ShapeKind::Convex: return convex_ref(verts, faces, model.shape_hull[s].view());
      default: return plane_ref(faces[0], dot(faces[0], verts[0]));  // its normal, offset
    }
  }();
  r.scale = scale;
  return r;
}

// Shape s as its body will be after t (s) of free motion: its vertex rows into verts,
// its face (or plane normal) rows into faces, and the ShapeRef3 over them.
ShapeRef3 place_shape(const Model<3>& model, const State<3>& st, int s, double t, double scale,
                      Vec3* verts, Vec3* faces);

// ρ (m): the farthest core vertex of shape s from its body's centre of mass (a turn by
// θ moves no point of its surface farther than ρ θ).
template <int D>
inline double core_reach(const Model<D>& model, int s) {
  // (the world's allocate keeps it per shape: the same number, sqrt being monotone)
  if (static_cast<std::size_t>(s) < model.shape_reach.size()) return model.shape_reach[s];
  double r = 0.0;
  const int v0 = model.shape_vstart[s];
  for (int k = v0; k < v0 + model.shape_vcount[s]; ++k) r = std::max(r, length(model.vertex_local[k]));
  return r;
}

// The rows of a ToiRoom's norms one 3D shape needs at its time of impact: a hull's
// faces, a plane's normal, none for the others.
int toi_face_rows(const Model<3>& model, int s);

// Room for two shapes moved to their time of impact, for a model of v vertex rows: v
// vertex rows; v normal rows in 2D, 2v + 2 in 3D (a hull's face normals, at most 2 per
// vertex: a closed triangulated surface has 2v - 4 triangles, or a plane's normal). Each
// caller keeps its own (each part of the manifold stage: narrow_pairs).
template <int D>
struct ToiRoom {
  std::vector<typename Dim<D>::Vec> verts, norms;
  ToiRoom() = default;  // (empty: fit before use)
  explicit ToiRoom(int v) { fit(v); }
  void fit(int v) {
    verts.resize(std::max(v, 2));
    norms.resize(D == 2 ? std::max(v, 2) : 2 * v + 2);
  }
};

struct Impact {
  int points;  // the manifold's point count at the impact (0: the pair passed by)
  double t;    // s: 0 when the pair is separating or does not meet within dt
  // the search made its TOI_ITERATIONS advancements before the step's end with the gap
  // still open: t is short of the impact, which may still fall within the step
  bool short_of_it = false;
};

// Move the speculative manifold `out` (npts points, of shapes a and b at the step's
// start) to the moment of impact: the manifold at the last t replaces `out` (normal,
// points, separations, ids). spec: the narrowphase's speculative distance (m); scale:
// the pair's tolerance scale (SCALE_LENGTH); tv, tn: room for both shapes' vertices and
// normals (a ToiRoom's verts and norms; in 3D the norms hold the hulls' face normals and
// a plane's normal, toi_face_rows).
// bounded: in the plane, advance by the bound on the approach of any point (search_approach
// with the shapes' reaches), which never passes the impact, instead of by the nearest
// point's own approach, which a body turning fast passes (the continuous sweep: a box
// struck within the step and spun at 90 rad/s, swept 3 m to a ceiling 5 cm thick, was
// found 28 cm into it from the far side, and went through; the narrowphase uses it past
// TOI_FAST_TURN). Space is always bounded.
Impact time_of_impact(const Model<2>& model, const State<2>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec2* tv, Vec2* tn,
                      Manifold2& out, bool bounded = false);
Impact time_of_impact(const Model<3>& model, const State<3>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec3* tv, Vec3* tn,
                      Manifold3& out, bool bounded = true);

}  // namespace rbsim
