"""Heavy bodies on light ones through whole runs, 2D and 3D: a heavy ball on a thin
plate, a box 10⁴ times heavier than the box under it, a slab dropped onto a small box
with restitution. Each failed before the shock pass took the right loads (shock.cpp:
touching contacts only hold bodies up; a load that would crush its supporter is taken out
however it approaches)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import rbsim

from .conftest import vector

PLATE_2D = """
version: 1
name: plate
world: {dt: 1/60, duration: 1}
bodies:
  - {name: ground, type: static, shape: {segment: {a: [-10, 0], b: [10, 0]}}}
  - {name: plate, position: [0, 0.005], mass: 1, shape: {box: {size: [0.2, 0.01]}}}
  - {name: ball, position: [0, 0.31], mass: 100, shape: {circle: {radius: 0.3}}}
"""

STACK_3D = """
version: 1
name: heavy_on_light
world: {dimension: 3, dt: 1/60, duration: 4}
bodies:
  - {name: ground, type: static, friction: 0.6, shape: {plane: {}}}
  - {name: light, position: [0, 0.5, 0], mass: 0.01, friction: 0.6, shape: {box: {size: [1, 1, 1]}}}
  - {name: heavy, position: [0, 1.5, 0], mass: 100, friction: 0.6, shape: {box: {size: [1, 1, 1]}}}
"""

SLAB_2D = """
version: 1
name: slab
world: {dt: 1/60, duration: 1.5}
materials:
  wood: {density: 600, friction: 0.5, restitution: 0.2}
bodies:
  - {name: ground, type: static, material: wood, shape: {segment: {a: [-20, 0], b: [20, 0]}}}
  - {name: box, position: [-2, 0.15], mass: 16, material: wood, shape: {box: {size: [0.3, 0.3]}}}
  - {name: slab, position: [0, 5], mass: 6000, material: wood, shape: {box: {size: [10, 0.1]}}}
"""

SLAB_3D = """
version: 1
name: slab
world: {dimension: 3, dt: 1/240, duration: 1.5}
materials:
  wood: {density: 600, friction: 0.5, restitution: 0.2}
bodies:
  - {name: ground, type: static, material: wood, shape: {plane: {}}}
  - {name: box, position: [-2, 0.15, 0], material: wood, shape: {box: {size: [0.3, 0.3, 0.3]}}}
  - {name: slab, position: [0, 5, 0], material: wood, shape: {box: {size: [10, 0.1, 10]}}}
"""


def test_a_heavy_ball_keeps_a_thin_plate_on_the_ground():
    """100 kg on a 1 kg, 1 cm plate on a segment: the plate stays where it lies (it went
    through the ground within 3 steps and fell away, 4.4 m down after 1 s)."""
    tr = rbsim.run(PLATE_2D)
    plate_y = tr.position[:, 1, 1]
    # m: the soft contacts' rest overlap under 100 kg is a fraction of a millimetre
    assert np.all(np.abs(plate_y - 0.005) < 0.001)
    assert np.all(np.abs(tr.position[:, 2, 1] - 0.31) < 0.002)  # m: the ball on the plate


def test_a_box_ten_thousand_times_heavier_does_not_sink_into_the_light_one():
    """3D, 100 kg on 0.01 kg: the overlap stays at round-off over 4 s (it grew at 3.6 cm/s
    without end: 13 cm at 4 s)."""
    tr = rbsim.run(STACK_3D)
    overlap = 1.0 - (tr.position[:, 2, 1] - tr.position[:, 1, 1])  # m
    assert overlap.max() < 0.001  # m: well inside the 5 mm slop
    assert tr.position[:, 1, 1].min() > 0.5 - 0.001  # m: nor the light box into the ground


@pytest.mark.parametrize("text", [SLAB_2D, SLAB_3D], ids=["2d", "3d"])
def test_a_dropped_slab_stops_on_the_box_under_it(text: str):
    """A 6 t slab falls 5 m onto a 16 kg box (restitution 0.2): it comes to rest on the box,
    tilted down to the ground (the box went through the slab and ended on top of it)."""
    tr = rbsim.run(text)
    box_y, slab_y = tr.position[:, 1, 1], tr.position[:, 2, 1]
    assert np.all(box_y < slab_y)  # the box never passes the slab's middle
    # m: the box is squeezed by at most the slop's worth, not crushed into the ground
    assert box_y.min() > 0.15 - 0.025
    # m: at the end the slab's centre is about half the box's height up (tilted on it)
    assert slab_y[-1] > 0.2


def pallet_on_ramp(degrees: float, friction: float, crate: float) -> str:
    """A crate of mass `crate` (kg, 1 m) on a 1 kg pallet (1.5 m × 10 cm) on a static ramp
    tilted by `degrees`, everything of `friction`, both bodies placed on the slope."""
    angle = math.radians(degrees)
    up = (-math.sin(angle), math.cos(angle))  # the ramp's normal
    pallet = [0.55 * up[0], 0.55 * up[1]]
    box = [1.1 * up[0], 1.1 * up[1]]
    return f"""
