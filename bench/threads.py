"""`make bench`, threads: rbsim's step on 1 and on 2 threads (solver.threads), wall µs per
step and their ratio, on a settled window (WARMUP steps, then REPEATS blocks of STEPS,
the runs' blocks taken in turn so that a slow spell of the host falls on each alike) of
the scenes in SCENES; "chosen", the step with solver.threads not set (the cores, each
step on one thread or on two as the run's trials time them: ThreadChoice in
cpp/include/rbsim/pool.hpp), its trials' steps included; and the serial fraction s of the
step, measured on one thread (World.parallel_seconds: the wall time of the work the step
splits over its threads, against the stages' total), from which Amdahl's law bounds the
2-thread speed-up at 1 / (s + (1 - s) / 2). The results are the same, bit for bit, on
every thread count (tests/test_threads.py); only the time differs. Needs idle cores: on a
loaded machine the ratio says little. So the table also says what the host gives two
threads of this work in the same run ("host"): the throughput of two one-thread copies of
the scene stepping at once, in processes of their own that share nothing, against one
copy alone (2.0 on two free cores; less where the two cores share one's execution units
or another tenant's load); and how much longer the passes' region tasks take side by
side on two threads than one after the other on one ("tasks", World.region_task_seconds:
1.0 where the threads do not slow each other). Run alone: python -m bench.threads [scenes].
"""

from __future__ import annotations

import argparse
import multiprocessing
import queue
import statistics
import sys
import time
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from multiprocessing.synchronize import Barrier
from pathlib import Path

from rbsim import config
from rbsim.core import EngineWorld
from rbsim.engines import Engine, make_engine
from rbsim.scene import Scene, load_scene
from rbsim.tools.measure import interleaved_block_times

from . import print_header

HERE = Path(__file__).parent
SCENES = ["pyramid40", "circles1000"]
WARMUP = 60
STEPS = 60
REPEATS = 5
TARGET = 1.7  # issue 13: at least 1.7x on two threads for these scenes
HOST_ROUNDS = 2  # rounds of one copy alone, then two at once
HOST_TIMEOUT = 600.0  # s: a copy that has not answered by then has failed


def engine(scene: Scene, threads: int | None) -> Engine:
    """rbsim on the scene, on `threads` threads (None: as a scene without solver.threads
    runs in `rbsim run`: the cores, the step choosing between one thread and them)."""
    with config.threads_default(threads):
        return make_engine("rbsim", scene)


def step_times(scene: Scene) -> tuple[float, float, float]:
    """Mean wall µs per step on 1 thread, on 2 and as chosen, after WARMUP steps."""
    runs = [engine(scene, 1), engine(scene, 2), engine(scene, None)]
    samples = interleaved_block_times(runs, WARMUP, STEPS, REPEATS, time.perf_counter)
    one, two, chosen = (statistics.fmean(s) for s in samples)
    return one, two, chosen


def profiled(scene: Scene, threads: int) -> EngineWorld:
    """The compiled world of rbsim on `threads` threads after WARMUP steps and then
    REPEATS blocks of STEPS with its profile on (stage times, region tasks)."""
    e = engine(scene, threads)
    e.advance(WARMUP)
    core = e.world.engine
    core.profile = True
    e.advance(REPEATS * STEPS)
    return core


def serial_fraction(one_thread: EngineWorld) -> float:
    """The share of one thread's step time spent outside the work the step splits over
    its threads (stages timed by the engine's profile: `profiled`, one thread)."""
    return 1.0 - one_thread.parallel_seconds / sum(one_thread.stage_times().values())


def task_slowdown(one_thread: EngineWorld, two_threads: EngineWorld) -> float | None:
    """How much longer a region's task of the solver's passes takes side by side with the
    other's on two threads than one after the other on one (wall seconds a pass, summed
    over the regions; `profiled` worlds); None for a scene of one region. 1.0 where the
    two threads do not slow each other."""
    alone_s, alone_n = one_thread.region_task_seconds["alone"]
    paired_s, paired_n = two_threads.region_task_seconds["paired"]
    if alone_n == 0 or paired_n == 0:
        return None
    return (paired_s / paired_n) / (alone_s / alone_n)


