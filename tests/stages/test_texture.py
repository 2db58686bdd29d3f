"""Texture stage: texels, mip chains, wrap, LOD and filter weights (softras.pipeline.texture).

Hand-computed values; the comparison with OpenGL is in tests/test_texture_gl.py.
"""

import numpy as np
import pytest

from softras.scene import texels
from softras.pipeline import texture


# --------------------------------------------------------------------------- texels and mips


def test_premultiply_rounds_to_nearest():
    straight = np.array([[255, 128, 0, 128], [10, 20, 30, 255], [200, 200, 200, 0]], np.uint8)
    # 255*128/255 = 128; 128*128/255 = 64.25 -> 64; alpha 255 keeps rgb; alpha 0 clears it.
    np.testing.assert_array_equal(texels.premultiply_rgba8(straight),
                                  [[128, 64, 0, 128], [10, 20, 30, 255], [0, 0, 0, 0]])


def test_mip_sizes_npot():
    assert texels.mip_sizes(5, 3) == [(5, 3), (2, 1), (1, 1)]
    assert texels.mip_sizes(8, 1) == [(8, 1), (4, 1), (2, 1), (1, 1)]
    assert texels.mip_sizes(1, 1) == [(1, 1)]
    assert texels.mip_sizes(37, 23) == [(37, 23), (18, 11), (9, 5), (4, 2), (2, 1), (1, 1)]


def test_mip_chain_shapes_match_sizes():
    level0 = np.zeros((3, 5, 4), np.uint8)
    chain = texels.mip_chain(level0)
    assert [lvl.shape[1::-1] for lvl in chain] == texels.mip_sizes(5, 3)


def test_box_downsample_is_a_rounded_2x2_box():
    level = np.array([[0, 255], [255, 255]], np.uint8)[..., None]
    assert texels.downsample(level, "box")[0, 0, 0] == (0 + 3 * 255 + 2) // 4 == 191
    # 3x3: floor(3/2) = 1, the box is the top-left 2x2; the last row and column are skipped.
    level = np.array([[4, 8, 99], [12, 16, 99], [99, 99, 99]], np.uint8)[..., None]
    assert texels.downsample(level, "box").shape == (1, 1, 1)
    assert texels.downsample(level, "box")[0, 0, 0] == 10
    # One texel thin: a 2x1 box.
    level = np.array([[10, 21, 30, 40]], np.uint8)[..., None]
    np.testing.assert_array_equal(texels.downsample(level, "box")[..., 0], [[16, 35]])


def test_llvmpipe_downsample_by_hand():
    """llvmpipe's glGenerateMipmap samples level i bilinearly (8.8 fixed
    point, clamp to edge) at each level-(i + 1) texel centre."""
    # 2x2 -> 1x1: weights 1/2, a rounded mean along x per row, then along y:
    # rows 0 + ((128 * 255 + 128) >> 8) = 128 and 255; 128 + ((128 * 127 + 128) >> 8) = 192
    # (the box rounds (0 + 3 * 255 + 2) // 4 = 191).
    level = np.array([[0, 255], [255, 255]], np.uint8)[..., None]
    assert texels.downsample(level)[0, 0, 0] == 192
    # 3x3 -> 1x1: the centre (1.5, 1.5) is texel (1, 1)'s centre: that texel alone.
    level = np.array([[4, 8, 99], [12, 16, 99], [99, 99, 99]], np.uint8)[..., None]
    assert texels.downsample(level)[0, 0, 0] == 16
    # 5x1 -> 2x1: centres at u = 1.25 and 3.75 texels: 8.8 coordinates
    # 1.25 * 256 - 128 = 192 (texels 0, 1, weight 192) and 832 (texels 3, 4, weight 64).
    level = np.array([[10, 50, 99, 200, 100]], np.uint8)[..., None]
    assert texels.llvmpipe_blit_coordinates((2, 1), (5, 1))[0].tolist() == [192, 832]
    np.testing.assert_array_equal(texels.downsample(level)[..., 0],
                                  [[10 + ((192 * 40 + 128) >> 8), 200 + ((64 * -100 + 128) >> 8)]])
    # One texel wide: the other axis's coordinate is the texel's centre, weight 0.
    column = np.array([[7], [9], [11], [13]], np.uint8)[..., None]
    np.testing.assert_array_equal(texels.downsample(column)[..., 0, 0], [8, 12])


