"""A ground truth for texture filters: the scene supersampled in exact precision.

softras's own filters (ripmap, EWA: `softras.pipeline.texture_beyond`) have no
GL to be compared with; they are judged against `supersampled_reference`
instead (tests/stages/test_texture_beyond.py, docs/textures_and_lighting.md).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from softras.renderer import render_scene


def supersampled_reference(scene, factor: int = 16) -> np.ndarray:
    """A supersampled ground truth: (H, W, 4) float64 premultiplied RGBA in
    [0, 1], row 0 = top.

    Every pixel is covered by factor x factor sample positions (a regular
    grid at ((a + 1/2) / factor, (b + 1/2) / factor)); at each the scene is
    rendered in exact precision (float64, analytic uv per sample) with
    ``texture_filter="level0"`` (bilinear on level 0: the texture as a
    continuous function, no pre-filtering), and the samples are box-averaged.
    """
    big = dataclasses.replace(scene, width=scene.width * factor, height=scene.height * factor, samples=1)
    image = render_scene(big, precision="exact", texture_filter="level0").astype(np.float64) / 255.0
    h, w = scene.height, scene.width
    return image.reshape(h, factor, w, factor, 4).mean(axis=(1, 3))


def errors_against(reference: np.ndarray, image: np.ndarray) -> dict:
    """RMSE and mean absolute error of an (H, W, 4) uint8 image against a
    float reference in [0, 1], over the RGB channels, on the 0..255 scale."""
    diff = image[..., :3].astype(np.float64) - reference[..., :3] * 255.0
    return {"rmse": float(np.sqrt(np.mean(diff ** 2))), "mean_abs": float(np.mean(np.abs(diff)))}
