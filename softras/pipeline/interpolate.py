"""Interpolate stage: barycentrics, perspective-correct attributes, depth.

All positions here are unsnapped window coordinates (GL's y-up window space,
pixel centres at half-integers); llvmpipe also sets up its attribute planes
from the unsnapped positions.

Screen-space barycentrics ``lam`` weight the three vertices linearly in window
space; depth z_w is interpolated with them (docs/design.md section 4: depth is linear in
screen space).  A vertex attribute is linear in clip space, not in window
space, so it is interpolated with the perspective-corrected weights
``b_i = (lam_i / w_i) / sum_j (lam_j / w_j)``, where the edge functions
(twice the sub-triangles' areas) may stand for ``lam``: the area cancels.
"""

from __future__ import annotations

import numpy as np


def edge_functions(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The three edge functions of each triangle at a window point.

    vertices : (F, 3, 2) float64 window x, y of each fragment's triangle.
    points : (F, 2) float64 window x, y where to evaluate.
    Returns e : (F, 3) float64; e_i is twice the signed area of the
    sub-triangle opposite vertex i (the edge from vertex i+1 to i+2 and the
    point), so e / e.sum() are the screen-space barycentrics.
    """
    x, y = vertices[..., 0], vertices[..., 1]
    px, py = points[:, 0:1], points[:, 1:2]
    nxt, prv = [1, 2, 0], [2, 0, 1]
    x1, y1, x2, y2 = x[:, nxt], y[:, nxt], x[:, prv], y[:, prv]
    return (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)


def barycentric(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Screen-space barycentric coordinates.

    vertices : (F, 3, 2) float64 window x, y of each fragment's triangle.
    points : (F, 2) float64 window x, y where to evaluate.
    Returns lam : (F, 3) float64 with lam.sum(axis=1) == 1 (up to rounding);
    lam_i is the area of the sub-triangle opposite vertex i over the area.
    """
    e = edge_functions(vertices, points)
    return e / e.sum(axis=1, keepdims=True)


def perspective_weights(lam: np.ndarray, inv_w: np.ndarray) -> np.ndarray:
    """Perspective-correct weights from screen-space barycentrics.

    lam : (F, 3) screen-space barycentrics, or any multiple of them per
    fragment: the weights are ratios, ``(lam_i / w_i) / sum_j (lam_j / w_j)``
    (GL 4.5 core, section 14.6.1, equation 14.9), so a common factor cancels,
    and the renderer passes the edge functions (`edge_functions`) without
    dividing them by the triangle's area (three float64 divisions a fragment
    fewer, and one rounding).
    inv_w : (F, 3) 1/w_clip per vertex.
    Returns (F, 3) weights that sum to 1 and interpolate clip-space-linear
    attributes exactly.
    """
    q = lam * inv_w
    return q / q.sum(axis=1, keepdims=True)


def perspective_weights_at(vertices: np.ndarray, inv_w: np.ndarray, points: np.ndarray) -> np.ndarray:
    """`perspective_weights` of the `edge_functions` at window points.

    vertices : (F, 3, >=2) window coordinates; inv_w : (F, 3); points : (F, 2).
    Returns (F, 3) perspective-correct weights.
    """
    return perspective_weights(edge_functions(vertices[..., :2], points), inv_w)


def interpolate(weights: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Weighted sum of per-vertex values: (F, 3) x (F, 3, K) -> (F, K)."""
    return np.einsum("fi,fik->fk", weights, values)


def depth_at_samples(vertices: np.ndarray, pixel_x: np.ndarray, pixel_y: np.ndarray,
                     sample_positions: np.ndarray) -> np.ndarray:
    """Window-space depth z_w of each fragment at each of its pixel's samples.

    vertices : (F, 3, 3) window x, y, z_w; pixel_x, pixel_y : (F,) pixels;
    sample_positions : (S, 2) positions within the pixel in [0, 1).
    Returns (F, S) float64.  z_w is linear in window space, so it is
    evaluated from the triangle's depth plane
    ``z = z_0 + dz/dx (x - x_0) + dz/dy (y - y_0)``, as GL implementations do;
    a triangle of constant depth gets exactly that depth everywhere (which
    matters for the "equal" depth test).
    """
    x, y, z = vertices[..., 0], vertices[..., 1], vertices[..., 2]
    dx1, dy1, dz1 = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0], z[:, 1] - z[:, 0]
    dx2, dy2, dz2 = x[:, 2] - x[:, 0], y[:, 2] - y[:, 0], z[:, 2] - z[:, 0]
    det = dx1 * dy2 - dx2 * dy1
    dzdx = (dz1 * dy2 - dz2 * dy1) / det
    dzdy = (dx1 * dz2 - dx2 * dz1) / det
    sx = pixel_x[:, None] + sample_positions[None, :, 0] - x[:, 0:1]
    sy = pixel_y[:, None] + sample_positions[None, :, 1] - y[:, 0:1]
    return z[:, 0:1] + dzdx[:, None] * sx + dzdy[:, None] * sy


def perspective_at(vertices: np.ndarray, inv_w: np.ndarray, values: np.ndarray,
                   points: np.ndarray) -> np.ndarray:
    """Perspective-correct attribute at window points, inside the triangle or not.

    vertices : (F, 3, >=2) window coordinates; inv_w : (F, 3); values :
    (F, 3, K) per-vertex attributes; points : (F, 2).  Returns (F, K); the
    attribute planes are simply extended outside the triangle.
    """
    return interpolate(perspective_weights_at(vertices, inv_w, points), values)


def quad_derivatives(vertices: np.ndarray, inv_w: np.ndarray, x: np.ndarray, y: np.ndarray,
                     values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Screen-space derivatives per 2x2 quad, as GL implementations take them.

    vertices, inv_w, values : as in `perspective_at`; x, y : (F,) pixels.
    The quad of pixel (x, y) has its top-left (in llvmpipe's view; GL's
    lower-left) pixel TL at (x & ~1, y & ~1).  The attribute is evaluated at
    the pixel centres of TL, TR = TL + (1, 0) and BL = TL + (0, 1) from the
    triangle's planes, whether those pixels are covered or not (helper
    pixels), rounded to float32 like a shader's values, and
    ``ddx = TR - TL``, ``ddy = BL - TL``.  Every pixel of a quad gets the same
    derivatives.  Returns (F, K) each.
    """
    qx = (x & ~1).astype(np.float64) + 0.5
    qy = (y & ~1).astype(np.float64) + 0.5
    tl = perspective_at(vertices, inv_w, values, np.stack([qx, qy], axis=1)).astype(np.float32)
    tr = perspective_at(vertices, inv_w, values, np.stack([qx + 1, qy], axis=1)).astype(np.float32)
    bl = perspective_at(vertices, inv_w, values, np.stack([qx, qy + 1], axis=1)).astype(np.float32)
    return (tr - tl).astype(np.float64), (bl - tl).astype(np.float64)


def analytic_derivatives(vertices: np.ndarray, inv_w: np.ndarray, points: np.ndarray,
                         values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact screen-space derivatives of a perspective-correct attribute at points.

    With q_i = lam_i / w_i (lam the screen-space barycentrics, affine in x and
    y) and Q = sum q_i, the attribute is a = sum q_i a_i / Q, so
    ``da/dx = (sum dq_i/dx a_i - a dQ/dx) / Q``.  Arguments as in
    `perspective_at`; returns (F, K) each.
    """
    vertices = vertices[..., :2]
    lam = barycentric(vertices, points)
    q = lam * inv_w
    big_q = q.sum(axis=1, keepdims=True)
    a = np.einsum("fi,fik->fk", q, values) / big_q
    out = []
    for step in ((1.0, 0.0), (0.0, 1.0)):
        dlam = barycentric(vertices, points + np.array(step)) - lam   # affine: exact step
        dq = dlam * inv_w
        out.append((np.einsum("fi,fik->fk", dq, values) - a * dq.sum(axis=1, keepdims=True)) / big_q)
    return out[0], out[1]
