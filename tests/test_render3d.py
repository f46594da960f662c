"""rbsim render of 3D trajectories to GIF, and rbsim plot of their 3-component series.

The trajectories are written directly in the 3D layout of docs/format.md ("Trajectories")
with h5py (known poses, no solver), so that what each pixel must show is known.
"""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from rbsim.view.mesh import Camera, quat_matrix, shade, shape_triangles
from rbsim.view.render import FrameReader, render_gif
from rbsim.view.render3d import COLOURS_3D, shaded_rgb
from tests.conftest import rbsim

PIL = pytest.importorskip("PIL", reason="the plot extra: pip install -e '.[plot]'")
from PIL import Image  # noqa: E402

DT = 0.05  # s between the synthetic frames
SPEED = 2.0  # m/s of the brick along x
SPIN = 1.5  # rad/s of the brick about y
BRICK = (1.6, 1.0, 1.0)  # m, the brick's full extents
BRICK_Y = 1.5  # m, the brick's height above the ground plane y = 0


def _outward(points: np.ndarray, tris: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    """The triangles of a convex solid, each counter-clockwise seen from outside."""
    centre = points.mean(axis=0)
    out = []
    for a, b, c in tris:
        n = np.cross(points[b] - points[a], points[c] - points[a])
        out.append((a, b, c) if n @ (points[a] - centre) > 0 else (a, c, b))
    return out


def box_shape(size: tuple[float, float, float]) -> tuple[np.ndarray, list]:
    """A box's 8 corners (body frame, m) and its 12 outward triangles."""
    half = np.array(size) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    quads = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return corners, _outward(corners, tris)


def quat_about(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a turn by `angle` rad about `axis`."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.array([math.cos(angle / 2), *(math.sin(angle / 2) * a)])


def write_trajectory3d(
    path: Path,
    names: list[str],
    types: list[str],
    shapes: list[dict],
    time: np.ndarray,
    position: np.ndarray,
    orientation: np.ndarray,
    observables: dict[str, np.ndarray] | None = None,
    engine: str = "rbsim",
) -> Path:
    """A 3D trajectory in docs/format.md's layout. shapes: dicts with body, kind, radius,
    vertices (k,3) and faces (m,3) (local indices) and normal (3,) (planes);
    position (T,N,3) m, orientation (T,N,4) (w, x, y, z)."""
    t, n = position.shape[:2]
    str_dt = h5py.string_dtype("utf-8")
    with h5py.File(path, "w") as f:
        f.create_group("h5md").attrs["version"] = np.array([1, 1], dtype=np.int32)
        g = f.create_group("particles/bodies")
        box = g.create_group("box")
        box.attrs["dimension"] = np.int32(3)
        box.attrs["boundary"] = np.array(["none"] * 3, dtype=str_dt)
        step = np.arange(t, dtype=np.int64)
        for name, value in (
            ("position", position),
            ("orientation", orientation),
            ("velocity", np.zeros((t, n, 3))),
            ("angular_velocity", np.zeros((t, n, 3))),
            ("angular_momentum", np.zeros((t, n, 3))),
        ):
            s = g.create_group(name)
            s["value"] = value
            s["step"] = step
            s["time"] = time
        g["name"] = np.array(names, dtype=object).astype(str_dt)
        g["type"] = np.array(types, dtype=object).astype(str_dt)
        g["mass"] = np.where(np.array(types) == "dynamic", 1.0, np.inf)
        g["moment_of_inertia"] = np.tile(np.eye(3), (n, 1, 1))
        g["center_of_mass"] = np.zeros((n, 3))
        sg = g.create_group("shapes")
        vstart, fstart, verts, faces = [], [], [], []
        for sh in shapes:
            vstart.append(sum(len(v) for v in verts))
            fstart.append(sum(len(x) for x in faces))
            verts.append(np.asarray(sh["vertices"], dtype=float).reshape(-1, 3))
            faces.append(np.asarray(sh.get("faces", []), dtype=np.int32).reshape(-1, 3))
        sg["body"] = np.array([sh["body"] for sh in shapes], dtype=np.int32)
        sg["kind"] = np.array([sh["kind"] for sh in shapes], dtype=object).astype(str_dt)
        sg["radius"] = np.array([sh.get("radius", 0.0) for sh in shapes])
        sg["vertex_start"] = np.array(vstart, dtype=np.int32)
        sg["vertex_count"] = np.array([len(v) for v in verts], dtype=np.int32)
        sg["vertices"] = np.concatenate(verts)
        sg["face_start"] = np.array(fstart, dtype=np.int32)
        sg["face_count"] = np.array([len(x) for x in faces], dtype=np.int32)
        sg["faces"] = np.concatenate(faces)
        sg["normal"] = np.array([sh.get("normal", (0, 0, 0)) for sh in shapes], dtype=float)
        for name, value in (observables or {}).items():
            o = f.create_group(f"observables/{name}")
            o["value"] = value
            o["step"] = step
            o["time"] = time
        rb = f.create_group("parameters/rbsim")
        for key, value in (
            ("engine", engine),
            ("status", "complete"),
            ("scene", "name: synthetic3d\n"),
        ):
            rb.create_dataset(key, data=value, dtype=str_dt)
    return path


def brick_scene(path: Path, frames: int = 41) -> Path:
    """ground (static plane y = 0), brick (box BRICK moving at SPEED along x from
    x = -3 at height BRICK_Y while turning at SPIN about y), ball (sphere r 0.6
    spinning in place at (3, 1, 0)), rod (capsule, still, at (0, 3, 0)) and tet
    (a convex tetrahedron, still, at (0, 0.5, -2))."""
    corners, faces = box_shape(BRICK)
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) - 0.25
    tet_faces = _outward(tet, [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)])
    shapes = [
        {"body": 0, "kind": "plane", "vertices": [[0, 0, 0]], "normal": (0, 1, 0)},
        {"body": 1, "kind": "box", "vertices": corners, "faces": faces},
        {"body": 2, "kind": "sphere", "vertices": [[0, 0, 0]], "radius": 0.6},
        {"body": 3, "kind": "capsule", "vertices": [[-0.5, 0, 0], [0.5, 0, 0]], "radius": 0.2},
        {"body": 4, "kind": "convex", "vertices": tet, "faces": tet_faces},
    ]
    time = np.arange(frames) * DT
    n = 5
    position = np.zeros((frames, n, 3))
    orientation = np.zeros((frames, n, 4))
    orientation[..., 0] = 1.0
    position[:, 1] = np.stack([-3 + SPEED * time, np.full(frames, BRICK_Y), 0 * time], 1)
    orientation[:, 1] = [quat_about((0, 1, 0), SPIN * t) for t in time]
    position[:, 2] = (3, 1, 0)
    orientation[:, 2] = [quat_about((0, 0, 1), 2.0 * t) for t in time]
    position[:, 3] = (0, 3, 0)
    position[:, 4] = (0, 0.5, -2)
    obs = {
        "kinetic_energy": np.full(frames, 0.5 * SPEED**2),
        "potential_energy": np.full(frames, 9.81 * BRICK_Y),
        "linear_momentum": np.tile([SPEED, 0.0, 0.0], (frames, 1)),
        "angular_momentum": np.tile([0.0, SPIN, 0.0], (frames, 1)),
    }
    return write_trajectory3d(
        path,
        ["ground", "brick", "ball", "rod", "tet"],
        ["static", "dynamic", "dynamic", "dynamic", "dynamic"],
        shapes,
        time,
        position,
        orientation,
        obs,
    )


