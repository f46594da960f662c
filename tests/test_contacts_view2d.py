"""Contact points of a 2D run (output.contacts: points) in its pictures: the GIF draws
a dot at each point with a line along its normal, and the HTML player the same, with
its toggle (the 3D pictures' tests are in test_render3d.py and test_player3d.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rbsim.io.trajectory import load_trajectory
from rbsim.view.render import COLOURS, render_gif
from tests.conftest import open_page, rbsim
from tests.test_contacts_output import BOX_ON_SEGMENT

PIL = pytest.importorskip("PIL", reason="the plot extra: pip install -e '.[plot]'")
from PIL import Image  # noqa: E402

RED = np.array([int(COLOURS["contact"][i : i + 2], 16) for i in (1, 3, 5)])


@pytest.fixture
def box_run(tmp_path):
    scene = tmp_path / "box.yaml"
    scene.write_text(BOX_ON_SEGMENT)
    run = tmp_path / "box.h5"
    assert rbsim("run", scene, "-o", run, "-q")[0] == 0
    return run


def gif_frames(path) -> list[np.ndarray]:
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB")).astype(int))
    return out


def test_gif_2d_draws_the_contact_points_and_their_normals(tmp_path, box_run):
    contacts = load_trajectory(box_run).contacts
    size = (400, 300)
    result = render_gif(box_run, tmp_path / "box.gif", fps=10, size=size)
    plain = render_gif(box_run, tmp_path / "plain.gif", fps=10, size=size, contacts=False)
    frames, without = gif_frames(result.path), gif_frames(plain.path)
    view = result.view
    assert view is not None

    def pixel(x: float, y: float) -> tuple[int, int]:
        col = (x - view.x0) / (view.x1 - view.x0) * size[0]
        row = (view.y1 - y) / (view.y1 - view.y0) * size[1]
        return int(col), int(row)

    red = [(f == RED).all(axis=2) for f in frames]
    assert not red[0].any()  # step 0: no contact yet
    rows = contacts.frame(len(contacts.count) - 1)
    for x, y in contacts.position[rows]:
        for point in ((x, y), (x, y + 0.15)):  # the dot, and its normal straight up
            col, row = pixel(*point)
            assert red[-1][row - 1 : row + 2, col - 1 : col + 2].any(), (point, col, row)
    assert not any((f == RED).all(axis=2).any() for f in without)


def test_player2d_shows_the_contact_points_and_toggles_them(tmp_path, box_run, browser):
    contacts = load_trajectory(box_run).contacts
    page_path = tmp_path / "box.html"
    code, _, err = rbsim("render", box_run, "-o", page_path, "--fps", "20")
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    player = "window.rbsimPlayer"
    assert page.evaluate(f"{player}.contactsShown()") is True
    last = page.evaluate(f"{player}.frameCount") - 1
    page.evaluate(f"{player}.setFrame({last})")
    drawn = page.evaluate(f"{player}.contactsDrawn()[0]")
    rows = contacts.frame(len(contacts.count) - 1)
    expected = [
        page.evaluate(f"{player}.worldToScreen({x}, {y})") for x, y in contacts.position[rows]
    ]
    # each dot where the page maps its recorded point (float32 in the page: 1e-7 m)
    assert np.allclose(sorted(drawn["dots"]), sorted(expected), atol=1e-3)
    assert len(drawn["normals"]) == 2 and all(n[3] < n[1] for n in drawn["normals"])  # up
    page.evaluate(f"{player}.setContactsShown(false)")
    assert page.evaluate(f"{player}.contactsDrawn()[0].dots") == []
    assert errors == []
    page.close()


def test_render_without_contacts_has_no_toggle(tmp_path, box_run, browser):
    page_path = tmp_path / "plain.html"
    code, _, err = rbsim("render", box_run, "-o", page_path, "--no-contacts")
    assert code == 0, err
    page, errors = open_page(browser, page_path)
    assert page.evaluate("window.rbsimPlayer.contactsRecorded") is False
    assert not page.locator("#contacts-toggle").is_visible()
    assert errors == []
    page.close()
