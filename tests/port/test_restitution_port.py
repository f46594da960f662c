"""The C++ restitution stage (keep_solve_impulses, apply_restitution) against the numba one.

The numba step is replayed stage by stage (as rbsim/engines/numba/world.py's step calls them); at
keep_solve_impulses (its first 100 calls, then wherever a bounce is listed) and at every
apply_restitution that has something to do (bounce_count != bounce_carried, up to
max_checks), the whole numba state and storage is copied into the C++ engine, the stage
runs in both, and every array is compared: integers exactly, floats to RTOL. The numba engine then
goes on from its own result, so a run checks the stage on each of its real inputs.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from rbsim import constants as C
from rbsim.engines.numba.contacts import store_impulses
from rbsim.engines.numba.integrator import integrate_positions, integrate_velocities
from rbsim.engines.numba.shock import deep_region, propagate_shock
from rbsim.engines.numba.solver import (
    _ALONE,
    _JOINED,
    _PUSHING,
    _QUIET,
    apply_restitution,
    limit_static_overlap,
    solve_contacts,
    warm_start,
)
from rbsim.engines.numba.world import collide

from .harness import Pair

HARD = Path(__file__).resolve().parents[2] / "scenes" / "hard"
SCENES = HARD.parent

# Floats may differ at round-off: the numba kernels are compiled with fastmath
# "contract" (fused multiply-adds where LLVM likes) and normal_velocity sums its terms
# in another order. Velocities are O(1-10) m/s, impulses O(1-100) N·s.
RTOL = 1e-12
# integer arrays and counters must agree exactly
INTEGER = ("bounce_kind", "body_mark", "bounce_list", "count")

BOXES_ON_CORNER = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 240}
materials:
  elastic: {density: 1.0, friction: 0.3, restitution: 1.0}
bodies:
  - {name: ground, type: static, material: elastic, shape: {segment: {a: [-8, 0], b: [8, 0]}}}
  - {name: wall, type: static, material: elastic, position: [5, 2], shape: {box: {size: [0.4, 4]}}}
  # one lands on a corner, one flat (the two-point block), one tilted into the wall's corner
  - {name: corner, position: [-3, 2.5], angle: 0.6, material: elastic,
     shape: {box: {size: [1, 0.6]}}}
  - {name: flat, position: [0, 1.5], material: elastic, shape: {box: {size: [1.2, 0.5]}}}
  - {name: tilted, position: [3.8, 3.5], angle: -0.3, velocity: [2, 0], angular_velocity: 1.5,
     material: elastic, shape: {box: {size: [0.8, 0.8]}}}
"""

BALL_ON_STACK = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 180}
materials:
  wood: {density: 1.0, friction: 0.6, restitution: 0.0}
  elastic: {density: 1.0, friction: 0.2, restitution: 1.0}
bodies:
  - {name: ground, type: static, material: wood, shape: {segment: {a: [-6, 0], b: [6, 0]}}}
  - stack: {count: 4, size: [1, 1], origin: [0, 0.5], spacing: 0.0, material: wood}
  # falls on the stack's top box, which rests on the others (a JOINED cluster)
  - {name: ball, position: [0.1, 6.5], material: elastic, shape: {circle: {radius: 0.3}}}
  # and a pair of elastic balls dropped onto an elastic ball resting on the ground
  - {name: rest, position: [3, 0.3], material: elastic, shape: {circle: {radius: 0.3}}}
  - {name: drop, position: [3.05, 3.5], material: elastic, shape: {circle: {radius: 0.3}}}
"""

# flat elastic boxes dropped from heights 0.6 + 0.0731 k m: at some the first impact is
# taken by the biased solve (before the positions move), so the two-point block also
# returns gravity's work
FLAT_BOXES = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 60}
materials:
  elastic: {density: 1.0, friction: 0.3, restitution: 1.0}
bodies:
  - {name: ground, type: static, material: elastic, position: [0, -0.5],
     shape: {box: {size: [80, 1]}}}
""" + "\n".join(
    f"  - {{name: f{k}, position: [{2 * k - 30}, {0.6 + 0.0731 * k:.4f}], material: elastic,"
    " shape: {box: {size: [1.2, 0.5]}}}"
    for k in range(30)
)

