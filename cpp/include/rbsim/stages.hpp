// Every stage of the step, declared once. step.cpp is the only file that orders them;
// each is defined in the source file named beside it and instantiated there for the
// dimensions it serves.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>

#include "constants.hpp"
#include "contacts.hpp"
#include "grid.hpp"
#include "model.hpp"
#include "state.hpp"
#include "types.hpp"
#include "wide.hpp"

namespace rbsim {

// A soft constraint for one substep: mass scale, impulse scale, bias rate (1/s).
struct Soft {
  double mass_scale = 1.0;
  double impulse_scale = 0.0;
  double bias_rate = 0.0;
};

// An implicit damped spring of `hertz` (Hz) and damping ratio zeta, integrated with step
// h (s), as scalings of the rigid impulse. hertz = 0 is a rigid constraint.
Soft soft_parameters(double hertz, double zeta, double h);

// The stiffness (Hz) of a contact with a static or kinematic body, where one between two
// dynamic bodies has `hertz`: twice that, within the same cap (Hz, a quarter of the
// substep rate).
inline double static_hertz(double hertz, double cap) { return std::min(2.0 * hertz, cap); }

// A range [first, last) of items (bodies, shapes, manifolds): a part of a stage that the
// step runs on one of its threads (step.cpp).
struct Span {
  std::int64_t first = 0, last = 0;
};

// Part p of `parts` near-equal parts of n items.
inline Span part_of(std::int64_t n, std::int64_t p, std::int64_t parts) {
  return {n * p / parts, n * (p + 1) / parts};
}

// A stage's items [0, n) in parts on the step's threads (World::parallel): f(part) for
// each, back once all are done; a part writes only its own items' outputs. A stage given
// none (one thread, the tests) makes the one call f({0, n}) itself (in_parts).
using InParts = std::function<void(std::int64_t n, const std::function<void(Span)>& f)>;
inline void in_parts(const InParts* parts, std::int64_t n, const std::function<void(Span)>& f) {
  if (parts != nullptr)
    (*parts)(n, f);
  else
    f(Span{0, n});
}

// Per-run numbers for the stages.
struct Config {
  double dt = 1.0 / 60.0;         // s
  int substeps = 4;
  int iterations = 1;             // per substep
  bool explicit_euler = false;    // else symplectic Euler
  Rotation rotation = Rotation::Normalize;  // how q turns (integrate.cpp)
  double restitution_threshold = 1.0;  // m/s
  MixRule friction_rule = MixRule::Sqrt;
  MixRule restitution_rule = MixRule::Max;
  bool elastic = false;           // some material has restitution > 0
  Soft soft;                      // contacts between two dynamic bodies
  Soft soft_static;               // contacts with a static or kinematic body (stiffer, to the cap)
  int threads = 1;                // the step's threads (solver.threads), >= 1
  // solver.threads not set: each step runs on one thread or on `threads`, whichever the
  // run's trials timed faster (ThreadChoice); the result is the same bits either way
  bool choose_threads = false;
};

// The soft contacts of config's substep h = dt / substeps: CONTACT_HERTZ, capped at a
// quarter of the substep rate, for contacts between dynamic bodies; twice that for
// contacts with a static or kinematic body; damping ratio CONTACT_DAMPING_RATIO.
void set_contact_softness(Config& config);

// collide/transform.cpp: world vertices and normals of every shape, how far each can move
// in the step (contacts.shape_margin, shape_turn: |dt v - frame| + dt² |a| + dt |ω| r and
// dt |ω| r), and in 3D each body's world inverse inertia tensor.
template <int D>
void transform_shapes(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      double dt);
// The same for the bodies and the shapes of two ranges (one thread's part), the boxes'
// reach about the frame's move `frame` (m, frame_move's).
template <int D>
void transform_shapes(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      double dt, const typename Dim<D>::Vec& frame, Span bodies, Span shapes);
// collide/transform.cpp: the median move (m) of the dynamic bodies in the last step
// (contacts.body_delta, before the step resets it) along each axis (the lower middle one
// of an even count; zero without dynamic bodies): how far the frame of the shapes' boxes
// moves this step (the boxes reach about it, and the broadphase keeps them in it,
// Grid::frame_offset). A heap falling as one then has boxes as tight, and as still, as
// a heap at rest; bodies at rest beside a few moving ones keep theirs.
template <int D>
typename Dim<D>::Vec frame_move(const Model<D>& model, const Contacts<D>& contacts);

// collide/transform.cpp: each convex shape's hull topology from model.face_local (once,
// when a 3D world is built), and the rows of Contacts::face_world they need. Returns
// false with a message in *error when a convex shape's triangles do not close a convex
// surface (the shape's vertex and triangle ranges must already be checked).
bool build_shape_hulls(Model<3>& model, std::string* error);

// collide/transform.cpp: model.segment_ghost from the static segments' world ends (once,
// when a 2D world is built: static bodies do not move).
void find_segment_neighbours(Model<2>& model, const State<2>& state);

// collide/transform.cpp: model.shape_covered, corner_covered and cover from the static
// polytopes' world faces (once, when a world is built: static bodies do not move);
// scale: each shape's contact scale (constants.hpp, SCALE_LENGTH), for FLUSH_DISTANCE.
template <int D>
void find_covered_faces(Model<D>& model, const State<D>& state, const std::vector<double>& scale);

// collide/broadphase.cpp: update contacts.pairs (sorted by (a, b), a < b) from the
// shapes' boxes; returns the pair count, which exceeds the capacity when the store must
// grow (the list is then invalid). The shapes' boxes and the moved shapes' queries in
// parts when given (the same pairs whatever the parts).
template <int D>
std::int64_t find_pairs(const Model<D>& model, Grid<D>& grid, Contacts<D>& contacts,
                        const InParts* parts = nullptr);

// contact/manifold.cpp: narrowphase (time of impact for fast speculative pairs) for the
// first n_pairs pairs, warm-start matching against last step's manifolds, carried
// manifolds for still bodies: narrow_pairs, manifold_slots, merge_manifolds and
// finish_manifolds over all the pairs, on the caller's thread.
template <int D>
void update_manifolds(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      const Grid<D>& grid, std::int64_t n_pairs, MixRule friction_rule,
                      MixRule restitution_rule, double dt);

// The stage in parts, for the step's threads (each part writes only its own pairs' and
// manifolds' rows; the result is the same bits for any parts):
// contact/manifold.cpp: what each pair of `pairs` holds: found_points[p] FOUND_APART
// (tight boxes apart), FOUND_CARRIED (bodies still, last step's manifold carried), else
// its point count after the narrowphase and, for a pair that meets within the step, the
// time of impact (found[p]: its manifold there, and the time).
template <int D>
void narrow_pairs(const Model<D>& model, const State<D>& state, const Contacts<D>& contacts,
                  const Grid<D>& grid, double dt, Span pairs, PairManifold<D>* found,
                  std::int8_t* found_points);
// Each pair's manifold slot: slot[p] the manifolds of the pairs before p in `pairs`,
// slot[pairs.last] all of them (a prefix count; on one thread).
void manifold_slots(Span pairs, const std::int8_t* found_points, std::int64_t* slot);
// What merge_manifolds tells of its pairs: whether every manifold is last step's pair in
// the same slot, and whether one touches where it did not, or no longer does.
struct MergeFlags {
  bool same = true;
  bool touch_changed = false;
};
// The manifolds of `pairs` into their slots (warm starting from last step's, carried
// ones updated).
template <int D>
MergeFlags merge_manifolds(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                           Span pairs, MixRule friction_rule, MixRule restitution_rule,
                           const PairManifold<D>* found, const std::int8_t* found_points,
                           const std::int64_t* slot);
// The store's counts from the merge: `manifolds` made, the parts' flags combined.
template <int D>
void finish_manifolds(Contacts<D>& contacts, std::int64_t manifolds, MergeFlags flags);

// contact/store.cpp: this step's manifolds become last step's (for warm starting).
template <int D>
void store_impulses(Contacts<D>& contacts);
// contact/store.cpp: the hand-over of a step whose pairs were mostly not still (few
// manifolds carried: the step writes every manifold anew). store_touching does the
// range's part of it that cannot wait, each manifold's support into prev_support, and
// returns its points that pushed (as store_impulses); the caller then sets
// contacts.prev_pending. take_prev, at the next step's start, swaps the manifold arrays
// with the prev_* ones (the keys copied: the current ones stay last step's) and sets
// contacts.prev_swapped; settle_prev copies them instead (the end of an advance: between
// calls the prev_* arrays are last step's, as a checkpoint and the tests read them).
// Either gives the next step the same prev_* as store_impulses (a swap costs no copy).
template <int D>
std::int64_t store_touching(Contacts<D>& contacts, Span manifolds);
template <int D>
void take_prev(Contacts<D>& contacts);
template <int D>
void settle_prev(Contacts<D>& contacts);
// contact/store.cpp: at the step's start, no point pushed by the shock pass yet
// (Contacts::shock_points) and, while contacts.record_impulses, each point's step
// impulse (Contacts::step_impulse, shock_impulse) zero; add_step_impulses adds each
// point's accumulated normal impulse at the end of each substep (the impulses in the
// store: 2D gives them back from the batches first).
template <int D>
void begin_step_impulses(Contacts<D>& contacts);
template <int D>
void add_step_impulses(Contacts<D>& contacts);
// The same for the manifolds of one range (the counts are left to the caller); returns
// the range's contact points that pushed.
template <int D>
std::int64_t store_impulses(Contacts<D>& contacts, Span manifolds);

// solver/prepare.cpp: effective masses, approach velocities and softness into the rows:
// config's soft and soft_static, or stiffer for small shapes (STIFFNESS_LENGTH), and each
// manifold's push-out speed and deep-overlap depth (SCALE_LENGTH).
template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      const Config& config);
// The same for the manifolds of one range (one thread's part).
template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      const Config& config, Span manifolds);

