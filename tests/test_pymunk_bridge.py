"""pymunk bridge: the scene as a pymunk Space, and readback in rbsim's layout.

Scenes are built from the resolved dataclasses directly (no YAML). Reference values come
from pymunk's own area_for_* / moment_for_* functions and from the analytic solutions
of the integrator pymunk uses (Chipmunk moves positions with the previous step's
velocity, then updates velocities).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pymunk
import pytest

from rbsim.engines.pymunk import PymunkSettings, PymunkWorld, UnsupportedScene, run_pymunk
from rbsim.scene import Body, Material, Output, Scene, Shape, Solver, World

WOOD = Material(density=2.0, friction=0.6, restitution=0.0)
SLOPE = math.radians(30)  # rad


def circle(r: float, centre=(0.0, 0.0), material: Material = WOOD) -> Shape:
    return Shape("circle", (tuple(centre),), r, material)


def box(w: float, h: float, offset=(0.0, 0.0), angle: float = 0.0, material=WOOD) -> Shape:
    c, s = math.cos(angle), math.sin(angle)
    corners = [(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)]
    verts = tuple((offset[0] + c * x - s * y, offset[1] + s * x + c * y) for x, y in corners)
    return Shape("box", verts, 0.0, material, size=(w, h), offset=tuple(offset), angle=angle)


def polygon(verts, material: Material = WOOD) -> Shape:
    return Shape("polygon", tuple(tuple(v) for v in verts), 0.0, material)


def segment(a, b, r: float = 0.0, material: Material = WOOD) -> Shape:
    return Shape("segment", (tuple(a), tuple(b)), r, material)


def body(name: str, shapes, type: str = "dynamic", position=(0.0, 0.0), angle=0.0, **kw) -> Body:
    kw.setdefault("velocity", (0.0, 0.0))
    kw.setdefault("angular_velocity", 0.0)
    return Body(name, type, tuple(position), angle, shapes=tuple(shapes), **kw)


def scene(*bodies: Body, **world) -> Scene:
    return Scene("test", World(**world), Solver(), Output(), tuple(bodies))


def table_of(*shapes: Shape, mass=None) -> dict:
    return PymunkWorld(scene(body("b", shapes, mass=mass))).body_table_arrays()


def first_bounce_ratio(world: PymunkWorld, i: int, steps: int = 2000) -> float:
    """-v_after / v_before of body i's vertical velocity at its first bounce."""
    for _ in range(steps):
        v0 = world.bodies[i].velocity.y
        world.step()
        v1 = world.bodies[i].velocity.y
        if v0 < -0.5 and v1 > -0.1 * abs(v0):
            return -v1 / v0
    raise AssertionError("no bounce")


# -- mass properties -------------------------------------------------------------------


def test_circle_mass_moment_centre_match_pymunk():
    t = table_of(circle(0.5, (0.3, -0.2)))
    m = 2.0 * pymunk.area_for_circle(0, 0.5)
    assert t["mass"][0] == pytest.approx(m, rel=1e-12)
    assert t["moment_of_inertia"][0] == pytest.approx(
        pymunk.moment_for_circle(m, 0, 0.5), rel=1e-12
    )
    np.testing.assert_allclose(t["center_of_mass"][0], (0.3, -0.2), atol=1e-15)


def test_offset_rotated_box_mass_moment_centre_match_pymunk():
    s = box(1.0, 0.4, offset=(2.0, 1.0), angle=0.3)
    t = table_of(s)
    m = 2.0 * pymunk.area_for_poly(s.vertices)
    # moment_for_poly is about the body origin; about the centre it loses m |c|²
    about_origin = pymunk.moment_for_poly(m, s.vertices)
    assert t["mass"][0] == pytest.approx(m, rel=1e-12)
    assert m == pytest.approx(2.0 * 0.4, rel=1e-12)
    assert t["moment_of_inertia"][0] == pytest.approx(about_origin - m * 5.0, rel=1e-9)
    assert t["moment_of_inertia"][0] == pytest.approx(
        pymunk.moment_for_box(m, (1.0, 0.4)), rel=1e-9
    )
    np.testing.assert_allclose(t["center_of_mass"][0], (2.0, 1.0), atol=1e-12)


