// Continuous sweep: a body whose motion within the step its contacts may not have covered
// is swept from its pose at the step's start to its pose now against the static shapes,
// and put back where it first met one that it then went on into deeply.
//
// Speculative contacts (contact/manifold.cpp) hold a body back from every shape within
// its reach at the step's start: how far it could go at the velocity it had then. A body
// struck within the step (by a fast body, by a kinematic paddle) can go much further, and
// a static shape beyond that reach has no contact to stop it: a ball at rest 25 cm from a
// 10 cm wall, struck by a heavy ball at 60 m/s, went through the wall in one step, and a
// capsule flung by a paddle into the corner of a box ended inside the wall and under the
// floor, held there by the two. Within the reach, a contact's time of impact follows the
// free path: a body turned off it by one contact meets shapes the free path missed (a
// chip thrown at 490 m/s into a corner, its free path past the floor's end, stopped at
// the wall and went on down through the floor), and a body turning fast leaves its
// manifold's points behind (a polygon spinning at 277 rad/s, its two points turning away
// from a wall while other corners came round into it). Box2D v3 sweeps its fast bodies
// against the static shapes after its solve (b2SolveContinuous); this is the same idea,
// for the bodies whose motion their contacts may not have covered.
//
// Which bodies: a dynamic body whose motion in the step (|Δx| plus its turn times its
// reach) exceeds CONTINUOUS_FRACTION of its inner size (the least distance from one of its
// shapes' centres to that shape's surface), and either exceeds what its contacts covered
// at the step's start (dt |v₀| + dt |ω₀| reach + dt² |a| + the speculative buffer) by
// that much, or left its free path by more than that and the buffer (|Δx − dt v₀|), or
// turned by more than TOI_FAST_TURN. A falling or flying body's motion is what it was
// expected to be, and a resting one's is small: in most steps of most scenes few bodies
// are swept, and a sweep that finds no impact changes no bits.
//
// The sweep: every static shape whose box meets the body's swept box, against each of
// the body's shapes, collided at the step's start and advanced along the straight path
// from the pose then to the pose now (velocity Δx / dt, turn by the rotation vector of Δq
// over dt) to the time of impact (collide/toi.cpp). A shape the body had a contact with
// is swept against too: a body struck within the step after its contacts were solved
// went through a wall it had a speculative contact with. An impact counts when the body's
// shape went on past it into the static shape by more than CONTINUOUS_FRACTION of its
// inner size (its lowest point along the impact's normal at the impact less that at the
// step's end: lowest_along, so that a body turning about the point where it meets a wall
// is not taken to have gone in by its centre's travel) and no neighbour holds it there
// (held_by_neighbour_at: the joints of a floor of pieces). The body is put back at the
// earliest such impact on its path, its velocity kept, so that the next step's
// speculative contact with the shape stops it or bounces it (manifold.cpp finds that
// contact anew, slow_pair: the pose is one its manifold was found at, more slowly). The
// stage runs after the overlap limits: bodies put back beside one another can overlap,
// and moved apart there they were pushed into the wall they had been stopped at. Only
// static shapes are swept against: a struck body may still pass through a dynamic or
// kinematic one.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "collide/toi.hpp"
#include "contact/pair.hpp"
#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

// The least distance (m) from shape s's centre (its vertices' mean) to its surface: its
// radius, plus for a polygon, box or hull the least distance to one of its faces (a
// box's least half extent; a hull's faces from its triangles).
template <int D>
double shape_inner(const Model<D>& model, int s) {
  using Vec = typename Dim<D>::Vec;
  const int v0 = model.shape_vstart[s], n = model.shape_vcount[s];
  if (n == 0) return model.shape_radius[s];
  Vec mean{};
  for (int k = 0; k < n; ++k) mean = mean + model.vertex_local[v0 + k];
  mean = (1.0 / n) * mean;
  double least = INF;  // m
  if constexpr (D == 2) {
    // (a polygon's edge k runs from vertex k, with outward normal normal_local[k])
    if (model.shape_kind[s] == ShapeKind::Polygon && n >= 3)
      for (int k = 0; k < n; ++k)
        least = std::min(least, dot(model.normal_local[v0 + k], model.vertex_local[v0 + k] - mean));
  } else if (model.shape_kind[s] == ShapeKind::Box && n == 8) {
    // its corners in BOX_SIGNS order: corner 1, 2, 4 differ from corner 0 along one axis
    for (const int k : {1, 2, 4})
      least = std::min(least, 0.5 * length(model.vertex_local[v0 + k] - model.vertex_local[v0]));
  } else {
    for (int f = model.shape_fstart[s]; f < model.shape_fstart[s] + model.shape_fcount[s]; ++f) {
      const auto& t = model.face_local[f];
      const Vec3 a = model.vertex_local[v0 + t[0]];
      const Vec3 normal =
          cross(model.vertex_local[v0 + t[1]] - a, model.vertex_local[v0 + t[2]] - a);
      const double area = length(normal);
      if (area > 0.0) least = std::min(least, dot(normal, a - mean) / area);
    }
  }
  return model.shape_radius[s] + (least == INF ? 0.0 : std::max(least, 0.0));
}

