"""3D mass properties (rbsim.scene.mass3d) against closed forms: volume, centre of mass
and the full inertia tensor of each shape kind, compounds by the parallel-axis theorem,
`mass:` scaling, principal axes, and the compiled arrays (L = R I Rᵀ ω, x = origin + R c).
"""

from __future__ import annotations

import math
from math import factorial

import numpy as np
import pytest

from rbsim.scene import load_scene_text
from rbsim.scene.compile import body_origin, build
from rbsim.scene.geometry3d import IDENTITY, axis_angle, convex_hull, quat_matrix
from rbsim.scene.mass3d import (
    body_mass_properties_3d,
    box_volume_inertia,
    capsule_volume_inertia,
    convex_volume_inertia,
    principal_axes,
    sphere_volume_inertia,
)

# every closed form below is a few dozen products and sums of O(1) numbers, so the two
# sides agree to a few units of round-off (2.2e-16 each); 1e-12 leaves room for that
RTOL = 1e-12


def body(text: str):
    """The one body of a 3D scene whose `bodies:` entry is ``text``."""
    scene = load_scene_text(f"version: 1\nworld: {{dimension: 3}}\nbodies:\n  - {text}\n")
    return scene.bodies[0]


def props_of(text: str):
    return body_mass_properties_3d(body(text))


def rotation_z(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_box_inertia_is_m_over_12_times_the_sums_of_squared_sides():
    p = props_of("{density: 2.0, shape: {box: {size: [0.3, 0.2, 0.1]}}}")
    m = 2.0 * 0.3 * 0.2 * 0.1
    assert p.mass == pytest.approx(m, rel=RTOL)
    expected = m / 12 * np.diag([0.2**2 + 0.1**2, 0.3**2 + 0.1**2, 0.3**2 + 0.2**2])
    np.testing.assert_allclose(p.inertia, expected, rtol=RTOL, atol=0)
    assert p.center == (0.0, 0.0, 0.0)


def test_sphere_inertia_is_two_fifths_m_r_squared():
    p = props_of("{density: 3.0, shape: {sphere: {radius: 0.7, offset: [1, 2, 3]}}}")
    m = 3.0 * 4 / 3 * math.pi * 0.7**3
    assert p.mass == pytest.approx(m, rel=RTOL)
    assert p.center == (1.0, 2.0, 3.0)
    np.testing.assert_allclose(p.inertia, 0.4 * m * 0.49 * np.eye(3), rtol=RTOL, atol=0)


def test_capsule_inertia_matches_the_cylinder_and_hemispheres_closed_form():
    # the textbook form: cylinder of height H, two hemispheres of mass m_h each;
    # I_axis = m_c r²/2 + 2 m_h (2 r²/5), I_perp = m_c (H²/12 + r²/4)
    # + 2 m_h (2 r²/5 + H²/4 + 3 H r/8)
    r, h, rho = 0.2, 0.9, 5.0
    p = props_of(
        f"{{density: {rho}, shape: {{capsule: {{a: [0, 0, 0], b: [0, 0, {h}], radius: {r}}}}}}}"
    )
    m_c = rho * math.pi * r * r * h
    m_h = rho * 2 / 3 * math.pi * r**3
    axis = m_c * r * r / 2 + 2 * m_h * 2 * r * r / 5
    perp = m_c * (h * h / 12 + r * r / 4) + 2 * m_h * (2 * r * r / 5 + h * h / 4 + 3 * h * r / 8)
    assert p.mass == pytest.approx(m_c + 2 * m_h, rel=RTOL)
    np.testing.assert_allclose(p.center, (0, 0, h / 2), rtol=RTOL, atol=1e-15)
    np.testing.assert_allclose(p.inertia, np.diag([perp, perp, axis]), rtol=RTOL, atol=1e-15)


def test_capsule_inertia_agrees_with_monte_carlo_sampling():
    # an independent check of the caps' offset centroids (3r/8): 2e6 uniform samples in
    # the capsule's bounding box; the standard error of each moment is about 0.1%, so
    # 1% is five standard errors and more
    a, b, r = np.array([0.1, -0.2, 0.3]), np.array([0.6, 0.4, -0.1]), 0.25
    volume, center, inertia = capsule_volume_inertia(tuple(a), tuple(b), r)
    rng = np.random.default_rng(15)
    lo, hi = np.minimum(a, b) - r, np.maximum(a, b) + r
    pts = rng.uniform(lo, hi, (2_000_000, 3))
    u = (b - a) / np.linalg.norm(b - a)
    t = np.clip((pts - a) @ u, 0.0, np.linalg.norm(b - a))
    inside = np.linalg.norm(pts - (a + t[:, None] * u), axis=1) <= r
    box = float(np.prod(hi - lo))
    q = pts[inside] - center
    sampled = box / len(pts) * (np.sum(q * q) * np.eye(3) - q.T @ q)
    assert box * inside.mean() == pytest.approx(volume, rel=0.01)
    assert np.abs(sampled - inertia).max() < 0.01 * np.abs(inertia).max()


def dirichlet_moments() -> tuple[float, np.ndarray, np.ndarray]:
    """Volume, first and second moments of the unit simplex (0, e1, e2, e3) from the
    Dirichlet integral ∫ x^a y^b z^c = a! b! c! / (a + b + c + 3)!."""

    def integral(a: int, b: int, c: int) -> float:
        return factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3)

    first = np.array([integral(1, 0, 0), integral(0, 1, 0), integral(0, 0, 1)])
    second = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            powers = [0, 0, 0]
            powers[i] += 1
            powers[j] += 1
            second[i, j] = integral(*powers)
    return integral(0, 0, 0), first, second


