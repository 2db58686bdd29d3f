"""Interpolation for the compiled path: perspective weights, depth at the
samples and the fragment colour, over the lanes (`softras.kernels.lanes`).

Mirrors `softras.pipeline.interpolate` (`barycentric`, `perspective_weights`,
`depth_at_samples`) and the unlit colour of `softras.pipeline.fragment.shade_unlit`
as `softras.pipeline.ops.unorm8` converts it, operation for operation.

The per-pixel helpers (`_weights_at`, `_shade_word`) take and return scalars
only.  A numba function that receives an array increments and decrements its
reference count (an atomic operation) on every call, inlined or not; per
pixel that costs more than the arithmetic, and with several threads the
shared counters bounce between cores.  So the lane loops do every array
access.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.lanes import _LF_CX, _LF_CY, _LF_S, _LF_T, _LF_TEX, _LF_W, _LI_PX, _LI_PY, _LI_WORD, _LI_Z
from softras.kernels.ops import DEPTH_SCALE
from softras.kernels.setup import _F_DZDX, _F_DZDY, _F_W, _F_X, _F_Y, _F_Z
from softras.pipeline.ops import unorm8


@numba.njit(cache=True, error_model="numpy", inline="always")
def _weights_at(x0, x1, x2, y0, y1, y2, iw0, iw1, iw2, px, py):
    """`softras.pipeline.interpolate.barycentric` then
    `softras.pipeline.interpolate.perspective_weights` at window point (px, py),
    same operations in the same order: (w0, w1, w2) float64."""
    e0 = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    e1 = (x0 - x2) * (py - y2) - (y0 - y2) * (px - x2)
    e2 = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0)
    total = e0 + e1 + e2
    q0 = e0 / total * iw0
    q1 = e1 / total * iw1
    q2 = e2 / total * iw2
    qs = q0 + q1 + q2
    return q0 / qs, q1 / qs, q2 / qs


@numba.njit(cache=True, error_model="numpy", inline="always")
def _shade_word(w0, w1, w2, cr0, cr1, cr2, cg0, cg1, cg2, cb0, cb1, cb2, ca0, ca1, ca2, tr, tg, tb, ta):
    """`softras.pipeline.fragment.shade_unlit` of the perspective colour
    (`softras.pipeline.interpolate.interpolate`; premultiplied, times the
    texel; texel 1 when untextured, which leaves every value as it is) as the
    bytes llvmpipe converts the fragment colour to
    (`softras.pipeline.ops.unorm8`), packed in one RGBA8 word
    (R in the low byte)."""
    alpha = w0 * ca0 + w1 * ca1 + w2 * ca2
    r = (w0 * cr0 + w1 * cr1 + w2 * cr2) * alpha * tr
    g = (w0 * cg0 + w1 * cg1 + w2 * cg2) * alpha * tg
    b = (w0 * cb0 + w1 * cb1 + w2 * cb2) * alpha * tb
    return unorm8(r) | (unorm8(g) << 8) | (unorm8(b) << 16) | (unorm8(alpha * ta) << 24)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_weights(n, t, tri_f, lf, uv, textured):
    """Perspective weights of triangle t at the n lanes' pixel centres
    (`_weights_at`) into the _LF_W rows and, when textured, its (s, t) there
    (uv (T, 3, 2) at the corners) into the _LF_S / _LF_T rows (a vectorised
    loop): `softras.pipeline.interpolate.perspective_weights` and the st of
    `softras.pipeline.render.uv_at_fragments`."""
    x0, x1, x2 = tri_f[t, _F_X], tri_f[t, _F_X + 1], tri_f[t, _F_X + 2]
    y0, y1, y2 = tri_f[t, _F_Y], tri_f[t, _F_Y + 1], tri_f[t, _F_Y + 2]
    iw0, iw1, iw2 = tri_f[t, _F_W], tri_f[t, _F_W + 1], tri_f[t, _F_W + 2]
    u0 = u1 = u2 = v0 = v1 = v2 = 0.0
    if textured:                        # (an untextured draw's uv is a (1, 3, 2) placeholder)
        u0, u1, u2 = uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0]
        v0, v1, v2 = uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1]
    for l in range(n):
        w0, w1, w2 = _weights_at(x0, x1, x2, y0, y1, y2, iw0, iw1, iw2, lf[_LF_CX, l], lf[_LF_CY, l])
        lf[_LF_W, l] = w0
        lf[_LF_W + 1, l] = w1
        lf[_LF_W + 2, l] = w2
        if textured:
            lf[_LF_S, l] = w0 * u0 + w1 * u1 + w2 * u2
            lf[_LF_T, l] = w0 * v0 + w1 * v1 + w2 * v2


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_words(n, t, colors, lf, li, textured):
    """The fragment colour of the n lanes as llvmpipe's bytes
    (`softras.pipeline.fragment.shade_unlit` then `softras.pipeline.ops.unorm8`,
    `_shade_word`:
    triangle t's corner colours under the _LF_W weights, times the _LF_TEX
    texel when textured), one RGBA8 word each into the _LI_WORD row (a
    vectorised loop)."""
    cr0, cr1, cr2 = colors[t, 0, 0], colors[t, 1, 0], colors[t, 2, 0]
    cg0, cg1, cg2 = colors[t, 0, 1], colors[t, 1, 1], colors[t, 2, 1]
    cb0, cb1, cb2 = colors[t, 0, 2], colors[t, 1, 2], colors[t, 2, 2]
    ca0, ca1, ca2 = colors[t, 0, 3], colors[t, 1, 3], colors[t, 2, 3]
    for l in range(n):
        tr = lf[_LF_TEX, l] if textured else 1.0
        tg = lf[_LF_TEX + 1, l] if textured else 1.0
        tb = lf[_LF_TEX + 2, l] if textured else 1.0
        ta = lf[_LF_TEX + 3, l] if textured else 1.0
        li[_LI_WORD, l] = _shade_word(lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l],
                                      cr0, cr1, cr2, cg0, cg1, cg2, cb0, cb1, cb2, ca0, ca1, ca2, tr, tg, tb, ta)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_depths(n, t, tri_f, positions, li, n_samples):
    """`softras.pipeline.interpolate.depth_at_samples` then
    `softras.pipeline.ops.quantize_depth`: depth of triangle t at every lane's
    samples from its plane equation, clamped and rounded to 24 bits, as the
    integer k of the stored k / DEPTH_SCALE (-1 for NaN), into the _LI_Z rows
    (a vectorised loop)."""
    x0, y0 = tri_f[t, _F_X], tri_f[t, _F_Y]
    z0, dzdx, dzdy = tri_f[t, _F_Z], tri_f[t, _F_DZDX], tri_f[t, _F_DZDY]
    for s in range(n_samples):
        ox, oy = positions[s, 0], positions[s, 1]
        for l in range(n):
            zx = (li[_LI_PX, l] + ox) - x0
            zy = (li[_LI_PY, l] + oy) - y0
            z = z0 + dzdx * zx + dzdy * zy
            k = np.rint(min(max(z, 0.0), 1.0) * DEPTH_SCALE)
            li[_LI_Z + s, l] = np.int32(k if k == k else -1.0)
