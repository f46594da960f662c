"""The `rbsim` command line (cli.md): run, validate, info, schema, exit codes.

Most tests call the click commands in this process (CliRunner); the interruption tests
run `python -m rbsim.cli` in a subprocess and send it a real signal.
"""

from __future__ import annotations

import errno
import io
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from rbsim import cli
from rbsim.__main__ import ONE_THREAD
from rbsim.io.trajectory import load_trajectory
from rbsim.scene import load_scene_text, scene_to_dict
from rbsim.scene.schema import json_schema

from .conftest import BLAS_THREADS, python_child, rbsim, started_rbsim

REPO = Path(__file__).resolve().parents[1]
SCENES = sorted((REPO / "scenes").glob("*.yaml"))
MODELINE = "# yaml-language-server: $schema=../rbsim-schema.json"

# A ball thrown upwards, no contacts: the cheapest scene to run.
BALL = """\
version: 1
name: ball
world: {dt: 0.01, steps: 10}
bodies:
  - name: ball
    position: [0, 10]
    velocity: [3, 10]
    shape: {circle: {radius: 0.5}}
"""

# Boxes resting on a ground line: exercises every contact stage.
CONTACT = """\
version: 1
name: contact
world: {dt: 1/60, steps: 5}
bodies:
  - name: ground
    type: static
    shape: {segment: {a: [-5, 0], b: [5, 0]}}
  - stack: {count: 2, size: [1, 1], origin: [0, 0.5]}
"""

# 211 bodies for a million steps: minutes of work, still running when signalled.
LONG = """\
version: 1
name: long
world: {dt: 1/60, steps: 1000000}
output: {every: 7}
bodies:
  - name: ground
    type: static
    shape: {segment: {a: [-40, 0], b: [40, 0]}}
  - pyramid: {base: 20, size: [1, 1], origin: [0, 0.5]}
"""

# A constant force of 7.8e5 N on a 0.785 kg disc (9.9e5 m/s², within the bound of 1e6;
# dt = 1 s): x = a (n² + n/4) / 2 after n steps of 4 substeps passes the engine's region
# (1e9 m) at step 45. Every value is valid.
BLOWUP = """\
version: 1
name: blowup
world: {gravity: [0, 0], dt: 1, steps: 50}
bodies:
  - name: rocket
    force: [7.8e+5, 0]
    shape: {circle: {radius: 0.5}}
"""

SUMMARY = re.compile(
    r"^(\d+) steps?, (\d+) bod(?:y|ies), (\d+) frames? in \d+\.\d\d s "
    r"\(set-up \d+\.\d\d s, stepping \d+\.\d\d s at [\d,]+ steps/s\) -> (.+)$"
)


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


# run --------------------------------------------------------------------------------------


def test_run_writes_the_trajectory_and_prints_the_summary_line(tmp_path: Path) -> None:
    out = tmp_path / "sub" / "ball.h5"
    code, stdout, stderr = rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", out)
    assert code == 0, stderr
    assert stderr == ""  # stderr is not a terminal: no progress bar
    match = SUMMARY.match(stdout.strip())
    assert match, stdout
    assert match.groups() == ("10", "1", "11", str(out))
    tr = load_trajectory(out)
    assert tr.status == "complete"
    assert tr.step.tolist() == list(range(11))
    assert tr.bodies.name == ["ball"]