def test_tetrahedron_inertia_matches_the_dirichlet_integral():
    # a general tetrahedron v0 + A u (u in the unit simplex): its moments are the unit
    # simplex's, mapped: V = |det A| V₁, ∫ x = |det A| (A m₁ + V₁ v0), ∫ x xᵀ =
    # |det A| (A M₂ Aᵀ + A m₁ v0ᵀ + v0 m₁ᵀ Aᵀ + V₁ v0 v0ᵀ)
    v = np.array([[0.2, 0.1, -0.3], [1.3, 0.2, 0.1], [0.4, 1.1, 0.2], [0.3, 0.4, 0.9]])
    verts, faces, _ = convex_hull([tuple(x) for x in v])
    volume, center, inertia = convex_volume_inertia(verts, faces)
    a = (v[1:] - v[0]).T
    det = abs(np.linalg.det(a))
    v1, m1, m2 = dirichlet_moments()
    vol = det * v1
    first = det * (a @ m1 + v1 * v[0])
    c = first / vol
    second = det * (a @ m2 @ a.T + np.outer(a @ m1, v[0]) + np.outer(v[0], a @ m1))
    second += det * v1 * np.outer(v[0], v[0])
    cov = second - vol * np.outer(c, c)
    expected = np.trace(cov) * np.eye(3) - cov
    assert volume == pytest.approx(vol, rel=RTOL)
    np.testing.assert_allclose(center, c, rtol=RTOL)
    np.testing.assert_allclose(inertia, expected, rtol=1e-11, atol=1e-14 * np.abs(expected).max())


def test_regular_tetrahedron_is_isotropic_with_m_a_squared_over_20():
    # the closed form of a regular tetrahedron of edge a: I = m a²/20 about every axis
    # through its centre
    v = [(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)]  # edge 2√2
    verts, faces, _ = convex_hull(v)
    volume, center, inertia = convex_volume_inertia(verts, faces)
    edge = 2 * math.sqrt(2)
    assert volume == pytest.approx(edge**3 / (6 * math.sqrt(2)), rel=RTOL)
    np.testing.assert_allclose(center, (0, 0, 0), atol=1e-15)
    np.testing.assert_allclose(inertia, volume * edge**2 / 20 * np.eye(3), rtol=RTOL, atol=1e-15)


def test_convex_hull_of_a_box_corners_is_the_box():
    size = (0.3, 0.2, 0.1)
    q = axis_angle((1.0, 2.0, 3.0), 0.7)
    helper = box_volume_inertia(size, (0.5, -0.2, 0.1), q)
    box = props_of(
        "{shape: {box: {size: [0.3, 0.2, 0.1], offset: [0.5, -0.2, 0.1], "
        "rotation: {axis: [1, 2, 3], angle: 0.7}}}}"
    )
    hull = body(
        "{shape: {box: {size: [0.3, 0.2, 0.1], offset: [0.5, -0.2, 0.1], "
        "rotation: {axis: [1, 2, 3], angle: 0.7}}}}"
    ).shapes[0]
    convex = props_of(
        "{shape: {convex: {vertices: "
        + str([list(p) for p in hull.vertices + ((0.5, -0.2, 0.1),)])  # and the centre
        + "}}}"
    )
    assert convex.mass == pytest.approx(box.mass, rel=RTOL)
    np.testing.assert_allclose(convex.center, box.center, rtol=RTOL, atol=1e-15)
    np.testing.assert_allclose(convex.inertia, box.inertia, rtol=1e-11, atol=1e-17)
    np.testing.assert_allclose(box.inertia, helper[2] * 1.0, rtol=RTOL)  # density 1


