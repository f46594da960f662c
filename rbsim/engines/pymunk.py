"""The same scene as a pymunk (Chipmunk2D) Space, and readback in rbsim's layout.

rbsim -> pymunk mapping (see docs/format.md for rbsim's side):

- A body's pymunk origin is the scene body origin; its `center_of_gravity` is the centre
  of mass computed here from the shapes (pymunk's own area/moment formulas, parallel-axis
  sums for compound bodies). pymunk's `Body.velocity` is the velocity of the centre of
  gravity, which is what a scene's `velocity` means, so it is set and read as is.
- Mass and inertia are set explicitly on the body (shapes carry no density), so pymunk
  never re-accumulates them; a scene `mass` scales mass and inertia together.
- Mixing: pymunk multiplies the two shapes' friction and elasticity. When per-shape
  values exist whose products reproduce the scene's mixing rule for every pair of
  bodies that can collide (sqrt friction: sqrt(μ); multiply: as is; a single value: its
  square root; min/max: solved per material class), those values are set on the shapes
  and no Python callback runs during a step. Otherwise a wildcard pre_solve handler sets
  `arbiter.friction` and `arbiter.restitution` to the mixed values of the shapes' own
  material values (measured with pymunk 7.3.1: both take effect when set in pre_solve;
  `arbiter.elasticity` does not exist in pymunk 7 and setting it does nothing).
- Restitution threshold: rbsim does not bounce a contact point approaching slower than
  `solver.restitution_threshold`; Chipmunk has no threshold. When some shape has e > 0
  and the threshold is > 0, the pre_solve handler sets `arbiter.restitution` to 0 for a
  contact whose fastest-approaching point is slower than the threshold (the relative
  normal velocity at the points before the step, which is the velocity Chipmunk
  computes its bounce from).
- Damping: Chipmunk applies v <- v * damping**h + h * a each step of length h; rbsim
  (Box2D form) applies the factor 1/(1 + h c). `space.damping` is set so that
  damping**h == 1/(1 + h c) for pymunk's step h = dt / substeps. Chipmunk damps linear
  and angular velocity with the same factor, so the scene's two dampings must be equal.
- Constant loads are written into `body.force` / `body.torque` before every pymunk step
  (Chipmunk zeroes both after each step).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pymunk

from ..config import NonFiniteState
from ..constants import LINEAR_SLOP
from ..scene import Body, Scene, Shape, World
from .base import Engine, Snapshot, UnsupportedScene

try:  # pymunk's batch readback (experimental in pymunk 7); a per-body loop otherwise
    import pymunk.batch as _batch
except ImportError:  # pragma: no cover - depends on the installed pymunk
    _batch = None
try:  # Chipmunk's C API as pymunk binds it, for counting contacts without callbacks
    from pymunk._chipmunk_cffi import lib as _cp_lib
except ImportError:  # pragma: no cover - depends on the installed pymunk
    _cp_lib = None

__all__ = [
    "PymunkEngine",
    "PymunkSettings",
    "PymunkWorld",
    "UnsupportedScene",
    "run_pymunk",
]

# Chipmunk's default collision bias: the fraction of overlap left after one second.
DEFAULT_COLLISION_BIAS = (1.0 - 0.1) ** 60

# Mixing rules of a scene (world.friction_mixing, world.restitution_mixing).
MIXING_RULES: dict[str, Callable[[float, float], float]] = {
    "sqrt": lambda a, b: math.sqrt(a * b),
    "multiply": lambda a, b: a * b,
    "min": min,
    "max": max,
}

# Above this many distinct (value, dynamic) classes the per-class product assignment is
# not searched (it checks every pair of classes); the pre_solve handler is used instead.
MAX_MIXING_CLASSES = 512

# Relative tolerance for a per-shape product to count as reproducing a mixing rule.
MIXING_RTOL = 1e-12


@dataclass
class PymunkSettings:
    """How the pymunk Space is configured.

    iterations: Chipmunk solver iterations per pymunk step.
    substeps: pymunk steps per scene dt (each of length dt / substeps, s).
    collision_slop: allowed overlap, m (rbsim's LINEAR_SLOP; pymunk's default of 0.1 is
        meant for pixels, so it is always set).
    collision_bias: fraction of overlap left uncorrected after one second
        (dimensionless); None sets pymunk's default (1 - 0.1)**60 ~= 0.0018 explicitly.
    mixing_handler: "auto" uses per-shape friction/elasticity values when their products
        reproduce the scene's mixing rules exactly and a pre_solve handler otherwise;
        "always" always mixes in the pre_solve handler; "never" never installs it and
        raises UnsupportedScene when per-shape values cannot reproduce a rule, or when
        the scene needs the restitution threshold (some e > 0 and a threshold > 0).
    """

    iterations: int = 10
    substeps: int = 1
    collision_slop: float = LINEAR_SLOP
    collision_bias: float | None = None
    mixing_handler: str = "auto"


# --------------------------------------------------------------------------------------
# Mass properties, with Chipmunk's formulas (cpAreaFor*, cpMomentFor*, cpCentroidForPoly)


def _shape_mass_properties(body: Body, shape: Shape) -> tuple[float, np.ndarray, float]:
    """Area (m²), centroid (2,) in the body frame (m) and moment of inertia per unit
    mass about the centroid (m²) of one shape, as pymunk computes them."""
    if shape.kind == "circle":
        r = shape.radius
        return math.pi * r * r, np.array(shape.vertices[0], dtype=float), 0.5 * r * r
    if shape.kind == "segment":
        a = np.array(shape.vertices[0], dtype=float)
        b = np.array(shape.vertices[1], dtype=float)
        r = shape.radius
        length = float(np.hypot(*(b - a)))
        # Chipmunk treats a capsule as a box of (length + 2r) x 2r for its moment.
        k = ((length + 2.0 * r) ** 2 + 4.0 * r * r) / 12.0
        return r * (math.pi * r + 2.0 * length), 0.5 * (a + b), k
    if shape.kind in ("box", "polygon"):
        v = np.array(shape.vertices, dtype=float)
        w = np.roll(v, -1, axis=0)
        cross = v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]
        area = 0.5 * cross.sum()
        if area == 0.0:
            return 0.0, v.mean(axis=0), 0.0
        centroid = ((v + w) * cross[:, None]).sum(axis=0) / (6.0 * area)
        p, q = v - centroid, w - centroid
        pq = p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]
        dots = (p * p).sum(axis=1) + (p * q).sum(axis=1) + (q * q).sum(axis=1)
        return float(area), centroid, float((pq * dots).sum() / (6.0 * pq.sum()))
    raise UnsupportedScene(f"body {body.name!r}: shape kind {shape.kind!r} has no pymunk shape")


def _body_mass_properties(body: Body) -> tuple[float, float, np.ndarray]:
    """Mass (kg), moment of inertia about the centre of mass (kg·m²) and centre of mass
    (2,) in the body frame (m). Static and kinematic bodies get inf mass and moment;
    their centre of mass is still computed (the point they rotate about)."""
    props = [_shape_mass_properties(body, s) for s in body.shapes]
    areas = np.array([p[0] for p in props])
    masses = areas * np.array([s.material.density for s in body.shapes])
    centroids = np.array([p[1] for p in props]).reshape(-1, 2)
    total = masses.sum()
    if total > 0.0:
        com = (masses[:, None] * centroids).sum(axis=0) / total
    elif areas.sum() > 0.0:
        com = (areas[:, None] * centroids).sum(axis=0) / areas.sum()
    elif len(props):
        com = centroids.mean(axis=0)
    else:
        com = np.zeros(2)
    if body.type != "dynamic":
        return math.inf, math.inf, com
    if not total > 0.0:
        raise UnsupportedScene(
            f"body {body.name!r}: dynamic body has zero mass from its shapes "
            "(density x area = 0); pymunk needs mass > 0 and moment > 0"
        )
    offsets = centroids - com
    moment = float(
        (masses * (np.array([p[2] for p in props]) + (offsets * offsets).sum(axis=1))).sum()
    )
    mass = float(total)
    if body.mass is not None:
        moment *= body.mass / mass
        mass = float(body.mass)
    if not moment > 0.0:
        raise UnsupportedScene(f"body {body.name!r}: dynamic body has zero moment of inertia")
    return mass, moment, com


# --------------------------------------------------------------------------------------
# Mixing rules as products of per-shape values


def _product_values(
    shape_values: list[float],
    shape_body: list[int],
    body_dynamic: list[bool],
    mix: Callable[[float, float], float],
) -> tuple[list[float] | None, tuple[int, int] | None]:
    """Per-shape values s with s_a * s_b == mix(v_a, v_b) for every pair of shapes on
    different bodies of which at least one is dynamic (Chipmunk skips pairs of two
    infinite masses and shapes of one body).

    Shapes are grouped into classes by (value, dynamic), the equations s_i s_j = t_ij are
    solved per class by propagation from a class whose value is fixed (a pair within
    the class) and, failing that, in log space by least squares. Returns (values, None)
    or (None, (shape_a, shape_b)) naming two shapes of a pair that cannot be reproduced, or
    (None, None) when there are more than MAX_MIXING_CLASSES classes (not searched).
    """
    keys: dict[tuple[float, bool], int] = {}
    shape_class = []
    for v, b in zip(shape_values, shape_body, strict=True):
        shape_class.append(keys.setdefault((v, body_dynamic[b]), len(keys)))
    k = len(keys)
    if k > MAX_MIXING_CLASSES:
        return None, None
    value = [key[0] for key in keys]
    dynamic = [key[1] for key in keys]
    bodies: list[set[int]] = [set() for _ in range(k)]
    first_shape: list[dict[int, int]] = [{} for _ in range(k)]
    for s, (c, b) in enumerate(zip(shape_class, shape_body, strict=True)):
        bodies[c].add(b)
        first_shape[c].setdefault(b, s)

    edges: list[tuple[int, int, float]] = []
    for i in range(k):
        for j in range(i, k):
            if not (dynamic[i] or dynamic[j]):
                continue
            if i == j:
                ok = len(bodies[i]) >= 2
            else:
                ok = not (len(bodies[i]) == 1 and bodies[i] == bodies[j])
            if ok:
                edges.append((i, j, mix(value[i], value[j])))

    def failing(s: list[float]) -> tuple[int, int, float] | None:
        for i, j, t in edges:
            if abs(s[i] * s[j] - t) > MIXING_RTOL * max(1.0, t):
                return i, j, t
        return None

    adj: list[list[tuple[int, float]]] = [[] for _ in range(k)]
    loop: list[float | None] = [None] * k
    for i, j, t in edges:
        if i == j:
            loop[i] = t
        else:
            adj[i].append((j, t))
            adj[j].append((i, t))
    s: list[float | None] = [None] * k
    for root in sorted(range(k), key=lambda c: loop[c] is None):
        if s[root] is not None:
            continue
        if loop[root] is not None:
            s[root] = math.sqrt(loop[root])
        else:
            s[root] = math.sqrt(max((t for _, t in adj[root]), default=value[root]))
        queue = [root]
        while queue:
            i = queue.pop()
            if s[i] == 0.0:
                continue
            for j, t in adj[i]:
                if s[j] is None:
                    s[j] = t / s[i]
                    queue.append(j)
    bad = failing(s)
    if bad is not None and all(t > 0.0 for _, _, t in edges):
        a = np.zeros((len(edges), k))
        for row, (i, j, _) in enumerate(edges):
            a[row, i] += 1.0
            a[row, j] += 1.0
        x = np.linalg.lstsq(a, np.log([t for _, _, t in edges]), rcond=None)[0]
        s2 = [float(v) for v in np.exp(x)]
        if failing(s2) is None:
            s, bad = s2, None
    if bad is None:
        return [s[c] for c in shape_class], None
    i, j, _ = bad
    # two different bodies, one with a shape in each class (the edge says they exist)
    b1, b2 = next((p, q) for p in sorted(bodies[i]) for q in sorted(bodies[j]) if p != q)
    return None, (first_shape[i][b1], first_shape[j][b2])


def _pre_solve_handler(
    world: World, mix: bool, threshold: float
) -> Callable[[pymunk.Arbiter, pymunk.Space, object], None]:
    """A pre_solve callback that sets the arbiter's friction and restitution to the
    scene's mixing of the two shapes' own values (when `mix`; else the shapes carry
    values whose product is already the mixed one) and drops the restitution of a
    contact approaching slower than `threshold` (m/s; 0: never)."""
    fmix = MIXING_RULES[world.friction_mixing]
    rmix = MIXING_RULES[world.restitution_mixing]

    def pre_solve(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        if mix:
            a, b = arbiter.shapes
            arbiter.friction = fmix(a.friction, b.friction)
            arbiter.restitution = rmix(a.elasticity, b.elasticity)
        if threshold > 0.0 and arbiter.restitution > 0.0:
            # relative normal velocity of b against a at each point; < 0 approaches
            points = arbiter.contact_point_set
            n = points.normal
            body_a, body_b = arbiter.bodies
            approach = min(
                (
                    (
                        body_b.velocity_at_world_point(p.point_b)
                        - body_a.velocity_at_world_point(p.point_a)
                    ).dot(n)
                    for p in points.points
                ),
                default=0.0,
            )
            if approach > -threshold:
                arbiter.restitution = 0.0

    return pre_solve


# --------------------------------------------------------------------------------------


class PymunkWorld:
    """A scene as a pymunk Space, stepped one scene dt at a time.

    space: the pymunk Space; bodies: one pymunk Body per scene body, in scene order.
    wall_time: seconds spent inside space.step calls so far (time.perf_counter).
    mixing_handler_installed: whether a pre_solve handler mixes friction/restitution.
    pre_solve_installed: whether a pre_solve handler runs at all (mixing, or the
    restitution threshold; restitution_threshold, m/s, is 0 when it is not applied).
    """

    def __init__(self, scene: Scene, settings: PymunkSettings | None = None) -> None:
        """Build the Space from a resolved scene; raises UnsupportedScene when pymunk
        cannot express it."""
        settings = PymunkSettings() if settings is None else settings
        if settings.substeps < 1 or settings.iterations < 1:
            raise ValueError("substeps and iterations must be >= 1")
        if settings.mixing_handler not in ("auto", "always", "never"):
            raise ValueError(
                f"mixing_handler must be auto|always|never, not {settings.mixing_handler!r}"
            )
        world = scene.world
        self.scene = scene
        self.settings = settings
        self.dt = float(world.dt)  # s, one scene step
        self.h = self.dt / settings.substeps  # s, one pymunk step
        self.step_count = 0
        self.wall_time = 0.0

        space = pymunk.Space()
        space.gravity = tuple(world.gravity)
        space.iterations = int(settings.iterations)
        space.collision_slop = float(settings.collision_slop)
        bias = (
            DEFAULT_COLLISION_BIAS if settings.collision_bias is None else settings.collision_bias
        )
        space.collision_bias = float(bias)
        space.damping = self._damping(world.linear_damping, world.angular_damping)
        self.space = space

        n = len(scene.bodies)
        self.body_mass = np.empty(n)
        self.body_moment = np.empty(n)
        self.body_com = np.zeros((n, 2))
        self.body_dynamic = np.zeros(n, dtype=bool)
        self.bodies: list[pymunk.Body] = []
        shapes: list[pymunk.Shape] = []
        shape_body: list[int] = []
        self._loads: list[tuple[pymunk.Body, tuple[float, float], np.ndarray | None, float]] = []
        for i, sb in enumerate(scene.bodies):
            if sb.type not in ("dynamic", "static", "kinematic"):
                raise UnsupportedScene(f"body {sb.name!r}: body type {sb.type!r}")
            mass, moment, com = _body_mass_properties(sb)
            self.body_mass[i], self.body_moment[i], self.body_com[i] = mass, moment, com
            self.body_dynamic[i] = sb.type == "dynamic"
            if sb.type == "dynamic":
                pb = pymunk.Body(mass, moment)
            elif sb.type == "static":
                pb = pymunk.Body(body_type=pymunk.Body.STATIC)
            else:
                pb = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            # Order matters: Chipmunk keeps the centre of gravity's world point when the
            # angle changes, and places it from the current angle when the origin is set.
            pb.center_of_gravity = (float(com[0]), float(com[1]))
            pb.angle = float(sb.angle)
            pb.position = (float(sb.position[0]), float(sb.position[1]))
            if sb.type != "static":
                pb.velocity = (float(sb.velocity[0]), float(sb.velocity[1]))
                pb.angular_velocity = float(sb.angular_velocity)
            body_shapes = [self._make_shape(sb, pb, s) for s in sb.shapes]
            space.add(pb, *body_shapes)
            self.bodies.append(pb)
            shapes.extend(body_shapes)
            shape_body.extend([i] * len(body_shapes))
            if sb.type == "dynamic" and (any(sb.force) or sb.torque or sb.force_point):
                point = None if sb.force_point is None else np.array(sb.force_point) - com
                self._loads.append((pb, (float(sb.force[0]), float(sb.force[1])), point, sb.torque))

        self.mixing_handler_installed = False
        self.pre_solve_installed = False
        self._setup_mixing(scene, shapes, shape_body)
        self._setup_readback()

    # -- construction -------------------------------------------------------------------

    def _damping(self, linear: float, angular: float) -> float:
        """space.damping (fraction of velocity kept per second) for rbsim's dampings."""
        if linear != angular and (linear or angular):
            raise UnsupportedScene(
                f"world: linear damping {linear} 1/s and angular damping {angular} 1/s "
                "differ; pymunk has one space.damping for both"
            )
        if linear < 0.0:
            raise UnsupportedScene(f"world: negative damping {linear} 1/s")
        # damping**h == 1 / (1 + h c) for pymunk's step h
        return (1.0 / (1.0 + self.h * linear)) ** (1.0 / self.h)

    @staticmethod
    def _make_shape(sb: Body, pb: pymunk.Body, shape: Shape) -> pymunk.Shape:
        """The pymunk shape for one scene shape (body frame); friction and elasticity are
        set later by the mixing setup."""
        if shape.kind == "circle":
            return pymunk.Circle(pb, float(shape.radius), tuple(shape.vertices[0]))
        if shape.kind in ("box", "polygon"):
            return pymunk.Poly(pb, [tuple(v) for v in shape.vertices], radius=0.0)
        if shape.kind == "segment":
            a, b = shape.vertices
            return pymunk.Segment(pb, tuple(a), tuple(b), float(shape.radius))
        raise UnsupportedScene(f"body {sb.name!r}: shape kind {shape.kind!r} has no pymunk shape")

    def _setup_mixing(
        self, scene: Scene, shapes: list[pymunk.Shape], shape_body: list[int]
    ) -> None:
        """Per-shape friction/elasticity whose products give the scene's mixing rules, or
        the raw material values and a pre_solve handler that mixes them. The handler
        also applies rbsim's restitution threshold when the scene needs it."""
        world = scene.world
        rules = {"friction": world.friction_mixing, "restitution": world.restitution_mixing}
        for what, rule in rules.items():
            if rule not in MIXING_RULES or (what == "restitution" and rule == "sqrt"):
                raise UnsupportedScene(f"world: unknown {what} mixing rule {rule!r}")
        materials = [s.material for sb in scene.bodies for s in sb.shapes]
        friction = [float(m.friction) for m in materials]
        restitution = [float(m.restitution) for m in materials]
        dynamic = [bool(d) for d in self.body_dynamic]
        mode = self.settings.mixing_handler

        def assign(what: str, values: list[float], rule: str) -> list[float] | None:
            if rule == "multiply":
                return values
            if rule == "sqrt":
                return [math.sqrt(v) for v in values]
            solved, pair = _product_values(values, shape_body, dynamic, MIXING_RULES[rule])
            if solved is not None or mode != "never":
                return solved
            if pair is None:
                raise UnsupportedScene(
                    f"world: more than {MAX_MIXING_CLASSES} distinct {what} values; "
                    f"{rule} mixing is not checked pair by pair (use mixing_handler='auto')"
                )
            a, b = (scene.bodies[shape_body[s]].name for s in pair)
            raise UnsupportedScene(
                f"bodies {a!r} and {b!r}: {rule} mixing of their {what} "
                f"({values[pair[0]]} and {values[pair[1]]}) cannot be reproduced by "
                "pymunk's product of per-shape values for every pair of bodies that "
                "can collide (mixing_handler='never')"
            )

        shape_u = shape_e = None
        if mode != "always":
            shape_u = assign("friction", friction, world.friction_mixing)
            shape_e = assign("restitution", restitution, world.restitution_mixing)
        threshold = float(scene.solver.restitution_threshold)
        if not (threshold > 0.0 and any(e > 0.0 for e in restitution)):
            threshold = 0.0  # nothing can bounce, or everything may: no threshold to apply
        elif mode == "never":
            raise UnsupportedScene(
                f"solver: restitution_threshold {threshold} m/s needs a pre_solve handler "
                "in pymunk, which has no threshold (mixing_handler='never')"
            )
        self.restitution_threshold = threshold  # m/s, applied by the handler; 0: not
        mix = shape_u is None or shape_e is None
        if mix:
            shape_u, shape_e = friction, restitution
        if mix or threshold > 0.0:
            self.space.on_collision(pre_solve=_pre_solve_handler(world, mix, threshold))
            self.pre_solve_installed = True
        self.mixing_handler_installed = mix
        for shape, u, e in zip(shapes, shape_u, shape_e, strict=True):
            shape.friction = u
            shape.elasticity = e

    def _setup_readback(self) -> None:
        """Map pymunk body ids to scene indices for the batch readback."""
        ids = np.array([b.id for b in self.bodies], dtype=np.uint64)
        order = np.argsort(ids)
        self._sorted_ids = ids[order]
        self._sorted_index = order
        self._buffer = _batch.Buffer() if _batch is not None else None

    # -- stepping -----------------------------------------------------------------------

    def _apply_loads(self) -> None:
        """Constant forces and torques for the next pymunk step (Chipmunk zeroes them
        after every step). A force at a point adds the torque r x f about the centre of
        mass, r rotated into the world frame."""
        for pb, f, point, torque in self._loads:
            pb.force = f
            tau = torque
            if point is not None:
                c, s = math.cos(pb.angle), math.sin(pb.angle)
                rx, ry = c * point[0] - s * point[1], s * point[0] + c * point[1]
                tau += rx * f[1] - ry * f[0]
            pb.torque = tau

    def step(self) -> None:
        """Advance one scene dt (s): `substeps` pymunk steps of dt / substeps."""
        space, h = self.space, self.h
        for _ in range(self.settings.substeps):
            if self._loads:
                self._apply_loads()
            t0 = time.perf_counter()
            space.step(h)
            self.wall_time += time.perf_counter() - t0
        self.step_count += 1

    # -- readback -----------------------------------------------------------------------

    def _read_raw(self) -> np.ndarray:
        """(N, 6) rows of origin x, y (m), angle (rad), COM velocity x, y (m/s), ω (rad/s)."""
        n = len(self.bodies)
        if self._buffer is None:
            out = np.empty((n, 6))
            for i, b in enumerate(self.bodies):
                p, v = b.position, b.velocity
                out[i] = (p.x, p.y, b.angle, v.x, v.y, b.angular_velocity)
            return out
        fields = (
            _batch.BodyFields.BODY_ID
            | _batch.BodyFields.POSITION
            | _batch.BodyFields.ANGLE
            | _batch.BodyFields.VELOCITY
            | _batch.BodyFields.ANGULAR_VELOCITY
        )
        buf = self._buffer
        buf.clear()
        _batch.get_space_bodies(self.space, fields, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp).astype(np.uint64)
        data = np.frombuffer(buf.float_buf(), dtype=np.float64).reshape(-1, 6)
        k = np.minimum(np.searchsorted(self._sorted_ids, ids), n - 1)
        mine = self._sorted_ids[k] == ids
        out = np.empty((n, 6))
        out[self._sorted_index[k[mine]]] = data[mine]
        if np.count_nonzero(mine) != n:  # pragma: no cover - every body is in the space
            raise RuntimeError("pymunk batch readback missed bodies")
        return out

    def read_state(self) -> dict[str, np.ndarray]:
        """State in rbsim's layout, scene body order: position (N,2) of the body origin
        (m), orientation (N,2) = (cos θ, sin θ), angle (N,) continuous (rad), velocity (N,2)
        of the centre of mass (m/s), angular_velocity (N,) (rad/s)."""
        raw = self._read_raw()
        angle = raw[:, 2].copy()
        return {
            "position": raw[:, 0:2].copy(),
            "orientation": np.stack([np.cos(angle), np.sin(angle)], axis=1),
            "angle": angle,
            "velocity": raw[:, 3:5].copy(),
            "angular_velocity": raw[:, 5].copy(),
        }

    def contact_count(self) -> int:
        """Contact points of the last pymunk step (pairs of two infinite masses, which
        Chipmunk does not solve, are excluded)."""
        if _cp_lib is not None:
            try:
                return self._contact_count_cached()
            except (AttributeError, TypeError):  # pragma: no cover - pymunk internals moved
                pass
        return self._contact_count_bodies()

    def _contact_count_cached(self) -> int:
        """Fast path over Chipmunk's arbiter cache (pymunk internals): an arbiter touched
        in the last step carries the space's current time stamp; older cached arbiters
        (kept `collision_persistence` steps after separating) do not."""
        stamp = _cp_lib.cpSpaceGetTimestamp(self.space._space)
        mass = _cp_lib.cpBodyGetMass
        total = 0
        for arb in self.space._get_arbiters():
            if arb.stamp == stamp and (
                mass(arb.body_a) != math.inf or mass(arb.body_b) != math.inf
            ):
                total += arb.count
        return total

    def _contact_count_bodies(self) -> int:
        """Public-API path: each dynamic body's arbiters of the last step."""
        total = [0.0]

        def count(arbiter: pymunk.Arbiter, pb: pymunk.Body) -> None:
            a, b = arbiter.bodies
            other = b if a is pb else a
            # a pair of two dynamic bodies is seen from both of them
            weight = 0.5 if other.body_type == pymunk.Body.DYNAMIC else 1.0
            total[0] += weight * len(arbiter.contact_point_set.points)

        for i in np.flatnonzero(self.body_dynamic):
            self.bodies[i].each_arbiter(count, self.bodies[i])
        return int(round(total[0]))

    def observables(self) -> dict[str, float | np.ndarray]:
        """Sums over dynamic bodies: kinetic_energy (J), potential_energy = -Σ m g·x_com (J,
        relative to the world origin), linear_momentum (2,) (kg·m/s), angular_momentum
        about the world origin, orbital + spin (kg·m²/s), contact_count (points)."""
        st = self.read_state()
        d = self.body_dynamic
        m, inertia = self.body_mass[d], self.body_moment[d]
        c, s = st["orientation"][d, 0], st["orientation"][d, 1]
        com = self.body_com[d]
        x = st["position"][d] + np.stack(
            [c * com[:, 0] - s * com[:, 1], s * com[:, 0] + c * com[:, 1]], axis=1
        )
        v, w = st["velocity"][d], st["angular_velocity"][d]
        g = np.asarray(self.scene.world.gravity, dtype=float)
        p = m[:, None] * v
        return {
            "kinetic_energy": float(
                0.5 * (m * (v * v).sum(axis=1)).sum() + 0.5 * (inertia * w * w).sum()
            ),
            "potential_energy": float(-(m * (x @ g)).sum()),
            "linear_momentum": p.sum(axis=0),
            "angular_momentum": float(
                (x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0]).sum() + (inertia * w).sum()
            ),
            "contact_count": self.contact_count(),
        }

    def body_table_arrays(self) -> dict[str, np.ndarray]:
        """Per-body constants, scene order: mass (N,) kg (inf for static/kinematic),
        moment_of_inertia (N,) kg·m² about the centre of mass (inf for static/kinematic),
        center_of_mass (N,2) in the body frame (m)."""
        return {
            "mass": self.body_mass.copy(),
            "moment_of_inertia": self.body_moment.copy(),
            "center_of_mass": self.body_com.copy(),
        }


