"""The gl-precision fast path: one fused, tiled, compiled kernel per draw.

`softras.pipeline.render` is the readable reference: every stage materialises its
output (clipped triangles, set-up triangles, a fragment list, per-fragment
attributes) as numpy arrays.  This module computes *the same numbers* (bit for
bit, see tests/test_fastpath.py) for the draws that need only the common
features, without the intermediate buffers:

1. vertex: `softras.pipeline.vertex.to_clip` (a compiled float32 loop, per vertex);
2. clip: `softras.pipeline.clip.clip_triangles` (its crossing triangles go through a
   compiled kernel in gl precision);
3. setup (`_setup`, compiled, one pass over the clipped triangles): viewport
   transform with llvmpipe's fused multiply-add, 1/256 snapping, area and
   culling, counter-clockwise corner order, integer edge functions, fill rule,
   pixel bounding box, depth plane, and (`_corner_values`) the attributes at
   the corners (clip weights x source vertex values, in the pipeline's order);
4. binning (`_bin`): the visible triangles are listed, in draw order, in every
   64x64-pixel tile their bounding box touches;
5. the tile driver (`_make_draw_tiles`, one per sample count and
   texturing): tiles in parallel (numba prange: a pixel belongs to one tile,
   so tiles never race on the framebuffer); within a tile the triangles in
   draw order; per triangle the 8x8 blocks of its bounding box inside the
   tile with the exact early-out / early-in corner test of
   `softras.pipeline.rasterize`; the covered pixels listed as "lanes" (below the
   tile kernel) and shaded by loops over the lanes that compile to SIMD:
   depth at each sample (plane equation, 24-bit rounding), depth test,
   perspective-correct colour, texture (`_textured_block`: the block's
   covered 2x2 quads, with per-quad derivatives and level of detail),
   RGBA8 rounding, blend and the write.  No fragment list exists.

The framebuffer here is what gl precision stores anyway: colour as RGBA8
bytes (``(H, W, S, 4) uint8``; byte k stands for the pipeline's float k/255)
and depth as the integer k of the pipeline's depth k / (2^24 - 1) (``(H, W, S)
int32``; -1 for NaN): the depth test compares integers, and no division
turns k back into a float (`_depth_pass_k`).

`unsupported(scene, ...)` says why a scene must take the general path (lines,
lit shading, anisotropic textures, other sample counts or clipping
policies...).  A draw pays only for what it uses: the texture stage runs only
for a textured draw, blending only with a blend mode (the kernel branches on
per-draw constants outside of the per-pixel work).

Why one module of ~1300 lines: it is one fused kernel.  The set-up, binning
and tile code share the row layouts of the set-up triangles (the ``_F_*``
columns, ``tri_i``) and the framebuffer's byte and depth-integer encoding,
and the small helpers are inlined (``inline="always"``) into the one tile
kernel; the sections follow the steps listed above.
"""

from __future__ import annotations

import math
import os
import threading

# numba's default OpenMP threading layer leaves its threads spinning after a
# parallel region; on a loaded 2-core machine they steal the core that
# llvmpipe's threads (glref, same process) and other processes need: the 24k
# grid took 24 ms with 2 spinning threads against 12 ms with 1 (docs/speed.md).
# Passive waiting (read by libgomp when numba first starts its threads) keeps
# the second thread's gain on a quiet machine.  An explicit setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numba  # noqa: E402  (after the environment default above)
import numpy as np

from softras.pipeline import clip as clip_stage
from softras.pipeline import ops, setup, texture, vertex
from softras.pipeline.ops import blend_byte, unorm8
from softras.scene import Scene, ordered_draws
from softras.scene.texels import levels_buffer
from softras.pipeline.texture import WRAP_CODES, wrap_index

TILE = 64          # pixels per tile side (binning and the parallel unit)
BLOCK = 8          # pixels per block side (hierarchical coverage test)
DEPTH_SCALE = float((1 << ops.DEPTH_BITS) - 1)

# Per set-up triangle, float64 row of `tri_f`: window x (3), y (3), z (3),
# 1/w (3), dz/dx, dz/dy.  int64 row of `tri_i`: edge A (3), B (3), X0 (3),
# Y0 (3), inclusive (3), corners swapped (1), visible (1).
_F_X, _F_Y, _F_Z, _F_W, _F_DZDX, _F_DZDY, _NF = 0, 3, 6, 9, 12, 13, 14
_I_A, _I_B, _I_X0, _I_Y0, _I_INC, _I_SWAP, _I_VIS, _NI = 0, 3, 6, 9, 12, 15, 16, 17

CULL_CODES = {"none": 0, "back": 1, "front": 2}
FILTER_CODES = {"nearest": 0, "linear": 1}
MIN_FILTERS = ("nearest", "linear") + texture.MIPMAP_FILTERS
# Texture parameter vector (int64): enabled, min image filter, mag filter,
# mip mode (0 none, 1 nearest, 2 linear), wrap s, wrap t, fixed8, levels,
# whether the vectorised filter applies (`_lanes_bilinear_fixed`).
_T_ON, _T_MIN, _T_MAG, _T_MIP, _T_WS, _T_WT, _T_FIXED, _T_LEVELS, _T_VEC, _NT = range(10)

# Sample counts the fast path renders (the positions are the pipeline's).
FAST_SAMPLES = (1, 4)


# ----------------------------------------------------------------------------- dispatch


def unsupported(scene: Scene, *, precision: str, samples: int, clipping: str | None) -> str | None:
    """Why ``scene`` must take the general pipeline, or None when this path renders it.

    The caller (`softras.renderer.render_scene`) has already checked the
    options this path does not look at (RGBA8 framebuffer, GL's sample
    pattern).
    """
    if precision != "gl":
        return "precision is not gl"
    if samples not in FAST_SAMPLES:
        return f"{samples} samples"
    if clipping not in (None, "llvmpipe"):
        return f"clipping {clipping!r}"
    for draw in scene.draws:
        material = draw.material
        if draw.mesh.primitive != "triangles":
            return f"{draw.path}: {draw.mesh.primitive}"
        if material.shading != "unlit":
            return f"{draw.path}: {material.shading} shading"
        if material.normal_map is not None or material.bump_map is not None:
            return f"{draw.path}: normal or bump map"
        if material.texture is not None:
            tex = scene.textures[material.texture]
            if (tex.max_anisotropy > 1 or tex.wrap_s not in WRAP_CODES or tex.wrap_t not in WRAP_CODES
                    or tex.mag_filter not in FILTER_CODES or tex.min_filter not in MIN_FILTERS):
                return f"{draw.path}: texture sampler state"
    return None


def render_samples(scene: Scene, positions: np.ndarray, *, texture_fixed_point: bool = True,
                   reuse: bool = False) -> np.ndarray:
    """Render a scene that `unsupported` accepts at GL's sample positions (S, 2).

    Returns the per-sample colour buffer (H, W, S, 4) uint8, GL's y-up rows:
    byte k where the general pipeline stores the float k/255.  reuse: the
    buffer is this thread's scratch colour buffer, overwritten by the next
    call (for a caller that copies it at once; saves the page faults of a
    fresh buffer).
    """
    offsets, _ = setup.sample_offsets(positions, "gl")
    shape = (scene.height, scene.width, len(positions))
    depth = _scratch.take("depth", shape, np.int32)
    color = _scratch.take("color", shape + (4,), np.uint8) if reuse else np.empty(shape + (4,), np.uint8)
    offsets = np.ascontiguousarray(offsets, np.int64)
    positions = np.ascontiguousarray(positions, np.float64)
    clear(color, depth, ops.unorm8_bytes(ops.premultiplied(scene.background)))
    for draw in ordered_draws(scene):
        draw_triangles(scene, draw, color, depth, offsets, positions, texture_fixed_point)
    return color


