"""Texture lookup bounds (softras.pipeline.texture_bounds): what any conformant GL may return.

Unit tests: the bounds contain softras's llvmpipe-precision and exact-precision
lookups for every filter / wrap pair, they are tight where GL leaves no room,
and each freedom (LOD range, min / mag switch, mip rounding, texel data)
widens them where it should.

Against OpenGL (marked ``gl``): every textured scene's picture from llvmpipe
and from softpipe (an independent GL 3.3 implementation; GALLIUM_DRIVER is
read at context creation, so each driver renders in its own subprocess) lies
within softras's bounds renders, ``render_scene(texture_bounds="lo" / "hi")``
at precision "gl" and "exact" (their per-channel min and max), widened by
T = 2/255, except on coverage-edge pixels.  Discrimination: planted bugs
rendered by softras leave many pixels outside the unmodified scene's bounds.

Run with ``pytest -s`` to see the per-scene counts.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import zlib

import numpy as np
import pytest

import softras
from conftest import REPO, SCENES
from softras.verification import ambiguity
from softras.pipeline import interpolate, texture
from softras.scene import texels
from softras.pipeline import texture_bounds as tb
from softras.renderer import render_scene

MIN_FILTERS = ("nearest", "linear", "nearest_mipmap_nearest", "linear_mipmap_nearest",
               "nearest_mipmap_linear", "linear_mipmap_linear")
WRAPS = ("repeat", "clamp_to_edge", "mirrored_repeat")
EPS = 1e-9
T = 2                                   # the verifier's shading tolerance, 1/255 units

BOUND_SCENES = ["texture_anisotropic_floor", "texture_floor_trilinear", "texture_mip_level_colors",
                "texture_npot", "texture_photo", "texture_wrap_modes", "lit_textured_sphere",
                "extreme_texture_1x1", "extreme_texture_magnify", "extreme_texture_strip"]
VARIANT_SCENES = ["bump_mapped_plane"]  # normal / bump maps: an envelope by variants, not a bound
VARIANT_ALLOWANCE = 0.01                # of the picture's pixels, see test_gl_within_bounds


def make_texture(kind="noise", size=(37, 23), min_filter="linear_mipmap_linear", mag_filter="linear",
                 wrap_s="repeat", wrap_t="repeat", max_anisotropy=1.0):
    if kind == "noise":
        level0 = texels.procedural_texels("noise", size, {"seed": 3})
    else:
        level0 = texels.procedural_texels("checker", size, {"squares": 8, "color0": [0.9, 0.9, 0.85, 1],
                                                            "color1": [0.15, 0.2, 0.6, 1]})
    chain = texels.mip_chain(texels.premultiply_rgba8(level0))
    return texture.MipTexture("t", chain, wrap_s, wrap_t, min_filter, mag_filter, max_anisotropy)


def solid_levels_texture(min_filter, mag_filter="linear", size=64):
    """Every level one solid colour: level k has red 30 k + 10, green 250 - 30 k."""
    levels = []
    for k, (w, h) in enumerate(texels.mip_sizes(size, size)):
        level = np.zeros((h, w, 4), np.uint8)
        level[..., 0], level[..., 1], level[..., 3] = 30 * k + 10, 250 - 30 * k, 255
        levels.append(level)
    return texture.MipTexture("solid", tuple(levels), "repeat", "repeat", min_filter, mag_filter, 1.0)


def footprint(lam, size):
    """Derivatives (F, 2) with rho = m_u = 2^lam and m_v = 0 (ddx along s, ddy = 0):
    every approximation of rho agrees, lambda's range is only the LOD errors wide."""
    lam = np.atleast_1d(np.asarray(lam, np.float64))
    ddx = np.stack([np.exp2(lam) / size[0], np.zeros_like(lam)], 1)
    return ddx, np.zeros_like(ddx)


