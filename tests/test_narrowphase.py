"""Contact manifolds between pairs of shapes (the compiled engine's collide2d).

Every test places shapes in the world with an analytic gap or overlap and checks the
manifold: point count, separation, the normal pointing from shape b towards shape a,
the contact points, and feature ids. The convention under test: the solver pushes a
along +normal and b along -normal, so moving a by -sep along the normal makes the
two shapes just touch.
"""

import math
from typing import NamedTuple

import numpy as np
import pytest

from rbsim.constants import REFERENCE_FACE_TOLERANCE, SEGMENT_SKIN, SPECULATIVE_DISTANCE
from rbsim.core import collide2d as collide
from rbsim.scene.types import SHAPE_CIRCLE, SHAPE_POLYGON, SHAPE_SEGMENT

SPEC = SPECULATIVE_DISTANCE
TOL = 1e-9


def rot(angle, v):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


class Shape(NamedTuple):
    kind: int
    start: int
    count: int
    radius: float


class Manifold(NamedTuple):
    normal: np.ndarray  # (2,)
    points: np.ndarray  # (n,2)
    seps: np.ndarray  # (n,)
    ids: np.ndarray  # (n,)

    @property
    def count(self):
        return len(self.seps)


class World:
    """Shapes in world coordinates, laid out as the caller lays them out for collide."""

    def __init__(self):
        self.verts = []
        self.norms = []

    def _add(self, kind, verts, norms, radius):
        shape = Shape(kind, len(self.verts), len(verts), float(radius))
        self.verts.extend(np.asarray(v, float) for v in verts)
        self.norms.extend(np.asarray(n, float) for n in norms)
        return shape

    def circle(self, centre, radius):
        return self._add(SHAPE_CIRCLE, [centre], [(0.0, 0.0)], radius)

    def polygon(self, points, radius=0.0):
        """Convex CCW polygon; an edge's outward normal is its direction turned clockwise."""
        pts = [np.asarray(p, float) for p in points]
        norms = []
        for i, p in enumerate(pts):
            d = pts[(i + 1) % len(pts)] - p
            norms.append(np.array([d[1], -d[0]]) / np.hypot(*d))
        return self._add(SHAPE_POLYGON, pts, norms, radius)

    def box(self, centre, size, angle=0.0, radius=0.0):
        hx, hy = 0.5 * size[0], 0.5 * size[1]
        corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
        return self.polygon([np.asarray(centre) + rot(angle, c) for c in corners], radius)

    def segment(self, a, b, radius=0.0):
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        n = np.array([d[1], -d[0]]) / np.hypot(*d)
        return self._add(SHAPE_SEGMENT, [a, b], [n, -n], radius)

    def collide(self, sa, sb, speculative=SPEC):
        verts = np.array(self.verts, dtype=np.float64).reshape(-1, 2)
        norms = np.array(self.norms, dtype=np.float64).reshape(-1, 2)
        normal = np.full(2, np.nan)
        point = np.full((2, 2), np.nan)
        sep = np.full(2, np.nan)
        fid = np.full(2, -1, dtype=np.int64)
        n = collide(
            sa.kind, sa.start, sa.count, sa.radius,
            sb.kind, sb.start, sb.count, sb.radius,
            verts, norms, speculative, normal, point, sep, fid,
        )  # fmt: skip
        return Manifold(normal, point[:n].copy(), sep[:n].copy(), fid[:n].copy())


def assert_normal(m, expected):
    assert np.linalg.norm(m.normal) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(m.normal, expected, atol=1e-9)


# --- one scene per kind pair, parameterised by the surface gap --------------------------
#
# Each builder places shape a at `gap` (negative = overlap) from shape b along a known
# direction and returns (world, a, b, expected normal b -> a, expected point count).

PHI = 0.4  # the whole scene is turned by this, so no test relies on axis alignment


def circle_circle(gap):
    w = World()
    u = np.array([0.6, 0.8])
    b = w.circle((1.0, -2.0), 0.3)
    a = w.circle(np.array([1.0, -2.0]) + (0.3 + 0.5 + gap) * u, 0.5)
    return w, a, b, u, 1