# and nearly flat, turning: the block would pull at the point that approaches slower, and
# the points are bounced one at a time (the one furthest below its target first)
SPINNING_BOXES = (
    FLAT_BOXES
    + "\n"
    + "\n".join(
        f"  - {{name: s{k}, position: [{2 * k - 30}, {3.7 + 0.0731 * k:.4f}],"
        f" angle: {0.004 * k:.4f}, angular_velocity: {(-1) ** k * 0.3 * k:.3f}, material: elastic,"
        " shape: {box: {size: [1.2, 0.5]}}}"
        for k in range(30)
    )
)

FAST_INELASTIC = """
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 60}
bodies:
  - {name: wall, type: static, position: [6.05, 0], shape: {box: {size: [0.1, 40]}}}
  - {name: ball, position: [0, 0], velocity: [90, 0], shape: {circle: {radius: 0.05}}}
  - {name: spinner, position: [0, 3], velocity: [70, 0], angular_velocity: 40,
     shape: {box: {size: [0.6, 0.2]}}}
  - {name: ground, type: static, shape: {segment: {a: [-5, -5], b: [5, -5]}}}
  - {name: faller, position: [0, -2], velocity: [0, -12], restitution: 0.5,
     shape: {circle: {radius: 0.2}}}
"""


def scene_text(name: str) -> str:
    """The text of a scene file of scenes/hard/ or scenes/."""
    path = HARD / name if (HARD / name).exists() else SCENES / name
    return path.read_text()


def replay(pair: Pair, steps: int, max_checks: int = 400):
    """Step the numba engine `steps` steps stage by stage, checking the restitution
    stages against C++ on the way. Returns (restitution calls checked, the bounce kinds
    they left, worst differences per array, deferred bounces carried)."""
    nb = pair.nb
    model, state, cfg = nb.model, nb.state, nb.config
    h = cfg.dt / cfg.substeps
    inv_h = 1.0 / h
    shift = 0.0 if cfg.explicit else h
    sign = -1.0 if cfg.explicit else 1.0
    threshold = cfg.restitution_threshold
    checks = bounces = kept = 0
    kinds: Counter = Counter()
    worst: dict[str, float] = {}
    carried = 0

    def compare(stage: str, **args) -> None:
        nonlocal checks
        pair.sync()
        pair.run(stage, **args)
        checks += 1
        bad = {}
        for name, a, b in pair._storage_pairs():
            a, b = np.asarray(a), np.asarray(b)
            assert a.shape == b.shape, name
            if name in INTEGER or a.dtype.kind != "f":
                if not np.array_equal(a, b):
                    bad[name] = "differs"
                continue
            both_nan = np.isnan(a) & np.isnan(b)
            same_inf = np.isinf(a) & (a == b)
            with np.errstate(invalid="ignore"):
                d = np.where(both_nan | same_inf, 0.0, np.abs(a - b))
            d = np.nan_to_num(d, nan=np.inf, posinf=np.inf)
            scale = np.maximum(1.0, np.where(np.isfinite(a), np.abs(a), 0.0))
            if (d > RTOL * scale).any():
                bad[name] = float(d.max())
            if d.size:
                worst[name] = max(worst.get(name, 0.0), float(d.max()))
        assert not bad, f"step {nb.step_index}, {stage}: {bad}"

    for _ in range(steps):
        c = nb.contacts
        if not collide(model, state, nb.grid, c, cfg):
            nb.advance(1)  # the store grows (nothing moved yet); this step goes unchecked
            continue
        delta = c.body_delta
        delta[:, 0] = delta[:, 1] = delta[:, 3] = 0.0
        delta[:, 2] = 1.0
        c.count[5] = c.count[8] = c.count[9] = 0
        order, n_man = c.solve_order, c.count[0]
        for _ in range(cfg.substeps):
            if cfg.explicit:
                integrate_positions(model, state, delta, h, cfg.exact)
                integrate_velocities(model, state, h)
            else:
                integrate_velocities(model, state, h)
            warm_start(model, state, c)
            c.count[6] = 0
            for _ in range(cfg.iterations):
                solve_contacts(model, state, c, inv_h, True, 0.0, threshold, order, n_man)
            if not cfg.explicit:
                if cfg.elastic:
                    if kept < 100 or c.count[5] != c.count[8]:
                        kept += 1
                        compare("keep_solve_impulses")
                    else:
                        pair.run("keep_solve_impulses")
                integrate_positions(model, state, delta, h, cfg.exact)
            for _ in range(cfg.iterations):
                solve_contacts(model, state, c, inv_h, False, shift, threshold, order, n_man)
            if c.count[6]:
                n_near = deep_region(model, c, C.DEEP_RELAX_REACH)
                for _ in range(cfg.iterations * (C.DEEP_RELAX_FACTOR - 1)):
                    solve_contacts(
                        model, state, c, inv_h, False, shift, threshold, c.relax_list, n_near
                    )
            if c.count[5] != c.count[8] and bounces < max_checks:
                compare("apply_restitution", threshold=threshold, h=h, sign=sign)
                bounces += 1
                n = c.count[0]
                kinds.update(zip(c.bounce_kind[:n].tolist(), c.points[:n].tolist(), strict=True))
                carried += int(c.count[8])
            else:
                apply_restitution(model, state, c, threshold, h, sign)
            propagate_shock(model, state, c, c.count[4], inv_h, threshold)
        limit_static_overlap(model, state, c, C.STATIC_OVERLAP_LIMIT)
        store_impulses(c)
        nb.step_index += 1
    return bounces, kinds, worst, carried


