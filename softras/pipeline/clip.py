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
    the end of its edge nearer the plane (the inside end on a tie), so the
    two triangles that share an edge compute bit-identical new vertices and
    a vertex 1e7 outside does not wipe out the float32 result.  The default in ``precision="gl"``.
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

import numba
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
    d = _plane_distances(np.ascontiguousarray(clip, np.float64), np.ascontiguousarray(planes, np.float64))
    if precision == "gl":
        d = d.astype(np.float32).astype(np.float64)
    return d


@numba.njit(cache=True)
def _plane_distances(c, planes):
    """The draw module's dot4 of every vertex c (N, 4) with every plane
    (P, 4), left to right, each step in c's type (float32 for the gl line
    clipper, rounded at each step; float64 for `plane_distances`, the sum
    `clip_polygon` takes): (N, P).  A loop, not BLAS (see
    `softras.pipeline.vertex._transform`).  The line stage and the line
    kernels use it too."""
    dist = np.empty((c.shape[0], planes.shape[0]), c.dtype)
    for v in range(c.shape[0]):
        for p in range(planes.shape[0]):
            d = c[v, 0] * planes[p, 0]
            for k in range(1, 4):
                d = d + c[v, k] * planes[p, k]
            dist[v, p] = d
    return dist


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
    keep, crossing = np.empty(len(indices), bool), np.empty(len(indices), bool)
    _classify(outside, finite, np.ascontiguousarray(indices, np.int64), keep, crossing)

    if not crossing.any():
        kept = np.nonzero(keep)[0]
        out_clip, out_weights = np.empty((len(kept), 3, 4)), np.empty((len(kept), 3, 3))
        _pass_through(clip, indices, kept, np.arange(len(kept)), out_clip, out_weights)
        return ClippedTriangles(clip=out_clip, source=kept.astype(np.int64), weights=out_weights)
    cross = np.nonzero(crossing)[0]
    plane_mask = outside[indices[cross]].any(axis=1)            # (C, 6) planes to clip against
    # The crossing triangles are clipped by a compiled kernel (bit for bit
    # `clip_polygon`, whose loop `_clip_with_polygons` is the reference; see
    # tests/stages/test_clip.py), in two passes (count, then write) so the
    # output is exact-sized.
    corners = np.ascontiguousarray(clip[indices[cross]], np.float64)    # (C, 3, 4)
    f32 = precision == "gl"
    fan_counts = _clip_kernel(corners, plane_mask, planes, f32, np.zeros(len(cross), np.int64),
                              np.zeros((0, 3, 4)), np.zeros((0, 3, 3)), False)
    cross_clip = np.empty((int(fan_counts.sum()), 3, 4))
    cross_weights = np.empty((len(cross_clip), 3, 3))
    _clip_kernel(corners, plane_mask, planes, f32, fan_counts, cross_clip, cross_weights, True)
    return _in_draw_order(clip, indices, keep, cross, fan_counts, cross_clip, cross_weights)


