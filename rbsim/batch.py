"""`rbsim batch`: many independent runs of scenes, on a Dask cluster.

A batch is every scene crossed with the grid of its `--vary` lists, or with `--samples`
draws of them, the runs sent as tasks: locally on a dask.distributed LocalCluster of
worker processes, or on an existing cluster at a scheduler's address. The steps:

1. `parse_vary` reads each `--vary KEY.PATH=LIST` (or a distribution for `--samples`);
   `expand` turns them into one dict of override texts per run.
2. `plan_batch` resolves and checks every run before any starts (the same key paths as
   `--set`: each varied value becomes one more `key=value` override), and names each run
   by a hash of its resolved scene and settings (`run_id`). Any problem raises
   BatchInvalid listing them all (`precheck`: the same for each scene and value alone,
   in a moment, before a local cluster is started beside the full check).
3. `run_batch` skips runs whose `DIR/<run-id>.h5` is complete, sends the others as tasks
   (`run_jobs`: several short runs to a task, each `run_one`), retries failures, and
   writes `DIR/summary.csv` (and `summary.parquet` when pyarrow is installed) with one
   row per run: the figures of `figures`, read from the trajectory after the run.

Worker processes that this module starts ignore SIGINT (forked from a fork server that
started with it ignored, and `dask_setup`, run in each as a Dask preload), so that
Ctrl-C reaches only the batch, which then records what finished and stops the cluster.
Dask is imported only when a batch or a distributed sweep runs.

Above rbsim.tools in the package (cli -> batch -> tools -> run).
"""

from __future__ import annotations

import collections
import contextlib
import csv
import hashlib
import importlib.util
import itertools
import json
import logging
import math
import os
import re
import shutil
import signal
import socket
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, config, ctrlc
from .forkserver import WORKER_MODULES, holding_sigint, ignoring_sigint, start_fork_server
from .scene import Scene, SceneError, load_scene, load_scene_text, scene_to_dict
from .scene.yamlsrc import YList, YMap, load_yaml

ENGINE = "rbsim"

# The max overlap is measured on at most this many frames of a run, evenly spread, the
# first and the last included: a pile of 1000 shapes costs about 10 ms a frame.
OVERLAP_FRAMES = 200

# Shown at most this many problems, or failed runs, before "... and N more".
MAX_LISTED = 20

SUMMARY_CSV = "summary.csv"
SUMMARY_PARQUET = "summary.parquet"

# The figures each run reports, in the summary's column order after run id, scene and
# the varied keys.
FIGURE_COLUMNS = (
    "status",
    "steps",
    "wall_time_s",
    "kinetic_energy_J",
    "max_overlap_m",
    "max_speed_m_s",
    "moved_most",
    "moved_most_m",
)
_INT_COLUMNS = ("steps",)
_FLOAT_COLUMNS = ("wall_time_s", "kinetic_energy_J", "max_overlap_m", "max_speed_m_s")


class VaryError(ValueError):
    """A `--vary` that cannot be read; the message names it and says what was expected."""


class BatchInvalid(ValueError):
    """Runs of a batch that cannot start: `problems` lists one line per problem."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        shown = self.problems[:MAX_LISTED]
        if len(self.problems) > MAX_LISTED:
            shown.append(f"... and {len(self.problems) - MAX_LISTED} more")
        super().__init__("\n".join(shown))


class BatchError(RuntimeError):
    """The batch cannot run at all (no scheduler at the address, a worker without rbsim)."""


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a batch; `result` holds every run finished by then,
    already written to the summary."""

    def __init__(self, result: BatchResult) -> None:
        super().__init__(
            f"interrupted: {result.finished} of {result.total} runs finished, "
            f"recorded in {result.paths[0] if result.paths else 'no summary'}"
        )
        self.result = result


# --------------------------------------------------------------------------------------
# --vary and --samples


@dataclass(frozen=True)
class Vary:
    """One `--vary`: the key path (as for `--set`) and either `values`, the YAML text of
    each value of a list, or a distribution `dist` = (name, a, b): ("uniform", low,
    high) or ("normal", mean, standard deviation), in the key's units."""

    key: str
    values: tuple[str, ...] = ()
    dist: tuple[str, float, float] | None = None


_DISTRIBUTION = re.compile(r"^\s*([A-Za-z_]\w*)\s*\((.*)\)\s*$", re.S)
DISTRIBUTIONS = ("uniform", "normal")


def parse_vary(raw: str) -> Vary:
    """Read `KEY.PATH=LIST` or `KEY.PATH=uniform(a,b)` / `normal(mu,sigma)`. LIST is a
    YAML list read with the scene files' rules; each item is kept as YAML text, to be
    set as `--set KEY.PATH=item` would. Raises VaryError."""
    key, eq, text = raw.partition("=")
    key = key.strip()
    if not eq or not key:
        raise VaryError(
            f"--vary {raw}: expected KEY.PATH=LIST, such as world.dt=[0.01,0.005] "
            "(or with --samples KEY.PATH=uniform(a,b))"
        )
    where = f"--vary {key}"
    match = _DISTRIBUTION.match(text)
    if match:
        name, args = match.group(1), match.group(2).split(",")
        if name not in DISTRIBUTIONS:
            raise VaryError(
                f"{where}: unknown distribution {name!r}; expected uniform(a,b) or normal(mu,sigma)"
            )
        numbers = []
        for arg in args:
            value = _scalar(arg)
            if value is None:
                raise VaryError(f"{where}: {name}(...) takes two numbers, got {arg.strip()!r}")
            numbers.append(value)
        if len(numbers) != 2 or not all(math.isfinite(x) for x in numbers):
            raise VaryError(f"{where}: {name}(...) takes two finite numbers, got {text.strip()}")
        a, b = numbers
        if name == "uniform" and not a < b:
            raise VaryError(f"{where}: uniform(a,b) needs a < b, got {text.strip()}")
        if name == "normal" and not b > 0:
            raise VaryError(f"{where}: normal(mu,sigma) needs sigma > 0, got {text.strip()}")
        return Vary(key, dist=(name, a, b))
    value, _, problems = load_yaml(text, origin=where)
    if problems:
        raise VaryError(f"{where}: " + "; ".join(p.message for p in problems))
    if not isinstance(value, YList) or not value:
        raise VaryError(
            f"{where}: expected a YAML list of values such as [0.01,0.005], got {text.strip()!r}"
        )
    return Vary(key, values=tuple(yaml_text(v) for v in value))


