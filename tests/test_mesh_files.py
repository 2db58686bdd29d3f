"""Mesh files (`"mesh": {"file": ...}`, softras.scene.meshfiles): PLY, OBJ, NPZ, glTF/GLB.

Every file is written here, in tmp_path, with numpy, struct and json (no
exporter library), so each test knows the exact bytes it reads back. The
checks:

- the loaded arrays, exactly: positions, triangles (OBJ/PLY polygons as fans
  from their first corner), normals, vertex colours as RGBA in [0, 1] (uint8
  / 255), uvs in the scene's convention (t = 0 at the image top: OBJ and PLY
  v flipped, glTF and NPZ kept);
- the picture: a textured quad whose file uvs say "the image, upright" shows
  the image upright in softras and in GL, whatever the format (the uv
  convention as a picture);
- softras and glref agree (strict verifier) on meshes read from files;
- every malformed file is a one-line SceneError naming the scene place and
  the file, and `softras render` exits 2 and writes nothing;
- a 1M-triangle binary PLY loads through `softras.load_scene` in well under
  a second.
"""

from __future__ import annotations

import base64
import json
import os
import statistics
import struct
import time
import tracemalloc

import numpy as np
import pytest

import softras
from softras import cli
from softras.scene import SceneError, meshfiles, scene_from_dict

from conftest import REPO, load_script

make_gltf_scenes = load_script("make_gltf_scenes")

# --------------------------------------------------------------------------- writers


def write_ply(path, positions, faces, *, fmt="binary_little_endian", colors=None, normals=None, uvs=None,
              uv_names=("s", "t"), index_type="int", truncate=0, face_count=None):
    """A PLY file: float32 x y z [nx ny nz] [s t] [red green blue [alpha]], faces as lists.

    ``colors``: uint8 (uchar properties) or float (float properties), 3 or 4 wide.
    ``faces``: a list of corner lists (any lengths).  ``truncate``: bytes cut off the end.
    """
    positions = np.asarray(positions, np.float32)
    props = [("x", "f4", positions[:, 0]), ("y", "f4", positions[:, 1]), ("z", "f4", positions[:, 2])]
    if normals is not None:
        normals = np.asarray(normals, np.float32)
        props += [(n, "f4", normals[:, k]) for k, n in enumerate(("nx", "ny", "nz"))]
    if uvs is not None:
        uvs = np.asarray(uvs, np.float32)
        props += [(uv_names[0], "f4", uvs[:, 0]), (uv_names[1], "f4", uvs[:, 1])]
    if colors is not None:
        colors = np.asarray(colors)
        code = "u1" if colors.dtype == np.uint8 else "f4"
        props += [(n, code, colors[:, k]) for k, n in enumerate(("red", "green", "blue", "alpha")[:colors.shape[1]])]
    ply_type = {"f4": "float", "u1": "uchar", "i4": "int", "u4": "uint", "u2": "ushort"}
    header = [f"ply", f"format {fmt} 1.0", "comment written by tests/test_mesh_files.py",
              f"element vertex {len(positions)}"]
    header += [f"property {ply_type[code]} {name}" for name, code, _ in props]
    header += [f"element face {len(faces) if face_count is None else face_count}",
               f"property list uchar {index_type} vertex_indices", "end_header"]
    head = ("\n".join(header) + "\n").encode("ascii")
    if fmt == "ascii":
        lines = [" ".join(repr(float(v)) if code == "f4" else str(int(v)) for _, code, column in props
                          for v in [column[i]]) for i in range(len(positions))]
        lines += [" ".join(str(int(x)) for x in [len(face), *face]) for face in faces]
        body = ("\n".join(lines) + "\n").encode("ascii")
    else:
        endian = "<" if fmt == "binary_little_endian" else ">"
        vertex = np.zeros(len(positions), [(name, endian + code) for name, code, _ in props])
        for name, _, column in props:
            vertex[name] = column
        index_code = {"int": "i4", "uint": "u4", "ushort": "u2"}[index_type]
        body = vertex.tobytes() + b"".join(
            struct.pack("B", len(face)) + np.asarray(face, endian + index_code).tobytes() for face in faces)
    data = head + body
    path.write_bytes(data[:len(data) - truncate])
    return path


