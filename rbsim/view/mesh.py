"""3D pictures: the shapes of a 3D trajectory as triangles in their bodies' frames, the
rotation of a unit quaternion, flat shading from one light, the ground grid, and the
orbiting camera. The GIF (`rbsim.view.render3d`) and the HTML player (player3d.js)
use the same camera and light, with the same numbers.

Conventions (docs/format.md, "Trajectories"): y is up; a body's shape vertices are in
its frame relative to its ORIGIN; a world point is position + R(q) v with
q = (w, x, y, z). Units: lengths m, angles rad, image sizes pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..io.trajectory import BodyTable

__all__ = [
    "AMBIENT",
    "BodyMeshes",
    "Camera",
    "FOV",
    "LIGHT",
    "Ground",
    "body_meshes",
    "body_reach3d",
    "fit_box_shown",
    "fit_camera",
    "fit_distance",
    "ground_grid",
    "merge_coplanar",
    "quat_matrix",
    "shade",
    "shape_mesh",
    "shape_points",
    "shape_triangles",
]

# The light: a direction towards it, world frame (from above, in front, to the right).
LIGHT = tuple(float(c) for c in np.array([0.35, 1.0, 0.55]) / np.linalg.norm([0.35, 1.0, 0.55]))
# Brightness of a face turned away from the light (as a fraction of its full colour).
AMBIENT = 0.35
# Vertical field of view of the camera, rad.
FOV = math.radians(40.0)
# The camera's first direction: turned YAW about y from +z (the 2D view's direction),
# raised PITCH above the horizontal, rad.
YAW = 0.6
PITCH = 0.4
# Subdivisions of the icosahedron that draws a sphere (1: 80 triangles).
ICOSPHERE_LEVEL = 1
# A capsule: sides around its axis, and rings per round end.
CAPSULE_SIDES = 16
CAPSULE_RINGS = 4
# Margin around the fitted bodies' box on each side, as a fraction of its largest side.
FIT_MARGIN = 0.05
# Smallest side of a fitted box, m, so that one small still body is not blown up.
FIT_MIN_SIDE = 1.0
# Lines of the ground grid across its patch (about; the spacing is a round number).
GRID_LINES = 12
# Half the side of the ground patch, as a multiple of the fitted radius.
GRID_EXTENT = 1.6


def shape_points(bodies: BodyTable, s: int) -> np.ndarray:
    """Shape s's vertex rows of a 3D body table, (k,3) m, body frame."""
    a = int(bodies.shape_vertex_start[s])
    return bodies.shape_vertices[a : a + int(bodies.shape_vertex_count[s])]


def shape_triangles(bodies: BodyTable, s: int) -> np.ndarray:
    """Shape s's triangles of a 3D body table, (m,3) indices into its vertex rows."""
    assert bodies.shape_face_start is not None and bodies.shape_face_count is not None
    assert bodies.shape_faces is not None
    a = int(bodies.shape_face_start[s])
    return np.asarray(bodies.shape_faces[a : a + int(bodies.shape_face_count[s])], dtype=np.int64)


