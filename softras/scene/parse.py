"""The scene model: scene format version 1 (docs/scene_format.md), read and validated.

:func:`load_scene` takes a JSON file path, a dict with the same keys, or an
already loaded :class:`Scene` (returned as is).  Validation is strict: unknown
keys, wrong types, NaN or infinite numbers, wrong vector lengths, indices out
of range and unknown enum strings are all errors.  Every error is a
:class:`SceneError` whose one-line message starts with the place, e.g.
``nodes[2].mesh.indices[5]: index 9 out of range for 8 positions``, or with
the file for a file problem (``scene.json: invalid JSON at line 3 column 5: ...``).

All matrices are float64 in the column-vector convention
(clip = projection @ view @ world @ [x, y, z, 1]); matrices written in a scene
file are row-major (the first four numbers are the first row).  Arrays in the
loaded scene are read-only.

Extensions to the original version-1 format (every original key keeps its
meaning):

- top-level ``"description"``: a free text string (:attr:`Scene.description`);
- top-level ``"framebuffer"``: ``"rgba8"`` (default) or ``"rgba32f"``, the colour
  buffer of both renderers (an rgba32f render returns float32 pixels);
- top-level ``"render_order"``: ``"scene"`` (default, GL's draw order) or
  ``"opaque_then_sorted"`` (see :func:`ordered_draws`);
- top-level ``"front_face"``: ``"ccw"`` (default) or ``"cw"``, glFrontFace:
  which window-space winding is front-facing, for ``cull``;
- material ``"alpha_cutoff"``: a number in [0, 1] (or null, the default: no
  test): fragments whose alpha is below it are discarded (glTF's MASK);
- ``"mesh": {"procedural": "grid" | "sphere" | "fan", ...}`` (see
  :mod:`softras.scene.meshes` and :data:`_PROCEDURAL_MESH_KEYS`);
- ``"mesh": {"file": PATH}``: a PLY, OBJ, NPZ or glTF/GLB mesh file relative to
  the scene's folder (see :mod:`softras.scene.meshfiles`);
- texture ``"procedural": "checker" | "gradient" | "noise" | "bumps"`` with ``"size"`` and
  per-kind parameters instead of ``"image"`` (see :data:`_PROCEDURAL_TEXTURE_KEYS`);
- material ``"normal_map": NAME`` (tangent-space normal texture) or
  ``"bump_map": NAME`` with ``"bump_scale"`` (height texture, red channel),
  both for ``"shading": "phong"`` only and needing mesh uvs (see
  :func:`softras.pipeline.fragment.bump_normals`); material ``"displacement":
  {"texture": NAME, "scale": S}`` moves the mesh's vertices along their
  normals when the scene is loaded (:mod:`softras.scene.displace`), so
  ``Draw.mesh`` is the displaced mesh for both renderers.

Why one module of ~820 lines: one parsing function per section of the format
(camera, textures, lights, meshes, materials, nodes), all sharing the same
validators and the place strings of their errors (docs/scene_format.md lists
the keys; the records are in `softras.scene.model`).
"""

from __future__ import annotations

import contextlib
import difflib
import gc
import itertools
import json
import math
import os
from typing import Any

import numpy as np
import orjson

from softras.scene import displace, gltf, meshes, meshfiles, texels
from softras.scene.fileio import is_number, number_problem, type_name
from softras.scene.model import (BLEND_MODES, CULL_MODES, DEFAULT_TOLERANCE, DEPTH_FUNCTIONS, FORMAT_VERSION, FRAMEBUFFERS,
                                 FRONT_FACES,
                                 LIGHT_TYPES, MAG_FILTERS, MAX_NODE_DEPTH, MAX_PIXELS, MAX_SIDE, MAX_TEXELS,
                                 MIN_FILTERS, PRIMITIVES, PROCEDURAL_TEXTURES, PROJECTIONS, RENDER_ORDERS, SHADINGS,
                                 WRAP_MODES,
                                 Camera, Displacement, Draw, Light, Material, Mesh, Scene, SceneError, Texture,
                                 _readonly)
from softras.scene.transforms import (cross3, frustum_matrix, look_at_matrix, orthographic_matrix,
                                      perspective_matrix, rotate_matrix, scale_matrix, translate_matrix)

