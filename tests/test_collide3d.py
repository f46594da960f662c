"""The 3D collision stages through the engine's API: the model's triangles and hull
topology as they cross the binding (bad arrays are a ValueError, never a crash), and the
manifolds a World3 finds (transform_shapes -> find_pairs -> update_manifolds, run one
by one with `stage` and read through `CoreWorld.storage`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbsim.config import make_config
from rbsim.core import CoreWorld
from rbsim.scene.compile import build

from .conftest import scene_from

SCENE = """\
version: 1
world: {{dimension: 3, dt: 0.01, steps: 1}}
bodies:
  - {{name: ground, type: static, shape: {{plane: {{normal: [0, 1, 0], offset: 0.0}}}}}}
  - {{name: ball, position: [0.3, {y}, -0.2], shape: {{sphere: {{radius: 0.5}}}}}}
  - name: crate
    position: [-3, 0.5, 0]
    rotation: {{axis: [0, 1, 0], angle: 0.4}}
    shape: {{box: {{size: [1, 1, 1]}}}}
  - name: tetra
    position: [3, 0, 0]
    shape: {{convex: {{vertices: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]}}}}
"""


def manifolds(world: CoreWorld) -> tuple:
    """Run the collision stages once; the contact store and its manifold count."""
    world.stage("transform_shapes")
    n_pairs = world.stage("find_pairs")
    world.stage("update_manifolds", n_pairs=n_pairs)
    c = world.storage
    return c, int(c.count[0])


def separations(c, m: int) -> np.ndarray:  # noqa: ANN001 - the store's namespace
    """Each point's separation (m) of manifold m: base + n · (sep anchor a − sep anchor b)."""
    k = int(c.points[m])
    arms = c.sep_anchor_a[m, :k] - c.sep_anchor_b[m, :k]
    return c.base_separation[m, :k] + arms @ c.normal[m]


def test_compile_gives_the_hulls_triangles_and_contacts_possible() -> None:
    model, _state = build(scene_from(SCENE.format(y=0.5)))
    assert model.has_shapes is True  # dynamic shapes over a plane can touch
    assert model.shape_fcount.tolist() == [0, 0, 12, 4]  # plane, sphere, box, tetrahedron
    assert model.shape_fstart.tolist() == [0, 0, 0, 12]
    assert model.face_local.shape == (16, 3) and model.face_local.dtype == np.int32
    lone = "version: 1\nworld: {dimension: 3}\nbodies: [{shape: {sphere: {radius: 1}}}]\n"
    assert build(scene_from(lone))[0].has_shapes is False
    flat, _ = build(scene_from("version: 1\nbodies: [{shape: {circle: {radius: 1}}}]\n"))
    assert flat.face_local.shape == (0, 3) and flat.shape_fcount.shape == (0,)


@pytest.mark.parametrize("gap", [0.005, -0.01])
def test_sphere_resting_on_a_plane_is_one_point_at_its_gap(gap: float) -> None:
    world = CoreWorld.from_scene(scene_from(SCENE.format(y=0.5 + gap)))
    c, n = manifolds(world)
    # the plane (shape 0) against the ball, crate and tetrahedron (each on the ground)
    assert n == 3 and c.shape_a[:n].tolist() == [0, 0, 0]
    assert c.shape_b[:n].tolist() == [1, 2, 3]
    ball = 0
    assert c.points[ball] == 1
    np.testing.assert_array_equal(c.normal[ball], [0.0, -1.0, 0.0])  # from the ball to the plane
    assert separations(c, ball)[0] == pytest.approx(gap, abs=1e-12)  # m: round-off
    # the ball's lever arm is under its centre
    np.testing.assert_allclose(c.anchor_b[ball, 0, [0, 2]], 0.0, atol=1e-12)


def test_box_and_tetrahedron_on_a_plane_touch_at_their_corners_with_stable_ids() -> None:
    world = CoreWorld.from_scene(scene_from(SCENE.format(y=0.5)))
    c, _n = manifolds(world)
    crate, tetra = 1, 2
    assert c.points[crate] == 4 and c.points[tetra] == 3  # a face, a triangle's corners
    np.testing.assert_allclose(separations(c, crate), 0.0, atol=1e-12)
    np.testing.assert_allclose(separations(c, tetra), 0.0, atol=1e-12)
    ids = c.feature[crate, :4].copy()
    assert len(set(ids.tolist())) == 4
    c.normal_impulse[crate, :4] = [1.0, 2.0, 3.0, 4.0]
    world.stage("store_impulses")
    # slide the crate 1 mm (past STILL_DISTANCE): recomputed, the same ids, the impulses
    # carried by id
    world.state.body_x[2, 0] += 1e-3
    c, _n = manifolds(world)
    assert c.carried[crate] == 0
    np.testing.assert_array_equal(c.feature[crate, :4], ids)
    np.testing.assert_array_equal(c.normal_impulse[crate, :4], [1.0, 2.0, 3.0, 4.0])


