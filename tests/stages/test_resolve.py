"""Resolve filters (softras.pipeline.ops.resolve): box, tent, llvmpipe's float32 box; float output.

The GL tests check the llvmpipe arithmetic and the rgba32f framebuffer against
glref (Mesa llvmpipe) on the MSAA and blend scenes.
"""

import json
from pathlib import Path

import numpy as np
import pytest

import softras
from softras.pipeline import ops, sampling

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def _pixels(*samples):
    """(1, 1, S, 4) buffer from S byte values (all four channels alike)."""
    v = np.array(samples, float) / 255.0
    return np.repeat(v[None, None, :, None], 4, axis=3)


def test_box_is_the_mean_rounded_half_to_even():
    assert ops.resolve(_pixels(255, 255, 0, 0))[0, 0, 0] == 128        # 127.5 -> 128
    assert ops.resolve(_pixels(10, 20, 30, 41))[0, 0, 0] == 25          # 25.25


def test_llvmpipe_arithmetic_by_hand():
    """Samples 161, 139, 143, 239: the exact mean is 170.5 -> 170 (half to even).
    llvmpipe in float32: each v * float32(1/255) summed, * 0.25, * 255 gives
    170.50002 -> 171 (float32 values computed step by step with numpy)."""
    c = _pixels(161, 139, 143, 239)
    f = np.float32(1 / 255)
    total = np.float32(0)
    for v in (161, 139, 143, 239):
        total = np.float32(total + np.float32(np.float32(v) * f))
    assert np.float32(np.float32(total * np.float32(0.25)) * np.float32(255)) > np.float32(170.5)
    assert ops.resolve(c)[0, 0, 0] == 170
    assert ops.resolve(c, arithmetic="llvmpipe")[0, 0, 0] == 171


def test_llvmpipe_arithmetic_keeps_single_sample_bytes():
    c = (np.arange(256, dtype=float) / 255.0)[:, None, None, None].repeat(4, axis=3)
    assert (ops.resolve(c, arithmetic="llvmpipe")[::-1, 0, 0] == np.arange(256)).all()


def test_compiled_byte_resolve_equals_the_float32_formula():
    """`resolve_llvmpipe_bytes` (one compiled loop, what the fast path's MSAA
    bytes take) = the documented float32 steps written as numpy, for every
    byte in every sample slot and random 1, 2, 4, 8-sample pixels; flipped."""
    rng = np.random.default_rng(7)
    for n_samples in (1, 2, 4, 8):
        stored = rng.integers(0, 256, size=(37, 11, n_samples, 4), dtype=np.uint8)
        stored[:7] = (np.arange(7 * 11 * n_samples * 4) % 256).reshape(7, 11, n_samples, 4)   # every byte
        values = stored.astype(np.float32) * np.float32(1.0 / 255.0)
        total = np.zeros(stored.shape[:2] + (4,), np.float32)
        for s in range(n_samples):
            total += values[:, :, s]
        mean = total * np.float32(1.0 / n_samples)
        expected = np.rint(np.clip(mean * np.float32(255.0), 0, 255)).astype(np.uint8)[::-1]
        np.testing.assert_array_equal(ops.resolve_llvmpipe_bytes(stored), expected)
        np.testing.assert_array_equal(ops.resolve(stored / 255.0, arithmetic="llvmpipe"), expected)


def test_compiled_exact_resolve_equals_the_float_resolve():
    """`resolve_exact_bytes` (what the fast path's bytes take at a pattern
    other than GL's) = `resolve`'s exact box filter of the k/255 values, for
    every byte in every sample slot, random bytes and tie-heavy pixels (few
    distinct bytes: means on a half step, where the summation order decides
    the rounding; summing in reverse order changes thousands of these
    bytes) at every sample count up to 32 and beyond; flipped."""
    rng = np.random.default_rng(11)
    for n_samples in list(range(1, 33)) + [64, 100]:
        every = (np.arange(7 * 11 * n_samples * 4) % 256).reshape(7, 11, n_samples, 4)
        random = rng.integers(0, 256, size=(24, 11, n_samples, 4))
        ties = rng.integers(0, 3, size=(24, 11, n_samples, 4)) * rng.integers(1, 128, size=(24, 11, 1, 4))
        stored = np.concatenate([every, random, ties]).astype(np.uint8)
        np.testing.assert_array_equal(ops.resolve_exact_bytes(stored),
                                      ops.resolve(stored / 255.0, arithmetic="exact"), err_msg=f"{n_samples}")


