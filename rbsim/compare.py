"""`rbsim compare`: the same scene in rbsim and in pymunk, and the differences between them.

Both engines write a trajectory in the same H5MD layout (DESIGN.md), with frames at the
same steps (0, every output.every-th, the last). pymunk takes steps of the same length as
rbsim's substeps (PymunkSettings.substeps = solver.substeps), so that a difference comes
from the methods, not from the step length. The differences are read back from the two
files: per body the largest and the final distance between the body origins (m), the
largest and final angle difference (rad) and the largest difference of the centre-of-mass
velocities (m/s). Tolerances (the scene's `compare:` block, overridden by options) bound
the largest differences over the whole run; a quantity without a tolerance is not checked.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .model import build
from .pymunk_bridge import PymunkSettings, PymunkWorld
from .run import body_table, parameters, run_scene
from .scene import Scene
from .trajectory import Trajectory, TrajectoryWriter, load_trajectory

__all__ = ["BodyDiff", "CompareResult", "QUANTITIES", "compare_scene", "run_pymunk_to_file"]

# Checked quantity -> (BodyDiff field it bounds, unit, words for messages)
QUANTITIES: dict[str, tuple[str, str, str]] = {
    "position": ("max_position", "m", "position difference"),
    "angle": ("max_angle", "rad", "angle difference"),
    "velocity": ("max_velocity", "m/s", "velocity difference"),
}

TABLE_ROWS = 10  # bodies shown in the table when there are more


@dataclass
class BodyDiff:
    """Differences rbsim - pymunk for one body over the run: positions of the body origin
    (m), angles (rad), centre-of-mass velocities (m/s); `*_step` is where the max is."""

    name: str
    max_position: float
    final_position: float
    max_angle: float
    final_angle: float
    max_velocity: float
    max_position_step: int
    max_angle_step: int
    max_velocity_step: int


@dataclass
class CompareResult:
    """What `rbsim compare` reports. energy: total kinetic + potential at the end (J);
    momentum: linear momentum at the end (kg·m/s); us_per_step: wall time per scene step
    in stepping alone (µs); violations: one message per checked quantity over tolerance."""

    scene: str
    steps: int
    bodies: list[BodyDiff]
    tolerances: dict[str, float]
    energy: dict[str, float]
    momentum: dict[str, list[float]]
    us_per_step: dict[str, float]
    files: dict[str, str]
    pymunk_settings: dict
    violations: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.violations

    def worst(self, limit: int = TABLE_ROWS) -> list[BodyDiff]:
        """The bodies to show: all when at most `limit`, else the `limit` worst by max
        position difference."""
        if len(self.bodies) <= limit:
            return list(self.bodies)
        return sorted(self.bodies, key=lambda b: b.max_position, reverse=True)[:limit]

    def to_dict(self) -> dict:
        """A JSON-ready dict: the same numbers as the table (every body), plus "ok"."""
        return {
            "ok": self.ok,
            "scene": self.scene,
            "steps": self.steps,
            "tolerances": dict(self.tolerances),
            "bodies": [dataclasses.asdict(b) for b in self.bodies],
            "energy": dict(self.energy),
            "linear_momentum": {k: list(v) for k, v in self.momentum.items()},
            "us_per_step": dict(self.us_per_step),
            "files": dict(self.files),
            "pymunk_settings": dict(self.pymunk_settings),
            "violations": list(self.violations),
        }

    def table(self) -> str:
        """The human-readable report."""
        shown = self.worst()
        lines = [f"{self.scene}: rbsim against pymunk, {self.steps} steps"]
        if len(shown) < len(self.bodies):
            lines[0] += f" ({len(shown)} worst of {len(self.bodies)} bodies by position)"
        width = max([4, *(len(b.name) for b in shown)])
        head = (
            f"  {'body':<{width}}  {'pos max m':>10}  {'pos end m':>10}  {'ang max rad':>11}"
            f"  {'ang end rad':>11}  {'vel max m/s':>11}"
        )
        lines.append(head)
        for b in shown:
            lines.append(
                f"  {b.name:<{width}}  {b.max_position:>10.3g}  {b.final_position:>10.3g}  "
                f"{b.max_angle:>11.3g}  {b.final_angle:>11.3g}  {b.max_velocity:>11.3g}"
            )
        tol = ", ".join(f"{k} {v:g} {QUANTITIES[k][1]}" for k, v in self.tolerances.items())
        lines.append(f"  tolerance: {tol or 'none (nothing checked)'}")
        lines.append("")
        lines.append(f"  {'at the end':<22}  {'rbsim':>14}  {'pymunk':>14}")
        lines.append(
            f"  {'energy (KE + PE) J':<22}  {self.energy['rbsim']:>14.6g}  "
            f"{self.energy['pymunk']:>14.6g}"
        )
        for axis, k in (("x", 0), ("y", 1)):
            lines.append(
                f"  {'momentum ' + axis + ' kg m/s':<22}  {self.momentum['rbsim'][k]:>14.6g}  "
                f"{self.momentum['pymunk'][k]:>14.6g}"
            )
        lines.append(
            f"  {'wall time / step µs':<22}  {self.us_per_step['rbsim']:>14.2f}  "
            f"{self.us_per_step['pymunk']:>14.2f}"
        )
        lines.append(f"  files: {self.files['rbsim']}, {self.files['pymunk']}")
        lines.append("  ok" if self.ok else "  OUTSIDE TOLERANCE")
        return "\n".join(lines)


def pymunk_settings_for(scene: Scene, iterations: int | None = None) -> PymunkSettings:
    """pymunk steps as long as rbsim's substeps; `iterations` per pymunk step (default
    PymunkSettings' own)."""
    settings = PymunkSettings(substeps=int(scene.solver.substeps))
    if iterations is not None:
        settings.iterations = int(iterations)
    return settings


