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

from ... import constants as C
from ...scene import types as T
from ...scene.types import MIX_MIN, MIX_MULTIPLY, MIX_SQRT
from .narrowphase import collide
from .solver import ROW_SIZE

# Time of impact by conservative advancement: stop when the gap is below this (m) or
# after this many advancements (each costs one narrowphase call, for approaching
# speculative pairs only). The gap shrinks by a large factor per advancement.
TOI_TOLERANCE = 1.0e-9
TOI_ITERATIONS = 12
TOI_FINISH = 1.0e-6  # m: within this, an impact just after the step is taken at its end


class Contacts(NamedTuple):
    """Preallocated contact storage with capacity M manifolds (2 points each).

    count (10,) int64: [manifolds now, manifolds last step, pairs found, points touching,
    manifolds in the shock pass, entries in bounce_list, entries in relax_list (points
    that overlap by more than DEEP_OVERLAP), 1 when the manifolds are last step's pairs
    in the same slots (the contact graph is unchanged), entries of bounce_list carried
    from the last restitution stage, 1 once an elastic manifold was listed this step].
    carried (M,) bool: the manifold is last step's, unchanged in its slot except for
    its separation (update_manifolds); later stages skip what cannot have changed.
    pairs (M,2) int32: broadphase output. shape_a, shape_b, body_a, body_b (M,) int32;
    key (M,) int64 = shape_a · S + shape_b; normal (M,2); points (M,) int32;
    friction, restitution (M,) mixed coefficients;
    anchor_a, anchor_b (M,2,2) m, from each COM at the start of the step;
    base_separation (M,2) m, the separation minus the anchors' contribution;
    feature (M,2) int64; normal_impulse, tangent_impulse (M,2) N·s (per substep);
    start_impulse (M,2) N·s: the normal impulse carried over into this step;
    ref_separation (M,2) m: the separation with both bodies at their reference poses;
    normal_mass (M,2) kg; solver_row (M, solver.ROW_SIZE): what the solver's passes
    read of each manifold (normal, softness, friction, and per point lever arms,
    normal K, tangent mass, anchors, base separation), written by prepare_contacts;
    approach_velocity (M,2) m/s and approach_separation (M,2) m where the point
    engaged (for restitution);
    max_normal_impulse (M,2) N·s; prev_* the same from last step for matching and
    for carrying a manifold forward. body_ref (N,3): each body's reference pose
    (x, y, angle), re-taken when it moves by more than STILL_DISTANCE or STILL_ANGLE;
    body_still (N,) bool: the body is within that reach of its reference pose.
    toi_verts, toi_norms (V,2): two shapes moved to their time of impact.
    scratch_*: one narrowphase result. body_delta (N,4): displacement and rotation
    of each body since the start of the step. vert_world, norm_world (V,2): shape
    geometry in the world this step. shape_margin (S,) m: speculative reach.
    body_level (N,), shock_side, shock_order (M,): the shock pass (shock.py);
    solve_order (M,): the order of the solver's passes over the manifolds;
    adj_start (N+1,), adj (2M,), queue (N+2,): its scratch. bounce_kind (M,),
    body_mark (N,): the restitution stage's scratch (solver.apply_restitution);
    solve_impulse (M,2) N·s: each point's impulse when the positions moved this substep
    (kept only in scenes with elastic materials, for the restitution stage);
    bounce_list (2M+2,): the manifolds whose points engaged faster than the restitution
    threshold since the last restitution stage, after those that stage left for later
    (count[5] of them, count[8] carried; a point is listed at most once at a time).
    relax_list (M,): the manifolds with a point deeper than DEEP_OVERLAP in this
    substep's solve (count[6] entries, M when full), then those the extra relax passes
    take (shock.deep_region); body_reach (N,): its scratch.
    """

    count: np.ndarray
    carried: np.ndarray
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
    anchor_a: np.ndarray
    anchor_b: np.ndarray
    base_separation: np.ndarray
    ref_separation: np.ndarray
    feature: np.ndarray
    normal_impulse: np.ndarray
    start_impulse: np.ndarray
    tangent_impulse: np.ndarray
    normal_mass: np.ndarray
    solver_row: np.ndarray
    approach_velocity: np.ndarray
    approach_separation: np.ndarray
    max_normal_impulse: np.ndarray
    prev_key: np.ndarray
    prev_points: np.ndarray
    prev_feature: np.ndarray
    prev_normal_impulse: np.ndarray
    prev_tangent_impulse: np.ndarray
    prev_normal: np.ndarray
    prev_anchor_a: np.ndarray
    prev_anchor_b: np.ndarray
    prev_ref_separation: np.ndarray
    body_ref: np.ndarray
    body_still: np.ndarray
    toi_verts: np.ndarray
    toi_norms: np.ndarray
    scratch_normal: np.ndarray
    scratch_point: np.ndarray
    scratch_separation: np.ndarray
    scratch_feature: np.ndarray
    body_delta: np.ndarray
    vert_world: np.ndarray
    norm_world: np.ndarray
    shape_margin: np.ndarray
    body_level: np.ndarray
    shock_side: np.ndarray
    shock_order: np.ndarray
    solve_order: np.ndarray
    adj_start: np.ndarray
    adj: np.ndarray
    queue: np.ndarray
    bounce_kind: np.ndarray
    body_mark: np.ndarray
    solve_impulse: np.ndarray
    bounce_list: np.ndarray
    relax_list: np.ndarray
    body_reach: np.ndarray


