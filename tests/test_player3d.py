"""The HTML player's 3D view, in a real headless browser (Debian's chromium driven by
playwright; without them these tests skip): it draws, the mouse orbits and zooms the
camera, the slider moves time, and hovering a body names it. The trajectories are
written directly in the 3D layout of docs/format.md (tests/test_render3d.py), so every body's
place is known."""

from __future__ import annotations

import io

import numpy as np
import pytest

from rbsim.view.player import render_html
from tests.conftest import open_page, rbsim
from tests.test_render3d import (
    BRICK,
    BRICK_Y,
    SPEED,
    box_shape,
    brick_scene,
    quat_about,
    write_trajectory3d,
)

PIL = pytest.importorskip("PIL", reason="the plot extra: pip install -e '.[plot]'")
from PIL import Image  # noqa: E402

BACKGROUND = (255, 255, 255)
BRICK_TOP = (-3.0, BRICK_Y + BRICK[1] / 2, 0.0)  # m, the brick's top centre at t = 0


def canvas_image(page) -> np.ndarray:
    """The whole canvas as (H,W,3) int RGB (a screenshot of its element)."""
    png = page.locator("#canvas").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def page_xy(page, canvas_xy) -> tuple[float, float]:
    """Page coordinates of CSS pixel canvas_xy from the canvas's top-left corner."""
    box = page.locator("#canvas").bounding_box()
    return box["x"] + canvas_xy[0], box["y"] + canvas_xy[1]


def screen(page, point) -> list[float]:
    """The page's own projection of world point (m) to canvas CSS pixels."""
    return page.evaluate("p => window.rbsimPlayer.worldToScreen(p[0], p[1], p[2])", list(point))


@pytest.fixture
def brick_page(tmp_path, browser):
    path = brick_scene(tmp_path / "b.h5", frames=41)
    page_path = tmp_path / "b.html"
    code, out, err = rbsim("render", path, "-o", page_path, "--fps", "10")
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    page.wait_for_timeout(50)  # the first frame drawn
    yield page, errors
    page.close()


def test_player3d_draws_the_shaded_bodies_without_errors(brick_page):
    page, errors = brick_page
    assert page.evaluate("window.rbsimPlayer.dimension") == 3
    assert page.evaluate("window.rbsimPlayer.frameCount") == 21
    image = canvas_image(page)
    drawn = (image != BACKGROUND).any(axis=2)
    assert drawn.mean() > 0.05  # bodies and the ground grid, not a blank canvas
    # the brick's top face at its centre: a blue (dynamic) face, not the ground
    col, row = (int(c) for c in screen(page, BRICK_TOP))
    r, g, b = image[row, col]
    assert b > r + 40 and b > g + 10, (r, g, b)  # the dynamic colour #6699cc, shaded
    assert page.evaluate(f"window.rbsimPlayer.bodyAt({col}, {row})") == "brick"
    assert errors == []


def test_player3d_dragging_orbits_the_camera_and_the_wheel_zooms(brick_page):
    page, errors = brick_page
    before = canvas_image(page)
    yaw0 = page.evaluate("window.rbsimPlayer.camera().yaw")
    centre = page_xy(page, (400, 300))
    page.mouse.move(*centre)
    page.mouse.down()
    page.mouse.move(centre[0] + 120, centre[1] + 40, steps=4)
    page.mouse.up()
    page.wait_for_timeout(100)  # one animation frame to redraw
    after = canvas_image(page)
    assert page.evaluate("window.rbsimPlayer.camera().yaw") != yaw0
    assert (before != after).any(axis=2).mean() > 0.05  # a different picture
    # the brick's top, projected by the page itself, is still the brick from there
    col, row = (int(c) for c in screen(page, BRICK_TOP))
    assert page.evaluate(f"window.rbsimPlayer.bodyAt({col}, {row})") == "brick"
    # shift-drag pans: the target moves, the orbit stays
    target0 = page.evaluate("window.rbsimPlayer.camera().target")
    yaw1 = page.evaluate("window.rbsimPlayer.camera().yaw")
    page.keyboard.down("Shift")
    page.mouse.move(*centre)
    page.mouse.down()
    page.mouse.move(centre[0] - 50, centre[1], steps=2)
    page.mouse.up()
    page.keyboard.up("Shift")
    assert page.evaluate("window.rbsimPlayer.camera().target") != target0
    assert page.evaluate("window.rbsimPlayer.camera().yaw") == yaw1
    # zoom in with the wheel: the camera comes nearer, the brick grows on screen
    corner = (BRICK_TOP[0] + BRICK[0] / 2, BRICK_TOP[1], BRICK_TOP[2])
    width0 = abs(screen(page, corner)[0] - screen(page, BRICK_TOP)[0])
    d0 = page.evaluate("window.rbsimPlayer.camera().distance")
    page.mouse.wheel(0, -400)
    page.wait_for_timeout(100)
    assert page.evaluate("window.rbsimPlayer.camera().distance") < d0
    assert abs(screen(page, corner)[0] - screen(page, BRICK_TOP)[0]) > width0
    # close in, the ground patch reaches behind the camera: it is clipped, still drawn
    page.evaluate("window.rbsimPlayer.setCamera({distance: 2, pitch: 0.3})")
    fill = page.evaluate("window.rbsimPlayer.colours.ground_fill")
    ground = np.array([int(fill[i : i + 2], 16) for i in (1, 3, 5)])
    assert (canvas_image(page) == ground).all(axis=2).mean() > 0.05
    assert errors == []


