"""RGBA8 blending against glref, byte for byte: softras reproduces llvmpipe's arithmetic.

Mesa 22.3 llvmpipe blends an RGBA8 buffer in 8-bit integers: the float32
fragment colour becomes bytes (float32 ``c * 255``, rounded half to even),
factors multiply with lp_build_mul_norm's ``(t + (t >> 8) + 0x80) >> 8``
and the equations saturate (`softras.pipeline.ops.blend_unorm8`).  These tests count
the pixels where softras and glref differ -- every one is a failure.

The random test isolates the blend: every pixel is its own quad of one
constant colour (no interpolation error), so base and source bytes are the
same in both renderers and any difference is blend arithmetic.
"""

from pathlib import Path

import numpy as np
import pytest

import softras

N = 48                       # the image is N x N pixels, one quad per pixel
MODES = ("over", "over_straight", "add", "subtract", "reverse_subtract", "min", "max")
SCENES = Path(__file__).resolve().parents[1] / "scenes"

# The byte pairs (x, y) where lp_build_mul_norm gives round(x * y / 255) - 1:
# x * y = 255 k + 128, k >= 136 (152 * 229 / 255 = 136.502 -> 136).
MUL_NORM_LOW = [(152, 229), (169, 212), (173, 241), (188, 196), (191, 253), (194, 232),
                (197, 244), (208, 236), (214, 227), (223, 251), (226, 233), (239, 247)]


def _cells(colors: np.ndarray) -> dict:
    """A mesh of N x N one-pixel quads; quad (i, j) has the straight RGBA colors[j, i] (j = GL row)."""
    positions, vertex_colors, indices = [], [], []
    for j in range(N):
        for i in range(N):
            k = len(positions)
            positions += [[i, j, 0], [i + 1, j, 0], [i + 1, j + 1, 0], [i, j + 1, 0]]
            vertex_colors += [colors[j, i].tolist()] * 4
            indices += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
    return {"positions": positions, "colors": vertex_colors, "indices": indices}


def _scene(base: np.ndarray, top: np.ndarray, mode: str, samples: int) -> dict:
    camera = {"projection": "orthographic", "left": 0, "right": N, "bottom": 0, "top": N,
              "near": -1, "far": 1}
    return {"softras_scene": 1, "width": N, "height": N, "samples": samples,
            "background": [0, 0, 0, 0], "camera": camera,
            "nodes": [{"name": "base", "mesh": _cells(base), "depth_test": False},
                      {"name": "top", "mesh": _cells(top), "depth_test": False, "blend": mode}]}


def _colours(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded random (base, top) straight colours, (N, N, 4) each, with directed cells.

    Half the base pixels are opaque.  Row 0 holds the byte pairs where llvmpipe's
    normalised multiply rounds down (dst byte x under source alpha byte 255 - y,
    and the mirrored pair), row 1 the extremes: alpha 0 and 1, colours 0 and 1.
    """
    rng = np.random.default_rng(seed)
    base = rng.random((N, N, 4))
    top = rng.random((N, N, 4))
    base[..., 3] = np.where(rng.random((N, N)) < 0.5, 1.0, base[..., 3])
    for k, (x, y) in enumerate(MUL_NORM_LOW + [(b, a) for a, b in MUL_NORM_LOW]):
        base[0, k] = [x / 255, x / 255, x / 255, 1.0]
        top[0, k] = [1.0, 0.0, (255 - y) / 255, (255 - y) / 255]
    extremes = [0.0, 1.0]
    for k in range(16):
        base[1, k] = [extremes[k & 1], extremes[(k >> 1) & 1], 0.5, 1.0]
        top[1, k] = [extremes[(k >> 2) & 1], 0.5, 1.0, extremes[(k >> 3) & 1]]
    return base, top


def _differing_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int((a != b).any(axis=-1).sum())


@pytest.mark.gl
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("mode", MODES)
def test_random_blends_match_llvmpipe(mode, samples):
    base, top = _colours(seed=MODES.index(mode))
    scene = _scene(base, top, mode, samples)
    gl = softras.render(scene, backend="gl")
    soft = softras.render(scene)
    stages = softras.render(scene, fast_path=False)
    assert _differing_pixels(soft, gl) == 0
    assert _differing_pixels(stages, gl) == 0


@pytest.mark.gl
def test_mul_norm_rounding_is_llvmpipe_s():
    # dst 152 under (1 - alpha) = 229/255, source colour 0: llvmpipe stores
    # (t + (t >> 8) + 128) >> 8 = 136 for t = 152 * 229, not round(136.502) = 137.
    base = np.zeros((N, N, 4))
    base[...] = [152 / 255, 0, 0, 1]
    top = np.zeros((N, N, 4))
    top[...] = [0, 0, 0, 26 / 255]
    scene = _scene(base, top, "over", 1)
    gl = softras.render(scene, backend="gl")
    soft = softras.render(scene)
    assert gl[0, 0, 0] == 136
    np.testing.assert_array_equal(soft, gl)


@pytest.mark.gl
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("name", ["blend_equations", "blend_self_overlap",
                                  "transparent_over_opaque", "extreme_alpha"])
def test_blend_scenes_identical_to_glref(name, samples):
    path = SCENES / f"{name}.json"
    gl = softras.render(path, backend="gl", samples=samples)
    soft = softras.render(path, samples=samples)
    assert _differing_pixels(soft, gl) == 0
