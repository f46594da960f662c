"""What the tools measure the same way.

- One penetration ruler: how deep two shapes of a pose overlap, from the model's shapes
  at given centres of mass and angles, by the engine's own separation function
  (rbsim.core.min_separation: SAT separation of the shapes' cores minus their radii).
- One stopwatch for engines stepped in blocks (block_times).
"""

from __future__ import annotations

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


def block_times(
    engine: Engine,
    warmup: int,
    block: int,
    repeats: int,
    clock: Callable[[], float] = time.process_time,
) -> list[float]:
    """µs per step of `repeats` blocks of `block` steps, after `warmup` untimed steps, by
    `clock` (s; CPU time by default, time.perf_counter for wall time)."""
    engine.advance(warmup)
    times = []
    for _ in range(repeats):
        t0 = clock()
        engine.advance(block)
        times.append((clock() - t0) / block * 1e6)
    return times
