"""`rbsim sweep`: speed against error over a grid of settings, rbsim and pymunk.

Each setting runs the scene twice over: once for its error, sampling the poses of the
tracked bodies every `sample_dt` (the largest dt of the grid, which every dt of the grid
divides, so that all runs are compared at the same instants), and several times for its
cost, timing `advance` (rbsim's engine, loaded beforehand) or the
loop of `space.step` calls (pymunk) with the process's CPU clock. The cost is the
median CPU time per simulated second; building the world is not timed. The runs are
deterministic, so the timed runs follow the same motion as the sampled one.

The error is the reference's (rbsim.reference): the largest over the samples and the
tracked bodies of the RMS distance between the body's material points and the
reference's, in metres. Each engine's Pareto front is the set of its points that no
other point of the same engine beats in both cost and error.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
import textwrap
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ..engines import Engine, NonFiniteState, Snapshot, TooManyPairs, make_engine
from ..engines.pymunk import PymunkSettings
from ..run import file_stem
from ..scene import Scene
from ..scene import types as T
from ..scene.resolve import MAX_STEPS
from ..scene.schema import DT_MAX, DT_MIN, WORK_MAX, WORK_MAX_3D
from .measure import block_times, penetration, touching_pairs
from .reference import Poses, Reference, make_reference, pose_error

__all__ = [
    "DEFAULT_DTS",
    "Grid",
    "PlotUnavailable",
    "Point",
    "Pool",
    "RotationPoint",
    "RotationSweepResult",
    "SerialPool",
    "Setting",
    "SweepError",
    "SweepLimit",
    "SweepResult",
    "check_limits",
    "free_body_period",
    "pareto_front",
    "run_rotation_sweep",
    "run_sweep",
]

DEFAULT_DTS = (1 / 30, 1 / 60, 1 / 120, 1 / 240, 1 / 480, 1 / 960)

# Errors below this are rounding, not method (m): positions of order 10 m carry about
# 1e-15 m of rounding per operation, times up to 1e5 steps; they count as equal.
ERROR_FLOOR = 1e-9

# "Dominates": at least as accurate and at most this fraction of the CPU time.
DOMINANCE_TIME_RATIO = 0.5

# Timing: at least `repeats` runs, and more (up to MAX_REPEATS) until they add up to
# MIN_TIMED seconds, so that runs of a few milliseconds are not timer noise.
MIN_TIMED = 0.2
MAX_REPEATS = 100

# The sweep keeps what it samples in memory: in 2D every run's poses at every sample
# (about 56 B a body: t, x, θ, v, ω), all runs at once; in 3D one run's frames at every
# step (about 80 B a body). At most this many body-samples (2D, over every run) or
# body-steps (3D, one run): about 1 GB either way.
MAX_SAMPLED = 20_000_000  # 2D: samples x dynamic bodies x runs
MAX_RECORDED_3D = 10_000_000  # 3D: steps x bodies of one run

# Converged reference: by default dt is the grid's smallest over this factor.
CONVERGED_DT_FACTOR = 4
CONVERGED_SUBSTEPS = 4
CONVERGED_ITERATIONS = 8

# Shapes within this distance at the start are checked for penetration (invariants), m.
PAIR_MARGIN = 0.05


class SweepError(ValueError):
    """A sweep that cannot run as asked (grid, reference); the message says why."""


class SweepLimit(SweepError):
    """An option value outside the scene format's bounds (cli.md, "Bounds"): `option` is
    the option to name ("--dt", "--duration", ...), the message says which bound."""

    def __init__(self, option: str, message: str) -> None:
        super().__init__(message)
        self.option = option


class PlotUnavailable(RuntimeError):
    """matplotlib is not installed (the `plot` extra)."""


@dataclass(frozen=True)
class Setting:
    """One run's settings: engine "rbsim" or "pymunk"; dt (s); substeps; iterations (per
    substep for rbsim, per step for pymunk); integrator and rotation (rbsim only)."""

    engine: str
    dt: float
    substeps: int = 1
    iterations: int = 10
    integrator: str = ""
    rotation: str = ""

    @property
    def family(self) -> str:
        """The curve this setting belongs to (everything but dt)."""
        if self.engine == "pymunk":
            return f"pymunk it{self.iterations}"
        integ = {"symplectic_euler": "symp", "explicit_euler": "expl"}.get(
            self.integrator, self.integrator
        )
        rot = {"normalize": "norm"}.get(self.rotation, self.rotation)
        return f"rbsim s{self.substeps} it{self.iterations} {integ} {rot}"


def parse_list(text: str, kind: str) -> tuple:
    """A comma-separated option value: kind "dt" (seconds, numbers or fractions such as
    1/60), "int" (positive integers), or a tuple of allowed words. Raises SweepError."""
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise SweepError(f"expected a comma-separated list, got {text!r}")
    out = []
    for item in items:
        if kind == "dt":
            try:
                num, _, den = item.partition("/")
                value = float(num) / float(den) if den else float(num)
            except (ValueError, ZeroDivisionError):
                raise SweepError(f"{item!r} is not a time step (such as 1/60 or 0.01)") from None
            if not (value > 0 and math.isfinite(value)):
                raise SweepError(f"a time step must be a positive number of seconds, got {item!r}")
            # the scene format's world.dt bounds: each run is a scene with this dt
            if not DT_MIN <= value <= DT_MAX:
                raise SweepError(
                    f"a time step must be within {DT_MIN:g} s to {DT_MAX:g} s (as world.dt), "
                    f"got {item!r}"
                )
        elif kind == "int":
            if not item.isdigit() or int(item) < 1:
                raise SweepError(f"expected a positive integer, got {item!r}")
            value = int(item)
            # as solver.substeps and solver.iterations (and compare.iterations)
            if value > WORK_MAX:
                raise SweepError(f"expected at most {WORK_MAX:,}, got {item!r}")
        else:
            if item not in kind:
                raise SweepError(f"expected one of {', '.join(kind)}, got {item!r}")
            value = item
        out.append(value)
    return tuple(dict.fromkeys(out))  # without repeats, in order


def check_limits(
    scene: Scene, grid: Grid, duration: float | None, given: Sequence[str] = ()
) -> None:
    """Hold the sweep's runs to the scene format's bounds (cli.md, "Bounds"), as if each
    were a scene file: at most MAX_STEPS steps (the run's duration, s, over the grid's
    smallest dt, and over the converged reference's quarter of it), and at most the work
    of one step (shapes x substeps x iterations). `duration` (s): --duration, None for
    the scene's; `given`: the options on the command line, which the message names
    first. Raises SweepLimit naming the option to change."""
    dts = grid.dts or DEFAULT_DTS
    total = scene.world.steps * scene.world.dt if duration is None else float(duration)
    smallest = min(dts)
    option = "--duration" if duration is not None or "--dt" not in given else "--dt"
    where = f"{total:g} s" if duration is not None else f"the scene's {total:g} s"
    steps = total / smallest
    if steps > MAX_STEPS:
        raise SweepLimit(
            option,
            f"{where} at dt {dt_text(smallest)} s is {steps:.3g} steps, more than the "
            f"{MAX_STEPS:,} a scene may run (world.steps)",
        )
    dynamic = max(1, sum(b.type == "dynamic" for b in scene.bodies))
    if scene.world.dimension == 3:
        held = steps * len(scene.bodies)
        if held > MAX_RECORDED_3D:
            raise SweepLimit(
                option,
                f"{where} at dt {dt_text(smallest)} s records {steps:.3g} steps of "
                f"{len(scene.bodies):,} bodies in memory, more than the {MAX_RECORDED_3D:,} "
                "body-steps a run of the sweep may hold: a larger dt or a shorter --duration",
            )
    else:
        samples = max(1.0, total / max(dts))  # every largest dt
        runs = len(grid.settings()) + 2  # (and a converged reference's two)
        if samples * dynamic * runs > MAX_SAMPLED:
            raise SweepLimit(
                option,
                f"{where} sampled every {dt_text(max(dts))} s (the largest dt) is "
                f"{samples:.3g} samples of {dynamic:,} bodies in each of {runs} runs, more "
                f"than the {MAX_SAMPLED:,} body-samples the sweep may hold in memory: a "
                "shorter --duration, a larger largest --dt, or fewer settings",
            )
    spec = dict(getattr(scene, "reference", None) or {})
    converged = spec.get("kind", "converged") == "converged" and "dt" not in spec
    if converged and scene.world.dimension == 2:  # run_sweep's reference steps finer still
        fine = smallest / CONVERGED_DT_FACTOR
        if fine < DT_MIN:
            why = f"less than the {DT_MIN:g} s a world.dt may be"
        elif total / fine > MAX_STEPS:
            why = f"{total / fine:.3g} steps over {where}, more than {MAX_STEPS:,}"
        else:
            why = ""
        if why:
            raise SweepLimit(
                "--dt" if "--dt" in given else option,
                f"the converged reference steps at a quarter of the smallest dt, "
                f"{fine:.3g} s: {why} (the scene has no reference: with reference.dt "
                "it steps at that)",
            )
    shapes = sum(len(b.shapes) for b in scene.bodies)
    work_max = WORK_MAX_3D if scene.world.dimension == 3 else WORK_MAX
    substeps = max(grid.substeps, default=1)
    iterations = max(grid.iterations, default=1) if scene.world.dimension == 2 else 1
    if shapes * substeps * iterations > work_max:
        option = "--iterations" if "--iterations" in given else "--substeps"
        raise SweepLimit(
            option,
            f"a step would cost {shapes:,} shapes x {substeps:,} substeps x {iterations:,} "
            f"iterations, more than the {work_max:,} shape-iterations a scene may ask",
        )


def dt_text(dt: float) -> str:
    """1/60 for a dt whose inverse is a whole number, else %g (s)."""
    inv = 1.0 / dt
    return f"1/{round(inv)}" if abs(inv - round(inv)) < 1e-9 * inv else f"{dt:g}"


@dataclass(frozen=True)
class Grid:
    """The settings to sweep: every combination of dts with rbsim's substeps,
    iterations, integrators and rotations, and of dts with pymunk's iterations (none: no
    pymunk runs). rotations None: normalize and exact in 2D (split is exact there), all
    three in 3D (run_rotation_sweep)."""

    dts: tuple[float, ...] = DEFAULT_DTS
    substeps: tuple[int, ...] = (1, 4)
    iterations: tuple[int, ...] = (1, 4)
    integrators: tuple[str, ...] = ("symplectic_euler",)
    rotations: tuple[str, ...] | None = None
    pymunk_iterations: tuple[int, ...] = (5, 10, 30)

    def settings(self) -> list[Setting]:
        """Every setting of the grid, rbsim first, each family ordered by dt."""
        out = []
        for sub in self.substeps:
            for it in self.iterations:
                for integ in self.integrators:
                    for rot in self.rotations or ("normalize", "exact"):
                        for dt in sorted(self.dts, reverse=True):
                            out.append(Setting("rbsim", dt, sub, it, integ, rot))
        for it in self.pymunk_iterations:
            for dt in sorted(self.dts, reverse=True):
                out.append(Setting("pymunk", dt, 1, it))
        return out

    def sample_dt(self) -> float:
        """The largest dt (s), after checking that every dt divides it."""
        if not self.dts:
            raise SweepError("the grid has no dt")
        big = max(self.dts)
        for dt in self.dts:
            ratio = big / dt
            if abs(ratio - round(ratio)) > 1e-9 * ratio:
                raise SweepError(
                    f"dt {dt_text(dt)} s does not divide the largest dt {dt_text(big)} s; "
                    "errors are compared at multiples of the largest dt (use 1/30, 1/60, ...)"
                )
        return big


@dataclass
class Point:
    """One run of the sweep: its setting; cpu (median CPU s per simulated s) and
    us_per_step (µs); error (m, see rbsim.reference) with its parts position_error (m)
    and angle_error (rad); penetration (m) and energy_drift (J) for invariants
    references; status "ok" or why the run failed; front: on its engine's Pareto front."""

    setting: Setting
    cpu: float = math.nan
    us_per_step: float = math.nan
    error: float = math.inf
    position_error: float = math.inf
    angle_error: float = math.inf
    penetration: float | None = None
    energy_drift: float | None = None
    timed_runs: int = 0
    status: str = "ok"
    front: bool = False

    def row(self) -> dict:
        """A flat dict for CSV and JSON (units in the keys)."""
        s = self.setting
        return {
            "engine": s.engine,
            "family": s.family,
            "dt_s": s.dt,
            "substeps": s.substeps,
            "iterations": s.iterations,
            "integrator": s.integrator,
            "rotation": s.rotation,
            "cpu_s_per_sim_s": self.cpu,
            "us_per_step": self.us_per_step,
            "error_m": self.error,
            "position_error_m": self.position_error,
            "angle_error_rad": self.angle_error,
            "penetration_m": self.penetration,
            "energy_drift_J": self.energy_drift,
            "timed_runs": self.timed_runs,
            "status": self.status,
            "pareto_front": self.front,
        }


