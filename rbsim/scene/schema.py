"""The scene format, version 1, written down once as data.

Every key of a scene file is a :class:`Key`: its kind, default, allowed values, range
and description. Two things are driven from the table:

- :func:`check_scene` validates a parsed tree (see rbsim.scene.yamlsrc) against it, fills
  defaults and reports every problem with its location and key path;
- :func:`json_schema` turns it into a JSON Schema (draft 2020-12) for editors
  (yaml-language-server: ``# yaml-language-server: $schema=rbsim-schema.json``).

Rules that tie several keys together (polygon convexity, unique body names, material
names that exist, static bodies that do not move) are checked by rbsim.scene.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from . import types as T
from .yamlsrc import BROKEN, Mark, Path, Problem, Shared, YList, YMap

SCENE_VERSION = 1


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


class _NoDefault:
    def __repr__(self) -> str:
        return "NO_DEFAULT"


REQUIRED: Any = _Required()  # the key must be given
NO_DEFAULT: Any = _NoDefault()  # optional; absent from the checked result when not given


class _Invalid:
    def __repr__(self) -> str:
        return "INVALID"


INVALID: Any = _Invalid()  # stands for a value that failed its check (already reported)


@dataclass(frozen=True)
class Key:
    """One key of the format.

    kind: number | integer | string | file_name (a string that names files) | enum |
        fraction (a number or "a/b") | vec2, vec3 (two, three numbers) | quat (four
        numbers w, x, y, z) | int2, int3 (two, three integers) | points, points3 (a list
        of vec2, vec3) | object (fixed keys) | map_of (names -> item) | list_of (items) |
        entry (a body or a one-key generator).
    gt, ge, le: bounds on numbers (for vectors and points: on every component); within:
        |x| <= within (the same, for a bound symmetric about 0).
    fields: an object's keys. exactly_one / at_most_one: groups of an object's keys.
    item: the value of a map_of, the item of a list_of, the plain body of an entry.
    variants: an entry's one-key alternatives (the generators).
    min_items, max_items: fewest and most items of a list_of or points.
    ref: name under ``$defs`` in the JSON Schema (for keys used in several places).
    """

    kind: str
    description: str
    default: Any = NO_DEFAULT
    choices: tuple[Any, ...] = ()
    gt: float | None = None
    ge: float | None = None
    le: float | None = None
    within: float | None = None
    fields: Mapping[str, Key] = field(default_factory=dict)
    exactly_one: tuple[tuple[str, ...], ...] = ()
    at_most_one: tuple[tuple[str, ...], ...] = ()
    item: Key | None = None
    variants: Mapping[str, Key] = field(default_factory=dict)
    min_items: int = 0
    max_items: int | None = None
    ref: str | None = None


# ---------------------------------------------------------------------------------------
# The range where the engine is meaningful. cli.md ("Bounds") gives each one's reason;
# the table below and rbsim.scene.resolve (rules over several keys) apply them.
# ---------------------------------------------------------------------------------------

LENGTH_MAX = 1e6  # m: |coordinate| of positions, offsets, vertices, ends, origins; sizes
LENGTH_MIN = 1e-6  # m: the smallest size (radius, side, edge, segment length, capsule radius)
ASPECT_MAX = 1e6  # a body's extent over its thinnest shape dimension
ANGLE_MAX = 1e6  # rad
SPEED_MAX = 1e6  # m/s
SPIN_MAX = 1e6  # rad/s
THREADS_MAX = 64  # solver.threads (the engine's THREADS_MAX, cpp/include/rbsim/world.hpp)
ACCELERATION_MAX = 1e6  # m/s²: gravity, and what a constant force or torque gives a body
DENSITY_MIN, DENSITY_MAX = 1e-6, 1e6  # kg/m²
MASS_MIN, MASS_MAX = 1e-12, 1e18  # kg
FRICTION_MAX = 1e3
DAMPING_MAX = 1e6  # 1/s
DT_MIN, DT_MAX = 1e-9, 1.0  # s
POLYGON_VERTICES_MAX = 32
# shapes x substeps x iterations of one step: about 0.25 µs each on one core (a pile
# with its contacts), so that a step takes a fraction of a second
WORK_MAX = 1_000_000
# the same in 3D, where a shape-iteration costs about 16 times more (4.5 µs in a pile of
# 55 boxes, whose faces hold 4 contact points solved as a block; 0.9 µs among 1,000
# spheres): a step at the bound takes about 0.3 s
WORK_MAX_3D = 62_500

# ---------------------------------------------------------------------------------------
# The table
# ---------------------------------------------------------------------------------------

DEFAULT_MATERIAL = {"density": 1.0, "friction": 0.6, "restitution": 0.0}

_density = Key("number", "Density per area, kg/m².", ge=DENSITY_MIN, le=DENSITY_MAX)
_friction = Key("number", "Coulomb friction coefficient μ.", ge=0, le=FRICTION_MAX)
_restitution = Key("number", "Coefficient of restitution e (0: no bounce, 1: elastic).", ge=0, le=1)

# Material keys that a body, a shape or a generator may carry inline. No defaults here:
# they override the named material (or the body's material for a shape).
INLINE_MATERIAL = {
    "material": Key("string", "Name of a material from `materials`."),
    "density": _density,
    "friction": _friction,
    "restitution": _restitution,
}

MATERIAL = Key(
    "object",
    "A named material; each key is optional.",
    fields={
        "density": replace(_density, default=DEFAULT_MATERIAL["density"]),
        "friction": replace(_friction, default=DEFAULT_MATERIAL["friction"]),
        "restitution": replace(_restitution, default=DEFAULT_MATERIAL["restitution"]),
    },
    ref="material",
)

SHAPE_KINDS = {
    "circle": Key(
        "object",
        "A circle (disc).",
        fields={
            "radius": Key("number", "Radius, m.", REQUIRED, ge=LENGTH_MIN, le=LENGTH_MAX),
            "offset": Key(
                "vec2", "Centre of the circle in the body frame, m.", (0.0, 0.0), within=LENGTH_MAX
            ),
        },
    ),
    "box": Key(
        "object",
        "A rectangle.",
        fields={
            "size": Key(
                "vec2", "Full width and height, m.", REQUIRED, ge=LENGTH_MIN, le=LENGTH_MAX
            ),
            "offset": Key(
                "vec2", "Centre of the box in the body frame, m.", (0.0, 0.0), within=LENGTH_MAX
            ),
            "angle": Key(
                "number", "Rotation of the box in the body frame, rad.", 0.0, within=ANGLE_MAX
            ),
        },
    ),
    "polygon": Key(
        "object",
        "A convex polygon; clockwise vertices are reordered counter-clockwise.",
        fields={
            "vertices": Key(
                "points",
                f"Vertices [x, y] in the body frame, m (3 to {POLYGON_VERTICES_MAX}).",
                REQUIRED,
                min_items=3,
                max_items=POLYGON_VERTICES_MAX,
                within=LENGTH_MAX,
            ),
        },
    ),
    "segment": Key(
        "object",
        "A line segment from a to b; with a radius > 0, a capsule.",
        fields={
            "a": Key("vec2", "First end in the body frame, m.", REQUIRED, within=LENGTH_MAX),
            "b": Key("vec2", "Second end in the body frame, m.", REQUIRED, within=LENGTH_MAX),
            "radius": Key(
                "number",
                "Radius around the segment (0 or at least 1e-6), m.",
                0.0,
                ge=0,
                le=LENGTH_MAX,
            ),
        },
    ),
}

SHAPE = Key(
    "object",
    "One shape: exactly one of circle, box, polygon, segment, optionally with material "
    "keys that override the body's for this shape.",
    fields={**SHAPE_KINDS, **INLINE_MATERIAL},
    exactly_one=(tuple(SHAPE_KINDS),),
    ref="shape",
)


BODY = Key(
    "object",
    "A rigid body with one shape (`shape`) or several (`shapes`, a compound body).",
    fields={
        "name": Key("string", "Unique name; default body[i] with i the index in `bodies`."),
        "type": Key("enum", "How the body moves.", "dynamic", choices=T.BODY_TYPES),
        "position": Key("vec2", "Body origin in the world, m.", (0.0, 0.0), within=LENGTH_MAX),
        "angle": Key("number", "Orientation, rad.", 0.0, within=ANGLE_MAX),
        "velocity": Key(
            "vec2", "Velocity of the centre of mass, m/s.", (0.0, 0.0), within=SPEED_MAX
        ),
        "angular_velocity": Key("number", "Angular velocity, rad/s.", 0.0, within=SPIN_MAX),
        **INLINE_MATERIAL,
        "mass": Key(
            "number",
            "Mass, kg: overrides the density (inertia scales).",
            ge=MASS_MIN,
            le=MASS_MAX,
        ),
        "force": Key("vec2", "Constant force in the world frame, N.", (0.0, 0.0)),
        "force_point": Key(
            "vec2", "Where the force acts, body frame, m; default: the COM.", within=LENGTH_MAX
        ),
        "torque": Key("number", "Constant torque, N·m.", 0.0),
        "shape": SHAPE,
        "shapes": Key("list_of", "Shapes of a compound body.", item=SHAPE, min_items=1),
    },
    exactly_one=(("shape", "shapes"),),
    ref="body",
)

_size = Key(
    "vec2", "Full width and height of each box, m.", (1.0, 1.0), ge=LENGTH_MIN, le=LENGTH_MAX
)
_spacing = Key("number", "Gap between neighbouring boxes, m.", 0.0, ge=0, le=LENGTH_MAX)
_origin = "Centre of the bottom row's middle, m; default [0, h/2]."

GENERATORS = {
    "pyramid": Key(
        "object",
        "Boxes in rows: row r (from 0 at the bottom) holds base - r boxes, named name[r,i].",
        fields={
            "base": Key("integer", "Number of boxes in the bottom row.", REQUIRED, ge=1),
            "size": _size,
            "origin": Key("vec2", _origin, within=LENGTH_MAX),
            "spacing": _spacing,
            "name": Key("string", "Name prefix.", "pyramid"),
            **INLINE_MATERIAL,
        },
    ),
    "stack": Key(
        "object",
        "A vertical column of boxes, named name[i] from the bottom.",
        fields={
            "count": Key("integer", "Number of boxes.", REQUIRED, ge=1),
            "size": _size,
            "origin": Key(
                "vec2", "Centre of the bottom box, m; default [0, h/2].", within=LENGTH_MAX
            ),
            "spacing": _spacing,
            "name": Key("string", "Name prefix.", "stack"),
            **INLINE_MATERIAL,
        },
    ),
    "grid": Key(
        "object",
        "nx by ny copies of one shape, body [i, j] at origin + (i dx, j dy), named name[i,j].",
        fields={
            "count": Key("int2", "[nx, ny], number of bodies along x and y.", REQUIRED, ge=1),
            "spacing": Key(
                "vec2", "[dx, dy], distance between body origins, m.", REQUIRED, within=LENGTH_MAX
            ),
            "origin": Key("vec2", "Position of body [0, 0], m.", (0.0, 0.0), within=LENGTH_MAX),
            "shape": replace(SHAPE, default=REQUIRED),
            "velocity": Key(
                "vec2", "Initial velocity of every body, m/s.", (0.0, 0.0), within=SPEED_MAX
            ),
            "name": Key("string", "Name prefix.", "grid"),
            **INLINE_MATERIAL,
        },
    ),
}
WORLD = Key(
    "object",
    "Gravity, time step and length of the run, damping, mixing rules.",
    {},
    fields={
        "dimension": Key(
            "integer",
            "2 for a planar scene (the default), 3 for a 3D one (3-vectors, quaternions, "
            "3D shape kinds).",
            2,
            choices=T.DIMENSIONS,
        ),
        "gravity": Key("vec2", "Gravity, m/s².", (0.0, -9.81), within=ACCELERATION_MAX),
        "dt": Key(
            "fraction",
            'Time step, s; a fraction such as "1/60" is accepted.',
            1 / 60,
            ge=DT_MIN,
            le=DT_MAX,
        ),
        "duration": Key("number", "Length of the run, s (default 10 when steps is absent).", gt=0),
        "steps": Key("integer", "Number of steps (instead of duration).", ge=1),
        "damping": Key(
            "object",
            "Velocity damping, 1/s.",
            {},
            fields={
                "linear": Key("number", "Linear damping, 1/s.", 0.0, ge=0, le=DAMPING_MAX),
                "angular": Key("number", "Angular damping, 1/s.", 0.0, ge=0, le=DAMPING_MAX),
            },
        ),
        "mixing": Key(
            "object",
            "How the two materials of a contact combine.",
            {},
            fields={
                "friction": Key(
                    "enum",
                    "Friction of a contact from the two shapes'.",
                    "sqrt",
                    choices=T.FRICTION_MIXING,
                ),
                "restitution": Key(
                    "enum",
                    "Restitution of a contact from the two shapes'.",
                    "max",
                    choices=T.RESTITUTION_MIXING,
                ),
            },
        ),
    },
    at_most_one=(("duration", "steps"),),
)

SOLVER = Key(
    "object",
    "Solver settings; every key is optional.",
    {},
    fields={
        "substeps": Key("integer", "Substeps per step.", 4, ge=1, le=WORK_MAX),
        "iterations": Key("integer", "Velocity iterations per substep.", 1, ge=1, le=WORK_MAX),
        "integrator": Key(
            "enum",
            "Time integrator.",
            "symplectic_euler",
            choices=T.INTEGRATORS,
        ),
        "rotation": Key(
            "enum",
            "Orientation update: normalize (the notes' q + h ω×q, normalised) or exact (the "
            "rotation by h ω; split is the same in 2D).",
            "normalize",
            choices=T.ROTATIONS,
        ),
        "restitution_threshold": Key(
            "number",
            "Approach speed below which contacts do not bounce, m/s.",
            1.0,
            ge=0,
            le=SPEED_MAX,
        ),
        "threads": Key(
            "integer",
            "Threads the step runs on. Without it the step may use the machine's cores and "
            "runs on one thread or on all, whichever short trials as the run goes time faster "
            "(1 in `rbsim batch` and `rbsim sweep` workers). The result is the same, bit for "
            "bit, for any count.",
            ge=1,
            le=THREADS_MAX,
        ),
    },
)

OUTPUT = Key(
    "object",
    "What the trajectory file holds.",
    {},
    fields={
        "every": Key("integer", "Write every k-th step (step 0 and the last always).", 1, ge=1),
        "precision": Key(
            "enum",
            "Floating-point width of the per-body series (observables stay float64).",
            "float64",
            choices=("float64", "float32"),
        ),
        "compression": Key(
            "enum",
            "Compression of the series, applied when the run closes the file.",
            "none",
            choices=("none", "lzf", "gzip"),
        ),
        "bodies": Key(
            "selection",
            "Bodies written in every frame: all, moving (every body that is not static), "
            "or a list of names and patterns (* matches any text: pyramid[*]); static "
            "bodies left out are stored once.",
            "all",
            choices=("all", "moving"),
        ),
        "contacts": Key(
            "enum",
            "Contact points in every frame: none, or points (each point that pushed in "
            "the step: its bodies, world position, normal and mean normal force over the "
            "step; rbsim's engine only).",
            "none",
            choices=("none", "points"),
        ),
    },
)

COMPARE = Key(
    "object",
    "Largest differences allowed between rbsim and pymunk (`rbsim compare`).",
    {},
    fields={
        "position": Key("number", "Position, m.", ge=0),
        "angle": Key("number", "Angle, rad.", ge=0),
        "velocity": Key("number", "Velocity, m/s.", ge=0),
        "angular_velocity": Key("number", "Angular velocity, rad/s.", ge=0),
        "iterations": Key(
            "integer",
            "pymunk solver iterations per pymunk step (default 10).",
            ge=1,
            le=WORK_MAX,
        ),
        "statistics": Key(
            "object",
            "Compare the two runs statistically (for chaotic scenes): the largest "
            "differences allowed at the last frame; a missing key is reported, not checked.",
            fields={
                "kinetic_energy": Key("number", "Total kinetic energy, J.", ge=0),
                "mean_height": Key("number", "Mean height of the dynamic bodies, m.", ge=0),
                "heights": Key(
                    "number",
                    "Distance between the distributions of the dynamic bodies' heights "
                    "(mean gap between the sorted heights), m.",
                    ge=0,
                ),
                "penetration": Key(
                    "number", "Largest overlap of two shapes in either run (a bound), m.", ge=0
                ),
            },
        ),
    },
)

# `rbsim sweep` references (rbsim.reference): analytic solutions, then the generic ones.
REFERENCE_KINDS = (
    "projectile",
    "free_spin",
    "slide",
    "bounce",
    "collision",
    "converged",
    "invariants",
)

REFERENCE = Key(
    "object",
    "What `rbsim sweep` measures errors against; without this block, a converged run.",
    fields={
        "kind": Key(
            "enum",
            "projectile, free_spin (one free body), slide (a block on a flat support with "
            "friction), bounce (a ball on a flat support), collision (two bodies, one "
            "impact): analytic; converged: a run with a much smaller dt; invariants: bodies "
            "placed at rest (error = drift from the rest pose).",
            REQUIRED,
            choices=REFERENCE_KINDS,
        ),
        "body": Key("string", "The dynamic body followed; default: the only dynamic body."),
        "support": Key(
            "string", "slide, bounce: the static body below; default: the only static body."
        ),
        "dt": Key("fraction", "converged: the reference run's time step, s.", ge=DT_MIN, le=DT_MAX),
        "substeps": Key("integer", "converged: the reference run's substeps.", ge=1, le=WORK_MAX),
        "iterations": Key(
            "integer", "converged: the reference run's iterations.", ge=1, le=WORK_MAX
        ),
    },
)

SCENE = Key(
    "object",
    "An rbsim scene, format version 1.",
    fields={
        "version": Key("integer", "Scene format version.", REQUIRED, choices=(SCENE_VERSION,)),
        "name": Key(
            "file_name",
            "Scene name, which names its output files (no / or \\); default: the file name "
            "without extension.",
        ),
        "world": WORLD,
        "solver": SOLVER,
        "output": OUTPUT,
        "materials": Key("map_of", "Named materials.", {}, item=MATERIAL),
        "bodies": Key(
            "list_of",
            "Bodies, and generators (pyramid, stack, grid) that expand into bodies.",
            REQUIRED,
            item=Key("entry", "A body or a generator.", item=BODY, variants=GENERATORS),
            min_items=1,
        ),
        "compare": COMPARE,
        "reference": REFERENCE,
    },
)

# ---------------------------------------------------------------------------------------
# The same format in 3D (world.dimension: 3): 3-vectors, quaternions, the 3D shape kinds.
# Keys that mean the same in both dimensions are the 2D table's own.
# ---------------------------------------------------------------------------------------

CONVEX_VERTICES_MAX = 256  # points given for one convex hull
# A hull triangle's doubled area over the square of the hull's size (its bounding box
# diagonal), at least: the engine's hull builder (cpp/src/collide/hull3d.cpp,
# PLANE_TOLERANCE) takes a triangle below 1e-9 as degenerate; twice that leaves room for
# the rounding of the points' shift to the centre of mass.
HULL_TRIANGLE_MIN = 2e-9

_density3 = Key("number", "Density per volume, kg/m³.", ge=DENSITY_MIN, le=DENSITY_MAX)
INLINE_MATERIAL_3D = {**INLINE_MATERIAL, "density": _density3}
MATERIAL_3D = replace(
    MATERIAL,
    fields={**MATERIAL.fields, "density": replace(_density3, default=DEFAULT_MATERIAL["density"])},
    ref="material3d",
)

ROTATION = Key(
    "object",
    "A rotation by `angle` about `axis` (normalised on load; a zero axis is an error).",
    fields={
        "axis": Key(
            "vec3", "Axis of the rotation (any length but zero).", REQUIRED, within=LENGTH_MAX
        ),
        "angle": Key("number", "Angle of the rotation, rad.", REQUIRED, within=ANGLE_MAX),
    },
    ref="rotation",
)


def _frame(what: str) -> dict[str, Key]:
    """The `offset`, `orientation` and `rotation` keys of a 3D shape placed in its body."""
    return {
        "offset": Key("vec3", f"{what} in the body frame, m.", (0.0, 0.0, 0.0), within=LENGTH_MAX),
        "orientation": Key(
            "quat",
            "Rotation of the shape in the body frame, unit quaternion [w, x, y, z] "
            "(normalised on load).",
            within=LENGTH_MAX,
        ),
        "rotation": ROTATION,
    }


SHAPE_KINDS_3D = {
    "sphere": Key(
        "object",
        "A ball.",
        fields={
            "radius": Key("number", "Radius, m.", REQUIRED, ge=LENGTH_MIN, le=LENGTH_MAX),
            **_frame("Centre of the sphere"),
        },
        at_most_one=(("orientation", "rotation"),),
    ),
    "box": Key(
        "object",
        "A rectangular box (cuboid).",
        fields={
            "size": Key(
                "vec3", "Full extents along x, y, z, m.", REQUIRED, ge=LENGTH_MIN, le=LENGTH_MAX
            ),
            **_frame("Centre of the box"),
        },
        at_most_one=(("orientation", "rotation"),),
    ),
    "capsule": Key(
        "object",
        "The segment a-b swept by a ball of `radius` (a cylinder with two hemispherical caps).",
        fields={
            "a": Key("vec3", "First end of the axis, m.", REQUIRED, within=LENGTH_MAX),
            "b": Key("vec3", "Second end of the axis, m.", REQUIRED, within=LENGTH_MAX),
            "radius": Key("number", "Radius, m.", REQUIRED, ge=LENGTH_MIN, le=LENGTH_MAX),
            **_frame("Where the capsule's own origin sits"),
        },
        at_most_one=(("orientation", "rotation"),),
    ),
    "convex": Key(
        "object",
        "The convex hull of the given points (points inside it are dropped).",
        fields={
            "vertices": Key(
                "points3",
                f"Points [x, y, z], m (4 to {CONVEX_VERTICES_MAX}, not all in one plane).",
                REQUIRED,
                min_items=4,
                max_items=CONVEX_VERTICES_MAX,
                within=LENGTH_MAX,
            ),
            **_frame("Where the points' origin sits"),
        },
        at_most_one=(("orientation", "rotation"),),
    ),
    "plane": Key(
        "object",
        "The solid half-space n·x <= offset in the body frame (static bodies only).",
        fields={
            "normal": Key(
                "vec3",
                "Outward normal (normalised on load; a zero normal is an error).",
                (0.0, 1.0, 0.0),
                within=LENGTH_MAX,
            ),
            "offset": Key(
                "number",
                "Distance of the plane from the body origin along n, m.",
                0.0,
                within=LENGTH_MAX,
            ),
        },
    ),
}

SHAPE_3D = Key(
    "object",
    "One shape: exactly one of sphere, box, capsule, convex, plane, optionally with "
    "material keys that override the body's for this shape.",
    fields={**SHAPE_KINDS_3D, **INLINE_MATERIAL_3D},
    exactly_one=(tuple(SHAPE_KINDS_3D),),
    ref="shape3d",
)

_zero3 = (0.0, 0.0, 0.0)
BODY_3D = Key(
    "object",
    "A rigid body with one shape (`shape`) or several (`shapes`, a compound body).",
    fields={
        "name": BODY.fields["name"],
        "type": BODY.fields["type"],
        "position": Key("vec3", "Body origin in the world, m.", _zero3, within=LENGTH_MAX),
        "orientation": Key(
            "quat",
            "Orientation, unit quaternion [w, x, y, z] (normalised on load).",
            within=LENGTH_MAX,
        ),
        "rotation": replace(
            ROTATION,
            description="Orientation as a rotation by `angle` about "
            "`axis` (instead of `orientation`).",
        ),
        "velocity": Key("vec3", "Velocity of the centre of mass, m/s.", _zero3, within=SPEED_MAX),
        "angular_velocity": Key(
            "vec3", "Angular velocity in the world frame, rad/s.", _zero3, within=SPIN_MAX
        ),
        **INLINE_MATERIAL_3D,
        "mass": BODY.fields["mass"],
        "force": Key("vec3", "Constant force in the world frame, N.", _zero3),
        "force_point": Key(
            "vec3", "Where the force acts, body frame, m; default: the COM.", within=LENGTH_MAX
        ),
        "torque": Key("vec3", "Constant torque in the world frame, N·m.", _zero3),
        "shape": SHAPE_3D,
        "shapes": Key("list_of", "Shapes of a compound body.", item=SHAPE_3D, min_items=1),
    },
    exactly_one=(("shape", "shapes"),),
    at_most_one=(("orientation", "rotation"),),
    ref="body3d",
)

_size3 = Key(
    "vec3",
    "Full extents of each box along x, y, z, m.",
    (1.0, 1.0, 1.0),
    ge=LENGTH_MIN,
    le=LENGTH_MAX,
)

GENERATORS_3D = {
    "pyramid": Key(
        "object",
        "Boxes in square layers: layer r (from 0 at the bottom) holds (base - r)² boxes "
        "centred over the origin, named name[r,i,j] (i along x, j along z).",
        fields={
            **GENERATORS["pyramid"].fields,
            "size": _size3,
            "origin": Key(
                "vec3", "Centre of the bottom layer, m; default [0, h/2, 0].", within=LENGTH_MAX
            ),
            **INLINE_MATERIAL_3D,
        },
    ),
    "stack": Key(
        "object",
        "A vertical column of boxes (along y), named name[i] from the bottom.",
        fields={
            **GENERATORS["stack"].fields,
            "size": _size3,
            "origin": Key(
                "vec3", "Centre of the bottom box, m; default [0, h/2, 0].", within=LENGTH_MAX
            ),
            **INLINE_MATERIAL_3D,
        },
    ),
    "grid": Key(
        "object",
        "nx by ny by nz copies of one shape, body [i, j, k] at origin + (i dx, j dy, k dz), "
        "named name[i,j,k].",
        fields={
            "count": Key(
                "int3", "[nx, ny, nz], number of bodies along x, y and z.", REQUIRED, ge=1
            ),
            "spacing": Key(
                "vec3",
                "[dx, dy, dz], distance between body origins, m.",
                REQUIRED,
                within=LENGTH_MAX,
            ),
            "origin": Key("vec3", "Position of body [0, 0, 0], m.", _zero3, within=LENGTH_MAX),
            "shape": replace(SHAPE_3D, default=REQUIRED),
            "velocity": Key(
                "vec3", "Initial velocity of every body, m/s.", _zero3, within=SPEED_MAX
            ),
            "name": GENERATORS["grid"].fields["name"],
            **INLINE_MATERIAL_3D,
        },
    ),
}

WORLD_3D = replace(
    WORLD,
    fields={
        **WORLD.fields,
        "gravity": Key("vec3", "Gravity, m/s².", (0.0, -9.81, 0.0), within=ACCELERATION_MAX),
    },
)

# In 3D the default rotation update is split: normalize and exact hold ω over a substep
# while a tumbling body's ω precesses, and a slender body's energy grows without bound (a
# 0.5 × 0.02 × 0.02 m stick spinning at 30 rad/s went to 500 in one step of 1/60 s).
SOLVER_3D = replace(
    SOLVER,
    fields={
        **SOLVER.fields,
        "rotation": replace(
            SOLVER.fields["rotation"],
            description="Orientation update: split (the free rigid body's own flow, split "
            "about its principal axes: keeps L and, to second order, the energy), normalize "
            "(the notes' q + (h/2) ω q, normalised) or exact (the rotation by h ω); the last "
            "two hold ω over a substep and gain energy on a body that tumbles.",
            default="split",
        ),
    },
)

SCENE_3D = replace(
    SCENE,
    description="An rbsim scene in 3D (world.dimension: 3), format version 1.",
    fields={
        **SCENE.fields,
        "world": WORLD_3D,
        "solver": SOLVER_3D,
        "materials": replace(SCENE.fields["materials"], item=MATERIAL_3D),
        "bodies": replace(
            SCENE.fields["bodies"],
            item=Key("entry", "A body or a generator.", item=BODY_3D, variants=GENERATORS_3D),
        ),
    },
)

# What a key of the other dimension's format is called here, for the message that
# names it: (dimension the key belongs to, name) -> what to write instead.
OTHER_DIMENSION_HINTS: dict[tuple[int, str], str] = {
    (2, "angle"): "a 3D scene gives orientation: [w,x,y,z] or rotation: {axis, angle}",
    (2, "circle"): "a 3D scene has sphere: {radius}",
    (2, "polygon"): "a 3D scene has convex: {vertices: [[x,y,z], ...]}",
    (2, "segment"): "a 3D scene has capsule: {a, b, radius}, or a static plane",
    (3, "orientation"): "a 2D scene gives angle: (rad)",
    (3, "rotation"): "a 2D scene gives angle: (rad)",
    (3, "sphere"): "a 2D scene has circle: {radius}",
    (3, "capsule"): "a 2D scene has segment: {a, b, radius}",
    (3, "convex"): "a 2D scene has polygon: {vertices: [[x,y], ...]}",
    (3, "plane"): "a 2D scene has a static segment for the ground",
}

SCENES_BY_DIMENSION = {2: SCENE, 3: SCENE_3D}
_ALL_SHAPE_KINDS = {*SHAPE_KINDS, *SHAPE_KINDS_3D}

# Every group of keys that exclude each other (a --set of one removes the others).
EXCLUSIVE_GROUPS: tuple[tuple[str, ...], ...] = (
    *WORLD.at_most_one,
    *BODY.exactly_one,
    *SHAPE.exactly_one,
    *SHAPE_3D.exactly_one,
    *BODY_3D.at_most_one,
)


# ---------------------------------------------------------------------------------------
# Checking a parsed tree against the table
# ---------------------------------------------------------------------------------------

_NUMBER = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
FRACTION_PATTERN = rf"^\s*{_NUMBER}\s*/\s*{_NUMBER}\s*$"
_FRACTION_RE = re.compile(rf"^\s*({_NUMBER})\s*/\s*({_NUMBER})\s*$")


class Checked(dict):
    """A checked mapping: converted values, defaults filled in, and where it came from.

    ``tag`` is the generator name for a generator entry of `bodies`, else None.
    """

    __slots__ = ("src", "path", "mark", "tag")

    def __init__(self, src: YMap, path: Path, mark: Mark) -> None:
        super().__init__()
        self.src = src
        self.path = path
        self.mark = mark
        self.tag: str | None = None

    def mark_of(self, key: str) -> Mark:
        """Where the value of ``key`` is written (the mapping itself if it is not)."""
        return self.src.value_marks.get(key, self.mark)

    def path_of(self, key: str | int) -> Path:
        """Key path of ``key`` below this mapping."""
        return self.path + (key,)


def counted(n: int, noun: str, nouns: str | None = None) -> str:
    """``n`` and the noun in the number it takes: "1 step", "2 steps", "1 body" ...
    (``nouns``: the plural, default noun + "s")."""
    return f"{n} {noun}" if n == 1 else f"{n} {nouns or noun + 's'}"


def describe(value: Any) -> str:
    """A short description of a parsed value for error messages."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, int):
        shown = _show(value)
        return shown if shown.startswith("an integer") else f"the integer {shown}"
    if isinstance(value, float):
        return f"the number {value!r}"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)} item{'' if len(value) == 1 else 's'}"
    return f"a {type(value).__name__}"


