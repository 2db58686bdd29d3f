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
from softras.scene import texels
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
    from softras.renderer import render_scene
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


# ----------------------------------------------------------------------------- the vertex transform


NEAR, FAR = 0.5, 4.0
PERSPECTIVE = np.array([[1, 0, 0, 0], [0, 1, 0, 0],
                        [0, 0, -(FAR + NEAR) / (FAR - NEAR), -2 * FAR * NEAR / (FAR - NEAR)], [0, 0, -1, 0]])


def _stage_fragments(clip, width, height):
    """(triangle, x, GL row) of the pixels the triangles (n, 3, 4), clip space,
    cover through the readable clip, setup and rasterize stages (one sample)."""
    from softras.pipeline import rasterize, setup
    from softras.pipeline.clip import clip_triangles
    n = len(clip)
    offsets, unit = setup.sample_offsets(np.array([[0.5, 0.5]]), "gl")
    clipped = clip_triangles(clip.reshape(-1, 4), np.arange(3 * n).reshape(n, 3), precision="gl")
    tris = setup.setup_triangles(clipped.clip, width, height, offsets=offsets, unit=unit,
                                 generated=clipped.generated)
    frags = rasterize.rasterize(tris, offsets, unit)
    return clipped.source[tris.triangle[frags.tri]], frags.x, frags.y


def _snapped_corners(clip, width, height):
    """(n, 3, 2) the triangles' (n, 3, 4) clip-space corners in raster units,
    snapped (`softras.pipeline.setup.snap`): all that a triangle's coverage
    depends on here (one sample, nothing clipped or culled)."""
    from softras.pipeline import setup
    window, _ = setup.viewport_transform(clip, width, height, "gl")
    return setup.snap(window[..., :2])


def _coverage_keys(fragments, n, width):
    """(n, 3) per triangle: its pixel count, and the sum and sum of squares of
    the pixels' indices y * width + x (equal for two coverages here only when
    they are equal)."""
    triangle, x, y = fragments
    key = (y * width + x).astype(float)
    return np.stack([np.bincount(triangle, weights, n) for weights in (None, key, key * key)], axis=1)


