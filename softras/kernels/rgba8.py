"""RGBA8 words and their "spread" form: four 16-bit lanes of one uint64.

The compiled path holds a colour as llvmpipe stores it, one RGBA8 word
(uint32, R in the low byte; byte k stands for the pipeline's float k/255,
`softras.pipeline.ops.unorm8`).  Spread into four 16-bit lanes of a uint64
(R, B, G, A at bits 0, 16, 32, 48), one 64-bit multiply-add works on all four
channels at once as long as no lane exceeds 2^16: the texture filter
(`softras.kernels.texture._lerp_lanes`, llvmpipe's 8.8 lerp) and the blend
(`softras.kernels.ops._mul_lanes`, lp_build_mul_norm) do.
"""

from __future__ import annotations

import numba
import numpy as np

_LANES = np.uint64(0x00FF00FF00FF00FF)
_HALF_LANES = np.uint64(0x0080008000800080)
_ONE_LANES = np.uint64(0x0001000100010001)
_BORROW_LANES = np.uint64(0x0100010001000100)     # (256 in each lane: a difference that cannot borrow)


@numba.njit(cache=True, inline="always")
def _spread(texel):
    """The spread lanes of an RGBA8 word: the channels of
    `softras.pipeline.ops.unorm8`'s bytes, each in its own 16-bit lane."""
    x = np.uint64(texel)
    return (x | (x << np.uint64(24))) & _LANES


@numba.njit(cache=True, inline="always")
def _unspread(x):
    """The RGBA8 word (int64) of spread lanes x: `_spread` undone (the bytes of
    `softras.pipeline.ops.unorm8` packed as llvmpipe stores them)."""
    return np.int64((x | (x >> np.uint64(24))) & np.uint64(0xFFFFFFFF))


@numba.njit(cache=True, inline="always")
def _lane(x, c):
    """Channel c (0 R, 1 G, 2 B, 3 A) of spread lanes, 0..255 (the byte
    `softras.pipeline.texture.filter_level` or `softras.pipeline.ops.blend_byte`
    gives for that channel)."""
    shift = 0 if c == 0 else (32 if c == 1 else (16 if c == 2 else 48))
    return np.int64((x >> np.uint64(shift)) & np.uint64(255))
