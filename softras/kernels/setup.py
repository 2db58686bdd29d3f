"""Set-up of the clipped triangles for the compiled path.

Mirrors `softras.pipeline.setup.setup_triangles` in gl precision (viewport
transform with llvmpipe's fused multiply-add, 1/256 snapping, area and
culling, counter-clockwise corner order, integer edge functions, fill rule,
pixel bounding box), the depth plane of
`softras.pipeline.interpolate.depth_at_samples`, and the attributes at the
corners of `softras.pipeline.render.corner_values` (a vertex's values, or
for a vertex the clipper made the clip weights x source vertex values, in
the pipeline's order), in one compiled pass over the
triangles that `softras.pipeline.clip.triangle_list_gl` lists.

The set-up triangles are two tables, one row per clipped triangle (layouts
below), read by the later kernels (`softras.kernels.rasterize`,
`softras.kernels.interpolate`).  The same pass lists the triangles it
keeps and counts the tiles their boxes touch: the first pass of binning,
in each share of a large draw's set-up on its thread, while the box is
at hand (the whole binning after the set-up took 0.53-0.69 ms of the
71k-triangle scan's render, on one thread; docs/speed.md,
"Forty-eighth round").
"""

from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softras.kernels.pool import on_threads
from softras.kernels.threads import _aligned_stack
from softras.pipeline import setup as setup_stage

# Per set-up triangle, float64 row of `tri_f`: window x (3), y (3), z (3),
# 1/w (3), dz/dx, dz/dy.  int64 row of `tri_i`: edge A (3), B (3), X0 (3),
# Y0 (3), inclusive (3).
_F_X, _F_Y, _F_Z, _F_W, _F_DZDX, _F_DZDY, _NF = 0, 3, 6, 9, 12, 13, 14
_I_A, _I_B, _I_X0, _I_Y0, _I_INC, _NI = 0, 3, 6, 9, 12, 15

CULL_CODES = {"none": 0, "back": 1, "front": 2}
SUBPIXEL_BITS = setup_stage.SUBPIXEL_BITS      # gl precision snaps to 1/256 pixel
SUBPIXEL_ONE = setup_stage.SUBPIXEL_ONE
TILE = 64          # pixels per tile side (binning and the parallel unit)
PARALLEL_SETUP = 4096      # triangles from which `_setup` runs in shares on threads

# A draw's clipped triangle list, as `softras.pipeline.clip.triangle_list_gl`
# returns it (source, slot, fan_clip, fan_weights), with the mesh's vertex
# indices (T, 3).
#
# Records of arrays cross into compiled code as plain tuples, tuple(record),
# read by unpacking in the record's order: numba's dispatcher types a plain
# tuple argument in C and a named one in Python, about 0.7 us more per
# argument and call (measured: the tile driver's seven records cost 7 us a
# draw as namedtuples).
Clipped = namedtuple("Clipped", ["indices", "source", "slot", "fan_clip", "fan_weights"])

# The set-up triangles, one row per clipped triangle: tables f (T, _NF)
# float64 and i (T, _NI) int64 (layouts above), pixel box bbox (T, 4) int64
# (x0, x1, y0, y1 inclusive), corner colours (T, 3, 4), corner uvs (T, 3,
# 2), or (1, 3, 2) unused when the draw is untextured, and for Phong shading
# the lit attributes by row: lit (V + 3 F, 6, or 10 with a normal or bump
# map) the world positions, (not unit) world normals (and tangents) of the
# vertices, then of the corners the clipper makes, and lit_rows (T, 3)
# int64 each corner's row (`_lit_rows`), else lit (0, 6) and lit_rows
# (1, 3) unused.
Triangles = namedtuple("Triangles", ["f", "i", "bbox", "colors", "uv", "lit", "lit_rows"])


