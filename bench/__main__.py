"""`make bench`: µs per step of rbsim and pymunk on the same scenes, and their ratio.

Both engines get the scene's dt (1/60 s), the same collision slop (rbsim's LINEAR_SLOP,
0.5 cm) and comparable solver work: rbsim runs its defaults (4 substeps, 1 solve + 1
relax pass each: 8 velocity passes and a restitution pass per step); pymunk runs 10
iterations per step (its usual setting). Each engine first steps WARMUP steps (the
engine loaded, contacts formed, outside the timing), then REPEATS timed blocks of STEPS
steps, the two engines' blocks taken in turn so that a slow spell of the shared machine
falls on both alike; each engine's median block is reported, and the ratio is the median
over the rounds of rbsim's block over pymunk's (rbsim on one thread). A block's time is
the CPU time of the thread that steps (both engines step on it), which a preempted or
interrupted thread does not accrue. A second table times `rbsim run` end to end (frames
written every step, and only the first and last) beside the engine alone and pymunk
alone, and the writer's own cost per frame. The from-rest scenes (FROM_REST) are timed
instead over their whole run from step 0, which a settled window leaves out (a pyramid
settling, a pile forming): REST_REPEATS fresh runs of each engine, in turn, round k's
pair on the scene with gravity changed by k parts in 10⁹ (bench.the_round: one
trajectory's time is one draw from a spread).
Timings report; they do not fail. After them, the 3D table (bench/bench3d.py): rbsim
against MuJoCo and PyBullet (where installed) on 3D contact scenes at dt = 1/240 s.
Between them, the threads table (bench/threads.py): rbsim on 1 and 2 threads and as a run
without solver.threads chooses, and the serial fraction.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from rbsim import config
from rbsim import constants as C
from rbsim.engines import Engine, make_engine
from rbsim.engines.pymunk import PymunkSettings
from rbsim.scene import load_scene
from rbsim.tools.measure import interleaved_block_times, median_ratio

from . import bench3d, print_header, the_round, threads

HERE = Path(__file__).parent
SCENES = [
    "pyramid20",
    "circles1000",
    "pyramid40",
    "pyramids4x4",
    "pyramid30",
    "rain800",
    "boxpile600",
]
WARMUP = 60
STEPS = 60
REPEATS = 9
# scenes timed over their whole run from rest (the scene's steps)
FROM_REST = {"pyramid30", "rain800", "boxpile600"}
REST_REPEATS = 5


def time_engines(engines: list[Engine]) -> tuple[list[float], float]:
    """Median µs per step of each engine and the median ratio of the first's to the
    second's: WARMUP steps each, then REPEATS rounds of a timed block of STEPS steps of
    each in turn (the stepping thread's CPU time)."""
    samples = interleaved_block_times(engines, WARMUP, STEPS, REPEATS, time.thread_time)
    return [statistics.median(s) for s in samples], median_ratio(samples[0], samples[1])


def time_from_rest(makes) -> tuple[list[float], float, int]:  # noqa: ANN001 - (round) -> Engine
    """Median µs per step of each engine over whole runs from step 0 (the scene's steps),
    each run in a fresh engine made from round k's scene (the_round), the engines' runs
    taken in turn (REST_REPEATS rounds); the median ratio of the first's runs to the
    second's, and the first's contact points at the end of its last run."""
    samples: list[list[float]] = [[] for _ in makes]
    contacts = 0
    for r in range(REST_REPEATS):
        for k, (make, out) in enumerate(zip(makes, samples, strict=True)):
            engine = make(r)
            steps = engine.scene.world.steps
            t0 = time.thread_time()
            engine.advance(steps)
            out.append((time.thread_time() - t0) / steps * 1e6)
            if k == 0:
                contacts = engine.contact_count
    medians = [statistics.median(s) for s in samples]
    return medians, median_ratio(samples[0], samples[1]), contacts


def pymunk_engine(scene, iterations: int) -> Engine:  # noqa: ANN001 - a Scene
    """pymunk with `iterations` iterations per step of dt and rbsim's collision slop."""
    settings = PymunkSettings(iterations=iterations, collision_slop=C.LINEAR_SLOP)
    return make_engine("pymunk", scene, settings=settings)


# `rbsim run` end to end: a run of E2E_STEPS + 1 steps less a run of 1 step (set-up
# cancels), over E2E_STEPS; output every step, and with only the first and last frames
END_TO_END = ["pyramid20", "circles1000"]
E2E_STEPS = 600
E2E_REPEATS = 3


def run_wall(scene_path: Path, steps: int, every: int) -> tuple[float, float]:
    """Wall time (s) of run_scene over `steps` steps writing every `every`-th frame to a
    temporary file, and the writer's share of it (s: the loop less the engine's time)."""
    import tempfile

    from rbsim.run import run_scene

    scene = load_scene(scene_path, [f"world.steps={steps}", f"output.every={every}"])
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        summary = run_scene(scene, Path(folder) / "run.h5")
        wall = time.perf_counter() - t0
    return wall, summary.loop_time - summary.step_time


def end_to_end(name: str, iterations: int) -> str:
    """One row: µs per step of `rbsim run` with output every step and with frames off,
    the engine alone and pymunk alone (each from rest, the median of E2E_REPEATS), the
    writer's µs per frame, and the ratio of the end-to-end run to the engine."""
    path = HERE / "scenes" / f"{name}.yaml"
    scene = load_scene(path, [f"world.steps={E2E_STEPS + 1}"])
    every, off, engine, pm, writer = [], [], [], [], []
    for _ in range(E2E_REPEATS):
        full, w = run_wall(path, E2E_STEPS + 1, 1)
        one, _ = run_wall(path, 1, 1)
        every.append((full - one) / E2E_STEPS * 1e6)
        writer.append(w / (E2E_STEPS + 2) * 1e6)
        full, _ = run_wall(path, E2E_STEPS + 1, 10**9)
        one, _ = run_wall(path, 1, 10**9)
        off.append((full - one) / E2E_STEPS * 1e6)
        for make, out in (
            (lambda: make_engine("rbsim", scene), engine),
            (lambda: pymunk_engine(scene, iterations), pm),
        ):
            e = make()
            e.advance(1)
            t0 = time.perf_counter()
            e.advance(E2E_STEPS)
            out.append((time.perf_counter() - t0) / E2E_STEPS * 1e6)
    m = statistics.median
    return (
        f"{name:<17}{m(every):>10.1f}{m(off):>11.1f}{m(engine):>9.1f}{m(pm):>10.1f}"
        f"{m(writer):>9.1f}{m(every) / m(engine):>9.2f}{m(every) / m(pm):>9.2f}"
    )


def table2d(names: list[str], iterations: int) -> None:
    """Print the 2D tables (rbsim against pymunk with `iterations`) of the scenes
    `names` of bench/scenes."""
    header = (
        f"{'scene':<17}{'bodies':>5}{'contacts':>10}{'rbsim us':>11}{'pymunk us':>11}{'ratio':>8}"
    )
    print_header(header)
    for name in names:
        scene = load_scene(HERE / "scenes" / f"{name}.yaml")
        if name in FROM_REST:
            makes = [
                lambda r, s=scene: make_engine("rbsim", the_round(s, r)),
                lambda r, s=scene: pymunk_engine(the_round(s, r), iterations),
            ]
            (rb, pm), ratio, rb_contacts = time_from_rest(makes)
            name = f"{name} (rest)"
        else:
            rbsim_engine = make_engine("rbsim", scene)
            (rb, pm), ratio = time_engines([rbsim_engine, pymunk_engine(scene, iterations)])
            rb_contacts = rbsim_engine.contact_count
        row = (
            f"{name:<17}{len(scene.bodies):>5}{rb_contacts:>10}{rb:>11.1f}{pm:>11.1f}{ratio:>8.2f}"
        )
        print(row, flush=True)
    print()
    print(f"rbsim run end to end, µs per step over {E2E_STEPS} steps from rest:")
    header = (
        f"{'scene':<17}{'frames':>10}{'no frames':>11}{'engine':>9}{'pymunk':>10}"
        f"{'writer':>9}{'/engine':>9}{'/pymunk':>9}"
    )
    print_header(header)
    for name in END_TO_END:
        if name in names:
            print(end_to_end(name, iterations), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__)
    parser.add_argument(
        "scenes",
        nargs="*",
        default=SCENES + list(bench3d.SCENES) + bench3d.EXAMPLES,
        help=f"bench/scenes/<name>.yaml, or a 3D scene: "
        f"{', '.join(list(bench3d.SCENES) + bench3d.EXAMPLES)}",
    )
    parser.add_argument("--iterations", type=int, default=10, help="pymunk iterations")
    args = parser.parse_args(argv)
    three_d = list(bench3d.SCENES) + bench3d.EXAMPLES
    scenes2d = [name for name in args.scenes if name not in three_d]
    scenes3d = [name for name in args.scenes if name in bench3d.SCENES]
    examples = [name for name in args.scenes if name in bench3d.EXAMPLES]
    if scenes2d:
        with config.threads_default(1):  # rbsim on one thread, as pymunk
            table2d(scenes2d, args.iterations)
        if names := [name for name in threads.SCENES if name in scenes2d]:
            print()
            threads.table(names)
    if scenes3d:
        if scenes2d:
            print()
        print(
            f"3D, dt = 1/240 s, CPU µs per step after {bench3d.WARMUP} steps from rest (median of "
            f"{bench3d.REPEATS} blocks of {bench3d.STEPS}); settings: bench/bench3d.py"
        )
        with config.threads_default(1):
            bench3d.table(scenes3d)
    if rest := [name for name in bench3d.FROM_REST if name in scenes3d] + examples:
        print()
        with config.threads_default(1):
            bench3d.rest_table(rest)
    return 0


if __name__ == "__main__":
    sys.exit(main())