def test_triangle_mass_moment_centre_match_pymunk():
    verts = [(0.5, -0.5), (1.5, -0.5), (0.5, 0.5)]
    t = table_of(polygon(verts))
    m = 2.0 * pymunk.area_for_poly(verts)
    c = np.mean(verts, axis=0)
    about_centre = pymunk.moment_for_poly(m, verts, offset=tuple(-c))
    assert t["mass"][0] == pytest.approx(m, rel=1e-12)
    assert t["moment_of_inertia"][0] == pytest.approx(about_centre, rel=1e-12)
    np.testing.assert_allclose(t["center_of_mass"][0], c, atol=1e-12)


def test_capsule_segment_mass_moment_centre_match_pymunk():
    a, b, r = (-1.0, 0.5), (2.0, 0.5), 0.25
    t = table_of(segment(a, b, r))
    m = 2.0 * pymunk.area_for_segment(a, b, r)
    mid = (0.5, 0.5)
    about_origin = pymunk.moment_for_segment(m, a, b, r)
    assert t["mass"][0] == pytest.approx(m, rel=1e-12)
    assert t["moment_of_inertia"][0] == pytest.approx(about_origin - m * 0.5, rel=1e-12)
    np.testing.assert_allclose(t["center_of_mass"][0], mid, atol=1e-12)


def test_compound_body_sums_with_parallel_axis_terms_and_matches_pymunk_accumulation():
    light = Material(density=0.5)
    shapes = [circle(0.5, (1.0, 0.0)), box(1.0, 2.0, (-1.0, 0.5), 0.4, light)]
    t = table_of(*shapes)
    m1 = 2.0 * pymunk.area_for_circle(0, 0.5)
    m2 = 0.5 * pymunk.area_for_poly(shapes[1].vertices)
    com = (m1 * np.array([1.0, 0.0]) + m2 * np.array([-1.0, 0.5])) / (m1 + m2)
    about_origin = pymunk.moment_for_circle(m1, 0, 0.5, (1.0, 0.0)) + pymunk.moment_for_poly(
        m2, shapes[1].vertices
    )
    moment = about_origin - (m1 + m2) * float(com @ com)
    assert t["mass"][0] == pytest.approx(m1 + m2, rel=1e-12)
    assert t["moment_of_inertia"][0] == pytest.approx(moment, rel=1e-12)
    np.testing.assert_allclose(t["center_of_mass"][0], com, atol=1e-12)
    # pymunk's own accumulation from shape densities gives the same body
    ref = pymunk.Body()
    c = pymunk.Circle(ref, 0.5, (1.0, 0.0))
    p = pymunk.Poly(ref, shapes[1].vertices)
    c.density, p.density = 2.0, 0.5
    space = pymunk.Space()
    space.add(ref, c, p)
    assert ref.mass == pytest.approx(m1 + m2, rel=1e-12)
    assert ref.moment == pytest.approx(moment, rel=1e-9)
    np.testing.assert_allclose(tuple(ref.center_of_gravity), com, atol=1e-12)


def test_mass_override_scales_mass_and_inertia_together_and_is_set_on_the_pymunk_body():
    shapes = [circle(0.5, (1.0, 0.0)), box(1.0, 2.0, (-1.0, 0.5))]
    free = table_of(*shapes)
    fixed = table_of(*shapes, mass=3.0)
    assert fixed["mass"][0] == 3.0
    assert fixed["moment_of_inertia"][0] == pytest.approx(
        free["moment_of_inertia"][0] * 3.0 / free["mass"][0], rel=1e-12
    )
    np.testing.assert_allclose(fixed["center_of_mass"], free["center_of_mass"])
    w = PymunkWorld(scene(body("b", shapes, mass=3.0)))
    assert w.bodies[0].mass == 3.0
    assert w.bodies[0].moment == pytest.approx(fixed["moment_of_inertia"][0], rel=1e-12)
    np.testing.assert_allclose(tuple(w.bodies[0].center_of_gravity), fixed["center_of_mass"][0])