# ---------------------------------------------------------------------------------------
# Rotations and shading
# ---------------------------------------------------------------------------------------


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (...,3,3) of quaternions q (...,4) = (w, x, y, z) (normalised
    here, so that a float32 file's rounding does not scale the bodies)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def shade(normal: np.ndarray) -> np.ndarray:
    """Brightness in [AMBIENT, 1] of faces with world-frame unit normals (...,3): Lambert's
    cosine law from LIGHT over an ambient floor (flat shading: one value per face)."""
    lit = np.clip(np.asarray(normal, dtype=float) @ np.array(LIGHT), 0.0, 1.0)
    return AMBIENT + (1.0 - AMBIENT) * lit


# ---------------------------------------------------------------------------------------
# Shapes as triangles
# ---------------------------------------------------------------------------------------


def _outward(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The triangles of a convex mesh, each turned counter-clockwise seen from outside
    (its right-hand normal pointing away from the mesh's centre)."""
    if not len(tris):
        return tris.reshape(0, 3)
    centre = points.mean(axis=0)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    n = np.cross(b - a, c - a)
    flip = np.einsum("ij,ij->i", n, (a + b + c) / 3 - centre) < 0
    out = tris.copy()
    out[flip] = out[flip][:, [0, 2, 1]]
    return out


def merge_coplanar(points: np.ndarray, tris: np.ndarray) -> list[list[int]]:
    """The faces of a convex solid from its triangles (counter-clockwise outside): the
    triangles that lie in one plane merged into one polygon, its points in
    counter-clockwise order seen from outside. A box's 12 triangles give its 6 sides."""
    if not len(tris):
        return []
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    offset = np.einsum("ij,ij->i", n, a)
    scale = max(float(np.max(np.abs(points))), 1e-12)
    faces: list[list[int]] = []
    used = np.zeros(len(tris), dtype=bool)
    for i in range(len(tris)):
        if used[i]:
            continue
        # the same plane: normals within 1e-9 rad, offsets within 1e-9 of the size
        same = ~used & (n @ n[i] > 1 - 1e-9) & (np.abs(offset - offset[i]) <= 1e-9 * scale)
        used |= same
        corners = np.unique(tris[same].reshape(-1))
        centre = points[corners].mean(axis=0)
        e1 = points[corners[0]] - centre
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n[i], e1)
        rel = points[corners] - centre
        angle = np.arctan2(rel @ e2, rel @ e1)
        faces.append([int(k) for k in corners[np.argsort(angle, kind="stable")]])
    return faces


def _split_in_four(
    points: list[np.ndarray], tris: list[tuple[int, int, int]]
) -> list[tuple[int, int, int]]:
    """Each triangle split in four at its edges' midpoints, pushed out onto the unit
    sphere (appended to `points`; a shared edge's midpoint once)."""
    middle: dict[tuple[int, int], int] = {}

    def mid(i: int, j: int) -> int:
        key = (min(i, j), max(i, j))
        if key not in middle:
            m = points[i] + points[j]
            points.append(m / np.linalg.norm(m))
            middle[key] = len(points) - 1
        return middle[key]

    finer = []
    for a, b, c in tris:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        finer += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return finer


def icosphere(level: int = ICOSPHERE_LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """A unit sphere: an icosahedron with each triangle split in four `level` times;
    (k,3) points on the sphere and (20·4^level, 3) triangles, counter-clockwise outside."""
    t = (1 + math.sqrt(5)) / 2
    pts = [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1),
    ]  # fmt: skip
    tris = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
        (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
        (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
        (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]  # fmt: skip
    points = [np.array(p, dtype=float) / np.linalg.norm(p) for p in pts]
    for _ in range(level):
        tris = _split_in_four(points, tris)
    p = np.array(points)
    return p, _outward(p, np.array(tris, dtype=np.int64))


def capsule_mesh(a: np.ndarray, b: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule (the points within r of segment a-b, m) as a closed triangle mesh:
    CAPSULE_SIDES around, CAPSULE_RINGS rings per round end; (k,3) points, (m,3)
    triangles, counter-clockwise seen from outside."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    d = axis / length if length > 0 else np.array([0.0, 1.0, 0.0])
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    phi = 2 * math.pi * np.arange(CAPSULE_SIDES) / CAPSULE_SIDES
    ring_dirs = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    rings: list[np.ndarray] = []
    # from the pole beyond a, over a's round end, along the side, over b's round end
    for k in range(1, CAPSULE_RINGS + 1):
        theta = math.pi / 2 * k / CAPSULE_RINGS  # from the axis
        rings.append(a - r * math.cos(theta) * d + r * math.sin(theta) * ring_dirs)
    for k in range(CAPSULE_RINGS, 0, -1):
        theta = math.pi / 2 * k / CAPSULE_RINGS
        rings.append(b + r * math.cos(theta) * d + r * math.sin(theta) * ring_dirs)
    m = CAPSULE_SIDES
    points = np.concatenate([[a - r * d], *rings, [b + r * d]])
    tris: list[tuple[int, int, int]] = []
    first, last = 1, 1 + m * (len(rings) - 1)
    for i in range(m):
        j = (i + 1) % m
        tris.append((0, first + j, first + i))
        tris.append((len(points) - 1, last + i, last + j))
    for k in range(len(rings) - 1):
        lo, hi = 1 + k * m, 1 + (k + 1) * m
        for i in range(m):
            j = (i + 1) % m
            tris += [(lo + i, lo + j, hi + j), (lo + i, hi + j, hi + i)]
    return points, _outward(points, np.array(tris, dtype=np.int64))


def shape_mesh(
    kind: str, verts: np.ndarray, faces: np.ndarray, radius: float
) -> tuple[np.ndarray, list[list[int]], bool] | None:
    """One shape as flat faces in its body's frame: ((k,3) m points, faces as lists of
    point indices counter-clockwise seen from outside, whether the faces' edges are
    drawn), or None for a plane (drawn with the ground). Boxes and hulls: their
    triangles merged into polygons, edges drawn; spheres and capsules: triangles, no
    edges (they stand for a round surface). verts, faces: the shape's rows of the body
    table; radius: m."""
    if kind == "plane":
        return None
    if kind == "sphere":
        unit, tris = icosphere()
        return np.asarray(verts[0], dtype=float) + float(radius) * unit, tris.tolist(), False
    if kind == "capsule":
        points, tris = capsule_mesh(verts[0], verts[1], float(radius))
        return points, tris.tolist(), False
    points = np.asarray(verts, dtype=float)
    tris = _outward(points, np.asarray(faces, dtype=np.int64).reshape(-1, 3))
    return points, merge_coplanar(points, tris), True


@dataclass
class BodyMeshes:
    """Every shape of N bodies as flat faces in each body's frame.

    points (P,3) m, body frame; point_body (P,); faces (M,K) point indices, each face's
    first face_size[i] entries counter-clockwise seen from outside, padded with its last
    point (so every row is a polygon of K corners); face_size (M,); face_body (M,);
    face_outlined (M,) bool: its edges are drawn (boxes and hulls); planes: (body,
    point (3,) m, unit normal (3,)) in body frames.
    """

    points: np.ndarray
    point_body: np.ndarray
    faces: np.ndarray
    face_size: np.ndarray
    face_body: np.ndarray
    face_outlined: np.ndarray
    planes: list[tuple[int, np.ndarray, np.ndarray]]


def body_meshes(bodies: BodyTable) -> BodyMeshes:
    """The faces of every shape of `bodies` (planes kept apart)."""
    points: list[np.ndarray] = []
    point_body: list[np.ndarray] = []
    faces: list[list[int]] = []
    face_body: list[int] = []
    outlined: list[bool] = []
    planes: list[tuple[int, np.ndarray, np.ndarray]] = []
    count = 0
    for s, kind in enumerate(bodies.shape_kind):
        b = int(bodies.shape_body[s])
        verts = shape_points(bodies, s)
        if kind == "plane":
            planes.append((b, verts[0].copy(), bodies.shape_normal[s].copy()))
            continue
        mesh = shape_mesh(kind, verts, shape_triangles(bodies, s), float(bodies.shape_radius[s]))
        assert mesh is not None
        p, shape_faces, edges = mesh
        points.append(p)
        point_body.append(np.full(len(p), b, dtype=np.int64))
        faces += [[k + count for k in f] for f in shape_faces]
        face_body += [b] * len(shape_faces)
        outlined += [edges] * len(shape_faces)
        count += len(p)
    size = np.array([len(f) for f in faces], dtype=np.int64)
    k = int(size.max()) if len(size) else 3
    padded = np.array([f + [f[-1]] * (k - len(f)) for f in faces], dtype=np.int64)
    return BodyMeshes(
        points=np.concatenate(points) if points else np.zeros((0, 3)),
        point_body=np.concatenate(point_body) if point_body else np.zeros(0, dtype=np.int64),
        faces=padded.reshape(-1, k),
        face_size=size,
        face_body=np.array(face_body, dtype=np.int64),
        face_outlined=np.array(outlined, dtype=bool),
        planes=planes,
    )


def body_reach3d(bodies: BodyTable) -> np.ndarray:
    """(N,) m: the largest distance from each body's origin to a point of its shapes
    other than planes (0 for a body without such shapes), whatever its orientation."""
    reach = np.zeros(len(bodies))
    for s, kind in enumerate(bodies.shape_kind):
        if kind == "plane":
            continue
        verts = shape_points(bodies, s)
        if len(verts):
            r = float(np.max(np.linalg.norm(verts, axis=1))) + float(bodies.shape_radius[s])
            b = int(bodies.shape_body[s])
            reach[b] = max(reach[b], r)
    return reach


# ---------------------------------------------------------------------------------------
# The camera
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Camera:
    """A perspective camera orbiting `target` (m): at `distance` m from it, turned `yaw`
    rad about the world's y axis from +z and raised `pitch` rad above the horizontal,
    looking at the target with y up; `fov` the vertical field of view, rad."""

    target: tuple[float, float, float]
    distance: float
    yaw: float = YAW
    pitch: float = PITCH
    fov: float = FOV

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(eye, right, up, forward): the camera's place, m, and its unit axes."""
        cp = math.cos(self.pitch)
        back = np.array([cp * math.sin(self.yaw), math.sin(self.pitch), cp * math.cos(self.yaw)])
        eye = np.array(self.target, dtype=float) + self.distance * back
        forward = -back
        right = np.array([math.cos(self.yaw), 0.0, -math.sin(self.yaw)])
        up = np.cross(right, forward)
        return eye, right, up, forward

    def project(self, points: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (K,2) (x right, y down, from the image's top-left corner) and depths
        (K,) m along the view direction of world points (K,3) m, in a width x height
        image. Points at depth <= 0 are behind the camera (their pixels are not used)."""
        eye, right, up, forward = self.basis()
        rel = np.asarray(points, dtype=float) - eye
        x, y, z = rel @ right, rel @ up, rel @ forward
        f = (height / 2) / math.tan(self.fov / 2)
        zs = np.where(z > 1e-9, z, 1e-9)  # guard the division; such points are culled
        px = np.stack([width / 2 + f * x / zs, height / 2 - f * y / zs], axis=-1)
        return px, z


def fit_box_shown(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box a fitted camera shows for the box [lo, hi] (m): grown by FIT_MARGIN of its
    largest side on every side, each side at least FIT_MIN_SIDE, about its centre."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    centre = (lo + hi) / 2
    side = np.maximum(hi - lo, FIT_MIN_SIDE) + 2 * FIT_MARGIN * float(np.max(hi - lo))
    return centre - side / 2, centre + side / 2


def fit_distance(lo: np.ndarray, hi: np.ndarray, camera: Camera, width: int, height: int) -> float:
    """The distance, m, from the box [lo, hi]'s centre at which `camera` (its yaw,
    pitch and fov) shows all eight corners in a width x height image: for each corner
    at (x, y, z) from the centre in the camera's axes, |x| <= tan(fov_w/2) (d + z) and
    |y| <= tan(fov/2) (d + z). player3d.js computes the same."""
    _eye, right, up, forward = camera.basis()
    corners = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)], dtype=float)
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    rel = lo + corners * (hi - lo) - (lo + hi) / 2
    ty = math.tan(camera.fov / 2)
    tx = ty * width / height
    x, y, z = rel @ right, rel @ up, rel @ forward
    return float(max(np.max(np.abs(x) / tx - z), np.max(np.abs(y) / ty - z)))


def fit_camera(lo: np.ndarray, hi: np.ndarray, width: int, height: int) -> Camera:
    """The camera at the default yaw and pitch that shows the box [lo, hi] (m, world;
    with fit_box_shown's margin) whole in a width x height image, aimed at its centre."""
    lo, hi = fit_box_shown(lo, hi)
    aimed = Camera(tuple(float(c) for c in (lo + hi) / 2), 1.0)  # type: ignore[arg-type]
    return replace(aimed, distance=fit_distance(lo, hi, aimed, width, height))


# ---------------------------------------------------------------------------------------
# The ground
# ---------------------------------------------------------------------------------------


@dataclass
class Ground:
    """What is drawn under the bodies, world frame, m: quads (Q,4,3) (each plane's
    finite patch, filled), lines (L,2,3) (grid lines on the patches, or on the floor
    under the bodies when the scene has no plane)."""

    quads: np.ndarray
    lines: np.ndarray


def _round_step(length: float) -> float:
    """A round spacing (1, 2 or 5 times a power of ten, m) near length / GRID_LINES."""
    raw = max(length / GRID_LINES, 1e-9)
    power = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if raw <= m * power * 1.0001:
            return m * power
    return 10 * power


def _patch(centre: np.ndarray, normal: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """A square patch of side 2 half (m) about `centre` in the plane of unit `normal`,
    and its grid lines at a round spacing aligned with the world's round coordinates
    where the plane is a coordinate plane."""
    n = normal / np.linalg.norm(normal)
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 0, 1.0])
    e1 = helper - n * (helper @ n)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    step = _round_step(2 * half)
    # snap the centre to the grid so the lines fall on round coordinates
    u0 = math.floor((centre @ e1) / step) * step
    v0 = math.floor((centre @ e2) / step) * step
    base = centre - (centre @ e1) * e1 - (centre @ e2) * e2 + u0 * e1 + v0 * e2
    k = math.ceil(half / step)
    quad = np.array([base + (su * k * step) * e1 + (sv * k * step) * e2
                     for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])  # fmt: skip
    lines = []
    for i in range(-k, k + 1):
        lines.append([base + i * step * e1 - k * step * e2, base + i * step * e1 + k * step * e2])
        lines.append([base - k * step * e1 + i * step * e2, base + k * step * e1 + i * step * e2])
    return quad, np.array(lines)


def ground_grid(
    planes: list[tuple[np.ndarray, np.ndarray]], lo: np.ndarray, hi: np.ndarray
) -> Ground:
    """The ground for a scene whose moving bodies fill the box [lo, hi] (m): a finite
    patch with grid lines on each plane (point, unit normal, world frame) about the
    point of the plane nearest the box's centre; without planes, a grid on the floor
    y = lo[1] under the box. Patches reach GRID_EXTENT times the box's radius."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    centre = (lo + hi) / 2
    half = GRID_EXTENT * max(float(np.linalg.norm(hi - lo)) / 2, FIT_MIN_SIDE)
    quads, lines = [], []
    for point, normal in planes:
        n = np.asarray(normal, dtype=float)
        n = n / np.linalg.norm(n)
        foot = centre - ((centre - point) @ n) * n
        q, g = _patch(foot, n, half)
        quads.append(q)
        lines.append(g)
    if not planes:
        _, g = _patch(np.array([centre[0], lo[1], centre[2]]), np.array([0, 1.0, 0]), half)
        lines.append(g)
    return Ground(
        quads=np.array(quads).reshape(-1, 4, 3),
        lines=np.concatenate(lines).reshape(-1, 2, 3),
    )
