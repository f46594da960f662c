// Tuning constants: each with its unit, a typical value and what changing it does.
// The solver follows the "soft step" design (sub-stepping, soft contact constraints, a
// relax pass, restitution applied last). Values are SI: metres, seconds, radians.
#pragma once

#include <cstdint>

namespace rbsim::constants {

// Contacts closer than this are created before the shapes touch, so that the solver can
// stop an approaching body exactly at the surface (no tunnelling within one step).
// m; typically 4 * LINEAR_SLOP. Larger values create more contacts (slower).
inline constexpr double SPECULATIVE_DISTANCE = 0.02;

// The collision tolerance, m; normally 0.5 cm. Gaps below it count as touching (no
// time-of-impact search); the narrowphase's face tolerance and the thin-segment skin
// scale with it, and pymunk gets it as its collision_slop. The soft contacts push every
// overlap out; they allow none.
inline constexpr double LINEAR_SLOP = 0.005;

// How far a shape's fat box reaches beyond its tight box, m. A shape is queried in the
// broadphase again only once it has moved this far; larger keeps more candidate pairs
// (each costs a box test per step), smaller re-queries moving shapes more often.
inline constexpr double AABB_MARGIN = 0.02;

// Soft contact stiffness, Hz; capped at a quarter of the substep rate (60 Hz at dt 1/60
// with 4 substeps). A contact under load F between bodies of effective mass m settles at
// an overlap F / (m (2π hertz)²): at 30 Hz a stack of 15 unit boxes sags 7 cm, at 60 Hz
// 2 cm. The two-point block solve and the shock pass keep large mass ratios stable at
// this stiffness; without them it was 30 Hz at most.
inline constexpr double CONTACT_HERTZ = 60.0;

// Soft contact damping ratio, dimensionless. 10 = heavily over-damped: overlaps are
// removed without bounce.
inline constexpr double CONTACT_DAMPING_RATIO = 10.0;

// Fastest speed at which the soft contacts push an overlap out, m/s (bounded push-out).
inline constexpr double CONTACT_PUSH_MAX_VELOCITY = 3.0;

// An overlap deeper than this (m, 4 * LINEAR_SLOP) is being pushed out, not resting:
// while one exists the contacts around it get DEEP_RELAX_FACTOR times as many relax
// passes, so that the push-out velocity is taken back through a whole stack instead of
// adding up from row to row. Resting contacts overlap by millimetres and never pay it.
inline constexpr double DEEP_OVERLAP = 0.02;
inline constexpr int DEEP_RELAX_FACTOR = 4;
// "Around it": the contacts of the dynamic bodies within this many contacts of a deep
// overlap. 8 reaches past the 3 extra passes' own reach; on a stack of 30 with a deep
// overlap at the bottom the top box's peak speed moved from 0.71 to 0.73 m/s.
inline constexpr int DEEP_RELAX_REACH = 8;

// Deepest overlap with a static or kinematic body left to the soft contacts, m; beyond
// it the body is moved out directly (limit_static_overlap). Bodies resting on static
// ground overlap it by well under a millimetre; 4 * LINEAR_SLOP acts only when a pile
// under pressure outruns the bounded push-out speed.
inline constexpr double STATIC_OVERLAP_LIMIT = 0.02;

// A body that has moved less than this since its contacts were computed keeps them: the
// narrowphase is skipped for pairs of such bodies and their manifolds are carried
// forward (separations updated from the motion). m and rad; the geometry error this
// allows (1e-4 m in a lever arm, 1e-4 rad in a normal) is far below LINEAR_SLOP. Zero
// turns the reuse off.
inline constexpr double STILL_DISTANCE = 1.0e-4;
inline constexpr double STILL_ANGLE = 1.0e-4;

// Passes of the restitution stage over a cluster of bounces that share bodies: each
// pass bounces every pair that still approaches. A row of n touching balls struck at
// one end needs up to n - 1; a ball wedged between two walls would bounce for ever, and
// after this many passes its approach is left to the next substep's solve.
inline constexpr int RESTITUTION_PASSES = 16;

// Time of impact by conservative advancement: stop when the gap is below TOI_TOLERANCE
// (m) or after TOI_ITERATIONS advancements (each one narrowphase call, for approaching
// speculative pairs only). Within TOI_FINISH (m) an impact just after the step is taken
// at its end.
inline constexpr double TOI_TOLERANCE = 1.0e-9;
inline constexpr int TOI_ITERATIONS = 12;
inline constexpr double TOI_FINISH = 1.0e-6;

// Narrowphase: a reference face is preferred unless another is deeper by more than
// this, m (0.1 * LINEAR_SLOP: faces of a resting box do not flicker); a segment is
// given this skin when clipped, m; lengths below LINEAR_EPSILON (m) are degenerate.
inline constexpr double REFERENCE_FACE_TOLERANCE = 0.1 * LINEAR_SLOP;
inline constexpr double SEGMENT_SKIN = LINEAR_SLOP;
inline constexpr double LINEAR_EPSILON = 1.0e-9;

// Shock pass: a contact counts as support when its normal is within this cosine of the
// vertical (about 45 degrees); steeper faces are solved normally. Approach speeds below
// SHOCK_MIN_APPROACH (m/s) are left to the ordinary solve (1 mm/s closes 4 µm in a
// substep) and cost no pass.
inline constexpr double SHOCK_COS = 0.7071;
inline constexpr double SHOCK_MIN_APPROACH = 1.0e-4;

// Broadphase grid: cell size in median half-diagonals (plus two fat margins); hash
// buckets per shape, at least; shapes made big (tested against every shape) while a
// wider cut allows; a shape wider than BIG_CELLS_MAX cells is always big; bits of a pair
// key sorted per radix pass; fewer new keys than INSERTION_SORT_MAX are sorted by
// insertion.
inline constexpr double CELL_SIZES = 4.0;
inline constexpr int TABLE_PER_SHAPE = 2;
inline constexpr int BIG_MAX = 16;
inline constexpr double BIG_CELLS_MAX = 16.0;
inline constexpr int RADIX_BITS = 8;
inline constexpr int INSERTION_SORT_MAX = 32;

// |x| below which the integrator's atan series is used: its first omitted term, x^19/19,
// is then below 1e-18 of x, far under double rounding.
inline constexpr double ATAN_SERIES_MAX = 0.1;

}  // namespace rbsim::constants
