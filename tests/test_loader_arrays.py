"""The loader's whole-array fast path for explicit mesh arrays
(`softras.scene.parse._fast_array`, `_fast_indices`) against its
element-by-element checks: for any input, both give the same arrays or the
same one-line error.

The fast path returns None on anything it does not take (the element code
then decides), so the property is checked by loading every generated mesh
twice, once with the fast path switched off.  Its speed is a figure of
``softras bench`` (the loader line), not a test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softras.scene import SceneError, parse


def _load(mesh: dict):
    """The loaded mesh's arrays, or the error message."""
    data = {"softras_scene": 1, "width": 4, "height": 4, "nodes": [{"mesh": mesh}]}
    try:
        loaded = parse.scene_from_dict(data).draws[0].mesh
    except SceneError as error:
        return str(error)
    return tuple(None if a is None else (a.dtype.str, a.shape, a.tobytes())
                 for a in (loaded.positions, loaded.indices, loaded.colors, loaded.normals, loaded.uvs))


def _both(mesh: dict, monkeypatch):
    fast = _load(mesh)
    with monkeypatch.context() as patch:
        patch.setattr(parse, "_fast_array", lambda *args: None)
        patch.setattr(parse, "_fast_indices", lambda *args: None)
        slow = _load(mesh)
    return fast, slow


# Mostly valid numbers, now and then something the format refuses or takes
# only on the element path.
_odd = st.sampled_from([True, False, None, "1", math.nan, math.inf, -math.inf, 10 ** 400, 2 ** 63, -1,
                        1.0000000000000002, -0.0, [1.0], (0.5,), np.float32(0.25), np.int64(1)])
_number = st.one_of(st.floats(-4, 4, allow_nan=False), st.integers(-3, 3))
_entry = st.one_of(_number, _number, _number, _number, _odd)


def _rows(width, entry=_entry, min_size=1, max_size=6):
    row = st.lists(entry, min_size=width, max_size=width)
    odd_row = st.one_of(st.lists(entry, min_size=0, max_size=5), st.just("row"), st.tuples(entry, entry, entry))
    return st.lists(st.one_of(row, row, row, row, odd_row), min_size=min_size, max_size=max_size)


_unit = st.one_of(st.floats(0, 1), st.sampled_from([0, 1]), _odd)
_index = st.one_of(st.integers(0, 5), st.integers(0, 5), st.integers(-2, 8), _odd)


@st.composite
def meshes(draw):
    mesh = {"positions": draw(_rows(3, max_size=6))}
    if draw(st.booleans()):
        if draw(st.booleans()):
            mesh["indices"] = draw(_rows(3, _index, max_size=4))
        else:
            mesh["indices"] = draw(st.lists(_index, min_size=0, max_size=12))
    if draw(st.booleans()):
        mesh["colors"] = draw(_rows(draw(st.sampled_from([3, 4])), _unit))
    if draw(st.booleans()):
        mesh["uvs"] = draw(_rows(2))
    return mesh


@settings(max_examples=600, derandomize=True, database=None, deadline=None,
          suppress_health_check=list(HealthCheck))
@given(meshes())
def test_fast_and_element_paths_agree(monkeypatch, mesh):
    fast, slow = _both(mesh, monkeypatch)
    assert fast == slow, mesh


def test_plain_meshes_take_the_fast_path(monkeypatch):
    """The property above is not vacuous: every array of a plain mesh is
    taken by the fast path, and an odd one (a tuple row) by the element path."""
    taken = []
    for name in ("_fast_array", "_fast_indices"):
        def spy(*args, _real=getattr(parse, name)):
            result = _real(*args)
            taken.append(result is not None)
            return result
        monkeypatch.setattr(parse, name, spy)
    mesh = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1.5, 0]], "indices": [[0, 1, 2]],
            "colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "uvs": [[0, 0], [1, 0], [0, 1]]}
    assert not isinstance(_load(mesh), str)
    assert taken == [True] * 4
    taken.clear()
    assert not isinstance(_load(dict(mesh, positions=[[0, 0, 0], (1, 0, 0), [0, 1.5, 0]])), str)
    assert taken == [False, True, True, True]


@pytest.mark.parametrize("mesh, message", [
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 3]]},
     "nodes[0].mesh.indices[0]: index 3 out of range for 3 positions"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1, True]]},
     "nodes[0].mesh.positions[2][2]: expected a number, got a boolean"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [0, 1, 2.0]},
     "nodes[0].mesh.indices[2]: expected an integer index, got 2.0"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "colors": [[1, 1, 1], [1, 1, 1], [1, 1, 1.0000000000000002]]},
     "nodes[0].mesh.colors[2][2]: 1.0000000000000002 is out of range [0, 1]"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 10 ** 400]]},
     "nodes[0].mesh.positions[2][2]: number too large"),
])
def test_errors_name_the_element(mesh, message):
    """Whole-array checks still report the first bad element's place (a
    value just above 1 is shown as it is, not rounded to "1")."""
    assert _load(mesh) == message


def test_numpy_arrays_from_python_load_like_lists():
    """A dict built in Python may hold numpy arrays: float32 positions and
    uint16 indices load to the same float64 / int64 arrays as lists."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    indices = np.array([[0, 1, 2]], np.uint16)
    assert _load({"positions": positions, "indices": indices}) == _load(
        {"positions": positions.tolist(), "indices": indices.tolist()})
    assert _load({"positions": positions, "indices": np.array([[0, 1, 3]], np.uint16)}) == (
        "nodes[0].mesh.indices[0]: index 3 out of range for 3 positions")


def test_loading_a_file_pauses_the_garbage_collector_and_restores_it(tmp_path, monkeypatch):
    """A scene file is parsed and built with the cyclic garbage collector
    off (`parse.collector_paused`: its ~100k lists for a 24k-triangle mesh
    would start dozens of collections), and the collector is left as it was:
    on, off, or on after a file that fails to load."""
    import gc
    import json

    from softras import bench
    path = tmp_path / "grid.json"
    path.write_text(json.dumps(bench.explicit_grid_scene(110)))
    broken = tmp_path / "broken.json"
    broken.write_text('{"softras_scene": 1, "width": 4, "height": 4, "nodes": [{"mesh": {"positions": [[0, 0]]}}]}')
    runs, seen = [], []

    def count(phase, info):
        if phase == "start":
            runs.append(info["generation"])

    def build(data, **options):         # the parsed document on its way to the scene
        seen.append((gc.isenabled(), len(runs)))
        scene = real_build(data, **options)
        seen.append((gc.isenabled(), len(runs)))
        return scene
    real_build = parse.scene_from_dict
    monkeypatch.setattr(parse, "scene_from_dict", build)
    gc.callbacks.append(count)
    try:
        gc.collect()
        runs.clear()
        assert len(parse.load_scene(path).draws[0].mesh.indices) == 24200
        assert seen == [(False, 0), (False, 0)] and gc.isenabled()
        gc.disable()
        parse.load_scene(path)
        assert not gc.isenabled()
        gc.enable()
        with pytest.raises(SceneError):
            parse.load_scene(broken)
        assert gc.isenabled()
    finally:
        gc.callbacks.remove(count)
        gc.enable()