def _setup(clip_pos, clipped, width, height, cull, box, vertex_values, tris, scratch, bins) -> tuple:
    """`softras.pipeline.setup.setup_triangles` (gl precision) of the clipped
    triangles, and the first pass of their binning (`_setup_range`): in one
    call, or from PARALLEL_SETUP triangles (read at call time) in a share a
    thread (`softras.kernels.pool.on_threads`), share r taking the r-th of
    n_shares runs of the triangles.  clip_pos : the mesh's vertices in clip
    space (V, 4); clipped : the `Clipped` list; box : the sample offsets'
    extremes (min x, max x, min y, max y) int64 (4,), raster units
    (`softras.pipeline.rasterize._sample_box`); vertex_values : (vertex
    colours (V, 4), vertex uvs (V, 2) or (0, 2) when untextured, vertex
    world positions and normals (V + 3 F, 6 or 10: tris' lit) or (0, 6)
    when not Phong-shaded); tris : the `Triangles` to fill; scratch : the caller's reused buffers
    (`softras.kernels.draw._Scratch`), for the per-vertex tables; bins :
    (listed (T,) int64, tiles_x, tiles_y), share r's visible triangles
    listed from its first row.  Returns found (n_shares, 3) int64: per
    share its first row, visible triangles and their boxes' pixels; and
    counts (tiles + 1,) int64: tile k's triangles at k + 1, the shares'
    counts summed (`softras.kernels.rasterize._fill_bins`)."""
    # The window corners of the input vertices, once per vertex (a vertex is
    # shared by ~6 triangles).
    vertex_f, vertex_i = window_buffers(scratch, len(clip_pos))
    _window_vertices(clip_pos, width, height, vertex_f, vertex_i)
    args = ((vertex_f, vertex_i), tuple(clipped), width, height, cull, box, vertex_values, tuple(tris))
    listed, tiles_x, tiles_y = bins
    n = len(clipped.source)
    # (The thread count asked only for a parallel set-up: 3.6 us a call.)
    n_shares = 1 if n < PARALLEL_SETUP else numba.get_num_threads()
    found = np.empty((n_shares, 3), np.int64)
    counts = np.zeros((n_shares, tiles_x * tiles_y + 1), np.int64)

    def share(r):
        start = r * n // n_shares
        found[r, 0] = start
        found[r, 1], found[r, 2] = _setup_range(start, (r + 1) * n // n_shares, *args, (listed, counts[r], tiles_x))

    on_threads(share, n_shares)
    return found, counts[0] if n_shares == 1 else counts.sum(axis=0)


def window_buffers(scratch, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """The tables `_window_vertices` fills for n_vertices input vertices,
    from the caller's reused buffers (`softras.kernels.draw._Scratch`):
    vertex_f (V, 4) float64 and vertex_i (V, 2) int64."""
    return (scratch.take("vertex_f", (n_vertices, 4), np.float64),
            scratch.take("vertex_i", (n_vertices, 2), np.int64))


@numba.njit(cache=True, error_model="numpy")
def _window_vertices(clip_pos, width, height, vertex_f, vertex_i):
    """`softras.pipeline.setup.viewport_transform` (gl, fused) and
    `softras.pipeline.setup.snap` of every input vertex (`_window_corner`,
    clip_pos (V, 4)): fills
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
    as `softras.pipeline.setup.viewport_transform` and `softras.pipeline.setup.snap`
    compute them in gl precision: llvmpipe's viewport transform with a fused
    multiply-add for an input vertex (``fused``), an unfused one for a vertex
    made by the clipper."""
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


@numba.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
def _setup_range(start, stop, window, clipped, width, height, cull, box, vertex_values, tris, bins):
    """`softras.pipeline.setup.setup_triangles` (gl precision) and the depth plane of
    `softras.pipeline.interpolate.depth_at_samples`, for the clipped triangles start
    to stop - 1 (clipped: the `Clipped` list as a plain tuple), the input vertices' window corners given
    (window = (vertex_f, vertex_i) of `_window_vertices`), box the sample
    offsets' extremes (`_setup`).

    Fills their rows of tris (the `Triangles` as a plain tuple): f, i, bbox, and the corner
    attributes (`_corner_values`) of vertex_values = (vertex colours (V, 4),
    vertex uvs (V, 2) or (0, 2) when untextured, world positions and
    normals (V + 3 F, 6 or 10: the same array as tris' lit) or (0, 6) when
    not Phong-shaded, by row (`_lit_rows`)); the rows of the
    triangles that the pipeline drops (zero area, culled, empty box) are
    left as they were.

    And the first pass of binning (the second is
    `softras.kernels.rasterize._fill_bins`), while each triangle's box is
    at hand: bins = (listed (T,) int64, counts (tiles + 1,) int64,
    tiles_x) takes the kept triangles, in order, at listed[start:start +
    n], and counts[k + 1] += 1 for each TILE x TILE tile k their boxes
    touch.  Returns n and the sum of their boxes' pixels (the draw's work,
    `softras.kernels.draw.shares`).

    Compiled without reference counting, as the tile drivers are
    (``_nrt=False``): it allocates nothing, and the corners are values
    (`_corner`), not small arrays, so that they stay in registers (with
    `_corner_values`' constant channel counts: 46 -> 37 ns a triangle of
    the 100k-triangle grid on one thread; docs/speed.md, "Forty-ninth
    round").
    """
    _aligned_stack()                    # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
    tri_f, tri_i, bbox, corner_colors, corner_uvs, _, lit_rows = tris
    vertex_colors, vertex_uvs, vertex_lit = vertex_values
    min_ox, max_ox, min_oy, max_oy = box[0], box[1], box[2], box[3]
    listed, counts, tiles_x = bins
    n_visible = 0
    pixels = 0
    for t in range(start, stop):
        c0 = _corner(t, 0, window, clipped, width, height)
        c1 = _corner(t, 1, window, clipped, width, height)
        c2 = _corner(t, 2, window, clipped, width, height)
        area = (c1[4] - c0[4]) * (c2[5] - c0[5]) - (c2[4] - c0[4]) * (c1[5] - c0[5])
        front = area > 0
        if area == 0 or (cull == 1 and not front) or (cull == 2 and front):
            continue
        swapped = 0 if front else 1
        if swapped:                             # swap corners 0 and 1 -> counter-clockwise
            c0, c1 = c1, c0
        # Bounding box in pixels, as setup_triangles computes it (its
        # float ceil / floor of a multiple of 1/256 here in integers).
        x_lo = -((max_ox - min(c0[4], min(c1[4], c2[4]))) >> SUBPIXEL_BITS)
        x_hi = (max(c0[4], max(c1[4], c2[4])) - min_ox) >> SUBPIXEL_BITS
        y_lo = -((max_oy - min(c0[5], min(c1[5], c2[5]))) >> SUBPIXEL_BITS)
        y_hi = (max(c0[5], max(c1[5], c2[5])) - min_oy) >> SUBPIXEL_BITS
        b0 = max(min(max(x_lo, -1), width), 0)
        b1 = min(min(max(x_hi, -1), width), width - 1)
        b2 = max(min(max(y_lo, -1), height), 0)
        b3 = min(min(max(y_hi, -1), height), height - 1)
        if b0 > b1 or b2 > b3:
            continue
        bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = b0, b1, b2, b3
        _edge(tri_i, t, 0, c0, c1)
        _edge(tri_i, t, 1, c1, c2)
        _edge(tri_i, t, 2, c2, c0)
        listed[start + n_visible] = t
        n_visible += 1
        pixels += (b1 - b0 + 1) * (b3 - b2 + 1)
        for ty in range(b2 // TILE, b3 // TILE + 1):
            for tx in range(b0 // TILE, b1 // TILE + 1):
                counts[ty * tiles_x + tx + 1] += 1
        wx, wy, wz = (c0[0], c1[0], c2[0]), (c0[1], c1[1], c2[1]), (c0[2], c1[2], c2[2])
        tri_f[t, _F_X], tri_f[t, _F_X + 1], tri_f[t, _F_X + 2] = wx
        tri_f[t, _F_Y], tri_f[t, _F_Y + 1], tri_f[t, _F_Y + 2] = wy
        tri_f[t, _F_Z], tri_f[t, _F_Z + 1], tri_f[t, _F_Z + 2] = wz
        tri_f[t, _F_W], tri_f[t, _F_W + 1], tri_f[t, _F_W + 2] = c0[3], c1[3], c2[3]
        tri_f[t, _F_DZDX], tri_f[t, _F_DZDY] = _depth_slopes(wx, wy, wz)
        _corner_values(vertex_colors, corner_colors, t, clipped, swapped, 4)
        if vertex_uvs.shape[0]:
            _corner_values(vertex_uvs, corner_uvs, t, clipped, swapped, 2)
        if vertex_lit.shape[0]:
            _lit_rows(vertex_lit, vertex_colors.shape[0], lit_rows, t, clipped, swapped)
    return n_visible, pixels


@numba.njit(cache=True, inline="always")
def _corner(t, k, window, clipped, width, height):
    """Corner k of clipped triangle t (clipped: the `Clipped` list as a plain
    tuple) in window space: (x, y, z, 1/w, snapped x, snapped y), an input
    vertex's from window = (vertex_f, vertex_i) of `_window_vertices`, a
    corner of a fan triangle the clipper made from its clip position
    (`_window_corner`, fused where the clipper passed the vertex through:
    `viewport_transform`)."""
    vertex_f, vertex_i = window
    indices, source, slot, fan_clip, fan_weights = clipped
    f = slot[t]
    if f < 0:
        v = indices[source[t], k]
        return vertex_f[v, 0], vertex_f[v, 1], vertex_f[v, 2], vertex_f[v, 3], vertex_i[v, 0], vertex_i[v, 1]
    fused = _own_vertex(f, fan_weights, k) >= 0
    return _window_corner(fan_clip[f, k, 0], fan_clip[f, k, 1], fan_clip[f, k, 2], fan_clip[f, k, 3], fused,
                          width, height)


@numba.njit(cache=True, inline="always")
def _edge(tri_i, t, i, p, q):
    """Edge i of set-up triangle t, from corner p to corner q (`_corner`s,
    snapped x, y at 4 and 5), into tri_i's row t: `softras.pipeline.setup.edge_equations`'
    A, B and origin (X0, Y0), from the endpoints in lexicographic order and
    negated if they were swapped, and the tie rule's inclusive flag
    (llvmpipe's "left_bottom": A > 0, or A = 0 and B > 0)."""
    x0, y0, x1, y1 = p[4], p[5], q[4], q[5]
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


@numba.njit(cache=True, error_model="numpy", inline="always")
def _depth_slopes(wx, wy, wz):
    """The depth plane's dz/dx and dz/dy through a triangle's three window
    corners (x, y, z each a 3-tuple), from corner 0: the operations of
    `softras.pipeline.interpolate.depth_at_samples` in their order."""
    dx1, dy1, dz1 = wx[1] - wx[0], wy[1] - wy[0], wz[1] - wz[0]
    dx2, dy2, dz2 = wx[2] - wx[0], wy[2] - wy[0], wz[2] - wz[0]
    det = dx1 * dy2 - dx2 * dy1
    return (dz1 * dy2 - dz2 * dy1) / det, (dx1 * dz2 - dx2 * dz1) / det


@numba.njit(cache=True, inline="always")
def _corner_values(values, out, t, clipped, swapped, channels):
    """`softras.pipeline.render.corner_values`: the attributes at set-up
    triangle t's corners, out[t] (3, K), from the vertex values (V, K), in
    set-up corner order: a corner the clipper passed through its vertex's
    values as they are, a corner it made the weighted sum of
    `_made_corner` (`_own_vertex` tells them apart).  channels : K, a
    constant at the call (4 for colours, 2 for uvs), so that the copies
    compile to a fixed count (``values.shape[1]`` cost the set-up ~2.5 ns
    of ~40 a triangle)."""
    indices, source, slot, _, fan_weights = clipped
    for k in range(3):
        row = 1 - k if swapped and k < 2 else k
        own = _own_vertex(slot[t], fan_weights, row)
        if own >= 0:
            v = indices[source[t], own]
            for c in range(channels):
                out[t, k, c] = values[v, c]
        else:
            for c in range(channels):
                out[t, k, c] = _made_corner(values, indices, source[t], fan_weights, slot[t], row, c)


@numba.njit(cache=True, inline="always")
def _lit_rows(values, n_vertices, rows, t, clipped, swapped):
    """The rows of a Phong draw's lit attributes, values (V + 3 F, K): the
    vertices' (V) from `softras.kernels.light.phong_inputs`, then three for
    each fan triangle f of the clipper.  Sets rows[t] (3,) int64 to the row
    of set-up triangle t's corner k (set-up corner order): a corner the
    clipper passed through its vertex's row, corner j of fan triangle f
    that the clipper made row V + 3 f + j, filled here with
    `_made_corner`'s values (each fan triangle is one
    set-up triangle's: no other thread writes the row).  The values the
    drivers read at the corners are `_corner_values`', without a copy of
    the vertices' for every triangle (the copies were a quarter of the
    71k-triangle scan's set-up time; docs/speed.md, "Forty-eighth round")."""
    indices, source, slot, _, fan_weights = clipped
    f = slot[t]
    for k in range(3):
        row = 1 - k if swapped and k < 2 else k
        own = _own_vertex(f, fan_weights, row)
        if own >= 0:
            rows[t, k] = indices[source[t], own]
        else:
            r = n_vertices + 3 * f + row
            rows[t, k] = r
            for c in range(values.shape[1]):
                values[r, c] = _made_corner(values, indices, source[t], fan_weights, f, row, c)


@numba.njit(cache=True, inline="always")
def _own_vertex(f, fan_weights, row):
    """Which vertex (0, 1, 2) of its source triangle corner ``row`` of
    clipped triangle f is when the clipper passed it through, else -1: of
    a passed-through triangle (f < 0) vertex ``row``; else, when the
    corner's largest clip weight (fan_weights (F, 3, 3)) is exactly 1 (not
    `softras.pipeline.clip.ClippedTriangles.generated`), the first vertex
    of weight 1, as numpy's argmax finds it."""
    if f < 0:
        return row
    w0, w1, w2 = fan_weights[f, row, 0], fan_weights[f, row, 1], fan_weights[f, row, 2]
    if max(w0, max(w1, w2)) != 1.0:
        return -1
    return 0 if w0 == 1.0 else 1 if w1 == 1.0 else 2


@numba.njit(cache=True, inline="always")
def _made_corner(values, indices, source_t, fan_weights, f, row, c):
    """Value c at corner ``row`` of clipped triangle f (its clip weights
    fan_weights[f, row]; source_t its source triangle), a corner the
    clipper made: `softras.pipeline.render.corner_values`'
    ``einsum("tkj,tjc->tkc", w, values[vertices])``, in the same sum order
    (from 0: a -0 sum comes back +0).  The set-up's fan triangles and
    exact precision's clipped triangles (`softras.kernels.exact`) alike."""
    i0, i1, i2 = indices[source_t, 0], indices[source_t, 1], indices[source_t, 2]
    return (((0.0 + fan_weights[f, row, 0] * values[i0, c]) + fan_weights[f, row, 1] * values[i1, c])
            + fan_weights[f, row, 2] * values[i2, c])
