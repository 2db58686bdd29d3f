"""Exact analytic area coverage: the box-prefiltered answer sampling approximates.

For a triangle and a pixel, the *exact coverage* is the area of the triangle
clipped against the pixel's unit square, in [0, 1]: what an infinitely dense
sample pattern with a box resolve would converge to.  GL has no such mode; it
is softras's ground truth for measuring sample patterns (`softras.pipeline.sampling`,
docs/antialiasing.md, scripts/coverage_error.py).

Spaces: every position here is a window coordinate (GL's y-up window space,
pixel (i, j) is the square [i, i+1] x [j, j+1], its centre at (i+0.5, j+0.5)),
float64, unsnapped.

Functions
---------
:func:`polygon_area`, :func:`clip_to_box` -- the two steps, for one polygon.
:func:`pixel_areas` -- exact coverage of every pixel of every triangle
(sparse: one entry per (triangle, pixel) with area > 0), numba kernel.
:func:`coverage_image` -- the sum over triangles per pixel, (H, W).
:func:`sampled_coverage` -- the same quantity estimated by softras's own
rasterizer with a sample pattern (covered samples / S).
:func:`coverage_error` -- the two side by side, per (triangle, pixel).
:func:`scene_triangles` -- a scene's triangles in window space, to measure on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

_MAX_VERTICES = 16     # a triangle clipped by 4 half-planes has at most 7 vertices


@numba.njit(cache=True)
def _clip_half_plane(xs, ys, n, axis, bound, keep_greater, out_x, out_y):
    """Sutherland-Hodgman: clip polygon (xs, ys)[:n] to x >= bound (axis 0,
    keep_greater) / x <= bound / y >= bound / y <= bound.  Returns the new count."""
    m = 0
    for k in range(n):
        ax, ay = xs[k], ys[k]
        bx, by = xs[(k + 1) % n], ys[(k + 1) % n]
        a = ax if axis == 0 else ay
        b = bx if axis == 0 else by
        a_in = a >= bound if keep_greater else a <= bound
        b_in = b >= bound if keep_greater else b <= bound
        if a_in:
            out_x[m] = ax
            out_y[m] = ay
            m += 1
        if a_in != b_in:
            t = (bound - a) / (b - a)
            if axis == 0:
                out_x[m] = bound
                out_y[m] = ay + t * (by - ay)
            else:
                out_x[m] = ax + t * (bx - ax)
                out_y[m] = bound
            m += 1
    return m


@numba.njit(cache=True)
def _area(xs, ys, n):
    """Unsigned shoelace area of polygon (xs, ys)[:n]."""
    twice = 0.0
    for k in range(n):
        j = (k + 1) % n
        twice += xs[k] * ys[j] - xs[j] * ys[k]
    return abs(twice) * 0.5


@numba.njit(cache=True)
def _pixel_area(tx, ty, x0, y0, bx, by, cx, cy):
    """Area of triangle (tx, ty) inside the square [x0, x0+1] x [y0, y0+1]."""
    n = 3
    for k in range(3):
        bx[k] = tx[k]
        by[k] = ty[k]
    n = _clip_half_plane(bx, by, n, 0, x0, True, cx, cy)
    n = _clip_half_plane(cx, cy, n, 0, x0 + 1.0, False, bx, by)
    n = _clip_half_plane(bx, by, n, 1, y0, True, cx, cy)
    n = _clip_half_plane(cx, cy, n, 1, y0 + 1.0, False, bx, by)
    if n < 3:
        return 0.0
    return _area(bx, by, n)


@numba.njit(cache=True, parallel=True)
def _areas(tris, bbox, starts, out_tri, out_x, out_y, out_area):
    for t in numba.prange(tris.shape[0]):
        bx = np.empty(_MAX_VERTICES)
        by = np.empty(_MAX_VERTICES)
        cx = np.empty(_MAX_VERTICES)
        cy = np.empty(_MAX_VERTICES)
        k = starts[t]
        for py in range(bbox[t, 2], bbox[t, 3] + 1):
            for px in range(bbox[t, 0], bbox[t, 1] + 1):
                out_tri[k] = t
                out_x[k] = px
                out_y[k] = py
                out_area[k] = _pixel_area(tris[t, :, 0], tris[t, :, 1], float(px), float(py), bx, by, cx, cy)
                k += 1


def clip_to_box(polygon: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """(N, 2) polygon -> (M, 2) its part inside [x0, x1] x [y0, y1] (Sutherland-Hodgman)."""
    xs = np.zeros(_MAX_VERTICES + len(polygon))
    ys = np.zeros_like(xs)
    xs[:len(polygon)], ys[:len(polygon)] = polygon[:, 0], polygon[:, 1]
    cx, cy = np.zeros_like(xs), np.zeros_like(xs)
    n = len(polygon)
    for axis, bound, greater in ((0, x0, True), (0, x1, False), (1, y0, True), (1, y1, False)):
        n = _clip_half_plane(xs, ys, n, axis, float(bound), greater, cx, cy)
        xs, ys, cx, cy = cx, cy, xs, ys
    return np.stack([xs[:n], ys[:n]], axis=1)


def polygon_area(polygon: np.ndarray) -> float:
    """Unsigned area of an (N, 2) simple polygon (shoelace formula)."""
    polygon = np.asarray(polygon, np.float64)
    return float(_area(polygon[:, 0].copy(), polygon[:, 1].copy(), len(polygon))) if len(polygon) >= 3 else 0.0


@dataclass(frozen=True)
class PixelAreas:
    """Sparse per-(triangle, pixel) coverage: tri (P,) int64, x, y (P,) int64
    pixels in GL's y-up window space, area (P,) float64 in (0, 1]."""

    tri: np.ndarray
    x: np.ndarray
    y: np.ndarray
    area: np.ndarray


