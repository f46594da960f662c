"""Fast bodies through the speculative contacts and the time of impact: what one fast
body's contact does must not depend on another fast body elsewhere in the scene, and a
fast body bounces where it meets what it hits, not a substep's travel before it."""

from __future__ import annotations

import numpy as np

import rbsim

# A 500 m/s steel ball flies at a static wall, and a 500 m/s box at a static floor 2 m
# above the ball's path. Their free paths come within 1.3 m of each other 13 ms into the
# first step (after each has hit its own obstacle), so the pair is speculative and asks
# for a time of impact.
TWO_BULLETS = """
version: 1
world: {gravity: [0, 0], dt: 1/60, steps: 2}
bodies:
  - {name: wall, type: static, position: [1, 10], shape: {box: {size: [0.01, 1]}}}
  - {name: ball, position: [-2, 10], velocity: [500, 0], density: 7800,
     shape: {circle: {radius: 0.005}}}
  - {name: box, position: [-2, 14], velocity: [400, -300], density: 7800,
     shape: {box: {size: [0.02, 0.005]}}}
  - {name: floor, type: static, shape: {segment: {a: [-5, 12], b: [10, 12]}}}
"""


def test_a_fast_ball_stops_at_its_wall_whatever_another_fast_body_does() -> None:
    both = rbsim.run(TWO_BULLETS)
    alone = rbsim.run(TWO_BULLETS.replace("velocity: [400, -300]", "velocity: [0, 0]"))
    ball = both.body("ball")
    # the wall stops the ball (e = 0): it used to leave at (98, −2.2) m/s, held to the
    # box's x by a contact of the two placed where their paths pass
    assert np.array_equal(both.velocity[1:, ball], alone.velocity[1:, ball])
    assert np.array_equal(both.position[1:, ball], alone.position[1:, ball])
    assert np.abs(both.velocity[-1, ball]).max() < 1e-9  # m/s: round-off of a full stop
