"""What the tools measure the same way.

- One penetration ruler: how deep two shapes of a pose overlap, from the model's shapes
  at given centres of mass and angles, by the engine's own separation function
  (rbsim.core.min_separation: SAT separation of the shapes' cores minus their radii);
  `deepest_overlap` asks it of many poses (a run's frames) at once.
- One stopwatch for engines stepped in blocks (block_times; interleaved_block_times for
  engines timed against one another, and median_ratio of their paired times).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np

from ..core import min_separation
from ..engines import Engine
from ..scene import types as T
from ..scene.compile import Model


def touching_pairs(model: Model, x: np.ndarray, theta: np.ndarray, margin: float) -> np.ndarray:
    """(P, 2) shape index pairs of different bodies, at least one dynamic, whose bounding
    boxes at the pose (x (N,2) centres of mass m, theta (N,) rad) are within `margin` m."""
    lo, hi = shape_boxes(model, x, theta)
    body = model.shape_body
    dynamic = model.body_type[body] == T.BODY_DYNAMIC
    overlap = np.all(lo[:, None, :] <= hi[None, :, :] + margin, axis=2) & np.all(
        lo[None, :, :] <= hi[:, None, :] + margin, axis=2
    )
    i, j = np.nonzero(np.triu(overlap, 1))
    keep = (body[i] != body[j]) & (dynamic[i] | dynamic[j])
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)


def shape_boxes(model: Model, x: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each shape's bounding box at the pose: lo (S,2), hi (S,2), m (radius included)."""
    verts = vertices_world(model, x, theta)
    n = model.shape_body.shape[0]
    lo, hi = np.empty((n, 2)), np.empty((n, 2))
    for s in range(n):
        v = verts[model.shape_vstart[s] : model.shape_vstart[s] + model.shape_vcount[s]]
        lo[s], hi[s] = v.min(axis=0) - model.shape_radius[s], v.max(axis=0) + model.shape_radius[s]
    return lo, hi


def vertices_world(model: Model, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Every shape's vertices (V,2) in the world frame at the pose (x (N,2) centres of
    mass m, theta (N,) rad), in the model's vertex order."""
    b = model.shape_body[np.repeat(np.arange(model.shape_body.shape[0]), model.shape_vcount)]
    c, s = np.cos(theta[b]), np.sin(theta[b])
    v = model.vertex_local
    return x[b] + np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], axis=1)


def penetration(model: Model, pairs: np.ndarray, x: np.ndarray, theta: np.ndarray) -> float:
    """Deepest overlap (m, 0 when none) among the shape `pairs` at the pose x (N,2)
    centres of mass (m), theta (N,) (rad): SAT separation of the shapes' cores (polygons,
    segments, circle centres) minus their radii."""
    if pairs.shape[0] == 0:
        return 0.0
    verts = vertices_world(model, x, theta)
    sep = min_separation(verts, model.shape_vstart, model.shape_vcount, model.shape_radius, pairs)
    return max(0.0, -float(sep.min()))


# deepest_overlap tests the bounding boxes of every pair of shapes of a frame at once, for
# as many frames together as keep that test within DENSE_PAIRS pairs (about as many bytes);
# above DENSE_SHAPES shapes a sweep along one axis finds each frame's candidate pairs
# instead (its cost grows as S log S plus the pairs found, the dense test's as S²).
DENSE_PAIRS = 1 << 22
DENSE_SHAPES = 256


def deepest_overlap(
    model: Model, x: np.ndarray, theta: np.ndarray, measured: np.ndarray | None = None
) -> float:
    """Deepest overlap (m, 0 when none) over a series of poses: the largest `penetration`
    of the pairs `touching_pairs` finds (margin 0) at any pose, x (T,N,2) centres of mass
    (m), theta (T,N) (rad), with one call of the engine's ruler per chunk of frames.
    measured: (N,) bool, the bodies whose poses are given (default every one); the
    shapes of the others are left out."""
    n = model.shape_body.shape[0]
    frames = x.shape[0]
    if frames == 0 or n < 2:
        return 0.0
    body = model.shape_body
    dynamic = model.body_type[body] == T.BODY_DYNAMIC
    used = np.ones(n, bool) if measured is None else np.asarray(measured, bool)[body]
    deepest = 0.0
    if n <= DENSE_SHAPES:
        allowed = np.triu(body[:, None] != body[None, :], 1)
        allowed &= dynamic[:, None] | dynamic[None, :]
        allowed &= used[:, None] & used[None, :]
        chunk = max(1, DENSE_PAIRS // (n * n))
        for t0 in range(0, frames, chunk):
            verts = _frame_vertices(model, x[t0 : t0 + chunk], theta[t0 : t0 + chunk])
            lo, hi = _frame_boxes(model, verts)
            touch = np.broadcast_to(allowed, (len(verts), n, n)).copy()
            for d in range(2):  # lo_i <= hi_j and lo_j <= hi_i along each axis
                a, b = lo[:, :, d], hi[:, :, d]
                touch &= a[:, :, None] <= b[:, None, :]
                touch &= a[:, None, :] <= b[:, :, None]
            f, i, j = np.nonzero(touch)
            deepest = max(deepest, _deepest(model, verts, f, i, j))
        return deepest
    for t in range(frames):
        verts = _frame_vertices(model, x[t : t + 1], theta[t : t + 1])
        lo, hi = _frame_boxes(model, verts)
        i, j = _sweep(lo[0], hi[0])
        keep = (body[i] != body[j]) & (dynamic[i] | dynamic[j]) & used[i] & used[j]
        i, j = i[keep], j[keep]
        deepest = max(deepest, _deepest(model, verts, np.zeros_like(i), i, j))
    return deepest


def _frame_vertices(model: Model, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """vertices_world of each pose: (F,V,2) m, from x (F,N,2) and theta (F,N)."""
    b = model.shape_body[np.repeat(np.arange(model.shape_body.shape[0]), model.shape_vcount)]
    c, s = np.cos(theta[:, b]), np.sin(theta[:, b])
    v = model.vertex_local
    return x[:, b] + np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], axis=-1)


