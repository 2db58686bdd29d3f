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
   pixel bounding box, depth plane, and the attributes at the corners (a
   vertex's values, or for a vertex the clipper made the clip weights x
   source vertex values, in the pipeline's order);
4. binning: the visible triangles are listed, in draw order, in every
   64x64-pixel tile their bounding box touches (the set-up's pass lists
   and counts, `softras.kernels.rasterize._fill_bins` fills the tiles;
   1-4 in one compiled call for a small unlit or flat draw,
   `softras.kernels.front_end`);
5. the tile driver (here: `_make_draw_tiles`, one per sample count and
   texturing): tiles in parallel (shares of the tiles on threads,
   `softras.kernels.threads`: a pixel belongs to one tile, so tiles never
   race on the framebuffer), for a batch of set-up draws at once
   (`draw_batch`: one hand-off to the threads, each share drawing its
   tiles of every draw in order); within a tile the triangles in
   draw order; per triangle the 8x8 blocks of its bounding box inside the
   tile with the exact early-out / early-in corner test of
   `softras.pipeline.rasterize` (`softras.kernels.rasterize`); the covered
   pixels listed as "lanes" (`softras.kernels.lanes`) and shaded by loops over
   the lanes that compile to SIMD: depth at each sample (plane equation,
   24-bit rounding) and perspective-correct colour
   (`softras.kernels.interpolate`), texture (`softras.kernels.texture`; here
   `_textured_tile`: each 8x8 block's covered 2x2 quads, with per-quad
   derivatives and level of detail), RGBA8 rounding, then the depth test,
   blend and write (`softras.kernels.ops`).  At 1 or 4 samples an unlit,
   untextured draw without alpha test into RGBA8 (the commonest), and at
   1 sample translucent layers and opaque depth-tested draws into rgba32f
   (`_float_rows`), skip the
   lanes: each row's run of covered pixels is depth-tested, shaded, blended
   and stored where it lies, in one loop LLVM vectorises (`_flat_row`).
   No fragment list exists.

The framebuffer here is what gl precision stores anyway: colour as RGBA8
bytes and depth as 24-bit integers (`softras.kernels.ops`); an rgba32f
framebuffer's colour as the stages' float32 values, its fragment colours
and writes by `softras.kernels.rgba32f`.

Line draws take `softras.kernels.lines` (clipping, set-up, coverage and the
per-fragment work in one compiled kernel, with the line stage's functions,
into the same byte framebuffer).
`unsupported(scene, ...)` says why a scene must take the general path (lit
or textured lines, other precisions or clipping policies...).  Every
shading model is drawn here, at any sample count and positions, with every
texture filter GL has (anisotropic included) and softras's own
(``texture_filter``: `softras.kernels.texture_beyond`), normal and bump maps (on the
textured driver, `softras.kernels.maps._map_normals`) and the alpha test.
Gouraud and flat shading are lit before the tile kernels, by compiled
loops with the stages' operations (`softras.kernels.light.base_colors`,
`face_colors`): Gouraud per vertex
(`softras.pipeline.render.vertex_base_colors`), its lit colours
interpolated as vertex colours are; flat per visible triangle
(`flat_corner_colors`), its colour taken as it is.  Phong shading lights
each covered pixel in the kernel (`softras.kernels.light`), from the corner
world positions and normals that the set-up interpolates like any
attribute.  ``front_face="cw"`` is drawn here as the
swapped cull mode (`softras.pipeline.setup.window_cull`).  A draw pays
only for what it uses: the texture stage runs only
for a textured draw, blending only with a blend mode (the kernel branches on
per-draw constants outside of the per-pixel work).

