"""The 3D bench (bench/bench3d.py) loads and steps in every engine, so that it cannot rot:
each scene a few steps in rbsim, MuJoCo and (if installed) PyBullet; no times asserted."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from bench import bench3d  # noqa: E402


@pytest.mark.parametrize("name", list(bench3d.SCENES))
def test_bench_scene_steps_in_every_engine(name: str) -> None:
    """Every engine starts from the scene's own body origins (the MJCF and PyBullet's
    bodies written from the resolved scene) and stays finite over 3 steps."""
    scene = bench3d.load(name)
    origins = np.array([b.position for b in scene.bodies])
    for make in bench3d.runners():
        runner = make(scene)
        # 1e-12 m: the origins are written as repr'd doubles (MuJoCo) or passed as
        # doubles (PyBullet); round-off of the engines' own set-up only
        assert np.allclose(runner.positions(), origins, atol=1e-12), make.name
        runner.advance(3)
        assert np.all(np.isfinite(runner.positions())), make.name
        if hasattr(runner, "close"):
            runner.close()


def test_the_stack_touches_and_stands_in_every_engine() -> None:
    """The 10-box stack has contacts in each engine after 30 steps (MuJoCo's geoms and
    PyBullet's shapes collide), and its top box has not fallen through the stack or the
    plane: sag under 5 cm (the hard case's bound for this stack)."""
    scene = bench3d.load("stack10")
    for make in bench3d.runners():
        result = bench3d.measure(scene, make, warmup=30, steps=1, repeats=1)
        assert result["contacts"] >= 4, make.name
        assert result["sag"] < 0.05, make.name
        assert result["move"] < 0.05, make.name


def test_the_plane_quaternion_turns_z_onto_the_normal() -> None:
    """MuJoCo's plane has its normal along its local z: the written quaternion takes z to
    the scene's normal, for the up plane and for a tilted and a downward one."""
    from rbsim.engines.mujoco import quat_matrix

    for n in ([0, 1, 0], [0.6, 0.8, 0], [0, 0, -1.0]):
        q = bench3d.quat_from_z(np.array(n, float))
        # 1e-12: one normalisation's round-off
        assert np.allclose(quat_matrix(q[None])[0] @ [0, 0, 1], n, atol=1e-12)


def test_every_engine_starts_from_the_scenes_velocities() -> None:
    """The struck wall's ball is thrown at 15 m/s along z: in every engine it has moved
    15 m/s × 2 dt along z after two steps (the MJCF and PyBullet's bodies once started
    at rest, and the ball fell in front of a wall it never struck); and a box turning at
    3 rad/s about a tilted axis turns the same way in every engine."""
    scene = bench3d.load("wall96")
    ball = [b.name for b in scene.bodies].index("ball")
    z0 = scene.bodies[ball].position[2]
    dt = scene.world.dt
    for make in bench3d.runners():
        runner = make(scene)
        runner.advance(2)
        # 1% of the move: gravity acts along y only; PyBullet's default damping takes
        # 0.4% of it in two steps (rbsim and MuJoCo: round-off)
        moved = runner.positions()[ball, 2] - z0
        assert abs(moved - 15.0 * 2 * dt) < 0.01 * 15.0 * 2 * dt, (make.name, moved)
        if hasattr(runner, "close"):
            runner.close()
    # a domino (0.1 x 1 x 0.5 m, standing on the plane) given 3 rad/s about z topples
    # within 1 s in every engine (its centre from 0.5 m to below 0.3), and without the
    # spin stands (the spin reached the engine, about the right axis, with its sign)
    for spin, falls in (("[0, 0, -3]", True), ("[0, 0, 0]", False)):
        text = bench3d._head("domino") + (
            f"  - {{name: d, position: [0, 0.5, 0], angular_velocity: {spin},\n"
            "     shape: {box: {size: [0.1, 1.0, 0.5]}}, material: wood}\n"
        )
        domino = bench3d.load_scene_text(text, "domino.yaml")
        for make in bench3d.runners():
            runner = make(domino)
            runner.advance(240)
            p = runner.positions()[-1]
            assert (p[1] < 0.3) == falls, (make.name, spin, p)
            if falls:
                assert p[0] > 0.1, (make.name, p)  # toppled towards +x: ω_z < 0 turns +y to +x
            if hasattr(runner, "close"):
                runner.close()
