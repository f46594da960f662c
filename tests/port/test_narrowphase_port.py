"""The C++ narrowphase (rbsim._core.collide2d) against the numba one
(rbsim.engines.numba.narrowphase.collide).

Every kind pair in both orders (circle, polygon incl. boxes and triangles, segment with and
without radius), on hand-made configurations (touching, deep, parallel faces, corner to
corner, concentric circles, a centre on a segment, degenerate short segments, separated
beyond the speculative distance) and on random ones (random convex polygons, random
placements, then the same pair moved to just touching; and shapes on a coarse lattice,
where SAT ties and the exact 0/1 end-point fractions are common).

Both engines do the same floating-point operations in the same order (no FMA: the
extension is built for baseline x86-64), so count, ids, normal, points and separations
must agree exactly.
"""

import math

import numpy as np
import pytest

from rbsim import _core
from rbsim.constants import SPECULATIVE_DISTANCE
from rbsim.engines.numba.narrowphase import collide
from rbsim.scene.types import SHAPE_CIRCLE, SHAPE_POLYGON, SHAPE_SEGMENT

SPEC = SPECULATIVE_DISTANCE
S = 1 << 16
KINDS = (SHAPE_CIRCLE, SHAPE_POLYGON, SHAPE_SEGMENT)
KIND_NAME = {SHAPE_CIRCLE: "circle", SHAPE_POLYGON: "polygon", SHAPE_SEGMENT: "segment"}


class Scene:
    """Shapes in world coordinates, laid out in flat verts/norms as collide expects."""

    def __init__(self):
        self.verts = []
        self.norms = []

    def _add(self, kind, verts, norms, radius):
        shape = (kind, len(self.verts), len(verts), float(radius))
        self.verts.extend(np.asarray(v, float) for v in verts)
        self.norms.extend(np.asarray(n, float) for n in norms)
        return shape

    def circle(self, centre, radius):
        return self._add(SHAPE_CIRCLE, [centre], [(0.0, 0.0)], radius)

    def polygon(self, points, radius=0.0):
        pts = [np.asarray(p, float) for p in points]
        norms = []
        for i, p in enumerate(pts):
            d = pts[(i + 1) % len(pts)] - p
            norms.append(np.array([d[1], -d[0]]) / math.hypot(*d))
        return self._add(SHAPE_POLYGON, pts, norms, radius)

    def box(self, centre, size, angle=0.0, radius=0.0):
        hx, hy = 0.5 * size[0], 0.5 * size[1]
        c, s = math.cos(angle), math.sin(angle)
        corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
        pts = [(centre[0] + c * x - s * y, centre[1] + s * x + c * y) for x, y in corners]
        return self.polygon(pts, radius)

    def segment(self, a, b, radius=0.0, normal=None):
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        if normal is None:
            n = np.array([d[1], -d[0]]) / math.hypot(*d)
        else:  # a degenerate segment: the caller gives its normal
            n = np.asarray(normal, float)
        return self._add(SHAPE_SEGMENT, [a, b], [n, -n], radius)

    def arrays(self):
        verts = np.array(self.verts, dtype=np.float64).reshape(-1, 2)
        norms = np.array(self.norms, dtype=np.float64).reshape(-1, 2)
        return verts, norms


def run_numba(sa, sb, verts, norms, speculative):
    normal = np.full(2, np.nan)
    point = np.full((2, 2), np.nan)
    sep = np.full(2, np.nan)
    fid = np.full(2, -1, dtype=np.int64)
    n = collide(*sa, *sb, verts, norms, speculative, normal, point, sep, fid)
    return n, normal, point, sep, fid


def run_cpp(sa, sb, verts, norms, speculative):
    return _core.collide2d(*sa, *sb, verts, norms, speculative)


def check_pair(sa, sb, verts, norms, speculative, label=""):
    """Assert both engines give the same manifold; returns numba's (count, ids)."""
    n0, normal0, point0, sep0, id0 = run_numba(sa, sb, verts, norms, speculative)
    n1, normal1, point1, sep1, id1 = run_cpp(sa, sb, verts, norms, speculative)
    where = f"{label} a={sa} b={sb} spec={speculative}"
    assert n1 == n0, where
    if n0 == 0:
        return n0, id0[:0]
    assert id1[:n0].tolist() == id0[:n0].tolist(), where
    # the same operations in the same order: bit for bit
    assert normal1.tolist() == normal0.tolist(), where
    assert point1[:n0].tolist() == point0[:n0].tolist(), where
    assert sep1[:n0].tolist() == sep0[:n0].tolist(), where
    return n0, id0[:n0]


