"""The 3D part of `make bench`: µs per step of rbsim, MuJoCo and PyBullet on the same
3D contact scenes, and the ratios rbsim / MuJoCo and rbsim / PyBullet, in one process.

Scenes (SCENES, written here as YAML text; every one on the plane y = 0, gravity
9.81 m/s² down y, friction 0.6, restitution 0, density 1000 kg/m³, dt = 1/240 s, the
step MuJoCo was measured at in issue 16): a stack of 10 unit boxes, a 5-layer square
pyramid of unit boxes (55), 100 boxes of 0.5 m dropped tumbling in a heap, 1000 spheres
of radius 0.1 m poured into a 4 m box, a 10 × 10 grid of stacks of 3 boxes of 0.5 m,
200 capsules dropped in a heap, a wall of 96 bricks struck by a ball, a heap of 50
boxes, 50 spheres and 50 capsules of several sizes (every pair kind), and a heap of 120
convex pebbles (hull against hull: MuJoCo's meshes, PyBullet's convex meshes). FROM_REST of
them are also timed block by block from step 0 against MuJoCo (rest_table): the
landing, the impact, what the settled window leaves out; and so are the project's own 3D
example scenes (EXAMPLES), each at its own dt.

Each engine steps the scene from rest: WARMUP steps (untimed), then REPEATS timed blocks
of STEPS steps, the engines' blocks taken in turn (rbsim's, MuJoCo's, PyBullet's, and
again), so that a slow spell of the shared machine falls on all of them alike. A block's
time is the CPU time of the thread that steps (on a shared machine less noisy than wall
time; each engine here steps on that one thread, so its CPU time is the engine's; the
process's CPU time would also count numpy's BLAS threads, which a scene's set-up wakes
and which spin on the other core for a while after: they made rbsim's 10-box stack read
27 µs a step where it took 21). The table gives each engine's median block and, as the
ratio, the median over the rounds of rbsim's block over the other's. The state at the
end of that window is the "end" of the table. Settings, each engine's own defaults at that dt:
- rbsim: the scene's solver (4 substeps × (1 solve + 1 relax)), its 0.5 cm slop.
- MuJoCo (`mjcf_contacts`): one mj_step per step, its defaults: Euler integrator,
  Newton solver, 100 iterations, tolerance 1e-8, pyramidal cone, condim 3, solref
  (0.02, 1), solimp (0.9, 0.95, 0.001, 0.5, 2), margin 0; friction (μ, 0.005, 0.0001)
  per geom (MuJoCo takes the larger of a pair; one material here).
- PyBullet (if installed): one stepSimulation per step at fixedTimeStep = dt, its
  defaults: 50 solver iterations, no substeps; friction μ, restitution 0 per body.
Every engine starts from the scene's velocities (the wall's ball thrown at 15 m/s: a free
joint's qvel, PyBullet's resetBaseVelocity; until 2026-12-04 MuJoCo and PyBullet started
every body at rest, and the ball fell in front of a wall it never struck).
Masses and inertias are rbsim's (the MJCF's `inertial`, PyBullet's baseMass and the
shapes' own inertia, which for boxes and spheres of uniform density are the same; for a
pebble PyBullet takes its box's inertia about the body's frame origin, a few mm from
its centre of mass).
"Stands" (stack scenes): the top boxes' largest sideways move (m, in x and z) and sag
(m, down y) at the end of the window; "contacts": contact points at the end (rbsim's
manifold points, MuJoCo's d.ncon, PyBullet's getContactPoints).
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence

import numpy as np

from rbsim.engines import make_engine
from rbsim.scene import Scene, load_scene, load_scene_text
from rbsim.scene import types as T
from rbsim.scene.compile import Model, State, build
from rbsim.scene.geometry3d import quat_matrix
from rbsim.scene.library import scenes_dir
from rbsim.tools.measure import interleaved_block_times, median_ratio

from . import the_round

try:
    import mujoco
except ImportError:  # the optional extra `mujoco`
    mujoco = None


def _import_pybullet():  # noqa: ANN202 - the module, or None
    """pybullet, imported with its "pybullet build time" line (C's printf at import,
    flushed at exit, in the middle of the table) sent to /dev/null; None when absent."""
    import ctypes
    import os
    import sys

    sys.stdout.flush()
    saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    try:
        import pybullet
    except ImportError:  # the `bench` extra: pip install -e '.[bench]' (make bench does)
        return None
    finally:
        ctypes.CDLL(None).fflush(None)  # C's buffer, while fd 1 is still /dev/null
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)
    return pybullet


pybullet = _import_pybullet()

DT = "1/240"
WARMUP = 240
STEPS = 60
REPEATS = 9
FRICTION = 0.6

HEAD = f"""\
version: 1
name: {{name}}
world: {{{{dimension: 3, gravity: [0, -9.81, 0], dt: {DT}, duration: 10}}}}
materials:
  wood: {{{{density: 1000, friction: {FRICTION}, restitution: 0.0}}}}
