"""An rgba32f framebuffer's fragment colours and writes for the tile kernels (gl precision).

Mirrors the end of `softras.pipeline.render.draw_triangles` when the pass's
buffer holds float32 colour (``Pass.quantize`` False): the premultiplied
float64 fragment colour of `softras.pipeline.fragment.shade_unlit` (after
Phong's `softras.pipeline.fragment.blinn_phong` for a lit draw), then
`softras.pipeline.ops.apply_fragments`' float blend and store, where an
RGBA8 buffer takes the colour's bytes (`softras.kernels.interpolate._lane_words`,
`softras.kernels.light._phong_words`, `softras.kernels.ops._write_lanes`).

The rest of a draw (coverage, depth, weights, texels, the alpha test) is
the tile kernel's as for RGBA8: `softras.kernels.draw` calls
`_float_fragments` in place of the colour words and their writes when the
draw's `softras.kernels.draw.DrawState` says rgba32f.  It is a function of
its own, not inlined: one compiled copy (Phong's lighting with it) serves
every tile driver, and the RGBA8 draws pay one branch per block.  At one
sample an unlit, interpolated draw without alpha test takes a row loop
instead when it is blended "over" without depth (`_row_floats_over`) or
depth-tested "less" with depth writes and not blended
(`_row_floats_less`): the same steps pixel by pixel along a row's run of
covered pixels, as RGBA8's `softras.kernels.draw._row_pixels_1`, called
once a row from the driver of one sample (`_row_floats`).

`resolve` makes the picture from the float samples, gl precision's
float32 and exact precision's float64 alike (`softras.kernels.exact.resolve`
hands it its rgba32f jobs): the stages' box filter
(`softras.pipeline.ops.resolve`, float32 output, the same arithmetic in
both precisions) in one parallel loop (`softras.kernels.ops._resolve_box`,
exact precision's RGBA8 pictures' too), the tent filter by the stages.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.interpolate import _mix, _weights_at
from softras.kernels.lanes import _LF_LIT, _LF_TEX, _LF_W, _LI_PASS, _LI_PX, _LI_PY, _whole_vectors
from softras.kernels.light import _phong_colors
from softras.kernels.ops import LESS, _depth_pass_k, _plane_depth_k, _resolve_box, _write_floats
from softras.kernels.stamp import sources_stamp
from softras.pipeline import libm, ops
from softras.pipeline import render as stages
from softras.pipeline.ops import _blend


def _make_float_fragments(sources: str):
    """The kernel `_float_fragments`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable)."""

    @numba.njit(cache=True, error_model="numpy")
    def _float_fragments(n, t, colors, lit, lit_rows, lf, li, lights, lighting, state, color_f, n_samples):
        """Shade the n lanes of triangle t and apply them to the rgba32f
        buffer color_f (H, W, S, 4) float32: each lane's straight colour
        into the _LF_LIT rows (Phong-lit by `_phong_colors` when
        ``state.lit``, with the _LF_MAP rows' normals when mapped; else the
        corner colours (T, 3, 4) ``colors`` under the _LF_W weights, or
        corner 0's as it is when flat: the stages' face colour, -0.0
        included), premultiplied and times the _LF_TEX texel when
        ``state.texture`` (`softras.pipeline.fragment.shade_unlit`:
        ``(r a) texel_r``, ``a texel_a``), then written to the lane's
        passed samples (_LI_PASS) with the draw's blend (`_write_floats`).

        lit, lit_rows, lights, lighting as `softras.kernels.light._phong_words`;
        state the draw's `softras.kernels.draw.DrawState`; n_samples the
        buffer's samples (an int64)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        m = _whole_vectors(n)           # (the colours over whole vectors, `softras.kernels.lanes.VECTOR`)
        if state.lit:
            _phong_colors(m, t, colors, lit, lit_rows, lf, lights, lighting, state.mapped != 0)
        elif state.flat:
            for l in range(m):
                for c in range(4):
                    lf[_LF_LIT + c, l] = colors[t, 0, c]
        else:
            for c in range(4):
                corner = (colors[t, 0, c], colors[t, 1, c], colors[t, 2, c])
                for l in range(m):
                    lf[_LF_LIT + c, l] = _mix((lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l]), corner)
        for l in range(m):
            alpha = lf[_LF_LIT + 3, l]
            for c in range(3):
                lf[_LF_LIT + c, l] = lf[_LF_LIT + c, l] * alpha
            if state.texture:
                for c in range(4):
                    lf[_LF_LIT + c, l] = lf[_LF_LIT + c, l] * lf[_LF_TEX + c, l]
        # (At one sample "none" and "over" in copies of their own, the
        # equation a constant there instead of a switch per sample and
        # channel: few_large_512's opaque quads into rgba32f 19 % faster on
        # one thread, docs/speed.md, "Forty-third round".)
        if n_samples == 1 and state.blend == 0:
            _write_lanes_floats(n, lf, li, color_f, np.int64(1), 0)
        elif n_samples == 1 and state.blend == 1:
            _write_lanes_floats(n, lf, li, color_f, np.int64(1), 1)
        else:
            _write_lanes_floats(n, lf, li, color_f, n_samples, state.blend)

    return _float_fragments


@numba.njit(cache=True, error_model="numpy", inline="always")
def _write_lanes_floats(n, lf, li, color_f, n_samples, blend):
    """`_write_floats` of the n lanes' _LF_LIT colours into their passed
    samples (_LI_PASS) of color_f."""
    for l in range(n):
        p = li[_LI_PASS, l]
        if p:
            _write_floats(color_f, li[_LI_PY, l], li[_LI_PX, l], p, n_samples, blend,
                          lf[_LF_LIT, l], lf[_LF_LIT + 1, l], lf[_LF_LIT + 2, l], lf[_LF_LIT + 3, l])


