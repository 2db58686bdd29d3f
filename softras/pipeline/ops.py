"""Per-sample operations: depth test, depth write, blending, resolve.

The framebuffer is per sample, in GL's y-up window space:

    color : (H, W, S, 4) float64 premultiplied RGBA
    depth : (H, W, S)    float64 z_w in [0, 1]

Fragments are applied strictly in order (GL's primitive order), one covered
sample at a time, by a numba kernel.  In gl precision the colour buffer is
RGBA8 UNORM and written as Mesa 22.3 llvmpipe writes it: the fragment colour
is converted to bytes first (`unorm8`) and blended in 8-bit integer
arithmetic (`blend_unorm8`); the buffer holds the bytes as k/255.  Depths are
rounded to the 24-bit depth buffer's k/(2^24 - 1).  Exact precision and
rgba32f framebuffers blend in floating point (`_blend`).
"""

from __future__ import annotations

import numba
import numpy as np

DEPTH_FUNCS = {None: 0, "never": 1, "less": 2, "equal": 3, "lequal": 4,
               "greater": 5, "notequal": 6, "gequal": 7, "always": 8}
BLEND_MODES = {"none": 0, "over": 1, "over_straight": 2, "add": 3, "subtract": 4,
               "reverse_subtract": 5, "min": 6, "max": 7}
DEPTH_BITS = 24


def new_framebuffer(width: int, height: int, samples: int, background: np.ndarray,
                    quantize: bool) -> tuple[np.ndarray, np.ndarray]:
    """Cleared (color, depth) buffers; background is straight RGBA, stored premultiplied."""
    clear = premultiplied(background)
    if quantize:
        clear = quantize_unorm8(clear)
    color = np.empty((height, width, samples, 4))
    color[...] = clear
    depth = np.ones((height, width, samples))
    return color, depth


def premultiplied(rgba) -> np.ndarray:
    """Straight RGBA (4,) -> premultiplied (r a, g a, b a, a) float64."""
    rgba = np.asarray(rgba, np.float64)
    return np.concatenate([rgba[:3] * rgba[3], rgba[3:4]])


def unorm8_bytes(c: np.ndarray) -> np.ndarray:
    """Float colour values -> the UNORM8 bytes, ``round_half_even(clamp(c, 0, 1) * 255)``
    as uint8 (the byte k of `quantize_unorm8`'s k/255)."""
    return np.rint(np.clip(c, 0.0, 1.0) * 255.0).astype(np.uint8)


