"""Interpolate stage: barycentrics and perspective correction."""

import numpy as np

from softras import interpolate


def test_lecture_worked_example():
    # Lecture notes, perspective-correct interpolation: screen-space
    # barycentrics (0.2, 0.1, 0.7), vertex depths w = 1, 2, 4, attributes
    # (0,0,0), (1,0,0), (0,1,0).  b ~ (0.2/1, 0.1/2, 0.7/4) = (0.2, 0.05, 0.175)
    # / 0.425, so the attribute is (0.05/0.425, 0.175/0.425, 0) = (0.1176, 0.4118, 0).
    lam = np.array([[0.2, 0.1, 0.7]])
    inv_w = 1.0 / np.array([[1.0, 2.0, 4.0]])
    weights = interpolate.perspective_weights(lam, inv_w)
    attrs = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    value = interpolate.interpolate(weights, attrs)[0]
    np.testing.assert_allclose(value, [0.12, 0.412, 0.0], atol=0.006)
    np.testing.assert_allclose(value, [0.05 / 0.425, 0.175 / 0.425, 0.0], rtol=1e-12)


def test_barycentric_at_vertices_and_centroid():
    tri = np.array([[[0.0, 0.0], [4.0, 0.0], [0.0, 2.0]]])
    for k in range(3):
        np.testing.assert_allclose(interpolate.barycentric(tri, tri[:, k]), np.eye(3)[k:k + 1], atol=1e-15)
    np.testing.assert_allclose(interpolate.barycentric(tri, tri.mean(axis=1)), [[1 / 3] * 3])


def test_equal_w_means_affine():
    lam = np.array([[0.3, 0.3, 0.4]])
    np.testing.assert_allclose(interpolate.perspective_weights(lam, np.full((1, 3), 0.5)), lam)


def test_depth_is_linear_in_screen_space():
    # z_w = 0.25 + x/16 on this triangle's plane; samples at pixel (1, 1).
    tri = np.array([[[0.0, 0.0, 0.25], [8.0, 0.0, 0.75], [0.0, 8.0, 0.25]]])
    z = interpolate.depth_at_samples(tri, np.array([1]), np.array([1]), np.array([[0.5, 0.5], [0.25, 0.75]]))
    np.testing.assert_allclose(z, [[0.25 + 1.5 / 16, 0.25 + 1.25 / 16]])
