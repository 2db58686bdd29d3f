"""Every conformance scene through both renderers, compared with its tolerance.

On failure the soft, gl and diff images are written under pytest's tmp_path
(never into the source tree) and the path is in the failure message.
"""

from __future__ import annotations

import pytest

import softras
from softras.verification.verifier import scene_tolerance
from conftest import SCENES, write_failure_images

SCENE_FILES = sorted(p for p in SCENES.glob("*.json"))


def test_there_are_scenes():
    assert len(SCENE_FILES) >= 12


@pytest.mark.gl
@pytest.mark.parametrize("path", SCENE_FILES, ids=[p.stem for p in SCENE_FILES])
def test_soft_matches_gl(path, tmp_path):
    scene = softras.load_scene(path)
    soft = softras.render(scene, precision="gl")
    gl = softras.render(scene, backend="gl")
    result = softras.compare(soft, gl, **scene_tolerance(scene)[0])   # the one set of defaults
    if not result.passed:
        write_failure_images(tmp_path, soft=soft, gl=gl, diff=result.diff_image)
        pytest.fail(f"{path.name}: {result.summary()} (images in {tmp_path})")
    # The contract's skeleton bar, whatever a scene's own tolerance says.
    assert result.ssim >= 0.99


@pytest.mark.parametrize("path", SCENE_FILES, ids=[p.stem for p in SCENE_FILES])
def test_exact_precision_close_to_gl_precision(path):
    """exact (float64, no snapping) differs from gl only near edges and ties.

    Snapping to 1/256 pixel moves an edge by at most 1/512 pixel, which flips
    only samples that lie that close to an edge: a small fraction of the
    edge pixels.  With 4 samples per pixel each edge pixel has 4 samples that
    can flip (seen: 2.8 % of pixels, by up to 7/255, on the MSAA fan whose
    many edges separate similar colours), so the allowance scales with the
    sample count; SSIM >= 0.99 (the skeleton bar) keeps the images close.
    """
    scene = softras.load_scene(path)
    gl = softras.render(scene, precision="gl")
    exact = softras.render(scene, precision="exact")
    threshold = 2
    if any(t.min_filter.endswith("mipmap_linear") for t in scene.textures.values()):
        # gl reproduces llvmpipe's piecewise-linear log2 (the trilinear blend
        # weight up to 0.043 off the spec's) and its 8-bit weights; exact
        # follows the spec: up to ~11/255 apart on high-contrast checkers.
        threshold = 12
    min_ssim = 0.99
    if any(t.max_anisotropy >= 2 for t in scene.textures.values()):
        # Two different anisotropic filters: exact averages the EXT spec's
        # probes, gl reproduces llvmpipe's EWA on one mip level
        # (softras.pipeline.texture).  Seen on the grazing floor: up to 64/255, SSIM
        # 0.984; each is checked against its own reference elsewhere (glref;
        # tests/stages/test_texture.py).
        threshold, min_ssim = 64, 0.98
    result = softras.compare(gl, exact, threshold=threshold, max_bad_fraction=0.02 * scene.samples,
                             min_ssim=min_ssim)
    assert result.passed, result.summary()
