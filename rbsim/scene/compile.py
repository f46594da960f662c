"""Scene -> Model (static struct-of-arrays) + State (what changes every step).

Both are NamedTuples of flat numpy arrays: the engine (rbsim.core) takes them whole.
Body state is kept at the centre of mass: `body_x` is the COM position, `body_q` the
unit complex rotation (cos θ, sin θ), `body_v` the COM velocity, `body_w` the angular
velocity. Shape geometry is stored in the body frame relative to the centre of mass,
so a shape's world vertex is body_x + R(q) · vertex_local.

A 3D scene (world.dimension: 3) gives the same two types with 3D shapes: body_q a unit
quaternion (w, x, y, z), body_w and body_l (angular momentum about the COM) world-frame
3-vectors, body_inertia the full body-frame tensor (N, 3, 3), and its principal axes
(body_axes, body_moments) for the splitting rotation update.

A static or kinematic body has zero inverse mass and inertia, so the solver treats
every body alike (no branch on the body type inside the contact loops).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from . import types as T
from .geometry3d import IDENTITY, quat_matrix
from .mass import MassProperties, body_mass_properties
from .mass3d import body_mass_properties_3d, principal_axes
from .resolve import Body, Scene


class ModelError(ValueError):
    """A scene that validates but cannot be simulated (for example a massless body)."""


# a Model without triangles (2D, or 3D arrays built by hand): shared, read-only
_NO_FACES = np.zeros((0, 3), np.int32)
_NO_FACES.flags.writeable = False
_NO_INDEX = np.zeros(0, np.int32)
_NO_INDEX.flags.writeable = False


class Model(NamedTuple):
    """Static data. N bodies, S shapes, V shape vertices.

    body_type (N,) int8: types.BODY_*; body_mass (N,) kg (inf if not dynamic);
    body_inertia (N,) kg·m²; body_inv_mass (N,) 1/kg; body_inv_inertia (N,) 1/(kg·m²);
    body_com (N,2) m, centre of mass in the body frame (relative to the origin);
    body_force (N,2) N, world frame; body_force_arm (N,2) m, body frame, from the COM;
    body_torque (N,) N·m; shape_body (S,) int32; shape_kind (S,) int32;
    shape_radius (S,) m; shape_vstart, shape_vcount (S,) int32 into vertex_local;
    shape_friction, shape_restitution (S,); vertex_local (V,2) m, body frame about
    the COM; normal_local (V,2) outward edge normals (polygons, segments);
    gravity (2,) m/s²; linear_damping, angular_damping 1/s; has_forces: any body
    carries a constant force or torque; has_shapes: the contact pipeline is needed
    (two bodies have shapes and one of them is dynamic; a lone ball pays nothing for it);
    body_axes (N,4) rows (1, 0, 0, 0) and body_moments (N,3) zeros (used in 3D only).

    In 3D: body_inertia (N,3,3) kg·m², the full symmetric tensor in body axes about the
    COM (diag(inf) if not dynamic), body_inv_inertia (N,3,3) (0 if not dynamic);
    body_com, body_force, body_force_arm, body_torque (N,3) (torque world frame);
    body_axes (N,4) the unit quaternion (w, x, y, z) of P, the principal axes in the
    body frame (I = P diag(body_moments) Pᵀ, right-handed), body_moments (N,3) kg·m²
    ascending (inf if not dynamic); shape_kind codes types.SHAPE_SPHERE..SHAPE_PLANE;
    vertex_local (V,3) m, body frame about the COM (sphere: centre; capsule: a, b; box:
    8 corners; convex: hull points; plane: one point); normal_local (V,3) a plane's
    unit normal on its vertex row, zeros elsewhere; gravity (3,); has_shapes as in 2D
    (the 3D step takes contacts once its solver does); face_local (F,3) int32 the box
    and convex shapes' triangles (the resolved Shape.faces, indices local to the shape's
    vertex rows, counter-clockwise seen from outside), shape_fstart, shape_fcount (S,)
    int32 each shape's rows of them (0 rows for the other kinds). In 2D the three are
    empty.
    """

    body_type: np.ndarray
    body_mass: np.ndarray
    body_inertia: np.ndarray
    body_inv_mass: np.ndarray
    body_inv_inertia: np.ndarray
    body_com: np.ndarray
    body_force: np.ndarray
    body_force_arm: np.ndarray
    body_torque: np.ndarray
    shape_body: np.ndarray
    shape_kind: np.ndarray
    shape_radius: np.ndarray
    shape_vstart: np.ndarray
    shape_vcount: np.ndarray
    shape_friction: np.ndarray
    shape_restitution: np.ndarray
    vertex_local: np.ndarray
    normal_local: np.ndarray
    gravity: np.ndarray
    linear_damping: float
    angular_damping: float
    has_forces: bool
    has_shapes: bool
    body_axes: np.ndarray
    body_moments: np.ndarray
    face_local: np.ndarray = _NO_FACES
    shape_fstart: np.ndarray = _NO_INDEX
    shape_fcount: np.ndarray = _NO_INDEX


_NONE = np.zeros(0)
_NONE.flags.writeable = False  # shared by every 2D State: nobody may write into it


class State(NamedTuple):
    """Per-step state: body_x (N,2) m (COM), body_q (N,2) (cos θ, sin θ), body_angle (N,)
    rad (accumulated, unwrapped), body_v (N,2) m/s (COM), body_w (N,) rad/s; body_l (0,)
    (empty: the angular momentum is a 3D state).

    In 3D: body_x (N,3), body_q (N,4) unit quaternion (w, x, y, z), body_angle (0,),
    body_v (N,3), body_w (N,3) rad/s world frame, body_l (N,3) kg·m²/s world-frame
    angular momentum about the COM (L = R I_b Rᵀ ω; 0 if not dynamic)."""

    body_x: np.ndarray
    body_q: np.ndarray
    body_angle: np.ndarray
    body_v: np.ndarray
    body_w: np.ndarray
    body_l: np.ndarray = _NONE


def _rotate(c: float, s: float, p: tuple[float, float]) -> tuple[float, float]:
    return (c * p[0] - s * p[1], s * p[0] + c * p[1])


def check_masses(scene: Scene) -> None:
    """Raise ModelError, as build would, if a dynamic body of the resolved scene has no
    mass (a batch's check of its runs: the mass properties of its dynamic bodies only,
    without the arrays; shapes shared by generated bodies are worked out once)."""
    known: set[tuple] = set()
    for body in scene.bodies:
        key = (body.shapes, body.mass)
        if body.type != "dynamic" or key in known:
            continue
        if scene.world.dimension == 3:
            _require_mass_3d(body, body_mass_properties_3d(body))
        else:
            _require_mass_2d(body, body_mass_properties(body))
        known.add(key)


def _require_mass_2d(body: Body, props: MassProperties) -> None:
    """Raise ModelError unless the dynamic 2D ``body`` (of mass properties ``props``)
    has a positive mass and moment of inertia."""
    if props.mass > 0.0 and props.inertia > 0.0:
        return
    if all(sh.kind == "segment" and sh.radius == 0 for sh in body.shapes):
        why = "its shapes have no area (thin segments): give it `mass:` or a radius"
    else:
        why = f"its mass {props.mass:g} kg and inertia {props.inertia:g} kg·m² "
        why += "are not both positive"
    raise ModelError(f"body {body.name!r}: a dynamic body needs a mass; {why}")


def _require_mass_3d(body: Body, props: Any) -> tuple[np.ndarray, np.ndarray]:
    """The principal axes and moments (kg·m²) of the dynamic 3D ``body`` (of mass
    properties ``props``); raises ModelError unless its mass and least moment are
    positive."""
    axes_q, principal = principal_axes(props.inertia)
    if not (props.mass > 0.0 and principal[0] > 0.0):
        why = f"its mass {props.mass:g} kg and least principal moment "
        why += f"{principal[0]:g} kg·m² are not both positive"
        raise ModelError(f"body {body.name!r}: a dynamic body needs a mass; {why}")
    return axes_q, principal


def build(scene: Scene) -> tuple[Model, State]:
    """Turn a resolved scene into a Model and its initial State (SI units), in the
    scene's dimension (world.dimension)."""
    if scene.world.dimension == 3:
        return build_3d(scene)
    bodies = scene.bodies
    n = len(bodies)
    body_type = np.zeros(n, np.int8)
    mass = np.zeros(n)
    inertia = np.zeros(n)
    com = np.zeros((n, 2))
    force = np.zeros((n, 2))
    force_arm = np.zeros((n, 2))
    torque = np.zeros(n)
    x = np.zeros((n, 2))
    q = np.zeros((n, 2))
    angle = np.zeros(n)
    v = np.zeros((n, 2))
    w = np.zeros(n)

    shape_body, shape_kind, shape_radius, shape_vcount = [], [], [], []
    shape_friction, shape_restitution = [], []
    vertices: list[tuple[float, float]] = []
    normals: list[tuple[float, float]] = []

    for i, body in enumerate(bodies):
        kind = T.BODY_TYPE_CODE[body.type]
        body_type[i] = kind
        props = body_mass_properties(body)
        com[i] = props.center
        if kind == T.BODY_DYNAMIC:
            _require_mass_2d(body, props)
            mass[i], inertia[i] = props.mass, props.inertia
        else:
            mass[i], inertia[i] = math.inf, math.inf
        c, s = math.cos(body.angle), math.sin(body.angle)
        rc = _rotate(c, s, props.center)
        x[i] = (body.position[0] + rc[0], body.position[1] + rc[1])
        q[i] = (c, s)
        angle[i] = body.angle
        if kind != T.BODY_STATIC:
            v[i] = body.velocity
            w[i] = body.angular_velocity
        force[i] = body.force
        fp = body.force_point if body.force_point is not None else props.center
        force_arm[i] = (fp[0] - props.center[0], fp[1] - props.center[1])
        torque[i] = body.torque

        for shape in body.shapes:
            shape_body.append(i)
            shape_radius.append(shape.radius)
            shape_friction.append(shape.material.friction)
            shape_restitution.append(shape.material.restitution)
            local = [(p[0] - props.center[0], p[1] - props.center[1]) for p in shape.vertices]
            if shape.kind == "segment":
                shape_kind.append(T.SHAPE_SEGMENT)
                (ax, ay), (bx, by) = local
                length = math.hypot(bx - ax, by - ay)
                nx, ny = (by - ay) / length, -(bx - ax) / length
                vertices.extend(local)
                normals.extend([(nx, ny), (-nx, -ny)])
            else:
                shape_kind.append(T.SHAPE_KIND_CODE[shape.kind])
                vertices.extend(local)
                m = len(local)
                for k in range(m):
                    (ax, ay), (bx, by) = local[k], local[(k + 1) % m]
                    length = math.hypot(bx - ax, by - ay)
                    normals.append(((by - ay) / length, -(bx - ax) / length) if m > 1 else (0, 0))
            shape_vcount.append(len(local))

    dynamic = body_type == T.BODY_DYNAMIC
    inv_inertia = np.where(dynamic, 1.0 / np.where(dynamic, inertia, 1.0), 0.0)
    rows = zip(
        shape_kind, shape_radius, shape_friction, shape_restitution, shape_vcount, strict=True
    )
    model = _model(
        scene,
        (body_type, mass, inertia, inv_inertia, com, force, force_arm, torque),
        (shape_body, list(rows)),
        np.asarray(vertices, np.float64).reshape(-1, 2),
        np.asarray(normals, np.float64).reshape(-1, 2),
        has_shapes=_contacts_possible(shape_body, body_type),
        axes=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        moments=np.zeros((n, 3)),
    )
    return model, State(x, q, angle, v, w)


