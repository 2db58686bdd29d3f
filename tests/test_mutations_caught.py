"""Tests added because a planted bug got past the suite (scripts/mutate.py, docs/testing.md).

Each test names the mutation it catches. Most of these mutations live in code
that both of softras's renderers run (the stages and the fast path), or that
softras and glref share, so the equality tests between renderers cannot see
them: these tests ask GL (Mesa llvmpipe here), or pin a value computed by hand
from the GL specification.
"""

from __future__ import annotations

import numpy as np
import pytest

import glref
import softras
from softras import texels
from softras.scene import load_scene

pytestmark = pytest.mark.gl


def ortho_scene(width, height, nodes, background=(0, 0, 0, 0), samples=1):
    """A scene whose orthographic camera maps world x, y to window x, y (y up)."""
    return load_scene({
        "softras_scene": 1, "width": width, "height": height, "background": list(background),
        "samples": samples,
        "camera": {"projection": "orthographic", "left": 0, "right": width, "bottom": 0, "top": height,
                   "near": -1, "far": 1},
        "nodes": nodes,
    })


def test_texel_premultiplication_is_gls_own():
    """Mutation ``premultiply_truncates``.

    softras premultiplies a texture's straight texels once, at load, as
    ``round(c a / 255)``; glref uploads those same bytes, so a wrong table
    changes both renderers alike. GL's own premultiplication is the one its
    fragment shader does to a straight colour (glref's unlit.frag:
    ``vec4(c.rgb * c.a, c.a)``, stored to RGBA8 by GL 4.6 section 2.3.5.2's
    float -> normalized conversion, round to nearest). Quads whose vertex
    colours make pixel (i, j) the straight colour (i, i, i, j) / 255 reads
    back round(i j / 255) there; the texel table must hold the same byte for
    every (c, a) pair. (c a / 255 is never a half, and at least 0.5/255 of a
    byte from one: the float32 interpolation, ~1e-7, cannot tip it.)"""
    size = 256
    lo, hi, edge = 0.5, size - 0.5, size + 0.5       # pixel centres lo..hi; vertex colours in [0, 1]
    positions, colors, indices = [], [], []
    # The ramp's quad (x, y in [lo, hi]: colour (x - 1/2) / 255 and alpha (y - 1/2) / 255) and
    # the strips beyond hi (value 1): a centre on the ramp's right or top edge (excluded there,
    # GL's fill rule) lies on a strip's left or bottom edge (included).
    for x0, x1 in ((lo, hi), (hi, edge)):
        for y0, y1 in ((lo, hi), (hi, edge)):
            base = len(positions)
            for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
                positions.append([x, y, 0.0])
                value, alpha = min((x - 0.5) / 255.0, 1.0), min((y - 0.5) / 255.0, 1.0)
                colors.append([value, value, value, alpha])
            indices += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    mesh = {"positions": positions, "indices": indices, "colors": colors}
    scene = ortho_scene(size, size, [{"mesh": mesh, "material": {"color": [1, 1, 1, 1]}}])
    picture = glref.render(scene)[::-1]                      # row j = window row j = alpha j
    c, a = np.meshgrid(np.arange(256), np.arange(256))
    straight = np.stack([c, c, c, a], axis=-1).astype(np.uint8)
    assert (picture[..., 3] == a).all()                     # the colours arrived as intended
    np.testing.assert_array_equal(texels.premultiply_rgba8(straight), picture)


WRAPS = ("repeat", "clamp_to_edge", "mirrored_repeat")


@pytest.mark.parametrize("wrap_s,wrap_t", [(s, t) for s in WRAPS for t in WRAPS if s != t])
@pytest.mark.parametrize("image_filter", ["nearest", "linear"])
def test_different_wraps_on_s_and_t_match_gl(wrap_s, wrap_t, image_filter):
    """Mutation ``glref_wrap_t_from_s``: glref set GL_TEXTURE_WRAP_T from wrap_s,
    and every scene and test used one wrap mode on both axes.

    GL 4.6 section 8.14.2: each coordinate wraps by its own mode
    (TEXTURE_WRAP_S for s, TEXTURE_WRAP_T for t). A square whose (s, t) run
    over [-1.5, 2.5] on both axes, each ordered pair of different modes:
    softras (gl precision) and GL agree to 1/255 on >= 99.9 % of the pixels
    (test_texture_gl's criterion; with mirrored_repeat, llvmpipe's float
    filter path, 1/255 apart on ~14 % of these magnified pixels), so an axis
    wrapped by the other's mode (differences up to 255 on the noise) shows."""
    size = 64
    scene = load_scene({**_scene_dict(size), "textures": {"t": {
        "procedural": "noise", "size": [8, 4], "seed": 3, "wrap_s": wrap_s, "wrap_t": wrap_t,
        "min_filter": image_filter, "mag_filter": image_filter}}})
    soft = softras.render(scene, precision="gl")
    gl = glref.render(scene)
    diff = np.abs(soft.astype(int) - gl.astype(int)).max(axis=2)
    assert (diff > 1).mean() <= 0.001, \
        f"{wrap_s}/{wrap_t} {image_filter}: {(diff > 1).sum()} pixels differ by more than 1 (max {diff.max()})"