def random_footprints(rng, n, size, lam=(-4, 7)):
    st = rng.uniform(-2, 3, (n, 2))
    scale = 2.0 ** rng.uniform(*lam, n)[:, None] / size[0]
    angle = rng.uniform(0, np.pi, n)
    ddx = np.stack([np.cos(angle), np.sin(angle)], 1) * scale
    ddy = np.stack([-np.sin(angle), np.cos(angle)], 1) * scale * rng.uniform(0.2, 1.5, n)[:, None]
    return st, ddx, ddy


# --------------------------------------------------------------------------- pieces


def test_float_error_is_a_power_of_two_below_the_value():
    np.testing.assert_array_equal(tb.float_error(np.array([1.0, 3.0, -0.75, 0.0]), 20),
                                  [2.0 ** -20, 2.0 ** -19, 2.0 ** -21, 0.0])


def test_log2_error_is_the_piecewise_linear_log2s():
    x = np.linspace(1, 2, 100001, dtype=np.float32)
    worst = float(np.max(np.log2(x.astype(np.float64)) - texture.fast_log2(x)))
    assert worst == pytest.approx(tb.LOG2_PIECEWISE_LINEAR_ERROR, abs=1e-6)
    assert tb.LOD.log2_error >= tb.LOG2_PIECEWISE_LINEAR_ERROR


def test_lambda_range_holds_every_permitted_rho():
    """The spec's exact rho, its two approximations and llvmpipe's lambda
    (float32 rho^2, piecewise-linear log2) all fall in the range."""
    rng = np.random.default_rng(0)
    size = (37, 23)
    _, ddx, ddy = random_footprints(rng, 5000, size)
    lam_lo, lam_hi = tb.lambda_range(tb.single_derivatives(ddx, ddy), size)
    du, dv = texture.texel_derivatives(ddx, ddy, size, gl=False)
    m_u = np.maximum(np.abs(du[:, 0]), np.abs(dv[:, 0]))
    m_v = np.maximum(np.abs(du[:, 1]), np.abs(dv[:, 1]))
    exact = 0.5 * np.log2(texture.rho_squared(du, dv))
    du32, dv32 = texture.texel_derivatives(ddx, ddy, size, gl=True)
    llvmpipe = 0.5 * texture.fast_log2(texture.rho_squared(du32, dv32)).astype(np.float64)
    for lam in (exact, llvmpipe, np.log2(np.maximum(m_u, m_v)), np.log2(m_u + m_v)):
        assert np.all((lam_lo <= lam) & (lam <= lam_hi))
    # and no wider than the freedoms: one level (m_u + m_v <= 2 max) plus the LOD errors
    assert np.max(lam_hi - lam_lo) <= 1 + 2 * 2.0 ** -tb.LOD.lod_bits + tb.LOD.log2_error + 1e-4


def test_fragment_derivatives_hold_the_pipelines_two():
    """Candidate 0 is llvmpipe's quad difference (interpolate.quad_derivatives,
    within its float32 rounding), candidate 4 the analytic derivative."""
    rng = np.random.default_rng(1)
    n = 200
    vertices = np.broadcast_to(np.array([[3.0, 4.0, 0.5], [90.0, 10.0, 0.5], [40.0, 70.0, 0.5]]), (n, 3, 3))
    inv_w = np.broadcast_to(np.array([1.0, 0.25, 0.5]), (n, 3))
    values = np.broadcast_to(np.array([[0.0, 0.0], [6.0, 1.0], [2.0, 16.0]]), (n, 3, 2))
    x, y = rng.integers(20, 50, n), rng.integers(10, 40, n)
    centres = np.stack([x + 0.5, y + 0.5], 1)
    c = tb.fragment_derivatives(vertices, inv_w, x, y, centres, values)
    qx, qy = interpolate.quad_derivatives(vertices, inv_w, x, y, values)
    assert np.all(np.abs(c.ddx[0] - qx) <= c.error[0]) and np.all(np.abs(c.ddy[0] - qy) <= c.error[0])
    ax, ay = interpolate.analytic_derivatives(vertices, inv_w, centres, values)
    np.testing.assert_array_equal(c.ddx[4], ax)
    np.testing.assert_array_equal(c.ddy[4], ay)
    assert c.ddx.shape == (5, n, 2)


