// A scene ready to step: model, state, the stages' storage and the run's settings.
#pragma once

#include <cstdint>
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "contacts.hpp"
#include "grid.hpp"
#include "model.hpp"
#include "pool.hpp"
#include "stages.hpp"
#include "state.hpp"

namespace rbsim {

// Farthest a body's centre of mass may go from the origin, m, per axis. Scenes start
// within 1e6 m (rbsim.scene.schema.LENGTH_MAX); a body that flies beyond 1e9 m, where a
// double resolves only 1.2e-7 m, has left the simulation: advance reports it as it does
// a non-finite state, before the broadphase's integer cell indices could overflow.
inline constexpr double POSITION_LIMIT = 1.0e9;

// The most threads a world steps on (config.threads; rbsim.scene.schema's bound on
// solver.threads): far beyond the regions' parallelism (SOLVER_REGIONS), it only bounds
// what a scene can ask for.
inline constexpr int THREADS_MAX = 64;

// The stages as the step calls them, for the time spent in each (World::profile).
enum class StageId : int {
  Transform, FindPairs, UpdateManifolds, Prepare, SupportOrder, Waves, IntegrateVelocities,
  WarmStart, Solve, IntegratePositions, Relax, ExtraRelax, Restitution, Shock, OverlapLimit,
  Store, Regions, DeepSolve, Continuous, Count
};
inline constexpr const char* STAGE_NAMES[] = {
    "transform", "find_pairs", "update_manifolds", "prepare", "support_order", "waves",
    "integrate_velocities", "warm_start", "solve", "integrate_positions", "relax",
    "extra_relax", "restitution", "shock", "limit_static_overlap", "store_impulses",
    "regions", "deep_solve", "continuous"};

// What one segment of a threaded pass lists (a PassLog's own storage; step.cpp appends it
// to the contact store's lists in segment order).
struct SegmentLog {
  std::vector<std::int32_t> bounce, deep;
  std::int64_t bounce_count = 0, deep_count = 0;
  PassLog log() {
    return {bounce.data(), &bounce_count, deep.data(), &deep_count,
            static_cast<std::int64_t>(deep.size()), static_cast<std::int64_t>(bounce.size())};
  }
};

template <int D>
struct World {
  Model<D> model;
  State<D> state;
  Config config;
  Grid<D> grid;
  Contacts<D> contacts;
  std::int64_t step_index = 0;
  // the contact pairs the step that advance refused with TooManyPairs would have held
  std::int64_t pairs_wanted = 0;
  // the manifolds of the step that found the store's room for them too small (0: none)
  std::int64_t manifolds_wanted = 0;
  // with profile set, each stage's wall time accumulates in stage_seconds (s)
  bool profile = false;
  std::array<double, static_cast<int>(StageId::Count)> stage_seconds{};
  // with profile set, the wall time (s) of the work that runs in parts on the threads
  // (each part on one thread): what more threads can shorten, the rest being serial
  double parallel_seconds = 0.0;
  // with profile set: the solver's region tasks (over_segments, a scene of more than one
  // region), their summed wall time (s) and the passes that ran them, [0] one after the
  // other on one thread, [1] side by side on the threads: how much longer a region's task
  // takes beside another than alone (bench/threads.py)
  std::array<double, 2> region_task_seconds{};
  std::array<std::int64_t, 2> region_task_passes{};
  // 2D on the threads with the solver's regions (begin_regions, at each step's start):
  // each region's dynamic bodies as runs of indices, the static and kinematic bodies'
  // runs, and each region's copy of the velocities for its passes (over_segments)
  std::vector<std::vector<Span>> region_runs;
  std::vector<Span> shared_runs;
  std::vector<State<D>> region_state;
  // the threads of config.threads beyond the caller (made at the first step that has a
  // use for them), and the segment logs of the threaded passes
  std::unique_ptr<Pool> pool;
  std::vector<SegmentLog> logs;
  // config.choose_threads: which of one thread and config.threads each step of advance
  // runs on (made at advance's first step)
  std::optional<ThreadChoice> thread_choice;
  // the pairs' narrowphase (narrow_pairs) and their manifolds' slots (manifold_slots), for
  // the manifold stage in parts (step.cpp)
  std::vector<PairManifold<D>> found;
  std::vector<std::int8_t> found_points;
  std::vector<std::int64_t> found_slot;
  // the continuous sweep's (collide/continuous.cpp): what it needs of the model (made by
  // allocate), and the bodies' velocities at the step's start (when a static shape exists)
  ContinuousIndex continuous_index;
  std::vector<typename Dim<D>::Vec> continuous_v;
  std::vector<typename Dim<D>::Ang> continuous_w;
  // the manifolds the restitution stage is to look at (its list, which it rewrites), whose
  // impulses the batches give it and take back (step.cpp)
  std::vector<std::int32_t> listed;
  // the deep overlaps a solve pass met (contacts.relax_list's first count.deep_count),
  // kept while the regions around them are solved again (step.cpp, deep_solve)
  std::vector<std::int32_t> deep_seeds;
  // 2D: the lanes of the waves' batches those regions hold (deep_region_lanes)
  std::vector<BatchLanes> deep_lanes;
  // Asked by advance after it grew the contact store, and inside a step that may be long
  // (step_may_be_long: after its contacts are found and between its substeps): true ends
  // advance with Status::Interrupted. Set by the caller for the length of its advance
  // calls (the binding: Python's signal handlers); empty: nothing is asked.
  std::function<bool()> interrupt;
  // A step was stopped inside: the state is partway through step step_index + 1, and
  // advance refuses to go on from it (Status::Torn); a checkpoint loaded ends it.
  bool torn = false;
  // wall time (s) of the last step taken, -1 before any
  double last_step_seconds = -1.0;

