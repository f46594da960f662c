"""update_manifolds (with the time of impact) and store_impulses: C++ against numba.

Each case steps the numba engine to a moment, runs numba's collide() up to find_pairs
(transform_shapes, find_pairs, growing the store as World.advance does), copies its whole
state and storage into the C++ engine, runs update_manifolds in both and compares every
contact array: integers and flags exactly, floats to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.engines.numba.broadphase import find_pairs, grow_grid
from rbsim.engines.numba.contacts import grow_contacts, transform_shapes, update_manifolds

from .harness import Pair

DT = 1 / 60

# Floats agree to round-off only: the C++ code sums dot products as vectors (a sum of
# two products, then added) where numba adds the terms one by one, and places a shape
# at its time of impact as p + R l instead of (p + R_x l) - ...; on metre-scale values
# that is a few 1e-16 m, far below this.
ATOL = 1e-12

# what update_manifolds writes
WRITTEN = (
    "count",
    "carried",
    "shape_a",
    "shape_b",
    "body_a",
    "body_b",
    "key",
    "normal",
    "points",
    "friction",
    "restitution",
    "anchor_a",
    "anchor_b",
    "base_separation",
    "ref_separation",
    "feature",
    "normal_impulse",
    "start_impulse",
    "tangent_impulse",
    "max_normal_impulse",
    "toi_verts",
    "toi_norms",
)


def ground(kind: str = "segment") -> str:
    if kind == "segment":
        return "- {name: ground, type: static, shape: {segment: {a: [-20, 0], b: [20, 0]}}}"
    return "- {name: ground, type: static, position: [0, -0.5], shape: {box: {size: [40, 1]}}}"


STACK = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 400}}
bodies:
  {ground()}
  - stack: {{count: 6, size: [1, 1], origin: [0, 0.5]}}
"""

PYRAMID = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 400}}
materials:
  wood: {{density: 1.0, friction: 0.6, restitution: 0.0}}
bodies:
  {ground("box")}
  - pyramid: {{base: 6, size: [1, 1], origin: [0, 0.5], spacing: 0.02, material: wood}}
"""

CIRCLES_CAPSULES = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 400, mixing: {{friction: min}}}}
materials:
  a: {{density: 1.0, friction: 0.3, restitution: 0.1}}
  b: {{density: 2.0, friction: 0.8, restitution: 0.4}}
bodies:
  {ground()}
  - {{name: slope, type: static, position: [3, 1], angle: 0.3,
     shape: {{segment: {{a: [-2, 0], b: [2, 0], radius: 0.1}}}}}}
  - grid: {{name: balls, count: [5, 3], spacing: [0.5, 0.6], origin: [-2, 0.5],
           material: a, shape: {{circle: {{radius: 0.2}}}}}}
  - {{name: cap1, position: [1.0, 1.0], angle: 0.4, material: b,
     shape: {{segment: {{a: [-0.4, 0], b: [0.4, 0], radius: 0.15}}}}}}
  - {{name: cap2, position: [3.0, 2.5], angle: -0.2, angular_velocity: 2, material: b,
     shape: {{segment: {{a: [-0.3, 0], b: [0.3, 0], radius: 0.1}}}}}}
  - {{name: cap3, position: [0.0, 2.8], material: a,
     shape: {{segment: {{a: [-0.5, 0], b: [0.5, 0], radius: 0.05}}}}}}
"""

POLYGONS_SEGMENTS = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 400, mixing: {{friction: multiply,
        restitution: min}}}}
materials:
  m: {{density: 1.0, friction: 0.5, restitution: 0.2}}