def _scalar(text: str) -> float | None:
    """A number as the scene files write one (YAML, or a fraction such as 1/60), else None."""
    parts = text.split("/")
    if len(parts) > 2:
        return None
    values = []
    for part in parts:
        value, _, problems = load_yaml(part)
        if problems or isinstance(value, bool) or not isinstance(value, int | float):
            return None
        values.append(float(value))
    if len(values) == 2:
        return values[0] / values[1] if values[1] != 0 else None
    return values[0]


def yaml_text(value: Any) -> str:
    """A value read by load_yaml written back as one-line YAML that reads the same
    (floats to every digit)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        return repr(value)
    if isinstance(value, str):
        back, _, problems = load_yaml(value)
        plain = not problems and back == value and isinstance(back, str) and "\n" not in value
        return value if plain and value.strip() == value and value else json.dumps(value)
    if isinstance(value, YMap | dict):
        return "{" + ", ".join(f"{yaml_text(k)}: {yaml_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, YList | list | tuple):
        return "[" + ", ".join(yaml_text(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as YAML")


def expand(varies: Sequence[Vary], samples: int | None = None, seed: int = 0) -> list[dict]:
    """The runs' varied values, key -> YAML text, in `varies` order. Without `samples`:
    every combination of the lists (the first key varies slowest), and distributions are
    an error (VaryError). With `samples` N: N draws from numpy's PCG64 seeded by `seed`,
    sample by sample and key by key: uniform(a,b), normal(mu,sigma), or one item of a
    list, each equally likely."""
    keys = [v.key for v in varies]
    for key in keys:
        if keys.count(key) > 1:
            raise VaryError(f"--vary {key}: given more than once")
    if samples is None:
        for v in varies:
            if v.dist is not None:
                name, a, b = v.dist
                raise VaryError(
                    f"--vary {v.key}: {name}({a:g},{b:g}) draws values only with --samples N"
                )
        return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(
            *(v.values for v in varies)
        )]  # fmt: skip
    rng = np.random.default_rng(seed)
    runs = []
    for _ in range(samples):
        run = {}
        for v in varies:
            if v.dist is None:
                run[v.key] = v.values[int(rng.integers(len(v.values)))]
            elif v.dist[0] == "uniform":
                run[v.key] = yaml_text(float(rng.uniform(v.dist[1], v.dist[2])))
            else:
                run[v.key] = yaml_text(float(rng.normal(v.dist[1], v.dist[2])))
        runs.append(run)
    return runs


# --------------------------------------------------------------------------------------
# The plan: every run resolved and checked before any starts


@dataclass(frozen=True)
class RunSpec:
    """One run: the scene file (as named on the command line) and its text, the
    overrides applied to it (`--set`s, then one per varied key), the varied values
    (key, YAML text) and the run id."""

    run_id: str
    scene_path: str
    source: str
    overrides: tuple[str, ...]
    varied: tuple[tuple[str, str], ...]

    def scene(self) -> Scene:
        """The run's resolved scene (as the worker resolves it)."""
        return load_scene_text(self.source, path=self.scene_path, overrides=self.overrides)

    def label(self) -> str:
        """`scenes/x.yaml world.dt=0.01 ...`: the run as a person would name it."""
        return " ".join([self.scene_path, *(f"{k}={v}" for k, v in self.varied)])


@dataclass
class Plan:
    """A checked batch: `specs` holds one run per grid point or sample of each scene, in
    order (two draws that resolve to the same scene share a run id, and are run once)."""

    specs: list[RunSpec]
    varied_keys: tuple[str, ...]

    def runs(self) -> list[RunSpec]:
        """One spec per run id, in the order they first appear."""
        seen: dict[str, RunSpec] = {}
        for spec in self.specs:
            seen.setdefault(spec.run_id, spec)
        return list(seen.values())


def run_id(scene: Scene, engine: str = ENGINE) -> str:
    """`<scene name>-<12 hex digits>`: the name (made safe for a file name) and the start
    of the SHA-256 of the resolved scene, the engine and rbsim's version."""
    settings = {"scene": scene_to_dict(scene), "engine": engine, "rbsim": __version__}
    text = json.dumps(settings, sort_keys=True, separators=(",", ":"))
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", scene.name).strip("._") or "run"
    return f"{name[:40]}-{digest}"


def plan_batch(
    scenes: Sequence[str],
    sets: Sequence[str] = (),
    varies: Sequence[Vary] = (),
    samples: int | None = None,
    seed: int = 0,
) -> Plan:
    """Resolve every run of the batch and check that it can be built (the scene, every
    `--set` and `--vary` value, the model: a massless dynamic body is found here).
    Raises BatchInvalid with every problem (file:line:column or `--vary KEY=VALUE`), or
    VaryError for a `--vary` that `expand` refuses."""
    return _plan(scenes, sets, expand(varies, samples, seed), tuple(v.key for v in varies))


