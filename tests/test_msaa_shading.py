"""This process's GL shades a multisampled pixel once, as softras models it.

softras writes one fragment colour to every covered sample of a pixel (GL
4.6 section 14.3.1.1's minimum); its strict profile holds the reference GL
to that. scripts/msaa_shading.py asks the GL (gl_SampleMaskIn, the
derivative of gl_FragCoord, textureQueryLOD); an NVIDIA H200 at 16 samples
answers 4 samples an invocation, invocations half a pixel apart and a
level of detail one lower (docs/verification.md, "On a GPU").
"""

from __future__ import annotations

import pytest

from conftest import load_script

pytestmark = pytest.mark.gl

ms = load_script("msaa_shading")


def test_one_invocation_covers_the_whole_pixel():
    import glref

    figures, _ = ms.measure()
    counts = [s for s in glref.info()["sample_counts"] if s <= 16]
    assert set(figures) == {f"{name}@{count}" for name in ms.SCENES for count in counts}
    for key, row in figures.items():
        count = int(key.rsplit("@", 1)[1])
        assert row["pixels"] > 6000
        assert row["samples_per_invocation"] == [count] * 3, key
        assert row["dFdx_fragcoord"] == [1.0] * 3, key
    for name in ms.SCENES:       # the same level of detail at every count (one shading position a pixel)
        lods = [figures[f"{name}@{count}"]["lod_median"] for count in counts]
        assert max(lods) - min(lods) < 0.05, (name, lods)