def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _number(value, place: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    """A finite number in [lo, hi] (ints and floats; booleans are not numbers):
    `softras.scene.fileio.number_problem`, the check the glTF reader shares."""
    problem = number_problem(value, lo, hi)
    if problem is not None:
        raise SceneError(place, problem)
    return float(value)


def _positive(value, place: str) -> float:
    number = _number(value, place)
    if number <= 0:
        raise SceneError(place, f"must be positive, got {number:g}")
    return number


def _integer(value, place: str, lo: int, hi: int) -> int:
    if not _is_int(value):
        raise SceneError(place, f"expected an integer, got {type_name(value)}")
    if not lo <= value <= hi:
        raise SceneError(place, f"{value} is out of range [{lo}, {hi}]")
    return int(value)


def _bool(value, place: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise SceneError(place, f"expected true or false, got {type_name(value)}")
    return bool(value)


def _string(value, place: str) -> str:
    if not isinstance(value, str):
        raise SceneError(place, f"expected a string, got {type_name(value)}")
    return value


def _choice(value, place: str, choices) -> str:
    if not isinstance(value, str) or value not in choices:
        raise SceneError(place, f"expected one of {', '.join(choices)}; got {type_name(value)}")
    return value


def _list(value, place: str) -> list:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if not isinstance(value, (list, tuple)):
        raise SceneError(place, f"expected a list, got {type_name(value)}")
    return list(value)


def _vec(value, n: int | tuple[int, ...], place: str, lo: float = -math.inf, hi: float = math.inf) -> np.ndarray:
    """A list of ``n`` finite numbers (``n`` may be a tuple of allowed lengths)."""
    items = _list(value, place)
    lengths = (n,) if isinstance(n, int) else n
    if len(items) not in lengths:
        want = " or ".join(str(k) for k in lengths)
        raise SceneError(place, f"expected {want} numbers, got {len(items)}")
    numbers = []
    for i, x in enumerate(items):
        if type(x) is float or (type(x) is int and -_EXACT_INT <= x <= _EXACT_INT):   # (JSON's own types)
            number = float(x)
            if lo <= number <= hi and number - number == 0:                   # in range and finite
                numbers.append(number)
                continue
        numbers.append(_number(x, f"{place}[{i}]", lo, hi))                # (raises, or another kind of number)
    return np.array(numbers, dtype=np.float64)


_EXACT_INT = 2 ** 53     # ints up to this size convert to float exactly (no OverflowError)


def _nonzero_vec3(value, place: str) -> np.ndarray:
    vector = _vec(value, 3, place)
    if not np.any(vector):
        raise SceneError(place, "must not be the zero vector")
    return vector


def _color(value, place: str) -> np.ndarray:
    """RGB or RGBA in [0, 1] -> (4,) RGBA (RGB gets alpha 1)."""
    rgba = _vec(value, (3, 4), place, 0.0, 1.0)
    return rgba if len(rgba) == 4 else np.append(rgba, 1.0)


def _matrix(value, place: str) -> np.ndarray:
    """16 numbers, row-major -> (4, 4)."""
    return _vec(value, 16, place).reshape(4, 4)


def _array(value, width: int | tuple[int, ...], place: str, lo: float = -math.inf, hi: float = math.inf) -> np.ndarray:
    """A list of rows of ``width`` finite numbers -> (N, width) float64.

    All rows must have the same length (``width`` may allow several)."""
    widths = (width,) if isinstance(width, int) else width
    fast = _fast_array(value, widths, lo, hi)
    if fast is not None:
        return fast
    rows = _list(value, place)
    if not rows:
        return np.zeros((0, widths[0]))
    first = _list(rows[0], f"{place}[0]")
    row_width = len(first)
    if row_width not in widths:
        want = " or ".join(str(k) for k in widths)
        raise SceneError(f"{place}[0]", f"expected {want} numbers, got {row_width}")
    out = np.empty((len(rows), row_width), dtype=np.float64)
    for i, row in enumerate(rows):
        row = row if isinstance(row, (list, tuple)) else _list(row, f"{place}[{i}]")
        if len(row) != row_width:
            raise SceneError(f"{place}[{i}]", f"expected {row_width} numbers like {place}[0], got {len(row)}")
        for k, x in enumerate(row):
            if type(x) is not float and type(x) is not int and not is_number(x):
                raise SceneError(f"{place}[{i}][{k}]", f"expected a number, got {type_name(x)}")
            try:
                out[i, k] = x
            except OverflowError:
                raise SceneError(f"{place}[{i}][{k}]", "number too large") from None
    bad = ~np.isfinite(out) | (out < lo) | (out > hi)
    if bad.any():
        i, k = np.argwhere(bad)[0]
        _number(rows[i][k], f"{place}[{i}][{k}]", lo, hi)   # raises with the reason
    return out


def _indices(value, width: int, vertex_count: int, place: str) -> np.ndarray:
    """Triangles (width 3) or lines (width 2), nested ([[0,1,2], ...]) or flat
    ([0,1,2, ...]), each index an integer in [0, vertex_count)."""
    fast = _fast_indices(value, width, vertex_count)
    if fast is not None:
        return fast
    items = _list(value, place)
    if items and not isinstance(items[0], (list, tuple, np.ndarray)):
        if len(items) % width:
            raise SceneError(place, f"a flat index list needs a multiple of {width} entries, got {len(items)}")
        groups = [items[i:i + width] for i in range(0, len(items), width)]
        flat = True
    else:
        groups = items
        flat = False
    out = np.empty((len(groups), width), dtype=np.int64)
    for g, group in enumerate(groups):
        group_place = f"{place}[{g}]"
        if not flat:
            group = _list(group, group_place)
            if len(group) != width:
                raise SceneError(group_place, f"expected {width} indices, got {len(group)}")
        for k, index in enumerate(group):
            index_place = f"{place}[{g * width + k}]" if flat else group_place
            if not _is_int(index):
                sub = index_place if flat else f"{group_place}[{k}]"
                raise SceneError(sub, f"expected an integer index, got {type_name(index)}")
            if not 0 <= index < vertex_count:
                raise SceneError(index_place, f"index {index} out of range for {vertex_count} positions")
            out[g, k] = index
    return out


# The fast paths of `_array` and `_indices`: a mesh's arrays as JSON gives
# them (lists of lists of int and float) or as numpy arrays, validated with
# whole-array checks.  They return None on anything unusual, valid or not
# (tuples, numpy scalars, a bad row); the element-by-element code after them
# then accepts it or raises with the exact place, so both paths accept the
# same input and every error message comes from one place.


_NUMBERS = frozenset((float, int))     # JSON's numbers as Python types (bool is not int here: type() is exact)
_INTS = frozenset((int,))


def _uniform_rows(value, widths, kinds) -> tuple[int, list] | None:
    """The common row length of ``value``, a list of lists each of one length
    in ``widths`` whose every entry's type is one of ``kinds``, and its
    entries flattened row by row into one list (walked once for their
    types and once by numpy: 0.2-0.3 ms less for a 12k-vertex mesh's
    positions or colours than walking the nested lists twice); None
    otherwise."""
    if type(value) is not list or not value or set(map(type, value)) != {list}:
        return None
    lengths = set(map(len, value))
    if len(lengths) != 1:
        return None
    row_width = lengths.pop()
    if row_width not in widths:
        return None
    flat = list(itertools.chain.from_iterable(value))
    if not set(map(type, flat)) <= kinds:
        return None
    return row_width, flat


def _from_rows(flat: list, row_width: int, dtype) -> np.ndarray | None:
    """A flat list of numbers as an (N, row_width) array (numpy reads a flat
    list twice as fast as nested lists); None when a number does not fit
    ``dtype`` (an int beyond float64's or int64's range)."""
    try:
        out = np.fromiter(flat, dtype, count=len(flat))
    except OverflowError:
        return None
    return out.reshape(-1, row_width)


def _fast_array(value, widths, lo: float, hi: float) -> np.ndarray | None:
    """`_array`'s result, (N, width) float64, when ``value`` is valid and plain
    (see above); None otherwise."""
    if isinstance(value, np.ndarray):
        if value.ndim != 2 or value.shape[1] not in widths or value.dtype.kind not in "fiu" or not len(value):
            return None
        out = value.astype(np.float64)
    else:
        rows = _uniform_rows(value, widths, _NUMBERS)
        if rows is None:
            return None
        row_width, flat = rows
        if (out := _from_rows(flat, row_width, np.float64)) is None:
            return None
    with np.errstate(invalid="ignore"):
        if not (np.isfinite(out).all() and (lo == -math.inf or out.min() >= lo)
                and (hi == math.inf or out.max() <= hi)):
            return None
    return out


def _fast_indices(value, width: int, vertex_count: int) -> np.ndarray | None:
    """`_indices`' result, (N, width) int64, when ``value`` is valid and plain:
    a list of lists of ``width`` ints or a flat list of ints (or an integer
    numpy array of either shape), all in [0, vertex_count); None otherwise."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iu" or value.ndim not in (1, 2) or not value.size:
            return None
        if value.size % width or (value.ndim == 2 and value.shape[1] != width):
            return None
        out = value.astype(np.int64).reshape(-1, width)
    elif type(value) is list and value and type(value[0]) is list:
        rows = _uniform_rows(value, (width,), _INTS)
        if rows is None or (out := _from_rows(rows[1], width, np.int64)) is None:     # (rows: width, flat list)
            return None
    elif type(value) is list and value:
        if len(value) % width or set(map(type, value)) != {int}:
            return None
        if (out := _from_rows(value, width, np.int64)) is None:
            return None
    else:
        return None
    if out.min() < 0 or out.max() >= vertex_count:
        return None
    return out


def _object(value, place: str, allowed, required=()) -> dict:
    """A dict whose keys are all in ``allowed`` and include ``required``."""
    if not isinstance(value, dict):
        raise SceneError(place, f"expected an object, got {type_name(value)}")
    for key in value:
        if key not in allowed:
            hint = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f"; did you mean {hint[0]!r}?" if hint else ""
            raise SceneError(_join(place, key), f"unknown key (allowed: {', '.join(allowed)}){hint}")
    for key in required:
        if key not in value:
            raise SceneError(_join(place, key), "missing (required)")
    return value


def _join(place: str, key) -> str:
    return str(key) if place == "scene" else f"{place}.{key}"


# --------------------------------------------------------------------------- sections


_TOP_KEYS = ("softras_scene", "description", "width", "height", "background", "samples",
             "camera", "textures", "lights", "nodes", "tolerance", "framebuffer", "render_order", "front_face")


def _parse_size(data: dict) -> tuple[int, int]:
    width = _integer(data["width"], "width", 1, MAX_SIDE)
    height = _integer(data["height"], "height", 1, MAX_SIDE)
    if width * height > MAX_PIXELS:
        raise SceneError("width", f"{width} x {height} is {width * height} pixels, more than the limit {MAX_PIXELS}")
    return width, height


_CAMERA_KEYS = ("projection", "fov_y", "aspect", "near", "far", "left", "right", "bottom", "top",
                "eye", "target", "up", "view_matrix", "projection_matrix")
_PROJECTION_KEYS = {"perspective": ("fov_y", "aspect", "near", "far"),
                    "orthographic": ("left", "right", "bottom", "top", "near", "far"),
                    "frustum": ("left", "right", "bottom", "top", "near", "far")}


def _parse_camera(value, width: int, height: int) -> Camera:
    """Projection from ``projection`` and its parameters, or ``projection_matrix``;
    view from eye/target/up (gluLookAt) or ``view_matrix``.  Default view: eye at
    the origin looking down −z with +y up, the identity.  With no camera at all
    both matrices are the identity (positions are clip coordinates)."""
    place = "camera"
    data = _object(value, place, _CAMERA_KEYS)

    if "view_matrix" in data:
        for key in ("eye", "target", "up"):
            if key in data:
                raise SceneError(f"camera.{key}", "not allowed together with camera.view_matrix")
        view = _matrix(data["view_matrix"], "camera.view_matrix")
    else:
        eye = _vec(data.get("eye", [0, 0, 0]), 3, "camera.eye")
        target = _vec(data["target"], 3, "camera.target") if "target" in data else eye + (0, 0, -1)
        up = _nonzero_vec3(data.get("up", [0, 1, 0]), "camera.up")
        forward = target - eye
        if not np.any(forward):
            raise SceneError("camera.target", "must differ from camera.eye")
        if np.linalg.norm(cross3(forward / np.linalg.norm(forward), up / np.linalg.norm(up))) < 1e-9:
            raise SceneError("camera.up", "must not be parallel to the view direction (target − eye)")
        view = look_at_matrix(eye, target, up)

    if "projection_matrix" in data:
        for key in ("projection",) + _PROJECTION_KEYS["orthographic"] + ("fov_y", "aspect"):
            if key in data:
                raise SceneError(f"camera.{key}", "not allowed together with camera.projection_matrix")
        return Camera(_readonly(view), _readonly(_matrix(data["projection_matrix"], "camera.projection_matrix")), "matrix")
    if "projection" not in data:
        if any(key in data for key in _PROJECTION_KEYS["orthographic"] + ("fov_y", "aspect")):
            raise SceneError("camera.projection", "missing (required when projection parameters are given)")
        return Camera(_readonly(view), _readonly(np.identity(4)), "matrix")

    kind = _choice(data["projection"], "camera.projection", PROJECTIONS)
    allowed = _PROJECTION_KEYS[kind]
    for key in _PROJECTION_KEYS["orthographic"] + ("fov_y", "aspect"):
        if key in data and key not in allowed:
            raise SceneError(f"camera.{key}", f"not a parameter of the {kind} camera (those are: {', '.join(allowed)})")
    for key in allowed:
        if key not in data and key != "aspect":
            raise SceneError(f"camera.{key}", f"missing (required for a {kind} camera)")

    near, far = _number(data["near"], "camera.near"), _number(data["far"], "camera.far")
    if kind == "perspective":
        fov_y = _number(data["fov_y"], "camera.fov_y")
        if not 0 < fov_y < 180:
            raise SceneError("camera.fov_y", f"must be between 0 and 180 degrees (exclusive), got {fov_y:g}")
        aspect = _positive(data["aspect"], "camera.aspect") if "aspect" in data else width / height
        _check_near_far(near, far, positive=True)
        projection = perspective_matrix(fov_y, aspect, near, far)
    else:
        left, right = _number(data["left"], "camera.left"), _number(data["right"], "camera.right")
        bottom, top = _number(data["bottom"], "camera.bottom"), _number(data["top"], "camera.top")
        if left == right:
            raise SceneError("camera.right", "must differ from camera.left")
        if bottom == top:
            raise SceneError("camera.top", "must differ from camera.bottom")
        _check_near_far(near, far, positive=kind == "frustum")
        matrix = frustum_matrix if kind == "frustum" else orthographic_matrix
        projection = matrix(left, right, bottom, top, near, far)
    return Camera(_readonly(view), _readonly(projection), kind)


def _check_near_far(near: float, far: float, positive: bool) -> None:
    if positive and near <= 0:
        raise SceneError("camera.near", f"must be positive, got {near:g}")
    if positive and far <= near:
        raise SceneError("camera.far", f"must be greater than camera.near ({near:g}), got {far:g}")
    if not positive and far == near:
        raise SceneError("camera.far", "must differ from camera.near")


_TEXTURE_KEYS = ("image", "procedural", "size", "wrap_s", "wrap_t", "min_filter", "mag_filter", "max_anisotropy")
# Parameters of procedural textures, with their defaults.
_PROCEDURAL_TEXTURE_KEYS = {
    "checker": {"squares": 8, "color0": [0, 0, 0, 1], "color1": [1, 1, 1, 1]},
    "gradient": {"direction": "horizontal", "color0": [0, 0, 0, 1], "color1": [1, 1, 1, 1]},
    "noise": {"seed": 0},
    "bumps": {"cells": 4},
}


def _decode_image(path: str, place: str) -> np.ndarray:
    """Decode a texture image once, at load time, so that a corrupt, truncated or
    oversized file is a SceneError here rather than a crash in a renderer.
    Returns its straight RGBA texels, (H, W, 4) uint8, row 0 = the file's top row.

    The size comes from the file's header and is checked (MAX_SIDE per side,
    MAX_TEXELS in all) before any pixel is decoded.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            return _readonly(texels.checked_texels(image, MAX_SIDE, MAX_TEXELS))
    except texels.TooManyTexels as error:
        raise SceneError(place, f"{path} is {error}") from None
    except UnidentifiedImageError:
        raise SceneError(place, f"{path} is not an image file (not a PNG or any format Pillow reads)") from None
    except Image.DecompressionBombError as error:
        raise SceneError(place, f"{path}: {error}") from None
    except texels.DECODE_ERRORS as error:
        raise SceneError(place, f"cannot decode {path}: {error}") from None


def _parse_textures(value, base_dir: str) -> dict[str, Texture]:
    textures = {}
    if not isinstance(value, dict):
        raise SceneError("textures", f"expected an object of named textures, got {type_name(value)}")
    for name, entry in value.items():
        place = f"textures.{name}"
        if not name:
            raise SceneError("textures", "a texture name must not be empty")
        extra = ()
        if isinstance(entry, dict) and "procedural" in entry:
            kind = _choice(entry["procedural"], f"{place}.procedural", PROCEDURAL_TEXTURES)
            extra = tuple(_PROCEDURAL_TEXTURE_KEYS[kind])
        data = _object(entry, place, _TEXTURE_KEYS + extra)
        if ("image" in data) == ("procedural" in data):
            raise SceneError(place, "needs exactly one of 'image' and 'procedural'")
        image = procedural = size = decoded = None
        params = {}
        if "image" in data:
            if "size" in data:
                raise SceneError(f"{place}.size", "only for procedural textures (an image has its own size)")
            image = os.path.normpath(os.path.join(base_dir, _string(data["image"], f"{place}.image")))
            if not os.path.isfile(image):
                raise SceneError(f"{place}.image", f"file not found: {image}")
            decoded = _decode_image(image, f"{place}.image")
        else:
            procedural = _choice(data["procedural"], f"{place}.procedural", PROCEDURAL_TEXTURES)
            if "size" not in data:
                raise SceneError(f"{place}.size", "missing (required for a procedural texture)")
            size_items = _list(data["size"], f"{place}.size")
            if len(size_items) != 2:
                raise SceneError(f"{place}.size", f"expected 2 integers [width, height], got {len(size_items)}")
            size = tuple(_integer(v, f"{place}.size[{i}]", 1, MAX_SIDE) for i, v in enumerate(size_items))
            if size[0] * size[1] > MAX_TEXELS:
                raise SceneError(f"{place}.size", f"{size[0]} x {size[1]} is {size[0] * size[1]} texels, "
                                                  f"more than the limit {MAX_TEXELS}")
            for key, default in _PROCEDURAL_TEXTURE_KEYS[procedural].items():
                raw = data.get(key, default)
                key_place = f"{place}.{key}"
                if key in ("squares", "cells"):
                    params[key] = _integer(raw, key_place, 1, MAX_SIDE)
                elif key == "seed":
                    params[key] = _integer(raw, key_place, 0, 2**32 - 1)
                elif key == "direction":
                    params[key] = _choice(raw, key_place, ("horizontal", "vertical"))
                else:
                    params[key] = _readonly(_color(raw, key_place))
        textures[name] = Texture(
            name=name, image=image,
            wrap_s=_choice(data.get("wrap_s", "repeat"), f"{place}.wrap_s", WRAP_MODES),
            wrap_t=_choice(data.get("wrap_t", "repeat"), f"{place}.wrap_t", WRAP_MODES),
            # GL's defaults: NEAREST_MIPMAP_LINEAR and LINEAR.
            min_filter=_choice(data.get("min_filter", "nearest_mipmap_linear"), f"{place}.min_filter", MIN_FILTERS),
            mag_filter=_choice(data.get("mag_filter", "linear"), f"{place}.mag_filter", MAG_FILTERS),
            max_anisotropy=_number(data.get("max_anisotropy", 1), f"{place}.max_anisotropy", 1, 16),
            procedural=procedural, size=size, params=params, decoded=decoded)
    return textures


def _parse_light(value, place: str) -> Light:
    data = _object(value, place, ("type", "position", "direction", "color"), required=("type",))
    kind = _choice(data["type"], f"{place}.type", LIGHT_TYPES)
    needed, forbidden = ("position", "direction") if kind == "point" else ("direction", "position")
    if forbidden in data:
        raise SceneError(f"{place}.{forbidden}", f"not used by a {kind} light")
    if needed not in data:
        raise SceneError(f"{place}.{needed}", f"missing (required for a {kind} light)")
    position = _vec(data["position"], 3, f"{place}.position") if kind == "point" else None
    direction = _nonzero_vec3(data["direction"], f"{place}.direction") if kind == "directional" else None
    color = _vec(data.get("color", [1, 1, 1]), 3, f"{place}.color", 0.0)
    return Light(kind, _readonly(position), _readonly(direction), _readonly(color))


_MESH_KEYS = ("primitive", "positions", "indices", "colors", "normals", "uvs", "procedural", "file")
# Parameters of procedural meshes: key -> (kind of value, default or None if required).
_PROCEDURAL_MESH_KEYS = {
    "grid": {"cols": ("count", None), "rows": ("count", None), "size": ("size2", [1, 1]),
             "corner_colors": ("colors4", None)},
    "sphere": {"segments": ("count", None), "rings": ("count", None), "radius": ("positive", 1),
               "color_from_normal": ("bool", False)},
    "fan": {"count": ("count", None), "radius": ("positive", 1), "angle": ("angle", 360),
            "center_color": ("color", None), "rim_colors": ("colors", None)},
}
_REQUIRED = object()


def _parse_mesh(value, place: str, budget: list[int], base_dir: str) -> Mesh:
    """``budget``: a one-element list, the procedural and file-mesh triangles
    the scene may still have; ``base_dir``: the folder mesh files are relative to."""
    if isinstance(value, dict) and "procedural" in value:
        return _parse_procedural_mesh(value, place, budget)
    if isinstance(value, dict) and "file" in value:
        return _parse_file_mesh(value, place, budget, base_dir)
    data = _object(value, place, _MESH_KEYS, required=("positions",))
    primitive = _choice(data.get("primitive", "triangles"), f"{place}.primitive", PRIMITIVES)
    width = 3 if primitive == "triangles" else 2
    positions = _array(data["positions"], 3, f"{place}.positions")
    count = len(positions)
    if count == 0:
        raise SceneError(f"{place}.positions", "must not be empty")
    if "indices" in data:
        indices = _indices(data["indices"], width, count, f"{place}.indices")
    else:
        if count % width:
            raise SceneError(f"{place}.positions", f"without indices, {primitive} need a multiple of {width} positions, got {count}")
        indices = np.arange(count, dtype=np.int64).reshape(-1, width)

    def per_vertex(key, widths, lo=-math.inf, hi=math.inf):
        if key not in data:
            return None
        array = _array(data[key], widths, f"{place}.{key}", lo, hi)
        if len(array) != count:
            raise SceneError(f"{place}.{key}", f"{len(array)} entries for {count} positions")
        return array

    colors = per_vertex("colors", (3, 4), 0.0, 1.0)
    if colors is not None and colors.shape[1] == 3:
        colors = np.concatenate([colors, np.ones((count, 1))], axis=1)
    normals = per_vertex("normals", 3)
    uvs = per_vertex("uvs", 2)
    return Mesh(primitive, *(_readonly(a) for a in (positions, indices, colors, normals, uvs)))


def _parse_file_mesh(value: dict, place: str, budget: list[int], base_dir: str) -> Mesh:
    """``{"file": PATH}``: a PLY, OBJ, NPZ or glTF file (softras.scene.meshfiles),
    nothing else beside it; its triangles count against ``budget``."""
    data = _object(value, place, _MESH_KEYS)
    for key in data:
        if key != "file":
            raise SceneError(f"{place}.{key}", "not allowed together with file (the file gives the whole mesh)")
    name = _string(data["file"], f"{place}.file")
    if not name:
        raise SceneError(f"{place}.file", "must not be empty")
    path = os.path.normpath(os.path.join(base_dir, name))
    mesh = meshfiles.read_mesh_file(path, name, f"{place}.file", budget[0])
    budget[0] -= len(mesh.indices)
    return mesh


def _parse_procedural_mesh(value, place: str, budget: list[int]) -> Mesh:
    kind = _choice(value["procedural"], f"{place}.procedural", tuple(_PROCEDURAL_MESH_KEYS))
    spec = _PROCEDURAL_MESH_KEYS[kind]
    data = _object(value, place, ("procedural",) + tuple(spec))
    args = {}
    for key, (form, default) in spec.items():
        key_place = f"{place}.{key}"
        if key not in data:
            if default is None and form == "count":
                raise SceneError(key_place, f"missing (required for a {kind} mesh)")
            args[key] = default
            continue
        raw = data[key]
        if form == "count":
            args[key] = _integer(raw, key_place, 1, meshes.MAX_TRIANGLES)
        elif form == "positive":
            args[key] = _positive(raw, key_place)
        elif form == "angle":
            args[key] = _number(raw, key_place, 0, 360)
            if args[key] == 0:
                raise SceneError(key_place, "must be greater than 0 degrees")
        elif form == "size2":
            args[key] = [_positive(v, f"{key_place}[{i}]") for i, v in enumerate(_vec(raw, 2, key_place))]
        elif form == "bool":
            args[key] = _bool(raw, key_place)
        elif form == "color":
            args[key] = _color(raw, key_place)
        else:  # "colors4" (exactly four) or "colors" (one or more)
            items = _list(raw, key_place)
            if form == "colors4" and len(items) != 4:
                raise SceneError(key_place, f"expected 4 colours (bottom-left, bottom-right, top-right, top-left), got {len(items)}")
            if not items:
                raise SceneError(key_place, "expected at least one colour")
            args[key] = [_color(c, f"{key_place}[{i}]") for i, c in enumerate(items)]

    if kind == "sphere" and args["segments"] < 3:
        raise SceneError(f"{place}.segments", f"a sphere needs at least 3 segments, got {args['segments']}")
    if kind == "sphere" and args["rings"] < 2:
        raise SceneError(f"{place}.rings", f"a sphere needs at least 2 rings, got {args['rings']}")
    if kind == "fan" and args["angle"] == 360 and args["count"] < 3:
        raise SceneError(f"{place}.count", "a full-turn fan needs at least 3 triangles")
    triangles = meshes.triangle_count(kind, **args)
    if triangles > budget[0]:
        raise SceneError(place, f"this {kind} has {triangles} triangles; the scene may have at most "
                                f"{meshes.MAX_TRIANGLES} procedural and file-mesh triangles in all")
    budget[0] -= triangles
    arrays = meshes.PROCEDURAL[kind](**args)
    return Mesh("triangles", *(_readonly(np.ascontiguousarray(a)) if a is not None else None for a in arrays))


_MATERIAL_KEYS = ("color", "texture", "shading", "ambient", "diffuse", "specular", "shininess",
                  "normal_map", "bump_map", "bump_scale", "displacement", "alpha_cutoff")


def _texture_name(value, place: str, textures: dict[str, Texture]) -> str:
    name = _string(value, place)
    if name not in textures:
        known = ", ".join(textures) or "none"
        raise SceneError(place, f"unknown texture {name!r} (defined: {known})")
    return name


def _parse_displacement(value, place: str, textures: dict[str, Texture]) -> Displacement:
    data = _object(value, place, ("texture", "scale"), required=("texture", "scale"))
    return Displacement(texture=_texture_name(data["texture"], f"{place}.texture", textures),
                        scale=_number(data["scale"], f"{place}.scale"))


def _parse_material(value, place: str, textures: dict[str, Texture]) -> Material:
    data = _object(value, place, _MATERIAL_KEYS)
    texture = None
    if "texture" in data and data["texture"] is not None:
        texture = _texture_name(data["texture"], f"{place}.texture", textures)
    shading = _choice(data.get("shading", "unlit"), f"{place}.shading", SHADINGS)
    maps = {}
    for key in ("normal_map", "bump_map"):
        if key in data:
            maps[key] = _texture_name(data[key], f"{place}.{key}", textures)
            if shading != "phong":
                raise SceneError(f"{place}.{key}", f"needs \"shading\": \"phong\" (a per-fragment normal); "
                                                   f"this material is {shading}")
    if len(maps) == 2:
        raise SceneError(f"{place}.bump_map", "not allowed together with normal_map (give one of them)")
    if "bump_scale" in data and "bump_map" not in data:
        raise SceneError(f"{place}.bump_scale", "only used with bump_map")
    bump_scale = _number(data.get("bump_scale", 1.0), f"{place}.bump_scale")
    displacement = None
    if "displacement" in data:
        displacement = _parse_displacement(data["displacement"], f"{place}.displacement", textures)
    alpha_cutoff = None
    if "alpha_cutoff" in data and data["alpha_cutoff"] is not None:
        alpha_cutoff = _number(data["alpha_cutoff"], f"{place}.alpha_cutoff", 0.0, 1.0)
    return Material(
        alpha_cutoff=alpha_cutoff,
        normal_map=maps.get("normal_map"), bump_map=maps.get("bump_map"), bump_scale=bump_scale,
        displacement=displacement,
        color=_readonly(_color(data.get("color", [1, 1, 1, 1]), f"{place}.color")),
        texture=texture,
        shading=shading,
        ambient=_number(data.get("ambient", 0.1), f"{place}.ambient", 0.0),
        diffuse=_number(data.get("diffuse", 0.8), f"{place}.diffuse", 0.0),
        specular=_number(data.get("specular", 0.5), f"{place}.specular", 0.0),
        shininess=_number(data.get("shininess", 32), f"{place}.shininess", 0.0, 4096.0))


_NODE_KEYS = ("name", "matrix", "translate", "rotate", "scale", "mesh", "material",
              "depth_test", "depth_write", "cull", "blend", "children")
_DRAW_STATE_KEYS = ("material", "depth_test", "depth_write", "cull", "blend")


def _local_matrix(data: dict, place: str) -> np.ndarray:
    """``matrix`` (row-major), or translate · rotate · scale (each optional)."""
    if "matrix" in data:
        for key in ("translate", "rotate", "scale"):
            if key in data:
                raise SceneError(f"{place}.{key}", "not allowed together with matrix")
        return _matrix(data["matrix"], f"{place}.matrix")
    local = np.identity(4)
    if "translate" in data:
        local = local @ translate_matrix(_vec(data["translate"], 3, f"{place}.translate"))
    if "rotate" in data:
        angle, *axis = _vec(data["rotate"], 4, f"{place}.rotate")
        if not any(axis):
            raise SceneError(f"{place}.rotate", "the axis (numbers 2 to 4) must not be zero")
        local = local @ rotate_matrix(angle, axis)
    if "scale" in data:
        local = local @ scale_matrix(_vec(data["scale"], 3, f"{place}.scale"))
    return local


def _depth_test(value, place: str) -> str | None:
    if isinstance(value, bool):
        return "less" if value else None
    if not isinstance(value, str) or value not in DEPTH_FUNCTIONS:
        raise SceneError(place, f"expected false, true or one of {', '.join(DEPTH_FUNCTIONS)}; got {type_name(value)}")
    return value


def _flatten_nodes(nodes, place: str, parent_world: np.ndarray, textures, draws: list, budget, depth: int,
                   base_dir: str) -> None:
    """Append a Draw for every node with a mesh: depth-first, parent before its
    children, in list order (GL draw-call order)."""
    if depth > MAX_NODE_DEPTH:
        raise SceneError(place, f"nodes nested more than {MAX_NODE_DEPTH} levels deep")
    for i, node in enumerate(_list(nodes, place)):
        node_place = f"{place}[{i}]"
        data = _object(node, node_place, _NODE_KEYS)
        name = _string(data["name"], f"{node_place}.name") if "name" in data else node_place
        with np.errstate(over="ignore", invalid="ignore"):
            world = parent_world @ _local_matrix(data, node_place)
        if not np.isfinite(world).all():
            raise SceneError(node_place, "the world matrix overflows (transform numbers too large)")
        if "mesh" in data:
            mesh = _parse_mesh(data["mesh"], f"{node_place}.mesh", budget, base_dir)
            material = _parse_material(data.get("material", {}), f"{node_place}.material", textures)
            if mesh.primitive == "lines":
                lit = material.line_problems()
                if lit:
                    raise SceneError(f"{node_place}.material", f"lines are drawn unlit and untextured, "
                                                               f"this material has {', '.join(lit)}")
            if material.texture is not None and mesh.uvs is None:
                raise SceneError(f"{node_place}.mesh", f"material uses texture {material.texture!r} but the mesh has no uvs")
            if material.shading in ("gouraud", "phong") and mesh.normals is None:
                raise SceneError(f"{node_place}.mesh", f"{material.shading} shading needs normals")
            for key in ("normal_map", "bump_map"):
                if getattr(material, key) is not None and mesh.uvs is None:
                    raise SceneError(f"{node_place}.mesh", f"material uses {key} {getattr(material, key)!r} but the mesh has no uvs")
            if material.displacement is not None:
                mesh = _displaced_mesh(mesh, material.displacement, textures, f"{node_place}.material.displacement")
            draws.append(Draw(
                path=node_place, name=name, world=_readonly(world.copy()), mesh=mesh, material=material,
                depth_test=_depth_test(data.get("depth_test", "less"), f"{node_place}.depth_test"),
                depth_write=_bool(data.get("depth_write", True), f"{node_place}.depth_write"),
                cull=_choice(data.get("cull", "none"), f"{node_place}.cull", CULL_MODES),
                blend=_choice(data.get("blend", "none"), f"{node_place}.blend", BLEND_MODES)))
        else:
            for key in _DRAW_STATE_KEYS:
                if key in data:
                    raise SceneError(f"{node_place}.{key}", "a node without a mesh draws nothing (give it to the node with the mesh)")
        if "children" in data:
            _flatten_nodes(data["children"], f"{node_place}.children", world, textures, draws, budget, depth + 1,
                           base_dir)


def _displaced_mesh(mesh: Mesh, displacement: Displacement, textures: dict[str, Texture], place: str) -> Mesh:
    """The mesh with its vertices moved along their normals (softras.scene.displace)."""
    if mesh.primitive != "triangles":
        raise SceneError(place, f"displacement needs triangles, this mesh has {mesh.primitive}")
    for key in ("normals", "uvs"):
        if getattr(mesh, key) is None:
            raise SceneError(place, f"displacement needs mesh {key}, the mesh has none")
    zero = np.flatnonzero(~np.any(mesh.normals, axis=1))
    if len(zero):
        raise SceneError(place, f"the mesh normal {zero[0]} is the zero vector (displacement moves along normals)")
    try:
        height = textures[displacement.texture]
        height.levels                   # decoded and premultiplied here, to report a bad file
    except (OSError, ValueError) as error:
        raise SceneError(f"{place}.texture", f"cannot read texture {displacement.texture!r}: {error}") from None
    positions, normals = displace.displace(mesh.positions, mesh.normals, mesh.uvs, mesh.indices,
                                           height, displacement.scale)
    return Mesh(mesh.primitive, _readonly(positions), mesh.indices, mesh.colors, _readonly(normals), mesh.uvs)


def _parse_tolerance(value) -> dict:
    data = _object(value, "tolerance", tuple(DEFAULT_TOLERANCE))
    tolerance = dict(DEFAULT_TOLERANCE)
    if "threshold" in data:
        tolerance["threshold"] = _integer(data["threshold"], "tolerance.threshold", 0, 255)
    if "max_bad_fraction" in data:
        tolerance["max_bad_fraction"] = _number(data["max_bad_fraction"], "tolerance.max_bad_fraction", 0, 1)
    if "min_ssim" in data:
        tolerance["min_ssim"] = _number(data["min_ssim"], "tolerance.min_ssim", -1, 1)
    return tolerance


# --------------------------------------------------------------------------- entry points


def scene_from_dict(data: Any, source: str = "<dict>", base_dir: str | None = None) -> Scene:
    """Validate a scene dict; relative paths resolve against ``base_dir`` (default: the current folder)."""
    base_dir = os.path.abspath(base_dir if base_dir is not None else os.getcwd())
    data = _object(data, "scene", _TOP_KEYS, required=("softras_scene", "width", "height"))
    version = data["softras_scene"]
    if not _is_int(version) or version != FORMAT_VERSION:
        raise SceneError("softras_scene", f"unsupported format version {type_name(version)} (this softras reads version {FORMAT_VERSION})")
    description = _string(data["description"], "description") if "description" in data else ""
    width, height = _parse_size(data)
    samples = data.get("samples", 1)
    if not _is_int(samples) or samples not in (1, 4):
        raise SceneError("samples", f"expected 1 or 4, got {type_name(samples)}")
    background = _color(data.get("background", [0, 0, 0, 1]), "background")
    camera = _parse_camera(data.get("camera", {}), width, height)
    if not (np.isfinite(camera.view).all() and np.isfinite(camera.projection).all()):
        raise SceneError("camera", "the view or projection matrix overflows (numbers too large)")
    textures = _parse_textures(data.get("textures", {}), base_dir)
    lights = tuple(_parse_light(light, f"lights[{i}]") for i, light in enumerate(_list(data.get("lights", []), "lights")))
    draws: list[Draw] = []
    _flatten_nodes(data.get("nodes", []), "nodes", np.identity(4), textures, draws, [meshes.MAX_TRIANGLES], 0,
                   base_dir)
    tolerance = _parse_tolerance(data.get("tolerance", {}))
    framebuffer = _choice(data.get("framebuffer", "rgba8"), "framebuffer", FRAMEBUFFERS)
    render_order = _choice(data.get("render_order", "scene"), "render_order", RENDER_ORDERS)
    front_face = _choice(data.get("front_face", "ccw"), "front_face", FRONT_FACES)
    return Scene(width=width, height=height, background=_readonly(background), samples=int(samples),
                 camera=camera, textures=textures, lights=lights, draws=tuple(draws),
                 tolerance=tolerance, source=source, description=description,
                 framebuffer=framebuffer, render_order=render_order, front_face=front_face,
                 declares_tolerance="tolerance" in data)


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def _no_duplicate_keys(pairs):
    result = {}
    for key, value in pairs:
        if key in result:
            raise ValueError(f"duplicate key {key!r}")
        result[key] = value
    return result


def _read_file(path: str) -> bytes:
    """The bytes of the scene file at ``path`` (SceneError: one line, for a
    missing file, a folder, no permission, any other OS error)."""
    try:
        with open(path, "rb") as file:
            return file.read()
    except FileNotFoundError:
        raise SceneError(path, "no such file") from None
    except IsADirectoryError:
        raise SceneError(path, "is a folder, not a scene file") from None
    except PermissionError:
        raise SceneError(path, "permission denied") from None
    except OSError as error:
        raise SceneError(path, error.strerror or str(error)) from None


# `_fast_json`'s answer when json must parse the file (`_exact_json`).
_UNDECIDED = object()


def _fast_json(data: bytes) -> Any:
    """The JSON document in ``data`` parsed by orjson (2.2-2.5 times faster
    than json on explicit arrays, docs/speed.md, "Forty-second round"), or
    `_UNDECIDED` where json must parse it: whatever orjson refuses (invalid
    JSON, text that is not UTF-8, NaN, Infinity or a number that overflows
    to one, nesting deeper than its limit), and a document with a duplicate
    key, which orjson would take silently (its last value).

    Without escapes of the form \\uXXXX, each colon of the text is a key's
    or a character of a string, so a document has no duplicate key when
    the text holds as many colons as its parsed keys and strings do
    (`_colons`): a pair lost to a duplicate takes its colons with it.  The
    count skips the rows of explicit arrays; a string or key there (nowhere
    in the format) leaves it short, and json decides."""
    if b"\\u" in data:         # (an escape might be a colon)
        return _UNDECIDED
    try:
        document = orjson.loads(data)
        colons = _colons(document)
    except (orjson.JSONDecodeError, RecursionError):
        return _UNDECIDED
    return document if colons == data.count(b":") else _UNDECIDED


def _colons(value) -> int:
    """The colons of a parsed JSON value as its text (without escapes) holds
    them: one per key, and those in its keys and strings, through objects
    and the lists whose first item is an object or a string."""
    if isinstance(value, str):
        return value.count(":")
    if isinstance(value, dict):
        return sum(1 + key.count(":") + _colons(item) for key, item in value.items())
    if isinstance(value, list) and value and isinstance(value[0], (dict, str)):
        return sum(_colons(item) for item in value)
    return 0


def _exact_json(data: bytes, path: str) -> Any:
    """The JSON document in ``data`` as json parses text read from a file
    (UTF-8, universal newlines), with its errors as one-line SceneErrors:
    not UTF-8, invalid JSON with its line and column, NaN and infinities
    (`_reject_constant`), duplicate keys (`_no_duplicate_keys`), nesting
    too deep."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SceneError(path, f"not UTF-8 text (byte {error.start})") from None
    if "\r" in text:           # (as a file opened as text reads it)
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    try:
        return json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_no_duplicate_keys)
    except json.JSONDecodeError as error:
        raise SceneError(path, f"invalid JSON at line {error.lineno} column {error.colno}: {error.msg}") from None
    except ValueError as error:   # from the hooks above
        raise SceneError(path, f"invalid JSON: {error}") from None
    except RecursionError:
        raise SceneError(path, "invalid JSON: nested too deeply") from None


#: The files `load_scene` reads as scenes (and `scene_files` finds in folders).
SCENE_SUFFIXES = (".json",) + gltf.SUFFIXES


def is_scene_file(name: str) -> bool:
    """Whether a file name has a scene suffix (`SCENE_SUFFIXES`, any case, as
    `load_scene` reads them)."""
    return name.lower().endswith(SCENE_SUFFIXES)


def folder_scene_files(folder: str | os.PathLike) -> list[str]:
    """The scene files of one folder (`is_scene_file`), sorted by name."""
    folder = os.fspath(folder)
    names = sorted(name for name in os.listdir(folder) if is_scene_file(name))
    return [os.path.join(folder, name) for name in names if os.path.isfile(os.path.join(folder, name))]


def scene_files(paths) -> list[str]:
    """The scene files named by command-line PATHs: a file as given, a folder's
    ``*.json``, ``*.gltf`` and ``*.glb`` files sorted by name; each file once,
    in the order found.

    Raises FileNotFoundError (one line) for a path that does not exist and
    ValueError when the paths hold no scene file at all.
    """
    found: dict[str, None] = {}
    for path in map(os.fspath, paths):
        if os.path.isdir(path):
            found.update((file, None) for file in folder_scene_files(path))
        elif os.path.isfile(path):
            found[path] = None
        else:
            raise FileNotFoundError(f"{path}: no such scene file or folder")
    if not found:
        raise ValueError("no scene files in " + ", ".join(map(os.fspath, paths)))
    return list(found)


def load_scene(source: str | os.PathLike | dict | Scene) -> Scene:
    """Load and validate a scene: a JSON file path, a glTF file path (``.gltf`` or
    ``.glb``, `softras.scene.gltf`), a dict, or a Scene (returned as is).

    Raises :class:`SceneError` (one line, starting with the place) for any problem.
    """
    if isinstance(source, Scene):
        return source
    if isinstance(source, dict):
        return scene_from_dict(source)
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if path.lower().endswith(gltf.SUFFIXES):         # a glTF file is a whole scene (docs/gltf.md)
            return gltf.load_gltf_scene(path)
        with collector_paused():
            raw = _read_file(path)
            data = _fast_json(raw)
            exact = data is _UNDECIDED or not isinstance(data, dict)
            if exact:
                data = _exact_json(raw, path)
            if not isinstance(data, dict):
                raise SceneError(path, f"the top level must be a JSON object, got {type_name(data)}")
            base_dir = os.path.dirname(os.path.abspath(path))
            try:
                scene = scene_from_dict(data, source=path, base_dir=base_dir)
            except SceneError:
                if exact:
                    raise
                # orjson reads an integer beyond 64 bits as a float, json as
                # an int: the error is json's document's.
                data = _exact_json(raw, path)
                scene = scene_from_dict(data, source=path, base_dir=base_dir)
            # (The document freed while the collector is off: alive as it
            # is switched on again, its lists were the next collection's.)
            del data
        return scene
    raise SceneError("scene", f"expected a file path, a dict or a Scene, got {type(source).__name__}")


@contextlib.contextmanager
def collector_paused():
    """Python's cyclic garbage collector off for the block (as it was
    before afterwards).  A scene file's arrays parse into one list per
    vertex and per triangle (100k containers for a 24k-triangle mesh), each
    of which counts towards the collector's next run; in a process holding
    many objects (after renders, with glref's and numba's) those runs
    traversed them all, again and again: load_scene of the bench's 24k
    grid took 98-105 ms there against 44 ms in a fresh process
    (docs/speed.md, thirty-fifth round).  The parsed document holds no
    cycles: refcounting frees it."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
