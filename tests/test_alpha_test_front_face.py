"""The alpha test (material ``alpha_cutoff``) and the scene's ``front_face``.

- ``alpha_cutoff``: softras's stages discard a fragment whose final alpha is
  below the cutoff (`softras.pipeline.fragment.alpha_test`), glref's shaders
  ``discard`` it; the pictures must be identical, byte for byte, with 1 and 4
  samples, unlit and lit, and a discarded fragment writes no depth (the
  surface behind it shows).  The compiled path draws them (its bytes equal
  the stages': tests/test_fastpath.py), so here it is the one checked
  against GL.
- ``front_face``: "cw" makes clockwise triangles front-facing for culling in
  the stages, the kernels and GL alike; flat shading keeps its face normal
  from the vertex order (as GL's geometry shader computes it).
"""

from __future__ import annotations

import numpy as np
import pytest

import softras
from softras.kernels import draw as kernels
from softras.scene import SceneError, scene_from_dict

QUAD = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
QUAD_UV = [[0, 1], [1, 1], [1, 0], [0, 0]]


def masked_scene(*, samples=1, shading="unlit", cutoff=0.5, filters="linear"):
    """A red quad behind a masked, checker-textured quad whose texel alpha runs
    from 0.2 to 0.9 across the cell edges (linear magnification), tilted so the
    cut follows slanted lines."""
    front = {"name": "masked", "rotate": [25, 0.3, 1, 0.2], "translate": [0, 0, 0.5],
             "mesh": {"positions": QUAD, "indices": [[0, 1, 2], [0, 2, 3]], "uvs": QUAD_UV,
                      "normals": [[0, 0, 1]] * 4,
                      "colors": [[1, 1, 1, 1], [0.5, 1, 0.5, 1], [1, 1, 1, 1], [0.6, 0.6, 1, 1]]},
             "material": {"texture": "holes", "alpha_cutoff": cutoff, "shading": shading}}
    return {
        "softras_scene": 1, "width": 48, "height": 40, "samples": samples, "background": [0, 0, 0.2, 1],
        "camera": {"projection": "perspective", "fov_y": 50, "near": 0.5, "far": 10, "eye": [0, 0, 3.2]},
        "lights": [{"type": "directional", "direction": [-0.3, -0.4, -1]}],
        "textures": {"holes": {"procedural": "checker", "size": [8, 8], "squares": 4,
                               "color0": [1, 0.8, 0.2, 0.2], "color1": [0.9, 0.9, 0.9, 0.9],
                               "min_filter": filters, "mag_filter": filters}},
        "nodes": [{"name": "behind", "translate": [0, 0, -0.5], "scale": [1.5, 1.5, 1],
                   "mesh": {"positions": QUAD, "indices": [[0, 1, 2], [0, 2, 3]]},
                   "material": {"color": [0.9, 0.1, 0.1, 1]}},
                  front],
    }


def both(data):
    scene = scene_from_dict(data)
    return scene, softras.render(scene), softras.render(scene, backend="gl")


@pytest.mark.gl
@pytest.mark.parametrize("samples, shading", [(1, "unlit"), (4, "unlit"), (1, "phong"), (4, "gouraud")])
def test_masked_material_soft_equals_gl(samples, shading):
    scene, soft, gl = both(masked_scene(samples=samples, shading=shading))
    assert kernels.unsupported(scene, precision="gl", clipping=None) is None       # (the compiled path)
    np.testing.assert_array_equal(soft, gl)
    # The test did something: some of the quad is cut away (the red quad and
    # the background show through), some is kept.
    red = (soft[..., 0] > 200) & (soft[..., 1] < 60)
    assert 50 < red.sum() < 0.6 * red.size
    kept = softras.render(scene_from_dict({**masked_scene(samples=samples, shading=shading)}),
                          fast_path=False)
    np.testing.assert_array_equal(kept, soft)


@pytest.mark.gl
def test_discarded_fragments_write_no_depth():
    """The masked quad is drawn FIRST, the red one behind it second: where the
    mask discards, the red quad must win the depth test."""
    data = masked_scene(filters="nearest")
    data["nodes"] = data["nodes"][::-1]
    scene, soft, gl = both(data)
    np.testing.assert_array_equal(soft, gl)
    assert ((soft[..., 0] > 200) & (soft[..., 1] < 60)).sum() > 50


