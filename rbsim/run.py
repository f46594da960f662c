"""Run a scene: step the world and append frames to a trajectory as they are computed.

An interruption (SIGINT, i.e. Ctrl-C, and any other signal the caller names, such as
SIGTERM) closes the file with every frame so far and status "interrupted", and lands
between two frames, never inside one; a non-finite state closes it with status
"failed", keeps the (finite) frames before it and names the body and step.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from types import FrameType

import numpy as np

from . import __version__
from .engines import DEFAULT_ENGINE, Engine, NonFiniteState, make_engine
from .io.trajectory import BodyTable, TrajectoryWriter
from .scene import Scene, scene_to_dict

# Steps are taken in chunks of about CHUNK_SECONDS (s) of wall time between returns to
# Python (for progress, and for Ctrl-C with an engine that cannot run the signal
# handlers between its steps itself), sized from the last chunk's rate: from 1 step,
# growing at most twofold per chunk, never above MAX_CHUNK steps. Chunking does not
# change the steps taken.
CHUNK_SECONDS = 0.1
MAX_CHUNK = 1 << 20


def _frames(n: int) -> str:
    return f"{n} frame" if n == 1 else f"{n} frames"


class RunFailed(RuntimeError):
    """The state turned non-finite (or a body flew off, or an observable overflowed);
    the message names the body or the observable, and the step."""


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
    `check` turns into a KeyboardInterrupt; the run checks before and after every chunk
    of steps (about CHUNK_SECONDS). Inside `engine(True)` (the compiled engine, which runs
    the handlers between two of its steps) the handler raises at once: the chunk stops
    after the step under way. Before the first check (building the model: seconds
    without a check), and for a second signal, the handler raises at once too, except
    inside `held` (writing a frame or closing the file).

    Handlers are installed only from the main thread, and only for signals whose current
    handler was set from Python and is not SIG_IGN (a run started with Ctrl-C ignored,
    as `nohup` and background jobs of scripts do, keeps ignoring it).
    """

    def __init__(self, signals: Collection[signal.Signals]) -> None:
        self.signals = signals
        self.received = 0  # signals received so far
        self.stepping = False  # True once the first steps are done
        self.holding = False
        self.in_engine = False  # inside an engine that takes a KeyboardInterrupt between steps

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.received += 1
        if not self.holding and (not self.stepping or self.received > 1 or self.in_engine):
            raise KeyboardInterrupt

    def check(self) -> None:
        """Raise KeyboardInterrupt if a signal has arrived. Called after each chunk of
        steps; from the first call on, a first signal waits for the next call."""
        self.stepping = True
        if self.received:
            raise KeyboardInterrupt

    @contextmanager
    def engine(self, interruptible: bool) -> Iterator[None]:
        """Inside the block, with ``interruptible`` (an engine whose advance runs the
        signal handlers between steps and stops at the exception), a signal raises at once."""
        self.in_engine = interruptible
        try:
            yield
        finally:
            self.in_engine = False

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
            yield
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


@dataclass
class RunSummary:
    """What a finished run reports: steps taken, bodies, frames written, wall time (s)
    of the whole run and of stepping alone, and the output path."""

    steps: int
    bodies: int
    frames: int
    wall_time: float
    step_time: float
    path: str

    def line(self) -> str:
        """The one-line summary `rbsim run` prints."""
        rate = self.steps / self.wall_time if self.wall_time > 0 else float("inf")
        bodies = "1 body" if self.bodies == 1 else f"{self.bodies} bodies"
        return (
            f"{self.steps} steps, {bodies}, {_frames(self.frames)} in "
            f"{self.wall_time:.2f} s ({rate:,.0f} steps/s) -> {self.path}"
        )


def body_table(scene: Scene, engine: Engine) -> BodyTable:
    """Static per-body data for the trajectory file (body frame, SI units), with the
    engine's own mass properties."""
    shape_body, kinds, radius, start, count, verts = [], [], [], [], [], []
    for i, body in enumerate(scene.bodies):
        for shape in body.shapes:
            shape_body.append(i)
            kinds.append(shape.kind)
            radius.append(shape.radius)
            start.append(len(verts))
            count.append(len(shape.vertices))
            verts.extend(shape.vertices)
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
        shape_vertices=np.asarray(verts, np.float64).reshape(-1, 2),
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


