"""Narrowphase: the contact manifold between two shapes, as numba kernels.

Every shape is a convex core with a radius around it: a circle is a point core, a
segment (capsule) a 2-vertex core, a polygon a convex CCW core (radius 0, or rounded).
The caller keeps all cores in WORLD coordinates in two flat arrays:

    verts (V,2) float64, m: shape s uses rows start..start+count-1.
    norms (V,2) float64: norms[i] is the outward unit normal of edge i, from vertex i
        to vertex i+1 (cyclic). A segment a-b has norms[start] = (a->b rotated
        clockwise) and norms[start+1] = its negative, so it is a 2-vertex polygon whose
        edges are a->b and b->a. A circle's norms row is unused.

A manifold is one normal and one or two points:

    out_normal (2,): unit normal pointing FROM shape b TOWARDS shape a (the impulse
        +λn acts on a, -λn on b).
    out_point (2,2), m: each point midway between the two surfaces.
    out_sep (2,), m: signed distance between the surfaces (radii included) along the
        normal; negative = overlap. Points farther apart than `speculative` are dropped.
    out_id (2,) int64: feature id of each point, see below.

Feature ids stay the same while the same features touch, so the solver can carry
impulses over from the last step (warm starting). With S = 2**16:

    clipped point:  (1 + ref_is_b) * S**2 + reference_edge * S + incident_vertex
    vertex-vertex:  3 * S**2 + vertex_of_a * S + vertex_of_b
    circle cases:   0 (one point, nothing to tell apart)

Indices are local to their shape (0..count-1). "a" and "b" are the pair function's own
arguments; `collide` keeps the ids of the pair function it calls.

One pure function per kind pair, `collide_<kind>_<kind>`, all with the signature of
`collide` minus the two kinds; `collide` dispatches on the kinds and swaps a pair that
comes in the other order, negating the normal back. Polygons and segments share one
routine (`_collide_cores`): SAT over both shapes' edge normals, a reference face on the
shape that is separated most, the incident edge clipped against the reference face's
side planes, and a corner-to-corner correction for separated rounded shapes.
"""

import math

import numpy as np
from numba import njit

from ...constants import LINEAR_SLOP
from ...scene.types import SHAPE_CIRCLE, SHAPE_POLYGON, SHAPE_SEGMENT

# The reference face stays on shape a unless b's best face is separated more by this
# much, so that nearly equal faces (a box resting flat on a box) do not swap the
# reference, the points and their ids from one step to the next. m.
REFERENCE_FACE_TOLERANCE = 0.1 * LINEAR_SLOP

# Least combined radius of two colliding segments, m: thin segments rest this far
# apart. About the linear slop; smaller lets a thin rod fall through a thin ground.
SEGMENT_SKIN = LINEAR_SLOP

# Lengths below this are treated as zero (directions are not normalised from them). m.
LINEAR_EPSILON = 1.0e-9

_ID_SHIFT = 1 << 16
_ID_VERTEX_VERTEX = 3


@njit(cache=True, _nrt=False, inline="always")
def _single_point(
    ax, ay, radius_a, bx, by, radius_b, nx, ny,
    fid, speculative, out_normal, out_point, out_sep, out_id,
):  # fmt: skip
    """One contact point between core points a and b with normal n (b -> a). Returns 0 or 1."""
    sep = (ax - bx) * nx + (ay - by) * ny - radius_a - radius_b
    if sep > speculative:
        return 0
    # a's surface faces b (along -n), b's surface faces a (along +n)
    out_normal[0] = nx
    out_normal[1] = ny
    out_point[0, 0] = 0.5 * ((ax - radius_a * nx) + (bx + radius_b * nx))
    out_point[0, 1] = 0.5 * ((ay - radius_a * ny) + (by + radius_b * ny))
    out_sep[0] = sep
    out_id[0] = fid
    return 1


@njit(cache=True, _nrt=False, inline="always")
def _flip_normal(out_normal):
    out_normal[0] = -out_normal[0]
    out_normal[1] = -out_normal[1]