def make_contacts(n_bodies: int, n_shapes: int, n_vertices: int, capacity: int) -> Contacts:
    """Allocate contact storage for `capacity` manifolds."""
    m = max(capacity, 1)
    return Contacts(
        count=np.zeros(10, np.int64),
        carried=np.zeros(m, np.bool_),
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
        anchor_a=np.zeros((m, 2, 2)),
        anchor_b=np.zeros((m, 2, 2)),
        base_separation=np.zeros((m, 2)),
        ref_separation=np.zeros((m, 2)),
        feature=np.zeros((m, 2), np.int64),
        normal_impulse=np.zeros((m, 2)),
        start_impulse=np.zeros((m, 2)),
        tangent_impulse=np.zeros((m, 2)),
        normal_mass=np.zeros((m, 2)),
        solver_row=np.zeros((m, ROW_SIZE)),
        approach_velocity=np.zeros((m, 2)),
        approach_separation=np.zeros((m, 2)),
        max_normal_impulse=np.zeros((m, 2)),
        prev_key=np.zeros(m, np.int64),
        prev_points=np.zeros(m, np.int32),
        prev_feature=np.zeros((m, 2), np.int64),
        prev_normal_impulse=np.zeros((m, 2)),
        prev_tangent_impulse=np.zeros((m, 2)),
        prev_normal=np.zeros((m, 2)),
        prev_anchor_a=np.zeros((m, 2, 2)),
        prev_anchor_b=np.zeros((m, 2, 2)),
        prev_ref_separation=np.zeros((m, 2)),
        body_ref=np.full((max(n_bodies, 1), 3), np.nan),
        body_still=np.zeros(max(n_bodies, 1), np.bool_),
        toi_verts=np.zeros((max(n_vertices, 2), 2)),
        toi_norms=np.zeros((max(n_vertices, 2), 2)),
        scratch_normal=np.zeros(2),
        scratch_point=np.zeros((2, 2)),
        scratch_separation=np.zeros(2),
        scratch_feature=np.zeros(2, np.int64),
        body_delta=np.zeros((max(n_bodies, 1), 4)),
        vert_world=np.zeros((max(n_vertices, 1), 2)),
        norm_world=np.zeros((max(n_vertices, 1), 2)),
        shape_margin=np.zeros(max(n_shapes, 1)),
        body_level=np.zeros(max(n_bodies, 1), np.int64),
        shock_side=np.zeros(m, np.int8),
        shock_order=np.zeros(m, np.int32),
        solve_order=np.zeros(m, np.int32),
        adj_start=np.zeros(max(n_bodies, 1) + 1, np.int64),
        adj=np.zeros(2 * m, np.int32),
        queue=np.zeros(max(n_bodies, 1) + 2, np.int64),
        bounce_kind=np.zeros(m, np.int8),
        body_mark=np.zeros(max(n_bodies, 1), np.int8),
        solve_impulse=np.zeros((m, 2)),
        bounce_list=np.zeros(2 * m + 2, np.int32),
        relax_list=np.zeros(m, np.int32),
        body_reach=np.zeros(max(n_bodies, 1), np.int64),
    )


