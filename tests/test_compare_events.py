"""`rbsim compare` judges impacts as events, not frames: velocity jumps are found in each
engine's run, paired, and the velocities compared with the impacts lined up (the time
offset reported), so that an impact landing one step apart in the two engines is not a
difference of the whole jump, while a wrong post-impact velocity or a missed impact
still fails."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rbsim.io.trajectory import load_trajectory
from rbsim.tools.compare import aligned_difference, events, jump_frames, pair_events

from .conftest import rbsim

# Two circles (r = 0.25 m, masses m and 2m) closing at u = 4 m/s with their centres
# 0.25 m apart across the line of motion: they touch with the normal at φ = 30° to it at
# t = (2 − 0.5 cos 30°) / 4 = 0.392 s; e = 0.5, no gravity, no friction, dt = 1 ms, one
# substep. Velocity tolerance: the impulse changes the lighter body's velocity by
# (1 + e) (2/3) u cos φ n, which turns with n by (1 + e) (2/3) u = 4 m/s per rad. Each
# engine takes the normal within u h = 4 mm (along x) of where the circles touch,
# Chipmunk past it (overlapping), rbsim (measured) before it: the normals differ by up to
# atan(0.25 / 0.429) − atan(0.25 / 0.437) = 8.23e-3 rad, so the lighter body's velocities
# by up to 0.0329 m/s after the impact (the heavier one half that). Positions: that over
# the remaining 0.608 s, 0.0200 m, plus Chipmunk's overlap lag of up to 2 |v| h = 4 mm:
# 0.024 m. Angles stay 0 (no friction, circles take no torque).
OFF_CENTRE = """\
version: 1
name: off_centre_e05
world: {gravity: [0, 0], dt: 0.001, duration: 1}
solver: {substeps: 1}
materials:
  bouncy: {density: 1.0, friction: 0.0, restitution: 0.5}
bodies:
  - {name: left, position: [-1, 0], velocity: [2, 0], material: bouncy,
     shape: {circle: {radius: 0.25}}}
  - {name: right, position: [1, 0.25], velocity: [-2, 0], material: bouncy, density: 2.0,
     shape: {circle: {radius: 0.25}}}