BOX_OBJ = """\
# a unit box, its six faces as quads, uvs of a cross-shaped net (v = 0 at the bottom)
o box
v -1 -1  1
v  1 -1  1
v  1  1  1
v -1  1  1
v -1 -1 -1
v  1 -1 -1
v  1  1 -1
v -1  1 -1
vt 0.25 0.0
vt 0.50 0.0
vt 0.25 0.25
vt 0.50 0.25
vt 0.00 0.50
vt 0.25 0.50
vt 0.50 0.50
vt 0.75 0.50
vt 1.00 0.50
vt 0.00 0.75
vt 0.25 0.75
vt 0.50 0.75
vt 0.75 0.75
vt 1.00 0.75
vn 0 0 1
vn 0 0 -1
vn 1 0 0
vn -1 0 0
vn 0 1 0
vn 0 -1 0
g box
usemtl checker
s off
f 1/11/1 2/12/1 3/7/1 4/6/1
f 6/14/2 5/13/2 8/8/2 7/9/2
f 2/12/3 6/13/3 7/8/3 3/7/3
f 5/10/4 1/11/4 4/6/4 8/5/4
f 4/6/5 3/7/5 7/4/5 8/3/5
f 5/1/6 6/2/6 2/4/6 1/3/6
"""


def obj_reference(text):
    """The arrays the OBJ reader must give, worked out the slow, obvious way:
    one vertex per distinct (v, vt, vn) corner in order of first appearance,
    each polygon a fan from its first corner, uvs (u, 1 - v)."""
    v, vt, vn, corners_of, seen = [], [], [], [], {}
    for line in text.splitlines():
        words = line.split()
        if words and words[0] in ("v", "vt", "vn"):
            {"v": v, "vt": vt, "vn": vn}[words[0]].append([float(w) for w in words[1:]])
        elif words and words[0] == "f":
            face = []
            for corner in words[1:]:
                key = tuple(int(i) - 1 for i in corner.split("/"))
                face.append(seen.setdefault(key, len(seen)))
            corners_of.append(face)
    keys = sorted(seen, key=seen.get)
    triangles = [[f[0], f[k], f[k + 1]] for f in corners_of for k in range(1, len(f) - 1)]
    return (np.array([v[k[0]] for k in keys]), np.array(triangles),
            np.array([[vt[k[1]][0], 1 - vt[k[1]][1]] for k in keys]), np.array([vn[k[2]] for k in keys]))


def gltf_document(primitives, nodes, *, index_bits=16, interleaved=True, colors_u8=True, glb=True,
                  external_bin=None):
    """A glTF 2.0 document and its one buffer, built by hand with
    scripts/make_gltf_scenes.py's `GltfWriter`, left apart so that a test
    can break them before writing.

    ``primitives``: list of dicts with positions (N, 3), indices (M, 3), and
    optional normals, uvs (glTF convention: v = 0 at the top), colors (N, 4)
    in [0, 1]; one mesh per primitive. ``nodes``: list of (mesh index, node
    dict of transform keys). With ``interleaved`` POSITION, NORMAL and
    TEXCOORD_0 share one bufferView with a byteStride of 32 bytes; COLOR_0 is
    normalized uint8 (or float32). Indices are uint16 or uint32.
    """
    writer = make_gltf_scenes.GltfWriter()
    for prim in primitives:
        writer.mesh(writer.primitive(prim["positions"], prim["indices"], normals=prim.get("normals"),
                                     uvs=prim.get("uvs"), colors=prim.get("colors"),
                                     color_code="u1" if colors_u8 else "f4", interleaved=interleaved,
                                     index_bits=index_bits))
    writer.scene(*(writer.node(mesh=mesh, **transform) for mesh, transform in nodes))
    blob = bytes(writer.blob) + b"\0" * (-len(writer.blob) % 4)
    gltf = dict(writer.doc, buffers=[{"byteLength": len(blob)}])
    if not glb:
        gltf["buffers"][0]["uri"] = external_bin or (
            "data:application/octet-stream;base64," + base64.b64encode(blob).decode())
    return gltf, blob


