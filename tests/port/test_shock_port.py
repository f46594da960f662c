"""The C++ shock pass (cpp/src/solver/shock.cpp) against the numba one
(rbsim/engines/numba/shock.py).

Each case steps the numba engine to a moment, then runs the numba stages of one step by
hand (world.py's step) up to the shock pass of a chosen substep, so that the shock
pass's input is exactly what it sees mid-step; copies that into the C++ engine and runs
support_order, deep_region and propagate_shock in both. support_order and deep_region
are integer work: levels, orders, sides, the adjacency and the relax list must be
identical. propagate_shock's velocities agree to round-off: numba contracts a·b + c
into fused multiply-adds, the C++ build does not.
"""

from __future__ import annotations

import numpy as np
import pytest

from rbsim import constants as C
from rbsim.engines.numba.integrator import integrate_positions, integrate_velocities
from rbsim.engines.numba.shock import SHOCK_COS as C_SHOCK_COS
from rbsim.engines.numba.shock import propagate_shock
from rbsim.engines.numba.solver import (
    apply_restitution,
    keep_solve_impulses,
    solve_contacts,
    warm_start,
)
from rbsim.engines.numba.world import collide

from .harness import Pair

# velocities after the pass: fused multiply-adds in numba only (m/s, rad/s)
VEL_TOL = 1e-12

GROUND = "{name: ground, type: static, material: m, shape: {segment: {a: [-20, 0], b: [20, 0]}}}"


def scene(bodies: str, *, gravity="[0, -9.81]", restitution=0.0, solver="") -> str:
    return f"""
version: 1
world: {{gravity: {gravity}, dt: 1/60, steps: 1000}}
{solver}
materials:
  m: {{density: 1.0, friction: 0.6, restitution: {restitution}}}
bodies:
{bodies}
"""


SCENES = {
    "stack": scene(
        f"""  - {GROUND}
  - stack: {{count: 8, size: [1, 1], origin: [0, 0.5], spacing: 0.02, material: m}}"""
    ),
    "pyramid": scene(
        f"""  - {GROUND}
  - pyramid: {{base: 7, size: [1, 1], origin: [0, 0.5], spacing: 0.01, material: m}}"""
    ),
    # a 400 kg slab dropped on two 1 kg boxes: the case the shock pass exists for
    "slab": scene(
        f"""  - {GROUND}
  - {{name: left, position: [-9.5, 0.5], material: m, shape: {{box: {{size: [1, 1]}}}}}}
  - {{name: right, position: [9.5, 0.5], material: m, shape: {{box: {{size: [1, 1]}}}}}}
  - {{name: slab, position: [0, 2.5], mass: 400, material: m,
     shape: {{box: {{size: [20, 1]}}}}}}"""
    ),
    # a heavy box on a pyramid, and bodies touching each other in the air (unreached)
    "heavy_top": scene(
        f"""  - {GROUND}
  - pyramid: {{base: 4, size: [1, 1], origin: [0, 0.5], material: m}}
  - {{name: heavy, position: [0, 4.6], mass: 100, material: m, shape: {{box: {{size: [1, 1]}}}}}}
  - {{name: f1, position: [8, 6], velocity: [0, -3], material: m,
     shape: {{box: {{size: [1, 1]}}}}}}
  - {{name: f2, position: [8, 4.95], material: m, shape: {{box: {{size: [1, 1]}}}}}}"""
    ),
    # elastic balls dropped on the ground and on each other (restitution > 0 branch)
    "circles": scene(
        f"""  - {GROUND}
  - grid: {{count: [5, 4], spacing: [1.02, 1.3], origin: [-2, 0.6], material: m,
      shape: {{circle: {{radius: 0.5}}}}}}""",
        restitution=0.5,
    ),
    # no gravity: support_order does nothing, deep_region takes every manifold
    "no_gravity": scene(
        """  - {name: a, position: [0, 0], velocity: [2, 0], material: m,
     shape: {box: {size: [1, 1]}}}
  - {name: b, position: [1.3, 0.1], velocity: [-2, 0], material: m,
     shape: {box: {size: [1, 1]}}}
  - {name: c, position: [3, 0], material: m, shape: {circle: {radius: 0.5}}}""",
        gravity="[0, 0]",
    ),
    # a plank leaning on a wall: the wall's normal is horizontal (not support)
    "leaning": scene(
        f"""  - {GROUND}
  - {{name: wall, type: static, material: m, shape: {{segment: {{a: [2, 0], b: [2, 6]}}}}}}
  - {{name: plank, position: [1.0, 1.9], angle: -0.5, material: m,
     shape: {{box: {{size: [0.3, 4]}}}}}}
  - {{name: box, position: [-3, 0.5], angle: 0.3, material: m,
     shape: {{box: {{size: [1, 1]}}}}}}""",
        solver="solver: {integrator: explicit_euler}",
    ),
    # boxes overlapping deeply at the start: deep_region's breadth-first walk
    "overlap": scene(
        f"""  - {GROUND}
  - stack: {{count: 6, size: [1, 1], origin: [4, 0.5], spacing: 0.0, material: m}}
"""
        + "\n".join(
            f"  - {{position: [{x}, {y}], material: m, shape: {{box: {{size: [1, 1]}}}}}}"
            for x, y in [
                (-1.125, 0.5),
                (-0.375, 0.5),
                (0.375, 0.5),
                (1.125, 0.5),
                (-0.75, 1.25),
                (0, 1.25),
                (0.75, 1.25),
                (-0.375, 2),
                (0.375, 2),
                (0, 2.75),
                (0, 3.5),
                (0, 4.25),
            ]
            # a column with a deep overlap at its foot: deep_region's reach matters
            + [(-6, 0.5), (-6, 1.3)]
            + [(-6, 2.3 + k) for k in range(8)]
        )
    ),
    # a kinematic platform carrying boxes (level 0 that moves)
    "kinematic": scene(
        f"""  - {GROUND}
  - {{name: belt, type: kinematic, position: [0, 1], velocity: [0.5, 0.3], material: m,
     shape: {{box: {{size: [6, 0.4]}}}}}}
  - stack: {{count: 3, size: [0.8, 0.8], origin: [0, 1.6], spacing: 0.01, material: m}}
  - {{name: capsule, position: [2, 1.8], material: m,
     shape: {{segment: {{a: [-0.5, 0], b: [0.5, 0], radius: 0.2}}}}}}"""
    ),
}

