"""``softras bench``: speed and error of softras's quality levels against glref.

What is measured
----------------
Every figure is taken in one process, warm (one untimed render first, so
kernels are compiled and caches filled), as the median of timed renders,
each softras render paired with a glref render of the same scene, the two
interleaved (`_paired_times`: at least ``runs`` pairs, and `MIN_PAIRS`
where they fit in `PAIR_BUDGET` seconds), so that both see the same state
of a noisy machine and their ratio compares like with like.  glref
renders at the level's sample count where GL has it (``gl_msaa4`` on a
1-sample scene is timed against glref's 4x MSAA), else at the scene's own
(exact and softras's own patterns: "gl ms" is then the scene's GL render, a
reference point, not the same work).  A render is timed end to end from the
loaded `Scene` to the image (``softras.render(scene, **options)``; for glref
``softras.render(scene, backend="gl")``, which includes its upload and
readback).  The figure that matters to a user is end to end *from the scene file*: for
the gl level (`E2E_LEVEL`) each row also carries ``file_seconds`` and
``glref_file_seconds``, the medians of ``softras.render(load_scene(path))``
and of ``softras.render(load_scene(path), backend="gl")`` on the scene written
to a temporary JSON file (parsing, procedural meshes and textures, mip chains
and every upload included: the shared scene layer does the same work for
both renderers), and ``file_ratio``, from interleaved pairs too.

Error is measured against one ground truth that favours no level
(`truth_image`): the scene supersampled in exact precision with the texture
as a continuous function, bilinear on level 0 at every sample, no mipmaps
(`softras.verification.ground_truth.supersampled_reference`, the truth of
docs/textures_and_lighting.md), `truth_factor` x `truth_factor` samples per
pixel on a regular grid, as many as keep the supersampled picture within
`TRUTH_MAX_SIDE` pixels a side (16x16 on a 128-pixel scene, 4x4 at 512, 2x2
at 1024; no error figures beyond).  A truth rendered with one of the levels'
own filters would score that filter best: the former truth, ``exact`` at 16
rotated-grid samples with trilinear filtering, put ripmap and EWA behind
trilinear on the floor.  For each level we report the mean absolute
difference (per channel, in /255) and the fraction of pixels with a channel
off by more than 2/255.

Memory: ``peak_mib`` is the peak of Python-tracked allocations during one
extra (untimed) render, measured with ``tracemalloc``: numpy arrays and
Python objects, including every array the pipeline and the fast path create
from Python, plus the fast path's per-thread reused buffers (set-up
tables, corner attributes, depth and colour buffers: about 400 bytes per
triangle and 12 per sample), which a warm render no longer allocates but
still holds.  Arrays allocated *inside* numba kernels (numba's own
allocator: the kernels' small per-tile scratch) are not included.  ``rss_mib`` is the
process's peak resident set size so far (``resource.getrusage``, monotone,
process-wide: it includes glref and every earlier scene).

Levels and scenes
-----------------
`LEVELS` is the table of quality levels: one line each (name, render
options, which scenes it applies to, whether the quick run includes it).
Options a renderer does not know make a level "n/a" on that build, not an
error.  `SCENES` are generated here: many small triangles (a tessellated,
perspective-tilted vertex-coloured grid), few large ones, a trilinear
textured floor, 4x MSAA, translucent layers blended "over"; stand-ins for
real content, gl level only (a lumpy scan-like sphere of 71k triangles lit
with Phong and with Gouraud shading, a Gouraud mesh at 4x MSAA, a
flat-shaded 6k mesh, a textured Phong model at 1024^2, an 8k-line
wireframe: `lit_scene`, `lines_scene`); the scaling sweeps vary triangles
(1k to 1M) at 512^2 and pixels (256^2 to 2048^2) at about 2k triangles, gl
level only, and fit ``time ~ n^k`` by least squares on log-log (k near 1 is
linear).

The loader
----------
``loader`` (`loader_times`): the median time of ``softras.load_scene`` on a
scene whose mesh is written out as explicit arrays (the 24k- and
100k-triangle grids, `explicit_grid_scene`), against ``json.load`` of the
same file, interleaved, each after a full garbage collection and both
without the collector's runs (load_scene pauses it while it parses,
`softras.scene.parse.collector_paused`; json.load is timed with it
paused too: its runs over the objects that earlier renders left took
json.load of the 100k grid from 250 to 465 ms in one bench run), and
their ratio: what validation and conversion cost beyond reading the JSON
at all.
"""

