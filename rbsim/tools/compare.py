"""`rbsim compare`: the same scene in rbsim and in a reference engine, pymunk in 2D and
MuJoCo in 3D (REFERENCE), and the differences between them.

In 3D MuJoCo steps the scene as rbsim.engines.mujoco writes it (rbsim's own masses and
inertia tensors, steps of dt / substeps, soft contacts with a damping ratio per pair
calibrated to the pair's restitution; the settings are stated in the output), and the
angle compared is the angle of the rotation between the two orientations,
2 acos |q1 · q2|. MuJoCo's impacts last several steps, so a state inside one is compared
with rbsim's path through it (SOFT_IMPACTS). What follows is said of pymunk and holds
for MuJoCo alike; 3D overlaps are measured with MuJoCo's collision functions.

Both engines write a trajectory in the same H5MD layout (docs/format.md), with frames at the
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
import itertools
import math
import textwrap
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engines import Engine, UnsupportedScene, make_engine
from ..engines.pymunk import PymunkSettings, PymunkWorld
from ..io.trajectory import Trajectory, load_trajectory
from ..run import file_stem, run_scene
from ..scene import Scene
from ..scene.geometry3d import quat_matrix

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
    "angular_velocity": ("max_angular_velocity", "rad/s", "angular velocity difference"),
}

# Events (impacts): a frame-to-frame change of a body's velocity or angular velocity that
# departs from the local trend (the median rate of change over the three intervals on either
# side, so that gravity, forces, precession and resting contact are not events) by more
# than the quantity's tolerance and more than EVENT_FRACTION of the body's largest speed
# in either run (round-off and solver jitter are not events). Consecutive jump frames are
# one event (an impact resolved over two steps).
EVENT_FRACTION = 1e-3
# The two engines' events are paired, in order, when their first jump frames are at most
# EVENT_FRAMES frames apart: each engine resolves an impact within one of its steps of the
# contact instant (a frame is one or more steps), so their jumps land in the same or the
# next frame, and an impact spread over two steps adds one. An event without a partner is
# a missed or an extra impact, reported when velocity or angular velocity is checked.
EVENT_FRAMES = 3

# Statistic -> (unit, words for the table and messages); see `statistics`.
STATISTICS: dict[str, tuple[str, str]] = {
    "kinetic_energy": ("J", "final kinetic energy"),
    "mean_height": ("m", "final mean height"),
    "heights": ("m", "final heights: spread | sorted gap"),
    "penetration": ("m", "max penetration (whole run)"),
}

# The reference engine of each world.dimension
REFERENCE = {2: "pymunk", 3: "mujoco"}
# Reference engines whose impacts take several steps (soft contacts): states inside an
# impact are compared with rbsim's path through it (aligned_difference's `through`)
SOFT_IMPACTS = {"mujoco"}

TABLE_ROWS = 10  # bodies shown in the table when there are more

# Frames on which the penetration is measured (evenly spread; every frame when fewer):
# each costs one pymunk shape query per dynamic shape.
PENETRATION_FRAMES = 400


@dataclass
class BodyDiff:
    """Differences rbsim - the other engine for one body over the run: positions of the
    body origin (m), angles (rad; in 3D the rotation angle between the two orientations),
    centre-of-mass velocities (m/s), angular velocities (rad/s); `*_step` is where the max
    is. Velocities and angular velocities are compared with the engines' impacts lined
    up (see `aligned_difference`): `impacts` is how many impacts (events) were paired,
    `max_offset` (s) the largest time offset between paired impacts (the other engine's
    time minus rbsim's), `unmatched` one (engine, time s) per impact without a partner."""

    name: str
    max_position: float
    final_position: float
    max_angle: float
    final_angle: float
    max_velocity: float
    max_position_step: int
    max_angle_step: int
    max_velocity_step: int
    max_angular_velocity: float = 0.0
    max_angular_velocity_step: int = 0
    impacts: int = 0
    max_offset: float = 0.0
    unmatched: list[tuple[str, float]] = field(default_factory=list)


@dataclass
class CompareResult:
    """What `rbsim compare` reports. energy: total kinetic + potential at the end (J);
    momentum: linear momentum at the end (kg·m/s); us_per_step: wall time per scene step
    in stepping alone (µs); violations: one message per checked quantity over tolerance;
    reference: the other engine ("pymunk" in 2D, "mujoco" in 3D), the key of its entries
    beside "rbsim"; pymunk_settings: the reference engine's settings (MuJoCo's in 3D);
    angular_momentum: about the world origin at the end (kg·m²/s; one value in 2D);
    reference_contacts: the reference engine's contact settings in words (MuJoCo's: its
    step, contact law and per pair kind the damping and the rebound it gives), "" or
    "disabled" when it has none to state."""

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
    reference: str = "pymunk"
    angular_momentum: dict[str, list[float]] = field(default_factory=dict)
    reference_contacts: str = ""

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
            "reference": self.reference,
            "steps": self.steps,
            "tolerances": dict(self.tolerances),
            "bodies": [dataclasses.asdict(b) for b in self.bodies],
            "energy": dict(self.energy),
            "linear_momentum": {k: list(v) for k, v in self.momentum.items()},
            "angular_momentum": {k: list(v) for k, v in self.angular_momentum.items()},
            "us_per_step": dict(self.us_per_step),
            "files": dict(self.files),
            "pymunk_settings": dict(self.pymunk_settings),
            "statistics": None if self.statistics is None else dict(self.statistics),
            "statistics_tolerances": dict(self.statistics_tolerances),
            "violations": list(self.violations),
            "reference_contacts": self.reference_contacts,
        }

    def table(self) -> str:
        """The human-readable report."""
        shown = self.worst()
        other = self.reference
        lines = [f"{self.scene}: rbsim against {other}, {self.steps} steps"]
        if len(shown) < len(self.bodies):
            lines[0] += f" ({len(shown)} worst of {len(self.bodies)} bodies by position)"
        width = max([4, *(len(b.name) for b in shown)])
        head = (
            f"  {'body':<{width}}  {'pos max m':>10}  {'pos end m':>10}  {'ang max rad':>11}"
            f"  {'ang end rad':>11}  {'vel max m/s':>11}  {'ω max rad/s':>11}"
            f"  {'impacts':>7}  {'Δt impact s':>11}"
        )
        lines.append(head)
        for b in shown:
            impacts = f"{b.impacts}" + (f"+{len(b.unmatched)}?" if b.unmatched else "")
            lines.append(
                f"  {b.name:<{width}}  {b.max_position:>10.3g}  {b.final_position:>10.3g}  "
                f"{b.max_angle:>11.3g}  {b.final_angle:>11.3g}  {b.max_velocity:>11.3g}  "
                f"{b.max_angular_velocity:>11.3g}  {impacts:>7}  {b.max_offset:>11.3g}"
            )
        lines.append(
            "  (velocities compared with the engines' impacts lined up; Δt impact: the "
            "largest time offset, other engine − rbsim; +n?: impacts only one engine has)"
        )
        tol = ", ".join(f"{k} {v:g} {QUANTITIES[k][1]}" for k, v in self.tolerances.items())
        lines.append(f"  tolerance: {tol or 'none (nothing checked)'}")
        lines.append("")
        lines.append(f"  {'at the end':<22}  {'rbsim':>14}  {other:>14}")
        lines.append(
            f"  {'energy (KE + PE) J':<22}  {self.energy['rbsim']:>14.6g}  "
            f"{self.energy[other]:>14.6g}"
        )
        for k, axis in enumerate("xyz"[: len(self.momentum["rbsim"])]):
            lines.append(
                f"  {'momentum ' + axis + ' kg m/s':<22}  {self.momentum['rbsim'][k]:>14.6g}  "
                f"{self.momentum[other][k]:>14.6g}"
            )
        spin = self.angular_momentum
        for k in range(len(spin.get("rbsim", ()))):
            axis = " " + "xyz"[k] if len(spin["rbsim"]) == 3 else ""
            lines.append(
                f"  {'ang. mom.' + axis + ' kg m²/s':<22}  {spin['rbsim'][k]:>14.6g}  "
                f"{spin[other][k]:>14.6g}"
            )
        lines.append(
            f"  {'wall time / step µs':<22}  {self.us_per_step['rbsim']:>14.2f}  "
            f"{self.us_per_step[other]:>14.2f}"
        )
        if self.statistics is not None:
            lines.append("")
            lines.append(
                f"  {'statistics':<34}  {'rbsim':>11}  {other:>11}  {'difference':>11}"
                f"  {'tolerance':>9}"
            )
            for key, (unit, words) in STATISTICS.items():
                st = self.statistics[key]
                tol = self.statistics_tolerances.get(key)
                lines.append(
                    f"  {words + ' ' + unit:<34}  {st['rbsim']:>11.4g}  {st[other]:>11.4g}"
                    f"  {st['difference']:>11.4g}  {'-' if tol is None else f'{tol:g}':>9}"
                )
        if self.reference_contacts and self.reference_contacts != "disabled":
            lines.append("")
            lines += textwrap.wrap(
                f"{other} contacts: {self.reference_contacts}",
                width=100,
                initial_indent="  ",
                subsequent_indent="    ",
            )
        lines.append(f"  files: {self.files['rbsim']}, {self.files[other]}")
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


