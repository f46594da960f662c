"""Scene files: YAML text -> a validated, fully resolved :class:`Scene`.

The format is version 1 of docs/format.md. Everything downstream (model,
world, pymunk bridge) reads only the dataclasses below: no defaults are applied
after this module, every generator (`pyramid`, `stack`, `grid`) is expanded into
plain bodies, every material is resolved onto each shape, and every shape is
expressed in its body's frame (metres, radians).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from . import geometry3d as g3
from . import schema
from .geometry3d import IDENTITY, Quat
from .mass import body_mass_properties
from .mass3d import body_mass_properties_3d, principal_axes
from .schema import INVALID, Checked, did_you_mean
from .types import SHAPE_KINDS, SHAPE_KINDS_3D
from .yamlsrc import (
    BROKEN,
    Mark,
    Problem,
    Shared,
    YList,
    YMap,
    copy_node,
    format_path,
    load_yaml,
    load_yaml_tree,
)

Vec2 = tuple[float, float]
Vec = tuple[float, ...]  # a 2-vector in a 2D scene, a 3-vector in a 3D one
_ZERO3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Material:
    """Surface and bulk properties: density kg/m², friction (Coulomb μ), restitution e."""

    density: float = 1.0
    friction: float = 0.6
    restitution: float = 0.0


@dataclass(frozen=True)
class Shape:
    """One shape of a body, in the body frame (metres about the body origin).

    kind: the kind as written in the scene ("circle", "box", "polygon", "segment" in
        2D; "sphere", "box", "capsule", "convex", "plane" in 3D).
    vertices: circle -> ((cx, cy),), its centre; segment -> (a, b);
        box and polygon -> convex counter-clockwise vertices (a box is turned
        into its four corners with `offset` and `angle` applied).
        3D: sphere -> (centre,); capsule -> (a, b); box -> its 8 corners (order of
        geometry3d.BOX_SIGNS); convex -> its hull's extreme points, in the order given;
        plane -> (the point of the plane nearest the body origin,). The shape's offset
        and orientation are applied.
    radius: circle radius; segment radius (a capsule when > 0); 0 for polygons.
        3D: sphere and capsule radius, 0 otherwise.
    size, offset, angle: the box as written (for output and the pymunk bridge);
        size is (0, 0) for other kinds. 3D: size (3,) of a box; offset (3,) and
        orientation (w, x, y, z) as written for a sphere and a box; a capsule's and a
        convex's are applied to their vertices (offset zero, orientation identity
        here); angle is 0.
    material: resolved material of this shape.
    faces: 3D box and convex: the hull's triangles, indices into `vertices`,
        counter-clockwise seen from outside.
    normal: 3D plane: unit outward normal in the body frame (the solid is
        n·(x − vertices[0]) <= 0).
    """

    kind: str
    vertices: tuple[Vec, ...]
    radius: float
    material: Material
    size: Vec = (0.0, 0.0)
    offset: Vec = (0.0, 0.0)
    angle: float = 0.0
    faces: tuple[tuple[int, int, int], ...] = ()
    normal: Vec = ()
    orientation: Quat = IDENTITY


@dataclass(frozen=True)
class Body:
    """A body as placed in the scene.

    position: the body origin in the world (m); angle (rad); velocity of the
    centre of mass (m/s); angular_velocity (rad/s). mass (kg) overrides the
    density-derived mass when not None (inertia scales with it). force (N) is a
    constant world-frame force applied at force_point (body frame, m) or at the
    centre of mass when force_point is None; torque (N·m) is constant.

    In 3D, position, velocity, force and force_point are 3-vectors; angle is 0;
    orientation is the unit quaternion (w, x, y, z) of the body frame (identity in 2D);
    angular_velocity (rad/s) and torque (N·m) are world-frame 3-vectors.
    """

    name: str
    type: str
    position: Vec
    angle: float
    velocity: Vec
    angular_velocity: float | Vec
    shapes: tuple[Shape, ...]
    mass: float | None = None
    force: Vec = (0.0, 0.0)
    force_point: Vec | None = None
    torque: float | Vec = 0.0
    orientation: Quat = IDENTITY


@dataclass(frozen=True)
class World:
    """gravity (m/s²), dt (s), steps (count; `duration` resolved to round(duration/dt)),
    linear and angular damping (1/s), mixing rules for friction and restitution;
    dimension 2 or 3 (gravity is then a 3-vector)."""

    gravity: Vec = (0.0, -9.81)
    dt: float = 1.0 / 60.0
    steps: int = 600
    linear_damping: float = 0.0
    angular_damping: float = 0.0
    friction_mixing: str = "sqrt"  # sqrt | multiply | min | max
    restitution_mixing: str = "max"  # max | multiply | min
    dimension: int = 2


@dataclass(frozen=True)
class Solver:
    """Solver settings; see rbsim.constants for what each one trades."""

    substeps: int = 4
    iterations: int = 1
    integrator: str = "symplectic_euler"  # or explicit_euler
    rotation: str = "normalize"  # or exact, split (a 3D scene's default: schema.SOLVER_3D)
    restitution_threshold: float = 1.0  # m/s
    threads: int | None = None  # None: the machine's cores (rbsim.config.default_threads)


@dataclass(frozen=True)
class Output:
    """every: write every k-th step (step 0 and the last step are always written).
    precision: "float64" | "float32" (per-body series). compression: "none" | "lzf" |
    "gzip". bodies: "all", "moving", or names and patterns (``*`` matches any text).
    contacts: "none" | "points" (each frame's touching contact points, /contacts)."""

    every: int = 1
    precision: str = "float64"
    compression: str = "none"
    bodies: str | tuple[str, ...] = "all"
    contacts: str = "none"

    def body_indices(self, names: Sequence[str], types: Sequence[str]) -> list[int]:
        """Indices of the bodies written in every frame, in scene order."""
        if self.bodies == "all":
            return list(range(len(names)))
        if self.bodies == "moving":
            return [i for i, t in enumerate(types) if t != "static"]
        rules = [_pattern(p) for p in self.bodies]
        return [i for i, n in enumerate(names) if any(r.fullmatch(n) for r in rules)]


def _pattern(text: str) -> re.Pattern[str]:
    """A body-name pattern: ``*`` matches any text, everything else itself."""
    return re.compile(".*".join(re.escape(part) for part in text.split("*")))


@dataclass(frozen=True)
class Scene:
    """A resolved scene. `source` is the YAML text as given (for /parameters);
    `path` the file it came from (or "<string>")."""

    name: str
    world: World
    solver: Solver
    output: Output
    bodies: tuple[Body, ...]
    materials: dict[str, Material] = field(default_factory=dict)
    compare: dict[str, Any] = field(default_factory=dict)  # tolerances; `statistics` a dict
    reference: dict[str, Any] = field(default_factory=dict)  # `rbsim sweep`; {} = converged
    source: str = ""
    path: str = "<string>"
    # what the scene does that its text may not say (a duration rounded to whole steps):
    # warnings, each naming the file, line and key; not part of the scene's value
    notes: tuple[SceneIssue, ...] = field(default=(), compare=False)


# ---------------------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SceneIssue:
    """One problem in a scene: where (file, 1-based line and column), which key
    (`bodies[3].shape.circle.radius`, empty when the problem is not about one key) and
    what. A problem in a command-line override has no line and column; ``override`` is
    then the key of the ``--set`` it came from."""

    file: str
    line: int | None
    column: int | None
    key_path: str
    message: str
    override: str | None = None

    def __str__(self) -> str:
        if self.override is not None:
            where = f"{self.file}: --set {self.override}"
            same = self.key_path == format_path(_override_path(self.override))
            key_path = "" if same else self.key_path  # do not say world.dt twice
        else:
            where = f"{self.file}:{self.line}:{self.column}"
            key_path = self.key_path
        return f"{where}: {key_path}: {self.message}" if key_path else f"{where}: {self.message}"


class SceneError(Exception):
    """An invalid scene; ``errors`` lists every problem found, in file order."""

    def __init__(self, errors: Sequence[SceneIssue]) -> None:
        self.errors: list[SceneIssue] = list(errors)
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join(str(issue) for issue in self.errors)


def _issues(file: str, problems: Iterable[Problem]) -> list[SceneIssue]:
    out: dict[SceneIssue, None] = {}  # ordered and without repeats
    for p in problems:
        path = format_path(p.path)
        if p.mark.origin is not None:
            override = p.mark.origin.removeprefix("--set ")
            issue = SceneIssue(file, None, None, path, p.message, override)
        else:
            issue = SceneIssue(file, p.mark.line, p.mark.column, path, p.message)
        out[issue] = None
    return sorted(out, key=lambda i: (i.override is not None, i.line or 0, i.column or 0))


# ---------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------

DEFAULT_MATERIAL = Material(**schema.DEFAULT_MATERIAL)

# Guards against typos such as `pyramid: {base: 100000}` or `dt: 1e-12`.
MAX_BODIES = 1_000_000
MAX_STEPS = 1_000_000_000
# How far world.duration / dt may be from a whole number (relative) and count as one:
# round-off in the division (duration 1 at dt 1/60 is 60.00000000000001 steps).
DURATION_ROUNDOFF = 1e-9


def load_scene(path: str | Path, overrides: str | Sequence[str] = ()) -> Scene:
    """Read, validate and resolve the scene file at ``path``.

    ``overrides`` are ``key.path=value`` strings (``--set``; a single string is one),
    applied before validation.
    Raises SceneError listing every problem found (including an unreadable file).
    """
    file = str(path)

    def fail(line: int, column: int, message: str) -> SceneError:
        return SceneError([SceneIssue(file, line, column, "", message)])

    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise fail(1, 1, "file not found") from None
    except IsADirectoryError:
        raise fail(1, 1, "is a directory, not a scene file") from None
    except PermissionError:
        raise fail(1, 1, "permission denied") from None
    except OSError as err:
        raise fail(1, 1, f"cannot read the file: {err.strerror or err}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        line_start = data.rfind(b"\n", 0, err.start) + 1
        column = len(data[line_start : err.start].decode("utf-8", "replace")) + 1
        message = f"not valid UTF-8 (byte 0x{data[err.start]:02x}); save the file as UTF-8"
        raise fail(line, column, message) from None
    return load_scene_text(text, path=file, overrides=overrides)


def load_scene_text(
    text: str, path: str = "<string>", overrides: str | Sequence[str] = ()
) -> Scene:
    """Validate and resolve a scene given as YAML text; ``path`` is used in messages
    and for the default name. Raises SceneError listing every problem found."""
    root, mark, problems, shared = load_yaml_tree(text)
    if isinstance(root, YMap):
        root = copy_node(root)  # (apply_overrides copies the nodes below it that it changes)
        problems += apply_overrides(root, overrides)
    scene = None
    if root is not None or not problems:  # a syntax error leaves nothing to check
        checked, found = schema.check_scene(root, mark, shared)
        problems += found
        if checked is not INVALID:
            resolver = _Resolver(shared)
            scene = resolver.scene(checked, text, path)
            problems += resolver.problems
    if problems or scene is None:
        raise SceneError(_issues(path, problems))
    return scene


# ---------------------------------------------------------------------------------------
# --set overrides
# ---------------------------------------------------------------------------------------


class _Quoted(str):
    """A part of a key path written in quotes: a name as it is, never an index."""


class _Bracketed(str):
    """A part of a key path written in brackets, unquoted: a list item (``bodies[0]``)."""


_NAME_MARKS = frozenset(".[]\"'")  # what a name in a key path must be quoted for


def _split_key(key: str) -> list[str]:
    """'bodies[2].velocity' or 'bodies.2.velocity' -> ['bodies', '2', 'velocity']. A part
    in double or single quotes is a name as written, dots and brackets and all:
    'bodies."ball_e1.0".velocity' and "bodies['stick[0]'].velocity" (_Quoted). A quote
    left open, or text after a closing quote, gives an empty part (malformed), and so
    does a bracket left open or one inside another ('bodies[1.velocity'); an unquoted
    part in brackets is _Bracketed."""
    parts: list[str] = []
    current, i, n = "", 0, len(key)
    bracket = False  # inside an unquoted [...]
    while i < n:
        ch = key[i]
        if ch in "\"'" and not current:
            end = key.find(ch, i + 1)
            after = key[end + 1 : end + 2] if end >= 0 else ""
            if end < 0 or after not in ("", ".", "]", "["):
                return [*parts, ""]
            parts.append(_Quoted(key[i + 1 : end]))
            i = end + 1
            if after == "]":
                i, bracket = i + 1, False
            if key[i : i + 1] == ".":
                i += 1
            continue
        if ch in ".[":
            if bracket:  # 'a[1.b', 'a[1[2]': the bracket was not closed
                return [*parts, ""]
            if current:
                parts.append(current)
            elif ch == "." or (i and key[i - 1] not in "]\"'"):
                parts.append("")  # an empty part: 'a..b', '.a', 'a[]'
            current, bracket = "", ch == "["
        elif ch == "]":
            if not bracket or key[i + 1 : i + 2] not in ("", ".", "["):  # 'a]b', 'a[0]b'
                return [*parts, ""]
            if current or key[i - 1] == "[":
                parts.append(_Bracketed(current))  # ('a[]': an empty part)
            current, bracket = "", False
            if key[i + 1 : i + 2] == ".":
                i += 1
        else:
            current += ch
        i += 1
    if bracket:  # 'bodies[1'
        return [*parts, ""]
    if current or not parts or key.endswith("."):
        parts.append(current)
    return parts


def _override_path(key: str) -> tuple[str | int, ...]:
    """'bodies.2.velocity' -> ('bodies', 2, 'velocity')."""
    return tuple(
        int(p) if p.isdigit() and not isinstance(p, _Quoted) else str(p) for p in _split_key(key)
    )


def key_part(name: str) -> str:
    """A name as a part of a key path: quoted where it holds a dot, a bracket or a quote."""
    if not any(ch in _NAME_MARKS for ch in name):
        return name
    return f"'{name}'" if '"' in name else f'"{name}"'


def override_lines(overrides: str | Sequence[str]) -> tuple[str, ...]:
    """``overrides`` as a tuple of ``key.path=value`` lines: a single string is one line
    (not a sequence of characters). Raises TypeError for anything but strings."""
    lines = (overrides,) if isinstance(overrides, str) else tuple(overrides)
    for line in lines:
        if not isinstance(line, str):
            raise TypeError(
                'overrides: expected "key.path=value" strings (such as "world.dt=0.01"), '
                f"got {type(line).__name__} {line!r}"
            )
    return lines


def apply_overrides(root: YMap, overrides: str | Sequence[str]) -> list[Problem]:
    """Apply ``key.path=value`` overrides to a parsed tree in place: ``root`` changes,
    and the mappings and lists below it on an override's path are replaced by copies
    (copy_node) before they change, so that a tree whose nodes are shared with another
    (load_yaml_tree's, given as a copy of its root) leaves the other as it was.

    Values are parsed as YAML with the same number rules as files; every value set
    remembers its override (for messages). Lists are indexed by position
    (``bodies.1``) or by the ``name`` of a mapping item (``bodies.ball``). Setting a key
    removes the keys it excludes (``world.steps`` removes ``world.duration``).
    Returns the problems found (malformed overrides, paths that do not exist).
    """
    problems: list[Problem] = []
    for raw in override_lines(overrides):
        key, eq, value_text = raw.partition("=")
        key = key.strip()
        origin = f"--set {key or raw}"
        here = Mark(0, 0, origin)
        parts = _split_key(key)
        if not eq or not key or not all(parts):
            message = f"expected key.path=value (such as world.dt=0.01), got {raw!r}"
            problems.append(Problem(here, (), message))
            continue
        value, _, found = load_yaml(value_text, origin=origin)
        if found and (value is None or value is BROKEN):  # unreadable: leave the file's value
            problems += [Problem(p.mark, tuple(parts), p.message) for p in found]
            continue
        node: Any = root
        path: tuple[str | int, ...] = ()
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            if isinstance(node, YMap) and isinstance(part, _Bracketed):  # 'world[dt]'
                dotted = format_path((*path, str(part)))
                where = format_path(path) or "the scene"
                message = f"[{part}] picks a list item, and {where} is a mapping: write {dotted}"
                problems.append(Problem(here, (), message))
                break
            if isinstance(node, YMap):
                if last or node.get(part) is None:  # set, or create a missing mapping
                    for group in schema.EXCLUSIVE_GROUPS:
                        if part in group:
                            for other in group:
                                if other != part:
                                    node.remove(other)
                    node.put(part, value if last else YMap(here), here, here)
                else:  # a node on the path: changed as a copy (the tree may be shared)
                    node[part] = copy_node(node[part])
                node, path = node[part], path + (part,)
            elif isinstance(node, YList):
                index = _list_index(node, part)
                if isinstance(index, str):
                    problems.append(Problem(here, path, index))
                    break
                if last:
                    node[index] = value
                    node.item_marks[index] = here
                else:
                    node[index] = copy_node(node[index])
                node, path = node[index], path + (index,)
            else:
                message = f"cannot set {key}: {format_path(path)} is {schema.describe(node)}"
                problems.append(Problem(here, (), message))
                break
        else:
            problems += [Problem(p.mark, path + p.path, p.message) for p in found]
    return problems


def _list_index(items: YList, part: str) -> int | str:
    """The index that ``part`` names in ``items``, or a message saying why there is none."""
    if part.lstrip("-").isdigit() and not isinstance(part, _Quoted):
        index = int(part)
        if 0 <= index < len(items):
            return index
        return f"index {index} is out of range (the list has {len(items)} items)"
    names = [item.get("name") for item in items if isinstance(item, YMap)]
    for index, item in enumerate(items):
        if isinstance(item, YMap) and item.get("name") == part:
            return index
    close = did_you_mean(part, [n for n in names if isinstance(n, str)])
    hint = f"; did you mean {key_part(close)}?" if close else ""
    quote = " in quotes where it holds . [ ]" if close and key_part(close) != close else ""
    return f"no item named {part!r}{hint} (use a name{quote} or an index)"


# ---------------------------------------------------------------------------------------
# Resolution: checked tree -> dataclasses, with the rules that tie keys together
# ---------------------------------------------------------------------------------------


def _ok(*values: Any) -> bool:
    return all(v is not INVALID for v in values)


def box_corners(size: Vec2, offset: Vec2 = (0.0, 0.0), angle: float = 0.0) -> tuple[Vec2, ...]:
    """The four counter-clockwise corners of a box of full ``size`` rotated by ``angle``
    about its centre and moved to ``offset``."""
    hw, hh = size[0] / 2, size[1] / 2
    c, s = math.cos(angle), math.sin(angle)
    ox, oy = offset
    return tuple(
        (ox + c * x - s * y, oy + s * x + c * y)
        for x, y in ((-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh))
    )


def convex_ccw(points: Sequence[Vec2]) -> tuple[tuple[Vec2, ...], str | None]:
    """(points in counter-clockwise order, None), or (points, why they are not a
    convex polygon). Clockwise input is reversed; repeated, collinear neighbouring
    or self-intersecting vertices are rejected."""
    pts = tuple(points)
    n = len(pts)
    seen: dict[Vec2, int] = {}
    for i, p in enumerate(pts):
        if p in seen:
            return pts, f"vertices {seen[p]} and {i} are the same point"
        seen[p] = i
    # about the first vertex, so that a small polygon far from the origin keeps its digits
    x0, y0 = pts[0]
    rel = [(x - x0, y - y0) for x, y in pts]
    area2 = sum(rel[i - 1][0] * p[1] - p[0] * rel[i - 1][1] for i, p in enumerate(rel))
    span = max(max(abs(x), abs(y)) for x, y in rel)
    if abs(area2) / 2 <= 1e-12 * span * span:
        crossing = _crossing_edges(pts)
        if crossing:  # a bow-tie: its two loops' areas cancel
            return pts, f"the edges cross each other ({crossing})"
        return pts, "the vertices enclose no area (all on one line?)"
    clockwise = area2 < 0
    if clockwise:
        pts = pts[:1] + pts[:0:-1]  # same first vertex, the others reversed
    turning = 0.0
    for k in range(n):
        (ax, ay), (bx, by), (cx, cy) = pts[k - 1], pts[k], pts[(k + 1) % n]
        e1x, e1y, e2x, e2y = bx - ax, by - ay, cx - bx, cy - by
        cross = e1x * e2y - e1y * e2x
        dot = e1x * e2x + e1y * e2y
        tol = 1e-9 * math.hypot(e1x, e1y) * math.hypot(e2x, e2y)
        written = (n - k) % n if clockwise else k  # the index as written in the file
        if cross < -tol:
            return pts, (
                f"not convex: the polygon turns inwards at vertex {written}; "
                "split it into convex parts with `shapes:`"
            )
        if cross <= tol:
            return pts, f"vertex {written} lies on the line through its neighbours; remove it"
        turning += math.atan2(cross, dot)
    if turning > 2 * math.pi + 1e-6:
        return pts, "the edges cross each other (the polygon winds more than once)"
    return pts, None


def _crossing_edges(pts: Sequence[Vec2]) -> str | None:
    """The first two edges of the closed polygon ``pts`` (as written) that cross each
    other, not at a shared vertex, in words ("edge 0-1 crosses edge 2-3"); else None."""
    n = len(pts)

    def side(a: Vec2, b: Vec2, c: Vec2) -> float:
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    for i in range(n):
        a, b = pts[i], pts[(i + 1) % n]
        for j in range(i + 2, n):
            if (j + 1) % n == i:  # the edge before i: they share vertex i
                continue
            c, d = pts[j], pts[(j + 1) % n]
            if side(a, b, c) * side(a, b, d) < 0 and side(c, d, a) * side(c, d, b) < 0:
                return f"edge {i}-{(i + 1) % n} crosses edge {j}-{(j + 1) % n}"
    return None


def _num(x: float) -> str:
    """A number for a message, to 3 digits: 1e-06 -> 1e-6, 1000000.0 -> 1e6, 0.25 ->
    0.25, 1999.5 -> 2000."""
    if 1000 <= abs(x) < 1e6:
        return f"{x:.0f}"
    return f"{x:.3g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def _short_edge(ccw: Sequence[Vec2], written: Sequence[Vec2]) -> str | None:
    """Why a convex polygon's edges are too short for the engine, or None."""
    n = len(ccw)
    for k in range(n):
        (ax, ay), (bx, by) = ccw[k - 1], ccw[k]
        length = math.hypot(bx - ax, by - ay)
        if length < schema.LENGTH_MIN:
            i, j = written.index(ccw[k - 1]), written.index(ccw[k])
            return (
                f"vertices {min(i, j)} and {max(i, j)} are {length:.3g} m apart, "
                f"less than {_num(schema.LENGTH_MIN)} m"
            )
    return None


def shape_bounds(shape: Shape) -> tuple[Vec, Vec]:
    """The shape's bounding box in the body frame, radius included: (min, max), m (a
    3D plane, which has none, gives its one point)."""
    r = shape.radius
    axes = list(zip(*shape.vertices, strict=True))
    return tuple(min(a) - r for a in axes), tuple(max(a) + r for a in axes)


def thinnest(shape: Shape) -> float:
    """The shape's smallest width, m: 2r for a circle, a sphere or a capsule, the smaller
    side of a box, a polygon's least width over its edge directions (a convex hull's
    over its face directions); a thin segment (radius 0), which has no width, counts
    with its length."""
    if shape.kind in ("circle", "sphere", "capsule"):
        return 2.0 * shape.radius
    if shape.kind == "convex" or (shape.kind == "box" and len(shape.size) == 3):
        return g3.hull_width(shape.vertices, shape.faces)
    if shape.kind == "segment":
        (ax, ay), (bx, by) = shape.vertices
        return 2.0 * shape.radius if shape.radius > 0 else math.hypot(bx - ax, by - ay)
    if shape.kind == "box":
        return min(shape.size)
    pts = shape.vertices
    widths = []
    for k in range(len(pts)):
        (ax, ay), (bx, by) = pts[k - 1], pts[k]
        length = math.hypot(bx - ax, by - ay)
        widths.append(
            max(abs((bx - ax) * (y - ay) - (by - ay) * (x - ax)) for x, y in pts) / length
        )
    return min(widths)


def _grid_reach(n: int, step: float, size: float) -> int:
    """How many neighbours along one axis of a grid (n bodies ``step`` apart) a body of
    ``size`` across overlaps on one side."""
    step = abs(step)
    if n <= 1:
        return 0
    if step * (n - 1) < size:
        return n - 1
    return min(n - 1, math.ceil(size / step) - 1)


class _Resolver:
    """Checked tree -> Scene. Checks the rules that tie several keys together and
    collects problems; a part that holds an INVALID value (already reported) is skipped."""

    def __init__(self, shared: Shared | None = None) -> None:
        self.shared = shared  # the parsed text's (schema.check_scene): bodies kept there
        self.problems: list[Problem] = []
        self.notes: list[Problem] = []  # warnings: the scene is valid, but says so
        self.materials: dict[str, Material | None] = {}  # None: invalid, already reported
        self.names: dict[str, tuple[str, Mark]] = {}  # body name -> (who, where)
        self.count = 0
        self.substeps = self.iterations = self.per_shape = 1  # the solver's, once known
        self.solver: Checked | Any = INVALID
        self.dimension = 2

    def error(self, mark: Mark, path: tuple[str | int, ...], message: str) -> None:
        self.problems.append(Problem(mark, path, message))

    # scene -------------------------------------------------------------------------------

    def scene(self, c: Checked, text: str, path: str) -> Scene | None:
        for name, m in c["materials"].items() if _ok(c["materials"]) else ():
            self.materials[name] = Material(**m) if _ok(m) and _ok(*m.values()) else None
        w = c["world"]
        if _ok(w) and _ok(w.get("dimension", 2)):
            self.dimension = w.get("dimension", 2)
        solver = self.solver = c["solver"]
        if _ok(solver) and _ok(solver["substeps"], solver["iterations"]):
            self.substeps, self.iterations = solver["substeps"], solver["iterations"]
            self.per_shape = self.substeps * self.iterations
        bodies: list[Body] = []
        if _ok(c.get("bodies", INVALID)):
            for index, entry in enumerate(c["bodies"]):
                if not _ok(entry):
                    continue
                if entry.tag is None:
                    body = self.body(entry, index)
                    if body is not None:
                        bodies.append(body)
                else:
                    bodies += self.generator(entry)
        shapes = sum(len(b.shapes) for b in bodies)
        if shapes * self.per_shape > self.work_max() and not self.problems:
            self.work_error(shapes, c.mark_of("bodies"), c.path_of("bodies"))
        world, solver, output = self.world(c["world"]), c["solver"], c["output"]
        compare = c["compare"]
        parts = (world, solver, output, compare, c.get("version", INVALID), c.get("name"))
        if not _ok(*parts) or not _ok(*solver.values(), *output.values(), *compare.values()):
            return None
        if not _ok(*compare.get("statistics", {}).values()):
            return None
        output = dict(output)
        if isinstance(output.get("bodies"), list):
            names = [b.name for b in bodies]
            for i, wanted in enumerate(output["bodies"]):
                if not any(_pattern(wanted).fullmatch(n) for n in names):
                    mark = c["output"].mark_of("bodies")
                    close = did_you_mean(wanted, names)
                    hint = f"; did you mean {close}?" if close else ""
                    self.error(mark, ("output", "bodies", i), f"no body matches {wanted!r}{hint}")
            output["bodies"] = tuple(output["bodies"])
            if self.problems:
                return None
        reference = self.reference(c.get("reference"), bodies)
        if not _ok(reference):
            return None
        stem = Path(path).stem if path != "<string>" else "scene"
        return Scene(
            name=c.get("name") or stem,
            world=world,
            solver=Solver(**solver),
            output=Output(**output),
            bodies=tuple(bodies),
            materials={k: v for k, v in self.materials.items() if v is not None},
            compare={k: dict(v) if isinstance(v, dict) else v for k, v in compare.items()},
            reference=reference,
            source=text,
            path=path,
            notes=tuple(_issues(path, self.notes)),
        )

    # Keys of `reference:` and the kinds they apply to.
    REFERENCE_KEYS = {
        "body": ("projectile", "free_spin", "slide", "bounce"),
        "support": ("slide", "bounce"),
        "dt": ("converged",),
        "substeps": ("converged",),
        "iterations": ("converged",),
    }

    def reference(self, r: Checked | None, bodies: list[Body]) -> dict[str, Any] | Any:
        """The `reference:` block of `rbsim sweep` ({} when absent), its keys checked
        against its kind and its body names against the bodies."""
        if r is None:
            return {}
        if not _ok(r) or not _ok(*r.values()):
            return INVALID
        kind = r["kind"]
        for key, kinds in self.REFERENCE_KEYS.items():
            if key in r and kind not in kinds:
                self.error(
                    r.mark_of(key),
                    r.path_of(key),
                    f"only for reference kind {' or '.join(kinds)}, not {kind}",
                )
        by_name = {b.name: b for b in bodies}
        for key, wanted in (("body", "dynamic"), ("support", "static")):
            if key not in r or kind not in self.REFERENCE_KEYS[key] or self.problems:
                continue
            body = by_name.get(r[key])
            if body is None:
                close = did_you_mean(r[key], by_name)
                hint = f"; did you mean {close}?" if close else ""
                self.error(r.mark_of(key), r.path_of(key), f"no body named {r[key]!r}{hint}")
            elif body.type != wanted:
                message = f"body {r[key]!r} is {body.type}; the {key} must be {wanted}"
                self.error(r.mark_of(key), r.path_of(key), message)
        return dict(r)

    def world(self, w: Checked) -> World | Any:
        if not _ok(w) or not _ok(*w.values()):
            return INVALID
        damping, mixing = w["damping"], w["mixing"]
        if not _ok(*damping.values(), *mixing.values()):
            return INVALID
        dt = w["dt"]
        key = "steps" if "steps" in w else "duration" if "duration" in w else "dt"
        steps = w["steps"] if "steps" in w else w.get("duration", 10.0) / dt
        if steps > MAX_STEPS:
            self.error(w.mark_of(key), w.path_of(key), f"more than {MAX_STEPS} steps")
            return INVALID
        if key == "duration":
            self.note_rounding(w, steps, dt)
        steps = max(1, round(steps))
        return World(
            gravity=w["gravity"],
            dt=dt,
            steps=steps,
            linear_damping=damping["linear"],
            angular_damping=damping["angular"],
            friction_mixing=mixing["friction"],
            restitution_mixing=mixing["restitution"],
            dimension=w["dimension"],
        )

    def note_rounding(self, w: Checked, ratio: float, dt: float) -> None:
        """A note when world.duration (``ratio`` dt) is not a whole number of steps of dt,
        beyond round-off: the run is rounded to whole steps (at least one)."""
        steps = max(1, round(ratio))
        if abs(steps - ratio) <= DURATION_ROUNDOFF * max(1.0, ratio):
            return
        message = (
            f"warning: {w['duration']:g} s is not a whole number of steps of dt = {dt:g} s; "
            f"the run is rounded to {schema.counted(steps, 'step')}, {steps * dt:g} s"
        )
        self.notes.append(Problem(w.mark_of("duration"), w.path_of("duration"), message))

    # materials and shapes ----------------------------------------------------------------

    def material(self, c: Checked, base: Material) -> Material | Any:
        """``base``, or the named material of ``c``, with ``c``'s inline keys on top."""
        if "material" in c:
            name = c["material"]
            if not _ok(name):
                return INVALID
            if name not in self.materials:
                close = did_you_mean(name, self.materials)
                if close:
                    hint = f"; did you mean {close}?"
                elif self.materials:
                    hint = f"; defined: {', '.join(self.materials)}"
                else:
                    hint = " (no `materials:` are defined)"
                self.error(
                    c.mark_of("material"), c.path_of("material"), f"unknown material {name!r}{hint}"
                )
                return INVALID
            base = self.materials[name]
            if base is None:
                return INVALID
        inline = {k: c[k] for k in ("density", "friction", "restitution") if k in c}
        if not _ok(*inline.values()):
            return INVALID
        return replace(base, **inline) if inline else base

    def shape(self, c: Checked, body_material: Material | Any) -> Shape | Any:
        """One resolved shape entry, or INVALID."""
        if not _ok(c):
            return INVALID
        kinds = [k for k in (SHAPE_KINDS_3D if self.dimension == 3 else SHAPE_KINDS) if k in c]
        material = self.material(c, body_material) if _ok(body_material) else INVALID
        if len(kinds) != 1 or not _ok(c[kinds[0]]) or not _ok(*c[kinds[0]].values()):
            return INVALID
        kind = kinds[0]
        spec = c[kind]
        if self.dimension == 3:
            return self.shape_3d(kind, spec, material)
        if kind == "circle":
            offset = spec["offset"]
            shape = Shape(kind, (offset,), spec["radius"], material, offset=offset)
        elif kind == "box":
            size, offset, angle = spec["size"], spec["offset"], spec["angle"]
            corners = box_corners(size, offset, angle)
            shape = Shape(kind, corners, 0.0, material, size=size, offset=offset, angle=angle)
        elif kind == "polygon":
            vertices, problem = convex_ccw(spec["vertices"])
            if not problem:
                problem = _short_edge(vertices, spec["vertices"])
            if problem:
                self.error(spec.mark_of("vertices"), spec.path_of("vertices"), problem)
                return INVALID
            shape = Shape(kind, vertices, 0.0, material)
        else:
            a, b, radius = spec["a"], spec["b"], spec["radius"]
            if a == b:
                message = "a segment needs two different ends a and b"
                self.error(spec.mark_of("b"), spec.path_of("b"), message)
                return INVALID
            length = math.hypot(b[0] - a[0], b[1] - a[1])
            if length < schema.LENGTH_MIN:
                message = (
                    f"the ends are {length:.3g} m apart, less than {_num(schema.LENGTH_MIN)} m "
                    "(a shorter capsule is a circle)"
                )
                self.error(spec.mark_of("b"), spec.path_of("b"), message)
                return INVALID
            if 0 < radius < schema.LENGTH_MIN:
                message = (
                    f"must be 0 (a thin segment) or at least {_num(schema.LENGTH_MIN)} m, "
                    f"got {radius!r}"
                )
                self.error(spec.mark_of("radius"), spec.path_of("radius"), message)
                return INVALID
            shape = Shape(kind, (a, b), radius, material)
        return shape if _ok(material) else INVALID

    # bodies ------------------------------------------------------------------------------

    def taken(self, name: str) -> str | None:
        """Who already uses body name ``name`` (with the line), or None."""
        first = self.names.get(name)
        if first is None:
            return None
        owner, where = first
        return f"{owner} at line {where.line}" if where.line else owner

    def body(self, c: Checked, index: int) -> Body | None:
        path = c.path
        name = c.get("name", f"body[{index}]")
        if _ok(name):
            owner = self.taken(name)
            if owner:
                message = f"duplicate body name {name!r} (already used by {owner})"
                self.error(c.mark_of("name"), path + ("name",), message)
            else:
                self.names[name] = (format_path(path), c.mark_of("name"))
        self.count += 1
        shared = self.shared
        if shared is None or not shared.holds(c.src):
            return self.body_of(c, name)
        # a body entry of the shared tree (so its checked value too) resolved by an earlier
        # load with the same dimension and materials: its Body again, and its problems
        known = ("body", id(c), self.dimension, tuple(self.materials.items()))
        found = shared.found.get(known)
        if found is None or found[0] is not c:
            start = len(self.problems)
            body = self.body_of(c, name)
            found = shared.found[known] = (c, body, self.problems[start:])
        else:
            self.problems += found[2]
        return found[1]

    def body_of(self, c: Checked, name: str | Any) -> Body | None:
        """body() past its name: the Body of the checked entry ``c``, or None."""
        kind = c["type"]
        material = self.material(c, DEFAULT_MATERIAL)
        entries = [c["shape"]] if "shape" in c else c.get("shapes", INVALID)
        shapes = [self.shape(s, material) for s in entries] if _ok(entries) else [INVALID]
        if not _ok(kind, name, *c.values()):
            return None
        if "mass" in c and kind != "dynamic":
            self.error(
                c.mark_of("mass"),
                c.path_of("mass"),
                f"mass is only for dynamic bodies; this one is {kind}",
            )
        if kind == "static":
            for key in ("velocity", "angular_velocity", "force", "torque"):
                if c[key] not in (0.0, (0.0, 0.0), (0.0, 0.0, 0.0)):
                    self.error(
                        c.mark_of(key),
                        c.path_of(key),
                        f"a static body cannot have a {key.replace('_', ' ')} "
                        "(use type: kinematic for a body that moves on its own)",
                    )
        if not _ok(*shapes):
            return None
        q = self.orientation(c) if self.dimension == 3 else IDENTITY
        if not _ok(q) or (self.dimension == 3 and not self.planes_static(c, kind, shapes)):
            return None
        if (
            kind == "dynamic"
            and "mass" not in c
            and all(s.kind == "segment" and s.radius == 0 for s in shapes)
        ):
            where = "shape" if "shape" in c else "shapes"
            self.error(
                c.mark_of(where),
                c.path_of(where),
                "a dynamic body needs a shape with area (a segment with radius 0 has none)",
            )
            return None
        where = "shape" if "shape" in c else "shapes"
        if not self.proportions(shapes, c.mark_of(where), c.path_of(where)):
            return None
        body = Body(
            name=name,
            type=kind,
            position=c["position"],
            angle=c.get("angle", 0.0),  # none in 3D
            velocity=c["velocity"],
            angular_velocity=c["angular_velocity"],
            shapes=tuple(shapes),
            mass=c.get("mass"),
            force=c["force"],
            force_point=c.get("force_point"),
            torque=c["torque"],
            orientation=q,
        )
        if kind == "dynamic" and not self.accelerations(body, c):
            return None
        return body

    def proportions(self, shapes: Sequence[Shape], mark: Mark, path: tuple) -> bool:
        """Whether a body of ``shapes`` is within ASPECT_MAX (the larger side of its
        bounding box over its thinnest shape's width); reports it at ``mark`` if not."""
        shapes = [sh for sh in shapes if sh.kind != "plane"]  # a plane has no extent
        if not shapes:
            return True
        boxes = [shape_bounds(sh) for sh in shapes]
        extent = max(
            max(hi[k] for _, hi in boxes) - min(lo[k] for lo, _ in boxes)
            for k in range(len(boxes[0][0]))
        )
        thin = min(thinnest(sh) for sh in shapes)
        if extent <= schema.ASPECT_MAX * thin * (1 + 1e-9):  # a ratio of exactly 1e6 passes
            return True
        self.error(
            mark,
            path,
            f"the body is {_num(extent)} m across and its thinnest shape {_num(thin)} m wide: "
            f"{_num(extent / thin)} times, more than {_num(schema.ASPECT_MAX)}",
        )
        return False

    def accelerations(self, body: Body, c: Checked) -> bool:
        """Whether the dynamic ``body``'s constant force and torque accelerate it (at its
        centre of mass, and its points at the radius of gyration; in 3D the least one,
        about the least principal axis) by at most ACCELERATION_MAX; reports the key if
        not."""
        force = body.force
        torque = written = body.torque if isinstance(body.torque, tuple) else (body.torque,)
        if not (any(force) or any(torque)):
            return True
        if len(force) == 3:
            props3 = body_mass_properties_3d(body)
            mass, inertia, center = props3.mass, principal_axes(props3.inertia)[1][0], props3.center
            about = "least radius of gyration"
        else:
            props = body_mass_properties(body)
            mass, inertia, center = props.mass, props.inertia, props.center
            about = "radius of gyration"
        if not (mass > 0.0 and inertia > 0.0):
            return True  # no mass: rbsim.scene.compile says so
        limit = schema.ACCELERATION_MAX
        linear = math.hypot(*force) / mass
        if not linear <= limit:  # also catches an overflow to inf
            message = (
                f"accelerates the body by {_num(linear)} m/s² (its mass is {_num(mass)} kg), "
                f"more than {_num(limit)} m/s²"
            )
            self.error(c.mark_of("force"), c.path_of("force"), message)
            return False
        if body.force_point is not None:  # and the force's torque about the COM, r × F
            r = [p - q for p, q in zip(body.force_point, center, strict=True)]
            if len(force) == 3:
                fx, fy, fz = force
                arm = (r[1] * fz - r[2] * fy, r[2] * fx - r[0] * fz, r[0] * fy - r[1] * fx)
                torque = tuple(t + a for t, a in zip(torque, arm, strict=True))
            else:
                torque = (torque[0] + (r[0] * force[1] - r[1] * force[0]),)
        radius = math.sqrt(inertia / mass)  # of gyration, m
        angular = math.hypot(*torque) / math.sqrt(inertia * mass)  # m/s² at that radius
        if not angular <= limit:
            key = "torque" if any(written) else "force_point"
            message = (
                f"the torque accelerates the body's points by {_num(angular)} m/s² (at its "
                f"{about} {_num(radius)} m), more than {_num(limit)} m/s²"
            )
            self.error(c.mark_of(key), c.path_of(key), message)
            return False
        return True

    def generator(self, c: Checked) -> list[Body]:
        """Expand a pyramid, stack or grid entry into bodies."""
        if not _ok(*c.values()):
            return []
        tag, prefix = c.tag, c["name"]
        if tag == "grid":
            total = math.prod(c["count"])
        elif tag == "pyramid" and self.dimension == 3:
            total = c["base"] * (c["base"] + 1) * (2 * c["base"] + 1) // 6
        elif tag == "pyramid":
            total = c["base"] * (c["base"] + 1) // 2
        else:
            total = c["count"]
        self.count += total
        key = "base" if tag == "pyramid" else "count"
        if self.count > MAX_BODIES:
            self.error(
                c.mark_of(key),
                c.path_of(key),
                f"the scene would have more than {MAX_BODIES} bodies",
            )
            return []
        if self.count * self.per_shape > self.work_max():  # before expanding it all
            self.work_error(self.count, c.mark_of(key), c.path_of(key))
            return []
        material = self.material(c, DEFAULT_MATERIAL)
        d3 = self.dimension == 3
        if tag == "grid":
            shape = self.shape(c["shape"], material)
            if d3 and _ok(shape) and shape.kind == "plane":
                self.plane_error(c["shape"], "a grid's bodies are dynamic")
                return []
        elif d3:
            size = c["size"]
            corners = g3.box_corners_3d(size, _ZERO3, IDENTITY)
            shape = Shape("box", corners, 0.0, material, size, _ZERO3, faces=g3.BOX_FACES)
            shape = shape if _ok(material) else INVALID
        else:
            shape = (
                Shape("box", box_corners(c["size"]), 0.0, material, size=c["size"])
                if _ok(material)
                else INVALID
            )
        if not _ok(shape):
            return []
        where = "shape" if tag == "grid" else "size"
        if not self.proportions([shape], c.mark_of(where), c.path_of(where)):
            return []
        if tag == "grid" and not self.grid_apart(c, shape):
            return []
        placed = list(getattr(self, "_" + tag + ("_3d" if d3 else ""))(c))  # [(name, position)]
        far = max(max(abs(x) for x in xyz) for _, xyz in placed)
        if not far <= schema.LENGTH_MAX:
            key = "spacing" if tag == "grid" or c["spacing"] > 0 else key
            limit = _num(schema.LENGTH_MAX)
            message = (
                f"this {tag} places bodies {_num(far)} m from the world's origin, "
                f"beyond the {limit} m that positions are bounded by"
            )
            self.error(c.mark_of(key), c.path_of(key), message)
            return []
        mark = c.mark_of("name") if "name" in c.src else c.mark
        for name, _ in placed:
            owner = self.taken(name)
            if owner:
                self.error(
                    mark,
                    c.path_of("name"),
                    f"this {tag} would name a body {name!r}, already used by {owner}; "
                    f"give it a different `name:` prefix than {prefix!r}",
                )
                return []
        who = f"{tag} {format_path(c.path[:-1])}"
        for name, _ in placed:
            self.names[name] = (who, mark)
        shapes = (shape,)
        if d3:
            velocity = c.get("velocity", _ZERO3)
            return [
                Body(
                    name, "dynamic", xyz, 0.0, velocity, _ZERO3, shapes, None, _ZERO3, None, _ZERO3
                )
                for name, xyz in placed
            ]
        velocity = c.get("velocity", (0.0, 0.0))
        return [Body(name, "dynamic", xy, 0.0, velocity, 0.0, shapes) for name, xy in placed]

    def grid_apart(self, c: Checked, shape: Shape) -> bool:
        """Whether a grid's bodies overlap at most their immediate neighbours (a heap of
        bodies inside each other makes a step cost the square of their number)."""
        counts, steps = c["count"], c["spacing"]
        lo, hi = shape_bounds(shape)
        sizes = [b - a for a, b in zip(lo, hi, strict=True)]
        reach = [_grid_reach(n, d, w) for n, d, w in zip(counts, steps, sizes, strict=True)]
        overlapped = math.prod(min(2 * k + 1, n) for k, n in zip(reach, counts, strict=True)) - 1
        neighbours = 3 ** len(counts) - 1
        if overlapped <= neighbours:
            return True
        apart = [_num(abs(d)) for d in steps]
        message = (
            f"the grid's bodies start inside each other: each overlaps up to {overlapped} "
            f"others (bodies {' x '.join(_num(w) for w in sizes)} m, "
            f"{', '.join(apart[:-1])} and {apart[-1]} m apart); at most its {neighbours} "
            "neighbours may overlap it"
        )
        self.error(c.mark_of("spacing"), c.path_of("spacing"), message)
        return False

    def work_max(self) -> int:
        """The most shapes x substeps x iterations of one step in this scene's dimension."""
        return schema.WORK_MAX_3D if self.dimension == 3 else schema.WORK_MAX

    def work_error(self, shapes: int, mark: Mark, path: tuple) -> None:
        """Report a step above work_max(): at the larger of solver.substeps and iterations
        when the scene gives them, else at ``mark`` (the bodies that make it)."""
        work = shapes * self.per_shape
        in_3d = " in 3D" if self.dimension == 3 else ""
        message = (
            f"a step would cost {shapes:,} shapes x {self.substeps:,} substeps x "
            f"{self.iterations:,} iterations = {work:,} shape-iterations, more than the "
            f"{self.work_max():,} that keep one step{in_3d} to a fraction of a second"
        )
        solver = self.solver
        given = [
            k
            for k in ("substeps", "iterations")
            if _ok(solver) and k in solver.src and _ok(solver[k])
        ]
        if given:
            key = max(given, key=lambda k: solver[k])
            mark, path = solver.mark_of(key), solver.path_of(key)
        self.error(mark, path, message)

    # Generator layouts: (name, position of the body origin) for each body, in order.

    @staticmethod
    def _pyramid(c: Checked) -> Iterable[tuple[str, Vec2]]:
        (w, h), gap, base, prefix = c["size"], c["spacing"], c["base"], c["name"]
        ox, oy = c.get("origin", (0.0, h / 2))
        for r in range(base):
            n = base - r  # boxes in row r, centred on ox
            for i in range(n):
                yield f"{prefix}[{r},{i}]", (ox + (i - (n - 1) / 2) * (w + gap), oy + r * (h + gap))

    @staticmethod
    def _stack(c: Checked) -> Iterable[tuple[str, Vec2]]:
        h, gap, prefix = c["size"][1], c["spacing"], c["name"]
        ox, oy = c.get("origin", (0.0, h / 2))
        for i in range(c["count"]):
            yield f"{prefix}[{i}]", (ox, oy + i * (h + gap))

    @staticmethod
    def _grid(c: Checked) -> Iterable[tuple[str, Vec2]]:
        (nx, ny), (dx, dy), (ox, oy), prefix = c["count"], c["spacing"], c["origin"], c["name"]
        for i in range(nx):
            for j in range(ny):
                yield f"{prefix}[{i},{j}]", (ox + i * dx, oy + j * dy)

    # 3D ----------------------------------------------------------------------------------

    def unit(self, spec: Checked, key: str, what: str) -> tuple[float, ...] | Any:
        """``spec[key]`` normalised, or INVALID after reporting a zero ``what``."""
        u = g3.normalized(spec[key])
        if u is None:
            self.error(spec.mark_of(key), spec.path_of(key), f"{what} must not be zero")
            return INVALID
        return u

    def orientation(self, c: Checked) -> Quat | Any:
        """The unit quaternion of ``c``'s `orientation` (normalised) or `rotation`
        ({axis, angle}); the identity when it has neither; INVALID after an error."""
        if "orientation" in c:
            return self.unit(c, "orientation", "a quaternion (orientation)")
        if "rotation" in c:
            r = c["rotation"]
            if not _ok(*r.values()):
                return INVALID
            axis = self.unit(r, "axis", "the axis of a rotation")
            return g3.axis_angle(axis, r["angle"]) if _ok(axis) else INVALID
        return IDENTITY

    def plane_error(self, spec: Checked, why: str) -> None:
        """Report a plane where only a static body may have one."""
        message = f"a plane is for static bodies only ({why}): it is an unbounded half-space"
        self.error(spec.mark_of("plane"), spec.path_of("plane"), message)

    def shape_3d(self, kind: str, spec: Checked, material: Material | Any) -> Shape | Any:
        """One resolved 3D shape of ``kind`` from its checked ``spec``, or INVALID."""
        if kind == "plane":
            n = self.unit(spec, "normal", "the normal of a plane")
            if not _ok(n, material):
                return INVALID
            point = tuple(spec["offset"] * x for x in n)
            return Shape(kind, (point,), 0.0, material, (0.0, 0.0, 0.0), _ZERO3, normal=n)
        q = self.orientation(spec)
        offset = spec["offset"]
        if not _ok(q, material):
            return INVALID
        if kind == "sphere":
            return Shape(kind, (offset,), spec["radius"], material, _ZERO3, offset, orientation=q)
        if kind == "box":
            size = spec["size"]
            corners = g3.box_corners_3d(size, offset, q)
            return Shape(
                kind, corners, 0.0, material, size, offset, faces=g3.BOX_FACES, orientation=q
            )
        if kind == "capsule":
            a, b = g3.transform((spec["a"], spec["b"]), offset, q)
            length = math.dist(spec["a"], spec["b"])
            if not length >= schema.LENGTH_MIN:
                message = (
                    f"the ends are {length:.3g} m apart, less than {_num(schema.LENGTH_MIN)} m "
                    "(a shorter capsule is a sphere)"
                )
                self.error(spec.mark_of("b"), spec.path_of("b"), message)
                return INVALID
            return Shape(kind, (a, b), spec["radius"], material, _ZERO3, _ZERO3)
        points = spec["vertices"]
        try:
            vertices, faces, given = g3.convex_hull(g3.transform(points, offset, q))
        except g3.HullError as err:
            self.error(spec.mark_of("vertices"), spec.path_of("vertices"), str(err))
            return INVALID
        problem = _short_hull_edge(vertices, faces, given) or _sliver_triangle(
            vertices, faces, given
        )
        if problem is None and not g3.hull_width(vertices, faces) >= schema.LENGTH_MIN:
            width = g3.hull_width(vertices, faces)
            problem = f"the hull is {width:.3g} m thin, less than {_num(schema.LENGTH_MIN)} m"
        if problem:
            self.error(spec.mark_of("vertices"), spec.path_of("vertices"), problem)
            return INVALID
        return Shape(kind, vertices, 0.0, material, _ZERO3, _ZERO3, faces=faces)

    def planes_static(self, c: Checked, kind: str, shapes: list[Shape]) -> bool:
        """Whether the body's planes, if any, are on a static body; reports one if not."""
        entries = [c["shape"]] if "shape" in c else c["shapes"]
        for spec, sh in zip(entries, shapes, strict=True):
            if sh.kind == "plane" and kind != "static":
                self.plane_error(spec, f"this body is {kind}")
                return False
        return True

    @staticmethod
    def _pyramid_3d(c: Checked) -> Iterable[tuple[str, Vec]]:
        (w, h, d), gap, base, prefix = c["size"], c["spacing"], c["base"], c["name"]
        ox, oy, oz = c.get("origin", (0.0, h / 2, 0.0))
        for r in range(base):
            n = base - r  # n x n boxes in layer r, centred on (ox, oz)
            y = oy + r * (h + gap)
            for i in range(n):
                for j in range(n):
                    x = ox + (i - (n - 1) / 2) * (w + gap)
                    z = oz + (j - (n - 1) / 2) * (d + gap)
                    yield f"{prefix}[{r},{i},{j}]", (x, y, z)

    @staticmethod
    def _stack_3d(c: Checked) -> Iterable[tuple[str, Vec]]:
        h, gap, prefix = c["size"][1], c["spacing"], c["name"]
        ox, oy, oz = c.get("origin", (0.0, h / 2, 0.0))
        for i in range(c["count"]):
            yield f"{prefix}[{i}]", (ox, oy + i * (h + gap), oz)

    @staticmethod
    def _grid_3d(c: Checked) -> Iterable[tuple[str, Vec]]:
        (nx, ny, nz), (dx, dy, dz), prefix = c["count"], c["spacing"], c["name"]
        ox, oy, oz = c["origin"]
        for i in range(nx):
            for j in range(ny):
                for k in range(nz):
                    yield f"{prefix}[{i},{j},{k}]", (ox + i * dx, oy + j * dy, oz + k * dz)


def _short_hull_edge(
    vertices: Sequence[Vec], faces: Sequence[tuple[int, int, int]], given: Sequence[int]
) -> str | None:
    """Why a convex hull's edges are too short for the engine, or None (the points are
    numbered as written)."""
    for face in faces:
        for k in range(3):
            i, j = face[k - 1], face[k]
            length = math.dist(vertices[i], vertices[j])
            if length < schema.LENGTH_MIN:
                a, b = sorted((given[i], given[j]))
                return (
                    f"points {a} and {b} are {length:.3g} m apart, "
                    f"less than {_num(schema.LENGTH_MIN)} m"
                )
    return None


def _sliver_triangle(
    vertices: Sequence[Vec], faces: Sequence[tuple[int, int, int]], given: Sequence[int]
) -> str | None:
    """Why a convex hull has a triangle too thin for the engine, or None: its doubled
    area below schema.HULL_TRIANGLE_MIN times the hull's size squared (m²; the points
    are numbered as written)."""
    lo = [min(v[k] for v in vertices) for k in range(3)]
    hi = [max(v[k] for v in vertices) for k in range(3)]
    size = math.dist(lo, hi)  # m
    for face in faces:
        a, b, c = (vertices[i] for i in face)
        u, w = [b[k] - a[k] for k in range(3)], [c[k] - a[k] for k in range(3)]
        area2 = math.hypot(
            u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]
        )
        if not area2 > schema.HULL_TRIANGLE_MIN * size * size:
            i, j, k = sorted(given[f] for f in face)
            return (
                f"points {i}, {j} and {k} make a face of {area2 / 2:.3g} m², less than "
                f"{_num(schema.HULL_TRIANGLE_MIN / 2)} of the hull's size squared "
                f"({size:.3g} m): the points span too many scales for the hull's faces"
            )
    return None


# ---------------------------------------------------------------------------------------
# Resolved scene -> plain data
# ---------------------------------------------------------------------------------------


def _shape_to_dict(shape: Shape) -> dict[str, Any]:
    if shape.kind in SHAPE_KINDS_3D and (shape.kind != "box" or len(shape.size) == 3):
        spec = _shape_3d_spec(shape)
    elif shape.kind == "circle":
        spec: dict[str, Any] = {"radius": shape.radius, "offset": list(shape.offset)}
    elif shape.kind == "box":
        spec = {"size": list(shape.size), "offset": list(shape.offset), "angle": shape.angle}
    elif shape.kind == "polygon":
        spec = {"vertices": [list(v) for v in shape.vertices]}
    else:
        spec = {"a": list(shape.vertices[0]), "b": list(shape.vertices[1]), "radius": shape.radius}
    m = shape.material
    return {
        shape.kind: spec,
        "density": m.density,
        "friction": m.friction,
        "restitution": m.restitution,
    }


def _shape_3d_spec(shape: Shape) -> dict[str, Any]:
    """A 3D shape's spec as a scene writes it (capsule and convex with their offset and
    orientation applied to the points)."""
    if shape.kind == "plane":
        offset = sum(p * n for p, n in zip(shape.vertices[0], shape.normal, strict=True))
        return {"normal": list(shape.normal), "offset": offset}
    if shape.kind == "capsule":
        a, b = shape.vertices
        return {"a": list(a), "b": list(b), "radius": shape.radius}
    if shape.kind == "convex":
        return {"vertices": [list(v) for v in shape.vertices]}
    frame = {"offset": list(shape.offset), "orientation": list(shape.orientation)}
    if shape.kind == "sphere":
        return {"radius": shape.radius, **frame}
    return {"size": list(shape.size), **frame}


def _body_to_dict(body: Body) -> dict[str, Any]:
    d3 = isinstance(body.torque, tuple)
    turn = {"orientation": list(body.orientation)} if d3 else {"angle": body.angle}
    spin = body.angular_velocity
    out: dict[str, Any] = {
        "name": body.name,
        "type": body.type,
        "position": list(body.position),
        **turn,
        "velocity": list(body.velocity),
        "angular_velocity": list(spin) if isinstance(spin, tuple) else spin,
    }
    if body.mass is not None:
        out["mass"] = body.mass
    out["force"] = list(body.force)
    if body.force_point is not None:
        out["force_point"] = list(body.force_point)
    out["torque"] = list(body.torque) if d3 else body.torque
    out["shapes"] = [_shape_to_dict(s) for s in body.shapes]
    return out


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """The resolved scene as plain data (dicts, lists, str, int, float): every default
    filled in, generators expanded, materials inlined on each shape, `steps` instead of
    `duration`. It is itself a valid version-1 scene that loads to an equal Scene (but
    for the point of a 3D plane whose normal is not along an axis, which it gives as
    normal and offset again: that point may come back one rounding apart)."""
    w, s = scene.world, scene.solver
    return {
        "version": schema.SCENE_VERSION,
        "name": scene.name,
        "world": {
            **({"dimension": 3} if w.dimension == 3 else {}),
            "gravity": list(w.gravity),
            "dt": w.dt,
            "steps": w.steps,
            "damping": {"linear": w.linear_damping, "angular": w.angular_damping},
            "mixing": {"friction": w.friction_mixing, "restitution": w.restitution_mixing},
        },
        "solver": {
            "substeps": s.substeps,
            "iterations": s.iterations,
            "integrator": s.integrator,
            "rotation": s.rotation,
            "restitution_threshold": s.restitution_threshold,
            **({"threads": s.threads} if s.threads is not None else {}),
        },
        "output": {
            "every": scene.output.every,
            "precision": scene.output.precision,
            "compression": scene.output.compression,
            "bodies": o if isinstance(o := scene.output.bodies, str) else list(o),
            "contacts": scene.output.contacts,
        },
        "materials": {
            name: {"density": m.density, "friction": m.friction, "restitution": m.restitution}
            for name, m in scene.materials.items()
        },
        "bodies": [_body_to_dict(b) for b in scene.bodies],
        "compare": {k: dict(v) if isinstance(v, dict) else v for k, v in scene.compare.items()},
        **({"reference": dict(scene.reference)} if scene.reference else {}),
    }
