"""Trajectory files: round trip, H5MD layout, status on close, and survival of kill -9."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rbsim.io.trajectory import BodyTable, TrajectoryWriter, load_trajectory, summarize

REPO = Path(__file__).resolve().parents[1]
N_FRAMES = 5


def three_bodies() -> BodyTable:
    """A static ground segment, a ball (circle) and a crate (box), in the body frame."""
    return BodyTable(
        name=["ground", "ball", "crate"],
        type=["static", "dynamic", "dynamic"],
        mass=np.array([np.inf, 0.785398, 1.0]),
        moment_of_inertia=np.array([np.inf, 0.0981748, 0.1666667]),
        center_of_mass=np.array([[0.0, 0.0], [0.0, 0.0], [0.25, -0.125]]),
        shape_body=np.array([0, 1, 2], dtype=np.int32),
        shape_kind=["segment", "circle", "box"],
        shape_radius=np.array([0.0, 0.5, 0.0]),
        shape_vertex_start=np.array([0, 2, 3], dtype=np.int32),
        shape_vertex_count=np.array([2, 1, 4], dtype=np.int32),
        shape_vertices=np.array(
            [[-50, 0], [50, 0], [0, 0], [-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]],
            dtype=np.float64,
        ),
    )


def frames(n_frames: int, n_bodies: int = 3, seed: int = 1) -> list[dict]:
    """Known frames with arbitrary (random) values; body 0 is static and never moves."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_frames):
        angle = rng.normal(size=n_bodies)
        angle[0] = 0.0
        position = rng.normal(size=(n_bodies, 2))
        position[0] = (0.0, 0.0)
        out.append(
            dict(
                step=2 * k,
                time=2 * k / 60.0,
                position=position,
                orientation=np.stack([np.cos(angle), np.sin(angle)], axis=1),
                angle=angle,
                velocity=rng.normal(size=(n_bodies, 2)),
                angular_velocity=rng.normal(size=n_bodies),
                observables={
                    "kinetic_energy": float(rng.random()),
                    "potential_energy": float(rng.normal()),
                    "linear_momentum": rng.normal(size=2),
                    "angular_momentum": float(rng.normal()),
                    "contact_count": int(k + 1),
                },
            )
        )
    return out


PARAMETERS = {
    "scene": "version: 1\nname: three\nbodies: []\n",
    "resolved_scene": json.dumps({"name": "three", "world": {"dt": 1 / 60}}),
    "solver": json.dumps({"substeps": 4, "iterations": 1}),
    "rbsim_version": "0.1.0",
}


def write(path: Path, data: list[dict], **kwargs) -> TrajectoryWriter:
    writer = TrajectoryWriter(path, bodies=three_bodies(), parameters=PARAMETERS, **kwargs)
    for frame in data:
        writer.append(**frame)
    return writer


