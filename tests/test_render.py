"""rbsim render (GIF and HTML player) and rbsim plot.

Trajectories are written directly with TrajectoryWriter (known positions, no solver),
plus one written by the pymunk bridge. The player page is tested in a real headless
browser (Debian's chromium driven by playwright); without chromium those tests skip.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rbsim.io.trajectory import BodyTable, TrajectoryWriter
from rbsim.view.render import (
    COLOURS,
    FrameReader,
    View,
    fit_view,
    gif_delays,
    render_gif,
    sample_frames,
)
from tests.conftest import canvas_rgb, open_page, rbsim, scene_from

PIL = pytest.importorskip("PIL", reason="the plot extra: pip install -e '.[plot]'")
from PIL import Image  # noqa: E402

DT = 0.05  # s between the synthetic frames
SPEED = 2.0  # m/s of the box along x


def _bodies() -> BodyTable:
    """ground (static segment, zero radius), box (1 x 1), wheel (circle r = 0.5),
    crate (compound: box, triangle, circle, capsule)."""
    verts = [
        [-10, 0], [10, 0],                                   # ground segment
        [-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5],  # box
        [0, 0],                                              # wheel centre
        [-0.4, -0.3], [0.4, -0.3], [0.4, 0.3], [-0.4, 0.3],  # crate box
        [0.4, -0.3], [0.9, -0.3], [0.4, 0.3],                # crate triangle
        [-0.6, 0.0],                                         # crate circle
        [-0.4, 0.5], [0.4, 0.5],                             # crate capsule
    ]  # fmt: skip
    return BodyTable(
        name=["ground", "box", "wheel", "crate"],
        type=["static", "dynamic", "dynamic", "dynamic"],
        mass=[np.inf, 1.0, 1.0, 2.0],
        moment_of_inertia=[np.inf, 1 / 6, 0.125, 0.5],
        center_of_mass=np.zeros((4, 2)),
        shape_body=[0, 1, 2, 3, 3, 3, 3],
        shape_kind=["segment", "box", "circle", "box", "polygon", "circle", "segment"],
        shape_radius=[0, 0, 0.5, 0, 0, 0.2, 0.1],
        shape_vertex_start=[0, 2, 6, 7, 11, 14, 15],
        shape_vertex_count=[2, 4, 1, 4, 3, 1, 2],
        shape_vertices=verts,
    )


def write_trajectory(path: Path, frames: int = 41, box_y: float = 2.0, engine: str = "rbsim"):
    """A trajectory with known motion: the box moves at SPEED along x from x = -3,
    the wheel spins in place at (3, 1), the crate rests at (0, 5), DT s apart."""
    bodies = _bodies()
    with TrajectoryWriter(
        path, bodies=bodies, parameters={"scene": "name: synthetic\n"}, engine=engine
    ) as w:
        for k in range(frames):
            t = k * DT
            pos = np.array([[0, 0], [-3 + SPEED * t, box_y], [3, 1], [0, 5]], dtype=float)
            ang = np.array([0, 0, 2.0 * t, 0])
            rot = np.stack([np.cos(ang), np.sin(ang)], axis=1)
            vel = np.array([[0, 0], [SPEED, 0], [0, 0], [0, 0]], dtype=float)
            obs = {
                "kinetic_energy": 0.5 * SPEED**2,
                "potential_energy": 9.81 * box_y,
                "linear_momentum": np.array([SPEED, 0.0]),
                "angular_momentum": 0.25,
            }
            w.append(k, t, pos, rot, ang, vel, np.array([0, 0, 2.0, 0]), obs)
    return path


def pixel(view: View, size: tuple[int, int], x: float, y: float) -> tuple[int, int]:
    """The (column, row) of world point (x, y) m in an image of `size` showing `view`."""
    w, h = size
    col = (x - view.x0) / (view.x1 - view.x0) * w
    row = (view.y1 - y) / (view.y1 - view.y0) * h
    return int(col), int(row)


def hex_rgb(colour: str) -> tuple[int, int, int]:
    return tuple(int(colour[i : i + 2], 16) for i in (1, 3, 5))  # type: ignore[return-value]


# ---------------------------------------------------------------------------------------
# Thinning and the camera
# ---------------------------------------------------------------------------------------


def test_sample_frames_picks_one_stored_frame_per_output_frame_by_time():
    time = np.arange(301) / 60.0  # 5 s at 60 frames/s
    idx = sample_frames(time, 30.0)
    assert len(idx) == 5 * 30 + 1
    assert np.array_equal(idx, np.arange(0, 301, 2))  # every second stored frame
    # fewer stored frames than asked for: each stored frame once, none repeated
    sparse = np.arange(0, 5.01, 0.5)
    assert np.array_equal(sample_frames(sparse, 30.0), np.arange(len(sparse)))
    # a window of the run
    part = sample_frames(time, 10.0, start=1.0, end=2.0)
    assert time[part[0]] == pytest.approx(1.0) and time[part[-1]] == pytest.approx(2.0)
    assert len(part) == 11
    assert len(sample_frames(time, 30.0, start=6.0)) == 0


def test_gif_delays_add_up_to_the_simulated_time():
    times = np.arange(0, 91) / 30.0  # 3 s at 30 frames/s: 1/30 s is not whole 1/100 s
    delays = gif_delays(times, 1 / 30)
    assert set(delays) <= {30, 40}  # each frame 3 or 4 hundredths of a second
    # the whole GIF lasts the simulated time, to one GIF tick (10 ms, its unit)
    assert abs(sum(delays) - (times[-1] + 1 / 30) * 1000) <= 10


def test_fit_view_holds_every_moving_body_at_every_frame(tmp_path):
    path = write_trajectory(tmp_path / "t.h5")
    with FrameReader(path) as r:
        idx = np.arange(len(r.time))
        view = fit_view([(r, idx)])
    # the box sweeps x from -3 to -3 + SPEED * 2 s = 1, its half-diagonal 0.71 m
    assert view.x0 < -3 - 0.7 and view.x1 > 1 + 0.7
    # the wheel at x = 3 with r = 0.5, the crate's top at 5.5 m (capsule 0.5 + 0.1)
    assert view.x1 > 3.5 and view.y1 > 5.6 and view.y0 < 0.5
    # the static ground (20 m long) is not fitted: the view stays near the bodies
    assert view.x1 - view.x0 < 12


# ---------------------------------------------------------------------------------------
# GIF
# ---------------------------------------------------------------------------------------


def test_gif_has_the_frame_count_and_size_asked_for(tmp_path):
    path = write_trajectory(tmp_path / "t.h5", frames=41)  # 2 s
    out = tmp_path / "movie.gif"
    result = render_gif(path, out, fps=10, size=(320, 200))
    with Image.open(out) as im:
        assert im.size == (320, 200)
        assert im.n_frames == result.frames == 2 * 10 + 1
        total = 0
        for k in range(im.n_frames):
            im.seek(k)
            total += im.info["duration"]
    assert abs(total - 2.1 * 1000) <= 10  # ms; plays in real time, to one 10 ms GIF tick


def test_gif_frame_differs_where_the_body_moved(tmp_path):
    path = write_trajectory(tmp_path / "t.h5", frames=41)
    out = tmp_path / "movie.gif"
    size = (400, 300)
    result = render_gif(path, out, fps=10, size=size)
    fill = np.array(hex_rgb(COLOURS["dynamic_fill"]))
    background = np.array(hex_rgb(COLOURS["background"]))
    with Image.open(out) as im:
        im.seek(0)
        first = np.asarray(im.convert("RGB")).astype(int)
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB")).astype(int)
    start = pixel(result.view, size, -3.0, 2.0)  # the box's centre at t = 0
    end = pixel(result.view, size, -3.0 + SPEED * 2.0, 2.0)  # and at t = 2 s
    assert np.array_equal(first[start[1], start[0]], fill)
    assert np.array_equal(last[start[1], start[0]], background)
    assert np.array_equal(last[end[1], end[0]], fill)
    assert np.array_equal(first[end[1], end[0]], background)
    # the crate does not move: the same there in both frames
    crate = pixel(result.view, size, 0.0, 5.0)
    assert np.array_equal(first[crate[1], crate[0]], last[crate[1], crate[0]])


def test_gif_is_bit_identical_for_the_same_inputs(tmp_path):
    path = write_trajectory(tmp_path / "t.h5", frames=11)
    render_gif(path, tmp_path / "a.gif", fps=10, size=(160, 120))
    render_gif(path, tmp_path / "b.gif", fps=10, size=(160, 120))
    assert (tmp_path / "a.gif").read_bytes() == (tmp_path / "b.gif").read_bytes()


def test_gif_overlay_draws_the_second_trajectory_in_its_colour(tmp_path):
    main = write_trajectory(tmp_path / "a.h5", frames=11)
    other = write_trajectory(tmp_path / "b.h5", frames=11, box_y=4.0, engine="pymunk")
    size = (400, 300)
    view = View(-5, -1, 5, 6)
    result = render_gif(main, tmp_path / "o.gif", fps=10, size=size, view=view, overlay=other)
    with Image.open(tmp_path / "o.gif") as im:
        frame = np.asarray(im.convert("RGB")).astype(int)
    # the other box's outline: its left edge at x = -3.5, between y = 3.5 and 4.5
    col, row = pixel(result.view, size, -3.5, 4.0)
    patch = frame[row - 2 : row + 3, col - 2 : col + 3].reshape(-1, 3)
    assert any(np.array_equal(p, hex_rgb(COLOURS["overlay_edge"])) for p in patch)


def test_render_reads_only_the_frames_it_shows(tmp_path, monkeypatch):
    path = write_trajectory(tmp_path / "t.h5", frames=41)  # 20 frames/s stored
    seen: list[int] = []
    original = FrameReader.read

    def spy(self, idx):
        seen.extend(int(i) for i in idx)
        return original(self, idx)

    monkeypatch.setattr(FrameReader, "read", spy)
    render_gif(path, tmp_path / "m.gif", fps=5, size=(64, 48), view=View(-5, -1, 5, 6))
    assert sorted(seen) == list(range(0, 41, 4))  # every fourth stored frame, once


def test_gif_of_a_pymunk_trajectory_with_every_shape_kind(tmp_path):
    from rbsim.tools.compare import pymunk_settings_for, run_pymunk_to_file

    scene = scene_from(
        """
        version: 1
        world: {dt: 1/60, steps: 30}
        bodies:
          - {name: ground, type: static, shape: {segment: {a: [-5, 0], b: [5, 0]}}}
          - name: crate
            position: [0, 2]
            angular_velocity: 1.0
            shapes:
              - {box: {size: [1, 0.5]}}
              - {polygon: {vertices: [[0.5, -0.25], [1, -0.25], [0.5, 0.25]]}}
              - {circle: {radius: 0.3, offset: [-0.8, 0]}}
          - name: rod
            position: [2, 3]
            shape: {segment: {a: [-0.5, 0], b: [0.5, 0], radius: 0.1}}
        """
    )
    path = tmp_path / "pm.h5"
    run_pymunk_to_file(scene, path, pymunk_settings_for(scene))
    code, out, err = rbsim("render", path, "-o", tmp_path / "pm.gif", "--fps", "20")
    assert code == 0, err
    with FrameReader(path) as r:
        assert r.engine == "pymunk"
        expected = len(sample_frames(r.time, 20))
    with Image.open(tmp_path / "pm.gif") as im:
        assert im.n_frames == expected
        drawn = np.asarray(im.convert("RGB"))
    assert (drawn != hex_rgb(COLOURS["background"])).any(axis=2).mean() > 0.01  # not blank


# ---------------------------------------------------------------------------------------
# The command line
# ---------------------------------------------------------------------------------------


def test_render_cli_errors_name_the_file_and_exit_with_the_right_code(tmp_path):
    good = write_trajectory(tmp_path / "t.h5", frames=3)
    notes = tmp_path / "notes.txt"
    notes.write_text("hello\n")
    code, _, err = rbsim("render", notes, "-o", tmp_path / "x.gif")
    assert code == 1 and "notes.txt: not an HDF5 file" in err and "Traceback" not in err
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.mp4")
    assert code == 2 and ".gif or .html" in err
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.gif", "--view", "1", "0", "0", "1")
    assert code == 2 and "X0 < X1" in err
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.gif", "--fps", "60")
    assert code == 2 and "at most 50" in err
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.gif", "--start", "9")
    assert code == 1 and str(good) in err and "no frame between" in err
    code, _, err = rbsim("render", tmp_path / "missing.h5")
    assert code == 2
    h5 = tmp_path / "other.h5"
    import h5py

    with h5py.File(h5, "w") as f:
        f["x"] = 1
    code, _, err = rbsim("render", h5, "-o", tmp_path / "x.html")
    assert code == 1 and "other.h5: not an rbsim trajectory" in err


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (("--fps", "nan"), "--fps"),
        (("--fps", "inf"), "--fps"),
        (("--fps", "1e300"), "--fps"),  # above the page's 240
        (("--start", "nan"), "--start"),
        (("--end", "inf"), "--end"),
        (("--view", "0", "0", "inf", "1"), "--view"),
    ],
)
def test_render_refuses_non_finite_numbers_as_usage_errors(tmp_path, args, option):
    """nan and inf pass click's float ranges (or stop a page's player with a ValueError
    traceback, or a JSON encoder's): a usage error naming the option instead."""
    good = write_trajectory(tmp_path / "t.h5", frames=3)
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.html", *args)
    assert code == 2 and f"'{option}'" in err and "Traceback" not in err
    assert not (tmp_path / "x.html").exists()