def draw_triangles(scene: Scene, draw, color, depth, offsets, positions, texture_fixed_point) -> None:
    """One triangle draw into the byte framebuffer (see the module docstring)."""
    mesh = draw.mesh
    width, height = scene.width, scene.height
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    clip_pos = vertex.to_clip(mesh.positions, mvp, "gl")
    source, slot, fan_clip, fan_weights = clip_stage.triangle_list_gl(clip_pos, mesh.indices)
    if len(source) == 0:
        return
    n = len(source)
    n_threads = numba.get_num_threads()
    material = draw.material
    textured = material.texture is not None
    vertex_colors = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
    base = np.ascontiguousarray(vertex_colors * material.color)             # straight, per vertex
    uvs = (np.ascontiguousarray(mesh.uvs.astype(np.float32).astype(np.float64)) if textured
           else np.zeros((0, 2)))
    tri_f = _scratch.take("tri_f", (n, _NF), np.float64)
    tri_i = _scratch.take("tri_i", (n, _NI), np.int64)
    bbox = _scratch.take("bbox", (n, 4), np.int64)
    colors = _scratch.take("colors", (n, 3, 4), np.float64)
    uv = _scratch.take("uv", (n if textured else 1, 3, 2), np.float64)
    _setup(clip_pos, mesh.indices, source, slot, fan_clip, fan_weights, width, height, CULL_CODES[draw.cull],
           offsets, tri_f, tri_i, bbox, (base, colors, uvs, uv), n_threads)
    visible = np.flatnonzero(tri_i[:, _I_VIS])
    if len(visible) == 0:
        return
    tex_params = np.zeros(_NT, np.int64)
    levels_flat, level_table = np.zeros(4, np.uint8), np.zeros((1, 3), np.int64)
    if textured:
        tex = texture.prepare(scene.textures[material.texture])
        tex_params, levels_flat, level_table = texture_tables(tex, texture_fixed_point)
    tiles_x = (width + TILE - 1) // TILE
    tiles_y = (height + TILE - 1) // TILE
    bin_start, bin_tri = _bin(visible, bbox, tiles_x, tiles_y)
    draw_tiles = _DRAW_TILES[len(offsets), textured]
    draw_tiles(bin_start, bin_tri, tiles_x, width, height, tri_f, tri_i, bbox, colors, uv,
                offsets, positions, color.view(np.uint32).reshape(color.shape[:3]), depth,
                ops.DEPTH_FUNCS[draw.depth_test], bool(draw.depth_write), ops.BLEND_MODES[draw.blend],
                textured and plain_colors(base),
                tex_params, levels_flat, levels_flat.view(np.uint32), level_table, n_threads)


def plain_colors(base: np.ndarray) -> bool:
    """Whether a textured draw's fragment colour is its texel's bytes as they
    are: every vertex colour (V, 4, straight, times the material's) is
    opaque white.

    The fragment colour is then (w0 + w1 + w2)^2 * k / 255 per colour
    channel and (w0 + w1 + w2) * k / 255 for alpha (`_shade_word`; corner
    colours of clipped triangles are sums of clip weights, 1 within a few
    ulp).  At a covered pixel centre the perspective weights are within
    rounding of [0, 1] and sum to 1 within a few ulp, so the value is k/255 within ~1e-15,
    and `ops.unorm8` gives back k (the product is within ~1e-13 of the
    integer k, nowhere near a rounding boundary; tests/test_fastpath.py
    checks every k).  The kernel uses it at one sample only, where the
    weights are taken at the covered sample itself."""
    return bool(np.all(base == 1.0))


_tables_cache: dict = {}


def texture_tables(tex: texture.MipTexture, fixed_point: bool):
    """A prepared texture as the kernel's (params (8,) int64, texels (N,) uint8,
    levels (L, 3) int64 offset / width / height) tables; cached per prepared
    texture (`texture.prepare` returns the same object for a scene texture)."""
    key = (id(tex), bool(fixed_point))
    hit = _tables_cache.get(key)
    if hit is not None and hit[0] is tex:
        return hit[1]
    tables = _texture_tables(tex, fixed_point)
    if len(_tables_cache) >= 16:
        _tables_cache.clear()
    _tables_cache[key] = (tex, tables)
    return tables


def _texture_tables(tex: texture.MipTexture, fixed_point: bool):
    levels = tex.used_levels
    table = np.zeros((len(levels), 3), np.int64)
    at = 0
    for k, level in enumerate(levels):
        h, w = level.shape[:2]
        table[k] = (at, w, h)
        at += h * w * 4
    flat = levels_buffer(levels)                    # the mip chain's own buffer: no copy
    mip = 0
    if tex.mipmapped:
        mip = 1 if tex.min_filter.endswith("mipmap_nearest") else 2
    fixed8 = fixed_point and texture.uses_fixed_point(tex, True)
    min_filter, mag_filter = FILTER_CODES[tex.min_filter.split("_")[0]], FILTER_CODES[tex.mag_filter]
    h, w = levels[0].shape[:2]
    # The vectorised filter: 8.8 bilinear on every level, wraps by mask or clamp
    # (a power-of-two level 0 has power-of-two levels all the way down).
    vectorised = (fixed8 and min_filter == mag_filter == FILTER_CODES["linear"]
                  and all(mode == "clamp_to_edge" or (size & (size - 1)) == 0
                          for mode, size in ((tex.wrap_s, w), (tex.wrap_t, h))))
    params = np.array([1, min_filter, mag_filter, mip, WRAP_CODES[tex.wrap_s], WRAP_CODES[tex.wrap_t],
                       int(fixed8), len(levels), int(vectorised)], np.int64)
    return params, flat, table


SUBPIXEL_BITS = setup.SUBPIXEL_BITS      # gl precision snaps to 1/256 pixel
SUBPIXEL_ONE = setup.SUBPIXEL_ONE
PARALLEL_SETUP = 4096      # triangles from which `_setup` runs in parallel chunks


class _Scratch(threading.local):
    """Per-thread arrays reused from one render to the next (the set-up tables,
    corner attributes and depth buffer).  A fresh multi-megabyte array costs a
    page fault per 4 KiB page when first written, on this machine about as
    much as setting up the triangles that fill it; a reused one is already
    mapped.  Buffers over MAX_BYTES are not kept."""

    MAX_BYTES = 64 << 20

    def __init__(self):
        self.buffers = {}

    def take(self, name: str, shape: tuple, dtype) -> np.ndarray:
        """An uninitialised C-contiguous array of this shape and dtype."""
        dtype = np.dtype(dtype)
        size = math.prod(shape)
        buffer = self.buffers.get(name)
        if buffer is None or buffer.dtype != dtype or buffer.size < size:
            buffer = np.empty(max(size, 1), dtype)
            if buffer.nbytes <= self.MAX_BYTES:
                self.buffers[name] = buffer
        return buffer[:size].reshape(shape)


_scratch = _Scratch()


def scratch_nbytes() -> int:
    """Bytes held by this thread's reused fast-path buffers (for memory reports)."""
    return sum(buffer.nbytes for buffer in _scratch.buffers.values())


# ----------------------------------------------------------------------------- setup


def _setup(clip_pos, indices, source, slot, fan_clip, fan_weights, width, height, cull, offsets,
           tri_f, tri_i, bbox, attributes, n_threads):
    """Set up the clipped triangles (`_setup_range`): in one call, or in
    parallel chunks from PARALLEL_SETUP triangles."""
    # The window corners of the input vertices, once per vertex (a vertex is
    # shared by ~6 triangles).
    vertex_f = _scratch.take("vertex_f", (len(clip_pos), 4), np.float64)
    vertex_i = _scratch.take("vertex_i", (len(clip_pos), 2), np.int64)
    _window_vertices(clip_pos, width, height, vertex_f, vertex_i)
    args = (vertex_f, vertex_i, indices, source, slot, fan_clip, fan_weights, width, height, cull, offsets,
            tri_f, tri_i, bbox, attributes)
    if len(source) < PARALLEL_SETUP:
        _setup_range(0, len(source), *args)
    else:
        _setup_chunks(*args, 4 * n_threads)


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _setup_chunks(vertex_f, vertex_i, indices, source, slot, fan_clip, fan_weights, width, height, cull,
                  offsets, tri_f, tri_i, bbox, attributes, n_chunks):
    """`_setup_range` over n_chunks parallel chunks of the triangles (one
    compiled loop body serves the serial and the parallel set-up)."""
    n = source.shape[0]
    for chunk in numba.prange(n_chunks):
        _setup_range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks, vertex_f, vertex_i, indices, source,
                     slot, fan_clip, fan_weights, width, height, cull, offsets, tri_f, tri_i, bbox, attributes)


@numba.njit(cache=True, error_model="numpy")
def _window_vertices(clip_pos, width, height, vertex_f, vertex_i):
    """`_window_corner` of every input vertex (clip_pos (V, 4)): fills
    vertex_f (V, 4) float64 with window x, y, z and 1/w and vertex_i (V, 2)
    int64 with the snapped x, y."""
    for v in range(clip_pos.shape[0]):
        (vertex_f[v, 0], vertex_f[v, 1], vertex_f[v, 2], vertex_f[v, 3], vertex_i[v, 0],
         vertex_i[v, 1]) = _window_corner(clip_pos[v, 0], clip_pos[v, 1], clip_pos[v, 2], clip_pos[v, 3],
                                          True, width, height)


