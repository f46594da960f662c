"""The MuJoCo bridge (rbsim.engines.mujoco) and `rbsim compare` in 3D.

The MJCF it writes is parsed back through MuJoCo and checked against rbsim's compiled
Model (masses, full inertia tensors, COM, gravity, timestep, contacts off); the state
layout MuJoCo 4.0.0 keeps for a free joint is measured on a known motion; MuJoCo alone is
held against the closed forms of its own integrator; and `rbsim compare` runs every 3D
compare scene (exit 0) and fails on a wrong value (exit 4).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from rbsim.engines import EngineUnavailable, UnsupportedScene, make_engine  # noqa: E402
from rbsim.engines import mujoco as bridge  # noqa: E402
from rbsim.engines.mujoco import MujocoEngine, MujocoSettings, quat_matrix, quat_mul  # noqa: E402
from rbsim.scene import load_scene  # noqa: E402

from .conftest import rbsim, scene_from  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
COMPARE3D = REPO / "scenes" / "3d" / "compare"
SCENES3D = sorted(COMPARE3D.glob("*.yaml"))
H = (1 / 60) / 4  # s, one MuJoCo step (dt / substeps) in every 3D compare scene


def test_the_3d_compare_scenes_exist():
    names = {p.stem for p in SCENES3D}
    assert {"free_spin", "projectile", "constant_torque", "thrown_compound"} <= names
    for path in SCENES3D:
        scene = load_scene(path)
        assert scene.world.dimension == 3 and scene.compare


# -- the model as written -------------------------------------------------------------------


@pytest.mark.parametrize("frame", ["com", "origin"])
def test_masses_inertia_com_gravity_timestep_as_written(frame: str):
    scene = load_scene(COMPARE3D / "thrown_compound.yaml")
    engine = MujocoEngine(scene, MujocoSettings(frame=frame))
    m, model = engine.mj_model, engine.model
    # parsed back from the MJCF text, not taken from the engine's own arrays
    parsed = mujoco.MjModel.from_xml_string(engine.xml)
    for mm in (m, parsed):
        assert mm.nbody == 2 and mm.njnt == 1 and mm.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
        assert mm.body_mass[1] == model.body_mass[0]  # repr() round-trips the double
        com = model.body_com[0] if frame == "origin" else np.zeros(3)
        np.testing.assert_array_equal(mm.body_ipos[1], com)
        # MuJoCo keeps principal moments and the principal axes' rotation (body_iquat):
        # R diag(I) Rᵀ rebuilds rbsim's full tensor to its eigen-solver's round-off
        rot = quat_matrix(mm.body_iquat[1:])[0]
        tensor = rot @ np.diag(mm.body_inertia[1]) @ rot.T
        inertia = model.body_inertia[0]
        assert abs(inertia[0, 1]) > 1e-3 * abs(inertia).max()  # a full tensor, not diagonal
        np.testing.assert_allclose(tensor, inertia, rtol=0, atol=1e-13 * abs(inertia).max())
        np.testing.assert_array_equal(mm.opt.gravity, [0.0, -9.81, 0.0])  # y-up, as given
        assert mm.opt.timestep == scene.world.dt / scene.solver.substeps
        assert mm.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
        assert mm.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert np.linalg.norm(model.body_com[0]) > 0.3  # the COM is well off the origin
    point = model.body_com[0] if frame == "com" else np.zeros(3)
    rot = quat_matrix(np.array([scene.bodies[0].orientation]))[0]
    frame_at = np.asarray(scene.bodies[0].position) + rot @ point
    np.testing.assert_array_equal(engine.mj_data.qpos[:3], frame_at)
    np.testing.assert_array_equal(engine.mj_data.qpos[3:], scene.bodies[0].orientation)
    np.testing.assert_allclose(engine.read().origin[0], scene.bodies[0].position, atol=1e-15)


def test_frame_at_the_com_keeps_the_com_on_rbsims_parabola():
    """A free joint moves its frame's point: with the frame at the body origin a spinning
    body whose COM is off it strays from the semi-implicit parabola x0 + v0 t + g t²/2 +
    g h t/2 that rbsim's COM follows (first order: 0.12 m in 2 s here); at the COM it
    follows it to round-off (the bridge's default)."""
    scene = load_scene(COMPARE3D / "thrown_compound.yaml")
    t = scene.world.steps * scene.world.dt
    g = np.array([0.0, -9.81, 0.0])
    strays = {}
    for frame in ("com", "origin"):
        engine = MujocoEngine(scene, MujocoSettings(frame=frame))
        x0, v0 = engine.read().com[0], np.asarray(scene.bodies[0].velocity)
        engine.advance(scene.world.steps)
        s = engine.read()
        parabola = x0 + v0 * t + g * t * t / 2 + g * H * t / 2
        strays[frame] = np.linalg.norm(s.com[0] - parabola)
        if frame == "com":
            np.testing.assert_allclose(s.velocity[0], v0 + g * t, atol=1e-12)  # round-off
    assert strays["com"] < 1e-12  # round-off of 480 steps
    assert strays["origin"] > 0.05


def test_static_bodies_are_not_written_and_kinematic_ones_move_as_prescribed():
    scene = scene_from(
        """
        version: 1
        world: {dimension: 3, gravity: [0, 0, 0], dt: 0.01, steps: 100}
        bodies:
          - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0]}}}
          - {name: belt, type: kinematic, velocity: [1, 0, 0], angular_velocity: [0, 2, 0],
             shape: {box: {size: [1, 1, 1]}}}
        """
    )
    engine = MujocoEngine(scene)
    assert engine.mj_model.nbody == 1  # the world alone
    engine.advance(100)
    s = engine.read()
    np.testing.assert_allclose(s.origin[1], [1.0, 0.0, 0.0], atol=1e-15)
    # turned by 2 rad about y: q = (cos 1, 0, sin 1, 0)
    np.testing.assert_allclose(s.orientation[1], [math.cos(1), 0, math.sin(1), 0], atol=1e-15)
    np.testing.assert_array_equal(s.origin[0], [0.0, 0.0, 0.0])


BALL_OVER_PLANE = """
version: 1
world: {dimension: 3, dt: 0.01, steps: 100}
bodies:
  - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0]}}}
  - {name: ball, position: [0, 3, 0], shape: {sphere: {radius: 0.5}}}
"""


def test_a_scene_whose_bodies_can_touch_gets_mujoco_contacts():
    """rbsim collides the ball with the plane, and so does MuJoCo: one explicit pair,
    contacts enabled, the geoms colliding through that pair only (contype 0); the
    contact tests are in tests/test_mujoco_contacts.py."""
    engine = MujocoEngine(scene_from(BALL_OVER_PLANE))
    m = engine.mj_model
    assert m.npair == 1 and len(engine.pairs) == 1
    assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert not m.geom_contype.any() and not m.geom_conaffinity.any()
    assert "1 pairs" in engine.settings["contacts"]


# -- the state as MuJoCo keeps it ------------------------------------------------------------

SPINNER = """
version: 1
world: {dimension: 3, gravity: [0, 0, 0], dt: 1.0e-6, steps: 1}
solver: {substeps: 1}
bodies:
  - name: lump
    position: [1, 2, 3]
    rotation: {axis: [1, 2, 3], angle: 0.7}
    velocity: [0.5, -0.3, 0.2]
    angular_velocity: [1.0, 2.0, -1.5]
    density: 1000
    shapes:
      - {box: {size: [0.4, 0.1, 0.1]}}
      - {sphere: {radius: 0.1, offset: [0.3, 0.1, 0]}}
"""


@pytest.mark.parametrize("frame", ["com", "origin"])
def test_free_joint_state_layout_measured(frame: str):
    """qpos: the frame's origin (world) + (w, x, y, z); qvel: the frame origin's world
    velocity, then the angular velocity in the BODY frame (MuJoCo 4.0.0). Measured by
    finite differences over one step of 1 µs: the differences are O(h) (a first-order
    step), 1e-5 here."""
    scene = scene_from(SPINNER)
    engine = MujocoEngine(scene, MujocoSettings(frame=frame))
    d = engine.mj_data
    p0, v0 = d.qpos.copy(), d.qvel.copy()
    h = engine.h
    mujoco.mj_step(engine.mj_model, d)
    p1 = d.qpos
    np.testing.assert_allclose((p1[:3] - p0[:3]) / h, v0[:3], atol=1e-5)
    q0, q1 = p0[3:], p1[3:]
    conj = np.array([[q0[0], -q0[1], -q0[2], -q0[3]]])
    body = quat_mul(conj, q1[None])[0]  # q0⁻¹ q1: the turn in the body frame
    np.testing.assert_allclose(2 * body[1:] / h, v0[3:], atol=1e-5)
    # rbsim's layout: the COM velocity and the world ω the scene gave
    engine = MujocoEngine(scene, MujocoSettings(frame=frame))
    s = engine.read()
    np.testing.assert_allclose(s.velocity[0], scene.bodies[0].velocity, atol=1e-15)
    np.testing.assert_allclose(s.angular_velocity[0], scene.bodies[0].angular_velocity, atol=1e-15)
    r = quat_matrix(s.orientation)[0] @ engine.com_local[0]
    assert np.linalg.norm(r) > 0.05  # the COM is off the origin: v_origin ≠ v_com
    np.testing.assert_allclose(s.com[0], s.origin[0] + r, atol=1e-15)
    # the COM moves with the reported COM velocity (finite difference, O(h) again)
    engine.advance(1)
    moved = engine.read().com[0] - s.com[0]
    np.testing.assert_allclose(moved / h, s.velocity[0], atol=1e-5)
    # world L = R I Rᵀ ω, constant without torque
    ang = engine.state().body_l[0]
    rot = quat_matrix(s.orientation)[0]
    expected = rot @ engine.inertia[0] @ rot.T @ np.asarray(scene.bodies[0].angular_velocity)
    np.testing.assert_allclose(ang, expected, rtol=1e-5)


# -- MuJoCo alone against the closed forms of its integrator --------------------------------


def test_projectile_follows_semi_implicit_euler():
    """v <- v + g h, then x <- x + v h: y(t) = y0 + vy t - g t²/2 - g h t/2 exactly."""
    scene = load_scene(COMPARE3D / "projectile.yaml")
    engine = MujocoEngine(scene)
    engine.advance(scene.world.steps)
    t = scene.world.steps * scene.world.dt
    s = engine.read()
    expected = [3 * t, 10 + 10 * t - 9.81 * t * t / 2 - 9.81 * H * t / 2, 2 * t]
    np.testing.assert_allclose(s.origin[0], expected, atol=1e-12)  # round-off of 480 steps
    np.testing.assert_allclose(s.velocity[0], [3, 10 - 9.81 * t, 2], atol=1e-12)


def test_constant_torque_about_a_principal_axis():
    """ω = α t along the axis (the gyroscopic term vanishes), and the body turns by
    h Σ ω_k = α t²/2 + α h t/2 about it."""
    scene = load_scene(COMPARE3D / "constant_torque.yaml")
    engine = MujocoEngine(scene)
    engine.advance(scene.world.steps)
    t = scene.world.steps * scene.world.dt
    izz = engine.inertia[0][2, 2]
    alpha = 0.5 / izz
    s = engine.read()
    axis = np.asarray(scene.bodies[0].torque) / 0.5
    np.testing.assert_allclose(s.angular_velocity[0], alpha * t * axis, rtol=1e-7)  # torque digits
    turn = quat_mul(s.orientation, (np.asarray([scene.bodies[0].orientation]) * [1, -1, -1, -1]))
    angle = 2 * math.atan2(np.linalg.norm(turn[0, 1:]), abs(turn[0, 0]))
    assert angle == pytest.approx(alpha * t * t / 2 + alpha * H * t / 2, rel=1e-7)


def test_damping_is_rbsims_implicit_law():
    """v_{k+1} = (v_k + g h) / (1 + h c) and L_{k+1} = L_k / (1 + h c_ang) (rbsim's law):
    MuJoCo with the bridge's damping forces follows the same recursion."""
    scene = scene_from(
        """
        version: 1
        world: {dimension: 3, dt: 0.01, steps: 50, damping: {linear: 0.7, angular: 0.3}}
        solver: {substeps: 2}
        bodies:
          - {name: ball, velocity: [2, 5, -1], angular_velocity: [0, 0, 3],
             shape: {sphere: {radius: 0.5}}}
        """
    )
    engine = MujocoEngine(scene)
    engine.advance(50)
    h, g = 0.005, np.array([0.0, -9.81, 0.0])
    v, w = np.array([2.0, 5.0, -1.0]), 3.0
    for _ in range(100):
        v = (v + g * h) / (1 + 0.7 * h)
        w = w / (1 + 0.3 * h)
    s = engine.read()
    np.testing.assert_allclose(s.velocity[0], v, rtol=1e-12)
    np.testing.assert_allclose(s.angular_velocity[0], [0, 0, w], rtol=1e-12, atol=1e-15)


def test_force_at_a_point_adds_its_torque():
    """A force at a body point, through the COM's line at start: (R arm) × f spins it."""
    scene = scene_from(
        """
        version: 1
        world: {dimension: 3, gravity: [0, 0, 0], dt: 0.001, steps: 1}
        bodies:
          - {name: box, force: [0, 2, 0], force_point: [0.5, 0, 0],
             shape: {box: {size: [1, 1, 1]}}}
        """
    )
    engine = MujocoEngine(scene)
    engine.advance(1)
    s = engine.read()
    h = 0.001 / scene.solver.substeps
    n = scene.solver.substeps
    # τ = (0.5, 0, 0) × (0, 2, 0) = (0, 0, 1) N·m on I = m/6 (unit cube, m = density)
    izz = engine.inertia[0][2, 2]
    assert s.angular_velocity[0][2] == pytest.approx(n * h / izz, rel=1e-6)
    assert s.velocity[0][1] == pytest.approx(n * h * 2 / engine.mass[0], rel=1e-12)


# -- the engine interface and compare ---------------------------------------------------------


def test_a_2d_scene_is_not_for_mujoco():
    scene = scene_from("version: 1\nbodies:\n  - {name: b, shape: {circle: {radius: 0.5}}}\n")
    with pytest.raises(UnsupportedScene, match="3D scenes only"):
        make_engine("mujoco", scene)


def test_missing_mujoco_is_a_message(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    monkeypatch.setattr(bridge, "mujoco", None)
    with pytest.raises(EngineUnavailable, match="rbsim\\[mujoco\\]"):
        MujocoEngine(load_scene(COMPARE3D / "projectile.yaml"))
    code, _out, err = rbsim("compare", COMPARE3D / "projectile.yaml", "-o", tmp_path)
    assert code == 1
    assert "MuJoCo is not installed" in err and "Traceback" not in err


@pytest.mark.parametrize("path", SCENES3D, ids=[p.stem for p in SCENES3D])
def test_3d_compare_scene_passes(path: Path, tmp_path: Path):
    code, out, err = rbsim("compare", path, "-o", tmp_path, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["ok"] and data["reference"] == "mujoco"
    name = load_scene(path).name
    assert (tmp_path / f"{name}.rbsim.h5").is_file()
    assert (tmp_path / f"{name}.mujoco.h5").is_file()
    bouncing = {"bounce_3d", "bounce_elastic_3d"}  # one impact each, lined up
    for body in data["bodies"]:
        expected = 1 if name in bouncing and body["name"] == "ball" else 0
        assert body["impacts"] == expected and body["unmatched"] == []


def test_wrong_velocity_in_mujoco_alone_exits_4(tmp_path: Path):
    """1 mm/s more along z in MuJoCo alone: 2 mm apart after 2 s, far above 1e-9 m."""
    code, _out, err = rbsim(
        "compare",
        COMPARE3D / "projectile.yaml",
        "-o",
        tmp_path,
        "--reference-set",
        "bodies.ball.velocity=[3, 10, 2.001]",
    )
    assert code == 4
    assert "body 'ball': max position difference" in err
    assert "max velocity difference 0.001" in err


def test_tightened_angle_tolerance_exits_4(tmp_path: Path):
    code, _out, err = rbsim(
        "compare", COMPARE3D / "free_spin.yaml", "-o", tmp_path, "--angle", "1e-6"
    )
    assert code == 4 and "body 'brick': max angle difference" in err


def test_a_blown_up_spin_is_a_non_finite_state_not_a_reset(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """MuJoCo resets the state when its acceleration blows up; the bridge says so
    (NonFiniteState) instead of reading the reset state as the body's. A box spun at
    400 rad/s about its intermediate axis, with MuJoCo steps of 20 ms (|ω| h = 8)."""
    from rbsim.engines import NonFiniteState

    monkeypatch.chdir(tmp_path)  # MuJoCo's warning writes MUJOCO_LOG.TXT here

    scene = scene_from(
        """
        version: 1
        world: {dimension: 3, gravity: [0, 0, 0], dt: 0.02, steps: 200}
        solver: {substeps: 1}
        bodies:
          - {name: brick, angular_velocity: [0.1, 400, 0.1],
             shape: {box: {size: [0.3, 0.2, 0.1]}}}
        """
    )
    engine = MujocoEngine(scene)
    with pytest.raises(NonFiniteState) as info:
        for _ in range(200):
            engine.advance(1)
    assert info.value.body == 0


def _converged_spin(engine: MujocoEngine, t: float) -> np.ndarray:
    """The orientation (w, x, y, z) at t (s) of the torque-free body of `engine`, from
    Euler's equations in the body frame solved to rtol 1e-13 (scipy's DOP853)."""
    from scipy.integrate import solve_ivp

    inertia = engine.inertia[0]
    inv = np.linalg.inv(inertia)
    q0 = engine.read().orientation[0]
    wb0 = quat_matrix(q0[None])[0].T @ engine.read().angular_velocity[0]

    def rate(_t: float, y: np.ndarray) -> np.ndarray:
        q, wb = y[:4], y[4:]
        dq = 0.5 * quat_mul(q[None], np.r_[0.0, wb][None])[0]
        return np.r_[dq, inv @ np.cross(inertia @ wb, wb)]

    sol = solve_ivp(rate, (0.0, t), np.r_[q0, wb0], rtol=1e-13, atol=1e-13, method="DOP853")
    q = sol.y[:4, -1]
    return q / np.linalg.norm(q)


def test_free_spin_tolerance_terms_first_and_second_order():
    """The terms free_spin.yaml's angle tolerance adds up: MuJoCo's orientation error is
    first order (4.042e-3 rad at h = 1/240 s, halving with h), rbsim's `split` second
    order (a quarter with h/2), both against a converged solution."""
    from types import SimpleNamespace

    from rbsim.tools.compare import angle_difference

    errors: dict[str, list[float]] = {"rbsim": [], "mujoco": []}
    for dt in ("1/60", "1/120"):
        scene = load_scene(COMPARE3D / "free_spin.yaml", [f"world.dt={dt}"])
        exact = None
        for name in errors:
            engine = make_engine(name, scene)
            if exact is None:
                exact = _converged_spin(MujocoEngine(scene), 2.0)
            engine.advance(scene.world.steps)
            q = engine.read().orientation
            a = SimpleNamespace(angle=None, orientation=q[None])
            b = SimpleNamespace(angle=None, orientation=exact[None, None])
            errors[name].append(float(angle_difference(a, b)[0, 0]))
    mj, rb = errors["mujoco"], errors["rbsim"]
    assert mj[0] == pytest.approx(4.042e-3, rel=1e-3)  # the comment's figure, 4 digits
    assert mj[0] / mj[1] == pytest.approx(2.0, rel=0.02)  # first order
    assert rb[0] / rb[1] == pytest.approx(4.0, rel=0.05)  # second order
    assert rb[0] < 1e-3 * mj[0]


def test_impacts_are_lined_up_in_3d_too(tmp_path: Path):
    """The event alignment of `rbsim compare` on 3D trajectories: the two runs of the
    projectile with a velocity jump put in by hand, one frame apart (an impact each
    engine lands one step apart) is no difference; a different rebound is."""
    from rbsim.io.trajectory import load_trajectory
    from rbsim.tools.compare import body_diffs

    code, _out, err = rbsim("compare", COMPARE3D / "projectile.yaml", "-o", tmp_path)
    assert code == 0, err
    tol = {"velocity": 1e-9, "angular_velocity": 1e-9}
    for other_jump, expected in (([0, 8, 0], 0.0), ([0, 7.5, 0], 0.5)):
        rb = load_trajectory(tmp_path / "projectile_3d.rbsim.h5")
        mj = load_trajectory(tmp_path / "projectile_3d.mujoco.h5")
        rb.velocity[60:, 0] += [0, 8, 0]  # a bounce between frames 59 and 60
        mj.velocity[61:, 0] += other_jump  # ... and a frame later
        (ball,) = body_diffs(rb, mj, tol, engines=("rbsim", "mujoco"))
        assert ball.impacts == 1 and ball.unmatched == []
        assert ball.max_offset == pytest.approx(1 / 60)
        assert ball.max_velocity == pytest.approx(expected, abs=1e-9)  # round-off


def test_checkpoint_restores_the_state():
    scene = load_scene(COMPARE3D / "thrown_compound.yaml")
    engine = MujocoEngine(scene)
    engine.advance(30)
    saved = engine.checkpoint()
    engine.advance(30)
    end = engine.read()
    again = MujocoEngine(scene)
    again.restore(saved)
    assert again.step_index == 30
    again.advance(30)
    np.testing.assert_array_equal(again.read().orientation, end.orientation)  # bit for bit
    np.testing.assert_array_equal(again.read().velocity, end.velocity)
