"""Vertex stage: model -> clip."""

import numpy as np

from softras.pipeline import vertex


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


def test_gl_precision_is_the_float32_column_sum_bit_for_bit():
    """The compiled float32 loop against numpy's float32 column sum (the shader's
    ``u_mvp * vec4(p, 1)``), without a fused multiply-add, from tiny to overflowing
    magnitudes (inf and NaN where float32 overflows)."""
    rng = np.random.default_rng(7)
    for scale in (1e-30, 1.0, 1e6, 1e30, 1e38):
        p = rng.normal(size=(5000, 3)) * scale
        m = rng.normal(size=(4, 4)) * 3
        with np.errstate(all="ignore"):
            m32, p32 = m.astype(np.float32), p.astype(np.float32)
            expected = ((m32[:, 0] * p32[:, 0:1] + m32[:, 1] * p32[:, 1:2]) + m32[:, 2] * p32[:, 2:3]) + m32[:, 3]
            got = vertex.to_clip(p, m, "gl")
        np.testing.assert_array_equal(got, expected.astype(np.float64))
    # An operand pair whose float32 product is inexact: a fused multiply-add would keep the low bits.
    a = np.float32(1 + 2 ** -12)
    mvp = np.array([[float(a), 0, 0, -1.0]] + [[0, 0, 0, 1.0]] * 3)
    clip = vertex.to_clip(np.array([[float(a), 0.0, 0.0]]), mvp, "gl")
    assert clip[0, 0] == np.float64(np.float32(a * a) - np.float32(1.0))


def test_normal_rows_of_a_stack_are_each_matrix_s_own_bits():
    """`vertex.normal_rows_of` inverts a stack of world matrices in one call
    (the compiled path's `softras.kernels.light.viewing`, once a pass): each
    (3, 4) block is the bits of the matrix inverted alone, ``inv(M3)^T`` with
    column 3 zero, for rotations, shears, mirrors, tiny and huge scales."""
    rng = np.random.default_rng(7)
    worlds = np.tile(np.eye(4), (200, 1, 1))
    worlds[:, :3, :3] = rng.normal(size=(200, 3, 3)) * 10.0 ** rng.integers(-6, 7, size=(200, 1, 1))
    worlds[:, :3, 3] = rng.normal(size=(200, 3))
    stacked = vertex.normal_rows_of(worlds)
    for world, rows in zip(worlds, stacked):
        alone = np.linalg.inv(world[:3, :3]).T
        assert rows[:, :3].tobytes() == alone.tobytes() and not rows[:, 3].any()
        assert vertex.normal_rows(world).tobytes() == rows.tobytes()
