"""The adapter of the numba engine ("rbsim-numba"): the same model and state as the
compiled engine's, stepped by rbsim.engines.numba.world."""

from __future__ import annotations

from ...scene import Scene
from ..compiled import RbsimEngine


class NumbaEngine(RbsimEngine):
    """The numba engine rbsim's compiled one was ported from (for holding them side by
    side: `--engine rbsim-numba`). `world` is its World."""

    name = "rbsim-numba"

    @staticmethod
    def _make_world(scene: Scene):  # noqa: ANN205 - the engine's world
        from .world import World  # imports numba: only when this engine is asked for

        return World.from_scene(scene)
