"""Tests for the conformance run (softras.verification.conformance, softras.verification.report,
softras.verification.ambiguity) and ``softras conformance``.

Scenes are tiny dicts in pixel units written to tmp_path, plus
scenes/lit_textured_sphere.json, whose softras and GL pictures differ by a
known 1/255 in 5 pixels (KNOWN_1_LEVEL; its tolerance allows it): with a
tolerance of 0 it must fail, in the colour stage.
Tests that render with glref carry the ``gl`` marker.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

import softras
from softras.verification import ambiguity, conformance
from softras.cli import main
from softras.verification.conformance import FAIL, PASS, WARN

from conftest import SCENES

# A scene with a known, legitimate 1/255 colour difference from llvmpipe (5 px:
# float32 vs float64 rounding in Phong shading of a textured sphere).
KNOWN_1_LEVEL = SCENES / "lit_textured_sphere.json"
EXACT = {"threshold": 0, "max_bad_fraction": 0.0, "min_ssim": 0.99}

# Pixel camera: 1 unit = 1 pixel, z in [-1, 1].
PIXELS = {"projection": "orthographic", "left": 0, "right": 16, "bottom": 0, "top": 12,
          "near": -1, "far": 1}
TRIANGLE = {
    "softras_scene": 1, "width": 16, "height": 12, "background": [0, 0, 0, 1], "camera": PIXELS,
    "nodes": [{"name": "triangle",
               "mesh": {"positions": [[1.3, 1.2, 0], [14.6, 2.1, 0], [6.2, 10.7, 0]],
                        "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]]}}],
}
# Two coplanar quads at z = 0: the second (less) loses the tie everywhere they overlap.
COPLANAR = {
    "softras_scene": 1, "width": 16, "height": 12, "background": [0, 0, 0, 1], "camera": PIXELS,
    "nodes": [
        {"name": "first", "mesh": {"positions": [[0, 0, 0], [10, 0, 0], [10, 12, 0], [0, 12, 0]],
                                   "indices": [[0, 1, 2], [0, 2, 3]], "colors": [[1, 0, 0, 1]] * 4}},
        {"name": "second", "mesh": {"positions": [[6, 0, 0], [16, 0, 0], [16, 12, 0], [6, 12, 0]],
                                    "indices": [[0, 1, 2], [0, 2, 3]], "colors": [[0, 0, 1, 1]] * 4},
         "depth_test": "less"},
    ],
}


def write_scene(folder: Path, name: str, data: dict) -> Path:
    path = folder / f"{name}.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def scene_names(n: int) -> list[Path]:
    return [Path(f"scenes/s{i:02d}.json") for i in range(n)]


# ---------------------------------------------------------------------------
# Choosing scenes: -k, --shard


@pytest.mark.parametrize("count", [1, 2, 3, 5, 8])
def test_shards_cover_every_scene_exactly_once(count):
    paths = scene_names(23)
    shards = [conformance.shard(paths, i, count) for i in range(1, count + 1)]
    together = [path for part in shards for path in part]
    assert sorted(together) == sorted(paths)            # every scene ...
    assert len(together) == len(set(together))          # ... exactly once
    sizes = [len(part) for part in shards]
    assert max(sizes) - min(sizes) <= 1
    # Deterministic: the input order does not matter.
    assert conformance.shard(list(reversed(paths)), 1, count) == shards[0]


def test_shards_of_the_repository_scenes_partition_them():
    everything = conformance.select([SCENES])
    parts = [conformance.select([SCENES], shard_spec=f"{i}/3") for i in (1, 2, 3)]
    assert sorted(p for part in parts for p in part) == everything


@pytest.mark.parametrize("text", ["0/3", "4/3", "a/b", "3", "1/0", "-1/2"])
def test_bad_shard_is_an_error(text):
    with pytest.raises(conformance.ConformanceError, match="--shard"):
        conformance.parse_shard(text)


def test_k_is_a_substring_or_a_glob(tmp_path):
    for name in ("texture_npot", "texture_photo", "depth_functions", "lit_spheres"):
        write_scene(tmp_path, name, TRIANGLE)
    stems = lambda **kw: [p.stem for p in conformance.select([tmp_path], **kw)]  # noqa: E731
    assert stems(patterns=["texture"]) == ["texture_npot", "texture_photo"]
    assert stems(patterns=["*_p*"]) == ["texture_photo"]          # glob: the whole name
    assert stems(patterns=["_p"]) == ["texture_photo"]             # substring
    assert stems(patterns=["depth", "lit_*"]) == ["depth_functions", "lit_spheres"]
    with pytest.raises(conformance.ConformanceError, match="no scene matches"):
        conformance.select([tmp_path], patterns=["nothing"])
    with pytest.raises(conformance.ConformanceError, match="no such scene"):
        conformance.select([tmp_path / "missing.json"])


# ---------------------------------------------------------------------------
# Tolerances


def test_tolerance_is_the_scenes_own_else_feature_defaults(tmp_path):
    own = write_scene(tmp_path, "own", dict(TRIANGLE, tolerance={"threshold": 5}))
    tolerance, source = conformance.scene_tolerance(softras.load_scene(own))
    assert source == "scene" and tolerance["threshold"] == 5 and tolerance["max_bad_fraction"] == 0.001
    plain = write_scene(tmp_path, "plain", TRIANGLE)
    tolerance, source = conformance.scene_tolerance(softras.load_scene(plain))
    assert tolerance == conformance.FEATURE_TOLERANCES["base"] and source == "defaults for base"
    msaa = write_scene(tmp_path, "msaa", dict(TRIANGLE, samples=4))
    tolerance, source = conformance.scene_tolerance(softras.load_scene(msaa))
    assert tolerance["max_bad_fraction"] == 0.002 and source == "defaults for base, msaa"


# ---------------------------------------------------------------------------
# Verdicts on pictures (no GL)


def picture(seed=0, height=12, width=16):
    rng = np.random.default_rng(seed)
    out = rng.integers(0, 255, size=(height, width, 4), dtype=np.uint8)
    out[..., 3] = 255
    return out


def mask_of(pixels, shape=(12, 16)):
    where = np.zeros(shape, dtype=bool)
    for row, col in pixels:
        where[row, col] = True
    nothing = np.zeros(shape, dtype=bool)
    return ambiguity.Ambiguity(coverage=where, depth=nothing, sampling=nothing.copy())


def test_identical_pictures_pass():
    scene = softras.load_scene(TRIANGLE)
    verdict, reasons, figures, images = conformance.judge(scene, picture(), picture(), EXACT)
    assert verdict == PASS and reasons == ["identical to GL"]
    assert figures["max_diff"] == 0 and figures["flip_mean"] == 0.0
    assert set(images) == {"diff", "ssim", "flip", "where"}


def test_one_level_off_fails_with_tolerance_zero_and_warns_inside_the_mask():
    scene = softras.load_scene(TRIANGLE)
    gl = picture()
    soft = gl.copy()
    soft[4, 7, 0] = gl[4, 7, 0] + 1
    soft[5, 9, 1] = gl[5, 9, 1] + 1
    loose = {"threshold": 1, "max_bad_fraction": 0.0, "min_ssim": 0.99}
    assert conformance.judge(scene, soft, gl, loose)[0] == PASS
    verdict, reasons, figures, _ = conformance.judge(scene, soft, gl, EXACT)
    assert verdict == FAIL
    assert figures["bad_outside_mask"] == 2 and "x 7..9, y 4..5" in reasons[0]
    # Both pixels ambiguous: the strict tier fails, the excused one passes.
    verdict, reasons, figures, images = conformance.judge(scene, soft, gl, EXACT,
                                                          ambiguity=mask_of([(4, 7), (5, 9)]))
    assert verdict == WARN
    assert figures["bad_inside_mask"] == 2 and "all 2 are in the ambiguity mask (coverage 2)" in reasons[0]
    assert tuple(images["where"][4, 7, :3]) == (0, 220, 255)  # cyan: inside the mask
    # One of the two outside the mask: a failure again, and red there.
    verdict, _, figures, images = conformance.judge(scene, soft, gl, EXACT, ambiguity=mask_of([(4, 7)]))
    assert verdict == FAIL and figures["bad_outside_mask"] == 1
    assert tuple(images["where"][5, 9, :3]) == (255, 30, 30)


def test_stage_of_a_difference_from_primitive_ids():
    scene = softras.load_scene(COPLANAR)
    shape = (12, 16)
    soft_primitive = np.ones(shape, np.int64)
    gl_primitive = soft_primitive.copy()
    gl_primitive[2, 3] = 0      # GL shows the background: coverage
    gl_primitive[6, 8] = 3      # GL shows draw 2's triangle; both cover it alike: depth
    soft_primitive[9, 1] = 2    # same draw, other triangle: coverage (fill rule)
    soft_draw = np.where(soft_primitive > 2, 2, np.where(soft_primitive > 0, 1, 0))
    gl_draw = np.where(gl_primitive > 2, 2, np.where(gl_primitive > 0, 1, 0))
    last = np.full(shape, 3)
    gl_last = last.copy()
    gl_last[2, 3] = 0
    gl_last[9, 1] = 1
    pixels = np.zeros(shape, bool)
    for row, col in ((2, 3), (6, 8), (9, 1), (10, 10)):
        pixels[row, col] = True
    diff = np.full(shape, 9)
    lines = ambiguity.classify_differences(pixels, (soft_primitive, soft_draw), (gl_primitive, gl_draw), diff,
                                           scene, where="outside the ambiguity mask", soft_last=last,
                                           gl_last=gl_last)
    assert lines[0].startswith("coverage: 2 px outside the ambiguity mask differ")
    assert lines[1].startswith("depth: 1 px") and "x 8..8, y 6..6" in lines[1]
    assert lines[2].startswith("colour: 1 px") and "in draw 'first'" in lines[2] and "vertex colours" in lines[2]


# ---------------------------------------------------------------------------
# The ambiguity mask (softras only)


def test_id_picture_names_each_primitive():
    scene = softras.load_scene(COPLANAR)
    ids = ambiguity.id_scene(scene)
    primitive, draw = ambiguity.decode_ids(softras.render(ids), scene)
    assert set(np.unique(primitive[:, :10])) == {1, 2}   # the first quad wins the ties (x 6..10)
    assert set(np.unique(primitive[:, 10:])) == {3, 4}   # the second alone
    assert set(np.unique(draw[:, :10])) == {1} and set(np.unique(draw[:, 10:])) == {2}
    last, last_draw = ambiguity.decode_ids(softras.render(ambiguity.id_scene(scene, depth_test=False)), scene)
    assert set(np.unique(last_draw[:, 6:])) == {2}       # without depth test the second is on top
    assert set(np.unique(last[:, 11:])) <= {3, 4}


def test_coverage_mask_marks_samples_on_an_edge_and_nothing_else():
    # A vertical edge through the pixel centres of column 7 (x = 7.5): those
    # samples flip under a 1/256-pixel move; pixels a quarter pixel or more
    # from an edge never do.
    scene = softras.load_scene({
        "softras_scene": 1, "width": 16, "height": 12, "camera": PIXELS,
        "nodes": [{"name": "quad", "mesh": {"positions": [[2.25, 2.25, 0], [7.5, 2.25, 0], [7.5, 9.75, 0],
                                                          [2.25, 9.75, 0]],
                                            "indices": [[0, 1, 2], [0, 2, 3]]}}],
    })
    result = ambiguity.ambiguity_mask(scene)
    columns = np.unique(np.nonzero(result.coverage)[1])
    assert 7 in columns
    assert set(columns) <= {2, 7} or set(columns) <= {2, 7, 3}  # only near the quad's vertical edges
    assert not result.coverage[:, 10:].any() and not result.coverage[5, 4]
    assert not result.depth.any()


def test_depth_ties_are_ambiguous():
    scene = softras.load_scene(COPLANAR)
    result = ambiguity.ambiguity_mask(scene)
    assert result.depth[:, 6:10].all()              # the overlap: equal depth
    assert not result.depth[:, :6].any() and not result.depth[:, 10:].any()


def test_shifted_scene_moves_the_picture_by_whole_pixels_too():
    scene = softras.load_scene(TRIANGLE)
    moved = softras.render(ambiguity.shifted_scene(scene, 3.0, 0.0))
    assert np.array_equal(moved[:, 3:], softras.render(scene)[:, :-3])


# ---------------------------------------------------------------------------
# Whole scenes through both renderers


@pytest.mark.gl
def test_a_passing_scene(tmp_path):
    result = conformance.check_scene(write_scene(tmp_path, "triangle", TRIANGLE))
    assert result.verdict == PASS, result.reasons
    assert result.reasons == ["identical to GL"]
    assert result.figures["coverage_mismatch_pixels"] == 0
    assert set(result.images) == {"soft", "gl", "diff", "ssim", "flip", "where", "ambiguity"}


@pytest.mark.gl
def test_a_known_one_level_difference_fails_with_tolerance_zero():
    result = conformance.check_scene(KNOWN_1_LEVEL)
    assert result.verdict == PASS, result.reasons            # its own tolerance
    broken = conformance.check_scene(KNOWN_1_LEVEL, tolerance=EXACT)
    assert broken.verdict == FAIL
    assert broken.figures["max_diff"] == 1 and broken.figures["bad_outside_mask"] > 0
    # Coverage agrees; the shaded colours differ: the reason names the colour stage and the shading.
    assert broken.figures["coverage_mismatch_pixels"] == 0
    stages = [reason.split(":")[0] for reason in broken.reasons[1:]]
    assert stages and set(stages) == {"colour"}
    assert any("phong shading" in reason for reason in broken.reasons[1:])


@pytest.mark.gl
def test_a_broken_rasterizer_fails_in_the_coverage_stage(tmp_path):
    path = write_scene(tmp_path, "triangle", TRIANGLE)

    def broken(scene):
        """softras with the second vertex of every draw moved 1.9 pixels up."""
        draws = []
        for draw in scene.draws:
            positions = draw.mesh.positions.copy()
            positions[1, 1] += 1.9
            draws.append(dataclasses.replace(draw, mesh=dataclasses.replace(draw.mesh, positions=positions)))
        return softras.render(dataclasses.replace(scene, draws=tuple(draws)))

    result = conformance.check_scene(path, render_soft=broken)
    assert result.verdict == FAIL
    assert any(reason.startswith("coverage:") for reason in result.reasons), result.reasons


@pytest.mark.gl
def test_an_error_is_a_failure_with_its_reason(tmp_path):
    def crash(scene):
        raise NotImplementedError("no such feature")

    result = conformance.check_scene(write_scene(tmp_path, "triangle", TRIANGLE), render_soft=crash)
    assert result.verdict == FAIL and "softras cannot render the scene: no such feature" in result.reasons[0]


@pytest.mark.gl
def test_parallel_run_in_spawned_processes_matches_serial(tmp_path):
    paths = [write_scene(tmp_path, "a_triangle", TRIANGLE), write_scene(tmp_path, "b_coplanar", COPLANAR),
             write_scene(tmp_path, "c_exact", dict(TRIANGLE, tolerance={"threshold": 0}))]
    seen = []
    parallel = conformance.run(paths, jobs=2, on_result=seen.append)
    serial = conformance.run(paths, jobs=1)
    assert [r.name for r in parallel] == ["a_triangle", "b_coplanar", "c_exact"]  # scene order
    assert sorted(r.name for r in seen) == ["a_triangle", "b_coplanar", "c_exact"]
    assert [r.verdict for r in parallel] == [r.verdict for r in serial] == [PASS, PASS, PASS]
    for p, s in zip(parallel, serial):
        assert np.array_equal(p.images["gl"], s.images["gl"])  # each worker had a working GL context


# ---------------------------------------------------------------------------
# The command and its report


@pytest.mark.gl
def test_cli_report_pass_and_fail(tmp_path, capsys):
    folder = tmp_path / "scenes"
    folder.mkdir()
    write_scene(folder, "triangle", TRIANGLE)
    known = json.loads(KNOWN_1_LEVEL.read_text())
    known["tolerance"] = {"threshold": 0, "max_bad_fraction": 0, "min_ssim": 0.99}
    for texture in known.get("textures", {}).values():      # the copy lives elsewhere
        if "image" in texture:
            texture["image"] = str(KNOWN_1_LEVEL.parent / texture["image"])
    write_scene(folder, "zz_lit_exact", known)
    report = tmp_path / "report"

    assert main(["conformance", str(folder), "--report", str(report)]) == 1
    captured = capsys.readouterr()
    assert "1 pass, 0 quality warning, 1 fail, 0 not supported in" in captured.out
    assert "[2/2]" in captured.err                        # progress (not a terminal: one line each)

    data = json.loads((report / "results.json").read_text())
    assert data["summary"]["pass"] == 1 and data["summary"]["fail"] == 1 and data["summary"]["seconds"] > 0
    verdicts = {scene["name"]: scene["verdict"] for scene in data["scenes"]}
    assert verdicts == {"triangle": PASS, "zz_lit_exact": FAIL}
    for scene in data["scenes"]:
        for image in scene["images"].values():
            assert (report / image).is_file()

    suite = ElementTree.parse(report / "junit.xml").getroot()
    assert suite.tag == "testsuite" and suite.get("tests") == "2" and suite.get("failures") == "1"
    failed = [case.get("name") for case in suite.iter("testcase") if case.find("failure") is not None]
    assert failed == ["zz_lit_exact"]

    page = (report / "index.html").read_text()
    assert "1 of 2 scenes FAILED" in page
    assert page.index('id="zz_lit_exact"') < page.index('id="triangle"')  # failures first
    assert "colour:" in page and "zz_lit_exact/where.png" in page

    # -k keeps only the passing scene: exit 0.
    assert main(["conformance", str(folder), "-k", "tri*"]) == 0


def test_cli_bad_input_is_status_2_and_writes_nothing(tmp_path, capsys):
    folder = tmp_path / "scenes"
    folder.mkdir()
    write_scene(folder, "triangle", TRIANGLE)
    report = tmp_path / "report"
    cases = [
        [str(folder / "missing.json")],
        [str(folder), "-k", "nothing"],
        [str(folder), "--shard", "3/2"],
        [str(folder), "-j", "0"],
    ]
    for args in cases:
        assert main(["conformance", *args, "--report", str(report)]) == 2, args
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and err[0].startswith("softras: error: "), err
    (folder / "bad.json").write_text('{"softras_scene": 1, "width": 0}')
    assert main(["conformance", str(folder), "--report", str(report)]) == 2
    assert "bad.json" in capsys.readouterr().err
    assert not report.exists()


def test_report_files_parse_without_gl(tmp_path):
    results = [
        conformance.SceneResult(name="good", path="good.json", verdict=PASS, reasons=["identical to GL"],
                                figures={"ssim": 1.0, "max_diff": 0}),
        conformance.SceneResult(name="bad", path="bad.json", verdict=FAIL, reasons=["error: <boom> & more"]),
        conformance.SceneResult(name="meh", path="meh.json", verdict=WARN, reasons=["ambiguous"]),
    ]
    from softras.verification.report import write_report

    index = write_report(tmp_path, results, {"seconds": 1.5, "jobs": 1, "gl_renderer": "test"})
    page = index.read_text()
    assert page.index('id="bad"') < page.index('id="meh"') < page.index('id="good"')
    assert "&lt;boom&gt; &amp; more" in page                  # escaped
    suite = ElementTree.parse(tmp_path / "junit.xml").getroot()
    assert [c.get("name") for c in suite.iter("testcase")] == ["good", "bad", "meh"]
    warn = [c for c in suite.iter("testcase") if c.get("name") == "meh"][0]
    assert warn.find("failure") is None
    assert warn.find("properties/property").get("value") == "quality_warning"
    assert json.loads((tmp_path / "results.json").read_text())["summary"] == {
        "pass": 1, "quality_warning": 1, "fail": 1, "not_supported": 0, "crash": 0, "timeout": 0, "flaky": 0,
        "total": 3, "seconds": 1.5}
