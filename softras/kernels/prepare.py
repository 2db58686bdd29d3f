"""Preparing the compiled kernels: once per machine, in the background or now.

numba compiles the kernels of `softras.kernels.draw` the first time a
process needs them and keeps them in its on-disk cache; on a fresh clone
(one core, each variant in a new process, one after another) that takes
10-25 s per tile-driver variant (a sample count, textured or not; the
first pays for the set-up, clipping and lighting kernels they share, the
textured ones for the filters and maps), ~25 s for the exact kernels
(`softras.kernels.exact`, the variant `EXACT`) and ~7 s for the gl line
kernel (`softras.kernels.lines`, the variant `LINES`): ~2.1 minutes in
all with `softras.pipeline.numba_fixes` (3.5 minutes with its first two
fixes only; docs/speed.md, "Twenty-seventh round" and "Thirty-eighth
round").  The readable stages give the
same bytes (tests/test_fastpath.py, tests/test_exact_path.py) and
compile in seconds, so a render need not wait: `ensure` either

- "background" (`MODE_BACKGROUND`): when a variant the scene needs is not
  ready, starts one detached process (``python -m softras.kernels.prepare``,
  at low priority) that compiles it into numba's cache, and tells the caller
  to render this scene with the stages; a later render (this process or
  another) finds the variant ready and takes the kernels; or
- "wait" (`MODE_WAIT`): compiles the missing variants now, in this process,
  before the render (tests, benchmarks: anything that must time or check
  the compiled path).

Either way each variant is compiled by one process at a time (an exclusive
lock per variant: a second process waits for the first and then loads from
the cache), by rendering `preparation_scene`, which reaches every kernel of
the variant (the parallel set-up, the clipper, flat, Gouraud and Phong
colours, the texture filters), and then marked ready by a file beside the
lock.  The mark's name holds a digest of softras's kernel sources, numba's
version and the host CPU: an edit or an upgrade prepares again.  A mark
counts only while numba's index of the variant's main kernels is current
and holds them (`_cached`: not cleared, not left by another version of
the sources);
one of the smaller kernels missing from numba's cache costs a compile in
the render, as before, not a wrong picture.

``SOFTRAS_COMPILE=wait|background`` chooses the mode (default: background;
the test suite's conftest and `softras bench` wait).
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import functools
import gc
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np

from softras.pipeline.cache_key import PACKAGE, sources_key

MODE_WAIT, MODE_BACKGROUND = "wait", "background"
MODES = (MODE_WAIT, MODE_BACKGROUND)
ENV = "SOFTRAS_COMPILE"

# A variant is a tile driver's (driver samples, textured), EXACT: the
# exact-precision kernels, one compiled set for every scene, or LINES: the
# gl-precision line kernel, one for every line draw.
EXACT = "exact"
LINES = "lines"
_NAMED = (EXACT, LINES)


def mode() -> str:
    """The preparation mode: ``SOFTRAS_COMPILE`` or "background"; any other
    value is a ValueError naming the choices."""
    value = os.environ.get(ENV, MODE_BACKGROUND)
    if value not in MODES:
        raise ValueError(f"{ENV}={value!r}: expected one of {', '.join(MODES)}")
    return value


def variants(scene, samples: int) -> set:
    """The variants that a scene which `softras.kernels.draw.unsupported`
    accepts needs at ``samples`` drawn in the stages' passes: the tile
    drivers (driver samples, textured) of its triangle draws
    (`softras.kernels.draw.driver_samples` of each pass: 1, 4 (untextured),
    or 0 for any other count), and LINES if it draws lines (a wireframe alone waited 20-40 s
    for the line kernel, silently, when it was compiled in the render)."""
    from softras.kernels.draw import driver_samples, textured
    from softras.pipeline.sampling import sample_passes

    kinds = {textured(draw.material) for draw in scene.draws if draw.mesh.primitive == "triangles"}
    needed = {(driver_samples(stop - start, kind), kind) for start, stop in sample_passes(samples) for kind in kinds}
    if any(draw.mesh.primitive == "lines" for draw in scene.draws):
        needed.add(LINES)
    return needed


@functools.cache
def _stamp() -> str:
    """What the compiled code depends on: the kernels' sources (the drivers'
    own stamp, `softras.kernels.draw._SOURCES`, and the exact kernels',
    kernels/exact.py and kernels/exact_lines.py), the stages' (numba loops
    of their own, and functions the kernels inline), numba's version, the
    host CPU (numba compiles for it)."""
    import llvmlite.binding as llvm

    from softras.kernels import draw

    sources = sources_key([*PACKAGE.glob("pipeline/*.py"), PACKAGE / "kernels" / "exact.py",
                           PACKAGE / "kernels" / "exact_lines.py"])
    text = f"{numba.__version__}\0{llvm.get_host_cpu_name()}\0{draw._SOURCES}\0{sources}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cache_dir() -> Path:
    """Where the ready marks and locks live: numba's cache directory
    (``NUMBA_CACHE_DIR``) or the kernels' ``__pycache__``, where numba keeps
    their compiled code."""
    if numba.config.CACHE_DIR:
        return Path(numba.config.CACHE_DIR)
    return _own_cache_dir()


@functools.cache
def _own_cache_dir() -> Path:
    # (Once: resolving the path took 0.1 ms, asked for by every render.)
    return Path(__file__).resolve().parent / "__pycache__"


def name(variant) -> str:
    """A variant's name in marks and on the command line: "1u" (1 sample,
    untextured), "4u" (4, untextured), "1t" (1, textured), "0t" (any other
    count, textured), "exact" or "lines"."""
    if variant in _NAMED:
        return variant
    samples, textured = variant
    return f"{samples}{'t' if textured else 'u'}"


def parse(text: str):
    """The variant named ``text`` (`name`'s inverse); ValueError for a name
    that is no variant (the tile drivers are `softras.kernels.draw._DRAW_TILES`' keys)."""
    from softras.kernels import draw

    if text in _NAMED:
        return text
    known = {name(v): v for v in draw._DRAW_TILES}
    if text not in known:
        raise ValueError(f"no kernel variant {text!r}: expected one of "
                         f"{', '.join(sorted(known) + list(_NAMED))}")
    return known[text]


def _mark(variant) -> Path:
    return cache_dir() / f"softras-ready-{_stamp()}-{name(variant)}"


_marks_seen: set[Path] = set()


def ready(variant) -> bool:
    """Whether ``variant`` ((samples, textured), EXACT or LINES) has been prepared on this
    machine: its mark is there and numba's cache holds its kernels for
    their sources as they are now (`_cached`).  A variant found ready is
    not looked up again in this process."""
    mark = _mark(variant)
    if mark not in _marks_seen and mark.exists() and _cached(variant):
        _marks_seen.add(mark)
    return mark in _marks_seen


def _cached(variant) -> bool:
    """Whether numba's on-disk cache holds the variant's main kernels (the
    tile driver; the line kernel; exact's draw and line kernels) compiled
    from their source files as they are now (`_in_index`).  numba keeps one
    index per function, for the last version of its file that it compiled:
    after a checkout of another version of softras, a render and a
    checkout back, the mark (keyed on the sources too) is there but the
    index is the other version's, and the first render compiled the driver
    again, even in the background mode.  And the five tile drivers are one
    function (`softras.kernels.draw._make_draw_tiles`'s closure): an index
    written anew for one of them holds none of the others."""
    return all(_in_index(kernel) for kernel in main_kernels(variant))


def main_kernels(variant) -> tuple:
    """The numba dispatchers a variant is prepared for: its tile driver
    (`softras.kernels.draw._DRAW_TILES`), the gl line kernel's two passes,
    or exact's draw kernel and its line kernel's two passes."""
    if variant == EXACT:
        from softras.kernels import exact, exact_lines

        return exact._DRAW, exact_lines._SET_UP_LINES, exact_lines._COVER_LINES
    if variant == LINES:
        from softras.kernels import lines

        return lines._SET_UP_LINES, lines._COVER_LINES
    from softras.kernels import draw

    return (draw._DRAW_TILES[variant],)


def _in_index(kernel) -> bool:
    """Whether numba's cache index of the dispatcher ``kernel`` is current
    and has an entry for its code and closure values, for any signature
    (numba's own keys: `Cache._index_key` without the signature, and
    `IndexDataCacheFile._load_index`, empty when the index is missing, of
    another numba version or stale)."""
    cache = kernel._cache
    _, magic, code = cache._index_key(None, kernel.targetctx.codegen())
    return any(key[1:] == (magic, code) for key in cache._cache_file._load_index())


@contextlib.contextmanager
def _full_collections_held_off():
    """Python's full garbage collections held off for the block, and one
    run after it.  numba's compilation leaves hundreds of thousands of
    long-lived objects (its type and overload caches, typed IR, llvmlite's
    wrappers: ~750k after one variant in a fresh cache), and Python runs a
    full collection, which walks every one of them, each time the objects
    that survived the young generations have grown by a quarter: 20 full
    collections, 5.0 s of a 27 s compile of the 4u variant.  The young
    generations still collect (most of numba's garbage dies young); what
    reaches the oldest one is collected once, at the end.  The 4u variant
    in a fresh cache: 27.2-27.5 s, 22.6-24.5 s so; peak memory 446 -> 550
    MB.  All seven variants in one process: 128-129 s, 111-119 s so
    (docs/speed.md, "Fortieth round").  Not the loader's
    `softras.scene.parse.collector_paused`, the collector off altogether:
    numba's young garbage then piles up too (4u: 23.4-24.2 s, 648 MB), and
    that pause leaves the old garbage to the next collection."""
    thresholds = gc.get_threshold()
    gc.set_threshold(thresholds[0], thresholds[1], 1 << 30)
    try:
        yield
    finally:
        gc.set_threshold(*thresholds)
        gc.collect()


@contextlib.contextmanager
def _locked(variant, blocking: bool = True):
    """An exclusive lock on preparing ``variant``: yields True when held,
    False when another process holds it and ``blocking`` is False."""
    path = _mark(variant).with_suffix(".lock")
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _frame() -> dict:
    """The preparation scenes' picture and camera (the near plane 0.5 in
    front of the eye), a new dict each time."""
    return {"softras_scene": 1, "width": 64, "height": 48,
            "camera": {"projection": "perspective", "fov_y": 60, "near": 0.5, "far": 20,
                       "eye": [0, 0, 1], "target": [0, 0, 0]}}


def preparation_scene(samples: int, textured: bool, lines: bool = True) -> dict:
    """A small scene that reaches every kernel of one variant: lit grids of
    18432 triangles, over PARALLEL_SETUP of them inside the frustum (the
    parallel set-up, `softras.kernels.setup.PARALLEL_SETUP`), crossing the
    near plane (the clipper), drawn unlit, flat, Gouraud and
    Phong, textured with a mipmapped filter (the lane filter) and a nearest
    one (the scalar filter) when ``textured``, blended and depth-tested; two
    draws of two triangles, unlit (its front end in one call,
    `softras.kernels.front_end`) and Gouraud-shaded (set up in one call,
    `softras.kernels.setup._setup_range`, which a lit draw under
    PARALLEL_SETUP triangles calls directly); and with ``lines`` the draw
    of `line_preparation_scene`."""
    from softras.kernels.setup import PARALLEL_SETUP

    cols = 2 * int(np.ceil(np.sqrt(PARALLEL_SETUP / 2)))     # (about half of it is inside the frustum)
    nodes = []
    for k, shading in enumerate(("unlit", "flat", "gouraud", "phong")):
        material = {"shading": shading}
        if textured:
            material["texture"] = "linear" if k % 2 else "nearest"
        nodes.append({"name": shading, "rotate": [-80, 1, 0, 0], "translate": [0.3 * k - 0.45, -0.5, 0],
                      "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [4, 8]},
                      "material": material, "blend": "over" if k == 3 else "none"})
    for k, shading in enumerate(("unlit", "gouraud")):           # (textured too: the same variant)
        nodes.append({"name": f"few_{shading}", "translate": [0.6 * k - 0.3, 0, -1],
                      "mesh": {"procedural": "grid", "cols": 1, "rows": 1, "size": [0.5, 0.5]},
                      "material": {"shading": shading, **({"texture": "nearest"} if textured else {})}})
    if lines:
        nodes += line_preparation_scene()["nodes"]
    textures = {name: {"procedural": "checker", "size": [16, 16], "min_filter": name + "_mipmap_linear"
                       if name == "linear" else name}
                for name in (("linear", "nearest") if textured else ())}
    return {**_frame(), "samples": samples, "textures": textures,
            "lights": [{"type": "point", "position": [1, 2, 3]}, {"type": "directional", "direction": [0, -1, 0]}],
            "nodes": nodes}


def line_preparation_scene() -> dict:
    """A scene of lines crossing the near plane: the line kernels
    (`softras.kernels.lines`, `softras.kernels.exact_lines`) and the line
    clipper's compiled loop."""
    return {**_frame(),
            "nodes": [{"name": "lines", "mesh": {"primitive": "lines", "indices": [[0, 1], [2, 3]],
                                                 "positions": [[-1, -0.5, 0.9], [1, 0.4, -3], [1, -0.3, 0.95],
                                                               [-1, 0.2, -2]]}}]}


def prepare(variant, wait: bool = True, freeze: bool = False) -> bool:
    """Compile ``variant`` now unless it is ready: under its lock, render
    `preparation_scene` on the compiled path (a tile driver (driver
    samples, textured): in gl precision, without lines, at 2 samples for
    the driver of any count, and above one sample both box resolves of
    its samples, `softras.pipeline.render.resolve_bytes`' compiled loops,
    and an rgba32f framebuffer's box resolve of float32 samples
    (`softras.kernels.ops._resolve_box`); EXACT: textured, in exact
    precision, and the rgba32f resolve of float64 samples) or LINES
    `line_preparation_scene` (gl precision), then mark it ready.  Returns
    whether it is ready; False only when ``wait`` is False and another
    process holds the lock (is preparing it): then nothing is done.

    freeze : after a compile and its full collection, what this process
    holds is frozen (`gc.freeze()`): what the compile left alive lives as
    long as the process, and the next variant's collections then do not
    walk it again (four variants in a fresh cache: the collector's time
    10.5 -> 7.4 s, docs/speed.md, "Forty-first round").  Only for the
    processes of softras's own that compile several variants in a row (the
    prepare command, the test suite's workers), never a user's."""
    if ready(variant):
        return True
    with _locked(variant, blocking=wait) as held:
        if not held:
            return False
        if ready(variant):                      # prepared by the process we waited for
            return True
        with _full_collections_held_off():
            _compile(variant)
        if freeze:
            gc.freeze()
        _mark(variant).touch()
    return True


def _compile(variant) -> None:
    """Render what reaches every kernel of ``variant`` (`prepare`), which
    numba compiles (or loads from its cache)."""
    from softras.kernels import draw
    from softras.kernels import ops as kernel_ops
    from softras.pipeline import ops, sampling
    from softras.scene import load_scene

    if variant == EXACT:
        from softras.kernels import exact
        from softras.pipeline import render as stages

        scene = load_scene(preparation_scene(1, True))
        job = stages.Job.of(scene, precision="exact", samples=None, pattern=None, seed=0, resolve_filter="box",
                            framebuffer=None, clipping=None, texture_fixed_point=True, texture_filter=None,
                            texture_bounds=None, tie_rule="left_bottom")
        exact.resolve(job, exact.render_samples(scene, job, reuse=True))
        kernel_ops._resolve_box(np.zeros((1, 1, 2, 4)), np.empty((1, 1, 4), np.float32))
    elif variant == LINES:
        # (One sample: MSAA's rectangular lines are the same compiled
        # function, a flag at run time.)
        draw.render_samples(load_scene(line_preparation_scene()), sampling.sample_positions(1))
    else:
        samples, textured = variant
        positions = (sampling.sample_positions(samples) if samples else
                     sampling.sample_positions(2, "halton"))          # (`softras.kernels.draw.ANY_SAMPLES`)
        scene = load_scene(preparation_scene(samples or 1, textured, lines=False))    # (a scene has 1 or 4)
        assert draw.unsupported(scene, precision="gl", clipping=None) is None
        stored = draw.render_samples(scene, positions)
        if len(positions) == 1:     # (a one-sample picture's copy, `softras.kernels.ops._tiles_out`)
            draw.render_picture(scene, positions)
        if len(positions) > 1:      # the box resolves: llvmpipe's (GL's patterns) and the exact mean's
            ops.resolve_llvmpipe_bytes(stored)
            ops.resolve_exact_bytes(stored)
        # An rgba32f framebuffer's box resolve (its colours and writes
        # are the driver's own, `softras.kernels.rgba32f._float_fragments`).
        kernel_ops._resolve_box(np.zeros((1, 1, 2, 4), np.float32), np.empty((1, 1, 4), np.float32))


# Called with `NOTICE` when a render starts a background preparation (the
# command line prints it on a terminal); None: say nothing.
announce = None
NOTICE = ("softras: compiling the rendering kernels for this machine in the background (about a "
          "minute, once); until they are ready, softras renders with its readable stages (the same bytes)")


def start_background(variants) -> bool:
    """Start one detached, low-priority process that prepares ``variants``
    unless another process is preparing them already.  Returns whether one
    was started."""
    missing = []
    for variant in variants:
        with _locked(variant, blocking=False) as free:
            if free and not ready(variant):
                missing.append(variant)
    if not missing:
        return False
    args = [name(variant) for variant in missing]
    subprocess.Popen([sys.executable, "-m", "softras.kernels.prepare", *args], stdin=subprocess.DEVNULL,
                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                     env={**os.environ, ENV: MODE_WAIT})
    if announce is not None:
        announce(NOTICE)
    return True


def ensure(variants, stages_can_draw: bool = True) -> bool:
    """Make the compiled kernels of ``variants`` usable for a render, per
    `mode`.  Returns True when the render may take them (ready, or prepared
    now), False when it should use the stages this time (a background
    process is preparing them).  stages_can_draw : whether the stages can
    draw the scene at all (their sample buffers are larger); if not, the
    kernels are prepared now in either mode."""
    variants = sorted(set(variants), key=name)
    if all(ready(v) for v in variants):
        return True
    if mode() == MODE_BACKGROUND and stages_can_draw:
        start_background(variants)
        return False
    for variant in variants:
        prepare(variant)
    return True


def dispatchers(modules) -> dict:
    """{name: numba dispatcher} of the compiled functions that ``modules``
    hold at module level: each global, and each value of a module-level
    dict or tuple (the tile drivers in `softras.kernels.draw._DRAW_TILES`),
    named "module.global" or "module.global[key]".  A function that several
    modules import is there under each name.  (What the preparation must
    reach: tests/test_prepare.py counts their specialisations;
    scripts/compile_profile.py reports their compile times.)"""
    found = {}
    for module in modules:
        for name, value in vars(module).items():
            items = (value.items() if isinstance(value, dict) else
                     enumerate(value) if isinstance(value, tuple) else [(None, value)])
            for key, item in items:
                if isinstance(item, numba.core.registry.CPUDispatcher):
                    found[f"{module.__name__}.{name}" + ("" if key is None else f"[{key}]")] = item
    return found


def main(argv: list[str] | None = None) -> int:
    """``python -m softras.kernels.prepare 1u 0t exact lines ...``: prepare the
    variants (`name`: samples, then u untextured or t textured; exact; lines)
    at low priority."""
    parser = argparse.ArgumentParser(prog="python -m softras.kernels.prepare", description=main.__doc__)
    parser.add_argument("variants", nargs="+",
                        help="e.g. 1u (1 sample, untextured), 4u (4, untextured), 0t (any other count, "
                             "textured), exact (the exact-precision kernels) or lines (the gl line kernel)")
    args = parser.parse_args(argv)
    try:
        chosen = [parse(text) for text in args.variants]
    except ValueError as error:
        parser.error(str(error))                # (one line, exit status 2)
    for variant in chosen:
        prepare(variant, freeze=True)
    return 0


if __name__ == "__main__":
    with contextlib.suppress(OSError):
        os.nice(10)                 # (behind the renders of the process that started it)
    sys.exit(main())