def test_rotated_offset_compound_matches_the_closed_form():
    # a box 2 x 0.2 x 0.2 turned 30° about z, a ball r = 0.3 at (1, 0.5, 0), density 1:
    # the box's tensor in its own axes, turned by R_z(30°) (written out), and each part
    # moved to the common centre with m (|d|² E − d dᵀ)
    theta = math.pi / 6
    p = props_of(
        "{shapes: [{box: {size: [2, 0.2, 0.2], rotation: {axis: [0, 0, 1], angle: "
        f"{theta!r}}}}}}}, {{sphere: {{radius: 0.3, offset: [1, 0.5, 0]}}}}]}}"
    )
    m_box, m_ball = 2 * 0.2 * 0.2, 4 / 3 * math.pi * 0.027
    ixx, iyy, izz = m_box / 12 * (0.04 + 0.04), m_box / 12 * (4 + 0.04), m_box / 12 * (4 + 0.04)
    c, s = math.cos(theta), math.sin(theta)
    box = np.array(
        [
            [c * c * ixx + s * s * iyy, c * s * (ixx - iyy), 0.0],
            [c * s * (ixx - iyy), s * s * ixx + c * c * iyy, 0.0],
            [0.0, 0.0, izz],
        ]
    )
    com = m_ball * np.array([1.0, 0.5, 0.0]) / (m_box + m_ball)
    expected = box + 0.4 * m_ball * 0.09 * np.eye(3)
    for m, at in ((m_box, np.zeros(3)), (m_ball, np.array([1.0, 0.5, 0.0]))):
        d = at - com
        expected += m * (d @ d * np.eye(3) - np.outer(d, d))
    assert p.mass == pytest.approx(m_box + m_ball, rel=RTOL)
    np.testing.assert_allclose(p.center, com, rtol=RTOL, atol=1e-16)
    np.testing.assert_allclose(p.inertia, expected, rtol=RTOL, atol=1e-15)
    assert p.inertia[0, 1] != 0.0  # the rotation and the offset give products of inertia


def test_mass_scales_every_shape_alike():
    shapes = "[{box: {size: [1, 1, 1]}}, {sphere: {radius: 0.5, offset: [1, 0, 0]}, density: 3}]"
    free = props_of(f"{{shapes: {shapes}}}")
    fixed = props_of(f"{{mass: 10, shapes: {shapes}}}")
    assert fixed.mass == 10.0
    assert fixed.center == free.center  # the density distribution is kept
    np.testing.assert_allclose(fixed.inertia, free.inertia * 10.0 / free.mass, rtol=RTOL)


def test_principal_axes_diagonalise_the_tensor_with_a_rotation():
    p = props_of(
        "{shapes: [{box: {size: [0.5, 0.2, 0.1], rotation: {axis: [1, 1, 0], angle: 0.4}}}, "
        "{capsule: {a: [0, 0, 0], b: [0, 0, 0.6], radius: 0.05}}]}"
    )
    q, moments = principal_axes(p.inertia)
    r = quat_matrix(q)
    assert math.hypot(*q) == pytest.approx(1.0, abs=1e-15)  # unit to round-off
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)  # right-handed, to round-off
    assert moments[0] <= moments[1] <= moments[2]
    # the eigen-solver's residual is round-off of the tensor's largest entry
    scale = np.abs(p.inertia).max()
    np.testing.assert_allclose(r @ np.diag(moments) @ r.T, p.inertia, atol=1e-13 * scale)


