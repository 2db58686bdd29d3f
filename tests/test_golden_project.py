"""A user's project, not ours: ``softras golden`` and ``softras conformance``
resolve their default folders from the current directory, never from where
softras is installed.

Each test works in a tmp folder with a scene of its own (``monkeypatch.chdir``)
and checks that this checkout's ``golden/`` is left exactly as it was (bytes
and modification times).  An update that changes nothing writes nothing: no
byte, no modification time, not even a temporary folder beside ``golden/``.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from softras.cli import main
from softras.verification import golden

from conftest import REPO
from test_golden import TRIANGLE  # the same tiny scene in pixel units


def state(folder: Path) -> dict:
    """Every entry under ``folder`` (and the folder itself): bytes and mtime in ns."""
    found = {".": ("dir", folder.stat().st_mtime_ns)}
    for path in sorted(folder.rglob("*")):
        stat = path.stat()
        found[str(path.relative_to(folder))] = (path.read_bytes() if path.is_file() else "dir", stat.st_mtime_ns)
    return found


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A user's project in tmp: ./scenes/mine.json, the current directory; the checkout's golden/ watched."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "mine.json").write_text(json.dumps(TRIANGLE), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    before = state(REPO / "golden")
    yield tmp_path
    assert state(REPO / "golden") == before, "the checkout's golden/ changed"


def test_help_shows_relative_defaults_not_the_installed_checkout(project, capsys):
    for command in (["golden", "--help"], ["conformance", "--help"]):
        assert main(command) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert str(REPO) not in text
        assert "./scenes of the current directory" in text
    assert main(["golden", "--help"]) == 0
    assert "default ./golden of the current directory" in " ".join(capsys.readouterr().out.split())


def test_no_scenes_here_is_one_line_status_2_and_nothing_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for command in (["golden"], ["golden", "--update"]):
        assert main(command) == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and "no scene files in ./scenes" in err[0] and str(tmp_path) in err[0]
    assert list(tmp_path.iterdir()) == []


def test_no_module_resolves_a_default_folder_from_its_own_location():
    """Only the README demo scene is softras's own (``softras demo``); nothing
    else in softras/ looks for scenes or golden images beside its source.
    (The kernels read their own source files, for numba's cache key:
    `softras.kernels.stamp.sources_stamp`, which names them relative to the
    package, `softras.pipeline.cache_key.PACKAGE`, and for the ready marks of
    `softras.kernels.prepare`, which sit beside numba's cache in the
    kernels' __pycache__: no user folder.)"""
    found = []
    for path in sorted((REPO / "softras").rglob("*.py")):
        source = path.read_text(encoding="utf-8")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.Name) and node.id == "__file__":
                line = source.splitlines()[node.lineno - 1].strip()
                found.append((str(path.relative_to(REPO)), line.split(" = ")[0]))
    assert found == [("softras/cli.py", "_PACKAGE"),
                     ("softras/kernels/prepare.py", 'return Path(__file__).resolve().parent / "__pycache__"'),
                     ("softras/kernels/stamp.py", "paths"),
                     ("softras/pipeline/cache_key.py", "PACKAGE")], found


@pytest.mark.gl
def test_update_and_verify_with_no_paths_use_scenes_and_golden_here(project, capsys):
    assert main(["golden", "--update"]) == 0
    out = capsys.readouterr().out
    assert "added     mine.png" in out and "golden update golden: 1 scene, 1 added" in out
    assert sorted(p.name for p in (project / "golden").iterdir()) == ["manifest.json", "mine.png"]
    assert sorted(p.name for p in project.iterdir()) == ["golden", "scenes"]

    assert main(["golden"]) == 0
    out = capsys.readouterr().out
    assert "PASS  mine" in out and "1 checked, 1 passed, 0 failed" in out


@pytest.mark.gl
def test_update_of_a_named_scene_elsewhere_writes_golden_of_the_current_directory(project, tmp_path_factory,
                                                                                   capsys):
    elsewhere = tmp_path_factory.mktemp("elsewhere")
    (elsewhere / "other.json").write_text(json.dumps(TRIANGLE), encoding="utf-8")
    assert main(["golden", "--update", str(elsewhere / "other.json")]) == 0
    assert "added     other.png" in capsys.readouterr().out
    assert sorted(p.name for p in (project / "golden").iterdir()) == ["manifest.json", "other.png"]
    assert sorted(p.name for p in elsewhere.iterdir()) == ["other.json"]


@pytest.mark.gl
def test_an_update_that_changes_nothing_writes_nothing(project, capsys):
    assert main(["golden", "--update"]) == 0
    manifest = project / "golden" / "manifest.json"
    # The update was made by other tools on another day: the pixels and the GL
    # are the same, so the provenance of the run that made them stays.
    data = json.loads(manifest.read_text())
    data["provenance"].update(date="2001-01-01T00:00:00+00:00", python="3.0.0", numpy="0.1", softras=None,
                              moderngl="1.0", cpu="another CPU", platform="another OS")
    manifest.write_text(golden._manifest_text(data), encoding="utf-8")
    os.utime(manifest, ns=(1_000_000_000, 1_000_000_000))
    capsys.readouterr()
    before = state(project)
    for command in (["golden", "--update"], ["golden", "--update", "scenes/mine.json"]):
        assert main(command) == 0
        out = capsys.readouterr().out
        assert "unchanged mine.png" in out and "(nothing written)" in out
        assert state(project) == before  # bytes and mtimes of golden/, its files and the project folder

    # A changed scene is written, with this run's provenance.
    moved = json.loads(json.dumps(TRIANGLE))
    moved["background"] = [0, 0, 1, 1]
    (project / "scenes" / "mine.json").write_text(json.dumps(moved), encoding="utf-8")
    assert main(["golden", "--update"]) == 0
    assert "changed   mine.png" in capsys.readouterr().out
    assert json.loads(manifest.read_text())["provenance"]["python"] != "3.0.0"


@pytest.mark.gl
def test_conformance_with_no_paths_checks_scenes_of_the_current_directory(project):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-m", "softras", "conformance", "--report", "report"],
                         cwd=project, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    results = json.loads((project / "report" / "results.json").read_text())
    assert [scene["name"] for scene in results["scenes"]] == ["mine"]
