"""Geometry of 3D scenes: unit quaternions (w, x, y, z), box corners and faces, and the
convex hull of a point set (qhull, through scipy.spatial.ConvexHull).

Plain floats and tuples in, plain floats and tuples out, so that a resolved scene holds
no numpy objects; lengths in metres, angles in radians.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)

# |q| or |n| this close to 1 counts as unit already: it is kept bit for bit, so that a
# resolved scene written out and read back is equal (q / |q| is within 2 ulp of unit
# length, inside this band, so normalising twice changes nothing)
UNIT_BAND = 2.0**-50


def normalized(v: Sequence[float]) -> tuple[float, ...] | None:
    """``v`` scaled to unit length (kept as given when it is unit already to rounding),
    or None for a zero vector."""
    n = math.hypot(*v)
    if not n > 0.0 or not math.isfinite(n):
        return None
    if abs(n - 1.0) <= UNIT_BAND:
        return tuple(float(x) for x in v)
    return tuple(float(x) / n for x in v)


def axis_angle(axis: Vec3, angle: float) -> Quat | None:
    """The unit quaternion of a rotation by ``angle`` (rad) about ``axis`` (any length
    but zero; None for a zero axis)."""
    u = normalized(axis)
    if u is None:
        return None
    s = math.sin(0.5 * angle)
    return (math.cos(0.5 * angle), s * u[0], s * u[1], s * u[2])


def quat_multiply(a: Quat, b: Quat) -> Quat:
    """The Hamilton product a b (the rotation b, then a)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_matrix(q: Sequence[float] | np.ndarray) -> np.ndarray:
    """The rotation matrices R (...,3,3) of unit quaternions q (...,4) (w, x, y, z): R v
    rotates v. One quaternion (4,) gives one (3,3) matrix, an (N,4) array N of them."""
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def matrix_quat(r: np.ndarray) -> Quat:
    """The unit quaternion (w >= 0) of a proper rotation matrix (Shepperd's method: the
    largest of the four squared components first, for accuracy)."""
    m = np.asarray(r, dtype=np.float64)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    candidates = (trace, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(candidates))
    if k == 0:
        s = 2.0 * math.sqrt(max(1.0 + trace, 0.0))
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0))
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(max(1.0 + m[1, 1] - m[0, 0] - m[2, 2], 0.0))
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 + m[2, 2] - m[0, 0] - m[1, 1], 0.0))
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    if q[0] < 0.0:
        q = (-q[0], -q[1], -q[2], -q[3])
    n = math.hypot(*q)
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def transform(points: Sequence[Sequence[float]], offset: Vec3, q: Quat) -> tuple[Vec3, ...]:
    """``points`` rotated by ``q`` about the origin, then moved by ``offset`` (m)."""
    if q == IDENTITY:
        return tuple(
            (float(p[0]) + offset[0], float(p[1]) + offset[1], float(p[2]) + offset[2])
            for p in points
        )
    r = quat_matrix(q)
    out = np.asarray(points, dtype=np.float64) @ r.T + np.asarray(offset, dtype=np.float64)
    return tuple((float(a), float(b), float(c)) for a, b, c in out)


# A box's corners: corner k has the sign bits (x, y, z) = (k & 1, k & 2, k & 4), so
# corner 0 is (-,-,-) and corner 7 is (+,+,+).
BOX_SIGNS = tuple(
    (1.0 if k & 1 else -1.0, 1.0 if k & 2 else -1.0, 1.0 if k & 4 else -1.0) for k in range(8)
)
# Its twelve triangles, counter-clockwise seen from outside (outward normal by the
# right-hand rule): two per face, -x, +x, -y, +y, -z, +z.
BOX_FACES: tuple[tuple[int, int, int], ...] = (
    (0, 4, 6), (0, 6, 2),  # -x
    (1, 3, 7), (1, 7, 5),  # +x
    (0, 1, 5), (0, 5, 4),  # -y
    (2, 6, 7), (2, 7, 3),  # +y
    (0, 2, 3), (0, 3, 1),  # -z
    (4, 5, 7), (4, 7, 6),  # +z
)  # fmt: skip


def box_corners_3d(size: Vec3, offset: Vec3, q: Quat) -> tuple[Vec3, ...]:
    """The eight corners (in BOX_SIGNS order) of a box of full extents ``size`` (m)
    rotated by ``q`` about its centre and moved to ``offset``."""
    half = [0.5 * s for s in size]
    local = [(sx * half[0], sy * half[1], sz * half[2]) for sx, sy, sz in BOX_SIGNS]
    return transform(local, offset, q)


class HullError(ValueError):
    """Points whose convex hull has no volume (all in one plane, or on one line)."""


def convex_hull(
    points: Sequence[Vec3],
) -> tuple[tuple[Vec3, ...], tuple[tuple[int, int, int], ...], tuple[int, ...]]:
    """The convex hull of ``points``: (its extreme points in the order given, its
    triangles as indices into them, counter-clockwise seen from outside, and which
    given point each extreme point is). Raises HullError for a flat or degenerate set."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    span = float(np.max(np.abs(pts - pts[0]))) if len(pts) else 0.0
    if not span > 0.0:
        raise HullError("all the points are the same point")
    try:
        # about the first point and in units of the span, so that a small hull far from
        # the origin keeps its digits and qhull's tolerances are relative
        hull = ConvexHull((pts - pts[0]) / span)
    except QhullError:
        raise HullError(
            "the points span no volume (all in one plane or on one line); "
            "a convex shape needs 4 points that are not in one plane"
        ) from None
    given = tuple(sorted(int(i) for i in hull.vertices))  # in the order given
    index = {g: k for k, g in enumerate(given)}
    faces = []
    for simplex, equation in zip(hull.simplices, hull.equations, strict=True):
        a, b, c = (int(i) for i in simplex)
        normal = np.cross(pts[b] - pts[a], pts[c] - pts[a])
        if float(np.dot(normal, equation[:3])) < 0.0:
            b, c = c, b
        faces.append((index[a], index[b], index[c]))
    vertices = tuple(tuple(float(x) for x in pts[g]) for g in given)
    return vertices, tuple(faces), given  # type: ignore[return-value]


def hull_width(vertices: Sequence[Vec3], faces: Sequence[tuple[int, int, int]]) -> float:
    """The least width of a convex hull over its face directions, m (for a box: its
    smallest side)."""
    pts = np.asarray(vertices, dtype=np.float64)
    widths = []
    for a, b, c in faces:
        n = np.cross(pts[b] - pts[a], pts[c] - pts[a])
        length = float(np.linalg.norm(n))
        if length > 0.0:
            widths.append(float(np.max(np.abs((pts - pts[a]) @ (n / length)))))
    return min(widths) if widths else 0.0
