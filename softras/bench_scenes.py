"""The scenes `softras.bench` measures, generated: vertex-coloured grids,
a trilinear floor, blended layers, a model of many parts, lit stand-ins
for scanned and textured models, and a wireframe.  Each function returns a
scene dict (docs/scene_format.md) of the size it is given."""

from __future__ import annotations

import math

import numpy as np


def grid_scene(cols: int, side: int, samples: int = 1) -> dict:
    """A perspective-tilted grid of 2*cols^2 vertex-coloured triangles, side^2 pixels."""
    return {
        "softras_scene": 1, "width": side, "height": side, "background": [0, 0, 0, 1], "samples": samples,
        "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100,
                   "eye": [0, 0, 2.6], "target": [0, 0, 0]},
        "nodes": [{"name": "grid", "rotate": [-30, 1, 0, 0],
                   "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [2.5, 2.5],
                            "corner_colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]}}],
    }


def floor_scene(side: int, anisotropy: float = 1) -> dict:
    """A checker floor (256^2 texels, linear_mipmap_linear) receding to the horizon: 2 triangles."""
    return {
        "softras_scene": 1, "width": side, "height": side, "background": [0.1, 0.1, 0.2, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 100,
                   "eye": [0, 1.0, 3], "target": [0, 0, -3]},
        "textures": {"checker": {"procedural": "checker", "size": [256, 256], "squares": 16,
                                 "color0": [0.9, 0.9, 0.85, 1], "color1": [0.15, 0.2, 0.6, 1],
                                 "min_filter": "linear_mipmap_linear", "mag_filter": "linear",
                                 "max_anisotropy": anisotropy}},
        "nodes": [{"name": "floor", "rotate": [-90, 1, 0, 0], "translate": [0, 0, -6],
                   "mesh": {"positions": [[-3, -12, 0], [3, -12, 0], [3, 12, 0], [-3, 12, 0]],
                            "indices": [[0, 1, 2], [0, 2, 3]],
                            "uvs": [[0, 8], [1.5, 8], [1.5, 0], [0, 0]]},
                   "material": {"texture": "checker"}}],
    }


def blended_scene(side: int, layers: int = 8, cols: int = 8, transparent: bool = False) -> dict:
    """``layers`` translucent tilted grids (2*cols^2 triangles each) blended "over", no depth test.

    With ``transparent`` the pass of a renderer's transparent objects
    instead: an opaque grid first (depth-tested, writing depth) slanting
    through the layers, then the layers depth-tested against it ("less")
    without writing depth, so that each is hidden where it lies behind
    the opaque one."""
    nodes = []
    if transparent:
        nodes.append({"name": "opaque", "rotate": [50, 0, 1, 0], "translate": [0, 0, -0.3],
                      "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [2.2, 2.2],
                               "corner_colors": [[0.8, 0.8, 0.7, 1], [0.3, 0.3, 0.3, 1], [0.5, 0.6, 0.7, 1],
                                                 [0.9, 0.5, 0.2, 1]]}})
    for k in range(layers):
        a = 0.25 + 0.5 * k / max(1, layers - 1)
        nodes.append({"name": f"layer{k}", "rotate": [-20 + 5 * k, 1, 0.3, 0], "translate": [0, 0, -0.1 * k],
                      "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [2.2, 2.2],
                               "corner_colors": [[1, 0, 0, a], [0, 1, 0, a], [0, 0, 1, a], [1, 1, 1, a]]},
                      "blend": "over", "depth_test": "less" if transparent else False,
                      "depth_write": False})
    return {"softras_scene": 1, "width": side, "height": side, "background": [0, 0, 0, 1],
            "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100,
                       "eye": [0, 0, 2.6], "target": [0, 0, 0]},
            "nodes": nodes}


