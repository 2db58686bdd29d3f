"""Tests for the verifier (softras.verification.verifier, softras.verify, softras verify / info)
and glref's capability record and NOT SUPPORTED.

Spec-profile tests judge softras's picture of a scene against glref's on this
machine's GL, and planted changes of the picture (a colour off by 5/255, a
vertex moved by one pixel, a broken reference) that must fail. The full
mutation x implementation table is scripts/planted_bugs.py
(tests/test_planted_bugs.py); the conformance scenes on a second GL
implementation (softpipe) are in tests/test_conformance_softpipe.py.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import glref
import softras
from softras.verification import conformance, verifier
from softras.cli import main
from softras.renderer import render_scene

from conftest import SCENES

# Pixel camera: 1 unit = 1 pixel, z in [-1, 1].
PIXELS = {"projection": "orthographic", "left": 0, "right": 32, "bottom": 0, "top": 24,
          "near": -1, "far": 1}
TRIANGLES = {
    "softras_scene": 1, "width": 32, "height": 24, "background": [0, 0, 0, 1], "camera": PIXELS,
    "nodes": [{"name": "pair",
               "mesh": {"positions": [[2.3, 2.2, 0], [29.6, 3.1, 0], [12.2, 21.7, 0], [30.5, 20.5, 0]],
                        "indices": [[0, 1, 2], [2, 1, 3]],
                        "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 0, 1]]}}],
}

CAPS_FAKE = {"GL_RENDERER": "some GPU", "GL_VERSION": "4.1", "subpixel_bits": 8, "sample_counts": [1, 2, 4, 8],
             "max_samples": 8, "max_anisotropy": 0.0, "max_texture_size": 64, "max_renderbuffer_size": 4096,
             "max_viewport_dims": [4096, 4096]}


def test_profiles_auto_picks_strict_only_for_the_reproduced_implementation():
    llvmpipe = {"GL_RENDERER": "llvmpipe (LLVM 15.0.6, 256 bits)", "GL_VERSION": "4.5 (Core Profile) Mesa 22.3.6"}
    newer = {"GL_RENDERER": "llvmpipe (LLVM 17.0.6, 256 bits)", "GL_VERSION": "4.5 (Core Profile) Mesa 24.0.1"}
    assert verifier.choose_profile("auto", llvmpipe) == "strict"
    assert verifier.choose_profile("auto", newer) == "spec"
    assert verifier.choose_profile("auto", {"GL_RENDERER": "softpipe", "GL_VERSION": "3.3 Mesa 22.3.6"}) == "spec"
    assert verifier.choose_profile("auto", None) == "spec"
    assert verifier.choose_profile("strict", None) == "strict"
    with pytest.raises(ValueError, match="profile"):
        verifier.choose_profile("lenient", None)


def test_colour_allowance_adds_one_step_per_feature():
    plain = softras.load_scene(TRIANGLES)
    assert verifier.colour_allowance(plain)[0] == pytest.approx(1 / 255)
    lit = softras.load_scene(SCENES / "lit_textured_sphere.json")
    allowance, parts = verifier.colour_allowance(lit)
    assert allowance == pytest.approx(3 / 255) and any("lighting" in p for p in parts)


def test_bounds_hold_softras_own_renders_and_widen_only_near_edges():
    scene = softras.load_scene(TRIANGLES)
    bounds = verifier.spec_bounds(scene, {"subpixel_bits": 8})
    for precision in ("gl", "exact"):
        outside, _ = verifier._outside(render_scene(scene, precision=precision), bounds)
        assert not outside.any()
    wide = ((bounds.hi - bounds.lo) > 1e-9).any(axis=-1)
    assert 0 < wide.sum() < 0.25 * wide.size      # edges only, not the interiors
    coarse = verifier.spec_bounds(scene, {"subpixel_bits": 4})
    assert ((coarse.hi - coarse.lo) > 1e-9).any(axis=-1).sum() >= wide.sum()


def test_bounds_sample_where_the_reference_gl_does():
    scene = softras.load_scene(SCENES / "msaa_fan.json")
    llvmpipe = render_scene(scene)                  # llvmpipe's 4x positions
    same = {"subpixel_bits": 8, "sample_positions": {"4": [[0.375, 0.125], [0.875, 0.375],
                                                          [0.125, 0.625], [0.625, 0.875]]}}
    grid = {"subpixel_bits": 8, "sample_positions": {"4": [[0.25, 0.25], [0.75, 0.25],
                                                          [0.25, 0.75], [0.75, 0.75]]}}
    assert not verifier._outside(llvmpipe, verifier.spec_bounds(scene, same))[0].any()
    assert verifier._outside(llvmpipe, verifier.spec_bounds(scene, grid))[0].sum() > 50
    assert not verifier._outside(render_scene(scene, pattern="grid"), verifier.spec_bounds(scene, grid))[0].any()


def _fake_render(broken_pixel):
    """A render function that plants a one-pixel bug in every variant: the
    bounds move with it, so GL's correct picture falls outside."""
    def render(scene, **options):
        picture = render_scene(scene, **options).copy()
        picture[broken_pixel] = (255, 255, 255, 255)
        return picture
    return render


