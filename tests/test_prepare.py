"""Preparing the compiled kernels (softras.kernels.prepare): the stages draw
while a background process compiles, "wait" compiles first, one process
compiles a variant at a time, and the preparation scene reaches every kernel."""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import softras
from softras.kernels import draw as fastpath
from softras.kernels import prepare
from softras.kernels import setup as k_setup
from softras.kernels import texture as k_texture
from softras.pipeline import clip as clip_stage
from softras.pipeline import render as stages
from softras.pipeline import lines, texture, vertex
from softras.renderer import render_scene

SCENE = softras.load_scene(prepare.preparation_scene(1, False))
SCENES_DIR = Path(__file__).resolve().parents[1] / "scenes"


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """Marks and locks in an empty directory: nothing is ready."""
    monkeypatch.setattr(prepare, "cache_dir", lambda: tmp_path)
    return tmp_path


@pytest.fixture
def started(monkeypatch):
    """start_background's processes, recorded instead of started."""
    calls = []

    def record(variants):
        calls.append(sorted(variants, key=prepare.name))
        return True

    monkeypatch.setattr(prepare, "start_background", record)
    return calls


@pytest.mark.parametrize("textured", [False, True])
def test_the_preparation_scene_reaches_every_kernel(textured):
    """Every draw but the last two crosses the near plane (the clipper's
    generated triangles) with at least PARALLEL_SETUP triangles (the
    parallel set-up), the last two have fewer, one unlit (the front end in
    one call, `softras.kernels.front_end`), one lit (the set-up in one
    call); every shading model; textured: a filter of each kind, lanes and
    scalar; and with lines, `line_preparation_scene`'s draw."""
    scene = softras.load_scene(prepare.preparation_scene(4, textured, lines=False))
    assert fastpath.unsupported(scene, precision="gl", clipping=None) is None
    assert {d.material.shading for d in scene.draws} == {"unlit", "flat", "gouraud", "phong"}
    with_lines = softras.load_scene(prepare.preparation_scene(4, textured))
    assert [d.mesh.primitive for d in with_lines.draws] == ["triangles"] * 6 + ["lines"]
    assert [d.material.shading for d in scene.draws[-2:]] == ["unlit", "gouraud"]
    assert all(0 < len(d.mesh.indices) < k_setup.PARALLEL_SETUP for d in scene.draws[-2:])
    for draw in scene.draws[:-2]:
        mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
        source, slot, _, _ = clip_stage.triangle_list_gl(vertex.to_clip(draw.mesh.positions, mvp, "gl"),
                                                          draw.mesh.indices)
        assert len(source) >= k_setup.PARALLEL_SETUP, draw.path
        assert (slot >= 0).any(), f"{draw.path} crosses no clip plane"
        assert (draw.material.texture is not None) == textured
    kinds = {k_texture.texture_tables(texture.prepare(tex), True)[0].vectorised for tex in scene.textures.values()}
    assert kinds == ({0, 1} if textured else set())


def test_the_line_preparation_scene_crosses_the_near_plane():
    """The lines of `line_preparation_scene` reach the line clipper's
    generated end points."""
    scene = softras.load_scene(prepare.line_preparation_scene())
    (draw,) = scene.draws
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    clipped = lines.clip_lines(vertex.to_clip(draw.mesh.positions, mvp, "gl"), draw.mesh.indices)
    assert len(clipped) == 2 and clipped.generated.any(), "the lines cross no clip plane"


def test_background_mode_draws_with_the_stages_meanwhile(fresh_cache, started, monkeypatch):
    """Nothing ready: the stages draw the scene (the same bytes), one
    background preparation of the scene's variants (its triangles' tile
    driver, the line kernel) is started, no mark is written by the render."""
    monkeypatch.setenv(prepare.ENV, prepare.MODE_BACKGROUND)
    image = render_scene(SCENE)
    assert started == [[(1, False), prepare.LINES]]
    assert not prepare.ready((1, False)) and not prepare.ready(prepare.LINES)
    assert np.array_equal(image, render_scene(SCENE, fast_path=False))


