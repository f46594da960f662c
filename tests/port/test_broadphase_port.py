"""The C++ transform_shapes and find_pairs against the numba ones.

Both engines run the same arithmetic in the same order (no FMA contraction: the build
has no -march), so everything they write must agree to the bit: world vertices and
normals, speculative reach, reference poses, the boxes, the grid's cells, buckets and
entries, and the sorted pair list. The scenes cover the dense (direct-bucket) and the
hashed table, big shapes (long grounds, a fast gas whose cut is raised), compound
bodies, the fresh path (no valid pairs yet), the kept-pairs merge after motion, and the
overflow return and fresh search after the store grows.
"""

from __future__ import annotations

import numpy as np
import pytest

from rbsim.engines.numba.broadphase import BIG_MAX, grow_grid
from rbsim.engines.numba.broadphase import find_pairs as nb_find_pairs
from tests.port.harness import STATE, Pair

PYRAMID = """
version: 1
name: pyramid
world: {gravity: [0, -9.81], dt: 1/60, duration: 5}
materials:
  wood: {density: 1.0, friction: 0.6, restitution: 0.0}
bodies:
  - {name: ground, type: static, material: wood, shape: {segment: {a: [-20, 0], b: [20, 0]}}}
  - pyramid: {base: 10, size: [1, 1], origin: [0, 0.5], material: wood}
"""

# 1000 circles poured into a box: the dense table, many pairs, a settling pile
CIRCLES = """
version: 1
name: circles
world: {gravity: [0, -9.81], dt: 1/60, duration: 5}
materials:
  m: {density: 1.0, friction: 0.3, restitution: 0.1}
bodies:
  - {name: floor, type: static, position: [0, -0.5], material: m, shape: {box: {size: [11, 1]}}}
  - {name: left, type: static, position: [-5.25, 6], material: m, shape: {box: {size: [0.5, 12]}}}
  - {name: right, type: static, position: [5.25, 6], material: m, shape: {box: {size: [0.5, 12]}}}
  - grid: {name: c, count: [40, 25], spacing: [0.24, 0.3], origin: [-4.7, 1.0],
           velocity: [0.4, -1], material: m, shape: {circle: {radius: 0.1}}}
"""

# boxes, circles, a post, a compound crate, and a second cluster at `far` (5000 m away:
# the occupied cells no longer fit the table, so cells are hashed)
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
           material: m, shape: {{polygon: {{vertices: [[0, 0], [0.3, 0], [0.15, 0.3]]}}}}}}
  - name: crate
    position: [0, 9]
    shapes:
      - {{box: {{size: [2, 0.5]}}}}
      - {{circle: {{radius: 0.3, offset: [-1.2, 0]}}}}
      - {{segment: {{a: [1.0, 0.3], b: [1.4, 0.8], radius: 0.05}}}}
"""

# two clusters of capsules and circles 1e4 m apart: hashed
CLUSTERS = """
version: 1
name: clusters
world: {gravity: [0, -9.81], dt: 1/60, duration: 2}
bodies:
  - {name: g1, type: static, shape: {segment: {a: [-5, 0], b: [5, 0]}}}
  - {name: g2, type: static, shape: {segment: {a: [9995, 0], b: [10005, 0]}}}
  - grid: {name: a, count: [10, 6], spacing: [0.5, 0.5], origin: [-2.5, 0.5], velocity: [1, 0],
           shape: {segment: {a: [-0.15, 0], b: [0.15, 0], radius: 0.08}}}
  - grid: {name: b, count: [10, 6], spacing: [0.5, 0.5], origin: [9997.5, 0.5], velocity: [-1, 0],
           shape: {circle: {radius: 0.2}}}
"""

# at 60 m/s each ball's speculative reach spans more than a cell: the cut is raised
GAS = """
version: 1
name: gas
world: {gravity: [0, 0], dt: 1/60, duration: 1}
bodies:
  - {name: wall, type: static, shape: {segment: {a: [-30, -8], b: [30, -8]}}}
  - grid: {name: g, count: [12, 8], spacing: [1.0, 1.0], origin: [-6, -4],
           velocity: [60, 60], shape: {circle: {radius: 0.2}}}
  - grid: {name: h, count: [6, 4], spacing: [2.0, 2.0], origin: [-6, 6],
           velocity: [-40, 10], shape: {box: {size: [1.5, 0.6]}}}
