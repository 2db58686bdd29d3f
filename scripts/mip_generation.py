"""How far each GL's glGenerateMipmap is from softras's two mip reductions.

For every level-0 size w x h in 1..20 x 1..20 plus 37x23, 64x64, 256x256 and
255x129, two premultiplied contents (noise with random alpha; black and white
with alpha 0 or 255), GL's levels (`glref.generate_mipmaps`) are compared
with `softras.scene.texels.mip_chain(level0, method=...)` for method "llvmpipe" and
"box".  Per level (1, 2, ...) the maximum |GL - softras| over all sizes and
contents is reported twice:

* chain: softras's whole chain from level 0 against GL's (differences
  accumulate down the chain);
* step: one reduction of GL's own level i against GL's level i + 1 (what a
  single generation step differs by).

Each GL runs in a child process, because Mesa reads GALLIUM_DRIVER and
GALLIVM_PERF once per process:

* llvmpipe: Mesa's default driver, default settings;
* llvmpipe no_aos: ``GALLIVM_PERF=no_aos_sampling`` (float sampling);
* softpipe: ``GALLIUM_DRIVER=softpipe`` (GL 3.3 core).

Prints one Markdown table per GL.  Run from the repository root::

    PYTHONPATH=. python scripts/mip_generation.py
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

CONFIGS = {"llvmpipe": {}, "llvmpipe no_aos": {"GALLIVM_PERF": "no_aos_sampling"},
           "softpipe": {"GALLIUM_DRIVER": "softpipe"}}
SIZES = [(w, h) for h in range(1, 21) for w in range(1, 21)] + [(37, 23), (64, 64), (256, 256), (255, 129)]
METHODS = ("llvmpipe", "box")


def measure() -> dict:
    """This process's GL against softras: {"renderer", "rows": [{size, pot,
    method, chain: [max per level 1..], step: [...]}]}."""
    import numpy as np

    import glref
    from softras.scene import texels

    rng = np.random.default_rng(20)
    rows = []
    for w, h in SIZES:
        noise = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
        binary = (rng.integers(0, 2, (h, w, 4)) * 255).astype(np.uint8)
        for straight in (noise, binary):
            level0 = texels.premultiply_rgba8(straight)
            gl = glref.generate_mipmaps(level0)
            for method in METHODS:
                soft = texels.mip_chain(level0, method=method)
                chain = [int(np.abs(a.astype(int) - b).max()) for a, b in zip(soft[1:], gl[1:])]
                step = [int(np.abs(texels.downsample(gl[i], method).astype(int) - gl[i + 1]).max())
                        for i in range(len(gl) - 1)]
                rows.append({"size": [w, h], "pot": w & (w - 1) == 0 and h & (h - 1) == 0,
                             "method": method, "chain": chain, "step": step})
    info = glref.info()
    return {"renderer": f"{info['GL_RENDERER']}, {info['GL_VERSION']}", "rows": rows}


def table(name: str, result: dict) -> str:
    """Markdown: per level, max |GL - softras| for each method and kind, all / POT / NPOT sizes."""
    rows = result["rows"]
    n_levels = max(len(r["chain"]) for r in rows)
    lines = [f"{name} ({result['renderer']}): max |GL - softras| per level, all / POT / NPOT sizes",
             "",
             "| level | llvmpipe chain | llvmpipe step | box chain | box step | textures |",
             "|---|---|---|---|---|---|"]
    for level in range(1, n_levels + 1):
        cells = []
        for method in METHODS:
            for kind in ("chain", "step"):
                picked = [(r["pot"], r[kind][level - 1]) for r in rows
                          if r["method"] == method and len(r[kind]) >= level]
                worst = [max((v for pot, v in picked if keep(pot)), default=None)
                         for keep in (lambda p: True, lambda p: p, lambda p: not p)]
                cells.append(" / ".join("-" if v is None else str(v) for v in worst))
        count = sum(1 for r in rows if r["method"] == "llvmpipe" and len(r["chain"]) >= level)
        lines.append(f"| {level} | " + " | ".join(cells) + f" | {count} |")
    return "\n".join(lines)


def main() -> int:
    if "--child" in sys.argv:
        json.dump(measure(), sys.stdout)
        return 0
    for name, env in CONFIGS.items():
        child = subprocess.run([sys.executable, __file__, "--child"], env=dict(os.environ, **env),
                               check=True, capture_output=True, text=True)
        print(table(name, json.loads(child.stdout)), end="\n\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