def circle_polygon(gap):
    w = World()
    centre = np.array([1.0, -1.0])
    b = w.box(centre, (2.0, 1.0), PHI)
    a = w.circle(centre + rot(PHI, (0.2, 0.5 + 0.4 + gap)), 0.4)
    return w, a, b, rot(PHI, (0.0, 1.0)), 1


def circle_segment(gap):
    w = World()
    p, q = np.array([-1.0, 0.0]), np.array([2.0, 1.0])
    d = (q - p) / np.linalg.norm(q - p)
    n = np.array([-d[1], d[0]])
    b = w.segment(p, q, 0.2)
    a = w.circle(p + 1.2 * d + (0.2 + 0.5 + gap) * n, 0.5)
    return w, a, b, n, 1


def polygon_polygon(gap):
    w = World()
    b = w.box(rot(PHI, (0.0, -0.5)), (4.0, 1.0), PHI)
    a = w.box(rot(PHI, (0.3, 0.5 + gap)), (1.0, 1.0), PHI)
    return w, a, b, rot(PHI, (0.0, 1.0)), 2


def polygon_segment(gap):
    w = World()
    b = w.segment(rot(PHI, (-2.0, 0.0)), rot(PHI, (2.0, 0.0)), 0.1)
    a = w.box(rot(PHI, (0.2, 0.1 + 0.5 + gap)), (1.0, 1.0), PHI)
    return w, a, b, rot(PHI, (0.0, 1.0)), 2


def segment_segment(gap):
    w = World()
    b = w.segment(rot(PHI, (-0.5, 0.0)), rot(PHI, (2.0, 0.0)), 0.15)
    y = 0.15 + 0.25 + gap
    a = w.segment(rot(PHI, (-1.0, y)), rot(PHI, (1.0, y)), 0.25)
    return w, a, b, rot(PHI, (0.0, 1.0)), 2


PAIRS = [
    circle_circle,
    circle_polygon,
    circle_segment,
    polygon_polygon,
    polygon_segment,
    segment_segment,
]
pair = pytest.mark.parametrize("scene", PAIRS, ids=[f.__name__ for f in PAIRS])


@pair
def test_touching_shapes_report_zero_separation(scene):
    w, a, b, n, count = scene(0.0)
    m = w.collide(a, b)
    assert m.count == count
    np.testing.assert_allclose(m.seps, 0.0, atol=TOL)
    assert_normal(m, n)


@pair
def test_shapes_within_speculative_distance_report_their_positive_gap(scene):
    gap = 0.5 * SPEC
    w, a, b, n, count = scene(gap)
    m = w.collide(a, b)
    assert m.count == count
    np.testing.assert_allclose(m.seps, gap, atol=TOL)
    assert_normal(m, n)


@pair
def test_shapes_beyond_speculative_distance_report_no_contact(scene):
    w, a, b, _, _ = scene(1.5 * SPEC)
    assert w.collide(a, b).count == 0
    # ... but the same scene is reported when the solver asks for a longer reach
    assert w.collide(a, b, speculative=2.0 * SPEC).count > 0


@pair
def test_overlapping_shapes_report_the_analytic_overlap(scene):
    w, a, b, n, count = scene(-0.05)
    m = w.collide(a, b)
    assert m.count == count
    np.testing.assert_allclose(m.seps, -0.05, atol=TOL)
    assert_normal(m, n)


@pair
def test_normal_points_from_b_to_a_so_moving_a_along_it_separates(scene):
    overlap = 0.05
    w, a, b, n, _ = scene(-overlap)
    m = w.collide(a, b)
    assert m.count > 0
    # move a out along the reported normal by the reported depth: the shapes then touch
    moved = scene(-overlap)[0]
    shift = -m.seps.min() * m.normal
    moved.verts[a.start : a.start + a.count] = [
        v + shift for v in w.verts[a.start : a.start + a.count]
    ]
    np.testing.assert_allclose(moved.collide(a, b).seps.min(), 0.0, atol=TOL)
    assert np.dot(m.normal, n) > 0.99


