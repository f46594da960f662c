// The narrowphase over the broadphase's pairs, into the manifold store.
//
// Run the narrowphase on every pair whose tight boxes overlap, and keep the manifolds
// with points. A point whose feature id matches one of last step's points in the same
// pair takes over that point's accumulated impulses (warm start); both lists are sorted
// by key = a · S + b, so the matching is a merge pass (one per part of the pairs on the
// step's threads, each from its first pair's place in last step's list). The stage runs
// in two halves: each pair's narrowphase and time of impact (narrow_pairs), then, once
// a prefix count has given each pair its manifold's slot, each pair's manifold into its
// slot (merge_manifolds); every part writes only its own pairs' rows. A pair of bodies
// that have not moved one against the other since its manifold was found (their offset
// within STILL_DISTANCE of the manifold's, ref_offset) nor turned (each within
// STILL_ANGLE of its rotation then, ref_turn_a and ref_turn_b) carries last step's
// manifold forward instead: only its separation changes, by their relative move. A stack
// or a pyramid swaying as one (a base-40 pyramid's top rows sway by tens of micrometres a
// step for seconds while it settles, its rows together) keeps its manifolds so (56 - 69%
// of them were carried with each body held to its own place, 99 - 100% by pairs). A
// normal is never more than STILL_ANGLE stale: held to a reference rotation of each body
// (taken again only once the body had turned past it), a carried normal could be twice
// that, and the resting pyramids' contacts still approached after the relax pass, which
// doubled the shock pass's work on pyramid-20. A speculative pair that meets within the
// step is moved to its time of impact first (collide/toi.cpp).
//
// In 3D the narrowphase is collide/narrow3d.cpp's, on each shape's world geometry from
// the transform stage (ShapeRef3), with up to four points per manifold; a fast pair's
// manifold is moved to its time of impact as in 2D (the shapes turned by the rotation
// vector ω t).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "collide/narrow2d.hpp"
#include "collide/narrow3d.hpp"
#include "collide/toi.hpp"
#include "contact/pair.hpp"
#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// A 2D shape as the narrowphase reads it: its rows of contacts.vert_world and norm_world
// (transform.cpp), at the pair's tolerance scale.
ShapeRef2 world_shape(const Model<2>& model, const Contacts<2>&, int s, double scale) {
  return {model.shape_kind[s], model.shape_vstart[s], model.shape_vcount[s],
          model.shape_radius[s], scale};
}

// A 3D shape as the narrowphase reads it: its world geometry this step (transform.cpp),
// at the pair's tolerance scale.
ShapeRef3 world_shape(const Model<3>& model, const Contacts<3>& c, int s, double scale) {
  const int k = model.shape_vstart[s];
  // a plane's normal is its one normal row; a hull's face normals have their own rows
  const Vec3* faces = model.shape_kind[s] == ShapeKind::Plane
                          ? c.norm_world.data() + k
                          : c.face_world.data() + model.shape_hface[s];
  ShapeRef3 r = shape_ref(model, s, c.vert_world.data() + k, faces, scale);
  if (model.shape_kind[s] == ShapeKind::Convex) {  // (made by the transform stage)
    r.face_offsets = c.face_offset.data() + model.shape_hface[s];
    r.spread = &c.shape_spread[s];
  }
  return r;
}

// Whether the static segment s with neighbours (model.segment_ghost) would push, along
// n_out (unit, out of s towards the other shape), across one of its joints: a push
// tilted from the segment's face towards a neighbour by more than that neighbour's own
// face is tilted (by none where the two lie straight on, as a floor of pieces does), so
// it comes from the joint's corner where the neighbour's face holds the other shape. The neighbour's face contact is the contact there (Box2D's
// chain segments and their ghost vertices serve the same end): crossing a floor of 0.5 m
// segments, a frictionless ball at 4 m/s was thrown up at every joint by the next piece's
// corner and left at 1.34 m/s. The segment's face is the one on the side of the other
// shape's body centre, `other` (m; n_out's where that lies on the segment's line): a push
// nearly along the segment takes no side (a box sliding on a chain that bends down 0.05
// rad, 0.1 mm below the next piece's end, had a push straight back from it taken as from
// the chain's underside, where the joint is a valley, and was stopped dead at 5 m/s).
inline bool pushes_across_joint(const Model<2>& model, const Contacts<2>& c, int s, Vec2 n_out,
                                Vec2 other) {
  if (model.segment_ghost.empty() || model.shape_kind[s] != ShapeKind::Segment) return false;
  const auto& ghost = model.segment_ghost[s];
  auto none = [](Vec2 g) { return !(g.x == g.x); };  // no neighbour at that end (NaN)
  if (none(ghost[0]) && none(ghost[1])) return false;
  const Vec2 p[2] = {c.vert_world[model.shape_vstart[s]], c.vert_world[model.shape_vstart[s] + 1]};
  const Vec2 along = p[1] - p[0];
  const double len = length(along);
  if (!(len > 0.0)) return false;
  Vec2 face = (1.0 / len) * Vec2{-along.y, along.x};  // the face normal on the other's side
  const double side = dot(face, other - p[0]);  // m
  if (side < 0.0 || (side == 0.0 && dot(face, n_out) < 0.0)) face = -face;
  // (1e-9: round-off of a normal computed straight up from a joint; 1e-6: the sine of a
  // bend below which two pieces lie straight, above the round-off of ends computed from
  // angles, far below any kink a scene means)
  constexpr double TILT_TOL = 1e-9, CONCAVE_SIN = 1e-6;
  for (int k = 0; k < 2; ++k) {
    const Vec2 g = ghost[k];
    if (none(g)) continue;
    const Vec2 out = (k == 0 ? -1.0 : 1.0) / len * along;  // along the segment past end k
    const double tilt = dot(n_out, out);
    if (tilt <= TILT_TOL) continue;
    const Vec2 d = g - p[k];
    const double dl = length(d);
    if (!(dl > 0.0)) continue;
    Vec2 next = (1.0 / dl) * Vec2{-d.y, d.x};  // the neighbour's face normal on that side
    if (dot(next, face) < 0.0) next = -next;
    const double bend = dot(next, out);  // > 0: the joint is convex on that side
    // a valley's joint stays a corner: the shape passing it meets this segment's face as
    // it rises, and the corner's push is the speculative contact that stops it there
    // (dropped, a ball rolling in a bowl of 200 pieces gained 4% of its energy in 10 s)
    if (bend < -CONCAVE_SIN) continue;
    if (tilt > std::max(bend, 0.0) + TILT_TOL) return true;
  }
  return false;
}