def parts_scene(side: int, parts: int = 64, cols: int = 8, textured: bool = False) -> dict:
    """A stand-in for a model of many parts (a glTF file gives a draw per
    primitive): ``parts`` small opaque grids of 2*cols^2 triangles each, a
    draw each, tilted in a square array, depth-tested, each its own
    colour; with ``textured`` each part Phong-lit by a point light and
    sampling one shared checker texture (trilinear), as a textured model's
    parts share its material.  What it measures is the cost per draw."""
    n = math.ceil(math.sqrt(parts))                 # parts a row
    nodes = []
    for k in range(parts):
        colors = [[1, 0.2 + 0.1 * (k % 8), 0, 1], [0, 1, 0.1 * (k % 5), 1], [0, 0, 1, 1], [1, 1, 1, 1]]
        nodes.append({"name": f"part{k}", "rotate": [25 + 3 * (k % 7), 1, 0.4, 0],
                      "translate": [2.4 * (k % n - (n - 1) / 2), 2.4 * (k // n - (n - 1) / 2), 0],
                      "mesh": {"procedural": "grid", "cols": cols, "rows": cols, "size": [2, 2],
                               "corner_colors": colors}})
        if textured:
            nodes[-1]["material"] = {"shading": "phong", "texture": "checker"}
    scene = {"softras_scene": 1, "width": side, "height": side, "background": [0, 0, 0, 1],
             "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100,
                        "eye": [0, 0, 2.7 * n], "target": [0, 0, 0]},
             "nodes": nodes}
    if textured:
        scene["textures"] = {"checker": {"procedural": "checker", "size": [256, 256], "squares": 16,
                                         "min_filter": "linear_mipmap_linear", "mag_filter": "linear"}}
        scene["lights"] = [{"type": "point", "position": [3 * n, 3 * n, 4 * n], "color": [1, 1, 1]}]
    return scene


def lit_scene(side: int, shading: str, segments: int, rings: int, *, samples: int = 1,
              textured: bool = False, bumpy: bool = True, bump_map: bool = False) -> dict:
    """A stand-in for a real model: a sphere of 2 * segments * (rings - 1)
    triangles, lumpy like a scan (displaced along its normals by a noise
    height map) unless ``bumpy`` is False, Blinn-Phong lit with ``shading``
    by a point and a directional light, optionally checker-textured
    (trilinear) and bump-mapped (a trilinear noise height map, four taps a
    pixel), at ``samples`` samples a pixel."""
    material = {"shading": shading, "color": [0.85, 0.6, 0.4, 1], "ambient": 0.12, "diffuse": 0.8,
                "specular": 0.5, "shininess": 32}
    textures = {}
    if bumpy:
        textures["height"] = {"procedural": "noise", "size": [64, 64], "min_filter": "linear"}
        material["displacement"] = {"texture": "height", "scale": 0.08}
    if textured:
        textures["checker"] = {"procedural": "checker", "size": [256, 256], "squares": 16,
                               "min_filter": "linear_mipmap_linear", "mag_filter": "linear"}
        material["texture"] = "checker"
    if bump_map:
        textures["bumps"] = {"procedural": "noise", "size": [128, 128], "min_filter": "linear_mipmap_linear",
                             "mag_filter": "linear"}
        material.update(bump_map="bumps", bump_scale=6)
    return {"softras_scene": 1, "width": side, "height": side, "background": [0.05, 0.05, 0.08, 1],
            "samples": samples, "textures": textures,
            "camera": {"projection": "perspective", "fov_y": 40, "near": 0.5, "far": 20,
                       "eye": [0, 0.6, 3.4], "target": [0, 0, 0]},
            "lights": [{"type": "point", "position": [3, 3, 4], "color": [1, 1, 1]},
                       {"type": "directional", "direction": [-1, -0.2, -0.5], "color": [0.25, 0.3, 0.5]}],
            "nodes": [{"name": "model", "rotate": [20, 0, 1, 0],
                       "mesh": {"procedural": "sphere", "segments": segments, "rings": rings},
                       "material": material, "cull": "back"}]}


def lines_scene(side: int, cols: int = 64) -> dict:
    """A wireframe: the 2 * cols * (cols + 1) edges of a tilted cols x cols
    grid as a line mesh, vertex-coloured."""
    ticks = np.linspace(-1.2, 1.2, cols + 1)
    xs, ys = np.meshgrid(ticks, ticks)
    positions = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    index = np.arange(xs.size).reshape(cols + 1, cols + 1)
    edges = np.concatenate([np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], axis=1),
                            np.stack([index[:-1, :].ravel(), index[1:, :].ravel()], axis=1)])
    colors = np.stack([(xs.ravel() + 1.2) / 2.4, (ys.ravel() + 1.2) / 2.4, np.full(xs.size, 0.8)], axis=1)
    return {"softras_scene": 1, "width": side, "height": side, "background": [0, 0, 0, 1],
            "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100,
                       "eye": [0, 0, 2.6], "target": [0, 0, 0]},
            "nodes": [{"name": "wireframe", "rotate": [-30, 1, 0, 0],
                       "mesh": {"primitive": "lines", "positions": positions.round(6).tolist(),
                                "indices": edges.tolist(), "colors": colors.round(6).tolist()}}]}
