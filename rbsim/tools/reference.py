"""What `rbsim sweep` measures errors against: analytic solutions, a converged run, or the
invariants of a scene at rest.

A scene names its reference in a `reference:` block (docs/format.md; cli.md, `rbsim sweep`):

- `projectile`, `free_spin`: one free body under gravity and constant loads,
  x(t) = x0 + v0 t + (g + F/m) t²/2 for the centre of mass, θ(t) = θ0 + ω0 t + (τ/I) t²/2.
- `slide`: a block sliding on a flat static support, its bottom face along its own x axis;
  Coulomb friction with the mixed coefficient μ: along the surface it accelerates by
  g·t - μ |g·n| sign(u) while it slides, and sticks when |g·t| <= μ |g·n|.
- `bounce`: a ball falling onto a flat static support: free flight between impacts, and
  at each impact v_n⁺ = -e v_n⁻ (e = 0 below solver.restitution_threshold: it rests).
- `collision`: two bodies (circles or convex polygons) in free flight that meet once; at
  the first touch the frictionless impulse γ = -(1 + e) m_eff v_n⁻ with
  m_eff⁻¹ = m_a⁻¹ + m_b⁻¹ + I_a⁻¹ (r_a × n)² + I_b⁻¹ (r_b × n)², then free flight again.
- `converged`: the same scene run by rbsim with a much smaller dt and more iterations
  (the sweep checks it against a run at twice its dt).
- `invariants`: bodies placed at rest in equilibrium (stacks, pyramids): the exact motion
  is no motion, so the error is the distance from the rest pose; penetration and energy
  drift are reported beside it.

The error of a run is the largest over the sample times and the tracked bodies of the
RMS distance between the body's material points in the run and in the reference,
sqrt(|Δx|² + 2 r_g² (1 - cos Δθ)) with r_g = sqrt(I/m) the radius of gyration: metres,
position and rotation errors in one number (|Δx| when the body does not turn).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..scene import Body, Scene
from ..scene.mass import body_mass_properties

__all__ = [
    "ANALYTIC_KINDS",
    "REFERENCE_KINDS",
    "Poses",
    "Reference",
    "ReferenceError",
    "make_reference",
    "pose_error",
]

ANALYTIC_KINDS = ("projectile", "free_spin", "slide", "bounce", "collision")
REFERENCE_KINDS = (*ANALYTIC_KINDS, "converged", "invariants")

# Impacts followed by the bounce reference before the ball is taken to rest (an e < 1
# ball without a restitution threshold bounces infinitely often in finite time).
MAX_BOUNCES = 1000

# Conservative advancement for the collision reference: stop at this gap, m, or after
# this many advances (the gap shrinks geometrically, so neither is reached in practice).
TOUCH_GAP = 1e-13
MAX_ADVANCES = 100_000


class ReferenceError(ValueError):
    """The scene's `reference:` cannot be built for this scene; the message says why."""


@dataclass
class Poses:
    """Sampled motion of some bodies: t (K,) s; x (K, B, 2) centre of mass, m; theta
    (K, B) unwrapped angle, rad; v (K, B, 2) m/s and w (K, B) rad/s (None when not
    recorded)."""

    t: np.ndarray
    x: np.ndarray
    theta: np.ndarray
    v: np.ndarray | None = None
    w: np.ndarray | None = None


def pose_error(run: Poses, ref: Poses, gyration: np.ndarray) -> tuple[float, float, float]:
    """(max RMS material-point distance m, max centre-of-mass distance m, max angle
    difference rad) over samples and bodies; `gyration` (B,) is sqrt(I/m) per body, m.
    A non-finite run gives inf."""
    dx = np.linalg.norm(run.x - ref.x, axis=2)
    dth = run.theta - ref.theta
    rms = np.sqrt(dx * dx + 2.0 * gyration[None, :] ** 2 * (1.0 - np.cos(dth)))
    if not (np.all(np.isfinite(rms)) and np.all(np.isfinite(dth))):
        return math.inf, math.inf, math.inf
    return (
        float(rms.max(initial=0.0)),
        float(dx.max(initial=0.0)),
        float(np.abs(dth).max(initial=0.0)),
    )


