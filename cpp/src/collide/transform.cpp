// The shapes in the world for this step: world vertices and normals of every shape, each
// shape's speculative reach (3D: and each body's world inverse inertia tensor).
//
// The reach (m) is how far the shape's surface can move in one step, dt (|v| + |ω| r)
// with r the farthest core vertex from the centre of mass, so that contacts are created
// before a fast body can pass through another. A pair's speculative distance takes the
// bodies' relative move, dt |v_a - v_b|, and the boxes of the broadphase reach about the
// frame's move (frame_move: the dynamic bodies' median move), a static shape's by
// |frame|, and a dynamic shape's box by dt² |a| more (its acceleration over the step):
// the boxes of two shapes still meet wherever their surfaces can, and those of a heap
// falling as one are as tight as at rest.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "collide/narrow3d.hpp"
#include "collide/toi.hpp"
#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// x + R(q) l, a body-frame vertex in the world (m; 3D: through the body's rotation
// matrix, transform_shapes). In 2D the sums are taken in the
// numba kernel's order, (x + c lx) − s ly and (y + s lx) + c ly, so that the world
// vertices, and the boxes and pairs found from them, are the same to the bit.
inline Vec2 world_point(Vec2 x, Rot2 q, Vec2 l) {
  return {x.x + q.c * l.x - q.s * l.y, x.y + q.s * l.x + q.c * l.y};
}

// x + R l for LANES body-frame points l (m), lane by lane: Mat3 * Vec3's products and
// sums in its order, then x added, as for one point.
inline LanesXYZ world_points(Vec3 x, const Mat3& m, const LanesXYZ& l) {
  auto row = [&](int i) { return dot(Vec3{m.r[i][0], m.r[i][1], m.r[i][2]}, l); };
  return {splat(x.x) + row(0), splat(x.y) + row(1), splat(x.z) + row(2)};
}

// |ω| (rad/s): a scalar in the plane, a vector in space.
inline double magnitude(double w) { return std::fabs(w); }
inline double magnitude(Vec3 w) { return length(w); }

// |a| (m/s²) of body i: gravity (|g| given) and its constant force over its mass for a
// dynamic body, zero for the others. A body let go at rest above a floor has no speed
// yet, and may fall far in the step under a strong gravity: its box reaches that far too.
template <int D>
inline double acceleration(const Model<D>& model, int i, double g_norm) {
  if (!model.is_dynamic(i)) return 0.0;
  return model.has_forces ? length(model.acceleration(i)) : g_norm;
}

}  // namespace

template <int D>
void transform_shapes(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      double dt) {
  transform_shapes(model, state, contacts, dt, frame_move(model, contacts),
                   Span{0, static_cast<std::int64_t>(model.body_count())},
                   Span{0, model.shape_count()});
}

namespace {

// The median along each axis of value(i) over the dynamic bodies i, of at most about
// FRAME_SAMPLES of them evenly spread (the lower middle one of an even count; zero
// without dynamic bodies). The frame needs no more: any frame gives the same pairs.
constexpr int FRAME_SAMPLES = 64;
template <int D, class F>
typename Dim<D>::Vec dynamic_median(const Model<D>& model, F value) {
  using Vec = typename Dim<D>::Vec;
  const int n = model.body_count();
  const int stride = std::max(1, n / FRAME_SAMPLES);
  double along[D][FRAME_SAMPLES + 1];
  int count = 0;
  for (int i = 0; i < n && count <= FRAME_SAMPLES; i += stride) {
    if (!model.is_dynamic(i)) continue;
    const double* v = &value(i).x;
    for (int d = 0; d < D; ++d) along[d][count] = v[d];
    ++count;
  }
  Vec out{};
  if (count == 0) return out;
  for (int d = 0; d < D; ++d) {
    double* middle = along[d] + (count - 1) / 2;
    std::nth_element(along[d], middle, along[d] + count);
    (&out.x)[d] = *middle;
  }
  return out;
}

}  // namespace

template <int D>
typename Dim<D>::Vec frame_move(const Model<D>& model, const Contacts<D>& contacts) {
  return dynamic_median(model, [&](int i) -> const auto& { return contacts.body_delta[i].dx; });
}

