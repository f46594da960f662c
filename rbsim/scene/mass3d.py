"""Mass properties of 3D shapes and compound bodies (density per volume, kg/m³).

Each shape kind has one function returning (volume m³, centroid m (body frame),
inertia tensor per unit density m⁵ about the centroid, body axes). Multiplying by the
density gives mass (kg) and inertia (kg·m²). A compound body sums its shapes about the
common centre of mass with the parallel-axis theorem, I += m (|d|² E − d dᵀ).

The shapes come resolved (rbsim.scene.resolve.Shape): their vertices are in the body
frame with the shape's offset and orientation applied, so a box rotates its diagonal
tensor by its orientation (I = R I₀ Rᵀ) and the other kinds take their geometry from
the vertices.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .geometry3d import Quat, Vec3, matrix_quat, quat_matrix

if TYPE_CHECKING:  # resolve uses this module to check forces against masses
    from .resolve import Body, Shape

# (volume m³, centroid (3,) m, inertia per unit density (3, 3) m⁵ about the centroid)
Part = tuple[float, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class MassProperties3D:
    """mass (kg), center (body frame, m), inertia (3, 3) kg·m² about the centre of mass
    in body axes (full symmetric tensor)."""

    mass: float
    center: Vec3
    inertia: np.ndarray


def sphere_volume_inertia(radius: float, center: Vec3) -> Part:
    """Ball of ``radius`` (m) at ``center``: volume 4/3 π r³, inertia 2/5 V r² E."""
    volume = 4.0 / 3.0 * math.pi * radius**3
    return volume, np.asarray(center, dtype=np.float64), 0.4 * volume * radius**2 * np.eye(3)


def box_volume_inertia(size: Vec3, center: Vec3, orientation: Quat) -> Part:
    """Box of full extents ``size`` (m) at ``center``, rotated by ``orientation``:
    volume abc, inertia V/12 diag(b² + c², a² + c², a² + b²) in its own axes, turned
    into the body's by R I Rᵀ."""
    a, b, c = size
    volume = a * b * c
    own = volume / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    r = quat_matrix(orientation)
    return volume, np.asarray(center, dtype=np.float64), r @ own @ r.T


def capsule_volume_inertia(a: Vec3, b: Vec3, radius: float) -> Part:
    """The segment a-b swept by ``radius`` (m): a cylinder of length L = |b − a| and two
    hemispherical caps.

    About the centre, along the axis u: the cylinder's V_c r²/2 and each cap's
    2/5 V_h r². Across it: the cylinder's V_c (3r² + L²)/12, and each cap's own
    83/320 V_h r² about its centroid (which sits 3r/8 beyond its end) moved out to
    L/2 + 3r/8 from the centre. The tensor is I⊥ E + (I∥ − I⊥) u uᵀ.
    """
    pa, pb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    axis = pb - pa
    length = float(np.linalg.norm(axis))
    u = axis / length
    r2 = radius * radius
    v_cyl = math.pi * r2 * length
    v_cap = 2.0 / 3.0 * math.pi * radius**3  # each of the two
    along = 0.5 * v_cyl * r2 + 2.0 * 0.4 * v_cap * r2
    reach = 0.5 * length + 3.0 / 8.0 * radius
    across = v_cyl * (3.0 * r2 + length * length) / 12.0
    across += 2.0 * v_cap * (83.0 / 320.0 * r2 + reach * reach)
    inertia = across * np.eye(3) + (along - across) * np.outer(u, u)
    return v_cyl + 2.0 * v_cap, 0.5 * (pa + pb), inertia


