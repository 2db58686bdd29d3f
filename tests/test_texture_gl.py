"""Texture sampling against OpenGL (glref): level choice and every filter/wrap pair.

The level test gives every mip level its own solid colour (softras.scene.texels's
mip chain is replaced for the test, and glref uploads that chain,
``mipmaps="upload"``, instead of generating the levels), so the colour of a
pixel says which level the sampler chose.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

import glref
import softras
from conftest import SCENES, write_failure_images
from softras.scene import texels
from softras.pipeline import texture

PALETTE = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [255, 0, 255],
                    [0, 255, 255], [255, 255, 255], [128, 128, 128], [128, 0, 0]], np.uint8)

GRAZING_FLOOR = {
    "softras_scene": 1, "width": 160, "height": 120, "background": [0, 0, 0, 1],
    "camera": {"projection": "perspective", "fov_y": 60, "near": 0.05, "far": 200,
               "eye": [0, 0.6, 2], "target": [0.4, 0, -8]},
    "textures": {"t": {"procedural": "checker", "size": [256, 256],
                       "min_filter": "nearest_mipmap_nearest", "mag_filter": "nearest"}},
    "nodes": [{"rotate": [-90, 1, 0, 0],
               "mesh": {"positions": [[-20, -3, 0], [20, -3, 0], [20, 80, 0], [-20, 80, 0]],
                        "indices": [[0, 1, 2], [0, 2, 3]],
                        "uvs": [[0, 40], [20, 40], [20, 0], [0, 0]]},
               "material": {"texture": "t"}}],
}


@pytest.fixture
def solid_levels(monkeypatch):
    """Mip level k of every texture is the solid colour PALETTE[k]."""
    real_chain = texels.mip_chain

    def chain(level0, premultiply=False, method="llvmpipe"):
        levels = []
        for k, level in enumerate(real_chain(level0, premultiply, method)):
            solid = np.empty_like(level)
            solid[..., :3] = PALETTE[k]
            solid[..., 3] = 255
            levels.append(solid)
        return tuple(levels)

    monkeypatch.setattr(texels, "mip_chain", chain)


def level_of(image: np.ndarray) -> np.ndarray:
    """(H, W) level index per pixel, -1 where the colour is no level's."""
    distance = np.abs(image[:, :, None, :3].astype(int) - PALETTE[None, None].astype(int)).sum(-1)
    level = distance.argmin(-1)
    level[distance.min(-1) > 0] = -1
    return level


@pytest.mark.gl
def test_mip_level_choice_equals_gl(solid_levels, monkeypatch, tmp_path):
    """nearest_mipmap_nearest on a grazing floor: softras (gl precision) picks
    GL's level on every pixel that is not within rounding of a level boundary.

    "Within rounding" = the level changes when rho^2 is scaled by 1 -/+ 0.2 %
    (lambda -/+ 0.0007), i.e. float32 noise in the interpolated uvs could
    decide it.
    """
    scene = softras.load_scene(GRAZING_FLOOR)
    gl_image = glref.render(scene, mipmaps="upload")
    soft_image = softras.render(scene, precision="gl")
    gl, soft = level_of(gl_image), level_of(soft_image)
    covered = gl >= 0
    assert covered.sum() > 8000
    assert len(np.unique(gl[covered])) >= 7, "the floor should show most of the 9 levels"

    real_rho2 = texture.rho_squared
    nudged = []
    for factor in (1 - 2e-3, 1 + 2e-3):
        monkeypatch.setattr(texture, "rho_squared",
                            lambda du, dv, f=factor: real_rho2(du, dv) * np.float32(f))
        nudged.append(level_of(softras.render(scene, precision="gl")))
    monkeypatch.setattr(texture, "rho_squared", real_rho2)
    ambiguous = nudged[0] != nudged[1]
    assert ambiguous.mean() < 0.01

    wrong = (soft != gl) & ~ambiguous
    if wrong.any():
        write_failure_images(tmp_path, soft=soft_image, gl=gl_image)
        ys, xs = np.nonzero(wrong)
        pytest.fail(f"{wrong.sum()} pixels choose another level than GL, e.g. pixel "
                    f"({xs[0]}, {ys[0]}): soft {soft[ys[0], xs[0]]}, gl {gl[ys[0], xs[0]]} "
                    f"(images in {tmp_path})")


