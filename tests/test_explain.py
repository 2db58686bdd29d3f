"""Tests for `softras explain`: a pixel's history through every stage (softras.verification.explain).

The contract: the explained final value IS softras's rendered pixel (checked
on a grid of pixels and on edge pixels of scenes with edges, textures,
lighting, blending, MSAA and lines, in both precisions), and each stage's
record says what that stage did (fill rule on a shared edge, depth test of an
occluded fragment, blend arithmetic, texture filter weights, lighting terms).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import softras
from softras.cli import main
from softras.verification.explain import explain_pixel, format_text

SCENES = Path(__file__).resolve().parents[1] / "scenes"

# Scenes covering every kind of history: shared edges, culling, depth tests,
# textures (trilinear, wrap modes), lighting, blending, MSAA, lines, clipping.
EXPLAINED_SCENES = ["fan_shared_edges", "culling_back", "depth_functions", "texture_floor_trilinear",
                    "texture_wrap_modes", "lit_spheres", "lit_textured_sphere", "blend_equations",
                    "msaa_fan", "line_star", "near_plane_crossing"]


def pixels_to_check(image: np.ndarray, seed: int) -> list[tuple[int, int]]:
    """A 3 x 3 grid of image pixels plus 8 seeded pixels where the image has an edge."""
    height, width = image.shape[:2]
    grid = [(int(x), int(y)) for y in np.linspace(0, height - 1, 3).astype(int)
            for x in np.linspace(0, width - 1, 3).astype(int)]
    edge = np.abs(np.diff(image.astype(np.int64), axis=1)).max(axis=2) > 0     # (H, W-1)
    ys, xs = np.nonzero(edge)
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(xs), size=min(8, len(xs)), replace=False) if len(xs) else []
    return grid + [(int(xs[i]), int(ys[i])) for i in picks]


@pytest.mark.parametrize("precision", ["gl", "exact"])
@pytest.mark.parametrize("name", EXPLAINED_SCENES)
def test_explained_value_is_the_rendered_pixel(name, precision):
    scene = softras.load_scene(SCENES / f"{name}.json")
    image = softras.render(scene, precision=precision)
    for x, y in pixels_to_check(image, seed=len(name)):
        history = explain_pixel(scene, x, y, precision=precision)
        assert history["final"]["resolved"] == image[y, x].tolist(), (name, precision, x, y)
        # Every covered primitive's mask agrees with its per-sample record.
        for draw in history["draws"]:
            for p in draw["primitives"]:
                assert p["mask"] != 0
                assert len(p["samples_ops"]) == bin(p["mask"]).count("1")


# ----------------------------------------------------------------------------- small scenes


def pixel_scene(nodes, width=16, height=12, samples=1, background=(0, 0, 0, 1)):
    """A scene whose world x, y are GL window coordinates (orthographic 0..W, 0..H)."""
    return {"softras_scene": 1, "width": width, "height": height, "samples": samples,
            "background": list(background),
            "camera": {"projection": "orthographic", "left": 0, "right": width, "bottom": 0,
                       "top": height, "near": -1, "far": 1},
            "nodes": nodes}


def quad(name, x0, y0, x1, y1, z, color, **extra):
    return dict({"name": name,
                 "mesh": {"positions": [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]],
                          "indices": [[0, 1, 2], [0, 2, 3]]},
                 "material": {"color": list(color)}}, **extra)


def test_pixel_on_a_shared_diagonal_is_claimed_by_exactly_one_triangle():
    # The quad (2.5, 2.5)-(10.5, 10.5) is split along its diagonal, which
    # passes exactly through the pixel centres (k + 0.5, k + 0.5).
    scene = pixel_scene([quad("q", 2.5, 2.5, 10.5, 10.5, 0, (1, 1, 1, 1))])
    for precision in ("gl", "exact"):
        # Window pixel (5, 5), whose centre is on the diagonal, is image row 12 - 1 - 5.
        h = explain_pixel(scene, 5, 12 - 1 - 5, precision=precision)
        assert h["pixel"]["window"] == [5, 5]
        (draw,) = h["draws"]
        covered = draw["primitives"]
        assert len(covered) == 1, "exactly one triangle claims the sample on the shared edge"
        (miss,) = [m for m in draw["near_misses"] if m["status"] == "not covering"]
        for p, claimed in ((covered[0], True), (miss, False)):
            (sample,) = p["coverage"]
            assert 0 in sample["E"], "the sample lies exactly on the shared edge"
            assert sample["covered"] is claimed
            assert ("fill rule says in" if claimed else "fill rule says out") in sample["why"]
        # The edge both share: inclusive for the claimer, exclusive for the other.
        tie = [e for e, v in zip(covered[0]["edges"], covered[0]["coverage"][0]["E"]) if v == 0]
        assert tie[0]["inclusive"] and tie[0]["kind"] in ("left", "bottom")
        image = softras.render(scene, precision=precision)
        assert h["final"]["resolved"] == image[12 - 1 - 5, 5].tolist() == [255, 255, 255, 255]


def test_vertical_shared_edge_goes_to_the_right_triangle():
    # Two quads meet at x = 6.5, through the centres of column 6: GL's rule
    # (llvmpipe: left edges inclusive) gives those pixels to the right quad.
    scene = pixel_scene([quad("left", 1, 1, 6.5, 9, 0, (1, 0, 0, 1)),
                         quad("right", 6.5, 1, 12, 9, 0, (0, 0, 1, 1))])
    h = explain_pixel(scene, 6, 6)
    names = [d["name"] for d in h["draws"] if d["primitives"]]
    assert names == ["right"]
    left = next(d for d in h["draws"] if d["name"] == "left")
    ties = [m for m in left["near_misses"] if 0 in m["coverage"][0]["E"]]
    assert ties and all("exclusive" in m["coverage"][0]["why"] and not m["mask"] for m in ties)
    right = next(d for d in h["draws"] if d["name"] == "right")
    assert "e" in right["primitives"][0]["coverage"][0]["why"] and "fill rule says in" in \
        right["primitives"][0]["coverage"][0]["why"]
    assert h["final"]["resolved"] == [0, 0, 255, 255]


def test_depth_test_of_an_occluded_fragment():
    # Orthographic near -1, far 1: z_ndc = -z, so z 0.5 is z_w 0.25 and z -0.5 is z_w 0.75.
    near = quad("near", 2, 2, 10, 10, 0.5, (1, 0, 0, 1))
    far = quad("far", 4, 4, 14, 11, -0.5, (0, 1, 0, 1))
    scene = pixel_scene([near, far])
    for precision in ("gl", "exact"):
        h = explain_pixel(scene, 6, 12 - 1 - 6, precision=precision)
        first, second = h["draws"]
        (op1,) = first["primitives"][0]["samples_ops"]
        (op2,) = second["primitives"][0]["samples_ops"]
        assert op1["depth_before"] == 1.0 and op1["passed"] and op1["depth_written"]
        assert op2["depth_func"] == "less"
        assert op2["depth_before"] == op1["z"], "the buffer holds the first fragment's depth"
        assert op2["z"] > op2["depth_before"]
        assert not op2["passed"] and not op2["depth_written"]
        assert op2["depth_after"] == op1["z"]
        assert h["final"]["resolved"] == [255, 0, 0, 255]
        assert "FAIL" in format_text(h)


def test_blend_record_is_the_over_equation():
    scene = pixel_scene([quad("bg", 0, 0, 16, 12, 0, (0.2, 0.4, 0.6, 1)),
                         quad("glass", 2, 2, 10, 10, 0, (1, 0.5, 0, 0.5), blend="over", depth_test=False)])
    h = explain_pixel(scene, 5, 5)
    (op,) = h["draws"][1]["primitives"][0]["samples_ops"]
    src, dst = np.array(op["src"]), np.array(op["dst"])
    np.testing.assert_allclose(src, [0.5, 0.25, 0, 0.5])           # premultiplied fragment colour
    np.testing.assert_allclose(dst * 255, np.rint(np.array([0.2, 0.4, 0.6, 1]) * 255))
    expected = np.rint(np.clip(src + (1 - src[3]) * dst, 0, 1) * 255)     # GL: ONE, ONE_MINUS_SRC_ALPHA
    np.testing.assert_array_equal(np.array(op["out"]) * 255, expected)
    assert op["depth_func"] == "disabled"
    assert h["final"]["resolved"] == expected.astype(int).tolist()


def test_image_and_window_coordinates():
    # A small quad in the top-left corner of the picture (GL: high y).
    scene = pixel_scene([quad("corner", 0, 9, 3, 12, 0, (1, 1, 0, 1))])
    h = explain_pixel(scene, 1, 1)
    assert h["pixel"]["image"] == [1, 1] and h["pixel"]["window"] == [1, 10]
    assert h["final"]["resolved"] == [255, 255, 0, 255]
    assert explain_pixel(scene, 1, 10)["final"]["resolved"] == [0, 0, 0, 255]
    text = format_text(h)
    assert "pixel (1, 1) in the image" in text and "window pixel (1, 10)" in text


def test_msaa_edge_pixel_has_partial_coverage():
    scene = softras.load_scene(SCENES / "msaa_fan.json")
    image = softras.render(scene)
    found = 0
    for x, y in pixels_to_check(image, seed=3)[9:]:
        h = explain_pixel(scene, x, y)
        masks = [p["mask"] for d in h["draws"] for p in d["primitives"]]
        if any(0 < m < 0b1111 for m in masks):
            found += 1
            samples = np.array(h["final"]["samples"])
            assert samples.shape == (4, 4)
        assert h["final"]["resolved"] == image[y, x].tolist()
    assert found > 0


def test_texture_weights_and_levels_rebuild_the_texel():
    scene = softras.load_scene(SCENES / "texture_floor_trilinear.json")
    checked = 0
    for precision in ("gl", "exact"):
        for x, y in [(64, 80), (20, 60), (100, 50), (64, 45)]:
            h = explain_pixel(scene, x, y, precision=precision)
            for d in h["draws"]:
                for p in d["primitives"]:
                    tex = p["texture"]
                    assert tex is not None
                    total = np.zeros(4)
                    for level in tex["mip"]:
                        weights = [t["weight"] for t in level["taps"]]
                        assert sum(weights) == pytest.approx(1.0)
                        taps = sum(t["weight"] * np.array(t["texel"], float) for t in level["taps"])
                        # fixed point rounds each of its three lerps to a byte
                        assert np.abs(taps - level["filtered"]).max() <= (1.5 if tex["fixed_point"] else 1e-9)
                        total += level["weight"] * np.array(level["filtered"])
                    assert sum(level["weight"] for level in tex["mip"]) == pytest.approx(1.0)
                    allowed = 1 / 255 if tex["fixed_point"] else 1e-12     # the mip lerp rounds to a byte
                    assert np.abs(total / 255 - tex["result"]).max() <= allowed
                    checked += 1
    assert checked >= 6


def test_lighting_terms_add_up_to_the_lit_colour():
    scene = softras.load_scene(SCENES / "lit_spheres.json")
    image = softras.render(scene)
    ys, xs = np.nonzero(image[..., :3].max(axis=2) > 40)
    rng = np.random.default_rng(7)
    seen = set()
    for i in rng.choice(len(xs), 12, replace=False):
        h = explain_pixel(scene, int(xs[i]), int(ys[i]))
        for d in h["draws"]:
            for p in d["primitives"]:
                sh = p["shading"]
                records = sh["vertices"] if sh["model"] == "gouraud" else [sh]
                for r in records:
                    total = np.array(r["ambient"]) + sum(
                        np.array(light["diffuse"]) + np.array(light["specular"])
                        for light in r["lights"] if light["N_dot_L"] > 0)
                    np.testing.assert_allclose(total, r["lit_rgb"], atol=1e-12)
                seen.add(sh["model"])
    assert seen, "some lit fragments were explained"


def test_lines_are_explained():
    scene = softras.load_scene(SCENES / "line_star.json")
    image = softras.render(scene)
    ys, xs = np.nonzero(image[..., :3].max(axis=2) > 0)
    h = explain_pixel(scene, int(xs[0]), int(ys[0]))
    kinds = {p["kind"] for d in h["draws"] for p in d["primitives"]}
    assert kinds == {"line"}
    assert h["final"]["resolved"] == image[ys[0], xs[0]].tolist()


def test_bad_input_raises():
    scene = pixel_scene([quad("q", 1, 1, 5, 5, 0, (1, 1, 1, 1))])
    with pytest.raises(ValueError, match="outside the 16x12 image"):
        explain_pixel(scene, 16, 0)
    with pytest.raises(ValueError, match="outside"):
        explain_pixel(scene, 0, -1)
    with pytest.raises(ValueError, match="precision"):
        explain_pixel(scene, 0, 0, precision="fast")


# ----------------------------------------------------------------------------- command line


def write_scene(tmp_path, scene) -> str:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    return str(path)


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("softras: error: ") and "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("pixel", ["3", "3,4,5", "a,b", "3;4", "1.5,2", ""])
def test_cli_malformed_pixel(tmp_path, capsys, pixel):
    path = write_scene(tmp_path, pixel_scene([quad("q", 1, 1, 5, 5, 0, (1, 1, 1, 1))]))
    assert main(["explain", path, "--pixel", pixel]) == 2
    assert "--pixel" in one_error_line(capsys)


@pytest.mark.parametrize("pixel", ["16,0", "0,12", "--pixel=-1,0"])
def test_cli_pixel_outside_the_image(tmp_path, capsys, pixel):
    path = write_scene(tmp_path, pixel_scene([quad("q", 1, 1, 5, 5, 0, (1, 1, 1, 1))]))
    args = ["explain", path, pixel] if pixel.startswith("--") else ["explain", path, "--pixel", pixel]
    assert main(args) == 2
    assert "outside the 16x12 image" in one_error_line(capsys)


def test_cli_bad_scene(tmp_path, capsys):
    assert main(["explain", str(tmp_path / "missing.json"), "--pixel", "1,1"]) == 2
    one_error_line(capsys)
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    assert main(["explain", str(bad), "--pixel", "1,1"]) == 2
    assert "bad.json" in one_error_line(capsys)
    scene = pixel_scene([quad("q", 1, 1, 5, 5, 0, (1, 1, 1, 1))])
    scene["nodes"][0]["mesh"]["indices"] = [[0, 1, 9]]
    assert main(["explain", write_scene(tmp_path, scene), "--pixel", "1,1"]) == 2
    assert "indices" in one_error_line(capsys)
    assert main(["explain", write_scene(tmp_path, pixel_scene([])), "--pixel", "1,1",
                 "--samples", "3"]) == 2
    one_error_line(capsys)


def test_cli_without_gl_still_prints_the_history(tmp_path, capsys, monkeypatch):
    import glref
    from softras.verification import explain

    def no_gl(*args, **kwargs):
        raise glref.GLUnavailable("no EGL display (test)")

    monkeypatch.setattr(explain, "gl_pixel", no_gl)
    path = write_scene(tmp_path, pixel_scene([quad("q", 1, 1, 5, 5, 0, (1, 0, 1, 1))]))
    assert main(["explain", path, "--pixel", "2,8"]) == 0
    out = capsys.readouterr().out
    assert "glref: OpenGL unavailable (no EGL display (test))" in out
    assert "softras: (255, 0, 255, 255)" in out and "(same)" in out
    assert main(["explain", path, "--pixel", "2,8", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["gl"]["value"] is None and "unavailable" in data["gl"]
    assert data["final"]["resolved"] == data["softras_image"] == [255, 0, 255, 255]


@pytest.mark.gl
@pytest.mark.parametrize("name,pixel", [("demo", "160,120"), ("msaa_fan", "40,40"),
                                         ("lit_textured_sphere", "64,48")])
def test_cli_shows_glref_value(capsys, name, pixel):
    path = str(SCENES / f"{name}.json")
    assert main(["explain", path, "--pixel", pixel, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    x, y = map(int, pixel.split(","))
    gl = softras.render(path, backend="gl")
    assert data["gl"]["value"] == gl[y, x].tolist()
    assert data["gl"]["renderer"]
    soft = softras.render(path)
    assert data["final"]["resolved"] == data["softras_image"] == soft[y, x].tolist()
    assert main(["explain", path, "--pixel", pixel]) == 0
    assert "glref:   (" in capsys.readouterr().out


def test_alpha_tested_fragments_are_explained_as_discarded():
    """A MASK material's fragments below the cutoff write nothing: the
    explained value is still the rendered pixel, and at least one checked
    pixel shows a discarded fragment (no sample operations)."""
    scene = softras.load_scene(SCENES / "gltf_alpha_modes.gltf")
    image = softras.render(scene)
    discarded = 0
    for x, y in pixels_to_check(image, seed=3) + [(x, y) for y in range(0, scene.height, 9)
                                                  for x in range(0, scene.width, 9)]:
        history = explain_pixel(scene, x, y)
        assert history["final"]["resolved"] == image[y, x].tolist(), (x, y)
        for draw in history["draws"]:
            for p in draw["primitives"]:
                if p["alpha_test"] is not None and not p["alpha_test"]["kept"]:
                    discarded += 1
                    assert p["samples_ops"] == []
    assert discarded > 0


def test_culled_triangles_face_by_the_scenes_front_face():
    """With ``front_face`` "cw" and back-face culling, a counter-clockwise
    triangle is culled as back-facing, and the history says so."""
    tri = {"name": "ccw", "mesh": {"positions": [[2, 2, 0], [12, 2, 0], [2, 10, 0]]}, "cull": "back"}
    scene = softras.load_scene(dict(pixel_scene([tri]), front_face="cw"))
    history = explain_pixel(scene, 4, 4)
    culled = [m for draw in history["draws"] for m in draw["near_misses"] if m["status"].startswith("culled")]
    assert culled and all(m["front_facing"] is False for m in culled), culled