def test_render_without_matplotlib_says_how_to_install_it(tmp_path, monkeypatch):
    good = write_trajectory(tmp_path / "t.h5", frames=3)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now fails
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.gif")
    assert code == 1 and "needs matplotlib" in err and "rbsim[plot]" in err
    code, _, err = rbsim("plot", good, "-o", tmp_path / "e.png")
    assert code == 1 and "needs matplotlib" in err
    # the HTML player needs no matplotlib
    code, _, err = rbsim("render", good, "-o", tmp_path / "x.html")
    assert code == 0, err


def test_plot_draws_energy_and_momentum_of_several_trajectories(tmp_path):
    a = write_trajectory(tmp_path / "a.h5", frames=11)
    b = write_trajectory(tmp_path / "b.h5", frames=11, box_y=3.0, engine="pymunk")
    code, out, err = rbsim("plot", a, b, "-o", tmp_path / "e.png")
    assert code == 0, err
    with Image.open(tmp_path / "e.png") as im:
        assert im.size[0] > 300 and im.size[1] > 300
    from rbsim.view.plot import read_observables

    obs = read_observables(b)
    assert obs.label == "b.h5 (pymunk)"
    np.testing.assert_allclose(obs.values["total_energy"], 0.5 * SPEED**2 + 9.81 * 3.0)
    code, _, err = rbsim("plot", a, "-o", tmp_path / "e.txt")
    assert code == 2 and ".png, .pdf or .svg" in err


