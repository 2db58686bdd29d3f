"""A glTF 2.0 file (.gltf or .glb) loaded as a whole scene (docs/gltf.md).

`softras.load_scene("model.glb")` comes here (`load_gltf_scene`) and gets
the same `softras.scene.Scene` record a JSON scene gives, so both renderers
draw it as any scene.  The container (buffers, accessors, images) is read by
`softras.scene.gltf_files`; this module maps glTF's scene onto the scene
model:

- the default scene (``scene``, else ``scenes[0]``), its nodes depth-first,
  each parent before its children, in list order; a node's world matrix is
  ``parent world @ local`` (``matrix`` or T · R · S); every triangle
  primitive of a node's mesh is one `Draw`, in that order;
- a node whose world matrix has a negative determinant draws its
  triangles with the index order reversed (glTF 2.0 section 3.7.4: such a
  node's triangles are clockwise), so front faces stay front faces; normals
  go through the inverse transpose of the world matrix as always;
- the first camera met in that traversal (perspective or orthographic), its
  view the inverse of the camera node's world matrix; without one, a
  framing camera (:func:`framing_camera`);
- materials (:func:`_Builder.material`): base colour factor and texture,
  COLOR_0, alpha modes (OPAQUE: alpha forced to 1; MASK: the scene format's
  ``alpha_cutoff``; BLEND: premultiplied "over", drawn opaque first then
  sorted back to front), ``doubleSided`` (cull none, else cull back),
  KHR_materials_unlit, and for lit materials metallic-roughness mapped to
  Blinn-Phong (:func:`blinn_phong_from_pbr`) under the file's directional
  KHR_lights_punctual lights or the default rig (:func:`default_rig`);
- everything else that would change the picture is refused with one
  `SceneError` line naming the file and the glTF place:
  ``model.gltf: meshes[0].primitives[0].extensions.KHR_draco_mesh_compression: not supported``.

Spaces: glTF is right-handed, +Y up, cameras look down their local −Z: the
scene model's conventions, so matrices are used as they are (glTF stores
them column-major; :func:`softras.scene.gltf_files.node_matrix` transposes).
glTF's TEXCOORD_0 has v = 0 at the top of the image, as the scene format.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os

import numpy as np

from softras.scene import gltf_files, meshes, meshfiles, texels
from softras.scene.fileio import BadFile, check_counts
from softras.scene.gltf_files import number, numbers
from softras.scene.meshes import MeshArrays
from softras.scene.model import (DEFAULT_TOLERANCE, MAX_SIDE, MAX_TEXELS, Camera, Draw, Light,
                                 Material, Scene, SceneError, Texture, _readonly)
from softras.scene.transforms import look_at_matrix, orthographic_matrix, perspective_matrix

SUFFIXES = (".gltf", ".glb")
#: Extensions this loader implements (KHR_lights_punctual: directional lights only).
EXTENSIONS = ("KHR_materials_unlit", "KHR_lights_punctual")
#: Picture height; the width is ``round(HEIGHT · aspect)`` (the camera's aspectRatio, xmag / ymag, or 1).
HEIGHT = 256
#: The framing camera's vertical field of view, degrees.
FRAMING_FOV_Y = 45.0
#: Ambient factor of every lit material (glTF has no ambient light).
AMBIENT = 0.2
#: The default light rig: one white directional light of this intensity,
#: travelling along this direction in EYE space (from the upper left, behind
#: the viewer, into the scene).
RIG_DIRECTION = (0.4, -0.5, -1.0)
RIG_INTENSITY = 0.8
#: Shininess range of the roughness mapping.
SHININESS_RANGE = (1.0, 4096.0)

_WRAP = {10497: "repeat", 33071: "clamp_to_edge", 33648: "mirrored_repeat"}
_MAG = {9728: "nearest", 9729: "linear"}
_MIN = {9728: "nearest", 9729: "linear", 9984: "nearest_mipmap_nearest", 9985: "linear_mipmap_nearest",
        9986: "nearest_mipmap_linear", 9987: "linear_mipmap_linear"}
_DEFAULT_MAG, _DEFAULT_MIN = "linear", "linear_mipmap_linear"


def load_gltf_scene(path: str) -> Scene:
    """The scene in a .gltf / .glb file (``path`` as given, for messages).
    Raises `SceneError` with one line ``PATH: glTF place: reason``."""
    if not os.path.exists(path):
        raise SceneError(path, "no such file")
    if os.path.isdir(path):
        raise SceneError(path, "is a folder, not a scene file")
    try:
        return _Builder(gltf_files.GltfFile(path), path).scene()
    except BadFile as error:
        raise SceneError(path, str(error)) from None
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
        raise SceneError(path, f"malformed glTF ({type(error).__name__}: {error})") from None
    except PermissionError:
        raise SceneError(path, "permission denied") from None
    except OSError as error:
        raise SceneError(path, error.strerror or str(error)) from None
    except MemoryError:
        raise SceneError(path, "too large to read into memory") from None


# --------------------------------------------------------------------------- the documented mappings


def blinn_phong_from_pbr(base_color: np.ndarray, metallic: float, roughness: float) -> dict:
    """Blinn-Phong factors of the scene format for a metallic-roughness material:

    - ambient = :data:`AMBIENT`;
    - diffuse = 1 − metallic (metals have no diffuse term);
    - specular = mix(0.04, luminance(baseColorFactor.rgb), metallic): the
      dielectric Fresnel F0 0.04, for metals the base colour's luminance
      0.2126 R + 0.7152 G + 0.0722 B (the scene format's specular is one
      number: a metal's highlight is not tinted, except by its texture);
    - shininess = 2 / α² − 2 with α = roughness² (the Blinn-Phong exponent
      whose lobe matches a GGX lobe of that roughness), clamped to
      :data:`SHININESS_RANGE` (roughness 0 gives the top of the range).
    """
    luminance = float(np.dot([0.2126, 0.7152, 0.0722], base_color[:3]))
    alpha = roughness * roughness
    shininess = SHININESS_RANGE[1] if alpha == 0 else 2.0 / (alpha * alpha) - 2.0
    return {"ambient": AMBIENT, "diffuse": 1.0 - metallic,
            "specular": 0.04 * (1.0 - metallic) + luminance * metallic,
            "shininess": float(np.clip(shininess, *SHININESS_RANGE))}


def picture_size(aspect: float | None) -> tuple[int, int]:
    """(width, height): :data:`HEIGHT` rows, ``round(HEIGHT · aspect)`` columns (1..MAX_SIDE); aspect None: square."""
    if aspect is None:
        return HEIGHT, HEIGHT
    return int(min(MAX_SIDE, max(1, round(HEIGHT * aspect)))), HEIGHT


def framing_camera(lo: np.ndarray, hi: np.ndarray) -> Camera:
    """The camera of a file without one: it looks down −Z at the bounding
    sphere of the drawn geometry (world space: centre c = the middle of the
    axis-aligned box ``lo``..``hi``, radius r = half its diagonal, 1 if that
    is 0) from the distance d = r / sin(fov_y / 2) at which the sphere just
    fits a fov_y = :data:`FRAMING_FOV_Y` view (the picture is square, so it
    fits across as well): eye = c + (0, 0, d), up +Y, near = (d − r) / 2,
    far = 2 (d + r)."""
    centre = (lo + hi) / 2.0
    radius = float(np.linalg.norm(hi - lo)) / 2.0 or 1.0
    distance = radius / math.sin(math.radians(FRAMING_FOV_Y) / 2.0)
    view = look_at_matrix(centre + (0.0, 0.0, distance), centre, (0.0, 1.0, 0.0))
    projection = perspective_matrix(FRAMING_FOV_Y, 1.0, (distance - radius) / 2.0, 2.0 * (distance + radius))
    return Camera(_readonly(view), _readonly(projection), "perspective")


def default_rig(view: np.ndarray) -> tuple[Light, ...]:
    """The lights of a file without KHR_lights_punctual lights: one
    directional light of colour :data:`RIG_INTENSITY` (white), travelling
    along :data:`RIG_DIRECTION` in eye space, i.e. fixed to the camera."""
    eye_direction = np.array(RIG_DIRECTION) / np.linalg.norm(RIG_DIRECTION)
    direction = np.linalg.inv(view)[:3, :3] @ eye_direction            # eye -> world (a direction)
    return (Light("directional", None, _readonly(direction), _readonly(np.full(3, RIG_INTENSITY))),)


# --------------------------------------------------------------------------- checks


def _refuse_extensions(entry: dict, where: str | None, allowed=()) -> dict:
    """The entry's ``extensions`` object; any extension not in ``allowed`` is refused."""
    place = "extensions" if where is None else f"{where}.extensions"        # None: the document's own
    extensions = entry.get("extensions", {})
    if not isinstance(extensions, dict):
        raise BadFile(f"{place}: expected an object")
    for name in extensions:
        if name not in allowed:
            raise BadFile(f"{place}.{name}: not supported")
    return extensions


# --------------------------------------------------------------------------- the builder


class _Builder:
    def __init__(self, file: gltf_files.GltfFile, path: str):
        self.file, self.doc, self.path = file, file.document, path
        self.textures: dict[str, Texture] = {}
        self.images: dict[int, np.ndarray] = {}
        self.meshes: dict[tuple, object] = {}

    def scene(self) -> Scene:
        doc = self.doc
        version = doc.get("asset", {}).get("version") if isinstance(doc.get("asset"), dict) else None
        if not isinstance(version, str) or not version.startswith("2."):
            raise BadFile(f"asset.version: {version!r} (only glTF 2.x is read)")
        for i, name in enumerate(doc.get("extensionsRequired", [])):
            if name not in EXTENSIONS:
                raise BadFile(f"extensionsRequired[{i}]: {name}: not supported")
        _refuse_extensions(doc, None, EXTENSIONS)
        if not doc.get("scenes"):
            raise BadFile("scenes: none (a glTF scene file needs a scene to draw)")
        index = doc.get("scene", 0)
        scene = self.file.item("scenes", index, "scene")
        _refuse_extensions(scene, f"scenes[{index}]")
        nodes = self.file.walk(scene.get("nodes", []), f"scenes[{index}].nodes")
        draws, camera, lights, budget = [], None, [], [meshes.MAX_TRIANGLES]
        for n, world in nodes:
            node = self.doc["nodes"][n]
            if "camera" in node and camera is None:
                camera = self.camera(node["camera"], world, f"nodes[{n}].camera")
            light = _refuse_extensions(node, f"nodes[{n}]", ("KHR_lights_punctual",)).get("KHR_lights_punctual")
            if light is not None:
                lights.append(self.light(light, world, f"nodes[{n}].extensions.KHR_lights_punctual"))
            if "mesh" in node:
                draws.extend(self.node_draws(n, node, world, budget))
        if not draws:
            raise BadFile(f"scenes[{index}]: draws nothing (no mesh primitives in its nodes)")
        if camera is None:
            camera, size = framing_camera(*_world_bounds(draws)), picture_size(None)
        else:
            camera, size = camera
        lit = any(draw.material.shading != "unlit" for draw in draws)
        lights = tuple(lights) if lights or not lit else default_rig(camera.view)
        blended = any(draw.blend != "none" for draw in draws)
        return Scene(width=size[0], height=size[1], background=_readonly(np.array([0.0, 0.0, 0.0, 1.0])),
                     samples=1, camera=camera, textures=self.textures, lights=lights, draws=tuple(draws),
                     tolerance=dict(DEFAULT_TOLERANCE), source=self.path,
                     description=f"glTF scene {os.path.basename(self.path)}",
                     render_order="opaque_then_sorted" if blended else "scene")

    # ----------------------------------------------------------------- cameras and lights

    def camera(self, index, world: np.ndarray, where: str) -> tuple[Camera, tuple[int, int]]:
        """(Camera, picture size) of cameras[index] on a node with this world matrix."""
        camera = self.file.item("cameras", index, where)
        place = f"cameras[{index}]"
        _refuse_extensions(camera, place)
        if abs(np.linalg.det(world)) < 1e-300:
            raise BadFile(f"{where}: the camera node's world matrix is not invertible")
        view = np.linalg.inv(world)
        kind = camera.get("type")
        if kind == "perspective":
            p = camera["perspective"]
            fov = number(p["yfov"], f"{place}.perspective.yfov", 0.0, math.pi)
            near = number(p["znear"], f"{place}.perspective.znear", 0.0)
            if fov in (0.0, math.pi) or near == 0:
                raise BadFile(f"{place}.perspective: yfov must be in (0, π) and znear positive")
            aspect = number(p["aspectRatio"], f"{place}.perspective.aspectRatio", 0.0) if "aspectRatio" in p else None
            if aspect == 0:
                raise BadFile(f"{place}.perspective.aspectRatio: must be positive")
            size = picture_size(aspect)
            aspect = aspect or size[0] / size[1]
            if "zfar" in p:
                far = number(p["zfar"], f"{place}.perspective.zfar", near)
                if far == near:
                    raise BadFile(f"{place}.perspective.zfar: must be greater than znear")
                return Camera(_readonly(view), _readonly(perspective_matrix(math.degrees(fov), aspect, near, far)),
                              "perspective"), size
            f = 1.0 / math.tan(fov / 2.0)                   # glTF's infinite projection (section 3.10.3)
            infinite = np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0], [0, 0, -1, -2 * near], [0, 0, -1, 0]], float)
            return Camera(_readonly(view), _readonly(infinite), "matrix"), size
        if kind == "orthographic":
            o = camera["orthographic"]
            xmag, ymag = (number(o[k], f"{place}.orthographic.{k}") for k in ("xmag", "ymag"))
            near = number(o["znear"], f"{place}.orthographic.znear", 0.0)
            far = number(o["zfar"], f"{place}.orthographic.zfar", near)
            if xmag == 0 or ymag == 0 or far == near:
                raise BadFile(f"{place}.orthographic: xmag and ymag must not be 0, zfar must exceed znear")
            projection = orthographic_matrix(-xmag, xmag, -ymag, ymag, near, far)
            return Camera(_readonly(view), _readonly(projection), "orthographic"), picture_size(abs(xmag / ymag))
        raise BadFile(f"{place}.type: {kind!r} (expected perspective or orthographic)")

    def light(self, entry, world: np.ndarray, where: str) -> Light:
        """A node's KHR_lights_punctual light: directional lights only (colour ×
        intensity, along the node's −Z); point and spot lights fall off with
        distance, which the scene model's lights do not, and are refused."""
        index = entry["light"] if isinstance(entry, dict) else None
        table = self.doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(table):
            raise BadFile(f"{where}.light: light index {index!r} out of range ({len(table)} lights)")
        light, place = table[index], f"extensions.KHR_lights_punctual.lights[{index}]"
        if light.get("type") != "directional":
            raise BadFile(f"{place}.type: {light.get('type')!r} lights are not supported (directional only: "
                          f"the scene model's lights have no distance falloff)")
        color = numbers(light.get("color", [1, 1, 1]), 3, f"{place}.color", 0.0)
        intensity = number(light.get("intensity", 1.0), f"{place}.intensity", 0.0)
        direction = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
        if not np.any(direction):
            raise BadFile(f"{where}: the light node's matrix maps its −Z axis to zero")
        return Light("directional", None, _readonly(direction), _readonly(color * intensity))

    # ----------------------------------------------------------------- meshes and materials

    def node_draws(self, n: int, node: dict, world: np.ndarray, budget: list[int]) -> list[Draw]:
        m = node["mesh"]
        mesh = self.file.item("meshes", m, f"nodes[{n}].mesh")
        _refuse_extensions(mesh, f"meshes[{m}]")
        if "weights" in mesh:
            raise BadFile(f"meshes[{m}].weights: morph target weights are not supported")
        mirrored = bool(np.linalg.det(world[:3, :3]) < 0)
        draws = []
        for p in range(len(mesh.get("primitives", []))):
            place = f"meshes[{m}].primitives[{p}]"
            primitive = self.file.primitive_entry(m, p, place)
            _refuse_extensions(primitive, place)
            if "targets" in primitive:
                raise BadFile(f"{place}.targets: morph targets are not supported")
            vertices, triangles = self.file.primitive_counts(m, p)
            check_counts(vertices, triangles, budget[0], f"{place}: ")
            budget[0] -= triangles
            material, blend, cull, opaque = self.material(primitive.get("material"), place)
            arrays = self.primitive_mesh(m, p, mirrored, opaque, material.shading != "unlit",
                                         material.normal_map is not None)
            if arrays.uvs is None and (material.texture is not None or material.normal_map is not None):
                what = "baseColorTexture" if material.texture is not None else "normalTexture"
                raise BadFile(f"{place}: its material has a {what} but it has no TEXCOORD_0")
            draws.append(Draw(path=f"nodes[{n}].mesh.primitives[{p}]", name=str(node.get("name", f"nodes[{n}]")),
                              world=_readonly(world.copy()), mesh=arrays, material=material,
                              depth_test="less", depth_write=True, cull=cull, blend=blend))
        return draws

    def primitive_mesh(self, m: int, p: int, mirrored: bool, opaque: bool, lit: bool, mapped: bool = False):
        """The scene Mesh of a primitive (cached): model space; a primitive
        without NORMAL drawn lit gets flat normals (each triangle its own
        three vertices with its face normal, as glTF asks); indices reversed
        for a mirroring node; vertex alpha forced to 1 for OPAQUE materials;
        ``mapped`` (a normal map): the file's TANGENT, where it has one and
        NORMAL too (glTF ignores the tangents of flat normals), as
        ``Mesh.given_tangents`` with the handedness negated: glTF's bitangent
        points up the image, softras's down it (the normal map's green is
        flipped to match, `texture`)."""
        key = (m, p, mirrored, opaque, lit, mapped)
        if key not in self.meshes:
            where = f"meshes[{m}].primitives[{p}]"
            positions, indices, colors, normals, uvs = self.file.primitive(m, p)
            given = self.file.primitive_tangents(m, p) if mapped and lit and normals is not None else None
            if lit and normals is None:
                corners = indices.reshape(-1)
                positions, colors, uvs = (None if a is None else a[corners] for a in (positions, colors, uvs))
                triangles = positions.reshape(-1, 3, 3)
                face = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
                normals = np.repeat(face, 3, axis=0)
                indices = np.arange(len(positions), dtype=np.int64).reshape(-1, 3)
                if len(face) and not np.any(face, axis=1).all():
                    normals[~np.repeat(np.any(face, axis=1), 3)] = (0.0, 0.0, 1.0)   # degenerate: never drawn
            if mirrored:
                indices = indices[:, ::-1]
            if colors is not None and opaque:
                colors = colors.copy()
                colors[:, 3] = 1.0
            try:
                mesh = meshfiles.checked_mesh(MeshArrays(positions, indices, colors, normals, uvs),
                                              meshes.MAX_TRIANGLES)
            except BadFile as error:
                raise BadFile(f"{where}: {error}") from None
            if given is not None:
                frames = np.column_stack([given[:, :3], np.where(given[:, 3] < 0, 1.0, -1.0)])
                mesh = dataclasses.replace(mesh, given_tangents=_readonly(frames))
            self.meshes[key] = mesh
        return self.meshes[key]

    def material(self, index, where: str) -> tuple[Material, str, str, bool]:
        """(Material, blend, cull, opaque) of materials[index], or glTF's default
        material when the primitive has none (index None)."""
        entry, place = ({}, f"{where} (default material)") if index is None else \
            (self.file.item("materials", index, f"{where}.material"), f"materials[{index}]")
        extensions = _refuse_extensions(entry, place, ("KHR_materials_unlit",))
        for key in ("occlusionTexture", "emissiveTexture"):
            if key in entry:
                raise BadFile(f"{place}.{key}: not supported")
        if any(numbers(entry.get("emissiveFactor", [0, 0, 0]), 3, f"{place}.emissiveFactor", 0.0, 1.0)):
            raise BadFile(f"{place}.emissiveFactor: not supported (only black)")
        pbr = entry.get("pbrMetallicRoughness", {})
        _refuse_extensions(pbr, f"{place}.pbrMetallicRoughness")
        if "metallicRoughnessTexture" in pbr:
            raise BadFile(f"{place}.pbrMetallicRoughness.metallicRoughnessTexture: not supported")
        color = numbers(pbr.get("baseColorFactor", [1, 1, 1, 1]), 4, f"{place}.pbrMetallicRoughness.baseColorFactor",
                         0.0, 1.0)
        metallic = number(pbr.get("metallicFactor", 1.0), f"{place}.pbrMetallicRoughness.metallicFactor", 0.0, 1.0)
        roughness = number(pbr.get("roughnessFactor", 1.0), f"{place}.pbrMetallicRoughness.roughnessFactor", 0.0, 1.0)
        mode = entry.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise BadFile(f"{place}.alphaMode: {mode!r} (expected OPAQUE, MASK or BLEND)")
        cutoff = None
        if mode == "MASK":
            cutoff = number(entry.get("alphaCutoff", 0.5), f"{place}.alphaCutoff", 0.0, 1.0)
        opaque = mode == "OPAQUE"
        if opaque:
            color[3] = 1.0
        texture = None
        if "baseColorTexture" in pbr:
            texture = self.texture(pbr["baseColorTexture"], f"{place}.pbrMetallicRoughness.baseColorTexture", opaque)
        double = entry.get("doubleSided", False)
        if not isinstance(double, bool):
            raise BadFile(f"{place}.doubleSided: expected true or false")
        unlit = "KHR_materials_unlit" in extensions
        normal_map = None
        if "normalTexture" in entry and not unlit:      # an unlit material has no lighting to perturb
            info = entry["normalTexture"]
            scale = number(info.get("scale", 1.0), f"{place}.normalTexture.scale") if isinstance(info, dict) else 1.0
            if scale != 1.0:
                raise BadFile(f"{place}.normalTexture.scale: {scale!r} not supported (only 1)")
            normal_map = self.texture(info, f"{place}.normalTexture", opaque=True, green_up=True)
        # (An unlit material carries the mapped factors too, unread.)
        material = Material(color=_readonly(color), texture=texture, shading="unlit" if unlit else "phong",
                            alpha_cutoff=cutoff, normal_map=normal_map,
                            **blinn_phong_from_pbr(color, metallic, roughness))
        return material, "over" if mode == "BLEND" else "none", "none" if double else "back", opaque

    def texture(self, info, where: str, opaque: bool, green_up: bool = False) -> str:
        """The scene texture name of a textureInfo (created once per texture and
        alpha handling: an OPAQUE material's copy has alpha 255). ``green_up``:
        a normalTexture, whose green channel is glTF's +Y, up the image
        (decreasing v); softras's normal maps have +Y along increasing t, down
        the image (docs/scene_format.md), so the copy has green 255 - G (the
        byte of -y: 2 (255 - G) / 255 - 1 = -(2 G / 255 - 1), exactly)."""
        if not isinstance(info, dict) or "index" not in info:
            raise BadFile(f"{where}: expected an object with an index")
        _refuse_extensions(info, where)
        if info.get("texCoord", 0) != 0:
            raise BadFile(f"{where}.texCoord: {info['texCoord']!r} not supported (only TEXCOORD_0)")
        index = info["index"]
        texture = self.file.item("textures", index, f"{where}.index")
        _refuse_extensions(texture, f"textures[{index}]")
        name = f"textures[{index}]" + (" (normals, green down)" if green_up else " (alpha 1)" if opaque else "")
        if name in self.textures:
            return name
        if "source" not in texture:
            raise BadFile(f"textures[{index}].source: missing (no image)")
        sampler = {}
        if "sampler" in texture:
            sampler = self.file.item("samplers", texture["sampler"], f"textures[{index}].sampler")
        place = f"samplers[{texture.get('sampler')}]"
        modes = {}
        for key, table, default in (("wrapS", _WRAP, "repeat"), ("wrapT", _WRAP, "repeat"),
                                    ("magFilter", _MAG, _DEFAULT_MAG), ("minFilter", _MIN, _DEFAULT_MIN)):
            if key in sampler and sampler[key] not in table:
                raise BadFile(f"{place}.{key}: {sampler[key]!r} is not a glTF value "
                              f"(one of {', '.join(map(str, table))})")
            modes[key] = table[sampler[key]] if key in sampler else default
        decoded = self.image(texture["source"], f"textures[{index}].source")
        if opaque or green_up:
            decoded = decoded.copy()                  # (the decoded image is shared)
        if opaque:
            decoded[..., 3] = 255
        if green_up:
            decoded[..., 1] = 255 - decoded[..., 1]
        self.textures[name] = Texture(name=name, image=None, wrap_s=modes["wrapS"], wrap_t=modes["wrapT"],
                                      min_filter=modes["minFilter"], mag_filter=modes["magFilter"],
                                      max_anisotropy=1.0, decoded=_readonly(decoded))
        return name

    def image(self, index, where: str) -> np.ndarray:
        """images[index] decoded: (H, W, 4) uint8 straight RGBA, row 0 = the image's top (v = 0)."""
        if index not in self.images:
            from PIL import Image, UnidentifiedImageError

            data = self.file.image_bytes(index, where)
            place = f"images[{index}]"
            try:
                with Image.open(io.BytesIO(data)) as image:
                    if image.format not in ("PNG", "JPEG"):
                        raise BadFile(f"{place}: a {image.format} image (glTF images are PNG or JPEG)")
                    self.images[index] = texels.checked_texels(image, MAX_SIDE, MAX_TEXELS)
            except texels.TooManyTexels as error:
                raise BadFile(f"{place}: {error}") from None
            except UnidentifiedImageError:
                raise BadFile(f"{place}: not a PNG or JPEG image") from None
            except (*texels.DECODE_ERRORS, Image.DecompressionBombError) as error:
                raise BadFile(f"{place}: cannot decode the image: {' '.join(str(error).split())}") from None
        return self.images[index]


def _world_bounds(draws) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (3,) corners of the world-space box around every drawn vertex."""
    boxes = []
    for draw in draws:
        world = draw.mesh.positions @ draw.world[:3, :3].T + draw.world[:3, 3]
        boxes += [world.min(axis=0), world.max(axis=0)]
    boxes = np.array(boxes)
    return boxes.min(axis=0), boxes.max(axis=0)
