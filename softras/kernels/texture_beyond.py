"""softras's own texture filters for the compiled paths: ripmap, EWA, level 0.

`_beyond_texel` mirrors `softras.pipeline.texture_beyond.sample_beyond`
(``texture_filter`` "ripmap", "ewa" or "level0"; float64 in any precision)
one sample at a time, with the stage's operations in their order: the
ripmap's lambdas and its level or the four levels around them
(`_ripmap_texel`); EWA's footprint ellipse, its level or two and the
stage's own per-sample ellipse loop (`_ewa_texel`,
`softras.pipeline.texture_beyond.ewa_ellipse`); level 0's bilinear filter;
each level filtered by `softras.kernels.texture._filter_level`.  The
texture is one buffer of levels (`beyond_tables`: the ripmap's levels, the
mip chain, or level 0).  The textured tile drivers call it per lane with
the quad's derivatives (`_beyond_lane`, gl precision), the exact kernel
per fragment with the analytic ones (`softras.kernels.exact._texels`)."""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.lanes import _LF_S, _LF_T, _LF_TEX
from softras.kernels.stamp import sources_stamp
from softras.kernels.texture import (_EWA, _LINEAR, FILTER_CODES, Sampler, Texels, _filter_level, _nan_max,
                                     _quad_st_derivatives, cached_tables, level_table)
from softras.pipeline import libm, texture_beyond
from softras.pipeline import texture as texture_stage
from softras.pipeline.texture import WRAP_CODES
from softras.scene.texels import levels_buffer

# `Sampler.beyond` of each of softras's filters (0: a GL filter).
BEYOND_CODES = {"ripmap": 1, "ewa": 2, "level0": 3}
_RIPMAP, _EWA_FILTER = BEYOND_CODES["ripmap"], BEYOND_CODES["ewa"]


def beyond_tables(tex: texture_stage.MipTexture, name: str):
    """A texture under the ``texture_filter`` ``name`` (one of
    `softras.pipeline.texture_beyond.FILTERS`) as `_beyond_lane` reads it,
    (`Sampler`, `Texels`), cached per prepared texture
    (`softras.kernels.texture.cached_tables`): for "ripmap" `ripmap_tables`;
    for "ewa" the whole mip chain (``tex.levels``, whatever the min filter:
    the stage's), ``levels`` its count; for "level0" level 0 alone.  The
    sampler's ``beyond`` is the filter's `BEYOND_CODES`."""
    if name == "ripmap":
        return ripmap_tables(tex)
    return cached_tables(tex, name, lambda: _chain_tables(tex, name))


def _chain_tables(tex: texture_stage.MipTexture, name: str):
    levels = list(tex.levels if name == "ewa" else tex.levels[:1])
    flat = levels_buffer(levels)
    sampler = Sampler(FILTER_CODES["linear"], FILTER_CODES["linear"], 0, WRAP_CODES[tex.wrap_s],
                      WRAP_CODES[tex.wrap_t], 0, len(levels), 0, 0, 0, BEYOND_CODES[name])
    return sampler, Texels(flat, flat.view(np.uint32), level_table(levels), _EWA)


def ripmap_tables(tex: texture_stage.MipTexture):
    """A texture under the ``texture_filter`` "ripmap" as the kernels read it
    (`_ripmap_lane`), (`Sampler`, `Texels`): the levels of
    `softras.pipeline.texture_beyond.ripmap` (rip[j][i], i halvings along u,
    j along v) as one flat buffer, level (i, j) at row j n_u + i of the
    level table; the sampler's ``ripmap`` is n_u, ``levels`` n_u n_v, ``mip``
    1 for a mipmap_nearest min filter (the nearest level) and 2 otherwise.
    Cached per prepared texture (`softras.kernels.texture.cached_tables`)."""
    return cached_tables(tex, "ripmap", lambda: _ripmap_tables(tex))


