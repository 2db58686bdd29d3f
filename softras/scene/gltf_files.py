"""The glTF 2.0 container: a .gltf or .glb file's JSON, buffers, accessors and images.

Shared by the two glTF readers of the scene layer: `softras.scene.meshfiles`
(``"mesh": {"file": "model.glb"}``: the triangles of a file as one mesh) and
`softras.scene.gltf` (a whole glTF file as a scene).  What is read here:

- the file: a .glb's chunks (12-byte header, a JSON chunk, an optional BIN
  chunk) or a .gltf's JSON text;
- buffers: the GLB's BIN chunk (a buffer without ``uri``), ``data:`` URIs
  (base64) and files relative to the glTF file, each at least its
  ``byteLength`` long;
- accessors (:meth:`GltfFile.accessor`): any componentType (signed and
  unsigned 8/16/32-bit integers, float32), SCALAR and VECn types, a
  bufferView's ``byteStride`` (interleaved attributes), ``normalized``
  integers (:meth:`GltfFile.floats` divides by the type's maximum); sparse
  accessors are refused;
- a primitive's arrays (:meth:`GltfFile.primitive`), in model space:
  POSITION (N, 3), the indices (M, 3) int64 (8, 16 or 32-bit unsigned, or
  none: 0, 1, 2, ...), NORMAL (N, 3), TEXCOORD_0 (N, 2) with v = 0 at the
  TOP of the image (glTF's convention is the scene format's: kept as is),
  COLOR_0 (N, 4) straight RGBA (RGB gets alpha 1);
- images (:meth:`GltfFile.image_bytes`): an image's bytes from a ``data:``
  URI, a file or a bufferView;
- node transforms (:func:`node_matrix`): ``matrix`` (column-major) or
  translation · rotation · scale, as (4, 4) float64 column-vector matrices,
  and the node hierarchy with world matrices (:meth:`GltfFile.walk`).

Every problem raises `softras.scene.fileio.BadFile` whose one line starts
with the glTF place, ``meshes[0].primitives[1]: index 9 out of range for 8
vertices``; the readers add the file (and the scene place).
"""

from __future__ import annotations

import base64
import json
import math
import os
import struct
import urllib.parse
from typing import NamedTuple

import numpy as np

from softras.scene.fileio import BadFile, number_problem, read_bytes
from softras.scene.model import MAX_NODE_DEPTH

COMPONENTS = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES",
         5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942


class Primitive(NamedTuple):
    """One glTF primitive's vertex arrays, model space (see the module docstring)."""
    positions: np.ndarray          # (N, 3) float64
    indices: np.ndarray            # (M, 3) int64
    colors: np.ndarray | None      # (N, 4) float64 straight RGBA in [0, 1] (unchecked)
    normals: np.ndarray | None     # (N, 3) float64
    uvs: np.ndarray | None         # (N, 2) float64, v = 0 at the image top


def glb_chunks(raw: bytes) -> tuple[bytes, bytes | None]:
    """A .glb file's (JSON chunk, BIN chunk or None)."""
    if len(raw) < 12 or raw[:4] != b"glTF":
        raise BadFile("not a GLB file (no 'glTF' magic)")
    version, length = struct.unpack_from("<II", raw, 4)
    if version != 2:
        raise BadFile(f"GLB version {version} (only version 2 is read)")
    if length > len(raw):
        raise BadFile(f"truncated: the GLB header says {length} bytes, the file has {len(raw)}")
    chunks, offset = [], 12
    while offset < length:
        if offset + 8 > length:
            raise BadFile("truncated: a GLB chunk header is cut off")
        size, kind = struct.unpack_from("<II", raw, offset)
        if offset + 8 + size > length:
            raise BadFile(f"truncated: a GLB chunk of {size} bytes at byte {offset} runs past the end ({length} bytes)")
        chunks.append((kind, raw[offset + 8:offset + 8 + size]))
        offset += 8 + size
    if not chunks or chunks[0][0] != _JSON_CHUNK:
        raise BadFile("the first GLB chunk is not JSON")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN_CHUNK else None
    return chunks[0][1], binary


