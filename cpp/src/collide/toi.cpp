// Time of impact by conservative advancement (see toi.hpp).
#include "collide/toi.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "rbsim/constants.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// Conservative advancement, in either dimension: move both bodies freely by
// t = separation / approach speed, collide again (collide_at(t, out) places both shapes
// at t and returns the manifold's point count), repeat, until the gap is below
// `tolerance` (m), the pair separates (passing each other further apart than `clear`, m,
// it keeps its manifold of the start), or TOI_ITERATIONS advancements were made (each
// one narrowphase call; the result is then short_of_it, t before any impact). An impact
// that falls after the step is taken at the step's end only when the search came within
// `finish` (m) of it.
//
// In space, and in the plane where bounded (reaches given: the continuous sweep, and a
// pair turning fast), the approach speed is a bound (search_approach), and for a turning
// body it can be twice the gap's true rate or more: each advancement closes only part of
// the gap, and a pebble landing at 5 m/s took all 12 to close 2 cm to a few µm. There a
// faster step is tried first: the root of the line through the last two samples (secant),
// or, once a sample has passed the impact, of the line to that one (regula falsi). It is kept
// if it lands short of the impact or within `tolerance` past it, and otherwise bounds the
// impact from above. No trial reaches further than the bound can close the gap plus
// `overlap` (m): along the normal the shapes then overlap by no more than that at any
// time up to the trial, so that a trial neither passes through a shape nor skips more
// than a graze of that depth (once the gap is below `overlap` the trials can reach
// several advancements ahead).
template <int D, class Manifold, class Collide>
Impact advance_to_impact(const State<D>& st, int ba, int bb, int npts, double dt,
                         double tolerance, double finish, double clear, double overlap,
                         double reach_a, double reach_b, Manifold& out, Collide&& collide_at) {
  double t = 0.0;
  // by the bound: the sample before t (s, and its gap, m), and the earliest one past the
  // impact
  double t_before = 0.0, gap_before = -1.0;
  double t_past = dt, gap_past = 1.0;
  int it = 0;
  for (; it < C::TOI_ITERATIONS; ++it) {
    const Approach ap = search_approach(out, npts, ba, bb, t, st, reach_a, reach_b);
    if (ap.gap <= tolerance) break;
    if (ap.vn >= 0.0) {
      // separating: at the start, the pair stays there. Later, short of an impact, the
      // free paths pass each other. A close pass (a graze over an edge) keeps the
      // manifold where it passes, which holds the two apart there. One that passes
      // clear, further than `clear` (m), has none: the plane where it passes holds only
      // along the free paths, and a body that meets something else first leaves them (a
      // ball and a box, each flying at its own wall 4 m apart and passing 1.3 m apart
      // 13 ms on: that plane ran through both starts and held the ball, stopped by its
      // wall, to the box's x at 98 m/s); and the manifold of the step's start is a plane
      // the free paths cross within the step (the search ran because they do), where
      // the solver stopped them (a pellet at 600 m/s passing 3 m above a post's corner
      // was thrown off at 206 m/s). How far apart they pass is the gap across their
      // relative motion: an advancement may step past the closest approach, and the
      // part of the gap along the motion is what it stepped past
      if (t > 0.0 && ap.gap > clear) {
        const auto u = st.body_v[ba] - st.body_v[bb];  // m/s
        const double uu = dot(u, u), un = dot(u, out.normal);
        const double across = uu > 0.0 ? std::sqrt(std::max(1.0 - un * un / uu, 0.0)) : 1.0;
        if (ap.gap * across > clear) return {0, t};
      }
      break;
    }
    double step = ap.sep / -ap.vn;  // s
    if (D == 3 || reach_a > 0.0 || reach_b > 0.0) {  // (by the bound: the faster step)
      double guess = 0.0;  // s: the faster step, if any
      if (gap_past < 0.0) {
        guess = ap.gap * (t_past - t) / (ap.gap - gap_past);
      } else if (gap_before > ap.gap) {
        guess = ap.gap * (t - t_before) / (gap_before - ap.gap);
      }
      guess = std::min(guess, (ap.gap + overlap) / -ap.vn);
      if (guess > step && t + guess < std::min(t_past, dt)) {
        Manifold trial = out;
        const int n = collide_at(t + guess, trial);
        const double gap = n > 0 ? trial.separation[nearest_point(trial, n)] : 0.0;
        if (n > 0 && gap >= -tolerance) {  // short of the impact, or at it
          t_before = t;
          gap_before = ap.gap;
          t += guess;
          out = trial;
          npts = n;
          continue;
        }
        if (n > 0) {  // past it
          t_past = t + guess;
          gap_past = gap;
        }
      }
    }
    const bool last = t + step >= dt;
    if (last) {
      // the impact falls after the step. Right after it (the search came within
      // TOI_FINISH), the manifold is taken at the step's end, which has the impact's
      // normal (stopping short left one on a frame 5e-8 rad off); further, it stays
      // where it is (a turning body's arc is not in the estimate, and it may meet the
      // other before the step's end)
      step = dt - t;
      if (step <= 0.0 || ap.sep > finish) break;
    }
    t_before = t;
    gap_before = ap.gap;
    t += step;
    npts = collide_at(t, out);
    if (npts == 0) return {0, t};  // passed by after all
    if (last) break;
  }
  return {npts, t, it == C::TOI_ITERATIONS};
}

