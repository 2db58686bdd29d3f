"""softras's pytest plugin (softras/pytest_plugin.py), run on a copy of examples/pytest_project.

Each test copies the example project to tmp_path and runs pytest on it in a
subprocess, as its user would: the plugin comes from the ``pytest11`` entry
point when softras is installed (else ``-p softras.pytest_plugin``).  The
example's own suite: a ``softras_check`` test on a scene file and on a dict,
``softras_golden`` on two scenes, a ``@pytest.mark.softras_golden`` test, and
its two scene files collected as conformance items (ini ``softras_scenes``).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from softras.scene.imageio import read_png

from conftest import REPO

EXAMPLE = REPO / "examples" / "pytest_project"
# The example's tests (7): 2 scene items, 5 test functions (one parametrized twice).
EXAMPLE_TESTS = {
    "scenes.quads.json::quads", "scenes.triangle.json::triangle",
    "tests.test_pictures::test_triangle_conforms", "tests.test_pictures::test_scene_built_in_code_conforms",
    "tests.test_pictures::test_golden_image[triangle]", "tests.test_pictures::test_golden_image[quads]",
    "tests.test_pictures::test_quads_golden_marker",
}


def plugin_installed() -> bool:
    return any(entry.value == "softras.pytest_plugin" for entry in metadata.entry_points(group="pytest11"))


@pytest.fixture
def project(tmp_path):
    folder = tmp_path / "project"
    shutil.copytree(EXAMPLE, folder, ignore=shutil.ignore_patterns(".softras-results", ".pytest_cache",
                                                                   "__pycache__"))
    return folder


def run_pytest(folder: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    environ = {key: value for key, value in os.environ.items()
               if not key.startswith(("PYTEST_", "SOFTRAS_GL_DEVICE", "SOFTRAS_ALLOW_NO_GL"))}
    environ["PYTHONPATH"] = os.pathsep.join([str(REPO)] + ([os.environ["PYTHONPATH"]]
                                                          if os.environ.get("PYTHONPATH") else []))
    environ.update(env or {})
    plugin = [] if plugin_installed() else ["-p", "softras.pytest_plugin"]
    # (Not hypothesis's plugin, which softras's own test dependencies bring: it
    # imports hypothesis at the end of every run, 0.9 s of each of these runs.
    # Nor pytest's watch for unraisable exceptions, five full garbage
    # collections at the end of each run: 0.18 s of each.)
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:hypothesispytest",
                           "-p", "no:unraisableexception", *plugin, *args],
                          cwd=folder, env=environ, capture_output=True, text=True, timeout=900)


def junit_cases(path: Path) -> dict[str, str]:
    """{classname::name: outcome} of a JUnit XML file (passed, failure, error, skipped)."""
    cases = {}
    for case in ET.parse(path).getroot().iter("testcase"):
        outcome = next((child.tag for child in case if child.tag in ("failure", "error", "skipped")), "passed")
        cases[f"{case.get('classname')}::{case.get('name')}"] = outcome
    return cases


def tree_state(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None, p.stat().st_mtime_ns)
            for p in sorted([folder, *folder.rglob("*")])}


def test_the_plugin_is_declared_as_a_pytest11_entry_point():
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    assert project["project"]["entry-points"]["pytest11"] == {"softras": "softras.pytest_plugin"}
    assert "pytest-xdist>=3" in project["project"]["optional-dependencies"]["test"]


@pytest.mark.gl
def test_example_passes_with_one_junit_testcase_per_scene(project):
    run = run_pytest(project, "--junitxml=junit.xml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "7 passed" in run.stdout
    cases = junit_cases(project / "junit.xml")
    assert cases == dict.fromkeys(EXAMPLE_TESTS, "passed")
    assert not (project / ".softras-results").exists()  # pictures only of failed checks


@pytest.mark.gl
def test_k_selects_scenes_and_tests_and_x_stops(project):
    run = run_pytest(project, "-k", "quads", "--junitxml=junit.xml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert set(junit_cases(project / "junit.xml")) == {
        "scenes.quads.json::quads", "tests.test_pictures::test_golden_image[quads]",
        "tests.test_pictures::test_quads_golden_marker"}

    (project / "tests" / "golden" / "triangle.png").unlink()
    run = run_pytest(project, "-x", "-k", "triangle", "--junitxml=junit.xml")
    assert run.returncode == 1
    assert "stopping after 1 failures" in run.stdout
    assert sum(outcome == "failure" for outcome in junit_cases(project / "junit.xml").values()) == 1


@pytest.mark.gl
def test_xdist_runs_the_example_on_two_workers(project):
    assert importlib.util.find_spec("xdist"), "pytest-xdist is a test dependency: pip install -e '.[test]'"
    run = run_pytest(project, "-n", "2", "--junitxml=junit.xml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "2 workers" in run.stdout and "7 passed" in run.stdout
    assert junit_cases(project / "junit.xml") == dict.fromkeys(EXAMPLE_TESTS, "passed")

    # Workers updating one golden folder take turns; nothing changed, nothing written.
    golden = project / "tests" / "golden"
    before = tree_state(golden)
    run = run_pytest(project, "-n", "2", "--softras-update-golden")
    assert run.returncode == 0, run.stdout + run.stderr
    assert tree_state(golden) == before


@pytest.mark.gl
def test_wrong_golden_fails_with_the_reason_and_update_rewrites_it(project):
    golden = project / "tests" / "golden"
    right = (golden / "quads.png").read_bytes()
    pixels = read_png(golden / "quads.png").copy()
    pixels[..., :3] = 255 - pixels[..., :3]  # a wrong golden image: the colours inverted
    Image.fromarray(pixels).save(golden / "quads.png")

    run = run_pytest(project)
    assert run.returncode == 1
    assert "2 failed, 5 passed" in run.stdout
    text = run.stdout
    assert "FAILED tests/test_pictures.py::test_golden_image[quads]" in text
    assert "FAILED tests/test_pictures.py::test_quads_golden_marker" in text
    assert f"softras golden: {golden / 'quads.png'} does not hold for scene" in text
    assert "golden pixels do not match the sha256 in manifest.json" in text
    assert "glref no longer reproduces the golden image (480 pixels differ)" in text
    assert "softras vs golden: ssim" in text
    pictures = project / ".softras-results" / "tests_test_pictures.py_test_golden_image_quads" / "quads"
    assert f"pictures: {pictures}/" in text
    assert sorted(p.name for p in pictures.iterdir()) == [
        "diff_gl.png", "diff_soft.png", "gl.png", "golden.png", "soft.png"]

    run = run_pytest(project, "--softras-update-golden")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "softras golden images written" in run.stdout
    assert re.search(r"changed +quads\.png +\(480 pixels differ\)", run.stdout)
    assert (golden / "quads.png").read_bytes() == right

    # Updating again changes nothing: not a byte, not a modification time.
    before = tree_state(golden)
    run = run_pytest(project, "--softras-update-golden")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "softras golden images written" not in run.stdout
    assert tree_state(golden) == before


@pytest.mark.gl
def test_missing_golden_is_a_clear_failure_and_update_writes_it(project):
    golden = project / "tests" / "golden"
    (golden / "triangle.png").unlink()
    run = run_pytest(project, "-k", "golden")
    assert run.returncode == 1
    assert "1 failed, 2 passed" in run.stdout
    assert (f"softras golden: no golden image {golden / 'triangle.png'} for scene "
            f"{project / 'scenes' / 'triangle.json'}: run pytest with --softras-update-golden to write it"
            in run.stdout)

    run = run_pytest(project, "-k", "golden", "--softras-update-golden")
    assert run.returncode == 0, run.stdout + run.stderr
    assert re.search(r"added +triangle\.png +\(32x24\)", run.stdout)
    assert (golden / "triangle.png").read_bytes() == (EXAMPLE / "tests" / "golden" / "triangle.png").read_bytes()


PLANTED_BUG = '''
from softras.verification import conformance

real = conformance._render_gl


def swapped(scene):
    """A planted bug: the reference picture's red and blue swapped."""
    return real(scene)[..., [2, 1, 0, 3]]


