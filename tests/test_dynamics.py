"""Free-body dynamics against analytic solutions, with the integrators' known errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

PROJECTILE = """
version: 1
world: {{gravity: [0, -9.81], dt: {dt}, duration: 2.0}}
solver: {{substeps: {sub}, integrator: {integrator}}}
bodies:
  - name: ball
    position: [0, 10]
    velocity: [3, 10]
    shape: {{circle: {{radius: 0.1}}}}
"""


@pytest.mark.parametrize("integrator, sign", [("symplectic_euler", 1.0), ("explicit_euler", -1.0)])
def test_projectile_error_is_the_integrators_first_order_term(run_text, integrator, sign):
    g = np.array([0.0, -9.81])
    errors = []
    for dt in (1 / 60, 1 / 120):
        tr = run_text(PROJECTILE.format(dt=dt, sub=2, integrator=integrator))
        t = tr.time[:, None]
        exact = np.array([0.0, 10.0]) + np.array([3.0, 10.0]) * t + 0.5 * g * t * t
        err = tr.position[:, 0, :] - exact
        h = dt / 2
        # symplectic Euler moves with the new velocity: error + g h t / 2; explicit - g h t / 2
        np.testing.assert_allclose(err, sign * 0.5 * g * h * t, atol=1e-9)
        errors.append(np.abs(err).max())
    assert errors[1] / errors[0] == pytest.approx(0.5, rel=1e-6)


SPIN = """
version: 1
world: {{gravity: [0, 0], dt: 0.016666666666666666, duration: 10.0}}
solver: {{substeps: 4, rotation: {rotation}}}
bodies:
  - name: box
    angular_velocity: 7.0
    shape: {{box: {{size: [1, 0.5]}}}}
"""


def test_free_spin_exact_rotation_keeps_unit_q_and_angle_omega_t(run_text):
    tr = run_text(SPIN.format(rotation="exact"))
    q = tr.orientation[:, 0, :]
    assert np.abs(np.hypot(q[:, 0], q[:, 1]) - 1.0).max() < 1e-12
    assert abs(tr.angle[-1, 0] - 70.0) < 1e-9
    np.testing.assert_allclose(tr.angle[:, 0], 7.0 * tr.time, atol=1e-9)
    # the stored angle is the angle of q, unwrapped
    np.testing.assert_allclose(np.cos(tr.angle[:, 0]), q[:, 0], atol=1e-9)


def test_free_spin_normalize_lags_by_h_omega_minus_atan(run_text):
    tr = run_text(SPIN.format(rotation="normalize"))
    q = tr.orientation[:, 0, :]
    assert np.abs(np.hypot(q[:, 0], q[:, 1]) - 1.0).max() < 1e-12
    h, w = 1 / 60 / 4, 7.0
    n = np.round(tr.time / h)
    lag = n * (h * w - math.atan(h * w))
    np.testing.assert_allclose(7.0 * tr.time - tr.angle[:, 0], lag, atol=1e-9)
    assert lag[-1] > 1e-3  # the lag is real, not rounding
    np.testing.assert_allclose(np.sin(tr.angle[:, 0]), q[:, 1], atol=1e-9)


TORQUE = """
version: 1
world: {{gravity: [0, 0], dt: {dt}, duration: 3.0}}
solver: {{substeps: 1, rotation: exact}}
bodies:
  - name: box
    density: 1.0
    torque: 2.5
    shape: {{box: {{size: [2, 1]}}}}
