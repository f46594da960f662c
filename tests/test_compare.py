"""`rbsim compare`: the same scene in rbsim and pymunk (DESIGN.md, exit code 4).

The matching scenes in scenes/compare/ carry tolerances derived from the two engines'
update orders (see the comment in each file); these tests run them, check the derived
differences themselves, and check that an honest difference (a setting that only rbsim
has) is reported with exit 4 and the body's name.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rbsim.compare import BodyDiff, CompareResult, compare_scene
from rbsim.scene import load_scene
from rbsim.trajectory import load_trajectory

from .conftest import rbsim

REPO = Path(__file__).resolve().parents[1]
COMPARE = REPO / "scenes" / "compare"
SCENES = sorted(COMPARE.glob("*.yaml"))
G = 9.81  # m/s², the gravity of projectile.yaml
H = (1 / 60) / 4  # s, one step of either engine (dt / substeps) in every compare scene


def test_the_matching_scenes_exist():
    names = {p.stem for p in SCENES}
    assert {"projectile", "free_spin", "constant_torque", "head_on"} <= names
    for path in SCENES:
        scene = load_scene(path)
        assert scene.compare, f"{path.name} has no compare: block"
        assert scene.world.steps * scene.world.dt <= 2.0 + 1e-9


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_matching_scene_passes(path: Path, tmp_path: Path):
    code, out, err = rbsim("compare", path, "-o", tmp_path)
    assert code == 0, err
    assert "ok" in out.splitlines()[-1]
    name = load_scene(path).name
    assert (tmp_path / f"{name}.rbsim.h5").is_file()
    assert (tmp_path / f"{name}.pymunk.h5").is_file()


def test_projectile_differs_by_g_h_t(tmp_path: Path):
    """rbsim updates v before x, pymunk x before v: the positions differ by g h t."""
    scene = load_scene(COMPARE / "projectile.yaml")
    result = compare_scene(scene, tmp_path)
    t = scene.world.steps * scene.world.dt
    (ball,) = result.bodies
    assert ball.final_position == pytest.approx(G * H * t, rel=1e-9)
    assert ball.max_position == pytest.approx(G * H * t, rel=1e-9)
    assert ball.max_velocity < 1e-9
    # both engines conserve momentum in x; the y momentum is m (vy0 - g t) in both
    m = math.pi * 0.25**2
    for engine in ("rbsim", "pymunk"):
        assert result.momentum[engine][1] == pytest.approx(m * (10 - G * t), rel=1e-9)


def test_free_spin_and_torque_angles_as_derived(tmp_path: Path):
    spin = compare_scene(load_scene(COMPARE / "free_spin.yaml"), tmp_path)
    n = 120 * 4  # pymunk/rbsim steps of 1/240 s in 2 s
    assert spin.bodies[0].final_angle == pytest.approx(n * (7 * H - math.atan(7 * H)), rel=1e-6)
    torque = compare_scene(load_scene(COMPARE / "constant_torque.yaml"), tmp_path)
    alpha = 0.5 / (2 * (2**2 + 1**2) / 12)  # rad/s²
    assert torque.bodies[0].final_angle == pytest.approx(alpha * H * 2.0, rel=1e-9)


def test_head_on_swaps_velocities_in_both(tmp_path: Path):
    result = compare_scene(load_scene(COMPARE / "head_on.yaml"), tmp_path)
    rb = load_trajectory(result.files["rbsim"])
    pm = load_trajectory(result.files["pymunk"])
    for tr in (rb, pm):
        np.testing.assert_allclose(tr.velocity[-1, :, 0], [-2.0, 2.0], atol=1e-12)
    # rbsim follows the analytic bounce: x_left(1 s) = -0.25 - 2 m/s × 0.625 s
    assert rb.position[-1, 0, 0] == pytest.approx(-1.5, abs=1e-9)
    for b in result.bodies:
        assert 0 < b.max_position <= 2 * 2.0 * H


def test_rbsim_only_setting_differs_and_exits_4(tmp_path: Path):
    """A restitution threshold of 5 m/s (rbsim only) stops the 4 m/s approach from
    bouncing in rbsim; pymunk still bounces: velocities differ by 2 m/s per body."""
    code, out, err = rbsim(
        "compare",
        COMPARE / "head_on.yaml",
        "-o",
        tmp_path,
        "--set",
        "solver.restitution_threshold=5",
    )
    assert code == 4
    assert "body 'left'" in err and "velocity" in err
    assert "body 'right'" in err
    assert "OUTSIDE TOLERANCE" in out


def test_option_overrides_scene_tolerance(tmp_path: Path):
    """--position below the derived g h t = 0.0818 m makes the projectile fail."""
    code, _out, err = rbsim(
        "compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--position", "0.05"
    )
    assert code == 4
    assert "body 'ball'" in err and "position" in err and "0.05" in err


def test_unchecked_quantity_is_not_checked(tmp_path: Path):
    # a scene without compare: block and no options checks nothing: exit 0 even though
    # the positions differ by g h t
    scene = tmp_path / "bare.yaml"
    scene.write_text(
        "version: 1\nworld: {dt: 1/60, steps: 30}\n"
        "bodies:\n  - {name: ball, shape: {circle: {radius: 0.5}}}\n"
    )
    code, out, err = rbsim("compare", scene, "-o", tmp_path, "--angle", "1e-12")
    assert code == 0, err
    assert "angle 1e-12 rad" in out and "position" not in out.split("tolerance:")[1]


def test_json_output(tmp_path: Path):
    code, out, _err = rbsim("compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--json")
    assert code == 0
    data = json.loads(out)
    assert data["ok"] is True
    assert data["tolerances"] == {"position": 0.0818, "angle": 1e-9, "velocity": 1e-9}
    (ball,) = data["bodies"]
    assert ball["name"] == "ball" and ball["max_position"] == pytest.approx(G * H * 2.0)
    assert set(data["energy"]) == set(data["us_per_step"]) == {"rbsim", "pymunk"}

    code, out, _err = rbsim(
        "compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--json", "--velocity", "0"
    )
    assert code in (0, 4)
    assert json.loads(out)["ok"] is (code == 0)
    code, out, _err = rbsim(
        "compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--json", "--position", "0.01"
    )
    assert code == 4 and json.loads(out)["ok"] is False


def test_trajectories_have_same_frames(tmp_path: Path):
    code, _out, err = rbsim(
        "compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--set", "output.every=7"
    )
    assert code == 0, err
    rb = load_trajectory(tmp_path / "projectile.rbsim.h5")
    pm = load_trajectory(tmp_path / "projectile.pymunk.h5")
    assert rb.engine == "rbsim" and pm.engine == "pymunk"
    assert rb.status == pm.status == "complete"
    expected = [*range(0, 120, 7), 120]
    assert rb.step.tolist() == expected
    np.testing.assert_array_equal(rb.step, pm.step)
    np.testing.assert_array_equal(rb.time, pm.time)
    assert rb.bodies.name == pm.bodies.name == ["ball"]
    assert json.loads(pm.parameters["solver"])["substeps"] == 4
    assert set(pm.observables) == set(rb.observables)


def test_unsupported_scene_exits_3(tmp_path: Path):
    code, out, err = rbsim(
        "compare",
        COMPARE / "projectile.yaml",
        "-o",
        tmp_path,
        "--set",
        "world.damping={linear: 0.1, angular: 0.2}",
    )
    assert code == 3
    assert "pymunk cannot express" in err and "damping" in err
    assert not (tmp_path / "projectile.rbsim.h5").exists()


def test_table_shows_ten_worst():
    bodies = [BodyDiff(f"b{i}", i * 0.1, 0, 0, 0, 0, 0, 0, 0) for i in range(12)]
    result = CompareResult(
        scene="many",
        steps=1,
        bodies=bodies,
        tolerances={},
        energy={"rbsim": 0.0, "pymunk": 0.0},
        momentum={"rbsim": [0.0, 0.0], "pymunk": [0.0, 0.0]},
        us_per_step={"rbsim": 1.0, "pymunk": 1.0},
        files={"rbsim": "a.h5", "pymunk": "b.h5"},
        pymunk_settings={},
    )
    names = [b.name for b in result.worst()]
    assert names == [f"b{i}" for i in range(11, 1, -1)]
    text = result.table()
    assert "b11" in text and " b0 " not in text and " b1 " not in text
    assert "10 worst of 12" in text
    assert len(result.to_dict()["bodies"]) == 12