def test_a_wireframe_waits_for_no_compile(fresh_cache, started, monkeypatch):
    """Lines alone need the line kernel (`prepare.LINES`): the stages draw
    them while it compiles in the background, then the kernel draws them
    (the same bytes)."""
    kernel_draws = []
    draw_lines = fastpath.draw_lines
    monkeypatch.setattr(fastpath, "draw_lines", lambda *args: kernel_draws.append(1) or draw_lines(*args))
    monkeypatch.setenv(prepare.ENV, prepare.MODE_BACKGROUND)
    wireframe = softras.load_scene(prepare.line_preparation_scene())
    assert prepare.variants(wireframe, 4) == {prepare.LINES}
    image = render_scene(wireframe, samples=4)
    assert started == [[prepare.LINES]] and kernel_draws == []
    assert prepare.main([prepare.LINES]) == 0
    assert prepare.ready(prepare.LINES) and not prepare.ready((1, False))
    kernel_draws.clear()
    assert np.array_equal(render_scene(wireframe, samples=4), image) and kernel_draws == [1]
    assert image[..., :3].any()


def test_background_mode_waits_when_the_stages_refuse_the_scene(fresh_cache, started, monkeypatch):
    """A scene whose float64 sample buffers the stages refuse (here: a lower
    limit) is compiled now, in this process (no background process beside
    it), and drawn by the kernels."""
    monkeypatch.setenv(prepare.ENV, prepare.MODE_BACKGROUND)
    monkeypatch.setattr(stages, "MAX_SAMPLE_BYTES", SCENE.width * SCENE.height * 8)
    render_scene(SCENE)
    assert started == []
    assert prepare.ready((1, False))


def test_wait_mode_prepares_first_and_marks_ready(fresh_cache, started, monkeypatch):
    monkeypatch.setenv(prepare.ENV, prepare.MODE_WAIT)
    textured = softras.load_scene(prepare.preparation_scene(1, True))
    render_scene(textured, samples=4)
    assert started == []
    assert prepare.ready((0, True)) and not prepare.ready((1, True))
    monkeypatch.setenv(prepare.ENV, prepare.MODE_BACKGROUND)       # ready: no background process
    render_scene(textured, samples=4)
    assert started == []


def test_exact_precision_draws_with_the_stages_while_its_kernels_compile(fresh_cache, started, monkeypatch):
    """Exact precision, nothing ready: the stages draw the scene (the same
    bytes) and one background preparation of `prepare.EXACT` is started;
    once it is ready, none is."""
    from softras.kernels import exact

    kernel_renders = []
    render_samples = exact.render_samples
    monkeypatch.setattr(exact, "render_samples",
                        lambda *args, **kw: kernel_renders.append(1) or render_samples(*args, **kw))
    monkeypatch.setenv(prepare.ENV, prepare.MODE_BACKGROUND)
    image = render_scene(SCENE, precision="exact")
    assert started == [[prepare.EXACT]] and kernel_renders == []
    assert not prepare.ready(prepare.EXACT)
    assert np.array_equal(image, render_scene(SCENE, precision="exact", fast_path=False))
    prepare.main([prepare.EXACT])
    assert prepare.ready(prepare.EXACT) and not prepare.ready((1, False))
    kernel_renders.clear()
    assert np.array_equal(render_scene(SCENE, precision="exact"), image)
    assert started == [[prepare.EXACT]] and kernel_renders == [1]


def test_variant_names_round_trip():
    every = [(1, False), (4, False), (0, True), prepare.EXACT, prepare.LINES]
    for variant in every:
        assert prepare.parse(prepare.name(variant)) == variant
    assert [prepare.name(v) for v in every] == ["1u", "4u", "0t", "exact", "lines"]
    assert sorted(map(prepare.name, fastpath._DRAW_TILES)) == ["0t", "0u", "1t", "1u", "4u"]