def precheck(scenes: Sequence[str], sets: Sequence[str] = (), varies: Sequence[Vary] = ()) -> None:
    """What plan_batch checks, for each scene with its `--set`s alone and with each value
    of each `--vary` list alone (not their grid, nor draws): the common mistakes (a
    missing file, a bad `--set`, a bad value), found in a moment. Raises BatchInvalid."""
    combos: list[dict] = [{}]
    combos += [{v.key: value} for v in varies if v.dist is None for value in v.values]
    _plan(scenes, sets, combos, ())


def _plan(
    scenes: Sequence[str], sets: Sequence[str], combos: list[dict], varied_keys: tuple[str, ...]
) -> Plan:
    """plan_batch over the given varied values (key -> YAML text) of each run."""
    from .scene.compile import ModelError, check_masses

    problems: list[str] = []
    specs: list[RunSpec] = []
    for path in scenes:
        try:
            base = load_scene(path, sets)
        except SceneError as err:
            problems.extend(str(err).splitlines())
            continue
        for combo in combos:
            overrides = tuple(sets) + tuple(f"{k}={v}" for k, v in combo.items())
            try:
                scene = load_scene_text(base.source, path=str(path), overrides=overrides)
                check_masses(scene)
            except SceneError as err:
                for issue in err.errors:
                    line = str(issue)
                    if issue.override in combo:  # name the --vary and the value
                        line = line.replace(
                            f"{issue.file}: --set {issue.override}",
                            f"{issue.file}: --vary {issue.override}={combo[issue.override]}",
                            1,
                        )
                    problems.append(line)
                continue
            except ModelError as err:
                where = " ".join([str(path), *(f"{k}={v}" for k, v in combo.items())])
                problems.append(f"{where}: {err}")
                continue
            specs.append(
                RunSpec(run_id(scene), str(path), base.source, overrides, tuple(combo.items()))
            )
    if problems:
        raise BatchInvalid(list(dict.fromkeys(problems)))
    return Plan(specs, varied_keys)


# --------------------------------------------------------------------------------------
# One run (a task on a worker) and its figures


@dataclass(frozen=True)
class Job:
    """What a worker needs for one run: the spec, the folder to write into (None: write
    into the worker's temporary folder and send the file back) and the client's rbsim
    version (a worker with another version refuses the run)."""

    spec: RunSpec
    out_dir: str | None
    version: str


@dataclass
class Outcome:
    """A run's summary figures (FIGURE_COLUMNS) and, when the worker wrote the file in
    its own temporary folder, the file's bytes; or, for a run that raised (run_jobs),
    no figures and the `error` it is recorded with ("failed: ..."). `seconds`: the
    worker's wall time for the run and its figures (s; 0 when not measured)."""

    figures: dict[str, Any] | None
    data: bytes | None = None
    error: str | None = None
    seconds: float = 0.0


def run_one(job: Job) -> Outcome:
    """Run one spec with rbsim's engine (rbsim.run.run_scene) and measure its figures.

    The trajectory is written to a hidden `.<run-id>.part` file and renamed to
    `<run-id>.h5` once closed, so that a worker killed mid-run leaves no file that looks
    finished. In a folder shared with the batch (a local cluster), an attempt that finds
    the part file of an earlier attempt killed mid-run, with its checkpoint, continues
    it (rbsim.run.resume_run: the frames are those of an uninterrupted run, bit for bit)
    instead of starting again; an flock on `.<run-id>.lock` keeps two live attempts of
    one run from sharing a part file (the second writes its own). A non-finite state is
    a finished run with status "failed: ..." (the file keeps the frames before it); any
    other error is raised for the batch to retry. Scenes that do not set solver.threads
    run on one thread (the workers run side by side, a core each)."""
    if job.version != __version__:
        import rbsim

        raise BatchError(
            f"this worker has rbsim {__version__} ({Path(rbsim.__file__).parent}); "
            f"the batch was planned with rbsim {job.version}: install the same version"
        )
    with config.threads_default(1):  # a worker beside others: one thread unless the scene says
        return _run_job(job)


def one_thread(fn: Callable[..., Any], *args: Any) -> Any:
    """fn(*args) with the scenes that do not set solver.threads run on one thread (a
    worker process beside others: the sweep's tasks)."""
    with config.threads_default(1):
        return fn(*args)


def _run_job(job: Job) -> Outcome:
    """run_one's work (rbsim.run's run or resume of the job's spec, then its figures)."""
    from .io.trajectory import CHECKPOINT_SUFFIX
    from .run import ResumeError, RunFailed, resume_run, run_scene

    spec = job.spec
    scene = spec.scene()
    if job.out_dir is not None:  # an earlier attempt of a task of several runs did this one
        done = Path(job.out_dir) / f"{spec.run_id}.h5"
        if is_complete(done):
            return Outcome(figures(done, scene))
    own_dir = None if job.out_dir is not None else tempfile.mkdtemp(prefix="rbsim-batch-")
    folder = Path(job.out_dir if job.out_dir is not None else own_dir)
    lock = _claim(folder, spec.run_id) if own_dir is None else None
    tag = "" if lock is not None else f".{uuid.uuid4().hex[:8]}"
    part = folder / f".{spec.run_id}{tag}.part"
    try:
        try:
            try:
                if lock is None or not part.exists():
                    raise ResumeError("no earlier attempt")
                resume_run(part, progress=None, signals=())
            except ResumeError:
                run_scene(
                    scene, part, progress=None, signals=(), engine=ENGINE, overrides=spec.overrides
                )
        except RunFailed:
            pass  # the file says which body and step; figures() reads it
        found = figures(part, scene)
        if own_dir is not None:
            return Outcome(found, part.read_bytes())
        os.replace(part, folder / f"{spec.run_id}.h5")
        return Outcome(found)
    finally:
        if own_dir is not None:
            shutil.rmtree(own_dir, ignore_errors=True)
        else:
            part.unlink(missing_ok=True)
            Path(f"{part}{CHECKPOINT_SUFFIX}").unlink(missing_ok=True)
            if lock is not None:
                _release(folder, spec.run_id, lock)