def _frame_boxes(model: Model, verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """shape_boxes of each pose: lo, hi (F,S,2) m from its vertices (F,V,2) (a shape's
    vertices follow the previous shape's, and every shape has at least one)."""
    r = model.shape_radius[None, :, None]
    start = model.shape_vstart
    return np.minimum.reduceat(verts, start, axis=1) - r, np.maximum.reduceat(
        verts, start, axis=1
    ) + r


def _sweep(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (i < j) of boxes lo, hi (S,2) that overlap (touching counts), found by
    sorting them along the axis their centres spread most."""
    axis = int(np.argmax(np.ptp(lo + hi, axis=0)))
    order = np.argsort(lo[:, axis], kind="stable")
    low = lo[order, axis]
    # box order[a] meets, along the axis, every box order[k] of a < k < end[a]
    end = np.searchsorted(low, hi[order, axis], side="right")
    first = np.arange(1, len(order) + 1)
    count = np.maximum(end - first, 0)
    a = np.repeat(np.arange(len(order)), count)
    k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    i, j = order[a], order[k + first[a]]
    other = 1 - axis
    meet = (lo[i, other] <= hi[j, other]) & (lo[j, other] <= hi[i, other])
    i, j = i[meet], j[meet]
    return np.minimum(i, j), np.maximum(i, j)


def _deepest(model: Model, verts: np.ndarray, f: np.ndarray, i: np.ndarray, j: np.ndarray) -> float:
    """The deepest overlap (m, 0 when none) of the shape pairs (i, j) of poses f, whose
    vertices are verts (F,V,2): one call of the engine's ruler for every pose at once."""
    if i.shape[0] == 0:
        return 0.0
    frames, nv = verts.shape[0], verts.shape[1]
    n = model.shape_body.shape[0]
    start = (np.arange(frames)[:, None] * nv + model.shape_vstart[None, :]).ravel()
    sep = min_separation(
        verts.reshape(-1, 2),
        start,
        np.tile(model.shape_vcount, frames),
        np.tile(model.shape_radius, frames),
        np.stack([f * n + i, f * n + j], axis=1),
    )
    return max(0.0, -float(sep.min()))


def block_times(
    engine: Engine,
    warmup: int,
    block: int,
    repeats: int,
    clock: Callable[[], float] = time.process_time,
) -> list[float]:
    """µs per step of `repeats` blocks of `block` steps, after `warmup` untimed steps, by
    `clock` (s; CPU time by default, time.perf_counter for wall time)."""
    return interleaved_block_times([engine], warmup, block, repeats, clock)[0]


def interleaved_block_times(
    engines: list[Engine],
    warmup: int,
    block: int,
    repeats: int,
    clock: Callable[[], float] = time.process_time,
) -> list[list[float]]:
    """block_times of several engines, their blocks taken in turn (a block of each, then
    again, `repeats` rounds) so that a slow spell of a shared machine falls on all of them
    alike: one list of µs per step for each engine, in the engines' order."""
    for engine in engines:
        engine.advance(warmup)
    times: list[list[float]] = [[] for _ in engines]
    for _ in range(repeats):
        for engine, out in zip(engines, times, strict=True):
            t0 = clock()
            engine.advance(block)
            out.append((clock() - t0) / block * 1e6)
    return times


def median_ratio(a: list[float], b: list[float]) -> float:
    """The median over paired samples of a / b (the ratio of two engines' times from
    blocks or runs taken in turn)."""
    ratios = [x / y for x, y in zip(a, b, strict=True) if y > 0.0]
    return statistics.median(ratios) if ratios else float("nan")
