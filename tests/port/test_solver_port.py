"""The C++ solver stages (prepare_contacts, warm_start, solve_contacts,
limit_static_overlap) against the numba ones, on the same inputs.

Each scene is stepped by the numba engine to a few moments; then one more step is taken
stage by stage by hand (the order of rbsim/engines/numba/world.py's step), and before each of the
four solver stages the numba state and storage are copied into the C++ engine and the
stage runs in both: every solve and relax pass of every substep, the extra relax passes
over relax_list near a deep overlap, prepare before them and the overlap limit after.

The numba kernels fuse multiplies and adds (fastmath "contract"), the C++ build does
not: floats agree to round-off (RTOL relative, ATOL absolute for values near zero);
integer arrays (bounce_list, relax_list, the counters) and the places of inf and NaN
(approach velocity after a bounce) agree exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from rbsim import constants as C
from rbsim.engines.numba.broadphase import find_pairs as nb_find_pairs
from rbsim.engines.numba.broadphase import grow_grid
from rbsim.engines.numba.contacts import (
    grow_contacts,
    store_impulses,
    transform_shapes,
    update_manifolds,
)
from rbsim.engines.numba.integrator import integrate_positions, integrate_velocities
from rbsim.engines.numba.shock import deep_region, propagate_shock, support_order
from rbsim.engines.numba.solver import apply_restitution, keep_solve_impulses

from .harness import Pair

RTOL = 1e-9  # relative: round-off of a pass's few dozen operations, FMA against none
ATOL = 1e-12  # absolute (m/s, N·s, m): round-off of values that cancel to near zero

SOLVER_STAGES = ("prepare_contacts", "warm_start", "solve_contacts", "limit_static_overlap")


def compare(pair: Pair) -> dict[str, float]:
    """{array: worst excess} for arrays where numba and C++ disagree beyond round-off
    (integers: exactly; floats: equal infinities and NaNs in the same places, else
    |a − b| <= ATOL + RTOL |a|)."""
    bad = {}
    for name, a, b in pair._storage_pairs():
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            bad[name] = float("inf")
            continue
        if a.size == 0:
            continue
        if a.dtype.kind != "f":
            if not np.array_equal(a.astype(np.int64), b.astype(np.int64)):
                bad[name] = float(np.abs(a.astype(np.int64) - b.astype(np.int64)).max())
            continue
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        with np.errstate(invalid="ignore"):
            excess = np.where(same, 0.0, np.abs(a - b) - (ATOL + RTOL * np.abs(a)))
        excess = np.nan_to_num(excess, nan=np.inf)
        if excess.max() > 0.0:
            bad[name] = float(excess.max())
    return bad


class Checker:
    """Runs a solver stage in both engines from numba's inputs, and records how far
    their outputs are apart."""

    def __init__(self, pair: Pair) -> None:
        self.pair = pair
        self.calls: dict[str, int] = {}
        self.worst_rel = 0.0  # largest relative difference of a float seen
        self.seen: set[str] = set()  # the branches the calls went through

    def __call__(self, stage: str, **args) -> None:
        pair = self.pair
        pair.sync()
        assert not compare(pair), "sync left differences"
        c = pair.nb.contacts
        before = c.count.copy(), pair.nb.state.body_x.copy()
        pair.run(stage, **args)
        bad = compare(pair)
        assert not bad, f"{stage} {args}: {bad}"
        self.calls[stage] = self.calls.get(stage, 0) + 1
        self._note(stage, args, *before)
        for _name, a, b in pair._storage_pairs():
            a, b = np.asarray(a), np.asarray(b)
            if a.dtype.kind == "f" and a.size:
                with np.errstate(invalid="ignore"):
                    d = np.abs(a - b) / np.maximum(np.abs(a), 1.0)
                d = d[np.isfinite(d)]
                if d.size:
                    self.worst_rel = max(self.worst_rel, float(d.max()))

    def _note(self, stage, args, count, x) -> None:
        """Which of the stage's branches this call went through (self.seen)."""
        c, seen = self.pair.nb.contacts, self.seen
        n = int(c.count[0])
        if stage == "prepare_contacts":
            seen.add("carried") if c.carried[:n].any() else seen.add("fresh")
            if (c.points[:n] == 2).any():
                seen.add("two-point")
            if (c.points[:n] == 1).any():
                seen.add("one-point")
        elif stage == "solve_contacts":
            if c.count[5] > count[5]:
                seen.add("bounce listed")
            if c.count[6] > count[6]:
                seen.add("deep")
            if args["order"] == "relax_list":
                seen.add("relax_list")
            mu_n = c.friction[:n, None] * c.normal_impulse[:n]
            tangent = np.abs(c.tangent_impulse[:n])
            if ((tangent == mu_n) & (mu_n > 0)).any():
                seen.add("friction at limit")
            if ((tangent < mu_n) & (tangent > 0)).any():
                seen.add("friction within")
            if np.isinf(c.approach_velocity[:n]).any():
                seen.add("approach inf")
        elif stage == "limit_static_overlap":
            if (self.pair.nb.state.body_x != x).any():
                seen.add("moved out")


