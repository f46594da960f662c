"""Contact solver: sequential impulses on soft contacts (the "soft step").

For a contact with normal n (from b towards a) and anchors r_a, r_b from the centres
of mass, the normal velocity is v_n = n · (v_a + ω_a × r_a − v_b − ω_b × r_b), and an
impulse λ n on a (−λ n on b) changes it by λ / m_eff with

    1 / m_eff = 1/m_a + 1/m_b + (r_a × n)²/I_a + (r_b × n)²/I_b.

Each substep warm-starts with the accumulated impulses, solves with a soft position
bias (a damped spring of CONTACT_HERTZ that pushes overlap out at no more than
CONTACT_PUSH_MAX_VELOCITY), moves the bodies, then relaxes without the bias so that
the push-out does not turn into velocity. A speculative point (separation s > 0)
lets the bodies approach by s in the substep and no further. Accumulated impulses
are clamped: λ_n >= 0 and |λ_t| <= μ λ_n (Coulomb). At the end of the substep in
which a point first pushes, restitution sets v_n⁺ = −e v_n⁻ if it was approaching
faster than the threshold (the restitution hypothesis), so one isolated contact
receives exactly γ = −(1 + e) m_eff v_n⁻. The approach speed is the one at impact,
not at the start of the step: a ball falling under gravity would otherwise lose
g·dt of speed at every bounce (see apply_restitution for the rest of that story).
"""

from __future__ import annotations

import math

from numba import njit

from ... import constants as C
from ...config import soft_parameters  # noqa: F401 (kept where it was)
from ...scene import types as T

