"""The trajectory file's room for frames: made as the frames come, never in proportion to
the whole run before its first frame; and a stopped run closed without copying its frames
(rbsim.io.trajectory ROOM_FRAMES, ROOM_BYTES, STOP_COPY_BYTES; docs/design.md, "Output")."""

from __future__ import annotations

import os

import h5py
import numpy as np
import pytest

import rbsim.io.trajectory as trajectory
from rbsim.io.trajectory import (
    CHECKPOINT_SUFFIX,
    OBSERVABLES,
    BodyTable,
    LayoutStopped,
    TrajectoryWriter,
    load_trajectory,
    summarize,
)
from rbsim.run import resume_run, run_scene

from .conftest import scene_from

BALL = """\
version: 1
world: {steps: STEPS}
output: {contacts: points}
bodies:
  - {name: ground, type: static, shape: {segment: {a: [-50, 0], b: [50, 0]}}}
  - {name: ball, position: [0, 3], velocity: [1, 0], shape: {circle: {radius: 0.5}}}
  - {name: box, position: [2, 0.5], shape: {box: {size: [1, 1]}}}
"""


def ball_scene(steps: int):
    return scene_from(BALL.replace("STEPS", str(steps)))


def same(a, b) -> bool:
    """Whether two trajectories hold the same frames and contact points, bit for bit."""
    keys = ("step", "time", "position", "orientation", "angle", "velocity", "angular_velocity")
    if not all(np.array_equal(getattr(a, k), getattr(b, k)) for k in keys):
        return False
    if not all(np.array_equal(a.observables[k], b.observables[k]) for k in a.observables):
        return False
    ca, cb = a.contacts, b.contacts
    names = ("start", "count", "body", "position", "normal", "force")
    return all(np.array_equal(getattr(ca, k), getattr(cb, k)) for k in names)


def one_ball() -> BodyTable:
    return BodyTable(
        name=["ball"],
        type=["dynamic"],
        mass=[1.0],
        moment_of_inertia=[0.5],
        center_of_mass=[[0.0, 0.0]],
        shape_body=[0],
        shape_kind=["circle"],
        shape_radius=[1.0],
        shape_vertex_start=[0],
        shape_vertex_count=[1],
        shape_vertices=[[0.0, 0.0]],
    )


def append(writer: TrajectoryWriter, step: int) -> None:
    z = np.zeros((1, 2))
    obs = {"kinetic_energy": 0.0, "potential_energy": 0.0, "linear_momentum": np.zeros(2)}
    obs |= {"angular_momentum": 0.0, "contact_count": 0}
    writer.append(step, step / 60, z + step, z, np.zeros(1), z, np.zeros(1), obs)


def test_a_writer_told_a_billion_frames_makes_little_room_before_the_first(tmp_path) -> None:
    # A scene of one ball with 1e9 steps wrote 16 GB of step and time (-1, NaN) before its
    # first step, and room for 136 GB of frames
    out = tmp_path / "long.h5"
    writer = TrajectoryWriter(
        out, bodies=one_ball(), parameters={}, frames=10**9 + 1, observables=OBSERVABLES
    )
    size, used = os.stat(out).st_size, os.stat(out).st_blocks * 512
    # 64 MB: room for ROOM_FRAMES (2^18) frames of 136 bytes is 36 MB, written 4 MB of it
    assert size < 64e6 and used < 16e6, (size, used)
    with h5py.File(out, "r") as f:
        assert f["particles/bodies/position/step"].shape[0] == trajectory.ROOM_FRAMES
    for step in range(3):
        append(writer, step)
    writer.close(status="interrupted")
    traj = load_trajectory(out)
    assert list(traj.step) == [0, 1, 2] and traj.status == "interrupted"


def test_a_run_of_a_billion_steps_starts_with_a_small_file(tmp_path) -> None:
    out = tmp_path / "long.h5"
    seen = []

    def stop(step: int, total: int) -> None:  # after the first call of the engine
        seen.append((os.stat(out).st_size, os.stat(out).st_blocks * 512))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_scene(scene_from(BALL.replace("STEPS", "1000000000")), out, progress=stop, signals=())
    size, used = seen[0]
    # three bodies and contact rows: 2^18 frames of about 250 bytes, 4 MB of it written
    assert size < 200e6 and used < 16e6, (size, used)
    assert load_trajectory(out).status == "interrupted"