@dataclass
class Reference:
    """A reference for one scene.

    kind: one of REFERENCE_KINDS; family: "analytic", "converged" or "invariants";
    bodies: scene indices of the tracked bodies; gyration (B,) m; statement: one sentence
    that says what the error is measured against (printed with every sweep).
    """

    kind: str
    family: str
    bodies: tuple[int, ...]
    gyration: np.ndarray
    statement: str
    options: dict = field(default_factory=dict)
    _solution: object = None

    def poses(self, t: np.ndarray) -> Poses:
        """The analytic (or rest) poses of the tracked bodies at times t (s)."""
        if self._solution is None:
            raise ValueError(f"reference {self.kind!r} has no closed form; run it")
        x, theta = self._solution(np.asarray(t, dtype=float))
        return Poses(np.asarray(t, dtype=float), x, theta)


# --------------------------------------------------------------------------------------
# Helpers


def _com_world(body: Body) -> tuple[np.ndarray, float, float, float]:
    """Centre of mass in the world (m), mass (kg), inertia (kg·m²), r_g (m) of a body."""
    props = body_mass_properties(body)
    c, s = math.cos(body.angle), math.sin(body.angle)
    cx, cy = props.center
    x = np.array([body.position[0] + c * cx - s * cy, body.position[1] + s * cx + c * cy])
    return x, props.mass, props.inertia, math.sqrt(props.inertia / props.mass)


def _pick(scene: Scene, name: str | None, kind: str, what: str) -> int:
    """Index of the body named `name`, else of the only body of type `kind`."""
    if name is not None:
        for i, b in enumerate(scene.bodies):
            if b.name == name:
                if b.type != kind:
                    raise ReferenceError(f"{what} {name!r} must be {kind}, it is {b.type}")
                return i
        raise ReferenceError(f"no body named {name!r}")
    found = [i for i, b in enumerate(scene.bodies) if b.type == kind]
    if len(found) != 1:
        raise ReferenceError(
            f"the scene has {len(found)} {kind} bodies; name the {what} with "
            f"reference.{'body' if what == 'body' else 'support'}"
        )
    return found[0]


def _mix(rule: str, a: float, b: float) -> float:
    return {
        "sqrt": lambda: math.sqrt(a * b),
        "multiply": lambda: a * b,
        "min": lambda: min(a, b),
        "max": lambda: max(a, b),
    }[rule]()


def _single_material(body: Body, what: str):
    materials = {s.material for s in body.shapes}
    if len(materials) != 1:
        raise ReferenceError(f"{what} {body.name!r} has shapes of different materials")
    return body.shapes[0].material


def _no_damping(scene: Scene, kind: str) -> None:
    w = scene.world
    if w.linear_damping or w.angular_damping:
        raise ReferenceError(f"the {kind} reference assumes no damping (world.damping)")


def _world_vertices(body: Body) -> list[tuple[np.ndarray, float]]:
    """Each shape of a body as (world vertices (V,2) m, radius m)."""
    c, s = math.cos(body.angle), math.sin(body.angle)
    out = []
    for shape in body.shapes:
        v = np.array(shape.vertices, dtype=float)
        w = np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], axis=1)
        out.append((w + np.array(body.position), float(shape.radius)))
    return out


# --------------------------------------------------------------------------------------
# Analytic solutions


def _free_motion(scene: Scene, index: int, kind: str):
    """x(t), θ(t) of one body under gravity and its constant force and torque."""
    body = scene.bodies[index]
    _no_damping(scene, kind)
    if body.force_point is not None and any(body.force):
        raise ReferenceError(
            f"the {kind} reference needs the force at the centre of mass (no force_point)"
        )
    x0, m, inertia, _ = _com_world(body)
    v0 = np.array(body.velocity, dtype=float)
    a = np.array(scene.world.gravity, dtype=float) + np.array(body.force, dtype=float) / m
    alpha = body.torque / inertia

    def solution(t: np.ndarray):
        x = x0 + v0 * t[:, None] + 0.5 * a * (t * t)[:, None]
        theta = body.angle + body.angular_velocity * t + 0.5 * alpha * t * t
        return x[:, None, :], theta[:, None]

    return solution


