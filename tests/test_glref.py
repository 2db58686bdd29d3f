"""Tests of glref, the OpenGL reference renderer (docs/design.md sections 4, 5, 9).

Every scene here is built by hand so the expected pixels follow from GL's rules
alone: an orthographic camera maps world x, y straight to window coordinates
(left=0, right=W, bottom=0, top=H, near=-1, far=1, eye at the origin looking
down -z), so a vertex at (x, y, z) lands at x_w = x, y_w = y (y up, GL window
coordinates) and z_ndc = -z (larger z is nearer). Pixel (i, j) has its centre
at (i+0.5, j+0.5); the returned image has row 0 = the top, so window row j is
image row H-1-j.
"""

from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np
import pytest

import glref

pytestmark = pytest.mark.gl


@pytest.fixture(scope="module", autouse=True)
def gl_context():
    """A missing GL context fails the tests unless SOFTRAS_ALLOW_NO_GL=1 (docs/design.md section 9)."""
    try:
        return glref.info()
    except glref.GLUnavailable as exc:
        if os.environ.get("SOFTRAS_ALLOW_NO_GL") == "1":
            pytest.skip(str(exc))
        pytest.fail(str(exc))


# --------------------------------------------------------------------------- helpers

def quad(x0, y0, x1, y1, z=0.0):
    """Positions and CCW (in window coordinates) indices of an axis-aligned rectangle."""
    return {"positions": [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]],
            "indices": [[0, 1, 2], [0, 2, 3]]}


def node(mesh, color=(1, 1, 1, 1), **state):
    """A scene node with an unlit material; `state` gives depth_test, blend, cull, ..."""
    return {"mesh": mesh, "material": {"color": list(color)}, **state}


def make_scene(width, height, nodes, background=(0, 0, 0, 1), samples=1):
    """Load a scene dict through softras.scene.load_scene (the one scene model)."""
    from softras.scene import load_scene
    return load_scene({
        "softras_scene": 1,
        "width": width, "height": height,
        "background": list(background),
        "samples": samples,
        "camera": {"projection": "orthographic", "left": 0, "right": width,
                   "bottom": 0, "top": height, "near": -1, "far": 1},
        "nodes": nodes,
    })


def u8(*c):
    """Straight-alpha float RGBA -> the premultiplied RGBA8 value GL stores (round(c*255))."""
    c = np.asarray(c, np.float64)
    return np.round(np.concatenate([c[:3] * c[3], c[3:]]) * 255).astype(np.uint8)


def window_mask(image_mask):
    """Flip a boolean mask written in GL window rows (row 0 = bottom) to image rows."""
    return np.asarray(image_mask, bool)[::-1]


# --------------------------------------------------------------------------- context

def test_info_reports_the_gl():
    info = glref.info()
    for key in ("GL_RENDERER", "GL_VERSION", "GL_VENDOR", "moderngl"):
        assert isinstance(info[key], str) and info[key]
    assert set(info["env"]) == {"GALLIUM_DRIVER", "GALLIVM_PERF", "LP_PERF", "LP_NUM_THREADS"}
    assert "depth_format" in info
    # info() hands out a copy: callers cannot change the cached record.
    info["env"]["LP_PERF"] = "changed"
    assert glref.info()["env"]["LP_PERF"] != "changed"


# --------------------------------------------------------------------------- readback

def test_readback_dtype_shape_and_background():
    img = glref.render(make_scene(5, 3, [], background=(0.2, 0.4, 0.6, 1.0)))
    assert img.dtype == np.uint8
    assert img.shape == (3, 5, 4)
    assert img.flags.c_contiguous
    assert (img == u8(0.2, 0.4, 0.6, 1.0)).all()


def test_background_is_premultiplied():
    img = glref.render(make_scene(2, 2, [], background=(1.0, 0.6, 0.2, 0.4)))
    assert (img == u8(1.0, 0.6, 0.2, 0.4)).all()   # (102, 61, 20, 102)


def test_full_screen_quad_gives_material_colour():
    img = glref.render(make_scene(6, 4, [node(quad(0, 0, 6, 4), (0.2, 0.4, 0.6, 1.0))]))
    assert (img == u8(0.2, 0.4, 0.6, 1.0)).all()


def test_output_is_vertex_colour_times_material_premultiplied():
    mesh = quad(0, 0, 2, 2)
    mesh["colors"] = [[1.0, 0.5, 1.0, 0.8]] * 4
    img = glref.render(make_scene(2, 2, [node(mesh, (0.5, 1.0, 0.2, 0.5))]))
    # colour (0.5, 0.5, 0.2, 0.4) -> premultiplied (0.2, 0.2, 0.08, 0.4)
    assert (img == u8(0.5, 0.5, 0.2, 0.4)).all()