// solver/prepare.cpp, 3D, within a step: the rows of the contacts of a body that has
// turned far since they were made (ROW_TURN_MAX, weighted by how far its inertia is from
// round) made again with its world tensor at its rotation now, so that the passes'
// response to an impulse stays the one the position update finds from L. The contact
// points (arms), normals and approach velocities stay the step's start's.
// mark_turned_bodies marks those bodies (contacts.body_row_remade) and returns whether
// any is; refresh_turned_rows remakes the rows of the manifolds in range that touch one.
// turn_watch lists the bodies that may need it (contacts.turn_watch, made at allocate);
// begin_turn_watch takes their rotations at the step's start, where the rows are made.
std::vector<TurnWatch> turn_watch(const Model<3>& model);
void begin_turn_watch(const State<3>& state, Contacts<3>& contacts);
bool mark_turned_bodies(const State<3>& state, Contacts<3>& contacts);
void refresh_turned_rows(const Model<3>& model, const State<3>& state, Contacts<3>& contacts,
                         const Config& config, Span manifolds);
// solver/waves.cpp, 3D: the rows refresh_turned_rows remade into their batches' lanes.
void repack_turned_rows(const Model<3>& model, Contacts<3>& contacts);

// solver/shock.cpp: support levels and the solve order; returns the shock pass's count.
template <int D>
std::int64_t support_order(const Model<D>& model, Contacts<D>& contacts);
// solver/shock.cpp: each manifold's friction load (SolverRow::friction_load), the weight
// a heavy body's support carries through the shock pass, per substep h (s); after
// support_order, whose shock order (n_order manifolds) and borne loads it reads.
template <int D>
void friction_loads(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                    std::int64_t n_order, double h);
// solver/shock.cpp, after the step of a run that records its contact points
// (contacts.record_impulses): the shock pass pushed each supported body off a supporter
// held still, so the supporter's reaction went into no contact; it is handed down the
// shock order, from the top, into the step impulses of the contacts that hold the
// supporter up, to a static or kinematic body: what presses on a body goes to its
// supports that it presses on (their normals against it), each taking its part along
// its own normal split evenly among them, over its points by what each carried. Each
// dynamic body's recorded normal forces then add up to its change of momentum less
// gravity where the normals are parallel (a stack on a floor); elsewhere the part of a
// load across a support's normal is not handed on (the friction that carries it is not
// recorded).
template <int D>
void hand_down_shock_impulses(const Model<D>& model, Contacts<D>& contacts);