def frames_rgb(path: Path) -> list[np.ndarray]:
    """Every frame of a GIF as (H,W,3) int RGB."""
    out = []
    with Image.open(path) as im:
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB")).astype(int))
    return out


def pixel_of(camera: Camera, size: tuple[int, int], point) -> tuple[int, int]:
    """(column, row) of world point (m) in the GIF drawn by `camera` at `size`."""
    px, depth = camera.project(np.array([point], dtype=float), *size)
    assert depth[0] > 0
    return int(px[0, 0]), int(px[0, 1])


def test_reader_knows_a_3d_trajectory_and_its_shapes(tmp_path):
    path = brick_scene(tmp_path / "b.h5", frames=5)
    with FrameReader(path) as r:
        assert r.dimension == 3
        assert r.bodies.name == ["ground", "brick", "ball", "rod", "tet"]
        pos, rot = r.read(np.array([0, 4]))
        assert pos.shape == (2, 5, 3) and rot.shape == (2, 5, 4)
        assert pos[1, 1, 0] == pytest.approx(-3 + SPEED * 4 * DT)
        assert shape_triangles(r.bodies, 1).shape == (12, 3)


def test_quat_matrix_turns_x_into_y_about_z():
    R = quat_matrix(quat_about((0, 0, 1), math.pi / 2))
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-15)  # round-off of cos(π/4)²
    # the stored sign is free: -q is the same rotation
    np.testing.assert_allclose(quat_matrix(-quat_about((1, 2, 3), 0.7)),
                               quat_matrix(quat_about((1, 2, 3), 0.7)), atol=1e-15)  # fmt: skip


