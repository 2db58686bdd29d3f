"""Tests for golden images (softras.verification.golden) and ``softras golden``.

Scenes are tiny dicts written to tmp_path as JSON; every golden folder lives
under tmp_path except in the last test, which verifies the repository's own
golden/ (it passes once ``softras golden --update`` has been run and
committed). Tests that render with glref carry the ``gl`` marker.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import glref
from softras.verification import golden
from softras.cli import main
from softras.scene.imageio import read_png

from conftest import REPO, SCENES, write_failure_images

# Two tiny scenes in pixel units (orthographic, 1 unit = 1 pixel).
TRIANGLE = {
    "softras_scene": 1,
    "width": 16, "height": 12,
    "background": [0, 0, 0, 1],
    "camera": {"projection": "orthographic", "left": 0, "right": 16, "bottom": 0, "top": 12,
               "near": -1, "far": 1},
    "nodes": [{
        "name": "triangle",
        "mesh": {"positions": [[1.3, 1.2, 0], [14.6, 2.1, 0], [6.2, 10.7, 0]],
                 "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]]},
    }],
}
QUADS = {
    "softras_scene": 1,
    "width": 12, "height": 10,
    "background": [0.2, 0.2, 0.2, 1],
    "camera": {"projection": "orthographic", "left": 0, "right": 12, "bottom": 0, "top": 10,
               "near": -1, "far": 1},
    "nodes": [
        {"name": "left", "mesh": {"positions": [[1, 1, 0], [6, 1, 0], [6, 9, 0], [1, 9, 0]],
                                  "indices": [[0, 1, 2], [0, 2, 3]], "colors": [[1, 1, 0]] * 4}},
        {"name": "right", "mesh": {"positions": [[6, 1, 0], [11, 1, 0], [11, 9, 0], [6, 9, 0]],
                                   "indices": [[0, 1, 2], [0, 2, 3]], "colors": [[0, 1, 1]] * 4}},
    ],
}


def write_scene(folder: Path, name: str, data: dict) -> Path:
    path = folder / f"{name}.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


@pytest.fixture
def scenes(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    return [write_scene(folder, "triangle", TRIANGLE), write_scene(folder, "quads", QUADS)]


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def flip_pixel(png: Path, row: int = 3, col: int = 5) -> None:
    pixels = read_png(png).copy()
    pixels[row, col, 0] ^= 0x01
    Image.fromarray(pixels).save(png)  # not through update: the manifest keeps the old hash


def by_name(results) -> dict:
    return {Path(r.golden).stem: r for r in results}


# ---------------------------------------------------------------------------
# Without GL


def test_golden_path_is_scene_stem_png_in_golden_of_the_current_directory():
    assert golden.golden_path("scenes/fill_rule_grid.json") == Path("golden") / "fill_rule_grid.png"
    assert golden.golden_path("/x/y/a.json", "/g") == Path("/g/a.png")
    assert golden.SCENES_DIR == Path("scenes") and golden.GOLDEN_DIR == Path("golden")


def test_pixel_hash_is_of_decoded_pixels_not_png_bytes(tmp_path):
    rng = np.random.default_rng(1)
    pixels = rng.integers(0, 256, size=(9, 7, 4), dtype=np.uint8)
    Image.fromarray(pixels).save(tmp_path / "a.png", compress_level=0)
    Image.fromarray(pixels).save(tmp_path / "b.png", compress_level=9)
    assert (tmp_path / "a.png").read_bytes() != (tmp_path / "b.png").read_bytes()
    assert golden.pixel_hash(read_png(tmp_path / "a.png")) == golden.pixel_hash(read_png(tmp_path / "b.png"))
    assert golden.pixel_hash(read_png(tmp_path / "a.png")) == golden.pixel_hash(pixels)
    changed = pixels.copy()
    changed[8, 6, 3] ^= 1
    assert golden.pixel_hash(changed) != golden.pixel_hash(pixels)


def test_provenance_parses_mesa_and_llvm_versions():
    info = {"GL_RENDERER": "llvmpipe (LLVM 15.0.6, 256 bits)", "GL_VERSION": "4.5 (Core Profile) Mesa 22.3.6",
            "GL_VENDOR": "Mesa/X.org", "moderngl": "5.13.0"}
    prov = golden.provenance(info)
    assert prov["mesa"] == "22.3.6" and prov["llvm"] == "15.0.6"
    assert prov["GL_RENDERER"] == info["GL_RENDERER"] and prov["moderngl"] == "5.13.0"
    assert prov["cpu"] and prov["python"] and prov["date"].endswith("+00:00")
    other = golden.provenance({"GL_RENDERER": "NVIDIA H100/PCIe/SSE2", "GL_VERSION": "4.5.0 NVIDIA 550.54",
                               "GL_VENDOR": "NVIDIA Corporation"})
    assert other["mesa"] is None and other["llvm"] is None


def test_cli_bad_input_is_one_line_status_2(tmp_path, capsys):
    assert main(["golden", str(tmp_path / "missing.json")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("softras: error: ") and "missing.json" in err[0]

    bad = tmp_path / "bad.json"
    bad.write_text('{"softras_scene": 1, "width": 0}', encoding="utf-8")
    assert main(["golden", "--update", "--golden-dir", str(tmp_path / "g"), str(bad)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("softras: error: ")
    assert not (tmp_path / "g").exists()


# ---------------------------------------------------------------------------
# With GL


@pytest.mark.gl
def test_update_then_verify_passes(scenes, tmp_path):
    golden_dir = tmp_path / "golden"
    changes = golden.update(scenes, golden_dir)
    assert [(c.name, c.status) for c in changes] == [("triangle.png", "added"), ("quads.png", "added")]
    assert sorted(p.name for p in golden_dir.iterdir()) == ["manifest.json", "quads.png", "triangle.png"]

    manifest = json.loads((golden_dir / "manifest.json").read_text())
    for key in ("GL_RENDERER", "GL_VERSION", "GL_VENDOR", "mesa", "llvm", "cpu", "moderngl", "python", "date",
                "capabilities"):
        assert key in manifest["provenance"]
    assert manifest["provenance"]["capabilities"]["subpixel_bits"] == glref.info()["subpixel_bits"]
    entry = manifest["images"]["triangle.png"]
    assert (entry["scene"], entry["width"], entry["height"]) == ("triangle.json", 16, 12)
    assert entry["sha256"] == golden.pixel_hash(read_png(golden_dir / "triangle.png"))

    results = golden.verify(scenes, golden_dir)
    assert all(r.passed for r in results), [r.line() for r in results]
    assert all(r.hash_ok and r.gl_diff_pixels == 0 and r.soft.passed for r in results)

    # Updating again changes nothing, not even a byte of the manifest.
    before = snapshot(golden_dir)
    changes = golden.update(scenes, golden_dir)
    assert {c.status for c in changes} == {"unchanged"}
    assert snapshot(golden_dir) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["golden", "scenes"]  # no temporary folders left


@pytest.mark.gl
def test_one_flipped_golden_pixel_fails(scenes, tmp_path):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    flip_pixel(golden_dir / "triangle.png")
    results = by_name(golden.verify(scenes, golden_dir))
    bad = results["triangle"]
    assert not bad.passed
    assert bad.hash_ok is False and bad.gl_diff_pixels == 1
    assert any("sha256" in message for message in bad.failures)
    assert results["quads"].passed


@pytest.mark.gl
def test_edited_manifest_hash_fails(scenes, tmp_path):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    path = golden_dir / "manifest.json"
    manifest = json.loads(path.read_text())
    digest = manifest["images"]["quads.png"]["sha256"]
    manifest["images"]["quads.png"]["sha256"] = ("0" if digest[0] != "0" else "1") + digest[1:]
    path.write_text(json.dumps(manifest))
    results = by_name(golden.verify(scenes, golden_dir))
    assert not results["quads"].passed and results["quads"].hash_ok is False
    assert results["quads"].gl_diff_pixels == 0
    assert results["triangle"].passed


@pytest.mark.gl
def test_a_changed_render_is_caught(scenes, tmp_path):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    moved = copy.deepcopy(TRIANGLE)
    moved["nodes"][0]["mesh"]["positions"][1] = [14.6, 3.4, 0]  # one vertex moves 1.3 pixels up
    write_scene(scenes[0].parent, "triangle", moved)

    results = by_name(golden.verify(scenes, golden_dir))
    bad = results["triangle"]
    assert not bad.passed
    assert bad.hash_ok is True and bad.gl_diff_pixels > 0
    assert any("glref no longer reproduces" in message for message in bad.failures)
    assert results["quads"].passed

    changes = {c.name: c for c in golden.update(scenes, golden_dir)}
    assert changes["triangle.png"].status == "changed"
    assert changes["triangle.png"].diff_pixels == bad.gl_diff_pixels
    assert changes["quads.png"].status == "unchanged"
    assert all(r.passed for r in golden.verify(scenes, golden_dir))


@pytest.mark.gl
def test_interrupted_update_leaves_golden_as_it_was(scenes, tmp_path, monkeypatch):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    before = snapshot(golden_dir)

    # Both scenes change, and rendering the second one fails.
    moved = copy.deepcopy(TRIANGLE)
    moved["background"] = [0, 0, 1, 1]
    write_scene(scenes[0].parent, "triangle", moved)
    recoloured = copy.deepcopy(QUADS)
    recoloured["background"] = [1, 1, 1, 1]
    write_scene(scenes[0].parent, "quads", recoloured)
    real = golden._render_gl
    calls = []

    def flaky(scene):
        calls.append(scene)
        if len(calls) == 2:
            raise RuntimeError("renderer died")
        return real(scene)

    monkeypatch.setattr(golden, "_render_gl", flaky)
    with pytest.raises(RuntimeError, match="renderer died"):
        golden.update(scenes, golden_dir, prune=True)
    assert len(calls) == 2
    assert snapshot(golden_dir) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["golden", "scenes"]


@pytest.mark.gl
def test_swap_without_atomic_exchange(scenes, tmp_path, monkeypatch):
    golden_dir = tmp_path / "golden"
    golden.update(scenes[:1], golden_dir)
    monkeypatch.setattr(golden, "_exchange", lambda a, b: False)
    changes = golden.update(scenes, golden_dir)
    assert [c.status for c in changes] == ["unchanged", "added"]
    assert all(r.passed for r in golden.verify(scenes, golden_dir))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["golden", "scenes"]


@pytest.mark.gl
def test_subset_update_keeps_other_images_and_full_update_prunes(scenes, tmp_path):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    quads_bytes = (golden_dir / "quads.png").read_bytes()
    quads_entry = json.loads((golden_dir / "manifest.json").read_text())["images"]["quads.png"]

    moved = copy.deepcopy(TRIANGLE)
    moved["background"] = [0, 0.5, 0, 1]
    write_scene(scenes[0].parent, "triangle", moved)
    changes = golden.update(scenes[:1], golden_dir)
    assert [(c.name, c.status) for c in changes] == [("triangle.png", "changed")]
    assert (golden_dir / "quads.png").read_bytes() == quads_bytes
    assert json.loads((golden_dir / "manifest.json").read_text())["images"]["quads.png"] == quads_entry
    assert all(r.passed for r in golden.verify(scenes, golden_dir))

    # A full update with the quads scene gone removes its image and entry.
    changes = golden.update(scenes[:1], golden_dir, prune=True)
    assert [(c.name, c.status) for c in changes] == [("triangle.png", "unchanged"), ("quads.png", "removed")]
    assert sorted(p.name for p in golden_dir.iterdir()) == ["manifest.json", "triangle.png"]
    assert list(json.loads((golden_dir / "manifest.json").read_text())["images"]) == ["triangle.png"]


@pytest.mark.gl
def test_missing_golden_image_is_a_clear_failure(scenes, tmp_path):
    results = golden.verify(scenes, tmp_path / "nothing-here")
    assert [r.passed for r in results] == [False, False]
    assert all(r.failures == [golden.NO_GOLDEN] for r in results)
    assert "softras golden --update" in results[0].line()


@pytest.mark.gl
def test_cli_update_and_verify(scenes, tmp_path, capsys):
    golden_dir = str(tmp_path / "golden")
    paths = [str(p) for p in scenes]
    assert main(["golden", "--update", "--golden-dir", golden_dir, *paths]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("added") and "triangle.png" in out[0]
    assert out[-1].startswith("golden update") and "2 added" in out[-1] and " s" in out[-1]

    assert main(["golden", "--golden-dir", golden_dir, *paths]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 3 and out[0].startswith("PASS  triangle") and "2 passed, 0 failed" in out[-1]

    flip_pixel(tmp_path / "golden" / "quads.png")
    report = tmp_path / "report"
    assert main(["golden", "--golden-dir", golden_dir, "--out-dir", str(report), *paths]) == 1
    out = capsys.readouterr().out
    assert "FAIL  quads" in out and "1 failed" in out
    assert sorted(p.name for p in (report / "quads").iterdir()) == [
        "diff_gl.png", "diff_soft.png", "gl.png", "golden.png", "soft.png"]

    # A folder as PATH means its scene files.
    assert main(["golden", "--update", "--golden-dir", golden_dir, str(scenes[0].parent)]) == 0
    assert "1 changed, 1 unchanged" in capsys.readouterr().out


@pytest.mark.gl
def test_repository_golden_images_verify(tmp_path):
    """The committed golden/ matches glref and softras for every scene in scenes/."""
    paths = golden.default_scenes(SCENES)
    if not paths:
        pytest.skip("no scenes in scenes/")
    results = golden.verify(paths, REPO / "golden", orphans=True, keep_images=True)
    failed = [r for r in results if not r.passed]
    for result in failed:
        if result.images:
            write_failure_images(tmp_path / Path(result.golden).stem, **result.images)
    assert not failed, "\n".join(r.line() for r in failed) + f"\nimages under {tmp_path}"


@pytest.mark.gl
def test_one_pixel_change_in_the_gl_render_is_caught(scenes, tmp_path, monkeypatch):
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    real = golden._render_gl

    def one_pixel_off(scene):
        image = real(scene).copy()
        image[0, 0, 2] ^= 0x01
        return image

    monkeypatch.setattr(golden, "_render_gl", one_pixel_off)
    results = by_name(golden.verify(scenes, golden_dir))
    for result in results.values():
        assert not result.passed and result.hash_ok is True and result.gl_diff_pixels == 1
        assert any("1 pixel differ" in message for message in result.failures)


@pytest.mark.gl
@pytest.mark.parametrize("where", ["manifest", "swap"])
def test_update_interrupted_late_leaves_golden_as_it_was(scenes, tmp_path, monkeypatch, where):
    """Interrupted (Ctrl-C) after every image is rendered: writing the manifest, or the swap itself."""
    golden_dir = tmp_path / "golden"
    golden.update(scenes, golden_dir)
    before = snapshot(golden_dir)
    recoloured = copy.deepcopy(QUADS)
    recoloured["background"] = [1, 1, 1, 1]
    write_scene(scenes[0].parent, "quads", recoloured)

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    if where == "manifest":
        monkeypatch.setattr(golden, "_manifest_text", interrupt)
    else:
        # No atomic exchange: the old folder is renamed aside, then the new one
        # into place -- which is interrupted; the old folder must come back.
        monkeypatch.setattr(golden, "_exchange", lambda a, b: False)
        real_rename = golden.os.rename
        interrupted = []

        def rename(src, dst):
            if Path(dst) == golden_dir and Path(src).name.startswith(".golden.new-") and not interrupted:
                interrupted.append(src)
                raise KeyboardInterrupt
            return real_rename(src, dst)

        monkeypatch.setattr(golden.os, "rename", rename)
    with pytest.raises(KeyboardInterrupt):
        golden.update(scenes, golden_dir, prune=True)
    monkeypatch.undo()
    if where == "swap":
        assert interrupted  # the interruption hit the rename of the new folder into place
    assert snapshot(golden_dir) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["golden", "scenes"]


def test_pytest_update_golden_option_runs_softras_golden_update(monkeypatch, capsys):
    """``pytest --update-golden`` (tests/conftest.py) calls the code of ``softras golden --update``."""
    import conftest

    calls = []

    def update(paths, golden_dir=None, *, prune=False, on_change=None):
        calls.append((Path.cwd(), list(paths), Path(golden_dir), prune))
        return []

    monkeypatch.setattr(golden, "update", update)

    class Config:
        def __init__(self, value):
            self.value = value

        def getoption(self, name, default=None):
            assert name == "--update-golden"
            return self.value

    class Session:
        def __init__(self, value):
            self.config = Config(value)

    conftest.pytest_sessionstart(Session(False))
    assert calls == []
    conftest.pytest_sessionstart(Session(True))
    # In the repository's root, wherever pytest runs: its ./scenes and ./golden.
    assert [(cwd, golden_dir, prune) for cwd, _, golden_dir, prune in calls] == [(REPO, Path("golden"), True)]
    assert [REPO / path for path in calls[0][1]] == golden.default_scenes(SCENES)
    assert "golden update" in capsys.readouterr().out