def test_a_name_that_is_no_variant_is_one_line_and_status_2(capsys):
    """A textured draw at 4 samples takes the driver of any count: there is no "4t"."""
    for text in ("4t", "2u", "x"):
        with pytest.raises(ValueError, match="no kernel variant"):
            prepare.parse(text)
    with pytest.raises(SystemExit) as exit_info:
        prepare.main(["1u", "4t"])
    assert exit_info.value.code == 2
    assert "no kernel variant '4t'" in capsys.readouterr().err


def test_a_textured_scene_at_4_samples_needs_the_driver_of_any_count():
    textured = softras.load_scene(prepare.preparation_scene(1, True, lines=False))
    assert prepare.variants(textured, 4) == {(0, True)}
    assert prepare.variants(textured, 1) == {(1, True)}
    untextured = softras.load_scene(prepare.preparation_scene(1, False, lines=False))
    assert prepare.variants(untextured, 4) == {(4, False)}


def new_specialisations(tmp_path, kernels: list[str], stages: list[str], preparation: str,
                        renders: list[dict]) -> tuple[dict, dict]:
    """In a new process (the preparation's marks in tmp_path): run
    ``preparation`` (Python, with `prepare` imported), count the compiled
    specialisations of every numba dispatcher of the named modules of
    softras.kernels and softras.pipeline (module globals, and the dicts of
    them such as `draw._DRAW_TILES`), render every scene file (JSON and
    glTF) and random lit, textured, blended and line scenes with each
    option set of ``renders``, and count again.  Returns ({name: count}
    before, after)."""
    program = f"""
import importlib, json, sys
from pathlib import Path
sys.path.insert(0, {str(Path(__file__).resolve().parent)!r})
import softras
from softras.kernels import prepare
from softras.renderer import render_scene
from test_fastpath import lit_scene, random_line_scene, random_scene

prepare.cache_dir = lambda: Path({str(tmp_path)!r})
modules = ([importlib.import_module("softras.kernels." + name) for name in {kernels!r}]
           + [importlib.import_module("softras.pipeline." + name) for name in {stages!r}])
def compiled():
    return {{name: len(d.signatures) for name, d in prepare.dispatchers(modules).items()}}
{preparation}
before = compiled()
folder = Path({str(SCENES_DIR)!r})
scenes = [softras.load_scene(p) for p in sorted([*folder.glob("*.json"), *folder.glob("*.glb")])]
scenes += [softras.load_scene(f(seed)) for seed in range(4) for f in (random_scene, random_line_scene)]
scenes += [softras.load_scene(lit_scene(seed, shading))
           for seed in range(2) for shading in ("flat", "gouraud", "phong")]
for scene in scenes:
    for options in {renders!r}:
        render_scene(scene, **options)
print(json.dumps([before, compiled()]))
"""
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=600,
                          env={**os.environ, prepare.ENV: prepare.MODE_WAIT})
    assert done.returncode == 0, done.stderr[-3000:]
    before, after = json.loads(done.stdout.splitlines()[-1])
    return before, after


def test_the_exact_preparation_reaches_every_exact_kernel(tmp_path):
    """In a new process, preparing `prepare.EXACT` compiles (or loads) every
    kernel of softras.kernels that exact precision calls, and the clipper's:
    rendering the scene files and random lit, textured, blended scenes at 1
    and 4 samples afterwards adds no compiled specialisation to any of their
    dispatchers (`new_specialisations`), into an rgba32f framebuffer too
    (its box resolve from float64 samples).  (The draws exact precision
    leaves to the stages compile the stages' own kernels, seconds, as the
    stages do.)"""
    before, after = new_specialisations(tmp_path, ["exact", "exact_lines", "interpolate", "light", "rgba32f", "setup"],
                                        ["clip"], "prepare.prepare(prepare.EXACT)",
                                        [{"precision": "exact", "samples": samples, "framebuffer": framebuffer}
                                         for samples in (None, 4) for framebuffer in ("rgba8", "rgba32f")])
    for kernel in ("_DRAW", "_setup", "_corners", "_resolve_box"):           # (called from Python)
        assert before[f"softras.kernels.exact.{kernel}"] >= 1, f"the preparation did not compile exact.{kernel}"
    for kernel in ("_SET_UP_LINES", "_COVER_LINES"):
        assert before[f"softras.kernels.exact_lines.{kernel}"] >= 1, f"the preparation did not compile {kernel}"
    assert {name: n for name, n in after.items() if n != before[name]} == {}


