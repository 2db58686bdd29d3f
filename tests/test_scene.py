"""Scene loading and validation (softras.scene) and procedural meshes (softras.scene.meshes)."""

import copy
import glob
import json
import os

import numpy as np
import pytest

from softras.scene import meshes
from softras.scene import MAX_PIXELS, Scene, SceneError, load_scene

SCENES_DIR = os.path.join(os.path.dirname(__file__), "..", "scenes")

TRIANGLE = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}


def minimal(**top):
    """The smallest valid scene, plus top-level overrides."""
    data = {"softras_scene": 1, "width": 8, "height": 6, "nodes": [{"mesh": copy.deepcopy(TRIANGLE)}]}
    data.update(top)
    return data


def with_camera(**camera):
    return minimal(camera=camera)


def first_draw(data):
    return load_scene(data).draws[0]


# --------------------------------------------------------------------------- defaults


def test_minimal_scene_defaults():
    scene = load_scene(minimal())
    assert (scene.width, scene.height, scene.samples) == (8, 6, 1)
    np.testing.assert_array_equal(scene.background, [0, 0, 0, 1])
    assert scene.camera.kind == "matrix"
    np.testing.assert_array_equal(scene.camera.view, np.identity(4))
    np.testing.assert_array_equal(scene.camera.projection, np.identity(4))
    assert scene.tolerance == {"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99}
    assert scene.source == "<dict>" and scene.description == "" and scene.lights == () and scene.textures == {}
    draw = scene.draws[0]
    assert (draw.path, draw.name) == ("nodes[0]", "nodes[0]")
    assert (draw.depth_test, draw.depth_write, draw.cull, draw.blend) == ("less", True, "none", "none")
    np.testing.assert_array_equal(draw.world, np.identity(4))
    material = draw.material
    np.testing.assert_array_equal(material.color, [1, 1, 1, 1])
    assert (material.texture, material.shading) == (None, "unlit")
    assert (material.ambient, material.diffuse, material.specular, material.shininess) == (0.1, 0.8, 0.5, 32)
    mesh = draw.mesh
    assert mesh.primitive == "triangles"
    assert mesh.positions.dtype == np.float64 and mesh.positions.shape == (3, 3)
    assert mesh.indices.dtype == np.int64
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2]])          # sequential when absent
    assert mesh.colors is None and mesh.normals is None and mesh.uvs is None


def test_scene_is_returned_as_is_and_arrays_are_read_only():
    scene = load_scene(minimal())
    assert load_scene(scene) is scene
    with pytest.raises(ValueError):
        scene.draws[0].mesh.positions[0, 0] = 5.0


def test_rgb_colours_get_alpha_one():
    data = minimal(background=[0.2, 0.4, 0.6])
    data["nodes"][0]["mesh"]["colors"] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    data["nodes"][0]["material"] = {"color": [0.5, 0.5, 0.5]}
    scene = load_scene(data)
    np.testing.assert_array_equal(scene.background, [0.2, 0.4, 0.6, 1])
    np.testing.assert_array_equal(scene.draws[0].mesh.colors, [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]])
    np.testing.assert_array_equal(scene.draws[0].material.color, [0.5, 0.5, 0.5, 1])


@pytest.mark.parametrize("value, expected", [(False, None), (True, "less"), ("gequal", "gequal"), ("never", "never")])
def test_depth_test_values(value, expected):
    data = minimal()
    data["nodes"][0]["depth_test"] = value
    assert first_draw(data).depth_test == expected


def test_flat_and_nested_indices_agree():
    nested = minimal()
    nested["nodes"][0]["mesh"]["indices"] = [[0, 1, 2], [2, 1, 0]]
    flat = minimal()
    flat["nodes"][0]["mesh"]["indices"] = [0, 1, 2, 2, 1, 0]
    np.testing.assert_array_equal(first_draw(nested).mesh.indices, first_draw(flat).mesh.indices)


def test_lines_primitive():
    data = minimal()
    data["nodes"][0]["mesh"] = {"primitive": "lines", "positions": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]}
    assert first_draw(data).mesh.indices.tolist() == [[0, 1], [2, 3]]


def test_tolerance_partial_override_and_description():
    scene = load_scene(minimal(tolerance={"threshold": 4}, description="a test"))
    assert scene.tolerance == {"threshold": 4, "max_bad_fraction": 0.001, "min_ssim": 0.99}
    assert scene.description == "a test"


def test_lights():
    scene = load_scene(minimal(lights=[{"type": "point", "position": [1, 2, 3]},
                                       {"type": "directional", "direction": [0, -1, 0], "color": [2, 2, 2]}]))
    point, directional = scene.lights
    np.testing.assert_array_equal(point.position, [1, 2, 3])
    np.testing.assert_array_equal(point.color, [1, 1, 1])
    assert point.direction is None and directional.position is None
    np.testing.assert_array_equal(directional.color, [2, 2, 2])


# --------------------------------------------------------------------------- camera matrices


def test_glu_perspective():
    """gluPerspective(90, 1, 1, 3): f = cot(45°) = 1, P[2,2] = (far+near)/(near−far) = 4/−2 = −2,
    P[2,3] = 2·far·near/(near−far) = 6/−2 = −3, P[3,2] = −1."""
    camera = load_scene(with_camera(projection="perspective", fov_y=90, aspect=1, near=1, far=3)).camera
    assert camera.kind == "perspective"
    np.testing.assert_allclose(camera.projection, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -2, -3], [0, 0, -1, 0]], atol=1e-15)


