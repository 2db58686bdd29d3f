"""Mesh files: a scene mesh read from a PLY, OBJ, NPZ or glTF (.gltf / .glb) file.

A node may say ``"mesh": {"file": "bunny.ply"}`` instead of inline arrays
(docs/scene_format.md, "Mesh files"); :func:`read_mesh_file` reads the file
into the same :class:`softras.scene.model.Mesh` record an inline mesh gives
(triangles; positions, indices, and the normals, uvs and vertex colours the
file has), so both renderers draw it as they draw any mesh.

Conventions (the same picture whatever the format):

- **uvs**: the scene format has t = 0 at the TOP row of the image. OBJ and PLY
  put v = 0 at the bottom, so their uvs become (u, 1 − v); glTF already has
  v = 0 at the top and NPZ holds the scene's own arrays, so theirs are kept.
- **Vertex colours** become straight RGBA float64 in [0, 1]: unsigned
  integer colours are divided by their type's maximum (uint8 / 255,
  uint16 / 65535), float colours are kept and must lie in [0, 1]; RGB gets
  alpha 1.
- **Polygons** (OBJ faces, PLY faces with more than three corners) are split
  into a fan from their first corner, (c0, c1, c2), (c0, c2, c3), ...: right
  for the convex polygons exporters write.
- **glTF**: only the meshes' triangle primitives are read; materials,
  textures, cameras, lights, skins and animations are ignored. The
  primitives of the default scene (``scene``, else ``scenes[0]``) are
  concatenated, each transformed by its node's world matrix (normals by its
  inverse transpose; a mirroring matrix reverses the winding so front faces
  stay front faces); a file with no scenes gives every mesh once,
  untransformed.

Every problem is a :class:`SceneError` whose one line names the scene place
and the file, ``nodes[0].mesh.file: bunny.ply: truncated: ...``. Sizes are
checked from headers (PLY element counts, glTF accessor counts, NPZ array
headers) against the scene's triangle budget and :data:`MAX_VERTICES` before
the arrays are read; binary data is read with ``numpy.frombuffer`` (a
1M-triangle binary PLY loads in a few tens of milliseconds), never through
Python lists.

Why readers of our own, not trimesh: trimesh 5.2 keeps either a texture or
vertex colours, never both (a PLY with uvs and colours loses its colours);
with ``maintain_order=True`` its OBJ loader does not split vertices whose
face corners use different uvs (the uvs come out wrong), without it the
vertices are reordered; it stores colours as uint8 (float colours lose
precision) and flips glTF uvs on its own; its errors are whatever exception
its internals raise; and its import alone takes longer than loading a
1M-triangle PLY here. These formats' geometry is small enough to read
exactly, with the conventions above stated and tested
(tests/test_mesh_files.py).

Why one module of ~700 lines: one reader per format, all sharing the checks,
the polygon fan and the error form; each reader is a section below (the
glTF container itself is `softras.scene.gltf_files`, shared with the glTF
scene reader `softras.scene.gltf`).
"""

from __future__ import annotations

import math
import os
import struct
import zipfile
import zlib

import numpy as np

from softras.scene import gltf_files
from softras.scene.fileio import MAX_VERTICES  # noqa: F401  (the limit, documented here)
from softras.scene.fileio import BadFile as _Bad
from softras.scene.fileio import check_counts as _check_counts
from softras.scene.fileio import read_bytes as _read_bytes
from softras.scene.meshes import MeshArrays
from softras.scene.model import Mesh, SceneError, _readonly

SUFFIXES = (".ply", ".obj", ".npz", ".glb", ".gltf")




