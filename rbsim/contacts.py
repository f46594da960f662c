"""Contact manifolds: storage, creation from the narrowphase, and warm-start matching.

A manifold joins shape a to shape b (a < b) with one normal, pointing from b towards
a, and one or two points. Each point keeps its anchors relative to the two centres
of mass at the start of the step, its separation, its feature id and the impulses
the solver accumulates. Manifolds are kept sorted by (a, b), so this step's
manifolds are matched to last step's in one merge pass, and a point whose feature id
matches takes over last step's impulses (warm starting).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import constants as C
from .narrowphase import collide

MIX_SQRT, MIX_MULTIPLY, MIX_MIN, MIX_MAX = 0, 1, 2, 3
MIXING = {"sqrt": MIX_SQRT, "multiply": MIX_MULTIPLY, "min": MIX_MIN, "max": MIX_MAX}


class Contacts(NamedTuple):
    """Preallocated contact storage with capacity M manifolds (2 points each).

    count (4,) int64: [manifolds now, manifolds last step, pairs found, points touching].
    pairs (M,2) int32: broadphase output. shape_a, shape_b, body_a, body_b (M,) int32;
    key (M,) int64 = shape_a · S + shape_b; normal (M,2); points (M,) int32;
    friction, restitution (M,) mixed coefficients; softness (M,3) mass scale, impulse
    scale, bias rate (1/s) for this manifold's soft constraint;
    anchor_a, anchor_b (M,2,2) m, from each COM at the start of the step;
    base_separation (M,2) m, the separation minus the anchors' contribution;
    feature (M,2) int64; normal_impulse, tangent_impulse (M,2) N·s (per substep);
    normal_mass, tangent_mass (M,2) kg; approach_velocity (M,2) m/s and
    approach_separation (M,2) m where the point engaged (for restitution);
    max_normal_impulse (M,2) N·s; prev_* the same from last step for matching.
    scratch_*: one narrowphase result. body_delta (N,4): displacement and rotation
    of each body since the start of the step. vert_world, norm_world (V,2): shape
    geometry in the world this step. shape_margin (S,) m: speculative reach.
    """

    count: np.ndarray
    pairs: np.ndarray
    shape_a: np.ndarray
    shape_b: np.ndarray
    body_a: np.ndarray
    body_b: np.ndarray
    key: np.ndarray
    normal: np.ndarray
    points: np.ndarray
    friction: np.ndarray
    restitution: np.ndarray
    softness: np.ndarray
    anchor_a: np.ndarray
    anchor_b: np.ndarray
    base_separation: np.ndarray
    feature: np.ndarray
    normal_impulse: np.ndarray
    tangent_impulse: np.ndarray
    normal_mass: np.ndarray
    tangent_mass: np.ndarray
    approach_velocity: np.ndarray
    approach_separation: np.ndarray
    max_normal_impulse: np.ndarray
    prev_key: np.ndarray
    prev_points: np.ndarray
    prev_feature: np.ndarray
    prev_normal_impulse: np.ndarray
    prev_tangent_impulse: np.ndarray
    scratch_normal: np.ndarray
    scratch_point: np.ndarray
    scratch_separation: np.ndarray
    scratch_feature: np.ndarray
    body_delta: np.ndarray
    vert_world: np.ndarray
    norm_world: np.ndarray
    shape_margin: np.ndarray


def make_contacts(n_bodies: int, n_shapes: int, n_vertices: int, capacity: int) -> Contacts:
    """Allocate contact storage for `capacity` manifolds."""
    m = max(capacity, 1)
    return Contacts(
        count=np.zeros(4, np.int64),
        pairs=np.zeros((m, 2), np.int32),
        shape_a=np.zeros(m, np.int32),
        shape_b=np.zeros(m, np.int32),
        body_a=np.zeros(m, np.int32),
        body_b=np.zeros(m, np.int32),
        key=np.zeros(m, np.int64),
        normal=np.zeros((m, 2)),
        points=np.zeros(m, np.int32),
        friction=np.zeros(m),
        restitution=np.zeros(m),
        softness=np.zeros((m, 3)),
        anchor_a=np.zeros((m, 2, 2)),
        anchor_b=np.zeros((m, 2, 2)),
        base_separation=np.zeros((m, 2)),
        feature=np.zeros((m, 2), np.int64),
        normal_impulse=np.zeros((m, 2)),
        tangent_impulse=np.zeros((m, 2)),
        normal_mass=np.zeros((m, 2)),
        tangent_mass=np.zeros((m, 2)),
        approach_velocity=np.zeros((m, 2)),
        approach_separation=np.zeros((m, 2)),
        max_normal_impulse=np.zeros((m, 2)),
        prev_key=np.zeros(m, np.int64),
        prev_points=np.zeros(m, np.int32),
        prev_feature=np.zeros((m, 2), np.int64),
        prev_normal_impulse=np.zeros((m, 2)),
        prev_tangent_impulse=np.zeros((m, 2)),
        scratch_normal=np.zeros(2),
        scratch_point=np.zeros((2, 2)),
        scratch_separation=np.zeros(2),
        scratch_feature=np.zeros(2, np.int64),
        body_delta=np.zeros((max(n_bodies, 1), 4)),
        vert_world=np.zeros((max(n_vertices, 1), 2)),
        norm_world=np.zeros((max(n_vertices, 1), 2)),
        shape_margin=np.zeros(max(n_shapes, 1)),
    )


def grow_contacts(old: Contacts, capacity: int) -> Contacts:
    """A larger copy of `old` that keeps last step's manifolds for warm starting."""
    new = make_contacts(
        old.body_delta.shape[0], old.shape_margin.shape[0], old.vert_world.shape[0], capacity
    )
    n = int(old.count[1])
    new.count[:] = old.count
    for name in ("prev_key", "prev_points", "prev_feature"):
        getattr(new, name)[:n] = getattr(old, name)[:n]
    new.prev_normal_impulse[:n] = old.prev_normal_impulse[:n]
    new.prev_tangent_impulse[:n] = old.prev_tangent_impulse[:n]
    return new