def test_gif_3d_shows_the_shaded_brick_where_it_is_and_it_moves_and_turns(tmp_path):
    path = brick_scene(tmp_path / "b.h5", frames=41)  # 2 s
    out = tmp_path / "b.gif"
    size = (400, 300)
    result = render_gif(path, out, fps=10, size=size)
    frames = frames_rgb(out)
    assert len(frames) == result.frames == 21
    assert frames[0].shape == (300, 400, 3)
    camera = result.camera
    assert isinstance(camera, Camera)
    # the brick's top face (normal +y at every turn about y) at its centre: the exact
    # palette colour of a dynamic face of that brightness
    top = shaded_rgb(COLOURS_3D["dynamic_fill"], shade(np.array([0.0, 1.0, 0.0])))
    for k, t in ((0, 0.0), (20, 2.0)):
        col, row = pixel_of(camera, size, (-3 + SPEED * t, BRICK_Y + BRICK[1] / 2, 0))
        assert np.array_equal(frames[k][row, col], top), (k, frames[k][row, col], top)
    # where the brick was at t = 0 it is gone at t = 2 s: not the brick's colour there
    col, row = pixel_of(camera, size, (-3, BRICK_Y + BRICK[1] / 2, 0))
    assert not np.array_equal(frames[20][row, col], top)
    # consecutive frames differ (the brick moved, the ball turned); the turning itself
    # is test_gif_3d_shows_a_turning_body_in_changing_shades
    diff = (frames[0] != frames[1]).any(axis=2)
    assert diff.mean() > 0.001
    # the rod does not move: its pixel is the same in every frame
    col, row = pixel_of(camera, size, (0, 3, 0))
    assert all(np.array_equal(f[row, col], frames[0][row, col]) for f in frames)
    assert not np.array_equal(frames[0][row, col], [255, 255, 255])  # and drawn


def test_gif_3d_shows_a_turning_body_in_changing_shades(tmp_path):
    """A box turning in place about y: its visible side faces' shades change."""
    corners, faces = box_shape((1, 1, 1))
    time = np.arange(9) * 0.1
    q = np.array([[quat_about((0, 1, 0), 0.8 * k)] for k in range(9)])
    write_trajectory3d(
        tmp_path / "spin.h5", ["cube"], ["dynamic"],
        [{"body": 0, "kind": "box", "vertices": corners, "faces": faces}],
        time, np.zeros((9, 1, 3)), q,
    )  # fmt: skip
    result = render_gif(tmp_path / "spin.h5", tmp_path / "spin.gif", fps=10, size=(200, 160))
    frames = frames_rgb(tmp_path / "spin.gif")
    centre = pixel_of(result.camera, (200, 160), (0, 0, 0))
    patch = [f[centre[1] - 20 : centre[1] + 20, centre[0] - 20 : centre[0] + 20] for f in frames]
    assert not np.array_equal(patch[0], patch[1])  # the same place, other shades: it turned
    background = np.array([255, 255, 255])
    assert (patch[0] != background).any(axis=2).all()  # the cube fills the patch


def test_gif_3d_is_bit_identical_for_the_same_inputs(tmp_path):
    path = brick_scene(tmp_path / "b.h5", frames=6)
    render_gif(path, tmp_path / "a.gif", fps=10, size=(160, 120))
    render_gif(path, tmp_path / "c.gif", fps=10, size=(160, 120))
    assert (tmp_path / "a.gif").read_bytes() == (tmp_path / "c.gif").read_bytes()


def test_render_3d_cli_rejects_a_2d_view_and_a_2d_overlay(tmp_path):
    from tests.test_render import write_trajectory

    path = brick_scene(tmp_path / "b.h5", frames=3)
    code, _, err = rbsim("render", path, "-o", tmp_path / "x.gif", "--view", "0", "0", "1", "1")
    assert code == 1 and "3D trajectory: --view" in err
    flat = write_trajectory(tmp_path / "flat.h5", frames=3)
    for out in ("x.gif", "x.html"):
        code, _, err = rbsim("render", path, "--overlay", flat, "-o", tmp_path / out)
        assert code == 1 and "2D trajectory cannot be overlaid" in err
        assert "overlaid all the same" not in err  # only the error, no warning before it
    code, _, err = rbsim("render", path, "-o", tmp_path / "x.html", "--view", "0", "0", "1", "1")
    assert code == 1 and "3D trajectory: --view" in err