def bevelled_brick(bevel: float) -> str:
    """A 0.48 × 0.3 × 1.5 m brick as a hull whose edges are bevelled by `bevel` (m): 16
    points, its bottom face the four corners inset by the bevel at y = −0.15."""
    hx, hy, hz = 0.24, 0.15, 0.75
    points = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                points.append([sx * hx, sy * (hy - bevel), sz * hz])
                points.append([sx * (hx - bevel), sy * hy, sz * (hz - bevel)])
    return str(points)


BRICK = """\
version: 1
world: {{dimension: 3, dt: 1/240, steps: 1}}
bodies:
  - {{name: ground, type: static, shape: {{plane: {{normal: [0, 1, 0], offset: 0.0}}}}}}
  - {{name: brick, position: [0, 0.15, 0], shape: {{convex: {{vertices: {points}}}}}}}
"""


def test_a_bevelled_hull_rests_on_its_face_not_on_its_bevels() -> None:
    """Lying on the ground, a brick with 2 cm bevels has 12 corners within the speculative
    reach (its face's 4 on the ground, the bevels' 8 a centimetre or two up and further
    out): its manifold is the face's four corners, and it lies still. (When the reduction
    kept the outermost corners, it rested on one corner and three gaps and rocked at
    0.35 rad/s.)"""
    scene = scene_from(BRICK.format(points=bevelled_brick(0.02)))
    world = CoreWorld.from_scene(scene)
    c, n = manifolds(world)
    assert n == 1 and c.points[0] == 4
    np.testing.assert_allclose(separations(c, 0), 0.0, atol=1e-12)  # m: on the ground
    # the points under the face's corners, inset by the bevel: (±0.22, ±0.73)
    corners = np.sort(np.abs(c.anchor_b[0, :4][:, [0, 2]]), axis=0)
    np.testing.assert_allclose(corners, [[0.22, 0.73]] * 4, atol=1e-12)
    world.advance(480)
    # 1e-6 m/s and rad/s: at rest (it rocked at 0.05 m/s and 0.35 rad/s)
    assert np.abs(world.state.body_v[1]).max() < 1e-6
    assert np.abs(world.state.body_w[1]).max() < 1e-6


def test_a_many_sided_prism_rests_on_its_side() -> None:
    """A 64-sided prism (radius 0.3 m) lying on one of its sides: the side is 3 cm wide
    and the corners beside it are 1.4 mm up, within the speculative reach and further
    out; it rests on the side's four corners and stays put (it rocked at 0.06 rad/s on
    the corners 1.4 mm up, moving 3 mm a second)."""
    sides, r = 64, 0.3
    ring = [
        (r * math.cos(2 * math.pi * k / sides), r * math.sin(2 * math.pi * k / sides))
        for k in range(sides)
    ]
    points = [[x, y, z] for x in (-0.4, 0.4) for y, z in ring]
    # turned about x so that the side between corners 31 and 32 is at the bottom
    text = BRICK.format(points=str(points)).replace(
        "position: [0, 0.15, 0],",
        f"position: [0, {r * math.cos(math.pi / sides)!r}, 0],"
        f" rotation: {{axis: [1, 0, 0], angle: {math.pi / 2 + math.pi / sides!r}}},",
    )
    world = CoreWorld.from_scene(scene_from(text))
    c, n = manifolds(world)
    assert n == 1 and c.points[0] == 4
    np.testing.assert_allclose(separations(c, 0), 0.0, atol=1e-9)  # m: on the ground
    world.advance(480)
    # 0.01 rad/s and 1 mm in 2 s: it stays on its side (it rocked at 0.06 rad/s and crept)
    assert np.abs(world.state.body_w[1]).max() < 0.01
    assert np.linalg.norm(world.state.body_x[1, [0, 2]]) < 1e-3