template <int D>
void transform_shapes(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      double dt, const typename Dim<D>::Vec& frame, Span bodies, Span shapes) {
  // (frame: m, the frame's move this step)
  using Vec = typename Dim<D>::Vec;
  if constexpr (D == 3) world_inertia(model, state, contacts, bodies);
  const double frame_reach = length(frame);  // m: a static shape's
  const double g_norm = length(model.gravity);  // m/s²

  Vec* vw = contacts.vert_world.data();
  Vec* nw = contacts.norm_world.data();
  const Vec* vl = model.vertex_local.data();
  const Vec* nl = model.normal_local.data();
  for (int s = static_cast<int>(shapes.first); s < shapes.last; ++s) {
    const int i = model.shape_body[s];
    const auto q = state.body_q[i];
    const Vec x = state.body_x[i];
    const int k0 = model.shape_vstart[s], k1 = k0 + model.shape_vcount[s];
    if constexpr (D == 3) {
      // the body's rotation as a matrix, once for all its points
      const Mat3 r = rotation_matrix(q);
      const bool plane = model.shape_kind[s] == ShapeKind::Plane;
      int k = k0;
      if (!plane) {
        // LANES vertices at a time (a box's eight corners in two), by the operations of
        // x + r * v: the same bits
        for (; k + LANES <= k1; k += LANES) store_xyz(vw + k, world_points(x, r, load_xyz(vl + k)));
      }
      for (; k < k1; ++k) {
        vw[k] = x + r * vl[k];
        if (plane) nw[k] = r * nl[k];  // (only a plane has a normal row; the others' stay zero)
      }
      // a convex hull's face normals (the box's come from its corners, narrow3d.hpp), and
      // what the narrowphase's bounds read of it, once here for all its pairs
      const Hull3& hull = model.shape_hull[s];
      Vec3* fw = contacts.face_world.data() + model.shape_hface[s];
      for (int f = 0; f < hull.face_count(); ++f) fw[f] = r * hull.face_normal[f];
      if (model.shape_kind[s] == ShapeKind::Convex) {
        const HullView view = hull.view();
        hull_face_offsets(view, vw + k0, fw, contacts.face_offset.data() + model.shape_hface[s]);
        contacts.shape_spread[s] = hull_spread(vw + k0, view.vertex_count);
      }
    } else {
      for (int k = k0; k < k1; ++k) {
        vw[k] = world_point(x, q, vl[k]);
        nw[k] = rotate(q, nl[k]);
      }
    }
    const double reach = model.shape_reach[s];  // m
    if (model.body_type[i] == BodyType::Static) {
      contacts.shape_turn[s] = 0.0;
      contacts.shape_margin[s] = frame_reach;
    } else {
      // turning moves a rounded shape's surface only as far as it moves its core (a
      // circle about its centre does not move its surface at all)
      const double turn = dt * magnitude(state.body_w[i]) * reach;  // m
      contacts.shape_turn[s] = turn;
      const double fall = dt * dt * acceleration(model, i, g_norm);  // m
      contacts.shape_margin[s] = length(dt * state.body_v[i] - frame) + fall + turn;
    }
  }
}

void world_inertia(const Model<3>& model, const State<3>& state, Contacts<3>& contacts,
                   Span bodies) {
  for (std::int64_t i = bodies.first; i < bodies.last; ++i) {
    const Quat q = state.body_q[i];
    Quat& made = contacts.body_inertia_q[i];
    // (the last step's position update made it at this rotation: the same bits)
    if (q.w == made.w && q.x == made.x && q.y == made.y && q.z == made.z) continue;
    contacts.body_inv_inertia_world[i] = world_tensor(q, model.body_inv_inertia[i]);
    made = q;
  }
}

