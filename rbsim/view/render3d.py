"""3D trajectories as GIFs: every shape as triangles (rbsim.view.mesh), placed per frame
by its body's origin and quaternion, flat-shaded from one light and drawn far to near
(the painter's algorithm, back faces culled) onto a 2D matplotlib canvas in pixels,
over the ground grid, from a fixed camera that frames every moving body's path.

Units: lengths m, times s, image sizes pixels.
"""

from __future__ import annotations

import numpy as np

from .mesh import (
    AMBIENT,
    BodyMeshes,
    Camera,
    Ground,
    body_meshes,
    body_reach3d,
    fit_camera,
    ground_grid,
    quat_matrix,
    shade,
)
from .render import (
    COLOURS,
    FrameContacts,
    FrameReader,
    Pose,
    Progress,
    contact_artists,
    contact_normal_length,
    gif_palette,
    write_frames,
)

__all__ = [
    "COLOURS_3D",
    "SHADE_LEVELS",
    "fit_box",
    "frame_faces",
    "gif_palette3d",
    "clip_near",
    "contact_pixels",
    "ground_for",
    "shaded_rgb",
    "write_gif3d",
]

# Colours of the 3D pictures besides the 2D ones (COLOURS): the ground patch and grid.
COLOURS_3D = {**COLOURS, "ground_fill": "#eeeeee", "grid": "#b0b0b0"}
# Brightness steps of each body colour in the GIF palette (3 colours x 60 + the rest
# fits 256; 60 steps over [AMBIENT, 1] are 1.1% apart, below visible banding).
SHADE_LEVELS = 60
# Depth of the near plane, as a fraction of the camera's distance to its target: nearer
# points are not drawn (nor faces reaching them; the ground is clipped there). As in
# player3d.js.
NEAR_FRACTION = 0.05


def _rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)


def shade_level(brightness: np.ndarray) -> np.ndarray:
    """The palette step (0..SHADE_LEVELS-1) nearest each brightness in [AMBIENT, 1]."""
    u = (np.asarray(brightness, dtype=float) - AMBIENT) / (1.0 - AMBIENT)
    return np.clip(np.rint(u * (SHADE_LEVELS - 1)), 0, SHADE_LEVELS - 1).astype(np.int64)


def shaded_rgb(colour: str, brightness: np.ndarray) -> np.ndarray:
    """(...,3) uint8: `colour` ("#rrggbb") at the GIF's palette step of each brightness
    (shade()), the exact colour the GIF shows for a face of that brightness."""
    level = shade_level(brightness)
    b = AMBIENT + (1.0 - AMBIENT) * level / (SHADE_LEVELS - 1)
    return np.rint(_rgb(colour) * b[..., None]).astype(np.uint8)


def gif_palette3d() -> np.ndarray:
    """The 256-colour palette of 3D GIFs, (256,3) uint8: SHADE_LEVELS steps of each body
    type's fill colour, the ground, grid, text, overlay and background colours, and the
    rest of the 2D palette (greys and the colour cube) for antialiased edges."""
    steps = np.linspace(AMBIENT, 1.0, SHADE_LEVELS)
    entries: list[tuple[int, int, int]] = []
    for kind in ("dynamic", "static", "kinematic"):
        entries += [tuple(c) for c in shaded_rgb(COLOURS_3D[f"{kind}_fill"], steps).tolist()]
    edges = ("dynamic_edge", "static_edge", "kinematic_edge")
    for key in ("background", "ground_fill", "grid", "text", "overlay_edge", "contact", *edges):
        entries.append(tuple(int(c) for c in _rgb(COLOURS_3D[key])))
    seen: set[tuple[int, int, int]] = set()
    unique = [e for e in entries if not (e in seen or seen.add(e))]
    for extra in gif_palette().tolist():
        if len(unique) >= 256:
            break
        t = tuple(extra)
        if t not in seen:
            seen.add(t)
            unique.append(t)
    return np.array(unique[:256], dtype=np.uint8)


