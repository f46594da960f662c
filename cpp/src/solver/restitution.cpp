// The restitution stage: bounces by the restitution hypothesis, v_n⁺ from v_n⁻, at the
// points that engaged in this substep approaching faster than the threshold.
//
// Run after every substep, so that impacts follow each other in order. A bouncing point's
// accumulated impulse is dropped afterwards (what it carried into the step, a resting
// load, it keeps), so that later substeps do not warm-start the bounce a second time.
//
// Without forces the target is exactly v_n⁺ = −e v_n⁻. Under a constant relative normal
// acceleration a (gravity, constant forces) the target is taken on the discrete
// trajectory instead: Euler with substep h (s) conserves not the energy but
// I = v²/2 − a s + sign (a h / 2) v (sign +1 symplectic, −1 explicit Euler), and
// reversing v alone would lose or gain about |a| h |v| per bounce. So v_n⁺ makes I after
// the bounce (at the current separation) equal e² times I where the point engaged. For
// e = 1 a ball then keeps its apex bounce after bounce, to round-off.
//
// Impacts that share a body within a substep (a ball struck by two others, a ball hitting
// a wall while another hits it, a row of touching balls struck at one end) are where
// energy went: the solve treats them as one inelastic impact, and each point's approach
// was recorded mid-pass, after its neighbours had pushed. So a cluster of bouncing points
// (e > 0) whose bodies nothing else pushes is done again exactly: the substep's impulses
// at its points are taken back, which leaves each point's true approach velocity, and the
// impacts are then resolved one pair at a time, in passes, each a bounce against the
// point's velocity at that moment, until no point of the cluster approaches (a point
// struck again within the substep, as in the row of balls, bounces again; one that
// approaches slower than the threshold is only stopped). The cluster also takes in
// elastic points that pushed slower than the threshold and carried no load into the
// step: in a touching row struck at one end, the solve's joint push engages them at a
// fraction of the striker's speed. A pair's bounce with e = 1 keeps the kinetic energy
// exactly, so the cluster does. After RESTITUTION_PASSES passes what still approaches is
// left to the next substep's solve. A resting elastic contact on a static or kinematic
// body (a ball of the row resting on the floor) is taken in the same way and only stopped
// again. Clusters that also hold resting contacts between two dynamic bodies (a ball
// landing on a stack) keep the solve's impulses and get the targets from the recorded
// approach.
//
// An impact is resolved where the bodies meet. A fast body engages a substep before it
// reaches what it hits, through the speculative push that lets it close the gap and no
// more; its impact then waits (listed again for the next call) until the gap is within
// IMPACT_GAP, so that nothing bounces back from, or stops short of, a wall (a static or
// kinematic body) it has not reached. (Between two dynamic bodies it is taken within
// SPECULATIVE_DISTANCE, and an elastic one records its approach afresh by the push of the
// substep they meet in: see impact_state.) A waiting impact's push, given while the point
// is apart (no friction there: solve.cpp), is taken back, so that the whole impact falls
// in the substep where the bodies meet. Every normal impulse this stage applies comes
// with its friction: an impact's, Coulomb's for its point's whole normal impulse of the
// substep (impact_coulomb); a lone cluster's, Coulomb's for each push (impact_friction).
// An impact's friction is then held to the normal impulse the impact really delivered,
// in whichever substeps it fell, and does not depend on the step.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// bounce_kind of a manifold in the restitution stage (contacts.bounce_kind, int8)
enum BounceKind : std::int8_t {
  kQuiet = 0,    // no point pushes or bounces
  kAlone = 1,    // bounces, e > 0, and touches no body that anything else pushes: redone exactly
  kJoined = 2,   // bounces within a cluster that also has resting or inelastic contacts
  kPushing = 3,  // pushes without bouncing (a resting or slow contact)
  kPassive = 4,  // elastic, pushed slowly, no load carried in: joins a lone cluster it touches
  kWaiting = 5,  // its impacts engaged at a gap and have not met yet: looked at again later
};

// Where an impact of a point stands when the restitution stage looks at it.
enum class Impact : std::int8_t {
  None,     // no impact: the point did not engage faster than the threshold
  Due,      // the bodies have met there: the impact is resolved now
  Waiting,  // engaged at a gap (a speculative push) and still apart: resolved once they meet
  Over,     // engaged at a gap, and no longer approaching there: it never struck
};

// body_mark bits: bit 1, something other than a lone cluster pushes the body; bit 2, the
// body is reached from a lone cluster's bounce
constexpr std::int8_t kPushed = 1;
constexpr std::int8_t kReached = 2;

// a · b of two angular quantities (2D: scalars; 3D: vectors)
inline double ang_dot(double a, double b) { return a * b; }
inline double ang_dot(Vec3 a, Vec3 b) { return dot(a, b); }

// The normal velocity (m/s) after a bounce of coefficient e: the one that makes the
// discrete trajectory's invariant at separation s_now (m) e² times `invariant` (m²/s²),
// with relative normal acceleration acc (m/s²), substep h (s), sign +1 for symplectic
// and −1 for explicit Euler. The invariant after the bounce, v²/2 + sign a h v / 2 − a s,
// set to e² I: v = (−a h sign + √((a h)² + 8 (e² I + a s))) / 2 (the root moving apart).
inline double bounce_target(double invariant, double s_now, double acc, double e, double h,
                            double sign) {
  const double ah = sign * acc * h;
  const double rhs = e * e * invariant + acc * s_now;
  return 0.5 * (-ah + std::sqrt(std::fmax(ah * ah + 8.0 * rhs, 0.0)));
}

// The discrete trajectory's invariant (m²/s²) where a point engaged, at normal velocity
// vn0 (m/s, after the substep's velocity update) and separation s0 (m, before its position
// update), relative normal acceleration acc (m/s²), substep h (s): what bounce_target's
// target keeps.
inline double engaged_invariant(double vn0, double s0, double acc, double h) {
  return 0.5 * vn0 * vn0 - 0.5 * acc * h * vn0 - acc * s0;
}

// Body i's acceleration (m/s²) along n from gravity and its constant force.
template <int D>
inline double own_acceleration(const Model<D>& model, int i, typename Dim<D>::Vec n) {
  return dot(model.gravity + model.body_inv_mass[i] * model.body_force[i], n);
}

// Relative normal acceleration (m/s²) of bodies a and b along n from gravity and forces.
template <int D>
inline double relative_acceleration(const Model<D>& model, int a, int b, typename Dim<D>::Vec n) {
  double acc = 0.0;
  if (model.body_type[a] == BodyType::Dynamic) acc += own_acceleration(model, a, n);
  if (model.body_type[b] == BodyType::Dynamic) acc -= own_acceleration(model, b, n);
  return acc;
}

// The slowest approach (m/s) of manifold m (bodies a, b, normal n) that is an impact: the
// restitution threshold, or twice one substep h (s) of either body's own acceleration
// along n (gravity, constant forces), a h, if that is faster. A body resting on another
// reaches it at a h every substep with no impact at all (the substep's acceleration,
// before the contact stops it), and the discrete trajectory cannot tell that rest from
// an impact as slow: its invariant there is zero, and a bounce is then the mirror root of
// bounce_target, a hop of a h taken every substep (a ball resting on the floor with e > 0
// and threshold 0 reported v = +g h for ever, and gained that energy). Twice a h, so that
// the rest's own approach, exactly a h and raised by rounding or by a face's points and
// friction coupled in the solve, is never taken for an impact; the slowest bounce kept
// is then that of a drop from 2 a h² (0.34 mm under gravity at a substep of 1/240 s).
template <int D>
inline double impact_speed(const Model<D>& model, int a, int b, typename Dim<D>::Vec n,
                           double threshold, double h) {
  double acc = 0.0;  // m/s²: the larger of the two bodies' accelerations along n
  if (model.body_type[a] == BodyType::Dynamic) acc = std::fabs(own_acceleration(model, a, n));
  if (model.body_type[b] == BodyType::Dynamic)
    acc = std::fmax(acc, std::fabs(own_acceleration(model, b, n)));
  return std::fmax(threshold, 2.0 * acc * h);
}

// How far apart (m) the shapes of manifold m are along its normal n (from b towards a)
// at the bodies' poses now: the least of n · (a's surface) less the most of n · (b's),
// from each shape's core vertices and radius. The shapes are convex, so this bounds their
// distance from below whatever the manifold's points.
template <int D>
double projected_gap(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                     std::int64_t m, typename Dim<D>::Vec n) {
  const auto along = [&](int s, typename Dim<D>::Vec dir) {  // m: the least of dir · p
    const int i = model.shape_body[s];
    return model.lowest_along(s, st.body_x[i], st.body_q[i], dir);
  };
  return along(c.shape_a[m], n) + along(c.shape_b[m], -n);
}

// Where point k of manifold m (bodies a, b, normal n) stands. An impact against a static
// or kinematic body is due once the separation is within IMPACT_GAP (times the contact's
// scale, m) of touching, so that
// no body bounces back from (or is stopped short of) a wall it has not reached; until
// then it waits, with the approach it engaged with. The speculative push carries the
// bodies together within a substep, following the separation linearly in each body's
// motion, which a turning body's arc leaves by about |r| (ω h)² / 2 per substep (h in s).
// When that exceeds tol the point's separation may never come within tol, and the
// shapes themselves are asked: the impact is due once their projections on n
// (projected_gap, a bound from below on their distance) are within tol. Until then it
// waits while the point's gap is beyond what the turn moves it in a substep, |ω h| |r|
// (within that, the push cannot place it nearer: waiting again and again, a box landing
// on a corner hovered with its approach given back, and gained energy), and while the
// manifold's nearest point is within DEEP_OVERLAP (scaled) of the shape's nearest along
// n, so that the next substep's push, which carries the points to the other body,
// carries the shape there too (once the turn has brought another part of the shape
// nearer than that, the push would carry that part into or through the other body).
// Otherwise the impact is taken now, as it stands. (Taken as it stands whenever
// the arc exceeded tol, a slug tumbling at 583 rad/s with 4 substeps of 1/240 s, which
// engages by the relax stage's push a substep's travel before the wall, bounced 1.25 m
// short of it; a 0.2 m box at 150 m/s and 60 rad/s, 0.49 m short.)
//
// Between two dynamic bodies an impact within SPECULATIVE_DISTANCE (scaled) is taken at
// once, at the gap: waiting, their speculative push would reach what touches them (a row
// of balls struck at one end, a box struck into its neighbours) in the solve before the
// positions move, and the lone clusters' exact redo and a struck pile's contacts would
// see it too late. Further apart it waits as against a wall, elastic or not: a fast body
// engages a whole substep's travel away (a 600 m/s pellet 2.5 m before a free-standing
// door at 4 substeps of 1/60 s), and taken there its bounce turned it back in mid-air.
// With explicit Euler the positions move before the next solve could push: impacts are
// taken at once there too.
//
// where_met() is the part that asks where the bodies are, for a point approaching now
// whether or not it engaged as an impact.
template <int D>
Impact where_met(const Model<D>& model, const State<D>& st, const Contacts<D>& c, std::int64_t m,
               int k, int a, int b, typename Dim<D>::Vec n, double h, bool explicit_euler);