def _ripmap_tables(tex: texture_stage.MipTexture):
    rip = texture_beyond.ripmap(tex)
    levels = [level for row in rip for level in row]
    flat = levels_buffer(levels)
    sampler = Sampler(FILTER_CODES["linear"], FILTER_CODES[tex.mag_filter],
                      1 if tex.min_filter.endswith("mipmap_nearest") else 2, WRAP_CODES[tex.wrap_s],
                      WRAP_CODES[tex.wrap_t], 0, len(levels), 0, 0, len(rip[0]), _RIPMAP)
    return sampler, Texels(flat, flat.view(np.uint32), level_table(levels), _EWA)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ripmap_level(lam, n):
    """`softras.pipeline.texture_beyond.sample_ripmap`'s lambda along one
    axis after ``np.nan_to_num(np.maximum(lam, 0.0), posinf=n - 1)``."""
    if lam != lam:
        return 0.0
    return float(n - 1) if lam == np.inf else max(lam, 0.0)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ripmap_texel(s, t, du0, du1, dv0, dv1, sampler, texels, table):
    """`softras.pipeline.texture_beyond.sample_ripmap` of one sample on the
    0..255 scale: the lambdas along u and v (`softras.pipeline.libm._log2`
    of the footprint's extents in level-0 texels, du = d(u, v)/dx, dv =
    d(u, v)/dy), magnified (both <= 0): the mag filter on level 0; else the
    nearest level (mipmap_nearest) or the four levels around the lambdas,
    each bilinear (`_filter_level`), weighted and summed in the stage's
    order.  The ripmap in `ripmap_tables`' layout."""
    w0, h0 = table[0, 1], table[0, 2]
    lam_u = libm._log2(_nan_max(np.abs(du0), np.abs(dv0)))
    lam_v = libm._log2(_nan_max(np.abs(du1), np.abs(dv1)))
    wrap_s, wrap_t = sampler.wrap_s, sampler.wrap_t
    if not ((lam_u > 0) | (lam_v > 0)):                 # magnified
        return _filter_level(texels, 0, w0, h0, s, t, sampler.mag_filter == _LINEAR, wrap_s, wrap_t)
    n_u = sampler.ripmap
    n_v = sampler.levels // n_u
    lu, lv = _ripmap_level(lam_u, n_u), _ripmap_level(lam_v, n_v)
    if sampler.mip == 1:                            # the nearest level along each axis: weights 1, 0, 0, 0
        i0 = i1 = np.int64(min(max(np.ceil(lu - 0.5), 0.0), float(n_u - 1)))
        j0 = j1 = np.int64(min(max(np.ceil(lv - 0.5), 0.0), float(n_v - 1)))
        fu = fv = 0.0
    else:
        i0 = np.int64(min(max(np.floor(lu), 0.0), float(n_u - 1)))
        j0 = np.int64(min(max(np.floor(lv), 0.0), float(n_v - 1)))
        fu = lu - i0 if i0 < n_u - 1 else 0.0
        fv = lv - j0 if j0 < n_v - 1 else 0.0
        i1, j1 = min(i0 + 1, n_u - 1), min(j0 + 1, n_v - 1)
    r = g = b = a = 0.0
    for k in range(4):
        i = i1 if k & 1 else i0
        j = j1 if k & 2 else j0
        weight = (fu if k & 1 else 1 - fu) * (fv if k & 2 else 1 - fv)
        if weight > 0:
            row = j * n_u + i
            cr, cg, cb, ca = _filter_level(texels, table[row, 0], table[row, 1], table[row, 2], s, t, True,
                                           wrap_s, wrap_t)
            r, g, b, a = r + weight * cr, g + weight * cg, b + weight * cb, a + weight * ca
    return r, g, b, a


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nan_to_num(x):
    """``np.nan_to_num`` of a float64: NaN 0, +-inf the largest finite float of its sign."""
    if x != x:
        return 0.0
    if x == np.inf:
        return np.finfo(np.float64).max
    return -np.finfo(np.float64).max if x == -np.inf else x


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ewa_level(s, t, s00, s01, s11, level, sampler, texels, table):
    """`softras.pipeline.texture_beyond.ewa_level` of one sample: the
    footprint S (level-0 texels) in the level's texels plus the identity,
    `softras.pipeline.texture_beyond.ewa_ellipse` there, and where it takes
    no texel the level's bilinear filter at (s, t) made finite."""
    w0, h0 = table[0, 1], table[0, 2]
    base, wl, hl = table[level, 0], table[level, 1], table[level, 2]
    su, sv = wl / w0, hl / h0
    r, g, b, a, _ = texture_beyond.ewa_ellipse(texels, base, wl, hl, s, t, s00 * su * su + 1.0, s01 * su * sv,
                                               s11 * sv * sv + 1.0, sampler.wrap_s, sampler.wrap_t,
                                               texture_beyond.EWA_ALPHA)
    if r != r:
        return _filter_level(texels, base, wl, hl, _nan_to_num(s), _nan_to_num(t), True, sampler.wrap_s,
                             sampler.wrap_t)
    return r, g, b, a


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ewa_texel(s, t, du0, du1, dv0, dv1, sampler, texels, table):
    """`softras.pipeline.texture_beyond.sample_ewa` of one sample on the
    0..255 scale: `softras.pipeline.texture_beyond.footprint_covariance` of
    du = d(u, v)/dx, dv = d(u, v)/dy (level-0 texels) with its minor axis
    grown to 1 / EWA_MAX_ECCENTRICITY of the major, the level from the minor
    semi-axis (`softras.pipeline.libm._log2`, NaN and -inf 0, clipped to the
    chain; a footprint wider than the last level takes shrunk),
    `_ewa_level` there, and with a fraction the next level's blended in.
    The mip chain in `beyond_tables`' layout."""
    s00 = du0 * du0 + dv0 * dv0
    s01 = du0 * du1 + dv0 * dv1
    s11 = du1 * du1 + dv1 * dv1
    mean = 0.5 * (s00 + s11)
    spread = np.sqrt(0.25 * ((s00 - s11) * (s00 - s11)) + s01 * s01)
    major2, minor2 = mean + spread, _nan_max(mean - spread, 0.0)
    wanted = major2 / (texture_beyond.EWA_MAX_ECCENTRICITY * texture_beyond.EWA_MAX_ECCENTRICITY)
    grow = wanted - minor2 if minor2 < wanted else 0.0
    k = grow / (2 * spread) if spread > 0 else 0.0
    s00 = s00 + k * (major2 - s00)
    s01 = s01 - k * s01
    s11 = s11 + k * (major2 - s11)
    minor = np.sqrt(_nan_max(minor2, wanted))
    last = sampler.levels - 1
    lam = libm._log2(minor / texture_beyond.EWA_MINOR_TEXELS)
    lam = 0.0 if (lam != lam) or lam == -np.inf else _nan_to_num(lam)
    lam = min(max(lam, 0.0), float(last))
    widest = 2 * texture_beyond.EWA_MINOR_TEXELS * float(1 << last)
    if minor > widest:                                  # (shrunk to what the last level takes)
        shrink = widest / minor
        shrink = shrink * shrink
        s00, s01, s11 = s00 * shrink, s01 * shrink, s11 * shrink
    level = np.int64(np.floor(lam))
    frac = lam - level
    r = g = b = a = 0.0
    # The level, then with a fraction the next one blended in (one loop: one
    # inlined copy of `_ewa_level`, a quarter of this function's compile).
    for upper in range(2 if frac > 0 and level < last else 1):
        cr, cg, cb, ca = _ewa_level(s, t, s00, s01, s11, level + upper, sampler, texels, table)
        if upper:
            r, g, b, a = r + frac * (cr - r), g + frac * (cg - g), b + frac * (cb - b), a + frac * (ca - a)
        else:
            r, g, b, a = cr, cg, cb, ca
    return r, g, b, a


