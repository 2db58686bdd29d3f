"""A cache key for compiled code that reaches another module's compiled code.

numba's on-disk cache (``cache=True``) checks the source file of the
function it compiled and nothing else, yet the cached machine code holds
every compiled function it calls or inlines.  A kernel that calls into
another module would load stale after an edit of that module alone (a
``git pull`` that changes only the callee's file, on a machine whose cache
is warm).  Such a kernel is made by a factory that takes `sources_key` of
the callees' files and reads it in the kernel's body: numba keys a closure's
cache entry on its variables, so an edit of any of those files compiles the
kernel again.  tests/test_prepare.py scans every cached kernel of softras
for calls that no key covers.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent        # the softras folder


def sources_key(paths) -> str:
    """``"<SHA-256> <name> <name> ..."``: the digest of the files at
    ``paths`` (each one's name and bytes, in the order of the names) and
    their names relative to the softras folder ("pipeline/texture.py"), so
    that a reader, and the test, can see what the key covers.  One key per
    set of files, whatever the order given, read and hashed once per
    process (the kernels' modules ask for the same sets at import)."""
    return _key(tuple(sorted({Path(path).resolve().relative_to(PACKAGE).as_posix() for path in paths})))


@functools.cache
def _key(names: tuple[str, ...]) -> str:
    """`sources_key` of the files named (relative to the softras folder)."""
    digest = hashlib.sha256()
    for name in names:
        digest.update(name.encode() + b"\0" + (PACKAGE / name).read_bytes())
    return " ".join((digest.hexdigest(),) + names)


def covered(key: str) -> list[str]:
    """The file names (relative to the softras folder) that `sources_key`'s
    ``key`` covers; none for a string that is not such a key."""
    digest, *names = key.split(" ")
    is_key = len(digest) == 64 and all(ch in "0123456789abcdef" for ch in digest)
    return names if is_key else []