def _lock_path(folder: Path, run_id: str) -> Path:
    return folder / f".{run_id}.lock"


def _claim(folder: Path, run_id: str) -> int | None:
    """An exclusive flock on the run's lock file (its descriptor), or None when another
    live attempt holds it. The kernel drops the lock of a killed process, so a retry
    after a lost worker gets it."""
    import fcntl

    path = _lock_path(folder, run_id)
    while True:
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        try:  # the holder before us may have removed the file we locked
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def _release(folder: Path, run_id: str, fd: int) -> None:
    """Remove the run's lock file and drop the lock (the file first, while held)."""
    _lock_path(folder, run_id).unlink(missing_ok=True)
    os.close(fd)


def run_jobs(jobs: Sequence[Job]) -> list[Outcome]:
    """run_one of each job in turn (one task of several short runs), each Outcome with
    its `seconds`; a run that raises gives an Outcome with its `error` (the status
    "failed: ..." the batch records), and the next runs go on."""
    outcomes = []
    for job in jobs:
        t0 = time.perf_counter()
        try:
            outcome = run_one(job)
        except Exception as err:  # noqa: BLE001 - recorded as the run's failure
            outcome = Outcome(None, error=_describe(err))
        outcome.seconds = time.perf_counter() - t0
        outcomes.append(outcome)
    return outcomes


def figures(path: str | Path, scene: Scene) -> dict[str, Any]:
    """A run's summary figures from its trajectory file (io.trajectory.load_frames):

    status (the file's: "complete", "failed: ..."); steps (the last frame's step);
    wall_time_s (s, the whole run as the file records it); kinetic_energy_J (J, at the
    last frame); max_overlap_m (m, the deepest overlap of two shapes of different
    bodies, one dynamic, by the penetration ruler of rbsim.tools.measure, over at most
    OVERLAP_FRAMES frames; 2D only, None in 3D: there is no 3D ruler yet); max_speed_m_s
    (m/s, the fastest centre of mass over every frame); moved_most and moved_most_m (the
    body whose origin ends farthest from where it started, and that distance, m). With
    output.bodies, of the bodies the file holds (static ones stored once included).
    Figures of a file with no frame are None."""
    from .io.trajectory import load_frames

    series = ("position", "velocity") + (
        ("orientation", "angle") if scene.world.dimension == 2 else ()
    )
    tr = load_frames(path, series, ("kinetic_energy",))
    out: dict[str, Any] = dict.fromkeys(FIGURE_COLUMNS)
    out.update(status=tr.status, wall_time_s=tr.wall_time)
    if len(tr.step) == 0:
        return out
    rows = _written_rows(scene)
    position = tr.series["position"]
    with np.errstate(over="ignore", invalid="ignore"):
        deepest = _max_overlap(tr, scene, rows) if tr.dimension == 2 else None
        speed = np.linalg.norm(tr.series["velocity"], axis=2)
        moved = np.linalg.norm(position[-1] - position[0], axis=1)
    most = int(np.argmax(moved)) if moved.size else None
    out.update(
        steps=int(tr.step[-1]),
        kinetic_energy_J=float(tr.observables["kinetic_energy"][-1]),
        max_overlap_m=deepest,
        max_speed_m_s=float(speed.max(initial=0.0)),
        moved_most=scene.bodies[rows[most]].name if most is not None else None,
        moved_most_m=float(moved[most]) if most is not None else None,
    )
    return out


def _written_rows(scene: Scene) -> list[int]:
    """The scene's bodies that its trajectory holds in every frame (output.bodies), as
    indices into scene.bodies in the file's order."""
    return scene.output.body_indices([b.name for b in scene.bodies], [b.type for b in scene.bodies])


def _max_overlap(tr: Any, scene: Scene, rows: list[int]) -> float:
    """max_overlap_m of the frames `tr` (io.trajectory.Frames) of a 2D run of `scene`,
    whose per-frame bodies are scene.bodies[rows] (see figures), over at most
    OVERLAP_FRAMES frames evenly spread, the first and the last included."""
    from .scene.compile import build
    from .tools.measure import deepest_overlap

    model, _ = build(scene)
    frames, n = len(tr.step), len(scene.bodies)
    picks = np.unique(np.linspace(0, frames - 1, min(frames, OVERLAP_FRAMES)).round().astype(int))
    x = np.zeros((len(picks), n, 2))
    theta = np.zeros((len(picks), n))
    known = np.zeros(n, bool)

    def centres(origin: np.ndarray, orientation: np.ndarray, at: list[int]) -> np.ndarray:
        c, s = orientation[..., 0], orientation[..., 1]
        com = model.body_com[at]
        return origin + np.stack([c * com[:, 0] - s * com[:, 1], s * com[:, 0] + c * com[:, 1]], -1)

    x[:, rows] = centres(tr.series["position"][picks], tr.series["orientation"][picks], rows)
    theta[:, rows] = tr.series["angle"][picks]
    known[rows] = True
    if tr.fixed is not None and tr.fixed.angle is not None:  # static bodies stored once
        chosen = set(rows)
        once = [i for i, b in enumerate(scene.bodies) if b.type == "static" and i not in chosen]
        x[:, once] = centres(tr.fixed.position, tr.fixed.orientation, once)
        theta[:, once] = tr.fixed.angle
        known[once] = True
    return deepest_overlap(model, x, theta, known)


