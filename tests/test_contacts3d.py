"""3D contacts end to end, through inline YAML scenes and the compiled engine: a sphere's
bounces by the restitution hypothesis (e = 0.5 and e = 1), a box resting on a plane, a
box on a 0.25 rad slope sliding and sticking, a stack of 10 unit boxes, and runs that
are deterministic and resume from a checkpoint bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rbsim
from rbsim.core import CoreWorld

from .conftest import scene_from

G = 9.81  # m/s²

BALL = """\
version: 1
world: {{dimension: 3, dt: {dt}, steps: {steps}}}
solver: {{substeps: 4, restitution_threshold: 0.2}}
materials:
  floor: {{density: 1000, friction: 0.5, restitution: {e}}}
bodies:
  - name: ground
    type: static
    material: floor
    shape: {{plane: {{normal: [0, 1, 0], offset: 0.0}}}}
  - name: ball
    position: [0, {h0}, 0]
    material: floor
    shape: {{sphere: {{radius: 0.1}}}}
"""


def run(text: str, steps: int, every: int = 1) -> tuple[CoreWorld, list]:
    """The world after `steps` steps of the inline scene, and its state every `every`
    steps (copies of x, v, w, q)."""
    world = CoreWorld.from_scene(scene_from(text))
    frames = []
    for _ in range(steps // every):
        world.advance(every)
        st = world.state
        frames.append((st.body_x.copy(), st.body_v.copy(), st.body_w.copy(), st.body_q.copy()))
    return world, frames


def apexes(y: np.ndarray) -> list[float]:
    """The heights (m) of the local maxima of a trajectory sampled every step."""
    return [float(y[i]) for i in range(1, len(y) - 1) if y[i - 1] < y[i] >= y[i + 1]]


def test_sphere_bounce_with_e_half_has_apex_ratio_a_quarter() -> None:
    h0, r = 1.0, 0.1  # m: drop height of the centre, radius
    text = BALL.format(dt=1 / 240, steps=1200, e=0.5, h0=h0)
    _w, frames = run(text, 1200)
    y = np.array([f[0][1, 1] for f in frames])
    tops = apexes(y)
    assert len(tops) >= 2
    ratio = (tops[0] - r) / (h0 - r)
    # the issue's ±0.02: e² = 0.25 on the integrator's discrete energy
    assert abs(ratio - 0.25) < 0.02, tops
    assert abs((tops[1] - r) / (tops[0] - r) - 0.25) < 0.02, tops


def test_elastic_sphere_keeps_its_apex_over_ten_bounces_and_never_gains_energy() -> None:
    h0, r = 1.0, 0.1
    text = BALL.format(dt=1 / 240, steps=2400, e=1.0, h0=h0)
    _w, frames = run(text, 2400)
    y = np.array([f[0][1, 1] for f in frames])
    v = np.array([f[1][1] for f in frames])
    tops = apexes(y)
    assert len(tops) >= 10, tops
    for top in tops[:10]:
        assert abs(top - h0) < 0.02 * (h0 - r), tops  # the issue's 2% of the drop
    # the energy per unit mass never above the start's, beyond the symplectic step's own
    # oscillation (|g| h |v| / 2: the discrete invariant is not ½v² + g y)
    energy = 0.5 * np.sum(v * v, axis=1) + G * y
    wobble = 0.5 * G * (1 / 240 / 4) * np.max(np.abs(v[:, 1])) * 4
    assert np.max(energy) <= G * h0 + wobble


@pytest.mark.parametrize(
    "shape",
    [
        "box: {size: [0.2, 0.2, 0.2]}",
        "box: {size: [1, 0.2, 1]}",
        "capsule: {radius: 0.1, a: [-0.2, 0, 0], b: [0.2, 0, 0]}",
    ],
    ids=["cube", "slab", "capsule"],
)
@pytest.mark.parametrize("e", [1.0, 0.5])
def test_a_face_landing_flat_bounces_as_a_sphere_does(shape: str, e: float) -> None:
    """A body 0.2 m thick dropped flat from 1 m onto the floor (dt 1/240: 1.8 cm a step at
    impact) bounces to e² of the drop, turning not at all. Its points' bounce owed the work
    gravity did during the impact's push, and was taken one point at a time: the first
    corner took it and tipped the body (a cube with e = 0.8 left at 1.2 m/s, not 3.5,
    spinning; apexes 0.18 and 0.008 of the drop for e = 1 and 0.5)."""
    tr = rbsim.run(
        "version: 1\nworld: {dimension: 3, dt: 1/240, duration: 2.5}\n"
        "bodies:\n  - {name: ground, type: static, restitution: 0, friction: 0.5,"
        " shape: {plane: {}}}\n"
        f"  - {{name: b, position: [0, 1.1, 0], density: 1000, friction: 0.5,"
        f" restitution: {e}, shape: {{{shape}}}}}\n"
    )
    tops = apexes(tr.position[:, 1, 1] - 0.1)
    assert len(tops) >= 2, tops
    # the sphere's figures (test above): e² on the integrator's discrete energy, ±2%
    assert abs(tops[0] - e * e) < 0.02, tops
    # rad/s: rounding, grown where a capsule comes to rest (1.5 - 15 rad/s before)
    assert np.abs(tr.angular_velocity[:, 1]).max() < 1e-3


def on_ground(world: str, material: str, bodies: str) -> str:
    """A 3D scene's YAML: `world` keys, one material `m` (`material` keys), a static
    ground plane y = 0 of it, then `bodies` (YAML list items)."""
    return (
        f"version: 1\nworld: {{dimension: 3, {world}}}\nmaterials:\n  m: {{{material}}}\n"
        "bodies:\n  - name: ground\n    type: static\n    material: m\n"
        "    shape: {plane: {normal: [0, 1, 0], offset: 0.0}}\n" + bodies
    )


BOX_ON_PLANE = on_ground(
    "dt: 0.016666666666666666, steps: 240",
    "density: 1000, friction: 0.6, restitution: 0.0",
    """\
  - name: box
    position: [0, 0.5, 0]
    rotation: {axis: [0, 1, 0], angle: 0.4}
    material: m
    shape: {box: {size: [1, 1, 1]}}
