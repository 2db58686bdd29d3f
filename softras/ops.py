"""Per-sample operations: depth test, depth write, blending, resolve.

The framebuffer is per sample, in GL's y-up window space:

    color : (H, W, S, 4) float64 premultiplied RGBA
    depth : (H, W, S)    float64 z_w in [0, 1]

Fragments are applied strictly in order (GL's primitive order), one covered
sample at a time, by a numba kernel.  In gl precision the colour buffer is
RGBA8 UNORM: fragment and destination colours are clamped to [0, 1] and every
stored value is rounded to k/255 as GL does, and depths are rounded to the
24-bit depth buffer's k/(2^24 - 1).
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
    clear = np.concatenate([background[:3] * background[3], background[3:4]])
    if quantize:
        clear = quantize_unorm8(clear)
    color = np.empty((height, width, samples, 4))
    color[...] = clear
    depth = np.ones((height, width, samples))
    return color, depth


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


@numba.njit(cache=True)
def _blend(mode, src, dst, out):
    for ch in range(4):
        s = src[ch]
        d = dst[ch]
        if mode == 0:
            v = s
        elif mode == 1:
            v = s + (1.0 - src[3]) * d
        elif mode == 2:
            v = s * src[3] + (1.0 - src[3]) * d
        elif mode == 3:
            v = s + d
        elif mode == 4:
            v = s - d
        elif mode == 5:
            v = d - s
        elif mode == 6:
            v = min(s, d)
        else:
            v = max(s, d)
        out[ch] = v


@numba.njit(cache=True)
def apply_fragments(x, y, mask, z, rgba, color, depth, depth_func, depth_write, blend, quantize):
    """Depth-test, blend and store fragments in order.

    x, y : (F,) pixels; mask : (F,) uint32 covered samples; z : (F, S) depth
    per sample; rgba : (F, 4) premultiplied colour (one shading per pixel);
    color, depth : the framebuffer, updated in place.
    depth_func : DEPTH_FUNCS code (0 = test disabled: pass, never write);
    depth_write : bool; blend : BLEND_MODES code; quantize : RGBA8 rounding.
    """
    n_samples = depth.shape[2]
    src = np.empty(4)
    out = np.empty(4)
    write_z = depth_write and depth_func != 0
    for f in range(x.shape[0]):
        px = x[f]
        py = y[f]
        for ch in range(4):
            v = rgba[f, ch]
            if quantize:
                v = min(max(v, 0.0), 1.0)
            src[ch] = v
        for s in range(n_samples):
            if not (mask[f] >> s) & 1:
                continue
            if not _depth_pass(depth_func, z[f, s], depth[py, px, s]):
                continue
            if write_z:
                depth[py, px, s] = z[f, s]
            _blend(blend, src, color[py, px, s], out)
            for ch in range(4):
                v = out[ch]
                if quantize:
                    v = np.rint(min(max(v, 0.0), 1.0) * 255.0) / 255.0
                color[py, px, s, ch] = v


def resolve(color: np.ndarray) -> np.ndarray:
    """Box-filter the samples and convert to the output image.

    color : (H, W, S, 4) float64, y-up.  Returns (H, W, 4) uint8 with row 0 =
    the top of the picture (GL's last row).
    """
    mean = color.mean(axis=2)
    image = np.rint(np.clip(mean, 0.0, 1.0) * 255.0).astype(np.uint8)
    return image[::-1].copy()