def test_static_and_kinematic_bodies_have_infinite_mass_in_the_table():
    w = PymunkWorld(
        scene(
            body("ground", [segment((-5, 0), (5, 0))], type="static"),
            body("belt", [box(1, 1)], type="kinematic", velocity=(1.0, 0.0)),
        )
    )
    t = w.body_table_arrays()
    assert np.all(np.isinf(t["mass"])) and np.all(np.isinf(t["moment_of_inertia"]))
    assert w.bodies[0].body_type == pymunk.Body.STATIC
    assert w.bodies[1].body_type == pymunk.Body.KINEMATIC


def test_dynamic_body_without_mass_is_unsupported():
    with pytest.raises(UnsupportedScene, match="'stick'"):
        PymunkWorld(scene(body("stick", [segment((0, 0), (1, 0), 0.0)])))


# -- integration and readback ----------------------------------------------------------


def test_projectile_follows_parabola_up_to_pymunk_euler_error():
    g, dt, substeps = (0.0, -9.81), 1.0 / 60.0, 2
    x0, v0 = np.array([1.0, 2.0]), np.array([3.0, 4.0])
    sc = scene(body("ball", [circle(0.1)], position=x0, velocity=v0), gravity=g, dt=dt)
    w = PymunkWorld(sc, PymunkSettings(substeps=substeps))
    h = dt / substeps
    for n in range(1, 121):
        w.step()
        t = n * dt
        st = w.read_state()
        parabola = x0 + v0 * t + 0.5 * np.array(g) * t * t
        # Chipmunk: x += h v, then v += h g, so x_n = exact - g h t / 2 after n steps
        np.testing.assert_allclose(
            st["position"][0], parabola - 0.5 * np.array(g) * h * t, atol=1e-9
        )
        np.testing.assert_allclose(st["velocity"][0], v0 + np.array(g) * t, atol=1e-9)
    assert abs(st["position"][0][1] - parabola[1]) <= 0.5 * 9.81 * h * t + 1e-9
    assert abs(st["position"][0][1] - parabola[1]) > 1e-3  # the integrator error is visible


def test_offcentre_body_reads_back_origin_as_placed_and_velocity_of_centre_of_mass():
    shapes = [circle(0.5, (1.5, 0.0)), box(1.0, 1.0, (0.5, 0.5))]
    x0, a0, v0, w0 = (2.0, 3.0), 0.7, (1.0, -2.0), 12.0
    sc = scene(
        body("crank", shapes, position=x0, angle=a0, velocity=v0, angular_velocity=w0),
        gravity=(0.0, 0.0),
    )
    w = PymunkWorld(sc)
    com = w.body_table_arrays()["center_of_mass"][0]
    assert np.hypot(*com) > 0.5
    st = w.read_state()
    np.testing.assert_allclose(st["position"][0], x0, atol=1e-12)
    np.testing.assert_allclose(st["angle"][0], a0, atol=1e-15)
    np.testing.assert_allclose(st["orientation"][0], (math.cos(a0), math.sin(a0)), atol=1e-15)
    np.testing.assert_allclose(st["velocity"][0], v0, atol=1e-12)
    # pymunk's body.velocity is the centre of gravity's: the origin moves differently
    origin_velocity = np.array(tuple(w.bodies[0].velocity_at_local_point((0.0, 0.0))))
    assert np.linalg.norm(origin_velocity - np.array(v0)) > 1.0

    def com_world(s):
        c, sn = s["orientation"][0]
        return s["position"][0] + np.array([c * com[0] - sn * com[1], sn * com[0] + c * com[1]])

    start = com_world(st)
    for _ in range(30):
        w.step()
    st = w.read_state()
    t = 30 * sc.world.dt
    np.testing.assert_allclose(com_world(st), start + np.array(v0) * t, atol=1e-9)
    np.testing.assert_allclose(st["velocity"][0], v0, atol=1e-12)
    assert st["angle"][0] == pytest.approx(a0 + w0 * t, abs=1e-9)  # unwrapped (> 2π)
    assert st["angle"][0] > 2 * math.pi