def test_a_bug_in_the_bounds_renderer_shows_as_the_reference_outside():
    scene = softras.load_scene(TRIANGLES)
    good = render_scene(scene)
    bounds = verifier.spec_bounds(scene, {"subpixel_bits": 8}, render=_fake_render((12, 15)))
    verdict, reasons, figures, _ = verifier.judge_spec(scene, good, good, scene.tolerance, bounds)
    assert verdict == verifier.FAIL
    assert figures["outside_reference"] == 1 and figures["outside_image"] == 1
    assert any(r.startswith("the reference: 1 px") and "(15, 12)" in r for r in reasons)


@pytest.mark.gl
def test_spec_passes_softras_against_gl_and_fails_planted_bugs():
    scene = softras.load_scene(TRIANGLES)
    caps = glref.info()
    reference = glref.render(scene)
    ok = softras.verify(scene, render_scene(scene), reference, capabilities=caps)
    assert ok.verdict == verifier.PASS, ok.reasons

    # A colour off by 5/255 (the material colour: every pixel of the pair).
    data = json.loads(json.dumps(TRIANGLES))
    data["nodes"][0]["material"] = {"color": [1, 1, 1 - 5 / 255, 1]}
    off = softras.verify(scene, render_scene(softras.load_scene(data)), reference, capabilities=caps)
    assert off.verdict == verifier.FAIL
    assert off.reasons[0].startswith("the image:") and "'pair'" in off.reasons[0]
    # One vertex moved by one pixel.
    data = json.loads(json.dumps(TRIANGLES))
    data["nodes"][0]["mesh"]["positions"][3][0] -= 1.0
    moved = softras.verify(scene, render_scene(softras.load_scene(data)), reference, capabilities=caps)
    assert moved.verdict == verifier.FAIL
    # The image is fine but the reference has one wrong pixel: the reference is named.
    broken = reference.copy()
    broken[10, 10] = (0, 0, 0, 255)
    bad_ref = softras.verify(scene, render_scene(scene), broken, capabilities=caps)
    assert bad_ref.verdict == verifier.FAIL and bad_ref.reasons[0].startswith("the reference: 1 px")


@pytest.mark.gl
def test_bounds_computed_once_judge_as_verify_computes_them():
    """``verify(..., bounds=spec_bounds(scene, caps))`` gives every picture of
    the scene the verdict, reasons and figures of a verify that renders the
    bounds itself (the bounds do not depend on the picture judged); bounds
    of another size are refused."""
    scene = softras.load_scene(TRIANGLES)
    caps = glref.info()
    reference = glref.render(scene)
    bounds = verifier.spec_bounds(scene, caps)
    moved = json.loads(json.dumps(TRIANGLES))
    moved["nodes"][0]["mesh"]["positions"][3][0] -= 1.0
    for image in (render_scene(scene), render_scene(softras.load_scene(moved))):
        fresh = softras.verify(scene, image, reference, capabilities=caps)
        reused = softras.verify(scene, image, reference, capabilities=caps, bounds=bounds)
        assert (reused.verdict, reused.reasons, reused.figures) == (fresh.verdict, fresh.reasons, fresh.figures)
        assert reused.bounds is bounds
    assert {softras.verify(scene, image, reference, capabilities=caps, bounds=bounds).verdict
            for image in (render_scene(scene), render_scene(softras.load_scene(moved)))} == {verifier.PASS,
                                                                                             verifier.FAIL}
    small = dataclasses.replace(bounds, lo=bounds.lo[:10], hi=bounds.hi[:10])
    with pytest.raises(ValueError, match="bounds are 32x10 but the scene is 32x24"):
        softras.verify(scene, render_scene(scene), reference, capabilities=caps, bounds=small)


