"""Per-sample operations for the compiled path: the depth test, blending and
the framebuffer writes.

Mirrors `softras.pipeline.ops.apply_fragments` in gl precision, on the
storage gl precision implies anyway: an RGBA8 colour buffer as RGBA8
bytes (``(H, W, S, 4) uint8``, written as (H, W, S) RGBA8 words, R in the
low byte; byte k stands for the pipeline's float k/255) and depth as the
integer k of the pipeline's depth k / (2^24 - 1)
(`softras.pipeline.ops.quantize_depth`; ``(H, W, S) int32``, -1 for NaN): the
depth test compares integers, and no division turns k back into a float
(`_depth_pass_k`).  An rgba32f colour buffer is what the stages hold,
``(H, W, S, 4) float32``, blended in float64 by the stages' own `_blend`
(`_write_floats`).

`_resolve_box` is `softras.pipeline.ops.resolve`'s box filter of float
samples (exact precision's float64 buffer into bytes or floats, an rgba32f
buffer's float32 into floats); gl precision's RGBA8 samples are resolved by
`softras.pipeline.ops.resolve_llvmpipe_bytes` and `resolve_exact_bytes`.
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.lanes import _LI_COV, _LI_DST, _LI_PASS, _LI_PIX, _LI_PX, _LI_PY, _LI_WORD, _LI_Z
from softras.kernels.rasterize import _tile_columns
from softras.kernels.rgba8 import _BORROW_LANES, _HALF_LANES, _LANES, _ONE_LANES, _spread, _unspread
from softras.kernels.setup import TILE
from softras.kernels.stamp import sources_stamp
from softras.kernels.threads import _owns
from softras.pipeline import ops as ops_stage
from softras.pipeline.ops import _blend

DEPTH_SCALE = float((1 << ops_stage.DEPTH_BITS) - 1)
LESS = ops_stage.DEPTH_FUNCS["less"]                   # (the common depth test: `_depth_test_lanes`)
# What each depth function passes (`_depth_pass_k`), 4 bits a function in
# the order of its code: bit 0 a depth less than the stored one, bit 1
# equal, bit 2 greater, bit 3 unordered (NaN on either side).  Disabled
# (code 0) and "always" pass all; "notequal" passes the unordered too.
_RELATIONS = {None: 0b1111, "never": 0, "less": 0b0001, "equal": 0b0010, "lequal": 0b0011, "greater": 0b0100,
              "notequal": 0b1101, "gequal": 0b0110, "always": 0b1111}
_ACCEPTS = np.int64(sum(bits << (4 * ops_stage.DEPTH_FUNCS[name]) for name, bits in _RELATIONS.items()))

# The framebuffer the kernels update in place (see the module docstring):
# color32 the (H, W, S, 4) uint8 colour buffer seen as (H, W, S) RGBA8 words
# (uint32, R in the low byte), depth (H, W, S) int32, color_f the (H, W, S,
# 4) float32 colour buffer of an rgba32f framebuffer.  A pass has one of
# the two colour buffers; the other is a (1, 1, 1) placeholder (`NO_WORDS`,
# `NO_FLOATS`), and `softras.kernels.draw.DrawState`'s rgba32f says which.
# The buffers are cleared tile by tile (TILE x TILE pixels, row-major, as
# the tile drivers bin them), by the share that first draws in a tile
# (`_clear_tile`), as llvmpipe's rasterizer threads clear their tiles: fresh
# (tiles,) uint8 is 1 for a tile not cleared yet, and the clear values are
# clear_word (1,) uint32 (the background's RGBA8 word) and clear_f (4,)
# float32 (its floats).  `_clear_fresh` clears the tiles no draw has
# reached, before anything reads the whole buffer.
Framebuffer = namedtuple("Framebuffer", ["color32", "depth", "color_f", "fresh", "clear_word", "clear_f"])
NO_WORDS = np.zeros((1, 1, 1), np.uint32)
NO_FLOATS = np.zeros((1, 1, 1, 4), np.float32)
NO_CLEAR_WORD = np.zeros(1, np.uint32)
NO_CLEAR_F = np.zeros(4, np.float32)
DEPTH_CLEAR = np.int32(DEPTH_SCALE)          # (the depth 1.0, as k: `softras.pipeline.ops.new_framebuffer`)


def holds_floats(fb) -> bool:
    """Whether the `Framebuffer` fb is an rgba32f one (its colour in color_f)."""
    return fb.color_f is not NO_FLOATS


def new_framebuffer(color: np.ndarray, depth: np.ndarray, background) -> Framebuffer:
    """`softras.pipeline.ops.new_framebuffer` in the compiled path's storage,
    to be cleared tile by tile: the colour buffer (H, W, S, 4), uint8 or
    float32 (an rgba32f framebuffer), and depth (H, W, S) int32, as they
    are (their tiles all fresh), with the premultiplied background (4,) as
    the clear values: its RGBA8 bytes (`softras.pipeline.ops.unorm8_bytes`)
    as one word, or its floats rounded to float32 as the stages' buffer
    holds them (`softras.pipeline.render.new_pass_framebuffer`)."""
    height, width = depth.shape[:2]
    fresh = np.ones(((height + TILE - 1) // TILE) * ((width + TILE - 1) // TILE), np.uint8)
    if color.dtype == np.uint8:
        word = np.ascontiguousarray(ops_stage.unorm8_bytes(background), np.uint8).view(np.uint32)
        return Framebuffer(color.view(np.uint32).reshape(depth.shape), depth, NO_FLOATS, fresh, word, NO_CLEAR_F)
    return Framebuffer(NO_WORDS, depth, color, fresh, NO_CLEAR_WORD,
                       np.asarray(background, np.float64).astype(np.float32))


@numba.njit(cache=True, inline="always")
def _tile_rect(tile, width, height):
    """The pixels of tile k of a width x height framebuffer (TILE x TILE
    tiles, row-major, as `new_framebuffer` counts them and the drivers bin
    them, `softras.kernels.rasterize._tile_columns`): first column, last
    column + 1, first row, last row + 1."""
    tiles_x = (width + TILE - 1) // TILE
    x0, x_last = _tile_columns(tile, tiles_x, width)
    y0 = (tile // tiles_x) * TILE
    return x0, x_last + 1, y0, min(y0 + TILE, height)


def _make_tile_kernels(sources: str):
    """The kernels `_clear_tile`, `_clear_fresh` and `_tiles_out`, cached
    under the key ``sources`` (`softras.kernels.stamp.sources_stamp`, a
    closure variable): they read `softras.kernels.setup.TILE` and the depth
    bits of `softras.pipeline.ops`, and `_tiles_out` inlines
    `softras.kernels.threads._owns`.  (Keyed on ops.py alone, an edit of
    those would leave a tile driver calling a stale clear.)  Compiled
    without reference counting, as the tile drivers are: they take views
    of the buffers row by row and allocate nothing, and counting the
    views' references took the picture's copy 0.44 -> 0.28 ms at 1024^2
    on one thread."""

    @numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
    def _clear_tile(tile, color32, depth, color_f, clear_word, clear_f, rgba32f):
        """Clear one tile (`_tile_rect`) of a framebuffer's buffers (`Framebuffer`): its
        samples' depth to 1.0 (`DEPTH_CLEAR`) and their colour to the clear
        word, or with ``rgba32f`` to the clear floats (as two 64-bit words a
        sample).  Each of the tile's rows is one run of the buffers seen flat
        (they are C-contiguous), filled as a slice: a whole 1024^2 RGBA8
        framebuffer in 0.29 ms on one thread where numpy's fills took 0.23;
        indexed by (y, x, s), the sample count unknown until run time, 5.1
        ms (docs/speed.md, "Fiftieth round")."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        height, width, count = depth.shape
        x0, x1, y0, y1 = _tile_rect(tile, width, height)
        depths = depth.reshape(depth.size)
        if rgba32f:
            halves = color_f.reshape(color_f.size).view(np.uint64)
            low, high = clear_f.view(np.uint64)[0], clear_f.view(np.uint64)[1]
            for y in range(y0, y1):
                first, last = (y * width + x0) * count, (y * width + x1) * count
                depths[first:last] = DEPTH_CLEAR
                row = halves[2 * first:2 * last]
                for i in range(0, row.size, 2):
                    row[i] = low
                    row[i + 1] = high
        else:
            words, word = color32.reshape(color32.size), clear_word[0]
            for y in range(y0, y1):
                first, last = (y * width + x0) * count, (y * width + x1) * count
                depths[first:last] = DEPTH_CLEAR
                words[first:last] = word

    @numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
    def _clear_fresh(fb, rgba32f):
        """`_clear_tile` of every tile of the `Framebuffer` fb (as a tuple) that
        is still fresh, marking it cleared."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        color32, depth, color_f, fresh, clear_word, clear_f = fb
        for tile in range(fresh.shape[0]):
            if fresh[tile]:
                _clear_tile(tile, color32, depth, color_f, clear_word, clear_f, rgba32f)
                fresh[tile] = 0

    @numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
    def _tiles_out(fb, r, owners, picture):
        """Share r's part of a one-sample RGBA8 pass's picture: every tile it
        owns or takes (`softras.kernels.threads._owns`, the last batch's
        owners) copied into ``picture`` (H, W) uint32, the tile's rows upside
        down (row 0 the top of the picture; the buffer's row 0 is GL's bottom),
        or for a tile no draw has reached (fresh) the clear word, without
        clearing the tile.  The bytes of
        `softras.pipeline.ops.resolve_llvmpipe_bytes` of the cleared and drawn
        buffer at one sample.  (Rows as slices of the arrays seen flat, as
        `_clear_tile`.)"""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        color32, depth, color_f, fresh, clear_word, clear_f = fb
        height, width = picture.shape
        words = color32.reshape(color32.size)
        pixels = picture.reshape(picture.size)
        word = clear_word[0]
        for tile in range(fresh.shape[0]):
            if not _owns(owners, tile, r):
                continue
            x0, x1, y0, y1 = _tile_rect(tile, width, height)
            for y in range(y0, y1):
                at, to = y * width + x0, (height - 1 - y) * width + x0
                row = pixels[to:to + x1 - x0]
                if fresh[tile]:
                    row[:] = word
                else:
                    drawn = words[at:at + x1 - x0]
                    for x in range(x1 - x0):    # (an array assigned to a slice is copied first: 3x the time)
                        row[x] = drawn[x]

    return _clear_tile, _clear_fresh, _tiles_out


_clear_tile, _clear_fresh, _tiles_out = _make_tile_kernels(sources_stamp(ops_stage))


@numba.njit(cache=True, inline="always")
def _depth_k(z):
    """`softras.pipeline.ops.quantize_depth` of one window depth z as the
    integer k of the stored k / DEPTH_SCALE: clamped to [0, 1] and rounded
    to 24 bits (-1 for NaN)."""
    k = np.rint(min(max(z, 0.0), 1.0) * DEPTH_SCALE)
    return np.int32(k if k == k else -1.0)


@numba.njit(cache=True, inline="always")
def _plane_depth_k(plane, x, y):
    """`_depth_k` of a set-up triangle's depth at the window point (x, y)
    (a sample: its pixel plus its offset in the pixel), from its plane
    ``plane`` = (x0, y0, z0, dz/dx, dz/dy): z0 + dz/dx (x - x0) + dz/dy
    (y - y0), `softras.pipeline.interpolate.depth_at_samples`'s operations
    in its order (the lanes' `softras.kernels.interpolate._lane_depths`,
    and the row loops of `softras.kernels.draw` and
    `softras.kernels.rgba32f`, where the term of y is the same for a whole
    row and LLVM computes it once)."""
    fx0, fy0, z0, dzdx, dzdy = plane
    return _depth_k(z0 + dzdx * (x - fx0) + dzdy * (y - fy0))


@numba.njit(cache=True, inline="always")
def _depth_test_lane(mask, li, l, depth, py, px, depth_func, write_z, n_samples):
    """`softras.pipeline.ops.apply_fragments`'s depth test (and depth write) of
    lane l's samples in ``mask`` against the integer depth buffer, writing
    the passed depths when write_z; returns the mask of passed samples.  No
    branches on the outcome."""
    p = 0
    for s in range(n_samples):
        k = li[_LI_Z + s, l]
        stored = depth[py, px, s]
        passed = ((mask >> s) & 1 != 0) & _depth_pass_k(depth_func, k, stored)
        depth[py, px, s] = k if passed & write_z else stored
        p |= np.int64(passed) << s
    return p


@numba.njit(cache=True, inline="always")
def _depth_test_lanes(n, li, depth, depths, depth_func, write_z, n_samples):
    """`_depth_test_lane` of the n lanes in place: each lane's passed samples
    from its _LI_COV mask into _LI_PASS.  depths : ``depth.reshape(-1)``.
    At one sample a "less" test with depth writes, the common case, runs in a
    copy of its own with the test a constant (no dispatch on the function
    for each lane) and the pixel's index in depths worked out once.

    A lane with mask 0 (a helper pixel of a textured draw's 2x2 quad) passes
    nothing and touches no depth: at the right or bottom edge of a picture
    of odd width or height it lies one pixel outside the picture, where its
    depth would be one pixel past a row (in another thread's tile) or past
    the buffer's end (tests/test_helper_lanes.py).  A draw that neither
    tests nor writes depth (`_uses_depth`) passes every lane's mask as it is,
    without reading the buffer or the lanes' depths (not computed then)."""
    if not _uses_depth(depth_func, write_z):
        for l in range(n):
            li[_LI_PASS, l] = li[_LI_COV, l]
        return
    if n_samples == 1 and depth_func == LESS and write_z:
        width = depth.shape[1]
        for l in range(n):
            if li[_LI_COV, l] == 0:
                li[_LI_PASS, l] = 0
                continue
            i = li[_LI_PY, l] * width + li[_LI_PX, l]
            k = li[_LI_Z, l]
            stored = depths[i]
            passed = _depth_pass_k(LESS, k, stored)
            depths[i] = k if passed else stored
            li[_LI_PASS, l] = passed
        return
    for l in range(n):
        mask = li[_LI_COV, l]
        li[_LI_PASS, l] = (_depth_test_lane(mask, li, l, depth, li[_LI_PY, l], li[_LI_PX, l], depth_func, write_z,
                                            n_samples) if mask != 0 else 0)


@numba.njit(cache=True, inline="always")
def _uses_depth(depth_func, write_z):
    """Whether a draw reads or writes depth: not when its depth test passes
    every fragment (disabled or "always") and it writes no depth, as a draw
    without depth test (`softras.pipeline.ops.apply_fragments`); then the
    kernels compute no depths and leave the depth buffer alone."""
    return write_z or (depth_func != 0 and depth_func != 8)


@numba.njit(cache=True, inline="always")
def _depth_pass_k(func, k, stored):
    """`softras.pipeline.ops._depth_pass` on depths held as their 24-bit integers k (the
    depth is k / DEPTH_SCALE, a strictly increasing map, so every comparison
    agrees) and -1 for NaN, which compares as NaN does: unequal to all,
    neither less nor greater.

    Without a branch: the function's bits of `_ACCEPTS` (the relations it
    passes) select the comparisons, so a loop over pixels with the function
    unknown until the draw still vectorises (`softras.kernels.draw._flat_row`'s
    copy for any state), and where func is a constant the selection folds
    away: "less" compiles to ``ordered & (k < stored)``."""
    accepts = (_ACCEPTS >> (4 * func)) & 15
    ordered = (k >= 0) & (stored >= 0)
    unordered = (k < 0) | (stored < 0)
    relation = ((accepts & 1 != 0) & (k < stored)) | ((accepts & 2 != 0) & (k == stored)) \
        | ((accepts & 4 != 0) & (k > stored))
    return (ordered & relation) | (unordered & (accepts & 8 != 0))


@numba.njit(cache=True, inline="always")
def _write_lanes(n, li, color32, blend, n_samples):
    """The writes of `softras.pipeline.ops.apply_fragments`: store or blend the
    n lanes' RGBA8 words into their passed samples (`_write_word` per lane,
    scalar).  At one sample each passed lane's word is stored directly (4 %
    off the large triangles of the bench's few_large), and a blending
    draw's words are blended first: the passed lanes' stored words gathered
    into the _LI_DST row, then `_blend_word` per lane, in a loop of its own
    for each spread-lane equation ("over", "over_straight": its mode a
    constant there, so LLVM vectorises the loop; 6.0 -> 4.5 ns a lane).  A
    blending draw reads and writes the words at each pixel's index in the
    picture seen as one row of words (the _LI_PIX row, worked out in a
    vectorised loop; 6.7 -> 4.9 ns a lane for the gather, blend and store in
    a harness); a draw that only stores did not gain from it (its bench
    scenes 0-4 % slower).  The lanes are distinct pixels (one triangle's, or
    one block's quads), so no lane reads a word another lane writes."""
    if n_samples == 1 and blend != 0:
        words = color32.reshape(-1)            # (a view: one word a pixel at one sample)
        width = color32.shape[1]
        for l in range(n):
            li[_LI_PIX, l] = li[_LI_PY, l] * width + li[_LI_PX, l]
        for l in range(n):
            passed = li[_LI_PASS, l] != 0          # (a helper pixel may lie outside the picture)
            li[_LI_DST, l] = np.int64(words[li[_LI_PIX, l]]) if passed else 0
        if blend == 1:                      # (the equation a constant in each copy)
            _blend_lanes(n, li, 1)
        elif blend == 2:
            _blend_lanes(n, li, 2)
        else:
            _blend_lanes(n, li, blend)
        for l in range(n):
            if li[_LI_PASS, l]:
                words[li[_LI_PIX, l]] = np.uint32(li[_LI_WORD, l])
        return
    if n_samples == 1:
        for l in range(n):
            if li[_LI_PASS, l]:
                color32[li[_LI_PY, l], li[_LI_PX, l], 0] = np.uint32(li[_LI_WORD, l])
        return
    for l in range(n):
        p = li[_LI_PASS, l]
        if p:
            _write_word(color32, li[_LI_PY, l], li[_LI_PX, l], p, n_samples, blend, li[_LI_WORD, l])


@numba.njit(cache=True, inline="always")
def _blend_lanes(n, li, blend):
    """`_blend_word` of each of the n lanes' words (_LI_WORD) over its stored
    word (_LI_DST), into _LI_WORD: a loop LLVM vectorises where ``blend`` is
    a constant (`_write_lanes` calls it with 1 and 2)."""
    for l in range(n):
        word = li[_LI_WORD, l]
        li[_LI_WORD, l] = _blend_word(blend, word, li[_LI_DST, l], (word >> 24) & 255)


@numba.njit(cache=True, inline="always")
def _write_word(color32, py, px, p, n_samples, blend, word):
    """`softras.pipeline.ops.apply_fragments`'s colour write: store (blend == 0:
    one 32-bit store per sample) or blend (`_blend_word`: `softras.pipeline.ops.blend_byte`
    per channel, as `softras.pipeline.ops.blend_unorm8`) the fragment's RGBA8 word (R in the
    low byte) into the samples of pixel (px, py) set in mask p.  A blend
    into every sample of a pixel whose samples hold one word (inside a
    triangle of every earlier layer: most pixels) is worked out once and
    stored to each: `_blend_word` is a function of the two words alone."""
    alpha = (word >> 24) & 255
    if blend != 0 and n_samples > 1 and p == (1 << n_samples) - 1:
        stored = color32[py, px, 0]
        same = True
        for s in range(1, n_samples):
            same &= color32[py, px, s] == stored
        if same:
            blended = np.uint32(_blend_word(blend, word, np.int64(stored), alpha))
            for s in range(n_samples):
                color32[py, px, s] = blended
            return
    for s in range(n_samples):
        if not (p >> s) & 1:
            continue
        if blend == 0:
            color32[py, px, s] = np.uint32(word)
        else:
            color32[py, px, s] = np.uint32(_blend_word(blend, word, np.int64(color32[py, px, s]), alpha))


@numba.njit(cache=True, inline="always")
def _write_floats(color_f, py, px, p, n_samples, blend, r, g, b, a):
    """`softras.pipeline.ops.apply_fragments`' colour write into an rgba32f
    buffer: the fragment's premultiplied float64 colour (r, g, b, a) stored
    or blended (the stages' `softras.pipeline.ops._blend`, float64, the
    stored float32 widened) into the samples of pixel (px, py) set in mask
    p, each result rounded to float32 as it is stored."""
    for s in range(n_samples):
        if not (p >> s) & 1:
            continue
        color_f[py, px, s, 0] = _blend(blend, r, color_f[py, px, s, 0], a)
        color_f[py, px, s, 1] = _blend(blend, g, color_f[py, px, s, 1], a)
        color_f[py, px, s, 2] = _blend(blend, b, color_f[py, px, s, 2], a)
        color_f[py, px, s, 3] = _blend(blend, a, color_f[py, px, s, 3], a)


@numba.njit(cache=True, inline="always")
def _blend_word(blend, word, stored, alpha):
    """`softras.pipeline.ops.blend_byte` on each channel of the RGBA8 words (fragment ``word``
    with alpha byte ``alpha`` over ``stored``), on the four spread lanes at
    once and without a branch, so that a loop over pixels with the mode
    unknown until the draw still vectorises (`softras.kernels.draw._flat_row`'s
    copy for any state); where blend is a constant the other modes' values
    fold away.  "none", "over", "over_straight" and "add" are a sum of two
    terms (`_mul_lanes`), saturated (every lane sum stays below 2^9);
    "subtract" and "reverse_subtract" a difference and "min" and "max" a
    choice, from the lanes of ``(src | 256) - dst``: 256 + src - dst, at
    least 256 where src >= dst (no lane borrows from the next)."""
    src, dst = _spread(word), _spread(stored)
    first = _mul_lanes(src, alpha) if blend == 2 else src
    second = dst if blend == 3 else _mul_lanes(dst, 255 - alpha)
    total = first + (second if blend != 0 else np.uint64(0))
    carry = (total >> np.uint64(8)) & _ONE_LANES          # lanes over 255
    summed = (total | (carry * np.uint64(255))) & _LANES
    forward, backward = (src | _BORROW_LANES) - dst, (dst | _BORROW_LANES) - src
    src_ge = ((forward >> np.uint64(8)) & _ONE_LANES) * np.uint64(255)      # 255 in the lanes where src >= dst
    dst_ge = ((backward >> np.uint64(8)) & _ONE_LANES) * np.uint64(255)
    if blend <= 3:
        lanes = summed
    elif blend == 4:
        lanes = forward & src_ge
    elif blend == 5:
        lanes = backward & dst_ge
    elif blend == 6:
        lanes = (dst & src_ge) | (src & ~src_ge)
    else:
        lanes = (src & src_ge) | (dst & ~src_ge)
    return _unspread(lanes & _LANES)


@numba.njit(cache=True, inline="always")
def _mul_lanes(x, factor):
    """`softras.pipeline.ops.mul_unorm8` of each spread lane of x by one factor byte:
    t = x f, (t + (t >> 8) + 0x80) >> 8 per lane (t < 2^16 per lane, and
    so is the sum: no carry between lanes)."""
    t = x * np.uint64(factor)
    return ((t + ((t >> np.uint64(8)) & _LANES) + _HALF_LANES) >> np.uint64(8)) & _LANES


@numba.njit(cache=True, error_model="numpy", inline="always")
def _sample_mean(color, y, x, c):
    """``color[y, x, :, c]``'s mean as `softras.pipeline.ops.resolve`'s box
    filter takes it, numpy's ``mean(axis=2, dtype=float64)``: from 0.0, the
    samples added in order, then divided by their count (so -0.0 samples
    give +0.0)."""
    total = 0.0
    for s in range(color.shape[2]):
        total += color[y, x, s, c]
    return total / color.shape[2]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _unorm8_byte(v):
    """`softras.pipeline.ops.unorm8_bytes` of one float: ``rint(clamp(v, 0,
    1) * 255)``, NaN giving 0 as numpy's conversion gives it (a select, no
    branch)."""
    byte = np.uint8(np.rint(min(max(v, 0.0), 1.0) * 255.0))
    return np.uint8(0) if v != v else byte


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _resolve_box(color, out):
    """`softras.pipeline.ops.resolve`'s box filter (exact arithmetic) of
    float samples color (H, W, S, 4), float64 (exact precision) or float32
    (an rgba32f buffer in gl precision), into out (H, W, 4), row 0 = top:
    out[H - 1 - y, x, c] = the `_sample_mean` of color[y, x, :, c], as its
    `_unorm8_byte` into a uint8 out (an RGBA8 picture), rounded to float32
    into a float32 one (an rgba32f picture; out's type decides, at compile
    time).  One sample is its own mean (a division by 1 is exact): that row
    is the sample's byte, or ``0.0 + sample`` (-0.0 made +0.0, as the mean
    from 0.0 makes it), without the mean's loop over the samples (in a loop
    of its own: a select inside one loop took exact's 512^2 resolve from
    0.59 to 0.87 ms; the two, 1.36 -> 0.67)."""
    to_bytes = out.itemsize == 1            # (a constant of out's type)
    height, width, n_samples = color.shape[0], color.shape[1], color.shape[2]
    for y in numba.prange(height):
        row = height - 1 - y
        if n_samples == 1:
            for x in range(width):
                for c in range(4):
                    if to_bytes:            # (two stores: a select would convert the byte to float and back)
                        out[row, x, c] = _unorm8_byte(color[y, x, 0, c])
                    else:
                        out[row, x, c] = 0.0 + color[y, x, 0, c]
        else:
            for x in range(width):
                for c in range(4):
                    if to_bytes:
                        out[row, x, c] = _unorm8_byte(_sample_mean(color, y, x, c))
                    else:
                        out[row, x, c] = _sample_mean(color, y, x, c)
