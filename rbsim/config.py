"""A run's settings for the engine (Config, from the scene's world and solver blocks),
and what the engines raise. Pure Python: building a world in the compiled engine
imports nothing heavier than numpy."""

from __future__ import annotations

from typing import NamedTuple

from .scene import Scene
from .scene.types import MIXING


class NonFiniteState(RuntimeError):
    """The state became NaN or infinite: `body` (index) at `step`."""

    def __init__(self, body: int, step: int) -> None:
        super().__init__(f"state of body {body} became non-finite at step {step}")
        self.body = body
        self.step = step


class Config(NamedTuple):
    """Per-run numbers for the engine: dt (s), substeps, iterations per substep,
    explicit (explicit Euler), exact (exact rotation), restitution_threshold (m/s),
    friction_rule and restitution_rule (MIX_*), elastic (some material has
    restitution > 0). The engine derives the soft contacts' stiffness from dt and
    substeps itself (set_contact_softness in cpp/src/step.cpp)."""

    dt: float
    substeps: int
    iterations: int
    explicit: bool
    exact: bool
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
        exact=sol.rotation == "exact",
        restitution_threshold=float(sol.restitution_threshold),
        friction_rule=MIXING[scene.world.friction_mixing],
        restitution_rule=MIXING[scene.world.restitution_mixing],
        elastic=any(sh.material.restitution > 0.0 for b in scene.bodies for sh in b.shapes),
    )