// Whether a manifold of normal n (unit, from shape b towards shape a) pushes across the
// joint of a static segment (a or b) with its neighbour (pushes_across_joint).
inline bool catches_at_joint(const Model<2>& model, const State<2>& st, const Contacts<2>& c,
                             int a, int b, Vec2 n) {
  if (model.segment_ghost.empty()) return false;
  const Vec2 xa = st.body_x[model.shape_body[a]], xb = st.body_x[model.shape_body[b]];
  return pushes_across_joint(model, c, b, n, xa) || pushes_across_joint(model, c, a, -n, xb);
}

// A static polytope's world corners (2D: a polygon's; 3D: a box's in box_hull()'s order,
// or a hull's) and, in 3D, its faces' loops over them.
template <int D>
struct Corners {
  using Vec = typename Dim<D>::Vec;
  const Vec* v = nullptr;
  int n = 0;
  const Vec* normal = nullptr;  // its faces' outward unit normals (2D: edge k's at row k)
  HullView hull{};              // (3D)
  std::array<Vec, 8> box{};     // (3D: a box's, made here)
  std::array<Vec, 6> box_normal{};
};
template <int D>
void corners_of(const Model<D>& model, const Contacts<D>& c, int s, Corners<D>& out) {
  out.v = c.vert_world.data() + model.shape_vstart[s];
  out.n = model.shape_vcount[s];
  out.normal = c.norm_world.data() + model.shape_vstart[s];
  if constexpr (D == 3) {
    if (model.shape_kind[s] == ShapeKind::Box) {
      box_geometry(world_shape(model, c, s, 1.0), out.box.data(), out.box_normal.data());
      out.v = out.box.data(), out.n = 8, out.hull = box_hull();
      out.normal = out.box_normal.data();
    } else {
      out.hull = model.shape_hull[s].view();
      out.normal = c.face_world.data() + model.shape_hface[s];
    }
  }
}

// A polytope's faces, face f's corners (2D: its edge's two ends; 3D: its loop) and the
// i-th of them (an index into P.v).
template <int D>
inline int face_count(const Corners<D>& P) {
  if constexpr (D == 2) return P.n; else return P.hull.face_count;
}
template <int D>
inline int corner_count(const Corners<D>& P, int f) {
  if constexpr (D == 2) return 2; else return P.hull.face_start[f + 1] - P.hull.face_start[f];
}
template <int D>
inline int corner(const Corners<D>& P, int f, int i) {
  if constexpr (D == 2) return (f + i) % P.n; else return P.hull.face_vertex[P.hull.face_start[f] + i];
}

// P's support along n: its corners within round-off (1e-9 of their size, as
// find_covered_faces's) of the farthest out along n (most, m; tol, m).
template <int D>
struct Support {
  const Corners<D>& P;
  typename Dim<D>::Vec n;
  double most = -std::numeric_limits<double>::infinity(), tol = 0.0;
  Support(const Corners<D>& corners, typename Dim<D>::Vec dir) : P(corners), n(dir) {
    double size = 0.0;  // m
    for (int k = 0; k < P.n; ++k) {
      most = std::max(most, dot(n, P.v[k]));
      size = std::max(size, length(P.v[k]));
    }
    tol = 1e-9 * (1.0 + size);
  }
  bool holds(int k) const { return dot(n, P.v[k]) >= most - tol; }
};

// Whether dir (unit) is the outward normal of one of shape o's faces (to 1e-12 in its
// cosine): a polygon's or segment's edge, a box's or hull's face, a plane.
template <int D>
bool has_face_along(const Model<D>& model, const Contacts<D>& c, int o, typename Dim<D>::Vec dir) {
  constexpr double SAME = 1.0 - 1e-12;
  const ShapeKind kind = model.shape_kind[o];
  if constexpr (D == 2) {
    if (kind == ShapeKind::Circle) return false;
    const int v0 = model.shape_vstart[o];
    for (int k = 0; k < model.shape_vcount[o]; ++k)
      if (dot(c.norm_world[v0 + k], dir) >= SAME) return true;
    return false;
  } else {
    if (kind == ShapeKind::Sphere || kind == ShapeKind::Capsule) return false;
    if (kind == ShapeKind::Plane) return dot(c.norm_world[model.shape_vstart[o]], dir) >= SAME;
    Corners<3> other;
    corners_of(model, c, o, other);
    for (int f = 0; f < other.hull.face_count; ++f)
      if (dot(other.normal[f], dir) >= SAME) return true;
    return false;
  }
}

// Whether the point x (m) lies over face f of polytope P: within its polygon seen along
// its normal (2D: between its edge's ends), to tol (m).
template <int D>
bool over_face(const Corners<D>& P, int f, typename Dim<D>::Vec x, double tol) {
  if constexpr (D == 2) {
    const Vec2 a = P.v[f], along = P.v[(f + 1) % P.n] - a;
    const double len = length(along), t = dot(x - a, along);  // m² (len times the distance)
    return t >= -tol * len && t <= len * (len + tol);
  } else {
    const int first = P.hull.face_start[f], count = P.hull.face_start[f + 1] - first;
    for (int j = 0; j < count; ++j) {
      const Vec3 a = P.v[P.hull.face_vertex[first + j]];
      const Vec3 b = P.v[P.hull.face_vertex[first + (j + 1) % count]];
      if (dot(cross(b - a, P.normal[f]), x - a) > tol * length(b - a)) return false;
    }
    return true;
  }
}