def grow_contacts(old: Contacts, capacity: int) -> Contacts:
    """A larger copy of `old` that keeps last step's manifolds for warm starting."""
    new = make_contacts(
        old.body_delta.shape[0], old.shape_margin.shape[0], old.vert_world.shape[0], capacity
    )
    n = int(old.count[1])
    new.count[:] = old.count
    new.count[2] = 0  # the pair list is found anew
    for name in (
        "prev_key",
        "prev_points",
        "prev_feature",
        "prev_normal_impulse",
        "prev_tangent_impulse",
        "prev_normal",
        "prev_anchor_a",
        "prev_anchor_b",
        "prev_ref_separation",
    ):
        getattr(new, name)[:n] = getattr(old, name)[:n]
    new.body_ref[:] = old.body_ref
    new.body_still[:] = old.body_still
    return new


@njit(cache=True, _nrt=False)
def transform_shapes(model, state, contacts, dt):
    """World vertices and normals of every shape, and each shape's speculative reach.

    The reach (m) is how far the shape's surface can move in one step, dt (|v| + |ω| r),
    so that contacts are created before a fast body can pass through another.
    """
    c_shape_margin = contacts.shape_margin
    m_body_type = model.body_type
    m_normal_local = model.normal_local
    m_shape_body = model.shape_body
    m_shape_radius = model.shape_radius
    m_shape_vcount = model.shape_vcount
    m_shape_vstart = model.shape_vstart
    m_vertex_local = model.vertex_local
    s_body_q = state.body_q
    s_body_v = state.body_v
    s_body_w = state.body_w
    s_body_x = state.body_x
    ref, still = contacts.body_ref, contacts.body_still
    angle = state.body_angle
    for i in range(ref.shape[0]):
        dx, dy = s_body_x[i, 0] - ref[i, 0], s_body_x[i, 1] - ref[i, 1]
        near = dx * dx + dy * dy < C.STILL_DISTANCE**2 and abs(angle[i] - ref[i, 2]) < C.STILL_ANGLE
        still[i] = near
        if not near:  # re-take the reference pose: this body's contacts are recomputed
            ref[i, 0], ref[i, 1], ref[i, 2] = s_body_x[i, 0], s_body_x[i, 1], angle[i]
    vw, nw = contacts.vert_world, contacts.norm_world
    for s in range(m_shape_body.shape[0]):
        i = m_shape_body[s]
        c, sn = s_body_q[i, 0], s_body_q[i, 1]
        x, y = s_body_x[i, 0], s_body_x[i, 1]
        reach = 0.0
        for k in range(m_shape_vstart[s], m_shape_vstart[s] + m_shape_vcount[s]):
            lx, ly = m_vertex_local[k, 0], m_vertex_local[k, 1]
            vw[k, 0] = x + c * lx - sn * ly
            vw[k, 1] = y + sn * lx + c * ly
            nx, ny = m_normal_local[k, 0], m_normal_local[k, 1]
            nw[k, 0] = c * nx - sn * ny
            nw[k, 1] = sn * nx + c * ny
            reach = max(reach, math.sqrt(lx * lx + ly * ly))
        if m_body_type[i] == T.BODY_STATIC:
            c_shape_margin[s] = 0.0
        else:
            speed = math.sqrt(s_body_v[i, 0] ** 2 + s_body_v[i, 1] ** 2)
            reach += m_shape_radius[s]
            c_shape_margin[s] = dt * (speed + abs(s_body_w[i]) * reach)


@njit(cache=True, _nrt=False, inline="always")
def mix(a, b, rule):
    """Combine two shapes' coefficients by the scene's mixing rule."""
    if rule == MIX_SQRT:
        return math.sqrt(a * b)
    if rule == MIX_MULTIPLY:
        return a * b
    if rule == MIX_MIN:
        return min(a, b)
    return max(a, b)