@dataclass
class SweepResult:
    """A whole sweep: the scene, what the error means, the points and the verdict."""

    scene: str
    path: str
    reference_kind: str
    reference: str
    metric: str
    duration: float
    sample_dt: float
    points: list[Point]
    reference_uncertainty: float | None = None
    notes: list[str] = field(default_factory=list)

    def engine_points(self, engine: str) -> list[Point]:
        return [p for p in self.points if p.setting.engine == engine]

    def verdict(self) -> dict:
        """Does rbsim dominate pymunk's front? For each pymunk front point, the fastest
        rbsim point at least as accurate, and whether it takes at most half the time."""
        rb = [p for p in self.engine_points("rbsim") if _finite(p)]
        rows = []
        for p in sorted(self.engine_points("pymunk"), key=lambda q: q.cpu):
            if not p.front:
                continue
            better = [r for r in rb if _floor(r.error) <= _floor(p.error)]
            best = min(better, key=lambda r: r.cpu) if better else None
            rows.append(
                {
                    "pymunk": p.setting.family + " dt " + dt_text(p.setting.dt),
                    "pymunk_cpu": p.cpu,
                    "pymunk_error_m": p.error,
                    "rbsim": (best.setting.family + " dt " + dt_text(best.setting.dt))
                    if best
                    else None,
                    "rbsim_cpu": best.cpu if best else None,
                    "rbsim_error_m": best.error if best else None,
                    "time_ratio": best.cpu / p.cpu if best else None,
                    "dominated": bool(best and best.cpu <= DOMINANCE_TIME_RATIO * p.cpu),
                }
            )
        return {
            "pymunk_front_points": len(rows),
            "dominated": sum(r["dominated"] for r in rows),
            "rbsim_dominates": bool(rows) and all(r["dominated"] for r in rows),
            "rows": rows,
        }

    def to_dict(self) -> dict:
        """JSON-ready: the header, every point and the verdict."""
        return {
            "scene": self.scene,
            "path": self.path,
            "reference_kind": self.reference_kind,
            "reference": self.reference,
            "reference_uncertainty_m": self.reference_uncertainty,
            "metric": self.metric,
            "duration_s": self.duration,
            "sample_dt_s": self.sample_dt,
            "cost": "median CPU time (s) per simulated second, compile and setup excluded",
            "notes": list(self.notes),
            "points": [p.row() for p in self.points],
            "verdict": self.verdict(),
        }

    def verdict_line(self) -> str:
        v = self.verdict()
        if not v["pymunk_front_points"]:
            return "verdict: no pymunk points"
        head = "rbsim dominates" if v["rbsim_dominates"] else "rbsim does NOT dominate"
        return (
            f"verdict: {head} pymunk's front: {v['dominated']} of {v['pymunk_front_points']} "
            f"pymunk front points have an rbsim point at least as accurate in at most "
            f"{DOMINANCE_TIME_RATIO:g} of the time"
        )

    def table(self) -> str:
        """The human-readable table."""
        lines = [
            f"{self.scene}: speed against error, {self.duration:g} s simulated, "
            f"errors sampled every {dt_text(self.sample_dt)} s",
            f"  reference: {self.reference}",
            f"  error: {self.metric}",
            "  cost: median CPU time per simulated second, compile and setup excluded",
        ]
        lines += [f"  note: {n}" for n in self.notes]
        width = max([6, *(len(p.setting.family) for p in self.points)])
        lines.append(
            f"  {'family':<{width}}  {'dt s':>7}  {'cpu ms/s':>10}  {'us/step':>9}  "
            f"{'error m':>9}  {'pos m':>9}  {'ang rad':>9}  front"
        )
        for p in self.points:
            s = p.setting
            mark = "*" if p.front else ""
            if p.status != "ok":
                mark = p.status
            elif self.reference_uncertainty is not None and p.error <= 2 * (
                self.reference_uncertainty
            ):
                mark += " (at the reference's uncertainty)"
            lines.append(
                f"  {s.family:<{width}}  {dt_text(s.dt):>7}  {1e3 * p.cpu:>10.4g}  "
                f"{p.us_per_step:>9.4g}  {p.error:>9.3g}  {p.position_error:>9.3g}  "
                f"{p.angle_error:>9.3g}  {mark}"
            )
        lines.append("  " + self.verdict_line())
        return "\n".join(lines)

    def write(self, out_dir: str | Path, plot: bool = True) -> dict[str, Path]:
        """Write <scene>.csv, <scene>.json and (plot=True) <scene>.png into out_dir;
        returns the paths written. Raises PlotUnavailable after writing CSV and JSON when
        matplotlib is missing."""
        return _write_files(self, out_dir, plot_sweep if plot else None)


