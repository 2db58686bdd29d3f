"""The conformance run: every scene through both renderers, one verdict each.

``softras conformance`` renders each scene with softras (precision "gl") and
with glref, and gives it one of dEQP's verdicts through
:mod:`softras.verification.verifier` under a profile (``--profile``):

* ``strict`` -- the scene's tolerance on every pixel, quality warning when
  it holds only with the ambiguity mask excused (:func:`softras.verification.verifier.judge_strict`);
  softras's contract with the implementation it reproduces (llvmpipe 22.3);
* ``spec`` -- both pictures within the per-pixel bounds of what any
  conformant GL may draw (:func:`softras.verification.verifier.judge_spec`);
* ``auto`` (default) -- strict for the implementation softras reproduces,
  spec for any other (:func:`softras.verification.verifier.choose_profile`).

A fourth verdict, **not supported** (dEQP's NotSupported), is given to a scene
that needs what the GL context lacks (a sample count, anisotropic filtering,
a texture size: :func:`glref.unsupported`); it is never a failure.

Tolerance: the scene's own ``"tolerance"`` when its file declares one,
otherwise the defaults for the features it uses
(:data:`softras.verification.verifier.FEATURE_TOLERANCES`, the one set of defaults).

Scenes run in this process (``jobs=1``) or in worker processes started with
``spawn`` (a fresh interpreter each: every worker creates its own EGL context;
a context cannot survive ``fork``). Results come back in scene order.
:mod:`softras.verification.runner` runs them the way ``softras conformance`` does: one
supervised worker process per job, crash isolation, time limits, retries,
baselines and resumable reports, and the verdicts that only a runner can give
(CRASH, TIMEOUT, FLAKY, defined here with the others).
"""

from __future__ import annotations

import fnmatch
import functools
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
from softras.verification.verifier import (FAIL, FEATURE_TOLERANCES, NOT_SUPPORTED, PASS, PROFILES, VERDICT_NAMES, WARN,
                              feature_tolerance, judge_strict, scene_tolerance)

__all__ = [
    "PASS", "WARN", "FAIL", "NOT_SUPPORTED", "CRASH", "TIMEOUT", "FLAKY", "CONFORMING", "VERDICT_NAMES",
    "VERDICT_ORDER", "FEATURE_TOLERANCES", "PROFILES",
    "ConformanceError", "SceneResult",
    "feature_tolerance", "scene_tolerance", "select", "parse_shard", "shard", "check_scene", "judge",
    "run", "counts", "ProgressBar",
]

#: Verdicts of the runner (:mod:`softras.verification.runner`), never of a check: the worker
#: died (CRASH), overran ``--timeout`` (TIMEOUT), or the verdict changed
#: between attempts of ``--retries`` (FLAKY).
CRASH, TIMEOUT, FLAKY = "crash", "timeout", "flaky"
VERDICT_NAMES = {**VERDICT_NAMES, CRASH: "CRASH", TIMEOUT: "TIMEOUT", FLAKY: "FLAKY"}

#: The verdicts that never fail a run by themselves.
CONFORMING = (PASS, WARN, NOT_SUPPORTED)

#: Crashes, timeouts and failures first, then flaky scenes, warnings, not supported, passes.
VERDICT_ORDER = {CRASH: 0, TIMEOUT: 1, FAIL: 2, FLAKY: 3, WARN: 4, NOT_SUPPORTED: 5, PASS: 6}


