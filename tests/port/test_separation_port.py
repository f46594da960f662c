"""The C++ penetration ruler (cpp/src/tools/separation.cpp, rbsim._core.min_separation)
against the numba kernels it was ported from (tests/port/separation_numba.py:
min_separation and the two it calls), and rbsim.tools.measure.penetration over it.

Both do the same operations in the same order without fused multiply-adds, so every
pair's separation must be bit-identical; the scenes are stepped (or posed at random, to
overlap deeply) so that every branch is met: circle-circle, a circle centre inside and
outside a polygon, against a segment or a capsule, polygon-polygon, segment-polygon.
"""

from __future__ import annotations

import numpy as np
import pytest

from rbsim import _core
from rbsim.core import min_separation
from rbsim.engines.numba.world import World
from rbsim.scene import load_scene_text
from rbsim.tools import measure as M

from . import separation_numba as NB

SCENE = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 1000}
materials:
  m: {density: 1.0, friction: 0.4, restitution: 0.2}
bodies:
  - {name: ground, type: static, material: m, shape: {segment: {a: [-20, 0], b: [20, 0]}}}
  - {name: wall, type: static, material: m,
     shape: {segment: {a: [6, 0], b: [6, 8], radius: 0.1}}}
  - pyramid: {base: 4, size: [1, 1], origin: [-3, 0.5], material: m}
  - grid: {count: [4, 3], spacing: [0.9, 0.9], origin: [1.5, 1], material: m,
      shape: {circle: {radius: 0.5}}}
  - {name: tri, position: [-3, 6], angle: 0.4, material: m,
     shape: {polygon: {vertices: [[-0.6, -0.4], [0.7, -0.3], [0.0, 0.6]]}}}
  - {name: capsule, position: [4.5, 5], angle: 1.0, material: m,
     shape: {segment: {a: [-0.6, 0], b: [0.6, 0], radius: 0.25}}}
  - {name: rod, type: kinematic, position: [0.5, 2], angle: -0.3, material: m,
     shape: {segment: {a: [-1, 0], b: [1, 0]}}}
  - {name: crate, position: [3, 8], material: m,
     shapes: [{box: {size: [1, 0.6]}}, {circle: {radius: 0.3, offset: [0.6, 0.3]}}]}
"""


def cxx(verts, model, pairs):
    return _core.min_separation(
        np.ascontiguousarray(verts, dtype=np.float64),
        model.shape_vstart.astype(np.int32),
        model.shape_vcount.astype(np.int32),
        model.shape_radius.astype(np.float64),
        np.ascontiguousarray(pairs, dtype=np.int32).reshape(-1, 2),
    )


def compare(model, x, theta, pairs) -> np.ndarray:
    """Every pair's separation from both; asserts them bit-identical. Returns them."""
    verts = M.vertices_world(model, x, theta)
    got = cxx(verts, model, pairs)
    assert got.shape == (pairs.shape[0],) and got.dtype == np.float64
    want = np.array(
        [
            NB.min_separation(
                verts, model.shape_vstart, model.shape_vcount, model.shape_radius, pairs[p : p + 1]
            )
            for p in range(pairs.shape[0])
        ]
    )
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(
        min_separation(verts, model.shape_vstart, model.shape_vcount, model.shape_radius, pairs),
        got,
    )
    if pairs.shape[0]:
        whole = NB.min_separation(
            verts, model.shape_vstart, model.shape_vcount, model.shape_radius, pairs
        )
        assert got.min() == whole
        assert max(0.0, -got.min()) == M.penetration(model, pairs, x, theta)
    return got


def kinds(model, pairs) -> set[tuple[int, int]]:
    """The (vertex count class, vertex count class) of the pairs: 1 circle, 2 segment,
    3 polygon."""
    n = np.minimum(model.shape_vcount, 3)
    return {tuple(sorted((int(n[a]), int(n[b])))) for a, b in pairs}


@pytest.mark.parametrize("steps", [0, 20, 60, 200])
def test_stepped_scene_agrees(steps):
    w = World.from_scene(load_scene_text(SCENE, "<port test>"))
    w.advance(steps)
    x, theta = w.state.body_x, w.state.body_angle
    pairs = M.touching_pairs(w.model, x, theta, 0.05)
    assert pairs.shape[0] > 0
    compare(w.model, x, theta, pairs)


def test_random_poses_meet_every_branch():
    """Bodies thrown into a small box at random poses: deep overlaps of every kind."""
    w = World.from_scene(load_scene_text(SCENE, "<port test>"))
    model = w.model
    rng = np.random.default_rng(7)
    n = model.body_mass.shape[0]
    seen: set = set()
    signs = set()
    for _ in range(30):
        x = w.state.body_x.copy()
        theta = w.state.body_angle.copy()
        dyn = model.body_type == 0
        x[dyn] = rng.uniform([-2, -0.5], [2, 2.5], size=(int(dyn.sum()), 2))
        theta[dyn] = rng.uniform(-np.pi, np.pi, size=int(dyn.sum()))
        pairs = M.touching_pairs(model, x, theta, 0.3)
        got = compare(model, x, theta, pairs)
        seen |= kinds(model, pairs)
        signs |= set(np.sign(got).astype(int).tolist())
    assert n > 10
    assert {(1, 1), (1, 2), (1, 3), (2, 2), (2, 3), (3, 3)} <= seen
    assert {-1, 1} <= signs  # overlaps and gaps


def test_no_pairs_gives_an_empty_array():
    w = World.from_scene(load_scene_text(SCENE, "<port test>"))
    verts = M.vertices_world(w.model, w.state.body_x, w.state.body_angle)
    out = cxx(verts, w.model, np.zeros((0, 2), np.int32))
    assert out.shape == (0,)


def test_bad_input_is_refused():
    w = World.from_scene(load_scene_text(SCENE, "<port test>"))
    m = w.model
    verts = M.vertices_world(m, w.state.body_x, w.state.body_angle)
    good = dict(
        verts=verts,
        vstart=m.shape_vstart.astype(np.int32),
        vcount=m.shape_vcount.astype(np.int32),
        radius=m.shape_radius.astype(np.float64),
        pairs=np.array([[0, 1]], np.int32),
    )
    s = m.shape_vstart.shape[0]
    bad = [
        {"pairs": np.array([[0, s]], np.int32)},  # index out of range
        {"pairs": np.array([[-1, 0]], np.int32)},
        {"pairs": np.array([[0, 1]], np.int64)},  # dtype
        {"pairs": np.array([0, 1], np.int32)},  # shape
        {"verts": verts.astype(np.float32)},
        {"verts": verts[:, :1].copy()},
        {"verts": verts[:-1]},  # the last shape's vertices out of range
        {"vcount": good["vcount"][:-1]},  # (S,) mismatch
        {"radius": np.zeros(s + 1)},
        {"vstart": good["vstart"] - 1},
    ]
    for change in bad:
        args = {**good, **change}
        with pytest.raises(ValueError):
            _core.min_separation(**args)
    assert _core.min_separation(**good).shape == (1,)
