"""The conformance runner: scenes in supervised worker processes, as GPU teams run their suites.

On a real GPU the thing under test is a driver, and drivers crash, hang and
run out of memory. ``softras conformance`` therefore runs every check in a
worker process watched by this one (the supervisor), the way Mesa CI's
``deqp-runner``, piglit's ``--timeout`` and pytest-xdist's worker restart do:

* **crash isolation** -- ``jobs`` long-lived workers (multiprocessing
  ``spawn``: a fresh interpreter each, its own EGL context; GL contexts and
  ``fork`` do not mix) check scene after scene, so start-up (imports, numba's
  cached kernels, the GL context) is paid once per worker. A worker that dies
  (a signal such as SIGSEGV in the GL driver, SIGKILL from the kernel's
  out-of-memory killer, an exit status) costs only the scene it was checking:
  that scene gets the verdict CRASH with the signal or status and the last
  lines the worker wrote (its stdout and stderr, file descriptors 1 and 2,
  go to a log file; :mod:`faulthandler` adds the Python stack on a fatal
  signal), a new worker starts and the run goes on. With ``jobs=1`` too.
* **time limits** -- a scene whose check has not answered within
  ``timeout`` seconds (:data:`DEFAULT_TIMEOUT`) gets TIMEOUT; its worker is
  killed (SIGKILL: a hung driver may ignore SIGTERM) and replaced. The clock
  stops while the worker compiles numba kernels (it reports numba's
  ``numba:compile`` events): the first run in a fresh checkout compiles them
  for minutes, once, and that is not the scene's time.
* **retries and flakes** -- ``retries`` re-runs a scene whose verdict is
  CRASH, TIMEOUT or FAIL up to that many times (stopping at the first
  attempt that conforms). When the attempts' verdicts differ the scene is
  FLAKY, with every attempt's outcome in ``SceneResult.attempts``
  (deqp-runner's flake handling). A FLAKY scene fails the run only when no
  attempt conformed (:meth:`SceneResult.failed`).
* **memory** -- a scene whose check would need more than ``max_memory``
  (by :func:`estimate_bytes`, from its size, samples, triangles and texels,
  plus :data:`WORKER_BYTES` for the worker itself) is refused up front with
  NOT SUPPORTED, naming the estimate; scenes are started only while the
  estimates of those running fit the budget together. Workers are *not*
  limited with ``setrlimit``: RLIMIT_AS counts the virtual ranges drivers
  reserve (vendor GL and CUDA drivers reserve tens of GiB they never touch),
  so it would refuse a working driver; a scene that still runs out is
  a CRASH (SIGKILL) or a FAIL (MemoryError) and costs only itself.
* **baselines** -- :func:`load_baseline` reads the expected non-passing
  scenes of one implementation (Mesa CI's ``*-fails.txt`` / ``*-flakes.txt``
  in one file: ``scene,VERDICT`` lines); :func:`compare_baseline` lists new
  failures and unexpected passes.
* **nothing lost** -- :class:`ReportWriter` rewrites results.json, junit.xml
  and index.html after every scene (each atomically) and a
  ``failures.csv`` baseline; SIGINT or SIGTERM stops the workers and leaves
  the report of what finished (``"complete": false``, the ``pending``
  scenes); :func:`load_resume` lets ``--resume DIR`` finish it.

Fault injection (tests only): the environment variable ``SOFTRAS_TEST_FAULT``
(:data:`FAULT_ENV`), read only inside workers, makes a worker misbehave on
named scenes: ``"crash:a,hang:b,raise:c,exit:d,abort:e,flaky:f"`` -- crash
with SIGSEGV, hang forever, raise inside softras's render (a FAIL), exit with
status 3, ``abort()``, or crash on the first attempt only (the marker files
live in the folder named by ``SOFTRAS_TEST_FAULT_DIR``, so this holds across
worker processes; a hanging worker also writes its pid there, ``b.pid``, for
a test to kill it from outside). Never set it outside tests.

Exit status of ``softras conformance`` (:func:`exit_status`): 0 when no scene
fails (or, with a baseline, the results match it), 1 on a failing scene (or
a new failure or unexpected pass against the baseline), 2 on bad input,
130 when interrupted.

Why one module of ~1040 lines: the supervisor, the worker loop and the
protocol between them (messages, deadlines, retries, baselines, resume) are
one concurrent design whose invariants cross those parts; the report itself
is written by `softras.verification.report`.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math
import os
import signal
import sys
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from softras.verification.conformance import (CRASH, FAIL, FLAKY, NOT_SUPPORTED, PASS, TIMEOUT, VERDICT_NAMES,
                                 VERDICT_ORDER, WARN, ConformanceError, SceneResult, counts)

__all__ = [
    "DEFAULT_TIMEOUT", "STARTUP_TIMEOUT", "DEFAULT_MEMORY_FRACTION", "WORKER_BYTES", "FAULT_ENV", "FAULT_DIR_ENV",
    "EXIT_OK", "EXIT_FAILED", "EXIT_ERROR", "EXIT_INTERRUPTED",
    "RunnerError", "RunOutcome", "Baseline", "BaselineCheck", "ReportWriter",
    "run", "combine_attempts", "parse_faults", "parse_size", "format_size", "default_max_memory",
    "scene_footprint", "estimate_bytes", "parse_baseline", "load_baseline", "compare_baseline",
    "failures_csv", "run_options", "load_resume", "result_from_dict", "exit_status", "unique_names",
    "interrupts", "conformance_command",
]

#: Seconds one scene's check may take (``--timeout``; 0 = no limit). Warm, the
#: slowest scene of scenes/ takes under 2 s here; 300 s leaves room for a slow
#: driver, softpipe and a busy machine, while a hang costs five minutes, not a CI job.
#: numba's compilations do not count (see the module's docstring).
DEFAULT_TIMEOUT = 300.0

#: Seconds a new worker may take to import softras and create its GL context.
STARTUP_TIMEOUT = 300.0

#: ``--max-memory`` by default: this fraction of the machine's physical memory.
DEFAULT_MEMORY_FRACTION = 0.5

#: A warm worker's own resident memory (measured: 0.27 GB with llvmpipe), rounded up.
WORKER_BYTES = 400 * 2**20

#: The test-only fault injection variable, and the folder of its ``flaky`` markers.
FAULT_ENV = "SOFTRAS_TEST_FAULT"
FAULT_DIR_ENV = "SOFTRAS_TEST_FAULT_DIR"
FAULT_KINDS = ("crash", "abort", "exit", "hang", "raise", "flaky")

#: Exit statuses of ``softras conformance``.
EXIT_OK, EXIT_FAILED, EXIT_ERROR, EXIT_INTERRUPTED = 0, 1, 2, 130

#: Verdicts that ``retries`` re-runs.
RETRIED = (FAIL, CRASH, TIMEOUT)

#: Lines of a dead or killed worker's output kept in its scene's reasons.
TAIL_LINES = 12


class RunnerError(ConformanceError):
    """Bad input for a run (a baseline, a --resume folder, an option) or a worker that cannot start; one line."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------------