void find_segment_neighbours(Model<2>& model, const State<2>& state) {
  // every end of every static segment, world frame, sorted along x (then y)
  struct End {
    Vec2 p;
    int shape, k;
  };
  auto end_of = [&](int s, int k) {  // m: end k of segment s in the world
    const int i = model.shape_body[s];
    return state.body_x[i] + rotate(state.body_q[i], model.vertex_local[model.shape_vstart[s] + k]);
  };
  std::vector<End> ends;
  const int n = model.shape_count();
  for (int s = 0; s < n; ++s) {
    if (model.shape_kind[s] != ShapeKind::Segment) continue;
    if (model.body_type[model.shape_body[s]] != BodyType::Static) continue;
    for (int k = 0; k < 2; ++k) ends.push_back({end_of(s, k), s, k});
  }
  model.segment_ghost.clear();
  if (ends.size() < 4) return;
  std::sort(ends.begin(), ends.end(), [](const End& u, const End& v) {
    return u.p.x < v.p.x || (u.p.x == v.p.x && (u.p.y < v.p.y || (u.p.y == v.p.y && u.shape < v.shape)));
  });
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::array<Vec2, 2>> ghost(n, {Vec2{nan, nan}, Vec2{nan, nan}});
  bool any = false;
  // two ends meet within 1e-9 of their coordinates' size (a floor laid end to end from
  // the same numbers meets exactly); an end that two or more others meet is a fork: none.
  // The ends within that of end e along x are a run about it in the sorted list.
  for (std::size_t e = 0; e < ends.size(); ++e) {
    const Vec2 p = ends[e].p;
    const double tol = 1e-9 * (1.0 + std::fabs(p.x) + std::fabs(p.y));  // m
    std::size_t f = e;
    while (f > 0 && p.x - ends[f - 1].p.x <= tol) --f;
    int found = -1, count = 0;
    for (; f < ends.size() && ends[f].p.x - p.x <= tol; ++f)
      if (ends[f].shape != ends[e].shape && std::fabs(ends[f].p.y - p.y) <= tol)
        found = static_cast<int>(f), ++count;
    if (count != 1) continue;
    ghost[ends[e].shape][ends[e].k] = end_of(ends[found].shape, 1 - ends[found].k);
    any = true;
  }
  if (any) model.segment_ghost = std::move(ghost);
}

