"""softras's spec bounds against a GPU's pictures, recorded on an NVIDIA H200.

tests/recorded/nvidia_h200 holds glref's pictures of every JSON scene in
scenes/ at its own sample count, drawn by an NVIDIA H200 (driver 580.159.04,
EGL) with ``scripts/planted_bugs.py``'s format (``pictures.npz`` and the
context's capability record in ``info.json``). CI has no GPU; judging needs
none: each picture must lie within the spec bounds softras computes with
the GPU's own capability record (sub-pixel bits, sample positions), as
``softras conformance`` on that machine judged it (docs/verification.md,
"On a GPU").

Three scenes are outside the bounds, each a difference the bounds do not
model (docs/verification.md lists them with the figures); they are asserted
to FAIL as recorded, so that a change in the bounds that admits them, or a
new difference, shows here.

``pictures_4x.npz`` holds the same GPU's pictures of every scene at 4
samples a pixel (GL's MSAA count; a fourth H200, the same driver and
capability record, 2026-11-28), judged the same way: softras's picture at
the GPU's 4 sample positions, the bounds of the scene at 4 samples.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import softras
from conftest import REPO, SCENES, load_script
from softras.renderer import render_scene
from softras.verification import verifier

pb = load_script("planted_bugs")

RECORDED = REPO / "tests" / "recorded" / "nvidia_h200"
NAMES = sorted(p.stem for p in SCENES.glob("*.json"))

# scene -> (pixels outside, the largest excess /255), as recorded: the GPU's
# picture leaves the bounds there (docs/verification.md, "On a GPU").
KNOWN = {
    # vertices at 1e7: the ceiling's far-plane edge 1.2 px lower (how the GPU clips: not established).
    "extreme_huge_coordinates": (4, 254.0),
    # the horizon of a floor 1e6 wide: colours 1.5/255 off (likely float32 interpolation).
    "huge_coordinates": (256, 1.0),
    # bump-mapped lighting: one pixel 1/255 beyond the envelope of the variants.
    "bump_mapped_plane": (1, 1.0),
}


@pytest.fixture(scope="module")
def recorded():
    return pb.recorded_pictures(RECORDED, NAMES)


def test_every_scene_was_recorded(recorded):
    assert recorded.info["GL_RENDERER"].startswith("NVIDIA H200")
    missing = [n for n, picture in recorded.pictures.items() if isinstance(picture, str)]
    assert missing == []
    assert set(KNOWN) <= set(NAMES)


def _judge(scene, picture, caps, known):
    """The GPU's picture of the scene judged against softras's spec bounds
    (softras's picture at the GPU's sample positions): FAIL with the
    recorded (pixels outside, largest excess) when ``known``, else not FAIL;
    softras's own picture always inside."""
    image = render_scene(scene, precision="gl", pattern=verifier.gl_positions(scene, caps))
    result = verifier.verify(scene, image, picture, profile="spec", capabilities=caps)
    assert result.figures["outside_image"] == 0, result.reasons
    if known is not None:
        pixels, excess = known
        assert result.verdict == verifier.FAIL
        assert result.figures["outside_reference"] == pixels, result.reasons
        assert f"worst {excess:.1f}/255 beyond" in result.reasons[0], result.reasons
    else:
        assert result.verdict != verifier.FAIL, result.reasons


@pytest.mark.parametrize("name", NAMES)
def test_the_gpu_picture_is_within_the_spec_bounds(recorded, name):
    scene = softras.load_scene(SCENES / f"{name}.json")
    _judge(scene, recorded.pictures[name], recorded.info, KNOWN.get(name))


# scene -> (pixels outside, the largest excess /255) at 4 samples, as recorded.
KNOWN_4X = {
    "extreme_huge_coordinates": (4, 190.0),
    "huge_coordinates": (128, 1.0),
    "bump_mapped_plane": (1, 1.0),
}


@pytest.fixture(scope="module")
def recorded_4x():
    with np.load(RECORDED / "pictures_4x.npz", allow_pickle=False) as data:
        return {key: data[key] for key in data.files}


def test_every_scene_was_recorded_at_4_samples(recorded_4x):
    assert sorted(recorded_4x) == NAMES
    assert set(KNOWN_4X) <= set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_the_gpu_4x_picture_is_within_the_spec_bounds(recorded, recorded_4x, name):
    scene = dataclasses.replace(softras.load_scene(SCENES / f"{name}.json"), samples=4)
    _judge(scene, recorded_4x[name], recorded.info, KNOWN_4X.get(name))