template <int D>
Impact impact_state(const Model<D>& model, const State<D>& st, const Contacts<D>& c,
                    std::int64_t m, int k, int a, int b, typename Dim<D>::Vec n,
                    double threshold, double h, bool explicit_euler) {
  if (c.approach_velocity[m][k] >= -threshold || c.max_normal_impulse[m][k] == 0.0)
    return Impact::None;
  return where_met(model, st, c, m, k, a, b, n, h, explicit_euler);
}

template <int D>
Impact where_met(const Model<D>& model, const State<D>& st, const Contacts<D>& c, std::int64_t m,
               int k, int a, int b, typename Dim<D>::Vec n, double h, bool explicit_euler) {
  if (explicit_euler) return Impact::Due;
  const double s_now = point_separation(c, m, k, a, b, n);
  const double tol = c.scale[m] * C::IMPACT_GAP;  // m: how close counts as met
  const bool both_dynamic = model.is_dynamic(a) && model.is_dynamic(b);
  if (both_dynamic) {
    if (s_now <= c.scale[m] * C::SPECULATIVE_DISTANCE) return Impact::Due;
  } else if (s_now <= tol) {
    return Impact::Due;
  }
  if (normal_velocity(st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n) >= 0.0)
    return Impact::Over;
  const auto ta = st.body_w[a] * h, tb = st.body_w[b] * h;
  double arc = ang_dot(ta, ta) * length(c.sep_anchor_a[m][k]);
  arc += ang_dot(tb, tb) * length(c.sep_anchor_b[m][k]);
  if (0.5 * arc < tol) return Impact::Waiting;
  // a turning body: met once its shape, wherever its points, is within reach
  const double gap = projected_gap(model, st, c, m, n);  // m
  if (gap <= (both_dynamic ? c.scale[m] * C::SPECULATIVE_DISTANCE : tol)) return Impact::Due;
  const double sweep = std::sqrt(ang_dot(ta, ta)) * length(c.sep_anchor_a[m][k]) +
                       std::sqrt(ang_dot(tb, tb)) * length(c.sep_anchor_b[m][k]);
  if (s_now <= sweep) return Impact::Due;
  // apart: it waits while the gap is beyond the turn's sweep and the manifold's nearest
  // point within DEEP_OVERLAP of the shape's nearest (see above)
  double nearest = kInf;  // m
  for (int j = 0; j < c.points[m]; ++j)
    nearest = std::fmin(nearest, point_separation(c, m, j, a, b, n));
  return nearest - gap <= c.scale[m] * C::DEEP_OVERLAP ? Impact::Waiting : Impact::Due;
}

// Take back this substep's impulses at point k of manifold m (bodies a, b), normal and
// tangent, in a lone cluster that is redone exactly. A waiting point of the cluster (its
// speculative push is no part of the impacts redone) is taken back too: the next
// substep's solve pushes again before the positions move, and its impact is resolved once
// the bodies meet.
template <int D>
void take_back(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t m, int k,
               int a, int b) {
  const auto n = c.normal[m];
  const double j = c.normal_impulse[m][k];
  c.normal_impulse[m][k] = 0.0;
  push_point(model, st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n, -j);
  const auto jt = c.tangent_impulse[m][k];
  if constexpr (D == 2) {
    if (jt != 0.0) {
      c.tangent_impulse[m][k] = 0.0;
      push_point(model, st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], cross(n, 1.0), -jt);
    }
  } else {
    if (jt.x != 0.0 || jt.y != 0.0 || jt.z != 0.0) {
      c.tangent_impulse[m][k] = Vec3{};
      push_impulse(model, st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], -jt);
    }
  }
}

// Point k of manifold m (bodies a, b, normal n), waiting for its impact, its push taken
// back: its approach (m/s, < 0) held to the discrete trajectory's from where it engaged
// (approach_velocity, approach_separation) at its separation now, the approaching root
// of bounce_target's equation at e = 1 (acc m/s², h s, sign as there). Only ever slowed,
// by a push at the point: it gives no energy.
template <int D>
void hold_approach(const Model<D>& model, State<D>& st, const Contacts<D>& c, std::int64_t m,
                   int k, int a, int b, typename Dim<D>::Vec n, double acc, double h,
                   double sign) {
  const double vn0 = c.approach_velocity[m][k], s0 = c.approach_separation[m][k];
  if (!(vn0 < 0.0)) return;  // (none recorded)
  const double invariant = engaged_invariant(vn0, s0, acc, h);  // m²/s²
  const double ah = sign * acc * h;
  const double rhs = invariant + acc * point_separation(c, m, k, a, b, n);
  const double fastest = 0.5 * (-ah - std::sqrt(std::fmax(ah * ah + 8.0 * rhs, 0.0)));  // m/s
  const auto ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
  const double now = normal_velocity(st, a, b, ra, rb, n);  // m/s
  // (a margin for rounding: a fall the positions followed gives back its own approach)
  if (now >= fastest - 1e-9 * std::fabs(fastest)) return;
  // what the push gave back and a substep or two of acceleration can bring it to: faster,
  // the cluster's bounces have turned the body since (its arms, the step's start's, no
  // longer say where the point is on a body that turns fast), and it is left as it is
  if (now < vn0 - 2.0 * std::fabs(acc) * h) return;
  // through the arms its velocity was read at, so that the push brings it to `fastest`
  // and no further (overshot, past the mirror of its approach, it would give energy)
  const double mass = point_mass_now(model, st, a, b, ra, rb, n);  // kg
  push_point(model, st, a, b, ra, rb, n, (fastest - now) * mass);
}

// An impact that is over: a later approach engages afresh (see solve_contacts).
template <int D>
inline void end_impact(Contacts<D>& c, std::int64_t m, int k) {
  c.approach_velocity[m][k] = kInf;
}

// 3D: a point's tangent block (t1, t2) inverted (kg), and the mass of a slide along one
// direction of it (2 / trace), through the bodies' tensors at their rotations now, as
// push_impulse pushes through them (the row's are the step's start's).
struct TangentMasses {
  double m11 = 0.0, m12 = 0.0, m22 = 0.0, m = 0.0;
};
inline TangentMasses tangent_masses_now(const Model<3>& model, const State<3>& st, int a, int b,
                                        Vec3 ra, Vec3 rb, Vec3 t1, Vec3 t2) {
  const double mass = model.body_inv_mass[a] + model.body_inv_mass[b];  // 1/kg
  const Vec3 a1 = cross(ra, t1), a2 = cross(ra, t2), b1 = cross(rb, t1), b2 = cross(rb, t2);
  const Vec3 ia1 = inv_inertia_now(model, st, a, a1), ia2 = inv_inertia_now(model, st, a, a2);
  const Vec3 ib1 = inv_inertia_now(model, st, b, b1), ib2 = inv_inertia_now(model, st, b, b2);
  const double k11 = (mass + dot(a1, ia1)) + dot(b1, ib1);
  const double k22 = (mass + dot(a2, ia2)) + dot(b2, ib2);
  const double k12 = dot(a1, ia2) + dot(b1, ib2);
  const double det = k11 * k22 - k12 * k12;
  TangentMasses out;
  if (det > 1.0e-12 * k11 * k22 && det > 0.0) {
    out.m11 = k22 / det;
    out.m12 = -k12 / det;
    out.m22 = k11 / det;
  }
  if (k11 + k22 > 0.0) out.m = 2.0 / (k11 + k22);
  return out;
}

// Coulomb friction at point k of manifold m (bodies a, b): the tangent impulse `held`
// (N·s) moved to stop the sliding there, within `limit` (N·s; 3D: the 2×2 tangent block,
// clamped to Coulomb's circle, as the solve's, its masses at the rotations now: with the
// row's, of the step's start, a 2.6 cm stick 2 mm thick landing spinning at dt 1/60 was
// thrown up by its impact's friction with 7 times its energy). The change is applied to
// the bodies and added to the point's tangent impulse.
template <int D>
void friction_step(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t m, int k,
                   int a, int b, typename Dim<D>::Tangent held, double limit) {
  const auto& row = c.solver_row[m];
  if constexpr (D == 3) {
    const Vec3 ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
    const Vec3 u = (st.body_v[a] + cross(st.body_w[a], ra)) - (st.body_v[b] + cross(st.body_w[b], rb));
    const TangentMasses tm = tangent_masses_now(model, st, a, b, ra, rb, row.t1, row.t2);
    double d1 = 0.0, d2 = 0.0;
    friction_change(dot(held, row.t1), dot(held, row.t2), dot(u, row.t1), dot(u, row.t2), tm.m11,
                    tm.m12, tm.m22, tm.m, limit, d1, d2);
    if (d1 == 0.0 && d2 == 0.0) return;
    const Vec3 p = d1 * row.t1 + d2 * row.t2;
    push_impulse(model, st, a, b, ra, rb, p);
    c.tangent_impulse[m][k] += p;
  } else {
    const auto& pt = row.point[k];
    const Vec2 t = cross(row.normal, 1.0);  // (n_y, −n_x), as the solve's
    const double vt =
        dot(st.body_v[a] - st.body_v[b], t) + (st.body_w[a] * pt.rta - st.body_w[b] * pt.rtb);
    const double jt = std::fmin(std::fmax(held - pt.tangent_mass * vt, -limit), limit) - held;
    if (jt == 0.0) return;
    st.body_v[a] += (model.body_inv_mass[a] * jt) * t;
    st.body_w[a] += model.body_inv_inertia[a] * (jt * pt.rta);
    st.body_v[b] -= (model.body_inv_mass[b] * jt) * t;
    st.body_w[b] -= model.body_inv_inertia[b] * (jt * pt.rtb);
    c.tangent_impulse[m][k] += jt;
  }
}

// Friction of an impact's normal impulse jn (N·s) at point k of manifold m (bodies a, b):
// the tangential impulse that stops the sliding there, at most μ jn either way. The
// solve's friction is held to the normal impulse it accumulates in a substep, which a
// bounce is no part of; so every normal impulse of a lone cluster's passes gets its own,
// and an impact's friction is Coulomb's for the normal impulse it really delivered,
// whatever the substep it fell in. Added to the point's tangent impulse (N·s).
template <int D>
void impact_friction(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t m, int k,
                     int a, int b, double jn) {
  const double limit = c.friction[m] * jn;
  if (!(limit > 0.0)) return;
  friction_step(model, st, c, m, k, a, b, typename Dim<D>::Tangent{}, limit);
}

