"""Broadphase: candidate shape pairs whose bounding boxes overlap, in O(N).

Every shape has a tight box (its geometry, radius and speculative reach) and a fat box
that contains it with AABB_MARGIN to spare. Pairs are found between fat boxes and kept
from step to step; only a shape whose tight box has left its fat box ("moved") is
queried again. A resting stack therefore costs one containment test per shape.

Queries use a uniform grid hashed into a table. Each shape is entered in every cell
its fat box touches (at most MAX_CELLS); a pair sharing several cells is reported only
from the cell that holds the corner max(min_a, min_b), so no pair is found twice.
Shapes whose box spans more cells than that (a long ground, a very fast body) are
"big": they are tested against every other shape directly, cheap while they are few.

Pairs are kept sorted by (shape a, shape b) with a < b, so the order is deterministic
and the contact stage matches them against the previous step in one merge pass.
Pairs within one body, and pairs where neither body is dynamic, are skipped.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import constants as C

MAX_CELLS = 16  # cells a shape may touch before it is treated as big
RADIX_BITS = 8  # bits of a pair key sorted per radix pass (256 buckets)
INSERTION_SORT_MAX = 32  # fewer new pair keys than this are sorted by insertion


class Grid(NamedTuple):
    """Broadphase storage; S shapes, E = MAX_CELLS·S entries, T table buckets, P pairs.

    inv_cell: 1 / cell size (1/m). shape_aabb (S,4) tight boxes min x, min y, max x,
    max y (m); shape_fat (S,4) fat boxes; shape_moved (S,) bool; shape_cells (S,4)
    int64 cell range of the fat box ix0, iy0, ix1, iy1; shape_big (S,) bool;
    entry_shape, entry_ix, entry_iy (E,) sorted by bucket; entry_bucket (E,) scratch;
    bucket_start (T+1,); big_list (S,) the big shapes in index order; meta (2,) int64:
    [big shape count, 1 once the pairs are valid]; new_keys (P,) int64 and
    kept (P,2) int32: scratch for the pair update; sort_scratch (P,) int64 and
    sort_count (2**RADIX_BITS + 1,) int64: scratch for sorting the new keys.
    """

    inv_cell: float
    shape_aabb: np.ndarray
    shape_fat: np.ndarray
    shape_moved: np.ndarray
    shape_cells: np.ndarray
    shape_big: np.ndarray
    entry_shape: np.ndarray
    entry_ix: np.ndarray
    entry_iy: np.ndarray
    entry_bucket: np.ndarray
    bucket_start: np.ndarray
    big_list: np.ndarray
    meta: np.ndarray
    new_keys: np.ndarray
    kept: np.ndarray
    sort_scratch: np.ndarray
    sort_count: np.ndarray


def make_grid(shape_size: np.ndarray, shape_is_dynamic: np.ndarray, capacity: int) -> Grid:
    """Preallocate the broadphase for S shapes and `capacity` pairs.

    The cell size is four times the median half-diagonal (m) of the dynamic shapes plus the
    fat margin, so a typical shape touches 1 to 4 cells.
    """
    s = shape_size.shape[0]
    dyn = shape_size[shape_is_dynamic]
    size = 4.0 * float(np.median(dyn)) if dyn.size else 1.0
    cell = max(size, 1e-3) + 2.0 * C.AABB_MARGIN
    table = 64
    while table < 4 * s:
        table *= 2
    e = MAX_CELLS * max(s, 1)
    p = max(capacity, 1)
    return Grid(
        inv_cell=1.0 / cell,
        shape_aabb=np.zeros((s, 4)),
        shape_fat=np.zeros((s, 4)),
        shape_moved=np.zeros(s, np.bool_),
        shape_cells=np.zeros((s, 4), np.int64),
        shape_big=np.zeros(s, np.bool_),
        entry_shape=np.zeros(e, np.int32),
        entry_ix=np.zeros(e, np.int64),
        entry_iy=np.zeros(e, np.int64),
        entry_bucket=np.zeros(e, np.int64),
        bucket_start=np.zeros(table + 1, np.int64),
        big_list=np.zeros(max(s, 1), np.int32),
        meta=np.zeros(2, np.int64),
        new_keys=np.zeros(p, np.int64),
        kept=np.zeros((p, 2), np.int32),
        sort_scratch=np.zeros(p, np.int64),
        sort_count=np.zeros((1 << RADIX_BITS) + 1, np.int64),
    )


def grow_grid(old: Grid, capacity: int) -> Grid:
    """The same grid with room for `capacity` pairs; the pairs are found anew."""
    p = max(capacity, 1)
    grid = old._replace(
        new_keys=np.zeros(p, np.int64),
        kept=np.zeros((p, 2), np.int32),
        sort_scratch=np.zeros(p, np.int64),
    )
    grid.meta[1] = 0
    return grid


@njit(cache=True, _nrt=False)
def update_aabbs(model, grid, vert_world, shape_margin):
    """Tight boxes from world vertices, radius and speculative reach (m); fat boxes for
    the shapes whose tight box left theirs. Returns how many shapes moved."""
    m_shape_body = model.shape_body
    m_shape_radius = model.shape_radius
    m_shape_vcount = model.shape_vcount
    m_shape_vstart = model.shape_vstart
    g_meta = grid.meta
    g_shape_moved = grid.shape_moved
    reach = 0.5 * C.SPECULATIVE_DISTANCE
    fresh = g_meta[1] == 0
    box, fat = grid.shape_aabb, grid.shape_fat
    moved = 0
    for s in range(m_shape_body.shape[0]):
        start, count = m_shape_vstart[s], m_shape_vcount[s]
        x0, y0 = vert_world[start, 0], vert_world[start, 1]
        x1, y1 = x0, y0
        for k in range(start + 1, start + count):
            px, py = vert_world[k, 0], vert_world[k, 1]
            x0, y0, x1, y1 = min(x0, px), min(y0, py), max(x1, px), max(y1, py)
        r = m_shape_radius[s] + shape_margin[s] + reach
        x0, y0, x1, y1 = x0 - r, y0 - r, x1 + r, y1 + r
        box[s, 0], box[s, 1], box[s, 2], box[s, 3] = x0, y0, x1, y1
        out = fresh or x0 < fat[s, 0] or y0 < fat[s, 1] or x1 > fat[s, 2] or y1 > fat[s, 3]
        g_shape_moved[s] = out
        if out:
            m = C.AABB_MARGIN
            fat[s, 0], fat[s, 1], fat[s, 2], fat[s, 3] = x0 - m, y0 - m, x1 + m, y1 + m
            moved += 1
    return moved


@njit(cache=True, _nrt=False)
def _fill_grid(grid):
    """Enter every small shape's fat box into the cells it touches (counting sort)."""
    g_big_list = grid.big_list
    g_bucket_start = grid.bucket_start
    g_entry_bucket = grid.entry_bucket
    g_entry_ix = grid.entry_ix
    g_entry_iy = grid.entry_iy
    g_entry_shape = grid.entry_shape
    g_meta = grid.meta
    g_shape_big = grid.shape_big
    g_shape_cells = grid.shape_cells
    g_shape_fat = grid.shape_fat
    n = g_shape_fat.shape[0]
    mask = g_bucket_start.shape[0] - 2  # table size - 1 (a power of two minus one)
    inv = grid.inv_cell
    starts = g_bucket_start
    starts[:] = 0
    e = 0
    nbig = 0
    for s in range(n):
        ix0 = math.floor(g_shape_fat[s, 0] * inv)
        iy0 = math.floor(g_shape_fat[s, 1] * inv)
        ix1 = math.floor(g_shape_fat[s, 2] * inv)
        iy1 = math.floor(g_shape_fat[s, 3] * inv)
        big = (ix1 - ix0 + 1) * (iy1 - iy0 + 1) > MAX_CELLS
        g_shape_big[s] = big
        g_shape_cells[s, 0], g_shape_cells[s, 1] = ix0, iy0
        g_shape_cells[s, 2], g_shape_cells[s, 3] = ix1, iy1
        if big:
            g_big_list[nbig] = s
            nbig += 1
            continue
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                b = ((ix * 73856093) ^ (iy * 19349663)) & mask
                g_entry_bucket[e] = b
                starts[b + 1] += 1
                e += 1
    g_meta[0] = nbig
    for b in range(mask + 1):
        starts[b + 1] += starts[b]
    # place entries; `starts[b]` walks forward and is restored afterwards
    e = 0
    for s in range(n):
        if g_shape_big[s]:
            continue
        ix0, iy0 = g_shape_cells[s, 0], g_shape_cells[s, 1]
        ix1, iy1 = g_shape_cells[s, 2], g_shape_cells[s, 3]
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                b = g_entry_bucket[e]
                k = starts[b]
                g_entry_shape[k] = s
                g_entry_ix[k] = ix
                g_entry_iy[k] = iy
                starts[b] = k + 1
                e += 1
    for b in range(mask, 0, -1):
        starts[b] = starts[b - 1]
    starts[0] = 0


