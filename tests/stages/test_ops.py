"""Per-sample operations: depth functions, blend equations, resolve."""

import numpy as np
import pytest

from softras import ops


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