def test_vertex_colours_are_interpolated():
    mesh = quad(0, 0, 4, 1)
    mesh["colors"] = [[0, 0, 0, 1], [1, 0, 0, 1], [1, 0, 0, 1], [0, 0, 0, 1]]
    img = glref.render(make_scene(4, 1, [node(mesh)]))
    # red = x at the pixel centres 0.5, 1.5, 2.5, 3.5 (of 4)
    expected = np.round(np.array([0.5, 1.5, 2.5, 3.5]) / 4 * 255)
    assert np.abs(img[0, :, 0].astype(int) - expected).max() <= 1


# --------------------------------------------------------------------------- coverage

def test_lower_left_half_triangle_covers_known_pixels():
    # x + y < 4: pixel centres with i + j + 1 < 4 are inside; the centres with
    # i + j == 3 lie exactly on the hypotenuse, a top/right edge: not covered.
    mesh = {"positions": [[0, 0, 0], [4, 0, 0], [0, 4, 0]], "indices": [[0, 1, 2]]}
    img = glref.render(make_scene(4, 4, [node(mesh, (1, 0, 0, 1))]))
    j, i = np.mgrid[0:4, 0:4]             # window row j (from the bottom), column i
    expected = window_mask(i + j < 3)
    assert ((img[..., 0] == 255) == expected).all(), img[..., 0]
    assert (img[~expected] == u8(0, 0, 0, 1)).all()


def test_row_zero_is_the_top_of_the_picture():
    # A triangle in the top-left corner of GL window coordinates (y up).
    mesh = {"positions": [[0, 4, 0], [0, 2, 0], [2, 4, 0]], "indices": [[0, 1, 2]]}
    img = glref.render(make_scene(4, 4, [node(mesh)]))
    lit = img[..., 0] == 255
    assert lit[0, 0]                      # image row 0 = window row 3 = top
    assert lit.sum() == 1                 # (1.5, 3.5) is on the right edge: excluded
    assert not lit[3, 0]


def test_node_transform_is_applied():
    n = node(quad(0, 0, 1, 1))
    n["translate"] = [3, 0, 0]
    img = glref.render(make_scene(4, 2, [n]))
    lit = img[..., 0] == 255
    assert lit.sum() == 1 and lit[1, 3]   # window pixel (3, 0) = image (row 1, col 3)


def test_perspective_camera():
    # A 2x2 quad at z=0 seen from z=3 with fov_y=60: half-height visible at
    # z=0 is 3*tan(30 deg) = 1.732, so the quad spans |x_ndc| < 0.577, i.e.
    # window x in (1.69, 6.31) of 8: pixel columns (and rows) 2..5.
    from softras.scene import load_scene
    scene = load_scene({
        "softras_scene": 1, "width": 8, "height": 8, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 10,
                   "eye": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0]},
        "nodes": [node(quad(-1, -1, 1, 1))]})
    lit = glref.render(scene)[..., 0] == 255
    expected = np.zeros((8, 8), bool)
    expected[2:6, 2:6] = True
    assert (lit == expected).all(), lit.astype(int)


def test_lines_width_one():
    mesh = {"primitive": "lines", "positions": [[0, 0.5, 0], [4, 0.5, 0]], "indices": [[0, 1]]}
    img = glref.render(make_scene(4, 3, [node(mesh)]))
    lit = img[..., 0] == 255
    assert lit[2].all() and not lit[:2].any()   # window row 0 = image row 2


# --------------------------------------------------------------------------- depth

RED, GREEN = (1, 0, 0, 1), (0, 1, 0, 1)


@pytest.mark.parametrize("func, winner", [("less", GREEN), ("lequal", GREEN),
                                          ("greater", RED), ("always", GREEN),
                                          ("never", (0, 0, 0, 1))])
def test_depth_func(func, winner):
    # red far (z=-0.5 -> depth 0.75) drawn first, green near (z=0.5 -> 0.25) second;
    # both draws use `func` (the far one passes against the cleared 1.0 except
    # for "greater" and "never").
    nodes = [node(quad(0, 0, 2, 2, z=-0.5), RED, depth_test=func),
             node(quad(0, 0, 2, 2, z=+0.5), GREEN, depth_test=func)]
    if func == "greater":
        # Nothing passes "greater" against 1.0: draw red with "always" first.
        nodes[0]["depth_test"] = "always"
    img = glref.render(make_scene(2, 2, nodes))
    assert (img == u8(*winner)).all(), img[0, 0]


