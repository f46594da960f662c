"""Run a scene: step the world and append frames to a trajectory as they are computed.

An interruption (KeyboardInterrupt, which the CLI also raises on SIGTERM) closes the
file with every frame so far and status "interrupted"; a non-finite state closes it
with status "failed" and names the body and step.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from . import __version__
from .model import Model, body_origin
from .observables import observables
from .scene import Scene, scene_to_dict
from .trajectory import BodyTable, TrajectoryWriter
from .world import NonFiniteState, World

# at most this many steps between returns to Python, so Ctrl-C and progress stay lively
MAX_CHUNK = 256


class RunFailed(RuntimeError):
    """The state turned non-finite; the message names the body and the step."""


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
        return (
            f"{self.steps} steps, {self.bodies} bodies, {self.frames} frames in "
            f"{self.wall_time:.2f} s ({rate:,.0f} steps/s) -> {self.path}"
        )


def body_table(scene: Scene, model: Model) -> BodyTable:
    """Static per-body data for the trajectory file (body frame, SI units)."""
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
        mass=model.body_mass.copy(),
        moment_of_inertia=model.body_inertia.copy(),
        center_of_mass=model.body_com.copy(),
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


def write_frame(writer: TrajectoryWriter, world: World) -> None:
    """Append the world's current state as one frame."""
    model, state = world.model, world.state
    writer.append(
        world.step_index,
        world.time,
        body_origin(model, state),
        state.body_q,
        state.body_angle,
        state.body_v,
        state.body_w,
        observables(model, state, world.contact_count),
    )


def run_scene(
    scene: Scene,
    out: str | Path,
    progress: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """Step `scene` for world.steps steps, writing frames to `out` (HDF5, H5MD layout).

    Step 0 and every output.every-th step are written, and the last step always.
    progress(step, total) is called after each chunk of steps. Raises RunFailed on a
    non-finite state and re-raises KeyboardInterrupt; the file is valid either way.
    """
    t0 = time.perf_counter()
    world = World.from_scene(scene)
    total = scene.world.steps
    every = scene.output.every
    step_time = 0.0
    writer = TrajectoryWriter(
        out, bodies=body_table(scene, world.model), parameters=parameters(scene, "rbsim")
    )
    status = "interrupted"
    try:
        write_frame(writer, world)
        while world.step_index < total:
            to_frame = every - world.step_index % every
            n = min(to_frame, total - world.step_index, MAX_CHUNK)
            ts = time.perf_counter()
            try:
                world.advance(n)
            except NonFiniteState as err:
                name = scene.bodies[err.body].name
                status = f"failed: body {name!r} became non-finite at step {err.step}"
                write_frame(writer, world)
                raise RunFailed(
                    f"{scene.path}: the state of body {name!r} became non-finite at step "
                    f"{err.step} (t = {err.step * scene.world.dt:g} s); "
                    f"{writer.frames_written} frames kept in {out}"
                ) from None
            step_time += time.perf_counter() - ts
            if world.step_index % every == 0 or world.step_index == total:
                write_frame(writer, world)
            if progress is not None:
                progress(world.step_index, total)
        status = "complete"
    finally:
        writer.close(status=status, wall_time=time.perf_counter() - t0)
    return RunSummary(
        steps=world.step_index,
        bodies=len(scene.bodies),
        frames=writer.frames_written,
        wall_time=time.perf_counter() - t0,
        step_time=step_time,
        path=str(out),
    )
