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


# A 4 mm lead pellet at 600 m/s and a free-standing 24 kg door 5 m ahead (e = 0.2 both).
PELLET_DOOR = """
version: 1
world: {dimension: 3, dt: 1/60, steps: 1, gravity: [0, 0, 0]}
bodies:
  - {name: door, position: [5, 1, 0], density: 600, restitution: 0.2,
     shape: {box: {size: [0.02, 2, 1]}}}
  - {name: pellet, position: [0, 1, 0], velocity: [600, 0, 0], density: 11300,
     restitution: 0.2, shape: {sphere: {radius: 0.004}}}
"""


def test_a_fast_pellet_bounces_off_a_free_door_where_it_meets_it() -> None:
    free = rbsim.run(PELLET_DOOR)
    fixed = rbsim.run(PELLET_DOOR.replace("density: 600,", "type: static,"))
    pellet = free.body("pellet")
    # it meets the door's face (x = 4.99 m) at 8.3 ms and leaves at about −120 m/s: at
    # the step's end it is at 4.986 − 120 × 8.35 ms ≈ 3.986 m (it turned back at 2.5 m,
    # a substep's travel short of the door, and was at 1.0 m)
    x_free, x_fixed = free.position[-1, pellet, 0], fixed.position[-1, pellet, 0]
    # m: the door is pushed back 0.76 mm in the step; the pellet's mass is 1e-4 of its
    assert abs(x_free - x_fixed) < 2e-3
    assert abs(x_fixed - 3.986) < 1e-3  # m: the closed form to the substep's rounding
    v_free = free.velocity[-1, pellet, 0]
    # m/s: e = 0.2 of the approach relative to the door (which gains 0.09 m/s)
    assert abs(v_free + 119.9) < 0.1
