"""`make bench`: µs per step of rbsim and pymunk on the same scenes, and their ratio.

Both engines get the scene's dt (1/60 s), the same collision slop (rbsim's
LINEAR_SLOP, 0.5 cm) and comparable solver work: rbsim runs its defaults (4 substeps,
1 solve + 1 relax pass each: 8 velocity passes and a restitution pass per step);
pymunk runs 10 iterations per step (its usual setting). Each engine first steps
WARMUP steps (the engine loaded, contacts formed, outside the timing), then the median
of REPEATS timed blocks of STEPS steps is reported. The from-rest scenes (FROM_REST) are
timed instead over their whole run from step 0, which a settled window leaves out (a
pyramid settling, a pile forming): the median of REST_REPEATS fresh runs. Timings report;
they do not fail.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from rbsim import constants as C
from rbsim.engines import Engine, make_engine
from rbsim.engines.pymunk import PymunkSettings
from rbsim.scene import load_scene
from rbsim.tools.measure import block_times

HERE = Path(__file__).parent
SCENES = ["pyramid20", "circles1000", "pyramid40", "pyramids4x4", "pyramid30", "rain800"]
WARMUP = 60
STEPS = 60
REPEATS = 5
# scenes timed over their whole run from rest (the scene's steps)
FROM_REST = {"pyramid30", "rain800"}
REST_REPEATS = 3


def time_engine(engine: Engine) -> tuple[float, int]:
    """Median µs per step and the contact points at the end: WARMUP steps, then REPEATS
    timed blocks of STEPS steps (wall time)."""
    samples = block_times(engine, WARMUP, STEPS, REPEATS, time.perf_counter)
    return statistics.median(samples), engine.contact_count


def time_from_rest(make) -> tuple[float, int]:  # noqa: ANN001 - a () -> Engine
    """Median µs per step over whole runs from step 0 (the scene's steps), each in a fresh
    engine, and the contact points at the end of the last."""
    samples = []
    for _ in range(REST_REPEATS):
        engine = make()
        steps = engine.scene.world.steps
        t0 = time.perf_counter()
        engine.advance(steps)
        samples.append((time.perf_counter() - t0) / steps * 1e6)
    return statistics.median(samples), engine.contact_count


def pymunk_engine(scene, iterations: int) -> Engine:  # noqa: ANN001 - a Scene
    """pymunk with `iterations` iterations per step of dt and rbsim's collision slop."""
    settings = PymunkSettings(iterations=iterations, collision_slop=C.LINEAR_SLOP)
    return make_engine("pymunk", scene, settings=settings)


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__)
    parser.add_argument("scenes", nargs="*", default=SCENES, help="bench/scenes/<name>.yaml")
    parser.add_argument("--iterations", type=int, default=10, help="pymunk iterations")
    args = parser.parse_args(argv)
    header = (
        f"{'scene':<17}{'bodies':>5}{'contacts':>10}{'rbsim us':>11}{'pymunk us':>11}{'ratio':>8}"
    )
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        scene = load_scene(HERE / "scenes" / f"{name}.yaml")
        if name in FROM_REST:
            rb, rb_contacts = time_from_rest(lambda s=scene: make_engine("rbsim", s))
            pm, _ = time_from_rest(lambda s=scene: pymunk_engine(s, args.iterations))
            name = f"{name} (rest)"
        else:
            rb, rb_contacts = time_engine(make_engine("rbsim", scene))
            pm, _ = time_engine(pymunk_engine(scene, args.iterations))
        row = (
            f"{name:<17}{len(scene.bodies):>5}{rb_contacts:>10}{rb:>11.1f}{pm:>11.1f}"
            f"{rb / pm:>8.2f}"
        )
        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