def run_pymunk(
    scene: Scene,
    settings: PymunkSettings | None = None,
    on_frame: Callable[[int, float, dict, dict], None] | None = None,
    every: int = 1,
) -> float:
    """Step `scene.world.steps` scene steps in pymunk.

    on_frame(step, time (s), state, observables) is called for step 0 (the initial state),
    every `every`-th step and the last step. Returns the wall time (s, perf_counter) spent
    in space.step calls only.
    """
    if every < 1:
        raise ValueError("every must be >= 1")
    world = PymunkWorld(scene, settings)
    steps = int(scene.world.steps)
    if on_frame is not None:
        on_frame(0, 0.0, world.read_state(), world.observables())
    for n in range(1, steps + 1):
        world.step()
        if on_frame is not None and (n % every == 0 or n == steps):
            on_frame(n, n * world.dt, world.read_state(), world.observables())
    return world.wall_time


class PymunkEngine(Engine):
    """pymunk's Space behind the engine interface. `world` is the PymunkWorld;
    `settings` (PymunkSettings, default PymunkSettings()) says how its Space steps.
    step_time counts the time inside space.step only. A non-finite state is found
    when the state is read."""

    name = "pymunk"

    def __init__(self, scene: Scene, settings: PymunkSettings | None = None) -> None:
        super().__init__(scene)
        self.world = PymunkWorld(scene, settings)
        self.pymunk_settings = self.world.settings
        self.settings = dataclasses.asdict(self.world.settings)
        self.mass = self.world.body_mass.copy()
        self.inertia = self.world.body_moment.copy()
        self.com_local = self.world.body_com.copy()
        self.dynamic = self.world.body_dynamic.copy()

    def advance(self, n: int) -> None:
        step = self.world.step
        for _ in range(n):
            step()
        self.step_time = self.world.wall_time

    def read(self) -> Snapshot:
        """The current state; raises NonFiniteState when a position or velocity is not
        finite (Chipmunk does not stop: the state is checked when it is read)."""
        st = self.world.read_state()
        origin, angle = st["position"], st["angle"]
        bad = np.flatnonzero(
            ~(np.isfinite(origin).all(axis=1) & np.isfinite(st["velocity"]).all(axis=1))
        )
        if bad.size:
            raise NonFiniteState(int(bad[0]), self.step_index)
        c, s = np.cos(angle), np.sin(angle)
        cx, cy = self.com_local[:, 0], self.com_local[:, 1]
        com = origin + np.stack([c * cx - s * cy, s * cx + c * cy], axis=1)
        return Snapshot(
            origin=origin,
            angle=angle,
            orientation=st["orientation"],
            com=com,
            velocity=st["velocity"],
            angular_velocity=st["angular_velocity"],
        )

    @property
    def step_index(self) -> int:
        return self.world.step_count

    @property
    def contact_count(self) -> int:
        return self.world.contact_count()

    def observables(self) -> dict:
        return self.world.observables()