def _write_files(
    result: SweepResult | RotationSweepResult,
    out_dir: str | Path,
    plot: Callable[[Any, Path], None] | None,
) -> dict[str, Path]:
    """<scene>.csv (a row per point), <scene>.json (result.to_dict()) and, with `plot`,
    <scene>.png into out_dir; the paths written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = file_stem(result.scene)
    paths = {"csv": out / f"{stem}.csv", "json": out / f"{stem}.json"}
    rows = [p.row() for p in result.points]
    with open(paths["csv"], "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["engine"])
        writer.writeheader()
        writer.writerows(rows)
    paths["json"].write_text(json.dumps(_jsonable(result.to_dict()), indent=2) + "\n")
    if plot is not None:
        paths["png"] = out / f"{stem}.png"
        plot(result, paths["png"])
    return paths


def _finite(p: Point) -> bool:
    return p.status == "ok" and math.isfinite(p.error) and math.isfinite(p.cpu)


def _floor(error: float) -> float:
    return max(error, ERROR_FLOOR)


def _jsonable(x):
    """NaN and infinity as null (JSON has neither)."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_jsonable(v) for v in x]
    return x


def pareto_front(points: Sequence[Point]) -> list[Point]:
    """The points no other point beats: faster and at least as accurate, or as fast and
    more accurate (errors below ERROR_FLOOR count as equal). Sorted by cost."""
    ok = sorted((p for p in points if _finite(p)), key=lambda p: (p.cpu, _floor(p.error)))
    front, best = [], math.inf
    for p in ok:
        if _floor(p.error) < best:
            front.append(p)
            best = _floor(p.error)
    return front