@pytest.mark.parametrize("full", ["before_the_file", "before_the_first_frame"])
def test_a_full_disk_says_what_was_kept_and_marks_the_file_failed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, full: str
) -> None:
    from rbsim.io.trajectory import TrajectoryWriter

    def no_space(*_args: object, **_kwargs: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    # the file cannot be created at all, or is laid out but no frame can be written
    method = "_layout" if full == "before_the_file" else "_write_block"
    monkeypatch.setattr(TrajectoryWriter, method, no_space)
    out = tmp_path / "ball.h5"
    code, _out, stderr = rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", out, "-q")
    assert code == 1 and "Traceback" not in stderr
    assert f"cannot write {out}: No space left on device" in stderr
    assert "nothing was kept" in stderr, stderr
    monkeypatch.undo()
    if full == "before_the_file":
        assert not out.exists()
    else:
        tr = load_trajectory(out)
        assert tr.status.startswith("failed") and len(tr.step) == 0
        assert "holds no frame (status failed)" in stderr


def test_one_step_one_frame_and_info_words(tmp_path: Path) -> None:
    out = tmp_path / "one.h5"
    scene = write(tmp_path, "one.yaml", BALL.replace("steps: 10", "steps: 1"))
    code, stdout, stderr = rbsim("run", scene, "-o", out)
    assert code == 0 and stdout.startswith("1 step, 1 body, 2 frames in "), stderr
    code, stdout, _err = rbsim("render", out, "-o", tmp_path / "one.gif", "--end", "0")
    assert code == 0 and stdout.startswith("1 frame, "), stdout
    code, stdout, _err = rbsim("info", out)
    assert code == 0 and "None" not in stdout
    assert re.search(r"^\s+threads\s+not set \(the cores the process may run on", stdout, re.M)
    # the file's wall time is the whole run's, set-up included: said so
    assert re.search(r"^\s+wall time\s+[\d.]+ s \(the whole run, set-up included", stdout, re.M)


def test_quiet_run_prints_nothing(tmp_path: Path) -> None:
    out = tmp_path / "ball.h5"
    code, stdout, stderr = rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", out, "--quiet")
    assert (code, stdout, stderr) == (0, "", "")
    assert len(load_trajectory(out).step) == 11


def test_default_output_is_out_slash_scene_name(tmp_path: Path, monkeypatch) -> None:
    scene = write(tmp_path, "file_stem.yaml", BALL)
    monkeypatch.chdir(tmp_path)
    code, stdout, stderr = rbsim("run", scene)
    assert code == 0, stderr
    assert stdout.strip().endswith(f"-> {Path('out', 'ball.h5')}")
    assert load_trajectory(tmp_path / "out" / "ball.h5").status == "complete"
    # without `name:` the scene is named after its file
    unnamed = write(tmp_path, "file_stem.yaml", BALL.replace("name: ball\nworld", "world"))
    assert rbsim("run", unnamed, "-q")[0] == 0
    assert (tmp_path / "out" / "file_stem.h5").is_file()


def test_set_world_dt_and_steps(tmp_path: Path) -> None:
    out = tmp_path / "ball.h5"
    scene = write(tmp_path, "ball.yaml", BALL.replace("steps: 10", "duration: 5"))
    args = ("--set", "world.dt=0.005", "--set", "world.steps=10")
    code, _, stderr = rbsim("run", scene, "-o", out, "-q", *args)
    assert code == 0, stderr
    tr = load_trajectory(out)
    assert tr.step.tolist() == list(range(11))
    np.testing.assert_allclose(np.diff(tr.time), 0.005, rtol=1e-12)


@pytest.mark.parametrize(
    "override",
    ["world.dt=abc", "world.dt", "solver.substep=8", "bodies.nobody.position=[0, 0]"],
)
def test_bad_set_exits_3_and_names_the_set(tmp_path: Path, override: str) -> None:
    out = tmp_path / "ball.h5"
    code, stdout, stderr = rbsim(
        "run", write(tmp_path, "b.yaml", BALL), "-o", out, "--set", override
    )
    assert code == 3
    assert "--set" in stderr
    assert stdout == ""
    assert not out.exists()


def test_output_every_writes_every_kth_step_and_the_last(tmp_path: Path) -> None:
    out = tmp_path / "ball.h5"
    scene = write(tmp_path, "ball.yaml", BALL + "output: {every: 3}\n")
    code, stdout, stderr = rbsim("run", scene, "-o", out)
    assert code == 0, stderr
    assert SUMMARY.match(stdout.strip()).groups()[:3] == ("10", "1", "5")
    tr = load_trajectory(out)
    assert tr.step.tolist() == [0, 3, 6, 9, 10]
    np.testing.assert_allclose(tr.time, [0, 0.03, 0.06, 0.09, 0.1])


def test_output_every_past_the_last_step_writes_the_first_and_last(tmp_path: Path) -> None:
    # 10⁴⁰⁰ is beyond the engine's integers: it must mean "step 0 and the last" (fuzz 938)
    out = tmp_path / "ball.h5"
    scene = write(tmp_path, "ball.yaml", BALL + "output: {every: 1" + "0" * 400 + "}\n")
    code, stdout, stderr = rbsim("run", scene, "-o", out)
    assert code == 0, stderr
    assert load_trajectory(out).step.tolist() == [0, 10]


@pytest.mark.parametrize("scene", SCENES, ids=[p.stem for p in SCENES])
def test_every_shipped_scene_runs(tmp_path: Path, scene: Path) -> None:
    out = tmp_path / f"{scene.stem}.h5"
    code, _, stderr = rbsim("run", scene, "--set", "world.steps=5", "-o", out, "-q")
    assert code == 0, stderr
    assert load_trajectory(out).step.tolist() == [0, 1, 2, 3, 4, 5]


# failures -----------------------------------------------------------------------------------


def test_body_leaving_the_region_exits_1_naming_body_and_step(tmp_path: Path) -> None:
    out = tmp_path / "blowup.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no numpy overflow warnings either
        code, stdout, stderr = rbsim("run", write(tmp_path, "blowup.yaml", BLOWUP), "-o", out)
    assert code == 1
    assert stdout == ""
    assert "body 'rocket' left the simulated region" in stderr and "step 45" in stderr, stderr
    tr = load_trajectory(out)
    assert tr.status.startswith("failed")
    assert "'rocket'" in tr.status and "step 45" in tr.status
    assert tr.step.tolist() == list(range(45))  # every frame before the failure
    assert np.isfinite(tr.position).all() and np.isfinite(tr.velocity).all()
    assert np.abs(tr.position).max() <= 1e9


@pytest.mark.parametrize("where", ["directory", "file_as_folder", "missing_proc_folder"])
def test_unwritable_output_exits_nonzero_with_a_message(tmp_path: Path, where: str) -> None:
    if where == "directory":
        out, expected = tmp_path, "is a directory"
    elif where == "file_as_folder":
        (tmp_path / "plain").write_text("")
        out, expected = tmp_path / "plain" / "x.h5", "is not a folder"
    else:
        if not Path("/proc/self").is_dir():
            pytest.skip("no /proc")
        out, expected = Path("/proc/nope/x.h5"), "No such file or directory"
    code, stdout, stderr = rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", out)
    assert code != 0
    assert stdout == ""
    assert str(out) in stderr and expected in stderr, stderr


def test_missing_scene_exits_3(tmp_path: Path) -> None:
    code, _, stderr = rbsim("run", tmp_path / "nope.yaml")
    assert code == 3
    assert "nope.yaml:1:1: file not found" in stderr


# interruption (real signals, in a subprocess) -------------------------------------------------


def frames_on_disk(path: Path) -> int:
    """Frames the running writer has flushed so far (0 if it cannot be read yet). Opens
    without a file lock: a locking reader could stop the writer from reopening it."""
    try:
        with h5py.File(path, "r", swmr=True, locking=False) as f:
            return int(f["particles/bodies/position/step"].shape[0])
    except (OSError, KeyError, ValueError):
        return 0


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_exits_130_and_keeps_a_valid_trajectory(
    tmp_path: Path, signum: signal.Signals
) -> None:
    out = tmp_path / "long.h5"
    scene = write(tmp_path, "long.yaml", LONG)
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}  # SIGABRT dumps the Python stack
    with started_rbsim("run", scene, "-o", out, env=env) as proc:
        started = time.monotonic()
        deadline = started + 60.0  # a loaded machine may start the process slowly
        # frames on disk, and past the first second (when a terminal would get a progress bar)
        while frames_on_disk(out) < 2 or time.monotonic() - started < 1.5:
            assert proc.poll() is None, f"rbsim ended early: {proc.communicate()}"
            assert time.monotonic() < deadline, "no frames on disk after 60 s"
            time.sleep(0.1)
        proc.send_signal(signum)
        try:
            stdout, stderr = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            pytest.fail(f"still running 60 s after {signum.name}:\n{proc.communicate()[1][-3000:]}")
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert "\r" not in stderr  # no progress bar: stderr is not a terminal
    assert stdout == ""
    tr = load_trajectory(out)
    assert tr.status == "interrupted"
    frames = len(tr.step)
    assert frames >= 2
    assert f"interrupted: {frames} frames kept in {out}" in stderr
    assert tr.step.tolist() == [7 * i for i in range(frames)]
    assert np.isfinite(tr.position).all() and np.isfinite(tr.angular_velocity).all()