@pair
@pytest.mark.parametrize("gap", [-0.05, 0.0, 0.5 * SPEC])
def test_swapping_shapes_negates_normal_and_keeps_separations(scene, gap):
    w, a, b, _, _ = scene(gap)
    ab, ba = w.collide(a, b), w.collide(b, a)
    assert ab.count == ba.count > 0
    np.testing.assert_allclose(ba.normal, -ab.normal, atol=1e-12)
    np.testing.assert_allclose(np.sort(ba.seps), np.sort(ab.seps), atol=TOL)
    order = lambda p: p[np.lexsort(p.T[::-1])]  # noqa: E731
    np.testing.assert_allclose(order(ba.points), order(ab.points), atol=TOL)


def boundary_distance(w, s, p):
    """Distance from p to the boundary of shape s's core (its centre, segment or outline)."""
    vs = shape_verts(w, s)
    if s.kind == SHAPE_CIRCLE:
        return np.linalg.norm(p - vs[0])
    if s.kind == SHAPE_SEGMENT:
        return point_segment_distance(p, vs[0], vs[1])
    return min(point_segment_distance(p, vs[i], vs[(i + 1) % len(vs)]) for i in range(len(vs)))


@pair
@pytest.mark.parametrize("gap", [-0.04, 0.0, 0.5 * SPEC])
def test_contact_points_lie_midway_between_the_two_surfaces(scene, gap):
    w, a, b, n, _ = scene(gap)
    m = w.collide(a, b)
    for p, sep in zip(m.points, m.seps, strict=True):
        on_a = p + 0.5 * sep * n  # a lies on the +n side of b
        on_b = p - 0.5 * sep * n
        assert boundary_distance(w, a, on_a) == pytest.approx(a.radius, abs=TOL)
        assert boundary_distance(w, b, on_b) == pytest.approx(b.radius, abs=TOL)


# --- boxes --------------------------------------------------------------------------------


def resting_box(x):
    """A unit box on a 4 x 1 ground box whose top face is y = 0 and spans x in [-2, 2]."""
    w = World()
    top = w.box((x, 0.5), (1.0, 1.0))
    ground = w.box((0.0, -0.5), (4.0, 1.0))
    return w, top, ground


def test_box_resting_flat_on_box_touches_at_both_ends_of_the_overlap():
    w, top, ground = resting_box(1.8)  # the top box overhangs the ground's right end
    m = w.collide(top, ground)
    assert m.count == 2
    xs = np.sort(m.points[:, 0])
    np.testing.assert_allclose(xs, [1.3, 2.0], atol=TOL)
    np.testing.assert_allclose(m.points[:, 1], 0.0, atol=TOL)
    assert m.seps[0] == m.seps[1] == pytest.approx(0.0, abs=TOL)
    assert_normal(m, (0.0, 1.0))
    assert m.ids[0] != m.ids[1]


def test_box_resting_flat_on_box_is_exactly_symmetric():
    w, top, ground = resting_box(0.0)
    m = w.collide(top, ground)
    assert m.count == 2
    np.testing.assert_allclose(np.sort(m.points[:, 0]), [-0.5, 0.5], atol=TOL)
    assert m.points[0, 0] == -m.points[1, 0]
    assert m.ids[0] != m.ids[1]
    assert m.seps[0] == m.seps[1]


def test_feature_ids_survive_a_small_sideways_shift():
    ids = []
    for x in (0.3, 0.31, 0.35):
        w, top, ground = resting_box(x)
        m = w.collide(top, ground)
        assert m.count == 2
        ids.append(tuple(m.ids))
    assert ids[0] == ids[1] == ids[2]


