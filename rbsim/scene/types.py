"""The scene's vocabularies, defined once: shape kinds, body types, integrators,
rotation updates and mixing rules, as a scene writes them and as the model's integer
arrays store them (the same numbers as cpp/include/rbsim/types.hpp).

Everything else (the schema, the resolver, the compiler, the trajectory file, the
engines and the tools) takes its names and numbers from here.
"""

from __future__ import annotations

# Shape kinds as a scene writes them. A box is stored as a polygon; a segment with a
# radius is a capsule.
SHAPE_KINDS = ("circle", "box", "polygon", "segment")

# Shape kinds as stored in Model.shape_kind.
SHAPE_CIRCLE = 0
SHAPE_POLYGON = 1
SHAPE_SEGMENT = 2
SHAPE_KIND_CODE = {
    "circle": SHAPE_CIRCLE,
    "box": SHAPE_POLYGON,
    "polygon": SHAPE_POLYGON,
    "segment": SHAPE_SEGMENT,
}

# 3D shape kinds as a scene writes them (world.dimension: 3). A plane is the solid
# half-space n·x <= offset, static bodies only.
SHAPE_KINDS_3D = ("sphere", "box", "capsule", "convex", "plane")

# 3D shape kinds as stored in Model.shape_kind (after the 2D codes, so one table of
# kinds serves both dimensions).
SHAPE_SPHERE = 3
SHAPE_BOX = 4
SHAPE_CAPSULE = 5
SHAPE_CONVEX = 6
SHAPE_PLANE = 7
SHAPE_KIND_CODE_3D = {
    "sphere": SHAPE_SPHERE,
    "box": SHAPE_BOX,
    "capsule": SHAPE_CAPSULE,
    "convex": SHAPE_CONVEX,
    "plane": SHAPE_PLANE,
}

# world.dimension
DIMENSIONS = (2, 3)

# Body types as a scene writes them, and as stored in Model.body_type.
BODY_TYPES = ("dynamic", "static", "kinematic")
BODY_DYNAMIC = 0
BODY_STATIC = 1
BODY_KINEMATIC = 2
BODY_TYPE_CODE = {"dynamic": BODY_DYNAMIC, "static": BODY_STATIC, "kinematic": BODY_KINEMATIC}

# solver.integrator and solver.rotation; the first of each is the default (a 3D scene's
# rotation: split, schema.SOLVER_3D).
INTEGRATORS = ("symplectic_euler", "explicit_euler")
# normalize: the notes' q <- normalize(q + h ω×q) (2D), normalize(q + (h/2) ω q) (3D);
# exact: q <- exp(h ω) q with ω held over the substep; split: the torque-free body split
# symmetrically into exact rotations about its principal axes (keeps L, symplectic;
# the same as exact in 2D). Codes as cpp/include/rbsim/types.hpp's Rotation.
ROTATIONS = ("normalize", "exact", "split")
ROTATION_CODE = {"normalize": 0, "exact": 1, "split": 2}

# world.mixing: how a contact's friction and restitution come from its two shapes'
# values (the first of each is the default), and the numbers the engines use for them.
FRICTION_MIXING = ("sqrt", "multiply", "min", "max")
RESTITUTION_MIXING = ("max", "multiply", "min")
MIX_SQRT, MIX_MULTIPLY, MIX_MIN, MIX_MAX = 0, 1, 2, 3
MIXING = {"sqrt": MIX_SQRT, "multiply": MIX_MULTIPLY, "min": MIX_MIN, "max": MIX_MAX}
