"""`rbsim compare`: the same scene in rbsim and pymunk (cli.md, exit code 4).

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

from rbsim.io.trajectory import load_trajectory
from rbsim.scene import load_scene
from rbsim.tools.compare import BodyDiff, CompareResult, compare_scene

from .conftest import rbsim, scene_from

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


def test_explicit_euler_is_chipmunks_update_order(tmp_path: Path):
    """Chipmunk moves x with the old v, then updates v: rbsim's explicit Euler does the
    same, so the g h t difference of projectile.yaml vanishes."""
    scene = load_scene(COMPARE / "projectile.yaml", ["solver.integrator=explicit_euler"])
    (ball,) = compare_scene(scene, tmp_path).bodies
    assert ball.max_position < 1e-9  # round-off, against g h t = 0.08 m


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


# -- the matching scenes added for issue 4, and statistics -------------------------------


def test_every_matching_scene_of_the_issue_is_there():
    names = {p.stem for p in SCENES}
    assert {"slope_rest", "slope_slide", "bounce", "off_centre", "stack"} <= names
    assert load_scene(COMPARE / "stack.yaml").compare["iterations"] == 100


def test_different_restitution_in_pymunk_alone_exits_4(tmp_path: Path):
    """e = 0.5 instead of 1 in pymunk only: the head-on pair no longer swaps velocities."""
    code, out, err = rbsim(
        "compare",
        COMPARE / "head_on.yaml",
        "-o",
        tmp_path,
        "--pymunk-set",
        "materials.elastic.restitution=0.5",
    )
    assert code == 4
    assert "body 'left'" in err and "velocity" in err
    pm = load_trajectory(tmp_path / "head_on.pymunk.h5")
    # e = 0.5, equal masses: each leaves at (1 - e)/2 × 2 - (1 + e)/2 × 2 = -1 m/s
    np.testing.assert_allclose(pm.velocity[-1, :, 0], [-1.0, 1.0], atol=1e-9)  # round-off


def test_bounce_scene_fails_with_restitution_0_4_in_pymunk(tmp_path: Path):
    code, _out, err = rbsim(
        "compare",
        COMPARE / "bounce.yaml",
        "-o",
        tmp_path,
        "--pymunk-set",
        "materials.rubber.restitution=0.4",
    )
    assert code == 4 and "body 'ball'" in err and "position" in err


def test_restitution_threshold_applies_in_both_engines(tmp_path: Path):
    """A 5 m/s threshold stops the 4 m/s head-on approach from bouncing in both engines
    (pymunk through the bridge's pre_solve handler): both end at rest together."""
    code, _out, err = rbsim(
        "compare",
        COMPARE / "head_on.yaml",
        "-o",
        tmp_path,
        "--set",
        "solver.restitution_threshold=5",
        "--position",
        "1",
    )
    assert code == 0, err
    for engine in ("rbsim", "pymunk"):
        tr = load_trajectory(tmp_path / f"head_on.{engine}.h5")
        np.testing.assert_allclose(tr.velocity[-1, :, 0], [0.0, 0.0], atol=1e-9)  # round-off


def test_pymunk_set_must_keep_the_same_frames(tmp_path: Path):
    code, _out, err = rbsim(
        "compare", COMPARE / "head_on.yaml", "-o", tmp_path, "--pymunk-set", "world.steps=3"
    )
    assert code == 3 and "steps or dt differ" in err


def test_compare_iterations_key_sets_pymunk_iterations(tmp_path: Path):
    scene = load_scene(COMPARE / "stack.yaml")
    result = compare_scene(scene, tmp_path)
    assert result.pymunk_settings["iterations"] == 100
    # with Chipmunk's default 10 iterations the stack creeps beyond the slop bound
    assert not compare_scene(scene, tmp_path, iterations=10).ok


def test_statistics_of_a_resting_stack(tmp_path: Path):
    scene = load_scene(COMPARE / "stack.yaml")
    result = compare_scene(scene, tmp_path, with_statistics=True)
    st = result.statistics
    assert st is not None and result.statistics_tolerances == {}
    for engine in ("rbsim", "pymunk"):
        # heights 0.5 .. 4.5 m: mean 2.5, spread sqrt(2); each sags by less than 5 slops
        assert st["mean_height"][engine] == pytest.approx(2.5, abs=0.025)
        assert st["heights"][engine] == pytest.approx(math.sqrt(2), abs=0.025)
        assert 0.0 < st["penetration"][engine] < 0.005  # within the collision slop
    tr = load_trajectory(result.files["pymunk"])
    assert st["kinetic_energy"]["pymunk"] == tr.observables["kinetic_energy"][-1]
    assert st["heights"]["difference"] >= st["mean_height"]["difference"]


def test_max_penetration_measures_a_known_overlap(tmp_path: Path):
    from rbsim.tools.compare import max_penetration

    scene = scene_from(
        """
        version: 1
        world: {gravity: [0, 0], steps: 1}
        bodies:
          - {name: a, shape: {circle: {radius: 0.5}}}
          - {name: b, position: [0.9, 0], shape: {circle: {radius: 0.5}}}
        """
    )
    scene.compare["statistics"] = {}
    out = tmp_path / "two.h5"
    from rbsim.run import run_scene

    run_scene(scene, out)
    tr = load_trajectory(out)
    tr.position[:] = [[0.0, 0.0], [0.9, 0.0]]  # 0.1 m overlap at every frame
    assert max_penetration(tr, scene) == pytest.approx(0.1, abs=1e-12)  # round-off
    tr.position[:, 1, 0] = 1.2
    assert max_penetration(tr, scene) == 0.0


def test_statistics_tolerance_from_set_exits_4_and_is_in_json(tmp_path: Path):
    code, out, err = rbsim(
        "compare",
        COMPARE / "stack.yaml",
        "-o",
        tmp_path,
        "--json",
        "--set",
        "compare.statistics={mean_height: 1.0e-12, penetration: 1}",
    )
    assert code == 4
    assert "statistics: final mean height" in err and "mean_height tolerance" in err
    data = json.loads(out)
    assert data["statistics_tolerances"] == {"mean_height": 1e-12, "penetration": 1.0}
    assert set(data["statistics"]) == {"kinetic_energy", "mean_height", "heights", "penetration"}


def test_statistics_flag_prints_the_table(tmp_path: Path):
    code, out, _err = rbsim("compare", COMPARE / "projectile.yaml", "-o", tmp_path, "--statistics")
    assert code == 0
    assert "final kinetic energy J" in out and "max penetration" in out


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("compare.statistics.kinetic_energy=-1", "must be >= 0"),
        ("compare.statistics.heigths=1", "did you mean heights?"),
        ("compare.iterations=0", "must be between 1 and 1e6"),
    ],
)
def test_bad_compare_keys_exit_3_naming_the_key(tmp_path: Path, setting: str, message: str):
    code, _out, err = rbsim("compare", COMPARE / "stack.yaml", "-o", tmp_path, "--set", setting)
    assert code == 3 and message in err and setting.split("=")[0].split(".")[0] in err


