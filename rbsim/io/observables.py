"""Observables written with every frame: energies, momenta, contact count.

Only dynamic bodies count (static and kinematic bodies have infinite mass).
"""

from __future__ import annotations

import numpy as np

from ..scene import types as T
from ..scene.compile import Model, State


def observables(model: Model, state: State, contact_count: int) -> dict[str, float | np.ndarray]:
    """kinetic_energy (J), potential_energy (J, −m g·x relative to the world origin),
    linear_momentum (D,) kg·m/s, angular_momentum about the world origin (kg·m²/s, orbital
    plus spin: a scalar in 2D, (3,) in 3D), contact_count (points that pushed in the last
    step). In 3D the rotational energy is ½ ω·L and the spin L, the state's own angular
    momentum (world frame, about each COM)."""
    dyn = model.body_type == T.BODY_DYNAMIC
    dimension = model.body_com.shape[1]
    m = model.body_mass[dyn]
    x, v, w = state.body_x[dyn], state.body_v[dyn], state.body_w[dyn]
    p = (m[:, None] * v).sum(axis=0) if m.size else np.zeros(dimension)
    pe = -float(np.sum(m * (x @ model.gravity)))
    translational = float(np.sum(m * np.einsum("ij,ij->i", v, v)))
    if dimension == 3:
        spin = state.body_l[dyn]
        ke = 0.5 * (translational + float(np.sum(np.einsum("ij,ij->i", w, spin))))
        orbital = np.cross(x, m[:, None] * v).sum(axis=0) if m.size else np.zeros(3)
        angular = np.asarray(orbital + spin.sum(axis=0), np.float64)
    else:
        inertia = model.body_inertia[dyn]
        ke = 0.5 * (translational + float(np.sum(inertia * w * w)))
        orbital = np.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))
        angular = float(orbital + np.sum(inertia * w))
    return {
        "kinetic_energy": ke,
        "potential_energy": pe,
        "linear_momentum": np.asarray(p, np.float64),
        "angular_momentum": angular,
        "contact_count": int(contact_count),
    }