// Whether static polytope s would push along n_out (unit, out of s towards the other
// shape) into a neighbour that covers one of its faces (model.shape_covered): its support
// along n_out (the corners farthest out along it) lies on a covered face, and the plane
// through the support across n_out cuts into a shape that lies against that face. The
// body is then where the neighbour's own face holds it: the covered face itself pushes
// into the neighbour, and so does a corner or an edge of it whose push leans towards the
// neighbour farther than the neighbour's face there (flush tiles: any lean at all). A push
// no farther over than the neighbour's face, at a joint where the floor bends down, is the
// corner's own, and stays (dropped, a box sliding over such a joint fell through it). So
// does a valley's: where the neighbour rises above the open faces that meet the covered
// one at the support, the corner's push is the speculative contact that stops the body
// at the rising neighbour (dropped, a ball rolling in a bowl of 60 flush polygons gained
// 3.4% of its energy in 9 s; as for segments, pushes_across_joint).
// Crossing a floor of static tiles 0.5 m wide, a frictionless box at 4 m/s met the next
// tile's covered side at every joint, and stopped within 2.3 m (0.16 m/s left).
// `points` (m, npts of them): the manifold's points; slop (m): the pair's LINEAR_SLOP.
template <int D>
bool pushes_from_covered(const Model<D>& model, const Contacts<D>& c, int s, int o,
                         typename Dim<D>::Vec n_out, const typename Dim<D>::Vec* points,
                         int npts, double slop) {
  using Vec = typename Dim<D>::Vec;
  if (model.corner_start.empty() || model.corner_start[s] == model.corner_start[s + 1])
    return false;
  Corners<D> own;
  corners_of(model, c, s, own);
  const Support<D> along(own, n_out);
  const double most = along.most, tol = along.tol;  // m
  // m: how far the neighbours may lie off this shape's faces and still be flush with them
  const double flush = std::max(tol, C::FLUSH_DISTANCE * c.shape_scale[s]);
  std::array<int, HULL_MAX_FACE_VERTICES> support;
  int count = 0;
  for (int k = 0; k < own.n; ++k) {
    if (!along.holds(k)) continue;
    if (count == HULL_MAX_FACE_VERTICES) return false;
    support[count++] = k;
  }
  // a push along a face's normal (the support a whole face), or from a corner or edge
  const bool face_push = count >= D;
  // where corner k lies in face f's loop (-1: not on f)
  auto position = [&](int f, int k) {
    for (int i = 0; i < corner_count(own, f); ++i)
      if (corner(own, f, i) == k) return i;
    return -1;
  };
  auto holds_support = [&](int f) {
    for (int i = 0; i < count; ++i)
      if (position(f, support[i]) < 0) return false;
    return true;
  };
  const std::uint64_t* corners = model.corner_covered.data() + model.corner_start[s];
  const int n_faces = model.corner_start[s + 1] - model.corner_start[s];
  auto wholly = [&](int f) { return f < 64 && (model.shape_covered[s] >> f & 1u); };
  // a corner or edge under the other shape's own face, within a tenth (its sine) of the
  // open face that holds it, is that face resting on it, a little tilted: kept (dropped,
  // a 0.5 mm box tilted 0.03 rad on a floor of 0.5 mm tiles lost the tile under most of
  // it, and fell through the floor). Tilted more, it is a side of the other shape meeting
  // the joint (a hexagon's slanted side: caught, it left at half its speed)
  if (!face_push && has_face_along(model, c, o, -n_out)) {
    for (int g = 0; g < n_faces; ++g)
      if (!wholly(g) && holds_support(g) && dot(own.normal[g], n_out) >= 0.995) return false;
  }
  const auto p = own.v[support[0]];  // m: a corner of the support
  bool drop = false;
  // whether the manifold's points all lie over the faces of f's neighbours that lie
  // against it (the part of f they cover), at f's rim (where a tile's side meets the
  // next tile's top), to the pair's slop: a point midway to a face from a corner that
  // rests on the floor lies at the floor's height, where the face ends, up or down by
  // the soft contact's give. A point within f, further than the slop from its rim, is
  // where a neighbour rises from f (a wall standing on a floor box covers the floor's
  // top under its foot), and the push there is f's: a body falling down the wall's face,
  // its lowest corner 1.6 cm into the wall, lost the floor's push at the foot and fell
  // through the floor at 10 m/s
  auto points_covered = [&](int f) {
    for (int k = 0; k < npts; ++k) {
      if (over_face(own, f, points[k], -slop)) return false;
      bool over = false;
      for (int e = model.cover_start[s]; e < model.cover_start[s + 1] && !over; ++e) {
        if (!(model.cover[e].faces >> f & 1u)) continue;
        Corners<D> other;
        corners_of(model, c, model.cover[e].shape, other);
        for (int g = 0; g < face_count(other) && !over; ++g)
          over = dot(other.normal[g], own.normal[f]) <= -1.0 + 1e-9 &&
                 over_face(other, g, points[k], slop);
      }
      if (!over) return false;
    }
    return true;
  };
  for (int f = 0; f < n_faces; ++f) {
    if (corners[f] == 0 || !holds_support(f)) continue;
    // covered where the support is: near each of its corners; for a push along the
    // face's own normal, wholly, or where the manifold's points are
    bool here = true;
    for (int i = 0; i < count && here; ++i) {
      const int at = position(f, support[i]);
      here = at < 64 && (corners[f] >> at & 1u);
    }
    if (face_push && !wholly(f)) here = points_covered(f);
    if (!here) continue;
    // each neighbour against face f: whether it reaches past the plane through the
    // support (the push goes into it), or rises past an open face that holds the
    // support (a valley: the push stays)
    for (int e = model.cover_start[s]; e < model.cover_start[s + 1]; ++e) {
      if (!(model.cover[e].faces >> f & 1u)) continue;
      const int o_shape = model.cover[e].shape;
      Corners<D> other;
      corners_of(model, c, o_shape, other);
      // whether the neighbour reaches further along dir than bound (m) past x: a
      // polytope by its corners, a plane (3D: the half-space under it) along any dir
      // but its own normal
      auto beyond = [&](Vec dir, Vec x, double bound) {
        if (D == 3 && model.shape_kind[o_shape] == ShapeKind::Plane) {
          const Vec n_plane = c.norm_world[model.shape_vstart[o_shape]];  // (its one row)
          return dot(dir, n_plane) < 1.0 - 1e-12 || dot(n_plane, other.v[0] - x) > bound;
        }
        for (int k = 0; k < other.n; ++k)
          if (dot(dir, other.v[k] - x) > bound) return true;
        return false;
      };
      for (int g = 0; g < n_faces; ++g) {
        if (g == f || wholly(g) || !holds_support(g)) continue;
        if (beyond(own.normal[g], p, flush)) return false;
      }
      drop = drop || beyond(n_out, Vec{}, most + tol);
    }
  }
  return drop;
}

// Whether a manifold of normal n (unit, from shape b towards shape a) pushes from where a
// static neighbour's face holds the other shape: across the joint of static segments
// laid end to end (catches_at_joint), or from a covered face (pushes_from_covered).
// A covered face's push is dropped only while the manifold is shallow: no point deeper
// than the pair's LINEAR_SLOP. A body driven deep into a floor of narrow tiles (a box
// dropped at 6 m/s onto tiles 0.2 m wide, 6 cm in) overlaps each tile less through its
// side than through its top, and with every side's push dropped it fell through the
// floor; kept, the sides' pushes hold it as they did, and the next step, out of the
// overlap, finds the tops.
template <int D, class M>
inline bool held_by_neighbour(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                              int a, int b, const M& out, int npts) {
  if constexpr (D == 2)
    if (catches_at_joint(model, st, c, a, b, out.normal)) return true;
  if (model.corner_start.empty()) return false;
  // (not below a twentieth of SCALE_LENGTH: parts of a few millimetres rest deeper than
  // their slop at the usual step, 69 µm at 1/240 s, and the pieces' pushes are then all
  // they stand on: 1 mm boxes sliding over a floor of 1 mm tiles fell through it, 2 mm
  // ones sped up by 65%. There they are kept, and the joints catch, as they did)
  const double scale = std::min(c.shape_scale[a], c.shape_scale[b]);
  if (scale < C::COVERED_MIN_SCALE) return false;
  const double slop = scale * C::LINEAR_SLOP;  // m
  for (int k = 0; k < npts; ++k)
    if (out.separation[k] < -slop) return false;
  return pushes_from_covered(model, c, b, a, out.normal, out.point.data(), npts, slop) ||
         pushes_from_covered(model, c, a, b, -out.normal, out.point.data(), npts, slop);
}

