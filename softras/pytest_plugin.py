"""softras's pytest plugin: conformance checks and golden images in a project's own suite.

Installed with softras (entry point ``softras`` in the ``pytest11`` group), it
is inert until a test asks for it (docs/pytest_plugin.md):

- the fixture ``softras_check(scene)`` renders a scene (a file, a dict or a
  Scene) with softras and with OpenGL and judges it exactly as
  ``softras conformance`` does (:func:`softras.verification.conformance.check_scene`):
  FAIL fails the test with the verdict's reasons, QUALITY WARNING passes with
  a :class:`SoftrasQualityWarning`, NOT SUPPORTED skips;
- the fixture ``softras_golden(scene)`` and the marker
  ``@pytest.mark.softras_golden`` (the test returns the scene) check a scene
  against its golden image in ``golden/`` beside the test module -- a golden
  folder of ``softras golden`` (:mod:`softras.verification.golden`: the PNG
  matches its manifest hash, glref reproduces it, softras's rendering is
  within the scene's tolerance); ``--softras-update-golden`` (re)writes them,
  writing nothing when nothing changed;
- ``--softras-scenes DIR`` (or the ini option ``softras_scenes``) makes the
  scene files of a folder test items, one per scene, each running the
  conformance check: ``-k``, ``-x``, ``--junitxml`` and pytest-xdist's ``-n``
  work on them as on any test.

A failing check writes its pictures (soft.png, gl.png, diff.png and the
others of the verdict) to ``<results>/<test id>/<scene>/``, results being
``--softras-results DIR``, the ini option ``softras_results``, or
``.softras-results`` in the rootdir; the failure message names the folder.

OpenGL is needed, as by the tests of softras marked ``gl``: without a GL
context the checks fail, unless ``SOFTRAS_ALLOW_NO_GL=1`` is set, when they
are skipped.
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
import json
import os
import re
import shutil
import tempfile
import warnings
from pathlib import Path

import pytest

__all__ = ["SoftrasQualityWarning", "ALLOW_NO_GL", "RESULTS_DIR", "GOLDEN_DIR"]

#: Set to ``1`` to skip (not fail) softras's checks on a machine without OpenGL.
ALLOW_NO_GL = "SOFTRAS_ALLOW_NO_GL"
#: Default folder of the pictures of failed checks, in the rootdir.
RESULTS_DIR = ".softras-results"
#: Default golden folder, beside the test module.
GOLDEN_DIR = "golden"

_PROFILES = ("auto", "strict", "spec")
_SCENE_DIRS = pytest.StashKey[list]()


class SoftrasQualityWarning(UserWarning):
    """A check gave QUALITY WARNING: softras and GL differ only where GL's answer is ambiguous."""


# ---------------------------------------------------------------------------
# Options


def pytest_addoption(parser):
    group = parser.getgroup("softras", "softras: conformance checks and golden images")
    group.addoption("--softras-scenes", action="append", default=[], metavar="DIR",
                    help="collect the scene files (*.json, *.gltf, *.glb) of DIR as test items, one conformance check "
                         "each (repeatable; DIR is added to the paths to collect)")
    group.addoption("--softras-profile", choices=_PROFILES, default=None,
                    help="verification profile of the conformance checks (default: ini softras_profile, "
                         "else auto)")
    group.addoption("--softras-results", default=None, metavar="DIR",
                    help=f"write the pictures of failed checks to DIR/<test id>/<scene>/ (default: ini "
                         f"softras_results, else {RESULTS_DIR} in the rootdir)")
    group.addoption("--softras-update-golden", action="store_true", default=False,
                    help="(re)write the golden images of the tests that check them (softras_golden), "
                         "then check; an unchanged image is not written")
    group.addoption("--softras-golden-dir", default=None, metavar="DIR",
                    help=f"golden folder of every golden check (default: ini softras_golden_dir, else "
                         f"{GOLDEN_DIR}/ beside each test module)")
    parser.addini("softras_scenes", type="paths", default=[],
                  help="folders whose scene files (*.json, *.gltf, *.glb) are collected as conformance test items "
                       "when pytest visits them (relative to the ini file)")
    parser.addini("softras_profile", default="auto", help="verification profile: auto, strict or spec")
    parser.addini("softras_results", default="",
                  help=f"folder of the pictures of failed checks (relative to the rootdir; default {RESULTS_DIR})")
    parser.addini("softras_golden_dir", default="",
                  help=f"golden folder of every golden check (relative to the rootdir; default {GOLDEN_DIR}/ "
                       f"beside each test module)")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "softras_golden(golden_dir=None, name=None): the test returns a scene (file or dict), checked against "
        "its golden image (softras's pytest plugin, docs/pytest_plugin.md)")
    profile = _profile(config)
    if profile not in _PROFILES:
        raise pytest.UsageError(f"softras_profile = {profile}: expected one of {', '.join(_PROFILES)}")
    invocation = Path(config.invocation_params.dir)
    given = [(invocation / folder).resolve() for folder in config.getoption("softras_scenes")]
    for folder in given:
        if not folder.is_dir():
            raise pytest.UsageError(f"--softras-scenes {folder}: no such folder")
    folders = [Path(folder).resolve() for folder in config.getini("softras_scenes")] + given
    config.stash[_SCENE_DIRS] = folders
    # --softras-scenes DIR: DIR is collected too, unless a path given already holds it.
    for folder in given:
        covered = False
        for arg in config.args:
            target = (invocation / arg.split("::")[0]).resolve()
            if target == folder or target in folder.parents:
                covered = True
        if not covered:
            config.args.append(str(folder))