def test_batch_readback_equals_per_body_properties():
    bodies = [body("ground", [segment((-10, 0), (10, 0), 0.1)], type="static")]
    bodies += [
        body(
            f"b{i}", [box(0.5, 0.5, (0.2, 0.1))], position=(i * 0.6 - 3, 1 + 0.3 * i), angle=0.1 * i
        )
        for i in range(10)
    ]
    w = PymunkWorld(scene(*bodies))
    for _ in range(40):
        w.step()
    st = w.read_state()
    for i, b in enumerate(w.bodies):
        np.testing.assert_array_equal(st["position"][i], tuple(b.position))
        np.testing.assert_array_equal(st["velocity"][i], tuple(b.velocity))
        assert st["angle"][i] == b.angle and st["angular_velocity"][i] == b.angular_velocity


def test_kinematic_body_moves_with_its_velocity_about_its_centre_of_mass():
    sc = scene(
        body(
            "paddle",
            [box(1.0, 0.2, (1.0, 0.0))],
            type="kinematic",
            velocity=(2.0, 0.0),
            angular_velocity=1.0,
        ),
    )
    w = PymunkWorld(sc)
    for _ in range(60):
        w.step()
    st = w.read_state()
    c, s = st["orientation"][0]
    com_world = st["position"][0] + np.array([c * 1.0, s * 1.0])
    np.testing.assert_allclose(com_world, (1.0 + 2.0 * 60 * sc.world.dt, 0.0), atol=1e-9)
    np.testing.assert_allclose(st["velocity"][0], (2.0, 0.0))


def test_damping_mapping_reproduces_box2d_factor_per_step_for_linear_and_angular():
    c, dt, substeps, n = 0.8, 1.0 / 60.0, 3, 50
    sc = scene(
        body("puck", [circle(0.5)], velocity=(2.0, -1.0), angular_velocity=4.0),
        gravity=(0.0, 0.0),
        dt=dt,
        linear_damping=c,
        angular_damping=c,
    )
    w = PymunkWorld(sc, PymunkSettings(substeps=substeps))
    h = dt / substeps
    for _ in range(n):
        w.step()
    factor = (1.0 / (1.0 + h * c)) ** (n * substeps)
    st = w.read_state()
    np.testing.assert_allclose(st["velocity"][0], np.array([2.0, -1.0]) * factor, rtol=1e-12)
    assert st["angular_velocity"][0] == pytest.approx(4.0 * factor, rel=1e-12)


def test_different_linear_and_angular_damping_is_unsupported():
    sc = scene(body("puck", [circle(0.5)]), linear_damping=0.1, angular_damping=0.2)
    with pytest.raises(UnsupportedScene, match="damping"):
        PymunkWorld(sc)


def test_constant_force_and_torque_are_applied_once_per_pymunk_step():
    f, tau, dt, substeps, n = (3.0, -1.0), 0.5, 0.01, 2, 40
    sc = scene(body("b", [circle(0.5)], force=f, torque=tau), gravity=(0.0, 0.0), dt=dt)
    w = PymunkWorld(sc, PymunkSettings(substeps=substeps))
    m, inertia = w.body_table_arrays()["mass"][0], w.body_table_arrays()["moment_of_inertia"][0]
    for _ in range(n):
        w.step()
    st = w.read_state()
    np.testing.assert_allclose(st["velocity"][0], np.array(f) / m * n * dt, rtol=1e-12)
    assert st["angular_velocity"][0] == pytest.approx(tau / inertia * n * dt, rel=1e-12)


def test_force_at_a_point_adds_the_moment_about_the_centre_of_mass():
    dt = 0.01
    sc = scene(
        body("b", [box(2.0, 1.0, (1.0, 0.0))], angle=0.5, force=(0.0, 2.0), force_point=(2.0, 0.0)),
        gravity=(0.0, 0.0),
        dt=dt,
    )
    w = PymunkWorld(sc)
    inertia = w.body_table_arrays()["moment_of_inertia"][0]
    w.step()
    r = 1.0 * np.array([math.cos(0.5), math.sin(0.5)])  # force point - centre, world frame
    assert w.read_state()["angular_velocity"][0] == pytest.approx(
        (r[0] * 2.0 - r[1] * 0.0) / inertia * dt, rel=1e-12
    )