@njit(cache=True, _nrt=False)
def _place(g, s, t, start, x, q, v, w, verts, norms):
    """Write shape s's vertices and normals, as its body will be after t seconds of
    free motion, into rows start.. of verts and norms. g: (shape_body, shape_vstart,
    shape_vcount, vertex_local, normal_local) of the model."""
    shape_body, shape_vstart, shape_vcount, vertex_local, normal_local = g
    i = shape_body[s]
    cr, sr = math.cos(t * w[i]), math.sin(t * w[i])
    c, sn = cr * q[i, 0] - sr * q[i, 1], sr * q[i, 0] + cr * q[i, 1]
    px, py = x[i, 0] + t * v[i, 0], x[i, 1] + t * v[i, 1]
    v0 = shape_vstart[s]
    for k in range(shape_vcount[s]):
        lx, ly = vertex_local[v0 + k, 0], vertex_local[v0 + k, 1]
        verts[start + k, 0] = px + c * lx - sn * ly
        verts[start + k, 1] = py + sn * lx + c * ly
        nx, ny = normal_local[v0 + k, 0], normal_local[v0 + k, 1]
        norms[start + k, 0] = c * nx - sn * ny
        norms[start + k, 1] = sn * nx + c * ny


@njit(cache=True, _nrt=False, inline="always")
def _nearest_approach(out, npts, ba, bb, t, x, v, w):
    """(separation m, normal velocity m/s; < 0 approaching) of the nearest point of the
    manifold `out` between bodies ba and bb, both moved freely by t (s): the arms are
    taken from the moved centres. x, v, w: the state's body arrays."""
    out_n, out_p, out_s = out[0], out[1], out[2]
    sep = min(out_s[0], out_s[1]) if npts == 2 else out_s[0]
    k = 0 if npts == 1 or out_s[0] <= out_s[1] else 1
    rax, ray = out_p[k, 0] - x[ba, 0] - t * v[ba, 0], out_p[k, 1] - x[ba, 1] - t * v[ba, 1]
    rbx, rby = out_p[k, 0] - x[bb, 0] - t * v[bb, 0], out_p[k, 1] - x[bb, 1] - t * v[bb, 1]
    dvx = v[ba, 0] - w[ba] * ray - v[bb, 0] + w[bb] * rby
    dvy = v[ba, 1] + w[ba] * rax - v[bb, 1] - w[bb] * rbx
    return sep, dvx * out_n[0] + dvy * out_n[1]


@njit(cache=True, _nrt=False)
def _time_of_impact(g, kinds, radii, a, b, npts, dt, spec, x, q, v, w, tv, tn, out):
    """Move a speculative manifold to the moment of impact.

    A manifold found before the shapes touch has the normal and points of the start
    of the step; for a glancing approach (two balls off centre) those are not the
    normal and points of the impact. Conservative advancement: move both bodies
    freely by t = separation / approach speed, collide again, repeat; the manifold
    at the last t replaces the scratch one `out` (normal, points, separations, ids).
    Returns (points, t) with t in s (0 when the pair is separating or does not meet
    within dt). g as for _place; kinds, radii: the model's shape arrays.
    """
    out_n, out_p, out_s, out_f = out
    shape_body, shape_vcount = g[0], g[2]
    ba, bb = shape_body[a], shape_body[b]
    t = 0.0
    for _ in range(TOI_ITERATIONS):
        sep, vn = _nearest_approach(out, npts, ba, bb, t, x, v, w)
        if sep <= TOI_TOLERANCE or vn >= 0.0:
            break
        step = sep / -vn
        last = t + step >= dt
        if last:
            # the impact falls after the step. Right after it (the search came within
            # TOI_FINISH), the manifold is taken at the step's end, which has the
            # impact's normal (stopping short left one on a frame 5e-8 rad off);
            # further, it stays where it is (a turning body's arc is not in the
            # estimate, and it may meet the other before the step's end)
            step = dt - t
            if step <= 0.0 or sep > TOI_FINISH:
                break
        t += step
        na, nb = shape_vcount[a], shape_vcount[b]
        _place(g, a, t, 0, x, q, v, w, tv, tn)
        _place(g, b, t, na, x, q, v, w, tv, tn)
        npts = collide(
            kinds[a], 0, na, radii[a], kinds[b], na, nb, radii[b],
            tv, tn, spec, out_n, out_p, out_s, out_f,
        )  # fmt: skip
        if npts == 0:  # passed by after all
            return 0, t
        if last:
            break
    return npts, t


