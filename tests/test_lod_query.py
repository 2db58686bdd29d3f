"""softras's lambda range against the level of detail two GLs computed.

`softras.pipeline.texture_bounds.lambda_range` is a claim about GL 4.6
section 8.14.1: every lambda a conformant GL computes for a lookup lies in
it. scripts/lod_query.py asks a GL (textureQueryLOD) for the lambda of each
bump-mapped fragment and compares (docs/verification.md, "On a GPU"):

- this process's GL (llvmpipe here): inside everywhere;
- an NVIDIA H200, recorded (tests/recorded/nvidia_h200/lod.npz): inside but
  at 167 silhouette pixels of the 8k-triangle sphere, up to 0.425 above, and
  164 of those are pixels where the footprint's major axis (the Jacobian's
  largest singular value) is above the range too: the GPU takes the major
  axis, which section 8.14.1's m_u + m_v does not bound.
"""

from __future__ import annotations

import dataclasses

import pytest

from conftest import REPO, load_script
from softras.pipeline import texture_bounds

lq = load_script("lod_query")


@pytest.fixture(scope="module")
def scenes():
    return lq.scenes()


@pytest.fixture(scope="module")
def ranges(scenes):
    return {name: lq.ranges(scene) for name, scene in scenes.items()}


@pytest.fixture(scope="module")
def drawing(scenes):
    """This process's GL's lambdas; glref's pictures are its own again after the probe."""
    import glref

    plane = scenes["bump_mapped_plane"]
    before = glref.render(plane)
    drawn = lq.draw(scenes)
    assert (glref.render(plane) == before).all()
    return drawn


@pytest.mark.gl
def test_this_gl_computes_lambdas_inside_the_range(ranges, drawing):
    for name, r in ranges.items():
        row = lq.judge(drawing[name], r)
        assert row["pixels"] > 7000, name
        assert (row["below"], row["above"]) == (0, 0), (name, row)


def test_the_recorded_gpu_lambdas(ranges):
    import numpy as np

    with np.load(REPO / "tests" / "recorded" / "nvidia_h200" / "lod.npz") as data:
        drawing = {k: data[k] for k in data.files}
    plane = lq.judge(drawing["bump_mapped_plane"], ranges["bump_mapped_plane"])
    assert (plane["pixels"], plane["below"], plane["above"]) == (7880, 0, 0)
    sphere = lq.judge(drawing["bump_mapped_8k_512"], ranges["bump_mapped_8k_512"])
    assert (sphere["below"], sphere["above"], sphere["above_where_sigma1_above"]) == (0, 167, 164)
    assert sphere["worst_above"] == pytest.approx(0.425, abs=0.001)
    low, median, high = sphere["sigma1_offset_p1_p50_p99"]
    assert -0.1 < low and abs(median) < 0.01 and high < 0.07     # lambda = log2 sigma1, give or take 0.1


@pytest.mark.gl
def test_the_check_can_fail(scenes, drawing, monkeypatch):
    """Planted: lambda_range without the piecewise-linear log2's error (the
    lower end 0.086 too high): llvmpipe's lambdas fall below it."""
    original = texture_bounds.lambda_range
    exact_log2 = dataclasses.replace(texture_bounds.LOD, log2_error=0.0)
    monkeypatch.setattr(texture_bounds, "lambda_range", lambda c, size, lod=None: original(c, size, exact_log2))
    row = lq.judge(drawing["bump_mapped_8k_512"], lq.ranges(scenes["bump_mapped_8k_512"]))
    assert row["below"] > 1000