def test_round_trip_reproduces_every_array_exactly(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    data = frames(N_FRAMES)
    write(path, data).close()

    traj = load_trajectory(path)
    assert traj.step.dtype == np.int64
    np.testing.assert_array_equal(traj.step, [f["step"] for f in data])
    np.testing.assert_array_equal(traj.time, [f["time"] for f in data])
    for name in ("position", "orientation", "angle", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(traj, name), np.stack([f[name] for f in data]))
    assert traj.position.shape == (N_FRAMES, 3, 2) and traj.angle.shape == (N_FRAMES, 3)
    assert set(traj.observables) == set(data[0]["observables"])
    for name, series in traj.observables.items():
        np.testing.assert_array_equal(series, np.stack([f["observables"][name] for f in data]))
    assert traj.observables["linear_momentum"].shape == (N_FRAMES, 2)
    assert traj.observables["contact_count"].dtype.kind == "i"

    expected = three_bodies()
    assert traj.bodies.name == expected.name
    assert traj.bodies.type == expected.type
    assert traj.bodies.shape_kind == expected.shape_kind
    for name in (
        "mass",
        "moment_of_inertia",
        "center_of_mass",
        "shape_body",
        "shape_radius",
        "shape_vertex_start",
        "shape_vertex_count",
        "shape_vertices",
    ):
        np.testing.assert_array_equal(getattr(traj.bodies, name), getattr(expected, name))
    for key, value in PARAMETERS.items():
        assert traj.parameters[key] == value
    assert traj.engine == "rbsim" and traj.parameters["engine"] == "rbsim"
    assert traj.body("crate") == 2


def test_file_follows_h5md_layout_with_shared_step_and_time(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    write(path, frames(N_FRAMES)).close()

    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["h5md"].attrs["version"], [1, 1])
        assert "name" in f["h5md/author"].attrs
        assert f["h5md/creator"].attrs["name"] == "rbsim"
        assert "version" in f["h5md/creator"].attrs
        box = f["particles/bodies/box"]
        assert box.attrs["dimension"] == 2
        assert [b.decode() if isinstance(b, bytes) else b for b in box.attrs["boundary"]] == [
            "none",
            "none",
        ]

        step = f["particles/bodies/position/step"]
        time = f["particles/bodies/position/time"]
        groups = [
            f"particles/bodies/{n}"
            for n in ("orientation", "angle", "velocity", "angular_velocity")
        ] + [f"observables/{n}" for n in f["observables"]]
        assert len(groups) == 9
        for group in groups:
            assert f[group]["step"].id == step.id, group  # a hard link: the same object
            assert f[group]["time"].id == time.id, group
        assert step.dtype == np.int64 and time.dtype == np.float64

        units = {
            "position": "m",
            "velocity": "m s-1",
            "angle": "rad",
            "angular_velocity": "rad s-1",
        }
        # H5MD's units module: its group, the SI system, each unit a fixed-length ASCII string
        module = f["h5md/modules/units"]
        assert list(module.attrs["version"]) == [1, 0]
        assert module.attrs["system"] == b"SI"
        for name, unit in units.items():
            attr = f[f"particles/bodies/{name}/value"].attrs.get_id("unit")
            assert attr.get_type().get_cset() == h5py.h5t.CSET_ASCII, name
            assert not attr.get_type().is_variable_str(), name
            assert f[f"particles/bodies/{name}/value"].attrs["unit"] == unit.encode()
        assert f["observables/kinetic_energy/value"].attrs["unit"] == b"J"
        assert f["particles/bodies/position/time"].attrs["unit"] == b"s"

        value = f["particles/bodies/position/value"]
        assert value.shape == (N_FRAMES, 3, 2)
        assert value.chunks is None  # closed: contiguous, exactly its frames
        assert value.compression is None
        assert f["particles/bodies/angle/value"].shape == (N_FRAMES, 3)
        assert f["observables/linear_momentum/value"].shape == (N_FRAMES, 2)
        assert f["particles/bodies/name"].asstr()[()].tolist() == ["ground", "ball", "crate"]
        assert f["particles/bodies/shapes/vertices"].shape == (7, 2)
        assert f["parameters/rbsim/engine"].asstr()[()] == "rbsim"


def test_close_records_complete_status_and_wall_time_and_is_idempotent(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    writer = write(path, frames(2))
    writer.close(wall_time=1.5)
    writer.close(status="failed")  # a second close changes nothing

    traj = load_trajectory(path)
    assert traj.status == "complete"
    assert float(traj.parameters["wall_time"]) == 1.5
    assert len(traj.step) == 2 and writer.frames_written == 2
    with pytest.raises(ValueError, match="closed"):
        writer.append(**frames(1)[0])


def test_keyboard_interrupt_in_context_manager_records_interrupted_and_keeps_frames(
    tmp_path: Path,
) -> None:
    path = tmp_path / "t.h5"
    data = frames(3)
    with pytest.raises(KeyboardInterrupt):
        with TrajectoryWriter(path, bodies=three_bodies(), parameters=PARAMETERS) as writer:
            for frame in data:
                writer.append(**frame)
            raise KeyboardInterrupt

    traj = load_trajectory(path)
    assert traj.status == "interrupted"
    np.testing.assert_array_equal(traj.position, np.stack([f["position"] for f in data]))


def test_other_exception_in_context_manager_records_failed(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    with pytest.raises(FloatingPointError):
        with TrajectoryWriter(path, bodies=three_bodies(), parameters=PARAMETERS) as writer:
            writer.append(**frames(1)[0])
            raise FloatingPointError("non-finite state")
    assert load_trajectory(path).status == "failed"


def test_close_keeps_a_detailed_failure_status_cut_to_the_stored_length(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    detail = "failed: body 'ball' became non-finite at step 12"
    write(path, frames(1)).close(status=detail)
    assert load_trajectory(path).status == detail
    write(path, frames(1)).close(status="failed: " + "é" * 1000)
    status = load_trajectory(path).status
    assert status.startswith("failed: éé") and len(status.encode()) <= 256


CHILD = """
import sys, time
import numpy as np
sys.path.insert(0, {tests!r})
from test_trajectory import PARAMETERS, frames, three_bodies
from rbsim.io.trajectory import TrajectoryWriter

data = frames(40)
w = TrajectoryWriter({path!r}, bodies=three_bodies(), parameters=PARAMETERS, flush_seconds=0.2)
for frame in data[:30]:
    w.append(**frame)
    time.sleep(0.02)  # long enough for the writer's own timed flushes to happen
w.flush()
print("flushed", w.frames_flushed, flush=True)
for frame in data[30:]:  # appended but (most likely) not flushed
    w.append(**frame)
print("appended", w.frames_written, flush=True)
time.sleep(2)
print("not killed", flush=True)
"""


def test_kill_9_leaves_a_readable_file_with_every_flushed_frame(tmp_path: Path) -> None:
    path = tmp_path / "killed.h5"
    code = CHILD.format(tests=str(REPO / "tests"), path=str(path))
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    child = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        flushed_line = child.stdout.readline()
        appended_line = child.stdout.readline()
        assert flushed_line.startswith("flushed"), child.stderr.read()
        assert appended_line.startswith("appended"), child.stderr.read()
        live = load_trajectory(path)  # a SWMR reader, while the writer still runs
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.communicate(timeout=10)
    assert child.returncode == -signal.SIGKILL
    flushed = int(flushed_line.split()[1])
    assert flushed == 30
    assert len(live.step) >= flushed and live.status == "running"

    traj = load_trajectory(path)
    assert flushed <= len(traj.step) <= 40
    assert traj.status == "running"
    data = frames(40)[: len(traj.step)]
    np.testing.assert_array_equal(traj.step, [f["step"] for f in data])
    np.testing.assert_array_equal(traj.position, np.stack([f["position"] for f in data]))
    np.testing.assert_array_equal(
        traj.observables["contact_count"], [f["observables"]["contact_count"] for f in data]
    )
    assert "running" in summarize(path)


def test_a_writer_that_never_closes_leaves_its_flushed_frames_readable(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    data = frames(7)
    writer = TrajectoryWriter(path, bodies=three_bodies(), parameters=PARAMETERS, frames=10)
    for frame in data[:4]:
        writer.append(**frame)
    writer.flush()
    for frame in data[4:]:
        writer.append(**frame)  # gathered, not yet written
    writer.abandon()  # as a kill leaves it: no close
    with h5py.File(path, "r") as f:  # plain h5py, no SWMR
        assert f["particles/bodies/position/step"][:5].tolist() == [0, 2, 4, 6, -1]
    traj = load_trajectory(path)
    assert traj.status == "running" and len(traj.step) == 4
    np.testing.assert_array_equal(traj.position, np.stack([f["position"] for f in data[:4]]))


def test_load_trims_to_the_shortest_series(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    write(path, frames(4)).close()
    with h5py.File(path, "a") as f:  # a series one frame short (not something rbsim writes)
        value = f["particles/bodies/angle/value"][:3]
        del f["particles/bodies/angle/value"]
        f["particles/bodies/angle/value"] = value
    traj = load_trajectory(path)
    assert traj.position.shape == (3, 3, 2) and traj.angle.shape == (3, 3)
    assert len(traj.step) == 3 and traj.observables["kinetic_energy"].shape == (3,)


def test_file_without_frames_is_readable_before_and_after_close(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    writer = TrajectoryWriter(path, bodies=three_bodies(), parameters=PARAMETERS, engine="pymunk")
    before = load_trajectory(path)  # as a kill before the first frame would leave it
    assert before.status == "running" and before.position.shape == (0, 3, 2)
    writer.close()
    after = load_trajectory(path)
    assert after.status == "complete" and after.engine == "pymunk"
    assert after.position.shape == (0, 3, 2) and after.angle.shape == (0, 3)
    assert "frames     0" in summarize(path)


def test_summarize_mentions_engine_bodies_and_frame_count(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    write(path, frames(N_FRAMES), engine="pymunk").close(wall_time=0.25)
    text = summarize(path)
    assert "pymunk" in text
    assert "3 (2 dynamic, 1 static)" in text
    assert f"frames     {N_FRAMES} (steps 0..8" in text
    assert "three" in text  # the scene name
    assert "complete" in text
    for name in ("kinetic_energy", "total_energy", "linear_momentum", "contact_count"):
        assert name in text
    assert "substeps" in text
    assert "0.0166667 s" in text  # dt from steps and times


def test_body_lookup_names_close_matches(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    write(path, frames(1)).close()
    traj = load_trajectory(path)
    assert traj.body("ball") == 1
    with pytest.raises(KeyError, match="'crate'"):
        traj.body("crat")


def test_append_rejects_wrong_shapes_and_changed_observables(tmp_path: Path) -> None:
    path = tmp_path / "t.h5"
    data = frames(3)
    writer = write(path, data[:1])
    bad = dict(data[1], position=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="position"):
        writer.append(**bad)
    renamed = dict(data[1], observables={**data[1]["observables"], "extra": 1.0})
    with pytest.raises(ValueError, match="extra"):
        writer.append(**renamed)
    fractional = dict(data[1], observables={**data[1]["observables"], "contact_count": 2.5})
    with pytest.raises(ValueError, match="contact_count"):
        writer.append(**fractional)
    writer.append(**data[1])
    writer.close()
    assert len(load_trajectory(path).step) == 2


def test_writer_refuses_parameters_it_owns(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="status"):
        TrajectoryWriter(
            tmp_path / "t.h5", bodies=three_bodies(), parameters={**PARAMETERS, "status": "x"}
        )
