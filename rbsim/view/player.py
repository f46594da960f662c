"""The self-contained HTML player: one file that plays a trajectory on a canvas.

The page (template `rbsim/view/player.html` with the view script of the trajectory's
dimension, player2d.js or player3d.js, package data) draws from the stored numbers,
not from pictures: for each shown frame and body, in 2D x and y (m) and the angle (rad),
in 3D x, y, z (m) and the quaternion (w, x, y, z), as little-endian float32,
base64-encoded (16 bytes per body and frame in 2D, 37 in 3D), plus each body's shapes
once (in 3D as flat faces). Its size therefore grows with frames x bodies, not with
pixels: 1000 bodies x 600 frames make a 2D page of about 10 MB, 100 bodies x 300 frames
a 3D page of about 1.4 MB. No script, font or style is loaded from anywhere else, so it
works offline.
"""

from __future__ import annotations

import base64
import html
import json
import os
from dataclasses import dataclass
from importlib import resources

import numpy as np

from .mesh import (
    AMBIENT,
    FOV,
    LIGHT,
    PITCH,
    YAW,
    body_meshes,
    body_reach3d,
    fit_box_shown,
)
from .render import (
    COLOURS,
    FrameReader,
    Progress,
    RenderError,
    View,
    body_reach,
    check_dimensions,
    contact_normal_length,
    fit_view,
    match_frames,
    no_frames_message,
    sample_frames,
    shape_outline,
    shape_vertices,
)
from .render3d import COLOURS_3D, fit_box, ground_for

__all__ = ["HtmlResult", "render_html"]

TEMPLATE = "player.html"
# The view script pasted into the page, by dimension: the camera, drawing and hit test.
VIEW_SCRIPTS = {2: "player2d.js", 3: "player3d.js"}
# Frames per second above which a page only grows: browsers draw at most 60 per second
# on common screens, and the player shows the latest frame due.
HTML_MAX_FPS = 240.0


@dataclass
class HtmlResult:
    """What render_html wrote: path, frames, bodies (of the main trajectory), bytes."""

    path: str
    frames: int
    bodies: int
    size: int


def _round(values: np.ndarray) -> list[float]:
    """Body-frame coordinates for the page, m, to 1e-6 m (the page draws in float64)."""
    return [round(float(v), 6) for v in np.asarray(values).reshape(-1)]


def _shapes(reader: FrameReader) -> dict[str, list]:
    """The page's shape lists for one trajectory, in body frames (m): polys
    [[body, [x0, y0, x1, y1, ...]], ...], circles [[body, cx, cy, r]], lines
    [[body, ax, ay, bx, by]] (segments of zero radius)."""
    bodies = reader.bodies
    polys: list = []
    circles: list = []
    lines: list = []
    for s, kind in enumerate(bodies.shape_kind):
        b = int(bodies.shape_body[s])
        verts = shape_vertices(bodies, s)
        r = float(bodies.shape_radius[s])
        if kind == "circle":
            circles.append([b, *_round(verts[0]), round(r, 6)])
            continue
        what, outline = shape_outline(kind, verts, r)
        if what == "line":
            lines.append([b, *_round(outline)])
        else:
            polys.append([b, _round(outline)])
    return {"polys": polys, "circles": circles, "lines": lines}


def _frames_b64(reader: FrameReader, idx: np.ndarray, progress: Progress | None) -> str:
    """Frames idx (increasing, distinct) as base64 of float32 (frame, body, pose): in 2D
    [x, y, θ] (12 bytes per body and frame), in 3D [x, y, z, qw, qx, qy, qz] (28)."""
    n = len(reader.bodies)
    out = np.empty((len(idx), n, 3 if reader.dimension == 2 else 7), dtype="<f4")
    done = 0
    for part, pos, rot in reader.batches(idx):
        k = len(part)
        if reader.dimension == 2:
            rot = np.arctan2(rot[..., 1], rot[..., 0])[..., None]
        out[done : done + k] = np.concatenate([pos, rot], axis=2)
        done += k
        if progress is not None:
            progress(done, len(idx))
    return base64.b64encode(out.tobytes()).decode("ascii")