version: 1
name: pallet
world: {{dt: 1/60, duration: 3}}
materials:
  wood: {{density: 1, friction: {friction}, restitution: 0}}
bodies:
  - {{name: ramp, type: static, material: wood, angle: {angle},
     shape: {{box: {{size: [30, 1]}}}}}}
  - {{name: pallet, material: wood, position: {pallet}, angle: {angle}, mass: 1,
     shape: {{box: {{size: [1.5, 0.1]}}}}}}
  - {{name: crate, material: wood, position: {box}, angle: {angle}, mass: {crate},
     shape: {{box: {{size: [1, 1]}}}}}}
"""


def sliding_stack(
    dimension: int, masses: list[float], heights: list[float], speed: float, friction: float
) -> str:
    """Boxes of `masses` (kg) stacked on the ground, each `heights` (m) tall (the top one
    a cube, the others plates 1 m wide), all sliding along x at `speed` (m/s)."""
    lines, y = [], 0.0
    for k, (mass, height) in enumerate(zip(masses, heights, strict=True)):
        width = height if k == len(masses) - 1 else 1.0
        y += 0.5 * height
        pos, vel = vector(dimension, 0, y, 0), vector(dimension, speed, 0, 0)
        size = vector(dimension, width, height, width)
        lines.append(
            f"  - {{name: b{k}, material: m, position: {pos}, velocity: {vel}, mass: {mass},"
            f" shape: {{box: {{size: {size}}}}}}}"
        )
        y += 0.5 * height
    ground = "{segment: {a: [-50, 0], b: [50, 0]}}" if dimension == 2 else "{plane: {}}"
    dt = "1/60" if dimension == 2 else "1/240"
    head = f"""
version: 1
name: sliding_stack
world: {{dimension: {dimension}, dt: {dt}, duration: 2}}
materials:
  m: {{density: 1, friction: {friction}, restitution: 0}}
bodies:
  - {{name: ground, type: static, material: m, shape: {ground}}}
"""
    return head + "\n".join(lines) + "\n"


def coulomb_stop(speed: float, friction: float) -> float:
    """How far (m) a body sliding at `speed` (m/s) goes before friction stops it,
    v² / (2 μ g), under rbsim's default gravity."""
    return speed**2 / (2 * friction * 9.81)


def slid(tr) -> np.ndarray:  # noqa: ANN001 - a trajectory
    """How far (m) each dynamic body (all but the first, the ground) moved along x."""
    return tr.position[-1, 1:, 0] - tr.position[0, 1:, 0]


@pytest.mark.parametrize(
    ("degrees", "friction", "crate"),
    [(20, 0.8, 100), (40, 1.2, 100), (20, 0.8, 1000)],
    ids=["20 deg", "40 deg", "1000 kg"],
)
def test_a_heavy_crate_on_a_light_pallet_stays_on_a_ramp_friction_holds(
    degrees: float, friction: float, crate: float
):
    """100 kg (and 1000 kg) on 1 kg, friction above tan θ: nothing slides (the crate slid
    3.1 m down the pallet at 20° and tumbled off in 3 s: the shock pass carried its weight,
    and its friction was bounded by the contact's normal impulse alone, near zero; at 40°
    both slid 1.5 m in 2 s when the load's friction went to the pallet's lifted end too;
    1000 kg took the pallet 4.6 m down with it while the passes' friction was bounded and
    the shock pass had none)."""
    tr = rbsim.run(pallet_on_ramp(degrees, friction, crate))
    moved = np.linalg.norm(tr.position[-1, 1:] - tr.position[0, 1:], axis=1)
    assert moved.max() < 0.15  # m: the pair settles by a cm or two (0.7 to 1.7 measured)


