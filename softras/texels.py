"""Texel data of a scene texture: decoding, procedural textures, premultiplication
and the mip chain -- the scene layer's half of texturing.

Both renderers read the result through ``softras.scene.Texture.levels`` (computed
once per texture, on first use), so softras samples and glref uploads identical
bytes, and glref needs no module of softras but `softras.scene`.

- :func:`source_texels` reads a PNG through Pillow, or generates a procedural
  texture (checker, gradient, noise, bumps), as straight RGBA8, row 0 = the top
  of the image = v 0 (DESIGN.md section 3).
- :func:`premultiply_rgba8` premultiplies at load (before mip generation):
  ``c' = round(c * a / 255)``.
- :func:`mip_chain` builds the levels as glGenerateMipmap would: level sizes
  ``max(1, floor(size / 2))`` down to 1x1 (non-power-of-two too), each texel
  the rounded mean of a 2x2 box of the level above (2x1 or 1x1 where the level
  above is one texel thin).  With an odd size the last row or column of the
  level above has no box and is skipped: that is what a 2x2 box with
  ``floor(size / 2)`` means.  The levels are views of one buffer, back to
  back (:func:`levels_buffer`: the fast path samples them without a copy).

The per-texel loops are compiled (numba): a new scene's texture costs both
renderers its premultiplication and mip chain.
"""

from __future__ import annotations

import numba
import numpy as np



def source_texels(texture) -> np.ndarray:
    """Level 0 of a scene texture (`softras.scene.Texture`) as straight RGBA: (H, W, 4) uint8, row 0 = v 0."""
    if texture.decoded is not None:                 # an image, decoded by the loader
        return texture.decoded
    if texture.image is not None:
        return load_image(texture.image)
    return procedural_texels(texture.procedural, texture.size, texture.params)


def load_image(path: str) -> np.ndarray:
    """A picture file (PNG, anything Pillow reads) -> (H, W, 4) uint8 straight RGBA.

    Row 0 is the top row of the file, which is texture row t = 0.
    """
    from PIL import Image
    with Image.open(path) as image:
        return rgba_texels(image)


def rgba_texels(image) -> np.ndarray:
    """An open Pillow image -> (H, W, 4) uint8 straight RGBA, row 0 = its top row."""
    return np.ascontiguousarray(np.asarray(image.convert("RGBA"), dtype=np.uint8))


def _rgba8(color) -> np.ndarray:
    """(4,) float colour in [0, 1] -> (4,) uint8, round(c * 255)."""
    return np.rint(np.asarray(color, np.float64) * 255.0).astype(np.uint8)


def procedural_texels(kind: str, size: tuple[int, int], params: dict) -> np.ndarray:
    """Generate a procedural texture: (H, W, 4) uint8 straight RGBA, row 0 = v 0.

    checker : ``squares`` x ``squares`` cells; texel (i, j) is in cell
        (i * squares // W, j * squares // H) and has ``color0`` where the cell
        indices sum to an even number, ``color1`` elsewhere (so the top-left
        cell is color0).
    gradient : ``color0`` to ``color1`` across the width ("horizontal", left to
        right) or height ("vertical", top to bottom), sampled at texel centres:
        ``mix(color0, color1, (i + 0.5) / W)``, rounded to bytes.
    noise : white noise, RGB uniform in 0..255 from ``numpy.random.default_rng(seed)``,
        alpha 255.
    bumps : a height map for bump and displacement mapping: ``cells`` x
        ``cells`` round bumps, grey (R = G = B = height), alpha 255.  At texel
        centre (x, y) = ((i + 0.5) / W, (j + 0.5) / H) the cell-local position
        is ``f = frac((x, y) * cells) - 1/2`` and the height
        ``h = (1 + cos(pi min(2 |f|, 1))) / 2`` (1 at a cell centre, 0 from
        the inscribed circle outwards), rounded to bytes ``round(255 h)``.
    """
    width, height = int(size[0]), int(size[1])
    if kind == "checker":
        return _checker(width, height, int(params["squares"]), _rgba8(params["color0"]), _rgba8(params["color1"]))
    if kind == "gradient":
        c0 = np.asarray(params["color0"], np.float64)
        c1 = np.asarray(params["color1"], np.float64)
        if params["direction"] == "horizontal":
            f = (np.arange(width) + 0.5) / width
            row = c0 + f[:, None] * (c1 - c0)                      # (W, 4)
            out = np.broadcast_to(row[None], (height, width, 4))
        else:
            f = (np.arange(height) + 0.5) / height
            col = c0 + f[:, None] * (c1 - c0)                      # (H, 4)
            out = np.broadcast_to(col[:, None], (height, width, 4))
        return np.ascontiguousarray(np.rint(out * 255.0).astype(np.uint8))
    if kind == "noise":
        rng = np.random.default_rng(int(params["seed"]))
        out = np.empty((height, width, 4), np.uint8)
        out[..., :3] = rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8)
        out[..., 3] = 255
        return out
    if kind == "bumps":
        cells = int(params["cells"])
        fx = np.mod((np.arange(width) + 0.5) / width * cells, 1.0) - 0.5     # (W,)
        fy = np.mod((np.arange(height) + 0.5) / height * cells, 1.0) - 0.5   # (H,)
        radius = np.minimum(2.0 * np.hypot(fx[None, :], fy[:, None]), 1.0)   # (H, W)
        grey = np.rint(255.0 * (1.0 + np.cos(np.pi * radius)) / 2.0).astype(np.uint8)
        out = np.empty((height, width, 4), np.uint8)
        out[..., :3] = grey[..., None]
        out[..., 3] = 255
        return out
    raise ValueError(f"unknown procedural texture {kind!r}")


