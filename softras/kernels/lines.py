"""Lines on the compiled path: a GL_LINES draw in one compiled loop.

Mirrors what `softras.pipeline.render.draw_lines` does with a line draw
in gl precision, operation for operation, line by line and without a
fragment list:

1. clip: `softras.pipeline.lines.clip_lines` (Mesa's do_clip_line in
   float32; the same `_plane_distances` and `_clip_line`);
2. viewport: `softras.pipeline.setup.viewport_transform`, fused for the
   shader's vertices and unfused for the clipper's
   (`softras.kernels.setup._window_corner`);
3. set-up: `softras.pipeline.lines.line_quads` (llvmpipe's
   try_setup_line, the same `_setup_line`);
4. coverage: `softras.pipeline.lines.rasterize_lines` (its
   `_raster_quad`'s rows and columns, `_binned_region`, `_row_span`,
   `_pixel_mask`), each covered pixel at once shaded and applied:
5. `softras.pipeline.lines.depth_at_samples` (depth at each sample, linear
   in the line's t) and `softras.pipeline.ops.quantize_depth`,
   `softras.pipeline.lines.interpolate_lines` (the colour, perspective-correct
   in the `_line_t` of the pixel) and `softras.pipeline.fragment.shade_unlit`
   as `softras.pipeline.ops.unorm8` converts it, then
   `softras.pipeline.ops.apply_fragments`' depth test, blend and write into
   the compiled path's byte framebuffer (`softras.kernels.ops`), or its
   float colour into an rgba32f buffer.

Two passes, each in a share a thread (`softras.kernels.pool.on_threads`):
the set-up by lines, then the coverage by bands of rows, where each
thread walks all the lines in order over its own rows, so every pixel
sees the lines in the stages' fragment order and blending and equal
depths resolve as there (docs/speed.md, "Lines").
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.interpolate import RGBA, _color_word
from softras.kernels.ops import _depth_k, _depth_pass_k, _write_floats, _write_word, holds_floats
from softras.kernels.pool import on_threads
from softras.kernels.scratch import _Scratch, read_only
from softras.kernels.setup import _window_corner
from softras.kernels.stamp import sources_stamp
from softras.kernels.threads import NoAliasCompiler, _aligned_stack, _unowned
from softras.pipeline import clip as clip_stage
from softras.pipeline import lines as lines_stage
from softras.pipeline import ops, vertex
from softras.pipeline import rasterize
from softras.pipeline.clip import _plane_distances
from softras.pipeline.lines import (FIXED_ONE, _binned_region, _clip_line, _end_values, _line_t, _pixel_mask,
                                    _quad_planes, _quad_rows, _row_span, _sample_t, _setup_line)
from softras.pipeline.rasterize import _sample_box
from softras.pipeline.render import vertex_colors


# A draw's lines after clipping and set-up, one row per input line
# (`_set_up_lines`): whether it is drawn, its quad's corners qx, qy (L, 4)
# in raster units, the pixels llvmpipe covers it over, region (L, 4) int64
# (x0, x1, y0, y1; `softras.pipeline.lines._binned_region`), the clipped
# end points' window x, y, z (L, 2, 3) float32 values and 1/w (L, 2), and
# their straight colours ends (L, 2, 4).
LineTable = namedtuple("LineTable", ["drawn", "qx", "qy", "region", "window", "inv_w", "ends"])

# Rows of pixels per band: thread r covers bands r, r + n_threads, ...
# (32 drew lines_8k_512 2-5 % faster than 64 in four alternated runs,
# 16 slower: docs/speed.md, "Forty-fifth round".)
BAND = 32


def draw_lines(scene, draw, fb, positions: np.ndarray) -> None:
    """One GL_LINES draw into the framebuffer `softras.kernels.ops.Framebuffer`
    fb (RGBA8 words, or rgba32f floats) at the sample positions (S, 2) in [0, 1), S <= 32 (GL's: S > 1
    draws llvmpipe's rectangular lines, `softras.pipeline.lines`)."""
    mesh = draw.mesh
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    clip_pos = vertex.to_clip(mesh.positions, mvp, "gl")
    c, finite, planes = lines_stage.clip_inputs(clip_pos, "gl", "llvmpipe", scene.width, scene.height)
    rectangular = len(positions) > 1
    offsets = lines_stage.sample_offsets(positions, rectangular, True)
    depth_func = ops.DEPTH_FUNCS[draw.depth_test]
    n = len(mesh.indices)
    table = LineTable(_scratch.take("drawn", (n,), np.bool_), _scratch.take("qx", (n, 4), np.float64),
                      _scratch.take("qy", (n, 4), np.float64), _scratch.take("region", (n, 4), np.int64),
                      _scratch.take("window", (n, 2, 3), np.float64), _scratch.take("inv_w", (n, 2), np.float64),
                      _scratch.take("ends", (n, 2, 4), np.float64))
    n_threads = numba.get_num_threads()
    indices, values = read_only(mesh.indices, np.int64), read_only(vertex_colors(mesh), np.float64)
    dist = _plane_distances(c, planes)
    on_threads(lambda r: _SET_UP_LINES(r, n_threads, c, dist, finite, indices, values, rectangular,
                                       scene.width, scene.height, *table), n_threads)
    material = read_only(draw.material.color, np.float64)
    positions = np.ascontiguousarray(positions, np.float64)
    shift = lines_stage.attribute_shift("gl", rectangular)
    write_z = bool(draw.depth_write) and depth_func != 0
    blend = ops.BLEND_MODES[draw.blend]
    rgba32f = holds_floats(fb)
    on_threads(lambda r: _COVER_LINES(r, n_threads, material, offsets, positions, rectangular, shift, fb.color32,
                                      fb.color_f, rgba32f, fb.depth, depth_func, write_z, blend, *table),
               n_threads)


_scratch = _Scratch()


def _make_line_passes(sources: str):
    """The line kernel's two passes, each one share of n_threads for
    `softras.kernels.pool.on_threads`: the set-up by lines
    (`_set_up_lines`: share r sets up the r-th run of them), then
    the coverage, shading and writes by bands of BAND rows (`_cover_lines`:
    bands r, r + n_threads, ...; a pixel is one share's, and it sees the
    lines in order).  Arguments as those two take them, the `LineTable`'s
    arrays one by one.  Compiled with ``sources`` (`softras.kernels.stamp`:
    the kernels' and the line stage's sources, whose functions they reach)
    in their cache key.

    Compiled as numba compiles a parallel loop's body (they were one until
    the forty-sixth round): ``noalias`` on their arrays
    (`softras.kernels.threads.NoAliasCompiler`), and the arrays handed on
    unowned (`softras.kernels.threads._unowned`), so that the views the
    helpers take of each line's rows are not reference-counted (1.28 ->
    0.72 ms for lines_8k_512's set-up on one thread).  The helpers are
    called, not inlined, as in `softras.kernels.exact_lines`: inlined into
    a parallel loop the kernel took 31 s to compile cold, called 17 s,
    drawing as fast."""

    @numba.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
    def set_up_pass(r, n_threads, c, dist, finite, indices, values, rectangular, width, height, drawn, qx, qy,
                    region, window, inv_w, ends):
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        _set_up_lines(r, n_threads, _unowned(c), _unowned(dist), _unowned(finite), _unowned(indices),
                      _unowned(values), rectangular, width, height, _unowned(drawn), _unowned(qx), _unowned(qy),
                      _unowned(region), _unowned(window), _unowned(inv_w), _unowned(ends))

    @numba.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
    def cover_pass(r, n_threads, material, offsets, positions, rectangular, shift, color32, color_f, rgba32f, depth,
                   depth_func, write_z, blend, drawn, qx, qy, region, window, inv_w, ends):
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        _cover_lines(r, n_threads, _unowned(material), _unowned(offsets), _unowned(positions), rectangular, shift,
                     _unowned(color32), _unowned(color_f), rgba32f, _unowned(depth), depth_func, write_z, blend,
                     LineTable(_unowned(drawn), _unowned(qx), _unowned(qy), _unowned(region), _unowned(window),
                               _unowned(inv_w), _unowned(ends)))

    return set_up_pass, cover_pass


@numba.njit(error_model="numpy")
def _set_up_lines(r, n_threads, c, dist, finite, indices, values, rectangular, width, height, drawn, qx, qy,
                  region, window, inv_w, ends):
    """`softras.pipeline.lines.rasterized_lines` up to the coverage, for
    share r of n_threads of the input lines (a run of them: interleaved,
    the shares wrote the same cache lines of the table, and the pass took
    1.2-1.3 ms on two threads in a render against 0.6-0.8 ms in runs)
    into their `LineTable` rows: clipped
    (`_clip_line`), the end points' window coordinates and 1/w
    (`_window_corner`), set up (`_setup_line`) and binned
    (`_binned_region`); drawn False for a line dropped on the way.

    c (N, 4) float32 clip positions, dist (N, 6) their plane distances
    (`softras.pipeline.clip._plane_distances`), finite (N,) whether their
    float64 values are finite, indices (M, 2), values (N, 4) straight
    vertex colours; rectangular: MSAA lines; the framebuffer's size; the
    `LineTable`'s arrays one by one (numba's parallel loop dropped this
    loop as dead when they came as a record built in it, when the passes
    were one)."""
    _aligned_stack()                    # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
    end_clip = np.empty((1, 2, 4))
    weights = np.empty((1, 2, 2))
    generated = np.empty((1, 2), np.bool_)
    pixel_offset = 0.0 if rectangular else 0.5
    n_lines = indices.shape[0]
    for line in range(r * n_lines // n_threads, (r + 1) * n_lines // n_threads):
        drawn[line] = False
        i0, i1 = indices[line, 0], indices[line, 1]
        if not (finite[i0] and finite[i1]
                and _clip_line(c, dist, i0, i1, np.float32(0), end_clip, weights, generated, 0)):
            continue
        for e in range(2):
            (window[line, e, 0], window[line, e, 1], window[line, e, 2], inv_w[line, e],
             _, _) = _window_corner(end_clip[0, e, 0], end_clip[0, e, 1], end_clip[0, e, 2], end_clip[0, e, 3],
                                    not generated[0, e], width, height)
            _end_values(values, i0, i1, e, weights, generated, ends[line])
        drawn[line] = (_setup_line(window[line, 0, 0], window[line, 0, 1], window[line, 1, 0], window[line, 1, 1],
                                   rectangular, pixel_offset, True, qx[line], qy[line])
                       and _binned_region(qx[line], qy[line], 0, rectangular, width, height, region[line]))


@numba.njit(error_model="numpy")
def _cover_lines(r, n_threads, material, offsets, positions, rectangular, shift, color32, color_f, rgba32f, depth,
                 depth_func, write_z, blend, table):
    """`_cover_lines_into` with rgba32f a constant in each of its two
    copies: with it a flag at run time, the RGBA8 loop (the rgba32f
    writes beside it) took 1.31-1.37 ms on one thread for lines_8k_512's
    coverage, against 1.15-1.19 (docs/speed.md, "Forty-seventh round")."""
    _aligned_stack()                    # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
    if rgba32f:
        _cover_lines_into(r, n_threads, material, offsets, positions, rectangular, shift, color32, color_f, True,
                          depth, depth_func, write_z, blend, table)
    else:
        _cover_lines_into(r, n_threads, material, offsets, positions, rectangular, shift, color32, color_f, False,
                          depth, depth_func, write_z, blend, table)


@numba.njit(error_model="numpy", inline="always")
def _cover_lines_into(r, n_threads, material, offsets, positions, rectangular, shift, color32, color_f, rgba32f,
                      depth, depth_func, write_z, blend, table):
    """The set-up lines of the `LineTable` in order, in the bands of rows
    r, r + n_threads, ... (BAND rows each): covered (`_raster_quad`'s rows
    and columns), and each covered pixel shaded and applied at once.

    material (4,) the material colour; offsets (S, 2) the samples in raster
    units and positions (S, 2) within the pixel
    (`softras.pipeline.lines.rasterize_lines`); rectangular: MSAA lines;
    shift: `softras.pipeline.lines.attribute_shift`; color32, color_f,
    depth: the framebuffer (`softras.kernels.ops.Framebuffer`), its colour
    in color_f's floats when rgba32f, else in color32's words; the draw's
    depth function, depth write and blend codes."""
    n_samples = depth.shape[2]
    unit = np.float64(FIXED_ONE)
    centre = 0.5 + shift
    box = _sample_box(offsets)
    white = RGBA(1.0, 1.0, 1.0, 1.0)
    for line in range(table.drawn.shape[0]):
        if not table.drawn[line] or not _in_bands(table.region[line, 2], table.region[line, 3], r, n_threads):
            continue
        # (The line's rows as tuples of scalars, for the stage's functions.)
        qx = (table.qx[line, 0], table.qx[line, 1], table.qx[line, 2], table.qx[line, 3])
        qy = (table.qy[line, 0], table.qy[line, 1], table.qy[line, 2], table.qy[line, 3])
        region = (table.region[line, 0], table.region[line, 1], table.region[line, 2], table.region[line, 3])
        ends = table.ends
        x0, y0, z0 = table.window[line, 0, 0], table.window[line, 0, 1], table.window[line, 0, 2]
        x1, y1, z1 = table.window[line, 1, 0], table.window[line, 1, 1], table.window[line, 1, 2]
        inv_w0, inv_w1 = table.inv_w[line, 0], table.inv_w[line, 1]
        planes = _quad_planes(qx, qy, 0)
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        x_major = abs(np.float32(dx)) >= abs(np.float32(dy))
        py0, py1 = _quad_rows(qy, unit, box, region)
        for py in range(py0, py1 + 1):
            if (py // BAND) % n_threads != r:
                continue
            px0, px1 = _row_span(qx, qy, py, unit, box, region)
            for px in range(px0, px1 + 1):
                mask = _pixel_mask(planes, px, py, offsets, unit)
                if mask == 0:
                    continue
                # depth_at_samples: t at each sample (`_sample_t`: the
                # projection onto the line, or along the major axis compared
                # in float32), z linear in t; the depth test and write.
                passed = 0
                for s in range(n_samples):
                    if not (mask >> s) & 1:
                        continue
                    sx = (px + positions[s, 0]) + shift
                    sy = (py + positions[s, 1]) + shift
                    k = _depth_k(z0 + _sample_t(sx, sy, x0, y0, dx, dy, rectangular, x_major) * dz)
                    stored = depth[py, px, s]
                    if _depth_pass_k(depth_func, k, stored):
                        if write_z:
                            depth[py, px, s] = k
                        passed |= 1 << s
                if passed == 0:
                    continue
                # interpolate_lines at the pixel's t, then shade_unlit's
                # (vertex x material), premultiplied, as bytes (or floats).
                t = _line_t(x0, y0, x1, y1, px + centre, py + centre, rectangular, True)
                q0 = (1.0 - t) * inv_w0
                q1 = t * inv_w1
                total = q0 + q1
                b0, b1 = q0 / total, q1 / total
                red = (b0 * ends[line, 0, 0] + b1 * ends[line, 1, 0]) * material[0]
                green = (b0 * ends[line, 0, 1] + b1 * ends[line, 1, 1]) * material[1]
                blue = (b0 * ends[line, 0, 2] + b1 * ends[line, 1, 2]) * material[2]
                alpha = (b0 * ends[line, 0, 3] + b1 * ends[line, 1, 3]) * material[3]
                if rgba32f:
                    _write_floats(color_f, py, px, passed, n_samples, blend, red * alpha, green * alpha,
                                  blue * alpha, alpha)
                else:
                    _write_word(color32, py, px, passed, n_samples, blend,
                                _color_word(red, green, blue, alpha, white))


@numba.njit(inline="always")
def _in_bands(y0, y1, r, n_threads):
    """Whether any of the rows y0 .. y1 lies in thread r's bands of BAND
    rows (r, r + n_threads, ...: `_cover_lines`): a short line in another
    thread's band is passed over before its set-up for coverage (most
    lines of a wireframe lie in one or two bands)."""
    for band in range(y0 // BAND, min(y1 // BAND, y0 // BAND + n_threads - 1) + 1):
        if band % n_threads == r:
            return True
    return False


_SET_UP_LINES, _COVER_LINES = _make_line_passes(sources_stamp(lines_stage, ops, rasterize, clip_stage))