def test_tent_weights_by_hand():
    """3 x 1 image, 2 x 2 grid samples (at .25/.75): the middle pixel white.

    From the left pixel's centre, the middle pixel's samples sit at
    dx = 0.75 and 1.25, weights (1 - 0.75) = 0.25 and 0 in x, 0.75 in y (dy =
    +-0.25): 2 x 0.1875 = 0.375 of white; its own four samples weigh
    0.75 x 0.75 each = 2.25; no left or vertical neighbours.  Left: 0.375 /
    2.625 = 1/7 -> 36.4 -> 36.  Middle: 2.25 / (2.25 + 2 x 0.375) = 0.75 ->
    191.25 -> 191."""
    color = np.zeros((1, 3, 4, 4))
    color[0, 1] = 1.0
    image = ops.resolve(color, sampling.grid(2), filter="tent")
    assert image[0, :, 0].tolist() == [36, 191, 36]


def test_tent_keeps_a_flat_colour_and_equals_box_for_the_centre_sample():
    flat = np.full((5, 6, 16, 4), 0.3)
    np.testing.assert_allclose(ops.resolve(flat, sampling.halton(16), filter="tent", output="float32"), 0.3,
                               rtol=1e-6)
    rng = np.random.default_rng(2)
    one = rng.uniform(size=(5, 6, 1, 4))
    np.testing.assert_array_equal(ops.resolve(one, sampling.GL_CENTER, filter="tent"), ops.resolve(one))


def _tent_in_numpy(color, positions):
    """The tent filter written in numpy in `ops._tent_filter`'s documented
    order: per neighbour (dy, then dx), its samples times their weights
    summed in sample order, added to the total."""
    height, width = color.shape[:2]
    total, weight = np.zeros((height, width, 4)), np.zeros((height, width, 1))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            w = ops._tent(dx + positions[:, 0] - 0.5) * ops._tent(dy + positions[:, 1] - 0.5)
            y0, y1, x0, x1 = max(0, -dy), height - max(0, dy), max(0, -dx), width - max(0, dx)
            if not w.any() or y0 >= y1 or x0 >= x1:
                continue
            neighbour = color[y0 + dy:y1 + dy, x0 + dx:x1 + dx]
            partial = neighbour[:, :, 0] * w[0]
            for s in range(1, len(w)):
                partial = partial + neighbour[:, :, s] * w[s]
            total[y0:y1, x0:x1] += partial
            weight[y0:y1, x0:x1] += w.sum()
    return total / weight


@pytest.mark.parametrize("positions", [sampling.GL_CENTER, sampling.grid(2), sampling.grid(3), sampling.halton(5),
                                       sampling.halton(16), sampling.rotated_grid(4)],
                         ids=["1", "grid4", "grid9", "halton5", "halton16", "rotated4"])
def test_the_compiled_tent_is_the_numpy_sum_and_reads_bytes_as_their_values(positions):
    """`ops._tent_filter` (a compiled loop) gives the float64 values of the
    same sums written in numpy, to the bit; fed an RGBA8 buffer's bytes it
    gives the picture of their k/255 values (what `render.resolve_bytes`
    passes it, without a float copy)."""
    rng = np.random.default_rng(len(positions))
    stored = rng.integers(0, 256, size=(7, 9, len(positions), 4)).astype(np.uint8)
    values = stored / 255.0
    np.testing.assert_array_equal(ops._tent_filter(values, positions), _tent_in_numpy(values, positions))
    wide = rng.normal(size=(5, 6, len(positions), 4)) * 3.0                        # (unclamped, signed)
    np.testing.assert_array_equal(ops._tent_filter(wide, positions), _tent_in_numpy(wide, positions))
    for output in ("uint8", "float32"):
        np.testing.assert_array_equal(ops.resolve(stored, positions, filter="tent", output=output),
                                      ops.resolve(values, positions, filter="tent", output=output))


def test_float_output_is_unclamped_and_flipped():
    color = np.zeros((2, 1, 2, 4))
    color[0, 0] = [[1.5, -0.5, 0.25, 1.0], [0.5, -0.5, 0.25, 1.0]]      # GL row 0 = bottom
    image = ops.resolve(color, output="float32")
    assert image.dtype == np.float32
    np.testing.assert_array_equal(image[1, 0], [1.0, -0.5, 0.25, 1.0])