@njit(cache=True)
def transform_shapes(model, state, contacts, dt):
    """World vertices and normals of every shape, and each shape's speculative reach.

    The reach (m) is how far the shape's surface can move in one step, dt (|v| + |ω| r),
    so that contacts are created before a fast body can pass through another.
    """
    vw, nw = contacts.vert_world, contacts.norm_world
    for s in range(model.shape_body.shape[0]):
        i = model.shape_body[s]
        c, sn = state.body_q[i, 0], state.body_q[i, 1]
        x, y = state.body_x[i, 0], state.body_x[i, 1]
        reach = 0.0
        for k in range(model.shape_vstart[s], model.shape_vstart[s] + model.shape_vcount[s]):
            lx, ly = model.vertex_local[k, 0], model.vertex_local[k, 1]
            vw[k, 0] = x + c * lx - sn * ly
            vw[k, 1] = y + sn * lx + c * ly
            nx, ny = model.normal_local[k, 0], model.normal_local[k, 1]
            nw[k, 0] = c * nx - sn * ny
            nw[k, 1] = sn * nx + c * ny
            reach = max(reach, math.sqrt(lx * lx + ly * ly))
        if model.body_type[i] == C.BODY_STATIC:
            contacts.shape_margin[s] = 0.0
        else:
            speed = math.sqrt(state.body_v[i, 0] ** 2 + state.body_v[i, 1] ** 2)
            reach += model.shape_radius[s]
            contacts.shape_margin[s] = dt * (speed + abs(state.body_w[i]) * reach)


@njit(cache=True, inline="always")
def mix(a, b, rule):
    """Combine two shapes' coefficients by the scene's mixing rule."""
    if rule == MIX_SQRT:
        return math.sqrt(a * b)
    if rule == MIX_MULTIPLY:
        return a * b
    if rule == MIX_MIN:
        return min(a, b)
    return max(a, b)