def test_plot_of_a_3d_trajectory_draws_three_momentum_components(tmp_path):
    path = brick_scene(tmp_path / "b.h5", frames=11)
    code, _, err = rbsim("plot", path, "-o", tmp_path / "e.png")
    assert code == 0, err
    from rbsim.view.plot import plot_lines, read_observables

    lines = {
        label: (panel, values)
        for panel, label, _style, values in plot_lines(read_observables(path))
    }
    for label, panel, value in (("px", 1, SPEED), ("py", 1, 0), ("pz", 1, 0),
                                ("Lx", 2, 0), ("Ly", 2, SPIN), ("Lz", 2, 0)):  # fmt: skip
        assert lines[label][0] == panel
        np.testing.assert_array_equal(lines[label][1], value)
    assert lines["total"][0] == 0


# ---------------------------------------------------------------------------------------
# Real runs: a small 3D scene through the engine, the file through load_trajectory
# ---------------------------------------------------------------------------------------

EVERY_KIND = """
    version: 1
    name: every_kind
    world: {dimension: 3, gravity: [0, -9.81, 0], dt: 0.01, duration: 0.5}
    bodies:
      - {name: ground, type: static, shape: {plane: {normal: [0, 1, 0], offset: 0}}}
      - name: crate
        position: [0, 2, 0]
        angular_velocity: [0, 2, 0]
        shape: {box: {size: [1, 0.6, 0.8]}}
      - name: ball
        position: [2, 2, 0]
        velocity: [0, 3, 0]
        angular_velocity: [0, 0, 4]
        shape: {sphere: {radius: 0.4}}
      - name: rod
        position: [-2, 2, 0]
        angular_velocity: [0, 0, 3]
        shape: {capsule: {a: [-0.5, 0, 0], b: [0.5, 0, 0], radius: 0.15}}
      - name: gem
        position: [0, 2, -2]
        angular_velocity: [1, 1, 0]
        shape: {convex: {vertices: [[0, 0, 0], [0.6, 0, 0], [0, 0.6, 0], [0, 0, 0.6]]}}
"""
CRATE_HALF_HEIGHT = 0.3  # m, half the crate's y extent in EVERY_KIND


def run_every_kind(tmp_path: Path) -> Path:
    """EVERY_KIND run by the engine to tmp_path/every.h5."""
    from rbsim.run import run_scene
    from tests.conftest import scene_from

    out = tmp_path / "every.h5"
    run_scene(scene_from(EVERY_KIND), out)
    return out


def test_gif_of_a_real_3d_run_shows_the_falling_crate_where_the_file_puts_it(tmp_path):
    from rbsim.io.trajectory import load_trajectory
    from rbsim.view.render import sample_frames

    path = run_every_kind(tmp_path)
    traj = load_trajectory(path)
    assert traj.dimension == 3
    size = (480, 360)
    gif = tmp_path / "every.gif"
    code, _, err = rbsim("render", path, "-o", gif, "--fps", "20", "--size", *map(str, size))
    assert code == 0, err
    idx = sample_frames(traj.time, 20)
    frames = frames_rgb(gif)
    assert len(frames) == len(idx) == 11
    camera = render_gif(path, tmp_path / "again.gif", fps=20, size=size).camera
    # the crate turns about y only: its top face keeps the normal +y, so the same colour
    top = shaded_rgb(COLOURS_3D["dynamic_fill"], shade(np.array([0.0, 1.0, 0.0])))
    crate = traj.body("crate")
    for k in (0, len(idx) - 1):
        x, y, z = traj.position[idx[k], crate]
        col, row = pixel_of(camera, size, (x, y + CRATE_HALF_HEIGHT, z))
        assert np.array_equal(frames[k][row, col], top), (k, frames[k][row, col], top)
    # it fell 1.2 m in 0.5 s: the first frame's top is not the crate's colour at the end
    x, y, z = traj.position[idx[0], crate]
    col, row = pixel_of(camera, size, (x, y + CRATE_HALF_HEIGHT, z))
    assert not np.array_equal(frames[-1][row, col], top)


def test_plot_of_a_real_3d_run_has_the_momenta_of_the_file(tmp_path):
    from rbsim.io.trajectory import load_trajectory
    from rbsim.view.plot import plot_lines, read_observables

    path = run_every_kind(tmp_path)
    code, _, err = rbsim("plot", path, "-o", tmp_path / "e.png")
    assert code == 0, err
    lines = {label: values for _p, label, _s, values in plot_lines(read_observables(path))}
    traj = load_trajectory(path)
    for j, axis in enumerate("xyz"):
        np.testing.assert_array_equal(lines[f"p{axis}"], traj.observables["linear_momentum"][:, j])
        np.testing.assert_array_equal(lines[f"L{axis}"], traj.observables["angular_momentum"][:, j])