# Stacks sliding on the ground that stop together where Coulomb says, v²/(2 μ g):
# masses (kg), heights (m), speed (m/s), friction, and the tolerance (m) on each body's
# distance with its reason. Before the friction loads:
# - a 1 kg plate carrying 100 kg (1.5 m/s, μ = 0.6; Coulomb 0.191 m) slid 0.55 m and its
#   load 1.26 m in 2D, 0.51 and 0.55 m in 3D: the ground's friction on the plate did not
#   see the load (the soft contacts' slip and the substeps: 0.167 - 0.189 measured);
# - 100 kg on a 2 kg plate 2 cm thick (3 m/s, μ = 0.2; 2.29 m): the cube slipped 1.3 m
#   over the plate and off it, the ground 1 cm under it, a speculative contact, counted as
#   one of its two supports, halving its friction's load (the slip while the load settles
#   on the plate: 2.04 - 2.30 measured).
SLIDING_STACKS = {
    "plate under 100 times its mass": ([1, 100], [0.1, 0.5], 1.5, 0.6, 0.04),
    "cube on a thin plate": ([2, 100], [0.02, 1.0], 3.0, 0.2, 0.3),
}


@pytest.mark.parametrize("case", SLIDING_STACKS, ids=list(SLIDING_STACKS))
@pytest.mark.parametrize("dimension", [2, 3])
def test_a_stack_sliding_under_a_heavy_load_stops_where_coulomb_says(dimension: int, case: str):
    """Each of SLIDING_STACKS stops together where Coulomb says, and is at rest at the end."""
    masses, heights, speed, friction, tolerance = SLIDING_STACKS[case]
    tr = rbsim.run(sliding_stack(dimension, masses, heights, speed, friction))
    moved = slid(tr)
    assert np.all(np.abs(moved - coulomb_stop(speed, friction)) < tolerance), moved
    assert np.abs(tr.velocity[-1, 1:]).max() < 0.01  # m/s: at rest at the end


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_heavy_box_sliding_on_light_plates_is_never_thrown(dimension: int):
    """100 kg on two stacked 1 kg plates, all sliding at 2 m/s (μ = 0.7): the kinetic
    energy of the bodies' motion only falls and the stack stops within twice Coulomb's
    0.29 m. Before, the plates tipped under the load's friction and the shock pass, holding
    each still, lifted the box at the speed of a rising edge: 1.7 times the starting
    energy in 2D (1.4 in 3D), the box thrown at 2.6 m/s, sliding 2.8 m."""
    masses = np.array([1.0, 1.0, 100.0])  # kg
    tr = rbsim.run(sliding_stack(dimension, list(masses), [0.2, 0.2, 0.8], 2.0, 0.7))
    energy = 0.5 * (masses * (tr.velocity[:, 1:] ** 2).sum(axis=2)).sum(axis=1)  # J
    assert energy.max() <= energy[0] * (1 + 1e-9)  # (rounding of the start's sum)
    moved = slid(tr)[2]  # m: the box
    assert 0.29 < moved < 2 * 0.29  # m: friction stops it, in the right distance's order


LIFT_2D = """
version: 1
name: lift
world: {dt: 1/60, duration: 3}
bodies:
  - {name: lift, type: kinematic, velocity: [0, 1], shape: {box: {size: [4, 0.2]}}}
  - {name: light, position: [0, 0.2], mass: 1, shape: {box: {size: [1, 0.2]}}}
  - {name: heavy, position: [0, 0.8], mass: 100, shape: {box: {size: [1, 1]}}}
"""


def test_a_heavy_box_on_a_light_one_rides_a_kinematic_lift():
    """A lift rising at 1 m/s carries 100 kg on 1 kg: the light box's rise is handed on to
    the heavy one (with none of a dynamic supporter's move handed on, the heavy box sank
    2 cm into the light one, and it 2 cm into the lift)."""
    tr = rbsim.run(LIFT_2D)
    y = tr.position[:, :, 1]
    lift_gap = (y[:, 1] - 0.1) - (y[:, 0] + 0.1)  # m
    box_gap = (y[:, 2] - 0.5) - (y[:, 1] + 0.1)
    # m: within the collision slop (1.3 mm measured); handing on none of the light box's
    # travel, the heavy one sank 2 cm
    assert min(lift_gap.min(), box_gap.min()) > -0.005
    assert abs(tr.velocity[-1, 2, 1] - 1.0) < 0.01  # m/s: riding with the lift


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_plate_under_a_thousand_times_its_mass_stops_with_its_load(dimension: int):
    """1 kg under 1000 kg, sliding at 1.5 m/s (μ = 0.6): the load stops where Coulomb says,
    0.191 m (1.26 m while the shock pass had no friction), never faster than it started."""
    tr = rbsim.run(sliding_stack(dimension, [1, 1000], [0.1, 0.5], 1.5, 0.6))
    coulomb, moved = coulomb_stop(1.5, 0.6), slid(tr)
    assert abs(moved[1] - coulomb) < 0.04, moved  # m: the substeps' slip (0.19 - 0.22 measured)
    # m: the plate, a thousand times lighter, stops first, by its own slip (0.14 - 0.20)
    assert abs(moved[0] - coulomb) < 0.06, moved
    speed = np.linalg.norm(tr.velocity[:, 2], axis=1)
    assert speed.max() <= 1.5 * (1 + 1e-9)  # m/s: (rounding of the start's)


