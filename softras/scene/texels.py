"""Texel data of a scene texture: decoding, procedural textures, premultiplication
and the mip chain -- the scene layer's half of texturing.

softras samples the result through ``softras.scene.Texture.levels`` (computed
once per texture, on first use).  glref uploads level 0 of it (the same
premultiplied bytes) and has GL build the other levels with glGenerateMipmap;
:func:`mip_chain` reproduces what Mesa llvmpipe writes there byte for byte
(tests/test_mipmap_gl.py), so on llvmpipe both renderers still filter
identical texels.  glref needs no module of softras but `softras.scene`.

- :func:`source_texels` reads a PNG through Pillow, or generates a procedural
  texture (checker, gradient, noise, bumps), as straight RGBA8, row 0 = the top
  of the image = v 0 (docs/design.md section 3).
- :func:`premultiply_rgba8` premultiplies at load (before mip generation):
  ``c' = round(c * a / 255)``.
- :func:`mip_chain` builds the levels: sizes ``max(1, floor(size / 2))`` down
  to 1x1 (non-power-of-two too), each level reduced from the one above.
  The GL specification leaves the reduction open (GL 4.6 section 8.14.4,
  "No particular filter algorithm is required, though a box filter is
  recommended"); two are here:

  - ``method="llvmpipe"`` (the default): llvmpipe's glGenerateMipmap, a blit
    of level i onto level i + 1 that samples level i bilinearly at each
    destination texel's centre, in llvmpipe's 8.8 fixed point with clamp to
    edge (:func:`llvmpipe_blit_coordinates`, with the Mesa source it follows).
    Where a size is even the weights are exactly 1/2: the rounded mean of two
    texels along x, then of the two rows' means along y (within 1/255 of the
    rounded 2x2 mean); where it is odd the centre falls elsewhere between
    texels and the weights are not halves (3 -> 1 takes the middle texel alone).
  - ``method="box"``: the rounded mean of a 2x2 box of the level above (2x1
    or 1x1 where the level above is one texel thin); with an odd size the
    last row or column of the level above has no box and is skipped.

  The levels are views of one buffer, back to back (:func:`levels_buffer`:
  the fast path samples them without a copy).

The per-texel loops are compiled (numba, at their first call: `_compiled`):
a new scene's texture costs both renderers its premultiplication and mip
chain (glref reads level 0 of ``Texture.levels``, which builds the whole
chain).
"""

from __future__ import annotations

import functools

import numpy as np


def _compiled(loop):
    """``numba.njit(cache=True)`` of a per-texel loop, made at its first call.
    Importing numba costs a process ~0.16 s, and most processes that read a
    scene build no texels: the conformance supervisor (its workers render),
    `softras info`, `softras compare`."""
    jitted = None

    @functools.wraps(loop)
    def call(*args):
        nonlocal jitted
        if jitted is None:
            import numba

            jitted = numba.njit(cache=True)(loop)
        return jitted(*args)

    return call


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


class TooManyTexels(ValueError):
    """An image over the texture size limits; the message is "W x H texels, more than the limit (...)"."""


#: The exceptions Pillow reports truncated or corrupt image data with: for
#: the readers' "cannot decode" message (`parse`, `gltf`).
DECODE_ERRORS = (OSError, SyntaxError, ValueError, EOFError)


def checked_texels(image, max_side: int, max_texels: int) -> np.ndarray:
    """`rgba_texels` of an open Pillow image whose size, from its header, is
    within the limits (``max_side`` a side, ``max_texels`` in all: the scene
    model's MAX_SIDE and MAX_TEXELS); `TooManyTexels` before any pixel is
    decoded otherwise."""
    width, height = image.size
    if not (1 <= width <= max_side and 1 <= height <= max_side) or width * height > max_texels:
        raise TooManyTexels(f"{width} x {height} texels, more than the limit ({max_side} per side, "
                            f"{max_texels} in all)")
    return rgba_texels(image)


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


@_compiled
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


@_compiled
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


#: The reductions :func:`mip_chain` builds a level from the one above with.
MIP_METHODS = ("llvmpipe", "box")


