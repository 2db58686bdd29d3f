"""What the file readers of the scene layer share: the error, reading, size checks.

`softras.scene.meshfiles` (PLY, OBJ, NPZ, glTF meshes), `softras.scene.gltf_files`
(the glTF container) and `softras.scene.gltf` (glTF scenes) raise
:class:`BadFile` with the reason alone; the caller turns it into a
`SceneError` that names the scene place and the file.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

MAX_VERTICES = 16 * 1024 * 1024    # vertices of one mesh file


class BadFile(Exception):
    """A problem with a file; the reader's one-line message, without the place."""


def read_bytes(path: str) -> bytes:
    with open(path, "rb") as file:
        return file.read()


def check_counts(vertices: int, triangles: int, max_triangles: int, what: str = "") -> None:
    """Refuse sizes over the limits, from counts alone (before allocating):
    more than :data:`MAX_VERTICES` vertices or ``max_triangles`` triangles."""
    if vertices > MAX_VERTICES:
        raise BadFile(f"{what}{vertices} vertices, more than the limit {MAX_VERTICES} of a mesh file")
    if triangles > max_triangles:
        raise BadFile(f"{what}{triangles} triangles; the scene may have at most {max_triangles} more "
                      f"(procedural and file meshes together)")


def is_number(value) -> bool:
    """An int or a float, not a boolean."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def type_name(value) -> str:
    """What a JSON value is, for an error message ("the string 'x'", "null")."""
    if value is None:
        return "null"
    if isinstance(value, (bool, np.bool_)):
        return "a boolean"
    if isinstance(value, str):
        return f"the string {value!r}" if len(value) <= 40 else "a string"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)}"
    return repr(value) if is_number(value) else type(value).__name__


def shown(value: float) -> str:
    """``value`` as short as it reads back exactly: "1" for 1.0, but
    "1.0000000000000002" for the float just above 1 (which %g shows as "1",
    an error message saying "1 is out of range [0, 1]")."""
    short = f"{value:g}"
    return short if float(short) == value else repr(value)


def number_problem(value, lo: float = -math.inf, hi: float = math.inf) -> str | None:
    """Why ``value`` is not a finite number in [lo, hi], or None: the one number
    check of the scene format (`softras.scene.parse`) and of glTF files
    (`softras.scene.gltf_files.number`), each adding its place."""
    if not is_number(value):
        return f"expected a number, got {type_name(value)}"
    try:
        value = float(value)
    except OverflowError:
        return "number too large"
    if not math.isfinite(value):
        return f"expected a finite number, got {value}"
    if not lo <= value <= hi:
        if hi == math.inf:
            return f"must be at least {lo:g}, got {shown(value)}"
        if lo == -math.inf:
            return f"must be at most {hi:g}, got {shown(value)}"
        return f"{shown(value)} is out of range [{lo:g}, {hi:g}]"
    return None
