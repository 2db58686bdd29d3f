"""Rasterize stage: edge-function coverage per sample -> fragments.

For every set-up triangle (see `softras.pipeline.setup`), every sample of every pixel in
its bounding box is tested against the three edge functions
``E_i = A_i (X - X0_i) + B_i (Y - Y0_i)`` in raster units: inside when every E_i > 0, or
E_i == 0 on an inclusive edge (the fill rule).  In gl precision the values
are int64 and exact; in exact precision they are float64.

The bounding box is walked in 8x8-pixel blocks.  A block whose corners are all
outside one edge is skipped (early-out); a block whose corners are all inside
every edge is accepted whole (early-in); the rest are tested sample by
sample.  Because E is linear, its extremes over a block are at the block's
corner samples, so both shortcuts are exact.

Output is a fragment buffer in triangle order (draw order): one fragment per
(triangle, pixel) with at least one covered sample.

    tri  : (F,) int64   index into the TriangleSetup arrays
    x, y : (F,) int32   pixel, window space (y up, row 0 = GL's bottom row)
    mask : (F,) uint32  bit s set when sample s is covered

Triangles are rasterized in parallel (numba prange) in two passes, count
then write, so the buffer is exact-sized and its order is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from softras.pipeline.setup import TriangleSetup

BLOCK = 8  # pixels per block side for the hierarchical test


@dataclass(frozen=True)
class Fragments:
    """Covered pixels in draw order (see the module docstring for the layout)."""

    tri: np.ndarray
    x: np.ndarray
    y: np.ndarray
    mask: np.ndarray

    def __len__(self) -> int:
        return len(self.tri)

    @classmethod
    def allocate(cls, counts: np.ndarray) -> tuple["Fragments", np.ndarray]:
        """Uninitialised buffers for primitives that cover ``counts`` (P,) pixels each.

        Returns (fragments, starts): primitive p writes its fragments at
        ``starts[p] : starts[p] + counts[p]`` (the write pass of the two-pass
        count-then-write scheme, shared by triangles and lines).
        """
        starts = np.zeros(len(counts), np.int64)
        np.cumsum(counts[:-1], out=starts[1:])
        total = int(counts.sum())
        return cls(np.empty(total, np.int64), np.empty(total, np.int32), np.empty(total, np.int32),
                   np.empty(total, np.uint32)), starts


@numba.njit(cache=True, inline="always")
def _inside(e, inclusive):
    return e > 0 or (e == 0 and inclusive)


@numba.njit(cache=True, inline="always")
def _edge(a, b, x0, y0, x, y):
    return a * (x - x0) + b * (y - y0)


@numba.njit(cache=True, inline="always")
def _sample_box(offsets):
    """The extreme sample offsets (S, 2) of a pixel, in raster units: (min x,
    max x, min y, max y), the corner samples of a block or a band of rows
    (also `softras.pipeline.lines`' and the kernels')."""
    return offsets[:, 0].min(), offsets[:, 0].max(), offsets[:, 1].min(), offsets[:, 1].max()


@numba.njit(cache=True)
def _raster_triangle(a, b, x0, y0, inclusive, bbox, offsets, unit, out_x, out_y, out_mask, start, write):
    """Cover one triangle; write fragments from index `start` when `write`.

    a, b, x0, y0 : (3,) edge functions; inclusive : (3,) bool; bbox : (4,) int64.
    Returns the number of fragments.
    """
    n_samples = offsets.shape[0]
    full_mask = np.uint32((1 << n_samples) - 1) if n_samples < 32 else np.uint32(0xFFFFFFFF)
    min_ox, max_ox, min_oy, max_oy = _sample_box(offsets)
    count = 0
    for by in range(bbox[2], bbox[3] + 1, BLOCK):
        by1 = min(by + BLOCK - 1, bbox[3])
        for bx in range(bbox[0], bbox[1] + 1, BLOCK):
            bx1 = min(bx + BLOCK - 1, bbox[1])
            # Extreme sample positions of this block, raster units.
            x_lo = bx * unit + min_ox
            x_hi = bx1 * unit + max_ox
            y_lo = by * unit + min_oy
            y_hi = by1 * unit + max_oy
            outside = False
            all_in = True
            for i in range(3):
                e00 = _edge(a[i], b[i], x0[i], y0[i], x_lo, y_lo)
                e10 = _edge(a[i], b[i], x0[i], y0[i], x_hi, y_lo)
                e01 = _edge(a[i], b[i], x0[i], y0[i], x_lo, y_hi)
                e11 = _edge(a[i], b[i], x0[i], y0[i], x_hi, y_hi)
                e_max = max(max(e00, e10), max(e01, e11))
                e_min = min(min(e00, e10), min(e01, e11))
                if not _inside(e_max, inclusive[i]):
                    outside = True
                    break
                if not _inside(e_min, inclusive[i]):
                    all_in = False
            if outside:
                continue
            for py in range(by, by1 + 1):
                for px in range(bx, bx1 + 1):
                    if all_in:
                        mask = full_mask
                    else:
                        mask = np.uint32(0)
                        for s in range(n_samples):
                            sx = px * unit + offsets[s, 0]
                            sy = py * unit + offsets[s, 1]
                            if (_inside(_edge(a[0], b[0], x0[0], y0[0], sx, sy), inclusive[0])
                                    and _inside(_edge(a[1], b[1], x0[1], y0[1], sx, sy), inclusive[1])
                                    and _inside(_edge(a[2], b[2], x0[2], y0[2], sx, sy), inclusive[2])):
                                mask |= np.uint32(1) << np.uint32(s)
                    if mask != 0:
                        if write:
                            out_x[start + count] = px
                            out_y[start + count] = py
                            out_mask[start + count] = mask
                        count += 1
    return count


@numba.njit(cache=True, parallel=True)
def _cover(a, b, x0, y0, inclusive, bbox, offsets, unit, starts, out_x, out_y, out_mask, out_tri, write):
    """Every triangle's coverage (`_raster_triangle`), triangles in parallel:
    counted (write False; the out arrays may be empty) or written from
    ``starts`` (write True).  Returns (T,) int64 fragments per triangle.
    One kernel for both passes, so numba compiles it and `_raster_triangle`
    once (a pass each compiled `_raster_triangle` twice: 7 s of a cold start)."""
    n = a.shape[0]
    counts = np.zeros(n, np.int64)
    for t in numba.prange(n):
        start = starts[t] if write else 0
        k = _raster_triangle(a[t], b[t], x0[t], y0[t], inclusive[t], bbox[t], offsets, unit,
                             out_x, out_y, out_mask, start, write)
        counts[t] = k
        if write:
            for j in range(start, start + k):
                out_tri[j] = t
    return counts


def rasterize(setup: TriangleSetup, offsets: np.ndarray, unit: float) -> Fragments:
    """Cover the set-up triangles; return their fragments in draw order.

    offsets : (S, 2) sample offsets in raster units (S <= 32), from
    `softras.pipeline.setup.sample_offsets`; unit : raster units per pixel.
    """
    if len(offsets) > 32:
        raise ValueError("at most 32 samples per pixel per pass")
    if len(setup) == 0:
        return Fragments.allocate(np.zeros(0, np.int64))[0]
    # Raster values are int64 (gl) or float64 (exact); offsets match them.
    dtype = setup.edge_a.dtype
    args = (np.ascontiguousarray(setup.edge_a), np.ascontiguousarray(setup.edge_b, dtype),
            np.ascontiguousarray(setup.edge_x0, dtype), np.ascontiguousarray(setup.edge_y0, dtype),
            np.ascontiguousarray(setup.edge_inclusive),
            np.ascontiguousarray(setup.bbox), np.ascontiguousarray(offsets, dtype),
            int(unit) if dtype.kind == "i" else float(unit))
    empty, none = Fragments.allocate(np.zeros(0, np.int64))      # (the count pass writes nothing)
    frags, starts = Fragments.allocate(_cover(*args, none, empty.x, empty.y, empty.mask, empty.tri, False))
    _cover(*args, starts, frags.x, frags.y, frags.mask, frags.tri, True)
    return frags
