// The time step as the list of its stages, and the loop that runs a scene. This is the
// only file that orders stages:
//
//   transform -> find_pairs -> update_manifolds -> prepare -> support_order -> regions
//   -> waves
//   -> [per substep: integrate_velocities -> warm_start -> solve (-> shock, while a heavy
//       body rests on a light one) (-> deep_solve, while a deep overlap still closes)
//       -> integrate_positions (-> 3D: refresh_turned_rows, for a body turned far)
//       -> relax (-> extra relax passes near a deep overlap) -> restitution -> shock
//       (-> the points' step impulses, for a run that records its contact points)]
//   -> limit_dynamic_overlap -> limit_static_overlap
//   -> continuous (a body that went further than its contacts reached, swept against the
//      static shapes)
//   (-> hand_down_shock_impulses, for a run that records its contact points)
//   -> store_impulses
//
// A scene without contacts possible skips the contact stages; one without forces skips
// their evaluation (integrate.cpp).
//
// Threads (config.threads, solver.threads): the stages whose items are independent
// (transform per body and shape, prepare per manifold, the integrator per body) run in
// parts on the pool's threads; the solver's passes (warm start, solve, relax, shock) run
// region by region (regions.cpp), the regions at once. Every part writes only its own
// items and what the passes list is gathered in a fixed order, so the state after a step
// is the same, bit for bit, for every number of threads.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "rbsim/constants.hpp"
#include "rbsim/wide.hpp"
#include "rbsim/world.hpp"

