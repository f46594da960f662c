"""Scene -> Model (static struct-of-arrays) + State (what changes every step).

Both are NamedTuples of flat numpy arrays: the engine (rbsim.core) takes them whole.
Body state is kept at the centre of mass: `body_x` is the COM position, `body_q` the
unit complex rotation (cos θ, sin θ), `body_v` the COM velocity, `body_w` the angular
velocity. Shape geometry is stored in the body frame relative to the centre of mass,
so a shape's world vertex is body_x + R(q) · vertex_local.

A static or kinematic body has zero inverse mass and inertia, so the solver treats
every body alike (no branch on the body type inside the contact loops).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from . import types as T
from .mass import body_mass_properties
from .resolve import Scene


class ModelError(ValueError):
    """A scene that validates but cannot be simulated (for example a massless body)."""


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
    (two bodies have shapes and one of them is dynamic; a lone ball pays nothing for it).
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


class State(NamedTuple):
    """Per-step state: body_x (N,2) m (COM), body_q (N,2) (cos θ, sin θ), body_angle (N,)
    rad (accumulated, unwrapped), body_v (N,2) m/s (COM), body_w (N,) rad/s."""

    body_x: np.ndarray
    body_q: np.ndarray
    body_angle: np.ndarray
    body_v: np.ndarray
    body_w: np.ndarray


def _rotate(c: float, s: float, p: tuple[float, float]) -> tuple[float, float]:
    return (c * p[0] - s * p[1], s * p[0] + c * p[1])


def build(scene: Scene) -> tuple[Model, State]:
    """Turn a resolved scene into a Model and its initial State (SI units)."""
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

    shape_body, shape_kind, shape_radius, shape_vstart, shape_vcount = [], [], [], [], []
    shape_friction, shape_restitution = [], []
    vertices: list[tuple[float, float]] = []
    normals: list[tuple[float, float]] = []

    for i, body in enumerate(bodies):
        kind = T.BODY_TYPE_CODE[body.type]
        body_type[i] = kind
        props = body_mass_properties(body)
        com[i] = props.center
        if kind == T.BODY_DYNAMIC:
            if not (props.mass > 0.0 and props.inertia > 0.0):
                if all(sh.kind == "segment" and sh.radius == 0 for sh in body.shapes):
                    why = "its shapes have no area (thin segments): give it `mass:` or a radius"
                else:
                    why = f"its mass {props.mass:g} kg and inertia {props.inertia:g} kg·m² "
                    why += "are not both positive"
                raise ModelError(f"body {body.name!r}: a dynamic body needs a mass; {why}")
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
            shape_vstart.append(len(vertices))
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
    inv_mass = np.where(dynamic, 1.0 / np.where(dynamic, mass, 1.0), 0.0)
    inv_inertia = np.where(dynamic, 1.0 / np.where(dynamic, inertia, 1.0), 0.0)
    world = scene.world
    model = Model(
        body_type=body_type,
        body_mass=mass,
        body_inertia=inertia,
        body_inv_mass=inv_mass,
        body_inv_inertia=inv_inertia,
        body_com=com,
        body_force=force,
        body_force_arm=force_arm,
        body_torque=torque,
        shape_body=np.asarray(shape_body, np.int32),
        shape_kind=np.asarray(shape_kind, np.int32),
        shape_radius=np.asarray(shape_radius, np.float64),
        shape_vstart=np.asarray(shape_vstart, np.int32),
        shape_vcount=np.asarray(shape_vcount, np.int32),
        shape_friction=np.asarray(shape_friction, np.float64),
        shape_restitution=np.asarray(shape_restitution, np.float64),
        vertex_local=np.asarray(vertices, np.float64).reshape(-1, 2),
        normal_local=np.asarray(normals, np.float64).reshape(-1, 2),
        gravity=np.asarray(world.gravity, np.float64),
        linear_damping=float(world.linear_damping),
        angular_damping=float(world.angular_damping),
        has_forces=bool(np.any(force != 0.0) or np.any(torque != 0.0)),
        has_shapes=_contacts_possible(shape_body, body_type),
    )
    return model, State(x, q, angle, v, w)


def _contacts_possible(shape_body: list[int], body_type: np.ndarray) -> bool:
    """True when two bodies with shapes can touch and one of them can respond."""
    shaped = np.unique(np.asarray(shape_body, np.int64))
    return len(shaped) >= 2 and bool(np.any(body_type[shaped] == T.BODY_DYNAMIC))


def body_origin(model: Model, state: State) -> np.ndarray:
    """World position (N,2) m of each body origin as placed in the scene."""
    c, s = state.body_q[:, 0], state.body_q[:, 1]
    rx = c * model.body_com[:, 0] - s * model.body_com[:, 1]
    ry = s * model.body_com[:, 0] + c * model.body_com[:, 1]
    return np.stack([state.body_x[:, 0] - rx, state.body_x[:, 1] - ry], axis=1)