def test_perspective_aspect_defaults_to_width_over_height():
    """8 x 6 pixels: aspect 4/3, so with fov 90 (f = 1) P[0,0] = f/aspect = 0.75."""
    camera = load_scene(with_camera(projection="perspective", fov_y=90, near=1, far=3)).camera
    assert camera.projection[0, 0] == pytest.approx(0.75)
    assert camera.projection[1, 1] == pytest.approx(1.0)


def test_gl_frustum():
    """glFrustum(−1, 3, −2, 2, 1, 3): 2n/(r−l) = 0.5, (r+l)/(r−l) = 0.5, 2n/(t−b) = 0.5,
    (t+b)/(t−b) = 0, −(f+n)/(f−n) = −2, −2fn/(f−n) = −3."""
    camera = load_scene(with_camera(projection="frustum", left=-1, right=3, bottom=-2, top=2, near=1, far=3)).camera
    assert camera.kind == "frustum"
    np.testing.assert_allclose(camera.projection, [[0.5, 0, 0.5, 0], [0, 0.5, 0, 0], [0, 0, -2, -3], [0, 0, -1, 0]])


def test_gl_ortho_pixel_camera():
    """glOrtho(0, 128, 0, 96, −1, 1): x_ndc = x/64 − 1, y_ndc = y/48 − 1, z_ndc = −z."""
    data = minimal(width=128, height=96,
                   camera={"projection": "orthographic", "left": 0, "right": 128, "bottom": 0, "top": 96,
                           "near": -1, "far": 1})
    camera = load_scene(data).camera
    assert camera.kind == "orthographic"
    np.testing.assert_allclose(camera.projection, [[1 / 64, 0, 0, -1], [0, 1 / 48, 0, -1], [0, 0, -1, 0], [0, 0, 0, 1]])