@njit(cache=True, _nrt=False)
def update_manifolds(model, state, contacts, box, n_pairs, friction_rule, restitution_rule, dt):
    """Run the narrowphase on every pair whose tight boxes `box` (S,4) overlap, and keep
    the manifolds with points.

    A point whose feature id matches one of last step's points in the same pair takes
    over that point's accumulated impulses (warm start). Returns the manifold count.
    """
    c_anchor_a = contacts.anchor_a
    c_anchor_b = contacts.anchor_b
    c_base_separation = contacts.base_separation
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_feature = contacts.feature
    c_friction = contacts.friction
    c_key = contacts.key
    c_max_normal_impulse = contacts.max_normal_impulse
    c_normal = contacts.normal
    c_normal_impulse = contacts.normal_impulse
    c_pairs = contacts.pairs
    c_points = contacts.points
    c_prev_feature = contacts.prev_feature
    c_prev_key = contacts.prev_key
    c_prev_normal_impulse = contacts.prev_normal_impulse
    c_prev_points = contacts.prev_points
    c_prev_tangent_impulse = contacts.prev_tangent_impulse
    c_restitution = contacts.restitution
    c_shape_a = contacts.shape_a
    c_shape_b = contacts.shape_b
    c_shape_margin = contacts.shape_margin
    c_tangent_impulse = contacts.tangent_impulse
    m_shape_body = model.shape_body
    m_shape_friction = model.shape_friction
    m_shape_kind = model.shape_kind
    m_shape_radius = model.shape_radius
    m_shape_restitution = model.shape_restitution
    m_shape_vcount = model.shape_vcount
    m_shape_vstart = model.shape_vstart
    s_body_x = state.body_x
    s_body_v, s_body_w = state.body_v, state.body_w
    c_ref_separation = contacts.ref_separation
    c_start_impulse = contacts.start_impulse
    s_body_q = state.body_q
    toi_verts, toi_norms = contacts.toi_verts, contacts.toi_norms
    geometry = (
        model.shape_body,
        model.shape_vstart,
        model.shape_vcount,
        model.vertex_local,
        model.normal_local,
    )
    c_prev_normal = contacts.prev_normal
    c_prev_anchor_a, c_prev_anchor_b = contacts.prev_anchor_a, contacts.prev_anchor_b
    c_prev_ref_separation = contacts.prev_ref_separation
    ref, still = contacts.body_ref, contacts.body_still
    n_shapes = m_shape_body.shape[0]
    vw, nw = contacts.vert_world, contacts.norm_world
    out_n, out_p = contacts.scratch_normal, contacts.scratch_point
    out_s, out_f = contacts.scratch_separation, contacts.scratch_feature
    out = (out_n, out_p, out_s, out_f)
    c_carried = contacts.carried
    n_prev = c_count[1]
    j = 0  # merge pointer into last step's manifolds (both sorted by key)
    m = 0
    same = True  # every manifold so far is last step's pair in the same slot
    for p in range(n_pairs):
        a, b = c_pairs[p, 0], c_pairs[p, 1]
        if (
            box[a, 0] > box[b, 2]
            or box[b, 0] > box[a, 2]
            or box[a, 1] > box[b, 3]
            or box[b, 1] > box[a, 3]
        ):
            continue  # near in the fat boxes only: out of reach this step
        ba, bb = m_shape_body[a], m_shape_body[b]
        key = np.int64(a) * n_shapes + b
        while j < n_prev and c_prev_key[j] < key:
            j += 1
        matched = j < n_prev and c_prev_key[j] == key
        in_slot = matched and j == m and c_key[m] == key
        # motion of the two bodies since their reference poses
        ddx = (s_body_x[ba, 0] - ref[ba, 0]) - (s_body_x[bb, 0] - ref[bb, 0])
        ddy = (s_body_x[ba, 1] - ref[ba, 1]) - (s_body_x[bb, 1] - ref[bb, 1])
        if in_slot and still[ba] and still[bb]:
            # neither body has moved, and last step's manifold is still in this slot
            # (store_impulses copied it to prev_*, so the two agree): only its
            # separation and this step's impulse records change
            nx, ny = c_normal[m, 0], c_normal[m, 1]
            for k in range(c_points[m]):
                rax, ray = c_anchor_a[m, k, 0], c_anchor_a[m, k, 1]
                rbx, rby = c_anchor_b[m, k, 0], c_anchor_b[m, k, 1]
                sep = c_ref_separation[m, k] + nx * ddx + ny * ddy
                c_base_separation[m, k] = sep - (nx * (rax - rbx) + ny * (ray - rby))
                c_start_impulse[m, k] = c_normal_impulse[m, k]
                c_max_normal_impulse[m, k] = 0.0
            c_carried[m] = True
            m += 1
            continue
        if matched and still[ba] and still[bb]:
            # neither body has moved: carry last step's manifold forward
            nx, ny = c_prev_normal[j, 0], c_prev_normal[j, 1]
            npts = c_prev_points[j]
            for k in range(npts):
                rax, ray = c_prev_anchor_a[j, k, 0], c_prev_anchor_a[j, k, 1]
                rbx, rby = c_prev_anchor_b[j, k, 0], c_prev_anchor_b[j, k, 1]
                c_anchor_a[m, k, 0], c_anchor_a[m, k, 1] = rax, ray
                c_anchor_b[m, k, 0], c_anchor_b[m, k, 1] = rbx, rby
                ref_sep = c_prev_ref_separation[j, k]
                c_ref_separation[m, k] = ref_sep
                sep = ref_sep + nx * ddx + ny * ddy
                c_base_separation[m, k] = sep - (nx * (rax - rbx) + ny * (ray - rby))
                c_feature[m, k] = c_prev_feature[j, k]
                c_normal_impulse[m, k] = c_prev_normal_impulse[j, k]
                c_start_impulse[m, k] = c_prev_normal_impulse[j, k]
                c_tangent_impulse[m, k] = c_prev_tangent_impulse[j, k]
                c_max_normal_impulse[m, k] = 0.0
        else:
            spec = C.SPECULATIVE_DISTANCE + c_shape_margin[a] + c_shape_margin[b]
            npts = collide(
                m_shape_kind[a],
                m_shape_vstart[a],
                m_shape_vcount[a],
                m_shape_radius[a],
                m_shape_kind[b],
                m_shape_vstart[b],
                m_shape_vcount[b],
                m_shape_radius[b],
                vw,
                nw,
                spec,
                out_n,
                out_p,
                out_s,
                out_f,
            )
            t = 0.0
            # only a pair that is clearly apart can turn its normal before the impact,
            # and only if it meets within the step: most such pairs do not (two balls
            # falling side by side), and their test is made here, as the search's
            # first, so that they skip the call (it takes the whole model)
            meets = False
            if npts > 0 and min(out_s[0], out_s[npts - 1]) > C.LINEAR_SLOP:
                sep, vn = _nearest_approach(out, npts, ba, bb, 0.0, s_body_x, s_body_v, s_body_w)
                meets = vn < 0.0 and sep / -vn < dt
            if meets:
                npts, t = _time_of_impact(
                    geometry, m_shape_kind, m_shape_radius, a, b, npts, dt, spec,
                    s_body_x, s_body_q, s_body_v, s_body_w, toi_verts, toi_norms, out,
                )  # fmt: skip
            if npts == 0:
                continue
            nx, ny = out_n[0], out_n[1]
            # the bodies' free motion to the impact (t = 0 unless it was moved there)
            vax, vay = t * s_body_v[ba, 0], t * s_body_v[ba, 1]
            vbx, vby = t * s_body_v[bb, 0], t * s_body_v[bb, 1]
            ca, sa, cb, sb = 1.0, 0.0, 1.0, 0.0  # the rotations by ω t; t = 0 is the
            if t != 0.0:  # common case, and then costs no trigonometry
                ca, sa = math.cos(t * s_body_w[ba]), math.sin(t * s_body_w[ba])
                cb, sb = math.cos(t * s_body_w[bb]), math.sin(t * s_body_w[bb])
            for k in range(npts):
                # lever arms at the impact
                rax = out_p[k, 0] - s_body_x[ba, 0] - vax
                ray = out_p[k, 1] - s_body_x[ba, 1] - vay
                rbx = out_p[k, 0] - s_body_x[bb, 0] - vbx
                rby = out_p[k, 1] - s_body_x[bb, 1] - vby
                c_anchor_a[m, k, 0], c_anchor_a[m, k, 1] = rax, ray
                c_anchor_b[m, k, 0], c_anchor_b[m, k, 1] = rbx, rby
                # separation = base + n · (d_a + R(Δθ_a) r_a - d_b - R(Δθ_b) r_b) as the
                # bodies move (d, Δθ: motion since the step's start); at the impact
                # (d = v t, Δθ = ω t) it equals the separation found there
                qax, qay = ca * rax - sa * ray, sa * rax + ca * ray
                qbx, qby = cb * rbx - sb * rby, sb * rbx + cb * rby
                moved = nx * (vax + qax - vbx - qbx) + ny * (vay + qay - vby - qby)
                base = out_s[k] - moved
                c_base_separation[m, k] = base
                start = base + nx * (rax - rbx) + ny * (ray - rby)
                c_ref_separation[m, k] = start - (nx * ddx + ny * ddy)
                c_feature[m, k] = out_f[k]
                jn, jt = 0.0, 0.0
                if matched:
                    for kk in range(c_prev_points[j]):
                        if c_prev_feature[j, kk] == out_f[k]:
                            jn = c_prev_normal_impulse[j, kk]
                            jt = c_prev_tangent_impulse[j, kk]
                c_normal_impulse[m, k] = jn
                c_start_impulse[m, k] = jn
                c_tangent_impulse[m, k] = jt
                c_max_normal_impulse[m, k] = 0.0
        same = same and in_slot
        c_carried[m] = False
        c_shape_a[m], c_shape_b[m] = a, b
        c_body_a[m], c_body_b[m] = ba, bb
        c_key[m] = key
        c_normal[m, 0], c_normal[m, 1] = nx, ny
        c_points[m] = npts
        c_friction[m] = mix(m_shape_friction[a], m_shape_friction[b], friction_rule)
        c_restitution[m] = mix(m_shape_restitution[a], m_shape_restitution[b], restitution_rule)
        m += 1
    c_count[0] = m
    c_count[7] = 1 if same and m == n_prev else 0
    return m


