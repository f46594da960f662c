"""The engines that step a scene, each behind the one interface of engines.base:
`make_engine(name, scene, **options)` -> an Engine.

- "rbsim": rbsim's compiled engine (compiled.py, over rbsim.core).
- "pymunk": pymunk (Chipmunk2D), the reference engine in 2D (pymunk.py; options:
  settings=PymunkSettings(...)).
- "mujoco": MuJoCo, the reference engine in 3D (mujoco.py; options:
  settings=MujocoSettings(...)); the optional extra `mujoco`: without it the adapter
  raises EngineUnavailable.

Adapters are imported when their engine is asked for: pymunk and MuJoCo load only then.
"""

from __future__ import annotations

from importlib import import_module

from ..scene import Scene
from .base import (
    Engine,
    EngineUnavailable,
    NonFiniteState,
    Snapshot,
    TooManyPairs,
    UnsupportedScene,
)

# engine name -> (module, adapter class), relative to this package
ENGINES = {
    "rbsim": (".compiled", "RbsimEngine"),
    "pymunk": (".pymunk", "PymunkEngine"),
    "mujoco": (".mujoco", "MujocoEngine"),
}
DEFAULT_ENGINE = "rbsim"
# the engines that are rbsim's own (they step rbsim's model; `rbsim run --engine`)
RBSIM_ENGINES = ("rbsim",)


def engine_class(name: str) -> type[Engine]:
    """The adapter class of the named engine (one of ENGINES)."""
    if name not in ENGINES:
        raise ValueError(f"unknown engine {name!r}; expected one of {', '.join(ENGINES)}")
    module, cls = ENGINES[name]
    return getattr(import_module(module, __name__), cls)


def make_engine(name: str, scene: Scene, **options) -> Engine:  # noqa: ANN003 - per engine
    """`scene` ready to step in the named engine (one of ENGINES)."""
    return engine_class(name).from_scene(scene, **options)


__all__ = [
    "DEFAULT_ENGINE",
    "ENGINES",
    "RBSIM_ENGINES",
    "Engine",
    "EngineUnavailable",
    "NonFiniteState",
    "TooManyPairs",
    "Snapshot",
    "UnsupportedScene",
    "engine_class",
    "make_engine",
]