def glb_bytes(gltf: dict, blob: bytes) -> bytes:
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def write_gltf(path, primitives, nodes, **options):
    glb = path.suffix == ".glb"
    gltf, blob = gltf_document(primitives, nodes, glb=glb, **options)
    if glb:
        path.write_bytes(glb_bytes(gltf, blob))
    else:
        if options.get("external_bin"):
            (path.parent / options["external_bin"]).write_bytes(blob)
        path.write_text(json.dumps(gltf))
    return path


# --------------------------------------------------------------------------- scenes


def scene(mesh_file, *, size=32, material=None, textures=None, camera=None, **node):
    return {"softras_scene": 1, "width": size, "height": size, "background": [0, 0, 0, 1],
            "camera": camera or {"projection": "orthographic", "left": -1, "right": 1, "bottom": -1, "top": 1,
                                 "near": -10, "far": 10},
            "textures": textures or {},
            "lights": [{"type": "directional", "direction": [-0.3, -0.5, -1]}],
            "nodes": [{"mesh": {"file": mesh_file}, "material": material or {}, **node}]}


def load(tmp_path, mesh_file, **options):
    return scene_from_dict(scene(mesh_file, **options), base_dir=str(tmp_path)).draws[0].mesh


def assert_soft_matches_gl(loaded_scene):
    soft = softras.render(loaded_scene)
    gl = softras.render(loaded_scene, backend="gl")
    verdict = softras.verify(loaded_scene, soft, gl, profile="strict")
    assert verdict.verdict == "pass", verdict
    return soft


# A quad over the whole view, corner k at POSITIONS[k]; the uvs each format
# writes so that the image appears upright: (x, y) in [0, 1] from the bottom
# left for OBJ and PLY (v = 0 at the image bottom), (x, 1 - y) for glTF.
QUAD = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
QUAD_UP = (QUAD[:, :2] + 1) / 2                                         # v = 0 at the bottom
QUAD_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])
QUADRANTS = {"top_left": (255, 0, 0, 255), "top_right": (0, 255, 0, 255),
             "bottom_left": (0, 0, 255, 255), "bottom_right": (255, 255, 255, 255)}


def write_quadrant_png(path, side=8):
    """An image whose four quadrants have four colours (row 0 = top)."""
    from PIL import Image
    pixels = np.zeros((side, side, 4), np.uint8)
    h = side // 2
    pixels[:h, :h], pixels[:h, h:] = QUADRANTS["top_left"], QUADRANTS["top_right"]
    pixels[h:, :h], pixels[h:, h:] = QUADRANTS["bottom_left"], QUADRANTS["bottom_right"]
    Image.fromarray(pixels).save(path)


def write_upright_quad(tmp_path, kind):
    if kind == "obj":
        lines = [f"v {x:g} {y:g} {z:g}" for x, y, z in QUAD] + [f"vt {u:g} {v:g}" for u, v in QUAD_UP]
        lines.append("f 1/1 2/2 3/3 4/4")
        (tmp_path / "quad.obj").write_text("\n".join(lines) + "\n")
        return "quad.obj"
    if kind in ("ply", "ply_ascii"):
        write_ply(tmp_path / f"{kind}.ply", QUAD, [[0, 1, 2, 3]], uvs=QUAD_UP,
                  fmt="ascii" if kind == "ply_ascii" else "binary_little_endian")
        return f"{kind}.ply"
    if kind in ("glb", "gltf"):
        uvs = QUAD_UP * [1, -1] + [0, 1]                                  # v = 0 at the top
        write_gltf(tmp_path / f"quad.{kind}", [{"positions": QUAD, "indices": QUAD_TRIANGLES, "uvs": uvs}], [(0, {})])
        return f"quad.{kind}"
    assert kind == "npz"
    np.savez(tmp_path / "quad.npz", positions=QUAD, indices=QUAD_TRIANGLES, uvs=QUAD_UP * [1, -1] + [0, 1])
    return "quad.npz"


# --------------------------------------------------------------------------- loaded arrays


