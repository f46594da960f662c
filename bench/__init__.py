"""Benchmarks: rbsim against pymunk on the same scenes, in the same process."""

from __future__ import annotations

import dataclasses

from rbsim.scene import Scene

# the relative change of gravity from one from-rest round to the next (the_round)
ROUND_NUDGE = 1e-9


def print_header(columns: str) -> None:
    """Print a table's column line and a rule of its width under it."""
    print(columns)
    print("-" * len(columns))


def the_round(scene: Scene, k: int) -> Scene:
    """``scene`` with gravity (m/s²) scaled by 1 + k ROUND_NUDGE: the trajectory of round k
    of a from-rest timing. A pile forming or a heap landing is chaotic, and one
    trajectory's time is one draw from a spread (800 circles raining took 414 to 586 µs a
    step over six such rounds): the rounds measure that spread, not one trajectory's
    time again and again."""
    gravity = tuple(g * (1.0 + k * ROUND_NUDGE) for g in scene.world.gravity)
    return dataclasses.replace(scene, world=dataclasses.replace(scene.world, gravity=gravity))
