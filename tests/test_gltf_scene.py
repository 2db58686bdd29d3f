"""glTF files as scenes (`softras.load_scene("model.glb")`, softras.scene.gltf, docs/gltf.md).

Every file is built here in tmp_path with the writer of
scripts/make_gltf_scenes.py (no exporter library), so each test knows what
the file says.  The checks:

- softras and glref agree (strict verifier) on glTF scenes: the conformance
  scenes of scenes/, a vertex-coloured mesh with 8/16/32-bit indices and
  interleaved attributes, MASK and BLEND materials;
- a glTF texture shows upright (uv (0, 0) = the image's top-left corner);
- a mirrored node (negative determinant) keeps its front faces (reversed
  winding), the first camera of the traversal is used, and a file without
  a camera gets the documented framing camera;
- the documented mappings (metallic-roughness to Blinn-Phong, picture size,
  OPAQUE ignores alpha, normalTexture's green up the image);
- `softras render model.glb` works; malformed and unsupported files are one
  line naming the file and the glTF place, exit 2, nothing written;
- conformance finds .gltf / .glb files in folders.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

import softras
from conftest import load_script
from softras import cli
from softras.scene import SceneError, gltf, load_scene, scene_files

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
make = load_script("make_gltf_scenes")
GltfWriter = make.GltfWriter

CONFORMANCE = ["gltf_textured_box.glb", "gltf_alpha_modes.gltf", "gltf_hierarchy_framed.glb",
               "gltf_normal_mapped.glb"]
UNLIT = {"KHR_materials_unlit": {}}


def soft_and_gl(scene):
    soft = softras.render(scene)
    gl = softras.render(scene, backend="gl")
    verdict = softras.verify(scene, soft, gl, profile="strict")
    assert verdict.verdict == "pass", verdict
    return soft, gl


def ortho_camera(g: GltfWriter, xmag=1.0, ymag=1.0) -> int:
    camera = g.add("cameras", {"type": "orthographic", "orthographic": {"xmag": xmag, "ymag": ymag,
                                                                        "znear": 0.1, "zfar": 10}})
    return g.node(name="camera", translation=[0, 0, 5], camera=camera)


QUADRANTS = {"top_left": (255, 0, 0, 255), "top_right": (0, 255, 0, 255),
             "bottom_left": (0, 0, 255, 255), "bottom_right": (255, 255, 255, 255)}


def quadrant_pixels(side=8, alpha=255):
    pixels = np.zeros((side, side, 4), np.uint8)
    h = side // 2
    pixels[:h, :h], pixels[:h, h:] = QUADRANTS["top_left"], QUADRANTS["top_right"]
    pixels[h:, :h], pixels[h:, h:] = QUADRANTS["bottom_left"], QUADRANTS["bottom_right"]
    pixels[..., 3] = alpha
    return pixels


def textured_quad(tmp_path, name="quad.gltf", where="data", material=None, alpha=255, **node):
    """A quad filling an orthographic view, its image upright by glTF's convention."""
    g = GltfWriter()
    g.doc["extensionsUsed"] = ["KHR_materials_unlit"]
    texture = g.texture(g.image(quadrant_pixels(alpha=alpha), where, "quadrants.png"), magFilter=9728,
                        minFilter=9728)
    m = g.add("materials", material or {"extensions": UNLIT,
                                        "pbrMetallicRoughness": {"baseColorTexture": {"index": texture}}})
    p, uv, t = make.quad(2, 2)
    g.scene(ortho_camera(g), g.node(mesh=g.mesh(g.primitive(p, t, uvs=uv, material=m)), **node))
    return g.write(tmp_path / name)


# --------------------------------------------------------------------------- pictures against GL


@pytest.mark.gl
@pytest.mark.parametrize("name", CONFORMANCE)
def test_conformance_scenes_soft_matches_gl(name):
    soft, _ = soft_and_gl(load_scene(os.path.join(REPO, "scenes", name)))
    assert soft[..., :3].any()