def test_obj_textured_box_arrays(tmp_path):
    (tmp_path / "box.obj").write_text(BOX_OBJ)
    mesh = load(tmp_path, "box.obj")
    positions, triangles, uvs, normals = obj_reference(BOX_OBJ)
    assert mesh.primitive == "triangles"
    assert len(positions) == 24 and len(triangles) == 12                  # 6 faces x 4 corners, 2 triangles each
    np.testing.assert_array_equal(mesh.positions, positions)
    np.testing.assert_array_equal(mesh.indices, triangles)
    np.testing.assert_array_equal(mesh.uvs, uvs)
    np.testing.assert_array_equal(mesh.normals, normals)
    assert mesh.colors is None
    assert mesh.indices.dtype == np.int64 and mesh.positions.dtype == np.float64
    assert not mesh.positions.flags.writeable and not mesh.uvs.flags.writeable


def test_obj_without_uvs_keeps_the_file_vertices_and_triangulates_polygons(tmp_path):
    """Positions only: the file's vertices in the file's order (even an unused
    one); a pentagon is a fan of 3 triangles; negative indices count back;
    'v x y z r g b' gives vertex colours."""
    text = ("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0.5 1.5 0 1 1 1\nv 0 1 0 0.5 0.5 0.5\n"
            "v 9 9 9 0 0 0\n"
            "f 1 2 3 4 5\nf -6 -5 -4\n")
    (tmp_path / "penta.obj").write_text(text)
    mesh = load(tmp_path, "penta.obj")
    np.testing.assert_array_equal(mesh.positions, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0.5, 1.5, 0], [0, 1, 0],
                                                   [9, 9, 9]])
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 1, 2]])
    np.testing.assert_array_equal(mesh.colors[:3], [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]])
    assert mesh.uvs is None and mesh.normals is None


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
def test_ply_vertex_colours_normals_uvs(tmp_path, fmt):
    rng = np.random.default_rng(1)
    positions = rng.uniform(-1, 1, (5, 3)).astype(np.float32)
    normals = rng.uniform(-1, 1, (5, 3)).astype(np.float32)
    uvs = rng.uniform(0, 1, (5, 2)).astype(np.float32)
    colors = rng.integers(0, 256, (5, 4)).astype(np.uint8)
    faces = [[0, 1, 2], [2, 3, 4, 0]]                                     # a triangle and a quad
    write_ply(tmp_path / "m.ply", positions, faces, fmt=fmt, colors=colors, normals=normals, uvs=uvs)
    mesh = load(tmp_path, "m.ply")
    np.testing.assert_array_equal(mesh.positions, positions.astype(np.float64))
    np.testing.assert_array_equal(mesh.normals, normals.astype(np.float64))
    np.testing.assert_array_equal(mesh.colors, colors / 255.0)
    np.testing.assert_array_equal(mesh.uvs[:, 0], uvs[:, 0].astype(np.float64))
    np.testing.assert_array_equal(mesh.uvs[:, 1], 1.0 - uvs[:, 1].astype(np.float64))   # v up -> t down
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2], [2, 3, 4], [2, 4, 0]])


@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_ply_float_rgb_colours_and_uv_names(tmp_path, fmt):
    colors = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]], np.float32)
    write_ply(tmp_path / "m.ply", QUAD[:3], [[0, 1, 2]], fmt=fmt, colors=colors, uvs=QUAD_UP[:3],
              uv_names=("texture_u", "texture_v"), index_type="uint")
    mesh = load(tmp_path, "m.ply")
    np.testing.assert_array_equal(mesh.colors[:, :3], colors.astype(np.float64))
    np.testing.assert_array_equal(mesh.colors[:, 3], 1.0)
    np.testing.assert_array_equal(mesh.uvs, [[0, 1], [1, 1], [1, 0]])


def test_npz_arrays(tmp_path):
    colors = np.array([[0, 128, 255], [255, 0, 0], [1, 2, 3], [4, 5, 6]], np.uint8)
    np.savez(tmp_path / "m.npz", positions=QUAD.astype(np.float32), indices=QUAD_TRIANGLES.reshape(-1).astype(np.uint32),
             colors=colors, normals=np.tile([0, 0, 1.0], (4, 1)), uvs=QUAD_UP)
    mesh = load(tmp_path, "m.npz")
    np.testing.assert_array_equal(mesh.positions, QUAD)
    np.testing.assert_array_equal(mesh.indices, QUAD_TRIANGLES)
    np.testing.assert_array_equal(mesh.colors[:, :3], colors / 255.0)
    np.testing.assert_array_equal(mesh.colors[:, 3], 1.0)
    np.testing.assert_array_equal(mesh.uvs, QUAD_UP)                    # the scene's own convention: kept
    np.testing.assert_array_equal(mesh.normals, np.tile([0, 0, 1.0], (4, 1)))