""",
)


def test_a_world_tensor_follows_a_rotation_set_between_steps() -> None:
    # the step's start makes a body's world inverse inertia tensor R I⁻¹ Rᵀ again only
    # where its rotation is not the one the last position update made it at: a rotation
    # set from outside (through the state's views) between two steps is taken
    text = BOX_ON_PLANE.replace("size: [1, 1, 1]", "size: [2, 1, 0.5]")
    w = CoreWorld.from_scene(scene_from(text))
    w.advance(3)
    c = w.contacts
    assert np.array_equal(c.body_inertia_q[1], w.state.body_q[1])  # made at the last update
    half = 0.3  # rad: half the new turn, about x
    w.state.body_q[1] = [np.cos(half), np.sin(half), 0.0, 0.0]
    w.stage("transform_shapes")
    qw, qx, qy, qz = w.state.body_q[1]
    rot = np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
            [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
            [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )
    want = rot @ w.model.body_inv_inertia[1] @ rot.T
    xx, yy, zz, xy, xz, yz = c.body_inv_inertia_world[1]
    got = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    np.testing.assert_allclose(got, want, rtol=1e-12)  # round-off of R's products


def test_box_resting_on_a_plane_stays() -> None:
    _w, frames = run(BOX_ON_PLANE, 240, every=10)
    x = np.array([f[0][1] for f in frames])
    assert np.all(0.5 - x[:, 1] < 1e-3)  # m: the issue's sag below 1 mm
    assert np.all(np.abs(x[:, 1] - 0.5) < 1e-3)
    assert np.max(np.hypot(x[:, 0], x[:, 2])) < 1e-6  # m: no drift
    w = np.array([f[2][1] for f in frames])
    assert np.max(np.abs(w)) < 1e-6  # rad/s: no turn


SLOPE = """\
version: 1
world: {{dimension: 3, dt: 0.004166666666666667, steps: {steps}}}
materials:
  m: {{density: 1000, friction: {mu}, restitution: 0.0}}