@pytest.mark.parametrize("command", ["run", "batch"])
def test_ctrl_c_at_any_moment_of_the_start_exits_130_without_a_traceback(
    tmp_path: Path, command: str
) -> None:
    """Ctrl-C in a run's or batch's first half second once ended in click's "Aborted!"
    and exit 1 (before the command installed its handling), or in a KeyboardInterrupt
    traceback (while Python imported the command line)."""
    scene = write(tmp_path, "long.yaml", LONG)
    for k, delay in enumerate((0.05, 0.1, 0.15, 0.18, 0.2, 0.22, 0.25, 0.3, 0.45, 0.7)):
        out = tmp_path / f"{command}{k}"
        args = ("-o", out) if command == "batch" else ("-o", f"{out}.h5")
        with started_rbsim(command, scene, *args, "-q") as proc:
            time.sleep(delay)
            proc.send_signal(signal.SIGINT)
            _stdout, stderr = proc.communicate(timeout=60)
        if proc.returncode == -signal.SIGINT and not stderr:
            continue  # before the interpreter set its handler: the default action, silent
        assert proc.returncode == 130, f"at {delay} s: {stderr}"
        assert "interrupted" in stderr and "Traceback" not in stderr, f"at {delay} s: {stderr}"
        assert "Aborted" not in stderr, f"at {delay} s: {stderr}"