def _show(x: float) -> str:
    """A number as a user would write it: -1.0 -> '-1', 0.25 -> '0.25'; an integer of
    more than 20 digits by its length."""
    if isinstance(x, int) and not isinstance(x, bool):
        digits = str(abs(x))
        return str(x) if len(digits) <= 20 else f"an integer of {len(digits)} digits"
    return str(int(x)) if x.is_integer() and abs(x) < 1e15 else repr(x)


def _bound(x: float) -> str:
    """A bound as the format's tables write it: 1e6, 1e-6, 0.5, -1e6."""
    return f"{x:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def did_you_mean(word: str, candidates: Any) -> str | None:
    """The closest of ``candidates`` to ``word``, if any is close enough."""
    close = difflib.get_close_matches(word, [str(c) for c in candidates], n=1, cutoff=0.6)
    return close[0] if close else None


def _vector_hint(wanted: int, given: int) -> str:
    """What to say when a vector of the other dimension is given ('' if it is not one)."""
    if wanted == 2 and given == 3:
        return "; a 3-vector is for a 3D scene (world.dimension: 3)"
    if wanted == 3 and given == 2:
        return "; [x, y] is for a 2D scene, this one is 3D (world.dimension: 3)"
    return ""


def _key_at(key: Key, path: Path) -> Key | None:
    """The key of the table ``key`` that ``path`` (a key path into a scene) leads to, or
    None when the table has no such key."""
    for part in path:
        if isinstance(part, int):
            if key.kind != "list_of" or key.item is None:
                return None
            key = key.item
            continue
        if key.kind == "entry":
            if part in key.variants:
                key = key.variants[part]
                continue
            key = key.item
        if key.kind == "map_of" and key.item is not None:
            key = key.item
            continue
        if key.kind != "object" or part not in key.fields:
            return None
        key = key.fields[part]
    return key.item if key.kind == "entry" else key  # a body, not a generator