@numba.njit(cache=True)
def _checker(width, height, squares, color0, color1):
    """The checker of `procedural_texels`: (H, W, 4) uint8."""
    ci = np.empty(width, np.int64)
    for i in range(width):
        ci[i] = i * squares // width
    out = np.empty((height, width, 4), np.uint8)
    for j in range(height):
        cj = j * squares // height
        for i in range(width):
            odd = (cj + ci[i]) & 1
            for c in range(4):
                out[j, i, c] = color1[c] if odd else color0[c]
    return out


# round(c * a / 255) for every alpha a (row) and channel value c (column),
# halves up: (2 c a + 255) // 510.
_PREMULTIPLIED = ((np.arange(256)[None, :] * np.arange(256)[:, None] * 2 + 255) // 510).astype(np.uint8).ravel()


def premultiply_rgba8(straight: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Straight (..., 4) uint8 RGBA -> premultiplied uint8, ``round(c * a / 255)``
    (``(2 c a + 255) // 510``: halves round up); into ``out`` (same shape) when given."""
    straight = np.ascontiguousarray(straight, np.uint8)
    if out is None:
        out = np.empty_like(straight)
    _premultiply(straight.reshape(-1, 4), _PREMULTIPLIED, out.reshape(-1, 4))
    return out


@numba.njit(cache=True)
def _premultiply(texels, table, out):
    """(N, 4) uint8 straight -> out (N, 4) premultiplied, through the table (a * 256 + c)."""
    for i in range(texels.shape[0]):
        row = np.int64(texels[i, 3]) * 256
        out[i, 0] = table[row + texels[i, 0]]
        out[i, 1] = table[row + texels[i, 1]]
        out[i, 2] = table[row + texels[i, 2]]
        out[i, 3] = texels[i, 3]


def mip_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """(width, height) of every level, ``max(1, floor(size / 2))`` down to 1x1.

    >>> mip_sizes(5, 3)
    [(5, 3), (2, 1), (1, 1)]
    """
    sizes = [(int(width), int(height))]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append((max(1, w // 2), max(1, h // 2)))
    return sizes


def downsample(level: np.ndarray) -> np.ndarray:
    """The next mip level: 2x2 box (2x1 / 1x2 where the level is one texel thin),
    rounded to nearest (halves up).  (H, W, C) uint8 -> uint8."""
    h, w, channels = level.shape
    out = np.empty((max(1, h // 2), max(1, w // 2), channels), np.uint8)
    _downsample(np.ascontiguousarray(level, np.uint8), out)
    return out


@numba.njit(cache=True)
def _downsample(level, out):
    """`downsample` of a C-contiguous (H, W, C) uint8 level into out (H // 2, W // 2, C)."""
    h, w, channels = level.shape
    nh, nw = out.shape[0], out.shape[1]
    fy = 2 if h > 1 else 1
    fx = 2 if w > 1 else 1
    n = fy * fx
    for j in range(nh):
        for i in range(nw):
            for c in range(channels):
                total = np.uint32(0)
                for dy in range(fy):
                    for dx in range(fx):
                        total += np.uint32(level[j * fy + dy, i * fx + dx, c])
                out[j, i, c] = (total + np.uint32(n // 2)) // np.uint32(n)


def mip_chain(level0: np.ndarray, premultiply: bool = False) -> tuple[np.ndarray, ...]:
    """All levels from level 0 (H, W, C) uint8 down to 1x1 (see :func:`downsample`),
    level 0 premultiplied first when ``premultiply`` (C = 4, straight RGBA in).

    The levels lie back to back in one buffer, each a view of it
    (:func:`levels_buffer`), so that a renderer can take them all at once.
    """
    level0 = np.ascontiguousarray(level0, np.uint8)
    h, w, channels = level0.shape
    sizes = mip_sizes(w, h)
    buffer = np.empty(sum(sw * sh for sw, sh in sizes) * channels, np.uint8)
    levels, at = [], 0
    for sw, sh in sizes:
        levels.append(buffer[at:at + sw * sh * channels].reshape(sh, sw, channels))
        at += sw * sh * channels
    if premultiply:
        premultiply_rgba8(level0, levels[0])
    else:
        levels[0][...] = level0
    for above, level in zip(levels, levels[1:]):
        _downsample(above, level)
    return tuple(levels)


def levels_buffer(levels) -> np.ndarray:
    """``levels`` (uint8, level 0 first) as one flat buffer, back to back: the
    buffer :func:`mip_chain` laid them out in (no copy) when they lie in it
    from its start, else a concatenated copy."""
    buffer = levels[0].base
    if buffer is not None and buffer.ndim == 1 and buffer.dtype == np.uint8:
        start = at = buffer.__array_interface__["data"][0]
        for level in levels:
            if not level.flags.c_contiguous or level.__array_interface__["data"][0] != at:
                break
            at += level.nbytes
        else:
            return buffer[:at - start]
    return np.concatenate([np.ascontiguousarray(level, np.uint8).reshape(-1) for level in levels])