bodies:
  - name: slope
    type: static
    material: m
    shape: {{plane: {{normal: [{nx}, {ny}, 0], offset: 0.0}}}}
  - name: box
    position: [{px}, {py}, 0]
    rotation: {{axis: [0, 0, 1], angle: {theta}}}
    material: m
    shape: {{box: {{size: [0.5, 0.5, 0.5]}}}}
"""


def slope_run(mu: float, seconds: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A 0.5 m box resting on a plane tilted 0.25 rad about z (downhill: −x, down);
    returns the times (s), its distances downhill (m) and the slope angle."""
    theta = 0.25
    n = (-math.sin(theta), math.cos(theta))  # the plane's normal, tilted about z
    steps = round(seconds * 240)
    text = SLOPE.format(
        steps=steps, mu=mu, nx=n[0], ny=n[1], px=0.25 * n[0], py=0.25 * n[1], theta=theta
    )
    _w, frames = run(text, steps)
    x = np.array([f[0][1] for f in frames])
    down = np.array([-math.cos(theta), -math.sin(theta), 0.0])  # downhill along the slope
    s = (x - x[0]) @ down
    t = np.arange(1, steps + 1) / 240
    return t, s, theta


def test_box_slides_down_a_slope_at_g_sin_minus_mu_cos() -> None:
    mu = 0.1  # < tan 0.25 = 0.255: it slides
    t, s, theta = slope_run(mu, 2.0)
    late = t > 0.5  # after the contact has settled
    a = np.polyfit(t[late], s[late], 2)[0] * 2  # m/s²
    expected = G * (math.sin(theta) - mu * math.cos(theta))
    assert abs(a / expected - 1) < 0.05, a  # the issue's ±5%


def test_box_sticks_on_a_slope_when_mu_is_above_tan_theta() -> None:
    t, s, _theta = slope_run(0.4, 5.0)  # 0.4 > tan 0.25
    assert np.max(np.abs(s)) < 0.01  # m: the issue's slip below 1 cm in 5 s


STACK = on_ground(
    "dt: 0.016666666666666666, steps: 600",
    "density: 1000, friction: 0.6, restitution: 0.0",
    "  - stack: {count: 10, size: [1, 1, 1], origin: [0, 0.5, 0], material: m}\n",
)


def test_stack_of_ten_boxes_stands_ten_seconds() -> None:
    _w, frames = run(STACK, 600, every=30)
    top = np.array([f[0][10] for f in frames])
    assert np.max(np.hypot(top[:, 0], top[:, 2])) < 0.05  # m: the issue's 5 cm sideways
    assert np.all(9.5 - top[:, 1] < 0.05)  # m: the issue's sag below 5 cm


def jenga(layers: int, scale: float) -> str:
    """A Jenga tower: blocks 7.5 × 2.5 × 1.5 cm times `scale`, three a layer (2% apart),
    each layer crossed on the one below, on the ground plane, dt 1/60, 5 s."""
    length, width, height = 0.075 * scale, 0.025 * scale, 0.015 * scale
    blocks = []
    for k in range(layers):
        y = height / 2 + k * height
        for j in (-1, 0, 1):
            if k % 2 == 0:
                at, size = [j * width, y, 0.0], [0.98 * width, height, length]
            else:
                at, size = [0.0, y, j * width], [length, height, 0.98 * width]
            blocks.append(
                f"  - {{name: b{k}_{j + 1}, position: {at}, material: m,"
                f" shape: {{box: {{size: {size}}}}}}}\n"
            )
    return on_ground(
        "dt: 0.016666666666666666, steps: 300",
        "density: 600, friction: 0.5, restitution: 0.0",
        "".join(blocks),
    )