# Attempts and flakes


def _attempt_record(result: SceneResult, number: int) -> dict:
    return {"attempt": number, "verdict": result.verdict, "reasons": list(result.reasons),
            "seconds": round(result.seconds, 4)}


def combine_attempts(attempts: list[SceneResult]) -> SceneResult:
    """One scene's result from its attempts (the last one's figures and pictures).

    One attempt: that result as it is. Several with the same verdict: the
    last, with ``attempts`` filled in and a closing reason. Verdicts that
    differ: FLAKY, the reasons listing each attempt's verdict and first reason.
    ``seconds`` is the sum over the attempts.
    """
    last = attempts[-1]
    if len(attempts) == 1:
        return last
    records = [_attempt_record(result, number) for number, result in enumerate(attempts, 1)]
    verdicts = [result.verdict for result in attempts]
    seconds = sum(result.seconds for result in attempts)
    if len(set(verdicts)) == 1:
        reasons = list(last.reasons) + [f"the same verdict in all {len(attempts)} attempts"]
        return dataclasses.replace(last, reasons=reasons, attempts=records, seconds=seconds)
    reasons = ["verdict changed between attempts: " + ", ".join(VERDICT_NAMES[v] for v in verdicts)]
    for record in records:
        first = f": {record['reasons'][0]}" if record["reasons"] else ""
        reasons.append(f"attempt {record['attempt']}: {VERDICT_NAMES[record['verdict']]}{first}")
    return dataclasses.replace(last, verdict=FLAKY, reasons=reasons, attempts=records, seconds=seconds)


# ---------------------------------------------------------------------------
# Fault injection (tests only; read inside workers)


def parse_faults(text: str) -> dict[str, str]:
    """``"crash:a,hang:b"`` -> ``{"a": "crash", "b": "hang"}``; ValueError on an unknown kind."""
    faults = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        kind, colon, name = item.partition(":")
        if not colon or kind not in FAULT_KINDS or not name:
            raise ValueError(f"{FAULT_ENV}: {item!r} is not KIND:SCENE with KIND one of {', '.join(FAULT_KINDS)}")
        faults[name] = kind
    return faults


def _raising_render(scene):
    raise RuntimeError(f"{FAULT_ENV}: injected error")


def _inject_fault(name: str, kind: str | None):
    """Misbehave as asked for scene ``name``; returns a render_soft for ``raise``, else None."""
    if kind is None:
        return None
    if kind == "flaky":
        marker = Path(os.environ.get(FAULT_DIR_ENV) or tempfile.gettempdir()) / f"{name}.flaky"
        if marker.exists():
            return None
        marker.write_text("crashed once\n", encoding="utf-8")
        kind = "crash"
    print(f"{FAULT_ENV}: {kind} on scene {name}", file=sys.stderr, flush=True)
    if kind == "crash":
        os.kill(os.getpid(), signal.SIGSEGV)
    elif kind == "abort":
        os.abort()
    elif kind == "exit":
        os._exit(3)
    elif kind == "hang":
        if os.environ.get(FAULT_DIR_ENV):   # for a test that kills the worker from outside
            (Path(os.environ[FAULT_DIR_ENV]) / f"{name}.pid").write_text(f"{os.getpid()}\n", encoding="utf-8")
        while True:
            time.sleep(3600)
    return _raising_render


# ---------------------------------------------------------------------------
# Memory


_SIZE_UNITS = {"": 1, "B": 1, "K": 2**10, "KB": 2**10, "KIB": 2**10, "M": 2**20, "MB": 2**20, "MIB": 2**20,
               "G": 2**30, "GB": 2**30, "GIB": 2**30, "T": 2**40, "TB": 2**40, "TIB": 2**40}


