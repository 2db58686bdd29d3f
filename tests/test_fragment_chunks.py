"""The stages shade a draw's fragments in chunks (`render.fragment_chunks`):
the picture must not depend on where the chunks split a draw."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softras
from softras.pipeline import rasterize, render

SCENES = Path(__file__).resolve().parents[1] / "scenes"

# Every shading model, textures with quad derivatives (mipmapped,
# anisotropic), normal and bump maps, the alpha test (glTF MASK), blending
# over a draw's own fragments and depth ties.
CASES = ["lit_spheres.json", "lit_textured_sphere.json", "bump_mapped_plane.json",
         "texture_anisotropic_floor.json", "gltf_alpha_modes.gltf", "blend_self_overlap.json",
         "intersecting_triangles.json", "msaa_fan.json"]


def test_fragment_chunks_are_the_fragments_in_order():
    frags = rasterize.Fragments(np.arange(10), np.arange(10, 20, dtype=np.int32), np.arange(20, 30, dtype=np.int32),
                                np.arange(10, dtype=np.uint32))
    chunks = list(render.fragment_chunks(frags, 3))
    assert [len(c) for c in chunks] == [3, 3, 3, 1]
    for field in ("tri", "x", "y", "mask"):
        assert np.array_equal(np.concatenate([getattr(c, field) for c in chunks]), getattr(frags, field))


@pytest.mark.parametrize("precision", ["gl", "exact"])
@pytest.mark.parametrize("name", CASES)
def test_chunked_draws_give_the_same_picture(name, precision, monkeypatch):
    """Chunks of 97 fragments (a prime: chunks end inside quads, rows and
    triangles) against one chunk per draw."""
    scene = softras.load_scene(SCENES / name)
    monkeypatch.setattr(render, "FRAGMENT_CHUNK", 1 << 40)
    whole = softras.render(scene, precision=precision, fast_path=False)
    monkeypatch.setattr(render, "FRAGMENT_CHUNK", 97)
    chunked = softras.render(scene, precision=precision, fast_path=False)
    assert np.array_equal(whole, chunked), f"{name} ({precision}): {int((whole != chunked).any(-1).sum())} pixels differ"