def read_mesh_file(path: str, name: str, place: str, max_triangles: int) -> Mesh:
    """The triangle mesh in the file at ``path`` (``name`` as the scene wrote
    it, for messages; ``place`` the scene place of the ``file`` key), with at
    most ``max_triangles`` triangles.  Raises SceneError (one line)."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in _READERS:
        raise SceneError(place, f"{name}: unsupported mesh file type {suffix or '(none)'!r} "
                                f"(supported: {', '.join(SUFFIXES)})")
    if not os.path.exists(path):
        raise SceneError(place, f"{name}: no such file ({path})")
    if os.path.isdir(path):
        raise SceneError(place, f"{name}: is a folder, not a mesh file")
    try:
        arrays = _READERS[suffix](path, max_triangles)
        return checked_mesh(arrays, max_triangles)
    except _Bad as error:
        raise SceneError(place, f"{name}: {error}") from None
    except PermissionError:
        raise SceneError(place, f"{name}: permission denied") from None
    except OSError as error:
        raise SceneError(place, f"{name}: {error.strerror or error}") from None
    except MemoryError:
        raise SceneError(place, f"{name}: too large to read into memory") from None


# --------------------------------------------------------------------------- shared checks


def checked_mesh(arrays: MeshArrays, max_triangles: int) -> Mesh:
    """The mesh with every value checked: finite numbers, colours in [0, 1],
    indices in range, at least one triangle."""
    positions, indices, colors, normals, uvs = arrays
    count = len(positions)
    if count == 0:
        raise _Bad("no vertices")
    if len(indices) == 0:
        raise _Bad("no triangles")
    _check_counts(count, len(indices), max_triangles)
    for what, array in (("position", positions), ("normal", normals), ("uv", uvs), ("colour", colors)):
        if array is None:
            continue
        assert len(array) == count, (what, array.shape, count)
        bad = ~np.isfinite(array).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise _Bad(f"vertex {i} has a non-finite {what} {_numbers(array[i])}")
    if colors is not None:
        bad = ((colors < 0) | (colors > 1)).any(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise _Bad(f"vertex {i} has colour {_numbers(colors[i])} outside [0, 1]")
    bad = ((indices < 0) | (indices >= count)).any(axis=1)
    if bad.any():
        t = int(np.flatnonzero(bad)[0])
        index = next(int(i) for i in indices[t] if not 0 <= i < count)
        raise _Bad(f"triangle {t} has vertex index {index}, out of range for {count} vertices")
    return Mesh("triangles", *(_readonly(np.ascontiguousarray(a, dtype=t)) if a is not None else None
                               for a, t in ((positions, np.float64), (indices, np.int64), (colors, np.float64),
                                            (normals, np.float64), (uvs, np.float64))))


def _numbers(row) -> str:
    return "(" + ", ".join(f"{float(x):g}" for x in row) + ")"


def _flip_v(uvs: np.ndarray | None) -> np.ndarray | None:
    """(u, v) with v = 0 at the image bottom (OBJ, PLY) -> the scene's (s, t), t = 0 at the top."""
    if uvs is None:
        return None
    out = np.array(uvs, dtype=np.float64)
    out[:, 1] = 1.0 - out[:, 1]
    return out