def physical_memory() -> int:
    """This machine's physical memory in bytes."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def default_max_memory() -> int:
    """:data:`DEFAULT_MEMORY_FRACTION` of the machine's physical memory."""
    return int(DEFAULT_MEMORY_FRACTION * physical_memory())


def parse_size(text: str) -> int:
    """``--max-memory``: ``"8G"``, ``"512M"``, ``"1.5GiB"``, ``"123456"`` (bytes) or ``"40%"`` of the machine."""
    raw = str(text).strip().upper()
    try:
        if raw.endswith("%"):
            value = float(raw[:-1]) / 100 * physical_memory()
        else:
            number = raw.rstrip("KMGTIB")
            value = float(number) * _SIZE_UNITS[raw[len(number):]]
    except (KeyError, ValueError):
        value = -1
    if not value > 0 or not math.isfinite(value):
        raise RunnerError(f"--max-memory {text}: expected a size such as 8G, 512M or 50%")
    return int(value)


def format_size(size: float) -> str:
    """Bytes as ``"1.2 GiB"`` / ``"340 MiB"``."""
    return f"{size / 2**30:.1f} GiB" if size >= 2**30 else f"{size / 2**20:.0f} MiB"


def _texels(texture) -> int:
    if texture.decoded is not None:
        return int(texture.decoded.shape[0] * texture.decoded.shape[1])
    if texture.size is not None:
        return int(texture.size[0] * texture.size[1])
    try:
        from PIL import Image

        with Image.open(texture.image) as image:
            return image.width * image.height
    except (OSError, ValueError, TypeError):
        return 0


def scene_footprint(scene) -> dict:
    """What a check's memory grows with: ``pixels``, ``samples``, ``primitives`` and ``texels``."""
    return {"pixels": scene.width * scene.height, "samples": scene.samples,
            "primitives": sum(len(draw.mesh.indices) for draw in scene.draws),
            "texels": sum(_texels(texture) for texture in scene.textures.values())}


#: Bytes per pixel, per pixel-sample, per primitive and per texel of level 0, fitted
#: to the peak resident memory a check adds to a warm worker (scripts/runner_memory.py:
#: 256^2..2048^2 at 1 sample 300-330 B/px, 512^2 and 1024^2 at 4 samples 530-540 B/px,
#: 20k and 180k triangles 3.6 and 2.0 kB each, 1024^2 and 4096^2 texels 9 and 13 B each).
MEMORY_MODEL = {"pixel": 240, "sample": 75, "primitive": 3000, "texel": 16, "margin": 1.25}


def estimate_bytes(footprint: dict) -> int:
    """The peak memory a check of a scene adds to its worker, by :data:`MEMORY_MODEL` (an upper estimate)."""
    m = MEMORY_MODEL
    total = (m["pixel"] * footprint["pixels"] + m["sample"] * footprint["pixels"] * footprint["samples"]
             + m["primitive"] * footprint["primitives"] + m["texel"] * footprint["texels"])
    return int(m["margin"] * total)


def _estimate(path: str) -> tuple[int | None, object]:
    """(estimate, scene) for a scene file, (None, None) when it cannot be loaded (the check will say why)."""
    from softras.scene import load_scene

    try:
        scene = load_scene(path)
    except (OSError, ValueError):
        return None, None
    return estimate_bytes(scene_footprint(scene)), scene


def _refused(path: str, name: str, scene, estimate: int, budget: int) -> SceneResult:
    return SceneResult(
        name=name, path=path, verdict=NOT_SUPPORTED, description=getattr(scene, "description", ""),
        reasons=[f"refused up front: the check would need about {format_size(estimate)} by softras's estimate "
                 f"({scene.width}x{scene.height}, {scene.samples} sample{'s' if scene.samples != 1 else ''}), "
                 f"{format_size(estimate + WORKER_BYTES)} with its worker, over --max-memory "
                 f"{format_size(budget)}"],
        figures={"estimated_bytes": estimate})


# ---------------------------------------------------------------------------
# The worker process


def _worker_setup(log_path: str) -> None:
    """In a new worker: output to the log file, fatal signals dumped, Ctrl-C left to the supervisor."""
    import faulthandler

    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    sys.stdout.flush()
    sys.stderr.flush()
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    sys.stdout = open(1, "w", encoding="utf-8", errors="replace", buffering=1, closefd=False)
    sys.stderr = open(2, "w", encoding="utf-8", errors="replace", buffering=1, closefd=False)
    faulthandler.enable(file=sys.stderr)
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # the terminal's Ctrl-C: the supervisor stops us
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:   # die with the supervisor (Linux), even when hung in a driver
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)   # PR_SET_PDEATHSIG
        if os.getppid() == 1:
            os._exit(1)
    except (OSError, AttributeError):
        pass


def _compile_listener(conn):
    """A numba event listener that tells the supervisor when compilation starts and ends."""
    from numba.core import event

    class Listener(event.Listener):
        depth = 0

        def on_start(self, ev):
            if self.depth == 0:
                conn.send(("compiling", None))
            self.depth += 1

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0:
                conn.send(("compiled", None))

    return Listener()