def angle_difference(ra: Trajectory, pm: Trajectory) -> np.ndarray:
    """(T, N) angle between the two engines' orientations, rad. 2D: |a - b| of the
    unwrapped angles (both engines start from the scene's angle, so the unwrapped
    difference is the physical one: a whole extra turn counts). 3D: the angle of the
    rotation taking one orientation to the other, 2 acos |q1 · q2| (q and -q are the
    same rotation), computed as 4 atan2(|q1 - s q2|, |q1 + s q2|) with s the sign of
    q1 · q2 (|q1 ∓ q2| = 2 sin or 2 cos of a quarter of the angle), which keeps its
    accuracy near 0 where acos loses half the digits."""
    if ra.angle is not None and pm.angle is not None:
        return np.abs(ra.angle - pm.angle)
    q1, q2 = ra.orientation, pm.orientation
    sign = np.where(np.sum(q1 * q2, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    minus = np.linalg.norm(q1 - sign * q2, axis=-1)
    plus = np.linalg.norm(q1 + sign * q2, axis=-1)
    return 4.0 * np.arctan2(minus, plus)


def _columns(series: np.ndarray) -> np.ndarray:
    """(T, N, k) view of a (T, N) or (T, N, k) per-body series."""
    return series[:, :, None] if series.ndim == 2 else series


def trend(time: np.ndarray, series: np.ndarray) -> np.ndarray:
    """(T-1, k) the local trend of `series` (T, k): per interval i (frame i to i+1), the
    median rate of change (per second; time (T,) s) of the three intervals on either
    side of it, i itself left out. A steady acceleration or a smooth turn follows it (off
    by at most 2 |v''| h², at the ends), and a jump, even spread over two intervals (two
    outliers of six), does not move it."""
    change = np.diff(series, axis=0)
    if len(change) == 0:
        return np.zeros((0, series.shape[1]))
    rate = change / np.diff(time)[:, None]
    padded = np.pad(rate, ((3, 3), (0, 0)), constant_values=np.nan)
    n = len(rate)
    around = np.stack([padded[k : k + n] for k in (0, 1, 2, 4, 5, 6)])
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN: fewer than 2 frames
        return np.nan_to_num(np.nanmedian(around, axis=0))


def jump_frames(time: np.ndarray, series: np.ndarray, threshold: float) -> np.ndarray:
    """(T-1,) bool: whether the change of `series` (T, k) from frame i to i+1 departs from
    its local `trend` times the interval's length by more than `threshold` (the series'
    unit): a steady acceleration, a smooth turn or the interval next to a jump spread
    over two intervals are not jumps."""
    change = np.diff(series, axis=0)
    span = np.diff(time)[:, None]
    return np.linalg.norm(change - trend(time, series) * span, axis=1) > threshold


def events(jumps: np.ndarray) -> list[tuple[int, int]]:
    """The runs of consecutive True in `jumps` (T-1,) as (first, last) interval indices:
    the state jumps between frames first and last + 1."""
    out: list[tuple[int, int]] = []
    for i in np.flatnonzero(jumps):
        if out and out[-1][1] == i - 1:
            out[-1] = (out[-1][0], int(i))
        else:
            out.append((int(i), int(i)))
    return out


def pair_events(
    a: list[tuple[int, int]], b: list[tuple[int, int]], frames: int = EVENT_FRAMES
) -> tuple[list[tuple[tuple[int, int], tuple[int, int]]], list[int], list[int]]:
    """Pair two engines' events in time order: the next two pair when their first jump
    frames are at most `frames` apart, else the earlier one has no partner. Returns
    (pairs, indices of a's unpaired events, indices of b's)."""
    pairs, lone_a, lone_b = [], [], []
    i = j = 0
    while i < len(a) and j < len(b):
        if abs(a[i][0] - b[j][0]) <= frames:
            pairs.append((a[i], b[j]))
            i, j = i + 1, j + 1
        elif a[i][0] < b[j][0]:
            lone_a.append(i)
            i += 1
        else:
            lone_b.append(j)
            j += 1
    return pairs, lone_a + list(range(i, len(a))), lone_b + list(range(j, len(b)))


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from point p to the segment from a to b (the units of the points)."""
    ab = b - a
    span = float(ab @ ab)
    t = 0.0 if span == 0.0 else min(max(float((p - a) @ ab) / span, 0.0), 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def aligned_difference(
    a: np.ndarray,
    b: np.ndarray,
    pairs: list[tuple[tuple[int, int], tuple[int, int]]],
    time: np.ndarray | None = None,
    through: bool = False,
) -> np.ndarray:
    """(T,) |a - b| per frame for two (T, k) series, with paired jumps lined up: on the
    frames between the two engines' jumps of a pair (one engine has jumped, the other
    not yet), each engine's state is compared with the nearest state of the other over
    the pair's frames (from the frame before the first jump to the frame after the last),
    carried to the frame's time along its local `trend` (so that gravity acting over the
    offset is no difference; time (T,) s, None: no carrying), the larger of the two
    ways. Everywhere else, frame by frame: a wrong post-impact velocity or a missed
    impact still shows in full after the pair's frames. `through`: for an engine whose
    impacts take time (MuJoCo's soft contacts last several steps, so a frame may fall
    inside one), a state is compared with the other's path over the pair's frames
    instead, the segments joining its carried states: a velocity on its way from before
    to after the impact is no difference."""
    diff = np.linalg.norm(a - b, axis=1)
    if not pairs:
        return diff
    carry = time is not None and len(a) > 1

    def nearest(x: np.ndarray, k: int, y: np.ndarray, rate: np.ndarray | None, w: range) -> float:
        guesses = []
        for j in w:
            guess = y[j]
            if rate is not None and j != k:
                interval = min(j, k) if j < k else j - 1  # the rate beside j, towards k
                guess = y[j] + rate[interval] * (time[k] - time[j])
            guesses.append(guess)
        best = min(float(np.linalg.norm(x[k] - g)) for g in guesses)
        if through:
            for g0, g1 in itertools.pairwise(guesses):
                best = min(best, segment_distance(x[k], g0, g1))
        return best

    rate_a = trend(time, a) if carry else None
    rate_b = trend(time, b) if carry else None
    for (a0, a1), (b0, b1) in pairs:
        lo, hi = min(a0, b0) + 1, max(a1, b1)
        window = range(lo - 1, min(hi + 2, len(a)))
        for k in range(lo, hi + 1):
            diff[k] = max(nearest(a, k, b, rate_b, window), nearest(b, k, a, rate_a, window))
    return diff


def body_diffs(
    ra: Trajectory,
    pm: Trajectory,
    tolerances: dict[str, float] | None = None,
    engines: tuple[str, str] = ("rbsim", "pymunk"),
    through: bool = False,
) -> list[BodyDiff]:
    """Per-body differences between two trajectories with the same frames and bodies.
    Velocity jumps (impacts) are found in each run (`jump_frames`, with the velocity and
    angular_velocity `tolerances` as thresholds: the jumps of the checked ones among the
    two, or of both when neither is checked), paired (`pair_events`) and lined up for the
    velocity and angular velocity differences (`aligned_difference`).
    `engines` names the two runs in `unmatched`; `through`: compare states inside an
    impact with the other engine's path through it (`aligned_difference`), for a
    reference engine whose impacts take time."""
    if not np.array_equal(ra.step, pm.step):
        raise ValueError("the two trajectories have different frames")
    tolerances = tolerances or {}
    dpos = np.linalg.norm(ra.position - pm.position, axis=2)  # (T, N)
    dang = angle_difference(ra, pm)
    vel = (ra.velocity, pm.velocity)
    omega = (_columns(ra.angular_velocity), _columns(pm.angular_velocity))
    time = ra.time
    # the quantities whose jumps are events: those checked, else both (for the report)
    watched = [
        (series, key)
        for series, key in ((vel, "velocity"), (omega, "angular_velocity"))
        if key in tolerances
    ] or [(vel, "velocity"), (omega, "angular_velocity")]
    out = []
    for i, name in enumerate(ra.bodies.name):
        jumps = [np.zeros(max(len(time) - 1, 0), bool) for _ in engines]
        for series, key in watched:
            scale = max(float(np.abs(s[:, i]).max(initial=0.0)) for s in series)
            threshold = max(tolerances.get(key, 0.0), EVENT_FRACTION * scale)
            for e in range(2):
                jumps[e] |= jump_frames(time, series[e][:, i], threshold)
        ev_ra, ev_pm = events(jumps[0]), events(jumps[1])
        pairs, lone_ra, lone_pm = pair_events(ev_ra, ev_pm)
        dvel = aligned_difference(vel[0][:, i], vel[1][:, i], pairs, time, through)
        domg = aligned_difference(omega[0][:, i], omega[1][:, i], pairs, time, through)
        offsets = [float(time[b[0]] - time[a[0]]) for a, b in pairs]
        unmatched = [(engines[0], float(time[ev_ra[k][0] + 1])) for k in lone_ra] + [
            (engines[1], float(time[ev_pm[k][0] + 1])) for k in lone_pm
        ]
        ip, ia, iv, iw = (int(np.argmax(d)) for d in (dpos[:, i], dang[:, i], dvel, domg))
        out.append(
            BodyDiff(
                name=name,
                max_position=float(dpos[ip, i]),
                final_position=float(dpos[-1, i]),
                max_angle=float(dang[ia, i]),
                final_angle=float(dang[-1, i]),
                max_velocity=float(dvel[iv]),
                max_position_step=int(ra.step[ip]),
                max_angle_step=int(ra.step[ia]),
                max_velocity_step=int(ra.step[iv]),
                max_angular_velocity=float(domg[iw]),
                max_angular_velocity_step=int(ra.step[iw]),
                impacts=len(pairs),
                max_offset=max(offsets, key=abs, default=0.0),
                unmatched=sorted(unmatched, key=lambda u: u[1]),
            )
        )
    return out


def violations(bodies: list[BodyDiff], tolerances: dict[str, float]) -> list[str]:
    """One message per body and checked quantity above its tolerance (NaN counts), and,
    when velocity or angular velocity is checked, one per impact that only one engine
    has (a missed or an extra collision)."""
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
        if "velocity" in tolerances or "angular_velocity" in tolerances:
            for engine, t in b.unmatched:
                found.append(
                    f"body {b.name!r}: a velocity jump (impact) at t = {t:.6g} s in {engine} "
                    f"has no match in the other engine within {EVENT_FRAMES} frames"
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
    norm = float(np.linalg.norm(g))
    return -g / norm if norm > 0.0 else np.eye(len(g))[1]


def final_heights(tr: Trajectory, scene: Scene) -> np.ndarray:
    """Heights (m) of the dynamic bodies' centres of mass at the last frame, measured
    against gravity (along y when there is none), in scene order."""
    dynamic = np.array([b.type == "dynamic" for b in scene.bodies], dtype=bool)
    com = tr.bodies.center_of_mass
    if tr.orientation.shape[-1] == 4:  # 3D: x + R(q) com
        rot = quat_matrix(tr.orientation[-1])
        x = tr.position[-1] + np.einsum("nij,nj->ni", rot, com)
        return x[dynamic] @ _up(scene)
    c, sn = tr.orientation[-1, :, 0], tr.orientation[-1, :, 1]
    x = tr.position[-1] + np.stack(
        [c * com[:, 0] - sn * com[:, 1], sn * com[:, 0] + c * com[:, 1]], axis=1
    )
    return x[dynamic] @ _up(scene)


def frames_measured(count: int, frames: int = PENETRATION_FRAMES) -> np.ndarray:
    """Indices of at most `frames` of `count` frames, evenly spread, the first and the
    last included."""
    return np.unique(np.linspace(0, count - 1, min(count, max(frames, 2))).round().astype(int))


def max_penetration_3d(tr: Trajectory, scene: Scene, frames: int = PENETRATION_FRAMES) -> float:
    """Largest overlap (m) of two shapes that can touch over the frames of a 3D
    trajectory `tr` (at most `frames` of them, evenly spread), measured with MuJoCo's
    collision functions on a MuJoCo model of `scene` (engines.mujoco
    MujocoEngine.deepest_overlap), so that both engines' runs are measured with one
    ruler; 0 when nothing overlaps."""
    ruler = make_engine("mujoco", scene)
    return max(
        (
            ruler.deepest_overlap(tr.position[t], tr.orientation[t])
            for t in frames_measured(len(tr.step), frames)
        ),
        default=0.0,
    )


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
    deepest = 0.0
    for t in frames_measured(len(tr.step), frames):
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


def statistics(
    ra: Trajectory, pm: Trajectory, scene: Scene, reference: str = "pymunk"
) -> dict[str, dict[str, float]]:
    """Statistics of the two runs: statistic -> {"rbsim", reference, "difference"}
    (reference: the other engine's name, "pymunk" in 2D, "mujoco" in 3D).

    kinetic_energy: total at the last frame (J). mean_height: mean final height of the
    dynamic bodies' centres of mass (m). heights: per engine the spread (standard
    deviation) of the final heights, and as the difference the distance between the two
    distributions, the mean gap between the sorted heights (the 1-Wasserstein distance;
    body identities do not matter) (m). penetration: the
    largest overlap of two shapes over the run (m); its difference is the larger of
    the two, which is what a penetration tolerance bounds. In 3D the overlaps are
    measured with MuJoCo's collision functions (`max_penetration_3d`).
    """
    out: dict[str, dict[str, float]] = {}
    other = reference

    def entry(a: float, b: float, difference: float) -> dict[str, float]:
        return {"rbsim": a, other: b, "difference": difference}

    ke = [float(tr.observables["kinetic_energy"][-1]) for tr in (ra, pm)]
    out["kinetic_energy"] = entry(ke[0], ke[1], abs(ke[0] - ke[1]))
    h_ra, h_pm = final_heights(ra, scene), final_heights(pm, scene)
    mean = [float(h.mean()) if h.size else 0.0 for h in (h_ra, h_pm)]
    out["mean_height"] = entry(mean[0], mean[1], abs(mean[0] - mean[1]))
    gap = float(np.abs(np.sort(h_ra) - np.sort(h_pm)).mean()) if h_ra.size else 0.0
    spread = [float(h.std()) if h.size else 0.0 for h in (h_ra, h_pm)]
    out["heights"] = entry(spread[0], spread[1], gap)
    ruler = max_penetration_3d if ra.orientation.shape[-1] == 4 else max_penetration
    pen = [ruler(tr, scene) for tr in (ra, pm)]
    out["penetration"] = entry(pen[0], pen[1], max(pen))
    return out


def statistics_violations(
    stats: dict[str, dict[str, float]], tolerances: dict[str, float], reference: str = "pymunk"
) -> list[str]:
    """One message per statistic above its tolerance (NaN counts); `reference` names the
    other engine's entries."""
    found = []
    for key, tol in tolerances.items():
        unit, words = STATISTICS[key]
        st = stats[key]
        if key == "penetration":
            for engine in ("rbsim", reference):
                if not st[engine] <= tol:
                    found.append(
                        f"statistics: {words} {st[engine]:.4g} {unit} in {engine} exceeds "
                        f"the penetration tolerance {tol:g} {unit}"
                    )
        elif not st["difference"] <= tol:
            found.append(
                f"statistics: {words}: rbsim {st['rbsim']:.6g} {unit}, {reference} "
                f"{st[reference]:.6g} {unit}, difference {st['difference']:.4g} {unit} "
                f"exceeds the {key} tolerance {tol:g} {unit}"
            )
    return found


