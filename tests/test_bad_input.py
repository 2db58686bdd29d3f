"""Bad input never costs data: one line, exit 2, nothing on disk lost or half-written.

Every kind of bad input -- malformed JSON, wrong types, NaN or infinite
numbers, indices out of range, unknown keys, missing or corrupt texture files,
undefined texture names, absurd sizes, an unwritable output path -- gives:

* from the command line: exit status 2, exactly one line on stderr
  (``softras: error: <place>: <reason>``), no traceback, and no output file
  created or changed (a pre-existing output survives byte for byte);
* from the API: the same message as a typed exception (``SceneError`` for the
  scene, ``ImageError`` for an output path).
"""

from __future__ import annotations

import json
import os
import struct
import tracemalloc
import zlib

import numpy as np
import pytest

import softras
from softras import cli
from softras.scene.imageio import ImageError, write_png_atomic
from softras.scene import SceneError

OLD_OUTPUT = b"previous output, must survive"


def triangle_scene(**top) -> dict:
    scene = {"softras_scene": 1, "width": 8, "height": 6,
             "nodes": [{"mesh": {"positions": [[-1, -1, 0], [1, -1, 0], [0, 1, 0]],
                                 "uvs": [[0, 0], [1, 0], [0, 1]]}}]}
    scene.update(top)
    return scene


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_textures(folder) -> None:
    """Broken texture files next to the scene."""
    from PIL import Image
    Image.new("RGBA", (16, 16), (1, 2, 3, 255)).save(folder / "good.png")
    good = (folder / "good.png").read_bytes()
    (folder / "truncated.png").write_bytes(good[: len(good) // 2])
    (folder / "text.png").write_text("I am not a PNG\n")
    header = struct.pack(">IIBBBBB", 60_000, 60_000, 8, 6, 0, 0, 0)      # 14 GB if decoded
    (folder / "bomb.png").write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + _png_chunk(b"IEND", b""))


def textured(image: str) -> dict:
    scene = triangle_scene(textures={"t": {"image": image}})
    scene["nodes"][0]["material"] = {"texture": "t"}
    return scene


def _with(path_value, value):
    """triangle_scene() with one value replaced (path of keys and indices)."""
    scene = triangle_scene()
    target = scene
    for key in path_value[:-1]:
        target = target[key]
    target[path_value[-1]] = value
    return scene


MESH = ("nodes", 0, "mesh")
# (id, scene text or dict, the place the message must start with (after "softras: error: "))
CASES = [
    ("malformed_json", '{"softras_scene": 1, "width": 8,, "height": 6}', "{scene}: invalid JSON at line 1"),
    ("not_utf8", b'{"softras_scene": 1, "width": "\xff"}', "{scene}: not UTF-8 text"),
    ("top_level_list", "[1, 2, 3]", "{scene}: the top level must be a JSON object"),
    ("nan_literal", '{"softras_scene": 1, "width": 8, "height": 6, "background": [0, NaN, 0, 1]}',
     "{scene}: invalid JSON: NaN"),
    ("infinity_literal", '{"softras_scene": 1, "width": Infinity, "height": 6}', "{scene}: invalid JSON: Infinity"),
    ("overflowing_number", '{"softras_scene": 1, "width": 8, "height": 6, "nodes": [{"mesh": '
     '{"positions": [[0, 0, 1e999], [1, 0, 0], [0, 1, 0]]}}]}', "nodes[0].mesh.positions[0][2]: expected a finite"),
    ("width_string", _with(("width",), "8"), "width: expected an integer"),
    ("positions_string", _with(MESH + ("positions",), "triangle"), "nodes[0].mesh.positions: expected a list"),
    ("index_out_of_range", _with(MESH + ("indices",), [[0, 1, 3]]), "nodes[0].mesh.indices[0]: index 3 out of range"),
    ("unknown_key", _with(MESH + ("colour",), [1, 0, 0]), "nodes[0].mesh.colour: unknown key"),
    ("missing_texture_file", textured("nowhere.png"), "textures.t.image: file not found"),
    ("truncated_png", textured("truncated.png"), "textures.t.image: cannot decode"),
    ("text_named_png", textured("text.png"), "textures.t.image: "),
    ("png_header_60000_squared", textured("bomb.png"), "textures.t.image: "),
    ("undefined_texture", _with(("nodes", 0, "material"), {"texture": "wood"}),
     "nodes[0].material.texture: unknown texture 'wood'"),
    ("width_100000", _with(("width",), 100_000), "width: 100000 is out of range"),
    ("pixels_16384_squared", triangle_scene(width=16384, height=16384), "width: 16384 x 16384"),
    ("texture_16384_squared", triangle_scene(textures={"t": {"procedural": "noise", "size": [16384, 16384]}}),
     "textures.t.size: 16384 x 16384"),
    ("lit_lines", {"softras_scene": 1, "width": 8, "height": 6,
                   "nodes": [{"mesh": {"primitive": "lines", "positions": [[-1, 0, 0], [1, 0, 0]],
                                       "normals": [[0, 0, 1], [0, 0, 1]]},
                              "material": {"shading": "gouraud"}}]},
     "nodes[0].material: lines are drawn unlit and untextured, this material has gouraud shading"),
    ("textured_lines", {"softras_scene": 1, "width": 8, "height": 6,
                        "textures": {"t": {"procedural": "checker", "size": [4, 4]}},
                        "nodes": [{"mesh": {"primitive": "lines", "positions": [[-1, 0, 0], [1, 0, 0]],
                                            "uvs": [[0, 0], [1, 0]]},
                                   "material": {"texture": "t"}}]},
     "nodes[0].material: lines are drawn unlit and untextured, this material has texture"),
    ("grid_of_8_million", _with(MESH, {"procedural": "grid", "cols": 4096, "rows": 1024}),
     "nodes[0].mesh: this grid has 8388608 triangles"),
]


def write_scene(folder, content):
    path = folder / "scene.json"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


@pytest.mark.parametrize("content, place", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_cli_refuses_bad_scene_and_keeps_the_old_output(tmp_path, capsys, content, place):
    write_textures(tmp_path)
    scene = write_scene(tmp_path, content)
    output = tmp_path / "out.png"
    output.write_bytes(OLD_OUTPUT)
    before = sorted(os.listdir(tmp_path))
    status = cli.main(["render", str(scene), "-o", str(output)])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith("softras: error: " + place.format(scene=scene)), captured.err
    assert output.read_bytes() == OLD_OUTPUT
    assert sorted(os.listdir(tmp_path)) == before                  # no temporary file left either


@pytest.mark.parametrize("content, place", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_api_raises_scene_error_with_the_same_place(tmp_path, content, place):
    write_textures(tmp_path)
    scene = write_scene(tmp_path, content)
    for load in (softras.load_scene, softras.render):
        with pytest.raises(SceneError) as info:
            load(str(scene))
        message = str(info.value)
        assert message.startswith(place.format(scene=scene)) and "\n" not in message, message
    if isinstance(content, dict):                                  # the dict API: the same place
        with pytest.raises(SceneError) as info:
            softras.scene.scene_from_dict(content, base_dir=str(tmp_path))
        assert str(info.value).startswith(place.format(scene=scene))


@pytest.mark.parametrize("case", ["pixels_16384_squared", "texture_16384_squared", "grid_of_8_million",
                                  "png_header_60000_squared"])
def test_absurd_sizes_are_refused_before_any_large_allocation(tmp_path, case):
    """The loader checks sizes from the numbers (and the PNG header) alone:
    refusing these allocates well under 10 MB (tracemalloc, which numpy and
    Pillow report to)."""
    write_textures(tmp_path)
    content = dict((c[0], c[1]) for c in CASES)[case]
    tracemalloc.start()
    try:
        with pytest.raises(SceneError):
            softras.scene.scene_from_dict(content, base_dir=str(tmp_path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 * 2 ** 20, peak


def test_nan_and_infinity_through_the_dict_api():
    for bad in (float("nan"), float("inf"), -float("inf")):
        with pytest.raises(SceneError, match=r"^nodes\[0\]\.mesh\.positions\[1\]\[0\]: expected a finite number"):
            softras.load_scene(_with(MESH + ("positions",), [[0, 0, 0], [bad, 0, 0], [0, 1, 0]]))


def test_transform_overflow_is_a_scene_error():
    """Finite numbers whose product overflows: the world matrix would be inf."""
    scene = triangle_scene()
    scene["nodes"] = [{"scale": [1e200, 1, 1], "children": [{"scale": [1e200, 1, 1], "mesh": scene["nodes"][0]["mesh"]}]}]
    with pytest.raises(SceneError, match=r"^nodes\[0\]\.children\[0\]: the world matrix overflows"):
        softras.load_scene(scene)


def test_key_with_a_newline_gives_a_one_line_message():
    with pytest.raises(SceneError) as info:
        softras.load_scene(triangle_scene(**{"bad\nkey": 1}))
    assert "\n" not in str(info.value) and str(info.value).startswith("bad\\nkey: unknown key")


# --------------------------------------------------------------------------- unwritable outputs


def _unwritable(tmp_path, kind):
    if kind == "missing_folder":
        return tmp_path / "no" / "such" / "out.png", "folder"
    if kind == "output_is_a_folder":
        (tmp_path / "out.png").mkdir()
        return tmp_path / "out.png", "is a directory"
    folder = tmp_path / "read_only"
    folder.mkdir()
    (folder / "out.png").write_bytes(OLD_OUTPUT)
    folder.chmod(0o555)
    return folder / "out.png", "not writable"


@pytest.mark.parametrize("kind", ["missing_folder", "output_is_a_folder", "read_only_folder"])
def test_unwritable_output(tmp_path, capsys, kind):
    if kind == "read_only_folder" and os.geteuid() == 0:
        pytest.skip("root writes into read-only folders; the check cannot fail as root")
    scene = write_scene(tmp_path, triangle_scene())
    output, reason = _unwritable(tmp_path, kind)
    listing = sorted(p.name for p in tmp_path.rglob("*"))
    status = cli.main(["render", str(scene), "-o", str(output)])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert captured.err.startswith(f"softras: error: {output}: ") and reason in captured.err, captured.err
    assert sorted(p.name for p in tmp_path.rglob("*")) == listing
    if kind == "read_only_folder":
        assert output.read_bytes() == OLD_OUTPUT
    with pytest.raises(ImageError, match=f"^{output}: "):
        write_png_atomic(output, np.zeros((2, 2, 4), np.uint8))