_float_fragments = _make_float_fragments(sources_stamp(ops, libm))


@numba.njit(error_model="numpy", _nrt=False)
def _row_floats(start, end, py, corners, corner_colors, plane, positions, depths, floats, width, write_z):
    """The rows of an rgba32f draw at one sample (`softras.kernels.draw._float_rows`):
    `_row_floats_less` for an opaque depth-tested draw (``write_z``), else
    `_row_floats_over`.  Called, not inlined, and without reference
    counting (``_nrt=False``: its arrays are the driver's, and it
    allocates nothing): inlined into the one-sample driver, the loop for
    "less" slowed the driver's RGBA8 draws (blended_8x128_512 1.18x,
    scale_tris_10082 1.05-1.10x), as a call with reference counting it
    slowed the small triangles of many_small_24k_512 into rgba32f 1.11x
    (docs/speed.md, "Forty-sixth round")."""
    if write_z:
        _row_floats_less(start, end, py, corners, corner_colors, plane, positions, depths, floats, width)
    else:
        _row_floats_over(start, end, py, corners, corner_colors, floats, width)


@numba.njit(error_model="numpy", inline="always")
def _row_floats_less(start, end, py, corners, corner_colors, plane, positions, depths, floats, width):
    """`_float_fragments` of an unlit, untextured, interpolated triangle's
    fragments at pixels start..end of row py, one sample a pixel, every
    pixel covered, depth-tested "less" with depth writes, not blended (an
    opaque draw): per pixel the depth from the plane and its test and write
    (as `softras.kernels.draw._row_pixels_1`: plane = (x0, y0, z0, dz/dx,
    dz/dy) of the set-up triangle, positions (x, y) the sample's within the
    pixel), the straight colour under the weights `_weights_at` at the
    pixel centre, premultiplied, stored rounded to float32 where the depth
    test passed (what `_write_floats` stores without a blend: the
    fragment's value).
    The same operations in the same order as the lanes; a select, not a
    branch, where the test fails.  depths, floats : the depth buffer and
    the colour buffer (H, W, 1, 4) seen as one row each; width : the
    picture's."""
    row = py * width
    cy = py + 0.5
    for px in range(start, end + 1):
        i = np.uint64(row + px)
        k = _plane_depth_k(plane, px + positions[0], py + positions[1])
        stored = depths[i]
        passed = _depth_pass_k(LESS, k, stored)
        depths[i] = k if passed else stored
        w = _weights_at(corners, px + 0.5, cy)
        r, g, b, a = _mix(w, corner_colors.r), _mix(w, corner_colors.g), _mix(w, corner_colors.b), \
            _mix(w, corner_colors.a)
        j = i * np.uint64(4)
        floats[j] = r * a if passed else floats[j]
        floats[j + np.uint64(1)] = g * a if passed else floats[j + np.uint64(1)]
        floats[j + np.uint64(2)] = b * a if passed else floats[j + np.uint64(2)]
        floats[j + np.uint64(3)] = a if passed else floats[j + np.uint64(3)]


@numba.njit(error_model="numpy", inline="always")
def _row_floats_over(start, end, py, corners, corner_colors, floats, width):
    """`_float_fragments` of an unlit, untextured triangle's fragments at
    pixels start..end of row py, one sample a pixel, every pixel covered,
    without depth test, depth writes or alpha test, blended "over": the
    steps of `softras.kernels.draw._flat_block` into an rgba32f buffer with
    the same operations in the same order, pixel by pixel (the pixels are
    distinct, so their order does not matter): the straight colour (the
    corner colours ``corner_colors``, an `RGBA` of corner triples, under the
    perspective weights `_weights_at` at the pixel centre; `Corners`
    corners), premultiplied, and `softras.kernels.ops._write_floats`' blend
    of each channel over the stored float32 (widened), stored rounded to
    float32.  floats : the colour buffer (H, W, 1, 4) seen as one row
    (``reshape(-1)``); width : the picture's.

    A loop LLVM vectorises, as `softras.kernels.draw._row_pixels_1`: no
    branch, and the index an unsigned integer (blended_8x128_512 into
    rgba32f 8.7 -> 5.2 ms, where the lanes blended each channel as they
    stored it; docs/speed.md, "Thirty-sixth round")."""
    row = py * width
    cy = py + 0.5
    for px in range(start, end + 1):
        w = _weights_at(corners, px + 0.5, cy)
        r, g, b, a = _mix(w, corner_colors.r), _mix(w, corner_colors.g), _mix(w, corner_colors.b), \
            _mix(w, corner_colors.a)
        j = np.uint64(row + px) * np.uint64(4)
        floats[j] = _blend(1, r * a, floats[j], a)
        floats[j + np.uint64(1)] = _blend(1, g * a, floats[j + np.uint64(1)], a)
        floats[j + np.uint64(2)] = _blend(1, b * a, floats[j + np.uint64(2)], a)
        floats[j + np.uint64(3)] = _blend(1, a, floats[j + np.uint64(3)], a)


def resolve(job: stages.Job, color: np.ndarray) -> np.ndarray:
    """`softras.pipeline.render.resolve` of an rgba32f job's samples
    (H, W, S, 4), float32 in gl precision, float64 in exact: the picture
    (H, W, 4) float32, row 0 = top.  The box filter by
    `softras.kernels.ops._resolve_box`, the tent filter by the stages."""
    if job.rgba8:
        raise ValueError("softras.kernels.rgba32f resolves an rgba32f job only")
    if job.resolve_filter != "box":
        return stages.resolve(job, color)
    out = np.empty(color.shape[:2] + (4,), np.float32)
    _resolve_box(color, out)
    return out