@pytest.mark.gl
def test_exact_level_choice_close_to_gl(solid_levels):
    """exact precision (analytic derivatives per pixel, the spec's rounding)
    differs from GL's per-quad choice only along level boundaries."""
    scene = softras.load_scene(GRAZING_FLOOR)
    gl = level_of(glref.render(scene, mipmaps="upload"))
    exact = level_of(softras.render(scene, precision="exact"))
    covered = gl >= 0
    assert ((exact == gl) & covered).sum() / covered.sum() > 0.9
    assert (np.abs(exact - gl)[covered] <= 1).all()


MIN_FILTERS = ("nearest", "linear", "nearest_mipmap_nearest", "linear_mipmap_nearest",
               "nearest_mipmap_linear", "linear_mipmap_linear")
WRAPS = ("repeat", "clamp_to_edge", "mirrored_repeat")


def _filter_scene(min_filter: str, wrap: str) -> dict:
    """A 37x23 noise texture on a turned floor (minified) and a near quad
    (magnified), uvs beyond [0, 1] so that the wrap mode shows."""
    quad = {"indices": [[0, 1, 2], [0, 2, 3]]}
    return {
        "softras_scene": 1, "width": 128, "height": 96,
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 100,
                   "eye": [0.3, 1.2, 2.5], "target": [0, 0, -2]},
        "textures": {"t": {"procedural": "noise", "size": [37, 23], "seed": 1, "wrap_s": wrap,
                           "wrap_t": wrap, "min_filter": min_filter, "mag_filter": "linear"}},
        "nodes": [
            {"rotate": [-90, 1, 0, 0], "translate": [0, 0, -3],
             "mesh": dict(quad, positions=[[-2, -6, 0], [2, -6, 0], [2, 6, 0], [-2, 6, 0]],
                          uvs=[[-1, 2], [2, 2], [2, -1], [-1, -1]]),
             "material": {"texture": "t"}},
            {"translate": [0.6, 0.9, 1.2], "rotate": [20, 0.3, 1, 0],
             "mesh": dict(quad, positions=[[-0.3, -0.3, 0], [0.3, -0.3, 0], [0.3, 0.3, 0], [-0.3, 0.3, 0]],
                          uvs=[[-0.2, 1.2], [1.2, 1.2], [1.2, -0.2], [-0.2, -0.2]]),
             "material": {"texture": "t"}},
        ],
    }


@pytest.mark.gl
@pytest.mark.parametrize("min_filter,wrap", list(itertools.product(MIN_FILTERS, WRAPS)))
def test_filter_and_wrap_match_gl(min_filter, wrap, tmp_path):
    """Every GL min filter with every wrap: llvmpipe's 8.8 fixed-point (repeat,
    clamp) and float (mirrored) paths reproduced to 1/255 on >= 99.9 % of
    pixels (the rest: float32 rounding of the interpolated uvs)."""
    scene = softras.load_scene(_filter_scene(min_filter, wrap))
    soft = softras.render(scene, precision="gl")
    gl = softras.render(scene, backend="gl")
    diff = np.abs(soft.astype(int) - gl.astype(int)).max(axis=2)
    if (diff > 1).mean() > 0.001 or (diff > 0).mean() > 0.005:
        write_failure_images(tmp_path, soft=soft, gl=gl)
        pytest.fail(f"{min_filter}/{wrap}: {(diff > 0).sum()} pixels differ, {(diff > 1).sum()} "
                    f"by more than 1/255 (max {diff.max()}; images in {tmp_path})")


# The mip levels are uploaded, not generated: with no_aos_sampling llvmpipe's
# glGenerateMipmap samples in float too, which softras's chain does not follow.
_GL_IN_SUBPROCESS = """
import sys, numpy as np, glref
assert glref.info()["env"]["GALLIVM_PERF"] == "no_aos_sampling"
np.save(sys.argv[2], glref.render(sys.argv[1], mipmaps="upload"))
"""