// Friction of a point's whole normal impulse this substep, once an impact resolved here
// has changed it: Coulomb's, as the solve's passes take it (the tangent impulse
// accumulated in the substep moved to stop the sliding at point k of manifold m, bodies
// a, b, within μ times the normal impulse accumulated). Where the solve's friction
// already took its share this adds μ times what the impact added, as impact_friction
// does; but a face's impulses shifted from one point to the other (a box landing flat,
// its friction's turn taken out) change its friction by the shift alone, and a push the
// solve gave while the bodies were apart, without friction (solve.cpp), gets its own.
template <int D>
void impact_coulomb(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t m, int k,
                    int a, int b) {
  if (!(c.friction[m] > 0.0)) return;
  friction_step(model, st, c, m, k, a, b, c.tangent_impulse[m][k],
                c.friction[m] * c.normal_impulse[m][k]);
}

// The impulses left on a bounced point for the next substep's warm start: the load it
// carried into the step at most (a bounce is not warm-started), and friction within μ of
// that.
template <int D>
inline void drop_bounce(Contacts<D>& c, std::int64_t m, int k) {
  const double jn = std::fmin(c.normal_impulse[m][k], c.start_impulse[m][k]);
  // (the bounce was pushed in this substep: the step's impulse keeps it)
  if (c.record_impulses) c.step_impulse[m][k] += c.normal_impulse[m][k] - jn;
  c.normal_impulse[m][k] = jn;
  const double limit = c.friction[m] * jn;
  if constexpr (D == 2) {
    c.tangent_impulse[m][k] = std::fmin(std::fmax(c.tangent_impulse[m][k], -limit), limit);
  } else {  // onto Coulomb's circle
    const Vec3 jt = c.tangent_impulse[m][k];
    const double sq = dot(jt, jt);
    if (sq > limit * limit) c.tangent_impulse[m][k] = (limit / std::sqrt(sq)) * jt;
  }
}

// Energy the impact owes besides the bounce (see the passes below; zeros elsewhere): work
// (J), e², h·sign·acc (m/s), and u[k] (m/s), each point's target alone with its own
// share of the work.
template <int D>
struct Owed {
  double work = 0.0, e2 = 0.0, hsa = 0.0;
  std::array<double, Dim<D>::max_points> u{};
};

template <int D>
using PointImpulses = std::array<double, Dim<D>::max_points>;  // N·s at each point
template <int D>
using PointFlags = std::array<bool, Dim<D>::max_points>;

// 3D: manifold m's normal block K (1/kg, packed as SolverRow<3>::k) over its np points,
// through the bodies' inverse inertia tensors at their rotations now.
inline void k_now_of(const Model<3>& model, const State<3>& st, const Contacts<3>& c,
                     std::int64_t m, int a, int b, int np, std::array<double, 10>& k) {
  const Vec3 n = c.normal[m];
  Vec3 ca[4], cb[4], ia[4], ib[4];  // r × n at each point, and I⁻¹ of it (zero: not dynamic)
  for (int i = 0; i < np; ++i) {
    ca[i] = cross(c.anchor_a[m][i], n);
    cb[i] = cross(c.anchor_b[m][i], n);
    ia[i] = inv_inertia_now(model, st, a, ca[i]);
    ib[i] = inv_inertia_now(model, st, b, cb[i]);
  }
  const double im = model.body_inv_mass[a] + model.body_inv_mass[b];
  for (int i = 0; i < np; ++i)
    for (int j = i; j < np; ++j) k[PACKED_K[i][j]] = im + dot(ca[i], ia[j]) + dot(cb[i], ib[j]);
}

// Raise the normal velocity of manifold m's points to their targets t[k] (m/s) where
// need[k], by impulses added to normal_impulse (kept >= 0). In 2D both points at once are
// one 2x2 block (a box landing flat gets mirror-image impulses; one after the other would
// tip it); in 3D the points of a face that need it, two or more, likewise (their rows of
// K at the rotations now). When the block would pull, one point at a time;
// with `single`, only the point furthest below its target (the caller comes back for the
// others with targets from their velocities then: the first point's impulse changes
// them). Returns the impulses applied.
//
// With owed.work != 0 the block raises both targets by the same c for which its impulses
// do e² times that work; a single point takes u[k], its own target with its own share of
// the work. (The block is of a manifold's two points: 2D's face contact.)
template <int D>
PointImpulses<D> push_targets(const Model<D>& model, State<D>& st, Contacts<D>& c,
                              std::int64_t m, int a, int b, PointFlags<D> need,
                              std::array<double, Dim<D>::max_points> t, bool single,
                              const Owed<D>& owed) {
  using Vec = typename Dim<D>::Vec;
  constexpr int P = Dim<D>::max_points;
  const Vec n = c.normal[m];
  const bool need0 = need[0], need1 = need[1];
  const double t0 = t[0], t1 = t[1];
  const double ima = model.body_inv_mass[a], imb = model.body_inv_mass[b];
  const auto& iia = model.body_inv_inertia[a];
  const auto& iib = model.body_inv_inertia[b];
  const auto qa = st.body_q[a], qb = st.body_q[b];
  if (D == 2 && need0 && need1) {
    const Vec r0a = c.anchor_a[m][0], r0b = c.anchor_b[m][0];
    const Vec r1a = c.anchor_a[m][1], r1b = c.anchor_b[m][1];
    // lever arms r × n (2D: m; 3D: vectors)
    const auto ca0 = cross(r0a, n), cb0 = cross(r0b, n);
    const auto ca1 = cross(r1a, n), cb1 = cross(r1b, n);
    const auto ia0 = Dim<D>::apply_inv_inertia(iia, qa, ca0);
    const auto ib0 = Dim<D>::apply_inv_inertia(iib, qb, cb0);
    const auto ia1 = Dim<D>::apply_inv_inertia(iia, qa, ca1);
    const auto ib1 = Dim<D>::apply_inv_inertia(iib, qb, cb1);
    // the block K (1/kg)
    const double k11 = ima + imb + ang_dot(ca0, ia0) + ang_dot(cb0, ib0);
    const double k22 = ima + imb + ang_dot(ca1, ia1) + ang_dot(cb1, ib1);
    const double k12 = ima + imb + ang_dot(ca1, ia0) + ang_dot(cb1, ib0);
    const double det = k11 * k22 - k12 * k12;
    if (det > 1.0e-9 * k11 * k22) {
      const double vn0 = normal_velocity(st, a, b, r0a, r0b, n);
      const double vn1 = normal_velocity(st, a, b, r1a, r1b, n);
      const double d0 = t0 - vn0, d1 = t1 - vn1;
      double j0 = (k22 * d0 - k12 * d1) / det;
      double j1 = (k11 * d1 - k12 * d0) / det;
      if (owed.work != 0.0) {
        // impulses j + c q (q = K⁻¹ 1) do ΔE(c) = ΔE(0) + L c + B c² / 2
        const double q0 = (k22 - k12) / det, q1 = (k11 - k12) / det;
        const double big_b = q0 + q1;
        const double big_l =
            0.5 * (q0 * (vn0 + t0) + q1 * (vn1 + t1) + j0 + j1 + owed.hsa * big_b);
        const double disc = big_l * big_l + 2.0 * big_b * owed.e2 * owed.work;
        if (big_l > 0.0 && disc >= 0.0) {
          const double cc = 2.0 * owed.e2 * owed.work / (big_l + std::sqrt(disc));
          j0 += cc * q0;
          j1 += cc * q1;
        }
      }
      auto& lam = c.normal_impulse[m];
      if (lam[0] + j0 >= 0.0 && lam[1] + j1 >= 0.0) {
        lam[0] += j0;
        lam[1] += j1;
        const Vec p = (j0 + j1) * n;
        st.body_v[a] += ima * p;
        add_angular(model, st, a, j0 * ca0 + j1 * ca1);
        st.body_v[b] -= imb * p;
        add_angular(model, st, b, -(j0 * cb0 + j1 * cb1));
        PointImpulses<D> out{};
        out[0] = j0;
        out[1] = j1;
        return out;
      }
    }
  }
  PointImpulses<D> out{};
  const auto targets = t;  // (a block's; one point alone takes its own u[k])
  t = owed.u;
  if constexpr (D == 3) {
    // the face's points that need a push, two or more: one block, as the solve's (every
    // point: K + BLOCK_EPS diag(K), as the row's rigid factor; fewer, their rows and
    // columns of K), if no point would pull; with work owed, raised as 2D's block is, by
    // c K⁻¹ 1 (one point at a time instead, the first corner of a box landing flat took
    // the bounce and tipped it: from 4.4 m/s, e = 0.8, it left at 1.2 m/s, spinning; and a
    // cube struck edge first into a wall at 30 m/s, e = 0.5, its two leading corners'
    // impact taken one after the other, left at 3 m/s, not 15, sliding at 4 m/s and
    // turning at 50 rad/s)
    const int np = c.points[m];
    int idx[4], ns = 0;  // the points that need a push
    for (int k = 0; k < np; ++k)
      if (need[k]) idx[ns++] = k;
    BlockFactor own;
    if (ns > 1) {
      // K through the tensors at the rotations now, those push_point pushes through (as
      // point_mass_now for one point): with the step's start's, a thin plate spinning at
      // 110 rad/s at dt 1/60 (0.46 rad a substep) had each pair of its face's points
      // bounced by a block that overshot, which the other pair's next bounce answered,
      // 27 times larger each pass: thrown to 1e19 m/s in one call
      std::array<double, 10> k_now{};
      k_now_of(model, st, c, m, a, b, np, k_now);
      if (ns == np) {
        const double none[4] = {0.0, 0.0, 0.0, 0.0};
        factor_block(k_now, none, np, own);
      } else {
        double A[4][4];
        block_of(k_now, idx, ns, A);
        own.ok = ldlt_factor(A, ns, 1e-12, own) ? 1.0 : 0.0;
      }
    }
    if (ns > 1 && own.ok != 0.0) {
      double r[4] = {0.0, 0.0, 0.0, 0.0}, d[4] = {0.0, 0.0, 0.0, 0.0}, vn[4] = {};
      for (int i = 0; i < ns; ++i) {
        const int k = idx[i];
        vn[i] = normal_velocity(st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n);
        r[i] = targets[k] - vn[i];
      }
      ldlt_apply(own, ns, r, d);
      if (owed.work != 0.0) {
        // impulses d + c q (q = K⁻¹ 1) do ΔE(c) = ΔE(0) + L c + B c² / 2 (as in 2D)
        double ones[4] = {1.0, 1.0, 1.0, 1.0}, q[4] = {0.0, 0.0, 0.0, 0.0};
        ldlt_apply(own, ns, ones, q);
        double big_b = 0.0, big_l = 0.0;
        for (int i = 0; i < ns; ++i) {
          big_b += q[i];
          big_l += q[i] * (vn[i] + targets[idx[i]]) + d[i];
        }
        big_l = 0.5 * (big_l + owed.hsa * big_b);
        const double disc = big_l * big_l + 2.0 * big_b * owed.e2 * owed.work;
        if (big_l > 0.0 && disc >= 0.0) {
          const double cc = 2.0 * owed.e2 * owed.work / (big_l + std::sqrt(disc));
          for (int i = 0; i < ns; ++i) d[i] += cc * q[i];
        }
      }
      auto& lam = c.normal_impulse[m];
      bool pulls = false;
      for (int i = 0; i < ns; ++i) pulls = pulls || lam[idx[i]] + d[i] < 0.0;
      if (!pulls) {
        for (int i = 0; i < ns; ++i) {
          const int k = idx[i];
          lam[k] += d[i];
          push_point(model, st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n, d[i]);
          out[k] = d[i];
        }
        return out;
      }
    }
  }
  int needing = 0;
  for (int k = 0; k < P; ++k) needing += need[k] ? 1 : 0;
  if (single && needing > 1) {
    // only the point furthest below its target (the first on a tie)
    int best = -1;
    double most = 0.0;
    for (int k = 0; k < P; ++k) {
      if (!need[k]) continue;
      const double d = t[k] - normal_velocity(st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n);
      if (best < 0 || d > most) {
        best = k;
        most = d;
      }
    }
    for (int k = 0; k < P; ++k) need[k] = k == best;
  }
  for (int k = 0; k < P; ++k) {
    if (!need[k]) continue;
    const Vec ra = c.anchor_a[m][k], rb = c.anchor_b[m][k];
    const double vn = normal_velocity(st, a, b, ra, rb, n);
    const double lam = c.normal_impulse[m][k];
    // (3D: through the tensors push_point pushes through, at the rotations now)
    double mass = c.normal_mass[m][k];  // kg
    if constexpr (D == 3) mass = point_mass_now(model, st, a, b, ra, rb, n);
    const double next = std::fmax(lam - mass * (vn - t[k]), 0.0);
    const double impulse = next - lam;
    c.normal_impulse[m][k] = next;
    push_point(model, st, a, b, ra, rb, n, impulse);
    out[k] = impulse;
  }
  return out;
}