def test_plot_titles_name_z_only_in_3d(tmp_path):
    from rbsim.view.plot import panel_titles, read_observables

    flat = read_observables(write_trajectory(tmp_path / "a.h5", frames=3))
    _energy, momentum, angular = panel_titles([flat])
    assert momentum == "x (solid), y (dashed)" and angular == ""  # L is a scalar in 2D
    solid = replace(flat, values={**flat.values, "linear_momentum": np.zeros((3, 3))})
    assert "z (dash-dot)" in panel_titles([flat, solid])[1]


# ---------------------------------------------------------------------------------------
# The HTML player
# ---------------------------------------------------------------------------------------


def test_html_page_is_self_contained_and_grows_with_frames_times_bodies(tmp_path):
    from rbsim.view.player import render_html

    path = write_trajectory(tmp_path / "t.h5", frames=41)
    small = render_html(path, tmp_path / "a.html", fps=5)
    large = render_html(path, tmp_path / "b.html", fps=20)
    text = (tmp_path / "b.html").read_text()
    for remote in ("http://", "https://", "src=", "@import", "url("):
        assert remote not in text
    # per frame: 4 bodies x 3 float32 = 48 bytes, 64 in base64, plus the time and index
    per_frame = (large.size - small.size) / (large.frames - small.frames)
    assert 64 <= per_frame < 120  # bytes: the numbers and their JSON separators, no more
    assert render_html(path, tmp_path / "c.html", fps=20).size == large.size
    assert (tmp_path / "b.html").read_bytes() == (tmp_path / "c.html").read_bytes()


