// Every stage of the step, declared once. step.cpp is the only file that orders them;
// each is defined in the source file named beside it and instantiated there for the
// dimensions it serves.
#pragma once

#include <cstdint>
#include <string>

#include "constants.hpp"
#include "contacts.hpp"
#include "grid.hpp"
#include "model.hpp"
#include "state.hpp"
#include "types.hpp"

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
  Soft soft_static;               // contacts with a static or kinematic body (stiffer)
};

// The soft contacts of config's substep h = dt / substeps: CONTACT_HERTZ, capped at a
// quarter of the substep rate, for contacts between dynamic bodies; twice that for
// contacts with a static or kinematic body; damping ratio CONTACT_DAMPING_RATIO.
void set_contact_softness(Config& config);

// collide/transform.cpp: world vertices and normals of every shape, each shape's
// speculative reach dt (|v| + |ω| r), and which bodies are still near their reference pose.
template <int D>
void transform_shapes(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      double dt);

// collide/transform.cpp: each convex shape's hull topology from model.face_local (once,
// when a 3D world is built), and the rows of Contacts::face_world they need. Returns
// false with a message in *error when a convex shape's triangles do not close a convex
// surface (the shape's vertex and triangle ranges must already be checked).
bool build_shape_hulls(Model<3>& model, std::string* error);

// collide/broadphase.cpp: update contacts.pairs (sorted by (a, b), a < b) from the
// shapes' boxes; returns the pair count, which exceeds the capacity when the store must
// grow (the list is then invalid).
template <int D>
std::int64_t find_pairs(const Model<D>& model, Grid<D>& grid, Contacts<D>& contacts);

// contact/manifold.cpp: narrowphase (time of impact for fast speculative pairs) for the
// first n_pairs pairs, warm-start matching against last step's manifolds, carried
// manifolds for still bodies.
template <int D>
void update_manifolds(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      const Grid<D>& grid, std::int64_t n_pairs, MixRule friction_rule,
                      MixRule restitution_rule, double dt);

// contact/store.cpp: this step's manifolds become last step's (for warm starting).
template <int D>
void store_impulses(Contacts<D>& contacts);

// solver/prepare.cpp: effective masses, approach velocities and softness into the rows:
// config's soft and soft_static, or stiffer for small shapes (STIFFNESS_LENGTH), and each
// manifold's push-out speed and deep-overlap depth (SCALE_LENGTH).
template <int D>
void prepare_contacts(const Model<D>& model, const State<D>& state, Contacts<D>& contacts,
                      const Config& config);

// solver/shock.cpp: support levels and the solve order; returns the shock pass's count.
template <int D>
std::int64_t support_order(const Model<D>& model, Contacts<D>& contacts);

// solver/waves.cpp: the waves of the solve order (manifolds that share no dynamic body,
// solved at once with the result of solving them in solve order) into contacts.wave_order
// and contacts.batches; returns the number of waves.
template <int D>
std::int64_t find_waves(const Model<D>& model, Contacts<D>& contacts);

// solver/shock.cpp: the manifolds within `reach` contacts of a deep overlap, written to
// contacts.relax_list; returns their count.
template <int D>
std::int64_t deep_region(const Model<D>& model, Contacts<D>& contacts, int reach);

// solver/shock.cpp: one pass from the ground up, the supporting body held still; a point
// approaching slower than min_approach (m/s) is left alone.
template <int D>
void propagate_shock(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                     std::int64_t n_order, double inv_h, double threshold,
                     double min_approach = constants::SHOCK_MIN_APPROACH);

// dynamics/integrate.cpp: v += h (g + F/m), angular from torque, then damping.
template <int D>
void integrate_velocities(const Model<D>& model, State<D>& state, double h);

// dynamics/integrate.cpp: x += h v, q turned by ω h (exact) or the notes' update;
// delta accumulates each body's motion since the step's start.
template <int D>
void integrate_positions(const Model<D>& model, State<D>& state,
                         std::vector<BodyDelta<D>>& delta, double h, Rotation rotation);

// solver/warm_start.cpp: last substep's accumulated impulses applied again.
template <int D>
void warm_start(const Model<D>& model, State<D>& state, Contacts<D>& contacts);

// solver/warm_start.cpp: the same, wave by wave, LANES manifolds at a time (the step's).
template <int D>
void warm_start_waves(const Model<D>& model, State<D>& state, Contacts<D>& contacts);

// solver/solve.cpp: one pass of sequential impulses over order[0..n): with the soft
// bias (use_bias, the solve stage) or without (the relax stage). inv_h: 1/substep (1/s);
// shift: h in the relax stage of symplectic Euler (s); threshold (m/s).
template <int D>
void solve_contacts(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                    double inv_h, bool use_bias, double shift, double threshold,
                    const std::int32_t* order, std::int64_t n);

// solver/solve.cpp: the same pass over the solve order, wave by wave: a wave's two-point
// manifolds LANES at a time (contacts.batches), its one-point manifolds one by one.
template <int D>
void solve_waves(const Model<D>& model, State<D>& state, Contacts<D>& contacts, double inv_h,
                   bool use_bias, double shift, double threshold);

// solver/restitution.cpp: keep each point's impulse at the position update (scenes with
// elastic materials), and the restitution stage itself.
template <int D>
void keep_solve_impulses(Contacts<D>& contacts);
template <int D>
void apply_restitution(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                       double threshold, double h, double sign);

// solver/overlap_limit.cpp: a body deeper than max_overlap (m; times the contact's scale,
// SCALE_LENGTH) in a static or kinematic body is moved out directly.
template <int D>
void limit_static_overlap(const Model<D>& model, State<D>& state, Contacts<D>& contacts,
                          double max_overlap);

}  // namespace rbsim