@pytest.mark.gl
@pytest.mark.parametrize("where", ["data", "bufferView", "file"])
def test_gltf_texture_is_upright(tmp_path, where):
    path = textured_quad(tmp_path, "quad.glb" if where == "bufferView" else "quad.gltf", where)
    scene = load_scene(str(path))
    assert (scene.width, scene.height) == (256, 256)
    for picture in soft_and_gl(scene):
        for (row, col), quadrant in {(64, 64): "top_left", (64, 192): "top_right", (192, 64): "bottom_left",
                                     (192, 192): "bottom_right"}.items():
            assert tuple(picture[row, col]) == QUADRANTS[quadrant], (where, quadrant, picture[row, col])


@pytest.mark.gl
@pytest.mark.parametrize("index_bits, interleaved, suffix", [(8, False, ".glb"), (16, True, ".glb"),
                                                            (32, True, ".gltf")])
def test_vertex_coloured_mesh_soft_matches_gl(tmp_path, index_bits, interleaved, suffix):
    rng = np.random.default_rng(index_bits)
    xs, ys = np.meshgrid(np.linspace(-0.9, 0.9, 6), np.linspace(-0.9, 0.9, 6))
    positions = np.stack([xs.ravel(), ys.ravel(), 0.3 * np.sin(3 * xs.ravel() + 2 * ys.ravel())], axis=1)
    ids = np.arange(36).reshape(6, 6)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(), ids[1:, 1:].ravel(), ids[1:, :-1].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    colors = np.concatenate([rng.uniform(0, 1, (36, 3)), np.ones((36, 1))], axis=1)
    g = GltfWriter()
    m = g.add("materials", {"extensions": UNLIT})
    mesh = g.mesh(g.primitive(positions, triangles, colors=colors, color_code="u2", normals=np.tile([0, 0, 1], (36, 1)),
                              interleaved=interleaved, index_bits=index_bits, material=m))
    g.scene(ortho_camera(g), g.node(mesh=mesh, rotation=[0.2, 0.1, 0, 0.975]))
    path = g.write(tmp_path / f"coloured{suffix}", external_bin="coloured.bin" if suffix == ".gltf" else None)
    scene = load_scene(str(path))
    np.testing.assert_array_equal(scene.draws[0].mesh.indices, triangles)
    np.testing.assert_allclose(scene.draws[0].mesh.colors, np.round(colors * 65535) / 65535)
    soft_and_gl(scene)


@pytest.mark.gl
def test_mask_and_blend_soft_matches_gl(tmp_path):
    """MASK with a linearly filtered texture whose alpha crosses the cutoff, over
    an opaque quad, under two BLEND quads: identical to GL, byte for byte."""
    g = GltfWriter()
    g.doc["extensionsUsed"] = ["KHR_materials_unlit"]
    pixels = quadrant_pixels()
    pixels[::2, 1::2, 3] = 40                      # a fine pattern of alpha 40 / 255 texels
    texture = g.texture(g.image(pixels), magFilter=9729, minFilter=9729)
    mask = g.add("materials", {"extensions": UNLIT, "alphaMode": "MASK", "alphaCutoff": 0.6,
                               "pbrMetallicRoughness": {"baseColorTexture": {"index": texture}}})
    blend = g.add("materials", {"extensions": UNLIT, "alphaMode": "BLEND",
                                "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.9, 0.9, 0.5]}})
    opaque = g.add("materials", {"extensions": UNLIT, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0, 0.5, 0.1]}})
    p, uv, t = make.quad(1.6, 1.6)
    g.scene(ortho_camera(g),
            g.node(mesh=g.mesh(g.primitive(p * 0.6, t, material=blend)), translation=[0.3, 0.3, 1]),
            g.node(mesh=g.mesh(g.primitive(p, t, uvs=uv, material=mask)), rotation=[0, 0, 0.1, 0.995]),
            g.node(mesh=g.mesh(g.primitive(p * 1.2, t, material=opaque)), translation=[0, 0, -1]),
            g.node(mesh=g.mesh(g.primitive(p * 0.6, t, material=blend)), translation=[-0.3, -0.3, -0.5]))
    scene = load_scene(str(g.write(tmp_path / "alpha.glb")))
    assert scene.render_order == "opaque_then_sorted"
    assert [d.blend for d in scene.draws] == ["over", "none", "none", "over"]
    assert scene.draws[1].material.alpha_cutoff == 0.6
    soft, gl = soft_and_gl(scene)
    np.testing.assert_array_equal(soft, gl)
    assert tuple(soft[128, 10]) == (128, 0, 128, 255)         # OPAQUE: alpha 0.1 ignored


