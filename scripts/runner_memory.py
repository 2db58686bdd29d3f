"""The memory a conformance check adds to a warm worker, against softras.verification.runner's estimate.

For each generated scene (a perspective grid, optionally textured, at a size,
sample count and triangle count), a fresh process checks a tiny scene of the
same kind first (imports, numba's cached kernels, the GL context), then the
scene itself with ``softras.verification.conformance.check_scene``, and reports how far its
peak resident memory (``VmHWM``) rose. Beside it: ``softras.verification.runner.
estimate_bytes`` of the scene, which must not be below the measurement
(``softras.verification.runner.MEMORY_MODEL`` was fitted to these figures).

    python scripts/runner_memory.py [--quick]

Each case is one process (seconds to tens of seconds for 2048^2); --quick
skips the largest. Linux only (/proc/self/status).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

CASES = [
    {"w": 256, "h": 256}, {"w": 512, "h": 512}, {"w": 1024, "h": 1024}, {"w": 2048, "h": 2048},
    {"w": 512, "h": 512, "samples": 4}, {"w": 1024, "h": 1024, "samples": 4},
    {"w": 256, "h": 256, "cols": 100, "rows": 100}, {"w": 256, "h": 256, "cols": 300, "rows": 300},
    {"w": 256, "h": 256, "tex": 1024}, {"w": 256, "h": 256, "tex": 4096},
]
QUICK_SKIPS = ({"w": 2048, "h": 2048}, {"w": 256, "h": 256, "cols": 300, "rows": 300})


def scene(w, h, samples=1, cols=8, rows=8, tex=None) -> dict:
    """A grid of cols x rows quads tilted towards the camera, vertex-coloured or checker-textured."""
    data = {"softras_scene": 1, "width": w, "height": h, "samples": samples, "background": [0, 0, 0, 1],
            "camera": {"projection": "perspective", "fov_y": 60, "near": 0.5, "far": 20, "eye": [0, 0, 2.2],
                       "target": [0, 0, 0]},
            "nodes": [{"name": "grid", "rotate": [20, 1, 0, 0],
                       "mesh": {"procedural": "grid", "cols": cols, "rows": rows, "size": [2.4, 2.4],
                                "corner_colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]}}]}
    if tex:
        data["textures"] = {"t": {"procedural": "checker", "size": [tex, tex], "squares": 8,
                                  "min_filter": "linear_mipmap_linear", "mag_filter": "linear"}}
        data["nodes"][0]["material"] = {"texture": "t"}
    return data


def _status(key: str) -> int:
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    raise KeyError(key)


def measure(case: dict) -> dict:
    """In this process: warm up on a tiny scene of the kind, then check the case; its peak RSS rise."""
    from softras.verification import conformance, runner
    from softras.scene import load_scene

    folder = tempfile.mkdtemp()

    def write(data, name):
        path = os.path.join(folder, name + ".json")
        with open(path, "w") as handle:
            json.dump(data, handle)
        return path

    small = dict(case, w=16, h=12, cols=2, rows=2, tex=8 if case.get("tex") else None)
    conformance.check_scene(write(scene(**small), "small"))
    before, resident = _status("VmHWM"), _status("VmRSS")
    path = write(scene(**case), "case")
    start = time.perf_counter()
    result = conformance.check_scene(path)
    return {"case": case, "verdict": result.verdict, "worker_rss": resident, "peak_rise": _status("VmHWM") - before,
            "estimate": runner.estimate_bytes(runner.scene_footprint(load_scene(path))),
            "seconds": round(time.perf_counter() - start, 2)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="skip the largest cases")
    parser.add_argument("--one", default=None, help=argparse.SUPPRESS)   # a case, in its own process
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(measure(json.loads(args.one))))
        return 0
    print("| case | verdict | worker RSS | peak rise | estimate | estimate / rise | check |")
    print("|---|---|---|---|---|---|---|")
    worst = 0
    for case in CASES:
        if args.quick and case in QUICK_SKIPS:
            continue
        run = subprocess.run([sys.executable, __file__, "--one", json.dumps(case)], capture_output=True, text=True)
        if run.returncode != 0:
            print(f"| {case} | error: {run.stderr.strip().splitlines()[-1:]} |")
            worst = 1
            continue
        row = json.loads(run.stdout.strip().splitlines()[-1])
        ratio = row["estimate"] / max(row["peak_rise"], 1)
        worst = worst or ratio < 1
        print(f"| {case} | {row['verdict']} | {row['worker_rss'] / 2**20:.0f} MiB | {row['peak_rise'] / 2**20:.0f} MiB "
              f"| {row['estimate'] / 2**20:.0f} MiB | {ratio:.2f} | {row['seconds']} s |", flush=True)
    return 1 if worst else 0


if __name__ == "__main__":
    sys.exit(main())
