"""Blending: premultiplied "over" and the other equations, in both renderers."""

import numpy as np
import pytest

import softras


def _closure_scene(samples=1):
    # Lecture example: red with alpha 0.5 over red with alpha 0.5 over nothing.
    # Premultiplied, one layer is (0.5, 0, 0, 0.5); over: src + (1 - 0.5) dst,
    # so two layers give (0.5 + 0.25, 0, 0, 0.5 + 0.25) = (0.75, 0, 0, 0.75).
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "indices": [[0, 1, 2], [0, 2, 3]]}
    layer = {"mesh": square, "material": {"color": [1, 0, 0, 0.5]}, "blend": "over", "depth_test": False}
    return {"softras_scene": 1, "width": 8, "height": 8, "samples": samples, "background": [0, 0, 0, 0],
            "nodes": [dict(layer, name="first"), dict(layer, name="second")]}


@pytest.mark.parametrize("precision", ["gl", "exact"])
@pytest.mark.parametrize("samples", [1, 4])
def test_closure_example_soft(precision, samples):
    image = softras.render(_closure_scene(samples), precision=precision)
    np.testing.assert_allclose(image / 255.0, np.broadcast_to([0.75, 0, 0, 0.75], image.shape), atol=1 / 255)


@pytest.mark.gl
@pytest.mark.parametrize("samples", [1, 4])
def test_closure_example_gl(samples):
    image = softras.render(_closure_scene(samples), backend="gl")
    np.testing.assert_allclose(image / 255.0, np.broadcast_to([0.75, 0, 0, 0.75], image.shape), atol=1 / 255)


def test_gl_precision_rounds_after_every_blend():
    # 0.5 premultiplied red stores as 128/255 after the first layer (rint(127.5)
    # = 128, half to even); the second gives 0.5 + 0.5 * 128/255 = 191.5/255 ->
    # 192 (even).  In exact float64 the result is 0.75 * 255 = 191.25 -> 191.
    gl = softras.render(_closure_scene(), precision="gl")
    exact = softras.render(_closure_scene(), precision="exact")
    assert gl[0, 0, 0] == 192 and exact[0, 0, 0] == 191