def downsample(level: np.ndarray, method: str = "llvmpipe") -> np.ndarray:
    """The next mip level of a (H, W, C) uint8 level: (max(1, H // 2), max(1, W // 2), C) uint8.

    method "llvmpipe": llvmpipe's glGenerateMipmap, a bilinear blit in 8.8
    fixed point (:func:`llvmpipe_blit_coordinates`); "box": the rounded mean
    of a 2x2 box (2x1 / 1x2 where the level is one texel thin; an odd last
    row or column is skipped), halves up.
    """
    h, w, channels = level.shape
    out = np.empty((max(1, h // 2), max(1, w // 2), channels), np.uint8)
    _REDUCE[_method(method)](np.ascontiguousarray(level, np.uint8), out)
    return out


def _method(method: str) -> str:
    if method not in MIP_METHODS:
        raise ValueError(f"mip method must be one of {MIP_METHODS}, not {method!r}")
    return method


@_compiled
def _downsample(level, out):
    """The box reduction of a C-contiguous (H, W, C) uint8 level into out (H // 2, W // 2, C)."""
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


# --------------------------------------------------------------------------- llvmpipe's glGenerateMipmap
#
# Mesa (source read in a 23.0-devel snapshot, behaviour checked on 22.3.6; W x H
# is the destination level): glGenerateMipmap -> st_generate_mipmap
# (state_tracker/st_gen_mipmap.c; llvmpipe has no pipe->generate_mipmap) ->
# util_gen_mipmap (auxiliary/util/u_gen_mipmap.c): for every level i + 1 a
# pipe->blit of the whole level i onto the whole level i + 1 with
# PIPE_TEX_FILTER_LINEAR -> lp_blit (llvmpipe/lp_surface.c) ->
# util_blitter_blit (auxiliary/util/u_blitter.c): a draw of one rectangle over
# the destination, the source level bound as a sampler view
# with a linear, clamp-to-edge sampler (sampler_state_linear) and normalized
# texture coordinates 0 and 1 at the rectangle's corners (get_texcoords), the
# vertices at window (0, 0), (W, 0), (W, H), (0, H) (blitter_set_rectangle,
# a triangle fan), each pixel's colour the sampled texel (TEX, no blending).
# llvmpipe draws the fan as two triangles (lp_setup_vbuf.c: rect() falls back
# to triangles when the colour buffer is not B8G8R8A8: no linear rasterizer
# for RGBA8), and the arithmetic that decides the bytes is:
#
# - per triangle, plane equations of s and t in float32 (lp_state_setup.c,
#   init_args and calc_coef4): ooa = 1 / (W H), ds/dx = H ooa, dt/dy = W ooa,
#   a0 = a_v - (dadx (x_v - 1/2) + dady (y_v - 1/2)) from the triangle's first
#   vertex v (after triangle_both's swap to counter-clockwise: (W, 0) for the
#   upper-right triangle, (W, H) for the lower-left one), so s is the same in
#   both triangles but t's a0 is not;
# - per pixel (i, j): s = fma(ds/dx, i, a0_s) and t = fma(dt/dy, j, a0_t)
#   (lp_bld_interp.c, attribs_update_simple: lp_build_fmuladd, fused on a CPU
#   with FMA; the other term's slope is 0);
# - sampling (gallivm/lp_bld_sample_aos.c, lp_build_sample_image_linear: the
#   RGBA8 "AoS" path): round(s * float(256 W_src)) - 128 in 8.8 fixed point
#   (round half to even), index = that >> 8, weight = that & 255, both
#   indices clamped to the level (clamp to edge), the four texels blended by
#   the byte lerps of `softras.pipeline.texture.lerp8` (along x, then y);
# - a pixel centre exactly on the diagonal belongs to the upper-right
#   triangle (measured: 5 sizes where the two triangles' t differ there).
#
# Checked byte for byte against llvmpipe's glGenerateMipmap read back
# (tests/test_mipmap_gl.py).  Without FMA (a CPU older than x86-64-v3) LLVM
# would not fuse, and 0.1-0.2 % of a large NPOT level's texels would differ by 1.


def _fma32(a, b, c) -> np.ndarray:
    """float32 fused multiply-add ``a b + c`` rounded once: float32 arrays or
    scalars (broadcast) -> float32 array.

    ``a b`` of two float32 is exact in float64; the float64 sum is made
    round-to-odd (its TwoSum error decides the last bit), and rounding that
    to float32 is then the correctly rounded result (53 >= 24 + 2 bits;
    Boldo and Melquiond, "When double rounding is odd", 2005).
    """
    p = np.asarray(a, np.float32).astype(np.float64) * np.asarray(b, np.float32).astype(np.float64)
    c = np.asarray(c, np.float32).astype(np.float64)
    s = p + c
    bp = s - c
    err = (p - bp) + (c - (s - bp))                       # p + c = s + err exactly
    even = (np.asarray(s).view(np.int64) & 1) == 0
    s = np.where((err != 0) & even, np.nextafter(s, np.where(err > 0, np.inf, -np.inf)), s)
    return s.astype(np.float32)


def llvmpipe_blit_coordinates(dst_size: tuple[int, int], src_size: tuple[int, int]):
    """The 8.8 fixed-point source coordinates of llvmpipe's linear blit of a
    whole (W_src, H_src) level onto a whole (W, H) one (``dst_size`` and
    ``src_size`` as (width, height); see the comment above for the Mesa source).

    Returns (s, t_upper, t_lower): int64 texel-space coordinates times 256,
    minus 128 (half a texel): s (W,) per destination column; t (H,) per
    destination row, in the upper-right triangle (pixel centres with
    ``(j + 1/2) W <= (i + 1/2) H``, the diagonal included) and in the
    lower-left one.  Index ``c >> 8``, weight of the next texel ``c & 255``.
    """
    f32 = np.float32
    width, height = int(dst_size[0]), int(dst_size[1])
    ooa = f32(1) / (f32(width) * f32(height))             # 1 / (e - f), twice the area
    dsdx = f32(height) * ooa                              # da01 dy20_ooa - da20 dy01_ooa
    dtdy = f32(width) * ooa
    s0 = f32(1) - dsdx * f32(width - 0.5)                 # vertex (W, y): s = 1
    t0_upper = f32(0) - dtdy * f32(-0.5)                  # vertex (W, 0): t = 0
    t0_lower = f32(1) - dtdy * f32(height - 0.5)          # vertex (W, H): t = 1
    s = _fma32(dsdx, np.arange(width, dtype=np.float32), s0)
    rows = np.arange(height, dtype=np.float32)
    t_upper, t_lower = _fma32(dtdy, rows, t0_upper), _fma32(dtdy, rows, t0_lower)

    def fixed(coord, size):
        return np.rint(coord * f32(size * 256)).astype(np.int64) - 128

    return fixed(s, src_size[0]), fixed(t_upper, src_size[1]), fixed(t_lower, src_size[1])


def _axis(fixed: np.ndarray, size: int):
    """8.8 coordinates -> (first index, second index, weight of the second),
    int64 each, the indices clamped to [0, size) (clamp to edge)."""
    i0 = fixed >> 8
    return np.clip(i0, 0, size - 1), np.clip(i0 + 1, 0, size - 1), fixed & 255


@functools.lru_cache(maxsize=256)
def _blit_axes(dst_size: tuple[int, int], src_size: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """`_axis` of s, t_upper and t_lower for one level size pair: nine read-only
    int64 arrays.  Cached: the float32 steps cost ~0.1 ms a level in numpy,
    more than the blend itself, and a scene loaded again has the same sizes."""
    s, t_upper, t_lower = llvmpipe_blit_coordinates(dst_size, src_size)
    axes = (*_axis(s, src_size[0]), *_axis(t_upper, src_size[1]), *_axis(t_lower, src_size[1]))
    for a in axes:
        a.flags.writeable = False
    return axes


def _llvmpipe_reduce(level, out):
    """llvmpipe's blit of a C-contiguous (H, W, C) uint8 level into out (H', W', C)."""
    h, w = level.shape[:2]
    _blit_linear(level, *_blit_axes((out.shape[1], out.shape[0]), (w, h)), out)


@_compiled
def _blit_linear(level, x0, x1, wx, y0u, y1u, wyu, y0l, y1l, wyl, out):
    """Bilinear 8.8 blend of `level` into out at per-column (x0, x1, wx) and
    per-row coordinates of the upper-right (y0u, y1u, wyu) and lower-left
    (y0l, y1l, wyl) triangle: llvmpipe's lerps ``a + ((w (b - a) + 128) >> 8)``,
    along x on both rows, then along y."""
    nh, nw, channels = out.shape
    for j in range(nh):
        for i in range(nw):
            if (2 * j + 1) * nw <= (2 * i + 1) * nh:      # on or above the diagonal (0, 0)-(W, H)
                ya, yb, wy = y0u[j], y1u[j], wyu[j]
            else:
                ya, yb, wy = y0l[j], y1l[j], wyl[j]
            xa, xb, w = x0[i], x1[i], wx[i]
            for c in range(channels):
                t00 = np.int64(level[ya, xa, c])
                t10 = np.int64(level[ya, xb, c])
                t01 = np.int64(level[yb, xa, c])
                t11 = np.int64(level[yb, xb, c])
                top = t00 + ((w * (t10 - t00) + 128) >> 8)
                bottom = t01 + ((w * (t11 - t01) + 128) >> 8)
                out[j, i, c] = top + ((wy * (bottom - top) + 128) >> 8)


_REDUCE = {"llvmpipe": _llvmpipe_reduce, "box": _downsample}


def mip_chain(level0: np.ndarray, premultiply: bool = False, method: str = "llvmpipe") -> tuple[np.ndarray, ...]:
    """All levels from level 0 (H, W, C) uint8 down to 1x1, each reduced from
    the one above by :func:`downsample` with ``method`` ("llvmpipe": what
    llvmpipe's glGenerateMipmap writes, byte for byte; "box": the rounded
    2x2 mean), level 0 premultiplied first when ``premultiply`` (C = 4,
    straight RGBA in).

    The levels lie back to back in one buffer, each a view of it
    (:func:`levels_buffer`), so that a renderer can take them all at once.
    """
    reduce = _REDUCE[_method(method)]
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
        reduce(above, level)
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


# ----------------------------------------------------------------------------- addressing


def wrap(i: np.ndarray, size: int, mode: str) -> np.ndarray:
    """Integer texel index -> index inside [0, size) (GL 4.5 section 8.14.2).

    repeat : i mod size.  clamp_to_edge : clamp to [0, size - 1].
    mirrored_repeat : the texture mirrored every other period,
    ``m = i mod 2 size; m if m < size else 2 size - 1 - m``.
    """
    if mode == "repeat":
        return np.mod(i, size)
    if mode == "clamp_to_edge":
        return np.clip(i, 0, size - 1)
    if mode == "mirrored_repeat":
        m = np.mod(i, 2 * size)
        return np.where(m < size, m, 2 * size - 1 - m)
    raise ValueError(f"unknown wrap mode {mode!r}")


def linear_float_addresses(s: np.ndarray, size: int, mode: str):
    """GL's linear filter along one axis in float64 (GL 4.5 section 8.14.2):
    ``u = s size - 1/2``; returns (i0, i1, weight of i1) = (wrap(floor(u)),
    wrap(floor(u) + 1), frac(u)), (N,) each."""
    u = s * size - 0.5
    i0 = np.floor(u)
    return wrap(i0.astype(np.int64), size, mode), wrap(i0.astype(np.int64) + 1, size, mode), u - i0


def bilinear(level: np.ndarray, s: np.ndarray, t: np.ndarray, wrap_s: str, wrap_t: str) -> np.ndarray:
    """One level (H, W, 4) uint8 filtered bilinearly at (s, t), (N,) each, in
    float64: (N, 4) texel values on the 0..255 scale."""
    h, w = level.shape[:2]
    i0, i1, a = linear_float_addresses(s, w, wrap_s)
    j0, j1, b = linear_float_addresses(t, h, wrap_t)
    t00, t10 = level[j0, i0].astype(np.float64), level[j0, i1].astype(np.float64)
    t01, t11 = level[j1, i0].astype(np.float64), level[j1, i1].astype(np.float64)
    a, b = a[:, None], b[:, None]
    return (1 - a) * (1 - b) * t00 + a * (1 - b) * t10 + (1 - a) * b * t01 + a * b * t11
