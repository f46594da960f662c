"""The fuzz driver of tests/test_fuzz.py: mutated scenes through `rbsim validate` and
`rbsim run --set world.steps=2`, all in this one process.

    python -m tests.fuzz --count 1000 --seed 18 --dir /tmp/fuzz

Each mutant starts from a shipped scene (rbsim/scenes) or a bad one (tests/bad_scenes)
and takes one to three mutations: a number set to an extreme (0, 5e-324, 1e308, 2**63,
an integer of 400 digits, nan, inf, ...), a value swapped for another type, a key
dropped, misspelt or copied next to its neighbours, a list or mapping emptied, a list
item doubled; or, on the text, a line doubled (a duplicate key) or dropped, the text cut
short, a stray character put in. A 3D scene (world.dimension: 3) also takes mutations of
what only 3D has (mutate_3d): orientations and rotations (a quaternion of zero norm, an
axis [0, 0, 0]), degenerate convex hulls (collinear, coplanar, duplicate or 4 points),
capsules of zero length, planes with zero normals, huge and tiny sizes, keys and vectors
of the other dimension, 3-vectors of the wrong length, huge angular velocities, torques,
inertia extremes and mass ratios. Each mutant is validated as it is and with the --set of
the run, and run; the click command is called in this process (as CliRunner does) and
everything it raises is caught.

Prints one JSON report on stdout: the number of mutants and every failure (a Python
exception out of the command, an exit code the rules do not allow, a validate/run
disagreement, a run failure without its documented message), each with the mutant's
text. Before each mutant, a line "mutant N: <what>" goes to stderr (flushed), so that a
hang or a crash names the mutant it happened in.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import random
import signal
import sys
import traceback
from pathlib import Path
from typing import Any

import yaml
from click.testing import CliRunner

from rbsim import cli

ROOT = Path(__file__).parent.parent
SCENES = ROOT / "rbsim" / "scenes"
BAD = Path(__file__).parent / "bad_scenes"
# scenes of hundreds to thousands of bodies: a second per mutant would cost the budget
HEAVY = {"pyramid100.yaml", "balls_in_box.yaml"}

EXTREMES: list[Any] = [
    0,
    -1,
    0.0,
    -0.0,
    5e-324,
    1e-300,
    1e-7,
    1e-6,
    0.999,
    1e6,
    1e7,
    1e9,
    1e21,
    1e200,
    1e308,
    -1e308,
    1.7976931348623157e308,
    2**31,
    2**63,
    2**64,
    10**400,
    -(10**400),
    math.nan,
    math.inf,
    -math.inf,
]
# at the bounds (cli.md: Bounds) and around them: mutants that still validate
EDGES: list[Any] = [
    1e-6,
    1.000001e-6,
    1e-3,
    0.1,
    10,
    100,
    1000,
    1e5,
    999999.0,
    1e6,
    -1e6,
    1e-9,
    1e12,
]
OTHER_TYPES: list[Any] = [
    "text",
    "",
    "1/0",
    "1/60",
    True,
    None,
    [],
    {},
    [1, 2],
    [1, 2, 3],
    [[0, 0], [1, 0]],
    {"a": 1},
    {"circle": {"radius": 1}},
]
STRAY = ["\t", ":", "[", "]", "{", "&a", "*a", "!!python/object ", "%", "- ", "'", '"', "\x00"]

# exit codes the rules allow, and what a run's exit 1 must say (cli.md: exit codes)
VALIDATE_CODES = {0, 3}
RUN_CODES = {0, 1, 3}
RUN_FAILURES = (
    "became non-finite",
    "left the simulated region",
    "overflowed",
    "out of memory",
    "cannot write",
)
STEPS = ("--set", "world.steps=2")


class Hang(Exception):
    """One command took longer than the per-mutant limit."""


def sources() -> list[tuple[Path, str, Any]]:
    """(path, text, parsed tree or None) of every scene the mutants start from."""
    out = []
    for path in sorted(SCENES.rglob("*.yaml")) + sorted(BAD.glob("*.yaml")):
        if path.name in HEAVY:
            continue
        text = path.read_bytes().decode("utf-8", "replace")
        try:
            tree = yaml.safe_load(text)
        except yaml.YAMLError:
            tree = None
        out.append((path, text, tree if isinstance(tree, dict) else None))
    return out


def is_3d(tree: Any) -> bool:
    """Whether a parsed scene says world.dimension: 3."""
    world = tree.get("world") if isinstance(tree, dict) else None
    return isinstance(world, dict) and world.get("dimension") == 3


def _places(node: Any, path: tuple = ()) -> list[tuple]:
    """Every (path, value) inside a parsed tree, containers included."""
    out = [(path, node)]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _places(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _places(v, path + (i,))
    return out


def _parent(tree: Any, path: tuple) -> Any:
    for part in path[:-1]:
        tree = tree[part]
    return tree


def _misspell(word: str, rng: random.Random) -> str:
    i = rng.randrange(len(word) + 1)
    how = rng.choice(("drop", "add", "swap"))
    if how == "drop" and word:
        i = min(i, len(word) - 1)
        return word[:i] + word[i + 1 :]
    if how == "swap" and len(word) > 1:
        i = min(i, len(word) - 2)
        return word[:i] + word[i + 1] + word[i] + word[i + 2 :]
    return word[:i] + rng.choice("aeiosx_") + word[i:]


def mutate_tree(tree: Any, rng: random.Random) -> str:
    """Apply one mutation to the parsed tree in place; returns what it did."""
    places = [(p, v) for p, v in _places(tree) if p]
    path, value = rng.choice(places)
    parent, key = _parent(tree, path), path[-1]
    numbers = [(p, v) for p, v in places if isinstance(v, int | float) and not isinstance(v, bool)]
    op = rng.choice(
        ("extreme", "extreme", "extreme", "type", "drop", "misspell", "empty", "double")
    )
    if op == "extreme" and numbers:
        path, value = rng.choice(numbers)
        new = rng.choice(EXTREMES if rng.random() < 0.6 else EDGES)
        _parent(tree, path)[path[-1]] = new
        return f"{_show(path)}: {_brief(value)} -> {_brief(new)}"
    if op == "type":
        new = copy.deepcopy(rng.choice(OTHER_TYPES))
        parent[key] = new
        return f"{_show(path)}: -> {_brief(new)}"
    if op == "drop":
        del parent[key]
        return f"{_show(path)}: dropped"
    if op == "misspell" and isinstance(key, str):
        parent[_misspell(key, rng)] = parent.pop(key)
        return f"{_show(path)}: key misspelt"
    if op == "empty" and isinstance(value, list | dict):
        parent[key] = type(value)()
        return f"{_show(path)}: emptied"
    if isinstance(parent, list):
        parent.insert(key, copy.deepcopy(value))
        return f"{_show(path)}: doubled"
    if isinstance(parent, dict) and isinstance(key, str):
        parent[key + rng.choice(("", "s", "_2"))] = copy.deepcopy(value)
        return f"{_show(path)}: copied next to itself"
    new = rng.choice(EXTREMES)
    parent[key] = new
    return f"{_show(path)}: -> {_brief(new)}"


def mutate_text(text: str, rng: random.Random) -> tuple[str, str]:
    """One mutation of the text itself: (new text, what it did)."""
    lines = text.split("\n")
    op = rng.choice(("double", "drop", "cut", "stray"))
    i = rng.randrange(len(lines))
    if op == "double":
        lines.insert(i, lines[i])
        return "\n".join(lines), f"line {i + 1} doubled"
    if op == "drop":
        del lines[i]
        return "\n".join(lines), f"line {i + 1} dropped"
    if op == "cut":
        at = rng.randrange(len(text) + 1)
        return text[:at], f"cut after {at} characters"
    at = rng.randrange(len(text) + 1)
    stray = rng.choice(STRAY)
    return text[:at] + stray + text[at:], f"{stray!r} put in at {at}"


# 3D mutations: what only a 3D scene has, and the edges of its bounds ----------------------

# quaternions [w, x, y, z]: zero norm, tiny and huge norms, wrong lengths, non-finite
QUATERNIONS: list[Any] = [
    [0, 0, 0, 0],
    [0.0, -0.0, 0.0, -0.0],
    [5e-324, 0, 0, 0],
    [1e-300, 1e-300, 0, 0],
    [1e-7, 0, 0, 0],
    [1e6, 1e6, 1e6, 1e6],
    [1e7, 0, 0, 0],
    [1e308, 1e308, 0, 0],
    [math.nan, 0, 0, 0],
    [1, 0, 0],
    [1, 0, 0, 0, 0],
    [0.5, 0.5, 0.5, 0.5],
    [-1, 0, 0, 0],
    [0, 1, 0, 0],
    [1, 1e-17, 0, 0],
]
AXES: list[Any] = [
    [0, 0, 0],
    [5e-324, 0, 0],
    [1e-300, 0, 0],
    [1e-7, 0, 0],
    [1e6, 1e6, 1e6],
    [1e308, 0, 0],
    [math.inf, 0, 0],
    [0, 1],
    [0, 0, 1, 0],
    [1, 1, 1],
]
ANGLES: list[Any] = [0, 1e-300, 3.141592653589793, 1e6, -1e6, 1e7, 1e300, math.nan]
# 3-vectors at and past the bounds, of the wrong length, of the other dimension
VECTORS: list[Any] = [
    [0, 0, 0],
    [1e6, 1e6, 1e6],
    [-1e6, 1e6, -1e6],
    [1e7, 0, 0],
    [1e308, 0, 0],
    [5e-324, 5e-324, 5e-324],
    [math.nan, 0, 0],
    [1, 2],
    [1, 2, 3, 4],
    [],
    [[1, 2, 3]],
    5.0,
]
SIZES: list[Any] = [
    [1e-6, 1e-6, 1e-6],
    [1e-6, 1, 1],
    [1e6, 1e-6, 1e6],
    [1e6, 1e6, 1e6],
    [1e-3, 1e3, 1e-3],
    [1, 1e-7, 1],
    [5e-324, 1, 1],
    [0, 1, 1],
    [1, 1],
    [1, 1, 1, 1],
]
# point sets a hull is built from: degenerate, at the edges of the bounds, or fine
HULLS: list[Any] = [
    [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]],  # collinear
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]],  # coplanar
    [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]],  # one point four times
    [[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]],  # three points, one doubled
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],  # a tetrahedron: the fewest points
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1e-12]],  # flat to rounding
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1e-6]],  # flat at the width bound
    [[0, 0, 0], [1e-6, 0, 0], [0, 1e-6, 0], [0, 0, 1e-6]],  # the smallest
    [[0, 0, 0], [1e6, 0, 0], [0, 1e6, 0], [0, 0, 1e6]],  # the largest
    [[0, 0, 0], [1e6, 0, 0], [0, 1e-3, 0], [0, 0, 1e-3]],  # a needle
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1e-9, 1e-9, 1e-9]],  # a point 1e-9 inside
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1 + 1e-12, 0, 0]],  # near-duplicate corner
    [[1, 2], [3, 4], [5, 6], [7, 8]],  # 2D points
    [[0, 0, 0], [1, 0, 0], [0, 1, 0]],  # three points
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, math.nan]],
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1e308]],
    [
        [math.cos(k) * (1 + 1e-9 * k), math.sin(k), math.cos(3 * k) * 1e-3] for k in range(40)
    ],  # a thin, slightly bumpy disc of 40 points
    [[(k % 3) - 1, (k // 3 % 3) - 1, (k // 9) - 1] for k in range(27)],  # a 3x3x3 lattice
]
CAPSULES: list[Any] = [
    {"a": [0, 0, 0], "b": [0, 0, 0], "radius": 0.1},  # zero length
    {"a": [0, 0, 0], "b": [0, 1e-12, 0], "radius": 0.1},  # zero length to rounding
    {"a": [0, 0, 0], "b": [0, 1, 0], "radius": 0},
    {"a": [0, 0, 0], "b": [0, 1, 0], "radius": 1e-6},
    {"a": [0, 0, 0], "b": [0, 1e6, 0], "radius": 1e-6},  # a needle
    {"a": [-1e6, 0, 0], "b": [1e6, 0, 0], "radius": 1},
    {"a": [0, 0, 0], "b": [0, 1e-6, 0], "radius": 1e6},
    {"a": [0, 0], "b": [0, 1], "radius": 0.1},
    {"a": [0, 0, 0], "radius": 0.1},
]
PLANES: list[Any] = [
    {"normal": [0, 0, 0], "offset": 0},
    {"normal": [5e-324, 0, 0], "offset": 0},
    {"normal": [1e-300, 1e-300, 0], "offset": 0},
    {"normal": [1e6, 1e6, 1e6], "offset": 0},
    {"normal": [0, -1, 0], "offset": 0},  # upside down: every body starts inside it
    {"normal": [0, 1, 0], "offset": 1e6},
    {"normal": [0, 1, 0], "offset": 1e7},
    {"normal": [0, 1, 0], "offset": math.inf},
    {"normal": [0, 1], "offset": 0},
    {"normal": [1, 1, 1]},
]
SHAPES_3D: list[Any] = [{"sphere": {"radius": r}} for r in (1e-6, 1e-7, 1e6, 1e7, 5e-324, 0)] + [
    {"box": {"size": [1, 1, 1], "offset": [1e6, 0, 0]}},
    {"box": {"size": [1, 1, 1], "orientation": [0, 0, 0, 0]}},
    {"box": {"size": [1, 1, 1], "rotation": {"axis": [0, 0, 0], "angle": 1}}},
    {"box": {"size": [1, 1, 1], "orientation": [1, 0, 0, 0], "rotation": {"axis": [1, 0, 0]}}},
    {"plane": {"normal": [0, 1, 0]}, "offset": [0, 1, 0]},
    {"circle": {"radius": 0.5}},
    {"segment": {"a": [0, 0], "b": [1, 0]}},
    {"polygon": {"vertices": [[0, 0], [1, 0], [0, 1]]}},
]
BODY_VECTOR_KEYS = ("position", "velocity", "angular_velocity", "force", "force_point", "torque")
GENERATORS = ("stack", "pyramid", "grid")
GENERATOR_VECTOR_KEYS = ("origin", "spacing", "velocity", "count", "size")
MASSES: list[Any] = [1e-12, 1e-6, 1e6, 1e18, 1e19, 1e-13]
DENSITIES: list[Any] = [1e-6, 1e6, 1e-7, 1e7]


def _bodies_of(tree: Any) -> list[dict]:
    """The body mappings of a tree (generators included), or [] when there are none."""
    bodies = tree.get("bodies") if isinstance(tree, dict) else None
    return [b for b in bodies if isinstance(b, dict)] if isinstance(bodies, list) else []


def _generator_of(body: dict) -> dict | None:
    """The mapping inside a generator item ({stack: {...}}), or None for a body."""
    return next((body[g] for g in GENERATORS if isinstance(body.get(g), dict)), None)


def _shape_slots(body: dict) -> list[tuple[Any, Any]]:
    """(container, key) of every shape of a body or a generator, for replacing it."""
    inner = _generator_of(body)
    slots: list[tuple[Any, Any]] = []
    if inner is not None and "shape" in inner:
        slots.append((inner, "shape"))
    if "shape" in body:
        slots.append((body, "shape"))
    shapes = body.get("shapes")
    if isinstance(shapes, list):
        slots += [(shapes, i) for i in range(len(shapes))]
    return slots


def _kind_of(shape: Any) -> tuple[str, dict] | None:
    """(kind, its mapping) of a shape mapping, or None."""
    if not isinstance(shape, dict):
        return None
    for kind in ("sphere", "box", "capsule", "convex", "plane"):
        if isinstance(shape.get(kind), dict):
            return kind, shape[kind]
    return None


def mutate_3d(tree: Any, rng: random.Random) -> str:
    """One mutation of what a 3D scene has (quaternions, axes, hulls, capsules, planes,
    3-vectors, angular quantities, inertia and mass extremes, keys of the other
    dimension), in place; returns what it did. Raises IndexError when the tree has
    nothing of the kind chosen."""
    bodies = _bodies_of(tree)
    body = rng.choice(bodies)
    inner = _generator_of(body)
    where = f"bodies.{tree['bodies'].index(body)}"
    op = rng.choice(
        (
            "orientation", "rotation", "shape_frame", "hull", "hull", "capsule", "plane",
            "shape", "size", "vector", "vector", "spin", "torque", "inertia", "ratio",
            "dimension", "foreign",
        )
    )  # fmt: skip
    target = inner if inner is not None else body
    if op == "orientation":
        new = copy.deepcopy(rng.choice(QUATERNIONS))
        target["orientation"] = new
        if rng.random() < 0.7:
            target.pop("rotation", None)
        return f"{where}.orientation -> {_brief(new)}"
    if op == "rotation":
        new = {"axis": copy.deepcopy(rng.choice(AXES)), "angle": rng.choice(ANGLES)}
        target["rotation"] = new
        if rng.random() < 0.7:
            target.pop("orientation", None)
        return f"{where}.rotation -> {_brief(new)}"
    slots = _shape_slots(body)
    if op == "shape_frame":
        container, key = rng.choice(slots)
        shape = container[key]
        kind = _kind_of(shape)
        if kind is None:
            raise IndexError("no 3D shape")
        what = rng.choice(("offset", "orientation", "rotation"))
        new = copy.deepcopy(
            rng.choice(VECTORS)
            if what == "offset"
            else rng.choice(QUATERNIONS)
            if what == "orientation"
            else {"axis": rng.choice(AXES), "angle": rng.choice(ANGLES)}
        )
        kind[1][what] = new
        return f"{where} shape {kind[0]}.{what} -> {_brief(new)}"
    if op in ("hull", "capsule", "plane", "shape"):
        container, key = rng.choice(slots)
        if op == "hull":
            new = {"convex": {"vertices": copy.deepcopy(rng.choice(HULLS))}}
        elif op == "capsule":
            new = {"capsule": copy.deepcopy(rng.choice(CAPSULES))}
        elif op == "plane":
            new = {"plane": copy.deepcopy(rng.choice(PLANES))}
        else:
            new = copy.deepcopy(rng.choice(SHAPES_3D))
        old = _kind_of(container[key])
        for extra in ("offset", "orientation", "rotation"):  # keep the shape's frame
            if old is not None and extra in old[1] and op != "plane":
                next(iter(new.values()))[extra] = old[1][extra]
        if isinstance(container[key], dict):  # keep its material keys
            for k, v in container[key].items():
                if k in ("material", "density", "friction", "restitution"):
                    new[k] = v
        container[key] = new
        return f"{where} shape -> {_brief(new)}"
    if op == "size":
        sized = [
            (s[1], "size") for s in (_kind_of(c[k]) for c, k in slots) if s and s[0] == "box"
        ] + [(s[1], "radius") for s in (_kind_of(c[k]) for c, k in slots) if s and "radius" in s[1]]
        if inner is not None and "size" in inner:
            sized.append((inner, "size"))
        holder, key = rng.choice(sized)
        new = (
            copy.deepcopy(rng.choice(SIZES))
            if key == "size"
            else rng.choice((1e-6, 1e-7, 1e6, 1e7, 5e-324, 0.0, 1e-3))
        )
        holder[key] = new
        return f"{where} {key} -> {_brief(new)}"
    if op == "vector":
        key = rng.choice(BODY_VECTOR_KEYS if inner is None else GENERATOR_VECTOR_KEYS)
        new = copy.deepcopy(rng.choice(VECTORS))
        target[key] = new
        return f"{where}.{key} -> {_brief(new)}"
    if op == "spin":
        w = rng.choice((1e3, 1e5, 1e6, 1e6 + 1, 1e9))
        new = [w * rng.choice((-1, 0, 1)) for _ in range(3)]
        target["angular_velocity"] = new
        return f"{where}.angular_velocity -> {new}"
    if op == "torque":
        t = rng.choice((1e2, 1e4, 1e5, 1e6, 1e9, 1e306))
        target["torque" if rng.random() < 0.8 else "force"] = new = [
            t * rng.choice((-1, 0, 1)) for _ in range(3)
        ]
        if rng.random() < 0.3:
            target["force_point"] = copy.deepcopy(rng.choice(VECTORS[:6]))
        return f"{where} torque/force -> {new}"
    if op == "inertia":  # a long thin body, heavy or light
        container, key = rng.choice(slots)
        shape = rng.choice(
            (
                {"box": {"size": [1e-3, 1e3, 1e-3]}},
                {"box": {"size": [1e-6, 1, 1]}},
                {"capsule": {"a": [0, -500, 0], "b": [0, 500, 0], "radius": 5e-4}},
                {"sphere": {"radius": 1e-6}},
            )
        )
        container[key] = copy.deepcopy(shape)
        holder = target if rng.random() < 0.5 else container[key]
        holder["mass" if holder is target else "density"] = new = rng.choice(
            MASSES if holder is target else DENSITIES
        )
        return f"{where} shape -> {_brief(shape)}, mass/density {new}"
    if op == "ratio":  # one body far heavier or lighter than the rest
        new = rng.choice(MASSES)
        target["mass"] = new
        other = rng.choice(bodies)
        other_target = _generator_of(other) or other
        other_target["mass"] = rng.choice(MASSES)
        return f"{where}.mass -> {new}, another body's mass {other_target['mass']}"
    if op == "dimension":
        world = tree.setdefault("world", {})
        new = rng.choice((2, 4, "3", 3.0, True, None, 0))
        if new is None:
            world.pop("dimension", None)
            return "world.dimension dropped"
        world["dimension"] = new
        return f"world.dimension -> {new!r}"
    # foreign: a key of the 2D format in the 3D scene
    key, new = rng.choice(
        (
            ("angle", 0.3),
            ("angular_velocity", 5.0),
            ("torque", 1.0),
            ("position", [0, 1]),
            ("velocity", [1, 0]),
            ("force", [0, 1]),
        )
    )
    if rng.random() < 0.3:
        tree.setdefault("world", {})["gravity"] = [0, -9.81]
        return "world.gravity -> [0, -9.81]"
    target[key] = new
    return f"{where}.{key} -> {new!r} (2D)"


def _show(path: tuple) -> str:
    return ".".join(str(p) for p in path)


def _brief(value: Any) -> str:
    """repr, with an integer of more than 20 digits by its length."""
    if isinstance(value, int) and len(str(abs(value))) > 20:
        return f"<an integer of {len(str(abs(value)))} digits>"
    return repr(value)


def make_mutant(source: tuple[Path, str, Any], rng: random.Random) -> tuple[str, list[str]]:
    """(mutant text, what was done to it) from one source scene."""
    path, text, tree = source
    done: list[str] = []
    for _ in range(rng.choice((1, 1, 2, 3))):
        if tree is not None and rng.random() < 0.8:
            new = copy.deepcopy(tree)
            try:
                what = (mutate_3d if is_3d(new) and rng.random() < 0.6 else mutate_tree)(new, rng)
            except (IndexError, KeyError, TypeError, ValueError):  # nothing there to mutate
                continue
            tree, text = new, yaml.safe_dump(new, sort_keys=False, allow_unicode=True)
            done.append(what)
        else:
            text, what = mutate_text(text, rng)
            done.append(what)
            tree = None  # the text no longer matches a tree
    return text, done


def invoke(args: list[str], limit: float) -> tuple[int | None, str, str | None]:
    """Run the rbsim command line with `args` in this process: (exit code, stderr,
    traceback of an exception it let out, or None). `limit` s: a Hang after that."""
    try:
        runner = CliRunner(mix_stderr=False)  # click < 8.2 mixes the streams otherwise
    except TypeError:
        runner = CliRunner()
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        result = runner.invoke(cli.main, args, catch_exceptions=True)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    error = None
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        exc = result.exception
        error = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    try:
        stderr = result.stderr
    except ValueError:
        stderr = ""
    return result.exit_code, stderr, error


def judge(
    validate: tuple[int | None, str, str | None],
    validate_set: tuple[int | None, str, str | None],
    run: tuple[int | None, str, str | None],
) -> list[str]:
    """What is wrong with one mutant's three results (empty: nothing)."""
    problems = []
    for name, (code, stderr, error) in (
        ("validate", validate),
        ("validate --set", validate_set),
        ("run", run),
    ):
        if error is not None:
            problems.append(f"{name}: an exception got out:\n{error}")
        elif "Traceback" in stderr:
            problems.append(f"{name}: a traceback on stderr:\n{stderr}")
        allowed = RUN_CODES if name == "run" else VALIDATE_CODES
        if error is None and code not in allowed:
            problems.append(f"{name}: exit {code}, expected one of {sorted(allowed)}:\n{stderr}")
    (v_code, _, _), (r_code, r_err, _) = validate_set, run
    if v_code == 3 and r_code != 3:
        problems.append(f"run exits {r_code} on a scene that validate rejects")
    if v_code == 0 and r_code == 3:
        problems.append(f"run rejects a scene that validate accepts:\n{r_err}")
    if r_code == 1 and not (r_err.startswith("error: ") and any(s in r_err for s in RUN_FAILURES)):
        problems.append(f"run exits 1 without a documented failure:\n{r_err}")
    if r_code == 1 and len(r_err.strip().splitlines()) != 1:
        problems.append(f"run's failure is not one line:\n{r_err}")
    return problems