def _slide(scene: Scene, index: int, support: int):
    """A block sliding along its own x axis on a flat support, with Coulomb friction."""
    body, base = scene.bodies[index], scene.bodies[support]
    _no_damping(scene, "slide")
    if any(body.force) or body.torque or body.angular_velocity:
        raise ReferenceError("the slide reference needs no force, torque or spin on the block")
    mu = _mix(
        scene.world.friction_mixing,
        _single_material(body, "body").friction,
        _single_material(base, "support").friction,
    )
    tangent = np.array([math.cos(body.angle), math.sin(body.angle)])
    normal = np.array([-tangent[1], tangent[0]])
    g = np.array(scene.world.gravity, dtype=float)
    press = -float(g @ normal)  # normal force per unit mass, m/s²
    if press <= 0.0:
        raise ReferenceError("gravity does not press the block onto its support (slide)")
    v0 = np.array(body.velocity, dtype=float)
    if abs(float(v0 @ normal)) > 1e-12 * (1.0 + float(np.abs(v0).max())):
        raise ReferenceError("the block's velocity must lie along its bottom face (slide)")
    x0, *_ = _com_world(body)
    u0, ag, f = float(v0 @ tangent), float(g @ tangent), mu * press

    def after_rest(tau: np.ndarray) -> np.ndarray:
        a = ag - math.copysign(f, ag) if abs(ag) > f else 0.0
        return 0.5 * a * tau * tau

    def along(t: np.ndarray) -> np.ndarray:
        if u0 == 0.0:
            return after_rest(t)
        a1 = ag - math.copysign(f, u0)
        if a1 * u0 >= 0.0:  # never slows down
            return u0 * t + 0.5 * a1 * t * t
        ts = -u0 / a1  # it stops at ts
        before = u0 * t + 0.5 * a1 * t * t
        s_stop = u0 * ts + 0.5 * a1 * ts * ts
        return np.where(t <= ts, before, s_stop + after_rest(np.maximum(t - ts, 0.0)))

    def solution(t: np.ndarray):
        x = x0 + along(t)[:, None] * tangent
        return x[:, None, :], np.full((t.shape[0], 1), body.angle)

    return solution, mu


def _support_height(support: Body, up: np.ndarray) -> float:
    """Highest point (m) of a static body along `up`."""
    top = -math.inf
    for v, r in _world_vertices(support):
        top = max(top, float((v @ up).max()) + r)
    return top


def _bounce(scene: Scene, index: int, support: int):
    """A ball falling onto a flat support, bouncing with v_n⁺ = -e v_n⁻."""
    body, base = scene.bodies[index], scene.bodies[support]
    _no_damping(scene, "bounce")
    if len(body.shapes) != 1 or body.shapes[0].kind != "circle":
        raise ReferenceError("the bounce reference needs a ball (one circle shape)")
    if any(body.force) or body.torque:
        raise ReferenceError("the bounce reference needs no force or torque on the ball")
    g = np.array(scene.world.gravity, dtype=float)
    gn = float(np.linalg.norm(g))
    if gn == 0.0:
        raise ReferenceError("the bounce reference needs gravity")
    up = -g / gn
    side = np.array([-up[1], up[0]])
    ball_mat, base_mat = _single_material(body, "body"), _single_material(base, "support")
    mu = _mix(scene.world.friction_mixing, ball_mat.friction, base_mat.friction)
    e = _mix(scene.world.restitution_mixing, ball_mat.restitution, base_mat.restitution)
    v0 = np.array(body.velocity, dtype=float)
    if mu > 0.0 and (abs(float(v0 @ side)) > 0.0 or body.angular_velocity):
        raise ReferenceError(
            "the bounce reference needs a ball that falls straight without spin, or no "
            f"friction (friction mixes to {mu:g})"
        )
    x0, *_ = _com_world(body)
    radius = body.shapes[0].radius
    rest = _support_height(base, up) + radius  # centre height when touching
    threshold = float(scene.solver.restitution_threshold)
    # events: (time s, height m, upward velocity m/s) at the start of each flight
    h, u, t0 = float(x0 @ up), float(v0 @ up), 0.0
    if h < rest - 1e-12:
        raise ReferenceError("the ball starts below the top of its support (bounce)")
    flights = []
    for _ in range(MAX_BOUNCES):
        flights.append((t0, h, u))
        tau = (u + math.sqrt(u * u + 2.0 * gn * (h - rest))) / gn
        v_in = u - gn * tau
        t0, h = t0 + tau, rest
        u = -e * v_in if -v_in > threshold else 0.0
        if u == 0.0:
            break
    flights.append((t0, rest, 0.0))  # at rest from here on (u = 0, no gravity effect)
    starts = np.array([f[0] for f in flights])
    x_side, w0 = float(x0 @ side), body.angular_velocity
    v_side = float(v0 @ side)

    def solution(t: np.ndarray):
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(flights) - 1)
        ts, hs, us = (np.array([f[j] for f in flights])[k] for j in range(3))
        tau = t - ts
        resting = k == len(flights) - 1
        height = np.where(resting, rest, hs + us * tau - 0.5 * gn * tau * tau)
        x = height[:, None] * up + (x_side + v_side * t)[:, None] * side
        return x[:, None, :], (body.angle + w0 * t)[:, None]

    return solution, e, flights[:-1]


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


