"""The continuous sweep (cpp/src/collide/continuous.cpp), end to end in 2D and 3D: a body
struck within a step far beyond its contacts' reach does not pass through a static wall;
nor one turned off its free path by a wall into a floor its free path missed, nor one
turning too fast for its manifold's points to follow; and in 2D the time of impact of a
body turning fast (collide/toi.cpp, by the bound on any point's approach: the sweep's,
and the narrowphase's past TOI_FAST_TURN) neither."""

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


# A box spun at 33 rad/s and thrown at 25 m/s meets a bat (a long capsule, 28 times its
# mass, at 27 m/s and 50 rad/s) in a closed box (2D, zero g); the bat flings it at 100 m/s
# and 96 rad/s towards a static ceiling 5 cm thick (near face y = 8.775), 1.7 m away: its
# path within the step crosses the ceiling while it turns half a turn. The sweep's time of
# impact, by each point's own approach, passed the impact and found the box 28 cm into
# the ceiling from the far side, and let it through (27 m beyond after 10 steps); by the
# bound on any point's approach it stops at the ceiling.
SPUN_BOX = """\
version: 1
world: {dt: 1/30, steps: 10, gravity: [0, 0]}
solver: {substeps: 8}
bodies:
  - {name: ceiling, type: static, position: [0, 8.8], shape: {box: {size: [10, 0.05]}}}
  - {name: bat, position: [-1.114, 6.459], angle: -1.01, velocity: [26.7, 1.0],
     angular_velocity: -49.8, density: 13.4, restitution: 0.8, friction: 0.2,
     shape: {segment: {a: [-0.84, 0], b: [0.84, 0], radius: 0.105}}}
  - {name: box, position: [-1.329, 7.075], angle: 0.984, velocity: [-24.6, 0.16],
     angular_velocity: -33.1, density: 1.2, friction: 1.2, shape: {box: {size: [0.68, 0.225]}}}
"""

# A capsule 15 cm long at 51 m/s, turning at 106 rad/s (1.8 rad a step at dt 1/60), 76 cm
# from a static wall 5 cm thick (near face x = 3.716): its speculative contact's time of
# impact, by the nearest point's own approach, passed the impact and found the capsule on
# the far side of the wall, which then pushed it out there (20 m beyond after 20 steps).
FAST_CAPSULE = """\
version: 1
world: {dt: 1/60, steps: 20, gravity: [0, 0]}
solver: {substeps: 8, iterations: 2}
bodies:
  - {name: wall, type: static, position: [3.741, 3.7], shape: {box: {size: [0.05, 7.5]}}}
  - {name: capsule, position: [2.954, 2.532], angle: 2.0, velocity: [50.6, -4.1],
     angular_velocity: -105.8, density: 1.9, restitution: 0.8, friction: 0.1,
     shape: {segment: {a: [-0.076, 0], b: [0.076, 0], radius: 0.03}}}
"""


# A quadrilateral 17 cm across at 25 m/s towards a static wall 5 cm thick (near face
# x = 4.469), spinning at 277 rad/s (0.58 rad a substep): its manifold's two points turn
# away from the wall as its other corners come round into it, and nothing stopped it
# (4 m beyond after 20 steps). Swept for its turn (continuous.cpp), it stays in front of the wall.
SPINNER = """\
version: 1
world: {dt: 1/120, steps: 20, gravity: [0, 0]}
solver: {substeps: 4, iterations: 2}
bodies:
  - {name: wall, type: static, position: [4.494, 4.8], shape: {box: {size: [0.05, 9.6]}}}
  - {name: spinner, position: [4.2942, 4.6019], angle: -14.6348, velocity: [25.44, 0],
     angular_velocity: -277.1, density: 18.72,
     shape: {polygon: {vertices: [[0.01552, 0.1746], [-0.0481, 0.1685], [-0.168, -0.04978],
                                  [-0.1373, -0.1089]]}}}
"""


@pytest.mark.parametrize(
    ("text", "body", "axis", "face"),
    [(SPUN_BOX, 2, 1, 8.775), (FAST_CAPSULE, 1, 0, 3.716), (SPINNER, 1, 0, 4.469)],
    ids=["struck_box_to_ceiling", "turning_capsule_to_wall", "spinner_past_its_points"],
)
def test_a_body_turning_fast_stops_at_a_thin_wall(text: str, body: int, axis: int, face: float):
    world = CoreWorld.from_scene(scene_from(text))
    along = []
    for _ in range(world.scene.world.steps):
        world.advance(1)
        along.append(world.state.body_x[body, axis])
    # its centre of mass never reaches the wall's near face (its half width is 11 cm for
    # the box, 3 cm for the capsule's radius; 2 cm through would put it over the face)
    assert max(along) < face
    assert along[-1] < along[int(np.argmax(along))]  # and it comes back off it


# A chip 5 cm across thrown at 490 m/s down into the corner of a floor and a wall, each
# 5 cm thick: its free path meets the wall 15 cm above the floor and then passes beyond
# the floor's end, so the floor's speculative contact found none; stopped at the wall, it
# went on down through the floor within the step (its motion was what its velocity at the
# step's start had it do, and it was not swept). Swept once its path left its free path,
# it stops on the floor, spinning (1840 rad/s) or not.
CORNER = """\
version: 1
world: {{dt: 1/60, steps: 20}}
solver: {{substeps: 1, iterations: 2}}
bodies:
  - {{name: floor, type: static, position: [0, -0.025], shape: {{box: {{size: [9.6, 0.05]}}}}}}
  - {{name: wall, type: static, position: [4.77, 4.3], shape: {{box: {{size: [0.05, 8.6]}}}}}}
  - {{name: chip, position: [-2.2, 3.18], velocity: [448, -195], angular_velocity: {spin},
     density: 27, shape: {{box: {{size: [0.05, 0.05]}}}}}}
"""


@pytest.mark.parametrize("spin", [0.0, -1840.0])
def test_a_body_turned_off_its_path_by_a_wall_stops_on_the_floor(spin: float) -> None:
    world = CoreWorld.from_scene(scene_from(CORNER.format(spin=spin)))
    xs = []
    for _ in range(world.scene.world.steps):
        world.advance(1)
        xs.append(world.state.body_x[2].copy())
    xs = np.array(xs)
    # its centre never below the floor's top (y = 0) nor past the wall's face (x = 4.745):
    # half its width (2.5 cm) on the wrong side is most of the way in
    assert xs[:, 1].min() > 0.0
    assert xs[:, 0].max() < 4.745