def step_by_stages(pair: Pair, check: Checker) -> None:
    """One numba step, as world.py's step calls its stages; the solver stages through
    `check` (which runs them in both engines), the others in numba alone."""
    nb = pair.nb
    m, s, cfg = nb.model, nb.state, nb.config
    contacts_on = m.has_shapes
    if contacts_on:
        while True:  # world.collide, growing the storage as World.advance does
            c, g = nb.contacts, nb.grid
            transform_shapes(m, s, c, cfg.dt)
            n_pairs = nb_find_pairs(m, g, c.vert_world, c.shape_margin, c.pairs, c.count[2])
            c.count[2] = n_pairs
            if n_pairs <= c.pairs.shape[0]:
                break
            nb.contacts = grow_contacts(c, 2 * int(n_pairs))
            nb.grid = grow_grid(g, 2 * int(n_pairs))
        update_manifolds(
            m, s, c, g.shape_aabb, n_pairs, cfg.friction_rule, cfg.restitution_rule, cfg.dt
        )
        check("prepare_contacts")
        c.count[4] = support_order(m, c)
    c = nb.contacts
    delta = c.body_delta
    delta[:, 0] = delta[:, 1] = delta[:, 3] = 0.0
    delta[:, 2] = 1.0
    h = cfg.dt / cfg.substeps
    inv_h = 1.0 / h
    shift = 0.0 if cfg.explicit else h
    sign = -1.0 if cfg.explicit else 1.0
    threshold = cfg.restitution_threshold
    c.count[5] = c.count[8] = c.count[9] = 0
    n_man = int(c.count[0])
    solve = dict(inv_h=inv_h, threshold=threshold)
    for _ in range(cfg.substeps):
        if cfg.explicit:
            integrate_positions(m, s, delta, h, cfg.exact)
            integrate_velocities(m, s, h)
        else:
            integrate_velocities(m, s, h)
        if contacts_on:
            check("warm_start")
            c.count[6] = 0
            for _ in range(cfg.iterations):
                check("solve_contacts", use_bias=True, shift=0.0, order="solve_order", n=n_man,
                      **solve)  # fmt: skip
        if not cfg.explicit:
            if contacts_on and cfg.elastic:
                keep_solve_impulses(c)
            integrate_positions(m, s, delta, h, cfg.exact)
        if contacts_on:
            for _ in range(cfg.iterations):
                check("solve_contacts", use_bias=False, shift=shift, order="solve_order",
                      n=n_man, **solve)  # fmt: skip
            if c.count[6]:
                n_near = int(deep_region(m, c, C.DEEP_RELAX_REACH))
                for _ in range(cfg.iterations * (C.DEEP_RELAX_FACTOR - 1)):
                    check("solve_contacts", use_bias=False, shift=shift, order="relax_list",
                          n=n_near, **solve)  # fmt: skip
            apply_restitution(m, s, c, threshold, h, sign)
            propagate_shock(m, s, c, c.count[4], inv_h, threshold)
    if contacts_on:
        check("limit_static_overlap", max_overlap=C.STATIC_OVERLAP_LIMIT)
        store_impulses(c)
    nb.step_index += 1


def column(sink: float, n: int = 6) -> str:
    """A column of n touching unit circles on the ground, the bottom one `sink` (m)
    into it (tests/test_contacts.py's column_scene)."""
    balls = "".join(
        f"  - {{name: b{i}, position: [0, {0.5 + i - (sink if i == 0 else 0.0)}],"
        f" shape: {{circle: {{radius: 0.5}}}}}}\n"
        for i in range(n)
    )
    return (
        "version: 1\nworld: {dt: 1/60, duration: 3}\nbodies:\n"
        "  - {name: ground, type: static, shape: {segment: {a: [-50, 0], b: [50, 0]}}}\n" + balls
    )