def test_the_gl_preparation_reaches_every_kernel_with_the_types_scenes_give(tmp_path):
    """In a new process, preparing every gl variant (the tile drivers and
    LINES) compiles (or loads) the kernels that gl precision calls and the
    stages' loops they call (the clipper, the transform, the line stage,
    the resolves), and rendering the scene files and random scenes at 1, 4
    and 8 samples afterwards adds no compiled specialisation to any of
    their dispatchers (`new_specialisations`).  numba types an array with
    whether it is read-only, and a scene's arrays are read-only or not by
    where they come from (a mesh's default vertex colours and the
    verifier's derived scenes are fresh arrays): the kernels' inputs go
    through `softras.kernels.scratch.read_only`, without which the line
    kernel, the clipper and the set-up compiled again at a user's first
    render of such a scene.  An unlit draw of a few triangles takes
    `softras.kernels.front_end`, a lit one `_setup_range` alone, and an
    MSAA picture is resolved by `_resolve_bytes` (GL's patterns) or
    `_resolve_exact` (any other), an
    rgba32f one by `softras.kernels.ops._resolve_box`: the
    preparation reaches them too."""
    before, after = new_specialisations(
        tmp_path, ["draw", "front_end", "light", "lines", "maps", "rgba32f", "setup", "texture", "texture_beyond"],
        ["clip", "ops", "rasterize", "vertex", "lines"],
        "from softras.kernels import draw\nfor variant in [*draw._DRAW_TILES, prepare.LINES]:\n"
        "    prepare.prepare(variant)",
        [{"precision": "gl"}, {"precision": "gl", "samples": 4},
         {"precision": "gl", "samples": 8, "pattern": "halton"},
         {"precision": "gl", "framebuffer": "rgba32f"}, {"precision": "gl", "samples": 4, "framebuffer": "rgba32f"}])
    for key in fastpath._DRAW_TILES:
        assert before[f"softras.kernels.draw._DRAW_TILES[{key}]"] == 1, f"the preparation missed the driver {key}"
    for kernel in ("_SET_UP_LINES", "_COVER_LINES"):
        assert before[f"softras.kernels.lines.{kernel}"] == 1, "the preparation did not compile the line kernel"
    assert before["softras.pipeline.clip.triangle_list_gl"] == 1
    assert before["softras.kernels.front_end._front_end"] == 1, "the preparation missed the front end in one call"
    assert before["softras.pipeline.ops._resolve_bytes"] == 1, "the preparation did not compile the MSAA resolve"
    assert before["softras.kernels.rgba32f._resolve_box"] == 1, "the preparation missed the rgba32f resolve"
    assert {name: n for name, n in after.items() if n != before[name]} == {}


def test_one_process_prepares_a_variant_at_a_time(fresh_cache, monkeypatch):
    """While another process holds a variant's lock, no second background
    process is started for it; once free, one is (here: not really started)."""
    spawned = []
    monkeypatch.setattr(prepare.subprocess, "Popen", lambda args, **kw: spawned.append(args))
    with prepare._locked((1, False)) as held:
        assert held
        assert not prepare.start_background([(1, False)])
    assert spawned == []
    assert prepare.start_background([(1, False), (0, True)])
    assert spawned[0][-2:] == ["1u", "0t"] and spawned[0][1:3] == ["-m", "softras.kernels.prepare"]