"""

SCENES = {
    "pyramid": PYRAMID,
    "circles": CIRCLES,
    "pile_dense": PILE.format(far=-5, far_end=-2),
    "pile_hashed": PILE.format(far=5000, far_end=5003),
    "clusters": CLUSTERS,
    "gas": GAS,
}
DENSE = {"pyramid": 1, "circles": 1, "pile_dense": 1, "pile_hashed": 0, "clusters": 0}

CONTACT_OUT = ("vert_world", "norm_world", "shape_margin", "body_ref", "body_still")
GRID = (
    "inv_cell", "shape_aabb", "shape_fat", "shape_moved", "shape_big", "shape_cell",
    "shape_bucket", "entry_shape", "entry_cell", "entry_fat", "entry_tag", "bucket_start",
    "big_list", "span", "meta", "new_keys", "kept", "sort_scratch", "sort_count",
)  # fmt: skip
# what the two stages write (the other arrays are synced and untouched; the harness's
# diff reports equal infinities, as in approach_velocity, as a difference)
WRITTEN = CONTACT_OUT + ("pairs",) + tuple("grid." + g for g in GRID)


def _pairs_agree(pair: Pair, r: int, rc: int) -> None:
    """The counts, the pair lists and every array both engines hold agree exactly."""
    assert r == rc == pair.cc.storage.count[2] == pair.nb.contacts.count[2]
    n = int(r)
    np.testing.assert_array_equal(pair.cc.storage.pairs[:n], pair.nb.contacts.pairs[:n])
    assert pair.diff(WRITTEN) == {}


def _transform_and_pairs(pair: Pair) -> int:
    pair.run("transform_shapes")
    assert pair.diff(CONTACT_OUT) == {}
    r, rc = pair.run("find_pairs")
    _pairs_agree(pair, r, rc)
    return int(r)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("steps", [0, 7, 45])
def test_transform_and_find_pairs_agree(name: str, steps: int) -> None:
    pair = Pair.from_text(SCENES[name])
    pair.advance_numba(steps)
    pair.sync()
    n = _transform_and_pairs(pair)
    assert n > 0
    meta = pair.nb.grid.meta
    if name in DENSE:
        assert meta[2] == DENSE[name]
    if name == "gas":
        cell = 1.0 / pair.nb.grid.inv_cell
        fat = pair.nb.grid.shape_fat
        wide = np.maximum(fat[:, 2] - fat[:, 0], fat[:, 3] - fat[:, 1]) > cell
        assert wide.sum() > BIG_MAX and meta[0] <= BIG_MAX  # the raised cut at work


@pytest.mark.parametrize("name", ["pyramid", "circles", "pile_hashed", "gas"])
def test_pairs_follow_motion(name: str) -> None:
    """Synced once, then each engine keeps its own grid and pair list while only the
    bodies' state is copied step by step: the kept pairs of shapes that did not move
    are merged with the new ones (in a resting pyramid none moves: the list stays)."""
    pair = Pair.from_text(SCENES[name])
    pair.advance_numba(3)
    pair.sync()
    merged = still = 0
    for _ in range(12):
        _transform_and_pairs(pair)
        moved = pair.nb.grid.shape_moved
        merged += bool(moved.any() and not moved.all())
        still += bool(not moved.any())
        pair.advance_numba(1)
        for key in STATE:
            getattr(pair.cc.state, key)[...] = getattr(pair.nb.state, key)
        assert pair.cc.storage.pairs.shape == pair.nb.contacts.pairs.shape  # no growth
    if name == "pyramid":
        assert still > 0  # a resting stack: no box left its fat box, the list is kept
    else:
        assert merged > 0  # the merge path ran


@pytest.mark.parametrize("name", ["circles", "pile_hashed", "gas"])
def test_pairs_after_the_store_grows(name: str) -> None:
    """Too small a store: both return the count needed; grown to twice that, both find
    the whole list anew."""
    pair = Pair.from_text(SCENES[name])
    pair.advance_numba(10)
    pair.sync()
    pair.run("transform_shapes")
    nb, cs = pair.nb, None
    m, c = nb.model, nb.contacts

    def copy_geometry():
        s = pair.cc.storage
        s.vert_world[...] = c.vert_world
        s.shape_margin[...] = c.shape_margin
        return s

    small = 8
    grid = grow_grid(nb.grid, small)
    r = nb_find_pairs(m, grid, c.vert_world, c.shape_margin, np.zeros((small, 2), np.int32), 0)
    # World::grow keeps last step's manifolds: none, since the store shrinks here
    pair.cc.storage.count[1] = 0
    pair.cc.engine.grow(small)
    cs = copy_geometry()
    assert cs.count[2] == 0 and cs.grid.meta[1] == 0
    rc = pair.cc.engine.stage("find_pairs", {})
    assert r == rc > small
    assert cs.grid.meta[1] == 0  # the list is invalid

    big = 2 * int(r)
    grid = grow_grid(grid, big)
    pairs = np.zeros((big, 2), np.int32)
    r = nb_find_pairs(m, grid, c.vert_world, c.shape_margin, pairs, 0)
    pair.cc.engine.grow(big)
    cs = copy_geometry()
    rc = pair.cc.engine.stage("find_pairs", {})
    assert r == rc <= big
    np.testing.assert_array_equal(cs.pairs[: int(r)], pairs[: int(r)])
    for key in ("shape_aabb", "shape_fat", "shape_cell", "bucket_start", "entry_shape", "meta"):
        np.testing.assert_array_equal(getattr(cs.grid, key), np.asarray(getattr(grid, key)))


@pytest.mark.parametrize("name", SCENES)
def test_fresh_engines_agree(name: str) -> None:
    """Without a sync: the C++ grid as allocated (cell size from the median shape,
    table size, capacities) finds the same first pair list as numba's."""
    pair = Pair.from_text(SCENES[name])
    assert float(pair.cc.storage.grid.inv_cell) == pair.nb.grid.inv_cell
    _transform_and_pairs(pair)
