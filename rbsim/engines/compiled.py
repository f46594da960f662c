"""The adapter of rbsim's compiled engine ("rbsim", rbsim.core.CoreWorld): it steps the
model that rbsim.scene.compile builds."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ..core import CONTACTS_FULL, INTERRUPTED, NON_FINITE, TOO_MANY_PAIRS, CoreWorld
from ..io.observables import observables
from ..io.trajectory import grow_contact_rows
from ..scene import Scene
from ..scene import types as T
from ..scene.compile import body_origin
from .base import Engine, Snapshot


class RbsimEngine(Engine):
    """rbsim's compiled engine. `world` is the engine's world (CoreWorld): its model,
    state views and stages, for tests and tools that look inside."""

    name = "rbsim"
    records_contacts = True

    def __init__(self, scene: Scene) -> None:
        super().__init__(scene)
        self.world = self._make_world(scene)
        # a run that writes its contact points: each one's mean force over its step
        self.world.engine.record_contact_impulses = scene.output.contacts == "points"
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

    def advance_recording(
        self,
        n: int,
        every: int,
        last_step: int,
        block: dict[str, np.ndarray],
        row: int,
        stop: Callable[[], bool] | None = None,
    ) -> tuple[int, int, BaseException | None]:
        t0 = time.perf_counter()
        try:
            status, taken, written, bad = self.world.engine.advance_recording(
                int(n), int(every), int(last_step), block, int(row), stop
            )
        finally:
            self.step_time += time.perf_counter() - t0
        err: BaseException | None = None
        if status == CONTACTS_FULL:
            # the step is taken but its frame's contact points did not fit: room, then
            # the frame (the state is that step's still)
            self.record(block, int(row) + int(written))
            written += 1
        elif status == NON_FINITE:
            err = self.world.non_finite(int(bad))
        elif status == TOO_MANY_PAIRS:
            err = self.world.too_many_pairs()
        elif status == INTERRUPTED:
            err = KeyboardInterrupt()
        return int(taken), int(written), err

    def record(self, block: dict[str, np.ndarray], row: int) -> None:
        missing = self.world.engine.record(block, int(row))
        if missing > 0:  # the frame's contact points need more rows than the block has
            grow_contact_rows(block, missing)
            missing = self.world.engine.record(block, int(row))
        assert missing == 0

    def checkpoint(self) -> bytes:
        return self.world.engine.save_checkpoint()

    def checkpoint_size(self) -> int:
        return int(self.world.engine.checkpoint_size())

    def restore(self, data: bytes) -> None:
        self.world.engine.load_checkpoint(data)

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
    def torn(self) -> bool:
        return bool(self.world.engine.torn)

    @property
    def contact_count(self) -> int:
        return int(self.world.contact_count)

    def observables(self) -> dict:
        return observables(self.model, self.world.state, self.world.contact_count)