def check_both_orders(scene, sa, sb, speculative=SPEC, label=""):
    verts, norms = scene.arrays()
    r = check_pair(sa, sb, verts, norms, speculative, label)
    check_pair(sb, sa, verts, norms, speculative, label + " (swapped)")
    return r


# --- hand-made configurations -------------------------------------------------------------


def rot(angle, v):
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1])


GAPS = [-0.3, -0.05, -1e-3, 0.0, 1e-12, 0.5 * SPEC, SPEC, 1.5 * SPEC, 0.5]


@pytest.mark.parametrize("gap", GAPS)
@pytest.mark.parametrize("speculative", [0.0, SPEC, 0.2])
def test_hand_made_pairs_at_analytic_gaps(gap, speculative):
    phi = 0.4
    builders = []

    def circle_circle(w):
        u = np.array([0.6, 0.8])
        b = w.circle((1.0, -2.0), 0.3)
        return w.circle(np.array([1.0, -2.0]) + (0.8 + gap) * u, 0.5), b

    def circle_box_face(w):
        b = w.box((1.0, -1.0), (2.0, 1.0), phi)
        return w.circle(np.add((1.0, -1.0), rot(phi, (0.2, 0.9 + gap))), 0.4), b

    def circle_box_corner(w):
        b = w.box((0.0, 0.0), (2.0, 1.0), phi, radius=0.05)
        u = np.array(rot(phi, (1.0, 0.5)))
        corner = u
        d = u / np.linalg.norm(u)
        return w.circle(corner + (0.45 + gap) * d, 0.4), b

    def circle_segment(w):
        p, q = np.array([-1.0, 0.0]), np.array([2.0, 1.0])
        d = (q - p) / np.linalg.norm(q - p)
        n = np.array([-d[1], d[0]])
        b = w.segment(p, q, 0.2)
        return w.circle(p + 1.2 * d + (0.7 + gap) * n, 0.5), b

    def circle_segment_end(w):
        b = w.segment((0.0, 0.0), (1.0, 0.0))
        return w.circle((1.3 + gap, 0.0), 0.3), b

    def box_on_ground(w):
        b = w.box(rot(phi, (0.0, -0.5)), (4.0, 1.0), phi)
        return w.box(rot(phi, (0.3, 0.5 + gap)), (1.0, 1.0), phi), b

    def equal_boxes(w):
        b = w.box((0.0, -0.5), (1.0, 1.0))
        return w.box((0.0, 0.5 + gap), (1.0, 1.0)), b

    def box_corner_on_corner(w):
        b = w.box((0.0, 0.0), (2.0, 2.0))
        return w.box((2.0, 2.0 + gap), (2.0, 2.0)), b

    def rounded_boxes_corner(w):
        b = w.box((0.0, 0.0), (2.0, 2.0), radius=0.1)
        d = (0.2 + gap) / math.sqrt(2.0)
        return w.box((2.0 + d, 2.0 + d), (2.0, 2.0), radius=0.1), b

    def tilted_box_corner(w):
        angle = math.radians(30.0)
        lowest = 0.5 * (abs(math.cos(angle)) + abs(math.sin(angle)))
        b = w.box((0.0, -0.5), (4.0, 1.0))
        return w.box((0.4, lowest + gap), (1.0, 1.0), angle), b

    def triangle_on_box(w):
        b = w.box((0.0, -0.5), (3.0, 1.0), 0.1)
        return w.polygon([rot(0.1, p) for p in [(-0.5, gap), (0.5, gap), (0.0, 0.8 + gap)]]), b

    def box_on_segment(w):
        b = w.segment(rot(phi, (-2.0, 0.0)), rot(phi, (2.0, 0.0)), 0.1)
        return w.box(rot(phi, (0.2, 0.6 + gap)), (1.0, 1.0), phi), b

    def box_on_thin_segment(w):
        b = w.segment((-2.0, 0.0), (2.0, 0.0))
        return w.box((0.2, 0.5 + gap), (1.0, 1.0)), b

    def capsule_on_box(w):
        b = w.box((0.0, -0.5), (2.0, 1.0))
        return w.segment((-0.5, 0.1 + gap), (0.5, 0.1 + gap), 0.1), b

    def capsules_parallel(w):
        b = w.segment(rot(phi, (-0.5, 0.0)), rot(phi, (2.0, 0.0)), 0.15)
        y = 0.4 + gap
        return w.segment(rot(phi, (-1.0, y)), rot(phi, (1.0, y)), 0.25), b

    def capsules_end_to_end(w):
        b = w.segment((0.0, 0.0), (1.0, 0.0), 0.1)
        return w.segment((1.2 + gap, 0.0), (2.0, 0.0), 0.1), b

    def thin_segments_crossing(w):
        b = w.segment((-1.0, 0.0), (1.0, 0.0))
        return w.segment((-0.5, gap), (0.7, gap + 0.01)), b

    def thin_segments_parallel(w):
        b = w.segment((-1.0, 0.0), (1.0, 0.0))
        return w.segment((-0.5, gap), (1.5, gap)), b

    def short_segment_on_box(w):
        b = w.box((0.0, -0.5), (2.0, 1.0))
        return w.segment((0.1, gap + 0.05), (0.1 + 1e-10, gap + 0.05), 0.05, (0.0, -1.0)), b

    def point_segment_on_segment(w):
        b = w.segment((-1.0, 0.0), (1.0, 0.0), 0.02)
        return w.segment((0.3, 0.05 + gap), (0.3, 0.05 + gap), 0.03, (1.0, 0.0)), b

    def circle_on_point_segment(w):
        b = w.segment((0.0, 0.0), (0.0, 0.0), 0.1, (0.0, -1.0))
        return w.circle((0.0, 0.3 + gap), 0.2), b

    builders = [
        circle_circle, circle_box_face, circle_box_corner, circle_segment,
        circle_segment_end, box_on_ground, equal_boxes, box_corner_on_corner,
        rounded_boxes_corner, tilted_box_corner, triangle_on_box, box_on_segment,
        box_on_thin_segment, capsule_on_box, capsules_parallel, capsules_end_to_end,
        thin_segments_crossing, thin_segments_parallel, short_segment_on_box,
        point_segment_on_segment, circle_on_point_segment,
    ]  # fmt: skip
    for build in builders:
        w = Scene()
        a, b = build(w)
        check_both_orders(w, a, b, speculative, build.__name__)


