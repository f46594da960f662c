"""Trajectory output as a user meets it: frames written in blocks, files that survive a
kill at any moment and resume bit for bit, and the output options (precision,
compression, a subset of bodies).

Kills are real (SIGKILL to an `rbsim run` subprocess) at seeded random moments; every
file left must open with plain h5py and hold a prefix of an uninterrupted run's frames.
"""

from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from rbsim.io.trajectory import (
    BLOCK_BYTES,
    BLOCK_MAX_FRAMES,
    CHECKPOINT_SUFFIX,
    OBSERVABLES,
    STOP_COPY_BYTES,
    TRAJECTORY_ID,
    BodyTable,
    TrajectoryWriter,
    load_trajectory,
    summarize,
    write_checkpoint,
)
from rbsim.run import RunInterrupted, frame_steps, resume_run, run_scene

from .conftest import PYTHON, rbsim, scene_from

SERIES = ("step", "time", "position", "orientation", "angle", "velocity", "angular_velocity")

# Large frames (1,600 bodies, 100 kB a frame) so that kills land inside block writes as
# well as between them; a pile that collapses onto a ramp, so that contacts (and the
# warm-start cache a checkpoint must hold) change all the time.
BIG = """\
version: 1
name: big
world: {gravity: [0, -10], dt: 1/60, steps: STEPS}
materials:
  m: {density: 1.0, friction: 0.5, restitution: 0.1}
bodies:
  - name: floor
    type: static
    material: m
    shape: {segment: {a: [-60, 0], b: [60, 0]}}
  - name: ramp
    type: static
    material: m
    shape: {segment: {a: [-60, 30], b: [0, 2]}}
  - grid: {count: [40, 40], spacing: [1.05, 1.05], origin: [-35, 20], material: m,
           shape: {circle: {radius: 0.5}}}
"""


def big_scene(folder: Path, steps: int) -> Path:
    path = folder / "big.yaml"
    path.write_text(BIG.replace("STEPS", str(steps)))
    return path


def same_frames(a, b, n: int | None = None) -> bool:
    """Whether trajectory b's frames equal a's first len(b) (or n) frames, bit for bit."""
    n = len(b.step) if n is None else n
    if not all(np.array_equal(getattr(a, k)[:n], getattr(b, k)[:n]) for k in SERIES):
        return False
    return all(np.array_equal(a.observables[k][:n], b.observables[k][:n]) for k in a.observables)