def build_3d(scene: Scene) -> tuple[Model, State]:
    """build() for a 3D scene: the arrays of Model and State in their 3D shapes."""
    bodies = scene.bodies
    n = len(bodies)
    body_type = np.array([T.BODY_TYPE_CODE[b.type] for b in bodies], np.int8).reshape(n)
    mass = np.full(n, math.inf)
    inertia = np.tile(np.diag([math.inf] * 3), (n, 1, 1))
    inv_inertia = np.zeros((n, 3, 3))
    axes = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    moments = np.full((n, 3), math.inf)
    com, force_arm, ang = (np.zeros((n, 3)) for _ in range(3))

    def column(values: list, width: int) -> np.ndarray:
        return np.array(values, np.float64).reshape(n, width)

    origin = column([b.position for b in bodies], 3)
    q = column([b.orientation for b in bodies], 4)
    moving = (body_type != T.BODY_STATIC)[:, None]
    v = np.where(moving, column([b.velocity for b in bodies], 3), 0.0)
    w = np.where(moving, column([b.angular_velocity for b in bodies], 3), 0.0)
    force = column([b.force for b in bodies], 3)
    torque = column([b.torque for b in bodies], 3)

    shape_body: list[int] = []
    parts: list[list] = []  # per body: its shapes' (kind, radius, friction, restitution, count)
    vertices: list[np.ndarray] = []
    normals: list[np.ndarray] = []
    faces: list[np.ndarray] = []  # per body: its shapes' triangles (F, 3)
    face_counts: list[list[int]] = []  # per body: each shape's triangle count
    # generated bodies share one shape tuple: their mass properties and vertex rows are
    # worked out once
    known: dict[tuple, tuple] = {}

    for i, body in enumerate(bodies):
        kind = int(body_type[i])
        key = (body.shapes, body.mass, kind)
        if key not in known:
            known[key] = _body_3d(body, kind)
        props, center, inverse, axes_q, principal, shapes, local, rows, tris, counts = known[key]
        com[i] = center
        if kind == T.BODY_DYNAMIC:
            mass[i], inertia[i], inv_inertia[i] = props.mass, props.inertia, inverse
            axes[i], moments[i] = axes_q, principal
        turned = body.orientation != IDENTITY
        r = quat_matrix(body.orientation) if turned else None
        if props.center != (0.0, 0.0, 0.0):
            origin[i] += r @ center if turned else center
        if kind == T.BODY_DYNAMIC and any(body.angular_velocity):
            i_world = r @ props.inertia @ r.T if turned else props.inertia
            ang[i] = i_world @ w[i]
        if body.force_point is not None:
            force_arm[i] = np.asarray(body.force_point) - center
        shape_body.extend([i] * len(body.shapes))
        parts.append(shapes)
        vertices.append(local)
        normals.append(rows)
        faces.append(tris)
        face_counts.append(counts)

    fcount = np.array([c for counts in face_counts for c in counts], np.int32)
    model = _model(
        scene,
        (body_type, mass, inertia, inv_inertia, com, force, force_arm, torque),
        (shape_body, [row for rows in parts for row in rows]),
        np.concatenate(vertices) if vertices else np.zeros((0, 3)),
        np.concatenate(normals) if normals else np.zeros((0, 3)),
        has_shapes=_contacts_possible(shape_body, body_type),
        axes=axes,
        moments=moments,
    )
    model = model._replace(
        face_local=np.concatenate(faces).astype(np.int32) if faces else _NO_FACES,
        shape_fstart=(np.cumsum(fcount, dtype=np.int64) - fcount).astype(np.int32),
        shape_fcount=fcount,
    )
    return model, State(origin, q, np.zeros(0), v, w, ang)