def test_llvmpipe_coordinates_of_even_sizes_are_exact_halves():
    """Halving an even size, every texel centre lands halfway between two
    texels (8.8 coordinate 512 i + 128: texel 2 i, weight 128), whatever the
    float32 rounding of the plane equations (every size up to 2 x 2048)."""
    for n in range(1, 2049):
        s, t_upper, t_lower = texels.llvmpipe_blit_coordinates((n, 2049 - n), (2 * n, 2 * (2049 - n)))
        np.testing.assert_array_equal(s, 512 * np.arange(n) + 128)
        np.testing.assert_array_equal(t_upper, 512 * np.arange(2049 - n) + 128)
        np.testing.assert_array_equal(t_lower, t_upper)


def test_fma32_is_rounded_once():
    """`texels._fma32` against the exact product and sum rounded to float32
    (ties to even) by hand with fractions, on random and tie-making values."""
    from fractions import Fraction

    def round32(q: Fraction) -> Fraction:
        f = np.float32(float(q))
        candidates = [np.nextafter(f, np.float32(-np.inf)), f, np.nextafter(f, np.float32(np.inf))]
        return min((abs(Fraction(float(c)) - q), int(np.float32(c).view(np.uint32) & 1), Fraction(float(c)))
                   for c in candidates)[2]

    rng = np.random.default_rng(3)
    a = rng.standard_normal(3000).astype(np.float32)
    b = rng.integers(0, 4096, 3000).astype(np.float32)
    c = (rng.standard_normal(3000) * np.where(np.arange(3000) < 1000, 1e-9, 1e-2)).astype(np.float32)
    # a b = 1 + 2^-11 + 2^-24, halfway between two float32, plus a tiny c: the
    # float64 sum is that tie (c is below its ulp), which float32 would round
    # down to even; rounded once, a b + c rounds up.
    a[:10], b[:10] = np.float32(1 + 2 ** -12), np.float32(1 + 2 ** -12)
    c[:5], c[5:10] = np.float32(2 ** -70), np.float32(-2 ** -70)
    got = texels._fma32(a, b, c)
    assert got[0] == np.float32(1 + 2 ** -11 + 2 ** -23) and got[5] == np.float32(1 + 2 ** -11)
    for x, y, z, g in zip(a, b, c, got):
        want = round32(Fraction(float(x)) * Fraction(float(y)) + Fraction(float(z)))
        assert Fraction(float(g)) == want, (x, y, z)


