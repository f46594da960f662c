"""Mass properties of shapes and compound bodies.

Each shape kind has one function returning (area m², centroid m (body frame), polar
second moment of area about its centroid m⁴). Multiplying by the density (kg/m²)
gives mass (kg) and moment of inertia (kg·m²). A compound body sums its shapes with
the parallel-axis theorem about the common centre of mass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # resolve uses this module to check forces against masses
    from .resolve import Body, Shape

Vec2 = tuple[float, float]


@dataclass(frozen=True)
class MassProperties:
    """mass (kg), center (body frame, m), inertia about the centre of mass (kg·m²)."""

    mass: float
    center: Vec2
    inertia: float


def circle_area_moment(radius: float, center: Vec2) -> tuple[float, Vec2, float]:
    """Disc of `radius` (m) at `center`: area π r², polar moment π r⁴ / 2 about its centre."""
    area = math.pi * radius * radius
    return area, (float(center[0]), float(center[1])), 0.5 * area * radius * radius


def polygon_area_moment(vertices: tuple[Vec2, ...]) -> tuple[float, Vec2, float]:
    """Convex CCW polygon: area, centroid and polar moment about the centroid.

    Sums the triangles (c, v_i, v_i+1) fanned from a reference point c inside the
    polygon (the vertex average, for round-off), each with polar moment
    A/6 (|e1|² + e1·e2 + |e2|²) about c.
    """
    n = len(vertices)
    cx = sum(v[0] for v in vertices) / n
    cy = sum(v[1] for v in vertices) / n
    area = 0.0
    sx = sy = 0.0
    moment_c = 0.0
    for i in range(n):
        e1x, e1y = vertices[i][0] - cx, vertices[i][1] - cy
        e2x, e2y = vertices[(i + 1) % n][0] - cx, vertices[(i + 1) % n][1] - cy
        a = 0.5 * (e1x * e2y - e1y * e2x)
        area += a
        sx += a * (e1x + e2x) / 3.0
        sy += a * (e1y + e2y) / 3.0
        dots = e1x * e1x + e1y * e1y + e1x * e2x + e1y * e2y + e2x * e2x + e2y * e2y
        moment_c += a / 6.0 * dots
    if not area > 0.0:  # no area left to the rounding: the caller rejects a zero mass
        return 0.0, (cx, cy), 0.0
    dx, dy = sx / area, sy / area
    # moment about the centroid: shift from c by the parallel-axis theorem
    moment = moment_c - area * (dx * dx + dy * dy)
    return area, (cx + dx, cy + dy), moment


def capsule_area_moment(a: Vec2, b: Vec2, radius: float) -> tuple[float, Vec2, float]:
    """Segment a-b swept by `radius` (a capsule): a 2r × L rectangle and two half discs.

    Polar moment about the centre: rectangle A_r (L² + 4r²)/12, plus the half discs
    A_c (r²/2 + L²/4 + 4 L r / (3π)) (each half disc's centroid sits 4r/(3π) beyond
    its end). A radius-0 segment has zero area; see `body_mass_properties`.
    """
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    center = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]))
    area_rect = 2.0 * radius * length
    area_caps = math.pi * radius * radius
    moment = area_rect * (length * length + 4.0 * radius * radius) / 12.0
    moment += area_caps * (
        0.5 * radius * radius + 0.25 * length * length + 4.0 * length * radius / (3.0 * math.pi)
    )
    return area_rect + area_caps, center, moment


def shape_area_moment(shape: Shape) -> tuple[float, Vec2, float]:
    """Dispatch on the shape kind: (area m², centroid m, polar moment m⁴ about centroid)."""
    if shape.kind == "circle":
        return circle_area_moment(shape.radius, shape.vertices[0])
    if shape.kind == "segment":
        return capsule_area_moment(shape.vertices[0], shape.vertices[1], shape.radius)
    return polygon_area_moment(shape.vertices)


def _rod(shape: Shape) -> tuple[float, Vec2, float]:
    """A thin segment as a uniform rod: (length m, centre m, length·L²/12 m³)."""
    a, b = shape.vertices
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    center = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]))
    return length, center, length * length * length / 12.0


def combine(parts: list[tuple[float, Vec2, float]]) -> MassProperties:
    """Sum (mass, centre, inertia about own centre) parts about their common centre."""
    mass = sum(p[0] for p in parts)
    if mass <= 0.0:
        return MassProperties(0.0, (0.0, 0.0), 0.0)
    cx = sum(p[0] * p[1][0] for p in parts) / mass
    cy = sum(p[0] * p[1][1] for p in parts) / mass
    inertia = 0.0
    for m, (px, py), i in parts:
        inertia += i + m * ((px - cx) ** 2 + (py - cy) ** 2)
    return MassProperties(mass, (cx, cy), inertia)


def body_mass_properties(body: Body) -> MassProperties:
    """Mass (kg), centre of mass (body frame, m) and inertia (kg·m²) of a body.

    Each shape contributes density × (area, moment). `body.mass`, when given, scales
    mass and inertia together (the density distribution is kept). A body made only of
    thin segments has no area: with `mass` given it is treated as uniform rods;
    without it the mass is zero (the caller rejects a zero-mass dynamic body).
    """
    parts = []
    for shape in body.shapes:
        area, center, moment = shape_area_moment(shape)
        rho = shape.material.density
        parts.append((rho * area, center, rho * moment))
    props = combine(parts)
    if body.mass is None:
        return props
    if props.mass <= 0.0:
        rods = [_rod(s) for s in body.shapes if s.kind == "segment"]
        props = combine(rods)
        if props.mass <= 0.0:
            return MassProperties(0.0, (0.0, 0.0), 0.0)
    scale = body.mass / props.mass
    return MassProperties(body.mass, props.center, props.inertia * scale)
