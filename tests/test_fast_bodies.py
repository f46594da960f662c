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


# A 2 cm lead slug at 300 m/s tumbling at 583 rad/s, and a static wall whose near face
# is at x = 4.99 m (e = 0.2 both).
SPINNING_SLUG = """
version: 1
world: {dimension: 3, dt: 1/60, duration: 0.1, gravity: [0, 0, 0]}
bodies:
  - {name: wall, type: static, restitution: 0.2, position: [5, 1, 0],
     shape: {box: {size: [0.02, 2, 2]}}}
  - {name: slug, position: [0, 1, 0], velocity: [300, 0, 0],
     angular_velocity: [0, 500, 300], density: 11300, restitution: 0.2,
     shape: {box: {size: [0.02, 0.01, 0.01]}}}
"""


def slug_reach(overrides: tuple[str, ...] = ()) -> float:
    """The farthest x (m) any corner of the slug reaches in a frame."""
    from rbsim.scene.geometry3d import quat_matrix

    traj = rbsim.run(SPINNING_SLUG, overrides=overrides)
    slug = traj.body("slug")
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    half = signs * [0.01, 0.005, 0.005]  # m: the corners about the centre
    corners = [
        p + half @ quat_matrix(q[None])[0].T
        for p, q in zip(traj.position[:, slug], traj.orientation[:, slug], strict=True)
    ]
    return float(max(c[:, 0].max() for c in corners))


def test_a_tumbling_slug_bounces_off_its_wall_where_it_meets_it() -> None:
    # it turns 2.4 rad in each substep of 1/240 s, and engages a substep's travel (1.25
    # m) before the wall: it bounced there, its farthest corner at 3.739 m (with steps
    # of 1/600 s, 4.884 m). Now it turns back at the wall, never through it (its far
    # face is at 5.01 m); 5 mm: the push that carries it there follows its corners
    # linearly, and the turn within the last substep leaves them a few mm off
    for overrides in ((), ("world.dt=1/600",)):
        assert abs(slug_reach(overrides) - 4.99) < 5e-3