# The solver's row of a manifold (contacts.solver_row, (M, ROW_SIZE) float64): what its
# passes read, in one record, so that a pass reads one row per manifold at fixed
# offsets instead of a dozen arrays (each with its own address arithmetic).
ROW_NX, ROW_NY = 0, 1  # the normal, from b towards a
ROW_K01 = 2  # 1/kg: the off-diagonal of the two points' normal block
ROW_GAMMA = 3  # γ/K of the soft constraint (impulse scale / mass scale)
ROW_BIAS_RATE = 4  # 1/s: the soft constraint's push-out rate
ROW_FRICTION = 5  # the mixed friction coefficient
ROW_POINT = 6  # point k's fields start at ROW_POINT + k POINT_SIZE
POINT_SIZE = 11
# offsets within a point: the lever arms r_a × n, r_b × n, r_a × t, r_b × t (m); the
# normal row's K (1/kg) and the tangent mass (kg); the anchors r_a, r_b (m); the base
# separation (m)
PT_RNA, PT_RNB, PT_RTA, PT_RTB, PT_KN, PT_TMASS = 0, 1, 2, 3, 4, 5
PT_RAX, PT_RAY, PT_RBX, PT_RBY, PT_BASE = 6, 7, 8, 9, 10
ROW_SIZE = 32  # 28 used, padded to four cache lines


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def normal_velocity(v, w, a, b, rax, ray, rbx, rby, nx, ny):
    """Relative normal velocity (m/s) of a's point at arm (rax, ray) against b's point
    at arm (rbx, rby), along the normal (nx, ny) from b towards a; < 0 approaching."""
    dvx = v[a, 0] - w[a] * ray - v[b, 0] + w[b] * rby
    dvy = v[a, 1] + w[a] * rax - v[b, 1] - w[b] * rbx
    return dvx * nx + dvy * ny


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def push_point(v, w, im, ii, a, b, rax, ray, rbx, rby, nx, ny, j):
    """Apply the normal impulse j (N·s) at a point with arms r_a, r_b (m): +j n on body
    a, −j n on body b (normal (nx, ny) from b towards a). Takes arrays (world.py's
    rule for helpers)."""
    px, py = j * nx, j * ny
    v[a, 0] += im[a] * px
    v[a, 1] += im[a] * py
    w[a] += ii[a] * (rax * py - ray * px)
    v[b, 0] -= im[b] * px
    v[b, 1] -= im[b] * py
    w[b] -= ii[b] * (rbx * py - rby * px)


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy", inline="always")
def approach_point(v, w, a, b, rax, ray, rbx, rby, nx, ny, base, m, k, approach, approach_sep):
    """Write point k of manifold m's approach velocity (m/s) and separation (m) at the
    start of the step: bodies a, b with velocities v, w, anchors r_a, r_b (m), normal
    n, base separations `base` (M,2). Takes arrays (world.py's rule for helpers)."""
    approach[m, k] = normal_velocity(v, w, a, b, rax, ray, rbx, rby, nx, ny)
    approach_sep[m, k] = base[m, k] + (nx * (rax - rbx) + ny * (ray - rby))


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def prepare_contacts(model, state, contacts, soft, soft_static):
    """Effective masses, approach velocities and softness of every contact point,
    written into the solver rows (contacts.solver_row; ROW_* and PT_* above).

    soft, soft_static: (mass scale, impulse scale, bias rate) for contacts between two
    dynamic bodies and for contacts with a static or kinematic body (stiffer).
    """
    c_anchor_a = contacts.anchor_a
    c_anchor_b = contacts.anchor_b
    c_approach_separation = contacts.approach_separation
    c_approach_velocity = contacts.approach_velocity
    c_base_separation = contacts.base_separation
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_friction = contacts.friction
    c_normal = contacts.normal
    c_normal_mass = contacts.normal_mass
    c_points = contacts.points
    row = contacts.solver_row
    c_carried = contacts.carried
    im, ii = model.body_inv_mass, model.body_inv_inertia
    v, w = state.body_v, state.body_w
    # γ/K of each soft constraint: mass scale K/(K+γ), impulse scale γ/(K+γ)
    gamma = soft[1] / soft[0] if soft[0] > 0.0 else 0.0
    gamma_static = soft_static[1] / soft_static[0] if soft_static[0] > 0.0 else 0.0
    for m in range(c_count[0]):
        a, b = c_body_a[m], c_body_b[m]
        nx, ny = c_normal[m, 0], c_normal[m, 1]
        if c_carried[m]:
            # last step's manifold in the same slot: its row holds all but the separation
            for k in range(c_points[m]):
                p = ROW_POINT + k * POINT_SIZE
                rax, ray = row[m, p + PT_RAX], row[m, p + PT_RAY]
                rbx, rby = row[m, p + PT_RBX], row[m, p + PT_RBY]
                row[m, p + PT_BASE] = c_base_separation[m, k]
                approach_point(v, w, a, b, rax, ray, rbx, rby, nx, ny, c_base_separation, m, k,
                               c_approach_velocity, c_approach_separation)  # fmt: skip
            continue
        ma, mb, ia, ib = im[a], im[b], ii[a], ii[b]
        tx, ty = ny, -nx
        row[m, ROW_NX], row[m, ROW_NY] = nx, ny
        if ma == 0.0 or mb == 0.0:
            row[m, ROW_GAMMA], row[m, ROW_BIAS_RATE] = gamma_static, soft_static[2]
        else:
            row[m, ROW_GAMMA], row[m, ROW_BIAS_RATE] = gamma, soft[2]
        row[m, ROW_FRICTION] = c_friction[m]
        for k in range(c_points[m]):
            p = ROW_POINT + k * POINT_SIZE
            rax, ray = c_anchor_a[m, k, 0], c_anchor_a[m, k, 1]
            rbx, rby = c_anchor_b[m, k, 0], c_anchor_b[m, k, 1]
            rna = rax * ny - ray * nx
            rnb = rbx * ny - rby * nx
            kn = ma + mb + ia * rna * rna + ib * rnb * rnb
            c_normal_mass[m, k] = 1.0 / kn if kn > 0.0 else 0.0
            rta = rax * ty - ray * tx
            rtb = rbx * ty - rby * tx
            kt = ma + mb + ia * rta * rta + ib * rtb * rtb
            row[m, p + PT_RNA], row[m, p + PT_RNB] = rna, rnb
            row[m, p + PT_RTA], row[m, p + PT_RTB] = rta, rtb
            row[m, p + PT_KN] = kn
            row[m, p + PT_TMASS] = 1.0 / kt if kt > 0.0 else 0.0
            row[m, p + PT_RAX], row[m, p + PT_RAY] = rax, ray
            row[m, p + PT_RBX], row[m, p + PT_RBY] = rbx, rby
            row[m, p + PT_BASE] = c_base_separation[m, k]
            approach_point(v, w, a, b, rax, ray, rbx, rby, nx, ny, c_base_separation, m, k,
                           c_approach_velocity, c_approach_separation)  # fmt: skip
        if c_points[m] == 2:
            p0, p1 = ROW_POINT, ROW_POINT + POINT_SIZE
            k01 = ma + mb + ia * row[m, p0 + PT_RNA] * row[m, p1 + PT_RNA]
            row[m, ROW_K01] = k01 + ib * row[m, p0 + PT_RNB] * row[m, p1 + PT_RNB]


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def warm_start(model, state, contacts):
    """Apply last substep's accumulated impulses again (they are impulses per substep)."""
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_normal_impulse = contacts.normal_impulse
    c_points = contacts.points
    c_tangent_impulse = contacts.tangent_impulse
    row = contacts.solver_row
    im, ii = model.body_inv_mass, model.body_inv_inertia
    v, w = state.body_v, state.body_w
    for m in range(c_count[0]):
        a, b = c_body_a[m], c_body_b[m]
        nx, ny = row[m, ROW_NX], row[m, ROW_NY]
        tx, ty = ny, -nx
        px = py = ta = tb = 0.0
        for k in range(c_points[m]):
            p = ROW_POINT + k * POINT_SIZE
            jn, jt = c_normal_impulse[m, k], c_tangent_impulse[m, k]
            px += jn * nx + jt * tx
            py += jn * ny + jt * ty
            ta += jn * row[m, p + PT_RNA] + jt * row[m, p + PT_RTA]
            tb += jn * row[m, p + PT_RNB] + jt * row[m, p + PT_RTB]
        ma, mb, ia, ib = im[a], im[b], ii[a], ii[b]
        if ma != 0.0 or ia != 0.0:  # a fixed body is not written (see solve_contacts)
            v[a, 0] += ma * px
            v[a, 1] += ma * py
            w[a] += ia * ta
        if mb != 0.0 or ib != 0.0:
            v[b, 0] -= mb * px
            v[b, 1] -= mb * py
            w[b] -= ib * tb


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy", inline="always")
def row_separation(row, m, p, moved, nax, nay, nbx, nby):
    """Separation now (m) of the point whose fields start at offset p of manifold m's
    solver row: n · (d_a − d_b + R_a r_a − R_b r_b) + base, with the normal turned back
    into each body's start frame (nax, nay and nbx, nby) instead of each anchor forward,
    and moved = n · (d_a − d_b) (m). Takes arrays (world.py's rule for helpers)."""
    s = moved + row[m, p + PT_BASE]
    s += nax * row[m, p + PT_RAX] + nay * row[m, p + PT_RAY]
    s -= nbx * row[m, p + PT_RBX] + nby * row[m, p + PT_RBY]
    return s


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy", inline="always")
def soft_target(s, use_bias, inv_h, bias_rate, max_push, kn, soft_gamma):
    """(bias m/s, γ 1/kg) of a point at separation s (m) with normal row K = kn (1/kg).

    A gap (s > 0) may close in the substep, no more (speculative); an overlap is pushed
    out softly in the solve stage (use_bias), as the regularised constraint
    (K + γ) Δλ = −(vn + b) − γλ with b = max(bias_rate s, max_push) (1/s, m/s) and
    γ = soft_gamma K, and not at all in the relax stage. inv_h: 1 / substep (1/s).
    Written as selects, not branches: whether a resting point's s is just above or
    just below zero is a coin toss the processor would often guess wrong."""
    push = use_bias and s <= 0.0
    bias = s * inv_h if s > 0.0 else 0.0
    bias = max(bias_rate * s, max_push) if push else bias
    gamma = kn * soft_gamma if push else 0.0
    return bias, gamma


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy", inline="always")
def clamp_normal(lam_arr, max_arr, approach, approach_sep, bounce_list, count, m, k, lam,
                 impulse, vn, s, shift, threshold):  # fmt: skip
    """Apply the clamp λ >= 0 to point k of manifold m, whose accumulated normal impulse
    is lam (N·s) and whose solve asks for `impulse` (N·s) at normal velocity vn (m/s)
    and separation s (m); returns the impulse applied. A point that engages (its first
    push this step, or the first after a bounce) records its approach (see
    solve_contacts). Takes arrays (world.py's rule for helpers)."""
    # (the rarely true test first: whether a resting point's impulse is positive is a
    # coin toss, and a branch on it would often be mispredicted)
    engaged = max_arr[m, k] > 0.0
    if (not engaged or approach[m, k] == math.inf) and impulse > 0.0:
        # the point engages: its approach speed at impact, which gravity may have
        # raised since the start of the step. Later approaches of an engaged point are
        # the solver's own doing (a warm start re-applying an impact impulse) and are
        # not recorded; after a bounce (approach set to inf) a new impact is
        approach[m, k] = vn
        approach_sep[m, k] = s - shift * vn
        if vn < -threshold:  # a bounce for the restitution stage's list
            bounce_list[count[5]] = m
            count[5] += 1
    new = max(lam + impulse, 0.0)  # clamp the accumulated impulse
    impulse = new - lam
    lam_arr[m, k] = new
    max_arr[m, k] = max(max_arr[m, k], impulse)
    return impulse