# --------------------------------------------------------------------------- containment


@pytest.mark.parametrize("min_filter", MIN_FILTERS)
@pytest.mark.parametrize("mag_filter", ("nearest", "linear"))
@pytest.mark.parametrize("wrap", WRAPS)
@pytest.mark.parametrize("kind,size", [("noise", (37, 23)), ("checker", (64, 64))])
def test_bounds_hold_softras_lookups(min_filter, mag_filter, wrap, kind, size):
    """llvmpipe's arithmetic (8.8 fixed point and float) and the exact one,
    at random points and footprints, lie within the bounds from the same
    derivatives."""
    tex = make_texture(kind, size, min_filter, mag_filter, wrap, wrap)
    rng = np.random.default_rng(zlib.crc32(f"{min_filter} {mag_filter} {wrap} {kind}".encode()))
    st, ddx, ddy = random_footprints(rng, 4000, size)
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    assert np.all(lo <= hi)
    for precision, fixed in (("gl", True), ("gl", False), ("exact", False)):
        value = texture.sample(tex, st, ddx, ddy, precision, fixed)
        outside = (value < lo - EPS) | (value > hi + EPS)
        assert not outside.any(), f"{precision} fixed={fixed}: {outside.any(1).sum()} lookups outside"


@pytest.mark.parametrize("min_filter", ("linear_mipmap_linear", "nearest_mipmap_nearest", "linear"))
@pytest.mark.parametrize("wrap", WRAPS)
def test_anisotropic_bounds_hold_llvmpipe_ewa_and_spec_probes(min_filter, wrap):
    tex = make_texture("checker", (128, 128), min_filter, "linear", wrap, wrap, max_anisotropy=16.0)
    rng = np.random.default_rng(7)
    n = 2000
    st = rng.uniform(-2, 3, (n, 2))
    minor = 2.0 ** rng.uniform(-3, 4, n)
    major = minor * 2.0 ** rng.uniform(0, 5, n)
    angle = rng.uniform(0, np.pi, n)
    c, s = np.cos(angle), np.sin(angle)
    ddx = np.stack([c * major, s * major], 1) / 128
    ddy = np.stack([-s * minor, c * minor], 1) / 128
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    for precision in ("gl", "exact"):
        value = texture.sample(tex, st, ddx, ddy, precision)
        assert not ((value < lo - 1e-5) | (value > hi + 1e-5)).any(), precision   # float32 EWA sums


# --------------------------------------------------------------------------- tightness and each freedom


def test_magnified_nearest_at_texel_centres_is_exact():
    tex = make_texture("noise", (37, 23), "nearest_mipmap_nearest", "nearest")
    i, j = np.meshgrid(np.arange(37), np.arange(23))
    st = np.stack([(i.ravel() + 0.5) / 37, (j.ravel() + 0.5) / 23], 1)
    ddx, ddy = footprint(np.full(len(st), -2.0), tex.size)
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    texel = tex.levels[0][j.ravel(), i.ravel()] / 255.0
    np.testing.assert_array_equal(lo, texel)
    np.testing.assert_array_equal(hi, texel)