# --------------------------------------------------------------------------------------
# Running one setting


def scene_for(scene: Scene, s: Setting, steps: int) -> Scene:
    """The scene with the setting's dt, substeps, iterations, integrator and rotation."""
    solver = scene.solver
    if s.engine == "rbsim":
        solver = replace(
            solver,
            substeps=s.substeps,
            iterations=s.iterations,
            integrator=s.integrator or solver.integrator,
            rotation=s.rotation or solver.rotation,
        )
    else:
        solver = replace(solver, substeps=1)
    return replace(scene, world=replace(scene.world, dt=s.dt, steps=steps), solver=solver)


@dataclass
class _Sampled:
    poses: Poses
    penetration: float | None
    energy_drift: float | None
    status: str


class _Probe:
    """Reads what the error needs from a state given as centres of mass x (N,2) m, angles
    (N,) rad, velocities v (N,2) m/s and w (N,) rad/s."""

    def __init__(self, scene: Scene, ref: Reference) -> None:
        from ..scene.compile import build

        self.model, state = build(scene)
        self.bodies = np.array(ref.bodies, dtype=np.int64)
        self.invariants = ref.family == "invariants"
        self.pairs = (
            touching_pairs(self.model, state.body_x, state.body_angle, PAIR_MARGIN)
            if self.invariants
            else None
        )
        dyn = self.model.body_type == T.BODY_DYNAMIC
        self.dyn = dyn
        self.g = np.asarray(scene.world.gravity, dtype=float)
        self.e0 = self.energy(state.body_x, state.body_v, state.body_w)
        self.x, self.th, self.v, self.w = [], [], [], []
        self.pen, self.drift = 0.0, 0.0

    def energy(self, x, v, w) -> float:
        m, inertia = self.model.body_mass[self.dyn], self.model.body_inertia[self.dyn]
        xd, vd, wd = x[self.dyn], v[self.dyn], w[self.dyn]
        return float(
            0.5 * (m * (vd * vd).sum(axis=1)).sum()
            + 0.5 * (inertia * wd * wd).sum()
            - (m * (xd @ self.g)).sum()
        )

    def take(self, snap: Snapshot) -> None:
        x, th, v, w = snap.com, snap.angle, snap.velocity, snap.angular_velocity
        b = self.bodies
        self.x.append(x[b].copy())
        self.th.append(th[b].copy())
        self.v.append(v[b].copy())
        self.w.append(w[b].copy())
        if self.invariants:
            self.pen = max(self.pen, penetration(self.model, self.pairs, x, th))
            self.drift = max(self.drift, abs(self.energy(x, v, w) - self.e0))

    def result(self, t: np.ndarray, status: str) -> _Sampled:
        k = len(self.x)
        nb = self.bodies.shape[0]
        x = np.full((t.shape[0], nb, 2), np.nan)
        th = np.full((t.shape[0], nb), np.nan)
        v, w = np.full_like(x, np.nan), np.full_like(th, np.nan)
        if k:
            x[:k], th[:k], v[:k], w[:k] = self.x, self.th, self.v, self.w
        return _Sampled(
            Poses(t, x, th, v, w),
            self.pen if self.invariants else None,
            self.drift if self.invariants else None,
            status,
        )


def engine_for(scene: Scene, s: Setting) -> Engine:
    """The scene in the setting's engine: rbsim with the scene's solver block (scene_for
    put the setting there), pymunk with s.iterations iterations per step of dt."""
    if s.engine == "pymunk":
        return make_engine(
            "pymunk", scene, settings=PymunkSettings(iterations=s.iterations, substeps=1)
        )
    return make_engine(s.engine, scene)


def sample_run(scene: Scene, ref: Reference, s: Setting, per_sample: int, samples: int) -> _Sampled:
    """Run the setting's engine, reading the tracked bodies every `per_sample` steps."""
    probe = _Probe(scene, ref)
    engine = engine_for(scene, s)
    t = np.arange(samples + 1) * per_sample * scene.world.dt
    status = "ok"
    probe.take(engine.read())
    for _ in range(samples):
        try:
            engine.advance(per_sample)
            snap = engine.read()
        except NonFiniteState as err:
            status = f"non-finite at step {err.step}"
            break
        except TooManyPairs as err:
            status = str(err)
            break
        probe.take(snap)
    return probe.result(t, status)


def _median_time(run_once: Callable[[], float], repeats: int) -> tuple[float, int]:
    samples: list[float] = []
    while len(samples) < repeats or (sum(samples) < MIN_TIMED and len(samples) < MAX_REPEATS):
        samples.append(run_once())
    return statistics.median(samples), len(samples)


def time_run(scene: Scene, s: Setting, repeats: int) -> tuple[float, int]:
    """Median CPU seconds of `advance(steps)` on fresh engines of the setting (the
    compiled engine loaded first, outside the timing)."""
    if s.engine != "pymunk":
        engine_for(scene, s).advance(1)

    def once() -> float:
        engine = engine_for(scene, s)
        t0 = time.process_time()
        engine.advance(scene.world.steps)
        return time.process_time() - t0

    return _median_time(once, repeats)


# --------------------------------------------------------------------------------------
# Where the runs go