def _timed_copy(path: str, steps: int, start: Barrier, out: Queue) -> None:
    """(In a process of its own.) rbsim on one thread on the scene at `path`: WARMUP
    steps, then, once every copy is ready (the barrier `start`), `steps` more, whose wall
    seconds go to the queue `out`."""
    e = engine(load_scene(path), 1)
    e.advance(WARMUP)
    start.wait()
    t0 = time.perf_counter()
    e.advance(steps)
    out.put(time.perf_counter() - t0)


def host_scaling(path: Path, steps: int = REPEATS * STEPS, rounds: int = HOST_ROUNDS) -> float:
    """The throughput of two one-thread copies of the scene at `path` stepping at once
    (each `steps` steps after WARMUP, in processes of their own), against one copy alone:
    2 t1 / t2, t1 one copy's wall seconds and t2 the slower of the two's, each the mean of
    `rounds` rounds (one copy, then two, in turn). RuntimeError when a copy fails."""
    ctx = multiprocessing.get_context("spawn")  # (a fork would copy the pools' threads)
    alone: list[float] = []
    paired: list[float] = []
    for _ in range(rounds):
        for copies, times in ((1, alone), (2, paired)):
            start, out = ctx.Barrier(copies), ctx.Queue()
            procs = [
                ctx.Process(target=_timed_copy, args=(str(path), steps, start, out))
                for _ in range(copies)
            ]
            for p in procs:
                p.start()
            try:
                times.append(max(_answer(out, procs) for _ in procs))
            except BaseException:
                for p in procs:  # (a copy left waiting at the barrier would wait for ever)
                    p.kill()
                raise
            finally:
                for p in procs:
                    p.join()
    return 2.0 * statistics.fmean(alone) / statistics.fmean(paired)


def _answer(out: Queue, procs: list[BaseProcess]) -> float:
    """The next copy's wall seconds from the queue `out`; RuntimeError once one of
    `procs` has ended without answering (its traceback is on stderr), or when none has
    answered within HOST_TIMEOUT."""
    deadline = time.monotonic() + HOST_TIMEOUT
    while time.monotonic() < deadline:
        try:
            return out.get(timeout=0.5)
        except queue.Empty:
            if any(p.exitcode not in (None, 0) for p in procs):
                raise RuntimeError("a timed copy of the scene failed (its error above)") from None
    raise RuntimeError(f"no timed copy of the scene answered within {HOST_TIMEOUT:.0f} s")


def table(names: list[str]) -> None:
    """Print the threads table for the bench scenes `names`."""
    print(
        f"threads: wall µs per step after {WARMUP} steps (mean of {REPEATS} blocks of "
        f"{STEPS}, the three runs' blocks in turn); chosen: solver.threads not set (the step "
        f"times one thread against {config.available_cores()} as it runs); serial fraction s "
        f"on one thread, bound 1 / (s + (1 - s) / 2); tasks: a region's task of the passes "
        f"side by side on 2 threads against one after the other (1.00x: no slowing); host: "
        f"two one-thread copies at once against one alone (2.00x on two free cores); target "
        f"{TARGET}x"
    )
    header = (
        f"{'scene':<17}{'1 thread':>10}{'2 threads':>11}{'speed-up':>10}{'chosen':>8}"
        f"{'serial':>8}{'bound':>7}{'tasks':>7}{'host':>7}"
    )
    print_header(header)
    for name in names:
        path = HERE / "scenes" / f"{name}.yaml"
        scene = load_scene(path)
        one, two, chosen = step_times(scene)
        one_thread, two_threads = profiled(scene, 1), profiled(scene, 2)
        s = serial_fraction(one_thread)
        bound = 1.0 / (s + (1.0 - s) / 2.0)
        slowdown = task_slowdown(one_thread, two_threads)
        tasks = f"{slowdown:>6.2f}x" if slowdown is not None else f"{'-':>7}"
        host = host_scaling(path)
        print(
            f"{name:<17}{one:>10.1f}{two:>11.1f}{one / two:>9.2f}x{chosen:>8.1f}"
            f"{s:>8.2f}{bound:>6.2f}x{tasks}{host:>6.2f}x",
            flush=True,
        )


def main(argv: list[str] | None = None) -> int:
    """Print the threads table; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench.threads", description=__doc__)
    parser.add_argument("scenes", nargs="*", default=SCENES, help="bench/scenes/<name>.yaml")
    args = parser.parse_args(argv)
    table(args.scenes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
