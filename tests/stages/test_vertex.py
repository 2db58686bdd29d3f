"""Vertex stage: model -> clip."""

import numpy as np

from softras import vertex


def test_identity_matrix_keeps_positions_exactly():
    p = np.array([[0.1, -0.7, 0.3], [1e-7, 3.0, -2.5]])
    for precision in ("gl", "exact"):
        clip = vertex.to_clip(p, np.eye(4), precision)
        np.testing.assert_array_equal(clip[:, :3], p.astype(np.float32) if precision == "gl" else p)
        np.testing.assert_array_equal(clip[:, 3], 1.0)


def test_translation_and_projection_by_hand():
    # Translate by (1, 2, 3), then a projection whose w row copies -z:
    # (0, 0, -5) -> translated (1, 2, -2) -> w = 2.
    mvp = np.array([[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, -1, -3]], float)
    clip = vertex.to_clip(np.array([[0.0, 0.0, -5.0]]), mvp, "exact")
    np.testing.assert_allclose(clip, [[1, 2, -2, 2]])


def test_gl_precision_rounds_like_float32():
    mvp = np.diag([1 / 3, 1 / 3, 1.0, 1.0])
    clip = vertex.to_clip(np.array([[1.0, 2.0, 0.0]]), mvp, "gl")
    assert clip[0, 0] == np.float32(np.float32(1 / 3) * np.float32(1.0))
    assert clip[0, 0] != 1 / 3
