"""Vertex stage: model space -> clip space.

The matrices themselves (node hierarchy, look-at, projections) are part of the
scene model (`softras.scene`), because both renderers must agree on them; this
stage applies them to vertices, the way glref's vertex shader does.

Spaces: model (mesh positions) -> world (`Draw.world`) -> eye (`Camera.view`)
-> clip (`Camera.projection`).  All matrices use the column-vector convention,
``clip = P @ V @ M @ [x, y, z, 1]``.
"""

from __future__ import annotations

import numpy as np


def model_view_projection(projection: np.ndarray, view: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Return ``P @ V @ M``, shape (4, 4) float64 (model -> clip)."""
    return projection @ view @ world


def to_clip(positions: np.ndarray, mvp: np.ndarray, precision: str = "gl") -> np.ndarray:
    """Transform model-space positions to clip space.

    Parameters
    ----------
    positions : (N, 3) float array, model space.
    mvp : (4, 4) float64, model -> clip.
    precision : "gl" or "exact".
        "gl" does what glref's vertex shader does with ``u_mvp * vec4(p, 1)``:
        the matrix and positions rounded to float32, the product summed column
        by column in float32.  "exact" works in float64.

    Returns
    -------
    (N, 4) float64 clip-space positions (x_c, y_c, z_c, w_c); in "gl" mode
    every value is exactly a float32.
    """
    if precision == "gl":
        m = mvp.astype(np.float32)
        p = positions.astype(np.float32)
        clip = m[:, 0] * p[:, 0:1]
        clip = clip + m[:, 1] * p[:, 1:2]
        clip = clip + m[:, 2] * p[:, 2:3]
        clip = clip + m[:, 3]
        return clip.astype(np.float64)
    homogeneous = np.concatenate([positions.astype(np.float64), np.ones((len(positions), 1))], axis=1)
    return homogeneous @ mvp.T


def world_positions(positions: np.ndarray, world: np.ndarray) -> np.ndarray:
    """(N, 3) model positions -> (N, 3) world positions (lighting space)."""
    return positions @ world[:3, :3].T + world[:3, 3]


def world_normals(normals: np.ndarray, world: np.ndarray, unit: bool = True) -> np.ndarray:
    """(N, 3) model normals -> world normals by the inverse-transpose of the
    world matrix's 3x3 (normalised when ``unit``)."""
    n = normals @ np.linalg.inv(world[:3, :3])           # == (inv(M)^T @ n^T)^T
    return n / np.linalg.norm(n, axis=1, keepdims=True) if unit else n


def world_tangents(tangents: np.ndarray, world: np.ndarray) -> np.ndarray:
    """(N, 4) model tangents (xyz, handedness w) -> (N, 4) world tangents:
    xyz by the world matrix's 3x3 M (tangents follow the surface, unlike
    normals), not normalised; w times sign(det M), so that a mirroring world
    matrix keeps ``B = w cross(N, T)`` pointing along the mapped bitangent."""
    out = np.array(tangents, dtype=np.float64)
    out[:, :3] = out[:, :3] @ world[:3, :3].T
    out[:, 3] *= -1.0 if np.linalg.det(world[:3, :3]) < 0 else 1.0
    return out
