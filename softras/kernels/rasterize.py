"""Binning and coverage for the compiled path.

Mirrors `softras.pipeline.rasterize.rasterize` in gl precision: the integer
edge functions ``E_i = A_i (X - X0_i) + B_i (Y - Y0_i)`` of
`softras.pipeline.setup.edge_equations` with the fill rule, tested per sample,
and the same exact early-out / early-in test per 8x8 block (E is linear: its
extremes over a block are at the block's corner samples).  The tile kernels
(`softras.kernels.draw._flat_tile`, `_textured_tile`) walk the blocks, or,
untextured at one sample a pixel, the rows; at one sample a row's covered
pixels are found by exact integer division (`_row_run`: `_list_row` lists
them, `_list_quads` masks a partly covered block's quads with them);
nothing here materialises a fragment list.

Binning has no readable counterpart: the visible triangles are listed,
in draw order, in every TILE x TILE tile their bounding box touches
(counted by the set-up's pass, `softras.kernels.setup._setup_range`,
filled by `_fill_bins`), so a tile's pixels see their triangles in the
pipeline's fragment order.
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.lanes import _LF_CX, _LF_CY, _LI_COV, _LI_PX, _LI_PY, LANES
from softras.kernels.setup import _I_A, _I_B, _I_INC, _I_X0, _I_Y0, TILE

BLOCK = 8          # pixels per block side (hierarchical coverage test)

# One integer edge function of `softras.pipeline.setup.edge_equations`,
# E(x, y) = a (x - x0) + b (y - y0) in raster units (1/256 pixel), and its
# fill rule as a bias: 0 for an inclusive edge (inside: E >= 0), 1 for an
# exclusive one (inside: E > 0, that is E - 1 >= 0).  Records of scalars
# cost nothing in the compiled code (numba passes them as values; no
# reference counts).
Edge = namedtuple("Edge", ["a", "b", "x0", "y0", "bias"])

# A triangle's three `Edge`s (`_edges`).  A record, read by attribute: a
# plain tuple of records, unpacked, trips numba's array analysis in the
# parallel tile driver (it takes a tuple of integer tuples for an array
# shape: "Dimension mismatch").
Edges = namedtuple("Edges", ["e0", "e1", "e2"])

# A draw's binned triangles (`_fill_bins`): tile k's at tri[start[k]:start[k + 1]],
# tiles_x tiles per row.
Bins = namedtuple("Bins", ["start", "tri", "tiles_x"])


@numba.njit(cache=True)
def _fill_bins(visible, bbox, tiles_x, counts):
    """Binning's second pass (the first, `softras.kernels.setup._setup_range`,
    lists the visible set-up triangles and counts the TILE x TILE tiles
    their pixel boxes touch): the visible triangles (K,) in draw order
    into the lists of their tiles, from the tiles' counts (tiles + 1,
    tile k's at k + 1).  Returns bin_start (tiles + 1,) and bin_tri (N,):
    tile k's triangles at bin_tri[bin_start[k]:bin_start[k + 1]], in draw
    order, so a tile's pixels see their triangles in the pipeline's
    fragment order.

    A mesh's triangles come in runs within one tile (neighbours in the
    mesh's order): the next place in the run's tile is held in a register
    (``run_at``) and stored back when the run ends, instead of each
    triangle's place waiting on the store of the one before it (the 100k
    grid's binning 0.50 -> 0.22 ms on one thread; docs/speed.md,
    "Forty-ninth round")."""
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    out = np.empty(start[-1], np.int64)
    run_k, run_at = -1, 0                   # the run's tile (-1: none) and its next place
    for v in range(visible.shape[0]):
        t = visible[v]
        tx0, tx1, ty0, ty1 = bbox[t, 0] // TILE, bbox[t, 1] // TILE, bbox[t, 2] // TILE, bbox[t, 3] // TILE
        if tx0 == tx1 and ty0 == ty1:       # (in one tile: the run's, or the start of another)
            k = ty0 * tiles_x + tx0
            if k != run_k:
                if run_k >= 0:
                    fill[run_k] = run_at
                run_k, run_at = k, fill[k]
            out[run_at] = t
            run_at += 1
            continue
        if run_k >= 0:                      # (a triangle across tiles ends the run)
            fill[run_k] = run_at
            run_k = -1
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                k = ty * tiles_x + tx
                out[fill[k]] = t
                fill[k] += 1
    return start, out


@numba.njit(cache=True, inline="always")
def _edges(tri_i, t):
    """Set-up triangle t's `Edges` (its tri_i row, `softras.kernels.setup`):
    `softras.pipeline.setup.setup_triangles`' edge_a, edge_b, edge_x0,
    edge_y0 and edge_inclusive."""
    return Edges(Edge(tri_i[t, _I_A], tri_i[t, _I_B], tri_i[t, _I_X0], tri_i[t, _I_Y0], 1 - tri_i[t, _I_INC]),
                 Edge(tri_i[t, _I_A + 1], tri_i[t, _I_B + 1], tri_i[t, _I_X0 + 1], tri_i[t, _I_Y0 + 1],
                      1 - tri_i[t, _I_INC + 1]),
                 Edge(tri_i[t, _I_A + 2], tri_i[t, _I_B + 2], tri_i[t, _I_X0 + 2], tri_i[t, _I_Y0 + 2],
                      1 - tri_i[t, _I_INC + 2]))


@numba.njit(cache=True, inline="always")
def _edge_at(e, x, y):
    """E(x, y) - bias of `Edge` e at raster point (x, y): >= 0 exactly where
    `softras.pipeline.rasterize._inside` of `softras.pipeline.rasterize._edge`
    holds."""
    return e.a * (x - e.x0) + e.b * (y - e.y0) - e.bias


@numba.njit(cache=True, inline="always")
def _inside3(sx, sy, edges):
    """Whether sample (sx, sy) (1/256 px) is inside all three `Edges` of
    `softras.pipeline.rasterize._raster_triangle`'s per-sample test."""
    return (_edge_at(edges.e0, sx, sy) | _edge_at(edges.e1, sx, sy) | _edge_at(edges.e2, sx, sy)) >= 0