def test_player3d_slider_moves_time_and_hover_names_the_body(brick_page):
    page, errors = brick_page
    first = canvas_image(page)
    start = screen(page, BRICK_TOP)
    end = screen(page, (BRICK_TOP[0] + SPEED * 2.0, BRICK_TOP[1], BRICK_TOP[2]))
    assert page.evaluate(f"window.rbsimPlayer.bodyAt({end[0]}, {end[1]})") != "brick"
    page.locator("#slider").fill("20")  # as a person drags it: to the end, t = 2 s
    assert page.evaluate("window.rbsimPlayer.frame()") == 20
    page.wait_for_timeout(100)
    last = canvas_image(page)
    assert (first != last).any(axis=2).mean() > 0.005  # the brick moved (and turned)
    assert "t = 2.000 s" in page.locator("#clock").inner_text()
    assert page.evaluate(f"window.rbsimPlayer.bodyAt({start[0]}, {start[1]})") != "brick"
    # hover where the brick is now: the tip names it
    page.mouse.move(*page_xy(page, end))
    page.wait_for_timeout(100)
    tip = page.locator("#tip").inner_text()
    assert tip.startswith("brick  (dynamic)"), tip
    assert "x 1.000 m" in tip  # the brick's origin at t = 2 s: -3 + SPEED * 2
    # play runs the clock forward from the start
    page.locator("#slider").fill("0")
    page.evaluate("window.rbsimPlayer.play()")
    page.wait_for_function("window.rbsimPlayer.frame() > 0", timeout=5000)
    page.evaluate("window.rbsimPlayer.pause()")
    assert errors == []


def test_player3d_shows_a_sphere_turn(tmp_path, browser):
    """A sphere spinning in place about z: its facets move, so the picture changes
    (a sphere drawn as a disc would look the same at every frame)."""
    time = np.arange(5) * 0.1
    q = np.array([[quat_about((0, 0, 1), 0.3 * k)] for k in range(5)])
    write_trajectory3d(
        tmp_path / "ball.h5", ["ball"], ["dynamic"],
        [{"body": 0, "kind": "sphere", "vertices": [[0, 0, 0]], "radius": 1.0}],
        time, np.zeros((5, 1, 3)), q,
    )  # fmt: skip
    render_html(tmp_path / "ball.h5", tmp_path / "ball.html", fps=10)
    page, errors = open_page(browser, tmp_path / "ball.html")
    page.wait_for_timeout(50)
    a = canvas_image(page)
    page.evaluate("window.rbsimPlayer.setFrame(1)")
    b = canvas_image(page)
    centre = [int(c) for c in screen(page, (0, 0, 0))]
    patch = (slice(centre[1] - 30, centre[1] + 30), slice(centre[0] - 30, centre[0] + 30))
    assert (a[patch] != BACKGROUND).any(axis=2).all()  # the sphere covers its centre
    assert (a[patch] != b[patch]).any(axis=2).mean() > 0.05  # and its shading moved
    assert errors == []
    page.close()


def test_player3d_page_of_100_bodies_by_300_frames_is_compact_and_plays(tmp_path, browser):
    n, frames = 100, 300
    corners, faces = box_shape((0.5, 0.5, 0.5))
    shapes = [
        {"body": i, "kind": "box", "vertices": corners, "faces": faces} if i % 2 else
        {"body": i, "kind": "sphere", "vertices": [[0, 0, 0]], "radius": 0.3}
        for i in range(n)
    ]  # fmt: skip
    time = np.arange(frames) / 60
    grid = np.stack(np.meshgrid(np.arange(10), np.arange(10)), -1).reshape(-1, 2) * 1.2
    position = np.zeros((frames, n, 3))
    position[:, :, 0] = grid[:, 0]
    position[:, :, 2] = grid[:, 1]
    position[:, :, 1] = 5 - 0.5 * 9.81 * time[:, None] ** 2
    q = np.array([quat_about((1, 1, 0), 2 * t) for t in time])
    orientation = np.repeat(q[:, None, :], n, axis=1)
    path = write_trajectory3d(
        tmp_path / "many.h5", [f"b[{i}]" for i in range(n)], ["dynamic"] * n, shapes,
        time, position, orientation,
    )  # fmt: skip
    result = render_html(path, tmp_path / "many.html", fps=60)
    assert result.frames == frames
    # 28 bytes per body and frame (7 float32), 4/3 of it in base64, and the meshes once
    assert result.size < 28 * 4 / 3 * n * frames * 1.3
    page, errors = open_page(browser, tmp_path / "many.html")
    page.evaluate("window.rbsimPlayer.setFrame(299)")
    # the box nearest the camera (at the grid's far corner in x and z), at its centre
    col, row = (int(c) for c in screen(page, position[299, 99]))
    assert page.evaluate(f"window.rbsimPlayer.bodyAt({col}, {row})") == "b[99]"
    page.evaluate("window.rbsimPlayer.setFrame(0); window.rbsimPlayer.play()")
    page.wait_for_function("window.rbsimPlayer.frame() > 10", timeout=5000)
    page.evaluate("window.rbsimPlayer.pause()")
    assert errors == []
    page.close()