@numba.njit(cache=True, inline="always")
def _window_corner(x, y, z, w, fused, width, height):
    """One clip-space corner (x, y, z, w) -> window (x, y, z) as float32
    values, 1/w (float32) and the corner snapped to 1/256 pixel (x, y int64),
    as `softras.pipeline.setup` computes them in gl precision: llvmpipe's viewport
    transform with a fused multiply-add for an input vertex (``fused``), an
    unfused one for a vertex made by the clipper."""
    oow = np.float32(1.0) / np.float32(w)
    px = np.float64(np.float32(x) * oow)
    py = np.float64(np.float32(y) * oow)
    pz = np.float64(np.float32(z) * oow)
    hx, hy, hz = width / 2.0, height / 2.0, 0.5
    if fused:
        wx = np.float64(np.float32(px * hx + hx))
        wy = np.float64(np.float32(py * hy + hy))
        wz = np.float64(np.float32(pz * hz + hz))
    else:
        wx = np.float64(np.float32(np.float32(px * hx) + np.float32(hx)))
        wy = np.float64(np.float32(np.float32(py * hy) + np.float32(hy)))
        wz = np.float64(np.float32(np.float32(pz * hz) + np.float32(hz)))
    rx = np.int64(np.rint((np.float32(wx) - np.float32(0.5)) * np.float32(SUBPIXEL_ONE)))
    ry = np.int64(np.rint((np.float32(wy) - np.float32(0.5)) * np.float32(SUBPIXEL_ONE)))
    return wx, wy, wz, np.float64(oow), rx, ry


@numba.njit(cache=True, error_model="numpy")
def _setup_range(start, stop, vertex_f, vertex_i, indices, source, slot, fan_clip, fan_weights, width, height,
                 cull, offsets, tri_f, tri_i, bbox, attributes):
    """`softras.pipeline.setup.setup_triangles` (gl precision) and the depth plane of
    `softras.pipeline.interpolate.depth_at_samples`, for the clipped triangles start
    to stop - 1 listed by `softras.pipeline.clip.triangle_list_gl` (source, slot,
    fan_clip, fan_weights), the input vertices' window corners given
    (`_window_vertices`).

    Fills their rows of tri_f (T, 14) float64, tri_i (T, 17) int64 (layouts
    at the top of the module), bbox (T, 4) int64 (x0, x1, y0, y1 inclusive)
    and the corner attributes (`_corner_values`) of ``attributes`` = (vertex
    colours (V, 4), corner colours (T, 3, 4), vertex uvs (V, 2) or (0, 2)
    when untextured, corner uvs (T, 3, 2)); the triangles that the pipeline
    drops (zero area, culled, empty box) have tri_i[:, _I_VIS] == 0 and their
    other entries undefined.
    """
    min_ox, max_ox = offsets[:, 0].min(), offsets[:, 0].max()
    min_oy, max_oy = offsets[:, 1].min(), offsets[:, 1].max()
    vertex_colors, corner_colors, vertex_uvs, corner_uvs = attributes
    wx = np.empty(3)
    wy = np.empty(3)
    wz = np.empty(3)
    iw = np.empty(3)
    rx = np.empty(3, np.int64)
    ry = np.empty(3, np.int64)
    for t in range(start, stop):
        tri_i[t, _I_VIS] = 0
        tri_i[t, _I_SWAP] = 0
        f = slot[t]
        for k in range(3):
            if f < 0:
                v = indices[source[t], k]
                wx[k], wy[k], wz[k], iw[k] = vertex_f[v, 0], vertex_f[v, 1], vertex_f[v, 2], vertex_f[v, 3]
                rx[k], ry[k] = vertex_i[v, 0], vertex_i[v, 1]
            else:
                # A vertex made by the clipper has no weight exactly 1 (clip.generated).
                fused = max(fan_weights[f, k, 0], max(fan_weights[f, k, 1], fan_weights[f, k, 2])) == 1.0
                wx[k], wy[k], wz[k], iw[k], rx[k], ry[k] = _window_corner(
                    fan_clip[f, k, 0], fan_clip[f, k, 1], fan_clip[f, k, 2], fan_clip[f, k, 3], fused,
                    width, height)
        area = (rx[1] - rx[0]) * (ry[2] - ry[0]) - (rx[2] - rx[0]) * (ry[1] - ry[0])
        front = area > 0
        if area == 0 or (cull == 1 and not front) or (cull == 2 and front):
            continue
        if not front:                           # swap corners 0 and 1 -> counter-clockwise
            wx[0], wx[1] = wx[1], wx[0]
            wy[0], wy[1] = wy[1], wy[0]
            wz[0], wz[1] = wz[1], wz[0]
            iw[0], iw[1] = iw[1], iw[0]
            rx[0], rx[1] = rx[1], rx[0]
            ry[0], ry[1] = ry[1], ry[0]
            tri_i[t, _I_SWAP] = 1
        # Bounding box in pixels, as setup_triangles computes it (its
        # float ceil / floor of a multiple of 1/256 here in integers).
        x_lo = -((max_ox - min(rx[0], min(rx[1], rx[2]))) >> SUBPIXEL_BITS)
        x_hi = (max(rx[0], max(rx[1], rx[2])) - min_ox) >> SUBPIXEL_BITS
        y_lo = -((max_oy - min(ry[0], min(ry[1], ry[2]))) >> SUBPIXEL_BITS)
        y_hi = (max(ry[0], max(ry[1], ry[2])) - min_oy) >> SUBPIXEL_BITS
        b0 = max(min(max(x_lo, -1), width), 0)
        b1 = min(min(max(x_hi, -1), width), width - 1)
        b2 = max(min(max(y_lo, -1), height), 0)
        b3 = min(min(max(y_hi, -1), height), height - 1)
        if b0 > b1 or b2 > b3:
            continue
        bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = b0, b1, b2, b3
        for i in range(3):
            j = (i + 1) % 3
            x0, y0, x1, y1 = rx[i], ry[i], rx[j], ry[j]
            sign = 1
            if x0 > x1 or (x0 == x1 and y0 > y1):
                x0, y0, x1, y1 = x1, y1, x0, y0
                sign = -1
            a = (y0 - y1) * sign
            b = (x1 - x0) * sign
            tri_i[t, _I_A + i] = a
            tri_i[t, _I_B + i] = b
            tri_i[t, _I_X0 + i] = x0
            tri_i[t, _I_Y0 + i] = y0
            tri_i[t, _I_INC + i] = 1 if (a > 0 or (a == 0 and b > 0)) else 0
        tri_i[t, _I_VIS] = 1
        for k in range(3):
            tri_f[t, _F_X + k] = wx[k]
            tri_f[t, _F_Y + k] = wy[k]
            tri_f[t, _F_Z + k] = wz[k]
            tri_f[t, _F_W + k] = iw[k]
        dx1, dy1, dz1 = wx[1] - wx[0], wy[1] - wy[0], wz[1] - wz[0]
        dx2, dy2, dz2 = wx[2] - wx[0], wy[2] - wy[0], wz[2] - wz[0]
        det = dx1 * dy2 - dx2 * dy1
        tri_f[t, _F_DZDX] = (dz1 * dy2 - dz2 * dy1) / det
        tri_f[t, _F_DZDY] = (dx1 * dz2 - dx2 * dz1) / det
        _corner_values(vertex_colors, corner_colors, t, indices, source, slot, fan_weights,
                       tri_i[t, _I_SWAP])
        if vertex_uvs.shape[0]:
            _corner_values(vertex_uvs, corner_uvs, t, indices, source, slot, fan_weights,
                           tri_i[t, _I_SWAP])


@numba.njit(cache=True, inline="always")
def _corner_values(values, out, t, indices, source, slot, fan_weights, swapped):
    """Attributes at set-up triangle t's corners: out[t] (3, K) from the
    vertex values (V, K), as the pipeline's ``einsum("tkj,tjc->tkc", w,
    values[vertices])`` with the clip weights (identity for a passed-through
    triangle) in set-up corner order and the same sum order."""
    i0, i1, i2 = indices[source[t], 0], indices[source[t], 1], indices[source[t], 2]
    f = slot[t]
    for k in range(3):
        row = 1 - k if swapped and k < 2 else k
        if f < 0:
            w0, w1, w2 = (1.0 if row == 0 else 0.0), (1.0 if row == 1 else 0.0), (1.0 if row == 2 else 0.0)
        else:
            w0, w1, w2 = fan_weights[f, row, 0], fan_weights[f, row, 1], fan_weights[f, row, 2]
        for c in range(values.shape[1]):
            out[t, k, c] = w0 * values[i0, c] + w1 * values[i1, c] + w2 * values[i2, c]


# ----------------------------------------------------------------------------- binning