def test_a_compile_runs_no_full_collection_and_one_after(fresh_cache, monkeypatch):
    """While `prepare` compiles, Python's garbage collector runs no full
    collection (each walked every long-lived object numba had made: 5 s
    of a 27 s compile), then one, which frees what died old, and its
    thresholds are as they were.  The compile here leaves 200k lists in
    cycles that live through the young collections, as numba's IR does:
    enough for several full collections under the default thresholds."""
    full = []

    def on_collection(phase, info):
        if phase == "stop" and info["generation"] == 2:
            full.append((compiling, info["collected"]))

    def compile_(variant):
        nonlocal compiling
        compiling = True
        kept = []
        for _ in range(200_000):
            node = []
            node.append(node)
            kept.append(node)
        kept.clear()
        compiling = False

    compiling = False
    thresholds = gc.get_threshold()
    monkeypatch.setattr(prepare, "_compile", compile_)
    gc.callbacks.append(on_collection)
    try:
        assert prepare.prepare((1, False))
    finally:
        gc.callbacks.remove(on_collection)
    assert len(full) == 1 and not full[0][0] and full[0][1] >= 200_000
    assert gc.get_threshold() == thresholds and prepare.ready((1, False))


def test_the_prepare_command_freezes_what_each_variant_left(fresh_cache, monkeypatch):
    """``python -m softras.kernels.prepare`` compiles its variants one after
    another in one process: what a compile left alive (numba's compiled
    objects) is frozen before the next compile, whose collections then do
    not walk it again."""
    kept, frozen = [], []

    def compile_(variant):
        frozen.append(gc.get_freeze_count())
        kept.append([[] for _ in range(50_000)])      # (no cycles: freed by reference counting after the test)

    monkeypatch.setattr(prepare, "_compile", compile_)
    try:
        assert prepare.main(["1u", "4u"]) == 0
        assert frozen[1] - frozen[0] >= 50_000
    finally:
        kept.clear()


def test_the_prepare_command_marks_its_variants(fresh_cache):
    assert prepare.main(["1u"]) == 0
    assert prepare.ready((1, False)) and not prepare.ready((1, True))


def test_an_edit_of_the_kernels_prepares_again(fresh_cache, monkeypatch):
    """The mark's name holds the sources' digest: another digest is not ready."""
    prepare.main(["1u"])
    monkeypatch.setattr(prepare, "_stamp", lambda: "0123456789abcdef")
    assert not prepare.ready((1, False))


@pytest.mark.parametrize("variant", [(1, False), (0, True), prepare.EXACT, prepare.LINES], ids=prepare.name)
def test_a_mark_over_another_version_s_compiled_code_is_not_ready(fresh_cache, monkeypatch, variant):
    """The mark is there but numba's index of the variant's kernel was
    written for another version of its source file (a checkout of another
    version, a render, a checkout back: numba keeps the last version's
    index only): not ready, so that the preparation, not the first render,
    compiles it again."""
    prepare.prepare(variant)
    assert prepare.ready(variant)
    kernel = prepare.main_kernels(variant)[0]
    with monkeypatch.context() as patch:
        patch.setattr(kernel._cache._cache_file, "_source_stamp", b"another version of the file")
        patch.setattr(prepare, "_marks_seen", set())
        assert not prepare.ready(variant)
    monkeypatch.setattr(prepare, "_marks_seen", set())
    assert prepare.ready(variant)


def test_an_index_written_anew_for_another_driver_leaves_this_one_not_ready(fresh_cache, monkeypatch):
    """The tile drivers are one function with different closure values, one
    numba index: current, but holding only another driver's entries (that
    driver compiled after an edit and its undoing), this one is not ready."""
    prepare.prepare((1, False))
    prepare.prepare((4, False))
    assert prepare.ready((4, False))
    (mine,), (other,) = prepare.main_kernels((4, False)), prepare.main_kernels((1, False))
    cache_file = mine._cache._cache_file
    index = cache_file._load_index()
    own = mine._cache._index_key(None, mine.targetctx.codegen())[1:]
    theirs = other._cache._index_key(None, other.targetctx.codegen())[1:]
    assert any(key[1:] == own for key in index) and any(key[1:] == theirs for key in index)
    monkeypatch.setattr(cache_file, "_load_index", lambda: {k: v for k, v in index.items() if k[1:] != own})
    monkeypatch.setattr(prepare, "_marks_seen", set())
    assert not prepare.ready((4, False))


