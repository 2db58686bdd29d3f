"""Lines in exact precision: a GL_LINES draw in one compiled loop, float64.

Mirrors what `softras.pipeline.render.draw_lines` does with a line draw in
``precision="exact"``, operation for operation and in the same order, line
by line and without a fragment list, into the same float64 buffers (the
samples are the stages', value for value: tests/test_exact_lines.py):

1. clip: `softras.pipeline.lines.clip_lines` in float64 with the pass's
   policy (guard band by default; `clip_inputs`, the same
   `_plane_distances` and `_clip_line`);
2. viewport: `softras.pipeline.setup.viewport_transform` in exact
   precision, ``(c / w) W/2 + W/2`` (in `_set_up_lines`, as `softras.kernels.exact._setup`);
3. set-up: `softras.pipeline.lines.line_quads` (the same `_setup_line`,
   gl False: unsnapped, later Mesa's end-pixel tests), no binning;
4. coverage: `softras.pipeline.lines.rasterize_lines` (`_raster_quad`'s
   rows and columns over the whole framebuffer: `_quad_planes`,
   `_quad_rows`, `_row_span`, `_pixel_mask`; the raster offsets of
   `sample_offsets` with gl False), each covered pixel at once shaded and
   applied:
5. `softras.pipeline.lines.depth_at_samples` (z linear in the t of each
   sample, not quantized), `interpolate_lines` (the colour,
   perspective-correct in the `_line_t` of the pixel centre; the
   `attribute_shift` of exact precision is 0),
   `softras.pipeline.fragment.shade_unlit` (vertex x material,
   premultiplied) and `softras.pipeline.ops.apply_fragments` without
   quantizing (its own `_depth_pass` and `_blend`, per covered sample).

Two passes, as `softras.kernels.lines`', each in a share a thread
(`softras.kernels.pool.on_threads`): the set-up by lines, then the coverage
by bands of `BAND_ROWS` rows (share r of n bands r, r + n, ...), where each
share walks all the lines in order over its own rows, so every pixel sees
the lines in the stages' fragment order.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.pool import on_threads
from softras.kernels.scratch import _Scratch, read_only
from softras.kernels.stamp import sources_stamp
from softras.kernels.threads import NoAliasCompiler, _aligned_stack, _unowned, share_count
from softras.pipeline import clip as clip_stage
from softras.pipeline import lines as lines_stage
from softras.pipeline import ops, rasterize
from softras.pipeline import render as stages
from softras.pipeline.clip import _plane_distances
from softras.pipeline.lines import (FIXED_ONE, _clip_line, _end_values, _line_t, _pixel_mask, _quad_planes,
                                    _quad_rows, _row_span, _sample_t, _setup_line)
from softras.pipeline.rasterize import _sample_box

# Rows of the picture a thread covers at once (thread r of n: bands r, r + n, ...).
BAND_ROWS = 16


def draw_lines(scene, draw, inputs: stages.Pass, color: np.ndarray, depth: np.ndarray) -> None:
    """`softras.pipeline.render.draw_lines` of an exact-precision pass: the
    line draw into color (H, W, S, 4) float64 premultiplied and depth (H, W,
    S) float64, GL's y-up rows, the same values.  A material lines cannot
    have (``line_problems``) and other precisions are the stages' (which
    refuse the former)."""
    if inputs.precision != "exact" or draw.material.line_problems():
        return stages.draw_lines(scene, draw, inputs, color, depth)
    mesh = draw.mesh
    clip_pos = stages.draw_clip_positions(scene, draw, inputs.precision)
    c, finite, planes = lines_stage.clip_inputs(clip_pos, inputs.precision, inputs.policy, scene.width,
                                                scene.height)
    positions = read_only(inputs.positions, np.float64)
    rectangular = len(positions) > 1
    indices = read_only(np.asarray(mesh.indices, np.int64).reshape(-1, 2), np.int64)
    n = len(indices)
    depth_func = ops.DEPTH_FUNCS[draw.depth_test]
    write_z = bool(draw.depth_write) and depth_func != 0
    c = read_only(c, np.float64)
    dist = _plane_distances(c, read_only(planes, np.float64))
    table = (_scratch.take("drawn", (n,), np.bool_), _scratch.take("qx", (n, 4), np.float64),
             _scratch.take("qy", (n, 4), np.float64), _scratch.take("window", (n, 2, 3), np.float64),
             _scratch.take("inv_w", (n, 2), np.float64), _scratch.take("ends", (n, 2, 4), np.float64))
    finite, values = read_only(finite, np.bool_), read_only(stages.vertex_colors(mesh), np.float64)
    n_set_up = share_count(n)
    on_threads(lambda r: _SET_UP_LINES(r, n_set_up, c, dist, finite, indices, values, rectangular, scene.width,
                                       scene.height, *table), n_set_up)
    material = read_only(draw.material.color, np.float64)
    offsets = read_only(lines_stage.sample_offsets(positions, rectangular, False), np.float64)
    n_cover = share_count(-(-scene.height // BAND_ROWS))
    on_threads(lambda r: _COVER_LINES(r, n_cover, BAND_ROWS, material, offsets, positions, rectangular, color,
                                      depth, depth_func, write_z, ops.BLEND_MODES[draw.blend], *table), n_cover)


_scratch = _Scratch()


def _make_line_passes(sources: str):
    """The exact line kernel's two passes, each one share of n_threads for
    `softras.kernels.pool.on_threads`, as `softras.kernels.lines`' passes:
    the set-up by lines (`_set_up_lines`: share r lines r, r + n_threads,
    ...), then the coverage, shading and writes by bands of ``band_rows``
    rows (`_cover_lines`).  c (N, 4) float64 clip positions, finite (N,)
    (`softras.pipeline.lines.clip_inputs`), dist (N, 6) their distances to
    its clip planes (`softras.pipeline.clip._plane_distances`), indices
    (M, 2), values (N, 4) straight vertex colours, material (4,) its colour;
    offsets (S, 2) raster offsets, positions (S, 2) in the pixel;
    rectangular: MSAA lines; the float64 buffers; the depth function, depth
    write (and a depth test) and blend codes; the per-line tables drawn
    (M,), qx, qy (M, 4), window (M, 2, 3), inv_w (M, 2), ends (M, 2, 4)
    (scratch, written by the set-up).  Compiled with ``sources``
    (`softras.kernels.stamp`: the kernels' and the line, ops, rasterize and
    clip stages' sources, whose functions they call) in their cache key,
    as numba compiles a parallel loop's body (``noalias`` on their arrays,
    `softras.kernels.threads.NoAliasCompiler`; the arrays handed on
    unowned, `softras.kernels.threads._unowned`).  The helpers are called,
    not inlined (inlined into the numba parallel loops these passes were
    until the fifty-first round, the kernel took 35 s to compile cold here;
    called, 22 s)."""

    @numba.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
    def set_up_pass(r, n_threads, c, dist, finite, indices, values, rectangular, width, height, drawn, qx, qy,
                    window, inv_w, ends):
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        _set_up_lines(r, n_threads, _unowned(c), _unowned(dist), _unowned(finite), _unowned(indices),
                      _unowned(values), rectangular, width, height, _unowned(drawn), _unowned(qx), _unowned(qy),
                      _unowned(window), _unowned(inv_w), _unowned(ends))

    @numba.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
    def cover_pass(r, n_threads, band_rows, material, offsets, positions, rectangular, color, depth, depth_func,
                   write_z, blend, drawn, qx, qy, window, inv_w, ends):
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        _cover_lines(r, n_threads, band_rows, _unowned(material), _unowned(offsets), _unowned(positions),
                     rectangular, _unowned(color), _unowned(depth), depth_func, write_z, blend, _unowned(drawn),
                     _unowned(qx), _unowned(qy), _unowned(window), _unowned(inv_w), _unowned(ends))

    return set_up_pass, cover_pass


@numba.njit(error_model="numpy")
def _set_up_lines(r, n_threads, c, dist, finite, indices, values, rectangular, width, height, drawn, qx, qy,
                  window, inv_w, ends):
    """`softras.pipeline.lines.rasterized_lines` up to the coverage, exact
    precision, for the input lines r, r + n_threads, ... into their table
    rows: clipped (`_clip_line` in float64), the end points' window
    coordinates and 1/w (`softras.pipeline.setup.viewport_transform`,
    exact: ``clip[:3] * oow * scale + scale``), their colours (the clip
    weights x the vertices' values) and the quad (`_setup_line`, gl
    False); drawn False for a line dropped or culled."""
    _aligned_stack()                    # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
    end_clip = np.empty((1, 2, 4))
    weights = np.empty((1, 2, 2))
    generated = np.empty((1, 2), np.bool_)
    pixel_offset = 0.0 if rectangular else 0.5
    scale = (width / 2.0, height / 2.0, 0.5)
    for line in range(r, indices.shape[0], n_threads):
        drawn[line] = False
        i0, i1 = indices[line, 0], indices[line, 1]
        if not (finite[i0] and finite[i1] and _clip_line(c, dist, i0, i1, 0.0, end_clip, weights, generated, 0)):
            continue
        for e in range(2):
            oow = 1.0 / end_clip[0, e, 3]
            inv_w[line, e] = oow
            for k in range(3):
                window[line, e, k] = end_clip[0, e, k] * oow * scale[k] + scale[k]
            _end_values(values, i0, i1, e, weights, generated, ends[line])
        drawn[line] = _setup_line(window[line, 0, 0], window[line, 0, 1], window[line, 1, 0], window[line, 1, 1],
                                  rectangular, pixel_offset, False, qx[line], qy[line])


@numba.njit(error_model="numpy")
def _cover_lines(r, n_threads, band_rows, material, offsets, positions, rectangular, color, depth, depth_func,
                 write_z, blend, drawn, qx, qy, window, inv_w, ends):
    """The set-up lines in order over the bands of rows r, r + n_threads,
    ... (band_rows rows each): covered (`_raster_quad`'s rows and columns
    over the framebuffer: exact precision bins nothing), and each covered
    pixel's samples depth-tested and written (`depth_at_samples`,
    `_depth_pass`), its colour interpolated at the pixel centre
    (`_line_t`, `interpolate_lines`), shaded (`shade_unlit`) and blended
    into each passed sample (`_blend`), as `apply_fragments` applies it."""
    _aligned_stack()                    # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
    height, width, n_samples = depth.shape[0], depth.shape[1], depth.shape[2]
    unit = np.float64(FIXED_ONE)
    box = _sample_box(offsets)
    region = (0, width - 1, 0, height - 1)
    n_bands = (height + band_rows - 1) // band_rows
    for line in range(drawn.shape[0]):
        if not drawn[line]:
            continue
        # (The line's quad as tuples of scalars, for the stage's functions.)
        lqx = (qx[line, 0], qx[line, 1], qx[line, 2], qx[line, 3])
        lqy = (qy[line, 0], qy[line, 1], qy[line, 2], qy[line, 3])
        py0, py1 = _quad_rows(lqy, unit, box, region)
        if py0 > py1:
            continue
        planes = _quad_planes(lqx, lqy, 0)
        x0, y0, z0 = window[line, 0, 0], window[line, 0, 1], window[line, 0, 2]
        x1, y1, z1 = window[line, 1, 0], window[line, 1, 1], window[line, 1, 2]
        inv_w0, inv_w1 = inv_w[line, 0], inv_w[line, 1]
        # depth_at_samples' d = ends[1] - ends[0] and major axis (float64).
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        x_major = abs(dx) >= abs(dy)
        first = py0 // band_rows
        first += (r - first) % n_threads               # this thread's first band from py0's on
        for band in range(first, min(py1 // band_rows, n_bands - 1) + 1, n_threads):
            for py in range(max(band * band_rows, py0), min(band * band_rows + band_rows - 1, py1) + 1):
                px0, px1 = _row_span(lqx, lqy, py, unit, box, region)
                for px in range(px0, px1 + 1):
                    mask = _pixel_mask(planes, px, py, offsets, unit)
                    if mask == 0:
                        continue
                    # (mask as uint64: one type whatever numba infers for it)
                    _apply_pixel(px, py, np.uint64(mask), n_samples, positions, rectangular, x_major, x0, y0, z0,
                                 x1, y1, dx, dy, dz, inv_w0, inv_w1, ends, line, material, color, depth, depth_func,
                                 write_z, blend)


@numba.njit(error_model="numpy", inline="always")
def _apply_pixel(px, py, mask, n_samples, positions, rectangular, x_major, x0, y0, z0, x1, y1, dx, dy, dz, inv_w0,
                 inv_w1, ends, line, material, color, depth, depth_func, write_z, blend):
    """One covered pixel (px, py) of a line, samples mask: the depth test
    and write of each covered sample (`depth_at_samples`: t at the sample,
    the projection onto the line or along the major axis, not finite -> 0;
    `_depth_pass`), then, where any passed, the colour
    (`interpolate_lines` at the pixel centre's `_line_t`, `shade_unlit`'s
    vertex x material premultiplied) blended into the passed samples
    (`_blend`).  Samples are independent: the same values as
    `apply_fragments`' per-sample order."""
    passed = np.uint32(0)
    for s in range(n_samples):
        if not (mask >> s) & 1:
            continue
        sx = (px + positions[s, 0]) + 0.0
        sy = (py + positions[s, 1]) + 0.0
        z = z0 + _sample_t(sx, sy, x0, y0, dx, dy, rectangular, x_major) * dz
        if ops._depth_pass(depth_func, z, depth[py, px, s]):
            if write_z:
                depth[py, px, s] = z
            passed |= np.uint32(1) << np.uint32(s)
    if passed == 0:
        return
    t = _line_t(x0, y0, x1, y1, px + 0.5, py + 0.5, rectangular, False)
    q0 = (1.0 - t) * inv_w0
    q1 = t * inv_w1
    total = q0 + q1
    b0, b1 = q0 / total, q1 / total
    r = (b0 * ends[line, 0, 0] + b1 * ends[line, 1, 0]) * material[0]
    g = (b0 * ends[line, 0, 1] + b1 * ends[line, 1, 1]) * material[1]
    b = (b0 * ends[line, 0, 2] + b1 * ends[line, 1, 2]) * material[2]
    a = (b0 * ends[line, 0, 3] + b1 * ends[line, 1, 3]) * material[3]
    src = (r * a, g * a, b * a, a)
    for s in range(n_samples):
        if (passed >> s) & 1:
            for ch in range(4):
                color[py, px, s, ch] = ops._blend(blend, src[ch], color[py, px, s, ch], a)


_SET_UP_LINES, _COVER_LINES = _make_line_passes(sources_stamp(lines_stage, ops, rasterize, clip_stage))
