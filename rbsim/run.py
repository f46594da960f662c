"""Run a scene: step the world and append frames to a trajectory as they are computed.

An interruption (SIGINT, i.e. Ctrl-C, and any other signal the caller names, such as
SIGTERM) closes the file with every frame so far and status "interrupted", and lands
between two frames, never inside one; a non-finite state closes it with status
"failed", keeps the (finite) frames before it and names the body and step.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import signal
import sys
import threading
import time
import types
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import contextmanager
from contextlib import suppress as contextlib_suppress
from dataclasses import asdict, dataclass
from pathlib import Path
from types import FrameType

import numpy as np

from . import __version__, ctrlc
from .engines import DEFAULT_ENGINE, Engine, NonFiniteState, TooManyPairs, make_engine
from .io.trajectory import (
    BLOCK_MAX_FRAMES,
    CHECKPOINT_SUFFIX,
    OBSERVABLES,
    STATUS_RUNNING,
    TRAJECTORY_ID,
    BodyTable,
    FixedBodies,
    LayoutStopped,
    Trajectory,
    TrajectoryError,
    TrajectoryWriter,
    frame_count,
    load_trajectory,
    observables_spec,
    open_for_reading,
    read_checkpoint,
    read_parameters,
)
from .scene import Scene, load_scene_text, scene_to_dict
from .scene.schema import counted

# wall time (s) the engine steps between returns to Python, so that Ctrl-C, progress
# and flushes stay lively; the frames per call adapt to it
CHUNK_SECONDS = 0.1
# The engine's checkpoint goes beside the file with a flush (once a second) only when the
# time since the last one is at least CHECKPOINT_SHARE_INVERSE times what that one took,
# so that a large world (a checkpoint of a 40,000-circle pile: 2 GB, seconds to write)
# spends at most a tenth of its run on checkpoints; and a run stopped by a signal saves
# its last state only when the last checkpoint took under CHECKPOINT_STOP_SECONDS (s)
# and is at most CHECKPOINT_STOP_BYTES, so that it ends within a second (else the last
# flush's checkpoint stays beside it): a write's time is not steady (the 195 MB checkpoint
# of a pile of 40,000 circles took 0.2 s at a flush, then 1.3 - 2.3 s written into the
# closed file, a shared machine's disk holding back its new pages).
# Before a first one is timed, a checkpoint is expected to take its size over
# CHECKPOINT_BYTES_PER_SECOND (B/s; measured 0.25-0.5 GB/s taking it, on a shared 2-core
# machine).
CHECKPOINT_SHARE_INVERSE = 10.0
CHECKPOINT_STOP_SECONDS = 0.3
CHECKPOINT_STOP_BYTES = 50e6
CHECKPOINT_BYTES_PER_SECOND = 2.5e8


# The most bytes of a file name made from a scene name (`name:` may be any length): the
# file systems' 255 (NAME_MAX) less the longest suffix rbsim adds to it, with room to
# spare (".mujoco.h5.tmp-<pid>", ".rbsim.h5.resume.tmp": about 22). A 300-character name
# failed the run with "File name too long".
NAME_BYTES_MAX = 200
NAME_DIGEST_DIGITS = 12  # hex digits of the name's SHA-256 that keep shortened names apart


def file_stem(name: str) -> str:
    """The scene name as the stem of the files named after it (out/<stem>.h5, compare's
    and sweep's): the name itself, or, longer than NAME_BYTES_MAX bytes of UTF-8, its
    first bytes (whole characters) and the start of its SHA-256, "<head>-<12 hex>"."""
    raw = name.encode("utf-8")
    if len(raw) <= NAME_BYTES_MAX:
        return name
    import hashlib

    digest = hashlib.sha256(raw).hexdigest()[:NAME_DIGEST_DIGITS]
    head = raw[: NAME_BYTES_MAX - NAME_DIGEST_DIGITS - 1].decode("utf-8", "ignore")
    return f"{head}-{digest}"


def _frames(n: int) -> str:
    return counted(n, "frame")


def system_reason(err: OSError) -> str:
    """The system's short reason for an OSError ("No space left on device"), else its
    text (h5py's wording around the reason is long)."""
    return os.strerror(err.errno) if err.errno else str(err)


class WriteFailed(OSError):
    """Writing the trajectory failed (a full disk, a vanished folder): errno and strerror
    are the OSError's; `path` the trajectory, `frames` the frames its file keeps (None:
    no file was written, or an existing one left as it was) and `marked` whether the
    file's status says failed. str() says what was kept."""

    def __init__(self, err: OSError, path: str, frames: int | None, marked: bool) -> None:
        super().__init__(err.errno, system_reason(err))
        self.path, self.frames, self.marked = path, frames, marked

    def kept(self) -> str:
        """What the run leaves on disk, in words."""
        if self.frames is None:
            if os.path.exists(self.path):
                return "nothing was written (the file is as it was)"
            return "nothing was kept (no trajectory was written)"
        status = "status failed" if self.marked else "its status could not be updated"
        if self.frames == 0:
            return f"nothing was kept: the file holds no frame ({status})"
        # a checkpoint is made at the flushes, the first about a second into the run
        if os.path.exists(self.path + CHECKPOINT_SUFFIX):
            then = "once there is room, rbsim run --resume finishes it"
        else:
            then = "no checkpoint was made yet: once there is room, run it again"
        return f"the file keeps {_frames(self.frames)} ({status}); {then}"

    def __str__(self) -> str:
        return f"cannot write {self.path}: {self.strerror}; {self.kept()}"


class RunFailed(RuntimeError):
    """The state turned non-finite (or a body flew off, or an observable overflowed);
    the message names the body or the observable, and the step."""


class OutputBusy(RunFailed):
    """Another live process is writing the trajectory (a run or a resume of it)."""


class OutputLock:
    """The lock of a trajectory `path` while a run or a resume writes it: an exclusive
    flock on PATH.lock beside it, which the kernel drops with the process (a killed run
    leaves none held; its file, left behind, is taken again). Two runs into one file
    wrote it both (the later one's layout replaced the earlier run's without a word), and
    a file still being written could be resumed. Raises OutputBusy when another process
    holds it, OSError when the lock file cannot be made (a read-only folder)."""

    def __init__(self, path: str | Path) -> None:
        self.path = f"{path}.lock"
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OutputBusy(
                    f"another rbsim process is writing {path} (a run or a resume of it): "
                    f"wait for it to end, or write elsewhere with -o"
                ) from None
            # the holder removes the lock file as it ends: ours must be the one there now
            try:
                here = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                here = False
            if here:
                self.fd = fd
                return
            os.close(fd)

    def __enter__(self) -> OutputLock:
        return self

    def __exit__(self, *exc: object) -> None:
        with contextlib_suppress(OSError):
            os.unlink(self.path)
        os.close(self.fd)


class ObservableOverflow(RuntimeError):
    """An observable of a frame (such as the kinetic energy) is inf or NaN: `name`, at
    `step`."""

    def __init__(self, name: str, step: int) -> None:
        super().__init__(f"{name} overflowed at step {step}")
        self.name = name
        self.step = step


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (or another of run_scene's `signals`, such as SIGTERM) during a run. The
    trajectory at `path` is closed with status "interrupted" and holds `frames` frames,
    the last at `step`."""

    def __init__(self, path: str, frames: int, step: int) -> None:
        super().__init__(f"interrupted: {_frames(frames)} kept in {path}, the last at step {step}")
        self.path = path
        self.frames = frames
        self.step = step


class _Interrupts:
    """Turns `signals` that arrive during a run into a KeyboardInterrupt at a point where
    the trajectory file is consistent.

    A KeyboardInterrupt raised straight from a signal handler can land anywhere: inside
    a frame being written, or inside a weakref callback or __del__, where Python prints
    "Exception ignored" and carries on as if nothing happened (the run would then go on
    to the end). So once the first steps have been taken, a signal only sets a flag that
    `check` turns into a KeyboardInterrupt; the run checks before and after every call
    of the engine (about CHUNK_SECONDS), and the compiled engine asks `pending` between
    two of its steps (every 20 ms) and returns early, with every frame so far recorded.
    Before the first check (building the model: seconds without a check), and for a
    second signal, the handler raises at once, except inside `held` (writing a frame or
    closing the file).

    Handlers are installed only from the main thread, and only for signals whose current
    handler was set from Python and is not SIG_IGN (a run started with Ctrl-C ignored,
    as `nohup` and background jobs of scripts do, keeps ignoring it).
    """

    def __init__(self, signals: Collection[signal.Signals]) -> None:
        self.signals = signals
        self.received = 0  # signals received so far
        self.stepping = False  # True once the first steps are done
        self.holding = False

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.received += 1
        if not self.holding and (not self.stepping or self.received > 1):
            raise KeyboardInterrupt

    def check(self) -> None:
        """Raise KeyboardInterrupt if a signal has arrived. Called after each chunk of
        steps; from the first call on, a first signal waits for the next call."""
        self.stepping = True
        if self.received:
            raise KeyboardInterrupt

    def pending(self) -> bool:
        """Whether a signal has arrived (for an engine to ask between its steps)."""
        return self.received > 0

    @contextmanager
    def held(self) -> Iterator[None]:
        """No KeyboardInterrupt from a signal inside the block (it is still counted)."""
        self.holding = True
        try:
            yield
        finally:
            self.holding = False

    @contextmanager
    def installed(self) -> Iterator[None]:
        """Handle `signals` inside the block; the previous handlers are restored after."""
        previous = {}
        if threading.current_thread() is threading.main_thread():
            for signum in self.signals:
                handler = signal.getsignal(signum)
                if handler is not None and handler != signal.SIG_IGN:
                    previous[signum] = signal.signal(signum, self._handle)
        try:
            if signal.SIGINT in previous:
                ctrlc.raise_if_arrived()  # one lost before (rbsim.ctrlc) stops the run now
            yield
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


@dataclass
class RunSummary:
    """What a finished run reports: steps taken, bodies, frames written, wall time (s)
    of the whole run, of set-up (reading the scene, building the engine, creating the
    file, the first frame: from process start when known) and of stepping and writing
    (the loop), the engine's own stepping time (s), and the output path."""

    steps: int
    bodies: int
    frames: int
    wall_time: float
    step_time: float
    path: str
    setup_time: float = 0.0
    loop_time: float = 0.0
    steps_run: int = 0  # steps taken by this process (less than `steps` after a resume)

    def line(self) -> str:
        """The one-line summary `rbsim run` prints: set-up apart from stepping, and the
        stepping rate (steps this process took per second of its loop)."""
        taken = self.steps_run or self.steps
        rate = taken / self.loop_time if self.loop_time > 0 else float("inf")
        bodies = counted(self.bodies, "body", "bodies")
        return (
            f"{counted(self.steps, 'step')}, {bodies}, {_frames(self.frames)} in "
            f"{self.wall_time:.2f} s "
            f"(set-up {self.setup_time:.2f} s, stepping {self.loop_time:.2f} s at "
            f"{rate:,.0f} steps/s) -> {self.path}"
        )


def process_start() -> float | None:
    """time.perf_counter() at which this process started (Linux), or None."""
    try:
        with open("/proc/self/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        started = int(fields[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None
    return time.perf_counter() - max(0.0, uptime - started)


def frame_steps(total: int, every: int) -> int:
    """Frames a complete run writes: step 0, every `every`-th step, and the last."""
    return total // every + 1 + (1 if total % every else 0)


def dimension(scene: Scene) -> int:
    """The scene's world dimension, 2 or 3."""
    return int(scene.world.dimension)


def body_table(scene: Scene, engine: Engine) -> BodyTable:
    """Static per-body data for the trajectory file (body frame, SI units), with the
    engine's own mass properties; in 3D with each shape's faces and plane normal."""
    d = dimension(scene)
    shape_body, kinds, radius, start, count, verts = [], [], [], [], [], []
    face_start, face_count, faces, normals = [], [], [], []
    for i, body in enumerate(scene.bodies):
        for shape in body.shapes:
            shape_body.append(i)
            kinds.append(shape.kind)
            radius.append(shape.radius)
            start.append(len(verts))
            count.append(len(shape.vertices))
            verts.extend(shape.vertices)
            if d == 3:
                face_start.append(len(faces))
                face_count.append(len(shape.faces))
                faces.extend(shape.faces)
                normals.append(shape.normal if len(shape.normal) else (0.0, 0.0, 0.0))
    extra = {}
    if d == 3:
        extra = {
            "shape_face_start": np.asarray(face_start, np.int32),
            "shape_face_count": np.asarray(face_count, np.int32),
            "shape_faces": np.asarray(faces, np.int32).reshape(-1, 3),
            "shape_normal": np.asarray(normals, np.float64).reshape(-1, 3),
            "dimension": 3,
        }
    return BodyTable(
        name=[b.name for b in scene.bodies],
        type=[b.type for b in scene.bodies],
        mass=engine.mass.copy(),
        moment_of_inertia=engine.inertia.copy(),
        center_of_mass=engine.com_local.copy(),
        shape_body=np.asarray(shape_body, np.int32),
        shape_kind=kinds,
        shape_radius=np.asarray(radius, np.float64),
        shape_vertex_start=np.asarray(start, np.int32),
        shape_vertex_count=np.asarray(count, np.int32),
        shape_vertices=np.asarray(verts, np.float64).reshape(-1, d),
        **extra,
    )


def parameters(scene: Scene, engine: str, settings: dict | None = None) -> dict[str, str]:
    """/parameters/rbsim entries: scene text, resolved scene, solver settings, version."""
    solver = asdict(scene.solver) if settings is None else settings
    return {
        "scene": scene.source,
        "scene_path": str(scene.path),
        "resolved_scene": json.dumps(scene_to_dict(scene)),
        "solver": json.dumps(solver),
        "rbsim_version": __version__,
        "engine": engine,
    }


def output_layout(
    scene: Scene, engine: Engine
) -> tuple[BodyTable, np.ndarray | None, FixedBodies | None]:
    """The bodies written in every frame (their table, their engine rows or None for
    all) and the static bodies stored once, as the scene's output.bodies asks."""
    table = body_table(scene, engine)
    names = [b.name for b in scene.bodies]
    types = [b.type for b in scene.bodies]
    chosen = scene.output.body_indices(names, types)
    if len(chosen) == len(names):
        return table, None, None
    keep = set(chosen)
    fixed_rows = [i for i, t in enumerate(types) if t == "static" and i not in keep]
    fixed = None
    if fixed_rows:
        s = engine.read()
        fixed = FixedBodies(
            bodies=table.subset(fixed_rows),
            position=s.origin[fixed_rows],
            orientation=s.orientation[fixed_rows],
            angle=s.angle[fixed_rows] if dimension(scene) == 2 else None,
        )
    return table.subset(chosen), np.asarray(chosen, np.intp), fixed


def run_scene(
    scene: Scene,
    out: str | Path,
    progress: Callable[[int, int], None] | None = None,
    signals: Collection[signal.Signals] = (signal.SIGINT,),
    engine: str = DEFAULT_ENGINE,
    options: dict | None = None,
    overrides: Sequence[str] = (),
    started: float | None = None,
    flush_seconds: float = 1.0,
) -> RunSummary:
    """Step `scene` for world.steps steps, writing frames to `out` (HDF5, H5MD layout).

    Step 0 and every output.every-th step are written, and the last step always; the
    file also follows output.precision, output.compression and output.bodies. Frames are
    gathered in blocks and written at least every `flush_seconds` of wall time, each time
    with the engine's checkpoint beside the file (OUT.h5.resume), so that a killed run
    keeps its frames up to the last flush and `resume_run` can continue it.
    progress(step, total) is called after each chunk of steps (about CHUNK_SECONDS). The
    file is closed and valid however the run ends: on a non-finite state it keeps the
    frames before that step, with status "failed: ...", and RunFailed is raised; when
    one of `signals` (or a KeyboardInterrupt) stops the run it keeps every frame so far,
    with status "interrupted" and the checkpoint inside, and RunInterrupted (a
    KeyboardInterrupt) is raised; an error writing the file raises OSError with the
    frames flushed so far kept. Interrupted before the file is created (while the model
    is built), KeyboardInterrupt propagates as it is. `engine`: one of engines.ENGINES
    ("rbsim", the compiled engine; "pymunk"), built with `options` (pymunk: {"settings":
    PymunkSettings(...)}). `overrides`: the --set lines the scene was loaded with
    (recorded for --resume). `started`: time.perf_counter() when the run began (for the
    set-up time; default: now). The summary's step_time is the engine's own (pymunk:
    inside space.step only).
    """
    t0 = time.perf_counter() if started is None else started
    interrupts = _Interrupts(signals)
    try:
        lock = OutputLock(out)
    except OSError as err:  # nothing written: the file is as it was, or absent
        raise WriteFailed(err, str(out), None, False) from err
    with lock, interrupts.installed():
        world = make_engine(engine, scene, **(options or {}))
        params = parameters(scene, engine, world.settings or None)
        params["overrides"] = json.dumps(list(overrides))
        with interrupts.held():
            try:
                writer = _writer(
                    scene, world, out, params, engine, flush_seconds, keep=0, started=t0
                )
            except OSError as err:  # nothing written: the file is as it was, or absent
                raise WriteFailed(err, str(out), None, False) from err
        return _loop(scene, world, writer, interrupts, progress, t0, first_frame=True)


def _writer(
    scene: Scene,
    world: Engine,
    path: str | Path,
    params: dict[str, str],
    engine: str,
    flush_seconds: float,
    keep: int,
    started: float | None = None,
    wall_before: float = 0.0,
) -> TrajectoryWriter:
    """The trajectory writer of a run of `scene` (its output options) into `path`,
    keeping the first `keep` frames of the file there (resume); its wall time counts
    from `started` and adds `wall_before` (the earlier segments' of a resumed run)."""
    bodies, select, fixed = output_layout(scene, world)
    contacts = scene.output.contacts == "points" and world.records_contacts
    contact_bodies = None
    if contacts and select is not None:
        # a contact names its bodies by their rows in the file: the bodies written in
        # every frame, then the static ones stored once, -1 for one not stored
        contact_bodies = np.full(len(scene.bodies), -1, np.int64)
        contact_bodies[select] = np.arange(len(select))
        if fixed is not None:
            rows = [i for i, b in enumerate(scene.bodies) if b.name in set(fixed.bodies.name)]
            contact_bodies[rows] = len(select) + np.arange(len(rows))
    return TrajectoryWriter(
        path,
        bodies=bodies,
        parameters=params,
        engine=engine,
        flush_seconds=flush_seconds,
        frames=frame_steps(scene.world.steps, scene.output.every),
        precision=scene.output.precision,
        compression=scene.output.compression,
        select=select,
        block_bodies=len(scene.bodies),
        fixed=fixed,
        observables=observables_spec(dimension(scene)),
        keep=keep,
        contacts=contacts,
        contact_bodies=contact_bodies,
        started=started,
        wall_before=wall_before,
    )


def _loop(
    scene: Scene,
    world: Engine,
    writer: TrajectoryWriter,
    interrupts: _Interrupts,
    progress: Callable[[int, int], None] | None,
    t0: float,
    first_frame: bool,
) -> RunSummary:
    """Step `world` to the scene's last step, recording frames into `writer`'s blocks,
    and close the writer however the loop ends (see run_scene)."""
    total = scene.world.steps
    # an `every` past the last step writes what `every = total` does (step 0 and the last),
    # and stays within the engine's integer range however large the scene's number is
    every = min(scene.output.every, max(total, 1))
    out = writer.path
    status = "failed"  # made precise below
    checkpoint: bytes | None = None
    checkpoint_step = -1  # the step of `checkpoint`
    keep_sidecar = False  # the checkpoint file beside the trajectory stays
    checkpoint_cost = -1.0  # s the last checkpoint took (taking it and writing it)
    checkpoint_made = -math.inf  # time.perf_counter() when it was made

    def checkpoint_expected() -> float:
        """s the next checkpoint should take."""
        if checkpoint_cost >= 0.0:
            return checkpoint_cost
        return world.checkpoint_size() / CHECKPOINT_BYTES_PER_SECOND

    start_step = world.step_index
    loop_start = time.perf_counter()
    setup = loop_start - t0
    last_step = start_step
    frames_per_call = 1
    committed_step = start_step
    try:
        if first_frame:
            with interrupts.held():
                world.record(writer.block, writer.rows)
                _good, overflow = _finite_rows(writer.block, writer.rows, 1)
                if overflow is not None:
                    raise overflow
                writer.commit(1, write_when_full=False)
        while world.step_index < total:
            cur = world.step_index
            if writer.room == 0:
                # the file's room is full: laid out anew with twice as much (a copy of the
                # frames, seconds for a large file, that a signal stops, the file as it was)
                with interrupts.held():
                    writer.make_room(interrupts.pending)
            k = max(1, min(writer.rows_free, writer.room, frames_per_call))
            target = min((cur // every + k) * every, total)
            interrupts.check()
            call = time.perf_counter()
            # the engine asks between its steps whether a signal came (the handler only
            # counts it), and stops there with every frame so far recorded
            taken, written, err = world.advance_recording(
                target - cur, every, total, writer.block, writer.rows, interrupts.pending
            )
            elapsed = time.perf_counter() - call
            with interrupts.held():
                good, overflow = _finite_rows(writer.block, writer.rows, written)
                writer.commit(good, write_when_full=False)
                committed_step = world.step_index
            if overflow is not None:
                raise overflow
            if good:
                last_step = int(writer.block["step"][writer.rows - 1 if writer.rows else -1])
            if written:
                per_frame = elapsed / written
                frames_per_call = max(
                    1, min(BLOCK_MAX_FRAMES, int(CHUNK_SECONDS / max(per_frame, 1e-9)))
                )
            if err is not None:
                raise err
            if writer.flush_due():  # frames, and the engine's checkpoint when it is due
                with interrupts.held():
                    now = time.perf_counter()
                    if now - checkpoint_made >= CHECKPOINT_SHARE_INVERSE * checkpoint_expected():
                        # a signal drops the checkpoint's write midway (the last one stays)
                        writer.flush(world.checkpoint(), world.step_index, interrupts.pending)
                        checkpoint_made = time.perf_counter()
                        checkpoint_cost = checkpoint_made - now
                    else:
                        writer.flush()
            elif writer.rows_free == 0:  # a full block: its frames only
                with interrupts.held():
                    writer.write_block()
            interrupts.check()
            if progress is not None:
                progress(world.step_index, total)
        status = "complete"
    except NonFiniteState as err:  # from a step, or from reading a frame (pymunk)
        name = repr(scene.bodies[err.body].name)
        what = err.describe(name)
        status = f"failed: {what.removeprefix('the state of ')} at step {err.step}"
        raise RunFailed(
            f"{scene.path}: {what} at step {err.step} (t = {err.step * scene.world.dt:g} s); "
            f"{_frames(writer.frames_written)} before it kept in {out}"
        ) from None
    except TooManyPairs as err:  # shapes pressed into one another beyond the pair bound
        status = f"failed: {err}"
        raise RunFailed(
            f"{scene.path}: {err} (t = {(err.step + 1) * scene.world.dt:g} s): shapes pressed into "
            f"one another; {_frames(writer.frames_written)} before it kept in {out}"
        ) from None
    except ObservableOverflow as err:
        status = f"failed: {err.name} overflowed at step {err.step}"
        raise RunFailed(
            f"{scene.path}: the {err.name.replace('_', ' ')} overflowed (inf or NaN) at "
            f"step {err.step} (t = {err.step * scene.world.dt:g} s); "
            f"{_frames(writer.frames_written)} before it kept in {out}"
        ) from None
    except KeyboardInterrupt:
        status = "interrupted"
        slow = (
            checkpoint_expected() > CHECKPOINT_STOP_SECONDS
            or world.checkpoint_size() > CHECKPOINT_STOP_BYTES
        )
        if world.torn or slow:
            # a long step stopped inside, or a checkpoint too slow to take and write now:
            # the last flush's checkpoint stays beside the file, to resume from
            keep_sidecar = True
        elif world.step_index == committed_step:  # every frame up to this state is kept
            checkpoint, checkpoint_step = world.checkpoint(), world.step_index
        raise RunInterrupted(str(out), writer.frames_written, last_step) from None
    except OSError as err:  # writing the file: a full disk, a vanished folder
        status = f"failed: {system_reason(err)}"
        marked = writer.abandon(status)
        raise WriteFailed(err, str(out), writer.frames_flushed, marked) from err
    except Exception as err:
        if status == "failed":  # not the non-finite state: an error writing, or a bug
            status = f"failed: {type(err).__name__}: {err}"
        raise
    finally:
        # the final layout (a copy of the frames: a complete run's compression, seconds for
        # a large file; a stopped run's, at most STOP_COPY_BYTES) stops at a signal, and a
        # stopped run's at a second one, the file closed in place with every frame as
        # the run wrote them, to resume; a failed run's is copied whole
        stop_layout: Callable[[], bool] | None = None
        if status == "complete":
            stop_layout = interrupts.pending
        elif status == "interrupted":
            stop_layout = lambda: interrupts.received > 1  # noqa: E731
        with interrupts.held():
            try:
                writer.close(  # the wall time since t0, the file's last write included
                    status=status,
                    checkpoint=checkpoint,
                    checkpoint_step=checkpoint_step,
                    keep_sidecar=keep_sidecar,
                    stop=stop_layout,
                )
            except LayoutStopped:
                raise RunInterrupted(str(out), writer.frames_written, last_step) from None
            except OSError as err:  # the last frames or the final layout
                failed = f"failed: {system_reason(err)}"
                marked = writer.abandon(failed)
                if status == "complete":
                    raise WriteFailed(err, str(out), writer.frames_flushed, marked) from err
    loop = time.perf_counter() - loop_start
    # this process's part of the recorded wall time (all of it but for a resume)
    wall = writer.wall_time - writer.wall_before
    return RunSummary(
        steps=world.step_index,
        bodies=len(scene.bodies),
        frames=writer.frames_written,
        wall_time=wall if math.isfinite(wall) else time.perf_counter() - t0,
        step_time=world.step_time,
        path=str(out),
        setup_time=setup,
        loop_time=loop,
        steps_run=world.step_index - start_step,
    )


def _finite_rows(
    block: dict[str, np.ndarray], row: int, count: int
) -> tuple[int, ObservableOverflow | None]:
    """Of the `count` frames just recorded in `block` from `row` on: how many lead with
    finite observables, and the ObservableOverflow of the first that does not (None)."""
    first, culprit = count, None
    if count == 0:
        return 0, None
    for name in OBSERVABLES:
        rows = block[name][row : row + count].reshape(count, -1)
        bad = np.flatnonzero(~np.isfinite(rows).all(axis=1))
        if bad.size and bad[0] < first:
            first, culprit = int(bad[0]), name
    if culprit is None:
        return count, None
    return first, ObservableOverflow(culprit, int(block["step"][row + first]))


class ResumeError(ValueError):
    """A trajectory that cannot be resumed: complete, not rbsim's, or without a checkpoint."""


def resume_run(
    path: str | Path,
    progress: Callable[[int, int], None] | None = None,
    signals: Collection[signal.Signals] = (signal.SIGINT,),
    started: float | None = None,
    flush_seconds: float = 1.0,
) -> RunSummary:
    """Continue the interrupted or killed run whose trajectory is `path`, from its last
    checkpoint (in the file for a run stopped by a signal or a failure, beside it as
    PATH.resume for a killed one): the scene is rebuilt from the text and --set lines
    the file records, the engine restored, and the frames after the checkpoint are
    written as an uninterrupted run would have written them, bit for bit. Raises
    ResumeError when the file cannot be resumed; otherwise as run_scene."""
    t0 = time.perf_counter() if started is None else started
    path = str(path)
    with OutputLock(path):
        return _resume_locked(path, progress, signals, t0, flush_seconds)


def _resume_locked(
    path: str,
    progress: Callable[[int, int], None] | None,
    signals: Collection[signal.Signals],
    t0: float,
    flush_seconds: float,
) -> RunSummary:
    """resume_run with its trajectory's lock held."""
    try:
        with open_for_reading(path) as f:
            params = read_parameters(f)
            inside = f.get("parameters/rbsim/checkpoint")
            stored = bytes(inside[()].tobytes()) if inside is not None else None
            on_file = frame_count(f, closed=params.get("status", STATUS_RUNNING) != STATUS_RUNNING)
    except TrajectoryError as err:
        raise ResumeError(str(err)) from None
    status = params.get("status", "")
    if "scene" not in params or params.get("engine") is None:
        raise ResumeError(f"{path}: not an rbsim trajectory (no scene recorded)")
    if status == "complete":
        raise ResumeError(f"{path}: the run is complete; there is nothing to resume")
    frames, step, data = -1, -1, b""
    sidecar = read_checkpoint(path + CHECKPOINT_SUFFIX)
    foreign = sidecar is not None and sidecar[3] != params.get(TRAJECTORY_ID, "")
    if foreign:  # written by another run at this path (a new run removes it; a copy?)
        sidecar = None
    # the checkpoint beside the file: a killed run's, or an interrupted one's whose long
    # step was stopped inside (the file then holds none)
    if sidecar is not None and (status == STATUS_RUNNING or stored is None):
        frames, step, data, _owner = sidecar
    elif stored is not None:
        frames, step, data = on_file, -1, stored
    if not data:
        other = f"; {path}{CHECKPOINT_SUFFIX} is another run's checkpoint" if foreign else ""
        raise ResumeError(
            f"{path}: no checkpoint to resume from (status {status!r}; a run killed before "
            f"its first flush, or one that failed, starts again with rbsim run){other}"
        )
    if frames > on_file:
        raise ResumeError(
            f"{path}: the checkpoint is ahead of the file ({frames} > {on_file} frames)"
        )
    overrides = json.loads(params.get("overrides", "[]"))
    scene = load_scene_text(params["scene"], params.get("scene_path", path), overrides)
    engine = params["engine"]
    interrupts = _Interrupts(signals)
    with interrupts.installed():
        world = make_engine(engine, scene)
        try:
            world.restore(data)
        except ValueError as err:  # the engine's check: not a checkpoint of this scene
            raise ResumeError(f"{path}: {err}") from None
        if step >= 0 and world.step_index != step:
            raise ResumeError(f"{path}: the checkpoint is at step {world.step_index}, not {step}")
        try:  # the earlier segments' (to the last flush of a killed one; none: 0)
            before = max(float(params.get("wall_time", "")), 0.0)
        except ValueError:
            before = 0.0
        before = before if math.isfinite(before) else 0.0
        params = {k: v for k, v in params.items() if k not in ("status", "wall_time", "checkpoint")}
        params["resumed"] = str(int(params.get("resumed", "0")) + 1)
        with interrupts.held():
            writer = _writer(scene, world, path, params, engine, flush_seconds, frames, t0, before)
        return _loop(scene, world, writer, interrupts, progress, t0, first_frame=False)


def run(
    scene: Scene | str | os.PathLike | dict,
    out: str | os.PathLike | None = None,
    overrides: str | Sequence[str] = (),
) -> Trajectory:
    """Run a scene and return its trajectory (rbsim.io.trajectory.Trajectory) in memory.

    scene: a Scene, a path to a YAML file (str or Path), YAML text, or a dict of the
    scene format. out: a .h5 file to write as well (kept); by default a temporary file,
    removed once read. overrides: --set lines ("world.dt=0.005"), or one such string.
    Raises rbsim.scene.SceneError for an invalid scene, RunFailed for a non-finite state
    and TypeError for overrides that are not strings."""
    import tempfile

    from .scene import load_scene, override_lines

    overrides = override_lines(overrides)

    if isinstance(scene, Scene):
        sc = scene
    elif isinstance(scene, dict):
        import yaml

        sc = load_scene_text(yaml.safe_dump(scene, sort_keys=False), "<dict>", overrides)
    elif isinstance(scene, os.PathLike) or (
        isinstance(scene, str) and "\n" not in scene and ":" not in scene
    ):
        sc = load_scene(scene, overrides)
    else:
        sc = load_scene_text(str(scene), "<string>", overrides)
    if out is not None:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        run_scene(sc, out, overrides=overrides)
        return load_trajectory(out)
    with tempfile.TemporaryDirectory(prefix="rbsim-") as folder:
        path = os.path.join(folder, "run.h5")
        run_scene(sc, path, overrides=overrides)
        return load_trajectory(path)


class _Module(types.ModuleType):
    """rbsim.run, the module, is callable: `rbsim.run(scene)` works whether the name is
    the package's function or (once imported) this module."""

    def __call__(
        self,
        scene: Scene | str | os.PathLike | dict,
        out: str | os.PathLike | None = None,
        overrides: str | Sequence[str] = (),
    ) -> Trajectory:
        return run(scene, out, overrides)


sys.modules[__name__].__class__ = _Module