@pytest.mark.parametrize("gap", [0.0, 0.01])
@pytest.mark.parametrize("tilted", ["top", "ground"])
def test_feature_ids_survive_a_small_tilt_of_either_box(tilted, gap):
    # Two equal boxes, the top one offset sideways: tilting either one makes the other's
    # face slightly better, so without a tolerance the reference face (and every id)
    # would flip between the boxes from one step to the next.
    ids = set()
    for angle in (0.0, 1e-4, -1e-4):
        w = World()
        top = w.box((0.3, 0.5 + gap), (1.0, 1.0), angle if tilted == "top" else 0.0)
        ground = w.box((0.0, -0.5), (1.0, 1.0), angle if tilted == "ground" else 0.0)
        m = w.collide(top, ground, speculative=0.1)
        assert m.count == 2
        np.testing.assert_allclose(m.seps, gap, atol=1e-4)
        ids.add(tuple(sorted(m.ids)))
    assert len(ids) == 1


def test_equal_boxes_stacked_with_a_small_gap_give_two_points():
    # the closest points of the two faces are corners, yet it is a face contact
    w = World()
    top = w.box((0.0, 0.5 + 0.01), (1.0, 1.0))
    ground = w.box((0.0, -0.5), (1.0, 1.0))
    m = w.collide(top, ground)
    assert m.count == 2
    np.testing.assert_allclose(np.sort(m.points[:, 0]), [-0.5, 0.5], atol=TOL)
    np.testing.assert_allclose(m.seps, 0.01, atol=TOL)
    assert_normal(m, (0.0, 1.0))


def test_box_corner_exactly_above_box_corner_gives_one_point():
    w = World()
    top = w.box((2.0, 2.0 + 0.01), (2.0, 2.0))  # bottom-left corner at (1, 1.01)
    ground = w.box((0.0, 0.0), (2.0, 2.0))  # top-right corner at (1, 1)
    m = w.collide(top, ground)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(0.01, abs=TOL)
    np.testing.assert_allclose(m.points[0], (1.0, 1.005), atol=TOL)


@pytest.mark.parametrize("angle", [math.radians(30.0), math.radians(45.0), math.radians(-20.0)])
def test_rotated_box_corner_into_box_face_gives_one_point_at_analytic_depth(angle):
    depth = 0.03
    lowest = 0.5 * (abs(math.cos(angle)) + abs(math.sin(angle)))  # centre to lowest corner
    w = World()
    box = w.box((0.4, lowest - depth), (1.0, 1.0), angle)
    ground = w.box((0.0, -0.5), (4.0, 1.0))
    m = w.collide(box, ground)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(-depth, abs=TOL)
    assert_normal(m, (0.0, 1.0))
    corner = min(w.verts[box.start : box.start + 4], key=lambda v: v[1])
    np.testing.assert_allclose(m.points[0], (corner[0], -0.5 * depth), atol=TOL)


@pytest.mark.parametrize(
    ("centre", "normal", "depth"),
    [
        ((1.5, 0.2), (1.0, 0.0), 0.7),  # nearest the right face: out through +x
        ((0.3, 0.7), (0.0, 1.0), 0.5),  # nearest the top face: out through +y
        ((-1.6, -0.3), (-1.0, 0.0), 0.6),  # 0.6 past the left face, 0.9 past the bottom
    ],
)
def test_deep_overlap_pushes_out_along_the_minimal_penetration_axis(centre, normal, depth):
    w = World()
    small = w.box(centre, (0.4, 0.4))
    big = w.box((0.0, 0.0), (4.0, 2.0))
    m = w.collide(small, big)
    assert 1 <= m.count <= 2
    assert_normal(m, normal)
    np.testing.assert_allclose(m.seps, -depth, atol=TOL)
    swapped = w.collide(big, small)
    assert_normal(swapped, -np.asarray(normal))
    np.testing.assert_allclose(swapped.seps, -depth, atol=TOL)


def test_rounded_box_on_box_includes_the_rounding_in_the_separation():
    w = World()
    top = w.box((0.0, 0.5 + 0.1 + 0.01), (1.0, 1.0), radius=0.1)
    ground = w.box((0.0, -0.5), (4.0, 1.0))
    m = w.collide(top, ground)
    assert m.count == 2
    np.testing.assert_allclose(m.seps, 0.01, atol=TOL)
    # midway between ground (y = 0) and the rounded surface (y = 0.01)
    np.testing.assert_allclose(m.points[:, 1], 0.005, atol=TOL)