def two_primitives():
    rng = np.random.default_rng(7)
    first = {"positions": rng.uniform(-0.5, 0.5, (4, 3)), "indices": [[0, 1, 2], [0, 2, 3]],
             "normals": rng.uniform(-1, 1, (4, 3)), "uvs": rng.uniform(0, 1, (4, 2)),
             "colors": rng.integers(0, 256, (4, 4)) / 255}
    second = {"positions": rng.uniform(-0.5, 0.5, (3, 3)), "indices": [[0, 1, 2]],
              "normals": rng.uniform(-1, 1, (3, 3)), "uvs": rng.uniform(0, 1, (3, 2))}   # no COLOR_0: white
    return [first, second]


@pytest.mark.parametrize("suffix, index_bits, interleaved", [(".glb", 16, True), (".gltf", 32, True),
                                                              (".glb", 32, False), (".gltf", 16, False)])
def test_gltf_primitives_concatenated_with_node_transforms(tmp_path, suffix, index_bits, interleaved):
    """Two meshes under two nodes: translated, and scaled with a mirror
    (negative determinant: winding reversed, normals by the inverse transpose)."""
    prims = two_primitives()
    nodes = [(0, {"translation": [0.25, 0, 0]}), (1, {"scale": [-1, 2, 1]})]
    write_gltf(tmp_path / f"m{suffix}", prims, nodes, index_bits=index_bits, interleaved=interleaved)
    mesh = load(tmp_path, f"m{suffix}")
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)
    expected_positions = np.concatenate([f32(prims[0]["positions"]) + [0.25, 0, 0],
                                         f32(prims[1]["positions"]) * [-1, 2, 1]])
    expected_normals = np.concatenate([f32(prims[0]["normals"]), f32(prims[1]["normals"]) * [-1, 0.5, 1]])
    expected_indices = [[0, 1, 2], [0, 2, 3], [6, 5, 4]]                  # second: offset 4, reversed
    np.testing.assert_array_equal(mesh.positions, expected_positions)
    np.testing.assert_array_equal(mesh.indices, expected_indices)
    np.testing.assert_allclose(mesh.normals, expected_normals, rtol=1e-15)
    np.testing.assert_array_equal(mesh.uvs, np.concatenate([f32(p["uvs"]) for p in prims]))   # glTF: kept
    np.testing.assert_array_equal(mesh.colors, np.concatenate([prims[0]["colors"], np.ones((3, 4))]))


def test_gltf_float_colours_and_external_buffer(tmp_path):
    prims = two_primitives()[:1]
    write_gltf(tmp_path / "m.gltf", prims, [(0, {})], colors_u8=False, external_bin="m data.bin")
    mesh = load(tmp_path, "m.gltf")
    np.testing.assert_array_equal(mesh.colors, np.asarray(prims[0]["colors"], np.float32).astype(np.float64))


def test_relative_to_the_scene_file_or_the_current_folder(tmp_path, monkeypatch):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "box.obj").write_text(BOX_OBJ)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene("meshes/box.obj")))
    monkeypatch.chdir("/")
    assert len(softras.load_scene(str(path)).draws[0].mesh.indices) == 12
    with pytest.raises(SceneError, match=r"^nodes\[0\]\.mesh\.file: meshes/box\.obj: no such file"):
        softras.load_scene(scene("meshes/box.obj"))                     # a dict: the current folder, /
    monkeypatch.chdir(tmp_path)
    assert len(softras.load_scene(scene("meshes/box.obj")).draws[0].mesh.indices) == 12


# --------------------------------------------------------------------------- pictures


