"""The compiled engine (rbsim._core, C++20) behind the same World API as the numba one.

`CoreWorld.from_scene` compiles the scene into the model's flat arrays (model.build,
the same compiler the numba engine uses), hands them to the engine, and shows the
engine's state as numpy views that share its memory: `world.state.body_x` is the
engine's array, not a copy. This module is the only importer of rbsim._core.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from . import _core
from .config import Config, NonFiniteState, make_config
from .model import Model, build
from .scene import Scene


def _model_arrays(model: Model) -> dict:
    arrays = {}
    for name, value in model._asdict().items():
        arrays[name] = np.ascontiguousarray(value) if isinstance(value, np.ndarray) else value
    return arrays


class _StateView:
    """The engine's state arrays as numpy views (fresh on each read, same memory)."""

    def __init__(self, engine: _core.World2) -> None:
        self._engine = engine

    @property
    def body_x(self) -> np.ndarray:
        """(N,2) m, centre-of-mass positions."""
        return self._engine.body_x

    @property
    def body_q(self) -> np.ndarray:
        """(N,2) (cos θ, sin θ)."""
        return self._engine.body_q

    @property
    def body_angle(self) -> np.ndarray:
        """(N,) rad, unwrapped."""
        return self._engine.body_angle

    @property
    def body_v(self) -> np.ndarray:
        """(N,2) m/s, centre-of-mass velocities."""
        return self._engine.body_v

    @property
    def body_w(self) -> np.ndarray:
        """(N,) rad/s."""
        return self._engine.body_w


@dataclass
class CoreWorld:
    """A scene ready to step in the compiled engine."""

    scene: Scene
    model: Model
    config: Config
    engine: _core.World2

    @classmethod
    def from_scene(cls, scene: Scene) -> CoreWorld:
        """Compile the scene and build the engine's world from it."""
        model, state = build(scene)
        config = make_config(scene)
        engine = _core.World2(
            _model_arrays(model),
            {k: np.ascontiguousarray(v) for k, v in state._asdict().items()},
            config._asdict(),
        )
        return cls(scene, model, config, engine)

    @property
    def state(self) -> _StateView:
        """The state (views of the engine's arrays)."""
        return _StateView(self.engine)

    @property
    def step_index(self) -> int:
        """Steps taken."""
        return int(self.engine.step_index)

    @property
    def time(self) -> float:
        """Simulated time (s) of the current state."""
        return self.step_index * self.config.dt

    def advance(self, n_steps: int) -> None:
        """Take n_steps steps; raises NonFiniteState if the state blows up."""
        status, _taken, bad = self.engine.advance(int(n_steps))
        if status == _core.NON_FINITE:
            raise NonFiniteState(int(bad), self.step_index)

    @property
    def contact_count(self) -> int:
        """Contact points that pushed in the last step."""
        return int(self.engine.contact_count)

    @property
    def storage(self) -> SimpleNamespace:
        """The stages' storage arrays by name (views; valid until the store grows)."""
        d = self.engine.storage()
        grid = SimpleNamespace(**d.pop("grid"))
        return SimpleNamespace(grid=grid, **d)


# The engines that step a scene, by the name a trajectory records. "rbsim" is the
# compiled engine; "rbsim-numba" the numba kernels it was ported from, kept until the
# port is complete so that the two can be held against each other.
ENGINES = ("rbsim", "rbsim-numba")
DEFAULT_ENGINE = "rbsim"


def make_world(scene: Scene, engine: str = DEFAULT_ENGINE):
    """A world for `scene` in the named engine (one of ENGINES)."""
    if engine == "rbsim":
        return CoreWorld.from_scene(scene)
    if engine == "rbsim-numba":
        from .world import World  # imports numba: only when asked for

        return World.from_scene(scene)
    raise ValueError(f"unknown engine {engine!r}; expected one of {', '.join(ENGINES)}")