def _worker_main(conn, log_path: str, profile: str) -> None:
    """A worker: start up, say ready, then check each scene it is sent until its pipe closes."""
    _worker_setup(log_path)
    try:
        faults = parse_faults(os.environ.get(FAULT_ENV, ""))
        import glref
        from numba.core import event

        from softras.verification import ambiguity, metrics, verifier  # noqa: F401 - imported once, not per scene
        from softras.verification.conformance import check_scene

        glref.info()   # the GL context, once
        event.register("numba:compile", _compile_listener(conn))
    except BaseException as error:  # noqa: BLE001 - told to the supervisor, which stops the run
        conn.send(("failed", f"{type(error).__name__}: {_one_line(error)}"))
        return
    conn.send(("ready", os.getpid()))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message[0] != "check":
            return
        _, path, attempt = message
        name = Path(path).stem
        print(f"[softras worker {os.getpid()}] {name} (attempt {attempt})", file=sys.stderr, flush=True)
        render_soft = _inject_fault(name, faults.get(name))
        result = check_scene(path, profile=profile, render_soft=render_soft)
        conn.send(("result", result))


class _Worker:
    """The supervisor's handle on one worker process: its pipe, log, task and deadline."""

    def __init__(self, context, slot: int, generation: int, log_dir: Path, profile: str):
        self.slot = slot
        self.log_path = log_dir / f"worker-{slot}-{generation}.log"
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker_main, args=(child, str(self.log_path), profile),
                                       name=f"softras-worker-{slot}", daemon=True)
        self.process.start()
        child.close()
        self.ready = False
        self.failed: str | None = None
        self.task: tuple[str, int] | None = None
        self.deadline = time.monotonic() + STARTUP_TIMEOUT
        self.paused: float | None = None   # seconds left, while numba compiles
        self.started = 0.0
        self.log_offset = 0
        self.estimate = 0
        self.messages: list = []

    def assign(self, path: str, attempt: int, timeout: float, estimate: int) -> None:
        """Send one scene to check."""
        try:
            self.log_offset = self.log_path.stat().st_size
        except OSError:
            self.log_offset = 0
        self.task = (path, attempt)
        self.estimate = estimate
        self.started = time.monotonic()
        self.deadline = self.started + timeout if timeout > 0 else math.inf
        self.paused = None
        self.conn.send(("check", path, attempt))

    def receive(self) -> bool:
        """Read every message waiting; False when the pipe is closed (the worker is gone)."""
        try:
            while self.conn.poll():
                self.messages.append(self.conn.recv())
        except (EOFError, OSError):
            return False
        return True

    def handle_timing(self, kind: str) -> None:
        """Stop the clock while numba compiles, restart it after."""
        now = time.monotonic()
        if kind == "compiling" and self.paused is None:
            self.paused = self.deadline - now
            self.deadline = math.inf
        elif kind == "compiled" and self.paused is not None:
            self.deadline = now + self.paused
            self.paused = None

    def tail(self) -> list[str]:
        """The last lines the worker wrote since its current task began."""
        try:
            with open(self.log_path, "rb") as handle:
                handle.seek(max(self.log_offset, handle.seek(0, os.SEEK_END) - 65536))
                text = handle.read().decode("utf-8", errors="replace")
        except OSError:
            return []
        lines = [line.rstrip() for line in text.splitlines() if line.strip()]
        return [line if len(line) <= 300 else line[:297] + "..." for line in lines[-TAIL_LINES:]]

    def stop(self) -> None:
        """End the process with SIGKILL: a hung driver may ignore anything else, and an idle
        worker holds nothing to clean up (a clean exit takes 0.4 s here)."""
        if self.process.is_alive():
            self.process.kill()
        self.process.join(5)
        self.conn.close()


def describe_exit(exitcode: int | None) -> str:
    """How a worker ended: ``killed by signal SIGSEGV (Segmentation fault)``, ``exit status 3``."""
    if exitcode is None:
        return "it closed its pipe"
    if exitcode < 0:
        try:
            name, text = signal.Signals(-exitcode).name, signal.strsignal(-exitcode)
        except ValueError:
            name, text = f"signal {-exitcode}", None
        note = "; the kernel's out-of-memory killer sends SIGKILL" if -exitcode == signal.SIGKILL else ""
        return f"killed by signal {name}" + (f" ({text})" if text else "") + note
    return f"exit status {exitcode}"


def _output_reasons(lines: list[str]) -> list[str]:
    if not lines:
        return ["the worker wrote nothing during this scene"]
    return ["the worker's last output:"] + [f"| {line}" for line in lines]


# ---------------------------------------------------------------------------
# The supervisor


@dataclass
class RunOutcome:
    """What :func:`run` did: finished results by path, scenes not finished, whether it was interrupted."""

    results: dict = field(default_factory=dict)
    pending: list = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0

    def ordered(self, paths) -> list[SceneResult]:
        """The finished results in the order of ``paths``."""
        return [self.results[str(path)] for path in paths if str(path) in self.results]


def unique_names(paths) -> dict[str, str]:
    """Each path's scene name: its file stem, ``stem-2``, ``stem-3`` ... for repeats (the report's folders)."""
    names, taken = {}, set()
    for path in paths:
        stem = name = Path(path).stem
        suffix = 2
        while name in taken:
            name, suffix = f"{stem}-{suffix}", suffix + 1
        taken.add(name)
        names[str(path)] = name
    return names


