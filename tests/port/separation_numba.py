"""The numba kernels of the penetration ruler that rbsim.core.min_separation (C++,
cpp/src/tools/separation.cpp) was ported from; tests/port/test_separation_port.py holds
the two against each other. Moved here unchanged from rbsim/reference.py when the tools
switched to the C++ ruler."""

import numpy as np
from numba import njit


@njit(cache=True)
def core_separation(verts, sa, na, sb, nb):
    """Largest separation (m) of core b's vertices along the outward edge normals of core
    a (a polygon, or a segment with both of its normals)."""
    best = -np.inf
    edges = na if na > 2 else 1
    signs = 2 if na == 2 else 1
    for k in range(edges):
        ax, ay = verts[sa + k, 0], verts[sa + k, 1]
        bx, by = verts[sa + (k + 1) % na, 0], verts[sa + (k + 1) % na, 1]
        ex, ey = bx - ax, by - ay
        length = np.sqrt(ex * ex + ey * ey)
        for si in range(signs):
            sign = 1.0 - 2.0 * si
            nx, ny = sign * ey / length, -sign * ex / length
            low = np.inf
            for j in range(nb):
                d = (verts[sb + j, 0] - ax) * nx + (verts[sb + j, 1] - ay) * ny
                low = min(low, d)
            best = max(best, low)
    return best


@njit(cache=True)
def point_core_distance(verts, c, sa, na):
    """Signed distance (m) from vertex c to core a (a polygon or a segment): the distance
    to the nearest edge outside a polygon, minus the depth of the nearest face inside."""
    inside = na > 2 and core_separation(verts, sa, na, c, 1) <= 0.0
    if inside:
        return core_separation(verts, sa, na, c, 1)
    best = np.inf
    edges = na if na > 2 else 1
    px, py = verts[c, 0], verts[c, 1]
    for k in range(edges):
        ax, ay = verts[sa + k, 0], verts[sa + k, 1]
        ex = verts[sa + (k + 1) % na, 0] - ax
        ey = verts[sa + (k + 1) % na, 1] - ay
        s = ((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey)
        s = min(max(s, 0.0), 1.0)
        dx, dy = px - ax - s * ex, py - ay - s * ey
        best = min(best, np.sqrt(dx * dx + dy * dy))
    return best


@njit(cache=True)
def min_separation(verts, vstart, vcount, radius, pairs):
    """Smallest separation (m) over the pairs of shapes: the signed distance of their
    cores (SAT for two polygons or segments, exact for a circle centre), minus both
    radii."""
    worst = np.inf
    for p in range(pairs.shape[0]):
        a, b = pairs[p, 0], pairs[p, 1]
        sa, na, sb, nb = vstart[a], vcount[a], vstart[b], vcount[b]
        if na == 1 and nb == 1:
            dx = verts[sb, 0] - verts[sa, 0]
            dy = verts[sb, 1] - verts[sa, 1]
            sep = np.sqrt(dx * dx + dy * dy)
        elif na == 1:
            sep = point_core_distance(verts, sa, sb, nb)
        elif nb == 1:
            sep = point_core_distance(verts, sb, sa, na)
        else:
            sep = max(
                core_separation(verts, sa, na, sb, nb), core_separation(verts, sb, nb, sa, na)
            )
        worst = min(worst, sep - radius[a] - radius[b])
    return worst