def normal_mapped_quad(tmp_path, green: int, name="bumpy.gltf", tangents=None, normals=True, **info):
    """A lit quad facing the camera, its normalTexture the glTF tangent-space
    normal (0, +-0.6, 0.8) (green 204: up the image; 51: down) but for a red
    ramp in four middle columns (x tilts, so the map is not uniform), and a directional
    light from above and in front (KHR_lights_punctual, travelling along
    (0, -1, -1) / sqrt 2)."""
    pixels = np.zeros((16, 16, 4), np.uint8)
    pixels[...] = (128, green, 230, 255)
    pixels[:, 6:10, 0] = np.arange(96, 160, 16, dtype=np.uint8)     # x tilts across four columns
    g = GltfWriter()
    g.doc["extensionsUsed"] = ["KHR_lights_punctual"]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 1.0}]}}
    texture = g.texture(g.image(pixels), magFilter=9729, minFilter=9987)
    m = g.add("materials", {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0.0,
                                                     "roughnessFactor": 0.6},
                            "normalTexture": {"index": texture, **info}})
    p, uv, t = make.quad(2, 2)
    light = g.node(name="sun", rotation=[-0.3826834, 0, 0, 0.9238795],
                   extensions={"KHR_lights_punctual": {"light": 0}})
    primitive = g.primitive(p, t, normals=np.tile([0.0, 0.0, 1.0], (4, 1)) if normals else None, uvs=uv, material=m)
    if tangents is not None:
        primitive["attributes"]["TANGENT"] = g.accessor(np.tile(np.asarray(tangents, np.float32), (4, 1)))
    g.scene(ortho_camera(g), light, g.node(mesh=g.mesh(primitive)))
    return g.write(tmp_path / name)


@pytest.mark.gl
def test_normal_texture_soft_matches_gl_and_green_points_up(tmp_path):
    """glTF's normal maps point +Y up the image: a normal tilted up faces the
    light from above (brighter) and one tilted down turns away; the loader's
    copy has green 255 - G, softras's convention (docs/gltf.md)."""
    up, down = (load_scene(str(normal_mapped_quad(tmp_path, green, f"n{green}.gltf"))) for green in (204, 51))
    draw = up.draws[0]
    assert draw.material.normal_map is not None and draw.material.shading == "phong"
    assert up.textures[draw.material.normal_map].levels[0][0, 0, :3].tolist() == [128, 51, 230]
    lit_up, lit_down = soft_and_gl(up)[0], soft_and_gl(down)[0]
    centre = lit_up[64:192, 16:80, :3].astype(int).mean(), lit_down[64:192, 16:80, :3].astype(int).mean()
    assert centre[0] > centre[1] + 60, centre


@pytest.mark.gl
def test_normal_texture_takes_the_files_tangents(tmp_path):
    """A TANGENT attribute gives the tangent frames, its handedness negated
    (glTF's bitangent points up the image): the frame glTF implies for an
    upright quad, (1, 0, 0, +1), is the one softras computes, (1, 0, 0, -1);
    a frame turned a quarter in the plane, (0, -1, 0, +1) (u up the image),
    moves the map's up-tilt onto x: the light from above no longer meets it,
    and glref draws the same frames (strict). Without NORMAL the tangents are
    ignored (glTF: flat normals get computed tangents)."""
    computed = load_scene(str(normal_mapped_quad(tmp_path, 204, "plain.gltf")))
    upright = load_scene(str(normal_mapped_quad(tmp_path, 204, "upright.gltf", tangents=[1, 0, 0, 1])))
    turned = load_scene(str(normal_mapped_quad(tmp_path, 204, "turned.gltf", tangents=[0, -1, 0, 1])))
    assert computed.draws[0].mesh.given_tangents is None
    assert upright.draws[0].mesh.tangents.tolist() == [[1.0, 0.0, 0.0, -1.0]] * 4
    assert np.allclose(computed.draws[0].mesh.tangents, upright.draws[0].mesh.tangents)
    assert (soft_and_gl(upright)[0] == soft_and_gl(computed)[0]).all()
    lit_upright, lit_turned = soft_and_gl(upright)[0], soft_and_gl(turned)[0]
    centre = lit_upright[64:192, 16:80, :3].astype(int).mean(), lit_turned[64:192, 16:80, :3].astype(int).mean()
    assert centre[0] > centre[1] + 20, centre
    flat = load_scene(str(normal_mapped_quad(tmp_path, 204, "flat.gltf", tangents=[0, -1, 0, 1], normals=False)))
    assert flat.draws[0].mesh.given_tangents is None


