"""docs/scene_format.md documents every key the scene loader accepts.

The keys come from the loader itself, two ways:

- the key tuples and dicts of `softras.scene.parse` (``_TOP_KEYS``,
  ``_CAMERA_KEYS``, ``_PROCEDURAL_TEXTURE_KEYS``, ...), including every
  procedural texture and mesh parameter;
- the loader's own answer: an object with a made-up key at each level is
  refused with ``unknown key (allowed: ...)``, which lists the keys of that
  level, so keys the loader checks against an inline tuple (lights,
  displacement) are covered too.

Each key must appear in the document as a code span (`` `key` ``). The
defaults the loader fills in must appear in the row of their key, and the
example scene in the document must load.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from softras.scene import SceneError, load_scene
from softras.scene import meshes as scene_meshes
from softras.scene import model, parse

DOC = Path(__file__).resolve().parents[1] / "docs" / "scene_format.md"

MADE_UP_KEY = "zz_not_a_scene_key"


# --------------------------------------------------------------------------- helpers


def doc_text() -> str:
    return DOC.read_text(encoding="utf-8")


def missing_code_spans(text: str, names) -> list[str]:
    """The names that do not appear in ``text`` as a code span `` `name` ``
    (an enum value may also be written as the JSON string `` `"name"` ``)."""
    return [name for name in names
            if f"`{name}`" not in text and f'`"{name}"`' not in text]


def constant(name: str):
    """A constant of the scene layer, wherever the package keeps it."""
    for module in (parse, model, scene_meshes):
        if hasattr(module, name):
            return getattr(module, name)
    raise AssertionError(f"{name} is in none of softras.scene.parse, .model, .meshes")


def allowed_keys(scene: dict) -> list[str]:
    """The keys the loader allows at the level where ``scene`` has MADE_UP_KEY,
    read from its 'unknown key (allowed: ...)' error."""
    base = {"softras_scene": 1, "width": 4, "height": 4}
    with pytest.raises(SceneError) as caught:
        load_scene({**base, **scene})
    match = re.search(r"unknown key \(allowed: ([^)]*)\)", str(caught.value))
    assert match and MADE_UP_KEY in str(caught.value), f"not an unknown-key error: {caught.value}"
    return [key.strip() for key in match.group(1).split(",")]


TRIANGLE = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}


def probes() -> dict[str, dict]:
    """A scene fragment per level of the format, each with MADE_UP_KEY at that level."""
    x = {MADE_UP_KEY: 0}
    out = {
        "top level": x,
        "camera": {"camera": x},
        "texture": {"textures": {"t": x}},
        "light": {"lights": [x]},
        "node": {"nodes": [x]},
        "mesh": {"nodes": [{"mesh": x}]},
        "material": {"nodes": [{"mesh": TRIANGLE, "material": x}]},
        "displacement": {"nodes": [{"mesh": TRIANGLE, "material": {"displacement": x}}]},
        "tolerance": {"tolerance": x},
    }
    for kind in constant("PROCEDURAL_TEXTURES"):
        out[f"procedural texture {kind}"] = {"textures": {"t": {"procedural": kind, **x}}}
    for kind in parse._PROCEDURAL_MESH_KEYS:
        out[f"procedural mesh {kind}"] = {"nodes": [{"mesh": {"procedural": kind, **x}}]}
    return out


def section(text: str, heading: str) -> str:
    """The part of ``text`` under the first heading line containing ``heading``,
    up to the next heading of the same or a higher level."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        found = re.match(r"(#+) ", line)
        if found and heading in line:
            level = len(found.group(1))
            end = next((j for j in range(i + 1, len(lines))
                        if (m := re.match(r"(#+) ", lines[j])) and len(m.group(1)) <= level), len(lines))
            return "\n".join(lines[i:end])
    raise AssertionError(f"{DOC.name}: no heading containing {heading!r}")


def row(text: str, key: str) -> str:
    """The table row of ``key`` in ``text`` (a line starting ``| `key` |``)."""
    for line in text.splitlines():
        if line.startswith(f"| `{key}` |") or line.startswith(f"| `{key}`,"):
            return line
    raise AssertionError(f"no table row for `{key}` in:\n{text[:200]}...")


def as_json(value) -> str:
    """A default as the document writes it: JSON, numbers without a needless '.0'."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return f"{value:g}"
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(as_json(v) for v in value) + "]"
    raise TypeError(value)


def documents_default(line: str, default) -> bool:
    return f"`{as_json(default)}`" in line


# --------------------------------------------------------------------------- the helpers themselves


def test_helper_reports_a_made_up_key_as_missing():
    text = doc_text()
    assert missing_code_spans(text, ["softras_scene", MADE_UP_KEY]) == [MADE_UP_KEY]
    assert missing_code_spans("a `key` and `\"value\"`", ["key", "value", "other"]) == ["other"]


def test_loader_probe_reads_the_allowed_keys():
    assert allowed_keys({"tolerance": {MADE_UP_KEY: 0}}) == list(constant("DEFAULT_TOLERANCE"))
    assert allowed_keys({MADE_UP_KEY: 0}) == list(parse._TOP_KEYS)


# --------------------------------------------------------------------------- every key is documented


KEY_TUPLES = ("_TOP_KEYS", "_CAMERA_KEYS", "_TEXTURE_KEYS", "_MESH_KEYS", "_MATERIAL_KEYS",
              "_NODE_KEYS", "_DRAW_STATE_KEYS")


@pytest.mark.parametrize("name", KEY_TUPLES)
def test_key_tuple_is_documented(name):
    keys = getattr(parse, name)
    assert keys, name
    assert missing_code_spans(doc_text(), keys) == [], f"{name}: keys missing from {DOC.name}"


def test_projection_parameters_are_documented():
    text = section(doc_text(), "## `camera`")
    for kind, keys in parse._PROJECTION_KEYS.items():
        assert missing_code_spans(text, [kind, *keys]) == [], kind


@pytest.mark.parametrize("kind", sorted(parse._PROCEDURAL_TEXTURE_KEYS))
def test_procedural_texture_parameters_and_defaults_are_documented(kind):
    text = section(doc_text(), f"Procedural texture `{kind}`")
    for key, default in parse._PROCEDURAL_TEXTURE_KEYS[kind].items():
        line = row(text, key)
        assert documents_default(line, default), f"{kind}.{key}: default {as_json(default)} not in: {line}"


@pytest.mark.parametrize("kind", sorted(parse._PROCEDURAL_MESH_KEYS))
def test_procedural_mesh_parameters_and_defaults_are_documented(kind):
    text = section(doc_text(), f"Procedural mesh `{kind}`")
    for key, (form, default) in parse._PROCEDURAL_MESH_KEYS[kind].items():
        line = row(text, key)
        if default is None:
            expected = "required" if form == "count" else "none"
            assert expected in line, f"{kind}.{key}: should say {expected!r}: {line}"
        else:
            assert documents_default(line, default), f"{kind}.{key}: default {as_json(default)} not in: {line}"


@pytest.mark.parametrize("level", sorted(probes()))
def test_every_key_the_loader_allows_is_documented(level):
    keys = allowed_keys(probes()[level])
    assert MADE_UP_KEY not in keys
    assert missing_code_spans(doc_text(), keys) == [], f"{level}: keys missing from {DOC.name}"


ENUMS = ("PROJECTIONS", "PRIMITIVES", "SHADINGS", "DEPTH_FUNCTIONS", "CULL_MODES", "BLEND_MODES",
         "LIGHT_TYPES", "WRAP_MODES", "MIN_FILTERS", "MAG_FILTERS", "PROCEDURAL_TEXTURES",
         "FRAMEBUFFERS", "RENDER_ORDERS")


@pytest.mark.parametrize("name", ENUMS)
def test_every_enum_value_is_documented(name):
    assert missing_code_spans(doc_text(), constant(name)) == [], name


def test_procedural_mesh_kinds_are_documented():
    assert missing_code_spans(doc_text(), list(parse._PROCEDURAL_MESH_KEYS)) == []


@pytest.mark.parametrize("name", ["MAX_SIDE", "MAX_PIXELS", "MAX_TEXELS", "MAX_NODE_DEPTH",
                                  "MAX_TRIANGLES", "FORMAT_VERSION"])
def test_limits_are_documented_with_their_values(name):
    line = row(section(doc_text(), "## Limits"), name)
    assert f"`{constant(name)}`" in line, f"{name} = {constant(name)}: {line}"


# --------------------------------------------------------------------------- defaults the loader fills in


def loaded_defaults():
    """(section heading, key, the loader's default) for defaults read back
    from a scene that leaves them out."""
    scene = load_scene({
        "softras_scene": 1, "width": 4, "height": 4,
        "textures": {"t": {"procedural": "noise", "size": [2, 2]}},
        "lights": [{"type": "point", "position": [0, 0, 1]}],
        "nodes": [{"mesh": TRIANGLE}],
    })
    texture, light, draw = scene.textures["t"], scene.lights[0], scene.draws[0]
    material = draw.material
    return [
        ("## Top level", "background", scene.background),
        ("## Top level", "samples", scene.samples),
        ("## Top level", "description", scene.description),
        ("## Top level", "framebuffer", scene.framebuffer),
        ("## Top level", "render_order", scene.render_order),
        ("## `textures`", "wrap_s", texture.wrap_s),
        ("## `textures`", "wrap_t", texture.wrap_t),
        ("## `textures`", "min_filter", texture.min_filter),
        ("## `textures`", "mag_filter", texture.mag_filter),
        ("## `textures`", "max_anisotropy", texture.max_anisotropy),
        ("## `lights`", "color", light.color),
        ("### Draw state", "depth_test", draw.depth_test),
        ("### Draw state", "depth_write", draw.depth_write),
        ("### Draw state", "cull", draw.cull),
        ("### Draw state", "blend", draw.blend),
        ("## `material`", "color", material.color),
        ("## `material`", "shading", material.shading),
        ("## `material`", "ambient", material.ambient),
        ("## `material`", "diffuse", material.diffuse),
        ("## `material`", "specular", material.specular),
        ("## `material`", "shininess", material.shininess),
        ("## `material`", "bump_scale", material.bump_scale),
        *(("## `tolerance`", key, value) for key, value in scene.tolerance.items()),
    ]


@pytest.mark.parametrize("heading, key, default", loaded_defaults(),
                         ids=lambda v: v if isinstance(v, str) else None)
def test_loader_defaults_are_the_documented_ones(heading, key, default):
    line = row(section(doc_text(), heading), key)
    assert documents_default(line, default), f"{heading} {key}: default {as_json(default)} not in: {line}"


# --------------------------------------------------------------------------- the example


def test_example_scene_loads():
    block = re.search(r"## Example.*?```json\n(.*?)```", doc_text(), re.S)
    assert block, f"{DOC.name}: no JSON example under '## Example'"
    scene = load_scene(json.loads(block.group(1)))
    assert scene.draws and math.isfinite(float(scene.camera.projection.sum()))