def test_what_fails_to_close_after_a_ctrl_c_is_not_reported() -> None:
    # Ctrl-C 0.22 s into a run left an h5py identifier half-made; it failed to close as
    # the process ended, and two tracebacks followed "interrupted" (exit 130 all the same).
    # This child leaves an object whose closing fails at exit, then is interrupted
    script = textwrap.dedent(
        """
        import os, signal
        import rbsim.cli
        class Half:
            def __del__(self):
                raise RuntimeError("Can't decrement id ref count")
        kept = []
        def main():
            kept.append(Half())
            os.kill(os.getpid(), signal.SIGINT)
        rbsim.cli.main = main
        from rbsim.__main__ import entry
        entry()
        """
    )
    done = python_child(script)
    assert (done.returncode, done.stderr) == (130, "interrupted before the command started\n")


def test_ctrl_c_that_breaks_an_import_exits_130_without_a_traceback() -> None:
    # Ctrl-C while h5py's compiled modules were imported (0.22 s into a run, here) came
    # out as their ImportError ("Failed to import 'zlib.decompress' - cannot initialise
    # module strings"): a traceback and exit 1. This child breaks an import the same way
    script = textwrap.dedent(
        """
        import os, signal
        import rbsim.cli
        def main():
            try:
                os.kill(os.getpid(), signal.SIGINT)
            except KeyboardInterrupt:
                raise ImportError("Failed to import 'zlib.decompress'") from None
        rbsim.cli.main = main
        from rbsim.__main__ import entry
        entry()
        """
    )
    done = python_child(script)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")


@pytest.mark.parametrize("command", ["run", "batch"])
def test_ctrl_c_lost_where_it_landed_still_stops_the_command(tmp_path: Path, command: str) -> None:
    # a Ctrl-C that lands in a weakref callback or a __del__ (one of importlib's module
    # locks, while a batch imported Dask, on CI) is reported as "Exception ignored", with
    # a traceback, and dropped: the batch ran on. This child drops one so (it goes on to
    # print), then runs the command
    scene = write(tmp_path, "ball.yaml", BALL)
    out = tmp_path / ("ball.h5" if command == "run" else "out")
    script = textwrap.dedent(
        f"""
        import os, signal, sys
        from rbsim import ctrlc
        ctrlc.install()
        class Drop:
            def __del__(self):
                os.kill(os.getpid(), signal.SIGINT)
        Drop()
        print("went on", flush=True)
        sys.argv = ["rbsim", {command!r}, {str(scene)!r}, "-o", {str(out)!r}, "-q"]
        from rbsim.cli import main
        main()
        """
    )
    done = python_child(script)
    assert done.stdout == "went on\n"  # dropped where it landed
    assert done.returncode == 130, done.stderr
    assert "interrupted" in done.stderr
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr


# info, validate, schema ---------------------------------------------------------------------