class _Rigid:
    """One body of the collision reference in free flight: geometry in the body frame
    about the centre of mass."""

    def __init__(self, scene: Scene, index: int) -> None:
        body = scene.bodies[index]
        if len(body.shapes) != 1 or body.shapes[0].kind not in ("circle", "box", "polygon"):
            raise ReferenceError(
                f"the collision reference needs one circle or polygon shape per body "
                f"({body.name!r} has {', '.join(s.kind for s in body.shapes)})"
            )
        if any(body.force) or body.torque:
            raise ReferenceError("the collision reference needs no forces or torques")
        props = body_mass_properties(body)
        shape = body.shapes[0]
        self.circle = shape.kind == "circle"
        self.radius = float(shape.radius)
        self.local = np.array(shape.vertices, dtype=float) - np.array(props.center)
        self.m, self.inertia = props.mass, props.inertia
        self.x0, *_ = _com_world(body)
        self.th0 = body.angle
        self.v = np.array(body.velocity, dtype=float)
        self.w = body.angular_velocity
        self.t0 = 0.0
        self.g = np.array(scene.world.gravity, dtype=float)
        self.reach = float(np.linalg.norm(self.local, axis=1).max()) + self.radius

    def pose(self, t: float) -> tuple[np.ndarray, float]:
        tau = t - self.t0
        return self.x0 + self.v * tau + 0.5 * self.g * tau * tau, self.th0 + self.w * tau

    def vertices(self, t: float) -> np.ndarray:
        x, th = self.pose(t)
        c, s = math.cos(th), math.sin(th)
        v = self.local
        return x + np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], axis=1)

    def restart(self, t: float, v: np.ndarray, w: float) -> None:
        """Continue in free flight from the pose at t with new velocities."""
        self.x0, self.th0 = self.pose(t)
        self.v = v + self.g * (t - self.t0)
        self.w, self.t0 = w, t


