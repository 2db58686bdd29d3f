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


def shade_unlit(vertex_color: np.ndarray, material_color: np.ndarray) -> np.ndarray:
    """Unlit shading: (F, 4) interpolated straight vertex colours, (4,) material
    colour -> (F, 4) premultiplied fragment colours."""
    return premultiply(vertex_color * material_color)