def _track(
    reader: FrameReader,
    idx: np.ndarray,
    overlay: bool,
    progress: Progress | None,
    contacts: bool = True,
) -> dict[str, object]:
    """One trajectory for the page; idx: the track frame shown at each player frame
    (non-decreasing, repeats allowed; only the distinct frames are stored). With
    `contacts` and contact points recorded, also those of the stored frames."""
    uniq, inverse = np.unique(idx, return_inverse=True)
    extra = {"contacts": _contacts_b64(reader, uniq)} if contacts and reader.has_contacts else {}
    return {
        "label": reader.label,
        "overlay": overlay,
        "names": list(reader.bodies.name),
        "types": list(reader.bodies.type),
        **_shapes(reader),
        "frame_index": [int(i) for i in inverse],
        "frames": _frames_b64(reader, uniq, progress),
        **extra,
    }


def _contacts_b64(reader: FrameReader, idx: np.ndarray) -> dict[str, object]:
    """The contact points of frames idx (increasing, distinct) for the page: their count
    per frame, and frame after frame base64 of float32 [x, y, z, nx, ny, nz] (position
    m, unit normal; 24 bytes per point; in 2D [x, y, nx, ny], 16 bytes)."""
    count, pos, normal = reader.contacts(idx)
    rows = np.concatenate([pos, normal], axis=1).astype("<f4")
    return {
        "count": [int(c) for c in count],
        "rows": base64.b64encode(rows.tobytes()).decode("ascii"),
    }


def _track3d(
    reader: FrameReader,
    idx: np.ndarray,
    overlay: bool,
    progress: Progress | None,
    contacts: bool = True,
) -> dict[str, object]:
    """One 3D trajectory for the page: its shapes as flat faces in body frames (points
    m to 1e-6 m, their bodies; each face's point indices, counter-clockwise outside,
    their count, and whether its edges are drawn), and the frames as
    base64 of float32 (frame, body, [x, y, z, qw, qx, qy, qz]) (28 bytes per body and
    frame); idx as for `_track`. With `contacts` and contact points recorded, also
    those of the stored frames (`_contacts_b64`)."""
    uniq, inverse = np.unique(idx, return_inverse=True)
    meshes = body_meshes(reader.bodies)
    extra = {"contacts": _contacts_b64(reader, uniq)} if contacts and reader.has_contacts else {}
    return {
        "label": reader.label,
        "overlay": overlay,
        "names": list(reader.bodies.name),
        "types": list(reader.bodies.type),
        "points": _round(meshes.points),
        "point_body": [int(b) for b in meshes.point_body],
        "faces": [
            int(i) for f, k in zip(meshes.faces, meshes.face_size, strict=True) for i in f[:k]
        ],
        "face_size": [int(k) for k in meshes.face_size],
        "face_outlined": [int(e) for e in meshes.face_outlined],
        "frame_index": [int(i) for i in inverse],
        "frames": _frames_b64(reader, uniq, progress),
        **extra,
    }


def _scene3d(main: FrameReader, pairs: list[tuple[FrameReader, np.ndarray]]) -> dict[str, object]:
    """The 3D page's camera (the box to show whole: lo and hi corners, m; yaw, pitch,
    fov rad), light (a unit vector towards it, world frame) and ambient brightness, colours,
    ground (plane patches and grid lines, world frame, m, flat lists), and the length
    contact normals are drawn with, m."""
    lo, hi = fit_box(pairs)
    ground = ground_for(main, lo, hi)
    shown_lo, shown_hi = fit_box_shown(lo, hi)  # the page fits its distance to its shape
    return {
        "dimension": 3,
        "camera": {
            "box": [float(c) for c in (*shown_lo, *shown_hi)],
            "yaw": YAW,
            "pitch": PITCH,
            "fov": FOV,
        },
        "light": list(LIGHT),
        "ambient": AMBIENT,
        "colours": COLOURS_3D,
        "ground": {"quads": _round(ground.quads), "lines": _round(ground.lines)},
        "contact_length": contact_normal_length(
            body_reach3d(main.bodies), main.bodies.type, lo, hi
        ),
    }