Why one module of ~1100 lines: the tile drivers (`_make_draw_tiles`), the
tile functions they inline (`_flat_tile`, `_flat_block`, `_textured_tile`;
called, not inlined, they drew 6-18 % slower, docs/speed.md, "Compile
time" and "Twenty-seventh round"), and the Python side that picks a
driver and hands it its arrays are one compiled unit under one cache key.
"""

from __future__ import annotations

import os
from collections import namedtuple

# numba's default OpenMP threading layer leaves its threads spinning after a
# parallel region; on a loaded 2-core machine they steal the core that
# llvmpipe's threads (glref, same process) and other processes need: the 24k
# grid took 24 ms with 2 spinning threads against 12 ms with 1 (docs/speed.md).
# Passive waiting (read by libgomp when numba first starts its threads) keeps
# the second thread's gain on a quiet machine.  An explicit setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numba  # noqa: E402  (after the environment default above)
import numpy as np

from softras.kernels.front_end import _front_end
from softras.kernels.interpolate import (RGBA, _corner_colors, _corners, _lane_alpha_test, _lane_depths,
                                        _lane_weights, _lane_words, _shade_word, _weights_at, plain_colors)
from softras.kernels.lanes import (_LF_CX, _LF_CY, _LF_W, _LI_COV, _LI_PASS, _LI_PX, _LI_PY, _LI_Z, _NLF, LANES,
                                   LaneBuffers, _whole_vectors)
from softras.kernels.lines import draw_lines
from softras.kernels.light import (NO_LIGHTING, _phong_words, base_colors, flat_corner_colors, phong_inputs,
                                   viewing)
from softras.kernels.ops import (LESS, Framebuffer, _blend_word, _clear_fresh, _clear_tile, _depth_pass_k,
                                 _depth_test_lanes, _plane_depth_k, _tiles_out, _uses_depth, _write_lanes,
                                 new_framebuffer)
from softras.kernels.rasterize import (BLOCK, TILE, Bins, _block_test, _edges, _fill_bins, _list_pixels, _list_quads,
                                       _list_row, _list_whole_block, _row_run, _tile_box, _tile_columns)
from softras.kernels.rgba32f import _float_fragments, _row_floats
from softras.kernels.scratch import _Scratch, read_only
from softras.kernels.setup import (_F_DZDX, _F_DZDY, _F_X, _F_Y, _F_Z, _NF, _NI, CULL_CODES, PARALLEL_SETUP, Clipped,
                                   Triangles, _setup, window_buffers)
from softras.kernels.stamp import sources_stamp
from softras.kernels.pool import on_threads
from softras.kernels.threads import NoAliasCompiler, _aligned_stack, _owns, owners_table
from softras.kernels.maps import _map_normals
from softras.kernels.texture import (FILTER_CODES, MIN_FILTERS, NO_TEXTURE, VECTORISED_NEAREST, Sampler, Texels,
                                     _lanes_aniso_levels, _lanes_bilinear_fixed, _lanes_lod, _lanes_nearest_fixed,
                                     _quad_levels, _sample_lane, texture_tables)
from softras.kernels.texture_beyond import _beyond_lane, beyond_tables
from softras.pipeline import clip as clip_stage
from softras.pipeline import libm, ops, sampling, setup, texture, texture_beyond, vertex
from softras.pipeline.rasterize import _sample_box
from softras.pipeline.render import check_sample_memory
from softras.pipeline.texture import WRAP_CODES
from softras.scene import Scene, ordered_draws

# Bytes a sample holds here: RGBA8 colour and a 24-bit depth in an int32
# (the stages hold 32 for the colour alone: 4096^2 at 4x fits here, not
# there); an rgba32f framebuffer's float32 colour and the depth.
SAMPLE_BYTES = 4 + 4
SAMPLE_BYTES_RGBA32F = 16 + 4

# A draw's sample positions: offsets (S, 2) int64 in raster units
# (`softras.pipeline.setup.sample_offsets`, gl), positions (S, 2) float64
# within the pixel, and box (4,) int64 their extremes in raster units
# (`softras.pipeline.rasterize._sample_box`: min x, max x, min y, max y).
Samples = namedtuple("Samples", ["offsets", "positions", "box"])

# A draw's per-fragment operations, as codes: depth function
# (`softras.pipeline.ops.DEPTH_FUNCS`), whether passed depths are written
# (depth_write and a depth test), blend mode (`softras.pipeline.ops.BLEND_MODES`),
# whether the fragment colour is the texel's own (`plain_colors`), whether
# the colour is the triangle's, not interpolated (flat shading,
# `flat_corner_colors`), whether it is lit per fragment (Phong shading,
# `softras.kernels.light._phong_words`), the alpha test (whether, and its
# cutoff: `softras.kernels.interpolate._lane_alpha_test`), whether a texture
# multiplies the colour, the normal or bump map (NO_MAP, NORMAL_MAP or
# BUMP_MAP: `softras.kernels.maps._map_normals`), the bump scale, and
# whether the framebuffer is rgba32f (`softras.kernels.ops.Framebuffer`'s
# color_f: the colours and writes of `softras.kernels.rgba32f`).
DrawState = namedtuple("DrawState", ["depth_func", "write_z", "blend", "plain", "flat", "lit", "alpha_test",
                                     "cutoff", "texture", "mapped", "bump_scale", "rgba32f"])
NO_MAP, NORMAL_MAP, BUMP_MAP = 0, 1, 2


# ----------------------------------------------------------------------------- dispatch


def unsupported(scene: Scene, *, precision: str, clipping: str | None) -> str | None:
    """Why ``scene`` must take the general pipeline, or None when this path
    renders it.  The caller (`softras.renderer.render_scene`) has already
    checked the options this path does not look at (texture bounds, tie
    rule); every ``texture_filter`` is drawn here
    (`softras.kernels.texture_beyond._beyond_lane`), into an RGBA8 or an
    rgba32f framebuffer (`softras.kernels.rgba32f`)."""
    if precision != "gl":
        return "precision is not gl"
    if clipping not in (None, "llvmpipe"):
        return f"clipping {clipping!r}"
    for draw in scene.draws:
        material = draw.material
        if draw.mesh.primitive == "lines":
            if material.line_problems():            # (the stages refuse these; the loader too)
                return f"{draw.path}: lines with {', '.join(material.line_problems())}"
            continue
        for name in filter(None, (material.texture, material.normal_map, material.bump_map)):
            tex = scene.textures[name]
            if (tex.wrap_s not in WRAP_CODES or tex.wrap_t not in WRAP_CODES
                    or tex.mag_filter not in FILTER_CODES or tex.min_filter not in MIN_FILTERS):
                return f"{draw.path}: texture sampler state"
    return None


def textured(material) -> bool:
    """Whether a draw of ``material`` takes a textured tile driver (a texture, normal or bump map: uvs, quads)."""
    return material.texture is not None or material.normal_map is not None or material.bump_map is not None


def render_samples(scene: Scene, positions: np.ndarray, *, texture_fixed_point: bool = True,
                   reuse: bool = False, texture_filter=None, rgba8: bool = True) -> np.ndarray:
    """`softras.pipeline.render.render_samples` of a scene that `unsupported`
    accepts, at any sample positions (S, 2) in [0, 1): in the stages' passes
    of at most `softras.pipeline.sampling.MAX_PASS_SAMPLES` (coverage masks
    in one integer; `softras.pipeline.sampling.sample_passes`).

    Returns the per-sample colour buffer (H, W, S, 4) uint8, GL's y-up rows:
    byte k where the general pipeline stores the float k/255; with rgba8
    False (an rgba32f framebuffer) float32, the stages' values.  reuse: the
    buffer is this thread's scratch colour buffer, overwritten by the next
    call (for a caller that copies it at once; saves the page faults of a
    fresh buffer; one pass only).  texture_filter: None, or one of
    softras's filters for some or all textures
    (`softras.pipeline.texture_beyond.FILTERS`).
    """
    check_sample_memory(scene, len(positions), SAMPLE_BYTES if rgba8 else SAMPLE_BYTES_RGBA32F)

    def render_pass(pass_positions):
        # (A pass of several is copied at once: it may take the scratch buffer.)
        return _render_pass(scene, pass_positions, texture_fixed_point, reuse or len(pass_positions) < len(positions),
                            texture_filter, rgba8)

    return sampling.in_passes(positions, render_pass)


def render_picture(scene: Scene, position: np.ndarray, *, texture_fixed_point: bool = True,
                   texture_filter=None) -> np.ndarray:
    """The picture of a scene that `unsupported` accepts at one sample a pixel
    (position (1, 2) in [0, 1)) into an RGBA8 framebuffer: (H, W, 4) uint8,
    row 0 = the top, the bytes of
    ``softras.pipeline.ops.resolve_llvmpipe_bytes(render_samples(...))``.
    The last batch's shares copy the tiles they drew into it, and the
    background into the tiles no draw reached, without clearing those
    (`softras.kernels.ops._tiles_out`); when the last draw is a line
    draw, the buffer is copied after it, as `render_samples`' is resolved."""
    check_sample_memory(scene, 1, SAMPLE_BYTES)
    return _render_pass(scene, position, texture_fixed_point, True, texture_filter, True, picture=True)


def _render_pass(scene: Scene, positions: np.ndarray, texture_fixed_point: bool, reuse: bool,
                 texture_filter=None, rgba8: bool = True, picture: bool = False) -> np.ndarray:
    """`render_samples` of one pass's positions (S, 2): the
    draws into this pass's framebuffer, (H, W, S, 4) uint8 colour (float32
    unless rgba8); with ``picture`` (one sample, RGBA8) `render_picture`'s
    picture instead.  The framebuffer's tiles are cleared where a draw
    first reaches them (`softras.kernels.ops.Framebuffer`), the others
    before a line draw (which may draw anywhere) and at the end."""
    offsets, _ = setup.sample_offsets(positions, "gl")
    shape = (scene.height, scene.width, len(positions))
    depth = _scratch.take("depth", shape, np.int32)
    dtype = np.uint8 if rgba8 else np.float32
    color = (_scratch.take("color" if rgba8 else "color_f", shape + (4,), dtype) if reuse
             else np.empty(shape + (4,), dtype))
    offsets = np.ascontiguousarray(offsets, np.int64)
    positions = np.ascontiguousarray(positions, np.float64)
    # (The sample box once a pass, in Python: numba's array min and max need
    # its reference counting, which the tile drivers are compiled without.)
    samples = Samples(offsets, positions, np.array(_sample_box.py_func(offsets), np.int64))
    fb = new_framebuffer(color, depth, ops.premultiplied(scene.background))
    draws = ordered_draws(scene)
    # (What every draw of the pass reads: the eye and the lit draws' normal
    # rows, None when unlit, and the camera's P @ V, found once a pass.)
    this_pass = Pass(scene, fb, samples, texture_fixed_point, texture_filter, viewing(scene, draws),
                     scene.camera.projection @ scene.camera.view, not rgba8)
    batch = []                          # set-up triangle draws not yet drawn (`TileWork`)
    batched = 0                         # their mesh triangles
    for draw in draws:
        lines = draw.mesh.primitive == "lines"
        # (Before a line draw, the triangle draws before it.)
        if batch and (lines or len(batch) == MAX_BATCH or batched + len(draw.mesh.indices) > BATCH_TRIANGLES):
            draw_batch(batch)
            batch, batched = [], 0
        if lines:
            _clear_fresh(tuple(fb), not rgba8)
            draw_lines(scene, draw, fb, positions)
            continue
        work = set_up_triangles(this_pass, draw, len(batch))
        if work is not None:
            batch.append(work)
            batched += work.triangles
    if picture and batch:
        out = np.empty((scene.height, scene.width, 4), np.uint8)
        draw_batch(batch, (tuple(fb), out.view(np.uint32).reshape(scene.height, scene.width)))
        return out
    draw_batch(batch)
    _clear_fresh(tuple(fb), not rgba8)
    # (With no triangle draw after the last line draw there is no batch to
    # copy the tiles in, and numpy's copy by rows is the faster on one thread.)
    return ops.resolve_llvmpipe_bytes(color) if picture else color


# What every triangle draw of a pass reads (`set_up_triangles`): the scene,
# the pass's `softras.kernels.ops.Framebuffer` and `Samples`, the texture
# options of `render_samples`, the `softras.kernels.light.Viewing` (None
# when no draw is lit), the camera's projection @ view (4, 4) float64 (the
# first product of `softras.pipeline.vertex.model_view_projection`: the
# same bits), and whether the framebuffer is rgba32f.
Pass = namedtuple("Pass", ["scene", "fb", "samples", "texture_fixed_point", "texture_filter", "view",
                           "camera", "rgba32f"])


# A triangle draw set up and binned, ready for its tile driver: the driver,
# the records it takes (plain tuples, `softras.kernels.setup.Clipped`), the
# sample count of its lanes (`lane_buffers`), the estimated time of drawing
# it on one thread (`draw_work`, ns), and its mesh's triangles
# (`BATCH_TRIANGLES`).
TileWork = namedtuple("TileWork", ["driver", "records", "n_samples", "work", "triangles"])

# At most this many triangle draws are set up before they are drawn, and
# no more mesh triangles than BATCH_TRIANGLES unless one draw has more
# (it is then drawn alone): each draw holds its own set-up buffers
# (`set_up_triangles`' slot, ~500 bytes a triangle) until then.  The
# batches are for the small draws, whose hand-off to the threads costs as
# much as drawing them; a large draw gains nothing from sharing one.
# (32 since the forty-fifth round: with the tiles taken as the shares reach
# them, parts_64x128_512 drew 0.97x and textured_parts 0.93-0.98x their
# time in batches of 16; 64 was no faster, docs/speed.md.)
MAX_BATCH = 32
BATCH_TRIANGLES = 8192


def draw_batch(batch: list, picture: tuple | None = None) -> None:
    """Draw the set-up triangle draws of ``batch`` (`TileWork`) in order, with
    one hand-off to the threads for all of them: each share draws the
    draws in turn, each in the tiles it owns, taking any tile nobody has
    taken yet (`tile_owners`, `softras.kernels.threads._owns`), so a
    share that starts late or draws slower takes fewer.  A tile belongs to
    one share for the whole batch, so its pixels see the draws in order on
    one thread: the bytes of drawing them one by one.

    picture: for a pass's last batch, (the `Framebuffer` as a tuple, the
    picture (H, W) uint32): then each share, its draws drawn,
    copies the tiles it owns or takes into the picture
    (`softras.kernels.ops._tiles_out`)."""
    if not batch:
        return
    extra = 0.0 if picture is None else OUT_PIXEL_NS * picture[1].size
    n_shares = shares(batch, numba.get_num_threads(), extra)
    owners = tile_owners(batch, n_shares)

    def share(r):
        # One share's lanes for the whole batch (one pass: one sample count),
        # carried from draw to draw as from block to block within a draw:
        # the drivers write every lane they read (tests/test_threads.py
        # draws with lanes full of junk).
        lanes = lane_buffers(batch[0].n_samples)
        for work in batch:
            work.driver(*work.records, lanes, r, owners)
        if picture is not None:
            fb, out = picture
            _tiles_out(fb, r, owners, out)

    on_threads(share, n_shares)


def tile_owners(batch: list, n_shares: int) -> np.ndarray:
    """The table the shares of a batch take its tiles in
    (`softras.kernels.threads.owners_table`)."""
    bin_start = batch[0].records[0][0]          # (tiles + 1 entries; every draw of a pass has the same tiles)
    return owners_table(len(bin_start) - 1, n_shares)


def set_up_triangles(this_pass: Pass, draw, slot: int = 0) -> TileWork | None:
    """`softras.pipeline.render.draw_triangles` in gl precision (see the
    module docstring) up to the tile driver, for one triangle draw of the
    `Pass`: the draw's vertices, clipping, set-up and binning, into set-up
    buffers for ``slot`` (the draw's place in its batch, `draw_batch`):
    this thread's reused ones for the first, fresh ones for the others
    (fewer than BATCH_TRIANGLES triangles in all; reused buffers for each
    slot would keep the largest draw ever batched there for the life of
    the process).  An unlit or flat draw of fewer than PARALLEL_SETUP
    mesh triangles takes the four in one compiled call
    (`softras.kernels.front_end`), the others one call each, the set-up in
    a share a thread from PARALLEL_SETUP clipped triangles (`_setup`).
    None when no triangle is visible."""
    scene, samples, view = this_pass.scene, this_pass.samples, this_pass.view
    mesh, material = draw.mesh, draw.material
    mvp = this_pass.camera @ draw.world                     # (P @ V @ M: model_view_projection's bits)
    indices = read_only(mesh.indices, np.int64)             # (one compiled type: `read_only`)
    is_textured = textured(material)
    lit = material.shading == "phong"
    take = _scratch.take if slot == 0 else _fresh           # (slot 0: this thread's reused buffers)
    cull = CULL_CODES[setup.window_cull(draw.cull, scene.front_face)]
    tiles_x, tiles_y = (scene.width + TILE - 1) // TILE, (scene.height + TILE - 1) // TILE
    if len(indices) < PARALLEL_SETUP and material.shading in ("unlit", "flat"):
        # (Vertex values before clipping here: they need no lighting.)
        base, uvs, world_normals, lights, lighting = _vertex_inputs(scene, draw, view, is_textured, lit, take)
        rows = len(indices)
        while True:
            tris = _triangle_buffers(take, rows, is_textured, world_normals)
            n, source, visible, bin_start, bin_tri, pixels = _front_end(
                read_only(mesh.positions, np.float32), mvp.astype(np.float32), indices, scene.width,
                scene.height, cull, samples.box, (base, uvs, world_normals), tuple(tris),
                window_buffers(_scratch, len(mesh.positions)), tiles_x, tiles_y)
            if n <= rows:
                break
            rows = n                                        # (clipping made fans: room for them)
    else:
        clip_pos = vertex.to_clip(mesh.positions, mvp, "gl")
        clipped = Clipped(indices, *clip_stage.triangle_list_gl(clip_pos, indices))
        if len(clipped.source) == 0:
            return None
        base, uvs, world_normals, lights, lighting = _vertex_inputs(scene, draw, view, is_textured, lit, take,
                                                                    3 * len(clipped.fan_weights))
        tris = _triangle_buffers(take, len(clipped.source), is_textured, world_normals)
        visible, bin_start, bin_tri, pixels = _set_up_and_bin(
            clip_pos, clipped, scene, cull, samples.box, (base, uvs, world_normals), tris, take, tiles_x,
            tiles_y)
        source = clipped.source
    if len(visible) == 0:
        return None
    flat = material.shading == "flat"
    if flat:                # (only the visible triangles are binned: the others' colours are never read)
        tris.colors[visible] = flat_corner_colors(scene, draw, base, source[visible], view)
    mapped = NORMAL_MAP if material.normal_map is not None else BUMP_MAP if material.bump_map is not None else NO_MAP
    map_name = material.normal_map if material.normal_map is not None else material.bump_map
    sampler, texels = NO_TEXTURE
    if material.texture is not None:
        tex = texture.prepare(scene.textures[material.texture])
        beyond = texture_beyond.filter_for(this_pass.texture_filter, tex.name)
        sampler, texels = (beyond_tables(tex, beyond) if beyond is not None
                           else texture_tables(tex, this_pass.texture_fixed_point))
    map_sampler, map_texels = (texture_tables(texture.prepare(scene.textures[map_name]), this_pass.texture_fixed_point)
                               if map_name is not None else NO_TEXTURE)
    depth_func = ops.DEPTH_FUNCS[draw.depth_test]
    cutoff = material.alpha_cutoff
    rgba32f = this_pass.rgba32f
    state = DrawState(depth_func, bool(draw.depth_write) and depth_func != 0, ops.BLEND_MODES[draw.blend],
                      bool(material.texture is not None and not flat and not lit and cutoff is None
                           and not rgba32f and plain_colors(base)), flat, lit,
                      cutoff is not None, float(cutoff or 0.0), material.texture is not None, mapped,
                      float(material.bump_scale), rgba32f)
    n_samples = len(samples.offsets)
    draw_tiles = _DRAW_TILES[driver_samples(n_samples, is_textured), is_textured]
    # (The records as plain tuples: see `softras.kernels.setup.Clipped`.)
    records = ((bin_start, bin_tri, tiles_x), tuple(tris), tuple(samples), tuple(this_pass.fb),
               tuple(state), tuple(sampler), tuple(texels), tuple(map_sampler), tuple(map_texels), lights,
               tuple(lighting))
    work = draw_work(len(bin_tri), pixels, is_textured or lit, n_samples)
    return TileWork(draw_tiles, records, n_samples, work, len(mesh.indices))


def _set_up_and_bin(clip_pos, clipped, scene, cull, box, vertex_values, tris, take, tiles_x: int,
                    tiles_y: int) -> tuple:
    """`_setup` of the clipped triangles into tris, and their binning:
    (visible (K,), bin_start (tiles + 1,), bin_tri (N,), pixels) (`Bins`;
    pixels: the visible boxes' area).  Each set-up share lists the
    triangles it keeps and counts their tiles as it sets them up
    (`softras.kernels.setup._setup_range`); the lists joined in share order
    are the draw order, and `_fill_bins` fills the tiles from the counts
    summed."""
    listed = take("listed", (len(clipped.source),), np.int64)
    found, counts = _setup(clip_pos, clipped, scene.width, scene.height, cull, box, vertex_values, tris, _scratch,
                           (listed, tiles_x, tiles_y))
    runs = [listed[start:start + k] for start, k, _ in found]
    visible = runs[0] if len(runs) == 1 else np.concatenate(runs)
    bin_start, bin_tri = _fill_bins(visible, tris.bbox, tiles_x, counts)
    return visible, bin_start, bin_tri, int(found[:, 2].sum())


def _vertex_inputs(scene: Scene, draw, view, is_textured: bool, lit: bool, take, fan_rows: int = 0) -> tuple:
    """A triangle draw's per-vertex inputs: straight base colours (V, 4)
    (`base_colors`: lit by Gouraud), uvs rounded to float32 (V, 2) or
    NO_UVS, in this thread's reused buffers (the set-up copies them to the
    corners, and each draw's set-up is done before the next); and for
    Phong shading the world positions and normals with fan_rows rows more
    for the corners the clipper makes (the drivers read them by row:
    from the draw's ``take``, as its set-up tables), light table and
    `Lighting` (`phong_inputs`), else NO_LIGHTING."""
    mesh = draw.mesh
    base = base_colors(scene, draw, _scratch.take, view)
    uvs = NO_UVS
    if is_textured:
        uvs = _scratch.take("uvs", mesh.uvs.shape, np.float64)
        uvs[:] = mesh.uvs.astype(np.float32)
    world_normals, lights, lighting = phong_inputs(scene, draw, take, view, fan_rows) if lit else NO_LIGHTING
    return base, uvs, world_normals, lights, lighting


def _triangle_buffers(take, rows: int, is_textured: bool, lit: np.ndarray) -> Triangles:
    """`Triangles` for ``rows`` set-up triangles from ``take(name, shape,
    dtype)``: the corner uvs and the rows of the lit attributes ``lit``
    (`phong_inputs`', or NO_LIGHTING's (0, 6) when unlit) only when the
    draw reads them, else one unused row."""
    return Triangles(take("tri_f", (rows, _NF), np.float64), take("tri_i", (rows, _NI), np.int64),
                     take("bbox", (rows, 4), np.int64), take("colors", (rows, 3, 4), np.float64),
                     take("uv", (rows if is_textured else 1, 3, 2), np.float64), lit,
                     take("lit_rows", (rows if len(lit) else 1, 3), np.int64))


def _fresh(name: str, shape: tuple, dtype) -> np.ndarray:
    """A new array (the ``take`` of a batch's later draws, `set_up_triangles`)."""
    return np.empty(shape, dtype)


# An untextured draw's vertex uvs (`_setup`'s vertex_values).
NO_UVS = np.zeros((0, 2))


# A draw's work as `draw_work` estimates it, in ns on one thread: per
# (triangle, tile) pair that binning lists (each tile sets up the triangle's
# edges and walks its box there) and per pixel of the visible triangles'
# boxes, four times that for a draw that textures or Phong-lights each pixel,
# twice that at more than one sample.  Against the bench scenes' one-thread
# draws it gives 0.6-1.7x their time, bump_mapped_8k_512's 0.23x (four
# more texture taps a pixel) (docs/speed.md, "Forty-third round"): it only
# has to tell a batch worth two threads from one that is not.
BINNED_NS = 100
BOX_PIXEL_NS = 0.75

# What handing a batch's shares to the threads costs, ns: the hand-off and
# wait (~50 us here, `softras.kernels.threads`), and per draw of the batch
# a trade of the GIL between the threads (each share calls the driver from
# Python, one draw after another).  With fixed shares that was ~15 us a
# draw on parts_64x128_512, whose batches of 16 draws took 0.38 ms on one
# thread and 0.30 or 0.55 ms on two; with the tiles taken as the shares
# reach them (`softras.kernels.threads._owns`) its renders on two took
# 0.88-0.91x their time on one, ~3 us a draw (docs/speed.md, "Forty-fifth
# round").
HAND_OFF_NS = 50_000
HAND_OFF_NS_PER_DRAW = 3_000

# The picture's copy by tiles (`softras.kernels.ops._tiles_out`), ns a
# pixel on one thread: 0.28 ms at 1024^2 (docs/speed.md, "Fiftieth round").
OUT_PIXEL_NS = 0.27


def draw_work(binned: int, box_pixels: int, heavy: bool, n_samples: int) -> float:
    """The estimated ns of drawing a set-up draw on one thread: ``binned``
    (triangle, tile) pairs and ``box_pixels`` pixels of its visible
    triangles' boxes (`_set_up_and_bin`), ``heavy`` when it is textured or
    Phong-lit, at n_samples samples (`BINNED_NS`)."""
    return (BINNED_NS * binned + BOX_PIXEL_NS * box_pixels) * (4 if heavy else 1) * (2 if n_samples > 1 else 1)


def shares(batch: list, n_threads: int, extra: float = 0.0) -> int:
    """How many threads draw a batch of `TileWork`: n_threads where a share of
    the estimated work (`draw_work`, and ``extra`` ns: the picture's copy)
    takes longer than handing a share over (`HAND_OFF_NS`), else one."""
    total = sum(work.work for work in batch) + extra
    return n_threads if total / n_threads > HAND_OFF_NS + HAND_OFF_NS_PER_DRAW * len(batch) else 1


def lane_buffers(n_samples: int) -> LaneBuffers:
    """A share's `LaneBuffers` for a batch of draws of n_samples samples a
    pixel (`softras.kernels.lanes`), zeroed."""
    return LaneBuffers(np.zeros((_NLF, 2 * LANES)), np.zeros((_LI_Z + n_samples, 2 * LANES), np.int64),
                       np.zeros((8, 2 * LANES), np.uint64), np.empty((2, 4)), np.zeros((3, n_samples), np.int64))


_scratch = _Scratch()


def scratch_nbytes() -> int:
    """Bytes held by this thread's reused fast-path buffers (for memory reports)."""
    return sum(buffer.nbytes for buffer in _scratch.buffers.values())


# ----------------------------------------------------------------------------- the tile kernel
#
# See `softras.kernels.lanes` for the lanes the tile kernel lists and shades.


# The tile drivers' sample counts (`driver_samples`): GL's 1 and 4, unrolled
# (4 draws the 24k grid 14-16 % faster so, docs/speed.md), and ANY_SAMPLES,
# any other count of a pass, read at run time.  Textured draws have no
# driver of their own for 4: at 4 samples the driver of any count draws
# them 4-7 % slower, and a fresh clone compiles 66 s less (docs/speed.md,
# "Twenty-fourth round").
ANY_SAMPLES = 0
DRIVER_SAMPLES = {False: (1, 4, ANY_SAMPLES), True: (1, ANY_SAMPLES)}      # untextured, textured

# A row's run of more than this many pixels, drawn at one sample by the
# row loops' copy for any state with a depth test that can fail, has its
# two end pixels tested first; when one fails, only the run between the
# first and last passing pixel is shaded (`_flat_row`, `_passing_run`).
# The layers of a transparent pass partly behind an opaque grid
# (transparent_8x128_512) took ~20 % less time, layers hiding one another
# ~30-45 % less, and unhidden layers 0-7 % more; shorter runs (small
# triangles) are shaded whole, their ends untested (docs/speed.md,
# "Fifty-third round").
TRIMMED_RUN = 16


def driver_samples(samples: int, is_textured: bool) -> int:
    """The tile driver that draws ``samples`` samples a pixel, untextured
    (1, 4 or ANY_SAMPLES) or textured (1 or ANY_SAMPLES): `DRIVER_SAMPLES`."""
    return samples if samples in DRIVER_SAMPLES[is_textured] else ANY_SAMPLES


def _make_draw_tiles(n_samples: int, textured: bool, sources: str):
    """`softras.pipeline.rasterize.rasterize` and the per-fragment stages, tile by tile:
    the tile driver (one share of it, `softras.kernels.pool.on_threads`)
    compiled for one sample count (`DRIVER_SAMPLES`:
    1, 4 (untextured), or ANY_SAMPLES for the count of the draw's sample
    table) and textured or not, as constants (closure variables are compile-time constants to
    numba, and part of its cache key): the compiler unrolls the per-sample
    loops of 1 and 4 and drops the texture code from untextured draws, and a
    scene compiles only the variants it uses.  sources : `softras.kernels.stamp.sources_stamp`,
    in the cache key only."""

    # Whether untextured rows may be shaded where they lie (`_flat_row`):
    # a constant, so that the driver of any count does not compile them.
    row_runs = n_samples == 1 or n_samples == 4

    # Compiled as numba compiled it in the body of a parallel loop (the
    # driver was one until the thirty-third round): with ``noalias`` on its
    # arrays (`softras.kernels.threads.NoAliasCompiler`) and without
    # reference counting (``_nrt=False``).  It has nothing to free (the
    # lanes come from `lane_buffers`), and counting the references to
    # arrays taken out of records and handed to inlined functions cost the
    # 24k grid ~7 % of its time in NRT_incref and NRT_decref.
    @numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False, pipeline_class=NoAliasCompiler)
    def draw_tiles(bins, tris, samples, fb, state, sampler, tex, map_sampler, map_tex, lights, lighting, lanes,
                   r, owners):
        """`softras.pipeline.render.draw_triangles` for one triangle draw after its
        set-up, share r of its batch (`softras.kernels.pool.on_threads`):
        rasterize, shade and apply every binned triangle (`Bins` of the
        set-up `Triangles`) in the tiles the share owns or takes (owners:
        the batch's tile owners, `softras.kernels.threads._owns`) at the
        `Samples`, into the `Framebuffer` fb with the `DrawState`, the
        texture's `Sampler` and `Texels` tex, the normal or bump map's
        (map_sampler, map_tex), and for Phong shading the light table and
        `Lighting` (`softras.kernels.light`), with this share's own
        `LaneBuffers` lanes.  The records come as plain tuples
        (`softras.kernels.setup.Clipped`) and are named again here.
        """
        stamp = sources                 # noqa: F841  (a closure variable: the cache key, `softras.kernels.stamp`)
        _aligned_stack()                # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
        n_tiles = bins[0].shape[0] - 1
        count = n_samples if n_samples != ANY_SAMPLES else samples[0].shape[0]
        # (One statement each: a tuple of records, built and unpacked,
        # trips numba's array analysis, see `softras.kernels.rasterize.Edges`.)
        bins_r = Bins(*bins)
        tris_r = Triangles(*tris)
        samples_r = Samples(*samples)
        fb_r = Framebuffer(*fb)
        state_r = DrawState(*state)
        sampler_r = Sampler(*sampler)
        tex_r = Texels(*tex)
        map_sampler_r = Sampler(*map_sampler)
        map_r = Texels(*map_tex)
        lanes_r = LaneBuffers(*lanes)
        for tile in range(n_tiles):
            if bins_r.start[tile] == bins_r.start[tile + 1] or not _owns(owners, tile, r):
                continue                # (no triangle there, nor the tile functions' set-up; or another share's)
            if fb_r.fresh[tile]:        # (the pass's first draw here: `softras.kernels.ops.Framebuffer`)
                _clear_tile(tile, fb_r.color32, fb_r.depth, fb_r.color_f, fb_r.clear_word, fb_r.clear_f,
                            state_r.rgba32f)
                fb_r.fresh[tile] = 0
            if textured and n_samples == 1:
                _textured_tile(tile, bins_r, tris_r, samples_r, fb_r, state_r, sampler_r, tex_r, map_sampler_r,
                               map_r, lights, lighting, lanes_r, n_samples)
            elif textured:
                _textured_tile_called(tile, bins_r, tris_r, samples_r, fb_r, state_r, sampler_r, tex_r,
                                      map_sampler_r, map_r, lights, lighting, lanes_r, n_samples)
            else:
                _flat_tile(tile, bins_r, tris_r, samples_r, fb_r, state_r, lights, lighting, lanes_r,
                           count, row_runs)

    return draw_tiles