@pytest.mark.parametrize("bad, message", [({"filter": "gauss"}, "filter"), ({"arithmetic": "fast"}, "arithmetic"),
                                          ({"output": "uint16"}, "output"), ({"filter": "tent"}, "positions")])
def test_bad_resolve_options_raise(bad, message):
    with pytest.raises(ValueError, match=message):
        ops.resolve(np.zeros((1, 1, 4, 4)), **bad)


# --------------------------------------------------------------------------- against GL

def _differing(a, b):
    return int((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 0).sum())


@pytest.mark.gl
@pytest.mark.parametrize("name", ["line_star", "msaa_fan"])
def test_msaa_resolve_matches_llvmpipe_pixel_for_pixel(name):
    """With llvmpipe's float32 resolve, 4x MSAA line_star and msaa_fan are
    identical to GL (with the exact-mean resolve: 1031 and 310 pixels 1/255
    off, measured when it was introduced)."""
    scene = softras.load_scene(SCENES / f"{name}.json")
    gl = softras.render(scene, backend="gl", samples=4)
    assert _differing(softras.render(scene, samples=4), gl) == 0


@pytest.mark.gl
@pytest.mark.parametrize("name", ["blend_equations", "blend_self_overlap", "line_star", "msaa_fan",
                                  "transparent_over_opaque"])
@pytest.mark.parametrize("samples", [1, 4])
def test_rgba32f_framebuffer_agrees_with_gl(name, samples):
    """An RGBA32F framebuffer in both renderers: no 8-bit rounding after each
    blend, so softras and llvmpipe agree to float32 rounding (here < 2e-5;
    measured max 6e-6 on line_star, 3.6e-7 on blend_equations).  (The RGBA8
    pictures, with llvmpipe's byte blend reproduced, differ on 1 pixel by
    1/255: msaa_fan at one sample.)"""
    scene = softras.load_scene(SCENES / f"{name}.json")
    soft = softras.render(scene, samples=samples, framebuffer="rgba32f")
    gl = softras.render(scene, backend="gl", samples=samples, framebuffer="rgba32f")
    assert soft.dtype == gl.dtype == np.float32 and soft.shape == gl.shape
    result = softras.compare(soft, gl, threshold=1, max_bad_fraction=0)     # compares floats unrounded
    assert result.passed and result.max_abs_diff < 2e-5
    assert result.max_abs_diff == pytest.approx(float(np.abs(soft - gl).max()), rel=1e-9)


@pytest.mark.gl
def test_rgba32f_is_unclamped_in_both_renderers():
    """add and subtract leave [0, 1] in a float buffer: both renderers keep the values."""
    scene = softras.load_scene(SCENES / "blend_equations.json")
    for backend in ("soft", "gl"):
        image = softras.render(scene, backend=backend, framebuffer="rgba32f")
        assert image.max() > 1.5 and image.min() < -0.5, backend


@pytest.mark.gl
def test_closure_example_in_rgba32f():
    """Red alpha 0.5 over red alpha 0.5 over nothing = (0.75, 0, 0, 0.75), exactly in float."""
    quad = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "indices": [[0, 1, 2], [0, 2, 3]]}
    red = {"name": "r", "mesh": quad, "material": {"color": [1, 0, 0, 0.5]}, "blend": "over", "depth_test": False}
    scene = {"softras_scene": 1, "width": 4, "height": 4, "background": [0, 0, 0, 0],
             "framebuffer": "rgba32f", "nodes": [red, dict(red, name="r2")]}
    for backend in ("soft", "gl"):
        image = softras.render(scene, backend=backend)
        np.testing.assert_allclose(image, np.broadcast_to([0.75, 0, 0, 0.75], image.shape), atol=1e-6)


def test_framebuffer_key_is_validated():
    base = json.loads((SCENES / "msaa_fan.json").read_text())
    with pytest.raises(softras.SceneError, match="framebuffer"):
        softras.load_scene(dict(base, framebuffer="rgba16f"))
    assert softras.load_scene(dict(base, framebuffer="rgba32f")).framebuffer == "rgba32f"
    assert softras.load_scene(base).framebuffer == "rgba8"
