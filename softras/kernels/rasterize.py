"""Binning and coverage for the compiled path.

Mirrors `softras.pipeline.rasterize.rasterize` in gl precision: the integer
edge functions ``E_i = A_i (X - X0_i) + B_i (Y - Y0_i)`` of
`softras.pipeline.setup.edge_equations` with the fill rule, tested per sample,
and the same exact early-out / early-in test per 8x8 block (E is linear: its
extremes over a block are at the block's corner samples).  The tile kernel
(`softras.kernels.draw._tile`) walks the blocks; nothing here materialises a
fragment list.

Binning (`_bin`) has no readable counterpart: the visible triangles are
listed, in draw order, in every TILE x TILE tile their bounding box touches,
so a tile's pixels see their triangles in the pipeline's fragment order.
"""

from __future__ import annotations

import numba
import numpy as np

TILE = 64          # pixels per tile side (binning and the parallel unit)
BLOCK = 8          # pixels per block side (hierarchical coverage test)


@numba.njit(cache=True)
def _bin(visible, bbox, tiles_x, tiles_y):
    """Per-tile triangle lists in draw order: (bin_start (tiles + 1,), bin_tri (N,)),
    tile k's triangles at bin_tri[bin_start[k]:bin_start[k + 1]] (visible : the
    set-up triangles `softras.pipeline.setup.setup_triangles` keeps, bbox :
    their pixel boxes)."""
    counts = np.zeros(tiles_x * tiles_y + 1, np.int64)
    for v in range(visible.shape[0]):
        t = visible[v]
        for ty in range(bbox[t, 2] // TILE, bbox[t, 3] // TILE + 1):
            for tx in range(bbox[t, 0] // TILE, bbox[t, 1] // TILE + 1):
                counts[ty * tiles_x + tx + 1] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    out = np.empty(start[-1], np.int64)
    for v in range(visible.shape[0]):
        t = visible[v]
        for ty in range(bbox[t, 2] // TILE, bbox[t, 3] // TILE + 1):
            for tx in range(bbox[t, 0] // TILE, bbox[t, 1] // TILE + 1):
                k = ty * tiles_x + tx
                out[fill[k]] = t
                fill[k] += 1
    return start, out


@numba.njit(cache=True, inline="always")
def _inside3(sx, sy, a0, b0, ex0, ey0, k0, a1, b1, ex1, ey1, k1, a2, b2, ex2, ey2, k2):
    """Whether sample (sx, sy) (1/256 px) is inside all three integer edge
    functions of `softras.pipeline.rasterize._raster_triangle` (k = 1 for an exclusive edge: e > 0,
    k = 0 for an inclusive one: e >= 0)."""
    return ((a0 * (sx - ex0) + b0 * (sy - ey0) - k0) | (a1 * (sx - ex1) + b1 * (sy - ey1) - k1)
            | (a2 * (sx - ex2) + b2 * (sy - ey2) - k2)) >= 0


@numba.njit(cache=True, inline="always")
def _edge_range(a, b, ex, ey, x_lo, x_hi, y_lo, y_hi):
    """(min, max) of the integer edge function a (x - ex) + b (y - ey) over a
    rectangle's corners: the early-out / early-in values of
    `softras.pipeline.rasterize._raster_triangle`'s block test."""
    e00 = a * (x_lo - ex) + b * (y_lo - ey)
    e10 = a * (x_hi - ex) + b * (y_lo - ey)
    e01 = a * (x_lo - ex) + b * (y_hi - ey)
    e11 = a * (x_hi - ex) + b * (y_hi - ey)
    return min(min(e00, e10), min(e01, e11)), max(max(e00, e10), max(e01, e11))