namespace {

// A face of a static polytope in the world: its shape, its index in the shape (2D: edge
// f, vertex f to f + 1; 3D: the hull's face f, a box's in box_hull()'s order), its unit
// outward normal, its corners (first .. first + count in a list of points; 2D: the
// edge's two ends, 3D: the face's loop, counter-clockwise seen from outside) and their
// bounding box (m).
template <int D>
struct WorldFace {
  using Vec = typename Dim<D>::Vec;
  int shape, index;
  Vec normal;
  int first, count;
  Vec lo, hi;
};

// Every face of the static polytopes (2D: polygons without a radius; 3D: boxes and
// convex hulls) into faces, their corners into points.
void static_faces(const Model<2>& model, const State<2>& state, std::vector<WorldFace<2>>& faces,
                  std::vector<Vec2>& points) {
  for (int s = 0; s < model.shape_count(); ++s) {
    const int i = model.shape_body[s];
    if (model.body_type[i] != BodyType::Static || model.shape_kind[s] != ShapeKind::Polygon ||
        model.shape_radius[s] != 0.0)
      continue;
    const int v0 = model.shape_vstart[s], n = model.shape_vcount[s];
    const int first = static_cast<int>(points.size());
    for (int k = 0; k < n; ++k)
      points.push_back(state.body_x[i] + rotate(state.body_q[i], model.vertex_local[v0 + k]));
    for (int k = 0; k < n; ++k) {
      // (the edge's two ends copied next to each other: a face is a run of points)
      const int at = static_cast<int>(points.size());
      points.push_back(points[first + k]);
      points.push_back(points[first + (k + 1) % n]);
      faces.push_back({s, k, rotate(state.body_q[i], model.normal_local[v0 + k]), at, 2, {}, {}});
    }
  }
}

void static_faces(const Model<3>& model, const State<3>& state, std::vector<WorldFace<3>>& faces,
                  std::vector<Vec3>& points) {
  std::vector<Vec3> verts, normals;
  for (int s = 0; s < model.shape_count(); ++s) {
    const ShapeKind kind = model.shape_kind[s];
    if (model.body_type[model.shape_body[s]] != BodyType::Static ||
        (kind != ShapeKind::Box && kind != ShapeKind::Convex))
      continue;
    verts.resize(model.shape_vcount[s]);
    normals.resize(std::max(6, model.shape_hull[s].face_count()));
    const ShapeRef3 ref = place_shape(model, state, s, 0.0, 1.0, verts.data(), normals.data());
    HullView hull = model.shape_hull[s].view();
    if (kind == ShapeKind::Box) {
      verts.resize(8);
      box_geometry(ref, verts.data(), normals.data());
      hull = box_hull();
    }
    for (int f = 0; f < hull.face_count; ++f) {
      const int at = static_cast<int>(points.size());
      for (int k = hull.face_start[f]; k < hull.face_start[f + 1]; ++k)
        points.push_back(verts[hull.face_vertex[k]]);
      faces.push_back({s, f, normals[f], at, static_cast<int>(points.size()) - at, {}, {}});
    }
  }
}

// Component-wise bounds, and the largest |component| (m).
inline Vec2 lower(Vec2 a, Vec2 b) { return {std::min(a.x, b.x), std::min(a.y, b.y)}; }
inline Vec2 upper(Vec2 a, Vec2 b) { return {std::max(a.x, b.x), std::max(a.y, b.y)}; }
inline Vec3 lower(Vec3 a, Vec3 b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
inline Vec3 upper(Vec3 a, Vec3 b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
inline bool boxes_meet(Vec2 lo, Vec2 hi, Vec2 lo2, Vec2 hi2, double tol) {
  return lo.x <= hi2.x + tol && lo2.x <= hi.x + tol && lo.y <= hi2.y + tol && lo2.y <= hi.y + tol;
}
inline bool boxes_meet(Vec3 lo, Vec3 hi, Vec3 lo2, Vec3 hi2, double tol) {
  return boxes_meet(Vec2{lo.x, lo.y}, Vec2{hi.x, hi.y}, Vec2{lo2.x, lo2.y}, Vec2{hi2.x, hi2.y}, tol) &&
         lo.z <= hi2.z + tol && lo2.z <= hi.z + tol;
}
inline double largest(Vec2 x) { return std::max(std::fabs(x.x), std::fabs(x.y)); }
inline double largest(Vec3 x) { return std::max({std::fabs(x.x), std::fabs(x.y), std::fabs(x.z)}); }

// Whether the point x lies within face g (its corners p[g.first ..]) up to tol (m): on
// its plane and inside its polygon (2D: between the edge's ends).
inline bool within_face(const WorldFace<2>& g, const Vec2* p, Vec2 x, double tol) {
  const Vec2 a = p[g.first], along = p[g.first + 1] - a;
  const double len = length(along), t = dot(x - a, along);
  return std::fabs(dot(g.normal, x - a)) <= tol && t >= -tol * len && t <= len * (len + tol);
}
inline bool within_face(const WorldFace<3>& g, const Vec3* p, Vec3 x, double tol) {
  if (std::fabs(dot(g.normal, x - p[g.first])) > tol) return false;
  for (int k = 0; k < g.count; ++k) {
    const Vec3 a = p[g.first + k], b = p[g.first + (k + 1) % g.count];
    if (dot(cross(b - a, g.normal), x - a) > tol * length(b - a)) return false;
  }
  return true;
}

// How much of face f (its corners in p) face g covers, both in one plane up to tol (m):
// 2D, the length of f's edge within g's (m); 3D, the area of f's polygon within g's (m²,
// f clipped by g's sides, Sutherland–Hodgman); 0 when g leaves f's plane.
double overlap(const WorldFace<2>& f, const WorldFace<2>& g, const Vec2* p, double tol) {
  const Vec2 a = p[f.first], along = p[f.first + 1] - a;
  const double len = length(along);
  if (!(len > 0.0)) return 0.0;
  for (int k = 0; k < 2; ++k)
    if (std::fabs(dot(g.normal, p[f.first + k] - p[g.first])) > tol) return 0.0;
  const double t0 = dot(p[g.first] - a, along) / len, t1 = dot(p[g.first + 1] - a, along) / len;
  return std::max(0.0, std::min({len, std::max(t0, t1)}) - std::max(0.0, std::min(t0, t1)));
}
double overlap(const WorldFace<3>& f, const WorldFace<3>& g, const Vec3* p, double tol) {
  for (int k = 0; k < f.count; ++k)
    if (std::fabs(dot(g.normal, p[f.first + k] - p[g.first])) > tol) return 0.0;
  std::vector<Vec3> poly(p + f.first, p + f.first + f.count), next;
  for (int k = 0; k < g.count && !poly.empty(); ++k) {
    const Vec3 a = p[g.first + k], b = p[g.first + (k + 1) % g.count];
    const Vec3 side = cross(b - a, g.normal);  // out of g across its edge a -> b
    next.clear();
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const Vec3 u = poly[i], v = poly[(i + 1) % poly.size()];
      const double du = dot(side, u - a), dv = dot(side, v - a);
      if (du <= 0.0) next.push_back(u);
      if ((du < 0.0 && dv > 0.0) || (du > 0.0 && dv < 0.0)) next.push_back(u + (du / (du - dv)) * (v - u));
    }
    poly.swap(next);
  }
  Vec3 twice{};  // m²: twice the clipped polygon's vector area
  for (std::size_t i = 0; i + 2 < poly.size(); ++i) twice += cross(poly[i + 1] - poly[0], poly[i + 2] - poly[0]);
  return 0.5 * std::fabs(dot(twice, f.normal));
}

// What of face f may go uncovered where faces meet it to within tol (m): f's own length
// (2D, m) or area (3D, m²) less a band of tol along its boundary.
double must_cover(const WorldFace<2>& f, const Vec2* p, double tol) {
  return length(p[f.first + 1] - p[f.first]) - 2.0 * tol;
}
double must_cover(const WorldFace<3>& f, const Vec3* p, double tol) {
  Vec3 twice{};
  double perimeter = 0.0;  // m
  for (int i = 0; i < f.count; ++i) {
    perimeter += length(p[f.first + (i + 1) % f.count] - p[f.first + i]);
    if (i + 2 < f.count) twice += cross(p[f.first + i + 1] - p[f.first], p[f.first + i + 2] - p[f.first]);
  }
  return 0.5 * std::fabs(dot(twice, f.normal)) - tol * perimeter;
}

// Bit i set for each corner i of face f (its corners in p) near which face g, in f's plane
// up to tol (m), covers f: g holds the point a thousandth of the way from the corner to
// f's centre.
template <int D>
std::uint64_t corners_covered(const WorldFace<D>& f, const WorldFace<D>& g, const typename Dim<D>::Vec* p,
                              double tol) {
  using Vec = typename Dim<D>::Vec;
  Vec centre{};
  for (int k = 0; k < f.count; ++k) centre = centre + p[f.first + k];
  centre = (1.0 / f.count) * centre;
  std::uint64_t bits = 0;
  for (int k = 0; k < f.count && k < 64; ++k) {
    const Vec x = p[f.first + k] + 1e-3 * (centre - p[f.first + k]);
    if (within_face(g, p, x, tol)) bits |= std::uint64_t{1} << k;
  }
  return bits;
}

}  // namespace

template <int D>
void find_covered_faces(Model<D>& model, const State<D>& state, const std::vector<double>& scale) {
  using Vec = typename Dim<D>::Vec;
  std::vector<WorldFace<D>> faces;
  std::vector<Vec> points;
  static_faces(model, state, faces, points);
  model.shape_covered.clear();
  model.corner_start.clear();
  model.corner_covered.clear();
  model.cover_start.clear();
  model.cover.clear();
  if (faces.size() < 2) return;
  // two faces meet within FLUSH_DISTANCE at the smaller shape's scale, round-off (1e-9
  // of the largest coordinate's size) aside: a wall placed to three decimals, its foot
  // 0.5 mm over the floor (2.601 − 5.201 / 2), lay 0.5 mm and a few 1e-16 m off it, not
  // flush, and its foot's corner pushed a body into the floor
  double size = 0.0;  // m
  for (const Vec& x : points) size = std::max(size, largest(x));
  const double round_off = 1e-9 * (1.0 + size);  // m
  auto flush = [&](const WorldFace<D>& f, const WorldFace<D>& g) {  // m
    return C::FLUSH_DISTANCE * std::min(scale[f.shape], scale[g.shape]) + round_off;
  };
  double widest = round_off;  // m: the sweep's reach along x
  for (const auto& f : faces) widest = std::max(widest, C::FLUSH_DISTANCE * scale[f.shape] + round_off);
  for (auto& f : faces) {
    f.lo = f.hi = points[f.first];
    for (int k = 1; k < f.count; ++k) {
      f.lo = lower(f.lo, points[f.first + k]);
      f.hi = upper(f.hi, points[f.first + k]);
    }
  }
  std::sort(faces.begin(), faces.end(), [](const WorldFace<D>& u, const WorldFace<D>& v) {
    return u.lo.x < v.lo.x || (u.lo.x == v.lo.x && (u.shape < v.shape ||
                                                     (u.shape == v.shape && u.index < v.index)));
  });
  // how much of each face the opposite faces in its plane cover: the faces of static
  // shapes side by side do not overlap, so a face is covered when they cover all of it
  // (but a band of tol along its edges), by one face (tiles of a size) or several (bricks
  // laid in bond, planks of a floor); a gap between two tiles leaves both sides open
  std::vector<double> cover(faces.size(), 0.0);  // m (2D) or m² (3D)
  std::vector<std::uint64_t> corners(faces.size(), 0);  // corners_covered, over all neighbours
  std::vector<std::pair<std::size_t, std::int32_t>> touch;  // (face, the shape lying on it)
  // the faces whose boxes meet face u's along x follow it in the sorted list
  for (std::size_t u = 0; u < faces.size(); ++u) {
    for (std::size_t v = u + 1; v < faces.size() && faces[v].lo.x <= faces[u].hi.x + widest; ++v) {
      const WorldFace<D>&fu = faces[u], &fv = faces[v];
      const double tol = flush(fu, fv);  // m
      if (fu.shape == fv.shape || dot(fu.normal, fv.normal) > -1.0 + 1e-9 ||
          !boxes_meet(fu.lo, fu.hi, fv.lo, fv.hi, tol))
        continue;
      for (const auto& [f, g, k] : {std::tuple{&fu, &fv, u}, std::tuple{&fv, &fu, v}}) {
        const double part = overlap(*f, *g, points.data(), tol);
        if (!(part > 0.0)) continue;
        cover[k] += part;
        corners[k] |= corners_covered(*f, *g, points.data(), tol);
        touch.emplace_back(k, g->shape);
      }
    }
  }
  if constexpr (D == 3) {
    // a ground plane covers the faces that lie in it, turned down into it (a wall
    // standing on it): the half-space under it is solid everywhere
    for (int g = 0; g < model.shape_count(); ++g) {
      if (model.shape_kind[g] != ShapeKind::Plane ||
          model.body_type[model.shape_body[g]] != BodyType::Static)
        continue;
      Vec3 point, n;
      const ShapeRef3 plane = place_shape(model, state, g, 0.0, 1.0, &point, &n);
      for (std::size_t u = 0; u < faces.size(); ++u) {
        const WorldFace<D>& f = faces[u];
        const double tol = C::FLUSH_DISTANCE * scale[f.shape] + round_off;  // m
        if (dot(f.normal, plane.normal) > -1.0 + 1e-9) continue;
        bool in_plane = true;
        for (int k = 0; k < f.count && in_plane; ++k)
          in_plane = std::fabs(dot(plane.normal, points[f.first + k]) - plane.offset) <= tol;
        if (!in_plane) continue;
        cover[u] = std::numeric_limits<double>::infinity();
        touch.emplace_back(u, g);
      }
    }
  }
  std::vector<std::uint64_t> covered(model.shape_count(), 0);
  bool any = false;
  for (std::size_t u = 0; u < faces.size(); ++u) {
    const WorldFace<D>& f = faces[u];
    if (f.index >= 64 || !(cover[u] > 0.0)) continue;
    if (cover[u] >= must_cover(f, points.data(), std::max(round_off, C::FLUSH_DISTANCE * scale[f.shape]))) {
      covered[f.shape] |= std::uint64_t{1} << f.index;
      corners[u] = f.count >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << f.count) - 1;
    }
    any = any || corners[u] != 0;
  }
  if (!any) return;
  model.shape_covered = std::move(covered);
  // each shape's rows of corner masks, face by face (shapes with none, no rows)
  const int n_shapes = model.shape_count();
  std::vector<int> face_count(n_shapes, 0);
  std::vector<char> has(n_shapes, 0);
  for (std::size_t u = 0; u < faces.size(); ++u) {
    face_count[faces[u].shape] = std::max(face_count[faces[u].shape], faces[u].index + 1);
    if (corners[u] != 0) has[faces[u].shape] = 1;
  }
  model.corner_start.assign(n_shapes + 1, 0);
  for (int s = 0; s < n_shapes; ++s) model.corner_start[s + 1] = model.corner_start[s] + (has[s] ? face_count[s] : 0);
  model.corner_covered.assign(model.corner_start[n_shapes], 0);
  for (std::size_t u = 0; u < faces.size(); ++u)
    if (has[faces[u].shape]) model.corner_covered[model.corner_start[faces[u].shape] + faces[u].index] = corners[u];
  // each such face's neighbours, shape by shape in order (and by neighbour within)
  std::vector<std::tuple<std::int32_t, std::int32_t, std::uint64_t>> by_shape;
  for (const auto& [k, other] : touch) {
    const WorldFace<D>& f = faces[k];
    if (f.index < 64 && corners[k] != 0) by_shape.emplace_back(f.shape, other, std::uint64_t{1} << f.index);
  }
  std::sort(by_shape.begin(), by_shape.end());
  model.cover_start.assign(n_shapes + 1, 0);
  for (std::size_t i = 0; i < by_shape.size();) {
    const std::int32_t s = std::get<0>(by_shape[i]), other = std::get<1>(by_shape[i]);
    std::uint64_t mask = 0;
    for (; i < by_shape.size() && std::get<0>(by_shape[i]) == s && std::get<1>(by_shape[i]) == other; ++i)
      mask |= std::get<2>(by_shape[i]);
    model.cover.push_back({other, mask});
    ++model.cover_start[s + 1];
  }
  for (int s = 0; s < n_shapes; ++s) model.cover_start[s + 1] += model.cover_start[s];
}

