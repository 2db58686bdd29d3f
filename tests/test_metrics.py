"""Tests for softras.verification.metrics: compare(), Comparison and the difference heat map."""

import json

import numpy as np
import pytest

from softras.verification.metrics import Comparison, ShapeMismatch, compare, diff_heatmap


def random_image(height=24, width=32, seed=0):
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 256, size=(height, width, 4), dtype=np.uint8)
    image[..., 3] = 255
    return image


def test_identical_images_pass():
    a = random_image()
    result = compare(a, a.copy())
    assert isinstance(result, Comparison)
    assert result.ssim == pytest.approx(1.0, abs=1e-12)
    assert result.max_diff == 0
    assert result.bad_pixels == 0
    assert result.bad_fraction == 0.0
    assert result.passed
    assert np.all(result.diff_image[..., :3] == 0)


def test_one_pixel_changed_by_10():
    a = random_image()
    b = a.copy()
    b[5, 7, 1] = a[5, 7, 1] + 10 if a[5, 7, 1] < 200 else a[5, 7, 1] - 10
    result = compare(a, b, threshold=2)
    assert result.max_diff == 10
    assert result.bad_pixels == 1
    assert result.bad_fraction == pytest.approx(1 / (24 * 32))
    # Exactly one non-black pixel in the heat map, where the change is.
    lit = np.argwhere(result.diff_image[..., :3].any(axis=-1))
    assert lit.tolist() == [[5, 7]]
    # 1/768 > 0.001 bad pixels: fails on the pixel criterion.
    assert not result.passed
    assert compare(a, b, max_bad_fraction=0.01, min_ssim=0.0).passed


def test_difference_within_threshold_is_not_bad():
    a = random_image()
    b = a.copy()
    b[..., 0] = np.where(a[..., 0] < 255, a[..., 0] + 1, 254)
    result = compare(a, b, threshold=2)
    assert result.max_diff == 1
    assert result.bad_pixels == 0
    assert result.passed


def test_ssim_criterion_alone_fails():
    a = random_image()
    b = random_image(seed=1)
    result = compare(a, b, threshold=255, max_bad_fraction=1.0, min_ssim=0.99)
    assert result.bad_pixels == 0
    assert result.ssim < 0.5
    assert not result.passed


def test_shape_mismatch_raises():
    with pytest.raises(ValueError, match="differ in shape"):
        compare(random_image(24, 32), random_image(24, 31))
    with pytest.raises(ShapeMismatch):
        compare(random_image(24, 32), random_image(24, 32)[..., :3])


def test_non_uint8_raises():
    # Float images are compared unrounded (rgba32f renders, tests/stages/test_resolve.py);
    # other dtypes are refused.
    a = random_image()
    with pytest.raises(ValueError, match="uint8"):
        compare(a.astype(np.int32), a.astype(np.int32))


@pytest.mark.parametrize(
    "options",
    [{"threshold": -1}, {"threshold": 256}, {"threshold": 1.5}, {"max_bad_fraction": 2.0}, {"min_ssim": 1.5}],
)
def test_bad_tolerance_raises(options):
    a = random_image()
    with pytest.raises(ValueError):
        compare(a, a, **options)


def test_diff_image_shape_and_dtype():
    a = random_image(10, 13)
    b = random_image(10, 13, seed=3)
    result = compare(a, b)
    assert result.diff_image.shape == (10, 13, 4)
    assert result.diff_image.dtype == np.uint8
    assert np.all(result.diff_image[..., 3] == 255)
    assert result.ssim_map.shape == (10, 13)
    assert result.ssim_map.dtype == np.float64


def test_heatmap_scale():
    threshold = 4
    diff = np.array([[0, 2, 4, 5, 40, 255]])
    image = diff_heatmap(diff, threshold)
    zero, within_low, within_top, just_bad, bad, worst = (image[0, i, :3].astype(int) for i in range(6))
    assert zero.tolist() == [0, 0, 0]
    # Within tolerance: blue, brighter as d approaches the threshold.
    for colour in (within_low, within_top):
        assert colour[2] > colour[0] and colour[2] > colour[1]
    assert within_top[2] > within_low[2]
    # Over the threshold: red first, then towards yellow, then white.
    assert just_bad[0] > 100 and just_bad[1] == 0 and just_bad[2] == 0
    assert bad[0] == 255 and bad[2] < bad[0]
    assert worst.tolist() == [255, 255, 255]
    assert np.all(image[..., 3] == 255)


def test_heatmap_threshold_zero_and_255():
    assert diff_heatmap(np.array([[0, 1, 255]]), 0)[0, 1, 0] > 100  # red at once
    within = diff_heatmap(np.array([[255]]), 255)[0, 0, :3]
    assert within[2] == 255 and within[0] < 255  # all within tolerance: blue


@pytest.mark.parametrize("size", [(3, 3), (1, 1), (2, 5), (6, 6), (7, 7), (4, 40)])
def test_tiny_images(size):
    a = random_image(*size)
    same = compare(a, a.copy())
    assert same.ssim == pytest.approx(1.0, abs=1e-12)
    assert same.passed
    b = a.copy()
    b[0, 0, 0] ^= 0x80
    result = compare(a, b)
    assert np.isfinite(result.ssim)
    assert result.max_diff == 128
    assert result.ssim_map.shape == size
    assert result.diff_image.shape == size + (4,)


def test_rgb_and_grey_images_accepted():
    a = random_image()
    assert compare(a[..., :3], a[..., :3]).passed
    assert compare(a[..., 0], a[..., 0]).passed


def test_paths_are_read(tmp_path):
    from softras.scene.imageio import write_png_atomic

    a = random_image()
    write_png_atomic(tmp_path / "a.png", a)
    result = compare(tmp_path / "a.png", a)
    assert result.max_diff == 0


def test_to_dict_is_json_and_has_no_arrays():
    a = random_image()
    b = a.copy()
    b[0, 0, 0] ^= 0xFF
    data = compare(a, b).to_dict()
    text = json.dumps(data)
    assert json.loads(text) == data
    for key in ("passed", "ssim", "max_diff", "bad_fraction", "bad_pixels", "threshold",
                "min_ssim", "max_bad_fraction", "width", "height"):
        assert key in data
    assert data["width"] == 32 and data["height"] == 24
    assert data["passed"] is False


def test_summary_is_one_line():
    a = random_image()
    summary = compare(a, a).summary()
    assert summary.startswith("PASS")
    assert "\n" not in summary