@njit(cache=True, _nrt=False, inline="always")
def mark_deep(count, relax_list, m):
    """List manifold m in relax_list as having a deep overlap (count[6] entries; once
    the list is full it stays at its length, which means every manifold)."""
    if count[6] < relax_list.shape[0]:
        relax_list[count[6]] = m
        count[6] += 1


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def solve_contacts(model, state, contacts, inv_h, use_bias, shift, threshold, order, n):
    """One sequential-impulse pass (normal, then friction) over the manifolds order[:n]:
    contacts.solve_order (ground first, shock.support_order) or a part of it.

    inv_h: 1 / substep length (1/s). use_bias: True in the solve stage (soft position
    correction), False in the relax stage (rigid, no push-out). shift (s): how far
    back the separation is to be taken when a point engages, so that the recorded
    (separation, velocity) is the state before this substep's position update: the
    substep length in the relax stage of symplectic Euler, else 0. threshold (m/s): the
    restitution threshold; a point that engages faster than it enters its manifold in
    bounce_list (count[5] entries), which the restitution stage works through. A
    manifold with a point that overlaps deeper than DEEP_OVERLAP in the solve stage
    enters relax_list (count[6] entries).
    """
    c_approach_separation = contacts.approach_separation
    c_approach_velocity = contacts.approach_velocity
    c_bounce_list = contacts.bounce_list
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_max_normal_impulse = contacts.max_normal_impulse
    c_normal_impulse = contacts.normal_impulse
    c_points = contacts.points
    c_tangent_impulse = contacts.tangent_impulse
    row = contacts.solver_row
    im, ii = model.body_inv_mass, model.body_inv_inertia
    v, w = state.body_v, state.body_w
    delta = contacts.body_delta
    max_push = -C.CONTACT_PUSH_MAX_VELOCITY
    deep = -C.DEEP_OVERLAP
    relax_list = contacts.relax_list
    for o in range(n):
        m = order[o]
        a, b = c_body_a[m], c_body_b[m]
        ma, mb, ia, ib = im[a], im[b], ii[a], ii[b]
        vax, vay, wa = v[a, 0], v[a, 1], w[a]
        vbx, vby, wb = v[b, 0], v[b, 1], w[b]
        nx, ny = row[m, ROW_NX], row[m, ROW_NY]
        tx, ty = ny, -nx
        # body motion since the start of the step, for the current separation
        dax, day, ca, sa = delta[a, 0], delta[a, 1], delta[a, 2], delta[a, 3]
        dbx, dby, cb, sb = delta[b, 0], delta[b, 1], delta[b, 2], delta[b, 3]
        soft_gamma, bias_rate = row[m, ROW_GAMMA], row[m, ROW_BIAS_RATE]
        npts = c_points[m]
        moved = nx * (dax - dbx) + ny * (day - dby)
        nax, nay = ca * nx + sa * ny, ca * ny - sa * nx
        nbx, nby = cb * nx + sb * ny, cb * ny - sb * nx
        if npts == 1:
            # one point (circles, capsule ends): the two-point solve below with the
            # second point's terms dropped, so that it does not pay for them (the
            # circles' solve went from 180 to 150 µs per step against the loop over
            # points that both replace)
            p = ROW_POINT
            s = row_separation(row, m, p, moved, nax, nay, nbx, nby)
            kn = row[m, p + PT_KN]
            bias, gamma = soft_target(s, use_bias, inv_h, bias_rate, max_push, kn, soft_gamma)
            if use_bias and s < deep:
                mark_deep(c_count, relax_list, m)
            rna, rnb = row[m, p + PT_RNA], row[m, p + PT_RNB]
            rta, rtb = row[m, p + PT_RTA], row[m, p + PT_RTB]
            dvx, dvy = vax - vbx, vay - vby
            vn = (dvx * nx + dvy * ny) + (wa * rna - wb * rnb)
            vt = (dvx * tx + dvy * ty) + (wa * rta - wb * rtb)
            lam = c_normal_impulse[m, 0]
            impulse = (-vn - (bias + gamma * lam)) * (1.0 / (kn + gamma))
            jn = clamp_normal(c_normal_impulse, c_max_normal_impulse, c_approach_velocity,
                              c_approach_separation, c_bounce_list, c_count, m, 0, lam,
                              impulse, vn, s, shift, threshold)  # fmt: skip
            jt = 0.0
            mu = row[m, ROW_FRICTION]
            lam = c_tangent_impulse[m, 0]
            limit = mu * c_normal_impulse[m, 0]
            if mu > 0.0 and not (limit == 0.0 and lam == 0.0):
                vt += jn * (ia * rna * rta + ib * rnb * rtb)
                new = min(max(lam - row[m, p + PT_TMASS] * vt, -limit), limit)
                jt = new - lam
                c_tangent_impulse[m, 0] = new
            px, py = jn * nx + jt * tx, jn * ny + jt * ty
            if ma != 0.0 or ia != 0.0:
                v[a, 0], v[a, 1] = vax + ma * px, vay + ma * py
                w[a] = wa + ia * (jn * rna + jt * rta)
            if mb != 0.0 or ib != 0.0:
                v[b, 0], v[b, 1] = vbx - mb * px, vby - mb * py
                w[b] = wb - ib * (jn * rnb + jt * rtb)
            continue
        # two points (every manifold has one or two)
        p0, p1 = ROW_POINT, ROW_POINT + POINT_SIZE
        s0 = row_separation(row, m, p0, moved, nax, nay, nbx, nby)
        s1 = row_separation(row, m, p1, moved, nax, nay, nbx, nby)
        kn0, kn1 = row[m, p0 + PT_KN], row[m, p1 + PT_KN]
        b0, g0 = soft_target(s0, use_bias, inv_h, bias_rate, max_push, kn0, soft_gamma)
        b1, g1 = soft_target(s1, use_bias, inv_h, bias_rate, max_push, kn1, soft_gamma)
        if use_bias and min(s0, s1) < deep:
            mark_deep(c_count, relax_list, m)
        rna0, rnb0 = row[m, p0 + PT_RNA], row[m, p0 + PT_RNB]
        rta0, rtb0 = row[m, p0 + PT_RTA], row[m, p0 + PT_RTB]
        rna1, rnb1 = row[m, p1 + PT_RNA], row[m, p1 + PT_RNB]
        rta1, rtb1 = row[m, p1 + PT_RTA], row[m, p1 + PT_RTB]
        # sums grouped as two halves: each pass is one long chain of dependent
        # arithmetic through the body velocities, and a shallow sum shortens it
        dvx, dvy = vax - vbx, vay - vby
        vn0 = (dvx * nx + dvy * ny) + (wa * rna0 - wb * rnb0)
        vn1 = (dvx * nx + dvy * ny) + (wa * rna1 - wb * rnb1)
        vt0 = (dvx * tx + dvy * ty) + (wa * rta0 - wb * rtb0)
        vt1 = (dvx * tx + dvy * ty) + (wa * rta1 - wb * rtb1)
        lam0, lam1 = c_normal_impulse[m, 0], c_normal_impulse[m, 1]
        # both points as one 2x2 block, so that a face held at two points gets
        # mirror-image impulses (solved one after the other they would leave a spin that
        # friction turns into a sideways drift); one point at a time if a clamp is hit
        k00, k11, k01 = kn0 + g0, kn1 + g1, row[m, ROW_K01]
        det = k00 * k11 - k01 * k01
        block = False
        d0 = d1 = 0.0
        if det > 1.0e-9 * k00 * k11:
            r0 = -vn0 - (b0 + g0 * lam0)  # the bracket is off the chain
            r1 = -vn1 - (b1 + g1 * lam1)
            inv_det = 1.0 / det  # known before the velocities: a product on the chain
            d0 = (k11 * r0 - k01 * r1) * inv_det
            d1 = (k00 * r1 - k01 * r0) * inv_det
            block = lam0 + d0 >= 0.0 and lam1 + d1 >= 0.0
        # the velocities change once, at the end, by the sum of the manifold's impulses.
        # On the way, a point's velocity is its value at the start plus what the
        # impulses so far did to it, through the coupling of their rows: a shorter
        # chain of dependent arithmetic than updating the velocities after each impulse.
        # 1 / (K + γ) does not wait for the velocities: a product on the chain
        if not block:
            d0 = (-vn0 - (b0 + g0 * lam0)) * (1.0 / (kn0 + g0))
        j0 = clamp_normal(c_normal_impulse, c_max_normal_impulse, c_approach_velocity,
                          c_approach_separation, c_bounce_list, c_count, m, 0, lam0, d0,
                          vn0, s0, shift, threshold)  # fmt: skip
        if not block:
            vn1 += j0 * k01
            d1 = (-vn1 - (b1 + g1 * lam1)) * (1.0 / (kn1 + g1))
        j1 = clamp_normal(c_normal_impulse, c_max_normal_impulse, c_approach_velocity,
                          c_approach_separation, c_bounce_list, c_count, m, 1, lam1, d1,
                          vn1, s1, shift, threshold)  # fmt: skip
        f0 = f1 = 0.0  # the friction impulses applied
        mu = row[m, ROW_FRICTION]
        if mu > 0.0:
            # the normal impulses turn the bodies (n · t = 0: they add no sliding)
            lam = c_tangent_impulse[m, 0]
            limit = mu * c_normal_impulse[m, 0]
            if not (limit == 0.0 and lam == 0.0):  # no normal force, no friction
                vt0 += j0 * (ia * rna0 * rta0 + ib * rnb0 * rtb0)
                vt0 += j1 * (ia * rna1 * rta0 + ib * rnb1 * rtb0)
                new = min(max(lam - row[m, p0 + PT_TMASS] * vt0, -limit), limit)
                f0 = new - lam
                c_tangent_impulse[m, 0] = new
            lam = c_tangent_impulse[m, 1]
            limit = mu * c_normal_impulse[m, 1]
            if not (limit == 0.0 and lam == 0.0):
                vt1 += j0 * (ia * rna0 * rta1 + ib * rnb0 * rtb1)
                vt1 += j1 * (ia * rna1 * rta1 + ib * rnb1 * rtb1)
                vt1 += f0 * (ma + mb + ia * rta0 * rta1 + ib * rtb0 * rtb1)
                new = min(max(lam - row[m, p1 + PT_TMASS] * vt1, -limit), limit)
                f1 = new - lam
                c_tangent_impulse[m, 1] = new
        jn, jt = j0 + j1, f0 + f1
        px, py = jn * nx + jt * tx, jn * ny + jt * ty
        vax += ma * px
        vay += ma * py
        wa += ia * ((j0 * rna0 + j1 * rna1) + (f0 * rta0 + f1 * rta1))
        vbx -= mb * px
        vby -= mb * py
        wb -= ib * ((j0 * rnb0 + j1 * rnb1) + (f0 * rtb0 + f1 * rtb1))
        # a static or kinematic body's velocity is unchanged: not written back, so that
        # the next manifold on it need not wait for this one
        if ma != 0.0 or ia != 0.0:
            v[a, 0], v[a, 1], w[a] = vax, vay, wa
        if mb != 0.0 or ib != 0.0:
            v[b, 0], v[b, 1], w[b] = vbx, vby, wb


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def point_separation(anchor_a, anchor_b, base_separation, delta, m, k, a, b, nx, ny):
    """Separation (m) now of point k of manifold m between bodies a and b with normal
    (nx, ny): its anchors moved by delta (each body's motion since the step began).
    Takes arrays, not the tuples (world.py's rule for helpers called per point)."""
    ca, sa, cb, sb = delta[a, 2], delta[a, 3], delta[b, 2], delta[b, 3]
    rax, ray = anchor_a[m, k, 0], anchor_a[m, k, 1]
    rbx, rby = anchor_b[m, k, 0], anchor_b[m, k, 1]
    pax, pay = ca * rax - sa * ray, sa * rax + ca * ray
    pbx, pby = cb * rbx - sb * rby, sb * rbx + cb * rby
    s = (delta[a, 0] - delta[b, 0] + pax - pbx) * nx + (delta[a, 1] - delta[b, 1] + pay - pby) * ny
    return s + base_separation[m, k]