conformance._render_gl = swapped
'''


@pytest.mark.gl
def test_a_planted_bug_fails_the_conformance_checks_with_the_reasons_and_pictures(project):
    (project / "conftest.py").write_text(PLANTED_BUG, encoding="utf-8")
    run = run_pytest(project, "--junitxml=junit.xml")
    assert run.returncode == 1
    cases = junit_cases(project / "junit.xml")
    assert {name for name, outcome in cases.items() if outcome == "failure"} == {
        "scenes.quads.json::quads", "scenes.triangle.json::triangle",
        "tests.test_pictures::test_triangle_conforms", "tests.test_pictures::test_scene_built_in_code_conforms"}
    # The failure message is the verdict's reasons, as softras conformance gives them.
    assert "softras conformance: FAIL triangle (profile auto, tolerance: defaults for base)\n  236 px" in run.stdout
    assert "softras conformance: FAIL fan (profile auto, tolerance: defaults for base)" in run.stdout
    assert "outside the ambiguity mask" in run.stdout
    pictures = project / ".softras-results" / "scenes_triangle.json_triangle" / "triangle"
    assert f"pictures: {pictures}/ (gl.png, soft.png, diff.png" in run.stdout
    assert {"soft.png", "gl.png", "diff.png"} <= {p.name for p in pictures.iterdir()}
    gl = read_png(pictures / "gl.png")
    assert np.array_equal(read_png(pictures / "soft.png"), gl[..., [2, 1, 0, 3]])


@pytest.mark.gl
def test_without_gl_checks_fail_unless_the_user_opts_out(project):
    no_gl = {"SOFTRAS_GL_DEVICE": "none"}  # glref refuses it: no context
    run = run_pytest(project, "--junitxml=junit.xml", env=no_gl)
    assert run.returncode == 1
    assert set(junit_cases(project / "junit.xml").values()) == {"failure"}
    assert "OpenGL unavailable" in run.stdout and "set SOFTRAS_ALLOW_NO_GL=1 to skip" in run.stdout

    run = run_pytest(project, "--junitxml=junit.xml", env=no_gl | {"SOFTRAS_ALLOW_NO_GL": "1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "7 skipped" in run.stdout
    assert set(junit_cases(project / "junit.xml").values()) == {"skipped"}


@pytest.mark.gl
def test_softras_scenes_option_collects_a_folder_and_bad_options_are_usage_errors(project, tmp_path):
    more = tmp_path / "more"
    more.mkdir()
    shutil.copy(project / "scenes" / "quads.json", more / "extra.json")
    run = run_pytest(project, "tests/test_pictures.py", "--softras-scenes", str(more), "-k", "extra or conforms",
                     "--junitxml=junit.xml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert set(junit_cases(project / "junit.xml")) == {
        "tests.test_pictures::test_triangle_conforms", "tests.test_pictures::test_scene_built_in_code_conforms",
        "extra.json::extra"}

    run = run_pytest(project, "--softras-scenes", str(tmp_path / "missing"))
    assert run.returncode == 4  # pytest's usage error
    assert "--softras-scenes" in run.stderr and "no such folder" in run.stderr
    run = run_pytest(project, "--softras-profile", "loose")
    assert run.returncode == 4 and "invalid choice" in run.stderr


@pytest.mark.gl
def test_check_scene_takes_a_scene_in_memory():
    """softras_check(dict or Scene): check_scene judges a scene built in code, with its declared tolerance."""
    import json

    from softras.scene import load_scene
    from softras.verification.conformance import PASS, check_scene

    data = json.loads((EXAMPLE / "scenes" / "triangle.json").read_text(encoding="utf-8"))
    from_file = check_scene(EXAMPLE / "scenes" / "triangle.json")
    from_scene = check_scene(load_scene(data), name="mine")
    assert (from_scene.name, from_scene.path, from_scene.verdict) == ("mine", "", PASS)
    assert from_scene.tolerance == from_file.tolerance and from_scene.tolerance_source == "defaults for base"
    assert check_scene(load_scene(data)).name == "scene"
    declared = dict(data, tolerance={"threshold": 9, "max_bad_fraction": 0.5, "min_ssim": 0.5})
    result = check_scene(declared)
    assert result.tolerance_source == "scene" and result.tolerance["threshold"] == 9


def test_marked_test_with_a_defaulted_parameter_gets_its_default(project):
    """``@pytest.mark.softras_golden`` calls the test with the fixtures it asks
    for, as pytest does: a parameter with a default keeps its default."""
    (project / "tests" / "test_defaulted.py").write_text(
        "from pathlib import Path\n\nimport pytest\n\n\n"
        "@pytest.mark.softras_golden\n"
        "def test_defaulted(tmp_path, name='triangle'):\n"
        "    return str(Path(__file__).parents[1] / 'scenes' / f'{name}.json')\n")
    run = run_pytest(project, "tests/test_defaulted.py")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "1 passed" in run.stdout


def test_loading_the_plugin_does_not_import_numba():
    """pytest imports the plugin in every session of an environment with
    softras installed: that costs no numpy or numba until a test uses softras."""
    code = "import sys, softras.pytest_plugin; print(sorted(m for m in ('numba', 'numpy') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.strip() == "[]", out.stdout
