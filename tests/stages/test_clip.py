"""Clip stage: homogeneous clipping against the frustum planes."""

import numpy as np
import pytest

from softras.clip import clip_triangles


def _tri(*points):
    return np.array(points, float)


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_inside_triangle_passes_unchanged(precision):
    clip = _tri([-0.5, -0.5, 0, 1], [0.5, -0.5, 0, 1], [0, 0.5, 0, 1])
    out = clip_triangles(clip, np.array([[0, 1, 2]]), precision=precision)
    assert len(out) == 1
    np.testing.assert_array_equal(out.clip[0], clip)
    np.testing.assert_array_equal(out.weights[0], np.eye(3))
    assert not out.generated.any()


def test_triangle_outside_one_plane_is_culled():
    clip = _tri([2, 0, 0, 1], [3, 1, 0, 1], [2, 1, 0, 1])     # x > w everywhere
    assert len(clip_triangles(clip, np.array([[0, 1, 2]]))) == 0


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_near_plane_cut_by_hand(precision):
    # One vertex behind the near plane (z < -w).  z + w is -2 at the outside
    # vertex, 1 and 2 at the others, so the edges meet z = -w at 2/3 of the
    # way to (0.5, 0, 0, 1) -> (1/3, 0, -1, 1) and half way to (0, 0.5, 1, 1)
    # -> (0, 0.25, -1, 1).
    clip = _tri([0, 0, -3, 1], [0.5, 0, 0, 1], [0, 0.5, 1, 1])
    out = clip_triangles(clip, np.array([[0, 1, 2]]), precision=precision)
    vertices = out.clip.reshape(-1, 4)
    assert (vertices[:, 2] >= -vertices[:, 3] - 1e-7).all()
    # The quadrilateral left over becomes two triangles.
    assert len(out) == 2
    # Every new vertex lies on the near plane, with weights that reproduce it.
    for t in range(len(out)):
        np.testing.assert_allclose(out.weights[t] @ clip, out.clip[t], atol=1e-6)
    new = vertices[out.generated.reshape(-1)]
    np.testing.assert_allclose(new[:, 2], -new[:, 3], atol=1e-7)
    assert any(np.allclose(v, [1 / 3, 0, -1, 1]) for v in new)
    assert any(np.allclose(v, [0, 0.25, -1, 1]) for v in new)


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_shared_edge_gives_identical_new_vertices(precision):
    # Two triangles share the edge a-b, which crosses the right plane x = w;
    # they traverse it in opposite directions.
    a, b = [0.3, -0.2, 0.1, 1.0], [1.7, 0.4, -0.2, 1.3]
    c, d = [0.1, 0.9, 0.0, 1.1], [0.2, -0.9, 0.3, 0.9]
    clip = np.array([a, b, c, d])
    out = clip_triangles(clip, np.array([[0, 1, 2], [1, 0, 3]]), precision=precision)
    first = {tuple(v) for v in out.clip[out.source == 0].reshape(-1, 4)}
    second = {tuple(v) for v in out.clip[out.source == 1].reshape(-1, 4)}
    shared = first & second
    # a itself and the one point where a-b leaves the volume are common.
    assert tuple(a) in shared and len(shared) == 2


def test_all_six_planes_clip_in_llvmpipe_policy_but_not_guard_band():
    clip = _tri([-3, -0.5, 0, 1], [3, -0.5, 0, 1], [0, 0.5, 0, 1])
    assert len(clip_triangles(clip, np.array([[0, 1, 2]]), policy="llvmpipe")) > 1
    out = clip_triangles(clip, np.array([[0, 1, 2]]), policy="guard_band", width=64, height=64)
    assert len(out) == 1 and not out.generated.any()