@pytest.mark.parametrize("chosen", [None, "2"])
def test_a_command_runs_numpys_blas_on_one_thread_unless_the_user_chose(chosen: str | None) -> None:
    # OpenBLAS's idle threads spin on the other cores after each call (0.15 s of CPU in
    # every command's start); a user's OPENBLAS_NUM_THREADS is kept
    script = """
        import sys
        from rbsim.__main__ import entry
        sys.argv = ["rbsim", "schema"]
        try:
            entry()
        except SystemExit:
            pass
        print(blas_threads(), file=sys.stderr)
        """
    env = {k: v for k, v in os.environ.items() if k not in ONE_THREAD}
    if chosen:
        env["OPENBLAS_NUM_THREADS"] = chosen
    done = python_child(BLAS_THREADS + textwrap.dedent(script), env)
    assert done.returncode == 0, done.stderr
    threads = done.stderr.split()[-1]
    if threads == "None":
        pytest.skip("numpy's BLAS here is not OpenBLAS")
    if chosen and os.cpu_count() < int(chosen):
        pytest.skip("fewer cores than the threads chosen: OpenBLAS takes the cores")
    assert threads == (chosen or "1")


def test_info_prints_engine_bodies_and_frames(tmp_path: Path) -> None:
    out = tmp_path / "ball.h5"
    assert rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", out, "-q")[0] == 0
    code, stdout, stderr = rbsim("info", out)
    assert code == 0, stderr
    assert re.search(r"^\s+engine\s+rbsim\b", stdout, re.M)
    assert re.search(r"^\s+status\s+complete$", stdout, re.M)
    assert re.search(r"^\s+bodies\s+1 \(1 dynamic\)$", stdout, re.M)
    assert re.search(r"^\s+frames\s+11 \(steps 0\.\.10,", stdout, re.M)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (b"hello\n", "not an HDF5 file"),
        (b"", "not an HDF5 file"),
        (None, "not an rbsim trajectory"),
    ],
    ids=["text", "empty", "other_hdf5"],
)
def test_info_on_other_files_fails_with_a_message(
    tmp_path: Path, content: bytes | None, expected: str
) -> None:
    path = tmp_path / "x.h5"
    if content is None:
        h5py.File(path, "w").close()
    else:
        path.write_bytes(content)
    code, stdout, stderr = rbsim("info", path)
    assert code == 1
    assert stdout == ""
    assert stderr.startswith(f"error: {path}: {expected}"), stderr


def test_info_render_and_plot_word_an_unreadable_file_alike(tmp_path: Path) -> None:
    other = tmp_path / "plain.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.arange(3)
    good = tmp_path / "ball.h5"
    assert rbsim("run", write(tmp_path, "ball.yaml", BALL), "-o", good, "-q")[0] == 0
    cut = tmp_path / "cut.h5"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    for path, what in ((other, "not an rbsim trajectory"), (cut, "truncated")):
        said = set()
        for command in (("info",), ("render", "-o", tmp_path / "x.gif"), ("plot",)):
            code, _out, err = rbsim(*command[:1], path, *command[1:])
            assert code == 1 and "Traceback" not in err, err
            assert err.startswith(f"error: {path}: ") and what in err, err
            assert err.count(str(path)) == 1 and "Unable to" not in err and "Error" not in err
            said.add(err)
        assert len(said) == 1, said  # one wording for all three


def test_validate_prints_ok_or_the_resolved_scene(tmp_path: Path) -> None:
    scene = write(tmp_path, "ball.yaml", BALL)
    code, stdout, _ = rbsim("validate", scene)
    assert (code, stdout) == (0, f"{scene}: ok (1 body, 10 steps of 0.01 s)\n")
    code, stdout, stderr = rbsim("validate", scene, "--resolved", "--set", "world.dt=1/50")
    assert code == 0, stderr
    resolved = yaml.safe_load(stdout)
    assert resolved["world"]["dt"] == 0.02
    assert resolved["world"]["steps"] == 10
    # the resolved scene is itself a scene, and resolves to the same thing
    assert scene_to_dict(load_scene_text(stdout, "resolved.yaml")) == resolved


def test_a_duration_rounded_to_whole_steps_is_warned_of(tmp_path: Path) -> None:
    scene = write(tmp_path, "ball.yaml", BALL)
    code, stdout, stderr = rbsim("validate", scene, "--set", "world.duration=1e-12")
    assert code == 0 and "1 step of 0.01 s" in stdout
    assert f"{scene}: --set world.duration: warning: " in stderr and "rounded to 1 step" in stderr
    # a whole number of steps but for round-off in duration / dt: nothing to say
    code, _out, stderr = rbsim(
        "validate", scene, "--set", "world.dt=1/60", "--set", "world.duration=1"
    )
    assert (code, stderr) == (0, "")
    text = BALL.replace("steps: 10", "duration: 0.025")
    out = tmp_path / "ball.h5"
    code, stdout, stderr = rbsim("run", write(tmp_path, "b.yaml", text), "-o", out, "-q")
    assert code == 0 and "Traceback" not in stderr
    assert "b.yaml:3:" in stderr and "world.duration" in stderr and "rounded to 2 steps" in stderr
    assert len(load_trajectory(out).step) == 3


