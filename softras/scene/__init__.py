"""The scene layer: what both renderers draw, and the files it comes from.

- `model`: the loaded scene's records (Scene, Draw, Mesh, Material, Texture,
  Light, Camera) and the format's enumerations and limits;
- `parse`: `load_scene`, the scene format's reader and validator
  (docs/scene_format.md);
- `transforms`: GL's matrix helpers (gluPerspective, glFrustum, glOrtho,
  gluLookAt, node transforms);
- `meshes`: procedural meshes (grid, sphere, fan) and vertex tangents;
- `meshfiles`: mesh files (PLY, OBJ, NPZ, glTF/GLB) for ``"mesh": {"file": ...}``;
- `gltf`: a glTF file (.gltf / .glb) as a whole scene (docs/gltf.md), on
  `gltf_files` (the glTF container) and `fileio` (the file readers' checks);
- `texels`: texture images, procedural textures, premultiplication and
  llvmpipe's mipmap generation;
- `displace`: displacement mapping, applied to meshes when a scene is loaded;
- `imageio`: PNG reading and atomic writing.

This layer imports nothing else of softras; every other layer and glref build
on it.
"""

from softras.scene.model import (BLEND_MODES, CULL_MODES, DEFAULT_TOLERANCE, DEPTH_FUNCTIONS, FORMAT_VERSION,
                                 FRAMEBUFFERS, FRONT_FACES, LIGHT_TYPES, MAG_FILTERS, MAX_NODE_DEPTH, MAX_PIXELS, MAX_SIDE,
                                 MAX_TEXELS, MIN_FILTERS, MIPMAP_FILTERS, PRIMITIVES, PROCEDURAL_TEXTURES,
                                 PROJECTIONS, RENDER_ORDERS, SHADINGS, WRAP_MODES, Camera, Displacement, Draw,
                                 Light, Material, Mesh, Scene, SceneError, Texture, ordered_draws)
from softras.scene.parse import load_scene, scene_files, scene_from_dict
from softras.scene.transforms import (cross3, frustum_matrix, look_at_matrix, orthographic_matrix,
                                      perspective_matrix, rotate_matrix, scale_matrix, translate_matrix)

__all__ = ["BLEND_MODES", "CULL_MODES", "DEFAULT_TOLERANCE", "DEPTH_FUNCTIONS", "FORMAT_VERSION", "FRAMEBUFFERS",
           "FRONT_FACES", "LIGHT_TYPES", "MAG_FILTERS", "MAX_NODE_DEPTH", "MAX_PIXELS", "MAX_SIDE", "MAX_TEXELS", "MIN_FILTERS",
           "MIPMAP_FILTERS", "PRIMITIVES", "PROCEDURAL_TEXTURES", "PROJECTIONS", "RENDER_ORDERS", "SHADINGS",
           "WRAP_MODES", "Camera", "Displacement", "Draw", "Light", "Material", "Mesh", "Scene", "SceneError",
           "Texture", "ordered_draws", "load_scene", "scene_files", "scene_from_dict", "cross3",
           "frustum_matrix", "look_at_matrix", "orthographic_matrix", "perspective_matrix", "rotate_matrix",
           "scale_matrix", "translate_matrix"]