// A dynamic body's impact on several static or kinematic bodies at once (a box landing
// flat across the seam of two floor tiles, or in a corner on the floor and a wall): the
// points of all those manifolds that need a push, as one block. Each manifold's own
// block pulls there (its points lie to one side of the centre of mass), and its points
// one at a time, manifold after manifold, tipped the body: a box landing across two tiles
// at 6.25 m/s, e = 0.5, left at 1.75 m/s (2D; 0.43 m/s in 3D), not 3.1, spinning at 5.4
// rad/s. At most GROUP_MAX_POINTS points (else each manifold on its own).
constexpr int GROUP_MAX_POINTS = 16;

// A group's points (manifold m, point k): the block's rows and what they ask.
struct GroupPoints {
  int n = 0;
  std::int32_t m[GROUP_MAX_POINTS];
  int k[GROUP_MAX_POINTS];
  double t[GROUP_MAX_POINTS];  // m/s: the target normal velocity
};

// The impulses d (N·s) that bring the group's points to their targets t (m/s) with every
// accumulated impulse λ + d >= 0 and no point below its target: the linear
// complementarity problem x = λ + d >= 0, w = A d − r >= 0, x·w = 0, r = t − v_n, A the
// block K of the one dynamic body u (1/kg; where a set's rows are dependent, a face's
// four coplanar points or a seam's point in both manifolds, K + BLOCK_EPS diag(K), else
// K itself, so that an elastic bounce keeps the energy to round-off), solved exactly by
// active sets as solve.cpp's active_set_block does a face's: every point in the set to
// begin with; one whose x comes out below zero leaves it (the most negative), and when
// none does, the one left out most short of its target (w < 0 beyond rounding) comes in;
// at most 4 n + 4 sets. With `owed` (work J, e², h sign acc m/s: a group whose normals
// agree), the set's targets are raised together as push_targets raises a face's, by
// c K⁻¹ 1 where the impulses do e² times the work. Applies the impulses (normal_impulse,
// the bodies) and returns them in d; false where no answer was found (nothing applied).
template <int D>
bool push_group(const Model<D>& model, State<D>& st, Contacts<D>& c, int u,
                const GroupPoints& g, const Owed<D>* owed, double* d) {
  using Vec = typename Dim<D>::Vec;
  using Ang = typename Dim<D>::Ang;
  const int n = g.n;
  const double im = model.body_inv_mass[u];
  const auto& ii = model.body_inv_inertia[u];
  const auto q = st.body_q[u];
  Vec lin[GROUP_MAX_POINTS];  // each point's push on u per unit impulse: ±n
  Ang ang[GROUP_MAX_POINTS], turn[GROUP_MAX_POINTS];  // ±(r × n), and I⁻¹ of it
  double A[GROUP_MAX_POINTS][GROUP_MAX_POINTS], r[GROUP_MAX_POINTS], lam[GROUP_MAX_POINTS];
  double vn[GROUP_MAX_POINTS];
  double scale = 0.0;  // m/s: the largest |r|, for rounding
  for (int i = 0; i < n; ++i) {
    const std::int32_t m = g.m[i];
    const int k = g.k[i];
    const int a = c.body_a[m], b = c.body_b[m];
    const Vec nrm = c.normal[m];
    const double sgn = a == u ? 1.0 : -1.0;
    lin[i] = sgn * nrm;
    ang[i] = sgn * cross(a == u ? c.anchor_a[m][k] : c.anchor_b[m][k], nrm);
    turn[i] = Dim<D>::apply_inv_inertia(ii, q, ang[i]);
    vn[i] = normal_velocity(st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], nrm);
    r[i] = g.t[i] - vn[i];
    lam[i] = c.normal_impulse[m][k];
    scale = std::fmax(scale, std::fabs(r[i]));
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A[i][j] = im * dot(lin[i], lin[j]) + ang_dot(ang[i], turn[j]);
  const double tol = 1e-9 * scale;
  bool in[GROUP_MAX_POINTS];
  double eps = 0.0;  // the regularisation: none, then BLOCK_EPS where rows are dependent
  // the set's system (its rows; a point let go has d = −λ), solved by L D Lᵀ; false where
  // a pivot is not above 1e-12 of its diagonal (1e-14 regularised). With `ones`, K_SS⁻¹ 1
  // instead.
  auto solve_set = [&](bool ones, double* out) {
    int idx[GROUP_MAX_POINTS], ns = 0;
    for (int i = 0; i < n; ++i) {
      if (in[i]) idx[ns++] = i;
      out[i] = ones ? 0.0 : -lam[i];
    }
    double L[GROUP_MAX_POINTS][GROUP_MAX_POINTS], piv[GROUP_MAX_POINTS], y[GROUP_MAX_POINTS];
    for (int x = 0; x < ns; ++x) {
      const int i = idx[x];
      double rhs = ones ? 1.0 : r[i];
      if (!ones)
        for (int j = 0; j < n; ++j)
          if (!in[j]) rhs += A[i][j] * lam[j];
      y[x] = rhs;
    }
    for (int x = 0; x < ns; ++x) {
      const double diag = A[idx[x]][idx[x]] * (1.0 + eps);
      double p = diag;
      for (int z = 0; z < x; ++z) p -= L[x][z] * L[x][z] * piv[z];
      if (!(p > (eps == 0.0 ? 1e-12 : 1e-14) * diag)) return false;
      piv[x] = p;
      for (int w = x + 1; w < ns; ++w) {
        double e = A[idx[w]][idx[x]];
        for (int z = 0; z < x; ++z) e -= L[w][z] * L[x][z] * piv[z];
        L[w][x] = e / p;
      }
    }
    for (int x = 0; x < ns; ++x)
      for (int z = 0; z < x; ++z) y[x] -= L[x][z] * y[z];
    for (int x = ns - 1; x >= 0; --x) {
      double v = y[x] / piv[x];
      for (int z = x + 1; z < ns; ++z) v -= L[z][x] * out[idx[z]];
      out[idx[x]] = v;
    }
    return true;
  };
  // the sets, from every point in: false where none answers within 4 n + 4 of them, or
  // a set's rows are dependent
  auto search = [&] {
    for (int i = 0; i < n; ++i) in[i] = true;
    for (int pass = 0; pass < 4 * n + 4; ++pass) {
      if (!solve_set(false, d)) return false;
      int worst = -1;
      double most = 0.0;  // N·s
      for (int i = 0; i < n; ++i) {
        if (in[i] && lam[i] + d[i] < most) {
          most = lam[i] + d[i];
          worst = i;
        }
      }
      if (worst >= 0) {
        in[worst] = false;
        continue;
      }
      int shortest = -1;
      double least = -tol;  // m/s
      for (int i = 0; i < n; ++i) {
        if (in[i]) continue;
        double w = -r[i];
        for (int j = 0; j < n; ++j) w += A[i][j] * d[j];
        if (w < least) {
          least = w;
          shortest = i;
        }
      }
      if (shortest < 0) return true;
      in[shortest] = true;
    }
    return false;
  };
  bool found = search();
  if (!found) {
    eps = BLOCK_EPS;
    found = search();
  }
  if (!found) return false;
  if (owed && owed->work != 0.0) {
    // impulses d + c q (q = K⁻¹ 1 over the set) do ΔE(c) = ΔE(0) + L c + B c² / 2
    double qv[GROUP_MAX_POINTS];
    if (solve_set(true, qv)) {
      double big_b = 0.0, big_l = 0.0;
      for (int i = 0; i < n; ++i) {
        if (!in[i]) continue;
        big_b += qv[i];
        big_l += qv[i] * (vn[i] + g.t[i]) + d[i];
      }
      big_l = 0.5 * (big_l + owed->hsa * big_b);
      const double disc = big_l * big_l + 2.0 * big_b * owed->e2 * owed->work;
      if (big_l > 0.0 && disc >= 0.0) {
        const double cc = 2.0 * owed->e2 * owed->work / (big_l + std::sqrt(disc));
        bool pulls = false;
        for (int i = 0; i < n; ++i) pulls = pulls || (in[i] && lam[i] + d[i] + cc * qv[i] < 0.0);
        if (!pulls)
          for (int i = 0; i < n; ++i)
            if (in[i]) d[i] += cc * qv[i];
      }
    }
  }
  for (int i = 0; i < n; ++i) {
    const std::int32_t m = g.m[i];
    const int k = g.k[i];
    const double next = std::fmax(lam[i] + d[i], 0.0);
    d[i] = next - lam[i];
    c.normal_impulse[m][k] = next;
    push_point(model, st, c.body_a[m], c.body_b[m], c.anchor_a[m][k], c.anchor_b[m][k],
               c.normal[m], d[i]);
  }
  return true;
}

}  // namespace

