"""The scene model: what a loaded scene is (the records both renderers draw).

Scene, Camera, Mesh, Material, Texture, Light, Draw and Displacement are frozen
dataclasses whose arrays are read-only; `softras.scene.parse.load_scene` builds
them from a scene file (docs/scene_format.md).  Coordinate conventions: matrices
are float64 (4, 4) in the column-vector convention, clip = projection @ view @
world @ [x, y, z, 1]; colours are straight RGBA in [0, 1]; texture rows run from
v = 0 (row 0) down.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np

from softras.scene import meshes, texels


FORMAT_VERSION = 1
MAX_SIDE = 16384                   # pixels per side
MAX_PIXELS = 64 * 1024 * 1024      # width * height
MAX_NODE_DEPTH = 64
MAX_TEXELS = 64 * 1024 * 1024      # texels of one texture's level 0 (image or procedural)

PROJECTIONS = ("perspective", "orthographic", "frustum")
PRIMITIVES = ("triangles", "lines")
SHADINGS = ("unlit", "flat", "gouraud", "phong")
DEPTH_FUNCTIONS = ("never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always")
CULL_MODES = ("none", "back", "front")
BLEND_MODES = ("none", "over", "over_straight", "add", "subtract", "reverse_subtract", "min", "max")
LIGHT_TYPES = ("point", "directional")
WRAP_MODES = ("repeat", "clamp_to_edge", "mirrored_repeat")
MIN_FILTERS = ("nearest", "linear", "nearest_mipmap_nearest", "linear_mipmap_nearest",
               "nearest_mipmap_linear", "linear_mipmap_linear")
MIPMAP_FILTERS = MIN_FILTERS[2:]
MAG_FILTERS = ("nearest", "linear")
PROCEDURAL_TEXTURES = ("checker", "gradient", "noise", "bumps")

DEFAULT_TOLERANCE = {"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99}
# Top-level "framebuffer": the colour buffer both renderers draw into.
FRAMEBUFFERS = ("rgba8", "rgba32f")
# Top-level "render_order": the order both renderers draw in (see ordered_draws).
RENDER_ORDERS = ("scene", "opaque_then_sorted")
# Top-level "front_face": the winding in window space that makes a triangle
# front-facing (glFrontFace: GL_CCW, the default, or GL_CW).
FRONT_FACES = ("ccw", "cw")


class SceneError(ValueError):
    """Bad scene input.

    ``str(e)`` is ONE line that starts with the place, e.g.
    ``'nodes[2].mesh.indices[5]: index 9 out of range for 8 positions'`` or
    ``'scene.json: invalid JSON at line 3 column 5: ...'``.  The parts are
    also available as ``e.place`` and ``e.reason``.
    """

    def __init__(self, place: str, reason: str):
        # One line even when a key holds a newline or another control character.
        self.place = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(place))
        place = self.place
        self.reason = " ".join(str(reason).split())   # one line
        super().__init__(f"{place}: {self.reason}")


# --------------------------------------------------------------------------- model


@dataclass(frozen=True, eq=False)
class Camera:
    view: np.ndarray          # (4, 4) float64, world -> eye
    projection: np.ndarray    # (4, 4) float64, eye -> clip (z_ndc in [-1, 1])
    kind: str                 # "perspective" | "orthographic" | "frustum" | "matrix"


@dataclass(frozen=True, eq=False)
class Mesh:
    primitive: str             # "triangles" | "lines"
    positions: np.ndarray      # (N, 3) float64, model space
    indices: np.ndarray        # (M, 3) int64 for triangles, (M, 2) for lines
    colors: np.ndarray | None  # (N, 4) float64 RGBA (RGB input gets alpha 1)
    normals: np.ndarray | None  # (N, 3) float64, model space
    uvs: np.ndarray | None     # (N, 2) float64, v = 0 at the image top
    # (N, 4) float64 tangent frames a file gives (glTF's TANGENT, converted to
    # softras's handedness), used instead of computed ones; None: computed.
    given_tangents: np.ndarray | None = None

    @functools.cached_property
    def tangents(self) -> np.ndarray:
        """(N, 4) float64 per-vertex tangent frames for normal and bump mapping:
        xyz = tangent along +s (model space), w = handedness +-1, the bitangent
        ``w cross(N, T)`` along +t: ``given_tangents`` when the file gave
        them, else `softras.scene.meshes.vertex_tangents` (unit, orthogonal to
        the normal), computed once, on first use.  Read by both renderers."""
        if self.given_tangents is not None:
            return self.given_tangents
        return _readonly(meshes.vertex_tangents(self.positions, self.normals, self.uvs, self.indices))


@dataclass(frozen=True, eq=False)
class Material:
    color: np.ndarray         # (4,) float64 straight RGBA, default (1, 1, 1, 1)
    texture: str | None       # name in Scene.textures
    shading: str              # "unlit" | "flat" | "gouraud" | "phong"
    ambient: float
    diffuse: float
    specular: float
    shininess: float
    normal_map: str | None = None    # texture name: tangent-space normals, rgb = (n + 1) / 2 (phong only)
    bump_map: str | None = None      # texture name: height in the red channel (phong only)
    bump_scale: float = 1.0          # bump strength (height units per texel, see softras.pipeline.fragment)
    displacement: "Displacement | None" = None  # already applied to Draw.mesh by the loader
    # Alpha test (glTF's alphaMode MASK): a fragment whose final alpha (vertex x
    # material x texel, before blending) is below this is discarded; None = no test.
    alpha_cutoff: float | None = None

    def line_problems(self) -> list[str]:
        """What of this material a line draw cannot have (softras draws lines
        unlit and untextured): its maps, its shading if not unlit, its alpha
        test.  Empty for a material lines can use."""
        problems = [key for key in ("texture", "normal_map", "bump_map") if getattr(self, key) is not None]
        problems += [f"{self.shading} shading"] if self.shading != "unlit" else []
        return problems + (["alpha_cutoff"] if self.alpha_cutoff is not None else [])


@dataclass(frozen=True, eq=False)
class Displacement:
    texture: str              # name in Scene.textures: height in the red channel
    scale: float              # model-space distance along the normal for height 1


@dataclass(frozen=True, eq=False)
class Texture:
    name: str
    image: str | None         # absolute path of the image file; None for a procedural texture
    wrap_s: str
    wrap_t: str
    min_filter: str
    mag_filter: str
    max_anisotropy: float
    procedural: str | None = None             # "checker" | "gradient" | "noise"
    size: tuple[int, int] | None = None       # (width, height) of a procedural texture
    params: dict = field(default_factory=dict)  # its parameters, defaults filled in
    # An image texture's level 0, straight RGBA (H, W, 4) uint8, row 0 = v 0:
    # decoded once by the loader (which must decode it to check the file).
    decoded: np.ndarray | None = field(default=None, repr=False)

    @property
    def mipmapped(self) -> bool:
        """Whether the min filter reads mip levels (else only level 0 is used)."""
        return self.min_filter in MIPMAP_FILTERS

    @functools.cached_property
    def levels(self) -> tuple[np.ndarray, ...]:
        """The premultiplied mip chain, level 0 down to 1x1, each (H_l, W_l, 4)
        uint8, row 0 = v 0 (`softras.scene.texels.mip_chain`: llvmpipe's
        glGenerateMipmap).  softras samples it; glref uploads level 0 and
        has GL generate the rest.  Decoded and built once, on first use."""
        chain = texels.mip_chain(texels.source_texels(self), premultiply=True)
        return tuple(_readonly(level) for level in chain)


@dataclass(frozen=True, eq=False)
class Light:
    type: str                        # "point" | "directional"
    position: np.ndarray | None      # (3,) world space, point lights
    direction: np.ndarray | None     # (3,) world space, the way the light travels
    color: np.ndarray                # (3,) linear RGB, >= 0


@dataclass(frozen=True, eq=False)
class Draw:
    path: str                 # "nodes[0].children[1]"
    name: str
    world: np.ndarray         # (4, 4) float64 model -> world = parent.world @ local
    mesh: Mesh
    material: Material
    depth_test: str | None    # None = depth test disabled
    depth_write: bool
    cull: str                 # "none" | "back" | "front" (front face: Scene.front_face)
    blend: str


@dataclass(frozen=True, eq=False)
class Scene:
    width: int
    height: int
    background: np.ndarray    # (4,) float64 straight RGBA in [0, 1]
    samples: int              # 1 or 4
    camera: Camera
    textures: dict[str, Texture]
    lights: tuple[Light, ...]
    draws: tuple[Draw, ...]   # depth-first, parents before children, list order
    tolerance: dict           # threshold (int, /255), max_bad_fraction, min_ssim
    source: str               # file path or "<dict>"
    description: str = ""
    framebuffer: str = "rgba8"          # "rgba8" | "rgba32f" (see FRAMEBUFFERS)
    render_order: str = "scene"         # "scene" | "opaque_then_sorted" (see ordered_draws)
    front_face: str = "ccw"             # "ccw" | "cw": the front winding in window space (FRONT_FACES)
    declares_tolerance: bool = False    # the scene file (or dict) gave "tolerance" itself, not the defaults


def _readonly(array: np.ndarray | None) -> np.ndarray | None:
    if array is not None:
        array.setflags(write=False)
    return array




def ordered_draws(scene: Scene) -> tuple[Draw, ...]:
    """The draws in the order both renderers issue them (``scene.render_order``).

    "scene": ``scene.draws`` as they are (GL's draw-call order).
    "opaque_then_sorted" (the lecture's order for transparency): first every
    opaque draw (``blend == "none"``) in scene order, then the transparent
    ones back to front -- decreasing view-space distance ``-z_eye`` of the
    centre of their mesh's model-space bounding box, ties kept in scene
    order -- each with depth writes off (depth read-only: still tested
    against the opaque surfaces, but transparent surfaces do not hide each
    other).  Sorting is per draw, not per triangle: within a draw primitives
    still blend in index order.
    """
    if getattr(scene, "render_order", "scene") == "scene":     # (or a Scene-like object without one)
        return scene.draws
    opaque = [draw for draw in scene.draws if draw.blend == "none"]
    transparent = [draw for draw in scene.draws if draw.blend != "none"]

    def distance(draw: Draw) -> float:
        positions = draw.mesh.positions
        centre = (positions.min(axis=0) + positions.max(axis=0)) / 2 if len(positions) else np.zeros(3)
        eye = scene.camera.view @ draw.world @ np.append(centre, 1.0)     # eye space, looking down -z
        return -eye[2]

    back_to_front = sorted(transparent, key=distance, reverse=True)
    return tuple(opaque) + tuple(replace(draw, depth_write=False) for draw in back_to_front)