def test_magnified_linear_at_texel_centres_is_tight():
    """Exact with no coordinate or arithmetic room; otherwise within the
    2^-7 texel box's share of the neighbours plus the colour threshold."""
    tex = make_texture("noise", (37, 23), "linear_mipmap_linear", "linear")
    i, j = np.meshgrid(np.arange(37), np.arange(23))
    st = np.stack([(i.ravel() + 0.5) / 37, (j.ravel() + 0.5) / 23], 1)
    ddx, ddy = footprint(np.full(len(st), -1.0), tex.size)
    c = tb.single_derivatives(ddx, ddy)
    texel = tex.levels[0][j.ravel(), i.ravel()] / 255.0
    no_room = tb.LookupPrecision(coord_bits=52, uvw_bits=40, color_threshold=0.0)
    lo, hi = tb.lookup_bounds(tex, st, c, lookup=no_room)
    np.testing.assert_allclose(lo, texel, atol=1e-9)
    np.testing.assert_allclose(hi, texel, atol=1e-9)
    lo, hi = tb.lookup_bounds(tex, st, c)
    assert np.all((lo <= texel) & (texel <= hi))
    assert np.max(hi - lo) <= 2 * (2.0 ** -7 + 2.0 ** -12) + 2 * tb.LOOKUP.color_threshold


def test_uniform_texture_bounds_are_exact_at_any_lod():
    level0 = np.zeros((16, 16, 4), np.uint8)
    level0[...] = (200, 100, 50, 255)
    tex = texture.MipTexture("u", texels.mip_chain(level0), "repeat", "repeat", "linear_mipmap_linear",
                             "linear", 1.0)
    rng = np.random.default_rng(3)
    st, ddx, ddy = random_footprints(rng, 500, (16, 16))
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    np.testing.assert_array_equal(lo, np.broadcast_to(level0[0, 0] / 255.0, lo.shape))
    np.testing.assert_array_equal(hi, lo)


def test_trilinear_range_spans_levels_and_their_blends():
    tex = solid_levels_texture("linear_mipmap_linear")
    colour = {k: tex.levels[k][0, 0] / 255.0 for k in range(len(tex.levels))}
    st = np.full((2, 2), 0.3)
    ddx, ddy = footprint([1.0, 1.3], tex.size)       # lambda 1 (the range straddles it), 1.3 (inside [1, 2])
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    lam_lo, lam_hi = tb.lambda_range(tb.single_derivatives(ddx, ddy), tex.size)
    # lambda 1: the range reaches below 1, so level 0 enters the blend: red spans both sides of level 1's
    assert lo[0, 0] < colour[1][0] < hi[0, 0]
    # lambda 1.3: red is linear in lambda, so the bounds are the blends at the range's ends (+- threshold)
    blend = [colour[1] + (lam - 1) * (colour[2] - colour[1]) for lam in (lam_lo[1], lam_hi[1])]
    assert lo[1, 0] == pytest.approx(blend[0][0] - tb.LOOKUP.color_threshold, abs=1e-9)
    assert hi[1, 0] == pytest.approx(blend[1][0] + tb.LOOKUP.color_threshold, abs=1e-9)


def test_mipmap_nearest_takes_both_roundings_at_a_half():
    tex = solid_levels_texture("nearest_mipmap_nearest", "nearest")
    st = np.full((3, 2), 0.3)
    ddx, ddy = footprint([1.5, 1.2, 1.8], tex.size)
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    red = [tex.levels[k][0, 0, 0] / 255.0 for k in range(4)]
    assert (lo[0, 0], hi[0, 0]) == (red[1], red[2])        # ceil(1.5 + 1/2) - 1 = 1 or floor(2.0) = 2
    assert (lo[1, 0], hi[1, 0]) == (red[1], red[1])
    assert (lo[2, 0], hi[2, 0]) == (red[2], red[2])


def test_min_and_mag_filters_are_both_candidates_near_lambda_zero():
    """Nearest magnification, linear minification: at a texel edge the two
    disagree; near lambda 0 the bounds hold both, away from it only one."""
    tex = make_texture("noise", (16, 16), "linear", "nearest")
    st = np.array([[4.02 / 16, 0.5 / 16]] * 3)
    ddx, ddy = footprint([0.0, -1.0, 1.0], tex.size)
    lo, hi = tb.lookup_bounds(tex, st, tb.single_derivatives(ddx, ddy))
    mag, mini = (texture.filter_level(tex.levels[0], st[:1, 0], st[:1, 1], image_filter, "repeat", "repeat",
                                      False, False) for image_filter in ("nearest", "linear"))
    both = np.concatenate([mag, mini]) / 255.0
    assert np.all(lo[0] <= both.min(0)) and np.all(both.max(0) <= hi[0])
    np.testing.assert_array_equal(lo[1], mag[0] / 255.0)           # only magnified: exact nearest texel
    # only minified: linear, within the threshold and the 2^-7-texel box along both axes
    assert np.all(np.abs(lo[2] - mini[0] / 255.0) <= tb.LOOKUP.color_threshold + 2 * 2.0 ** -7)