bodies:
  {ground()}
  - {{name: step, type: static, shape: {{segment: {{a: [1, 0.5], b: [3, 0.5]}}}}}}
  - {{name: ramp, type: static, shape: {{segment: {{a: [-4, 2], b: [-1, 0.2]}}}}}}
  - {{name: tri, position: [-3, 3], angle: 0.2, material: m,
     shape: {{polygon: {{vertices: [[0, 0], [0.6, 0], [0.2, 0.5]]}}}}}}
  - {{name: pent, position: [2, 1.5], angular_velocity: 3, material: m, friction: 0.9,
     shape: {{polygon: {{vertices: [[0.3, 0], [0.09, 0.29], [-0.24, 0.18], [-0.24, -0.18],
                                  [0.09, -0.29]]}}}}}}
  - {{name: box, position: [0, 1], angle: 0.7, material: m,
     shape: {{box: {{size: [0.6, 0.3]}}}}}}
  - name: compound
    position: [2.2, 3]
    material: m
    shapes:
      - {{box: {{size: [0.8, 0.2]}}}}
      - {{box: {{size: [0.2, 0.6], offset: [-0.3, 0.4]}}}}
      - {{circle: {{radius: 0.15, offset: [0.25, 0.3]}}}}
"""

THIN_WALL = f"""
version: 1
world: {{gravity: [0, 0], dt: {DT!r}, steps: 30}}
bodies:
  - {{name: wall, type: static, position: [10.05, 0], restitution: 1.0,
     shape: {{box: {{size: [0.1, 4]}}}}}}
  - {{name: bullet, position: [0, 0.3], velocity: [300, 0], restitution: 1.0,
     shape: {{circle: {{radius: 0.05}}}}}}
  - {{name: brick, position: [0, -1], velocity: [200, 10], angular_velocity: 30,
     shape: {{box: {{size: [0.2, 0.1]}}}}}}
"""

ELASTIC = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 600}}
materials:
  rubber: {{density: 1.0, friction: 0.4, restitution: 1.0}}
bodies:
  {ground()}
  - {{name: b1, position: [-1, 1.0], material: rubber, shape: {{circle: {{radius: 0.25}}}}}}
  - {{name: b2, position: [0, 2.0], material: rubber, restitution: 0.8,
     shape: {{circle: {{radius: 0.25}}}}}}
  - {{name: b3, position: [0.1, 2.6], velocity: [0, -3], material: rubber,
     shape: {{circle: {{radius: 0.25}}}}}}
  - {{name: box, position: [1.5, 1.5], angle: 0.3, material: rubber,
     shape: {{box: {{size: [0.5, 0.5]}}}}}}
"""

# a dense pile of grains (radius 1 cm, 5 mm apart): each one's fat box (2 cm margin)
# meets some 24 others', far more pairs than the first store holds (4 S + 16)
GROW = f"""
version: 1
world: {{gravity: [0, -9.81], dt: {DT!r}, steps: 400}}
bodies:
  - {{name: floor, type: static, position: [0, -0.5], shape: {{box: {{size: [2, 1]}}}}}}
  - grid: {{name: grains, count: [10, 10], spacing: [0.025, 0.025], origin: [-0.12, 0.011],
           shape: {{circle: {{radius: 0.01}}}}}}
"""


def glancing(eps: float, v: float = 6.0, y0: float = 0.15, r: float = 0.1) -> str:
    """A ball passing a post off centre, placed so that it touches it at dt (1 + eps): the
    time-of-impact search is needed (the start's normal is not the impact's)."""
    x0 = -math.sqrt((2 * r) ** 2 - y0**2) - v * DT * (1 + eps)
    return f"""
version: 1
world: {{gravity: [0, 0], dt: {DT!r}, steps: 10}}
bodies:
  - {{name: post, type: static, shape: {{circle: {{radius: {r}}}}}}}
  - {{name: ball, position: [{x0!r}, {y0!r}], velocity: [{v}, 0], angular_velocity: 1.5,
     shape: {{circle: {{radius: {r}}}}}}}
"""


def collide_to_pairs(pair: Pair) -> int:
    """numba's collide() up to find_pairs; grows the numba store (and retries, as
    World.advance does) when the pairs do not fit. Returns the pair count."""
    nb = pair.nb
    while True:
        c = nb.contacts
        transform_shapes(nb.model, nb.state, c, nb.config.dt)
        n = find_pairs(nb.model, nb.grid, c.vert_world, c.shape_margin, c.pairs, c.count[2])
        c.count[2] = n
        if n <= c.pairs.shape[0]:
            return int(n)
        nb.contacts = grow_contacts(c, 2 * int(n))
        nb.grid = grow_grid(nb.grid, 2 * int(n))


