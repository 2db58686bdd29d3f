"""Per-sample operations: depth functions, blend equations, resolve."""

import numpy as np
import pytest

from softras.pipeline import ops


def _apply(z, stored, func, write=True, blend="none", src=(1, 0, 0, 1), dst=(0, 0, 1, 1)):
    color = np.array(dst, float).reshape(1, 1, 1, 4).copy()
    depth = np.full((1, 1, 1), stored)
    ops.apply_fragments(np.array([0], np.int32), np.array([0], np.int32), np.array([1], np.uint32),
                        np.array([[z]]), np.array([src], float), color, depth,
                        ops.DEPTH_FUNCS[func], write, ops.BLEND_MODES[blend], False)
    return color[0, 0, 0], depth[0, 0, 0]


@pytest.mark.parametrize("func, passes", [
    ("never", [False, False, False]), ("less", [True, False, False]), ("equal", [False, True, False]),
    ("lequal", [True, True, False]), ("greater", [False, False, True]), ("notequal", [True, False, True]),
    ("gequal", [False, True, True]), ("always", [True, True, True]), (None, [True, True, True]),
])
def test_depth_functions(func, passes):
    for z, expected in zip([0.25, 0.5, 0.75], passes):
        color, depth = _apply(z, 0.5, func)
        assert (color[0] == 1.0) == expected
        # A disabled depth test never writes depth (GL).
        assert depth == (z if expected and func is not None else 0.5)


def test_depth_write_mask():
    color, depth = _apply(0.25, 0.5, "less", write=False)
    assert color[0] == 1.0 and depth == 0.5


@pytest.mark.parametrize("mode, expected", [
    # src = (0.4, 0.2, 0, 0.5) premultiplied, dst = (0.2, 0.6, 0.8, 1)
    ("over", [0.4 + 0.5 * 0.2, 0.2 + 0.5 * 0.6, 0.5 * 0.8, 0.5 + 0.5]),
    ("over_straight", [0.4 * 0.5 + 0.5 * 0.2, 0.2 * 0.5 + 0.5 * 0.6, 0.5 * 0.8, 0.25 + 0.5]),
    ("add", [0.6, 0.8, 0.8, 1.5]),
    ("subtract", [0.2, -0.4, -0.8, -0.5]),
    ("reverse_subtract", [-0.2, 0.4, 0.8, 0.5]),
    ("min", [0.2, 0.2, 0.0, 0.5]),
    ("max", [0.4, 0.6, 0.8, 1.0]),
])
def test_blend_equations_unclamped(mode, expected):
    color, _ = _apply(0.1, 0.5, "always", blend=mode, src=(0.4, 0.2, 0, 0.5), dst=(0.2, 0.6, 0.8, 1))
    np.testing.assert_allclose(color, expected)


def test_quantize_unorm8_half_to_even_and_clamp():
    np.testing.assert_array_equal(ops.quantize_unorm8(np.array([0.5, 1.5, -0.1])) * 255, [128, 255, 0])


def test_resolve_averages_samples_and_flips_rows():
    color = np.zeros((2, 1, 4, 4))
    color[0, 0, :2] = 1.0          # bottom row (GL row 0): 2 of 4 samples white
    image = ops.resolve(color)
    assert image[1, 0, 0] == 128 and image[0, 0, 0] == 0


# ----------------------------------------------------------------------------- RGBA8 blending (gl precision)
# llvmpipe's arithmetic (Mesa 22.3); tests/test_blend_gl.py checks it against glref.

def test_unorm8_rounds_the_float32_product_half_to_even():
    assert ops.unorm8(0.5) == 128                    # 127.5 -> 128 (even)
    assert ops.unorm8(0.4) == 102 and ops.unorm8(1.0) == 255 and ops.unorm8(0.0) == 0
    assert ops.unorm8(1.7) == 255 and ops.unorm8(-0.2) == 0 and ops.unorm8(float("nan")) == 0
    # float32 arithmetic: 0.5 / 255 * 255 is 0.5 in float32 -> 0 (even); 1.5 / 255 -> 2.
    assert ops.unorm8(0.5 / 255) == 0 and ops.unorm8(1.5 / 255) == 2


def test_mul_unorm8_is_round_x_y_over_255_but_for_24_pairs():
    a = np.arange(256)[:, None]
    b = np.arange(256)[None, :]
    got = np.array([[ops.mul_unorm8(int(x), int(y)) for y in range(256)] for x in range(256)])
    exact = np.floor(a * b / 255 + 0.5)
    low = got != exact
    assert low.sum() == 24
    # Each of them is one below, with x * y = 255 k + 128 (k >= 136).
    assert np.all(exact[low] - got[low] == 1) and np.all((a * b)[low] % 255 == 128)
    assert ops.mul_unorm8(152, 229) == 136 and ops.mul_unorm8(255, 255) == 255 and ops.mul_unorm8(0, 255) == 0


@pytest.mark.parametrize("mode, expected", [
    # src bytes (102, 51, 0, 128) = unorm8 of (0.4, 0.2, 0, 0.5); dst bytes (51, 153, 204, 255).
    # over: s + mul(d, 127): mul(51, 127) = 25, mul(153, 127) = 76, mul(204, 127) = 102, mul(255, 127) = 127.
    ("over", [127, 127, 102, 255]),
    # over_straight: mul(s, 128) + mul(d, 127): mul(102, 128) = 51, mul(51, 128) = 26, mul(128, 128) = 64.
    ("over_straight", [76, 102, 102, 191]),
    ("add", [153, 204, 204, 255]),                   # saturates at 255
    ("subtract", [51, 0, 0, 0]),                     # saturates at 0
    ("reverse_subtract", [0, 102, 204, 127]),
    ("min", [51, 51, 0, 128]),
    ("max", [102, 153, 204, 255]),
])
def test_blend_unorm8_by_hand(mode, expected):
    out = np.zeros(4, np.int64)
    ops.blend_unorm8(ops.BLEND_MODES[mode], np.array([102, 51, 0, 128]), np.array([51, 153, 204, 255]), out)
    assert out.tolist() == expected
    # apply_fragments in RGBA8 (quantize) stores the same bytes as k/255.
    color = np.array([51, 153, 204, 255], float).reshape(1, 1, 1, 4) / 255
    ops.apply_fragments(np.array([0], np.int32), np.array([0], np.int32), np.array([1], np.uint32),
                        np.array([[0.1]]), np.array([[0.4, 0.2, 0.0, 0.5]]), color, np.full((1, 1, 1), 0.5),
                        ops.DEPTH_FUNCS["always"], True, ops.BLEND_MODES[mode], True)
    np.testing.assert_array_equal(np.rint(color[0, 0, 0] * 255), expected)
    np.testing.assert_array_equal(color[0, 0, 0], np.array(expected) / 255)
