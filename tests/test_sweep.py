"""`rbsim sweep`: the machinery on tiny grids, the analytic references, the output files."""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rbsim.scene import SceneError, load_scene
from rbsim.tools.reference import ReferenceError, make_reference
from rbsim.tools.sweep import Grid, Point, Setting, fitted_slope, pareto_front, run_sweep
from tests.conftest import rbsim, scene_from
from tests.test_dynamics3d import BRICK

ROOT = Path(__file__).parent.parent
REFERENCE_SCENES = ROOT / "scenes" / "reference"

PROJECTILE = """
version: 1
name: throw
world: {gravity: [0, -9.81], dt: 1/60, duration: 1}
bodies:
  - {name: ball, position: [0, 10], velocity: [3, 10], shape: {circle: {radius: 0.25}}}
reference: {kind: projectile}
"""

TINY = {"substeps": (1,), "iterations": (1,), "rotations": ("normalize",)}


def rbsim_points(result, **match) -> list[Point]:
    """rbsim points of a sweep, ordered from the largest dt down."""
    pts = [p for p in result.points if p.setting.engine == "rbsim"]
    for key, value in match.items():
        pts = [p for p in pts if getattr(p.setting, key) == value]
    return sorted(pts, key=lambda p: p.setting.dt, reverse=True)


def test_projectile_error_shrinks_at_first_order_in_dt():
    scene = scene_from(PROJECTILE)
    grid = Grid(dts=(1 / 30, 1 / 60, 1 / 120), pymunk_iterations=(), **TINY)
    result = run_sweep(scene, grid, repeats=1)
    pts = rbsim_points(result)
    errors = [p.error for p in pts]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    # symplectic Euler's projectile error is exactly g h t / 2: order 1 up to rounding
    assert orders == pytest.approx([1.0, 1.0], abs=1e-6)
    for p in pts:  # largest at the end of the run, t = 1 s
        # the same closed form; rounding of positions of ~10 m over <= 120 steps
        assert p.error == pytest.approx(9.81 * p.setting.dt * 1.0 / 2, rel=1e-9)
        assert p.cpu > 0 and p.timed_runs >= 1


def test_free_spin_exact_rotation_is_exact_and_normalize_is_second_order():
    scene = load_scene(REFERENCE_SCENES / "free_spin.yaml")
    grid = Grid(
        dts=(1 / 30, 1 / 60, 1 / 120),
        substeps=(1,),
        iterations=(1,),
        rotations=("normalize", "exact"),
        pymunk_iterations=(),
    )
    result = run_sweep(scene, grid, repeats=1, duration=1.0)
    for p in rbsim_points(result, rotation="exact"):
        # the exact update turns by ω h each step: only rounding of the angle remains
        assert p.error < 1e-12
    errors = [p.error for p in rbsim_points(result, rotation="normalize")]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    # per step the angle is short by ω h - atan(ω h) ≈ (ω h)³/3, so by t (ω h)²ω/3 at t:
    # order 2, approached as ω h -> 0 (ω h = 0.23 at 1/30 s; the next term is 5 % of it)
    assert orders == pytest.approx([2.0, 2.0], abs=0.1)


