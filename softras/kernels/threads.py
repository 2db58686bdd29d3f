"""The tile drivers' threads: a compiled kernel's shares run on Python
threads, not in a numba parallel loop.

A tile driver (`softras.kernels.draw._make_draw_tiles`) is compiled as a
plain function that releases the GIL (``nogil``) and draws share r of
n_threads: tiles r, r + n_threads, ...  `on_threads` runs share 0 on the
calling thread and the others on a pool of threads kept for the process,
and returns when all are done.  The same work as a numba ``prange`` over
the shares, compiled at half the cost: numba's parallel-loop passes (its
copy propagation over the whole inlined body, the loop body outlined and
compiled again) were half of a driver's compile (the textured one-sample
driver 143 -> 72 s, docs/speed.md, "Thirty-third round").  The price: a
share handed to a pool thread and waited for costs ~50 us here, where
numba's own threads start a loop in ~2 us when they are awake (so the
shares of a batch of draws are handed over once, `softras.kernels.draw.draw_batch`,
and a batch whose estimated work is small takes one share,
`softras.kernels.draw.shares`).  A parallel
loop that calls the shares as functions of their own compiled little
less (numba optimises a callee again in each caller).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

from numba.core import compiler


class NoAliasCompiler(compiler.Compiler):
    """numba's compiler, with ``noalias`` on the compiled function's pointer
    arguments (its arrays' data), as numba gives the body of a parallel
    loop where it finds no aliases (`numba.parfors.parfor_lowering`): a
    tile driver's arrays are distinct, or only read.  Without it the
    textured drivers drew 4-10 % slower than in the parallel loop
    (docs/speed.md, "Thirty-third round").  For ``numba.njit(pipeline_class=...)``."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return super().define_pipelines()


_pools: dict[tuple[int, int], ThreadPoolExecutor] = {}
_lock = threading.Lock()


def _pool(size: int) -> ThreadPoolExecutor:
    """This process's pool of ``size`` threads (a forked child makes its own:
    the parent's threads do not exist there)."""
    key = (os.getpid(), size)
    pool = _pools.get(key)
    if pool is None:
        with _lock:
            pool = _pools.get(key)
            if pool is None:
                pool = _pools[key] = ThreadPoolExecutor(size, thread_name_prefix="softras-tiles")
    return pool


def on_threads(share, n_threads: int) -> None:
    """``share(r)`` for r = 0 .. n_threads - 1 at once: r = 0 on this thread,
    the others on the pool's; returns when every share has, raising the
    first error.  The shares must be independent (the tile drivers' are:
    a pixel belongs to one tile, a tile to one share)."""
    if n_threads <= 1:
        share(0)
        return
    pool = _pool(n_threads - 1)
    futures = [pool.submit(share, r) for r in range(1, n_threads)]
    try:
        share(0)
    finally:
        for future in futures:
            future.exception()              # (waits: no share outlives the call)
    for future in futures:
        future.result()