def test_html_player_draws_the_bodies_and_the_slider_moves_them(tmp_path, browser):
    path = write_trajectory(tmp_path / "t.h5", frames=41)
    page_path = tmp_path / "player.html"
    code, _, err = rbsim("render", path, "-o", page_path, "--fps", "10")
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    assert page.evaluate("window.rbsimPlayer.frameCount") == 21
    fill = hex_rgb(COLOURS["dynamic_fill"])
    background = hex_rgb(COLOURS["background"])
    start = page.evaluate("window.rbsimPlayer.worldToScreen(-3, 2)")
    end = page.evaluate(f"window.rbsimPlayer.worldToScreen({-3 + SPEED * 2}, 2)")
    assert (canvas_rgb(page, *start) == fill).all()
    assert (canvas_rgb(page, *end) == background).all()
    # drag the slider to its end, as a person would: the box is drawn at its last place
    page.locator("#slider").fill("20")
    assert page.evaluate("window.rbsimPlayer.frame()") == 20
    page.wait_for_timeout(100)  # one animation frame to redraw
    assert (canvas_rgb(page, *end) == fill).all()
    assert (canvas_rgb(page, *start) == background).all()
    assert "t = 2.000 s" in page.locator("#clock").inner_text()
    # names on hover
    page.mouse.move(*_page_xy(page, end))
    page.wait_for_timeout(100)
    assert page.locator("#tip").inner_text().startswith("box")
    # play runs the clock forward from the start
    page.locator("#slider").fill("0")
    page.evaluate("window.rbsimPlayer.play()")
    page.wait_for_function("window.rbsimPlayer.frame() > 0", timeout=5000)
    page.evaluate("window.rbsimPlayer.pause()")
    assert errors == []
    page.close()


