"""Shock propagation: contacts solved from the ground up, the supporting body held still.

Sequential impulses converge slowly when a heavy body presses on light ones: each pass
over a slab resting on a small box hands the box the slab's whole approach speed and
takes back only a mass ratio's worth of it from the slab, so a 400 kg slab falling on
1 kg boxes needs hundreds of passes to stop and, in a few, crushes them into the ground.
After the relax pass of every substep this stage makes one more pass over the contacts,
ordered by how far each body is from a static or kinematic body through the contact
graph (its support level, found once per step), and solves each contact between a
supporting body (lower level, underneath with respect to gravity) and a supported one
(higher level) as if the supporter had infinite mass: only the supported body's approach
is removed. A rigidly supported body cannot be pushed into what holds it, so for
vertical support this is what the converged solve would give; the impulse goes into
the ground through the chain, as it physically does.

The pass only removes approach velocity (it never pushes apart and never adds energy)
and keeps no accumulated impulse, so warm starting and the resting equilibrium of the
soft contacts are unchanged. It needs gravity to say what is underneath: a scene
without gravity, or a contact whose normal is closer to horizontal than SHOCK_COS,
is left to the ordinary solve. (Guendelman, Bridson and Fedkiw 2003 introduced shock
propagation for stacking; this is a velocity-level variant of it.)
"""

from __future__ import annotations

import math

from numba import njit

from .solver import (
    POINT_SIZE,
    PT_RNA,
    PT_RNB,
    ROW_NX,
    ROW_NY,
    ROW_POINT,
    row_separation,
)

# A contact counts as support when its normal is within this cosine of the vertical
# (about 45 degrees). Steeper faces (a box leaning on a wall) are solved normally.
SHOCK_COS = 0.7071

# Approach speeds below this are left to the ordinary solve, m/s: the relax pass
# leaves such residues at most resting contacts, and removing them changes nothing
# visible (1 mm/s closes 4 µm in a substep) but costs a full pass.
SHOCK_MIN_APPROACH = 1.0e-4

UNREACHED = 1 << 30


@njit(cache=True, _nrt=False)
def contact_levels(model, contacts):
    """contacts.body_level (N,): 0 for static and kinematic bodies, 1 for the bodies
    they touch, ..., UNREACHED for bodies not connected to one (breadth first over
    the manifolds with points). Uses contacts.adj_start, adj and queue as scratch."""
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_points = contacts.points
    level = contacts.body_level
    adj_start = contacts.adj_start
    adj = contacts.adj
    queue = contacts.queue
    body_type = model.body_type
    n_bodies = level.shape[0]
    n_man = contacts.count[0]
    # adjacency of the contact graph (compressed rows, manifolds with points only)
    for i in range(n_bodies + 1):
        adj_start[i] = 0
    for m in range(n_man):
        if c_points[m] > 0:
            adj_start[c_body_a[m] + 1] += 1
            adj_start[c_body_b[m] + 1] += 1
    for i in range(n_bodies):
        adj_start[i + 1] += adj_start[i]
    for i in range(n_bodies):
        queue[i] = adj_start[i]  # fill cursor
    for m in range(n_man):
        if c_points[m] > 0:
            a, b = c_body_a[m], c_body_b[m]
            adj[queue[a]] = b
            queue[a] += 1
            adj[queue[b]] = a
            queue[b] += 1
    # breadth-first levels from every static or kinematic body
    head = tail = 0
    for i in range(n_bodies):
        if body_type[i] != 0:
            level[i] = 0
            queue[tail] = i
            tail += 1
        else:
            level[i] = UNREACHED
    while head < tail:
        i = queue[head]
        head += 1
        for e in range(adj_start[i], adj_start[i + 1]):
            j = adj[e]
            if level[j] == UNREACHED:
                level[j] = level[i] + 1
                queue[tail] = j
                tail += 1


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def support_order(model, contacts):
    """Support level of every body, and the orders of the solver's and the shock pass.

    Writes contacts.solve_order (M,): every manifold, lowest supporter level first (the
    order of the solver's passes; the manifolds' own order without gravity);
    contacts.body_level (N,): 0 for static and kinematic bodies, 1 for bodies they
    touch, ...; UNREACHED otherwise; contacts.shock_order: the manifolds with a
    supporter, lowest supporter first; contacts.shock_side (M,): 1 when body a supports
    body b, 2 when body b supports body a, 0 when neither. Returns the number of
    manifolds in shock_order. When the manifolds are last step's (contacts.count[7]),
    the levels and the solve order are kept and only the shock pass's side and order
    are found again (a normal may have turned). Uses contacts.queue as scratch.
    """
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_normal = contacts.normal
    c_points = contacts.points
    level = contacts.body_level
    queue = contacts.queue
    side = contacts.shock_side
    order = contacts.shock_order
    body_type = model.body_type
    n_bodies = level.shape[0]
    n_man = contacts.count[0]
    gx, gy = model.gravity[0], model.gravity[1]
    g = math.sqrt(gx * gx + gy * gy)
    solve_order = contacts.solve_order
    # the same manifolds as last step, in the same slots: its levels and solve order hold
    same = contacts.count[7] == 1
    for m in range(n_man):
        side[m] = 0
        if not same:
            solve_order[m] = m
    if g == 0.0 or n_man == 0:
        return 0
    upx, upy = -gx / g, -gy / g
    if not same:
        contact_levels(model, contacts)
    # which side supports, and a counting sort by the supporter's level
    max_level = 0
    for m in range(n_man):
        if c_points[m] == 0:
            continue
        a, b = c_body_a[m], c_body_b[m]
        up = c_normal[m, 0] * upx + c_normal[m, 1] * upy  # normal points from b to a
        if level[b] < level[a] and up >= SHOCK_COS and body_type[a] == 0:
            side[m] = 2
            max_level = max(max_level, level[b])
        elif level[a] < level[b] and up <= -SHOCK_COS and body_type[b] == 0:
            side[m] = 1
            max_level = max(max_level, level[a])
    # every manifold, ordered by the lower of its two bodies' levels (ground first,
    # bodies not connected to the ground last): the order of the solver's passes, in
    # which a pass carries a push or a correction up a stack within one sweep
    count = queue  # reuse as bucket counts (the levels are known now)
    if not same:
        top = 0
        for i in range(n_bodies):
            if level[i] != UNREACHED and level[i] > top:
                top = level[i]
        for k in range(top + 3):
            count[k] = 0
        for m in range(n_man):
            lv = min(min(level[c_body_a[m]], level[c_body_b[m]]), top + 1)
            count[lv + 1] += 1
        for k in range(top + 2):
            count[k + 1] += count[k]
        for m in range(n_man):
            lv = min(min(level[c_body_a[m]], level[c_body_b[m]]), top + 1)
            solve_order[count[lv]] = m
            count[lv] += 1
    for k in range(max_level + 2):
        count[k] = 0
    for m in range(n_man):
        if side[m] == 2:
            count[level[c_body_b[m]] + 1] += 1
        elif side[m] == 1:
            count[level[c_body_a[m]] + 1] += 1
    for k in range(max_level + 1):
        count[k + 1] += count[k]
    total = count[max_level + 1]
    for m in range(n_man):
        if side[m] == 2:
            lv = level[c_body_b[m]]
        elif side[m] == 1:
            lv = level[c_body_a[m]]
        else:
            continue
        order[count[lv]] = m
        count[lv] += 1
    return total