// Body i's pose after t (s) of free motion: turned by ω t, moved by v t.
template <int D>
std::pair<typename Dim<D>::Rot, typename Dim<D>::Vec> pose_at(const State<D>& st, int i,
                                                              double t) {
  return {mul(turn_by(t * st.body_w[i]), st.body_q[i]), st.body_x[i] + t * st.body_v[i]};
}

}  // namespace

void place_shape(const Model<2>& model, const State<2>& st, int s, double t, int start,
                 Vec2* verts, Vec2* norms) {
  const auto [q, p] = pose_at(st, model.shape_body[s], t);
  const int v0 = model.shape_vstart[s];
  for (int k = 0; k < model.shape_vcount[s]; ++k) {
    verts[start + k] = p + rotate(q, model.vertex_local[v0 + k]);
    norms[start + k] = rotate(q, model.normal_local[v0 + k]);
  }
}

int toi_face_rows(const Model<3>& model, int s) {
  if (model.shape_kind[s] == ShapeKind::Plane) return 1;
  return model.shape_hull[s].face_count();  // 0 but for a convex hull
}

ShapeRef3 place_shape(const Model<3>& model, const State<3>& st, int s, double t, double scale,
                      Vec3* verts, Vec3* faces) {
  const auto [q, p] = pose_at(st, model.shape_body[s], t);
  const int v0 = model.shape_vstart[s];
  for (int k = 0; k < model.shape_vcount[s]; ++k) verts[k] = p + rotate(q, model.vertex_local[v0 + k]);
  if (model.shape_kind[s] == ShapeKind::Plane) {
    faces[0] = rotate(q, model.normal_local[v0]);
  } else {
    const Hull3& hull = model.shape_hull[s];
    for (int f = 0; f < hull.face_count(); ++f) faces[f] = rotate(q, hull.face_normal[f]);
  }
  return shape_ref(model, s, verts, faces, scale);
}

Impact time_of_impact(const Model<2>& model, const State<2>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec2* tv, Vec2* tn,
                      Manifold2& out, bool bounded) {
  const int na = model.shape_vcount[a], nb = model.shape_vcount[b];
  const ShapeRef2 sa{model.shape_kind[a], 0, na, model.shape_radius[a], scale};
  const ShapeRef2 sb{model.shape_kind[b], na, nb, model.shape_radius[b], scale};
  const double tolerance = scale * C::TOI_TOLERANCE, finish = scale * C::TOI_FINISH;  // m
  const double clear = scale * C::SPECULATIVE_DISTANCE;                                  // m
  const double overlap = bounded ? scale * C::TOI_OVERLAP : 0.0;  // m
  const double reach_a = bounded ? core_reach(model, a) : 0.0;       // m
  const double reach_b = bounded ? core_reach(model, b) : 0.0;
  return advance_to_impact(st, model.shape_body[a], model.shape_body[b], npts, dt, tolerance,
                           finish, clear, overlap, reach_a, reach_b, out,
                           [&](double t, Manifold2& m) {
                             place_shape(model, st, a, t, 0, tv, tn);
                             place_shape(model, st, b, t, na, tv, tn);
                             return collide2d(sa, sb, tv, tn, spec, m);
                           });
}

// In space the shapes' rows follow one another: a's vertices, then b's, in tv; a's face
// (or plane normal) rows, then b's, in tn.
Impact time_of_impact(const Model<3>& model, const State<3>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec3* tv, Vec3* tn,
                      Manifold3& out, bool) {
  const int na = model.shape_vcount[a], fa = toi_face_rows(model, a);
  const double tolerance = scale * C::TOI_TOLERANCE, finish = scale * C::TOI_FINISH;  // m
  const double clear = scale * C::SPECULATIVE_DISTANCE;                                  // m
  return advance_to_impact(st, model.shape_body[a], model.shape_body[b], npts, dt, tolerance,
                           finish, clear, scale * C::TOI_OVERLAP, core_reach(model, a),
                           core_reach(model, b), out,
                           [&](double t, Manifold3& m) {
                             const ShapeRef3 sa = place_shape(model, st, a, t, scale, tv, tn);
                             const ShapeRef3 sb =
                                 place_shape(model, st, b, t, scale, tv + na, tn + fa);
                             return collide3d(sa, sb, spec, m);
                           });
}

}  // namespace rbsim