def test_near_first_occludes_with_less():
    nodes = [node(quad(0, 0, 2, 2, z=+0.5), GREEN, depth_test="less"),
             node(quad(0, 0, 2, 2, z=-0.5), RED, depth_test="less")]
    assert (glref.render(make_scene(2, 2, nodes)) == u8(*GREEN)).all()


def test_depth_test_disabled_draws_in_order_and_writes_no_depth():
    nodes = [node(quad(0, 0, 2, 2, z=+0.5), GREEN, depth_test="less"),
             node(quad(0, 0, 2, 2, z=-0.5), RED, depth_test=False),
             # would be hidden by green if red had written its depth 0.75... it
             # did not, so the stored depth is still green's 0.25
             node(quad(0, 0, 2, 2, z=0.0), (0, 0, 1, 1), depth_test="less")]
    assert (glref.render(make_scene(2, 2, nodes)) == u8(*RED)).all()


def test_depth_write_false_keeps_depth():
    nodes = [node(quad(0, 0, 2, 2, z=+0.5), GREEN, depth_write=False),
             node(quad(0, 0, 2, 2, z=-0.5), RED)]
    assert (glref.render(make_scene(2, 2, nodes)) == u8(*RED)).all()


# --------------------------------------------------------------------------- culling

CCW = {"positions": [[0, 0, 0], [2, 0, 0], [0, 2, 0]], "indices": [[0, 1, 2]]}
CW = {"positions": [[0, 0, 0], [2, 0, 0], [0, 2, 0]], "indices": [[0, 2, 1]]}


@pytest.mark.parametrize("cull, mesh, drawn", [("none", CCW, True), ("none", CW, True),
                                               ("back", CCW, True), ("back", CW, False),
                                               ("front", CCW, False), ("front", CW, True)])
def test_cull(cull, mesh, drawn):
    img = glref.render(make_scene(2, 2, [node(mesh, cull=cull)]))
    assert (img[1, 0, 0] == 255) == drawn   # window pixel (0, 0)


# --------------------------------------------------------------------------- blending

BG = (0.2, 0.4, 0.6, 1.0)


@pytest.mark.parametrize("blend, src, expected", [
    ("none", (0.4, 0.2, 0.2, 0.6), (0.24, 0.12, 0.12, 0.6)),
    ("over", (1.0, 0.0, 0.0, 0.6), (0.6 + 0.4 * 0.2, 0.4 * 0.4, 0.4 * 0.6, 1.0)),
    ("over_straight", (1.0, 0.0, 0.0, 0.6), (0.36 + 0.08, 0.16, 0.24, 0.36 + 0.4)),
    ("add", (0.4, 0.2, 0.2, 1.0), (0.6, 0.6, 0.8, 1.0)),
    ("subtract", (0.4, 0.2, 0.2, 1.0), (0.2, 0.0, 0.0, 0.0)),
    ("reverse_subtract", (0.4, 0.2, 0.2, 1.0), (0.0, 0.2, 0.4, 0.0)),
    ("min", (0.4, 0.2, 0.2, 1.0), (0.2, 0.2, 0.2, 1.0)),
    ("max", (0.4, 0.2, 0.2, 1.0), (0.4, 0.4, 0.6, 1.0)),
])
def test_blend_equations_on_premultiplied_colour(blend, src, expected):
    """`expected` is premultiplied RGBA: the GL equation on premultiplied src and dst."""
    img = glref.render(make_scene(2, 2, [node(quad(0, 0, 2, 2), src, blend=blend)],
                                  background=BG))
    want = np.round(np.asarray(expected) * 255)
    # blending happens on RGBA8 values: allow one step of rounding
    assert np.abs(img.astype(int) - want).max() <= 1, (img[0, 0], want)


# --------------------------------------------------------------------------- MSAA

def test_msaa_resolves_partial_coverage():
    mesh = {"positions": [[0, 0, 0], [4, 0, 0], [0, 4, 0]], "indices": [[0, 1, 2]]}
    scene = make_scene(4, 4, [node(mesh)], samples=4)
    img = glref.render(scene)
    single = glref.render(scene, samples=1)
    assert set(np.unique(single[..., 0])) <= {0, 255}
    # On the diagonal (i + j == 3) two of llvmpipe's four sample positions
    # (.375,.125) (.875,.375) (.125,.625) (.625,.875) have x + y < 1 in the pixel.
    j, i = np.mgrid[0:4, 0:4]
    diag = window_mask(i + j == 3)
    assert np.isin(img[..., 0][diag], (127, 128)).all(), img[..., 0]
    assert (img[..., 0][window_mask(i + j < 3)] == 255).all()
    assert (img[..., 0][window_mask(i + j > 3)] == 0).all()