@njit(cache=True, _nrt=False, inline="always")
def collide_circle_circle(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Circle a against circle b: one point on the line of centres."""
    ax, ay = verts[start_a, 0], verts[start_a, 1]
    bx, by = verts[start_b, 0], verts[start_b, 1]
    dx, dy = ax - bx, ay - by
    dist = math.sqrt(dx * dx + dy * dy)
    if dist - radius_a - radius_b > speculative:
        return 0
    if dist > LINEAR_EPSILON:
        nx, ny = dx / dist, dy / dist
    else:  # concentric: any direction separates them equally well
        nx, ny = 0.0, 1.0
    return _single_point(
        ax, ay, radius_a, bx, by, radius_b, nx, ny,
        0, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False, inline="always")
def collide_circle_polygon(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Circle a against (possibly rounded) convex polygon b, count_b >= 3.

    The face that separates the centre most decides: when the centre lies beyond one of
    that face's end points (vertex region) the normal runs from the vertex to the
    centre, otherwise it is the face normal (also when the centre is inside).
    """
    cx, cy = verts[start_a, 0], verts[start_a, 1]
    radius = radius_a + radius_b
    best = -np.inf
    edge = 0
    for i in range(count_b):
        k = start_b + i
        s = norms[k, 0] * (cx - verts[k, 0]) + norms[k, 1] * (cy - verts[k, 1])
        if s > best:
            best = s
            edge = i
    if best - radius > speculative:
        return 0
    i1 = start_b + edge
    i2 = start_b + (edge + 1) % count_b
    v1x, v1y = verts[i1, 0], verts[i1, 1]
    v2x, v2y = verts[i2, 0], verts[i2, 1]
    ex, ey = v2x - v1x, v2y - v1y
    u1 = (cx - v1x) * ex + (cy - v1y) * ey
    u2 = (v2x - cx) * ex + (v2y - cy) * ey
    # vertex regions exist only outside the polygon (best > 0), so |c - v| >= best > 0
    if u1 < 0.0 and best > LINEAR_EPSILON:
        px, py = v1x, v1y
    elif u2 < 0.0 and best > LINEAR_EPSILON:
        px, py = v2x, v2y
    else:
        nx, ny = norms[i1, 0], norms[i1, 1]
        px, py = cx - best * nx, cy - best * ny
        return _single_point(
            cx, cy, radius_a, px, py, radius_b, nx, ny,
            0, speculative, out_normal, out_point, out_sep, out_id,
        )  # fmt: skip
    dx, dy = cx - px, cy - py
    dist = math.sqrt(dx * dx + dy * dy)
    return _single_point(
        cx, cy, radius_a, px, py, radius_b, dx / dist, dy / dist,
        0, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False, inline="always")
def collide_circle_segment(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Circle a against segment (capsule) b: one point from the closest point on the core."""
    cx, cy = verts[start_a, 0], verts[start_a, 1]
    p1x, p1y = verts[start_b, 0], verts[start_b, 1]
    ex, ey = verts[start_b + 1, 0] - p1x, verts[start_b + 1, 1] - p1y
    ee = ex * ex + ey * ey
    t = 0.0
    if ee > LINEAR_EPSILON * LINEAR_EPSILON:
        t = min(max(((cx - p1x) * ex + (cy - p1y) * ey) / ee, 0.0), 1.0)
    px, py = p1x + t * ex, p1y + t * ey
    dx, dy = cx - px, cy - py
    dist = math.sqrt(dx * dx + dy * dy)
    if dist - radius_a - radius_b > speculative:
        return 0
    if dist > LINEAR_EPSILON:
        nx, ny = dx / dist, dy / dist
    else:  # centre on the core: push out along the segment's normal
        nx, ny = norms[start_b, 0], norms[start_b, 1]
    return _single_point(
        cx, cy, radius_a, px, py, radius_b, nx, ny,
        0, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False, inline="always")
def _max_separation(start1, count1, start2, count2, verts, norms):
    """The edge of core 1 whose normal separates core 2 most: (separation m, local edge)."""
    best = -np.inf
    best_edge = 0
    for i in range(count1):
        k = start1 + i
        nx, ny = norms[k, 0], norms[k, 1]
        vx, vy = verts[k, 0], verts[k, 1]
        s = np.inf
        for j in range(start2, start2 + count2):
            d = nx * (verts[j, 0] - vx) + ny * (verts[j, 1] - vy)
            if d < s:
                s = d
        if s > best:
            best = s
            best_edge = i
    return best, best_edge


@njit(cache=True, _nrt=False, inline="always")
def _segment_closest_fractions(p1x, p1y, q1x, q1y, p2x, p2y, q2x, q2y):
    """Fractions (s, t) of the closest points p1 + s (q1 - p1) and p2 + t (q2 - p2).

    An end point is reported exactly as 0.0 or 1.0 (by clamping), which is how the
    caller recognises the vertex-vertex region. Parallel segments start from s = 0.
    """
    d1x, d1y = q1x - p1x, q1y - p1y
    d2x, d2y = q2x - p2x, q2y - p2y
    rx, ry = p1x - p2x, p1y - p2y
    a = d1x * d1x + d1y * d1y
    e = d2x * d2x + d2y * d2y
    f = d2x * rx + d2y * ry
    tiny = LINEAR_EPSILON * LINEAR_EPSILON
    if a <= tiny and e <= tiny:
        return 0.0, 0.0
    if a <= tiny:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = d1x * rx + d1y * ry
    if e <= tiny:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = d1x * d2x + d1y * d2y
    denom = a * e - b * b
    s = 0.0
    if denom > 1.0e-12 * a * e:
        s = min(max((b * f - c * e) / denom, 0.0), 1.0)
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((b - c) / a, 0.0), 1.0)
    return s, t


@njit(cache=True, _nrt=False, inline="always")
def _clip_incident_edge(
    ref_is_b, ref_start, ref_count, ref_edge, ref_radius, inc_start, inc_count, inc_edge,
    inc_radius, verts, norms, speculative, out_normal, out_point, out_sep, out_id,
):  # fmt: skip
    """Clip the incident edge to the reference face's side planes; keep points within reach.

    In the reference face's frame (origin v1, tangent t along the face, normal n out of
    the reference shape) the incident edge w(λ) = w1 + λ (w2 - w1) is cut to the part
    with 0 <= t·(w - v1) <= face length; each end of that part is a point whose core
    separation is n·(w - v1).
    """
    i1 = ref_start + ref_edge
    i2 = ref_start + (ref_edge + 1) % ref_count
    nx, ny = norms[i1, 0], norms[i1, 1]
    tx, ty = -ny, nx  # n rotated counter-clockwise = the face direction v1 -> v2
    v1x, v1y = verts[i1, 0], verts[i1, 1]
    length = (verts[i2, 0] - v1x) * tx + (verts[i2, 1] - v1y) * ty
    j1 = inc_start + inc_edge
    j2 = inc_start + (inc_edge + 1) % inc_count
    w1x, w1y = verts[j1, 0], verts[j1, 1]
    ex, ey = verts[j2, 0] - w1x, verts[j2, 1] - w1y
    u1 = (w1x - v1x) * tx + (w1y - v1y) * ty
    du = ex * tx + ey * ty
    lo, hi = 0.0, 1.0
    if abs(du) > LINEAR_EPSILON:
        la = -u1 / du
        lb = (length - u1) / du
        lo = max(0.0, min(la, lb))
        hi = min(1.0, max(la, lb))
        if lo > hi:  # the edge misses the face: keep its end nearest the face
            if hi < 0.0:
                hi = lo
            else:
                lo = hi
    if ref_is_b:
        out_normal[0], out_normal[1] = nx, ny
    else:
        out_normal[0], out_normal[1] = -nx, -ny
    radius = ref_radius + inc_radius
    id_ref = (1 + ref_is_b) * _ID_SHIFT * _ID_SHIFT + ref_edge * _ID_SHIFT
    n_points = 0
    for k in range(2):
        if k == 0:
            lam = lo
            inc_vertex = inc_edge
        else:
            if hi <= lo:  # both ends clipped to one place: one point
                break
            lam = hi
            inc_vertex = (inc_edge + 1) % inc_count
        px, py = w1x + lam * ex, w1y + lam * ey
        depth = (px - v1x) * nx + (py - v1y) * ny
        sep = depth - radius
        if sep > speculative:
            continue
        # midway between the reference surface (p + (r_ref - depth) n) and the
        # incident surface (p - r_inc n)
        shift = 0.5 * (ref_radius - inc_radius - depth)
        out_point[n_points, 0] = px + shift * nx
        out_point[n_points, 1] = py + shift * ny
        out_sep[n_points] = sep
        out_id[n_points] = id_ref + inc_vertex
        n_points += 1
    return n_points


@njit(cache=True, _nrt=False, inline="always")
def _collide_cores(
    start_a, count_a, radius_a, start_b, count_b, radius_b,
    verts, norms, speculative, out_normal, out_point, out_sep, out_id,
):  # fmt: skip
    """Two convex cores with 2 or more vertices each (polygons and segments), rounded."""
    radius = radius_a + radius_b
    sep_a, edge_a = _max_separation(start_a, count_a, start_b, count_b, verts, norms)
    if sep_a - radius > speculative:
        return 0
    sep_b, edge_b = _max_separation(start_b, count_b, start_a, count_a, verts, norms)
    if sep_b - radius > speculative:
        return 0

    ref_is_b = 1 if sep_b > sep_a + REFERENCE_FACE_TOLERANCE else 0
    if ref_is_b:
        ref_start, ref_count, ref_edge, ref_radius = start_b, count_b, edge_b, radius_b
        inc_start, inc_count, inc_radius = start_a, count_a, radius_a
    else:
        ref_start, ref_count, ref_edge, ref_radius = start_a, count_a, edge_a, radius_a
        inc_start, inc_count, inc_radius = start_b, count_b, radius_b

    # incident edge: the one whose normal is most anti-parallel to the reference normal
    i1 = ref_start + ref_edge
    nx, ny = norms[i1, 0], norms[i1, 1]
    inc_edge = 0
    min_dot = np.inf
    for j in range(inc_count):
        d = nx * norms[inc_start + j, 0] + ny * norms[inc_start + j, 1]
        if d < min_dot:
            min_dot = d
            inc_edge = j

    # Corner to corner: when the cores are apart and the closest points of the two
    # edges are end points of both, the true distance exceeds the SAT separation (face
    # normals miss the corner-to-corner axis; for segments they can miss the distance
    # entirely, e.g. two collinear capsules end to end). Report the true distance.
    sat_sep = max(sep_a, sep_b)
    if sat_sep > -LINEAR_EPSILON:
        r1 = ref_start + (ref_edge + 1) % ref_count
        k1 = inc_start + inc_edge
        k2 = inc_start + (inc_edge + 1) % inc_count
        p1x, p1y = verts[i1, 0], verts[i1, 1]
        q1x, q1y = verts[r1, 0], verts[r1, 1]
        p2x, p2y = verts[k1, 0], verts[k1, 1]
        q2x, q2y = verts[k2, 0], verts[k2, 1]
        s, t = _segment_closest_fractions(p1x, p1y, q1x, q1y, p2x, p2y, q2x, q2y)
        if (s == 0.0 or s == 1.0) and (t == 0.0 or t == 1.0):
            cx1, cy1 = p1x + s * (q1x - p1x), p1y + s * (q1y - p1y)
            cx2, cy2 = p2x + t * (q2x - p2x), p2y + t * (q2y - p2y)
            dx, dy = cx2 - cx1, cy2 - cy1
            dist = math.sqrt(dx * dx + dy * dy)
            if dist > sat_sep + LINEAR_EPSILON:
                if dist - radius > speculative:
                    return 0
                ref_vertex = ref_edge if s == 0.0 else (ref_edge + 1) % ref_count
                inc_vertex = inc_edge if t == 0.0 else (inc_edge + 1) % inc_count
                if ref_is_b:  # incident = a
                    fid = (_ID_VERTEX_VERTEX * _ID_SHIFT + inc_vertex) * _ID_SHIFT + ref_vertex
                    return _single_point(
                        cx2, cy2, radius_a, cx1, cy1, radius_b, dx / dist, dy / dist,
                        fid, speculative, out_normal, out_point, out_sep, out_id,
                    )  # fmt: skip
                fid = (_ID_VERTEX_VERTEX * _ID_SHIFT + ref_vertex) * _ID_SHIFT + inc_vertex
                return _single_point(
                    cx1, cy1, radius_a, cx2, cy2, radius_b, -dx / dist, -dy / dist,
                    fid, speculative, out_normal, out_point, out_sep, out_id,
                )  # fmt: skip

    return _clip_incident_edge(
        ref_is_b, ref_start, ref_count, ref_edge, ref_radius, inc_start, inc_count, inc_edge,
        inc_radius, verts, norms, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False)
def collide_polygon_polygon(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Convex polygon a against convex polygon b (either may be rounded): 0, 1 or 2 points."""
    return _collide_cores(
        start_a, count_a, radius_a, start_b, count_b, radius_b,
        verts, norms, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False)
def collide_polygon_segment(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Polygon a against segment (capsule) b, the segment as a 2-vertex rounded polygon."""
    return _collide_cores(
        start_a, count_a, radius_a, start_b, count_b, radius_b,
        verts, norms, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False)
def collide_segment_segment(
    start_a: int, count_a: int, radius_a: float, start_b: int, count_b: int, radius_b: float,
    verts: np.ndarray, norms: np.ndarray, speculative: float,
    out_normal: np.ndarray, out_point: np.ndarray, out_sep: np.ndarray, out_id: np.ndarray,
) -> int:  # fmt: skip
    """Segment (capsule) a against segment (capsule) b, both as 2-vertex rounded polygons."""
    return _collide_cores(
        start_a, count_a, radius_a, start_b, count_b, radius_b,
        verts, norms, speculative, out_normal, out_point, out_sep, out_id,
    )  # fmt: skip


@njit(cache=True, _nrt=False, inline="always")
def collide(
    kind_a: int,
    start_a: int,
    count_a: int,
    radius_a: float,
    kind_b: int,
    start_b: int,
    count_b: int,
    radius_b: float,
    verts: np.ndarray,
    norms: np.ndarray,
    speculative: float,
    out_normal: np.ndarray,
    out_point: np.ndarray,
    out_sep: np.ndarray,
    out_id: np.ndarray,
) -> int:
    """Contact manifold between shape a and shape b; returns the point count 0, 1 or 2.

    kind_*: SHAPE_CIRCLE, SHAPE_POLYGON or SHAPE_SEGMENT. start_*, count_*: the shape's
    rows in verts/norms (V,2) (world frame, m). radius_*: m. speculative: m, points
    whose surfaces are farther apart are dropped. Outputs (preallocated):
    out_normal (2,) b -> a, out_point (2,2) m, out_sep (2,) m, out_id (2,) int64; only
    the first `count` rows are written. Unknown kinds give 0 points.
    """
    if kind_a != SHAPE_CIRCLE and kind_b != SHAPE_CIRCLE:
        # polygons and segments alike: one core routine, so one call site to inline
        if kind_a > SHAPE_SEGMENT or kind_b > SHAPE_SEGMENT:
            return 0
        if kind_a == SHAPE_SEGMENT and kind_b == SHAPE_SEGMENT:
            # two thin segments have no inside: once one dips below the other by a
            # rounding error the normal flips and it falls through. A skin keeps them
            # apart by SEGMENT_SKIN instead (as polygon radii did in Box2D v2).
            skin = 0.5 * max(SEGMENT_SKIN - radius_a - radius_b, 0.0)
            radius_a += skin
            radius_b += skin
        return _collide_cores(
            start_a, count_a, radius_a, start_b, count_b, radius_b,
            verts, norms, speculative, out_normal, out_point, out_sep, out_id,
        )  # fmt: skip
    # at least one circle: put it first as shape a, flipping the normal back if swapped
    swap = kind_a != SHAPE_CIRCLE
    if swap:
        kind_a, kind_b = kind_b, kind_a
        start_a, start_b = start_b, start_a
        count_a, count_b = count_b, count_a
        radius_a, radius_b = radius_b, radius_a
    if kind_b == SHAPE_CIRCLE:
        n = collide_circle_circle(
            start_a, count_a, radius_a, start_b, count_b, radius_b,
            verts, norms, speculative, out_normal, out_point, out_sep, out_id,
        )  # fmt: skip
    elif kind_b == SHAPE_POLYGON:
        n = collide_circle_polygon(
            start_a, count_a, radius_a, start_b, count_b, radius_b,
            verts, norms, speculative, out_normal, out_point, out_sep, out_id,
        )  # fmt: skip
    elif kind_b == SHAPE_SEGMENT:
        n = collide_circle_segment(
            start_a, count_a, radius_a, start_b, count_b, radius_b,
            verts, norms, speculative, out_normal, out_point, out_sep, out_id,
        )  # fmt: skip
    else:
        return 0
    if swap:
        _flip_normal(out_normal)
    return n