def test_look_at_down_minus_x():
    """gluLookAt(eye (3,0,0), target 0, up y): f = (−1,0,0), s = f × up = (0,0,−1), u = s × f = (0,1,0);
    rows s, u, −f, then translate(−eye).  The eye maps to the origin, the target to (0,0,−3)."""
    view = load_scene(with_camera(eye=[3, 0, 0], target=[0, 0, 0], up=[0, 1, 0])).camera.view
    np.testing.assert_allclose(view, [[0, 0, -1, 0], [0, 1, 0, 0], [1, 0, 0, -3], [0, 0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(view @ [0, 0, 0, 1], [0, 0, -3, 1], atol=1e-15)


def test_default_view_looks_down_minus_z_from_eye():
    """Eye alone: target = eye − z, up = +y, so the view is translate(−eye); no eye: the identity."""
    view = load_scene(with_camera(eye=[1, 2, 3])).camera.view
    np.testing.assert_allclose(view, [[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3], [0, 0, 0, 1]], atol=1e-15)


def test_explicit_matrices_are_row_major():
    view = list(range(1, 17))
    scene = load_scene(with_camera(view_matrix=view, projection_matrix=[2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1, 7, 0, 0, 0, 1]))
    assert scene.camera.kind == "matrix"
    assert scene.camera.view[0].tolist() == [1, 2, 3, 4]          # first four numbers = first row
    assert scene.camera.projection[2, 3] == 7


# --------------------------------------------------------------------------- node transforms and draw order


def test_translate_rotate_scale_order():
    """local = T·R·S: (1,0,0) scaled by 2 -> (2,0,0), turned 90° about z -> (0,2,0),
    moved by (10,0,0) -> (10,2,0).  The axis (0,0,5) is normalised."""
    data = minimal()
    data["nodes"][0].update(translate=[10, 0, 0], rotate=[90, 0, 0, 5], scale=[2, 2, 2])
    np.testing.assert_allclose(first_draw(data).world @ [1, 0, 0, 1], [10, 2, 0, 1], atol=1e-12)


def test_rotate_is_counter_clockwise_like_gl_rotate():
    """glRotate(90, 1, 0, 0) takes +y to +z."""
    data = minimal()
    data["nodes"][0]["rotate"] = [90, 1, 0, 0]
    np.testing.assert_allclose(first_draw(data).world @ [0, 1, 0, 0], [0, 0, 1, 0], atol=1e-12)


def test_world_is_parent_times_local():
    """Parent translate (1,0,0), child scale 2: (1,0,0) -> (2,0,0) -> (3,0,0).
    The other order (local · parent) would give (4,0,0)."""
    data = minimal(nodes=[{"translate": [1, 0, 0], "children": [{"scale": [2, 2, 2], "mesh": TRIANGLE}]}])
    np.testing.assert_allclose(first_draw(data).world @ [1, 0, 0, 1], [3, 0, 0, 1])


def test_node_matrix_is_row_major():
    data = minimal()
    data["nodes"][0]["matrix"] = [1, 0, 0, 7, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    np.testing.assert_array_equal(first_draw(data).world @ [0, 0, 0, 1], [7, 0, 0, 1])


def test_draw_order_is_depth_first_parents_first():
    tree = [
        {"name": "a", "mesh": TRIANGLE, "children": [
            {"name": "b", "mesh": TRIANGLE, "children": [{"name": "c", "mesh": TRIANGLE}]},
            {"name": "group", "translate": [0, 0, 1], "children": [{"name": "d", "mesh": TRIANGLE}]}]},
        {"name": "e", "mesh": TRIANGLE},
    ]
    draws = load_scene(minimal(nodes=tree)).draws
    assert [d.name for d in draws] == ["a", "b", "c", "d", "e"]
    assert [d.path for d in draws] == ["nodes[0]", "nodes[0].children[0]", "nodes[0].children[0].children[0]",
                                      "nodes[0].children[1].children[0]", "nodes[1]"]
    assert draws[3].world[2, 3] == 1            # the mesh-less group passes its transform on


# --------------------------------------------------------------------------- files and textures


def test_file_and_dict_load_the_same(tmp_path):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(minimal()))
    from_file = load_scene(path)
    assert from_file.source == str(path)
    np.testing.assert_array_equal(from_file.draws[0].mesh.positions, load_scene(minimal()).draws[0].mesh.positions)


def test_texture_path_resolves_against_scene_folder(tmp_path, monkeypatch):
    folder = tmp_path / "scenes"
    (folder / "textures").mkdir(parents=True)
    # A real image: the loader decodes texture files (a corrupt one is a SceneError).
    from PIL import Image
    Image.new("RGBA", (2, 2)).save(folder / "textures" / "checker.png")
    data = minimal(textures={"checker": {"image": "textures/checker.png", "min_filter": "linear"}})
    data["nodes"][0]["mesh"]["uvs"] = [[0, 1], [1, 1], [0, 0]]
    data["nodes"][0]["material"] = {"texture": "checker"}
    (folder / "scene.json").write_text(json.dumps(data))
    monkeypatch.chdir(tmp_path)                                  # not the scene's folder
    texture = load_scene("scenes/scene.json").textures["checker"]
    assert texture.image == str(folder / "textures" / "checker.png")
    assert (texture.wrap_s, texture.wrap_t, texture.min_filter, texture.mag_filter) == ("repeat", "repeat", "linear", "linear")
    assert texture.max_anisotropy == 1 and texture.procedural is None


def test_procedural_texture_parameters():
    data = minimal(textures={"c": {"procedural": "checker", "size": [64, 32], "squares": 4}})
    texture = load_scene(data).textures["c"]
    assert (texture.image, texture.procedural, texture.size) == (None, "checker", (64, 32))
    assert texture.params["squares"] == 4
    np.testing.assert_array_equal(texture.params["color1"], [1, 1, 1, 1])
    assert texture.min_filter == "nearest_mipmap_linear"        # GL's default


# --------------------------------------------------------------------------- procedural meshes


def _signed_areas_z(positions, indices):
    a, b, c = (positions[indices[:, k]] for k in range(3))
    return np.cross(b - a, c - a)[:, 2]


def test_grid_mesh():
    """2 x 1 cells of size [4, 2]: 6 vertices, row 0 at the top (y = +1) with v = 0."""
    positions, indices, colors, normals, uvs = meshes.grid(2, 1, (4, 2))
    assert positions.shape == (6, 3) and indices.shape == (4, 3) and colors is None
    np.testing.assert_array_equal(positions[0], [-2, 1, 0])
    np.testing.assert_array_equal(uvs[0], [0, 0])
    np.testing.assert_array_equal(positions[-1], [2, -1, 0])
    np.testing.assert_array_equal(uvs[-1], [1, 1])
    assert (_signed_areas_z(positions, indices) > 0).all()     # counter-clockwise seen from +z
    np.testing.assert_array_equal(normals, np.tile([0, 0, 1], (6, 1)))


def test_grid_corner_colours_in_scene():
    data = minimal()
    data["nodes"][0]["mesh"] = {"procedural": "grid", "cols": 2, "rows": 2,
                                "corner_colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]}
    mesh = first_draw(data).mesh
    # vertex 0 is the top-left corner, vertex 4 the centre (average of the four corners)
    np.testing.assert_allclose(mesh.colors[0], [1, 1, 1, 1])
    np.testing.assert_allclose(mesh.colors[4], [0.5, 0.5, 0.5, 1])


def test_sphere_mesh_faces_outwards():
    positions, indices, colors, normals, uvs = meshes.sphere(8, 5, radius=2.0)
    assert len(indices) == meshes.triangle_count("sphere", segments=8, rings=5) == 8 * (2 * 5 - 2)
    np.testing.assert_allclose(np.linalg.norm(positions, axis=1), 2.0)
    a, b, c = (positions[indices[:, k]] for k in range(3))
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c)
    assert (outward > 0).all()
    assert uvs.min() == 0 and uvs.max() == 1


@pytest.mark.parametrize("angle, vertices", [(360, 7), (90, 8)])
def test_fan_mesh_shares_edges(angle, vertices):
    positions, indices, *_ = meshes.fan(6, radius=1.0, angle=angle)
    assert len(positions) == vertices and len(indices) == 6
    assert (indices[:, 0] == 0).all()
    np.testing.assert_array_equal(indices[:-1, 2], indices[1:, 1])      # consecutive triangles share an edge
    assert (_signed_areas_z(positions, indices) > 0).all()


def test_procedural_triangle_budget():
    data = minimal()
    data["nodes"][0]["mesh"] = {"procedural": "grid", "cols": 2048, "rows": 1025}
    with pytest.raises(SceneError, match=r"^nodes\[0\]\.mesh: this grid has 4198400 triangles"):
        load_scene(data)


# --------------------------------------------------------------------------- bad input


def _set(path, value):
    """A function that sets data[path...] = value (path of keys and indices)."""
    def apply(data):
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return apply


def _delete(path):
    def apply(data):
        target = data
        for key in path[:-1]:
            target = target[key]
        del target[path[-1]]
    return apply


MESH = ("nodes", 0, "mesh")
BAD = [
    ("unknown_top_key", _set(("colour",), 1), "colour"),
    ("unknown_node_key", _set(("nodes", 0, "transform"), 1), "nodes[0].transform"),
    ("unknown_mesh_key", _set(MESH + ("colours",), []), "nodes[0].mesh.colours"),
    ("unknown_camera_key", _set(("camera",), {"fov": 60}), "camera.fov"),
    ("missing_version", _delete(("softras_scene",)), "softras_scene"),
    ("wrong_version", _set(("softras_scene",), 2), "softras_scene"),
    ("missing_width", _delete(("width",)), "width"),
    ("width_float", _set(("width",), 8.0), "width"),
    ("width_bool", _set(("width",), True), "width"),
    ("width_zero", _set(("width",), 0), "width"),
    ("width_too_big", _set(("width",), 16385), "width"),
    ("height_negative", _set(("height",), -3), "height"),
    ("too_many_pixels", lambda d: d.update(width=16384, height=4097), "width"),
    ("samples_2", _set(("samples",), 2), "samples"),
    ("background_nan", _set(("background",), [0, float("nan"), 0, 1]), "background[1]"),
    ("background_too_bright", _set(("background",), [0, 2, 0, 1]), "background[1]"),
    ("background_length", _set(("background",), [0, 0]), "background"),
    ("position_inf", _set(MESH + ("positions",), [[0, 0, 0], [1, 0, float("inf")], [0, 1, 0]]), "nodes[0].mesh.positions[1][2]"),
    ("position_bool", _set(MESH + ("positions",), [[0, 0, 0], [1, 0, 0], [0, True, 0]]), "nodes[0].mesh.positions[2][1]"),
    ("position_string", _set(MESH + ("positions",), [[0, 0, 0], [1, 0, "0"], [0, 1, 0]]), "nodes[0].mesh.positions[1][2]"),
    ("position_length", _set(MESH + ("positions",), [[0, 0, 0], [1, 0], [0, 1, 0]]), "nodes[0].mesh.positions[1]"),
    ("positions_empty", _set(MESH + ("positions",), []), "nodes[0].mesh.positions"),
    ("positions_not_multiple_of_3", _set(MESH + ("positions",), [[0, 0, 0], [1, 0, 0]]), "nodes[0].mesh.positions"),
    ("index_out_of_range", _set(MESH + ("indices",), [[0, 1, 2], [0, 1, 3]]), "nodes[0].mesh.indices[1]"),
    ("index_negative", _set(MESH + ("indices",), [[0, -1, 2]]), "nodes[0].mesh.indices[0]"),
    ("index_float", _set(MESH + ("indices",), [[0, 1.0, 2]]), "nodes[0].mesh.indices[0][1]"),
    ("index_triplet_length", _set(MESH + ("indices",), [[0, 1]]), "nodes[0].mesh.indices[0]"),
    ("flat_index_out_of_range", _set(MESH + ("indices",), [0, 1, 2, 0, 5, 1]), "nodes[0].mesh.indices[4]"),
    ("colors_count", _set(MESH + ("colors",), [[1, 0, 0], [0, 1, 0]]), "nodes[0].mesh.colors"),
    ("colors_mixed_lengths", _set(MESH + ("colors",), [[1, 0, 0], [0, 1, 0, 1], [0, 0, 1]]), "nodes[0].mesh.colors[1]"),
    ("uvs_width", _set(MESH + ("uvs",), [[0, 0, 0]] * 3), "nodes[0].mesh.uvs[0]"),
    ("primitive_unknown", _set(MESH + ("primitive",), "quads"), "nodes[0].mesh.primitive"),
    ("procedural_unknown", _set(MESH, {"procedural": "torus"}), "nodes[0].mesh.procedural"),
    ("procedural_missing_count", _set(MESH, {"procedural": "grid", "cols": 2}), "nodes[0].mesh.rows"),
    ("procedural_with_positions", _set(MESH, {"procedural": "fan", "count": 3, "positions": []}), "nodes[0].mesh.positions"),
    ("sphere_too_few_segments", _set(MESH, {"procedural": "sphere", "segments": 2, "rings": 4}), "nodes[0].mesh.segments"),
    ("fan_angle_zero", _set(MESH, {"procedural": "fan", "count": 3, "angle": 0}), "nodes[0].mesh.angle"),
    ("matrix_and_translate", lambda d: d["nodes"][0].update(matrix=list(range(16)), translate=[0, 0, 0]), "nodes[0].translate"),
    ("matrix_15_numbers", _set(("nodes", 0, "matrix"), [0] * 15), "nodes[0].matrix"),
    ("rotate_zero_axis", _set(("nodes", 0, "rotate"), [30, 0, 0, 0]), "nodes[0].rotate"),
    ("scale_length", _set(("nodes", 0, "scale"), [1, 1]), "nodes[0].scale"),
    ("depth_test_unknown", _set(("nodes", 0, "depth_test"), "lesser"), "nodes[0].depth_test"),
    ("depth_write_int", _set(("nodes", 0, "depth_write"), 1), "nodes[0].depth_write"),
    ("cull_unknown", _set(("nodes", 0, "cull"), "both"), "nodes[0].cull"),
    ("blend_unknown", _set(("nodes", 0, "blend"), "multiply"), "nodes[0].blend"),
    ("child_error_place", _set(("nodes", 0, "children"), [{"mesh": TRIANGLE}, {"mesh": {"positions": "x"}}]),
     "nodes[0].children[1].mesh.positions"),
    ("state_without_mesh", _set(("nodes",), [{"cull": "back"}]), "nodes[0].cull"),
    ("nodes_not_list", _set(("nodes",), {"a": 1}), "nodes"),
    ("material_unknown_shading", _set(("nodes", 0, "material"), {"shading": "toon"}), "nodes[0].material.shading"),
    ("material_negative", _set(("nodes", 0, "material"), {"diffuse": -1}), "nodes[0].material.diffuse"),
    ("material_unknown_texture", _set(("nodes", 0, "material"), {"texture": "wood"}), "nodes[0].material.texture"),
    ("phong_without_normals", _set(("nodes", 0, "material"), {"shading": "phong"}), "nodes[0].mesh"),
    ("texture_without_uvs", lambda d: d.update(textures={"t": {"procedural": "noise", "size": [4, 4]}},
                                               nodes=[{"mesh": TRIANGLE, "material": {"texture": "t"}}]), "nodes[0].mesh"),
    ("texture_missing_file", _set(("textures",), {"t": {"image": "does/not/exist.png"}}), "textures.t.image"),
    ("texture_image_and_procedural", _set(("textures",), {"t": {"image": "a.png", "procedural": "noise"}}), "textures.t"),
    ("texture_bad_wrap", _set(("textures",), {"t": {"procedural": "noise", "size": [4, 4], "wrap_s": "clamp"}}), "textures.t.wrap_s"),
    ("texture_bad_filter", _set(("textures",), {"t": {"procedural": "noise", "size": [4, 4], "mag_filter": "linear_mipmap_linear"}}), "textures.t.mag_filter"),
    ("texture_anisotropy", _set(("textures",), {"t": {"procedural": "noise", "size": [4, 4], "max_anisotropy": 32}}), "textures.t.max_anisotropy"),
    ("texture_param_of_other_kind", _set(("textures",), {"t": {"procedural": "noise", "size": [4, 4], "squares": 2}}), "textures.t.squares"),
    ("light_unknown_type", _set(("lights",), [{"type": "spot", "position": [0, 0, 0]}]), "lights[0].type"),
    ("point_light_direction", _set(("lights",), [{"type": "point", "position": [0, 0, 0], "direction": [0, 0, 1]}]), "lights[0].direction"),
    ("directional_zero", _set(("lights",), [{"type": "directional", "direction": [0, 0, 0]}]), "lights[0].direction"),
    ("camera_unknown_projection", _set(("camera",), {"projection": "fisheye"}), "camera.projection"),
    ("camera_missing_near", _set(("camera",), {"projection": "perspective", "fov_y": 60, "far": 10}), "camera.near"),
    ("camera_fov_180", _set(("camera",), {"projection": "perspective", "fov_y": 180, "near": 1, "far": 2}), "camera.fov_y"),
    ("camera_near_zero", _set(("camera",), {"projection": "perspective", "fov_y": 60, "near": 0, "far": 2}), "camera.near"),
    ("camera_far_before_near", _set(("camera",), {"projection": "frustum", "left": -1, "right": 1, "bottom": -1,
                                                  "top": 1, "near": 2, "far": 1}), "camera.far"),
    ("camera_ortho_left_equals_right", _set(("camera",), {"projection": "orthographic", "left": 1, "right": 1,
                                                          "bottom": -1, "top": 1, "near": -1, "far": 1}), "camera.right"),
    ("camera_fov_on_ortho", _set(("camera",), {"projection": "orthographic", "fov_y": 60, "left": 0, "right": 1,
                                               "bottom": 0, "top": 1, "near": -1, "far": 1}), "camera.fov_y"),
    ("camera_eye_is_target", _set(("camera",), {"eye": [1, 1, 1], "target": [1, 1, 1]}), "camera.target"),
    ("camera_up_parallel", _set(("camera",), {"eye": [0, 0, 0], "target": [0, 5, 0]}), "camera.up"),
    ("camera_matrix_and_eye", _set(("camera",), {"view_matrix": list(range(16)), "eye": [0, 0, 1]}), "camera.eye"),
    ("camera_matrix_and_projection", _set(("camera",), {"projection_matrix": list(range(16)), "projection": "perspective"}), "camera.projection"),
    ("camera_matrix_nan", _set(("camera",), {"projection_matrix": [0] * 15 + [float("nan")]}), "camera.projection_matrix[15]"),
    ("tolerance_unknown", _set(("tolerance",), {"ssim": 0.9}), "tolerance.ssim"),
    ("tolerance_threshold_float", _set(("tolerance",), {"threshold": 2.5}), "tolerance.threshold"),
    ("description_not_string", _set(("description",), 3), "description"),
]


@pytest.mark.parametrize("mutate, place", [case[1:] for case in BAD], ids=[case[0] for case in BAD])
def test_bad_input_reports_its_place(mutate, place):
    data = minimal()
    mutate(data)
    with pytest.raises(SceneError) as info:
        load_scene(data)
    message = str(info.value)
    assert message.startswith(place + ": "), message
    assert "\n" not in message
    assert info.value.place == place


def test_top_level_not_an_object_from_dict_api():
    with pytest.raises(SceneError, match=r"^scene: expected a file path"):
        load_scene(42)


def test_too_many_pixels_is_refused_before_allocating():
    """16384 x 4097 is just over MAX_PIXELS = 64 Mi; the error names both sides."""
    assert 16384 * 4096 == MAX_PIXELS
    with pytest.raises(SceneError, match=r"^width: 16384 x 4097"):
        load_scene(minimal(width=16384, height=4097))


@pytest.mark.parametrize("text, reason", [
    ('{"softras_scene": 1,\n "width": 8\n "height": 6}', "invalid JSON at line 3 column 2"),
    ('{"softras_scene": 1, "width": NaN}', "invalid JSON: NaN is not a number JSON allows"),
    ('{"width": 8, "width": 9}', "invalid JSON: duplicate key 'width'"),
    ('[1, 2]', "the top level must be a JSON object"),
    ('', "invalid JSON at line 1 column 1"),
])
def test_bad_files(tmp_path, text, reason):
    path = tmp_path / "scene.json"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(str(path))
    assert str(info.value).startswith(f"{path}: {reason}"), str(info.value)


def _same_json(a, b) -> bool:
    """Whether two parsed JSON values are equal with the same types, floats
    to the bit; but where b holds an integer beyond 64 bits, a may hold it
    as the float nearest to it (orjson reads it so, `parse._fast_json`)."""
    if isinstance(a, float) and type(b) is int and not -2**63 <= b < 2**64:
        return np.float64(a).tobytes() == np.float64(float(b)).tobytes()
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same_json(a[key], b[key]) for key in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same_json(x, y) for x, y in zip(a, b))
    if isinstance(a, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    return a == b


def _json_value(data):
    """Hypothesis data -> JSON text of a random value whose objects may
    repeat a key, and whose strings may hold colons and quotes, plain or
    escaped."""
    from hypothesis import strategies as st

    keys = st.sampled_from(["a", "b", "near", "x:y", 'q"t', "c\\:"])
    leaves = (st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.sampled_from([0, -0.0, 5e-324, 1e308])
              | st.floats(allow_nan=False, allow_infinity=False) | st.text(alphabet='ab:"\\ ', max_size=4))
    escaped = st.sampled_from(['"\\u003a"', '"a\\u003a\\u0022"'])        # (":" and 'a:"' as escapes)
    tree = st.recursive(leaves.map(json.dumps) | escaped, lambda inner: (
        st.lists(inner, max_size=4).map(lambda items: "[" + ",".join(items) + "]")
        | st.lists(st.tuples(keys, inner), max_size=4).map(
            lambda pairs: "{" + ", ".join(f"{json.dumps(k)} : {v}" for k, v in pairs) + "}")), max_leaves=12)
    return data.draw(tree)


def test_the_fast_parse_is_json_s_or_leaves_the_file_to_json():
    """`parse._fast_json` (orjson) gives json's document, types and float
    bits included, or `_UNDECIDED` (json decides): on random documents with
    duplicate keys, colons and quotes in strings, integers beyond 64 bits
    (read as the nearest float: `load_scene` validates json's document
    again when a scene is refused, `test_a_file_loads_as_json_reads_it`),
    subnormals.  A duplicate key, which orjson would take silently, is
    never let through."""
    from hypothesis import given, settings, strategies as st

    from softras.scene import parse

    @settings(max_examples=400, derandomize=True, database=None, deadline=None)
    @given(st.data())
    def check(data):
        text = _json_value(data)
        fast = parse._fast_json(text.encode())
        try:
            exact = json.loads(text, object_pairs_hook=parse._no_duplicate_keys)
        except ValueError:
            assert fast is parse._UNDECIDED, text
            return
        assert fast is parse._UNDECIDED or _same_json(fast, exact), text

    check()
    # The scene files take the fast parse, and so do colons in keys and strings.
    texts = [open(os.path.join(SCENES_DIR, name), "rb").read()
             for name in ("lit_spheres.json", "fill_rule_grid.json", "explicit_matrices.json")]
    texts.append(b'{"a:b": "c:d", "e" : ["f:g", {"h": "i::j"}], "k": [[1, 2], [3, 4]]}')
    for raw in texts:
        assert _same_json(parse._fast_json(raw), json.loads(raw)), raw[:60]


@pytest.mark.parametrize("text", [
    '{"softras_scene": 1, "width": 8, "height": 6, "camera": {"near": 1, "near": 2}}',
    '{"softras_scene": 1, "width": 18446744073709551616, "height": 6}',
    '{"softras_scene": 1, "width": 8, "height": 6, "background": [1e400, 0, 0]}',
    '{"softras_scene": 1,\r\n "width": 8\r\n "height": 6}',
    '{"softras_scene": 1, "width": 8, "height": 6, "nodes": [{"name": "a\\":b", "mesh": {"procedural": "quad"}},'
    ' {"name": "c", "mesh": {"positions": [[0, 0, 0], [1, 0, 123456789012345678901234567890], [0, 1, 0]],'
    ' "indices": [[0, 1, 2]]}}]}',
])
def test_a_file_loads_as_json_reads_it(tmp_path, text):
    """A scene file gives the scene, or the error, of json's document (read
    as text, NaN and duplicate keys refused, as before orjson): a nested
    duplicate key, an integer beyond 64 bits where an integer belongs (orjson
    reads it as a float), a number that overflows to infinity, an error on a
    line after CRLF line ends, a colon in a string, an integer beyond 64
    bits where a float belongs."""
    from softras.scene import parse

    path = tmp_path / "scene.json"
    path.write_bytes(text.encode())

    def outcome(load):
        try:
            scene = load()
        except SceneError as error:
            return str(error)
        return [(draw.path, draw.mesh.positions.tobytes(), draw.mesh.indices.tobytes()) for draw in scene.draws]

    with open(path, encoding="utf-8") as file:
        document = file.read()

    def as_before():
        try:
            data = json.loads(document, parse_constant=parse._reject_constant,
                              object_pairs_hook=parse._no_duplicate_keys)
        except ValueError as error:
            raise SceneError(str(path), f"invalid JSON: {error}") from None
        return parse.scene_from_dict(data, source=str(path), base_dir=str(tmp_path))

    expected = outcome(as_before)
    got = outcome(lambda: load_scene(str(path)))
    if isinstance(expected, str) and expected.startswith(f"{path}: invalid JSON"):
        assert got.startswith(f"{path}: invalid JSON"), got     # (json's message, with its line and column)
        assert ("duplicate key" in got) == ("duplicate key" in expected)
    else:
        assert got == expected


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(SceneError, match="no such file$"):
        load_scene(tmp_path / "missing.json")
    with pytest.raises(SceneError, match="is a folder"):
        load_scene(tmp_path)


# --------------------------------------------------------------------------- the conformance scenes


SCENE_FILES = sorted(glob.glob(os.path.join(SCENES_DIR, "*.json")))


def test_there_are_conformance_scenes():
    assert len(SCENE_FILES) >= 14


@pytest.mark.parametrize("path", SCENE_FILES, ids=[os.path.basename(p)[:-5] for p in SCENE_FILES])
def test_conformance_scene_loads(path):
    scene = load_scene(path)
    assert isinstance(scene, Scene) and scene.draws and scene.description
    for draw in scene.draws:
        assert np.isfinite(draw.world).all()
        if draw.mesh.colors is not None:
            assert -1e-12 <= draw.mesh.colors.min() and draw.mesh.colors.max() <= 1 + 1e-12
        if draw.material.texture is not None:
            assert draw.mesh.uvs is not None and draw.material.texture in scene.textures


# --------------------------------------------------------------------------- normal, bump and displacement maps

LIT_QUAD = {"procedural": "grid", "cols": 1, "rows": 1}      # normals and uvs
HEIGHTS = {"h": {"procedural": "bumps", "size": [8, 8]}}


def mapped(material, mesh=LIT_QUAD, textures=HEIGHTS):
    """A scene whose one node has ``material`` and ``mesh``."""
    return minimal(textures=copy.deepcopy(textures),
                   nodes=[{"mesh": copy.deepcopy(mesh), "material": material}])


BAD_MAPS = [
    ("normal_map_on_gouraud", {"shading": "gouraud", "normal_map": "h"}, LIT_QUAD, "nodes[0].material.normal_map"),
    ("bump_map_unlit", {"bump_map": "h"}, LIT_QUAD, "nodes[0].material.bump_map"),
    ("normal_map_unknown_texture", {"shading": "phong", "normal_map": "wood"}, LIT_QUAD, "nodes[0].material.normal_map"),
    ("normal_map_not_string", {"shading": "phong", "normal_map": 1}, LIT_QUAD, "nodes[0].material.normal_map"),
    ("both_maps", {"shading": "phong", "normal_map": "h", "bump_map": "h"}, LIT_QUAD, "nodes[0].material.bump_map"),
    ("bump_scale_without_map", {"shading": "phong", "bump_scale": 2}, LIT_QUAD, "nodes[0].material.bump_scale"),
    ("bump_scale_nan", {"shading": "phong", "bump_map": "h", "bump_scale": float("nan")}, LIT_QUAD,
     "nodes[0].material.bump_scale"),
    ("bump_map_without_uvs", {"shading": "phong", "bump_map": "h"},
     dict(TRIANGLE, normals=[[0, 0, 1]] * 3), "nodes[0].mesh"),
    ("displacement_not_object", {"displacement": "h"}, LIT_QUAD, "nodes[0].material.displacement"),
    ("displacement_missing_scale", {"displacement": {"texture": "h"}}, LIT_QUAD, "nodes[0].material.displacement.scale"),
    ("displacement_unknown_key", {"displacement": {"texture": "h", "scale": 1, "bias": 0}}, LIT_QUAD,
     "nodes[0].material.displacement.bias"),
    ("displacement_unknown_texture", {"displacement": {"texture": "x", "scale": 1}}, LIT_QUAD,
     "nodes[0].material.displacement.texture"),
    ("displacement_scale_inf", {"displacement": {"texture": "h", "scale": float("inf")}}, LIT_QUAD,
     "nodes[0].material.displacement.scale"),
    ("displacement_without_normals", {"displacement": {"texture": "h", "scale": 1}},
     dict(TRIANGLE, uvs=[[0, 0], [1, 0], [0, 1]]), "nodes[0].material.displacement"),
    ("displacement_zero_normal", {"displacement": {"texture": "h", "scale": 1}},
     dict(TRIANGLE, uvs=[[0, 0], [1, 0], [0, 1]], normals=[[0, 0, 1], [0, 0, 0], [0, 0, 1]]),
     "nodes[0].material.displacement"),
    ("displacement_of_lines", {"displacement": {"texture": "h", "scale": 1}},
     {"primitive": "lines", "positions": [[0, 0, 0], [1, 0, 0]], "normals": [[0, 0, 1]] * 2, "uvs": [[0, 0]] * 2},
     "nodes[0].material.displacement"),
]


@pytest.mark.parametrize("material, mesh, place", [case[1:] for case in BAD_MAPS], ids=[case[0] for case in BAD_MAPS])
def test_bad_map_keys_report_their_place(material, mesh, place):
    with pytest.raises(SceneError) as info:
        load_scene(mapped(material, mesh))
    message = str(info.value)
    assert message.startswith(place + ": "), message
    assert "\n" not in message


def test_bumps_texture_cells_is_validated():
    with pytest.raises(SceneError, match=r"^textures\.h\.cells: "):
        load_scene(mapped({}, textures={"h": {"procedural": "bumps", "size": [8, 8], "cells": 0}}))
    assert load_scene(mapped({}, textures=HEIGHTS)).textures["h"].params == {"cells": 4}


def test_map_keys_are_stored_and_displacement_moves_the_mesh():
    material = load_scene(mapped({"shading": "phong", "bump_map": "h", "bump_scale": 3})).draws[0].material
    assert (material.bump_map, material.bump_scale, material.normal_map) == ("h", 3.0, None)
    material = load_scene(mapped({"shading": "phong", "normal_map": "h"})).draws[0].material
    assert (material.normal_map, material.bump_map, material.displacement) == ("h", None, None)
    # A constant height 255 (bumps with 1 cell is 0 at the corners: use a gradient of one colour).
    flat = {"h": {"procedural": "gradient", "size": [4, 4], "color0": [1, 1, 1, 1], "color1": [1, 1, 1, 1]}}
    draw = load_scene(mapped({"displacement": {"texture": "h", "scale": 0.25}}, textures=flat)).draws[0]
    assert (draw.material.displacement.texture, draw.material.displacement.scale) == ("h", 0.25)
    np.testing.assert_allclose(draw.mesh.positions[:, 2], 0.25)
    np.testing.assert_array_equal(draw.mesh.normals, np.tile([0.0, 0.0, 1.0], (4, 1)))
    assert not draw.mesh.positions.flags.writeable


def test_cross3_is_np_cross_bit_for_bit():
    """scene.cross3 (look_at and the camera check) computes np.cross's doubles."""
    from softras.scene import cross3
    rng = np.random.default_rng(5)
    for scale in (1e-300, 1e-8, 1.0, 1e8, 1e300):
        for a, b in zip(rng.normal(size=(200, 3)) * scale, rng.normal(size=(200, 3))):
            assert cross3(a, b).tobytes() == np.cross(a, b).tobytes()


@pytest.mark.parametrize("eye, message", [
    ([0, True, 3], r"^camera\.eye\[1\]: expected a number, got a boolean$"),
    ([0, "1", 3], r"^camera\.eye\[1\]: expected a number, got the string '1'$"),
    ([0, 1, 10 ** 400], r"^camera\.eye\[2\]: number too large$"),
    ([0, float("inf"), 3], r"^camera\.eye\[1\]: expected a finite number, got inf$"),
    ([0, None, 3], r"^camera\.eye\[1\]: expected a number, got null$"),
])
def test_vector_numbers_are_checked_one_by_one(eye, message):
    with pytest.raises(SceneError, match=message):
        load_scene(with_camera(eye=eye, target=[0, 0, -5]))


def test_vector_numbers_keep_their_value():
    """Ints beyond 2^53 and numpy numbers take the checked path; the value is float(x) either way."""
    big = 2 ** 60 + 1
    view = load_scene(with_camera(eye=[big, np.float32(0.5), 3], target=[0, 0, -5])).camera.view
    np.testing.assert_array_equal(view[:3, 3], -(view[:3, :3] @ [float(big), 0.5, 3.0]))
    with pytest.raises(SceneError, match=r"^background\[3\]: 1\.5 is out of range \[0, 1\]$"):
        load_scene(minimal(background=[0, 0, 0, 1.5]))
