#!/usr/bin/env python3
"""Where numba's compile time goes: render one scene on a cold cache and
print, per compiled softras function, the seconds of numba's passes (total,
its inliner, type inference; LLVM's own optimisation is not in these).

    NUMBA_CACHE_DIR=$(mktemp -d) python scripts/compile_profile.py scenes/demo.json

Run it with an empty NUMBA_CACHE_DIR: a function loaded from the cache was
not compiled and has no figures (docs/speed.md, "Compile time").
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import resource
import time

import softras
from softras.kernels import prepare
from softras.renderer import render_scene
from softras.scene import load_scene


def dispatchers():
    """(name, dispatcher) of every compiled function softras defines at module
    level, directly or in a module-level dict or tuple
    (`softras.kernels.prepare.dispatchers`), each once."""
    modules = []
    for info in pkgutil.walk_packages(softras.__path__, "softras."):
        try:
            modules.append(importlib.import_module(info.name))
        except ImportError:
            continue
    seen = set()
    for name, dispatcher in prepare.dispatchers(modules).items():
        if id(dispatcher) not in seen:
            seen.add(id(dispatcher))
            yield name, dispatcher


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="scene file to render (default options)")
    args = parser.parse_args()
    start = time.perf_counter()
    render_scene(load_scene(args.scene))
    print(f"first render {time.perf_counter() - start:.1f} s, peak RSS "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    rows = []
    for name, dispatcher in dispatchers():
        for cres in dispatcher.overloads.values():
            passes = (cres.metadata or {}).get("pipeline_times", {}).get("nopython", {})     # (None: from the cache)
            total = sum(t.run for t in passes.values())
            inline = sum(t.run for k, t in passes.items() if "inline_inlinables" in k)
            typing = sum(t.run for k, t in passes.items() if "type_inference" in k)
            rows.append((total, inline, typing, name))
    print(f"{'total s':>8s} {'inliner':>8s} {'typing':>8s}  function (nested compiles count in their callers too)")
    for total, inline, typing, name in sorted(rows, reverse=True):
        print(f"{total:8.2f} {inline:8.2f} {typing:8.2f}  {name}")


if __name__ == "__main__":
    main()