// solver/waves.cpp: the waves of the solve order (manifolds that share no dynamic body,
// solved at once with the result of solving them in solve order) into contacts.wave_order
// and contacts.batches (3D: batches3 and faces3); returns the number of waves.
// 2D: the batches packed in parts when given (each batch from its own manifolds' rows).
template <int D>
std::int64_t find_waves(const Model<D>& model, Contacts<D>& contacts,
                        const InParts* parts = nullptr);

// solver/waves.cpp (2D): the batches' lanes take their manifolds' impulses (normal,
// tangent, largest normal, approach speed) for the passes, which then read and write them
// there instead of gathering and scattering them every pass; give_impulses writes them
// back before anything else reads or writes them (restitution, the extra relax passes,
// the store). Each does nothing when the impulses are already where it puts them, and
// both nothing in 3D.
template <int D>
void take_impulses(Contacts<D>& contacts);
template <int D>
void give_impulses(Contacts<D>& contacts);
// The same for the manifolds list[0..n) alone (a manifold listed twice is harmless); a
// list of more than one in HANDOVER_WHOLE of the manifolds is given as all of them (the
// take that follows then does nothing: the next pass takes them all).
template <int D>
void take_impulses(Contacts<D>& contacts, const std::int32_t* list, std::int64_t n);
template <int D>
void give_impulses(Contacts<D>& contacts, const std::int32_t* list, std::int64_t n);