# What the tile code costs to compile (docs/speed.md, "Compile time",
# "Twenty-seventh round" and "Thirty-third round").  The tile functions are
# inlined into the driver where that pays.  As a separate function (then
# in a numba parallel loop) `_flat_tile` drew the 24k grid 10-18 %
# slower, and `_textured_tile` textured_phong_8k_1024 6-15 % slower with
# two threads (the floor 6-12 % in most rounds, the bump map 1-13 %).  A
# driver inlines only the tile function its ``textured`` constant selects.
# The driver of any sample count calls the texture code instead
# (`_textured_tile_called`): inlined there it took ~40 s more to compile,
# for the rarer draws.  Until the twenty-seventh round every textured
# driver called it, because numba's inliner copied a callee's whole
# variable table once per block (`softras.pipeline.numba_fixes`), which
# made inlining it cost tens of seconds per variant.


@numba.njit(error_model="numpy", inline="always")
def _flat_tile(tile, bins, tris, samples, fb, state, lights, lighting, lanes, n_samples, row_runs):
    """One 64x64 tile of an untextured draw: its triangles in draw order; per
    triangle the 8x8 blocks of its bounding box inside the tile with the
    exact early-out / early-in corner test of
    `softras.pipeline.rasterize._raster_triangle`
    (`softras.kernels.rasterize._block_test`), or at one sample a pixel the
    box's rows, each row's run of covered pixels
    (`softras.kernels.rasterize._list_row`); the covered pixels listed as
    lanes and shaded (`_flat_block`) from LANES of them on (a row adds at
    most TILE, so the lanes never exceed 2 * LANES) and after the
    triangle's last block or row.  At 1 or 4 samples an unlit draw without
    alpha test into RGBA8 (at 1 sample the commonest draws into rgba32f too,
    `_float_rows`) shades each row's run where it lies instead
    (`_flat_row`): the lanes' steps in one loop, without writing the pixels
    down first (docs/speed.md, "Thirty-second round").  The per-pixel arithmetic is
    `softras.pipeline.render.draw_triangles`'s, operation for operation.

    Arguments as `_make_draw_tiles`' ``draw_tiles``; lanes : the share's
    `LaneBuffers`; row_runs : whether the driver's sample count is 1 or 4, a
    constant, so that numba prunes the row code from the driver of any
    count (it is pruned on constants only, and n_samples is none there)."""
    # Every array out of its record once per tile, here: where numba counts
    # references (the driver's callees that are not inlined; the driver
    # itself no longer does), it counts one each time an array is taken out
    # of a record or passed to a function, an atomic operation, and per
    # triangle or block that showed: passing the records on to `_flat_block`
    # made the 24k-triangle grid's tile kernel 4-6 % slower.
    lf, li, rows = lanes.lf, lanes.li, lanes.rows
    offsets, positions = samples.offsets, samples.positions
    bin_start, bin_tri = bins.start, bins.tri
    tri_f, tri_i, bbox, colors, uv = tris.f, tris.i, tris.bbox, tris.colors, tris.uv
    lit, lit_rows = tris.lit, tris.lit_rows
    color32, depth, color_f = fb.color32, fb.depth, fb.color_f
    depths = depth.reshape(-1)              # (a view: a pixel's samples one after another)
    # At 1 or 4 samples an unlit draw without alpha test into RGBA8 shades
    # each row's run where it lies (`_flat_row`), without lanes; so does
    # one sample's commonest draws into rgba32f (`_float_rows`).
    by_rows = not (state.lit or state.alpha_test or state.rgba32f) or (n_samples == 1 and _float_rows(state))
    words = color32.reshape(-1)             # (the colour words: a pixel's samples one after another)
    floats = color_f.reshape(-1)            # (an rgba32f buffer's floats, a pixel's four after another)
    full_mask = (1 << n_samples) - 1
    box = samples.box
    tile_x0, tile_x1 = _tile_columns(tile, bins.tiles_x, depth.shape[1])        # (`_padded_run`)
    for j in range(bin_start[tile], bin_start[tile + 1]):
        t = bin_tri[j]
        edges = _edges(tri_i, t)
        x_start, x_end, y_start, y_end = _tile_box(tile, bins.tiles_x, bbox, t, depth)
        if row_runs and by_rows:
            for y in range(y_start, y_end + 1):
                _flat_row(x_start, x_end, y, edges, offsets, t, tri_f, colors, positions, depths, words, floats,
                          depth.shape[1], state, n_samples, tile_x0, tile_x1)
            continue
        # The units k = 0 .. n_units - 1: at one sample the box's pixel rows
        # (`_list_row`), else its 8x8 blocks row by row; and k = n_units to
        # shade what is left: one call site of `_flat_block`, which numba
        # inlines (each inlined copy costs seconds of compile time).
        blocks_x = max((x_end - x_start) // BLOCK + 1, 0)
        if n_samples == 1:
            n_units = max(y_end - y_start + 1, 0) if x_end >= x_start else 0
        else:
            n_units = blocks_x * max((y_end - y_start) // BLOCK + 1, 0)
        n_flat = 0                              # lanes listed, shaded from LANES on
        for k in range(n_units + 1):
            if k < n_units and n_samples == 1:
                n_flat = _list_row(n_flat, x_start, x_end, y_start + k, edges, offsets, li)
                if n_flat < LANES:
                    continue
            elif k < n_units:
                by = y_start + (k // blocks_x) * BLOCK
                bx = x_start + (k % blocks_x) * BLOCK
                by1 = min(by + BLOCK - 1, y_end)
                bx1 = min(bx + BLOCK - 1, x_end)
                outside, all_in = _block_test(edges, bx * 256 + box[0], bx1 * 256 + box[1],
                                              by * 256 + box[2], by1 * 256 + box[3])
                if outside:
                    continue
                n_flat = _list_pixels(n_flat, bx, bx1, by, by1, all_in, edges, offsets, full_mask, rows, li,
                                      n_samples)
                if n_flat < LANES:
                    continue
            elif n_flat == 0:
                break
            _flat_block(n_flat, t, tri_f, colors, uv, lit, lit_rows, positions, depth, depths, color32, color_f,
                        state, lights, lighting, lf, li, n_samples)
            n_flat = 0


@numba.njit(error_model="numpy", inline="always")
def _textured_tile(tile, bins, tris, samples, fb, state, sampler, tex, map_sampler, map_tex, lights, lighting, lanes,
                   n_samples):
    """One 64x64 tile of a textured draw: as `_flat_tile`, but the blocks
    start at even pixels (whole 2x2 quads, for the texture derivatives), the
    covered quads are listed (`softras.kernels.rasterize._list_quads`, or
    every quad of a block inside all edges), block after block, and shaded
    together once LANES or more are listed or at the triangle's last block
    in the tile: `softras.pipeline.texture.sample` and
    `softras.pipeline.ops.apply_fragments` of a textured triangle's
    fragments, as `softras.pipeline.render.draw_triangles` does them, on the n
    lanes (n / 4 quads, with pixel, centre and coverage) of one triangle.
    A small triangle's few quads in each of its blocks were shaded block by
    block: together, bump_mapped_8k_512 draws 14-18 % faster on one
    thread, textured_phong_8k_1024 4-9 %, the floor's large triangles
    (whole blocks, shaded one by one as before) the same (docs/speed.md,
    "Forty-third round").  Arguments as `_flat_tile`, plus the texture's `Sampler`
    and `Texels` tex and the normal or bump map's (map_sampler, map_tex).
    A draw with a map and no colour texture comes here too (``state.texture``
    False): its quads give the map's derivatives.

    Per quad the top-left, top-right and bottom-left lanes give the texture
    derivatives (`softras.pipeline.interpolate.quad_derivatives`) and the
    level of detail is the quad's (`softras.kernels.texture._lanes_lod`);
    every lane's own (s, t) is its pixel's.  Lanes outside the triangle are
    the quad's helper pixels: computed, never written.  With ``state.plain``
    (`plain_colors`) at one sample the filtered texel's bytes are the
    fragment's colour word.  An anisotropic sampler takes one level per quad
    (`softras.kernels.texture._lanes_aniso_levels`); an alpha-tested draw
    samples every covered quad, then discards, then depth-tests.

    The shading is written out in the block loop rather than called:
    as a function of its own (a call per block, with the records' arrays
    counted at each) it made the 1024^2 floor 16 % slower, and as a function
    numba inlines it took 26 s of this function's compile time (numba copied
    an inlined callee's IR block by block, each block with its own copy of
    the callee's variable table, until `softras.pipeline.numba_fixes`).
    Inlined into the one-sample driver, called by the others
    (`_textured_tile_called`)."""
    texels, texels32, table, ewa = tex.bytes, tex.words, tex.levels, tex.ewa
    lf, li, lu, texel = lanes.lf, lanes.li, lanes.lu, lanes.texel
    offsets, depth = samples.offsets, fb.depth
    depths = depth.reshape(-1)              # (a view: a pixel's samples one after another)
    count = n_samples if n_samples != ANY_SAMPLES else offsets.shape[0]      # (a constant for 1 and 4)
    bin_start, bin_tri, tri_i, bbox = bins.start, bins.tri, tris.i, tris.bbox
    depth_func, write_z = state.depth_func, state.write_z
    use_depth = _uses_depth(depth_func, write_z)
    vectorised = sampler.vectorised != 0          # `_lanes_bilinear_fixed` / `_nearest_fixed`, else `_sample_lane`
    full_mask = (1 << count) - 1
    box = samples.box
    for j in range(bin_start[tile], bin_start[tile + 1]):
        t = bin_tri[j]
        edges = _edges(tri_i, t)
        x_start, x_end, y_start, y_end = _tile_box(tile, bins.tiles_x, bbox, t, depth)
        # The 8x8 blocks from even pixels, k = 0 .. n_blocks - 1 row by row.
        x0, y0 = x_start & -2, y_start & -2
        blocks_x = max((x_end - x0) // BLOCK + 1, 0)
        n_blocks = blocks_x * max((y_end - y0) // BLOCK + 1, 0)
        listed = 0                  # lanes listed and not yet shaded
        for k in range(n_blocks):
            block_y = y0 + (k // blocks_x) * BLOCK
            block_x = x0 + (k % blocks_x) * BLOCK
            by, by1 = max(block_y, y_start), min(block_y + BLOCK - 1, y_end)
            bx, bx1 = max(block_x, x_start), min(block_x + BLOCK - 1, x_end)
            outside, all_in = _block_test(edges, bx * 256 + box[0], bx1 * 256 + box[1],
                                          by * 256 + box[2], by1 * 256 + box[3])
            if not outside:
                if all_in and bx1 - bx == BLOCK - 1 and by1 - by == BLOCK - 1:
                    if listed == 0:         # (lanes known at compile time: 9 % off the floor's whole blocks)
                        listed = _list_whole_block(0, bx, by, full_mask, lf, li)
                    else:
                        listed = _list_whole_block(listed, bx, by, full_mask, lf, li)
                else:
                    listed = _list_quads(listed, bx, bx1, by, by1, all_in, edges, offsets, full_mask, lf, li, count)
            # Shaded once LANES or more are listed (another block's 64 might
            # not fit the rows' 2 * LANES) or at the last block.
            if listed == 0 or (listed < LANES and k < n_blocks - 1):
                continue
            n = listed
            listed = 0
            # The n lanes shaded.
            _lane_weights(_whole_vectors(n), t, tris.f, lf, tris.uv, True)        # weights and (s, t), vectorised
            if use_depth:
                _lane_depths(_whole_vectors(n), t, tris.f, samples.positions, li, count)   # (vectorised)
            if state.mapped != NO_MAP:        # (first: it leaves the map's levels in the level rows)
                _map_normals(n, lf, li, lu, texel, map_sampler, map_tex.bytes, map_tex.words, map_tex.levels,
                             map_tex.ewa, state.mapped == BUMP_MAP, state.bump_scale)
            # The level of detail of every quad (before the depth test), kept on the
            # quad's first lane; whether a quad samples two levels.
            any_two = False
            if not state.texture or sampler.beyond:       # (softras's filters choose their levels per lane)
                pass
            elif sampler.aniso:                           # (one level each, never vectorised)
                _lanes_aniso_levels(n, sampler, table[0, 1], table[0, 2], lf, li)
            else:
                any_two = _lanes_lod(n, sampler, table[0, 1], table[0, 2], lf, li)
            # Depth test (scalar; helper lanes untested, see `_depth_test_lanes`);
            # a quad without a passed sample samples level 0 alone.
            if state.alpha_test:                          # (its depth test after the texels, below)
                for l in range(n):
                    li[_LI_PASS, l] = li[_LI_COV, l]
            else:
                _depth_test_lanes(n, li, depth, depths, depth_func, write_z, count)
            block_passed = 0
            block_two = False                             # a passed quad samples two levels
            # (The vectorised filter over whole vectors, m lanes: the quads
            # past n sample level 0, as `softras.kernels.maps._map_normals`.)
            m = _whole_vectors(n) if vectorised else n
            for q in range(m >> 2):
                l = 4 * q
                quad_passed = 0
                if q < n >> 2:
                    quad_passed = li[_LI_PASS, l] | li[_LI_PASS, l + 1] | li[_LI_PASS, l + 2] | li[_LI_PASS, l + 3]
                block_passed |= quad_passed
                if state.texture and not sampler.beyond:  # the quad's levels on its lanes: what each filter reads
                    block_two |= _quad_levels(q, quad_passed != 0, sampler, table, vectorised, any_two, lf, li)
            if block_passed == 0:
                continue
            words = state.plain and count == 1 and vectorised     # texels straight into _LI_WORD
            if not state.texture:
                pass
            elif sampler.vectorised == VECTORISED_NEAREST:
                if block_two:                         # (the level count a constant in each copy)
                    _lanes_nearest_fixed(m, 2, words, lf, li, lu, texels32, sampler)
                else:
                    _lanes_nearest_fixed(m, 1, words, lf, li, lu, texels32, sampler)
            elif vectorised:
                if block_two:
                    _lanes_bilinear_fixed(m, 2, words, False, lf, li, lu, texels32, sampler)
                else:
                    _lanes_bilinear_fixed(m, 1, words, False, lf, li, lu, texels32, sampler)
            elif sampler.beyond:
                for l in range(n):
                    if li[_LI_PASS, l]:
                        _beyond_lane(l, lf, sampler, texels, table)
            else:
                for l in range(n):
                    if li[_LI_PASS, l]:
                        _sample_lane(l, lf, li, texel, sampler, texels, texels32, table, ewa)
            # The fragment colour as llvmpipe's bytes, blended and written
            # (`softras.pipeline.ops.apply_fragments`); an rgba32f buffer's
            # floats after the alpha test (`softras.kernels.rgba32f`).
            if state.rgba32f:
                pass                                  # (`_float_fragments` below)
            elif state.lit:
                _phong_words(_whole_vectors(n), t, tris.colors, tris.lit, tris.lit_rows, lf, li, lights, lighting,
                             state.texture, state.mapped != NO_MAP)
            elif not words:
                _lane_words(_whole_vectors(n), t, tris.colors, lf, li, True, state.flat)
            if state.alpha_test:                          # (a discarded lane's coverage made 0)
                _lane_alpha_test(n, t, tris.colors, lf, li, _LI_COV, state.texture, state.flat, state.cutoff)
                _depth_test_lanes(n, li, depth, depths, depth_func, write_z, count)
            if state.rgba32f:
                _float_fragments(n, t, tris.colors, tris.lit, tris.lit_rows, lf, li, lights, lighting, state,
                                 fb.color_f, np.int64(count))
            else:
                _write_lanes(n, li, fb.color32, state.blend, count)


@numba.njit(error_model="numpy")
def _textured_tile_called(tile, bins, tris, samples, fb, state, sampler, tex, map_sampler, map_tex, lights,
                          lighting, lanes, n_samples):
    """`_textured_tile` as a function of its own, for the driver of any
    sample count (ANY_SAMPLES): compiled once per count (`numba.literally`:
    the count is a compile-time constant in the inlined body)."""
    numba.literally(n_samples)
    _textured_tile(tile, bins, tris, samples, fb, state, sampler, tex, map_sampler, map_tex, lights, lighting, lanes,
                   n_samples)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _flat_block(n, t, tri_f, colors, uv, lit, lit_rows, positions, depth, depths, color32, color_f, state, lights,
                lighting, lf, li, n_samples):
    """`softras.pipeline.ops.apply_fragments` of an untextured triangle's
    fragments (`softras.pipeline.fragment.shade_unlit` colours), as
    `softras.pipeline.render.draw_triangles` does them.
    Depth-test, shade and write the n lanes (covered pixels of one
    untextured triangle, listed by `_flat_tile` with pixel and coverage mask):
    depths (vectorised), the depth test of every lane in its place (scalar,
    no branch on its outcome; `softras.kernels.ops._depth_test_lanes`):
    unlit, each lane stays there (a failed lane is shaded and not written),
    lit per fragment (Phong) or alpha-tested, the lanes with a passed sample
    move to the front; a draw without depth test or alpha test keeps every lane
    (vectorised); perspective weights and colour bytes (vectorised), the
    writes (scalar), or into an rgba32f buffer the float colours and their
    writes (`softras.kernels.rgba32f._float_fragments`); an alpha-tested
    draw's alpha test comes first, on weights at every lane.

    The arrays one by one, not as `Triangles`, `Samples`, `Framebuffer` and
    `LaneBuffers` records: this runs about once per small triangle, and the
    records' arrays taken out here cost reference counts (see `_flat_tile`);
    depths : the depth buffer seen as one row, ``depth.reshape(-1)``, taken
    once a tile (`softras.kernels.ops._depth_test_lanes`); state : the
    `DrawState` (scalars: free)."""
    depth_func, write_z = state.depth_func, state.write_z
    use_depth = _uses_depth(depth_func, write_z)
    if state.alpha_test:                    # (before the depth test: the colour at every lane)
        for l in range(n):
            lf[_LF_CX, l], lf[_LF_CY, l] = li[_LI_PX, l] + 0.5, li[_LI_PY, l] + 0.5
        if not state.flat:                  # (a flat colour is read without weights)
            _lane_weights(n, t, tri_f, lf, uv, False)
        _lane_alpha_test(n, t, colors, lf, li, _LI_COV, False, state.flat, state.cutoff)
    if use_depth:
        _lane_depths(_whole_vectors(n), t, tri_f, positions, li, n_samples)
    # (An int64 from the start: from a literal 0, numba typed `_phong_words`'
    # count as Literal[int](0) on its first pass and compiled it twice, 3 s.)
    kept = np.int64(0)
    if not (use_depth or state.alpha_test):     # every lane kept with its coverage: no compaction (SIMD)
        for l in range(n):
            li[_LI_PASS, l] = li[_LI_COV, l]
            lf[_LF_CX, l], lf[_LF_CY, l] = li[_LI_PX, l] + 0.5, li[_LI_PY, l] + 0.5
        kept = np.int64(n)
    elif not (state.alpha_test or state.lit):
        # Unlit: the lanes keep their places through the depth test, and a
        # failed lane is shaded and not written (`_write_lanes` writes passed
        # samples only): the weights and colour bytes are vectorised loops,
        # cheaper than moving the passed lanes to the front one by one.
        _depth_test_lanes(n, li, depth, depths, depth_func, write_z, n_samples)
        for l in range(n):
            lf[_LF_CX, l], lf[_LF_CY, l] = li[_LI_PX, l] + 0.5, li[_LI_PY, l] + 0.5
        kept = np.int64(n)
    else:                                   # Phong or alpha-tested: the passed lanes to the front
        _depth_test_lanes(n, li, depth, depths, depth_func, write_z, n_samples)
        for l in range(n):
            px, py = li[_LI_PX, l], li[_LI_PY, l]
            p = li[_LI_PASS, l]
            li[_LI_PX, kept] = px
            li[_LI_PY, kept] = py
            li[_LI_PASS, kept] = p
            lf[_LF_CX, kept] = px + 0.5
            lf[_LF_CY, kept] = py + 0.5
            if state.alpha_test:            # (its weights, computed above, go with the lane)
                for c in range(3):
                    lf[_LF_W + c, kept] = lf[_LF_W + c, l]
            kept += p != 0
    if not state.alpha_test and not state.flat:
        _lane_weights(_whole_vectors(kept), t, tri_f, lf, uv, False)
    if state.rgba32f:
        _float_fragments(kept, t, colors, lit, lit_rows, lf, li, lights, lighting, state, color_f, np.int64(n_samples))
        return
    if state.lit:
        _phong_words(_whole_vectors(kept), t, colors, lit, lit_rows, lf, li, lights, lighting, False, False)
    else:
        _lane_words(_whole_vectors(kept), t, colors, lf, li, False, state.flat)
    _write_lanes(kept, li, color32, state.blend, n_samples)


@numba.njit(error_model="numpy", inline="always")
def _float_rows(state):
    """Whether an untextured draw into an rgba32f buffer, at one sample, is
    shaded by rows (`_flat_row`): unlit, without alpha test, colours
    interpolated, and either without depth test or depth writes, blended
    "over" (translucent layers, `softras.kernels.rgba32f._row_floats_over`),
    or "less" with depth writes, not blended (opaque surfaces,
    `softras.kernels.rgba32f._row_floats_less`).  Every other such draw
    takes the lanes (`_flat_block`).  (The copy for "less" raised the peak
    memory of the one-sample driver's compile from 0.69 to 1.08 GB in the
    thirty-sixth round and was left out; in the forty-sixth, after the
    compile's fixes, the peak went 0.58 -> 0.56 GB with it, docs/speed.md.)"""
    return (state.rgba32f and not (state.lit or state.alpha_test or state.flat)
            and ((not _uses_depth(state.depth_func, state.write_z) and state.blend == 1)
                 or (state.depth_func == LESS and state.write_z and state.blend == 0)))


@numba.njit(error_model="numpy", inline="always")
def _flat_row(x0, x1, py, edges, offsets, t, tri_f, colors, positions, depths, words, floats, width, state,
              n_samples, tile_x0, tile_x1):
    """`_flat_block` of an unlit, untextured triangle t's fragments in pixels
    x0..x1 of row py at 1 or 4 samples a pixel (n_samples, a constant),
    without alpha test, into an RGBA8 buffer (or at one sample an rgba32f
    one, where `_float_rows` holds): the row's run of covered pixels
    (`softras.kernels.rasterize._row_run`, the pixels `_list_row` lists; at
    4 samples the union of each sample's run) depth-tested, shaded and
    written where they lie, pixel by pixel (`_row_pixels`,
    `softras.kernels.rgba32f._row_floats_over`), with no lane rows in between.
    depths, words, floats : the depth buffer, the colour words and an
    rgba32f buffer's floats seen as one row each (``reshape(-1)``, a
    pixel's samples one after another); width : the picture's.  The common
    draws get a copy of the pixel loop with their depth test, blend and
    shading constants: "less" with depth writes and no blend, interpolated
    or flat (one sample), and no depth with "over" (rgba32f: that one and
    "less" interpolated).  Every other state takes one copy that reads them
    as values; there, at one sample, a run longer than `TRIMMED_RUN` whose
    first or last pixel fails a depth test is shaded between its first and
    last passing pixel alone (`_passing_run`: the pixels outside fail, and
    the copy would only write back what is stored).  Each copy is a loop
    without a branch, which LLVM vectorises (`_row_pixels`).  tile_x0,
    tile_x1 : the columns of the tile (`_padded_run`)."""
    # The runs as one flat tuple (lo, hi, ...) a sample (numba's array
    # analysis fails on a tuple of tuples indexed in a loop).  (The two
    # branches give tuples of different types: only the drivers of 1 and 4
    # samples compile this code, where n_samples is a constant and numba
    # keeps one branch.)
    if n_samples == 1:
        lo, hi = _row_run(x0, x1, py, edges, offsets)
        runs = (lo, hi)
    else:                                   # (4: one run per sample, and their union)
        lo0, hi0 = _row_run(x0, x1, py, edges, offsets, 0)
        lo1, hi1 = _row_run(x0, x1, py, edges, offsets, 1)
        lo2, hi2 = _row_run(x0, x1, py, edges, offsets, 2)
        lo3, hi3 = _row_run(x0, x1, py, edges, offsets, 3)
        runs = (lo0, hi0, lo1, hi1, lo2, hi2, lo3, hi3)
        lo = min(min(lo0, lo1), min(lo2, lo3))
        hi = max(max(hi0, hi1), max(hi2, hi3))
    if lo > hi:
        return
    corners, corner_colors = _corners(tri_f, t), _corner_colors(colors, t)
    plane = (tri_f[t, _F_X], tri_f[t, _F_Y], tri_f[t, _F_Z], tri_f[t, _F_DZDX], tri_f[t, _F_DZDY])
    # (The sample positions as values, x and y a sample, as the runs: read
    # from the array in the loop, they were loaded again after every store.)
    if n_samples == 1:
        positions = (positions[0, 0], positions[0, 1])
    else:
        positions = (positions[0, 0], positions[0, 1], positions[1, 0], positions[1, 1],
                     positions[2, 0], positions[2, 1], positions[3, 0], positions[3, 1])
    start, end = x0 + lo, x0 + hi
    depth_func, write_z, blend, flat = state.depth_func, state.write_z, state.blend, state.flat
    if n_samples == 1 and state.rgba32f:     # (`_float_rows`: interpolated, "less" with depth writes or "over")
        _row_floats(start, end, py, corners, corner_colors, plane, positions, depths, floats, width, write_z)
    elif depth_func == LESS and write_z and blend == 0 and not flat:
        _row_pixels(start, end, start, end, False, py, runs, x0, corners, corner_colors, plane, positions,
                    depths, words, width, True, LESS, True, 0, False, n_samples)
    elif depth_func == LESS and write_z and blend == 0 and n_samples == 1:
        _row_pixels(start, end, start, end, False, py, runs, x0, corners, corner_colors, plane, positions,
                    depths, words, width, True, LESS, True, 0, True, n_samples)
    elif not _uses_depth(depth_func, write_z) and blend == 1 and not flat:
        first, last = _padded_run(start, end, tile_x0, tile_x1)
        _row_pixels(start, end, first, last, True, py, runs, x0, corners, corner_colors, plane, positions,
                    depths, words, width, False, 0, False, 1, False, n_samples)
    else:                                   # (any other state: every step without a branch, see `_row_pixels`)
        if n_samples == 1 and depth_func != 0 and depth_func != 8 and end - start >= TRIMMED_RUN and not (
                _passes(start, py, plane, positions, depths, width, depth_func)
                and _passes(end, py, plane, positions, depths, width, depth_func)):
            start, end = _passing_run(start, end, py, plane, positions, depths, width, depth_func)
        _row_pixels(start, end, start, end, False, py, runs, x0, corners, corner_colors, plane, positions,
                    depths, words, width, True, depth_func, write_z, blend, flat, n_samples)


@numba.njit(error_model="numpy", inline="always")
def _passes(px, py, plane, positions, depths, width, depth_func):
    """Whether pixel (px, py)'s one sample passes the depth test, its depth
    computed and tested as `_row_pixels_1` does."""
    k = _plane_depth_k(plane, px + positions[0], py + positions[1])
    return _depth_pass_k(depth_func, k, depths[np.uint64(py * width + px)])


@numba.njit(error_model="numpy", inline="always")
def _passing_run(start, end, py, plane, positions, depths, width, depth_func):
    """The first and last pixel of start..end in row py whose sample passes
    the depth test (`_passes`), or an empty run (end + 1, start - 1)."""
    lo, hi = end + 1, start - 1
    for px in range(start, end + 1):
        passed = _passes(px, py, plane, positions, depths, width, depth_func)
        lo = min(lo, px if passed else end + 1)
        hi = max(hi, px if passed else start - 1)
    return lo, hi


@numba.njit(cache=True, inline="always")
def _padded_run(start, end, tile_x0, tile_x1):
    """The pixels first..last that a row's run start..end is computed over:
    the run widened to whole vectors of `softras.kernels.lanes.VECTOR`
    pixels within the tile's columns tile_x0..tile_x1 (on this machine LLVM
    compiles the row loop to vectors of 16 pixels, then of 4, then takes
    the rest pixel by pixel, each with its own three divisions: a multiple
    of 4 leaves none to the last).  The pixels added are this share's (a
    tile belongs to one) and are written back as stored.  Only
    the copy for "over" without depth takes it: blended_8x128_512 on one
    thread 5.81-6.01 -> 4.93-4.97 ms, its grids of 16,384 triangles
    12.0-12.2 -> 10.8 ms; the depth-tested copies took it and got slower
    on small triangles (many_small_24k_512 4.7-4.8 -> 5.7-9.1 ms;
    docs/speed.md, "Forty-first round")."""
    count = _whole_vectors(end - start + 1)
    first = max(min(start, tile_x1 - count + 1), tile_x0)
    return first, min(first + count - 1, tile_x1)


@numba.njit(error_model="numpy", inline="always")
def _row_pixels(start, end, first, last, widened, py, runs, x0, corners, corner_colors, plane, positions, depths,
                words, width, use_depth, depth_func, write_z, blend, flat, n_samples):
    """Pixels start..end of row py, sample s of pixel px covered where
    runs[2 s] <= px - x0 <= runs[2 s + 1] (one sample: `_row_pixels_1`),
    computed over first..last: with ``widened`` (a constant) `_padded_run`'s
    pixels, those outside the run written back as they are stored, else
    start..end itself: the
    steps of `_flat_block` per pixel, with the same operations in the same
    order (the pixels are distinct, so their order does not matter):
    perspective weights (`_weights_at`) at the pixel centre and the colour
    word (`_shade_word`; flat: corner 0's, weights (1, 0, 0)), then per
    covered sample the depth from the plane
    (`softras.kernels.interpolate._lane_depths`; plane = (x0, y0, z0,
    dz/dx, dz/dy) of the set-up triangle, positions (x, y, ...) the
    samples' within the pixel),
    its test and write (`softras.kernels.ops._depth_test_lane`), the blend
    over the stored word (`softras.kernels.ops._blend_word`; at 4 samples
    per sample: `_write_word`'s one blend for equal samples gives the same
    words) and the store of a passed sample's word.

    Written for LLVM's vectoriser: no branch in the loop, every value
    computed, every store a bitwise select of the new value or the stored
    one (a pixel belongs to one tile, so its thread alone reads and writes
    it; the depth is written back as stored where write_z is off), and the
    index an unsigned integer, so that numba adds no test for negative
    indices and the loads and stores are seen to be consecutive.
    `_flat_row`'s copies for the common states have the depth function,
    blend, ``flat`` and the sample count as constants; its copy for any
    other state reads them as values, through the depth test
    (`softras.kernels.ops._depth_pass_k`) and blend
    (`softras.kernels.ops._blend_word`) that select without a branch, and
    with use_depth on (a draw without depth passes every sample there): the
    blended layers with a depth test, "add" or "min" at 512^2 took 1.5-2.4x
    the time of "over" without depth before (docs/speed.md, "Fifty-third
    round")."""
    if n_samples == 1:
        _row_pixels_1(start, end, first, last, widened, py, corners, corner_colors, plane, positions, depths, words,
                      width, use_depth, depth_func, write_z, blend, flat)
        return
    cy = py + 0.5
    for px in range(first, last + 1):
        w = (1.0, 0.0, 0.0)
        if not flat:
            w = _weights_at(corners, px + 0.5, cy)
        word = _shade_word(w, corner_colors, RGBA(1.0, 1.0, 1.0, 1.0))
        pixel = np.uint64((py * width + px) * n_samples)
        for s in range(n_samples):
            # All ones where the sample is covered (and, below, passes), else 0.
            keep = -np.int64((runs[2 * s] <= px - x0) & (px - x0 <= runs[2 * s + 1]))
            i = pixel + np.uint64(s)
            if use_depth:
                k = _plane_depth_k(plane, px + positions[2 * s], py + positions[2 * s + 1])
                stored = depths[i]
                keep &= -np.int64(_depth_pass_k(depth_func, k, stored))
                written = keep & -np.int64(write_z)             # (keep where write_z is a constant True)
                depths[i] = np.int32((k & written) | (stored & ~written))
            dst = np.int64(words[i])
            out = word
            if blend != 0:
                out = _blend_word(blend, word, dst, (word >> 24) & 255)
            words[i] = np.uint32((out & keep) | (dst & ~keep))


@numba.njit(error_model="numpy", inline="always")
def _row_pixels_1(start, end, first, last, widened, py, corners, corner_colors, plane, positions, depths, words,
                  width, use_depth, depth_func, write_z, blend, flat):
    """`_row_pixels` at one sample a pixel, every pixel of start..end
    covered: the same steps without the loop over the samples (with it
    LLVM vectorised the row's last pixels no more: the blended layers' gain
    of this path was lost, 8.4 -> 9.4 ms on one thread)."""
    row = py * width
    cy = py + 0.5
    for px in range(first, last + 1):
        i = np.uint64(row + px)
        keep = np.int64(-1)                         # all ones: the pixel passed
        if widened:                                 # (and is the run's: a test the others would pay for)
            keep = -np.int64((start <= px) & (px <= end))
        if use_depth:
            k = _plane_depth_k(plane, px + positions[0], py + positions[1])
            stored = depths[i]
            keep &= -np.int64(_depth_pass_k(depth_func, k, stored))
            written = keep & -np.int64(write_z)                 # (keep where write_z is a constant True)
            depths[i] = np.int32((k & written) | (stored & ~written))
        w = (1.0, 0.0, 0.0)
        if not flat:
            w = _weights_at(corners, px + 0.5, cy)
        word = _shade_word(w, corner_colors, RGBA(1.0, 1.0, 1.0, 1.0))
        dst = np.int64(words[i])
        if blend != 0:
            word = _blend_word(blend, word, dst, (word >> 24) & 255)
        words[i] = np.uint32((word & keep) | (dst & ~keep))


# One compiled tile driver per (samples, textured) variant (`_make_draw_tiles`),
# keyed on the kernels' sources and those of the stages' kernels they inline
# (`unorm8` of softras.pipeline.ops, `wrap_index` and
# `ewa_texel` of softras.pipeline.texture, `ewa_ellipse` of
# softras.pipeline.texture_beyond, and softras.pipeline.libm).
_SOURCES = sources_stamp(ops, texture, libm, texture_beyond)
_DRAW_TILES = {(n_samples, textured): _make_draw_tiles(n_samples, textured, _SOURCES)
               for textured, counts in DRIVER_SAMPLES.items() for n_samples in counts}