def test_a_light_box_on_a_plank_under_a_heavy_load_has_its_own_friction():
    """2D: a 1 kg box and a 100 kg one on a 1 kg plank, all sliding at 3 m/s (μ = 1): the
    light box stops after about v²/(2 μ g) = 0.46 m. While a heavy body rests on a light
    one the 2D shock pass takes every approach it meets, the light box's load too, and its
    friction saw none of it: it slid 0.84 m on the plank."""
    plank = """
version: 1
name: plank
world: {dt: 1/60, duration: 3}
materials:
  m: {density: 1, friction: 1.0, restitution: 0}
bodies:
  - {name: ground, type: static, material: m, shape: {segment: {a: [-50, 0], b: [50, 0]}}}
  - {name: plank, material: m, position: [0, 0.025], velocity: [3, 0], mass: 1,
     shape: {box: {size: [4, 0.05]}}}
  - {name: light, material: m, position: [-1, 0.35], velocity: [3, 0], mass: 1,
     shape: {box: {size: [0.6, 0.6]}}}
  - {name: heavy, material: m, position: [1, 0.55], velocity: [3, 0], mass: 100,
     shape: {box: {size: [1, 1]}}}
"""
    tr = rbsim.run(plank)
    coulomb, moved = coulomb_stop(3.0, 1.0), slid(tr)
    # m: the substeps' slip, and the plank's own stop (0.48 - 0.50 measured)
    assert np.all(np.abs(moved - coulomb) < 0.08), moved


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_light_plate_between_two_heavy_boxes_passes_the_friction_on(dimension: int):
    """10 t on a 1 kg plate on 10 t, all sliding at 3 m/s (μ = 0.4): the three stop
    together after v²/(2 μ g) = 1.15 m. The ground's friction counted the upper box's whole
    load, whose friction the shock pass takes into the ground, and the lower box stopped at
    0.57 m while the upper one slid on over the plate to 1.8 m."""
    heights = [0.5, 0.05, 0.5]  # m: the boxes 1 m and 0.5 m wide, the plate 1 m
    tr = rbsim.run(sliding_stack(dimension, [10000, 1, 10000], heights, 3.0, 0.4))
    coulomb, moved = coulomb_stop(3.0, 0.4), slid(tr)
    assert np.all(np.abs(moved - coulomb) < 0.1), moved  # m: the substeps' slip (≤ 0.05)


def on_a_belt(dimension: int, box: float) -> str:
    """A `box` kg cube on a 1 kg plate on a kinematic belt at 1 m/s, μ 0.3, for 3 s."""
    v = functools.partial(vector, dimension)
    return f"""
version: 1
world: {{dimension: {dimension}, dt: 1/60, duration: 3}}
materials:
  m: {{density: 1000, friction: 0.3, restitution: 0.0}}
bodies:
  - {{name: belt, type: kinematic, material: m, position: {v(0, 0.1, 0)}, velocity: {v(1, 0, 0)},
      shape: {{box: {{size: {v(20, 0.2, 4)}}}}}}}
  - {{name: plate, material: m, position: {v(0, 0.22, 0)}, mass: 1,
      shape: {{box: {{size: {v(1, 0.04, 1)}}}}}}}
  - {{name: box, material: m, position: {v(0, 0.74, 0)}, mass: {box},
      shape: {{box: {{size: {v(1, 1, 1)}}}}}}}
"""


@pytest.mark.parametrize("box", [100, 1000, 10_000])
@pytest.mark.parametrize("dimension", [2, 3])
def test_a_heavy_box_on_a_light_plate_rides_a_belt(dimension: int, box: float):
    # friction brings the box to the belt's 1 m/s at μ g = 2.94 m/s²: 0.34 s, then it rides,
    # 2.83 m in all. Before, the passes' friction through the 1 kg plate was bounded at
    # 50 kg's and the shock pass's never sped the box up: 2.66, 0.66 and 0.07 m
    tr = rbsim.run(on_a_belt(dimension, box))
    b = tr.body("box")
    reach = 1.0 / (0.3 * 9.81)  # s: till the box rides
    expected = 3.0 - 0.5 * reach  # m
    moved = tr.position[-1, b, 0] - tr.position[0, b, 0]
    # (the plate is brought up to the belt's speed first, over a few steps: 2.807 - 2.830 m)
    assert abs(moved - expected) < 0.05
    assert abs(tr.velocity[-1, b, 0] - 1.0) < 0.01  # m/s: riding (0.998 - 1.000)