def test_validate_invalid_scene_exits_3(tmp_path: Path) -> None:
    scene = write(tmp_path, "bad.yaml", BALL.replace("radius: 0.5", "radius: -1"))
    code, _, stderr = rbsim("validate", scene)
    assert code == 3
    assert f"{scene}:8:" in stderr and "radius" in stderr


def test_schema_prints_the_json_schema() -> None:
    code, stdout, _ = rbsim("schema")
    assert code == 0
    assert json.loads(stdout) == json.loads(json.dumps(json_schema()))


def test_committed_schema_file_is_up_to_date() -> None:
    committed = json.loads((REPO / "rbsim-schema.json").read_text())
    assert committed == json.loads(json.dumps(json_schema())), (
        "rbsim-schema.json is stale: regenerate it with `rbsim schema > rbsim-schema.json`"
    )


def test_the_format_reference_lists_every_key_as_validate_knows_them() -> None:
    from rbsim.tools import formatdoc

    text = formatdoc.FORMAT_DOC.read_text(encoding="utf-8")
    assert formatdoc.current(text) == text, (
        "docs/format.md is stale: python -m rbsim.tools.formatdoc"
    )
    for key in (
        "`world.dt`",
        "`bodies[i].shapes[j].polygon.vertices`",
        "`bodies[i].rotation.axis`",
    ):
        assert key in text
    assert formatdoc.main(["--check"]) == 0


