"""Setup stage: viewport, snapping, culling, edge equations."""

import numpy as np
import pytest

from softras.pipeline import setup

ONE_SAMPLE = setup.sample_offsets(np.array([[0.5, 0.5]]), "gl")


def _clip_from_window(tri, width, height):
    clip = np.zeros((1, 3, 4))
    clip[0, :, 0] = np.array(tri)[:, 0] / (width / 2) - 1
    clip[0, :, 1] = np.array(tri)[:, 1] / (height / 2) - 1
    clip[0, :, 3] = 1
    return clip


def test_viewport_transform_by_hand():
    # NDC (0, 0, 0) is the centre of a 64x48 viewport at depth 0.5;
    # NDC (-1, 1, 1) with w = 2 is (-0.5, 0.5, 0.5) -> (16, 36, 0.75).
    window, inv_w = setup.viewport_transform(np.array([[0, 0, 0, 1.0], [-1, 1, 1, 2.0]]), 64, 48, "exact")
    np.testing.assert_allclose(window, [[32, 24, 0.5], [16, 36, 0.75]])
    np.testing.assert_allclose(inv_w, [1, 0.5])


@pytest.mark.parametrize("x, expected", [
    (0.5, 0),            # a pixel centre is raster 0
    (1.5, 256),
    (0.501953125, 0),    # 0.001953125 * 256 = 0.5 -> ties to even: 0
    (0.505859375, 2),    # 1.5 -> 2 (even)
    (0.509765625, 2),    # 2.5 -> 2 (even)
])
def test_snap_rounds_half_to_even(x, expected):
    assert setup.snap(np.array([[x, x]]))[0, 0] == expected


def test_fill_rule_left_and_bottom_edges_inclusive():
    # Counter-clockwise triangle (0,0) (4,0) (0,4): the bottom edge (A = 0,
    # B > 0) and the left edge (A > 0) are inclusive, the diagonal is not.
    tri = setup.setup_triangles(_clip_from_window([[0.5, 0.5], [4.5, 0.5], [0.5, 4.5]], 8, 8),
                                8, 8, offsets=ONE_SAMPLE[0], unit=ONE_SAMPLE[1])
    assert tri.edge_inclusive[0].tolist() == [True, False, True]


def test_clockwise_triangle_is_reordered_and_culled_as_back():
    cw = _clip_from_window([[0.5, 0.5], [0.5, 4.5], [4.5, 0.5]], 8, 8)
    none = setup.setup_triangles(cw, 8, 8, offsets=ONE_SAMPLE[0], unit=ONE_SAMPLE[1])
    assert len(none) == 1 and not none.front_facing[0]
    assert none.corner[0].tolist() == [1, 0, 2]
    assert len(setup.setup_triangles(cw, 8, 8, cull="back", offsets=ONE_SAMPLE[0], unit=ONE_SAMPLE[1])) == 0
    assert len(setup.setup_triangles(cw, 8, 8, cull="front", offsets=ONE_SAMPLE[0], unit=ONE_SAMPLE[1])) == 1


def test_zero_area_after_snapping_is_dropped():
    # Three distinct points that snap onto one line (differences below 1/512 px).
    tri = _clip_from_window([[1.0, 1.5], [5.0, 1.5], [3.0, 1.501]], 8, 8)
    assert len(setup.setup_triangles(tri, 8, 8, offsets=ONE_SAMPLE[0], unit=ONE_SAMPLE[1])) == 0
    exact = setup.sample_offsets(np.array([[0.5, 0.5]]), "exact")
    assert len(setup.setup_triangles(tri, 8, 8, precision="exact", offsets=exact[0], unit=exact[1])) == 1


def test_fused_viewport_transform_rounds_once():
    # x_ndc * 24 + 24 for an x_ndc whose product needs more than 24 bits.
    x = np.float32(-0.7700195)
    clip = np.array([[x, 0, 0, 1.0]])
    fused, _ = setup.viewport_transform(clip, 48, 48, "gl", fused=True)
    separate, _ = setup.viewport_transform(clip, 48, 48, "gl", fused=False)
    assert fused[0, 0] == np.float32(float(x) * 24.0 + 24.0)
    assert separate[0, 0] == np.float32(np.float32(x * np.float32(24.0)) + np.float32(24.0))
