"""Whole steps: the compiled engine against the numba one it was ported from.

Scenes without contact decisions that round-off can flip (free flight, a lone bounce,
a head-on collision, a block on a slope, a resting stack) follow the numba engine to
round-off over their whole run; chaotic ones (piles, pyramids settling, a card house)
agree at first and drift apart once a round-off difference flips a decision (a block
solve's clamp, a contact made one step later), as two runs of one engine would under
any change of rounding. `python -m tests.port.agreement` prints the full table.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rbsim.core import CoreWorld
from rbsim.engines.numba.world import World
from rbsim.scene import load_scene

from .agreement import DEFAULT_SCENES, state_difference
from .harness import Pair

ROOT = Path(__file__).resolve().parents[2]

# follow the numba engine to round-off over their whole run (or 300 steps)
ROUND_OFF_SCENES = [
    "scenes/compare/projectile.yaml",
    "scenes/compare/free_spin.yaml",
    "scenes/compare/constant_torque.yaml",
    "scenes/compare/head_on.yaml",
    "scenes/compare/off_centre.yaml",
    "scenes/compare/bounce.yaml",
    "scenes/compare/slope_slide.yaml",
    "scenes/compare/stack.yaml",
    "scenes/reference/collision.yaml",
    "scenes/reference/slide.yaml",
    "scenes/reference/stack.yaml",
    "scenes/hard/cradle.yaml",
    "scenes/hard/restitution_elastic.yaml",
    "scenes/hard/restitution_half.yaml",
    "scenes/hard/stack15.yaml",
    "scenes/hard/arch.yaml",
    "scenes/bounce.yaml",
    "scenes/compound.yaml",
    "scenes/spin.yaml",
    "scenes/torque.yaml",
    "scenes/pyramid.yaml",
]
# 1e-9 m and m/s: round-off (the engines fuse multiply-adds in different places in the
# geometry) grows through hundreds of contact solves, but stays far below this
ROUND_OFF = 1e-9


def _run_both(path: Path, steps: int):
    scene = load_scene(path)
    nb, cc = World.from_scene(scene), CoreWorld.from_scene(scene)
    worst = (0.0, 0.0)
    for _ in range(min(steps, scene.world.steps)):
        nb.advance(1)
        cc.advance(1)
        dx, dv = state_difference(nb.state, cc.state)
        worst = (max(worst[0], dx), max(worst[1], dv))
    return worst


@pytest.mark.parametrize("name", ROUND_OFF_SCENES)
def test_scene_follows_the_numba_engine_to_round_off(name):
    dx, dv = _run_both(ROOT / name, 300)
    assert dx < ROUND_OFF and dv < ROUND_OFF, (dx, dv)


@pytest.mark.parametrize("path", DEFAULT_SCENES, ids=lambda p: str(p.relative_to(ROOT)))
def test_first_step_agrees_on_every_scene(path):
    # chaotic scenes too: the first step is the same computation up to round-off (the
    # base-100 pyramid flips a block-solve decision within 10 steps)
    dx, dv = _run_both(path, 1)
    assert dx < ROUND_OFF and dv < ROUND_OFF, (dx, dv)


QUAD_BOX = ROOT / "tests" / "port" / "data" / "spinning_quads.yaml"


def _modified_energy(world) -> float:
    m, s = world.model, world.state
    d = m.body_type == 0
    return float(
        0.5 * (m.body_mass[d] * (s.body_v[d] ** 2).sum(axis=1)).sum()
        + 0.5 * (m.body_inertia[d] * s.body_w[d] ** 2).sum()
    )


def _load_state(world: CoreWorld, path: Path) -> None:
    """Put a saved state and contact store (tests/port/data/*.npz) into a world."""
    saved = np.load(path)
    if world.contacts.key.shape[0] != saved["key"].shape[0]:
        world.engine.grow(saved["key"].shape[0])
    storage = world.engine.storage()
    for name in saved.files:
        if name.startswith("state."):
            getattr(world.engine, name[6:])[...] = saved[name]
        elif name.startswith("grid."):
            storage["grid"][name[5:]][...] = saved[name]
        elif name == "step_index":
            world.engine.step_index = int(saved[name])
        else:
            storage[name][...] = saved[name]


def test_an_energy_loss_of_the_compiled_engine_is_the_numba_engines_from_the_same_state():
    # 20 spinning elastic quadrilaterals in a closed box, no gravity (the scene of
    # test_contacts' energy test): the compiled engine's trajectory, different from
    # the numba one's by round-off, reached at step 466 two quadrilaterals that passed
    # 1.5 cm into each other within one step (a corner of a spinning body the
    # speculative points did not see), and their soft push-out lost 1.1e-5 of the
    # energy in step 468. From that state (saved: the run depends on the build's
    # rounding) the numba engine takes the same step and loses the same energy: the
    # algorithm's limitation, not the port's.
    pair = Pair(load_scene(QUAD_BOX))
    _load_state(pair.cc, QUAD_BOX.with_name("spinning_quads_step467.npz"))
    pair.sync_to_numba()
    e0 = _modified_energy(pair.cc)
    pair.nb.advance(1)
    pair.cc.advance(1)
    lost_cc = 1.0 - _modified_energy(pair.cc) / e0
    lost_nb = 1.0 - _modified_energy(pair.nb) / e0
    assert lost_cc > 1e-6  # the loss happens at this step
    assert lost_nb == pytest.approx(lost_cc, rel=1e-9)  # and the same in both
    assert np.max(np.abs(pair.nb.state.body_v - pair.cc.state.body_v)) < 1e-12
