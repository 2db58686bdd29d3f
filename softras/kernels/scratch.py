"""What the compiled path hands its kernels besides the scene: per-thread
scratch arrays it reuses from one render to the next, and read-only views
of its inputs (`read_only`)."""

from __future__ import annotations

import math
import threading

import numpy as np


class _Scratch(threading.local):
    """Per-thread arrays reused from one render to the next (the set-up tables,
    corner attributes and depth buffer).  A fresh multi-megabyte array costs a
    page fault per 4 KiB page when first written, on this machine about as
    much as setting up the triangles that fill it; a reused one is already
    mapped.  Buffers over MAX_BYTES are not kept."""

    MAX_BYTES = 64 << 20

    def __init__(self):
        self.buffers = {}
        self.last = {}          # name -> (shape, dtype as asked, the view handed out)

    def take(self, name: str, shape: tuple, dtype) -> np.ndarray:
        """An uninitialised C-contiguous array of this shape and dtype.  The
        same shape and dtype as the last time gets the same view again (a
        scene of many draws of one mesh asks ~9 times a draw: 0.85 us a
        call to make a new view, 0.24 us to hand out the last one)."""
        last = self.last.get(name)
        if last is not None and last[0] == shape and last[1] is dtype:
            return last[2]
        size = math.prod(shape)
        buffer = self.buffers.get(name)
        if buffer is None or buffer.dtype != np.dtype(dtype) or buffer.size < size:
            buffer = np.empty(max(size, 1), dtype)
            if buffer.nbytes > self.MAX_BYTES:
                return buffer[:size].reshape(shape)
            self.buffers[name] = buffer
        view = buffer[:size].reshape(shape)
        self.last[name] = (shape, dtype, view)
        return view


def read_only(a, dtype) -> np.ndarray:
    """A C-contiguous read-only view of ``a`` as ``dtype`` (a copy only where
    the layout or dtype differs).  numba compiles a kernel once per argument
    type, and whether an array is read-only is part of its type: a loaded
    scene's arrays are read-only (`softras.scene.model`), but a mesh's
    default vertex colours (`softras.pipeline.render.vertex_colors`) and the
    scenes the verifier derives (moved, without lines) hold fresh, writable
    ones, so a kernel handed both compiled again at a user's first render
    of such a scene, after its preparation (docs/speed.md, "Twenty-sixth
    round").  Handed through this view, every caller gives the one type
    that `softras.kernels.prepare` compiles."""
    view = np.ascontiguousarray(a, dtype).view()
    view.flags.writeable = False
    return view
