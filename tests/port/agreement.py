"""How closely the compiled engine follows the numba one, scene by scene.

    python -m tests.port.agreement [--steps N] [SCENE.yaml ...]

Both engines run each scene for N steps (default 300, or the scene's own length if
shorter) from the same state; the table gives, per scene, the first step at which the
states differ at all, and the largest difference in position (m) and velocity (m/s)
at steps 1, 10, 100 and the last. Scenes that agree to round-off stay near 1e-15 m;
chaotic ones (piles, pyramids settling) drift apart once a round-off difference flips
a contact decision, growing from there.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from rbsim.core import CoreWorld
from rbsim.engines.numba.world import World
from rbsim.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SCENES = sorted(
    [*ROOT.glob("scenes/*.yaml"), *ROOT.glob("scenes/compare/*.yaml"),
     *ROOT.glob("scenes/compare/statistics/*.yaml"), *ROOT.glob("scenes/hard/*.yaml"),
     *ROOT.glob("scenes/reference/*.yaml"), *ROOT.glob("bench/scenes/*.yaml")]
)  # fmt: skip
CHECKPOINTS = (1, 10, 100)


def state_difference(a, b) -> tuple[float, float]:
    """(max position difference m, max velocity difference m/s) between two states."""
    dx = float(np.max(np.abs(a.body_x - b.body_x), initial=0.0))
    dv = float(np.max(np.abs(a.body_v - b.body_v), initial=0.0))
    dq = float(np.max(np.abs(a.body_q - b.body_q), initial=0.0))
    dw = float(np.max(np.abs(a.body_w - b.body_w), initial=0.0))
    return max(dx, dq), max(dv, dw)


def agreement(scene, steps: int) -> dict:
    """Step both engines `steps` steps; the first differing step and the differences."""
    nb, cc = World.from_scene(scene), CoreWorld.from_scene(scene)
    first = None
    marks = {}
    for k in range(1, steps + 1):
        nb.advance(1)
        cc.advance(1)
        dx, dv = state_difference(nb.state, cc.state)
        if first is None and (dx > 0 or dv > 0):
            first = k
        if k in CHECKPOINTS or k == steps:
            marks[k] = (dx, dv)
        if not (math.isfinite(dx) and math.isfinite(dv)):
            marks[k] = (dx, dv)
            break
    return {"first": first, "marks": marks, "steps": steps}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.port.agreement")
    parser.add_argument("scenes", nargs="*", type=Path, default=DEFAULT_SCENES)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args(argv)
    print(f"{'scene':<40}{'first diff':>11}  position / velocity difference at steps")
    for path in args.scenes:
        scene = load_scene(path)
        steps = min(args.steps, scene.world.steps)
        r = agreement(scene, steps)
        first = "never" if r["first"] is None else str(r["first"])
        cells = "  ".join(f"{k}: {dx:.1e}/{dv:.1e}" for k, (dx, dv) in r["marks"].items())
        name = str(path.relative_to(ROOT)) if path.is_absolute() else str(path)
        print(f"{name:<40}{first:>11}  {cells}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
