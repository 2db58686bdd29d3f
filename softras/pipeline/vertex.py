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
        return _transform(np.ascontiguousarray(positions, np.float32), mvp.astype(np.float32))
    return _transform(np.ascontiguousarray(positions, np.float64), np.ascontiguousarray(mvp, np.float64))


# The transforms are loops of our own, not numpy's matrix product: that goes
# through BLAS, whose order of summation and fused multiply-adds depend on the
# CPU, and whose threads, spinning after a product, took the cores from the
# compiled kernels that run next (the 71k scan in exact precision: 60-73 ms
# a render with one BLAS thread, 80-106 ms with two).
@numba.njit(cache=True)
def _transform(p, m):
    """(N, 3) positions and an (R, 4) matrix of the same type -> (N, R)
    float64, each row ``((m[:, 0] x + m[:, 1] y) + m[:, 2] z) + m[:, 3]`` in
    that type: float32 in gl precision, as GLSL sums ``u_mvp * vec4(p, 1)``
    column by column; float64 otherwise (no fused multiply-add: numba does
    not contract)."""
    out = np.empty((p.shape[0], m.shape[0]))
    for v in range(p.shape[0]):
        x, y, z = p[v, 0], p[v, 1], p[v, 2]
        for r in range(m.shape[0]):
            out[v, r] = np.float64(((m[r, 0] * x + m[r, 1] * y) + m[r, 2] * z) + m[r, 3])
    return out


def world_positions(positions: np.ndarray, world: np.ndarray) -> np.ndarray:
    """(N, 3) model positions -> (N, 3) world positions (lighting space):
    ``M @ [x, y, z, 1]`` for the world matrix's top rows (`_transform`)."""
    return _transform(np.ascontiguousarray(positions, np.float64), np.ascontiguousarray(world[:3], np.float64))


def world_normals(normals: np.ndarray, world: np.ndarray, unit: bool = True) -> np.ndarray:
    """(N, 3) model normals -> world normals by the inverse-transpose of the
    world matrix's 3x3 (normalised when ``unit``), ``inv(M)^T @ n`` summed
    as `_transform` sums (its translation column 0)."""
    n = _transform(np.ascontiguousarray(normals, np.float64), normal_rows(world))
    return n / np.linalg.norm(n, axis=1, keepdims=True) if unit else n


def normal_rows(world: np.ndarray) -> np.ndarray:
    """The (3, 4) float64 rows `world_normals` transforms normals by: the
    inverse-transpose of the world matrix's 3x3, translation column 0."""
    return normal_rows_of(world[None])[0]


def normal_rows_of(worlds: np.ndarray) -> np.ndarray:
    """`normal_rows` of a stack of world matrices (D, 4, 4): (D, 3, 4), in
    one call of numpy's inverse, which inverts each matrix of a stack as it
    inverts a matrix alone (the same LAPACK solve: the same bits).  A call
    took 3-9 us for one matrix; the compiled path lights many draws with
    one call a pass."""
    rows = np.zeros((len(worlds), 3, 4))
    rows[:, :, :3] = np.linalg.inv(np.asarray(worlds, np.float64)[:, :3, :3]).transpose(0, 2, 1)
    return rows


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
