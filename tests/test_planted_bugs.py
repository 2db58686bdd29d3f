"""Planted bugs (scripts/planted_bugs.py): the spec profile fails every one.

Each planted bug is judged against GL's picture of the unmodified scene under
``profile="spec"``: on llvmpipe in this process, on softpipe through the
script's child process (``GALLIUM_DRIVER=softpipe``: the driver is chosen
when a context is created), and on an NVIDIA H200's pictures recorded in
tests/recorded/nvidia_h200 (``scripts/planted_bugs.py --draw`` there; no
GPU is needed to judge them). Every bug in every scene of the script's list
(about 30 s once numba's kernels are cached), as ``python
scripts/planted_bugs.py`` does.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import REPO, load_script

pb = load_script("planted_bugs")

MUTATIONS = pb.MUTATIONS
BUGS = [(m.name, scene) for m in MUTATIONS if not m.permitted for scene in m.scenes]
#: The consistent fill-rule swap, which the specification permits (see below).
SWAP = next(m for m in MUTATIONS if m.permitted)
RECORDED_GPU = REPO / "tests" / "recorded" / "nvidia_h200"


@pytest.fixture(scope="module")
def references():
    import glref

    here = pb.gl_pictures_in_process(pb.scene_names(MUTATIONS))
    if not str(here.info.get("GL_RENDERER", "")).startswith("llvmpipe"):
        pytest.skip(f"this process's GL is {here.info.get('GL_RENDERER')!r}, not llvmpipe")
    try:
        softpipe = pb.gl_pictures_subprocess("softpipe", pb.scene_names(MUTATIONS))
    except RuntimeError as exc:
        if "GL_RENDERER" in str(exc):
            pytest.skip(str(exc))
        raise
    assert glref.info()["GL_RENDERER"].startswith("llvmpipe")    # the child did not change this process
    return [here, softpipe, pb.recorded_pictures(RECORDED_GPU, pb.scene_names(MUTATIONS))]


@pytest.fixture(scope="module")
def rows(references):
    return pb.run(references, MUTATIONS)


def _describe(row) -> str:
    return f"{row.mutation or '(unmodified)'} on {row.scene}, {row.implementation}: {row.verdict}: {row.reasons}"


@pytest.mark.gl
def test_every_implementation_drew_every_scene(references):
    assert [r.name for r in references] == ["llvmpipe", "softpipe", "NVIDIA"]
    assert references[1].info["GL_RENDERER"].startswith("softpipe")
    assert references[2].info["GL_RENDERER"].startswith("NVIDIA H200")
    for ref in references:
        for name, picture in ref.pictures.items():
            assert isinstance(picture, np.ndarray), f"{ref.name} could not draw {name}: {picture}"


@pytest.mark.gl
@pytest.mark.parametrize("mutation, scene", BUGS)
def test_planted_bug_fails_under_spec(rows, mutation, scene):
    mine = [r for r in rows if r.mutation == mutation and r.scene == scene and r.profile == "spec"]
    assert len(mine) == 3                                      # three implementations
    for row in mine:
        assert row.changed_pixels > 0, f"{mutation} changes nothing in {scene}"
        assert row.verdict == pb.FAIL, _describe(row)
        assert row.outside_image > 0 and row.outside_reference == 0, _describe(row)


@pytest.mark.gl
def test_no_unmodified_scene_fails(rows):
    clean = [r for r in rows if r.mutation is None]
    assert len(clean) == 3 * len(pb.scene_names(MUTATIONS))
    assert pb.false_failures(clean) == [], [_describe(r) for r in pb.false_failures(clean)]


@pytest.mark.gl
@pytest.mark.parametrize("scene", SWAP.scenes)
def test_consistent_fill_rule_swap_is_not_failed_under_spec(rows, scene):
    """GL 4.6 section 14.6.1 permits either consistent tie rule: not a bug."""
    mine = [r for r in rows if r.mutation == SWAP.name and r.scene == scene and r.profile == "spec"]
    assert len(mine) == 3
    for row in mine:
        assert row.changed_pixels > 0                          # the swap is visible in this scene
        assert row.verdict != pb.FAIL, _describe(row)


def test_patches_are_undone():
    from softras.pipeline import interpolate, setup

    before = (setup.setup_triangles, interpolate.perspective_weights)
    for patch in (pb.fill_rule_swapped, pb.fill_rule_ties_excluded, pb.perspective_off):
        with patch():
            assert (setup.setup_triangles, interpolate.perspective_weights) != before
    assert (setup.setup_triangles, interpolate.perspective_weights) == before


def test_moved_vertex_moves_one_pixel():
    from softras.scene import load_scene

    scene = load_scene(pb.scene_path("perspective_gradient"))
    moved = pb.moved_vertex(scene, 1.0, 0.0)
    before, _ = pb._window(scene, scene.draws[0])
    after, _ = pb._window(moved, moved.draws[0])
    ndc = lambda c: c[:, :2] / c[:, 3:4]                       # noqa: E731
    window = (ndc(after) - ndc(before)) * np.array([scene.width, scene.height]) / 2
    changed = np.flatnonzero(np.abs(window).sum(axis=1) > 1e-9)
    assert len(changed) == 1
    assert np.allclose(window[changed[0]], [1.0, 0.0], atol=1e-9)
    assert np.allclose(after[changed[0], 3], before[changed[0], 3])


@pytest.mark.gl
def test_main_prints_the_table_and_writes_json(tmp_path, capsys):
    out = tmp_path / "planted.json"
    status = pb.main(["--only", "vertex_moved,blend_swapped", "--quick", "--implementations", "llvmpipe",
                      "--json", str(out)])
    printed = capsys.readouterr().out
    assert status == 0, printed
    assert "| a vertex moved by 1 px (window x) | fill_rule_grid | spec |" in printed
    assert "0 false failures of 2 verdicts" in printed
    record = pb.json.loads(out.read_text())
    assert record["summary"]["planted_bugs_failed"] == record["summary"]["planted_bug_verdicts"] == 2
    assert {r["verdict"] for r in record["rows"] if r["mutation"]} == {"fail"}