def _profile(config) -> str:
    return config.getoption("softras_profile") or config.getini("softras_profile") or "auto"


def _results_dir(config) -> Path:
    option = config.getoption("softras_results")
    if option:
        return Path(config.invocation_params.dir) / option
    ini = config.getini("softras_results")
    return config.rootpath / (ini or RESULTS_DIR)


def _golden_dir(item, given) -> Path:
    """The golden folder of a test: the argument or marker's (relative to the test
    module), else --softras-golden-dir (relative to where pytest runs), else the ini
    option (relative to the rootdir), else golden/ beside the test module."""
    here = Path(item.path).parent
    if given:
        return here / given
    option = item.config.getoption("softras_golden_dir")
    if option:
        return Path(item.config.invocation_params.dir) / option
    ini = item.config.getini("softras_golden_dir")
    if ini:
        return item.config.rootpath / ini
    return here / GOLDEN_DIR


# ---------------------------------------------------------------------------
# Shared by the fixtures and the scene items


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def require_gl() -> None:
    """Fail the test without OpenGL, or skip it when ``SOFTRAS_ALLOW_NO_GL=1``."""
    try:
        import glref
    except ModuleNotFoundError as error:
        reason = f"OpenGL reference renderer unavailable: {_one_line(error)}"
    else:
        try:
            glref.info()
            return
        except glref.GLUnavailable as error:
            reason = f"OpenGL unavailable: {_one_line(error)}"
    if os.environ.get(ALLOW_NO_GL) == "1":
        pytest.skip(f"{reason} ({ALLOW_NO_GL}=1)")
    pytest.fail(f"{reason} (set {ALLOW_NO_GL}=1 to skip softras's checks)", pytrace=False)


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "test"


def _picture_dir(item, scene_name: str) -> Path:
    return _results_dir(item.config) / _safe(item.nodeid) / _safe(scene_name)


def _write_pictures(folder: Path, images: dict) -> list[str]:
    from softras.scene.imageio import write_png_atomic

    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    written = []
    for name, image in images.items():
        write_png_atomic(folder / f"{name}.png", image)
        written.append(f"{name}.png")
    return written


def _check(item, scene, *, profile=None, tolerance=None, name=None):
    """The conformance check of one scene for a test: returns the SceneResult or fails / skips."""
    from softras.verification import conformance
    from softras.verification.conformance import FAIL, NOT_SUPPORTED, VERDICT_NAMES, WARN

    require_gl()
    profile = profile or _profile(item.config)
    if name is None and not isinstance(scene, (str, os.PathLike)):
        name = _safe(getattr(item, "originalname", None) or item.name)
    result = conformance.check_scene(scene, profile=profile, tolerance=tolerance, name=name)
    if result.verdict == NOT_SUPPORTED:
        pytest.skip(f"NOT SUPPORTED {result.name}: " + "; ".join(result.reasons))
    if result.verdict not in (FAIL, WARN):
        return result
    folder = _picture_dir(item, result.name)
    written = _write_pictures(folder, result.images) if result.images else []
    item.user_properties.append(("softras_pictures", str(folder)))
    where = f"\npictures: {folder}/ ({', '.join(written)})" if written else ""
    text = (f"softras conformance: {VERDICT_NAMES[result.verdict]} {result.name} (profile {profile}, "
            f"tolerance: {result.tolerance_source})\n" + "\n".join(f"  {reason}" for reason in result.reasons)
            + where)
    if result.verdict == WARN:
        warnings.warn(SoftrasQualityWarning(text), stacklevel=3)
        return result
    pytest.fail(text, pytrace=False)


@contextlib.contextmanager
def _golden_lock(golden_dir: Path):
    """One writer per golden folder at a time (pytest-xdist workers updating the same folder)."""
    try:
        import fcntl
    except ImportError:  # no flock (Windows): updates of one folder must not run in parallel
        yield
        return
    key = hashlib.sha256(str(golden_dir.resolve()).encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f"softras-golden-{key}.lock"
    with open(path, "a") as handle:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)