def main(argv: list[str] | None = None) -> int:
    """Run the mutants and print the report; 0 (the report says what failed)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=18)
    parser.add_argument("--dir", type=Path, required=True, help="folder for the mutant files")
    parser.add_argument("--limit", type=float, default=20.0, help="s per command")
    args = parser.parse_args(argv)

    def hang(signum: int, frame: Any) -> None:
        raise Hang(f"longer than {args.limit:g} s")

    signal.signal(signal.SIGALRM, hang)
    rng = random.Random(args.seed)
    pool = sources()
    good = [s for s in pool if s[0].is_relative_to(SCENES)]
    good_3d = [s for s in good if is_3d(s[2])]
    args.dir.mkdir(parents=True, exist_ok=True)
    scene, out = args.dir / "mutant.yaml", args.dir / "mutant.h5"
    failures = []
    codes: dict[str, dict[str, int]] = {"validate": {}, "run": {}}
    from_3d = 0  # mutants of a 3D scene
    for k in range(args.count):
        # mostly runnable ones; 3D scenes (a quarter of those shipped) in two of five
        draw = rng.random()
        source = rng.choice(good_3d if draw < 0.4 else good if draw < 0.8 else pool)
        from_3d += is_3d(source[2])
        text, done = make_mutant(source, rng)
        print(f"mutant {k}: {source[0].relative_to(ROOT)}: {'; '.join(done)}", file=sys.stderr)
        sys.stderr.flush()
        scene.write_bytes(text.encode("utf-8", "surrogateescape"))
        out.unlink(missing_ok=True)
        v = invoke(["validate", str(scene)], args.limit)
        vs = invoke(["validate", str(scene), *STEPS], args.limit)
        r = invoke(["run", str(scene), *STEPS, "-q", "-o", str(out)], args.limit)
        for name, result in (("validate", v), ("run", r)):
            key = str(result[0])
            codes[name][key] = codes[name].get(key, 0) + 1
        problems = judge(v, vs, r)
        if problems:
            failures.append(
                {
                    "mutant": k,
                    "source": str(source[0].relative_to(ROOT)),
                    "mutations": done,
                    "problems": problems,
                    "text": text[:3000],
                }
            )
    report = {"mutants": args.count, "from_3d": from_3d, "exit_codes": codes}
    json.dump({**report, "failures": failures}, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
