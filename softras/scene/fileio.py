"""What the file readers of the scene layer share: the error, reading, size checks.

`softras.scene.meshfiles` (PLY, OBJ, NPZ, glTF meshes), `softras.scene.gltf_files`
(the glTF container) and `softras.scene.gltf` (glTF scenes) raise
:class:`BadFile` with the reason alone; the caller turns it into a
`SceneError` that names the scene place and the file.
"""

from __future__ import annotations

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