# bounce_kind of a manifold in the restitution stage
_QUIET = 0  # no point pushes or bounces
_ALONE = 1  # bounces, e > 0, and touches no body that anything else pushes: redone exactly
_JOINED = 2  # bounces within a cluster that also has resting or inelastic contacts
_PUSHING = 3  # pushes without bouncing (a resting or slow contact)
_PASSIVE = 4  # elastic, pushed slowly, no load carried in: joins a lone cluster it touches


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def bounce_target(invariant, s_now, acc, e, h, sign):
    """The normal velocity (m/s) after a bounce of coefficient e: the one that makes
    the discrete trajectory's invariant at separation s_now (m) e² times `invariant`
    (m²/s², see apply_restitution), with relative normal acceleration acc (m/s²),
    substep h (s), sign +1 for symplectic and -1 for explicit Euler."""
    ah = sign * acc * h
    rhs = e * e * invariant + acc * s_now
    return 0.5 * (-ah + math.sqrt(max(ah * ah + 8.0 * rhs, 0.0)))


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def push_targets(bodies, rows, m, a, b, need0, t0, need1, t1, single, owed):
    """Raise the normal velocity of manifold m's points to their targets t0, t1 (m/s)
    where need0, need1, by impulses added to normal_impulse (kept >= 0). bodies is
    (v, w, inverse mass, inverse inertia), rows (anchor_a, anchor_b, normal,
    normal_mass, normal_impulse), all arrays (world.py's rule for per-manifold
    helpers). Both points at once are one 2x2 block (a box landing flat gets
    mirror-image impulses; one after the other would tip it). When the block would
    pull, one point at a time; with `single`, only the point furthest below its
    target (the caller comes back for the other with a target from its velocity
    then: the first point's impulse changes it). Returns the impulses (N·s) applied
    at the two points.

    owed = (work, e², h·sign·acc, u0, u1): energy (J) that the impact must return
    besides the bounce, for the restitution stage (see apply_restitution; zeros
    elsewhere). The block then raises both targets by the same c for which its
    impulses do e² times that work; a single point takes u0 or u1, its own target
    with its own share of the work."""
    v, w, im, ii = bodies
    anchor_a, anchor_b, normal, normal_mass, normal_impulse = rows
    nx, ny = normal[m, 0], normal[m, 1]
    if need0 and need1:
        r0ax, r0ay = anchor_a[m, 0, 0], anchor_a[m, 0, 1]
        r0bx, r0by = anchor_b[m, 0, 0], anchor_b[m, 0, 1]
        r1ax, r1ay = anchor_a[m, 1, 0], anchor_a[m, 1, 1]
        r1bx, r1by = anchor_b[m, 1, 0], anchor_b[m, 1, 1]
        ca0, cb0 = r0ax * ny - r0ay * nx, r0bx * ny - r0by * nx
        ca1, cb1 = r1ax * ny - r1ay * nx, r1bx * ny - r1by * nx
        k11 = im[a] + im[b] + ii[a] * ca0 * ca0 + ii[b] * cb0 * cb0
        k22 = im[a] + im[b] + ii[a] * ca1 * ca1 + ii[b] * cb1 * cb1
        k12 = im[a] + im[b] + ii[a] * ca0 * ca1 + ii[b] * cb0 * cb1
        det = k11 * k22 - k12 * k12
        if det > 1.0e-9 * k11 * k22:
            vn0 = normal_velocity(v, w, a, b, r0ax, r0ay, r0bx, r0by, nx, ny)
            vn1 = normal_velocity(v, w, a, b, r1ax, r1ay, r1bx, r1by, nx, ny)
            d0, d1 = t0 - vn0, t1 - vn1
            j0 = (k22 * d0 - k12 * d1) / det
            j1 = (k11 * d1 - k12 * d0) / det
            work, e2, hsa = owed[0], owed[1], owed[2]
            if work != 0.0:
                # impulses j + c q (q = K⁻¹ 1) do ΔE(c) = ΔE(0) + L c + B c² / 2
                q0, q1 = (k22 - k12) / det, (k11 - k12) / det
                big_b = q0 + q1
                big_l = 0.5 * (q0 * (vn0 + t0) + q1 * (vn1 + t1) + j0 + j1 + hsa * big_b)
                disc = big_l * big_l + 2.0 * big_b * e2 * work
                if big_l > 0.0 and disc >= 0.0:
                    c = 2.0 * e2 * work / (big_l + math.sqrt(disc))
                    j0 += c * q0
                    j1 += c * q1
            if normal_impulse[m, 0] + j0 >= 0.0 and normal_impulse[m, 1] + j1 >= 0.0:
                normal_impulse[m, 0] += j0
                normal_impulse[m, 1] += j1
                px, py = (j0 + j1) * nx, (j0 + j1) * ny
                v[a, 0] += im[a] * px
                v[a, 1] += im[a] * py
                w[a] += ii[a] * (j0 * ca0 + j1 * ca1)
                v[b, 0] -= im[b] * px
                v[b, 1] -= im[b] * py
                w[b] -= ii[b] * (j0 * cb0 + j1 * cb1)
                return j0, j1
    j0 = j1 = 0.0
    t0, t1 = owed[3], owed[4]
    if single and need0 and need1:
        d0 = t0 - normal_velocity(
            v, w, a, b, anchor_a[m, 0, 0], anchor_a[m, 0, 1], anchor_b[m, 0, 0],
            anchor_b[m, 0, 1], nx, ny,
        )  # fmt: skip
        d1 = t1 - normal_velocity(
            v, w, a, b, anchor_a[m, 1, 0], anchor_a[m, 1, 1], anchor_b[m, 1, 0],
            anchor_b[m, 1, 1], nx, ny,
        )  # fmt: skip
        if d0 >= d1:
            need1 = False
        else:
            need0 = False
    for k in range(2):
        if not (need0 if k == 0 else need1):
            continue
        rax, ray = anchor_a[m, k, 0], anchor_a[m, k, 1]
        rbx, rby = anchor_b[m, k, 0], anchor_b[m, k, 1]
        vn = normal_velocity(v, w, a, b, rax, ray, rbx, rby, nx, ny)
        lam = normal_impulse[m, k]
        new = max(lam - normal_mass[m, k] * (vn - (t0 if k == 0 else t1)), 0.0)
        impulse = new - lam
        normal_impulse[m, k] = new
        push_point(v, w, im, ii, a, b, rax, ray, rbx, rby, nx, ny, impulse)
        if k == 0:
            j0 = impulse
        else:
            j1 = impulse
    return j0, j1