@njit(cache=True, _nrt=False)
def _query_moved(model, grid):
    """Keys a·S + b of the pairs that involve a moved shape, unsorted; returns the count
    (which may exceed the key storage: the caller then grows it).

    A pair is recorded by a's query, except when b moved too and comes first (then b's
    query records it). The tests are written out in the loops: this is the hottest
    loop of a falling pile.
    """
    shape_body, body_type = model.shape_body, model.body_type
    bucket_start, entry_shape = grid.bucket_start, grid.entry_shape
    entry_ix, entry_iy = grid.entry_ix, grid.entry_iy
    fat, moved, big = grid.shape_fat, grid.shape_moved, grid.shape_big
    cells, big_list, keys = grid.shape_cells, grid.big_list, grid.new_keys
    n_big = grid.meta[0]
    n = fat.shape[0]
    capacity = keys.shape[0]
    mask = bucket_start.shape[0] - 2
    count = 0
    for a in range(n):
        if not moved[a]:
            continue
        body_a = shape_body[a]
        dyn_a = body_type[body_a] == C.BODY_DYNAMIC
        ax0, ay0, ax1, ay1 = fat[a, 0], fat[a, 1], fat[a, 2], fat[a, 3]
        ix0, iy0, ix1, iy1 = cells[a, 0], cells[a, 1], cells[a, 2], cells[a, 3]
        # candidates: every shape for a big shape; else the grid cells, then big shapes
        n_cand = n if big[a] else n_big
        for ix in range(ix0, ix1 + 1):
            if big[a]:
                break
            for iy in range(iy0, iy1 + 1):
                bk = ((ix * 73856093) ^ (iy * 19349663)) & mask
                for k in range(bucket_start[bk], bucket_start[bk + 1]):
                    if entry_ix[k] != ix or entry_iy[k] != iy:
                        continue
                    b = entry_shape[k]
                    # report the pair only from the cell at max(min_a, min_b)
                    if ix != max(ix0, cells[b, 0]) or iy != max(iy0, cells[b, 1]):
                        continue
                    if b == a or (moved[b] and b < a):
                        continue
                    if fat[b, 0] > ax1 or ax0 > fat[b, 2] or fat[b, 1] > ay1 or ay0 > fat[b, 3]:
                        continue
                    body_b = shape_body[b]
                    if body_b == body_a or not (dyn_a or body_type[body_b] == C.BODY_DYNAMIC):
                        continue
                    if count < capacity:
                        keys[count] = np.int64(min(a, b)) * n + max(a, b)
                    count += 1
        for g in range(n_cand):
            b = g if big[a] else big_list[g]
            if b == a or (moved[b] and b < a):
                continue
            if fat[b, 0] > ax1 or ax0 > fat[b, 2] or fat[b, 1] > ay1 or ay0 > fat[b, 3]:
                continue
            body_b = shape_body[b]
            if body_b == body_a or not (dyn_a or body_type[body_b] == C.BODY_DYNAMIC):
                continue
            if count < capacity:
                keys[count] = np.int64(min(a, b)) * n + max(a, b)
            count += 1
    return count


