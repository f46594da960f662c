"""The adapter of MuJoCo ("mujoco"), rbsim's reference engine in 3D.

The scene is written as an MJCF model (`mjcf`): one body with a free joint per dynamic
body, with the scene body's orientation, and an `inertial` element with rbsim's own mass
and full inertia tensor (`fullinertia`, about the centre of mass, at the COM's position
`pos` in the MuJoCo body's frame), from rbsim's compiled Model: MuJoCo never
computes mass properties itself (its meshes are float32: a hull's centre of mass comes
out 3e-9 m off and its inertia 7e-8 relative). Static bodies are not written and contacts
are disabled (`<flag contact="disable"/>`): the bridge takes only scenes whose bodies
cannot touch (one body with shapes, or none dynamic) and refuses the others with
UnsupportedScene, since rbsim collides them and MuJoCo would not; kinematic
bodies move as prescribed (x0 + v t, exp(t ω / 2) q0; MuJoCo has nothing to compute
for them). Gravity is written as the scene gives it, in rbsim's y-up world (MuJoCo
takes any vector; its z-up default does not apply). One scene step is
`solver.substeps` MuJoCo steps of dt / substeps with MuJoCo's Euler integrator
(semi-implicit: qvel += h qacc, then qpos moves with the new qvel).

Where the MuJoCo body's frame sits (MujocoSettings.frame): "com" (the default) puts it
at the centre of mass (inertial pos 0), "origin" at the scene's body origin (inertial
pos = the COM's body-frame offset). A free joint moves its frame's point with that
point's velocity, so with "origin" a spinning body whose COM is off its origin moves its
COM by h v_origin + (R(h ω) − 1) R com per step instead of h v_com: a first-order error
that rbsim (which moves the COM) does not have; measured on the thrown compound of
scenes/3d/compare (COM 0.31 m off the origin, |ω| = 6.4 rad/s, h = 1/240 s), 0.12 m of
COM position and 0.062 m/s of COM velocity off the semi-implicit parabola in 2 s
(halving with h), against round-off with "com". The comparison wants the engines'
methods, not that frame choice, to differ: "com".

State, as MuJoCo 4.0.0 keeps it (tests/test_mujoco.py measures it): a free joint's
qpos is the body frame's origin (3, world) and its orientation (w, x, y, z); qvel is the
frame origin's velocity (world frame) followed by the angular velocity in the BODY frame.
rbsim's layout: the body origin x − R p (p: the frame's point in rbsim's body frame, the
COM or 0), the COM's velocity v_frame + ω × R (com − p) and ω in the world frame.

Forces and torques go through xfrc_applied (world frame, at the COM): a scene force at
a body point adds its torque (R arm) × f, evaluated at the start of each MuJoCo step as
rbsim does. Damping: rbsim's law is implicit, v <- (v + h a) / (1 + h c) and
L <- (L + h τ) / (1 + h c_ang) (cpp/src/dynamics/integrate.cpp); MuJoCo's joint damping
acts on qvel (origin velocity, body-frame ω) with one coefficient for all six dofs, so
the bridge applies instead, before each step, the force -m c (v + h a) / (1 + h c) and
the torque -c_ang (L + h τ) / (1 + h c_ang): with them one Euler step gives rbsim's
damped COM velocity exactly and its damped L up to MuJoCo's own rotation error.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..config import NonFiniteState
from ..io.observables import observables
from ..scene import Scene
from ..scene import types as T
from ..scene.compile import Model, State, build
from ..scene.geometry3d import quat_matrix
from .base import Engine, EngineUnavailable, Snapshot, UnsupportedScene

try:
    import mujoco
except ImportError:  # the optional extra `mujoco` is not installed
    mujoco = None

__all__ = [
    "INSTALL_HINT",
    "MujocoEngine",
    "MujocoSettings",
    "mjcf",
    "quat_exp",
    "quat_matrix",
    "quat_mul",
]

INSTALL_HINT = (
    "MuJoCo is not installed; it is rbsim's optional extra `mujoco`: "
    "pip install 'rbsim[mujoco]' (make install installs it)"
)


FRAMES = ("com", "origin")


@dataclass
class MujocoSettings:
    """How the MuJoCo model is set up. substeps: MuJoCo steps per scene dt (each of
    length dt / substeps, s); None: the scene's solver.substeps. frame: where each MuJoCo
    body's frame sits, "com" or "origin" (the module's docstring)."""

    substeps: int | None = None
    frame: str = "com"


def quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """(N,4) unit quaternions exp(θ/2) of rotation vectors (N,3) (rad)."""
    angle = np.linalg.norm(rotvec, axis=1)
    half = 0.5 * angle
    k = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return np.concatenate([np.cos(half)[:, None], k[:, None] * rotvec], axis=1)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,4) Hamilton products a b of (N,4) quaternions (w, x, y, z)."""
    aw, av = a[:, :1], a[:, 1:]
    bw, bv = b[:, :1], b[:, 1:]
    w = aw * bw - np.sum(av * bv, axis=1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.concatenate([w, v], axis=1)


def _num(x: float) -> str:
    """A float as MJCF text that reads back to the same double (repr round-trips)."""
    return repr(float(x))


def _nums(values: np.ndarray) -> str:
    return " ".join(_num(v) for v in np.ravel(values))


def mjcf(
    model: Model,
    positions: np.ndarray,
    orientations: np.ndarray,
    timestep: float,
    name: str = "rbsim",
    names: list[str] | None = None,
    frame_points: np.ndarray | None = None,
) -> str:
    """The MJCF text of a 3D rbsim Model: a body with a free joint per dynamic body, its
    frame at `positions` (N,3) m (world) with `orientations` (N,4) (w, x, y, z), with
    rbsim's mass (kg) and full inertia tensor (kg·m², body frame, about the COM) at the
    COM's position in that frame, body_com − frame_points (N,3) m (frame_points: where
    the frame sits in rbsim's body frame; default the body origins, zeros); gravity
    (m/s²) as the model has it (y-up world); `timestep` (s) MuJoCo's step; Euler
    integrator; contacts disabled. MuJoCo body k+1 is the k-th dynamic body."""
    if frame_points is None:
        frame_points = np.zeros_like(model.body_com)
    lines = [
        f'<mujoco model="{name}">',
        '  <compiler angle="radian" inertiafromgeom="false"/>',
        f'  <option timestep="{_num(timestep)}" gravity="{_nums(model.gravity)}"'
        ' integrator="Euler">',
        '    <flag contact="disable"/>',
        "  </option>",
        "  <worldbody>",
    ]
    for i in np.flatnonzero(model.body_type == T.BODY_DYNAMIC):
        inertia = model.body_inertia[i]
        full = [inertia[0, 0], inertia[1, 1], inertia[2, 2]]
        full += [inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        label = names[i] if names else f"body{i}"
        label = label.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
        lines += [
            f'    <body name="{label}" pos="{_nums(positions[i])}"'
            f' quat="{_nums(orientations[i])}">',
            "      <freejoint/>",
            f'      <inertial pos="{_nums(model.body_com[i] - frame_points[i])}"'
            f' mass="{_num(model.body_mass[i])}" fullinertia="{_nums(full)}"/>',
            "    </body>",
        ]
    lines += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


class MujocoEngine(Engine):
    """A 3D scene stepped by MuJoCo (see the module's docstring). `model`: rbsim's compiled
    Model of the scene (the masses and inertias written); `xml`: the MJCF written;
    `mj_model`, `mj_data`: MuJoCo's MjModel and MjData."""

    name = "mujoco"

    def __init__(self, scene: Scene, settings: MujocoSettings | None = None) -> None:
        if mujoco is None:
            raise EngineUnavailable(INSTALL_HINT)
        if int(getattr(scene.world, "dimension", 2)) != 3:
            raise UnsupportedScene(
                "MuJoCo is the reference engine of 3D scenes only (2D compares with pymunk)"
            )
        super().__init__(scene)
        self.model, state = build(scene)
        model = self.model
        if model.has_shapes:
            # rbsim collides in 3D; this bridge writes no MuJoCo contacts yet (issue 16:
            # MuJoCo's soft contacts need per-pair solref/solimp to match a restitution),
            # so a scene whose bodies can touch would compare different physics
            raise UnsupportedScene(
                "the MuJoCo bridge compares free bodies only: two bodies of this scene can "
                "touch (rbsim collides them; the bridge writes no MuJoCo contacts yet)"
            )
        settings = settings or MujocoSettings()
        if settings.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, not {settings.frame!r}")
        self.frame = settings.frame
        self.substeps = int(settings.substeps or scene.solver.substeps)
        self.h = self.dt / self.substeps
        self.mass = model.body_mass.copy()
        self.inertia = model.body_inertia.copy()
        self.com_local = model.body_com.copy()
        self.dynamic = model.body_type == T.BODY_DYNAMIC
        self.kinematic = model.body_type == T.BODY_KINEMATIC
        self._dyn = np.flatnonzero(self.dynamic)
        rot0 = quat_matrix(state.body_q)
        self._origin0 = state.body_x - np.einsum("nij,nj->ni", rot0, model.body_com)
        self._q0 = state.body_q.copy()
        self._v0 = state.body_v.copy()
        self._w0 = state.body_w.copy()
        # the MuJoCo frame's point in rbsim's body frame, and the COM from it
        self._point = (
            model.body_com.copy() if self.frame == "com" else np.zeros_like(model.body_com)
        )
        self._arm_com = model.body_com - self._point
        self.xml = mjcf(
            model,
            self._origin0 + np.einsum("nij,nj->ni", rot0, self._point),
            self._q0,
            self.h,
            name=scene.name,
            names=[b.name for b in scene.bodies],
            frame_points=self._point,
        )
        self.mj_model = mujoco.MjModel.from_xml_string(self.xml)
        self.mj_data = mujoco.MjData(self.mj_model)
        d, dyn = self.mj_data, self._dyn
        qpos = d.qpos.reshape(-1, 7)
        qvel = d.qvel.reshape(-1, 6)
        r = np.einsum("nij,nj->ni", rot0[dyn], self._arm_com[dyn])
        qvel[:, :3] = self._v0[dyn] - np.cross(self._w0[dyn], r)
        qvel[:, 3:] = np.einsum("nji,nj->ni", rot0[dyn], self._w0[dyn])  # Rᵀ ω
        assert qpos.shape[0] == len(dyn)
        self._force = model.body_force[dyn]
        self._torque = model.body_torque[dyn]
        self._arm = model.body_force_arm[dyn]
        self._moving_arm = bool(model.has_forces and np.any(self._arm != 0.0))
        self._damped = bool(model.linear_damping or model.angular_damping)
        self._per_step = self._moving_arm or self._damped
        if model.has_forces and not self._per_step:
            d.xfrc_applied[1:, :3] = self._force
            d.xfrc_applied[1:, 3:] = self._torque
        self._steps = 0
        self.settings = {
            "substeps": self.substeps,
            "timestep": self.h,
            "integrator": "Euler",
            "contacts": "disabled",
            "frame": self.frame,
            "mujoco_version": mujoco.__version__,
        }

    def _applied(self) -> None:
        """xfrc_applied for the next MuJoCo step: the scene's forces and torques, with a
        force's torque about the COM at the current orientation, and the damping force
        and torque that give rbsim's implicit damping law (module docstring)."""
        model, d, dyn = self.model, self.mj_data, self._dyn
        qpos = d.qpos.reshape(-1, 7)
        force = self._force.copy()
        torque = self._torque.copy()
        rot = quat_matrix(qpos[:, 3:])
        if self._moving_arm:
            torque += np.cross(np.einsum("nij,nj->ni", rot, self._arm), self._force)
        if self._damped:
            h = self.h
            m = model.body_mass[dyn][:, None]
            v, w = self._com_velocity(rot), self._world_omega(rot)
            c, ca = model.linear_damping, model.angular_damping
            if c:
                force -= m * c * (v + h * (model.gravity + force / m)) / (1.0 + h * c)
            if ca:
                ang = self._momentum(rot, w)
                torque -= ca * (ang + h * torque) / (1.0 + h * ca)
        d.xfrc_applied[1:, :3] = force
        d.xfrc_applied[1:, 3:] = torque

    def _world_omega(self, rot: np.ndarray) -> np.ndarray:
        """(n,3) world angular velocities of the dynamic bodies (rad/s)."""
        qvel = self.mj_data.qvel.reshape(-1, 6)
        return np.einsum("nij,nj->ni", rot, qvel[:, 3:])

    def _com_velocity(self, rot: np.ndarray) -> np.ndarray:
        """(n,3) COM velocities of the dynamic bodies (m/s): v_frame + ω × R (com − p)."""
        qvel = self.mj_data.qvel.reshape(-1, 6)
        r = np.einsum("nij,nj->ni", rot, self._arm_com[self._dyn])
        return qvel[:, :3] + np.cross(self._world_omega(rot), r)

    def _momentum(self, rot: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(n,3) world angular momenta about the COMs, R I_b Rᵀ ω (kg·m²/s)."""
        inertia = self.model.body_inertia[self._dyn]
        world = np.einsum("nij,njk,nlk->nil", rot, inertia, rot)
        return np.einsum("nij,nj->ni", world, w)

    def advance(self, n: int) -> None:
        t0 = time.perf_counter()
        m, d = self.mj_model, self.mj_data
        try:
            if n <= 0 or len(self._dyn) == 0:
                pass
            elif self._per_step:
                for _ in range(n * self.substeps):
                    self._applied()
                    mujoco.mj_step(m, d)
            else:
                mujoco.mj_step(m, d, nstep=n * self.substeps)
        finally:
            self.step_time += time.perf_counter() - t0
        self._steps += max(n, 0)
        bad = ~np.isfinite(d.qpos.reshape(-1, 7)).all(axis=1)
        bad |= ~np.isfinite(d.qvel.reshape(-1, 6)).all(axis=1)
        if bad.any():
            raise NonFiniteState(int(self._dyn[np.argmax(bad)]), self._steps)
        # MuJoCo does not stop on a non-finite or huge (> 1e10) acceleration: it warns
        # and resets the state to the model's initial one, which would read as a valid
        # state. Its explicit Euler grows a fast spin's wobble exponentially (|ω| h near
        # 1), so this is reachable.
        warning = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        if warning.number > 0:
            dof = min(max(int(warning.lastinfo), 0), m.nv - 1)
            raise NonFiniteState(int(self._dyn[int(m.dof_bodyid[dof]) - 1]), self._steps)

    def read(self) -> Snapshot:
        n = len(self.scene.bodies)
        t = self.time
        origin = self._origin0.copy()
        q = self._q0.copy()
        v = np.zeros((n, 3))
        w = np.zeros((n, 3))
        kin = self.kinematic
        if kin.any():  # prescribed motion
            origin[kin] = self._origin0[kin] + t * self._v0[kin]
            q[kin] = quat_mul(quat_exp(t * self._w0[kin]), self._q0[kin])
            v[kin], w[kin] = self._v0[kin], self._w0[kin]
        dyn = self._dyn
        qpos = self.mj_data.qpos.reshape(-1, 7)
        if len(dyn):
            rot = quat_matrix(qpos[:, 3:])
            origin[dyn] = qpos[:, :3] - np.einsum("nij,nj->ni", rot, self._point[dyn])
            q[dyn] = qpos[:, 3:]
            v[dyn] = self._com_velocity(rot)
            w[dyn] = self._world_omega(rot)
        com = origin + np.einsum("nij,nj->ni", quat_matrix(q), self.com_local)
        return Snapshot(
            origin=origin,
            angle=None,
            orientation=q,
            com=com,
            velocity=v,
            angular_velocity=w,
        )

    def state(self) -> State:
        """The current state in rbsim's layout (State of rbsim.scene.compile): COM x, q,
        COM v, world ω and world L about each COM (0 for bodies that are not dynamic)."""
        s = self.read()
        ang = np.zeros_like(s.angular_velocity)
        if len(self._dyn):
            rot = quat_matrix(s.orientation[self._dyn])
            ang[self._dyn] = self._momentum(rot, s.angular_velocity[self._dyn])
        return State(
            body_x=s.com,
            body_q=s.orientation,
            body_angle=np.zeros(0),
            body_v=s.velocity,
            body_w=s.angular_velocity,
            body_l=ang,
        )

    def record(self, block: dict[str, np.ndarray], row: int) -> None:
        super().record(block, row)
        if "body_angular_momentum" in block:
            block["body_angular_momentum"][row] = self.state().body_l

    @property
    def step_index(self) -> int:
        return self._steps

    @property
    def contact_count(self) -> int:
        return 0

    def observables(self) -> dict:
        return observables(self.model, self.state(), 0)

    def checkpoint(self) -> bytes:
        d = self.mj_data
        head = np.array([self._steps, d.time], np.float64)
        return np.concatenate([head, d.qpos, d.qvel]).tobytes()

    def restore(self, data: bytes) -> None:
        values = np.frombuffer(data, np.float64)
        d = self.mj_data
        nq, nv = len(d.qpos), len(d.qvel)
        if len(values) != 2 + nq + nv:
            raise ValueError("the checkpoint is not of this scene's MuJoCo model")
        self._steps = int(values[0])
        d.time = float(values[1])
        d.qpos[:] = values[2 : 2 + nq]
        d.qvel[:] = values[2 + nq :]