@pytest.mark.gl
@pytest.mark.parametrize("name", ["texture_photo", "texture_npot"])
def test_float_weights_match_llvmpipe_without_aos_sampling(name, tmp_path):
    """GALLIVM_PERF=no_aos_sampling makes llvmpipe filter in float; softras's
    ``texture_fixed_point=False`` reproduces that, while its default (8.8 fixed
    point, llvmpipe's default) does not.  The variable is read once per
    process, so that GL runs in a child process, with softras's mip levels
    uploaded (no_aos_sampling changes glGenerateMipmap's blit too)."""
    import os
    import subprocess
    import sys
    from conftest import SCENES
    path = SCENES / f"{name}.json"
    out = tmp_path / "gl.npy"
    env = dict(os.environ, GALLIVM_PERF="no_aos_sampling")
    subprocess.run([sys.executable, "-c", _GL_IN_SUBPROCESS, str(path), str(out)], env=env,
                   check=True, timeout=120)
    gl_float = np.load(out)
    soft_float = softras.render(path, precision="gl", texture_fixed_point=False)
    soft_fixed = softras.render(path, precision="gl")
    diff = np.abs(soft_float.astype(int) - gl_float.astype(int)).max(axis=2)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.005
    changed = np.abs(soft_fixed.astype(int) - gl_float.astype(int)).max(axis=2) > 0
    assert changed.mean() > 0.05       # the fixed-point weights show on many pixels


# --------------------------------------------------------------------------- anisotropic filtering


def _aniso_scene(min_filter: str, wrap: str, max_anisotropy: float) -> dict:
    """The anisotropic grazing floor with another sampler state; uvs reach
    below 0 on the near side so that the wrap mode shows."""
    data = json.loads((SCENES / "texture_anisotropic_floor.json").read_text())
    tex = data["textures"]["checker"]
    tex.update(min_filter=min_filter, wrap_s=wrap, wrap_t=wrap, max_anisotropy=max_anisotropy)
    if wrap != "repeat":
        tex.update(procedural="noise", size=[64, 32], seed=2)
        for k in ("squares", "color0", "color1"):
            tex.pop(k)
        data["nodes"][0]["mesh"]["uvs"] = [[-0.5, 3], [1.5, 3], [1.5, -0.2], [-0.5, -0.2]]
    return data


@pytest.mark.gl
@pytest.mark.parametrize("min_filter,wrap", [("linear_mipmap_linear", "repeat"), ("linear", "repeat"),
                                             ("nearest_mipmap_nearest", "clamp_to_edge"),
                                             ("linear_mipmap_linear", "mirrored_repeat")])
def test_anisotropic_matches_llvmpipe(min_filter, wrap, tmp_path):
    """max_anisotropy 16: softras's gl precision reproduces llvmpipe's EWA
    (level from the minor axis, Gaussian table, float32) to 1/255 on
    >= 99 % of pixels; the rest is float32 uv noise deciding whether a texel
    at the ellipse's edge gets weight exp(-2) or none (seen: up to 11/255 on
    2 pixels of the floor)."""
    scene = softras.load_scene(_aniso_scene(min_filter, wrap, 16))
    soft = softras.render(scene, precision="gl")
    gl = softras.render(scene, backend="gl")
    diff = np.abs(soft.astype(int) - gl.astype(int)).max(axis=2)
    if (diff > 1).mean() > 0.001 or (diff > 0).mean() > 0.01:
        write_failure_images(tmp_path, soft=soft, gl=gl)
        pytest.fail(f"{min_filter}/{wrap}: {(diff > 0).sum()} pixels differ, {(diff > 1).sum()} by "
                    f"more than 1/255 (max {diff.max()}; images in {tmp_path})")


@pytest.mark.gl
def test_llvmpipe_anisotropy_limit_is_ignored_and_truncated():
    """What llvmpipe 22.3 does with the limit, found by experiment and in its
    source: 2, 3, 8 and 16 give the same bytes (lp_build_pmin compares pmin2
    with pmin2 * maxAniso^2, so the clamp never fires) and 1.5 is no
    anisotropy at all (the state tracker truncates to an integer).  softras's
    gl precision does the same; exact precision follows the spec, where the
    limit matters."""
    images = {a: softras.render(_aniso_scene("linear_mipmap_linear", "repeat", a), backend="gl")
              for a in (1, 1.5, 2, 16)}
    assert (images[2] == images[16]).all()
    assert (images[1.5] == images[1]).all()
    assert (images[2] != images[1]).any()
    soft = {a: softras.render(_aniso_scene("linear_mipmap_linear", "repeat", a), precision="gl")
            for a in (1, 1.5, 2, 16)}
    assert (soft[2] == soft[16]).all() and (soft[1.5] == soft[1]).all()
    exact = {a: softras.render(_aniso_scene("linear_mipmap_linear", "repeat", a), precision="exact")
             for a in (2, 16)}
    assert (exact[2] != exact[16]).any()