def _page_xy(page, canvas_xy) -> tuple[float, float]:
    box = page.locator("#canvas").bounding_box()
    return box["x"] + canvas_xy[0], box["y"] + canvas_xy[1]


def test_html_player_overlays_a_second_trajectory_in_its_own_colour(tmp_path, browser):
    main = write_trajectory(tmp_path / "a.h5", frames=21)
    other = write_trajectory(tmp_path / "b.h5", frames=21, box_y=4.0, engine="pymunk")
    page_path = tmp_path / "overlay.html"
    code, _, err = rbsim("render", main, "--overlay", other, "-o", page_path)
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    edge = hex_rgb(COLOURS["overlay_edge"])
    left = page.evaluate("window.rbsimPlayer.worldToScreen(-3.5, 4)")  # the other box's edge
    assert any(
        (np.abs(px.astype(int) - edge) <= 40).all() for px in canvas_rgb(page, *left)
    )  # an antialiased 1.5 px line: a pixel within 40 of each channel of its colour
    assert page.evaluate("window.rbsimPlayer.bodyName(-3, 4)") == "box"
    legend = page.locator("#legend").inner_text()
    assert "a.h5 (rbsim)" in legend and "b.h5 (pymunk)" in legend
    # zoom with the wheel around the box: it gets bigger on screen
    before = page.evaluate("window.rbsimPlayer.worldToScreen(-3.5, 2)[0]")
    centre = page.evaluate("window.rbsimPlayer.worldToScreen(-3, 2)")
    page.mouse.move(*_page_xy(page, centre))
    page.mouse.wheel(0, -400)
    page.wait_for_timeout(100)
    after = page.evaluate("window.rbsimPlayer.worldToScreen(-3.5, 2)[0]")
    assert centre[0] - after > centre[0] - before  # the box's half-width grew on screen
    assert errors == []
    page.close()