@numba.njit(cache=True, inline="always")
def _edge_range(e, x_lo, x_hi, y_lo, y_hi):
    """(min, max) of `Edge` e's function a (x - x0) + b (y - y0) over a
    rectangle's corners: the early-out / early-in values of
    `softras.pipeline.rasterize._raster_triangle`'s block test."""
    e00 = e.a * (x_lo - e.x0) + e.b * (y_lo - e.y0)
    e10 = e.a * (x_hi - e.x0) + e.b * (y_lo - e.y0)
    e01 = e.a * (x_lo - e.x0) + e.b * (y_hi - e.y0)
    e11 = e.a * (x_hi - e.x0) + e.b * (y_hi - e.y0)
    return min(min(e00, e10), min(e01, e11)), max(max(e00, e10), max(e01, e11))


@numba.njit(cache=True, inline="always")
def _block_test(edges, x_lo, x_hi, y_lo, y_hi):
    """`softras.pipeline.rasterize._raster_triangle`'s exact block test for the
    block whose extreme sample positions span x_lo..x_hi, y_lo..y_hi (raster
    units): (outside, all_in): every sample is outside one edge (skip the
    block), or every sample is inside all three (no per-sample tests)."""
    e_min0, e_max0 = _edge_range(edges.e0, x_lo, x_hi, y_lo, y_hi)
    e_min1, e_max1 = _edge_range(edges.e1, x_lo, x_hi, y_lo, y_hi)
    e_min2, e_max2 = _edge_range(edges.e2, x_lo, x_hi, y_lo, y_hi)
    outside = ((e_max0 - edges.e0.bias) | (e_max1 - edges.e1.bias) | (e_max2 - edges.e2.bias)) < 0
    all_in = ((e_min0 - edges.e0.bias) | (e_min1 - edges.e1.bias) | (e_min2 - edges.e2.bias)) >= 0
    return outside, all_in


# ----------------------------------------------------------------------------- a block's lanes
#
# What `softras.pipeline.rasterize._raster_triangle` writes as fragments of
# one block, listed as lanes (`softras.kernels.lanes`) instead: pixel and
# coverage mask.  These take the lane arrays once per block (an array
# argument costs a reference count per call), never per pixel.


