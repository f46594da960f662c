"""The one interface every engine is reached through: an Engine steps one scene and
reads its state back in scene body order.

compare, sweep, the hard cases, the benchmark and the run loop all drive engines
through it; adding a reference engine means one adapter (a subclass) and one entry in
rbsim.engines.ENGINES.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..config import NonFiniteState, TooManyPairs
from ..scene import Scene

__all__ = [
    "Engine",
    "EngineUnavailable",
    "NonFiniteState",
    "Snapshot",
    "TooManyPairs",
    "UnsupportedScene",
]


class UnsupportedScene(Exception):
    """The scene uses something the engine cannot express; the message names the body or
    the pair of bodies and what is missing."""


class EngineUnavailable(RuntimeError):
    """The engine's package is not installed; the message says how to install it."""


@dataclass
class Snapshot:
    """One engine's state, scene body order, D = 2 or 3: origin (N,D) m (the body origin
    as placed in the scene), angle (N,) rad (unwrapped; 2D only, None in 3D), orientation
    the stored rotation: (N,2) (cos θ, sin θ) in 2D, (N,4) unit quaternion (w, x, y, z) in
    3D, com (N,D) m (centre of mass), velocity (N,D) m/s of the centre of mass,
    angular_velocity (N,) rad/s in 2D, (N,3) rad/s world frame in 3D."""

    origin: np.ndarray
    angle: np.ndarray | None
    orientation: np.ndarray
    com: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray

    @property
    def q_norm(self) -> np.ndarray:
        """(N,) |q| of the stored orientation (1 for an exact unit rotation)."""
        return np.linalg.norm(self.orientation, axis=1)

    def finite(self) -> bool:
        """Whether every position and velocity is finite."""
        return bool(np.all(np.isfinite(self.origin)) and np.all(np.isfinite(self.velocity)))


class Engine:
    """A scene being stepped by one engine.

    name: the engine's name as a trajectory records it. scene: the scene it steps.
    dt (s): one step. mass (N,) kg and inertia about the centre of mass, (N,) kg·m² in
    2D, (N,3,3) body frame in 3D (inf for static and kinematic bodies), com_local (N,D) m
    the centre of mass in the body frame, dynamic (N,) bool: each engine's own mass
    properties. settings: the engine's
    settings as a trajectory's /parameters records them. step_time (s): wall time spent
    stepping so far (time.perf_counter), as the engine measures it.
    """

    name = ""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.dt = float(scene.world.dt)
        self.mass = np.zeros(0)
        self.inertia = np.zeros(0)
        self.com_local = np.zeros((0, 2))
        self.dynamic = np.zeros(0, bool)
        self.settings: dict = {}
        self.step_time = 0.0

    @classmethod
    def from_scene(cls, scene: Scene, **options) -> Engine:  # noqa: ANN003 - per engine
        """The scene ready to step; raises what the engine raises when it cannot express
        the scene (pymunk: UnsupportedScene)."""
        return cls(scene, **options)

    def advance(self, n: int) -> None:
        """Take n steps of dt; raises NonFiniteState (body index, step) if the state
        becomes non-finite (an engine that cannot tell while stepping raises it from
        `read`), TooManyPairs (rbsim) if a step would hold more contact pairs than the
        engine's bound."""
        raise NotImplementedError

    def read(self) -> Snapshot:
        """The current state (copies); may raise NonFiniteState (see advance)."""
        raise NotImplementedError

    @property
    def step_index(self) -> int:
        """Steps taken."""
        raise NotImplementedError

    @property
    def torn(self) -> bool:
        """True when a signal stopped a long step inside (the compiled engine's): the
        state is partway through it, and the engine neither steps nor checkpoints."""
        return False

    @property
    def time(self) -> float:
        """Simulated time of the current state, s."""
        return self.step_index * self.dt

    @property
    def contact_count(self) -> int:
        """Contact points of the last step."""
        raise NotImplementedError

    # Whether the engine records contact points into a block (output.contacts): the
    # block's contact_* keys (TrajectoryWriter.block). Other engines' files have none.
    records_contacts = False

    def record(self, block: dict[str, np.ndarray], row: int) -> None:
        """Write the current state as frame `row` of `block` (the trajectory writer's
        block: step, time s, position, orientation, angle, velocity, angular_velocity,
        and the observables, each with rows first; see TrajectoryWriter.block)."""
        s = self.read()
        with np.errstate(over="ignore", invalid="ignore"):
            obs = self.observables()
        values = {
            "position": s.origin,
            "orientation": s.orientation,
            "angle": s.angle,
            "velocity": s.velocity,
            "angular_velocity": s.angular_velocity,
            **obs,
        }
        for key, value in values.items():
            if key in block and value is not None:
                block[key][row] = value
        block["step"][row] = self.step_index
        block["time"][row] = self.time

    def advance_recording(
        self,
        n: int,
        every: int,
        last_step: int,
        block: dict[str, np.ndarray],
        row: int,
        stop: Callable[[], bool] | None = None,
    ) -> tuple[int, int, BaseException | None]:
        """Take up to n steps, recording a frame into `block` from `row` on after each
        step that is a multiple of `every` or is `last_step`, stopping early when the
        block is full. An engine that can looks at stop() between steps (every 20 ms or
        so) and stops when it is true. Returns (steps taken, frames recorded, and the
        NonFiniteState or KeyboardInterrupt that stopped it, or None)."""
        taken = written = 0
        rows = len(block["step"])
        while taken < n and row + written < rows:
            try:
                self.advance(1)
            except (NonFiniteState, TooManyPairs) as err:
                return taken, written, err
            taken += 1
            step = self.step_index
            if step % every == 0 or step == last_step:
                try:
                    self.record(block, row + written)
                except NonFiniteState as err:
                    return taken, written, err
                written += 1
        return taken, written, None

    def checkpoint(self) -> bytes | None:
        """The engine's whole state (bytes) for a resumed run, or None if it has none."""
        return None

    def checkpoint_size(self) -> int:
        """Bytes `checkpoint` would return now (0 for an engine without checkpoints)."""
        return 0

    def restore(self, data: bytes) -> None:
        """Continue from a `checkpoint` of an engine built from the same scene."""
        raise NotImplementedError(f"the {self.name} engine cannot resume a run")

    def observables(self) -> dict[str, float | np.ndarray]:
        """Sums over the dynamic bodies for a trajectory frame: kinetic_energy (J),
        potential_energy (J), linear_momentum (2,) (kg·m/s), angular_momentum about the
        world origin (kg·m²/s), contact_count (points)."""
        raise NotImplementedError
