"""A run's settings for the engine (Config, from the scene's world and solver blocks),
and what the engines raise. Pure Python: building a world in the compiled engine
imports nothing heavier than numpy."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NamedTuple

from .scene import Scene
from .scene.schema import THREADS_MAX
from .scene.types import MIXING, ROTATION_CODE

# the thread count of a scene that does not set solver.threads in this process (None: the
# cores it may run on); worker processes of `rbsim batch` and `rbsim sweep` set 1
_process_threads: int | None = None


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextmanager
def threads_default(threads: int | None) -> Iterator[None]:
    """Within the block, scenes that do not set solver.threads run on `threads` threads
    (None: the cores, available_cores()); the previous default after it. A worker
    process that runs scenes side by side with other workers sets 1, so that the workers
    do not oversubscribe the cores; the results do not change (they are the same for
    every thread count)."""
    global _process_threads
    if threads is not None and not 1 <= threads <= THREADS_MAX:
        raise ValueError(f"threads must be between 1 and {THREADS_MAX}, got {threads}")
    previous, _process_threads = _process_threads, threads
    try:
        yield
    finally:
        _process_threads = previous


def default_threads() -> int:
    """The threads of a scene that does not set solver.threads: threads_default's value
    where one is in force, else the cores, at most THREADS_MAX."""
    if _process_threads is not None:
        return _process_threads
    return min(available_cores(), THREADS_MAX)


class NonFiniteState(RuntimeError):
    """The state of `body` (index) became NaN or infinite at `step`, or, with `beyond`
    (m), the body left the region the engine simulates (|x| or |y| > beyond; in a world
    of `dimension` 3, |x|, |y| or |z|)."""

    def __init__(
        self, body: int, step: int, beyond: float | None = None, dimension: int = 2
    ) -> None:
        self.body = body
        self.step = step
        self.beyond = beyond
        self.dimension = dimension
        super().__init__(f"{self.describe(f'{body}')} at step {step}")

    def describe(self, name: str) -> str:
        """What happened to the body called `name`, as a sentence's start: "the state
        of body 'b' became non-finite", "body 'b' left the simulated region (...)"."""
        if self.beyond is None:
            return f"the state of body {name} became non-finite"
        limit = f"{self.beyond:g}".replace("e+0", "e").replace("e+", "e")
        axes = "|x|, |y| or |z|" if self.dimension == 3 else "|x| or |y|"
        return f"body {name} left the simulated region ({axes} > {limit} m)"


class TooManyPairs(RuntimeError):
    """The step after `step` would hold `pairs` contact pairs, more than the engine's
    `limit` (shapes pressed into one another; cli.md, "The contact pairs of a step"): no
    step was taken from that state."""

    def __init__(self, pairs: int, limit: int, step: int) -> None:
        self.pairs = pairs
        self.limit = limit
        self.step = step
        super().__init__(f"more than {limit:,} contact pairs ({pairs:,}) at step {step + 1}")


class Config(NamedTuple):
    """Per-run numbers for the engine: dt (s), substeps, iterations per substep,
    explicit (explicit Euler), rotation (the rotation update's code,
    scene.types.ROTATION_CODE: normalize 0, exact 1, split 2; in 2D split turns as exact
    does, the rotation having one axis), restitution_threshold (m/s),
    friction_rule and restitution_rule (MIX_*), elastic (some material has
    restitution > 0), threads (the step's threads, >= 1), choose_threads (solver.threads
    not set and no threads_default in force: each step runs on one thread or on
    `threads`, whichever the run's trials timed faster; the same result). The engine
    derives the soft contacts' stiffness from dt and substeps itself
    (set_contact_softness in cpp/src/step.cpp)."""

    dt: float
    substeps: int
    iterations: int
    explicit: bool
    rotation: int
    restitution_threshold: float
    friction_rule: int
    restitution_rule: int
    elastic: bool
    threads: int = 1
    choose_threads: bool = False


def make_config(scene: Scene) -> Config:
    """Engine settings from the scene's world and solver blocks."""
    sol = scene.solver
    return Config(
        dt=float(scene.world.dt),
        substeps=int(sol.substeps),
        iterations=int(sol.iterations),
        explicit=sol.integrator == "explicit_euler",
        rotation=ROTATION_CODE[sol.rotation],
        restitution_threshold=float(sol.restitution_threshold),
        friction_rule=MIXING[scene.world.friction_mixing],
        restitution_rule=MIXING[scene.world.restitution_mixing],
        elastic=any(sh.material.restitution > 0.0 for b in scene.bodies for sh in b.shapes),
        threads=int(sol.threads) if sol.threads is not None else default_threads(),
        choose_threads=sol.threads is None and _process_threads is None,
    )
