"""The threads the compiled path's work runs on in shares (the tile
drivers', a large draw's set-up, Gouraud's lighting of a large mesh, the
gl line kernel's two passes): `on_threads` runs share 0 on the calling
thread and the others on a pool of Python threads kept for the process,
and returns when all are done.  No compiled code: an edit here compiles
no kernel again (`softras.kernels.stamp.NOT_INLINED`).

Why Python threads and not a numba parallel loop over the shares: the
drivers compile at half the cost (`softras.kernels.threads`; the set-up
and lighting loops 4 s less of a cold start, the line kernel 7.9 -> 6.0
s), and the threads can be kept apart (below), which numba's OpenMP
threads cannot without pinning the caller too.  The price: a share
handed to a pool thread and waited for costs ~50 us here, where numba's
own threads start a loop in ~2 us when they are awake (so the shares of
a batch of draws are handed over once, `softras.kernels.draw.draw_batch`,
a batch whose estimated work is small takes one share,
`softras.kernels.draw.shares`, and the set-up and the lighting take
shares only from `softras.kernels.setup.PARALLEL_SETUP` triangles and
`softras.kernels.light.PARALLEL_LIGHTING` vertices).

The pool's threads run on the CPUs other than the one the calling thread
is on when it hands shares over (`_keep_apart`).  On this 2-vCPU VM a
thread woken after a few milliseconds of idleness was put on its waker's
CPU in 191 of 200 hand-offs (the other vCPU halted, which the guest's
scheduler takes for busy), and there it waited for the calling thread's
share to end: the shares ran one after the other, and a render after
idleness took up to twice its time after another render
(scale_pixels_512 0.89 -> 1.70 ms; docs/speed.md, "Forty-sixth round").
"""

from __future__ import annotations

import ctypes
import os
import threading
from concurrent.futures import ThreadPoolExecutor


class _Pool(ThreadPoolExecutor):
    """A ThreadPoolExecutor that knows its threads' kernel ids (``tids``,
    as they start) and the CPU it last kept them away from (`_keep_apart`)."""

    def __init__(self, size: int):
        self.tids: list[int] = []
        self.apart_from = (None, 0)                     # (the caller's CPU, threads pinned)
        super().__init__(size, thread_name_prefix="softras-tiles",
                         initializer=lambda: self.tids.append(threading.get_native_id()))


_pools: dict[tuple[int, int], _Pool] = {}
_lock = threading.Lock()


def _pool(size: int) -> _Pool:
    """This process's pool of ``size`` threads (a forked child makes its own:
    the parent's threads do not exist there)."""
    key = (os.getpid(), size)
    pool = _pools.get(key)
    if pool is None:
        with _lock:
            pool = _pools.get(key)
            if pool is None:
                pool = _pools[key] = _Pool(size)
    return pool


try:
    _sched_getcpu = ctypes.CDLL(None).sched_getcpu      # (glibc's: os has no getcpu)
except (OSError, AttributeError):                       # (no such call: the threads stay where they are)
    _sched_getcpu = None


def _keep_apart(pool: _Pool) -> None:
    """Let ``pool``'s threads run on every CPU this process may use but the
    one the calling thread is on now (on all of them where that leaves
    none), so that a share handed over is not queued behind the caller's
    own (the module docstring).  Only when the caller's CPU or the pool's
    threads have changed since the last call: two system calls a thread
    then, ~0.3 us otherwise.  A thread that cannot be pinned (gone, or not
    permitted) is left as it is: the shares' work is the same on any CPU."""
    if _sched_getcpu is None or not hasattr(os, "sched_setaffinity"):
        return
    cpu = _sched_getcpu()
    if (cpu, len(pool.tids)) == pool.apart_from:
        return
    allowed = os.sched_getaffinity(0)
    others = (allowed - {cpu}) or allowed
    for tid in list(pool.tids):
        try:
            os.sched_setaffinity(tid, others)
        except OSError:
            pass
    pool.apart_from = (cpu, len(pool.tids))


def on_threads(share, n_threads: int) -> None:
    """``share(r)`` for r = 0 .. n_threads - 1 at once: r = 0 on this thread,
    the others on the pool's, kept off this thread's CPU (`_keep_apart`);
    returns when every share has, raising the first error.  The shares
    must be independent (the tile drivers' are: a pixel belongs to one
    tile, a tile to one share)."""
    if n_threads <= 1:
        share(0)
        return
    pool = _pool(n_threads - 1)
    _keep_apart(pool)
    futures = [pool.submit(share, r) for r in range(1, n_threads)]
    try:
        share(0)
    finally:
        for future in futures:
            future.exception()              # (waits: no share outlives the call)
    for future in futures:
        future.result()
