"""The penetration ruler (rbsim.core.min_separation, through rbsim.tools.measure):
known gaps and overlaps of every kind of pair, and bad input refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.core import min_separation
from rbsim.scene.compile import build
from rbsim.tools.measure import penetration, touching_pairs

from .conftest import scene_from

SQUARE = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]


def one(verts, shapes, radius, pair=(0, 1)):
    """Separation of two shapes given as (start, count) rows of `verts`."""
    v = np.asarray(verts, np.float64)
    start = np.array([s for s, _ in shapes], np.int32)
    count = np.array([c for _, c in shapes], np.int32)
    return float(min_separation(v, start, count, np.asarray(radius, np.float64), [pair])[0])


@pytest.mark.parametrize("gap", [-0.2, -0.01, 0.0, 0.3])
def test_two_squares_side_by_side_are_apart_by_their_gap(gap):
    right = [[x + 1.0 + gap, y] for x, y in SQUARE]
    assert one(SQUARE + right, [(0, 4), (4, 4)], [0, 0]) == pytest.approx(gap, abs=1e-12)


@pytest.mark.parametrize("gap", [-0.1, 0.0, 0.25])
def test_a_circle_above_a_square_face_and_past_its_corner(gap):
    # the circle is a point core with its radius
    above = SQUARE + [[0.2, 0.5 + 0.3 + gap]]
    assert one(above, [(0, 4), (4, 1)], [0, 0.3]) == pytest.approx(gap, abs=1e-12)
    d = 0.3 + gap  # off the corner (0.5, 0.5) along the diagonal
    corner = SQUARE + [[0.5 + d / math.sqrt(2), 0.5 + d / math.sqrt(2)]]
    assert one(corner, [(0, 4), (4, 1)], [0, 0.3]) == pytest.approx(gap, abs=1e-12)


def test_a_capsule_lying_on_a_square_and_two_circles():
    # a segment core 0.1 above the top face, radius 0.15: overlap 0.05
    verts = SQUARE + [[-0.3, 0.6], [0.3, 0.6]]
    assert one(verts, [(0, 4), (4, 2)], [0, 0.15]) == pytest.approx(-0.05, abs=1e-12)
    circles = [[0.0, 0.0], [3.0, 4.0]]  # centres 5 apart, radii 1 and 2
    assert one(circles, [(0, 1), (1, 1)], [1.0, 2.0]) == pytest.approx(2.0, abs=1e-12)


def test_penetration_of_a_scene_pose_is_its_deepest_overlap():
    scene = scene_from(
        """
        version: 1
        world: {steps: 1}
        bodies:
          - {name: floor, type: static, shape: {box: {size: [10, 1]}}, position: [0, -0.5]}
          - {name: a, position: [0, 0.47], shape: {box: {size: [1, 1]}}}
          - {name: b, position: [3, 0.4], shape: {circle: {radius: 0.5}}}
        """
    )
    model, state = build(scene)
    pairs = touching_pairs(model, state.body_x, state.body_angle, 0.0)
    assert penetration(model, pairs, state.body_x, state.body_angle) == pytest.approx(0.1)
    lifted = state.body_x + np.array([[0, 0], [0, 1], [0, 1]])
    assert penetration(model, pairs, lifted, state.body_angle) == 0.0


def test_bad_input_is_refused_with_a_message():
    v = np.zeros((4, 2))
    with pytest.raises(ValueError):
        min_separation(
            v, np.array([0, 2], np.int32), np.array([2, 3], np.int32), np.zeros(2), [(0, 1)]
        )
    with pytest.raises(ValueError):
        min_separation(
            v, np.array([0, 2], np.int32), np.array([2, 2], np.int32), np.zeros(2), [(0, 5)]
        )