def run(paths, *, jobs: int = 1, timeout: float = DEFAULT_TIMEOUT, retries: int = 0, profile: str = "auto",
        max_memory: int | None = None, on_result: Callable[[SceneResult], None] | None = None,
        on_retry: Callable[[SceneResult, int], None] | None = None, names: dict | None = None) -> RunOutcome:
    """Check scenes in ``jobs`` supervised worker processes (see the module's docstring).

    Parameters
    ----------
    paths : list of path
        Scene files (:func:`softras.verification.conformance.select`).
    jobs : int
        Worker processes, one scene each at a time (at least 1).
    timeout : float
        Seconds per scene check; 0 = no limit.
    retries : int
        Re-runs of a scene whose verdict is CRASH, TIMEOUT or FAIL.
    profile : str
        The verification profile ("auto", "strict", "spec").
    max_memory : int, optional
        The memory budget in bytes (default :func:`default_max_memory`).
    on_result : callable, optional
        Called with each scene's final result as it finishes (progress, reports).
    on_retry : callable, optional
        Called with an attempt's result and the attempt's number when the scene will run again.
    names : dict, optional
        Each path's scene name (default :func:`unique_names` of ``paths``).

    Returns
    -------
    RunOutcome
        Interrupted (Ctrl-C; SIGTERM too inside :func:`interrupts`) when it
        was: the workers are stopped and the scenes not finished are listed.

    Raises
    ------
    RunnerError
        No worker could start (twice in a row), with the reason.
    """
    import multiprocessing
    from multiprocessing.connection import wait

    if jobs < 1:
        raise RunnerError(f"-j {jobs}: need at least 1 process")
    if timeout < 0 or retries < 0:
        raise RunnerError("--timeout and --retries must be >= 0")
    start = time.monotonic()
    paths = [str(path) for path in paths]
    names = dict(names) if names is not None else unique_names(paths)
    budget = default_max_memory() if max_memory is None else max_memory
    outcome = RunOutcome()
    attempts: dict[str, list[SceneResult]] = collections.defaultdict(list)

    def finish(path: str, result: SceneResult) -> None:
        result.name, result.path = names[path], path
        attempts[path].append(result)
        if result.verdict in RETRIED and len(attempts[path]) <= retries:
            queue.appendleft(path)
            if on_retry is not None:
                on_retry(result, len(attempts[path]))
            return
        final = combine_attempts(attempts.pop(path))
        outcome.results[path] = final
        if on_result is not None:
            on_result(final)

    queue: collections.deque = collections.deque()
    estimates = {}
    context = multiprocessing.get_context("spawn")
    log_dir = Path(tempfile.mkdtemp(prefix="softras-workers-"))
    workers: list[_Worker | None] = [None] * min(jobs, max(len(paths), 1))
    generation = 0
    start_failures = 0

    def start_workers() -> None:
        nonlocal generation
        for slot, worker in enumerate(workers):
            if worker is None:
                generation += 1
                workers[slot] = _Worker(context, slot, generation, log_dir, profile)

    def next_fitting() -> str | None:
        busy = [w for w in workers if w is not None and w.task is not None]
        free = budget - WORKER_BYTES * sum(w is not None for w in workers) - sum(w.estimate for w in busy)
        for path in queue:
            if not busy or estimates[path] <= free:
                queue.remove(path)
                return path
        return None

    def lost(worker: _Worker, verdict: str, reasons: list[str]) -> None:
        """The worker died or was killed: charge its scene, forget the worker."""
        nonlocal start_failures
        workers[worker.slot] = None
        if worker.task is not None:
            path, _ = worker.task
            seconds = time.monotonic() - worker.started
            worker.stop()
            finish(path, SceneResult(name=names[path], path=path, verdict=verdict, reasons=reasons,
                                     seconds=seconds))
            return
        worker.stop()
        if not worker.ready:
            start_failures += 1
            if start_failures >= 2 or worker.failed:
                why = worker.failed or "; ".join(worker.tail()[-3:]) or describe_exit(worker.process.exitcode)
                raise RunnerError(f"a conformance worker process could not start: {_one_line(why)}")

    try:
        for path in paths:   # the workers start with the first scene to check, and start up meanwhile
            estimate, scene = _estimate(path)
            if estimate is not None and estimate + WORKER_BYTES > budget:
                finish(path, _refused(path, names[path], scene, estimate, budget))
            else:
                estimates[path] = estimate or 0
                queue.append(path)
                start_workers()
        while queue or any(w is not None and w.task is not None for w in workers):
            for slot, worker in enumerate(workers):
                if worker is None and queue:
                    start_workers()
                elif worker is not None and worker.ready and worker.task is None and queue:
                    path = next_fitting()
                    if path is not None:
                        worker.assign(path, len(attempts[path]) + 1, timeout, estimates[path])
            live = [w for w in workers if w is not None]
            wait_for = min((w.deadline for w in live), default=math.inf) - time.monotonic()
            wait([w.conn for w in live] + [w.process.sentinel for w in live], timeout=min(max(wait_for, 0.0), 1.0))
            for worker in live:
                open_ = worker.receive()
                while worker.messages:
                    kind, *data = worker.messages.pop(0)
                    if kind == "ready":
                        worker.ready, worker.deadline, start_failures = True, math.inf, 0
                    elif kind == "failed":
                        worker.failed = data[0]
                    elif kind in ("compiling", "compiled"):
                        worker.handle_timing(kind)
                    elif kind == "result" and worker.task is not None:
                        path, _ = worker.task
                        worker.task, worker.deadline = None, math.inf
                        finish(path, data[0])
                if not open_ or not worker.process.is_alive():
                    worker.process.join(5)
                    exitcode = worker.process.exitcode
                    lost(worker, CRASH, [f"the worker process died during the check: {describe_exit(exitcode)}"]
                         + _output_reasons(worker.tail()))
                elif time.monotonic() >= worker.deadline:
                    if worker.task is None:
                        worker.failed = f"no answer within {STARTUP_TIMEOUT:g} s of starting"
                        lost(worker, CRASH, [])
                    else:
                        lost(worker, TIMEOUT, [f"no verdict within {timeout:g} s (--timeout): the worker "
                                               f"was killed"] + _output_reasons(worker.tail()))
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        for worker in workers:
            if worker is not None:
                worker.stop()
        import shutil

        shutil.rmtree(log_dir, ignore_errors=True)
    outcome.pending = [path for path in paths if path not in outcome.results]
    outcome.seconds = time.monotonic() - start
    return outcome


