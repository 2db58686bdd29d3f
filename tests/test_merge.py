"""``softras conformance --merge DIR... --report OUT``: shard reports merged into one.

The tests without GL build shard reports from synthetic SceneResults
(softras.verification.report.write_report, with the meta a sharded run
writes); the ``gl`` test runs a few cheap scenes of scenes/ unsharded and as
4 shards and checks that the merge of the shards is the unsharded report.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

from softras.cli import main
from softras.verification.conformance import FAIL, PASS, WARN, SceneResult, shard
from softras.verification.report import FORMAT, write_report

LLVMPIPE = "llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6"
SOFTPIPE = "softpipe, OpenGL 3.3 (Core Profile) Mesa 22.3.6"
NAMES = ["alpha", "bravo", "charlie", "delta", "echo", "foxtrot", "golf"]
# A few cheap scenes of scenes/ (each well under a second warm).
CHEAP = ["culling_back", "culling_front", "extreme_1x1", "fill_rule_grid", "orthographic_camera"]


def synthetic_result(name: str, verdict: str = PASS) -> SceneResult:
    picture = np.zeros((6, 8, 4), np.uint8)
    picture[..., 3] = 255
    picture[1:4, 2:6, 0] = 40 + 10 * NAMES.index(name) if name in NAMES else 200
    return SceneResult(name=name, path=f"scenes/{name}.json", verdict=verdict,
                       reasons=[] if verdict == PASS else [f"{verdict}: colour differs at (2, 1)"],
                       figures={"ssim": 1.0, "max_diff": 0}, seconds=0.25,
                       images={"soft": picture, "gl": picture, "diff": picture})


def write_shard(folder: Path, index: int, count: int, *, names=NAMES, gl=LLVMPIPE, verdicts=None, part=None,
                **meta) -> Path:
    """The report ``softras conformance --shard index/count`` would write for scenes ``names`` (or just
    the scenes ``part``)."""
    verdicts = verdicts or {}
    if part is None:
        part = [path.stem for path in shard([Path(f"{name}.json") for name in names], index, count)]
    results = [synthetic_result(name, verdicts.get(name, PASS)) for name in part]
    run = {"seconds": 1.0 + index, "jobs": 1, "gl_renderer": gl, "profile": "auto: strict",
           "gl": {"GL_RENDERER": gl.split(",")[0]}, "shard": f"{index}/{count}", "patterns": [],
           "paths": [result.path for result in results], "date": "2024-05-01T12:00:00+00:00",
           "options": {"scenes": [], "profile": "auto", "timeout": 300.0, "retries": 0, "max_memory": 1},
           "complete": True, "interrupted": False, "pending": []}
    write_report(folder, results, run | meta)
    return folder


def write_shards(root: Path, count: int = 4, **options) -> list[Path]:
    return [write_shard(root / f"shard-{index}", index, count, **options) for index in range(1, count + 1)]


def snapshot(folder: Path) -> dict:
    return {str(path.relative_to(folder)): path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


def merge_cli(shards, out: Path, *extra) -> int:
    return main(["conformance", "--merge", *map(str, shards), "--report", str(out), *extra])


def listed_images(page: str) -> list[str]:
    return re.findall(r'<img src="([^"]+)"', page)


# ---------------------------------------------------------------------------
# Without GL: synthetic shards


def test_merged_report_is_every_scene_of_the_shards_with_its_pictures(tmp_path, capsys):
    shards = write_shards(tmp_path)
    out = tmp_path / "merged"
    assert merge_cli(reversed(shards), out) == 0
    data = json.loads((out / "results.json").read_text())
    assert data["softras_conformance"] == FORMAT
    assert [scene["name"] for scene in data["scenes"]] == NAMES            # sorted, as an unsharded run
    assert data["summary"]["total"] == len(NAMES) and data["summary"]["pass"] == len(NAMES)
    assert data["summary"]["seconds"] == pytest.approx(2 + 3 + 4 + 5)     # the shards' times added up
    assert data["shard"] is None and "options" not in data                # not resumable
    assert [item["shard"] for item in data["merged"]["reports"]] == ["1/4", "2/4", "3/4", "4/4"]
    assert {item["gl_renderer"] for item in data["merged"]["reports"]} == {LLVMPIPE}
    suite = ElementTree.parse(out / "junit.xml").getroot()
    assert sorted(case.get("name") for case in suite.iter("testcase")) == NAMES
    page = (out / "index.html").read_text()
    images = listed_images(page)
    assert len(images) == 3 * len(NAMES)
    for name in NAMES:
        assert f'id="{name}"' in page
    for relative in images:
        assert (out / relative).is_file(), relative
    # Byte for byte the shard's picture.
    assert (out / "bravo" / "gl.png").read_bytes() == (tmp_path / "shard-2" / "bravo" / "gl.png").read_bytes()
    assert "merged from 4 reports" in page
    assert (out / "failures.csv").read_text().count("\n") == 1           # the header only
    assert "7 scenes: 7 pass" in capsys.readouterr().out


def test_merged_exit_status_follows_the_merged_verdicts(tmp_path, capsys):
    shards = write_shards(tmp_path / "warn", verdicts={"delta": WARN})
    assert merge_cli(shards, tmp_path / "out-warn") == 0
    shards = write_shards(tmp_path / "fail", verdicts={"delta": FAIL, "golf": WARN})
    assert merge_cli(shards, tmp_path / "out-fail") == 1
    out = capsys.readouterr().out
    assert "FAIL            delta" in out
    data = json.loads((tmp_path / "out-fail" / "results.json").read_text())
    assert data["summary"]["fail"] == 1 and data["summary"]["quality_warning"] == 1
    assert "delta,FAIL" in (tmp_path / "out-fail" / "failures.csv").read_text()
    # With the baseline that lists the failure, the merge matches it: 0.
    baseline = tmp_path / "baseline.csv"
    baseline.write_text("delta,FAIL\ngolf,QUALITY_WARNING\n")
    assert merge_cli(shards, tmp_path / "out-base", "--baseline", str(baseline)) == 0
    assert json.loads((tmp_path / "out-base" / "results.json").read_text())["baseline"]["matches"] is True


def test_unsharded_reports_of_different_scenes_merge(tmp_path):
    first = tmp_path / "a"
    second = tmp_path / "b"
    meta = {"seconds": 1.0, "gl_renderer": LLVMPIPE, "profile": "auto: strict", "patterns": [], "complete": True}
    write_report(first, [synthetic_result("alpha")], meta)
    write_report(second, [synthetic_result("bravo", FAIL)], meta)
    assert merge_cli([first, second], tmp_path / "out") == 1
    names = [scene["name"] for scene in json.loads((tmp_path / "out" / "results.json").read_text())["scenes"]]
    assert names == ["alpha", "bravo"]


def _bad_inputs(tmp_path: Path) -> dict:
    """name -> (the folders to merge, a fragment of the one-line error)."""
    good = write_shards(tmp_path / "good")
    cases = {"missing folder": ([*good[:3], tmp_path / "nowhere"], "no such folder")}
    empty = tmp_path / "empty"
    empty.mkdir()
    cases["not a report"] = ([*good[:3], empty], "no results.json")
    other = tmp_path / "other-json"
    other.mkdir()
    (other / "results.json").write_text('{"softras_golden": 1}')
    cases["a results.json of something else"] = ([*good[:3], other], "not a softras conformance report")
    broken = tmp_path / "broken-json"
    broken.mkdir()
    (broken / "results.json").write_text('{"softras_conformance": 2, "scenes": [')
    cases["broken json"] = ([*good[:3], broken], "cannot read results.json")
    old = write_shard(tmp_path / "old-format", 4, 4)
    data = json.loads((old / "results.json").read_text())
    (old / "results.json").write_text(json.dumps(data | {"softras_conformance": 1}))
    cases["format version"] = ([*good[:3], old], "format version 1")
    cases["shard missing"] = (good[:3], "shard 4/4 missing")
    cases["a folder twice"] = ([*good, good[0]], "given twice")
    twice = write_shard(tmp_path / "twice", 4, 4, names=NAMES + ["aardvark"])
    cases["same scene in two shards"] = ([*good[:3], twice], "is in both")
    cases["shards of different N"] = ([*good[:3], write_shard(tmp_path / "n5", 4, 5)], "different N")
    cases["same shard twice"] = ([*good, write_shard(tmp_path / "dup", 2, 4, names=["zulu"])],
                                 "are both shard 2/4")
    cases["different GL"] = ([*good[:3], write_shard(tmp_path / "softpipe", 4, 4, gl=SOFTPIPE)], "GL renderer")
    cases["different profile"] = ([*good[:3], write_shard(tmp_path / "spec", 4, 4, profile="spec")],
                                  "--profile")
    cases["different -k"] = ([*good[:3], write_shard(tmp_path / "k", 4, 4, patterns=["a"])], "-k")
    cases["incomplete"] = ([*good[:3], write_shard(tmp_path / "stopped", 4, 4, complete=False,
                                                   pending=["scenes/x.json"])], "incomplete run")
    lost = write_shard(tmp_path / "lost", 4, 4)
    (lost / "delta" / "gl.png").unlink()
    cases["a picture missing"] = ([*good[:3], lost], "delta/gl.png is missing")
    # Shard 4 of 7 scenes is the 4th name; "bz" would be the 3rd of these.
    moved = write_shard(tmp_path / "other-scenes", 4, 4, part=["bz"])
    cases["another scene set"] = ([*good[:3], moved], "different scene sets")
    plain = tmp_path / "plain"
    write_report(plain, [synthetic_result("zulu")], {"gl_renderer": LLVMPIPE, "profile": "auto: strict",
                                                     "patterns": [], "complete": True})
    cases["unsharded among shards"] = ([*good, plain], "is not a shard")
    return cases


def test_bad_input_is_one_line_status_2_and_leaves_the_output_alone(tmp_path, capsys):
    cases = _bad_inputs(tmp_path)
    fresh = tmp_path / "fresh-out"
    used = tmp_path / "used-out"
    write_report(used, [synthetic_result("yankee")], {"gl_renderer": "an earlier report"})
    before = snapshot(used)
    for name, (folders, fragment) in cases.items():
        for out in (fresh, used):
            assert merge_cli(folders, out) == 2, name
            err = capsys.readouterr().err.splitlines()
            assert len(err) == 1 and err[0].startswith("softras: error: "), (name, err)
            assert fragment in err[0], (name, err[0])
            assert not fresh.exists(), name
            assert snapshot(used) == before, name


def test_merge_takes_no_run_options_and_needs_report(tmp_path, capsys):
    shards = write_shards(tmp_path)
    merging = ["--merge", *map(str, shards), "--report", str(tmp_path / "out")]
    for args in (merging + ["-k", "alpha"], merging + ["--shard", "1/2"], merging + ["-j", "2"],
                 merging + ["--resume", str(shards[0])], merging + ["--profile", "spec"], merging + ["--timeout", "10"],
                 merging + ["--retries", "1"], merging + ["--max-memory", "8G"], [str(tmp_path)] + merging):
        assert main(["conformance", *args]) == 2, args
        assert capsys.readouterr().err.startswith("softras: error: --merge combines finished reports"), args
    assert main(["conformance", "--merge", *map(str, shards)]) == 2
    assert "needs --report" in capsys.readouterr().err
    assert merge_cli(shards, shards[1]) == 2
    assert "is one of the reports being merged" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_merged_report_cannot_be_resumed(tmp_path, capsys):
    shards = write_shards(tmp_path)
    assert merge_cli(shards, tmp_path / "out") == 0
    assert main(["conformance", "--resume", str(tmp_path / "out")]) == 2
    assert "not a resumable run" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# With GL: 4 shards of a real run against the unsharded run


def _without_times(data: dict) -> list[dict]:
    scenes = []
    for scene in data["scenes"]:
        scene = dict(scene)
        scene.pop("seconds")
        scene["figures"] = {key: value for key, value in scene["figures"].items() if not key.endswith("_seconds")}
        scenes.append(scene)
    return scenes


@pytest.mark.gl
def test_four_shards_merged_equal_the_unsharded_run(tmp_path, capsys):
    selection = [arg for name in CHEAP for arg in ("-k", name)]
    whole = tmp_path / "whole"
    assert main(["conformance", *selection, "--report", str(whole)]) == 0
    shards = []
    for index in range(1, 5):
        shards.append(tmp_path / f"shard-{index}")
        assert main(["conformance", *selection, "--shard", f"{index}/4", "--report", str(shards[-1])]) == 0
    merged = tmp_path / "merged"
    assert merge_cli(shards, merged) == 0
    capsys.readouterr()

    expected = json.loads((whole / "results.json").read_text())
    got = json.loads((merged / "results.json").read_text())
    assert [scene["name"] for scene in got["scenes"]] == [scene["name"] for scene in expected["scenes"]]
    assert len(got["scenes"]) == len(CHEAP)
    assert _without_times(got) == _without_times(expected)                   # verdicts, reasons, figures
    assert {key: value for key, value in got["summary"].items() if key != "seconds"} == \
        {key: value for key, value in expected["summary"].items() if key != "seconds"}
    assert got["gl_renderer"] == expected["gl_renderer"] and got["profile"] == expected["profile"]

    def cases(folder):
        suite = ElementTree.parse(folder / "junit.xml").getroot()
        return {case.get("name"): (case.get("classname"), [child.tag for child in case],
                                   case.find("properties/property").get("value"))
                for case in suite.iter("testcase")}
    assert cases(merged) == cases(whole)

    page = (merged / "index.html").read_text()
    images = listed_images(page)
    assert sorted(images) == sorted(listed_images((whole / "index.html").read_text()))
    for name in CHEAP:
        assert f'id="{name}"' in page and f'src="{name}/soft.png"' in page
    for relative in images:
        assert (merged / relative).is_file(), relative
        assert (merged / relative).read_bytes() == (whole / relative).read_bytes(), relative
