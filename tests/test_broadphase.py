"""Broadphase against brute force: after every step the pair list must hold exactly the
pairs of overlapping fat boxes (different bodies, at least one dynamic), sorted, both
when the grid's cells are their own buckets and when shapes far apart force hashing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rbsim.constants import BIG_MAX
from rbsim.core import CoreWorld as World
from rbsim.scene import load_scene
from rbsim.scene.types import BODY_DYNAMIC

from .conftest import scene_from, vector

ROOT = Path(__file__).resolve().parents[1]

PILE = """
version: 1
name: pile
world: {{gravity: [0, -10], dt: 1/60, duration: 2}}
materials:
  m: {{density: 1.0, friction: 0.5, restitution: 0.1}}
bodies:
  - {{name: floor, type: static, shape: {{segment: {{a: [-6, 0], b: [6, 0]}}}}}}
  - {{name: far_floor, type: static, shape: {{segment: {{a: [{far}, -3], b: [{far_end}, -3]}}}}}}
  - {{name: post, type: static, position: [2, 0.5], shape: {{box: {{size: [0.4, 1]}}}}}}
  - grid: {{name: ball, count: [12, 6], spacing: [0.6, 0.6], origin: [-4, 1], velocity: [0.5, 0],
           material: m, shape: {{circle: {{radius: 0.22}}}}}}
  - grid: {{name: brick, count: [8, 4], spacing: [0.9, 0.9], origin: [-3.5, 5], velocity: [0, -3],
           material: m, shape: {{box: {{size: [0.7, 0.4]}}}}}}
  - grid: {{name: far, count: [3, 3], spacing: [0.5, 0.5], origin: [{far}, 0],
           material: m, shape: {{circle: {{radius: 0.2}}}}}}
  - name: crate
    position: [0, 9]
    shapes:
      - {{box: {{size: [2, 0.5]}}}}
      - {{circle: {{radius: 0.3, offset: [-1.2, 0]}}}}
"""


def brute_pairs(world: World) -> np.ndarray:
    """All pairs a < b whose fat boxes overlap, of different bodies, one dynamic."""
    fat = world.grid.shape_fat
    body = world.model.shape_body
    dyn = world.model.body_type[body] == BODY_DYNAMIC
    a, b = np.triu_indices(fat.shape[0], 1)
    keep = (
        (fat[a, 0] <= fat[b, 2])
        & (fat[b, 0] <= fat[a, 2])
        & (fat[a, 1] <= fat[b, 3])
        & (fat[b, 1] <= fat[a, 3])
        & (body[a] != body[b])
        & (dyn[a] | dyn[b])
    )
    return np.stack([a[keep], b[keep]], axis=1)  # row-major: sorted by (a, b)


@pytest.mark.parametrize("far, dense", [(-5, True), (5000, False)])
def test_pairs_match_brute_force(far: float, dense: bool) -> None:
    world = World.from_scene(scene_from(PILE.format(far=far, far_end=far + 3)))
    for _ in range(90):
        world.advance(1)
        n = int(world.contacts.count[2])
        assert bool(world.grid.meta[2]) == dense
        np.testing.assert_array_equal(world.contacts.pairs[:n], brute_pairs(world))


GAS = """
version: 1
name: gas
world: {{gravity: [0, 0], dt: 1/60, duration: 1}}
bodies:
  - {{name: wall, type: static, shape: {{segment: {{a: [-30, -8], b: [30, -8]}}}}}}
  - grid: {{name: g, count: [12, 4], spacing: [1.0, 1.0], origin: [-6, -4],
           velocity: [{speed}, {speed}], shape: {{circle: {{radius: 0.2}}}}}}
  - grid: {{name: h, count: [12, 4], spacing: [1.0, 1.0], origin: [-5.5, 0.5],
           velocity: [-{speed}, -{speed}], shape: {{circle: {{radius: 0.2}}}}}}
  - grid: {{name: r, count: [12, 4], spacing: [1.0, 1.0], origin: [-6, 4.5],
           shape: {{circle: {{radius: 0.2}}}}}}
"""


def test_a_fast_gas_stays_in_the_grid() -> None:
    # two streams crossing at 60 m/s through balls at rest (the frame velocity, about
    # which the boxes reach, is the median one, at rest): each streaming ball's
    # speculative reach spans more than a cell: were every such
    # shape "big" (tested against every shape), the broadphase would cost N² per step.
    # The cut rises until at most BIG_MAX shapes are big; the pairs stay exact
    world = World.from_scene(scene_from(GAS.format(speed=60.0)))
    for _ in range(20):
        world.advance(1)
        cell = 1.0 / world.grid.inv_cell
        fat = world.grid.shape_fat
        wide = np.maximum(fat[:, 2] - fat[:, 0], fat[:, 3] - fat[:, 1]) > cell
        assert wide.sum() > BIG_MAX  # the case at hand: most balls wider than a cell
        assert world.grid.meta[0] <= BIG_MAX  # the big shapes
        n = int(world.contacts.count[2])
        np.testing.assert_array_equal(world.contacts.pairs[:n], brute_pairs(world))


FALL = """
version: 1
name: fall
world: {gravity: [0, -9.81], dt: 1/60, duration: 2}
bodies:
  - {name: floor, type: static, shape: {segment: {a: [-5, -500], b: [5, -500]}}}
  - grid: {name: b, count: [4, 3], spacing: [1.5, 1.5], origin: [-2, 0],
           shape: {box: {size: [1, 1]}}}
