"""Exact analytic area coverage (softras.pipeline.coverage), checked by hand."""

import numpy as np
import pytest

from softras.pipeline import coverage, sampling


def test_half_pixel_triangle_covers_one_half():
    """The triangle (0,0) (1,0) (0,1) is half of pixel (0, 0) and nothing else."""
    areas = coverage.pixel_areas(np.array([[[0, 0], [1, 0], [0, 1]]], float), 4, 4)
    assert areas.tri.tolist() == [0] and (areas.x[0], areas.y[0]) == (0, 0)
    assert areas.area[0] == pytest.approx(0.5, abs=1e-15)


def test_triangle_over_the_pixel_covers_it_fully():
    image = coverage.coverage_image(np.array([[[-2, -2], [6, -2], [-2, 6]]], float), 3, 3)
    # Window space, y up: the hypotenuse x + y = 4 halves pixels (1, 2), (2, 1)
    # and misses (2, 2); every other pixel is inside.
    expected = np.array([[1, 1, 1], [1, 1, 0.5], [1, 0.5, 0]])
    np.testing.assert_allclose(image, expected, atol=1e-14)


def test_area_by_hand_for_a_thin_sliver():
    """Sliver (0, 0.25) (3, 0.25) (3, 0.75): over pixel column i its height grows
    linearly, 1/6 per pixel; areas (1/12, 3/12, 5/12) x 1/2 ... by integration:
    area in [i, i+1] = (1/6) * ((i+1)^2 - i^2) / 2."""
    areas = coverage.pixel_areas(np.array([[[0, 0.25], [3, 0.25], [3, 0.75]]], float), 4, 2)
    expected = [(1 / 6) * ((i + 1) ** 2 - i ** 2) / 2 for i in range(3)]
    np.testing.assert_allclose(areas.area, expected, atol=1e-15)
    assert areas.x.tolist() == [0, 1, 2] and areas.y.tolist() == [0, 0, 0]


def test_areas_sum_to_the_triangle_area():
    rng = np.random.default_rng(20240611)
    tris = rng.uniform(0.0, 40.0, size=(200, 3, 2))
    areas = coverage.pixel_areas(tris, 40, 40)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    expected = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    np.testing.assert_allclose(np.bincount(areas.tri, areas.area, minlength=200), expected, atol=1e-9)
    assert (areas.area > 0).all() and (areas.area <= 1 + 1e-12).all()


def test_parts_outside_the_image_are_not_counted():
    # A 4 x 4 square as two triangles, half of it left of the image.
    tris = np.array([[[-2, 0], [2, 0], [2, 4]], [[-2, 0], [2, 4], [-2, 4]]], float)
    assert coverage.coverage_image(tris, 8, 8).sum() == pytest.approx(8.0)


def test_fan_is_watertight_in_exact_area():
    """Triangles of a fan sharing edges: coverage sums to exactly 1 per pixel inside."""
    angles = np.linspace(0, 2 * np.pi, 13)
    centre = np.array([16.0, 16.0])
    rim = centre + 15.5 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    tris = np.stack([np.broadcast_to(centre, (12, 2)), rim[:-1], rim[1:]], axis=1)
    image = coverage.coverage_image(tris, 32, 32)
    assert image.max() <= 1 + 1e-12
    np.testing.assert_allclose(image[10:22, 10:22], 1.0, atol=1e-12)


def test_clip_to_box_and_polygon_area():
    square = coverage.clip_to_box(np.array([[-1, -1], [3, -1], [3, 3], [-1, 3]], float), 0, 0, 1, 1)
    assert coverage.polygon_area(square) == pytest.approx(1.0)
    assert coverage.polygon_area(coverage.clip_to_box(np.array([[5, 5], [6, 5], [5, 6]], float), 0, 0, 1, 1)) == 0


def test_sampled_coverage_counts_the_rasterizers_samples():
    """Pixel centre only: a pixel is 1 when its centre is inside, like GL; a
    4 x 4 grid on the half-pixel triangle counts the 6 cell centres below the
    diagonal x + y < 1 (cells (i, j) with i + j < 3) of 16."""
    tri = np.array([[[0, 0], [1, 0], [0, 1]]], float)
    assert len(coverage.sampled_coverage(tri, 2, 2, sampling.sample_positions(1)).tri) == 0
    s = coverage.sampled_coverage(tri, 2, 2, sampling.grid(4))
    assert s.area.tolist() == [6 / 16]


def test_coverage_error_shrinks_with_the_grid():
    rng = np.random.default_rng(7)
    tris = rng.uniform(0.0, 24.0, size=(40, 3, 2))
    rms = [coverage.coverage_error(tris, 24, 24, sampling.grid(n)).rms() for n in (1, 2, 4, 8, 16)]
    assert all(a > b for a, b in zip(rms, rms[1:])), rms
    assert rms[-1] < 0.03


def test_bad_triangles_raise():
    with pytest.raises(ValueError, match="shape"):
        coverage.pixel_areas(np.zeros((2, 3)), 4, 4)
    with pytest.raises(ValueError, match="NaN"):
        coverage.pixel_areas(np.full((1, 3, 2), np.nan), 4, 4)
