"""The continuous sweep (cpp/src/collide/continuous.cpp), end to end in 2D and 3D: a body
struck within a step far beyond its contacts' reach does not pass through a static wall."""

from __future__ import annotations

import numpy as np
import pytest

from rbsim.core import CoreWorld

from .conftest import scene_from, vector

# A ball of 5 cm at rest 25 cm in front of a static wall 10 cm thick (x 0.3 .. 0.4), struck
# by a ball of 10 cm four (2D) or eight (3D) times its mass at 60 m/s: within the step the
# small ball goes a metre, where its contacts, found at rest, reached 2 cm.
STRUCK = """\
version: 1
world: {{dimension: {dim}, dt: 1/60, steps: 30, gravity: {zero}}}
materials:
  m: {{density: 1000, friction: 0.3, restitution: {e}}}
bodies:
  - {{name: wall, type: static, material: m, position: {wall}, shape: {{box: {{size: {size}}}}}}}
  - {{name: small, material: m, position: {origin}, shape: {ball_small}}}
  - {{name: striker, material: m, position: {left}, velocity: {fast}, shape: {ball_big}}}
"""


def struck(dim: int, e: float) -> np.ndarray:
    """The small ball's x (m) after each step of the struck scene."""
    ball = "circle" if dim == 2 else "sphere"
    text = STRUCK.format(
        dim=dim,
        e=e,
        zero=vector(dim, 0, 0, 0),
        wall=vector(dim, 0.35, 0, 0),
        size=vector(dim, 0.1, 1, 1),
        origin=vector(dim, 0, 0, 0),
        left=vector(dim, -0.2, 0, 0),
        fast=vector(dim, 60, 0, 0),
        ball_small=f"{{{ball}: {{radius: 0.05}}}}",
        ball_big=f"{{{ball}: {{radius: 0.1}}}}",
    )
    world = CoreWorld.from_scene(scene_from(text))
    xs = []
    for _ in range(world.scene.world.steps):
        world.advance(1)
        xs.append(world.state.body_x[1, 0])
    return np.array(xs)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_ball_struck_towards_a_wall_bounces_off_it(dim: int) -> None:
    # (before the sweep it went through: 36 m beyond the wall after 0.5 s in 2D, 40 m in 3D)
    x = struck(dim, 0.5)
    assert x.max() < 0.26  # touching at 0.25; 1 cm for the soft contact's give at 60 m/s
    assert x[-1] < 0.0  # bounced back


@pytest.mark.parametrize("dim", [2, 3])
def test_a_ball_struck_into_a_wall_stays_in_front_of_it(dim: int) -> None:
    # e = 0: the striker, stopped at the wall by its own contact, presses the small ball
    # into it the step after (an overlap between two dynamic bodies, which the sweep does
    # not see), never past the wall's middle, and it is pushed back out
    x = struck(dim, 0.0)
    assert x.max() < 0.35
    assert x[-1] < 0.25