@contextmanager
def interrupts():
    """SIGTERM raises KeyboardInterrupt, as SIGINT does (main thread only), until the block ends."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def raise_interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def _signals_ignored():
    """SIGINT and SIGTERM ignored while the final report is written (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


# ---------------------------------------------------------------------------
# Baselines


#: Verdict spellings a baseline may use (Mesa's ``Fail``, ``Crash``, ``Flake``, ``Skip`` among them).
_BASELINE_WORDS = {"FAIL": FAIL, "CRASH": CRASH, "TIMEOUT": TIMEOUT, "FLAKY": FLAKY, "FLAKE": FLAKY,
                   "QUALITY_WARNING": WARN, "WARN": WARN, "WARNING": WARN, "NOT_SUPPORTED": NOT_SUPPORTED,
                   "SKIP": NOT_SUPPORTED}


@dataclass
class Baseline:
    """Expected non-passing verdicts of one implementation: ``{scene name: verdict}``."""

    expected: dict
    source: str = ""


def parse_baseline(text: str, source: str = "baseline") -> Baseline:
    """Parse a baseline: one ``scene,VERDICT`` per line, ``#`` comments, blank lines.

    VERDICT: FAIL, CRASH, TIMEOUT, QUALITY_WARNING, NOT_SUPPORTED, or FLAKY (any
    verdict is accepted for that scene); case and ``-`` / space for ``_`` do
    not matter, and Mesa's ``Flake``, ``Warn`` and ``Skip`` are read too.
    RunnerError (``source:line: why``) on anything else or a scene listed twice.
    """
    expected = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, comma, word = (part.strip() for part in line.partition(","))
        verdict = _BASELINE_WORDS.get(word.upper().replace("-", "_").replace(" ", "_"))
        if not comma or not name or "," in word:
            raise RunnerError(f"{source}:{number}: expected 'scene,VERDICT', found {line!r}")
        if verdict is None:
            raise RunnerError(f"{source}:{number}: {word!r} is not an expected non-passing verdict (FAIL, CRASH, "
                              f"TIMEOUT, FLAKY, QUALITY_WARNING, NOT_SUPPORTED)")
        if name in expected:
            raise RunnerError(f"{source}:{number}: scene {name} is listed twice")
        expected[name] = verdict
    return Baseline(expected, source)


def load_baseline(path) -> Baseline:
    """Read a baseline file (:func:`parse_baseline`); RunnerError when it is missing or unreadable."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RunnerError(f"--baseline {path}: {getattr(error, 'strerror', None) or _one_line(error)}") from None
    return parse_baseline(text, str(path))


@dataclass
class BaselineCheck:
    """The results against a baseline: ``(scene, expected, got)`` triples, verdict keys.

    ``new_failures``: a scene that fails (:meth:`SceneResult.failed`) where
    the baseline expects it to conform, or fails differently from what the
    baseline lists. ``unexpected``: a listed scene that got another,
    non-failing verdict (an unexpected pass: update the baseline). FLAKY in
    the baseline accepts any verdict; scenes of the baseline not in the run are
    ignored (``-k``, ``--shard``).
    """

    new_failures: list = field(default_factory=list)
    unexpected: list = field(default_factory=list)
    source: str = ""

    @property
    def matches(self) -> bool:
        return not self.new_failures and not self.unexpected

    def to_dict(self) -> dict:
        rows = lambda items: [{"scene": s, "expected": e, "got": g} for s, e, g in items]  # noqa: E731
        return {"file": self.source, "matches": self.matches, "new_failures": rows(self.new_failures),
                "unexpected": rows(self.unexpected)}

    def lines(self) -> list[str]:
        """For the terminal: each finding, then the summary line."""
        out = []
        for title, items in (("new failure", self.new_failures), ("unexpected", self.unexpected)):
            for scene, expected, got in items:
                out.append(f"baseline: {title}: {scene}: expected {VERDICT_NAMES.get(expected, expected)}, "
                           f"got {VERDICT_NAMES[got]}")
        news, unexpected = len(self.new_failures), len(self.unexpected)
        out.append(f"baseline {self.source}: " + ("results match it" if self.matches else
                   f"{news} new failure{'s' if news != 1 else ''}, "
                   f"{unexpected} unexpected verdict{'s' if unexpected != 1 else ''}"))
        return out


def compare_baseline(results: list[SceneResult], baseline: Baseline) -> BaselineCheck:
    """New failures and unexpected verdicts of ``results`` against ``baseline`` (see :class:`BaselineCheck`)."""
    check = BaselineCheck(source=baseline.source)
    for result in results:
        expected = baseline.expected.get(result.name)
        if expected == FLAKY or expected == result.verdict:
            continue
        if expected is None:
            if result.failed():
                check.new_failures.append((result.name, PASS, result.verdict))
        elif result.failed():
            check.new_failures.append((result.name, expected, result.verdict))
        else:
            check.unexpected.append((result.name, expected, result.verdict))
    return check


def failures_csv(results: list[SceneResult], title: str = "") -> str:
    """Every scene that did not pass, ``name,VERDICT``: a baseline file for the next run."""
    words = {FAIL: "FAIL", CRASH: "CRASH", TIMEOUT: "TIMEOUT", FLAKY: "FLAKY", WARN: "QUALITY_WARNING",
             NOT_SUPPORTED: "NOT_SUPPORTED"}
    lines = [f"# softras conformance baseline{': ' + title if title else ''} (scene,VERDICT; --baseline FILE)"]
    lines += [f"{result.name},{words[result.verdict]}" for result in results if result.verdict != PASS]
    return "\n".join(lines) + "\n"


def exit_status(results: list[SceneResult], baseline: BaselineCheck | None = None,
                interrupted: bool = False) -> int:
    """130 interrupted; with a baseline 0 when the results match it, else 1; without, 1 when a scene failed."""
    if interrupted:
        return EXIT_INTERRUPTED
    if baseline is not None:
        return EXIT_OK if baseline.matches else EXIT_FAILED
    return EXIT_FAILED if any(result.failed() for result in results) else EXIT_OK


# ---------------------------------------------------------------------------
# Resuming


def run_options(paths, *, profile: str, timeout: float, retries: int, max_memory: int) -> dict:
    """What results depend on, stored in results.json: ``--resume`` needs the same."""
    return {"scenes": [str(Path(path).resolve()) for path in paths], "profile": profile, "timeout": timeout,
            "retries": retries, "max_memory": max_memory}


_OPTION_FLAGS = {"profile": "--profile", "timeout": "--timeout", "retries": "--retries",
                 "max_memory": "--max-memory"}


def result_from_dict(entry: dict, folder) -> SceneResult:
    """A scene's result back from results.json, its pictures read from ``folder``."""
    from softras.scene.imageio import ImageError, read_png

    if entry.get("verdict") not in VERDICT_NAMES:
        raise RunnerError(f"{folder}/results.json: scene {entry.get('name')!r} has no valid verdict")
    images = {}
    for key, relative in (entry.get("images") or {}).items():
        try:
            images[key] = read_png(Path(folder) / relative)
        except ImageError:
            pass   # the picture was lost: the report shows the scene without it
    try:
        return SceneResult(name=entry["name"], path=entry["path"], verdict=entry["verdict"],
                           reasons=list(entry.get("reasons", [])), description=entry.get("description", ""),
                           tolerance=dict(entry.get("tolerance", {})),
                           tolerance_source=entry.get("tolerance_source", ""), figures=dict(entry.get("figures", {})),
                           seconds=float(entry.get("seconds", 0.0)), images=images,
                           attempts=list(entry.get("attempts", [])))
    except (KeyError, TypeError, ValueError) as error:
        raise RunnerError(f"{folder}/results.json: a scene entry is malformed ({_one_line(error)})") from None


def load_resume(folder, paths, options: dict) -> tuple[dict, dict]:
    """The finished scenes of a stopped run in ``folder``, by path (as in ``paths``), and its results.json.

    RunnerError (one line) when the folder holds no readable results.json of
    a run, or that run's scenes or options (:func:`run_options`) differ from
    this one's. (The caller compares the GL: ``gl_renderer``.)
    """
    folder = Path(folder)
    where = f"--resume {folder}"
    try:
        data = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RunnerError(f"{where}: no results.json there (not a conformance report folder)") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise RunnerError(f"{where}: cannot read results.json: {_one_line(error)}") from None
    if not isinstance(data, dict) or not isinstance(data.get("options"), dict) or not isinstance(
            data.get("scenes"), list):
        raise RunnerError(f"{where}: results.json is not a resumable run (no options: written by another "
                          f"softras or another command)")
    stored = data["options"]
    if stored.get("scenes") != options["scenes"]:
        before, now = stored.get("scenes") or [], options["scenes"]
        raise RunnerError(f"{where}: that run checked {len(before)} scenes, this one {len(now)}"
                          f"{' others' if len(before) == len(now) else ''}: give the same paths, -k and --shard")
    for key, flag in _OPTION_FLAGS.items():
        if stored.get(key) != options[key]:
            raise RunnerError(f"{where}: that run used {flag} {stored.get(key)}, this one {options[key]}")
    by_resolved = {str(Path(path).resolve()): str(path) for path in paths}
    done = {}
    for entry in data["scenes"]:
        if not isinstance(entry, dict):
            raise RunnerError(f"{where}: results.json has a scene entry that is not an object")
        path = by_resolved.get(str(Path(str(entry.get("path", ""))).resolve()))
        if path is not None:
            result = result_from_dict(entry, folder)
            result.path = path
            done[path] = result
    return done, data


# ---------------------------------------------------------------------------
# The report, written as scenes finish


class ReportWriter:
    """Writes the report folder after every scene: pictures, then results.json, junit.xml, index.html, failures.csv.

    Each file is replaced atomically, so the folder always holds a valid
    report of the scenes finished so far (``"complete": false`` and the
    ``pending`` scenes until the end).
    """

    def __init__(self, folder, paths, meta: dict, done: dict | None = None, seconds_before: float = 0.0):
        self.folder = Path(folder)
        self.paths = [str(path) for path in paths]
        self.meta = dict(meta)
        self.results = dict(done or {})
        self.seconds_before = seconds_before
        self.start = time.monotonic()
        self.index = self.folder / "index.html"
        self.folder.mkdir(parents=True, exist_ok=True)

    def ordered(self) -> list[SceneResult]:
        return [self.results[path] for path in self.paths if path in self.results]

    def add(self, result: SceneResult) -> None:
        """Record a finished scene and rewrite the report."""
        from softras.verification.report import write_scene_images

        write_scene_images(self.folder, result)
        self.results[result.path] = result
        self.write()

    def write(self, *, interrupted: bool = False, baseline: BaselineCheck | None = None) -> Path:
        """Rewrite results.json, junit.xml, index.html and failures.csv."""
        from softras.scene.imageio import write_text_atomic
        from softras.verification.report import write_summary

        ordered = self.ordered()
        pending = [path for path in self.paths if path not in self.results]
        meta = self.meta | {"seconds": round(self.seconds_before + time.monotonic() - self.start, 3),
                            "complete": not pending, "interrupted": interrupted, "pending": pending}
        if baseline is not None:
            meta["baseline"] = baseline.to_dict()
        self.index = write_summary(self.folder, ordered, meta)
        title = f"{self.meta.get('gl_renderer')}, profile {self.meta.get('profile')}"
        write_text_atomic(self.folder / "failures.csv", failures_csv(ordered, title))
        return self.index


# ---------------------------------------------------------------------------
# The command


def _summary_line(results: list[SceneResult]) -> str:
    tally = counts(results)
    extra = "".join(f", {tally[verdict]} {VERDICT_NAMES[verdict].lower()}" for verdict in (CRASH, TIMEOUT, FLAKY)
                    if tally[verdict])
    return (f"{tally['total']} scene{'s' if tally['total'] != 1 else ''}: {tally['pass']} pass, "
            f"{tally['quality_warning']} quality warning, {tally['fail']} fail, {tally['not_supported']} "
            f"not supported{extra}")


def conformance_command(paths, *, jobs: int, profile: str, profile_text: str, timeout: float, retries: int,
                        max_memory: int, meta: dict, report=None, done: dict | None = None,
                        seconds_before: float = 0.0, baseline: Baseline | None = None, resume_hint: str = "",
                        out=None, err=None) -> int:
    """``softras conformance`` after its input checks: run, print, report; returns the exit status.

    ``done``: results of a resumed run (by path), not run again. ``meta``:
    the run's record for results.json (``options`` among it). Prints one line
    per scene that did not pass, the baseline's findings and the counts.
    """
    from softras.verification.conformance import ProgressBar

    out = out if out is not None else sys.stdout
    err = err if err is not None else sys.stderr
    done = dict(done or {})
    paths = [str(path) for path in paths]
    todo = [path for path in paths if path not in done]
    writer = ReportWriter(report, paths, meta, done, seconds_before) if report is not None else None
    bar = ProgressBar(len(paths), stream=err)
    bar.done = len(done)
    start = time.monotonic()
    finished = dict(done)

    def on_result(result: SceneResult) -> None:
        finished[result.path] = result
        bar.advance(result)
        if writer is not None:
            writer.add(result)

    def on_retry(result: SceneResult, attempt: int) -> None:
        err.write(f"retrying {result.name}: attempt {attempt} gave {VERDICT_NAMES[result.verdict]}\n")

    outcome = RunOutcome(interrupted=False)
    with interrupts():
        try:
            if writer is not None:
                writer.write()   # a resumable report before the first scene ends
            if todo:
                outcome = run(todo, jobs=jobs, timeout=timeout, retries=retries, profile=profile,
                              max_memory=max_memory, on_result=on_result, on_retry=on_retry,
                              names=unique_names(paths))
        except KeyboardInterrupt:
            outcome.interrupted = True
        finally:
            bar.close()
    with _signals_ignored():
        results = [finished[path] for path in paths if path in finished]
        check = compare_baseline(results, baseline) if baseline is not None and not outcome.interrupted else None
        for result in sorted(results, key=lambda r: (VERDICT_ORDER[r.verdict], r.name)):
            print(result.line(), file=out)
            if result.verdict != PASS:
                for reason in result.reasons[1:]:
                    print(f"{'':<16}{reason}", file=out)
        if writer is not None:
            index = writer.write(interrupted=outcome.interrupted, baseline=check)
            print(f"report: {index}", file=out)
        seconds = seconds_before + time.monotonic() - start
        if outcome.interrupted:
            missing = len(paths) - len(results)
            print(f"conformance: interrupted: {len(results)} of {len(paths)} scenes finished, {missing} not run"
                  + (f"; {resume_hint}" if resume_hint and writer is not None else ""), file=out)
        if check is not None:
            for line in check.lines():
                print(line, file=out)
        print(f"conformance: {_summary_line(results)} in {seconds:.1f} s (-j {jobs}, profile {profile_text})",
              file=out)
        out.flush()
    return exit_status(results, check, outcome.interrupted)