def fresh_folder(out: str | Path) -> bool:
    """True when `out` holds no trajectory file (or does not exist): no run of a batch
    into it can be skipped."""
    folder = Path(out)
    return not folder.is_dir() or next(folder.glob("*.h5"), None) is None


def is_complete(path: str | Path) -> bool:
    """True when `path` is a trajectory file whose status is "complete"."""
    from .io.trajectory import open_for_reading, read_parameters

    if not Path(path).is_file():
        return False
    try:
        with open_for_reading(path) as f:
            return read_parameters(f).get("status") == "complete"
    except (OSError, KeyError, ValueError):
        return False


# --------------------------------------------------------------------------------------
# Dask


# Dask settings of a local cluster (its scheduler, nannies and workers): its periodic
# work made rarer, so that it takes less of the cores the runs need. The worker's
# statistical profiler (a stack sample of the running task every 10 ms) is off; the
# event loop's health tick (20 ms), the nannies' memory checks (100 ms) and the
# system monitor (500 ms, the dashboard's graphs) run every second. Worker processes
# are forked from a fork server that imported WORKER_MODULES once (rbsim.forkserver;
# where the platform has one, else spawned): they start in a fraction of the time and
# CPU, and leave without Python's finalization, which took 1-2 s per worker at the end
# of a batch.
LOCAL_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "1s",
}


def dask_setup(worker: Any) -> None:  # noqa: ARG001 - Dask's preload interface
    """Run by Dask in every worker process this module starts (a preload): Ctrl-C in
    the terminal reaches the whole process group, and only the batch should act on it
    (a worker killed by it would be retried elsewhere and print a traceback). Imports
    WORKER_MODULES (already there when forked from the fork server)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in WORKER_MODULES:
        importlib.import_module(name)


def available_cores() -> int:
    """Cores this process may run on."""
    return config.available_cores()


def _serving(link: str) -> bool:
    """True when the dashboard page answers (a scheduler without bokeh still lists its
    web server as "dashboard", and serves no page there)."""
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(link, timeout=2) as page:
            return page.status == 200
    except (OSError, ValueError, urllib.error.URLError):
        return False


@dataclass
class Cluster:
    """A connected Dask client; `local` when this process started the cluster (a
    LocalCluster on this machine, whose workers can write into the batch's folder);
    `dashboard` the dashboard's address when one is running; `workers` the local
    cluster's number of worker processes (of one thread each), None for a scheduler's."""

    client: Any
    local: bool
    dashboard: str | None
    workers: int | None = None
    _threads: tuple[float, int] = (-math.inf, 1)  # (time.monotonic(), count) last asked

    def threads(self) -> int:
        """Worker threads of the cluster (asked of a scheduler at most once a second)."""
        if self.workers is not None:
            return self.workers
        asked, count = self._threads
        if time.monotonic() - asked > 1.0:
            try:
                count = max(1, sum(self.client.nthreads().values()))
            except (OSError, TimeoutError):
                pass
            self._threads = (time.monotonic(), count)
        return count


@contextmanager
def dask_config(settings: dict[str, Any]) -> Iterator[None]:
    """Dask's configuration with `settings` set, restored on leaving."""
    import dask

    with dask.config.set(settings):
        yield


def _connect(scheduler: str) -> tuple[Cluster, Callable[[], None]]:
    """A client of the scheduler at `scheduler` and the function that closes it."""
    from distributed import Client
    from distributed.comm import get_address_host_port

    try:
        host, port = get_address_host_port(scheduler)
    except (ValueError, TypeError) as err:
        raise BatchError(
            f"{scheduler!r} is not a scheduler address such as tcp://host:8786 ({err})"
        ) from None
    if scheduler.startswith("tcp://"):
        # a refused connection is no scheduler: said at once (Dask's client tries again
        # for its whole timeout, 10 s); a host that does not answer is left to it
        try:
            socket.create_connection((host, port), timeout=2).close()
        except ConnectionRefusedError as err:
            raise BatchError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
        except OSError:
            pass
    try:
        client = Client(scheduler, timeout=10, set_as_default=False)
    except (OSError, TimeoutError) as err:
        raise BatchError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
    try:
        services = client.scheduler_info().get("services", {})
        link = client.dashboard_link if "dashboard" in services else None
        dashboard = link if link and _serving(link) else None
    except BaseException:
        client.close()
        raise
    return Cluster(client, local=False, dashboard=dashboard), client.close


def _start_local(n: int, forked: bool) -> tuple[Cluster, Callable[[], None]]:
    """A LocalCluster of `n` single-threaded worker processes on the loopback interface
    (LOCAL_CONFIG; forked from the fork server when `forked`), its client, and the
    function that closes both. In the main thread, a Ctrl-C while the cluster starts
    waits until it has started (and is then raised, the cluster closed), where it
    would have left a half-made cluster; without a fork server, SIGINT is ignored
    meanwhile instead, so that the spawned workers inherit it (dask_setup keeps it)."""
    from distributed import Client, LocalCluster

    dashboard_address = "127.0.0.1:0" if importlib.util.find_spec("bokeh") else None
    settings = dict(LOCAL_CONFIG)
    if forked:
        settings["distributed.worker.multiprocessing-method"] = "forkserver"
    main = threading.current_thread() is threading.main_thread()
    if not main:
        guard = contextlib.nullcontext()
    else:
        guard = holding_sigint() if forked else ignoring_sigint()
    config = dask_config(settings)
    config.__enter__()  # for the cluster's whole life: a lost worker restarts alike
    cluster = client = None

    def close() -> None:
        try:
            if client is not None:
                client.close()
        finally:
            try:
                if cluster is not None:
                    cluster.close()
            finally:
                config.__exit__(None, None, None)

    try:
        with guard:
            try:
                cluster = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=dashboard_address,
                    silence_logs=logging.CRITICAL,  # shutdown races (a last heartbeat) log
                    preload=[__name__],
                )
            except (OSError, RuntimeError, TimeoutError) as err:
                raise BatchError(
                    f"cannot start a local Dask cluster of {n} workers: {err}"
                ) from None
            client = Client(cluster, set_as_default=False)
    except BaseException:
        close()
        raise

    dashboard = client.dashboard_link if dashboard_address else None
    return Cluster(client, local=True, dashboard=dashboard, workers=n), close