// solver/shock.cpp: the manifolds within `reach` contacts of a deep overlap between
// bodies that have moved this step, written to contacts.relax_list; returns their count.
template <int D>
std::int64_t deep_region(const Model<D>& model, Contacts<D>& contacts, int reach);
// Lanes of one of the waves' batches (2D): contacts.batches[batch], lane l where bit l of
// `lanes` is set; `two`: a batch of two-point manifolds.
struct BatchLanes {
  std::int32_t batch;
  std::uint8_t lanes;
  bool two;
};
// solver/shock.cpp, 2D: the same manifolds as lanes of the waves' batches, in the batches'
// order, only those closing faster than min_approach (m/s) when it is > 0 (keep_closing),
// into `out` (room for every batch); returns how many batches.
std::int64_t deep_region_lanes(const Model<2>& model, const State<2>& state,
                               Contacts<2>& contacts, int reach, double min_approach,
                               BatchLanes* out);

// solver/shock.cpp: whether a deep overlap the solve pass met (contacts.relax_list[:
// count.deep_count]) has a point closing faster than min_approach (m/s).
template <int D>
bool deep_approaching(const State<D>& state, const Contacts<D>& contacts, double min_approach);
// solver/shock.cpp: the manifolds of list[0..n) with a point closing faster than
// min_approach (m/s) at the bodies' velocities now, moved to the list's front in their
// order; returns their count.
template <int D>
std::int64_t keep_closing(const State<D>& state, const Contacts<D>& contacts, std::int32_t* list,
                          std::int64_t n, double min_approach);

// solver/shock.cpp: one pass from the ground up, the supporting body held still; a point
// approaching slower than min_approach (m/s) is left alone.
template <int D>
void propagate_shock(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                     std::int64_t n_order, double inv_h, double threshold,
                     double min_approach = constants::SHOCK_MIN_APPROACH);

// dynamics/integrate.cpp: v += h (g + F/m), angular from torque, then damping.
template <int D>
void integrate_velocities(const Model<D>& model, State<D>& state, double h);
template <int D>
void integrate_velocities(const Model<D>& model, State<D>& state, double h, Span bodies);

// dynamics/integrate.cpp: x += h v, q turned by ω h (exact) or the notes' update;
// delta accumulates each body's motion since the step's start.
// 3D: inv_inertia_world (N,), when given, is kept at each turned body's new rotation (its
// inverse inertia tensor in world axes, contacts.body_inv_inertia_world), and a dynamic
// body's ω is found from L through it; without it, as apply_inv_inertia.
template <int D>
void integrate_positions(const Model<D>& model, State<D>& state,
                         std::vector<BodyDelta<D>>& delta, double h, Rotation rotation);
template <int D>
void integrate_positions(const Model<D>& model, State<D>& state,
                         std::vector<BodyDelta<D>>& delta, double h, Rotation rotation,
                         Span bodies, typename Dim<D>::Inertia* inv_inertia_world = nullptr);

// collide/transform.cpp (3D): contacts.body_inv_inertia_world of the bodies `bodies` at
// their rotations now (transform_shapes makes it for every body at the step's start).
void world_inertia(const Model<3>& model, const State<3>& state, Contacts<3>& contacts,
                   Span bodies);

// solver/warm_start.cpp: last substep's accumulated impulses applied again.
template <int D>
void warm_start(const Model<D>& model, State<D>& state, Contacts<D>& contacts);

// solver/warm_start.cpp: the same, wave by wave, LANES manifolds at a time (the step's
// warm_start_range over every wave); the impulses in the store before and after.
template <int D>
void warm_start_waves(const Model<D>& model, State<D>& state, Contacts<D>& contacts);