bodies:
  - name: ground
    type: static
    shape: {{{{plane: {{{{normal: [0, 1, 0], offset: 0.0}}}}}}}}
    material: wood
"""


def _head(name: str) -> str:
    return HEAD.format(name=name)


def _turned(
    name: str,
    position: Sequence[float],
    axis: Sequence[float],
    angle: float,
    shape: str,
    digits: int = 3,
) -> str:
    """One body's YAML lines: at `position` (m, 3 decimals), turned by `angle` (rad) about
    `axis` (both to `digits` decimals), of the inline `shape`, in wood."""
    x, y, z = position
    a = ", ".join(f"{c:.{digits}f}" for c in axis)
    return (
        f"  - name: {name}\n    position: [{x:.3f}, {y:.3f}, {z:.3f}]\n"
        f"    rotation: {{axis: [{a}], angle: {angle:.{digits}f}}}\n"
        f"    shape: {shape}\n    material: wood\n"
    )


def stack10() -> str:
    """A stack of 10 unit boxes resting on the plane."""
    return _head("stack10") + (
        "  - stack: {count: 10, size: [1, 1, 1], origin: [0, 0.5, 0], material: wood}\n"
    )


def pyramid55() -> str:
    """A square pyramid of 5 layers of unit boxes (25 + 16 + 9 + 4 + 1 = 55)."""
    return _head("pyramid55") + (
        "  - pyramid: {base: 5, size: [1, 1, 1], origin: [0, 0.5, 0], material: wood}\n"
    )


def tumble100() -> str:
    """100 boxes of 0.5 m in a 5 × 4 × 5 heap, each turned by its own angle about its own
    axis (a fixed sequence), dropped from 0.5 m up onto the plane."""
    lines = []
    k = 0
    for i in range(5):
        for j in range(4):
            for m in range(5):
                axis = [math.sin(1.3 * k + 0.2), math.cos(0.7 * k), math.sin(2.1 * k + 1.0)]
                position = (-1.8 + 0.9 * i, 0.9 + 0.9 * j, -1.8 + 0.9 * m)
                box = "{box: {size: [0.5, 0.5, 0.5]}}"
                lines.append(_turned(f"box{k}", position, axis, 0.37 * k % math.pi, box, 4))
                k += 1
    return _head("tumble100") + "".join(lines)


def spheres1000() -> str:
    """1000 spheres of radius 0.1 m in a 10 × 10 × 10 block, 0.3 m apart, poured into a
    4 m × 4 m box (four static walls 0.2 m thick, 4 m high)."""
    walls = []
    for name, pos, size in (
        ("wall_x0", (-2.1, 2, 0), (0.2, 4, 4.4)),
        ("wall_x1", (2.1, 2, 0), (0.2, 4, 4.4)),
        ("wall_z0", (0, 2, -2.1), (4.0, 4, 0.2)),
        ("wall_z1", (0, 2, 2.1), (4.0, 4, 0.2)),
    ):
        walls.append(
            f"  - name: {name}\n    type: static\n    position: [{pos[0]}, {pos[1]}, {pos[2]}]\n"
            f"    shape: {{box: {{size: [{size[0]}, {size[1]}, {size[2]}]}}}}\n"
            "    material: wood\n"
        )
    spheres = []
    for k in range(1000):
        i, j, m = k // 100, k // 10 % 10, k % 10
        # each sphere shifted up to 5 cm sideways (a fixed sequence): aligned columns
        # would land exactly on top of each other and stand as 100 towers
        dx, dz = 0.05 * math.sin(2.3 * k + 0.4), 0.05 * math.cos(1.7 * k + 0.9)
        x, y, z = -1.35 + 0.3 * i + dx, 0.4 + 0.3 * j, -1.35 + 0.3 * m + dz
        spheres.append(
            f"  - name: ball{k}\n    position: [{x:.4f}, {y:.4f}, {z:.4f}]\n"
            "    shape: {sphere: {radius: 0.1}}\n    material: wood\n"
        )
    return _head("spheres1000") + "".join(walls) + "".join(spheres)


def stacks100() -> str:
    """A 10 × 10 grid of stacks of 3 boxes of 0.5 m, 1 m apart."""
    return _head("stacks3x100") + (
        "  - grid:\n      count: [10, 3, 10]\n      spacing: [1.0, 0.5, 1.0]\n"
        "      origin: [-4.5, 0.25, -4.5]\n      shape: {box: {size: [0.5, 0.5, 0.5]}}\n"
        "      material: wood\n"
    )


def capsules200() -> str:
    """200 capsules (0.4 m between their ends' centres, radius 0.1 m) in a 5 × 8 × 5 heap,
    each turned its own way (a fixed sequence), dropped from up to 4.7 m onto the plane."""
    lines = []
    for k in range(200):
        i, j, m = k // 40, k // 5 % 8, k % 5
        axis = [math.sin(1.1 * k + 0.3), math.cos(0.9 * k), math.sin(1.7 * k + 0.5)]
        position = (-1.6 + 0.8 * i, 0.5 + 0.6 * j, -1.6 + 0.8 * m)
        capsule = "{capsule: {a: [-0.2, 0, 0], b: [0.2, 0, 0], radius: 0.1}}"
        lines.append(_turned(f"c{k}", position, axis, 0.41 * k % 3.1, capsule))
    return _head("capsules200") + "".join(lines)


def wall96() -> str:
    """A wall of 12 × 8 bricks (0.5 × 0.25 × 0.3 m) standing on the plane, struck at 1 m
    up by a ball of radius 0.3 m thrown at 15 m/s (it arrives after about 0.2 s)."""
    return _head("wall96") + (
        "  - grid: {count: [12, 8, 1], spacing: [0.5, 0.25, 0.3], origin: [-2.75, 0.125, 0],\n"
        "           shape: {box: {size: [0.5, 0.25, 0.3]}}, material: wood}\n"
        "  - {name: ball, position: [0, 1.0, -3], velocity: [0, 0, 15],\n"
        "     shape: {sphere: {radius: 0.3}}, material: wood}\n"
    )


def mixed150() -> str:
    """A heap of 50 boxes (sides 0.3 to 0.7 m), 50 spheres (radius 0.1 to 0.3 m) and 50
    capsules (0.5 m between their ends' centres, radius 0.12 m), in turn, 6 layers of 5 × 5
    a metre apart, each turned its own way (a fixed sequence), dropped from up to 5.6 m
    onto the plane: every pair kind at once, light spheres under heavy boxes."""
    lines = []
    for k in range(150):
        i, j, m = k % 5, (k // 5) % 6, k // 30
        x = -2 + 1.0 * i + 0.1 * math.sin(k)
        y, z = 0.6 + 1.0 * j, -2 + 1.0 * m + 0.1 * math.cos(k)
        axis = [math.sin(0.9 * k + 0.1), math.cos(1.3 * k), math.sin(0.5 * k + 2.0)]
        if k % 3 == 0:
            sx, sy = 0.3 + 0.4 * ((k * 7) % 5) / 4, 0.3 + 0.3 * ((k * 3) % 4) / 3
            shape = f"{{box: {{size: [{sx:.2f}, {sy:.2f}, 0.4]}}}}"
        elif k % 3 == 1:
            shape = f"{{sphere: {{radius: {0.1 + 0.2 * ((k * 5) % 7) / 6:.3f}}}}}"
        else:
            shape = "{capsule: {a: [-0.25, 0, 0], b: [0.25, 0, 0], radius: 0.12}}"
        lines.append(_turned(f"b{k}", (x, y, z), axis, 0.53 * k % 3.0, shape))
    return _head("mixed150") + "".join(lines)


def pebbles120() -> str:
    """120 convex pebbles, each the hull of 8 to 12 points drawn about an ellipsoid of
    semi-axes 0.2 to 0.3 m (a fixed seed), in 4 layers of 5 × 6 a metre apart, each turned
    its own way, dropped from up to 4.6 m onto the plane: hull against hull."""
    rng = np.random.default_rng(7)
    lines = []
    for k in range(120):
        count = 8 + k % 5
        d = rng.normal(size=(count, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        points = d * np.array([0.25, 0.18, 0.2]) * (0.8 + 0.4 * rng.random((count, 1)))
        vertices = ", ".join(f"[{a:.3f}, {b:.3f}, {c:.3f}]" for a, b, c in points)
        x, y, z = -2 + 1.0 * (k % 5), 0.6 + 0.8 * ((k // 5) % 6), -1.5 + 1.0 * (k // 30)
        axis = [math.sin(0.9 * k + 0.1), math.cos(1.3 * k), math.sin(0.5 * k + 2.0)]
        shape = f"{{convex: {{vertices: [{vertices}]}}}}"
        lines.append(_turned(f"p{k}", (x, y, z), axis, 0.53 * k % 3.0, shape))
    return _head("pebbles120") + "".join(lines)


SCENES: dict[str, Callable[[], str]] = {
    "stack10": stack10,
    "pyramid55": pyramid55,
    "tumble100": tumble100,
    "spheres1000": spheres1000,
    "stacks3x100": stacks100,
    "capsules200": capsules200,
    "wall96": wall96,
    "mixed150": mixed150,
    "pebbles120": pebbles120,
}
# scenes also timed from rest, block by block (rest_table): what the settled window after
# WARMUP leaves out (the landing of a heap, a wall standing and then struck)
FROM_REST = ["tumble100", "capsules200", "wall96", "stack10", "mixed150", "pebbles120"]
# The project's own 3D example scenes (scenes/3d/), timed from rest the same way at their
# own dt: what a user meets first, beside the bench's heaps at 1/240 s. The collapsing
# pile (39 bodies, dt 1/120) read 0.38 - 1.15 of MuJoCo's time block by block on
# 2026-12-06, where the bench's scenes read 0.11 - 0.73: a small scene's contacts chain
# one on another (a face solved on its own costs about twice its share of a lane's)
EXAMPLES = ["collapsing_pile"]
REST_BLOCKS = 8  # blocks of STEPS steps from step 0: the first 2 s
# runs from rest of each scene, each in fresh engines, run k on the scene with gravity
# changed by k parts in 10⁹ (bench.the_round: a landing heap is chaotic, and one
# trajectory's time is one draw); a block's ratio is the median over the runs (one run's
# block of 60 steps, 4 to 15 ms, is within reach of the shared machine's slow spells: the
# same block read 0.38 to 0.60 in three runs)
REST_RUNS = 3
# MuJoCo options other than its defaults, per scene (stated in the table): on the 1000
# spheres its default Newton solver took 340 ms per step at 1764 contacts and climbing
# (2.25 s in), its CG solver 40-80 ms with 2400 (measured here, 2026-12-02)
MUJOCO_OPTIONS = {"spheres1000": {"solver": "CG"}}
# scenes whose top boxes should stand: the table reports their move and sag
STANDING = {"stack10", "pyramid55", "stacks3x100"}


def load(name: str, overrides: list[str] | None = None) -> Scene:
    """The bench scene `name` (a key of SCENES, or of EXAMPLES: scenes/3d/<name>.yaml),
    resolved."""
    if name in EXAMPLES:
        return load_scene(scenes_dir("3d", f"{name}.yaml"), overrides or ())
    return load_scene_text(SCENES[name](), f"bench3d/{name}.yaml", overrides or ())


def _num(x: float) -> str:
    return repr(float(x))


def _nums(values: np.ndarray) -> str:
    return " ".join(_num(v) for v in np.ravel(values))


def quat_from_z(n: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of the shortest rotation taking +z to unit n."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, n))
    if c < -1.0 + 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])
    q = np.concatenate([[1.0 + c], np.cross(z, n)])
    return q / np.linalg.norm(q)


def _geoms(shape, friction: str, name: str) -> list[str]:  # noqa: ANN001 - a resolved Shape
    """MJCF geom lines of one resolved 3D shape, in its body's frame (m); a convex hull's
    geom names the mesh `name` (_meshes writes it)."""
    f = f' friction="{friction}"'
    if shape.kind == "sphere":
        return [
            f'<geom type="sphere" size="{_num(shape.radius)}" pos="{_nums(shape.vertices[0])}"{f}/>'
        ]
    if shape.kind == "box":
        half = 0.5 * np.asarray(shape.size)
        return [
            f'<geom type="box" size="{_nums(half)}" pos="{_nums(shape.offset)}"'
            f' quat="{_nums(shape.orientation)}"{f}/>'
        ]
    if shape.kind == "capsule":
        a, b = shape.vertices
        return [
            f'<geom type="capsule" size="{_num(shape.radius)}" fromto="{_nums(a)} {_nums(b)}"{f}/>'
        ]
    if shape.kind == "plane":
        q = quat_from_z(np.asarray(shape.normal, float))
        return [
            f'<geom type="plane" size="0 0 1" pos="{_nums(shape.vertices[0])}"'
            f' quat="{_nums(q)}"{f}/>'
        ]
    if shape.kind == "convex":
        return [f'<geom type="mesh" mesh="{name}"{f}/>']
    raise ValueError(f"the bench's MJCF writer has no {shape.kind!r} geom")


def _meshes(scene: Scene) -> list[str]:
    """MJCF <asset> lines: a mesh of each convex hull's vertices (m, its body's frame),
    named m<body>_<shape> as _geoms names it; MuJoCo collides a mesh as its convex hull."""
    lines = []
    for i, body in enumerate(scene.bodies):
        for j, shape in enumerate(body.shapes):
            if shape.kind == "convex":
                points = " ".join(_nums(v) for v in shape.vertices)
                lines.append(f'    <mesh name="m{i}_{j}" vertex="{points}"/>')
    return ["  <asset>", *lines, "  </asset>"] if lines else []


def mjcf_contacts(
    scene: Scene, options: dict[str, str] | None = None, model: Model | None = None
) -> str:
    """The MJCF text of a 3D scene WITH contacts (MuJoCo's defaults, the module's
    docstring): every body a MuJoCo body at its origin with its orientation, dynamic
    ones with a free joint and rbsim's mass (kg) and inertia (kg·m², about the COM);
    static ones welded to the world; one step of the scene's dt (s); `options`: more
    attributes of MJCF's <option> (e.g. {"solver": "CG"}); `model`: the scene built, if
    the caller has built it."""
    if model is None:
        model, _ = build(scene)
    extra = "".join(f' {k}="{v}"' for k, v in (options or {}).items())
    lines = [
        f'<mujoco model="{scene.name}">',
        '  <compiler angle="radian" inertiafromgeom="false"/>',
        f'  <option timestep="{_num(scene.world.dt)}" gravity="{_nums(model.gravity)}"{extra}/>',
        *_meshes(scene),
        "  <worldbody>",
    ]
    for i, body in enumerate(scene.bodies):
        kind = int(model.body_type[i])
        if kind == T.BODY_KINEMATIC:
            raise ValueError("the bench's MJCF writer takes no kinematic bodies")
        lines.append(
            f'    <body name="b{i}" pos="{_nums(body.position)}" quat="{_nums(body.orientation)}">'
        )
        if kind == T.BODY_DYNAMIC:
            inertia = model.body_inertia[i]
            full = [inertia[0, 0], inertia[1, 1], inertia[2, 2]]
            full += [inertia[0, 1], inertia[0, 2], inertia[1, 2]]
            lines += [
                "      <freejoint/>",
                f'      <inertial pos="{_nums(model.body_com[i])}"'
                f' mass="{_num(model.body_mass[i])}" fullinertia="{_nums(full)}"/>',
            ]
        for j, shape in enumerate(body.shapes):
            friction = f"{_num(shape.material.friction)} 0.005 0.0001"
            lines += ["      " + g for g in _geoms(shape, friction, f"m{i}_{j}")]
        lines.append("    </body>")
    lines += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


def start_velocities(model: Model, state: State) -> tuple[np.ndarray, np.ndarray]:
    """Each body's starting velocity at its frame's origin (m/s, world) and its angular
    velocity (rad/s, world), from a built scene's (its state holds the centre of mass's:
    v_origin = v − ω × R c, c the body-frame COM)."""
    arm = np.einsum("nij,nj->ni", quat_matrix(state.body_q), model.body_com)  # m
    return state.body_v - np.cross(state.body_w, arm), state.body_w.copy()


class Runner:
    """One engine stepping one scene: advance(n) steps (each of the scene's dt),
    positions() the body origins (N,3) m, contacts() the contact points now."""

    name = ""

    def advance(self, n: int) -> None:
        raise NotImplementedError

    def positions(self) -> np.ndarray:
        raise NotImplementedError

    def contacts(self) -> int:
        raise NotImplementedError


class RbsimRunner(Runner):
    """rbsim's compiled engine with the scene's own solver settings."""

    name = "rbsim"

    def __init__(self, scene: Scene) -> None:
        self.engine = make_engine("rbsim", scene)

    def advance(self, n: int) -> None:
        self.engine.advance(n)

    def positions(self) -> np.ndarray:
        return np.asarray(self.engine.read().origin)

    def contacts(self) -> int:
        return int(self.engine.contact_count)


class MujocoRunner(Runner):
    """MuJoCo stepping `mjcf_contacts(scene)` (with the scene's MUJOCO_OPTIONS): one
    mj_step per scene step."""

    name = "mujoco"

    def __init__(self, scene: Scene) -> None:
        options = MUJOCO_OPTIONS.get(scene.name)
        model, state = build(scene)
        self.model = mujoco.MjModel.from_xml_string(mjcf_contacts(scene, options, model))
        self.data = mujoco.MjData(self.model)
        # the scene's velocities (a thrown ball, a pushed domino): a free joint's qvel is
        # its frame origin's velocity (world) and ω in the body's frame
        origin_v, w = start_velocities(model, state)
        qvel = self.data.qvel.reshape(-1, 6)
        dynamic = np.flatnonzero(model.body_type == T.BODY_DYNAMIC)
        rot = quat_matrix(state.body_q[dynamic])
        qvel[:, :3] = origin_v[dynamic]
        qvel[:, 3:] = np.einsum("nji,nj->ni", rot, w[dynamic])  # Rᵀ ω
        mujoco.mj_forward(self.model, self.data)

    def advance(self, n: int) -> None:
        step, m, d = mujoco.mj_step, self.model, self.data
        for _ in range(n):
            step(m, d)

    def positions(self) -> np.ndarray:
        # xpos is made at a step's start, from the qpos before the step moved it: made
        # again here from qpos now (mj_kinematics; the stepping is not touched)
        mujoco.mj_kinematics(self.model, self.data)
        return np.array(self.data.xpos[1:])  # body 0 is MuJoCo's world

    def contacts(self) -> int:
        return int(self.data.ncon)


class BulletRunner(Runner):
    """PyBullet (DIRECT, no GUI) with the scene's bodies as multibodies of one link,
    one stepSimulation of dt per step, its default 50 solver iterations."""

    name = "pybullet"

    def __init__(self, scene: Scene) -> None:
        model, state = build(scene)
        p = pybullet
        self.client = p.connect(p.DIRECT)
        c = self.client
        p.setGravity(*model.gravity, physicsClientId=c)
        p.setPhysicsEngineParameter(fixedTimeStep=scene.world.dt, physicsClientId=c)
        self.ids = []
        for i, body in enumerate(scene.bodies):
            if len(body.shapes) != 1:
                raise ValueError("the bench's PyBullet writer takes one shape per body")
            shape = body.shapes[0]
            if shape.kind == "sphere":
                geom = {"shapeType": p.GEOM_SPHERE, "radius": shape.radius}
                geom["collisionFramePosition"] = shape.vertices[0]
            elif shape.kind == "box":
                geom = {"shapeType": p.GEOM_BOX, "halfExtents": [0.5 * s for s in shape.size]}
                geom["collisionFramePosition"] = shape.offset
                geom["collisionFrameOrientation"] = _xyzw(shape.orientation)
            elif shape.kind == "capsule":  # Bullet's capsule lies along its frame's z
                a, b = np.asarray(shape.vertices[0]), np.asarray(shape.vertices[1])
                axis = b - a
                length = float(np.linalg.norm(axis))
                geom = {"shapeType": p.GEOM_CAPSULE, "radius": shape.radius, "height": length}
                geom["collisionFramePosition"] = list(0.5 * (a + b))
                geom["collisionFrameOrientation"] = _xyzw(quat_from_z(axis / length))
            elif shape.kind == "plane":
                geom = {"shapeType": p.GEOM_PLANE, "planeNormal": shape.normal}
                geom["collisionFramePosition"] = shape.vertices[0]
            elif shape.kind == "convex":  # Bullet collides a mesh's points as their hull
                geom = {"shapeType": p.GEOM_MESH, "vertices": [list(v) for v in shape.vertices]}
            else:
                raise ValueError(f"the bench's PyBullet writer has no {shape.kind!r}")
            col = p.createCollisionShape(**geom, physicsClientId=c)
            dynamic = int(model.body_type[i]) == T.BODY_DYNAMIC
            uid = p.createMultiBody(
                baseMass=float(model.body_mass[i]) if dynamic else 0.0,
                baseCollisionShapeIndex=col,
                basePosition=body.position,
                baseOrientation=_xyzw(body.orientation),
                physicsClientId=c,
            )
            p.changeDynamics(
                uid,
                -1,
                lateralFriction=shape.material.friction,
                restitution=shape.material.restitution,
                physicsClientId=c,
            )
            self.ids.append(uid)
        # the scene's velocities: Bullet's base here is the body's frame (its inertial
        # frame left at the origin), moving with the origin's velocity
        origin_v, w = start_velocities(model, state)
        for i, uid in enumerate(self.ids):
            if int(model.body_type[i]) == T.BODY_DYNAMIC and (origin_v[i].any() or w[i].any()):
                p.resetBaseVelocity(uid, list(origin_v[i]), list(w[i]), physicsClientId=c)

    def advance(self, n: int) -> None:
        step, c = pybullet.stepSimulation, self.client
        for _ in range(n):
            step(physicsClientId=c)

    def positions(self) -> np.ndarray:
        get, c = pybullet.getBasePositionAndOrientation, self.client
        return np.array([get(uid, physicsClientId=c)[0] for uid in self.ids])

    def contacts(self) -> int:
        return len(pybullet.getContactPoints(physicsClientId=self.client))

    def close(self) -> None:
        pybullet.disconnect(physicsClientId=self.client)


def _xyzw(q) -> list[float]:  # noqa: ANN001 - (w, x, y, z)
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


def runners() -> list[type[Runner]]:
    """The engines installed here: rbsim, then MuJoCo and PyBullet if importable."""
    out: list[type[Runner]] = [RbsimRunner]
    if mujoco is not None:
        out.append(MujocoRunner)
    if pybullet is not None:
        out.append(BulletRunner)
    return out


def tops(scene: Scene) -> np.ndarray:
    """Indices of the dynamic bodies that start highest (the tops of stacks), within 1 mm
    (the generators place them at one height)."""
    y = np.array([b.position[1] if b.type == "dynamic" else -np.inf for b in scene.bodies])
    return np.flatnonzero(y > y.max() - 1e-3)


def measure_all(
    scene: Scene,
    makes: list[type[Runner]],
    warmup: int = WARMUP,
    steps: int = STEPS,
    repeats: int = REPEATS,
) -> list[dict]:
    """The engines `makes` on one scene, their timed blocks interleaved (a block of each
    engine in turn, `repeats` rounds), so that a slow spell of a shared machine falls on
    all of them alike: per engine, CPU µs per step (the median of its `repeats` blocks of
    `steps` after `warmup`), "ratio" to the first engine (the median over the rounds of
    the first's block time over this one's), contact points at the end, and the top
    bodies' largest sideways move and sag (m) from the start."""
    runners = [make(scene) for make in makes]
    starts = [r.positions() for r in runners]
    samples = interleaved_block_times(runners, warmup, steps, repeats, time.thread_time)
    top = tops(scene)
    results = []
    for r, start, us in zip(runners, starts, samples, strict=True):
        d = r.positions()[top] - start[top]
        results.append(
            {
                "us": statistics.median(us),
                "ratio": median_ratio(samples[0], us),
                "contacts": r.contacts(),
                "move": float(np.max(np.hypot(d[:, 0], d[:, 2]))),
                "sag": float(np.max(-d[:, 1])),
            }
        )
        if hasattr(r, "close"):
            r.close()
    return results


def measure(
    scene: Scene,
    make: type[Runner],
    warmup: int = WARMUP,
    steps: int = STEPS,
    repeats: int = REPEATS,
) -> dict:
    """One engine on one scene (measure_all of that engine alone)."""
    return measure_all(scene, [make], warmup, steps, repeats)[0]


def rest_table(names: list[str] | None = None) -> list[str]:
    """rbsim against MuJoCo from rest: REST_BLOCKS blocks of STEPS steps of each in turn
    from step 0 (the thread's CPU time), in REST_RUNS runs of fresh engines; each block's
    ratio is the median over the runs of rbsim's block over MuJoCo's; the lines printed
    as they are measured. Without MuJoCo, nothing."""
    if mujoco is None:
        return []
    lines = [
        f"3D from rest, rbsim / MuJoCo by block of {STEPS} steps ({STEPS / 240:.2f} s) from "
        f"step 0 (each block's ratio, in order: the median of {REST_RUNS} runs), and the "
        f"median",
    ]
    print(lines[0], flush=True)
    for name in names or FROM_REST + EXAMPLES:
        scene = load(name)
        runs = []
        for k in range(REST_RUNS):
            engines = [RbsimRunner(the_round(scene, k)), MujocoRunner(the_round(scene, k))]
            samples = interleaved_block_times(engines, 0, STEPS, REST_BLOCKS, time.thread_time)
            runs.append([a / b for a, b in zip(*samples, strict=True)])
        ratios = [statistics.median(block) for block in zip(*runs, strict=True)]
        line = f"{name:<16}" + " ".join(f"{r:5.2f}" for r in ratios)
        line += f"   median {statistics.median(ratios):.2f}, worst {max(ratios):.2f}"
        if name in EXAMPLES:
            line += f"   (scenes/3d/{name}.yaml at its dt, {scene.world.dt:.4g} s)"
        print(line, flush=True)
        lines.append(line)
    return lines


def table(names: list[str] | None = None) -> list[str]:
    """The 3D table's lines, printed as they are measured."""
    makes = runners()
    others = [m for m in makes if m is not RbsimRunner]
    header = f"{'scene':<13}{'bodies':>7}"
    for m in makes:
        header += f"{m.name + ' us':>13}{'contacts':>9}"
    for m in others:
        header += f"{'/' + m.name:>10}"
    header += "   stands: top move / sag, m (each engine)"
    lines = [header, "-" * len(header)]
    for module, hint in (
        (mujoco, "mujoco: the extra `mujoco`"),
        (pybullet, "pybullet: the extra `bench` (pip install pybullet)"),
    ):
        if module is None:
            lines.insert(0, f"(not installed, left out: {hint})")
    print("\n".join(lines))
    for name in names or list(SCENES):
        scene = load(name)
        rows = measure_all(scene, makes)
        dynamic = sum(b.type == "dynamic" for b in scene.bodies)
        line = f"{name:<13}{dynamic:>7}"
        for r in rows:
            line += f"{r['us']:>13.1f}{r['contacts']:>9}"
        for r in rows[1:]:
            line += f"{r['ratio']:>10.2f}"
        if name in STANDING:
            line += "   " + "  ".join(f"{r['move']:.3f}/{r['sag']:.3f}" for r in rows)
        if mujoco is not None and name in MUJOCO_OPTIONS:
            line += "   mujoco: " + " ".join(f"{k}={v}" for k, v in MUJOCO_OPTIONS[name].items())
        print(line, flush=True)
        lines.append(line)
    return lines