def test_concentric_and_centre_on_core_cases():
    w = Scene()
    a = w.circle((0.3, -0.2), 0.5)
    b = w.circle((0.3, -0.2), 0.2)
    c = w.segment((0.0, -0.2), (1.0, -0.2), 0.1)  # a's centre on its core
    d = w.box((0.3, -0.2), (1.0, 0.6), 0.3)  # a's centre at the box centre
    e = w.box((0.3, -0.2), (0.2, 0.2), 0.0, radius=0.05)  # same, small rounded box
    f = w.polygon([(0.3, -0.2), (1.0, -0.2), (0.3, 0.5)])  # a's centre on a vertex
    g = w.segment((0.3, -0.2), (0.3, -0.2), 0.1, (0.0, 1.0))  # a point at the centre
    for s in (b, c, d, e, f, g):
        n, ids = check_both_orders(w, a, s, label="concentric")
        assert n == 1 and ids.tolist() == [0]


def test_deep_overlap_and_containment():
    w = Scene()
    big = w.box((0.0, 0.0), (4.0, 2.0))
    shapes = [
        w.box((1.5, 0.2), (0.4, 0.4)),
        w.box((0.3, 0.7), (0.4, 0.4), 0.7),
        w.box((0.0, 0.0), (4.0, 2.0)),  # identical boxes
        w.box((0.0, 0.0), (4.0, 2.0), math.pi / 2),
        w.polygon([(-1.6, -0.3), (-1.2, -0.3), (-1.4, 0.1)]),
        w.segment((-1.0, 0.1), (1.0, 0.3), 0.05),
        w.segment((-3.0, 0.0), (3.0, 0.0)),  # through the box
        w.circle((0.1, 0.0), 0.3),
        w.circle((1.9, 0.9), 1.0),
    ]
    for s in shapes:
        for spec in (0.0, SPEC):
            check_both_orders(w, s, big, spec, "deep")