def start_run(*args: str | Path) -> subprocess.Popen:
    return subprocess.Popen(
        [*PYTHON, "-m", "rbsim", "run", *map(str, args), "-q"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, Path, object]:
    folder = tmp_path_factory.mktemp("reference")
    # long enough that a run goes on well past its first checkpoint (a second in): at 700
    # steps a run on two threads ended 0.2 s after it, and the kill tests skipped
    scene = big_scene(folder, 1500)
    out = folder / "ref.h5"
    t0 = time.monotonic()
    proc = start_run(scene, "-o", out)
    _o, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    traj = load_trajectory(out)
    traj.wall = time.monotonic() - t0  # how long a whole run takes on this machine
    return folder, scene, traj


@pytest.fixture(scope="module")
def killed(reference, tmp_path_factory) -> list[tuple[Path, float]]:
    """Runs of the big scene killed with SIGKILL at six seeded random moments, from
    before the file exists to late in the run: (file, moment in s) of each."""
    _folder, scene, ref = reference
    folder = tmp_path_factory.mktemp("killed")
    rng = random.Random(14)
    files = []
    for k in range(6):
        out = folder / f"killed{k}.h5"
        proc = start_run(scene, "-o", out)
        moment = rng.uniform(0.15, 0.95) * ref.wall
        time.sleep(moment)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        files.append((out, moment))
    return files


def test_sigkill_at_random_moments_leaves_a_plain_readable_prefix(reference, killed) -> None:
    _folder, _scene, ref = reference
    lengths = []
    for k, (out, _moment) in enumerate(killed):
        if not out.exists():  # killed while the engine was still being built
            lengths.append(-1)
            continue
        with h5py.File(out, "r") as f:  # plain h5py: no SWMR, no consistency flags
            assert "particles/bodies/position/step" in f
        traj = load_trajectory(out)
        assert traj.status in ("running", "complete")
        assert same_frames(ref, traj), f"kill {k}: frames differ from the reference"
        assert "frames" in summarize(out)
        lengths.append(len(traj.step))
    # the moments spread over the run: some kills land mid-run, with frames kept
    assert any(0 < n < len(ref.step) for n in lengths), lengths


H5DUMP = shutil.which("h5dump")


@pytest.mark.skipif(
    H5DUMP is None,
    reason="h5dump is not on PATH: HDF5's command-line tools are not installed "
    "(Debian: apt-get install hdf5-tools, or without root as cli.md says)",
)
def test_a_killed_run_leaves_a_file_that_h5dump_reads(killed) -> None:
    """HDF5's own reader (h5dump, its C library and not h5py's) opens every file a kill
    left: the header of each with exit 0, the frames' datasets in it."""
    assert H5DUMP is not None
    read = 0
    for out, moment in killed:
        if not out.exists():
            continue
        done = subprocess.run([H5DUMP, "-H", str(out)], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, f"killed at {moment:.2f} s: {done.stderr}"
        assert f'HDF5 "{out}"' in done.stdout and 'DATASET "step"' in done.stdout
        read += 1
    assert read, "no kill left a file"


def test_killed_runs_resume_bit_identically(reference, tmp_path) -> None:
    folder, scene, ref = reference
    for k, delay in enumerate((0.0, 0.15)):
        out = tmp_path / f"resumed{k}.h5"
        proc = start_run(scene, "-o", out)
        checkpoint = Path(f"{out}{CHECKPOINT_SUFFIX}")
        deadline = time.monotonic() + 60
        while not checkpoint.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)  # until the first flush
        time.sleep(delay)  # then at once, or a while later
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        kept = len(load_trajectory(out).step)
        if not checkpoint.exists():
            pytest.skip("the run finished before the kill")
        code, _o, err = rbsim("run", "--resume", out, "-q")
        assert code == 0, err
        traj = load_trajectory(out)
        assert traj.status == "complete" and len(traj.step) == len(ref.step), kept
        assert same_frames(ref, traj, len(ref.step))
        assert not Path(f"{out}{CHECKPOINT_SUFFIX}").exists()


def test_a_run_stopped_by_sigterm_keeps_its_checkpoint_and_resumes(reference, tmp_path) -> None:
    folder, scene, ref = reference
    out = tmp_path / "term.h5"
    proc = start_run(scene, "-o", out)
    # once it steps (its handlers installed, however slowly a loaded machine starts it)
    # and has written its first checkpoint: a fixed 1.2 s was too soon at times
    checkpoint = Path(f"{out}{CHECKPOINT_SUFFIX}")
    deadline = time.monotonic() + 60
    while not checkpoint.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _out, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the run finished before SIGTERM arrived")
    assert proc.returncode == 130, err
    with h5py.File(out, "r") as f:
        inside = "parameters/rbsim/checkpoint" in f
    stopped = load_trajectory(out)
    # its checkpoint in the file, or beside it where the file, more than STOP_COPY_BYTES
    # of frames (640 of these 100 kB ones: a second or two of this run), is closed in
    # place without a copy
    # (the body series read back: the file's frames less its observables, a few per cent)
    frame_bytes = sum(getattr(stopped, k).nbytes for k in SERIES)
    assert inside or (checkpoint.exists() and frame_bytes > 0.9 * STOP_COPY_BYTES), frame_bytes
    assert stopped.status == "interrupted" and same_frames(ref, stopped)
    summary = resume_run(out)
    assert summary.steps == ref.step[-1] and summary.steps_run < summary.steps
    done = load_trajectory(out)
    assert done.parameters["resumed"] == "1"
    assert same_frames(ref, done, len(ref.step))


def killed_after_its_checkpoint(out: Path, scene: Path, *sets: str, other: bytes = b"") -> bytes:
    """Start `rbsim run SCENE -o OUT` (with --set SETS), SIGKILL it once the file exists
    and a checkpoint other than `other` lies beside it; that checkpoint's bytes."""
    proc = start_run(scene, "-o", out, *(a for s in sets for a in ("--set", s)))
    checkpoint = Path(f"{out}{CHECKPOINT_SUFFIX}")

    def own() -> bool:
        return out.exists() and checkpoint.exists() and checkpoint.read_bytes() != other

    deadline = time.monotonic() + 60
    while not own() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    if not own():
        pytest.skip("the run finished before the kill")
    return checkpoint.read_bytes()


def test_a_checkpoint_resumes_only_the_run_that_wrote_it(reference, tmp_path) -> None:
    """A killed run's OUT.h5.resume once stayed when a new run wrote OUT.h5; resuming
    the new run (killed before its own first checkpoint) continued from the old run's
    state, said complete, and its frames were wrong by metres. A new run now removes
    the checkpoint at its path before it writes, and a checkpoint records the
    identifier of its trajectory, which resume checks."""
    _folder, scene, _ref = reference
    out = tmp_path / "x.h5"
    checkpoint = Path(f"{out}{CHECKPOINT_SUFFIX}")
    old = killed_after_its_checkpoint(out, scene, "world.steps=5000")
    # a new run at the same path removes the old checkpoint before anything else
    seen: list[bool] = []
    run_scene(scene_from(PILE), out, progress=lambda *_: seen.append(checkpoint.exists()))
    assert seen and not any(seen) and not checkpoint.exists()
    # a different run killed; the old run's checkpoint put back beside its file
    killed_after_its_checkpoint(out, scene, "world.steps=5000", "world.gravity=[0,-3]", other=old)
    kept = load_trajectory(out)
    checkpoint.write_bytes(old)
    code, _o, err = rbsim("run", "--resume", out, "-q")
    assert code == 1 and "another run's checkpoint" in err and "Traceback" not in err
    after = load_trajectory(out)
    assert after.status == "running" and same_frames(kept, after, len(kept.step))
    assert len(after.step) == len(kept.step)


def test_the_wall_time_of_a_resumed_run_is_the_sum_of_its_segments(reference, tmp_path) -> None:
    """The wall time a resumed run recorded was its last segment's alone (1.3 s of a 7 s
    run resumed 3 times); it is now the sum: the killed segment's to its last flush
    (rewritten at each), then the resume's."""
    _folder, scene, _ref = reference
    out = tmp_path / "w.h5"
    killed_after_its_checkpoint(out, scene, "world.steps=1400")
    before = float(load_trajectory(out).parameters["wall_time"])
    assert before > 0.5  # at least the first flush's second
    summary = resume_run(out)
    after = float(load_trajectory(out).parameters["wall_time"])
    assert after == pytest.approx(before + summary.wall_time, rel=1e-12)
    assert "the sum of its 2 segments, resumed 1 time" in summarize(out)


def test_the_recorded_wall_time_is_the_summarys_compression_included(tmp_path) -> None:
    """A gzip file recorded its wall time before the compressed final layout, which the
    run's summary line counted: they now agree."""
    scene = scene_from(PILE, ["output.compression=gzip"])
    summary = run_scene(scene, tmp_path / "g.h5")
    assert float(load_trajectory(tmp_path / "g.h5").parameters["wall_time"]) == pytest.approx(
        summary.wall_time, rel=1e-12
    )


def test_resume_refuses_a_complete_run_with_a_message(reference) -> None:
    folder, _scene, _ref = reference
    code, _o, err = rbsim("run", "--resume", folder / "ref.h5")
    assert code == 1 and "complete" in err and "Traceback" not in err


PILE = """\
version: 1
world: {gravity: [0, -9.81], dt: 1/60, steps: 90}
bodies:
  - name: ground
    type: static
    shape: {segment: {a: [-20, 0], b: [20, 0]}}
  - name: wall
    type: static
    shape: {box: {size: [1, 4], offset: [8, 2]}}
  - pyramid: {base: 6, size: [1, 1], origin: [0, 0.5]}
  - name: ball
    position: [-6, 1]
    velocity: [8, 0]
    mass: 20
    shape: {circle: {radius: 1}}
"""


def run_pile(tmp_path: Path, name: str, *overrides: str):
    scene = scene_from(PILE, overrides)
    out = tmp_path / f"{name}.h5"
    run_scene(scene, out)
    return load_trajectory(out), out


def test_float32_differs_from_float64_by_float32_rounding_and_halves_the_series(tmp_path) -> None:
    full, full_path = run_pile(tmp_path, "f64")
    half, half_path = run_pile(tmp_path, "f32", "output.precision=float32")
    assert half.position.dtype == np.float32 and full.position.dtype == np.float64
    for name in ("position", "orientation", "angle", "velocity", "angular_velocity"):
        exact = getattr(full, name)
        # float32 rounding: half an ulp of float32 at each value, relative 2**-24
        assert np.all(np.abs(getattr(half, name) - exact) <= np.abs(exact) * 2.0**-24 + 1e-45)
    np.testing.assert_array_equal(half.step, full.step)
    np.testing.assert_array_equal(
        half.observables["kinetic_energy"], full.observables["kinetic_energy"]
    )
    series = lambda p: sum(  # noqa: E731 - bytes of the per-body series on file
        h5py.File(p)[f"particles/bodies/{n}/value"].id.get_storage_size()
        for n in ("position", "orientation", "angle", "velocity", "angular_velocity")
    )
    assert series(half_path) * 2 == series(full_path)


@pytest.mark.parametrize("compression", ["lzf", "gzip"])
def test_compressed_files_hold_the_same_frames(tmp_path, compression: str) -> None:
    plain, _ = run_pile(tmp_path, "plain")
    packed, path = run_pile(tmp_path, compression, f"output.compression={compression}")
    assert same_frames(plain, packed, len(plain.step)) and len(packed.step) == len(plain.step)
    with h5py.File(path, "r") as f:
        assert f["particles/bodies/position/value"].compression == compression
    assert "complete" in summarize(path)


def test_a_signal_during_the_final_compression_stops_it_and_the_run_resumes(
    tmp_path, monkeypatch
) -> None:
    # Ctrl-C in the seconds a large gzip file takes to lay out at close was held until
    # the layout ended: the run then said "complete" and exited 0. It now stops there,
    # the frames kept as the run wrote them, and --resume finishes the file
    gzip = ("output.compression=gzip",)
    scene = scene_from(PILE, gzip)
    ref = tmp_path / "ref.h5"
    run_scene(scene, ref)
    close = TrajectoryWriter.close

    def signalled_close(self, **kwargs):
        if kwargs.get("status") == "complete":  # the run's own handler counts it
            os.kill(os.getpid(), signal.SIGINT)
        return close(self, **kwargs)

    monkeypatch.setattr(TrajectoryWriter, "close", signalled_close)
    out = tmp_path / "stopped.h5"
    # (Python's own Ctrl-C handler for the run to find: a shell running the tests in the
    # background may ignore SIGINT, and a run keeps ignoring what was ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(RunInterrupted):
            run_scene(scene, out, overrides=gzip, flush_seconds=0.0)  # (a checkpoint each flush)
    finally:
        signal.signal(signal.SIGINT, previous)
    monkeypatch.undo()
    assert "interrupted" in summarize(out)
    position = "particles/bodies/position/value"
    with h5py.File(out, "r") as f:
        assert f[position].compression is None  # as laid out during the run
    assert same_frames(load_trajectory(ref), load_trajectory(out), len(load_trajectory(ref).step))
    resume_run(out)
    assert "complete" in summarize(out)
    with h5py.File(out, "r") as f:
        assert f[position].compression == "gzip"
    a, b = load_trajectory(ref), load_trajectory(out)
    assert len(b.step) == len(a.step) and same_frames(a, b, len(a.step))


def test_a_dead_writers_layout_file_is_removed_by_the_next_run_at_its_path(tmp_path) -> None:
    # kill -9 while a file is laid out anew (its compression at close) left OUT.h5.tmp-PID,
    # tens of MB that nothing removed; a live process's is left alone
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    out = tmp_path / "pile.h5"
    dead, live = Path(f"{out}.tmp-{child.pid}"), Path(f"{out}.tmp-{os.getppid()}")
    dead.write_bytes(b"x" * 100)
    live.write_bytes(b"y")
    run_scene(scene_from(PILE), out)
    assert not dead.exists() and live.exists()


def test_a_subset_of_bodies_keeps_their_rows_and_stores_the_rest_once(tmp_path) -> None:
    full, _ = run_pile(tmp_path, "all")
    some, path = run_pile(tmp_path, "some", "output.bodies=[ball, 'pyramid[0,*]']")
    names = some.bodies.name
    assert names[0] == "pyramid[0,0]" and names[-1] == "ball" and len(names) == 7
    rows = [full.body(n) for n in names]
    np.testing.assert_array_equal(some.position, full.position[:, rows])
    np.testing.assert_array_equal(some.angular_velocity, full.angular_velocity[:, rows])
    # the static bodies left out are stored once, with their shapes and pose
    assert some.fixed is not None and some.fixed.bodies.name == ["ground", "wall"]
    np.testing.assert_array_equal(some.fixed.position, full.position[0, :2])
    assert "and 2 static stored once" in summarize(path)
    moving, _ = run_pile(tmp_path, "moving", "output.bodies=moving")
    assert "ground" not in moving.bodies.name and len(moving.bodies) == len(full.bodies) - 2


def test_a_list_of_output_bodies_keeps_the_scene_text_so_batch_and_resume_work(
    tmp_path,
) -> None:
    """A list under output.bodies once replaced the recorded scene text with its last item
    (a loop variable shadowed the text): batch and --resume then exited 3."""
    path = tmp_path / "s.yaml"
    path.write_text(PILE + "output: {bodies: [ball, 'pyramid[0,*]']}\n")
    out = tmp_path / "s.h5"
    code, _o, err = rbsim("run", path, "-o", out, "-q")
    assert code == 0, err
    with h5py.File(out, "r") as f:
        assert f["parameters/rbsim/scene"][()].decode() == path.read_text()
    code, _o, err = rbsim("batch", path, "-o", tmp_path / "b", "-q")
    assert code == 0 and "Traceback" not in err, err


def test_output_bodies_that_match_nothing_is_an_invalid_scene(tmp_path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(PILE + "output: {bodies: [bal]}\n")
    code, _o, err = rbsim("validate", path)
    assert code == 3 and "output.bodies" in err and "ball" in err and ":" in err


def test_the_writer_holds_a_bounded_number_of_frames(tmp_path) -> None:
    n = 10_000
    bodies = BodyTable(
        name=[f"b{i}" for i in range(n)],
        type=["dynamic"] * n,
        mass=np.ones(n),
        moment_of_inertia=np.ones(n),
        center_of_mass=np.zeros((n, 2)),
        shape_body=np.arange(n),
        shape_kind=["circle"] * n,
        shape_radius=np.full(n, 0.5),
        shape_vertex_start=np.arange(n),
        shape_vertex_count=np.ones(n),
        shape_vertices=np.zeros((n, 2)),
    )
    writer = TrajectoryWriter(
        tmp_path / "w.h5", bodies=bodies, parameters={}, frames=100, observables=OBSERVABLES
    )
    frame_bytes = n * 8 * 8  # position, orientation, velocity (2 each), angle, angular velocity
    rows = len(writer.block["step"])
    # the bound: BLOCK_BYTES of frames (at least one, at most BLOCK_MAX_FRAMES)
    assert 1 <= rows <= BLOCK_MAX_FRAMES and rows * frame_bytes <= max(BLOCK_BYTES, frame_bytes)
    frame = {
        "position": np.zeros((n, 2)),
        "orientation": np.tile([1.0, 0.0], (n, 1)),
        "angle": np.zeros(n),
        "velocity": np.zeros((n, 2)),
        "angular_velocity": np.zeros(n),
        "observables": {
            "kinetic_energy": 0.0,
            "potential_energy": 0.0,
            "linear_momentum": np.zeros(2),
            "angular_momentum": 0.0,
            "contact_count": 0,
        },
    }
    writer.flush_seconds = 1e9  # only a full block writes
    for t in range(3 * rows + 1):
        writer.append(t, 0.1 * t, **frame)
        assert writer.rows <= rows and writer.frames_written - writer.frames_flushed <= rows
    writer.close()
    assert len(load_trajectory(tmp_path / "w.h5").step) == 3 * rows + 1


def test_a_write_error_mid_run_keeps_the_frames_flushed_and_exits_1(tmp_path, monkeypatch) -> None:
    import rbsim.io.trajectory as trajectory

    scene = big_scene(tmp_path, 300)
    out = tmp_path / "full.h5"
    calls = {"n": 0}
    real = os.pwrite

    def pwrite(fd, data, offset):  # noqa: ANN001, ANN202 - os.pwrite's
        calls["n"] += 1
        if calls["n"] > 40:  # a disk that fills up after some blocks
            raise OSError(28, "No space left on device")
        return real(fd, data, offset)

    monkeypatch.setattr(trajectory.os, "pwrite", pwrite)
    code, _o, err = rbsim("run", scene, "-o", out, "-q", "--set", "output.every=1")
    monkeypatch.setattr(trajectory.os, "pwrite", real)
    assert code == 1 and "No space left on device" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    with h5py.File(out, "r") as f:
        assert "particles/bodies/position/value" in f
    kept = load_trajectory(out)
    assert 0 < len(kept.step) < frame_steps(300, 1)
    # what to do once there is room: resume where a checkpoint was made (the first comes
    # about a second in), else run again (the message said resume where none existed)
    resumable = Path(f"{out}{CHECKPOINT_SUFFIX}").exists()
    assert ("rbsim run --resume finishes it" in err) == resumable
    assert ("no checkpoint was made yet: once there is room, run it again" in err) != resumable
    assert not Path(f"{out}{CHECKPOINT_SUFFIX}.tmp").exists()


@pytest.mark.parametrize("checkpoint", [True, False])
def test_a_full_disk_message_reads_with_and_without_a_checkpoint(tmp_path, checkpoint) -> None:
    """It read '...; once there is room, no checkpoint was made yet: run it again'
    before the first checkpoint."""
    from rbsim.run import WriteFailed

    out = tmp_path / "full.h5"
    out.write_bytes(b"")
    if checkpoint:
        Path(f"{out}{CHECKPOINT_SUFFIX}").write_bytes(b"")
    err = WriteFailed(OSError(28, "No space left on device"), str(out), 583, True)
    then = (
        "once there is room, rbsim run --resume finishes it"
        if checkpoint
        else "no checkpoint was made yet: once there is room, run it again"
    )
    assert str(err) == (
        f"cannot write {out}: No space left on device; the file keeps 583 frames "
        f"(status failed); {then}"
    )


def test_a_checkpoint_that_fails_midway_leaves_no_temporary_file(tmp_path) -> None:
    """A full disk while the checkpoint was written left OUT.h5.resume.tmp (holding the
    disk's last room); the last whole checkpoint stays."""
    path = str(tmp_path / "full.h5.resume")
    write_checkpoint(path, 3, 3, b"old" * 10, owner="x")
    before = Path(path).read_bytes()

    def full() -> bool:  # asked between chunks: the disk fills up midway
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space"):
        write_checkpoint(path, 5, 5, bytes(3 * (1 << 20)), stop=full, owner="x")
    assert not Path(f"{path}.tmp").exists()
    assert Path(path).read_bytes() == before


def test_an_unwritable_folder_is_a_clear_message(tmp_path) -> None:
    scene = big_scene(tmp_path, 3)
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        if os.access(folder, os.W_OK):
            pytest.skip("running as a user who may write anywhere")
        code, _o, err = rbsim("run", scene, "-o", folder / "x.h5")
    finally:
        folder.chmod(0o700)
    assert code == 1 and "Permission denied" in err and "Traceback" not in err


def test_a_truncated_trajectory_fails_at_once_with_a_message(reference, tmp_path) -> None:
    folder, _scene, _ref = reference
    cut = tmp_path / "cut.h5"
    cut.write_bytes((folder / "ref.h5").read_bytes()[:5000])
    t0 = time.monotonic()
    code, _o, err = rbsim("info", cut)
    assert code == 1 and "truncated" in err and time.monotonic() - t0 < 5
    with pytest.raises(OSError, match="truncated"):
        load_trajectory(cut)


def test_run_from_python_returns_the_trajectory_in_memory(tmp_path) -> None:
    import rbsim as rb

    traj = rb.run(textwrap.dedent(PILE))
    assert len(traj.step) == 91 and traj.status == "complete"
    path = tmp_path / "pile.yaml"
    path.write_text(PILE)
    again = rb.run(path)
    assert same_frames(traj, again, 91)
    as_dict = rb.run(
        {"version": 1, "world": {"steps": 5}, "bodies": [{"shape": {"circle": {"radius": 1}}}]}
    )
    assert len(as_dict.step) == 6 and as_dict.position[-1, 0, 1] < 0
    out = tmp_path / "kept.h5"
    on_file = rb.run(path, out)
    assert out.exists() and same_frames(traj, on_file, 91)


def test_run_from_python_takes_one_override_as_a_string(tmp_path) -> None:
    import rbsim as rb

    # one string is one --set line, not a sequence of one-letter lines
    one = rb.run(textwrap.dedent(PILE), overrides="world.steps=4")
    assert len(one.step) == 5
    listed = rb.run(textwrap.dedent(PILE), overrides=["world.steps=4"])
    assert same_frames(one, listed, 5)
    with pytest.raises(TypeError, match="overrides"):
        rb.run(textwrap.dedent(PILE), overrides=[("world.steps", 4)])


def test_a_run_stopped_between_frames_resumes_bit_identically(tmp_path) -> None:
    # output every 7th step: the stop lands between frames, and the checkpoint holds the
    # state of the last whole step, past the last frame
    # the first checkpoint (a second in) well before the end (at 900 steps, on two threads,
    # SIGTERM came as the run ended, and killed it outright)
    scene = big_scene(tmp_path, 1800)
    ref = tmp_path / "ref7.h5"
    code, _o, err = rbsim("run", scene, "-o", ref, "-q", "--set", "output.every=7")
    assert code == 0, err
    out = tmp_path / "stopped7.h5"
    proc = start_run(scene, "-o", out, "--set", "output.every=7")
    checkpoint = Path(f"{out}{CHECKPOINT_SUFFIX}")
    deadline = time.monotonic() + 60
    while not checkpoint.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.13)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the run finished before SIGTERM arrived")
    assert proc.returncode == 130
    code, _o, err = rbsim("run", "--resume", out, "-q")
    assert code == 0, err
    a, b = load_trajectory(ref), load_trajectory(out)
    assert len(b.step) == len(a.step) and same_frames(a, b, len(a.step))


def test_resume_from_a_damaged_checkpoint_is_a_message(reference, tmp_path) -> None:
    folder, scene, _ref = reference
    out = tmp_path / "damaged.h5"
    code, _o, err = rbsim("run", scene, "-o", out, "-q", "--set", "world.steps=30")
    assert code == 0, err
    with h5py.File(out, "a") as f:  # as a killed run leaves it, with a cut checkpoint
        f["parameters/rbsim/status"][()] = b"running"
    Path(f"{out}{CHECKPOINT_SUFFIX}").write_bytes(
        b"RBSIMRS1" + (31).to_bytes(8, "little") * 2 + b"RBSIMCK9"
    )
    code, _o, err = rbsim("run", "--resume", out)
    assert code == 1 and "checkpoint" in err and "Traceback" not in err


def test_resume_from_another_versions_checkpoint_says_so(reference, tmp_path) -> None:
    folder, scene, _ref = reference
    out = tmp_path / "older.h5"
    code, _o, err = rbsim("run", scene, "-o", out, "-q", "--set", "world.steps=30")
    assert code == 0, err
    with h5py.File(out, "a") as f:  # as a killed run leaves it
        f["parameters/rbsim/status"][()] = b"running"
    # an engine checkpoint of format 6 (before a solver row kept the distance within
    # which its points touch: read by this engine, every row and every array after them
    # would be misread)
    owner = load_trajectory(out).parameters[TRAJECTORY_ID]
    write_checkpoint(f"{out}{CHECKPOINT_SUFFIX}", 31, 31, b"RBSIMCK6" + bytes(64), owner=owner)
    code, _o, err = rbsim("run", "--resume", out)
    assert code == 1, err
    assert "another version of rbsim's engine (format 6, this one reads E)" in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("limit", [50e6, 0.0])
def test_a_stopped_run_writes_its_last_state_only_when_it_is_small(tmp_path, monkeypatch, limit):
    # Ctrl-C saves the world's last state into the file only when that is quick: a
    # checkpoint larger than CHECKPOINT_STOP_BYTES (a large pile's: 195 MB, seconds to
    # write on a busy disk) is left out, and the last flush's stays beside the file
    import rbsim.run as run_module

    monkeypatch.setattr(run_module, "CHECKPOINT_STOP_BYTES", limit)
    scene = scene_from(
        "version: 1\nworld: {steps: 50}\nbodies:\n  - {shape: {circle: {radius: 1}}}\n"
    )

    def stop(step: int, total: int) -> None:
        if step >= 20:
            raise KeyboardInterrupt

    out = tmp_path / "stopped.h5"
    with pytest.raises(KeyboardInterrupt):
        run_scene(scene, out, progress=stop, signals=())
    assert load_trajectory(out).status == "interrupted"
    with h5py.File(out, "r") as f:
        assert ("parameters/rbsim/checkpoint" in f) == (limit > 0)


def test_a_file_another_process_writes_is_neither_run_into_nor_resumed(tmp_path) -> None:
    # two runs into one file both wrote it (the later one's layout replaced the earlier
    # run's frames without a word), and a file still being written could be resumed
    scene = big_scene(tmp_path, 3)
    out = tmp_path / "shared.h5"
    code, _o, err = rbsim("run", scene, "-o", out, "-q")
    assert code == 0, err
    assert not Path(f"{out}.lock").exists()  # a run that ended leaves no lock file
    holder = subprocess.Popen(
        [*PYTHON, "-c", HOLD_LOCK, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        assert holder.stdout.readline().strip() == b"held"
        before = out.read_bytes()
        code, _o, err = rbsim("run", scene, "-o", out, "-q")
        assert code == 1 and "another rbsim process is writing" in err, err
        code, _o, err = rbsim("run", "--resume", out, "-q")
        assert code == 1 and "another rbsim process is writing" in err, err
        assert out.read_bytes() == before  # untouched
    finally:
        holder.kill()  # killed: the kernel drops its lock
        holder.wait()
    code, _o, err = rbsim("run", scene, "-o", out, "-q")
    assert code == 0, err


# a process that holds a trajectory's lock (as a run writing it does) until killed
HOLD_LOCK = """\
import sys, time
from rbsim.run import OutputLock
lock = OutputLock(sys.argv[1])
print("held", flush=True)
time.sleep(600)
"""