def differences(pair: Pair) -> dict[str, float]:
    """Max |numba - C++| per array that differs, as pair.diff() but with equal values
    (the solver's inf markers in approach_velocity) and NaN in the same places equal."""
    out = {}
    for name, a, b in pair._storage_pairs():
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            out[name] = math.inf
            continue
        if a.size == 0:
            continue
        a, b = a.astype(np.float64), b.astype(np.float64)
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        with np.errstate(invalid="ignore"):
            d = np.where(same, 0.0, np.nan_to_num(np.abs(a - b), nan=math.inf))
        if d.max() > 0.0:
            out[name] = float(d.max())
    return out


def split_diff(pair: Pair) -> tuple[dict, dict]:
    """(integer/flag arrays that differ at all, float arrays beyond ATOL)."""
    names = dict((name, a) for name, a, _ in pair._storage_pairs())
    diff = differences(pair)
    ints = {k: v for k, v in diff.items() if np.asarray(names[k]).dtype.kind != "f"}
    floats = {k: v for k, v in diff.items() if k not in ints and v > ATOL}
    return ints, floats


WORST: dict[str, float] = {}


def check_manifolds(text: str, steps: int) -> Pair:
    """Step numba `steps` steps, then update_manifolds in both from the same input."""
    pair = Pair.from_text(text)
    pair.advance_numba(steps)
    n = collide_to_pairs(pair)
    pair.nb.contacts.toi_verts[:] = 0.0  # to see whether the search placed shapes
    pair.sync()
    assert differences(pair) == {}
    pair.run("update_manifolds", n_pairs=n)
    ints, floats = split_diff(pair)
    assert ints == {}, f"integer arrays differ: {ints}"
    assert floats == {}, f"float arrays beyond {ATOL}: {floats}"
    for k, v in differences(pair).items():
        WORST[k] = max(WORST.get(k, 0.0), v)
        assert k in WRITTEN, k  # nothing else was touched
    return pair


def manifolds(pair: Pair) -> int:
    return int(pair.nb.contacts.count[0])


@pytest.mark.parametrize("steps", [0, 3, 30, 120, 240])
def test_resting_stack(steps):
    pair = check_manifolds(STACK, steps)
    c = pair.nb.contacts
    assert manifolds(pair) == 6
    if steps >= 120:  # settled: manifolds carried in their slots, the graph unchanged
        assert c.carried[:6].all()
        assert c.count[7] == 1


@pytest.mark.parametrize("steps", [0, 1, 8, 40, 150])
def test_pyramid_settling(steps):
    pair = check_manifolds(PYRAMID, steps)
    assert manifolds(pair) >= 6  # the ground row at least (the rows start 2 cm apart)


@pytest.mark.parametrize("steps", [0, 20, 45, 70, 120, 300])
def test_circles_and_capsules(steps):
    pair = check_manifolds(CIRCLES_CAPSULES, steps)
    if steps >= 20:
        assert manifolds(pair) > 0


@pytest.mark.parametrize("steps", [0, 15, 30, 50, 90, 200])
def test_polygons_against_segments(steps):
    pair = check_manifolds(POLYGONS_SEGMENTS, steps)
    if steps >= 30:
        assert manifolds(pair) > 0


@pytest.mark.parametrize("steps", [0, 1, 2, 3, 5])
def test_fast_bodies_towards_a_thin_wall(steps):
    pair = check_manifolds(THIN_WALL, steps)
    if steps == 1:  # the bullet meets the wall within the next step: the search ran
        assert manifolds(pair) > 0
        assert np.any(pair.nb.contacts.toi_verts != 0.0)


