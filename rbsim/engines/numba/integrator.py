"""Integration stages: velocities from forces, positions from velocities.

Symplectic (semi-implicit) Euler integrates velocities first and moves bodies with
the new velocity; explicit Euler moves bodies with the old velocity first. Both are
first order: a projectile's height error after time t is ∓ g h t / 2 for step h.

Rotation is a unit complex number q = (cos θ, sin θ). `normalize` applies the
derived update q <- normalize(q + h ω×q), which rotates by atan(h ω) per step (a lag
of h ω − atan(h ω)); `exact` rotates by h ω. The accumulated angle `body_angle`
advances by the same amount, so it stays equal to the angle of q, unwrapped.
"""

from __future__ import annotations

import math

from numba import njit

from ...scene import types as T

# |x| below which atan_small's series is used: its first omitted term, x^19 / 19, is
# then below 1e-18 of x, far under double rounding.
ATAN_SERIES_MAX = 0.1


@njit(cache=True, _nrt=False, inline="always")
def atan_small(x: float) -> float:
    """atan(x) (rad) for |x| < ATAN_SERIES_MAX, from its Taylor series to x^17: a few
    multiply-adds instead of a library call, for the rotation of a slow body."""
    x2 = x * x
    p = 1.0 / 17.0
    p = 1.0 / 15.0 - x2 * p
    p = 1.0 / 13.0 - x2 * p
    p = 1.0 / 11.0 - x2 * p
    p = 1.0 / 9.0 - x2 * p
    p = 1.0 / 7.0 - x2 * p
    p = 1.0 / 5.0 - x2 * p
    p = 1.0 / 3.0 - x2 * p
    return x - x * x2 * p


@njit(cache=True, _nrt=False)
def integrate_velocities(model, state, h):
    """v += h (g + F/m), ω += h τ/I for dynamic bodies, then damping 1/(1 + h c).

    h: step length in s. F is the constant world-frame force, applied at its arm
    (body frame, from the COM), so it adds the torque r × F with r = R(q) arm.
    """
    m_angular_damping = model.angular_damping
    m_body_force = model.body_force
    m_body_force_arm = model.body_force_arm
    m_body_inv_inertia = model.body_inv_inertia
    m_body_inv_mass = model.body_inv_mass
    m_body_torque = model.body_torque
    m_body_type = model.body_type
    m_gravity = model.gravity
    m_has_forces = model.has_forces
    m_linear_damping = model.linear_damping
    s_body_q = state.body_q
    gx, gy = m_gravity[0], m_gravity[1]
    lin = 1.0 / (1.0 + h * m_linear_damping)
    ang = 1.0 / (1.0 + h * m_angular_damping)
    v, w = state.body_v, state.body_w
    for i in range(v.shape[0]):
        if m_body_type[i] != T.BODY_DYNAMIC:
            continue
        ax, ay, alpha = gx, gy, 0.0
        if m_has_forces:
            fx, fy = m_body_force[i, 0], m_body_force[i, 1]
            c, s = s_body_q[i, 0], s_body_q[i, 1]
            rx = c * m_body_force_arm[i, 0] - s * m_body_force_arm[i, 1]
            ry = s * m_body_force_arm[i, 0] + c * m_body_force_arm[i, 1]
            im = m_body_inv_mass[i]
            ax += im * fx
            ay += im * fy
            alpha = m_body_inv_inertia[i] * (m_body_torque[i] + rx * fy - ry * fx)
        v[i, 0] = (v[i, 0] + h * ax) * lin
        v[i, 1] = (v[i, 1] + h * ay) * lin
        w[i] = (w[i] + h * alpha) * ang


@njit(cache=True, _nrt=False)
def integrate_positions(model, state, delta, h, exact):
    """x += h v and rotate q by ω h (exact) or by atan(h ω) (normalize) for moving bodies.

    delta (N,4): per-body displacement (dx, dy) and rotation (cos, sin) accumulated
    since the start of the step, which the contact solver uses to track separations.
    """
    m_body_type = model.body_type
    x, q, angle, v, w = state.body_x, state.body_q, state.body_angle, state.body_v, state.body_w
    for i in range(x.shape[0]):
        if m_body_type[i] == T.BODY_STATIC:
            continue
        dx, dy = h * v[i, 0], h * v[i, 1]
        x[i, 0] += dx
        x[i, 1] += dy
        hw = h * w[i]
        c, s = q[i, 0], q[i, 1]
        if exact:
            rc, rs = math.cos(hw), math.sin(hw)
            angle[i] += hw
            nc, ns = rc * c - rs * s, rs * c + rc * s
            # renormalise: rounding drift is kept at the 1e-16 level over any run
            inv = 1.0 / math.sqrt(nc * nc + ns * ns)
            nc *= inv
            ns *= inv
        else:
            nc, ns = c - hw * s, s + hw * c
            inv = 1.0 / math.sqrt(nc * nc + ns * ns)
            nc *= inv
            ns *= inv
            rc, rs = inv, hw * inv  # the rotation applied: by atan(h ω)
            angle[i] += atan_small(hw) if abs(hw) < ATAN_SERIES_MAX else math.atan(hw)
        q[i, 0], q[i, 1] = nc, ns
        delta[i, 0] += dx
        delta[i, 1] += dy
        dc, ds = delta[i, 2], delta[i, 3]
        delta[i, 2], delta[i, 3] = rc * dc - rs * ds, rs * dc + rc * ds