// What a solver pass lists as it meets it (solve.cpp): manifolds with a point that engaged
// faster than the restitution threshold (for bounce_list, *bounce_count entries) and
// manifolds with a deep overlap (for relax_list, *deep_count entries, at most
// deep_capacity). direct() writes into the contact store's own lists; a region of a
// threaded pass writes into its own (step.cpp appends them in region order).
struct PassLog {
  std::int32_t* bounce = nullptr;
  std::int64_t* bounce_count = nullptr;
  std::int32_t* deep = nullptr;
  std::int64_t* deep_count = nullptr;
  std::int64_t deep_capacity = 0;
  std::int64_t bounce_capacity = 0;
  // (the bounce list is sized for every point engaging once, contacts.hpp: the bound is
  // a guard against writing past it, never reached)
  void add_bounce(std::int32_t m) {
    if (*bounce_count < bounce_capacity) bounce[(*bounce_count)++] = m;
  }
  void add_deep(std::int32_t m) {
    if (*deep_count < deep_capacity) deep[(*deep_count)++] = m;
  }
  template <int D>
  static PassLog direct(Contacts<D>& c) {
    return {c.bounce_list.data(), &c.count.bounce_count, c.relax_list.data(),
            &c.count.deep_count, static_cast<std::int64_t>(c.relax_list.size()),
            static_cast<std::int64_t>(c.bounce_list.size())};
  }
};

// solver/solve.cpp: one pass of sequential impulses over order[0..n): with the soft
// bias (use_bias, the solve stage) or without (the relax stage). inv_h: 1/substep (1/s);
// shift: h in the relax stage of symplectic Euler (s); threshold (m/s).
template <int D>
void solve_contacts(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                    double inv_h, bool use_bias, double shift, double threshold,
                    const std::int32_t* order, std::int64_t n);

// solver/solve.cpp: the same, listing into `log` instead of the store's lists.
template <int D>
void solve_contacts(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                    double inv_h, bool use_bias, double shift, double threshold,
                    const std::int32_t* order, std::int64_t n, PassLog& log);

// solver/solve.cpp, 2D: a pass over the lanes of batches[0..n) (deep_region_lanes), in
// that order: a pass over their manifolds in solve order, four at a time. The batches
// hold the impulses (take_impulses).
void solve_batch_lanes(State<2>& state, Contacts<2>& contacts, double inv_h, bool use_bias,
                       double shift, double threshold, const BatchLanes* batches, std::int64_t n,
                       PassLog& log);

// 2D: which lanes of a range's batches a pass takes (WideBatch::cut): all (one thread),
// all but a cut's (a region's task on threads) or only a cut's (the cut's pass after the
// regions, over the batches of its host region: waves.cpp, schedule_units).
enum class CutLanes : std::uint8_t { All, Without, Only };
// The lanes (bit l: lane l) a pass takes of a batch whose cut's lanes are `cut`: 0 for
// none (the batch is passed over), ALL_LANES for the whole batch.
inline unsigned cut_lanes_taken(CutLanes lanes, unsigned cut) {
  if (lanes == CutLanes::All) return ALL_LANES;
  return lanes == CutLanes::Only ? cut : ALL_LANES & ~cut;
}

// solver/solve.cpp: the pass over waves [first, last) (contacts.batches; 3D: batches3, faces3), listing
// into `log`: a region of the solve order (regions.cpp, contacts.segment_wave), `lanes` of
// its batches. In 2D the batches hold the impulses: the caller takes them first
// (take_impulses).
template <int D>
void solve_wave_range(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                      double inv_h, bool use_bias, double shift, double threshold,
                      std::int64_t first, std::int64_t last, PassLog& log,
                      CutLanes lanes = CutLanes::All);

// solver/solve.cpp: the same pass over the whole solve order, wave by wave (find_waves'
// batches, LANES manifolds at a time); the impulses in the store before and after.
template <int D>
void solve_waves(const Model<D>& model, State<D>& state, Contacts<D>& contacts, double inv_h,
                   bool use_bias, double shift, double threshold);

// solver/warm_start.cpp: the warm start of waves [first, last) (2D: the batches' impulses,
// taken first by the caller, in `lanes` of the batches), or, in 3D, of
// solve_order[first, last): a region of the solve order (regions.cpp).
template <int D>
void warm_start_range(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                      std::int64_t first, std::int64_t last, CutLanes lanes = CutLanes::All);

// solver/shock.cpp: the shock pass over shock_order[first, last) (a region's part).
template <int D>
void propagate_shock_range(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                           std::int64_t first, std::int64_t last, double inv_h,
                           double threshold,
                           double min_approach = constants::SHOCK_MIN_APPROACH);

