"""Interpolate stage: barycentrics and perspective correction."""

import numpy as np

from softras.pipeline import interpolate, setup


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


# --------------------------------------------------------------------------- screen-space derivatives


def _one_triangle(fragments):
    """A perspective triangle's per-fragment arrays (vertices, inv_w, values)."""
    clip = np.array([[[-0.9, -0.8, 0.1, 1.0], [2.4, -1.2, 0.5, 3.0], [0.3, 1.5, 0.9, 2.0]]])
    offsets, unit = setup.sample_offsets(np.array([[0.5, 0.5]]), "exact")
    tris = setup.setup_triangles(clip, 64, 48, precision="exact", offsets=offsets, unit=unit)
    values = np.array([[0.0, 1.0], [2.0, -1.0], [0.5, 3.0]])[tris.corner[0]][None]
    t = np.zeros(fragments, np.int64)
    return tris.window[t], tris.inv_w[t], values[t]


def test_analytic_derivatives_match_finite_differences():
    vertices, inv_w, values = _one_triangle(5)
    points = np.array([[20.5, 10.5], [30.5, 20.5], [12.5, 30.5], [40.5, 5.5], [25.5, 25.5]])
    ddx, ddy = interpolate.analytic_derivatives(vertices, inv_w, points, values)
    h = 1e-5

    def at(p):
        return interpolate.perspective_at(vertices, inv_w, values, p)

    fx = (at(points + [h, 0]) - at(points - [h, 0])) / (2 * h)
    fy = (at(points + [0, h]) - at(points - [0, h])) / (2 * h)
    np.testing.assert_allclose(ddx, fx, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(ddy, fy, rtol=1e-6, atol=1e-9)


def test_quad_derivatives_are_shared_by_the_quad():
    vertices, inv_w, values = _one_triangle(5)
    x = np.array([20, 21, 20, 21, 22], np.int32)
    y = np.array([10, 10, 11, 11, 10], np.int32)
    ddx, ddy = interpolate.quad_derivatives(vertices, inv_w, x, y, values)
    for k in range(1, 4):
        np.testing.assert_array_equal(ddx[k], ddx[0])
        np.testing.assert_array_equal(ddy[k], ddy[0])
    assert (ddx[4] != ddx[0]).any()
    tl = interpolate.perspective_at(vertices[:1], inv_w[:1], values[:1], np.array([[20.5, 10.5]]))
    tr = interpolate.perspective_at(vertices[:1], inv_w[:1], values[:1], np.array([[21.5, 10.5]]))
    np.testing.assert_allclose(ddx[0], (tr - tl)[0], atol=1e-6)    # float32 values