def test_vertex_shader_sums_the_matrix_columns_in_order_like_gl():
    """Mutation ``vertex_sum_order``: ``u_mvp * vec4(p, 1)`` summed in another
    float32 order. softras and glref share no code here -- glref's shader does
    the product on GL's side -- but the stage test pins the order only against
    numpy's sum, i.e. against our own expectation; this asks GL.

    A rotated, scaled and translated view makes every matrix entry and
    product inexact in float32, so the order of the four terms changes clip
    coordinates by an ulp, and now and then a snapped vertex and the pixels
    covered. Of 1,000 random triangles inside the view of a 999 x 601 picture,
    those whose coverage ``x m0 + y m1 + z m2 + m3`` summed left to right
    (GLSL's column order, no fused multiply-add) and right to left would
    differ (24 here), the first 12 are drawn by GL, each adding its own bit:
    GL covers exactly what the left-to-right sum covers, the other order
    differs from GL on each, and both of softras's renderers match GL's
    picture exactly."""
    from softras.pipeline import vertex
    from softras.renderer import render_scene

    width, height, n = 999, 601, 1000
    rng = np.random.default_rng(20261123)
    rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    view = np.eye(4)
    view[:3, :3] = rotation * 1.7
    view[:3, 3] = rng.uniform(-3, 3, 3)
    w = rng.uniform(0.6, 3.0, size=(n, 3, 1))                     # eye space: in front, inside the frustum
    eye = np.concatenate([rng.uniform(-0.98, 0.98, size=(n, 3, 2)) * w, -w, np.ones((n, 3, 1))], axis=2)
    world = (np.linalg.inv(view) @ eye.reshape(-1, 4).T).T[:, :3].reshape(n, 3, 3)
    mvp = PERSPECTIVE @ view
    ours = vertex.to_clip(world.reshape(-1, 3), mvp, "gl").reshape(n, 3, 4)
    m, p = mvp.astype(np.float32), world.reshape(-1, 3).astype(np.float32)
    other = (m[:, 0] * p[:, 0:1] + (m[:, 1] * p[:, 1:2] + (m[:, 2] * p[:, 2:3] + m[:, 3])))
    other = other.astype(np.float64).reshape(n, 3, 4)
    # Only a triangle with a corner snapped elsewhere can cover other pixels
    # (40 of the 1,000 here): those rasterized (4.4 s for all 1,000).
    moved = np.nonzero((_snapped_corners(ours, width, height) != _snapped_corners(other, width, height))
                       .any(axis=(1, 2)))[0]
    keys = [_coverage_keys(_stage_fragments(c[moved], width, height), len(moved), width) for c in (ours, other)]
    differ = moved[np.nonzero((keys[0] != keys[1]).any(axis=1))[0]]
    assert len(differ) >= 12, f"only {len(differ)} triangles whose coverage depends on the order"
    chosen = differ[:12]
    nodes = [{"name": f"t{k}", "mesh": {"positions": tri.tolist(), "indices": [[0, 1, 2]]},
              "material": {"color": [float(c == k // 8) * (1 << (k % 8)) / 255 for c in range(3)] + [1.0]},
              "blend": "add", "depth_test": False} for k, tri in enumerate(world[chosen])]
    scene = load_scene({"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
                        "camera": {"projection_matrix": PERSPECTIVE.ravel().tolist(),
                                   "view_matrix": view.ravel().tolist()}, "nodes": nodes})
    gl = glref.render(scene)
    gl_masks = np.stack([(gl[..., k // 8] >> (k % 8)) & 1 for k in range(12)]).astype(bool)
    for name, clip, same in (("left to right", ours, True), ("right to left", other, False)):
        triangle, x, y = _stage_fragments(clip[chosen], width, height)
        masks = np.zeros((12, height, width), bool)
        masks[triangle, height - 1 - y, x] = True
        equal = (masks == gl_masks).all(axis=(1, 2))
        assert equal.all() if same else not equal.any(), f"{name}: equal to GL for triangles {chosen[equal]}"
    for path, image in (("fast path", softras.render(scene)), ("stages", render_scene(scene, fast_path=False))):
        assert (image == gl).all(), f"{path}: {int((image != gl).any(axis=2).sum())} pixels differ from GL"


@pytest.mark.parametrize("backend", ["soft", "gl"])
@pytest.mark.parametrize("fov_y,aspect,width,height", [(90.0, 1.0, 64, 64), (60.0, 2.0, 96, 48)])
def test_perspective_camera_frames_a_quad_as_glu_perspective_says(backend, fov_y, aspect, width, height):
    """Mutation ``projection_full_angle`` (the camera's matrix, which both
    renderers take from the scene model): gluPerspective's f = cot(fov_y / 2).
    A quad at distance d spanning half of tan(fov_y / 2) d (times the aspect
    ratio across) covers the middle half of the picture on both axes: its
    edges fall on pixel boundaries, so exactly the pixels of the middle half."""
    t, d = np.tan(np.radians(fov_y) / 2), 2.0
    hx, hy = 0.5 * d * t * aspect, 0.5 * d * t
    quad = {"positions": [[-hx, -hy, -d], [hx, -hy, -d], [hx, hy, -d], [-hx, hy, -d]], "indices": [[0, 1, 2], [0, 2, 3]]}
    scene = load_scene({"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
                        "camera": {"projection": "perspective", "fov_y": fov_y, "aspect": aspect, "near": 0.5,
                                   "far": 10, "eye": [0, 0, 0], "target": [0, 0, -1]},
                        "nodes": [{"mesh": quad, "material": {"color": [1, 1, 1, 1]}}]})
    covered = softras.render(scene, backend=backend)[..., 0] > 0
    expected = np.zeros((height, width), bool)
    expected[height // 4: 3 * height // 4, width // 4: 3 * width // 4] = True
    assert (covered == expected).all(), f"{int((covered != expected).sum())} pixels differ from the hand count"