MOMENTS = (0, 6, 40, 120)


def run_to_shock(pair: Pair, substep: int) -> None:
    """The numba engine's step by hand (world.py's step) up to its shock pass of
    `substep`: the shock pass's exact input mid-step."""
    w = pair.nb
    m, s, c, cfg = w.model, w.state, w.contacts, w.config
    assert m.has_shapes
    assert collide(m, s, w.grid, c, cfg), "contact store too small"
    delta = c.body_delta
    delta[:, 0:2] = 0.0
    delta[:, 2] = 1.0
    delta[:, 3] = 0.0
    h = cfg.dt / cfg.substeps
    inv_h = 1.0 / h
    shift = 0.0 if cfg.explicit else h
    sign = -1.0 if cfg.explicit else 1.0
    threshold = cfg.restitution_threshold
    c.count[5] = c.count[8] = c.count[9] = 0
    order, n_man = c.solve_order, c.count[0]
    for sub in range(substep + 1):
        if cfg.explicit:
            integrate_positions(m, s, delta, h, cfg.exact)
            integrate_velocities(m, s, h)
        else:
            integrate_velocities(m, s, h)
        warm_start(m, s, c)
        c.count[6] = 0
        for _ in range(cfg.iterations):
            solve_contacts(m, s, c, inv_h, True, 0.0, threshold, order, n_man)
        if not cfg.explicit:
            if cfg.elastic:
                keep_solve_impulses(c)
            integrate_positions(m, s, delta, h, cfg.exact)
        for _ in range(cfg.iterations):
            solve_contacts(m, s, c, inv_h, False, shift, threshold, order, n_man)
        # (the extra relax passes near a deep overlap are left out: the relax list they
        # leave is deep_region's, which the test compares itself)
        apply_restitution(m, s, c, threshold, h, sign)
        if sub < substep:
            propagate_shock(m, s, c, c.count[4], inv_h, threshold)


