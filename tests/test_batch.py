"""`rbsim batch`: --vary grids and --samples draws, run ids, checks before any run, and
batches on Dask: a LocalCluster, a real scheduler with a worker killed mid-batch, Ctrl-C.

The cluster tests run `python -m rbsim.cli batch` in a subprocess, as a person would (the
workers are spawned processes; a test process is a poor parent for them)."""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from rbsim import cli
from rbsim.batch import (
    FIGURE_COLUMNS,
    BatchInvalid,
    Vary,
    VaryError,
    expand,
    is_complete,
    parse_vary,
    plan_batch,
    read_summary,
    write_summary,
)
from rbsim.io.trajectory import load_trajectory
from tests.conftest import BLAS_THREADS, TAKE_CTRL_C, python_child, rbsim

ROOT = Path(__file__).parent.parent
BOUNCE = ROOT / "scenes" / "bounce.yaml"
STACK = ROOT / "scenes" / "hard" / "stack15.yaml"

# The grid of the bit-for-bit test: 2 time steps x 3 launch velocities of ball 1 (e = 1).
GRID = ("--vary", "world.dt=[1/60,1/120]", "--vary", "bodies.1.velocity=[[0,0],[1,0],[2,0]]")

# A constant force of 3.9e306 N on a 0.785 kg disc (dt = 1 s): the position passes
# 1.6e308 m at step 8 and overflows to inf at step 9 (as in test_cli.py); 1 N is harmless.
ROCKET = """\
version: 1
name: rocket
world: {gravity: [0, 0], dt: 1, steps: 20}
bodies:
  - name: rocket
    force: [1, 0]
    shape: {circle: {radius: 0.5}}
"""

TIMEOUT = 120  # s for a batch subprocess: a loaded 2-core machine starts workers slowly