@contextmanager
def dask_cluster(scheduler: str | None = None, workers: int | None = None) -> Iterator[Cluster]:
    """Connect to the scheduler at `scheduler` (tcp://host:port), or start a LocalCluster
    of `workers` single-threaded worker processes (default: every core) on the loopback
    interface, with a dashboard when bokeh is installed; close it on leaving. Raises
    BatchError when the scheduler cannot be reached."""
    with starting_cluster(scheduler, workers, background=False) as start:
        yield start.get()


class ClusterStart:
    """A cluster being connected or started (see starting_cluster): `get` waits for it."""

    def __init__(self, scheduler: str | None, workers: int | None, background: bool) -> None:
        logging.getLogger("distributed").setLevel(logging.CRITICAL)
        self.scheduler = scheduler
        self.workers = workers or available_cores()
        self._made: tuple[Cluster, Callable[[], None]] | None = None
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        self._forked = scheduler is None and start_fork_server()
        if background and self._forked:  # workers that ignore SIGINT from their start
            self._thread = threading.Thread(target=self._make, name="rbsim-cluster", daemon=True)
            self._thread.start()

    def _make(self) -> None:
        try:
            if self.scheduler is not None:
                self._made = _connect(self.scheduler)
            else:
                self._made = _start_local(self.workers, self._forked)
        except BaseException as err:  # noqa: BLE001 - handed to get()
            self._error = err

    def get(self) -> Cluster:
        """The cluster, once started (in this thread, if no background start was made).
        Raises what starting it raised (BatchError)."""
        if self._thread is None and self._made is None and self._error is None:
            self._make()
        elif self._thread is not None:
            self._thread.join()
        if self._error is not None:
            raise self._error
        assert self._made is not None
        return self._made[0]

    def close(self) -> None:
        """Stop the cluster (or disconnect), waiting for a start under way to end."""
        if self._thread is not None:
            self._thread.join()
        if self._made is not None:
            made, self._made = self._made, None
            made[1]()


@contextmanager
def starting_cluster(
    scheduler: str | None = None, workers: int | None = None, background: bool = True
) -> Iterator[ClusterStart]:
    """As dask_cluster, but yields at once: with `background`, a local cluster starts
    in a thread while the caller goes on (planning the batch: the workers' start-up
    then costs the batch little wall time), and `get()` waits for it; without, `get()`
    starts it. Closed on leaving, whether or not it was used."""
    start = ClusterStart(scheduler, workers, background)
    try:
        yield start
    finally:
        start.close()