def test_small_tilts_keep_ids_as_numba_does():
    # nearly equal faces: the reference face tolerance decides in both engines alike
    for angle in (0.0, 1e-4, -1e-4, 1e-7, 0.5e-3):
        for gap in (0.0, 0.01, -0.004):
            w = Scene()
            top = w.box((0.3, 0.5 + gap), (1.0, 1.0), angle)
            ground = w.box((0.0, -0.5), (1.0, 1.0), -angle)
            check_both_orders(w, top, ground, 0.1, "tilt")


# --- random configurations ------------------------------------------------------------------


def random_shape(rng, w, kind, centre, lattice=False):
    if lattice:  # coordinates on a 0.25 grid, no rotation: exact ties everywhere
        radius = float(rng.choice([0.0, 0.0, 0.25]))
        if kind == SHAPE_CIRCLE:
            return w.circle(centre, float(rng.choice([0.25, 0.5, 1.0])))
        if kind == SHAPE_POLYGON:
            hx, hy = rng.integers(1, 5, size=2) * 0.25
            return w.box(centre, (2 * hx, 2 * hy), radius=radius)
        d = rng.integers(-4, 5, size=2) * 0.25
        if not d.any():
            d = np.array([0.5, 0.0])
        return w.segment(np.asarray(centre) - d, np.asarray(centre) + d, radius)
    scale = float(rng.choice([0.05, 0.5, 1.0, 3.0]))
    radius = float(rng.choice([0.0, 0.0, 0.02, 0.2])) * scale
    angle = rng.uniform(-math.pi, math.pi)
    if kind == SHAPE_CIRCLE:
        return w.circle(centre, scale * rng.uniform(0.1, 1.0))
    if kind == SHAPE_SEGMENT:
        length = scale * float(rng.choice([rng.uniform(0.2, 2.0), 1e-10, 0.0, 1e-6]))
        half = 0.5 * length * np.array([math.cos(angle), math.sin(angle)])
        normal = (math.sin(angle), -math.cos(angle))  # the direction turned clockwise
        return w.segment(np.asarray(centre) - half, np.asarray(centre) + half, radius, normal)
    style = rng.integers(3)
    if style == 0:  # box
        size = scale * rng.uniform(0.2, 2.0, size=2)
        return w.box(centre, size, angle if rng.random() < 0.8 else 0.0, radius)
    if style == 1:  # triangle or regular polygon
        k = int(rng.choice([3, 3, 5, 6, 8]))
        r = scale * rng.uniform(0.2, 1.0)
        pts = [
            np.asarray(centre) + r * np.array([math.cos(angle + 2 * math.pi * i / k),
                                               math.sin(angle + 2 * math.pi * i / k)])
            for i in range(k)
        ]  # fmt: skip
        return w.polygon(pts, radius)
    # convex hull of random points (counter-clockwise, no collinear points)
    while True:
        p = rng.uniform(-1.0, 1.0, size=(int(rng.integers(3, 10)), 2)) * scale
        hull = convex_hull(p)
        if len(hull) >= 3 and polygon_area(hull) > 1e-3 * scale * scale:
            return w.polygon([np.asarray(centre) + q for q in hull], radius)


def convex_hull(points):
    pts = sorted(map(tuple, points))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2:
                (ox, oy), (ax, ay) = out[-2], out[-1]
                if (ax - ox) * (p[1] - oy) - (ay - oy) * (p[0] - ox) > 1e-12:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return lower[:-1] + upper[:-1]


def polygon_area(pts):
    return 0.5 * sum(
        pts[i][0] * pts[(i + 1) % len(pts)][1] - pts[(i + 1) % len(pts)][0] * pts[i][1]
        for i in range(len(pts))
    )


def translated(w, shape, shift):
    """A copy of the scene with shape moved by shift."""
    moved = Scene()
    moved.verts = list(w.verts)
    moved.norms = list(w.norms)
    _, start, count, _ = shape
    for i in range(start, start + count):
        moved.verts[i] = moved.verts[i] + shift
    return moved


PAIRS = [(ka, kb) for ka in KINDS for kb in KINDS]