@pytest.mark.parametrize("tangent, reason", [([1, 0, 0], r"TANGENT has 3 components, expected 4"),
                                             ([float("nan"), 0, 0, 1], r"TANGENT of vertex 0 is not finite")])
def test_bad_tangents_are_refused_with_the_place(tmp_path, tangent, reason):
    path = normal_mapped_quad(tmp_path, 204, tangents=tangent)
    with pytest.raises(SceneError, match=r"meshes\[0\]\.primitives\[0\]: " + reason):
        load_scene(str(path))


def test_normal_texture_scale_other_than_1_is_refused(tmp_path):
    path = normal_mapped_quad(tmp_path, 204, scale=0.5)
    with pytest.raises(SceneError, match=r"materials\[0\]\.normalTexture\.scale: 0\.5 not supported \(only 1\)"):
        load_scene(str(path))


@pytest.mark.gl
def test_mirrored_node_keeps_its_front_faces_and_first_camera_is_used(tmp_path):
    """Two single-sided quads facing the camera; the second under scale (-1, 1, 1)
    (negative determinant): both drawn, culling back faces, the second one's
    texture mirrored.  A second camera later in the traversal is ignored."""
    g = GltfWriter()
    g.doc["extensionsUsed"] = ["KHR_materials_unlit"]
    texture = g.texture(g.image(quadrant_pixels()), magFilter=9728, minFilter=9728)
    m = g.add("materials", {"extensions": UNLIT, "pbrMetallicRoughness": {"baseColorTexture": {"index": texture}}})
    p, uv, t = make.quad(0.9, 0.9)
    mesh = g.mesh(g.primitive(p, t, uvs=uv, material=m))
    other = g.add("cameras", {"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}})
    group = g.node(name="group", translation=[0, 0, 0.5],
                   children=[g.node(mesh=mesh, translation=[-0.5, 0, 0]),
                             g.node(mesh=mesh, translation=[0.5, 0, 0], scale=[-1, 1, 1]),
                             g.node(camera=other, translation=[0, 0, 9])])
    g.scene(ortho_camera(g), group)
    scene = load_scene(str(g.write(tmp_path / "mirror.glb")))
    assert scene.camera.kind == "orthographic"
    np.testing.assert_array_equal(scene.draws[1].mesh.indices, t[:, ::-1])
    assert all(d.cull == "back" for d in scene.draws)
    soft, gl = soft_and_gl(scene)
    # left quad upright: its top-left quadrant red; the mirrored one: its top-left shows green
    assert tuple(soft[80, 50]) == QUADRANTS["top_left"] and tuple(soft[80, 145]) == QUADRANTS["top_right"]


def test_framing_camera_without_a_camera(tmp_path):
    g = GltfWriter()
    positions, normals, uvs, triangles = make.box()
    g.scene(g.node(mesh=g.mesh(g.primitive(positions * [2, 1, 1] + [1, 2, 3], triangles, normals=normals))))
    scene = load_scene(str(g.write(tmp_path / "framed.glb")))
    lo, hi = np.array([0, 1.5, 2.5]), np.array([2, 2.5, 3.5])
    r = np.linalg.norm(hi - lo) / 2
    d = r / math.sin(math.radians(22.5))
    eye = np.linalg.inv(scene.camera.view)[:3, 3]
    np.testing.assert_allclose(eye, (lo + hi) / 2 + [0, 0, d])
    assert (scene.width, scene.height) == (256, 256)
    np.testing.assert_allclose(scene.camera.projection,
                               softras.scene.perspective_matrix(45, 1, (d - r) / 2, 2 * (d + r)))
    assert len(scene.lights) == 1 and scene.draws[0].material.shading == "phong"     # the default rig


def test_camera_picture_size_and_infinite_far(tmp_path):
    g = GltfWriter()
    camera = g.add("cameras", {"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.2, "aspectRatio": 2.0}})
    p, _, t = make.quad()
    g.scene(g.node(camera=camera, translation=[0, 0, 3]), g.node(mesh=g.mesh(g.primitive(p, t))))
    scene = load_scene(str(g.write(tmp_path / "wide.gltf")))
    assert (scene.width, scene.height) == (512, 256) and scene.camera.kind == "matrix"
    f = 1 / math.tan(0.35)
    np.testing.assert_allclose(scene.camera.projection,
                               [[f / 2, 0, 0, 0], [0, f, 0, 0], [0, 0, -1, -0.4], [0, 0, -1, 0]])


def test_pbr_mapping():
    factors = gltf.blinn_phong_from_pbr(np.array([1.0, 0.5, 0.0, 1.0]), metallic=0.25, roughness=0.5)
    assert factors["diffuse"] == 0.75 and factors["ambient"] == gltf.AMBIENT
    assert factors["specular"] == pytest.approx(0.04 * 0.75 + 0.25 * (0.2126 + 0.7152 * 0.5))
    assert factors["shininess"] == pytest.approx(2 / 0.25 ** 2 - 2)
    assert gltf.blinn_phong_from_pbr(np.ones(4), 0.0, 0.0)["shininess"] == 4096
    assert gltf.blinn_phong_from_pbr(np.ones(4), 0.0, 1.0)["shininess"] == 1


def test_opaque_ignores_alpha(tmp_path):
    scene = load_scene(str(textured_quad(tmp_path, alpha=60)))
    texture = scene.textures[scene.draws[0].material.texture]
    assert (texture.levels[0][..., 3] == 255).all()
    np.testing.assert_array_equal(texture.levels[0][..., :3], quadrant_pixels()[..., :3])


# --------------------------------------------------------------------------- command line


def test_cli_render_writes_the_picture(tmp_path, capsys):
    path = textured_quad(tmp_path)
    out = tmp_path / "out.png"
    assert cli.main(["render", str(path), "-o", str(out)]) == 0
    from softras.scene.imageio import read_png
    picture = read_png(out)
    assert picture.shape == (256, 256, 4) and tuple(picture[64, 64]) == QUADRANTS["top_left"]


def test_conformance_finds_gltf_files_in_folders(tmp_path):
    textured_quad(tmp_path, "a.gltf", "file")
    textured_quad(tmp_path, "b.glb", "bufferView")
    (tmp_path / "c.json").write_text("{}")
    names = [os.path.basename(p) for p in scene_files([tmp_path])]
    assert names == ["a.gltf", "b.glb", "c.json"]
    from softras.verification.conformance import select
    assert [p.name for p in select([tmp_path / "b.glb"])] == ["b.glb"]


# --------------------------------------------------------------------------- refusals


def _bad_files(folder):
    """name -> (file, the start of the reason after 'PATH: ')."""
    good = textured_quad(folder, "good.glb", "bufferView").read_bytes()
    (folder / "truncated.glb").write_bytes(good[:-40])

    def variant(name, edit, where="bufferView"):
        path = textured_quad(folder, name, where)
        if path.suffix == ".gltf":
            doc = json.loads(path.read_text())
            edit(doc)
            path.write_text(json.dumps(doc))
        return path.name

    def out_of_range(doc):
        g_index = doc["meshes"][0]["primitives"][0]["indices"]
        doc["accessors"][g_index]["count"] = 6
        doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["count"] = 2

    def draco(doc):
        doc["meshes"][0]["primitives"][0]["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0}}

    def required(doc):
        doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]

    def skin(doc):
        doc["nodes"][1]["skin"] = 0

    def transform(doc):
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = {"KHR_texture_transform": {}}

    def strip(doc):
        doc["meshes"][0]["primitives"][0]["mode"] = 5

    def point_light(doc):
        doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point"}]}}
        doc["nodes"][1]["extensions"] = {"KHR_lights_punctual": {"light": 0}}

    def texcoord1(doc):
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 1

    def huge(doc):
        doc["nodes"][1]["translation"] = [10 ** 400, 0, 0]

    def cutoff(doc):
        doc["materials"][0].update(alphaMode="MASK", alphaCutoff=1.0000000000000002)

    missing = variant("missing.gltf", lambda doc: None, "file")
    os.remove(folder / "quadrants.png")
    return {
        "truncated_glb": ("truncated.glb", "truncated"),
        "index_out_of_range": (variant("range.gltf", out_of_range, "data"),
                               "meshes[0].primitives[0]: index 2 out of range for 2 vertices"),
        "missing_texture_file": (missing, "images[0]: no such file 'quadrants.png'"),
        "draco": (variant("draco.gltf", draco, "data"),
                  "meshes[0].primitives[0].extensions.KHR_draco_mesh_compression: not supported"),
        "extension_required": (variant("required.gltf", required, "data"),
                               "extensionsRequired[0]: KHR_draco_mesh_compression: not supported"),
        "skin": (variant("skin.gltf", skin, "data"), "nodes[1].skin: skins are not supported"),
        "texture_transform": (variant("transform.gltf", transform, "data"),
                              "materials[0].pbrMetallicRoughness.baseColorTexture.extensions.KHR_texture_transform: "
                              "not supported"),
        "triangle_strip": (variant("strip.gltf", strip, "data"),
                           "meshes[0].primitives[0]: mode 5 (TRIANGLE_STRIP) is not supported"),
        "point_light": (variant("point.gltf", point_light, "data"),
                        "extensions.KHR_lights_punctual.lights[0].type: 'point' lights are not supported"),
        "texcoord_1": (variant("uv1.gltf", texcoord1, "data"),
                       "materials[0].pbrMetallicRoughness.baseColorTexture.texCoord: 1 not supported"),
        # (the scene format's own number check, `fileio.number_problem`)
        "huge_number": (variant("huge.gltf", huge, "data"), "nodes[1].translation[0]: number too large"),
        "cutoff_above_one": (variant("cutoff.gltf", cutoff, "data"),
                             "materials[0].alphaCutoff: 1.0000000000000002 is out of range [0, 1]"),
    }


BAD = ["cutoff_above_one", "draco", "extension_required", "huge_number", "index_out_of_range", "missing_texture_file",
       "point_light", "skin", "texcoord_1", "texture_transform", "triangle_strip", "truncated_glb"]


def test_the_list_of_bad_files_is_complete(tmp_path):
    assert sorted(_bad_files(tmp_path)) == BAD


@pytest.mark.parametrize("case", BAD)
def test_bad_file_is_one_line_naming_file_and_place(tmp_path, case):
    name, reason = _bad_files(tmp_path)[case]
    path = str(tmp_path / name)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: {reason}"), message


@pytest.mark.parametrize("case", ["truncated_glb", "draco", "skin", "missing_texture_file", "index_out_of_range"])
def test_cli_exits_2_and_writes_nothing(tmp_path, capsys, case):
    name, reason = _bad_files(tmp_path)[case]
    output = tmp_path / "out.png"
    output.write_bytes(b"previous output")
    before = sorted(os.listdir(tmp_path))
    status = cli.main(["render", str(tmp_path / name), "-o", str(output)])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith(f"softras: error: {tmp_path / name}: {reason}"), captured.err
    assert output.read_bytes() == b"previous output"
    assert sorted(os.listdir(tmp_path)) == before


def test_a_folder_lists_scene_files_in_any_case(tmp_path):
    """`parse.folder_scene_files` takes the suffixes `load_scene` reads, in any
    case (MODEL.GLB loads by name, so a folder lists it too)."""
    from softras.scene.parse import folder_scene_files
    for name in ("A.JSON", "b.glb", "MODEL.GLB", "c.Gltf", "notes.txt"):
        (tmp_path / name).write_text("")
    (tmp_path / "folder.json").mkdir()
    assert [os.path.basename(p) for p in folder_scene_files(tmp_path)] == ["A.JSON", "MODEL.GLB", "b.glb", "c.Gltf"]