def _rgba(channels: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(N, 3 or 4) colour channels stored as ``dtype`` -> (N, 4) float64 in [0, 1] (unchecked)."""
    dtype = np.dtype(dtype)
    out = np.ones((len(channels), 4))
    if dtype.kind == "u":
        out[:, :channels.shape[1]] = channels / float(np.iinfo(dtype).max)
    elif dtype.kind == "f":
        out[:, :channels.shape[1]] = channels
    else:
        raise _Bad(f"vertex colours of type {dtype.name} (expected unsigned integers or floats)")
    return out


def _fan(counts: np.ndarray, flat: np.ndarray, max_triangles: int) -> np.ndarray:
    """Polygons given as corner counts and their concatenated corners -> (M, 3)
    triangles, each polygon a fan from its first corner."""
    counts = np.asarray(counts, dtype=np.int64)
    flat = np.asarray(flat)
    if len(counts) and (counts == 3).all():
        return flat.reshape(-1, 3)
    if len(counts) and counts.min() < 3:
        f = int(np.flatnonzero(counts < 3)[0])
        raise _Bad(f"face {f} has {int(counts[f])} corners (a face needs at least 3)")
    per_face = counts - 2
    total = int(per_face.sum())
    _check_counts(0, total, max_triangles, "its polygons make ")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    face = np.repeat(np.arange(len(counts)), per_face)
    j = np.arange(total) - np.repeat(np.cumsum(per_face) - per_face, per_face) + 1
    base = starts[face]
    return np.stack([flat[base], flat[base + j], flat[base + j + 1]], axis=1)


# --------------------------------------------------------------------------- PLY


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")


def _ply_type(name: str, line: int) -> str:
    if name not in _PLY_TYPES:
        raise _Bad(f"header line {line}: unknown property type {name!r}")
    return _PLY_TYPES[name]


def _ply_header(file) -> tuple[str, list, int]:
    """(format, elements, size of the header in bytes); an element is
    [name, count, [(property, type code, list count type code or None), ...]]."""
    head = b""
    while b"end_header" not in head:
        chunk = file.read(65536)
        if not chunk or len(head) > 1 << 20:
            raise _Bad("not a PLY file (no end_header line)" if head.startswith(b"ply") else "not a PLY file")
        head += chunk
    end = head.index(b"end_header") + len(b"end_header")
    newline = head.find(b"\n", end)
    if newline < 0 or head[end:newline].strip():
        raise _Bad("truncated or malformed end_header line")
    try:
        lines = head[:end].decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise _Bad("the PLY header is not ASCII text") from None
    if not lines or lines[0].strip() != "ply":
        raise _Bad("not a PLY file (it does not start with 'ply')")
    fmt = None
    elements: list = []
    for number, line in enumerate(lines[1:], 2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info", "end_header"):
            continue
        if words[0] == "format" and len(words) == 3:
            if words[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise _Bad(f"header line {number}: unknown format {words[1]!r}")
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            if not words[2].isdigit():
                raise _Bad(f"header line {number}: element count {words[2]!r} is not a whole number")
            elements.append([words[1], int(words[2]), []])
        elif words[0] == "property" and elements:
            if len(words) == 5 and words[1] == "list":
                prop = (words[4], _ply_type(words[3], number), _ply_type(words[2], number))
                if prop[2][0] == "f":
                    raise _Bad(f"header line {number}: a list count must be an integer type, got {words[2]}")
            elif len(words) == 3:
                prop = (words[2], _ply_type(words[1], number), None)
            else:
                raise _Bad(f"header line {number}: malformed property line {line.strip()!r}")
            if any(p[0] == prop[0] for p in elements[-1][2]):
                raise _Bad(f"header line {number}: property {prop[0]!r} given twice")
            elements[-1][2].append(prop)
        else:
            raise _Bad(f"header line {number}: cannot read {line.strip()!r}")
    if fmt is None:
        raise _Bad("the PLY header has no format line")
    return fmt, elements, newline + 1


def _read_ply(path: str, max_triangles: int) -> MeshArrays:
    with open(path, "rb") as file:
        fmt, elements, header_size = _ply_header(file)
        by_name = {element[0]: element for element in elements}
        if "vertex" not in by_name:
            raise _Bad("no vertex element")
        if "face" not in by_name:
            raise _Bad("no face element (no triangles)")
        _check_counts(by_name["vertex"][1], by_name["face"][1], max_triangles)
        size = os.fstat(file.fileno()).st_size
        if fmt != "ascii":
            # The smallest possible body must fit in the file before anything is read.
            least = sum(count * sum(np.dtype(p[2] or p[1]).itemsize for p in props)
                        for _, count, props in elements)
            if header_size + least > size:
                raise _Bad(f"truncated: the header promises at least {least} bytes of data, "
                           f"the file has {size - header_size}")
        file.seek(header_size)
        body = file.read()
    if fmt == "ascii":
        data = _ply_ascii(body, elements)
    else:
        data = _ply_binary(body, elements, "<" if fmt == "binary_little_endian" else ">")
    return _ply_mesh(data, by_name, max_triangles)


def _ply_binary(body: bytes, elements: list, endian: str) -> dict:
    """element name -> {property: array (scalars) or (counts, flat items) (lists)}."""
    out = {}
    offset = 0
    for name, count, props in elements:
        truncated = _Bad(f"truncated: the data ends inside element {name!r} "
                         f"({count} records from byte {offset} of {len(body)})")
        fields = []
        lists = {}
        position = offset
        for prop, code, count_code in props:        # the first record fixes the list lengths
            if count_code is None:
                fields.append((prop, endian + code))
                position += np.dtype(code).itemsize
                continue
            length = 0
            if count:
                if position + np.dtype(count_code).itemsize > len(body):
                    raise truncated
                length = int(np.frombuffer(body, endian + count_code, 1, position)[0])
                if length < 0:
                    raise _Bad(f"element {name!r}: negative list length {length}")
            fields.append((f"{prop} count", endian + count_code))
            fields.append((prop, endian + code, (length,)))
            lists[prop] = length
            position += np.dtype(count_code).itemsize + length * np.dtype(code).itemsize
        dtype = np.dtype(fields)
        if offset + count * dtype.itemsize <= len(body):
            records = np.frombuffer(body, dtype, count, offset)
            if all((records[f"{p} count"] == n).all() for p, n in lists.items()):
                out[name] = {p: (records[p] if p not in lists else
                                 (np.full(count, lists[p]), records[p].reshape(-1)))
                             for p, _, _ in props}
                offset += count * dtype.itemsize
                continue
        elif not lists:
            raise truncated
        out[name], offset = _ply_binary_slow(body, offset, count, props, endian, truncated)
    return out


def _ply_binary_slow(body, offset, count, props, endian, truncated):
    """Records whose lists differ in length: one record at a time."""
    values = {p: [] for p, _, _ in props}
    counts = {p: [] for p, _, c in props if c is not None}
    formats = {code: struct.Struct(endian + np.dtype(code).char) for _, code, c in props for code in (code, c)
               if code is not None}
    for _ in range(count):
        for prop, code, count_code in props:
            unit = formats[count_code or code]
            if offset + unit.size > len(body):
                raise truncated
            value = unit.unpack_from(body, offset)[0]
            offset += unit.size
            if count_code is None:
                values[prop].append(value)
                continue
            item = np.dtype(code).itemsize
            if value < 0 or offset + value * item > len(body):
                raise truncated
            counts[prop].append(value)
            values[prop].append(np.frombuffer(body, endian + code, value, offset))
            offset += value * item
    out = {}
    for prop, code, count_code in props:
        if count_code is None:
            out[prop] = np.array(values[prop], dtype=code)
        else:
            flat = np.concatenate(values[prop]) if values[prop] else np.zeros(0, code)
            out[prop] = (np.array(counts[prop], dtype=np.int64), flat)
    return out, offset


def _ply_ascii(body: bytes, elements: list) -> dict:
    try:
        tokens = body.decode("ascii").split()
    except UnicodeDecodeError as error:
        raise _Bad(f"the ASCII PLY data is not ASCII text (byte {error.start})") from None
    try:
        values = np.array(tokens, dtype=np.float64)
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise _Bad(f"{bad[:20]!r} in the ASCII data is not a number") from None
    out = {}
    p = 0
    for name, count, props in elements:
        def truncated():
            return _Bad(f"truncated: the ASCII data ends inside element {name!r}")
        # The first record fixes the list lengths and the record length.
        layout, q = [], p
        for prop, code, count_code in props:
            if count_code is None:
                layout.append((prop, q - p, None))
                q += 1
            else:
                if count and q >= len(values):
                    raise truncated()
                length = int(values[q]) if count else 0
                layout.append((prop, q - p, length))
                q += 1 + length
        width = q - p
        if p + count * width <= len(values):
            block = values[p:p + count * width].reshape(count, width)
            if all(length is None or (block[:, at] == length).all() for _, at, length in layout):
                out[name] = {prop: block[:, at] if length is None else
                             (np.full(count, length), block[:, at + 1:at + 1 + length].reshape(-1))
                             for prop, at, length in layout}
                p += count * width
                continue
        out[name] = data = {}
        scalars = {prop: [] for prop, _, c in props if c is None}
        lists = {prop: ([], []) for prop, _, c in props if c is not None}
        for _ in range(count):                    # lists of different lengths: one record at a time
            for prop, code, count_code in props:
                if p >= len(values):
                    raise truncated()
                if count_code is None:
                    scalars[prop].append(values[p])
                    p += 1
                else:
                    length = int(values[p])
                    if length < 0 or p + 1 + length > len(values):
                        raise truncated()
                    lists[prop][0].append(length)
                    lists[prop][1].append(values[p + 1:p + 1 + length])
                    p += 1 + length
        data.update({prop: np.array(v) for prop, v in scalars.items()})
        data.update({prop: (np.array(c, dtype=np.int64), np.concatenate(v) if v else np.zeros(0))
                     for prop, (c, v) in lists.items()})
    return out


def _is_float(token: str) -> bool:
    try:
        float(token)
        return True
    except ValueError:
        return False


def _ply_mesh(data: dict, by_name: dict, max_triangles: int) -> MeshArrays:
    vertex = data["vertex"]
    types = {prop: code for prop, code, _ in by_name["vertex"][2]}

    def columns(names, what):
        present = [n for n in names if n in vertex]
        if not present:
            return None
        if len(present) != len(names):
            raise _Bad(f"the vertex element has {', '.join(present)} but not "
                       f"{', '.join(n for n in names if n not in vertex)} ({what})")
        if any(isinstance(vertex[n], tuple) for n in names):
            raise _Bad(f"vertex property {names[0]!r} is a list, expected a number")
        return np.stack([vertex[n] for n in names], axis=1)

    positions = columns(("x", "y", "z"), "positions")
    if positions is None:
        raise _Bad("the vertex element has no x, y, z properties")
    normals = columns(("nx", "ny", "nz"), "normals")
    uvs = next((columns(pair, "uvs") for pair in _PLY_UV_NAMES if pair[0] in vertex or pair[1] in vertex), None)
    colors = columns(("red", "green", "blue", "alpha") if "alpha" in vertex else ("red", "green", "blue"), "colours")
    if colors is not None:
        kinds = {types[n] for n in ("red", "green", "blue", "alpha") if n in types}
        if len(kinds) != 1:
            raise _Bad(f"the colour properties have different types ({', '.join(sorted(kinds))})")
        colors = _rgba(colors.astype(np.float64), kinds.pop())

    face = data["face"]
    key = next((k for k in _PLY_FACE_LISTS if k in face), None)
    if key is None or not isinstance(face[key], tuple):
        raise _Bad("the face element has no vertex_indices list")
    counts, flat = face[key]
    code = next(c for p, c, _ in by_name["face"][2] if p == key)
    if code[0] == "f" or (flat.dtype.kind == "f" and (flat != np.round(flat)).any()):
        raise _Bad("face vertex indices must be integers")
    indices = _fan(counts, flat.astype(np.int64), max_triangles)
    return MeshArrays(positions.astype(np.float64), indices, colors,
                      None if normals is None else normals.astype(np.float64), _flip_v(uvs))


# --------------------------------------------------------------------------- OBJ


_OBJ_IGNORED = ("o", "g", "s", "usemtl", "mtllib", "vp")


def _read_obj(path: str, max_triangles: int) -> MeshArrays:
    try:
        text = _read_bytes(path).decode("utf-8")
    except UnicodeDecodeError as error:
        raise _Bad(f"not UTF-8 text (byte {error.start})") from None
    v, vt, vn = [], [], []
    counts, corners = [], []
    colored = None
    triangles = 0
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        key, args = words[0], words[1:]
        try:
            if key == "v":
                if len(args) not in (3, 6):
                    raise _Bad(f"line {number}: 'v' with {len(args)} numbers "
                               f"(expected x y z, or x y z r g b)")
                if colored is None:
                    colored = len(args) == 6
                elif colored != (len(args) == 6):
                    raise _Bad(f"line {number}: vertex colours on some vertices only")
                v.append([float(a) for a in args])
            elif key == "vt":
                if not 1 <= len(args) <= 3:
                    raise _Bad(f"line {number}: 'vt' with {len(args)} numbers (expected u [v [w]])")
                vt.append([float(args[0]), float(args[1]) if len(args) > 1 else 0.0])
            elif key == "vn":
                if len(args) != 3:
                    raise _Bad(f"line {number}: 'vn' with {len(args)} numbers (expected 3)")
                vn.append([float(a) for a in args])
            elif key == "f":
                if len(args) < 3:
                    raise _Bad(f"line {number}: a face needs at least 3 corners, got {len(args)}")
                counts.append(len(args))
                for corner in args:
                    corners.append(_obj_corner(corner, (len(v), len(vt), len(vn)), number))
                triangles += len(args) - 2
                if triangles > max_triangles:
                    _check_counts(0, triangles, max_triangles, "its faces make at least ")
            elif key in ("l", "p"):
                raise _Bad(f"line {number}: {'lines' if key == 'l' else 'points'} ('{key}') are not "
                           f"supported (a mesh file gives triangles)")
            elif key not in _OBJ_IGNORED:
                raise _Bad(f"line {number}: unsupported statement {key[:20]!r}")
        except ValueError:
            raise _Bad(f"line {number}: expected numbers, got {' '.join(args)[:40]!r}") from None
    if not counts:
        raise _Bad("no faces (no triangles)")
    _check_counts(len(v), 0, max_triangles)
    corners = np.array(corners, dtype=np.int64)
    for column, what in ((1, "texture coordinates (vt)"), (2, "normals (vn)")):
        has = corners[:, column] >= 0
        if has.any() and not has.all():
            raise _Bad(f"some face corners have {what} and others do not")
    positions = np.array(v, dtype=np.float64).reshape(-1, 6 if colored else 3)
    colors = _rgba(positions[:, 3:], np.float64) if colored else None
    positions = positions[:, :3]
    if (corners[:, 1:] < 0).all():
        # Only position indices: the file's vertices, in the file's order.
        return MeshArrays(positions, _fan(counts, corners[:, 0], max_triangles), colors, None, None)
    # One vertex per distinct (v, vt, vn) corner, in order of first appearance.
    keys, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    keys = keys[order]
    _check_counts(len(keys), 0, max_triangles)
    uvs = np.array(vt, dtype=np.float64).reshape(-1, 2)[keys[:, 1]] if keys[0, 1] >= 0 else None
    normals = np.array(vn, dtype=np.float64).reshape(-1, 3)[keys[:, 2]] if keys[0, 2] >= 0 else None
    return MeshArrays(positions[keys[:, 0]], _fan(counts, rank[inverse.reshape(-1)], max_triangles),
                      None if colors is None else colors[keys[:, 0]], normals, _flip_v(uvs))


def _obj_corner(corner: str, sizes: tuple[int, int, int], number: int) -> tuple[int, int, int]:
    """'v', 'v/vt', 'v//vn' or 'v/vt/vn' (1-based, or negative: from the end so far) -> 0-based, -1 = none."""
    parts = corner.split("/")
    if len(parts) > 3 or not parts[0]:
        raise _Bad(f"line {number}: cannot read face corner {corner[:20]!r}")
    out = []
    for part, size, what in zip(parts + [""] * (3 - len(parts)), sizes, ("v", "vt", "vn")):
        if not part:
            out.append(-1)
            continue
        index = int(part)
        resolved = index - 1 if index > 0 else size + index
        if index == 0 or not 0 <= resolved < size:
            raise _Bad(f"line {number}: {what} index {index} out of range ({size} {what} so far)")
        out.append(resolved)
    return tuple(out)


# --------------------------------------------------------------------------- NPZ


_NPZ_ARRAYS = ("positions", "indices", "normals", "uvs", "colors")


def _npz_header(archive: zipfile.ZipFile, member: str):
    with archive.open(member) as file:
        version = np.lib.format.read_magic(file)
        if version == (1, 0):
            return np.lib.format.read_array_header_1_0(file)
        if version == (2, 0):
            return np.lib.format.read_array_header_2_0(file)
        raise _Bad(f"array {member!r}: unsupported .npy version {version}")


def _read_npz(path: str, max_triangles: int) -> MeshArrays:
    """The scene's own arrays in a file: positions (N, 3), indices (M, 3) or
    flat (3M,) (optional: sequential), normals (N, 3), uvs (N, 2) with t = 0
    at the image top, colors (N, 3 or 4) float in [0, 1] or unsigned integers."""
    try:
        with zipfile.ZipFile(path) as archive:
            members = {m[:-4] if m.endswith(".npy") else m: m for m in archive.namelist()}
            for name in members:
                if name not in _NPZ_ARRAYS:
                    raise _Bad(f"unknown array {name[:40]!r} (allowed: {', '.join(_NPZ_ARRAYS)})")
            if "positions" not in members:
                raise _Bad("no 'positions' array")
            headers = {name: _npz_header(archive, member) for name, member in members.items()}
            count = headers["positions"][0][0] if headers["positions"][0] else 0
            triangles = math.prod(headers["indices"][0]) // 3 if "indices" in headers else count // 3
            _check_counts(count, triangles, max_triangles)
            arrays = {}
            for name, member in members.items():
                with archive.open(member) as file:
                    arrays[name] = np.lib.format.read_array(file, allow_pickle=False)
    except (zipfile.BadZipFile, zlib.error, EOFError) as error:
        raise _Bad(f"not a readable .npz archive ({error})") from None
    except ValueError as error:                    # numpy: bad header, short data, object arrays
        raise _Bad(f"cannot read an array: {error}") from None

    def real(name, width, kinds="fiu"):
        array = arrays.get(name)
        if array is None:
            return None
        widths = (width,) if isinstance(width, int) else width
        if array.dtype.kind not in kinds:
            raise _Bad(f"array {name!r} has type {array.dtype} (expected numbers)")
        if array.ndim != 2 or array.shape[1] not in widths:
            raise _Bad(f"array {name!r} has shape {array.shape}, expected (N, {' or '.join(map(str, widths))})")
        if len(array) != len(positions):
            raise _Bad(f"array {name!r} has {len(array)} rows for {len(positions)} positions")
        return array

    positions = arrays["positions"]
    if positions.dtype.kind not in "fiu" or positions.ndim != 2 or positions.shape[1] != 3:
        raise _Bad(f"array 'positions' has shape {positions.shape} and type {positions.dtype}, expected (N, 3) numbers")
    if "indices" in arrays:
        indices = arrays["indices"]
        if indices.dtype.kind not in "iu":
            raise _Bad(f"array 'indices' has type {indices.dtype} (expected integers)")
        if not (indices.ndim == 2 and indices.shape[1] == 3) and not (indices.ndim == 1 and len(indices) % 3 == 0):
            raise _Bad(f"array 'indices' has shape {indices.shape}, expected (M, 3) or (3M,)")
        indices = indices.reshape(-1, 3).astype(np.int64)
    else:
        if len(positions) % 3:
            raise _Bad(f"without 'indices', the number of positions must be a multiple of 3, got {len(positions)}")
        indices = np.arange(len(positions), dtype=np.int64).reshape(-1, 3)
    colors = real("colors", (3, 4), "fu")
    if colors is not None:
        colors = _rgba(colors.astype(np.float64), colors.dtype)
    normals, uvs = real("normals", 3), real("uvs", 2)
    return MeshArrays(positions.astype(np.float64), indices, colors,
                      None if normals is None else normals.astype(np.float64),
                      None if uvs is None else uvs.astype(np.float64))


# --------------------------------------------------------------------------- glTF


def _read_gltf(path: str, max_triangles: int) -> MeshArrays:
    """The default scene's triangle primitives concatenated into one mesh (the
    container is read by `softras.scene.gltf_files`)."""
    try:
        return _gltf_mesh(gltf_files.GltfFile(path), max_triangles)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
        raise _Bad(f"malformed glTF ({type(error).__name__}: {error})") from None


def _gltf_draws(file: gltf_files.GltfFile) -> list[tuple[int, np.ndarray]]:
    """(mesh index, world matrix) for every mesh of the default scene."""
    gltf = file.document
    if not gltf.get("scenes"):
        return [(m, np.identity(4)) for m in range(len(gltf.get("meshes", [])))]
    index = gltf.get("scene", 0)
    scene = file.item("scenes", index, "scene")
    found = []
    for n, world in file.walk(scene.get("nodes", []), f"scenes[{index}].nodes"):
        node = gltf["nodes"][n]
        if "mesh" in node:
            file.item("meshes", node["mesh"], f"nodes[{n}].mesh")
            found.append((node["mesh"], world))
    return found


def _gltf_mesh(file: gltf_files.GltfFile, max_triangles: int) -> MeshArrays:
    required = file.document.get("extensionsRequired", [])
    if required:
        raise _Bad(f"needs glTF extension(s) {', '.join(map(str, required))}, not supported")
    primitives = [(m, p, world) for m, world in _gltf_draws(file)
                  for p in range(len(file.item("meshes", m, "nodes").get("primitives", [])))]
    vertices = triangles = 0
    for m, p, _ in primitives:                 # sizes first, from the accessors' counts
        counts = file.primitive_counts(m, p)
        vertices, triangles = vertices + counts[0], triangles + counts[1]
        _check_counts(vertices, triangles, max_triangles)
    parts = [_transformed(file.primitive(m, p), world) for m, p, world in primitives]
    if not parts:
        raise _Bad("no mesh primitives (no triangles)")
    for key, what in ((3, "normals (NORMAL)"), (4, "uvs (TEXCOORD_0)")):
        has = [part[key] is not None for part in parts]
        if any(has) and not all(has):
            missing, present = has.index(False), has.index(True)
            raise _Bad(f"primitive {present} has {what} and primitive {missing} has not "
                       f"(counting the primitives drawn, in order)")
    offsets = np.cumsum([0] + [len(part[0]) for part in parts])
    positions = np.concatenate([part[0] for part in parts])
    indices = np.concatenate([part[1] + offset for part, offset in zip(parts, offsets)])
    colors = None
    if any(part[2] is not None for part in parts):       # primitives without COLOR_0 are white
        colors = np.concatenate([part[2] if part[2] is not None else np.ones((len(part[0]), 4))
                                 for part in parts])
    normals = np.concatenate([part[3] for part in parts]) if parts[0][3] is not None else None
    uvs = np.concatenate([part[4] for part in parts]) if parts[0][4] is not None else None
    return MeshArrays(positions, indices, colors, normals, uvs)


def _transformed(primitive: gltf_files.Primitive, world: np.ndarray) -> gltf_files.Primitive:
    """A primitive's arrays in world space: positions by ``world``, normals by
    its inverse transpose, the winding reversed where ``world`` mirrors."""
    positions, indices, colors, normals, uvs = primitive
    if not np.array_equal(world, np.identity(4)):
        positions = positions @ world[:3, :3].T + world[:3, 3]
        linear = world[:3, :3]
        if normals is not None:
            with np.errstate(all="ignore"):
                normals = normals @ np.linalg.inv(linear)          # (inverse transpose) applied to rows
        if np.linalg.det(linear) < 0:
            indices = indices[:, ::-1]                              # keep counter-clockwise front faces
    return gltf_files.Primitive(positions, indices, colors, normals, uvs)


_READERS = {".ply": _read_ply, ".obj": _read_obj, ".npz": _read_npz, ".glb": _read_gltf, ".gltf": _read_gltf}