# -- materials and mixing --------------------------------------------------------------


def ball_on_ground(e_ground, e_balls, rule="max", settings=None, **world) -> PymunkWorld:
    ground = body(
        "ground", [segment((-50, 0), (50, 0), 0.0, Material(restitution=e_ground))], type="static"
    )
    balls = [
        body(f"ball{i}", [circle(0.25, material=Material(restitution=e))], position=(4.0 * i, 1.0))
        for i, e in enumerate(e_balls)
    ]
    sc = scene(ground, *balls, restitution_mixing=rule, dt=1.0 / 240.0, **world)
    return PymunkWorld(sc, settings)


def test_sqrt_elasticity_on_each_shape_gives_the_scene_bounce():
    w = ball_on_ground(0.5, [0.5])
    assert not w.mixing_handler_installed
    assert list(w.bodies[1].shapes)[0].elasticity == pytest.approx(math.sqrt(0.5))
    assert first_bounce_ratio(w, 1) == pytest.approx(0.5, abs=0.05)


def test_max_mixing_of_zero_ground_and_elastic_ball_is_solved_with_shape_values():
    w = ball_on_ground(0.0, [1.0])
    assert not w.mixing_handler_installed
    assert first_bounce_ratio(w, 1) == pytest.approx(1.0, abs=0.05)


def test_unreproducible_mixing_raises_naming_both_bodies_when_the_handler_is_not_allowed():
    with pytest.raises(UnsupportedScene) as err:
        ball_on_ground(0.0, [1.0, 1.0, 0.0, 0.0], settings=PymunkSettings(mixing_handler="never"))
    message = str(err.value)
    assert "max" in message and "restitution" in message
    assert "'ball0'" in message or "'ball1'" in message or "'ground'" in message
    assert "'ball2'" in message or "'ball3'" in message


def test_unreproducible_mixing_within_a_compound_body_names_the_other_body():
    # shapes of one body never collide with each other; only the pair with 'b' counts
    a = body(
        "a",
        [
            circle(0.2, material=Material(restitution=0.0)),
            circle(0.2, (1.0, 0.0), material=Material(restitution=1.0)),
        ],
    )
    b = body("b", [circle(0.2, material=Material(restitution=0.0))], position=(5.0, 0.0))
    with pytest.raises(UnsupportedScene, match="'a' and 'b'|'b' and 'a'"):
        PymunkWorld(scene(a, b), PymunkSettings(mixing_handler="never"))
    # alone, the compound body has no pair to reproduce (and with no threshold to apply,
    # no handler is needed at all)
    alone = dataclasses.replace(scene(a), solver=Solver(restitution_threshold=0.0))
    assert not PymunkWorld(alone, PymunkSettings(mixing_handler="never")).pre_solve_installed


def test_unreproducible_mixing_falls_back_to_the_pre_solve_handler_by_default():
    # ball0 (e=1) and ball1 (e=0) on ground e=0 under max: no per-shape products work
    w = ball_on_ground(0.0, [1.0, 0.0])
    assert w.mixing_handler_installed
    ratios = []
    for i in (1, 2):
        w2 = ball_on_ground(0.0, [1.0, 0.0])
        ratios.append(first_bounce_ratio(w2, i))
    assert ratios[0] == pytest.approx(1.0, abs=0.05)
    assert ratios[1] == pytest.approx(0.0, abs=0.05)


def slope_acceleration(mu_slope, mu_block, rule, settings=None, theta=SLOPE) -> float:
    """Measured acceleration along a slope of a block released on it, m/s²."""
    c, s = math.cos(theta), math.sin(theta)
    slope = body(
        "slope",
        [box(40.0, 1.0, material=Material(friction=mu_slope))],
        type="static",
        angle=theta,
        position=(0.0, 0.0),
    )
    # block resting on the top face, 0.5 + 0.25 above the slope's centre line
    normal = np.array([-s, c])
    block = body(
        "block",
        [box(0.5, 0.5, material=Material(friction=mu_block))],
        angle=theta,
        position=tuple(normal * 0.75),
    )
    w = PymunkWorld(scene(slope, block, friction_mixing=rule, dt=1.0 / 120.0), settings)
    down = -np.array([c, s])
    speeds = []
    for n in range(1, 181):
        w.step()
        if n in (60, 180):
            speeds.append(float(w.read_state()["velocity"][1] @ down))
    return (speeds[1] - speeds[0]) / (120 * w.dt)