@njit(cache=True, _nrt=False)
def _sort_prefix(keys, n, scratch, count):
    """Sort the non-negative keys[:n] in place (numba's own array sort needs the
    reference counting that these kernels are compiled without). A few keys by
    insertion; more by a least-significant-digit radix sort, RADIX_BITS per pass,
    through scratch (at least n long) and count (2**RADIX_BITS + 1): about 4 µs for
    the thousand or so keys of a moving pile, where a heapsort took 20."""
    if n <= INSERTION_SORT_MAX:
        for i in range(1, n):
            key = keys[i]
            j = i - 1
            while j >= 0 and keys[j] > key:
                keys[j + 1] = keys[j]
                j -= 1
            keys[j + 1] = key
        return
    top = keys[0]
    for i in range(1, n):
        top = max(top, keys[i])
    mask = (1 << RADIX_BITS) - 1
    src, dst = keys, scratch
    in_scratch = False
    shift = 0
    while (top >> shift) > 0:
        for d in range(mask + 2):
            count[d] = 0
        for i in range(n):
            count[((src[i] >> shift) & mask) + 1] += 1
        for d in range(mask + 1):
            count[d + 1] += count[d]
        for i in range(n):  # stable: keeps the order of the lower digits
            d = (src[i] >> shift) & mask
            dst[count[d]] = src[i]
            count[d] += 1
        src, dst = dst, src
        in_scratch = not in_scratch
        shift += RADIX_BITS
    if in_scratch:
        for i in range(n):
            keys[i] = scratch[i]