// The step's turn Δq as a signed angle (2D) or rotation vector (3D, the shorter way), rad.
inline double turn_of(Rot2 q) { return std::atan2(q.s, q.c); }
inline Vec3 turn_of(Quat q) {
  if (q.w < 0.0) q = {-q.w, -q.x, -q.y, -q.z};
  const Vec3 u{q.x, q.y, q.z};
  const double s = length(u);
  if (s == 0.0) return {};
  return (2.0 * std::atan2(s, q.w) / s) * u;
}
// A bound on the step's turn θ without an arc (rad): π/2 times the chord |R − I| =
// 2 |sin(θ/2)|, itself at most chord() (math.hpp, with norm1 the bounds without roots).
template <class Rot>
inline double turn_bound(Rot q) {
  return 0.5 * std::numbers::pi * chord(q);
}
inline double magnitude(double a) { return std::fabs(a); }
inline double magnitude(Vec3 a) { return length(a); }
inline Rot2 inverse(Rot2 q) { return {q.c, -q.s}; }
inline Quat inverse(Quat q) { return {q.w, -q.x, -q.y, -q.z}; }

template <int D>
bool boxes_meet(const typename Dim<D>::Vec& lo, const typename Dim<D>::Vec& hi,
                const typename Dim<D>::Vec& other_lo, const typename Dim<D>::Vec& other_hi) {
  const double* a0 = &lo.x;
  const double* a1 = &hi.x;
  const double* b0 = &other_lo.x;
  const double* b1 = &other_hi.x;
  for (int d = 0; d < D; ++d)
    if (a0[d] > b1[d] || b0[d] > a1[d]) return false;
  return true;
}

// Body i's approach to static body o at point p (m) along n (from o towards i), at its
// velocities now, reversed by the restitution e (e = 0 where slower than threshold, m/s)
// in one impulse at p: j = −(1 + e) v_n m_eff, the notes' collision at one point through
// the effective mass (row.hpp's point velocity, mass and push, o's inverse mass and
// inertia zero). Nothing where the point does not approach. A single impulse with e <= 1
// gives no energy.
template <int D>
void strike_back(const Model<D>& model, State<D>& st, int i, int o, typename Dim<D>::Vec p,
                 typename Dim<D>::Vec n, double e, double threshold) {
  const auto r = p - st.body_x[i], ro = p - st.body_x[o];  // m
  const double vn = normal_velocity(st, i, o, r, ro, n);  // m/s
  if (vn >= 0.0) return;
  if (-vn <= threshold) e = 0.0;
  push_point(model, st, i, o, r, ro, n, -(1.0 + e) * vn * point_mass_now(model, st, i, o, r, ro, n));
}

}  // namespace

template <int D>
ContinuousIndex find_continuous_index(const Model<D>& model) {
  ContinuousIndex ix;
  const int n = model.body_count(), n_shapes = model.shape_count();
  ix.shape_start.assign(n + 1, 0);
  ix.inner.assign(n, INF);
  ix.reach.assign(n, 0.0);
  for (int s = 0; s < n_shapes; ++s) {
    const int i = model.shape_body[s];
    if (model.body_type[i] == BodyType::Static) ix.static_shapes.push_back(s);
    ++ix.shape_start[i + 1];
    ix.reach[i] = std::max(ix.reach[i], core_reach(model, s) + model.shape_radius[s]);
    ix.inner[i] = std::min(ix.inner[i], shape_inner(model, s));
  }
  for (int i = 0; i < n; ++i) {
    ix.shape_start[i + 1] += ix.shape_start[i];
    if (ix.inner[i] == INF) ix.inner[i] = 0.0;
  }
  ix.shapes.resize(n_shapes);
  std::vector<std::int32_t> next(ix.shape_start.begin(), ix.shape_start.end() - 1);
  for (int s = 0; s < n_shapes; ++s) ix.shapes[next[model.shape_body[s]]++] = s;
  return ix;
}

