// The contact store: manifolds (up to Dim<D>::max_points points each), their solver rows,
// last step's manifolds for warm starting, and the scratch of the stages that walk the
// contact graph. Room for M manifolds and for the broadphase's pairs (more than touch:
// a falling body's boxes reach ahead of it), each grown between steps (World::grow_store),
// never in one.
//
// A manifold joins shape a to shape b (a < b) with one normal pointing from b towards a.
// Manifolds are kept sorted by key = a · S + b, so this step's are matched to last step's
// in one merge pass and a point whose feature id matches takes over last step's impulses.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "constants.hpp"
#include "hull3d.hpp"
#include "math.hpp"
#include "state.hpp"
#include "wide.hpp"

namespace rbsim {

// Counters of the contact store, by name (the numba engine kept them as count[0..9], in
// this order; the bindings show the struct as that array).
struct ContactCounts {
  std::int64_t manifolds = 0;       // manifolds this step
  std::int64_t manifolds_prev = 0;  // manifolds last step (prev_* hold them)
  std::int64_t pairs = 0;           // broadphase pairs found (may exceed capacity: grow)
  std::int64_t points_touching = 0; // contact points that pushed in the last step
  std::int64_t shock_count = 0;     // manifolds in the shock pass's order
  std::int64_t bounce_count = 0;    // entries in bounce_list
  std::int64_t deep_count = 0;      // entries in relax_list: points deeper than DEEP_OVERLAP
  std::int64_t graph_unchanged = 0; // 1: the manifolds are last step's pairs in the same slots
  std::int64_t bounce_carried = 0;  // entries of bounce_list carried from the last restitution
  // 1 once an elastic manifold, or an inelastic impact of a group (restitution.cpp,
  // push_group), was listed this step: the restitution stage looks at every manifold
  std::int64_t elastic_listed = 0;
  std::int64_t support_changed = 0; // 1: a pair touches where it did not last step, or no longer
  std::int64_t friction_loaded = 0; // 1: rows hold a friction_load (shock.cpp, friction_loads)
};

// One pair's narrowphase result (manifold.cpp, narrow_pairs), at its time of impact where
// it meets within the step: the normal, up to Dim<D>::max_points points midway between
// the surfaces (m), their signed separations (m) and feature ids, and that time.
template <int D>
struct PairManifold {
  static constexpr int P = Dim<D>::max_points;
  typename Dim<D>::Vec normal;
  std::array<typename Dim<D>::Vec, P> point;
  std::array<double, P> separation;
  std::array<std::int64_t, P> id;
  double t = 0.0;  // s: the time of impact it was moved to (0: the step's start)
};

// What narrow_pairs found of a pair besides its point count (0 or more, after the time of
// impact): its tight boxes apart, or a still pair whose last manifold is carried.
inline constexpr std::int8_t FOUND_APART = -2;
inline constexpr std::int8_t FOUND_CARRIED = -1;

// What the solver's passes read of one manifold, in one record of four cache lines.
template <int D>
struct SolverRow;

// (Its fields, 32 doubles, lie in the order of WideBatch's lane vectors: waves.cpp packs
// four rows into a batch four doubles at a time.)
template <>
struct SolverRow<2> {
  struct Point {
    double rna = 0, rnb = 0;  // m: lever arms r_a × n, r_b × n
    double rta = 0, rtb = 0;  // m: r_a × t, r_b × t
    double kn = 0;            // 1/kg: the normal row's K
    double tangent_mass = 0;  // kg
    Vec2 ra, rb;              // m: separation anchors from each COM (sep_anchor_a, _b)
    double base = 0;          // m: base separation
  };
  Vec2 normal;              // from b towards a
  double k01 = 0;           // 1/kg: off-diagonal of the two points' normal block
  double gamma = 0;         // γ/K of the soft constraint (impulse scale / mass scale)
  double bias_rate = 0;     // 1/s: the soft constraint's push-out rate
  double friction = 0;      // the mixed friction coefficient
  std::array<Point, 2> point;
  double max_push = 0;      // m/s, < 0: the fastest push-out (CONTACT_PUSH_MAX_VELOCITY, scaled)
  double deep = 0;          // m, < 0: a separation below it is a deep overlap (DEEP_OVERLAP)
  double touch = 0;         // m: a point within it touches and has friction (LINEAR_SLOP)
  // N·s: the least normal impulse the manifold's friction is bounded by (μ times the larger
  // of it and its points' sum): the weight a heavy body's support carries through the
  // shock pass, else 0 (shock.cpp, friction_loads; solve.cpp, bounding_impulses)
  double friction_load = 0;
};
static_assert(sizeof(SolverRow<2>) == 32 * sizeof(double));
// In 3D a manifold has up to four points and two friction directions t1, t2 (an
// orthonormal basis of the tangent plane, any: the friction is solved as one 2×2 block
// per point and clamped to Coulomb's circle, so the result does not depend on the basis).
// A face's points are solved as one block (solve.cpp), whose K the row keeps.
// The angular terms are vectors; the world inverse inertia tensors are taken at the
// step's start (what the passes use to follow the bodies' velocities within a manifold;
// a manifold writes each body's ω back from its angular momentum, see solve.cpp).
// A symmetric block of up to four rows as L D Lᵀ (row.hpp, factor_block): L unit lower
// triangular, D diagonal. Its units are the block's (here 1/kg).
// (No default member values: a solve makes one on its stack for a face whose points are
// pushed out in part, written only where used; a row's are value-initialised with it.)
struct BlockFactor {
  double l[6];      // L below the diagonal by rows: L10 L20 L21 L30 L31 L32
  double d[4];      // D's diagonal
  double inv_d[4];  // 1 / D's diagonal (a solve multiplies: no division)
  double ok;        // 1 when every pivot was positive (else the block is not solved at once)
  double pad;
};

// Three components of four points, component by component (x of points 0..3, then y,
// then z): a component of every point loads as one vector of four lanes (wide.hpp).
struct Vec3x4 {
  alignas(32) double x[4], y[4], z[4];
  Vec3 operator[](int k) const { return {x[k], y[k], z[k]}; }
  void set(int k, Vec3 v) { x[k] = v.x, y[k] = v.y, z[k] = v.z; }
};

template <>
struct SolverRow<3> {
  // One point of the row, as the passes that take a point at a time read it.
  struct Point {
    Vec3 ra, rb;        // m: separation anchors from each COM (sep_anchor_a, _b)
    Vec3 arm_a, arm_b;  // m: lever arms, the contact point from each COM (anchor_a, _b)
    Vec3 rna, rnb;      // m: r_a × n, r_b × n
    Vec3 wna, wnb;      // 1/(kg·m): I_a⁻¹ (r_a × n), I_b⁻¹ (r_b × n), world frame
    double kn = 0;      // 1/kg: the normal row's K
    double base = 0;    // m: base separation
    // kg: the inverse of the point's 2×2 tangent block K_t (rows t1, t2), symmetric
    double tm11 = 0, tm12 = 0, tm22 = 0;
    double tangent_mass = 0;  // kg: 2 / trace K_t, the sliding step's (friction_circle)
    // m: friction's levers r × t1, r × t2 on each body (the moments of unit impulses
    // along the tangents; the ω they make is the row's inverse inertia times them)
    Vec3 rt1a, rt2a, rt1b, rt2b;
  };
  // The four points' fields as Point names them, stored field by field (structure of
  // arrays), so that the solve takes a field of a face's points as one vector. A point
  // past the manifold's count is all zeros (prepare_contacts), so a lane of it adds
  // nothing to a sum. point[k] reads point k as one Point.
  struct Points {
    Vec3x4 ra, rb, arm_a, arm_b, rna, rnb, wna, wnb, rt1a, rt2a, rt1b, rt2b;
    alignas(32) double kn[4], base[4], tm11[4], tm12[4], tm22[4], tangent_mass[4];
    Point operator[](int k) const {
      return {ra[k],  rb[k],      arm_a[k],   arm_b[k],   rna[k],     rnb[k],
              wna[k], wnb[k],     kn[k],      base[k],    tm11[k],    tm12[k],
              tm22[k], tangent_mass[k], rt1a[k], rt2a[k], rt1b[k], rt2b[k]};
    }
    void set(int k, const Point& p) {
      ra.set(k, p.ra), rb.set(k, p.rb), arm_a.set(k, p.arm_a), arm_b.set(k, p.arm_b);
      rna.set(k, p.rna), rnb.set(k, p.rnb), wna.set(k, p.wna), wnb.set(k, p.wnb);
      kn[k] = p.kn, base[k] = p.base, tm11[k] = p.tm11, tm12[k] = p.tm12, tm22[k] = p.tm22;
      tangent_mass[k] = p.tangent_mass;
      rt1a.set(k, p.rt1a), rt2a.set(k, p.rt2a), rt1b.set(k, p.rt1b), rt2b.set(k, p.rt2b);
    }
  };
  Vec3 normal;             // from b towards a
  Vec3 t1, t2;             // the tangent basis: t1 × t2 = n
  Sym3 inv_ia, inv_ib;     // 1/(kg·m²): world inverse inertia tensors at the step's start
  double gamma = 0;        // γ/K of the soft constraint
  double bias_rate = 0;    // 1/s: the soft constraint's push-out rate
  double friction = 0;     // the mixed friction coefficient
  double max_push = 0;     // m/s, < 0: the fastest push-out (CONTACT_PUSH_MAX_VELOCITY, scaled)
  double deep = 0;         // m, < 0: a separation below it is a deep overlap (DEEP_OVERLAP)
  double touch = 0;        // m: a point within it touches and has friction (LINEAR_SLOP)
  double friction_load = 0;  // N·s: as SolverRow<2>'s
  // 1/kg: the points' normal block K (symmetric 4×4, rows 0..points-1), its upper
  // triangle by rows: K00 K01 K02 K03 K11 K12 K13 K22 K23 K33
  std::array<double, 10> k{};
  // the normal block's LDLᵀ factors for the passes' two usual cases (row.hpp,
  // factor_block): `rigid`, K + ε diag(K) (the relax stage, and a solve in which no point
  // overlaps); `soft`, with every point's γ added (a solve in which every point overlaps)
  BlockFactor rigid{}, soft{};
  // kg⁻¹: how friction at one point moves another's sliding velocity. For points i > j,
  // tangent_coupling[i (i − 1) / 2 + j] is the 2×2 block (row-major: t1 t1, t1 t2, t2 t1,
  // t2 t2) of K_t between them: the change of point i's (v·t1, v·t2) per unit impulse
  // along t1, t2 at point j (its transpose, j's per unit impulse at i)
  std::array<std::array<double, 4>, 6> tangent_coupling{};
  Points point{};
};

// 3D: a body watched for its turn within a step (Contacts::turn_watch).
struct TurnWatch {
  std::int32_t body;
  double limit;  // sin²(φ/2) of the turn φ after which its rows are made again
  Quat rows{};   // the rotation its rows were made at, within a step (the step's start's,
                 // or where refresh_turned_rows made them again)
};

template <int D>
struct Contacts {
  static constexpr int P = Dim<D>::max_points;
  using Vec = typename Dim<D>::Vec;
  template <class T>
  using PerPoint = std::array<T, P>;