def _polygon_gap(p: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """SAT separation of convex CCW polygons p and q (m; a lower bound on their distance,
    exact in sign), the normal from p to q, and the touching point."""
    best = (-math.inf, np.zeros(2), np.zeros(2))
    for a, b, flip in ((p, q, 1.0), (q, p, -1.0)):
        edges = np.roll(a, -1, axis=0) - a
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        sep = np.einsum("ekd,ed->ek", b[None, :, :] - a[:, None, :], normals)  # (E, Vb)
        low = sep.min(axis=1)
        k = int(np.argmax(low))
        if low[k] > best[0]:
            touching = b[np.abs(sep[k] - low[k]) <= 1e-9 * (1.0 + abs(low[k]))]
            best = (
                float(low[k]),
                flip * normals[k],
                touching.mean(axis=0) - 0.5 * low[k] * normals[k],
            )
    return best


def _point_polygon(c: np.ndarray, poly: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Signed distance (m) from point c to a convex CCW polygon, the unit direction from
    the polygon towards c, and the closest point on the polygon boundary."""
    edges = np.roll(poly, -1, axis=0) - poly
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    sep = np.einsum("ed,ed->e", c[None, :] - poly, normals)
    if sep.max() <= 0.0:  # inside: the nearest face
        k = int(np.argmax(sep))
        return float(sep[k]), normals[k], c - sep[k] * normals[k]
    best = (math.inf, np.zeros(2), np.zeros(2))
    for k in range(poly.shape[0]):
        a, e = poly[k], edges[k]
        s = min(max(float((c - a) @ e) / float(e @ e), 0.0), 1.0)
        p = a + s * e
        d = float(np.linalg.norm(c - p))
        if d < best[0]:
            best = (d, (c - p) / d, p)
    return best


def _gap(a: _Rigid, b: _Rigid, t: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(gap m, lower bound on the distance, exact in sign; normal from a to b; contact
    point) of the two bodies at time t."""
    va, vb = a.vertices(t), b.vertices(t)
    if a.circle and b.circle:
        d = vb[0] - va[0]
        dist = float(np.linalg.norm(d))
        n = d / dist if dist > 0.0 else np.array([1.0, 0.0])
        return (
            dist - a.radius - b.radius,
            n,
            va[0] + (a.radius + 0.5 * (dist - a.radius - b.radius)) * n,
        )
    if a.circle or b.circle:
        circle, poly, sign = (a, b, -1.0) if a.circle else (b, a, 1.0)
        c = (va if a.circle else vb)[0]
        d, n, p = _point_polygon(c, vb if a.circle else va)
        return d - circle.radius, sign * n, p
    return _polygon_gap(va, vb)


def _collision(scene: Scene):
    """Two bodies in free flight, one frictionless impact, free flight again."""
    _no_damping(scene, "collision")
    dynamic = [i for i, b in enumerate(scene.bodies) if b.type == "dynamic"]
    if len(dynamic) != 2 or len(scene.bodies) != 2:
        raise ReferenceError(
            f"the collision reference needs exactly two bodies, both dynamic "
            f"(the scene has {len(scene.bodies)} bodies, {len(dynamic)} dynamic)"
        )
    ia, ib = dynamic
    mat_a = _single_material(scene.bodies[ia], "body")
    mat_b = _single_material(scene.bodies[ib], "body")
    mu = _mix(scene.world.friction_mixing, mat_a.friction, mat_b.friction)
    if mu != 0.0:
        raise ReferenceError(
            f"the collision reference is frictionless; the bodies' friction mixes to {mu:g}"
        )
    e = _mix(scene.world.restitution_mixing, mat_a.restitution, mat_b.restitution)
    a, b = _Rigid(scene, ia), _Rigid(scene, ib)
    duration = scene.world.steps * scene.world.dt
    # conservative advancement: the gap cannot close faster than `rate`
    rate = float(np.linalg.norm(a.v - b.v)) + abs(a.w) * a.reach + abs(b.w) * b.reach
    t, hit = 0.0, None
    gap, n, p = _gap(a, b, t)
    if gap < -1e-9:
        raise ReferenceError("the two bodies overlap at the start (collision)")
    for _ in range(MAX_ADVANCES):
        if gap <= TOUCH_GAP:
            hit = t
            break
        if rate == 0.0:
            break
        t += gap / rate
        if t > duration:
            break
        gap, n, p = _gap(a, b, t)
    if hit is None:
        raise ReferenceError(f"the two bodies do not meet within the run ({duration:g} s)")
    xa, _ = a.pose(hit)
    xb, _ = b.pose(hit)
    va = a.v + a.g * (hit - a.t0)
    vb = b.v + b.g * (hit - b.t0)
    ra, rb = p - xa, p - xb
    rel = (vb + b.w * np.array([-rb[1], rb[0]])) - (va + a.w * np.array([-ra[1], ra[0]]))
    vn = float(rel @ n)
    if vn >= 0.0:
        raise ReferenceError("the bodies touch without approaching (collision)")
    threshold = float(scene.solver.restitution_threshold)
    e_used = e if -vn > threshold else 0.0
    k = 1 / a.m + 1 / b.m + _cross(ra, n) ** 2 / a.inertia + _cross(rb, n) ** 2 / b.inertia
    gamma = -(1.0 + e_used) * vn / k  # impulse on b along n (on a along -n), N·s
    a_after = (va - gamma * n / a.m, a.w - _cross(ra, n) * gamma / a.inertia)
    b_after = (vb + gamma * n / b.m, b.w + _cross(rb, n) * gamma / b.inertia)
    before = (
        (a.x0.copy(), a.th0, a.v.copy(), a.w, a.t0),
        (b.x0.copy(), b.th0, b.v.copy(), b.w, b.t0),
    )
    flights = {"before": before}
    a.restart(hit, *a_after)
    b.restart(hit, *b_after)
    flights["after"] = (
        (a.x0.copy(), a.th0, a.v.copy(), a.w, a.t0),
        (b.x0.copy(), b.th0, b.v.copy(), b.w, b.t0),
    )
    g = a.g

    def solution(t: np.ndarray):
        x = np.empty((t.shape[0], 2, 2))
        theta = np.empty((t.shape[0], 2))
        for j, key in enumerate(("before", "after")):
            mask = t < hit if key == "before" else t >= hit
            tm = t[mask]
            for i, (x0, th0, v, w, t0) in enumerate(flights[key]):
                tau = tm - t0
                x[mask, i] = x0 + v * tau[:, None] + 0.5 * g * (tau * tau)[:, None]
                theta[mask, i] = th0 + w * tau
            del j
        return x, theta

    return solution, (ia, ib), hit, e_used, gamma


# --------------------------------------------------------------------------------------
# Building a reference from the scene's `reference:` block


def make_reference(scene: Scene) -> Reference:
    """The reference the scene declares (`reference:`), or a converged run when it
    declares none. Raises ReferenceError when the scene does not fit the declared kind."""
    spec = dict(getattr(scene, "reference", None) or {})
    kind = spec.get("kind", "converged")
    if kind not in REFERENCE_KINDS:
        raise ReferenceError(f"unknown reference kind {kind!r}")
    duration = scene.world.steps * scene.world.dt

    def gyr(indices) -> np.ndarray:
        return np.array([_com_world(scene.bodies[i])[3] for i in indices])

    if kind in ("projectile", "free_spin"):
        i = _pick(scene, spec.get("body"), "dynamic", "body")
        name = scene.bodies[i].name
        what = "projectile" if kind == "projectile" else "free spin"
        statement = (
            f"analytic {what} of body {name!r}: x = x0 + v0 t + (g + F/m) t²/2, "
            "θ = θ0 + ω0 t + (τ/I) t²/2"
        )
        return Reference(
            kind, "analytic", (i,), gyr([i]), statement, spec, _free_motion(scene, i, kind)
        )
    if kind == "slide":
        i = _pick(scene, spec.get("body"), "dynamic", "body")
        s = _pick(scene, spec.get("support"), "static", "support")
        solution, mu = _slide(scene, i, s)
        statement = (
            f"analytic slide of body {scene.bodies[i].name!r} on {scene.bodies[s].name!r} "
            f"with Coulomb friction μ = {mu:g}"
        )
        return Reference(kind, "analytic", (i,), gyr([i]), statement, spec, solution)
    if kind == "bounce":
        i = _pick(scene, spec.get("body"), "dynamic", "body")
        s = _pick(scene, spec.get("support"), "static", "support")
        solution, e, flights = _bounce(scene, i, s)
        impacts = sum(1 for f in flights[1:] if f[0] <= duration)
        statement = (
            f"analytic bounce of ball {scene.bodies[i].name!r} on {scene.bodies[s].name!r}: "
            f"free fall, v_n⁺ = -e v_n⁻ with e = {e:g} ({impacts} impact"
            f"{'' if impacts == 1 else 's'} within the run)"
        )
        return Reference(kind, "analytic", (i,), gyr([i]), statement, spec, solution)
    if kind == "collision":
        solution, pair, hit, e, gamma = _collision(scene)
        na, nb = (scene.bodies[i].name for i in pair)
        statement = (
            f"analytic collision of {na!r} and {nb!r} at t = {hit:.6g} s: frictionless "
            f"impulse γ = -(1 + e) m_eff v_n⁻ = {gamma:.6g} N·s with e = {e:g}"
        )
        return Reference(kind, "analytic", pair, gyr(pair), statement, spec, solution)
    dynamic = tuple(i for i, b in enumerate(scene.bodies) if b.type == "dynamic")
    if not dynamic:
        raise ReferenceError("the scene has no dynamic body to measure")
    if kind == "invariants":
        for i in dynamic:
            b = scene.bodies[i]
            if any(b.velocity) or b.angular_velocity or any(b.force) or b.torque:
                raise ReferenceError(
                    f"the invariants reference needs every body placed at rest without "
                    f"loads; body {b.name!r} is not"
                )
        rest = [_com_world(scene.bodies[i])[0] for i in dynamic]
        x_rest = np.array(rest)
        th_rest = np.array([scene.bodies[i].angle for i in dynamic])

        def at_rest(t: np.ndarray):
            k = t.shape[0]
            return np.broadcast_to(x_rest, (k, *x_rest.shape)).copy(), np.tile(th_rest, (k, 1))

        statement = (
            f"invariants: the {len(dynamic)} bodies start at rest in equilibrium, so the "
            "exact motion is none; error = distance from the rest pose (drift); "
            "penetration and energy drift reported beside it"
        )
        return Reference(kind, "invariants", dynamic, gyr(dynamic), statement, spec, at_rest)
    statement = "converged rbsim run of the same scene"  # completed by the sweep
    return Reference(kind, "converged", dynamic, gyr(dynamic), statement, spec, None)


# --------------------------------------------------------------------------------------
# Penetration (invariants)