@njit(cache=True, _nrt=False)
def keep_solve_impulses(contacts):
    """Copy each point's accumulated normal impulse (N·s) to solve_impulse: the push
    that the positions move with this substep (see apply_restitution)."""
    c_normal_impulse = contacts.normal_impulse
    c_solve_impulse = contacts.solve_impulse
    for m in range(contacts.count[0]):
        c_solve_impulse[m, 0] = c_normal_impulse[m, 0]
        c_solve_impulse[m, 1] = c_normal_impulse[m, 1]


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def apply_restitution(model, state, contacts, threshold, h, sign):
    """Bounce: v_n⁺ from v_n⁻ by the restitution hypothesis, at points that engaged in
    this substep approaching faster than `threshold` (m/s). Run after every substep,
    so that impacts follow each other in order. A bouncing point's accumulated impulse
    is dropped afterwards (what it carried into the step, a resting load, it keeps), so
    that later substeps do not warm-start the bounce a second time.

    Without forces the target is exactly v_n⁺ = −e v_n⁻. Under a constant relative
    normal acceleration a (gravity, constant forces) the target is taken on the
    discrete trajectory instead: Euler with substep h (s) conserves not the energy but
    I = v²/2 − a s + sign (a h / 2) v (sign +1 symplectic, −1 explicit Euler), and
    reversing v alone would lose or gain about |a| h |v| per bounce. So v_n⁺ makes
    I after the bounce (at the current separation) equal e² times I where the point
    engaged. For e = 1 a ball then keeps its apex bounce after bounce, to round-off.

    Impacts that share a body within a substep (a ball struck by two others, a ball
    hitting a wall while another hits it, a row of touching balls struck at one end)
    are where energy went: the solve treats them as one inelastic impact, and each
    point's approach was recorded mid-pass, after its neighbours had pushed. So a
    cluster of bouncing points (e > 0) whose bodies nothing else pushes is done again
    exactly: the substep's impulses at its points are taken back, which leaves each
    point's true approach velocity, and the impacts are then resolved one pair at a
    time, in passes, each a bounce against the point's velocity at that moment, until
    no point of the cluster approaches (a point struck again within the substep, as
    in the row of balls, bounces again; one that approaches slower than the threshold
    is only stopped). The cluster also takes in elastic points that pushed slower than
    the threshold and carried no load into the step: in a touching row struck at one
    end, the solve's joint push engages them at a fraction of the striker's speed. A
    pair's bounce with e = 1 keeps the kinetic energy exactly, so the cluster does.
    After RESTITUTION_PASSES passes what still approaches is left to the next
    substep's solve. Clusters that also hold resting contacts (a ball landing on a
    stack) keep the solve's impulses and get the targets from the recorded approach.
    """
    c_anchor_a = contacts.anchor_a
    c_anchor_b = contacts.anchor_b
    c_approach_separation = contacts.approach_separation
    c_start_impulse = contacts.start_impulse
    c_approach_velocity = contacts.approach_velocity
    c_base_separation = contacts.base_separation
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_max_normal_impulse = contacts.max_normal_impulse
    c_normal = contacts.normal
    c_normal_impulse = contacts.normal_impulse
    c_normal_mass = contacts.normal_mass
    c_points = contacts.points
    c_restitution = contacts.restitution
    c_order = contacts.solve_order
    c_solve_impulse = contacts.solve_impulse
    kind = contacts.bounce_kind
    mark = contacts.body_mark
    c_bounce_list = contacts.bounce_list
    m_body_force = model.body_force
    m_body_type = model.body_type
    m_gravity = model.gravity
    im, ii = model.body_inv_mass, model.body_inv_inertia
    v, w = state.body_v, state.body_w
    delta = contacts.body_delta
    gx, gy = m_gravity[0], m_gravity[1]
    bodies = (v, w, im, ii)
    rows = (c_anchor_a, c_anchor_b, c_normal, c_normal_mass, c_normal_impulse)
    n_listed = c_count[5]
    if n_listed == c_count[8]:
        return  # no point engaged faster than the threshold since the last call
    c_count[5] = c_count[8] = 0
    n_man = c_count[0]
    # the manifolds that bounce are listed (some twice), after those left for later
    # below; while none in this step was elastic, each is ended on its own (in index
    # order, as in the full pass) and nothing else needs a look
    for i in range(n_listed):
        if c_restitution[c_bounce_list[i]] > 0.0:
            c_count[9] = 1
    elastic_listed = c_count[9] == 1
    if not elastic_listed:
        for i in range(n_listed):
            kind[c_bounce_list[i]] = _JOINED
    # which manifolds bounce, and which bodies something else pushes (mark bit 1)
    if elastic_listed:
        mark[:] = 0
    n_alone = 0
    for m in range(n_man if elastic_listed else 0):
        bouncing = joining = pushing = 0
        elastic = c_restitution[m] > 0.0
        for k in range(c_points[m]):
            if c_approach_velocity[m, k] < -threshold and c_max_normal_impulse[m, k] > 0.0:
                bouncing += 1
            elif c_normal_impulse[m, k] > 0.0:
                # pushed, slower than the threshold: in an elastic contact that carried
                # no load into the step, it may be a passive part of an impact (a ball
                # of a touching row, engaged only by its neighbour's push)
                if elastic and c_start_impulse[m, k] == 0.0:
                    joining += 1
                else:
                    pushing += 1
        if pushing == 0 and (bouncing > 0 or joining > 0) and elastic:
            kind[m] = _ALONE if bouncing > 0 else _PASSIVE
            n_alone += 1
            continue
        if bouncing > 0:
            kind[m] = _JOINED
        else:
            kind[m] = _PUSHING if pushing + joining > 0 else _QUIET
        if kind[m] != _QUIET:
            mark[c_body_a[m]] |= 1
            mark[c_body_b[m]] |= 1
    # a cluster that touches a pushed body joins it (until nothing changes)
    changed = n_alone > 0
    while changed:
        changed = False
        for m in range(n_man):
            if kind[m] != _ALONE and kind[m] != _PASSIVE:
                continue
            a, b = c_body_a[m], c_body_b[m]
            if (mark[a] & 1 and im[a] > 0.0) or (mark[b] & 1 and im[b] > 0.0):
                kind[m] = _JOINED if kind[m] == _ALONE else _PUSHING
                mark[a] |= 1
                mark[b] |= 1
                n_alone -= 1
                changed = True
    # passive points take part only in a cluster that holds a bounce (mark bit 2: the
    # body is reached from one); the others stay as the solve left them
    if n_alone > 0:
        for m in range(n_man):
            if kind[m] == _ALONE:
                mark[c_body_a[m]] |= 2
                mark[c_body_b[m]] |= 2
        changed = True
        while changed:
            changed = False
            for m in range(n_man):
                if kind[m] != _PASSIVE:
                    continue
                a, b = c_body_a[m], c_body_b[m]
                if (mark[a] & 2 and im[a] > 0.0) or (mark[b] & 2 and im[b] > 0.0):
                    kind[m] = _ALONE
                    mark[a] |= 2
                    mark[b] |= 2
                    changed = True
    for m in range(n_man):
        if kind[m] == _ALONE:
            # take back this substep's impulses at the cluster's points
            a, b = c_body_a[m], c_body_b[m]
            nx, ny = c_normal[m, 0], c_normal[m, 1]
            for k in range(c_points[m]):
                j = c_normal_impulse[m, k]
                c_normal_impulse[m, k] = 0.0
                rax, ray = c_anchor_a[m, k, 0], c_anchor_a[m, k, 1]
                rbx, rby = c_anchor_b[m, k, 0], c_anchor_b[m, k, 1]
                push_point(v, w, im, ii, a, b, rax, ray, rbx, rby, nx, ny, -j)
            continue
        if kind[m] != _JOINED:
            continue
        if not elastic_listed:
            kind[m] = _QUIET  # the next call's list starts clean
        a, b = c_body_a[m], c_body_b[m]
        e = c_restitution[m]
        nx, ny = c_normal[m, 0], c_normal[m, 1]
        acc = _relative_acceleration(m_body_type, m_body_force, im, gx, gy, a, b, nx, ny)
        t0 = t1 = 0.0
        bounce0 = bounce1 = deferred = False
        for k in range(c_points[m]):
            vn0 = c_approach_velocity[m, k]
            if vn0 >= -threshold or c_max_normal_impulse[m, k] == 0.0:
                continue
            s_now = point_separation(
                c_anchor_a, c_anchor_b, c_base_separation, delta, m, k, a, b, nx, ny
            )
            if s_now > C.SPECULATIVE_DISTANCE and e == 0.0:
                # engaged through a speculative push while still far apart (a fast
                # body one substep from a wall). With e = 0, ending the approach now
                # would stop it short by up to a substep's travel: leave it to the
                # solver, which stops it where the bodies meet, if the speculative
                # separation can be trusted that far: it is linear in the motion, so
                # a turning body's arc leaves it by about |r| (ω h)² / 2 per substep.
                # Closer, or turning faster, the impact is ended here, exactly by the
                # formula above. (With e > 0 the bounce is taken now, a little early,
                # so that the energy it returns is exact.)
                ta, tb = w[a] * h, w[b] * h
                rax, ray = c_anchor_a[m, k, 0], c_anchor_a[m, k, 1]
                rbx, rby = c_anchor_b[m, k, 0], c_anchor_b[m, k, 1]
                arc = ta * ta * math.sqrt(rax * rax + ray * ray)
                arc += tb * tb * math.sqrt(rbx * rbx + rby * rby)
                if 0.5 * arc < C.LINEAR_SLOP:
                    deferred = True
                    continue
            # one bounce per impact; should the bodies meet again within the step, the
            # point engages afresh (see solve_contacts) and records its new approach
            c_approach_velocity[m, k] = math.inf
            s0 = c_approach_separation[m, k]
            invariant = 0.5 * vn0 * vn0 - 0.5 * acc * h * vn0 - acc * s0
            target = bounce_target(invariant, s_now, acc, e, h, sign)
            if k == 0:
                bounce0, t0 = True, target
            else:
                bounce1, t1 = True, target
        if deferred:  # looked at again when the stage next has something to do
            c_bounce_list[c_count[5]] = m
            c_count[5] += 1
        if not (bounce0 or bounce1):
            continue
        owed = (0.0, 0.0, 0.0, t0, t1)
        j0, j1 = push_targets(bodies, rows, m, a, b, bounce0, t0, bounce1, t1, False, owed)
        for k in range(c_points[m]):
            jk = j0 if k == 0 else j1
            c_max_normal_impulse[m, k] = max(c_max_normal_impulse[m, k], jk)
            if bounce0 if k == 0 else bounce1:
                c_normal_impulse[m, k] = min(c_normal_impulse[m, k], c_start_impulse[m, k])
    c_count[8] = c_count[5]  # the deferred ones, carried to the next call
    if n_alone == 0:
        return
    # the lone clusters, one pair's impact at a time
    for _ in range(C.RESTITUTION_PASSES):
        struck = False
        for o in range(n_man):
            m = c_order[o]
            if kind[m] != _ALONE:
                continue
            a, b = c_body_a[m], c_body_b[m]
            e = c_restitution[m]
            nx, ny = c_normal[m, 0], c_normal[m, 1]
            acc = _relative_acceleration(m_body_type, m_body_force, im, gx, gy, a, b, nx, ny)
            t0 = t1 = u0 = u1 = total_work = 0.0
            need0 = need1 = False
            for k in range(c_points[m]):
                rax, ray = c_anchor_a[m, k, 0], c_anchor_a[m, k, 1]
                rbx, rby = c_anchor_b[m, k, 0], c_anchor_b[m, k, 1]
                vn = normal_velocity(v, w, a, b, rax, ray, rbx, rby, nx, ny)
                if vn >= 0.0:
                    continue
                first = c_approach_velocity[m, k] < -threshold
                if first or vn < -threshold:
                    s_now = point_separation(
                        c_anchor_a, c_anchor_b, c_base_separation, delta, m, k, a, b, nx, ny
                    )
                    # the invariant here and now; at its first impact the point also
                    # owes the work gravity did on the bodies' centres over the part
                    # of the substep's motion that its own solve impulse caused
                    # (symplectic Euler moves the positions after the solve; explicit
                    # Euler before it, which owes nothing)
                    invariant = 0.5 * vn * vn + 0.5 * sign * acc * h * vn - acc * s_now
                    target = bounce_target(invariant, s_now, acc, e, h, sign)
                    work = 0.0
                    if first and sign > 0.0:
                        work = acc * h * c_solve_impulse[m, k]  # J
                    alone = target
                    if work != 0.0:  # per unit effective mass, for the point alone
                        invariant += work / c_normal_mass[m, k]
                        alone = bounce_target(invariant, s_now, acc, e, h, sign)
                else:
                    target = alone = work = 0.0
                total_work += work
                if k == 0:
                    need0, t0, u0 = True, target, alone
                else:
                    need1, t1, u1 = True, target, alone
            if not (need0 or need1):
                continue
            # each impulse is a bounce against the velocity it meets (a block's two
            # targets are both taken from the velocities before it): e = 1 keeps the
            # energy exactly, and a point left for later is taken up in the next pass
            owed = (total_work, e * e, sign * h * acc, u0, u1)
            j0, j1 = push_targets(bodies, rows, m, a, b, need0, t0, need1, t1, True, owed)
            for k in range(c_points[m]):
                jk = j0 if k == 0 else j1
                bounced = (need0 if k == 0 else need1) and jk != 0.0
                if bounced and (u0 if k == 0 else u1) > 0.0:
                    c_approach_velocity[m, k] = math.inf  # bounced (see below)
            if j0 > 0.0 or j1 > 0.0:
                struck = True
        if not struck:
            break
    for m in range(n_man):
        if kind[m] == _ALONE:
            for k in range(c_points[m]):
                total = c_normal_impulse[m, k]
                c_max_normal_impulse[m, k] = max(c_max_normal_impulse[m, k], total)
                if c_approach_velocity[m, k] == math.inf:
                    # a bounce is not warm-started; a point that only stopped an
                    # approach keeps its impulse, as the solve's points do
                    c_normal_impulse[m, k] = min(total, c_start_impulse[m, k])
                elif c_approach_velocity[m, k] < -threshold:
                    # its impact was met by the others' bounces before it struck: it
                    # is over (a later approach engages afresh in the solve)
                    c_approach_velocity[m, k] = math.inf


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def _relative_acceleration(body_type, body_force, im, gx, gy, a, b, nx, ny):
    """Relative normal acceleration (m/s²) of bodies a and b from gravity and forces."""
    acc = 0.0
    if body_type[a] == T.BODY_DYNAMIC:
        acc += (gx + im[a] * body_force[a, 0]) * nx + (gy + im[a] * body_force[a, 1]) * ny
    if body_type[b] == T.BODY_DYNAMIC:
        acc -= (gx + im[b] * body_force[b, 0]) * nx + (gy + im[b] * body_force[b, 1]) * ny
    return acc