@pytest.mark.parametrize(
    ("rule", "handler", "mu"),
    [
        ("sqrt", "auto", math.sqrt(0.4 * 0.1)),
        ("sqrt", "always", math.sqrt(0.4 * 0.1)),
        ("min", "always", 0.1),
        ("max", "auto", 0.4),
    ],
)
def test_block_on_slope_slides_with_the_mixed_friction(rule, handler, mu):
    theta, g = SLOPE, 9.81
    expected = g * (math.sin(theta) - mu * math.cos(theta))
    measured = slope_acceleration(0.4, 0.1, rule, PymunkSettings(mixing_handler=handler))
    assert measured == pytest.approx(expected, rel=0.05)
    # pymunk's own product (0.04) would be clearly different
    assert abs(measured - g * (math.sin(theta) - 0.04 * math.cos(theta))) > 0.2


def test_friction_handler_is_installed_only_when_needed():
    def world(rule, n_blocks=1, handler="auto"):
        bodies = [body("floor", [box(10, 1, material=Material(friction=0.9))], type="static")]
        bodies += [
            body(
                f"b{i}",
                [box(0.5, 0.5, material=Material(friction=0.1 * (1 + i % 2)))],
                position=(i, 1.0),
            )
            for i in range(n_blocks)
        ]
        return PymunkWorld(
            scene(*bodies, friction_mixing=rule), PymunkSettings(mixing_handler=handler)
        )

    assert not world("sqrt", 4).mixing_handler_installed
    assert not world("multiply", 4).mixing_handler_installed
    assert not world("min", 1).mixing_handler_installed  # one pair: solvable
    assert world("min", 4).mixing_handler_installed  # 0.1 vs 0.2 blocks and the floor
    assert world("sqrt", 1, "always").mixing_handler_installed


# -- observables and the run loop ------------------------------------------------------


def test_observables_of_a_free_body_match_their_definitions():
    shapes = [circle(0.5, (1.0, 0.0))]
    sc = scene(body("b", shapes, position=(1.0, 2.0), velocity=(3.0, -1.0), angular_velocity=2.0))
    w = PymunkWorld(sc)
    t = w.body_table_arrays()
    m, inertia = t["mass"][0], t["moment_of_inertia"][0]
    x = np.array([2.0, 2.0])  # centre of mass in the world
    v = np.array([3.0, -1.0])
    obs = w.observables()
    assert obs["kinetic_energy"] == pytest.approx(0.5 * m * (v @ v) + 0.5 * inertia * 4.0)
    assert obs["potential_energy"] == pytest.approx(m * 9.81 * 2.0)
    np.testing.assert_allclose(obs["linear_momentum"], m * v)
    assert obs["angular_momentum"] == pytest.approx(m * (x[0] * v[1] - x[1] * v[0]) + inertia * 2.0)
    assert obs["contact_count"] == 0


def test_contact_count_counts_points_of_a_resting_stack():
    bodies = [body("ground", [segment((-10, 0), (10, 0))], type="static")]
    bodies += [body(f"box{i}", [box(1.0, 1.0)], position=(0.0, 0.5 + i)) for i in range(3)]
    w = PymunkWorld(scene(*bodies))
    for _ in range(60):
        w.step()
    assert w.observables()["contact_count"] == 6  # two points per face contact
    assert w._contact_count_bodies() == 6  # the public-API path agrees
    # lift the top box away: its two points go at once, though Chipmunk keeps the
    # separated arbiter cached for a few steps
    w.bodies[3].position = (5.0, 5.0)
    w.step()
    assert w.observables()["contact_count"] == 4
    assert w._contact_count_bodies() == 4