def _model(
    scene: Scene,
    bodies: tuple,
    shapes: tuple,
    vertex_local: np.ndarray,
    normal_local: np.ndarray,
    has_shapes: bool,
    axes: np.ndarray,
    moments: np.ndarray,
) -> Model:
    """The Model of either dimension from its columns: ``bodies`` = (type, mass,
    inertia, inverse inertia, com, force, force arm, torque), ``shapes`` = (each
    shape's body, each shape's (kind code, radius, friction, restitution, vertex
    count)); a shape's vertices follow the previous shape's."""
    body_type, mass, inertia, inv_inertia, com, force, force_arm, torque = bodies
    dynamic = body_type == T.BODY_DYNAMIC
    world = scene.world
    body, rows = shapes
    columns = [list(c) for c in zip(*rows, strict=True)] if rows else [[] for _ in range(5)]
    kind, radius, friction, restitution, vcount = columns
    vstart = np.cumsum(vcount, dtype=np.int64) - np.asarray(vcount, np.int64)
    return Model(
        body_type=body_type,
        body_mass=mass,
        body_inertia=inertia,
        body_inv_mass=np.where(dynamic, 1.0 / np.where(dynamic, mass, 1.0), 0.0),
        body_inv_inertia=inv_inertia,
        body_com=com,
        body_force=force,
        body_force_arm=force_arm,
        body_torque=torque,
        shape_body=np.asarray(body, np.int32),
        shape_kind=np.asarray(kind, np.int32),
        shape_radius=np.asarray(radius, np.float64),
        shape_vstart=np.asarray(vstart, np.int32),
        shape_vcount=np.asarray(vcount, np.int32),
        shape_friction=np.asarray(friction, np.float64),
        shape_restitution=np.asarray(restitution, np.float64),
        vertex_local=vertex_local,
        normal_local=normal_local,
        gravity=np.asarray(world.gravity, np.float64),
        linear_damping=float(world.linear_damping),
        angular_damping=float(world.angular_damping),
        has_forces=bool(np.any(force != 0.0) or np.any(torque != 0.0)),
        has_shapes=has_shapes,
        body_axes=axes,
        body_moments=moments,
    )