def write_frame(writer: TrajectoryWriter, world: Engine) -> None:
    """Append the engine's current state as one frame. An observable that overflows (a
    state racing towards infinity) raises ObservableOverflow (without a numpy warning)
    and the frame is not written."""
    s = world.read()
    with np.errstate(over="ignore", invalid="ignore"):
        obs = world.observables()
    for name, value in obs.items():
        if not np.all(np.isfinite(value)):
            raise ObservableOverflow(name, world.step_index)
    writer.append(
        world.step_index,
        world.time,
        s.origin,
        s.orientation,
        s.angle,
        s.velocity,
        s.angular_velocity,
        obs,
    )


def run_scene(
    scene: Scene,
    out: str | Path,
    progress: Callable[[int, int], None] | None = None,
    signals: Collection[signal.Signals] = (signal.SIGINT,),
    engine: str = DEFAULT_ENGINE,
    options: dict | None = None,
) -> RunSummary:
    """Step `scene` for world.steps steps, writing frames to `out` (HDF5, H5MD layout).

    Step 0 and every output.every-th step are written, and the last step always.
    progress(step, total) is called after each chunk of steps. The file is closed and
    valid however the run ends: on a non-finite state (or a body beyond the engine's
    region, or an observable that overflows) it keeps the frames before that step, with
    status "failed: ...", and RunFailed is raised; when one of `signals`
    (or a KeyboardInterrupt) stops the run it keeps every frame so far, with status
    "interrupted", and RunInterrupted (a KeyboardInterrupt) is raised. Interrupted
    before the file is created (while the model is built), KeyboardInterrupt propagates
    as it is. See _Interrupts for when a signal takes effect. `engine`: one of
    engines.ENGINES ("rbsim", the compiled engine; "pymunk"), built with
    `options` (pymunk: {"settings": PymunkSettings(...)}). The summary's step_time is
    the engine's own (pymunk: inside space.step only).
    """
    t0 = time.perf_counter()
    interrupts = _Interrupts(signals)
    with interrupts.installed():
        world = make_engine(engine, scene, **(options or {}))
        total = scene.world.steps
        every = scene.output.every
        with interrupts.held():
            writer = TrajectoryWriter(
                out,
                bodies=body_table(scene, world),
                parameters=parameters(scene, engine, world.settings or None),
                engine=engine,
            )
        status = "failed"  # made precise below
        last_step = 0
        try:
            with interrupts.held():
                write_frame(writer, world)
            chunk = 1  # steps per chunk, from the last chunk's rate
            interruptible = getattr(world, "interruptible", False)
            while world.step_index < total:
                to_frame = every - world.step_index % every
                n = min(to_frame, total - world.step_index, chunk)
                interrupts.check()
                started = time.perf_counter()
                with interrupts.engine(interruptible):
                    world.advance(n)
                elapsed = time.perf_counter() - started
                fit = int(n * CHUNK_SECONDS / elapsed) if elapsed > 0 else MAX_CHUNK
                chunk = max(1, min(MAX_CHUNK, 2 * chunk, fit))
                interrupts.check()
                if world.step_index % every == 0 or world.step_index == total:
                    with interrupts.held():
                        write_frame(writer, world)
                        last_step = world.step_index
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
        except ObservableOverflow as err:
            status = f"failed: {err.name} overflowed at step {err.step}"
            raise RunFailed(
                f"{scene.path}: the {err.name.replace('_', ' ')} overflowed (inf or NaN) at "
                f"step {err.step} (t = {err.step * scene.world.dt:g} s); "
                f"{_frames(writer.frames_written)} before it kept in {out}"
            ) from None
        except KeyboardInterrupt:
            status = "interrupted"
            raise RunInterrupted(str(out), writer.frames_written, last_step) from None
        except Exception as err:
            if status == "failed":  # not the non-finite state: an error writing, or a bug
                status = f"failed: {type(err).__name__}: {err}"
            raise
        finally:
            with interrupts.held():
                writer.close(status=status, wall_time=time.perf_counter() - t0)
    return RunSummary(
        steps=world.step_index,
        bodies=len(scene.bodies),
        frames=writer.frames_written,
        wall_time=time.perf_counter() - t0,
        step_time=world.step_time,
        path=str(out),
    )