def convex_volume_inertia(
    vertices: tuple[Vec3, ...], faces: tuple[tuple[int, int, int], ...]
) -> Part:
    """A closed convex hull given by its triangles (counter-clockwise seen from outside).

    Sums the tetrahedra (p, a, b, c) from an interior point p (the vertex mean) to each
    triangle: signed volume V = (a' · (b' × c'))/6 with a' = a − p, centroid
    p + (a' + b' + c')/4, and covariance ∫ r rᵀ dV = V/20 (a'a'ᵀ + b'b'ᵀ + c'c'ᵀ + s sᵀ)
    with s = a' + b' + c'. About the centroid d: C − V d dᵀ; then I = tr(C) E − C.
    """
    pts = np.asarray(vertices, dtype=np.float64)
    p = pts.mean(axis=0)
    rel = pts - p
    tri = np.asarray(faces, dtype=np.int64)
    a, b, c = rel[tri[:, 0]], rel[tri[:, 1]], rel[tri[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    s = a + b + c
    volume = float(vol.sum())
    first = (vol[:, None] * s).sum(axis=0) / 4.0
    outer = (
        np.einsum("i,ij,ik->jk", vol, a, a)
        + np.einsum("i,ij,ik->jk", vol, b, b)
        + np.einsum("i,ij,ik->jk", vol, c, c)
        + np.einsum("i,ij,ik->jk", vol, s, s)
    ) / 20.0
    if not volume > 0.0:
        return 0.0, p, np.zeros((3, 3))
    d = first / volume
    cov = outer - volume * np.outer(d, d)
    inertia = np.trace(cov) * np.eye(3) - cov
    return volume, p + d, 0.5 * (inertia + inertia.T)


def shape_volume_inertia(shape: Shape) -> Part:
    """Dispatch on the 3D shape kind: (volume m³, centroid m, inertia per unit density
    m⁵ about the centroid, body axes). A plane (static bodies only) has none."""
    kind = shape.kind
    if kind == "sphere":
        return sphere_volume_inertia(shape.radius, shape.vertices[0])
    if kind == "box":
        return box_volume_inertia(shape.size, shape.offset, shape.orientation)
    if kind == "capsule":
        return capsule_volume_inertia(shape.vertices[0], shape.vertices[1], shape.radius)
    if kind == "convex":
        return convex_volume_inertia(shape.vertices, shape.faces)
    if kind == "plane":
        return 0.0, np.asarray(shape.vertices[0], dtype=np.float64), np.zeros((3, 3))
    raise ValueError(f"not a 3D shape kind: {kind!r}")


def combine_3d(parts: list[Part]) -> MassProperties3D:
    """Sum (mass kg, centre m, inertia kg·m² about its own centre) parts about their
    common centre of mass (the parallel-axis theorem, I += m (|d|² E − d dᵀ))."""
    mass = sum(p[0] for p in parts)
    if not mass > 0.0:
        return MassProperties3D(0.0, (0.0, 0.0, 0.0), np.zeros((3, 3)))
    center = sum(m * c for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, i in parts:
        d = c - center
        inertia += i + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    inertia = 0.5 * (inertia + inertia.T)
    return MassProperties3D(mass, tuple(float(x) for x in center), inertia)  # type: ignore[arg-type]


def body_mass_properties_3d(body: Body) -> MassProperties3D:
    """Mass (kg), centre of mass (body frame, m) and inertia tensor (kg·m², body axes,
    about the COM) of a 3D body. Each shape contributes density × (volume, inertia);
    `body.mass`, when given, scales mass and tensor together (every shape's density
    alike)."""
    parts = []
    for shape in body.shapes:
        volume, center, inertia = shape_volume_inertia(shape)
        rho = shape.material.density
        parts.append((rho * volume, center, rho * inertia))
    props = combine_3d(parts)
    if body.mass is None or not props.mass > 0.0:
        return props
    scale = body.mass / props.mass
    return MassProperties3D(body.mass, props.center, props.inertia * scale)


def principal_axes(inertia: np.ndarray) -> tuple[Quat, tuple[float, float, float]]:
    """The principal axes of a symmetric tensor: (P as a unit quaternion (w, x, y, z),
    moments kg·m² ascending) with inertia = P diag(moments) Pᵀ, P's columns the axes
    (numpy.linalg.eigh), each axis's largest component made positive and the third
    turned so that the axes are right-handed (a rotation)."""
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    for k in range(3):
        column = axes[:, k]
        if column[int(np.argmax(np.abs(column)))] < 0.0:
            axes[:, k] = -column
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    m0, m1, m2 = (float(m) for m in moments)
    return matrix_quat(axes), (m0, m1, m2)