  ContactCounts count;
  // this step's manifolds (M,)
  std::vector<std::uint8_t> carried;  // last step's, unchanged in its slot but for separation
  std::vector<std::array<std::int32_t, 2>> pairs;  // broadphase output (shape a, shape b)
  std::vector<std::int32_t> shape_a, shape_b, body_a, body_b;
  std::vector<std::int64_t> key;                    // shape_a · S + shape_b
  std::vector<Vec> normal;                          // from b towards a
  std::vector<std::int32_t> points;                 // point count
  std::vector<double> friction, restitution;        // mixed coefficients
  std::vector<double> scale;                         // the contact tolerances' scale s (SCALE_LENGTH)
  std::vector<PerPoint<Vec>> anchor_a, anchor_b;    // m: lever arms, contact point from each COM
  // m: the material points whose motion the separation follows, from each COM in its
  // body's frame at the step's start: the anchors, but on a rounded shape the point of
  // its core (a circle's centre: turning it does not move its surface) and, for a
  // manifold moved to a time of impact, turned back to the step's start
  std::vector<PerPoint<Vec>> sep_anchor_a, sep_anchor_b;
  std::vector<PerPoint<double>> base_separation;    // m: separation minus the anchors' part
  std::vector<PerPoint<double>> ref_separation;     // m: with the bodies at ref_offset
  // m: x_a − x_b (the two bodies' COMs) when the manifold's geometry was found, and each
  // body's rotation then: a pair of bodies that has not moved one against the other since
  // (STILL_DISTANCE), nor turned (STILL_ANGLE), carries it forward (narrow_pairs), its
  // separation changed by their relative move
  std::vector<Vec> ref_offset;
  std::vector<typename Dim<D>::RefTurn> ref_turn_a, ref_turn_b;
  std::vector<double> start_separation;             // m: its deepest point's at the step's start
  std::vector<PerPoint<std::int64_t>> feature;      // feature ids
  std::vector<PerPoint<double>> normal_impulse;     // N·s, per substep
  std::vector<PerPoint<double>> start_impulse;      // N·s carried into this step
  using Tangent = typename Dim<D>::Tangent;
  // N·s: 2D, along the one tangent; 3D, a world vector in the tangent plane
  std::vector<PerPoint<Tangent>> tangent_impulse;
  std::vector<PerPoint<double>> normal_mass;        // kg
  std::vector<SolverRow<D>> solver_row;
  std::vector<PerPoint<double>> approach_velocity;  // m/s where the point engaged
  std::vector<PerPoint<double>> approach_separation;  // m where the point engaged
  std::vector<PerPoint<double>> max_normal_impulse;   // N·s
  // last step's manifolds, for matching and for carrying a manifold forward (M,)
  std::vector<std::int64_t> prev_key;
  std::vector<std::int32_t> prev_points;
  std::vector<PerPoint<std::int64_t>> prev_feature;
  std::vector<PerPoint<double>> prev_normal_impulse;
  std::vector<PerPoint<Tangent>> prev_tangent_impulse;
  std::vector<Vec> prev_normal;
  std::vector<PerPoint<Vec>> prev_anchor_a, prev_anchor_b;
  std::vector<PerPoint<Vec>> prev_sep_anchor_a, prev_sep_anchor_b;
  std::vector<PerPoint<double>> prev_ref_separation;
  std::vector<Vec> prev_ref_offset;
  std::vector<typename Dim<D>::RefTurn> prev_ref_turn_a, prev_ref_turn_b;
  // per body (N,)
  std::vector<BodyDelta<D>> body_delta;  // motion since the step's start
  // 3D (2D: empty): 1/(kg·m²), each body's inverse inertia tensor in world axes at its
  // rotation now, R I_b⁻¹ Rᵀ (world_inertia at the step's start, integrate_positions when
  // the body turns), so that the solver's passes find ω = I⁻¹ L with one product
  std::vector<typename Dim<D>::Inertia> body_inv_inertia_world;
  // 3D (2D: empty): the rotation each body's world tensor was made at (NaN: not made),
  // so that the step's start makes it again only where the rotation was set from outside
  std::vector<typename Dim<D>::Rot> body_inertia_q;
  // 3D (2D: empty), within a step: whether each body's contact rows were just made again
  // at its rotation now (1; refresh_turned_rows)
  std::vector<std::uint8_t> body_row_remade;
  // 3D (2D: empty): the dynamic bodies whose inertia is far enough from round that a turn
  // within a step can call for their rows to be made again (ROW_TURN_MAX), each with the
  // sin²(φ/2) of the turn φ that does (World::allocate, from the model) and the rotation
  // its rows were made at
  std::vector<TurnWatch> turn_watch;
  // per vertex / shape
  std::vector<Vec> vert_world, norm_world;  // (V,) shape geometry in the world this step
  std::vector<Vec> face_world;  // 3D: (Model::hull_face_count,) convex hulls' face normals
                                // in the world this step (sized by World::allocate)
  // 3D, made with face_world (2D: empty): each hull face's plane offset n · o (m, o its
  // loop's first vertex), and each hull shape's HullSpread (S,; the others' unused)
  std::vector<double> face_offset;
  std::vector<HullSpread> shape_spread;
  // how far each shape's surface can move this step (collide/transform.cpp), m: its
  // box's reach, |dt v - frame| + dt² |a| + shape_turn, about the move of the frame of
  // the moving bodies (frame_move; a static shape's |frame|); and what its turning adds,
  // dt |ω| r (a pair's speculative distance takes the two turns and the bodies' relative
  // move, dt |v_a - v_b|: bodies falling side by side come no closer)
  std::vector<double> shape_margin;         // (S,)
  std::vector<double> shape_turn;           // (S,)
  std::vector<double> shape_size;           // (S,) m: half its bounding box's diagonal
  std::vector<double> shape_scale;          // (S,) min(1, size / SCALE_LENGTH)
  std::vector<double> body_scale;           // (N,) its smallest shape's (1 without shapes)
  // the shock pass and the solve order (shock.cpp)
  std::vector<std::int64_t> body_level;     // (N,)
  std::vector<std::int32_t> body_supporters;  // (N,) 3D: the manifolds that support each body
                                              // (support_order sizes it)
  std::vector<std::int8_t> support;         // (M,) 1: a point within SUPPORT_GAP (manifold.cpp)
  std::vector<std::int8_t> prev_support;    // (M,) last step's, as prev_key
  std::vector<double> body_load;            // (N,) kg each body bears (while heavy_on_light)
  // (N,) the moving kinematic body that carries each body: itself for a moving kinematic
  // body, its supporter's carrier for a dynamic one resting on a carried body, else -1
  // (friction_loads, while heavy_on_light; the shock pass's friction may bring a body on
  // a carried supporter up to the carrier's speed)
  std::vector<std::int32_t> body_carried;
  std::vector<std::int8_t> shock_side;      // (M,)
  std::vector<std::int32_t> shock_order;    // (M,)
  std::vector<std::int32_t> solve_order;    // (M,) the order of the solver's passes
  std::vector<std::int64_t> adj_start;      // (N+1,)
  std::vector<std::int32_t> adj;            // (2M,)
  std::vector<std::int64_t> queue;          // (N+2,)
  // the restitution stage (restitution.cpp)
  std::vector<std::int8_t> bounce_kind;     // (M,)
  std::vector<std::int8_t> body_mark;       // (N,)
  std::vector<PerPoint<double>> solve_impulse;  // (M,) N·s when the positions moved
  // each point's normal impulse over the whole step (M,), N·s: every substep's
  // accumulated one, what the restitution stage drops after a bounce, the shock pass's
  // pushes and what those hand down the support chain (hand_down_shock_impulses); kept
  // only while record_impulses (a run that writes its contact points: each one's mean
  // force over the step, tools/record.cpp). shock_impulse: each manifold's shock pushes
  // in the step, N·s.
  std::vector<PerPoint<double>> step_impulse;
  std::vector<double> shock_impulse;
  // (M,) bit k: the shock pass pushed at point k in this step (a point the soft contacts
  // leave to it, as under a heavy load in 2D, pushes too: pushed_in_step)
  std::vector<std::uint8_t> shock_points;
  // (M(P+1)+2,) manifolds that engaged fast: between two restitution stages each point
  // engages at most once (P per manifold), after at most M deferred ones carried over
  std::vector<std::int32_t> bounce_list;
  std::vector<std::int32_t> relax_list;     // (M,) deep manifolds, then the extra passes' set
  std::vector<std::int64_t> body_reach;     // (N,) deep_region's scratch
  std::vector<std::int32_t> overlap_list;   // (M,) limit_dynamic_overlap's: the deep pairs
  std::vector<double> body_motion;          // (N,) m: how far its points moved, at most
  // the waves of the solve order (waves.cpp): groups of independent manifolds
  std::int64_t wave_count = 0;             // waves
  bool waves_valid = false;                 // the waves are this contact graph's
  // 2D: some batches of a region hold manifolds of a cut in lanes of their own
  // (WideBatch::cut; waves.cpp, schedule_units)
  bool cut_lanes = false;
  // 2D: the batches hold the impulses of their manifolds (normal_impulse,
  // tangent_impulse, max_normal_impulse and approach_velocity are behind them) while the
  // passes run: take_impulses, give_impulses (waves.cpp)
  bool impulses_in_lanes = false;
  bool heavy_on_light = false;              // a body rests on one HEAVY_RATIO times lighter
  bool unit_scale = true;                   // every shape's scale is 1 (SCALE_LENGTH)
  bool record_impulses = false;             // keep step_impulse (a run's setting)
  // The store's hand-over to the next step (contact/store.cpp) when few of the step's
  // pairs were still: the manifold arrays are swapped with their prev_* ones at the next
  // step's start (take_prev) instead of copied at this step's end. prev_pending: this
  // step's manifolds are still in the current arrays only (never between advance calls:
  // settle_prev); prev_swapped: in the step under way the current arrays are not last
  // step's manifolds (no slot's manifold is carried as it stands)
  bool prev_pending = false;
  bool prev_swapped = false;
  std::vector<std::int32_t> wave_order;    // (M,) the manifolds wave by wave
  std::vector<std::int32_t> manifold_wave;  // (M,) each manifold's wave (scratch)
  std::vector<std::int32_t> body_wave;      // (N,) the last wave that moved the body (scratch)
  std::vector<std::int64_t> wave_start;    // (M+2,) wave g: wave_order[start[g]..start[g+1])
  std::vector<std::int64_t> wave_batch;    // (M+2,) wave g: batches[batch[g]..batch[g+1])
                                            // (3D: batches3)
  std::vector<std::int64_t> wave_single;   // (M+1,) 2D: wave g's one-point manifolds,
                                            // wave_order[single[g]..start[g+1]); 3D: its
                                            // manifolds of more points, solved one by one
  std::vector<std::int64_t> wave_single_batch;  // (M+1,) and their batches, from here
                                                 // to wave_batch[g+1]
  std::vector<std::int64_t> wave_idle;     // (M+1,) 3D: wave g's faces that hold no impulse,
                                            // wave_order[idle[g]..start[g+1]), solved one by
                                            // one (waves.cpp)
  std::vector<WideBatch> batches;           // the waves' manifolds, LANES at a time (find_waves sizes it)
  std::vector<WideBatch3> batches3;         // 3D: the waves' one-point manifolds, LANES at a time
  std::vector<WideFace3> faces3;            // 3D: and the others, LANES of one point count at a
                                            // time (wave g: faces3[wave_single_batch[g]..[g+1]))
  // the regions of the solver's passes (regions.cpp): segment g of segment_count(regions)
  // is solve_order[segment_order[g]..segment_order[g+1]), its waves
  // [segment_wave[g], segment_wave[g+1]) and its part of the shock pass
  // shock_order[segment_shock[g]..segment_shock[g+1])
  std::int64_t region_count = 1;            // regions (1: the whole scene)
  std::vector<std::int32_t> body_region;    // (N,) a dynamic body's region, else -1
  std::vector<std::int64_t> segment_order;  // (SEGMENTS+1,)
  std::vector<std::int64_t> segment_wave;   // (SEGMENTS+1,)
  std::vector<std::int64_t> segment_shock;  // (SEGMENTS+1,)