// Pair a, b's narrowphase at the pair's tolerance scale and speculative distance.
template <int D>
inline int narrow_pair(const Model<D>& model, const Contacts<D>& c, int a, int b, double scale,
                       double spec, std::conditional_t<D == 2, Manifold2, Manifold3>& out) {
  if constexpr (D == 2) {
    return collide2d(world_shape(model, c, a, scale), world_shape(model, c, b, scale),
                     c.vert_world.data(), c.norm_world.data(), spec, out);
  } else {
    return collide3d(world_shape(model, c, a, scale), world_shape(model, c, b, scale), spec, out);
  }
}

// Pair a, b's manifold where a static polytope s pushes the other shape o from a covered
// face (pushes_from_covered), made again from s's open face that o reaches least far
// past: the push of the solid that s and its neighbours make. held_by_neighbour drops
// such a push while the manifold is shallow and o rests on the neighbour (a body crossing
// the joint of flush tiles); here it is made again where o is not held so: a manifold
// deeper than the pair's LINEAR_SLOP, or o that far inside a neighbour of s. A body
// pressed by a pile under the foot of a wall that stands on the floor (the wall's bottom
// face covered) was pushed by that face down into the floor, or not at all, and stayed
// wedged there or was squeezed out of the box beneath the wall; from the wall's open side
// it is pushed back into the box. So is a push that pushes_from_covered keeps (a valley's
// corner) but that leans into a face covered wholly or near that corner, against an o
// that deep inside the neighbour (a wall a little wider than the floor's end under it).
// Returns the point count: npts where s's push stays as found, else the manifold's from
// the open face (0: o no nearer it than the speculative distance spec, m); 0 where
// held_by_neighbour drops it.
template <int D, class M>
inline int against_neighbours(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                              int a, int b, double scale, double spec, M& out, int npts) {
  using Vec = typename Dim<D>::Vec;
  // (held_by_neighbour's tests, in its order)
  if constexpr (D == 2)
    if (catches_at_joint(model, st, c, a, b, out.normal)) return 0;
  if (model.corner_start.empty() || scale < C::COVERED_MIN_SCALE) return npts;
  const double slop = scale * C::LINEAR_SLOP;  // m
  // whether shape o lies deeper than the slop in a static neighbour of s (inside the
  // solid they make)
  auto inside_neighbour = [&](int s, int o) {
    for (int e = model.cover_start[s]; e < model.cover_start[s + 1]; ++e) {
      M in;
      const int k = narrow_pair(model, c, o, model.cover[e].shape, scale, 0.0, in);
      for (int i = 0; i < k; ++i)
        if (in.separation[i] < -slop) return true;
    }
    return false;
  };
  // the faces of s (corners own) that a push along n_out (out of s) may not come from:
  // those covered wholly, and for a push from a corner (or an edge, 3D) those it leans
  // towards (n_out · their normal > 0) that a neighbour covers near it: a push into the
  // neighbour
  auto blocked_faces = [&](int s, const Corners<D>& own, Vec n_out) {
    std::uint64_t blocked = model.shape_covered[s];
    if (model.corner_start[s] == model.corner_start[s + 1]) return blocked;
    const Support<D> along(own, n_out);
    int support = 0;
    for (int k = 0; k < own.n; ++k) support += along.holds(k);
    if (support >= D) return blocked;  // (a face's push: its points decide, points_covered)
    const int n_faces = model.corner_start[s + 1] - model.corner_start[s];
    for (int f = 0; f < n_faces && f < 64; ++f) {
      const std::uint64_t near = model.corner_covered[model.corner_start[s] + f];
      if (near == 0 || !(dot(n_out, own.normal[f]) > 0.0)) continue;
      for (int i = 0; i < corner_count(own, f) && i < 64; ++i)
        if ((near >> i & 1u) && along.holds(corner(own, f, i))) blocked |= std::uint64_t{1} << f;
    }
    return blocked;
  };
  int s = -1;
  if (pushes_from_covered(model, c, b, a, out.normal, out.point.data(), npts, slop))
    s = b;
  else if (pushes_from_covered(model, c, a, b, -out.normal, out.point.data(), npts, slop))
    s = a;
  // a manifold apart by more than the slop at every point is no push yet: as found, or
  // dropped where held by a neighbour (a body 19 cm over a floor made again from the
  // floor's bottom face, 59 cm past it, was thrown down through the floor)
  bool apart = true;
  for (int k = 0; k < npts; ++k) apart = apart && out.separation[k] > slop;
  if (s >= 0) {
    // shallow, and the other shape not inside the neighbour: held by it, and dropped
    bool deep = false;
    for (int k = 0; k < npts; ++k) deep = deep || out.separation[k] < -slop;
    if (apart || (!deep && !inside_neighbour(s, s == a ? b : a))) return 0;
  } else if (apart) {
    return npts;
  }
  // the push out of each static shape of the pair, and the faces of s (corners own) it
  // may not come from
  const Vec out_of_b = out.normal, out_of_a = -out.normal;
  Corners<D> own;
  std::uint64_t blocked = 0;
  if (s >= 0) {
    corners_of(model, c, s, own);
    blocked = blocked_faces(s, own, s == b ? out_of_b : out_of_a);
  } else {
    // a push kept (the corner of a valley, pushes_from_covered) that leans into the
    // neighbour, against a shape inside it, is made again too
    for (const int t : {b, a}) {
      if (model.corner_start[t] == model.corner_start[t + 1]) continue;  // (none covered)
      const Vec n_out = t == b ? out_of_b : out_of_a;
      corners_of(model, c, t, own);
      const std::uint64_t mask = blocked_faces(t, own, n_out);
      bool leans = false;
      for (int f = 0; f < face_count(own) && f < 64; ++f)
        leans = leans || ((mask >> f & 1u) && dot(n_out, own.normal[f]) > 0.0);
      if (leans && inside_neighbour(t, t == b ? a : b)) {
        s = t;
        blocked = mask;
        break;
      }
    }
    if (s < 0) return npts;
  }
  // s's open face beside the push (holding a corner of its support) that the other
  // shape's core reaches least far past
  Corners<D> other;
  corners_of(model, c, s == a ? b : a, other);
  const Support<D> along(own, s == b ? out_of_b : out_of_a);
  auto beside = [&](int f) {
    for (int i = 0; i < corner_count(own, f); ++i)
      if (along.holds(corner(own, f, i))) return true;
    return false;
  };
  int face = -1;
  double best = -std::numeric_limits<double>::infinity();  // m
  for (int f = 0; f < face_count(own); ++f) {
    if ((f < 64 && (blocked >> f & 1u)) || !beside(f)) continue;
    const Vec origin = own.v[corner(own, f, 0)];  // m
    double least = std::numeric_limits<double>::infinity();  // m
    for (int k = 0; k < other.n; ++k) least = std::min(least, dot(own.normal[f], other.v[k] - origin));
    if (least > best) {
      best = least;
      face = f;
    }
  }
  if (face < 0) return npts;  // (every face beside it covered: s inside the solid)
  const int ref_is_b = s == b ? 1 : 0;
  if constexpr (D == 2) {
    return collide_on_face(world_shape(model, c, a, scale), world_shape(model, c, b, scale),
                           ref_is_b, face, c.vert_world.data(), c.norm_world.data(), spec, out);
  } else {
    return collide_on_face(world_shape(model, c, a, scale), world_shape(model, c, b, scale),
                           ref_is_b, face, spec, out);
  }
}