def run_pymunk_to_file(scene: Scene, out: str | Path, settings: PymunkSettings) -> float:
    """Step `scene` in pymunk and write its trajectory to `out` (engine "pymunk"), with
    frames at rbsim's steps: 0, every output.every-th and the last. Returns the wall time
    (s) spent in pymunk's space.step. Raises UnsupportedScene before creating the file
    when pymunk cannot express the scene."""
    t0 = time.perf_counter()
    world = PymunkWorld(scene, settings)
    model, _state = build(scene)
    table = body_table(scene, model)
    arrays = world.body_table_arrays()  # pymunk's own mass properties
    table = dataclasses.replace(
        table,
        mass=arrays["mass"],
        moment_of_inertia=arrays["moment_of_inertia"],
        center_of_mass=arrays["center_of_mass"],
    )
    writer = TrajectoryWriter(
        out,
        bodies=table,
        parameters=parameters(scene, "pymunk", dataclasses.asdict(settings)),
        engine="pymunk",
    )
    total, every = int(scene.world.steps), int(scene.output.every)
    status = "failed"

    def frame() -> None:
        st = world.read_state()
        writer.append(
            world.step_count,
            world.step_count * world.dt,
            st["position"],
            st["orientation"],
            st["angle"],
            st["velocity"],
            st["angular_velocity"],
            world.observables(),
        )

    try:
        frame()
        while world.step_count < total:
            world.step()
            if world.step_count % every == 0 or world.step_count == total:
                frame()
        status = "complete"
    except KeyboardInterrupt:
        status = "interrupted"
        raise
    except Exception as err:
        status = f"failed: {type(err).__name__}: {err}"
        raise
    finally:
        writer.close(status=status, wall_time=time.perf_counter() - t0)
    return world.wall_time