def page_text(data: dict[str, object], title: str, dimension: int = 2) -> str:
    """The player page with `data` (the JSON the page reads), `title` and the view
    script of `dimension` (2 or 3) filled in."""
    files = resources.files(__package__)
    template = files.joinpath(TEMPLATE).read_text(encoding="utf-8")
    view = files.joinpath(VIEW_SCRIPTS[dimension]).read_text(encoding="utf-8")
    # "</" could end the <script> element early (a body named "</script>"): escape it.
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    page = template.replace("{{VIEW}}", view.rstrip("\n"))
    return page.replace("{{TITLE}}", html.escape(title)).replace("{{DATA}}", payload)


def render_html(
    path: str | os.PathLike,
    output: str | os.PathLike,
    *,
    fps: float = 30.0,
    view: View | None = None,
    overlay: str | os.PathLike | None = None,
    start: float | None = None,
    end: float | None = None,
    progress: Progress | None = None,
    contacts: bool = True,
) -> HtmlResult:
    """Write the player page for the trajectory `path` to `output`.

    fps: frames per second of simulated time stored in the page (the page plays in
    real time, at a speed the viewer picks). view: the world rectangle shown first (m);
    default: fitted to the moving bodies. A 3D trajectory gets the 3D view (`view`
    must be None): shaded shapes over the ground, seen by a camera that orbits with the
    mouse, first fitted to the moving bodies. overlay: a second trajectory drawn over the
    first in its own colour, at the frames nearest in time. start, end: s, the part of
    the run to store. progress(done, total) is called as frames are read. contacts: the
    run's recorded contact points (output.contacts) go into the page too, shown
    (as dots with a short line along each normal) until the viewer turns them off.
    Raises RenderError (unreadable input) or ValueError (bad argument).
    """
    if not 0 < fps <= HTML_MAX_FPS:
        raise ValueError(f"frames per second must lie in (0, {HTML_MAX_FPS:g}], got {fps:g}")
    output = os.fspath(output)
    with FrameReader(path) as main:
        idx = sample_frames(main.time, fps, start, end)
        if not len(idx):
            raise RenderError(no_frames_message(main, start, end))
        times = main.time[idx]
        other = FrameReader(overlay) if overlay is not None else None
        try:
            if other is not None and not len(other.time):
                raise RenderError(f"{other.path}: no frames to overlay")
            other_idx = match_frames(other.time, times) if other is not None else None
            check_dimensions(main, other, view)
            pairs = [(main, idx)]
            if other is not None and other_idx is not None:
                pairs.append((other, np.unique(other_idx)))
            if view is None and main.dimension == 2:
                view = fit_view(pairs)
            total = len(idx) + (len(np.unique(other_idx)) if other_idx is not None else 0)

            def step(offset: int) -> Progress | None:
                if progress is None:
                    return None
                return lambda done, _n: progress(offset + done, total)

            track = _track if main.dimension == 2 else _track3d
            tracks = [track(main, idx, False, step(0), contacts)]
            if other is not None and other_idx is not None:
                tracks.append(track(other, other_idx, True, step(len(idx)), contacts))
            data: dict[str, object] = {
                "version": 1,
                "scene": main.scene,
                "time": [float(t) for t in times],
            }
            if main.dimension == 2:
                assert view is not None
                data["view"] = [view.x0, view.y0, view.x1, view.y1]
                data["colours"] = COLOURS
                lo, hi = np.array([view.x0, view.y0]), np.array([view.x1, view.y1])
                reach = body_reach(main.bodies)
                data["contact_length"] = contact_normal_length(reach, main.bodies.type, lo, hi)
            else:
                data.update(_scene3d(main, pairs))
            data["tracks"] = tracks
        finally:
            if other is not None:
                other.close()
        title = f"rbsim: {main.scene}"
        n = len(main.bodies)
    text = page_text(data, title, main.dimension)
    tmp = output + ".part"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, output)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return HtmlResult(output, len(idx), n, len(text.encode("utf-8")))