// The speculative distance of pair a, b (m) at scale `scale`: how far their surfaces can
// come closer in a step of dt, by their bodies' relative move and each one's turning,
// and by what their relative acceleration adds over the step, dt² |a_a − a_b|, beyond
// the scaled SPECULATIVE_DISTANCE (which covers it in any usual scene: 2.7 mm under
// gravity at dt 1/60). A pellet let go at rest 3 cm over a floor at dt 1/10 falls 10 cm
// in the step: it had no contact and fell through.
template <int D>
inline double speculative(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                          double dt, int a, int b, double scale) {
  const int ba = model.shape_body[a], bb = model.shape_body[b];
  const auto apart = dt * st.body_v[ba] - dt * st.body_v[bb];
  const double buffer = scale * C::SPECULATIVE_DISTANCE;  // m
  const double spec = buffer + length(apart) + c.shape_turn[a] + c.shape_turn[b];
  // (squared: the root is taken only past the buffer, not for every pair of every step)
  const double dt2 = dt * dt;  // s²
  const double fall2 = dt2 * dt2 * length_squared(model.acceleration(ba) - model.acceleration(bb));
  return fall2 > buffer * buffer ? spec + (std::sqrt(fall2) - buffer) : spec;
}

// 3D: the impulses of last step's manifold j that no feature id carried over go to the
// points of manifold m that no id matched: each such point takes its nearest old point
// within `reach` (m; the contact point from body a's centre, anchor_a), and what old
// points are left over is shared out evenly among the new points left (among all points
// when none is left), so that the manifold keeps last step's total impulse. A face
// lying flush on another is cut into points where its edges cross the other's sides,
// and where those edges are nearly parallel the crossings slide far for a tiny turn
// (25 cm for 1 mrad): the points' ids change from step to step, and a point that
// started from zero left a quarter of a 100 t box's load off the 1 t box under it,
// whose supports then threw it up at 0.2 m/s.
void carry_unmatched(Contacts<3>& c, std::int64_t m, std::int64_t j, int npts, double reach) {
  const int n_old = c.prev_points[j];
  bool taken[4] = {false, false, false, false};
  bool found[4] = {false, false, false, false};
  for (int k = 0; k < npts; ++k) {
    for (int kk = 0; kk < n_old; ++kk) {
      if (c.prev_feature[j][kk] == c.feature[m][k]) {
        taken[kk] = true;
        found[k] = true;
      }
    }
  }
  for (int k = 0; k < npts; ++k) {
    if (found[k]) continue;
    int best = -1;
    double best_d2 = reach * reach;
    for (int kk = 0; kk < n_old; ++kk) {
      if (taken[kk]) continue;
      const double d2 = length_squared(c.anchor_a[m][k] - c.prev_anchor_a[j][kk]);
      if (d2 <= best_d2) {
        best_d2 = d2;
        best = kk;
      }
    }
    if (best < 0) continue;
    taken[best] = found[k] = true;
    c.normal_impulse[m][k] = c.start_impulse[m][k] = c.prev_normal_impulse[j][best];
    c.tangent_impulse[m][k] = c.prev_tangent_impulse[j][best];
  }
  double left = 0.0;  // N·s: the old points' normal impulse no new point took
  Vec3 left_t{};      // N·s: and their friction
  for (int kk = 0; kk < n_old; ++kk) {
    if (taken[kk]) continue;
    left += c.prev_normal_impulse[j][kk];
    left_t += c.prev_tangent_impulse[j][kk];
  }
  if (left == 0.0 && left_t.x == 0.0 && left_t.y == 0.0 && left_t.z == 0.0) return;
  int open = 0;
  for (int k = 0; k < npts; ++k) open += found[k] ? 0 : 1;
  const int share = open > 0 ? open : npts;
  for (int k = 0; k < npts; ++k) {
    if (open > 0 && found[k]) continue;
    c.normal_impulse[m][k] += left / share;
    c.tangent_impulse[m][k] += (1.0 / share) * left_t;
  }
  for (int k = 0; k < npts; ++k) c.start_impulse[m][k] = c.normal_impulse[m][k];
}

// Whether bodies ba and bb lie within STILL_DISTANCE (m, times the smaller body's scale)
// of the offset x_a − x_b they had at `ref` (m): have not moved one against the other.
template <int D>
inline bool near_offset(const State<D>& st, const Contacts<D>& c, int ba, int bb,
                        const typename Dim<D>::Vec& ref) {
  const auto d = (st.body_x[ba] - st.body_x[bb]) - ref;  // m
  const double still = std::min(c.body_scale[ba], c.body_scale[bb]) * C::STILL_DISTANCE;  // m
  return length_squared(d) < still * still;
}

// Whether shapes a and b (scale m) reach no further towards each other within the step
// (dt, s) than LINEAR_SLOP (scaled) at their velocities now: a still pair's manifold, found
// when they were slower, may lack a point that they now reach (a capsule lying on the
// floor on one end's point, its other end 3 cm up, struck at the end of a step into a
// turn of 51 rad/s: carried, the manifold let that end through the floor).
template <int D>
inline bool slow_pair(const Model<D>& model, const State<D>& st, const Contacts<D>& c, double dt,
                      int a, int b, double scale) {
  const int ba = model.shape_body[a], bb = model.shape_body[b];
  // m: what the move may take of the slop once the turns have (squared: no root per pair)
  const double room = scale * C::LINEAR_SLOP - (c.shape_turn[a] + c.shape_turn[b]);
  return room >= 0.0 && dt * dt * length_squared(st.body_v[ba] - st.body_v[bb]) <= room * room;
}