def test_run_pymunk_calls_on_frame_at_start_every_kth_and_last_step():
    sc = scene(body("ball", [circle(0.1)]), steps=10)
    frames = []

    def on_frame(step, t, state, obs):
        frames.append((step, t))
        assert state["position"].shape == (1, 2) and "kinetic_energy" in obs

    wall = run_pymunk(sc, PymunkSettings(), on_frame, every=4)
    assert [s for s, _ in frames] == [0, 4, 8, 10]
    assert frames[-1][1] == pytest.approx(10 * sc.world.dt)
    assert wall > 0.0


# -- restitution: the bounce pymunk gives is the one the scene means --------------------

MIX = {"max": max, "min": min, "multiply": lambda a, b: a * b}


@pytest.mark.parametrize("rule", sorted(MIX))
@pytest.mark.parametrize("handler", ["auto", "always"])
def test_first_bounce_ratio_is_the_mixed_restitution_for_every_rule(rule, handler):
    """Chipmunk bounces to v⁺ = −e v⁻ with v⁻ the velocity before the step (gravity of
    the step is absorbed by the contact), so the measured ratio is e to round-off, by
    per-shape values (auto) and by arbiter.restitution set in pre_solve (always)."""
    for e_ground, e_ball in [(0.3, 0.8), (0.8, 0.3), (0.0, 0.6)]:
        w = ball_on_ground(e_ground, [e_ball], rule, PymunkSettings(mixing_handler=handler))
        assert w.mixing_handler_installed is (handler == "always")
        # 1e-12: the ratio of two velocities of a few m/s, exact up to round-off
        assert first_bounce_ratio(w, 1) == pytest.approx(MIX[rule](e_ground, e_ball), abs=1e-12)


@pytest.mark.parametrize("rule", sorted(MIX))
def test_mixing_no_product_can_reproduce_still_gives_each_pair_its_bounce(rule):
    # three balls of different e on a ground of e = 0.5, every pair of bodies can meet:
    # under max no set of per-shape products fits every pair and the handler mixes;
    # min and multiply have products that fit (found by the bridge)
    e_balls = [1.0, 0.4, 0.0]
    for i, e in enumerate(e_balls, start=1):
        w = ball_on_ground(0.5, e_balls, rule)
        assert w.mixing_handler_installed is (rule == "max")
        # 1e-12: as above, round-off only
        assert first_bounce_ratio(w, i) == pytest.approx(MIX[rule](0.5, e), abs=1e-12)


def test_restitution_threshold_is_applied_in_pymunk_too():
    """rbsim does not bounce approaches slower than solver.restitution_threshold;
    pymunk has no threshold, so the handler drops the restitution of such contacts."""

    def ratio(threshold: float, drop: float) -> float:
        # a ball dropped from `drop` m above the ground hits at sqrt(2 g drop)
        ground = body(
            "ground", [segment((-5, 0), (5, 0), 0.0, Material(restitution=1.0))], "static"
        )
        ball = body(
            "ball", [circle(0.25, material=Material(restitution=1.0))], position=(0, 0.25 + drop)
        )
        sc = dataclasses.replace(
            scene(ground, ball, dt=1.0 / 240.0), solver=Solver(restitution_threshold=threshold)
        )
        w = PymunkWorld(sc)
        assert w.pre_solve_installed is (threshold > 0)
        return first_bounce_ratio(w, 1)

    slow = 0.03  # m: hits at 0.77 m/s
    assert ratio(0.0, slow) == pytest.approx(1.0, abs=1e-12)  # 1e-12: round-off
    assert ratio(1.0, slow) == pytest.approx(0.0, abs=1e-12)  # below the threshold
    assert ratio(1.0, 0.2) == pytest.approx(1.0, abs=1e-12)  # 1.98 m/s: above it


def test_restitution_threshold_without_a_handler_is_unsupported():
    ground = body("ground", [segment((-5, 0), (5, 0), 0.0, Material(restitution=0.5))], "static")
    with pytest.raises(UnsupportedScene, match="restitution_threshold"):
        PymunkWorld(
            scene(ground, body("ball", [circle(0.25)])), PymunkSettings(mixing_handler="never")
        )