// Copy each point's accumulated normal impulse (N·s) to solve_impulse: the push that the
// positions move with this substep (symplectic Euler; see the lone clusters' passes).
template <int D>
void keep_solve_impulses(Contacts<D>& c) {
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) c.solve_impulse[m] = c.normal_impulse[m];
}

template <int D>
void start_restitution(Contacts<D>& c) {
  c.count.bounce_count = c.count.bounce_carried = c.count.elastic_listed = 0;
  // (a call that found clusters over the whole graph leaves every manifold's kind; the
  // next step's manifolds are in other slots, and a call that looks at the listed ones
  // alone must find the others quiet)
  std::fill_n(c.bounce_kind.begin(), c.count.manifolds, std::int8_t{kQuiet});
}

namespace {

// The pieces of one surface a body meets (push_group): entries of `list` (the dynamic
// body, the manifold against a static or kinematic body), sorted by body, whose manifolds'
// normals agree to 1e-9 (flush pieces of a floor, to rounding; a floor and a wall are two
// surfaces: the bounce's energy owed to gravity, Owed, is a face's, along one normal).
// Returns each entry's surface: the index of the first entry of its body with its normal.
template <int D>
std::vector<std::int32_t> surfaces(const Contacts<D>& c,
                                   const std::vector<std::pair<int, std::int32_t>>& list) {
  std::vector<std::int32_t> first(list.size());
  std::size_t run = 0;  // the first entry of the body's run
  for (std::size_t i = 0; i < list.size(); ++i) {
    if (list[i].first != list[run].first) run = i;
    first[i] = static_cast<std::int32_t>(i);
    for (std::size_t j = run; j < i; ++j) {
      if (first[j] == static_cast<std::int32_t>(j) &&
          dot(c.normal[list[i].second], c.normal[list[j].second]) >= 1.0 - 1e-9) {
        first[i] = static_cast<std::int32_t>(j);
        break;
      }
    }
  }
  return first;
}

// Whether the manifolds listed (bounce_list[0..n_listed)) hold an inelastic impact that
// may be part of a group (push_group): two listed manifolds of one surface of a dynamic
// body, one of them inelastic. The stage then looks at the whole contact graph, as for an
// elastic one.
template <int D>
bool group_listed(const Model<D>& model, const Contacts<D>& c, std::int64_t n_listed) {
  std::vector<std::pair<int, std::int32_t>> fixed;  // (the dynamic body, the manifold)
  for (std::int64_t i = 0; i < n_listed; ++i) {
    const std::int32_t m = c.bounce_list[i];
    const int a = c.body_a[m], b = c.body_b[m];
    if (model.is_dynamic(a) != model.is_dynamic(b)) fixed.push_back({model.is_dynamic(a) ? a : b, m});
  }
  std::sort(fixed.begin(), fixed.end());
  fixed.erase(std::unique(fixed.begin(), fixed.end()), fixed.end());
  const std::vector<std::int32_t> surface = surfaces(c, fixed);
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    const std::size_t j = static_cast<std::size_t>(surface[i]);
    if (j != i && (c.restitution[fixed[i].second] == 0.0 || c.restitution[fixed[j].second] == 0.0))
      return true;
  }
  return false;
}

}  // namespace

template <int D>
int restitution_reach(const Model<D>& model, const Contacts<D>& c) {
  const auto& count = c.count;
  if (count.bounce_count == count.bounce_carried) return 0;  // (apply_restitution's own test)
  if (count.elastic_listed == 1) return 2;
  for (std::int64_t i = 0; i < count.bounce_count; ++i)
    if (c.restitution[c.bounce_list[i]] > 0.0) return 2;
  return group_listed(model, c, count.bounce_count) ? 2 : 1;
}

namespace {

// A lone cluster's bodies and points as they were before the stage's bounces (its
// impulses of the substep taken back): each body's velocities, each point's impulses.
template <int D>
struct BodyBefore {
  int u;
  typename Dim<D>::Vec v;
  typename Dim<D>::Ang w, l;  // (l: 3D)
};
template <int D>
struct PointBefore {
  std::int32_t m;
  int k;
  double normal;                     // N·s
  typename Dim<D>::Tangent tangent;  // N·s
};
// A lone cluster that bounces only among its own bodies and off static bodies: its
// entries in the stage's lists of bodies and points.
struct FreeCluster {
  std::size_t bodies_first, bodies_last, points_first, points_last;
};
template <int D>
struct ClustersBefore {
  std::vector<FreeCluster> clusters;
  std::vector<BodyBefore<D>> bodies;
  std::vector<PointBefore<D>> points;
};

// The kinetic energy (J) of body i at v + s dv, ω + s dω (3D: L + s dL) as the quadratic
// k0 + k1 s + k2 s²: {k0, k1, k2}. 2D: I ω² / 2; 3D: ω · L / 2 (ω = I⁻¹ L).
inline std::array<double, 3> energy_along(const Model<2>& model, int i, Vec2 v, Vec2 dv, double w,
                                          double dw, double, double) {
  const double mass = 1.0 / model.body_inv_mass[i];  // kg
  const double inertia =
      model.body_inv_inertia[i] > 0.0 ? 1.0 / model.body_inv_inertia[i] : 0.0;  // kg·m²
  return {0.5 * (mass * dot(v, v) + inertia * w * w), mass * dot(v, dv) + inertia * w * dw,
          0.5 * (mass * dot(dv, dv) + inertia * dw * dw)};
}
inline std::array<double, 3> energy_along(const Model<3>& model, int i, Vec3 v, Vec3 dv, Vec3 w,
                                          Vec3 dw, Vec3 l, Vec3 dl) {
  const double mass = 1.0 / model.body_inv_mass[i];  // kg
  return {0.5 * (mass * dot(v, v) + dot(w, l)),
          mass * dot(v, dv) + 0.5 * (dot(w, dl) + dot(dw, l)),
          0.5 * (mass * dot(dv, dv) + dot(dw, dl))};
}

// The lone clusters (contacts.bounce_kind kAlone; their bodies nothing else pushes) that
// touch no kinematic body, each the dynamic bodies its manifolds join, with what they
// had before the stage's bounces.
template <int D>
ClustersBefore<D> free_clusters(const Model<D>& model, const State<D>& st,
                                const Contacts<D>& c) {
  ClustersBefore<D> out;
  std::vector<std::int32_t> lone;  // the lone manifolds
  std::vector<int> bodies;         // their dynamic bodies
  for (std::int64_t m = 0; m < c.count.manifolds; ++m) {
    if (c.bounce_kind[m] != kAlone) continue;
    if (!model.is_dynamic(c.body_a[m]) && !model.is_dynamic(c.body_b[m])) continue;
    lone.push_back(static_cast<std::int32_t>(m));
    for (const int i : {c.body_a[m], c.body_b[m]})
      if (model.is_dynamic(i)) bodies.push_back(i);
  }
  if (lone.empty()) return out;
  std::sort(bodies.begin(), bodies.end());
  bodies.erase(std::unique(bodies.begin(), bodies.end()), bodies.end());
  const auto n = static_cast<int>(bodies.size());
  auto index = [&](int i) {
    return static_cast<int>(std::lower_bound(bodies.begin(), bodies.end(), i) - bodies.begin());
  };
  // the clusters: the bodies joined by their manifolds (union-find, each set named by its
  // least member), and whether one touches a kinematic body (energy may come from it)
  std::vector<int> root(n);
  for (int x = 0; x < n; ++x) root[x] = x;
  auto find = [&](int x) {
    while (root[x] != x) x = root[x] = root[root[x]];
    return x;
  };
  std::vector<std::uint8_t> barred(n, 0);
  for (const std::int32_t m : lone) {
    const int a = c.body_a[m], b = c.body_b[m];
    const bool da = model.is_dynamic(a), db = model.is_dynamic(b);
    if (da && db) {
      const int x = find(index(a)), y = find(index(b));
      root[std::max(x, y)] = std::min(x, y);
    } else if (model.body_type[da ? b : a] == BodyType::Kinematic) {
      barred[index(da ? a : b)] = 1;
    }
  }
  for (int x = 0; x < n; ++x)
    if (barred[x]) barred[find(x)] = 1;
  // each cluster's bodies and manifolds, clusters in the order of their least body:
  // (its root, the body's or manifold's place) sorted
  std::vector<std::pair<int, int>> members, held;
  for (int x = 0; x < n; ++x)
    if (!barred[find(x)]) members.push_back({find(x), x});
  for (std::size_t e = 0; e < lone.size(); ++e) {
    const std::int32_t m = lone[e];
    const int r = find(index(model.is_dynamic(c.body_a[m]) ? c.body_a[m] : c.body_b[m]));
    if (!barred[r]) held.push_back({r, static_cast<int>(e)});
  }
  std::sort(members.begin(), members.end());
  std::sort(held.begin(), held.end());
  for (std::size_t x = 0, e = 0; x < members.size();) {
    const int r = members[x].first;
    FreeCluster f{out.bodies.size(), 0, out.points.size(), 0};
    for (; x < members.size() && members[x].first == r; ++x) {
      const int u = bodies[members[x].second];
      BodyBefore<D> b{u, st.body_v[u], st.body_w[u], Dim<D>::angular_zero()};
      if constexpr (D == 3) b.l = st.body_l[u];
      out.bodies.push_back(b);
    }
    for (; e < held.size() && held[e].first == r; ++e) {
      const std::int32_t m = lone[held[e].second];
      for (int k = 0; k < c.points[m]; ++k)
        out.points.push_back({m, k, c.normal_impulse[m][k], c.tangent_impulse[m][k]});
    }
    f.bodies_last = out.bodies.size();
    f.points_last = out.points.size();
    out.clusters.push_back(f);
  }
  return out;
}

// A lone cluster that bounces only among its own bodies and off static bodies leaves with
// no more kinetic energy than it came with, but for what the bounces' discrete
// trajectory (bounce_target) trades for position: twice |a| h for each N·s of normal
// impulse (a, the largest of its bodies' own accelerations; h, the substep). Where it
// would leave with more, the stage's change of its bodies' velocities and of its points'
// impulses is scaled down, all of it alike, until it does not (its energy is quadratic
// in the scale). Each pair's bounce is exact, but a body spinning fast that meets a wall
// at several points of a face is struck again at one by what the others' bounces turned
// into it (a convex pebble spinning at 54 rad/s left a wall with 1650 J more than it met
// it with, a 114 kg one at 63 rad/s with 3080 J more), and a light body caught between a
// heavy one and a wall was struck to and fro, one pass after another (a 1.2 kg body
// between a 213 kg one at 18 m/s and a wall left at 210 m/s, and both gained).
template <int D>
void hold_free_energy(const Model<D>& model, State<D>& st, Contacts<D>& c,
                      const ClustersBefore<D>& before, double h) {
  for (const FreeCluster& f : before.clusters) {
    double k0 = 0.0, k1 = 0.0, k2 = 0.0;  // J, J, J (energy_along)
    double acc = 0.0;                     // m/s²
    for (std::size_t x = f.bodies_first; x < f.bodies_last; ++x) {
      const BodyBefore<D>& b = before.bodies[x];
      auto dl = b.l;
      if constexpr (D == 3) dl = st.body_l[b.u] - b.l;
      const auto e = energy_along(model, b.u, b.v, st.body_v[b.u] - b.v, b.w,
                                  st.body_w[b.u] - b.w, b.l, dl);
      k0 += e[0];
      k1 += e[1];
      k2 += e[2];
      const auto a = model.acceleration(b.u);
      acc = std::fmax(acc, std::sqrt(dot(a, a)));
    }
    double pushed = 0.0;  // N·s
    for (std::size_t x = f.points_first; x < f.points_last; ++x) {
      const PointBefore<D>& p = before.points[x];
      pushed += std::fabs(c.normal_impulse[p.m][p.k] - p.normal);
    }
    const double allowed = 2.0 * acc * h * pushed + 1e-9 * k0;  // J
    if (!(k1 + k2 > allowed) || !(k2 > 0.0)) continue;
    // the largest s in [0, 1] with k1 s + k2 s² <= allowed (s = 0 gives 0 <= allowed): the
    // positive root, in the form without cancellation for k1 >= 0
    const double root = std::sqrt(k1 * k1 + 4.0 * k2 * allowed);
    const double s =
        k1 >= 0.0 ? (k1 + root > 0.0 ? 2.0 * allowed / (k1 + root) : 0.0) : (root - k1) / (2.0 * k2);
    if (!(s < 1.0)) continue;
    for (std::size_t x = f.bodies_first; x < f.bodies_last; ++x) {
      const BodyBefore<D>& b = before.bodies[x];
      st.body_v[b.u] = b.v + s * (st.body_v[b.u] - b.v);
      st.body_w[b.u] = b.w + s * (st.body_w[b.u] - b.w);
      if constexpr (D == 3) st.body_l[b.u] = b.l + s * (st.body_l[b.u] - b.l);
    }
    for (std::size_t x = f.points_first; x < f.points_last; ++x) {
      const PointBefore<D>& p = before.points[x];
      c.normal_impulse[p.m][p.k] = p.normal + s * (c.normal_impulse[p.m][p.k] - p.normal);
      c.tangent_impulse[p.m][p.k] = p.tangent + s * (c.tangent_impulse[p.m][p.k] - p.tangent);
    }
  }
}

}  // namespace