def test_room_made_as_frames_come_holds_the_same_frames(tmp_path, monkeypatch) -> None:
    # room for 4 frames at first, doubled (the file laid out anew) five times over the run
    plain = tmp_path / "plain.h5"
    run_scene(ball_scene(100), plain)
    monkeypatch.setattr(trajectory, "ROOM_FRAMES", 4)
    monkeypatch.setattr(trajectory, "INITIAL_FRAMES", 1)
    layouts = []
    lay_out = TrajectoryWriter._layout

    def counted(self, capacity, *args, **kwargs):
        layouts.append(capacity)
        return lay_out(self, capacity, *args, **kwargs)

    monkeypatch.setattr(TrajectoryWriter, "_layout", counted)
    grown = tmp_path / "grown.h5"
    run_scene(ball_scene(100), grown)
    assert layouts[0] == 4 and layouts[-1] == 101 and len(layouts) >= 6, layouts
    a, b = load_trajectory(plain), load_trajectory(grown)
    assert b.status == "complete" and len(b.step) == 101 and same(a, b)
    with h5py.File(grown, "r") as f:  # exactly its frames
        assert f["particles/bodies/position/step"].shape == (101,)


def test_a_signal_while_the_room_grows_leaves_the_file_as_it_was(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(trajectory, "ROOM_FRAMES", 4)
    monkeypatch.setattr(trajectory, "INITIAL_FRAMES", 1)
    out = tmp_path / "grow.h5"
    writer = TrajectoryWriter(
        out, bodies=one_ball(), parameters={}, frames=1000, observables=OBSERVABLES
    )
    for step in range(4):
        append(writer, step)
    assert writer.room == 0
    with pytest.raises(LayoutStopped):
        writer.make_room(stop=lambda: True)
    assert not [p for p in os.listdir(tmp_path) if ".tmp-" in p]
    assert list(load_trajectory(out).step) == [0, 1, 2, 3]  # the file as it was, on disk
    writer.close(status="interrupted")
    traj = load_trajectory(out)
    assert list(traj.step) == [0, 1, 2, 3] and traj.status == "interrupted"


def test_a_stopped_run_with_a_large_file_is_closed_without_a_copy(tmp_path, monkeypatch) -> None:
    # Ctrl-C on a pile of 20,000 boxes waited 1.5 s (305 frames, 442 MB) to 3 s (1 GB)
    # for the copy of every frame into a file of exactly its frames; every file is
    # "large" here
    monkeypatch.setattr(trajectory, "STOP_COPY_BYTES", 0)
    reference = tmp_path / "reference.h5"
    run_scene(ball_scene(200), reference)
    finals = []
    lay_out = TrajectoryWriter._layout

    def spied(self, capacity, *args, **kwargs):
        finals.append(kwargs.get("final", False))
        return lay_out(self, capacity, *args, **kwargs)

    monkeypatch.setattr(TrajectoryWriter, "_layout", spied)

    def stop(step: int, total: int) -> None:  # after the first call of the engine
        raise KeyboardInterrupt

    out = tmp_path / "stopped.h5"
    with pytest.raises(KeyboardInterrupt):
        run_scene(ball_scene(200), out, progress=stop, signals=())
    assert not any(finals), finals  # no layout copied the frames at the close
    stopped = load_trajectory(out)
    kept = len(stopped.step)
    assert stopped.status == "interrupted" and 2 <= kept < 201
    with h5py.File(out, "r") as f:  # its room kept, unwritten rows read step -1
        step = f["particles/bodies/position/step"][()]
        assert len(step) == 201 and (step[kept:] == -1).all()
        assert "parameters/rbsim/checkpoint" not in f
    assert os.path.exists(f"{out}{CHECKPOINT_SUFFIX}")  # the last state, beside it
    assert "status     interrupted" in summarize(out)
    monkeypatch.setattr(TrajectoryWriter, "_layout", lay_out)
    resume_run(out)
    done, ref = load_trajectory(out), load_trajectory(reference)
    assert done.status == "complete" and same(ref, done)
    assert not os.path.exists(f"{out}{CHECKPOINT_SUFFIX}")


def test_a_second_signal_stops_a_stopped_runs_copy(tmp_path) -> None:
    # a small stopped file is laid out with exactly its frames; a second Ctrl-C during
    # that copy leaves it as it was, its checkpoint beside it
    out = tmp_path / "small.h5"
    writer = TrajectoryWriter(out, bodies=one_ball(), parameters={}, frames=50)
    for step in range(5):
        append(writer, step)
    with pytest.raises(LayoutStopped):
        writer.close(
            status="interrupted", checkpoint=b"engine", checkpoint_step=4, stop=lambda: True
        )
    traj = load_trajectory(out)
    assert list(traj.step) == list(range(5)) and traj.status == "interrupted"
    frames, step, data, _owner = trajectory.read_checkpoint(f"{out}{CHECKPOINT_SUFFIX}")
    assert (frames, step, data) == (5, 4, b"engine")