# --- capsules and thin segments -------------------------------------------------------------


def test_capsule_lying_on_box_touches_at_both_ends():
    w = World()
    capsule = w.segment((-0.5, 0.1), (0.5, 0.1), 0.1)
    box = w.box((0.0, -0.5), (2.0, 1.0))
    m = w.collide(capsule, box)
    assert m.count == 2
    np.testing.assert_allclose(np.sort(m.points[:, 0]), [-0.5, 0.5], atol=TOL)
    np.testing.assert_allclose(m.points[:, 1], 0.0, atol=TOL)
    np.testing.assert_allclose(m.seps, 0.0, atol=TOL)
    assert_normal(m, (0.0, 1.0))
    assert m.ids[0] != m.ids[1]


@pytest.mark.parametrize("along", [(0.126, 0.168), (0.2, 0.05), (0.03, 0.2)])
@pytest.mark.parametrize("horizontal", [True, False])
def test_capsule_end_near_box_corner_reports_the_true_corner_distance(along, horizontal):
    radius = 0.2
    offset = np.array(along)
    end = np.array([1.0, 1.0]) + offset  # the box's top-right corner plus a diagonal offset
    far = end + ((2.0, 0.0) if horizontal else (0.0, 2.0))
    dist = np.linalg.norm(offset)
    w = World()
    capsule = w.segment(end, far, radius)
    box = w.box((0.0, 0.0), (2.0, 2.0))
    m = w.collide(capsule, box, speculative=0.5)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(dist - radius, abs=TOL)
    assert_normal(m, offset / dist)  # from the corner towards the capsule's end
    # midway between the corner and the capsule's surface
    expected = np.array([1.0, 1.0]) + 0.5 * (dist - radius) * offset / dist
    np.testing.assert_allclose(m.points[0], expected, atol=TOL)
    swapped = w.collide(box, capsule, speculative=0.5)
    assert swapped.count == 1
    assert_normal(swapped, -offset / dist)
    assert swapped.seps[0] == pytest.approx(dist - radius, abs=TOL)


def test_capsule_corner_contact_beyond_speculative_distance_is_dropped():
    # SAT alone sees 0.1 - 0.05 = 0.05 along each face; the true gap is sqrt(2)*0.1 - 0.05
    w = World()
    capsule = w.segment((1.1, 1.1), (3.0, 1.1), 0.05)
    box = w.box((0.0, 0.0), (2.0, 2.0))
    true_gap = math.sqrt(2.0) * 0.1 - 0.05
    assert w.collide(capsule, box, speculative=0.06).count == 0
    m = w.collide(capsule, box, speculative=0.1)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(true_gap, abs=TOL)


def test_thin_ground_segment_under_a_box_gives_two_points():
    w = World()
    ground = w.segment((-50.0, 0.0), (50.0, 0.0))
    box = w.box((3.0, 0.5 - 0.002), (1.0, 1.0))
    m = w.collide(box, ground)
    assert m.count == 2
    np.testing.assert_allclose(np.sort(m.points[:, 0]), [2.5, 3.5], atol=TOL)
    np.testing.assert_allclose(m.seps, -0.002, atol=TOL)
    assert_normal(m, (0.0, 1.0))
    # a segment is two-sided: a box below it is pushed down
    below = World()
    ground = below.segment((-50.0, 0.0), (50.0, 0.0))
    box = below.box((3.0, -0.5 + 0.002), (1.0, 1.0))
    m = below.collide(box, ground)
    assert m.count == 2
    assert_normal(m, (0.0, -1.0))


@pytest.mark.parametrize("gap", [-0.1, 0.0, 0.01])
def test_collinear_capsules_end_to_end_touch_along_their_axis(gap):
    # face normals of two collinear segments see no gap at all: only the end-to-end
    # distance tells how far apart they are
    w = World()
    b = w.segment((0.0, 0.0), (1.0, 0.0), 0.3)
    a = w.segment((1.0 + 0.3 + 0.2 + gap, 0.0), (3.0, 0.0), 0.2)
    m = w.collide(a, b)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(gap, abs=TOL)
    assert_normal(m, (1.0, 0.0))


