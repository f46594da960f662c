"""`python -m bench.output`: file size and write cost of a 10,000-body trajectory of 1000
frames for each output precision and compression (the README's table).

The frames are a real run (10,000 circles poured onto a floor, every step written), made
once; each variant then writes the same frames through the trajectory writer's blocks,
as `rbsim run` does, and the wall time of that (laying out, writing, closing; the
compressed variants compress at close) is its write cost.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

from rbsim.engines import make_engine
from rbsim.io.trajectory import OBSERVABLES, TrajectoryWriter, load_trajectory
from rbsim.run import body_table, run_scene
from rbsim.scene import load_scene_text

SCENE = """\
version: 1
name: pour
world: {gravity: [0, -10], dt: 1/60, steps: 999}
bodies:
  - name: floor
    type: static
    shape: {segment: {a: [-80, 0], b: [80, 0]}}
  - grid: {count: [100, 100], spacing: [1.1, 1.1], origin: [-55, 1], shape: {circle: {radius: 0.5}}}
"""
VARIANTS = [(p, c) for p in ("float64", "float32") for c in ("none", "lzf", "gzip")]
KEYS = ("position", "orientation", "angle", "velocity", "angular_velocity")


def main() -> int:
    scene = load_scene_text(SCENE, "pour.yaml")
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "source.h5"
        t0 = time.perf_counter()
        run_scene(scene, source)
        print(
            f"simulated {len(scene.bodies)} bodies x 1000 frames "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        traj = load_trajectory(source)
        bodies = body_table(scene, make_engine("rbsim", scene))
        n = len(traj.step)
        print(f"{'precision':<10}{'compression':<13}{'file MB':>9}{'write s':>9}{'us/frame':>10}")
        for precision, compression in VARIANTS:
            out = Path(folder) / f"{precision}-{compression}.h5"
            t0 = time.perf_counter()
            writer = TrajectoryWriter(
                out, bodies=bodies, parameters={}, frames=n, precision=precision,
                compression=compression, observables=OBSERVABLES,
            )  # fmt: skip
            block = writer.block
            for t in range(n):
                r = writer.rows
                block["step"][r], block["time"][r] = traj.step[t], traj.time[t]
                for key in KEYS:
                    block[key][r] = getattr(traj, key)[t]
                for key in OBSERVABLES:
                    block[key][r] = traj.observables[key][t]
                writer.commit(1)
            writer.close()
            wall = time.perf_counter() - t0
            size = os.path.getsize(out) / 1e6
            print(
                f"{precision:<10}{compression:<13}{size:>9.1f}{wall:>9.2f}{wall / n * 1e6:>10.0f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
