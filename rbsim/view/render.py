"""Play a trajectory back: frames thinned by time, shapes in world coordinates, and the
GIF writer (matplotlib draws, Pillow encodes; no external programs).

The reading side (`FrameReader`, `sample_frames`, `fit_view`) is shared with the HTML
player (`rbsim.player`): both read only the frames they show, in batches, and only the
series they draw (position and orientation), never the whole file.

Units: lengths m, times s, angles rad, image sizes pixels.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING

import numpy as np

from ..io.trajectory import (
    DAMAGED,
    READ_ERRORS,
    BodyTable,
    check_rbsim,
    frame_count,
    open_for_reading,
    read_body_table,
    read_parameters,
    scene_name,
    unreadable,
)
from .mesh import Camera

if TYPE_CHECKING:  # matplotlib is optional (the plot extra): types only
    from matplotlib.axes import Axes
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PathCollection
    from matplotlib.text import Text

__all__ = [
    "FrameReader",
    "RenderError",
    "View",
    "fit_view",
    "render_gif",
    "sample_frames",
    "match_frames",
]

Progress = Callable[[int, int], None]

# Frames read from the file at once (bounds memory: BATCH x bodies x 32 bytes).
BATCH_FRAMES = 64
# Viewers treat GIF delays under 2/100 s as 1/10 s, so a GIF plays at most 50 frames/s.
GIF_MAX_FPS = 50.0
# Margin around the fitted bodies, as a fraction of the larger side of their box.
VIEW_MARGIN = 0.08
# Smallest side of a fitted view, m, so that one small still body is not blown up.
VIEW_MIN_SIDE = 2.0
# Sides of the polygon that stands for a circle or a capsule's round end (per full turn).
CIRCLE_SIDES = 32

# Colours (all on the 6x6x6 "web-safe" cube of the GIF palette, so they stay exact).
COLOURS = {
    "background": "#ffffff",
    "dynamic_fill": "#6699cc",
    "dynamic_edge": "#336699",
    "static_fill": "#999999",
    "static_edge": "#666666",
    "kinematic_fill": "#99cc99",
    "kinematic_edge": "#336633",
    "overlay_edge": "#ff6600",
    "text": "#000000",
    "contact": "#cc0000",  # contact points (output.contacts): a red no body has
}
# Contact points in the GIFs: the dot's diameter and the normal's line width, pixels.
CONTACT_DOT_PX = 4.0
CONTACT_LINE_PX = 1.5


class RenderError(Exception):
    """A trajectory that cannot be rendered (not HDF5, not rbsim's layout, no frames),
    or an output that cannot be written. The message names the file."""


# ---------------------------------------------------------------------------------------
# Reading only the frames shown
# ---------------------------------------------------------------------------------------


class FrameReader:
    """An open trajectory file that reads frames on demand.

    path: an rbsim trajectory (either engine, either dimension). Attributes: dimension
    (2 or 3), bodies (static data, of that dimension), time (T,) s
    and step (T,) of the frames present, engine ("rbsim" / "pymunk" / ...), scene
    (scene name), status. Use as a context manager; `read(idx)` returns the body
    origins (k,N,D) m and orientations of frames idx: (k,N,2) = (cos θ, sin θ) in 2D,
    (k,N,4) = (w, x, y, z) in 3D. has_contacts: the run recorded contact points
    (output.contacts), which `contacts(idx)` reads.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = os.fspath(path)
        try:
            self._file = open_for_reading(self.path)
        except OSError as err:
            raise RenderError(str(unreadable(self.path, err))) from None
        try:
            f = self._file
            check_rbsim(f, self.path)
            box = f.get("particles/bodies/box")
            # 2 or 3: /particles/bodies/box's `dimension` (files without it are 2D)
            self.dimension = int(box.attrs.get("dimension", 2)) if box is not None else 2
            if self.dimension not in (2, 3):
                raise ValueError(f"dimension {self.dimension}")
            self.bodies: BodyTable = read_body_table(f["particles/bodies"])
            # static bodies stored once (output.bodies) are drawn too, after the others
            self._fixed: tuple[np.ndarray, np.ndarray] | None = None
            if "particles/static" in f:
                fixed = f["particles/static"]
                self._moving = len(self.bodies)
                self.bodies = self.bodies.joined(read_body_table(fixed))
                self._fixed = (fixed["position"][()], fixed["orientation"][()])
            params = read_parameters(f)
            self.engine = params.get("engine", "unknown")
            self.status = params.get("status", "unknown")
            self.scene = scene_name(params, self.path)
            t = frame_count(f, closed=self.status != "running")
            if t:
                self.time = np.asarray(f["particles/bodies/position/time"][:t], dtype=float)
                self.step = np.asarray(f["particles/bodies/position/step"][:t], dtype=np.int64)
                self._position = f["particles/bodies/position/value"]
                self._orientation = f["particles/bodies/orientation/value"]
            else:
                self.time = np.zeros(0)
                self.step = np.zeros(0, dtype=np.int64)
            self.has_contacts = "contacts/start" in f
            if self.has_contacts:
                self._contact_start = f["contacts/start/value"][:t]
                self._contact_count = f["contacts/count/value"][:t]
        except READ_ERRORS as err:
            self._file.close()
            raise RenderError(str(unreadable(self.path, err))) from None
        if self._fixed is not None and not all(np.isfinite(a).all() for a in self._fixed):
            self._file.close()
            raise RenderError(f"{self.path}: the static bodies' poses are not finite (damaged)")
        if len(self.time) > 1 and np.any(np.diff(self.time) <= 0):
            self._file.close()
            raise RenderError(f"{self.path}: frame times do not increase")

    def __enter__(self) -> FrameReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    @property
    def label(self) -> str:
        """A short name for legends: the file name and its engine."""
        return f"{os.path.basename(self.path)} ({self.engine})"

    def read(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body origins (k,N,D) m and orientations (k,N,2) (cos θ, sin θ) in 2D,
        (k,N,4) (w, x, y, z) in 3D, of the frames idx (increasing indices into
        `time`). A dense run of indices is read as one slice; a sparse one frame by
        frame, so that nothing else is read."""
        idx = np.asarray(idx, dtype=np.int64)
        n = len(self.bodies)
        if len(idx) == 0 or n == 0:
            d = self.dimension
            return np.zeros((len(idx), n, d)), np.zeros((len(idx), n, 2 if d == 2 else 4))
        if self._fixed is not None:
            pos, rot = self._read(idx)
            k = len(idx)
            fixed_pos = np.broadcast_to(self._fixed[0], (k, *self._fixed[0].shape))
            fixed_rot = np.broadcast_to(self._fixed[1], (k, *self._fixed[1].shape))
            return np.concatenate([pos, fixed_pos], 1), np.concatenate([rot, fixed_rot], 1)
        return self._read(idx)

    def contacts(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The contact points of the frames idx (increasing indices into `time`): their
        number per frame (k,), and, frame after frame, their world positions (K,D) m and
        unit normals (K,D) (from the first body towards the second). None recorded:
        no points."""
        idx = np.asarray(idx, dtype=np.int64)
        d = self.dimension
        if not self.has_contacts or not len(idx):
            return np.zeros(len(idx), np.int64), np.zeros((0, d)), np.zeros((0, d))
        try:
            return self._read_contacts(idx)
        except (OSError, KeyError, ValueError, *DAMAGED) as err:
            raise RenderError(f"{self.path}: cannot read contact points: {err}") from None

    def _read_contacts(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        start, count = self._contact_start[idx], self._contact_count[idx]
        g = self._file["contacts"]
        lo, hi = int(start[0]), int(start[-1] + count[-1])
        if hi - lo <= 2 * int(count.sum()) + 64:  # dense: one slice, then pick
            rows = np.concatenate([np.arange(a, a + c) for a, c in zip(start, count, strict=True)])
            pos = g["position"][lo:hi][rows - lo]
            normal = g["normal"][lo:hi][rows - lo]
        else:
            pos = np.concatenate(
                [g["position"][a : a + c] for a, c in zip(start, count, strict=True)]
            )
            normal = np.concatenate(
                [g["normal"][a : a + c] for a, c in zip(start, count, strict=True)]
            )
        return count.astype(np.int64), np.asarray(pos, float), np.asarray(normal, float)

    def _read(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        try:
            pos, rot = self._read_frames(idx)
        except (OSError, KeyError, ValueError, *DAMAGED) as err:
            raise RenderError(f"{self.path}: cannot read frames: {err}") from None
        if not (np.isfinite(pos).all() and np.isfinite(rot).all()):
            # rbsim writes finite frames only (a non-finite state fails the run first)
            raise RenderError(f"{self.path}: a frame holds non-finite values (damaged)")
        return pos, rot

    def _read_frames(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = int(idx[0]), int(idx[-1]) + 1
        if hi - lo <= 2 * len(idx):  # dense: one slice, then pick
            pos = self._position[lo:hi][idx - lo]
            rot = self._orientation[lo:hi][idx - lo]
        else:
            pos = np.stack([self._position[i] for i in idx])
            rot = np.stack([self._orientation[i] for i in idx])
        return np.asarray(pos, dtype=float), np.asarray(rot, dtype=float)

    def batches(
        self, idx: np.ndarray, size: int = BATCH_FRAMES
    ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(frame indices, origins, orientations) for idx in batches of `size` frames."""
        for lo in range(0, len(idx), size):
            part = idx[lo : lo + size]
            pos, rot = self.read(part)
            yield part, pos, rot


def sample_frames(
    time: np.ndarray, fps: float, start: float | None = None, end: float | None = None
) -> np.ndarray:
    """Indices of the stored frames to show at `fps` frames per second of simulated
    time: for each time t0 + k / fps in [start, end] (s; default the whole run), the
    stored frame nearest in time, each frame at most once. Increasing; empty when no
    frame lies in [start, end]."""
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    time = np.asarray(time, dtype=float)
    lo = 0 if start is None else int(np.searchsorted(time, start, side="left"))
    hi = len(time) if end is None else int(np.searchsorted(time, end, side="right"))
    if hi <= lo:
        return np.zeros(0, dtype=np.int64)
    t0, t1 = time[lo], time[hi - 1]
    # 1e-9 frames of slack: t1 - t0 = 5 s at 30 fps gives 151 frames despite rounding
    count = int(math.floor((t1 - t0) * fps + 1e-9)) + 1
    return match_frames(time[lo:hi], t0 + np.arange(count) / fps, unique=True) + lo


def match_frames(time: np.ndarray, targets: np.ndarray, unique: bool = False) -> np.ndarray:
    """For each target time (s), the index of the frame of `time` (increasing, s)
    nearest to it; targets outside the run get its first or last frame. With
    unique=True each frame appears once (the result is then possibly shorter)."""
    time = np.asarray(time, dtype=float)
    targets = np.asarray(targets, dtype=float)
    right = np.clip(np.searchsorted(time, targets), 1, max(len(time) - 1, 1))
    left = right - 1
    if len(time) == 1:
        return np.zeros(len(targets), dtype=np.int64)
    nearer_left = np.abs(targets - time[left]) <= np.abs(time[right] - targets)
    idx = np.where(nearer_left, left, right).astype(np.int64)
    return np.unique(idx) if unique else idx


# ---------------------------------------------------------------------------------------
# Shapes and the camera
# ---------------------------------------------------------------------------------------


def body_reach(bodies: BodyTable) -> np.ndarray:
    """(N,) m: the largest distance from each body's origin to a point of its shapes
    (0 for a body without shapes); the body stays within this radius of its origin
    whatever its angle."""
    reach = np.zeros(len(bodies))
    for s in range(len(bodies.shape_kind)):
        verts = shape_vertices(bodies, s)
        if len(verts):
            r = float(np.max(np.hypot(verts[:, 0], verts[:, 1]))) + bodies.shape_radius[s]
            b = bodies.shape_body[s]
            reach[b] = max(reach[b], r)
    return reach


def contact_normal_length(
    reach: np.ndarray, types: list[str], lo: np.ndarray, hi: np.ndarray
) -> float:
    """m: how long the pictures draw a contact point's normal: half the median reach
    (body_reach, body_reach3d) of the moving bodies, short beside a body; else 5% of the
    diagonal of the region [lo, hi] shown."""
    moving = reach[(np.array(types, dtype=object) != "static") & (reach > 0)]
    if len(moving):
        return 0.5 * float(np.median(moving))
    return 0.05 * float(np.linalg.norm(np.asarray(hi, float) - np.asarray(lo, float)))


class FrameContacts:
    """The contact points of frames idx of `reader` (FrameReader.contacts), handed out
    frame by frame in that order: `next()` gives the next frame's positions (k,D) m and
    unit normals (k,D)."""

    def __init__(self, reader: FrameReader, idx: np.ndarray) -> None:
        counts, self.position, self.normal = reader.contacts(idx)
        self.ends = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.k = 0

    def next(self) -> tuple[np.ndarray, np.ndarray]:
        rows = slice(int(self.ends[self.k]), int(self.ends[self.k + 1]))
        self.k += 1
        return self.position[rows], self.normal[rows]


def contact_artists(ax: Axes, dpi: float) -> tuple[LineCollection, PathCollection]:
    """The GIF's contact artists on `ax`, over everything: the normals' lines and the
    dots (set their segments and offsets per frame)."""
    from matplotlib.collections import LineCollection

    colour = COLOURS["contact"]
    normals = LineCollection([], colors=colour, linewidths=CONTACT_LINE_PX, zorder=4)
    ax.add_collection(normals)
    side = CONTACT_DOT_PX * 72.0 / dpi  # a marker's size is its area in points²
    dots = ax.scatter([], [], s=side * side, c=colour, marker="o", linewidths=0, zorder=5)
    return normals, dots


@dataclass(frozen=True)
class View:
    """The part of the world shown, m: x0 < x1 (left, right), y0 < y1 (bottom, top)."""

    x0: float
    y0: float
    x1: float
    y1: float

    def with_aspect(self, width: int, height: int) -> View:
        """The smallest view containing this one, centred on it, whose sides have the
        ratio width : height (pixels), so that a metre is as wide as it is high."""
        w, h = self.x1 - self.x0, self.y1 - self.y0
        cx, cy = (self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2
        ratio = width / height
        if w / h < ratio:
            w = h * ratio
        else:
            h = w / ratio
        return View(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)


def fit_view(readers: list[tuple[FrameReader, np.ndarray]]) -> View:
    """A view holding every moving (dynamic or kinematic) body of every (reader, frame
    indices) pair at every one of those frames, with a margin; the static world is
    fitted only when nothing moves. Each body counts as a disc of its reach around its
    origin, so the view does not depend on angles. At least VIEW_MIN_SIDE m a side."""
    lo = np.array([np.inf, np.inf])
    hi = -lo
    for moving_only in (True, False):
        for reader, idx in readers:
            reach = body_reach(reader.bodies)
            keep = np.array([t != "static" or not moving_only for t in reader.bodies.type])
            if not keep.any() or len(idx) == 0:
                continue
            # static bodies do not move: their first frame is enough
            frames = idx if moving_only else idx[:1]
            for _part, pos, _rot in reader.batches(frames):
                p = pos[:, keep]
                r = reach[keep][None, :, None]
                finite = np.isfinite(p).all(axis=2)
                if finite.any():
                    lo = np.minimum(lo, np.min(np.where(finite[..., None], p - r, np.inf), (0, 1)))
                    hi = np.maximum(hi, np.max(np.where(finite[..., None], p + r, -np.inf), (0, 1)))
        if np.all(np.isfinite(lo)):
            break
    if not np.all(np.isfinite(lo)):
        lo, hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    side = max(float(np.max(hi - lo)), VIEW_MIN_SIDE)
    margin = VIEW_MARGIN * side
    centre = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, VIEW_MIN_SIDE / 2) + margin
    return View(
        float(centre[0] - half[0]),
        float(centre[1] - half[1]),
        float(centre[0] + half[0]),
        float(centre[1] + half[1]),
    )


@dataclass
class Outlines:
    """Every shape of N bodies as body-frame outlines, ready to be placed per frame.

    polygons: list of (k,2) m outlines (boxes, polygons, circles and capsules as
    polygons of CIRCLE_SIDES per turn); polygon_body: (P,) body of each;
    lines: (L,2,2) m segments of zero radius; line_body: (L,);
    spokes: (C,2,2) m, a radius of each circle (centre to rim along the body's x axis),
    drawn so that rotation shows; spoke_body: (C,).
    """

    polygons: list[np.ndarray]
    polygon_body: np.ndarray
    lines: np.ndarray
    line_body: np.ndarray
    spokes: np.ndarray
    spoke_body: np.ndarray


def _arc(centre: np.ndarray, r: float, a0: float, a1: float) -> np.ndarray:
    n = max(2, int(math.ceil(CIRCLE_SIDES * (a1 - a0) / (2 * math.pi))) + 1)
    a = np.linspace(a0, a1, n)
    return centre + r * np.stack([np.cos(a), np.sin(a)], axis=1)


def shape_outline(kind: str, verts: np.ndarray, radius: float) -> tuple[str, np.ndarray]:
    """One shape's outline in its body's frame (m): ("polygon", (k,2) corners), for
    boxes, polygons, circles and capsules (round parts as CIRCLE_SIDES-gons per turn),
    or ("line", (2,2)) for a segment of zero radius. verts: the shape's rows of the body
    table (circle: centre; segment: a, b; box, polygon: corners); radius: m."""
    r = float(radius)
    if kind == "circle":
        return "polygon", _arc(verts[0], r, 0.0, 2 * math.pi)[:-1]
    if kind == "segment":
        a, e = verts[0], verts[1]
        d = e - a
        if r <= 0:
            return "line", np.array([a, e], dtype=float)
        if not np.any(d):  # a point with a radius: a circle
            return "polygon", _arc(a, r, 0.0, 2 * math.pi)[:-1]
        phi = math.atan2(d[1], d[0])
        cap_b = _arc(e, r, phi - math.pi / 2, phi + math.pi / 2)
        cap_a = _arc(a, r, phi + math.pi / 2, phi + 3 * math.pi / 2)
        return "polygon", np.concatenate([cap_b, cap_a])
    return "polygon", np.array(verts, dtype=float)  # box, polygon: corners, CCW


def shape_vertices(bodies: BodyTable, s: int) -> np.ndarray:
    """The rows of bodies.shape_vertices that belong to shape s, (k,2) m."""
    start = bodies.shape_vertex_start[s]
    return bodies.shape_vertices[start : start + bodies.shape_vertex_count[s]]


def body_outlines(bodies: BodyTable) -> Outlines:
    """The outlines of every shape of `bodies`, in each body's frame (m)."""
    polygons: list[np.ndarray] = []
    polygon_body: list[int] = []
    lines: list[np.ndarray] = []
    line_body: list[int] = []
    spokes: list[np.ndarray] = []
    spoke_body: list[int] = []
    for s, kind in enumerate(bodies.shape_kind):
        b = int(bodies.shape_body[s])
        verts = shape_vertices(bodies, s)
        r = float(bodies.shape_radius[s])
        what, outline = shape_outline(kind, verts, r)
        if what == "line":
            lines.append(outline)
            line_body.append(b)
        else:
            polygons.append(outline)
            polygon_body.append(b)
        if kind == "circle":
            spokes.append(np.array([verts[0], verts[0] + (r, 0.0)]))
            spoke_body.append(b)
    return Outlines(
        polygons=polygons,
        polygon_body=np.array(polygon_body, dtype=np.int64),
        lines=np.array(lines, dtype=float).reshape(-1, 2, 2),
        line_body=np.array(line_body, dtype=np.int64),
        spokes=np.array(spokes, dtype=float).reshape(-1, 2, 2),
        spoke_body=np.array(spoke_body, dtype=np.int64),
    )


def _place(points: np.ndarray, body: np.ndarray, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """World coordinates (m) of body-frame points (K,2) owned by body (K,), for one
    frame's origins pos (N,2) and orientations rot (N,2) = (cos θ, sin θ)."""
    c, s = rot[body, 0], rot[body, 1]
    x, y = points[:, 0], points[:, 1]
    return np.stack([pos[body, 0] + c * x - s * y, pos[body, 1] + s * x + c * y], axis=1)


class _PlacedOutlines:
    """Outlines flattened once so that placing them in a frame is one numpy call."""

    def __init__(self, outlines: Outlines) -> None:
        self.outlines = outlines
        counts = [len(p) for p in outlines.polygons]
        self.split = np.cumsum(counts)[:-1]
        if counts:
            self.points = np.concatenate(outlines.polygons)
            self.point_body = np.repeat(outlines.polygon_body, counts)
        else:
            self.points = np.zeros((0, 2))
            self.point_body = np.zeros(0, dtype=np.int64)

    def polygons(self, pos: np.ndarray, rot: np.ndarray) -> list[np.ndarray]:
        if not len(self.points):
            return []
        return np.split(_place(self.points, self.point_body, pos, rot), self.split)

    def segments(
        self, which: np.ndarray, body: np.ndarray, pos: np.ndarray, rot: np.ndarray
    ) -> np.ndarray:
        if not len(which):
            return np.zeros((0, 2, 2))
        flat = _place(which.reshape(-1, 2), np.repeat(body, 2), pos, rot)
        return flat.reshape(-1, 2, 2)


# ---------------------------------------------------------------------------------------
# GIF
# ---------------------------------------------------------------------------------------


def need_matplotlib(what: str) -> None:
    """Raise RenderError saying how to install matplotlib when it is missing."""
    try:
        import matplotlib  # noqa: F401
        import PIL  # noqa: F401
    except ImportError:
        raise RenderError(
            f"{what} needs matplotlib (and Pillow, which it brings): "
            "pip install 'rbsim[plot]' (or `make install` in rbsim's folder)"
        ) from None


def gif_palette() -> np.ndarray:
    """The fixed 256-colour GIF palette, (256,3) uint8 RGB: the 216 colours of the
    6x6x6 cube (every colour rbsim draws with is one of them) and 40 greys for the
    antialiased text. Every frame is mapped onto it, so that all frames share one
    global colour table, colours do not flicker, and encoding is deterministic."""
    levels = [0, 51, 102, 153, 204, 255]
    entries = [(r, g, b) for r in levels for g in levels for b in levels]
    greys = [g for g in range(6, 256, 6) if g not in levels][: 256 - len(entries)]
    entries += [(g, g, g) for g in greys]
    return np.array(entries, dtype=np.uint8)


class PaletteMapper:
    """Maps RGB frames exactly onto `palette` (K,3) uint8: each colour to the nearest
    entry (squared RGB distance, lowest index on ties). Pillow's own mapping goes
    through a coarse cache that can turn white into a near-white grey; this one
    keeps a lookup table over all 2^24 colours, filled as colours first appear."""

    def __init__(self, palette: np.ndarray) -> None:
        self.palette = np.asarray(palette, dtype=np.uint8)
        self.table = np.zeros(1 << 24, dtype=np.uint8)
        self.known = np.zeros(1 << 24, dtype=bool)

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """(H,W) uint8 palette indices of the (H,W,3) uint8 image rgb."""
        rgb = rgb.astype(np.uint32)
        key = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
        new = np.unique(key[~self.known[key]])
        if len(new):
            colours = np.stack([(new >> 16) & 255, (new >> 8) & 255, new & 255], axis=1)
            d = colours[:, None, :].astype(np.int64) - self.palette[None, :, :].astype(np.int64)
            self.table[new] = np.argmin(np.einsum("ckj,ckj->ck", d, d), axis=1)
            self.known[new] = True
        return self.table[key]


def gif_delays(times: np.ndarray, last: float) -> list[int]:
    """Frame delays, ms, in whole hundredths of a second (the GIF unit), for frames
    shown at `times` (s): frame k lasts until frame k + 1; the last lasts `last` s.
    Rounding is carried over from frame to frame, so the whole GIF lasts as long as
    the simulated time it shows."""
    times = np.asarray(times, dtype=float)
    ends = np.append(times[1:], times[-1] + last) - times[0]
    cs = np.round(ends * 100).astype(np.int64)
    return [int(d) * 10 for d in np.diff(np.concatenate([[0], cs]))]


@dataclass
class GifResult:
    """What render_gif wrote: path, frames, size (pixels), view (m; 2D, else None),
    seconds shown, and in 3D the camera (None in 2D)."""

    path: str
    frames: int
    width: int
    height: int
    view: View | None
    duration: float
    camera: Camera | None = None


def render_gif(
    path: str | os.PathLike,
    output: str | os.PathLike,
    *,
    fps: float = 30.0,
    size: tuple[int, int] = (640, 480),
    view: View | None = None,
    overlay: str | os.PathLike | None = None,
    start: float | None = None,
    end: float | None = None,
    progress: Progress | None = None,
    contacts: bool = True,
) -> GifResult:
    """Draw the trajectory `path` into an animated GIF at `output`.

    fps: frames per second of simulated time (<= GIF_MAX_FPS); the GIF plays in real
    time. size: (width, height) pixels. view: the world rectangle shown (m), widened to
    the image's aspect ratio; default: fitted to the moving bodies over the frames shown.
    overlay: a second trajectory drawn over the first as orange outlines, at the same
    times. A 3D trajectory is drawn in perspective from a camera that frames every
    moving body over the frames shown (`view` must then be None). start, end: s, the
    part of the run to show. progress(done, total) is called after each frame. Frames
    are drawn and written one at a time (memory does not grow with their number).
    contacts: draw the contact points the run recorded (output.contacts), each a dot
    with a short line along its normal. Raises RenderError.
    """
    need_matplotlib("rbsim render to a GIF")
    if not 0 < fps <= GIF_MAX_FPS:
        raise ValueError(f"GIF frames per second must lie in (0, {GIF_MAX_FPS:g}], got {fps:g}")
    width, height = int(size[0]), int(size[1])
    if width < 16 or height < 16:
        raise ValueError(f"image size must be at least 16 x 16 pixels, got {width} x {height}")
    output = os.fspath(output)

    with FrameReader(path) as main:
        idx = sample_frames(main.time, fps, start, end)
        if not len(idx):
            raise RenderError(no_frames_message(main, start, end))
        other = FrameReader(overlay) if overlay is not None else None
        try:
            if other is not None and not len(other.time):
                raise RenderError(f"{other.path}: no frames to overlay")
            check_dimensions(main, other, view)
            other_idx = match_frames(other.time, main.time[idx]) if other else None
            if main.dimension == 3:
                from .render3d import write_gif3d

                camera = write_gif3d(
                    main, idx, other, other_idx, output, fps, width, height, progress,
                    contacts=contacts,
                )  # fmt: skip
                duration = float(main.time[idx[-1]] - main.time[idx[0]]) + 1.0 / fps
                return GifResult(output, len(idx), width, height, None, duration, camera)
            if view is None:
                pairs = [(main, idx)]
                if other is not None and other_idx is not None:
                    pairs.append((other, np.unique(other_idx)))
                view = fit_view(pairs)
            view = view.with_aspect(width, height)
            _write_gif(
                main, idx, other, other_idx, output, fps, width, height, view, progress, contacts
            )
        finally:
            if other is not None:
                other.close()
        duration = float(main.time[idx[-1]] - main.time[idx[0]]) + 1.0 / fps
    return GifResult(output, len(idx), width, height, view, duration)


def overlay_mismatch(path: str | os.PathLike, overlay: str | os.PathLike) -> str | None:
    """Why the trajectory `overlay` looks like the run of another scene than `path`'s
    (its bodies' count or names differ), in words; None when they match, when either
    file cannot be read or they differ in dimension (rendering then fails, and says why:
    "overlaid all the same" would not be true)."""
    try:
        with FrameReader(path) as main, FrameReader(overlay) as other:
            if main.dimension != other.dimension:
                return None
            ours, theirs = list(main.bodies.name), list(other.bodies.name)
    except RenderError:
        return None
    if len(ours) != len(theirs):
        why = f"it has {len(theirs)} bodies, {os.fspath(path)} {len(ours)}"
    elif ours != theirs:
        k = next(i for i, (a, b) in enumerate(zip(ours, theirs, strict=True)) if a != b)
        why = f"its body {k} is {theirs[k]!r}, {os.fspath(path)}'s {ours[k]!r}"
    else:
        return None
    return f"{os.fspath(overlay)}: {why}: the run of another scene? (overlaid all the same)"


def check_dimensions(main: FrameReader, other: FrameReader | None, view: View | None) -> None:
    """Raise RenderError when the overlay `other` is of another dimension than `main`,
    or a view rectangle (2D) is given for a 3D trajectory."""
    if other is not None and other.dimension != main.dimension:
        raise RenderError(
            f"{other.path}: a {other.dimension}D trajectory cannot be overlaid on "
            f"{main.path} ({main.dimension}D)"
        )
    if main.dimension == 3 and view is not None:
        raise RenderError(
            f"{main.path}: a 3D trajectory: --view (a 2D rectangle) does not apply; "
            "the 3D camera is fitted to the moving bodies"
        )


def no_frames_message(reader: FrameReader, start: float | None, end: float | None) -> str:
    """What to say when no frame of `reader` falls in [start, end] (s)."""
    if not len(reader.time):
        return f"{reader.path}: no frames to render (status {reader.status})"
    return (
        f"{reader.path}: no frame between {start if start is not None else reader.time[0]:g} s "
        f"and {end if end is not None else reader.time[-1]:g} s (the run spans "
        f"{reader.time[0]:g}..{reader.time[-1]:g} s)"
    )


def _write_gif(
    main: FrameReader,
    idx: np.ndarray,
    other: FrameReader | None,
    other_idx: np.ndarray | None,
    output: str,
    fps: float,
    width: int,
    height: int,
    view: View,
    progress: Progress | None,
    contacts: bool = True,
) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    dpi = 100
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=COLOURS["background"])
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.set_xlim(view.x0, view.x1)
    ax.set_ylim(view.y0, view.y1)

    def artists(reader: FrameReader, overlay: bool) -> Callable[[np.ndarray, np.ndarray], None]:
        outlines = body_outlines(reader.bodies)
        placed = _PlacedOutlines(outlines)
        types = np.array(reader.bodies.type, dtype=object)
        poly_types = types[outlines.polygon_body] if len(outlines.polygon_body) else []
        if overlay:
            faces = ["none"] * len(outlines.polygons)
            edges = [COLOURS["overlay_edge"]] * len(outlines.polygons)
            line_colour = spoke_colour = COLOURS["overlay_edge"]
        else:
            faces = [COLOURS[f"{t}_fill"] for t in poly_types]
            edges = [COLOURS[f"{t}_edge"] for t in poly_types]
            line_colour, spoke_colour = COLOURS["static_edge"], COLOURS["dynamic_edge"]
        z = 3 if overlay else 2
        polys = PolyCollection(
            [], facecolors=faces, edgecolors=edges, linewidths=1.5 if overlay else 0.8, zorder=z
        )
        lines = LineCollection([], colors=line_colour, linewidths=1.5, zorder=z)
        spokes = LineCollection([], colors=spoke_colour, linewidths=1.2, zorder=z + 0.5)
        for artist in (polys, lines, spokes):
            ax.add_collection(artist)

        def update(pos: np.ndarray, rot: np.ndarray) -> None:
            polys.set_verts(placed.polygons(pos, rot))
            lines.set_segments(placed.segments(outlines.lines, outlines.line_body, pos, rot))
            spokes.set_segments(placed.segments(outlines.spokes, outlines.spoke_body, pos, rot))

        return update

    update_main = artists(main, overlay=False)
    update_other = artists(other, overlay=True) if other is not None else None
    points = FrameContacts(main, idx) if contacts and main.has_contacts else None
    if points is not None:
        normals, dots = contact_artists(ax, dpi)
        lo, hi = np.array([view.x0, view.y0]), np.array([view.x1, view.y1])
        length = contact_normal_length(body_reach(main.bodies), main.bodies.type, lo, hi)
    clock = ax.text(
        0.015,
        0.975,
        "",
        transform=ax.transAxes,
        ha="left",
        va="top",
        family="monospace",
        fontsize=10,
        color=COLOURS["text"],
        zorder=10,
    )
    if other is not None:
        ax.text(
            0.985,
            0.975,
            f"{main.label}\n ",
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize=8,
            color=COLOURS["text"],
            zorder=10,
        )
        ax.text(
            0.985,
            0.975,
            " \n" + other.label,
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize=8,
            color=COLOURS["overlay_edge"],
            zorder=11,
        )

    def draw(pos: np.ndarray, rot: np.ndarray, other_pose: Pose | None) -> None:
        update_main(pos, rot)
        if update_other is not None and other_pose is not None:
            update_other(*other_pose)
        if points is not None:  # world coordinates: the axes are the view, m
            at, normal = points.next()
            dots.set_offsets(at.reshape(-1, 2))
            normals.set_segments(np.stack([at, at + length * normal], axis=1))

    write_frames(main, idx, other, other_idx, output, gif_palette(), fps, canvas, clock, draw,
                 progress)  # fmt: skip


# One frame's body origins (N,D) m and orientations (N,2) or (N,4).
Pose = tuple[np.ndarray, np.ndarray]


def write_frames(
    main: FrameReader,
    idx: np.ndarray,
    other: FrameReader | None,
    other_idx: np.ndarray | None,
    output: str,
    palette: np.ndarray,
    fps: float,
    canvas: FigureCanvasAgg,
    clock: Text,
    draw: Callable[[np.ndarray, np.ndarray, Pose | None], None],
    progress: Progress | None,
) -> None:
    """The GIF loop of both dimensions: for each frame idx of `main` (and the overlay's
    frame other_idx at the same place), draw(origins, orientations, overlay pose or
    None) updates the figure, the clock shows the time, and `canvas` is drawn into the
    GIF `output` on `palette`, each frame shown until the next (fps: frames per second
    of simulated time). progress(done, total) after each frame."""
    delays = gif_delays(main.time[idx], 1.0 / fps)
    digits = clock_digits(fps)
    others = None
    if other is not None and other_idx is not None:
        others = _reorder_reads(other, other_idx)
    with GifWriter(output, palette) as gif:
        k = 0
        for _part, pos, rot in main.batches(idx):
            for j in range(len(pos)):
                draw(pos[j], rot[j], next(others) if others is not None else None)
                clock.set_text(f"t = {main.time[idx[k]]:.{digits}f} s")
                canvas.draw()
                gif.add(np.asarray(canvas.buffer_rgba())[:, :, :3], delays[k])
                k += 1
                if progress is not None:
                    progress(k, len(idx))


def clock_digits(fps: float) -> int:
    """Decimals of the clock shown on frames that are 1/fps s apart (at least 2)."""
    return max(2, int(math.ceil(-math.log10(1.0 / fps))) if fps > 1 else 2)


class GifWriter:
    """An animated GIF written frame by frame to `output` (under `output`.part, renamed
    when closed without error; removed otherwise). Every frame is mapped onto the one
    global `palette` (K,3) uint8 (PaletteMapper), and after the first only the
    rectangle that changed is stored (each frame is drawn over the one before)."""

    def __init__(self, output: str, palette: np.ndarray) -> None:
        from PIL import GifImagePlugin, Image

        self._plugin, self._image = GifImagePlugin, Image
        self.output = output
        self._tmp = output + ".part"
        self._to_palette = PaletteMapper(palette)
        self._flat = np.asarray(palette, dtype=np.uint8).reshape(-1).tobytes()
        self._previous: np.ndarray | None = None
        self._fh = open(self._tmp, "wb")  # noqa: SIM115 (closed in close / __exit__)

    def add(self, rgb: np.ndarray, delay: int) -> None:
        """Append the (H,W,3) uint8 image rgb, shown for `delay` ms (whole 10 ms)."""
        indices = self._to_palette(rgb)
        x0, y0, x1, y1 = _changed_box(self._previous, indices)
        first = self._previous is None
        self._previous = indices
        part = np.ascontiguousarray(indices[y0:y1, x0:x1])
        frame = self._image.frombytes("P", (x1 - x0, y1 - y0), part.tobytes())
        frame.putpalette(self._flat)
        if first:
            header, _ = self._plugin.getheader(frame, None, {"loop": 0})
            self._fh.write(b"".join(header))
        self._fh.write(b"".join(self._plugin.getdata(frame, (x0, y0), duration=delay)))

    def __enter__(self) -> GifWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self._fh.write(b";")  # GIF trailer
            self._fh.close()
            os.replace(self._tmp, self.output)
        else:
            self._fh.close()
            if os.path.exists(self._tmp):
                os.remove(self._tmp)


def _changed_box(previous: np.ndarray | None, current: np.ndarray) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels: the smallest rectangle holding every pixel that differs
    between two (H,W) frames (at least one pixel); the whole frame when there is no
    previous one. Each GIF frame is drawn over the one before (no disposal)."""
    h, w = current.shape
    if previous is None:
        return 0, 0, w, h
    diff = previous != current
    rows, cols = np.flatnonzero(diff.any(axis=1)), np.flatnonzero(diff.any(axis=0))
    if not len(rows):
        return 0, 0, 1, 1
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def _reorder_reads(reader: FrameReader, idx: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(origins, orientations) of the frames idx (non-decreasing, repeats allowed),
    one frame at a time, read in batches of distinct frames."""
    for lo in range(0, len(idx), BATCH_FRAMES):
        part = idx[lo : lo + BATCH_FRAMES]
        uniq, inverse = np.unique(part, return_inverse=True)
        pos, rot = reader.read(uniq)
        for i in inverse:
            yield pos[i], rot[i]
