"""Texture sampling for the compiled path.

Mirrors `softras.pipeline.texture.sample` in gl precision for the samplers
`softras.kernels.draw.unsupported` lets through (nearest or linear, with or
without mipmaps; any wrap; 8.8 fixed-point or float weights; llvmpipe's
anisotropic filter): the level of detail per 2x2 quad (`_quad_lod`,
`_lanes_aniso_levels`), the texel addresses, the fetches and the filters,
either per lane (`_sample_lane`, any filter, the anisotropic one with the
stages' own `softras.pipeline.texture.ewa_texel`) or vectorised over the
lanes (`_lanes_bilinear_fixed`, 8.8 bilinear, and `_lanes_nearest_fixed`,
nearest, with power-of-two or clamped wraps).  The 8.8 filters run on
RGBA8 texels spread into 16-bit lanes (`softras.kernels.rgba8`).

`texture_tables` turns a prepared texture (`softras.pipeline.texture.prepare`)
into the kernel's tables: a parameter vector (layout below), the mip chain's
texels as one flat buffer and a level table.

Why one module of ~640 lines: every function here mirrors one stage
function, `softras.pipeline.texture.sample`, in the order it works (tables,
addresses and filters, level of detail, the lanes' and the single lane's
samplers), and the lane filters and the scalar sampler share its address
and filter helpers; softras's own filters, which mirror
`softras.pipeline.texture_beyond`, are `softras.kernels.texture_beyond`.
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.lanes import (_LF_FRAC, _LF_S, _LF_SCALE, _LF_T, _LF_TEX, _LI_ADDR, _LI_BASE, _LI_FRAC8,
                                   _LI_IMGF, _LI_LEVEL, _LI_LH, _LI_LW, _LI_TWO, _LI_W8, _LI_WORD)
from softras.kernels.rgba8 import _HALF_LANES, _LANES, _lane, _spread, _unspread
from softras.kernels.stamp import sources_stamp
from softras.pipeline import texture as texture_stage
from softras.pipeline.ops import BYTE_VALUES
from softras.pipeline.texture import WRAP_CODES, wrap_index
from softras.scene.texels import levels_buffer

FILTER_CODES = {"nearest": 0, "linear": 1}
_LINEAR = FILTER_CODES["linear"]                # (a constant the kernels read)
MIN_FILTERS = ("nearest", "linear") + texture_stage.MIPMAP_FILTERS

# A texture's sampler state as the kernels read it, every field an int:
# the image filters for minification and magnification (FILTER_CODES), the
# mip mode (0 none, 1 nearest, 2 linear), the wraps of s and t (WRAP_CODES),
# fixed8 (1: llvmpipe's 8.8 fixed-point weights,
# `softras.pipeline.texture.uses_fixed_point`), the number of levels used,
# which vectorised filter applies (VECTORISED_LINEAR: `_lanes_bilinear_fixed`,
# VECTORISED_NEAREST: `_lanes_nearest_fixed`; 0: none, `_sample_lane`),
# whether the sampler is llvmpipe's anisotropic one (`_aniso_lane`), for
# the ripmap filter (`softras.kernels.texture_beyond.ripmap_tables`) the
# ripmap's levels along u (0: not a ripmap), and which of softras's own
# filters it is (`softras.kernels.texture_beyond.BEYOND_CODES`; 0: a GL one).
Sampler = namedtuple("Sampler", ["min_filter", "mag_filter", "mip", "wrap_s", "wrap_t", "fixed8", "levels",
                                 "vectorised", "aniso", "ripmap", "beyond"])

# A prepared texture's texels as the kernels read them (`texture_tables`): the
# used mip levels as one flat buffer of bytes (N,) uint8, the same buffer as
# RGBA8 words (N / 4,) uint32, the level table (L, 3) int64: byte offset,
# width, height per level, and the anisotropic filter's weights (1024,)
# float32 (`softras.pipeline.texture.llvmpipe_ewa_table`).  (Kept apart
# from the `Sampler`: numba's parallel loops take a record of arrays or of
# scalars as an argument, not a record holding a record.)
Texels = namedtuple("Texels", ["bytes", "words", "levels", "ewa"])

_EWA = texture_stage.llvmpipe_ewa_table()

# What an untextured draw passes (the same types: one compiled kernel).
NO_TEXTURE = (Sampler(0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0),
              Texels(np.zeros(4, np.uint8), np.zeros(1, np.uint32), np.zeros((1, 3), np.int64), _EWA))


VECTORISED_LINEAR, VECTORISED_NEAREST = 1, 2

_tables_cache: dict = {}


def texture_tables(tex: texture_stage.MipTexture, fixed_point: bool):
    """A prepared texture as the kernels read it, (`Sampler`, `Texels`); cached
    per prepared texture (`softras.pipeline.texture.prepare` returns the same object for a scene texture)."""
    return cached_tables(tex, bool(fixed_point), lambda: _texture_tables(tex, fixed_point))


def cached_tables(tex: texture_stage.MipTexture, kind, make):
    """The tables ``make()`` builds for the prepared texture ``tex``, once per
    (texture, kind) (at most 16 kept)."""
    key = (id(tex), kind)
    hit = _tables_cache.get(key)
    if hit is not None and hit[0] is tex:
        return hit[1]
    tables = make()
    if len(_tables_cache) >= 16:
        _tables_cache.clear()
    _tables_cache[key] = (tex, tables)
    return tables


def level_table(levels) -> np.ndarray:
    """The level table (L, 3) int64 of (H, W, 4) uint8 levels laid out one
    after the other in one buffer: byte offset, width, height per level."""
    table = np.zeros((len(levels), 3), np.int64)
    at = 0
    for k, level in enumerate(levels):
        h, w = level.shape[:2]
        table[k] = (at, w, h)
        at += h * w * 4
    return table


def _texture_tables(tex: texture_stage.MipTexture, fixed_point: bool):
    levels = tex.used_levels
    table = level_table(levels)
    flat = levels_buffer(levels)                    # the mip chain's own buffer: no copy
    mip = 0
    if tex.mipmapped:
        mip = 1 if tex.min_filter.endswith("mipmap_nearest") else 2
    fixed8 = fixed_point and texture_stage.uses_fixed_point(tex, True)
    min_filter, mag_filter = FILTER_CODES[tex.min_filter.split("_")[0]], FILTER_CODES[tex.mag_filter]
    h, w = levels[0].shape[:2]
    # The vectorised filters: 8.8 bilinear, or nearest, on every level (one
    # image filter for minification and magnification), wraps by mask or
    # clamp (a power-of-two level 0 has power-of-two levels all the way down).
    vectorised = 0
    if fixed8 and min_filter == mag_filter and all(mode == "clamp_to_edge" or (size & (size - 1)) == 0
                                                   for mode, size in ((tex.wrap_s, w), (tex.wrap_t, h))):
        vectorised = VECTORISED_LINEAR if min_filter == FILTER_CODES["linear"] else VECTORISED_NEAREST
    aniso = texture_stage.effective_anisotropy(tex.max_anisotropy, True) > 1    # (then never fixed8)
    sampler = Sampler(min_filter, mag_filter, mip, WRAP_CODES[tex.wrap_s], WRAP_CODES[tex.wrap_t], int(fixed8),
                      len(levels), vectorised, int(aniso), 0, 0)
    return sampler, Texels(flat, flat.view(np.uint32), table, _EWA)


# ----------------------------------------------------------------------------- addresses and filters


@numba.njit(cache=True, inline="always")
def _nearest(s, size, mode):
    """`softras.pipeline.texture.nearest_addresses` (gl): the texel index of coordinate s."""
    return wrap_index(np.int64(np.floor(np.float32(s) * np.float32(size))), size, mode)


@numba.njit(cache=True, inline="always")
def _linear_fixed(s, size, mode):
    """`softras.pipeline.texture.linear_addresses` with fixed8: (i0, i1, weight 0..255)."""
    s32 = np.float32(s)
    if mode == 0 and (size & (size - 1)) != 0:
        f = s32 - np.float32(np.floor(s32))
        fixed = np.int64(np.rint(np.float32(f * np.float32(size)) * np.float32(256))) - 128
        weight = fixed & 255
        i0 = fixed >> 8
        if i0 < 0:
            i0 = size - 1
        i0 = min(i0, size - 1)
        i1 = i0 + 1 if i0 != size - 1 else 0
        return i0, i1, weight
    fixed = np.int64(np.rint(np.float32(s32 * np.float32(size * 256)))) - 128
    weight = fixed & 255
    i0 = fixed >> 8
    return wrap_index(i0, size, mode), wrap_index(i0 + 1, size, mode), weight


@numba.njit(cache=True, error_model="numpy", inline="always")
def _linear_float(s, size, mode):
    """`softras.pipeline.texture.linear_addresses` with float weights
    (`softras.scene.texels.linear_float_addresses`): (i0, i1, weight)."""
    u = s * size - 0.5
    fu = np.floor(u)
    return wrap_index(np.int64(fu), size, mode), wrap_index(np.int64(fu) + 1, size, mode), u - fu


@numba.njit(cache=True, error_model="numpy", inline="always")
def _bilinear_float(a, b, t00, t10, t01, t11):
    """The float bilinear filter of `softras.pipeline.texture.filter_level`
    (`softras.scene.texels.bilinear`) on one channel: texels t00, t10 (row 0)
    and t01, t11 (row 1), weights a across and b down."""
    return (1 - a) * (1 - b) * t00 + a * (1 - b) * t10 + (1 - a) * b * t01 + a * b * t11


@numba.njit(cache=True, inline="always")
def _wrap_select(i, size, mode):
    """`softras.pipeline.texture.wrap_index` for a power-of-two size (or clamp_to_edge, any size)
    without branches, so that a loop over lanes vectorises."""
    repeat = i & (size - 1)
    clamped = min(max(i, 0), size - 1)
    m = i & (2 * size - 1)
    mirrored = m if m < size else 2 * size - 1 - m
    return clamped if mode == 1 else (repeat if mode == 0 else mirrored)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _filter_level(texels, base, lw, lh, s, t, linear, wrap_s, wrap_t):
    """`softras.pipeline.texture.filter_level` in float64 (exact precision,
    and softras's own filters' levels in any,
    `softras.kernels.texture_beyond._beyond_lane`) on the level of lw x lh
    texels from byte ``base`` of ``texels`` (the mip chain's bytes, RGBA8
    premultiplied): nearest (``floor(s W)``, wrapped) or the float bilinear
    filter.  Returns the four channels on the 0..255
    scale, float64."""
    if not linear:
        i = wrap_index(np.int64(np.floor(s * lw)), lw, wrap_s)
        j = wrap_index(np.int64(np.floor(t * lh)), lh, wrap_t)
        at = base + (j * lw + i) * 4
        return (np.float64(texels[at]), np.float64(texels[at + 1]), np.float64(texels[at + 2]),
                np.float64(texels[at + 3]))
    i0, i1, a = _linear_float(s, lw, wrap_s)
    j0, j1, b = _linear_float(t, lh, wrap_t)
    at00, at10 = base + (j0 * lw + i0) * 4, base + (j0 * lw + i1) * 4
    at01, at11 = base + (j1 * lw + i0) * 4, base + (j1 * lw + i1) * 4
    return (_bilinear_float(a, b, np.float64(texels[at00]), np.float64(texels[at10]), np.float64(texels[at01]),
                            np.float64(texels[at11])),
            _bilinear_float(a, b, np.float64(texels[at00 + 1]), np.float64(texels[at10 + 1]),
                            np.float64(texels[at01 + 1]), np.float64(texels[at11 + 1])),
            _bilinear_float(a, b, np.float64(texels[at00 + 2]), np.float64(texels[at10 + 2]),
                            np.float64(texels[at01 + 2]), np.float64(texels[at11 + 2])),
            _bilinear_float(a, b, np.float64(texels[at00 + 3]), np.float64(texels[at10 + 3]),
                            np.float64(texels[at01 + 3]), np.float64(texels[at11 + 3])))


@numba.njit(cache=True, inline="always")
def _lerp_lanes(w, a, b):
    """`softras.pipeline.texture.lerp8` (``_lerp8(w, a, b) = a + ((w (b - a) +
    128) >> 8)``) on all four lanes at
    once, for 0 <= w <= 256: the same integer as ``((256 - w) a + w b + 128) >> 8``,
    which stays below 2^16 in every lane (no carry between lanes)."""
    return ((np.uint64(256 - w) * a + np.uint64(w) * b + _HALF_LANES) >> np.uint64(8)) & _LANES


@numba.njit(cache=True, inline="always")
def _bilerp_lanes(fa, fb, t00, t10, t01, t11):
    """llvmpipe's 8.8 bilinear filter (`softras.pipeline.texture.filter_level`
    with fixed8) on spread lanes: texels t00, t10 (row
    0) and t01, t11 (row 1) with weights fa across and fb down (0..255)."""
    return _lerp_lanes(fb, _lerp_lanes(fa, t00, t10), _lerp_lanes(fa, t01, t11))


@numba.njit(cache=True, inline="always")
def _lerp8(w, a, b):
    """`softras.pipeline.texture.lerp8`: llvmpipe's 8.8 fixed-point lerp of
    bytes a, b with weight w in 0..256."""
    return a + ((w * (b - a) + 128) >> 8)


@numba.njit(cache=True, inline="always")
def _bilerp8(fa, fb, t00, t10, t01, t11):
    """`_bilerp_lanes` of one channel: bytes t00, t10 (row 0) and t01, t11
    (row 1), weights fa across and fb down, by `_lerp8`."""
    return _lerp8(fb, _lerp8(fa, t00, t10), _lerp8(fa, t01, t11))


# ----------------------------------------------------------------------------- level of detail


@numba.njit(cache=True, inline="always")
def _nan_max(x, y):
    """np.maximum as `softras.pipeline.texture.rho_squared` takes it: NaN if
    either is NaN (selects, no branches)."""
    return x + y if (x != x) | (y != y) else (x if x >= y else y)


_FLOAT32_TINY = np.float32(np.finfo(np.float32).tiny)


@numba.njit(cache=True, inline="always")
def _frexp32(x):
    """np.frexp (of `softras.pipeline.texture.choose_levels` and
    `softras.pipeline.texture.fast_log2`) of a float32 x from its bits: (mantissa in [0.5, 1) as
    float32, exponent) for a normal x; (x, 0) for inf and NaN as C's frexp
    gives them.  (Subnormals are not handled: callers pass x >= the
    smallest normal or only use the exponent of x > 0, where a subnormal's
    -126 and frexp's lower exponent select the same level.)"""
    bits = np.int64(np.float32(x).view(np.int32))
    field = (bits >> 23) & 255
    special = field == 255
    mantissa = np.int32((bits & 0x807FFFFF) | 0x3F000000).view(np.float32)
    return (np.float32(x) if special else mantissa), (0 if special else field - 126)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lengths2(ddx_s, ddx_t, ddy_s, ddy_t, width0, height0):
    """The squared lengths |du|^2, |dv|^2 (float32) of one quad's texel-space
    derivative vectors (`softras.pipeline.texture.texel_derivatives`, gl:
    the float32 derivatives of (s, t) times the level-0 size width0 x
    height0), as `softras.pipeline.texture.rho_squared` and
    `softras.pipeline.texture.llvmpipe_aniso_levels` sum them."""
    w32 = np.float32(width0)
    h32 = np.float32(height0)
    du0 = np.float32(ddx_s) * w32
    du1 = np.float32(ddx_t) * h32
    dv0 = np.float32(ddy_s) * w32
    dv1 = np.float32(ddy_t) * h32
    return du0 * du0 + du1 * du1, dv0 * dv0 + dv1 * dv1


@numba.njit(cache=True, error_model="numpy", inline="always")
def _quad_lod(sampler, width0, height0, ddx_s, ddx_t, ddy_s, ddy_t):
    """The level choice of `softras.pipeline.texture.sample` (gl precision:
    `softras.pipeline.texture.rho_squared` and `softras.pipeline.texture.choose_levels`)
    for one quad's derivatives (float32 values) on a texture whose level 0 is
    width0 x height0 (`Sampler` sampler): (level0, level1, frac, image
    filter, whether to blend two levels).  Written with selects, no branches
    to mispredict and no call to frexp; lod = +-inf or NaN picks levels as the
    float -> int64 conversion of numpy and llvmpipe does (the "integer
    indefinite", negative)."""
    mip, last, mag_filter, min_filter = sampler.mip, sampler.levels - 1, sampler.mag_filter, sampler.min_filter
    px2, py2 = _lengths2(ddx_s, ddx_t, ddy_s, ddy_t, width0, height0)
    rho2 = _nan_max(px2, py2)                           # float32
    magnified = not (rho2 > 1)
    level0 = 0
    level1 = 0
    frac = 0.0
    if mip == 1:
        e = _frexp32(rho2)[1]                          # (rho2 > 0: a subnormal's -126 -> level 0 too)
        level = e >> 1 if rho2 > 0 else 0
        level0 = min(max(level, 0), last)
        level1 = level0
    elif mip == 2:
        m, e = _frexp32(_nan_max(rho2, _FLOAT32_TINY))
        log2 = np.float32(np.float32(e - 1) + (np.float32(2) * m - np.float32(1)))
        lod = np.float32(0.5) * log2
        ipart_f = np.float32(np.floor(lod))
        frac = np.float64(np.float32(lod - ipart_f))
        finite = np.abs(ipart_f) <= np.float32(1e6)     # (|lod| <= 64 when finite)
        ipart = np.int64(ipart_f if finite else np.float32(-1e6))
        frac = 0.0 if (ipart < 0) | (ipart >= last) else frac
        level0 = min(max(ipart, 0), last)
        level1 = min(max(ipart + 1, 0), last)
    level0 = 0 if magnified else level0
    image_filter = mag_filter if magnified else min_filter
    two = (not magnified) & (level1 != level0) & (frac > 0)
    return level0, level1, frac, image_filter, two


@numba.njit(cache=True, inline="always")
def _quad_st_derivatives(l, lf):
    """The (s, t) derivatives of lane l's 2x2 quad as
    `softras.pipeline.interpolate.quad_derivatives` takes them: from its
    top-left, top-right and bottom-left lanes' (s, t) rounded to float32,
    (ds/dx, dt/dx, ds/dy, dt/dy) in float32."""
    q = l & -4
    s_tl, t_tl = np.float32(lf[_LF_S, q]), np.float32(lf[_LF_T, q])
    return (np.float32(lf[_LF_S, q + 1]) - s_tl, np.float32(lf[_LF_T, q + 1]) - t_tl,
            np.float32(lf[_LF_S, q + 2]) - s_tl, np.float32(lf[_LF_T, q + 2]) - t_tl)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lanes_lod(n, sampler, width0, height0, lf, li):
    """`_quad_lod` of each of the n / 4 quads listed in the lanes (top-left,
    top-right, bottom-left lanes give the derivatives of (s, t),
    `softras.pipeline.interpolate.quad_derivatives` rounded to float32), kept
    on the quad's first lane: levels, image filter, whether it blends two
    levels (_LI_LEVEL, _LI_IMGF, _LI_TWO) and the blend fraction (_LF_FRAC).
    Returns whether any quad blends two levels."""
    any_two = False
    for q in range(n >> 2):
        l = 4 * q
        ddx_s, ddx_t, ddy_s, ddy_t = _quad_st_derivatives(l, lf)
        level0, level1, frac, image_filter, two = _quad_lod(sampler, width0, height0, ddx_s, ddx_t, ddy_s, ddy_t)
        li[_LI_LEVEL, l] = level0
        li[_LI_LEVEL + 1, l] = level1
        li[_LI_IMGF, l] = image_filter
        li[_LI_TWO, l] = two
        lf[_LF_FRAC, l] = frac
        any_two |= two
    return any_two


@numba.njit(cache=True, error_model="numpy", inline="always")
def _aniso_level(ddx_s, ddx_t, ddy_s, ddy_t, width0, height0, last):
    """`softras.pipeline.texture.llvmpipe_aniso_levels` of one quad's
    derivatives (float32 values) on a texture whose level 0 is width0 x
    height0: ``pmin2 = min(|du|^2, |dv|^2)`` in float32 (NaN if either is),
    ``lod = 0.5 fast_log2(pmin2)``, the level ``clamp(trunc(lod), 0, last)``
    (NaN -> 0, +inf -> last).  `_frexp32` gives a level-0 exponent for 0 and
    subnormals where frexp gives a lower one: both make lod negative."""
    px2, py2 = _lengths2(ddx_s, ddx_t, ddy_s, ddy_t, width0, height0)
    pmin2 = -_nan_max(-px2, -py2)                       # np.minimum: NaN if either is
    m, e = _frexp32(pmin2)
    lod = np.float32(0.5) * np.float32(np.float32(e - 1) + (np.float32(2) * m - np.float32(1)))
    if not lod > 0:                                     # (NaN and negative: level 0)
        return 0
    return min(np.int64(lod), last) if lod < np.float32(1e6) else last


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lanes_aniso_levels(n, sampler, width0, height0, lf, li):
    """`_aniso_level` of each of the n / 4 quads listed in the lanes (their
    derivatives as `_lanes_lod` takes them), kept on the quad's first lane
    as `_lanes_lod` keeps its choice: one level, the linear image filter
    (the scalar filter's bilinear where no texel got weight, as
    `softras.pipeline.texture.sample_anisotropic_llvmpipe`), no blend."""
    for q in range(n >> 2):
        l = 4 * q
        ddx_s, ddx_t, ddy_s, ddy_t = _quad_st_derivatives(l, lf)
        level = _aniso_level(ddx_s, ddx_t, ddy_s, ddy_t, width0, height0, sampler.levels - 1)
        li[_LI_LEVEL, l] = level
        li[_LI_LEVEL + 1, l] = level
        li[_LI_IMGF, l] = _LINEAR
        li[_LI_TWO, l] = 0
        lf[_LF_FRAC, l] = 0.0


def _make_aniso_lane(sources: str):
    """The kernel `_aniso_lane`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable): a function
    of its own, not inlined, as `softras.kernels.texture_beyond._beyond_texel`,
    so that the textured tile drivers call one compiled copy of llvmpipe's
    anisotropic filter (inlined, it made each driver's compile longer; see
    docs/speed.md)."""

    @numba.njit(cache=True, error_model="numpy")
    def _aniso_lane(l, lf, li, sampler, texels, table, ewa):
        """llvmpipe's anisotropic filter of lane l (`softras.pipeline.texture.ewa_texel`
        on its quad's `_lanes_aniso_levels` level, the quad's derivatives in
        float32, its own (s, t) in float32) into the _LF_TEX rows; returns False
        where no texel got weight (the caller filters bilinearly)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        ddx_s, ddx_t, ddy_s, ddy_t = _quad_st_derivatives(l, lf)
        level = li[_LI_LEVEL, l]
        r, g, b, a, _ = texture_stage.ewa_texel(
            texels, table[level, 0] >> 2, table[level, 1], table[level, 2], level,
            np.float32(lf[_LF_S, l]), np.float32(lf[_LF_T, l]), ddx_s, ddy_s, ddx_t, ddy_t,
            table[0, 1], table[0, 2], sampler.wrap_s, sampler.wrap_t, ewa)
        if r != r:
            return False
        lf[_LF_TEX, l] = np.float64(r)
        lf[_LF_TEX + 1, l] = np.float64(g)
        lf[_LF_TEX + 2, l] = np.float64(b)
        lf[_LF_TEX + 3, l] = np.float64(a)
        return True

    return _aniso_lane


_aniso_lane = _make_aniso_lane(sources_stamp(texture_stage))


# ----------------------------------------------------------------------------- the lanes


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lanes_bilinear_fixed(n, n_levels, words, red_only, lf, li, lu, texels32, sampler):
    """`softras.pipeline.texture.sample` (gl, fixed8, linear image filter, power-of-two or
    clamped wraps) of every lane on its first level or (n_levels 2) its two
    levels (the same level twice with mip weight 0 where the quad uses one):
    addresses and 8.8 weights (`_linear_fixed`, vectorised), the 4 or 8 texel
    fetches (scalar), the lane lerps (vectorised).  Writes the texel as k/255
    floats into the _LF_TEX rows (with ``red_only`` its red channel alone,
    all a bump map reads, filtered as bytes: `_lerp8`, which is
    `_lerp_lanes` per channel), or with ``words`` as its RGBA8 word into
    the _LI_WORD row.  (k/255 divided, not looked up in
    `BYTE_VALUES`: a loop of gathers from numba's constant array took 10.8
    ns a lane against 2.6 for the four divisions.)"""
    wrap_s, wrap_t = sampler.wrap_s, sampler.wrap_t
    for lv in range(n_levels):
        for l in range(n):
            lw, lh = li[_LI_LW + lv, l], li[_LI_LH + lv, l]
            scale_s, scale_t = np.float32(lf[_LF_SCALE + 2 * lv, l]), np.float32(lf[_LF_SCALE + 2 * lv + 1, l])
            fs = np.int64(np.rint(np.float32(np.float32(lf[_LF_S, l]) * scale_s))) - 128
            ft = np.int64(np.rint(np.float32(np.float32(lf[_LF_T, l]) * scale_t))) - 128
            li[_LI_FRAC8 + 2 * lv, l] = fs & 255
            li[_LI_FRAC8 + 2 * lv + 1, l] = ft & 255
            i0 = _wrap_select(fs >> 8, lw, wrap_s)
            i1 = _wrap_select((fs >> 8) + 1, lw, wrap_s)
            row0 = li[_LI_BASE + lv, l] + _wrap_select(ft >> 8, lh, wrap_t) * lw
            row1 = li[_LI_BASE + lv, l] + _wrap_select((ft >> 8) + 1, lh, wrap_t) * lw
            li[_LI_ADDR + 4 * lv, l] = row0 + i0
            li[_LI_ADDR + 4 * lv + 1, l] = row0 + i1
            li[_LI_ADDR + 4 * lv + 2, l] = row1 + i0
            li[_LI_ADDR + 4 * lv + 3, l] = row1 + i1
    if red_only:            # one channel: plain integer lerps (`_lerp8`), 14.3 -> 9.6 ns a lane at two levels
        for a in range(4 * n_levels):
            for l in range(n):
                lu[a, l] = texels32[li[_LI_ADDR + a, l]] & 255
        for l in range(n):
            fa0, fb0 = li[_LI_FRAC8, l], li[_LI_FRAC8 + 1, l]
            red = _bilerp8(fa0, fb0, np.int64(lu[0, l]), np.int64(lu[1, l]), np.int64(lu[2, l]), np.int64(lu[3, l]))
            if n_levels == 2:
                fa1, fb1 = li[_LI_FRAC8 + 2, l], li[_LI_FRAC8 + 3, l]
                red = _lerp8(li[_LI_W8, l], red, _bilerp8(fa1, fb1, np.int64(lu[4, l]), np.int64(lu[5, l]),
                                                          np.int64(lu[6, l]), np.int64(lu[7, l])))
            lf[_LF_TEX, l] = np.float64(red) / 255.0
        return
    for a in range(4 * n_levels):
        for l in range(n):
            lu[a, l] = _spread(texels32[li[_LI_ADDR + a, l]])
    if n_levels == 2:
        for l in range(n):
            fa0, fb0 = li[_LI_FRAC8, l], li[_LI_FRAC8 + 1, l]
            fa1, fb1 = li[_LI_FRAC8 + 2, l], li[_LI_FRAC8 + 3, l]
            x = _bilerp_lanes(fa0, fb0, lu[0, l], lu[1, l], lu[2, l], lu[3, l])
            y = _bilerp_lanes(fa1, fb1, lu[4, l], lu[5, l], lu[6, l], lu[7, l])
            lu[0, l] = _lerp_lanes(li[_LI_W8, l], x, y)
    else:
        for l in range(n):
            fa0, fb0 = li[_LI_FRAC8, l], li[_LI_FRAC8 + 1, l]
            lu[0, l] = _bilerp_lanes(fa0, fb0, lu[0, l], lu[1, l], lu[2, l], lu[3, l])
    _store_texels(n, words, lf, li, lu)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _store_texels(n, words, lf, li, lu):
    """The n lanes' filtered texels (spread lanes in lu's row 0) stored
    as the lane filters give them: with ``words`` each one's RGBA8 word
    into the _LI_WORD row, else its channels as k/255 floats into the
    _LF_TEX rows.  (Separate loops: one loop with a branch on ``words``
    compiles to both sides computed and masked stores; a channel count
    read at run time took 6.6 ns a lane for four channels against 2.6
    unrolled.)"""
    if words:
        for l in range(n):
            li[_LI_WORD, l] = _unspread(lu[0, l])
    else:
        for l in range(n):
            for c in range(4):
                lf[_LF_TEX + c, l] = np.float64(_lane(lu[0, l], c)) / 255.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lanes_nearest_fixed(n, n_levels, words, lf, li, lu, texels32, sampler):
    """`softras.pipeline.texture.sample` (gl, fixed8, nearest image filter,
    power-of-two or clamped wraps) of every lane on its first level or
    (n_levels 2) its two levels (the same level twice with mip weight 0
    where the quad uses one), as `_sample_lane` takes a nearest texel: its
    address (`_nearest`, by `_wrap_select`), the fetch, the two levels'
    texels blended as spread lanes (`_lerp_lanes`).  Writes the texel as
    k/255 floats into the _LF_TEX rows or with ``words`` its RGBA8 word into
    the _LI_WORD row, as `_lanes_bilinear_fixed` does; the level rows as it
    reads them (`_quad_levels`)."""
    wrap_s, wrap_t = sampler.wrap_s, sampler.wrap_t
    for lv in range(n_levels):
        for l in range(n):
            lw, lh = li[_LI_LW + lv, l], li[_LI_LH + lv, l]
            i = _wrap_select(np.int64(np.floor(np.float32(lf[_LF_S, l]) * np.float32(lw))), lw, wrap_s)
            j = _wrap_select(np.int64(np.floor(np.float32(lf[_LF_T, l]) * np.float32(lh))), lh, wrap_t)
            li[_LI_ADDR + lv, l] = li[_LI_BASE + lv, l] + j * lw + i
    for lv in range(n_levels):
        for l in range(n):
            lu[lv, l] = _spread(texels32[li[_LI_ADDR + lv, l]])
    if n_levels == 2:
        for l in range(n):
            lu[0, l] = _lerp_lanes(li[_LI_W8, l], lu[0, l], lu[1, l])
    _store_texels(n, words, lf, li, lu)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _sample_lane(l, lf, li, texel, sampler, texels, texels32, table, ewa):
    """`softras.pipeline.texture.sample` (gl precision) of lane l on its quad's level(s), any
    filter and wrap (the scalar path beside `_lanes_bilinear_fixed`), the
    anisotropic filter (`_aniso_lane`) included; sampler : the texture's
    `Sampler`; texels, texels32, table, ewa : its `Texels` (arrays passed one
    by one: taken out of the record per lane, they would cost reference
    counts per lane); texel : (2, 4) float64 scratch."""
    if sampler.aniso != 0 and _aniso_lane(l, lf, li, sampler, texels, table, ewa):
        return
    wrap_s, wrap_t, fixed8 = sampler.wrap_s, sampler.wrap_t, sampler.fixed8 != 0
    s_px, t_px = lf[_LF_S, l], lf[_LF_T, l]
    image_filter = li[_LI_IMGF, l]
    two = li[_LI_TWO, l] != 0
    frac = lf[_LF_FRAC, l]
    n_levels = 2 if two else 1
    lanes = fixed8 or (image_filter == 0 and not two)
    lanes_texel = np.uint64(0)
    x = np.uint64(0)
    for lv in range(n_levels):
        level = li[_LI_LEVEL + lv, l]
        base, lw, lh = table[level, 0], table[level, 1], table[level, 2]
        if image_filter == 0:
            i = _nearest(s_px, lw, wrap_s)
            jj = _nearest(t_px, lh, wrap_t)
            if lanes:
                x = _spread(texels32[(base >> 2) + jj * lw + i])
            else:
                for c in range(4):
                    texel[lv, c] = np.float64(texels[base + (jj * lw + i) * 4 + c])
        elif lanes:
            i0, i1, fa = _linear_fixed(s_px, lw, wrap_s)
            j0, j1, fb = _linear_fixed(t_px, lh, wrap_t)
            row0 = (base >> 2) + j0 * lw
            row1 = (base >> 2) + j1 * lw
            x = _bilerp_lanes(fa, fb, _spread(texels32[row0 + i0]), _spread(texels32[row0 + i1]),
                              _spread(texels32[row1 + i0]), _spread(texels32[row1 + i1]))
        else:
            i0, i1, fa = _linear_float(s_px, lw, wrap_s)
            j0, j1, fb = _linear_float(t_px, lh, wrap_t)
            for c in range(4):
                texel[lv, c] = _bilinear_float(
                    fa, fb, np.float64(texels[base + (j0 * lw + i0) * 4 + c]),
                    np.float64(texels[base + (j0 * lw + i1) * 4 + c]),
                    np.float64(texels[base + (j1 * lw + i0) * 4 + c]),
                    np.float64(texels[base + (j1 * lw + i1) * 4 + c]))
        if lanes:
            lanes_texel = x if lv == 0 else _lerp_lanes(li[_LI_W8, l], lanes_texel, x)
    if lanes:
        for c in range(4):
            lf[_LF_TEX + c, l] = BYTE_VALUES[_lane(lanes_texel, c)]
    else:
        if two:
            for c in range(4):
                texel[0, c] = texel[0, c] + frac * (texel[1, c] - texel[0, c])
        for c in range(4):
            lf[_LF_TEX + c, l] = texel[0, c] / 255.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _quad_levels(q, on, sampler, table, vectorised, any_two, lf, li):
    """Quad q's level choice (`_lanes_lod` or `_lanes_aniso_levels`, on its
    first lane) on its four lanes, as the filter reads it: the level rows of
    `_lanes_bilinear_fixed` (word offset, size and 8.8 scales of the first
    level and, where ``any_two``, the second) when ``vectorised``, else those of
    `_sample_lane`, and the mip weight (0..256).  A quad that is not ``on``
    (no lane to shade) samples level 0 alone.  Returns whether the quad
    blends two levels."""
    l = 4 * q
    level0, level1 = li[_LI_LEVEL, l], li[_LI_LEVEL + 1, l]
    image_filter, two, frac = li[_LI_IMGF, l], li[_LI_TWO, l] != 0, lf[_LF_FRAC, l]
    if not on:
        level0 = level1 = 0
        image_filter = sampler.mag_filter
        two = False
        frac = 0.0
    w8 = np.int64(np.floor(frac * 256)) if two else 0
    if vectorised:
        for lv in range(2 if any_two else 1):     # (the second level's rows only where read)
            level = level1 if (lv == 1 and two) else level0
            lw, lh, base = table[level, 1], table[level, 2], table[level, 0] >> 2
            scale_s, scale_t = np.float32(lw * 256), np.float32(lh * 256)
            for l in range(4 * q, 4 * q + 4):
                li[_LI_BASE + lv, l] = base
                li[_LI_LW + lv, l] = lw
                li[_LI_LH + lv, l] = lh
                lf[_LF_SCALE + 2 * lv, l] = scale_s
                lf[_LF_SCALE + 2 * lv + 1, l] = scale_t
    for l in range(4 * q, 4 * q + 4):
        li[_LI_W8, l] = w8
        if not vectorised:
            li[_LI_LEVEL, l] = level0
            li[_LI_LEVEL + 1, l] = level1
            li[_LI_IMGF, l] = image_filter
            li[_LI_TWO, l] = two
            lf[_LF_FRAC, l] = frac
    return two