@njit(cache=True)
def update_manifolds(model, state, contacts, n_pairs, friction_rule, restitution_rule):
    """Run the narrowphase on every pair and keep the manifolds with points.

    A point whose feature id matches one of last step's points in the same pair takes
    over that point's accumulated impulses (warm start). Returns the manifold count.
    """
    n_shapes = model.shape_body.shape[0]
    vw, nw = contacts.vert_world, contacts.norm_world
    out_n, out_p = contacts.scratch_normal, contacts.scratch_point
    out_s, out_f = contacts.scratch_separation, contacts.scratch_feature
    n_prev = contacts.count[1]
    j = 0  # merge pointer into last step's manifolds (both sorted by key)
    m = 0
    for p in range(n_pairs):
        a, b = contacts.pairs[p, 0], contacts.pairs[p, 1]
        spec = C.SPECULATIVE_DISTANCE + contacts.shape_margin[a] + contacts.shape_margin[b]
        npts = collide(
            model.shape_kind[a],
            model.shape_vstart[a],
            model.shape_vcount[a],
            model.shape_radius[a],
            model.shape_kind[b],
            model.shape_vstart[b],
            model.shape_vcount[b],
            model.shape_radius[b],
            vw,
            nw,
            spec,
            out_n,
            out_p,
            out_s,
            out_f,
        )
        if npts == 0:
            continue
        ba, bb = model.shape_body[a], model.shape_body[b]
        key = np.int64(a) * n_shapes + b
        contacts.shape_a[m], contacts.shape_b[m] = a, b
        contacts.body_a[m], contacts.body_b[m] = ba, bb
        contacts.key[m] = key
        nx, ny = out_n[0], out_n[1]
        contacts.normal[m, 0], contacts.normal[m, 1] = nx, ny
        contacts.points[m] = npts
        contacts.friction[m] = mix(model.shape_friction[a], model.shape_friction[b], friction_rule)
        contacts.restitution[m] = mix(
            model.shape_restitution[a], model.shape_restitution[b], restitution_rule
        )
        while j < n_prev and contacts.prev_key[j] < key:
            j += 1
        matched = j < n_prev and contacts.prev_key[j] == key
        for k in range(npts):
            rax = out_p[k, 0] - state.body_x[ba, 0]
            ray = out_p[k, 1] - state.body_x[ba, 1]
            rbx = out_p[k, 0] - state.body_x[bb, 0]
            rby = out_p[k, 1] - state.body_x[bb, 1]
            contacts.anchor_a[m, k, 0], contacts.anchor_a[m, k, 1] = rax, ray
            contacts.anchor_b[m, k, 0], contacts.anchor_b[m, k, 1] = rbx, rby
            # separation = base + n · ((x_a + r_a) - (x_b + r_b)) as the bodies move
            contacts.base_separation[m, k] = out_s[k] - (nx * (rax - rbx) + ny * (ray - rby))
            contacts.feature[m, k] = out_f[k]
            jn, jt = 0.0, 0.0
            if matched:
                for kk in range(contacts.prev_points[j]):
                    if contacts.prev_feature[j, kk] == out_f[k]:
                        jn = contacts.prev_normal_impulse[j, kk]
                        jt = contacts.prev_tangent_impulse[j, kk]
            contacts.normal_impulse[m, k] = jn
            contacts.tangent_impulse[m, k] = jt
            contacts.max_normal_impulse[m, k] = 0.0
        m += 1
    contacts.count[0] = m
    return m


@njit(cache=True)
def store_impulses(contacts):
    """Keep this step's manifolds as next step's warm-start source; count touching points."""
    m = contacts.count[0]
    touching = 0
    for i in range(m):
        contacts.prev_key[i] = contacts.key[i]
        contacts.prev_points[i] = contacts.points[i]
        for k in range(contacts.points[i]):
            contacts.prev_feature[i, k] = contacts.feature[i, k]
            contacts.prev_normal_impulse[i, k] = contacts.normal_impulse[i, k]
            contacts.prev_tangent_impulse[i, k] = contacts.tangent_impulse[i, k]
            if contacts.max_normal_impulse[i, k] > 0.0:
                touching += 1
    contacts.count[1] = m
    contacts.count[3] = touching