@pytest.mark.parametrize(("layers", "scale"), [(18, 10.0), (12, 1.0)])
def test_a_jenga_tower_stands(layers: int, scale: float) -> None:
    # (before the twenty-fourth session the large tower of 18 layers swayed ever wider and
    # fell, 13 cm off at 5 s; the real-sized one of 12 fell within a second)
    world = CoreWorld.from_scene(scene_from(jenga(layers, scale)))
    x0 = world.state.body_x[1:].copy()
    world.advance(300)
    drift = np.hypot(*(world.state.body_x[1:] - x0)[:, [0, 2]].T)
    assert drift.max() < 0.01 * scale  # m: under a tenth of a block's width
    assert np.abs(world.state.body_v[1:]).max() < 0.01  # m/s: at rest, not swaying


PILE = on_ground(
    "dt: 0.016666666666666666, steps: 120",
    "density: 1000, friction: 0.5, restitution: 0.3",
    """\
  - name: a
    position: [0, 0.6, 0]
    rotation: {axis: [1, 1, 0], angle: 0.5}
    material: m
    shape: {box: {size: [1, 0.5, 0.7]}}
  - name: b
    position: [0.3, 2.0, 0.2]
    angular_velocity: [1, 2, 3]
    material: m
    shape: {sphere: {radius: 0.4}}
  - name: c
    position: [-0.2, 3.2, -0.1]
    rotation: {axis: [0, 0, 1], angle: 0.3}
    material: m
    shape: {capsule: {a: [-0.4, 0, 0], b: [0.4, 0, 0], radius: 0.2}}
""",
)


def state_bytes(world: CoreWorld) -> bytes:
    st = world.state
    return b"".join(np.ascontiguousarray(a).tobytes() for a in st)


def test_3d_contact_runs_are_deterministic_and_resume_bit_identically() -> None:
    a, _ = run(PILE, 120)
    b, _ = run(PILE, 120)
    assert a.contact_count > 0
    assert state_bytes(a) == state_bytes(b)
    half = CoreWorld.from_scene(scene_from(PILE))
    half.advance(60)
    saved = half.engine.save_checkpoint()
    resumed = CoreWorld.from_scene(scene_from(PILE))
    resumed.engine.load_checkpoint(saved)
    resumed.advance(60)
    assert state_bytes(resumed) == state_bytes(a)


def test_storage_of_a_world_restored_from_a_checkpoint_reads_only_batches_it_packed() -> None:
    # a checkpoint carries the waves' counts but not the face batches, which every step
    # packs anew: storage() of a world that had not stepped read the saved world's count
    # of batches from its own empty list, and the process crashed
    stepped = CoreWorld.from_scene(scene_from(STACK))
    stepped.advance(30)
    assert len(stepped.storage.face_batch_points) > 0
    fresh = CoreWorld.from_scene(scene_from(STACK))
    fresh.engine.load_checkpoint(stepped.engine.save_checkpoint())
    assert fresh.storage.face_batch_points == []
    fresh.advance(1)
    assert len(fresh.storage.face_batch_points) > 0


def test_solve_waves_of_a_world_restored_from_a_checkpoint_asks_for_packed_waves() -> None:
    # the same: solve_waves on a restored world solved batches it had not packed, past
    # the end of its empty lists (the process crashed); now it says so, and solves once
    # find_waves has packed them
    stepped = CoreWorld.from_scene(scene_from(STACK))
    stepped.advance(30)
    fresh = CoreWorld.from_scene(scene_from(STACK))
    fresh.engine.load_checkpoint(stepped.engine.save_checkpoint())
    args = {"inv_h": 240.0, "use_bias": True, "shift": 0.0, "threshold": 1.0}
    with pytest.raises(ValueError, match="not packed"):
        fresh.engine.stage("solve_waves", args)
    assert fresh.engine.stage("find_waves") > 0
    fresh.engine.stage("solve_waves", args)


