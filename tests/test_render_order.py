"""The lecture's render order (scene key "render_order": "opaque_then_sorted")
in both renderers: softras.scene.ordered_draws, and pixels computed by hand."""

import json
from pathlib import Path

import numpy as np
import pytest

import softras
from softras.scene import ordered_draws

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "transparent_over_opaque.json"
QUAD = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "indices": [[0, 1, 2], [0, 2, 3]]}


def _layer(name, z, color, blend="over"):
    """A full-screen quad at depth z (orthographic camera looking down -z from z = 5)."""
    return {"name": name, "translate": [0, 0, z], "mesh": QUAD, "material": {"color": color},
            "blend": blend, "depth_test": "less", "depth_write": True}


def _stack(order):
    """Transparent red (near, z = 1) and blue (far, z = -1) listed BEFORE the
    opaque green wall (z = -2) they lie in front of."""
    return {"softras_scene": 1, "width": 4, "height": 4, "background": [0, 0, 0, 1], "render_order": order,
            "framebuffer": "rgba32f",
            "camera": {"projection": "orthographic", "left": -1, "right": 1, "bottom": -1, "top": 1,
                       "near": 0.5, "far": 10, "eye": [0, 0, 5], "target": [0, 0, 0]},
            "nodes": [_layer("red_near", 1, [1, 0, 0, 0.5]), _layer("blue_far", -1, [0, 0, 1, 0.25]),
                      _layer("green_wall", -2, [0, 1, 0, 1], blend="none")]}


def test_ordered_draws_puts_opaque_first_then_transparent_back_to_front_read_only():
    scene = softras.load_scene(_stack("opaque_then_sorted"))
    draws = ordered_draws(scene)
    assert [d.name for d in draws] == ["green_wall", "blue_far", "red_near"]
    assert [d.depth_write for d in draws] == [True, False, False]
    # The scene itself is untouched; "scene" order is the file's.
    assert [d.depth_write for d in scene.draws] == [True, True, True]
    assert [d.name for d in ordered_draws(softras.load_scene(_stack("scene")))] == \
        ["red_near", "blue_far", "green_wall"]


def test_ties_keep_scene_order():
    data = _stack("opaque_then_sorted")
    data["nodes"] = [_layer("a", 0, [1, 0, 0, 0.5]), _layer("b", 0, [0, 1, 0, 0.5]), _layer("c", 0, [0, 0, 1, 0.5])]
    assert [d.name for d in ordered_draws(softras.load_scene(data))] == ["a", "b", "c"]


def test_bad_render_order_is_a_scene_error():
    with pytest.raises(softras.SceneError, match="render_order"):
        softras.load_scene(_stack("front_to_back"))


@pytest.mark.parametrize("backend", ["soft", pytest.param("gl", marks=pytest.mark.gl)])
def test_sorted_order_composites_back_to_front_by_hand(backend):
    """Premultiplied over, back to front, on the opaque green wall:
    blue (0, 0, 0.25, 0.25) over green (0, 1, 0, 1) = (0, 0.75, 0.25, 1);
    red (0.5, 0, 0, 0.5) over that = (0.5, 0.375, 0.125, 1)."""
    image = softras.render(_stack("opaque_then_sorted"), backend=backend)
    np.testing.assert_allclose(image, np.broadcast_to([0.5, 0.375, 0.125, 1.0], image.shape), atol=1e-6)


@pytest.mark.parametrize("backend", ["soft", pytest.param("gl", marks=pytest.mark.gl)])
def test_scene_order_lets_the_near_glass_hide_everything(backend):
    """Scene order with depth writes: red is drawn first over the black
    background and writes depth 1 in front of the rest, so blue and the wall
    fail the depth test: (0.5, 0, 0, 0.5) over (0, 0, 0, 1) = (0.5, 0, 0, 1)."""
    image = softras.render(_stack("scene"), backend=backend)
    np.testing.assert_allclose(image, np.broadcast_to([0.5, 0.0, 0.0, 1.0], image.shape), atol=1e-6)


@pytest.mark.gl
@pytest.mark.parametrize("order", ["opaque_then_sorted", "scene"])
def test_transparent_over_opaque_scene_matches_gl(order):
    """The conformance scene in both orders: RGBA8 within 1/255 (GL rounds
    each blend's result in its own fixed point), rgba32f within float32
    rounding; and the order makes a visible difference."""
    data = json.loads(SCENE.read_text())
    data["render_order"] = order
    scene = softras.load_scene(dict(data))
    soft, gl = softras.render(scene), softras.render(scene, backend="gl")
    assert np.abs(soft.astype(int) - gl.astype(int)).max() <= 1
    soft32 = softras.render(scene, framebuffer="rgba32f")
    gl32 = softras.render(scene, backend="gl", framebuffer="rgba32f")
    assert np.abs(soft32 - gl32).max() < 2e-5
    other = dict(data, render_order="scene" if order != "scene" else "opaque_then_sorted")
    assert (np.abs(softras.render(other).astype(int) - soft.astype(int)).max(axis=2) > 8).sum() > 1000