// Whether a body at rotation q (2D: its unwrapped angle, rad) is within STILL_ANGLE of
// ref, its rotation when a manifold was found. In 3D by the angle of the turn q ref⁻¹,
// 2 asin |vector part of q ref*| (q and −q alike).
inline bool near_turn(double angle, double ref) { return std::fabs(angle - ref) < C::STILL_ANGLE; }
inline bool near_turn(const Quat& q, const Quat& ref) {
  const Quat turn = mul(q, Quat{ref.w, -ref.x, -ref.y, -ref.z});
  // sin²(θ/2) of the turn θ, against that of STILL_ANGLE (its series to s⁵: the next term
  // is below 1e-30 of it)
  constexpr double s = 0.5 * C::STILL_ANGLE;
  constexpr double sin_s = s - s * s * s / 6.0 + s * s * s * s * s / 120.0;
  return turn.x * turn.x + turn.y * turn.y + turn.z * turn.z < sin_s * sin_s;
}

// A body's rotation as a manifold keeps it (ref_turn_a, ref_turn_b): 2D its unwrapped
// angle, 3D its quaternion.
inline double turn_of(const State<2>& st, int i) { return st.body_angle[i]; }
inline Quat turn_of(const State<3>& st, int i) { return st.body_q[i]; }

// The store's key of the pair of shapes a < b, of n_shapes: a · S + b, in the order of the
// pair list (the order of last step's manifolds too, prev_key).
inline std::int64_t pair_key(std::int64_t n_shapes, int a, int b) { return a * n_shapes + b; }

// Where pair p's key falls among last step's manifolds' (the first not below it): a
// part's merge pointer starts there.
template <int D>
std::int64_t first_match(const Model<D>& model, const Contacts<D>& c, std::int64_t p) {
  const std::int64_t key = pair_key(model.shape_count(), c.pairs[p][0], c.pairs[p][1]);
  const std::int64_t* prev = c.prev_key.data();
  return std::lower_bound(prev, prev + c.count.manifolds_prev, key) - prev;
}

}  // namespace

template <int D>
void narrow_pairs(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                  const Grid<D>& grid, double dt, Span pairs, PairManifold<D>* found,
                  std::int8_t* found_points) {
  const auto& box = grid.shape_aabb;
  const std::int64_t n_shapes = model.shape_count();
  const std::int64_t* prev = c.prev_key.data();
  const std::int64_t n_prev = c.count.manifolds_prev;
  std::conditional_t<D == 2, Manifold2, Manifold3> out;
  ToiRoom<D> room;  // the time of impact's, made when first asked
  if (pairs.first >= pairs.last) return;
  // a pointer into last step's keys: the pairs are sorted by key too, so it only moves on
  // (a binary search per still pair was half of this stage in a settled pile)
  std::int64_t j = first_match(model, c, pairs.first);
  for (std::int64_t p = pairs.first; p < pairs.last; ++p) {
    found_points[p] = FOUND_APART;
    const int a = c.pairs[p][0], b = c.pairs[p][1];
    if (disjoint<D>(box[a], box[b])) continue;  // near in the fat boxes only: out of reach
    const int ba = model.shape_body[a], bb = model.shape_body[b];
    // the contact tolerances' scale: the smaller shape's (constants.hpp, SCALE_LENGTH)
    const double scale = std::min(c.shape_scale[a], c.shape_scale[b]);
    // last step's manifold of a still pair is carried: no narrowphase
    const std::int64_t key = pair_key(n_shapes, a, b);
    while (j < n_prev && prev[j] < key) ++j;
    if (j < n_prev && prev[j] == key && near_turn(turn_of(st, ba), c.prev_ref_turn_a[j]) &&
        near_turn(turn_of(st, bb), c.prev_ref_turn_b[j]) &&
        near_offset(st, c, ba, bb, c.prev_ref_offset[j]) &&
        slow_pair(model, st, c, dt, a, b, scale)) {
      found_points[p] = FOUND_CARRIED;
      continue;
    }
    const double spec = speculative(model, st, c, dt, a, b, scale);
    int npts = narrow_pair(model, c, a, b, scale, spec, out);
    if (npts > 0) npts = against_neighbours(model, st, c, a, b, scale, spec, out, npts);
    // only a pair that is clearly apart can turn its normal before the impact, and only
    // if it meets within the step: most such pairs do not (two balls falling side by
    // side), and their test is made here, as the search's first, so that they skip the
    // call (in 3D, and in 2D for a pair turning faster than TOI_FAST_TURN in the step, at
    // a bound on the closing speed that takes in the bodies' turns, from each shape's
    // reach, looked up only for a pair that is apart)
    const double slop = scale * C::LINEAR_SLOP;  // m
    bool meets = false, bounded = D == 3;
    if (npts > 0 && out.separation[nearest_point(out, npts)] > slop) {
      if constexpr (D == 2)
        bounded = (std::fabs(st.body_w[ba]) + std::fabs(st.body_w[bb])) * dt > C::TOI_FAST_TURN;
      double reach_a = 0.0, reach_b = 0.0;  // m
      if (bounded) {
        reach_a = core_reach(model, a);
        reach_b = core_reach(model, b);
      }
      meets = meets_within(out, npts, ba, bb, dt, slop, st, reach_a, reach_b);
    }
    double t = 0.0;  // s
    if (meets) {
      if (room.norms.empty()) room.fit(model.vertex_count());
      const Impact hit = time_of_impact(model, st, a, b, npts, dt, spec, scale, room.verts.data(),
                                        room.norms.data(), out, bounded);
      npts = hit.points;
      t = hit.t;
      if (npts > 0 && held_by_neighbour(model, st, c, a, b, out, npts)) npts = 0;
    }
    found_points[p] = static_cast<std::int8_t>(npts);
    PairManifold<D>& f = found[p];
    f.normal = out.normal;
    f.t = t;
    for (int k = 0; k < npts; ++k) {
      f.point[k] = out.point[k];
      f.separation[k] = out.separation[k];
      f.id[k] = out.id[k];
    }
  }
}

template <int D>
int collide_pair(const Model<D>& model, const Contacts<D>& c, int a, int b, double scale,
                 double spec, PairOut<D>& out) {
  return narrow_pair(model, c, a, b, scale, spec, out);
}