def _check_triangles(triangles: np.ndarray) -> np.ndarray:
    triangles = np.asarray(triangles, np.float64)
    if triangles.ndim != 3 or triangles.shape[1:] != (3, 2):
        raise ValueError(f"triangles must have shape (T, 3, 2) (window x, y), not {triangles.shape}")
    if not np.isfinite(triangles).all():
        raise ValueError("triangles have NaN or infinite coordinates")
    return np.ascontiguousarray(triangles)


def pixel_areas(triangles: np.ndarray, width: int, height: int) -> PixelAreas:
    """Exact coverage of each pixel of a width x height image by each triangle.

    triangles : (T, 3, 2) float64 window-space x, y (any winding).
    Returns the (triangle, pixel) pairs with a positive area, by triangle
    then row then column.  Parts of a triangle outside the image are not
    counted; a triangle's areas sum to its area inside the image.
    """
    tris = _check_triangles(triangles)
    if len(tris) == 0:
        empty = np.zeros(0, np.int64)
        return PixelAreas(empty, empty, empty, np.zeros(0))
    lo = np.floor(tris.min(axis=1)).astype(np.int64)        # (T, 2)
    hi = np.ceil(tris.max(axis=1)).astype(np.int64) - 1
    bbox = np.stack([np.maximum(lo[:, 0], 0), np.minimum(hi[:, 0], width - 1),
                     np.maximum(lo[:, 1], 0), np.minimum(hi[:, 1], height - 1)], axis=1)
    counts = np.maximum(bbox[:, 1] - bbox[:, 0] + 1, 0) * np.maximum(bbox[:, 3] - bbox[:, 2] + 1, 0)
    starts = np.zeros(len(tris), np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    total = int(counts.sum())
    out = (np.empty(total, np.int64), np.empty(total, np.int64), np.empty(total, np.int64), np.empty(total))
    _areas(tris, bbox, starts, *out)
    keep = out[3] > 0
    return PixelAreas(*(a[keep] for a in out))


def coverage_image(triangles: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) float64 sum of the triangles' exact pixel coverage, GL's y-up rows.

    For the triangles of a mesh without overlaps (a fan, a grid) this is the
    box-filtered coverage of the mesh, in [0, 1].
    """
    areas = pixel_areas(triangles, width, height)
    image = np.zeros((height, width))
    np.add.at(image, (areas.y, areas.x), areas.area)
    return image


def sampled_coverage(triangles: np.ndarray, width: int, height: int, positions: np.ndarray,
                     precision: str = "exact") -> PixelAreas:
    """Coverage estimated by softras's rasterizer: covered samples / S per (triangle, pixel).

    triangles : (T, 3, 2) window x, y; positions : (S, 2) sample positions in
    [0, 1)^2 (`softras.pipeline.sampling`), any S (rasterized in passes of <= 32).
    precision : "exact" (float64 edge functions, no snapping: the pattern's
    own error) or "gl" (llvmpipe's 1/256 snapping of vertices and samples).
    Returns the pairs with at least one covered sample (``area`` holds the
    fraction), by triangle then row then column.
    """
    from softras.pipeline import rasterize, setup
    from softras.pipeline.sampling import sample_passes

    tris = _check_triangles(triangles)
    positions = np.asarray(positions, np.float64)
    n_samples = len(positions)
    # Window x, y -> clip coordinates with w = 1 (the viewport transform undoes this).
    clip = np.concatenate([tris / [width / 2.0, height / 2.0] - 1.0, np.zeros(tris.shape[:2] + (1,)),
                           np.ones(tris.shape[:2] + (1,))], axis=2)
    keys, counts = [], []
    for start, stop in sample_passes(n_samples):
        offsets, unit = setup.sample_offsets(positions[start:stop], precision)
        ts = setup.setup_triangles(clip, width, height, precision=precision, offsets=offsets, unit=unit)
        frags = rasterize.rasterize(ts, offsets, unit)
        bits = np.unpackbits(frags.mask.astype("<u4").view(np.uint8).reshape(-1, 4), axis=1).sum(axis=1)
        tri = ts.triangle[frags.tri]
        keys.append((tri * height + frags.y) * width + frags.x)
        counts.append(bits)
    key, inverse = np.unique(np.concatenate(keys), return_inverse=True)
    covered = np.bincount(inverse, weights=np.concatenate(counts))
    tri, rest = np.divmod(key, height * width)
    y, x = np.divmod(rest, width)
    return PixelAreas(tri, x, y, covered / n_samples)


def scene_triangles(scene) -> np.ndarray:
    """(T, 3, 2) float64 window x, y of every triangle a scene draws (exact precision).

    Vertex stage and clipping (guard band: only the near/far and w planes cut)
    in float64, then the viewport transform; lines are skipped.  Culling is
    ignored: coverage does not depend on winding.
    """
    from softras.pipeline import clip as clip_stage
    from softras.pipeline import setup, vertex
    from softras.scene import load_scene

    scene = load_scene(scene)
    found = [np.zeros((0, 3, 2))]
    for draw in scene.draws:
        if draw.mesh.primitive != "triangles" or len(draw.mesh.indices) == 0:
            continue
        mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
        clip_pos = vertex.to_clip(draw.mesh.positions, mvp, "exact")
        clipped = clip_stage.clip_triangles(clip_pos, draw.mesh.indices, precision="exact", policy="guard_band",
                                            width=scene.width, height=scene.height)
        window, _ = setup.viewport_transform(clipped.clip, scene.width, scene.height, "exact")
        found.append(window[..., :2])
    return np.concatenate(found)


@dataclass(frozen=True)
class CoverageError:
    """Exact and sampled coverage of the same (triangle, pixel) pairs: tri, x, y (P,)
    int64; exact, sampled (P,) float64 in [0, 1].  The pairs are those where
    either is positive, except pixels both call fully covered."""

    tri: np.ndarray
    x: np.ndarray
    y: np.ndarray
    exact: np.ndarray
    sampled: np.ndarray

    @property
    def error(self) -> np.ndarray:
        return self.sampled - self.exact

    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.error ** 2))) if len(self.tri) else 0.0

    def max_abs(self) -> float:
        return float(np.abs(self.error).max()) if len(self.tri) else 0.0


def coverage_error(triangles: np.ndarray, width: int, height: int, positions: np.ndarray,
                   precision: str = "exact") -> CoverageError:
    """Sampled coverage (`sampled_coverage`) against exact area (`pixel_areas`) per (triangle, pixel).

    Pixels both call fully covered (the interiors, error 0 for every
    pattern) are left out, so the statistics describe edge pixels.
    """
    exact = pixel_areas(triangles, width, height)
    sampled = sampled_coverage(triangles, width, height, positions, precision)
    key_e = (exact.tri * height + exact.y) * width + exact.x
    key_s = (sampled.tri * height + sampled.y) * width + sampled.x
    key = np.union1d(key_e, key_s)
    e = np.zeros(len(key))
    s = np.zeros(len(key))
    e[np.searchsorted(key, key_e)] = exact.area
    s[np.searchsorted(key, key_s)] = sampled.area
    # Exact areas of fully covered pixels can be 1 - 1e-16: compare with a hair of slack.
    keep = ~((s == 1.0) & (e >= 1.0 - 1e-12))
    tri, rest = np.divmod(key[keep], height * width)
    y, x = np.divmod(rest, width)
    return CoverageError(tri, x, y, e[keep], s[keep])
