"""The 3D example scene scenes/3d/collapsing_pile.yaml: the iron ball knocks the
pyramid down and the pieces come to rest on the ground, none through it (the ball and
the capsules roll on)."""

from __future__ import annotations

import numpy as np

from rbsim.engines import make_engine
from rbsim.scene import load_scene
from rbsim.scene.library import scenes_dir


def test_collapsing_pile_falls_and_comes_to_rest_above_the_ground():
    sim = make_engine("rbsim", load_scene(scenes_dir("3d") / "collapsing_pile.yaml"))
    names = [b.name for b in sim.scene.bodies]
    boxes = np.array([n.startswith("pyramid") for n in names])
    ball = names.index("ball")
    first = sim.read()
    sim.advance(int(sim.scene.world.steps))
    last = sim.read()
    assert first.com[boxes, 1].max() == 1.75  # m: the top of 4 layers of 0.5 m boxes
    # collapsed: no box stands higher than two layers (0.75 m, its centre)
    assert last.com[boxes, 1].max() < 0.75 + 0.01  # m: a resting box's soft sag and tilt
    # nothing below the ground: every body's centre above it by more than 5 cm (the
    # smallest half-extent, a capsule's radius of 0.1 m, less the soft contacts' give)
    assert last.com[sim.dynamic, 1].min() > 0.05
    # the boxes and the pebbles at rest; the ball and the capsules may roll on (nothing
    # resists rolling in rbsim, as in the notes' Coulomb friction), and so may what
    # lies against one that rolls (the pile is chaotic: where the pieces end up changes
    # with the rounding of any change to the solver, and with it whether a pebble or a
    # box touches a capsule still rolling on the boxes at the end)
    rolls = np.array([n.startswith(("ball", "stick")) for n in names])
    c = sim.world.contacts
    m = int(c.count[0])
    touching = c.normal_impulse[:m].sum(axis=1) > 0  # manifolds that pushed
    a, b = c.body_a[:m][touching], c.body_b[:m][touching]
    pushed = np.zeros(len(names), bool)
    pushed[a[rolls[b]]] = pushed[b[rolls[a]]] = True
    v = np.linalg.norm(last.velocity, axis=1)
    still = np.array([n.startswith(("pyramid", "pebble")) for n in names]) & ~pushed
    assert still.sum() >= 20  # most of the 30 boxes and 4 pebbles rest clear of the rollers
    assert v[still].max() < 0.01  # m/s: the 2D stack's "at rest"
    assert last.com[ball, 0] > 3.0  # m: the ball went through the pile and out the far side
