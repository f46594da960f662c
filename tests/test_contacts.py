"""Contacts against the physics: the isolated-collision formula, conservation laws,
bouncing, stacking, tunneling, Coulomb friction, resting contact, determinism, and the
example scenes that show them.

Most tests step a `World` directly and read `state.body_v` / `state.body_w` after each
step (the same numbers the trajectory would hold, without the file); the bouncing ball
and the resting box go through `run_scene` and read the trajectory.
"""

from __future__ import annotations

import hashlib
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

import rbsim
from rbsim.constants import SEGMENT_SKIN
from rbsim.core import CoreWorld as World
from rbsim.scene import load_scene
from rbsim.scene.types import BODY_DYNAMIC
from rbsim.tools.measure import penetration, touching_pairs

from .conftest import scene_from, vector

G = 9.81
DT = 1 / 60
SCENES = Path(__file__).resolve().parent.parent / "scenes"


def make_world(text: str) -> World:
    return World.from_scene(scene_from(text))


def record(world: World, steps: int) -> dict[str, np.ndarray]:
    """Step `world` one step at a time; every body's state at every frame (step 0 too):
    x (T,N,2) centre of mass, q (T,N,2), v (T,N,2), w (T,N), contacts (T,) points."""
    frames: dict[str, list] = {"x": [], "q": [], "v": [], "w": [], "contacts": []}

    def keep() -> None:
        s = world.state
        frames["x"].append(s.body_x.copy())
        frames["q"].append(s.body_q.copy())
        frames["v"].append(s.body_v.copy())
        frames["w"].append(s.body_w.copy())
        frames["contacts"].append(world.contact_count)

    keep()
    for _ in range(steps):
        world.advance(1)
        keep()
    return {k: np.array(v) for k, v in frames.items()}


def cross(r: np.ndarray, n: np.ndarray) -> float:
    return float(r[0] * n[1] - r[1] * n[0])


def perp(r: np.ndarray) -> np.ndarray:
    """ω × r for a unit ω out of the plane."""
    return np.array([-r[1], r[0]])


def restitution_formula(m, inertia, v, w, x, p, n, e):
    """Velocities after one frictionless collision of bodies 0 (a) and 1 (b) at point p
    with normal n (from b towards a): γ = −(1 + e) m_eff v_n⁻, +γn on a, −γn on b."""
    ra, rb = p - x[0], p - x[1]
    vn = float(n @ (v[0] + w[0] * perp(ra) - v[1] - w[1] * perp(rb)))
    inv_meff = 1 / m[0] + 1 / m[1] + cross(ra, n) ** 2 / inertia[0] + cross(rb, n) ** 2 / inertia[1]
    gamma = -(1 + e) * vn / inv_meff
    v_after, w_after = v.copy(), w.copy()
    v_after[0] += gamma * n / m[0]
    v_after[1] -= gamma * n / m[1]
    w_after[0] += cross(ra, n) * gamma / inertia[0]
    w_after[1] -= cross(rb, n) * gamma / inertia[1]
    return v_after, w_after, vn