@pytest.mark.gl
@pytest.mark.parametrize("kind", ["obj", "ply", "ply_ascii", "glb", "gltf", "npz"])
def test_uv_convention_shows_the_image_upright(tmp_path, kind):
    """A quad whose uvs, in the file's own convention, put the image upright:
    both renderers show the image's top-left quadrant at the top left, etc."""
    write_quadrant_png(tmp_path / "quadrants.png")
    name = write_upright_quad(tmp_path, kind)
    data = scene(name, size=16, material={"texture": "q"},
                 textures={"q": {"image": "quadrants.png", "min_filter": "nearest", "mag_filter": "nearest"}})
    loaded = scene_from_dict(data, base_dir=str(tmp_path))
    picture = assert_soft_matches_gl(loaded)
    for (row, col), quadrant in {(3, 3): "top_left", (3, 12): "top_right", (12, 3): "bottom_left",
                                 (12, 12): "bottom_right"}.items():
        assert tuple(picture[row, col]) == QUADRANTS[quadrant], (kind, quadrant, picture[row, col])


@pytest.mark.gl
def test_textured_box_obj_soft_matches_gl(tmp_path):
    (tmp_path / "box.obj").write_text(BOX_OBJ)
    data = scene("box.obj", size=48, material={"texture": "c", "shading": "phong"},
                 textures={"c": {"procedural": "checker", "size": [64, 64], "squares": 8,
                                 "min_filter": "linear_mipmap_linear"}},
                 camera={"projection": "perspective", "fov_y": 50, "near": 0.5, "far": 20,
                         "eye": [2.5, 2, 3.5], "target": [0, 0, 0]}, cull="back")
    assert_soft_matches_gl(scene_from_dict(data, base_dir=str(tmp_path)))


@pytest.mark.gl
@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_vertex_coloured_ply_soft_matches_gl(tmp_path, fmt):
    rng = np.random.default_rng(3)
    grid = np.array([[x, y, 0.3 * np.sin(3 * x + 2 * y)] for y in np.linspace(-0.9, 0.9, 5)
                     for x in np.linspace(-0.9, 0.9, 5)])
    faces = [[j * 5 + i, j * 5 + i + 1, (j + 1) * 5 + i + 1, (j + 1) * 5 + i] for j in range(4) for i in range(4)]
    write_ply(tmp_path / "c.ply", grid, faces, fmt=fmt, colors=rng.integers(0, 256, (25, 3)).astype(np.uint8))
    mesh = load(tmp_path, "c.ply")
    assert len(mesh.indices) == 32
    assert_soft_matches_gl(scene_from_dict(scene("c.ply", size=40), base_dir=str(tmp_path)))


@pytest.mark.gl
@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_soft_matches_gl(tmp_path, suffix):
    prims = two_primitives()
    write_gltf(tmp_path / f"m{suffix}", prims, [(0, {"translation": [0.25, 0, 0]}), (1, {"scale": [-1, 2, 1]})],
               index_bits=16 if suffix == ".glb" else 32)
    assert_soft_matches_gl(scene_from_dict(scene(f"m{suffix}", size=40, material={"shading": "gouraud"}),
                                           base_dir=str(tmp_path)))


# --------------------------------------------------------------------------- speed


