"""Write the glTF conformance scenes of scenes/ (docs/gltf.md), and the glTF
writer tests/test_gltf_scene.py builds its files with.

A glTF file is itself a scene (`softras.load_scene("model.glb")`), so each
file here is a conformance scene of its own:

- ``scenes/gltf_textured_box.glb``: a lit, textured box (PNG in a
  bufferView, trilinear sampler, interleaved POSITION/NORMAL/TEXCOORD_0
  with a byteStride, 16-bit indices) and its mirror image (a node with scale
  (-1, 1, 1): negative determinant, reversed winding) under a perspective
  camera node, lit by the default light rig, back faces culled;
- ``scenes/gltf_alpha_modes.gltf`` with ``gltf_alpha_modes.bin`` and
  ``gltf_alpha_modes.png``: OPAQUE (alpha ignored), MASK (alphaCutoff 0.5
  on a texture with holes) and BLEND (translucent vertex colours) quads,
  unlit (KHR_materials_unlit), an orthographic camera, 32-bit indices;
- ``scenes/gltf_hierarchy_framed.glb``: a node hierarchy (``matrix`` and
  TRS nodes) of vertex-coloured (normalized uint8 COLOR_0) and flat-lit
  (no NORMAL) meshes, 8-bit indices, no camera: the framing camera.

Run from the repository root:

    python3 scripts/make_gltf_scenes.py

The golden images (golden/) hold JSON scenes only; these are checked
against GL by tests/test_gltf_scene.py and `softras conformance scenes/`.
"""

from __future__ import annotations

import base64
import io
import json
import math
import struct
from pathlib import Path

import numpy as np

SCENES = Path(__file__).resolve().parents[1] / "scenes"

_COMPONENT = {"i1": 5120, "u1": 5121, "i2": 5122, "u2": 5123, "u4": 5125, "f4": 5126}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def png_bytes(pixels: np.ndarray) -> bytes:
    """(H, W, 4) uint8 RGBA, row 0 = top -> PNG bytes."""
    from PIL import Image
    out = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels, np.uint8), "RGBA").save(out, format="PNG")
    return out.getvalue()


