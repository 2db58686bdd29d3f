"""What process isolation costs: the scenes of scenes/ in-process against supervised workers.

Each configuration runs in a fresh interpreter (imports, numba's cached kernels
and the GL context included, as a user's command pays them), interleaved
round by round so that a busy machine slows them alike; the table gives the
median wall time of each and its ratio to the in-process run:

- ``in-process -j 1``: ``softras.verification.conformance.run(paths)`` (the Python API;
  what ``softras conformance`` did before the runner);
- ``pool -j 2``: ``softras.verification.conformance.run(paths, jobs=2)`` (a
  ProcessPoolExecutor: what ``-j 2`` did before);
- ``runner -j 1`` and ``runner -j 2``: ``softras.verification.runner.run`` (supervised
  workers, as ``softras conformance`` now);
- ``in-process -j 1, report at the end``: ``conformance.run`` then
  ``report.write_report`` once (the old command's ``--report``);
- ``runner -j 1, report after each scene``: ``runner.run`` with a
  ``runner.ReportWriter`` (the pictures of a scene and the rewritten
  results.json, junit.xml, index.html and failures.csv, each fsynced);
- ``command -j 1 --report``: ``python -m softras conformance --report DIR``
  (as the last, plus the command's checks: every scene loaded, its own GL
  context for the capability record, the FLIP import).

    python scripts/runner_overhead.py [--rounds 3] [--markdown]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

_API = ("import sys; from softras import conformance, runner; paths = conformance.select(['scenes']); "
        "{call}; sys.exit(0 if len(results) == len(paths) else 1)")
CONFIGS = {
    "in-process -j 1": [sys.executable, "-c", _API.format(call="results = conformance.run(paths)")],
    "pool -j 2": [sys.executable, "-c", _API.format(call="results = conformance.run(paths, jobs=2)")],
    "runner -j 1": [sys.executable, "-c", _API.format(call="results = runner.run(paths).results")],
    "runner -j 2": [sys.executable, "-c", _API.format(call="results = runner.run(paths, jobs=2).results")],
    "in-process -j 1, report at the end": [sys.executable, "-c", _API.format(
        call="results = conformance.run(paths); from softras import report; "
             "report.write_report('{report}', results, {{}})")],
    "runner -j 1, report after each scene": [sys.executable, "-c", _API.format(
        call="writer = runner.ReportWriter('{report}', paths, {{}}); "
             "results = runner.run(paths, on_result=writer.add).results; writer.write()")],
    "command -j 1 --report": [sys.executable, "-m", "softras", "conformance", "--report", "{report}"],
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3, help="runs of each configuration (median; default 3)")
    args = parser.parse_args()
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    times: dict[str, list[float]] = {name: [] for name in CONFIGS}
    loads = []
    for round_ in range(args.rounds):
        for name, command in CONFIGS.items():
            report = tempfile.mkdtemp(prefix="softras-overhead-")
            command = [part.format(report=report) for part in command]
            start = time.perf_counter()
            run = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True)
            times[name].append(time.perf_counter() - start)
            loads.append(os.getloadavg()[0])
            if run.returncode != 0:
                print(f"{name}: exit {run.returncode}\n{run.stderr[-2000:]}", file=sys.stderr)
                return 1
            print(f"round {round_ + 1} {name}: {times[name][-1]:.2f} s", file=sys.stderr, flush=True)
    base = statistics.median(times["in-process -j 1"])
    print(f"{os.cpu_count()} cores, load average during the runs {min(loads):.1f}-{max(loads):.1f}; "
          f"median of {args.rounds} runs each, wall time of a fresh process\n")
    print("| configuration | median | runs | ratio to in-process -j 1 |")
    print("|---|---|---|---|")
    for name, values in times.items():
        runs = ", ".join(f"{value:.1f}" for value in values)
        print(f"| {name} | {statistics.median(values):.2f} s | {runs} | {statistics.median(values) / base:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