# A capsule 2.5 cm long and 5 mm thick, of density 10 (6.6 mg), e = 0.9, falling at 6 m/s
# onto the plane at dt 1/60 (a step moves it 5 lengths) and landing on one end.
SPINNER = """\
version: 1
world: {dimension: 3, dt: 1/60, duration: 1}
materials:
  light: {density: 10, friction: 0.1, restitution: 0.9}
  ground: {density: 1000, friction: 0.5, restitution: 0.3}
bodies:
  - {name: ground, type: static, material: ground, shape: {plane: {normal: [0, 1, 0], offset: 0.0}}}
  - name: needle
    position: [1.1194, 0.7923, -1.8453]
    rotation: {axis: [1.891, 0.601, -0.745], angle: 2.483}
    velocity: [0.868, -6.199, 1.740]
    angular_velocity: [0.024, 0.011, -0.181]
    shape: {capsule: {a: [-0.0125, 0, 0], b: [0.0125, 0, 0], radius: 0.0027}}
    material: light
"""


def body_energies(world: CoreWorld, steps: int) -> list[float]:
    """Body 1's energy (J: kinetic, linear and angular, and its height's under 9.81 m/s²)
    before each of `steps` steps, stepping the world."""
    m = world.model.body_mass[1]
    energies = []
    for _ in range(steps):
        eng = world.engine
        v, w, ang, x = eng.body_v[1], eng.body_w[1], eng.body_l[1], eng.body_x[1]
        energies.append(0.5 * m * (v @ v) + 0.5 * (w @ ang) + m * 9.81 * x[1])
        world.advance(1)
    return energies


def test_a_small_capsule_landing_on_one_end_never_gains_energy() -> None:
    # The impact spins it up to 1000 rad/s, 4 rad a substep. It spun faster and faster:
    # the passes stepped by the rows' effective masses (the step's start's tensors) while
    # pushing through the tensors at its rotation now, the restitution stage alike, and
    # the rotation update swung its energy up (20 times its start's), until a step threw
    # it 1e9 m. Its energy (kinetic and height) stays at or below the start's (rtol: the
    # integrator's round-off), and it stays above the plane.
    world = CoreWorld.from_scene(scene_from(SPINNER))
    energies = body_energies(world, 60)
    assert max(energies) <= energies[0] * (1.0 + 1e-9)
    assert world.engine.body_x[1][1] > 0.0


# Thin bodies thrown spinning onto the ground, where they turn up to half a radian a
# substep: plates 2.6 to 6.8 cm long and 2 to 5 mm thick dropped on a floor slab and
# thrown onto the plane, a needle and a long stick with two small sides, and a capsule
# 20 times longer than thick. Each: a material (density, friction, restitution), the
# ground, the body's place, turn (axis, angle), velocity and spin, its shape (a box's
# size, or a shape), and the time step (m, rad, m/s, rad/s, s).
PLANE = "shape: {plane: {normal: [0, 1, 0], offset: 0.0}}"
THIN_BODIES = {
    "e0.8 dropped": (
        (113.2, 0.1, 0.8),
        "position: [0, -0.5, 0], shape: {box: {size: [4, 1, 4]}}",
        ([-0.04453, 0.30429, -0.14645], ([1.719, -0.530, -0.136], 2.534), [0, 0, 0], [0, 0, 0]),
        [0.016788275159138225, 0.003803656406098583, 0.06758112558814332],
        "1/60",
    ),
    "e0.5 thrown": (
        (500, 0.2, 0.5),
        PLANE,
        (
            [0, 0.3923, 0],
            ([-0.289, 0.070, -0.972], 0.571),
            [-0.862, -0.105, 0],
            [1.34, -33.997, 7.6],
        ),
        [0.00473, 0.01113, 0.06391],
        "1/60",
    ),
    "e0.9 stick": (
        (500, 0.73, 0.9),
        PLANE,
        ([0, 0.5047, 0], ([0.416, 1.752, 0.778], 1.359), [1.448, -0.169, 0], [4.822, 1.64, -2.218]),
        [0.00198, 0.00427, 0.02577],
        "1/60",
    ),
    "e0.5 needle": (
        (500, 0.41, 0.5),
        PLANE,
        (
            [0, 0.4099, 0],
            ([2.151, 0.469, -0.194], 2.19),
            [-0.514, -0.035, 0],
            [16.741, -13.009, -39.196],
        ),
        [0.00094, 0.00091, 0.01623],
        "1/60",
    ),
    "e0.5 long stick": (
        (500, 0.24, 0.5),
        PLANE,
        (
            [0, 0.5184, 0],
            ([-1.242, 0.993, -0.418], 2.043),
            [0.319, -0.744, 0],
            [27.097, -52.984, 3.208],
        ),
        [0.00793, 0.01424, 0.25893],
        "1/60",
    ),
    "e0 capsule needle": (
        (4877, 0.25, 0.0),
        PLANE,
        (
            [0, 0.4956, 0],
            ([-0.057, -2.104, -0.781], 0.642),
            [-0.491, -0.233, 0.664],
            [36.459, 51.242, 67.271],
        ),
        "{capsule: {a: [-0.02169, 0, 0], b: [0.02169, 0, 0], radius: 0.00106}}",
        "1/240",
    ),
}


