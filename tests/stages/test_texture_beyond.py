"""Filters beyond GL (softras.pipeline.texture_beyond): ripmaps, EWA, the supersampled
ground truth they are judged against, and the cost table.

GL has no ripmap or EWA, so besides hand-computed cases these filters are
checked against a supersampled ground truth: on the anisotropic grazing
floor they must come closer to it than trilinear filtering.
"""

import copy
import json

import numpy as np
import pytest

import softras
from conftest import SCENES
from softras.scene import texels
from softras.pipeline import texture, texture_beyond
from softras.verification import ground_truth


def _tex(level0, min_filter="linear_mipmap_linear", wrap="repeat"):
    return texture.MipTexture("t", texels.mip_chain(level0), wrap, wrap, min_filter, "linear", 1.0)


# --------------------------------------------------------------------------- ripmap


def test_downsample_axis_by_hand():
    level = np.array([[10, 21, 30, 41, 99]], np.uint8)[..., None]      # 1 x 5
    # u halves: (10 + 21 + 1) // 2 = 16, (30 + 41 + 1) // 2 = 36; the odd last texel is skipped.
    np.testing.assert_array_equal(texture_beyond.downsample_axis(level, 1)[..., 0], [[16, 36]])
    # v is one texel thin: unchanged.
    assert texture_beyond.downsample_axis(level, 0) is level


def test_ripmap_sizes():
    rip = texture_beyond.ripmap_levels(np.zeros((4, 8, 4), np.uint8))
    assert [[lvl.shape[:2] for lvl in row] for row in rip] == [
        [(4, 8), (4, 4), (4, 2), (4, 1)], [(2, 8), (2, 4), (2, 2), (2, 1)], [(1, 8), (1, 4), (1, 2), (1, 1)]]


def test_ripmap_memory_is_four_times_mip_memory_four_thirds():
    """The lecture's figures: a mip chain holds ~4/3 of level 0's texels, a
    ripmap ~4x: sum over i, j of 2^-i 2^-j = (2 - 1/256)^2 for 256 x 256."""
    level0 = np.zeros((256, 256, 4), np.uint8)
    mip = sum(lvl.shape[0] * lvl.shape[1] for lvl in texels.mip_chain(level0)) / 256 ** 2
    rip = texture_beyond.ripmap_texel_count(texture_beyond.ripmap_levels(level0)) / 256 ** 2
    assert mip == pytest.approx(4 / 3, rel=1e-4)
    assert rip == pytest.approx((2 - 1 / 256) ** 2) and rip == pytest.approx(4, rel=0.01)


def test_ripmap_picks_the_level_per_axis():
    """A footprint 8 texels long along u and 1 along v reads level (3, 0):
    u averaged over 8 texels, v untouched.  Columns alternate 0/255 and rows
    0/255 (a checker); level (3, 0) of it keeps the rows' stripes."""
    level0 = np.zeros((16, 16, 4), np.uint8)
    level0[..., 0] = np.where((np.arange(16)[:, None] + np.arange(16)[None, :]) % 2, 255, 0)
    level0[..., 3] = 255
    tex = _tex(level0, "linear_mipmap_nearest")
    lam_u, lam_v = texture_beyond.ripmap_lods(np.array([[8.0, 0.0]]), np.array([[0.0, 1.0]]))
    assert (lam_u[0], lam_v[0]) == (3.0, 0.0)
    rip = texture_beyond.ripmap(tex)
    # level (i=3, j=0): 16 x 2, every texel the mean of 8 alternating ones: 127.5 -> 128
    assert rip[0][3].shape[:2] == (16, 2) and (rip[0][3][..., 0] == 128).all()
    st = np.array([[0.3, 0.53]])
    out, reads = texture_beyond.sample_ripmap(tex, st, np.array([[8 / 16, 0.0]]), np.array([[0.0, 1 / 16]]))
    assert out[0, 0] * 255 == pytest.approx(128) and reads[0] == 4
    # trilinear's square texel at lambda 3 blurs v too; the ripmap keeps it: both 128 here,
    # but a v-striped texture shows it:
    level0[..., 0] = np.where(np.arange(16)[:, None] % 2, 255, 0)
    tex = _tex(level0, "linear_mipmap_nearest")
    out, _ = texture_beyond.sample_ripmap(tex, np.array([[0.3, 9.5 / 16]]),
                                          np.array([[8 / 16, 0.0]]), np.array([[0.0, 1 / 16]]))
    assert out[0, 0] * 255 == pytest.approx(255)     # the centre of texel row 9: a 255 stripe


