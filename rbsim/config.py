"""A run's settings for the engine (Config, from the scene's world and solver blocks),
and what the engines raise. Pure Python: building a world in the compiled engine
imports nothing heavier than numpy."""

from __future__ import annotations

import math
from typing import NamedTuple

from .scene import Scene
from .scene.types import MIXING


class NonFiniteState(RuntimeError):
    """The state became NaN or infinite: `body` (index) at `step`."""

    def __init__(self, body: int, step: int) -> None:
        super().__init__(f"state of body {body} became non-finite at step {step}")
        self.body = body
        self.step = step


def soft_parameters(hertz: float, damping_ratio: float, h: float) -> tuple[float, float, float]:
    """(mass scale, impulse scale, bias rate 1/s) of a soft constraint for substep h (s).

    An implicit damped spring of frequency `hertz` and the given damping ratio,
    integrated with step h, expressed as scalings of the rigid impulse.
    """
    if hertz == 0.0:
        return 1.0, 0.0, 0.0
    omega = 2.0 * math.pi * hertz
    a1 = 2.0 * damping_ratio + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return a2 * a3, a3, omega / a1


class Config(NamedTuple):
    """Per-run numbers for the engine: dt (s), substeps, iterations per substep,
    explicit (explicit Euler), exact (exact rotation), restitution_threshold (m/s),
    friction_rule and restitution_rule (MIX_*), elastic (some material has
    restitution > 0), soft and soft_static (mass scale, impulse scale, bias rate 1/s)
    for the substep length."""

    dt: float
    substeps: int
    iterations: int
    explicit: bool
    exact: bool
    restitution_threshold: float
    friction_rule: int
    restitution_rule: int
    elastic: bool
    soft: tuple[float, float, float]
    soft_static: tuple[float, float, float]


def make_config(scene: Scene) -> Config:
    """Engine settings from the scene's world and solver blocks."""
    from . import constants as C  # the engine's (rbsim.core imports this module)

    sol = scene.solver
    h = scene.world.dt / sol.substeps
    hertz = min(C.CONTACT_HERTZ, 0.25 / h)
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
        soft=soft_parameters(hertz, C.CONTACT_DAMPING_RATIO, h),
        soft_static=soft_parameters(2.0 * hertz, C.CONTACT_DAMPING_RATIO, h),
    )
