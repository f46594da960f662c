"""The integrator through the engine's API: closed forms of symplectic and explicit Euler,
the two rotation updates, damping and the torque of a force applied off the centre."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.core import CoreWorld
from tests.conftest import scene_from

G = 9.81  # m/s²

FALL = """
version: 1
world: {{gravity: [0, -9.81], dt: 0.01, duration: 1}}
solver: {{substeps: 2, integrator: {integrator}}}
bodies:
  - {{name: ball, position: [0, 10], velocity: [3, 5], shape: {{circle: {{radius: 0.1}}}}}}
"""


def world(text: str) -> CoreWorld:
    return CoreWorld.from_scene(scene_from(text))


@pytest.mark.parametrize("integrator", ["symplectic_euler", "explicit_euler"])
def test_projectile_matches_euler_closed_form(integrator):
    # after n substeps of h from v0: symplectic y = y0 + v0 t - g h² n (n + 1) / 2,
    # explicit y = y0 + v0 t - g h² n (n - 1) / 2
    w = world(FALL.format(integrator=integrator))
    w.advance(100)
    h, n = 0.005, 200
    t = n * h
    k = n + 1 if integrator == "symplectic_euler" else n - 1
    x, y = w.state.body_x[0]
    assert x == pytest.approx(3.0 * t, abs=1e-12)  # m: round-off of 200 sums
    assert y == pytest.approx(10.0 + 5.0 * t - G * h * h * n * k / 2, abs=1e-12)
    assert w.state.body_v[0, 1] == pytest.approx(5.0 - G * t, abs=1e-12)


def test_height_error_sign_is_symplectic_low_explicit_high():
    # first-order errors of opposite sign: symplectic Euler falls faster than the exact
    # parabola (- g h t / 2), explicit Euler slower (+ g h t / 2)
    exact = 10.0 + 5.0 * 1.0 - 0.5 * G
    errors = {}
    for integrator in ("symplectic_euler", "explicit_euler"):
        w = world(FALL.format(integrator=integrator))
        w.advance(100)
        errors[integrator] = w.state.body_x[0, 1] - exact
    expected = 0.5 * G * 0.005 * 1.0  # m: g h t / 2
    assert errors["symplectic_euler"] == pytest.approx(-expected, rel=1e-9)
    assert errors["explicit_euler"] == pytest.approx(expected, rel=1e-9)


SPIN = """
version: 1
world: {{gravity: [0, 0], dt: 0.02, duration: 1}}
solver: {{substeps: 1, rotation: {rotation}}}
bodies:
  - {{name: box, angular_velocity: 20.0, shape: {{box: {{size: [1, 0.5]}}}}}}
"""


@pytest.mark.parametrize("rotation", ["normalize", "exact"])
def test_rotation_turns_by_atan_h_omega_or_h_omega(rotation):
    # normalize(q + h ω×q) turns by atan(h ω) per step; the exact update by h ω
    w = world(SPIN.format(rotation=rotation))
    w.advance(50)
    hw = 0.02 * 20.0
    per_step = math.atan(hw) if rotation == "normalize" else hw
    assert w.state.body_angle[0] == pytest.approx(50 * per_step, abs=1e-12)  # rad
    c, s = w.state.body_q[0]
    assert math.hypot(c, s) == pytest.approx(1.0, abs=1e-15)
    assert math.atan2(s, c) == pytest.approx(math.remainder(50 * per_step, 2 * math.pi), abs=1e-12)


DAMPED = """
version: 1
world: {gravity: [0, 0], dt: 0.01, duration: 1, damping: {linear: 2.0, angular: 5.0}}
solver: {substeps: 4}
bodies:
  - {name: box, velocity: [4, -2], angular_velocity: 3.0, shape: {box: {size: [1, 1]}}}
"""


def test_damping_scales_velocity_by_one_over_one_plus_h_c():
    w = world(DAMPED)
    w.advance(25)
    n, h = 100, 0.0025
    # round-off of 100 products: rtol 1e-13
    want = np.array([4.0, -2.0]) / (1 + h * 2.0) ** n
    np.testing.assert_allclose(w.state.body_v[0], want, rtol=1e-13)
    assert w.state.body_w[0] == pytest.approx(3.0 / (1 + h * 5.0) ** n, rel=1e-13)


FORCE = """
version: 1
world: {gravity: [0, 0], dt: 0.01, duration: 1}
bodies:
  - name: box
    angle: 0.5
    force: [0, 2]
    force_point: [1, 0]
    shape: {box: {size: [2, 1]}}
"""


def test_force_at_arm_gives_torque_r_cross_f():
    w = world(FORCE)
    h = 0.01
    w.stage("integrate_velocities", h=h)
    # the arm turns with the body: r = R(0.5) (1, 0); torque = r × F (N·m)
    r = np.array([math.cos(0.5), math.sin(0.5)])
    torque = r[0] * 2.0 - r[1] * 0.0
    m, inertia = w.model.body_mass[0], w.model.body_inertia[0]
    assert w.state.body_w[0] == pytest.approx(h * torque / inertia, rel=1e-14)
    np.testing.assert_allclose(w.state.body_v[0], [0.0, h * 2.0 / m], rtol=1e-14)


def test_the_package_world_steps_a_scene_and_its_state_is_the_engines_memory():
    import rbsim

    world = rbsim.World.from_scene(
        scene_from(
            """
            version: 1
            world: {gravity: [0, 0], dt: 0.01, steps: 10}
            bodies:
              - {name: ball, position: [0, 0], shape: {circle: {radius: 0.5}}}
            """
        )
    )
    world.state.body_v[0] = (2.0, 0.0)  # a view: writing it sets the engine's state
    x = world.state.body_x  # taken before the steps
    world.advance(10)
    assert world.step_index == 10
    assert x[0, 0] == pytest.approx(0.2, abs=1e-12)  # 10 steps of 0.02 m, seen through it