# --------------------------------------------------------------------------- EWA


def test_footprint_covariance_by_hand():
    # du = (4, 0), dv = (0, 1): S = J J^T = diag(16, 1), minor semi-axis 1.
    S, minor = texture_beyond.footprint_covariance(np.array([[4.0, 0.0]]), np.array([[0.0, 1.0]]))
    np.testing.assert_allclose(S[0], [[16, 0], [0, 1]])
    assert minor[0] == pytest.approx(1)
    # Rotated by 45 degrees: same axes.
    c = np.sqrt(0.5)
    S, minor = texture_beyond.footprint_covariance(np.array([[4 * c, 4 * c]]), np.array([[-c, c]]))
    np.testing.assert_allclose(np.linalg.eigvalsh(S[0]), [1, 16])
    # Eccentricity 64 > 16: the minor axis grows to 64 / 16 = 4, the major stays.
    S, minor = texture_beyond.footprint_covariance(np.array([[64.0, 0.0]]), np.array([[0.0, 1.0]]))
    np.testing.assert_allclose(S[0], [[4096, 0], [0, 16]])
    assert minor[0] == pytest.approx(4)


def test_a_footprint_wider_than_the_last_level_is_shrunk():
    """EWA shrinks a footprint wider than the last level takes to a minor
    semi-axis of 2 EWA_MINOR_TEXELS of its texels (a near-singular view gave
    ellipses of 1e9 texels, and the loop never ended): a circle of radius
    1000 texels on a 32² texture reads at most pi 5² texels of its 1 x 1
    last level (not pi 31²) and gives that texel."""
    rng = np.random.default_rng(3)
    tex = _tex(rng.integers(0, 256, (32, 32, 4)).astype(np.uint8))
    d = 1000.0 / 32                                   # (s, t) units: 1000 texels
    out, reads = texture_beyond.sample_ewa(tex, np.array([[0.3, 0.6]]), np.array([[d, 0.0]]),
                                           np.array([[0.0, d]]))
    assert 1 <= reads[0] <= np.pi * 5 ** 2
    np.testing.assert_allclose(out[0] * 255, tex.levels[-1][0, 0], atol=1e-9)


def test_ewa_of_a_constant_is_the_constant():
    level0 = np.full((32, 32, 4), 200, np.uint8)
    rng = np.random.default_rng(7)
    st = rng.uniform(-1, 2, (200, 2))
    ddx, ddy = rng.normal(0, 0.2, (200, 2)), rng.normal(0, 0.02, (200, 2))
    for wrap in ("repeat", "clamp_to_edge", "mirrored_repeat"):
        out, reads = texture_beyond.sample_ewa(_tex(level0, wrap=wrap), st, ddx, ddy)
        np.testing.assert_allclose(out * 255, 200, atol=1e-9)
        assert (reads >= 1).all()