class ConformanceError(ValueError):
    """Bad input for a conformance run (no scenes, a bad pattern or shard); one line."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------------
# Choosing scenes and tolerances


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
        Scene files, or folders whose ``*.json``, ``*.gltf`` and ``*.glb`` files are scenes.
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
    ``gl``, ``diff`` (heat map, :func:`softras.verification.metrics.diff_heatmap`),
    ``ssim`` and ``flip`` (:func:`softras.verification.metrics.error_map_image`),
    ``ambiguity`` (:meth:`softras.verification.ambiguity.Ambiguity.image`) and ``where``
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
    attempts: list = field(default_factory=list)

    def failed(self) -> bool:
        """Whether this scene fails the run: FAIL, CRASH, TIMEOUT, or FLAKY with no attempt conforming."""
        if self.verdict == FLAKY:
            return not any(attempt["verdict"] in CONFORMING for attempt in self.attempts)
        return self.verdict not in CONFORMING

    def line(self) -> str:
        """One line for the terminal: verdict, name, first reason, time."""
        reason = self.reasons[0] if self.reasons else ""
        more = f" (+{len(self.reasons) - 1} more)" if len(self.reasons) > 1 else ""
        return f"{VERDICT_NAMES[self.verdict]:<15} {self.name}: {reason}{more}  ({self.seconds:.2f} s)"

    def to_dict(self) -> dict:
        """JSON-serialisable summary (no arrays); ``attempts``: one entry per try when retried, else empty."""
        return {"name": self.name, "path": self.path, "verdict": self.verdict,
                "verdict_name": VERDICT_NAMES[self.verdict], "reasons": list(self.reasons),
                "description": self.description, "tolerance": dict(self.tolerance),
                "tolerance_source": self.tolerance_source, "figures": dict(self.figures),
                "seconds": round(self.seconds, 4), "attempts": [dict(attempt) for attempt in self.attempts]}


def _render_soft(scene, pattern=None) -> np.ndarray:
    """softras's picture at precision "gl"; ``pattern``: the reference GL's
    sample positions where they are not softras's "gl" pattern
    (`softras.verification.verifier.gl_positions`), so that both pictures
    sample at the same places (a GPU's 4x, or its 8x and 16x, which softras's
    "gl" pattern does not have)."""
    from softras.renderer import render_scene

    return render_scene(scene, precision="gl", pattern=pattern)


def _render_gl(scene) -> np.ndarray:
    import glref

    return glref.render(scene)


#: The strict profile's verdict (moved to :mod:`softras.verification.verifier`; kept under its old name).
judge = judge_strict


def _gl_info() -> dict:
    """The reference context's capability record (looked up at call time: tests patch it)."""
    import glref

    return glref.info()


def _unsupported(scene, capabilities: dict) -> str | None:
    import glref

    return glref.unsupported(scene, capabilities=capabilities)