  // The manifolds the store has room for.
  std::int64_t capacity() const { return static_cast<std::int64_t>(key.size()); }
  // The broadphase pairs the store has room for (pairs, and the step's buffers by pair).
  std::int64_t pair_capacity() const { return static_cast<std::int64_t>(pairs.size()); }
  // Room for `n` pairs (none kept: the pair list is found anew).
  void grow_pairs(std::int64_t n) {
    if (n > pair_capacity()) pairs.assign(static_cast<std::size_t>(n), {});
    count.pairs = 0;
  }

  // Storage for `capacity` manifolds, n_bodies bodies, n_shapes shapes, n_vertices.
  // stop, when given, is asked after each array: true leaves the rest unmade and returns
  // false (the store is then not usable: grow drops it).
  bool allocate(int n_bodies, int n_shapes, int n_vertices, std::int64_t capacity,
                const std::function<bool()>* stop = nullptr);
  // Room for `capacity` manifolds, keeping last step's manifolds (warm starting) and the
  // room for pairs (the pair list is found anew). A large store takes seconds to make
  // (its memory is new): stop is asked meanwhile, and true leaves the store as it was and
  // returns false.
  bool grow(std::int64_t capacity, const std::function<bool()>* stop = nullptr);
};

template <int D>
bool Contacts<D>::allocate(int n_bodies, int n_shapes, int n_vertices, std::int64_t capacity,
                           const std::function<bool()>* stop) {
  const std::size_t m = static_cast<std::size_t>(capacity < 1 ? 1 : capacity);
  const std::size_t n = static_cast<std::size_t>(n_bodies < 1 ? 1 : n_bodies);
  const std::size_t s = static_cast<std::size_t>(n_shapes < 1 ? 1 : n_shapes);
  const std::size_t v = static_cast<std::size_t>(n_vertices < 1 ? 1 : n_vertices);
  count = ContactCounts{};
  bool stopped = false;
  auto reset = [&](auto& vec, std::size_t size) {
    if (stopped) return;
    vec.assign(size, {});
    stopped = stop != nullptr && *stop && (*stop)();
  };
  reset(carried, m); reset(pairs, m);
  reset(shape_a, m); reset(shape_b, m); reset(body_a, m); reset(body_b, m);
  reset(key, m); reset(normal, m); reset(points, m); reset(friction, m); reset(restitution, m);
  reset(scale, m);
  reset(anchor_a, m); reset(anchor_b, m); reset(base_separation, m); reset(ref_separation, m);
  reset(ref_offset, m); reset(ref_turn_a, m); reset(ref_turn_b, m);
  reset(start_separation, m);
  reset(sep_anchor_a, m); reset(sep_anchor_b, m);
  reset(feature, m); reset(normal_impulse, m); reset(start_impulse, m);
  reset(tangent_impulse, m); reset(normal_mass, m); reset(solver_row, m);
  reset(approach_velocity, m); reset(approach_separation, m); reset(max_normal_impulse, m);
  reset(prev_key, m); reset(prev_points, m); reset(prev_feature, m);
  reset(prev_normal_impulse, m); reset(prev_tangent_impulse, m); reset(prev_normal, m);
  reset(prev_anchor_a, m); reset(prev_anchor_b, m); reset(prev_ref_separation, m);
  reset(prev_ref_offset, m); reset(prev_ref_turn_a, m); reset(prev_ref_turn_b, m);
  reset(prev_sep_anchor_a, m); reset(prev_sep_anchor_b, m);
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  reset(body_delta, n); reset(body_inv_inertia_world, D == 3 ? n : 0);
  reset(body_inertia_q, D == 3 ? n : 0);
  reset(body_row_remade, D == 3 ? n : 0);
  for (auto& q : body_inertia_q)  // (not made yet: NaN, which equals no rotation)
    std::fill_n(reinterpret_cast<double*>(&q), sizeof q / sizeof(double), nan);
  reset(vert_world, v); reset(norm_world, v); reset(shape_margin, s); reset(shape_turn, s);
  shape_size.assign(s, 1.0); shape_scale.assign(s, 1.0); body_scale.assign(n, 1.0);
  reset(body_level, n); reset(support, m); reset(prev_support, m); reset(body_load, n);
  reset(body_carried, n);
  reset(shock_side, m);
  reset(shock_order, m); reset(solve_order, m);
  reset(adj_start, n + 1); reset(adj, 2 * m); reset(queue, n + 2);
  reset(bounce_kind, m); reset(body_mark, n); reset(solve_impulse, m);
  reset(step_impulse, m); reset(shock_impulse, m); reset(shock_points, m);
  reset(bounce_list, (P + 1) * m + 2); reset(relax_list, m); reset(body_reach, n);
  reset(overlap_list, m); reset(body_motion, n);
  wave_count = 0;
  waves_valid = false;
  cut_lanes = false;
  impulses_in_lanes = false;
  heavy_on_light = false;
  reset(wave_order, m); reset(manifold_wave, m); reset(body_wave, n);
  reset(wave_start, m + 2); reset(wave_batch, m + 2); reset(wave_single, m + 1);
  reset(wave_single_batch, m + 1); reset(wave_idle, D == 3 ? m + 1 : 0);
  // made by find_waves, as many as a step packs (waves.cpp)
  batches.clear();
  batches3.clear();
  faces3.clear();
  region_count = 1;
  body_region.assign(n, 0);
  const std::size_t segments = static_cast<std::size_t>(constants::SOLVER_REGIONS) * 2 + 2;
  reset(segment_order, segments); reset(segment_wave, segments); reset(segment_shock, segments);
  return !stopped;
}

// Whether point k of manifold m pushed in the step: by the impulse it carried into the
// step (the warm start applies it), in the solver's passes or the restitution stage (an
// impulse that raised its accumulated one: max_normal_impulse), or in the shock pass.
template <int D>
inline bool pushed_in_step(const Contacts<D>& c, std::int64_t m, int k) {
  return c.start_impulse[m][k] > 0.0 || c.max_normal_impulse[m][k] > 0.0 ||
         (c.shock_points[m] >> k & 1u) != 0;
}

template <int D>
bool Contacts<D>::grow(std::int64_t new_capacity, const std::function<bool()>* stop) {
  // never below what last step's manifolds need
  if (new_capacity < count.manifolds_prev) new_capacity = count.manifolds_prev;
  Contacts<D> made;
  if (!made.allocate(static_cast<int>(body_delta.size()), static_cast<int>(shape_margin.size()),
                     static_cast<int>(vert_world.size()), new_capacity, stop))
    return false;
  Contacts<D> old = std::move(*this);
  *this = std::move(made);
  const std::int64_t n = old.count.manifolds_prev;
  count = old.count;
  count.pairs = 0;  // the pair list is found anew, in the room it had
  if (old.pair_capacity() > pair_capacity()) pairs = std::move(old.pairs);
  for (std::int64_t i = 0; i < n; ++i) {
    prev_key[i] = old.prev_key[i];
    prev_points[i] = old.prev_points[i];
    prev_feature[i] = old.prev_feature[i];
    prev_normal_impulse[i] = old.prev_normal_impulse[i];
    prev_tangent_impulse[i] = old.prev_tangent_impulse[i];
    prev_normal[i] = old.prev_normal[i];
    prev_anchor_a[i] = old.prev_anchor_a[i];
    prev_anchor_b[i] = old.prev_anchor_b[i];
    prev_ref_separation[i] = old.prev_ref_separation[i];
    prev_ref_offset[i] = old.prev_ref_offset[i];
    prev_ref_turn_a[i] = old.prev_ref_turn_a[i];
    prev_ref_turn_b[i] = old.prev_ref_turn_b[i];
    prev_sep_anchor_a[i] = old.prev_sep_anchor_a[i];
    prev_sep_anchor_b[i] = old.prev_sep_anchor_b[i];
    prev_support[i] = old.prev_support[i];
  }
  face_world = std::move(old.face_world);
  face_offset = std::move(old.face_offset);
  shape_spread = std::move(old.shape_spread);
  turn_watch = std::move(old.turn_watch);
  shape_size = std::move(old.shape_size);
  shape_scale = std::move(old.shape_scale);
  body_scale = std::move(old.body_scale);
  unit_scale = old.unit_scale;
  record_impulses = old.record_impulses;
  return true;
}

}  // namespace rbsim