def test_msaa_full_coverage_equals_single_sample():
    scene = make_scene(3, 2, [node(quad(0, 0, 3, 2), (0.2, 0.4, 0.6, 0.8))],
                       background=(0, 0, 1, 1), samples=4)
    assert (glref.render(scene) == glref.render(scene, samples=1)).all()


# --------------------------------------------------------------------------- robustness

def test_many_renders_stay_clean():
    """GL objects are released per render; state does not leak between renders."""
    blended = make_scene(4, 4, [node(quad(0, 0, 4, 4), (1, 0, 0, 0.5), blend="add",
                                     cull="front", depth_test="never")])
    plain = make_scene(4, 4, [node(quad(0, 0, 4, 4), (0, 1, 0, 1))])
    first = glref.render(plain)
    for _ in range(200):
        glref.render(blended)
        glref.render(blended, samples=4)
    assert (glref.render(plain) == first).all()
    assert (first == u8(*GREEN)).all()


def test_a_texture_shared_by_draws_is_uploaded_once_a_render(monkeypatch):
    """Each texture is uploaded (and its mipmaps generated) once per render,
    however many draws sample it, as an application would: a model of 64
    parts sharing a texture took glref 52 ms a render, 10 ms so
    (docs/speed.md, "Forty-second round").  The picture is the one of the
    same draws each with textures of its own (an upload each)."""
    import importlib

    import softras

    glref_render = importlib.import_module("glref.render")

    def scene(shared: bool):
        grid = {"procedural": "grid", "cols": 2, "rows": 2, "size": [0.8, 0.8]}
        textures, nodes = {}, []
        for k, (x, y) in enumerate([(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]):
            own = "" if shared else str(k)
            textures["checker" + own] = {"procedural": "checker", "size": [16, 16],
                                         "min_filter": "linear_mipmap_linear"}
            textures["bumps" + own] = {"procedural": "noise", "size": [16, 16], "min_filter": "linear"}
            nodes.append({"name": f"part{k}", "translate": [x, y, 0], "mesh": grid,
                          "material": {"shading": "phong", "texture": "checker" + own, "bump_map": "bumps" + own}})
        return softras.load_scene({"softras_scene": 1, "width": 32, "height": 32, "textures": textures,
                                   "lights": [{"type": "point", "position": [0, 0, 3]}], "nodes": nodes})

    uploads = []
    upload = glref_render._upload_texture

    def counted(ctx, texture, unit, mipmaps):
        uploads.append(texture.name)
        return upload(ctx, texture, unit, mipmaps)

    monkeypatch.setattr(glref_render, "_upload_texture", counted)
    shared = glref.render(scene(True))
    assert sorted(uploads) == ["bumps", "checker"]
    uploads.clear()
    assert np.array_equal(glref.render(scene(False)), shared)
    assert len(uploads) == 8


def test_unsupported_material_raises_before_rendering():
    draw = make_scene(2, 2, [node(quad(0, 0, 2, 2))]).draws[0]
    fields = ("path", "name", "world", "depth_test", "depth_write", "cull", "blend")
    lit_lines = SimpleNamespace(**{f: getattr(draw, f) for f in fields},
                                mesh=SimpleNamespace(primitive="lines", colors=None,
                                                     positions=draw.mesh.positions,
                                                     indices=np.array([[0, 1]])),
                                material=SimpleNamespace(color=np.ones(4), texture=None,
                                                         shading="flat"))
    fake = SimpleNamespace(width=2, height=2, background=np.array([0, 0, 0, 1.0]), samples=1,
                           camera=SimpleNamespace(view=np.eye(4), projection=np.eye(4)),
                           lights=(), draws=(lit_lines,), source="<test>")
    with pytest.raises(NotImplementedError, match="lit lines"):
        glref.render(fake)


def test_glref_imports_only_the_scene_model_from_softras():
    """docs/design.md section 1: imports go one way, glref may import softras.scene
    (texels and tangents reach it as scene data: Texture.levels, Mesh.tangents)."""
    import ast
    from pathlib import Path

    imported = set()
    for path in Path(glref.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("softras"):
                imported.add(node.module if node.module != "softras" else
                             "softras." + ",".join(alias.name for alias in node.names))
            elif isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names if alias.name.startswith("softras"))
    assert imported == {"softras.scene"}