class DaskPool:
    """rbsim.tools.sweep.Pool on a Dask cluster: `map` sends every call as a task (the
    workers take them side by side), `alone` sends one task at a time to the same worker
    (the first by address; another if that one is lost)."""

    def __init__(self, client: Any) -> None:
        self.client = client
        self.timer: str | None = None  # the worker that runs the timed calls

    def map(self, fn: Callable[..., Any], calls: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        """(index, fn(*calls[index])) as the tasks finish; a task's error is raised."""
        from distributed import as_completed

        index = {}
        for i, args in enumerate(calls):
            index[self.client.submit(one_thread, fn, *args, pure=False)] = i
        for future in as_completed(list(index), loop=self.client.loop):
            yield index[future], future.result()

    def alone(self, fn: Callable[..., Any], *args: Any) -> Any:
        """fn(*args) on the timing worker, with no other task of this pool running."""
        if self.timer is None:
            self.timer = sorted(self.client.scheduler_info()["workers"])[0]
        future = self.client.submit(
            one_thread, fn, *args, workers=[self.timer], allow_other_workers=True, pure=False
        )
        return future.result()


# --------------------------------------------------------------------------------------
# The batch


@dataclass
class BatchResult:
    """A finished (or interrupted) batch: one row per spec of the plan, in its order;
    counts of unique runs: total, complete (ran now or skipped), skipped (already
    complete), failed, not finished (interrupted); the summary files; wall time (s)."""

    rows: list[dict[str, Any]]
    total: int
    complete: int
    skipped: int
    failed: int
    interrupted: int
    paths: list[Path]
    wall_time: float
    failures: list[tuple[RunSpec, str]]

    @property
    def finished(self) -> int:
        """Runs that ended (complete or failed), skipped ones included."""
        return self.complete + self.failed

    @property
    def ran(self) -> int:
        """Runs that ran in this batch (not skipped)."""
        return self.finished - self.skipped


Progress = Callable[[int, int, int], None]  # (runs finished, of them failed, total)


def _remove_parts(out: Path, specs: Sequence[RunSpec]) -> None:
    """Delete the part files, their checkpoints and the locks of the specs' unfinished
    attempts (`.<run-id>.*` in `out`), found in one listing of the folder."""
    ids = {spec.run_id for spec in specs}
    try:
        entries = list(os.scandir(out))
    except OSError:
        return
    for entry in entries:
        if not entry.name.startswith("."):
            continue
        rest = entry.name[1:]
        dot = rest.find(".")
        while dot >= 0:  # a run id may hold dots itself
            if rest[:dot] in ids:
                Path(entry.path).unlink(missing_ok=True)
                break
            dot = rest.find(".", dot + 1)


def run_batch(
    plan: Plan,
    out_dir: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retries: int = 1,
    progress: Progress | None = None,
    notify: Callable[[str], None] | None = None,
    cluster: ClusterStart | None = None,
    started: float | None = None,
) -> BatchResult:
    """Run the plan's runs into `out_dir`, skipping those whose `<run-id>.h5` is complete.

    Runs go to a LocalCluster of `workers` processes (at most one per run; by default
    every core), whose workers write into `out_dir` directly, or to the cluster at
    `scheduler`, whose workers send each file back to be written here; or to `cluster`,
    one already being started (starting_cluster), which the batch closes when it ends.
    Short runs go several to a task (about TASK_SECONDS of work each, see _Pace), and
    TASKS_AHEAD tasks per worker thread are sent at a time. A run that fails (a
    non-finite state, an error, its worker lost) is sent again up to `retries` times,
    then recorded with status "failed: ...". The summary files are written at the end,
    and on Ctrl-C, which raises BatchInterrupted after the cluster is stopped.
    notify(text) is told the dashboard's address. `started`: time.perf_counter() when
    the batch began (default: now), for its wall time. Raises BatchError."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter() if started is None else started
    runs = plan.runs()
    total = len(runs)
    old = read_summary(out / SUMMARY_CSV)
    found: dict[str, dict[str, Any]] = {}
    skipped = 0
    todo = []
    present = set(os.listdir(out))  # a fresh folder: no file opened (nor h5py imported)
    for spec in runs:
        name = f"{spec.run_id}.h5"
        if name in present and is_complete(out / name):
            prior = old.get(spec.run_id)
            good = prior is not None and prior.get("status") == "complete"
            found[spec.run_id] = prior if good else figures(out / f"{spec.run_id}.h5", spec.scene())
            skipped += 1
        else:
            todo.append(spec)
    state = _Tally(found, total, progress)
    state.report()
    interrupted = False
    try:
        with contextlib.ExitStack() as stack:
            start = cluster
            if start is None and todo:
                n = min(workers or available_cores(), len(todo))
                start = stack.enter_context(
                    starting_cluster(scheduler, None if scheduler else n, background=False)
                )
            if start is not None:
                stack.callback(start.close)
            if todo:
                assert start is not None
                running = start.get()
                if running.dashboard and notify is not None:
                    notify(f"dashboard: {running.dashboard}")
                ctrlc.raise_if_arrived()  # one lost while Dask was imported (rbsim.ctrlc)
                _run_tasks(running, todo, out, retries, state)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        _remove_parts(out, todo)
    if interrupted:  # runs that workers finished after the last one recorded
        for spec in todo:
            path = out / f"{spec.run_id}.h5"
            if spec.run_id not in found and is_complete(path):
                found[spec.run_id] = figures(path, spec.scene())
    result = _result(plan, found, skipped, out, time.perf_counter() - t0)
    if interrupted:
        raise BatchInterrupted(result)
    return result


class _Tally:
    """The figures found so far (by run id), and the progress callback told of each."""

    def __init__(self, found: dict[str, dict], total: int, progress: Progress | None) -> None:
        self.found, self.total, self.progress = found, total, progress
        self.failed = sum(1 for f in found.values() if f["status"] != "complete")

    def record(self, run_id: str, figures: dict[str, Any]) -> None:
        """Keep a finished run's figures and redraw the progress."""
        self.found[run_id] = figures
        self.failed += figures["status"] != "complete"
        self.report()

    def report(self) -> None:
        if self.progress is not None:
            self.progress(len(self.found), self.failed, self.total)


# A task of a batch holds several runs when runs are short, so that Dask's own cost per
# task (a few ms of the scheduler's and the worker's CPU, and a round trip) stays small
# beside them: about TASK_SECONDS (s) of runs, by the mean time of the runs so far, at
# most MAX_RUNS_PER_TASK, and at most the runs left / (TASKS_AHEAD x worker threads),
# so that the last tasks are small and no worker waits long for another at the end.
TASK_SECONDS = 0.5
MAX_RUNS_PER_TASK = 64
# Tasks sent ahead per worker thread: one running and one waiting on each, so that a
# worker never waits for its next task to come from the scheduler.
TASKS_AHEAD = 2


class _Pace:
    """The mean time (s) of the runs finished so far, and the runs a task gets from it."""

    def __init__(self) -> None:
        self.runs = 0
        self.seconds = 0.0

    def add(self, outcome: Outcome) -> None:
        """Count a finished run's time."""
        if outcome.seconds > 0:
            self.runs += 1
            self.seconds += outcome.seconds

    def runs_per_task(self, left: int, threads: int) -> int:
        """Runs for the next task, with `left` runs not yet sent and `threads` worker
        threads: one until a run has finished."""
        if self.runs == 0:
            return 1
        per_run = self.seconds / self.runs
        share = -(-left // (TASKS_AHEAD * threads))  # ceil
        return max(1, min(int(TASK_SECONDS / max(per_run, 1e-6)), MAX_RUNS_PER_TASK, share))


def _run_tasks(
    cluster: Cluster, todo: list[RunSpec], out: Path, retries: int, state: _Tally
) -> None:
    """Send the runs as tasks (run_jobs) TASKS_AHEAD per worker thread at a time, send
    failed runs again while retries remain, and record each run's outcome."""
    from distributed import as_completed

    client = cluster.client
    token = uuid.uuid4().hex[:8]
    out_dir = str(out.resolve()) if cluster.local else None
    attempts: dict[str, int] = {}
    waiting = collections.deque(todo)  # runs not yet sent; a retry goes first
    sent: dict[str, list[RunSpec]] = {}  # the runs of each task in flight, by key
    pending = as_completed(loop=client.loop)
    pace = _Pace()
    serial = itertools.count()

    def send() -> None:
        threads = cluster.threads()
        while waiting and len(sent) < TASKS_AHEAD * threads:
            specs = [waiting.popleft() for _ in range(pace.runs_per_task(len(waiting), threads))]
            for spec in specs:
                attempts[spec.run_id] = attempts.get(spec.run_id, 0) + 1
            key = f"rbsim-runs-{token}-{next(serial)}"
            sent[key] = specs
            jobs = [Job(spec, out_dir, __version__) for spec in specs]
            pending.add(client.submit(run_jobs, jobs, key=key, pure=False, retries=0))

    send()
    for future in pending:
        specs = sent.pop(future.key)
        try:
            outcomes = future.result()
        except Exception as err:  # noqa: BLE001 - the task's error is each run's failure
            outcomes = [Outcome(None, error=_describe(err)) for _ in specs]
        finally:
            future.release()
        for spec, outcome in zip(specs, outcomes, strict=True):
            pace.add(outcome)
            result = outcome.figures
            failure = outcome.error
            if result is not None and result["status"] != "complete":
                failure = result["status"]
            if failure is not None and attempts[spec.run_id] <= retries:
                waiting.appendleft(spec)
                continue
            if outcome.data is not None:
                part = out / f".{spec.run_id}.{token}.part"
                part.write_bytes(outcome.data)
                os.replace(part, out / f"{spec.run_id}.h5")
            if result is None:
                result = dict.fromkeys(FIGURE_COLUMNS)
                result["status"] = failure
            state.record(spec.run_id, result)
        send()


def _describe(err: BaseException) -> str:
    """The status of a run whose task raised `err`."""
    name = type(err).__name__
    if name == "KilledWorker":
        return "failed: worker lost (every worker that took this run died)"
    if name == "CancelledError":
        return "failed: the cluster cancelled the run"
    text = str(err).splitlines()[0] if str(err) else ""
    return f"failed: {name}: {text}" if text else f"failed: {name}"


def _result(
    plan: Plan, found: dict[str, dict], skipped: int, out: Path, wall: float
) -> BatchResult:
    rows, failures = [], []
    for spec in plan.specs:
        got = found.get(spec.run_id)
        row: dict[str, Any] = {"run_id": spec.run_id, "scene": spec.scene_path}
        row.update(dict(spec.varied))
        if got is None:
            row.update(dict.fromkeys(FIGURE_COLUMNS), status="interrupted")
        else:
            row.update({k: got.get(k) for k in FIGURE_COLUMNS})
        rows.append(row)
    unique = plan.runs()
    complete = sum(1 for s in unique if found.get(s.run_id, {}).get("status") == "complete")
    failed = 0
    for spec in unique:
        status = found.get(spec.run_id, {}).get("status")
        if status is not None and status != "complete":
            failed += 1
            failures.append((spec, status))
    paths = write_summary(rows, plan.varied_keys, out)
    return BatchResult(
        rows=rows,
        total=len(unique),
        complete=complete,
        skipped=skipped,
        failed=failed,
        interrupted=len(unique) - complete - failed,
        paths=paths,
        wall_time=wall,
        failures=failures,
    )


# --------------------------------------------------------------------------------------
# The summary


def summary_columns(varied_keys: Sequence[str]) -> list[str]:
    """run_id, scene, the varied keys, then FIGURE_COLUMNS."""
    return ["run_id", "scene", *varied_keys, *FIGURE_COLUMNS]


def write_summary(rows: Sequence[dict], varied_keys: Sequence[str], out: Path) -> list[Path]:
    """Write `summary.csv` (floats to every digit, empty for a missing figure) and, when
    pyarrow is installed, `summary.parquet` (varied values as numbers when every one is
    a number); each written to a temporary name first. Returns the paths written."""
    columns = summary_columns(varied_keys)
    path = out / SUMMARY_CSV
    part = out / f".{SUMMARY_CSV}.part"
    with open(part, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if row.get(k) is None else row[k] for k in columns})
    os.replace(part, path)
    paths = [path]
    if importlib.util.find_spec("pyarrow") is not None:
        paths.append(_write_parquet(rows, columns, varied_keys, out))
    return paths


def _write_parquet(
    rows: Sequence[dict], columns: list[str], varied: Sequence[str], out: Path
) -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    data: dict[str, Any] = {}
    for name in columns:
        values = [row.get(name) for row in rows]
        if name in _INT_COLUMNS:
            data[name] = pa.array(values, pa.int64())
        elif name in _FLOAT_COLUMNS or name == "moved_most_m":
            data[name] = pa.array(values, pa.float64())
        elif name in varied and all(_number(v) is not None for v in values):
            data[name] = pa.array([_number(v) for v in values], pa.float64())
        else:
            data[name] = pa.array(values, pa.string())
    path = out / SUMMARY_PARQUET
    part = out / f".{SUMMARY_PARQUET}.part"
    pq.write_table(pa.table(data), part)
    os.replace(part, path)
    return path


def _number(text: Any) -> float | None:
    return _scalar(text) if isinstance(text, str) else None


def read_summary(path: Path) -> dict[str, dict[str, Any]]:
    """The figures of each run id in an earlier summary.csv ({} when there is none or
    it cannot be read), typed as `figures` returns them."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error):
        return {}
    out = {}
    for row in rows:
        try:
            got: dict[str, Any] = {}
            for k in FIGURE_COLUMNS:
                text = row[k]
                if text == "" or text is None:
                    got[k] = None
                elif k in _INT_COLUMNS:
                    got[k] = int(text)
                elif k in _FLOAT_COLUMNS or k == "moved_most_m":
                    got[k] = float(text)
                else:
                    got[k] = text
            out[row["run_id"]] = got
        except (KeyError, ValueError, TypeError):
            continue
    return out
