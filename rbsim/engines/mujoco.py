"""The adapter of MuJoCo ("mujoco"), rbsim's reference engine in 3D.

The scene is written as an MJCF model (`mjcf`): one body with a free joint per dynamic
body, with the scene body's orientation, and an `inertial` element with rbsim's own mass
and full inertia tensor (`fullinertia`, about the centre of mass, at the COM's position
`pos` in the MuJoCo body's frame), from rbsim's compiled Model: MuJoCo never
computes mass properties itself (its meshes are float32: a hull's centre of mass comes
out 3e-9 m off and its inertia 7e-8 relative). A scene whose bodies cannot touch is
written with contacts disabled (`<flag contact="disable"/>`) and its static bodies left
out; one whose bodies can touch gets a geom per shape and an MJCF <pair> per pair of
shapes that can touch, with MuJoCo's soft contact law set per pair (see "contacts"
below: the damping ratio that gives the pair's restitution in MuJoCo's own impact), or
is refused with UnsupportedScene where MuJoCo cannot express it; kinematic
bodies move as prescribed (x0 + v t, exp(t ω / 2) q0; MuJoCo has nothing to compute
for them). Gravity is written as the scene gives it, in rbsim's y-up world (MuJoCo
takes any vector; its z-up default does not apply). One scene step is
`solver.substeps` MuJoCo steps of dt / substeps with MuJoCo's Euler integrator
(semi-implicit: qvel += h qacc, then qpos moves with the new qvel).

Where the MuJoCo body's frame sits (MujocoSettings.frame): "com" (the default) puts it
at the centre of mass (inertial pos 0), "origin" at the scene's body origin (inertial
pos = the COM's body-frame offset). A free joint moves its frame's point with that
point's velocity, so with "origin" a spinning body whose COM is off its origin moves its
COM by h v_origin + (R(h ω) − 1) R com per step instead of h v_com: a first-order error
that rbsim (which moves the COM) does not have; measured on the thrown compound of
scenes/3d/compare (COM 0.31 m off the origin, |ω| = 6.4 rad/s, h = 1/240 s), 0.12 m of
COM position and 0.062 m/s of COM velocity off the semi-implicit parabola in 2 s
(halving with h), against round-off with "com". The comparison wants the engines'
methods, not that frame choice, to differ: "com".

State, as MuJoCo 4.0.0 keeps it (tests/test_mujoco.py measures it): a free joint's
qpos is the body frame's origin (3, world) and its orientation (w, x, y, z); qvel is the
frame origin's velocity (world frame) followed by the angular velocity in the BODY frame.
rbsim's layout: the body origin x − R p (p: the frame's point in rbsim's body frame, the
COM or 0), the COM's velocity v_frame + ω × R (com − p) and ω in the world frame.

Contacts (the "contacts" section below has the measurements): every shape is a geom
with contype = conaffinity = 0, so that only the explicit pairs collide, each pair
with the scene's mixed friction (MuJoCo would take the larger of two geoms' values)
and its own solref (MuJoCo would average two geoms'): condim 3, the elliptic cone,
solimp SOLIMP (a constant impedance 0.99: a linear law), solref (-ω0², -2 ζ ω0) with
ω0 = π / (CONTACT_STEPS h), ζ = `damping_for(e, h)` found by bisection on MuJoCo's own
impact, friction rows damped with FRICTION_ZETA. MuJoCo has no restitution threshold:
the bridge switches a pair that starts touching slowly to its most damped contact
(`_setup_threshold`).
Refused: a kinematic body that can touch, 0 < e below MuJoCo's least rebound, a step at
which an impact could tunnel (`contact_pairs`' depth estimate), more than MAX_PAIRS.

Forces and torques go through xfrc_applied (world frame, at the COM): a scene force at
a body point adds its torque (R arm) × f, evaluated at the start of each MuJoCo step as
rbsim does. Damping: rbsim's law is implicit, v <- (v + h a) / (1 + h c) and
L <- (L + h τ) / (1 + h c_ang) (cpp/src/dynamics/integrate.cpp); MuJoCo's joint damping
acts on qvel (origin velocity, body-frame ω) with one coefficient for all six dofs, so
the bridge applies instead, before each step, the force -m c (v + h a) / (1 + h c) and
the torque -c_ang (L + h τ) / (1 + h c_ang): with them one Euler step gives rbsim's
damped COM velocity exactly and its damped L up to MuJoCo's own rotation error.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..config import NonFiniteState
from ..io.observables import observables
from ..scene import Scene
from ..scene import types as T
from ..scene.compile import Model, State, build
from ..scene.geometry3d import hull_width, matrix_quat, quat_matrix
from .base import Engine, EngineUnavailable, Snapshot, UnsupportedScene

try:
    import mujoco
except ImportError:  # the optional extra `mujoco` is not installed
    mujoco = None

__all__ = [
    "INSTALL_HINT",
    "ContactPair",
    "MujocoEngine",
    "MujocoSettings",
    "contact_pairs",
    "damping_for",
    "geoms",
    "mjcf",
    "pair_lines",
    "rebound",
    "rebounds",
    "solref",
    "quat_exp",
    "quat_matrix",
    "quat_mul",
]

INSTALL_HINT = (
    "MuJoCo is not installed; it is rbsim's optional extra `mujoco`: "
    "pip install 'rbsim[mujoco]' (make install installs it)"
)


FRAMES = ("com", "origin")


@dataclass
class MujocoSettings:
    """How the MuJoCo model is set up. substeps: MuJoCo steps per scene dt (each of
    length dt / substeps, s); None: the scene's solver.substeps. frame: where each MuJoCo
    body's frame sits, "com" or "origin" (the module's docstring)."""

    substeps: int | None = None
    frame: str = "com"


def quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """(N,4) unit quaternions exp(θ/2) of rotation vectors (N,3) (rad)."""
    angle = np.linalg.norm(rotvec, axis=1)
    half = 0.5 * angle
    k = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return np.concatenate([np.cos(half)[:, None], k[:, None] * rotvec], axis=1)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,4) Hamilton products a b of (N,4) quaternions (w, x, y, z)."""
    aw, av = a[:, :1], a[:, 1:]
    bw, bv = b[:, :1], b[:, 1:]
    w = aw * bw - np.sum(av * bv, axis=1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.concatenate([w, v], axis=1)


def _num(x: float) -> str:
    """A float as MJCF text that reads back to the same double (repr round-trips)."""
    return repr(float(x))


def _nums(values: np.ndarray) -> str:
    return " ".join(_num(v) for v in np.ravel(values))


# -- contacts ---------------------------------------------------------------------------
#
# MuJoCo's contacts are soft: a contact's reference acceleration is a_ref = -b v - k r
# (r the penetration, v its rate; solref's direct form (-k, -b)), and with a constant
# impedance d (solimp (d, d, width, mid, power)) the solved normal acceleration is
# (1 - d) a_free + d a_ref: a damped spring, integrated with MuJoCo's explicit damping.
# An impact is thus a half period of that oscillator, and its rebound depends on ζ alone
# when the period is a fixed number of steps. Measured with MuJoCo 4.0.0 (issue 16):
# e = 0 is out of reach (the damping is explicit), a matched e needs the contact to last
# about CONTACT_STEPS steps, and the step must be short for that contact to stay shallow.

# MuJoCo steps an impact lasts: ω0 = π / (CONTACT_STEPS h) (rad/s). Fewer steps resolve
# the half period too coarsely for a matched e; more make the contact softer (deeper and
# longer) for the same h.
CONTACT_STEPS = 25
# solimp (d0, d_width, width m, midpoint, power): a constant impedance d = 0.99, so that
# the contact law is linear (e does not depend on the impact speed) and nearly the
# reference acceleration itself.
SOLIMP = (0.99, 0.99, 0.001, 0.5, 2.0)
# The most damping the bridge gives (ζ): MuJoCo's explicit damping stops resolving the
# impact near ζ = 4 at CONTACT_STEPS = 25 (the rebound grows again: b h = 2 ζ π / 25
# nears 1), so 3 keeps a margin. It rebounds with e = 0.016 on average (0.007 to 0.025
# by where the impact falls in a step; `rebounds`), the least e the bridge reaches.
ZETA_MAX = 3.0
# The friction rows' damping ratio (their solref (-ω0², -2 ζf ω0); friction has no
# stiffness): a slide's reference deceleration is b v_t with b = 2 ζf ω0, so friction is
# Coulomb's (saturated at μ g) above v_t = μ g / b and viscous below it; and MuJoCo's
# soft elliptic cone trades normal force for friction, so a large b kicks a sliding box
# off its support. Measured at h = 0.2 ms: on the 3D slope the normal velocity chatters
# at 0.007 m/s with ζf = 0.03 (0.017 with 0.1, 0.12 with 1); the 3D pile (μ = 0.5)
# settles with 0.03 and 0.05 (kinetic energy 2e-5 J and 7e-4 J at 3 s) and does not
# with 0.1 (11 J: a box keeps rocking on the others). With 0.03 (b = 37.7/s) friction is
# viscous below 13 cm/s on that pile, and its boxes spread wider than rbsim's
# (scenes/3d/compare/statistics/pile.yaml).
FRICTION_ZETA = 0.03
# A pair whose estimated deepest penetration (`contact_pairs`) exceeds this fraction of
# its thinner shape's half-thickness is refused: the estimate is the undamped depth
# v / ω0, and a body pushed far into a thin one is pushed out through its far side.
# Measured (a 5 cm pellet at 10 m/s onto a 10 cm floor, e = 0.5): through the floor at
# h = 2 ms (estimate 0.21 m), its centre down to the floor's surface at 1 ms (0.10 m),
# a clean bounce at 0.5 ms (estimate 0.052 m, actual depth 0.029 m); refused above
# 0.025 m, at h > 0.24 ms.
TUNNEL_FRACTION = 0.5
# The impact that `rebounds` runs: approach speed (m/s) onto a plane, sphere radius (m)
# (the contact law is linear, so neither changes e), and the number of depths of the
# first step in contact it averages over.
CALIBRATION_SPEED = 1.0
CALIBRATION_RADIUS = 1.0
CALIBRATION_PHASES = 16
# The most shape pairs the bridge writes (each an MJCF <pair>, which MuJoCo tests every
# step, a bounding-sphere check first): a bound on the model's size. The 27-box pile's
# 378 pairs cost MuJoCo about 0.5 ms per step (measured on the shared machine).
MAX_PAIRS = 20000


def contact_frequency(h: float) -> float:
    """ω0 (rad/s) of the contact oscillator for MuJoCo steps of h (s): its half period
    lasts CONTACT_STEPS steps."""
    return math.pi / (CONTACT_STEPS * h)


def solref(zeta: float, h: float) -> tuple[float, float]:
    """MuJoCo's direct solref (-ω0², -2 ζ ω0) (1/s², 1/s) for damping ratio ζ and steps
    of h (s)."""
    w0 = contact_frequency(h)
    return (-w0 * w0, -2.0 * zeta * w0)


def _impact_model(h: float) -> tuple:
    """MuJoCo's model and data of the calibration impact at steps of h (s): a sphere of
    CALIBRATION_RADIUS over a plane (z up), no gravity, one frictionless pair (condim 1)
    with SOLIMP; its solref is set per run. Built afresh for each call (about 1 ms), never
    cached: MuJoCo objects that outlive the call (in a module-level cache, freed only when
    the interpreter tears its modules down, after MuJoCo's own) crashed the process at
    exit."""
    if mujoco is None:
        raise EngineUnavailable(INSTALL_HINT)
    r = _num(CALIBRATION_RADIUS)
    xml = (
        f'<mujoco><option timestep="{_num(h)}" gravity="0 0 0" integrator="Euler"/>'
        '<worldbody><geom name="plane" type="plane" size="0 0 1" contype="0"'
        f' conaffinity="0"/><body pos="0 0 {r}"><freejoint/>'
        f'<geom name="ball" type="sphere" size="{r}" mass="1" contype="0"'
        ' conaffinity="0"/></body></worldbody><contact><pair geom1="plane" geom2="ball"'
        f' condim="1" solimp="{_nums(SOLIMP)}"/></contact></mujoco>'
    )
    m = mujoco.MjModel.from_xml_string(xml)
    return m, mujoco.MjData(m)


@lru_cache(maxsize=1024)
def rebounds(zeta: float, h: float) -> tuple[float, ...]:
    """The restitutions MuJoCo gives with damping ratio ζ at steps of h (s): the normal
    speed after / before one impact of a sphere onto a plane, without gravity or
    friction, with the bridge's solref and SOLIMP, measured by running MuJoCo at each of
    CALIBRATION_PHASES evenly spread depths of the first step in contact (0 to one
    step's travel: where the impact falls within a step changes MuJoCo's rebound by a
    few per cent when ζ > 0)."""
    m, d = _impact_model(h)
    m.pair_solref[0] = solref(zeta, h)
    v = CALIBRATION_SPEED
    out = []
    for k in range(CALIBRATION_PHASES):
        mujoco.mj_resetData(m, d)
        d.qpos[2] = CALIBRATION_RADIUS - (k + 0.5) / CALIBRATION_PHASES * v * h
        d.qvel[2] = -v
        for _ in range(100 * CONTACT_STEPS):
            mujoco.mj_step(m, d)
            if d.ncon == 0:
                break
        out.append(float(d.qvel[2]) / v)
    return tuple(out)


def rebound(zeta: float, h: float) -> float:
    """MuJoCo's restitution with damping ratio ζ at steps of h (s): the mean of
    `rebounds` over where the impact falls within a step."""
    values = rebounds(zeta, h)
    return math.fsum(values) / len(values)


@lru_cache(maxsize=256)
def damping_for(e: float, h: float) -> float:
    """The damping ratio ζ in [0, ZETA_MAX] whose MuJoCo impact (`rebound`) leaves at
    restitution e, by bisection (the rebound falls as ζ grows); ZETA_MAX when e is at or
    below what ZETA_MAX gives (the least MuJoCo reaches)."""
    if e <= rebound(ZETA_MAX, h):
        return ZETA_MAX
    lo, hi = 0.0, ZETA_MAX
    if rebound(0.0, h) <= e:
        return 0.0
    for _ in range(48):  # to 1e-14 of ZETA_MAX
        mid = 0.5 * (lo + hi)
        if rebound(mid, h) > e:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def half_thickness(shape) -> float:  # noqa: ANN001 - a resolved 3D Shape
    """Half the least width of a resolved 3D shape (m): a sphere's or capsule's radius, half
    a box's smallest side or a convex hull's least width; inf for a plane (a half-space
    cannot be passed through)."""
    if shape.kind == "plane":
        return math.inf
    if shape.kind in ("sphere", "capsule"):
        return float(shape.radius)
    if shape.kind == "box":
        return 0.5 * float(min(shape.size))
    return 0.5 * hull_width(shape.vertices, shape.faces)


@dataclass(frozen=True)
class ContactPair:
    """One MJCF <pair>: shapes a, b (scene shape indices), bodies (names), the mixed
    friction μ and restitution e, MuJoCo's damping ratio ζ for that e and the rebound it
    gives (e_mujoco), and the estimated deepest penetration (m) of their fastest impact
    against the thinner shape's half-thickness (m)."""

    a: int
    b: int
    bodies: tuple[str, str]
    friction: float
    restitution: float
    zeta: float
    e_mujoco: float
    depth: float
    thickness: float
    speed: float


def speed_bounds(scene: Scene, model: Model, state: State) -> np.ndarray:
    """(N,) an estimate of each body's fastest speed over the run (m/s; 0 for bodies that
    are not dynamic): its initial speed plus the spin's speed at its farthest vertex,
    plus what gravity and its force add, the lesser of a fall from its COM to the lowest
    point of any shape (for a level ground) and |g| + |F| / m over the whole duration.
    Speed passed on by collisions is not counted (an estimate, not a bound)."""
    g = float(np.linalg.norm(model.gravity))
    duration = float(scene.world.steps) * float(scene.world.dt)
    up = -model.gravity / g if g > 0.0 else np.array([0.0, 1.0, 0.0])
    rot = quat_matrix(state.body_q)
    lowest = math.inf
    for s in range(len(model.shape_body)):
        i = int(model.shape_body[s])
        rows = slice(int(model.shape_vstart[s]), int(model.shape_vstart[s] + model.shape_vcount[s]))
        points = state.body_x[i] + model.vertex_local[rows] @ rot[i].T
        if int(model.shape_kind[s]) == T.SHAPE_PLANE:
            normal = rot[i] @ model.normal_local[rows][0]
            level = abs(float(normal @ up)) > 1.0 - 1e-12
            lowest = min(lowest, float(points[0] @ up) if level else -math.inf)
        else:
            lowest = min(lowest, float((points @ up).min()) - float(model.shape_radius[s]))
    out = np.zeros(len(model.body_type))
    for i in np.flatnonzero(model.body_type == T.BODY_DYNAMIC):
        push = float(np.linalg.norm(model.body_force[i])) / float(model.body_mass[i])
        drop = max(float(state.body_x[i] @ up) - lowest, 0.0)
        fall = math.sqrt(2.0 * g * drop) if push == 0.0 else math.inf
        gain = min(fall, (g + push) * duration)
        spin = float(np.linalg.norm(state.body_w[i])) * body_reach(model, i)
        out[i] = float(np.linalg.norm(state.body_v[i])) + spin + gain
    return out


def body_reach(model: Model, i: int) -> float:
    """The farthest point of body i's shapes from its COM, m."""
    reach = 0.0
    for s in np.flatnonzero(model.shape_body == i):
        start = int(model.shape_vstart[s])
        v = model.vertex_local[start : start + int(model.shape_vcount[s])]
        reach = max(reach, float(np.linalg.norm(v, axis=1).max()) + float(model.shape_radius[s]))
    return reach


def plane_approach(scene: Scene, model: Model, state: State, i: int, plane: int) -> float:
    """An estimate of the fastest approach (m/s) of dynamic body i onto the static plane
    shape `plane` (a shape index): its initial velocity into the plane, the spin's speed
    at its farthest point, and a fall through its lowest point's gap to the plane under
    the part of gravity and of its force that presses into the plane (over the whole
    duration when it has a force). Speed from collisions with other bodies is not
    counted (an estimate)."""
    j = int(model.shape_body[plane])
    rot = quat_matrix(state.body_q[[i, j]])
    start = int(model.shape_vstart[plane])
    n = rot[1] @ model.normal_local[start]
    point = state.body_x[j] + rot[1] @ model.vertex_local[start]
    gap = math.inf
    for s in np.flatnonzero(model.shape_body == i):
        first = int(model.shape_vstart[s])
        rows = slice(first, first + int(model.shape_vcount[s]))
        heights = (state.body_x[i] + model.vertex_local[rows] @ rot[0].T - point) @ n
        gap = min(gap, float(heights.min()) - float(model.shape_radius[s]))
    force = model.body_force[i] / float(model.body_mass[i])
    press = max(-float((model.gravity + force) @ n), 0.0)
    fall = math.sqrt(2.0 * press * max(gap, 0.0))
    if np.any(force != 0.0):
        fall = max(fall, press * float(scene.world.steps) * float(scene.world.dt))
    into = max(-float(state.body_v[i] @ n), 0.0)
    return into + float(np.linalg.norm(state.body_w[i])) * body_reach(model, i) + fall


def plane_quat(normal: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a frame whose z axis is the unit `normal` (an
    MJCF plane is its frame's z = 0, solid below): x along the world axis least aligned
    with the normal, made orthogonal to it, y = z × x."""
    z = np.asarray(normal, float)
    x = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    return np.asarray(matrix_quat(np.column_stack([x, np.cross(z, x), z])))


def geoms(
    scene: Scene, model: Model, state: State, frame_points: np.ndarray
) -> tuple[list[list[str]], list[str]]:
    """The MJCF geoms of every shape, named g<shape index>, with collisions off (contype
    and conaffinity 0: only the explicit pairs collide): per body the lines to write in
    its MuJoCo body (dynamic bodies: in their MuJoCo frame, at frame_points (N,3) m of
    rbsim's body frame; static bodies: in the world, at their placement), and the
    <asset> mesh lines of convex shapes (their vertices in the geom's frame)."""
    per_body: list[list[str]] = [[] for _ in scene.bodies]
    assets: list[str] = []
    rot = quat_matrix(state.body_q)
    s = 0
    for i, body in enumerate(scene.bodies):
        # a point p of rbsim's body frame is at `shift` + `turn` p in the geom's frame
        if int(model.body_type[i]) == T.BODY_DYNAMIC:  # the MuJoCo body, at frame_points
            shift, turn, q = -frame_points[i], np.eye(3), np.array([1.0, 0.0, 0.0, 0.0])
        else:  # the world: x = x_com + R (p - com)
            shift, turn, q = state.body_x[i] - rot[i] @ model.body_com[i], rot[i], state.body_q[i]
        for shape in body.shapes:

            def at(p: tuple, shift: np.ndarray = shift, turn: np.ndarray = turn) -> str:
                return _nums(shift + turn @ np.asarray(p, float))

            quat = _nums(quat_mul(q[None], np.asarray([shape.orientation], float))[0])
            line = f'<geom name="g{s}" contype="0" conaffinity="0"'
            if shape.kind == "sphere":
                line += f' type="sphere" size="{_num(shape.radius)}" pos="{at(shape.vertices[0])}"'
            elif shape.kind == "box":
                half = _nums(0.5 * np.asarray(shape.size, float))
                line += f' type="box" size="{half}" pos="{at(shape.offset)}" quat="{quat}"'
            elif shape.kind == "capsule":
                a, b = shape.vertices
                line += f' type="capsule" size="{_num(shape.radius)}" fromto="{at(a)} {at(b)}"'
            elif shape.kind == "convex":
                points = " ".join(at(v) for v in shape.vertices)
                assets.append(f'    <mesh name="m{s}" vertex="{points}"/>')
                line += f' type="mesh" mesh="m{s}"'
            else:  # a plane (static): MJCF's plane is its frame's z = 0, normal +z
                up = _nums(plane_quat(turn @ np.asarray(shape.normal, float)))
                line += f' type="plane" size="0 0 1" pos="{at(shape.vertices[0])}" quat="{up}"'
            per_body[i].append(line + "/>")
            s += 1
    return per_body, assets


def contact_pairs(scene: Scene, model: Model, state: State, h: float) -> list[ContactPair]:
    """Every pair of shapes that can touch (of two bodies, one of them dynamic), in shape
    order, with the scene's mixed friction and restitution, MuJoCo's damping ratio for
    that restitution at steps of h (s), and the depth estimate of their fastest impact:
    the approach speed estimate v (onto a plane `plane_approach`, else the sum of the
    two bodies' `speed_bounds`) over ω0, plus the sag of resting on the contact,
    |g| / (d ω0²)."""
    from .pymunk import MIXING_RULES

    fmix = MIXING_RULES[scene.world.friction_mixing]
    rmix = MIXING_RULES[scene.world.restitution_mixing]
    speed = speed_bounds(scene, model, state)
    w0 = contact_frequency(h)
    sag = float(np.linalg.norm(model.gravity)) / (SOLIMP[0] * w0 * w0)
    shapes = [(i, shape) for i, body in enumerate(scene.bodies) for shape in body.shapes]
    names = [b.name for b in scene.bodies]
    dynamic = model.body_type == T.BODY_DYNAMIC
    out = []
    for a in range(len(shapes)):
        i, sa = shapes[a]
        for b in range(a + 1, len(shapes)):
            j, sb = shapes[b]
            if i == j or not (dynamic[i] or dynamic[j]):
                continue
            e = rmix(sa.material.restitution, sb.material.restitution)
            zeta = damping_for(e, h)
            if sa.kind == "plane" or sb.kind == "plane":
                moving, plane = (j, a) if sa.kind == "plane" else (i, b)
                v = plane_approach(scene, model, state, moving, plane)
            else:
                v = float(speed[i] + speed[j])
            out.append(
                ContactPair(
                    a=a,
                    b=b,
                    bodies=(names[i], names[j]),
                    friction=fmix(sa.material.friction, sb.material.friction),
                    restitution=e,
                    zeta=zeta,
                    e_mujoco=rebound(zeta, h),
                    depth=v / w0 + sag,
                    thickness=min(half_thickness(sa), half_thickness(sb)),
                    speed=v,
                )
            )
    return out


def tunnel_free_step(speed: float, thickness: float, gravity: float) -> float:
    """The longest MuJoCo step h (s) at which `contact_pairs`' depth estimate of an
    impact at `speed` (m/s), v / ω0 + |g| / (d ω0²) with ω0 = π / (CONTACT_STEPS h),
    stays within TUNNEL_FRACTION of `thickness` (m): the root of a quadratic in 1 / ω0."""
    room = TUNNEL_FRACTION * thickness
    a = gravity / SOLIMP[0]
    # a x² + v x = room for x = 1 / ω0, in the form that does not cancel when a is small
    x = 2.0 * room / (speed + math.sqrt(speed * speed + 4.0 * a * room))
    return math.pi * x / CONTACT_STEPS


def pair_lines(pairs: list[ContactPair], h: float) -> list[str]:
    """The MJCF <contact> element of the pairs: condim 3 (normal and two friction
    directions, no torsion or rolling), friction (μ, μ, 0, 0, 0), solref (-ω0², -2 ζ ω0),
    the friction's solref (-ω0², -2 FRICTION_ZETA ω0), SOLIMP."""
    if not pairs:
        return []
    fric = _nums(solref(FRICTION_ZETA, h))
    lines = ["  <contact>"]
    for p in pairs:
        lines.append(
            f'    <pair geom1="g{p.a}" geom2="g{p.b}" condim="3"'
            f' friction="{_num(p.friction)} {_num(p.friction)} 0 0 0"'
            f' solref="{_nums(solref(p.zeta, h))}" solreffriction="{fric}"'
            f' solimp="{_nums(SOLIMP)}"/>'
        )
    lines.append("  </contact>")
    return lines


def mjcf(
    model: Model,
    positions: np.ndarray,
    orientations: np.ndarray,
    timestep: float,
    name: str = "rbsim",
    names: list[str] | None = None,
    frame_points: np.ndarray | None = None,
    contacts: tuple[list[list[str]], list[str], list[str]] | None = None,
) -> str:
    """The MJCF text of a 3D rbsim Model: a body with a free joint per dynamic body, its
    frame at `positions` (N,3) m (world) with `orientations` (N,4) (w, x, y, z), with
    rbsim's mass (kg) and full inertia tensor (kg·m², body frame, about the COM) at the
    COM's position in that frame, body_com − frame_points (N,3) m (frame_points: where
    the frame sits in rbsim's body frame; default the body origins, zeros); gravity
    (m/s²) as the model has it (y-up world); `timestep` (s) MuJoCo's step; Euler
    integrator; MuJoCo body k+1 is the k-th dynamic body. `contacts`: None (contacts
    disabled), or (`geoms` per body, mesh assets, `pair_lines`): the geoms written in
    their bodies (a static body's in the world body), MuJoCo's elliptic (isotropic)
    friction cone."""
    if frame_points is None:
        frame_points = np.zeros_like(model.body_com)
    body_geoms, assets, pairs = contacts or ([[] for _ in model.body_type], [], [])
    lines = [
        f'<mujoco model="{name}">',
        '  <compiler angle="radian" inertiafromgeom="false"/>',
        f'  <option timestep="{_num(timestep)}" gravity="{_nums(model.gravity)}"'
        ' integrator="Euler"' + (' cone="elliptic">' if contacts else ">"),
    ]
    if not contacts:
        lines.append('    <flag contact="disable"/>')
    lines.append("  </option>")
    if assets:
        lines += ["  <asset>", *assets, "  </asset>"]
    lines.append("  <worldbody>")
    for i in np.flatnonzero(model.body_type == T.BODY_STATIC):
        lines += ["    " + g for g in body_geoms[i]]
    for i in np.flatnonzero(model.body_type == T.BODY_DYNAMIC):
        inertia = model.body_inertia[i]
        full = [inertia[0, 0], inertia[1, 1], inertia[2, 2]]
        full += [inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        label = names[i] if names else f"body{i}"
        label = label.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
        lines += [
            f'    <body name="{label}" pos="{_nums(positions[i])}"'
            f' quat="{_nums(orientations[i])}">',
            "      <freejoint/>",
            f'      <inertial pos="{_nums(model.body_com[i] - frame_points[i])}"'
            f' mass="{_num(model.body_mass[i])}" fullinertia="{_nums(full)}"/>',
            *("      " + g for g in body_geoms[i]),
            "    </body>",
        ]
    lines += ["  </worldbody>", *pairs, "</mujoco>", ""]
    return "\n".join(lines)


class MujocoEngine(Engine):
    """A 3D scene stepped by MuJoCo (see the module's docstring). `model`: rbsim's compiled
    Model of the scene (the masses and inertias written); `xml`: the MJCF written;
    `mj_model`, `mj_data`: MuJoCo's MjModel and MjData."""

    name = "mujoco"

    def __init__(self, scene: Scene, settings: MujocoSettings | None = None) -> None:
        if mujoco is None:
            raise EngineUnavailable(INSTALL_HINT)
        if int(getattr(scene.world, "dimension", 2)) != 3:
            raise UnsupportedScene(
                "MuJoCo is the reference engine of 3D scenes only (2D compares with pymunk)"
            )
        super().__init__(scene)
        self.model, state = build(scene)
        model = self.model
        settings = settings or MujocoSettings()
        if settings.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, not {settings.frame!r}")
        self.frame = settings.frame
        self.substeps = int(settings.substeps or scene.solver.substeps)
        self.h = self.dt / self.substeps
        self.pairs: list[ContactPair] = []
        if model.has_shapes:
            self.pairs = self._contact_pairs(scene, state)
        self.mass = model.body_mass.copy()
        self.inertia = model.body_inertia.copy()
        self.com_local = model.body_com.copy()
        self.dynamic = model.body_type == T.BODY_DYNAMIC
        self.kinematic = model.body_type == T.BODY_KINEMATIC
        self._dyn = np.flatnonzero(self.dynamic)
        rot0 = quat_matrix(state.body_q)
        self._origin0 = state.body_x - np.einsum("nij,nj->ni", rot0, model.body_com)
        self._q0 = state.body_q.copy()
        self._v0 = state.body_v.copy()
        self._w0 = state.body_w.copy()
        # the MuJoCo frame's point in rbsim's body frame, and the COM from it
        self._point = (
            model.body_com.copy() if self.frame == "com" else np.zeros_like(model.body_com)
        )
        self._arm_com = model.body_com - self._point
        contacts = None
        if model.has_shapes:
            body_geoms, assets = geoms(scene, model, state, self._point)
            contacts = (body_geoms, assets, pair_lines(self.pairs, self.h))
        self.xml = mjcf(
            model,
            self._origin0 + np.einsum("nij,nj->ni", rot0, self._point),
            self._q0,
            self.h,
            name=scene.name,
            names=[b.name for b in scene.bodies],
            frame_points=self._point,
            contacts=contacts,
        )
        self.mj_model = mujoco.MjModel.from_xml_string(self.xml)
        self.mj_data = mujoco.MjData(self.mj_model)
        d, dyn = self.mj_data, self._dyn
        qpos = d.qpos.reshape(-1, 7)
        qvel = d.qvel.reshape(-1, 6)
        r = np.einsum("nij,nj->ni", rot0[dyn], self._arm_com[dyn])
        qvel[:, :3] = self._v0[dyn] - np.cross(self._w0[dyn], r)
        qvel[:, 3:] = np.einsum("nji,nj->ni", rot0[dyn], self._w0[dyn])  # Rᵀ ω
        assert qpos.shape[0] == len(dyn)
        self._force = model.body_force[dyn]
        self._torque = model.body_torque[dyn]
        self._arm = model.body_force_arm[dyn]
        self._moving_arm = bool(model.has_forces and np.any(self._arm != 0.0))
        self._damped = bool(model.linear_damping or model.angular_damping)
        self._per_step = self._moving_arm or self._damped
        if model.has_forces and not self._per_step:
            d.xfrc_applied[1:, :3] = self._force
            d.xfrc_applied[1:, 3:] = self._torque
        self._setup_threshold(scene)
        self._steps = 0
        self.settings = {
            "substeps": self.substeps,
            "timestep": self.h,
            "integrator": "Euler",
            "contacts": self.contact_settings() if self.pairs else "disabled",
            "frame": self.frame,
            "mujoco_version": mujoco.__version__,
        }

    def _setup_threshold(self, scene: Scene) -> None:
        """rbsim's restitution threshold in MuJoCo, which has none: when a pair that
        bounces (ζ below ZETA_MAX) starts touching at a normal approach slower than
        solver.restitution_threshold, its solref is set to ZETA_MAX's (MuJoCo's most
        damped contact, as for e = 0) until it stops touching (`_gate`). The first step of
        a contact is taken with the pair's own solref: in it the spring has barely
        compressed, so the rebound is about MuJoCo's least."""
        m = self.mj_model
        self.threshold = float(scene.solver.restitution_threshold)
        bouncy = [p.zeta < ZETA_MAX for p in self.pairs]
        self._gated = self.threshold > 0.0 and any(bouncy)
        self._touching = np.zeros(len(self.pairs), bool)
        self._slow = np.zeros(len(self.pairs), bool)
        if not self._gated:
            return
        self._geom_pair = np.full((m.ngeom, m.ngeom), -1, np.int64)
        for k, p in enumerate(self.pairs):
            g1 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"g{p.a}")
            g2 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"g{p.b}")
            self._geom_pair[g1, g2] = self._geom_pair[g2, g1] = k
        self._bounce_solref = m.pair_solref.copy()
        self._still_solref = np.array(solref(ZETA_MAX, self.h))
        self._per_step = True

    def _gate(self, qvel: np.ndarray) -> None:
        """After a MuJoCo step taken from velocities `qvel` (d.contact and the bodies'
        frames are still those of the step's start): pairs that started touching get the
        damping of their approach speed (`_setup_threshold`), pairs that stopped get
        their own solref back."""
        m, d = self.mj_model, self.mj_data
        now = np.zeros(len(self.pairs), bool)
        ncon = int(d.ncon)
        if ncon:
            con = d.contact
            pair = self._geom_pair[con.geom[:ncon, 0], con.geom[:ncon, 1]]
            now[pair[pair >= 0]] = True
            new = now & ~self._touching
            if new.any():
                body = m.geom_bodyid[con.geom[:ncon]]  # (ncon, 2); 0 is the world
                rel = np.zeros((ncon, 3))
                for side, sign in ((0, -1.0), (1, 1.0)):
                    b = body[:, side]
                    moving = b > 0
                    dof = 6 * (b[moving] - 1)
                    v = qvel[dof[:, None] + np.arange(3)]
                    w = np.einsum(
                        "nij,nj->ni",
                        d.xmat[b[moving]].reshape(-1, 3, 3),
                        qvel[dof[:, None] + np.arange(3, 6)],
                    )
                    arm = con.pos[:ncon][moving] - d.xpos[b[moving]]
                    rel[moving] += sign * (v + np.cross(w, arm))
                # normal speed of geom 2 against geom 1, along frame's first row (1 -> 2)
                approach = -np.einsum("ni,ni->n", rel, con.frame[:ncon, :3])
                for k in np.flatnonzero(new):
                    fastest = float(approach[pair == k].max())
                    self._slow[k] = fastest < self.threshold
                    if self._slow[k]:
                        m.pair_solref[k] = self._still_solref
        for k in np.flatnonzero(self._touching & ~now & self._slow):
            m.pair_solref[k] = self._bounce_solref[k]
            self._slow[k] = False
        self._touching = now

    def _contact_pairs(self, scene: Scene, state: State) -> list[ContactPair]:
        """The scene's contact pairs (`contact_pairs`), or UnsupportedScene where MuJoCo
        cannot express them: a kinematic body that can touch (a mocap body's velocity is
        not seen by MuJoCo's contacts), more than MAX_PAIRS pairs, a restitution between
        0 and the least MuJoCo reaches, an impact estimated to tunnel at this step."""
        model = self.model
        for i in np.flatnonzero(model.body_type == T.BODY_KINEMATIC):
            if scene.bodies[i].shapes:
                raise UnsupportedScene(
                    f"body {scene.bodies[i].name!r} is kinematic with shapes: MuJoCo would "
                    "move it as a mocap body, whose velocity its contacts do not see "
                    "(no friction drag, no push)"
                )
        pairs = contact_pairs(scene, model, state, self.h)
        if len(pairs) > MAX_PAIRS:
            raise UnsupportedScene(
                f"{len(pairs)} shape pairs can touch; the bridge writes each as an MJCF "
                f"<pair> (for its mixed friction and restitution) and takes at most {MAX_PAIRS}"
            )
        floor = rebound(ZETA_MAX, self.h)
        for p in pairs:
            if 0.0 < p.restitution < floor:
                raise UnsupportedScene(
                    f"bodies {p.bodies[0]!r} and {p.bodies[1]!r}: restitution "
                    f"{p.restitution:g} is out of MuJoCo's reach: its contacts are soft with "
                    f"explicit damping, the least rebound is e = {floor:.3g} (damping ratio "
                    f"{ZETA_MAX:g}); e = 0 is given as that"
                )
        self._tunnel_check(pairs)
        return pairs

    def _tunnel_check(self, pairs: list[ContactPair]) -> None:
        """Raise UnsupportedScene when an impact is estimated to tunnel at this step,
        naming the pair that needs the shortest step and that step, which holds for
        every pair at once (`tunnel_free_step`), as solver.substeps at the scene's dt."""
        deep = [p for p in pairs if p.depth > TUNNEL_FRACTION * p.thickness]
        if not deep:
            return
        g = float(np.linalg.norm(self.model.gravity))
        fits = [tunnel_free_step(p.speed, p.thickness, g) for p in deep]
        p = deep[int(np.argmin(fits))]
        substeps = max(math.ceil(self.dt / min(fits)), self.substeps + 1)
        while any(self.dt / substeps > fit for fit in fits):  # round-off at the boundary
            substeps += 1
        others = len(deep) - 1
        also = f" ({others} other pair{'s' if others != 1 else ''} could too)" if others else ""
        raise UnsupportedScene(
            f"bodies {p.bodies[0]!r} and {p.bodies[1]!r} could tunnel in MuJoCo at its "
            f"step h = {self.h:.3g} s: at {p.speed:.3g} m/s, a bound on their approach "
            "speed from their initial speed and spin and what gravity and force could add "
            "over a fall or the whole run (not a predicted impact), the estimated depth in its "
            f"soft contact (lasting {CONTACT_STEPS} steps) is {p.depth:.3g} m, more than "
            f"{TUNNEL_FRACTION:g} of the thinner shape's half-thickness {p.thickness:.3g} m; "
            f"a step of h <= {self.dt / substeps:.3g} s holds for every pair{also}: "
            f"solver.substeps >= {substeps} at dt = {self.dt:.3g} s "
            f"(--set solver.substeps={substeps})"
        )

    def contact_settings(self) -> str:
        """MuJoCo's contact settings in words: the step, the contact law and, per distinct
        (friction, restitution), the damping ratio and the rebound it gives."""
        w0 = contact_frequency(self.h)
        kinds = sorted({(p.friction, p.restitution, p.zeta) for p in self.pairs})
        parts = []
        for mu, e, zeta in kinds[:6]:
            spread = rebounds(zeta, self.h)
            parts.append(
                f"μ {mu:.4g}, e {e:.4g} -> ζ {zeta:.4g} (MuJoCo's e {rebound(zeta, self.h):.4g},"
                f" {min(spread):.4g} to {max(spread):.4g} by where the impact falls in a step)"
            )
        if len(kinds) > 6:
            parts.append(f"... ({len(kinds)} kinds)")
        law = ", ".join(f"{x:g}" for x in SOLIMP)
        gate = (
            f"a pair that starts touching slower than {self.threshold:g} m/s "
            f"(solver.restitution_threshold) gets ζ {ZETA_MAX:g} until it parts"
            if self._gated
            else "no restitution threshold applied (nothing bounces, or the threshold is 0)"
        )
        return (
            f"{len(self.pairs)} pairs (MJCF <pair>, condim 3, elliptic cone, Newton solver), "
            f"h = {self.h:.4g} s, solref direct (-ω0², -2 ζ ω0) with ω0 = π / "
            f"({CONTACT_STEPS} h) = {w0:.4g} rad/s, the friction rows' ζ {FRICTION_ZETA:g}, "
            f"solimp ({law}); {'; '.join(parts)}; {gate}"
        )

    def _applied(self) -> None:
        """xfrc_applied for the next MuJoCo step: the scene's forces and torques, with a
        force's torque about the COM at the current orientation, and the damping force
        and torque that give rbsim's implicit damping law (module docstring)."""
        model, d, dyn = self.model, self.mj_data, self._dyn
        qpos = d.qpos.reshape(-1, 7)
        force = self._force.copy()
        torque = self._torque.copy()
        rot = quat_matrix(qpos[:, 3:])
        if self._moving_arm:
            torque += np.cross(np.einsum("nij,nj->ni", rot, self._arm), self._force)
        if self._damped:
            h = self.h
            m = model.body_mass[dyn][:, None]
            v, w = self._com_velocity(rot), self._world_omega(rot)
            c, ca = model.linear_damping, model.angular_damping
            if c:
                force -= m * c * (v + h * (model.gravity + force / m)) / (1.0 + h * c)
            if ca:
                ang = self._momentum(rot, w)
                torque -= ca * (ang + h * torque) / (1.0 + h * ca)
        d.xfrc_applied[1:, :3] = force
        d.xfrc_applied[1:, 3:] = torque

    def _world_omega(self, rot: np.ndarray) -> np.ndarray:
        """(n,3) world angular velocities of the dynamic bodies (rad/s)."""
        qvel = self.mj_data.qvel.reshape(-1, 6)
        return np.einsum("nij,nj->ni", rot, qvel[:, 3:])

    def _com_velocity(self, rot: np.ndarray) -> np.ndarray:
        """(n,3) COM velocities of the dynamic bodies (m/s): v_frame + ω × R (com − p)."""
        qvel = self.mj_data.qvel.reshape(-1, 6)
        r = np.einsum("nij,nj->ni", rot, self._arm_com[self._dyn])
        return qvel[:, :3] + np.cross(self._world_omega(rot), r)

    def _momentum(self, rot: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(n,3) world angular momenta about the COMs, R I_b Rᵀ ω (kg·m²/s)."""
        inertia = self.model.body_inertia[self._dyn]
        world = np.einsum("nij,njk,nlk->nil", rot, inertia, rot)
        return np.einsum("nij,nj->ni", world, w)

    def advance(self, n: int) -> None:
        t0 = time.perf_counter()
        m, d = self.mj_model, self.mj_data
        try:
            if n <= 0 or len(self._dyn) == 0:
                pass
            elif self._per_step:
                applied = self._moving_arm or self._damped
                for _ in range(n * self.substeps):
                    if applied:
                        self._applied()
                    if self._gated:
                        qvel = d.qvel.copy()
                        mujoco.mj_step(m, d)
                        self._gate(qvel)
                    else:
                        mujoco.mj_step(m, d)
            else:
                mujoco.mj_step(m, d, nstep=n * self.substeps)
        finally:
            self.step_time += time.perf_counter() - t0
        self._steps += max(n, 0)
        bad = ~np.isfinite(d.qpos.reshape(-1, 7)).all(axis=1)
        bad |= ~np.isfinite(d.qvel.reshape(-1, 6)).all(axis=1)
        if bad.any():
            raise NonFiniteState(int(self._dyn[np.argmax(bad)]), self._steps)
        # MuJoCo does not stop on a non-finite or huge (> 1e10) acceleration: it warns
        # and resets the state to the model's initial one, which would read as a valid
        # state. Its explicit Euler grows a fast spin's wobble exponentially (|ω| h near
        # 1), so this is reachable.
        warning = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        if warning.number > 0:
            dof = min(max(int(warning.lastinfo), 0), m.nv - 1)
            raise NonFiniteState(int(self._dyn[int(m.dof_bodyid[dof]) - 1]), self._steps)

    def read(self) -> Snapshot:
        n = len(self.scene.bodies)
        t = self.time
        origin = self._origin0.copy()
        q = self._q0.copy()
        v = np.zeros((n, 3))
        w = np.zeros((n, 3))
        kin = self.kinematic
        if kin.any():  # prescribed motion
            origin[kin] = self._origin0[kin] + t * self._v0[kin]
            q[kin] = quat_mul(quat_exp(t * self._w0[kin]), self._q0[kin])
            v[kin], w[kin] = self._v0[kin], self._w0[kin]
        dyn = self._dyn
        qpos = self.mj_data.qpos.reshape(-1, 7)
        if len(dyn):
            rot = quat_matrix(qpos[:, 3:])
            origin[dyn] = qpos[:, :3] - np.einsum("nij,nj->ni", rot, self._point[dyn])
            q[dyn] = qpos[:, 3:]
            v[dyn] = self._com_velocity(rot)
            w[dyn] = self._world_omega(rot)
        com = origin + np.einsum("nij,nj->ni", quat_matrix(q), self.com_local)
        return Snapshot(
            origin=origin,
            angle=None,
            orientation=q,
            com=com,
            velocity=v,
            angular_velocity=w,
        )

    def state(self) -> State:
        """The current state in rbsim's layout (State of rbsim.scene.compile): COM x, q,
        COM v, world ω and world L about each COM (0 for bodies that are not dynamic)."""
        s = self.read()
        ang = np.zeros_like(s.angular_velocity)
        if len(self._dyn):
            rot = quat_matrix(s.orientation[self._dyn])
            ang[self._dyn] = self._momentum(rot, s.angular_velocity[self._dyn])
        return State(
            body_x=s.com,
            body_q=s.orientation,
            body_angle=np.zeros(0),
            body_v=s.velocity,
            body_w=s.angular_velocity,
            body_l=ang,
        )

    def record(self, block: dict[str, np.ndarray], row: int) -> None:
        super().record(block, row)
        if "body_angular_momentum" in block:
            block["body_angular_momentum"][row] = self.state().body_l

    @property
    def step_index(self) -> int:
        return self._steps

    @property
    def contact_count(self) -> int:
        return int(self.mj_data.ncon)

    def observables(self) -> dict:
        return observables(self.model, self.state(), self.contact_count)

    def deepest_overlap(self, origin: np.ndarray, orientation: np.ndarray) -> float:
        """The largest overlap (m, 0 when none) of two shapes that can touch, with the
        bodies at body origins `origin` (N,3) m and orientations (N,4) (w, x, y, z), by
        MuJoCo's collision functions (its contact distances). A ruler: it overwrites
        MuJoCo's derived quantities (qpos is put back), so call it on an engine that is
        not being stepped."""
        if not self.pairs:
            return 0.0
        m, d, dyn = self.mj_model, self.mj_data, self._dyn
        saved = d.qpos.copy()
        qpos = d.qpos.reshape(-1, 7)
        rot = quat_matrix(orientation[dyn])
        qpos[:, :3] = origin[dyn] + np.einsum("nij,nj->ni", rot, self._point[dyn])
        qpos[:, 3:] = orientation[dyn]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        dist = d.contact.dist[: d.ncon]
        d.qpos[:] = saved
        return max(0.0, -float(dist.min())) if len(dist) else 0.0

    def checkpoint(self) -> bytes:
        d = self.mj_data
        head = np.array([self._steps, d.time], np.float64)
        flags = np.concatenate([self._touching, self._slow]).astype(np.float64)
        return np.concatenate([head, d.qpos, d.qvel, flags]).tobytes()

    def restore(self, data: bytes) -> None:
        values = np.frombuffer(data, np.float64)
        d = self.mj_data
        nq, nv, npair = len(d.qpos), len(d.qvel), len(self.pairs)
        if len(values) != 2 + nq + nv + 2 * npair:
            raise ValueError("the checkpoint is not of this scene's MuJoCo model")
        self._steps = int(values[0])
        d.time = float(values[1])
        d.qpos[:] = values[2 : 2 + nq]
        d.qvel[:] = values[2 + nq : 2 + nq + nv]
        flags = values[2 + nq + nv :].astype(bool)
        self._touching, self._slow = flags[:npair].copy(), flags[npair:].copy()
        if self._gated:
            slow = self._slow
            self.mj_model.pair_solref[:] = np.where(
                slow[:, None], self._still_solref, self._bounce_solref
            )
