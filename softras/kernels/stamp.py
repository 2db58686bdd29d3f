"""The cache key of the compiled kernels that inline other modules' kernels.

numba's on-disk cache checks the source file of the function it compiled and
nothing else (`softras.pipeline.cache_key`), but the tile drivers
(`softras.kernels.draw`) and the line kernel (`softras.kernels.lines`)
inline kernels of every module of this folder and some of the stages'
(`softras.pipeline.ops`, `softras.pipeline.texture`,
`softras.pipeline.libm`, `softras.pipeline.texture_beyond`, and for the
line kernel `softras.pipeline.lines` and `softras.pipeline.rasterize`),
and the exact kernel
(`softras.kernels.exact`) those of `softras.kernels.interpolate`,
`softras.kernels.light` and `softras.kernels.texture`, and it calls the
stages' (`softras.pipeline.rasterize`, `softras.pipeline.ops`,
`softras.pipeline.texture`, `softras.pipeline.libm`), and Gouraud's and
flat shading's lighting loops (`softras.kernels.light`) inline
`softras.pipeline.libm`'s pow: an edit of one of those alone would load a
stale kernel.  The stamp is a closure variable of the kernel, and numba
keys a closure's cache on its variables, so any edit of a module it covers
compiles the kernel again.
"""

from __future__ import annotations

from pathlib import Path

from softras.pipeline.cache_key import sources_key


# Modules of this folder that no other kernel inlines: prepare.py and pool.py
# hold no compiled code, and the exact kernels are compiled for themselves
# (an edit of them need not compile the tile drivers again: five minutes on
# two cores).
NOT_INLINED = ("prepare.py", "pool.py", "exact.py", "exact_lines.py")


def sources_stamp(*stage_modules) -> str:
    """`softras.pipeline.cache_key.sources_key` of the sources of
    softras.kernels (every module of this folder but `NOT_INLINED`) and of
    the ``stage_modules`` (modules of softras.pipeline whose kernels are
    inlined too)."""
    paths = [path for path in sorted(Path(__file__).resolve().parent.glob("*.py")) if path.name not in NOT_INLINED]
    return sources_key(paths + [Path(module.__file__) for module in stage_modules])
