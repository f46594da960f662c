"""The time step, as the list of its stages, and the loop that runs a scene.

    find_pairs -> collide (manifolds) -> prepare -> support_order ->
    [per substep: integrate_velocities -> warm_start -> solve (biased)
                  -> integrate_positions -> relax -> restitution -> shock]
    -> limit_static_overlap -> store_impulses

(DESIGN.md lists the core of this; support_order and the shock pass (shock.py) carry
pushes up stacks and stop heavy bodies on light ones, and limit_static_overlap keeps
piles from squeezing bodies through walls.)

`step` is one numba kernel that calls each stage in turn, so a step costs one call
from Python; `advance` runs many steps.

Three rules keep the kernels fast. A kernel binds the NamedTuple fields it uses to
locals before its loops (numba updates a reference count on every field read, which
made the broadphase 30 times slower). A function called per pair or per contact
takes arrays, not the Model/State/Contacts tuples (each call would pay the same).
And every kernel of the step is compiled without numba's reference counting
(`_nrt=False`): the arrays all belong to the caller for the whole call, and kernels
allocate nothing, so the counts are pure overhead, yet numba could not remove them
from kernels with several exits: a call that took the Contacts tuple (about 60
arrays) paid 0.2-0.3 µs even when it had nothing to do, some 30 times per step. A
kernel compiled this way cannot allocate (numba refuses to compile it), which
enforces the no-allocation rule as a side effect.

The solver and shock kernels also let LLVM fuse a multiply and an add into one
instruction (fastmath "contract": rounding differs from separate operations, results
stay the same run to run) and skip numba's division-by-zero checks (error_model
"numpy": none of their divisions can have a zero divisor, so nothing is lost). The
solve is a chain of dependent arithmetic, so both shorten its critical path. The
other fastmath flags are never set: math.inf is a sentinel (no 'ninf', 'nnan').

A scene without shapes skips the contact stages entirely, and one without forces
skips their evaluation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ... import constants as C
from ...config import Config, NonFiniteState, make_config
from ...scene import Scene
from ...scene import types as T
from ...scene.compile import Model, State, build
from .broadphase import Grid, find_pairs, grow_grid, make_grid
from .contacts import (
    Contacts,
    grow_contacts,
    make_contacts,
    store_impulses,
    transform_shapes,
    update_manifolds,
)
from .integrator import integrate_positions, integrate_velocities
from .shock import deep_region, propagate_shock, support_order
from .solver import (
    apply_restitution,
    keep_solve_impulses,
    limit_static_overlap,
    prepare_contacts,
    solve_contacts,
    warm_start,
)

# advance() status codes
OK = 0
NEED_CAPACITY = 1
NON_FINITE = 2


@njit(cache=True, _nrt=False)
def collide(model, state, grid, contacts, cfg):
    """Broadphase, narrowphase and contact preparation. Returns False when the contact
    storage is too small (nothing has moved yet; the caller grows it and retries)."""
    transform_shapes(model, state, contacts, cfg.dt)
    n_pairs = find_pairs(
        model, grid, contacts.vert_world, contacts.shape_margin, contacts.pairs, contacts.count[2]
    )
    if n_pairs > contacts.pairs.shape[0]:
        contacts.count[2] = n_pairs
        return False
    contacts.count[2] = n_pairs
    update_manifolds(
        model,
        state,
        contacts,
        grid.shape_aabb,
        n_pairs,
        cfg.friction_rule,
        cfg.restitution_rule,
        cfg.dt,
    )
    prepare_contacts(model, state, contacts, cfg.soft, cfg.soft_static)
    contacts.count[4] = support_order(model, contacts)
    return True


@njit(cache=True, _nrt=False)
def step(model, state, grid, contacts, cfg):
    """Advance the state by one time step cfg.dt. Returns False when contact storage is
    too small (the state is then unchanged)."""
    contacts_on = model.has_shapes
    if contacts_on and not collide(model, state, grid, contacts, cfg):
        return False
    delta = contacts.body_delta
    delta[:, 0] = 0.0
    delta[:, 1] = 0.0
    delta[:, 2] = 1.0
    delta[:, 3] = 0.0
    h = cfg.dt / cfg.substeps
    inv_h = 1.0 / h
    shift = 0.0 if cfg.explicit else h
    sign = -1.0 if cfg.explicit else 1.0
    threshold = cfg.restitution_threshold
    # the restitution stage's list names this step's manifolds
    contacts.count[5] = contacts.count[8] = contacts.count[9] = 0
    order, n_man = contacts.solve_order, contacts.count[0]
    for _ in range(cfg.substeps):
        if cfg.explicit:
            integrate_positions(model, state, delta, h, cfg.exact)
            integrate_velocities(model, state, h)
        else:
            integrate_velocities(model, state, h)
        if contacts_on:
            warm_start(model, state, contacts)
            contacts.count[6] = 0
            for _ in range(cfg.iterations):
                solve_contacts(model, state, contacts, inv_h, True, 0.0, threshold, order, n_man)
        if not cfg.explicit:
            if contacts_on and cfg.elastic:
                keep_solve_impulses(contacts)
            integrate_positions(model, state, delta, h, cfg.exact)
        if contacts_on:
            for _ in range(cfg.iterations):  # relax
                solve_contacts(model, state, contacts, inv_h, False, shift, threshold, order, n_man)
            if contacts.count[6]:
                # a deep overlap is being pushed out: the contacts around it get more
                # relax passes, so that the push's velocity is taken back all the way
                # up a stack instead of adding up from row to row
                near = contacts.relax_list
                n_near = deep_region(model, contacts, C.DEEP_RELAX_REACH)
                for _ in range(cfg.iterations * (C.DEEP_RELAX_FACTOR - 1)):
                    solve_contacts(
                        model, state, contacts, inv_h, False, shift, threshold, near, n_near
                    )
            # bounces first: the shock pass then leaves them alone, and would otherwise
            # take a ball struck down onto the floor as a load and stop it dead
            apply_restitution(model, state, contacts, threshold, h, sign)
            propagate_shock(model, state, contacts, contacts.count[4], inv_h, threshold)
    if contacts_on:
        limit_static_overlap(model, state, contacts, C.STATIC_OVERLAP_LIMIT)
        store_impulses(contacts)
    return True


@njit(cache=True, _nrt=False)
def _first_non_finite(state):
    x, v, w, q = state.body_x, state.body_v, state.body_w, state.body_q
    for i in range(x.shape[0]):
        if not (
            math.isfinite(x[i, 0])
            and math.isfinite(x[i, 1])
            and math.isfinite(v[i, 0])
            and math.isfinite(v[i, 1])
            and math.isfinite(w[i])
            and math.isfinite(q[i, 0])
        ):
            return i
    return -1


@njit(cache=True, _nrt=False)
def advance(model, state, grid, contacts, cfg, n_steps, result):
    """Take up to n_steps steps. result[0] = steps taken; returns OK, NEED_CAPACITY
    (grow contacts, call again) or NON_FINITE (result[1] = the body index)."""
    for k in range(n_steps):
        if not step(model, state, grid, contacts, cfg):
            result[0] = k
            return NEED_CAPACITY
        bad = _first_non_finite(state)
        if bad >= 0:
            result[0] = k + 1
            result[1] = bad
            return NON_FINITE
    result[0] = n_steps
    return OK


@dataclass
class World:
    """A scene ready to step: model, state and preallocated stage storage."""

    scene: Scene
    model: Model
    state: State
    config: Config
    grid: Grid
    contacts: Contacts
    step_index: int = 0

    @classmethod
    def from_scene(cls, scene: Scene) -> World:
        """Build the model, state and storage for a resolved scene."""
        model, state = build(scene)
        n_shapes = model.shape_body.shape[0]
        capacity = 4 * n_shapes + 16
        dynamic = model.body_type[model.shape_body] == T.BODY_DYNAMIC
        grid = make_grid(shape_extent(model), dynamic, capacity)
        contacts = make_contacts(
            model.body_mass.shape[0], n_shapes, model.vertex_local.shape[0], capacity
        )
        return cls(scene, model, state, make_config(scene), grid, contacts)

    @property
    def time(self) -> float:
        """Simulated time (s) of the current state."""
        return self.step_index * self.config.dt

    def advance(self, n_steps: int) -> None:
        """Take n_steps steps; raises NonFiniteState if the state blows up."""
        result = np.zeros(2, np.int64)
        remaining = n_steps
        while remaining > 0:
            status = advance(
                self.model, self.state, self.grid, self.contacts, self.config, remaining, result
            )
            taken = int(result[0])
            self.step_index += taken
            remaining -= taken
            if status == NEED_CAPACITY:
                capacity = 2 * int(self.contacts.count[2])
                self.contacts = grow_contacts(self.contacts, capacity)
                self.grid = grow_grid(self.grid, capacity)
            elif status == NON_FINITE:
                raise NonFiniteState(int(result[1]), self.step_index)

    @property
    def contact_count(self) -> int:
        """Contact points that pushed in the last step."""
        return int(self.contacts.count[3]) if self.model.has_shapes else 0


def shape_extent(model: Model) -> np.ndarray:
    """Half the diagonal (m) of each shape's own bounding box, radius included."""
    ext = np.zeros(model.shape_body.shape[0])
    for s in range(ext.shape[0]):
        start = model.shape_vstart[s]
        v = model.vertex_local[start : start + model.shape_vcount[s]]
        span = v.max(axis=0) - v.min(axis=0)
        ext[s] = 0.5 * float(np.hypot(span[0], span[1])) + model.shape_radius[s]
    return ext