namespace rbsim {

namespace C = constants;

// Contacts between bodies exist in both dimensions (3D: issue 16). The step list is the
// same; the stages differ inside where the dimensions do (waves.cpp: 3D packs its one-point
// manifolds and its faces of two and three points in lanes, and leaves the others one by
// one).
template <int D>
inline constexpr bool HAS_CONTACTS = D == 2 || D == 3;

template <int D>
void World<D>::allocate() {
  const int n_shapes = model.shape_count();
  const std::int64_t capacity = 4 * static_cast<std::int64_t>(n_shapes) + 16;
  // the collision stages' storage
  std::vector<std::uint8_t> dynamic(n_shapes);
  for (int s = 0; s < n_shapes; ++s) dynamic[s] = model.is_dynamic(model.shape_body[s]);
  const std::vector<double> size = shape_extent(model);  // m: each shape's half diagonal
  model.shape_reach.assign(n_shapes, 0.0);
  for (int s = 0; s < n_shapes; ++s) {
    double reach2 = 0.0;  // m²
    for (int k = model.shape_vstart[s]; k < model.shape_vstart[s] + model.shape_vcount[s]; ++k)
      reach2 = std::max(reach2, length_squared(model.vertex_local[k]));
    model.shape_reach[s] = std::sqrt(reach2);  // (as the largest length: sqrt is monotone)
  }
  model.shape_depth = shape_depth(model);
  if constexpr (D == 2) find_segment_neighbours(model, state);
  continuous_index = find_continuous_index(model);
  grid.allocate(size, dynamic, capacity);
  contacts.allocate(model.body_count(), n_shapes, model.vertex_count(), capacity);
  size_pair_buffers();
  if constexpr (D == 3) {
    contacts.face_world.assign(model.hull_face_count, Vec3{});
    contacts.face_offset.assign(model.hull_face_count, 0.0);
    contacts.shape_spread.assign(n_shapes, HullSpread{});
    contacts.turn_watch = turn_watch(model);
  }
  // the contact tolerances' scale of every shape and body (constants.hpp, SCALE_LENGTH)
  contacts.unit_scale = true;
  for (int s = 0; s < static_cast<int>(size.size()); ++s) {
    contacts.shape_size[s] = size[s];
    contacts.shape_scale[s] = std::min(1.0, size[s] / C::SCALE_LENGTH);
    double& body = contacts.body_scale[model.shape_body[s]];
    body = std::min(body, contacts.shape_scale[s]);
    contacts.unit_scale = contacts.unit_scale && contacts.shape_scale[s] == 1.0;
  }
  find_covered_faces(model, state, contacts.shape_scale);
}

template <int D>
void World<D>::size_pair_buffers() {
  const std::int64_t capacity = contacts.pair_capacity();
  found.resize(capacity);  // (a pair's narrowphase result each)
  found_points.resize(capacity);
  found_slot.resize(capacity + 1);
}

template <int D>
bool World<D>::grow(std::int64_t capacity, bool stoppable) {
  if (!contacts.grow(capacity, stoppable && interrupt ? &interrupt : nullptr)) return false;
  return grow_store(0, capacity);  // (the pairs' room, and the buffers by pair)
}

template <int D>
bool World<D>::grow_store(std::int64_t manifolds, std::int64_t pairs, bool stoppable) {
  if (manifolds > contacts.capacity() &&
      !contacts.grow(manifolds, stoppable && interrupt ? &interrupt : nullptr))
    return false;
  contacts.grow_pairs(pairs);  // (the pair list found anew: after a grow too)
  grid.grow(contacts.pair_capacity());
  size_pair_buffers();
  return true;
}

namespace {

// run(), its wall time added to total (s) when profiling.
template <class F>
void clocked(bool profile, double& total, F&& run) {
  if (!profile) {
    run();
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  run();
  const std::chrono::duration<double> dt = std::chrono::steady_clock::now() - t0;
  total += dt.count();
}

// The velocities (body_v, body_w) of the bodies in `bodies` from one state to another
// (the regions' copies: over_segments, begin_regions).
template <int D>
void copy_velocities(const State<D>& from, State<D>& to, Span bodies) {
  std::copy(from.body_v.begin() + bodies.first, from.body_v.begin() + bodies.last,
            to.body_v.begin() + bodies.first);
  std::copy(from.body_w.begin() + bodies.first, from.body_w.begin() + bodies.last,
            to.body_w.begin() + bodies.first);
}

}  // namespace

template <int D>
template <class F>
void World<D>::timed(StageId stage, F&& run) {
  clocked(profile, stage_seconds[static_cast<int>(stage)], run);
}

template <int D>
template <class F>
void World<D>::parallel_timed(F&& run) {
  clocked(profile, parallel_seconds, run);
}

template <int D>
template <class F>
void World<D>::parallel(std::int64_t n, F&& f) {
  const std::int64_t threads = active_threads();
  const std::int64_t parts = std::min<std::int64_t>(n / C::TASK_ITEMS, 4 * threads);
  if (n < 2 * C::TASK_ITEMS) {  // too few items to split
    f(Span{0, n});
    return;
  }
  parallel_timed([&] {
    if (parts < 2 || threads < 2)
      f(Span{0, n});
    else
      pool->run(parts, [&](std::int64_t p) { f(part_of(n, p, parts)); });
  });
}

template <int D>
template <class F>
void World<D>::over_segments(bool with_logs, F&& f) {
  auto& c = contacts;
  const int regions = static_cast<int>(c.region_count);
  const int n_segments = segment_count(regions);
  if (regions == 1 || active_threads() < 2) {
    // one thread: the segments in order, listing straight into the store's lists (what
    // the threads' logs, appended in segment order, also give)
    PassLog log = PassLog::direct(c);
    int g = 0;
    if (regions > 1) {  // (the part that threads would share, for the profile)
      parallel_timed([&] {
        for (; g < regions; ++g)
          clocked(profile, region_task_seconds[0], [&] { f(g, log, state, CutLanes::All); });
        region_task_passes[0] += profile;
        if (regions / 2 > 1)
          for (; g < regions + regions / 2; ++g) f(g, log, state, CutLanes::All);
      });
    }
    for (; g < n_segments; ++g) f(g, log, state, CutLanes::All);
    return;
  }
  if (with_logs) {
    const std::size_t bounce = c.bounce_list.size(), deep = c.relax_list.size();
    logs.resize(n_segments);
    for (auto& l : logs) {
      if (l.bounce.size() != bounce) l.bounce.assign(bounce, 0);
      if (l.deep.size() != deep) l.deep.assign(deep, 0);
      l.bounce_count = l.deep_count = 0;
    }
  }
  PassLog none{};  // (a pass that lists nothing)
  // segment g's part: `lanes` of the batches of segment `batches` (its own, or for a
  // cut's lanes in its host region's batches, the host's), listing into g's log
  auto run_on = [&](std::int64_t g, State<D>& st, std::int64_t batches, CutLanes lanes) {
    if (!with_logs) {
      f(static_cast<int>(batches), none, st, lanes);
      return;
    }
    PassLog log = logs[g].log();
    f(static_cast<int>(batches), log, st, lanes);
  };
  // a cut between regions 2k and 2k + 1: its lanes in region 2k + 1's batches first
  const bool cut_lanes = D == 2 && c.cut_lanes;
  auto run = [&](std::int64_t g) {
    const int host = cut_lanes ? cut_host(regions, static_cast<int>(g)) : -1;
    if (host >= 0) run_on(g, state, host, CutLanes::Only);
    run_on(g, state, g, CutLanes::All);
  };
  // 2D: a region's pass on its own copy of the velocities (region_state, begin_regions),
  // its bodies copied in and back: bodies numbered near one another fall in both regions
  // (a pyramid's rows cut in two), and one cache line of velocities written from both
  // threads made the region tasks of a base-40 pyramid take 1.7-2.0 times as long side by
  // side as alone (1.2-1.5 with the copies and the integrator by region)
  auto run_region = [&](std::int64_t g) {
    if constexpr (D == 2) {
      State<D>& own = region_state[g];
      for (const Span run : region_runs[g]) copy_velocities(state, own, run);
      run_on(g, own, g, cut_lanes ? CutLanes::Without : CutLanes::All);
      for (const Span run : region_runs[g]) copy_velocities(own, state, run);
    } else {
      run_on(g, state, g, CutLanes::All);
    }
  };
  // (each task's clock its own, summed once they are done)
  std::array<double, constants::SOLVER_REGIONS> task_seconds{};
  parallel_timed([&] {
    pool->run(regions, [&](std::int64_t g) {
      clocked(profile, task_seconds[g], [&] { run_region(g); });
    });
  });
  if (profile) {
    for (const double t : task_seconds) region_task_seconds[1] += t;
    region_task_passes[1] += 1;
  }
  if (regions / 2 > 1)
    parallel_timed([&] { pool->run(regions / 2, [&](std::int64_t k) { run(regions + k); }); });
  else
    run(regions);
  for (int g = regions + regions / 2; g < n_segments; ++g) run(g);
  if (!with_logs) return;
  PassLog store = PassLog::direct(c);
  for (auto& l : logs) {
    for (std::int64_t i = 0; i < l.bounce_count; ++i) store.add_bounce(l.bounce[i]);
    for (std::int64_t i = 0; i < l.deep_count; ++i) store.add_deep(l.deep[i]);
  }
}

template <int D>
void World<D>::warm_start_pass() {
  auto& c = contacts;
  take_impulses(c);  // (2D: the passes read and write them in the batches until given back)
  if (c.region_count == 1) {
    if constexpr (D == 2)
      warm_start_range(model, state, c, 0, c.wave_count);
    else
      warm_start_waves(model, state, c);
    return;
  }
  const auto& bounds = D == 2 ? c.segment_wave : c.segment_order;
  over_segments(false, [&](int g, PassLog&, State<D>& st, CutLanes lanes) {
    warm_start_range(model, st, c, bounds[g], bounds[g + 1], lanes);
  });
}

template <int D>
void World<D>::solve_pass(double inv_h, bool use_bias, double shift, double threshold) {
  auto& c = contacts;
  take_impulses(c);
  over_segments(true, [&](int g, PassLog& log, State<D>& st, CutLanes lanes) {
    solve_wave_range(model, st, c, inv_h, use_bias, shift, threshold, c.segment_wave[g],
                     c.segment_wave[g + 1], log, lanes);
  });
}

template <int D>
void World<D>::shock_pass(double inv_h, double threshold, double min_approach) {
  auto& c = contacts;
  over_segments(false, [&](int g, PassLog&, State<D>& st, CutLanes lanes) {
    if (lanes == CutLanes::Only) return;  // (the shock order keeps a cut's in its segment)
    propagate_shock_range(model, st, c, c.segment_shock[g], c.segment_shock[g + 1], inv_h,
                          threshold, min_approach);
  });
}

template <int D>
std::int64_t World<D>::find_near_deep(double min_approach) {
  auto& c = contacts;
  if constexpr (D == 2) {
    deep_lanes.resize(static_cast<std::size_t>(c.wave_count > 0 ? c.wave_batch[c.wave_count] : 0));
    const std::int64_t n =
        deep_region_lanes(model, state, c, C::DEEP_RELAX_REACH, min_approach, deep_lanes.data());
    if (n > 0) take_impulses(c);  // (the batches hold them through the passes)
    return n;
  } else {
    const std::int64_t n = deep_region(model, c, C::DEEP_RELAX_REACH);
    return min_approach > 0.0 ? keep_closing(state, c, c.relax_list.data(), n, min_approach) : n;
  }
}

template <int D>
void World<D>::pass_near_deep(std::int64_t n, double inv_h, bool use_bias, double shift,
                              double threshold, PassLog& log) {
  auto& c = contacts;
  if constexpr (D == 2)
    solve_batch_lanes(state, c, inv_h, use_bias, shift, threshold, deep_lanes.data(), n, log);
  else
    solve_contacts(model, state, c, inv_h, use_bias, shift, threshold, c.relax_list.data(), n, log);
}

template <int D>
void World<D>::deep_solve(double inv_h, double threshold) {
  auto& c = contacts;
  // (the region's walk moves the seeds that have moved to the list's head, and in 3D
  // writes the region over it, which the relax stage's extra passes read again: kept, and
  // put back before each region is found)
  const std::int64_t n_deep = c.count.deep_count;
  deep_seeds.assign(c.relax_list.begin(), c.relax_list.begin() + n_deep);
  auto seeds = [&] { std::copy(deep_seeds.begin(), deep_seeds.end(), c.relax_list.begin()); };
  std::int64_t bounces = 0, deeps = 0;
  PassLog quiet{c.bounce_list.data(), &bounces, c.relax_list.data(), &deeps, 0, 0};
  // one pass over the contacts within DEEP_RELAX_REACH of the overlaps in
  // relax_list[:count.deep_count] (without the bias: only those still closing)
  auto pass_near = [&](bool use_bias) {
    const std::int64_t n = find_near_deep(use_bias ? 0.0 : C::SHOCK_MIN_APPROACH);
    pass_near_deep(n, inv_h, use_bias, 0.0, threshold, quiet);
  };
  // the overlaps still driven in (DEEP_CLOSING_SPEED): the approach of the closing
  // contacts around them taken out first, without the bias, which would push out more at
  // each pass (with biased passes a column of balls over one 20 cm deep was thrown up at
  // 1.19 m/s, against 0.93), and never pulling back a push-out (an unbiased pass over a
  // contact parting would: the biased pass after it then starts short)
  for (int pass = 1; pass < C::DEEP_SOLVE_PASSES; ++pass) {
    seeds();
    c.count.deep_count = keep_closing(state, c, c.relax_list.data(), n_deep, C::DEEP_CLOSING_SPEED);
    if (c.count.deep_count == 0) break;
    pass_near(false);
  }
  seeds();
  c.count.deep_count = n_deep;
  pass_near(true);
  seeds();
}

template <int D>
bool World<D>::collide() {
  if constexpr (!HAS_CONTACTS<D>) {
    return true;
  } else {
  const Config& cfg = config;
  auto& c = contacts;
  using S = StageId;
  manifolds_wanted = 0;
  // the move of the frame (m) about which the boxes reach, and in which the broadphase
  // keeps them: the median move of the dynamic bodies in the last step
  const auto frame = frame_move(model, c);
  grid.frame_offset = grid.frame_origin + frame;
  // last step's manifolds into prev_*, where its store left them in the current arrays
  // (first: a step that grows the store keeps the prev_* arrays)
  timed(S::Store, [&] { take_prev(c); });
  timed(S::Transform, [&] {
    const std::int64_t n_bodies = model.body_count(), n_shapes = model.shape_count();
    parallel(std::max(n_bodies, n_shapes), [&](Span part) {
      const std::int64_t n = std::max(n_bodies, n_shapes);
      // the same fraction of the bodies and of the shapes
      auto scaled = [n](std::int64_t k, std::int64_t total) { return k * total / n; };
      transform_shapes(model, state, c, cfg.dt, frame,
                       Span{scaled(part.first, n_bodies), scaled(part.last, n_bodies)},
                       Span{scaled(part.first, n_shapes), scaled(part.last, n_shapes)});
    });
  });
  // (the stages that split their own work: the broadphase, the waves' batches)
  const InParts split = [this](std::int64_t n, const std::function<void(Span)>& f) {
    parallel(n, f);
  };
  std::int64_t n_pairs = 0;
  timed(S::FindPairs, [&] { n_pairs = find_pairs(model, grid, c, &split); });
  c.count.pairs = n_pairs;
  if (n_pairs > c.pair_capacity() || n_pairs > pair_limit()) return false;
  if (stop_here()) return true;  // torn: advance ends the call
  timed(S::UpdateManifolds, [&] {
    // the narrowphase pair by pair on the threads, each manifold's slot (a prefix count in
    // pair order), then the manifolds into their slots on the threads (on one thread the
    // same calls over all the pairs: every count takes the same path). (The buffers are
    // sized with the store, at allocate and grow; and here after a checkpoint's store was
    // loaded)
    if (static_cast<std::int64_t>(found_slot.size()) < n_pairs + 1) size_pair_buffers();
    parallel(n_pairs, [&](Span part) {
      narrow_pairs(model, state, c, grid, cfg.dt, part, found.data(), found_points.data());
    });
    manifold_slots(Span{0, n_pairs}, found_points.data(), found_slot.data());
    if (found_slot[n_pairs] > c.capacity()) {  // (no manifold written yet: grow, step again)
      manifolds_wanted = found_slot[n_pairs];
      return;
    }
    std::atomic<bool> same{true}, touch_changed{false};
    parallel(n_pairs, [&](Span part) {
      const MergeFlags f = merge_manifolds(model, state, c, part, cfg.friction_rule,
                                           cfg.restitution_rule, found.data(),
                                           found_points.data(), found_slot.data());
      if (!f.same) same = false;  // (flags: the same whatever the parts' order)
      if (f.touch_changed) touch_changed = true;
    });
    finish_manifolds(c, found_slot[n_pairs], MergeFlags{same.load(), touch_changed.load()});
  });
  if (manifolds_wanted > 0) return false;
  timed(S::Prepare, [&] {
    parallel(c.count.manifolds, [&](Span part) { prepare_contacts(model, state, c, cfg, part); });
  });
  if (stop_here()) return true;
  timed(S::SupportOrder, [&] {
    c.count.shock_count = support_order(model, c);
    friction_loads(model, state, c, c.count.shock_count, cfg.dt / cfg.substeps);
  });
  timed(S::Regions, [&] { partition_regions(model, state, c); });
  timed(S::Waves, [&] { find_waves(model, c, &split); });
  return true;
  }
}

template <int D>
void World<D>::begin_regions() {
  const auto& region = contacts.body_region;
  const int regions = static_cast<int>(contacts.region_count);
  region_runs.resize(regions);
  for (auto& runs : region_runs) runs.clear();
  shared_runs.clear();
  const std::int64_t n = model.body_count();
  for (std::int64_t i = 0; i < n;) {
    std::int64_t j = i + 1;
    while (j < n && region[j] == region[i]) ++j;
    (region[i] >= 0 ? region_runs[region[i]] : shared_runs).push_back(Span{i, j});
    i = j;
  }
  // each region's copy of the velocities: the static and kinematic bodies' now (the
  // step does not change them), its own bodies' at each of its passes (over_segments)
  region_state.resize(regions);
  for (auto& own : region_state) {
    own.body_v.resize(state.body_v.size());
    own.body_w.resize(state.body_w.size());
    for (const Span run : shared_runs) copy_velocities(state, own, run);
  }
}

template <int D>
bool World<D>::step() {
  if (config.threads > 1 && !pool) pool = std::make_unique<Pool>(config.threads);
  if constexpr (!HAS_CONTACTS<D>) {
    return step_free();
  } else {
  const Config& cfg = config;
  const bool contacts_on = model.has_shapes;
  if (contacts_on && !collide()) return false;
  if (torn || stop_here()) return false;
  auto& c = contacts;
  using S = StageId;
  // whether the passes have anything to solve: a step without a manifold (bodies in
  // flight) only moves them, through the same integrator calls
  const bool touching = contacts_on && c.count.manifolds > 0;
  for (auto& d : c.body_delta) d = BodyDelta<D>{};
  // the velocities the contacts were found at, for the sweep at the step's end
  const bool sweeping = contacts_on && !continuous_index.static_shapes.empty();
  if (sweeping) {
    continuous_v = state.body_v;
    continuous_w = state.body_w;
  }
  const double h = cfg.dt / cfg.substeps;
  const double inv_h = 1.0 / h;
  const double shift = cfg.explicit_euler ? 0.0 : h;
  const double sign = cfg.explicit_euler ? -1.0 : 1.0;
  const double threshold = cfg.restitution_threshold;
  // m/s²: |g|, for the shock passes' slowest approaches
  const double g_norm = std::sqrt(dot(model.gravity, model.gravity));
  // the restitution stage's list names this step's manifolds
  start_restitution(c);
  begin_step_impulses(c);
  const std::int64_t n_bodies = model.body_count();
  // 3D with contacts: each body's world inverse inertia kept with its rotation, for the
  // solver's passes (contacts.body_inv_inertia_world)
  auto* inertia_world = D == 3 && contacts_on ? c.body_inv_inertia_world.data() : nullptr;
  // 2D on the threads with the solver's regions: each region's bodies are moved on its
  // thread (the static and kinematic ones with the first region's), so that its passes
  // find them in their own core's cache (docs/design.md, "Threads")
  const bool by_region = D == 2 && contacts_on && c.region_count > 1 && active_threads() >= 2;
  if (by_region) begin_regions();
  auto over_bodies = [&](auto&& part_of_bodies) {
    if (by_region) {
      parallel_timed([&] {
        pool->run(c.region_count, [&](std::int64_t g) {
          for (const Span run : region_runs[g]) part_of_bodies(run);
          if (g == 0)
            for (const Span run : shared_runs) part_of_bodies(run);
        });
      });
    } else {
      parallel(n_bodies, part_of_bodies);
    }
  };
  if constexpr (D == 3) {
    if (contacts_on) begin_turn_watch(state, c);  // (the rows' tensors: the step's start's)
  }
  auto move = [&] {
    over_bodies([&](Span part) {
      integrate_positions(model, state, c.body_delta, h, cfg.rotation, part, inertia_world);
    });
    if constexpr (D == 3) {
      // a body that has turned far within the step: its contacts' rows made again at its
      // rotation now (refresh_turned_rows)
      if (contacts_on && c.count.manifolds > 0 && mark_turned_bodies(state, c)) {
        parallel(c.count.manifolds,
                 [&](Span part) { refresh_turned_rows(model, state, c, cfg, part); });
        repack_turned_rows(model, c);
      }
    }
  };
  auto accelerate = [&] {
    over_bodies([&](Span part) { integrate_velocities(model, state, h, part); });
  };
  for (int sub = 0; sub < cfg.substeps; ++sub) {
    if (cfg.explicit_euler) timed(S::IntegratePositions, move);
    timed(S::IntegrateVelocities, accelerate);
    if (touching) {
      timed(S::WarmStart, [&] { warm_start_pass(); });
      c.count.deep_count = 0;
      timed(S::Solve, [&] {
        for (int it = 0; it < cfg.iterations; ++it) solve_pass(inv_h, true, 0.0, threshold);
      });
    }
    if (touching && c.heavy_on_light) {
      // a heavy body on a light one: its approach is taken out before the positions move.
      // In 3D only an impact's: an approach no faster than a step of gravity gives is a
      // resting load, which the soft contacts carry (taken out here too, its impulse, kept
      // by no contact, starved their warm start: a 100 t box on 1 t ones jittered)
      const double impact = D == 3 ? g_norm * cfg.dt : C::SHOCK_MIN_APPROACH;  // m/s
      timed(S::Shock, [&] { shock_pass(inv_h, threshold, impact); });
    }
    if (touching && c.count.deep_count > 0 &&
        deep_approaching(state, c, C::SHOCK_MIN_APPROACH)) {
      // a deep overlap (DEEP_OVERLAP) comes out of the solve pass still closing: the pass
      // solves ground first, and a deep contact's push-out above drives the bodies below it
      // together after their own contacts were solved, which the positions would then move
      // deeper. In a pile of 600 boxes raining into a box the overlaps so walked down the
      // columns and grew to 5 - 14 cm, held there step after step. The contacts around the
      // deep ones are solved once more first (deep_solve): 3 to 5 cm on average once the
      // pile has landed (docs/design.md, "Overlaps that walk down a column"). One still
      // closing at impact speed (DEEP_CLOSING_SPEED) gets passes that take out its approach
      // first: a heavy ball driving a row of light boxes into each other squeezed two of
      // them 8.2 cm together, 3.8 cm with them. After the shock pass too: it takes a heavy
      // body's load, not its push sideways (the same ball at 20 m/s, resting on a box as it
      // flew over the pyramid, squeezed two of the second row 10 cm together, 3.5 with it).
      // (The shock pass, as for a heavy load, kept them under 3 cm, but handed a push-out
      // up the column above it, where no relax pass takes it back: a column of balls over
      // a ball 20 cm into the ground was thrown up at 1.7 m/s, against 0.8)
      timed(S::DeepSolve, [&] { deep_solve(inv_h, threshold); });
    }
    if (!cfg.explicit_euler) {
      if (touching && cfg.elastic) {
        give_impulses(c);
        keep_solve_impulses(c);
      }
      timed(S::IntegratePositions, move);
    }
    if (touching) {
      timed(S::Relax, [&] {
        for (int it = 0; it < cfg.iterations; ++it) solve_pass(inv_h, false, shift, threshold);
      });
      if (c.count.deep_count) {
        // a deep overlap is being pushed out: the contacts around it get more relax
        // passes, so that the push's velocity is taken back all the way up a stack
        // instead of adding up from row to row
        timed(S::ExtraRelax, [&] {
          PassLog log = PassLog::direct(c);
          // (the region found once: the passes do not move the bodies)
          const std::int64_t n = find_near_deep(0.0);
          for (int it = 0; n && it < cfg.iterations * (C::DEEP_RELAX_FACTOR - 1); ++it)
            pass_near_deep(n, inv_h, false, shift, threshold, log);
        });
      }
      // bounces first: the shock pass then leaves them alone, and would otherwise take a
      // ball struck down onto the floor as a load and stop it dead
      timed(S::Restitution, [&] {
        // it reads and writes the store's impulses: of the manifolds listed, or of all
        const int reach = restitution_reach(model, c);
        if (reach == 2) give_impulses(c);
        const std::int64_t n_listed = reach == 1 ? c.count.bounce_count : 0;
        listed.assign(c.bounce_list.begin(), c.bounce_list.begin() + n_listed);
        give_impulses(c, listed.data(), n_listed);
        apply_restitution(model, state, c, threshold, h, sign);
        take_impulses(c, listed.data(), n_listed);
      });
      // In 3D, unless a heavy body rests on a light one, an approach no faster than one
      // substep of gravity gives is left to the soft contacts as a resting load: after the
      // relax pass most resting points still approach by a little, and taking each out
      // cost a fifth of a settled heap's step, with the same stacks (make hard's 3D cases)
      const double load = D == 3 && !c.heavy_on_light ? g_norm * h : 0.0;  // m/s
      const double slowest = std::max(load, C::SHOCK_MIN_APPROACH);
      timed(S::Shock, [&] { shock_pass(inv_h, threshold, slowest); });
      // (a run that records its contact points: what each pushed in the substep)
      if (c.record_impulses) add_step_impulses(c);
    }
    if (sub + 1 < cfg.substeps && stop_here()) {
      give_impulses(c);
      return false;
    }
  }
  if constexpr (D == 3) {
    // the world tensors were made at these rotations (integrate_positions): the next
    // step's start need not make them again (world_inertia)
    if (contacts_on) c.body_inertia_q = state.body_q;
  }
  if (contacts_on) {
    if (touching) {
      timed(S::OverlapLimit, [&] {
        limit_dynamic_overlap(model, state, c, C::DYNAMIC_OVERLAP_LIMIT, C::OVERLAP_LIMIT_PASSES);
        limit_static_overlap(model, state, c, C::STATIC_OVERLAP_LIMIT);
      });
    }
    if (sweeping) {
      // a body that went further than its contacts reached: swept against the static
      // shapes, and put back before one it went into (collide/continuous.cpp). After the
      // overlap limits: bodies put back beside one another may overlap, and moved apart
      // here they were pushed into the wall they were stopped at
      timed(S::Continuous, [&] {
        sweep_fast_bodies(model, state, c, grid, continuous_index, continuous_v, continuous_w,
                          cfg.dt, cfg.restitution_rule, threshold);
      });
    }
    if (c.record_impulses) hand_down_shock_impulses(model, c);
    timed(S::Store, [&] {
      give_impulses(c);  // (2D: the batches held them through the passes)
      // each part counts its touching points (an integer sum: the same in any order).
      // Where most pairs were still, the manifolds are copied into prev_* (a carried one's
      // impulses only); else, every manifold written anew, the arrays are swapped at the
      // next step's start instead (take_prev), which saves the copy: in a pile landing or
      // jostling, 4% of the step
      const std::int64_t n = c.count.manifolds, n_pairs = c.count.pairs;
      const std::int64_t still =
          std::count(found_points.begin(), found_points.begin() + n_pairs, FOUND_CARRIED);
      const bool swap_next = 2 * still < n;
      std::atomic<std::int64_t> touching{0};
      parallel(n, [&](Span part) {
        touching += swap_next ? store_touching(c, part) : store_impulses(c, part);
      });
      c.count.manifolds_prev = n;
      c.count.points_touching = touching.load();
      c.prev_pending = swap_next;
      c.prev_swapped = false;
    });
    grid.frame_origin = grid.frame_offset;  // the step is done: its frame is the next's origin
  }
  return true;
  }
}

// A step of bodies that do not touch: the integrator's substeps alone.
template <int D>
bool World<D>::step_free() {
  const Config& cfg = config;
  auto& c = contacts;
  using S = StageId;
  for (auto& d : c.body_delta) d = BodyDelta<D>{};
  const double h = cfg.dt / cfg.substeps;
  const std::int64_t n_bodies = model.body_count();
  auto move = [&] {
    parallel(n_bodies, [&](Span part) {
      integrate_positions(model, state, c.body_delta, h, cfg.rotation, part);
    });
  };
  for (int sub = 0; sub < cfg.substeps; ++sub) {
    if (cfg.explicit_euler) timed(S::IntegratePositions, move);
    timed(S::IntegrateVelocities, [&] {
      parallel(n_bodies, [&](Span part) { integrate_velocities(model, state, h, part); });
    });
    if (!cfg.explicit_euler) timed(S::IntegratePositions, move);
  }
  return true;
}

namespace {

template <class T>
bool finite(const T& v) {
  if constexpr (std::is_same_v<T, double>) {
    return std::isfinite(v);
  } else {
    const double* p = reinterpret_cast<const double*>(&v);
    for (std::size_t k = 0; k < sizeof(T) / sizeof(double); ++k)
      if (!std::isfinite(p[k])) return false;
    return true;
  }
}

template <class T>
bool within(const T& v, double limit) {
  const double* p = reinterpret_cast<const double*>(&v);
  for (std::size_t k = 0; k < sizeof(T) / sizeof(double); ++k)
    if (!(std::abs(p[k]) <= limit)) return false;
  return true;
}

// Whether some double of `values` is NaN or has a magnitude above `bound`: LANES at a
// time, each lane's outcome kept in a mask (a scalar loop with its early exit, or an
// integer compare of the bits, was not vectorised: 2% of a 1000-circle pile's step).
template <class T>
bool beyond(const std::vector<T>& values, double bound) {
  const double* p = reinterpret_cast<const double*>(values.data());
  const std::size_t n = values.size() * (sizeof(T) / sizeof(double));
  const Lanes hi = splat(bound), lo = splat(-bound);
  LaneMask out{};
  std::size_t k = 0;
  for (; k + LANES <= n; k += LANES) {
    const Lanes x = load_lanes(p + k);
    out |= ~((x <= hi) & (x >= lo));  // (NaN: neither)
  }
  bool hit = any(out);
  for (; k < n; ++k) hit = hit || !(std::abs(p[k]) <= bound);
  return hit;
}

// The body to blame for a bad state: the first dynamic body whose state is not finite
// or has left POSITION_LIMIT. A static or kinematic body only goes bad through a dynamic
// one (a non-finite impulse times its zero inverse mass), so it is named only when no
// dynamic body is bad. -1: none.
template <int D>
std::int64_t first_bad_body(const Model<D>& model, const State<D>& st) {
  constexpr double largest = std::numeric_limits<double>::max();  // (above it: ±inf)
  if (!beyond(st.body_v, largest) && !beyond(st.body_w, largest) &&
      !beyond(st.body_q, largest) && !beyond(st.body_x, POSITION_LIMIT))
    return -1;  // (the search below only for a bad state)
  std::int64_t other = -1;
  for (std::size_t i = 0; i < st.body_x.size(); ++i) {
    if (finite(st.body_v[i]) && finite(st.body_w[i]) && finite(st.body_q[i]) &&
        within(st.body_x[i], POSITION_LIMIT))
      continue;
    if (model.is_dynamic(static_cast<int>(i))) return static_cast<std::int64_t>(i);
    if (other < 0) other = static_cast<std::int64_t>(i);
  }
  return other;
}

}  // namespace

template <int D>
Status World<D>::advance(std::int64_t n_steps, std::int64_t* taken, std::int64_t* bad_body) {
  *taken = 0;
  // between calls the prev_* arrays hold last step's manifolds, however the call ends
  // (a checkpoint and the tests read them; the store may have left them to a swap)
  struct Settle {
    Contacts<D>& c;
    ~Settle() { settle_prev(c); }
  } settle{contacts};
  if (torn) return Status::Torn;  // a step stopped inside: no step from a torn state
  // a state set bad from outside (through the numpy views) is refused before any stage
  // sees it: a non-finite or huge position would reach the broadphase's cell arithmetic
  if (n_steps > 0) {
    const std::int64_t bad = first_bad_body(model, state);
    if (bad >= 0) {
      *bad_body = bad;
      return Status::NonFinite;
    }
  }
  const std::int64_t limit = pair_limit();
  bool grew = false;  // the step under way found the store too small and grew it
  if (config.choose_threads && config.threads > 1 && !thread_choice)
    thread_choice.emplace(config.threads, C::THREAD_TRIAL_BLOCK, C::THREAD_TRIAL_FIRST_SECONDS,
                          C::THREAD_TRIAL_EVERY_SECONDS);
  while (*taken < n_steps) {
    // a step that may be long is asked inside too (stop_here): one the store grew for
    // has more contacts than the last step had
    stoppable_ = static_cast<bool>(interrupt) && (grew || step_may_be_long());
    if (thread_choice) step_threads_ = thread_choice->next();
    const auto start = std::chrono::steady_clock::now();
    const bool done = step();
    stoppable_ = false;
    step_threads_ = 0;
    if (torn) {
      *bad_body = -1;
      return Status::Interrupted;
    }
    if (!done) {
      const std::int64_t pairs = contacts.count.pairs;
      if (pairs > limit) {
        // the pair list was not completed: found anew by the next step, as after grow
        pairs_wanted = pairs;
        contacts.count.pairs = 0;
        grid.meta.pairs_valid = 0;
        *bad_body = -1;
        return Status::TooManyPairs;
      }
      // the room the step found too small: its pairs' or its manifolds' (a pair has one
      // manifold at most). Growing a large store takes a while (its memory is new): a
      // stop asked meanwhile ends the call, the world as it was
      const std::int64_t pair_room =
          pairs > contacts.pair_capacity() ? std::min(2 * pairs, limit) : 0;
      const std::int64_t manifold_room = std::min(2 * manifolds_wanted, limit);
      manifolds_wanted = 0;
      if (!grow_store(manifold_room, pair_room, true)) {
        *bad_body = -1;
        return Status::Interrupted;
      }
      grew = true;
      continue;
    }
    last_step_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // (a step the store grew for is not timed: its time is not the choice's)
    if (thread_choice && !grew) thread_choice->took(last_step_seconds);
    grew = false;
    ++*taken;
    ++step_index;
    std::int64_t bad = first_bad_body(model, state);
    if (bad >= 0) {
      *bad_body = bad;
      return Status::NonFinite;
    }
  }
  return Status::Ok;
}

template <int D>
bool World<D>::stop_here() {
  if (!stoppable_ || !interrupt || !interrupt()) return false;
  torn = true;
  return true;
}

template <int D>
bool World<D>::step_may_be_long() const {
  if (last_step_seconds >= 0.0) return last_step_seconds >= C::STEP_STOP_SECONDS;
  if (!model.has_shapes) return false;  // the integrator alone: within the work bound, fast
  const double per_pair = D == 2 ? C::STEP_SECONDS_PER_PAIR : C::STEP_SECONDS_PER_PAIR_3D;
  const double passes = static_cast<double>(config.substeps) * config.iterations;
  return static_cast<double>(pair_limit()) * passes * per_pair >= C::STEP_STOP_SECONDS;
}

template <int D>
std::int64_t World<D>::pair_limit() const {
  const double work = D == 2 ? C::PAIR_WORK_MAX : C::PAIR_WORK_MAX_3D;
  const double per_pair = static_cast<double>(config.substeps) * config.iterations;
  const auto by_work = static_cast<std::int64_t>(work / std::max(per_pair, 1.0));
  return std::min(C::PAIRS_PER_SHAPE * model.shape_count() + C::PAIRS_FLOOR, by_work);
}

template <int D>
std::vector<double> shape_extent(const Model<D>& model) {
  std::vector<double> ext(model.shape_count());
  for (int s = 0; s < model.shape_count(); ++s) {
    const int start = model.shape_vstart[s], count = model.shape_vcount[s];
    auto lo = model.vertex_local[start], hi = lo;
    for (int k = start + 1; k < start + count; ++k) {
      const double* p = reinterpret_cast<const double*>(&model.vertex_local[k]);
      double* l = reinterpret_cast<double*>(&lo);
      double* u = reinterpret_cast<double*>(&hi);
      for (int d = 0; d < D; ++d) {
        l[d] = std::min(l[d], p[d]);
        u[d] = std::max(u[d], p[d]);
      }
    }
    auto span = hi - lo;
    if constexpr (D == 2) {
      ext[s] = 0.5 * std::hypot(span.x, span.y) + model.shape_radius[s];
    } else if (model.shape_kind[s] == ShapeKind::Plane) {
      // a half-space has no size: its contacts take the other shape's scale
      ext[s] = std::numeric_limits<double>::infinity();
    } else {
      ext[s] = 0.5 * length(span) + model.shape_radius[s];
    }
  }
  return ext;
}

template <int D>
std::vector<double> shape_depth(const Model<D>& model) {
  using Vec = typename Dim<D>::Vec;
  std::vector<double> depth(model.shape_count());
  for (int s = 0; s < model.shape_count(); ++s) {
    const int start = model.shape_vstart[s], count = model.shape_vcount[s];
    const ShapeKind kind = model.shape_kind[s];
    double core = 0.0;  // m: the core's own depth (a point or a segment has none)
    if (kind == ShapeKind::Plane) {
      core = std::numeric_limits<double>::infinity();
    } else if (kind == ShapeKind::Box) {
      // (its corners: the nearest to the first lies along the shortest edge)
      core = std::numeric_limits<double>::infinity();
      for (int k = start + 1; k < start + count; ++k)
        core = std::min(core, 0.5 * length(model.vertex_local[k] - model.vertex_local[start]));
    } else if (kind == ShapeKind::Polygon || kind == ShapeKind::Convex) {
      Vec mean{};  // m: inside the (convex) core
      for (int k = start; k < start + count; ++k) mean += model.vertex_local[k];
      mean = (1.0 / count) * mean;
      core = std::numeric_limits<double>::infinity();
      if constexpr (D == 2) {
        for (int k = start; k < start + count; ++k)  // (edge k: vertex k to the next)
          core = std::min(core, dot(model.normal_local[k], model.vertex_local[k] - mean));
      } else {
        for (int f = model.shape_fstart[s]; f < model.shape_fstart[s] + model.shape_fcount[s];
             ++f) {
          const auto& t = model.face_local[f];
          const Vec a = model.vertex_local[start + t[0]];
          const Vec n = cross(model.vertex_local[start + t[1]] - a,
                              model.vertex_local[start + t[2]] - a);
          const double len = length(n);
          if (len > 0.0) core = std::min(core, dot(n, a - mean) / len);
        }
      }
      core = std::max(core, 0.0);
    }
    depth[s] = core + model.shape_radius[s];
  }
  return depth;
}

Soft soft_parameters(double hertz, double zeta, double h) {
  if (hertz == 0.0) return {1.0, 0.0, 0.0};
  const double omega = 2.0 * M_PI * hertz;
  const double a1 = 2.0 * zeta + h * omega;
  const double a2 = h * omega * a1;
  const double a3 = 1.0 / (1.0 + a2);
  return {a2 * a3, a3, omega / a1};
}

void set_contact_softness(Config& cfg) {
  const double h = cfg.dt / cfg.substeps;
  const double cap = 0.25 / h;  // Hz
  const double hertz = std::min(C::CONTACT_HERTZ, cap);
  cfg.soft = soft_parameters(hertz, C::CONTACT_DAMPING_RATIO, h);
  cfg.soft_static = soft_parameters(static_hertz(hertz, cap), C::CONTACT_DAMPING_RATIO, h);
}

template struct World<2>;
template struct World<3>;
template std::vector<double> shape_extent(const Model<2>&);
template std::vector<double> shape_extent(const Model<3>&);
template std::vector<double> shape_depth(const Model<2>&);
template std::vector<double> shape_depth(const Model<3>&);

}  // namespace rbsim
