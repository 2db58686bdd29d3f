"""piglit-style random triangles: softras coverage must equal llvmpipe's exactly.

Triangles are drawn 24 at a time with additive blending, triangle k adding
2^(k mod 8)/255 to channel k // 8, so one image of each renderer holds 24
independent coverage masks (RGBA8 sums of distinct powers of two are exact).
Positions are given directly in clip space (identity camera), so both
renderers see the same float32 vertices and differences can only come from
the viewport transform, snapping and the fill rule.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import softras

PER_PASS = 24
TRIANGLES_PER_KIND = 1008


def random_triangles(rng: np.random.Generator, n: int, kind: str, width: int, height: int) -> np.ndarray:
    """(n, 3, 2) window coordinates (GL, y up) inside the viewport."""
    size = np.array([width, height])
    if kind == "pixel_centres":
        return rng.integers(0, size, size=(n, 3, 2)) + 0.5
    if kind == "pixel_corners":
        return rng.integers(0, size + 1, size=(n, 3, 2)).astype(float)
    if kind == "subpixel":
        return rng.uniform(0, size - 2, size=(n, 1, 2)) + rng.uniform(0, 1.5, size=(n, 3, 2))
    if kind == "slivers":
        a, b = rng.uniform(0, size, size=(n, 1, 2)), rng.uniform(0, size, size=(n, 1, 2))
        c = a + (b - a) * rng.uniform(0, 1, size=(n, 1, 1)) + rng.normal(0, 0.3, size=(n, 1, 2))
        return np.clip(np.concatenate([a, b, c], axis=1), 0, size)
    if kind == "ties":
        # On a 1/1024 grid: many vertices snap exactly half-way between two
        # 1/256 positions, and many samples lie exactly on edges.
        return np.round(rng.uniform(0, size, size=(n, 3, 2)) * 1024) / 1024
    if kind == "large":
        return rng.uniform(0, size, size=(n, 3, 2))
    raise ValueError(kind)


def coverage_scene(triangles: np.ndarray, width: int, height: int) -> dict:
    """A scene drawing up to 24 triangles given in window coordinates."""
    nodes = []
    for k, tri in enumerate(triangles):
        ndc = np.zeros((3, 3))
        ndc[:, 0] = tri[:, 0] / (width / 2) - 1
        ndc[:, 1] = tri[:, 1] / (height / 2) - 1
        color = [0.0, 0.0, 0.0, 1.0]
        color[k // 8] = (1 << (k % 8)) / 255
        nodes.append({"name": f"t{k}", "mesh": {"positions": ndc.tolist(), "indices": [[0, 1, 2]]},
                      "material": {"color": color}, "blend": "add", "depth_test": False})
    identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    return {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
            "camera": {"projection_matrix": identity, "view_matrix": identity}, "nodes": nodes}


def coverage_masks(image: np.ndarray, n: int) -> np.ndarray:
    """(H, W, 4) encoded image -> (n, H, W) bool coverage of each triangle."""
    return np.stack([(image[..., k // 8] >> (k % 8)) & 1 for k in range(n)]).astype(bool)


@pytest.mark.gl
@pytest.mark.parametrize("kind", ["pixel_centres", "pixel_corners", "subpixel", "slivers", "ties", "large"])
@pytest.mark.parametrize("width, height", [(64, 48), (256, 160)])
def test_coverage_identical_to_llvmpipe(kind, width, height):
    seed = 20261121 + width
    rng = np.random.default_rng([seed, len(kind)])
    mismatched = []
    for start in range(0, TRIANGLES_PER_KIND, PER_PASS):
        triangles = random_triangles(rng, PER_PASS, kind, width, height)
        scene = coverage_scene(triangles, width, height)
        soft = coverage_masks(softras.render(scene, precision="gl"), PER_PASS)
        gl = coverage_masks(softras.render(scene, backend="gl"), PER_PASS)
        for k in np.nonzero((soft != gl).any(axis=(1, 2)))[0]:
            mismatched.append((start + k, int((soft[k] != gl[k]).sum()), triangles[k]))
    if mismatched:
        index, pixels, tri = mismatched[0]
        minimal = coverage_scene(tri[None], width, height)
        pytest.fail(f"{len(mismatched)} of {TRIANGLES_PER_KIND} triangles differ (seed {seed}, kind {kind}); "
                    f"first: triangle {index}, {pixels} pixels, window {tri.tolist()}; "
                    f"minimal scene: {json.dumps(minimal)}")