COIN = """\
version: 1
world: {{dimension: 3, dt: 1/60, duration: 2}}
materials:
  m: {{density: 8000, friction: 0.3, restitution: 0.2}}
bodies:
  - {{name: ground, type: static, material: m, shape: {{plane: {{normal: [0, 1, 0], offset: 0}}}}}}
  - name: coin
    material: m
    position: [0, 0.003, 0]
    rotation: {{axis: [1, 0, 0], angle: 1.5707963}}
    angular_velocity: [0, {spin}, 0.5]
    shape: {{convex: {{vertices: {points}}}}}
"""


@pytest.mark.parametrize(("sides", "spin"), [(16, 0.0), (16, 30.0), (8, 30.0)])
def test_a_coin_landing_tilted_stays_on_the_plane(sides: int, spin: float) -> None:
    """A coin 24 mm across and 2 mm thick (a hull of 16 or 8 sides) dropped from 3 mm,
    tipping at 0.5 rad/s, at dt 1/60: every corner of its face within reach is a contact
    candidate. Only the corners within the face tolerance of the deepest were kept where
    more than four were within reach: it was held at its low side while its high side went
    through the plane within the step, and it sank below the ground (its centre to -1.9
    mm, -3.2 mm spinning). Its centre stays within 0.2 mm of half its thickness (the soft
    contacts' give, 90 µm at dt 1/60 for a 7 g coin, and its landing's dip), and it comes
    to rest."""
    r, t = 0.012, 0.002  # m
    ring = [
        (r * math.cos(2 * math.pi * k / sides), r * math.sin(2 * math.pi * k / sides))
        for k in range(sides)
    ]
    points = [[x, y, z] for x, y in ring for z in (-t / 2, t / 2)]
    world = CoreWorld.from_scene(scene_from(COIN.format(spin=spin, points=points)))
    lowest = math.inf
    for _ in range(world.scene.world.steps):
        world.advance(1)
        lowest = min(lowest, world.state.body_x[1, 1])
    assert lowest > t / 2 - 2e-4
    assert np.abs(world.state.body_v[1]).max() < 1e-3  # m/s: at rest after 2 s


TETRA = SCENE.format(y=0.5)


def arrays(text: str) -> tuple:
    """The compiled model and state of an inline 3D scene, for tampering."""
    return build(scene_from(text))


def engine(model, state) -> CoreWorld:  # noqa: ANN001 - compiled Model and State
    """The engine's world of tampered arrays (the settings of TETRA)."""
    return CoreWorld.from_arrays(model, state, make_config(scene_from(TETRA)), 3)


@pytest.mark.parametrize(
    ("tamper", "message"),
    [
        (lambda m: m._replace(face_local=m.face_local[:-1]), "shape_fstart|triangles"),
        (
            lambda m: m._replace(face_local=np.where(m.face_local == 3, 9, m.face_local)),
            "triangle vertex",
        ),
        (lambda m: m._replace(face_local=m.face_local[:, ::-1].copy()), "inwards"),
        (lambda m: m._replace(shape_fstart=m.shape_fstart[:2]), "shape_fstart"),
        (lambda m: m._replace(face_local=m.face_local.astype(np.int64)), "face_local"),
        (lambda m: m._replace(normal_local=2.0 * m.normal_local), "unit vector"),
        # the box's first and last corners swapped: no longer a box in BOX_SIGNS order
        (
            lambda m: m._replace(
                vertex_local=m.vertex_local[[0, 1, 9, *range(3, 9), 2, 10, 11, 12, 13]]
            ),
            "box",
        ),
    ],
)
def test_bad_geometry_is_a_value_error(tamper, message: str) -> None:  # noqa: ANN001
    model, state = arrays(TETRA)
    bad = tamper(model)
    with pytest.raises(ValueError, match=message):
        engine(bad, state)


@pytest.mark.parametrize(
    ("count", "last", "message"),
    [(3, None, "4 triangles"), (4, 12, "used twice"), (4, "flip", "used twice")],
)
def test_hull_that_is_not_closed_is_a_value_error_naming_the_shape(count, last, message) -> None:  # noqa: ANN001
    """The tetrahedron's triangles cut short, one repeated, or one turned inside out."""
    model, state = arrays(TETRA)
    fcount = model.shape_fcount.copy()
    fcount[3] = count
    faces = model.face_local.copy()
    if last == "flip":
        faces[15] = faces[15][[0, 2, 1]]
    elif last is not None:
        faces[15] = faces[last]
    with pytest.raises(ValueError, match=f"shape 3 .convex.: .*{message}"):
        engine(model._replace(shape_fcount=fcount, face_local=faces), state)