def thin_scene(name: str) -> str:
    """THIN_BODIES[name] as a scene: the ground and the body, 2 s."""
    (density, friction, e), ground, (x, (axis, angle), v, w), shape, dt = THIN_BODIES[name]
    if isinstance(shape, list):
        shape = f"{{box: {{size: {shape}}}}}"
    return f"""\
version: 1
world: {{dimension: 3, dt: {dt}, duration: 2}}
materials:
  m: {{density: {density}, friction: {friction}, restitution: {e}}}
bodies:
  - {{name: ground, type: static, material: m, {ground}}}
  - name: body
    material: m
    position: {x}
    rotation: {{axis: {axis}, angle: {angle}}}
    velocity: {v}
    angular_velocity: {w}
    shape: {shape}
"""


@pytest.mark.parametrize("name", list(THIN_BODIES))
def test_a_thin_body_landing_spinning_never_gains_energy(name: str) -> None:
    # Landing spinning at up to 140 rad/s, the plates bounce in the restitution stage,
    # which pushed through the tensors at the rotation now but took a face block's K, and
    # the friction of an impact its tangent masses, at the step's start's: each block
    # overshot, the face's other pair answered 27 times larger, and the first plate left
    # the ground at 25.7 m/s, 116 times its start's energy, the second at 1e19 m/s; with
    # the blocks mended, the stick's impact friction still threw it up with 7 times its
    # energy (724 before). The needle, the long stick and the capsule gained 390, 49 and
    # 96 times in the passes: they stepped ω by the rows' tensors of the step's start
    # while the position update made ω from L at the rotation now, 30,000 rad/s where
    # the passes saw 190, until the rows of a body turned far were made again within the
    # step (refresh_turned_rows). Its energy stays at or below the start's (rtol: the
    # integrator's round-off), above the plane.
    world = CoreWorld.from_scene(scene_from(thin_scene(name)))
    energies = body_energies(world, world.scene.world.steps)
    assert max(energies) <= energies[0] * (1.0 + 1e-9)
    assert world.engine.body_x[1][1] > 0.0


SPINNING_BOX = """\
version: 1
world: {dimension: 3, dt: 1/120, steps: 240, gravity: [0, 0, 0]}
solver: {substeps: 2, iterations: 2}
materials:
  m: {density: 1000, friction: 0.5, restitution: 1.0}
bodies:
  - {name: ground, type: static, material: m, shape: {plane: {normal: [0, 1, 0], offset: 0}}}
  - name: box
    material: m
    position: [0, 1.0, 0]
    rotation: {axis: [0.3, 1, 0.2], angle: 0.7}
    velocity: [0, -2, 0]
    angular_velocity: [80, 0, 10]
    shape: {box: {size: [0.5, 0.4, 0.3]}}
"""


