"""``softras bench``: speed and error of softras's quality levels against glref.

Every figure is measured in one process, warm (one untimed render first),
as the median of several runs, with glref timed on the same scene in the same
run, so ratios are comparable on a noisy machine.  Error is measured against
a ground truth rendered by softras itself at the highest quality the scene
allows (exact precision, 4x MSAA positions); for each level we report the
mean absolute difference (in /255) and the fraction of pixels off by more
than 2/255.

The scenes are generated here (a tessellated, perspective-tilted grid), so
their size can be scaled: triangles from 1k to 1M (``--max-triangles``) and
pixels from 256^2 to 2048^2 (``--max-side``).  The cost growth is fitted as
``time ~ n^k`` by least squares on log-log; k near 1 is linear.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from dataclasses import asdict, dataclass

import numpy as np

LEVELS = {
    "gl": {"precision": "gl"},
    "exact": {"precision": "exact"},
    "gl_msaa4": {"precision": "gl", "samples": 4},
}


@dataclass
class Row:
    scene: str
    triangles: int
    pixels: int
    level: str
    seconds: float
    glref_seconds: float
    ratio: float            # softras time / glref time (lower is better, <= 1 beats GL)
    mtri_per_s: float
    mpix_per_s: float
    mean_error: float       # mean |soft - truth| per channel, in /255
    bad_fraction: float     # pixels with a channel off by > 2/255


def grid_scene(cols: int, side: int, samples: int = 1) -> dict:
    """A perspective-tilted grid of 2*cols^2 vertex-coloured triangles, side^2 pixels."""
    return {
        "softras_scene": 1, "width": side, "height": side, "background": [0, 0, 0, 1], "samples": samples,
        "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100,
                   "eye": [0, 0, 2.6], "target": [0, 0, 0]},
        "nodes": [{"name": "grid", "rotate": [-30, 1, 0, 0],
                   "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [2.5, 2.5],
                            "corner_colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]}}],
    }


def _median_time(fn, runs: int) -> tuple[float, object]:
    result = fn()                      # warm: kernels compiled, caches filled
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def measure(name: str, scene_dict: dict, runs: int, levels=LEVELS) -> list[Row]:
    """Time glref and each softras level on one scene; error against exact 4x."""
    import softras

    scene = softras.load_scene(scene_dict)
    triangles = sum(len(d.mesh.indices) for d in scene.draws)
    pixels = scene.width * scene.height
    gl_seconds, _ = _median_time(lambda: softras.render(scene, backend="gl"), runs)
    truth = softras.render(scene, precision="exact", samples=4).astype(float)
    rows = []
    for level, options in levels.items():
        seconds, image = _median_time(lambda: softras.render(scene, **options), runs)
        diff = np.abs(image.astype(float) - truth)
        rows.append(Row(name, triangles, pixels, level, seconds, gl_seconds, seconds / gl_seconds,
                        triangles / seconds / 1e6, pixels / seconds / 1e6,
                        float(diff.mean()), float((diff.max(axis=2) > 2).mean())))
    return rows


def fit_exponent(sizes, seconds) -> float:
    """Least-squares slope of log(seconds) against log(size)."""
    x, y = np.log(np.asarray(sizes, float)), np.log(np.asarray(seconds, float))
    return float(np.polyfit(x, y, 1)[0])


def run(runs: int = 5, max_triangles: int = 100_000, max_side: int = 1024, out_json: str | None = None,
        echo=print) -> dict:
    """Run the benchmark set, print a table, return (and optionally write) the figures."""
    rows: list[Row] = []
    header = (f"{'scene':18s} {'tris':>8s} {'pixels':>9s} {'level':9s} {'soft ms':>9s} {'gl ms':>8s} "
              f"{'ratio':>7s} {'Mtri/s':>7s} {'Mpix/s':>7s} {'err/255':>8s} {'bad':>7s}")
    echo(header)

    def emit(new_rows):
        for r in new_rows:
            echo(f"{r.scene:18s} {r.triangles:8d} {r.pixels:9d} {r.level:9s} {r.seconds * 1e3:9.1f} "
                 f"{r.glref_seconds * 1e3:8.1f} {r.ratio:7.1f} {r.mtri_per_s:7.2f} {r.mpix_per_s:7.1f} "
                 f"{r.mean_error:8.3f} {r.bad_fraction:7.4f}")
        rows.extend(new_rows)

    emit(measure("grid_24k_512", grid_scene(110, 512), runs))
    emit(measure("few_large_512", grid_scene(2, 512), runs))

    # Scaling in triangles at 512^2 and in pixels at ~2k triangles, gl level only.
    tri_sizes, tri_times = [], []
    cols = 23
    while 2 * cols * cols <= max_triangles:
        r = measure(f"scale_tris_{2 * cols * cols}", grid_scene(cols, 512), runs, {"gl": LEVELS["gl"]})
        emit(r)
        tri_sizes.append(r[0].triangles)
        tri_times.append(r[0].seconds)
        cols = int(cols * math.sqrt(10))
    pix_sizes, pix_times = [], []
    side = 256
    while side <= max_side:
        r = measure(f"scale_pixels_{side}", grid_scene(32, side), runs, {"gl": LEVELS["gl"]})
        emit(r)
        pix_sizes.append(r[0].pixels)
        pix_times.append(r[0].seconds)
        side *= 2
    fits = {"triangles_exponent": fit_exponent(tri_sizes, tri_times) if len(tri_sizes) > 1 else None,
            "pixels_exponent": fit_exponent(pix_sizes, pix_times) if len(pix_sizes) > 1 else None}
    echo(f"cost ~ triangles^{fits['triangles_exponent']:.2f}, ~ pixels^{fits['pixels_exponent']:.2f} "
         "(1.0 = linear)" if None not in fits.values() else f"fits: {fits}")
    report = {"rows": [asdict(r) for r in rows], "fits": fits, "runs": runs}
    if out_json:
        from .imageio import write_text_atomic
        write_text_atomic(out_json, json.dumps(report, indent=1))
    return report
