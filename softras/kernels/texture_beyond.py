"""The ripmap filter for the compiled path.

Mirrors `softras.pipeline.texture_beyond.sample_ripmap` (softras's own
filter, ``texture_filter="ripmap"``; float64 in any precision) per lane of
the textured tile kernel (`softras.kernels.draw._textured_tile`): the
stage's ripmap levels as one buffer (`ripmap_tables`), the lambdas from the
quad's derivatives, the level or the four levels around them, each
filtered by `softras.kernels.texture._filter_level` (`_ripmap_lane`).
EWA and "level0" take the stages (`softras.kernels.draw.unsupported`).
"""

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
                      WRAP_CODES[tex.wrap_t], 0, len(levels), 0, 0, len(rip[0]))
    return sampler, Texels(flat, flat.view(np.uint32), level_table(levels), _EWA)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ripmap_level(lam, n):
    """`softras.pipeline.texture_beyond.sample_ripmap`'s lambda along one
    axis after ``np.nan_to_num(np.maximum(lam, 0.0), posinf=n - 1)``."""
    if lam != lam:
        return 0.0
    return float(n - 1) if lam == np.inf else max(lam, 0.0)


def _make_ripmap_lane(sources: str):
    """The kernel `_ripmap_lane`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable): a function
    of its own, not inlined, so that the three textured tile drivers call
    one compiled copy (inlined, it added about 40 s to the compile of each)."""

    @numba.njit(cache=True, error_model="numpy")
    def _ripmap_lane(l, lf, sampler, texels, table):
        """`softras.pipeline.texture_beyond.sample_ripmap` of lane l (float64
        whatever the precision; its quad's derivatives as `_lanes_lod` takes
        them, quad differences in float32, then in texels of level 0 in
        float64 as `softras.pipeline.texture.texel_derivatives` without gl),
        the ripmap in `ripmap_tables`' layout, into the _LF_TEX rows: the
        lambdas along u and v (`softras.pipeline.libm._log2` of the footprint's
        extents), magnified (both <= 0): the mag filter on level 0; else the
        nearest level (mipmap_nearest) or the four levels around the lambdas,
        each bilinear (`_filter_level`), weighted and summed in the stage's
        order."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        w0, h0 = table[0, 1], table[0, 2]
        ddx_s, ddx_t, ddy_s, ddy_t = _quad_st_derivatives(l, lf)
        du0, du1 = np.float64(ddx_s) * w0, np.float64(ddx_t) * h0
        dv0, dv1 = np.float64(ddy_s) * w0, np.float64(ddy_t) * h0
        lam_u = libm._log2(_nan_max(np.abs(du0), np.abs(dv0)))
        lam_v = libm._log2(_nan_max(np.abs(du1), np.abs(dv1)))
        s, t = lf[_LF_S, l], lf[_LF_T, l]
        wrap_s, wrap_t = sampler.wrap_s, sampler.wrap_t
        if not ((lam_u > 0) | (lam_v > 0)):                 # magnified
            r, g, b, a = _filter_level(texels, 0, w0, h0, s, t, sampler.mag_filter == _LINEAR, wrap_s, wrap_t)
        else:
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
        lf[_LF_TEX, l] = r / 255.0
        lf[_LF_TEX + 1, l] = g / 255.0
        lf[_LF_TEX + 2, l] = b / 255.0
        lf[_LF_TEX + 3, l] = a / 255.0

    return _ripmap_lane


_ripmap_lane = _make_ripmap_lane(sources_stamp(texture_stage, libm))