class GltfWriter:
    """A glTF 2.0 document built by hand, one buffer; ``write`` makes a .glb or a .gltf."""

    def __init__(self):
        self.doc: dict = {"asset": {"version": "2.0", "generator": "softras scripts/make_gltf_scenes.py"}}
        self.blob = bytearray()

    def add(self, table: str, entry: dict) -> int:
        self.doc.setdefault(table, []).append(entry)
        return len(self.doc[table]) - 1

    def view(self, data: bytes, stride: int | None = None, target: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        entry = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if stride:
            entry["byteStride"] = stride
        if target:
            entry["target"] = target
        self.blob.extend(data)
        return self.add("bufferViews", entry)

    def accessor(self, array, code: str = "f4", *, normalized: bool = False, view: int | None = None,
                 offset: int = 0, count: int | None = None, width: int | None = None, minmax: bool = False) -> int:
        """An accessor of ``array`` (N, K) stored as ``code`` (its own bufferView unless ``view``)."""
        array = np.asarray(array)
        array = array.reshape(len(array), -1)
        if view is None:
            view = self.view(np.ascontiguousarray(array.astype("<" + code)).tobytes())
        entry = {"bufferView": view, "byteOffset": offset, "componentType": _COMPONENT[code],
                 "type": _TYPE[width or array.shape[1]], "count": len(array) if count is None else count}
        if normalized:
            entry["normalized"] = True
        if minmax:
            entry["min"], entry["max"] = array.min(0).tolist(), array.max(0).tolist()
        return self.add("accessors", entry)

    def primitive(self, positions, indices=None, *, normals=None, uvs=None, colors=None, color_code="f4",
                  interleaved: bool = False, index_bits: int = 16, material: int | None = None) -> dict:
        """A TRIANGLES primitive; ``interleaved``: POSITION, NORMAL, TEXCOORD_0 in one
        bufferView with a byteStride of 32 bytes."""
        positions = np.asarray(positions, np.float32)
        n = len(positions)
        attributes = {}
        if interleaved:
            record = np.zeros(n, [("p", "<f4", 3), ("n", "<f4", 3), ("t", "<f4", 2)])
            record["p"] = positions
            if normals is not None:
                record["n"] = normals
            if uvs is not None:
                record["t"] = uvs
            view = self.view(record.tobytes(), stride=32, target=34962)
            attributes["POSITION"] = self.accessor(positions, view=view, minmax=True)
            if normals is not None:
                attributes["NORMAL"] = self.accessor(normals, view=view, offset=12, width=3)
            if uvs is not None:
                attributes["TEXCOORD_0"] = self.accessor(uvs, view=view, offset=24, width=2)
        else:
            attributes["POSITION"] = self.accessor(positions, minmax=True)
            if normals is not None:
                attributes["NORMAL"] = self.accessor(normals)
            if uvs is not None:
                attributes["TEXCOORD_0"] = self.accessor(uvs)
        if colors is not None:
            colors = np.asarray(colors, np.float64)
            if color_code == "f4":
                attributes["COLOR_0"] = self.accessor(colors)
            else:
                top = np.iinfo(np.dtype(color_code)).max
                attributes["COLOR_0"] = self.accessor(np.round(colors * top), color_code, normalized=True)
        primitive = {"attributes": attributes}
        if indices is not None:
            code = {8: "u1", 16: "u2", 32: "u4"}[index_bits]
            flat = np.asarray(indices).reshape(-1, 1)
            primitive["indices"] = self.accessor(flat, code, view=self.view(flat.astype("<" + code).tobytes(),
                                                                            target=34963))
        if material is not None:
            primitive["material"] = material
        return primitive

    def mesh(self, *primitives: dict) -> int:
        return self.add("meshes", {"primitives": list(primitives)})

    def image(self, pixels: np.ndarray, where: str = "bufferView", file_name: str | None = None) -> int:
        """A PNG image: in a bufferView, a data URI, or the file ``file_name`` (written by ``write``)."""
        data = png_bytes(pixels)
        if where == "bufferView":
            return self.add("images", {"bufferView": self.view(data), "mimeType": "image/png"})
        if where == "data":
            return self.add("images", {"uri": "data:image/png;base64," + base64.b64encode(data).decode()})
        self.files = {**getattr(self, "files", {}), file_name: data}
        return self.add("images", {"uri": file_name})

    def texture(self, image: int, **sampler) -> int:
        entry = {"source": image}
        if sampler:
            entry["sampler"] = self.add("samplers", sampler)
        return self.add("textures", entry)

    def node(self, **entry) -> int:
        return self.add("nodes", entry)

    def scene(self, *roots: int) -> None:
        self.doc["scenes"] = [{"nodes": list(roots)}]
        self.doc["scene"] = 0

    def write(self, path: Path, external_bin: str | None = None) -> Path:
        """A .glb (the buffer as its BIN chunk) or a .gltf (the buffer as a data
        URI, or as the file ``external_bin`` beside it)."""
        path = Path(path)
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        doc = json.loads(json.dumps(self.doc))
        if blob:
            doc["buffers"] = [{"byteLength": len(blob)}]
        for name, data in getattr(self, "files", {}).items():
            (path.parent / name).write_bytes(data)
        if path.suffix == ".glb":
            text = json.dumps(doc).encode()
            text += b" " * (-len(text) % 4)
            chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
            if blob:
                chunks += struct.pack("<II", len(blob), 0x004E4942) + blob
            path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
            return path
        if blob:
            if external_bin:
                (path.parent / external_bin).write_bytes(blob)
                doc["buffers"][0]["uri"] = external_bin
            else:
                doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        path.write_text(json.dumps(doc, indent=1) + "\n")
        return path


# --------------------------------------------------------------------------- geometry


def box(size: float = 1.0):
    """A cube's 24 vertices (positions, normals, uvs with v = 0 at the top of
    the image) and 12 counter-clockwise triangles seen from outside."""
    positions, normals, uvs, triangles = [], [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(positions)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                positions.append((n + a * u + b * v) * size / 2)
                normals.append(n)
                uvs.append(((a + 1) / 2, (1 - b) / 2))             # v = 0 at the image top
            triangles += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(positions), np.array(normals), np.array(uvs), np.array(triangles)


def quad(width: float = 1.0, height: float = 1.0, z: float = 0.0):
    """A quad in the z plane facing +z: positions, uvs (image upright), 2 triangles."""
    w, h = width / 2, height / 2
    positions = np.array([[-w, -h, z], [w, -h, z], [w, h, z], [-w, h, z]])
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float64)
    return positions, uvs, np.array([[0, 1, 2], [0, 2, 3]])


def letter_texture(side: int = 32) -> np.ndarray:
    """An 'F' on a two-colour checker: shows any flip or rotation of the uvs."""
    y, x = np.mgrid[0:side, 0:side]
    cell = side // 4
    pixels = np.where((((x // cell) + (y // cell)) % 2 == 0)[..., None], [230, 200, 60, 255], [60, 110, 200, 255])
    f = ((x >= side // 4) & (x < side // 4 + side // 8) & (y >= side // 8) & (y < side - side // 8)) \
        | ((y >= side // 8) & (y < side // 8 + side // 8) & (x >= side // 4) & (x < side - side // 4)) \
        | ((y >= side // 2 - side // 16) & (y < side // 2 + side // 16) & (x >= side // 4) & (x < side // 2 + side // 8))
    pixels[f] = [180, 30, 40, 255]
    return pixels.astype(np.uint8)


def holes_texture(side: int = 16) -> np.ndarray:
    """Opaque texels with round transparent holes (alpha 0 or 255), for MASK."""
    y, x = np.mgrid[0:side, 0:side] + 0.5
    cell = side / 2
    fx, fy = (x % cell) / cell - 0.5, (y % cell) / cell - 0.5
    pixels = np.zeros((side, side, 4), np.uint8)
    pixels[..., 0], pixels[..., 1], pixels[..., 2] = 40 + 12 * x.astype(int), 200, 90
    pixels[..., 3] = np.where(fx * fx + fy * fy < 0.1, 0, 255)
    return pixels


def dimples_normal_map(side: int = 64, cells: int = 4) -> np.ndarray:
    """A glTF tangent-space normal map (+Y up the image, as glTF's
    normalTexture): round dimples, ``cells`` x ``cells``, of a height field h,
    n = normalize(-dh/dcol, +dh/drow, 1) (up the image is -row), rgb = (n + 1) / 2."""
    y, x = np.mgrid[0:side, 0:side] + 0.5
    cell = side / cells
    fx, fy = (x % cell) / cell - 0.5, (y % cell) / cell - 0.5
    r2 = fx * fx + fy * fy
    h = np.where(r2 < 0.16, -(0.16 - r2) * 6.0 * side / 4, 0.0)     # dimples, depth in texels
    n = np.stack([-np.gradient(h, axis=1), np.gradient(h, axis=0), np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    pixels = np.empty((side, side, 4), np.uint8)
    pixels[..., :3] = np.round((n + 1.0) * 127.5).astype(np.uint8)
    pixels[..., 3] = 255
    return pixels


def gltf_tangents(positions, normals, uvs, triangles) -> np.ndarray:
    """glTF TANGENT (xyz, w; the bitangent w cross(N, T) up the image) of a
    mesh whose uvs run along its faces: softras's frames with w negated."""
    from softras.scene.meshes import vertex_tangents

    frames = vertex_tangents(np.asarray(positions, float), np.asarray(normals, float), np.asarray(uvs, float),
                             np.asarray(triangles))
    frames[:, 3] *= -1.0
    return frames


# --------------------------------------------------------------------------- the scenes


def textured_box() -> GltfWriter:
    g = GltfWriter()
    positions, normals, uvs, triangles = box()
    texture = g.texture(g.image(letter_texture()), magFilter=9729, minFilter=9987, wrapS=10497, wrapT=33071)
    material = g.add("materials", {"pbrMetallicRoughness": {"baseColorTexture": {"index": texture},
                                                             "metallicFactor": 0.1, "roughnessFactor": 0.5}})
    mesh = g.mesh(g.primitive(positions, triangles, normals=normals, uvs=uvs, interleaved=True, material=material))
    yaw, pitch = math.radians(35), math.radians(-25)              # a camera above and to the right
    q_yaw = (0, math.sin(yaw / 2), 0, math.cos(yaw / 2))
    q_pitch = (math.sin(pitch / 2), 0, 0, math.cos(pitch / 2))
    camera = g.add("cameras", {"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.5, "zfar": 20,
                                                                      "aspectRatio": 1.5}})
    camera_node = g.node(name="camera", translation=[0, 0, 4.2], camera=camera)
    rig = g.node(name="camera yaw", rotation=list(q_yaw),
                 children=[g.node(name="camera pitch", rotation=list(q_pitch), children=[camera_node])])
    left = g.node(name="box", mesh=mesh, translation=[-0.8, 0, 0], rotation=[0, 0.259, 0, 0.966])
    right = g.node(name="mirrored box", mesh=mesh, translation=[0.8, 0, 0], scale=[-1, 1, 1],
                   rotation=[0, 0.259, 0, 0.966])
    g.scene(rig, left, right)
    return g


def alpha_modes() -> GltfWriter:
    g = GltfWriter()
    unlit = {"KHR_materials_unlit": {}}
    g.doc["extensionsUsed"] = ["KHR_materials_unlit"]
    holes = g.texture(g.image(holes_texture(), "file", "gltf_alpha_modes.png"), magFilter=9728, minFilter=9728)
    opaque = g.add("materials", {"extensions": unlit, "alphaMode": "OPAQUE",
                                 "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.3, 0.8, 0.2]}})
    mask = g.add("materials", {"extensions": unlit, "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
                               "pbrMetallicRoughness": {"baseColorTexture": {"index": holes}}})
    blend = g.add("materials", {"extensions": unlit, "alphaMode": "BLEND", "doubleSided": True})
    p, uv, t = quad(2.4, 1.6)
    back = g.mesh(g.primitive(p, t, index_bits=32, material=opaque))
    masked = g.mesh(g.primitive(p * 0.8, t, uvs=uv * 2, index_bits=32, material=mask))
    colors = [[1, 0.2, 0.2, 0.6], [1, 1, 0.2, 0.3], [0.2, 1, 0.2, 0.8], [1, 1, 1, 0.5]]
    glass = g.mesh(g.primitive(p * 0.5, t, colors=colors, index_bits=32, material=blend))
    camera = g.add("cameras", {"type": "orthographic",
                               "orthographic": {"xmag": 1.5, "ymag": 1.0, "znear": 0.1, "zfar": 10}})
    g.scene(g.node(name="camera", translation=[0, 0, 5], camera=camera),
            g.node(name="glass front", mesh=glass, translation=[0.45, -0.2, 1.0]),
            g.node(name="back", mesh=back, translation=[0, 0, -1]),
            g.node(name="masked", mesh=masked, rotation=[0, 0.2, 0, 0.98]),
            g.node(name="glass behind", mesh=glass, translation=[-0.5, 0.3, -0.5]))
    return g


def hierarchy_framed() -> GltfWriter:
    g = GltfWriter()
    positions, normals, uvs, triangles = box()
    rng = np.random.default_rng(7)
    colors = np.concatenate([rng.uniform(0.2, 1, (24, 3)), np.ones((24, 1))], axis=1)
    coloured = g.mesh(g.primitive(positions, triangles, colors=colors, color_code="u1", index_bits=8,
                                  material=g.add("materials", {"extensions": {"KHR_materials_unlit": {}}})))
    flat = g.mesh(g.primitive(positions * [1.6, 0.3, 1.6], triangles, index_bits=8,      # no NORMAL: flat
                              material=g.add("materials", {"pbrMetallicRoughness": {
                                  "baseColorFactor": [0.9, 0.6, 0.3, 1], "metallicFactor": 0.0}})))
    g.doc["extensionsUsed"] = ["KHR_materials_unlit"]
    child = g.node(name="small", mesh=coloured, translation=[0, 1.2, 0], scale=[0.5, 0.5, 0.5],
                   rotation=[0, 0.383, 0, 0.924])
    # a rotation about +y and a translation, its rows written as glTF's columns (column-major)
    turned = np.array([[0.866, 0, 0.5, 0], [0, 1, 0, 0], [-0.5, 0, 0.866, 0], [0.6, 0.2, 0, 1]])
    g.scene(g.node(name="base", mesh=flat, translation=[0, -0.8, 0], children=[
        g.node(name="tower", mesh=coloured, matrix=turned.reshape(-1).tolist(), children=[child])]))
    return g


def normal_mapped() -> GltfWriter:
    """A lit box with a dimpled normalTexture and its TANGENTs, under a
    KHR_lights_punctual directional light from the upper left."""
    g = GltfWriter()
    positions, normals, uvs, triangles = box()
    g.doc["extensionsUsed"] = ["KHR_lights_punctual"]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 1.0,
                                                               "color": [1.0, 0.95, 0.9]}]}}
    dimples = g.texture(g.image(dimples_normal_map()), magFilter=9729, minFilter=9987)
    material = g.add("materials", {"pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.7, 0.65, 1],
                                                             "metallicFactor": 0.0, "roughnessFactor": 0.45},
                                   "normalTexture": {"index": dimples}})
    primitive = g.primitive(positions, triangles, normals=normals, uvs=uvs, material=material)
    tangents = gltf_tangents(positions, normals, uvs, np.asarray(triangles).reshape(-1, 3))
    primitive["attributes"]["TANGENT"] = g.accessor(tangents.astype(np.float32))
    camera = g.add("cameras", {"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.5, "zfar": 20,
                                                                      "aspectRatio": 1.25}})
    # the light travels along the node's -Z: turned to come from the upper left, in front
    g.scene(g.node(name="camera", translation=[0, 0, 3.6], camera=camera),
            g.node(name="sun", rotation=[-0.3, -0.25, 0.0, 0.92], extensions={"KHR_lights_punctual": {"light": 0}}),
            g.node(name="box", mesh=g.mesh(primitive), rotation=[0.2, 0.35, 0.05, 0.913]))
    return g


def main() -> None:
    textured_box().write(SCENES / "gltf_textured_box.glb")
    alpha_modes().write(SCENES / "gltf_alpha_modes.gltf", external_bin="gltf_alpha_modes.bin")
    hierarchy_framed().write(SCENES / "gltf_hierarchy_framed.glb")
    normal_mapped().write(SCENES / "gltf_normal_mapped.glb")


if __name__ == "__main__":
    main()