@numba.njit(cache=True, inline="always")
def _list_whole_block(n, bx, by, full_mask, lf, li):
    """The fragments of `softras.pipeline.rasterize._raster_triangle` for an
    8x8 block inside all three edges, starting at pixel (bx, by) (even: whole
    quads), as its 16 quads' lanes (4 lanes per quad, top-left, top-right,
    bottom-left, bottom-right in llvmpipe's view), every sample covered, no
    tests; the pixel centres too; appended as lanes from lane n on.
    Returns n + LANES."""
    for l in range(LANES):
        px = bx + ((l >> 2) & 3) * 2 + (l & 1)
        py = by + (l >> 4) * 2 + ((l >> 1) & 1)
        li[_LI_PX, n + l] = px
        li[_LI_PY, n + l] = py
        li[_LI_COV, n + l] = full_mask
        lf[_LF_CX, n + l] = px + 0.5
        lf[_LF_CY, n + l] = py + 0.5
    return n + LANES


@numba.njit(cache=True, inline="always")
def _list_quads(n, bx, bx1, by, by1, all_in, edges, offsets, full_mask, lf, li, n_samples):
    """The fragments of `softras.pipeline.rasterize._raster_triangle` in pixels
    bx..bx1 x by..by1 of one block, as the lanes of the 2x2 quads with a
    covered sample (4 lanes per quad; a lane outside the block or uncovered
    gets mask 0: a helper pixel); the pixel centres too.  all_in: the block
    test found every sample inside.  At one sample a partly covered block
    takes each row's run (`_row_run`, two per quad row) instead of testing
    every pixel (textured_phong_8k_1024 3-4 % faster on one thread), and
    looks only at the quads across the two runs (textured_parts_64x128_512
    5-7 % faster).
    Appended as lanes from lane n on; returns the new number of lanes."""
    runs = n_samples == 1 and not all_in
    for qy in range(by & -2, by1 + 1, 2):
        lo0 = hi0 = lo1 = hi1 = 0
        qx0, qx1 = bx & -2, bx1         # the quads' columns to look at
        if runs:                        # (the quad row's two rows, empty outside the block)
            lo0, hi0 = _row_run(bx, bx1, qy, edges, offsets) if qy >= by else (1, 0)
            lo1, hi1 = _row_run(bx, bx1, qy + 1, edges, offsets) if qy + 1 <= by1 else (1, 0)
            # Only the quads across the two runs: the others have no covered pixel.
            lo, hi = (min(lo0, lo1), max(hi0, hi1)) if lo0 <= hi0 and lo1 <= hi1 else \
                ((lo0, hi0) if lo0 <= hi0 else (lo1, hi1))
            qx0, qx1 = (bx + lo) & -2, bx + hi
        for qx in range(qx0, qx1 + 1, 2):
            quad_mask = 0
            for k in range(4):
                px = qx + (k & 1)
                py = qy + (k >> 1)
                mask = 0
                if runs:
                    mask = np.int64((lo0 <= px - bx <= hi0) if k < 2 else (lo1 <= px - bx <= hi1))
                elif bx <= px <= bx1 and by <= py <= by1:
                    mask = full_mask
                    if not all_in:
                        mask = 0
                        for s in range(n_samples):
                            if _inside3(px * 256 + offsets[s, 0], py * 256 + offsets[s, 1], edges):
                                mask |= 1 << s
                li[_LI_PX, n + k] = px
                li[_LI_PY, n + k] = py
                li[_LI_COV, n + k] = mask
                lf[_LF_CX, n + k] = px + 0.5
                lf[_LF_CY, n + k] = py + 0.5
                quad_mask |= mask
            if quad_mask:
                n += 4
    return n


