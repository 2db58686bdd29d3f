"""Vertex stage: model space -> clip space.

The matrices themselves (node hierarchy, look-at, projections) are part of the
scene model (`softras.scene`), because both renderers must agree on them; this
stage applies them to vertices, the way glref's vertex shader does.

Spaces: model (mesh positions) -> world (`Draw.world`) -> eye (`Camera.view`)
-> clip (`Camera.projection`).  All matrices use the column-vector convention,
``clip = P @ V @ M @ [x, y, z, 1]``.
"""

from __future__ import annotations

import numba
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
        return _to_clip_float32(np.ascontiguousarray(positions, np.float32), mvp.astype(np.float32))
    homogeneous = np.concatenate([positions.astype(np.float64), np.ones((len(positions), 1))], axis=1)
    return homogeneous @ mvp.T


@numba.njit(cache=True)
def _to_clip_float32(p, m):
    """(N, 3) float32 positions, (4, 4) float32 matrix -> (N, 4) float64 clip
    positions, each row ``((m[:, 0] x + m[:, 1] y) + m[:, 2] z) + m[:, 3]``
    in float32 (no fused multiply-add: numba does not contract)."""
    out = np.empty((p.shape[0], 4))
    for v in range(p.shape[0]):
        x, y, z = p[v, 0], p[v, 1], p[v, 2]
        for r in range(4):
            out[v, r] = np.float64(((m[r, 0] * x + m[r, 1] * y) + m[r, 2] * z) + m[r, 3])
    return out


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


def eye_position(view: np.ndarray) -> np.ndarray:
    """The camera's position in world space (3,): the translation of the
    inverse of the (4, 4) view matrix (lighting's eye, ``V = normalize(eye - P)``)."""
    return np.linalg.inv(view)[:3, 3]