def test_texel_bounds_widen_the_result():
    tex = make_texture("noise", (37, 23), "linear_mipmap_linear", "nearest")
    rng = np.random.default_rng(5)
    st, ddx, ddy = random_footprints(rng, 1000, tex.size)
    c = tb.single_derivatives(ddx, ddy)
    lo, hi = tb.lookup_bounds(tex, st, c)
    down = tuple(np.clip(level.astype(int) - 10, 0, 255) for level in tex.levels)
    up = tuple(np.clip(level.astype(int) + 10, 0, 255) for level in tex.levels)
    lo2, hi2 = tb.lookup_bounds(tex, st, c, levels_lo=down, levels_hi=up)
    assert np.all(lo2 <= lo + EPS) and np.all(hi2 >= hi - EPS)
    # by the full 10 where the shifted texels are not clipped at 0 or 255 (alpha is 255 throughout)
    assert np.median(lo - lo2) >= 10 / 255 - EPS and np.median((hi2 - hi)[:, :3]) >= 10 / 255 - EPS


def test_variant_derivatives_hit_the_chosen_lambdas():
    """Each of MAP_LODS: the lookup takes the range's ends, its middle, or
    its first / last whole level (the middle where the range holds none)."""
    tex = make_texture("noise", (64, 64), "linear_mipmap_linear", "linear")
    rng = np.random.default_rng(6)
    _, ddx, ddy = random_footprints(rng, 500, tex.size, lam=(0.1, 5))
    c = tb.single_derivatives(ddx, ddy)
    lam_lo, lam_hi = tb.lambda_range(c, tex.size)
    middle = 0.5 * (lam_lo + lam_hi)
    first, last = np.ceil(lam_lo), np.floor(lam_hi)
    expected = {"lowest": lam_lo, "highest": lam_hi, "middle": middle,
                "first_level": np.where(first <= lam_hi, first, middle),
                "last_level": np.where(last >= lam_lo, last, middle)}
    assert set(expected) == set(tb.MAP_LODS)
    assert (first <= lam_hi).sum() > 50 and (first > lam_hi).sum() > 50        # both cases drawn
    for precision in ("gl", "exact"):
        for where, lam in expected.items():
            _, vx, vy = tb.variant_derivatives(tex, c, where, precision)
            du, dv = texture.texel_derivatives(vx, vy, tex.size, precision == "gl")
            choice = texture.choose_levels(texture.rho_squared(du, dv), tex.min_filter, 7, precision == "gl")
            np.testing.assert_allclose(choice.level0 + choice.frac, np.clip(lam, 0, 6), atol=1e-5,
                                       err_msg=f"{where} ({precision})")


def test_bound_render_names():
    assert tb.bound_render("lo") == ("lo", "lowest") and tb.bound_render("hi") == ("hi", "highest")
    assert tb.bound_render("hi/first_level") == ("hi", "first_level")
    assert len(tb.BOUND_RENDERS) == 8
    for bad in ("mid", "lo/lowest", "lo/", "middle"):
        with pytest.raises(ValueError, match="texture_bounds"):
            tb.bound_render(bad)


# --------------------------------------------------------------------------- renders


