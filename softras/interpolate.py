"""Interpolate stage: barycentrics, perspective-correct attributes, depth.

All positions here are unsnapped window coordinates (GL's y-up window space,
pixel centres at half-integers); llvmpipe also sets up its attribute planes
from the unsnapped positions.

Screen-space barycentrics ``lam`` weight the three vertices linearly in window
space; depth z_w is interpolated with them (DESIGN.md: depth is linear in
screen space).  A vertex attribute is linear in clip space, not in window
space, so it is interpolated with the perspective-corrected weights
``b_i = (lam_i / w_i) / sum_j (lam_j / w_j)``.
"""

from __future__ import annotations

import numpy as np


def barycentric(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Screen-space barycentric coordinates.

    vertices : (F, 3, 2) float64 window x, y of each fragment's triangle.
    points : (F, 2) float64 window x, y where to evaluate.
    Returns lam : (F, 3) float64 with lam.sum(axis=1) == 1 (up to rounding);
    lam_i is the area of the sub-triangle opposite vertex i over the area.
    """
    x, y = vertices[..., 0], vertices[..., 1]
    px, py = points[:, 0:1], points[:, 1:2]
    nxt, prv = [1, 2, 0], [2, 0, 1]
    # Edge function of the edge opposite vertex i (from vertex i+1 to i+2).
    x1, y1, x2, y2 = x[:, nxt], y[:, nxt], x[:, prv], y[:, prv]
    e = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    return e / e.sum(axis=1, keepdims=True)


def perspective_weights(lam: np.ndarray, inv_w: np.ndarray) -> np.ndarray:
    """Perspective-correct weights from screen-space barycentrics.

    lam : (F, 3) screen-space barycentrics; inv_w : (F, 3) 1/w_clip per vertex.
    Returns (F, 3) weights that sum to 1 and interpolate clip-space-linear
    attributes exactly.
    """
    q = lam * inv_w
    return q / q.sum(axis=1, keepdims=True)


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
