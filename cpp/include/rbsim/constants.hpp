// Tuning constants: each with its unit, a typical value and what changing it does.
// The solver follows the "soft step" design (sub-stepping, soft contact constraints, a
// relax pass, restitution applied last). Values are SI: metres, seconds, radians.
#pragma once

#include <cstdint>

namespace rbsim::constants {

// Contacts at every scale. The contact tolerances below (LINEAR_SLOP and what follows
// it, SPECULATIVE_DISTANCE, AABB_MARGIN, DEEP_OVERLAP, STATIC_OVERLAP_LIMIT, IMPACT_GAP,
// STILL_DISTANCE, TOI_TOLERANCE, TOI_FINISH) are their values for shapes of SCALE_LENGTH
// and larger, m (a shape's size: the half diagonal of its bounding box, radius
// included). A contact between smaller shapes takes each times s = (the smaller shape's
// size) / SCALE_LENGTH, and the push-out speed CONTACT_PUSH_MAX_VELOCITY times sqrt(s); a
// body is still within STILL_DISTANCE times its smallest shape's s. 0.1: every shape of
// 10 cm or more (a 14 cm box) is as before; a 2 mm box has a slop of 71 µm.
inline constexpr double SCALE_LENGTH = 0.1;

// CONTACT_HERTZ is the stiffness of contacts between shapes of STIFFNESS_LENGTH and
// larger, m (a 1 m box's size); smaller ones are stiffer by sqrt(STIFFNESS_LENGTH / size)
// (still capped at a quarter of the substep rate), so that a pile of small boxes sinks
// into itself, relative to its size, as a pile of 1 m boxes does (a contact under load F
// overlaps by F / (m (2π hertz)²), and a small box's weight over its mass is the same g).
// At dt 1/60 and 4 substeps the cap holds every contact at 60 Hz, as before.
inline constexpr double STIFFNESS_LENGTH = 0.7071067811865476;

// Contacts closer than this are created before the shapes touch, so that the solver can
// stop an approaching body exactly at the surface (no tunnelling within one step).
// m (times a small pair's scale, SCALE_LENGTH); typically 4 * LINEAR_SLOP. Larger values
// create more contacts (slower).
inline constexpr double SPECULATIVE_DISTANCE = 0.02;

// The collision tolerance, m (times a small pair's scale, SCALE_LENGTH); normally 0.5 cm,
// 71 µm between 2 mm boxes. Gaps below it count as touching (no
// time-of-impact search); the narrowphase's face tolerance and the thin-segment skin
// scale with it, and pymunk gets it as its collision_slop. The soft contacts push every
// overlap out; they allow none.
inline constexpr double LINEAR_SLOP = 0.005;

// How far apart two faces of static shapes may lie and still be flush, m (times the
// smaller shape's scale, SCALE_LENGTH): a floor or wall of static pieces whose faces
// meet within it is one surface, and what crosses its joints is not caught there
// (find_covered_faces, pushes_from_covered). Normally 0.5 mm, a tenth of LINEAR_SLOP:
// pieces placed by hand to three decimals, or turned by angles, meet within it. Larger
// takes real steps and gaps for joints; smaller, misfits for steps.
inline constexpr double FLUSH_DISTANCE = 0.0005;
// The smallest contact scale (SCALE_LENGTH: a pair's smaller shape's half diagonal over
// 10 cm) at which flush pieces' joints are one surface; dimensionless. Smaller pairs
// rest deeper than their slop at the usual step (69 µm under gravity at 1/240 s), and
// their joints catch as if the pieces were apart. Smaller takes joints for one surface
// among millimetre parts, where bodies then sped up and fell through 1 mm tiles.
inline constexpr double COVERED_MIN_SCALE = 0.05;

// How far a shape's fat box reaches beyond its tight box, m (times a small shape's scale,
// SCALE_LENGTH). A shape is queried in the
// broadphase again only once it has moved this far; larger keeps more candidate pairs
// (each costs a box test per step), smaller re-queries moving shapes more often.
inline constexpr double AABB_MARGIN = 0.02;
// A moving shape's fat box also reaches this many of its last step's displacements ahead,
// along each axis it moved on (broadphase.cpp), at most FAT_AHEAD_SIZE of its width on
// that axis (dimensionless both): a falling shape is queried again every few steps
// instead of every step. Larger reaches keep more candidate pairs and widen every query.
inline constexpr double FAT_AHEAD_STEPS = 4.0;
inline constexpr double FAT_AHEAD_SIZE = 0.5;
// A shape that moved less than FAT_REST fat margins along every axis in its last step is
// at rest: one whose fat box reaches ahead of it is queried again with a plain one (a
// settled pile keeps no candidate pairs from its fall). Dimensionless.
inline constexpr double FAT_REST = 0.25;

// Soft contact stiffness, Hz; capped at a quarter of the substep rate (60 Hz at dt 1/60
// with 4 substeps). A contact under load F between bodies of effective mass m settles at
// an overlap F / (m (2π hertz)²): at 30 Hz a stack of 15 unit boxes sags 7 cm, at 60 Hz
// 2 cm. The two-point block solve and the shock pass keep large mass ratios stable at
// this stiffness; without them it was 30 Hz at most. A contact with a static or kinematic
// body is twice as stiff, within the same cap (step.cpp, set_contact_softness): at twice
// the cap, 120 Hz at 4 substeps of 1/60 s, the floor and walls under a pile of 600 boxes
// helped hold overlaps of up to 10 cm between the boxes (docs/design.md, "Overlaps that
// walk down a column").
inline constexpr double CONTACT_HERTZ = 60.0;

// Soft contact damping ratio, dimensionless. 10 = heavily over-damped: overlaps are
// removed without bounce.
inline constexpr double CONTACT_DAMPING_RATIO = 10.0;

// Fastest speed at which the soft contacts push an overlap out, m/s (bounded push-out);
// times the square root of a small pair's scale (SCALE_LENGTH): 0.36 m/s for 2 mm boxes.
inline constexpr double CONTACT_PUSH_MAX_VELOCITY = 3.0;

// A 3D manifold (a face, or one point) is idle, and a pass leaves it as it is, when each point
// holds an impulse worth less than this speed (m/s: λ times the point's normal row K,
// the speed the impulse gives; its friction likewise), and the pass would ask it for
// less (the normal speed it would remove). Bricks side by side in a resting wall hold
// impulses of round-off (1e-16 N·s) that made every pass solve them: half of a wall's
// faces; in a heap, half the one-point contacts are speculative (neighbours not yet
// touching) and hold nothing. The contact's speed error this allows, 1e-10 m/s, does not
// add up from pass to pass (a contact asked for more is solved) and is far below any
// scene's speeds (gravity gives 0.04 m/s in a step of 1/240 s), and far above round-off.
// Zero: only contacts that hold nothing and are asked nothing are left (the answer of
// their solve is exactly zero).
inline constexpr double IDLE_SPEED = 1.0e-10;
// In 2D a batch of four manifolds is idle only when none holds anything and none is asked
// anything (exactly: its pass would change nothing); find_waves packs those that held
// nothing at the step's start together, and packs the waves again once more than one in
// IDLE_SPOILED of those batches holds an impulse (dimensionless; each such batch is
// solved in full). Smaller packs again more often: in a settled base-40 pyramid a few
// contacts a step start or stop holding an impulse, and packing every step cost 30 µs
// more than it saved.
inline constexpr std::int64_t IDLE_SPOILED = 8;
// In 2D the batches hold the impulses through the passes (waves.cpp, take_impulses); a
// stage that reads or writes some manifolds' (the restitution stage's list, the region of
// a deep overlap) is handed those alone, unless they are more than one in HANDOVER_WHOLE
// of the manifolds: then all, in batch order (dimensionless; one manifold looked up alone
// costs about what two do in order).
inline constexpr std::int64_t HANDOVER_WHOLE = 2;
// In 3D the faces (manifolds of two to four points) of a wave that hold an impulse go
// into lanes, four of one point count at a time; a batch that would hold fewer than this
// many (the last of a run) is solved one manifold at a time instead: packing a face costs
// about what solving it on its own a few times does (dimensionless, 1 to LANES)
inline constexpr std::int64_t FACE_LANES_MIN = 3;

// An overlap deeper than this (m, 4 * LINEAR_SLOP; scaled as it) is being pushed out, not
// resting, unless neither body has moved in the step (STILL_DISTANCE, STILL_ANGLE: a
// circle wedged deep in a settled pile): while one exists the contacts around it get
// DEEP_RELAX_FACTOR times as many relax passes, so that the push-out velocity is taken
// back through a whole stack instead of adding up from row to row. Resting contacts
// overlap by millimetres and never pay it.
inline constexpr double DEEP_OVERLAP = 0.02;
inline constexpr int DEEP_RELAX_FACTOR = 4;
// "Around it": the contacts of the dynamic bodies within this many contacts of a deep
// overlap. 8 reaches past the 3 extra passes' own reach; on a stack of 30 with a deep
// overlap at the bottom the top box's peak speed moved from 0.71 to 0.73 m/s.
inline constexpr int DEEP_RELAX_REACH = 8;
// A deep overlap still closing faster than this after the solve pass, m/s (the default
// restitution threshold: it is being driven in as by an impact), has the contacts around
// it solved again without the bias, pass after pass until none closes that fast, before
// the biased pass of the deep solve (step.cpp, deep_solve); at most DEEP_SOLVE_PASSES - 1
// such passes. A heavy ball driving a row of light boxes into each other squeezed two of
// them 8.2 cm together at dt 1/60 in one biased pass (pymunk: 5.4 cm), 3.8 cm with these.
// Lower speeds or more passes run them in more substeps of a settled pile, for little:
// its overlaps are held by loads, not driven in.
inline constexpr double DEEP_CLOSING_SPEED = 1.0;
inline constexpr int DEEP_SOLVE_PASSES = 16;

// Deepest overlap with a static or kinematic body left to the soft contacts, m (scaled as
// LINEAR_SLOP); beyond
// it the body is moved out directly (limit_static_overlap). Bodies resting on static
// ground overlap it by well under a millimetre; 4 * LINEAR_SLOP acts only when a pile
// under pressure outruns the bounded push-out speed.
inline constexpr double STATIC_OVERLAP_LIMIT = 0.02;
// And where the step drove a shape in, at most this fraction of its depth (its radius,
// or a polygon's least distance from its middle to a face; never below LINEAR_SLOP,
// scaled): a capsule 3 cm thick lying in a corner, pushed 1.5 cm into the floor by a
// body landing on it (2 cm of overlap were allowed for its 16 cm length), had its core at
// the floor's surface; the wall's bottom face then met it from above, and the two
// squeezed it out under the wall at 14 m/s. Dimensionless.
inline constexpr double OVERLAP_DEPTH_FRACTION = 0.5;

// The continuous sweep (collide/continuous.cpp): a body whose motion in the step went
// further than its contacts reached at the step's start by more than this fraction of its
// inner size (the least distance from its shapes' centres to their surfaces) is swept
// against the static shapes, and put back where it first met one it then went on into by
// more than the same fraction. Within it push-out still returns a body to the side it
// came from.
// Dimensionless; 0.5 is Box2D v3's choice for its fast bodies. Larger sweeps fewer bodies
// and lets them deeper; smaller sweeps more, for nothing until it nears a slop.
inline constexpr double CONTINUOUS_FRACTION = 0.5;

// Deepest overlap between two dynamic bodies left at a step's end, m (2 * LINEAR_SLOP,
// scaled as it); beyond it both are moved apart along the contact normal, each by its
// share of the inverse mass, their velocities untouched (limit_dynamic_overlap), in up to
// OVERLAP_LIMIT_PASSES passes over the pairs that were that deep (a body wedged between
// two others is moved back and forth). The soft contacts hold a resting load well above
// it (a box on one 100 times lighter, 7 mm at dt 1/60; CRUSH_RATIO), but not a wedge:
// in 600 boxes piled 25 high, boxes jammed between a wall and their neighbours, or
// between two columns, held overlaps of 2 to 7 cm step after step (pymunk: 1 to 1.5 cm),
// and each one kept the deep passes (DEEP_OVERLAP) running. Larger leaves such jams
// deeper; smaller acts on resting loads. Dimensionless passes: 4 takes a jam of three.
inline constexpr double DYNAMIC_OVERLAP_LIMIT = 0.01;
inline constexpr int OVERLAP_LIMIT_PASSES = 4;

// A pair of bodies that has moved less than STILL_DISTANCE one against the other since
// its contact was computed, neither turning more than STILL_ANGLE, keeps it: the
// narrowphase is skipped and the manifold carried forward (separations updated from the
// relative move; a move of the two together changes nothing in it). m (times the smaller
// body's smallest shape's scale, SCALE_LENGTH) and rad; the geometry error this allows
// (1e-4 m in a lever arm, 1e-4 rad in a normal) is far below LINEAR_SLOP. Zero turns the
// reuse off.
inline constexpr double STILL_DISTANCE = 1.0e-4;
inline constexpr double STILL_ANGLE = 1.0e-4;

// An impact that engaged at a gap (a speculative push stops a fast body one substep
// from what it hits) is resolved, bounce and friction, once the gap has closed to this,
// m (0.25 * LINEAR_SLOP, scaled as it): no body bounces back from, or stops short of, a
// wall it has not reached by more. Larger resolves impacts earlier, further from the surface;
// smaller keeps more of them waiting for another substep.
inline constexpr double IMPACT_GAP = 0.25 * LINEAR_SLOP;

// Passes of the restitution stage over a cluster of bounces that share bodies: each
// pass bounces every pair that still approaches. A row of n touching balls struck at
// one end needs up to n - 1; a ball wedged between two walls would bounce for ever, and
// after this many passes its approach is left to the next substep's solve.
inline constexpr int RESTITUTION_PASSES = 16;

// Time of impact by conservative advancement: stop when the gap is below TOI_TOLERANCE
// (m) or after TOI_ITERATIONS advancements (each one narrowphase call, for approaching
// speculative pairs only). Within TOI_FINISH (m) an impact just after the step is taken
// at its end. Both times a small pair's scale (SCALE_LENGTH).
inline constexpr double TOI_TOLERANCE = 1.0e-9;
inline constexpr int TOI_ITERATIONS = 12;
inline constexpr double TOI_FINISH = 1.0e-6;
// In 3D the search's faster trial steps (toi.cpp) reach no further than the bound on the
// closing speed can close the gap plus this, m (0.2 * LINEAR_SLOP, scaled as it): the
// most two shapes can overlap along the normal before a trial. Larger lets trials reach
// further ahead; a shape thinner than it could be passed through.
inline constexpr double TOI_OVERLAP = 0.2 * LINEAR_SLOP;
// In 2D a pair whose bodies turn by more than this within the step together (rad,
// (|ω_a| + |ω_b|) dt) is searched for its time of impact by the bound on any point's
// approach, as in 3D; a slower one by its nearest point's own approach, which a turn that
// fast carries past the impact (a capsule 15 cm long at 51 m/s and 106 rad/s, 1.8 rad a
// step at dt 1/60, was found on the far side of a wall 5 cm thick and pushed out there),
// and which for slower turns is what the scenes and hard cases were tuned on (with the
// bound for every pair, the 2D manifold stage cost 4 - 8% more on piles, and 20 spinning
// boxes bouncing elastically in a box lost energy without an overlap in one rounding).
// Typical 0.25 (a body at 15 rad/s and dt 1/60); lower searches more pairs by the bound.
inline constexpr double TOI_FAST_TURN = 0.25;

// Narrowphase: a reference face is preferred unless another is deeper by more than
// this, m (0.1 * LINEAR_SLOP: faces of a resting box do not flicker), and in 3D an
// incident corner this close outside a reference face's side plane is kept unclipped
// (flush faces keep their corner ids, so their warm start); a segment is
// given this skin when clipped, m (both scaled as LINEAR_SLOP); lengths below
// LINEAR_EPSILON (m) are degenerate.
inline constexpr double REFERENCE_FACE_TOLERANCE = 0.1 * LINEAR_SLOP;
// Warm start in 3D: a contact point with a new feature id takes over the impulses of
// last step's nearest point of its manifold that no id matched within this distance,
// m (LINEAR_SLOP, scaled as it: a face's corner cut into clipped points keeps its own
// load; what is left is shared out over the manifold, contact/manifold.cpp).
inline constexpr double WARM_MATCH_DISTANCE = LINEAR_SLOP;
inline constexpr double SEGMENT_SKIN = LINEAR_SLOP;
inline constexpr double LINEAR_EPSILON = 1.0e-9;

// Shock pass: a contact counts as support when its normal is within this cosine of the
// vertical (about 45 degrees); steeper faces are solved normally. Approach speeds below
// SHOCK_MIN_APPROACH (m/s) are left to the ordinary solve (0.1 mm/s closes 0.4 µm in a
// substep of 1/240 s) and cost no pass; in 3D, unless a heavy body rests on a light one
// (HEAVY_RATIO), so are those below one substep of gravity, |g| h (step.cpp).
inline constexpr double SHOCK_COS = 0.7071;
inline constexpr double SHOCK_MIN_APPROACH = 1.0e-4;
// In 3D a body held by two supporters or more, this many contacts above the ground (its
// support level) or higher, has every approach taken out in the shock pass, however slow:
// what the relax pass leaves of the solve's push-outs adds up in a tall structure, and
// left to the soft contacts it drove a slender tower's rocking (a Jenga tower of 10 layers
// or more at dt 1/60 swayed ever wider and fell, with more energy than it started with).
// A column of single bodies does not rock so (a stack of 10 boxes stands still without
// it). Dimensionless; 4 holds towers of 10 – 30 layers within millimetres; higher costs
// less in deep heaps and holds fewer (at 6 a tower of 10 layers sways 13 mm; at 8, 32 mm).
inline constexpr int SHOCK_TALL_LEVEL = 4;

// A contact holds its bodies up (counts for the support levels, shock.cpp) while a point
// of it is within this gap at the step's start, m (times the pair's scale): far below
// the gaps of speculative contacts that matter (a ball on a 1 cm plate is 1 cm from the
// ground), above the soft contacts' flicker about zero at rest. Larger values count more
// near misses as support (the plate's ball then stood on the ground too: see shock.cpp).
inline constexpr double SUPPORT_GAP = 0.1 * LINEAR_SLOP;

// Mass ratio of a heavy body resting on a light dynamic one, dimensionless: while a step
// has a supported body at least this many times heavier than its (dynamic) supporter,
// the shock pass also runs before the positions move (step.cpp), so that the light body,
// kicked about in the one solve pass by impulses far above its mass, does not let the
// heavy one sink through it (a 100 kg box on a 0.01 kg one sank into it 0.5 mm a step,
// 33 cm in all). Smaller ratios are solved as before; lower values run the extra pass in
// more scenes (one pass over the supported contacts per substep).
inline constexpr double HEAVY_RATIO = 10.0;

// Ratio of the load a body bears (its mass and what rests on it, shock.cpp's body_load)
// to the mass of the lighter of it and its (dynamic) supporter, dimensionless, past which
// the load crushes: while a heavy body rests on a light one, the shock pass then takes
// out its approach however slow (3D: in the pass before the positions move, which in 2D
// takes every approach anyway) and however elastic (2D and 3D: an impact is otherwise
// the restitution stage's). Below it the soft contacts carry a load, and hold a box on
// one r times lighter about r × 0.07 mm deep at dt = 1/60 (7 mm at 100); above it they
// could not: a 100 kg box sank into a 0.01 kg one at 3.6 cm/s without end, and a 6 t slab
// dropped on a 16 kg box (e = 0.2) knocked it into the ground and went through it. Lower
// values take more loads out in the pass (a 100:1 box on a pyramid, all of its load taken
// so, rocked at 1 cm/s: the pass and the contacts' warm start shared it).
inline constexpr double CRUSH_RATIO = 150.0;

// Ratio of the load a body bears (shock.cpp's body_load) to the mass of the lighter of it
// and its supporter, dimensionless, up to which a support's friction is bounded through
// the passes by the weight it carries (friction_loads), typically 50. Beyond it the rest
// of the load's friction is the shock pass's (shock_friction): in the passes a light body
// between two large friction forces is pulled to and fro (at 150, a 100 kg box sliding on
// two stacked 1 kg plates reached 2.7 times its kinetic energy; without a bound, a 1 kg
// plate under 1000 kg 4 times). Lower values hand more of the friction to the shock pass,
// which holds the supporter still (at 20 a 100 kg box on a 2 kg plate, sliding, ran 20%
// past Coulomb's stop); higher ones bring the passes' instability back.
inline constexpr double FRICTION_LOAD_RATIO = 50.0;

// Broadphase grid: cell size in median half-diagonals (plus two fat margins); hash
// buckets per shape, at least; shapes made big (tested against every shape) while a
// wider cut allows; a shape wider than BIG_CELLS_MAX cells is always big; bits of a pair
// key sorted per radix pass; fewer new keys than INSERTION_SORT_MAX are sorted by
// insertion.
inline constexpr double CELL_SIZES = 4.0;
// In space a query reads a block of cells, not a strip: cells of CELL_SIZES_3D median
// half-diagonals (a ball's diameter at 2) test fewer entries per query.
inline constexpr double CELL_SIZES_3D = 2.0;
inline constexpr int TABLE_PER_SHAPE = 2;
inline constexpr int BIG_MAX = 16;
inline constexpr double BIG_CELLS_MAX = 16.0;
inline constexpr int RADIX_BITS = 8;
inline constexpr int INSERTION_SORT_MAX = 32;

// The most contact pairs (shape pairs whose fat boxes overlap) one step may hold: at most
// PAIRS_PER_SHAPE per shape plus PAIRS_FLOOR, and at most PAIR_WORK_MAX (2D) or
// PAIR_WORK_MAX_3D over substeps x iterations (World::pair_limit). A pile has 2 to 6
// pairs per shape (a face-centred pile of spheres 7); far more mean shapes pressed into
// one another (a pile crushed by a huge gravity, where every pair of n shapes overlaps),
// which the step cannot resolve. Beyond the limit advance takes no step and returns
// TooManyPairs, so that memory (about 1.5 KB per pair of storage in 2D) and the step's time
// stay bounded: a step within the work bound takes about a second at most. Raising them
// lets such a step run, slowly and with gigabytes; lowering them below 8 per shape can stop
// a dense pile that would have run.
inline constexpr std::int64_t PAIRS_PER_SHAPE = 32;
inline constexpr std::int64_t PAIRS_FLOOR = 65536;
inline constexpr double PAIR_WORK_MAX = 8.0e6;
inline constexpr double PAIR_WORK_MAX_3D = 1.0e6;

// Stopping a long step (World::interrupt). A step that may take STEP_STOP_SECONDS or more
// is asked inside too, between its substeps, so that Ctrl-C stops it within a second; a
// step stopped there leaves the world torn (partway through it: World::torn), whose run
// ends. s, typically 0.25: shorter steps finish first and stop between two steps, whole
// (the binding asks every 20 ms); lower values tear more runs that would have stopped
// whole a moment later. A step "may take" that long when the last one did, when the
// contact store grew for it, or, before any step, when the work bound (pair limit x
// substeps x iterations x STEP_SECONDS_PER_PAIR) says it could.
inline constexpr double STEP_STOP_SECONDS = 0.25;
// s per contact pair per iteration of a substep, an upper estimate (about 0.1 us measured in
// a crushed 2D pile, 1 us in 3D) for the first step's bound above.
inline constexpr double STEP_SECONDS_PER_PAIR = 0.25e-6;
inline constexpr double STEP_SECONDS_PER_PAIR_3D = 2.0e-6;

// |x| below which the integrator's atan series is used: its first omitted term, x^19/19,
// is then below 1e-18 of x, far under double rounding.
inline constexpr double ATAN_SERIES_MAX = 0.1;

// Threads (solver.threads; step.cpp, solver/regions.cpp, tools/pool.cpp).
// The solver's passes split the dynamic bodies into SOLVER_REGIONS regions, strips of
// equal body count across gravity, fixed whatever the number of threads (so the result
// is the same for every thread count): each region's manifolds are solved in its own
// support order, the regions at once, then the few manifolds that join two regions.
// Dimensionless, typically 2 (one cut: the fewest joining manifolds, which a pass solves
// after the regions, out of the ground-first order; more regions keep more threads busy
// and cut more load paths). Must be even (regions.cpp pairs neighbouring strips).
inline constexpr int SOLVER_REGIONS = 2;
// Dynamic bodies per region at least, typically 256: a scene with fewer than
// SOLVER_REGIONS times this many is one region, solved exactly as on one thread. (Measured
// on one thread, quiet machine: the split costs more than a second thread gives back
// today, 16 pyramids 0.36x -> 0.80x pymunk; 4096 avoided that, but came too late in the
// session to be checked from a fresh clone.)
inline constexpr int REGION_MIN_BODIES = 256;
// Items (bodies, shapes, manifolds, pairs) per task of a stage split over the pool,
// typically 128; a stage with fewer than two tasks' worth runs on the caller. Smaller
// values balance the threads better and pay more task overhead.
inline constexpr int TASK_ITEMS = 128;
// 3D: the most a body turns in one substep, rad (its ω is held to MAX_ROTATION / h, L with
// it, at each substep's start); typically π/4, Box2D's bound. The contacts are made at the
// step's start and solved with the step's start's tensors: a body turning further within
// the step is not what they describe, and its ω far from its principal axes swings its
// kinetic energy up through the rotation update (a 2.5 cm capsule landing on one end at 7
// m/s spun up to 4000 rad/s, 17 rad a substep, and gained 20 times its energy). Larger
// lets faster spins through unresolved; smaller clips spins a step could resolve (a top
// at 150 rad/s turns 0.16 rad a substep at dt 1/240).
inline constexpr double MAX_ROTATION = 0.7853981633974483;
// 3D: how far a body may turn within a step before the rows of its contacts are made
// again at its rotation now (refresh_turned_rows), as the turn weighted by how far its
// inertia is from round: (1 - I_min / I_max) times the angle (rad) since its rows' tensors
// were made. The rows' effective masses, and the passes' response to their impulses, take
// the tensors of the step's start, while the position update makes ω from L through the
// tensor at the rotation now; for a needle turned half a radian the two disagree by orders
// of magnitude along its axis (a 1.6 cm needle thrown spinning onto the floor at dt 1/60
// gained 390 times its energy, a 26 cm stick 49 times). A round body (a sphere, a cube)
// never needs it, nor a body within ROW_TURN_MAX / 2 of round. Typically 0.2: the needles
// above kept their energy at up to 0.8, and at 1.6 a capsule needle gained 96 times again;
// smaller remakes the rows of tumbling bodies more often (at 0.05 the bench's heaps of
// capsules and pebbles had some remade, 2% of the capsules' substeps, for no gain seen).
inline constexpr double ROW_TURN_MAX = 0.2;

// µs a worker spins for the next parallel stage before it sleeps, typically 1000: the
// serial stages between two parallel ones take up to some hundred µs in a pile of a
// thousand bodies, and a worker woken from its sleep came tens of µs late, every step (at
// 50, 3 sleeps a step: 1000 circles 330 -> 288 µs a step on two threads, pyramid-40 750 ->
// 733). Longer spins only burn a core between advance calls.
inline constexpr int POOL_SPIN_MICROSECONDS = 1000;

// Threads chosen as the run goes (Config::choose_threads: solver.threads not set): the
// step runs on one thread or on all of config.threads, whichever a trial timed faster
// (rbsim/pool.hpp, ThreadChoice). A trial is 4 blocks of THREAD_TRIAL_BLOCK steps, one
// thread and all in turn (a scene that grows or settles drifts both ways alike); the
// first after THREAD_TRIAL_FIRST_SECONDS of stepping, the next 4 times that after it,
// each wait twice the last up to THREAD_TRIAL_EVERY_SECONDS (a scene changes most as it
// starts: its bodies fall, then pile up; 1000 spheres poured into a box ran their first
// second on two threads, chosen as they fell, where one was 15% faster once they piled).
// The cost of the two threads' hand-offs varies with the host too: on the machines rbsim
// is measured on, two threads ran a pile 1.3x faster than one in some minutes and 2x
// slower in others. Steps, typically 4: fewer time single steps, which vary more; more
// spend longer on the slower choice. Seconds, typically 0.05 and 1: a trial costs at most
// half its steps' time, a few ms a second (where a trial takes longer than a fifteenth of
// the wait, steps of 60 ms or more, the next waits fifteen times the trial).
inline constexpr int THREAD_TRIAL_BLOCK = 4;
inline constexpr double THREAD_TRIAL_FIRST_SECONDS = 0.05;
inline constexpr double THREAD_TRIAL_EVERY_SECONDS = 1.0;

}  // namespace rbsim::constants
