"""Two fixes to numba's compile time, the same code compiled faster.

Most of the time a cold kernel took to compile was numba's own Python, not
LLVM (docs/speed.md, "Twenty-seventh round"), and two deep copies in it
cost time that grows as the square of a function's size:

- **the inliner** (``inline="always"``, `numba.core.inline_closurecall`,
  ``InlineWorker.inline_ir``) copies a callee's IR block by block with one
  ``copy.deepcopy`` per block.  Every variable holds the function's scope,
  and the scope holds every variable, so each block's copy copies the whole
  scope again: blocks x variables (numba issue #8989, NVIDIA/numba-cuda
  #688).  Here the blocks of one inlining share one memo, so the scope is
  copied once and the copy has the structure of the original (one scope,
  as every block of a function shares);
- **copy propagation** (`numba.core.ir_utils.copy_propagate`, run by the
  parallel loops' passes) deep-copies its table of copies, a dict of sets
  of ``(name, name)`` tuples, on every step of a fixed-point iteration.
  Such a table is copied here as new sets of the same tuples: what
  ``deepcopy`` returns for it (a tuple of strings is its own deep copy).

`install` swaps the name ``copy`` in those two modules for an object whose
``deepcopy`` does this and hands everything else to `copy.deepcopy`.  It is
called when `softras.pipeline` is imported, before any of softras's kernels
compiles, and leaves numba as it is if its modules do not look as expected
(then compiles are slower, nothing else).  ``SOFTRAS_NUMBA_FIXES=0`` turns
it off, to measure it.  The compiled code is the same either way: every
variant's kernels compiled with and without gave the same assembly
(docs/speed.md), and tests/test_numba_fixes.py compares one parallel
loop's.
"""

from __future__ import annotations

import copy
import functools
import os


class _InlinerCopy:
    """The ``copy`` module as `numba.core.inline_closurecall` sees it: while
    an ``inline_ir`` call runs, ``deepcopy`` without a memo uses that call's
    one memo (`_inline_ir_sharing_one_memo`)."""

    memo: dict | None = None

    def deepcopy(self, x, memo=None):
        return copy.deepcopy(x, self.memo if memo is None else memo)

    def __getattr__(self, name):
        return getattr(copy, name)


def _copy_table(x):
    """``x`` copied as `copy.deepcopy` would, fast when ``x`` is a dict of
    sets of tuples of strings (copy propagation's table), else None."""
    if type(x) is not dict:
        return None
    for value in x.values():
        if type(value) is not set:
            return None
        for item in value:
            if type(item) is not tuple or not all(type(s) is str for s in item):
                return None
    return {key: set(value) for key, value in x.items()}


class _PassesCopy:
    """The ``copy`` module as `numba.core.ir_utils` sees it: ``deepcopy`` of
    a table of copies (`_copy_table`) without walking it."""

    def deepcopy(self, x, memo=None):
        table = _copy_table(x) if memo is None else None
        return copy.deepcopy(x, memo) if table is None else table

    def __getattr__(self, name):
        return getattr(copy, name)


def install(inliner=None, passes=None) -> bool:
    """Install both fixes (once) into numba's `numba.core.inline_closurecall`
    and `numba.core.ir_utils` (or the modules given, for the tests); False,
    and nothing changed, where they are off or the modules are not as
    expected."""
    if os.environ.get("SOFTRAS_NUMBA_FIXES", "1") == "0":
        return False
    if inliner is None or passes is None:
        from numba.core import inline_closurecall as inliner, ir_utils as passes
    worker = getattr(inliner, "InlineWorker", None)
    inline_ir = getattr(worker, "inline_ir", None)
    if getattr(inline_ir, "_softras", False):
        return True
    if inline_ir is None or getattr(inliner, "copy", None) is not copy or getattr(passes, "copy", None) is not copy \
            or not hasattr(passes, "copy_propagate"):
        return False
    shared = _InlinerCopy()

    @functools.wraps(inline_ir)
    def _inline_ir_sharing_one_memo(*args, **kwargs):
        outer, shared.memo = shared.memo, {}
        try:
            return inline_ir(*args, **kwargs)
        finally:
            shared.memo = outer

    _inline_ir_sharing_one_memo._softras = True
    worker.inline_ir = _inline_ir_sharing_one_memo
    inliner.copy = shared
    passes.copy = _PassesCopy()
    return True
