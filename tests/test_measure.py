"""The penetration ruler (rbsim.core.min_separation, through rbsim.tools.measure):
known gaps and overlaps of every kind of pair, and bad input refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.core import min_separation
from rbsim.scene.compile import build
from rbsim.tools import measure
from rbsim.tools.measure import deepest_overlap, penetration, touching_pairs

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


# A pile of boxes, discs and a capsule on a floor and a wall (static), shaken at random:
# many frames with overlaps of every kind of pair, and pairs of statics (never counted).
SHAKEN = """
version: 1
world: {steps: 1}
bodies:
  - {name: floor, type: static, shape: {box: {size: [20, 1]}}, position: [0, -0.5]}
  - {name: wall, type: static, shape: {segment: {a: [-3, 0], b: [-3, 6]}}}
  - grid: {name: box, count: [5, 4], spacing: [0.9, 0.9], origin: [-2, 0.5],
           shape: {box: {size: [1, 1]}}}
  - grid: {name: disc, count: [4, 3], spacing: [1.0, 0.9], origin: [-1.5, 4.2],
           shape: {circle: {radius: 0.45}}}
  - {name: rod, position: [0, 7], shape: {segment: {a: [-1, 0], b: [1, 0], radius: 0.2}}}
"""


def shaken_poses(frames: int, seed: int = 3):
    model, state = build(scene_from(SHAKEN))
    rng = np.random.default_rng(seed)
    n = state.body_x.shape[0]
    moving = (model.body_type != model.body_type[0])[:, None]  # body 0 (floor) is static
    moving[1] = False  # and the wall
    x = state.body_x + rng.normal(0.0, 0.08, (frames, n, 2)) * moving
    theta = state.body_angle + rng.normal(0.0, 0.2, (frames, n)) * moving[:, 0]
    return model, x, theta


def per_frame_deepest(model, x, theta) -> float:
    return max(
        penetration(model, touching_pairs(model, x[t], theta[t], 0.0), x[t], theta[t])
        for t in range(len(x))
    )


@pytest.mark.parametrize("dense_shapes", [measure.DENSE_SHAPES, 0])  # dense test, sweep
def test_deepest_overlap_of_many_poses_is_the_deepest_of_each_pose(monkeypatch, dense_shapes):
    monkeypatch.setattr(measure, "DENSE_SHAPES", dense_shapes)
    monkeypatch.setattr(measure, "DENSE_PAIRS", 2000)  # several chunks of frames
    model, x, theta = shaken_poses(30)
    want = per_frame_deepest(model, x, theta)
    assert want > 0.05  # the shaking makes real overlaps
    assert deepest_overlap(model, x, theta) == want  # the same ruler: the same digits
    for t in range(len(x)):  # and frame by frame: a pair left out shows in some frame
        alone = per_frame_deepest(model, x[t : t + 1], theta[t : t + 1])
        assert deepest_overlap(model, x[t : t + 1], theta[t : t + 1]) == alone, t


def test_deepest_overlap_leaves_out_bodies_not_measured():
    model, x, theta = shaken_poses(10)
    known = np.ones(x.shape[1], bool)
    known[0] = False  # the floor: its overlaps with the bottom row no longer count
    far = x.copy()
    far[:, 0] = [1e4, 1e4]  # as if the floor were far away
    assert deepest_overlap(model, x, theta, known) == per_frame_deepest(model, far, theta)
    assert deepest_overlap(model, x[:0], theta[:0]) == 0.0


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


class _Clocked:
    """A stand-in engine for the stopwatch: each advance(n) moves a shared fake clock by
    n steps of `cost` seconds, and logs its name, so the order of the blocks shows."""

    def __init__(self, name: str, cost: float, clock: list[float], log: list[str]) -> None:
        self.name, self.cost, self.clock, self.log = name, cost, clock, log

    def advance(self, n: int) -> None:
        self.clock[0] += n * self.cost
        self.log.append(self.name)


def test_interleaved_blocks_alternate_and_time_each_engine_alone():
    clock, log = [0.0], []
    a = _Clocked("a", 2e-6, clock, log)
    b = _Clocked("b", 5e-6, clock, log)
    times = measure.interleaved_block_times([a, b], 3, 10, 4, lambda: clock[0])
    # the warm-ups first, then the blocks in turn (a slow spell falls on both alike)
    assert log == ["a", "b"] + ["a", "b"] * 4
    # 1e-9 µs: the fake clock's sums of microsecond costs, rounded
    assert times[0] == pytest.approx([2.0] * 4, abs=1e-9)
    assert times[1] == pytest.approx([5.0] * 4, abs=1e-9)
    assert measure.block_times(a, 0, 10, 2, lambda: clock[0]) == pytest.approx([2.0, 2.0])


def test_the_median_ratio_pairs_the_rounds():
    # a round's two blocks are divided, then the median taken: a slow round (the machine
    # busy for both blocks) keeps its ratio, and one odd pair does not move the median
    a = [1.0, 1.0, 4.0, 1.0, 3.0]
    b = [2.0, 2.0, 8.0, 2.0, 2.0]
    assert measure.median_ratio(a, b) == 0.5
    assert measure.median_ratio([1.0, 3.0], [1.0, 1.0]) == 2.0  # even count: the middle two
    assert math.isnan(measure.median_ratio([1.0], [0.0]))  # no valid pair