def _body_3d(body: Body, kind: int) -> tuple:
    """What build_3d needs of a body's shapes: (mass properties, COM (3,), inverse
    tensor, principal axes, moments, each shape's (kind code, radius, friction,
    restitution, vertex count), vertex rows about the COM (V, 3), normal rows (V, 3),
    triangles (F, 3) int32 local to each shape's rows, each shape's triangle count).
    Raises ModelError for a dynamic body without mass."""
    props = body_mass_properties_3d(body)
    center = np.asarray(props.center)
    inverse = axes_q = principal = None
    if kind == T.BODY_DYNAMIC:
        axes_q, principal = _require_mass_3d(body, props)
        inverse = np.linalg.inv(props.inertia)
        inverse = 0.5 * (inverse + inverse.T)
    shapes, local, rows, tris, tri_counts = [], [], [], [], []
    for shape in body.shapes:
        m = shape.material
        points = np.asarray(shape.vertices, np.float64).reshape(-1, 3) - center
        normal = np.zeros_like(points)
        if shape.kind == "plane":
            normal[0] = shape.normal
        code = T.SHAPE_KIND_CODE_3D[shape.kind]
        shapes.append((code, shape.radius, m.friction, m.restitution, len(points)))
        local.append(points)
        rows.append(normal)
        tris.append(np.asarray(shape.faces, np.int32).reshape(-1, 3))
        tri_counts.append(len(shape.faces))
    return (
        props,
        center,
        inverse,
        axes_q,
        principal,
        shapes,
        np.concatenate(local),
        np.concatenate(rows),
        np.concatenate(tris),
        tri_counts,
    )


def _contacts_possible(shape_body: list[int], body_type: np.ndarray) -> bool:
    """True when two bodies with shapes can touch and one of them can respond."""
    shaped = np.unique(np.asarray(shape_body, np.int64))
    return len(shaped) >= 2 and bool(np.any(body_type[shaped] == T.BODY_DYNAMIC))


def body_origin(model: Model, state: State) -> np.ndarray:
    """World position (N,2) or (N,3) m of each body origin as placed in the scene
    (origin = x − R(q) com)."""
    if state.body_q.shape[1] == 4:
        w, u = state.body_q[:, :1], state.body_q[:, 1:]
        c = model.body_com
        t = 2.0 * np.cross(u, c)  # R c = c + w t + u × t for a unit quaternion (w, u)
        return state.body_x - (c + w * t + np.cross(u, t))
    c, s = state.body_q[:, 0], state.body_q[:, 1]
    rx = c * model.body_com[:, 0] - s * model.body_com[:, 1]
    ry = s * model.body_com[:, 0] + c * model.body_com[:, 1]
    return np.stack([state.body_x[:, 0] - rx, state.body_x[:, 1] - ry], axis=1)