def test_bad_statistics_key_in_a_file_names_line_and_key(tmp_path: Path):
    scene = tmp_path / "bad.yaml"
    scene.write_text(
        "version: 1\nbodies:\n  - {name: ball, shape: {circle: {radius: 0.5}}}\n"
        "compare:\n  statistics: {mean_height: fast}\n"
    )
    code, _out, err = rbsim("compare", scene, "-o", tmp_path)
    assert code == 3
    assert f"{scene}:5:" in err and "compare.statistics.mean_height" in err


@pytest.mark.parametrize("option", ["--position", "--velocity", "--angle"])
@pytest.mark.parametrize("value", ["nan", "inf", "-1"])
def test_a_non_finite_or_negative_tolerance_is_a_usage_error(tmp_path: Path, option, value):
    """A nan tolerance passed every check (nan > x is false), so that nothing was
    compared; inf likewise: a usage error naming the option, before either engine runs."""
    code, _out, err = rbsim(
        "compare", COMPARE / "projectile.yaml", "-o", tmp_path, f"{option}={value}"
    )
    assert code == 2 and f"'{option}'" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("option", ["--pymunk-set", "--reference-set"])
def test_a_bad_reference_override_names_its_own_option(tmp_path: Path, option: str):
    """The reference engine's overrides go through the validator as --set lines; their
    messages name the option given, not --set."""
    scene = COMPARE / "projectile.yaml"
    code, _out, err = rbsim("compare", scene, "-o", tmp_path, option, "bogus")
    assert code == 3
    assert err.strip() == (
        f"{scene}: {option} bogus: expected key.path=value (such as world.dt=0.01), got 'bogus'"
    )
    code, _out, err = rbsim("compare", scene, "-o", tmp_path, option, "world.dt=fast")
    assert code == 3 and f"{scene}: {option} world.dt: expected a number" in err
    # a --set problem is still a --set's
    code, _out, err = rbsim(
        "compare", scene, "-o", tmp_path, "--set", "world.dt=fast", option, "world.steps=3"
    )
    assert code == 3 and f"{scene}: --set world.dt: expected a number" in err
