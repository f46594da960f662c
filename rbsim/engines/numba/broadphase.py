"""Broadphase: candidate shape pairs whose bounding boxes overlap, in O(N).

Every shape has a tight box (its geometry, radius and speculative reach) and a fat box
that contains it with AABB_MARGIN to spare. Pairs are found between fat boxes and kept
from step to step; only a shape whose tight box has left its fat box ("moved") is
queried again. A resting stack therefore costs one containment test per shape.

Queries use a loose uniform grid: each shape is entered once, in the cell that holds
its fat box's min corner, and a query looks at every cell where the min corner of an
overlapping box can lie, which the widest and tallest box in the grid bound. One entry
per shape keeps the fill cheap and finds each pair once per query. When the occupied
cells fit in a rectangle of at most as many cells as the table has buckets, each cell
is its own bucket, numbered row by row, so a query reads one run of entries per row
and needs no check that an entry is in the cell it looks at; otherwise (shapes far
apart) cells are hashed into the table. Shapes wider or taller than a cell (a long
ground, a very fast body) are "big": they are tested against every other shape
directly, cheap while they are few. When more than BIG_MAX shapes are that wide (a
fast gas), the cut is raised to 2, 4, ... cells until few are left above it.

Pairs are kept sorted by (shape a, shape b) with a < b, so the order is deterministic
and the contact stage matches them against the previous step in one merge pass.
Pairs within one body, and pairs where neither body is dynamic, are skipped.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ... import constants as C
from ...scene import types as T

CELL_SIZES = 4.0  # cell size in median half-diagonals (plus two fat margins)
TABLE_PER_SHAPE = 2  # hash table buckets per shape, at least
BIG_MAX = 16  # shapes made big (tested against every shape) while a wider cut allows
BIG_CELLS_MAX = 16.0  # a shape wider than this many cells is always big
RADIX_BITS = 8  # bits of a pair key sorted per radix pass (256 buckets)
INSERTION_SORT_MAX = 32  # fewer new pair keys than this are sorted by insertion


class Grid(NamedTuple):
    """Broadphase storage; S shapes, E = S entries, T table buckets, P pairs.

    inv_cell: 1 / cell size (1/m). shape_aabb (S,4) tight boxes min x, min y, max x,
    max y (m); shape_fat (S,4) fat boxes; shape_moved (S,) bool; shape_big (S,) bool;
    shape_cell (S,2) int64 cell ix, iy of a small shape's min corner; shape_bucket (S,)
    int64 its bucket. The small shapes' entries, sorted by bucket, copy what a pair
    test reads so that it reads memory in sequence: entry_shape (E,) int32; entry_cell
    (E,2) int64 cell ix, iy (hashed table only); entry_fat (E,4) the fat box (m);
    entry_tag (E,) int32 the body index if the body is dynamic, else -1 - body index.
    bucket_start (T+1,); big_list (S,) the big shapes in index order; span (2,) float64
    width and height (m) of the widest and tallest small fat box, padded up by a
    relative 1e-12 so that rounding cannot hide a pair; meta (7,) int64: [big shape
    count, 1 once the pairs are valid, 1 if the cells are their own buckets, then the
    first cell ix, iy and the rectangle's width and height in cells]; new_keys (P,)
    int64 and kept (P,2) int32: scratch for the pair update; sort_scratch (P,) int64
    and sort_count (2**RADIX_BITS + 1,) int64: scratch for sorting the new keys.
    """

    inv_cell: float
    shape_aabb: np.ndarray
    shape_fat: np.ndarray
    shape_moved: np.ndarray
    shape_big: np.ndarray
    shape_cell: np.ndarray
    shape_bucket: np.ndarray
    entry_shape: np.ndarray
    entry_cell: np.ndarray
    entry_fat: np.ndarray
    entry_tag: np.ndarray
    bucket_start: np.ndarray
    big_list: np.ndarray
    span: np.ndarray
    meta: np.ndarray
    new_keys: np.ndarray
    kept: np.ndarray
    sort_scratch: np.ndarray
    sort_count: np.ndarray


def make_grid(shape_size: np.ndarray, shape_is_dynamic: np.ndarray, capacity: int) -> Grid:
    """Preallocate the broadphase for S shapes and `capacity` pairs.

    The cell size is CELL_SIZES times the median half-diagonal (m) of the dynamic shapes
    plus twice the fat margin, so a typical fat box fits in one cell with room to spare
    (2 to 3 cells per axis per query); the table has at least TABLE_PER_SHAPE buckets per
    shape (2: measured a little faster to fill than 4, and as fast to query).
    """
    s = shape_size.shape[0]
    dyn = shape_size[shape_is_dynamic]
    size = CELL_SIZES * float(np.median(dyn)) if dyn.size else 1.0
    cell = max(size, 1e-3) + 2.0 * C.AABB_MARGIN
    table = 64
    while table < TABLE_PER_SHAPE * s:
        table *= 2
    e = max(s, 1)
    p = max(capacity, 1)
    return Grid(
        inv_cell=1.0 / cell,
        shape_aabb=np.zeros((s, 4)),
        shape_fat=np.zeros((s, 4)),
        shape_moved=np.zeros(s, np.bool_),
        shape_big=np.zeros(s, np.bool_),
        shape_cell=np.zeros((s, 2), np.int64),
        shape_bucket=np.zeros(s, np.int64),
        entry_shape=np.zeros(e, np.int32),
        entry_cell=np.zeros((e, 2), np.int64),
        entry_fat=np.zeros((e, 4)),
        entry_tag=np.zeros(e, np.int32),
        bucket_start=np.zeros(table + 1, np.int64),
        big_list=np.zeros(max(s, 1), np.int32),
        span=np.zeros(2),
        meta=np.zeros(7, np.int64),
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
def _fill_grid(model, grid):
    """Enter every small shape in the cell of its fat box's min corner (counting sort by
    bucket), with a copy of the shape data the pair tests read."""
    shape_body, body_type = model.shape_body, model.body_type
    g_big_list = grid.big_list
    g_entry_cell = grid.entry_cell
    g_entry_fat = grid.entry_fat
    g_entry_shape = grid.entry_shape
    g_entry_tag = grid.entry_tag
    g_meta = grid.meta
    g_shape_big = grid.shape_big
    g_shape_bucket = grid.shape_bucket
    g_shape_cell = grid.shape_cell
    g_shape_fat = grid.shape_fat
    g_span = grid.span
    n = g_shape_fat.shape[0]
    starts = grid.bucket_start
    table = starts.shape[0] - 1  # a power of two
    inv = grid.inv_cell
    cell = 1.0 / inv
    # the width (in cells) above which a shape is big: the smallest of 1, 2, 4, ...,
    # BIG_CELLS_MAX that leaves at most BIG_MAX shapes big. A few long walls or fast
    # bodies are cheaper tested against every shape; many wide ones (a fast gas whose
    # speculative reach spans more than a cell) are cheaper kept in the grid, where
    # they widen every query a little, than tested against every shape each
    cut = 1.0
    while cut < BIG_CELLS_MAX:
        over = 0
        for s in range(n):
            w = g_shape_fat[s, 2] - g_shape_fat[s, 0]
            h = g_shape_fat[s, 3] - g_shape_fat[s, 1]
            over += max(w, h) > cut * cell
        if over <= BIG_MAX:
            break
        cut *= 2.0
    nbig = 0
    wide = tall = 0.0
    gx0 = gy0 = np.int64(0)
    gx1 = gy1 = np.int64(-1)
    for s in range(n):
        w = g_shape_fat[s, 2] - g_shape_fat[s, 0]
        h = g_shape_fat[s, 3] - g_shape_fat[s, 1]
        big = max(w, h) > cut * cell
        g_shape_big[s] = big
        if big:
            g_big_list[nbig] = s
            nbig += 1
            continue
        wide, tall = max(wide, w), max(tall, h)
        ix = math.floor(g_shape_fat[s, 0] * inv)
        iy = math.floor(g_shape_fat[s, 1] * inv)
        g_shape_cell[s, 0], g_shape_cell[s, 1] = ix, iy
        if gx1 < gx0:
            gx0 = gx1 = ix
            gy0 = gy1 = iy
        gx0, gy0, gx1, gy1 = min(gx0, ix), min(gy0, iy), max(gx1, ix), max(gy1, iy)
    g_meta[0] = nbig
    g_span[0], g_span[1] = wide * (1.0 + 1e-12), tall * (1.0 + 1e-12)
    nx, ny = gx1 - gx0 + 1, gy1 - gy0 + 1
    dense = nx <= table and ny <= table and nx * ny <= table
    g_meta[2], g_meta[3], g_meta[4], g_meta[5], g_meta[6] = dense, gx0, gy0, nx, ny
    used = nx * ny if dense else table
    for b in range(used + 1):
        starts[b] = 0
    for s in range(n):
        if g_shape_big[s]:
            continue
        ix, iy = g_shape_cell[s, 0], g_shape_cell[s, 1]
        if dense:
            b = (ix - gx0) + nx * (iy - gy0)
        else:
            b = ((ix * 73856093) ^ (iy * 19349663)) & (table - 1)
        g_shape_bucket[s] = b
        starts[b] += 1
    # starts[b] becomes the end of bucket b; placing the shapes from the last one back
    # moves it down to the bucket's beginning, so no pass is needed to restore it
    for b in range(used - 1):
        starts[b + 1] += starts[b]
    starts[used] = n - nbig
    for s in range(n - 1, -1, -1):
        if g_shape_big[s]:
            continue
        b = g_shape_bucket[s]
        k = starts[b] - 1
        starts[b] = k
        body = shape_body[s]
        g_entry_shape[k] = s
        if not dense:
            g_entry_cell[k, 0], g_entry_cell[k, 1] = g_shape_cell[s, 0], g_shape_cell[s, 1]
        g_entry_fat[k, 0], g_entry_fat[k, 1] = g_shape_fat[s, 0], g_shape_fat[s, 1]
        g_entry_fat[k, 2], g_entry_fat[k, 3] = g_shape_fat[s, 2], g_shape_fat[s, 3]
        g_entry_tag[k] = body if body_type[body] == T.BODY_DYNAMIC else -1 - body


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
    entry_cell, entry_fat, entry_tag = grid.entry_cell, grid.entry_fat, grid.entry_tag
    fat, moved, big = grid.shape_fat, grid.shape_moved, grid.shape_big
    big_list, keys = grid.big_list, grid.new_keys
    wide, tall = grid.span[0], grid.span[1]
    g_meta = grid.meta
    n_big = g_meta[0]
    dense, gx0, gy0, nx, ny = g_meta[2] != 0, g_meta[3], g_meta[4], g_meta[5], g_meta[6]
    n = fat.shape[0]
    capacity = keys.shape[0]
    mask = bucket_start.shape[0] - 2
    inv = grid.inv_cell
    count = 0
    for a in range(n):
        if not moved[a]:
            continue
        body_a = shape_body[a]
        dyn_a = body_type[body_a] == T.BODY_DYNAMIC
        tag_a = body_a if dyn_a else -1 - body_a
        ax0, ay0, ax1, ay1 = fat[a, 0], fat[a, 1], fat[a, 2], fat[a, 3]
        # candidates: every shape for a big shape; else the grid cells, then big shapes
        n_cand = n if big[a] else n_big
        if big[a]:
            ix0, ix1, iy0, iy1 = 0, -1, 0, -1
        else:
            # a box overlapping a's has its min corner in [a's min - span, a's max]
            ix0, ix1 = math.floor((ax0 - wide) * inv), math.floor(ax1 * inv)
            iy0, iy1 = math.floor((ay0 - tall) * inv), math.floor(ay1 * inv)
            if dense:  # clip to the occupied rectangle; one run of entries per row
                ix0, ix1 = max(ix0, gx0), min(ix1, gx0 + nx - 1)
                iy0, iy1 = max(iy0, gy0), min(iy1, gy0 + ny - 1)
        for iy in range(iy0, iy1 + 1):
            # hashed: one bucket per cell; dense: a single pass reads the row's whole run
            for ix in range(ix0, ix1 + 1 if not dense else min(ix0, ix1) + 1):
                if dense:
                    row = (iy - gy0) * nx - gx0
                    k0, k1 = bucket_start[row + ix0], bucket_start[row + ix1 + 1]
                else:
                    bk = ((ix * 73856093) ^ (iy * 19349663)) & mask
                    k0, k1 = bucket_start[bk], bucket_start[bk + 1]
                for k in range(k0, k1):
                    if not dense and (entry_cell[k, 0] != ix or entry_cell[k, 1] != iy):
                        continue
                    if entry_fat[k, 0] > ax1 or ax0 > entry_fat[k, 2]:
                        continue
                    if entry_fat[k, 1] > ay1 or ay0 > entry_fat[k, 3]:
                        continue
                    # the same body, or neither body dynamic (both tags below zero)
                    if entry_tag[k] == tag_a or (tag_a & entry_tag[k]) < 0:
                        continue
                    b = entry_shape[k]
                    if b == a or (moved[b] and b < a):
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
            if body_b == body_a or not (dyn_a or body_type[body_b] == T.BODY_DYNAMIC):
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
    _fill_grid(model, grid)
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
