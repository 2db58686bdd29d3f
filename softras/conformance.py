"""The conformance run: every scene through both renderers, one verdict each.

``softras conformance`` (DESIGN.md section 6) renders each scene with softras
(precision "gl") and with glref, and gives it one of dEQP's verdicts:

* **pass** -- softras matches GL within the scene's tolerance (per-pixel
  threshold, fraction of bad pixels, mean SSIM; :func:`softras.compare`) over
  the whole image. This is the same check as ``tests/test_scenes.py`` and the
  golden images: where softras claims to reproduce llvmpipe bit for bit, the
  claim is enforced on every pixel.
* **quality warning** -- the strict check fails, but passes once the pixels of
  the ambiguity mask (:mod:`softras.ambiguity`: pixels whose answer depends on
  implementation choices GL allows) are excused: every difference beyond the
  tolerance is one that another correct implementation could also produce.
  dEQP's rasterization tests do the same: a strict pass, else a weaker check
  that, if it passes, gives ``QualityWarning``.
* **fail** -- the tolerance fails even with the ambiguous pixels excused (or
  softras cannot render the scene). The reasons say which stage disagrees
  (coverage, depth or colour, from primitive-ID pictures of both renderers,
  :func:`softras.ambiguity.classify_differences`) and where.

Tolerance: the scene's own ``"tolerance"`` when its file declares one,
otherwise the defaults for the features it uses (:data:`FEATURE_TOLERANCES`).

Scenes run in this process (``jobs=1``) or in worker processes started with
``spawn`` (a fresh interpreter each: every worker creates its own EGL context;
a context cannot survive ``fork``). Results come back in scene order.
"""

from __future__ import annotations

import fnmatch
import json
import multiprocessing
import os
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from softras.scene import scene_files

__all__ = [
    "PASS", "WARN", "FAIL", "VERDICT_NAMES", "FEATURE_TOLERANCES", "ConformanceError", "SceneResult",
    "feature_tolerance", "scene_tolerance", "select", "parse_shard", "shard", "check_scene", "judge",
    "run", "counts", "ProgressBar",
]

PASS, WARN, FAIL = "pass", "warn", "fail"
#: How each verdict is written for people.
VERDICT_NAMES = {PASS: "PASS", WARN: "QUALITY WARNING", FAIL: "FAIL"}
#: Failing scenes first, then warnings, then passes.
VERDICT_ORDER = {FAIL: 0, WARN: 1, PASS: 2}