compare: {position: 0.024, angle: 1.0e-9, velocity: 0.0329}
"""


@pytest.fixture
def off_centre(tmp_path: Path) -> Path:
    path = tmp_path / "off_centre_e05.yaml"
    path.write_text(OFF_CENTRE)
    return path


def test_impact_one_step_apart_is_not_a_velocity_difference(off_centre: Path, tmp_path: Path):
    code, out, err = rbsim("compare", off_centre, "-o", tmp_path, "--json")
    assert code == 0, err
    rb = load_trajectory(tmp_path / "off_centre_e05.rbsim.h5")
    pm = load_trajectory(tmp_path / "off_centre_e05.pymunk.h5")
    # the false alarm compared frame by frame: a whole jump (the impact lands one step
    # apart), far above the 0.0329 m/s that the two engines' normals explain
    frame_by_frame = np.linalg.norm(rb.velocity - pm.velocity, axis=2).max()
    assert frame_by_frame > 1.0
    import json

    data = json.loads(out)
    for body in data["bodies"]:
        assert body["impacts"] == 1 and body["unmatched"] == []
        # the offset is reported, within a step or two either way (EVENT_FRAMES)
        assert abs(body["max_offset"]) <= 3e-3 + 1e-12
        assert body["max_velocity"] < 0.0329
    assert any(b["max_offset"] != 0.0 for b in data["bodies"])  # they are one step apart
    assert "Δt impact s" in rbsim("compare", off_centre, "-o", tmp_path)[1]


def test_wrong_post_impact_velocity_still_fails(off_centre: Path, tmp_path: Path):
    """e = 0.4 in pymunk alone: the same impact time, a different rebound (the lighter
    body's by 0.1 × (2/3) × 4 cos² 30° = 0.2 m/s)."""
    code, _out, err = rbsim(
        "compare", off_centre, "-o", tmp_path, "--pymunk-set", "materials.bouncy.restitution=0.4"
    )
    assert code == 4
    assert "body 'left': max velocity difference" in err
    assert "no match" not in err  # the impacts pair; their results differ


def test_missed_impact_still_fails(off_centre: Path, tmp_path: Path):
    """The right circle 0.6 m off the line in pymunk alone: the circles pass by there."""
    code, _out, err = rbsim(
        "compare", off_centre, "-o", tmp_path, "--pymunk-set", "bodies.right.position=[1, 0.6]"
    )
    assert code == 4
    assert "body 'left': a velocity jump (impact) at t = 0.39" in err
    assert "in rbsim has no match" in err
    assert "max velocity difference" in err  # and the frames after it are not excused


def test_extra_impact_is_named_with_its_engine(tmp_path: Path):
    """A wall only pymunk has (by a static body moved into the path): pymunk bounces."""
    scene = tmp_path / "wall.yaml"
    scene.write_text(
        "version: 1\nworld: {gravity: [0, 0], dt: 0.001, duration: 0.5}\nsolver: {substeps: 1}\n"
        "bodies:\n"
        "  - {name: ball, velocity: [4, 0], restitution: 1.0, shape: {circle: {radius: 0.25}}}\n"
        "  - {name: wall, type: static, position: [9, 0], restitution: 1.0,\n"
        "     shape: {segment: {a: [0, -1], b: [0, 1]}}}\n"
        "compare: {velocity: 0.01}\n"
    )
    code, _out, err = rbsim(
        "compare", scene, "-o", tmp_path, "--pymunk-set", "bodies.wall.position=[1, 0]"
    )
    assert code == 4
    assert "body 'ball': a velocity jump (impact) at t = 0.18" in err and "in pymunk" in err


# -- the pieces, on series made in the test -----------------------------------------------


def test_steady_acceleration_and_smooth_turn_are_not_jumps():
    t = np.linspace(0.0, 2.0, 201)
    falling = np.stack([3.0 + 0 * t, 10.0 - 9.81 * t], axis=1)
    assert not jump_frames(t, falling, 1e-6).any()
    turning = np.stack([np.cos(5 * t), np.sin(5 * t), 0 * t], axis=1)  # precessing ω
    # the trend (a median of the neighbours' rates) is off by at most 2 intervals, at
    # either end: 2 |v''| h² = 2 × (5 rad/s)² × (0.01 s)² = 5e-3
    assert not jump_frames(t, turning, 5.1e-3).any()
    assert jump_frames(t, turning, 4.0e-3).any()  # ... and it is that large


def test_a_jump_on_a_trend_is_one_event_even_over_two_frames():
    t = np.linspace(0.0, 1.0, 101)
    v = (10.0 - 9.81 * t)[:, None]
    v[40:] -= 3.0  # an impact between frames 39 and 40
    v[41:] -= 3.0  # ... resolved over two steps
    found = events(jump_frames(t, v, 0.5))
    assert found == [(39, 40)]


def test_pairing_and_alignment():
    a, b = [(10, 10), (50, 50)], [(11, 11), (90, 90)]
    pairs, lone_a, lone_b = pair_events(a, b, frames=3)
    assert pairs == [((10, 10), (11, 11))] and lone_a == [1] and lone_b == [1]
    t = np.arange(30.0)
    va = np.where(t > 10, -1.0, 2.0)[:, None]
    vb = np.where(t > 11, -1.0, 2.0)[:, None]
    assert np.abs(va - vb).max() == 3.0  # frame 11: one has bounced, the other not
    assert aligned_difference(va, vb, [((10, 10), (11, 11))]).max() == 0.0
    vb_wrong = np.where(t > 11, -0.9, 2.0)[:, None]  # a different rebound
    assert aligned_difference(va, vb_wrong, [((10, 10), (11, 11))]).max() == pytest.approx(0.1)


def test_3d_angle_is_the_rotation_between_the_orientations():
    """2 acos |q1 · q2|: 0.3 rad about any axis, the same for -q2, accurate near 0."""
    from types import SimpleNamespace

    from rbsim.tools.compare import angle_difference

    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    q1 = np.array([[[0.6, 0.0, 0.8, 0.0]]])
    for angle in (0.3, 1e-9, 3.0):
        turn = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
        w1, v1 = q1[0, 0, 0], q1[0, 0, 1:]
        w2, v2 = turn[0], turn[1:]
        q2 = np.concatenate([[w2 * w1 - v2 @ v1], w2 * v1 + w1 * v2 + np.cross(v2, v1)])
        for sign in (1.0, -1.0):
            a = SimpleNamespace(angle=None, orientation=q1)
            b = SimpleNamespace(angle=None, orientation=sign * q2[None, None])
            assert angle_difference(a, b)[0, 0] == pytest.approx(angle, rel=1e-9)
