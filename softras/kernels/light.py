"""Phong shading for the compiled path: Blinn-Phong per lane.

Mirrors `softras.pipeline.render.phong_attributes` (the fragment's colour,
world position and normal interpolated with the perspective weights, the
normal normalised) and `softras.pipeline.fragment.blinn_phong` (world space,
point and directional lights), then the colour as
`softras.pipeline.fragment.shade_unlit` and `softras.pipeline.ops.unorm8`
make it, operation for operation and in the same order, so that the bytes
are the stages' (tests/test_fastpath.py).

The lights reach the kernels as one table (`light_table`) and the eye and
material terms as a record of scalars (`Lighting`).  `_phong_words` is a
function of its own, not inlined into the tile kernels: numba's inliner
would copy it into every driver variant, untextured ones included (see
`softras.kernels.draw`, "What the tile code costs to compile"), and a call
per block of up to 64 lanes costs nothing beside the lighting of each lane.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np

from softras.kernels.interpolate import RGBA, _color_word, _corner_colors, _mix
from softras.kernels.lanes import (_LF_LIT, _LF_MAP, _LF_NDL, _LF_NRM, _LF_POS, _LF_SPEC, _LF_TEX, _LF_VIEW,
                                   _LF_W, _LI_WORD)
from softras.kernels.pool import on_threads
from softras.kernels.threads import _aligned_stack
from softras.kernels.stamp import sources_stamp
from softras.pipeline import fragment, libm, vertex
from softras.pipeline import ops as ops_stage
from softras.pipeline.libm import _power_by, _whole_exponent

# The eye (world space) and the material's Blinn-Phong terms, as scalars.
Lighting = namedtuple("Lighting", ["eye_x", "eye_y", "eye_z", "ambient", "diffuse", "specular", "shininess"])

# Per light, one float64 row of the light table: the light vector
# (`softras.pipeline.fragment.light_vectors`: position and 1, or minus the
# direction and 0), then the colour.
_L_VECTOR, _L_COLOR, _NL = 0, 4, 7

# `phong_inputs` of a draw that is not Phong-shaded.
NO_LIGHTING = (np.zeros((0, 6)), np.zeros((0, _NL)), Lighting(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


@numba.njit(cache=True, error_model="numpy")
def _world_attributes(positions, world_rows, normals, normal_rows, out):
    """`softras.pipeline.vertex.world_positions` of positions (V, 3) by
    world_rows (3, 4) into out[:, 0:3] and `softras.pipeline.vertex.world_normals`
    (not unit) of normals (V, 3) by normal_rows (3, 4,
    `softras.pipeline.vertex.normal_rows`) into out[:, 3:6], float64,
    `softras.pipeline.vertex._transform`'s sums: the same bits, written in
    place (two arrays copied into out's columns took 0.33 ms of the 71k
    scan's set-up)."""
    for v in range(positions.shape[0]):
        x, y, z = positions[v, 0], positions[v, 1], positions[v, 2]
        nx, ny, nz = normals[v, 0], normals[v, 1], normals[v, 2]
        for r in range(3):
            out[v, r] = ((world_rows[r, 0] * x + world_rows[r, 1] * y) + world_rows[r, 2] * z) + world_rows[r, 3]
            out[v, 3 + r] = (((normal_rows[r, 0] * nx + normal_rows[r, 1] * ny) + normal_rows[r, 2] * nz)
                             + normal_rows[r, 3])


# What lights a pass's draws, found once for all of them (`viewing`): the
# eye (3,) world space (`softras.pipeline.vertex.eye_position`), and per
# draw that is lit with its normals (Phong, Gouraud) the (3, 4) rows of its
# normal transform (`softras.pipeline.vertex.normal_rows`), by the draw's
# id.  Per draw, the two inverses took 17 us of a textured, lit part's 47
# us set-up (docs/speed.md, "Forty-second round").
Viewing = namedtuple("Viewing", ["eye", "normal_rows"])


def viewing(scene, draws) -> Viewing | None:
    """The `Viewing` of ``draws`` (the pass's `softras.scene.ordered_draws`):
    one inverse of the view matrix and one of the stack of their world
    matrices (`softras.pipeline.vertex.normal_rows_of`).  When numpy cannot
    invert one of them (a part scaled to 0) the view holds no rows, and
    each draw finds its own where it did before (`world_attributes`): only
    if a triangle of it is left after clipping.  None when no draw is lit
    (an unlit pass reads neither: 5 us a render saved)."""
    if all(draw.material.shading == "unlit" for draw in draws):
        return None
    lit = [draw for draw in draws if draw.material.shading in ("phong", "gouraud")
           and draw.mesh.primitive == "triangles"]
    try:
        rows = dict(zip(map(id, lit), vertex.normal_rows_of(np.array([draw.world for draw in lit])))) if lit else {}
    except np.linalg.LinAlgError:
        rows = {}
    return Viewing(vertex.eye_position(scene.camera.view), rows)


def world_attributes(draw, out: np.ndarray, view: Viewing | None = None) -> np.ndarray:
    """The draw's world positions and (not unit) world normals into out[:V, 0:3]
    and out[:V, 3:6] (out (V or more, 6 or more) float64), `_world_attributes`, with
    the normal rows of ``view`` where it has the draw's; returns out."""
    mesh = draw.mesh
    rows = view.normal_rows.get(id(draw)) if view is not None else None
    _world_attributes(np.ascontiguousarray(mesh.positions, np.float64),
                      np.ascontiguousarray(draw.world[:3], np.float64), np.ascontiguousarray(mesh.normals, np.float64),
                      vertex.normal_rows(draw.world) if rows is None else rows, out)
    return out


def _fresh(name: str, shape: tuple, dtype) -> np.ndarray:
    """A new array (the default ``take`` of `phong_inputs` and `base_colors`)."""
    return np.empty(shape, dtype)


def phong_inputs(scene, draw, take=_fresh, view: Viewing | None = None,
                 extra_rows: int = 0) -> tuple[np.ndarray, np.ndarray, Lighting]:
    """What a Phong-shaded triangle draw's kernels read: per vertex the
    world position and the (not unit) world normal (V, 6) float64, the
    inputs of `softras.pipeline.render.phong_attributes`, and for a normal
    or bump map the world tangent and handedness after them (V, 10,
    `softras.pipeline.vertex.world_tangents`), and the scene's
    `light_table` and `Lighting`.  The (V + extra_rows, 6 or 10) array
    comes from ``take(name, shape, dtype)`` (the tile drivers' set-up
    passes a thread's reused buffers, `softras.kernels.scratch`), its
    rows past the vertices' left for the set-up to fill with the corners
    the clipper makes (`softras.kernels.setup._lit_rows`).  view : the
    pass's `Viewing`, or None to find the eye and normal rows here."""
    mesh, material = draw.mesh, draw.material
    mapped = material.normal_map is not None or material.bump_map is not None
    n = len(mesh.positions)
    out = world_attributes(draw, take("phong_inputs", (n + extra_rows, 10 if mapped else 6), np.float64), view)
    if mapped:
        out[:n, 6:] = vertex.world_tangents(mesh.tangents, draw.world)
    return (out, *scene_lighting(scene, material, view))


def scene_lighting(scene, material, view: Viewing | None = None) -> tuple[np.ndarray, Lighting]:
    """`light_table` of the scene's lights, its camera's eye (``view``'s
    when given) and the material."""
    return light_table(scene.lights, vertex.eye_position(scene.camera.view) if view is None else view.eye, material)


def light_table(lights, eye: np.ndarray, material) -> tuple[np.ndarray, Lighting]:
    """The scene's lights as the (L, _NL) float64 table, and the `Lighting`
    of the eye (3,) and the material."""
    table = np.zeros((len(lights), _NL))
    table[:, _L_VECTOR:_L_VECTOR + 4] = fragment.light_vectors(lights)
    for i, light in enumerate(lights):
        table[i, _L_COLOR:_L_COLOR + 3] = light.color
    return table, Lighting(*(float(v) for v in eye), float(material.ambient), float(material.diffuse),
                           float(material.specular), float(material.shininess))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _unit(x, y, z):
    """`softras.pipeline.fragment._normalize` of one vector: each component
    over ``sqrt((x^2 + y^2) + z^2)`` (numpy's norm, summed left to right)."""
    length = math.sqrt((x * x + y * y) + z * z)
    return x / length, y / length, z / length


@numba.njit(cache=True, error_model="numpy", inline="always")
def _dot(ax, ay, az, bx, by, bz):
    """`softras.pipeline.fragment._dot`: ``(a0 b0 + a1 b1) + a2 b2``."""
    return (ax * bx + ay * by) + az * bz


@numba.njit(cache=True, inline="always")
def _lit_corners(lit, r0, r1, r2, c):
    """Value c of a triangle's three corners in a table of lit attributes
    by row (`_phong_colors`: rows r0, r1, r2), as the 3-tuple `_mix`
    weighs."""
    return lit[r0, c], lit[r1, c], lit[r2, c]


@numba.njit(error_model="numpy", inline="always")
def _phong_colors(n, t, colors, lit, lit_rows, lf, lights, lighting, mapped):
    """The straight Phong-lit colour of the n lanes of triangle t into the
    _LF_LIT rows (r, g, b lit, a interpolated).

    Per lane, under its perspective weights (_LF_W rows): the straight
    colour (corner colours (T, 3, 4)), the world position and normal
    interpolated and the normal normalised
    (`softras.pipeline.render.phong_attributes`), from lit (R, 6) by
    row: corner k's position, then its normal (not unit), in row
    lit_rows[t, k] (lit_rows (T, 3) int64, `_lit_corners`); when
    ``mapped``, the normal perturbed by the _LF_MAP rows' tangent-space
    normal in the frame of the interpolated world tangent (lit (R, 10):
    then the tangent and handedness, `_perturb`); then
    `softras.pipeline.fragment.blinn_phong` with the light table (L, _NL)
    and the `Lighting`.  In passes over the lanes, each of which compiles
    to SIMD: the interpolation; the perturbation; per light its vectors,
    then the power (`softras.pipeline.libm._power_by`: binary powering for
    a whole shininess below 256, else `_power`; no library call), then
    its term."""
    eye_x, eye_y, eye_z, ambient, diffuse, specular, shininess = lighting
    whole = _whole_exponent(shininess)
    cc = _corner_colors(colors, t)
    r0, r1, r2 = lit_rows[t, 0], lit_rows[t, 1], lit_rows[t, 2]
    px3, py3, pz3 = _lit_corners(lit, r0, r1, r2, 0), _lit_corners(lit, r0, r1, r2, 1), _lit_corners(lit, r0, r1, r2, 2)
    nx3, ny3, nz3 = _lit_corners(lit, r0, r1, r2, 3), _lit_corners(lit, r0, r1, r2, 4), _lit_corners(lit, r0, r1, r2, 5)
    for l in range(n):
        w = (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
        px, py, pz = _mix(w, px3), _mix(w, py3), _mix(w, pz3)
        nx, ny, nz = _unit(_mix(w, nx3), _mix(w, ny3), _mix(w, nz3))
        vx, vy, vz = _unit(eye_x - px, eye_y - py, eye_z - pz)
        lf[_LF_POS, l], lf[_LF_POS + 1, l], lf[_LF_POS + 2, l] = px, py, pz
        lf[_LF_NRM, l], lf[_LF_NRM + 1, l], lf[_LF_NRM + 2, l] = nx, ny, nz
        lf[_LF_VIEW, l], lf[_LF_VIEW + 1, l], lf[_LF_VIEW + 2, l] = vx, vy, vz
        lf[_LF_LIT, l] = ambient * _mix(w, cc.r)
        lf[_LF_LIT + 1, l] = ambient * _mix(w, cc.g)
        lf[_LF_LIT + 2, l] = ambient * _mix(w, cc.b)
        lf[_LF_LIT + 3, l] = _mix(w, cc.a)
    if mapped:
        tx3, ty3, tz3, tw3 = (_lit_corners(lit, r0, r1, r2, 6), _lit_corners(lit, r0, r1, r2, 7),
                              _lit_corners(lit, r0, r1, r2, 8), _lit_corners(lit, r0, r1, r2, 9))
        for l in range(n):
            w = (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
            lf[_LF_NRM, l], lf[_LF_NRM + 1, l], lf[_LF_NRM + 2, l] = _perturb(
                lf[_LF_NRM, l], lf[_LF_NRM + 1, l], lf[_LF_NRM + 2, l],
                _mix(w, tx3), _mix(w, ty3), _mix(w, tz3), _mix(w, tw3),
                lf[_LF_MAP, l], lf[_LF_MAP + 1, l], lf[_LF_MAP + 2, l])
    for j in range(lights.shape[0]):
        ox, oy, oz, ow = (lights[j, _L_VECTOR], lights[j, _L_VECTOR + 1], lights[j, _L_VECTOR + 2],
                          lights[j, _L_VECTOR + 3])
        cr, cg, cb = lights[j, _L_COLOR], lights[j, _L_COLOR + 1], lights[j, _L_COLOR + 2]
        for l in range(n):
            lf[_LF_NDL, l], lf[_LF_SPEC, l] = _light_dots(
                ox, oy, oz, ow, lf[_LF_POS, l], lf[_LF_POS + 1, l], lf[_LF_POS + 2, l],
                lf[_LF_NRM, l], lf[_LF_NRM + 1, l], lf[_LF_NRM + 2, l],
                lf[_LF_VIEW, l], lf[_LF_VIEW + 1, l], lf[_LF_VIEW + 2, l])
        for l in range(n):
            lf[_LF_SPEC, l] = specular * _power_by(lf[_LF_SPEC, l], shininess, whole)
        for l in range(n):
            w = (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
            n_dot_l, spec = lf[_LF_NDL, l], lf[_LF_SPEC, l]
            lf[_LF_LIT, l] = lf[_LF_LIT, l] + _light_term(cr, diffuse, n_dot_l, _mix(w, cc.r), spec)
            lf[_LF_LIT + 1, l] = lf[_LF_LIT + 1, l] + _light_term(cg, diffuse, n_dot_l, _mix(w, cc.g), spec)
            lf[_LF_LIT + 2, l] = lf[_LF_LIT + 2, l] + _light_term(cb, diffuse, n_dot_l, _mix(w, cc.b), spec)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _perturb(nx, ny, nz, tx, ty, tz, tw, x, y, z):
    """`softras.pipeline.fragment.perturb_normals` of one fragment: the
    unit world normal n (normalised again, as the stage does), the world
    tangent t and handedness tw, the tangent-space normal (x, y, z) ->
    ``normalize(x T + y B + z N)`` with ``T = normalize(t - N (N.t))`` and
    ``B = sign(tw) cross(N, T)`` (numpy's cross: a1 b2 - a2 b1, ...)."""
    nx, ny, nz = _unit(nx, ny, nz)
    d = _dot(nx, ny, nz, tx, ty, tz)
    tx, ty, tz = _unit(tx - nx * d, ty - ny * d, tz - nz * d)
    sign = -1.0 if tw < 0 else 1.0
    bx, by, bz = sign * (ny * tz - nz * ty), sign * (nz * tx - nx * tz), sign * (nx * ty - ny * tx)
    return _unit((x * tx + y * bx) + z * nx, (x * ty + y * by) + z * ny, (x * tz + y * bz) + z * nz)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _light_dots(ox, oy, oz, ow, px, py, pz, nx, ny, nz, vx, vy, vz):
    """One light's dot products in `softras.pipeline.fragment.blinn_phong` at
    world point p with unit normal n and unit view vector v, the light
    vector o (x, y, z, w) of its table row: (N.L, max(N.H, 0)) with
    ``L = normalize(o.xyz - p o.w)`` and ``H = normalize(L + V)``
    (``numpy.maximum``: NaN stays NaN)."""
    lx, ly, lz = _unit(ox - px * ow, oy - py * ow, oz - pz * ow)
    hx, hy, hz = _unit(lx + vx, ly + vy, lz + vz)
    n_dot_h = _dot(nx, ny, nz, hx, hy, hz)
    return _dot(nx, ny, nz, lx, ly, lz), (n_dot_h if (n_dot_h >= 0.0 or n_dot_h != n_dot_h) else 0.0)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _light_term(c, diffuse, n_dot_l, base, spec):
    """One channel of one light's term in `softras.pipeline.fragment.blinn_phong`:
    ``c (diffuse (N.L) base + spec)`` where N.L > 0, else 0 (light colour
    channel c, spec = specular max(N.H, 0)^shininess)."""
    term = c * (diffuse * n_dot_l * base + spec)
    return term if n_dot_l > 0 else 0.0


def _make_phong_words(sources: str):
    """The kernel `_phong_words`, cached under the key ``sources``
    (`softras.kernels.stamp.sources_stamp`, a closure variable: it inlines
    this folder's kernels, `softras.pipeline.libm`'s pow and
    `softras.pipeline.ops`' rounding).  Every tile
    driver calls it, and uncached each variant compiled it again, 0.9-2.5 s
    a variant (docs/speed.md, "Forty-second round")."""

    @numba.njit(cache=True, error_model="numpy")
    def _phong_words(n, t, colors, lit, lit_rows, lf, li, lights, lighting, textured, mapped):
        """The fragment colour of the n lanes of triangle t, Phong-shaded (with
        the normal or bump map's normals of the _LF_MAP rows when ``mapped``), as
        llvmpipe's bytes: the lit colour (`_phong_colors`) times the _LF_TEX
        texel when textured (`softras.kernels.interpolate._color_word`), one
        RGBA8 word each into the _LI_WORD row."""
        stamp = sources                 # noqa: F841  (the cache key)
        _phong_colors(n, t, colors, lit, lit_rows, lf, lights, lighting, mapped)
        for l in range(n):
            texel = RGBA(1.0, 1.0, 1.0, 1.0)
            if textured:
                texel = RGBA(lf[_LF_TEX, l], lf[_LF_TEX + 1, l], lf[_LF_TEX + 2, l], lf[_LF_TEX + 3, l])
            li[_LI_WORD, l] = _color_word(lf[_LF_LIT, l], lf[_LF_LIT + 1, l], lf[_LF_LIT + 2, l],
                                          lf[_LF_LIT + 3, l], texel)

    return _phong_words


_phong_words = _make_phong_words(sources_stamp(libm, ops_stage))


# ----------------------------------------------------------------------------- per vertex and per face
#
# Gouraud and flat shading light once per vertex or per triangle, before the
# tile kernels: the same `softras.pipeline.fragment.blinn_phong`, point by
# point in a compiled loop (numpy's version spends ~20 temporaries per light
# on a 36k-vertex mesh, 60 % of the render).


# Points a chunk of `_light_points` lights together (`_vertex_lighting`'s
# unit), and the vertices from which Gouraud's lighting takes a share a
# thread: ~35 ns a vertex on one thread here, so from ~3,000 vertices half
# the work outweighs the ~50 us of handing a share over
# (`softras.kernels.pool`).
POINT_CHUNK = 256
PARALLEL_LIGHTING = 4096


@numba.njit(error_model="numpy", inline="always")
def _light_points(base, world, first, m, lights, lighting, out, vectors):
    """`softras.pipeline.fragment.blinn_phong` at the m world points first
    .. first + m - 1 (m <= POINT_CHUNK) of world (P, 6): positions, then
    normals (not unit: normalised here, `_unit`), with straight colours
    base (P, 4), into out (P, 4), alpha kept.  In passes over the points,
    as `_phong_colors` takes its lanes, so that each compiles to SIMD: the
    unit normals and view vectors, then per light the dot products, the
    power and the terms; vectors (8, POINT_CHUNK) float64, scratch."""
    eye_x, eye_y, eye_z, ambient, diffuse, specular, shininess = lighting
    whole = _whole_exponent(shininess)
    for i in range(m):
        v = first + i
        vectors[0, i], vectors[1, i], vectors[2, i] = _unit(world[v, 3], world[v, 4], world[v, 5])
        vectors[3, i], vectors[4, i], vectors[5, i] = _unit(eye_x - world[v, 0], eye_y - world[v, 1],
                                                            eye_z - world[v, 2])
        out[v, 0], out[v, 1], out[v, 2] = ambient * base[v, 0], ambient * base[v, 1], ambient * base[v, 2]
        out[v, 3] = base[v, 3]
    for j in range(lights.shape[0]):
        ox, oy, oz, ow = (lights[j, _L_VECTOR], lights[j, _L_VECTOR + 1], lights[j, _L_VECTOR + 2],
                          lights[j, _L_VECTOR + 3])
        cr, cg, cb = lights[j, _L_COLOR], lights[j, _L_COLOR + 1], lights[j, _L_COLOR + 2]
        for i in range(m):
            v = first + i
            vectors[6, i], vectors[7, i] = _light_dots(
                ox, oy, oz, ow, world[v, 0], world[v, 1], world[v, 2], vectors[0, i], vectors[1, i],
                vectors[2, i], vectors[3, i], vectors[4, i], vectors[5, i])
        for i in range(m):
            vectors[7, i] = specular * _power_by(vectors[7, i], shininess, whole)
        for i in range(m):
            v = first + i
            n_dot_l, spec = vectors[6, i], vectors[7, i]
            out[v, 0] = out[v, 0] + _light_term(cr, diffuse, n_dot_l, base[v, 0], spec)
            out[v, 1] = out[v, 1] + _light_term(cg, diffuse, n_dot_l, base[v, 1], spec)
            out[v, 2] = out[v, 2] + _light_term(cb, diffuse, n_dot_l, base[v, 2], spec)


def _make_lighting_loops(sources: str):
    """`_vertex_lighting` and `_face_lighting`, cached with the stamp of
    this folder's and `softras.pipeline.libm`'s sources as a closure
    variable (`softras.kernels.stamp`): they inline libm's pow, and numba's
    cache would check this file alone.  sources : in the cache key only."""

    @numba.njit(cache=True, error_model="numpy", nogil=True)
    def vertex_lighting(base, world, lights, lighting, out, r, n_shares):
        """Gouraud's lit vertex colours into out (V, 4): base (V, 4) straight,
        world (V, 6) the world positions and world normals (not unit:
        normalised here as `softras.pipeline.vertex.world_normals` does,
        `_world_attributes`), alpha kept (`_light_points`), in chunks of
        POINT_CHUNK vertices: share r of n_shares (a run of the chunks, for
        `softras.kernels.pool.on_threads`).  A scan's 36k vertices in 0.64
        ms on two threads against 0.92 a vertex at a time, each vertex's
        lighting one call."""
        _aligned_stack()                # (on the pool's threads: `softras.kernels.threads._aligned_stack`)
        stamp = sources                 # noqa: F841  (the cache key)
        n = base.shape[0]
        chunks = (n + POINT_CHUNK - 1) // POINT_CHUNK
        vectors = np.empty((8, POINT_CHUNK))
        for chunk in range(r * chunks // n_shares, (r + 1) * chunks // n_shares):
            first = chunk * POINT_CHUNK
            _light_points(base, world, first, min(n - first, POINT_CHUNK), lights, lighting, out, vectors)

    @numba.njit(cache=True, error_model="numpy")
    def face_lighting(world, triangles, base, lights, lighting, out):
        """Flat shading's colours into out (K, 4) for triangles (K, 3) vertex
        indices: `softras.pipeline.render.flat_colors`, the face normal
        (`softras.pipeline.fragment.face_normals`: ``normalize(cross(p1 - p0, p2
        - p0))``, numpy.cross's operations), the centroid (``(p0 + p1 + p2) /
        3``, numpy's mean) and the provoking (last) vertex's straight colour of
        base (V, 4), alpha kept: each face's centroid, cross product and
        colour as a point of `_light_points`, which normalises the normal."""
        stamp = sources                 # noqa: F841  (the cache key)
        k_faces = triangles.shape[0]
        points = np.empty((k_faces, 6))         # centroid, then the cross product (not unit)
        colors = np.empty((k_faces, 4))
        for k in range(k_faces):
            i0, i1, i2 = triangles[k, 0], triangles[k, 1], triangles[k, 2]
            ax, ay, az = world[i1, 0] - world[i0, 0], world[i1, 1] - world[i0, 1], world[i1, 2] - world[i0, 2]
            bx, by, bz = world[i2, 0] - world[i0, 0], world[i2, 1] - world[i0, 1], world[i2, 2] - world[i0, 2]
            points[k, 3], points[k, 4], points[k, 5] = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            for c in range(3):
                points[k, c] = (world[i0, c] + world[i1, c] + world[i2, c]) / 3.0
            for c in range(4):
                colors[k, c] = base[i2, c]
        vectors = np.empty((8, POINT_CHUNK))
        for first in range(0, k_faces, POINT_CHUNK):
            _light_points(colors, points, first, min(k_faces - first, POINT_CHUNK), lights, lighting, out, vectors)

    return vertex_lighting, face_lighting


_vertex_lighting, _face_lighting = _make_lighting_loops(sources_stamp(libm))


def base_colors(scene, draw, take=_fresh, view: Viewing | None = None) -> np.ndarray:
    """`softras.pipeline.render.vertex_base_colors` (V, 4) float64, Gouraud's
    lighting by `_vertex_lighting` (a share a thread from PARALLEL_LIGHTING
    vertices): the same bits.  Its arrays come from
    ``take(name, shape, dtype)``, its eye and normal rows from ``view`` (as
    in `phong_inputs`)."""
    material, mesh = draw.material, draw.mesh
    base = take("base_colors", (len(mesh.positions), 4), np.float64)
    if mesh.colors is None:     # (`softras.pipeline.render.vertex_colors`' white: 1 x colour, the same bits)
        for c in range(4):      # (a column at a time: numpy broadcast a row of 4 at ~3x the time)
            base[:, c] = material.color[c]
    else:
        np.multiply(mesh.colors, material.color, out=base)
    if material.shading != "gouraud":
        return base
    out = take("lit_base_colors", base.shape, np.float64)
    table, lighting = scene_lighting(scene, material, view)
    world = world_attributes(draw, take("world_attributes", (len(mesh.positions), 6), np.float64), view)
    lighting = tuple(lighting)
    n_shares = numba.get_num_threads() if len(base) >= PARALLEL_LIGHTING else 1
    on_threads(lambda r: _vertex_lighting(base, world, table, lighting, out, r, n_shares), n_shares)
    return out


def face_colors(scene, draw, base: np.ndarray, triangles: np.ndarray, view: Viewing | None = None) -> np.ndarray:
    """`softras.pipeline.render.flat_colors`' colours (K, 4) of the mesh
    triangles (K, 3) vertex indices, by `_face_lighting`: the same bits.
    base : (V, 4) straight vertex colours times the material's; view : as
    in `phong_inputs`."""
    out = np.empty((len(triangles), 4))
    table, lighting = scene_lighting(scene, draw.material, view)
    _face_lighting(np.ascontiguousarray(vertex.world_positions(draw.mesh.positions, draw.world)),
                   np.ascontiguousarray(triangles, np.int64), np.ascontiguousarray(base), table, tuple(lighting),
                   out)
    return out


def flat_corner_colors(scene, draw, base: np.ndarray, triangles: np.ndarray,
                       view: Viewing | None = None) -> np.ndarray:
    """Flat shading's colour of the draw's mesh triangles ``triangles`` (K,)
    as the kernels read it: (K, 3, 4), the colour of
    `softras.pipeline.render.flat_colors` (face normal, centroid and
    provoking vertex, straight) at corner 0 and zeros at corners 1 and 2
    (`softras.kernels.interpolate._lane_words` with ``flat``).  base : (V, 4)
    the straight vertex colours times the material's.  The stages light the
    same source triangles of the visible set-up triangles
    (`face_colors`: their operations, compiled; view as there)."""
    out = np.zeros((len(triangles), 3, 4))
    out[:, 0] = face_colors(scene, draw, base, draw.mesh.indices[triangles], view)
    return out
