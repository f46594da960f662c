// Time of impact by conservative advancement, for speculative manifolds of fast pairs.
//
// A manifold found before the shapes touch has the normal and points of the start of
// the step; for a glancing approach (two balls off centre) those are not the normal and
// points of the impact. The search moves both bodies freely (x + v t, turned by ω t),
// collides again, and repeats, each time by t = separation / approach speed, which
// never passes the impact (the gap shrinks by a large factor per advancement).
#pragma once

#include <algorithm>
#include <cmath>

#include "collide/narrow2d.hpp"
#include "rbsim/math.hpp"
#include "rbsim/model.hpp"
#include "rbsim/state.hpp"

namespace rbsim {

// The rotation by an angle ω t (rad) in the plane.
inline Rot2 turn_by(double angle) { return {std::cos(angle), std::sin(angle)}; }

struct Approach {
  double sep;  // m: the nearest point's separation
  double vn;   // m/s: its normal velocity, < 0 approaching
};

// The nearest point of the manifold `out` (npts points) between bodies ba and bb, both
// moved freely by t (s): its separation and normal velocity, with the lever arms taken
// from the moved centres.
template <int D, class Manifold>
inline Approach nearest_approach(const Manifold& out, int npts, int ba, int bb, double t,
                                 const State<D>& st) {
  const double sep =
      npts == 2 ? std::min(out.separation[0], out.separation[1]) : out.separation[0];
  const int k = (npts == 1 || out.separation[0] <= out.separation[1]) ? 0 : 1;
  const auto ra = out.point[k] - st.body_x[ba] - t * st.body_v[ba];
  const auto rb = out.point[k] - st.body_x[bb] - t * st.body_v[bb];
  // relative velocity of the point on a and on b: (v_a + ω_a × r_a) − (v_b + ω_b × r_b)
  const auto dv = st.body_v[ba] + cross(st.body_w[ba], ra) - st.body_v[bb] -
                  cross(st.body_w[bb], rb);
  return {sep, dot(dv, out.normal)};
}

// Shape s's world vertices and normals as its body will be after t (s) of free motion,
// into rows start.. of verts and norms.
void place_shape(const Model<2>& model, const State<2>& st, int s, double t, int start,
                 Vec2* verts, Vec2* norms);

struct Impact {
  int points;  // the manifold's point count at the impact (0: the pair passed by)
  double t;    // s: 0 when the pair is separating or does not meet within dt
};

// Move the speculative manifold `out` (npts points, of shapes a and b at the step's
// start) to the moment of impact: the manifold at the last t replaces `out` (normal,
// points, separations, ids). spec: the narrowphase's speculative distance (m); scale:
// the pair's tolerance scale (SCALE_LENGTH); tv, tn: room for both shapes' vertices (the
// store's toi_verts, toi_norms).
Impact time_of_impact(const Model<2>& model, const State<2>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec2* tv, Vec2* tn,
                      Manifold2& out);

}  // namespace rbsim