template <int D>
void apply_restitution(const Model<D>& model, State<D>& st, Contacts<D>& c, double threshold,
                       double h, double sign) {
  using Vec = typename Dim<D>::Vec;
  auto& count = c.count;
  const std::int64_t n_listed = count.bounce_count;
  // nothing engaged fast since the last call, and no impact waits for its bodies to meet
  if (n_listed == count.bounce_carried) return;
  count.bounce_count = count.bounce_carried = 0;
  bool meeting = false;  // an impact waits for a wall: the next call looks again
  const std::int64_t n_man = count.manifolds;
  auto& kind = c.bounce_kind;
  auto& mark = c.body_mark;
  const auto& im = model.body_inv_mass;
  const bool explicit_euler = sign < 0.0;
  // The manifolds that bounce are listed (some twice), after those left for later below;
  // while none in this step was elastic, each is ended on its own (in index order, as in
  // the full pass) and nothing else needs a look.
  for (std::int64_t i = 0; i < n_listed; ++i)
    if (c.restitution[c.bounce_list[i]] > 0.0) count.elastic_listed = 1;
  if (count.elastic_listed == 0 && group_listed(model, c, n_listed)) count.elastic_listed = 1;
  const bool elastic_listed = count.elastic_listed == 1;
  if (!elastic_listed)
    for (std::int64_t i = 0; i < n_listed; ++i) kind[c.bounce_list[i]] = kJoined;
  // which manifolds bounce, and which bodies something else pushes (mark bit 1)
  if (elastic_listed) std::fill(mark.begin(), mark.end(), std::int8_t{0});
  std::int64_t n_alone = 0;
  std::vector<std::pair<int, std::int32_t>> inelastic;  // (the dynamic body, the manifold)
  std::vector<std::uint8_t> met_impact;  // (M,) 1: an inelastic candidate with a met impact
  if (elastic_listed) met_impact.assign(static_cast<std::size_t>(n_man), 0);
  for (std::int64_t m = 0; m < (elastic_listed ? n_man : 0); ++m) {
    int bouncing = 0, waiting = 0, joining = 0, pushing = 0;
    const bool elastic = c.restitution[m] > 0.0;
    const int a = c.body_a[m], b = c.body_b[m];
    const bool fixed = !model.is_dynamic(a) || !model.is_dynamic(b);  // against a wall
    const double slow = impact_speed(model, a, b, c.normal[m], threshold, h);  // m/s
    for (int k = 0; k < c.points[m]; ++k) {
      // (an impact over before its bodies met is still part of a lone cluster: redone
      // exactly, it may approach again)
      const Impact at =
          impact_state(model, st, c, m, k, a, b, c.normal[m], slow, h, explicit_euler);
      if (at == Impact::Due || at == Impact::Over) {
        ++bouncing;
      } else if (at == Impact::Waiting) {
        ++waiting;
      } else if (c.normal_impulse[m][k] > 0.0) {
        // pushed, slower than an impact: in an elastic contact that carried no load
        // into the step, it may be a passive part of an impact (a ball of a touching
        // row, engaged only by its neighbour's push). So may a resting one where the
        // threshold is below the impact speed (every approach that is an impact bounces),
        // and one that rests on a static or kinematic body: a row of balls resting on the
        // floor is struck as the row alone is, its floor contacts only stopped again in
        // the exact redo (kept as loads, they joined the row's impacts to the solve, which
        // took two thirds of a struck row of five's energy)
        // (An inelastic one on a static or kinematic body is stopped again too, should its
        // manifold's impacts be redone: a box landing across two tiles, its point on the
        // seam reached slowly once the other tile's impact had turned the box.)
        if ((elastic && (c.start_impulse[m][k] == 0.0 || threshold < slow)) || fixed)
          ++joining;
        else
          ++pushing;
      }
    }
    // (a waiting impact of a lone cluster is taken back with it, and left out of its
    // passes: its own speculative push is no part of what the cluster redoes)
    if (pushing == 0 && (bouncing > 0 || waiting > 0 || joining > 0) && elastic) {
      kind[m] = bouncing + waiting > 0 ? kAlone : kPassive;
      ++n_alone;
      continue;
    }
    // an inelastic impact of one dynamic body on a static or kinematic one (or one that
    // waits for the body to meet it), its other points stopped again: redone exactly too
    // where the body has two or more on one surface, one of them met (a group,
    // push_group; the others are joined below). The solve's manifolds one after the
    // other, each block pulling, tipped a box landing flat across two floor tiles at
    // 6.25 m/s, e = 0: it left at 0.29 m/s, turning at 1 rad/s (2D; at 25 m/s, 2.8 m/s
    // and 9.7 rad/s, one tile's impact met a substep before the other's).
    if (!elastic && pushing == 0 && bouncing + waiting > 0 && fixed) {
      kind[m] = kAlone;
      ++n_alone;
      inelastic.push_back({model.is_dynamic(a) ? a : b, static_cast<std::int32_t>(m)});
      if (bouncing > 0) met_impact[m] = 1;
      continue;
    }
    if (bouncing > 0)
      kind[m] = kJoined;
    else if (waiting > 0)
      kind[m] = kWaiting;
    else
      kind[m] = pushing + joining > 0 ? kPushing : kQuiet;
    if (kind[m] != kQuiet) {
      mark[a] |= kPushed;
      mark[b] |= kPushed;
    }
  }
  // an inelastic impact alone on its surface of its body (no other such manifold), or on
  // a surface where none has met, is joined (or waits) as before: the solve's block is
  // its answer
  if (!inelastic.empty()) {
    std::sort(inelastic.begin(), inelastic.end());
    const std::vector<std::int32_t> surface = surfaces(c, inelastic);
    std::vector<std::int32_t> members(inelastic.size(), 0), met(inelastic.size(), 0);
    for (std::size_t i = 0; i < inelastic.size(); ++i) {
      ++members[surface[i]];
      met[surface[i]] += met_impact[inelastic[i].second];
    }
    for (std::size_t i = 0; i < inelastic.size(); ++i) {
      const std::int32_t m = inelastic[i].second;
      if (members[surface[i]] > 1 && met[surface[i]] > 0) continue;
      kind[m] = met_impact[m] != 0 ? kJoined : kWaiting;
      mark[c.body_a[m]] |= kPushed;
      mark[c.body_b[m]] |= kPushed;
      --n_alone;
    }
  }
  // a cluster that touches a pushed (dynamic) body joins it, until nothing changes
  bool changed = n_alone > 0;
  while (changed) {
    changed = false;
    for (std::int64_t m = 0; m < n_man; ++m) {
      if (kind[m] != kAlone && kind[m] != kPassive) continue;
      const int a = c.body_a[m], b = c.body_b[m];
      if (((mark[a] & kPushed) && im[a] > 0.0) || ((mark[b] & kPushed) && im[b] > 0.0)) {
        kind[m] = kind[m] == kAlone ? kJoined : kPushing;
        mark[a] |= kPushed;
        mark[b] |= kPushed;
        --n_alone;
        changed = true;
      }
    }
  }
  // passive points take part only in a cluster that holds a bounce (mark bit 2: the body
  // is reached from one); the others stay as the solve left them
  if (n_alone > 0) {
    for (std::int64_t m = 0; m < n_man; ++m) {
      if (kind[m] == kAlone) {
        mark[c.body_a[m]] |= kReached;
        mark[c.body_b[m]] |= kReached;
      }
    }
    changed = true;
    while (changed) {
      changed = false;
      for (std::int64_t m = 0; m < n_man; ++m) {
        if (kind[m] != kPassive) continue;
        const int a = c.body_a[m], b = c.body_b[m];
        if (((mark[a] & kReached) && im[a] > 0.0) || ((mark[b] & kReached) && im[b] > 0.0)) {
          kind[m] = kAlone;
          mark[a] |= kReached;
          mark[b] |= kReached;
          changed = true;
        }
      }
    }
  }
  // The lone bodies' manifolds with static and kinematic bodies, by body and in solve
  // order within each, and their surfaces: the groups of the passes below (push_group).
  // A lone body's other contacts with pieces of the same surface, quiet in the substep,
  // are its group's too: the solve's push at one of them may have stopped the body, which
  // it no longer does once taken back. A box landing flat on the corner of four tiles was
  // stopped by the first tile's manifold in the solve, the others never engaged; bounced
  // by that one alone, it tipped, and the next substep's impacts at the others sent it up
  // at 3.9 m/s, not 3.1 (e = 0.5). (A lone manifold's dynamic body is never pushed by
  // anything else: such a cluster was joined above.)
  std::vector<std::pair<int, std::int32_t>> fixed;  // (the dynamic body, the manifold)
  std::vector<std::int32_t> surface;
  if (n_alone > 0) {
    for (std::int64_t o = 0; o < n_man; ++o) {
      const std::int32_t m = c.solve_order[o];
      const int a = c.body_a[m], b = c.body_b[m];
      const int u = model.is_dynamic(a) == model.is_dynamic(b) ? -1 : model.is_dynamic(a) ? a : b;
      if (u < 0 || (mark[u] & kPushed)) continue;
      if (kind[m] == kAlone || (kind[m] == kQuiet && c.points[m] > 0)) fixed.push_back({u, m});
    }
    std::stable_sort(fixed.begin(), fixed.end(),
                     [](const auto& x, const auto& y) { return x.first < y.first; });
    surface = surfaces(c, fixed);
    std::vector<std::uint8_t> lone(fixed.size(), 0);  // a surface with a lone manifold
    for (std::size_t i = 0; i < fixed.size(); ++i)
      if (kind[fixed[i].second] == kAlone) lone[surface[i]] = 1;
    for (std::size_t i = 0; i < fixed.size(); ++i)
      if (lone[surface[i]]) kind[fixed[i].second] = kAlone;
  }
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (kind[m] == kAlone) {
      // take back this substep's impulses at the cluster's points, friction with them
      for (int k = 0; k < c.points[m]; ++k)
        take_back(model, st, c, m, k, c.body_a[m], c.body_b[m]);
      continue;
    }
    if (kind[m] != kJoined && kind[m] != kWaiting) continue;
    if (!elastic_listed) kind[m] = kQuiet;  // the next call's list starts clean
    const int a = c.body_a[m], b = c.body_b[m];
    const double e = c.restitution[m];
    const Vec n = c.normal[m];
    const double acc = relative_acceleration(model, a, b, n);
    const double slow = impact_speed(model, a, b, n, threshold, h);  // m/s
    std::array<double, Dim<D>::max_points> target{};
    PointFlags<D> bounce{};
    bool deferred = false, any_bounce = false;
    // every point's state first: a point's take-back turns the bodies, which would change
    // the others' (a face's one point taken back alone spun a flat box, and the other's
    // arc then took its impact in mid-air)
    std::array<Impact, Dim<D>::max_points> state{};
    for (int k = 0; k < c.points[m]; ++k)
      state[k] = impact_state(model, st, c, m, k, a, b, n, slow, h, explicit_euler);
    for (int k = 0; k < c.points[m]; ++k) {
      const Impact at = state[k];
      if (at == Impact::Waiting) {  // looked at again when the stage next runs
        const double s_now = point_separation(c, m, k, a, b, n);  // m
        if (e > 0.0 && s_now >= c.approach_separation[m][k]) {
          // an elastic one no nearer than where it engaged: held there by its bodies'
          // other contacts, the push given back at every call never moved the positions,
          // and the impact would wait for ever while the approach it restores grows (a
          // capsule pinned on the floor under a heavier body, a point 2 mm up and
          // approaching by its turn, was so spun up to 1000 rad/s in place). It does not
          // bounce: its push stays, the impact is over
          end_impact(c, m, k);
          continue;
        }
        // it gives its speculative push back, as a lone cluster's do, elastic or not
        // where it is apart: the impact is then resolved, with its friction, in the
        // substep where the bodies meet. Kept, an elastic one would cost the bounce its
        // approach should the bodies meet only after the step (the next step records the
        // approach afresh); an inelastic one was warm-started into the next substep,
        // which delivered only the rest of the impact, with Coulomb's friction for that
        // rest alone (the push, given apart, had none: solve.cpp). Within row.touch an
        // inelastic push is kept: it had its friction, and in a pile pressed against its
        // walls pushes taken back there came back as impacts (625 confined circles, over
        // full: kinetic energy to 3.55 times the hard case's bound, 0.08 kept)
        if (e > 0.0 || s_now > c.solver_row[m].touch) take_back(model, st, c, m, k, a, b);
        const bool both_dynamic = model.is_dynamic(a) && model.is_dynamic(b);
        if (both_dynamic) {
          // between two dynamic bodies the approach it engaged with goes stale before
          // they meet: whatever else pushes either body changes it (kept, a ball falling
          // onto two that touch on the floor was bounced by its approach of a substep
          // before, and 20 elastic balls lost 2.3% of their energy in that step). It
          // engages afresh with the next substep's push, and records its approach then
          end_impact(c, m, k);
          continue;
        }
        deferred = true;
        meeting = true;
        continue;
      }
      if (at == Impact::Over) end_impact(c, m, k);
      if (at != Impact::Due) continue;
      // one bounce per impact; should the bodies meet again within the step, the point
      // engages afresh (see solve_contacts) and records its new approach
      const double vn0 = c.approach_velocity[m][k];
      const double s0 = c.approach_separation[m][k];
      end_impact(c, m, k);
      const double s_now = point_separation(c, m, k, a, b, n);
      const double invariant = engaged_invariant(vn0, s0, acc, h);
      bounce[k] = true;
      any_bounce = true;
      target[k] = bounce_target(invariant, s_now, acc, e, h, sign);
    }
    if (deferred) PassLog::direct(c).add_bounce(static_cast<std::int32_t>(m));
    if (!any_bounce) continue;
    const Owed<D> owed{0.0, 0.0, 0.0, target};
    const auto j = push_targets(model, st, c, m, a, b, bounce, target, false, owed);
    for (int k = 0; k < c.points[m]; ++k) {
      const double jk = j[k];
      c.max_normal_impulse[m][k] = std::fmax(c.max_normal_impulse[m][k], jk);
      if (bounce[k]) {
        impact_coulomb(model, st, c, m, k, a, b);
        drop_bounce(c, m, k);
      }
    }
  }
  // the waiting ones, carried to the next call
  count.bounce_carried = meeting ? 0 : count.bounce_count;
  if (n_alone == 0) return;
  // The points of a lone manifold that need a push in a pass, and their targets (m/s):
  // t, the bounce's (with work owed, the block's); u, a point's alone.
  struct Needs {
    PointFlags<D> need{};
    std::array<double, Dim<D>::max_points> t{}, u{};
    double work = 0.0;  // J
    bool any = false;
  };
  // (with `met`, a point waiting within half a substep's approach of the other body,
  // |v_n| h / 2, is taken as met: see bounce_group)
  auto needs_of = [&](std::int64_t m, bool met = false) {
    Needs out;
    const int a = c.body_a[m], b = c.body_b[m];
    const double e = c.restitution[m];
    const Vec n = c.normal[m];
    const double acc = relative_acceleration(model, a, b, n);
    const double slow = impact_speed(model, a, b, n, threshold, h);  // m/s
    for (int k = 0; k < c.points[m]; ++k) {
      const double vn = normal_velocity(st, a, b, c.anchor_a[m][k], c.anchor_b[m][k], n);
      if (vn >= 0.0) continue;
      const bool first = c.approach_velocity[m][k] < -slow;
      // not met yet: an impact that engaged at a gap, or a point the solve pushed only
      // to close a gap (a capsule flying end first at a wall has a point at each end;
      // bounced there, its far end's turned it back 1.4 m short of the wall)
      if ((first || vn < -slow) &&
          where_met(model, st, c, m, k, a, b, n, h, explicit_euler) == Impact::Waiting &&
          !(met && point_separation(c, m, k, a, b, n) <= -0.5 * vn * h))
        continue;
      double target = 0.0, alone = 0.0, work = 0.0;
      if (first || vn < -slow) {
        const double s_now = point_separation(c, m, k, a, b, n);
        // The invariant here and now; at its first impact the point also owes the
        // work gravity did on the bodies' centres over the part of the substep's
        // motion that its own solve impulse caused (symplectic Euler moves the
        // positions after the solve; explicit Euler before it, which owes nothing).
        double invariant = 0.5 * vn * vn + 0.5 * sign * acc * h * vn - acc * s_now;
        target = bounce_target(invariant, s_now, acc, e, h, sign);
        if (first && sign > 0.0) work = acc * h * c.solve_impulse[m][k];  // J
        alone = target;
        if (work != 0.0) {  // per unit effective mass, for the point alone
          invariant += work / c.normal_mass[m][k];
          alone = bounce_target(invariant, s_now, acc, e, h, sign);
        }
      }
      out.work += work;
      out.need[k] = true;
      out.any = true;
      out.t[k] = target;
      out.u[k] = alone;
    }
    return out;
  };
  // the pushes' friction, each pushed point's impact over once bounced (u > 0; pushed:
  // need and an impulse j); where a face's (or a group's) several points were pushed, they
  // are brought back to the velocities the pushes reached (`again`, before the friction)
  // by shifting normal impulse from one to another, which changes their friction by the
  // shift alone (impact_coulomb). Else the friction's turn (it comes after the pushes,
  // below the centre of mass) is taken for a new approach of the face's leading point
  // and bounced again: a box bouncing flat from (400, −300) m/s, e = 0.5, μ = 0.6, left
  // too fast (166 m/s up, not 150) and spinning at 15,000 rad/s. Returns whether any
  // point was pushed.
  auto after_pushes = [&](int count, const std::int32_t* ms, const int* ks, const double* j,
                          const double* u, auto&& again) {
    double reached[GROUP_MAX_POINTS] = {};
    int n_pushed = 0;
    bool struck = false;
    for (int i = 0; i < count; ++i) {
      if (j[i] == 0.0) continue;
      ++n_pushed;
      const std::int64_t m = ms[i];
      reached[i] = normal_velocity(st, c.body_a[m], c.body_b[m], c.anchor_a[m][ks[i]],
                                   c.anchor_b[m][ks[i]], c.normal[m]);
    }
    for (int i = 0; i < count; ++i) {
      if (j[i] == 0.0) continue;
      const std::int64_t m = ms[i];
      impact_friction(model, st, c, m, ks[i], c.body_a[m], c.body_b[m], j[i]);
      if (u[i] > 0.0) end_impact(c, m, ks[i]);  // bounced
      if (j[i] > 0.0) struck = true;
    }
    if (n_pushed > 1) {
      again(reached);
      for (int i = 0; i < count; ++i)
        if (j[i] != 0.0) impact_coulomb(model, st, c, ms[i], ks[i], c.body_a[ms[i]], c.body_b[ms[i]]);
    }
    return struck;
  };
  // one lone manifold's points that need a push; returns whether any was pushed
  auto bounce_manifold = [&](std::int64_t m) {
    const Needs nd = needs_of(m);
    if (!nd.any) return false;
    const int a = c.body_a[m], b = c.body_b[m];
    const double e = c.restitution[m];
    const double acc = relative_acceleration(model, a, b, c.normal[m]);
    // each impulse is a bounce against the velocity it meets (a block's two targets
    // are both taken from the velocities before it): e = 1 keeps the energy exactly,
    // and a point left for later is taken up in the next pass; each has its friction
    const Owed<D> owed{nd.work, e * e, sign * h * acc, nd.u};
    const auto j = push_targets(model, st, c, m, a, b, nd.need, nd.t, true, owed);
    std::int32_t ms[Dim<D>::max_points];
    int ks[Dim<D>::max_points], count = 0;
    double js[Dim<D>::max_points], us[Dim<D>::max_points];
    PointFlags<D> pushed{};
    for (int k = 0; k < c.points[m]; ++k) {
      if (!nd.need[k]) continue;
      pushed[k] = j[k] != 0.0;
      ms[count] = static_cast<std::int32_t>(m);
      ks[count] = k;
      js[count] = pushed[k] ? j[k] : 0.0;
      us[count++] = nd.u[k];
    }
    return after_pushes(count, ms, ks, js, us, [&](const double* reached) {
      std::array<double, Dim<D>::max_points> back{};
      for (int i = 0; i < count; ++i) back[ks[i]] = reached[i];
      const Owed<D> none{0.0, 0.0, 0.0, back};
      push_targets(model, st, c, m, a, b, pushed, back, false, none);
    });
  };
  // Groups (push_group): the lone manifolds of a surface of a body (`fixed` above: a
  // surface's manifolds are all lone or none), two or more, each group in solve order;
  // group[m] is manifold m's (-1: none).
  std::vector<std::int32_t> group(fixed.empty() ? 0 : n_man, -1);
  std::vector<std::vector<std::int32_t>> groups;  // each one's manifolds, in solve order
  {
    std::vector<std::int32_t> members(fixed.size(), 0), index(fixed.size(), -1);
    for (std::size_t i = 0; i < fixed.size(); ++i)
      members[surface[i]] += kind[fixed[i].second] == kAlone ? 1 : 0;
    for (std::size_t i = 0; i < fixed.size(); ++i) {
      const std::int32_t j = surface[i];
      if (members[j] < 2 || kind[fixed[i].second] != kAlone) continue;
      if (index[j] < 0) {
        index[j] = static_cast<std::int32_t>(groups.size());
        groups.emplace_back();
      }
      groups[index[j]].push_back(fixed[i].second);
      group[fixed[i].second] = index[j];
    }
  }
  // a group's points that need a push, as one block, where two or more of its manifolds
  // have such points: 1 when any was pushed, 0 when none, -1 when the group is left to
  // its manifolds one by one (one manifold needs a push, too many points, no answer)
  auto bounce_group = [&](const std::vector<std::int32_t>& members) {
    GroupPoints g;
    double us[GROUP_MAX_POINTS];
    int needing = 0;
    double work = 0.0, e2 = 0.0, hsa = 0.0;
    bool same = true;  // every manifold's e the same (owed work)
    const std::int32_t m0 = members[0];
    const int u = model.is_dynamic(c.body_a[m0]) ? c.body_a[m0] : c.body_b[m0];
    // Where a point of the group has met its body, the group's points still a little apart
    // (within half a substep's approach, |v_n| h / 2) meet it with them: the body lands on
    // them as one. The solve's manifolds one after the other tilt a box landing flat
    // across two tiles by a little, its far corners up to a fifth of a substep's approach
    // apart (2.9 mm of 13 at 3.1 m/s, 17 of 104 at 25 m/s), and its corners met in two
    // substeps, each tile's bounced alone: e = 0.5, from 3.1 m/s the box left at 1.17
    // m/s, not 1.53, turning at 3 rad/s. (So a body tilted by less than that over its
    // pieces lands on them flat; tilted more, a corner first, that corner bounces alone,
    // as on one floor.)
    bool met = false;
    for (std::size_t x = 0; x < members.size() && !met; ++x) met = needs_of(members[x]).any;
    for (const std::int32_t m : members) {
      const Needs nd = needs_of(m, met);
      if (!nd.any) continue;
      ++needing;
      const double e = c.restitution[m];
      const Vec n = c.normal[m];
      const double acc = relative_acceleration(model, c.body_a[m], c.body_b[m], n);
      if (needing == 1) {
        e2 = e * e;
        hsa = sign * h * acc;
      } else {
        same = same && e * e == e2;
      }
      work += nd.work;
      for (int k = 0; k < c.points[m]; ++k) {
        if (!nd.need[k]) continue;
        if (g.n == GROUP_MAX_POINTS) return -1;
        g.m[g.n] = m;
        g.k[g.n] = k;
        g.t[g.n] = nd.t[k];
        us[g.n++] = nd.u[k];
      }
    }
    if (needing < 2) return -1;
    double j[GROUP_MAX_POINTS];
    const Owed<D> owed{same ? work : 0.0, e2, hsa, {}};
    if (!push_group(model, st, c, u, g, &owed, j)) return -1;
    const bool struck = after_pushes(g.n, g.m, g.k, j, us, [&](const double* reached) {
      GroupPoints back;
      for (int i = 0; i < g.n; ++i) {
        if (j[i] == 0.0) continue;
        back.m[back.n] = g.m[i];
        back.k[back.n] = g.k[i];
        back.t[back.n++] = reached[i];
      }
      double unused[GROUP_MAX_POINTS];
      push_group(model, st, c, u, back, static_cast<const Owed<D>*>(nullptr), unused);
    });
    return struck ? 1 : 0;
  };
  std::vector<int> group_pass(groups.size(), -1), group_alone(groups.size(), -1);
  const ClustersBefore<D> before = free_clusters(model, st, c);
  // the lone clusters, one pair's impact at a time (a group's at once)
  for (int pass = 0; pass < C::RESTITUTION_PASSES; ++pass) {
    bool struck = false;
    for (std::int64_t o = 0; o < n_man; ++o) {
      const std::int64_t m = c.solve_order[o];
      if (kind[m] != kAlone) continue;
      const int gi = group.empty() ? -1 : group[m];
      if (gi >= 0 && group_alone[gi] != pass) {
        if (group_pass[gi] == pass) continue;  // (solved with the group's first manifold)
        const int got = bounce_group(groups[gi]);
        if (got >= 0) {
          group_pass[gi] = pass;
          struck = struck || got == 1;
          continue;
        }
        group_alone[gi] = pass;
      }
      if (bounce_manifold(m)) struck = true;
    }
    if (!struck) break;
  }
  hold_free_energy(model, st, c, before, h);
  for (std::int64_t m = 0; m < n_man; ++m) {
    if (kind[m] != kAlone) continue;
    const int a = c.body_a[m], b = c.body_b[m];
    const double slow = impact_speed(model, a, b, c.normal[m], threshold, h);  // m/s
    bool deferred = false;
    // every point's state first (a point's approach held turns the bodies: as above)
    std::array<Impact, Dim<D>::max_points> state{};
    for (int k = 0; k < c.points[m]; ++k) {
      const double total = c.normal_impulse[m][k];
      c.max_normal_impulse[m][k] = std::fmax(c.max_normal_impulse[m][k], total);
      if (c.approach_velocity[m][k] != kInf)
        state[k] = impact_state(model, st, c, m, k, a, b, c.normal[m], slow, h, explicit_euler);
    }
    PointFlags<D> hold{};
    for (int k = 0; k < c.points[m]; ++k) {
      if (c.approach_velocity[m][k] == kInf) {
        // a bounce is not warm-started; a point that only stopped an approach keeps its
        // impulse, as the solve's points do
        drop_bounce(c, m, k);
      } else if (state[k] == Impact::Waiting) {
        if (model.is_dynamic(a) && model.is_dynamic(b)) {
          end_impact(c, m, k);  // engages afresh, as a joined cluster's (above)
        } else {
          deferred = true;  // looked at again when the stage next runs
          meeting = true;
          hold[k] = true;  // its push was taken back (the cluster's, above)
        }
      } else if (c.approach_velocity[m][k] < -slow) {
        // its impact was met by the others' bounces before it struck: it is over (a
        // later approach engages afresh in the solve)
        end_impact(c, m, k);
      }
    }
    // The positions moved this substep with the cluster's pushes, which were taken back:
    // a waiting point came nearer by less than its approach would have carried it (a box
    // whose push at a corner turned it, the corner swinging up as it fell, waited so step
    // after step). Its approach is held to what the discrete trajectory from where it
    // engaged allows at the separation it has now, the invariant of the bounce's target:
    // restored in full, the approach outran the fall the positions made, and a box
    // landing so gained 16% of the scene's energy. (A lone cluster's bodies fly free but
    // for its impacts: nothing else pushes them.)
    const double acc = relative_acceleration(model, a, b, c.normal[m]);
    for (int k = 0; k < c.points[m]; ++k)
      if (hold[k]) hold_approach(model, st, c, m, k, a, b, c.normal[m], acc, h, sign);
    if (deferred) PassLog::direct(c).add_bounce(static_cast<std::int32_t>(m));
  }
  count.bounce_carried = meeting ? 0 : count.bounce_count;
}

template void keep_solve_impulses(Contacts<2>&);
template void apply_restitution(const Model<2>&, State<2>&, Contacts<2>&, double, double, double);
template void start_restitution(Contacts<2>&);
template void start_restitution(Contacts<3>&);
template int restitution_reach(const Model<2>&, const Contacts<2>&);
template int restitution_reach(const Model<3>&, const Contacts<3>&);
template void keep_solve_impulses(Contacts<3>&);
template void apply_restitution(const Model<3>&, State<3>&, Contacts<3>&, double, double, double);

}  // namespace rbsim