class Checker:
    """Checks values against :class:`Key` entries, collecting :class:`Problem` s.

    ``dimension`` is the scene's (2 or 3): a key unknown here that the other
    dimension's table has at the same place is named as the other dimension's.
    """

    def __init__(self, dimension: int = 2, shared: Shared | None = None) -> None:
        self.problems: list[Problem] = []
        self.dimension = dimension
        self.shared = shared  # the parsed text's, whose nodes' checks are kept

    def _other_dimension(self, name: str, path: Path) -> str | None:
        """The message for ``name`` at ``path`` if it is a key of the other dimension."""
        other = 5 - self.dimension  # 2 <-> 3
        parent = _key_at(SCENES_BY_DIMENSION[other], path)
        if parent is None or parent.kind != "object" or name not in parent.fields:
            return None
        what = "shape" if name in (SHAPE_KINDS, SHAPE_KINDS_3D)[other - 2] else "key"
        message = f"`{name}` is a {other}D {what}"
        if self.dimension == 2:
            message += " (for a scene with world.dimension: 3)"
        hint = OTHER_DIMENSION_HINTS.get((other, name))
        if hint:
            return f"{message}: {hint}"
        return message if self.dimension == 2 else f"{message}, and this scene is 3D"

    def error(self, mark: Mark, path: Path, message: str) -> Any:
        """Record a problem; returns INVALID so that callers can ``return self.error(...)``."""
        self.problems.append(Problem(mark, path, message))
        return INVALID

    def check(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        """The checked, converted value, or INVALID after recording why not."""
        if value is BROKEN:  # unreadable YAML, already reported
            return INVALID
        shared = self.shared
        if shared is None or not shared.holds(value):
            return getattr(self, "_" + key.kind)(value, key, path, mark)
        # a node of the shared tree, checked by an earlier load in the same place: its
        # checked value again (never changed by those who read it), and its problems
        known = ("check", id(value), id(key), path, mark, self.dimension)
        found = shared.found.get(known)
        if found is None:
            start = len(self.problems)
            out = getattr(self, "_" + key.kind)(value, key, path, mark)
            found = shared.found[known] = (out, self.problems[start:])
        else:
            self.problems += found[1]
        return found[0]

    # scalars -----------------------------------------------------------------------------

    def _number(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(value, bool) or not isinstance(value, int | float):
            return self.error(mark, path, f"expected a number, got {describe(value)}")
        if isinstance(value, int):
            # the bounds first: an integer beyond float range fails them, or float()
            problem = self._out_of_bounds(value, key)
            if problem:
                return self.error(mark, path, problem)
            try:
                value = float(value)
            except OverflowError:
                message = f"is too large for a number (above 1.8e308), got {_show(value)}"
                return self.error(mark, path, message)
        return self._bounded(value, key, path, mark)

    def _integer(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(value, bool) or not isinstance(value, int):
            return self.error(mark, path, f"expected an integer, got {describe(value)}")
        if key.choices and value not in key.choices:
            allowed = " or ".join(str(c) for c in key.choices)
            return self.error(mark, path, f"must be {allowed}, got {_show(value)}")
        return self._bounded(value, key, path, mark)

    def _bounded(self, x: float, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            return self.error(mark, path, f"must be a finite number, got {x}")
        problem = self._out_of_bounds(x, key)
        return self.error(mark, path, problem) if problem else x

    @staticmethod
    def _out_of_bounds(x: float, key: Key) -> str | None:
        """Why ``x`` (a finite float, or an int of any size) is outside ``key``'s bounds,
        or None. Integers are compared exactly (no float conversion)."""
        shown = _show(x)
        if key.within is not None and not -key.within <= x <= key.within:
            w = _bound(key.within)
            return f"must be between -{w} and {w}, got {shown}"
        if key.ge is not None and key.le is not None and not key.ge <= x <= key.le:
            return f"must be between {_bound(key.ge)} and {_bound(key.le)}, got {shown}"
        if key.gt is not None and not x > key.gt:
            return f"must be > {_bound(key.gt)}, got {shown}"
        if key.ge is not None and not x >= key.ge:
            return f"must be >= {_bound(key.ge)}, got {shown}"
        if key.le is not None and not x <= key.le:
            return f"must be <= {_bound(key.le)}, got {shown}"
        return None

    def _fraction(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(value, str):
            match = _FRACTION_RE.match(value)
            if not match:
                return self.error(
                    mark, path, f'expected a number or a fraction such as "1/60", got {value!r}'
                )
            numerator, denominator = float(match[1]), float(match[2])
            if denominator == 0:
                return self.error(mark, path, f"{value!r} divides by zero")
            value = numerator / denominator
        return self._number(value, key, path, mark)

    def _string(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if not isinstance(value, str):
            return self.error(mark, path, f"expected a string, got {describe(value)}")
        if not value.strip():
            return self.error(mark, path, "must not be empty")
        # (names go into the trajectory's HDF5 strings, which hold no NUL, and to terminals)
        if any(ord(ch) < 32 or ord(ch) == 127 for ch in value):
            return self.error(mark, path, f"{value!r} holds a control character (such as NUL)")
        return value

    def _file_name(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        value = self._string(value, key, path, mark)
        if value is INVALID:
            return value
        if "/" in value or "\\" in value or value.strip() in (".", ".."):
            message = f"{value!r} is not a file name (the outputs are named after it): no / or \\"
            return self.error(mark, path, message + ", and not . or ..")
        return value

    def _selection(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(value, str):
            return self._enum(value, key, path, mark)
        if not isinstance(value, YList) or not value:
            message = f"expected {' or '.join(key.choices)} or a list of body names, got "
            return self.error(mark, path, message + describe(value))
        return [
            self._string(item, key, path + (i,), value.item_marks[i])
            for i, item in enumerate(value)
        ]

    def _enum(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if isinstance(value, str) and value in key.choices:
            return value
        message = f"expected one of {', '.join(key.choices)}, got {describe(value)}"
        close = did_you_mean(value, key.choices) if isinstance(value, str) else None
        if close:
            message += f"; did you mean {close}?"
        return self.error(mark, path, message)

    # lists of numbers --------------------------------------------------------------------

    def _vec2(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._tuple(value, key, path, mark, self._number, "numbers", "[x, y]")

    def _vec3(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._tuple(value, key, path, mark, self._number, "numbers", "[x, y, z]")

    def _quat(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._tuple(value, key, path, mark, self._number, "numbers", "[w, x, y, z]")

    def _int2(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._tuple(value, key, path, mark, self._integer, "integers", "[x, y]")

    def _int3(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._tuple(value, key, path, mark, self._integer, "integers", "[x, y, z]")

    def _tuple(
        self, value: Any, key: Key, path: Path, mark: Mark, item: Any, what: str, shape: str
    ) -> Any:
        n = shape.count(",") + 1
        if not isinstance(value, YList) or len(value) != n:
            message = f"expected {shape}, {n} {what}, got {describe(value)}"
            if isinstance(value, YList) and shape in ("[x, y]", "[x, y, z]"):
                message += _vector_hint(n, len(value))
            return self.error(mark, path, message)
        pair = tuple(item(v, key, path + (i,), value.item_marks[i]) for i, v in enumerate(value))
        return INVALID if INVALID in pair else pair

    def _points(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._point_list(value, key, path, mark, self._vec2, "[x, y]")

    def _points3(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        return self._point_list(value, key, path, mark, self._vec3, "[x, y, z]")

    def _point_list(
        self, value: Any, key: Key, path: Path, mark: Mark, point: Any, shape: str
    ) -> Any:
        if not isinstance(value, YList):
            return self.error(
                mark, path, f"expected a list of {shape} points, got {describe(value)}"
            )
        if len(value) < key.min_items:
            return self.error(
                mark, path, f"needs at least {key.min_items} points, got {len(value)}"
            )
        if key.max_items is not None and len(value) > key.max_items:
            return self.error(mark, path, f"at most {key.max_items} points, got {len(value)}")
        points = tuple(point(v, key, path + (i,), value.item_marks[i]) for i, v in enumerate(value))
        return INVALID if INVALID in points else points

    # containers --------------------------------------------------------------------------

    def _object(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if value is None:
            value = YMap(mark)  # `solver:` with everything commented out
        if not isinstance(value, YMap):
            return self.error(mark, path, f"expected a mapping (key: value), got {describe(value)}")
        out = Checked(value, path, mark)
        foreign = False  # a shape kind of the other dimension (say nothing more of it)
        for name, item in value.items():
            field_key = key.fields.get(name)
            if field_key is None:
                message = self._other_dimension(name, path)
                foreign = foreign or (message is not None and name in _ALL_SHAPE_KINDS)
                message = message or _unknown_key(name, key, value)
                self.error(value.key_marks[name], path + (name,), message)
            else:
                out[name] = self.check(item, field_key, path + (name,), value.value_marks[name])
        for group in key.exactly_one:
            given = [name for name in group if name in value]
            if not given and not foreign:
                self.error(mark, path, f"needs one of {', '.join(group)}")
            elif len(given) > 1:
                self.error(mark, path, f"give only one of {', '.join(given)}")
        for group in key.at_most_one:
            given = [name for name in group if name in value]
            if len(given) > 1:
                self.error(mark, path, f"give {' or '.join(given)}, not both")
        for name, field_key in key.fields.items():
            if name in value or field_key.default is NO_DEFAULT:
                continue
            if field_key.default is REQUIRED:
                out[name] = self.error(mark, path, f"missing required key {name!r}")
            elif field_key.kind in ("object", "map_of"):
                out[name] = self.check(None, field_key, path + (name,), mark)
            else:
                out[name] = field_key.default
        return out

    def _map_of(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if value is None:
            value = YMap(mark)
        if not isinstance(value, YMap):
            return self.error(mark, path, f"expected a mapping of names, got {describe(value)}")
        return {
            name: self.check(item, key.item, path + (name,), value.value_marks[name])
            for name, item in value.items()
        }

    def _list_of(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if not isinstance(value, YList):
            return self.error(mark, path, f"expected a list, got {describe(value)}")
        if len(value) < key.min_items:
            n = key.min_items
            return self.error(mark, path, f"needs at least {n} item{'s' if n > 1 else ''}")
        return [
            self.check(item, key.item, path + (i,), value.item_marks[i])
            for i, item in enumerate(value)
        ]

    def _entry(self, value: Any, key: Key, path: Path, mark: Mark) -> Any:
        if not isinstance(value, YMap):
            return self.error(
                mark,
                path,
                f"expected a body (a mapping) or a generator ({', '.join(key.variants)}), "
                f"got {describe(value)}",
            )
        generators = [name for name in value if name in key.variants]
        if not generators:
            return self.check(value, key.item, path, mark)
        if len(generators) > 1:
            return self.error(mark, path, f"one generator per entry, got {', '.join(generators)}")
        tag = generators[0]
        for name in value:
            if name != tag:
                self.error(
                    value.key_marks[name],
                    path + (name,),
                    f"unexpected key {name!r} next to {tag!r}: a generator entry has one key, "
                    f"put its options inside {tag}: {{...}}",
                )
        out = self.check(value[tag], key.variants[tag], path + (tag,), value.value_marks[tag])
        if isinstance(out, Checked):
            out.tag = tag
        return out


def _unknown_key(name: str, key: Key, value: Any = None) -> str:
    # (by identity, each dimension's table apart: both have a `box`)
    kinds = (*SHAPE_KINDS.items(), *SHAPE_KINDS_3D.items())
    kind = next((k for k, v in kinds if v is key), None)
    if kind is not None and name in INLINE_MATERIAL_3D:  # (2D's keys and density)
        # a material key written inside the kind's mapping, where the shape's geometry goes
        return (
            f"unknown key {name!r} in {kind}: it goes beside it, in the shape "
            f"(shape: {{{kind}: {{...}}, {name}: ...}}), or on the body"
        )
    # a key of the kind given beside it in the shape (shape: {box: {...}, rotation: ...}):
    # that, before a near spelling (`rotation` is near `restitution`)
    given = [k for k in (value or {}) if k in key.fields and key.fields[k].kind == "object"]
    for parent in given:
        if name in key.fields[parent].fields:
            return f"unknown key {name!r}; it goes inside {parent}: {parent}: {{..., {name}: ...}}"
    close = did_you_mean(name, key.fields)
    if close:
        return f"unknown key {name!r}; did you mean {close}?"
    for parent, child in key.fields.items():  # a key written one level too high
        if child.kind == "object" and name in child.fields:
            return f"unknown key {name!r}; did you mean {parent}.{name}?"
    return f"unknown key {name!r}; allowed keys: {', '.join(key.fields)}"


def check_scene(root: Any, mark: Mark, shared: Shared | None = None) -> tuple[Any, list[Problem]]:
    """Check a parsed scene tree against :data:`SCENE`.

    Returns (checked tree or INVALID, problems). The checked tree has every default of
    the table filled in; keys whose value is wrong hold INVALID. With `shared` (from
    yamlsrc.load_yaml_tree), the checks of its tree's nodes that ``root`` shares are
    worked out once and kept there (the checked values then shared too: read them only).
    """
    if _dimension_is_wrong(root):
        # the check of every key that depends on the dimension would only say what the
        # default dimension makes of it: report what both dimensions find wrong (the
        # dimension itself among it), nothing else
        both = [_check_scene_as(root, mark, shared, dimension)[1] for dimension in T.DIMENSIONS]
        return INVALID, [p for p in both[0] if all(p in other for other in both[1:])]
    return _check_scene_as(root, mark, shared, _dimension_of(root))


def _check_scene_as(
    root: Any, mark: Mark, shared: Shared | None, dimension: int
) -> tuple[Any, list[Problem]]:
    """:func:`check_scene` for a scene read as of ``dimension`` (2 or 3)."""
    checker = Checker(dimension, shared)
    if root is BROKEN:
        return INVALID, checker.problems
    if root is None:
        checker.error(mark, (), "the file is empty; a scene starts with `version: 1`")
        return INVALID, checker.problems
    if not isinstance(root, YMap):
        message = f"the top level must be a mapping (version: 1, bodies: ...), got {describe(root)}"
        checker.error(mark, (), message)
        return INVALID, checker.problems
    table = SCENES_BY_DIMENSION[checker.dimension]
    return checker.check(root, table, (), mark), checker.problems


def _dimension_is_wrong(root: Any) -> bool:
    """Whether the scene gives a world.dimension that is neither 2 nor 3."""
    world = root.get("world") if isinstance(root, YMap) else None
    if not isinstance(world, YMap) or world.get("dimension") is None:
        return False
    dimension = world["dimension"]
    return type(dimension) is not int or dimension not in T.DIMENSIONS


def _dimension_of(root: Any) -> int:
    """The scene's world.dimension as written (3 or 2; anything else, which the check
    reports, is read as the default 2)."""
    world = root.get("world") if isinstance(root, YMap) else None
    dimension = world.get("dimension") if isinstance(world, YMap) else None
    return 3 if type(dimension) is int and dimension == 3 else 2


# ---------------------------------------------------------------------------------------
# JSON Schema
# ---------------------------------------------------------------------------------------


_VECTOR_LENGTH = {"vec2": 2, "int2": 2, "vec3": 3, "int3": 3, "quat": 4}


def json_schema() -> dict:
    """The scene format as a JSON Schema (draft 2020-12) document.

    The top level's `world` and `bodies` accept either dimension's keys (so that an
    editor completes both); an if/then/else on world.dimension then holds a scene to its
    own dimension's format."""
    defs: dict[str, Any] = {}
    flat = _json(SCENE, defs)
    deep = _json(SCENE_3D, defs)
    props, props3 = flat["properties"], deep["properties"]
    # the keys whose format differs between the dimensions (world, materials, bodies)
    pinned = {k: (props[k], v) for k, v in props3.items() if v != props[k]}
    is_3d = {"properties": {"dimension": {"const": 3}}, "required": ["dimension"]}
    root = {
        **flat,
        "properties": {**props, **{k: _json_union(*v) for k, v in pinned.items()}},
        "if": {"properties": {"world": is_3d}, "required": ["world"]},
        "then": {"properties": {k: v[1] for k, v in pinned.items()}},
        "else": {"properties": {k: v[0] for k, v in pinned.items()}},
    }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": f"rbsim scene, format version {SCENE_VERSION}",
        **root,
        "$defs": dict(sorted(defs.items())),
    }


def _json_union(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    """A JSON Schema that accepts what ``a`` or ``b`` accepts, keeping the shape of ``a``
    (an object's properties side by side, a list's alternatives side by side)."""
    if a == b:
        return a
    if a.get("type") == b.get("type") == "object" and "properties" in a and "properties" in b:
        pa, pb = a["properties"], b["properties"]
        merged = {
            k: _json_union(pa[k], pb[k]) if k in pa and k in pb else pa.get(k, pb.get(k))
            for k in {**pa, **pb}
        }
        out = {k: v for k, v in a.items() if k not in ("allOf", "required", "default")}
        return out | {"properties": merged}
    if "anyOf" in a and "anyOf" in b and a.get("type") == b.get("type"):
        alternatives = list(a["anyOf"])
        for alt in b["anyOf"]:
            name = next(iter(alt.get("properties", {})), None)
            same = [
                i for i, x in enumerate(alternatives) if name and name in x.get("properties", {})
            ]
            if same:
                i = same[0]
                alternatives[i] = {
                    **alternatives[i],
                    "properties": {
                        name: {
                            "anyOf": [alternatives[i]["properties"][name], alt["properties"][name]]
                        }
                    },
                }
            elif alt not in alternatives:
                alternatives.append(alt)
        return {**a, "anyOf": alternatives}
    rest_a = {k: v for k, v in a.items() if k != "items"}
    if (
        a.get("type") == "array"
        and "items" in a
        and "items" in b
        and rest_a == {k: v for k, v in b.items() if k != "items"}
    ):
        return {**a, "items": _json_union(a["items"], b["items"])}
    return {"anyOf": [a, b]}


def _json(key: Key, defs: dict[str, Any]) -> dict[str, Any]:
    if key.ref is None:
        return _json_body(key, defs)
    if key.ref not in defs:
        defs[key.ref] = {}  # reserve the name first (no cycles today, but cheap insurance)
        defs[key.ref] = _json_body(key, defs)
    return {"$ref": f"#/$defs/{key.ref}"}


def _json_bounds(key: Key, kind: str) -> dict[str, Any]:
    out: dict[str, Any] = {"type": kind}
    if key.gt is not None:
        out["exclusiveMinimum"] = key.gt
    if key.ge is not None:
        out["minimum"] = key.ge
    if key.le is not None:
        out["maximum"] = key.le
    if key.within is not None:
        out["minimum"], out["maximum"] = -key.within, key.within
    return out


def _json_body(key: Key, defs: dict[str, Any]) -> dict[str, Any]:
    kind = key.kind
    out: dict[str, Any] = {"description": key.description}
    if kind == "number":
        out |= _json_bounds(key, "number")
    elif kind == "integer":
        out |= _json_bounds(key, "integer")
        if key.choices:
            out["enum"] = list(key.choices)
    elif kind == "string":
        out |= {"type": "string", "minLength": 1, "pattern": "^[^\\u0000-\\u001f\\u007f]+$"}
    elif kind == "file_name":
        out |= {"type": "string", "pattern": "^(?!\\.{1,2}$)[^/\\\\\\u0000-\\u001f\\u007f]+$"}
    elif kind == "enum":
        out |= {"type": "string", "enum": list(key.choices)}
    elif kind == "selection":
        out["anyOf"] = [
            {"type": "string", "enum": list(key.choices)},
            {"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 1},
        ]
    elif kind == "fraction":
        out["anyOf"] = [
            _json_bounds(key, "number"),
            {"type": "string", "pattern": FRACTION_PATTERN},
        ]
    elif kind in _VECTOR_LENGTH:
        n = _VECTOR_LENGTH[kind]
        item = _json_bounds(key, "integer" if kind.startswith("int") else "number")
        out |= {"type": "array", "items": item, "minItems": n, "maxItems": n}
    elif kind in ("points", "points3"):
        n = 2 if kind == "points" else 3
        item = _json_bounds(key, "number")
        point = {"type": "array", "items": item, "minItems": n, "maxItems": n}
        out |= {"type": "array", "items": point, "minItems": key.min_items}
        if key.max_items is not None:
            out["maxItems"] = key.max_items
    elif kind == "object":
        out |= {
            "type": "object",
            "properties": {name: _json(f, defs) for name, f in key.fields.items()},
            "additionalProperties": False,
        }
        required = [name for name, f in key.fields.items() if f.default is REQUIRED]
        if required:
            out["required"] = required
        rules = [{"oneOf": [{"required": [name]} for name in g]} for g in key.exactly_one]
        rules += [{"not": {"required": list(g)}} for g in key.at_most_one]
        if rules:
            out["allOf"] = rules
    elif kind == "map_of":
        out |= {"type": "object", "additionalProperties": _json(key.item, defs)}
    elif kind == "list_of":
        out |= {"type": "array", "items": _json(key.item, defs)}
        if key.min_items:
            out["minItems"] = key.min_items
    elif kind == "entry":
        generators = [
            {
                "type": "object",
                "properties": {name: _json(variant, defs)},
                "required": [name],
                "additionalProperties": False,
            }
            for name, variant in key.variants.items()
        ]
        out["anyOf"] = [_json(key.item, defs), *generators]
    else:
        raise ValueError(f"unknown kind {kind!r}")
    default = key.default
    if default not in (REQUIRED, NO_DEFAULT) and kind not in ("object", "map_of"):
        out["default"] = list(default) if isinstance(default, tuple) else default
    return out