def test_no_file_of_the_project_points_outside_it() -> None:
    # the README and cli.md sent a user to the shared folder's design file for the scene
    # format and the trajectory layout, a file no clone of the repository has:
    # docs/format.md holds them now
    outside = ("../" + "shared", "DESIGN" + ".md")  # (not written whole: this file is read)
    tracked = subprocess.run(
        ["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    for name in tracked:
        if name.endswith((".md", ".py", ".cpp", ".hpp", ".yaml", ".toml")) or name == "Makefile":
            text = (REPO / name).read_text(encoding="utf-8", errors="replace")
            assert not any(s in text for s in outside), name


@pytest.mark.parametrize("scene", SCENES, ids=[p.stem for p in SCENES])
def test_scene_files_name_the_schema_on_their_first_line(scene: Path) -> None:
    assert scene.read_text().splitlines()[0] == MODELINE


# progress bar -----------------------------------------------------------------------------


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal_and_after_one_second(monkeypatch) -> None:
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    off = cli._Progress(enabled=True)
    off.t0 -= 5.0
    off(10, 100)
    off.finish()
    assert sys.stderr.getvalue() == ""

    monkeypatch.setattr(sys, "stderr", _Terminal())
    bar = cli._Progress(enabled=True)
    bar(10, 100)  # within the first second: nothing yet
    assert sys.stderr.getvalue() == ""
    bar.t0 -= 2.0
    bar(50, 100)
    assert sys.stderr.getvalue().startswith("\r[") and "50/100 steps" in sys.stderr.getvalue()
    bar.finish()
    assert sys.stderr.getvalue().endswith("\n")

    quiet = cli._Progress(enabled=False)
    quiet.t0 -= 5.0
    quiet(10, 100)
    assert sys.stderr.getvalue().count("\r") == 1


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_scene_with_many_errors_lists_the_first_20_and_counts_the_rest(tmp_path, command):
    """A 20,000-body scene made 3D by --set printed its 60,000 problems; validate and run
    list at most cli.MAX_LISTED (batch's cap) and say how many more there are."""
    from rbsim.batch import MAX_LISTED

    bodies = "".join(
        f"  - {{name: b{i}, position: [{i}, 1], shape: {{box: {{size: [0.5, 0.5]}}}}}}\n"
        for i in range(30)
    )
    path = tmp_path / "many.yaml"
    path.write_text(f"version: 1\nworld: {{steps: 1}}\nbodies:\n{bodies}")
    out = ("-o", tmp_path / "x.h5") if command == "run" else ()
    code, _, err = rbsim(command, path, "--set", "world.dimension=3", *out)
    lines = err.splitlines()
    assert code == 3 and cli.MAX_LISTED == MAX_LISTED == 20
    assert len(lines) == 21 and lines[-1] == "... and 40 more problems"  # 2 a body
    assert all(line.startswith(f"{path}:") for line in lines[:20])
    code, _, err = rbsim(command, path, "--set", "bodies.0.velocity=[0,1,0]", *out)
    assert code == 3 and "more problem" not in err  # only one


def _as_reader_without_permission(args: list[str], path: Path) -> tuple[int, str]:
    """Run `rbsim ARGS` where `path` (chmod 000) cannot be read: (exit code, stderr). Root
    reads any file, so as root the command runs as nobody (setpriv); skipped without it."""
    import shutil

    from .conftest import PYTHON

    path.chmod(0o000)
    if os.geteuid() != 0:
        code, _, err = rbsim(*args)
        return code, err
    if shutil.which("setpriv") is None:
        pytest.skip("root reads any file, and setpriv is not there to run as nobody")
    nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    done = subprocess.run(
        [*nobody, *PYTHON, "-m", "rbsim", *args], capture_output=True, text=True, timeout=120
    )
    return done.returncode, done.stderr


@pytest.mark.parametrize("command", ["validate", "run", "sweep", "compare", "batch"])
def test_an_unreadable_scene_is_reported_at_its_line_1_like_a_missing_one(command):
    """click's Path said 'File ... is not readable.' (exit 2) where a missing scene is
    'missing.yaml:1:1: file not found' (exit 3): both are now the validator's."""
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="rbsim-unreadable-"))  # not under root's 0700 tmp
    try:
        folder.chmod(0o755)
        scene = folder / "scene.yaml"
        scene.write_text(BALL)
        code, err = _as_reader_without_permission([command, str(scene)], scene)
        assert code == 3 and err.strip() == f"{scene}:1:1: permission denied", err
        code, _, err = rbsim(command, folder / "missing.yaml")
        assert code == 3 and err.strip() == f"{folder / 'missing.yaml'}:1:1: file not found"
    finally:
        scene.unlink(missing_ok=True)
        folder.rmdir()


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["run", "SCENE", "-o", ""], "'-o' / '--output'"),
        (["run", "--resume", ""], "'--resume'"),
        (["compare", "SCENE", "-o", ""], "'-o' / '--output'"),
        (["sweep", "SCENE", "-o", ""], "'-o' / '--output'"),
        (["batch", "SCENE", "-o", ""], "'-o' / '--output'"),
        (["render", "OUT", "-o", ""], "'-o' / '--output'"),
    ],
)
def test_an_empty_output_path_is_a_usage_error(tmp_path, args, option, monkeypatch):
    """-o "" was the current folder: 'cannot write .: not a regular file', exit 1 (and
    compare, sweep and batch wrote into it: the test runs in tmp_path)."""
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "ball.yaml"
    scene.write_text(BALL)
    out = tmp_path / "out.h5"
    out.write_bytes(b"")
    args = [str(scene) if a == "SCENE" else str(out) if a == "OUT" else a for a in args]
    code, _, err = rbsim(*args)
    assert code == 2 and f"Invalid value for {option}: the path is empty" in err


def test_a_scene_name_too_long_for_a_file_name_is_shortened_for_the_default_output(
    tmp_path, monkeypatch
):
    """A 300-character `name:` validated, and the run failed with exit 1, 'File name too
    long' (out/<name>.h5): the default file takes the name's first bytes and 12 hex
    digits of its SHA-256, within NAME_BYTES_MAX bytes (room for the sidecars' suffixes)."""
    from rbsim.run import NAME_BYTES_MAX, file_stem

    name = "n" * 150 + "é" * 75  # 300 bytes of UTF-8, cut inside no character
    path = tmp_path / "long.yaml"
    path.write_text(BALL.replace("name: ball\n", f"name: {name}\n", 1), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    code, out, err = rbsim("run", path)
    assert code == 0, err
    (written,) = (tmp_path / "out").iterdir()
    stem = written.name.removesuffix(".h5")
    assert stem == file_stem(name) and len(stem.encode()) <= NAME_BYTES_MAX
    assert stem.startswith("n" * 150 + "é") and re.fullmatch(r".*-[0-9a-f]{12}", stem)
    assert str(written.relative_to(tmp_path)) in out
    assert file_stem(name[:-1]) != stem and file_stem("ball") == "ball"
