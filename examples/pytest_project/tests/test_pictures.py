"""This project's pictures, checked with softras's pytest plugin: no conftest.py needed.

- ``softras_check(scene)``: softras and OpenGL render the scene and must agree
  as ``softras conformance`` judges it (the test fails with the reasons);
- ``softras_golden(scene)`` and ``@pytest.mark.softras_golden`` (the test
  returns its scene): the scene against its golden image in tests/golden/;
  ``pytest --softras-update-golden`` writes them.
"""

from pathlib import Path

import pytest

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def test_triangle_conforms(softras_check):
    result = softras_check(SCENES / "triangle.json")  # a FAIL has failed the test here
    assert result.verdict in ("pass", "quality_warning")


def test_scene_built_in_code_conforms(softras_check):
    fan = {
        "softras_scene": 1, "width": 20, "height": 20, "background": [0, 0, 0, 1],
        "camera": {"projection": "orthographic", "left": 0, "right": 20, "bottom": 0, "top": 20,
                   "near": -1, "far": 1},
        "nodes": [{"name": "fan", "mesh": {
            "positions": [[10, 10, 0], [19, 10, 0], [10, 19, 0], [1, 10, 0], [10, 1, 0]],
            "indices": [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]],
            "colors": [[1, 1, 1], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]]}}],
    }
    softras_check(fan, name="fan")


@pytest.mark.parametrize("name", ["triangle", "quads"])
def test_golden_image(softras_golden, name):
    softras_golden(SCENES / f"{name}.json")


@pytest.mark.softras_golden
def test_quads_golden_marker():
    return SCENES / "quads.json"