def _scene_dict(size):
    return {"softras_scene": 1, "width": size, "height": size, "background": [0, 0, 0, 1],
            "camera": {"projection": "orthographic", "left": 0, "right": size, "bottom": 0, "top": size,
                       "near": -1, "far": 1},
            "nodes": [{"mesh": {"positions": [[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]],
                                "indices": [[0, 1, 2], [0, 2, 3]],
                                "uvs": [[-1.5, 2.5], [2.5, 2.5], [2.5, -1.5], [-1.5, -1.5]]},
                       "material": {"texture": "t"}}]}


def test_depth_is_rounded_to_nearest_at_24_bits():
    """Mutations ``depth_round_floor`` (the stages) and ``fast_depth_round_floor``
    (the fast path): the window depth rounded down to the 24-bit buffer.

    GL 4.6 section 2.3.5.2 (float -> normalized fixed point): the stored depth
    is z_w (2^24 - 1) rounded to the nearest integer. A window depth
    z_w = k / 2^24 with 2^21 <= k < 2^22 (z_w in [1/8, 1/4)) gives
    k (1 - 2^-24) = k - z_w: nearest k, rounded down k - 1. llvmpipe stores k
    too (it multiplies by 2^24 - 1 in float32, whose steps are 1/4 there:
    k - 1/4, then rounds to the nearest integer). Each column draws a
    constant-depth quad at k / 2^24 (test "less"), then one at (k + 1/2) / 2^24
    with the test "equal" (k + 1/2 - z_w, about k + 0.31: k however it is
    rounded, llvmpipe's float32 product k + 1/4): GL draws the second
    everywhere; a depth rounded down does not. (The depths, and z_ndc =
    2 z_w - 1, are exact in float32 -- a step of 1/4 in z_w would not be --
    and the planes have slope 0, so no interpolation error enters: near other
    depths llvmpipe's float32 plane and double rounding part from the exact
    rounding softras models; docs/testing.md.)"""
    from softras.pipeline import render_scene
    columns, width, height = 16, 8, 8
    ks = [(1 << 21) + 131071 * j + 5 * j for j in range(columns)]
    assert all((1 << 21) <= k < (1 << 22) for k in ks)

    def quads(depths, color, test):
        positions, indices = [], []
        for j, zw in enumerate(depths):
            z = 1.0 - 2.0 * zw                    # orthographic near -1, far 1: z_w = (1 - z) / 2
            base = len(positions)
            positions += [[j * width, 0, z], [(j + 1) * width, 0, z], [(j + 1) * width, height, z],
                          [j * width, height, z]]
            indices += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
        return {"mesh": {"positions": positions, "indices": indices}, "material": {"color": color},
                "depth_test": test}

    first = [k / (1 << 24) for k in ks]
    second = [(k + 0.5) / (1 << 24) for k in ks]
    scene = ortho_scene(columns * width, height, [quads(first, [1, 0, 0, 1], "less"),
                                                  quads(second, [0, 1, 0, 1], "equal")],
                        background=(0, 0, 0, 1))
    green = np.array([0, 255, 0, 255], np.uint8)
    gl = glref.render(scene)
    assert (gl == green).all(), "GL did not store both depths as the same 24-bit value"
    for fast_path in (True, False):
        soft = render_scene(scene, precision="gl", fast_path=fast_path)
        wrong = np.nonzero((soft != green).any(axis=2).any(axis=0))[0] // width
        assert len(wrong) == 0, f"fast_path={fast_path}: the second quad fails the equal test in columns " \
                                f"{sorted(set(wrong.tolist()))}"