def check_scene(path, *, render_soft: Callable | None = None,
                render_gl: Callable | None = None, tolerance: dict | None = None,
                profile: str = "auto", name: str | None = None) -> SceneResult:
    """Run one scene through both renderers and judge it.

    Parameters
    ----------
    path : path, dict or Scene
        A scene file, or a scene built in memory (a dict in the scene format
        or a :class:`softras.scene.Scene`). Its tolerance: the one the file
        or dict declares, else the defaults for its features.
    render_soft, render_gl : callable, optional
        ``render(scene) -> (H, W, 4) uint8``; default softras (precision
        "gl") and glref. (Tests pass broken ones.) ``render_soft`` also draws
        softras's primitive-ID pictures; the ambiguity mask and the spec
        bounds always come from the softras pipeline.
    tolerance : dict, optional
        Overrides the scene's tolerance (:func:`scene_tolerance`).
    profile : "auto", "strict" or "spec"
        :func:`softras.verification.verifier.choose_profile` with the GL's capability record.
    name : str, optional
        The result's name (default: the file's stem; ``"scene"`` for a scene in memory).

    Returns
    -------
    SceneResult
        Never raises for a scene that cannot be rendered or any other error
        inside the check: the result is a FAIL whose reason says what happened
        (NOT SUPPORTED when the GL context lacks what the scene needs).
    """
    from softras.verification import ambiguity as amb
    from softras.verification import verifier
    from softras.scene import load_scene

    render_soft = render_soft or _render_soft
    render_gl = render_gl or _render_gl
    source = path
    path = Path(path) if isinstance(path, (str, os.PathLike)) else None
    start = time.perf_counter()
    result = SceneResult(name=name or (path.stem if path is not None else "scene"),
                         path=str(path) if path is not None else "")
    try:
        scene = load_scene(source)
        result.description = scene.description
        result.tolerance, result.tolerance_source = scene_tolerance(scene)
        if tolerance is not None:
            result.tolerance, result.tolerance_source = dict(tolerance), "given"
        capabilities = _gl_info()
        chosen = verifier.choose_profile(profile, capabilities)
        reason = _unsupported(scene, capabilities)
        if reason is not None:
            result.verdict = NOT_SUPPORTED
            result.reasons.append(f"this OpenGL ({capabilities.get('GL_RENDERER')}) cannot draw {reason}")
            return result
        times = {}
        t = time.perf_counter()
        gl = render_gl(scene)
        times["gl_seconds"] = time.perf_counter() - t
        result.images["gl"] = amb.as_uint8(gl)
        t = time.perf_counter()
        try:
            soft = (_render_soft(scene, verifier.gl_positions(scene, capabilities))
                    if render_soft is _render_soft else render_soft(scene))
        except NotImplementedError as error:
            result.reasons.append(f"softras cannot render the scene: {_one_line(error)}")
            return result
        times["soft_seconds"] = time.perf_counter() - t
        result.images["soft"] = amb.as_uint8(soft)
        t = time.perf_counter()
        if chosen == "spec":
            bounds = verifier.spec_bounds(scene, capabilities)
            verdict, reasons, figures, images = verifier.judge_spec(
                scene, soft, gl, result.tolerance, bounds, draw_ids=verifier.draw_ids(scene, capabilities=capabilities))
            times["bounds_seconds"] = time.perf_counter() - t
        else:
            soft, gl = amb.as_uint8(soft), amb.as_uint8(gl)
            ambiguity = amb.ambiguity_mask(scene, soft if render_soft is _render_soft else None)
            ids = amb.id_scene(scene)
            soft_ids = amb.decode_ids(amb.as_uint8(render_soft(ids)), scene)
            gl_ids = amb.decode_ids(amb.as_uint8(_render_gl(ids)), scene)
            no_depth = amb.id_scene(scene, depth_test=False)
            soft_last = amb.decode_ids(amb.as_uint8(render_soft(no_depth)), scene)[0]
            gl_last = amb.decode_ids(amb.as_uint8(_render_gl(no_depth)), scene)[0]
            times["ambiguity_seconds"] = time.perf_counter() - t
            verdict, reasons, figures, images = judge_strict(scene, soft, gl, result.tolerance, soft_ids=soft_ids,
                                                             gl_ids=gl_ids, soft_last=soft_last, gl_last=gl_last,
                                                             ambiguity=ambiguity)
            images["ambiguity"] = ambiguity.image(soft)
        result.verdict, result.reasons = verdict, reasons
        result.figures = figures | {name: round(value, 4) for name, value in times.items()}
        result.images.update(images)
    except Exception as error:  # noqa: BLE001 - reported as this scene's failure
        frames = traceback.extract_tb(error.__traceback__)
        place = f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else ""
        result.verdict = FAIL
        result.reasons.append(f"error: {type(error).__name__}: {_one_line(error)}{place}")
    finally:
        result.seconds = time.perf_counter() - start
    return result


def _check_in_worker(path: str, profile: str = "auto") -> SceneResult:
    """check_scene for a worker process (a top-level function: spawn pickles it by name)."""
    return check_scene(path, profile=profile)


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
        check: Callable[[str], SceneResult] | None = None, profile: str = "auto") -> list[SceneResult]:
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
    profile : str
        The verification profile of the default check ("auto", "strict", "spec").

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

    This is the plain path for the Python API: a crash in the GL driver ends
    this process (``jobs=1``) or breaks the pool (every pending scene FAILs),
    and nothing limits a scene's time. :func:`softras.verification.runner.run` (what
    ``softras conformance`` uses) supervises one worker process per job instead.
    """
    if jobs < 1:
        raise ConformanceError(f"-j {jobs}: need at least 1 process")
    if profile not in PROFILES:
        raise ConformanceError(f"--profile {profile}: must be one of {', '.join(PROFILES)}")
    results: dict[str, SceneResult] = {}
    names = [str(path) for path in paths]
    if jobs == 1 or len(names) <= 1:
        check = check or functools.partial(check_scene, profile=profile)
        for name in names:
            results[name] = check(name)
            if on_result is not None:
                on_result(results[name])
    else:
        check = check or functools.partial(_check_in_worker, profile=profile)
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
    """``{"pass": n, "quality_warning": n, "fail": n, "not_supported": n, "crash": n, "timeout": n,
    "flaky": n, "total": n}``."""
    tally = {verdict: sum(r.verdict == verdict for r in results)
             for verdict in (PASS, WARN, FAIL, NOT_SUPPORTED, CRASH, TIMEOUT, FLAKY)}
    tally["total"] = len(results)
    return tally
