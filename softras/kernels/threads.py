"""The tile drivers' shares: a compiled kernel's shares run on Python
threads (`softras.kernels.pool.on_threads`), not in a numba parallel loop,
and take the tiles of a batch as they reach them; and what such a kernel
borrows from numba's parallel loops.

A tile driver (`softras.kernels.draw._make_draw_tiles`) is compiled as a
plain function that releases the GIL (``nogil``) and draws share r of a
batch: the tiles the share takes (below).  The same work as a numba
``prange`` over the shares, compiled at half the cost: numba's
parallel-loop passes (its copy propagation over the whole inlined body,
the loop body outlined and compiled again) were half of a driver's
compile (the textured one-sample driver 143 -> 72 s, docs/speed.md,
"Thirty-third round").  A parallel loop that calls the shares as
functions of their own compiled little less (numba optimises a callee
again in each caller).

The tiles go to the shares as they ask for them (`_owns`: a table of
owners, one atomic compare-and-swap a tile and draw, `_claim`), not in
fixed shares: the pool's thread starts its share 40-200 us after the
calling thread, and fixed shares of the same number of tiles ended up to
0.7 ms apart (docs/speed.md, "Forty-fifth round").  A tile's first taker
keeps it for the batch, so it sees every draw of the batch on one thread,
in order: a share that reaches a tile with triangles of a draw either owns
it or takes it, since had another share seen those triangles first it
would have taken the tile then.

`_unowned` gives a kernel called from Python what a parallel loop's body
had: arrays without an owner, whose views cost no reference counting
(the gl line kernel's passes, `softras.kernels.lines`).
"""

from __future__ import annotations

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


@intrinsic
def _unowned(typingctx, array):
    """``array`` as a parallel loop's body sees its arrays: the same data,
    shape and strides, with no owner (meminfo and parent NULL), so that
    numba's reference counting of it and of the views taken from it
    (``a[i]``) is a test of NULL, not an atomic add.  For a kernel called
    from Python that hands arrays or their views to functions it does not
    inline: the line kernel's set-up drew 1.28 ms with the arrays as
    passed and 0.72 ms unowned, as fast as in numba's parallel loop
    (docs/speed.md, "Forty-sixth round").  The caller keeps the arrays
    alive (the Python caller of the kernel holds them)."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, args):
        given = context.make_array(signature.args[0])(context, builder, args[0])
        unowned = context.make_array(signature.return_type)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(unowned, field, getattr(given, field))
        unowned.meminfo = cgutils.get_null_value(unowned.meminfo.type)
        unowned.parent = cgutils.get_null_value(unowned.parent.type)
        return unowned._getvalue()

    return array(array), codegen


@intrinsic
def _aligned_stack(typingctx):
    """Makes the compiled function that calls it align its stack to 64
    bytes when it starts (LLVM's ``alignstack(64)``).  LLVM keeps the
    AVX-512 registers a loop runs out of in 64-byte stack slots; the
    stack as a thread's caller leaves it is only 16-byte aligned, so
    without this the slots are placed at 16-byte offsets and, by where a
    thread's stack happens to stand, a slot can straddle two cache lines,
    its every store and load split in two.  A tile driver's share on the
    pool's thread drew blended_8x128_512's batch in 6.15-6.68 ms against
    5.15-5.35 ms from any other depth of its thread's stack, or on the
    calling thread (docs/speed.md, "Forty-eighth round"): which thread
    lost depended on the code's frame, not on the code's speed."""
    def codegen(context, builder, signature, args):
        builder.function.attributes.alignstack = 64
        # (llvmlite writes a function's attributes only when its set holds
        # a named one; nounwind is true of numba's functions, which return
        # their errors.)
        builder.function.attributes.add("nounwind")
        return context.get_dummy_value()

    return types.none(), codegen


# The tile owners of a batch drawn by one share (`_owns`): none, every tile is that share's.
ONE_SHARE = np.zeros(0, np.int64)


def share_count(pieces: int) -> int:
    """How many shares a pass of ``pieces`` pieces of work (bands, lines)
    runs in on `softras.kernels.pool.on_threads`: one per thread, at most
    one per piece (a share with nothing to do costs a hand-off to the pool
    all the same), at least one."""
    return max(1, min(numba.get_num_threads(), pieces))


def owners_table(n: int, n_shares: int) -> np.ndarray:
    """The table n_shares shares take n pieces of work in (`_owns`: the tiles
    of a batch, the bands of an exact draw): int64 (n,) of -1 (nobody's yet)
    for more than one share, else `ONE_SHARE`."""
    return np.full(n, -1, np.int64) if n_shares > 1 else ONE_SHARE


@intrinsic
def _claim(typingctx, owners, tile, r):
    """owners[tile] = r if it is -1, as one atomic operation (LLVM's
    ``cmpxchg``, monotonic: only the entry itself must be shared),
    returning the entry's value before: one caller takes a tile, whichever
    thread calls first."""

    def codegen(context, builder, signature, args):
        array_type, tile_type, r_type = signature.args
        array = context.make_array(array_type)(context, builder, args[0])
        entry = cgutils.get_item_pointer(context, builder, array_type, array,
                                         [context.cast(builder, args[1], tile_type, types.intp)])
        exchanged = builder.cmpxchg(entry, context.get_constant(types.int64, -1),
                                    context.cast(builder, args[2], r_type, types.int64), "monotonic", "monotonic")
        return builder.extract_value(exchanged, 0)

    return types.int64(owners, tile, r), codegen


@numba.njit(cache=True, inline="always")
def _owns(owners, tile, r):
    """Whether share r draws ``tile``: the batch's owners (int64 (tiles,),
    -1 for a tile nobody has taken yet) give it to the first share that
    asks, and to that share for every later draw of the batch;
    `ONE_SHARE`: every tile is share r's."""
    if owners.shape[0] == 0:
        return True
    owner = _claim(owners, tile, r)
    return owner == -1 or owner == r