EXPLICIT = "\nsolver: {integrator: explicit_euler}\n"
EXPLICIT_T0 = "\nsolver: {integrator: explicit_euler, restitution_threshold: 0.0}\n"


def with_solver(text: str, solver: str) -> str:
    """text with its `solver:` line (if any) replaced by `solver`."""
    lines = [ln for ln in text.splitlines() if not ln.startswith("solver:")]
    return "\n".join(lines) + solver


# case: (scene, steps, what the stage must have met: bounce kinds, or (kind, points))
CASES = {
    # elastic balls dropped on a ground from 1..10 m, e = 1: each a lone cluster
    "elastic_balls": (scene_text("restitution_elastic.yaml"), 200, {_ALONE}),
    "elastic_balls_explicit": (
        with_solver(scene_text("restitution_elastic.yaml"), EXPLICIT),
        200,
        {_ALONE},
    ),
    # e = 0.5, and e from 0.2 to 1 with friction
    "half": (scene_text("restitution_half.yaml"), 200, {_ALONE}),
    "bounce": (scene_text("bounce.yaml"), 300, {_ALONE}),
    # Newton's cradle: a row of touching balls, e = 1, threshold 0 (passive points join)
    "cradle": (scene_text("cradle.yaml"), 60, {_ALONE}),
    "cradle_explicit": (with_solver(scene_text("cradle.yaml"), EXPLICIT_T0), 60, {_ALONE}),
    # elastic circles in a closed box, threshold 0
    "long_run": (scene_text("long_run.yaml"), 150, {_ALONE}),
    "long_run_explicit": (with_solver(scene_text("long_run.yaml"), EXPLICIT_T0), 100, {_ALONE}),
    # elastic boxes on a corner, flat (the two-point block) and into a wall
    "boxes": (BOXES_ON_CORNER, 200, {(_ALONE, 1), (_ALONE, 2)}),
    "boxes_t0": (
        with_solver(BOXES_ON_CORNER, "\nsolver: {restitution_threshold: 0.0}\n"),
        150,
        {(_ALONE, 2)},
    ),
    "flat_boxes": (FLAT_BOXES, 60, {(_ALONE, 2)}),
    "spinning_boxes": (SPINNING_BOXES, 60, {(_ALONE, 2)}),
    # an elastic ball on a resting stack (JOINED), balls on a resting ball
    "ball_on_stack": (BALL_ON_STACK, 180, {_JOINED, _PUSHING}),
    "ball_on_stack_t0": (
        with_solver(BALL_ON_STACK, "\nsolver: {restitution_threshold: 0.0}\n"),
        120,
        {_JOINED, _ALONE, (_JOINED, 2)},
    ),
    # fast inelastic bodies one substep from a wall (the deferred branch; their kinds are
    # reset to QUIET as the stage leaves)
    "fast_inelastic": (FAST_INELASTIC, 40, {_QUIET}),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_restitution_matches_numba(case):
    text, steps, expect = CASES[case]
    pair = Pair.from_text(text)
    checks, kinds, worst, carried = replay(pair, steps)
    print(case, checks, dict(kinds), carried, {k: v for k, v in worst.items() if v})
    assert checks > 0
    seen = set(kinds) | {k for k, _ in kinds}
    missing = expect - seen
    assert not missing, f"{case}: the stage never met {missing}: {dict(kinds)}"
    if case == "fast_inelastic":
        assert carried > 0, "no deferred bounce was carried"
