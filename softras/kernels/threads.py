"""The tile drivers' threads: a compiled kernel's shares run on Python
threads, not in a numba parallel loop.

A tile driver (`softras.kernels.draw._make_draw_tiles`) is compiled as a
plain function that releases the GIL (``nogil``) and draws share r of
n_threads: the tiles it takes from a counter, or tiles r, r + n_threads,
... (below).  `on_threads` runs share 0 on the calling thread and the
others on a pool of threads kept for the process, and returns when all
are done.  The same work as a numba ``prange`` over
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

A batch of one draw hands its tiles out as the threads ask for them
(`_next_tile`: an atomic counter, `_claim`) instead of fixed shares:
the pool's thread starts its share 40-200 us after the calling thread,
and fixed shares of the same number of tiles ended up to 0.7 ms apart
(docs/speed.md, "Forty-fifth round").  A batch of several draws keeps the
fixed shares: there a tile must see every draw of the batch on one
thread, in order.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import types
from numba.core import cgutils, compiler
from numba.extending import intrinsic


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


# The tile counter of a batch of fixed shares (`_next_tile`): none.
FIXED_SHARES = np.zeros(0, np.int64)


@intrinsic
def _claim(typingctx, counter):
    """counter[0] += 1 as one atomic operation (LLVM's ``atomicrmw add``,
    monotonic: only the count must be shared), returning its value before:
    every value goes to one caller, whichever thread calls."""

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        first = cgutils.get_item_pointer(context, builder, array_type, array,
                                         [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", first, context.get_constant(types.int64, 1), "monotonic")

    return types.int64(counter), codegen


@numba.njit(cache=True, inline="always")
def _next_tile(counter, tile, n_threads):
    """The tile a tile driver's share draws after ``tile`` (r - n_threads
    before its first): the next one nobody has taken, from the batch's
    counter (int64 (1,), zeroed for the batch); tile + n_threads for
    fixed shares (counter `FIXED_SHARES`)."""
    return _claim(counter) if counter.shape[0] else tile + n_threads