"""


def test_constant_torque_gives_theta_tau_t2_over_2i(run_text):
    inertia = 2.0 * (4.0 + 1.0) / 12.0
    alpha = 2.5 / inertia
    errs = []
    for dt in (1 / 60, 1 / 120):
        tr = run_text(TORQUE.format(dt=dt))
        t = tr.time
        theta = tr.angle[:, 0]
        # symplectic Euler: θ_n = α t²/2 + α h t/2 exactly
        np.testing.assert_allclose(theta - alpha * t * t / 2, alpha * dt * t / 2, atol=1e-9)
        np.testing.assert_allclose(tr.angular_velocity[:, 0], alpha * t, rtol=1e-12)
        errs.append(np.abs(theta - alpha * t * t / 2).max())
    assert errs[1] / errs[0] == pytest.approx(0.5, rel=1e-6)


def test_force_at_point_adds_torque_r_cross_f(run_text):
    # a unit-density 1 x 1 box pushed up at its right edge: a = F/m, α = (r × F)/I
    tr = run_text(
        """
        version: 1
        world: {gravity: [0, 0], steps: 1, dt: 0.01}
        solver: {substeps: 1}
        bodies:
          - name: box
            force: [0, 3.0]
            force_point: [0.5, 0]
            shape: {box: {size: [1, 1]}}
        """.replace("\n        ", "\n")
    )
    inertia = 1.0 * 2.0 / 12.0
    assert tr.velocity[1, 0, 1] == pytest.approx(3.0 * 0.01, rel=1e-12)
    assert tr.angular_velocity[1, 0] == pytest.approx(0.5 * 3.0 / inertia * 0.01, rel=1e-12)


def test_linear_damping_follows_one_over_one_plus_hc(run_text):
    tr = run_text(
        """
        version: 1
        world: {gravity: [0, 0], steps: 10, dt: 0.1, damping: {linear: 0.5, angular: 2.0}}
        solver: {substeps: 1}
        bodies:
          - name: b
            velocity: [1, 0]
            angular_velocity: 1.0
            shape: {circle: {radius: 0.5}}
        """.replace("\n        ", "\n")
    )
    k = np.arange(11)
    np.testing.assert_allclose(tr.velocity[:, 0, 0], (1 / 1.05) ** k, rtol=1e-12)
    np.testing.assert_allclose(tr.angular_velocity[:, 0], (1 / 1.2) ** k, rtol=1e-12)


@pytest.mark.parametrize("rotation", ["normalize", "exact"])
@pytest.mark.parametrize("dimension", [2, 3])
def test_a_kinematic_body_turns_at_its_angular_velocity_under_any_rotation_update(
    run_text, rotation: str, dimension: int
):
    # a kinematic bar at 20 rad/s, dt 1/30, one substep: `normalize` turned it by
    # atan(h ω) a step, 52.9 rad in 3 s instead of 60 (its motion is given, not solved)
    spin = "20" if dimension == 2 else "[0, 0, 20]"
    shape = "{box: {size: [2, 0.2]}}" if dimension == 2 else "{box: {size: [2, 0.2, 0.2]}}"
    tr = run_text(
        f"""
        version: 1
        world: {{dimension: {dimension}, steps: 90, dt: 1/30, gravity: {[0] * dimension}}}
        solver: {{rotation: {rotation}, substeps: 1}}
        bodies:
          - {{name: bar, type: kinematic, angular_velocity: {spin}, shape: {shape}}}
        """.replace("\n        ", "\n")
    )
    turned = 60.0  # rad: 20 rad/s for 3 s
    if dimension == 2:
        # rad: 90 additions of h ω = 2/3 rad in floating point
        assert tr.angle[-1, 0] == pytest.approx(turned, abs=1e-12)
        q = tr.orientation[-1, 0]
        assert q == pytest.approx([math.cos(turned), math.sin(turned)], abs=1e-12)
    else:
        w, _x, _y, z = tr.orientation[-1, 0]
        # (a quaternion's angle is twice its half angle; its sign is free)
        along = w * math.cos(turned / 2) + z * math.sin(turned / 2)  # cos of the difference
        assert abs(along) == pytest.approx(1.0, abs=1e-12)


def test_static_body_does_not_move_and_kinematic_moves_at_its_velocity(run_text):
    tr = run_text(
        """
        version: 1
        world: {steps: 30, dt: 0.01}
        solver: {rotation: exact}
        bodies:
          - {name: s, type: static, position: [1, 2], shape: {box: {size: [1, 1]}}}
          - {name: k, type: kinematic, velocity: [2, 0], angular_velocity: 1.0,
             shape: {box: {size: [1, 1]}}}
        """.replace("\n        ", "\n")
    )
    assert np.all(tr.position[:, 0] == [1.0, 2.0])
    np.testing.assert_allclose(tr.position[-1, 1], [0.6, 0.0], atol=1e-12)
    np.testing.assert_allclose(tr.angle[-1, 1], 0.3, atol=1e-12)
