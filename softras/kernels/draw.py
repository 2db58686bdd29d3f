"""The gl-precision fast path: one fused, tiled, compiled kernel per draw.

`softras.pipeline.render` is the readable reference: every stage materialises its
output (clipped triangles, set-up triangles, a fragment list, per-fragment
attributes) as numpy arrays.  The kernels compute *the same numbers* (bit for
bit, see tests/test_fastpath.py) for the draws that need only the common
features, without the intermediate buffers.  One module per stage, each
naming the readable function it must equal:

1. vertex: `softras.pipeline.vertex.to_clip` (a compiled float32 loop, per vertex);
2. clip: `softras.pipeline.clip.clip_triangles` (its crossing triangles go through a
   compiled kernel in gl precision, `softras.pipeline.clip.triangle_list_gl`);
3. setup (`softras.kernels.setup`, one pass over the clipped triangles): viewport
   transform with llvmpipe's fused multiply-add, 1/256 snapping, area and
   culling, counter-clockwise corner order, integer edge functions, fill rule,
   pixel bounding box, depth plane, and the attributes at the corners (clip
   weights x source vertex values, in the pipeline's order);
4. binning (`softras.kernels.rasterize._bin`): the visible triangles are
   listed, in draw order, in every 64x64-pixel tile their bounding box touches;
5. the tile driver (here: `_make_draw_tiles`, one per sample count and
   texturing): tiles in parallel (numba prange: a pixel belongs to one tile,
   so tiles never race on the framebuffer); within a tile the triangles in
   draw order; per triangle the 8x8 blocks of its bounding box inside the
   tile with the exact early-out / early-in corner test of
   `softras.pipeline.rasterize` (`softras.kernels.rasterize`); the covered
   pixels listed as "lanes" (`softras.kernels.lanes`) and shaded by loops over
   the lanes that compile to SIMD: depth at each sample (plane equation,
   24-bit rounding) and perspective-correct colour
   (`softras.kernels.interpolate`), texture (`softras.kernels.texture`; here
   `_textured_block`: the block's covered 2x2 quads, with per-quad
   derivatives and level of detail), RGBA8 rounding, then the depth test,
   blend and write (`softras.kernels.ops`).  No fragment list exists.

The framebuffer here is what gl precision stores anyway: colour as RGBA8
bytes and depth as 24-bit integers (`softras.kernels.ops`).

`unsupported(scene, ...)` says why a scene must take the general path (lines,
lit shading, anisotropic textures, alpha-tested materials, other sample
counts or clipping policies...).  ``front_face="cw"`` is drawn here as the
swapped cull mode (`softras.pipeline.setup.window_cull`).  A draw pays
only for what it uses: the texture stage runs only
for a textured draw, blending only with a blend mode (the kernel branches on
per-draw constants outside of the per-pixel work).
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

from softras.kernels.interpolate import _lane_depths, _lane_weights, _lane_words
from softras.kernels.lanes import (_LF_CX, _LF_CY, _LF_FRAC, _LF_SCALE, _LF_S, _LF_T, _LI_BASE, _LI_COV,
                                   _LI_IMGF, _LI_LEVEL, _LI_LH, _LI_LW, _LI_PASS, _LI_PX, _LI_PY, _LI_TWO,
                                   _LI_W8, _LI_Z, _NLF, LANES)
from softras.kernels.ops import _depth_test_lane, _write_lanes, clear
from softras.kernels.rasterize import BLOCK, TILE, _bin, _edge_range, _inside3
from softras.kernels.setup import _I_A, _I_B, _I_INC, _I_VIS, _I_X0, _I_Y0, _NF, _NI, CULL_CODES, _setup
from softras.kernels.texture import (_T_FIXED, _T_LEVELS, _T_MAG, _T_MIN, _T_MIP, _T_VEC, _T_WS, _T_WT,
                                     _NT, FILTER_CODES, MIN_FILTERS, _lanes_bilinear_fixed, _quad_lod,
                                     _sample_lane, texture_tables)
from softras.pipeline import clip as clip_stage
from softras.pipeline import ops, setup, texture, vertex
from softras.pipeline.texture import WRAP_CODES
from softras.scene import Scene, ordered_draws

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
        if getattr(material, "alpha_cutoff", None) is not None:
            return f"{draw.path}: alpha test (alpha_cutoff)"
        if material.texture is not None:
            tex = scene.textures[material.texture]
            if (tex.max_anisotropy > 1 or tex.wrap_s not in WRAP_CODES or tex.wrap_t not in WRAP_CODES
                    or tex.mag_filter not in FILTER_CODES or tex.min_filter not in MIN_FILTERS):
                return f"{draw.path}: texture sampler state"
    return None


def render_samples(scene: Scene, positions: np.ndarray, *, texture_fixed_point: bool = True,
                   reuse: bool = False) -> np.ndarray:
    """`softras.pipeline.render.render_samples` of a scene that `unsupported`
    accepts, at GL's sample positions (S, 2).

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
    """One triangle draw into the byte framebuffer: `softras.pipeline.render._render_pass`'s
    per-draw work for one draw (see the module docstring)."""
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
    cull = CULL_CODES[setup.window_cull(draw.cull, getattr(scene, "front_face", "ccw"))]
    _setup(clip_pos, mesh.indices, source, slot, fan_clip, fan_weights, width, height, cull,
           offsets, tri_f, tri_i, bbox, (base, colors, uvs, uv), n_threads, _scratch)
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
    channel and (w0 + w1 + w2) * k / 255 for alpha
    (`softras.kernels.interpolate._shade_word`; corner
    colours of clipped triangles are sums of clip weights, 1 within a few
    ulp).  At a covered pixel centre the perspective weights are within
    rounding of [0, 1] and sum to 1 within a few ulp, so the value is k/255 within ~1e-15,
    and `softras.pipeline.ops.unorm8` gives back k (the product is within ~1e-13 of the
    integer k, nowhere near a rounding boundary; tests/test_fastpath.py
    checks every k).  The kernel uses it at one sample only, where the
    weights are taken at the covered sample itself."""
    return bool(np.all(base == 1.0))


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


# ----------------------------------------------------------------------------- the tile kernel
#
# See `softras.kernels.lanes` for the lanes the tile kernel lists and shades.


def _make_draw_tiles(n_samples: int, textured: bool):
    """`softras.pipeline.rasterize.rasterize` and the per-fragment stages, tile by tile:
    the parallel tile driver compiled for one sample count (1 or 4,
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
    """`softras.pipeline.ops.apply_fragments` of an untextured triangle's
    fragments (`softras.pipeline.fragment.shade_unlit` colours).
    Depth-test, shade and write the n lanes (covered pixels of one
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
def _textured_block(n, t, tri_f, colors, uv, positions, depth, color32, depth_func, write_z, blend,
                    plain, tex, buffers, n_samples):
    """`softras.pipeline.texture.sample` and `softras.pipeline.ops.apply_fragments`
    of a textured triangle's fragments.
    Shade the n lanes (n / 4 quads, listed by `_tile` with pixel, centre and
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






# One compiled tile driver per (samples, textured) variant (`_make_draw_tiles`).
_DRAW_TILES = {(n_samples, textured): _make_draw_tiles(n_samples, textured)
               for n_samples in FAST_SAMPLES for textured in (False, True)}