bool build_shape_hulls(Model<3>& model, std::string* error) {
  const int n = model.shape_count();
  model.shape_hull.assign(n, Hull3{});
  model.shape_hface.assign(n, 0);
  model.hull_face_count = 0;
  const bool has_faces = !model.shape_fstart.empty();
  for (int s = 0; s < n; ++s) {
    model.shape_hface[s] = model.hull_face_count;
    if (model.shape_kind[s] != ShapeKind::Convex) continue;
    const int f0 = has_faces ? model.shape_fstart[s] : 0;
    const int nf = has_faces ? model.shape_fcount[s] : 0;
    const int v0 = model.shape_vstart[s], nv = model.shape_vcount[s];
    std::vector<Vec3> vertices(model.vertex_local.begin() + v0, model.vertex_local.begin() + v0 + nv);
    std::vector<std::array<std::int32_t, 3>> triangles(model.face_local.begin() + f0,
                                                       model.face_local.begin() + f0 + nf);
    std::string why;
    if (!build_hull(vertices, triangles, model.shape_hull[s], &why)) {
      if (error) *error = "shape " + std::to_string(s) + " (convex): " + why;
      return false;
    }
    model.hull_face_count += model.shape_hull[s].face_count();
  }
  return true;
}

template void find_covered_faces(Model<2>&, const State<2>&, const std::vector<double>&);
template void find_covered_faces(Model<3>&, const State<3>&, const std::vector<double>&);
template void transform_shapes(const Model<2>&, const State<2>&, Contacts<2>&, double);
template void transform_shapes(const Model<3>&, const State<3>&, Contacts<3>&, double);
template Vec2 frame_move(const Model<2>&, const Contacts<2>&);
template Vec3 frame_move(const Model<3>&, const Contacts<3>&);
template void transform_shapes(const Model<2>&, const State<2>&, Contacts<2>&, double,
                               const Vec2&, Span, Span);
template void transform_shapes(const Model<3>&, const State<3>&, Contacts<3>&, double,
                               const Vec3&, Span, Span);

}  // namespace rbsim
