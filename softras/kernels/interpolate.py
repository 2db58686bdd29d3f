"""Interpolation for the compiled path: perspective weights, depth at the
samples and the fragment colour, over the lanes (`softras.kernels.lanes`).

Mirrors `softras.pipeline.interpolate` (`edge_functions`, `barycentric`, `perspective_weights`,
`depth_at_samples`) and the unlit colour of `softras.pipeline.fragment.shade_unlit`
as `softras.pipeline.ops.unorm8` converts it, operation for operation.

The per-pixel helpers (`_weights_at`, `_shade_word`) take and return scalars
and records of scalars only (`Corners`, `RGBA`: numba passes them as values,
and LLVM keeps their fields in registers).  A numba function that receives an array increments and decrements its
reference count (an atomic operation) on every call, inlined or not; per
pixel that costs more than the arithmetic, and with several threads the
shared counters bounce between cores.  So the lane loops do every array
access.
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.lanes import _LF_CX, _LF_CY, _LF_S, _LF_T, _LF_TEX, _LF_W, _LI_PX, _LI_PY, _LI_WORD, _LI_Z
from softras.kernels.ops import _plane_depth_k
from softras.kernels.setup import _F_DZDX, _F_DZDY, _F_W, _F_X, _F_Y, _F_Z
from softras.pipeline.ops import unorm8


# A set-up triangle's corners as the interpolation reads them: window x, y
# and 1/w, each a tuple of the three corners' values (`_corners`).
Corners = namedtuple("Corners", ["x", "y", "inv_w"])

# Four colour channels: floats (a texel), or per channel a tuple of the three
# corners' values (a triangle's corner colours, `_corner_colors`).
RGBA = namedtuple("RGBA", ["r", "g", "b", "a"])


@numba.njit(cache=True, inline="always")
def _corners(tri_f, t):
    """The `Corners` of set-up triangle t (its tri_f row): the window
    coordinates and inv_w of `softras.pipeline.setup.setup_triangles`."""
    return Corners((tri_f[t, _F_X], tri_f[t, _F_X + 1], tri_f[t, _F_X + 2]),
                   (tri_f[t, _F_Y], tri_f[t, _F_Y + 1], tri_f[t, _F_Y + 2]),
                   (tri_f[t, _F_W], tri_f[t, _F_W + 1], tri_f[t, _F_W + 2]))


@numba.njit(cache=True, inline="always")
def _corner_colors(colors, t):
    """Set-up triangle t's corner colours (colors (T, 3, 4), the values of
    `softras.pipeline.render.corner_values`) as an `RGBA` of corner triples."""
    return RGBA((colors[t, 0, 0], colors[t, 1, 0], colors[t, 2, 0]),
                (colors[t, 0, 1], colors[t, 1, 1], colors[t, 2, 1]),
                (colors[t, 0, 2], colors[t, 1, 2], colors[t, 2, 2]),
                (colors[t, 0, 3], colors[t, 1, 3], colors[t, 2, 3]))


@numba.njit(cache=True, inline="always")
def _triple(table, t, c):
    """Value c of set-up triangle t's three corners in a corner table
    (T, 3, K), as the 3-tuple `_mix` weighs."""
    return table[t, 0, c], table[t, 1, c], table[t, 2, c]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _edge_functions(c, px, py):
    """`softras.pipeline.interpolate.edge_functions` at window point (px, py)
    of the triangle with `Corners` c, same operations in the same order:
    (e0, e1, e2) float64."""
    x0, x1, x2 = c.x
    y0, y1, y2 = c.y
    e0 = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    e1 = (x0 - x2) * (py - y2) - (y0 - y2) * (px - x2)
    e2 = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0)
    return e0, e1, e2


@numba.njit(cache=True, error_model="numpy", inline="always")
def _barycentric(c, px, py):
    """`softras.pipeline.interpolate.barycentric` at window point (px, py)
    of the triangle with `Corners` c, same operations in the same order:
    (lam0, lam1, lam2) float64."""
    e0, e1, e2 = _edge_functions(c, px, py)
    total = e0 + e1 + e2
    return e0 / total, e1 / total, e2 / total


@numba.njit(cache=True, error_model="numpy", inline="always")
def _weights_at(c, px, py):
    """`softras.pipeline.interpolate.edge_functions` then
    `softras.pipeline.interpolate.perspective_weights` at window point (px, py)
    of the triangle with `Corners` c, same operations in the same order:
    (w0, w1, w2) float64.  Three divisions (the edge functions are not
    normalised first: the area cancels), 2.2 ns a lane where the six of
    barycentrics then weights took 4.5."""
    e0, e1, e2 = _edge_functions(c, px, py)
    iw0, iw1, iw2 = c.inv_w
    q0 = e0 * iw0
    q1 = e1 * iw1
    q2 = e2 * iw2
    qs = q0 + q1 + q2
    return q0 / qs, q1 / qs, q2 / qs


@numba.njit(cache=True, error_model="numpy", inline="always")
def _mix(w, v):
    """`softras.pipeline.interpolate.interpolate` of one attribute: weights w
    and corner values v (3-tuples), w0 v0 + w1 v1 + w2 v2 in this order."""
    return w[0] * v[0] + w[1] * v[1] + w[2] * v[2]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _shade_word(w, colors, texel):
    """`softras.pipeline.fragment.shade_unlit` of the perspective colour
    (`_mix` of the corner colours ``colors``, an `RGBA` of corner triples,
    under the weights w; premultiplied, times the `RGBA` texel; texel 1 when
    untextured, which leaves every value as it is) as the bytes llvmpipe
    converts the fragment colour to (`softras.pipeline.ops.unorm8`), packed in
    one RGBA8 word (R in the low byte)."""
    return _color_word(_mix(w, colors.r), _mix(w, colors.g), _mix(w, colors.b), _mix(w, colors.a), texel)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _color_word(r, g, b, alpha, texel):
    """`softras.pipeline.fragment.shade_unlit` of one straight colour (r, g,
    b, alpha): premultiplied, times the `RGBA` texel, as the RGBA8 word of
    `softras.pipeline.ops.unorm8`'s bytes (R in the low byte)."""
    return (unorm8(r * alpha * texel.r) | (unorm8(g * alpha * texel.g) << 8) | (unorm8(b * alpha * texel.b) << 16)
            | (unorm8(alpha * texel.a) << 24))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_weights(n, t, tri_f, lf, uv, textured):
    """Perspective weights of triangle t at the n lanes' pixel centres
    (`_weights_at`) into the _LF_W rows and, when textured, its (s, t) there
    (uv (T, 3, 2) at the corners) into the _LF_S / _LF_T rows (a vectorised
    loop): `softras.pipeline.interpolate.perspective_weights` and the st of
    `softras.pipeline.render.uv_at_fragments`."""
    corners = _corners(tri_f, t)
    u = v = (0.0, 0.0, 0.0)
    if textured:                        # (an untextured draw's uv is a (1, 3, 2) placeholder)
        u = (uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0])
        v = (uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1])
    for l in range(n):
        w = _weights_at(corners, lf[_LF_CX, l], lf[_LF_CY, l])
        lf[_LF_W, l] = w[0]
        lf[_LF_W + 1, l] = w[1]
        lf[_LF_W + 2, l] = w[2]
        if textured:
            lf[_LF_S, l] = _mix(w, u)
            lf[_LF_T, l] = _mix(w, v)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_words(n, t, colors, lf, li, textured, flat):
    """The fragment colour of the n lanes as llvmpipe's bytes
    (`softras.pipeline.fragment.shade_unlit` then `softras.pipeline.ops.unorm8`,
    `_shade_word`: triangle t's corner colours under the _LF_W weights, times
    the _LF_TEX texel when textured), one RGBA8 word each into the _LI_WORD
    row (a vectorised loop).

    flat: the triangle's colour is not interpolated
    (`softras.pipeline.render.flat_colors`): it is corner 0's, and corners 1
    and 2 hold zeros (`softras.kernels.light.flat_corner_colors`), so the
    weights (1, 0, 0) give back corner 0's colour exactly, 1 c + 0 0 + 0 0 =
    c, whatever c (infinite or NaN included)."""
    corner_colors = _corner_colors(colors, t)
    for l in range(n):
        texel = RGBA(1.0, 1.0, 1.0, 1.0)
        if textured:
            texel = RGBA(lf[_LF_TEX, l], lf[_LF_TEX + 1, l], lf[_LF_TEX + 2, l], lf[_LF_TEX + 3, l])
        w = (1.0, 0.0, 0.0) if flat else (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
        li[_LI_WORD, l] = _shade_word(w, corner_colors, texel)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_alpha_test(n, t, colors, lf, li, row, textured, flat, cutoff):
    """`softras.pipeline.fragment.alpha_test` (gl) of the n lanes: the
    fragment's alpha as `_shade_word` makes it (triangle t's corner alphas
    under the _LF_W weights, or corner 0's when flat, times the _LF_TEX
    texel's alpha when textured), rounded to float32, against the float32
    cutoff; a discarded lane's mask in row ``row`` of li becomes 0 (no depth
    or colour write for any sample).  NaN alphas are kept, as ``~(a <
    cutoff)`` keeps them."""
    alphas = (colors[t, 0, 3], colors[t, 1, 3], colors[t, 2, 3])
    cutoff32 = np.float32(cutoff)
    for l in range(n):
        w = (1.0, 0.0, 0.0) if flat else (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
        alpha = _mix(w, alphas) * (lf[_LF_TEX + 3, l] if textured else 1.0)
        if np.float32(alpha) < cutoff32:
            li[row, l] = 0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_depths(n, t, tri_f, positions, li, n_samples):
    """`softras.pipeline.interpolate.depth_at_samples` then
    `softras.pipeline.ops.quantize_depth`: depth of triangle t at every lane's
    samples from its plane equation, clamped and rounded to 24 bits, as the
    integer k of the stored k / DEPTH_SCALE (-1 for NaN), into the _LI_Z rows
    (a vectorised loop)."""
    plane = (tri_f[t, _F_X], tri_f[t, _F_Y], tri_f[t, _F_Z], tri_f[t, _F_DZDX], tri_f[t, _F_DZDY])
    for s in range(n_samples):
        ox, oy = positions[s, 0], positions[s, 1]
        for l in range(n):
            li[_LI_Z + s, l] = _plane_depth_k(plane, li[_LI_PX, l] + ox, li[_LI_PY, l] + oy)


def plain_colors(base: np.ndarray) -> bool:
    """Whether a textured draw's fragment colour is its texel's bytes as they
    are: every vertex colour (V, 4, straight, times the material's) is
    opaque white.

    The fragment colour is then (w0 + w1 + w2)^2 * k / 255 per colour
    channel and (w0 + w1 + w2) * k / 255 for alpha
    (`softras.kernels.interpolate._shade_word`; corner
    colours of clipped triangles are sums of clip weights, 1 within a few
    ulp).  At a covered pixel centre the perspective weights are within
    rounding of [0, 1] and sum to 1 within a few ulp, so the value is k/255 within ~1e-15,
    and `softras.pipeline.ops.unorm8` gives back k (the product is within ~1e-13 of the
    integer k, nowhere near a rounding boundary; tests/test_fastpath.py
    checks every k).  The kernel uses it at one sample only, where the
    weights are taken at the covered sample itself."""
    return bool(np.all(base == 1.0))
