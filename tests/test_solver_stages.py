"""The contact solver through the engine's API: an isolated impact, Coulomb friction on a
slope, a resting stack's impulses and warm starting. Tolerances allow for round-off and
for the solver's settling, not for a different law: each states why it is what it is."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.core import CoreWorld
from tests.conftest import scene_from

G = 9.81  # m/s²
DT = 1 / 60  # s

HEAD_ON = """
version: 1
world: {{gravity: [0, 0], dt: 1/60, duration: 1}}
materials:
  m: {{density: 1.0, friction: 0.0, restitution: {e}}}
bodies:
  - {{name: a, material: m, mass: 1.0, position: [-0.26, 0], velocity: [3, 0],
      shape: {{circle: {{radius: 0.25}}}}}}
  - {{name: b, material: m, mass: 2.0, position: [0.26, 0], velocity: [-1, 0],
      shape: {{circle: {{radius: 0.25}}}}}}
"""


def world(text: str) -> CoreWorld:
    return CoreWorld.from_scene(scene_from(text))


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_isolated_collision_matches_restitution_formula(e):
    # the impulse of a two-body impact is γ = (1 + e) m_eff |v_n⁻|, m_eff = m1 m2 / (m1 + m2)
    w = world(HEAD_ON.format(e=e))
    m1, m2 = w.model.body_mass
    w.advance(20)
    v = w.state.body_v
    gamma = (1 + e) * (m1 * m2 / (m1 + m2)) * 4.0  # N·s: approach at 4 m/s
    # round-off only: the impact is resolved exactly (e = 0 by the rigid relax pass,
    # e > 0 by the restitution stage's lone-pair bounce)
    assert m1 * (v[0, 0] - 3.0) == pytest.approx(-gamma, abs=1e-12)
    assert m2 * (v[1, 0] + 1.0) == pytest.approx(gamma, abs=1e-12)
    np.testing.assert_array_equal(v[:, 1], 0.0)


def slope(mu: float, theta: float) -> str:
    # a static 20 m slab turned by theta, a 0.5 m block resting on its top face
    nx, ny = -math.sin(theta), math.cos(theta)
    return f"""
version: 1
world: {{gravity: [0, -9.81], dt: 1/60, duration: 5}}
materials:
  m: {{density: 1.0, friction: {mu}, restitution: 0.0}}
bodies:
  - {{name: slope, type: static, material: m, angle: {theta}, shape: {{box: {{size: [20, 1]}}}}}}
  - name: block
    material: m
    position: [{0.75 * nx}, {0.75 * ny}]
    angle: {theta}
    shape: {{box: {{size: [0.5, 0.5]}}}}
"""


THETA = math.radians(20)
DOWNHILL = np.array([-math.cos(THETA), -math.sin(THETA)])


def test_block_sticks_on_slope_when_mu_exceeds_tan_theta():
    w = world(slope(0.6, THETA))  # tan 20° = 0.364
    x0 = w.state.body_x[1].copy()
    w.advance(300)
    # the block jitters by ~20 µm on its soft contacts (measured), without creeping
    assert abs((w.state.body_x[1] - x0) @ DOWNHILL) < 1e-4
    assert abs(w.state.body_v[1] @ DOWNHILL) < 1e-3


def test_block_slides_at_g_sin_minus_mu_cos():
    w = world(slope(0.1, THETA))
    w.advance(30)  # past the first contact's settling
    v1 = w.state.body_v[1] @ DOWNHILL
    w.advance(60)
    v2 = w.state.body_v[1] @ DOWNHILL
    a = (v2 - v1) / (60 * DT)
    # a sliding block's friction is μ λn every substep: the law holds to round-off
    # (1e-13 measured); 1e-6 leaves room for the solver's order of operations
    assert a == pytest.approx(G * (math.sin(THETA) - 0.1 * math.cos(THETA)), rel=1e-6)
    assert abs(w.state.body_w[1]) < 1e-9  # rad/s: a flat face slides without tipping


STACK = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, duration: 5}
solver: {substeps: 4}
materials:
  wood: {density: 1.0, friction: 0.6, restitution: 0.0}
bodies:
  - {name: ground, type: static, material: wood, shape: {segment: {a: [-5, 0], b: [5, 0]}}}
  - {name: b0, material: wood, position: [0, 0.5], shape: {box: {size: [1, 1]}}}
  - {name: b1, material: wood, position: [0, 1.5], shape: {box: {size: [1, 1]}}}
  - {name: b2, material: wood, position: [0, 2.5], shape: {box: {size: [1, 1]}}}
"""


def manifold_of(c, i: int, j: int) -> int:
    n = int(c.count[0])
    for m in range(n):
        if {int(c.body_a[m]), int(c.body_b[m])} == {i, j}:
            return m
    raise AssertionError(f"no manifold between bodies {i} and {j}")


def test_resting_stack_impulses_carry_the_weight_above():
    w = world(STACK)
    w.advance(120)  # settled
    c = w.contacts
    mass = w.model.body_mass[1]  # kg, every box
    for lower, boxes_above in ((0, 3), (1, 2), (2, 1)):
        m = manifold_of(c, lower, lower + 1)
        # normal_impulse is per substep: times the substeps, the step's impulse. At rest
        # the contacts hold the weight to round-off (1e-15 measured)
        per_step = c.normal_impulse[m].sum() * w.config.substeps
        assert per_step == pytest.approx(boxes_above * mass * G * DT, rel=1e-9)
        # a flat face: both points carry half
        assert c.normal_impulse[m, 0] == pytest.approx(c.normal_impulse[m, 1], rel=1e-12)


def test_warm_start_second_step_begins_with_first_steps_impulse():
    w = world(STACK)
    # settled to round-off (the ground contact, as stiff as the others at dt 1/60 since
    # 2026-12-05, takes longer: at step 120 its impulse still moved by 1.4e-12 a step)
    w.advance(240)
    c = w.contacts
    m = manifold_of(c, 0, 1)
    w.advance(1)
    first = c.normal_impulse[m].copy()
    w.advance(1)
    # the step starts from the last one's impulses (start_impulse) and, at rest, ends
    # where it began: equal to round-off
    np.testing.assert_array_equal(c.start_impulse[m], first)
    np.testing.assert_allclose(c.normal_impulse[m], first, rtol=1e-12)