from __future__ import annotations

import contextlib
import gc
import json
import math
import os
import resource
import statistics
import tempfile
import time
import tracemalloc
from dataclasses import asdict, dataclass

import numpy as np

from softras.bench_scenes import blended_scene, floor_scene, grid_scene, lines_scene, lit_scene, parts_scene
from softras.scene.parse import collector_paused


@dataclass(frozen=True)
class Level:
    """One quality level: softras render options, and where it applies."""

    name: str
    options: dict
    description: str
    textured_only: bool = False       # only meaningful on scenes with a texture
    quick: bool = True                # part of the default (quick) run
    max_pixels: int = 1 << 22         # skip on larger images (memory / time)


EXACT_16 = {"precision": "exact", "samples": 16, "pattern": "rotated_grid"}
TRUTH_MAX_SIDE = 2048   # the supersampled truth's largest side (memory: the exact stages hold every fragment)
E2E_LEVEL = "gl"        # the level also timed end to end from the scene file

LEVELS = [
    Level("gl", {"precision": "gl"}, "gl precision at the scene's samples (llvmpipe bit for bit)"),
    Level("exact", {"precision": "exact"}, "float64, unsnapped, the scene's samples"),
    Level("gl_msaa4", {"precision": "gl", "samples": 4}, "gl precision, llvmpipe's 4x MSAA"),
    Level("gl_16", {"precision": "gl", "samples": 16, "pattern": "rotated_grid"},
          "gl precision, 16 samples, rotated grid (the compiled path's driver of any count)"),
    Level("exact_16", EXACT_16, "exact, 16 samples, rotated grid", max_pixels=1 << 20),
    Level("exact_64", {"precision": "exact", "samples": 64, "pattern": "rotated_grid"},
          "exact, 64 samples, rotated grid", quick=False, max_pixels=1 << 18),
    Level("gl_rgba32f", {"precision": "gl", "framebuffer": "rgba32f"},
          "gl precision into an rgba32f framebuffer (float32 colour; glref's rgba32f too)"),
    Level("gl_ripmap", {"precision": "gl", "texture_filter": "ripmap"}, "ripmap texture filter",
          textured_only=True),
    Level("gl_ewa", {"precision": "gl", "texture_filter": "ewa"}, "EWA texture filter", textured_only=True),
]


@dataclass
class Row:
    scene: str
    triangles: int
    pixels: int
    level: str
    seconds: float | None
    glref_seconds: float
    ratio: float | None          # softras time / glref time (lower is better, <= 1 beats GL)
    mtri_per_s: float | None
    mpix_per_s: float | None
    mean_error: float | None     # mean |soft - truth| per channel, in /255
    bad_fraction: float | None   # pixels with a channel off by > 2/255
    peak_mib: float | None       # tracemalloc peak of one render (see the module docstring)
    rss_mib: float               # process peak RSS so far
    file_seconds: float | None = None         # end to end from the scene file (E2E_LEVEL only)
    glref_file_seconds: float | None = None
    file_ratio: float | None = None
    note: str = ""


# ----------------------------------------------------------------------------- scenes


@dataclass(frozen=True)
class BenchScene:
    name: str
    scene: dict
    quick: bool = True
    levels: bool = True          # all levels with errors; False: gl level only, no error (sweeps)
    series: str = ""             # "triangles" or "pixels" for the scaling fits


