"""Broadphase: candidate shape pairs whose bounding boxes overlap, in O(N).

A uniform grid hashed into a table. Each shape is entered in every cell its box
touches (at most MAX_CELLS); a pair sharing several cells is reported only from the
cell that holds the corner max(min_a, min_b), so no pair is found twice. Shapes whose
box spans more cells than that (a long ground, a very fast body) are "big": they
are tested against every other shape directly, which is cheap while they are few.

Pairs come out sorted by (shape a, shape b) with a < b, so the order is deterministic
and the contact stage can match them against the previous step in one merge pass.
Pairs within one body, and pairs where neither body is dynamic, are skipped.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import constants as C

MAX_CELLS = 16  # cells a shape may touch before it is treated as big


class Grid(NamedTuple):
    """Scratch for the grid; S shapes, E = MAX_CELLS·S entries, T table buckets.

    inv_cell: 1 / cell size (1/m). shape_aabb (S,4) min x, min y, max x, max y (m);
    shape_cells (S,4) int64 cell range ix0, iy0, ix1, iy1; shape_big (S,) bool;
    entry_shape, entry_ix, entry_iy (E,) sorted by bucket; bucket_start (T+1,);
    entry_bucket (E,) scratch; candidates (S,) scratch for one shape's partners;
    big_list (S,) the big shapes in index order, big_count (1,) how many.
    """

    inv_cell: float
    shape_aabb: np.ndarray
    shape_cells: np.ndarray
    shape_big: np.ndarray
    entry_shape: np.ndarray
    entry_ix: np.ndarray
    entry_iy: np.ndarray
    entry_bucket: np.ndarray
    bucket_start: np.ndarray
    candidates: np.ndarray
    big_list: np.ndarray
    big_count: np.ndarray


def make_grid(shape_extent: np.ndarray, shape_is_dynamic: np.ndarray) -> Grid:
    """Preallocate a grid sized for the scene's shapes.

    The cell size is twice the median extent (m, COM to farthest point) of the
    dynamic shapes plus the AABB margin, so a typical shape touches 1 to 4 cells.
    """
    s = shape_extent.shape[0]
    dyn = shape_extent[shape_is_dynamic]
    size = 2.0 * float(np.median(dyn)) if dyn.size else 1.0
    cell = max(size, 1e-3) + 2.0 * C.AABB_MARGIN
    table = 64
    while table < 4 * s:
        table *= 2
    e = MAX_CELLS * max(s, 1)
    return Grid(
        inv_cell=1.0 / cell,
        shape_aabb=np.zeros((s, 4)),
        shape_cells=np.zeros((s, 4), np.int64),
        shape_big=np.zeros(s, np.bool_),
        entry_shape=np.zeros(e, np.int32),
        entry_ix=np.zeros(e, np.int64),
        entry_iy=np.zeros(e, np.int64),
        entry_bucket=np.zeros(e, np.int64),
        bucket_start=np.zeros(table + 1, np.int64),
        candidates=np.zeros(max(s, 1), np.int32),
        big_list=np.zeros(max(s, 1), np.int32),
        big_count=np.zeros(1, np.int64),
    )


@njit(cache=True, inline="always")
def _bucket(ix, iy, mask):
    return ((ix * 73856093) ^ (iy * 19349663)) & mask


@njit(cache=True)
def update_aabbs(model, grid, vert_world, shape_margin):
    """Boxes of every shape from its world vertices, radius and margin (m)."""
    for s in range(model.shape_body.shape[0]):
        start, count = model.shape_vstart[s], model.shape_vcount[s]
        x0, y0 = vert_world[start, 0], vert_world[start, 1]
        x1, y1 = x0, y0
        for k in range(start + 1, start + count):
            px, py = vert_world[k, 0], vert_world[k, 1]
            x0, y0, x1, y1 = min(x0, px), min(y0, py), max(x1, px), max(y1, py)
        r = model.shape_radius[s] + shape_margin[s]
        grid.shape_aabb[s, 0] = x0 - r
        grid.shape_aabb[s, 1] = y0 - r
        grid.shape_aabb[s, 2] = x1 + r
        grid.shape_aabb[s, 3] = y1 + r


@njit(cache=True)
def _fill_grid(grid):
    """Enter every small shape into the cells it touches (counting sort by bucket)."""
    n = grid.shape_aabb.shape[0]
    mask = grid.bucket_start.shape[0] - 2  # table size - 1 (a power of two minus one)
    inv = grid.inv_cell
    starts = grid.bucket_start
    starts[:] = 0
    e = 0
    nbig = 0
    for s in range(n):
        box = grid.shape_aabb[s]
        ix0 = math.floor(box[0] * inv)
        iy0 = math.floor(box[1] * inv)
        ix1 = math.floor(box[2] * inv)
        iy1 = math.floor(box[3] * inv)
        big = (ix1 - ix0 + 1) * (iy1 - iy0 + 1) > MAX_CELLS
        grid.shape_big[s] = big
        grid.shape_cells[s, 0], grid.shape_cells[s, 1] = ix0, iy0
        grid.shape_cells[s, 2], grid.shape_cells[s, 3] = ix1, iy1
        if big:
            grid.big_list[nbig] = s
            nbig += 1
            continue
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                b = _bucket(ix, iy, mask)
                grid.entry_bucket[e] = b
                starts[b + 1] += 1
                e += 1
    grid.big_count[0] = nbig
    for b in range(mask + 1):
        starts[b + 1] += starts[b]
    # place entries; `starts[b]` walks forward and is restored afterwards
    e = 0
    for s in range(n):
        if grid.shape_big[s]:
            continue
        ix0, iy0 = grid.shape_cells[s, 0], grid.shape_cells[s, 1]
        ix1, iy1 = grid.shape_cells[s, 2], grid.shape_cells[s, 3]
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                b = grid.entry_bucket[e]
                k = starts[b]
                grid.entry_shape[k] = s
                grid.entry_ix[k] = ix
                grid.entry_iy[k] = iy
                starts[b] = k + 1
                e += 1
    for b in range(mask, 0, -1):
        starts[b] = starts[b - 1]
    starts[0] = 0


@njit(cache=True, inline="always")
def _may_collide(model, a, b):
    ba, bb = model.shape_body[a], model.shape_body[b]
    if ba == bb:
        return False
    return model.body_type[ba] == C.BODY_DYNAMIC or model.body_type[bb] == C.BODY_DYNAMIC


@njit(cache=True, inline="always")
def _overlap(grid, a, b):
    p, q = grid.shape_aabb[a], grid.shape_aabb[b]
    return p[0] <= q[2] and q[0] <= p[2] and p[1] <= q[3] and q[1] <= p[3]


@njit(cache=True)
def find_pairs(model, grid, vert_world, shape_margin, pairs):
    """Fill `pairs` (P,2) int32 with overlapping shape pairs, sorted; return their count.

    When more than P pairs exist, the count returned is the number needed and
    `pairs` holds only the first P: the caller grows the array and calls again.
    """
    update_aabbs(model, grid, vert_world, shape_margin)
    _fill_grid(grid)
    n = grid.shape_aabb.shape[0]
    mask = grid.bucket_start.shape[0] - 2
    cand = grid.candidates
    capacity = pairs.shape[0]
    count = 0
    for a in range(n):
        nc = 0
        if grid.shape_big[a]:
            for b in range(a + 1, n):
                if _overlap(grid, a, b) and _may_collide(model, a, b):
                    cand[nc] = b
                    nc += 1
        else:
            ix0, iy0 = grid.shape_cells[a, 0], grid.shape_cells[a, 1]
            ix1, iy1 = grid.shape_cells[a, 2], grid.shape_cells[a, 3]
            for ix in range(ix0, ix1 + 1):
                for iy in range(iy0, iy1 + 1):
                    bk = _bucket(ix, iy, mask)
                    for k in range(grid.bucket_start[bk], grid.bucket_start[bk + 1]):
                        b = grid.entry_shape[k]
                        if b <= a or grid.entry_ix[k] != ix or grid.entry_iy[k] != iy:
                            continue
                        # report the pair only from the cell at max(min_a, min_b)
                        if ix != max(ix0, grid.shape_cells[b, 0]):
                            continue
                        if iy != max(iy0, grid.shape_cells[b, 1]):
                            continue
                        if _overlap(grid, a, b) and _may_collide(model, a, b):
                            cand[nc] = b
                            nc += 1
            for g in range(grid.big_count[0]):
                b = grid.big_list[g]
                if b > a and _overlap(grid, a, b) and _may_collide(model, a, b):
                    cand[nc] = b
                    nc += 1
        # insertion sort of this shape's partners (a handful): deterministic order
        for i in range(1, nc):
            key = cand[i]
            j = i - 1
            while j >= 0 and cand[j] > key:
                cand[j + 1] = cand[j]
                j -= 1
            cand[j + 1] = key
        for i in range(nc):
            if count < capacity:
                pairs[count, 0] = a
                pairs[count, 1] = cand[i]
            count += 1
    return count