def on_three_plates(dimension: int) -> str:
    """A 10 t crate on three stacked 1 kg plates that grip one another (μ 1000, the pairs'
    least friction taken) on a belt at 1 m/s (μ 0.3), for 6 s."""
    v = functools.partial(vector, dimension)
    plates = "".join(
        f"  - {{name: p{k}, friction: 1000, mass: 1, position: {v(0, 0.025 + 0.05 * k, 0)},"
        f" shape: {{box: {{size: {v(1.0, 0.05, 1.0)}}}}}}}\n"
        for k in range(3)
    )
    return f"""
version: 1
world: {{dimension: {dimension}, dt: 1/60, duration: 6, mixing: {{friction: min}}}}
bodies:
  - {{name: belt, type: kinematic, friction: 0.3, velocity: {v(1, 0, 0)}, position: {v(0, -0.1, 0)},
      shape: {{box: {{size: {v(200, 0.2, 200)}}}}}}}
{plates}  - {{name: crate, friction: 0.3, mass: 10000, position: {v(0, 0.55, 0)},
      shape: {{box: {{size: {v(0.8, 0.8, 0.8)}}}}}}}
"""


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_heavy_crate_on_light_plates_on_a_belt_is_never_faster_than_the_belt(dimension: int):
    # the shock pass's friction brings the crate up to its carrier's speed, and no
    # further: following the top plate's speed instead, the crate on three 1 kg plates
    # sped up past the belt from 2 - 3 s on (3.1 m/s and 9 times its kinetic energy at
    # 6 s in 2D, 3.4 m/s and 12 times in 3D)
    tr = rbsim.run(on_three_plates(dimension))
    c = tr.body("crate")
    speed = np.linalg.norm(tr.velocity[:, c], axis=1)
    # m/s: the belt's 1, up to the plates' sway (1.002 measured)
    assert speed.max() < 1.01
    assert abs(speed[-1] - 1.0) < 0.01  # riding
    ride = 0.5 * 10_003 * 1.0**2  # J: the crate and plates at the belt's speed
    assert tr.observables["kinetic_energy"].max() < 1.01 * ride


# A 50 g capsule (e = 1) lying on the floor under a 16 kg slab 4 cm above it, moving down
# at 88 m/s (as a squeeze between the two leaves it): it bounces off the floor into the
# slab within the step. The shock pass took the slab's approach towards the rising capsule
# as a load on a held supporter and handed the slab the capsule's 88 m/s: 328 J became
# 25 kJ. A supporter travelling faster than an impact hands nothing on (shock.cpp).
STRUCK_FROM_BELOW = """
version: 1
name: struck_from_below
world: {dt: 1/60, steps: 30}
solver: {substeps: 1, iterations: 2}
bodies:
  - {name: floor, type: static, position: [0, -0.5], shape: {box: {size: [12, 1]}}}
  - {name: slab, position: [0, 0.5], velocity: [0, 1.5], density: 50, friction: 0.1,
     restitution: 0.3, shape: {box: {size: [0.8, 0.4]}}}
  - {name: capsule, position: [0, 0.11], velocity: [16, -88], angular_velocity: 117,
     density: 0.22, friction: 0.5, restitution: 1,
     shape: {segment: {a: [-0.43, 0], b: [0.43, 0], radius: 0.11}}}
"""


def test_a_light_body_bounced_up_into_a_heavy_one_gives_it_no_energy():
    from rbsim.engines import make_engine
    from rbsim.scene import load_scene_text

    engine = make_engine("rbsim", load_scene_text(STRUCK_FROM_BELOW))

    def energy() -> float:  # J: kinetic and potential
        o = engine.observables()
        return float(o["kinetic_energy"]) + float(o["potential_energy"])

    start, most = energy(), 0.0
    for _ in range(30):
        engine.advance(1)
        most = max(most, energy())
    # restitution is at most 1 and nothing drives the bodies: no rise beyond the
    # discrete gravity's round-off of a step (0.5% here)
    assert most < 1.005 * start
