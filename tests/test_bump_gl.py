"""Normal, bump and displacement mapping: softras (gl precision) against glref.

The conformance scenes bump_mapped_plane and displaced_grid run in
test_scenes.py; these add what they do not cover: a normal-map PNG, curved
tangent frames (a sphere), a mirroring world matrix (handedness), the float
("SoA") sampling path (mirrored_repeat) and displacement under Gouraud
shading.  Bar: at most 3/255 on >= 99.5 % of pixels and
SSIM >= 0.98; measured (llvmpipe 22.3.6) far inside it (see each test).
"""

from __future__ import annotations

import numpy as np
import pytest

import softras
from conftest import write_failure_images

TOLERANCE = {"threshold": 3, "max_bad_fraction": 0.005, "min_ssim": 0.98}
LIGHTS = [{"type": "point", "position": [-2, 2, 3], "color": [1, 0.95, 0.9]},
          {"type": "directional", "direction": [1, -0.3, -0.4], "color": [0.25, 0.3, 0.5]}]
CAMERA = {"projection": "perspective", "fov_y": 45, "near": 0.1, "far": 100, "eye": [0, 0.5, 4.5], "target": [0, 0, 0]}


def normal_map_png(path, size=64, cells=4):
    """A tangent-space normal map of round bumps (green along +t, i.e. down the
    image), written as an RGB PNG: rgb = round(255 (n + 1) / 2)."""
    from PIL import Image
    f = np.mod((np.arange(size) + 0.5) / size * cells, 1.0) - 0.5
    fx, fy = np.meshgrid(f, f)
    r = np.hypot(fx, fy)
    slope = np.where(r < 0.4, 2.5, 0.0)
    n = np.stack([-slope * fx, -slope * fy, np.ones_like(fx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    Image.fromarray(np.rint(255 * (n + 1) / 2).astype(np.uint8)).save(path)


def compare_backends(scene_dict, tmp_path, base_dir):
    scene = softras.scene.scene_from_dict(scene_dict, base_dir=str(base_dir))
    soft = softras.render(scene, precision="gl")
    gl = softras.render(scene, backend="gl")
    result = softras.compare(soft, gl, **TOLERANCE)
    if not result.passed:
        write_failure_images(tmp_path / "images", soft=soft, gl=gl, diff=result.diff_image)
    assert result.passed, f"{result.summary()} (images in {tmp_path})"
    return result, soft


def node(name, mesh, material, **extra):
    return {"name": name, "mesh": mesh, "material": material, **extra}


@pytest.mark.gl
def test_normal_map_sphere_and_mirrored_plane_match_gl(tmp_path):
    normal_map_png(tmp_path / "normals.png")
    phong = {"shading": "phong", "normal_map": "n", "color": [0.8, 0.7, 0.6, 1], "specular": 0.5, "shininess": 20}
    scene = {"softras_scene": 1, "width": 128, "height": 96, "camera": CAMERA, "lights": LIGHTS,
             "textures": {"n": {"image": "normals.png", "min_filter": "linear_mipmap_linear"}},
             "nodes": [node("sphere", {"procedural": "sphere", "segments": 32, "rings": 16}, phong,
                            translate=[-1.1, 0, 0], cull="back"),
                       # scale -1 in x mirrors the plane: the bitangent must flip with it.
                       node("mirrored", {"procedural": "grid", "cols": 2, "rows": 2, "size": [1.8, 1.8]}, phong,
                            translate=[1.1, 0, 0], rotate=[-30, 1, 0, 0], scale=[-1, 1, 1])]}
    result, _ = compare_backends(scene, tmp_path, tmp_path)
    assert result.max_diff <= 3 and result.bad_pixels == 0        # measured: 0 pixels differ


@pytest.mark.gl
@pytest.mark.parametrize("backend", ["soft", "gl"])
def test_mirrored_world_matrix_gives_the_mirror_image(tmp_path, backend):
    """A bump-mapped plane drawn with scale (-1, 1, 1) under lights mirrored in
    x, seen from a camera on the mirror plane, is the mirror image of the
    plain one: only if the bitangent flips with det(world) < 0
    (``vertex.world_tangents``, lit.vert's u_handedness)."""
    mirror = np.diag([-1.0, 1, 1])

    def scene(sign):
        lights = [dict(light) for light in LIGHTS]
        for light in lights:
            key = "position" if "position" in light else "direction"
            light[key] = list(mirror @ light[key]) if sign < 0 else light[key]
        material = {"shading": "phong", "bump_map": "h", "bump_scale": 8, "shininess": 20}
        return {"softras_scene": 1, "width": 128, "height": 96, "camera": CAMERA, "lights": lights,
                "textures": {"h": {"procedural": "bumps", "size": [64, 64], "cells": 3}},
                "nodes": [node("plane", {"procedural": "grid", "cols": 2, "rows": 2, "size": [2.4, 2.4]}, material,
                               rotate=[-35, 1, 0, 0], scale=[sign, 1, 1])]}

    plain, mirrored = (softras.render(softras.load_scene(scene(sign)), backend=backend) for sign in (1, -1))
    diff = np.abs(plain.astype(int) - mirrored[:, ::-1].astype(int)).max(axis=-1)
    # Edge pixels may differ (the fill rule is not mirror-symmetric); the lit relief may not.
    assert np.mean(diff > 2) < 0.01, (np.mean(diff > 2), diff.max())
    assert plain[..., :3].max() > 100                              # something is lit


@pytest.mark.gl
def test_bump_map_float_path_and_scale_sign_match_gl(tmp_path):
    # mirrored_repeat goes through llvmpipe's float (SoA) sampler; a negative
    # bump_scale turns the bumps into dents.
    textures = {"h": {"procedural": "bumps", "size": [64, 32], "cells": 3, "wrap_s": "mirrored_repeat",
                      "wrap_t": "mirrored_repeat", "min_filter": "linear_mipmap_linear"}}
    material = {"shading": "phong", "bump_map": "h", "color": [0.7, 0.8, 0.9, 1], "shininess": 40}
    scene = {"softras_scene": 1, "width": 128, "height": 96, "camera": CAMERA, "lights": LIGHTS,
             "textures": textures,
             "nodes": [node("sphere", {"procedural": "sphere", "segments": 32, "rings": 16},
                            dict(material, bump_scale=6), translate=[-1.1, 0, 0]),
                       node("plane", {"procedural": "grid", "cols": 3, "rows": 3, "size": [2, 2]},
                            dict(material, bump_scale=-6), translate=[1.1, 0, 0], rotate=[-50, 1, 0, 0])]}
    result, _ = compare_backends(scene, tmp_path, tmp_path)
    assert result.max_diff <= 3 and result.bad_pixels == 0


@pytest.mark.gl
def test_displaced_sphere_gouraud_matches_gl(tmp_path):
    textures = {"h": {"procedural": "bumps", "size": [64, 32], "cells": 4}}
    material = {"shading": "gouraud", "color": [0.9, 0.6, 0.4, 1], "displacement": {"texture": "h", "scale": 0.25}}
    scene = {"softras_scene": 1, "width": 128, "height": 96, "camera": CAMERA, "lights": LIGHTS,
             "textures": textures,
             "nodes": [node("sphere", {"procedural": "sphere", "segments": 48, "rings": 24}, material, cull="back")]}
    result, _ = compare_backends(scene, tmp_path, tmp_path)
    assert result.max_diff <= 3 and result.bad_pixels == 0