def _in_draw_order(clip, indices, keep, cross, fan_counts, cross_clip, cross_weights) -> ClippedTriangles:
    """The clipped triangles in draw order: each kept triangle (keep (M,)
    bool) as it is, each crossing one (cross (C,) their indices) replaced by
    its fan of fan_counts (C,) triangles, the fans' corners and weights
    cross_clip (sum, 3, 4) and cross_weights (sum, 3, 3) one after another."""
    counts = keep.astype(np.int64)
    counts[cross] = fan_counts
    starts = np.zeros(len(counts), np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    total = int(counts.sum())
    out_clip = np.empty((total, 3, 4))
    out_weights = np.empty((total, 3, 3))
    out_source = np.repeat(np.arange(len(indices), dtype=np.int64), counts)
    kept = np.nonzero(keep)[0]
    _pass_through(clip, indices, kept, starts[kept], out_clip, out_weights)
    slots = (np.repeat(starts[cross] - np.cumsum(fan_counts) + fan_counts, fan_counts)
             + np.arange(len(cross_clip)))
    out_clip[slots] = cross_clip
    out_weights[slots] = cross_weights
    return ClippedTriangles(out_clip, out_source, out_weights)


@numba.njit(cache=True)
def _pass_through(clip, indices, kept, slots, out_clip, out_weights):
    """The triangles passed through unchanged: for each i, the corners of
    triangle kept[i] (rows indices[kept[i]] of clip (N, 4)) into
    out_clip[slots[i]] (3, 4), and identity weights into out_weights[slots[i]]
    (3, 3).  (numpy's gather and broadcast copy took 4-5 ms for 70k.)"""
    for i in range(kept.shape[0]):
        t, slot = kept[i], slots[i]
        for k in range(3):
            for j in range(4):
                out_clip[slot, k, j] = clip[indices[t, k], j]
            for j in range(3):
                out_weights[slot, k, j] = 1.0 if j == k else 0.0


@numba.njit(cache=True)
def _classify(outside, finite, indices, keep, crossing):
    """Triangle by triangle (indices (M, 3)): culled when its three corners
    are outside one plane (outside (N, 6) bool per vertex) or one is not
    finite (finite (N,) bool); crossing when not culled and a corner is
    outside a plane; kept when neither.  Writes keep and crossing (M,)."""
    for t in range(indices.shape[0]):
        a, b, c = indices[t, 0], indices[t, 1], indices[t, 2]
        culled = not (finite[a] and finite[b] and finite[c])
        out = False
        for p in range(outside.shape[1]):
            culled |= outside[a, p] and outside[b, p] and outside[c, p]
            out |= outside[a, p] or outside[b, p] or outside[c, p]
        crossing[t] = out and not culled
        keep[t] = not (culled or out)


def _clip_with_polygons(clip, indices, keep, cross, plane_mask, planes, precision) -> ClippedTriangles:
    """The reference loop: `clip_polygon` per crossing triangle (cross (C,)
    their indices into indices (M, 3), keep (M,) the triangles passed
    through, plane_mask (C, 6) the planes (of planes (6, 4)) each crosses),
    its polygon fanned (v[k-1], v[k], v[0]), in draw order.  `clip_triangles`
    gives the same bits with the compiled `_clip_kernel`; this loop stays as
    what that kernel mirrors (tests/stages/test_clip.py)."""
    identity = np.eye(3)
    fan_counts = np.zeros(len(cross), np.int64)
    fans_clip, fans_weights = [np.zeros((0, 3, 4))], [np.zeros((0, 3, 3))]
    for i, t in enumerate(cross):
        points, weights = clip_polygon(clip[indices[t]], identity, planes[plane_mask[i]], precision)
        fan = [[k - 1, k, 0] for k in range(2, len(points))]
        fan_counts[i] = len(fan)
        if fan:
            fans_clip.append(points[fan])
            fans_weights.append(weights[fan])
    return _in_draw_order(clip, indices, keep, cross, fan_counts, np.concatenate(fans_clip),
                          np.concatenate(fans_weights))


def clip_polygon(points: np.ndarray, weights: np.ndarray, planes: np.ndarray,
                 precision: str) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland-Hodgman clipping of one convex polygon against planes in order.

    points : (n, 4) clip-space vertices; weights : (n, k) attributes carried
    along (interpolated with the same t); planes : (P, 4) coefficients, in
    the order to clip against them; precision : "gl" (distances, t and the
    new points in float32) or anything else (float64).  Returns the clipped
    (points, weights); fewer than 3 points means nothing is left.

    This is the readable reference: `clip_triangles` runs its compiled
    mirror `_clip_kernel` (the same operations in the same order), and
    tests/stages/test_clip.py checks the two bit for bit.
    """
    f32 = precision == "gl"
    for plane in planes:
        if len(points) < 3:
            break
        # a x + b y + c z + d w, summed left to right, each product rounded
        # (no fused multiply-add): the operations `_clip_kernel` does.
        # (`points @ plane` may go through BLAS, in another order or fused;
        # for the frustum and guard-band planes, two non-zero terms of which
        # one is exact, every order gives these bits.)
        d = points[:, 0] * plane[0] + points[:, 1] * plane[1] + points[:, 2] * plane[2] + points[:, 3] * plane[3]
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
                # Interpolate from the end nearer the plane towards the other
                # (Mesa's draw_pipe_clip.c; the inside end on a tie): starting
                # from a far outside vertex (|d| ~ 1e7) cancels catastrophically
                # in float32 (scenes/extreme_huge_coordinates.json).  Below,
                # "out" names that start vertex and "in" the other end.
                out_i, in_i = (cur, prev) if d_cur < 0 else (prev, cur)
                if not -d[out_i] < d[in_i]:
                    out_i, in_i = in_i, out_i
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


@numba.njit(cache=True, inline="always")
def _copy_row(dst, i, src, k):
    """dst[i] = src[k] for 2-D arrays, as a loop: numba's row assignment
    compiles to a broadcasting copy that checks for overlap, and ten of them
    made the clipper's kernel take 6 s to compile."""
    for j in range(src.shape[1]):
        dst[i, j] = src[k, j]


@numba.njit(cache=True)
def _clip_kernel(corners, plane_mask, planes, f32, fan_counts, out_clip, out_weights, write):
    """`clip_polygon` compiled: each triangle against its planes, fanned.

    corners : (C, 3, 4) float64 clip-space triangles (identity weights);
    plane_mask : (C, P) bool, which of planes (P, 4) (in that order) each
    one is clipped against; f32 : True for precision "gl" (distances, t and
    the new points in float32), False for "exact" (float64).  Count pass
    (``write`` False): returns (C,) fan sizes.  Write pass: writes each fan
    (v[k-1], v[k], v[0]) consecutively into out_clip (F, 3, 4) and
    out_weights (F, 3, 3), F = fan_counts.sum() (the count pass's result),
    and returns the same sizes again.

    Every operation is the one `clip_polygon` performs, in the same order,
    so the bits are the same: tests/stages/test_clip.py compares
    `clip_triangles` with `clip_polygon` per triangle in both precisions and
    both policies (vertices 1e7 to 1e308 outside, w near 0 or negative,
    distances that underflow or overflow), and this kernel with it against
    random planes (where the distance's order of summation shows).
    """
    n = corners.shape[0]
    counts = np.zeros(n, np.int64)
    # A convex polygon gains at most one vertex per plane, but a rounded or
    # NaN distance can make its in/out pattern alternate: n vertices become
    # at most 3n // 2 (3, 4, 6, 9, 13, 19, 28 over six planes).
    size = 3
    for p in range(planes.shape[0]):
        size = size * 3 // 2
    pts = np.empty((size, 4))
    wts = np.empty((size, 3))
    new_pts = np.empty((size, 4))
    new_wts = np.empty((size, 3))
    d = np.empty(size)                  # float64; holds float32 values when f32
    at = 0
    for c in range(n):
        m = 3
        for k in range(3):
            for j in range(4):
                pts[k, j] = corners[c, k, j]
            for j in range(3):
                wts[k, j] = 1.0 if j == k else 0.0
        for p in range(planes.shape[0]):
            if not plane_mask[c, p] or m < 3:
                continue
            a, b, cz, dw = planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3]
            for k in range(m):
                dist = a * pts[k, 0] + b * pts[k, 1] + cz * pts[k, 2] + dw * pts[k, 3]
                if f32:
                    d[k] = np.float32(dist)
                else:
                    d[k] = dist
            nm = 0
            for i in range(1, m + 1):
                prev = i - 1
                cur = i % m
                if d[prev] >= 0:
                    _copy_row(new_pts, nm, pts, prev)
                    _copy_row(new_wts, nm, wts, prev)
                    nm += 1
                if (d[prev] >= 0) != (d[cur] >= 0):
                    if d[cur] < 0:
                        out_i, in_i = cur, prev
                    else:
                        out_i, in_i = prev, cur
                    if not -d[out_i] < d[in_i]:                         # start from the nearer end
                        out_i, in_i = in_i, out_i
                    if f32:
                        d_out, d_in = np.float32(d[out_i]), np.float32(d[in_i])
                        t32 = d_out / (d_out - d_in)                    # float32
                        for j in range(4):
                            p_out = np.float32(pts[out_i, j])
                            p_in = np.float32(pts[in_i, j])
                            new_pts[nm, j] = np.float64(p_out + t32 * (p_in - p_out))
                        t = np.float64(t32)
                    else:
                        t = d[out_i] / (d[out_i] - d[in_i])
                        for j in range(4):
                            new_pts[nm, j] = pts[out_i, j] + t * (pts[in_i, j] - pts[out_i, j])
                    for j in range(3):
                        new_wts[nm, j] = wts[out_i, j] + t * (wts[in_i, j] - wts[out_i, j])
                    nm += 1
            m = nm
            for k in range(m):
                _copy_row(pts, k, new_pts, k)
                _copy_row(wts, k, new_wts, k)
        counts[c] = max(m - 2, 0)
        if write:
            for k in range(2, m):
                for corner, row in enumerate((k - 1, k, 0)):
                    _copy_row(out_clip[at], corner, pts, row)
                    _copy_row(out_weights[at], corner, wts, row)
                at += 1
    return counts