def test_compiled_texel_loops_equal_the_array_formulas():
    """The compiled premultiply, box and llvmpipe reductions and checker loops
    against their definitions written as numpy array expressions: every
    (c, a) byte pair, random levels of odd, thin and 1x1 sizes (and 158x475,
    which has a texel centre on the llvmpipe blit's diagonal), non-square checkers."""
    c, a = np.meshgrid(np.arange(256), np.arange(256))
    straight = np.stack([c, 255 - c, c // 2, a], axis=-1).astype(np.uint8)              # (256, 256, 4)
    expected = straight.astype(np.int32)
    expected[..., :3] = (expected[..., :3] * expected[..., 3:4] * 2 + 255) // 510
    np.testing.assert_array_equal(texels.premultiply_rgba8(straight), expected)

    def box(level):
        h, w = level.shape[:2]
        nh, nw, fy, fx = max(1, h // 2), max(1, w // 2), 2 if h > 1 else 1, 2 if w > 1 else 1
        x = level.astype(np.int32)[:nh * fy, :nw * fx]
        return (x.reshape(nh, fy, nw, fx, -1).sum(axis=(1, 3)) + fy * fx // 2) // (fy * fx)

    def llvmpipe(level):
        h, w = level.shape[:2]
        nh, nw = max(1, h // 2), max(1, w // 2)
        s, t_upper, t_lower = texels.llvmpipe_blit_coordinates((nw, nh), (w, h))
        i, j = np.meshgrid(np.arange(nw), np.arange(nh))
        t = np.where((2 * j + 1) * nw <= (2 * i + 1) * nh, t_upper[:, None], t_lower[:, None])
        s = np.broadcast_to(s[None, :], t.shape)
        x0, x1 = np.clip(s >> 8, 0, w - 1), np.clip((s >> 8) + 1, 0, w - 1)
        y0, y1 = np.clip(t >> 8, 0, h - 1), np.clip((t >> 8) + 1, 0, h - 1)
        a, b = (s & 255)[..., None], (t & 255)[..., None]
        x = level.astype(np.int64)
        top = texture.lerp8(a, x[y0, x0], x[y0, x1])
        return texture.lerp8(b, top, texture.lerp8(a, x[y1, x0], x[y1, x1]))

    rng = np.random.default_rng(5)
    for shape in [(1, 1, 4), (1, 9, 4), (7, 1, 4), (3, 5, 4), (33, 18, 4), (64, 64, 4), (6, 4, 1),
                  (475, 158, 4)]:
        level = rng.integers(0, 256, size=shape, dtype=np.uint8)
        for method, formula in (("box", box), ("llvmpipe", llvmpipe)):
            got = texels.downsample(level, method)
            assert got.dtype == np.uint8
            np.testing.assert_array_equal(got, formula(level))
    for width, height, squares in [(4, 4, 2), (7, 5, 3), (100, 30, 7), (1, 1, 1), (64, 96, 8)]:
        colors = [0.2, 0.4, 0.6, 1.0], [0.9, 0.1, 0.5, 0.5]
        tex = texels.procedural_texels("checker", (width, height),
                                       {"squares": squares, "color0": colors[0], "color1": colors[1]})
        odd = ((np.arange(height)[:, None] * squares // height + np.arange(width)[None, :] * squares // width)
               % 2).astype(bool)
        bytes0, bytes1 = (np.rint(np.asarray(color) * 255).astype(np.uint8) for color in colors)
        np.testing.assert_array_equal(tex, np.where(odd[..., None], bytes1, bytes0))


def test_mip_chain_levels_lie_back_to_back_in_one_buffer():
    """mip_chain's levels are views of one buffer in level order (`levels_buffer`
    returns it, what the fast path samples without a copy); premultiply=True
    equals premultiplying level 0 first."""
    straight = np.random.default_rng(9).integers(0, 256, size=(12, 20, 4), dtype=np.uint8)
    chain = texels.mip_chain(straight, premultiply=True)
    expected = texels.mip_chain(texels.premultiply_rgba8(straight))
    assert len(chain) == len(expected) == 5
    for level, want in zip(chain, expected):
        np.testing.assert_array_equal(level, want)
    buffer = texels.levels_buffer(chain)
    np.testing.assert_array_equal(buffer, np.concatenate([level.ravel() for level in chain]))
    assert all(np.shares_memory(buffer, level) for level in chain)
    assert texels.levels_buffer(chain[:1]).nbytes == chain[0].nbytes
    # Levels not laid out from one buffer's start: a concatenated copy.
    for levels in (chain[1:], (chain[0].copy(), chain[1])):
        copy = texels.levels_buffer(levels)
        np.testing.assert_array_equal(copy, np.concatenate([level.ravel() for level in levels]))
        assert not np.shares_memory(copy, buffer)


def test_mip_memory_is_four_thirds():
    """The lecture's figure: a full mip chain costs at most 1/3 more than level 0."""
    chain = texels.mip_chain(np.zeros((256, 256, 4), np.uint8))
    total = sum(level.size for level in chain)
    assert total / chain[0].size == pytest.approx(4 / 3, rel=1e-4)
    assert total / chain[0].size < 4 / 3


def test_procedural_checker_layout():
    tex = texels.procedural_texels("checker", (4, 4), {"squares": 2, "color0": [0, 0, 0, 1],
                                                        "color1": [1, 1, 1, 1]})
    assert tex.shape == (4, 4, 4) and tex.dtype == np.uint8
    assert tex[0, 0, 0] == 0 and tex[0, 2, 0] == 255 and tex[2, 0, 0] == 255 and tex[3, 3, 0] == 0
    assert (tex[..., 3] == 255).all()


def test_procedural_gradient_samples_texel_centres():
    tex = texels.procedural_texels("gradient", (4, 1), {"direction": "horizontal",
                                                         "color0": [0, 0, 0, 1], "color1": [1, 1, 1, 1]})
    # (i + 0.5) / 4 * 255 = 31.875, 95.625, 159.375, 223.125
    np.testing.assert_array_equal(tex[0, :, 0], [32, 96, 159, 223])


def test_procedural_noise_is_seeded():
    a = texels.procedural_texels("noise", (8, 8), {"seed": 5})
    b = texels.procedural_texels("noise", (8, 8), {"seed": 5})
    c = texels.procedural_texels("noise", (8, 8), {"seed": 6})
    np.testing.assert_array_equal(a, b)
    assert (a != c).any()


# --------------------------------------------------------------------------- wrap


def test_wrap_modes():
    i = np.array([-9, -5, -4, -1, 0, 3, 4, 5, 8])
    np.testing.assert_array_equal(texture.wrap(i, 4, "repeat"), [3, 3, 0, 3, 0, 3, 0, 1, 0])
    np.testing.assert_array_equal(texture.wrap(i, 4, "clamp_to_edge"), [0, 0, 0, 0, 0, 3, 3, 3, 3])
    # ... 0 1 2 3 | 3 2 1 0 | 0 1 2 3 | 3 2 1 0 ...  (period 8, index 0 starts a forward copy)
    np.testing.assert_array_equal(texture.wrap(i, 4, "mirrored_repeat"), [0, 3, 3, 0, 0, 3, 3, 2, 0])


# --------------------------------------------------------------------------- filter weights


def test_bilinear_weights_float_and_fixed_point():
    s = np.array([0.3])
    # u = 0.3 * 4 - 0.5 = 0.7: texels 0 and 1, weight 0.7 on texel 1.
    i0, i1, w = texture.linear_addresses(s, 4, "repeat", fixed8=False)
    assert (i0[0], i1[0]) == (0, 1) and w[0] == pytest.approx(0.7)
    # llvmpipe: round(0.3 * 4 * 256) - 128 = 307 - 128 = 179 = 0 * 256 + 179.
    i0, i1, w = texture.linear_addresses(s, 4, "repeat", fixed8=True)
    assert (i0[0], i1[0], w[0]) == (0, 1, 179)
    # Left of the first texel centre: repeat wraps to the last texel, clamp stays.
    s = np.array([0.05])          # u = -0.3
    assert [int(v[0]) for v in texture.linear_addresses(s, 4, "repeat", fixed8=False)[:2]] == [3, 0]
    assert [int(v[0]) for v in texture.linear_addresses(s, 4, "clamp_to_edge", fixed8=False)[:2]] == [0, 0]


def test_npot_repeat_fixed_point_wraps_like_pot():
    s = np.array([-0.01, 0.999, 1.5, 2.25])
    for fixed8 in (False, True):
        i0, i1, w = texture.linear_addresses(s, 5, "repeat", fixed8=fixed8)
        assert ((0 <= i0) & (i0 < 5) & (0 <= i1) & (i1 < 5)).all()
        np.testing.assert_array_equal(i1, (i0 + 1) % 5)


def test_lerp8_rounds_like_pmulhrsw():
    a, b = np.array([0, 255, 10]), np.array([255, 0, 11])
    w = np.array([179, 179, 128])
    # (179*255 + 128) >> 8 = 178; 255 + ((179*-255 + 128) >> 8) = 255 - 178 = 77; 10 + (128 + 128) >> 8 = 11
    np.testing.assert_array_equal(texture.lerp8(w, a, b), [178, 77, 11])


def test_filter_level_bilinear_by_hand():
    level = np.zeros((2, 2, 4), np.uint8)
    level[..., 0] = [[0, 100], [200, 40]]            # row 0 is t = 0
    st = np.array([[0.5, 0.5]])                        # midway between all four centres
    out = texture.filter_level(level, st[:, 0], st[:, 1], "linear", "clamp_to_edge",
                               "clamp_to_edge", gl=False, fixed8=False)
    assert out[0, 0] == pytest.approx((0 + 100 + 200 + 40) / 4)
    # Nearest at the centre of texel (1, 0): 100.
    out = texture.filter_level(level, np.array([0.75]), np.array([0.25]), "nearest",
                               "repeat", "repeat", gl=False, fixed8=False)
    assert out[0, 0] == 100


# --------------------------------------------------------------------------- LOD


def test_fast_log2_is_piecewise_linear():
    x = np.array([1, 2, 3, 4, 9, 0.75], np.float32)
    # exponent + mantissa - 1: 0, 1, 1 + 0.5, 2, 3 + 0.125, -1 + 0.5
    np.testing.assert_allclose(texture.fast_log2(x), [0, 1, 1.5, 2, 3.125, -0.5])


def _levels(rho, min_filter, gl, n_levels=9):
    return texture.choose_levels(np.array([rho * rho], np.float64), min_filter, n_levels, gl)


def test_lod_of_known_derivatives():
    # ds/dx = 1/64 on a 256-texel axis: 4 texels per pixel, lambda = 2.
    du, dv = texture.texel_derivatives(np.array([[1 / 64, 0]]), np.array([[0, 1 / 128]]), (256, 256), gl=False)
    rho2 = texture.rho_squared(du, dv)
    assert rho2[0] == pytest.approx(16)
    for gl in (False, True):
        choice = texture.choose_levels(rho2, "linear_mipmap_linear", 9, gl)
        assert (choice.level0[0], choice.level1[0], choice.frac[0]) == (2, 3, 0)
        assert not choice.magnified[0]


def test_lod_between_levels():
    # rho = 3: lambda = log2 3 = 1.585 (exact); llvmpipe 0.5 * fast_log2(9) = 1.5625.
    exact = _levels(3, "linear_mipmap_linear", gl=False)
    assert (exact.level0[0], exact.level1[0]) == (1, 2)
    assert exact.frac[0] == pytest.approx(np.log2(3) - 1)
    gl = _levels(3, "linear_mipmap_linear", gl=True)
    assert (gl.level0[0], gl.level1[0]) == (1, 2)
    assert gl.frac[0] == pytest.approx(0.5625)
    # mipmap_nearest: round(1.585) = 2 both ways; rho = 2.8 (lambda 1.485) -> 1.
    assert _levels(3, "nearest_mipmap_nearest", gl=False).level0[0] == 2
    assert _levels(3, "nearest_mipmap_nearest", gl=True).level0[0] == 2
    assert _levels(2.8, "nearest_mipmap_nearest", gl=False).level0[0] == 1
    assert _levels(2.8, "nearest_mipmap_nearest", gl=True).level0[0] == 1


def test_lod_magnification_and_clamping():
    for gl in (False, True):
        mag = _levels(0.5, "linear_mipmap_linear", gl)
        assert mag.magnified[0] and mag.level0[0] == 0 and mag.frac[0] == 0
        far = _levels(2.0 ** 20, "linear_mipmap_linear", gl, n_levels=9)
        assert (far.level0[0], far.level1[0], far.frac[0]) == (8, 8, 0)
        assert _levels(2.0 ** 20, "nearest_mipmap_nearest", gl, n_levels=9).level0[0] == 8
        # An infinite footprint (derivatives that overflowed) is the last level,
        # lambda = +inf >= q (GL 4.5 section 8.14.3); a zero one is level 0.
        if not gl:
            for min_filter in ("linear_mipmap_linear", "nearest_mipmap_nearest", "linear_mipmap_nearest"):
                choice = _levels(np.inf, min_filter, gl, n_levels=9)
                assert (choice.level0[0], choice.level1[0], choice.frac[0]) == (8, 8, 0), min_filter
                assert not choice.magnified[0]
                assert _levels(0.0, min_filter, gl, n_levels=9).level0[0] == 0
        # Without a mipmap filter only the min/mag switch matters.
        plain = _levels(8, "linear", gl)
        assert not plain.magnified[0] and plain.level0[0] == 0


def test_sample_picks_the_level():
    levels = tuple(np.full((2 ** (3 - k), 2 ** (3 - k), 4), 10 * k, np.uint8) for k in range(4))
    tex = texture.MipTexture("t", levels, "repeat", "repeat", "nearest_mipmap_nearest", "nearest", 1.0)
    st = np.full((3, 2), 0.3)
    ddx = np.array([[1 / 8, 0], [2 / 8, 0], [4 / 8, 0]])      # rho = 1, 2, 4 texels
    for precision in ("gl", "exact"):
        out = texture.sample(tex, st, ddx, np.zeros_like(ddx), precision)
        np.testing.assert_allclose(out[:, 0] * 255, [0, 10, 20])


# --------------------------------------------------------------------------- anisotropic filtering


def test_effective_anisotropy_truncates_in_gl():
    """Mesa's state tracker passes (unsigned) max_anisotropy: 1.5 is no anisotropy in GL."""
    assert texture.effective_anisotropy(1.5, gl=True) == 1
    assert texture.effective_anisotropy(16, gl=True) == 16
    assert texture.effective_anisotropy(1.5, gl=False) == 1.5


def test_anisotropic_probes_by_hand():
    # EXT_texture_filter_anisotropic: Px = 8, Py = 1 texels: N = min(ceil(8 / 1), maxAniso),
    # lambda' = log2(Pmax / N): 8 probes at lambda 0 with maxAniso 16, 4 at lambda 1 with 4.
    count, rho2 = texture.anisotropic_probes(np.array([8.0]), np.array([1.0]), 16)
    assert count[0] == 8 and rho2[0] == pytest.approx(1.0)
    count, rho2 = texture.anisotropic_probes(np.array([8.0]), np.array([1.0]), 4)
    assert count[0] == 4 and rho2[0] == pytest.approx(4.0)
    # Ratio 2.5 rounds up to 3 probes; Pmin = 0 takes maxAniso; no footprint: 1 probe.
    count, rho2 = texture.anisotropic_probes(np.array([1.0, 6.0, 0.0]), np.array([2.5, 0.0, 0.0]), 8)
    np.testing.assert_array_equal(count, [3, 8, 1])
    np.testing.assert_allclose(rho2, [(2.5 / 3) ** 2, (6 / 8) ** 2, 0.0])


def _ramp_texture(min_filter, mag_filter, max_anisotropy):
    """16x16, red = 10 * column index; a full mip chain."""
    level0 = np.zeros((16, 16, 4), np.uint8)
    level0[..., 0] = 10 * np.arange(16)[None, :]
    level0[..., 3] = 255
    return texture.MipTexture("ramp", texels.mip_chain(level0), "repeat", "repeat",
                              min_filter, mag_filter, float(max_anisotropy))


def test_exact_anisotropic_averages_the_spec_probes():
    """Px = 4 texels along u, Py = 1: N = 4 probes, lambda' = log2(4 / 4) = 0, so
    each probe is the mag filter (nearest) on level 0.  At s = 1/2 (u = 8) the
    probes sit at u = 8 + 4 (i / 5 - 1/2), i = 1..4: 6.8, 7.6, 8.4, 9.2 ->
    texels 6, 7, 8, 9 -> (60 + 70 + 80 + 90) / 4 = 75 (a single lookup: 80)."""
    tex = _ramp_texture("linear_mipmap_linear", "nearest", 16)
    st = np.array([[0.5, 0.5]])
    ddx, ddy = np.array([[4 / 16, 0.0]]), np.array([[0.0, 1 / 16]])
    out = texture.sample(tex, st, ddx, ddy, "exact")
    assert out[0, 0] * 255 == pytest.approx(75)
    single = _ramp_texture("linear_mipmap_linear", "nearest", 1)
    assert texture.sample(single, st, ddx * 0.25, ddy, "exact")[0, 0] * 255 == pytest.approx(80)


def test_llvmpipe_aniso_level_from_the_minor_axis():
    # pmin2 = min(64^2, 4^2) = 16: lod = 0.5 fast_log2(16) = 2 -> level 2.
    du, dv = np.array([[64.0, 0.0]], np.float32), np.array([[0.0, 4.0]], np.float32)
    assert texture.llvmpipe_aniso_levels(du, dv, 9)[0] == 2
    # pmin2 = 9: 0.5 fast_log2(9) = 0.5 * 3.125 = 1.5625, truncated -> 1; clamped to the chain.
    dv = np.array([[0.0, 3.0]], np.float32)
    assert texture.llvmpipe_aniso_levels(du, dv, 9)[0] == 1
    assert texture.llvmpipe_aniso_levels(du * 1000, dv * 1000, 3)[0] == 2
    # Magnified (pmin2 < 1): level 0.
    assert texture.llvmpipe_aniso_levels(du / 1000, dv / 1000, 9)[0] == 0


def test_llvmpipe_ewa_table():
    table = texture.llvmpipe_ewa_table()
    assert table.dtype == np.float32 and table.shape == (1024,)
    assert table[0] == 1 and table[1023] == pytest.approx(np.exp(-2), rel=1e-6)
    assert (np.diff(table) < 0).all()


def test_llvmpipe_ewa_weights_are_normalized_and_ignore_max_anisotropy():
    """A constant texture filters to itself; the result does not depend on
    maxAniso (22.3's clamp never fires); the ellipse spans Px x Py texels."""
    levels = tuple(np.full((2 ** (4 - k), 2 ** (4 - k), 4), 77, np.uint8) for k in range(5))
    tex = texture.MipTexture("c", levels, "repeat", "repeat", "linear_mipmap_linear", "linear", 16.0)
    rng = np.random.default_rng(3)
    st = rng.uniform(0, 1, (50, 2))
    ddx, ddy = rng.uniform(-0.5, 0.5, (50, 2)), rng.uniform(-0.05, 0.05, (50, 2))
    out, reads = texture.sample_anisotropic_llvmpipe(tex, st, ddx, ddy)
    np.testing.assert_allclose(out * 255, 77, atol=1e-3)
    assert (reads >= 1).all()
    ramp16, ramp2 = _ramp_texture("linear_mipmap_linear", "linear", 16), _ramp_texture("linear_mipmap_linear", "linear", 2)
    np.testing.assert_array_equal(texture.sample(ramp16, st, ddx, ddy, "gl"), texture.sample(ramp2, st, ddx, ddy, "gl"))
    # Px = 8, Py = 1 texels on level 0: the ellipse reaches ~4 texels either side along u, ~1 along v.
    _, reads = texture.sample_anisotropic_llvmpipe(ramp16, np.array([[0.5, 0.5]]),
                                                   np.array([[8 / 16, 0.0]]), np.array([[0.0, 1 / 16]]))
    assert 12 <= reads[0] <= 40


@pytest.mark.parametrize("mode", ["repeat", "clamp_to_edge", "mirrored_repeat"])
def test_compiled_wrap_index_equals_wrap_for_power_of_two_and_other_sizes(mode):
    i = np.arange(-70, 70)
    for size in (1, 2, 3, 7, 8, 16, 17):
        got = [texture.wrap_index(int(k), size, texture.WRAP_CODES[mode]) for k in i]
        assert got == texture.wrap(i, size, mode).tolist(), (mode, size)