def test_a_million_triangle_binary_ply_loads_in_well_under_a_second(tmp_path):
    cols, rows = 1000, 500
    xs, ys = np.meshgrid(np.linspace(-1, 1, cols + 1), np.linspace(-1, 1, rows + 1))
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1).astype("<f4")
    ids = np.arange(xs.size).reshape(rows + 1, cols + 1)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(), ids[1:, 1:].ravel(), ids[1:, :-1].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    assert len(triangles) == 1_000_000
    faces = np.zeros(len(triangles), [("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, triangles
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(positions)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(faces)}\n"
              f"property list uchar int vertex_indices\nend_header\n").encode()
    (tmp_path / "big.ply").write_bytes(header + positions.tobytes() + faces.tobytes())
    path = tmp_path / "big.json"
    path.write_text(json.dumps(scene("big.ply")))
    times = []
    for _ in range(5):
        start = time.perf_counter()
        loaded = softras.load_scene(str(path))
        times.append(time.perf_counter() - start)
    np.testing.assert_array_equal(loaded.draws[0].mesh.indices, triangles)
    # ~0.1 s measured here (numpy.frombuffer, no Python lists); a list-based
    # reader takes seconds.  The bound leaves room for a busy machine.
    assert statistics.median(times) < 1.0, times


# --------------------------------------------------------------------------- bad files


def _bad_files(folder):
    """name -> (file name to put in the scene, the start of the reason after 'NAME: ')."""
    write_ply(folder / "truncated.ply", QUAD, [[0, 1, 2], [0, 2, 3]], truncate=5)
    write_ply(folder / "truncated_ascii.ply", QUAD, [[0, 1, 2], [0, 2, 3]], fmt="ascii", truncate=8)
    write_ply(folder / "out_of_range.ply", QUAD, [[0, 1, 2], [0, 2, 4]])
    write_ply(folder / "nan.ply", [[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 1, 2]])
    write_ply(folder / "no_faces.ply", QUAD, [])
    write_ply(folder / "million_faces.ply", QUAD, [[0, 1, 2]], face_count=5_000_000)
    write_ply(folder / "bad_colour.ply", QUAD[:3], [[0, 1, 2]], colors=np.array([[0, 0, 0], [0.5, 2, 0], [0, 0, 0]]))
    (folder / "obj_out_of_range.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    (folder / "obj_no_faces.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (folder / "obj_lines.obj").write_text("v 0 0 0\nv 1 0 0\nl 1 2\n")
    (folder / "obj_nan.obj").write_text("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")
    (folder / "obj_mixed_uvs.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2 3\n")
    np.savez(folder / "npz_nan.npz", positions=np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]))
    np.savez(folder / "npz_extra.npz", positions=QUAD[:3], weights=np.ones(3))
    good = write_gltf(folder / "good.glb", [{"positions": QUAD, "indices": QUAD_TRIANGLES}], [(0, {})]).read_bytes()
    (folder / "truncated.glb").write_bytes(good[:-6])
    gltf, blob = gltf_document([{"positions": QUAD, "indices": QUAD_TRIANGLES}], [(0, {})])
    (folder / "short_buffer.glb").write_bytes(glb_bytes(gltf, blob[:-8]))
    gltf, blob = gltf_document([{"positions": QUAD, "indices": [[0, 1, 2], [0, 2, 7]]}], [(0, {})])
    (folder / "gltf_out_of_range.glb").write_bytes(glb_bytes(gltf, blob))
    gltf, blob = gltf_document([{"positions": QUAD, "indices": QUAD_TRIANGLES}], [(0, {})], glb=False)
    gltf["meshes"][0]["primitives"][0]["mode"] = 5
    (folder / "strip.gltf").write_text(json.dumps(gltf))
    (folder / "model.stl").write_text("solid x\nendsolid x\n")
    (folder / "empty.npz").write_bytes(b"")
    return {
        "missing_file": ("nowhere.ply", "no such file"),
        "truncated_binary_ply": ("truncated.ply", "truncated"),
        "truncated_ascii_ply": ("truncated_ascii.ply", "truncated"),
        "ply_index_out_of_range": ("out_of_range.ply", "triangle 1 has vertex index 4, out of range for 4 vertices"),
        "ply_nan_position": ("nan.ply", "vertex 2 has a non-finite position"),
        "ply_no_triangles": ("no_faces.ply", "no triangles"),
        "ply_5_million_faces": ("million_faces.ply", "5000000 triangles; the scene may have at most"),
        "ply_colour_above_1": ("bad_colour.ply", "vertex 1 has colour (0.5, 2, 0, 1) outside [0, 1]"),
        "obj_index_out_of_range": ("obj_out_of_range.obj", "line 4: v index 4 out of range"),
        "obj_no_triangles": ("obj_no_faces.obj", "no faces (no triangles)"),
        "obj_lines": ("obj_lines.obj", "line 3: lines ('l') are not supported"),
        "obj_nan_position": ("obj_nan.obj", "vertex 1 has a non-finite position"),
        "obj_mixed_uvs": ("obj_mixed_uvs.obj", "some face corners have texture coordinates"),
        "npz_infinite_position": ("npz_nan.npz", "vertex 2 has a non-finite position"),
        "npz_unknown_array": ("npz_extra.npz", "unknown array 'weights'"),
        "npz_empty_file": ("empty.npz", "not a readable .npz archive"),
        "truncated_glb": ("truncated.glb", "truncated"),
        "glb_buffer_shorter_than_byte_length": ("short_buffer.glb", "truncated: buffers[0] has"),
        "gltf_index_out_of_range": ("gltf_out_of_range.glb", "meshes[0].primitives[0]: index 7 out of range"),
        "gltf_triangle_strip": ("strip.gltf", "meshes[0].primitives[0]: mode 5 (TRIANGLE_STRIP) is not supported"),
        "unsupported_extension": ("model.stl", "unsupported mesh file type '.stl'"),
    }


