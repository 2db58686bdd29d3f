"""Coverage error of each sample pattern against exact area, on the scene set.

For every triangle of every scene in SCENES (window space, `softras.pipeline.coverage.
scene_triangles`) and every pixel it touches, the sampled coverage (covered
samples / S, from softras's own rasterizer in exact precision: float64 edge
functions, no snapping, so the figure is the pattern's error alone) is
compared with the exact area of the triangle inside the pixel.  Pixels both
call fully covered are left out (their error is 0 for every pattern): the
statistics are over edge pixels.  Random patterns (jittered, poisson) are
averaged over SEEDS seeds (the RMS is pooled over all of them).

Writes docs/coverage_error.png and prints the Markdown table; with
--update-docs it also replaces the table between the
``<!-- coverage-table:begin -->`` and ``<!-- coverage-table:end -->`` markers of
docs/antialiasing.md.

    python scripts/coverage_error.py [--update-docs] [--plot docs/coverage_error.png]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from softras.pipeline import coverage, sampling  # noqa: E402
from softras.scene.imageio import write_text_atomic  # noqa: E402
from softras.scene import load_scene  # noqa: E402

SCENES = ("msaa_fan", "slivers", "tiny_triangles", "fill_rule_grid", "demo", "lit_spheres")
SAMPLES = (1, 4, 16, 64, 256)
PATTERNS = ("gl", "grid", "rotated_grid", "jittered", "halton", "poisson")
SEEDS = (0, 1, 2, 3)
BEGIN, END = "<!-- coverage-table:begin -->", "<!-- coverage-table:end -->"


def measure() -> dict:
    """{(pattern, S): {"rms": {scene: float, "all": float}, "max": float, "mean_signed": float, "pairs": int}}."""
    scenes = {name: load_scene(REPO / "scenes" / f"{name}.json") for name in SCENES}
    triangles = {name: coverage.scene_triangles(scene) for name, scene in scenes.items()}
    results = {}
    for pattern in PATTERNS:
        for samples in SAMPLES:
            if pattern == "gl" and samples not in (1, 4):
                continue
            seeds = SEEDS if pattern in ("jittered", "poisson") else (0,)
            squares, counts, worst, signed = {}, {}, 0.0, 0.0
            for seed in seeds:
                positions = sampling.sample_positions(samples, pattern, seed)
                for name, scene in scenes.items():
                    err = coverage.coverage_error(triangles[name], scene.width, scene.height, positions).error
                    squares[name] = squares.get(name, 0.0) + float((err ** 2).sum())
                    counts[name] = counts.get(name, 0) + len(err)
                    worst = max(worst, float(np.abs(err).max()) if len(err) else 0.0)
                    signed += float(err.sum())
            rms = {name: np.sqrt(squares[name] / counts[name]) for name in SCENES}
            rms["all"] = np.sqrt(sum(squares.values()) / sum(counts.values()))
            results[(pattern, samples)] = {"rms": rms, "max": worst, "pairs": sum(counts.values()) // len(seeds),
                                           "mean_signed": signed / sum(counts.values())}
    return results


def table(results: dict) -> str:
    head = "| pattern | S | " + " | ".join(SCENES) + " | all (RMS) | max abs |"
    rule = "|" + "---|" * (len(SCENES) + 4)
    rows = [head, rule]
    for (pattern, samples), r in results.items():
        cells = " | ".join(f"{r['rms'][name]:.4f}" for name in SCENES)
        rows.append(f"| {pattern} | {samples} | {cells} | **{r['rms']['all']:.4f}** | {r['max']:.3f} |")
    pairs = next(iter(results.values()))["pairs"]
    rows.append("")
    rows.append(f"RMS of (covered samples / S - exact area) over the edge pixels of every triangle "
                f"(about {pairs} (triangle, pixel) pairs in all); max abs = the worst single pixel.")
    return "\n".join(rows)


def plot(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=100)
    for pattern in PATTERNS:
        points = [(s, results[(pattern, s)]["rms"]["all"]) for s in SAMPLES if (pattern, s) in results]
        xs, ys = zip(*points)
        ax.loglog(xs, ys, marker="o", label=pattern)
    s = np.array(SAMPLES, float)
    ref = results[("grid", 1)]["rms"]["all"]
    ax.loglog(s, ref / np.sqrt(s), "k:", lw=1, label="∝ S^-1/2")
    ax.loglog(s, ref / s ** 0.75, "k--", lw=1, label="∝ S^-3/4")
    ax.set_xlabel("samples per pixel S")
    ax.set_ylabel("RMS coverage error (edge pixels)")
    ax.set_title("Sampled coverage vs exact area, 6 scenes")
    ax.set_xticks(SAMPLES, [str(v) for v in SAMPLES])
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    tmp.replace(path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", default=str(REPO / "docs" / "coverage_error.png"), help="PNG plot to write")
    parser.add_argument("--update-docs", action="store_true",
                        help="replace the table in docs/antialiasing.md between its markers")
    args = parser.parse_args()
    start = time.perf_counter()
    results = measure()
    text = table(results)
    print(text)
    plot(results, Path(args.plot))
    print(f"\nplot -> {args.plot}  ({time.perf_counter() - start:.0f} s)")
    if args.update_docs:
        doc = REPO / "docs" / "antialiasing.md"
        body = doc.read_text(encoding="utf-8")
        if BEGIN not in body or END not in body:
            print(f"{doc}: no {BEGIN} ... {END} markers", file=sys.stderr)
            return 2
        before, rest = body.split(BEGIN, 1)
        _, after = rest.split(END, 1)
        write_text_atomic(doc, f"{before}{BEGIN}\n{text}\n{END}{after}")
        print(f"table -> {doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