@pytest.mark.parametrize(
    ("kind_a", "kind_b"), PAIRS, ids=[f"{KIND_NAME[a]}-{KIND_NAME[b]}" for a, b in PAIRS]
)
def test_random_configurations_agree(kind_a, kind_b):
    rng = np.random.default_rng(1000 + 10 * kind_a + kind_b)
    counts = {0: 0, 1: 0, 2: 0}
    kinds_of_id = set()
    for trial in range(300):
        w = Scene()
        b = random_shape(rng, w, kind_b, rng.uniform(-2.0, 2.0, size=2))
        offset = rng.normal(size=2) * float(rng.choice([0.3, 1.0, 3.0]))
        a = random_shape(rng, w, kind_a, np.asarray(w.verts[b[1]]) + offset)
        spec = float(rng.choice([0.0, SPEC, 0.1, 1.0]))
        verts, norms = w.arrays()
        n, ids = check_pair(a, b, verts, norms, spec, f"random {trial}")
        counts[n] += 1
        kinds_of_id.update(int(i) // (S * S) for i in ids)
        # the same pair moved along the reported normal to (nearly) touching
        if n > 0:
            normal = run_numba(a, b, verts, norms, spec)[1]
            for gap in (0.0, rng.uniform(-0.02, 0.02), 0.9 * SPEC, 1.1 * SPEC):
                sep = float(np.min(run_numba(a, b, verts, norms, spec)[3][:n]))
                m = translated(w, a, (gap - sep) * normal)
                mv, mn = m.arrays()
                n2, ids2 = check_pair(a, b, mv, mn, SPEC, f"touching {trial} gap {gap}")
                counts[n2] += 1
                kinds_of_id.update(int(i) // (S * S) for i in ids2)
    for trial in range(150):
        w = Scene()
        b = random_shape(rng, w, kind_b, (0.0, 0.0), lattice=True)
        a = random_shape(rng, w, kind_a, rng.integers(-8, 9, size=2) * 0.25, lattice=True)
        verts, norms = w.arrays()
        spec = float(rng.choice([0.0, SPEC, 0.5]))
        n, ids = check_pair(a, b, verts, norms, spec, f"lattice {trial}")
        counts[n] += 1
        kinds_of_id.update(int(i) // (S * S) for i in ids)
    # every branch of the pair was reached
    assert counts[0] > 0 and counts[1] > 0
    if SHAPE_CIRCLE not in (kind_a, kind_b):
        assert counts[2] > 0
        assert kinds_of_id == {1, 2, 3}, kinds_of_id  # ref on a, ref on b, vertex-vertex
    else:
        assert kinds_of_id == {0}


# --- the binding's checks -------------------------------------------------------------------


def test_binding_rejects_bad_arrays_and_ranges():
    w = Scene()
    a = w.circle((0.0, 0.0), 0.5)
    b = w.segment((-1.0, -0.51), (1.0, -0.51))
    verts, norms = w.arrays()
    assert _core.collide2d(*a, *b, verts, norms, SPEC)[0] == 1
    with pytest.raises(ValueError, match="dtype"):
        _core.collide2d(*a, *b, verts.astype(np.float32), norms, SPEC)
    with pytest.raises(ValueError, match="shape"):
        _core.collide2d(*a, *b, verts.reshape(-1), norms, SPEC)
    with pytest.raises(ValueError, match="rows"):
        _core.collide2d(*a, *b, verts, norms[:2], SPEC)
    with pytest.raises(ValueError, match="outside"):
        _core.collide2d(*a, SHAPE_SEGMENT, 2, 2, 0.0, verts, norms, SPEC)
    with pytest.raises(ValueError, match="outside"):
        _core.collide2d(SHAPE_CIRCLE, -1, 1, 0.5, *b, verts, norms, SPEC)
    with pytest.raises(ValueError, match="2 vertices"):
        _core.collide2d(*a, SHAPE_SEGMENT, 1, 1, 0.0, verts, norms, SPEC)
    # unknown kinds give no points, as in numba
    assert _core.collide2d(*a, 7, 1, 2, 0.0, verts, norms, SPEC)[0] == 0
    assert _core.collide2d(SHAPE_POLYGON, 1, 2, 0.0, 7, 0, 1, 0.5, verts, norms, SPEC)[0] == 0