def test_player3d_of_a_real_run_names_each_body_where_the_file_puts_it(tmp_path, browser):
    from rbsim.io.trajectory import load_trajectory
    from tests.test_render3d import run_every_kind

    path = run_every_kind(tmp_path)
    traj = load_trajectory(path)
    page_path = tmp_path / "every.html"
    code, _, err = rbsim("render", path, "-o", page_path, "--fps", "20")
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    last = page.evaluate("window.rbsimPlayer.frameCount") - 1
    page.evaluate(f"window.rbsimPlayer.setFrame({last})")
    for name in ("crate", "ball", "rod"):  # each body's origin is inside its shape
        col, row = screen(page, traj.position[-1, traj.body(name)])
        assert page.evaluate(f"window.rbsimPlayer.bodyAt({col}, {row})") == name
    assert errors == []
    page.close()


CONTACT_RED = (0xCC, 0x00, 0x00)  # COLOURS["contact"]


def red_pixels(image: np.ndarray) -> np.ndarray:
    """Where the canvas shows the contact colour (antialiased edges aside)."""
    return (np.abs(image - np.array(CONTACT_RED)) <= 12).all(axis=2)


def test_player3d_shows_recorded_contact_points_and_toggles_them(tmp_path, browser):
    from rbsim.io.trajectory import load_trajectory
    from tests.test_contacts_output import BOX_ON_PLANE

    scene = tmp_path / "box.yaml"
    scene.write_text(BOX_ON_PLANE)
    run, page_path = tmp_path / "box.h5", tmp_path / "box.html"
    assert rbsim("run", scene, "-o", run, "-q")[0] == 0
    code, _, err = rbsim("render", run, "-o", page_path, "--fps", "20")
    assert code == 0, err
    contacts = load_trajectory(run).contacts
    page, errors = open_page(browser, page_path)
    player = "window.rbsimPlayer"
    assert page.evaluate(f"{player}.contactsRecorded") is True
    assert page.evaluate(f"{player}.contactsShown()") is True  # on when recorded
    assert page.locator("#contacts-toggle").is_visible()
    # frame 0 (step 0) has none; the last frame the box's four corners on the plane
    page.evaluate(f"{player}.setFrame(0)")
    assert page.evaluate(f"{player}.contactsDrawn()[0].dots") == []
    assert not red_pixels(canvas_image(page)).any()
    last = page.evaluate(f"{player}.frameCount") - 1
    page.evaluate(f"{player}.setFrame({last})")
    drawn = page.evaluate(f"{player}.contactsDrawn()[0]")
    rows = contacts.frame(len(contacts.count) - 1)
    expected = [screen(page, p) for p in contacts.position[rows]]
    assert len(drawn["dots"]) == 4 and len(drawn["normals"]) == 4
    # each dot where the page projects its recorded point (float32 in the page: 1e-7 m)
    assert np.allclose(sorted(drawn["dots"]), sorted(expected), atol=1e-3)
    # the normals point up: their tips are higher on the screen than the dots
    assert all(n[3] < n[1] for n in drawn["normals"])
    image = canvas_image(page)
    for x, y in drawn["dots"]:  # a red dot at each (3 px radius about its centre)
        patch = red_pixels(image[int(y) - 2 : int(y) + 3, int(x) - 2 : int(x) + 3])
        assert patch.mean() > 0.5, (x, y)
    # the toggle hides them, the key c shows them again
    page.locator("#contacts").click()
    assert page.evaluate(f"{player}.contactsShown()") is False
    page.wait_for_timeout(100)  # one animation frame to redraw
    assert not red_pixels(canvas_image(page)).any()
    assert page.evaluate(f"{player}.contactsDrawn()[0].dots") == []
    page.keyboard.press("c")  # the checkbox still has the focus: it passes keys on
    page.wait_for_timeout(100)
    assert page.evaluate(f"{player}.contactsShown()") is True
    assert red_pixels(canvas_image(page)).sum() > 20
    assert errors == []
    page.close()


def test_player3d_has_no_contact_toggle_without_contacts(brick_page):
    page, errors = brick_page
    assert page.evaluate("window.rbsimPlayer.contactsRecorded") is False
    assert not page.locator("#contacts-toggle").is_visible()
    assert errors == []
