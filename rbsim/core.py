"""The compiled engine (rbsim._core, C++20) behind a World API.

`CoreWorld.from_scene` compiles the scene into the model's flat arrays (model.build,
the front's one flattener), hands them to the engine (World2 or World3, by the scene's
world.dimension), and shows the
engine's state as numpy views that share its memory: `world.state.body_x` is the
engine's array, not a copy. This module is the only importer of rbsim._core.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from . import _core
from .config import Config, NonFiniteState, TooManyPairs, make_config
from .scene import Scene
from .scene.compile import Model, State, build

# the engine's tuning constants by name (cpp/include/rbsim/constants.hpp; rbsim.constants)
CONSTANTS: dict = dict(_core.constants)
# the status World2.advance and advance_recording return when a state turned non-finite
NON_FINITE: int = _core.NON_FINITE
TOO_MANY_PAIRS: int = _core.TOO_MANY_PAIRS
# advance_recording's status when a signal handler raised between two steps
INTERRUPTED: int = _core.INTERRUPTED
# advance_recording's status when a frame's contact points did not fit in the block
CONTACTS_FULL: int = _core.CONTACTS_FULL
# m: a body farther from the origin along any axis ends the run (cpp/include/rbsim/world.hpp)
POSITION_LIMIT: float = float(_core.POSITION_LIMIT)
# the most threads a world steps on (solver.threads; rbsim.scene.schema.THREADS_MAX)
THREADS_MAX: int = int(_core.THREADS_MAX)


# the engine's world class by dimension, and the type of either
WORLDS = {2: _core.World2, 3: _core.World3}
EngineWorld = _core.World2 | _core.World3


def _model_arrays(model: Model) -> dict:
    arrays = {}
    for name, value in model._asdict().items():
        arrays[name] = np.ascontiguousarray(value) if isinstance(value, np.ndarray) else value
    return arrays


@dataclass
class CoreWorld:
    """A scene ready to step in the compiled engine; `dimension` 2 or 3 (the engine is
    a World2 or a World3)."""

    scene: Scene | None
    model: Model
    config: Config
    engine: EngineWorld
    dimension: int = 2

    @classmethod
    def from_scene(cls, scene: Scene) -> CoreWorld:
        """Compile the scene and build the engine's world from it (World2 or World3 by
        scene.world.dimension)."""
        model, state = build(scene)
        return cls.from_arrays(model, state, make_config(scene), scene.world.dimension, scene)

    @classmethod
    def from_arrays(
        cls,
        model: Model,
        state: State,
        config: Config,
        dimension: int,
        scene: Scene | None = None,
    ) -> CoreWorld:
        """The engine's world of `dimension` (2 or 3) from compiled arrays (SI units, as
        rbsim.scene.compile.build makes them); ValueError naming the array when one has
        the wrong dtype or shape."""
        if dimension not in WORLDS:
            raise ValueError(f"dimension must be 2 or 3, got {dimension!r}")
        engine = WORLDS[dimension](
            _model_arrays(model),
            {k: np.ascontiguousarray(v) for k, v in state._asdict().items()},
            config._asdict(),
        )
        return cls(scene, model, config, engine, dimension)

    @property
    def state(self) -> State:
        """The state, as a State tuple (rbsim.scene.compile) of the engine's own arrays
        (numpy views: no copy; they stay valid for the world's life). In 3D body_angle is
        empty and body_l the angular momentum (N,3); in 2D body_l is empty."""
        e = self.engine
        return State(e.body_x, e.body_q, e.body_angle, e.body_v, e.body_w, e.body_l)

    @property
    def step_index(self) -> int:
        """Steps taken."""
        return int(self.engine.step_index)

    @property
    def time(self) -> float:
        """Simulated time (s) of the current state."""
        return self.step_index * self.config.dt

    def advance(self, n_steps: int) -> None:
        """Take n_steps steps; raises NonFiniteState if the state blows up or a body
        flies beyond POSITION_LIMIT. A signal handler that raises between two steps
        stops it there (the exception propagates; the steps taken are kept)."""
        status, _taken, bad = self.engine.advance(int(n_steps))
        if status == _core.NON_FINITE:
            raise self.non_finite(int(bad))
        if status == _core.TOO_MANY_PAIRS:
            raise self.too_many_pairs()

    def too_many_pairs(self) -> TooManyPairs:
        """The TooManyPairs of the step that advance refused."""
        e = self.engine
        return TooManyPairs(int(e.pairs_wanted), int(e.pair_limit()), self.step_index)

    def non_finite(self, body: int) -> NonFiniteState:
        """The NonFiniteState of `body` at the current step: its state is not finite, or
        (all finite) it flew beyond POSITION_LIMIT."""
        e = self.engine
        values = (e.body_x[body], e.body_q[body], e.body_v[body], e.body_w[body])
        beyond = POSITION_LIMIT if all(np.isfinite(v).all() for v in values) else None
        return NonFiniteState(body, self.step_index, beyond, self.dimension)

    @property
    def contact_count(self) -> int:
        """Contact points that pushed in the last step."""
        return int(self.engine.contact_count)

    @property
    def contacts(self) -> SimpleNamespace:
        """The contact store's arrays by name (as `storage`), for tests and tools."""
        return self.storage

    @property
    def grid(self) -> SimpleNamespace:
        """The broadphase's arrays by name, for tests and tools."""
        return self.storage.grid

    def stage(self, name: str, **args):  # noqa: ANN201 - the stage's own result
        """Run one stage of the step by name on the current storage (tests, tools)."""
        return self.engine.stage(name, args)

    @property
    def storage(self) -> SimpleNamespace:
        """The stages' storage arrays by name (views; valid until the next step, which may
        swap the store's arrays, or until the store grows)."""
        d = self.engine.storage()
        grid = SimpleNamespace(**d.pop("grid"))
        return SimpleNamespace(grid=grid, **d)


def collide2d(
    kind_a: int,
    start_a: int,
    count_a: int,
    radius_a: float,
    kind_b: int,
    start_b: int,
    count_b: int,
    radius_b: float,
    verts: np.ndarray,
    norms: np.ndarray,
    speculative: float,
    out_normal: np.ndarray,
    out_point: np.ndarray,
    out_sep: np.ndarray,
    out_id: np.ndarray,
) -> int:
    """The engine's narrowphase for one pair of shapes (for tests and tools); returns
    the point count 0, 1 or 2 and writes its first rows of the outputs.

    kind_*: constants.SHAPE_*; start_*, count_*: the shape's rows of verts and norms
    ((V,2), world frame, m; norms the outward edge normals); radius_* m; speculative m:
    points whose surfaces are farther apart are dropped. Outputs: out_normal (2,) from
    b towards a, out_point (2,2) m, out_sep (2,) m (negative: overlap), out_id (2,)
    int64 feature ids."""
    n, normal, point, sep, ids = _core.collide2d(
        kind_a, start_a, count_a, radius_a, kind_b, start_b, count_b, radius_b,
        np.ascontiguousarray(verts, np.float64), np.ascontiguousarray(norms, np.float64),
        speculative,
    )  # fmt: skip
    out_normal[:] = normal
    out_point[:n] = point[:n]
    out_sep[:n] = sep[:n]
    out_id[:n] = ids[:n]
    return int(n)


def min_separation(
    verts: np.ndarray,
    vstart: np.ndarray,
    vcount: np.ndarray,
    radius: np.ndarray,
    pairs: np.ndarray,
) -> np.ndarray:
    """The engine's penetration ruler: per pair of shapes (P,) the signed distance (m) of
    their cores (SAT for two polygons or segments, exact for a circle centre), minus both
    radii; negative when they overlap.

    verts (V,2) world-frame vertices, m; vstart, vcount (S,) each shape's rows of verts;
    radius (S,) m; pairs (P,2) shape indices."""
    return _core.min_separation(
        np.ascontiguousarray(verts, np.float64),
        np.ascontiguousarray(vstart, np.int32),
        np.ascontiguousarray(vcount, np.int32),
        np.ascontiguousarray(radius, np.float64),
        np.ascontiguousarray(pairs, np.int32).reshape(-1, 2),
    )