@njit(cache=True, _nrt=False)
def find_pairs(model, grid, vert_world, shape_margin, pairs, n_pairs):
    """Update the sorted pair list `pairs` (P,2) int32 holding n_pairs; return the new count.

    When more than P pairs exist, the count returned is the number needed (> P) and the
    list is invalid: the caller grows the storage and calls again.
    """
    g_kept = grid.kept
    g_meta = grid.meta
    g_new_keys = grid.new_keys
    g_shape_fat = grid.shape_fat
    g_shape_moved = grid.shape_moved
    if update_aabbs(model, grid, vert_world, shape_margin) == 0:
        return n_pairs
    fresh = g_meta[1] == 0
    g_meta[1] = 0  # invalid until this update completes
    _fill_grid(grid)
    n = g_shape_fat.shape[0]
    capacity = pairs.shape[0]
    # keep the old pairs between shapes that did not move (already sorted)
    kept = 0
    if not fresh:
        for p in range(n_pairs):
            a, b = pairs[p, 0], pairs[p, 1]
            if not (g_shape_moved[a] or g_shape_moved[b]):
                g_kept[kept, 0], g_kept[kept, 1] = a, b
                kept += 1
    n_new = _query_moved(model, grid)
    if kept + n_new > capacity:
        return kept + n_new
    _sort_prefix(g_new_keys, n_new, grid.sort_scratch, grid.sort_count)
    keys = g_new_keys
    # merge the two sorted lists
    i = j = out = 0
    while i < kept or j < n_new:
        take_kept = j >= n_new or (i < kept and np.int64(g_kept[i, 0]) * n + g_kept[i, 1] < keys[j])
        if take_kept:
            pairs[out, 0], pairs[out, 1] = g_kept[i, 0], g_kept[i, 1]
            i += 1
        else:
            pairs[out, 0], pairs[out, 1] = keys[j] // n, keys[j] % n
            j += 1
        out += 1
    g_meta[1] = 1
    return out
