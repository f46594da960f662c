"""The adapter of rbsim's compiled engine ("rbsim", rbsim.core.CoreWorld): it steps the
model that rbsim.scene.compile builds."""

from __future__ import annotations

import time

from ..core import CoreWorld
from ..io.observables import observables
from ..scene import Scene
from ..scene import types as T
from ..scene.compile import body_origin
from .base import Engine, Snapshot


class RbsimEngine(Engine):
    """rbsim's compiled engine. `world` is the engine's world (CoreWorld): its model,
    state views and stages, for tests and tools that look inside."""

    name = "rbsim"
    interruptible = True  # Ctrl-C stops advance between two steps (rbsim.core)

    def __init__(self, scene: Scene) -> None:
        super().__init__(scene)
        self.world = self._make_world(scene)
        model = self.world.model
        self.model = model
        self.mass = model.body_mass.copy()
        self.inertia = model.body_inertia.copy()
        self.com_local = model.body_com.copy()
        self.dynamic = model.body_type == T.BODY_DYNAMIC
        self.settings = {}  # the solver block of the scene is the settings (run.parameters)

    @staticmethod
    def _make_world(scene: Scene):  # noqa: ANN205 - the engine's world
        return CoreWorld.from_scene(scene)

    def advance(self, n: int) -> None:
        t0 = time.perf_counter()
        try:
            self.world.advance(n)
        finally:
            self.step_time += time.perf_counter() - t0

    def read(self) -> Snapshot:
        st = self.world.state
        return Snapshot(
            origin=body_origin(self.model, st),
            angle=st.body_angle.copy(),
            orientation=st.body_q.copy(),
            com=st.body_x.copy(),
            velocity=st.body_v.copy(),
            angular_velocity=st.body_w.copy(),
        )

    @property
    def step_index(self) -> int:
        return int(self.world.step_index)

    @property
    def contact_count(self) -> int:
        return int(self.world.contact_count)

    def observables(self) -> dict:
        return observables(self.model, self.world.state, self.world.contact_count)