def _make_beyond_texel(sources: str):
    """The kernel `_beyond_texel`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable): a function
    of its own, not inlined, so that the three textured tile drivers
    (`_beyond_lane`) and the exact kernel (`softras.kernels.exact._texels`)
    call one compiled copy (the ripmap inlined added about 40 s to the
    compile of each driver)."""

    @numba.njit(cache=True, error_model="numpy")
    def _beyond_texel(s, t, du0, du1, dv0, dv1, sampler, texels, table):
        """`softras.pipeline.texture_beyond.sample_beyond` of one sample at
        (s, t) with the filter ``sampler.beyond`` (`BEYOND_CODES`), du =
        d(u, v)/dx and dv = d(u, v)/dy in level-0 texels (float64): the
        ripmap (`_ripmap_texel`), EWA (`_ewa_texel`) or level 0's bilinear
        filter.  Returns (r, g, b, a) on the 0..255 scale, float64."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        if sampler.beyond == _RIPMAP:
            return _ripmap_texel(s, t, du0, du1, dv0, dv1, sampler, texels, table)
        if sampler.beyond == _EWA_FILTER:
            return _ewa_texel(s, t, du0, du1, dv0, dv1, sampler, texels, table)
        return _filter_level(texels, 0, table[0, 1], table[0, 2], s, t, True, sampler.wrap_s, sampler.wrap_t)

    return _beyond_texel


_beyond_texel = _make_beyond_texel(sources_stamp(texture_stage, libm, texture_beyond))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _beyond_lane(l, lf, sampler, texels, table):
    """`_beyond_texel` of lane l into the _LF_TEX rows, in [0, 1]: its (s, t),
    its quad's derivatives as `_lanes_lod` takes them (quad differences in
    float32), then in texels of level 0 in float64 as
    `softras.pipeline.texture.texel_derivatives` without gl."""
    w0, h0 = table[0, 1], table[0, 2]
    ddx_s, ddx_t, ddy_s, ddy_t = _quad_st_derivatives(l, lf)
    r, g, b, a = _beyond_texel(lf[_LF_S, l], lf[_LF_T, l], np.float64(ddx_s) * w0, np.float64(ddx_t) * h0,
                               np.float64(ddy_s) * w0, np.float64(ddy_t) * h0, sampler, texels, table)
    lf[_LF_TEX, l] = r / 255.0
    lf[_LF_TEX + 1, l] = g / 255.0
    lf[_LF_TEX + 2, l] = b / 255.0
    lf[_LF_TEX + 3, l] = a / 255.0