template <int D>
bool held_by_neighbour_at(const Model<D>& model, const State<D>& st, const Contacts<D>& c, int a,
                          int b, const PairOut<D>& out, int npts) {
  return held_by_neighbour(model, st, c, a, b, out, npts);
}

void manifold_slots(Span pairs, const std::int8_t* found_points, std::int64_t* slot) {
  std::int64_t m = 0;
  for (std::int64_t p = pairs.first; p < pairs.last; ++p) {
    slot[p] = m;
    m += found_points[p] == FOUND_CARRIED || found_points[p] > 0;
  }
  slot[pairs.last] = m;
}

template <int D>
MergeFlags merge_manifolds(const Model<D>& model, const State<D>& st, Contacts<D>& c,
                           Span pairs, MixRule friction_rule, MixRule restitution_rule,
                           const PairManifold<D>* found, const std::int8_t* found_points,
                           const std::int64_t* slot) {
  using Vec = typename Dim<D>::Vec;
  using Rot = typename Dim<D>::Rot;
  const std::int64_t n_shapes = model.shape_count();
  const std::int64_t n_prev = c.count.manifolds_prev;
  MergeFlags flags;
  if (pairs.first >= pairs.last) return flags;
  // the merge pointer into last step's manifolds (both lists sorted by key)
  std::int64_t j = first_match(model, c, pairs.first);
  std::int64_t m = slot[pairs.first];
  for (std::int64_t p = pairs.first; p < pairs.last; ++p) {
    if (found_points[p] == FOUND_APART) continue;
    const int a = c.pairs[p][0], b = c.pairs[p][1];
    const int ba = model.shape_body[a], bb = model.shape_body[b];
    const std::int64_t key = pair_key(n_shapes, a, b);
    while (j < n_prev && c.prev_key[j] < key) ++j;
    const bool matched = j < n_prev && c.prev_key[j] == key;
    // (slot m still holds last step's manifold m: every manifold of this step before it
    // went to a slot before m)
    const bool in_slot = matched && j == m && c.key[m] == key;
    const bool still = found_points[p] == FOUND_CARRIED;
    const double scale = std::min(c.shape_scale[a], c.shape_scale[b]);
    // m: the bodies' offset x_a − x_b now
    const Vec offset = st.body_x[ba] - st.body_x[bb];
    // whether a point is within the support gap at the step's start (shock.cpp: only
    // touching contacts hold bodies up), twice that for a pair that touched last step: a
    // contact resting about the gap would otherwise change the levels step by step
    const bool touched = matched && c.prev_support[j];
    const double gap = (touched ? 2.0 : 1.0) * scale * C::SUPPORT_GAP;  // m
    bool touching = false;
    if (in_slot && still && !c.prev_swapped) {
      // the pair has not moved, and last step's manifold is still in this slot
      // (store_impulses copied it to prev_*, so the two agree; not after take_prev, which
      // swapped last step's into prev_*): only its separation and this step's impulse
      // records change
      const Vec n = c.normal[m];
      const Vec dd = offset - c.ref_offset[m];  // m: their relative move since it was found
      double deepest = std::numeric_limits<double>::infinity();  // m
      for (int k = 0; k < c.points[m]; ++k) {
        const Vec ra = c.sep_anchor_a[m][k], rb = c.sep_anchor_b[m][k];
        const double sep = c.ref_separation[m][k] + dot(n, dd);
        deepest = std::min(deepest, sep);
        touching = touching || sep <= gap;
        c.base_separation[m][k] = sep - dot(n, ra - rb);
        c.start_impulse[m][k] = c.normal_impulse[m][k];
        c.max_normal_impulse[m][k] = 0.0;
      }
      flags.touch_changed = flags.touch_changed || touched != touching;
      c.support[m] = touching;
      c.start_separation[m] = deepest;
      c.carried[m] = 1;
      ++m;
      continue;
    }
    Vec n;
    int npts;
    double deepest = std::numeric_limits<double>::infinity();  // m: at the step's start
    if (still) {
      // the pair has not moved: carry last step's manifold forward
      n = c.prev_normal[j];
      npts = c.prev_points[j];
      c.ref_offset[m] = c.prev_ref_offset[j];
      c.ref_turn_a[m] = c.prev_ref_turn_a[j];
      c.ref_turn_b[m] = c.prev_ref_turn_b[j];
      const Vec dd = offset - c.prev_ref_offset[j];  // m: their relative move since found
      for (int k = 0; k < npts; ++k) {
        c.anchor_a[m][k] = c.prev_anchor_a[j][k];
        c.anchor_b[m][k] = c.prev_anchor_b[j][k];
        const Vec ra = c.prev_sep_anchor_a[j][k], rb = c.prev_sep_anchor_b[j][k];
        c.sep_anchor_a[m][k] = ra;
        c.sep_anchor_b[m][k] = rb;
        const double ref_sep = c.prev_ref_separation[j][k];
        c.ref_separation[m][k] = ref_sep;
        const double sep = ref_sep + dot(n, dd);
        deepest = std::min(deepest, sep);
        touching = touching || sep <= gap;
        c.base_separation[m][k] = sep - dot(n, ra - rb);
        c.feature[m][k] = c.prev_feature[j][k];
        c.normal_impulse[m][k] = c.prev_normal_impulse[j][k];
        c.start_impulse[m][k] = c.prev_normal_impulse[j][k];
        c.tangent_impulse[m][k] = c.prev_tangent_impulse[j][k];
        c.max_normal_impulse[m][k] = 0.0;
      }
    } else {
      npts = found_points[p];
      if (npts == 0) continue;
      const PairManifold<D>& f = found[p];
      c.ref_offset[m] = offset;  // (its separations' reference: ref_separation = start)
      c.ref_turn_a[m] = turn_of(st, ba);
      c.ref_turn_b[m] = turn_of(st, bb);
      const double radius_a = model.shape_radius[a], radius_b = model.shape_radius[b];  // m
      const double t = f.t;  // s: the impact's time (narrow_pairs), 0 for most pairs
      n = f.normal;
      // the bodies' free motion to the impact (t = 0 unless it was moved there)
      const Vec da = t * st.body_v[ba], db = t * st.body_v[bb];
      Rot qa{}, qb{};  // the rotations by ω t; t = 0 is the common case, and then
      if (t != 0.0) {  // costs no trigonometry
        qa = turn_by(t * st.body_w[ba]);
        qb = turn_by(t * st.body_w[bb]);
      }
      for (int k = 0; k < npts; ++k) {
        // lever arms at the impact. The point lies midway between the surfaces; a rounded
        // shape's arm reaches its own surface instead, half the separation on (a's along
        // +n, b's along −n): where a ball will touch what it approaches, so that friction
        // turns it as its surface is pushed (at the midpoint, a ball a few centimetres from
        // a wall was turned as if it were larger)
        const double half = 0.5 * std::max(f.separation[k], 0.0);  // m
        Vec ra = f.point[k] - st.body_x[ba] - da;
        Vec rb = f.point[k] - st.body_x[bb] - db;
        if (radius_a > 0.0) ra = ra + half * n;
        if (radius_b > 0.0) rb = rb - half * n;
        c.anchor_a[m][k] = ra;
        c.anchor_b[m][k] = rb;
        // the points the separation follows: on a rounded shape its core's, one radius
        // inside its surface, in each body's frame at the step's start
        Vec sa_k = ra, sb_k = rb;
        if (radius_a > 0.0) sa_k = ra + radius_a * n;
        if (radius_b > 0.0) sb_k = rb - radius_b * n;
        if (t != 0.0) {
          sa_k = inv_rotate(qa, sa_k);
          sb_k = inv_rotate(qb, sb_k);
        }
        c.sep_anchor_a[m][k] = sa_k;
        c.sep_anchor_b[m][k] = sb_k;
        // separation = base + n · (d_a + R(Δθ_a) s_a − d_b − R(Δθ_b) s_b) as the bodies
        // move (d, Δθ: motion since the step's start); at the impact (d = v t, Δθ = ω t)
        // it equals the separation found there
        // (in 3D the turn by the identity is skipped: it was the constant it costs nothing
        // as, before the time of impact came to 3D)
        Vec turned_a = sa_k, turned_b = sb_k;  // m: R(Δθ) s at the impact
        if (D == 2 || t != 0.0) {
          turned_a = rotate(qa, sa_k);
          turned_b = rotate(qb, sb_k);
        }
        const double moved = dot(n, da + turned_a - db - turned_b);
        const double base = f.separation[k] - moved;
        c.base_separation[m][k] = base;
        const double start = base + dot(n, sa_k - sb_k);
        deepest = std::min(deepest, start);
        touching = touching || start <= gap;
        c.ref_separation[m][k] = start;
        c.feature[m][k] = f.id[k];
        double jn = 0.0;  // N·s
        std::remove_cvref_t<decltype(c.tangent_impulse[m][k])> jt{};  // N·s (2D: one direction)
        if (matched) {
          for (int kk = 0; kk < c.prev_points[j]; ++kk) {
            if (c.prev_feature[j][kk] == f.id[k]) {
              jn = c.prev_normal_impulse[j][kk];
              jt = c.prev_tangent_impulse[j][kk];
            }
          }
        }
        c.normal_impulse[m][k] = jn;
        c.start_impulse[m][k] = jn;
        c.tangent_impulse[m][k] = jt;
        c.max_normal_impulse[m][k] = 0.0;
      }
      if constexpr (D == 3) {
        if (matched) carry_unmatched(c, m, j, npts, scale * C::WARM_MATCH_DISTANCE);
      }
    }
    flags.same = flags.same && in_slot;
    flags.touch_changed = flags.touch_changed || touched != touching;
    c.support[m] = touching;
    c.start_separation[m] = deepest;
    c.carried[m] = 0;
    c.shape_a[m] = a;
    c.shape_b[m] = b;
    c.body_a[m] = ba;
    c.body_b[m] = bb;
    c.key[m] = key;
    c.normal[m] = n;
    c.points[m] = npts;
    c.friction[m] = mix(model.shape_friction[a], model.shape_friction[b], friction_rule);
    c.restitution[m] =
        mix(model.shape_restitution[a], model.shape_restitution[b], restitution_rule);
    c.scale[m] = scale;
    ++m;
  }
  return flags;
}

