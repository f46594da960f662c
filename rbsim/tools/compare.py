"""`rbsim compare`: the same scene in rbsim and in pymunk, and the differences between them.

Both engines write a trajectory in the same H5MD layout (DESIGN.md), with frames at the
same steps (0, every output.every-th, the last). pymunk takes steps of the same length as
rbsim's substeps (PymunkSettings.substeps = solver.substeps), so that a difference comes
from the methods, not from the step length. The differences are read back from the two
files: per body the largest and the final distance between the body origins (m), the
largest and final angle difference (rad) and the largest difference of the centre-of-mass
velocities (m/s). Tolerances (the scene's `compare:` block, overridden by options) bound
the largest differences over the whole run; a quantity without a tolerance is not checked.

Chaotic scenes (a pyramid collapsing, a billiards break) amplify any difference between
the engines until single trajectories no longer correspond; they are compared by
statistics of the whole run instead (`compare: {statistics: ...}` or `--statistics`):
final kinetic energy, the mean and the distribution of the dynamic bodies' final heights,
and the largest overlap of two shapes in each run, measured with pymunk's own collision
queries on both trajectories (one ruler for both engines).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engines import make_engine
from ..engines.pymunk import PymunkSettings, PymunkWorld, UnsupportedScene
from ..io.trajectory import Trajectory, load_trajectory
from ..run import run_scene
from ..scene import Scene

__all__ = [
    "BodyDiff",
    "CompareResult",
    "QUANTITIES",
    "STATISTICS",
    "compare_scene",
    "max_penetration",
    "run_pymunk_to_file",
    "statistics",
]

# Checked quantity -> (BodyDiff field it bounds, unit, words for messages)
QUANTITIES: dict[str, tuple[str, str, str]] = {
    "position": ("max_position", "m", "position difference"),
    "angle": ("max_angle", "rad", "angle difference"),
    "velocity": ("max_velocity", "m/s", "velocity difference"),
}

# Statistic -> (unit, words for the table and messages); see `statistics`.
STATISTICS: dict[str, tuple[str, str]] = {
    "kinetic_energy": ("J", "final kinetic energy"),
    "mean_height": ("m", "final mean height"),
    "heights": ("m", "final heights: spread | sorted gap"),
    "penetration": ("m", "max penetration (whole run)"),
}

TABLE_ROWS = 10  # bodies shown in the table when there are more

# Frames on which the penetration is measured (evenly spread; every frame when fewer):
# each costs one pymunk shape query per dynamic shape.
PENETRATION_FRAMES = 400


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
    statistics: dict[str, dict[str, float]] | None = None
    statistics_tolerances: dict[str, float] = field(default_factory=dict)

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
            "statistics": None if self.statistics is None else dict(self.statistics),
            "statistics_tolerances": dict(self.statistics_tolerances),
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
        if self.statistics is not None:
            lines.append("")
            lines.append(
                f"  {'statistics':<34}  {'rbsim':>11}  {'pymunk':>11}  {'difference':>11}"
                f"  {'tolerance':>9}"
            )
            for key, (unit, words) in STATISTICS.items():
                st = self.statistics[key]
                tol = self.statistics_tolerances.get(key)
                lines.append(
                    f"  {words + ' ' + unit:<34}  {st['rbsim']:>11.4g}  {st['pymunk']:>11.4g}"
                    f"  {st['difference']:>11.4g}  {'-' if tol is None else f'{tol:g}':>9}"
                )
        lines.append(f"  files: {self.files['rbsim']}, {self.files['pymunk']}")
        lines.append("  ok" if self.ok else "  OUTSIDE TOLERANCE")
        return "\n".join(lines)


def pymunk_settings_for(scene: Scene, iterations: int | None = None) -> PymunkSettings:
    """pymunk steps as long as rbsim's substeps; `iterations` per pymunk step (default:
    the scene's compare.iterations, else PymunkSettings' own)."""
    settings = PymunkSettings(substeps=int(scene.solver.substeps))
    if iterations is None:
        iterations = scene.compare.get("iterations")
    if iterations is not None:
        settings.iterations = int(iterations)
    return settings


def run_pymunk_to_file(scene: Scene, out: str | Path, settings: PymunkSettings) -> float:
    """Step `scene` in pymunk and write its trajectory to `out` (engine "pymunk"), with
    frames at rbsim's steps: 0, every output.every-th and the last. Returns the wall time
    (s) spent in pymunk's space.step. Raises UnsupportedScene before creating the file
    when pymunk cannot express the scene."""
    summary = run_scene(scene, out, engine="pymunk", options={"settings": settings})
    return summary.step_time


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


def _up(scene: Scene) -> np.ndarray:
    """Unit vector against gravity (the y axis when there is none)."""
    g = np.asarray(scene.world.gravity, dtype=float)
    norm = float(np.hypot(*g))
    return -g / norm if norm > 0.0 else np.array([0.0, 1.0])


def final_heights(tr: Trajectory, scene: Scene) -> np.ndarray:
    """Heights (m) of the dynamic bodies' centres of mass at the last frame, measured
    against gravity (along y when there is none), in scene order."""
    dynamic = np.array([b.type == "dynamic" for b in scene.bodies], dtype=bool)
    c, sn = tr.orientation[-1, :, 0], tr.orientation[-1, :, 1]
    com = tr.bodies.center_of_mass
    x = tr.position[-1] + np.stack(
        [c * com[:, 0] - sn * com[:, 1], sn * com[:, 0] + c * com[:, 1]], axis=1
    )
    return x[dynamic] @ _up(scene)


def max_penetration(tr: Trajectory, scene: Scene, frames: int = PENETRATION_FRAMES) -> float:
    """Largest overlap (m) of two shapes of different bodies, at least one dynamic, over
    the frames of `tr` (at most `frames` of them, evenly spread, the first and the last
    included). Measured with pymunk's collision queries, so that both engines' runs are
    measured with the same ruler; 0 when nothing overlaps."""
    geometry = PymunkWorld(scene, PymunkSettings(mixing_handler="auto"))
    space, bodies = geometry.space, geometry.bodies
    moving = [i for i, b in enumerate(scene.bodies) if b.type != "static"]
    queried = [
        (pb, shape)
        for i, pb in enumerate(bodies)
        if scene.bodies[i].type == "dynamic"
        for shape in pb.shapes
    ]
    count = len(tr.step)
    picks = np.unique(np.linspace(0, count - 1, min(count, max(frames, 2))).round().astype(int))
    deepest = 0.0
    for t in picks:
        for i in moving:
            pb = bodies[i]
            pb.angle = float(tr.angle[t, i])
            pb.position = (float(tr.position[t, i, 0]), float(tr.position[t, i, 1]))
            space.reindex_shapes_for_body(pb)
        for pb, shape in queried:
            for info in space.shape_query(shape):
                if info.shape is None or info.shape.body is pb:
                    continue
                for point in info.contact_point_set.points:
                    deepest = max(deepest, -point.distance)
    return deepest


def statistics(ra: Trajectory, pm: Trajectory, scene: Scene) -> dict[str, dict[str, float]]:
    """Statistics of the two runs: statistic -> {"rbsim", "pymunk", "difference"}.

    kinetic_energy: total at the last frame (J). mean_height: mean final height of the
    dynamic bodies' centres of mass (m). heights: per engine the spread (standard
    deviation) of the final heights, and as the difference the distance between the two
    distributions, the mean gap between the sorted heights (the 1-Wasserstein distance;
    body identities do not matter) (m). penetration: the
    largest overlap of two shapes over the run (m); its difference is the larger of
    the two, which is what a penetration tolerance bounds.
    """
    out: dict[str, dict[str, float]] = {}
    ke = [float(tr.observables["kinetic_energy"][-1]) for tr in (ra, pm)]
    out["kinetic_energy"] = {"rbsim": ke[0], "pymunk": ke[1], "difference": abs(ke[0] - ke[1])}
    h_ra, h_pm = final_heights(ra, scene), final_heights(pm, scene)
    mean = [float(h.mean()) if h.size else 0.0 for h in (h_ra, h_pm)]
    out["mean_height"] = {"rbsim": mean[0], "pymunk": mean[1], "difference": abs(mean[0] - mean[1])}
    gap = float(np.abs(np.sort(h_ra) - np.sort(h_pm)).mean()) if h_ra.size else 0.0
    spread = [float(h.std()) if h.size else 0.0 for h in (h_ra, h_pm)]
    out["heights"] = {"rbsim": spread[0], "pymunk": spread[1], "difference": gap}
    pen = [max_penetration(tr, scene) for tr in (ra, pm)]
    out["penetration"] = {"rbsim": pen[0], "pymunk": pen[1], "difference": max(pen)}
    return out


def statistics_violations(
    stats: dict[str, dict[str, float]], tolerances: dict[str, float]
) -> list[str]:
    """One message per statistic above its tolerance (NaN counts)."""
    found = []
    for key, tol in tolerances.items():
        unit, words = STATISTICS[key]
        st = stats[key]
        if key == "penetration":
            for engine in ("rbsim", "pymunk"):
                if not st[engine] <= tol:
                    found.append(
                        f"statistics: {words} {st[engine]:.4g} {unit} in {engine} exceeds "
                        f"the penetration tolerance {tol:g} {unit}"
                    )
        elif not st["difference"] <= tol:
            found.append(
                f"statistics: {words}: rbsim {st['rbsim']:.6g} {unit}, pymunk "
                f"{st['pymunk']:.6g} {unit}, difference {st['difference']:.4g} {unit} "
                f"exceeds the {key} tolerance {tol:g} {unit}"
            )
    return found


def _same_run(scene: Scene, other: Scene) -> None:
    """Raise UnsupportedScene unless `other` (pymunk's scene) has the same bodies, steps,
    step length and output frames as `scene`."""
    why = None
    if [b.name for b in scene.bodies] != [b.name for b in other.bodies]:
        why = "its bodies differ"
    elif (scene.world.steps, scene.world.dt) != (other.world.steps, other.world.dt):
        why = "its steps or dt differ"
    elif scene.output.every != other.output.every:
        why = "its output.every differs"
    elif scene.solver.substeps != other.solver.substeps:
        why = "its solver.substeps differ (pymunk's step length)"
    if why:
        raise UnsupportedScene(f"pymunk's scene must run the same frames as rbsim's: {why}")


def _warm_up(scene: Scene, engine: str) -> None:
    """Take one step of the scene on a throwaway world, so that loading rbsim's engine
    is not counted in its wall time per step."""
    make_engine(engine, scene).advance(1)


def compare_scene(
    scene: Scene,
    out_dir: str | Path = "out/compare",
    *,
    position: float | None = None,
    angle: float | None = None,
    velocity: float | None = None,
    iterations: int | None = None,
    with_statistics: bool = False,
    pymunk_scene: Scene | None = None,
    engine: str = "rbsim",
) -> CompareResult:
    """Run `scene` in rbsim and pymunk, writing out_dir/<name>.rbsim.h5 and
    out_dir/<name>.pymunk.h5, and compare them. Statistics (see `statistics`) are
    computed when `with_statistics` or the scene has a compare.statistics block.
    `pymunk_scene` (default `scene`) is what pymunk runs: the same scene with a setting
    changed, to see how much that setting matters. Raises UnsupportedScene (pymunk cannot
    express the scene) before running either engine, and whatever run_scene raises.
    `engine` is rbsim's side (engines.RBSIM_ENGINES)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pm_scene = scene if pymunk_scene is None else pymunk_scene
    _same_run(scene, pm_scene)
    settings = pymunk_settings_for(scene, iterations)
    make_engine("pymunk", pm_scene, settings=settings)  # UnsupportedScene before any work
    files = {
        "rbsim": str(out_dir / f"{scene.name}.rbsim.h5"),
        "pymunk": str(out_dir / f"{scene.name}.pymunk.h5"),
    }
    _warm_up(scene, engine)
    summary = run_scene(scene, files["rbsim"], engine=engine)
    pm_wall = run_pymunk_to_file(pm_scene, files["pymunk"], settings)
    ra, pm = load_trajectory(files["rbsim"]), load_trajectory(files["pymunk"])
    bodies = body_diffs(ra, pm)
    tol = tolerances_for(scene, position=position, angle=angle, velocity=velocity)
    steps = int(scene.world.steps)

    def energy(tr: Trajectory) -> float:
        return float(tr.observables["kinetic_energy"][-1] + tr.observables["potential_energy"][-1])

    stat_tol = {
        k: float(v)
        for k, v in (scene.compare.get("statistics") or {}).items()
        if k in STATISTICS and v is not None
    }
    wanted = with_statistics or "statistics" in scene.compare
    stats = statistics(ra, pm, scene) if wanted else None

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
        violations=violations(bodies, tol) + statistics_violations(stats or {}, stat_tol),
        statistics=stats,
        statistics_tolerances=stat_tol,
    )
