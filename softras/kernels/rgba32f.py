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
every tile driver, and the RGBA8 draws pay one branch per block.

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

from softras.kernels.interpolate import _mix
from softras.kernels.lanes import _LF_LIT, _LF_TEX, _LF_W, _LI_PASS, _LI_PX, _LI_PY
from softras.kernels.light import _phong_colors
from softras.kernels.ops import _resolve_box, _write_floats
from softras.kernels.stamp import sources_stamp
from softras.pipeline import libm, ops
from softras.pipeline import render as stages


def _make_float_fragments(sources: str):
    """The kernel `_float_fragments`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable)."""

    @numba.njit(cache=True, error_model="numpy")
    def _float_fragments(n, t, colors, lit, lf, li, lights, lighting, state, color_f, n_samples):
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

        lit, lights, lighting as `softras.kernels.light._phong_words`;
        state the draw's `softras.kernels.draw.DrawState`; n_samples the
        buffer's samples (an int64)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        if state.lit:
            _phong_colors(n, t, colors, lit, lf, lights, lighting, state.mapped != 0)
        elif state.flat:
            for l in range(n):
                for c in range(4):
                    lf[_LF_LIT + c, l] = colors[t, 0, c]
        else:
            for c in range(4):
                corner = (colors[t, 0, c], colors[t, 1, c], colors[t, 2, c])
                for l in range(n):
                    lf[_LF_LIT + c, l] = _mix((lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l]), corner)
        for l in range(n):
            alpha = lf[_LF_LIT + 3, l]
            for c in range(3):
                lf[_LF_LIT + c, l] = lf[_LF_LIT + c, l] * alpha
            if state.texture:
                for c in range(4):
                    lf[_LF_LIT + c, l] = lf[_LF_LIT + c, l] * lf[_LF_TEX + c, l]
        for l in range(n):
            p = li[_LI_PASS, l]
            if p:
                _write_floats(color_f, li[_LI_PY, l], li[_LI_PX, l], p, n_samples, state.blend,
                              lf[_LF_LIT, l], lf[_LF_LIT + 1, l], lf[_LF_LIT + 2, l], lf[_LF_LIT + 3, l])

    return _float_fragments


_float_fragments = _make_float_fragments(sources_stamp(ops, libm))


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