#: Default tolerance by feature, for scenes that declare none; a scene with
#: several features gets the loosest threshold and bad fraction and the
#: lowest SSIM among them. The values are those the existing scenes of each
#: kind declare, for the reasons in their descriptions and in tests/test_scenes.py.
FEATURE_TOLERANCES = {
    # The scene format's default: 2/255 covers one rounding step of each of
    # interpolation and blending.
    "base": {"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99},
    # llvmpipe filters RGBA8 textures with 8-bit weights and a piecewise
    # linear log2 for the LOD (reproduced in gl precision; other drivers
    # differ by a few levels at texel and mip boundaries).
    "texture": {"threshold": 3, "max_bad_fraction": 0.005, "min_ssim": 0.98},
    # Lighting: float32 normalize / pow in the shader, vendor-specific.
    "lighting": {"threshold": 3, "max_bad_fraction": 0.005, "min_ssim": 0.98},
    # 4x MSAA: the resolve averages four rounded samples.
    "msaa": {"threshold": 2, "max_bad_fraction": 0.002, "min_ssim": 0.99},
}


class ConformanceError(ValueError):
    """Bad input for a conformance run (no scenes, a bad pattern or shard); one line."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------------
# Choosing scenes and tolerances


def feature_tolerance(scene) -> tuple[dict, list[str]]:
    """The default tolerance for the features a scene uses.

    Returns
    -------
    tolerance : dict
        ``threshold``, ``max_bad_fraction``, ``min_ssim``.
    features : list of str
        The keys of :data:`FEATURE_TOLERANCES` that applied (``"base"`` first).
    """
    features = ["base"]
    if any(draw.material.texture is not None for draw in scene.draws):
        features.append("texture")
    if any(draw.material.shading != "unlit" for draw in scene.draws):
        features.append("lighting")
    if scene.samples > 1:
        features.append("msaa")
    chosen = [FEATURE_TOLERANCES[name] for name in features]
    tolerance = {"threshold": max(t["threshold"] for t in chosen),
                 "max_bad_fraction": max(t["max_bad_fraction"] for t in chosen),
                 "min_ssim": min(t["min_ssim"] for t in chosen)}
    return tolerance, features


def scene_tolerance(path: str | os.PathLike, scene) -> tuple[dict, str]:
    """The tolerance a scene is judged by, and where it comes from.

    Returns ``(scene.tolerance, "scene")`` when the scene file has a
    ``"tolerance"`` key, else ``(defaults, "defaults for base, texture, ...")``
    from :func:`feature_tolerance`.
    """
    try:
        declared = "tolerance" in json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        declared = True  # load_scene read it; keep what it parsed
    if declared:
        return dict(scene.tolerance), "scene"
    tolerance, features = feature_tolerance(scene)
    return tolerance, "defaults for " + ", ".join(features)


def _matches(name: str, pattern: str) -> bool:
    """-k: a glob when the pattern has * ? or [, else a substring."""
    if any(char in pattern for char in "*?["):
        return fnmatch.fnmatchcase(name, pattern)
    return pattern in name


def parse_shard(text: str) -> tuple[int, int]:
    """``"I/N"`` -> ``(I, N)`` with 1 <= I <= N; ConformanceError otherwise."""
    index, slash, count = text.partition("/")
    try:
        i, n = int(index), int(count)
    except ValueError:
        i = n = 0
    if not slash or not 1 <= i <= n:
        raise ConformanceError(f"--shard {text}: expected I/N with 1 <= I <= N, e.g. 2/4")
    return i, n


def shard(paths: list[Path], index: int, count: int) -> list[Path]:
    """Shard ``index`` of ``count`` (1-based): every count-th scene of the list sorted by name.

    Round robin over the names sorted, so the shards are deterministic, differ
    in size by at most one, and together hold every scene exactly once.
    """
    ordered = sorted(paths, key=lambda path: (path.stem, str(path)))
    return ordered[index - 1::count]


def select(paths: Iterable[str | os.PathLike], *, patterns: Iterable[str] = (),
           shard_spec: str | None = None) -> list[Path]:
    """The scene files of a run, sorted by name.

    Parameters
    ----------
    paths : iterable of path
        Scene files, or folders whose ``*.json`` files are scenes.
    patterns : iterable of str
        ``-k``: keep scenes whose name (file stem) contains a pattern, or
        matches it as a glob (``*?[``). Several patterns: any may match.
    shard_spec : str, optional
        ``"I/N"``: keep shard I of N (:func:`shard`), applied after ``-k``.

    Raises
    ------
    ConformanceError
        A missing path, no scenes at all, no scene matching ``-k``, a bad shard.
    """
    try:
        found = [Path(path) for path in scene_files(paths)]
    except (OSError, ValueError) as error:
        raise ConformanceError(str(error)) from None
    found.sort(key=lambda path: (path.stem, str(path)))
    patterns = list(patterns)
    if patterns:
        found = [path for path in found if any(_matches(path.stem, pattern) for pattern in patterns)]
        if not found:
            raise ConformanceError("no scene matches -k " + " -k ".join(patterns))
    if shard_spec is not None:
        found = shard(found, *parse_shard(shard_spec))
    return found


# ---------------------------------------------------------------------------
# One scene


@dataclass
class SceneResult:
    """The verdict on one scene, with its figures and pictures.

    ``images`` holds ``uint8`` ``(H, W, 4)`` pictures, row 0 = top: ``soft``,
    ``gl``, ``diff`` (heat map, :func:`softras.metrics.diff_heatmap`),
    ``ssim`` and ``flip`` (:func:`softras.metrics.error_map_image`),
    ``ambiguity`` (:meth:`softras.ambiguity.Ambiguity.image`) and ``where``
    (the differing pixels beyond the tolerance: red outside the ambiguity
    mask, cyan inside, over softras's picture dimmed).
    """

    name: str
    path: str
    verdict: str = FAIL
    reasons: list[str] = field(default_factory=list)
    description: str = ""
    tolerance: dict = field(default_factory=dict)
    tolerance_source: str = ""
    figures: dict = field(default_factory=dict)
    seconds: float = 0.0
    images: dict = field(default_factory=dict, repr=False)

    def line(self) -> str:
        """One line for the terminal: verdict, name, first reason, time."""
        reason = self.reasons[0] if self.reasons else ""
        more = f" (+{len(self.reasons) - 1} more)" if len(self.reasons) > 1 else ""
        return f"{VERDICT_NAMES[self.verdict]:<15} {self.name}: {reason}{more}  ({self.seconds:.2f} s)"

    def to_dict(self) -> dict:
        """JSON-serialisable summary (no arrays)."""
        return {"name": self.name, "path": self.path, "verdict": self.verdict,
                "verdict_name": VERDICT_NAMES[self.verdict], "reasons": list(self.reasons),
                "description": self.description, "tolerance": dict(self.tolerance),
                "tolerance_source": self.tolerance_source, "figures": dict(self.figures),
                "seconds": round(self.seconds, 4)}


def _bounds(selection: np.ndarray) -> str:
    rows, cols = np.nonzero(selection)
    return f"x {cols.min()}..{cols.max()}, y {rows.min()}..{rows.max()}"


def _where_image(soft: np.ndarray, outside: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Differences beyond the tolerance: red outside the mask, cyan inside, over soft dimmed."""
    grey = soft[..., :3].astype(np.float64).mean(axis=-1)
    out = np.empty(soft.shape[:2] + (4,), dtype=np.uint8)
    out[..., :3] = np.rint(30 + 0.3 * grey).astype(np.uint8)[..., None]
    out[inside, :3] = (0, 220, 255)
    out[outside, :3] = (255, 30, 30)
    out[..., 3] = 255
    return out


def _tolerance_text(tolerance: dict) -> str:
    return (f"threshold {tolerance['threshold']}/255, bad pixels <= {100 * tolerance['max_bad_fraction']:.2f}%, "
            f"SSIM >= {tolerance['min_ssim']:g}")


def _render_soft(scene) -> np.ndarray:
    import softras

    return softras.render(scene, precision="gl")


def _render_gl(scene) -> np.ndarray:
    import glref

    return glref.render(scene)


def judge(scene, soft: np.ndarray, gl: np.ndarray, tolerance: dict, *, soft_ids=None, gl_ids=None,
          soft_last=None, gl_last=None, ambiguity=None) -> tuple[str, list[str], dict, dict]:
    """The verdict on two pictures of a scene (the two tiers of the module docstring).

    Parameters
    ----------
    scene : softras.scene.Scene
    soft, gl : numpy.ndarray
        ``uint8`` ``(H, W, 4)`` pictures by softras and GL.
    tolerance : dict
        ``threshold``, ``max_bad_fraction``, ``min_ssim``.
    soft_ids, gl_ids : tuple, optional
        :func:`softras.ambiguity.decode_ids` of both renderers' primitive-ID
        pictures (for the stage of a failure).
    soft_last, gl_last : numpy.ndarray, optional
        Primitive numbers of both renderers' ID pictures without depth test
        (tell coverage from depth; :func:`softras.ambiguity.classify_differences`).
    ambiguity : softras.ambiguity.Ambiguity, optional
        The mask; without it nothing is excused.

    Returns
    -------
    verdict : str
        PASS, WARN or FAIL.
    reasons : list of str
    figures : dict
        JSON-able numbers.
    images : dict
        ``diff``, ``ssim``, ``flip``, ``where`` pictures.
    """
    from softras.ambiguity import classify_differences
    from softras.metrics import compare, error_map_image, pixel_difference

    strict = compare(soft, gl, flip=True, **tolerance)
    pixel_diff = pixel_difference(soft, gl)
    bad = pixel_diff > tolerance["threshold"]
    mask = ambiguity.mask if ambiguity is not None else np.zeros_like(bad)
    outside, inside = bad & ~mask, bad & mask
    figures = strict.to_dict()
    figures.pop("passed")
    figures.update(bad_outside_mask=int(outside.sum()), bad_inside_mask=int(inside.sum()),
                   differing_pixels=int((pixel_diff > 0).sum()))
    if ambiguity is not None:
        figures["ambiguous_pixels"] = ambiguity.counts()
    if soft_ids is not None and gl_ids is not None:
        figures["coverage_mismatch_pixels"] = int((soft_ids[0] != gl_ids[0]).sum())

    reasons: list[str] = []
    if strict.passed:
        verdict = PASS
        reasons.append("identical to GL" if strict.max_diff == 0 else
                       f"within tolerance: max diff {strict.max_diff}/255, {strict.bad_pixels} px beyond "
                       f"{tolerance['threshold']}/255, SSIM {strict.ssim:.5f}")
    else:
        # Second tier: ambiguous pixels count as agreeing (GL's value replaced by softras's).
        excused = np.where(mask[..., None], soft, gl)
        relaxed = compare(soft, excused, **tolerance)
        figures["ssim_excused"] = float(relaxed.ssim)
        strict_why = (f"{strict.bad_pixels} px ({100 * strict.bad_fraction:.3f}%) differ by more than "
                      f"{tolerance['threshold']}/255 (max {strict.max_diff}/255), SSIM {strict.ssim:.5f}")
        if relaxed.passed:
            verdict = WARN
            where = ambiguity.label(inside) if ambiguity is not None else {}
            labels = ", ".join(f"{name} {count}" for name, count in where.items() if count)
            reasons.append(f"{strict_why}: not within the strict tolerance, but "
                           + (f"all {int(inside.sum())} are in the ambiguity mask ({labels})"
                              if inside.any() else "only SSIM fails")
                           + f"; with them excused: {relaxed.bad_pixels} px beyond, SSIM {relaxed.ssim:.5f}")
        else:
            verdict = FAIL
            reasons.append(f"{strict_why}; {int(outside.sum())} of them outside the ambiguity mask"
                           + (f" at {_bounds(outside)}" if outside.any() else "")
                           + f"; with the ambiguous pixels excused: {relaxed.bad_pixels} px "
                             f"({100 * relaxed.bad_fraction:.3f}%) beyond, SSIM {relaxed.ssim:.5f} "
                             f"(needs {_tolerance_text(tolerance)})")
        if soft_ids is not None and gl_ids is not None:
            selection, where = (outside, "outside the ambiguity mask") if verdict == FAIL else \
                (inside, "inside the ambiguity mask")
            reasons.extend(classify_differences(selection, soft_ids, gl_ids, pixel_diff, scene, where=where,
                                                soft_last=soft_last, gl_last=gl_last))

    images = {"diff": strict.diff_image, "ssim": error_map_image(1.0 - strict.ssim_map),
              "flip": error_map_image(strict.flip_map), "where": _where_image(soft, outside, inside)}
    return verdict, reasons, figures, images


def check_scene(path: str | os.PathLike, *, render_soft: Callable | None = None,
                render_gl: Callable | None = None, tolerance: dict | None = None) -> SceneResult:
    """Run one scene through both renderers and judge it.

    Parameters
    ----------
    path : path
        A scene file.
    render_soft, render_gl : callable, optional
        ``render(scene) -> (H, W, 4) uint8``; default softras (precision
        "gl") and glref. (Tests pass broken ones.) ``render_soft`` also draws
        softras's primitive-ID pictures; the ambiguity mask always comes from
        the softras pipeline.
    tolerance : dict, optional
        Overrides the scene's tolerance (:func:`scene_tolerance`).

    Returns
    -------
    SceneResult
        Never raises for a scene that cannot be rendered or any other error
        inside the check: the result is a FAIL whose reason says what happened.
    """
    from softras import ambiguity as amb
    from softras.scene import load_scene

    render_soft = render_soft or _render_soft
    render_gl = render_gl or _render_gl
    path = Path(path)
    start = time.perf_counter()
    result = SceneResult(name=path.stem, path=str(path))
    try:
        scene = load_scene(path)
        result.description = scene.description
        result.tolerance, result.tolerance_source = scene_tolerance(path, scene)
        if tolerance is not None:
            result.tolerance, result.tolerance_source = dict(tolerance), "given"
        times = {}
        t = time.perf_counter()
        gl = amb.as_uint8(render_gl(scene))
        times["gl_seconds"] = time.perf_counter() - t
        result.images["gl"] = gl
        t = time.perf_counter()
        try:
            soft = amb.as_uint8(render_soft(scene))
        except NotImplementedError as error:
            result.reasons.append(f"softras cannot render the scene: {_one_line(error)}")
            return result
        times["soft_seconds"] = time.perf_counter() - t
        result.images["soft"] = soft
        t = time.perf_counter()
        ambiguity = amb.ambiguity_mask(scene, soft if render_soft is _render_soft else None)
        ids = amb.id_scene(scene)
        soft_ids = amb.decode_ids(amb.as_uint8(render_soft(ids)), scene)
        gl_ids = amb.decode_ids(amb.as_uint8(_render_gl(ids)), scene)
        no_depth = amb.id_scene(scene, depth_test=False)
        soft_last = amb.decode_ids(amb.as_uint8(render_soft(no_depth)), scene)[0]
        gl_last = amb.decode_ids(amb.as_uint8(_render_gl(no_depth)), scene)[0]
        times["ambiguity_seconds"] = time.perf_counter() - t
        verdict, reasons, figures, images = judge(scene, soft, gl, result.tolerance, soft_ids=soft_ids,
                                                  gl_ids=gl_ids, soft_last=soft_last, gl_last=gl_last,
                                                  ambiguity=ambiguity)
        result.verdict, result.reasons = verdict, reasons
        result.figures = figures | {name: round(value, 4) for name, value in times.items()}
        result.images.update(images)
        result.images["ambiguity"] = ambiguity.image(soft)
    except Exception as error:  # noqa: BLE001 - reported as this scene's failure
        frames = traceback.extract_tb(error.__traceback__)
        place = f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else ""
        result.verdict = FAIL
        result.reasons.append(f"error: {type(error).__name__}: {_one_line(error)}{place}")
    finally:
        result.seconds = time.perf_counter() - start
    return result


def _check_in_worker(path: str) -> SceneResult:
    """check_scene for a worker process (a top-level function: spawn pickles it by name)."""
    return check_scene(path)


# ---------------------------------------------------------------------------
# A run


class ProgressBar:
    """A one-line progress bar on a terminal (``\\r``), or one line per scene elsewhere.

    ``[########............]  12/30  scene_name`` -- no dependencies.
    """

    def __init__(self, total: int, stream=None, width: int = 30):
        self.total = total
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def advance(self, result: SceneResult) -> None:
        """Count one finished scene and redraw."""
        self.done += 1
        if self.tty:
            filled = self.width * self.done // max(self.total, 1)
            bar = "#" * filled + "." * (self.width - filled)
            text = f"\r[{bar}] {self.done:>{len(str(self.total))}}/{self.total}  {result.name[:40]:<40}"
            self.stream.write(text)
        else:
            self.stream.write(f"[{self.done}/{self.total}] {VERDICT_NAMES[result.verdict]} {result.name} "
                              f"({result.seconds:.2f} s)\n")
        self.stream.flush()

    def close(self) -> None:
        """Clear the bar (terminal)."""
        if self.tty:
            self.stream.write("\r" + " " * (self.width + 52) + "\r")
            self.stream.flush()


def run(paths: list[Path], *, jobs: int = 1, on_result: Callable[[SceneResult], None] | None = None,
        check: Callable[[str], SceneResult] | None = None) -> list[SceneResult]:
    """Check scenes, in this process or in ``jobs`` spawned worker processes.

    Parameters
    ----------
    paths : list of Path
        Scene files (from :func:`select`).
    jobs : int
        Worker processes; 1 = this process.
    on_result : callable, optional
        Called with each result as it finishes (progress), in finishing order.
    check : callable, optional
        ``check(path) -> SceneResult`` (default :func:`check_scene`); must be
        a top-level function when ``jobs > 1``.

    Returns
    -------
    list of SceneResult
        In the order of ``paths``.

    Notes
    -----
    ``spawn`` starts each worker by importing the caller's main module: a
    script that calls ``run(..., jobs=2)`` must do so under
    ``if __name__ == "__main__":`` (``softras`` and ``python -m softras`` do).
    Each worker pays a start-up of about 3 s here (numba's cached kernels, an
    EGL context), so ``-j`` helps only with more free cores than workers.
    """
    if jobs < 1:
        raise ConformanceError(f"-j {jobs}: need at least 1 process")
    results: dict[str, SceneResult] = {}
    names = [str(path) for path in paths]
    if jobs == 1 or len(names) <= 1:
        check = check or check_scene
        for name in names:
            results[name] = check(name)
            if on_result is not None:
                on_result(results[name])
    else:
        check = check or _check_in_worker
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(jobs, len(names)), mp_context=context) as pool:
            futures = {pool.submit(check, name): name for name in names}
            from concurrent.futures import as_completed

            for future in as_completed(futures):
                name = futures[future]
                try:
                    results[name] = future.result()
                except Exception as error:  # noqa: BLE001 - a worker died: this scene fails
                    results[name] = SceneResult(name=Path(name).stem, path=name, verdict=FAIL,
                                                reasons=[f"error: worker process failed: "
                                                         f"{type(error).__name__}: {_one_line(error)}"])
                if on_result is not None:
                    on_result(results[name])
    return [results[name] for name in names]


def counts(results: list[SceneResult]) -> dict:
    """``{"pass": n, "warn": n, "fail": n, "total": n}``."""
    tally = {verdict: sum(r.verdict == verdict for r in results) for verdict in (PASS, WARN, FAIL)}
    tally["total"] = len(results)
    return tally