@njit(cache=True, _nrt=False, fastmath={"contract"}, error_model="numpy")
def limit_static_overlap(model, state, contacts, max_overlap):
    """Move a dynamic body out of a static or kinematic one where it overlaps by more
    than max_overlap (m), along the contact normal, without touching its velocity.

    The soft contacts push overlaps out at a bounded speed, which a pile under
    permanent pressure (more bodies than fit in their box) can outrun: bodies were
    squeezed into the walls until the wall's normal flipped and they left the box.
    A surface that cannot move is rigid, so here the overlap is taken off the
    position directly. Resting contacts overlap far less than max_overlap (a fraction
    of a millimetre on static ground), so this acts only in such overload.
    """
    c_anchor_a = contacts.anchor_a
    c_anchor_b = contacts.anchor_b
    c_base_separation = contacts.base_separation
    c_body_a = contacts.body_a
    c_body_b = contacts.body_b
    c_count = contacts.count
    c_normal = contacts.normal
    c_points = contacts.points
    body_type = model.body_type
    x = state.body_x
    delta = contacts.body_delta
    for m in range(c_count[0]):
        a, b = c_body_a[m], c_body_b[m]
        a_fixed = body_type[a] != T.BODY_DYNAMIC
        b_fixed = body_type[b] != T.BODY_DYNAMIC
        if a_fixed == b_fixed:
            continue  # two dynamic bodies (left to the solver) or two fixed ones
        nx, ny = c_normal[m, 0], c_normal[m, 1]
        deepest = 0.0
        for k in range(c_points[m]):
            s = point_separation(
                c_anchor_a, c_anchor_b, c_base_separation, delta, m, k, a, b, nx, ny
            )
            deepest = min(deepest, s)
        push = -deepest - max_overlap
        if push <= 0.0:
            continue
        if b_fixed:  # the normal points from b to a: a moves along +n
            x[a, 0] += push * nx
            x[a, 1] += push * ny
            delta[a, 0] += push * nx
            delta[a, 1] += push * ny
        else:
            x[b, 0] -= push * nx
            x[b, 1] -= push * ny
            delta[b, 0] -= push * nx
            delta[b, 1] -= push * ny
