"""Property tests of coverage (hypothesis, derandomized): setup + rasterize.

Triangles are given in GL window pixels on a W x H = 64 x 64 viewport and
turned into clip coordinates with w = 1 (x_ndc = 2 x / W - 1), so they meet
the stages exactly as a pixel-camera scene does.

Ambiguity rule (gl vs exact): gl precision snaps each vertex to the 1/256-px
grid, moving it by at most sqrt(2)/512 px, so a point of an edge moves by at
most that much; float32 window coordinates add < 1e-5 px on a 64-px viewport.
A pixel centre may therefore change sides only if it lies within
1/256 px (> sqrt(2)/512 + 1e-5) of an edge.  Any other difference is a bug.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from softras.pipeline import rasterize, setup

SIZE = 64
AMBIGUITY_PX = 1 / 256
SETTINGS = settings(max_examples=40, derandomize=True, deadline=None, database=None)


def coverage(window_xy: np.ndarray, precision: str) -> np.ndarray:
    """(T, 3, 2) window-pixel triangles -> (SIZE, SIZE) int count of covers per pixel centre (y up)."""
    clip = np.concatenate([2 * window_xy / SIZE - 1, np.zeros(window_xy.shape[:2] + (1,)),
                           np.ones(window_xy.shape[:2] + (1,))], axis=-1)
    offsets, unit = setup.sample_offsets(np.array([[0.5, 0.5]]), precision)
    tris = setup.setup_triangles(clip, SIZE, SIZE, precision=precision, offsets=offsets, unit=unit)
    frags = rasterize.rasterize(tris, offsets, unit)
    count = np.zeros((SIZE, SIZE), np.int64)
    np.add.at(count, (frags.y, frags.x), 1)
    return count


def perturbed_grid(draw, cells: int) -> np.ndarray:
    """A cells x cells grid over [4, 60]^2 with interior vertices moved by up to
    a quarter cell (boundary vertices stay on the square): a planar partition."""
    step = 56 / cells
    xs, ys = np.meshgrid(4 + step * np.arange(cells + 1), 4 + step * np.arange(cells + 1))
    jitter = np.array(draw(st.lists(st.floats(-0.25, 0.25), min_size=2 * (cells + 1) ** 2,
                                     max_size=2 * (cells + 1) ** 2))).reshape(cells + 1, cells + 1, 2) * step
    jitter[[0, -1], :, :] = 0
    jitter[:, [0, -1], :] = 0
    points = np.stack([xs, ys], -1) + jitter
    tris = []
    for j in range(cells):
        for i in range(cells):
            a, b, c, d = points[j, i], points[j, i + 1], points[j + 1, i + 1], points[j + 1, i]
            tris += [[a, b, c], [a, c, d]] if draw(st.booleans()) else [[a, b, d], [b, c, d]]
    return np.array(tris)


@SETTINGS
@given(st.data(), st.integers(2, 7), st.sampled_from(["gl", "exact"]))
def test_shared_edges_are_watertight(data, cells, precision):
    """A mesh that tiles a square covers every pixel centre at most once, and
    every centre strictly inside the square exactly once."""
    count = coverage(perturbed_grid(data.draw, cells), precision)
    assert count.max() <= 1
    centres = np.arange(SIZE) + 0.5
    inside = ((centres > 4) & (centres < 60))
    assert (count[np.ix_(inside, inside)] == 1).all()


triangles = st.lists(st.tuples(*[st.floats(-8, 72, allow_nan=False)] * 6), min_size=1, max_size=12).map(
    lambda ts: np.array(ts, np.float64).reshape(-1, 3, 2))


@SETTINGS
@given(triangles, st.sampled_from(["gl", "exact"]))
def test_cyclic_vertex_order_gives_the_same_coverage(tris, precision):
    base = coverage(tris, precision)
    assert (coverage(tris[:, [1, 2, 0]], precision) == base).all()
    assert (coverage(tris[:, [2, 0, 1]], precision) == base).all()


@SETTINGS
@given(st.lists(st.tuples(*[st.integers(0, 48 * 16)] * 6), min_size=1, max_size=8),
       st.integers(-8, 8), st.integers(-8, 8), st.sampled_from(["gl", "exact"]))
def test_whole_pixel_translation_shifts_the_image(points, dx, dy, precision):
    """Vertices on a 1/16-px grid (exact in float32 and in 1/256-px fixed point
    on a power-of-two viewport): moving by whole pixels moves coverage exactly."""
    tris = np.array(points, np.float64).reshape(-1, 3, 2) / 16 + 8
    moved = coverage(tris + [dx, dy], precision)
    base = coverage(tris, precision)
    shifted = np.roll(base, (dy, dx), axis=(0, 1))
    keep = np.zeros_like(base, bool)
    keep[max(dy, 0):SIZE + min(dy, 0), max(dx, 0):SIZE + min(dx, 0)] = True
    assert (moved[keep] == shifted[keep]).all()


def distance_to_edges(tris: np.ndarray) -> np.ndarray:
    """(SIZE, SIZE) float64 distance of each pixel centre to the nearest triangle edge segment."""
    ys, xs = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    p = np.stack([xs, ys], -1)[..., None, :]                      # (H, W, 1, 2)
    a = tris.reshape(-1, 2)
    b = tris[:, [1, 2, 0]].reshape(-1, 2)
    ab = b - a
    length2 = np.maximum((ab ** 2).sum(-1), 1e-300)
    t = np.clip(((p - a) * ab).sum(-1) / length2, 0, 1)
    nearest = a + t[..., None] * ab
    return np.sqrt(((p - nearest) ** 2).sum(-1)).min(-1)


@SETTINGS
@given(triangles)
def test_gl_and_exact_differ_only_within_the_snapping_distance_of_an_edge(tris):
    gl, exact = coverage(tris, "gl"), coverage(tris, "exact")
    differ = gl != exact
    assert (distance_to_edges(tris)[differ] <= AMBIGUITY_PX).all()
