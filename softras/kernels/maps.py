"""Normal and bump maps for the compiled path (gl precision).

Mirrors the map half of `softras.pipeline.render.mapped_normals`
(`softras.pipeline.fragment.normal_map_normals`, `bump_normals`) over the
lanes of the textured tile kernel (`softras.kernels.draw._textured_tile`),
with `softras.kernels.texture`'s level of detail and filters; the
perturbation of the normal is `softras.kernels.light._perturb`.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.lanes import _LF_MAP, _LF_S, _LF_ST0, _LF_T, _LF_TEX, _LI_COV, _whole_vectors
from softras.kernels.stamp import sources_stamp
from softras.kernels.texture import (VECTORISED_LINEAR, _lanes_aniso_levels, _lanes_bilinear_fixed, _lanes_lod,
                                     _quad_levels, _sample_lane)
from softras.pipeline import texture as texture_stage


def _make_map_normals(sources: str):
    """The kernel `_map_normals`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable)."""

    @numba.njit(cache=True, error_model="numpy")
    def _map_normals(n, lf, li, lu, texel, sampler, texels, texels32, table, ewa, bump, bump_scale):
        """The tangent-space normals of `softras.pipeline.render.mapped_normals`
        at the n lanes (whole 2x2 quads of one triangle, (s, t) in the _LF_S and
        _LF_T rows, coverage in _LI_COV) into the _LF_MAP rows (x, y, z), the map
        (`Sampler` sampler; its `Texels` arrays one by one) sampled as
        `softras.pipeline.texture.sample` samples a texture, at each quad's own
        level of detail (`_lanes_lod`, `_lanes_aniso_levels`):

        - a normal map (``bump`` False): `softras.pipeline.fragment.normal_map_normals`
          of the texel, ``2 rgb - 1``;
        - a bump map: `softras.pipeline.fragment.bump_normals` in gl precision:
          the red channel at (s +- 1/W, t) and (s, t +- 1/H) (W x H its level 0;
          the coordinates rounded to float32 and the offset added in float32),
          all four at the quad's level of detail of (s, t) itself, then
          ``(-scale dh_s / 2, -scale dh_t / 2, 1)``.

        Every covered quad is sampled (the depth test comes later; a failed
        lane's normal is never read).  The level rows are the map's afterwards:
        the tile kernel chooses the colour texture's levels after this.  Not
        inlined: one compiled copy serves every textured tile driver, and it is
        cached on its own (18 s to compile)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        vectorised = sampler.vectorised == VECTORISED_LINEAR        # (a nearest map: `_sample_lane`)
        if sampler.aniso:
            _lanes_aniso_levels(n, sampler, table[0, 1], table[0, 2], lf, li)
            any_two = False
        else:
            any_two = _lanes_lod(n, sampler, table[0, 1], table[0, 2], lf, li)
        block_two = False
        # The vectorised filter's steps over whole vectors (m lanes,
        # `softras.kernels.lanes.VECTOR`): the quads past n sample level 0
        # (valid texel addresses whatever their stale (s, t)), unread.
        m = _whole_vectors(n) if vectorised else n
        for q in range(m >> 2):
            l = 4 * q
            covered = q < (n >> 2) and (li[_LI_COV, l] | li[_LI_COV, l + 1] | li[_LI_COV, l + 2]
                                        | li[_LI_COV, l + 3]) != 0
            block_two |= _quad_levels(q, covered, sampler, table, vectorised, any_two, lf, li)
        step_s, step_t = np.float32(1.0 / table[0, 1]), np.float32(1.0 / table[0, 2])
        if bump:
            for l in range(m):
                lf[_LF_ST0, l], lf[_LF_ST0 + 1, l] = lf[_LF_S, l], lf[_LF_T, l]
        for k in range(4 if bump else 1):
            axis = k >> 1                                   # bump: s + step, s - step, t + step, t - step
            sign = np.float32(1.0) if k & 1 == 0 else np.float32(-1.0)
            if bump:
                for l in range(m):
                    s32, t32 = np.float32(lf[_LF_ST0, l]), np.float32(lf[_LF_ST0 + 1, l])
                    if axis == 0:
                        s32 = np.float32(s32 + np.float32(sign * step_s))
                    else:
                        t32 = np.float32(t32 + np.float32(sign * step_t))
                    lf[_LF_S, l], lf[_LF_T, l] = np.float64(s32), np.float64(t32)
            if vectorised and block_two:                    # (the level count a constant in each copy)
                _lanes_bilinear_fixed(m, 2, False, bump, lf, li, lu, texels32, sampler)
            elif vectorised:
                _lanes_bilinear_fixed(m, 1, False, bump, lf, li, lu, texels32, sampler)
            else:
                for l in range(n):
                    if li[_LI_COV, l]:
                        _sample_lane(l, lf, li, texel, sampler, texels, texels32, table, ewa)
            if bump:                                        # dh = h(+) - h(-), the red channel
                for l in range(m):
                    h = lf[_LF_TEX, l]
                    lf[_LF_MAP + axis, l] = h if k & 1 == 0 else lf[_LF_MAP + axis, l] - h
        if bump:
            for l in range(m):
                lf[_LF_MAP, l] = -bump_scale * lf[_LF_MAP, l] * 0.5
                lf[_LF_MAP + 1, l] = -bump_scale * lf[_LF_MAP + 1, l] * 0.5
                lf[_LF_MAP + 2, l] = 1.0
                lf[_LF_S, l], lf[_LF_T, l] = lf[_LF_ST0, l], lf[_LF_ST0 + 1, l]
        else:
            for l in range(m):
                for c in range(3):
                    lf[_LF_MAP + c, l] = 2.0 * lf[_LF_TEX + c, l] - 1.0

    return _map_normals


_map_normals = _make_map_normals(sources_stamp(texture_stage))