def batch(cwd: Path, *args: str | Path, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
    """`rbsim batch ARGS` in a subprocess in `cwd`."""
    return subprocess.run(
        [sys.executable, "-m", "rbsim.cli", "batch", *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def summary(folder: Path) -> list[dict[str, str]]:
    with open(folder / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def datasets(path: Path) -> dict[str, tuple]:
    """Every dataset of an HDF5 file as (dtype, shape, bytes), and every attribute, by
    path; the run's wall time left out (it is the only thing that differs run to run)."""
    out: dict[str, tuple] = {}

    def exact(value) -> tuple:
        data = np.asarray(value)
        # strings (object arrays hold pointers): by value; numbers: by their bytes
        return (
            data.dtype.str,
            data.shape,
            data.tolist() if data.dtype.kind == "O" else data.tobytes(),
        )

    with h5py.File(path, "r") as f:

        def visit(name: str, obj) -> None:
            for key, value in obj.attrs.items():
                out[f"{name}@{key}"] = exact(value)
            if isinstance(obj, h5py.Dataset) and name != "parameters/rbsim/wall_time":
                out[name] = exact(obj[()])

        f.visititems(visit)
    return out


# --vary, --samples and the plan (no cluster) ----------------------------------------------


def test_several_vary_lists_make_a_grid_with_the_first_key_slowest() -> None:
    dt = parse_vary("world.dt=[1/60, 1e-3, .5]")
    v = parse_vary("bodies.ball.velocity=[[1,0],[2,0]]")
    assert dt.values == ("1/60", "0.001", "0.5")  # read with the scene files' number rules
    assert v.values == ("[1, 0]", "[2, 0]")
    runs = expand([dt, v])
    assert [tuple(r.values()) for r in runs] == [
        ("1/60", "[1, 0]"), ("1/60", "[2, 0]"), ("0.001", "[1, 0]"),
        ("0.001", "[2, 0]"), ("0.5", "[1, 0]"), ("0.5", "[2, 0]"),
    ]  # fmt: skip


def test_samples_are_reproducible_from_the_seed_and_follow_their_distributions() -> None:
    varies = [
        parse_vary("a=uniform(-0.5, 1/4)"),
        parse_vary("b=normal(10, 2)"),
        parse_vary("c=[x, y, z]"),
    ]
    draws = expand(varies, samples=400, seed=7)
    assert draws == expand(varies, samples=400, seed=7)
    assert draws != expand(varies, samples=400, seed=8)
    a = np.array([float(d["a"]) for d in draws])
    b = np.array([float(d["b"]) for d in draws])
    assert a.min() >= -0.5 and a.max() < 0.25
    # 400 draws: the sample mean of N(10, 2) is within 4 standard errors (4 * 2/20 = 0.4)
    assert abs(b.mean() - 10) < 0.4 and 1.6 < b.std() < 2.4
    assert {d["c"] for d in draws} == {"x", "y", "z"}


@pytest.mark.parametrize(
    "raw",
    [
        "world.dt",
        "world.dt=0.01",
        "world.dt=[]",
        "world.dt=[0.01",
        "x=uniform(1)",
        "x=uniform(2,1)",
        "x=normal(0,-1)",
        "x=poisson(1,2)",
        "x=uniform(a,b)",
    ],
)
def test_a_vary_that_cannot_be_read_is_an_error_naming_it(raw: str) -> None:
    with pytest.raises(VaryError, match="--vary"):
        parse_vary(raw)


def test_distributions_need_samples_and_keys_are_varied_once() -> None:
    with pytest.raises(VaryError, match="only with --samples"):
        expand([parse_vary("world.dt=uniform(0.01,0.02)")])
    with pytest.raises(VaryError, match="more than once"):
        expand([parse_vary("world.dt=[1]"), parse_vary("world.dt=[2]")])


def test_run_id_is_a_hash_of_the_resolved_scene() -> None:
    # 1/60 and 0.016666666666666666 resolve to the same dt; 1/120 does not
    plan = plan_batch([BOUNCE], varies=[parse_vary("world.dt=[1/60, 0.016666666666666666, 1/120]")])
    ids = [s.run_id for s in plan.specs]
    assert ids[0] == ids[1] != ids[2]
    assert all(i.startswith("bounce-") and len(i) == len("bounce-") + 12 for i in ids)
    assert len(plan.runs()) == 2  # the same scene is run once
    again = plan_batch([BOUNCE], varies=[parse_vary("world.dt=[1/120]")])
    assert again.specs[0].run_id == ids[2]


def test_draws_that_resolve_alike_share_one_run_but_keep_their_rows() -> None:
    plan = plan_batch([BOUNCE], varies=[Vary("world.dt", values=("1/60",))], samples=3)
    assert len(plan.specs) == 3 and len(plan.runs()) == 1


def test_every_run_is_checked_before_any_starts(tmp_path: Path) -> None:
    with pytest.raises(BatchInvalid) as err:
        plan_batch(
            [BOUNCE, tmp_path / "missing.yaml"], varies=[parse_vary("world.dt=[0.01, fast]")]
        )
    lines = err.value.problems
    assert any(f"{BOUNCE}: --vary world.dt=fast: expected a number" in line for line in lines), (
        lines
    )
    assert any("missing.yaml:1:1: file not found" in line for line in lines), lines
    assert not any("0.01" in line for line in lines)  # the good value is not blamed


def test_invalid_vary_value_exits_3_and_runs_nothing(tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, stdout, stderr = rbsim("batch", BOUNCE, "-o", out, "--vary", "solver.substeps=[2, 0]")
    assert code == 3
    assert f"{BOUNCE}: --vary solver.substeps=0:" in stderr, stderr
    assert not out.exists()  # checked before the folder was made, let alone a run started


@pytest.mark.parametrize(
    "args",
    [
        ("--vary", "world.dt=uniform(0.01,0.02)"),
        ("--samples", "3"),
        ("--seed", "1", "--vary", "world.dt=[0.01]"),
        ("--workers", "2", "--scheduler", "tcp://127.0.0.1:1"),
    ],
)
def test_option_combinations_that_make_no_batch_are_usage_errors(
    tmp_path: Path, args: tuple[str, ...]
) -> None:
    code, _, stderr = rbsim("batch", BOUNCE, "-o", tmp_path / "out", *args)
    assert code == 2, stderr


def test_no_scheduler_at_the_address_is_said_at_once_and_leaves_no_folder(
    tmp_path: Path,
) -> None:
    # port 1 refuses: Dask's client tried again for its whole 10 s timeout, and the batch
    # left the empty folder it had made
    out = tmp_path / "out"
    started = time.monotonic()
    code, _, stderr = rbsim(
        "batch", BOUNCE, "-o", out, "--scheduler", "tcp://127.0.0.1:1", "--vary", "world.steps=[1]"
    )
    assert code == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in stderr
    assert time.monotonic() - started < 8.0  # s: a refusal, not Dask's timeout (10 s)
    assert not out.exists()


def test_summary_round_trips_and_parquet_holds_numbers(tmp_path: Path) -> None:
    rows = [
        {"run_id": "a-1", "scene": "s.yaml", "world.dt": "0.01", **dict.fromkeys(FIGURE_COLUMNS)},
        {"run_id": "a-2", "scene": "s.yaml", "world.dt": "1/60", **dict.fromkeys(FIGURE_COLUMNS)},
    ]
    rows[0].update(
        status="complete", steps=10, wall_time_s=0.1, kinetic_energy_J=1 / 3, max_overlap_m=0.0,
        max_speed_m_s=2.5, moved_most="ball", moved_most_m=1e-17,
    )  # fmt: skip
    rows[1].update(status="failed: body 'ball' became non-finite at step 3")
    paths = write_summary(rows, ["world.dt"], tmp_path)
    back = read_summary(tmp_path / "summary.csv")
    assert back["a-1"] == {k: rows[0][k] for k in FIGURE_COLUMNS}  # every digit kept
    assert back["a-2"]["status"] == rows[1]["status"] and back["a-2"]["steps"] is None
    if len(paths) > 1:  # pyarrow installed
        import pyarrow.parquet as pq

        table = pq.read_table(paths[1]).to_pydict()
        assert table["world.dt"] == [0.01, 1 / 60] and table["steps"] == [10, None]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_one_progress_line_counts_runs_failures_and_the_time_left(monkeypatch) -> None:
    monkeypatch.setattr(sys, "stderr", _Terminal())
    bar = cli._BatchProgress(enabled=True)
    bar.runs(6, 0, 20)  # six skipped as complete: they do not count towards the rate
    assert sys.stderr.getvalue() == ""  # within the first second: nothing yet
    bar.t0 -= 2.0
    bar.started = (bar.started[0] - 2.0, 6)  # two seconds later, two more runs done
    bar.runs(8, 1, 20)
    line = sys.stderr.getvalue()
    assert line.startswith("\r[") and "8/20 runs, 1 failed, eta 12 s" in line, line
    bar.finish()
    assert sys.stderr.getvalue().endswith("\n")


# on a LocalCluster ------------------------------------------------------------------------


def test_a_batch_of_one_run_says_1_run(tmp_path: Path) -> None:
    code, out, err = rbsim("batch", BOUNCE, "-o", tmp_path / "one", "--workers", "1")
    assert code == 0, err
    assert "1 run: 1 complete, 0 failed" in out, out


def test_grid_on_two_workers_equals_single_runs_bit_for_bit_and_reruns_skip(
    tmp_path: Path,
) -> None:
    out = tmp_path / "out"
    done = batch(tmp_path, BOUNCE, "-o", out, "--set", "world.duration=1", *GRID, "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert "6 runs: 6 complete, 0 failed" in done.stdout
    assert "Traceback" not in done.stderr
    rows = summary(out)
    assert len(rows) == 6
    files = sorted(out.glob("*.h5"))
    assert len(files) == 6 and not list(out.glob(".*"))  # no partial file left
    for row in rows:
        assert row["status"] == "complete"
        assert int(row["steps"]) == (60 if row["world.dt"] == "1/60" else 120)
        single = tmp_path / f"single-{row['run_id']}.h5"
        code, _, err = rbsim(
            "run", BOUNCE, "-q", "-o", single, "--set", "world.duration=1",
            "--set", f"world.dt={row['world.dt']}",
            "--set", f"bodies.1.velocity={row['bodies.1.velocity']}",
        )  # fmt: skip
        assert code == 0, err
        assert datasets(out / f"{row['run_id']}.h5") == datasets(single)
        tr = load_trajectory(single)
        assert float(row["kinetic_energy_J"]) == float(tr.observables["kinetic_energy"][-1])
        assert float(row["max_speed_m_s"]) == float(np.linalg.norm(tr.velocity, axis=2).max())
    mtimes = {p: p.stat().st_mtime_ns for p in files}
    again = batch(tmp_path, BOUNCE, "-o", out, "--set", "world.duration=1", *GRID, "--workers", "2")
    assert again.returncode == 0, again.stderr
    assert "6 runs: 6 complete (6 already), 0 failed" in again.stdout
    assert {p: p.stat().st_mtime_ns for p in files} == mtimes  # nothing ran again
    assert summary(out) == rows


def test_a_run_that_blows_up_is_recorded_as_failed_and_the_others_complete(
    tmp_path: Path,
) -> None:
    scene = tmp_path / "rocket.yaml"
    scene.write_text(ROCKET.replace("steps: 20", "steps: 50"))
    # 7.8e5 N (within the force bound) takes the rocket out of the simulated region
    force = "bodies.rocket.force=[[1,0],[7.8e+5,0],[2,0]]"
    done = batch(tmp_path, "rocket.yaml", "-o", "out", "--vary", force, "--workers", "1")
    assert done.returncode == 1, done.stderr
    assert "3 runs: 2 complete, 1 failed" in done.stdout
    rows = {r["bodies.rocket.force"]: r for r in summary(tmp_path / "out")}
    bad = rows["[780000.0, 0]"]
    assert bad["status"].startswith("failed: body 'rocket' left the simulated region")
    assert bad["status"].endswith("at step 45")
    assert int(bad["steps"]) == 44  # the last frame inside it
    assert f"{bad['run_id']}: rocket.yaml bodies.rocket.force=[780000.0, 0]: failed" in done.stderr
    assert load_trajectory(tmp_path / "out" / f"{bad['run_id']}.h5").status.startswith("failed")
    for good in ("[1, 0]", "[2, 0]"):
        assert rows[good]["status"] == "complete"
        assert is_complete(tmp_path / "out" / f"{rows[good]['run_id']}.h5")
    # the failed run is not complete, so it is tried again; the others are skipped
    again = batch(tmp_path, "rocket.yaml", "-o", "out", "--vary", force, "--workers", "1")
    assert "3 runs: 2 complete (2 already), 1 failed" in again.stdout, again.stdout


def processes_in_session(sid: int) -> list[int]:
    """Ids of the live processes still in session `sid` (the batch's workers, if
    orphaned). Zombies do not count: they have ended, and wait for init to reap them."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
                if os.getsid(int(entry.name)) == sid and state != "Z":
                    found.append(int(entry.name))
            except (OSError, IndexError):  # gone meanwhile, or not ours to see
                continue
    return found


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc to find left-over workers")
def test_ctrl_c_keeps_every_finished_run_recorded_and_stops_the_workers(tmp_path: Path) -> None:
    out = tmp_path / "out"
    offsets = ",".join(f"{0.05 * i:.2f}" for i in range(12))
    proc = subprocess.Popen(
        [sys.executable, "-m", "rbsim.cli", "batch", str(STACK), "-o", str(out),
         "--vary", f"bodies.15.position.0=[{offsets}]", "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=TAKE_CTRL_C,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + TIMEOUT
        while not list(out.glob("*.h5")):
            assert proc.poll() is None, f"the batch ended early: {proc.communicate()}"
            assert time.monotonic() < deadline, "no run finished in time"
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the batch and its workers alike
        stdout, stderr = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    rows = summary(out)
    assert len(rows) == 12
    finished = [r for r in rows if r["status"] == "complete"]
    assert 1 <= len(finished) < 12
    assert all(r["status"] in ("complete", "interrupted") for r in rows)
    for r in rows:  # a complete file for every run recorded complete, none for the others
        assert is_complete(out / f"{r['run_id']}.h5") == (r["status"] == "complete")
    assert f"interrupted: {len(finished)} of 12 runs finished" in stderr
    assert not list(out.glob(".*.part"))
    assert processes_in_session(proc.pid) == []  # every worker process ended


# on a real scheduler ----------------------------------------------------------------------


def test_batch_on_a_scheduler_completes_every_run_when_a_worker_is_killed(tmp_path: Path) -> None:
    from distributed import Client

    info = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "dask"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [
        subprocess.Popen(
            [
                *dask,
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(info),
            ],
            **quiet,
        )  # fmt: skip
    ]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() or not info.read_text().strip():
            assert procs[0].poll() is None and time.monotonic() < deadline, "no scheduler"
            time.sleep(0.05)
        time.sleep(0.1)  # the file is written at once, but let it be complete
        address = json.loads(info.read_text())["address"]
        for name in ("w1", "w2"):
            procs.append(
                subprocess.Popen(
                    [
                        *dask,
                        "worker",
                        "--scheduler-file",
                        str(info),
                        "--nthreads",
                        "1",
                        "--no-nanny",
                        "--no-dashboard",
                        "--host",
                        "127.0.0.1",
                        "--name",
                        name,
                    ],
                    **quiet,
                )  # fmt: skip
            )
        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        out = tmp_path / "out"
        offsets = ",".join(f"{0.1 * i:.1f}" for i in range(10))
        run = subprocess.Popen(
            [sys.executable, "-m", "rbsim.cli", "batch", str(STACK), "-o", str(out),
             "--set", "world.duration=5", "--vary", f"bodies.15.position.0=[{offsets}]",
             "--scheduler", address, "--retries", "0"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        procs.append(run)
        deadline = time.monotonic() + TIMEOUT
        while not list(out.glob("*.h5")):
            assert run.poll() is None, f"the batch ended early: {run.communicate()}"
            assert time.monotonic() < deadline, "no run finished in time"
            time.sleep(0.02)
        procs[1].kill()  # worker w1, in the middle of a run
        procs[1].wait()
        assert run.poll() is None and len(list(out.glob("*.h5"))) < 10  # mid-batch
        stdout, stderr = run.communicate(timeout=TIMEOUT)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()
    # --retries 0: the lost worker's run is rescheduled by Dask itself, not retried by us
    assert run.returncode == 0, stderr
    assert "10 runs: 10 complete, 0 failed" in stdout
    rows = summary(out)
    assert [r["status"] for r in rows] == ["complete"] * 10
    assert all(is_complete(out / f"{r['run_id']}.h5") for r in rows)
    assert not list(out.glob(".*"))
    fell = [r["bodies.15.position.0"] for r in rows if float(r["moved_most_m"]) > 1.0]
    assert fell and fell == [r["bodies.15.position.0"] for r in rows][len(rows) - len(fell) :]


def test_a_retry_continues_the_run_its_killed_attempt_left(tmp_path: Path) -> None:
    """A worker killed mid-run leaves `.<run-id>.part` and its checkpoint; the retry
    (run_one again, as the batch sends it) continues from there and ends with the frames
    of an uninterrupted run, bit for bit."""
    from rbsim import __version__
    from rbsim.batch import Job, run_one
    from rbsim.io.trajectory import CHECKPOINT_SUFFIX
    from rbsim.run import run_scene

    sets = ["world.duration=120"]  # 7200 steps, about 0.7 s: killed at its first checkpoints
    (spec,) = plan_batch([str(STACK)], sets, [parse_vary("bodies.15.position.0=[0.3]")]).runs()
    out = tmp_path / "out"
    out.mkdir()
    part = out / f".{spec.run_id}.part"
    attempt = textwrap.dedent(f"""
        from rbsim.batch import RunSpec
        from rbsim.run import run_scene
        fields = {(spec.run_id, spec.scene_path, spec.source, spec.overrides, spec.varied)!r}
        spec = RunSpec(*fields)
        run_scene(spec.scene(), {str(part)!r}, progress=None, signals=(),
                  overrides=spec.overrides, flush_seconds=0.05)
    """)
    proc = subprocess.Popen([sys.executable, "-c", attempt], stderr=subprocess.PIPE)
    sidecar = Path(f"{part}{CHECKPOINT_SUFFIX}")
    deadline = time.monotonic() + TIMEOUT
    while not sidecar.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the attempt wrote no checkpoint in time"
        time.sleep(0.01)
    proc.kill()  # the worker dies mid-run
    proc.wait()
    killed = load_trajectory(part)
    assert 0 < len(killed.step) < 7201  # it died in the middle

    outcome = run_one(Job(spec, str(out), __version__))  # the retry
    assert outcome.figures["status"] == "complete"
    got = load_trajectory(out / f"{spec.run_id}.h5")
    assert got.parameters["resumed"] == "1"  # continued, not started again
    fresh = tmp_path / "fresh.h5"
    run_scene(spec.scene(), fresh, progress=None, signals=(), overrides=spec.overrides)
    want = load_trajectory(fresh)
    assert len(got.step) == len(want.step)
    for key in ("position", "angle", "velocity", "angular_velocity"):
        assert np.array_equal(getattr(got, key), getattr(want, key)), key
    assert not list(out.glob(".*"))  # no part, checkpoint or lock file left


def test_figures_of_a_3d_run_and_of_a_file_with_a_subset_of_bodies(tmp_path: Path) -> None:
    """run_one (a worker's task, here in this process) on a 3D scene, and on the stack
    written with output.bodies: moving (the ground stored once): the figures are those
    of the trajectory, and the subset's overlap is the whole file's."""
    from rbsim import __version__
    from rbsim.batch import Job, run_one

    pile = ROOT / "scenes" / "3d" / "collapsing_pile.yaml"
    (spec,) = plan_batch([str(pile)], ["world.duration=0.25"]).runs()
    got = run_one(Job(spec, str(tmp_path), __version__)).figures
    tr = load_trajectory(tmp_path / f"{spec.run_id}.h5")
    assert tr.dimension == 3 and got["status"] == "complete"
    assert got["max_overlap_m"] is None  # no 3D penetration ruler yet
    assert got["max_speed_m_s"] == float(np.linalg.norm(tr.velocity, axis=2).max())
    moved = np.linalg.norm(tr.position[-1] - tr.position[0], axis=1)
    assert got["moved_most"] == tr.bodies.name[int(np.argmax(moved))]
    assert got["kinetic_energy_J"] == float(tr.observables["kinetic_energy"][-1])

    vary = [parse_vary("bodies.15.position.0=[0.3]")]
    rows = {}
    for bodies in ("all", "moving"):
        sets = ["world.duration=1", f"output.bodies={bodies}"]
        (spec,) = plan_batch([str(STACK)], sets, vary).runs()
        rows[bodies] = run_one(Job(spec, str(tmp_path), __version__)).figures
    assert load_trajectory(tmp_path / f"{spec.run_id}.h5").fixed is not None  # ground once
    assert rows["moving"]["max_overlap_m"] > 0  # the bottom box rests on the ground
    for key in ("max_overlap_m", "max_speed_m_s", "moved_most", "moved_most_m", "steps"):
        assert rows["moving"][key] == rows["all"][key], key


# rbsim sweep on workers -------------------------------------------------------------------

PROJECTILE = """\
version: 1
name: throw
world: {gravity: [0, -9.81], dt: 1/60, duration: 1}
bodies:
  - {name: ball, position: [0, 10], velocity: [3, 10], shape: {circle: {radius: 0.25}}}
reference: {kind: projectile}
"""


def test_sweep_on_two_workers_measures_the_same_errors(tmp_path: Path) -> None:
    scene = tmp_path / "throw.yaml"
    scene.write_text(textwrap.dedent(PROJECTILE))
    grid = (
        "--dt", "1/30,1/60", "--substeps", "1,2", "--iterations", "1", "--rotation", "normalize",
        "--pymunk-iterations", "10", "--no-plot", "--repeats", "1",
    )  # fmt: skip
    code, _, err = rbsim("sweep", scene, "-o", tmp_path / "serial", *grid)
    assert code == 0, err
    done = subprocess.run(
        [sys.executable, "-m", "rbsim.cli", "sweep", str(scene), "-o", "pool", *grid,
         "--workers", "2"],
        cwd=tmp_path, capture_output=True, text=True, timeout=TIMEOUT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr

    def errors(folder: str) -> list[tuple[str, str, str]]:
        with open(tmp_path / folder / "throw.csv", newline="") as f:
            return [(r["family"], r["dt_s"], r["error_m"]) for r in csv.DictReader(f)]

    assert errors("pool") == errors("serial")  # the same runs, so the same digits
    assert len(errors("pool")) == 6


def run_script(script: str) -> str:
    """The stdout of `script` run by this Python in a process of its own (a Ctrl-C sent
    to pytest's own process would end the session) that takes Ctrl-C; fails on a non-zero
    exit."""
    done = python_child(script)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_ctrl_c_while_the_fork_server_starts_is_raised_once_it_has_started() -> None:
    # it was ignored while the server started (the server must ignore it, and inherited
    # that): a Ctrl-C in those tenths of a second was lost and the batch ran on
    out = run_script(
        """
        import os, signal
        from multiprocessing import forkserver
        from rbsim.forkserver import start_fork_server
        forkserver.ensure_running = lambda: os.kill(os.getpid(), signal.SIGINT)
        seed = os.environ.get("PYTHONHASHSEED")
        try:
            start_fork_server()
            print("went on")
        except KeyboardInterrupt:
            print("raised", os.environ.get("PYTHONHASHSEED") == seed)
        """
    )
    assert out.split() == ["raised", "True"]


def test_ctrl_c_while_a_local_cluster_starts_is_raised_once_it_started_and_closes_it() -> None:
    # a batch into a folder with trajectories starts its cluster in the main thread;
    # a Ctrl-C meanwhile was lost as above (and one let through would leave it half made)
    out = run_script(
        """
        import os, signal
        import distributed
        closed = []
        class Cluster:
            def __init__(self, **settings):
                os.kill(os.getpid(), signal.SIGINT)
                print("started")
            def close(self):
                closed.append("cluster")
        class Client:
            dashboard_link = None
            def __init__(self, cluster, set_as_default):
                pass
            def close(self):
                closed.append("client")
        distributed.LocalCluster, distributed.Client = Cluster, Client
        from rbsim.batch import _start_local
        try:
            _start_local(1, forked=True)
            print("went on")
        except KeyboardInterrupt:
            print("raised", *closed)
        """
    )
    assert out.split() == ["started", "raised", "client", "cluster"]


def test_local_workers_start_with_dasks_environment_from_the_early_fork_server() -> None:
    # rbsim batch starts the fork server before it imports Dask (rbsim.forkserver); the
    # workers forked from it must still run as Dask runs a worker it spawns: one BLAS
    # thread (set before the server imported numpy: Dask's own setting of the variable,
    # in the worker after the fork, comes too late for the library) and a fixed hash seed
    script = textwrap.dedent(
        """
        import os, signal, sys
        def sigint():  # ignored, blocked
            held = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, ())
            return f"{signal.getsignal(signal.SIGINT) == signal.SIG_IGN}/{held}"
        if __name__ == "__main__":
            from rbsim.forkserver import start_fork_server
            assert start_fork_server()
            from rbsim.batch import starting_cluster
            with starting_cluster(None, 1) as start:
                client = start.get().client
                print(client.submit(blas_threads).result())
                print(client.submit(lambda: os.environ.get("PYTHONHASHSEED")).result())
                print(client.submit(sigint).result(), sigint())
        """
    )
    keep = ("PYTHONHASHSEED", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")
    env = {k: v for k, v in os.environ.items() if k not in keep}
    done = python_child(BLAS_THREADS + script, env)
    assert done.returncode == 0, done.stderr
    threads, seed, sigint = done.stdout.split("\n")[:3]
    assert sigint == "True/False False/False"  # the worker ignores Ctrl-C, the batch not
    if threads == "None":
        pytest.skip("numpy's BLAS here is not OpenBLAS")
    assert (threads, seed) == ("1", "6640")