  // Storage for the model's bodies and shapes (call once the model and state are set).
  void allocate();
  // One time step config.dt. Returns false when the contact store is too small (the
  // state is then unchanged: grow and call again).
  bool step();
  // Up to n_steps steps, growing the contact store as needed. Returns Ok, Interrupted
  // (interrupt), Torn (a torn world: no step), or NonFinite
  // with *bad_body set to a body whose state is not finite or beyond POSITION_LIMIT
  // (the first dynamic one; a static or kinematic one only when no dynamic one is),
  // or TooManyPairs when a step would hold more than pair_limit() contact pairs (that
  // step is not taken; pairs_wanted holds how many it found):
  // *taken = steps taken (0 when the state was already bad: no step is taken from it).
  Status advance(std::int64_t n_steps, std::int64_t* taken, std::int64_t* bad_body);
  // The most contact pairs a step may hold (constants.hpp, PAIRS_PER_SHAPE).
  std::int64_t pair_limit() const;
  // Room for `capacity` manifolds and pairs, keeping what warm starting needs. With
  // `stoppable`, interrupt is asked while the store is made: true leaves the world as it
  // was and returns false.
  bool grow(std::int64_t capacity, bool stoppable = false);
  // Room for at least `manifolds` manifolds and `pairs` pairs: the manifold store is made
  // anew only where it has less room (grow), the pairs' room alone costs little (a rain
  // of balls finds four pairs for every manifold as it lands: the store made for them
  // took 3 - 6 ms a time). stoppable as grow's.
  bool grow_store(std::int64_t manifolds, std::int64_t pairs, bool stoppable = false);
  // Whether the next step may take STEP_STOP_SECONDS or more (constants.hpp).
  bool step_may_be_long() const;
  // The threads the steps run on: config.threads, or with choose_threads the last trial's
  // choice (1 before the first).
  int threads_chosen() const {
    if (!config.choose_threads || config.threads == 1) return config.threads;
    return thread_choice ? thread_choice->chosen() : 1;
  }
  // Contact points that pushed in the last step.
  std::int64_t contact_count() const { return model.has_shapes ? contacts.count.points_touching : 0; }

 private:
  bool stoppable_ = false;  // the step under way may be stopped inside
  int step_threads_ = 0;    // threads of the step under way (0: config.threads)
  // the threads the stages may use: step_threads_ (or config.threads), where a pool is
  int active_threads() const {
    return pool ? (step_threads_ > 0 ? step_threads_ : pool->size()) : 1;
  }
  // interrupt() asked, when the step under way may be stopped; true sets torn
  bool stop_here();
  bool collide();
  // found, found_points and found_slot for the contact store's capacity
  void size_pair_buffers();
  bool step_free();
  template <class F>
  void timed(StageId stage, F&& run);
  // run(), its wall time added to parallel_seconds when profiling
  template <class F>
  void parallel_timed(F&& run);
  // f(Span) over near-equal parts of n items, on the pool's threads (each part writes
  // only its own items)
  template <class F>
  void parallel(std::int64_t n, F&& f);
  // f(segment, log, state, lanes) over the solve's segments (regions.cpp): the regions at
  // once, then the cuts between regions 2k and 2k + 1 at once, then the rest; what the
  // passes list is appended to the store's lists in segment order (with_logs). `state` is
  // the world's, or in 2D, for a region on the threads, that region's copy of the
  // velocities (region_state: only body_v and body_w, which the passes read and write).
  // lanes (2D, contacts.cut_lanes): on one thread every segment's batches whole
  // (CutLanes::All); on the threads a region without the lanes of a cut that it hosts
  // (Without), and each cut's part first as its host region's batches, those lanes only
  // (f(host, log, state, Only)), then its own segment
  template <class F>
  void over_segments(bool with_logs, F&& f);
  void begin_regions();  // region_runs, shared_runs, region_state (2D, threaded regions)
  void warm_start_pass();
  void solve_pass(double inv_h, bool use_bias, double shift, double threshold);
  // the shock pass over the regions' shock orders; approaches slower than min_approach
  // (m/s) are left alone
  void shock_pass(double inv_h, double threshold,
                  double min_approach = constants::SHOCK_MIN_APPROACH);
  // the contacts around the deep overlaps the solve pass met, solved once more with the
  // soft bias, one manifold at a time, in solve order (nothing listed: the solve pass has);
  // first, while one still closes at DEEP_CLOSING_SPEED, the contacts around those without
  // the bias (at most DEEP_SOLVE_PASSES - 1 passes)
  void deep_solve(double inv_h, double threshold);
  // the contacts within DEEP_RELAX_REACH of the deep overlaps in
  // contacts.relax_list[:count.deep_count], only those closing faster than min_approach
  // (m/s) when it is > 0: 2D their lanes of the waves' batches into deep_lanes
  // (deep_region_lanes; the impulses taken into the batches), returning how many batches;
  // 3D the manifolds into contacts.relax_list in solve order, returning how many
  std::int64_t find_near_deep(double min_approach);
  // one pass over the n found (find_near_deep), in solve order (2D: four at a time in
  // their batches; 3D: one manifold at a time), listing into `log`
  void pass_near_deep(std::int64_t n, double inv_h, bool use_bias, double shift,
                      double threshold, PassLog& log);
};

// Half the diagonal (m) of each shape's own bounding box, radius included.
template <int D>
std::vector<double> shape_extent(const Model<D>& model);

// How far in each shape's surface lies from its middle where the shape is thinnest, m:
// its radius, and a polygon's or convex shape's least distance from its vertices' mean to
// a face (a circle's, a capsule's: its radius; a plane's: infinite).
template <int D>
std::vector<double> shape_depth(const Model<D>& model);

}  // namespace rbsim