def fit_box(readers: list[tuple[FrameReader, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) m, world: a box holding every moving body of every (reader, frame
    indices) pair at each of those frames, each body a ball of its reach about its
    origin; the static bodies (planes left out) only when nothing moves."""
    lo = np.full(3, np.inf)
    hi = -lo
    for moving_only in (True, False):
        for reader, idx in readers:
            reach = body_reach3d(reader.bodies)
            keep = np.array([t != "static" or not moving_only for t in reader.bodies.type])
            if not moving_only:  # bodies made only of planes have no extent
                keep &= reach > 0
            if not keep.any() or len(idx) == 0:
                continue
            frames = idx if moving_only else idx[:1]
            for _part, pos, _rot in reader.batches(frames):
                p = pos[:, keep]
                r = reach[keep][None, :, None]
                finite = np.isfinite(p).all(axis=2)[..., None]
                if finite.any():
                    lo = np.minimum(lo, np.min(np.where(finite, p - r, np.inf), (0, 1)))
                    hi = np.maximum(hi, np.max(np.where(finite, p + r, -np.inf), (0, 1)))
        if np.all(np.isfinite(lo)):
            break
    if not np.all(np.isfinite(lo)):
        lo, hi = -np.ones(3), np.ones(3)
    return lo, hi


def ground_for(reader: FrameReader, lo: np.ndarray, hi: np.ndarray) -> Ground:
    """The ground under a scene filling [lo, hi] (m): the reader's planes (at their
    bodies' first-frame poses; planes are static) as patches, else a floor grid."""
    meshes = body_meshes(reader.bodies)
    planes = []
    if meshes.planes:
        pos, rot = reader.read(np.array([0]))
        R = quat_matrix(rot[0])
        for b, point, normal in meshes.planes:
            planes.append((pos[0, b] + R[b] @ point, R[b] @ normal))
    return ground_grid(planes, lo, hi)


def frame_faces(
    meshes: BodyMeshes, pos: np.ndarray, rot: np.ndarray, camera: Camera, width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The faces to draw in one frame, far to near: indices into meshes.faces (F,),
    their corners' pixels (F,K,2) and brightness (F,) (shade() of the world normal).
    pos (N,3) m and rot (N,4) (w, x, y, z): the frame's body origins and orientations.
    Faces turned away from the camera and faces reaching behind it are left out."""
    k = meshes.faces.shape[1]
    if not len(meshes.faces):
        return np.zeros(0, dtype=np.int64), np.zeros((0, k, 2)), np.zeros(0)
    R = quat_matrix(rot)
    pb = meshes.point_body
    world = pos[pb] + np.einsum("kij,kj->ki", R[pb], meshes.points)
    px, depth = camera.project(world, width, height)
    a, b, c = (world[meshes.faces[:, i]] for i in range(3))
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    eye = camera.basis()[0]
    facing = np.einsum("ij,ij->i", normal, eye - a) > 0
    near = NEAR_FRACTION * camera.distance
    keep = np.flatnonzero(facing & (length > 0) & (depth[meshes.faces] > near).all(axis=1))
    corner = np.arange(k)[None, :] < meshes.face_size[keep][:, None]
    mean_depth = np.where(corner, depth[meshes.faces[keep]], 0).sum(1) / meshes.face_size[keep]
    keep = keep[np.argsort(-mean_depth, kind="stable")]
    bright = shade(normal[keep] / length[keep][:, None])
    return keep, px[meshes.faces[keep]], bright


def clip_near(points: np.ndarray, camera: Camera, closed: bool) -> np.ndarray:
    """The part beyond the camera's near plane (depth > NEAR_FRACTION x its distance)
    of a world polygon (k,3) m (a polyline when not `closed`), (j,3) m: one plane's
    Sutherland-Hodgman clipping."""
    eye, _right, _up, forward = camera.basis()
    near = NEAR_FRACTION * camera.distance
    depth = (points - eye) @ forward
    out = []
    n = len(points)
    for i in range(n if closed else n - 1):
        j = (i + 1) % n
        if depth[i] > near:
            out.append(points[i])
        if (depth[i] > near) != (depth[j] > near):  # the edge crosses the near plane
            u = (near - depth[i]) / (depth[j] - depth[i])
            out.append(points[i] + u * (points[j] - points[i]))
    if not closed and depth[-1] > near:
        out.append(points[-1])
    return np.array(out).reshape(-1, 3)


def contact_pixels(
    pos: np.ndarray, normal: np.ndarray, length: float, camera: Camera, width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """One frame's contact points in pixels: the dots (k,2) of the points pos (k,3) m in
    front of the camera's near plane, and the segments (k,2,2) from each along its unit
    normal for `length` m (those wholly in front)."""
    near = NEAR_FRACTION * camera.distance
    tips = pos + length * normal
    px, depth = camera.project(pos, width, height)
    tip_px, tip_depth = camera.project(tips, width, height)
    seen = depth > near
    both = seen & (tip_depth > near)
    return px[seen], np.stack([px[both], tip_px[both]], axis=1)


def _ground_pixels(
    camera: Camera, ground: Ground, width: int, height: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The ground's patches (polygons) and grid lines (segments) in pixels, clipped at
    the camera's near plane."""
    quads, lines = [], []
    for quad in ground.quads:
        part = clip_near(quad, camera, closed=True)
        if len(part) >= 3:
            quads.append(camera.project(part, width, height)[0])
    for line in ground.lines:
        part = clip_near(line, camera, closed=False)
        if len(part) == 2:
            lines.append(camera.project(part, width, height)[0])
    return quads, lines


def write_gif3d(
    main: FrameReader,
    idx: np.ndarray,
    other: FrameReader | None,
    other_idx: np.ndarray | None,
    output: str,
    fps: float,
    width: int,
    height: int,
    progress: Progress | None,
    contacts: bool = True,
) -> Camera:
    """Draw frames idx of the 3D trajectory `main` (and the overlay `other` at frames
    other_idx, as orange wireframes) into the GIF `output`, width x height pixels, each
    frame shown until the next (fps: frames per second of simulated time); with
    `contacts`, main's recorded contact points over everything (dots with a short line
    along each normal, see contact_pixels). Returns the camera used (fitted to the
    moving bodies over the frames shown)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    pairs = [(main, idx)]
    if other is not None and other_idx is not None:
        pairs.append((other, np.unique(other_idx)))
    lo, hi = fit_box(pairs)
    camera = fit_camera(lo, hi, width, height)
    ground = ground_for(main, lo, hi)

    dpi = 100
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=COLOURS["background"])
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)  # pixels, y down, as Camera.project gives them
    quads, lines = _ground_pixels(camera, ground, width, height)
    ax.add_collection(
        PolyCollection(quads, facecolors=COLOURS_3D["ground_fill"], edgecolors="none", zorder=0)
    )
    ax.add_collection(LineCollection(lines, colors=COLOURS_3D["grid"], linewidths=0.8, zorder=1))

    main_meshes = body_meshes(main.bodies)
    types = np.array(main.bodies.type, dtype=object)
    face_type = types[main_meshes.face_body] if len(main_meshes.face_body) else types[:0]
    faces = PolyCollection([], linewidths=0.6, zorder=2, antialiaseds=True)
    ax.add_collection(faces)
    other_meshes = body_meshes(other.bodies) if other is not None else None
    wire = PolyCollection(
        [], facecolors="none", edgecolors=COLOURS["overlay_edge"], linewidths=0.7, zorder=3
    )
    ax.add_collection(wire)
    points = FrameContacts(main, idx) if contacts and main.has_contacts else None
    if points is not None:
        normals, dots = contact_artists(ax, dpi)
        length = contact_normal_length(body_reach3d(main.bodies), main.bodies.type, lo, hi)
    clock = ax.text(
        0.015, 0.975, "", transform=ax.transAxes, ha="left", va="top", family="monospace",
        fontsize=10, color=COLOURS["text"], zorder=10,
    )  # fmt: skip
    if other is not None:
        ax.text(
            0.985, 0.975, f"{main.label}\n ", transform=ax.transAxes, ha="right", va="top",
            fontsize=8, color=COLOURS["text"], zorder=10,
        )  # fmt: skip
        ax.text(
            0.985, 0.975, " \n" + other.label, transform=ax.transAxes, ha="right", va="top",
            fontsize=8, color=COLOURS["overlay_edge"], zorder=11,
        )  # fmt: skip
    # every face colour the palette holds, by body type and step, as matplotlib RGBA
    steps = np.linspace(AMBIENT, 1.0, SHADE_LEVELS)
    tables = {
        t: np.concatenate([shaded_rgb(COLOURS_3D[f"{t}_fill"], steps) / 255.0,
                           np.ones((SHADE_LEVELS, 1))], 1)
        for t in set(types.tolist())
    }  # fmt: skip
    edge_rgba = {t: np.append(_rgb(COLOURS_3D[f"{t}_edge"]) / 255.0, 1.0) for t in tables}

    def draw(pos: np.ndarray, rot: np.ndarray, other_pose: Pose | None) -> None:
        shown, corners, bright = frame_faces(main_meshes, pos, rot, camera, width, height)
        levels = shade_level(bright)
        fill = np.zeros((len(shown), 4))
        edge = np.zeros((len(shown), 4))
        for t, table in tables.items():
            mine = face_type[shown] == t
            fill[mine] = table[levels[mine]]
            # boxes and hulls outlined; round shapes' facets edged in their own colour,
            # which hides the seams between them
            edge[mine] = fill[mine]
            edge[mine & main_meshes.face_outlined[shown]] = edge_rgba[t]
        faces.set_verts(corners)  # an (F,K,2) array: matplotlib's fast path
        faces.set_facecolor(fill)
        faces.set_edgecolor(edge)
        if other_meshes is not None and other_pose is not None:
            _shown, wire_px, _bright = frame_faces(other_meshes, *other_pose, camera, width, height)
            wire.set_verts(wire_px)
        if points is not None:
            at, lines = contact_pixels(*points.next(), length, camera, width, height)
            dots.set_offsets(at.reshape(-1, 2))
            normals.set_segments(lines)

    write_frames(main, idx, other, other_idx, output, gif_palette3d(), fps, canvas, clock, draw,
                 progress)  # fmt: skip
    return camera