@pytest.mark.gl
def test_strict_profile_through_verify():
    scene = softras.load_scene(SCENES / "fill_rule_grid.json")
    gl = glref.render(scene)
    assert softras.verify(scene, render_scene(scene), gl, profile="strict").verdict == verifier.PASS
    assert softras.verify(scene, render_scene(scene), gl, profile="auto",
                          capabilities=glref.info()).profile == verifier.choose_profile("auto", glref.info())


def test_verify_rejects_bad_pictures():
    scene = softras.load_scene(TRIANGLES)
    good = render_scene(scene)
    with pytest.raises(ValueError, match="scene is 32x24"):
        softras.verify(scene, good[:10], good)
    with pytest.raises(ValueError, match=r"\(H, W, 4\)"):
        softras.verify(scene, good, good[..., :3])


def test_rgba32f_pictures_are_compared_as_floats():
    scene = dataclasses.replace(softras.load_scene(TRIANGLES), framebuffer="rgba32f")
    picture = render_scene(scene)
    assert picture.dtype == np.float32
    nudged = picture + np.float32(2.2e-16)
    result = softras.verify(scene, picture, nudged, capabilities={"subpixel_bits": 8})
    assert result.verdict == verifier.PASS and result.figures["max_diff"] < 1e-9


# --------------------------------------------------------------------------- glref capabilities


@pytest.mark.gl
def test_capability_record():
    caps = glref.info()
    for key in ("GL_RENDERER", "GL_VERSION", "GL_SHADING_LANGUAGE_VERSION", "subpixel_bits", "max_samples",
                "sample_counts", "sample_positions", "max_anisotropy", "max_texture_size",
                "max_renderbuffer_size", "max_viewport_dims", "version", "env", "device_index"):
        assert key in caps, key
    assert caps["version"] >= [3, 3]
    assert caps["sample_counts"][0] == 1 and caps["sample_counts"] == sorted(caps["sample_counts"])
    for count in caps["sample_counts"]:
        places = np.array(caps["sample_positions"][str(count)])
        assert places.shape == (count, 2) and (places >= 0).all() and (places < 1).all()
    assert caps["subpixel_bits"] >= 4          # GL 4.6 table 23.53's minimum


def test_unsupported_names_what_the_context_lacks():
    scene = softras.load_scene(SCENES / "msaa_fan.json")
    assert glref.unsupported(scene, capabilities=CAPS_FAKE) is None
    assert "3 samples" in glref.unsupported(scene, samples=3, capabilities=CAPS_FAKE)
    assert "4 samples" in glref.unsupported(scene, capabilities=CAPS_FAKE | {"sample_counts": [1]})
    aniso = softras.load_scene(SCENES / "texture_anisotropic_floor.json")
    reason = glref.unsupported(aniso, capabilities=CAPS_FAKE | {"max_texture_size": 16384})
    assert "anisotropic" in reason
    assert "GL_MAX_TEXTURE_SIZE 64" in glref.unsupported(softras.load_scene(SCENES / "texture_photo.json"),
                                                         capabilities=CAPS_FAKE | {"max_anisotropy": 16.0})


@pytest.mark.gl
def test_gl_backend_refuses_what_it_cannot_do():
    scene = softras.load_scene(TRIANGLES)
    unsupported = [n for n in (2, 3, 8) if n not in glref.info()["sample_counts"]]
    for n in unsupported:
        with pytest.raises(glref.NotSupported, match=f"{n} samples"):
            softras.render(scene, backend="gl", samples=n)
    with pytest.raises(ValueError, match="texture_filter"):
        softras.render(scene, backend="gl", texture_filter="ewa")


