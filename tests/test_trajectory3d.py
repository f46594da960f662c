"""The 3D trajectory layout (docs/format.md, "Trajectories"): the writer, the reader,
`rbsim info`, and the engine's recorded frames (World3.advance_recording) in it."""

from __future__ import annotations

from typing import NamedTuple

import h5py
import numpy as np
import pytest

from rbsim.config import Config
from rbsim.core import CoreWorld
from rbsim.io.observables import observables
from rbsim.io.trajectory import (
    OBSERVABLES_3D,
    BodyTable,
    TrajectoryWriter,
    load_trajectory,
    summarize,
)
from rbsim.scene.compile import Model, State
from rbsim.scene.types import ROTATION_CODE, SHAPE_BOX


def box_world(
    size: tuple[float, float, float] = (0.2, 0.1, 0.05),
    mass: float = 2.0,
    com: tuple[float, float, float] = (0.01, 0.0, -0.02),
    omega: tuple[float, float, float] = (0.3, 5.0, 0.1),
    gravity: tuple[float, float, float] = (0.0, -9.81, 0.0),
    rotation: str = "split",
    dt: float = 1e-3,
) -> CoreWorld:
    """One box (principal axes = body axes, COM off the origin) as compiled arrays,
    built by hand as the contract lays them out (not by the scene compiler)."""
    a, b, c = size
    moments = mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    corners = np.array([[x, y, z] for x in (-a, a) for y in (-b, b) for z in (-c, c)]) / 2
    model = Model(
        body_type=np.zeros(1, np.int8),
        body_mass=np.array([mass]),
        body_inertia=np.diag(moments)[None],
        body_inv_mass=np.array([1.0 / mass]),
        body_inv_inertia=np.diag(1.0 / moments)[None],
        body_com=np.array([com]),
        body_axes=np.array([[1.0, 0.0, 0.0, 0.0]]),
        body_moments=moments[None],
        body_force=np.zeros((1, 3)),
        body_force_arm=np.zeros((1, 3)),
        body_torque=np.zeros((1, 3)),
        shape_body=np.zeros(1, np.int32),
        shape_kind=np.array([SHAPE_BOX], np.int32),
        shape_radius=np.zeros(1),
        shape_vstart=np.zeros(1, np.int32),
        shape_vcount=np.array([8], np.int32),
        shape_friction=np.array([0.5]),
        shape_restitution=np.zeros(1),
        vertex_local=corners - np.array(com),
        normal_local=np.zeros((8, 3)),
        gravity=np.array(gravity),
        linear_damping=0.0,
        angular_damping=0.0,
        has_forces=False,
        has_shapes=False,
    )
    w = np.array([omega])
    state = State(
        body_x=np.array([com]) + np.array([[0.0, 1.0, 0.0]]),
        body_q=np.array([[1.0, 0.0, 0.0, 0.0]]),
        body_angle=np.zeros(0),
        body_v=np.array([[1.0, 2.0, -0.5]]),
        body_w=w,
        body_l=w * moments,
    )
    config = Config(
        dt=dt,
        substeps=1,
        iterations=1,
        explicit=False,
        rotation=ROTATION_CODE[rotation],
        restitution_threshold=1.0,
        friction_rule=0,
        restitution_rule=3,
        elastic=False,
    )
    return CoreWorld.from_arrays(model, state, config, 3)