@njit(cache=True, _nrt=False)
def store_impulses(contacts):
    """Keep this step's manifolds as next step's warm-start source; count touching points."""
    c_count = contacts.count
    c_feature = contacts.feature
    c_key = contacts.key
    c_max_normal_impulse = contacts.max_normal_impulse
    c_normal_impulse = contacts.normal_impulse
    c_points = contacts.points
    c_prev_feature = contacts.prev_feature
    c_prev_key = contacts.prev_key
    c_prev_normal_impulse = contacts.prev_normal_impulse
    c_prev_points = contacts.prev_points
    c_prev_tangent_impulse = contacts.prev_tangent_impulse
    c_tangent_impulse = contacts.tangent_impulse
    normal, prev_normal = contacts.normal, contacts.prev_normal
    anchor_a, prev_anchor_a = contacts.anchor_a, contacts.prev_anchor_a
    anchor_b, prev_anchor_b = contacts.anchor_b, contacts.prev_anchor_b
    ref_sep, prev_ref_sep = contacts.ref_separation, contacts.prev_ref_separation
    c_carried = contacts.carried
    m = c_count[0]
    touching = 0
    for i in range(m):
        if c_carried[i]:  # the slot's prev_* already hold all but the impulses
            for k in range(c_points[i]):
                c_prev_normal_impulse[i, k] = c_normal_impulse[i, k]
                c_prev_tangent_impulse[i, k] = c_tangent_impulse[i, k]
                if c_max_normal_impulse[i, k] > 0.0:
                    touching += 1
            continue
        c_prev_key[i] = c_key[i]
        c_prev_points[i] = c_points[i]
        prev_normal[i, 0], prev_normal[i, 1] = normal[i, 0], normal[i, 1]
        for k in range(c_points[i]):
            prev_anchor_a[i, k, 0], prev_anchor_a[i, k, 1] = anchor_a[i, k, 0], anchor_a[i, k, 1]
            prev_anchor_b[i, k, 0], prev_anchor_b[i, k, 1] = anchor_b[i, k, 0], anchor_b[i, k, 1]
            prev_ref_sep[i, k] = ref_sep[i, k]
            c_prev_feature[i, k] = c_feature[i, k]
            c_prev_normal_impulse[i, k] = c_normal_impulse[i, k]
            c_prev_tangent_impulse[i, k] = c_tangent_impulse[i, k]
            if c_max_normal_impulse[i, k] > 0.0:
                touching += 1
    c_count[1] = m
    c_count[3] = touching