BAD = sorted([
    "missing_file", "truncated_binary_ply", "truncated_ascii_ply", "ply_index_out_of_range", "ply_nan_position",
    "ply_no_triangles", "ply_5_million_faces", "ply_colour_above_1", "obj_index_out_of_range", "obj_no_triangles",
    "obj_lines", "obj_nan_position", "obj_mixed_uvs", "npz_infinite_position", "npz_unknown_array",
    "npz_empty_file", "truncated_glb", "glb_buffer_shorter_than_byte_length", "gltf_index_out_of_range",
    "gltf_triangle_strip", "unsupported_extension"])


def test_the_list_of_bad_files_is_complete(tmp_path):
    assert sorted(_bad_files(tmp_path)) == BAD


@pytest.mark.parametrize("case", BAD)
def test_bad_mesh_file_is_one_line_naming_place_and_file(tmp_path, case):
    name, reason = _bad_files(tmp_path)[case]
    with pytest.raises(SceneError) as info:
        scene_from_dict(scene(name), base_dir=str(tmp_path))
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"nodes[0].mesh.file: {name}: {reason}"), message


@pytest.mark.parametrize("case", ["truncated_binary_ply", "gltf_index_out_of_range", "unsupported_extension",
                                  "missing_file", "obj_nan_position"])
def test_cli_exits_2_and_writes_nothing(tmp_path, capsys, case):
    name, reason = _bad_files(tmp_path)[case]
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene(name)))
    output = tmp_path / "out.png"
    output.write_bytes(b"previous output")
    before = sorted(os.listdir(tmp_path))
    status = cli.main(["render", str(path), "-o", str(output)])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith(f"softras: error: nodes[0].mesh.file: {name}: {reason}"), captured.err
    assert output.read_bytes() == b"previous output"
    assert sorted(os.listdir(tmp_path)) == before


def test_a_huge_face_count_is_refused_before_allocating(tmp_path):
    _bad_files(tmp_path)
    tracemalloc.start()
    try:
        with pytest.raises(SceneError, match="5000000 triangles"):
            scene_from_dict(scene("million_faces.ply"), base_dir=str(tmp_path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 * 2 ** 20, peak


def test_file_meshes_share_the_scene_triangle_budget(tmp_path, monkeypatch):
    write_ply(tmp_path / "quad.ply", QUAD, [[0, 1, 2], [0, 2, 3]])
    monkeypatch.setattr(softras.scene.meshes, "MAX_TRIANGLES", 3)
    data = scene("quad.ply")
    data["nodes"].append({"mesh": {"file": "quad.ply"}})
    with pytest.raises(SceneError, match=r"^nodes\[1\]\.mesh\.file: quad\.ply: 2 triangles; the scene may have at most 1 more"):
        scene_from_dict(data, base_dir=str(tmp_path))


@pytest.mark.parametrize("mesh, place, reason", [
    ({"file": "quad.ply", "positions": [[0, 0, 0]]}, "nodes[0].mesh.positions", "not allowed together with file"),
    ({"file": "quad.ply", "uvs": []}, "nodes[0].mesh.uvs", "not allowed together with file"),
    ({"file": 3}, "nodes[0].mesh.file", "expected a string"),
    ({"file": ""}, "nodes[0].mesh.file", "must not be empty"),
])
def test_file_key_refusals(tmp_path, mesh, place, reason):
    write_ply(tmp_path / "quad.ply", QUAD, [[0, 1, 2, 3]])
    data = scene("quad.ply")
    data["nodes"][0]["mesh"] = mesh
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, base_dir=str(tmp_path))
    assert str(info.value).startswith(f"{place}: {reason}"), str(info.value)


def test_supported_suffixes_are_documented():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "docs" / "scene_format.md").read_text()
    for suffix in meshfiles.SUFFIXES:
        assert f"`{suffix}`" in text, suffix
    assert f"| `MAX_VERTICES` | `{meshfiles.MAX_VERTICES}` |" in text