@numba.njit(cache=True, inline="always")
def _span(r, step, lo, hi):
    """Pixels lo..hi of a row narrowed to those i where one edge's
    ``r + step i >= 0`` (r: `_edge_at` at pixel 0's sample, step: the edge's
    a * 256 per pixel; integers): the i of `_inside3`'s test of this edge,
    without testing each.  Floor division, exact: for step > 0 the first i
    is ceil(-r / step) = -(r // step), for step < 0 the last is
    floor(r / -step); a zero step keeps the row or empties it."""
    if step > 0:
        lo = max(lo, -(r // step))
    elif step < 0:
        hi = min(hi, r // (-step))
    elif r < 0:
        hi = lo - 1
    return lo, hi


@numba.njit(cache=True, inline="always")
def _row_run(x0, x1, py, edges, offsets, s=0):
    """The run of pixels of row py in x0..x1 whose sample s (offsets (S,
    2); at one sample a pixel, its one sample) `_inside3` finds inside all
    three edges, as (lo, hi) counted from x0 (empty: lo > hi; never outside
    0..x1 - x0).  A triangle covers one run of a row's samples (the three
    edges' half-planes are convex), and each edge bounds it by one exact
    division (`_span`)."""
    sx, sy = x0 * 256 + offsets[s, 0], py * 256 + offsets[s, 1]
    lo, hi = _span(_edge_at(edges.e0, sx, sy), edges.e0.a * 256, 0, x1 - x0)
    lo, hi = _span(_edge_at(edges.e1, sx, sy), edges.e1.a * 256, lo, hi)
    return _span(_edge_at(edges.e2, sx, sy), edges.e2.a * 256, lo, hi)


@numba.njit(cache=True, inline="always")
def _list_row(n, x0, x1, py, edges, offsets, li):
    """At one sample a pixel (offsets (1, 2)): the fragments of
    `softras.pipeline.rasterize._raster_triangle` in pixels x0..x1 of row py,
    appended as lanes from lane n on (coverage mask 1).  A triangle covers
    one run of a row's pixels (the three edges' half-planes are convex), so
    the run's ends come from each edge's `_span` and the pixels between are
    written in a loop LLVM vectorises: per row three divisions instead of
    an 8x8 block test and a branch-free test of every pixel of the block's
    rows (`_list_pixels`).  The same pixels, in row order rather than block
    by block.  Returns the new number of lanes (at most n + x1 - x0 + 1)."""
    lo, hi = _row_run(x0, x1, py, edges, offsets)
    for i in range(lo, hi + 1):
        li[_LI_PX, n + i - lo] = x0 + i
        li[_LI_PY, n + i - lo] = py
        li[_LI_COV, n + i - lo] = 1
    return n + max(hi - lo + 1, 0)


@numba.njit(cache=True, inline="always")
def _list_pixels(n, bx, bx1, by, by1, all_in, edges, offsets, full_mask, rows, li, n_samples):
    """The fragments of `softras.pipeline.rasterize._raster_triangle` in pixels
    bx..bx1 x by..by1 of one block, appended as lanes from lane n on: every
    pixel of the block's part of the box is written, the covered ones kept
    without a branch (which pixels a small triangle covers is unpredictable).
    rows (3, S): scratch for a row's edge functions per sample, evaluated at
    the row's first pixel (`_edge_at`) and stepped by a * 256 per pixel.
    Returns the new number of lanes."""
    step0, step1, step2 = edges.e0.a * 256, edges.e1.a * 256, edges.e2.a * 256     # edge steps per pixel
    for py in range(by, by1 + 1):
        if not all_in:
            for s in range(n_samples):
                sx = bx * 256 + offsets[s, 0]
                sy = py * 256 + offsets[s, 1]
                rows[0, s] = _edge_at(edges.e0, sx, sy)
                rows[1, s] = _edge_at(edges.e1, sx, sy)
                rows[2, s] = _edge_at(edges.e2, sx, sy)
        for i in range(bx1 - bx + 1):
            mask = full_mask
            if not all_in:
                mask = 0
                for s in range(n_samples):
                    inside = ((rows[0, s] + step0 * i) | (rows[1, s] + step1 * i)
                              | (rows[2, s] + step2 * i)) >= 0
                    mask |= np.int64(inside) << s
            li[_LI_PX, n] = bx + i
            li[_LI_PY, n] = py
            li[_LI_COV, n] = mask
            n += mask != 0
    return n


@numba.njit(error_model="numpy", inline="always")
def _tile_columns(tile, tiles_x, width):
    """The tile's first and last pixel column in a picture ``width`` wide."""
    tx0 = (tile % tiles_x) * TILE
    return tx0, min(tx0 + TILE, width) - 1


@numba.njit(error_model="numpy", inline="always")
def _tile_box(tile, tiles_x, bbox, t, depth):
    """Triangle t's pixel bounding box (its bbox row) within the tile: first
    and last column, first and last row."""
    height, width = depth.shape[0], depth.shape[1]
    tx0, tx1 = _tile_columns(tile, tiles_x, width)
    ty0 = (tile // tiles_x) * TILE
    return (max(bbox[t, 0], tx0), min(bbox[t, 1], tx1),
            max(bbox[t, 2], ty0), min(bbox[t, 3], min(ty0 + TILE, height) - 1))
