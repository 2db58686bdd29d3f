"""Sample patterns (softras.pipeline.sampling) and rendering with more than 32 samples."""

import numpy as np
import pytest

import softras
from softras.pipeline import coverage, render as pipeline, sampling

SQUARE = [(1, "grid"), (4, "grid"), (9, "rotated_grid"), (16, "jittered"), (1024, "grid"),
          (1024, "rotated_grid"), (1024, "jittered")]
ANY = [(1, "halton"), (7, "halton"), (256, "halton"), (1, "poisson"), (13, "poisson"), (256, "poisson")]


@pytest.mark.parametrize("samples, pattern", SQUARE + ANY + [(1, "gl"), (4, "gl")])
def test_positions_are_s_points_in_the_unit_square(samples, pattern):
    p = sampling.sample_positions(samples, pattern)
    assert p.shape == (samples, 2) and p.dtype == np.float64
    assert (p >= 0).all() and (p < 1).all()


def test_gl_pattern_is_llvmpipes():
    np.testing.assert_array_equal(sampling.sample_positions(1), [[0.5, 0.5]])
    np.testing.assert_array_equal(sampling.sample_positions(4, "gl"),
                                  [[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
    np.testing.assert_array_equal(pipeline.sample_positions(4), sampling.GL_MSAA4)


def test_grid_is_cell_centres_row_by_row():
    np.testing.assert_array_equal(sampling.grid(2), [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]])
    g = sampling.grid(32)
    assert len(np.unique(g, axis=0)) == 1024
    np.testing.assert_array_equal(np.unique(g[:, 0]), (np.arange(32) + 0.5) / 32)


def test_rotated_grid_of_side_2_is_llvmpipes_4x():
    """atan(1/2) rotation + stretch of the 2x2 grid: sample for sample llvmpipe's positions."""
    np.testing.assert_array_equal(sampling.rotated_grid(2), sampling.GL_MSAA4)


@pytest.mark.parametrize("side", [2, 3, 5, 8, 32])
def test_rotated_grid_puts_every_sample_in_its_own_row_and_column(side):
    s = side * side
    p = sampling.rotated_grid(side)
    expected = (np.arange(s) + 0.5) / s
    np.testing.assert_allclose(np.sort(p[:, 0]), expected, atol=1e-12)
    np.testing.assert_allclose(np.sort(p[:, 1]), expected, atol=1e-12)


def test_jittered_has_one_sample_per_stratum_and_is_seeded():
    p = sampling.jittered(8, seed=3)
    cells = np.floor(p * 8).astype(int)
    assert len({tuple(c) for c in cells}) == 64
    np.testing.assert_array_equal(p, sampling.jittered(8, seed=3))
    assert not np.array_equal(p, sampling.jittered(8, seed=4))


def test_halton_first_points_by_hand():
    """Radical inverses of 1, 2, 3 in base 2: 1/2, 1/4, 3/4; in base 3: 1/3, 2/3, 1/9."""
    np.testing.assert_allclose(sampling.halton(3), [[1 / 2, 1 / 3], [1 / 4, 2 / 3], [3 / 4, 1 / 9]])


def test_poisson_disk_keeps_its_distance_and_is_seeded():
    p = sampling.poisson_disk(64, seed=5)
    d = np.abs(p[:, None] - p[None])
    d = np.minimum(d, 1 - d)                               # on the torus
    dist = np.sqrt((d ** 2).sum(axis=2)) + np.eye(64) * 9
    # Dart throwing starts at 0.9 x the hexagonal packing distance and shrinks
    # by 5 % steps; a uniform random set of 64 points would typically have a
    # nearest pair ~0.01 apart.
    assert dist.min() > 0.5 * np.sqrt(2 / (np.sqrt(3) * 64))
    np.testing.assert_array_equal(p, sampling.poisson_disk(64, seed=5))
    # (The points of a first call are kept: a caller's writes to its array
    # reach no later call.)
    p += 1.0
    assert sampling.poisson_disk(64, seed=5).max() < 1.0
    assert not np.array_equal(sampling.poisson_disk(64, seed=6), sampling.poisson_disk(64, seed=5))


@pytest.mark.parametrize("samples, pattern, message", [
    (5, "grid", "N\\*N"), (4096, "grid", "1..1024"), (8, "gl", "1 or 4"), (8, None, "1 or 4"),
    (0, "halton", "1..1024"), (4, "blue_noise", "pattern must be one of"), (2.0, "halton", "integer"),
])
def test_bad_pattern_requests_raise(samples, pattern, message):
    with pytest.raises(ValueError, match=message):
        sampling.sample_positions(samples, pattern)


@pytest.mark.parametrize("samples", [1, 4, 32, 33, 64, 100, 1024])
def test_passes_cover_the_samples_with_at_most_32_and_more_than_one_each(samples):
    passes = sampling.sample_passes(samples)
    assert passes[0][0] == 0 and passes[-1][1] == samples
    assert all(a[1] == b[0] for a, b in zip(passes, passes[1:]))
    sizes = [stop - start for start, stop in passes]
    assert max(sizes) <= 32 and (samples == 1 or min(sizes) > 1)


def _white_triangle_scene(width=24, height=16):
    tri = [[1.3, 0.7], [21.9, 4.2], [6.1, 15.4]]                  # window space
    ndc = [[2 * x / width - 1, 2 * y / height - 1, 0] for x, y in tri]
    ident = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    scene = {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
             "camera": {"view_matrix": ident, "projection_matrix": ident},
             "nodes": [{"name": "t", "mesh": {"positions": ndc}, "depth_test": False}]}
    return scene, np.array([tri])


@pytest.mark.parametrize("samples, pattern", [(64, "grid"), (1024, "grid"), (100, "halton")])
def test_many_samples_render_in_passes_and_converge_to_exact_area(samples, pattern):
    """A white triangle rendered with S > 32 samples (several passes through
    every stage) against its exact area coverage: a straight edge crossing an
    N x N grid misses at most ~2/N of the pixel, and the mean error is far
    smaller; passes written to the wrong slice would break both bounds."""
    scene, tri = _white_triangle_scene()
    image = softras.render(scene, precision="exact", samples=samples, pattern=pattern)
    exact = coverage.coverage_image(tri, 24, 16)[::-1]                   # row 0 = top
    error = image[..., 0] / 255.0 - exact
    side = int(np.sqrt(samples))
    assert np.abs(error).max() <= 2.0 / side + 0.5 / 255
    assert np.abs(error).mean() < 0.25 / side


def test_more_samples_means_less_coverage_error():
    scene, tri = _white_triangle_scene()
    exact = coverage.coverage_image(tri, 24, 16)[::-1]
    errors = [np.abs(softras.render(scene, precision="exact", samples=n * n, pattern="grid")[..., 0] / 255.0
                     - exact).mean() for n in (1, 2, 4, 8, 16)]
    assert all(a > b for a, b in zip(errors, errors[1:])), errors


def test_absurd_sample_buffers_are_refused():
    scene = {"softras_scene": 1, "width": 1024, "height": 1024, "nodes": []}
    with pytest.raises(ValueError, match="GiB of sample colour"):
        softras.render(scene, samples=1024, pattern="grid")