def _golden(item, scene, *, golden_dir=None, name=None):
    """Check a scene against its golden image (and write it first with --softras-update-golden)."""
    if isinstance(scene, dict):  # saved as <name>.json for the time of the check
        with tempfile.TemporaryDirectory(prefix="softras-golden-") as folder:
            path = Path(folder) / f"{_safe(name or getattr(item, 'originalname', None) or item.name)}.json"
            path.write_text(json.dumps(scene), encoding="utf-8")
            return _golden(item, path, golden_dir=golden_dir)
    if not isinstance(scene, (str, os.PathLike)):
        raise TypeError(f"softras_golden: expected a scene file or a dict, got {type(scene).__name__} "
                        f"(golden images are named after the scene file)")
    from softras.verification import golden

    scene = Path(scene)
    require_gl()
    folder = _golden_dir(item, golden_dir)
    update = item.config.getoption("softras_update_golden")
    try:
        with _golden_lock(folder) if update else contextlib.nullcontext():
            if update:
                for change in golden.update([scene], folder):
                    if change.status != "unchanged":
                        item.user_properties.append(("softras_golden", f"{change.line()}  in {folder}"))
            result = golden.verify([scene], folder, keep_images=True)[0]
    except golden.GoldenError as error:
        pytest.fail(f"softras golden: {_one_line(error)}", pytrace=False)
    if result.passed:
        return result
    golden_file = Path(result.golden)
    if result.failures == [golden.NO_GOLDEN]:
        pytest.fail(f"softras golden: no golden image {golden_file} for scene {scene}: run pytest with "
                    f"--softras-update-golden to write it", pytrace=False)
    images = golden.failure_images(result)
    where = ""
    if images:
        pictures = _picture_dir(item, scene.stem)
        written = _write_pictures(pictures, images)
        item.user_properties.append(("softras_pictures", str(pictures)))
        where = f"\npictures: {pictures}/ ({', '.join(written)})"
    pytest.fail(f"softras golden: {golden_file} does not hold for scene {scene}\n"
                + "\n".join(f"  {failure}" for failure in result.failures)
                + "\n  (if the change is intended: pytest --softras-update-golden)" + where, pytrace=False)


# ---------------------------------------------------------------------------
# Fixtures and the golden marker


@pytest.fixture
def softras_check(request):
    """``softras_check(scene, *, profile=None, tolerance=None, name=None)``: the conformance
    check of a scene (a file, a dict or a Scene); returns its
    :class:`softras.verification.conformance.SceneResult`, fails the test on FAIL."""

    def check(scene, *, profile: str | None = None, tolerance: dict | None = None, name: str | None = None):
        return _check(request.node, scene, profile=profile, tolerance=tolerance, name=name)

    return check


@pytest.fixture
def softras_golden(request):
    """``softras_golden(scene, *, golden_dir=None, name=None)``: check a scene file (or a
    dict, saved as ``<name>.json``) against ``<golden_dir>/<scene stem>.png``."""

    def check(scene, *, golden_dir: str | os.PathLike | None = None, name: str | None = None):
        return _golden(request.node, scene, golden_dir=golden_dir, name=name)

    return check


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """``@pytest.mark.softras_golden``: call the test, then check the scene it returns."""
    marker = pyfuncitem.get_closest_marker("softras_golden")
    if marker is None or inspect.iscoroutinefunction(pyfuncitem.obj):
        return None
    # (The fixtures the test asks for, as pytest's own pytest_pyfunc_call
    # passes them: not every parameter, which may have a default.)
    scene = pyfuncitem.obj(**{name: pyfuncitem.funcargs[name] for name in pyfuncitem._fixtureinfo.argnames})
    if scene is None:
        pytest.fail("@pytest.mark.softras_golden: the test must return its scene (a file path or a dict)",
                    pytrace=False)
    options = dict(marker.kwargs)
    unknown = set(options) - {"golden_dir", "name"}
    if unknown or marker.args:
        pytest.fail(f"@pytest.mark.softras_golden takes golden_dir= and name= only, got "
                    f"{', '.join(sorted(unknown)) or 'positional arguments'}", pytrace=False)
    _golden(pyfuncitem, scene, **options)
    return True


def pytest_terminal_summary(terminalreporter):
    """List the golden images --softras-update-golden wrote (from every xdist worker too)."""
    lines = []
    for reports in terminalreporter.stats.values():
        for report in reports:
            for key, value in getattr(report, "user_properties", ()):
                if key == "softras_golden" and getattr(report, "when", None) == "call":
                    lines.append(value)
    if lines:
        terminalreporter.section("softras golden images written")
        for line in sorted(set(lines)):
            terminalreporter.write_line(line)


# ---------------------------------------------------------------------------
# Scene files as test items


def pytest_collect_file(file_path, parent):
    folders = parent.config.stash.get(_SCENE_DIRS, [])
    if not folders or file_path.resolve().parent not in folders:
        return None                    # (softras itself is imported only for a scene folder)
    from softras.scene.parse import is_scene_file

    if is_scene_file(file_path.name):
        return SceneFile.from_parent(parent, path=file_path)
    return None


class SceneFile(pytest.File):
    """A scene file of a ``softras_scenes`` folder: one item, its conformance check."""

    def collect(self):
        yield SceneItem.from_parent(self, name=self.path.stem)


class SceneItem(pytest.Item):
    """The conformance check of one scene file, as ``softras conformance`` runs it."""

    def runtest(self):
        _check(self, self.path)

    def reportinfo(self):
        return self.path, None, f"softras conformance: {self.path.name}"