def test_crossing_thin_segments_overlap():
    w = World()
    a = w.segment((-1.0, 0.2), (1.0, 0.2))
    b = w.segment((0.0, -1.0), (0.0, 1.0))
    m = w.collide(a, b)
    assert m.count >= 1
    assert np.all(m.seps < 0.0)


def test_capsule_end_above_capsule_middle_touches_at_one_point():
    w = World()
    b = w.segment((-1.0, 0.0), (1.0, 0.0), 0.1)
    a = w.segment((0.3, 0.1 + 0.1 + 0.005), (0.3, 2.0), 0.1)  # a T, 5 mm apart
    m = w.collide(a, b)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(0.005, abs=TOL)
    assert_normal(m, (0.0, 1.0))
    np.testing.assert_allclose(m.points[0], (0.3, 0.1 + 0.0025), atol=TOL)


# --- circles against polygons --------------------------------------------------------------


@pytest.mark.parametrize("degrees", [10.0, 30.0, 45.0, 60.0, 80.0, 135.0, 200.0, 290.0])
def test_circle_in_a_box_vertex_region_is_pushed_along_the_corner_direction(degrees):
    # u points into the quadrant of one corner, so corner + u is in that corner's region
    u = rot(math.radians(degrees), (1.0, 0.0))
    corner = np.sign(u)
    w = World()
    box = w.box((0.0, 0.0), (2.0, 2.0))
    circle = w.circle(corner + 0.51 * u, 0.5)
    m = w.collide(circle, box)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(0.01, abs=TOL)
    assert_normal(m, u)
    np.testing.assert_allclose(m.points[0], corner + 0.005 * u, atol=TOL)


def test_circle_in_a_box_edge_region_is_pushed_along_the_face_normal():
    w = World()
    box = w.box((0.0, 0.0), (2.0, 2.0), math.pi / 2)  # the same box, vertices renumbered
    circle = w.circle((0.7, -1.0 - 0.45), 0.5)
    m = w.collide(circle, box)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(-0.05, abs=TOL)
    assert_normal(m, (0.0, -1.0))


def test_circle_with_centre_inside_a_polygon_leaves_through_the_nearest_face():
    w = World()
    tri = w.polygon([(0.0, 0.0), (4.0, 0.0), (0.0, 3.0)])  # hypotenuse 3x + 4y = 12
    circle = w.circle((0.5, 0.3), 0.2)  # 0.3 from the bottom, 0.5 from the left side
    m = w.collide(circle, tri)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(-0.3 - 0.2, abs=TOL)
    assert_normal(m, (0.0, -1.0))
    assert w.collide(tri, circle).normal == pytest.approx([0.0, 1.0])


def test_circle_against_rounded_polygon_adds_both_radii():
    w = World()
    box = w.box((0.0, 0.0), (2.0, 2.0), radius=0.1)
    circle = w.circle((1.0 + 0.1 + 0.3 + 0.004, 0.2), 0.3)
    m = w.collide(circle, box)
    assert m.seps[0] == pytest.approx(0.004, abs=TOL)
    assert_normal(m, (1.0, 0.0))


def test_circle_beyond_a_capsule_end_is_pushed_along_the_axis():
    w = World()
    capsule = w.segment((0.0, 0.0), (1.0, 0.0), 0.1)
    circle = w.circle((-0.1 - 0.2 - 0.01, 0.0), 0.2)
    m = w.collide(circle, capsule)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(0.01, abs=TOL)
    assert_normal(m, (-1.0, 0.0))


def test_concentric_circles_get_a_finite_unit_normal():
    w = World()
    a = w.circle((1.0, 1.0), 0.5)
    b = w.circle((1.0, 1.0), 0.25)
    m = w.collide(a, b)
    assert m.count == 1
    assert m.seps[0] == pytest.approx(-0.75)
    assert np.linalg.norm(m.normal) == pytest.approx(1.0)


# --- against brute force on random convex shapes ----------------------------------------------