def test_an_unknown_mode_is_refused(monkeypatch):
    monkeypatch.setenv(prepare.ENV, "soon")
    with pytest.raises(ValueError, match="SOFTRAS_COMPILE='soon': expected one of wait, background"):
        prepare.mode()


def test_the_cache_keys_cover_the_stage_kernels_the_kernels_inline(monkeypatch):
    """numba's cache checks only a kernel's own file: the tile drivers' key
    (`softras.kernels.draw._SOURCES`) must change with pipeline/ops.py,
    pipeline/texture.py and pipeline/texture_beyond.py, whose kernels they
    inline (pipeline/rasterize.py's sample box is computed in Python, once
    a pass) (the last through softras's filters,
    `softras.kernels.texture_beyond._beyond_texel`, keyed so too), and
    pipeline/libm.py (the Phong kernels' pow), the line
    kernel's with pipeline/lines.py, ops.py and rasterize.py, and the exact
    kernel's with pipeline/rasterize.py, pipeline/ops.py,
    pipeline/texture.py, pipeline/libm.py and pipeline/texture_beyond.py, and Gouraud's and flat
    shading's lighting loops' with pipeline/libm.py
    (`softras.kernels.stamp.sources_stamp`)."""
    from softras.kernels import exact as k_exact
    from softras.kernels import light as k_light
    from softras.kernels import lines as k_lines
    from softras.kernels import stamp
    from softras.kernels import texture_beyond as k_beyond
    from softras.pipeline import libm, ops, rasterize, texture_beyond

    def key(kernel):
        return [cell.cell_contents for cell in kernel.py_func.__closure__]

    line_key = key(k_lines._SET_UP_LINES)
    assert key(k_lines._COVER_LINES) == line_key
    exact_key = key(k_exact._DRAW)
    assert fastpath._SOURCES == stamp.sources_stamp(ops, texture, libm, texture_beyond)
    assert line_key == [stamp.sources_stamp(lines, ops, rasterize, clip_stage)]
    assert exact_key == [stamp.sources_stamp(rasterize, ops, texture, libm, texture_beyond)]
    for kernel in (k_exact._ANISOTROPIC, k_exact._PHONG, k_exact._UV_AT, k_exact._TEXELS, k_exact._MAP_TEXELS):
        assert key(kernel) == exact_key, kernel
    assert key(k_beyond._beyond_texel) == [stamp.sources_stamp(texture, libm, texture_beyond)]
    for loop in (k_light._vertex_lighting, k_light._face_lighting):
        assert [cell.cell_contents for cell in loop.py_func.__closure__] == [stamp.sources_stamp(libm)]
    from softras.pipeline import cache_key

    monkeypatch.setattr(cache_key, "_key", cache_key._key.__wrapped__)     # (read the files each time)
    read_bytes = Path.read_bytes
    for module, modules in ((ops, (ops, texture, rasterize)), (texture, (ops, texture, rasterize)),
                            (rasterize, (ops, texture, rasterize)), (lines, (lines, ops, rasterize)),
                            (clip_stage, (lines, ops, rasterize, clip_stage)),
                            (libm, (ops, texture, rasterize, libm)),
                            (texture_beyond, (ops, texture, rasterize, libm, texture_beyond)),
                            (k_lines, ()), (k_light, ())):
        before = stamp.sources_stamp(*modules)
        edited = Path(module.__file__)
        monkeypatch.setattr(Path, "read_bytes", lambda self: read_bytes(self) + (b"#" if self == edited else b""))
        assert stamp.sources_stamp(*modules) != before, module.__name__
        monkeypatch.setattr(Path, "read_bytes", read_bytes)
    # The exact kernels are inlined nowhere: their edits leave the other keys
    # alone (numba's cache checks their own files).
    from softras.kernels import exact_lines as k_exact_lines
    for module in (k_exact, k_exact_lines):
        before = stamp.sources_stamp(ops, texture, rasterize)
        edited = Path(module.__file__)
        monkeypatch.setattr(Path, "read_bytes", lambda self: read_bytes(self) + (b"#" if self == edited else b""))
        assert stamp.sources_stamp(ops, texture, rasterize) == before, module.__name__
        monkeypatch.setattr(Path, "read_bytes", read_bytes)


