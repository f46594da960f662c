"""A run's settings for the engine (Config, from the scene's world and solver blocks),
and what the engines raise. Pure Python: building a world in the compiled engine
imports nothing heavier than numpy."""

from __future__ import annotations

from typing import NamedTuple

from .scene import Scene
from .scene.types import MIXING, ROTATION_CODE


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


class Config(NamedTuple):
    """Per-run numbers for the engine: dt (s), substeps, iterations per substep,
    explicit (explicit Euler), rotation (the rotation update's code,
    scene.types.ROTATION_CODE: normalize 0, exact 1, split 2; in 2D split turns as exact
    does, the rotation having one axis), restitution_threshold (m/s),
    friction_rule and restitution_rule (MIX_*), elastic (some material has
    restitution > 0). The engine derives the soft contacts' stiffness from dt and
    substeps itself (set_contact_softness in cpp/src/step.cpp)."""

    dt: float
    substeps: int
    iterations: int
    explicit: bool
    rotation: int
    restitution_threshold: float
    friction_rule: int
    restitution_rule: int
    elastic: bool


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
    )