def unequal(pair: Pair, skip=()) -> list[str]:
    """The arrays not bit-identical in both engines (inf and NaN compare equal to
    themselves, unlike in pair.diff)."""
    return [
        name
        for name, a, b in pair._storage_pairs()
        if name not in skip and not np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    ]


INT_ARRAYS = ("body_level", "shock_side", "shock_order", "solve_order", "adj_start", "adj")


def check_moment(pair: Pair, substep: int) -> dict:
    """Run the three stages in both engines at the current moment; returns what the pass
    did (for the tests that the cases are not vacuous)."""
    run_to_shock(pair, substep)
    pair.sync()
    cfg = pair.nb.config
    count = pair.nb.contacts.count

    r_nb, r_cc = pair.run("support_order")
    assert r_nb == r_cc
    assert pair.diff(INT_ARRAYS + ("queue",)) == {}
    n_order = int(r_nb)
    assert n_order == count[4]  # same input as collide's own call

    # the relax list's seeds as the solve left them (count[6] deep points)
    # (short reaches too: the scenes are smaller than DEEP_RELAX_REACH)
    seeds = pair.nb.contacts.relax_list.copy()
    for reach in (1, 2, C.DEEP_RELAX_REACH):
        pair.nb.contacts.relax_list[:] = seeds
        pair.cc.storage.relax_list[:] = seeds
        r_nb, r_cc = pair.run("deep_region", reach=reach)
        assert r_nb == r_cc
        assert pair.diff(("relax_list", "body_reach", "queue")) == {}

    v0 = pair.nb.state.body_v.copy()
    w0 = pair.nb.state.body_w.copy()
    inv_h = cfg.substeps / cfg.dt
    pair.run(
        "propagate_shock",
        n_order=n_order,
        inv_h=inv_h,
        threshold=cfg.restitution_threshold,
    )
    assert pair.diff(("body_v", "body_w"), atol=VEL_TOL) == {}
    assert unequal(pair, skip=("body_v", "body_w")) == []  # the pass writes velocities only
    changed = float(
        max(np.abs(pair.nb.state.body_v - v0).max(), np.abs(pair.nb.state.body_w - w0).max())
    )
    c = pair.nb.contacts
    n_man = int(count[0])
    g = np.asarray(pair.nb.model.gravity, dtype=float)
    up = -g / max(np.hypot(*g), 1e-300)
    cos = np.abs(c.normal[:n_man] @ up)
    steep = (c.points[:n_man] > 0) & (cos < C_SHOCK_COS)
    assert not (c.shock_side[:n_man][steep] != 0).any()  # a steep contact is never support
    return {
        "steep": int(steep.sum()),
        "n_order": n_order,
        "deep": int(count[6]),
        "near": int(r_nb),
        "changed": changed,
        "unreached": int((pair.nb.contacts.body_level == 1 << 30).sum()),
    }


def walk(name: str) -> list[dict]:
    pair = Pair.from_text(SCENES[name])
    out = []
    done = 0
    for k in MOMENTS:
        pair.advance_numba(k - done)
        done = k
        substeps = pair.nb.config.substeps
        for sub in (0, substeps - 1):
            out.append(check_moment(pair, sub))
            done += 1  # the step taken by hand (its remaining substeps are skipped)
    return out


@pytest.mark.parametrize("name", sorted(SCENES))
def test_shock_stages_agree(name):
    info = walk(name)
    if name == "no_gravity":
        assert all(i["n_order"] == 0 and i["changed"] == 0.0 for i in info)
    else:
        assert any(i["n_order"] > 0 for i in info)


def test_cases_reach_the_branches():
    """The scenes exercise what they are there for: the pass pushes in the stacks and
    under the slab, deep overlaps seed deep_region, bodies off the ground are unreached."""
    assert any(i["changed"] > 0 for i in walk("slab"))
    assert any(i["changed"] > 0 for i in walk("stack"))
    overlap = walk("overlap")
    assert any(0 < i["near"] < max(j["n_order"] for j in overlap) + 20 for i in overlap)
    assert any(i["deep"] > 0 for i in overlap)
    assert any(i["unreached"] > 0 for i in walk("heavy_top"))
    assert all(i["steep"] > 0 for i in walk("leaning")[2:])  # the plank on the wall