def random_convex(rng, centre, n):
    """The convex hull of n random points around centre, CCW."""
    angles = rng.uniform(0.0, 2.0 * math.pi, n)
    radii = rng.uniform(0.3, 1.0, n)
    return convex_hull(centre + radii[:, None] * np.c_[np.cos(angles), np.sin(angles)])


def convex_hull(pts):
    pts = sorted(tuple(p) for p in pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-12:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-12:
            upper.pop()
        upper.append(p)
    return [np.array(p) for p in lower[:-1] + upper[:-1]]


def point_segment_distance(p, a, b):
    d = b - a
    t = np.clip(np.dot(p - a, d) / np.dot(d, d), 0.0, 1.0)
    return np.linalg.norm(p - (a + t * d))


def core_distance(pa, pb):
    """Distance between two disjoint convex cores given as vertex lists (>= 2 each)."""
    best = np.inf
    for ps, qs in ((pa, pb), (pb, pa)):
        for p in ps:
            for i in range(len(qs)):
                best = min(best, point_segment_distance(p, qs[i], qs[(i + 1) % len(qs)]))
    return best


def sat_depth(pa, pb):
    """Largest separation over both polygons' face normals (negative = penetration)."""
    best = -np.inf
    for ps, qs in ((pa, pb), (pb, pa)):
        for i in range(len(ps)):
            d = ps[(i + 1) % len(ps)] - ps[i]
            n = np.array([d[1], -d[0]]) / np.hypot(*d)
            best = max(best, min(np.dot(q - ps[i], n) for q in qs))
    return best


def random_pair(rng, w, kinds, spread=2.0):
    """Two random shapes of the given kinds ("polygon" or "segment"), random radii."""
    shapes = []
    for kind in kinds.split("-"):
        c = rng.uniform(-spread, spread, 2)
        r = rng.choice([0.0, 0.05, 0.2])
        if kind == "segment":
            u = rot(rng.uniform(0, 2 * math.pi), (1.0, 0.0)) * rng.uniform(0.2, 1.5)
            shapes.append(w.segment(c - u, c + u, r))
        else:
            shapes.append(w.polygon(random_convex(rng, c, rng.integers(3, 9)), r))
    return shapes


def shape_verts(w, s):
    return [np.asarray(v) for v in w.verts[s.start : s.start + s.count]]


@pytest.mark.parametrize("kinds", ["polygon-polygon", "polygon-segment", "segment-segment"])
def test_separated_shapes_report_the_true_distance_as_their_closest_point(kinds):
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(400):
        w = World()
        a, b = random_pair(rng, w, kinds)
        pa, pb = shape_verts(w, a), shape_verts(w, b)
        if sat_depth(pa, pb) <= 1e-6:
            continue  # cores overlap or touch
        radius = a.radius + b.radius
        if kinds == "segment-segment":  # two segments keep at least SEGMENT_SKIN between cores
            radius = max(radius, SEGMENT_SKIN)
        gap = core_distance(pa, pb) - radius
        m = w.collide(a, b, speculative=10.0)
        assert m.count >= 1
        # the closest point is the true gap, up to the reference face tolerance
        assert m.seps.min() == pytest.approx(gap, abs=2 * REFERENCE_FACE_TOLERANCE)
        assert np.all(m.seps >= gap - 2 * REFERENCE_FACE_TOLERANCE)
        checked += 1
    assert checked > 100


@pytest.mark.parametrize("kinds", ["polygon-polygon", "polygon-segment"])
def test_overlapping_shapes_report_the_sat_penetration_depth(kinds):
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(400):
        w = World()
        a, b = random_pair(rng, w, kinds, spread=1.0)
        pa, pb = shape_verts(w, a), shape_verts(w, b)
        depth = sat_depth(pa, pb)
        if depth >= -1e-6:
            continue
        m = w.collide(a, b)
        assert m.count >= 1
        assert m.seps.min() == pytest.approx(
            depth - a.radius - b.radius, abs=REFERENCE_FACE_TOLERANCE
        )
        checked += 1
    assert checked > 100