def reference_engine(scene: Scene) -> str:
    """The engine rbsim is compared with: pymunk in 2D, MuJoCo in 3D (REFERENCE)."""
    return REFERENCE[int(getattr(scene.world, "dimension", 2))]


def _same_run(scene: Scene, other: Scene, reference: str = "pymunk") -> None:
    """Raise UnsupportedScene unless `other` (the reference engine's scene) has the same
    bodies, steps, step length and output frames as `scene`."""
    why = None
    if [b.name for b in scene.bodies] != [b.name for b in other.bodies]:
        why = "its bodies differ"
    elif (scene.world.steps, scene.world.dt) != (other.world.steps, other.world.dt):
        why = "its steps or dt differ"
    elif scene.output.every != other.output.every:
        why = "its output.every differs"
    elif scene.solver.substeps != other.solver.substeps:
        why = f"its solver.substeps differ ({reference}'s step length)"
    if why:
        raise UnsupportedScene(f"{reference}'s scene must run the same frames as rbsim's: {why}")


def _warm_up(scene: Scene, engine: str) -> None:
    """Take one step of the scene on a throwaway world, so that loading rbsim's engine
    is not counted in its wall time per step."""
    make_engine(engine, scene).advance(1)


def _reference_options(scene: Scene, reference: str, iterations: int | None) -> dict:
    """The reference engine's options: pymunk steps as long as rbsim's substeps (and
    `iterations`); MuJoCo takes solver.substeps steps of dt / substeps."""
    if reference == "pymunk":
        return {"settings": pymunk_settings_for(scene, iterations)}
    from ..engines.mujoco import MujocoSettings

    return {"settings": MujocoSettings(substeps=int(scene.solver.substeps))}


