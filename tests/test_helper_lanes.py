"""A textured draw's helper lanes touch no memory outside the picture.

The compiled textured tile (`softras.kernels.draw._textured_tile`) shades
whole 2x2 quads, for the texture derivatives; a quad's uncovered pixels are
helper lanes (coverage mask 0), shaded and never written.  At the right or
bottom edge of a picture of odd width or height a helper lane lies one pixel
outside it.  The depth test used to read and write back every lane's depth,
helpers included: one pixel past a row (the next row's first pixel, in
another thread's tile: a lost depth write if that thread wrote it in
between) or past the depth buffer's end (NUMBA_BOUNDSCHECK=1 raised
IndexError in the tile driver for these scenes).

Here the depth buffer ends exactly where a page that cannot be read begins
(an anonymous mapping, its last page made inaccessible with ``mprotect``),
so a kernel that reads past its end kills the process: each render runs in
a child process, on the kernels the test workers compiled
(``SOFTRAS_COMPILE=wait``: never the stages).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

# The child's set-up: `guarded` arrays, and the depth buffer of the
# compiled path's renders taken from them.
_GUARD = r"""
import ctypes, mmap, sys
import numpy as np
import softras
from softras.kernels import draw

libc = ctypes.CDLL(None, use_errno=True)
libc.mprotect.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
kept = []

def guarded(shape, dtype):
    # A C-contiguous array of this shape whose last byte is the last byte
    # before an inaccessible page.
    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    pages = -(-nbytes // mmap.PAGESIZE)
    area = mmap.mmap(-1, (pages + 1) * mmap.PAGESIZE)
    start = ctypes.addressof(ctypes.c_char.from_buffer(area))
    if libc.mprotect(start + pages * mmap.PAGESIZE, mmap.PAGESIZE, 0) != 0:       # PROT_NONE
        raise OSError(ctypes.get_errno(), "mprotect")
    kept.append(area)
    return np.frombuffer(area, np.uint8, nbytes, pages * mmap.PAGESIZE - nbytes).view(dtype).reshape(shape)

take = draw._scratch.take
draw._scratch.take = lambda name, shape, dtype: guarded(shape, dtype) if name == "depth" else take(name, shape, dtype)
"""

_CHILD = _GUARD + r"""
for config in sys.argv[1:]:
    width, height, samples = (int(a) for a in config.split(","))
    scene = softras.load_scene({
        "softras_scene": 1, "width": width, "height": height, "samples": samples, "background": [0, 0, 0, 1],
        "camera": {"projection": "orthographic", "left": -1, "right": 1, "bottom": -1, "top": 1,
                   "near": 0.1, "far": 10, "eye": [0, 0, 3], "target": [0, 0, 0]},
        "textures": {"checker": {"procedural": "checker", "size": [8, 8]}},
        "nodes": [{"name": "quad",
                   "mesh": {"positions": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
                            "indices": [[0, 1, 2], [0, 2, 3]], "uvs": [[0, 1], [1, 1], [1, 0], [0, 0]]},
                   "material": {"texture": "checker"}}]})
    image = softras.render(scene)
    print("rendered", config, image.shape, flush=True)
"""


# (width, height, samples): helper lanes right of, below, and right of and
# below the picture, at one sample (the inlined tile) and four (the tile
# the driver of any count calls).
CONFIGS = [(width, height, samples) for samples in (1, 4) for width, height in ((129, 97), (128, 97), (129, 96))]


def test_a_textured_draw_reads_no_depth_outside_the_picture():
    """A full-picture textured quad with the depth test in each of `CONFIGS`'
    pictures of odd width and/or height.  One child renders them one after
    another (a child's start, numba's import and the kernels' load, is most
    of its second); a child killed by a read past the guard page fails that
    picture, and a new child goes on from the next."""
    env = dict(os.environ, SOFTRAS_COMPILE="wait")
    left, failures = [",".join(map(str, config)) for config in CONFIGS], []
    while left:
        done = subprocess.run([sys.executable, "-c", _CHILD, *left], capture_output=True, text=True, timeout=600,
                              env=env)
        rendered = [line for line in done.stdout.splitlines() if line.startswith("rendered ")]
        for config, line in zip(left, rendered):
            width, height, _ = config.split(",")
            assert line == f"rendered {config} ({height}, {width}, 4)"
        left = left[len(rendered):]
        if done.returncode != 0:
            failures.append(f"{left[0] if left else 'after the last'}: exit status {done.returncode}: "
                            f"{done.stderr[-2000:]}")
            left = left[1:]
        else:
            assert not left, f"the child stopped before {left}"
    assert not failures, "\n".join(failures)


def test_the_guard_page_stops_a_read_past_the_end():
    """The check can fail: a compiled read one element past the guarded
    buffer kills the child (SIGSEGV)."""
    program = _GUARD + (
        "import numba\n"
        "@numba.njit(cache=False)\n"
        "def past(a, i):\n"
        "    return a.reshape(-1)[i]\n"
        "depth = guarded((97, 129, 1), np.int32)\n"
        "print(past(depth, depth.size - 1))\n"
        "sys.stdout.flush()\n"
        "print(past(depth, depth.size))\n")
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=600)
    assert done.stdout.splitlines()[:1] == ["0"]
    assert done.returncode == -11, (done.returncode, done.stderr[-2000:])