def test_html_player_stays_usable_at_1000_bodies_by_600_frames(tmp_path, browser):
    from rbsim.view.player import render_html

    n, frames = 1000, 600
    bodies = BodyTable(
        name=[f"ball[{i}]" for i in range(n)],
        type=["dynamic"] * n,
        mass=np.ones(n),
        moment_of_inertia=np.ones(n),
        center_of_mass=np.zeros((n, 2)),
        shape_body=np.arange(n),
        shape_kind=["circle"] * n,
        shape_radius=np.full(n, 0.4),
        shape_vertex_start=np.arange(n),
        shape_vertex_count=np.ones(n),
        shape_vertices=np.zeros((n, 2)),
    )
    grid = np.stack(np.meshgrid(np.arange(40), np.arange(25)), axis=-1).reshape(-1, 2) * 1.0
    path = tmp_path / "big.h5"
    with TrajectoryWriter(path, bodies=bodies, parameters={}) as w:
        for k in range(frames):
            t = k / 60
            rot = np.tile([np.cos(t), np.sin(t)], (n, 1))
            pos = grid + [0.0, -t]
            w.append(k, t, pos, rot, np.full(n, t), np.zeros((n, 2)), np.zeros(n), {})
    page_path = tmp_path / "big.html"
    result = render_html(path, page_path, fps=60)
    assert result.frames == frames
    # 16 bytes of base64 per body and frame, plus the names, shapes and times
    assert result.size < 16 * n * frames * 1.1
    page, errors = open_page(browser, page_path)
    page.evaluate("window.rbsimPlayer.setFrame(599)")
    t = 599 / 60  # the last ball's centre less 0.2 m along its spoke (drawn dark)
    x, y = 39 - 0.2 * np.cos(t), 24 - t - 0.2 * np.sin(t)
    last = page.evaluate(f"window.rbsimPlayer.worldToScreen({x}, {y})")
    # the balls are 6 px in radius here: the 3 x 3 pixels 3 px from the centre are inside
    assert (canvas_rgb(page, *last) == hex_rgb(COLOURS["dynamic_fill"])).all()
    assert errors == []
    page.close()


def test_an_overlay_of_another_scene_is_warned_of(tmp_path):
    """An overlay whose bodies differ in count or names from the trajectory's is drawn,
    with a warning naming it; the same scene's run (either engine) is not."""
    runs = {}
    for name, bodies in (("a", ["ball"]), ("b", ["crate"]), ("c", ["ball", "crate"])):
        scene = tmp_path / f"{name}.yaml"
        listed = ", ".join(
            f"{{name: {n}, position: [{i}, 1], shape: {{circle: {{radius: 0.2}}}}}}"
            for i, n in enumerate(bodies)
        )
        scene.write_text(f"version: 1\nworld: {{dt: 0.01, steps: 2}}\nbodies: [{listed}]\n")
        runs[name] = tmp_path / f"{name}.h5"
        assert rbsim("run", scene, "-o", runs[name], "-q")[0] == 0
    for other, what in (("b", "its body 0 is 'crate'"), ("c", "it has 2 bodies")):
        code, _out, err = rbsim("render", runs["a"], "--overlay", runs[other], "-q")
        assert code == 0 and err.startswith(f"warning: {runs[other]}: ") and what in err, err
    code, _out, err = rbsim("render", runs["a"], "--overlay", runs["a"], "-q")
    assert (code, err) == (0, "")
