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
from softras.kernels.lanes import (_LF_LIT, _LF_NDL, _LF_NRM, _LF_POS, _LF_SPEC, _LF_TEX, _LF_VIEW, _LF_W,
                                   _LI_WORD)
from softras.pipeline import fragment, vertex

# The eye (world space) and the material's Blinn-Phong terms, as scalars.
Lighting = namedtuple("Lighting", ["eye_x", "eye_y", "eye_z", "ambient", "diffuse", "specular", "shininess"])

# Per light, one float64 row of the light table: the light vector
# (`softras.pipeline.fragment.light_vectors`: position and 1, or minus the
# direction and 0), then the colour.
_L_VECTOR, _L_COLOR, _NL = 0, 4, 7

# `phong_inputs` of a draw that is not Phong-shaded.
NO_LIGHTING = (np.zeros((0, 6)), np.zeros((0, _NL)), Lighting(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def phong_inputs(scene, draw) -> tuple[np.ndarray, np.ndarray, Lighting]:
    """What a Phong-shaded triangle draw's kernels read: per vertex the
    world position and the (not unit) world normal (V, 6) float64, the
    inputs of `softras.pipeline.render.phong_attributes` (the set-up takes
    them to the corners), and the scene's `light_table` and `Lighting`."""
    mesh = draw.mesh
    vertex_values = np.ascontiguousarray(np.concatenate(
        [vertex.world_positions(mesh.positions, draw.world),
         vertex.world_normals(mesh.normals, draw.world, unit=False)], axis=1))
    return (vertex_values,
            *light_table(scene.lights, vertex.eye_position(scene.camera.view), draw.material))


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


@numba.njit(cache=True, error_model="numpy", inline="always")
def _power(x, y):
    """``numpy.power(x, y)`` of float64 values as numpy computes it: its own
    results for the exponents it special-cases (2: ``x * x``, 0.5:
    ``sqrt(x)``, -1: ``1 / x``; C's ``pow`` gives other last bits there
    now and then), C's ``pow`` otherwise (which numba calls too).
    tests/test_fastpath.py checks a table of exponents against numpy."""
    if y == 2.0:
        return x * x
    if y == 0.5:
        return math.sqrt(x)
    if y == -1.0:
        return 1.0 / x
    return x ** y


@numba.njit(cache=True, error_model="numpy", inline="always")
def _phong_colors(n, t, colors, lit, lf, lights, lighting):
    """The straight Phong-lit colour of the n lanes of triangle t into the
    _LF_LIT rows (r, g, b lit, a interpolated).

    Per lane, under its perspective weights (_LF_W rows): the straight
    colour (corner colours (T, 3, 4)), the world position and normal
    (lit (T, 3, 6): corner positions, then corner normals, not unit)
    interpolated and the normal normalised
    (`softras.pipeline.render.phong_attributes`), then
    `softras.pipeline.fragment.blinn_phong` with the light table (L, _NL)
    and the `Lighting`.  In passes over the lanes, so that all but the
    power compile to SIMD: the interpolation; per light its vectors, then
    the power (a call per lane), then its term."""
    eye_x, eye_y, eye_z, ambient, diffuse, specular, shininess = lighting
    cc = _corner_colors(colors, t)
    px3 = (lit[t, 0, 0], lit[t, 1, 0], lit[t, 2, 0])
    py3 = (lit[t, 0, 1], lit[t, 1, 1], lit[t, 2, 1])
    pz3 = (lit[t, 0, 2], lit[t, 1, 2], lit[t, 2, 2])
    nx3 = (lit[t, 0, 3], lit[t, 1, 3], lit[t, 2, 3])
    ny3 = (lit[t, 0, 4], lit[t, 1, 4], lit[t, 2, 4])
    nz3 = (lit[t, 0, 5], lit[t, 1, 5], lit[t, 2, 5])
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
    for j in range(lights.shape[0]):
        ox, oy, oz, ow = (lights[j, _L_VECTOR], lights[j, _L_VECTOR + 1], lights[j, _L_VECTOR + 2],
                          lights[j, _L_VECTOR + 3])
        cr, cg, cb = lights[j, _L_COLOR], lights[j, _L_COLOR + 1], lights[j, _L_COLOR + 2]
        for l in range(n):
            lx, ly, lz = _unit(ox - lf[_LF_POS, l] * ow, oy - lf[_LF_POS + 1, l] * ow, oz - lf[_LF_POS + 2, l] * ow)
            nx, ny, nz = lf[_LF_NRM, l], lf[_LF_NRM + 1, l], lf[_LF_NRM + 2, l]
            hx, hy, hz = _unit(lx + lf[_LF_VIEW, l], ly + lf[_LF_VIEW + 1, l], lz + lf[_LF_VIEW + 2, l])
            n_dot_h = _dot(nx, ny, nz, hx, hy, hz)
            lf[_LF_NDL, l] = _dot(nx, ny, nz, lx, ly, lz)
            lf[_LF_SPEC, l] = n_dot_h if (n_dot_h >= 0.0 or n_dot_h != n_dot_h) else 0.0   # numpy.maximum(., 0)
        for l in range(n):
            lf[_LF_SPEC, l] = specular * _power(lf[_LF_SPEC, l], shininess)
        for l in range(n):
            w = (lf[_LF_W, l], lf[_LF_W + 1, l], lf[_LF_W + 2, l])
            n_dot_l, spec = lf[_LF_NDL, l], lf[_LF_SPEC, l]
            lit_here = n_dot_l > 0
            term_r = cr * (diffuse * n_dot_l * _mix(w, cc.r) + spec)
            term_g = cg * (diffuse * n_dot_l * _mix(w, cc.g) + spec)
            term_b = cb * (diffuse * n_dot_l * _mix(w, cc.b) + spec)
            lf[_LF_LIT, l] = lf[_LF_LIT, l] + (term_r if lit_here else 0.0)
            lf[_LF_LIT + 1, l] = lf[_LF_LIT + 1, l] + (term_g if lit_here else 0.0)
            lf[_LF_LIT + 2, l] = lf[_LF_LIT + 2, l] + (term_b if lit_here else 0.0)


@numba.njit(error_model="numpy")
def _phong_words(n, t, colors, lit, lf, li, lights, lighting, textured):
    """The fragment colour of the n lanes of triangle t, Phong-shaded, as
    llvmpipe's bytes: the lit colour (`_phong_colors`) times the _LF_TEX
    texel when textured (`softras.kernels.interpolate._color_word`), one
    RGBA8 word each into the _LI_WORD row."""
    _phong_colors(n, t, colors, lit, lf, lights, lighting)
    for l in range(n):
        texel = RGBA(1.0, 1.0, 1.0, 1.0)
        if textured:
            texel = RGBA(lf[_LF_TEX, l], lf[_LF_TEX + 1, l], lf[_LF_TEX + 2, l], lf[_LF_TEX + 3, l])
        li[_LI_WORD, l] = _color_word(lf[_LF_LIT, l], lf[_LF_LIT + 1, l], lf[_LF_LIT + 2, l], lf[_LF_LIT + 3, l],
                                      texel)