def test_gif_3d_overlay_draws_the_second_run_as_orange_wireframes(tmp_path):
    main = brick_scene(tmp_path / "a.h5", frames=6)
    other = brick_scene(tmp_path / "b.h5", frames=6)
    render_gif(main, tmp_path / "alone.gif", fps=10, size=(320, 240))
    render_gif(main, tmp_path / "o.gif", fps=10, size=(320, 240), overlay=other)
    alone = frames_rgb(tmp_path / "alone.gif")[0]
    both = frames_rgb(tmp_path / "o.gif")[0]
    edge = COLOURS_3D["overlay_edge"]
    orange = np.array([int(edge[i : i + 2], 16) for i in (1, 3, 5)])
    near = (np.abs(both - orange) <= 40).all(axis=2)  # antialiased 0.7 px lines: within 40
    assert near.sum() > 200  # the edges of every body's facing faces
    assert not (np.abs(alone - orange) <= 40).all(axis=2).any()  # and none without it


def test_clip_near_keeps_the_part_of_the_ground_in_front_of_the_camera():
    from rbsim.view.render3d import NEAR_FRACTION, clip_near

    camera = Camera((0.0, 0.0, 0.0), 10.0, yaw=0.0, pitch=0.0)  # at z = 10, looking to -z
    near = NEAR_FRACTION * camera.distance
    square = np.array([[-1, 0, -5], [1, 0, -5], [1, 0, 20], [-1, 0, 20]], dtype=float)
    part = clip_near(square, camera, closed=True)
    depth = 10 - part[:, 2]
    assert len(part) == 4 and depth.min() == pytest.approx(near, rel=1e-12)  # cut at near
    assert depth.max() == pytest.approx(15.0)  # the far edge (z = -5) kept whole
    line = clip_near(square[[1, 2]], camera, closed=False)
    np.testing.assert_allclose(line, [[1, 0, -5], [1, 0, 10 - near]], rtol=1e-12)
    assert len(clip_near(square + [0, 0, 20], camera, closed=True)) == 0  # all behind


def test_gif_3d_draws_the_recorded_contact_points_and_leaves_them_out_when_asked(tmp_path):
    from rbsim.io.trajectory import load_trajectory
    from tests.test_contacts_output import BOX_ON_PLANE

    scene = tmp_path / "box.yaml"
    scene.write_text(BOX_ON_PLANE)
    run = tmp_path / "box.h5"
    assert rbsim("run", scene, "-o", run, "-q")[0] == 0
    contacts = load_trajectory(run).contacts
    size = (400, 300)
    gif, plain = tmp_path / "box.gif", tmp_path / "plain.gif"
    code, _, err = rbsim("render", run, "-o", gif, "--fps", "20", "--size", *map(str, size))
    assert code == 0, err
    code, _, err = rbsim("render", run, "-o", plain, "--fps", "20", "--size", "400", "300",
                         "--no-contacts")  # fmt: skip
    assert code == 0, err
    camera = render_gif(run, tmp_path / "again.gif", fps=20, size=size).camera
    red = np.array([int(COLOURS_3D["contact"][i : i + 2], 16) for i in (1, 3, 5)])
    frames, without = frames_rgb(gif), frames_rgb(plain)
    is_red = [(f == red).all(axis=2) for f in frames]
    assert not is_red[0].any()  # step 0: no contact yet
    # the last frame (the last step, 0.6 s): a dot at each of the four corners' points
    rows = contacts.frame(len(contacts.count) - 1)
    for point in contacts.position[rows]:
        col, row = pixel_of(camera, size, point)
        assert is_red[-1][row - 1 : row + 2, col - 1 : col + 2].any(), (point, col, row)
    # and the normals' lines up from them: red above each dot (rows decrease upwards)
    for point in contacts.position[rows]:
        col, row = pixel_of(camera, size, point + [0.0, 0.15, 0.0])
        assert is_red[-1][row - 1 : row + 2, col - 1 : col + 2].any(), (point, col, row)
    # --no-contacts: no red anywhere, and the same picture otherwise
    assert not any((f == red).all(axis=2).any() for f in without)
    assert (frames[-1] != without[-1]).any(axis=2).mean() < 0.01
