"""Write scenes/mesh_file_ply.ply and scenes/mesh_file_ply.json: a conformance
scene whose mesh comes from a binary PLY file (docs/scene_format.md, "Mesh files").

The mesh is a UV sphere written the way PLY exporters write one: float32
positions, normals and uvs (``s t``, v = 0 at the BOTTOM of the image, the
PLY convention), uchar vertex colours, quads between the rings and triangles
at the poles (the loader splits the quads into fans).  The scene lights it
(gouraud), multiplies the vertex colours by a checker texture, and culls back
faces, so a wrong uv flip, colour scale, winding or fan shows in the picture.

Run from the repository root, then regenerate the golden image:

    python3 scripts/make_mesh_file_ply.py
    softras golden --update scenes/mesh_file_ply.json
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np

SCENES = Path(__file__).resolve().parents[1] / "scenes"
SEGMENTS, RINGS = 16, 8


def sphere():
    """(positions, normals, uvs with v = 0 at the bottom, uint8 colours, faces)."""
    rows = []
    for r in range(RINGS + 1):
        theta = math.pi * r / RINGS                     # 0 at the +y pole
        for s in range(SEGMENTS + 1):                   # the seam column twice, so u runs 0..1
            phi = 2 * math.pi * s / SEGMENTS
            rows.append((math.sin(theta) * math.sin(phi), math.cos(theta), math.sin(theta) * math.cos(phi),
                         s / SEGMENTS, 1 - r / RINGS))
    rows = np.array(rows)
    positions = rows[:, :3].astype(np.float32)
    normals = positions.copy()
    uvs = rows[:, 3:].astype(np.float32)
    colors = np.round((positions * 0.5 + 0.5) * 255).astype(np.uint8)
    faces = []
    at = lambda r, s: r * (SEGMENTS + 1) + s
    for r in range(RINGS):
        for s in range(SEGMENTS):
            # counter-clockwise seen from outside: down the ring, then along it
            quad = [at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1)]
            if r == 0:
                faces.append(quad[:3])                  # the top pole: one triangle
            elif r == RINGS - 1:
                faces.append([quad[0], quad[1], quad[3]])   # the bottom pole
            else:
                faces.append(quad)
    return positions, normals, uvs, colors, faces


def ply_bytes(positions, normals, uvs, colors, faces) -> bytes:
    header = "\n".join([
        "ply", "format binary_little_endian 1.0", "comment scripts/make_mesh_file_ply.py: a UV sphere",
        f"element vertex {len(positions)}",
        "property float x", "property float y", "property float z",
        "property float nx", "property float ny", "property float nz",
        "property float s", "property float t",
        "property uchar red", "property uchar green", "property uchar blue",
        f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]) + "\n"
    vertex = np.zeros(len(positions), [("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", 2), ("c", "u1", 3)])
    vertex["p"], vertex["n"], vertex["uv"], vertex["c"] = positions, normals, uvs, colors
    body = b"".join(struct.pack("<B", len(face)) + np.asarray(face, "<i4").tobytes() for face in faces)
    return header.encode("ascii") + vertex.tobytes() + body


SCENE = {
    "softras_scene": 1,
    "description": "A vertex-coloured, checker-textured, lit UV sphere read from a binary PLY file "
                   "(quads and pole triangles; uvs with v = 0 at the bottom).",
    "width": 96, "height": 72,
    "background": [0.08, 0.08, 0.1, 1],
    "camera": {"projection": "perspective", "fov_y": 40, "near": 0.5, "far": 10,
               "eye": [0.6, 1.2, 3.2], "target": [0, 0, 0]},
    "textures": {"checker": {"procedural": "checker", "size": [64, 32], "squares": 8,
                             "color0": [0.35, 0.35, 0.35], "color1": [1, 1, 1],
                             "min_filter": "linear", "mag_filter": "nearest"}},
    "lights": [{"type": "directional", "direction": [-0.4, -0.6, -1], "color": [1, 1, 1]}],
    "nodes": [{"name": "sphere", "rotate": [30, 0, 1, 0],
               "mesh": {"file": "mesh_file_ply.ply"},
               "material": {"texture": "checker", "shading": "gouraud", "ambient": 0.25, "specular": 0.3},
               "cull": "back"}],
}


def main() -> None:
    (SCENES / "mesh_file_ply.ply").write_bytes(ply_bytes(*sphere()))
    (SCENES / "mesh_file_ply.json").write_text(json.dumps(SCENE, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {SCENES / 'mesh_file_ply.ply'} and {SCENES / 'mesh_file_ply.json'}")


if __name__ == "__main__":
    main()