class Pool(Protocol):
    """Where a sweep's runs are computed. `map` calls fn(*args) for each tuple of
    `calls`, possibly several at once, and yields (index in calls, result) as each
    finishes; `alone` calls fn(*args) with nothing else of the sweep running, always in
    the same process (timed runs)."""

    def map(self, fn: Callable[..., Any], calls: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        """(index, fn(*calls[index])) for every call, in any order."""
        ...

    def alone(self, fn: Callable[..., Any], *args: Any) -> Any:
        """fn(*args), run by itself."""
        ...


class SerialPool:
    """Every run in this process, one after the other (the default)."""

    def map(self, fn: Callable[..., Any], calls: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        """(index, fn(*calls[index])) in order."""
        for i, args in enumerate(calls):
            yield i, fn(*args)

    def alone(self, fn: Callable[..., Any], *args: Any) -> Any:
        """fn(*args)."""
        return fn(*args)


# --------------------------------------------------------------------------------------
# The sweep


def run_sweep(
    scene: Scene,
    grid: Grid | None = None,
    *,
    repeats: int = 3,
    duration: float | None = None,
    progress: Callable[[int, int, Setting], None] | None = None,
    pool: Pool | None = None,
) -> SweepResult:
    """Run every setting of `grid` on `scene` and measure its cost and error.

    duration (s): simulated time, default the scene's; rounded to whole multiples of the
    grid's largest dt. The error runs (and the converged reference's) go to
    `pool.map`, side by side when the pool has several workers; then the timed runs go
    one at a time to `pool.alone`, so that no run of the sweep disturbs a timing.
    progress(k, total, setting) is called as runs finish (total: two per setting).
    Raises SweepError for a grid that cannot be compared, and
    rbsim.reference.ReferenceError when the scene does not fit its reference."""
    pool = pool or SerialPool()
    grid = grid or Grid()
    if repeats < 1:
        raise SweepError("repeats must be at least 1")
    sample_dt = grid.sample_dt()
    total = scene.world.steps * scene.world.dt if duration is None else float(duration)
    samples = max(1, round(total / sample_dt))
    duration = samples * sample_dt
    ref = make_reference(scene)
    notes: list[str] = []
    uncertainty = None
    settings = grid.settings()
    if ref.family == "converged":
        ref_poses, statement, uncertainty = _converged(scene, ref, grid, sample_dt, samples, pool)
        ref.statement = statement
    else:
        ref_poses = ref.poses(np.arange(samples + 1) * sample_dt)
    total = 2 * len(settings)
    scenes, calls = [], []
    for s in settings:
        per = _steps(s.dt, sample_dt)
        scenes.append(scene_for(scene, s, per * samples))
        calls.append((scenes[-1], ref, s, per, samples))
    sampled = _map_runs(pool, sample_run, calls, settings, progress)
    points = []
    for k, (s, sc, got) in enumerate(zip(settings, scenes, sampled, strict=True)):
        assert got is not None
        points.append(_measure(sc, ref, ref_poses, s, got, repeats, pool))
        if progress is not None:
            progress(len(settings) + k + 1, total, s)
    for engine in ("rbsim", "pymunk"):
        for p in pareto_front([p for p in points if p.setting.engine == engine]):
            p.front = True
    metric = (
        "max over samples and tracked bodies of the RMS distance between the body's "
        "material points and the reference's, sqrt(|dx|^2 + 2 r_g^2 (1 - cos dθ)), m"
    )
    if ref.family == "invariants":
        metric = (
            "max over samples and bodies of the RMS distance of the body's material points "
            "from their rest pose, m (drift)"
        )
        notes.append("penetration_m and energy_drift_J in the CSV/JSON: max over samples")
    return SweepResult(
        scene=scene.name,
        path=scene.path,
        reference_kind=ref.kind,
        reference=ref.statement,
        metric=metric,
        duration=duration,
        sample_dt=sample_dt,
        points=points,
        reference_uncertainty=uncertainty,
        notes=notes,
    )


def _steps(s_dt: float, sample_dt: float) -> int:
    return round(sample_dt / s_dt)


def _measure(
    sc: Scene,
    ref: Reference,
    ref_poses: Poses,
    s: Setting,
    got: _Sampled,
    repeats: int,
    pool: Pool,
) -> Point:
    """The setting's point: the error of its sampled run `got` of `sc`, then its cost
    from timed runs (none when the sampled run failed)."""
    point = Point(s, penetration=got.penetration, energy_drift=got.energy_drift, status=got.status)
    if got.status != "ok":
        return point
    point.error, point.position_error, point.angle_error = pose_error(
        got.poses, ref_poses, ref.gyration
    )
    point.cpu, point.us_per_step, point.timed_runs = _cost(sc, s, repeats, pool)
    return point


def _cost(sc: Scene, s: Setting, repeats: int, pool: Pool) -> tuple[float, float, int]:
    """The cost of running `sc` with setting s, timed alone in the pool: CPU s per
    simulated s, µs per step, and the number of timed runs."""
    seconds, n = pool.alone(time_run, sc, s, repeats)
    return seconds / (sc.world.steps * sc.world.dt), 1e6 * seconds / sc.world.steps, n


def _map_runs(
    pool: Pool,
    fn: Callable[..., Any],
    calls: Sequence[tuple],
    settings: Sequence[Setting],
    progress: Callable[[int, int, Setting], None] | None,
) -> list[Any]:
    """fn(*call) for every call through pool.map, in the order of `calls`; progress(k,
    total, setting) after each, total being two per setting (the timed runs follow)."""
    total = 2 * len(settings)
    if progress is not None and settings:
        progress(0, total, settings[0])
    results: list[Any] = [None] * len(calls)
    for done, (i, got) in enumerate(pool.map(fn, calls), start=1):
        results[i] = got
        if progress is not None:
            progress(done, total, settings[i])
    return results


def _converged(
    scene: Scene, ref: Reference, grid: Grid, sample_dt: float, samples: int, pool: Pool
) -> tuple[Poses, str, float]:
    """The converged reference's poses, its statement and its uncertainty (m): the error
    of a run at twice its dt measured against it."""
    opts = ref.options
    dt = float(opts.get("dt", min(grid.dts) / CONVERGED_DT_FACTOR))
    per = sample_dt / dt
    if abs(per - round(per)) > 1e-9 * per or round(per) % 2:
        raise SweepError(
            f"reference.dt {dt_text(dt)} s must divide the largest dt of the grid "
            f"({dt_text(sample_dt)} s) an even number of times"
        )
    sub = int(opts.get("substeps", CONVERGED_SUBSTEPS))
    it = int(opts.get("iterations", CONVERGED_ITERATIONS))
    fine = Setting("rbsim", dt, sub, it, "symplectic_euler", "exact")
    coarse = replace(fine, dt=2 * dt)
    per = round(per)
    calls = [
        (scene_for(scene, s, n * samples), ref, s, n, samples)
        for s, n in ((fine, per), (coarse, per // 2))
    ]
    runs: list[Poses | None] = [None, None]
    for i, got in pool.map(sample_run, calls):
        if got.status != "ok":
            family = calls[i][2].family
            raise SweepError(f"the converged reference run ({family}) failed: {got.status}")
        runs[i] = got.poses
    uncertainty = pose_error(runs[1], runs[0], ref.gyration)[0]
    statement = (
        f"converged rbsim run (dt {dt_text(dt)} s, {sub} substeps, {it} iterations, "
        f"symplectic Euler, exact rotation); a run at twice its dt differs from it by "
        f"{uncertainty:.3g} m"
    )
    return runs[0], statement, uncertainty


# --------------------------------------------------------------------------------------
# Plot


ENGINE_COLORS = {"rbsim": "tab:blue", "pymunk": "tab:red"}


def plot_sweep(result: SweepResult, path: str | Path) -> None:
    """A log-log plot of error (m) against CPU time per simulated second: one curve per
    family (dt varies along it), each engine's Pareto front drawn over it."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 5.5))
    families: dict[str, list[Point]] = {}
    for p in result.points:
        if _finite(p):
            families.setdefault(p.setting.family, []).append(p)
    markers = "osD^v<>ph*XP"
    shade = {"rbsim": 0, "pymunk": 0}
    for fam, pts in families.items():
        engine = pts[0].setting.engine
        cmap = plt.get_cmap("Blues" if engine == "rbsim" else "Reds")
        n_eng = sum(1 for f in families.values() if f[0].setting.engine == engine)
        color = cmap(0.35 + 0.6 * shade[engine] / max(1, n_eng - 1))
        marker = markers[shade[engine] % len(markers)]
        shade[engine] += 1
        pts = sorted(pts, key=lambda q: q.setting.dt, reverse=True)
        ax.plot(
            [1e3 * q.cpu for q in pts],
            [_floor(q.error) for q in pts],
            marker=marker,
            color=color,
            lw=1,
            ms=4,
            label=fam,
        )
    for engine, color in ENGINE_COLORS.items():
        front = [p for p in result.points if p.front and p.setting.engine == engine]
        front.sort(key=lambda q: q.cpu)
        if front:
            ax.step(
                [1e3 * q.cpu for q in front],
                [_floor(q.error) for q in front],
                where="post",
                color=color,
                lw=2.5,
                alpha=0.5,
                label=f"{engine} Pareto front",
            )
            ax.scatter(
                [1e3 * q.cpu for q in front],
                [_floor(q.error) for q in front],
                s=70,
                facecolors="none",
                edgecolors=color,
                linewidths=1.5,
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU time per simulated second, ms (median, compile excluded)")
    ax.set_ylabel(f"error, m (floor {ERROR_FLOOR:g})")
    ax.set_title(f"{result.scene}: {result.reference_kind} reference", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise PlotUnavailable(
            "matplotlib is not installed; install the plot extra "
            "(pip install 'rbsim[plot]', or make install)"
        ) from None
    return plt


# --------------------------------------------------------------------------------------
# Scaling: cost per step against the number of bodies


@dataclass
class ScalingPoint:
    """Median µs per step of each engine on a pile of `bodies` bodies."""

    bodies: int
    rbsim_us: float
    pymunk_us: float


def pile_scene(base: int) -> Scene:
    """A pyramid of 1 m boxes with `base` boxes in its bottom row, on a static ground."""
    from ..scene import load_scene_text

    half = base + 5
    text = f"""
version: 1
name: pile{base}
world: {{gravity: [0, -9.81], dt: 1/60, steps: 100000}}
materials:
  wood: {{density: 1.0, friction: 0.6, restitution: 0.0}}
bodies:
  - name: ground
    type: static
    material: wood
    shape: {{segment: {{a: [{-half}, 0], b: [{half}, 0]}}}}
  - pyramid: {{base: {base}, size: [1, 1], origin: [0, 0.5], material: wood}}
"""
    return load_scene_text(text, f"pile{base}.yaml")


def measure_scaling(
    bases: Sequence[int], warmup: int = 20, block: int = 10, repeats: int = 3
) -> list[ScalingPoint]:
    """µs per step of rbsim (its default settings) and pymunk (10 iterations), dt 1/60,
    on pyramids of the given bases: median of `repeats` timed blocks of `block` steps
    after `warmup` steps, CPU time."""
    out = []
    for base in bases:
        scene = pile_scene(base)
        rb = block_times(make_engine("rbsim", scene), warmup, block, repeats)
        pm = block_times(
            make_engine("pymunk", scene, settings=PymunkSettings(iterations=10)),
            warmup,
            block,
            repeats,
        )
        out.append(ScalingPoint(len(scene.bodies), statistics.median(rb), statistics.median(pm)))
    return out


def fitted_slope(n: Sequence[float], cost: Sequence[float]) -> float:
    """Least-squares slope of log(cost) against log(n)."""
    x, y = np.log(np.asarray(n, float)), np.log(np.asarray(cost, float))
    return float(np.polyfit(x, y, 1)[0])


def plot_scaling(points: Sequence[ScalingPoint], path: str | Path) -> None:
    """Log-log µs per step against bodies, both engines, with the fitted slopes."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    n = [p.bodies for p in points]
    for engine, attr in (("rbsim", "rbsim_us"), ("pymunk", "pymunk_us")):
        cost = [getattr(p, attr) for p in points]
        slope = fitted_slope(n, cost)
        ax.plot(n, cost, "o-", color=ENGINE_COLORS[engine], label=f"{engine} (slope {slope:.2f})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("bodies (pyramid of boxes on the ground)")
    ax.set_ylabel("CPU µs per step (median, dt 1/60)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------------------
# 3D: the rotation updates side by side on a tumbling body


@dataclass
class RotationPoint:
    """One run of a 3D rotation sweep: the update, dt (s) and substeps; its cost, cpu
    (median CPU s per simulated s) and us_per_step (µs); energy_error, the largest
    |E − E0| / E0 over the run (E the total energy); period_error, the first whole
    period of ω in the body against the closed form, relative (nan when the body
    makes no whole period or the scene has no closed form); status "ok" or why the run
    failed; front: on the Pareto front of energy error against cost."""

    rotation: str
    dt: float
    substeps: int
    cpu: float = math.nan
    us_per_step: float = math.nan
    energy_error: float = math.inf
    period_error: float = math.nan
    timed_runs: int = 0
    status: str = "ok"
    front: bool = False

    def row(self) -> dict:
        """A flat dict for CSV and JSON (units in the keys)."""
        return {
            "rotation": self.rotation,
            "dt_s": self.dt,
            "substeps": self.substeps,
            "cpu_s_per_sim_s": self.cpu,
            "us_per_step": self.us_per_step,
            "energy_error_rel": self.energy_error,
            "period_error_rel": self.period_error,
            "timed_runs": self.timed_runs,
            "status": self.status,
            "pareto_front": self.front,
        }


@dataclass
class RotationSweepResult:
    """A 3D sweep of the rotation updates: the scene, the tracked body, its closed-form
    period of ω in the body (s; None without one), the points."""

    scene: str
    path: str
    body: str
    duration: float
    period: float | None
    points: list[RotationPoint]
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready: the header and every point."""
        return {
            "scene": self.scene,
            "path": self.path,
            "body": self.body,
            "duration_s": self.duration,
            "closed_form_period_s": self.period,
            "cost": "median CPU time (s) per simulated second, compile and setup excluded",
            "energy_error": "max over the run of |E - E0| / E0",
            "period_error": "|T - T_closed| / T_closed, T the first whole period of ω in the body",
            "notes": list(self.notes),
            "points": [p.row() for p in self.points],
        }

    def table(self) -> str:
        """The human-readable table."""
        period = f"{self.period:.6g} s" if self.period is not None else "none (not torque-free)"
        lines = [
            f"{self.scene}: the rotation updates, work against error, {self.duration:g} s "
            f"simulated, body {self.body!r}",
            f"  closed-form period of ω in the body (Euler's equations, elliptic K): {period}",
            "  energy err: the scene's kinetic + potential energy E, max over the run of "
            "|E - E0| / E0; period err: the body's first whole period against the closed form",
            "  cost: median CPU time per simulated second, compile and setup excluded",
        ]
        lines += [f"  note: {n}" for n in self.notes]
        lines.append(
            f"  {'rotation':<9}  {'dt s':>7}  {'sub':>3}  {'cpu ms/s':>10}  {'us/step':>9}  "
            f"{'energy err':>10}  {'period err':>10}  front"
        )
        for p in self.points:
            mark = "*" if p.front else ""
            if p.status != "ok":
                mark = p.status
            lines.append(
                f"  {p.rotation:<9}  {dt_text(p.dt):>7}  {p.substeps:>3}  {1e3 * p.cpu:>10.4g}  "
                f"{p.us_per_step:>9.4g}  {p.energy_error:>10.3g}  {p.period_error:>10.3g}  {mark}"
            )
        return "\n".join(lines)

    def write(self, out_dir: str | Path, plot: bool = True) -> dict[str, Path]:
        """Write <scene>.csv, <scene>.json and (plot=True) <scene>.png into out_dir, as
        SweepResult.write does."""
        return _write_files(self, out_dir, plot_rotation_sweep if plot else None)


def _quat_inv_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rᵀ(q) v for rows of unit quaternions (w, x, y, z) and vectors."""
    u, w = -q[..., 1:], q[..., :1]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def free_body_period(moments: np.ndarray, omega: np.ndarray) -> float | None:
    """The period (s) of ω in the body of a torque-free rigid body with distinct
    principal moments (kg·m²) and principal-axes angular velocity omega (rad/s): Landau
    & Lifshitz §37, T = 4 K(k) sqrt(I1 I2 I3 / a) with a = (I3 − I2)(L² − 2E I1) and
    k² = (I2 − I1)(2E I3 − L²) / a when L² > 2E I2 (I1 < I2 < I3), the roles of I1 and
    I3 exchanged otherwise. None for a symmetric body, a spin about one principal axis
    or the separatrix itself (no finite period)."""
    from scipy.special import ellipk

    i1, i2, i3 = np.sort(np.asarray(moments, float))
    if not (i1 < i2 < i3) or not np.all(np.isfinite(moments)):
        return None
    e2 = float(np.sum(moments * omega**2))
    l2 = float(np.sum((moments * omega) ** 2))
    if l2 > e2 * i2:
        a, b = (i3 - i2) * (l2 - e2 * i1), (i2 - i1) * (e2 * i3 - l2)
    else:
        a, b = (i2 - i1) * (e2 * i3 - l2), (i3 - i2) * (l2 - e2 * i1)
    if not (a > 0 and 0 <= b < a):
        return None
    return float(4.0 * ellipk(b / a) * math.sqrt(i1 * i2 * i3 / a))


def principal_omega(model: Any, body: int, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The angular velocity (rad/s) in the principal axes of `body` of the model
    (rbsim.scene.compile.Model, 3D), from its orientations q (..., 4) and world-frame
    angular velocities w (..., 3)."""
    axes = np.broadcast_to(model.body_axes[body], q.shape)
    return _quat_inv_rotate(axes, _quat_inv_rotate(q, w))


def _tracked_body(scene: Scene) -> int:
    """The body the 3D sweep follows: the first dynamic body."""
    for i, body in enumerate(scene.bodies):
        if body.type == "dynamic":
            return i
    raise SweepError("the scene has no dynamic body to follow")


def _torque_free(scene: Scene, i: int) -> bool:
    """Whether body i turns free: no torque, no force (which may act off the COM), no
    angular damping (gravity acts at the COM)."""
    body = scene.bodies[i]
    return not any(body.torque) and not any(body.force) and scene.world.angular_damping == 0.0


def rotation_run(scene: Scene, rotation: str, dt: float, substeps: int, body: int) -> dict:
    """One error run of the 3D rotation sweep: (status, energy error, period error). The
    tracked body's frames are recorded by the engine every step."""
    from ..core import CoreWorld

    s = Setting("rbsim", dt, substeps, 1, scene.solver.integrator, rotation)
    sc = scene_for(scene, s, scene.world.steps)
    world = CoreWorld.from_scene(sc)
    n = sc.world.steps
    nb = len(sc.bodies)
    block = {
        "step": np.full(n, -1, np.int64),
        "orientation": np.zeros((n, nb, 4)),
        "angular_velocity": np.zeros((n, nb, 3)),
        "kinetic_energy": np.zeros(n),
        "potential_energy": np.zeros(n),
    }
    first = {k: v[:1].copy() for k, v in block.items()}
    world.engine.record(first, 0)
    status, _taken, written, _bad = world.engine.advance_recording(n, 1, n, block, 0, None)
    if status != 0:
        return {"status": f"non-finite at step {int(block['step'][max(0, written - 1)])}"}
    e0 = float(first["kinetic_energy"][0] + first["potential_energy"][0])
    energy = block["kinetic_energy"] + block["potential_energy"]
    energy_error = float(np.max(np.abs(energy - e0)) / abs(e0)) if e0 else math.nan
    # ω in the body's principal axes; its intermediate component changes sign twice a period
    q = np.concatenate([first["orientation"][:, body], block["orientation"][:, body]])
    w = np.concatenate([first["angular_velocity"][:, body], block["angular_velocity"][:, body]])
    wp = principal_omega(world.model, body, q, w)
    moments = world.model.body_moments[body]
    period = free_body_period(moments, wp[0]) if _torque_free(sc, body) else None
    period_error = math.nan
    if period is not None:
        k = int(np.argsort(moments)[1])
        y = wp[:, k]
        i = np.flatnonzero((y[:-1] > 0) & (y[1:] <= 0))
        times = (i + y[i] / (y[i] - y[i + 1])) * dt  # frame k is at t = k dt
        if len(times) >= 2:
            period_error = float(abs(times[1] - times[0] - period) / period)
    return {"status": "ok", "energy_error": energy_error, "period_error": period_error}


def run_rotation_sweep(
    scene: Scene,
    grid: Grid | None = None,
    *,
    repeats: int = 3,
    duration: float | None = None,
    progress: Callable[[int, int, Setting], None] | None = None,
    pool: Pool | None = None,
) -> RotationSweepResult:
    """The rotation updates of a 3D scene side by side: for every rotation of the grid
    (default normalize, exact, split) and every dt and substep count, the energy error
    and the error of the period of ω in the body of the first dynamic body against the
    closed form (a torque-free body), and the cost (CPU time, as run_sweep measures
    it). duration (s): simulated time, default the scene's. Iterations, integrators and
    pymunk's settings of the grid do not apply (no contacts in 3D yet; the scene's
    integrator is used)."""
    pool = pool or SerialPool()
    grid = grid or Grid()
    if repeats < 1:
        raise SweepError("repeats must be at least 1")
    if not grid.dts:
        raise SweepError("the grid has no dt")
    rotations = grid.rotations or T.ROTATIONS
    body = _tracked_body(scene)
    total = scene.world.steps * scene.world.dt if duration is None else float(duration)
    runs = []
    for rot in rotations:
        for sub in grid.substeps:
            for dt in sorted(grid.dts, reverse=True):
                steps = max(1, round(total / dt))
                sc = replace(scene, world=replace(scene.world, dt=dt, steps=steps))
                runs.append((rot, dt, sub, sc))
    count = 2 * len(runs)
    settings = [
        Setting("rbsim", dt, sub, 1, scene.solver.integrator, rot) for rot, dt, sub, _ in runs
    ]
    calls = [(sc, rot, dt, sub, body) for rot, dt, sub, sc in runs]
    results = _map_runs(pool, rotation_run, calls, settings, progress)
    points = []
    for k, ((rot, dt, sub, sc), got, s) in enumerate(zip(runs, results, settings, strict=True)):
        assert got is not None
        p = RotationPoint(rot, dt, sub, status=got["status"])
        if p.status == "ok":
            p.energy_error, p.period_error = got["energy_error"], got["period_error"]
            p.cpu, p.us_per_step, p.timed_runs = _cost(
                scene_for(sc, s, sc.world.steps), s, repeats, pool
            )
        points.append(p)
        if progress is not None:
            progress(len(runs) + k + 1, count, s)
    ok = sorted(
        (p for p in points if p.status == "ok" and math.isfinite(p.cpu)),
        key=lambda p: (p.cpu, p.energy_error),
    )
    best = math.inf
    for p in ok:
        if p.energy_error < best:
            p.front, best = True, p.energy_error
    model_body = scene.bodies[body]
    from ..core import CoreWorld

    world = CoreWorld.from_scene(scene)
    st = world.state
    wp = principal_omega(world.model, body, st.body_q[body], st.body_w[body])
    period = None
    if _torque_free(scene, body):
        period = free_body_period(world.model.body_moments[body], wp)
    notes = []
    others = sum(b.type == "dynamic" for b in scene.bodies) - 1
    if others > 0:
        notes.append(
            f"the energy error is the whole scene's ({others + 1} dynamic bodies, contacts and "
            f"friction included), not {model_body.name!r}'s alone: the period error is its"
        )
    unmeasured = [p for p in points if p.status == "ok" and not math.isfinite(p.period_error)]
    if period is None:
        notes.append(
            f"no closed-form period of ω in the body of {model_body.name!r} (not torque-free, "
            "two equal moments, or on the separatrix): the period errors are NaN"
        )
    elif total < period:
        notes.append(
            f"the run ({total:g} s) is shorter than one period ({period:.4g} s): the period "
            "errors are NaN (no whole period to measure); use --duration"
        )
    elif unmeasured:
        notes.append(
            f"{len(unmeasured)} of the runs ({total:g} s) made no whole period of ω in the body "
            f"(measured between two downward sign changes of its intermediate component, up "
            f"to twice the period, {period:.4g} s): their period errors are NaN; use --duration"
        )
    return RotationSweepResult(
        scene=scene.name,
        path=str(scene.path),
        body=model_body.name,
        duration=total,
        period=period,
        points=points,
        notes=notes,
    )


def plot_rotation_sweep(result: RotationSweepResult, path: str | Path) -> None:
    """Two log-log panels, energy error and period error against CPU time per simulated
    second, one curve per rotation update and substep count (dt varies along it)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    curves: dict[tuple[str, int], list[RotationPoint]] = {}
    for p in result.points:
        if p.status == "ok" and math.isfinite(p.cpu):
            curves.setdefault((p.rotation, p.substeps), []).append(p)
    colors = {"normalize": "tab:red", "exact": "tab:orange", "split": "tab:blue"}
    attrs = ("energy_error", "period_error")
    plotted = dict.fromkeys(attrs, False)
    for (rot, sub), pts in curves.items():
        pts = sorted(pts, key=lambda q: q.dt, reverse=True)
        for ax, attr in zip(axes, attrs, strict=True):
            # a NaN error (no whole period in the run) is left out, not drawn at the floor
            xy = [(1e3 * q.cpu, max(getattr(q, attr), 1e-16)) for q in pts
                  if math.isfinite(getattr(q, attr))]  # fmt: skip
            if xy:
                xs, ys = zip(*xy, strict=True)
                ax.plot(xs, ys, "o-", color=colors.get(rot), ms=4, label=f"{rot} s{sub}")
                plotted[attr] = True
    labels = ("energy error |E − E0| / E0", "period error")
    for ax, attr, label in zip(axes, attrs, labels, strict=True):
        ax.set_xlabel("CPU time per simulated second, ms")
        ax.set_ylabel(label)
        if not plotted[attr]:  # nothing measured: say why (log axes need a value)
            why = "\n".join(textwrap.wrap(result.notes[0], 50)) if result.notes else ""
            ax.text(0.5, 0.5, f"no {label.split(' |')[0]} measured\n{why}", ha="center",
                    va="center", fontsize=8, transform=ax.transAxes)  # fmt: skip
            continue
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{result.scene}: rotation updates, work against error", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
