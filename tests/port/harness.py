"""Hold each stage of the C++ engine against the numba engine's, on the same input.

    pair = Pair.from_text(scene_yaml)      # both engines on one scene
    pair.advance_numba(30)                 # step the numba engine into an interesting state
    pair.sync()                            # copy its whole state and storage into the C++ one
    pair.run("solve_contacts", inv_h=..., use_bias=True, ...)  # the stage in both
    pair.diff()                            # {array name: max |difference|}, nonzero only

`sync` copies every storage array that both engines have under the same name (the C++
store mirrors the numba one's names and shapes), after growing the C++ store to the
numba one's capacity.
"""

from __future__ import annotations

import numpy as np

from rbsim.core import CoreWorld
from rbsim.engines.numba import world as nw
from rbsim.engines.numba.broadphase import find_pairs as nb_find_pairs
from rbsim.engines.numba.contacts import store_impulses, transform_shapes, update_manifolds
from rbsim.engines.numba.integrator import integrate_positions, integrate_velocities
from rbsim.engines.numba.shock import deep_region, propagate_shock, support_order
from rbsim.engines.numba.solver import (
    apply_restitution,
    keep_solve_impulses,
    limit_static_overlap,
    prepare_contacts,
    solve_contacts,
    warm_start,
)
from rbsim.scene import load_scene_text

STATE = ("body_x", "body_q", "body_angle", "body_v", "body_w")


class Pair:
    """The numba World and the C++ CoreWorld of one scene."""

    def __init__(self, scene) -> None:
        self.scene = scene
        self.nb = nw.World.from_scene(scene)
        self.cc = CoreWorld.from_scene(scene)

    @classmethod
    def from_text(cls, text: str) -> Pair:
        return cls(load_scene_text(text, "<port test>"))

    def advance_numba(self, n: int) -> None:
        self.nb.advance(n)

    # -- copying and comparing ---------------------------------------------------------

    def _storage_pairs(self):
        """(name, numba array, C++ view) for every array both have."""
        cs = self.cc.storage
        out = []
        for name in STATE:
            out.append((name, getattr(self.nb.state, name), getattr(self.cc.state, name)))
        for name, arr in self.nb.contacts._asdict().items():
            if hasattr(cs, name):
                out.append((name, arr, getattr(cs, name)))
        for name, arr in self.nb.grid._asdict().items():
            if hasattr(cs.grid, name):
                out.append(("grid." + name, np.asarray(arr), getattr(cs.grid, name)))
        return out

    def sync(self) -> None:
        """Copy the numba engine's state and storage into the C++ engine."""
        capacity = self.nb.contacts.key.shape[0]
        if self.cc.storage.key.shape[0] != capacity:
            self.cc.engine.grow(capacity)
        for name, a, b in self._storage_pairs():
            a = np.asarray(a)
            if name == "grid.inv_cell" or a.shape == ():
                b[...] = a
                continue
            if b.shape != a.shape:
                raise AssertionError(f"{name}: C++ shape {b.shape}, numba shape {a.shape}")
            b[...] = a
        self.cc.engine.step_index = self.nb.step_index

    def sync_to_numba(self) -> None:
        """Copy the C++ engine's state and storage into the numba engine (the reverse
        of `sync`, to replay a step the C++ engine took in both)."""
        capacity = self.cc.storage.key.shape[0]
        if self.nb.contacts.key.shape[0] != capacity:
            from rbsim.engines.numba.broadphase import grow_grid
            from rbsim.engines.numba.contacts import grow_contacts

            self.nb.contacts = grow_contacts(self.nb.contacts, capacity)
            self.nb.grid = grow_grid(self.nb.grid, capacity)
        for name, a, b in self._storage_pairs():
            if name == "grid.inv_cell":
                continue  # a float in the numba grid, set at build
            np.asarray(a)[...] = b
        self.nb.step_index = self.cc.step_index

    def diff(self, names=None, *, atol: float = 0.0) -> dict[str, float]:
        """Max |numba − C++| per array (equal infinities and NaN in the same places count
        as equal); only
        arrays that differ by more than atol, or whose shapes differ."""
        out = {}
        for name, a, b in self._storage_pairs():
            if names is not None and name not in names:
                continue
            a, b = np.asarray(a), np.asarray(b)
            if a.shape != b.shape:
                out[name] = float("inf")
                continue
            if a.size == 0:
                continue
            same = (a == b) | (np.isnan(a) & np.isnan(b)) if a.dtype.kind == "f" else a == b
            with np.errstate(invalid="ignore"):
                d = np.where(same, 0.0, np.abs(a.astype(np.float64) - b.astype(np.float64)))
            d = np.nan_to_num(d, nan=np.inf)
            worst = float(d.max())
            if worst > atol:
                out[name] = worst
        return out

    # -- running one stage in both -------------------------------------------------------

    def run(self, stage: str, **args):
        """Run one stage in both engines on their own storage; returns (numba, C++)
        results."""
        n, c = self.nb, self.nb.contacts
        m, s, g, cfg = n.model, n.state, n.grid, n.config
        if stage == "transform_shapes":
            r = transform_shapes(m, s, c, cfg.dt)
        elif stage == "find_pairs":
            r = nb_find_pairs(m, g, c.vert_world, c.shape_margin, c.pairs, c.count[2])
            c.count[2] = r
        elif stage == "update_manifolds":
            r = update_manifolds(
                m, s, c, g.shape_aabb, args["n_pairs"], cfg.friction_rule,
                cfg.restitution_rule, cfg.dt,
            )  # fmt: skip
        elif stage == "prepare_contacts":
            r = prepare_contacts(m, s, c, cfg.soft, cfg.soft_static)
        elif stage == "support_order":
            r = support_order(m, c)
        elif stage == "deep_region":
            r = deep_region(m, c, args["reach"])
        elif stage == "propagate_shock":
            r = propagate_shock(m, s, c, args["n_order"], args["inv_h"], args["threshold"])
        elif stage == "integrate_velocities":
            r = integrate_velocities(m, s, args["h"])
        elif stage == "integrate_positions":
            r = integrate_positions(m, s, c.body_delta, args["h"], args["exact"])
        elif stage == "warm_start":
            r = warm_start(m, s, c)
        elif stage == "solve_contacts":
            order = c.relax_list if args["order"] == "relax_list" else c.solve_order
            r = solve_contacts(
                m, s, c, args["inv_h"], args["use_bias"], args["shift"], args["threshold"],
                order, args["n"],
            )  # fmt: skip
        elif stage == "keep_solve_impulses":
            r = keep_solve_impulses(c)
        elif stage == "apply_restitution":
            r = apply_restitution(m, s, c, args["threshold"], args["h"], args["sign"])
        elif stage == "limit_static_overlap":
            r = limit_static_overlap(m, s, c, args["max_overlap"])
        elif stage == "store_impulses":
            r = store_impulses(c)
        else:
            raise ValueError(stage)
        rc = self.cc.engine.stage(stage, args)
        if stage == "find_pairs":
            self.cc.storage.count[2] = rc
        return r, rc

    def step_both(self) -> None:
        """One whole step in each engine."""
        self.nb.advance(1)
        self.cc.advance(1)