@numba.njit(cache=True)
def outcodes_gl(clip):
    """Per-vertex outcodes for the llvmpipe planes in gl precision: (N,) int64,
    bit p set when the vertex is outside FRUSTUM_PLANES[p] (distance rounded
    to float32 < 0, as `plane_distances`), bit 6 set when not finite."""
    n = clip.shape[0]
    codes = np.zeros(n, np.int64)
    for v in range(n):
        x, y, z, w = clip[v, 0], clip[v, 1], clip[v, 2], clip[v, 3]
        code = 0
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z) and np.isfinite(w)):
            code |= 64
        for p in range(6):
            d = np.float32(FRUSTUM_PLANES[p, 0] * x + FRUSTUM_PLANES[p, 1] * y
                           + FRUSTUM_PLANES[p, 2] * z + FRUSTUM_PLANES[p, 3] * w)
            if d < 0:
                code |= 1 << p
        codes[v] = code
    return codes


@numba.njit(cache=True)
def triangle_list_gl(clip, indices):
    """`clip_triangles` (gl precision, llvmpipe policy) without copying the
    triangles that pass through unchanged.

    Returns (source (T,) int64 input triangle of each output triangle,
    slot (T,) int64: -1 for a passed-through triangle (its corners are
    ``clip[indices[source]]`` with identity weights), else the row of its fan
    triangle in fan_clip (F, 3, 4) / fan_weights (F, 3, 3)).  Same triangles,
    same order, same bits as `clip_triangles`.
    """
    codes = outcodes_gl(clip)
    m = indices.shape[0]
    if not codes.any():                     # (every vertex inside: every triangle passes through)
        return np.arange(m), np.full(m, -1), np.empty((0, 3, 4)), np.empty((0, 3, 3))
    status = np.zeros(m, np.int64)          # 0 culled, 1 passed through, 2 crossing
    n_cross = 0
    for t in range(m):
        c0, c1, c2 = codes[indices[t, 0]], codes[indices[t, 1]], codes[indices[t, 2]]
        if ((c0 | c1 | c2) & 64) or (c0 & c1 & c2) != 0:
            continue
        if (c0 | c1 | c2) == 0:
            status[t] = 1
        else:
            status[t] = 2
            n_cross += 1
    cross = np.empty(n_cross, np.int64)
    corners = np.empty((n_cross, 3, 4))
    mask = np.zeros((n_cross, 6), np.bool_)
    k = 0
    for t in range(m):
        if status[t] == 2:
            cross[k] = t
            union = codes[indices[t, 0]] | codes[indices[t, 1]] | codes[indices[t, 2]]
            for p in range(6):
                mask[k, p] = (union >> p) & 1
            for v in range(3):
                _copy_row(corners[k], v, clip, indices[t, v])        # (a loop: see `_copy_row`)
            k += 1
    # (The flags as bool values, not literals, and the planes a writable
    # copy: the types `clip_triangles` passes, so one compiled `_clip_kernel`
    # serves both.)
    planes, f32 = FRUSTUM_PLANES.copy(), np.bool_(True)
    fans = _clip_kernel(corners, mask, planes, f32, np.zeros(n_cross, np.int64),
                        np.zeros((0, 3, 4)), np.zeros((0, 3, 3)), np.bool_(False))
    fan_clip = np.empty((fans.sum(), 3, 4))
    fan_weights = np.empty((fans.sum(), 3, 3))
    _clip_kernel(corners, mask, planes, f32, fans, fan_clip, fan_weights, np.bool_(True))
    total = 0
    k = 0
    for t in range(m):
        if status[t] == 1:
            total += 1
        elif status[t] == 2:
            total += fans[k]
            k += 1
    source = np.empty(total, np.int64)
    slot = np.empty(total, np.int64)
    at = 0
    k = 0
    row = 0
    for t in range(m):
        if status[t] == 1:
            source[at] = t
            slot[at] = -1
            at += 1
        elif status[t] == 2:
            for f in range(fans[k]):
                source[at] = t
                slot[at] = row
                row += 1
                at += 1
            k += 1
    return source, slot, fan_clip, fan_weights