def quantize_unorm8(c: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and round to the nearest k/255 (half to even, like SSE)."""
    return np.rint(np.clip(c, 0.0, 1.0) * 255.0) / 255.0


def quantize_depth(z: np.ndarray) -> np.ndarray:
    """Round window depth to the 24-bit UNORM depth buffer's k/(2^24 - 1)."""
    scale = float((1 << DEPTH_BITS) - 1)
    return np.rint(np.clip(z, 0.0, 1.0) * scale) / scale


@numba.njit(cache=True)
def _depth_pass(func, z, stored):
    if func == 0 or func == 8:
        return True
    if func == 1:
        return False
    if func == 2:
        return z < stored
    if func == 3:
        return z == stored
    if func == 4:
        return z <= stored
    if func == 5:
        return z > stored
    if func == 6:
        return z != stored
    return z >= stored


@numba.njit(cache=True, inline="always")
def _blend(mode, s, d, alpha):
    """The float blend of one channel (an rgba32f or exact buffer, unclamped):
    fragment value s (premultiplied) over stored value d, the fragment's
    alpha ``alpha``; mode : BLEND_MODES code."""
    if mode == 0:
        return s
    if mode == 1:
        return s + (1.0 - alpha) * d
    if mode == 2:
        return s * alpha + (1.0 - alpha) * d
    if mode == 3:
        return s + d
    if mode == 4:
        return s - d
    if mode == 5:
        return d - s
    if mode == 6:
        return min(s, d)
    return max(s, d)


@numba.njit(cache=True)
def unorm8(v):
    """One fragment colour channel (float, premultiplied) -> the UNORM8 byte llvmpipe stores.

    llvmpipe's lp_build_conv (float32 -> unorm8, AVX path): ``min(v, 1)``,
    the float32 product ``v * 255``, rounded half to even (cvtps2dq), then
    saturated to [0, 255] by the pack instructions; NaN gives 0.  softras's
    float64 colour is first rounded to float32, as the shader's output is.
    Returns an int in [0, 255].  Written without branches (selects), so that
    a compiled loop calling it vectorises (`softras.kernels.draw`'s lanes).
    """
    v32 = np.float32(v)
    clamped = min(v32 if v32 > 0 else np.float32(0.0), np.float32(1.0))     # negative or NaN -> 0
    return np.int64(np.int32(np.rint(np.float64(np.float32(clamped * np.float32(255.0))))))


@numba.njit(cache=True)
def mul_unorm8(a, b):
    """a * b / 255 for bytes a, b as llvmpipe's lp_build_mul_norm (Mesa 22.3) computes it.

    The geometric-series approximation with rounding, in 16-bit integers:
    ``t = a * b; (t + (t >> 8) + 0x80) >> 8``.  It equals round(a * b / 255)
    except on 24 of the 65536 pairs, where the exact quotient is k + 0.502
    and it gives k (152 * 229 / 255 = 136.502 -> 136).
    """
    t = a * b
    return (t + (t >> 8) + 0x80) >> 8


@numba.njit(cache=True)
def blend_unorm8(mode, src, dst, out):
    """Blend bytes as llvmpipe's AoS blend does for an RGBA8 UNORM buffer.

    src : (4,) int64 fragment bytes (`unorm8`), dst : (4,) int64 stored
    bytes, out : (4,) int64 result bytes; mode : BLEND_MODES code.  The
    factors multiply with `mul_unorm8` (a factor ONE is no multiplication),
    ONE_MINUS_SRC_ALPHA is ``255 - a``, and the equation saturates: add with
    ``min(., 255)``, subtract and reverse_subtract with ``max(., 0)``; min and
    max compare the bytes (GL ignores their factors).  "over_straight"
    (SRC_ALPHA, ONE_MINUS_SRC_ALPHA) is two products and a saturating add,
    like every other factor pair (lp_build_blend's lerp shortcut for
    complementary factors is not taken for it in llvmpipe's AoS blend).
    """
    for ch in range(4):
        out[ch] = blend_byte(mode, src[ch], dst[ch], src[3])


@numba.njit(cache=True, inline="always")
def blend_byte(mode, s, d, alpha):
    """One channel of `blend_unorm8`: fragment byte s over stored byte d, the
    fragment's alpha byte ``alpha``; returns the result byte (an int)."""
    inv_alpha = 255 - alpha
    if mode == 0:
        return s
    if mode == 1:
        return min(s + mul_unorm8(d, inv_alpha), 255)
    if mode == 2:
        return min(mul_unorm8(s, alpha) + mul_unorm8(d, inv_alpha), 255)
    if mode == 3:
        return min(s + d, 255)
    if mode == 4:
        return max(s - d, 0)
    if mode == 5:
        return max(d - s, 0)
    if mode == 6:
        return min(s, d)
    return max(s, d)


@numba.njit(cache=True)
def apply_fragments(x, y, mask, z, rgba, color, depth, depth_func, depth_write, blend, quantize):
    """Depth-test, blend and store fragments in order.

    x, y : (F,) pixels; mask : (F,) uint32 covered samples; z : (F, S) depth
    per sample; rgba : (F, 4) premultiplied colour (one shading per pixel);
    color, depth : the framebuffer, updated in place.
    depth_func : DEPTH_FUNCS code (0 = test disabled: pass, never write);
    depth_write : bool; blend : BLEND_MODES code; quantize : an RGBA8 buffer
    (gl precision): the colour buffer holds k/255, the fragment colour is
    converted with `unorm8` and blended with `blend_unorm8`; otherwise the
    float blend `_blend`, unclamped.
    """
    n_samples = depth.shape[2]
    src = np.empty(4)
    src8 = np.empty(4, np.int64)
    dst8 = np.empty(4, np.int64)
    out8 = np.empty(4, np.int64)
    write_z = depth_write and depth_func != 0
    for f in range(x.shape[0]):
        px = x[f]
        py = y[f]
        for ch in range(4):
            src[ch] = rgba[f, ch]
            if quantize:
                src8[ch] = unorm8(rgba[f, ch])
        for s in range(n_samples):
            if not (mask[f] >> s) & 1:
                continue
            if not _depth_pass(depth_func, z[f, s], depth[py, px, s]):
                continue
            if write_z:
                depth[py, px, s] = z[f, s]
            if quantize:
                for ch in range(4):
                    dst8[ch] = np.int64(np.rint(color[py, px, s, ch] * 255.0))
                blend_unorm8(blend, src8, dst8, out8)
                for ch in range(4):
                    color[py, px, s, ch] = out8[ch] / 255.0
            else:
                for ch in range(4):
                    color[py, px, s, ch] = _blend(blend, src[ch], color[py, px, s, ch], src[3])


RESOLVE_FILTERS = ("box", "tent")


def _tent(d: np.ndarray) -> np.ndarray:
    """The 2-pixel-wide tent max(0, 1 - |d|), d in pixels."""
    return np.maximum(0.0, 1.0 - np.abs(d))


def resolve_llvmpipe_bytes(stored: np.ndarray) -> np.ndarray:
    """llvmpipe's MSAA resolve of an RGBA8 buffer's bytes: (H, W, S, 4) uint8,
    y-up -> (H, W, 4) uint8 with row 0 = the top of the picture.

    Mesa resolves with a blit shader in float32 (found by experiment against
    llvmpipe: see tests/stages/test_resolve.py): each stored byte v becomes
    ``v * (1/255)`` in float32, the S samples are summed in float32 in sample
    order, the sum is multiplied by ``1/S`` and stored to UNORM8 as
    ``round_half_even(m * 255)`` in float32.  Its rounding differs from the
    exact mean's on some partly covered pixels by 1/255; one sample comes
    back as its own byte.  A compiled loop per pixel and channel, no float
    arrays of the sample buffer's size.
    """
    if stored.shape[2] == 1:
        return stored[::-1, :, 0].copy()        # (a copy: the fast path's buffer is reused)
    stored = np.ascontiguousarray(stored, np.uint8)
    out = np.empty(stored.shape[:2] + (4,), np.uint8)
    _resolve_bytes(stored, out)
    return out


def resolve_exact_bytes(stored: np.ndarray) -> np.ndarray:
    """`resolve`'s exact box filter (``arithmetic="exact"``, uint8 output)
    of an RGBA8 sample buffer given as its bytes: (H, W, S, 4) uint8, y-up
    -> (H, W, 4) uint8, row 0 = the top, the bytes of
    ``resolve(stored / 255.0)`` without its float buffers (8x the bytes'
    size, twice over).  A compiled loop with numpy's operations in numpy's
    order: each byte k as the float64 k / 255, summed over the samples in
    sample order (numpy's mean over the sample axis, which is not the
    innermost), divided by S, clamped, times 255, rounded half to even
    (`unorm8_bytes`); tests/stages/test_resolve.py checks it against
    `resolve` on every byte and sample count."""
    stored = np.ascontiguousarray(stored, np.uint8)
    out = np.empty(stored.shape[:2] + (4,), np.uint8)
    _resolve_exact(stored, out)
    return out


@numba.njit(cache=True, parallel=True)
def _resolve_exact(stored, out):
    """out[H - 1 - y, x] = the exact mean of stored[y, x] (`resolve_exact_bytes`)."""
    height, width, n_samples = stored.shape[0], stored.shape[1], stored.shape[2]
    for y in numba.prange(height):
        for x in range(width):
            for c in range(4):
                total = 0.0
                for s in range(n_samples):
                    total += stored[y, x, s, c] / 255.0
                mean = min(max(total / n_samples, 0.0), 1.0)
                out[height - 1 - y, x, c] = np.uint8(np.rint(mean * 255.0))


@numba.njit(cache=True, parallel=True)
def _resolve_bytes(stored, out):
    """out[H - 1 - y, x] = llvmpipe's float32 resolve of stored[y, x] (see
    `resolve_llvmpipe_bytes`): v * (1/255) summed in sample order, times 1/S, times
    255, clamped, rounded half to even; every step in float32.

    Row by row, a sample at a time into a row of float32 sums: each loop
    runs over a row's pixels and channels, the four channels of a pixel
    side by side, which LLVM turns into SIMD (a loop per pixel and channel
    over the samples did not: 5.6 ms against 3.3 ms for 512^2 at 4 samples,
    medians of 30 alternating, two threads).  Each sum is still the samples'
    in sample order.

    At 4 samples (GL's MSAA on llvmpipe) the row's products come first, in
    one loop over its bytes as they lie, then each pixel's four are summed:
    512^2 in 0.34 ms against 0.60 a sample at a time (medians of 50, two
    threads; the same bytes).  At 2, 8 and 16 samples that order was slower
    (0.25, 0.74 and 1.51 ms against 0.16, 0.60 and 1.22 for 256 x 512)."""
    height, width, n_samples = stored.shape[0], stored.shape[1], stored.shape[2]
    inv_255 = np.float32(1.0 / 255.0)
    inv_n = np.float32(1.0 / n_samples)
    for y in numba.prange(height):
        top = out[height - 1 - y].reshape(width * 4)
        total = np.empty(width * 4, np.float32)
        if n_samples == 4:
            flat = stored[y].reshape(width * 16)                # pixel x: sample s's channel c at 16 x + 4 s + c
            products = np.empty(width * 16, np.float32)
            for i in range(width * 16):
                products[i] = np.float32(flat[i]) * inv_255
            for x in range(width):
                for c in range(4):
                    total[4 * x + c] = (((products[16 * x + c] + products[16 * x + 4 + c])
                                         + products[16 * x + 8 + c]) + products[16 * x + 12 + c])
        else:
            row = stored[y].reshape(width, n_samples * 4)      # pixel x: sample s's channel c at 4 s + c
            for x in range(width):
                for c in range(4):
                    total[4 * x + c] = np.float32(row[x, c]) * inv_255
            for s in range(1, n_samples):
                for x in range(width):
                    for c in range(4):
                        total[4 * x + c] += np.float32(row[x, 4 * s + c]) * inv_255
        for j in range(width * 4):
            value = np.float32(np.float32(total[j] * inv_n) * np.float32(255.0))
            value = min(max(value, np.float32(0.0)), np.float32(255.0))
            top[j] = np.uint8(np.rint(value))


# Rows a box resolve converts at once (`resolve`).
RESOLVE_ROWS = 256


def resolve(color: np.ndarray, positions: np.ndarray | None = None, *, filter: str = "box",
            arithmetic: str = "exact", output: str = "uint8") -> np.ndarray:
    """Filter the samples to one colour per pixel and convert to the output image.

    color : (H, W, S, 4) premultiplied RGBA per sample, GL's y-up rows; for
        the tent filter also an RGBA8 sample buffer's bytes (uint8, byte k
        for k/255: `_tent_filter`).
    positions : (S, 2) sample positions in [0, 1)^2 within the pixel (y up);
        needed by "tent" only.
    filter : "box" -- the mean of the pixel's own samples (GL's resolve);
        "tent" -- a weighted mean over the samples of the pixel and its 8
        neighbours with weight ``(1 - |dx|)(1 - |dy|)`` for a sample at
        (dx, dy) pixels from the pixel's centre (a tent 2 pixels wide); at
        the image border the missing neighbours' weight is left out of the
        normalisation.
    arithmetic : "exact" (float64) or "llvmpipe" (`resolve_llvmpipe_bytes`; box
        filter, uint8 output only).
    output : "uint8" -- ``round(clamp(c, 0, 1) * 255)``; "float32" -- the
        filtered values, unclamped (an rgba32f framebuffer).

    Returns (H, W, 4) uint8 or float32 with row 0 = the top of the picture
    (GL's last row).
    """
    if filter not in RESOLVE_FILTERS:
        raise ValueError(f"resolve: filter must be one of {RESOLVE_FILTERS}, not {filter!r}")
    if arithmetic not in ("exact", "llvmpipe"):
        raise ValueError(f"resolve: arithmetic must be 'exact' or 'llvmpipe', not {arithmetic!r}")
    if output not in ("uint8", "float32"):
        raise ValueError(f"resolve: output must be 'uint8' or 'float32', not {output!r}")
    if arithmetic == "llvmpipe" and filter == "box" and output == "uint8":
        return resolve_llvmpipe_bytes(unorm8_bytes(color))
    convert = (lambda m: m.astype(np.float32)) if output == "float32" else unorm8_bytes
    if filter == "box":
        # By bands of rows (the mean over the sample axis of a band is the
        # band of the mean): float64 buffers of a band, not of the picture.
        out = np.empty(color.shape[:2] + (4,), np.float32 if output == "float32" else np.uint8)
        for top in range(0, color.shape[0], RESOLVE_ROWS):
            out[top:top + RESOLVE_ROWS] = convert(color[top:top + RESOLVE_ROWS].mean(axis=2, dtype=np.float64))
    else:
        if positions is None:
            raise ValueError("resolve: the tent filter needs the sample positions")
        out = convert(_tent_filter(color, np.asarray(positions, np.float64)))
    return out[::-1].copy()


# k / 255 for every byte k (the same doubles as numpy's division): an RGBA8
# buffer's values as the stages hold them (the tent here, and the compiled
# path's texels, `softras.kernels.texture`).
BYTE_VALUES = np.arange(256) / 255.0


def _tent_filter(color: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """(H, W, S, 4), (S, 2) -> (H, W, 4) float64 tent-weighted mean (see `resolve`).

    color : float values per sample, or an RGBA8 sample buffer's bytes
    (uint8, byte k read as the float64 k / 255, as ``color / 255.0`` would
    give it, without that float copy of the buffer).  Per pixel and
    channel, the 9 neighbours in row order (dy, then dx, from -1): a
    neighbour that exists and that the tent reaches adds its samples'
    values times their weights, summed in sample order, to the pixel's
    total, and the weights' sum (numpy's) to its weight; the result is
    total / weight.  A compiled loop over the pixels (`_tent_sums`); the
    numpy version, a tensordot per neighbour, summed in its BLAS's order and
    took 0.18 s of a 512^2 render at 4 samples (box: 8 ms; now 40 ms)."""
    weights = [_tent(dx + positions[:, 0] - 0.5) * _tent(dy + positions[:, 1] - 0.5)
               for dy in (-1, 0, 1) for dx in (-1, 0, 1)]                       # 9 x (S,)
    sums = np.array([w.sum() for w in weights])
    out = np.empty(color.shape[:2] + (4,))
    _tent_sums(np.ascontiguousarray(color), color.dtype == np.uint8, np.ascontiguousarray(weights), sums, out)
    return out


@numba.njit(cache=True, parallel=True)
def _tent_sums(color, as_bytes, weights, sums, out):
    """out[y, x] = the tent-weighted mean of `_tent_filter` at every pixel:
    color (H, W, S, 4) float values, or bytes k standing for k / 255 when
    as_bytes; weights (9, S) per neighbour (row order, dy then dx from -1)
    and sample, sums (9,) their sums.  The four channels side by side in the
    innermost loops (each channel's sums in the documented order)."""
    height, width, n_samples = color.shape[0], color.shape[1], color.shape[2]
    for y in numba.prange(height):
        total, partial = np.empty(4), np.empty(4)
        for x in range(width):
            total[:] = 0.0
            weight = 0.0
            for k in range(9):
                ny, nx = y + k // 3 - 1, x + k % 3 - 1
                if sums[k] == 0.0 or ny < 0 or ny >= height or nx < 0 or nx >= width:
                    continue
                for c in range(4):
                    partial[c] = _value(color[ny, nx, 0, c], as_bytes) * weights[k, 0]
                for s in range(1, n_samples):
                    for c in range(4):
                        partial[c] = partial[c] + _value(color[ny, nx, s, c], as_bytes) * weights[k, s]
                for c in range(4):
                    total[c] = total[c] + partial[c]
                weight = weight + sums[k]
            for c in range(4):
                out[y, x, c] = total[c] / weight


@numba.njit(cache=True, inline="always")
def _value(v, as_bytes):
    """A sample buffer's value v as float64: for a byte k (as_bytes) k / 255
    (`BYTE_VALUES`)."""
    return BYTE_VALUES[np.int64(v)] if as_bytes else np.float64(v)
