"""The lane rows: where the tile kernel keeps the pixels it shades together.

No readable counterpart: `softras.pipeline.render` materialises a fragment
list (`softras.pipeline.rasterize.Fragments`) and per-fragment arrays; the
compiled path keeps at most two blocks' worth of them, per thread, in two
small arrays, float64 ``lf`` (_NLF, 2 * LANES) and int64 ``li``
(_LI_Z + samples, 2 * LANES), one column per lane.

Pixels are shaded in "lanes": `softras.kernels.draw._flat_tile` (or `_textured_tile`) lists an
untextured triangle's covered pixels (shaded from LANES of them on,
`_flat_block`) or a textured triangle's covered 2x2 quads of its 8x8 blocks (4
lanes per quad, up to 64 a block, shaded in `_textured_tile` from LANES of
them on or at the triangle's last block); then each step runs as one loop
over the lanes.  The steps without branches or table look-ups (the
perspective weights with their three divisions, depth, texel addresses, the
8.8 filter, the colour bytes) are loops that LLVM compiles to AVX2 (4 or 8
lanes per instruction); the depth test, the quad's level of detail, the
texel fetches and the framebuffer writes stay scalar.  Same operations in
the same order per lane, so the bits are those of the per-pixel code.

The row numbers are module-level constants: numba freezes them into every
kernel that reads them when it compiles.
"""

from collections import namedtuple

import numba

LANES = 64                                   # 16 quads of an 8x8 block

# The lanes of one vector register: 8 float64 (AVX-512; two registers on
# AVX2).  LLVM compiles a lane loop to whole vectors and a remainder taken
# lane by lane, and the remainder is what a small triangle pays: Phong
# (`softras.kernels.light._phong_words`, two lights) took 208 ns for 4
# lanes and 109 ns for 8, its square roots and divisions one lane at a
# time.  The arithmetic steps, which write nothing but their own lanes'
# rows, therefore run over the count rounded up to whole vectors
# (`_whole_vectors`): the lanes past the count compute on what earlier
# blocks left there, and nothing reads their results.  Both counts are
# below 2 * LANES, the lf, li and lu rows' width (a textured count is
# under LANES before its last block's at most LANES): rounded up, each stays inside
# its rows.
VECTOR = 8


@numba.njit(cache=True, inline="always")
def _whole_vectors(n):
    """The lane count n rounded up to whole vectors of `VECTOR` lanes, for
    the arithmetic lane steps: the lanes past n are computed and never read."""
    return (n + (VECTOR - 1)) & -VECTOR

# float64 lane rows: pixel centre, perspective weights, (s, t), per level the
# float32 scales size * 256 of s and t, the mip blend fraction, the filtered
# texel (r, g, b, a in [0, 1]), the Phong-lit straight colour (r, g, b, a),
# Phong's world position, unit normal and unit view vector (x, y, z each),
# one light's N.L and specular term, a normal or bump map's tangent-space
# normal (x, y, z), and the lane's own (s, t) while a bump map is sampled
# beside it (`softras.kernels.maps._map_normals`).
(_LF_CX, _LF_CY, _LF_W, _LF_S, _LF_T, _LF_SCALE, _LF_FRAC, _LF_TEX, _LF_LIT, _LF_POS, _LF_NRM, _LF_VIEW,
 _LF_NDL, _LF_SPEC, _LF_MAP, _LF_ST0, _NLF) = 0, 1, 2, 5, 6, 7, 11, 12, 16, 20, 23, 26, 29, 30, 31, 34, 36

# int64 lane rows: pixel, coverage mask, depth-passed mask, per level the
# texel word offset / width / height, mip weight (0..256), levels, image
# filter, two levels or one, the 8 texel addresses, the 4 filter weights,
# the fragment's RGBA8 word, the stored word a blending draw blends it
# over and the pixel's index in the picture's row-major order, py * width
# + px (`softras.kernels.ops._write_lanes`), then the depth at each sample
# as its 24-bit integer (`softras.kernels.interpolate._lane_depths`).
(_LI_PX, _LI_PY, _LI_COV, _LI_PASS, _LI_BASE, _LI_LW, _LI_LH, _LI_W8, _LI_LEVEL, _LI_IMGF, _LI_TWO,
 _LI_ADDR, _LI_FRAC8, _LI_WORD, _LI_DST, _LI_PIX, _LI_Z) = 0, 1, 2, 3, 4, 6, 8, 10, 11, 13, 14, 15, 23, 27, 28, 29, 30

# A share's lane buffers (allocated per batch of draws for each share of
# the tile drivers, `softras.kernels.draw.lane_buffers`): the float64 rows lf (_NLF,
# 2 * LANES), the int64 rows li (_LI_Z + samples, 2 * LANES), the 8 fetched
# texels per lane spread into 16-bit lanes lu (8, 2 * LANES) uint64, the scalar
# float filter's two levels' RGBA texel (2, 4) and a pixel row's edge
# functions per sample, rows (3, samples) int64.
LaneBuffers = namedtuple("LaneBuffers", ["lf", "li", "lu", "texel", "rows"])
