"""`make bench`: µs per step of rbsim and pymunk on the same scenes, and their ratio.

Both engines get the scene's dt (1/60 s), the same collision slop (rbsim's
LINEAR_SLOP, 0.5 cm) and comparable solver work: rbsim runs its defaults (4 substeps,
1 solve + 1 relax pass each: 8 velocity passes and a restitution pass per step);
pymunk runs 10 iterations per step (its usual setting). Each engine first steps
WARMUP steps (numba compile, contacts formed, outside the timing), then the median
of REPEATS timed blocks of STEPS steps is reported. Timings report; they do not fail.
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
SCENES = ["pyramid20", "circles1000", "pyramid40", "pyramids4x4"]
WARMUP = 60
STEPS = 60
REPEATS = 5


def time_engine(engine: Engine) -> tuple[float, int]:
    """Median µs per step and the contact points at the end: WARMUP steps, then REPEATS
    timed blocks of STEPS steps (wall time)."""
    samples = block_times(engine, WARMUP, STEPS, REPEATS, time.perf_counter)
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
    parser.add_argument(
        "--numba", action="store_true", help="also time the numba engine (rbsim-numba)"
    )
    args = parser.parse_args(argv)
    header = (
        f"{'scene':<14}{'bodies':>8}{'contacts':>10}{'rbsim us':>11}{'pymunk us':>11}{'ratio':>8}"
    )
    if args.numba:
        header += f"{'numba us':>11}{'ratio':>8}"
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        scene = load_scene(HERE / "scenes" / f"{name}.yaml")
        rb, rb_contacts = time_engine(make_engine("rbsim", scene))
        pm, _ = time_engine(pymunk_engine(scene, args.iterations))
        row = (
            f"{name:<14}{len(scene.bodies):>8}{rb_contacts:>10}{rb:>11.1f}{pm:>11.1f}"
            f"{rb / pm:>8.2f}"
        )
        if args.numba:
            nb, _ = time_engine(make_engine("rbsim-numba", scene))
            row += f"{nb:>11.1f}{nb / pm:>8.2f}"
        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