"""


def test_a_falling_shape_is_queried_again_every_few_steps_not_every_step() -> None:
    # at 5 to 15 m/s a box moves 8 to 25 cm a step, far past the fat margin (2 cm): its
    # fat box also reaches four of its last step's displacements ahead (at most half its
    # width), so the grid is queried on fewer than half the steps; the pairs stay exact
    world = World.from_scene(scene_from(FALL))
    world.advance(30)  # falling at 5 m/s
    queried = 0
    for _ in range(60):
        world.advance(1)
        queried += bool(world.grid.shape_moved[1:].any())  # the boxes (0: the floor)
        n = int(world.contacts.count[2])
        np.testing.assert_array_equal(world.contacts.pairs[:n], brute_pairs(world))
    assert queried < 30


def test_a_step_begun_again_after_the_store_grew_gives_the_same_bits() -> None:
    # a step that finds the contact store's room for pairs too small grows it and begins
    # again; that step must carry the same contacts (its manifolds compared with the
    # offsets and rotations they were found at) as in a world whose store was large from
    # the start. Only the pairs' room grows: the rain finds four pairs for every manifold
    # as it lands, and the manifolds have room enough (cpp/tests/test_step.cpp grows theirs)
    scene = load_scene(ROOT / "bench/scenes/rain800.yaml")  # its pairs outgrow it at step 98
    small, large = World.from_scene(scene), World.from_scene(scene)
    large.engine.grow(1 << 16)
    start, start_pairs = small.contacts.key.shape[0], small.contacts.pairs.shape[0]
    small.advance(120)
    large.advance(120)
    assert small.contacts.pairs.shape[0] > start_pairs  # the case at hand: the room grew
    assert small.contacts.key.shape[0] == start  # and the manifolds' did not
    for name in ("body_x", "body_q", "body_angle", "body_v", "body_w"):
        np.testing.assert_array_equal(getattr(small.engine, name), getattr(large.engine, name))


HEAP = """
version: 1
name: heap
world: {dimension: 3, gravity: [0, -9.81, 0], dt: 1/240, duration: 10}
bodies:
  - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0], offset: 0}}}
  - grid: {name: b, count: [5, 4, 5], spacing: [0.6, 0.6, 0.6], origin: [-1.2, 500, -1.2],
           shape: {box: {size: [0.5, 0.5, 0.5]}}}
"""


def test_a_heap_falling_as_one_has_no_contacts_and_is_not_queried_again() -> None:
    # 100 boxes 10 cm apart fall side by side: their speculative distance is their
    # relative move (none), not each one's own (20 m/s after 2 s: 8 cm a step each, once
    # 17 cm a pair, beyond the 10 cm gaps: 240 speculative manifolds a step, every box
    # queried every step); the boxes' frame falls with them (grid.frame_offset), so the
    # ground, not the boxes, is what moves in the grid. The pairs stay exact
    world = World.from_scene(scene_from(HEAP))
    start = world.state.body_x[1:].copy()
    world.advance(480)  # 2 s: 19.6 m/s
    queried = 0
    for _ in range(120):
        before = world.state.body_x[1:].copy()
        world.advance(1)
        assert int(world.contacts.count[0]) == 0  # manifolds
        queried += int(world.grid.shape_moved[1:].sum())
    assert queried == 0
    # the frame moves by the boxes' last step's move: as far as they fell before this one
    fell = before - start  # m, every box as far
    np.testing.assert_allclose(world.grid.frame_origin.ravel(), fell[0], rtol=0, atol=1e-9)
    assert fell[0][1] < -30


def belt_stack(dimension: int) -> str:
    """Four unit boxes stacked on a kinematic belt moving at 1 m/s along x, each box moving
    with it from the start (no slip to settle)."""
    v = vector(dimension, 1, 0, 0)
    size = vector(dimension, 1, 1, 1)
    world = "{dimension: 3, dt: 1/60, duration: 5}" if dimension == 3 else "{dt: 1/60, duration: 5}"
    boxes = "".join(
        f"  - {{name: b{k}, position: {vector(dimension, 0, 0.5 + k, 0)}, velocity: {v},"
        f" shape: {{box: {{size: {size}}}}}}}\n"
        for k in range(4)
    )
    return (
        f"version: 1\nworld: {world}\nbodies:\n"
        f"  - {{name: belt, type: kinematic, position: {vector(dimension, 0, -0.5, 0)},"
        f" velocity: {v}, shape: {{box: {{size: {vector(dimension, 400, 1, 4)}}}}}}}\n" + boxes
    )


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_stack_riding_a_belt_keeps_its_manifolds(dimension: int) -> None:
    # the stack moves 1.7 cm a step with the belt, 170 times STILL_DISTANCE, but not one
    # box against another: each pair's manifold is carried (contacts.ref_offset), where
    # with each body held to its own place every manifold was found again every step
    world = World.from_scene(scene_from(belt_stack(dimension)))
    world.advance(60)
    carried = []
    for _ in range(60):
        world.advance(1)
        n = int(world.contacts.count[0])
        assert n == 4  # the belt's and the three between the boxes
        carried.append(world.contacts.carried[:n].mean())
    assert np.mean(carried) > 0.9  # (a turn past STILL_ANGLE may find one again now and then)
    # and the stack stands on the belt, riding it
    x = world.state.body_x
    np.testing.assert_allclose(x[1:, 0] - x[0, 0], 0.0, atol=1e-3)  # m: no slip, no lean