# a 1×1×1 box's 12 triangles, counter-clockwise from outside, over corners (x,y,z) in
# the order x major: index = 4 ix + 2 iy + iz
BOX_FACES = [
    (0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
    (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3),
]  # fmt: skip


def table3d() -> BodyTable:
    """A dynamic box and a static plane."""
    corners = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    inertia = np.stack([np.diag([1 / 6] * 3), np.diag([np.inf] * 3)])
    return BodyTable(
        name=["box", "ground"],
        type=["dynamic", "static"],
        mass=[1.0, np.inf],
        moment_of_inertia=inertia,
        center_of_mass=[(0, 0, 0), (0, 0, 0)],
        shape_body=[0, 1],
        shape_kind=["box", "plane"],
        shape_radius=[0.0, 0.0],
        shape_vertex_start=[0, 8],
        shape_vertex_count=[8, 1],
        shape_vertices=[*corners, (0, 0, 0)],
        shape_face_start=[0, 12],
        shape_face_count=[12, 0],
        shape_faces=BOX_FACES,
        shape_normal=[(0, 0, 0), (0, 1, 0)],
        dimension=3,
    )


def test_box_faces_are_counter_clockwise_from_outside() -> None:
    """The test's own box is right (the reader test below relies on it): every face's
    right-hand normal points away from the centre."""
    t = table3d()
    v = t.shape_vertices[:8]
    for i, j, k in t.shape_faces:
        n = np.cross(v[j] - v[i], v[k] - v[i])
        assert n @ v[i] > 0


def frame(q: np.ndarray, k: int) -> dict:
    """One frame of the two bodies with the box at orientation q."""
    return {
        "step": k,
        "time": 0.01 * k,
        "position": np.array([[0.0, 1.0 + k, 0.0], [0.0, 0.0, 0.0]]),
        "orientation": np.array([q, [1.0, 0.0, 0.0, 0.0]]),
        "angle": None,
        "velocity": np.array([[0.0, 1.0, 2.0], [0.0, 0.0, 0.0]]),
        "angular_velocity": np.array([[0.0, 3.0, 0.0], [0.0, 0.0, 0.0]]),
        "angular_momentum": np.array([[0.0, 0.5, 0.0], [0.0, 0.0, 0.0]]),
        "observables": {
            "kinetic_energy": 1.0 + k,
            "potential_energy": 0.0,
            "linear_momentum": np.array([0.0, 1.0, 2.0]),
            "angular_momentum": np.array([0.0, 0.5, float(k)]),
            "contact_count": 0,
        },
    }


def turning(k: int) -> np.ndarray:
    """The box turned by 0.4 k rad about y, as a quaternion whose sign alternates with k
    (q and -q are one rotation): the writer must make it continuous."""
    half = 0.2 * k
    return (-1) ** k * np.array([np.cos(half), 0.0, np.sin(half), 0.0])


def test_3d_layout_round_trips_with_continuous_quaternion_sign(tmp_path) -> None:
    path = tmp_path / "t.h5"
    with TrajectoryWriter(path, bodies=table3d(), parameters={}, frames=20) as w:
        for k in range(20):
            w.append(**frame(turning(k), k))
    with h5py.File(path) as f:
        g = f["particles/bodies"]
        assert g["box"].attrs["dimension"] == 3
        assert list(g["box"].attrs["boundary"]) == ["none"] * 3
        assert "angle" not in g
        assert g["position/value"].shape == (20, 2, 3)
        assert g["orientation/value"].shape == (20, 2, 4)
        assert g["angular_velocity/value"].shape == (20, 2, 3)
        assert g["angular_momentum/value"].shape == (20, 2, 3)
        assert g["angular_momentum/value"].attrs["unit"] == b"kg m2 s-1"
        assert g["moment_of_inertia"].shape == (2, 3, 3)
        assert g["shapes/faces"].dtype == np.int32 and g["shapes/faces"].shape == (12, 3)
        assert list(g["shapes/face_start"]) == [0, 12]
        assert f["observables/angular_momentum/value"].shape == (20, 3)
        assert f["observables/linear_momentum/value"].shape == (20, 3)
    traj = load_trajectory(path)
    assert traj.dimension == 3 and traj.angle is None
    assert traj.angular_momentum.shape == (20, 2, 3)
    assert traj.bodies.shape_kind == ["box", "plane"]
    np.testing.assert_array_equal(traj.bodies.shape_faces, BOX_FACES)
    np.testing.assert_array_equal(traj.bodies.shape_normal[1], (0, 1, 0))
    np.testing.assert_array_equal(traj.observables["angular_momentum"][:, 2], np.arange(20))
    q = traj.orientation[:, 0]
    # the same rotations as given (up to sign), now with a continuous sign
    for k in range(20):
        assert abs(q[k] @ turning(k)) == pytest.approx(1.0, abs=1e-15)  # unit, same rotation
    assert np.all(np.einsum("ij,ij->i", q[1:], q[:-1]) > 0)
    # the turn passes π at k = 16 (0.2 k > π/2): the stored w then goes negative
    # continuously rather than jumping
    assert q[0, 0] == 1.0 and q[19, 0] < 0


def test_quaternion_sign_continues_across_resume(tmp_path) -> None:
    path = tmp_path / "t.h5"
    w = TrajectoryWriter(
        path, bodies=table3d(), parameters={}, frames=20, observables=OBSERVABLES_3D
    )
    for k in range(12):
        w.append(**frame(turning(k), k))
    w.close(status="interrupted")
    w = TrajectoryWriter(
        path, bodies=table3d(), parameters={}, frames=20, observables=OBSERVABLES_3D, keep=12
    )
    for k in range(12, 20):
        w.append(**frame(turning(k), k))
    w.close()
    q = load_trajectory(path).orientation[:, 0]
    assert np.all(np.einsum("ij,ij->i", q[1:], q[:-1]) > 0)


def test_body_table_3d_checks_faces() -> None:
    t = table3d()
    with pytest.raises(ValueError, match="faces must index its 8 vertices"):
        BodyTable(**{**vars(t), "shape_faces": [(0, 1, 8)] + BOX_FACES[1:]})
    with pytest.raises(ValueError, match="unknown"):
        BodyTable(**{**vars(t), "shape_kind": ["polygon", "plane"]})
    sub = t.subset([1, 0])
    assert sub.shape_kind == ["plane", "box"]
    assert list(sub.shape_face_start) == [0, 0] and list(sub.shape_face_count) == [0, 12]
    np.testing.assert_array_equal(sub.shape_normal[0], (0, 1, 0))


def test_info_shows_dimension_and_3d_series(tmp_path) -> None:
    path = tmp_path / "t.h5"
    with TrajectoryWriter(path, bodies=table3d(), parameters={}, frames=3) as w:
        for k in range(3):
            w.append(**frame(turning(k), k))
    text = summarize(path)
    assert "dimension  3" in text
    assert "orientation (T,N,4)" in text and "angular_momentum (T,N,3)" in text
    assert "angle (T,N)" not in text
    assert "(0, 0.5, 2)" in text  # the last frame's angular momentum, a 3-vector


def recording_block(n: int, rows: int) -> dict[str, np.ndarray]:
    return {
        "step": np.full(rows, -1, np.int64),
        "time": np.zeros(rows),
        "position": np.zeros((rows, n, 3)),
        "orientation": np.zeros((rows, n, 4)),
        "velocity": np.zeros((rows, n, 3)),
        "angular_velocity": np.zeros((rows, n, 3)),
        "body_angular_momentum": np.zeros((rows, n, 3)),
        "kinetic_energy": np.zeros(rows),
        "potential_energy": np.zeros(rows),
        "linear_momentum": np.zeros((rows, 3)),
        "angular_momentum": np.zeros((rows, 3)),
        "contact_count": np.zeros(rows, np.int64),
    }


def quat_rotate(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    w, u = q[0], q[1:]
    t = 2.0 * np.cross(u, p)
    return p + w * t + np.cross(u, t)


def test_engine_records_3d_frames_as_the_contract_says() -> None:
    world = box_world()
    block = recording_block(1, 4)
    status, taken, written, _bad = world.engine.advance_recording(30, 10, 30, block, 0, None)
    assert (status, taken, written) == (0, 30, 3)
    assert list(block["step"][:3]) == [10, 20, 30]
    st = world.state
    x, q, v, w, l = (a[0] for a in (st.body_x, st.body_q, st.body_v, st.body_w, st.body_l))
    com = world.model.body_com[0]
    # position is the body origin: x - R(q) com (to round-off of the rotation)
    np.testing.assert_allclose(block["position"][2, 0], x - quat_rotate(q, com), atol=1e-15)
    np.testing.assert_array_equal(block["orientation"][2, 0], q)
    np.testing.assert_array_equal(block["velocity"][2, 0], v)
    np.testing.assert_array_equal(block["angular_velocity"][2, 0], w)
    np.testing.assert_array_equal(block["body_angular_momentum"][2, 0], l)
    obs = observables(world.model, st, 0)  # type: ignore[arg-type]
    m = world.model.body_mass[0]
    assert obs["kinetic_energy"] == pytest.approx(0.5 * m * v @ v + 0.5 * w @ l, rel=1e-15)
    for key in ("kinetic_energy", "potential_energy", "linear_momentum", "angular_momentum"):
        # the engine's sums and numpy's, in another order: round-off apart
        np.testing.assert_allclose(block[key][2], obs[key], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(block["angular_momentum"][2], np.cross(x, m * v) + l, rtol=1e-14)


def test_world3_checks_arrays_as_they_cross() -> None:
    good = box_world()
    model, state = good.model, good.state
    config = good.config
    cases = [
        (model._replace(body_inertia=np.zeros((1, 3))), state, "body_inertia"),
        (model._replace(body_inertia=np.array([[[1, 0.5, 0], [0, 1, 0], [0, 0, 1.0]]])), state,
         "not a symmetric tensor"),
        (model._replace(body_axes=np.array([[2.0, 0, 0, 0]])), state, "unit quaternion"),
        (model._replace(body_moments=np.array([[0.0, 1, 1]])), state, "positive"),
        (model._replace(body_com=np.zeros((1, 3), np.float32)), state, "body_com: wrong dtype"),
        (model._replace(gravity=np.zeros(2)), state, "gravity"),
        (model._replace(shape_kind=np.array([1], np.int32)), state, "shape_kind out of range"),
        (model, state._replace(body_l=np.zeros((2, 3))), "body_l: expected 1 rows"),
        (model, state._replace(body_q=np.zeros((1, 2))), "body_q: wrong shape"),
    ]  # fmt: skip
    for m, s, message in cases:
        with pytest.raises(ValueError, match=message):
            CoreWorld.from_arrays(m, s, config, 3)
    with pytest.raises(ValueError, match="rotation must be"):
        CoreWorld.from_arrays(model, state, config._replace(rotation=3), 3)
    short = NamedTuple("Short", [(k, object) for k in Model._fields if k != "body_axes"])
    fields = {k: v for k, v in model._asdict().items() if k != "body_axes"}
    with pytest.raises(ValueError, match="missing key body_axes"):
        CoreWorld.from_arrays(short(**fields), state, config, 3)  # type: ignore[arg-type]


def test_world3_checkpoint_restores_bit_for_bit() -> None:
    a = box_world(rotation="normalize")
    a.advance(100)
    data = a.engine.save_checkpoint()
    b = box_world(rotation="normalize")
    b.engine.load_checkpoint(data)
    assert b.step_index == 100
    a.advance(50)
    b.advance(50)
    for x, y in zip(a.state, b.state, strict=True):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(ValueError, match="checkpoint"):
        b.engine.load_checkpoint(data[:-8])


def test_world3_checks_config_values_as_they_cross() -> None:
    good = box_world()
    with pytest.raises(ValueError, match="substeps: not an integer"):
        CoreWorld.from_arrays(good.model, good.state, good.config._replace(substeps="4"), 3)
    with pytest.raises(ValueError, match="linear_damping: not a number"):
        CoreWorld.from_arrays(good.model._replace(linear_damping=None), good.state, good.config, 3)


def test_quaternion_sign_rule_at_a_half_turn_between_frames(tmp_path) -> None:
    # frames a half turn apart (q·q_prev = 0 exactly): no sign is nearer, and the rule
    # (negate only when the dot product is negative) keeps each as given
    qs = [(1.0, 0, 0, 0), (0, 1.0, 0, 0), (-1.0, 0, 0, 0), (-0.6, 0.8, 0, 0), (0.6, -0.8, 0, 0)]
    path = tmp_path / "t.h5"
    with TrajectoryWriter(path, bodies=table3d(), parameters={}, frames=len(qs)) as w:
        for k, q in enumerate(qs):
            w.append(**frame(np.array(q), k))
    got = load_trajectory(path).orientation[:, 0]
    # the last is the previous one negated (dot −1): written with the previous sign
    np.testing.assert_array_equal(got, [*qs[:4], qs[3]])