def circle_impact(xa, xb, va, vb, reach):
    """Time until two circles in straight-line motion touch (centres `reach` apart), and
    the normal (b towards a) at that moment."""
    d, u = xa - xb, va - vb
    qa, qb, qc = u @ u, 2 * d @ u, d @ d - reach * reach
    t = (-qb - math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    dc = d + u * t
    return t, dc / np.hypot(*dc)


# ---------------------------------------------------------------------------------------
# 1. One isolated collision: γ = −(1 + e) m_eff v_n⁻
# ---------------------------------------------------------------------------------------

# Each geometry starts its bodies so that they touch at t = (IMPACT_STEP + f) dt: f is
# the landing, the fraction of the step at which the impact falls. Zero gravity, no
# friction; a is listed first (normal from b towards a).
IMPACT_STEP = 10
LANDINGS = {
    # just after a frame: the surfaces are 1e-13 m apart at frame IMPACT_STEP
    "on_frame": 1e-12,
    "inside_substep": 0.37,  # inside the 2nd of the 4 substeps
    "in_last_substep": 0.9,
}
BOX_CORNER_ANGLE = 0.5  # rad: box a hits b's top face with one corner only


def collision_scene(geometry: str, e: float, landing: float) -> str:
    t = (IMPACT_STEP + landing) * DT
    if geometry == "circles_head_on":
        # a (r 0.5) moves at +3, b (r 0.3) at -1 along the line of centres
        xa = 1.0 - t - 0.8 - 3.0 * t
        bodies = [
            f"{{name: a, position: [{xa!r}, 0], velocity: [3, 0], density: 1,"
            " shape: {circle: {radius: 0.5}}}",
            "{name: b, position: [1, 0], velocity: [-1, 0], density: 2,"
            " shape: {circle: {radius: 0.3}}}",
        ]
    elif geometry == "circles_off_centre":
        # impact parameter 0.4 of a contact distance 0.8: the normal is 30° off the motion
        xa = 1.0 - t - math.sqrt(0.8**2 - 0.4**2) - 3.0 * t
        bodies = [
            f"{{name: a, position: [{xa!r}, 0.4], velocity: [3, 0], density: 1,"
            " shape: {circle: {radius: 0.5}}}",
            "{name: b, position: [1, 0], velocity: [-1, 0], density: 2,"
            " shape: {circle: {radius: 0.3}}}",
        ]
    elif geometry == "circle_box_off_centre":
        # the circle hits the box's left face 0.35 m above the box's centre
        xa = 0.1 - 0.6 - 0.25 - 5.0 * t
        bodies = [
            f"{{name: a, position: [{xa!r}, 0.35], velocity: [5, 0], density: 3,"
            " shape: {circle: {radius: 0.25}}}",
            "{name: b, position: [0.1, 0], density: 1, shape: {box: {size: [1.2, 1.0]}}}",
        ]
    else:  # box_corner_on_box_face
        # a (1 x 0.6, turned 0.5 rad) falls at 4 m/s onto b's top face, b rises at 1 m/s
        th = BOX_CORNER_ANGLE
        corner_depth = 0.5 * math.sin(th) + 0.3 * math.cos(th)
        ya = 0.5 + 1.0 * t + corner_depth + 4.0 * t
        bodies = [
            f"{{name: a, position: [0.3, {ya!r}], angle: {th}, velocity: [0, -4], density: 2,"
            " shape: {box: {size: [1.0, 0.6]}}}",
            "{name: b, position: [0, 0], velocity: [0, 1], density: 1,"
            " shape: {box: {size: [3, 1.0]}}}",
        ]
    lines = "\n".join(f"  - {b[:-1]}, friction: 0, restitution: {e}}}" for b in bodies)
    return f"version: 1\nworld: {{gravity: [0, 0], dt: {DT!r}, steps: 30}}\nbodies:\n{lines}\n"


def contact_geometry(geometry: str, x: np.ndarray, q: np.ndarray, v: np.ndarray):
    """Contact point, normal (b towards a) and centres of mass at the impact, from the
    state at the last frame before it: the bodies move in straight lines until they
    touch (moving along the normal does not change r × n, so the boxes keep x)."""
    if geometry.startswith("circles"):
        # lever arms are taken at the impact, where the centres have moved by v t
        t, n = circle_impact(x[0], x[1], v[0], v[1], 0.8)
        return x[1] + v[1] * t + 0.3 * n, n, x + v * t
    if geometry == "circle_box_off_centre":
        # the circle moves along the normal: the point is where its centre line meets
        # the face, whenever the impact falls
        return np.array([0.1 - 0.6, x[0, 1]]), np.array([-1.0, 0.0]), x
    # the box falls along the normal without turning: its lowest corner, whenever it lands
    c, s = q[0]
    local = np.array([[sx * 0.5, sy * 0.3] for sx in (-1, 1) for sy in (-1, 1)])
    corners = x[0] + local @ np.array([[c, s], [-s, c]])
    return corners[np.argmin(corners[:, 1])], np.array([0.0, 1.0]), x


GEOMETRIES = (
    "circles_head_on",
    "circles_off_centre",
    "circle_box_off_centre",
    "box_corner_on_box_face",
)


def _collision_cases():
    # on_frame for the oblique circles was 3e-7 off: the impact was taken in the step
    # before, whose speculative manifold had stopped its time-of-impact search short
    for geometry in GEOMETRIES:
        for landing in LANDINGS:
            yield pytest.param(geometry, landing, id=f"{geometry}-{landing}")


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("geometry, landing", list(_collision_cases()))
def test_isolated_collision_matches_restitution_formula(geometry, landing, e):
    world = make_world(collision_scene(geometry, e, LANDINGS[landing]))
    m, inertia = world.model.body_mass, world.model.body_inertia
    tr = record(world, IMPACT_STEP + 1)
    # the collision step: the first whose velocities differ from the initial ones
    changed = np.any(tr["v"] != tr["v"][0], axis=(1, 2)) | np.any(tr["w"] != tr["w"][0], axis=1)
    assert changed.any()
    after = int(np.argmax(changed))
    before = after - 1
    x, q, v, w = tr["x"][before], tr["q"][before], tr["v"][before], tr["w"][before]
    p, n, x_impact = contact_geometry(geometry, x, q, v)
    v_exp, w_exp, vn = restitution_formula(m, inertia, v, w, x_impact, p, n, e)
    assert vn < -3.0  # a real impact, far above the 1 m/s restitution threshold
    assert tr["contacts"][after] == 1  # at one point
    # One contact point: the formula is exact, and a solver that applies every impulse of
    # the step along the contact's Jacobian reproduces it to rounding (1e-15); 1e-9 also
    # covers the 1e-13 m gap that the "on_frame" landing leaves at the frame before.
    scale = np.abs(v_exp).max()
    np.testing.assert_allclose(tr["v"][after], v_exp, rtol=1e-9, atol=1e-9 * scale)
    if geometry.startswith("circles"):
        # r × n = 0 for circles: no spin (rounding of the contact point only)
        assert np.abs(tr["w"][after]).max() < 1e-12
    else:
        assert abs(w_exp[1]) > 1e-3  # the struck box really spins
        w_scale = np.abs(w_exp).max()
        np.testing.assert_allclose(tr["w"][after], w_exp, rtol=1e-9, atol=1e-9 * w_scale)


THRESHOLD_SCENE = """
version: 1
world: {{gravity: [0, 0], dt: {dt!r}, steps: 30}}
solver: {{restitution_threshold: {threshold}}}
bodies:
  - {{name: a, position: [{xa!r}, 0], velocity: [{va!r}, 0], density: 1, friction: 0,
     restitution: 1, shape: {{circle: {{radius: 0.5}}}}}}
  - {{name: b, position: [1, 0], density: 2, friction: 0, restitution: 1,
     shape: {{circle: {{radius: 0.3}}}}}}
"""


@pytest.mark.parametrize("threshold", [1.0, 2.0])
@pytest.mark.parametrize("fraction, bounces", [(0.8, False), (1.2, True)])
def test_restitution_threshold_stops_slow_approaches_from_bouncing(threshold, fraction, bounces):
    # a head-on collision with e = 1 at 0.8 or 1.2 times the threshold: only the faster one
    # bounces; the slower one ends with v_n⁺ = 0 (both move on with the centre of mass)
    va = fraction * threshold
    t = (IMPACT_STEP + 0.37) * DT
    xa = 1.0 - 0.8 - va * t
    text = THRESHOLD_SCENE.format(dt=DT, threshold=threshold, xa=xa, va=va)
    world = make_world(text)
    m = world.model.body_mass
    tr = record(world, 30)
    vx = tr["v"][:, :, 0]
    vn = -(vx[:, 0] - vx[:, 1])  # the normal (b towards a) is -x
    assert vn[0] == -va
    e = 1.0 if bounces else 0.0  # below the threshold, e is ignored
    # 1e-12 m/s: one contact along the line of centres, the formula to rounding
    np.testing.assert_allclose(vn[IMPACT_STEP + 2 :], e * va, atol=1e-12)
    p = m[0] * vx[:, 0] + m[1] * vx[:, 1]
    np.testing.assert_allclose(p, m[0] * va, rtol=1e-12)  # momentum, to rounding


# ---------------------------------------------------------------------------------------
# 2. Conservation: an elastic, frictionless gas of circles in open space
# ---------------------------------------------------------------------------------------


def gas_scene(n: int = 50, seed: int = 20240601) -> str:
    rng = np.random.default_rng(seed)
    placed: list[tuple[float, float, float]] = []
    while len(placed) < n:
        x, y = rng.uniform(-3.5, 3.5, 2)
        r = rng.uniform(0.2, 0.4)
        if all(math.hypot(x - px, y - py) > r + pr + 0.02 for px, py, pr in placed):
            placed.append((float(x), float(y), float(r)))
    # random velocities plus a drift, so the total momentum is far from zero
    vel = rng.normal(0.0, 3.0, (n, 2)) + [1.0, -0.5]
    lines = [
        f"  - {{name: c{i}, position: [{x!r}, {y!r}], velocity: [{vx!r}, {vy!r}],"
        f" material: elastic, shape: {{circle: {{radius: {r!r}}}}}}}"
        for i, ((x, y, r), (vx, vy)) in enumerate(zip(placed, vel.tolist(), strict=True))
    ]
    return (
        "version: 1\n"
        f"world: {{gravity: [0, 0], dt: {DT!r}, duration: 10}}\n"
        # every approach bounces: the default 1 m/s threshold would make grazing
        # impacts inelastic by design
        "solver: {restitution_threshold: 0.0}\n"
        "materials: {elastic: {density: 1.0, friction: 0.0, restitution: 1.0}}\n"
        "bodies:\n" + "\n".join(lines) + "\n"
    )


def test_elastic_gas_conserves_momentum_and_kinetic_energy():
    world = make_world(gas_scene())
    m = world.model.body_mass
    tr = record(world, world.scene.world.steps)
    momentum = np.einsum("n,tnk->tk", m, tr["v"])
    kinetic = 0.5 * np.einsum("n,tnk->t", m, tr["v"] ** 2)
    kinetic += 0.5 * np.einsum("n,tn->t", world.model.body_inertia, tr["w"] ** 2)
    # the gas really collides: most circles change velocity at least once
    collided = np.any(tr["v"] != tr["v"][0], axis=(0, 2))
    assert collided.sum() >= 25
    # momentum: every impulse acts in equal and opposite pairs; 1e-9 relative allows the
    # rounding of ~10⁴ impulse applications
    p0 = np.hypot(*momentum[0])
    assert np.abs(momentum - momentum[0]).max() <= 1e-9 * p0
    # e = 1: every pair's impact restores −v_n exactly, also when several fall within
    # one substep (the restitution stage redoes them one pair at a time); 1e-12 allows
    # the rounding of some 10⁴ impacts (the issue asks for 1%)
    np.testing.assert_allclose(kinetic, kinetic[0], rtol=1e-12)


ELASTIC = """
version: 1
world: {{gravity: [0, {g}], dt: {dt!r}, duration: {duration}}}
solver: {{restitution_threshold: 0.0}}
materials: {{elastic: {{density: 1.0, friction: 0.0, restitution: 1.0}}}}
bodies:
{bodies}
"""


QUAD = "{polygon: {vertices: [[-0.3, -0.2], [0.3, -0.25], [0.35, 0.2], [-0.1, 0.3]]}}"


def elastic_world(bodies: list[str], g: float = 0.0, duration: float = 1.0) -> World:
    """e = 1, no friction, every approach bounces; `bodies` are YAML flow mappings."""
    listed = "\n".join(f"  - {{{b}, material: elastic}}" for b in bodies)
    return make_world(ELASTIC.format(g=g, dt=DT, duration=duration, bodies=listed))


def modified_energy(world: World) -> float:
    """The integrator's invariant in free flight (J): kinetic and potential energy plus
    (h/2) Σ m g·v, which symplectic Euler with substep h keeps exactly under gravity."""
    m, s = world.model, world.state
    d = m.body_type == BODY_DYNAMIC
    h = world.config.dt / world.config.substeps
    mass, v = m.body_mass[d], s.body_v[d]
    energy = (
        0.5 * (mass * (v**2).sum(axis=1)).sum() + 0.5 * (m.body_inertia[d] * s.body_w[d] ** 2).sum()
    )
    return float(
        energy - (mass * (s.body_x[d] @ m.gravity)).sum() + 0.5 * h * (mass * (v @ m.gravity)).sum()
    )


def test_ball_struck_by_two_balls_within_one_substep_keeps_kinetic_energy():
    # the two strikers reach the middle ball 1 ms apart (a substep is 4.2 ms): the
    # solve sees one impact of three bodies, which with targets from each point's own
    # approach lost 2.7% of the kinetic energy
    world = elastic_world(
        [
            "name: middle, position: [0, 0], shape: {circle: {radius: 0.5}}",
            "name: left, position: [-1.6, 0.3], velocity: [3, 0], shape: {circle: {radius: 0.5}}",
            "name: top, position: [0.2, 1.9592], velocity: [0, -5], shape: {circle: {radius: 0.4}}",
        ]
    )
    tr = record(world, 60)
    m = world.model.body_mass
    kinetic = 0.5 * np.einsum("n,tnk->t", m, tr["v"] ** 2)
    momentum = np.einsum("n,tnk->tk", m, tr["v"])
    assert np.hypot(*tr["v"][-1, 0]) > 1.0  # the middle ball was struck
    # exact up to rounding: each pair's bounce keeps its energy
    np.testing.assert_allclose(kinetic, kinetic[0], rtol=1e-12)
    np.testing.assert_allclose(momentum, momentum[:1].repeat(61, axis=0), atol=1e-12)


@pytest.mark.parametrize("shape", ["{box: {size: [0.6, 0.4]}}", QUAD])
def test_spinning_polygons_in_a_closed_box_lose_kinetic_energy_only_to_overlaps(shape):
    # 20 boxes or quadrilaterals, spinning, e = 1, no gravity, in a closed 10 m box for
    # 20 s: corner hits, face hits at two points, several at once. Every impact is a
    # pair's bounce against the velocity it meets (a face's two points as one block),
    # which keeps the kinetic energy exactly. (Targets taken from velocities that an
    # earlier impulse had changed gained energy here, up to 6000-fold; the solve's
    # joint impact lost half of it.) What can still lose energy is an overlap: a corner
    # of a spinning body that no speculative point saw can pass into another within a
    # step (the quadrilaterals of this scene do, 1.5 cm, in some roundings of the run),
    # and the soft push-out is not elastic. So every step that changes the energy must
    # start or end with an overlap deeper than the collision tolerance, and such steps
    # must be rare.
    rng = np.random.default_rng(5)
    walls = [
        f"name: {n}, type: static, position: [{x}, {y}], shape: {{box: {{size: [{w}, {h}]}}}}"
        for n, x, y, w, h in [
            ("floor", 0, -0.5, 12, 1),
            ("roof", 0, 10.5, 12, 1),
            ("left", -5.5, 5, 1, 12),
            ("right", 5.5, 5, 1, 12),
        ]
    ]
    bodies = [
        f"name: p{i}, position: [{-4 + 2 * (i % 5)}, {2 + 2 * (i // 5)}], "
        f"angle: {rng.uniform(0, 3)!r}, angular_velocity: {rng.normal(0, 2)!r}, "
        f"velocity: [{rng.normal(0, 3)!r}, {rng.normal(0, 3)!r}], shape: {shape}"
        for i in range(20)
    ]
    world = elastic_world(walls + bodies, duration=20.0)
    model = world.model
    e0 = previous = modified_energy(world)

    def overlap() -> float:
        st = world.state
        pairs = touching_pairs(model, st.body_x, st.body_angle, 0.0)
        return penetration(model, pairs, st.body_x, st.body_angle)

    struck = lossy = 0
    steps = world.scene.world.steps
    for _ in range(steps):
        w_before = world.state.body_w.copy()
        before = overlap()
        world.advance(1)
        struck += int((world.state.body_w != w_before).sum())
        energy = modified_energy(world)
        # 1e-13 of the energy: the rounding of one step's impacts
        if abs(energy - previous) > 1e-13 * e0:
            lossy += 1
            assert max(before, overlap()) > LINEAR_SLOP, (world.step_index, energy - previous)
        previous = energy
    assert struck > 100  # the bodies really collide (and turn)
    assert lossy <= steps // 100  # overlaps are rare (1 in 1200 steps, or none)


@pytest.mark.parametrize("angle, spin", [(0.0, 0.0), (0.3, 0.0), (0.7, -2.0)])
def test_elastic_box_bouncing_on_the_ground_keeps_its_energy(angle, spin):
    # a box landing flat (two points at once), on a corner, and spinning, e = 1, for
    # 20 s. The bounce returns the integrator's invariant exactly also for a turning
    # body: the work gravity did on the centre over the impact's push is counted per
    # body, not as if the point were the centre (that left 0.2% after 20 bounces)
    world = elastic_world(
        [
            "name: ground, type: static, shape: {segment: {a: [-50, 0], b: [50, 0]}}",
            f"name: box, position: [0, 3], angle: {angle}, angular_velocity: {spin}, "
            "shape: {box: {size: [0.6, 0.4]}}",
        ],
        g=-G,
        duration=20.0,
    )
    e0 = modified_energy(world)
    lowest = math.inf
    for _ in range(world.scene.world.steps):
        world.advance(1)
        lowest = min(lowest, float(world.state.body_v[1, 1]))
        assert modified_energy(world) == pytest.approx(e0, rel=1e-12)  # rounding
    assert lowest < -5.0  # it fell and bounced (from 3 m: 7.7 m/s)


@pytest.mark.parametrize("drop", [3.16, 3.19, 3.22])
def test_ball_struck_down_onto_the_floor_keeps_its_energy(drop):
    # a falling ball is hit from above by a fast one while it lands (the strikers'
    # heights are where the two impacts fall within one substep): it must bounce off
    # the floor, not be stopped dead by the shock pass or lose energy to the shared
    # impact (this lost 11-53%)
    world = elastic_world(
        [
            "name: ground, type: static, shape: {segment: {a: [-10, 0], b: [10, 0]}}",
            "name: low, position: [0, 0.6], shape: {circle: {radius: 0.25}}",
            f"name: high, position: [0.1, {drop}], velocity: [0, -8], "
            "shape: {circle: {radius: 0.25}}",
        ],
        g=-G,
    )
    e0 = modified_energy(world)
    balls = np.flatnonzero(world.model.body_type == BODY_DYNAMIC)
    rising = np.zeros(2)
    for _ in range(60):
        world.advance(1)
        rising = np.maximum(rising, world.state.body_v[balls, 1])
        # symplectic Euler keeps the invariant in flight; e = 1 bounces keep it too
        assert modified_energy(world) == pytest.approx(e0, rel=1e-12)
    assert rising.min() > 1.0  # both bounced: the two really met


def test_row_of_touching_balls_passes_the_whole_velocity_to_the_last():
    # Newton's cradle: four touching balls struck at one end. The restitution stage
    # resolves the row one pair at a time, so the velocity passes through to the last
    # ball (treated as one impact of five bodies it went 0.36 m/s to the last ball)
    row = [f"name: b{i}, position: [{i}, 0], shape: {{circle: {{radius: 0.5}}}}" for i in range(4)]
    world = elastic_world(
        ["name: striker, position: [-1.5, 0], velocity: [1, 0], shape: {circle: {radius: 0.5}}"]
        + row,
        duration=2.0,
    )
    world.advance(world.scene.world.steps)
    speeds = np.hypot(*world.state.body_v.T)
    np.testing.assert_allclose(speeds, [0, 0, 0, 0, 1], atol=1e-9)  # rounding


# ---------------------------------------------------------------------------------------
# 3. A ball bouncing on the ground
# ---------------------------------------------------------------------------------------

BALL_DROP = """
version: 1
world: {{dt: {dt!r}, duration: {duration}}}
solver: {{restitution_threshold: 1.0}}
bodies:
  - {{name: ground, type: static, restitution: {e},
     shape: {{segment: {{a: [-10, 0], b: [10, 0]}}}}}}
  - {{name: ball, position: [0, {y0!r}], restitution: {e},
     shape: {{circle: {{radius: {r}}}}}}}
"""
RADIUS = 0.25


def drop_ball(run_text, e: float, height: float, duration: float):
    """Height of the ball above its rest height (ground + radius) and its velocity at
    every step."""
    text = BALL_DROP.format(dt=DT, duration=duration, e=e, y0=RADIUS + height, r=RADIUS)
    tr = run_text(text)
    ball = tr.body("ball")
    return tr.position[:, ball, 1] - RADIUS, tr.velocity[:, ball]


def apexes(y: np.ndarray, vy: np.ndarray) -> np.ndarray:
    """Heights where the ball turns from rising to falling (the higher of the two
    frames around the turn: off the true apex by at most g dt²/8 = 0.03 mm). Turns
    below 1 mm are the ball settling into the soft contact at rest, not bounces (the
    smallest bounce, at the 1 m/s threshold with e = 0.5, rises 1.3 cm)."""
    turn = np.nonzero((vy[:-1] > 0) & (vy[1:] <= 0))[0]
    tops = np.maximum(y[turn], y[turn + 1])
    return tops[tops > 1e-3]


def test_elastic_ball_keeps_its_apex_for_ten_bounces(run_text):
    height = 2.0
    y, v = drop_ball(run_text, e=1.0, height=height, duration=14.0)
    tops = apexes(y, v[:, 1])
    assert len(tops) >= 10
    # e = 1 on both: the restitution stage keeps the discrete trajectory's energy, so the
    # apex is lost only to frame sampling; 2% as asked of any e = 1 scheme
    np.testing.assert_allclose(tops[:10], height, rtol=0.02)


def test_half_restitution_ball_apex_ratio_is_e_squared(run_text):
    height = 4.0
    y, v = drop_ball(run_text, e=0.5, height=height, duration=6.0)
    tops = np.concatenate([[height], apexes(y, v[:, 1])])
    ratios = tops[1:] / tops[:-1]
    # impact speeds 8.9, 4.4, 2.2, 1.1 m/s bounce (threshold 1 m/s); the next, 0.55 m/s,
    # does not: four bounces, each rising e² = 0.25 of the fall
    assert len(ratios) == 4, tops
    # ±0.02 as asked: sampling is 0.03 mm of the 1.5 cm last apex
    np.testing.assert_allclose(ratios, 0.25, atol=0.02)


def test_ball_slower_than_threshold_comes_to_rest_on_the_ground(run_text):
    # dropped from 3 cm: impact at 0.77 m/s, below the 1 m/s threshold, so e = 1 is ignored
    height = 0.03
    assert math.sqrt(2 * G * height) < 1.0
    y, v = drop_ball(run_text, e=1.0, height=height, duration=2.0)
    landed = np.argmax(y < 1e-3)
    assert landed > 0
    # no bounce: an e = 1 bounce would rise 3 cm; 0.1 mm allows the soft contact's settling
    assert y[landed:].max() < 1e-4
    # no penetration beyond the linear slop (0.005 m)
    assert y.min() > -0.005
    # at rest: 1e-6 m/s is far below one step of gravity (0.16 m/s)
    assert np.hypot(*v[-1]) < 1e-6


# ---------------------------------------------------------------------------------------
# 4. A pyramid of boxes stands
# ---------------------------------------------------------------------------------------


def test_pyramid_of_base_20_stands_for_ten_seconds():
    world = make_world(
        f"""
        version: 1
        world: {{dt: {DT!r}, duration: 10}}
        bodies:
          - {{name: ground, type: static, friction: 0.6,
             shape: {{segment: {{a: [-30, 0], b: [30, 0]}}}}}}
          - pyramid: {{base: 20, size: [1, 1], origin: [0, 0.5], friction: 0.6}}
        """
    )
    boxes = world.model.body_type == BODY_DYNAMIC
    assert boxes.sum() == 210
    x0 = world.state.body_x.copy()
    world.advance(world.scene.world.steps)
    moved = np.hypot(*(world.state.body_x - x0)[boxes].T)
    # a standing pyramid only settles into its soft contacts: 5 cm as asked
    assert moved.max() < 0.05
    # near zero kinetic energy: mean speed below 1 cm/s, and no box turning at 0.01 rad/s
    speed = np.hypot(*world.state.body_v[boxes].T)
    assert speed.mean() < 0.01
    assert np.abs(world.state.body_w[boxes]).max() < 0.01


def column_scene(columns: list[float], sink: float) -> str:
    """Columns of 10 touching unit circles on the ground at the given x (m); the
    bottom circle of the first column starts `sink` (m) into the ground."""
    bodies = []
    for c, x in enumerate(columns):
        for i in range(10):
            y = 0.5 + i - (sink if c == 0 else 0.0)
            bodies.append(
                f"- {{name: c{c}b{i}, position: [{x}, {y}], shape: {{circle: {{radius: 0.5}}}}}}"
            )
    return f"""
version: 1
world: {{dt: {DT!r}, duration: 3}}
bodies:
  - {{name: ground, type: static, shape: {{segment: {{a: [-50, 0], b: [50, 0]}}}}}}
""" + "".join(f"  {b}\n" for b in bodies)


def test_deep_overlap_under_a_column_is_pushed_out_gently():
    # the ball pushed 0.2 m into the ground lifts the nine above it; the extra relax
    # passes around a deep overlap take the push's velocity back up the column (with
    # one relax pass per substep the column reaches 1.38 m/s, with the extra ones 0.79;
    # 0.93 since the contacts around a deep overlap still closing after the solve pass
    # are solved once more, deep_solve)
    world = make_world(column_scene([0.0], sink=0.2))
    peak = 0.0
    for _ in range(world.scene.world.steps):
        world.advance(1)
        peak = max(peak, float(np.hypot(*world.state.body_v[1:].T).max()))
    assert peak < 1.0
    assert world.state.body_x[1, 1] == pytest.approx(0.5, abs=0.01)  # pushed out


def test_box_pile_keeps_its_overlaps_shallow():
    # 600 boxes raining into a box and piling up 25 high (the bench's from-rest pile,
    # bench/scenes/boxpile600.yaml). The solve pass goes ground first, and a deep
    # contact's push-out drove the boxes below it into their supporters after their own
    # contacts were solved: the overlaps walked down the columns and were held there.
    # Now the contacts around a deep overlap still closing after the pass are solved once
    # more (deep_solve), and a static contact is no stiffer than the substep allows. The
    # pile is chaotic, so the figure is the mean of the deepest overlap at five moments:
    # over six runs with gravity changed by parts in 10⁹ (bench.the_round) 2.9 - 5.0 cm
    # (before: 6.9 - 8.9; pymunk, 10 iterations, in the first: 1.2). Boxes wedged between
    # others held most of that: now an overlap between two dynamic bodies deeper than
    # DYNAMIC_OVERLAP_LIMIT at a step's end is taken off their positions: 1.0 - 2.0 cm
    # (the deepest left are the floor's and walls', held to STATIC_OVERLAP_LIMIT)
    from rbsim.engines import make_engine
    from rbsim.tools.hard import Geometry

    scene = load_scene(SCENES.parent / "bench/scenes/boxpile600.yaml")
    engine = make_engine("rbsim", scene)
    geometry = Geometry(scene)
    engine.advance(360)
    deepest = []
    for _ in range(5):  # after 420, 480, 540, 600 and 660 steps
        engine.advance(60)
        deepest.append(geometry.max_overlap(engine.read()))
    assert np.mean(deepest) < 0.03  # m: 2.9 - 5.0 before the limit, 1.0 - 2.0 with it


def test_an_overlap_between_dynamic_bodies_is_taken_to_the_limit_without_speed():
    # Two 1 m boxes placed 10 cm into each other on the ground. The soft contacts push an
    # overlap out a quarter at a time (7.5 cm after the first step, 3.1 after the fourth);
    # beyond DYNAMIC_OVERLAP_LIMIT the positions are moved instead, each box by its share
    # of the inverse mass, and no speed is added
    from rbsim.constants import DYNAMIC_OVERLAP_LIMIT
    from rbsim.engines import make_engine
    from rbsim.tools.hard import Geometry

    scene = scene_from("""
        version: 1
        name: overlap
        world: {dt: 1/60, steps: 1}
        bodies:
          - {name: ground, type: static, shape: {segment: {a: [-5, 0], b: [5, 0]}}}
          - {name: a, position: [-0.45, 0.5], shape: {box: {size: [1, 1]}}}
          - {name: b, position: [0.45, 0.5], density: 3, shape: {box: {size: [1, 1]}}}
    """)
    engine = make_engine("rbsim", scene)
    engine.advance(1)
    s = engine.read()
    assert Geometry(scene).max_overlap(s) <= DYNAMIC_OVERLAP_LIMIT + 1e-9  # m: at the limit
    assert np.abs(s.velocity[1:]).max() < 5e-3  # m/s: the soft push's own (2.2 mm/s), no more
    # the lighter box moved three times as far (7.5 of the 9 cm taken off, against 2.5)
    moved = np.abs(s.com[1:, 0] - [-0.45, 0.45])
    assert moved[0] == pytest.approx(3 * moved[1], rel=0.05)  # (the soft push shares it too)


@pytest.mark.parametrize("speed", [12, 20])
def test_a_heavy_ball_does_not_squeeze_a_row_of_light_boxes_together(speed):
    # make compare's pyramid_collapse: a 2.83 kg ball at 12 m/s into a pyramid of 0.25 kg
    # boxes drives the bottom row's boxes into each other. One biased pass over the
    # contacts around the deep overlap let two of them overlap by 8.2 cm; now, while a deep
    # overlap still closes at impact speed (DEEP_CLOSING_SPEED), the contacts around it
    # are solved again without the bias first: 3.8 cm (pymunk, 10 iterations: 5.4). At
    # 20 m/s the ball rests on a box as it flies over and squeezes the second row: the
    # deep solve ran only where no heavy body rested on a light one (10.1 cm); now it
    # follows the shock pass there too: 3.5 cm
    from rbsim.engines import make_engine
    from rbsim.tools.hard import Geometry

    path = SCENES / "compare/statistics/pyramid_collapse.yaml"
    scene = load_scene(path, [f"bodies.ball.velocity=[{speed}, 0]"])
    engine = make_engine("rbsim", scene)
    geometry = Geometry(scene)
    deepest = 0.0
    for _ in range(60):  # the ball strikes by step 21; the squeeze is over by step 30
        engine.advance(1)
        deepest = max(deepest, geometry.max_overlap(engine.read()))
    assert deepest < 0.055  # m: the scene's own penetration tolerance (its header says why)


FLYBY_2D = """
    version: 1
    name: flyby
    world: {dt: 1/60, steps: 1, gravity: [0, 0]}
    bodies:
      - {name: post, type: static, position: [5, 0], shape: {box: {size: [0.02, 4]}}}
      - {name: pellet, position: [0, 5], velocity: [600, 0], shape: {circle: {radius: 0.005}}}
"""
FLYBY_3D = """
    version: 1
    name: flyby
    world: {dimension: 3, dt: 1/60, steps: 1, gravity: [0, 0, 0]}
    bodies:
      - {name: post, type: static, position: [5, 0, 0], shape: {box: {size: [0.02, 4, 0.5]}}}
      - {name: pellet, position: [0, 5, 0], velocity: [600, 0, 0], shape: {sphere: {radius: 0.005}}}
"""


@pytest.mark.parametrize("text", [FLYBY_2D, FLYBY_3D], ids=["2d", "3d"])
@pytest.mark.parametrize("speed", [100, 600])
def test_a_fast_body_flying_past_a_corner_is_not_touched(text, speed):
    # A pellet passes 3 m above a post's top corner. The search for the time of impact
    # ran (along the normal of the step's start, corner to pellet, the pair closes within
    # the step) and found them passing clear; the pair kept that manifold, a plane the
    # free path crosses within the step, and at 600 m/s the solver stopped the pellet
    # there: thrown off at (106, 177) m/s and spinning at 41,000 rad/s (2D). A pair whose
    # free paths pass clear now has no manifold in the step
    from rbsim.engines import make_engine

    velocity = f"[{speed}, 0]" if text is FLYBY_2D else f"[{speed}, 0, 0]"
    engine = make_engine("rbsim", scene_from(text, (f"bodies.pellet.velocity={velocity}",)))
    engine.advance(1)
    v = np.asarray(engine.world.engine.body_v)[-1]
    w = np.asarray(engine.world.engine.body_w)[-1]
    assert v[0] == speed and not np.any(v[1:]) and not np.any(w)  # exactly: no impulse at all


def test_a_fast_pellet_past_a_box_still_stops_at_the_wall_behind_it():
    # A new user's scene: a 3000 m/s pellet flies 3 m over a box at its thin wall behind
    # it. The box's manifold of the step's start (the pair passes clear) threw the pellet
    # up the wall at 893 m/s; with none it stops at the wall as it does alone
    from rbsim.engines import make_engine

    wall = "  - {name: wall, type: static, shape: {segment: {a: [10, 3], b: [10, 7]}}}\n"
    text = textwrap.dedent(FLYBY_2D) + wall
    engine = make_engine("rbsim", scene_from(text, ("bodies.pellet.velocity=[3000, 0]",)))
    engine.advance(2)
    x = np.asarray(engine.world.engine.body_x)[1]  # (the pellet: post, pellet, wall)
    v = np.asarray(engine.world.engine.body_v)[1]
    assert abs(v[0]) < 1e-9 and abs(v[1]) < 1e-9  # m/s: stopped (e = 0), not deflected
    assert 9.99 < x[0] < 10.0  # m: at the wall's face, short of it by its radius


def pieces_floor(body: str, pieces: int = 40, length: float = 0.5, mu: float = 0.0) -> str:
    """A floor of `pieces` static segments laid end to end along y = 0 (each its own
    body), and `body` (a YAML flow mapping) on it, moving right at 4 m/s."""
    floor = "".join(
        f"  - {{name: f{i}, type: static, friction: {mu}, shape: {{segment: "
        f"{{a: [{i * length}, 0], b: [{(i + 1) * length}, 0]}}}}}}\n"
        for i in range(pieces)
    )
    return f"version: 1\nworld: {{dt: 1/60, steps: 240}}\nbodies:\n{floor}  - {body}\n"


@pytest.mark.parametrize(
    "body",
    [
        "{name: b, position: [0.5, 0.2], velocity: [4, 0], friction: 0,"
        " shape: {circle: {radius: 0.2}}}",
        "{name: b, position: [0.5, 0.1], velocity: [4, 0], friction: 0,"
        " shape: {box: {size: [0.4, 0.2]}}}",
        "{name: b, position: [0.5, 0.2], velocity: [4, 0], angular_velocity: -20, friction: 0.6,"
        " shape: {circle: {radius: 0.2}}}",
    ],
    ids=["ball", "box", "rolling-ball"],
)
def test_a_body_crossing_the_joints_of_a_floor_of_pieces_keeps_its_speed(body):
    # A new user's floor: 40 segments of 0.5 m end to end. At every joint the next piece's
    # corner pushed the body up and back, along its own normal: a frictionless ball at
    # 4 m/s left at 1.34 m/s, a box at 0.03 (pymunk: 4.0). The joint's corner is no
    # contact where the neighbour's face holds the body
    from rbsim.engines import make_engine

    mu = 0.6 if "rolling" in body else 0.0
    engine = make_engine("rbsim", scene_from(pieces_floor(body, mu=mu)))
    top = 0.0
    for _ in range(240):
        engine.advance(1)
        v = np.asarray(engine.world.engine.body_v)[-1]
        top = max(top, abs(float(v[1])))
    assert v[0] == pytest.approx(4.0, abs=1e-6)  # m/s: as on one long segment
    assert top < 1e-6  # m/s: never thrown up


def test_a_box_sliding_over_a_chain_that_bends_down_is_not_stopped():
    # two segments end to end, the second bending down 0.05 rad: the box, resting 0.1 mm
    # into the first, met the second's end straight ahead, a push taken as from the
    # chain's underside (where the joint is a valley) and kept: stopped from 5 m/s to 1.1
    # and turned over. Free flight over the bend ends at 5.44 m/s; pymunk 5.42
    from rbsim.engines import make_engine

    text = """
        version: 1
        world: {dt: 1/60, steps: 90}
        bodies:
          - {name: A, type: static, shape: {segment: {a: [-10, 0], b: [0, 0]}}}
          - {name: B, type: static, shape: {segment: {a: [0, 0], b: [10, -0.5]}}}
          - {name: box, position: [-3, 0.1], velocity: [5, 0], friction: 0,
             shape: {box: {size: [0.4, 0.2]}}}
    """
    engine = make_engine("rbsim", scene_from(text))
    spin = 0.0  # rad/s: the fastest turn
    for _ in range(90):
        engine.advance(1)
        spin = max(spin, abs(float(np.asarray(engine.world.engine.body_w)[-1])))
    v = np.asarray(engine.world.engine.body_v)[-1]
    # m/s: as over the bend in free flight (5.44), less its landing
    assert np.hypot(v[0], v[1]) > 5.3
    assert spin < 1.0  # rad/s (pymunk 0.63: the landing on the slope)


def arc_ends(n: int, radius: float = 2.0) -> list[tuple[float, float]]:
    """The n + 1 ends (m) of n pieces along a circular arc of `radius` (m) from -1.2 to 1.2
    rad about its lowest point, at the origin: a bowl."""
    return [
        (radius * math.sin(a), radius - radius * math.cos(a))
        for a in (-1.2 + 2.4 * k / n for k in range(n + 1))
    ]


def bowl_scene(floor: str) -> str:
    """A bowl's pieces (YAML lines) and a frictionless ball of 0.1 m set at (-1, 0.3) m,
    7 cm into a bowl of radius 2 m, for 600 steps of 1/60 s."""
    return (
        "version: 1\nworld: {dt: 1/60, steps: 600}\nbodies:\n" + floor + "  - {name: b, "
        "position: [-1.0, 0.3], friction: 0, shape: {circle: {radius: 0.1}}}\n"
    )


def assert_energy_never_rises(engine, after: int, steps: int) -> None:  # noqa: ANN001
    """Advance `after` steps, then `steps` more, each with a total energy no more than
    after the first `after` (J; to 1e-3 of it: the soft contacts' give)."""
    engine.advance(after)
    first = engine.observables()
    start = first["kinetic_energy"] + first["potential_energy"]
    for _ in range(steps):
        engine.advance(1)
        o = engine.observables()
        assert o["kinetic_energy"] + o["potential_energy"] <= start + 1e-3 * abs(start) + 1e-9


def test_a_ball_in_a_bowl_of_many_pieces_never_gains_energy():
    # a valley's joints stay corners: there the corner's push is what stops the ball at
    # the next piece, which rises (without it a ball rolling in a bowl of 200 pieces
    # gained 4% of its energy in 10 s)
    from rbsim.engines import make_engine

    ends = arc_ends(200)
    floor = "".join(
        f"  - {{name: f{k}, type: static, shape: {{segment: {{a: [{ends[k][0]!r}, {ends[k][1]!r}], "
        f"b: [{ends[k + 1][0]!r}, {ends[k + 1][1]!r}]}}}}}}\n"
        for k in range(200)
    )
    assert_energy_never_rises(make_engine("rbsim", scene_from(bowl_scene(floor))), 1, 599)


def static_box(
    name: str, position: tuple, size: tuple, friction: float | None = None, keys: str = ""
) -> str:
    """One static box as a scene's YAML line: its centre and full size (m, 2 or 3
    components each), its friction (None: the default material's) and further `keys`."""
    nums = lambda xs: "[" + ", ".join(repr(x) for x in xs) + "]"  # noqa: E731
    mu = "" if friction is None else f" friction: {friction},"
    return (
        f"  - {{name: {name}, type: static,{mu} position: {nums(position)},{keys}"
        f" shape: {{box: {{size: {nums(size)}}}}}}}\n"
    )


def scene_head(dimension: int, steps: int) -> str:
    """A scene's lines up to its bodies: dt 1/60 s, `steps` steps, in 2D or 3D."""
    world = f"{{dt: 1/60, steps: {steps}}}"
    if dimension == 3:
        world = f"{{dimension: 3, dt: 1/60, steps: {steps}}}"
    return f"version: 1\nworld: {world}\nbodies:\n"


def tile_floor(dimension: int, body: str, tiles: int = 16, mu: float = 0.0) -> str:
    """A floor of static boxes 0.5 m wide side by side, their tops at y = 0 (2D: a row of
    `tiles`; 3D: tiles × tiles of them), and `body` (a YAML flow mapping) on it."""
    if dimension == 2:
        floor = "".join(
            static_box(f"t{i}", (0.25 + 0.5 * i, -0.1), (0.5, 0.2), mu) for i in range(tiles)
        )
    else:
        floor = "".join(
            static_box(f"t{i}_{j}", (0.25 + 0.5 * i, -0.1, 0.25 + 0.5 * j), (0.5, 0.2, 0.5), mu)
            for i in range(tiles)
            for j in range(tiles)
        )
    return f"{scene_head(dimension, 90)}{floor}  - {body}\n"


TILE_MOVERS = {
    "ball-2d": (
        2,
        "{name: b, position: [0.5, 0.2], velocity: [4, 0], friction: 0,"
        " shape: {circle: {radius: 0.2}}}",
    ),
    "box-2d": (
        2,
        "{name: b, position: [0.5, 0.25], velocity: [4, 0], friction: 0,"
        " shape: {box: {size: [0.5, 0.5]}}}",
    ),
    "hexagon-2d": (
        2,
        "{name: b, position: [0.78, 0.0866], velocity: [1, 0], friction: 0, shape: {polygon:"
        " {vertices: [[0.1, 0], [0.05, 0.0866], [-0.05, 0.0866], [-0.1, 0], [-0.05, -0.0866],"
        " [0.05, -0.0866]]}}}",
    ),
    "capsule-2d": (
        2,
        "{name: b, position: [0.5, 0.1], velocity: [4, 0], friction: 0,"
        " shape: {segment: {a: [-0.2, 0], b: [0.2, 0], radius: 0.1}}}",
    ),
    "rolling-ball-2d": (
        2,
        "{name: b, position: [0.5, 0.2], velocity: [4, 0],"
        " angular_velocity: -20, friction: 0.6, shape: {circle: {radius: 0.2}}}",
    ),
    "sphere-3d": (
        3,
        "{name: b, position: [0.5, 0.2, 0.5], velocity: [3, 0, 3], friction: 0,"
        " shape: {sphere: {radius: 0.2}}}",
    ),
    "box-3d": (
        3,
        "{name: b, position: [0.5, 0.25, 0.5], velocity: [3, 0, 3], friction: 0,"
        " shape: {box: {size: [0.5, 0.5, 0.5]}}}",
    ),
    "pyramid-3d": (
        3,
        "{name: b, position: [0.5, 0.3, 0.5], velocity: [3, 0, 3], friction: 0,"
        " shape: {convex: {vertices: [[-0.3, -0.3, -0.3], [0.3, -0.3, -0.3],"
        " [0.3, -0.3, 0.3], [-0.3, -0.3, 0.3], [0, 0.3, 0]]}}}",
    ),
    "rolling-sphere-3d": (
        3,
        "{name: b, position: [0.5, 0.2, 0.5], velocity: [3, 0, 3],"
        " angular_velocity: [15, 0, -15], friction: 0.6,"
        " shape: {sphere: {radius: 0.2}}}",
    ),
}


def one_floor(dimension: int, body: str, mu: float = 0.0) -> str:
    """tile_floor's scene with its floor one static box."""
    at, size = ((4, -0.1), (8, 0.2)) if dimension == 2 else ((4, -0.1, 4), (8, 0.2, 8))
    floor = static_box("floor", at, size, mu)
    text = tile_floor(dimension, body, tiles=0, mu=mu)
    return text.replace("bodies:\n", "bodies:\n" + floor, 1)


def assert_moves_as_on_one_floor(text: str, one: str) -> None:
    """Run scene `text` and scene `one` (the same on one floor) for 90 steps: the last
    body ends with the same velocity (to 1e-4 m/s: the points change piece at each joint,
    and a box settles up to 0.1 mm otherwise than on one floor; catching, it stopped),
    and never moves up or down faster than 1 mm/s."""
    from rbsim.engines import make_engine

    runs = []
    for scene in (text, one):
        engine = make_engine("rbsim", scene_from(scene))
        top = 0.0  # m/s: the fastest up or down
        for _ in range(90):
            engine.advance(1)
            v = np.asarray(engine.world.engine.body_v)[-1].copy()
            top = max(top, abs(float(v[1])))
        runs.append((v, top))
    (v, top), (v_one, _) = runs
    assert np.allclose(v, v_one, rtol=0, atol=1e-4)  # m/s
    assert top < 1e-3  # m/s: never thrown up


@pytest.mark.parametrize("mover", list(TILE_MOVERS))
def test_a_body_crossing_a_floor_of_tiles_moves_as_on_one_floor(mover):
    # A floor of static boxes side by side: at every joint the next tile's side, which
    # the tile before covers, or its corner pushed the body back. A frictionless box at
    # 4 m/s stopped within 2.3 m, a ball left at 2.1 m/s; in 3D across a grid of tiles a
    # box was left at 0.27 m/s of 3. Where a neighbour's face covers a face, the neighbour
    # holds the body
    dimension, body = TILE_MOVERS[mover]
    mu = 0.6 if "rolling" in mover else 0.0
    assert_moves_as_on_one_floor(
        tile_floor(dimension, body, mu=mu), one_floor(dimension, body, mu=mu)
    )


@pytest.mark.parametrize(
    "dimension, body",
    [
        (
            2,
            "{name: b, position: [0.5, 0.25], velocity: [4, 0], friction: 0,"
            " shape: {box: {size: [0.5, 0.5]}}}",
        ),
        (
            2,
            "{name: b, position: [0.5, 0.2], velocity: [4, 0], friction: 0,"
            " shape: {circle: {radius: 0.2}}}",
        ),
        (
            3,
            "{name: b, position: [0.5, 0.25, 0.5], velocity: [3, 0, 3], friction: 0,"
            " shape: {box: {size: [0.5, 0.5, 0.5]}}}",
        ),
    ],
    ids=["box-2d", "ball-2d", "box-3d"],
)
def test_a_body_crossing_flush_tiles_of_unequal_depths_moves_as_on_one_floor(dimension, body):
    # tiles whose tops lie flush and whose bottoms do not (depths 0.2 and 0.6 m in turn;
    # in 3D a chequerboard of them): a deeper tile's side is covered only near its top,
    # by the shallower one's, and its corner and that side pushed back a box at 4 m/s
    # until 1.5 m/s were left (3D: 0.14 of 3)

    deep = lambda i, j=0: 0.6 if (i + j) % 2 else 0.2  # noqa: E731 - m
    if dimension == 2:
        floor = "".join(
            static_box(f"t{i}", (0.25 + 0.5 * i, -deep(i) / 2), (0.5, deep(i)), 0)
            for i in range(16)
        )
    else:
        floor = "".join(
            static_box(
                f"t{i}_{j}",
                (0.25 + 0.5 * i, -deep(i, j) / 2, 0.25 + 0.5 * j),
                (0.5, deep(i, j), 0.5),
                0,
            )
            for i in range(16)
            for j in range(16)
        )
    text = tile_floor(dimension, body, tiles=0).replace("bodies:\n", "bodies:\n" + floor, 1)
    assert_moves_as_on_one_floor(text, one_floor(dimension, body))


@pytest.mark.parametrize("misfit", [-3e-4, -1e-6, 3e-4])
def test_tiles_a_little_apart_or_overlapping_are_flush(misfit):
    # tiles placed by hand, to a few decimals, meet within FLUSH_DISTANCE (0.5 mm): one
    # surface still. (Overlapping by 1 µm, a floor stopped a box at 4 m/s within 2.3 m)
    body = (
        "{name: b, position: [0.5, 0.25], velocity: [4, 0], friction: 0,"
        " shape: {box: {size: [0.5, 0.5]}}}"
    )
    floor = "".join(
        static_box(f"t{i}", (0.25 + (0.5 + misfit) * i, -0.1), (0.5, 0.2), 0.0) for i in range(16)
    )
    assert_moves_as_on_one_floor(f"{scene_head(2, 90)}{floor}  - {body}\n", one_floor(2, body))


def test_a_turned_box_crossing_where_four_tilted_tiles_meet_moves_as_on_one_piece():
    # a ramp of four static boxes tilted 0.2 rad, placed to 5 decimals, meeting at one
    # point; a box turned 0.6 rad about the ramp's normal slides across that point. Its
    # side met the tiles' common corner there and it left spinning at 3.8 rad/s, with 40%
    # of its kinetic energy gone (helper-25)
    from rbsim.engines import make_engine

    tiles = (
        ("t00", (0.44037, -0.34435, 0.5), (3, 0.5, 3)),
        ("t01", (0.44037, -0.34435, 4.0), (3, 0.5, 4)),
        ("t10", (3.8706, -1.03969, 0.5), (4, 0.5, 3)),
        ("t11", (3.8706, -1.03969, 4.0), (4, 0.5, 4)),
    )
    box = (
        "  - {name: box, friction: 0, position: [0.31389, 0.03841, 0.47], orientation:"
        " [0.950564, 0.029503, 0.294044, -0.095375], velocity: [0.49003, -0.09933, 1.5],"
        " shape: {box: {size: [0.2, 0.2, 0.2]}}}\n"
    )
    turn = " rotation: {axis: [0, 0, 1], angle: -0.2},"
    pieces = "".join(static_box(n, x, size, 0, turn) for n, x, size in tiles)
    one = static_box("one", (2.4005, -0.74169, 2.5), (7, 0.5, 7), 0, turn)
    ends = []
    for floor in (pieces, one):
        engine = make_engine("rbsim", scene_from(scene_head(3, 72) + floor + box))
        engine.advance(72)
        ends.append(
            (
                np.asarray(engine.world.engine.body_v)[-1].copy(),
                np.asarray(engine.world.engine.body_w)[-1].copy(),
            )
        )
    (v, w), (v_one, w_one) = ends
    assert np.allclose(v, v_one, rtol=0, atol=1e-3)  # m/s
    assert np.allclose(w, w_one, rtol=0, atol=1e-2)  # rad/s


def segment_floor(dimension: int, body: str) -> str:
    """tile_floor's 2D scene (dimension 2) with its floor 16 static segments 0.5 m long end
    to end."""
    assert dimension == 2
    floor = "".join(
        f"  - {{name: s{i}, type: static, friction: 0.0, shape: {{segment:"
        f" {{a: [{0.5 * i!r}, 0.0], b: [{0.5 * (i + 1)!r}, 0.0]}}}}}}\n"
        for i in range(16)
    )
    return f"{scene_head(2, 90)}{floor}  - {body}\n"


def last_body_motion(text: str, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The scene `text` run for `steps` steps: its last body's velocity (m/s, steps × D)
    and angular velocity (rad/s, steps × 1 or 3) after each step."""
    from rbsim.engines import make_engine

    engine = make_engine("rbsim", scene_from(text))
    v, w = [], []
    for _ in range(steps):
        engine.advance(1)
        v.append(np.asarray(engine.world.engine.body_v)[-1].copy())
        w.append(np.atleast_1d(np.asarray(engine.world.engine.body_w)[-1]).copy())
    return np.array(v), np.array(w)


FLAT_LANDINGS = {
    # a box over one joint of the floor (2D: between two tiles or two segments; 3D: two
    # tiles), and over the corner where four tiles meet (3D)
    "tiles-2d": (tile_floor, 2, "[0.6, 0.35]", "[0.6, 0.6]"),
    "segments-2d": (segment_floor, 2, "[0.6, 0.35]", "[0.6, 0.6]"),
    "tiles-3d": (tile_floor, 3, "[0.6, 0.35, 2.25]", "[0.4, 0.6, 0.4]"),
    "corner-3d": (tile_floor, 3, "[0.5, 0.35, 0.5]", "[0.6, 0.6, 0.6]"),
}


@pytest.mark.parametrize("landing", list(FLAT_LANDINGS))
@pytest.mark.parametrize("e, speed", [(0.0, 6.25), (0.5, 6.25), (1.0, 6.25), (0.5, 25), (1.0, 25)])
def test_a_box_landing_flat_across_the_joints_of_a_floor_bounces_as_on_one_floor(landing, e, speed):
    # A box dropped flat at 6.25 m/s onto two or four pieces of floor at once: each
    # piece's manifold has points to one side of the box's centre, and bounced (or
    # stopped) one manifold after the other they tipped it. Across two segments in 2D, e =
    # 0.5, it left at 1.75 m/s, not 3.1, turning at 5.4 rad/s; e = 0 threw it up at 0.29
    # m/s; on the corner of four tiles (3D, e = 0.5) it left at 3.87 m/s, not 3.11; at 25
    # m/s, e = 1, it turned at 32 - 60 rad/s. The pieces' points are now one block
    # (restitution.cpp, push_group): for 40 steps, through the bounce and, for e = 0.5,
    # the next landing, the box moves as on one floor.
    floor, dimension, position, size = FLAT_LANDINGS[landing]
    velocity = f"[0, {-speed}]" if dimension == 2 else f"[0, {-speed}, 0]"
    body = (
        f"{{name: b, position: {position}, velocity: {velocity}, friction: 0.5,"
        f" restitution: {e}, shape: {{box: {{size: {size}}}}}}}"
    )
    texts = [
        t.replace("type: static,", f"type: static, restitution: {e},")
        for t in (floor(dimension, body), one_floor(dimension, body))
    ]
    (v, w), (v_one, _) = (last_body_motion(text, 40) for text in texts)
    # m/s and rad/s: in the impact's substep the positions move with the solve's tilted
    # push before the stage redoes it (e = 0: 0.035 m/s, 0.12 rad/s at most; else 0.01)
    slack = 2.0 if e == 0.0 else 0.5
    assert np.abs(v - v_one).max() < 0.025 * slack
    assert np.abs(w).max() < 0.1 * slack


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("e", [0.5, 1.0])
def test_a_box_landing_on_a_lift_of_two_slabs_bounces_as_on_one(dimension, e):
    # The pieces of a group (push_group) may move: a lift of two kinematic slabs rising at
    # 1 m/s, a box dropped flat across their joint at 6.25 m/s. It bounces off them as
    # off one slab, relative to the lift (each slab's manifold on its own, in 2D, e = 0.5
    # left at 2.85 m/s, not 4.61, turning; e = 1 at 4.19 m/s, not 8.28).
    def scene(pieces: int) -> str:
        z = ", 0" if dimension == 3 else ""
        deep = ", 2" if dimension == 3 else ""
        width = 2.0 / pieces
        lift = "".join(
            f"  - {{name: l{i}, type: kinematic, material: m,"
            f" position: [{-1 + width * (i + 0.5)!r}, -0.25{z}], velocity: [0, 1{z}],"
            f" shape: {{box: {{size: [{width!r}, 0.5{deep}]}}}}}}\n"
            for i in range(pieces)
        )
        size = "[0.6, 0.6, 0.6]" if dimension == 3 else "[0.6, 0.6]"
        world = "{dimension: 3, dt: 1/60, steps: 20}" if dimension == 3 else "{dt: 1/60, steps: 20}"
        return (
            f"version: 1\nworld: {world}\nmaterials:\n"
            f"  m: {{density: 1000, friction: 0.5, restitution: {e}}}\nbodies:\n{lift}"
            f"  - {{name: b, position: [0.1, 0.35{z}], velocity: [0, -6.25{z}],"
            f" shape: {{box: {{size: {size}}}}}, material: m}}\n"
        )

    (v, w), (v_one, _) = (last_body_motion(scene(pieces), 20) for pieces in (2, 1))
    assert v_one[0, 1] > 1.0 + 0.9 * e * 7.25  # m/s: it bounced off the rising lift
    # m/s and rad/s: as on the floor of tiles above (4.5e-3 m/s, 7.2e-3 rad/s measured)
    assert np.abs(v - v_one).max() < 0.0125
    assert np.abs(w).max() < 0.05


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_box_dropped_hard_onto_narrow_tiles_does_not_fall_through(dimension):
    # a box driven 6 cm into a floor of tiles 0.2 m wide overlaps each tile less through
    # its side than through its top: with every covered side's push dropped, it fell
    # through the floor (helper-26). Deep manifolds keep their push
    from rbsim.engines import make_engine

    if dimension == 2:
        floor = "".join(static_box(f"t{k}", (-0.9 + 0.2 * k, -0.15), (0.2, 0.3)) for k in range(10))
        body = (
            "  - {name: b, position: [0.05, 0.4], angle: 0.3, velocity: [0, -6],"
            " shape: {box: {size: [0.32, 0.135]}}}\n"
        )
    else:
        floor = "".join(
            static_box(f"t{i}_{j}", (-0.4 + 0.2 * i, -0.15, -0.4 + 0.2 * j), (0.2, 0.3, 0.2))
            for i in range(5)
            for j in range(5)
        )
        body = (
            "  - {name: b, position: [0, 0.4, 0], rotation: {axis: [0.3, 0.2, 1], angle: 0.785},"
            " velocity: [-2, -8, 1], density: 500, friction: 0.3, restitution: 0.3,"
            " shape: {box: {size: [0.32, 0.135, 0.2]}}}\n"
        )
    engine = make_engine("rbsim", scene_from(scene_head(dimension, 30) + floor + body))
    lowest = np.inf  # m: the box's centre
    for _ in range(30):
        engine.advance(1)
        lowest = min(lowest, float(np.asarray(engine.world.engine.body_x)[-1][1]))
    assert lowest > 0.0  # m: its centre never below the tiles' tops (half its height 0.0675)


@pytest.mark.parametrize("size", [0.001, 0.002])
def test_millimetre_tiles_never_let_a_box_through_or_speed_it_up(size):
    # parts of a few millimetres rest deeper than their slop at the usual step: there the
    # joints are left to catch (COVERED_MIN_SCALE), as before. Dropped, a 1 mm box
    # sliding over 1 mm tiles fell through them, a 2 mm one was sped up by 65%
    floor = "".join(
        static_box(f"t{k}", ((k + 0.5) * size, -size / 2), (size, size), 0) for k in range(20)
    )
    text = (
        f"{scene_head(2, 60)}{floor}  - {{name: b, position: [{size!r}, {size / 2!r}], velocity:"
        f" [{8 * size!r}, 0], friction: 0, shape: {{box: {{size: [{size!r}, {size!r}]}}}}}}\n"
    )
    from rbsim.engines import make_engine

    engine = make_engine("rbsim", scene_from(text))
    for _ in range(60):
        engine.advance(1)
        x = np.asarray(engine.world.engine.body_x)[-1]
        assert x[1] > 0.0  # m: its centre above the tiles' tops
    v = np.asarray(engine.world.engine.body_v)[-1]
    assert np.hypot(v[0], v[1]) <= 8 * size  # m/s: not faster than thrown (it is caught)


def test_a_box_crossing_planks_laid_in_bond_keeps_its_speed():
    # planks 2 m long, row by row across the way, each row half a plank along from the
    # last: each plank's long side is covered by two of the next row's
    from rbsim.engines import make_engine

    planks = "".join(
        static_box(f"p{j}_{i}", (-3.0 + (j % 2) + 2 * i, -0.1, 0.125 + 0.25 * j), (2, 0.2, 0.25), 0)
        for j in range(24)
        for i in range(4)
    )
    text = (
        "version: 1\nworld: {dimension: 3, dt: 1/60, steps: 90}\nbodies:\n"
        + planks
        + "  - {name: b, position: [0.3, 0.25, 0.3], velocity: [0, 0, 3], friction: 0,"
        " shape: {box: {size: [0.5, 0.5, 0.5]}}}\n"
    )
    engine = make_engine("rbsim", scene_from(text))
    engine.advance(90)
    v = np.asarray(engine.world.engine.body_v)[-1]
    assert np.allclose(v, [0, 0, 3], rtol=0, atol=1e-6)  # m/s


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_taller_tile_still_stops_a_box(dimension):
    # a face only partly covered is a face: the side of a tile 1 m taller than the floor
    # tiles before it stops a frictionless box (e = 0) that slides into it
    from rbsim.engines import make_engine

    v = lambda *xyz: vector(dimension, *xyz)  # noqa: E731
    pieces = [(0.25 + 0.5 * i, -0.1, 0.2) for i in range(12)] + [(6.25, 0.4, 1.2)]
    floor = "".join(
        static_box(f"t{i}", (x, y, 0.25)[:dimension], (0.5, h, 0.5)[:dimension], 0)
        for i, (x, y, h) in enumerate(pieces)
    )
    world = "{dt: 1/60, steps: 90}" if dimension == 2 else "{dimension: 3, dt: 1/60, steps: 90}"
    text = (
        f"version: 1\nworld: {world}\nbodies:\n{floor}  - {{name: b, position: "
        f"{v(0.5, 0.25, 0.25)}, velocity: {v(4, 0, 0)}, friction: 0,"
        f" shape: {{box: {{size: {v(0.5, 0.5, 0.5)}}}}}}}\n"
    )
    engine = make_engine("rbsim", scene_from(text))
    engine.advance(90)
    x = np.asarray(engine.world.engine.body_x)[-1]
    u = np.asarray(engine.world.engine.body_v)[-1]
    assert abs(u[0]) < 1e-3  # m/s: stopped (but the soft contact's slow push-out)
    assert 5.74 < x[0] <= 5.75 + 1e-6  # m: against the wall's side at x = 6


def test_a_wedge_falling_down_a_walls_face_lands_on_the_floor_the_wall_stands_on():
    # a wall standing on a 5 cm floor box covers the floor's top under its foot; a wedge
    # (its vertical side against the wall, its point down) falling down the wall's face
    # meets the floor at 10 m/s with that point 1.6 cm into the wall, where the floor's
    # push was dropped as a joint's (as in bench/random_scenes.py seed 4857, at 26 m/s):
    # it went through the floor and stuck in the wall's foot.
    # A point within the floor's face is the floor's own push: the wedge lands and tips
    # over onto its side (its centre then 3.2 cm up)
    from rbsim.engines import make_engine

    pieces = static_box("floor", (0, -0.025), (4.434, 0.05))
    pieces += static_box("wall", (2.192, 3.257), (0.05, 6.515))
    wedge = (
        "  - {name: wedge, position: [2.13337, 1.2], velocity: [0, -10], friction: 0.5,"
        " shape: {polygon: {vertices: [[-0.05, 0.3], [0.05, -0.3], [0.05, 0.3]]}}}\n"
    )
    text = "version: 1\nworld: {dt: 1/30, steps: 30}\nbodies:\n" + pieces + wedge
    engine = make_engine("rbsim", scene_from(text))
    lowest = np.inf  # m: its centre's
    for _ in range(30):
        engine.advance(1)
        lowest = min(lowest, float(np.asarray(engine.world.engine.body_x)[-1][1]))
    assert lowest > 0.0  # m: never below the floor's top (lying on its side: 0.032)


@pytest.mark.parametrize(
    ("dimension", "ground"), [(2, "box"), (2, "short"), (3, "box"), (3, "short"), (3, "plane")]
)
@pytest.mark.parametrize("kind", ["box", "capsule"])
def test_a_chip_wedged_under_the_foot_of_a_wall_comes_out_into_the_box(dimension, ground, kind):
    # a wall standing on the floor, its bottom face covered by the floor's top, and a chip
    # 2 cm thick (16 cm long) wedged 6 cm under the wall's foot and 1.2 cm into the floor,
    # as a pile squeezed small bodies there in bench/random_scenes.py (seeds 141, 1043,
    # 1209): the wall's covered face pushed it down into the floor (or, shallow, not at
    # all), and it stayed there for good, 7.6 mm deep and 1.6 cm under the wall, or slid
    # on out of the box beneath it. The push of the solid the two make, from the wall's
    # open side, brings it out to rest on the floor against the wall (in 3D on a floor
    # box, or on a ground plane: a face lying in the plane, turned down, is covered too).
    # A floor that ends 2 mm short of the wall's outer face covers the wall's foot only
    # near its inner corner, whose push into the floor is made again the same way
    # (bench/random_scenes.py seed 2795)
    from rbsim.engines import make_engine

    v = lambda *xyz: vector(dimension, *xyz)  # noqa: E731
    shape = {
        "box": f"box: {{size: {v(0.16, 0.02, 0.1)}}}",
        "capsule": f"{'segment' if dimension == 2 else 'capsule'}: {{a: {v(-0.07, 0, 0)},"
        f" b: {v(0.07, 0, 0)}, radius: 0.01}}",
    }[kind]
    pieces = static_box("floor", (0, -0.1, 0)[:dimension], (6, 0.2, 6)[:dimension])
    if ground == "short":  # (from x = -2.198 to 3)
        pieces = static_box("floor", (0.401, -0.1, 0)[:dimension], (5.198, 0.2, 6)[:dimension])
    if ground == "plane":
        pieces = "  - {name: floor, type: static, shape: {plane: {normal: [0, 1, 0], offset: 0}}}\n"
    pieces += static_box("wall", (-2.1, 2, 0)[:dimension], (0.2, 4, 6)[:dimension])
    chip = (
        f"  - {{name: chip, position: {v(-1.98, -0.002, 0)}, density: 200, shape: {{{shape}}}}}\n"
    )
    engine = make_engine("rbsim", scene_from(scene_head(dimension, 120) + pieces + chip))
    engine.advance(120)
    x = np.asarray(engine.world.engine.body_x)[-1]
    assert x[1] > 0.01 - 1e-3  # m: on the floor (half its thickness, less a soft contact's sink)
    assert x[0] - 0.08 > -2.0 - 0.005  # m: its end out of the wall (face x = -2), to the slop


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_box_sliding_over_a_bend_between_flush_pieces_stays_on_them(dimension):
    # two static pieces flush at x = 0, the second's top sloping down 0.05 rad from there:
    # the joint is a convex corner of the floor, whose push (leaning no farther than the
    # first piece's face) is the box's support as it tips over; dropped with the covered
    # sides' pushes, the box fell through the floor (pymunk: it slides on down the slope)
    from rbsim.engines import make_engine

    if dimension == 2:
        pieces = (
            "  - {name: A, type: static, shape: {polygon: {vertices:"
            " [[-10, -1], [0, -1], [0, 0], [-10, 0]]}}}\n"
            "  - {name: B, type: static, shape: {polygon: {vertices:"
            " [[0, -1], [10, -1], [10, -0.5], [0, 0]]}}}\n"
        )
        box = "position: [-0.5, 0.1], velocity: [0.3, 0], shape: {box: {size: [0.4, 0.2]}}"
        world = "{dt: 1/60, steps: 180}"
    else:
        pieces = (
            "  - {name: A, type: static, position: [-5, -0.5, 0],"
            " shape: {box: {size: [10, 1, 2]}}}\n"
            "  - {name: B, type: static, shape: {convex: {vertices: [[0, -1, -1], [0, -1, 1],"
            " [10, -1, -1], [10, -1, 1], [10, -0.5, -1], [10, -0.5, 1], [0, 0, -1], [0, 0, 1]]}}}\n"
        )
        box = (
            "position: [-0.5, 0.1, 0], velocity: [0.3, 0, 0], shape: {box: {size: [0.4, 0.2, 0.4]}}"
        )
        world = "{dimension: 3, dt: 1/60, steps: 180}"
    text = f"version: 1\nworld: {world}\nbodies:\n{pieces}  - {{name: box, friction: 0, {box}}}\n"
    engine = make_engine("rbsim", scene_from(text))
    lowest = np.inf  # m: the box's centre, least height above the floor's surface there
    for _ in range(180):
        engine.advance(1)
        x = np.asarray(engine.world.engine.body_x)[-1]
        surface = 0.0 if x[0] < 0 else -0.05 * x[0]  # m (tan 0.05 rad ~ 0.05)
        lowest = min(lowest, float(x[1]) - surface)
    assert x[0] > 0.5  # m: over the bend and on down the slope
    assert lowest > 0.09  # m: its half height 0.1, but the soft contacts' slop


def test_a_ball_in_a_bowl_of_flush_polygons_never_gains_energy():
    # 60 static quadrilaterals side by side under an arc, each one's sides covered by its
    # neighbours': every joint a valley, where the corner's push is the speculative contact
    # that stops the ball at the rising neighbour, and stays, as for segments. Dropped
    # with the covered sides' pushes, the ball rolling in the bowl gained 3.4% of its
    # energy between 1 and 10 s. (Set into the bowl, it is pushed out and lands in the
    # first second, which the test leaves out)
    from rbsim.engines import make_engine

    ends = arc_ends(60)
    floor = "".join(
        f"  - {{name: f{k}, type: static, shape: {{polygon: {{vertices: [[{ends[k][0]!r}, -1.0],"
        f" [{ends[k + 1][0]!r}, -1.0], [{ends[k + 1][0]!r}, {ends[k + 1][1]!r}],"
        f" [{ends[k][0]!r}, {ends[k][1]!r}]]}}}}}}\n"
        for k in range(60)
    )
    assert_energy_never_rises(make_engine("rbsim", scene_from(bowl_scene(floor))), 60, 540)


def end_first_scene(dimension: int, substeps: int) -> str:
    """A 0.4 m needle (a capsule, 5 mm radius) flying end first at a wall at 400 m/s
    (6.7 m a step of 1/60 s), e = 0.5, beside a ball whose front starts as far from it."""
    v = lambda *xyz: vector(dimension, *xyz)  # noqa: E731
    needle = "capsule" if dimension == 3 else "segment"
    ball = "sphere" if dimension == 3 else "circle"
    return f"""
    version: 1
    world: {{dimension: {dimension}, gravity: {v(0, 0, 0)}, dt: 1/60, steps: 1}}
    solver: {{substeps: {substeps}}}
    materials: {{m: {{density: 1000, friction: 0.3, restitution: 0.5}}}}
    bodies:
      - {{name: wall, type: static, material: m, position: {v(5, 0, 0)},
         shape: {{box: {{size: {v(0.05, 4, 4)}}}}}}}
      - {{name: needle, material: m, position: {v(0, 1, 0)}, velocity: {v(400, 0, 0)},
         shape: {{{needle}: {{a: {v(-0.2, 0, 0)}, b: {v(0.2, 0, 0)}, radius: 0.005}}}}}}
      - {{name: ball, material: m, position: {v(0, -1, 0)}, velocity: {v(400, 0, 0)},
         shape: {{{ball}: {{radius: 0.205}}}}}}
    """


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("substeps", [1, 2, 4])
def test_a_needle_flying_end_first_bounces_at_the_wall_as_a_ball_does(dimension, substeps):
    # A new user's scene: the needle has a contact point at each end, the far one 0.4 m
    # behind. The substep before the needle met the wall, the relax pass's speculative
    # push (closing the gaps and no more) engaged both; the near one waited for the
    # bodies to meet, but the restitution stage's exact redo bounced the far one as it
    # stood: the needle turned back 1.4 m short of the wall and ended the step at 1.67 m
    # (substeps 2 in 3D, 4 in both). It meets the wall now where the ball does
    from rbsim.engines import make_engine

    engine = make_engine("rbsim", scene_from(end_first_scene(dimension, substeps)))
    engine.advance(1)
    x = np.asarray(engine.world.engine.body_x)[:, 0]
    v = np.asarray(engine.world.engine.body_v)[:, 0]
    assert v[1] == pytest.approx(-200.0) and v[2] == pytest.approx(-200.0)  # e = 0.5
    # m: where the ball ends the step (4.77 at one substep: stopped at the wall, bounced
    # at the step's end; 3.94 at four), to round-off
    assert x[1] == pytest.approx(x[2], abs=1e-9)
    assert x[1] > 3.9


def test_extra_relax_passes_take_the_contacts_around_a_deep_overlap_only():
    # shock.deep_region: the manifolds of the dynamic bodies within `reach` contacts
    # of a deep one, in solve order; a column far away, and the ground itself, do not
    # carry the region over
    world = make_world(column_scene([0.0, 20.0], sink=0.0))
    world.advance(1)
    c = world.contacts
    n = int(c.count[0])
    pairs = [(int(c.body_a[m]), int(c.body_b[m])) for m in range(n)]
    names = [b.name for b in world.scene.bodies]
    bottom = next(m for m, ab in enumerate(pairs) if {names[i] for i in ab} == {"ground", "c0b0"})
    for reach in (0, 2):
        c.relax_list[0] = bottom
        c.count[6] = 1
        k = world.stage("deep_region", reach=reach)
        region = [int(m) for m in c.relax_list[:k]]
        assert region == [int(m) for m in c.solve_order[:n] if m in region]  # solve order
        # the balls within reach of the deep one (c0b0), and the next one up, at the
        # far end of their manifolds
        bodies = {names[i] for m in region for i in pairs[m]} - {"ground"}
        assert bodies == {f"c0b{i}" for i in range(reach + 2)}
    # a deep overlap between bodies that have not moved this step (contacts.body_delta)
    # is not being pushed out, as a circle wedged deep at the foot of a settled pile:
    # no region; a move or a turn of the ball above the ground makes one again
    ball = names.index("c0b0")
    for dx, turn, expected in ((0.0, 0.0, 0), (2e-4, 0.0, 2), (0.0, 2e-4, 2)):
        c.body_delta[:] = [0.0, 0.0, 1.0, 0.0]
        c.body_delta[ball] = [0.0, dx, np.cos(turn), np.sin(turn)]
        c.relax_list[0] = bottom
        c.count[6] = 1
        k = world.stage("deep_region", reach=0)
        assert k == expected  # reach 0: the ball's two manifolds, with the ground and c0b1


# ---------------------------------------------------------------------------------------
# 5. Determinism
# ---------------------------------------------------------------------------------------

PILE = """
version: 1
world: {dt: 1/60, steps: 300}
materials: {stuff: {density: 1.0, friction: 0.5, restitution: 0.3}}
bodies:
  - {name: floor, type: static, shape: {segment: {a: [-6, 0], b: [6, 0]}}}
  - {name: left, type: static, shape: {segment: {a: [-6, 0], b: [-6, 8]}}}
  - {name: right, type: static, shape: {segment: {a: [6, 0], b: [6, 8]}}}
  - grid: {name: balls, count: [8, 5], spacing: [1.1, 1.1], origin: [-4.1, 2.0],
           velocity: [0.7, 0], material: stuff, shape: {circle: {radius: 0.4}}}
  - grid: {name: crates, count: [7, 5], spacing: [1.1, 1.1], origin: [-3.55, 2.55],
           velocity: [-0.5, -1], material: stuff, shape: {box: {size: [0.6, 0.4], angle: 0.3}}}
"""


def state_digests(world: World, steps: int) -> list[str]:
    """sha256 of every body's position, orientation, velocity and spin after each step."""
    out = []
    for _ in range(steps):
        world.advance(1)
        s = world.state
        h = hashlib.sha256()
        for a in (s.body_x, s.body_q, s.body_angle, s.body_v, s.body_w):
            h.update(np.ascontiguousarray(a).tobytes())
        out.append(h.hexdigest())
    return out


def test_same_scene_twice_gives_bit_identical_trajectories():
    first = state_digests(make_world(PILE), 300)
    make_world(gas_scene(n=10)).advance(50)  # an unrelated run in between
    second = state_digests(make_world(PILE), 300)
    assert first == second
    # and the pile really is chaotic: the boxes and balls have hit each other
    world = make_world(PILE)
    world.advance(300)
    assert world.contact_count > 40


# ---------------------------------------------------------------------------------------
# 6. No tunneling
# ---------------------------------------------------------------------------------------

LINEAR_SLOP = 0.005  # m, the overlap the solver allows before pushing out


@pytest.mark.parametrize("e", [0.0, 1.0])
def test_fast_small_ball_never_passes_a_thin_wall(e):
    # 300 m/s is 5 m per step, 50 ball radii and 50 wall thicknesses
    world = make_world(
        f"""
        version: 1
        world: {{gravity: [0, 0], dt: {DT!r}, steps: 30}}
        bodies:
          - {{name: wall, type: static, position: [10.05, 0], restitution: {e},
             shape: {{box: {{size: [0.1, 4]}}}}}}
          - {{name: bullet, position: [0, 0.3], velocity: [300, 0], restitution: {e},
             shape: {{circle: {{radius: 0.05}}}}}}
        """
    )
    tr = record(world, 30)
    x = tr["x"][:, 1, 0]
    assert np.all(x < 10.1)  # never on the far side
    assert np.all(x + 0.05 <= 10.0 + LINEAR_SLOP)  # never through the near face
    assert tr["v"][-1, 1, 0] == pytest.approx(-300 * e, abs=1e-6 * 300)  # stopped or back


@pytest.mark.parametrize(
    "dt, drop, gravity",
    [("1/10", 0.03, -9.81), ("0.5", 0.9, -9.81), ("1/60", 0.9, -1e4)],
    ids=["pellet-dt-0.1", "ball-dt-0.5", "ball-g-1e4"],
)
@pytest.mark.parametrize("dimension", [2, 3])
def test_a_body_let_go_at_rest_never_falls_through_the_floor_in_a_long_step(
    dimension, dt, drop, gravity
):
    # A new user's scenes: at rest above the floor a body has no speed to reach it by,
    # but gravity gives it one within the step (10 cm at dt 1/10; 2.5 m at dt 0.5): no
    # contact was made, and it fell through in one step (every value within the bounds)
    from rbsim.engines import make_engine

    v = lambda *xyz: vector(dimension, *xyz)  # noqa: E731
    floor = (
        "{segment: {a: [-5, 0], b: [5, 0]}}"
        if dimension == 2
        else "{box: {size: [10, 0.001, 10], offset: [0, -0.0005, 0]}}"
    )
    ball = "circle" if dimension == 2 else "sphere"
    radius = 0.005 if drop < 0.1 else 0.1
    text = f"""
    version: 1
    world: {{dimension: {dimension}, dt: {dt}, steps: 20, gravity: {v(0, gravity, 0)}}}
    solver: {{substeps: 1}}
    bodies:
      - {{name: ground, type: static, shape: {floor}}}
      - {{name: b, position: {v(0, drop + radius, 0)}, shape: {{{ball}: {{radius: {radius}}}}}}}
    """
    engine = make_engine("rbsim", scene_from(text))
    for _ in range(20):
        engine.advance(1)
        y = float(np.asarray(engine.world.engine.body_x)[1, 1])
        assert y > 0.0  # m: the centre stays above the floor's top (y = 0)


@pytest.mark.parametrize("spin", [0.0, 30.0])
def test_fast_box_never_passes_a_segment_wall(spin):
    # 200 m/s is 3.3 m per step, 17 box lengths; spinning, it turns 0.5 rad per step
    world = make_world(
        f"""
        version: 1
        world: {{gravity: [0, 0], dt: {DT!r}, steps: 30}}
        bodies:
          - {{name: wall, type: static, shape: {{segment: {{a: [10, -5], b: [10, 5]}}}}}}
          - {{name: brick, position: [0, 0.2], velocity: [200, 10], angular_velocity: {spin},
             shape: {{box: {{size: [0.2, 0.1]}}}}}}
        """
    )
    tr = record(world, 30)
    c, s = tr["q"][:, 1, 0], tr["q"][:, 1, 1]
    for lx, ly in ((0.1, 0.05), (-0.1, 0.05), (-0.1, -0.05), (0.1, -0.05)):
        corner_x = tr["x"][:, 1, 0] + c * lx - s * ly
        assert np.all(corner_x <= 10.0 + LINEAR_SLOP)
    assert tr["contacts"].max() > 0  # it did reach the wall


# ---------------------------------------------------------------------------------------
# 7. Coulomb friction on a slope
# ---------------------------------------------------------------------------------------

SLOPE_ANGLE = 0.25  # rad; tan = 0.2553


def slope_scene(mu: float, duration: float) -> str:
    th = SLOPE_ANGLE
    normal = np.array([-math.sin(th), math.cos(th)])
    # a 1 m thick slope centred on the origin, the 0.5 m tall block resting on it
    bx, by = ((0.5 + 0.25) * normal).tolist()
    return f"""
version: 1
world: {{dt: {DT!r}, duration: {duration}}}
bodies:
  - {{name: slope, type: static, angle: {th}, friction: {mu},
     shape: {{box: {{size: [40, 1]}}}}}}
  - {{name: block, position: [{bx!r}, {by!r}], angle: {th}, friction: {mu},
     shape: {{box: {{size: [1, 0.5]}}}}}}
"""


def along_slope(tr: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (m) and velocity (m/s) of the block along the slope, downhill > 0."""
    down = -np.array([math.cos(SLOPE_ANGLE), math.sin(SLOPE_ANGLE)])
    return (tr["x"][:, 1] - tr["x"][0, 1]) @ down, tr["v"][:, 1] @ down


def test_block_on_slope_sticks_when_mu_exceeds_tan_theta():
    mu = 0.4
    assert mu > math.tan(SLOPE_ANGLE)
    world = make_world(slope_scene(mu, duration=5.0))
    s, _ = along_slope(record(world, world.scene.world.steps))
    assert np.abs(s).max() < 0.01  # static friction holds: slip below 1 cm in 5 s


def test_block_on_slope_slides_at_g_sin_minus_mu_cos_when_mu_below_tan_theta():
    mu = 0.1
    assert mu < math.tan(SLOPE_ANGLE)
    world = make_world(slope_scene(mu, duration=3.0))
    tr = record(world, world.scene.world.steps)
    _, v = along_slope(tr)
    t = np.arange(len(v)) * DT
    late = t >= 0.5  # past the first contact's settling
    accel = np.polyfit(t[late], v[late], 1)[0]
    expected = G * (math.sin(SLOPE_ANGLE) - mu * math.cos(SLOPE_ANGLE))
    assert accel == pytest.approx(expected, rel=0.05)  # 5% as asked
    # and the block stays on the slope without tipping
    assert np.abs(tr["w"][:, 1]).max() < 1e-3


# ---------------------------------------------------------------------------------------
# 8. Resting contact
# ---------------------------------------------------------------------------------------


def test_box_resting_on_ground_has_two_contacts_and_does_not_drift(run_text):
    tr = run_text(
        f"""
        version: 1
        world: {{dt: {DT!r}, duration: 4}}
        bodies:
          - {{name: ground, type: static, shape: {{segment: {{a: [-5, 0], b: [5, 0]}}}}}}
          - {{name: box, position: [0.3, 0.5], density: 2, shape: {{box: {{size: [1, 1]}}}}}}
        """
    )
    box = tr.body("box")
    count = tr.observables["contact_count"]
    assert np.all(count[1:] == 2)  # both bottom corners push at every step
    last = tr.time >= tr.time[-1] - 2.0
    speed = np.hypot(*tr.velocity[last, box].T)
    assert speed.max() < 1e-3  # no jitter: below 1 mm/s over the last 2 s
    # no drift: the box stays within 1 mm of where it was put
    assert np.abs(tr.position[:, box] - tr.position[0, box]).max() < 1e-3
    # the contact carries the weight: with no acceleration, N = m (g + dv/dt) = m g
    mass = tr.bodies.mass[box]
    dvdt = (tr.velocity[-1, box, 1] - tr.velocity[last, box, 1][0]) / 2.0
    normal_force = mass * (G + dvdt)
    assert normal_force == pytest.approx(mass * G, rel=1e-3)


# ---------------------------------------------------------------------------------------
# Example scenes
# ---------------------------------------------------------------------------------------

# The top of the ground (or, for the billiards table seen from above, the cushions)
# that every body must stay inside of: xmin, xmax, ymin, ymax (m).
EXAMPLES = {
    "bounce": (-math.inf, math.inf, 0.0, math.inf),
    "billiards": (-1.27, 1.27, -0.635, 0.635),
    "balls_in_box": (-5.0, 5.0, 0.0, math.inf),
    "stairs": (-math.inf, math.inf, 0.0, math.inf),
}
MARGIN = 0.05  # m: a little overlap is allowed, a body through the ground is not


def body_extents(world: World) -> np.ndarray:
    """(N,4) xmin, xmax, ymin, ymax of every body's shapes, radius included."""
    model, state = world.model, world.state
    ext = np.tile([np.inf, -np.inf, np.inf, -np.inf], (len(model.body_mass), 1))
    for shape, body in enumerate(model.shape_body):
        start, count = model.shape_vstart[shape], model.shape_vcount[shape]
        local = model.vertex_local[start : start + count]
        c, s = state.body_q[body]
        world_v = state.body_x[body] + local @ np.array([[c, s], [-s, c]])
        r = model.shape_radius[shape]
        ext[body, 0] = min(ext[body, 0], world_v[:, 0].min() - r)
        ext[body, 1] = max(ext[body, 1], world_v[:, 0].max() + r)
        ext[body, 2] = min(ext[body, 2], world_v[:, 1].min() - r)
        ext[body, 3] = max(ext[body, 3], world_v[:, 1].max() + r)
    return ext


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_example_scene_runs_and_keeps_bodies_above_ground(name):
    path = SCENES / f"{name}.yaml"
    assert path.read_text().startswith("# yaml-language-server: $schema=../rbsim-schema.json\n")
    world = World.from_scene(load_scene(path))
    dynamic = world.model.body_type == BODY_DYNAMIC
    xmin, xmax, ymin, ymax = EXAMPLES[name]
    for _ in range(120):
        world.advance(1)  # raises NonFiniteState on a NaN or infinite state
        ext = body_extents(world)[dynamic]
        assert np.all(ext[:, 0] > xmin - MARGIN) and np.all(ext[:, 1] < xmax + MARGIN)
        assert np.all(ext[:, 2] > ymin - MARGIN) and np.all(ext[:, 3] < ymax + MARGIN)
    for a in world.state:
        assert np.all(np.isfinite(a))


def test_thin_rod_rests_on_thin_ground_instead_of_falling_through():
    # two radius-0 segments have no inside: without a skin, a rounding-sized dip turns
    # the normal over and the rod falls through the ground
    world = make_world(
        """
        version: 1
        world: {duration: 3}
        bodies:
          - {name: ground, type: static, shape: {segment: {a: [-10, 0], b: [10, 0]}}}
          - {name: flat, position: [0, 2], mass: 2, shape: {segment: {a: [-1, 0], b: [1, 0]}}}
          - {name: tilted, position: [3, 2], angle: 0.3, mass: 2,
             shape: {segment: {a: [-1, 0], b: [1, 0]}}}
        """
    )
    world.advance(world.scene.world.steps)
    y = world.state.body_x[1:, 1]
    # at rest on the ground, held off it by the segment skin (plus soft-contact give)
    assert np.all(y > 0.0) and np.all(y < 2 * SEGMENT_SKIN)
    assert np.abs(world.state.body_v[1:]).max() < 1e-3  # at rest, m/s


@pytest.mark.parametrize("e", [1.0, 0.5])
def test_elastic_bodies_resting_on_the_floor_with_threshold_zero_stay_at_rest(e):
    # an approach no faster than a substep of gravity is a rest, not an impact: the
    # ball and the box bounced by g h (0.041 m/s) every substep and reported it in
    # every frame, with that kinetic energy, while they did not move
    tr = rbsim.run(
        textwrap.dedent(f"""
        version: 1
        world: {{dt: 1/60, duration: 2}}
        solver: {{restitution_threshold: 0.0}}
        bodies:
          - {{name: floor, type: static, restitution: {e},
             shape: {{segment: {{a: [-5, 0], b: [5, 0]}}}}}}
          - {{name: ball, position: [0, 0.25], restitution: {e}, density: 1,
             shape: {{circle: {{radius: 0.25}}}}}}
          - {{name: box, position: [2, 0.25], restitution: {e}, density: 1,
             shape: {{box: {{size: [0.5, 0.5]}}}}}}
        """)
    )
    # rounding (the bodies start at rest, just touching): g h is 0.041 m/s
    assert np.abs(tr.velocity).max() < 1e-9
    assert tr.observables["kinetic_energy"].max() < 1e-15  # J


def test_cradle_resting_on_the_floor_keeps_its_energy_and_stays_down():
    # two balls strike five resting in a row on the floor, e = 1, threshold 0: the row
    # passes their velocity to its far end as without the floor (the resting floor
    # contacts are stopped again in the impacts' exact redo), and nothing hops (the floor
    # contacts bounced by g h every substep: momentum up 0.125 kg m/s at 3 s, the
    # energy up 1.6 mJ)
    balls = [("s1", -3.0, 2), ("s2", -2.5, 2)] + [(f"b{i}", 0.5 * i, 0) for i in range(5)]
    lines = "\n".join(
        f"  - {{name: {n}, position: [{x}, 0.25], velocity: [{v}, 0], material: steel,"
        " shape: {circle: {radius: 0.25}}}"
        for n, x, v in balls
    )
    tr = rbsim.run(
        "version: 1\n"
        "world: {gravity: [0, -9.81], dt: 1/120, duration: 3}\n"
        "solver: {restitution_threshold: 0.0}\n"
        "materials: {steel: {density: 7.8, friction: 0.0, restitution: 1.0}}\n"
        "bodies:\n"
        "  - {name: floor, type: static, material: steel,"
        " shape: {segment: {a: [-20, 0], b: [20, 0]}}}\n" + lines + "\n"
    )
    ke = tr.observables["kinetic_energy"]
    p = tr.observables["linear_momentum"]
    # rounding of the impacts' bounces (each keeps the energy exactly)
    assert np.abs(ke - ke[0]).max() < 1e-12 * ke[0]
    assert np.abs(p[:, 1]).max() < 1e-9 * p[0, 0]  # rounding, against 6.1 kg m/s along x
    # the two balls at the far end leave at 2 m/s, the rest are still
    v = tr.velocity[-1, np.argsort(tr.position[0, :, 0])]
    np.testing.assert_allclose(v[-2:, 0], 2.0, rtol=1e-9)  # rounding


@pytest.mark.parametrize("dimension", [2, 3])
def test_cradle_on_the_floor_at_the_default_threshold_passes_the_strike_on(dimension: int):
    # a ball at 2 m/s strikes four resting in a row on the floor, e = 1, μ = 0, the default
    # restitution threshold: the floor contacts carry the balls' weight into the step and
    # are stopped again in the impacts' exact redo (kept as loads, they joined the row's
    # impacts to the solve: the far ball left at 0.625 m/s, the row kept a third of the
    # energy)
    def vec(x: float, y: float) -> str:
        return f"[{x}, {y}]" if dimension == 2 else f"[{x}, {y}, 0]"

    ball = "circle: {radius: 0.5}" if dimension == 2 else "sphere: {radius: 0.5}"
    ground = "segment: {a: [-20, 0], b: [20, 0]}" if dimension == 2 else "plane: {}"
    starts = [(-3.0, 2.0), (0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]  # x (m), v (m/s)
    lines = "".join(
        f"  - {{name: b{k}, material: steel, position: {vec(x, 0.5)},"
        f" velocity: {vec(v, 0)}, shape: {{{ball}}}}}\n"
        for k, (x, v) in enumerate(starts)
    )
    dt = "1/60" if dimension == 2 else "1/240"
    tr = rbsim.run(
        f"version: 1\nworld: {{dimension: {dimension}, dt: {dt}, duration: 3}}\n"
        "materials: {steel: {density: 7800, friction: 0.0, restitution: 1.0}}\n"
        f"bodies:\n  - {{name: floor, type: static, material: steel, shape: {{{ground}}}}}\n"
        + lines
    )
    v = tr.velocity[-1, :, 0]
    np.testing.assert_allclose(v[-1], 2.0, rtol=1e-9)  # rounding of exact bounces
    assert np.abs(v[:-1]).max() < 1e-9  # m/s: the others still