def _angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| for unwrapped angles (rad); both engines start from the scene's angle, so
    the unwrapped difference is the physical one (a whole extra turn counts)."""
    return np.abs(a - b)


def body_diffs(ra: Trajectory, pm: Trajectory) -> list[BodyDiff]:
    """Per-body differences between two trajectories with the same frames and bodies."""
    if not np.array_equal(ra.step, pm.step):
        raise ValueError("the two trajectories have different frames")
    dpos = np.linalg.norm(ra.position - pm.position, axis=2)  # (T, N)
    dang = _angle_diff(ra.angle, pm.angle)
    dvel = np.linalg.norm(ra.velocity - pm.velocity, axis=2)
    out = []
    for i, name in enumerate(ra.bodies.name):
        ip, ia, iv = (
            int(np.argmax(dpos[:, i])),
            int(np.argmax(dang[:, i])),
            int(np.argmax(dvel[:, i])),
        )
        out.append(
            BodyDiff(
                name=name,
                max_position=float(dpos[ip, i]),
                final_position=float(dpos[-1, i]),
                max_angle=float(dang[ia, i]),
                final_angle=float(dang[-1, i]),
                max_velocity=float(dvel[iv, i]),
                max_position_step=int(ra.step[ip]),
                max_angle_step=int(ra.step[ia]),
                max_velocity_step=int(ra.step[iv]),
            )
        )
    return out


def violations(bodies: list[BodyDiff], tolerances: dict[str, float]) -> list[str]:
    """One message per body and checked quantity above its tolerance (NaN counts)."""
    found = []
    for b in bodies:
        for key, tol in tolerances.items():
            attr, unit, words = QUANTITIES[key]
            value = getattr(b, attr)
            if not value <= tol:
                step = getattr(b, attr + "_step")
                found.append(
                    f"body {b.name!r}: max {words} {value:.4g} {unit} at step {step} "
                    f"exceeds the {key} tolerance {tol:g} {unit}"
                )
    return found


def tolerances_for(scene: Scene, **options: float | None) -> dict[str, float]:
    """The scene's compare: block overridden by the options that are given."""
    tol = {k: float(v) for k, v in scene.compare.items() if k in QUANTITIES and v is not None}
    for key, value in options.items():
        if key not in QUANTITIES:
            raise KeyError(f"unknown tolerance {key!r}")
        if value is not None:
            tol[key] = float(value)
    return {k: tol[k] for k in QUANTITIES if k in tol}


def _warm_up(scene: Scene) -> None:
    """Take one step of the scene on a throwaway World, so that loading (or compiling)
    rbsim's kernels is not counted in its wall time per step."""
    from .world import World

    World.from_scene(scene).advance(1)


def compare_scene(
    scene: Scene,
    out_dir: str | Path = "out/compare",
    *,
    position: float | None = None,
    angle: float | None = None,
    velocity: float | None = None,
    iterations: int | None = None,
) -> CompareResult:
    """Run `scene` in rbsim and pymunk, writing out_dir/<name>.rbsim.h5 and
    out_dir/<name>.pymunk.h5, and compare them. Raises UnsupportedScene (pymunk cannot
    express the scene) before running either engine, and whatever run_scene raises."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    settings = pymunk_settings_for(scene, iterations)
    PymunkWorld(scene, settings)  # UnsupportedScene before any work
    files = {
        "rbsim": str(out_dir / f"{scene.name}.rbsim.h5"),
        "pymunk": str(out_dir / f"{scene.name}.pymunk.h5"),
    }
    _warm_up(scene)
    summary = run_scene(scene, files["rbsim"])
    pm_wall = run_pymunk_to_file(scene, files["pymunk"], settings)
    ra, pm = load_trajectory(files["rbsim"]), load_trajectory(files["pymunk"])
    bodies = body_diffs(ra, pm)
    tol = tolerances_for(scene, position=position, angle=angle, velocity=velocity)
    steps = int(scene.world.steps)

    def energy(tr: Trajectory) -> float:
        return float(tr.observables["kinetic_energy"][-1] + tr.observables["potential_energy"][-1])

    def per_step(seconds: float) -> float:
        return 1e6 * seconds / steps if steps else math.nan

    return CompareResult(
        scene=scene.name,
        steps=steps,
        bodies=bodies,
        tolerances=tol,
        energy={"rbsim": energy(ra), "pymunk": energy(pm)},
        momentum={
            "rbsim": [float(x) for x in ra.observables["linear_momentum"][-1]],
            "pymunk": [float(x) for x in pm.observables["linear_momentum"][-1]],
        },
        us_per_step={"rbsim": per_step(summary.step_time), "pymunk": per_step(pm_wall)},
        files=files,
        pymunk_settings=dataclasses.asdict(settings),
        violations=violations(bodies, tol),
    )
