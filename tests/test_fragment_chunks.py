"""The stages rasterize a large draw by bands of rows (`render.row_bands`),
shade its fragments in chunks (`render.fragment_chunks`) and resolve the
picture by bands of rows (`ops.resolve`): the picture must not depend on
where the bands and chunks split a draw."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softras
from softras.pipeline import ops, rasterize, render

SCENES = Path(__file__).resolve().parents[1] / "scenes"

# Every shading model, textures with quad derivatives (mipmapped,
# anisotropic), normal and bump maps, the alpha test (glTF MASK), blending
# over a draw's own fragments and depth ties.
CASES = ["lit_spheres.json", "lit_textured_sphere.json", "bump_mapped_plane.json",
         "texture_anisotropic_floor.json", "gltf_alpha_modes.gltf", "blend_self_overlap.json",
         "intersecting_triangles.json", "msaa_fan.json"]


def test_fragment_chunks_are_the_fragments_in_order():
    frags = rasterize.Fragments(np.arange(10), np.arange(10, 20, dtype=np.int32),
                                np.arange(20, 30, dtype=np.int32), np.arange(10, dtype=np.uint32))
    chunks = list(render.fragment_chunks(frags, 3))
    assert [len(c) for c in chunks] == [3, 3, 3, 1]
    for field in ("tri", "x", "y", "mask"):
        assert np.array_equal(np.concatenate([getattr(c, field) for c in chunks]), getattr(frags, field))


def test_row_bands_cut_every_box_into_its_rows():
    bbox = np.array([[0, 9, 0, 99], [3, 5, 40, 41], [2, 2, 7, 6], [0, 0, 95, 99]])
    assert list(render.row_bands(bbox, 10, 1, limit=10_000))[0] is bbox        # small enough: as it is
    bands = list(render.row_bands(bbox, 10, 2, limit=300))                       # 15 rows a band
    assert len(bands) == 7
    for t, (x0, x1, y0, y1) in enumerate(bbox):
        rows = [y for band in bands for y in range(band[t, 2], band[t, 3] + 1)]
        assert rows == list(range(y0, y1 + 1))
        assert all((band[t, 0], band[t, 1]) == (x0, x1) for band in bands)


@pytest.mark.parametrize("precision", ["gl", "exact"])
@pytest.mark.parametrize("name", CASES)
def test_banded_and_chunked_draws_give_the_same_picture(name, precision, monkeypatch):
    """Bands of 20000 samples' rows, chunks of 997 fragments (a prime: chunks
    end inside quads, rows and triangles) and a resolve by 7 rows against
    one band, one chunk and one resolve per draw."""
    scene = softras.load_scene(SCENES / name)
    monkeypatch.setattr(render, "BAND_SAMPLES", 1 << 40)
    monkeypatch.setattr(render, "FRAGMENT_CHUNK", 1 << 40)
    monkeypatch.setattr(ops, "RESOLVE_ROWS", 1 << 40)
    whole = softras.render(scene, precision=precision, fast_path=False)
    monkeypatch.setattr(render, "BAND_SAMPLES", 20_000)
    monkeypatch.setattr(render, "FRAGMENT_CHUNK", 997)
    monkeypatch.setattr(ops, "RESOLVE_ROWS", 7)
    chunked = softras.render(scene, precision=precision, fast_path=False)
    differ = int((whole != chunked).any(-1).sum())
    assert differ == 0, f"{name} ({precision}): {differ} pixels differ"
