"""Displacement mapping: a mesh step, applied once when a scene is loaded.

A material ``"displacement": {"texture": NAME, "scale": S}`` moves every
vertex of its mesh along its unit normal by ``S * h``, with ``h`` the height
texture's red channel at the vertex uv.  :func:`softras.scene.load_scene`
applies it, so ``Draw.mesh`` already holds the displaced mesh and both
renderers (softras and glref) draw identical triangles.

The height at a vertex (:func:`vertex_heights`) is deterministic and does not
depend on the screen: the texture's level 0 (premultiplied RGBA8, the same
bytes the samplers use), bilinear in float64 with the GL convention
``u = s W - 1/2``, ``v = t H - 1/2`` and the texture's own ``wrap_s`` /
``wrap_t`` (repeat, clamp_to_edge, mirrored_repeat), red channel / 255.  The
texture's filters are not used (there are no screen derivatives at a vertex).

After the move the normals are recomputed from the displaced surface
(:func:`smooth_normals`): each vertex gets the normalised sum of the
(area-weighted) face normals ``cross(p1 - p0, p2 - p0)`` of every triangle
that touches a vertex at the same displaced position (equal after rounding
to 1e-9 of the mesh's largest coordinate), so duplicated seam vertices (the
sphere's u = 0 / u = 1 column, equal only to rounding) stay smooth.  A vertex whose sum
is zero keeps its original normal.
"""

from __future__ import annotations

import numpy as np

from softras.scene.model import Texture
from softras.scene.texels import bilinear


def vertex_heights(texture: Texture, uvs: np.ndarray) -> np.ndarray:
    """Heights in [0, 1] at vertex uvs: (N, 2) (s, t) -> (N,) float64.

    Bilinear in level 0 (float64 weights, GL texel centres), the texture's
    wrap modes, red channel of the premultiplied texel / 255.
    """
    uvs = np.asarray(uvs, np.float64)
    if len(uvs) == 0:
        return np.zeros(0)
    texel = bilinear(texture.levels[0], uvs[:, 0], uvs[:, 1], texture.wrap_s, texture.wrap_t)
    return texel[:, 0] / 255.0


def smooth_normals(positions: np.ndarray, indices: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """(N, 3) unit vertex normals of a triangle mesh: area-weighted face
    normals summed over every vertex with the same position (positions
    rounded to a grid of 1e-9 x the largest absolute coordinate, at least
    1e-9), normalised; ``fallback`` (N, 3) where that sum is zero."""
    positions = np.asarray(positions, np.float64)
    indices = np.asarray(indices, np.int64).reshape(-1, 3)
    p0, p1, p2 = (positions[indices[:, k]] for k in range(3))
    face = np.cross(p1 - p0, p2 - p0)                       # |face| = 2 x area
    cell = 1e-9 * max(1.0, float(np.abs(positions).max(initial=0.0)))
    _, welded = np.unique(np.rint(positions / cell), axis=0, return_inverse=True)
    welded = welded.reshape(-1)
    total = np.zeros((welded.max() + 1 if len(welded) else 0, 3))
    for k in range(3):
        np.add.at(total, welded[indices[:, k]], face)
    normal = total[welded]
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    fallback = np.asarray(fallback, np.float64)
    fallback = fallback / np.linalg.norm(fallback, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(length > 0, normal / length, fallback)


def displace(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, indices: np.ndarray,
             texture: Texture, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Move vertices along their normals by ``scale * height``.

    positions (N, 3), normals (N, 3) model space (need not be unit), uvs
    (N, 2), indices (M, 3) triangles; texture : the prepared height texture.
    Returns (displaced positions (N, 3), recomputed unit normals (N, 3)),
    float64, model space: ``p + scale * h(uv) * normalize(n)``.
    """
    n = np.asarray(normals, np.float64)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    moved = np.asarray(positions, np.float64) + (scale * vertex_heights(texture, uvs))[:, None] * n
    return moved, smooth_normals(moved, indices, n)