@pytest.mark.gl
@pytest.mark.parametrize("cutoff, expect", [(0.0, "all kept"), (1.0, "all cut")])
def test_cutoff_extremes(cutoff, expect):
    data = masked_scene(cutoff=cutoff, filters="nearest")
    scene, soft, gl = both(data)
    np.testing.assert_array_equal(soft, gl)
    unmasked = softras.render(scene_from_dict({**data, "nodes": [data["nodes"][0]]}))
    if expect == "all cut":           # alpha <= 0.9 < 1: every fragment of the masked quad goes
        np.testing.assert_array_equal(soft, unmasked)
    else:
        assert not np.array_equal(soft, unmasked)


def triangles(front_face, cull, shading="unlit"):
    """Two triangles, the left counter-clockwise, the right clockwise on screen."""
    return {"softras_scene": 1, "width": 40, "height": 24, "front_face": front_face,
            "camera": {"projection": "orthographic", "left": -2, "right": 2, "bottom": -1.2, "top": 1.2,
                       "near": -5, "far": 5},
            "lights": [{"type": "directional", "direction": [0, 0, -1]}],
            "nodes": [{"mesh": {"positions": [[-1.8, -1, 0], [-0.2, -1, 0], [-1, 1, 0],
                                              [0.2, -1, 0], [1, 1, 0], [1.8, -1, 0]],
                                "colors": [[1, 0, 0, 1]] * 3 + [[0, 1, 0, 1]] * 3},
                       "material": {"shading": shading, "ambient": 0.3}, "cull": cull}]}


@pytest.mark.gl
@pytest.mark.parametrize("cull", ["none", "back", "front"])
@pytest.mark.parametrize("shading", ["unlit", "flat"])
def test_front_face_cw_soft_equals_gl(cull, shading):
    scene, soft, gl = both(triangles("cw", cull, shading))
    np.testing.assert_array_equal(soft, gl)
    np.testing.assert_array_equal(softras.render(scene, fast_path=False), soft)
    left, right = soft[12, 10], soft[12, 30]
    drawn = {"none": (True, True), "back": (False, True), "front": (True, False)}[cull]
    assert (left[:3].any(), right[:3].any()) == drawn, (left, right)


def test_front_face_cw_is_the_other_cull():
    """cw + cull back culls what ccw + cull front culls, in the stages and the kernels."""
    for fast in (True, False):
        a = softras.render(scene_from_dict(triangles("cw", "back")), fast_path=fast)
        b = softras.render(scene_from_dict(triangles("ccw", "front")), fast_path=fast)
        np.testing.assert_array_equal(a, b)
        assert a[12, 10, :3].sum() == 0 and a[12, 30, 1] == 255


@pytest.mark.parametrize("patch, place, reason", [
    ({"front_face": "clockwise"}, "front_face", "expected one of ccw, cw"),
    ({"nodes": [{"mesh": {"positions": QUAD[:3]}, "material": {"alpha_cutoff": 1.5}}]},
     "nodes[0].material.alpha_cutoff", "out of range"),
    ({"nodes": [{"mesh": {"positions": QUAD[:2], "primitive": "lines"}, "material": {"alpha_cutoff": 0.5}}]},
     "nodes[0].material", "this material has alpha_cutoff"),
])
def test_bad_keys(patch, place, reason):
    with pytest.raises(SceneError) as caught:
        scene_from_dict({"softras_scene": 1, "width": 4, "height": 4, **patch})
    assert str(caught.value).startswith(place + ":") and reason in str(caught.value), caught.value


def test_defaults():
    scene = scene_from_dict({"softras_scene": 1, "width": 4, "height": 4,
                             "nodes": [{"mesh": {"positions": QUAD[:3]}, "material": {"alpha_cutoff": None}}]})
    assert scene.front_face == "ccw" and scene.draws[0].material.alpha_cutoff is None


@pytest.mark.gl
def test_alpha_equal_to_the_cutoff_is_kept():
    """glTF: alpha >= cutoff is kept (GL's shader discards alpha < cutoff)."""
    data = {"softras_scene": 1, "width": 16, "height": 16,
            "nodes": [{"mesh": {"positions": QUAD, "indices": [[0, 1, 2], [0, 2, 3]]},
                       "material": {"color": [1, 0.5, 0.25, 0.5], "alpha_cutoff": 0.5}}]}
    scene, soft, gl = both(data)
    np.testing.assert_array_equal(soft, gl)
    assert tuple(soft[8, 8]) == (128, 64, 32, 128)
