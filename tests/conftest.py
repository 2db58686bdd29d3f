"""Shared test fixtures.

Tests marked ``gl`` need glref's headless OpenGL context.  A missing context
is a failure, not a skip, unless ``SOFTRAS_ALLOW_NO_GL=1`` (docs/design.md
section 9).  glref.context is the one place a context is created.
"""

from __future__ import annotations

import contextlib
import gc
import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"


def load_script(name: str):
    """scripts/<name>.py as a module, loaded once and registered in
    sys.modules (its dataclasses look their module up there)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]

# The tests check the compiled kernels against the stages, so a render must
# not fall back to the stages while they compile in the background: compile
# them first (`softras.kernels.prepare`), in this process and in the
# command-line processes the tests start.
os.environ["SOFTRAS_COMPILE"] = "wait"

# Python's bytecode caches, written even where PYTHONDONTWRITEBYTECODE is
# set (this machine's image sets it), by this process and the Python
# processes the tests start (command lines, conformance workers, pytest runs
# of the example projects): without them each compiled softras's sources
# again (~0.08 s of a process's 0.85 s first render), and each pytest
# rewrote the asserts of every test file again (a collection of the suite
# 4.1 s, 1.65 s with the caches).  They go where Python keeps them, the
# ignored __pycache__ folders beside the sources, where numba keeps the
# compiled kernels too (docs/testing.md).
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


# The test files whose tests take longest (--durations with a warm cache:
# the whole CI workflow run locally 21 s, a hang waiting for its timeout
# 6 s, softpipe's conformance 9 s, pytest in subprocesses 4-8 s each):
# run first.  pytest-xdist hands the tests out in collection order, so a
# long test collected last ran alone at the end while the other worker
# idled (19.5 s of the fresh-clone run, docs/speed.md, "Thirty-fourth
# round").
SLOW_FILES = ("test_workflow.py", "test_runner.py", "test_conformance_softpipe.py", "test_pytest_plugin.py",
              "test_merge.py", "test_numba_fixes.py")


def pytest_collection_modifyitems(session, config, items):
    """The tests of `SLOW_FILES` first, every other test in its order."""
    items.sort(key=lambda item: item.path.name not in SLOW_FILES)


def pytest_collection_finish(session):
    """What is there now stays to the end of the session: the compiled
    kernels the workers prepared or loaded (~750k objects of numba's after
    a preparation), the modules, the collected tests.  Python's full
    garbage collections walked all of it, again and again: ~3.9 and ~12.3
    s of the two workers' CPU during the tests of a fresh clone's run (1.5
    and 4.0 s frozen), and pytest's five collections at the end of each
    worker ~6 s (~1 s frozen).  Frozen, they walk only what the tests make
    (docs/testing.md)."""
    gc.collect()
    gc.freeze()


def pytest_addoption(parser):
    parser.addoption("--update-golden", action="store_true", default=False,
                     help="before the tests, re-render golden/ from glref: the same code as "
                          "'softras golden --update' (all scenes, all or nothing)")


def pytest_sessionstart(session):
    """``pytest --update-golden`` runs ``softras golden --update`` in the repository's root
    (its ./scenes and ./golden, wherever pytest was started), then the tests.

    Under pytest-xdist the workers first prepare the compiled kernels'
    variants between them (`softras.kernels.prepare`; a no-op once they are
    ready): otherwise the first tests of every worker need the same variant
    and all but one worker wait on its lock while one core compiles."""
    worker, count = os.environ.get("PYTEST_XDIST_WORKER"), os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if worker and count:
        from softras.kernels import draw, prepare

        # Every variant: the tile drivers, exact precision's kernels and the
        # line kernel, handed out as the workers ask: each worker takes the
        # next variant in this order that no other process is preparing
        # (`prepare.prepare` without waiting for its lock), and when every
        # variant left is being prepared elsewhere it goes on to its tests
        # (a test that needs such a variant waits for it then, in
        # `prepare.ensure`; waiting here left a core idle ~9 s of a fresh
        # clone's run, docs/speed.md, "Forty-fourth round").  Longest
        # first.  The first worker begins with exact and then compiles the
        # stages' loops (their spec bounds render in exact precision); the
        # others leave exact to it (else one of them could take exact's lock
        # first and the first worker would wait for it).  A variant
        # prepared already (by the README's first command, in the
        # background) is skipped, so the workers share what is left
        # (docs/speed.md, "Thirty-eighth round": fixed shares left one
        # worker idle while the other compiled; "Thirty-fourth round" before).
        # What each compile leaves is frozen after it (``freeze``).
        order = [prepare.EXACT, (1, False), (1, True), (4, False), (0, True), (0, False), prepare.LINES]
        assert sorted(order, key=prepare.name) == sorted([*draw._DRAW_TILES, prepare.EXACT, prepare.LINES],
                                                         key=prepare.name)
        if worker == "gw0":
            prepare.prepare(prepare.EXACT, freeze=True)
            _compile_stage_loops()
            gc.collect()                        # (their renders leave garbage: freed, then the rest frozen)
            gc.freeze()
        else:
            order.append(order.pop(0))
        for variant in order:
            prepare.prepare(variant, wait=False, freeze=True)
    if not session.config.getoption("--update-golden", default=False):
        return
    from softras.cli import main

    with contextlib.chdir(REPO):
        status = main(["golden", "--update"])
    if status != 0:
        pytest.exit(f"softras golden --update failed (exit status {status})", returncode=status)


def _compile_stage_loops() -> None:
    """Compile the readable stages' own numba loops into numba's cache (the
    line stage, the per-fragment operations, the resolves, the texture
    bounds, exact precision's stages): every scene of scenes/ on the stages,
    and the spec bounds of five scenes (tie rules, lines moved, texture
    bounds).  Else the first tests to need each loop compile it, on both
    workers at once and in the conformance runner's processes: a fresh
    clone's suite spent ~70 s more in such tests than a warm one
    (docs/speed.md, "Twenty-sixth round").  About 30 s on one core, once;
    a second each after."""
    import softras
    from softras.renderer import render_scene
    from softras.verification import verifier

    for path in sorted(SCENES.glob("*.json")):
        render_scene(softras.load_scene(path), precision="gl", fast_path=False)
    for name in ("line_star", "texture_floor_trilinear", "texture_anisotropic_floor", "bump_mapped_plane",
                 "msaa_fan"):
        verifier.spec_bounds(softras.load_scene(SCENES / f"{name}.json"))
    fan = softras.load_scene(SCENES / "msaa_fan.json")
    render_scene(fan, samples=4, resolve_filter="tent", fast_path=False)
    render_scene(fan, samples=4, precision="exact", fast_path=False)


@pytest.fixture(autouse=True)
def _require_gl(request):
    if request.node.get_closest_marker("gl") is None:
        return
    import glref
    try:
        glref.info()
    except glref.GLUnavailable as exc:
        if os.environ.get("SOFTRAS_ALLOW_NO_GL") == "1":
            pytest.skip(str(exc))
        pytest.fail(str(exc))


def write_failure_images(directory: Path, **images: np.ndarray) -> None:
    """Save named (H, W, 4) uint8 images as PNGs under a test's tmp_path."""
    from PIL import Image
    directory.mkdir(parents=True, exist_ok=True)
    for name, image in images.items():
        Image.fromarray(image).save(directory / f"{name}.png")