@njit(cache=True, _nrt=False)
def deep_region(model, contacts, reach):
    """The manifolds near a deep overlap, for the relax stage's extra passes: those of
    the dynamic bodies within `reach` contacts of a body in a manifold of
    contacts.relax_list[:count[6]], written in solve order over that list; returns
    their count. Every manifold when the list is full or the scene has no gravity (the
    contact graph, contact_levels' adjacency, is built only for the shock pass).
    Uses contacts.queue and body_reach as scratch."""
    c_body_a, c_body_b = contacts.body_a, contacts.body_b
    adj_start, adj = contacts.adj_start, contacts.adj
    queue, dist = contacts.queue, contacts.body_reach
    relax_list, order = contacts.relax_list, contacts.solve_order
    body_type = model.body_type
    n_man = contacts.count[0]
    n_seeds = contacts.count[6]
    everything = n_seeds >= relax_list.shape[0]
    everything = everything or (model.gravity[0] == 0.0 and model.gravity[1] == 0.0)
    if everything:
        for o in range(n_man):
            relax_list[o] = order[o]
        return n_man
    for i in range(dist.shape[0]):
        dist[i] = -1
    # breadth first from the deep manifolds' bodies; static and kinematic bodies are
    # not passed through (a push does not travel through the ground)
    tail = 0
    for k in range(n_seeds):
        m = relax_list[k]
        for i in (c_body_a[m], c_body_b[m]):
            if body_type[i] == 0 and dist[i] < 0:
                dist[i] = 0
                queue[tail] = i
                tail += 1
    head = 0
    while head < tail:
        i = queue[head]
        head += 1
        if dist[i] >= reach:
            continue
        for e in range(adj_start[i], adj_start[i + 1]):
            j = adj[e]
            if body_type[j] == 0 and dist[j] < 0:
                dist[j] = dist[i] + 1
                queue[tail] = j
                tail += 1
    count = 0
    for o in range(n_man):
        m = order[o]
        if dist[c_body_a[m]] >= 0 or dist[c_body_b[m]] >= 0:
            relax_list[count] = m
            count += 1
    return count


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def propagate_shock(model, state, contacts, n_order, inv_h, threshold):
    """One pass over the supported contacts, lowest first, that removes each supported
    body's approach towards its supporter (the supporter taken as infinitely heavy).
    A point with a gap (m) may still close it within the substep (1/inv_h s). An
    elastic contact (restitution > 0) approaching faster than `threshold` (m/s) is an
    impact, not a load: it is left to the next substep's solve and bounce (taken here,
    its energy would be lost: a ball struck down onto the floor stopped dead)."""
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_points = contacts.points
    c_restitution = contacts.restitution
    row = contacts.solver_row
    side = contacts.shock_side
    order = contacts.shock_order
    delta = contacts.body_delta
    im, ii = model.body_inv_mass, model.body_inv_inertia
    v, w = state.body_v, state.body_w
    for o in range(n_order):
        m = order[o]
        a, b = c_body_a[m], c_body_b[m]
        nx, ny = row[m, ROW_NX], row[m, ROW_NY]
        npts = c_points[m]
        # most supported points are not approaching: skip them before any other work
        dvx, dvy = v[a, 0] - v[b, 0], v[a, 1] - v[b, 1]
        # (the two points in scalars: a kernel allocates nothing, not even scratch)
        p0, p1 = ROW_POINT, ROW_POINT + POINT_SIZE
        vel0 = dvx * nx + dvy * ny + w[a] * row[m, p0 + PT_RNA] - w[b] * row[m, p0 + PT_RNB]
        vel1 = 0.0
        approaching = vel0 < -SHOCK_MIN_APPROACH
        if npts == 2:
            vel1 = dvx * nx + dvy * ny + w[a] * row[m, p1 + PT_RNA] - w[b] * row[m, p1 + PT_RNB]
            approaching = approaching or vel1 < -SHOCK_MIN_APPROACH
        if not approaching:
            continue
        if c_restitution[m] > 0.0 and min(vel0, vel1) < -threshold:
            continue
        dax, day, ca, sa = delta[a, 0], delta[a, 1], delta[a, 2], delta[a, 3]
        dbx, dby, cb, sb = delta[b, 0], delta[b, 1], delta[b, 2], delta[b, 3]
        moved = nx * (dax - dbx) + ny * (day - dby)
        nax, nay = ca * nx + sa * ny, ca * ny - sa * nx
        nbx, nby = cb * nx + sb * ny, cb * ny - sb * nx
        # the supported body moves; the sign turns its push along +n (a) or -n (b)
        u, sgn, arm = (a, 1.0, PT_RNA) if side[m] == 2 else (b, -1.0, PT_RNB)
        mu, iu = im[u], ii[u]
        need0 = need1 = r0 = r1 = 0.0
        for k in range(npts):
            p = ROW_POINT + k * POINT_SIZE
            sep = row_separation(row, m, p, moved, nax, nay, nbx, nby)
            # how far the point is from allowed: a gap may close within the substep
            if k == 0:
                need0 = (-sep * inv_h if sep > 0.0 else 0.0) - vel0
                r0 = row[m, p0 + arm]
            else:
                need1 = (-sep * inv_h if sep > 0.0 else 0.0) - vel1
                r1 = row[m, p1 + arm]
        # impulses along the supported body's push direction, λ >= 0, that bring every
        # point to at least its target: the two-point case is a 2x2 complementarity
        # problem, solved by trying both points, then each alone
        l0 = l1 = 0.0
        k00 = mu + iu * r0 * r0
        if npts == 1:
            if need0 > 0.0 and k00 > 0.0:
                l0 = need0 / k00
        else:
            k11 = mu + iu * r1 * r1
            k01 = mu + iu * r0 * r1
            det = k00 * k11 - k01 * k01
            done = False
            if det > 1e-12 * k00 * k11:
                l0 = (k11 * need0 - k01 * need1) / det
                l1 = (k00 * need1 - k01 * need0) / det
                done = l0 >= 0.0 and l1 >= 0.0
            if not done:
                l0 = l1 = 0.0
                if need0 > 0.0 and k00 > 0.0 and k01 * need0 / k00 >= need1:
                    l0 = need0 / k00
                elif need1 > 0.0 and k11 > 0.0 and k01 * need1 / k11 >= need0:
                    l1 = need1 / k11
                elif need0 > 0.0 or need1 > 0.0:
                    # parallel arms (singular K): one impulse at the neediest point
                    if need0 >= need1 and k00 > 0.0:
                        l0 = need0 / k00
                    elif k11 > 0.0:
                        l1 = need1 / k11
        impulse = l0 + l1
        if impulse == 0.0:
            continue
        v[u, 0] += sgn * mu * impulse * nx
        v[u, 1] += sgn * mu * impulse * ny
        w[u] += sgn * iu * (l0 * r0 + l1 * r1)