def test_unit_box_rotated_has_axes_that_undo_the_rotation():
    theta = 0.3
    scene = load_scene_text(
        "version: 1\nworld: {dimension: 3}\nbodies:\n"
        f"  - shape: {{box: {{size: [3, 2, 1], rotation: {{axis: [0, 0, 1], angle: {theta}}}}}}}\n"
    )
    model, _ = build(scene)
    r = quat_matrix(model.body_axes[0])
    # moments ascending: the 3 m side's axis (least), then 2 m, then the 1 m side's;
    # in the box's own axes that is x, y, z, turned by R_z(θ)
    expected = rotation_z(theta)
    np.testing.assert_allclose(np.abs(r), np.abs(expected), atol=1e-12)  # round-off of eigh


def test_compiled_state_holds_the_com_and_the_angular_momentum():
    scene = load_scene_text(
        """\
version: 1
world: {dimension: 3}
bodies:
  - name: ground
    type: static
    shape: {plane: {normal: [0, 2, 0], offset: -1}}
  - name: lump
    position: [1, 2, 3]
    rotation: {axis: [1, 0, 1], angle: 0.8}
    velocity: [0.5, 0, 0]
    angular_velocity: [0.3, -2, 1]
    force: [0, 0, 1]
    force_point: [0.5, 0, 0]
    shapes:
      - {box: {size: [1, 0.4, 0.2]}}
      - {sphere: {radius: 0.3, offset: [0.6, 0.2, 0]}}
"""
    )
    model, state = build(scene)
    lump = scene.bodies[1]
    props = body_mass_properties_3d(lump)
    r = quat_matrix(lump.orientation)
    com = np.asarray(props.center)
    np.testing.assert_array_equal(model.body_com[1], com)
    np.testing.assert_allclose(state.body_x[1], np.array([1, 2, 3]) + r @ com, rtol=RTOL)
    np.testing.assert_allclose(state.body_q[1], lump.orientation, rtol=0)
    w = np.array([0.3, -2, 1])
    np.testing.assert_allclose(state.body_l[1], r @ props.inertia @ r.T @ w, rtol=RTOL)
    np.testing.assert_allclose(
        model.body_inv_inertia[1] @ model.body_inertia[1], np.eye(3), atol=1e-12
    )
    np.testing.assert_allclose(model.body_force_arm[1], np.array([0.5, 0, 0]) - com, rtol=RTOL)
    np.testing.assert_allclose(body_origin(model, state), [[0, 0, 0], [1, 2, 3]], atol=1e-15)
    # the static plane: infinite mass and inertia, nothing inverse, its normal on its row
    assert model.body_mass[0] == math.inf and model.body_inv_mass[0] == 0.0
    np.testing.assert_array_equal(model.body_inertia[0], np.diag([math.inf] * 3))
    assert not model.body_inv_inertia[0].any() and not state.body_l[0].any()
    k = model.shape_vstart[0]
    np.testing.assert_array_equal(model.vertex_local[k], [0, -1, 0])
    np.testing.assert_array_equal(model.normal_local[k], [0, 1, 0])
    assert not model.normal_local[model.shape_vstart[1] :].any()
    assert model.shape_kind.tolist() == [7, 4, 3]  # plane, box, sphere (types.SHAPE_*)
    assert model.body_axes.shape == (2, 4) and model.body_moments[0].tolist() == [math.inf] * 3
    assert state.body_angle.shape == (0,) and model.gravity.tolist() == [0, -9.81, 0]
    assert model.has_shapes is True  # a dynamic box and sphere can touch the ground plane


def test_a_2d_build_keeps_its_arrays_and_gains_an_empty_angular_momentum():
    scene = load_scene_text("version: 1\nbodies: [{shape: {circle: {radius: 1}}}]\n")
    model, state = build(scene)
    assert state.body_x.shape == (1, 2) and state.body_q.shape == (1, 2)
    assert model.body_inertia.shape == (1,)
    assert state.body_l.shape == (0,)
    assert model.body_axes.tolist() == [[1, 0, 0, 0]] and model.body_moments.tolist() == [[0, 0, 0]]


def test_sphere_and_box_helpers_take_the_identity_frame():
    v, c, i = sphere_volume_inertia(1.0, (0.0, 0.0, 0.0))
    assert v == pytest.approx(4 / 3 * math.pi, rel=RTOL) and i[0, 0] == pytest.approx(0.4 * v)
    v, c, i = box_volume_inertia((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), IDENTITY)
    assert v == 1.0 and i.tolist() == (np.eye(3) / 6).tolist()
