"""A small draw's front end in one compiled call: vertices, clipping, set-up
and binning.

`softras.kernels.draw.set_up_triangles` takes a draw through four compiled
steps: its vertices to clip space (`softras.pipeline.vertex.to_clip`, gl),
the clipped triangle list (`softras.pipeline.clip.triangle_list_gl`), their
set-up with binning's first pass (`softras.kernels.setup._setup`) and
binning's second (`softras.kernels.rasterize._fill_bins`).  Each call into compiled code costs
~65 ns per array it is handed and ~150 ns per array it returns, besides
the Python around it: a draw of 128 triangles spent ~14 us in the four
steps, half of it there (docs/speed.md, "Forty-fourth round").  A draw
that needs no parallel set-up (fewer than
`softras.kernels.setup.PARALLEL_SETUP` mesh triangles) whose vertex
values need no lighting takes `_front_end` instead: the same functions,
called from one compiled function, the same bits.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.rasterize import _fill_bins
from softras.kernels.setup import _setup_range, _window_vertices
from softras.kernels.stamp import sources_stamp
from softras.pipeline import clip as clip_stage
from softras.pipeline import vertex


def _make_front_end(sources: str):
    """`_front_end`, cached with the stamp of this folder's and the vertex
    and clip stages' sources as a closure variable (`softras.kernels.stamp`:
    it calls their compiled code, and numba's cache would check this file
    alone).  sources : in the cache key only."""

    @numba.njit(cache=True, error_model="numpy")
    def front_end(positions, mvp, indices, width, height, cull, box, vertex_values, tris, window, tiles_x,
                  tiles_y):
        """One triangle draw's vertices to clip space (`softras.pipeline.vertex._transform`
        of positions (V, 3) and mvp (4, 4), both float32: gl precision's
        `softras.pipeline.vertex.to_clip`), its clipped triangle list
        (`softras.pipeline.clip.triangle_list_gl` of indices (T, 3) int64),
        their set-up into the rows of tris (the `softras.kernels.setup.Triangles`
        as a plain tuple, with room for T or more; `softras.kernels.setup._setup`
        serially, the window corners in window = (vertex_f (V, 4) float64,
        vertex_i (V, 2) int64), the sample box and vertex values as there) and their
        binning into tiles_x x tiles_y tiles (`softras.kernels.setup._setup_range`'s
        listing and counting, `softras.kernels.rasterize._fill_bins`).

        Returns (n, source, visible, bin_start, bin_tri, pixels): n clipped
        triangles, source (n,) the mesh triangle of each (for flat shading),
        and the binned lists (`softras.kernels.rasterize.Bins`).  When tris has fewer than n rows (clipping made
        fans) nothing is set up and the lists are empty: the caller asks
        again with room for n."""
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        clip_pos = vertex._transform(positions, mvp)
        source, slot, fan_clip, fan_weights = clip_stage.triangle_list_gl(clip_pos, indices)
        n = source.shape[0]
        if n > tris[0].shape[0]:
            return n, source, source[:0], source[:1], source[:0], 0
        vertex_f, vertex_i = window
        _window_vertices(clip_pos, width, height, vertex_f, vertex_i)
        # (The first row as an int64, not the literal 0, which numba would
        # compile `_setup_range` again for: the types of `_setup`'s calls.)
        listed = np.empty(n, np.int64)
        counts = np.zeros(tiles_x * tiles_y + 1, np.int64)
        n_visible, pixels = _setup_range(np.int64(0), n, window, (indices, source, slot, fan_clip, fan_weights),
                                         width, height, cull, box, vertex_values, tris, (listed, counts, tiles_x))
        visible = listed[:n_visible]
        bin_start, bin_tri = _fill_bins(visible, tris[2], tiles_x, counts)
        return n, source, visible, bin_start, bin_tri, pixels

    return front_end


_front_end = _make_front_end(sources_stamp(vertex, clip_stage))