GROUND = (
    "  - {name: ground, type: static, friction: 0.6, shape: {segment: {a: [-30, 0], b: [30, 0]}}}\n"  # noqa: E501
)

SCENES = {
    # boxes on boxes: two-point manifolds, the 2x2 block solve, friction at two points
    "stack": "version: 1\nworld: {dt: 1/60, steps: 200}\nbodies:\n"
    + GROUND
    + "  - stack: {count: 6, size: [1, 1], origin: [0, 0.5], friction: 0.6}\n",
    # a pyramid: block solves with neighbours on both sides, the solve order
    "pyramid": "version: 1\nworld: {dt: 1/60, steps: 200}\nbodies:\n"
    + GROUND
    + "  - pyramid: {base: 6, size: [1, 1], origin: [0, 0.5], friction: 0.6}\n",
    # circles poured into a box: one-point manifolds, ball on ball, walls
    "circles": """
version: 1
world: {dt: 1/60, steps: 200}
materials: {p: {density: 1.0, friction: 0.3, restitution: 0.0}}
bodies:
  - {name: floor, type: static, position: [0, -0.5], material: p, shape: {box: {size: [5, 1]}}}
  - {name: wl, type: static, position: [-2.25, 2], material: p, shape: {box: {size: [0.5, 4]}}}
  - {name: wr, type: static, position: [2.25, 2], material: p, shape: {box: {size: [0.5, 4]}}}
  - grid: {name: g, count: [7, 5], spacing: [0.55, 0.55], origin: [-1.65, 0.4],
           velocity: [0.3, 0], material: p, shape: {circle: {radius: 0.2}}}
""",
    # a block sliding down a slope (friction at its limit) and one resting on it
    "slope": """
version: 1
world: {dt: 1/60, steps: 200}
bodies:
  - {name: slope, type: static, friction: 0.2,
     shape: {segment: {a: [-5.526365964017311, -2.336510053851903],
                       b: [5.526365964017311, 2.336510053851903]}}}
  - {name: slider, position: [1.7447674024286075, 1.0091019331180222], angle: 0.4,
     velocity: [-0.46, -0.19], friction: 0.2, shape: {box: {size: [0.5, 0.5]}}}
  - {name: rest, type: static, position: [0, -3], angle: 0.3, friction: 0.9,
     shape: {segment: {a: [-2, 0], b: [2, 0]}}}
  - {name: sitter, position: [-0.0739, -2.76], angle: 0.3, friction: 0.9,
     shape: {box: {size: [0.5, 0.5]}}}
""",
    # a ball 0.2 m into the ground under a column: deep_count, relax_list, the extra
    # relax passes over relax_list and the static overlap limit
    "deep": column(0.2),
    # a kinematic platform carrying a box, a box on a dynamic plank, polygons and
    # capsules: one fixed body moving, both sides dynamic, mixed manifolds
    "mixed": """
version: 1
world: {dt: 1/60, steps: 200}
bodies:
  - {name: ground, type: static, friction: 0.5, shape: {segment: {a: [-20, 0], b: [20, 0]}}}
  - {name: lift, type: kinematic, position: [-4, 1], velocity: [0.5, 0.3], angular_velocity: 0.1,
     friction: 0.5, shape: {box: {size: [2, 0.2]}}}
  - {name: rider, position: [-4, 1.35], friction: 0.5, shape: {box: {size: [0.5, 0.5]}}}
  - {name: plank, position: [0, 0.1], friction: 0.5, shape: {box: {size: [3, 0.2]}}}
  - {name: tri, position: [0.5, 0.6], friction: 0.5,
     shape: {polygon: {vertices: [[-0.4, -0.3], [0.4, -0.3], [0, 0.4]]}}}
  - {name: cap, position: [-0.8, 0.45], angle: 0.1, friction: 0.5,
     shape: {segment: {a: [-0.4, 0], b: [0.4, 0], radius: 0.15}}}
  - {name: heavy, position: [3, 0.5], mass: 50, friction: 0.5, shape: {circle: {radius: 0.5}}}
  - {name: light, position: [3, 1.2], mass: 0.1, friction: 0.5, shape: {box: {size: [0.4, 0.4]}}}
""",
    # elastic balls dropped on the ground and onto each other: engagement, bounce_list,
    # approach set to inf after a bounce and a new impact recorded
    "elastic": """
version: 1
world: {dt: 1/60, steps: 300}
bodies:
  - {name: ground, type: static, shape: {segment: {a: [-4, 0], b: [4, 0]}}}
  - {name: e1, position: [-2, 0.9], restitution: 1.0, shape: {circle: {radius: 0.25}}}
  - {name: e8, position: [-1, 0.7], restitution: 0.8, friction: 0.4,
     angular_velocity: 3, shape: {circle: {radius: 0.25}}}
  - {name: lo, position: [1, 0.3], restitution: 0.5, shape: {circle: {radius: 0.25}}}
  - {name: hi, position: [1.05, 1.2], restitution: 0.5, shape: {circle: {radius: 0.25}}}
  - {name: box, position: [2.5, 0.8], angle: 0.3, restitution: 0.6,
     shape: {box: {size: [0.4, 0.4]}}}
""",
    # Newton's cradle (threshold 0: every approach bounces; no gravity, no friction)
    "cradle": """
version: 1
world: {gravity: [0, 0], dt: 1/60, duration: 3}
solver: {restitution_threshold: 0.0}
materials: {steel: {density: 1.0, friction: 0.0, restitution: 1.0}}
bodies:
  - {name: b0, position: [-1.2, 0], velocity: [1, 0], material: steel,
     shape: {circle: {radius: 0.5}}}
  - {name: b1, position: [0, 0], material: steel, shape: {circle: {radius: 0.5}}}
  - {name: b2, position: [1, 0], material: steel, shape: {circle: {radius: 0.5}}}
  - {name: b3, position: [2, 0], material: steel, shape: {circle: {radius: 0.5}}}
""",
    # explicit Euler (shift 0 in the relax stage) and two iterations per substep
    "explicit": "version: 1\nworld: {dt: 1/60, steps: 200}\n"
    "solver: {integrator: explicit_euler, iterations: 2}\nbodies:\n"
    + GROUND
    + "  - pyramid: {base: 3, size: [1, 1], origin: [0, 0.5], friction: 0.6}\n"
    "  - {name: ball, position: [3, 1], restitution: 0.5, shape: {circle: {radius: 0.3}}}\n",
    # overlapping boxes pushed apart (large push-out), boxes squeezed into the ground
    "overlap": "version: 1\nworld: {dt: 1/60, steps: 200}\nbodies:\n"
    + GROUND
    + "".join(
        f"  - {{name: 'b{r}{i}', position: [{(i - (3 - r) / 2) * 0.75}, {0.45 + 0.75 * r}],"
        f" friction: 0.6, shape: {{box: {{size: [1, 1]}}}}}}\n"
        for r in range(3)
        for i in range(4 - r)
    ),
}