def _floor_check(engine: Engine, tol: dict[str, float]) -> None:
    """Raise UnsupportedScene when MuJoCo's least rebound, which it gives for e = 0 (its
    damping is explicit), would show as a velocity difference above the velocity
    tolerance: e_mujoco times the pair's estimated fastest approach."""
    if "velocity" not in tol:
        return
    for p in getattr(engine, "pairs", ()):
        jump = p.e_mujoco * p.speed
        if p.restitution == 0.0 and jump > tol["velocity"]:
            raise UnsupportedScene(
                f"bodies {p.bodies[0]!r} and {p.bodies[1]!r} have restitution 0, out of "
                f"MuJoCo's reach: its contacts are soft with explicit damping and rebound "
                f"at least e = {p.e_mujoco:.3g}; an impact at up to {p.speed:.3g} m/s (a bound "
                "on their approach speed, not a predicted impact) would "
                f"leave at {jump:.3g} m/s in MuJoCo and at 0 in rbsim, above the velocity "
                f"tolerance {tol['velocity']:g} m/s (compare this scene statistically, or "
                "with a restitution MuJoCo reaches)"
            )


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
    """Run `scene` in rbsim and in the reference engine (pymunk in 2D, MuJoCo in 3D),
    writing out_dir/<name>.rbsim.h5 and out_dir/<name>.<reference>.h5, and compare them.
    Statistics (see `statistics`) are computed when `with_statistics` or the
    scene has a compare.statistics block. `pymunk_scene` (default `scene`) is what the
    reference engine runs: the same scene with a setting changed, to see how much that
    setting matters. Raises UnsupportedScene (the reference engine cannot express the
    scene) and EngineUnavailable (MuJoCo is not installed) before running either engine,
    and whatever run_scene raises. `engine` is rbsim's side (engines.RBSIM_ENGINES)."""
    out_dir = Path(out_dir)
    reference = reference_engine(scene)
    pm_scene = scene if pymunk_scene is None else pymunk_scene
    _same_run(scene, pm_scene, reference)
    wanted = with_statistics or "statistics" in scene.compare
    options = _reference_options(scene, reference, iterations)
    probe = make_engine(reference, pm_scene, **options)  # UnsupportedScene before any work
    tol = tolerances_for(scene, position=position, angle=angle, velocity=velocity)
    _floor_check(probe, tol)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        "rbsim": str(out_dir / f"{file_stem(scene.name)}.rbsim.h5"),
        reference: str(out_dir / f"{file_stem(scene.name)}.{reference}.h5"),
    }
    _warm_up(scene, engine)
    summary = run_scene(scene, files["rbsim"], engine=engine)
    other = run_scene(pm_scene, files[reference], engine=reference, options=options)
    ra, pm = load_trajectory(files["rbsim"]), load_trajectory(files[reference])
    # MuJoCo's contacts are soft: its impacts last several steps (SOFT_IMPACTS)
    soft = reference in SOFT_IMPACTS
    bodies = body_diffs(ra, pm, tol, engines=("rbsim", reference), through=soft)
    steps = int(scene.world.steps)

    def energy(tr: Trajectory) -> float:
        return float(tr.observables["kinetic_energy"][-1] + tr.observables["potential_energy"][-1])

    stat_tol = {
        k: float(v)
        for k, v in (scene.compare.get("statistics") or {}).items()
        if k in STATISTICS and v is not None
    }
    stats = statistics(ra, pm, scene, reference) if wanted else None

    def per_step(seconds: float) -> float:
        return 1e6 * seconds / steps if steps else math.nan

    return CompareResult(
        scene=scene.name,
        steps=steps,
        bodies=bodies,
        tolerances=tol,
        energy={"rbsim": energy(ra), reference: energy(pm)},
        momentum={
            "rbsim": [float(x) for x in ra.observables["linear_momentum"][-1]],
            reference: [float(x) for x in pm.observables["linear_momentum"][-1]],
        },
        us_per_step={"rbsim": per_step(summary.step_time), reference: per_step(other.step_time)},
        angular_momentum={
            name: np.atleast_1d(tr.observables["angular_momentum"][-1]).astype(float).tolist()
            for name, tr in (("rbsim", ra), (reference, pm))
        },
        files=files,
        pymunk_settings=dataclasses.asdict(options["settings"]),
        violations=violations(bodies, tol)
        + statistics_violations(stats or {}, stat_tol, reference),
        statistics=stats,
        statistics_tolerances=stat_tol,
        reference=reference,
        reference_contacts=str(probe.settings.get("contacts", "")),
    )