template <int D>
std::int64_t sweep_fast_bodies(const Model<D>& model, State<D>& st, Contacts<D>& c,
                               const Grid<D>& grid, const ContinuousIndex& index,
                               const std::vector<typename Dim<D>::Vec>& v0,
                               const std::vector<typename Dim<D>::Ang>& w0, double dt,
                               MixRule restitution_rule, double threshold) {
  using Vec = typename Dim<D>::Vec;
  if (index.static_shapes.empty()) return 0;
  std::int64_t moved = 0;
  ToiRoom<D> room;  // the time of impact's, made when first asked
  const int n = model.body_count();
  for (int i = 0; i < n; ++i) {
    if (!model.is_dynamic(i)) continue;
    BodyDelta<D>& d = c.body_delta[i];
    const double reach = index.reach[i];                       // m
    const double deep = C::CONTINUOUS_FRACTION * index.inner[i];  // m
    // most bodies moved less than that, or as their velocity at the step's start took
    // them (|Δx| at most dt |v₀| + |Δx − dt v₀|): bounds without roots or arcs first
    const double turned = turn_bound(d.dq) * reach;                   // m
    if (norm1(d.dx) + turned <= deep) continue;
    const double buffer = c.body_scale[i] * C::SPECULATIVE_DISTANCE;  // m
    const double off_path = norm1(d.dx - dt * v0[i]);  // m: a bound on |Δx − dt v₀|
    if (off_path + turned <= deep + buffer) continue;
    const auto theta = turn_of(d.dq);                                // rad
    const double motion = length(d.dx) + magnitude(theta) * reach;  // m: a bound on any point's
    // what its contacts covered at the step's start (speculative in manifold.cpp)
    const double covered = dt * length(v0[i]) + dt * magnitude(w0[i]) * reach +
                           dt * dt * length(model.acceleration(i)) + buffer;
    if (motion - covered <= deep && off_path <= deep + buffer &&
        magnitude(theta) <= C::TOI_FAST_TURN)
      continue;
    // the path: from the pose at the step's start to the pose now
    const Vec x_end = st.body_x[i], v_end = st.body_v[i];
    const auto q_end = st.body_q[i];
    const auto w_end = st.body_w[i];
    const Vec x_start = x_end - d.dx;
    const auto q_start = normalize(mul(inverse(d.dq), q_end));
    // the rotation a fraction f of the way along the path
    auto turned_by = [&](double f) { return normalize(mul(turn_by(f * theta), q_start)); };
    Vec lo = x_start, hi = x_start;
    {
      double* l = &lo.x;
      double* h = &hi.x;
      const double* e = &x_end.x;
      for (int k = 0; k < D; ++k) {
        l[k] = std::min(l[k], e[k]) - (reach + buffer);
        h[k] = std::max(h[k], e[k]) + (reach + buffer);
      }
    }
    // the body at the start of its path, moving along it (toi.cpp moves it by v t, ω t)
    st.body_x[i] = x_start;
    st.body_q[i] = q_start;
    st.body_v[i] = (1.0 / dt) * d.dx;
    st.body_w[i] = (1.0 / dt) * theta;
    double first = 1.0;  // the earliest impact that counts, as a fraction of the path
    Vec hit_point{}, hit_normal{};  // m, and from the static shape towards the body
    double hit_e = 0.0;             // the pair's restitution
    int hit_body = 0;               // the static shape's body
    for (const std::int32_t s : index.static_shapes) {
      const auto& box = grid.shape_aabb[s];  // (in the broadphase's moving frame)
      if (!boxes_meet<D>(lo, hi, box.lo + grid.frame_offset, box.hi + grid.frame_offset)) continue;
      for (std::int32_t k = index.shape_start[i]; k < index.shape_start[i + 1]; ++k) {
        const int a = index.shapes[k];
        const double scale = std::min(c.shape_scale[a], c.shape_scale[s]);
        const double spec = motion + scale * C::SPECULATIVE_DISTANCE;  // m
        PairOut<D> out;
        const int npts = collide_pair(model, c, a, s, scale, spec, out);
        if (npts == 0) continue;
        if (room.verts.empty()) room.fit(model.vertex_count());
        // (bounded: the body may turn fast along its path)
        const Impact hit = time_of_impact(model, st, a, s, npts, dt, spec, scale,
                                          room.verts.data(), room.norms.data(), out, true);
        if (hit.points == 0 || hit.t >= first * dt) continue;
        // met within the step: the search closed the gap (else the impact lies beyond), or
        // ran out of advancements short of it, the gap still open (a body spinning at 268
        // rad/s, its bound's advancements each a sliver: the pose there is a safe one)
        if (out.separation[nearest_point(out, hit.points)] > scale * C::LINEAR_SLOP &&
            !hit.short_of_it)
          continue;
        if (held_by_neighbour_at(model, st, c, a, s, out, hit.points)) continue;
        // how far the body's shape went on into s past the impact (the normal from s to the
        // body): its lowest point along the normal at the impact less that at the step's
        // end, turn and all (by the centre's travel alone, a capsule held at a wall by one
        // end, turning about it as it slid on, was taken to have gone 18 cm in and put back
        // each step, while gravity built up its speed)
        const double f = hit.t / dt;
        const double at_impact =
            model.lowest_along(a, x_start + f * d.dx, turned_by(f), out.normal);
        const double on = at_impact - model.lowest_along(a, x_end, q_end, out.normal);  // m
        if (on > deep) {
          first = f;
          // the point: the mean of those within the slop of the nearest (a face's
          // middle where it meets the shape flat, not one of its corners)
          const double nearest = out.separation[nearest_point(out, hit.points)];  // m
          Vec sum{};
          int at = 0;
          for (int p = 0; p < hit.points; ++p) {
            if (out.separation[p] > nearest + scale * C::LINEAR_SLOP) continue;
            sum = sum + out.point[p];
            ++at;
          }
          hit_point = (1.0 / at) * sum;
          hit_normal = out.normal;
          hit_e = mix(model.shape_restitution[a], model.shape_restitution[s], restitution_rule);
          hit_body = model.shape_body[s];
        }
      }
    }
    st.body_v[i] = v_end;
    if (first < 1.0) {
      st.body_x[i] = x_start + first * d.dx;
      st.body_q[i] = turned_by(first);
      if constexpr (D == 2) {
        st.body_w[i] = w_end;
        st.body_angle[i] -= (1.0 - first) * theta;
      } else {
        // ω from L through the world tensor at the rotation it is put back at, kept with
        // that rotation for the next step's start (as integrate_positions keeps them)
        auto& tensor = c.body_inv_inertia_world[i];
        tensor = world_tensor(st.body_q[i], model.body_inv_inertia[i]);
        c.body_inertia_q[i] = st.body_q[i];
        st.body_w[i] = tensor * st.body_l[i];
      }
      d.dx = first * d.dx;
      d.dq = turn_by(first * theta);
      // put back where it started the step, within the slop: its contacts had the step to
      // stop it at the shape and did not, and from the same pose would not next step
      // either (a box thrown at 42 m/s into a wall by the floor's corner, its push there
      // turning it into the wall, was put back step after step with its approach given
      // back, gravity building up its speed, 65 m/s in 200 steps). The impact is taken
      // here, at its point, as one collision (no friction)
      if (first * motion <= c.body_scale[i] * C::LINEAR_SLOP)
        strike_back(model, st, i, hit_body, hit_point, hit_normal, hit_e, threshold);
      ++moved;
    } else {
      st.body_x[i] = x_end;
      st.body_q[i] = q_end;
      st.body_w[i] = w_end;
    }
  }
  return moved;
}

template ContinuousIndex find_continuous_index(const Model<2>&);
template ContinuousIndex find_continuous_index(const Model<3>&);
template std::int64_t sweep_fast_bodies(const Model<2>&, State<2>&, Contacts<2>&, const Grid<2>&,
                                        const ContinuousIndex&, const std::vector<Vec2>&,
                                        const std::vector<double>&, double, MixRule, double);
template std::int64_t sweep_fast_bodies(const Model<3>&, State<3>&, Contacts<3>&, const Grid<3>&,
                                        const ContinuousIndex&, const std::vector<Vec3>&,
                                        const std::vector<Vec3>&, double, MixRule, double);

}  // namespace rbsim
