"""The shock pass through the engine's API: a heavy box falling onto a light one has its
approach removed against the light one held still; nothing happens without gravity."""

from __future__ import annotations

import numpy as np

from rbsim.core import CoreWorld
from tests.conftest import scene_from

HEAVY_ON_LIGHT = """
version: 1
world: {{gravity: [0, {g}], dt: 1/60, duration: 2}}
materials:
  m: {{density: 1.0, friction: 0.6, restitution: 0.0}}
bodies:
  - {{name: ground, type: static, material: m, shape: {{segment: {{a: [-5, 0], b: [5, 0]}}}}}}
  - {{name: light, material: m, mass: 1.0, position: [0, 0.5], shape: {{box: {{size: [1, 1]}}}}}}
  - {{name: heavy, material: m, mass: 100.0, position: [0, 1.5], shape: {{box: {{size: [1, 1]}}}}}}
"""


def collided(g: float) -> tuple[CoreWorld, int]:
    """The world after the step's collision stages, the heavy box falling at 2 m/s onto
    the light one; returns it and the shock pass's manifold count."""
    w = CoreWorld.from_scene(scene_from(HEAVY_ON_LIGHT.format(g=g)))
    w.state.body_v[2] = [0.0, -2.0]
    w.stage("transform_shapes")
    n_pairs = w.stage("find_pairs")
    w.stage("update_manifolds", n_pairs=n_pairs)
    w.stage("prepare_contacts")
    return w, w.stage("support_order")


def shock(w: CoreWorld, n_order: int) -> None:
    h = w.config.dt / w.config.substeps
    w.stage("propagate_shock", n_order=n_order, inv_h=1.0 / h, threshold=1.0)


def test_heavy_box_on_light_one_is_stopped_against_it():
    w, n_order = collided(-9.81)
    c = w.contacts
    assert n_order == 2  # ground-light and light-heavy: both supported from below
    assert list(c.body_level[:3]) == [0, 1, 2]
    shock(w, n_order)
    v = w.state.body_v
    # the light box is held still: not pushed into the ground by the heavy one's fall
    np.testing.assert_array_equal(v[1], [0.0, 0.0])
    assert w.state.body_w[1] == 0.0
    # the heavy box's approach is removed (the boxes touch, to a gap of ~1e-16 m, so
    # the allowed closing speed gap / h is round-off)
    assert abs(v[2, 1]) < 1e-12
    assert abs(w.state.body_w[2]) < 1e-12


def test_shock_pass_leaves_a_separating_body_alone():
    w, n_order = collided(-9.81)
    w.state.body_v[2] = [0.2, 1.0]  # leaving the light box
    before = w.state.body_v.copy()
    shock(w, n_order)
    np.testing.assert_array_equal(w.state.body_v, before)


def test_no_gravity_nothing_changes():
    w, n_order = collided(0.0)
    assert n_order == 0  # no support without gravity
    names = ("body_x", "body_v", "body_w")
    before = {k: getattr(w.state, k).copy() for k in names}
    shock(w, n_order)
    for k in names:
        np.testing.assert_array_equal(getattr(w.state, k), before[k])