def test_ewa_averages_along_the_major_axis_only():
    """Vertical stripes (u varies) under a footprint long along v: EWA keeps
    the stripe; a footprint long along u averages it away."""
    level0 = np.zeros((64, 64, 4), np.uint8)
    level0[..., 0] = np.where((np.arange(64)[None, :] // 4) % 2, 255, 0)
    level0[..., 3] = 255
    tex = _tex(level0)
    st = np.array([[6 / 64, 0.5]])                   # centre of a 255 stripe (u = 6)
    along_v, _ = texture_beyond.sample_ewa(tex, st, np.array([[0.3 / 64, 0]]), np.array([[0, 16 / 64]]))
    along_u, _ = texture_beyond.sample_ewa(tex, st, np.array([[16 / 64, 0]]), np.array([[0, 0.3 / 64]]))
    assert along_v[0, 0] > 0.9
    assert 0.3 < along_u[0, 0] < 0.7


# --------------------------------------------------------------------------- the render option


def test_texture_filter_option_validation():
    scene = softras.load_scene(SCENES / "texture_anisotropic_floor.json")
    with pytest.raises(ValueError, match="unknown filter 'bicubic'"):
        softras.render(scene, texture_filter="bicubic")
    with pytest.raises(ValueError, match="no texture 'missing'"):
        softras.render(scene, texture_filter={"missing": "ewa"})
    texture_beyond.check_texture_filter({"checker": None}, scene.textures)


def test_texture_filter_dict_overrides_only_the_named_texture():
    scene = softras.load_scene(SCENES / "texture_anisotropic_floor.json")
    plain = softras.render(scene, precision="exact")
    assert (softras.render(scene, precision="exact", texture_filter={"checker": None}) == plain).all()
    ewa = softras.render(scene, precision="exact", texture_filter={"checker": "ewa"})
    assert (softras.render(scene, precision="exact", texture_filter="ewa") == ewa).all()
    assert (ewa != plain).any()


# --------------------------------------------------------------------------- against the ground truth


def _small_floor(min_filter="linear_mipmap_linear", max_anisotropy=1):
    data = json.loads((SCENES / "texture_anisotropic_floor.json").read_text())
    data = copy.deepcopy(data)
    data["width"], data["height"] = 48, 36
    data["textures"]["checker"]["min_filter"] = min_filter
    data["textures"]["checker"]["max_anisotropy"] = max_anisotropy
    return softras.load_scene(data)


def test_ripmap_and_ewa_beat_trilinear_against_the_supersampled_ground_truth():
    """The grazing floor at 48 x 36 pixels, 16 x 16 exact samples per pixel
    (bilinear on level 0 at each) as ground truth: ripmap and EWA come
    closer to it than trilinear (RMSE and mean abs error), trilinear closer
    than bilinear without mipmaps.  Deterministic: no randomness involved."""
    scene = _small_floor()
    reference = ground_truth.supersampled_reference(scene, factor=16)
    errors = {name: ground_truth.errors_against(reference, softras.render(scene, precision="exact",
                                                                           texture_filter=name))
              for name in ("ripmap", "ewa")}
    errors["trilinear"] = ground_truth.errors_against(reference, softras.render(scene, precision="exact"))
    errors["bilinear"] = ground_truth.errors_against(
        reference, softras.render(_small_floor("linear"), precision="exact"))
    for name in ("ripmap", "ewa"):
        for measure in ("rmse", "mean_abs"):
            assert errors[name][measure] < errors["trilinear"][measure], (name, errors)
    assert errors["trilinear"]["rmse"] < errors["bilinear"]["rmse"]


def test_supersampled_reference_of_a_flat_colour():
    """A 1-sample-per-texel constant texture: the reference is the colour
    where the floor is, the background elsewhere; values in [0, 1]."""
    scene = _small_floor()
    reference = ground_truth.supersampled_reference(scene, factor=2)
    assert reference.shape == (36, 48, 4)
    assert reference.min() >= 0 and reference.max() <= 1
    np.testing.assert_allclose(reference[0, 0, :3], np.rint(np.array([0.1, 0.1, 0.2]) * 255) / 255)


# --------------------------------------------------------------------------- cost


def test_filter_costs_count_the_reads():
    rows = texture_beyond.filter_costs(n=3000, runs=1, size=64)
    reads = {(r["name"], r["precision"]): r["reads"] for r in rows}
    assert reads[("nearest", "gl")] == 1 and reads[("linear", "exact")] == 4
    assert 4 < reads[("linear_mipmap_linear (trilinear)", "exact")] <= 8
    assert reads[("anisotropic 16", "exact")] > reads[("linear_mipmap_linear (trilinear)", "exact")]
    assert 4 < reads[("ripmap", "exact")] <= 16
    assert reads[("EWA", "exact")] > 8
    assert all(r["seconds_per_million"] > 0 for r in rows)
    table = texture_beyond.format_costs(rows)
    assert table.count("\n") == len(rows) + 1 and "| nearest | gl | 1 | 1.0 |" in table


@pytest.mark.parametrize("bad", [np.inf, np.nan])
def test_ewa_footprint_with_no_texel_falls_back_to_bilinear(bad):
    """Infinite or NaN derivatives give an ellipse that takes no texel (the
    stage divided by a zero weight sum: ZeroDivisionError); the sample gets
    its level's bilinear filter instead, with no EWA reads."""
    rng = np.random.default_rng(3)
    tex = _tex(rng.integers(0, 256, (16, 16, 4), dtype=np.uint8))
    st = np.array([[0.3, 0.4], [0.55, 0.9]])
    ddx = np.array([[bad, 0.0], [0.01, bad]])
    out, reads = texture_beyond.sample_ewa(tex, st, ddx, ddx[:, ::-1].copy())
    assert np.isfinite(out).all() and reads.tolist() == [0, 0]
    expected = texels.bilinear(tex.levels[0], st[:, 0], st[:, 1], "repeat", "repeat") / 255.0
    assert np.array_equal(out, expected)
    fine, fine_reads = texture_beyond.sample_ewa(tex, st, np.full((2, 2), 0.01), np.full((2, 2), 0.01))
    assert (fine_reads > 0).all() and np.isfinite(fine).all()
