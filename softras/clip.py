"""Clip stage: cull and clip triangles against the view volume in clip space.

A clip-space point (x, y, z, w) is inside the view volume when
``-w <= x <= w``, ``-w <= y <= w`` and ``-w <= z <= w``.  Each of the six
planes is a linear function ``d(p) = plane . p`` that is >= 0 inside.

Policies (``clipping=``):

``"llvmpipe"``
    What Mesa's draw module does for llvmpipe: every triangle that has a
    vertex outside any of the six planes is clipped against those planes
    (Sutherland-Hodgman, planes in the order right, left, top, bottom, near,
    far), in float32, with no guard band.  A new vertex is interpolated from
    the *outside* vertex of its edge, so the two triangles that share an edge
    compute bit-identical new vertices.  The default in ``precision="gl"``.
``"guard_band"``
    Only near and far clip geometrically; x and y are clipped against a band
    of +-GUARD_BAND_PIXELS around the viewport centre, and the rasterizer's
    bounding box does the rest.  This is what most GPUs do, and what
    ``precision="exact"`` uses: edges inside the band are never moved.

Clipped polygons are fanned into triangles (v[i-1], v[i], v[0]) like the draw
module does with the last vertex provoking.  Every output vertex carries its
barycentric weights with respect to the three vertices of its source
triangle, so any attribute can be interpolated later (in clip space, which is
where GL interpolates new vertices) without this stage knowing about them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Plane coefficients (a, b, c, d): inside when a*x + b*y + c*z + d*w >= 0.
FRUSTUM_PLANES = np.array([
    [-1, 0, 0, 1],   # right   x <= w
    [1, 0, 0, 1],    # left   -w <= x
    [0, -1, 0, 1],   # top     y <= w
    [0, 1, 0, 1],    # bottom -w <= y
    [0, 0, 1, 1],    # near   -w <= z
    [0, 0, -1, 1],   # far     z <= w
], dtype=np.float64)

GUARD_BAND_PIXELS = 8192.0


@dataclass(frozen=True)
class ClippedTriangles:
    """Triangles after clipping, in clip space.

    clip : (T, 3, 4) float64 clip-space vertex positions.
    source : (T,) int64 index of the input triangle each one came from.
    weights : (T, 3, 3) float64; ``weights[t, k]`` are the barycentric weights
        of output vertex k with respect to the source triangle's vertices, so
        an attribute is ``weights[t] @ attribute[indices[source[t]]]``.
    """

    clip: np.ndarray
    source: np.ndarray
    weights: np.ndarray

    @property
    def generated(self) -> np.ndarray:
        """(T, 3) bool: vertices made by the clipper rather than passed through."""
        return self.weights.max(axis=2) != 1.0

    def __len__(self) -> int:
        return len(self.source)


def clip_planes(policy: str, width: int, height: int) -> np.ndarray:
    """Return the (6, 4) plane coefficients used by a clipping policy."""
    planes = FRUSTUM_PLANES.copy()
    if policy == "llvmpipe":
        return planes
    if policy == "guard_band":
        # x_ndc in [-k, k] covers GUARD_BAND_PIXELS on each side of the centre.
        planes[0:2, 3] = max(1.0, GUARD_BAND_PIXELS / (width / 2.0))
        planes[2:4, 3] = max(1.0, GUARD_BAND_PIXELS / (height / 2.0))
        return planes
    raise ValueError(f"unknown clipping policy {policy!r} (use 'llvmpipe' or 'guard_band')")


def plane_distances(clip: np.ndarray, planes: np.ndarray, precision: str) -> np.ndarray:
    """Signed distances d (N, 6) of clip-space points (N, 4) to each plane.

    In "gl" precision each distance is rounded to float32 the way the draw
    module's ``dot4`` computes it (for the frustum planes this is ``w - x``
    and so on, one rounding).
    """
    d = clip @ planes.T
    if precision == "gl":
        d = d.astype(np.float32).astype(np.float64)
    return d


def clip_triangles(clip: np.ndarray, indices: np.ndarray, *, precision: str = "gl",
                   policy: str = "llvmpipe", width: int = 1, height: int = 1) -> ClippedTriangles:
    """Cull and clip indexed triangles.

    Parameters
    ----------
    clip : (N, 4) float64 clip-space vertex positions.
    indices : (M, 3) int64 triangle vertex indices.
    precision : "gl" (float32 arithmetic, like Mesa's draw module) or "exact".
    policy : "llvmpipe" or "guard_band" (see the module docstring).
    width, height : viewport size in pixels (sizes the guard band).

    Returns
    -------
    ClippedTriangles; triangles entirely outside one plane are dropped,
    triangles entirely inside are passed through unchanged and in order, and
    clipped ones are replaced by their fan in place, so draw order holds.
    """
    planes = clip_planes(policy, width, height)
    dist = plane_distances(clip, planes, precision)            # (N, 6)
    outside = dist < 0                                          # (N, 6)
    finite = np.isfinite(clip).all(axis=1)

    tri_out = outside[indices]                                  # (M, 3, 6)
    culled = tri_out.all(axis=1).any(axis=1) | ~finite[indices].all(axis=1)
    crossing = tri_out.any(axis=(1, 2)) & ~culled

    identity = np.eye(3)
    keep = ~culled & ~crossing
    if not crossing.any():
        kept = np.nonzero(keep)[0]
        return ClippedTriangles(
            clip=clip[indices[kept]],
            source=kept.astype(np.int64),
            weights=np.broadcast_to(identity, (len(kept), 3, 3)).copy(),
        )

    out_clip, out_source, out_weights = [], [], []
    for t in np.nonzero(keep | crossing)[0]:
        corners = clip[indices[t]]
        if keep[t]:
            out_clip.append(corners)
            out_source.append(t)
            out_weights.append(identity)
            continue
        mask = tri_out[t].any(axis=0)
        polygon = clip_polygon(corners, identity, planes[mask], precision)
        for k in range(2, len(polygon[0])):
            fan = [k - 1, k, 0]
            out_clip.append(polygon[0][fan])
            out_source.append(t)
            out_weights.append(polygon[1][fan])
    if not out_source:
        return ClippedTriangles(np.zeros((0, 3, 4)), np.zeros(0, np.int64), np.zeros((0, 3, 3)))
    return ClippedTriangles(
        clip=np.array(out_clip, dtype=np.float64),
        source=np.array(out_source, dtype=np.int64),
        weights=np.array(out_weights, dtype=np.float64),
    )


def clip_polygon(points: np.ndarray, weights: np.ndarray, planes: np.ndarray,
                 precision: str) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland-Hodgman clipping of one convex polygon against planes in order.

    points : (n, 4) clip-space vertices; weights : (n, k) attributes carried
    along (interpolated with the same t).  Returns the clipped (points,
    weights); fewer than 3 points means nothing is left.
    """
    f32 = precision == "gl"
    for plane in planes:
        if len(points) < 3:
            break
        d = points @ plane
        if f32:
            d = d.astype(np.float32)
        new_points, new_weights = [], []
        n = len(points)
        for i in range(1, n + 1):
            prev, cur = i - 1, i % n   # edges 0->1, 1->2, ..., (n-1)->0
            d_prev, d_cur = d[prev], d[cur]
            if d_prev >= 0:
                new_points.append(points[prev])
                new_weights.append(weights[prev])
            if (d_prev >= 0) != (d_cur >= 0):
                # Interpolate from the outside vertex towards the inside one.
                out_i, in_i = (cur, prev) if d_cur < 0 else (prev, cur)
                d_out, d_in = d[out_i], d[in_i]
                if f32:
                    t = np.float32(d_out) / (np.float32(d_out) - np.float32(d_in))
                    p_out = points[out_i].astype(np.float32)
                    p_in = points[in_i].astype(np.float32)
                    p = (p_out + t * (p_in - p_out)).astype(np.float64)
                    t = float(t)
                else:
                    t = d_out / (d_out - d_in)
                    p = points[out_i] + t * (points[in_i] - points[out_i])
                new_points.append(p)
                new_weights.append(weights[out_i] + t * (weights[in_i] - weights[out_i]))
        points = np.array(new_points).reshape(-1, 4)
        weights = np.array(new_weights).reshape(-1, weights.shape[1])
    return points, weights