def _is_index(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


class GltfFile:
    """A glTF file opened: ``document`` (the JSON, a dict), its buffers on demand."""

    def __init__(self, path: str):
        raw = read_bytes(path)
        self.binary = None
        if path.lower().endswith(".glb"):
            text, self.binary = glb_chunks(raw)
        else:
            text = raw
        try:
            document = json.loads(text.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as error:
            raise BadFile(f"invalid glTF JSON: {' '.join(str(error).split())}") from None
        if not isinstance(document, dict):
            raise BadFile("invalid glTF JSON: the top level is not an object")
        self.document, self.folder = document, os.path.dirname(path)
        self.buffers: dict[int, bytes] = {}

    # ----------------------------------------------------------------- tables

    def item(self, table: str, index, where: str) -> dict:
        """``document[table][index]``, an object; ``where``: the place referring to it."""
        items = self.document.get(table, [])
        if not isinstance(items, list) or not _is_index(index) or not 0 <= index < len(items):
            count = len(items) if isinstance(items, list) else 0
            raise BadFile(f"{where}: {table} index {index!r} out of range ({count} {table})")
        if not isinstance(items[index], dict):
            raise BadFile(f"{table}[{index}]: expected an object")
        return items[index]

    def _uri_bytes(self, uri, where: str) -> bytes:
        if not isinstance(uri, str):
            raise BadFile(f"{where}.uri: expected a string")
        if uri.startswith("data:"):
            try:
                return base64.b64decode(uri.split(",", 1)[1], validate=True)
            except (IndexError, ValueError):
                raise BadFile(f"{where}: malformed base64 data uri") from None
        file = os.path.join(self.folder, urllib.parse.unquote(uri))
        if not os.path.isfile(file):
            raise BadFile(f"{where}: no such file {uri!r}")
        return read_bytes(file)

    def buffer(self, index: int, where: str) -> bytes:
        if index not in self.buffers:
            entry = self.item("buffers", index, where)
            if entry.get("uri") is None:
                if self.binary is None or index != 0:
                    raise BadFile(f"buffers[{index}] has no uri and there is no GLB binary chunk")
                data = self.binary
            else:
                data = self._uri_bytes(entry["uri"], f"buffers[{index}]")
            declared = entry["byteLength"]
            if not _is_index(declared) or declared < 0:
                raise BadFile(f"buffers[{index}].byteLength: expected a count, got {declared!r}")
            if declared > len(data):
                raise BadFile(f"truncated: buffers[{index}] has {len(data)} bytes, its byteLength says {declared}")
            self.buffers[index] = data
        return self.buffers[index]

    def view(self, index: int, where: str) -> tuple[bytes, int, int, dict]:
        """(buffer bytes, offset, length, the bufferView) of bufferViews[index], checked."""
        view = self.item("bufferViews", index, where)
        data = self.buffer(view["buffer"], f"bufferViews[{index}]")
        offset, length = int(view.get("byteOffset", 0)), int(view["byteLength"])
        if offset < 0 or length < 0 or offset + length > len(data):
            raise BadFile(f"truncated: bufferViews[{index}] (bytes {offset} to {offset + length}) runs past "
                          f"the end of its buffer ({len(data)} bytes)")
        return data, offset, length, view

    # ----------------------------------------------------------------- accessors

    def accessor_count(self, index: int, where: str) -> int:
        count = self.item("accessors", index, where)["count"]
        if not _is_index(count) or count < 0:
            raise BadFile(f"accessors[{index}].count: expected a count, got {count!r}")
        return count

    def accessor(self, index: int, where: str) -> tuple[np.ndarray, np.dtype, bool]:
        """(count, components) array as stored, its component type, normalized?"""
        where = f"{where}: accessors[{index}]"
        accessor = self.item("accessors", index, where)
        if "sparse" in accessor:
            raise BadFile(f"{where}: sparse accessors are not supported")
        component = COMPONENTS.get(accessor["componentType"])
        width = TYPES.get(accessor["type"])
        if component is None or width is None:
            raise BadFile(f"{where}: unsupported componentType {accessor['componentType']!r} "
                          f"or type {accessor['type']!r}")
        count = self.accessor_count(index, where)
        dtype = np.dtype(component).newbyteorder("<")
        if "bufferView" not in accessor:
            return np.zeros((count, width), dtype), dtype, bool(accessor.get("normalized", False))
        data, view_offset, view_length, view = self.view(accessor["bufferView"], where)
        element = width * dtype.itemsize
        stride = int(view.get("byteStride", element))
        offset = int(accessor.get("byteOffset", 0))
        if stride < element or offset < 0:
            raise BadFile(f"{where}: byteStride {stride} is smaller than an element ({element} bytes)")
        if count and offset + stride * (count - 1) + element > view_length:
            raise BadFile(f"truncated: {where} needs {offset + stride * (count - 1) + element} bytes, its "
                          f"bufferView has {view_length}")
        array = np.ndarray((count, width), dtype, buffer=data, offset=view_offset + offset,
                           strides=(stride, dtype.itemsize))
        return array.copy(), dtype, bool(accessor.get("normalized", False))

    def floats(self, index: int, where: str, widths: tuple[int, ...], what: str) -> np.ndarray:
        """A float attribute (float32, or normalized unsigned integers / their maximum) as float64."""
        array, dtype, normalized = self.accessor(index, where)
        if array.shape[1] not in widths:
            raise BadFile(f"{where}: {what} has {array.shape[1]} components, expected {' or '.join(map(str, widths))}")
        if dtype.kind == "f":
            return array.astype(np.float64)
        if normalized and dtype.kind == "u":
            return array / float(np.iinfo(dtype).max)
        raise BadFile(f"{where}: {what} of type {dtype.name}{' (normalized)' if normalized else ''} is not "
                      f"supported (floats, or normalized unsigned integers)")

    # ----------------------------------------------------------------- meshes

    def primitive_entry(self, m: int, p: int, where: str) -> dict:
        """meshes[m].primitives[p], checked to be triangles with a POSITION."""
        mesh = self.item("meshes", m, where)
        primitives = mesh.get("primitives", [])
        if not isinstance(primitives, list) or not 0 <= p < len(primitives) or not isinstance(primitives[p], dict):
            raise BadFile(f"meshes[{m}].primitives[{p}]: missing or not an object")
        primitive = primitives[p]
        place = f"meshes[{m}].primitives[{p}]"
        mode = primitive.get("mode", 4)
        if mode != 4:
            raise BadFile(f"{place}: mode {mode} ({MODES.get(mode, 'unknown')}) is not supported (only TRIANGLES)")
        if not isinstance(primitive.get("attributes"), dict) or "POSITION" not in primitive["attributes"]:
            raise BadFile(f"{place}: no POSITION attribute")
        return primitive

    def primitive_counts(self, m: int, p: int) -> tuple[int, int]:
        """(vertices, triangles) of a primitive from its accessors' counts, before any data is read."""
        where = f"meshes[{m}].primitives[{p}]"
        primitive = self.primitive_entry(m, p, where)
        vertices = self.accessor_count(primitive["attributes"]["POSITION"], where)
        indexed = self.accessor_count(primitive["indices"], where) if "indices" in primitive else vertices
        return vertices, indexed // 3

    def primitive(self, m: int, p: int) -> Primitive:
        """The arrays of meshes[m].primitives[p] in model space (see the module docstring)."""
        where = f"meshes[{m}].primitives[{p}]"
        primitive = self.primitive_entry(m, p, where)
        attributes = primitive["attributes"]
        positions = self.floats(attributes["POSITION"], where, (3,), "POSITION")
        if "indices" in primitive:
            array, dtype, _ = self.accessor(primitive["indices"], where)
            if dtype.kind != "u" or array.shape[1] != 1:
                raise BadFile(f"{where}: indices must be unsigned integer scalars, got {array.shape[1]} x {dtype.name}")
            flat = array.reshape(-1).astype(np.int64)
        else:
            flat = np.arange(len(positions), dtype=np.int64)
        if len(flat) % 3:
            raise BadFile(f"{where}: {len(flat)} indices, not a multiple of 3")
        bad = flat >= len(positions)
        if bad.any():
            raise BadFile(f"{where}: index {int(flat[np.argmax(bad)])} out of range for {len(positions)} vertices")
        normals = self.floats(attributes["NORMAL"], where, (3,), "NORMAL") if "NORMAL" in attributes else None
        uvs = self.floats(attributes["TEXCOORD_0"], where, (2,), "TEXCOORD_0") if "TEXCOORD_0" in attributes else None
        colors = None
        if "COLOR_0" in attributes:
            channels = self.floats(attributes["COLOR_0"], where, (3, 4), "COLOR_0")
            colors = np.ones((len(channels), 4))
            colors[:, :channels.shape[1]] = channels
        for name, array in (("NORMAL", normals), ("TEXCOORD_0", uvs), ("COLOR_0", colors)):
            if array is not None and len(array) != len(positions):
                raise BadFile(f"{where}: {name} has {len(array)} entries for {len(positions)} positions")
        return Primitive(positions, flat.reshape(-1, 3), colors, normals, uvs)

    def primitive_tangents(self, m: int, p: int) -> np.ndarray | None:
        """TANGENT of meshes[m].primitives[p]: (N, 4) float64, xyz and the
        handedness w, as the file gives them (glTF: the bitangent
        ``w cross(N, T)`` points up the image); None without the attribute."""
        where = f"meshes[{m}].primitives[{p}]"
        attributes = self.primitive_entry(m, p, where)["attributes"]
        if "TANGENT" not in attributes:
            return None
        tangents = self.floats(attributes["TANGENT"], where, (4,), "TANGENT")
        count = self.accessor_count(attributes["POSITION"], where)
        if len(tangents) != count:
            raise BadFile(f"{where}: TANGENT has {len(tangents)} entries for {count} positions")
        bad = ~np.isfinite(tangents).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise BadFile(f"{where}: TANGENT of vertex {i} is not finite")
        return tangents

    # ----------------------------------------------------------------- nodes

    def walk(self, roots, where: str) -> list[tuple[int, np.ndarray]]:
        """(node index, world matrix (4, 4)) of the nodes under ``roots``
        (node indices; ``where``: the place listing them), depth-first,
        parents before children, in list order.  Refused: a node reached twice
        (glTF's nodes form a forest), nesting deeper than MAX_NODE_DEPTH, a
        world matrix that overflows, skins and morph target weights (drawn
        without them the picture would be wrong)."""
        found, seen = [], set()

        def visit(index, parent, depth, place):
            if depth > MAX_NODE_DEPTH:
                raise BadFile(f"{place}: nodes nested more than {MAX_NODE_DEPTH} deep")
            node = self.item("nodes", index, place)
            if index in seen:
                raise BadFile(f"{place}: nodes[{index}] is reached twice (the node hierarchy must be a forest)")
            seen.add(index)
            for key, what in (("skin", "skins"), ("weights", "morph target weights")):
                if key in node:
                    raise BadFile(f"nodes[{index}].{key}: {what} are not supported")
            with np.errstate(over="ignore", invalid="ignore"):
                world = parent @ node_matrix(node, f"nodes[{index}]")
            if not np.isfinite(world).all():
                raise BadFile(f"nodes[{index}]: the world matrix overflows")
            found.append((index, world))
            children = node.get("children", [])
            if not isinstance(children, list):
                raise BadFile(f"nodes[{index}].children: expected a list of node indices")
            for child in children:
                visit(child, world, depth + 1, f"nodes[{index}].children")

        if not isinstance(roots, list):
            raise BadFile(f"{where}: expected a list of node indices")
        for root in roots:
            visit(root, np.identity(4), 0, where)
        return found

    # ----------------------------------------------------------------- images

    def image_bytes(self, index: int, where: str) -> bytes:
        """The encoded bytes of images[index]: its ``uri`` (data: or a file) or its ``bufferView``."""
        image = self.item("images", index, where)
        place = f"images[{index}]"
        if "uri" in image:
            if "bufferView" in image:
                raise BadFile(f"{place}: has both uri and bufferView")
            return self._uri_bytes(image["uri"], place)
        if "bufferView" not in image:
            raise BadFile(f"{place}: has neither uri nor bufferView")
        data, offset, length, _ = self.view(image["bufferView"], place)
        return bytes(data[offset:offset + length])


def node_matrix(node: dict, where: str = "a node") -> np.ndarray:
    """A glTF node's local matrix (4, 4) float64: ``matrix`` (16 numbers,
    column-major) or T · R · S (translation, unit quaternion rotation
    (x, y, z, w), scale; each optional)."""
    if "matrix" in node:
        matrix = numbers(node["matrix"], 16, f"{where}.matrix")
        return matrix.reshape(4, 4).T
    x, y, z, w = numbers(node.get("rotation", (0, 0, 0, 1)), 4, f"{where}.rotation")
    rotation = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    local = np.identity(4)
    local[:3, :3] = rotation * numbers(node.get("scale", (1, 1, 1)), 3, f"{where}.scale")
    local[:3, 3] = numbers(node.get("translation", (0, 0, 0)), 3, f"{where}.translation")
    return local


def number(value, where: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    """A finite JSON number in [lo, hi] (not a boolean): the scene format's
    check (`softras.scene.fileio.number_problem`)."""
    problem = number_problem(value, lo, hi)
    if problem is not None:
        raise BadFile(f"{where}: {problem}")
    return float(value)


def numbers(value, count: int, where: str, lo: float = -math.inf, hi: float = math.inf) -> np.ndarray:
    """``count`` finite JSON numbers in [lo, hi] -> (count,) float64."""
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise BadFile(f"{where}: expected {count} numbers")
    return np.array([number(v, f"{where}[{i}]", lo, hi) for i, v in enumerate(value)])