def scene_envelope(scene):
    """Per-channel min and max (H, W, 4) int of the bounds renders "lo" and
    "hi" at precision "gl" and "exact"; for normal / bump maps, whose renders
    are variants, also the maps' other levels of detail in gl, as the
    verifier takes them (`softras.verification.verifier.spec_bounds`)."""
    renders = [render_scene(scene, precision=precision, texture_bounds=side).astype(int)
               for precision in ("gl", "exact") for side in tb.SIDES]
    if any(d.material.normal_map or d.material.bump_map for d in scene.draws):
        renders += [render_scene(scene, precision="gl", texture_bounds=value).astype(int)
                    for value in tb.BOUND_RENDERS if "/" in value]
    return np.minimum.reduce(renders), np.maximum.reduce(renders)


def coverage_edges(scene):
    """(H, W) bool: pixels whose visible primitive changes between softras's
    gl and exact renders or under a 1/256-pixel move (`softras.verification.ambiguity`)."""
    ids = ambiguity.id_scene(scene)
    base = ambiguity.decode_ids(render_scene(ids, precision="gl"), scene)[0]
    edge = ambiguity.decode_ids(render_scene(ids, precision="exact"), scene)[0] != base
    for dx, dy in ambiguity.SHIFTS:
        moved = render_scene(ambiguity.shifted_scene(ids, dx, dy), precision="gl")
        edge |= ambiguity.decode_ids(moved, scene)[0] != base
    return edge


_ENVELOPES: dict = {}


def envelope(name):
    """(scene, lo, hi, edge) of scenes/<name>.json, computed once per session."""
    if name not in _ENVELOPES:
        scene = softras.load_scene(SCENES / f"{name}.json")
        _ENVELOPES[name] = (scene, *scene_envelope(scene), coverage_edges(scene))
    return _ENVELOPES[name]


def outside(image, lo, hi, edge, tolerance=T):
    """(H, W) bool: pixels with a channel outside [lo - tolerance, hi + tolerance], edges excluded."""
    image = image.astype(int)
    return ((image < lo - tolerance) | (image > hi + tolerance)).any(-1) & ~edge


@pytest.mark.parametrize("name", ["texture_floor_trilinear", "texture_npot", "texture_wrap_modes",
                                  "texture_anisotropic_floor", "texture_mip_level_colors"])
def test_bounds_renders_hold_softras_renders(name):
    """The stages' own pictures (both precisions, fixed and float filtering)
    lie within the bounds renders without any tolerance."""
    scene, lo, hi, edge = envelope(name)
    for options in ({"precision": "gl"}, {"precision": "gl", "texture_fixed_point": False},
                    {"precision": "exact"}):
        image = render_scene(scene, **options)
        assert not outside(image, lo, hi, np.zeros_like(edge), tolerance=0).any(), options


def test_texture_bounds_option_is_checked():
    scene = softras.load_scene(SCENES / "texture_npot.json")
    with pytest.raises(ValueError, match="texture_bounds"):
        render_scene(scene, texture_bounds="mid")
    with pytest.raises(ValueError, match="texture_filter"):
        render_scene(scene, texture_bounds="lo", texture_filter="ewa")


# --------------------------------------------------------------------------- planted bugs


def _with_textures(scene, change):
    return dataclasses.replace(scene, textures={name: dataclasses.replace(tex, **change(tex))
                                                for name, tex in scene.textures.items()})


def _uv_half_texel(scene):
    draws = []
    for draw in scene.draws:
        tex = scene.textures.get(draw.material.texture)
        if tex is not None and draw.mesh.uvs is not None:
            h, w = tex.levels[0].shape[:2]
            moved = dataclasses.replace(draw.mesh, uvs=draw.mesh.uvs + [0.5 / w, 0.5 / h])
            draw = dataclasses.replace(draw, mesh=moved)
        draws.append(draw)
    return dataclasses.replace(scene, draws=tuple(draws))


