"""Fragment stage: colour of each fragment.

Colours are linear RGBA in [0, 1].  A fragment's colour is
vertex colour x material colour, output premultiplied (rgb * a, a), which is
what the per-sample operations and the framebuffer hold (DESIGN.md section 3).
"""

from __future__ import annotations

import numpy as np


def premultiply(rgba: np.ndarray) -> np.ndarray:
    """Straight (..., 4) RGBA -> premultiplied (rgb * a, a)."""
    out = rgba.copy()
    out[..., :3] *= rgba[..., 3:4]
    return out


def shade_unlit(vertex_color: np.ndarray, material_color: np.ndarray,
                texel: np.ndarray | None = None) -> np.ndarray:
    """Unlit shading: (F, 4) interpolated straight vertex colours, (4,) material
    colour, optional (F, 4) premultiplied texels -> (F, 4) premultiplied
    fragment colours: premultiply(vertex x material) x texel (the product of
    two premultiplied colours is the premultiplied product of the straight ones)."""
    rgba = premultiply(vertex_color * material_color)
    if texel is not None:
        rgba = rgba * texel
    return rgba


def _normalize(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def light_vectors(lights) -> np.ndarray:
    """(L, 4) light vectors: (position, 1) for point lights, (-direction, 0) for
    directional ones, so that ``L = normalize(xyz - P * w)`` either way."""
    out = np.zeros((len(lights), 4))
    for i, light in enumerate(lights):
        if light.type == "point":
            out[i] = (*light.position, 1.0)
        else:
            out[i] = (*(-np.asarray(light.direction, np.float64)), 0.0)
    return out


def blinn_phong(base_rgb: np.ndarray, position: np.ndarray, normal: np.ndarray,
                eye: np.ndarray, lights, material) -> np.ndarray:
    """Blinn-Phong in world space (the same formula as glref's lighting.glsl).

    base_rgb : (N, 3) straight vertex colour x material colour.
    position : (N, 3) world positions; normal : (N, 3) unit world normals.
    eye : (3,) camera position.  lights : scene lights; material : Material.

    ``ambient * base + sum_lights [N.L > 0] light_colour * (diffuse (N.L) base
    + specular max(N.H, 0)^shininess)`` with ``L`` towards the light,
    ``V = normalize(eye - P)``, ``H = normalize(L + V)``.  No attenuation, no
    clamping (the framebuffer clamps).  Returns (N, 3).
    """
    view = _normalize(eye[None, :] - position)
    out = material.ambient * base_rgb
    for vector, light in zip(light_vectors(lights), lights):
        to_light = _normalize(vector[None, :3] - position * vector[3])
        n_dot_l = np.einsum("nk,nk->n", normal, to_light)
        half = _normalize(to_light + view)
        n_dot_h = np.maximum(np.einsum("nk,nk->n", normal, half), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            spec = np.power(n_dot_h, material.shininess)
        term = np.asarray(light.color)[None, :] * (material.diffuse * n_dot_l[:, None] * base_rgb
                                                    + material.specular * spec[:, None])
        out = out + np.where((n_dot_l > 0)[:, None], term, 0.0)
    return out


def face_normals(world_positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) unit face normals ``normalize(cross(p1 - p0, p2 - p0))`` of
    triangles (T, 3) vertex indices into world positions (N, 3)."""
    p0, p1, p2 = (world_positions[triangles[:, k]] for k in range(3))
    return _normalize(np.cross(p1 - p0, p2 - p0))