def scenes(full: bool = False, max_triangles: int = 1_000_000, max_side: int = 2048) -> list[BenchScene]:
    """The fixed benchmark set (quick subset, or everything with ``full``)."""
    out = [
        BenchScene("many_small_24k_512", grid_scene(110, 512)),
        BenchScene("few_large_512", grid_scene(2, 512)),
        BenchScene("floor_trilinear_512", floor_scene(512)),
        BenchScene("floor_aniso16_512", floor_scene(512, anisotropy=16), quick=False),
        BenchScene("msaa4_24k_512", grid_scene(110, 512, samples=4)),
        BenchScene("blended_8x128_512", blended_scene(512)),
        BenchScene("transparent_8x128_512", blended_scene(512, transparent=True), levels=False),
        # Stand-ins for real content (gl level only: the supersampled truth
        # of a lit 70k-triangle scene would cost minutes).
        BenchScene("scan_phong_71k_512", lit_scene(512, "phong", 256, 140), levels=False),
        BenchScene("scan_gouraud_71k_512", lit_scene(512, "gouraud", 256, 140), levels=False),
        BenchScene("gouraud_msaa4_24k_512", lit_scene(512, "gouraud", 128, 95, samples=4), levels=False),
        BenchScene("flat_6k_512", lit_scene(512, "flat", 64, 48, bumpy=False), levels=False),
        BenchScene("textured_phong_8k_1024", lit_scene(1024, "phong", 96, 48, textured=True, bumpy=False),
                   levels=False),
        BenchScene("bump_mapped_8k_512", lit_scene(512, "phong", 96, 48, textured=True, bumpy=False, bump_map=True),
                   levels=False),
        BenchScene("lines_8k_512", lines_scene(512), levels=False),
        BenchScene("parts_64x128_512", parts_scene(512), levels=False),
        BenchScene("textured_parts_64x128_512", parts_scene(512, textured=True), levels=False),
    ]
    for triangles in (1_000, 10_000, 100_000, 1_000_000):
        if triangles <= max_triangles:
            cols = round(math.sqrt(triangles / 2))
            out.append(BenchScene(f"scale_tris_{2 * cols * cols}", grid_scene(cols, 512),
                                  quick=triangles <= 100_000, levels=False, series="triangles"))
    for side in (256, 512, 1024, 2048):
        if side <= max_side:
            out.append(BenchScene(f"scale_pixels_{side}", grid_scene(32, side), quick=side <= 1024,
                                  levels=False, series="pixels"))
    return [s for s in out if full or s.quick]


# ----------------------------------------------------------------------------- measuring


def _paired_times(soft, gl, runs: int) -> tuple[float, float, object]:
    """Median seconds of the calls ``soft()`` and ``gl()`` taken in
    interleaved pairs after one untimed pair (kernels compiled, caches
    filled): at least ``runs`` pairs, more up to `MIN_PAIRS` while they fit
    in `PAIR_BUDGET` seconds.  Returns (soft median, gl median, the last
    result of ``soft``)."""
    soft_times, gl_times = [], []
    pair, begin = 0, None
    while pair <= runs or (pair <= MIN_PAIRS and time.perf_counter() - begin < PAIR_BUDGET):
        start = time.perf_counter()
        result = soft()
        middle = time.perf_counter()
        gl()
        end = time.perf_counter()
        if pair:                                    # pair 0 warms
            soft_times.append(middle - start)
            gl_times.append(end - middle)
        else:
            begin = end
        pair += 1
    return statistics.median(soft_times), statistics.median(gl_times), result


def _peak_mib(fn) -> float:
    """tracemalloc peak (MiB) of Python-tracked allocations during fn(), plus the
    fast path's reused buffers held after it (`fastpath.scratch_nbytes`)."""
    from softras.kernels import draw as fastpath
    tracemalloc.start()
    try:
        fn()
        return (tracemalloc.get_traced_memory()[1] + fastpath.scratch_nbytes()) / 2**20
    finally:
        tracemalloc.stop()


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0     # KiB on Linux


def applicable(level: Level, scene, full: bool) -> bool:
    """Whether a level is measured on a loaded scene."""
    if not (full or level.quick):
        return False
    if level.textured_only and not any(d.material.texture is not None for d in scene.draws):
        return False
    return scene.width * scene.height <= level.max_pixels