// solver/regions.cpp: the regions of the solver's passes. When the contact graph changed
// (count.graph_unchanged == 0) the dynamic bodies are split into regions
// (contacts.body_region: strips across gravity of equal body count, SOLVER_REGIONS of
// them in a scene of SOLVER_REGIONS * REGION_MIN_BODIES dynamic bodies or more, else
// one) and solve_order is regrouped, stably, into segments (contacts.segment_order):
// each region's manifolds, then the manifolds that join two neighbouring regions, cut by
// cut, then the rest. Every step shock_order is regrouped the same way
// (contacts.segment_shock). The segments depend on the state only, never on the number
// of threads.
template <int D>
void partition_regions(const Model<D>& model, const State<D>& state, Contacts<D>& contacts);

// The segments of a partition into `regions` regions: the regions, the cuts between
// regions 2k and 2k + 1, and one for every other joining manifold.
inline constexpr int segment_count(int regions) { return regions + regions / 2 + 1; }
// The region whose batches may hold segment g's manifolds in lanes of their own (2D:
// waves.cpp, schedule_units): 2k + 1 for the cut between regions 2k and 2k + 1, -1 for a
// region or the segment of the other joining manifolds.
inline constexpr int cut_host(int regions, int g) {
  return regions > 1 && g >= regions && g < regions + regions / 2 ? 2 * (g - regions) + 1 : -1;
}

// solver/restitution.cpp: keep each point's impulse at the position update (scenes with
// elastic materials), and the restitution stage itself.
template <int D>
void keep_solve_impulses(Contacts<D>& contacts);
template <int D>
void apply_restitution(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                       double threshold, double h, double sign);
// solver/restitution.cpp: a step's start for the stage (nothing listed, no manifold's kind
// left from the last step's calls); and what its next call reads and writes of the
// manifolds' impulses: 0 nothing (nothing listed since the last), 1 the listed manifolds'
// alone (contacts.bounce_list[0..count.bounce_count)), 2 any manifold's (an elastic one,
// or an inelastic impact of a body on two pieces of one static or kinematic surface, is
// listed this step: clusters are found over the whole contact graph).
template <int D>
void start_restitution(Contacts<D>& contacts);
template <int D>
int restitution_reach(const Model<D>& model, const Contacts<D>& contacts);

// solver/overlap_limit.cpp: a body deeper than max_overlap (m; times the contact's scale,
// SCALE_LENGTH) in a static or kinematic body is moved out directly.
template <int D>
void limit_static_overlap(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                          double max_overlap);
// The same between two dynamic bodies: each is moved by its share of the inverse mass,
// in up to `passes` passes over the pairs that may be deeper than max_overlap (their
// deepest point at the step's start, contacts.start_separation, less what the bodies'
// motion since can have closed; their list in contacts.overlap_list). Returns the number
// of moves.
template <int D>
std::int64_t limit_dynamic_overlap(const Model<D>& model, State<D>& state,
                                   Contacts<D>& contacts, double max_overlap, int passes);


// collide/continuous.cpp: the continuous sweep of a body whose motion in the step went past
// its contacts' reach, against the static shapes. What it needs of the model, found once
// (find_continuous_index): the static shapes, each body's shapes, and each body's inner size
// and reach (m).
struct ContinuousIndex {
  std::vector<std::int32_t> static_shapes;  // the shapes of static bodies, in order
  std::vector<std::int32_t> shape_start;    // (N + 1,) where body i's shapes start in shapes
  std::vector<std::int32_t> shapes;
  std::vector<double> inner;  // (N,) m: the least distance from a shape's centre to its surface
  std::vector<double> reach;  // (N,) m: the farthest point of its shapes from its centre of mass
};
template <int D>
ContinuousIndex find_continuous_index(const Model<D>& model);
// Each dynamic body that moved further in the step than its contacts reached at its
// start (v0, w0: the velocities then) is swept from its pose then (state now less
// contacts.body_delta) to its pose now against the static shapes whose boxes
// (grid.shape_aabb) meet its path, and put back at the first impact it then went on past
// (constants.hpp, CONTINUOUS_FRACTION); body_delta follows. A body put back where it
// started the step (within the slop) has its approach there reversed by the pair's
// restitution (restitution_rule; none where slower than threshold, m/s). Returns how many
// were put back.
template <int D>
std::int64_t sweep_fast_bodies(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                               const Grid<D>& grid, const ContinuousIndex& index,
                               const std::vector<typename Dim<D>::Vec>& v0,
                               const std::vector<typename Dim<D>::Ang>& w0, double dt,
                               MixRule restitution_rule, double threshold);

}  // namespace rbsim
