"""Tuning constants, each with its unit, a typical value and what changing it does.

The solver follows the "soft step" design (sub-stepping, soft contact constraints,
a relax pass, restitution applied last). Values are SI: metres, seconds, radians.
"""

# Contacts closer than this are created before the shapes touch, so that the solver
# can stop an approaching body exactly at the surface (no tunneling within one step).
# m; typically 4 * LINEAR_SLOP. Larger values create more contacts (slower).
SPECULATIVE_DISTANCE = 0.02

# The collision tolerance, m; normally 0.5 cm. Gaps below it count as touching (no
# time-of-impact search), the narrowphase's face tolerance and the thin-segment skin
# scale with it, and pymunk gets it as its collision_slop. rbsim's soft contacts push
# every overlap out; they allow none.
LINEAR_SLOP = 0.005

# How far a shape's fat box reaches beyond its tight box, m. A shape is queried in
# the broadphase again only once it has moved this far; larger keeps more candidate
# pairs (each costs a box test per step), smaller re-queries moving shapes more often.
AABB_MARGIN = 0.02

# Soft contact stiffness, Hz; capped at a quarter of the substep rate (60 Hz at dt 1/60
# with 4 substeps). A contact under load F between bodies of effective mass m settles
# at an overlap F / (m (2π hertz)²): at 30 Hz a stack of 15 unit boxes sags 7 cm and a
# base-40 pyramid 7 cm; at 60 Hz 2 cm and 3 cm. The two-point block solve and the shock
# pass (shock.py) keep large mass ratios stable at this stiffness; without them it was
# 30 Hz at most.
CONTACT_HERTZ = 60.0

# Soft contact damping ratio, dimensionless. 10 = heavily over-damped: overlaps are
# removed without bounce.
CONTACT_DAMPING_RATIO = 10.0

# Fastest speed at which the soft contacts push an overlap out, m/s (bounded push-out).
CONTACT_PUSH_MAX_VELOCITY = 3.0

# An overlap deeper than this (m, 4 * LINEAR_SLOP) is being pushed out, not resting:
# while one exists the contacts around it get DEEP_RELAX_FACTOR times as many relax
# passes, so that the velocity of the push-out (at most CONTACT_PUSH_MAX_VELOCITY per
# contact) is taken back through a whole stack instead of adding up from row to row.
# Resting contacts overlap by millimetres and never pay for it.
DEEP_OVERLAP = 0.02
DEEP_RELAX_FACTOR = 4
# "Around it": the contacts of the dynamic bodies within this many contacts of a deep
# overlap (shock.deep_region). A pile's far contacts have nothing to take back: a ball
# landing hard on a pile of 1000 got the extra passes over a fifth of its contacts, not
# all. 8 reaches past the 3 extra passes' own reach; on a stack of 30 with a deep
# overlap at the bottom the top box's peak speed moved from 0.71 to 0.73 m/s.
DEEP_RELAX_REACH = 8

# Deepest overlap with a static or kinematic body that is left to the soft contacts, m;
# beyond it the body is moved out directly (solver.limit_static_overlap). Bodies resting
# on static ground overlap it by well under a millimetre; 4 * LINEAR_SLOP acts only when
# a pile under pressure outruns the bounded push-out speed.
STATIC_OVERLAP_LIMIT = 0.02

# A body that has moved less than this since its contacts were computed keeps them:
# the narrowphase is skipped for pairs of such bodies and their manifolds are carried
# forward (separations updated from the motion). m and rad; the geometry error this
# allows (1e-4 m in a lever arm, 1e-4 rad in a normal) is far below LINEAR_SLOP.
# Zero turns the reuse off.
STILL_DISTANCE = 1.0e-4
STILL_ANGLE = 1.0e-4

# Passes of the restitution stage over a cluster of bounces that share bodies (solver.
# apply_restitution): each pass bounces every pair that still approaches. A row of n
# touching balls struck at one end needs up to n - 1; a ball wedged between two walls
# would bounce back and forth for ever, and after this many passes its approach is left
# to the next substep's solve.
RESTITUTION_PASSES = 16
