"""Mass properties against closed forms."""

from __future__ import annotations

import math

import pytest

from rbsim.scene.mass import body_mass_properties
from tests.conftest import scene_from


def props(shape_yaml: str, extra: str = ""):
    scene = scene_from(
        f"""
        version: 1
        world: {{steps: 1}}
        bodies:
          - name: b
            density: 2.0
            {extra}
            {shape_yaml}
        """
    )
    return body_mass_properties(scene.bodies[0])


def test_circle_mass_and_inertia_match_closed_form():
    p = props("shape: {circle: {radius: 0.5}}")
    m = 2.0 * math.pi * 0.25
    assert p.mass == pytest.approx(m, rel=1e-14)
    assert p.inertia == pytest.approx(0.5 * m * 0.25, rel=1e-14)
    assert p.center == pytest.approx((0.0, 0.0), abs=1e-15)


def test_box_mass_and_inertia_match_closed_form_even_rotated_and_offset():
    p = props("shape: {box: {size: [2, 0.5], offset: [0.3, -0.2], angle: 0.7}}")
    m = 2.0 * 2.0 * 0.5
    assert p.mass == pytest.approx(m, rel=1e-13)
    assert p.inertia == pytest.approx(m * (4.0 + 0.25) / 12.0, rel=1e-12)
    assert p.center == pytest.approx((0.3, -0.2), abs=1e-13)


def test_right_triangle_centroid_and_inertia():
    # legs a (x) and b (y): area ab/2, centroid (a/3, b/3), polar moment about the
    # centroid m (a² + b²) / 18
    a, b = 3.0, 2.0
    p = props(f"shape: {{polygon: {{vertices: [[0, 0], [{a}, 0], [0, {b}]]}}}}")
    m = 2.0 * a * b / 2
    assert p.mass == pytest.approx(m, rel=1e-13)
    assert p.center == pytest.approx((a / 3, b / 3), abs=1e-13)
    assert p.inertia == pytest.approx(m * (a * a + b * b) / 18.0, rel=1e-12)


def test_compound_body_uses_parallel_axis_theorem():
    # two unit squares side by side = one 2 x 1 box centred at (0.5, 0)
    p = props(
        """shapes:
              - {box: {size: [1, 1], offset: [0, 0]}}
              - {box: {size: [1, 1], offset: [1, 0]}}"""
    )
    m = 2.0 * 2.0
    assert p.mass == pytest.approx(m, rel=1e-13)
    assert p.center == pytest.approx((0.5, 0.0), abs=1e-13)
    assert p.inertia == pytest.approx(m * (4.0 + 1.0) / 12.0, rel=1e-12)


def test_circle_and_offset_box_compound():
    p = props(
        """shapes:
              - {circle: {radius: 1.0, offset: [0, 0]}}
              - {box: {size: [1, 2], offset: [3, 0]}}"""
    )
    mc, mb = 2.0 * math.pi, 2.0 * 2.0
    cx = (mb * 3.0) / (mc + mb)
    inertia = mc * 0.5 + mc * cx**2 + mb * (1 + 4) / 12 + mb * (3.0 - cx) ** 2
    assert p.mass == pytest.approx(mc + mb, rel=1e-13)
    assert p.center == pytest.approx((cx, 0.0), abs=1e-13)
    assert p.inertia == pytest.approx(inertia, rel=1e-12)


def test_capsule_inertia_matches_rectangle_plus_half_discs():
    r, length = 0.25, 2.0
    p = props(f"shape: {{segment: {{a: [-1, 0], b: [1, 0], radius: {r}}}}}")
    ar, ac = 2 * r * length, math.pi * r * r
    d = 4 * r / (3 * math.pi)  # half-disc centroid from its flat side
    half = 2.0 * ac / 2  # mass of one half disc
    i_half = half * (r * r / 2 - d * d) + half * (length / 2 + d) ** 2
    expected = 2.0 * ar * (length**2 + 4 * r * r) / 12 + 2 * i_half
    assert p.mass == pytest.approx(2.0 * (ar + ac), rel=1e-13)
    assert p.inertia == pytest.approx(expected, rel=1e-12)


def test_mass_override_scales_inertia():
    p = props("shape: {box: {size: [1, 2]}}", extra="mass: 10.0")
    assert p.mass == 10.0
    assert p.inertia == pytest.approx(10.0 * 5.0 / 12.0, rel=1e-13)