def test_conformance_gives_not_supported(monkeypatch):
    monkeypatch.setattr(conformance, "_gl_info", lambda: CAPS_FAKE | {"sample_counts": [1]})
    result = conformance.check_scene(SCENES / "msaa_fan.json")
    assert result.verdict == verifier.NOT_SUPPORTED
    assert "4 samples" in result.reasons[0]
    assert conformance.counts([result])["not_supported"] == 1


# The 8x positions an NVIDIA H200 reports (glGetMultisamplefv, driver 580.159.04).
NVIDIA_8X = [[0.5625, 0.3125], [0.4375, 0.6875], [0.8125, 0.5625], [0.3125, 0.1875],
             [0.1875, 0.8125], [0.0625, 0.4375], [0.6875, 0.9375], [0.9375, 0.0625]]


def test_conformance_samples_where_the_gl_does(monkeypatch):
    """A GL that draws 8 samples (softras's "gl" pattern has only 1 and 4):
    conformance renders softras at the positions the GL reports, so a GL
    drawing there passes; a GL sampling elsewhere (Halton points) differs."""
    scene = dataclasses.replace(softras.load_scene(SCENES / "msaa_fan.json"), samples=8)
    caps = CAPS_FAKE | {"max_texture_size": 4096, "sample_positions": {"8": NVIDIA_8X}}
    monkeypatch.setattr(conformance, "_gl_info", lambda: caps)
    at_gl = np.asarray(NVIDIA_8X)
    result = conformance.check_scene(scene, render_gl=lambda s: render_scene(s, pattern=at_gl), profile="spec")
    assert result.verdict == verifier.PASS, result.reasons
    assert result.figures["max_diff"] == 0
    elsewhere = conformance.check_scene(scene, render_gl=lambda s: render_scene(s, pattern="halton"), profile="spec")
    assert elsewhere.figures["max_diff"] > 0


# --------------------------------------------------------------------------- command line


@pytest.mark.gl
def test_cli_verify_exit_codes_and_bound_images(tmp_path, capsys):
    from softras.scene.imageio import write_png_atomic

    scene_path = tmp_path / "pair.json"
    scene_path.write_text(json.dumps(TRIANGLES))
    scene = softras.load_scene(scene_path)
    write_png_atomic(tmp_path / "soft.png", render_scene(scene))
    np.save(tmp_path / "gl.npy", glref.render(scene))
    out = tmp_path / "out"
    assert main(["verify", str(scene_path), str(tmp_path / "soft.png"), str(tmp_path / "gl.npy"),
                 "--out-dir", str(out)]) == 0
    assert "PASS (spec profile)" in capsys.readouterr().out
    assert {p.name for p in out.iterdir()} >= {"bound_lo.png", "bound_hi.png", "where.png", "diff.png"}
    black = np.zeros((24, 32, 4), np.uint8)
    black[..., 3] = 255
    write_png_atomic(tmp_path / "black.png", black)
    assert main(["verify", str(scene_path), str(tmp_path / "black.png"), str(tmp_path / "gl.npy"),
                 "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["verdict"] == "fail"


def test_cli_verify_bad_input_is_exit_2(tmp_path, capsys):
    scene_path = tmp_path / "pair.json"
    scene_path.write_text(json.dumps(TRIANGLES))
    missing = tmp_path / "missing.png"
    assert main(["verify", str(scene_path), str(missing), str(missing)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softras: error:") and err.count("\n") == 1
    small = tmp_path / "small.npy"
    np.save(small, np.zeros((2, 2, 4), np.uint8))
    assert main(["verify", str(scene_path), str(small), str(small), "--profile", "strict"]) == 2
    assert "scene is 32x24" in capsys.readouterr().err
    assert main(["verify", str(scene_path), str(small), str(small), "--capabilities", str(small)]) == 2
    assert "capability record" in capsys.readouterr().err
    assert main(["verify", str(scene_path), str(small), str(small), "--profile", "loose"]) == 2


@pytest.mark.gl
def test_cli_info(capsys):
    assert main(["info", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["GL_RENDERER"] == glref.info()["GL_RENDERER"] and "profile_auto" in record
    assert main(["info"]) == 0
    assert "subpixel_bits" in capsys.readouterr().out


def test_cli_gl_device_must_be_an_index(capsys):
    assert main(["--gl-device", "x", "info"]) == 2
    assert "not a device index" in capsys.readouterr().err