def test_output_files_parse(tmp_path: Path):
    scene = scene_from(PROJECTILE)
    grid = Grid(dts=(1 / 30, 1 / 60), pymunk_iterations=(10,), **TINY)
    result = run_sweep(scene, grid, repeats=1, duration=0.5)
    paths = result.write(tmp_path, plot=True)
    with open(paths["csv"], newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(grid.settings()) == 4
    assert {r["engine"] for r in rows} == {"rbsim", "pymunk"}
    assert all(float(r["error_m"]) > 0 and float(r["cpu_s_per_sim_s"]) > 0 for r in rows)
    data = json.loads(paths["json"].read_text())
    assert data["reference_kind"] == "projectile"
    assert len(data["points"]) == 4
    assert any(p["pareto_front"] for p in data["points"] if p["engine"] == "pymunk")
    assert set(data["verdict"]) >= {"rbsim_dominates", "rows", "pymunk_front_points"}
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_missing_matplotlib_still_writes_table_and_csv(tmp_path: Path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib fails
    path = tmp_path / "throw.yaml"
    path.write_text(PROJECTILE)
    code, out, err = rbsim(
        "sweep", path, "-o", tmp_path, "--dt", "1/30", "--substeps", "1", "--iterations", "1",
        "--rotation", "normalize", "--no-pymunk", "--repeats", "1",
    )  # fmt: skip
    assert code == 0, err
    assert "matplotlib is not installed" in err
    assert "throw: speed against error" in out
    assert (tmp_path / "throw.csv").exists() and (tmp_path / "throw.json").exists()
    assert not (tmp_path / "throw.png").exists()


def test_pareto_front_keeps_only_undominated_points():
    def pt(cpu: float, error: float) -> Point:
        return Point(Setting("rbsim", 0.01), cpu=cpu, error=error)

    points = [pt(1, 10), pt(2, 5), pt(3, 6), pt(4, 1), pt(2.5, 5), pt(5, math.inf)]
    front = pareto_front(points)
    assert [(p.cpu, p.error) for p in front] == [(1, 10), (2, 5), (4, 1)]


def test_collision_reference_follows_the_restitution_formula():
    scene = load_scene(REFERENCE_SCENES / "collision.yaml")
    ref = make_reference(scene)
    t = np.array([0.0, 0.1, 1.0, 1.1])  # two samples before the impact (0.3125 s), two after
    poses = ref.poses(t)
    v = (poses.x[[1, 3]] - poses.x[[0, 2]]) / 0.1  # (2 flights, 2 bodies, 2): free flight
    w = (poses.theta[[1, 3]] - poses.theta[[0, 2]]) / 0.1
    m = np.array([math.pi * 0.25**2, 1.0])  # density 1: ball π r², box 1 m²
    inertia = np.array([0.5 * m[0] * 0.25**2, m[1] * 2 / 12])
    p_before, p_after = [(m[:, None] * v[k]).sum(axis=0) for k in (0, 1)]
    # momentum conservation holds to rounding (finite differences of linear motion)
    assert p_after == pytest.approx(p_before, abs=1e-12)
    # normal (x) relative velocity at the contact point (x = -0.5, y = 0.3): -e times
    r_box = np.array([-0.5, 0.3])
    rel = [v[k][1][0] - w[k][1] * r_box[1] - v[k][0][0] for k in (0, 1)]  # ball is a point
    assert rel[1] == pytest.approx(-0.5 * rel[0], rel=1e-9)  # e = 0.5, rounding only
    e_before = (0.5 * m * (v[0] ** 2).sum(axis=1) + 0.5 * inertia * w[0] ** 2).sum()
    e_after = (0.5 * m * (v[1] ** 2).sum(axis=1) + 0.5 * inertia * w[1] ** 2).sum()
    assert e_after < e_before  # e < 1 loses energy


def test_converged_reference_agrees_with_the_analytic_error():
    scene = scene_from(PROJECTILE.replace("reference: {kind: projectile}", ""))
    grid = Grid(dts=(1 / 30,), pymunk_iterations=(), **TINY)
    result = run_sweep(scene, grid, repeats=1, duration=0.5)
    assert result.reference_kind == "converged"
    assert "converged rbsim run" in result.reference
    (point,) = result.points
    # the reference (dt 1/120 s, 4 substeps) is itself off by g h t / 2 with h = 1/480 s
    analytic = 9.81 * (1 / 30) * 0.5 / 2
    assert point.error == pytest.approx(analytic, abs=2 * result.reference_uncertainty)


def test_invariants_of_a_resting_stack_report_penetration_and_energy():
    scene = load_scene(REFERENCE_SCENES / "stack.yaml", ["bodies.1.stack.count=3"])
    grid = Grid(dts=(1 / 60,), substeps=(4,), iterations=(1,), rotations=("normalize",))
    result = run_sweep(
        scene, Grid(**{**grid.__dict__, "pymunk_iterations": (10,)}), repeats=1, duration=0.5
    )
    for p in result.points:
        assert p.status == "ok"
        assert p.penetration is not None and 0.0 <= p.penetration < 0.05  # resting, not sunk
        assert p.energy_drift is not None and p.energy_drift >= 0.0
        assert p.error < 0.05  # three boxes stay within a few slops of their rest pose


def test_fitted_slope_of_a_power_law():
    n = [100, 1000, 10000]
    assert fitted_slope(n, [3.0 * x**1.2 for x in n]) == pytest.approx(1.2, abs=1e-12)


def test_reference_scenes_all_build_their_reference():
    for path in sorted(REFERENCE_SCENES.glob("*.yaml")):
        ref = make_reference(load_scene(path))
        assert ref.kind == load_scene(path).reference["kind"]


def test_reference_that_does_not_fit_the_scene_exits_3(tmp_path: Path):
    path = tmp_path / "two.yaml"
    path.write_text(PROJECTILE.replace("bodies:", "bodies:\n  - {shape: {circle: {radius: 1}}}"))
    with pytest.raises(ReferenceError, match="2 dynamic bodies"):
        make_reference(load_scene(path))
    code, _, err = rbsim("sweep", path, "--dt", "1/30", "--no-pymunk", "-o", tmp_path)
    assert code == 3
    assert f"{path}: reference: the scene has 2 dynamic bodies" in err


@pytest.mark.parametrize(
    ("option", "value"), [("--dt", "1/30,fast"), ("--substeps", "0"), ("--rotation", "exactly")]
)
def test_bad_grid_option_is_a_usage_error(tmp_path: Path, option: str, value: str):
    path = tmp_path / "throw.yaml"
    path.write_text(PROJECTILE)
    code, _, err = rbsim("sweep", path, option, value)
    assert code == 2
    assert option in err and "Traceback" not in err


def test_dts_that_do_not_divide_the_largest_are_a_usage_error(tmp_path: Path):
    path = tmp_path / "throw.yaml"
    path.write_text(PROJECTILE)
    code, _, err = rbsim("sweep", path, "--dt", "1/30,1/45", "--no-pymunk")
    assert code == 2
    assert "does not divide the largest dt 1/30" in err


def test_reference_body_name_is_checked_with_its_location():
    with pytest.raises(SceneError) as info:
        scene_from(PROJECTILE.replace("{kind: projectile}", "{kind: projectile, body: bal}"))
    assert "inline.yaml:7:37: " in str(info.value)  # the line of `reference:`, the column of `bal`
    assert "reference.body: no body named 'bal'; did you mean ball?" in str(info.value)


# the tumbling brick of the dynamics tests, for 17 s: two downward sign changes of ω_y
# (3.7 and 16.6 s), one whole period of ω in the body
BRICK_3D = BRICK.replace("duration: 40", "duration: 17")


def test_3d_sweep_shows_the_rotation_updates_side_by_side(tmp_path: Path):
    from rbsim.tools.sweep import run_rotation_sweep

    scene = scene_from(BRICK_3D)
    grid = Grid(dts=(0.004, 0.002), substeps=(1,))
    result = run_rotation_sweep(scene, grid, repeats=1)
    # two down-crossings of ω_y, at 3.7 and 16.6 s: one whole period; its closed form
    # (the dynamics tests hold it against Euler's equations integrated to 1e-12)
    assert result.period == pytest.approx(12.901246, rel=1e-6)
    by = {(p.rotation, p.dt): p for p in result.points}
    assert sorted({p.rotation for p in result.points}) == ["exact", "normalize", "split"]
    assert all(p.status == "ok" and p.cpu > 0 and p.us_per_step > 0 for p in result.points)
    for dt in (0.004, 0.002):
        split, norm = by["split", dt], by["normalize", dt]
        # split keeps the energy to its second-order error (measured 4.9e-6 at 4 ms)
        assert split.energy_error < 1e-5 and norm.energy_error > 1e4 * split.energy_error
        # and the period (measured 9.5e-6 at 4 ms), where normalize's flip comes early
        assert split.period_error < 1e-4 and norm.period_error > 0.3
    # split is second order: halving dt divides its errors by 4 (to a few per cent of
    # the next term, (h|ω|)² smaller)
    ratio = by["split", 0.004].energy_error / by["split", 0.002].energy_error
    assert ratio == pytest.approx(4.0, rel=0.05)
    text = result.table()
    assert "closed-form period" in text and "split" in text and "12.9012 s" in text
    paths = result.write(tmp_path, plot=False)
    with open(paths["csv"]) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 and {r["rotation"] for r in rows} == {"normalize", "exact", "split"}
    data = json.loads(paths["json"].read_text())
    assert data["closed_form_period_s"] == pytest.approx(result.period)


def test_3d_sweep_says_when_its_energy_error_is_the_whole_scenes():
    # A new user's scene had a ball, a capsule and a box sliding with friction; the table
    # named the ball, and its energy error (0.245, the box's friction) was the scene's.
    # With one dynamic body no note; with a second, a note says whose it is
    from rbsim.tools.sweep import run_rotation_sweep

    grid = Grid(dts=(0.004,), substeps=(1,), rotations=("split",))
    alone = run_rotation_sweep(scene_from(BRICK_3D), grid, repeats=1, duration=0.1)
    assert not any("whole scene" in n for n in alone.notes)
    second = "  - {name: other, position: [3, 1, 0], shape: {sphere: {radius: 0.1}}}\n"
    pair = run_rotation_sweep(scene_from(BRICK_3D + second), grid, repeats=1, duration=0.1)
    assert any("whole scene's (2 dynamic bodies" in n for n in pair.notes), pair.notes
    assert "energy err: the scene's kinetic + potential energy" in pair.table()


def test_3d_sweep_from_the_command_line(tmp_path: Path):
    scene = tmp_path / "brick.yaml"
    scene.write_text(BRICK_3D)
    code, out, err = rbsim(
        "sweep", scene, "-o", tmp_path / "sw", "--dt", "0.004", "--rotation", "split,normalize",
        "--repeats", "1", "--duration", "2", "--no-plot",
    )  # fmt: skip
    assert code == 0, err
    assert "split" in out and "normalize" in out and "exact" not in out.split("front")[-1]
    # 2 s is less than one period: no period errors, and the note says so
    assert "shorter than one period" in out
    code, _o, err = rbsim("sweep", scene, "--rotation", "splt")
    assert code == 2 and "expected one of normalize, exact, split" in err


def test_3d_sweep_too_short_for_a_period_still_plots_and_says_why(tmp_path: Path):
    """With every period error NaN (2 s, a period is 12.9 s) the plot once raised
    matplotlib's "Data cannot be log-scaled" (a traceback, no PNG): the period panel now
    says why instead, and the JSON's notes say why the period errors are NaN."""
    pytest.importorskip("matplotlib")
    scene = tmp_path / "brick.yaml"
    scene.write_text(BRICK_3D)
    code, _o, err = rbsim(
        "sweep", scene, "-o", tmp_path / "sw", "--dt", "0.004", "--substeps", "1",
        "--rotation", "split", "--repeats", "1", "--duration", "2",
    )  # fmt: skip
    assert code == 0 and "Traceback" not in err, err
    data = json.loads((tmp_path / "sw" / "brick.json").read_text())
    assert all(p["period_error_rel"] is None for p in data["points"])  # NaN: JSON null
    assert any("shorter than one period" in n and "NaN" in n for n in data["notes"])
    assert (tmp_path / "sw" / "brick.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "option", "words"),
    [
        (("--duration", "nan"), "--duration", "not a finite number"),
        (("--duration", "inf"), "--duration", "not a finite number"),
        (("--duration", "1e9", "--dt", "1/30"), "--duration", "more than the 1,000,000,000"),
        (("--dt", "1/1000000000000"), "--dt", "within 1e-09 s to 1 s"),
        (("--dt", "2"), "--dt", "within 1e-09 s to 1 s"),
        (("--dt", "1e-9", "--duration", "2"), "--duration", "more than the 1,000,000,000"),
        (("--dt", "1e-7"), "--dt", "body-samples the sweep may hold in memory"),
        (("--duration", "1e7", "--dt", "1"), "--duration", "body-samples"),
        (("--substeps", "2000000"), "--substeps", "at most 1,000,000"),
        (("--substeps", "1000", "--iterations", "1001"), "--iterations", "shape-iterations"),
    ],
)
def test_sweep_options_outside_the_scene_formats_bounds_are_usage_errors(
    tmp_path: Path, args: tuple[str, ...], option: str, words: str
):
    """Each run of a sweep is a scene: its dt, steps and work per step are held to the
    bounds of world.dt (1e-9..1 s), world.steps (1e9) and the work of a step (cli.md,
    "Bounds"), before any run, as a usage error naming the option (not a traceback, a
    numpy allocation of the whole run, or a run no scene could ask for)."""
    path = tmp_path / "throw.yaml"
    path.write_text(PROJECTILE)
    code, _, err = rbsim("sweep", path, *args, "--no-pymunk", "-o", tmp_path)
    assert code == 2, err
    assert f"Invalid value for '{option}'" in err or f"Invalid value for {option}" in err
    assert words in err and "Traceback" not in err


def test_converged_reference_below_the_dt_bound_is_a_usage_error(tmp_path: Path):
    """Without a reference: block the sweep's reference runs at a quarter of the smallest
    dt, which may not go below world.dt's 1e-9 s either."""
    path = tmp_path / "free.yaml"
    path.write_text(PROJECTILE.replace("reference: {kind: projectile}\n", ""))
    code, _, err = rbsim("sweep", path, "--dt", "2e-9", "--duration", "1e-6", "--no-pymunk")
    assert code == 2 and "Invalid value for --dt" in err and "converged reference" in err