@pytest.mark.parametrize(
    ("eps", "at_end"),
    [(-0.3, False), (-1e-3, False), (1e-9, True), (1e-7, True), (1e-4, False)],
)
def test_glancing_time_of_impact(eps, at_end):
    # eps < 0: the impact within the step; 1e-9, 1e-7: just after it (the search comes
    # within TOI_FINISH and takes the manifold at the step's end); 1e-4: further after
    # it (the search stops where it is)
    pair = check_manifolds(glancing(eps), 0)
    c, s = pair.nb.contacts, pair.nb.state
    assert manifolds(pair) == 1
    # the ball's (shape 1's) centre where the search left it: t = dt at the step's end
    t = (c.toi_verts[1, 0] - s.body_x[1, 0]) / s.body_v[1, 0]
    assert (abs(t - DT) < 1e-12) == at_end
    assert 0.0 < t <= DT


@pytest.mark.parametrize("steps", [0, 25, 27, 29, 40, 60, 100])
def test_elastic_bounces(steps):
    check_manifolds(ELASTIC, steps)


@pytest.mark.parametrize("steps", [0, 1, 10, 60])
def test_store_had_to_grow(steps):
    pair = Pair.from_text(GROW)
    first = pair.nb.contacts.key.shape[0]
    pair = check_manifolds(GROW, steps)
    assert pair.nb.contacts.key.shape[0] > first  # the store grew (now, or before)
    assert pair.nb.contacts.count[2] > first and manifolds(pair) > 100


def test_grown_store_carries_last_steps_manifolds_from_prev():
    # a store grown before the step keeps last step's manifolds in prev_* only (its
    # slots are empty): still bodies' manifolds are carried from there (matched, not in
    # their slots), the others collide again and match their feature ids
    pair = Pair.from_text(GROW)
    pair.advance_numba(200)
    nb = pair.nb
    capacity = 2 * nb.contacts.key.shape[0]
    nb.contacts = grow_contacts(nb.contacts, capacity)
    nb.grid = grow_grid(nb.grid, capacity)
    n = collide_to_pairs(pair)
    pair.sync()
    pair.run("update_manifolds", n_pairs=n)
    ints, floats = split_diff(pair)
    assert ints == {} and floats == {}
    c = pair.nb.contacts
    m = manifolds(pair)
    assert m > 0 and not c.carried[:m].any() and c.count[7] == 0
    assert c.body_still.any()  # some manifolds came from prev_* unchanged


# --- store_impulses ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "steps"),
    [(STACK, 200), (PYRAMID, 10), (CIRCLES_CAPSULES, 70), (ELASTIC, 27), (GROW, 5)],
)
def test_store_impulses(text, steps):
    pair = Pair.from_text(text)
    pair.advance_numba(steps)
    n = collide_to_pairs(pair)
    nb = pair.nb
    c = nb.contacts
    update_manifolds(
        nb.model, nb.state, c, nb.grid.shape_aabb, n, nb.config.friction_rule,
        nb.config.restitution_rule, nb.config.dt,
    )  # fmt: skip
    # stand in for the solver: new impulses, some points that pushed and some that did
    # not; anchors, normals and separations moved a little, so that a carried slot's
    # copy (which store_impulses must skip) would show
    rng = np.random.default_rng(steps)
    m = int(c.count[0])
    for name in ("normal_impulse", "tangent_impulse", "anchor_a", "anchor_b", "ref_separation"):
        a = getattr(c, name)
        a[:m] += rng.normal(scale=1e-3, size=a[:m].shape)
    c.normal[:m] += rng.normal(scale=1e-3, size=c.normal[:m].shape)
    c.max_normal_impulse[:m] = rng.choice([0.0, 0.0, 0.5], size=c.max_normal_impulse[:m].shape)
    pair.sync()
    pair.run("store_impulses")
    assert differences(pair) == {}  # copies and a count: exact
    assert c.count[1] == m
    if text is STACK:
        assert c.carried[:m].all()


def test_report_worst_difference():
    # not a check: the largest float difference seen above, for the record
    print({k: f"{v:.1e}" for k, v in sorted(WORST.items())})