def truth_factor(scene) -> int:
    """Samples per pixel side of the ground truth: the most, up to 16, that
    keep the supersampled picture within `TRUTH_MAX_SIDE` pixels a side."""
    return max(1, min(16, TRUTH_MAX_SIDE // max(scene.width, scene.height)))


def truth_image(scene) -> np.ndarray:
    """The ground truth of the error figures, (H, W, 4) float64 on the 0..255
    scale like a render's bytes: `supersampled_reference` at `truth_factor`."""
    from softras.verification.ground_truth import supersampled_reference
    return supersampled_reference(scene, truth_factor(scene)) * 255.0


def measure(name: str, scene_dict: dict, runs: int, levels=None, *, errors: bool = True,
            full: bool = False, memory: bool = True) -> list[Row]:
    """Time glref and each applicable softras level on one scene.

    levels : a list of `Level` (default `LEVELS`) or a dict name -> options.
    errors : compare each level with the `truth_image` (when the scene is
        small enough for one).
    """
    import softras

    if levels is None:
        levels = LEVELS
    if isinstance(levels, dict):
        levels = [Level(k, v, k) for k, v in levels.items()]
    scene = softras.load_scene(scene_dict)
    triangles = sum(len(d.mesh.indices) for d in scene.draws)
    pixels = scene.width * scene.height
    truth = truth_image(scene) if errors and truth_factor(scene) >= 2 else None
    rows = []
    for level in levels:
        if not applicable(level, scene, full):
            continue
        # glref at the level's sample count where GL draws it (GL's pattern),
        # else at the scene's own, and into the level's framebuffer: the
        # ratio compares like with like.
        gl_samples = level.options.get("samples")
        if level.options.get("pattern") not in (None, "gl") or gl_samples == scene.samples:
            gl_samples = None
        framebuffer = level.options.get("framebuffer")
        try:
            seconds, gl_seconds, image = _paired_times(
                lambda: softras.render(scene, **level.options),
                lambda: softras.render(scene, backend="gl", samples=gl_samples, framebuffer=framebuffer), runs)
        except (TypeError, ValueError, NotImplementedError) as error:
            rows.append(Row(name, triangles, pixels, level.name, None, None, None, None, None, None,
                            None, None, _rss_mib(), note=f"n/a: {error}"))
            continue
        peak = _peak_mib(lambda: softras.render(scene, **level.options)) if memory else None
        mean_error = bad = None
        if truth is not None:       # (an rgba32f picture's floats on the bytes' 0..255 scale)
            diff = np.abs(image.astype(float) * (255.0 if image.dtype == np.float32 else 1.0) - truth)
            mean_error = float(diff.mean())
            bad = float((diff.max(axis=2) > 2).mean())
        row = Row(name, triangles, pixels, level.name, seconds, gl_seconds, seconds / gl_seconds,
                  triangles / seconds / 1e6, pixels / seconds / 1e6, mean_error, bad, peak, _rss_mib())
        if level.name == E2E_LEVEL:
            row.file_seconds, row.glref_file_seconds = _file_times(scene_dict, level.options, runs)
            row.file_ratio = row.file_seconds / row.glref_file_seconds
        rows.append(row)
    return rows


# Every softras figure is a median of renders interleaved with glref's
# (`_paired_times`): at least MIN_PAIRS pairs while they fit in PAIR_BUDGET
# seconds (``runs`` pairs in any case).  On a noisy 2-core machine a median
# of 3 or 5 pairs of ~6 ms renders moves by +-10 % from one run to the next;
# of 21, by about +-3 %.  Timed apart (glref's median first, then
# softras's), the two medians saw different spells of the machine: glref's
# own time for one scene moved between 4.1 and 7.2 ms across runs
# (docs/speed.md, thirty-fifth round).
MIN_PAIRS = 21
PAIR_BUDGET = 1.5


@contextlib.contextmanager
def _scene_file(scene_dict: dict):
    """The scene written to a temporary JSON file (its path), removed afterwards."""
    handle, path = tempfile.mkstemp(suffix=".json", prefix="softras-bench-")
    try:
        with os.fdopen(handle, "w") as out:
            json.dump(scene_dict, out)
        yield path
    finally:
        os.unlink(path)


def _file_times(scene_dict: dict, options: dict, runs: int) -> tuple[float, float]:
    """Median seconds from the scene file to the image: (softras, glref),
    interleaved pairs (`_paired_times`)."""
    import softras
    with _scene_file(scene_dict) as path:
        soft, gl, _ = _paired_times(lambda: softras.render(softras.load_scene(path), **options),
                                    lambda: softras.render(softras.load_scene(path), backend="gl"), runs)
    return soft, gl


LOADER_GRIDS = (110, 224)     # explicit-array grids of the loader figure: 24k and 100k triangles
LOADER_RUNS = 9


def explicit_grid_scene(cols: int) -> dict:
    """`grid_scene` with its mesh written out as explicit arrays (positions,
    indices, colours: the procedural grid as loaded), as a user's exported
    model arrives: the scene of the loader figure."""
    import softras
    scene = grid_scene(cols, 512)
    mesh = softras.load_scene(scene).draws[0].mesh
    scene["nodes"][0]["mesh"] = {"positions": mesh.positions.tolist(), "indices": mesh.indices.tolist(),
                                 "colors": np.clip(mesh.colors, 0.0, 1.0).tolist()}
    return scene


def loader_times(cols: int, runs: int = LOADER_RUNS) -> dict:
    """Median seconds of ``json.load`` and of ``softras.load_scene`` on the
    `explicit_grid_scene` written to a file, interleaved, and their ratio (the
    scene layer's cost beyond reading the JSON: validation and conversion to
    arrays)."""
    import softras
    json_s, load_s = [], []
    with _scene_file(explicit_grid_scene(cols)) as path:
        for _ in range(runs):
            gc.collect()                # (each from the same state of the garbage collector,
            with collector_paused():    # and json.load as load_scene parses: without its runs)
                start = time.perf_counter()
                with open(path, encoding="utf-8") as file:
                    json.load(file)
                json_s.append(time.perf_counter() - start)
            gc.collect()
            start = time.perf_counter()
            scene = softras.load_scene(path)
            load_s.append(time.perf_counter() - start)
        megabytes = os.path.getsize(path) / 1e6
    json_median, load_median = statistics.median(json_s), statistics.median(load_s)
    return {"triangles": len(scene.draws[0].mesh.indices), "megabytes": megabytes,
            "json_seconds": json_median, "load_seconds": load_median, "ratio": load_median / json_median}


def fit_exponent(sizes, seconds) -> float:
    """Least-squares slope of log(seconds) against log(size)."""
    x, y = np.log(np.asarray(sizes, float)), np.log(np.asarray(seconds, float))
    return float(np.polyfit(x, y, 1)[0])


def _fmt(value, spec: str, width: int) -> str:
    return format(value, spec).rjust(width) if value is not None else "-".rjust(width)


def format_row(r: Row) -> str:
    return (f"{r.scene:22s} {r.triangles:8d} {r.pixels:8d} {r.level:10s} {_fmt(r.seconds and r.seconds * 1e3, '.1f', 9)} "
            f"{r.glref_seconds * 1e3:8.1f} {_fmt(r.ratio, '.2f', 7)} {_fmt(r.mtri_per_s, '.2f', 8)} "
            f"{_fmt(r.mpix_per_s, '.1f', 7)} {_fmt(r.mean_error, '.3f', 8)} {_fmt(r.bad_fraction, '.4f', 7)} "
            f"{_fmt(r.peak_mib, '.1f', 8)} {r.rss_mib:7.0f}"
            + (f"  from file: {r.file_seconds * 1e3:.1f} vs {r.glref_file_seconds * 1e3:.1f} ms, ratio "
               f"{r.file_ratio:.2f}" if r.file_ratio is not None else "")
            + (f"  {r.note}" if r.note else ""))


HEADER = (f"{'scene':22s} {'tris':>8s} {'pixels':>8s} {'level':10s} {'soft ms':>9s} {'gl ms':>8s} "
          f"{'ratio':>7s} {'Mtri/s':>8s} {'Mpix/s':>7s} {'err/255':>8s} {'bad':>7s} {'peakMiB':>8s} {'rssMiB':>7s}")


def run(runs: int = 3, full: bool = False, max_triangles: int = 1_000_000, max_side: int = 2048,
        out_json: str | None = None, out_plot: str | None = None, echo=print) -> dict:
    """Run the benchmark set, print a table, return (and optionally write) the figures.

    The compiled kernels are compiled before a scene is timed, not left to a
    background process while the stages draw (``SOFTRAS_COMPILE=wait``
    unless set, `softras.kernels.prepare`), and the warm-up render of each
    timing absorbs the compilation."""
    os.environ.setdefault("SOFTRAS_COMPILE", "wait")
    wall_start, cpu_start = time.perf_counter(), time.process_time()
    rows: list[Row] = []
    echo(HEADER)
    series: dict[str, list[tuple[int, float]]] = {"triangles": [], "pixels": []}
    for bench_scene in scenes(full, max_triangles, max_side):
        if bench_scene.levels:
            new = measure(bench_scene.name, bench_scene.scene, runs, LEVELS, errors=True, full=full)
        else:
            new = measure(bench_scene.name, bench_scene.scene, runs, [LEVELS[0]], errors=False, full=full,
                          memory=False)
        for r in new:
            echo(format_row(r))
        rows.extend(new)
        if bench_scene.series and new and new[0].seconds:
            size = new[0].triangles if bench_scene.series == "triangles" else new[0].pixels
            series[bench_scene.series].append((size, new[0].seconds))
            series[bench_scene.series + "_glref"] = series.get(bench_scene.series + "_glref", []) + [
                (size, new[0].glref_seconds)]
    fits = {}
    for key, points in series.items():
        if len(points) > 1:
            fits[key + "_exponent"] = fit_exponent([p[0] for p in points], [p[1] for p in points])
    echo("cost fits (time ~ n^k, gl level; 1.0 = linear): "
         + ", ".join(f"{k} {v:.2f}" for k, v in fits.items()))
    loader = [loader_times(cols) for cols in LOADER_GRIDS]
    for figure in loader:
        echo(f"loader: {figure['triangles']} triangles as explicit arrays ({figure['megabytes']:.1f} MB): "
             f"load_scene {figure['load_seconds'] * 1e3:.1f} ms, json.load {figure['json_seconds'] * 1e3:.1f} ms, "
             f"ratio {figure['ratio']:.2f}")
    # The run's CPU time beside its wall time: on a shared machine the two
    # threads of softras (and llvmpipe's) at times get one core's worth of
    # time between them, and every figure of that run is then about doubled
    # (docs/speed.md, twenty-fifth round); runs compare where these agree.
    run_time = {"wall_seconds": time.perf_counter() - wall_start, "cpu_seconds": time.process_time() - cpu_start,
                "cores": os.cpu_count()}
    echo(f"this run: {run_time['wall_seconds']:.1f} s of wall time, {run_time['cpu_seconds']:.1f} s of CPU in "
         f"this process (all its threads) on {run_time['cores']} cores")
    report = {"rows": [asdict(r) for r in rows], "fits": fits, "loader": loader, "run_time": run_time,
              "runs": runs, "full": full,
              "truth": "supersampled_reference, exact, level-0 bilinear, up to 16x16 samples per pixel "
                       f"within {TRUTH_MAX_SIDE} pixels a side", "levels": [asdict(level) for level in LEVELS],
              "memory": "peak_mib: tracemalloc peak of one render (numpy and Python allocations, not "
                        "numba-internal ones); rss_mib: process peak RSS so far (getrusage)"}
    if out_json:
        from softras.scene.imageio import write_text_atomic
        write_text_atomic(out_json, json.dumps(report, indent=1))
    if out_plot:
        plot(rows, out_plot)
    return report


def plot(rows: list[Row], path: str) -> None:
    """PNG: time (relative to glref) against error (mean, /255), one panel per scene with errors."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    from softras.scene.imageio import _write_atomic, check_writable
    names = [n for n in dict.fromkeys(r.scene for r in rows)
             if any(r.scene == n and r.mean_error is not None for r in rows)]
    if not names:
        return
    cols = min(3, len(names))
    nrows = -(-len(names) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5 * cols, 4 * nrows), squeeze=False)
    for ax, name in zip(axes.flat, names):
        for r in rows:
            if r.scene == name and r.ratio is not None and r.mean_error is not None:
                ax.scatter(r.ratio, r.mean_error + 1e-3, s=25)
                ax.annotate(r.level, (r.ratio, r.mean_error + 1e-3), fontsize=8,
                            xytext=(3, 3), textcoords="offset points")
        ax.axvline(1.0, color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("time / glref time")
        ax.set_ylabel("mean error vs truth (/255, +0.001)")
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.tight_layout()
    import io
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    plt.close(fig)
    _write_atomic(check_writable(path), lambda handle: handle.write(buffer.getvalue()), "plot")
