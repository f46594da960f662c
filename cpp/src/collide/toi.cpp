// Time of impact by conservative advancement (see toi.hpp).
#include "collide/toi.hpp"

#include "rbsim/constants.hpp"

namespace rbsim {

namespace C = constants;

void place_shape(const Model<2>& model, const State<2>& st, int s, double t, int start,
                 Vec2* verts, Vec2* norms) {
  const int i = model.shape_body[s];
  // the pose after t: turned by ω t, moved by v t
  const Rot2 q = mul(turn_by(t * st.body_w[i]), st.body_q[i]);
  const Vec2 p = st.body_x[i] + t * st.body_v[i];
  const int v0 = model.shape_vstart[s];
  for (int k = 0; k < model.shape_vcount[s]; ++k) {
    verts[start + k] = p + rotate(q, model.vertex_local[v0 + k]);
    norms[start + k] = rotate(q, model.normal_local[v0 + k]);
  }
}

// Conservative advancement: move both bodies freely by t = separation / approach speed,
// collide again, repeat, until the gap is below TOI_TOLERANCE (m, times the pair's scale),
// the pair separates, or TOI_ITERATIONS advancements were made (each one narrowphase
// call).
Impact time_of_impact(const Model<2>& model, const State<2>& st, int a, int b, int npts,
                      double dt, double spec, double scale, Vec2* tv, Vec2* tn,
                      Manifold2& out) {
  const int ba = model.shape_body[a], bb = model.shape_body[b];
  const int na = model.shape_vcount[a], nb = model.shape_vcount[b];
  const ShapeRef2 sa{model.shape_kind[a], 0, na, model.shape_radius[a], scale};
  const ShapeRef2 sb{model.shape_kind[b], na, nb, model.shape_radius[b], scale};
  const double tolerance = scale * C::TOI_TOLERANCE, finish = scale * C::TOI_FINISH;  // m
  double t = 0.0;
  for (int it = 0; it < C::TOI_ITERATIONS; ++it) {
    const Approach ap = nearest_approach(out, npts, ba, bb, t, st);
    if (ap.sep <= tolerance || ap.vn >= 0.0) break;
    double step = ap.sep / -ap.vn;  // s
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
    t += step;
    place_shape(model, st, a, t, 0, tv, tn);
    place_shape(model, st, b, t, na, tv, tn);
    npts = collide2d(sa, sb, tv, tn, spec, out);
    if (npts == 0) return {0, t};  // passed by after all
    if (last) break;
  }
  return {npts, t};
}

}  // namespace rbsim