template <int D>
void update_manifolds(const Model<D>& model, const State<D>& st, Contacts<D>& c,
                      const Grid<D>& grid, std::int64_t n_pairs, MixRule friction_rule,
                      MixRule restitution_rule, double dt) {
  std::vector<PairManifold<D>> found(n_pairs);
  std::vector<std::int8_t> found_points(n_pairs);
  std::vector<std::int64_t> slot(n_pairs + 1);
  const Span all{0, n_pairs};
  narrow_pairs(model, st, c, grid, dt, all, found.data(), found_points.data());
  manifold_slots(all, found_points.data(), slot.data());
  const MergeFlags flags = merge_manifolds(model, st, c, all, friction_rule, restitution_rule,
                                           found.data(), found_points.data(), slot.data());
  finish_manifolds(c, slot[n_pairs], flags);
}

template <int D>
void finish_manifolds(Contacts<D>& c, std::int64_t manifolds, MergeFlags flags) {
  c.count.manifolds = manifolds;
  c.count.graph_unchanged = (flags.same && manifolds == c.count.manifolds_prev) ? 1 : 0;
  c.count.support_changed = flags.touch_changed ? 1 : 0;
}

template void update_manifolds(const Model<2>&, const State<2>&, Contacts<2>&, const Grid<2>&,
                               std::int64_t, MixRule, MixRule, double);
template void update_manifolds(const Model<3>&, const State<3>&, Contacts<3>&, const Grid<3>&,
                               std::int64_t, MixRule, MixRule, double);
template void narrow_pairs(const Model<2>&, const State<2>&, const Contacts<2>&, const Grid<2>&,
                           double, Span, PairManifold<2>*, std::int8_t*);
template void narrow_pairs(const Model<3>&, const State<3>&, const Contacts<3>&, const Grid<3>&,
                           double, Span, PairManifold<3>*, std::int8_t*);
template MergeFlags merge_manifolds(const Model<2>&, const State<2>&, Contacts<2>&, Span, MixRule,
                                    MixRule, const PairManifold<2>*, const std::int8_t*,
                                    const std::int64_t*);
template MergeFlags merge_manifolds(const Model<3>&, const State<3>&, Contacts<3>&, Span, MixRule,
                                    MixRule, const PairManifold<3>*, const std::int8_t*,
                                    const std::int64_t*);
template void finish_manifolds(Contacts<2>&, std::int64_t, MergeFlags);
template void finish_manifolds(Contacts<3>&, std::int64_t, MergeFlags);

template int collide_pair(const Model<2>&, const Contacts<2>&, int, int, double, double,
                          Manifold2&);
template int collide_pair(const Model<3>&, const Contacts<3>&, int, int, double, double,
                          Manifold3&);
template bool held_by_neighbour_at(const Model<2>&, const State<2>&, const Contacts<2>&, int, int,
                                   const Manifold2&, int);
template bool held_by_neighbour_at(const Model<3>&, const State<3>&, const Contacts<3>&, int, int,
                                   const Manifold3&, int);

}  // namespace rbsim