def _cached_kernels():
    """Every compiled function of softras that numba caches on disk for
    itself: ``cache=True`` and not ``inline="always"`` (an inlined function
    is compiled into its callers, under their keys), found in the modules'
    globals and in the dicts and tuples there (the tile drivers)."""
    import importlib
    import pkgutil

    modules = [importlib.import_module(info.name) for info in pkgutil.walk_packages(softras.__path__, "softras.")
               if info.name not in ("softras.__main__", "softras.pytest_plugin")]
    found = {}
    for item in prepare.dispatchers(modules).values():
        if (item.py_func.__module__.startswith("softras.") and type(item._cache).__name__ != "NullCache"
                and item.targetoptions.get("inline") != "always"):
            found[id(item)] = item
    return list(found.values())


def _reached(kernel):
    """The compiled functions that ``kernel``'s code calls or inlines, at any
    depth: the dispatchers its code names (a global, a module's attribute,
    a closure variable), theirs, and so on."""
    import types

    from numba.core.registry import CPUDispatcher

    seen, todo = {}, [kernel]
    while todo:
        function = todo.pop().py_func
        codes, names = [function.__code__], set()
        while codes:
            code = codes.pop()
            names |= set(code.co_names)
            codes += [const for const in code.co_consts if isinstance(const, types.CodeType)]
        values = [function.__globals__.get(name) for name in names]
        values += [getattr(value, name, None) for value in list(values)
                   if isinstance(value, types.ModuleType) and value.__name__.startswith("softras.")
                   for name in names]
        values += [cell.cell_contents for cell in function.__closure__ or ()]
        for value in values:
            if isinstance(value, CPUDispatcher) and id(value) not in seen:
                seen[id(value)] = value
                todo.append(value)
    return list(seen.values())


def test_every_cached_kernel_is_keyed_on_the_compiled_code_it_reaches():
    """numba's cache checks a kernel's own source file alone, but the cached
    code holds everything the kernel calls or inlines: a cached kernel that
    reaches another module's compiled code must be made with a key of that
    module's source as a closure variable (`softras.pipeline.cache_key`),
    or an edit of that module alone would load it stale."""
    from softras.pipeline import cache_key

    kernels = _cached_kernels()
    assert len(kernels) > 50                           # (the scan sees softras's kernels)
    problems = []
    for kernel in kernels:
        own = Path(sys.modules[kernel.py_func.__module__].__file__)
        files = {Path(sys.modules[callee.py_func.__module__].__file__) for callee in _reached(kernel)} - {own}
        keys = [cell.cell_contents for cell in kernel.py_func.__closure__ or ()
                if isinstance(cell.cell_contents, str)]
        covered = {name for key in keys for name in cache_key.covered(key)}
        missing = sorted(path.resolve().relative_to(cache_key.PACKAGE).as_posix() for path in files)
        missing = [name for name in missing if name not in covered]
        if missing:
            problems.append(f"{kernel.py_func.__module__}.{kernel.py_func.__qualname__}: {', '.join(missing)}")
    assert problems == []


def test_a_normal_or_bump_map_needs_the_textured_driver():
    """A mapped draw without a colour texture still takes the textured tile
    driver (its quads give the map's derivatives): the variant prepared for
    it is the textured one."""
    scene = softras.load_scene(SCENES_DIR / "bump_mapped_plane.json")
    assert any(d.material.bump_map is not None and d.material.texture is None for d in scene.draws)
    assert prepare.variants(scene, 1) == {(1, True)}
    assert prepare.variants(scene, 4) == {(0, True)}
