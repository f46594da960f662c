"""`make report`: the work-precision report, rbsim against pymunk, written into reports/.

    python -m rbsim.tools.report [-o reports] [--quick]

Runs `rbsim sweep` on every scene of scenes/reference/ (each with a grid sized to keep
the whole report within about ten minutes on two cores), measures cost per step against
the number of bodies, and writes reports/work-precision.md with the plots and the data
(CSV/JSON) beside it. Every figure and sentence about the results is generated from the
measurements of this run; the file is never edited by hand.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import time
from pathlib import Path

from .. import __version__
from ..scene import load_scene
from ..scene.library import scenes_dir
from .sweep import (
    DOMINANCE_TIME_RATIO,
    Grid,
    SweepResult,
    dt_text,
    fitted_slope,
    measure_scaling,
    plot_scaling,
    plot_sweep,
    run_sweep,
)

SCENES = scenes_dir("reference")

# The grid of each reference scene: small scenes get the full default grid; the stack and
# the pyramid (every run costs far more) fewer dts and one rotation update (nothing
# spins in them, so the rotation update changes nothing measurable).
GRIDS: dict[str, Grid] = {
    "projectile": Grid(),
    "free_spin": Grid(),
    "slide": Grid(),
    "bounce": Grid(),
    "collision": Grid(),
    "stack": Grid(dts=(1 / 30, 1 / 60, 1 / 120, 1 / 240, 1 / 480), rotations=("normalize",)),
    "pyramid20": Grid(dts=(1 / 30, 1 / 60, 1 / 120, 1 / 240), rotations=("normalize",)),
}
QUICK = Grid(
    dts=(1 / 30, 1 / 60),
    substeps=(4,),
    iterations=(1,),
    rotations=("normalize",),
    pymunk_iterations=(10,),
)

# Pyramids of these bases: 105, 300, 1035, 3003 and 10011 bodies with the ground.
SCALING_BASES = (14, 24, 45, 77, 141)
QUICK_SCALING_BASES = (4, 8)


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "–" if x is None else format(x, spec)


def scene_section(result: SweepResult, png: str) -> list[str]:
    """Markdown for one scene: reference, verdict, the two fronts, the plot."""
    v = result.verdict()
    lines = [
        f"## {result.scene}",
        "",
        f"- reference: {result.reference}",
        f"- error: {result.metric}",
        f"- {result.duration:g} s simulated, errors sampled every {dt_text(result.sample_dt)} s; "
        f"{len(result.points)} runs",
        f"- **{result.verdict_line().removeprefix('verdict: ')}**",
        "",
        f"![{result.scene}]({png})",
        "",
        "Pareto fronts (cost in ms of CPU per simulated second):",
        "",
        "| engine | setting | dt s | cpu ms/s | error m |",
        "|---|---|---|---|---|",
    ]
    for p in sorted((p for p in result.points if p.front), key=lambda p: (p.setting.engine, p.cpu)):
        s = p.setting
        lines.append(
            f"| {s.engine} | {s.family} | {dt_text(s.dt)} | {1e3 * p.cpu:.3g} | {p.error:.3g} |"
        )
    missed = [r for r in v["rows"] if not r["dominated"]]
    if missed:
        lines += ["", "Where rbsim does not dominate (pymunk front point: best rbsim answer):", ""]
        for r in missed:
            if r["rbsim"] is None:
                answer = "no rbsim point is as accurate"
            else:
                answer = (
                    f"{r['rbsim']} is as accurate ({_fmt(r['rbsim_error_m'])} m) but takes "
                    f"{r['time_ratio']:.2f}× the time"
                )
            lines.append(
                f"- {r['pymunk']} ({1e3 * r['pymunk_cpu']:.3g} ms/s, "
                f"{_fmt(r['pymunk_error_m'])} m): {answer}"
            )
    failed = [p for p in result.points if p.status != "ok"]
    if failed:
        what = [f"{p.setting.family} dt {dt_text(p.setting.dt)} ({p.status})" for p in failed]
        lines += ["", "Runs that failed: " + "; ".join(what)]
    inv = [p for p in result.points if p.penetration is not None]
    if inv:
        worst = {
            e: max((p for p in inv if p.setting.engine == e), key=lambda p: p.penetration)
            for e in ("rbsim", "pymunk")
            if any(p.setting.engine == e for p in inv)
        }
        lines += ["", "Invariants (largest over the runs of each engine):"]
        for engine, p in worst.items():
            drift = max(q.energy_drift for q in inv if q.setting.engine == engine)
            lines.append(
                f"- {engine}: penetration {p.penetration:.3g} m ({p.setting.family} dt "
                f"{dt_text(p.setting.dt)}), energy drift up to {drift:.3g} J"
            )
    return lines + [""]


def write_report(out_dir: Path, quick: bool = False, log=print) -> Path:
    """Run every sweep and the scaling measurement; write the markdown report."""
    out_dir.mkdir(parents=True, exist_ok=True)
    data = out_dir / "data"
    t_start = time.perf_counter()
    results: list[SweepResult] = []
    for name, grid in GRIDS.items():
        scene = load_scene(SCENES / f"{name}.yaml")
        t0 = time.perf_counter()
        result = run_sweep(
            scene, QUICK if quick else grid, repeats=3, duration=0.5 if quick else None
        )
        result.write(data, plot=False)
        plot_sweep(result, out_dir / f"{name}.png")
        took = time.perf_counter() - t0
        log(f"{name}: {len(result.points)} runs in {took:.0f} s; {result.verdict_line()}")
        results.append(result)
    t0 = time.perf_counter()
    scaling = measure_scaling(QUICK_SCALING_BASES if quick else SCALING_BASES)
    plot_scaling(scaling, out_dir / "scaling.png")
    log(f"scaling: {len(scaling)} sizes in {time.perf_counter() - t0:.0f} s")
    n = [p.bodies for p in scaling]
    slope_rb = fitted_slope(n, [p.rbsim_us for p in scaling])
    slope_pm = fitted_slope(n, [p.pymunk_us for p in scaling])

    import numpy
    import pymunk

    dominated = [r.scene for r in results if r.verdict()["rbsim_dominates"]]
    not_dominated = [r.scene for r in results if not r.verdict()["rbsim_dominates"]]
    lines = [
        "# Speed against error: rbsim and pymunk",
        "",
        "Generated by `make report` (`python -m rbsim.tools.report`); do not edit by hand: "
        "every number and sentence below comes from the measurements of that run.",
        "",
        f"- generated {datetime.datetime.now().isoformat(timespec='seconds')} in "
        f"{time.perf_counter() - t_start:.0f} s on {platform.machine()}, {os.cpu_count()} "
        f"logical CPUs (shared: timings vary by 10-20 % between runs), Python "
        f"{platform.python_version()}, rbsim {__version__}, "
        f"numpy {numpy.__version__}, pymunk {pymunk.version} (Chipmunk {pymunk.chipmunk_version})",
        "- cost: median CPU time (process time) per simulated second of at least 3 runs "
        "(short runs repeated until they add up to 0.2 s), loading the engine and scene "
        "setup excluded; pymunk is timed around its `space.step` loop in the same process",
        "- rbsim settings: dt, substeps (s), iterations per substep (it), integrator, "
        "rotation update (norm: normalize(q + h ω×q), exact); pymunk: dt and iterations "
        "(it), one step per dt, collision slop 0.5 cm as rbsim's",
        f"- goal: for every point of pymunk's Pareto front an rbsim point at least as "
        f"accurate in at most {DOMINANCE_TIME_RATIO:g} of the time (errors below 1e-9 m "
        "count as equal)",
        "",
        "## Summary",
        "",
        "| scene | reference | pymunk front points dominated | rbsim dominates |",
        "|---|---|---|---|",
    ]
    for r in results:
        v = r.verdict()
        lines.append(
            f"| [{r.scene}](#{r.scene}) | {r.reference_kind} | {v['dominated']} of "
            f"{v['pymunk_front_points']} | {'yes' if v['rbsim_dominates'] else '**no**'} |"
        )
    lines += [
        "",
        f"rbsim dominates pymunk's front on {len(dominated)} of {len(results)} scenes"
        + (f" ({', '.join(dominated)})" if dominated else "")
        + (f"; it does not yet on {', '.join(not_dominated)}." if not_dominated else "."),
        "",
    ]
    for r in results:
        lines += scene_section(r, f"{r.scene}.png")
    lines += [
        "## Cost per step against the number of bodies",
        "",
        "Pyramids of 1 m boxes resting on the ground, dt 1/60 s; rbsim with its defaults "
        "(4 substeps, 1 iteration), pymunk with 10 iterations; median CPU µs per step of 3 "
        "blocks of 10 steps after 20 warm-up steps.",
        "",
        "![scaling](scaling.png)",
        "",
        "| bodies | rbsim µs/step | pymunk µs/step | rbsim / pymunk |",
        "|---|---|---|---|",
    ]
    for p in scaling:
        lines.append(
            f"| {p.bodies} | {p.rbsim_us:.4g} | {p.pymunk_us:.4g} | "
            f"{p.rbsim_us / p.pymunk_us:.2f} |"
        )
    lines += [
        "",
        f"Fitted slope of log(cost) against log(bodies): rbsim {slope_rb:.2f}, "
        f"pymunk {slope_pm:.2f} (1 is linear).",
        "",
        "Data: `data/<scene>.csv` and `data/<scene>.json` (every run, with status, "
        "position and angle errors, penetration and energy drift where they apply).",
        "",
    ]
    report = out_dir / "work-precision.md"
    report.write_text("\n".join(lines))
    return report


def main(argv: list[str] | None = None) -> int:
    """Write the report; return 0 (1 when matplotlib is missing)."""
    parser = argparse.ArgumentParser(prog="python -m rbsim.tools.report", description=__doc__)
    parser.add_argument("-o", "--output", default="reports", help="folder (default: reports/ here)")
    parser.add_argument("--quick", action="store_true", help="tiny grids (a smoke test)")
    args = parser.parse_args(argv)
    from .sweep import PlotUnavailable

    try:
        path = write_report(Path(args.output), quick=args.quick)
    except PlotUnavailable as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print(f"report written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