_SWAP = {"repeat": "clamp_to_edge", "clamp_to_edge": "repeat", "mirrored_repeat": "mirrored_repeat"}
BUGS = {
    "uv_half_texel": _uv_half_texel,
    "wrap_repeat_clamp_swapped": lambda s: _with_textures(
        s, lambda t: {"wrap_s": _SWAP[t.wrap_s], "wrap_t": _SWAP[t.wrap_t]}),
    "trilinear_as_mipmap_nearest": lambda s: _with_textures(
        s, lambda t: {"min_filter": t.min_filter.replace("_mipmap_linear", "_mipmap_nearest")}),
    "mipmaps_dropped": lambda s: _with_textures(s, lambda t: {"min_filter": t.min_filter.split("_")[0]}),
}
# (scene, bug) -> the fewest pixels it must put outside (measured counts in the commit message);
# pairs where the bug changes nothing (no trilinear texture, nothing minified) are left out,
# and texture_npot's level bugs: its NPOT noise levels may be any value of the texels near
# each footprint (generated_levels), so a wrong level stays inside the bounds there.
BUG_CASES = {
    ("texture_floor_trilinear", "uv_half_texel"): 500,
    ("texture_floor_trilinear", "wrap_repeat_clamp_swapped"): 500,
    ("texture_floor_trilinear", "trilinear_as_mipmap_nearest"): 50,
    ("texture_floor_trilinear", "mipmaps_dropped"): 500,
    ("texture_mip_level_colors", "uv_half_texel"): 500,
    ("texture_mip_level_colors", "wrap_repeat_clamp_swapped"): 500,
    ("texture_mip_level_colors", "mipmaps_dropped"): 500,
    ("texture_npot", "uv_half_texel"): 500,
    ("texture_npot", "wrap_repeat_clamp_swapped"): 500,
    ("texture_wrap_modes", "uv_half_texel"): 500,
    ("texture_wrap_modes", "wrap_repeat_clamp_swapped"): 500,
}


@pytest.mark.parametrize("name,bug", sorted(BUG_CASES))
def test_planted_bugs_leave_the_bounds(name, bug):
    scene, lo, hi, edge = envelope(name)
    count = int(outside(render_scene(BUGS[bug](scene)), lo, hi, edge).sum())
    print(f"\n{name} {bug}: {count} pixels outside")
    assert count >= BUG_CASES[name, bug]


# --------------------------------------------------------------------------- another GL's mip chains

# glGenerateMipmap's levels read back from an NVIDIA H200 (driver 580.159.04,
# glref.generate_mipmaps) for NPOT sizes where it differs most from llvmpipe
# (contents as tests/test_mipmap_gl.py's, seed 19) and texture_npot's 37 x 23
# texture: "<w>x<h>_<content>_<level>", level 0 the input.
RECORDED_MIPS = REPO / "tests" / "recorded" / "nvidia_h200" / "mipmaps.npz"


def _recorded_chains() -> dict[str, list[np.ndarray]]:
    data = np.load(RECORDED_MIPS)
    chains: dict[str, list[np.ndarray]] = {}
    for key in sorted(data.files, key=lambda k: (k.rsplit("_", 1)[0], int(k.rsplit("_", 1)[1]))):
        chains.setdefault(key.rsplit("_", 1)[0], []).append(data[key])
    return chains


def _generated_bounds(level0: np.ndarray):
    tex = texture.MipTexture("recorded", texels.mip_chain(level0), "repeat", "repeat",
                             "linear_mipmap_linear", "linear", 1.0)
    return tb.generated_levels(tex)


def _levels_outside(chains) -> int:
    outside = 0
    for levels in chains.values():
        lows, highs = _generated_bounds(levels[0])
        outside += sum(bool((level < lo).any() or (level > hi).any())
                       for level, lo, hi in zip(levels[1:], lows[1:], highs[1:]))
    return outside