# the moments (steps taken by numba first) at which a step is replayed stage by stage
MOMENTS = {
    "stack": (0, 3, 40),
    "pyramid": (0, 5, 60),
    "circles": (0, 15, 40, 90),
    "slope": (0, 10, 60),
    "deep": (0, 1, 5, 20),
    "mixed": (0, 4, 30, 80),
    "elastic": (0, 12, 20, 27, 40, 70),
    "cradle": (10, 11, 12, 14, 40),
    "explicit": (0, 5, 30, 45),
    "overlap": (0, 1, 10, 40),
}

# the branches each scene must go through (Checker._note)
EXPECT = {
    "stack": {"two-point", "carried", "friction within"},
    "pyramid": {"two-point", "fresh", "friction within"},
    "circles": {"one-point", "friction within", "friction at limit"},
    "slope": {"two-point", "friction at limit", "friction within"},
    "deep": {"deep", "relax_list", "moved out", "one-point"},
    "mixed": {"one-point", "two-point", "friction within"},
    "elastic": {"bounce listed", "approach inf", "one-point", "two-point"},
    "cradle": {"bounce listed", "one-point"},
    "explicit": {"two-point", "one-point", "bounce listed"},
    "overlap": {"two-point", "deep", "relax_list"},
}


@pytest.mark.parametrize("name", list(SCENES))
def test_solver_stages_agree(name):
    pair = Pair.from_text(SCENES[name])
    check = Checker(pair)
    done = 0
    for moment in MOMENTS[name]:
        pair.advance_numba(moment - done)
        step_by_stages(pair, check)
        done = moment + 1
    assert set(check.calls) == set(SOLVER_STAGES)
    # the scene holds what it is here for
    assert EXPECT[name] <= check.seen, EXPECT[name] - check.seen
    print(f"{name}: {check.calls} {sorted(check.seen)}, worst relative {check.worst_rel:.1e}")