def test_a_box_spinning_fast_onto_a_wall_never_leaves_with_more_energy() -> None:
    # No gravity, e = 1: a box spinning at 80 rad/s thrown at 2 m/s onto the plane meets
    # it at several points of a face within a step, each point's bounce exact, and the
    # others' bounces turned it into one again: it left with 8.5% more kinetic energy
    # than it came with. A body that bounces only off static bodies now leaves with no
    # more than it met them with (restitution.cpp, hold_free_energy). Its kinetic energy
    # stays at or below the start's (rtol: the integrator's round-off; its free turn
    # between the bounces keeps it within 1.2e-4 below).
    world = CoreWorld.from_scene(scene_from(SPINNING_BOX))
    m = world.model.body_mass[1]
    energies = []
    for _ in range(world.scene.world.steps):
        eng = world.engine
        v, w, ang = eng.body_v[1], eng.body_w[1], eng.body_l[1]
        energies.append(0.5 * m * (v @ v) + 0.5 * (w @ ang))
        world.advance(1)
    assert max(energies) <= energies[0] * (1.0 + 1e-9)
    assert world.engine.body_v[1][1] > 0.0  # (it bounced)


@pytest.mark.parametrize("e", [0.0])
def test_sphere_with_e_zero_comes_to_rest_on_the_plane(e: float) -> None:
    text = BALL.format(dt=1 / 240, steps=480, e=e, h0=1.0)
    _w, frames = run(text, 480)
    y = np.array([f[0][1, 1] for f in frames])
    assert abs(y[-1] - 0.1) < 1e-3  # m: resting on its surface, within the soft sag
    assert not apexes(y[len(y) // 2 :])  # no bounce


def test_elastic_sphere_and_box_resting_on_the_plane_with_threshold_zero_stay_at_rest() -> None:
    # e = 1, every approach bounces: a rest (an approach of one substep of gravity) is no
    # impact. The box bounced by g h every substep on its four corners, one after the
    # other, and drifted sideways at 1 cm/s while turning
    text = on_ground(
        "dt: 0.016666666666666666, duration: 2",
        "density: 1, friction: 0.5, restitution: 1.0",
        """\
  - {name: ball, position: [0, 0.25, 0], material: m, shape: {sphere: {radius: 0.25}}}
  - {name: box, position: [2, 0.25, 0], material: m, shape: {box: {size: [0.5, 0.5, 0.5]}}}
""",
    )
    tr = rbsim.run(text, overrides=["solver.restitution_threshold=0"])
    # rounding (the bodies start at rest, just touching): g h is 0.041 m/s
    assert np.abs(tr.velocity).max() < 1e-9
    assert np.abs(tr.angular_velocity).max() < 1e-9


def test_thin_plate_landing_tilted_on_a_plane_comes_to_rest_on_its_lower_face() -> None:
    # a 1 m x 1 cm steel plate, thinner than the speculative distance (2 cm), dropped
    # 2.4 cm tilted by 30 mrad: its upper face's corners were within reach too, the
    # reduction to four kept some of them over the lower ones, and the plate rested on
    # two corners and points 1 cm up: it sank 2 - 3 mm into the ground and rocked at up
    # to 0.12 m/s for ever
    text = on_ground(
        "dt: 0.008333333333333333, duration: 2",
        "density: 7800, friction: 0.2, restitution: 0.0",
        "  - {name: plate, position: [0, 0.05, 0], rotation: {axis: [1, 0, 1], angle: 0.03},\n"
        "     material: m, shape: {box: {size: [1.0, 0.01, 1.0]}}}\n",
    )
    tr = rbsim.run(text)
    late, plate = tr.time >= 1.0, tr.body("plate")  # s: landed at 0.05 s
    y = tr.position[late, plate, 1]
    # the soft contact's sag under 78 kg (tens of µm), against the 3 mm it sank
    assert np.all(np.abs(y - 0.005) < 1e-4), (y.min(), y.max())
    assert np.linalg.norm(tr.velocity[late, plate], axis=1).max() < 1e-3  # m/s: at rest
    assert np.linalg.norm(tr.angular_velocity[late, plate], axis=1).max() < 1e-2  # rad/s


TURNTABLE = """\
version: 1
name: turntable
world: {dimension: 3, gravity: [0, -9.81, 0], dt: 1/60, duration: 8}
materials:
  rubber: {density: 500, friction: 0.5, restitution: 0.0}
bodies:
  - name: table
    type: kinematic
    material: rubber
    angular_velocity: [0, 2, 0]
    shape: {box: {size: [3, 0.2, 3]}}
  - {name: parcel, material: rubber, position: [0.5, 0.2, 0], shape: {box: {size: [0.2, 0.2, 0.2]}}}
"""


def test_a_box_on_a_turntable_rides_round_instead_of_creeping_off() -> None:
    # ω² r = 2 m/s² < μ g = 4.9 m/s²: the box rides round at r = 0.5 m. With the table's
    # levers held at the step's start the box was given the table's velocity there for the
    # whole step and crept outward by r (ω dt)² / 2 a step: r = 0.68 m at 8 s
    tr = rbsim.run(TURNTABLE)
    box = tr.body("parcel")
    r = np.hypot(tr.position[:, box, 0], tr.position[:, box, 2])
    # what is left: the table's turn over a step is taken in its first substep, where
    # friction bounds the impulse (2.6 mm/s; 1 cm of the first second's slip)
    assert r.max() < 0.55, r.max()
    # and it turns with the table: its angle from the centre against the table's 2 t
    angle = np.unwrap(np.arctan2(-tr.position[:, box, 2], tr.position[:, box, 0]))
    late = tr.time >= 1.0
    lag = 2.0 * tr.time[late] - angle[late]
    assert np.ptp(lag) < 0.05, np.ptp(lag)


def struck(turn: str, e: float = 0.0) -> str:
    """A 0.1 m cube thrown at 30 m/s into a wall, turned by `turn` (a quaternion), μ = 0.5,
    no gravity."""
    return f"""\
version: 1
name: struck
world: {{dimension: 3, dt: 1/60, duration: 0.5, gravity: [0, 0, 0]}}
materials:
  m: {{density: 1000, friction: 0.5, restitution: {e}}}
bodies:
  - {{name: wall, type: static, position: [1.5, 0, 0], material: m,
     shape: {{box: {{size: [0.2, 4, 4]}}}}}}
  - {{name: cube, orientation: {turn}, velocity: [30, 0, 0], material: m,
     shape: {{box: {{size: [0.1, 0.1, 0.1]}}}}}}
"""


# edge first: 45° about y (the edge vertical); corner first: then atan(1/√2) about z
EDGE_FIRST = "[0.9238795325112867, 0, 0.3826834323650898, 0]"
CORNER_FIRST = "[0.8804762392171493, -0.11591689595929512, 0.3647051996310009, 0.2798481423331213]"


@pytest.mark.parametrize("turn", [EDGE_FIRST, CORNER_FIRST], ids=["edge", "corner"])
def test_a_cube_struck_edge_or_corner_first_into_a_wall_stops_dead(turn: str) -> None:
    # the impulse passes through the centre, e = 0: the cube stops, neither turning nor
    # sliding. The points one after the other (where the face's block would pull at its
    # far corners, within reach but not touching) left it at 1.8 rad/s, sliding along its
    # edge at 0.3 m/s (corner first: 3.7 rad/s)
    tr = rbsim.run(struck(turn))
    late, cube = tr.time >= 0.3, tr.body("cube")
    # rounding (measured: 6e-15 m/s, 7e-14 rad/s)
    assert np.linalg.norm(tr.velocity[late, cube], axis=1).max() < 1e-9
    assert np.linalg.norm(tr.angular_velocity[late, cube], axis=1).max() < 1e-9


@pytest.mark.parametrize("turn", [EDGE_FIRST, CORNER_FIRST], ids=["edge", "corner"])
def test_a_cube_struck_edge_or_corner_first_bounces_straight_back(turn: str) -> None:
    # e = 0.5 through the centre: 15 m/s straight back, not turning. The restitution stage
    # took the edge's two leading corners one after the other: 3 m/s back, sliding at 3 - 5
    # m/s and turning at 40 - 70 rad/s
    tr = rbsim.run(struck(turn, 0.5))
    late, cube = tr.time >= 0.3, tr.body("cube")
    # rounding, and the bounce's target on the discrete trajectory (exactly −e v here)
    assert np.abs(tr.velocity[late, cube] - [-15.0, 0.0, 0.0]).max() < 1e-9
    assert np.linalg.norm(tr.angular_velocity[late, cube], axis=1).max() < 1e-9