def test_generated_level_bounds_hold_another_gls_npot_chains():
    """Every level of the recorded NVIDIA chains lies within generated_levels'
    bounds (the NPOT footprint rule); llvmpipe's own chain does too."""
    chains = _recorded_chains()
    assert len(chains) == 31
    assert _levels_outside(chains) == 0
    for levels in chains.values():
        lows, highs = _generated_bounds(levels[0])
        for level, lo, hi in zip(texels.mip_chain(levels[0]), lows, highs):
            assert (level >= lo).all() and (level <= hi).all()


@pytest.mark.parametrize("reach", [0, None])
def test_generated_level_bounds_fail_the_recorded_chains_when_narrowed(monkeypatch, reach):
    """The check can fail: without the footprint's one-texel reach, or without
    the NPOT rule at all (the even-size envelope alone), recorded levels leave
    the bounds."""
    if reach is None:
        monkeypatch.setattr(tb, "_footprint_range", lambda lo, hi, size, grow: (
            np.full((size[1], size[0], 4), 255.0), np.zeros((size[1], size[0], 4))))
    else:
        monkeypatch.setattr(tb, "NPOT_FILTER_REACH", reach)
    monkeypatch.setattr(tb, "_generated", {})
    assert _levels_outside(_recorded_chains()) >= (10 if reach == 0 else 40)


# --------------------------------------------------------------------------- against OpenGL

_GL_SCRIPT = """
import pathlib, sys
sys.path.insert(0, sys.argv[1])
import numpy as np, glref, softras
out = pathlib.Path(sys.argv[2])
print(glref.info()["GL_RENDERER"])
for path in sys.argv[3:]:
    np.save(out / (pathlib.Path(path).stem + ".npy"), glref.render(softras.load_scene(path)))
"""


@pytest.fixture(scope="module", params=["llvmpipe", "softpipe"])
def gl_pictures(request, tmp_path_factory):
    """{scene name: (H, W, 4) uint8} from glref on one Mesa driver, rendered
    in a subprocess with GALLIUM_DRIVER set (the driver is chosen when the
    context is created)."""
    driver = request.param
    out = tmp_path_factory.mktemp(f"gl_{driver}")
    names = BOUND_SCENES + VARIANT_SCENES
    env = dict(os.environ, GALLIUM_DRIVER=driver)
    result = subprocess.run([sys.executable, "-c", _GL_SCRIPT, str(REPO), str(out),
                             *[str(SCENES / f"{name}.json") for name in names]],
                            env=env, capture_output=True, text=True, timeout=600)
    renderer = result.stdout.strip().splitlines()[0] if result.stdout.strip() else ""
    if result.returncode != 0 or driver not in renderer:
        message = f"no {driver} context: {renderer or result.stderr.strip()[-500:]}"
        if os.environ.get("SOFTRAS_ALLOW_NO_GL") == "1":
            pytest.skip(message)
        pytest.fail(message)
    return driver, {name: np.load(out / f"{name}.npy") for name in names}


@pytest.mark.gl
@pytest.mark.parametrize("name", BOUND_SCENES + VARIANT_SCENES)
def test_gl_within_bounds(gl_pictures, name):
    """Every pixel of llvmpipe's and softpipe's picture that is not a
    coverage edge lies within the bounds renders +- 2/255.  Scenes with
    normal / bump maps only have an envelope of variants (the maps at five
    lambdas of the permitted range; lighting is not monotone in the lambda
    between them): up to VARIANT_ALLOWANCE of their pixels may fall outside
    (measured: bump_mapped_plane 30 on llvmpipe and 4 on softpipe, 63 and 4
    with the range's ends alone)."""
    driver, pictures = gl_pictures
    scene, lo, hi, edge = envelope(name)
    bad = outside(pictures[name], lo, hi, edge)
    print(f"\n{driver} {name}: {int(bad.sum())} pixels outside ({int(edge.sum())} edge pixels excluded)")
    if name in VARIANT_SCENES:
        assert bad.sum() <= VARIANT_ALLOWANCE * bad.size
    else:
        assert not bad.any(), f"{driver} {name}: {int(bad.sum())} pixels outside, at {np.argwhere(bad)[:5]}"
