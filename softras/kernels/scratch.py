"""Per-thread scratch arrays the compiled path reuses from one render to the next."""

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

    def take(self, name: str, shape: tuple, dtype) -> np.ndarray:
        """An uninitialised C-contiguous array of this shape and dtype."""
        dtype = np.dtype(dtype)
        size = math.prod(shape)
        buffer = self.buffers.get(name)
        if buffer is None or buffer.dtype != dtype or buffer.size < size:
            buffer = np.empty(max(size, 1), dtype)
            if buffer.nbytes <= self.MAX_BYTES:
                self.buffers[name] = buffer
        return buffer[:size].reshape(shape)
