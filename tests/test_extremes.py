"""Numerical extremes (docs/numerics.md): the scenes/extreme_*.json scenes against analytic answers.

tests/test_scenes.py already compares every extreme scene with glref within
its tolerance (and exact precision with gl precision).  Here each scene is
also checked against an answer computed independently of both renderers:
ray casting in float64 for the perspective scenes, the geometry the scene was
built from (scripts/make_extreme_scenes.py) for the rest.  Each check runs on
softras gl precision, softras exact precision and, where marked ``gl``, glref.

Ambiguity rule for coverage (used by the ray-casting checks): a pixel is
*determined* when rays through its centre and through 8 points on a circle of
radius 1/128 px around it (twice GL's 1/256-px snapping step) all hit the same
triangle; only determined pixels are compared.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import softras
from conftest import REPO, SCENES, load_script
from softras.pipeline import clip as clip_stage

make = load_script("make_extreme_scenes")

RENDERERS = {
    "gl": lambda scene: softras.render(scene, precision="gl"),
    "exact": lambda scene: softras.render(scene, precision="exact"),
    "glref": lambda scene: softras.render(scene, backend="gl"),
}
RENDERER_PARAMS = [pytest.param(RENDERERS["gl"], id="gl"), pytest.param(RENDERERS["exact"], id="exact"),
                   pytest.param(RENDERERS["glref"], id="glref", marks=pytest.mark.gl)]


def load(name: str):
    return softras.load_scene(SCENES / f"extreme_{name}.json")


def rgba8(color) -> np.ndarray:
    return np.rint(np.clip(np.asarray(color, np.float64), 0, 1) * 255).astype(np.uint8)


# --------------------------------------------------------------------------- ray casting


def ray_cast(scene, offsets=((0.0, 0.0),)):
    """Nearest triangle along the ray through each pixel, in float64.

    Returns (ids (K, H, W) int, -1 = no hit; colours (T, 4) straight RGBA of
    each triangle's first vertex times its material colour), one id image per
    offset (pixels, GL y up) from the pixel centre.  A ray runs from the near
    plane (s = 0) to the far plane (s = 1), unprojected through the inverse
    of projection @ view, so only hits between the planes count.
    """
    width, height = scene.width, scene.height
    inverse = np.linalg.inv(scene.camera.projection @ scene.camera.view)
    triangles, colours = [], []
    for draw in scene.draws:
        mesh = draw.mesh
        world = np.c_[mesh.positions, np.ones(len(mesh.positions))] @ draw.world.T
        triangles.append(world[:, :3][mesh.indices])
        vertex_colours = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
        colours.append((vertex_colours * draw.material.color)[mesh.indices[:, 0]])
    triangles, colours = np.concatenate(triangles), np.concatenate(colours)
    rows, cols = np.mgrid[0:height, 0:width]
    gl_rows = height - 1 - rows
    out = []
    for ox, oy in offsets:
        x_ndc = 2 * (cols + 0.5 + ox) / width - 1
        y_ndc = 2 * (gl_rows + 0.5 + oy) / height - 1

        def unproject(z_ndc):
            p = np.stack([x_ndc, y_ndc, np.full_like(x_ndc, z_ndc), np.ones_like(x_ndc)], -1) @ inverse.T
            return p[..., :3] / p[..., 3:]

        origin = unproject(-1.0)
        direction = unproject(1.0) - origin
        nearest = np.full((height, width), np.inf)
        ids = np.full((height, width), -1)
        for k, (a, b, c) in enumerate(triangles):      # Moller-Trumbore
            e1, e2 = b - a, c - a
            p = np.cross(direction, e2)
            det = p @ e1
            with np.errstate(divide="ignore", invalid="ignore"):
                t_vec = origin - a
                u = np.einsum("hwk,hwk->hw", t_vec, p) / det
                q = np.cross(t_vec, e1)
                v = np.einsum("hwk,hwk->hw", direction, q) / det
                s = (q @ e2) / det
                hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (s >= 0) & (s <= 1) & (s < nearest)
            nearest[hit] = s[hit]
            ids[hit] = k
        out.append(ids)
    return np.array(out), colours


def ring(radius: float):
    """The pixel centre and 8 points on a circle of ``radius`` pixels around it."""
    return [(0.0, 0.0)] + [(radius * math.cos(a), radius * math.sin(a)) for a in np.arange(8) * math.pi / 4]


def expected_image(scene, ids, colours):
    background = rgba8(scene.background)
    premultiplied = np.concatenate([colours[:, :3] * colours[:, 3:], colours[:, 3:]], axis=1)
    return np.where((ids >= 0)[..., None], rgba8(premultiplied)[ids], background)


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_eye_plane_and_behind_the_eye_match_ray_casting(render):
    """Vertices with clip w = 0 and w < 0: every determined pixel is the ray-cast triangle."""
    scene = load("eye_plane")
    ids, colours = ray_cast(scene, ring(1 / 128))
    determined = (ids == ids[0]).all(axis=0)
    assert determined.mean() > 0.99
    image = render(scene)
    wrong = (image != expected_image(scene, ids[0], colours)).any(axis=-1) & determined
    assert not wrong.any(), f"{wrong.sum()} determined pixels differ from ray casting"
    # The triangle through the eye is seen edge-on and the one behind is culled.
    through_eye = [k for k, d in enumerate(scene.draws) if d.name in ("through_eye", "all_behind")]
    assert not np.isin(ids[0], through_eye).any()


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_huge_coordinates_cover_what_ray_casting_covers(render):
    """Coordinates up to 1e7.  Exact precision: every determined pixel is the
    ray-cast triangle.  gl precision and GL (float32, llvmpipe's clipper): the
    covered area is right to 2 px (ring of radius 2 px) away from the
    viewport border; at the border, clipping the ceiling (vertices 1e7 away)
    against the left plane in float32 leaves a 2-px gap at x = 0..1 -- GL's
    own arithmetic, reproduced bit for bit (tests/test_scenes.py)."""
    scene = load("huge_coordinates")
    image = render(scene)
    if render is not RENDERERS["exact"]:
        ids, _ = ray_cast(scene, ring(2.0))
        border = np.zeros(image.shape[:2], bool)
        border[:2], border[-2:], border[:, :2], border[:, -2:] = True, True, True, True
        assert_coverage(scene, image, ids, ~border)
        return
    ids, colours = ray_cast(scene, ring(1 / 128))
    assert_coverage(scene, image, ids)
    determined = (ids == ids[0]).all(axis=0)
    wrong = (image != expected_image(scene, ids[0], colours)).any(axis=-1) & determined
    assert not wrong.any(), f"{wrong.sum()} determined pixels differ from ray casting"


@pytest.mark.gl
def test_huge_side_wall_float32_is_gls_float32():
    """A wall with vertices 1e7 away, one on the eye plane, meeting the ceiling:
    float32 (GL) moves its edges by up to a few pixels and gets the ceiling's
    depth more than 10 % wrong near the top-left corner (its vertices lie 1e7
    either side of the eye).  softras gl reproduces GL there bit for bit;
    exact precision gets the ray-cast picture."""
    scene = softras.load_scene(make.huge_coordinates(side_wall=True) | {"description": ""})
    soft, gl = softras.render(scene), softras.render(scene, backend="gl")
    assert (soft == gl).all()
    ids, colours = ray_cast(scene, ring(1 / 128))
    determined = (ids == ids[0]).all(axis=0)
    exact = softras.render(scene, precision="exact")
    assert not ((exact != expected_image(scene, ids[0], colours)).any(axis=-1) & determined).any()
    assert (soft != exact).any(axis=-1).sum() > 50          # float32 really is visibly off here


def assert_coverage(scene, image, ids, where=True):
    """Pixels every ray of the ring hits are drawn; pixels no ray hits are background."""
    background = (image == rgba8(scene.background)).all(axis=-1)
    assert not (background & (ids >= 0).all(axis=0) & where).any()
    assert not (~background & (ids < 0).all(axis=0) & where).any()


def test_huge_coordinates_with_a_guard_band_in_fixed_point():
    """gl precision with guard-band clipping keeps +-8192 px around the viewport
    in 1/256-px fixed point (raster values up to ~2^22, edge products ~2^45:
    no int64 overflow): coverage is still the ray-cast one, to 2 px (float32
    vertex positions ~1e7 / w carry ~0.6 px of rounding)."""
    scene = load("huge_coordinates")
    ids, _ = ray_cast(scene, ring(2.0))
    assert_coverage(scene, softras.render(scene, precision="gl", clipping="guard_band"), ids)


def test_clipping_starts_from_the_end_nearer_the_plane():
    """Mesa's draw_pipe_clip.c interpolates a new vertex from the edge end
    nearer the plane.  From the far outside end (x = 1.3e7) the float32 result
    would be off by ~1 clip unit; from the inside end it is exact to float32.
    Edge (0, 0.5, z, 5) -> (1.3e7, 1.3e7, z, 5) against the right plane x <= w."""
    inside = np.array([0.0, 0.5, 1.0, 5.0])
    outside = np.array([1.3e7, 1.3e7, 1.0, 5.0])
    third = np.array([0.0, 4.0, 1.0, 5.0])
    points, _ = clip_stage.clip_polygon(np.array([inside, outside, third]), np.eye(3),
                                        clip_stage.FRUSTUM_PLANES[:1], "gl")
    t = 5.0 / 1.3e7                                     # the fraction of each edge where x = w = 5
    new = points[np.isclose(points[:, 0], 5.0, atol=1e-3), 1]
    exact = [0.5 + t * (1.3e7 - 0.5), 4.0 + t * (1.3e7 - 4.0)]     # y on both crossing edges
    assert np.abs(np.sort(new) - exact).max() < 2e-6                # float32 steps at 9 are 1e-6


# --------------------------------------------------------------------------- depth at near 1e-5, far 1e5


def window_depth(n: float, f: float, d: float) -> float:
    """GL window depth of a point at eye distance d (gluPerspective, float64)."""
    z_ndc = ((f + n) * d - 2 * f * n) / ((f - n) * d)
    return (z_ndc + 1) / 2


def near_far_classes() -> list[str]:
    """For each column, the 24-bit depths of the two quads (d and d (1 + 1e-3))
    predict the picture: well apart -> the near (green) quad shows; equal ->
    the far (red) quad, drawn first, stays (LESS fails on ties); both at
    2^24 - 1 (z_w rounds to 1.0) -> nothing passes LESS against the clear."""
    n, f = 1e-5, 1e5
    scale = 2 ** 24 - 1
    classes = []
    for d in make.NEAR_FAR_DISTANCES:
        near = window_depth(n, f, d) * scale
        far = window_depth(n, f, d * (1 + make.NEAR_FAR_SEPARATION)) * scale
        if round(near) >= scale:
            classes.append("background")
        elif far - near > 4:                      # float32 rounding moves each by < 1 step
            classes.append("green")
        elif far - near < 0.05 and abs(near - round(near)) < 0.3:
            classes.append("red")
        else:
            classes.append("unpredicted")
    return classes


def test_near_far_depth_classes_are_what_24_bits_predict():
    assert near_far_classes() == ["green", "green", "green", "red", "background"]


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_near_far_columns(render):
    scene = load("near_far")
    image = render(scene)
    classes = near_far_classes()
    if render is RENDERERS["exact"]:
        classes = ["green"] * 5                   # float64 depth resolves every pair
    row = scene.height // 2
    colour = {"green": (0, 255, 0), "red": (255, 0, 0), "background": (0, 0, 0)}
    for i, expected in enumerate(classes):
        x = int(round((-0.8 + 0.4 * i + 1) / 2 * scene.width))          # column centre
        assert tuple(image[row, x, :3]) == colour[expected], (i, expected, image[row, x])


# --------------------------------------------------------------------------- coverage by construction


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_sliver_fan_is_watertight(render):
    """2000 slivers, additive 64 per cover: every pixel centre inside the
    2000-gon (by more than 1/128 px) is covered exactly once, every one
    outside never, and no pixel anywhere twice (no 128)."""
    scene = load("sliver_fan")
    image = render(scene)
    red = image[..., 0]
    assert set(np.unique(red)) <= {0, 64}
    centre, radius, count = np.array([64.5, 48.5]), 45.0, 2000
    angles = 2 * np.pi * np.arange(count) / count
    rim = centre + radius * np.stack([np.cos(angles), np.sin(angles)], 1)
    rows, cols = np.mgrid[0:scene.height, 0:scene.width]
    p = np.stack([cols + 0.5, scene.height - 1 - rows + 0.5], -1)          # GL window coordinates
    # Signed distance to the polygon: min over its edges of the distance to each edge line.
    a, b = rim, np.roll(rim, -1, axis=0)
    normal = np.stack([(b - a)[:, 1], -(b - a)[:, 0]], 1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)                 # outward
    outside = np.max(np.einsum("hwk,ek->hwe", p, normal) - np.einsum("ek,ek->e", a, normal), axis=-1)
    assert (red[outside < -1 / 128] == 64).all()
    assert (red[outside > 1 / 128] == 0).all()
    assert red[scene.height - 1 - 48, 64] == 64                              # all 2000 meet here


@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_degenerate_triangles_draw_nothing(render, samples):
    scene = softras.load_scene(dict(make.degenerate(), samples=samples))
    image = render(scene)
    assert (image == rgba8([0.1, 0.2, 0.3, 1])).all()


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_subpixel_triangles_cover_exactly_their_centres(render):
    scene = load("subpixel")
    _, _, covered = make.subpixel_triangles()
    expected = np.zeros((scene.height, scene.width), np.uint8)
    for i, j in covered:
        expected[scene.height - 1 - j, i] = 64
    assert (render(scene)[..., 0] == expected).all()


def test_subpixel_triangle_below_the_snapping_step():
    """A triangle 1/1000 px across around a pixel centre: exact precision draws
    that pixel; gl precision snaps all three vertices to the same 1/256-px
    point (zero area) and draws nothing, as GL does."""
    r = 1e-3
    data = {"softras_scene": 1, "width": 4, "height": 4, "camera": make.pixel_camera(4, 4),
            "nodes": [{"mesh": {"positions": [[1.5 + r * math.cos(a), 2.5 + r * math.sin(a), 0]
                                              for a in (0, 2.1, 4.2)]}}]}
    scene = softras.load_scene(data)
    assert softras.render(scene, precision="exact")[1, 1, 0] == 255
    assert (softras.render(scene, precision="gl")[..., 0] == 0).all()


# --------------------------------------------------------------------------- textures at the LOD extremes


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_texture_strip_16384_is_the_gradient(render):
    """A box-filtered linear gradient is linear: at lambda = 7 each pixel is the
    gradient at its centre.  Allowance 3/255: each of the 7 mip levels rounds
    its texels to bytes (<= 1/2 each, mostly cancelling), plus 8-bit filter
    weights in gl precision (measured: <= 2)."""
    scene = load("texture_strip")
    image = render(scene).astype(int)
    s = (np.arange(scene.width) + 0.5) / scene.width
    expected = np.stack([255 * (1 - s), 0 * s, 255 * s], 1)
    for rows in (slice(0, 32), slice(32, 64)):                               # strip_s, strip_t
        assert np.abs(image[rows, :, :3] - expected[None]).max() <= 3


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_one_texel_texture_everywhere(render):
    scene = load("texture_1x1")
    image = render(scene)
    covered = (image != rgba8(scene.background)).any(axis=-1)
    assert covered.mean() > 0.3
    assert (image[covered] == rgba8(make.TEXEL_1X1)).all()


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_magnification_by_1000(render):
    """Nearest: the texel edge u = 2 falls at x = 29.5 px (u = 1.97 + x / 1000),
    the edge v = 3 at 20 px below the top.  Linear: the bilinear ramp of the
    four texels around (1.5, 0.5), within 2/255 (gl: 1/256-texel steps)."""
    scene = load("texture_magnify")
    image = render(scene).astype(int)
    from softras.pipeline import texture
    texels = texture.prepare(scene.textures["linear"]).levels[0].astype(float)   # (4, 4, 4) premultiplied
    size = 4
    u = make.MAGNIFY_NEAREST_UV0[0] + (np.arange(64) + 0.5) / make.MAGNIFY
    v = make.MAGNIFY_NEAREST_UV0[1] + (np.arange(96) + 0.5) / make.MAGNIFY       # image row 0 = v smallest
    nearest = texels[np.floor(v).astype(int) % size][:, np.floor(u).astype(int) % size]
    assert (image[:, :64] == nearest).all()
    u = make.MAGNIFY_LINEAR_UV0[0] + (np.arange(64) + 0.5) / make.MAGNIFY - 0.5
    v = make.MAGNIFY_LINEAR_UV0[1] + (np.arange(96) + 0.5) / make.MAGNIFY - 0.5
    i0, j0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = (u - i0)[None, :, None], (v - j0)[:, None, None]
    t = lambda j, i: texels[(j % size)][:, (i % size)]
    bilinear = ((1 - fv) * ((1 - fu) * t(j0, i0) + fu * t(j0, i0 + 1))
                + fv * ((1 - fu) * t(j0 + 1, i0) + fu * t(j0 + 1, i0 + 1)))
    assert np.abs(image[:, 64:] - bilinear).max() <= 2


# --------------------------------------------------------------------------- colour extremes


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_alpha_near_zero(render):
    """Each column is the blend equation on premultiplied values, rounded once
    (within 1/255); nothing is divided by alpha, so nothing can be NaN."""
    scene = load("alpha")
    image = render(scene).astype(int)
    dst = np.array([0.2, 0.4, 0.6, 1.0])
    dst = np.r_[dst[:3] * dst[3], dst[3]]
    for k, (a, blend) in enumerate(make.ALPHA_COLUMNS):
        src = np.array([a, a, a, a])                       # white, premultiplied
        result = {"over": src + (1 - a) * dst, "over_straight": src * a + (1 - a) * dst,
                  "none": src, "add": src + dst}[blend]
        column = image[:, 16 * k:16 * k + 16].reshape(-1, 4)
        assert np.abs(column - np.rint(np.clip(result, 0, 1) * 255)).max() <= 1, (k, a, blend, column[0])
    comparison = softras.compare(render(scene), render(scene))
    assert comparison.passed and np.isfinite(comparison.ssim) and np.isfinite(comparison.ssim_map).all()


def test_compare_of_fully_transparent_images_is_finite():
    zero = np.zeros((8, 8, 4), np.uint8)
    result = softras.compare(zero, zero)
    assert result.passed and result.ssim == pytest.approx(1.0) and np.isfinite(result.ssim_map).all()


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_colours_outside_0_1_are_clamped(render):
    """RGBA8 UNORM: a colour above 1 is stored as 255 and one below 0 as 0
    (GL 4.5 section 17.3.6: fixed-point colour buffers clamp)."""
    scene = load("overbright")
    image = render(scene)
    expect = {0: (255, 255, 255, 255),              # Phong lit by colour 4: ~3.65 per channel
              32: (255, 255, 255, 255),             # 0.75 + 0.75 and 1 + 1
              64: (64, 0, 64, 0),                   # src - dst = (0.25, -0.25, 0.25, 0)
              96: (0, 64, 0, 0)}                    # dst - src = (-0.25, 0.25, -0.25, 0)
    for x0, value in expect.items():
        block = image[:, x0:x0 + 32].reshape(-1, 4)
        assert (block == value).all(), (x0, block[0])


@pytest.mark.parametrize("render", RENDERER_PARAMS)
def test_one_by_one_framebuffer(render):
    scene = load("1x1")
    assert render(scene).tolist() == [[[0, 153, 255, 255]]]
    if render is not RENDERERS["exact"]:
        four = softras.load_scene(dict(make.one_pixel(), samples=4))
        image = render(four)
        assert image.shape == (1, 1, 4) and image[0, 0, 3] == 255


@pytest.mark.gl
def test_4096_square_framebuffer():
    """4096 x 4096: a rectangle with edges between pixel centres and a
    vertex-coloured triangle cover the pixels GL covers, and the rectangle
    exactly those whose centres are inside it (x in [1000.25, 3000.5), y in
    [2000.75, 3500.25)); colours within 1/255 of GL's (measured: 461 of the
    triangle's pixels differ by 1/255)."""
    side = 4096
    data = {"softras_scene": 1, "width": side, "height": side, "camera": make.pixel_camera(side, side),
            "nodes": [{"mesh": {**make.quad(1000.25, 2000.75, 3000.5, 3500.25, 0.5),
                                "colors": [[1, 0, 0]] * 4}},
                      {"mesh": {"positions": [[10, 10, 0], [4000, 100, 0], [200, 1500, 0]],
                                "colors": [[0, 0, 1], [0, 1, 0], [1, 1, 1]]}}]}
    scene = softras.load_scene(data)
    soft = softras.render(scene)
    gl = softras.render(scene, backend="gl")
    assert soft.shape == (side, side, 4)
    assert np.abs(soft.astype(np.int16) - gl).max() <= 1
    assert ((soft[..., :3] > 0).any(axis=2) == (gl[..., :3] > 0).any(axis=2)).all()
    red = (soft[..., 0] == 255) & (soft[..., 1] == 0) & (soft[..., 2] == 0)
    rows = side - 1 - np.arange(side)                     # GL row of each image row
    xs = np.arange(side) + 0.5
    inside_x = (xs >= 1000.25) & (xs < 3000.5)
    inside_y = (rows + 0.5 >= 2000.75) & (rows + 0.5 < 3500.25)
    assert (red == (inside_y[:, None] & inside_x[None, :])).all()


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_a_lit_part_scaled_to_zero_out_of_view_draws_nothing(precision):
    """A Phong-lit part scaled to 0 (its world 3x3 has no inverse, so no
    normal transform) that the clipper drops leaves the picture as it is
    without it: the compiled path's once-a-pass normal rows
    (`softras.kernels.light.viewing`) give way to each draw's own rather
    than fail the pass."""
    grid = {"name": "b", "mesh": {"procedural": "grid", "cols": 1, "rows": 1}, "material": {"shading": "gouraud"}}
    hidden = {"name": "a", "scale": [0, 0, 0], "translate": [0, 0, 50],
              "mesh": {"procedural": "sphere", "segments": 8, "rings": 6}, "material": {"shading": "phong"}}
    base = {"softras_scene": 1, "width": 16, "height": 16, "lights": [{"type": "point", "position": [0, 0, 3]}]}
    alone = softras.render(softras.load_scene({**base, "nodes": [grid]}), precision=precision)
    both = softras.render(softras.load_scene({**base, "nodes": [hidden, grid]}), precision=precision)
    assert np.array_equal(both, alone)
