"""Observables written with every frame: energies, momenta, contact count.

Only dynamic bodies count (static and kinematic bodies have infinite mass).
"""

from __future__ import annotations

import numpy as np

from ..scene import types as T
from ..scene.compile import Model, State


def observables(model: Model, state: State, contact_count: int) -> dict[str, float | np.ndarray]:
    """kinetic_energy (J), potential_energy (J, −m g·x relative to the world origin),
    linear_momentum (2,) kg·m/s, angular_momentum about the world origin (kg·m²/s,
    orbital plus spin), contact_count (points that pushed in the last step)."""
    dyn = model.body_type == T.BODY_DYNAMIC
    m = model.body_mass[dyn]
    inertia = model.body_inertia[dyn]
    x, v, w = state.body_x[dyn], state.body_v[dyn], state.body_w[dyn]
    ke = 0.5 * float(np.sum(m * np.einsum("ij,ij->i", v, v)) + np.sum(inertia * w * w))
    pe = -float(np.sum(m * (x @ model.gravity)))
    p = (m[:, None] * v).sum(axis=0) if m.size else np.zeros(2)
    orbital = np.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))
    return {
        "kinetic_energy": ke,
        "potential_energy": pe,
        "linear_momentum": np.asarray(p, np.float64),
        "angular_momentum": float(orbital + np.sum(inertia * w)),
        "contact_count": int(contact_count),
    }
