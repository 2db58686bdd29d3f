"""The compiled path of exact precision: float64 throughout, no snapping.

`softras.pipeline.render` in ``precision="exact"`` shades a draw's fragments
as numpy arrays, ~300 bytes and a few dozen array passes a fragment.  Here
a triangle draw (unlit, flat, Gouraud or Phong; textured with the GL
filters, anisotropic included, or softras's own; normal or bump mapped;
alpha test, every depth function and blend equation) is rasterized, shaded
and applied by one kernel in parallel shares (`_draw`); its vertex and clip stages
are the stages' own functions, its set-up and corner values compiled
mirrors (`setup_triangles`, `corner_values`); line draws take
`softras.kernels.exact_lines`, a textured draw under ``texture_bounds``
the stages' `draw_triangles`, on the same float64 buffers;
`resolve` makes the picture.  The bytes are the stages' (tests/test_exact_path.py):

- set-up: `softras.pipeline.setup.setup_triangles` (`_setup`) and the
  einsum of `softras.pipeline.render.corner_values` (`_corners`);
- coverage: `softras.pipeline.rasterize._raster_triangle` itself, on the
  triangle's pixel box cut to a band of rows;
- per fragment: `softras.pipeline.interpolate.edge_functions`,
  `perspective_weights` (`softras.kernels.interpolate._weights_at`),
  `interpolate` (`_mix`), `depth_at_samples` (`softras.kernels.setup._depth_slopes`), for Phong
  `softras.pipeline.render.phong_attributes` and
  `softras.pipeline.fragment.blinn_phong` (`_phong`: the tile kernels'
  `softras.kernels.light._phong_colors` on a band's fragments as lanes),
  for a texture `softras.pipeline.render.uv_at_fragments`
  (`_uv_at`, `_st_derivatives`) and `softras.pipeline.texture.sample` (`_footprint_levels`,
  `_texel_at`; anisotropic: `_anisotropic`) or
  `softras.pipeline.texture_beyond.sample_beyond`
  (`softras.kernels.texture_beyond._beyond_texel`), for
  a normal or bump map `softras.pipeline.render.mapped_normals`
  (`_map_texels`, `softras.kernels.light._perturb`),
  `shade_unlit`, `alpha_test`, each with the stages' operations in their order;
- per sample: `softras.pipeline.ops.apply_fragments` without quantizing
  (its own `_depth_pass` and `_blend`);
- the buffers: `softras.pipeline.render.new_pass_framebuffer`'s values,
  reused from one render to the next and cleared in parallel
  (`reused_framebuffer`, `_clear`);
- the picture: `softras.pipeline.ops.resolve`'s box filter
  (`softras.kernels.ops._resolve_box`, an RGBA8 picture's bytes or an
  rgba32f picture's floats, `softras.kernels.rgba32f.resolve`).

Bands of `BAND_ROWS` rows are drawn in parallel, in shares on
`softras.kernels.pool`'s threads that take the bands as they reach them
(not a numba parallel loop: the exact variant's cold compile 45.5 -> 29 s,
docs/speed.md, "Fifty-first round"); a band walks the draw's triangles in
order over its own rows, so every pixel sees the fragments in draw order,
as the stages apply them.

Why one module of ~700 lines: it is one kernel (`_draw`) and the compiled
mirrors only it calls, in the order of the stages they mirror, under one
cache key (`softras.kernels.stamp`: an edit of this file recompiles the exact
kernels alone, none of the tile drivers).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np

from softras.kernels import exact_lines
from softras.kernels.interpolate import Corners, _barycentric, _corner_colors, _mix, _triple, _weights_at
from softras.kernels.lanes import _LF_LIT, _LF_MAP, _LF_W, _NLF
from softras.kernels.light import NO_LIGHTING, _phong_colors, base_colors, flat_corner_colors, scene_lighting
from softras.kernels.ops import _resolve_box, _uses_depth
from softras.kernels import rgba32f
from softras.kernels.pool import on_threads
from softras.kernels.scratch import _Scratch
from softras.kernels.setup import CULL_CODES, _depth_slopes, _made_corner, _own_vertex
from softras.kernels.stamp import sources_stamp
from softras.kernels.texture import NO_TEXTURE, _filter_level, _nan_max, texture_tables
from softras.kernels.texture_beyond import _beyond_texel, beyond_tables
from softras.kernels.threads import NoAliasCompiler, _aligned_stack, _owns, _unowned, owners_table, share_count
from softras.pipeline import libm, ops, rasterize, render as stages, setup, texture, texture_beyond, vertex
from softras.pipeline.rasterize import _raster_triangle, _sample_box
from softras.scene import Scene

# Rows of the picture a thread draws at once.
BAND_ROWS = 16

# Shading codes of `_draw`.
UNLIT, FLAT, PHONG = 0, 1, 2          # (Gouraud is lit per vertex: UNLIT of its lit vertex colours)
NO_MAP, NORMAL_MAP, BUMP_MAP = 0, 1, 2     # a draw's normal or bump map


def compiled(scene: Scene, draw, inputs: stages.Pass) -> bool:
    """Whether `_draw` draws ``draw`` in the pass ``inputs``: triangles,
    untextured, or textured, normal or bump mapped without ``texture_bounds``
    (every filter: GL's, anisotropic included, and softras's own)."""
    material = draw.material
    if draw.mesh.primitive != "triangles":
        return False
    textured = any(name is not None for name in (material.texture, material.normal_map, material.bump_map))
    return not textured or inputs.texture_bounds is None


def render_samples(scene: Scene, job: stages.Job, reuse: bool = False) -> np.ndarray:
    """`softras.pipeline.render.render_samples` of an exact-precision job
    with `draw_triangles` for the triangle draws: the per-sample colour
    buffer (H, W, S, 4) float64, premultiplied, GL's y-up rows.  reuse: in
    this thread's scratch buffers (`reused_framebuffer`), which the next
    render with reuse overwrites (`softras.renderer` resolves it first)."""
    if job.precision != "exact":
        raise ValueError("softras.kernels.exact renders exact precision only")
    return stages.render_samples(scene, job, draw_triangles, reused_framebuffer if reuse else None,
                                 lines=exact_lines.draw_lines)


def reused_framebuffer(scene: Scene, inputs: stages.Pass) -> tuple[np.ndarray, np.ndarray]:
    """`softras.pipeline.render.new_pass_framebuffer`'s values, in this
    thread's scratch arrays (new ones over `_Scratch`'s MAX_BYTES) cleared in
    parallel (`_clear`): a new 1024² buffer faults a page per 4 KiB, 7 ms."""
    shape = (scene.height, scene.width, len(inputs.positions))
    color = _scratch.take("exact color", shape + (4,), np.float64)
    depth = _scratch.take("exact depth", shape, np.float64)
    _clear(color, ops.premultiplied(scene.background), depth)
    return color, depth


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _clear(color, clear, depth):
    """color[...] = clear (4,), depth[...] = 1, rows in parallel: the
    buffers (H, W, S, 4) and (H, W, S) of `softras.pipeline.ops.new_framebuffer`."""
    for y in numba.prange(color.shape[0]):
        for x in range(color.shape[1]):
            for s in range(color.shape[2]):
                for c in range(4):
                    color[y, x, s, c] = clear[c]
                depth[y, x, s] = 1.0


def set_up_draw(scene: Scene, draw, inputs: stages.Pass):
    """`softras.pipeline.render.set_up_draw` in exact precision: the stages'
    vertex and clip stages (`softras.pipeline.render.clip_draw`), then
    `setup_triangles`."""
    clipped = stages.clip_draw(scene, draw, inputs)
    return clipped, setup_triangles(clipped.clip, scene.width, scene.height, cull=draw.cull,
                                    offsets=inputs.offsets, unit=inputs.unit, tie_rule=inputs.tie_rule,
                                    front_face=scene.front_face)


def setup_triangles(clip: np.ndarray, width: int, height: int, *, cull: str, offsets: np.ndarray, unit: float,
                    tie_rule: str, front_face: str) -> setup.TriangleSetup:
    """`softras.pipeline.setup.setup_triangles` in exact precision, by one
    compiled pass over the clipped triangles (`_setup`): the same
    `softras.pipeline.setup.TriangleSetup`.  clip (T, 3, 4) float64."""
    n = len(clip)
    out = setup.TriangleSetup(
        triangle=np.empty(n, np.int64), corner=np.empty((n, 3), np.int64), window=np.empty((n, 3, 3)),
        inv_w=np.empty((n, 3)), raster=np.empty((n, 3, 2)), edge_a=np.empty((n, 3)), edge_b=np.empty((n, 3)),
        edge_x0=np.empty((n, 3)), edge_y0=np.empty((n, 3)), edge_inclusive=np.empty((n, 3), bool),
        bbox=np.empty((n, 4), np.int64), front_facing=np.empty(n, bool))
    fields = [getattr(out, field.name) for field in dataclasses.fields(out)]
    count = _setup(np.ascontiguousarray(clip, np.float64), width, height,
                   CULL_CODES[setup.window_cull(cull, front_face)], front_face == "ccw",
                   _sample_box(np.asarray(offsets, np.float64)), float(unit), setup.TIE_RULES[tie_rule], *fields)
    return setup.TriangleSetup(*(field[:count] for field in fields))


def corner_values(clipped, tris: setup.TriangleSetup, mesh):
    """`softras.pipeline.render.corner_values`' corners function, compiled
    (`_corners`): per-vertex values (N, K) -> (T', 3, K) at the set-up
    triangles' corners."""
    c = np.ascontiguousarray
    tables = (c(clipped.weights), c(clipped.source), c(mesh.indices, np.int64), c(tris.triangle), c(tris.corner))

    def corners(values: np.ndarray) -> np.ndarray:
        out = np.empty((len(tris.triangle), 3, values.shape[1]))
        _corners(*tables, c(values, np.float64), out)
        return out

    return corners


def _make_corners(sources: str):
    """`_corners`, cached with the stamp of the kernels' sources as a
    closure variable (`softras.kernels.stamp`: it inlines
    `softras.kernels.setup._own_vertex` and `_made_corner`).  sources : in
    the cache key only."""

    @numba.njit(cache=True, error_model="numpy")
    def corners(weights, source, indices, triangle, corner, values, out):
        """out[t, k] = the values at set-up corner k (row corner[t, k] of
        weights[triangle[t]]) as `softras.pipeline.render.corner_values`
        takes them: a corner's own vertex's values when the clipper passed
        it through (`softras.kernels.setup._own_vertex`), else the clip
        weights applied to the values of its source triangle's vertices
        (indices[source[triangle[t]]]) as numpy's einsum ``tkj,tjc->tkc``
        sums them (`softras.kernels.setup._made_corner`)."""
        stamp = sources                 # noqa: F841  (a closure variable: the cache key)
        for t in range(out.shape[0]):
            clipped = triangle[t]
            vertices = source[clipped]
            for k in range(3):
                row = corner[t, k]
                own = _own_vertex(clipped, weights, row)
                if own >= 0:
                    for c in range(out.shape[2]):
                        out[t, k, c] = values[indices[vertices, own], c]
                else:
                    for c in range(out.shape[2]):
                        out[t, k, c] = _made_corner(values, indices, vertices, weights, clipped, row, c)

    return corners


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nan_min(a, b):
    """np.minimum of two values: NaN if either is NaN."""
    if a != a or b != b:
        return np.nan
    return min(a, b)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nan_min3(a, b, c):
    """np.min of three values: NaN if any is NaN."""
    if a != a or b != b or c != c:
        return np.nan
    return min(a, b, c)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nan_max3(a, b, c):
    """np.max of three values: NaN if any is NaN."""
    if a != a or b != b or c != c:
        return np.nan
    return max(a, b, c)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _box_edge(v, lo, hi):
    """One bounding-box bound of `softras.pipeline.setup.setup_triangles`
    after its rounding: ``np.clip(v, lo, hi).astype(np.int64)`` (NaN gives
    -2^63, as numpy's conversion does)."""
    if v != v:
        return np.int64(-9223372036854775808)
    return np.int64(min(max(v, lo), hi))


@numba.njit(cache=True, error_model="numpy")
def _setup(clip, width, height, cull, front_ccw, box, unit, tie_rule, triangle, corner, window, inv_w, raster,
           edge_a, edge_b, edge_x0, edge_y0, inclusive, bbox, front):
    """`softras.pipeline.setup.setup_triangles` (exact precision) of the
    clipped triangles clip (T, 3, 4), with the same operations in the same
    order: the viewport transform ``(c / w) W/2 + W/2``, twice the signed
    area, culling (cull: CULL_CODES, counter-clockwise terms), the corners
    made counter-clockwise, the edge equations (`edge_equations`), the tie
    rule's inclusive edges, the pixel box from the sample offsets' extremes box (their
    `_sample_box`, from the caller: `softras.pipeline.cache_key`) and ``unit``.  Writes the visible
    triangles' rows, in order, into the `TriangleSetup`'s arrays (T rows
    each) and returns their count."""
    scale = (width / 2.0, height / 2.0, 0.5)
    sign_a, sign_b = tie_rule
    min_ox, max_ox, min_oy, max_oy = box
    wx, wy, wz, ww = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    n = 0
    for t in range(clip.shape[0]):
        for k in range(3):
            oow = 1.0 / clip[t, k, 3]
            ww[k] = oow
            wx[k] = clip[t, k, 0] * oow * scale[0] + scale[0]
            wy[k] = clip[t, k, 1] * oow * scale[1] + scale[1]
            wz[k] = clip[t, k, 2] * oow * scale[2] + scale[2]
        area = (wx[1] - wx[0]) * (wy[2] - wy[0]) - (wx[2] - wx[0]) * (wy[1] - wy[0])
        ccw = area > 0
        if not area != 0 or (cull == 1 and not ccw) or (cull == 2 and ccw):
            continue
        order = (0, 1, 2) if ccw else (1, 0, 2)        # corners 0 and 1 swapped: counter-clockwise
        xs = (wx[order[0]], wx[order[1]], wx[order[2]])
        ys = (wy[order[0]], wy[order[1]], wy[order[2]])
        x0 = np.ceil((_nan_min3(xs[0], xs[1], xs[2]) - max_ox) / unit)
        x1 = np.floor((_nan_max3(xs[0], xs[1], xs[2]) - min_ox) / unit)
        y0 = np.ceil((_nan_min3(ys[0], ys[1], ys[2]) - max_oy) / unit)
        y1 = np.floor((_nan_max3(ys[0], ys[1], ys[2]) - min_oy) / unit)
        bx0 = max(_box_edge(x0, -1.0, float(width)), 0)
        bx1 = min(_box_edge(x1, -1.0, float(width)), width - 1)
        by0 = max(_box_edge(y0, -1.0, float(height)), 0)
        by1 = min(_box_edge(y1, -1.0, float(height)), height - 1)
        if not (bx0 <= bx1 and by0 <= by1):
            continue
        triangle[n] = t
        front[n] = ccw if front_ccw else area < 0
        bbox[n, 0], bbox[n, 1], bbox[n, 2], bbox[n, 3] = bx0, bx1, by0, by1
        for k in range(3):
            c = order[k]
            corner[n, k] = c
            window[n, k, 0], window[n, k, 1], window[n, k, 2] = wx[c], wy[c], wz[c]
            inv_w[n, k] = ww[c]
            raster[n, k, 0], raster[n, k, 1] = wx[c], wy[c]
            # `softras.pipeline.setup.edge_equations`: the edge from corner k
            # to k + 1 from its endpoints in lexicographic order.
            ax, ay, bx, by = xs[k], ys[k], xs[(k + 1) % 3], ys[(k + 1) % 3]
            swap = (ax > bx) | ((ax == bx) & (ay > by))
            px, py, qx, qy = (bx, by, ax, ay) if swap else (ax, ay, bx, by)
            sign = -1.0 if swap else 1.0
            a, b = (py - qy) * sign, (qx - px) * sign
            edge_a[n, k], edge_b[n, k], edge_x0[n, k], edge_y0[n, k] = a, b, px, py
            inclusive[n, k] = (sign_a * a > 0) | ((a == 0) & (sign_b * b > 0))
        n += 1
    return n


def resolve(job: stages.Job, color: np.ndarray) -> np.ndarray:
    """`softras.pipeline.render.resolve` of an exact-precision job's
    per-sample colours (H, W, S, 4) float64: the picture (H, W, 4), row 0 =
    top.  An RGBA8 job's box filter by `softras.kernels.ops._resolve_box`
    (the same bytes, in parallel, without float buffers); an rgba32f job's by
    `softras.kernels.rgba32f.resolve`; the tent filter by the stages."""
    if job.precision != "exact":
        raise ValueError("softras.kernels.exact resolves exact precision only")
    if not job.rgba8:
        return rgba32f.resolve(job, color)
    if job.resolve_filter != "box":
        return stages.resolve(job, color)
    out = np.empty(color.shape[:2] + (4,), np.uint8)
    _resolve_box(color, out)
    return out


def draw_triangles(scene: Scene, draw, inputs: stages.Pass, color: np.ndarray, depth: np.ndarray) -> None:
    """`softras.pipeline.render.draw_triangles` in exact precision: a
    `compiled` draw by `set_up_draw` and `corner_values`, then `_draw`; any
    other by the stages.  Gouraud's vertex lighting and flat shading's face
    colours are the compiled ones of `softras.kernels.light` (the same
    bits)."""
    if not compiled(scene, draw, inputs):
        stages.draw_triangles(scene, draw, inputs, color, depth)
        return
    clipped, tris = set_up_draw(scene, draw, inputs)
    if len(tris) == 0:
        return
    mesh, material = draw.mesh, draw.material
    corners = corner_values(clipped, tris, mesh)
    base = base_colors(scene, draw)                                    # straight, Gouraud lit
    lit, lights, lighting = (np.zeros((0, 6)), np.zeros((1, 3), np.int64)), *NO_LIGHTING[1:]
    shading = {"flat": FLAT, "phong": PHONG}.get(material.shading, UNLIT)
    if shading == FLAT:                                                # (T', 3, 4): the colour at corner 0
        colors = flat_corner_colors(scene, draw, base, clipped.source[tris.triangle])
    else:
        colors = corners(base)                                         # (T', 3, 4)
    map_name = material.normal_map if material.normal_map is not None else material.bump_map
    if shading == PHONG:
        columns = [vertex.world_positions(mesh.positions, draw.world),
                   vertex.world_normals(mesh.normals, draw.world, unit=False)]
        if map_name is not None:
            columns.append(vertex.world_tangents(mesh.tangents, draw.world))
        at_corners = corners(np.concatenate(columns, axis=1))          # (T', 3, 6), mapped (T', 3, 10)
        # (By row, as `softras.kernels.light._phong_colors` reads them: corner k of t in row 3 t + k.)
        lit = (at_corners.reshape(-1, at_corners.shape[2]), np.arange(3 * len(at_corners)).reshape(-1, 3))
        lights, lighting = scene_lighting(scene, material)
    uv, (sampler, texels), (map_sampler, map_texels) = np.zeros((1, 3, 2)), NO_TEXTURE, NO_TEXTURE
    if material.texture is not None or map_name is not None:
        uv = corners(mesh.uvs)                                         # (T', 3, 2), float64 as given
    if material.texture is not None:
        tex = texture.prepare(scene.textures[material.texture])
        beyond = texture_beyond.filter_for(inputs.texture_filter, tex.name)
        sampler, texels = beyond_tables(tex, beyond) if beyond is not None else exact_sampler(tex)
    if map_name is not None:
        map_sampler, map_texels = exact_sampler(texture.prepare(scene.textures[map_name]))
    mapped = NORMAL_MAP if material.normal_map is not None else BUMP_MAP if map_name is not None else NO_MAP
    cutoff = material.alpha_cutoff
    c = np.ascontiguousarray
    args = (c(tris.window), c(tris.inv_w), c(tris.edge_a), c(tris.edge_b), c(tris.edge_x0), c(tris.edge_y0),
            c(tris.edge_inclusive), c(tris.bbox), c(inputs.offsets, np.float64), float(inputs.unit),
            c(inputs.positions, np.float64), shading, c(colors), lit, c(lights), tuple(lighting),
            material.texture is not None, c(uv), sampler, texels.bytes, texels.levels, mapped, map_sampler,
            map_texels.bytes, map_texels.levels, float(material.bump_scale), color, depth,
            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write, ops.BLEND_MODES[draw.blend],
            cutoff is not None, float(cutoff or 0.0), BAND_ROWS)
    bands = -(-color.shape[0] // BAND_ROWS)                                # (the kernel's bands)
    n_threads = share_count(bands)
    owners = owners_table(bands, n_threads)
    on_threads(lambda r: _DRAW(*args, owners, r), n_threads)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _st_derivatives(c, u, v, px, py):
    """`softras.pipeline.interpolate.analytic_derivatives` of (s, t) at
    window point (px, py) of the triangle with `Corners` c and corner
    coordinates u, v (3-tuples), same operations in the same order: the
    exact derivatives (ds/dx, dt/dx, ds/dy, dt/dy) in (s, t) per window
    pixel."""
    lam = _barycentric(c, px, py)
    iw = c.inv_w
    q = (lam[0] * iw[0], lam[1] * iw[1], lam[2] * iw[2])
    big_q = q[0] + q[1] + q[2]
    s, t = _mix(q, u) / big_q, _mix(q, v) / big_q
    dsdx, dtdx = _step_derivative(c, u, v, lam, s, t, big_q, px + 1.0, py + 0.0)
    dsdy, dtdy = _step_derivative(c, u, v, lam, s, t, big_q, px + 0.0, py + 1.0)
    return dsdx, dtdx, dsdy, dtdy


@numba.njit(cache=True, error_model="numpy", inline="always")
def _step_derivative(c, u, v, lam, s, t, big_q, px, py):
    """One step of `_st_derivatives`: the barycentrics' change from ``lam``
    to window point (px, py) (affine: exact for a one-pixel step), and the
    derivatives (ds, dt) of the quotient ``sum q_i a_i / Q``."""
    moved = _barycentric(c, px, py)
    iw = c.inv_w
    dq = ((moved[0] - lam[0]) * iw[0], (moved[1] - lam[1]) * iw[1], (moved[2] - lam[2]) * iw[2])
    dq_sum = dq[0] + dq[1] + dq[2]
    return (_mix(dq, u) - s * dq_sum) / big_q, (_mix(dq, v) - t * dq_sum) / big_q


@numba.njit(cache=True, error_model="numpy", inline="always")
def _levels(rho2, last, mip):
    """`softras.pipeline.texture.choose_levels` in exact precision, from
    rho^2 in level-0 texels^2; mip as `softras.kernels.texture.Sampler`'s
    (0 none, 1 mipmap_nearest, 2 mipmap_linear), ``last`` the last level.
    Returns (magnified, level0, level1, frac of level1)."""
    magnified = not rho2 > 1.0                     # lambda <= 0 (NaN: magnified)
    if mip == 0:
        return magnified, 0, 0, 0.0
    lod = 0.5 * libm._log2(rho2)
    if lod != lod:
        lod = -np.inf
    if mip == 1:                                   # ceil(lambda + 1/2) - 1 for lambda > 1/2, else 0
        level = np.ceil(lod + 0.5) - 1.0 if lod > 0.5 else 0.0
        level = np.int64(min(max(level, 0.0), float(last)))
        return magnified, level, level, 0.0
    if np.isfinite(lod):
        ipart = np.floor(lod)
        frac = lod - ipart
    else:
        ipart = float(last) if lod > 0 else -1.0
        frac = 0.0
    # (Below level 0 or from the last level on, both levels are one and the
    # same, and `_texel_at` does not blend: the stages' frac of 0 there is not needed.)
    level = np.int64(ipart)
    return magnified, min(max(level, 0), last), min(max(level + 1, 0), last), frac


@numba.njit(cache=True, error_model="numpy", inline="always")
def _footprint_levels(sampler, table, dsdx, dtdx, dsdy, dtdy):
    """The levels `softras.pipeline.texture.sample` takes in exact precision
    at the derivatives of `_st_derivatives` (d(s, t) per window pixel): the
    level-0 footprint rho^2 (`texel_derivatives`, `rho_squared`) and
    `_levels` of it, for `_texel_at`.  All lookups at one fragment share
    them (a bump map's four)."""
    width, height = table[0, 1], table[0, 2]
    du_s, du_t = dsdx * width, dtdx * height
    dv_s, dv_t = dsdy * width, dtdy * height
    rho2 = _nan_max(du_s * du_s + du_t * du_t, dv_s * dv_s + dv_t * dv_t)
    return _levels(rho2, sampler.levels - 1, sampler.mip)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _texel_at(sampler, texels, table, s, t, magnified, level0, level1, frac):
    """`softras.pipeline.texture.filter_at_lod` in exact precision at (s, t)
    on the levels `_levels` chose (magnified, level0, level1, frac): the
    min or mag filter on one or two levels and their blend
    ``c0 + f (c1 - c0)``.  sampler, texels (the mip chain's bytes) and
    table (L, 3) (byte offset, width, height per level) as `exact_sampler`
    gives them.  Inlined once in each kernel that samples (a second inlined
    level, or one copy per lookup, costs minutes of compile).  Returns
    premultiplied (r, g, b, a) in [0, 1]."""
    linear = (sampler.mag_filter if magnified else sampler.min_filter) == 1
    level = 0 if magnified else level0
    r, g, b, a = _filter_level(texels, table[level, 0], table[level, 1], table[level, 2], s, t, linear,
                               sampler.wrap_s, sampler.wrap_t)
    if not magnified and level1 != level0 and frac > 0:
        r1, g1, b1, a1 = _filter_level(texels, table[level1, 0], table[level1, 1], table[level1, 2], s, t, linear,
                                       sampler.wrap_s, sampler.wrap_t)
        r, g, b, a = r + frac * (r1 - r), g + frac * (g1 - g), b + frac * (b1 - b), a + frac * (a1 - a)
    return r / 255.0, g / 255.0, b / 255.0, a / 255.0


def _make_anisotropic(sources: str):
    """The kernel `_anisotropic`, cached under the key ``sources`` (a closure
    variable, `softras.kernels.stamp`): a function of its own, called by
    `_texels` and `_map_texels`."""

    @numba.njit(cache=True, error_model="numpy")
    def _anisotropic(sampler, texels, table, s, t, dsdx, dtdx, dsdy, dtdy):
        """`softras.pipeline.texture.sample_anisotropic` in exact precision:
        the EXT spec's probes (`softras.pipeline.texture.anisotropic_probes`
        with the limit ``sampler.aniso``, `exact_sampler`), each
        `_texel_at` the levels of the probes' rho^2, at ``(s, t) + (i / (N + 1) - 1/2)``
        times the longer derivative vector, i = 1 .. N, summed in that
        order and divided by N."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        width, height = table[0, 1], table[0, 2]
        px = np.hypot(dsdx * width, dtdx * height)
        py = np.hypot(dsdy * width, dtdy * height)
        pmax, pmin = _nan_max(px, py), _nan_min(px, py)
        ratio = pmax / pmin if pmin > 0 else np.inf
        if not pmax > 0:
            ratio = 1.0
        limit = float(sampler.aniso)
        if ratio != ratio:                                  # (inf / inf: numpy's int64 of NaN, then at least 1)
            count = np.int64(1)
        else:
            count = max(np.int64(min(np.ceil(min(ratio, limit)), limit)), np.int64(1))
        step = pmax / count
        magnified, level0, level1, frac = _levels(step * step, sampler.levels - 1, sampler.mip)
        axis_s, axis_t = (dsdx, dtdx) if px > py else (dsdy, dtdy)
        r = g = b = a = 0.0
        for i in range(1, count + 1):
            offset = i / (count + 1.0) - 0.5
            pr, pg, pb, pa = _texel_at(sampler, texels, table, s + offset * axis_s, t + offset * axis_t,
                                       magnified, level0, level1, frac)
            r, g, b, a = r + pr, g + pg, b + pb, a + pa
        return r / count, g / count, b / count, a / count

    return _anisotropic


def exact_sampler(tex: texture.MipTexture):
    """`softras.kernels.texture.texture_tables` of a prepared texture for
    `_texels` and `_map_texels`: float weights, and ``aniso`` the EXT spec's probe limit
    ``max(1, floor(max_anisotropy))`` where exact precision filters
    anisotropically (`softras.pipeline.texture.effective_anisotropy` > 1), else 0."""
    sampler, texels = texture_tables(tex, False)
    anisotropic = texture.effective_anisotropy(tex.max_anisotropy, gl=False) > 1
    return sampler._replace(aniso=max(1, math.floor(tex.max_anisotropy)) if anisotropic else 0), texels


def _make_phong(sources: str):
    """The kernel `_phong`, with the cache key ``sources`` as a closure
    variable (`softras.kernels.stamp.sources_stamp`)."""

    @numba.njit(cache=True, error_model="numpy")
    def _phong(k, t, colors, lit, lf, lights, lighting, mapped):
        """`softras.pipeline.render.phong_attributes` and
        `softras.pipeline.fragment.blinn_phong` of triangle t's k fragments of
        one band: the tile kernels' `softras.kernels.light._phong_colors`
        (`softras.kernels.light._light_points`' operations per fragment, in
        passes over the fragments that compile to SIMD), the fragments as its
        lanes: their perspective
        weights in lf's _LF_W rows, a map's tangent-space normals in the
        _LF_MAP rows; the lit straight colour into the _LF_LIT rows.  A
        function of its own: inlined into `_draw`'s parallel loop, numba's
        array analysis fails on it."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        _phong_colors(k, t, colors, lit[0], lit[1], lf, lights, lighting, mapped)

    return _phong


def _make_uv_at(sources: str):
    """The kernel `_uv_at`, with the cache key ``sources`` as a closure
    variable (`softras.kernels.stamp.sources_stamp`)."""

    @numba.njit(cache=True, error_model="numpy")
    def _uv_at(k, out_x, out_y, weights, corners, u, v, out):
        """The texture coordinates of a triangle's k fragments of one band,
        for `_texels` and `_map_texels` (a texture and a normal or bump map
        read the same ones): pixel (out_x[f], out_y[f]) with perspective
        weights weights[:, f], the triangle's `Corners` and its corners'
        (s, t) as u, v 3-tuples; into out (6, >= k) the rows s, t
        (`softras.pipeline.render.uv_at_fragments`, exact) and ds/dx, dt/dx,
        ds/dy, dt/dy (`_st_derivatives`)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        for f in range(k):
            w = (weights[0, f], weights[1, f], weights[2, f])
            out[0, f], out[1, f] = _mix(w, u), _mix(w, v)
            out[2, f], out[3, f], out[4, f], out[5, f] = _st_derivatives(corners, u, v, out_x[f] + 0.5,
                                                                         out_y[f] + 0.5)

    return _uv_at


def _make_texels(sources: str):
    """The kernel `_texels`, with the cache key ``sources`` as a closure
    variable (`softras.kernels.stamp.sources_stamp`)."""

    @numba.njit(cache=True, error_model="numpy")
    def _texels(k, uvs, sampler, texels, table, out):
        """The texels of a textured triangle's k fragments of one band at
        their (s, t) and derivatives (uvs (6, >= k), `_uv_at`): `_texel_at`
        on the levels `_footprint_levels` chose, anisotropic `_anisotropic`
        (under a ``texture_filter``: `softras.kernels.texture_beyond._beyond_texel`),
        into out (4, >= k).  A function of its own, called once per triangle and
        band: inlined into `_draw`, the texture code made it take 47 s to
        compile."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        for f in range(k):
            s, t = uvs[0, f], uvs[1, f]
            dsdx, dtdx, dsdy, dtdy = uvs[2, f], uvs[3, f], uvs[4, f], uvs[5, f]
            if sampler.beyond:                  # (`texture_filter`: level-0 texels as `texel_derivatives`)
                width, height = table[0, 1], table[0, 2]
                r, g, b, a = _beyond_texel(s, t, dsdx * width, dtdx * height, dsdy * width, dtdy * height, sampler,
                                           texels, table)
                r, g, b, a = r / 255.0, g / 255.0, b / 255.0, a / 255.0
            elif sampler.aniso:
                r, g, b, a = _ANISOTROPIC(sampler, texels, table, s, t, dsdx, dtdx, dsdy, dtdy)
            else:
                magnified, level0, level1, frac = _footprint_levels(sampler, table, dsdx, dtdx, dsdy, dtdy)
                r, g, b, a = _texel_at(sampler, texels, table, s, t, magnified, level0, level1, frac)
            out[0, f], out[1, f], out[2, f], out[3, f] = r, g, b, a

    return _texels


def _make_map_texels(sources: str):
    """The kernel `_map_texels`, with the cache key ``sources`` as a closure
    variable (`softras.kernels.stamp.sources_stamp`)."""

    @numba.njit(cache=True, error_model="numpy")
    def _map_texels(k, uvs, bump, bump_scale, sampler, texels, table, out):
        """The tangent-space normals of `softras.pipeline.render.mapped_normals`
        (exact) of a mapped triangle's k fragments of one band (arguments as
        `_texels`; the map's sampler, texels and table) into out (3, >= k):
        the map's texel (`_texel_at`, `_anisotropic`) at the fragment's (s, t) with its analytic
        derivatives, and `softras.pipeline.fragment.normal_map_normals` of it,
        or with ``bump`` `softras.pipeline.fragment.bump_normals`: the red
        channel at (s +- 1/W, t) and (s, t +- 1/H) (W x H the map's level 0)
        with the same derivatives, then ``(-scale dh_s / 2, -scale dh_t / 2, 1)``."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        step_s, step_t = 1.0 / table[0, 1], 1.0 / table[0, 2]
        for f in range(k):
            s, t = uvs[0, f], uvs[1, f]
            dsdx, dtdx, dsdy, dtdy = uvs[2, f], uvs[3, f], uvs[4, f], uvs[5, f]
            magnified, level0, level1, frac = False, np.int64(0), np.int64(0), 0.0
            if not sampler.aniso:
                magnified, level0, level1, frac = _footprint_levels(sampler, table, dsdx, dtdx, dsdy, dtdy)
            rise_s = rise_t = 0.0
            for j in range(4 if bump else 1):   # bump: (s + 1/W, t), (s - 1/W, t), (s, t + 1/H), (s, t - 1/H)
                at_s, at_t = s, t
                if bump and j < 2:
                    at_s = s + step_s if j == 0 else s + -step_s
                elif bump:
                    at_t = t + step_t if j == 2 else t + -step_t
                if sampler.aniso:
                    r, g, b, _ = _ANISOTROPIC(sampler, texels, table, at_s, at_t, dsdx, dtdx, dsdy, dtdy)
                else:
                    r, g, b, _ = _texel_at(sampler, texels, table, at_s, at_t, magnified, level0, level1, frac)
                if not bump:
                    out[0, f], out[1, f], out[2, f] = 2.0 * r - 1.0, 2.0 * g - 1.0, 2.0 * b - 1.0
                elif j == 0:
                    rise_s = r
                elif j == 1:
                    rise_s = rise_s - r
                elif j == 2:
                    rise_t = r
                else:
                    rise_t = rise_t - r
            if bump:
                out[0, f], out[1, f], out[2, f] = -bump_scale * rise_s * 0.5, -bump_scale * rise_t * 0.5, 1.0

    return _map_texels


@numba.njit(cache=True, error_model="numpy", inline="always")
def _shade(shade, f, r, g, b, a, textured):
    """`softras.pipeline.fragment.shade_unlit` of fragment f's straight colour
    (r, g, b, a) into column f of shade (4, >= f + 1): premultiplied (the
    material colour it multiplies by is ones: the values stay), times the
    texel already there when textured."""
    if textured:
        shade[0, f], shade[1, f] = (r * a) * shade[0, f], (g * a) * shade[1, f]
        shade[2, f], shade[3, f] = (b * a) * shade[2, f], a * shade[3, f]
    else:
        shade[0, f], shade[1, f], shade[2, f], shade[3, f] = r * a, g * a, b * a, a


def _make_draw(sources: str):
    """The exact kernel `_draw`, with the cache key ``sources``
    (`softras.kernels.stamp.sources_stamp`) as a closure variable."""

    @numba.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
    def _draw(window, inv_w, edge_a, edge_b, edge_x0, edge_y0, inclusive, bbox, offsets, unit, positions, shading,
              colors, lit, lights, lighting, textured, uv, sampler, texels, table, mapped, map_sampler, map_texels,
              map_table, bump_scale, color, depth, depth_func, depth_write, blend, alpha_test, cutoff, band_rows,
              owners, r):
        """Share r of one `compiled` triangle draw into the float64 buffers
        color (H, W, S, 4) and depth (H, W, S): the bands of ``band_rows``
        rows it takes (`softras.kernels.threads._owns`: owners (bands,)
        int64, `softras.kernels.threads.owners_table`), the
        shares run at once on `softras.kernels.pool.on_threads`.  Taken as
        the shares reach them, not in fixed shares: the pool's thread starts
        its share up to 0.2 ms after the calling thread, and in fixed shares
        the calling thread waited for it at every draw.

        window (T', 3, 3), inv_w (T', 3), edge_* (T', 3), inclusive (T', 3),
        bbox (T', 4): the `softras.pipeline.setup.TriangleSetup`'s arrays;
        offsets (S, 2) and unit: the raster sample offsets
        (`softras.pipeline.setup.sample_offsets`, exact); positions (S, 2) the
        sample positions in the pixel; shading: UNLIT, FLAT or PHONG; colors
        (T', 3, 4) straight corner colours (FLAT: the face's at corner 0, zeros
        at the others, `softras.kernels.light.flat_corner_colors`);
        lit = (values (3 T', 6), rows (T', 3)): the corner world positions and
        normals (PHONG), corner k of t in row rows[t, k] (3 t + k); lights and
        lighting: `softras.kernels.light.scene_lighting`; whether textured,
        uv (T', 3, 2) the corners' (s, t), and the texture's sampler, texels
        and level table (`exact_sampler`);
        the normal or bump map (`mapped`: NO_MAP, NORMAL_MAP or BUMP_MAP, with
        lit's values (3 T', 10): the corner world tangents after the normals), its
        sampler, texels and table, and the bump scale (`_map_texels`); the depth function,
        depth write, blend code, and whether the alpha test with ``cutoff``
        applies.  Fragments outside the triangle's box are never made; each
        covered pixel is shaded once (at its centre) and applied per covered
        sample in order (`softras.pipeline.ops.apply_fragments`)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        _aligned_stack()
        edge_a, edge_b, edge_x0, edge_y0 = _unowned(edge_a), _unowned(edge_b), _unowned(edge_x0), _unowned(edge_y0)
        inclusive = _unowned(inclusive)
        height, width = color.shape[0], color.shape[1]
        n_samples = positions.shape[0]
        n_tris = window.shape[0]
        n_bands = (height + band_rows - 1) // band_rows
        write_z = depth_write and depth_func != 0
        plain = n_samples == 1 and not _uses_depth(depth_func, write_z) and not alpha_test
        out_x = np.empty(band_rows * width, np.int32)
        out_y = np.empty(band_rows * width, np.int32)
        out_mask = np.empty(band_rows * width, np.uint32)
        box = np.empty(4, np.int64)
        # The fragments' rows as the tile kernels' lanes (`_phong` reads the
        # weights and a map's normals there): their perspective weights,
        # a normal or bump map's tangent-space normals, then Phong's own.
        lf = np.empty((_NLF, band_rows * width))
        weights = lf[_LF_W:_LF_W + 3]
        tangent_normals = lf[_LF_MAP:_LF_MAP + 3]
        shade = np.empty((4, band_rows * width))             # texels, then colours
        uvs = np.empty((6, band_rows * width))               # (s, t) and their derivatives
        for band in range(n_bands):
            if not _owns(owners, band, r):
                continue
            top = band * band_rows
            bottom = min(top + band_rows, height) - 1
            for t in range(n_tris):
                box[0], box[1] = bbox[t, 0], bbox[t, 1]
                box[2], box[3] = max(bbox[t, 2], top), min(bbox[t, 3], bottom)
                if box[2] > box[3]:
                    continue
                k = _raster_triangle(edge_a[t], edge_b[t], edge_x0[t], edge_y0[t], inclusive[t], box, offsets,
                                     unit, out_x, out_y, out_mask, 0, True)
                # The triangle's values as scalars: corners, depth plane, corner colours
                # (Phong reads its corners' world positions and normals itself).
                corners = Corners((window[t, 0, 0], window[t, 1, 0], window[t, 2, 0]),
                                  (window[t, 0, 1], window[t, 1, 1], window[t, 2, 1]),
                                  (inv_w[t, 0], inv_w[t, 1], inv_w[t, 2]))
                x0, y0, z0 = window[t, 0, 0], window[t, 0, 1], window[t, 0, 2]
                dzdx, dzdy = _depth_slopes(corners.x, corners.y, (z0, window[t, 1, 2], window[t, 2, 2]))
                cc = _corner_colors(colors, t)
                # The perspective weights of all k fragments first: a loop LLVM vectorises.
                if shading != FLAT or textured:
                    for f in range(k):
                        w = _weights_at(corners, out_x[f] + 0.5, out_y[f] + 0.5)
                        weights[0, f], weights[1, f], weights[2, f] = w[0], w[1], w[2]
                if textured or mapped != NO_MAP:
                    _UV_AT(k, out_x, out_y, weights, corners, _triple(uv, t, 0), _triple(uv, t, 1), uvs)
                if textured:
                    _TEXELS(k, uvs, sampler, texels, table, shade)
                if mapped != NO_MAP:
                    _MAP_TEXELS(k, uvs, mapped == BUMP_MAP, bump_scale, map_sampler, map_texels, map_table,
                                tangent_normals)
                # The fragments' colours, then their writes: two loops, the first free
                # of the writes' tests and stores (SIMD; in one loop, colours and writes
                # took 16 of the 8 blended layers' 30 ms); a draw that writes every
                # covered pixel at one sample (no depth, no alpha test) writes without
                # the per-sample tests (those layers: 31-40 -> 24-25 ms).
                if shading == PHONG:
                    _PHONG(k, t, colors, lit, lf, lights, lighting, mapped != NO_MAP)
                    for f in range(k):
                        _shade(shade, f, lf[_LF_LIT, f], lf[_LF_LIT + 1, f], lf[_LF_LIT + 2, f], lf[_LF_LIT + 3, f],
                               textured)
                else:
                    for f in range(k):
                        # (A flat colour is corner 0's: 1 c + 0 0 + 0 0 is c.)
                        w = (1.0, 0.0, 0.0) if shading == FLAT else (weights[0, f], weights[1, f], weights[2, f])
                        _shade(shade, f, _mix(w, cc.r), _mix(w, cc.g), _mix(w, cc.b), _mix(w, cc.a), textured)
                if plain:           # (one sample, every covered pixel written: no test at all)
                    for f in range(k):
                        px, py, alpha = out_x[f], out_y[f], shade[3, f]
                        for ch in range(4):
                            color[py, px, 0, ch] = ops._blend(blend, shade[ch, f], color[py, px, 0, ch], alpha)
                    continue
                for f in range(k):
                    px, py, mask = out_x[f], out_y[f], out_mask[f]
                    if alpha_test and shade[3, f] < cutoff:  # (`pipeline.fragment.alpha_test`: NaN kept)
                        continue
                    for s in range(n_samples):
                        if not (mask >> s) & 1:
                            continue
                        if _uses_depth(depth_func, write_z):    # (`depth_at_samples` from corner 0)
                            z = z0 + dzdx * ((px + positions[s, 0]) - x0) + dzdy * ((py + positions[s, 1]) - y0)
                            if not ops._depth_pass(depth_func, z, depth[py, px, s]):
                                continue
                            if write_z:
                                depth[py, px, s] = z
                        for ch in range(4):
                            color[py, px, s, ch] = ops._blend(blend, shade[ch, f], color[py, px, s, ch],
                                                              shade[3, f])

    return _draw


# The kernels, keyed on the kernels' sources and the stages' they call.
_SOURCES = sources_stamp(rasterize, ops, texture, libm, texture_beyond)
_ANISOTROPIC = _make_anisotropic(_SOURCES)
_corners = _make_corners(_SOURCES)
_PHONG = _make_phong(_SOURCES)
_UV_AT = _make_uv_at(_SOURCES)
_TEXELS = _make_texels(_SOURCES)
_MAP_TEXELS = _make_map_texels(_SOURCES)
_scratch = _Scratch()
_DRAW = _make_draw(_SOURCES)