@numba.njit(cache=True)
def _bin(visible, bbox, tiles_x, tiles_y):
    """Per-tile triangle lists in draw order: (bin_start (tiles + 1,), bin_tri (N,))."""
    counts = np.zeros(tiles_x * tiles_y + 1, np.int64)
    for v in range(visible.shape[0]):
        t = visible[v]
        for ty in range(bbox[t, 2] // TILE, bbox[t, 3] // TILE + 1):
            for tx in range(bbox[t, 0] // TILE, bbox[t, 1] // TILE + 1):
                counts[ty * tiles_x + tx + 1] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    out = np.empty(start[-1], np.int64)
    for v in range(visible.shape[0]):
        t = visible[v]
        for ty in range(bbox[t, 2] // TILE, bbox[t, 3] // TILE + 1):
            for tx in range(bbox[t, 0] // TILE, bbox[t, 1] // TILE + 1):
                k = ty * tiles_x + tx
                out[fill[k]] = t
                fill[k] += 1
    return start, out


# ----------------------------------------------------------------------------- per pixel
#
# The per-pixel helpers below take and return scalars only.  A numba function
# that receives an array increments and decrements its reference count (an
# atomic operation) on every call, inlined or not; per pixel that costs more
# than the arithmetic, and with several threads the shared counters bounce
# between cores.  So the tile kernel itself does every array access.


@numba.njit(cache=True, error_model="numpy", inline="always")
def _weights_at(x0, x1, x2, y0, y1, y2, iw0, iw1, iw2, px, py):
    """`interpolate.barycentric` then `interpolate.perspective_weights` at window
    point (px, py), same operations in the same order: (w0, w1, w2) float64."""
    e0 = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    e1 = (x0 - x2) * (py - y2) - (y0 - y2) * (px - x2)
    e2 = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0)
    total = e0 + e1 + e2
    q0 = e0 / total * iw0
    q1 = e1 / total * iw1
    q2 = e2 / total * iw2
    qs = q0 + q1 + q2
    return q0 / qs, q1 / qs, q2 / qs


@numba.njit(cache=True, inline="always")
def _inside3(sx, sy, a0, b0, ex0, ey0, k0, a1, b1, ex1, ey1, k1, a2, b2, ex2, ey2, k2):
    """Whether sample (sx, sy) (1/256 px) is inside all three integer edge
    functions of `softras.pipeline.rasterize` (k = 1 for an exclusive edge: e > 0,
    k = 0 for an inclusive one: e >= 0)."""
    return ((a0 * (sx - ex0) + b0 * (sy - ey0) - k0) | (a1 * (sx - ex1) + b1 * (sy - ey1) - k1)
            | (a2 * (sx - ex2) + b2 * (sy - ey2) - k2)) >= 0


@numba.njit(cache=True, inline="always")
def _edge_range(a, b, ex, ey, x_lo, x_hi, y_lo, y_hi):
    """(min, max) of the integer edge function a (x - ex) + b (y - ey) over a rectangle's corners."""
    e00 = a * (x_lo - ex) + b * (y_lo - ey)
    e10 = a * (x_hi - ex) + b * (y_lo - ey)
    e01 = a * (x_lo - ex) + b * (y_hi - ey)
    e11 = a * (x_hi - ex) + b * (y_hi - ey)
    return min(min(e00, e10), min(e01, e11)), max(max(e00, e10), max(e01, e11))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _shade_word(w0, w1, w2, cr0, cr1, cr2, cg0, cg1, cg2, cb0, cb1, cb2, ca0, ca1, ca2, tr, tg, tb, ta):
    """fragment.shade_unlit (premultiplied perspective colour x texel; texel 1
    when untextured, which leaves every value as it is) as the bytes llvmpipe
    converts the fragment colour to (`ops.unorm8`), packed in one RGBA8 word
    (R in the low byte)."""
    alpha = w0 * ca0 + w1 * ca1 + w2 * ca2
    r = (w0 * cr0 + w1 * cr1 + w2 * cr2) * alpha * tr
    g = (w0 * cg0 + w1 * cg1 + w2 * cg2) * alpha * tg
    b = (w0 * cb0 + w1 * cb1 + w2 * cb2) * alpha * tb
    return unorm8(r) | (unorm8(g) << 8) | (unorm8(b) << 16) | (unorm8(alpha * ta) << 24)


@numba.njit(cache=True, inline="always")
def _nearest(s, size, mode):
    """`texture.nearest_addresses`: the texel index of coordinate s."""
    return wrap_index(np.int64(np.floor(np.float32(s) * np.float32(size))), size, mode)


@numba.njit(cache=True, inline="always")
def _linear_fixed(s, size, mode):
    """`texture.linear_addresses` with fixed8: (i0, i1, weight 0..255)."""
    s32 = np.float32(s)
    if mode == 0 and (size & (size - 1)) != 0:
        f = s32 - np.float32(np.floor(s32))
        fixed = np.int64(np.rint(np.float32(f * np.float32(size)) * np.float32(256))) - 128
        weight = fixed & 255
        i0 = fixed >> 8
        if i0 < 0:
            i0 = size - 1
        i0 = min(i0, size - 1)
        i1 = i0 + 1 if i0 != size - 1 else 0
        return i0, i1, weight
    fixed = np.int64(np.rint(np.float32(s32 * np.float32(size * 256)))) - 128
    weight = fixed & 255
    i0 = fixed >> 8
    return wrap_index(i0, size, mode), wrap_index(i0 + 1, size, mode), weight


@numba.njit(cache=True, error_model="numpy", inline="always")
def _linear_float(s, size, mode):
    """`texture.linear_addresses` with float weights: (i0, i1, weight)."""
    u = s * size - 0.5
    fu = np.floor(u)
    return wrap_index(np.int64(fu), size, mode), wrap_index(np.int64(fu) + 1, size, mode), u - fu


@numba.njit(cache=True, error_model="numpy", inline="always")
def _bilinear_float(a, b, t00, t10, t01, t11):
    return (1 - a) * (1 - b) * t00 + a * (1 - b) * t10 + (1 - a) * b * t01 + a * b * t11


# k / 255 for every byte k (the same doubles as the division).
_BYTE_VALUES = np.arange(256) / 255.0

# An RGBA8 texel (uint32, R in the low byte) "spread" into four 16-bit lanes of
# a uint64 (R, B, G, A at bits 0, 16, 32, 48), so one 64-bit multiply-add
# filters all four channels: see `_lerp_lanes`.
_LANES = np.uint64(0x00FF00FF00FF00FF)
_HALF_LANES = np.uint64(0x0080008000800080)
_ONE_LANES = np.uint64(0x0001000100010001)


@numba.njit(cache=True, inline="always")
def _spread(texel):
    x = np.uint64(texel)
    return (x | (x << np.uint64(24))) & _LANES


@numba.njit(cache=True, inline="always")
def _unspread(x):
    """The RGBA8 word (int64) of spread lanes x: `_spread` undone."""
    return np.int64((x | (x >> np.uint64(24))) & np.uint64(0xFFFFFFFF))


@numba.njit(cache=True, inline="always")
def _lane(x, c):
    """Channel c (0 R, 1 G, 2 B, 3 A) of spread lanes, 0..255."""
    shift = 0 if c == 0 else (32 if c == 1 else (16 if c == 2 else 48))
    return np.int64((x >> np.uint64(shift)) & np.uint64(255))


@numba.njit(cache=True, inline="always")
def _lerp_lanes(w, a, b):
    """``_lerp8(w, a, b) = a + ((w (b - a) + 128) >> 8)`` on all four lanes at
    once, for 0 <= w <= 256: the same integer as ``((256 - w) a + w b + 128) >> 8``,
    which stays below 2^16 in every lane (no carry between lanes)."""
    return ((np.uint64(256 - w) * a + np.uint64(w) * b + _HALF_LANES) >> np.uint64(8)) & _LANES


@numba.njit(cache=True, inline="always")
def _bilerp_lanes(fa, fb, t00, t10, t01, t11):
    """llvmpipe's 8.8 bilinear filter on spread lanes: texels t00, t10 (row
    0) and t01, t11 (row 1) with weights fa across and fb down (0..255)."""
    return _lerp_lanes(fb, _lerp_lanes(fa, t00, t10), _lerp_lanes(fa, t01, t11))


@numba.njit(cache=True, inline="always")
def _lerp8(w, a, b):
    """llvmpipe's 8.8 fixed-point lerp of bytes a, b with weight w in 0..256."""
    return a + ((w * (b - a) + 128) >> 8)


@numba.njit(cache=True, inline="always")
def _nan_max(x, y):
    """np.maximum: NaN if either is NaN (selects, no branches)."""
    return x + y if (x != x) | (y != y) else (x if x >= y else y)


_FLOAT32_TINY = np.float32(np.finfo(np.float32).tiny)


@numba.njit(cache=True, inline="always")
def _frexp32(x):
    """math.frexp of a float32 x from its bits: (mantissa in [0.5, 1) as
    float32, exponent) for a normal x; (x, 0) for inf and NaN as C's frexp
    gives them.  (Subnormals are not handled: callers pass x >= the
    smallest normal or only use the exponent of x > 0, where a subnormal's
    -126 and frexp's lower exponent select the same level.)"""
    bits = np.int64(np.float32(x).view(np.int32))
    field = (bits >> 23) & 255
    special = field == 255
    mantissa = np.int32((bits & 0x807FFFFF) | 0x3F000000).view(np.float32)
    return (np.float32(x) if special else mantissa), (0 if special else field - 126)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _quad_lod(width0, height0, mip, last, mag_filter, min_filter, ddx_s, ddx_t, ddy_s, ddy_t):
    """The level choice of `texture.sample` (gl precision, `texture.choose_levels`)
    for one quad's derivatives (float32 values): (level0, level1, frac, image
    filter, whether to blend two levels).  Written with selects, no branches
    to mispredict and no call to frexp; lod = +-inf or NaN picks levels as the
    float -> int64 conversion of numpy and llvmpipe does (the "integer
    indefinite", negative)."""
    w32 = np.float32(width0)
    h32 = np.float32(height0)
    du0 = np.float32(ddx_s) * w32
    du1 = np.float32(ddx_t) * h32
    dv0 = np.float32(ddy_s) * w32
    dv1 = np.float32(ddy_t) * h32
    rho2 = _nan_max(du0 * du0 + du1 * du1, dv0 * dv0 + dv1 * dv1)      # float32
    magnified = not (rho2 > 1)
    level0 = 0
    level1 = 0
    frac = 0.0
    if mip == 1:
        e = _frexp32(rho2)[1]                          # (rho2 > 0: a subnormal's -126 -> level 0 too)
        level = e >> 1 if rho2 > 0 else 0
        level0 = min(max(level, 0), last)
        level1 = level0
    elif mip == 2:
        m, e = _frexp32(_nan_max(rho2, _FLOAT32_TINY))
        log2 = np.float32(np.float32(e - 1) + (np.float32(2) * m - np.float32(1)))
        lod = np.float32(0.5) * log2
        ipart_f = np.float32(np.floor(lod))
        frac = np.float64(np.float32(lod - ipart_f))
        finite = np.abs(ipart_f) <= np.float32(1e6)     # (|lod| <= 64 when finite)
        ipart = np.int64(ipart_f if finite else np.float32(-1e6))
        frac = 0.0 if (ipart < 0) | (ipart >= last) else frac
        level0 = min(max(ipart, 0), last)
        level1 = min(max(ipart + 1, 0), last)
    level0 = 0 if magnified else level0
    image_filter = mag_filter if magnified else min_filter
    two = (not magnified) & (level1 != level0) & (frac > 0)
    return level0, level1, frac, image_filter, two


def clear(color, depth, clear_bytes):
    """Fill the byte colour buffer (H, W, S, 4) with clear_bytes (4,) uint8 and depth
    (H, W, S) int32 with 1 (DEPTH_SCALE, see the module docstring).

    numpy's fill of the buffer seen as RGBA8 words: a third of the time of a
    parallel numba loop, which also pays the wake-up of its threads."""
    color.view(np.uint32).fill(np.ascontiguousarray(clear_bytes, np.uint8).view(np.uint32)[0])
    depth.fill(int(DEPTH_SCALE))


# ----------------------------------------------------------------------------- the tile kernel
#
# Pixels are shaded in "lanes": `_tile` lists an untextured triangle's
# covered pixels (shaded from LANES of them on, `_flat_block`) or a textured
# triangle's covered 2x2 quads of one 8x8 block (4 lanes per quad, up to 64,
# `_textured_block`); then each step runs as one loop over the lanes.  The
# steps without branches or table look-ups (the
# perspective weights with their six divisions, depth, texel addresses, the
# 8.8 filter, the colour bytes) are loops that LLVM compiles to AVX2 (4 or 8
# lanes per instruction); the depth test, the quad's level of detail, the
# texel fetches and the framebuffer writes stay scalar.  Same operations in
# the same order per lane, so the bits are those of the per-pixel code.

LANES = 64                                   # 16 quads of an 8x8 block
# float64 lane rows: pixel centre, perspective weights, (s, t), per level the
# float32 scales size * 256 of s and t, the mip blend fraction, the filtered
# texel (r, g, b, a in [0, 1]).
_LF_CX, _LF_CY, _LF_W, _LF_S, _LF_T, _LF_SCALE, _LF_FRAC, _LF_TEX, _NLF = 0, 1, 2, 5, 6, 7, 11, 12, 16
# int64 lane rows: pixel, coverage mask, depth-passed mask, per level the
# texel word offset / width / height, mip weight (0..256), levels, image
# filter, two levels or one, the 8 texel addresses, the 4 filter weights,
# the fragment's RGBA8 word, then the depth at each sample as its 24-bit
# integer (`_lane_depths`).
(_LI_PX, _LI_PY, _LI_COV, _LI_PASS, _LI_BASE, _LI_LW, _LI_LH, _LI_W8, _LI_LEVEL, _LI_IMGF, _LI_TWO,
 _LI_ADDR, _LI_FRAC8, _LI_WORD, _LI_Z) = 0, 1, 2, 3, 4, 6, 8, 10, 11, 13, 14, 15, 23, 27, 28


def _make_draw_tiles(n_samples: int, textured: bool):
    """The parallel tile driver compiled for one sample count (1 or 4,
    `FAST_SAMPLES`) and textured or not, as constants (closure variables are
    compile-time constants to numba, and part of its cache key): the compiler
    unrolls the per-sample and per-quad loops and drops the texture code from
    untextured draws, and a scene compiles only the variants it uses."""

    @numba.njit(cache=True, parallel=True, error_model="numpy")
    def draw_tiles(bin_start, bin_tri, tiles_x, width, height, tri_f, tri_i, bbox, colors, uv,
                   offsets, positions, color32, depth, depth_func, depth_write, blend, plain,
                   tex_params, texels, texels32, table, n_threads):
        """Rasterize, shade and apply every binned triangle, tiles in parallel.

        color32 : the (H, W, S, 4) uint8 colour buffer seen as (H, W, S) RGBA8
        words (R in the low byte), depth : (H, W, S) int32 (see the module
        docstring), updated in place.
        texels / texels32 : a texture's levels as bytes and as RGBA8 words.
        Thread r of ``n_threads`` draws tiles r, r + n_threads, ... (interleaved,
        so a scene covering only part of the picture still keeps every thread busy).
        """
        n_tiles = bin_start.shape[0] - 1
        for r in numba.prange(n_threads):
            texel = np.empty((2, 4))             # float-weight filtering: the two levels' RGBA
            lf = np.zeros((_NLF, 2 * LANES))                # lane rows (see above)
            li = np.zeros((_LI_Z + n_samples, 2 * LANES), np.int64)
            lu = np.zeros((8, LANES), np.uint64)             # the 8 fetched texels, spread
            edges = np.zeros((3, n_samples), np.int64)      # a row's edge functions per sample
            # (Grouped in tuples: CPython 3.11 passes a call with over 30
            # arguments as *args, which numba cannot inline.)
            buffers = (texel, lf, li, lu, edges)
            for tile in range(r, n_tiles, n_threads):
                _tile(tile, bin_start, bin_tri, tiles_x, width, height, tri_f, tri_i, bbox, colors, uv,
                      offsets, positions, color32, depth, (depth_func, depth_write, blend, plain),
                      (tex_params, texels, texels32, table), buffers, n_samples, textured)

    return draw_tiles


@numba.njit(cache=True, error_model="numpy", inline="always")
def _tile(tile, bin_start, bin_tri, tiles_x, width, height, tri_f, tri_i, bbox, colors, uv,
          offsets, positions, color32, depth, state, tex, buffers, n_samples, textured):
    """One 64x64 tile: its triangles in draw order; per triangle the 8x8 blocks
    of its bounding box inside the tile with the exact early-out / early-in
    corner test of `softras.pipeline.rasterize`; then in lanes: the covered pixels of
    an untextured triangle (`_flat_block`, from LANES of them and after its
    last block), the covered quads of a textured one per block
    (`_textured_block`).  The per-pixel arithmetic is `softras.pipeline.render`'s,
    operation for operation.

    state : (depth function, depth write, blend mode) codes and whether the
    draw's colour is the texel's own (`plain_colors`); tex : (params,
    texels as bytes, as RGBA8 words, level table); buffers : the thread's
    scratch arrays (see `_make_draw_tiles`)."""
    depth_func, depth_write, blend, plain = state
    lf, li, edges = buffers[1], buffers[2], buffers[4]
    full_mask = (1 << n_samples) - 1
    min_ox, max_ox = offsets[:, 0].min(), offsets[:, 0].max()
    min_oy, max_oy = offsets[:, 1].min(), offsets[:, 1].max()
    write_z = depth_write and depth_func != 0
    step = 2 if textured else 1             # blocks start at even pixels when textured (whole quads)
    tx0 = (tile % tiles_x) * TILE
    ty0 = (tile // tiles_x) * TILE
    tx1 = min(tx0 + TILE, width) - 1
    ty1 = min(ty0 + TILE, height) - 1
    for j in range(bin_start[tile], bin_start[tile + 1]):
        t = bin_tri[j]
        a0, b0, ex0, ey0, k0 = (tri_i[t, _I_A], tri_i[t, _I_B], tri_i[t, _I_X0], tri_i[t, _I_Y0],
                                1 - tri_i[t, _I_INC])
        a1, b1, ex1, ey1, k1 = (tri_i[t, _I_A + 1], tri_i[t, _I_B + 1], tri_i[t, _I_X0 + 1],
                                tri_i[t, _I_Y0 + 1], 1 - tri_i[t, _I_INC + 1])
        a2, b2, ex2, ey2, k2 = (tri_i[t, _I_A + 2], tri_i[t, _I_B + 2], tri_i[t, _I_X0 + 2],
                                tri_i[t, _I_Y0 + 2], 1 - tri_i[t, _I_INC + 2])
        n_flat = 0                              # untextured lanes listed, shaded from LANES on
        step0, step1, step2 = a0 * 256, a1 * 256, a2 * 256     # edge steps per pixel
        x_start = max(bbox[t, 0], tx0)
        x_end = min(bbox[t, 1], tx1)
        y_start = max(bbox[t, 2], ty0)
        y_end = min(bbox[t, 3], ty1)
        for block_y in range(y_start & -step, y_end + 1, BLOCK):
            by = max(block_y, y_start)
            by1 = min(block_y + BLOCK - 1, y_end)
            for block_x in range(x_start & -step, x_end + 1, BLOCK):
                bx = max(block_x, x_start)
                bx1 = min(block_x + BLOCK - 1, x_end)
                # The edge functions at the block's extreme sample positions.
                x_lo = bx * 256 + min_ox
                x_hi = bx1 * 256 + max_ox
                y_lo = by * 256 + min_oy
                y_hi = by1 * 256 + max_oy
                e_min0, e_max0 = _edge_range(a0, b0, ex0, ey0, x_lo, x_hi, y_lo, y_hi)
                e_min1, e_max1 = _edge_range(a1, b1, ex1, ey1, x_lo, x_hi, y_lo, y_hi)
                e_min2, e_max2 = _edge_range(a2, b2, ex2, ey2, x_lo, x_hi, y_lo, y_hi)
                if ((e_max0 - k0) | (e_max1 - k1) | (e_max2 - k2)) < 0:
                    continue                            # the block is outside an edge
                all_in = ((e_min0 - k0) | (e_min1 - k1) | (e_min2 - k2)) >= 0
                if textured:
                    if all_in and bx1 - bx == BLOCK - 1 and by1 - by == BLOCK - 1:
                        # A whole block inside the triangle: its 16 quads in
                        # the order below, every sample covered, no tests.
                        n = LANES
                        for l in range(LANES):
                            px = bx + ((l >> 2) & 3) * 2 + (l & 1)
                            py = by + (l >> 4) * 2 + ((l >> 1) & 1)
                            li[_LI_PX, l] = px
                            li[_LI_PY, l] = py
                            li[_LI_COV, l] = full_mask
                            lf[_LF_CX, l] = px + 0.5
                            lf[_LF_CY, l] = py + 0.5
                    else:
                        # List the block's quads with any covered sample as lanes.
                        n = 0
                        for qy in range(by & -2, by1 + 1, 2):
                            for qx in range(bx & -2, bx1 + 1, 2):
                                quad_mask = 0
                                for k in range(4):
                                    px = qx + (k & 1)
                                    py = qy + (k >> 1)
                                    mask = 0
                                    if bx <= px <= bx1 and by <= py <= by1:
                                        mask = full_mask
                                        if not all_in:
                                            mask = 0
                                            for s in range(n_samples):
                                                if _inside3(px * 256 + offsets[s, 0], py * 256 + offsets[s, 1],
                                                            a0, b0, ex0, ey0, k0, a1, b1, ex1, ey1, k1,
                                                            a2, b2, ex2, ey2, k2):
                                                    mask |= 1 << s
                                    li[_LI_PX, n + k] = px
                                    li[_LI_PY, n + k] = py
                                    li[_LI_COV, n + k] = mask
                                    lf[_LF_CX, n + k] = px + 0.5
                                    lf[_LF_CY, n + k] = py + 0.5
                                    quad_mask |= mask
                                if quad_mask:
                                    n += 4
                    if n:
                        _textured_block(n, t, tri_f, colors, uv, positions, depth, color32,
                                        depth_func, write_z, blend, plain, tex, buffers, n_samples)
                    continue
                # Untextured: the block's part of the box listed as lanes, the
                # covered pixels kept without a branch (which pixels a small
                # triangle covers is unpredictable); shaded once LANES are
                # listed and after the triangle's last block.
                n = n_flat
                for py in range(by, by1 + 1):
                    if not all_in:
                        # The edge functions (`_inside3`) at the row's first
                        # pixel, then stepped by a * 256 per pixel.
                        for s in range(n_samples):
                            sx = bx * 256 + offsets[s, 0]
                            sy = py * 256 + offsets[s, 1]
                            edges[0, s] = a0 * (sx - ex0) + b0 * (sy - ey0) - k0
                            edges[1, s] = a1 * (sx - ex1) + b1 * (sy - ey1) - k1
                            edges[2, s] = a2 * (sx - ex2) + b2 * (sy - ey2) - k2
                    for i in range(bx1 - bx + 1):
                        mask = full_mask
                        if not all_in:
                            mask = 0
                            for s in range(n_samples):
                                inside = ((edges[0, s] + step0 * i) | (edges[1, s] + step1 * i)
                                          | (edges[2, s] + step2 * i)) >= 0
                                mask |= np.int64(inside) << s
                        li[_LI_PX, n] = bx + i
                        li[_LI_PY, n] = py
                        li[_LI_COV, n] = mask
                        n += mask != 0
                n_flat = n
                if n_flat >= LANES:
                    _flat_block(n_flat, t, tri_f, colors, uv, positions, depth, color32, depth_func,
                                write_z, blend, buffers, n_samples)
                    n_flat = 0
        if n_flat:
            _flat_block(n_flat, t, tri_f, colors, uv, positions, depth, color32, depth_func, write_z,
                        blend, buffers, n_samples)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _flat_block(n, t, tri_f, colors, uv, positions, depth, color32, depth_func, write_z, blend,
                buffers, n_samples):
    """Depth-test, shade and write the n lanes (covered pixels of one
    untextured triangle, listed by `_tile` with pixel and coverage mask):
    depths (vectorised), the depth test keeping the lanes with a passed
    sample (scalar, without branches), perspective weights and colour bytes
    (vectorised), the writes (scalar)."""
    lf, li = buffers[1], buffers[2]
    _lane_depths(n, t, tri_f, positions, li, n_samples)
    kept = 0
    for l in range(n):
        px, py = li[_LI_PX, l], li[_LI_PY, l]
        p = _depth_test_lane(li[_LI_COV, l], li, l, depth, py, px, depth_func, write_z, n_samples)
        li[_LI_PX, kept] = px
        li[_LI_PY, kept] = py
        li[_LI_PASS, kept] = p
        lf[_LF_CX, kept] = px + 0.5
        lf[_LF_CY, kept] = py + 0.5
        kept += p != 0
    _lane_weights(kept, t, tri_f, lf, uv, False)
    _lane_words(kept, t, colors, lf, li, False)
    _write_lanes(kept, li, color32, blend, n_samples)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_weights(n, t, tri_f, lf, uv, textured):
    """Perspective weights of triangle t at the n lanes' pixel centres
    (`_weights_at`) into the _LF_W rows and, when textured, its (s, t) there
    (uv (T, 3, 2) at the corners) into the _LF_S / _LF_T rows (a vectorised loop)."""
    x0, x1, x2 = tri_f[t, _F_X], tri_f[t, _F_X + 1], tri_f[t, _F_X + 2]
    y0, y1, y2 = tri_f[t, _F_Y], tri_f[t, _F_Y + 1], tri_f[t, _F_Y + 2]
    iw0, iw1, iw2 = tri_f[t, _F_W], tri_f[t, _F_W + 1], tri_f[t, _F_W + 2]
    u0 = u1 = u2 = v0 = v1 = v2 = 0.0
    if textured:                        # (an untextured draw's uv is a (1, 3, 2) placeholder)
        u0, u1, u2 = uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0]
        v0, v1, v2 = uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1]
    for l in range(n):
        w0, w1, w2 = _weights_at(x0, x1, x2, y0, y1, y2, iw0, iw1, iw2, lf[_LF_CX, l], lf[_LF_CY, l])
        lf[_LF_W, l] = w0
        lf[_LF_W + 1, l] = w1
        lf[_LF_W + 2, l] = w2
        if textured:
            lf[_LF_S, l] = w0 * u0 + w1 * u1 + w2 * u2
            lf[_LF_T, l] = w0 * v0 + w1 * v1 + w2 * v2


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_words(n, t, colors, lf, li, textured):
    """The fragment colour of the n lanes as llvmpipe's bytes (`_shade_word`:
    triangle t's corner colours under the _LF_W weights, times the _LF_TEX
    texel when textured), one RGBA8 word each into the _LI_WORD row (a
    vectorised loop)."""
    cr0, cr1, cr2 = colors[t, 0, 0], colors[t, 1, 0], colors[t, 2, 0]
    cg0, cg1, cg2 = colors[t, 0, 1], colors[t, 1, 1], colors[t, 2, 1]
    cb0, cb1, cb2 = colors[t, 0, 2], colors[t, 1, 2], colors[t, 2, 2]
    ca0, ca1, ca2 = colors[t, 0, 3], colors[t, 1, 3], colors[t, 2, 3]
    for l in range(n):
        tr = lf[_LF_TEX, l] if textured else 1.0
        tg = lf[_LF_TEX + 1, l] if textured else 1.0
        tb = lf[_LF_TEX + 2, l] if textured else 1.0
        ta = lf[_LF_TEX + 3, l] if textured else 1.0
        li[_LI_WORD, l] = _shade_word(lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l],
                                      cr0, cr1, cr2, cg0, cg1, cg2, cb0, cb1, cb2, ca0, ca1, ca2, tr, tg, tb, ta)


@numba.njit(cache=True, inline="always")
def _write_lanes(n, li, color32, blend, n_samples):
    """Store or blend the n lanes' RGBA8 words into their passed samples
    (`_write_word` per lane, scalar)."""
    for l in range(n):
        p = li[_LI_PASS, l]
        if p:
            _write_word(color32, li[_LI_PY, l], li[_LI_PX, l], p, n_samples, blend, li[_LI_WORD, l])


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lane_depths(n, t, tri_f, positions, li, n_samples):
    """Depth of triangle t at every lane's samples from its plane equation,
    clamped and rounded to 24 bits, as the integer k of the stored k /
    DEPTH_SCALE (-1 for NaN), into the _LI_Z rows (a vectorised loop)."""
    x0, y0 = tri_f[t, _F_X], tri_f[t, _F_Y]
    z0, dzdx, dzdy = tri_f[t, _F_Z], tri_f[t, _F_DZDX], tri_f[t, _F_DZDY]
    for s in range(n_samples):
        ox, oy = positions[s, 0], positions[s, 1]
        for l in range(n):
            zx = (li[_LI_PX, l] + ox) - x0
            zy = (li[_LI_PY, l] + oy) - y0
            z = z0 + dzdx * zx + dzdy * zy
            k = np.rint(min(max(z, 0.0), 1.0) * DEPTH_SCALE)
            li[_LI_Z + s, l] = np.int32(k if k == k else -1.0)


@numba.njit(cache=True, inline="always")
def _depth_test_lane(mask, li, l, depth, py, px, depth_func, write_z, n_samples):
    """The depth test of lane l's samples in ``mask`` against the integer
    depth buffer, writing the passed depths when write_z; returns the mask of
    passed samples.  No branches on the outcome."""
    p = 0
    for s in range(n_samples):
        k = li[_LI_Z + s, l]
        stored = depth[py, px, s]
        passed = ((mask >> s) & 1 != 0) & _depth_pass_k(depth_func, k, stored)
        depth[py, px, s] = k if passed & write_z else stored
        p |= np.int64(passed) << s
    return p


@numba.njit(cache=True, inline="always")
def _depth_pass_k(func, k, stored):
    """`ops._depth_pass` on depths held as their 24-bit integers k (the
    depth is k / DEPTH_SCALE, a strictly increasing map, so every comparison
    agrees) and -1 for NaN, which compares as NaN does: unequal to all,
    neither less nor greater."""
    ordered = (k >= 0) & (stored >= 0)
    if func == 0 or func == 8:
        return True
    if func == 1:
        return False
    if func == 2:
        return ordered & (k < stored)
    if func == 3:
        return ordered & (k == stored)
    if func == 4:
        return ordered & (k <= stored)
    if func == 5:
        return ordered & (k > stored)
    if func == 6:
        return (not ordered) | (k != stored)
    return ordered & (k >= stored)


@numba.njit(cache=True, inline="always")
def _write_word(color32, py, px, p, n_samples, blend, word):
    """Store (blend == 0: one 32-bit store per sample) or blend (`ops.blend_byte`
    per channel, as `ops.blend_unorm8`) the fragment's RGBA8 word (R in the
    low byte) into the samples of pixel (px, py) set in mask p."""
    alpha = (word >> 24) & 255
    for s in range(n_samples):
        if not (p >> s) & 1:
            continue
        if blend == 0:
            color32[py, px, s] = np.uint32(word)
        else:
            color32[py, px, s] = np.uint32(_blend_word(blend, word, np.int64(color32[py, px, s]), alpha))


@numba.njit(cache=True, inline="always")
def _blend_word(blend, word, stored, alpha):
    """`ops.blend_byte` on each channel of the RGBA8 words (fragment ``word``
    with alpha byte ``alpha`` over ``stored``).  "over", "over_straight" and
    "add" run on the four spread lanes at once (`_mul_lanes`, then a
    saturating add: every lane sum stays below 2^9); the other equations
    per channel."""
    if blend == 1 or blend == 2 or blend == 3:
        src, dst = _spread(word), _spread(stored)
        if blend == 1:
            total = src + _mul_lanes(dst, 255 - alpha)
        elif blend == 2:
            total = _mul_lanes(src, alpha) + _mul_lanes(dst, 255 - alpha)
        else:
            total = src + dst
        carry = (total >> np.uint64(8)) & _ONE_LANES          # lanes over 255
        total = (total | (carry * np.uint64(255))) & _LANES
        return _unspread(total)
    blended = 0
    for c in range(4):
        blended |= blend_byte(blend, (word >> (8 * c)) & 255, (stored >> (8 * c)) & 255, alpha) << (8 * c)
    return blended


@numba.njit(cache=True, inline="always")
def _mul_lanes(x, factor):
    """`ops.mul_unorm8` of each spread lane of x by one factor byte:
    t = x f, (t + (t >> 8) + 0x80) >> 8 per lane (t < 2^16 per lane, and
    so is the sum: no carry between lanes)."""
    t = x * np.uint64(factor)
    return ((t + ((t >> np.uint64(8)) & _LANES) + _HALF_LANES) >> np.uint64(8)) & _LANES


@numba.njit(cache=True, inline="always")
def _wrap_select(i, size, mode):
    """`wrap_index` for a power-of-two size (or clamp_to_edge, any size)
    without branches, so that a loop over lanes vectorises."""
    repeat = i & (size - 1)
    clamped = min(max(i, 0), size - 1)
    m = i & (2 * size - 1)
    mirrored = m if m < size else 2 * size - 1 - m
    return clamped if mode == 1 else (repeat if mode == 0 else mirrored)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _textured_block(n, t, tri_f, colors, uv, positions, depth, color32, depth_func, write_z, blend,
                    plain, tex, buffers, n_samples):
    """Shade the n lanes (n / 4 quads, listed by `_tile` with pixel, centre and
    coverage) of one textured triangle in one 8x8 block.

    Per quad the top-left, top-right and bottom-left lanes give the texture
    derivatives (`interpolate.quad_derivatives`) and the level of detail is
    the quad's; every lane's own (s, t) is its pixel's.  Lanes outside the
    triangle are the quad's helper pixels: computed, never written.  With
    ``plain`` (`plain_colors`) at one sample the filtered texel's bytes are
    the fragment's colour word."""
    tex_params, texels, texels32, table = tex
    texel, lf, li, lu = buffers[0], buffers[1], buffers[2], buffers[3]
    wrap_s, wrap_t = tex_params[_T_WS], tex_params[_T_WT]
    fixed8 = tex_params[_T_FIXED] != 0
    vectorised = tex_params[_T_VEC] != 0          # `_lanes_bilinear_fixed`, else `_sample_lane`
    _lane_weights(n, t, tri_f, lf, uv, True)               # weights and (s, t), vectorised
    _lane_depths(n, t, tri_f, positions, li, n_samples)          # (vectorised)
    # The level of detail of every quad (one loop over the quads, before the
    # depth test), kept on the quad's first lane.
    width0, height0, last = table[0, 1], table[0, 2], tex_params[_T_LEVELS] - 1
    mip, mag_filter, min_filter = tex_params[_T_MIP], tex_params[_T_MAG], tex_params[_T_MIN]
    any_two = False                               # a quad samples two levels
    for q in range(n >> 2):
        l = 4 * q
        s_tl, t_tl = np.float32(lf[_LF_S, l]), np.float32(lf[_LF_T, l])
        level0, level1, frac, image_filter, two = _quad_lod(
            width0, height0, mip, last, mag_filter, min_filter,
            np.float32(lf[_LF_S, l + 1]) - s_tl, np.float32(lf[_LF_T, l + 1]) - t_tl,
            np.float32(lf[_LF_S, l + 2]) - s_tl, np.float32(lf[_LF_T, l + 2]) - t_tl)
        li[_LI_LEVEL, l] = level0
        li[_LI_LEVEL + 1, l] = level1
        li[_LI_IMGF, l] = image_filter
        li[_LI_TWO, l] = two
        lf[_LF_FRAC, l] = frac
        any_two |= two
    # Depth test (scalar); a quad without a passed sample samples level 0 alone.
    block_passed = 0
    block_two = False                             # a passed quad samples two levels
    for q in range(n >> 2):
        quad_passed = 0
        for l in range(4 * q, 4 * q + 4):
            p = _depth_test_lane(li[_LI_COV, l], li, l, depth, li[_LI_PY, l], li[_LI_PX, l], depth_func,
                                 write_z, n_samples)
            li[_LI_PASS, l] = p
            quad_passed |= p
        block_passed |= quad_passed
        l = 4 * q
        level0, level1 = li[_LI_LEVEL, l], li[_LI_LEVEL + 1, l]
        image_filter, two, frac = li[_LI_IMGF, l], li[_LI_TWO, l] != 0, lf[_LF_FRAC, l]
        if not quad_passed:
            level0 = level1 = 0
            image_filter = mag_filter
            two = False
            frac = 0.0
        w8 = np.int64(np.floor(frac * 256)) if two else 0
        block_two |= two
        # The quad's levels on its lanes: what each sampler reads.
        if vectorised:
            for lv in range(2 if any_two else 1):     # (the second level's rows only where read)
                level = level1 if (lv == 1 and two) else level0
                lw, lh, base = table[level, 1], table[level, 2], table[level, 0] >> 2
                scale_s, scale_t = np.float32(lw * 256), np.float32(lh * 256)
                for l in range(4 * q, 4 * q + 4):
                    li[_LI_BASE + lv, l] = base
                    li[_LI_LW + lv, l] = lw
                    li[_LI_LH + lv, l] = lh
                    lf[_LF_SCALE + 2 * lv, l] = scale_s
                    lf[_LF_SCALE + 2 * lv + 1, l] = scale_t
        for l in range(4 * q, 4 * q + 4):
            li[_LI_W8, l] = w8
            if not vectorised:
                li[_LI_LEVEL, l] = level0
                li[_LI_LEVEL + 1, l] = level1
                li[_LI_IMGF, l] = image_filter
                li[_LI_TWO, l] = two
                lf[_LF_FRAC, l] = frac
    if block_passed == 0:
        return
    words = plain and n_samples == 1 and vectorised     # texels straight into _LI_WORD
    if vectorised:
        if block_two:
            _lanes_bilinear_fixed(n, 2, words, lf, li, lu, texels32, wrap_s, wrap_t)
        else:
            _lanes_bilinear_fixed(n, 1, words, lf, li, lu, texels32, wrap_s, wrap_t)
    else:
        for l in range(n):
            if li[_LI_PASS, l]:
                _sample_lane(l, lf, li, texels, texels32, table, texel, wrap_s, wrap_t, fixed8)
    # The fragment colour as llvmpipe's bytes, blended and written (`ops.apply_fragments`).
    if not words:
        _lane_words(n, t, colors, lf, li, True)
    _write_lanes(n, li, color32, blend, n_samples)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _lanes_bilinear_fixed(n, n_levels, words, lf, li, lu, texels32, wrap_s, wrap_t):
    """`texture.sample` (gl, fixed8, linear image filter, power-of-two or
    clamped wraps) of every lane on its first level or (n_levels 2) its two
    levels (the same level twice with mip weight 0 where the quad uses one):
    addresses and 8.8 weights (`_linear_fixed`, vectorised), the 4 or 8 texel
    fetches (scalar), the lane lerps (vectorised).  Writes the texel as k/255
    floats into the _LF_TEX rows, or with ``words`` as its RGBA8 word into
    the _LI_WORD row."""
    for lv in range(n_levels):
        for l in range(n):
            lw, lh = li[_LI_LW + lv, l], li[_LI_LH + lv, l]
            scale_s, scale_t = np.float32(lf[_LF_SCALE + 2 * lv, l]), np.float32(lf[_LF_SCALE + 2 * lv + 1, l])
            fs = np.int64(np.rint(np.float32(np.float32(lf[_LF_S, l]) * scale_s))) - 128
            ft = np.int64(np.rint(np.float32(np.float32(lf[_LF_T, l]) * scale_t))) - 128
            li[_LI_FRAC8 + 2 * lv, l] = fs & 255
            li[_LI_FRAC8 + 2 * lv + 1, l] = ft & 255
            i0 = _wrap_select(fs >> 8, lw, wrap_s)
            i1 = _wrap_select((fs >> 8) + 1, lw, wrap_s)
            row0 = li[_LI_BASE + lv, l] + _wrap_select(ft >> 8, lh, wrap_t) * lw
            row1 = li[_LI_BASE + lv, l] + _wrap_select((ft >> 8) + 1, lh, wrap_t) * lw
            li[_LI_ADDR + 4 * lv, l] = row0 + i0
            li[_LI_ADDR + 4 * lv + 1, l] = row0 + i1
            li[_LI_ADDR + 4 * lv + 2, l] = row1 + i0
            li[_LI_ADDR + 4 * lv + 3, l] = row1 + i1
    for a in range(4 * n_levels):
        for l in range(n):
            lu[a, l] = _spread(texels32[li[_LI_ADDR + a, l]])
    if n_levels == 2:
        for l in range(n):
            fa0, fb0 = li[_LI_FRAC8, l], li[_LI_FRAC8 + 1, l]
            fa1, fb1 = li[_LI_FRAC8 + 2, l], li[_LI_FRAC8 + 3, l]
            x = _bilerp_lanes(fa0, fb0, lu[0, l], lu[1, l], lu[2, l], lu[3, l])
            y = _bilerp_lanes(fa1, fb1, lu[4, l], lu[5, l], lu[6, l], lu[7, l])
            lu[0, l] = _lerp_lanes(li[_LI_W8, l], x, y)
    else:
        for l in range(n):
            fa0, fb0 = li[_LI_FRAC8, l], li[_LI_FRAC8 + 1, l]
            lu[0, l] = _bilerp_lanes(fa0, fb0, lu[0, l], lu[1, l], lu[2, l], lu[3, l])
    # (Separate loops: one loop with a branch on ``words`` compiles to both
    # sides computed and masked stores.)
    if words:
        for l in range(n):
            li[_LI_WORD, l] = _unspread(lu[0, l])
    else:
        for l in range(n):
            for c in range(4):
                lf[_LF_TEX + c, l] = np.float64(_lane(lu[0, l], c)) / 255.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _sample_lane(l, lf, li, texels, texels32, table, texel, wrap_s, wrap_t, fixed8):
    """`texture.sample` (gl precision) of lane l on its quad's level(s), any
    filter and wrap (the scalar path beside `_lanes_bilinear_fixed`)."""
    s_px, t_px = lf[_LF_S, l], lf[_LF_T, l]
    image_filter = li[_LI_IMGF, l]
    two = li[_LI_TWO, l] != 0
    frac = lf[_LF_FRAC, l]
    n_levels = 2 if two else 1
    lanes = fixed8 or (image_filter == 0 and not two)
    lanes_texel = np.uint64(0)
    x = np.uint64(0)
    for lv in range(n_levels):
        level = li[_LI_LEVEL + lv, l]
        base, lw, lh = table[level, 0], table[level, 1], table[level, 2]
        if image_filter == 0:
            i = _nearest(s_px, lw, wrap_s)
            jj = _nearest(t_px, lh, wrap_t)
            if lanes:
                x = _spread(texels32[(base >> 2) + jj * lw + i])
            else:
                for c in range(4):
                    texel[lv, c] = np.float64(texels[base + (jj * lw + i) * 4 + c])
        elif lanes:
            i0, i1, fa = _linear_fixed(s_px, lw, wrap_s)
            j0, j1, fb = _linear_fixed(t_px, lh, wrap_t)
            row0 = (base >> 2) + j0 * lw
            row1 = (base >> 2) + j1 * lw
            x = _bilerp_lanes(fa, fb, _spread(texels32[row0 + i0]), _spread(texels32[row0 + i1]),
                              _spread(texels32[row1 + i0]), _spread(texels32[row1 + i1]))
        else:
            i0, i1, fa = _linear_float(s_px, lw, wrap_s)
            j0, j1, fb = _linear_float(t_px, lh, wrap_t)
            for c in range(4):
                texel[lv, c] = _bilinear_float(
                    fa, fb, np.float64(texels[base + (j0 * lw + i0) * 4 + c]),
                    np.float64(texels[base + (j0 * lw + i1) * 4 + c]),
                    np.float64(texels[base + (j1 * lw + i0) * 4 + c]),
                    np.float64(texels[base + (j1 * lw + i1) * 4 + c]))
        if lanes:
            lanes_texel = x if lv == 0 else _lerp_lanes(li[_LI_W8, l], lanes_texel, x)
    if lanes:
        for c in range(4):
            lf[_LF_TEX + c, l] = _BYTE_VALUES[_lane(lanes_texel, c)]
    else:
        if two:
            for c in range(4):
                texel[0, c] = texel[0, c] + frac * (texel[1, c] - texel[0, c])
        for c in range(4):
            lf[_LF_TEX + c, l] = texel[0, c] / 255.0


# One compiled tile driver per (samples, textured) variant (`_make_draw_tiles`).
_DRAW_TILES = {(n_samples, textured): _make_draw_tiles(n_samples, textured)
               for n_samples in FAST_SAMPLES for textured in (False, True)}
