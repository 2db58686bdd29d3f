"""The exact kernel (softras.kernels.exact) gives the stages' float64 samples exactly.

Exact precision keeps a float64 colour per sample, so these tests compare
the sample buffers themselves (`softras.pipeline.render.render_samples`
against `softras.kernels.exact.render_samples`), not only the pictures: a
one-ulp difference in any sum or product fails them.  The scenes are the
conformance scenes and the seeded random scenes of tests/test_fastpath.py
(every depth function and blend equation, culling, triangles crossing every
clip plane, lit with every shading, alpha-tested), with lines and textured
draws between them (those draws take the stages, into the same buffers).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softras
from softras.kernels import exact
from softras.pipeline import render as stages
from softras.pipeline import sampling
from softras.renderer import render_scene
from test_fastpath import lit_scene, random_line_scene, random_scene

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.json"))


def exact_job(scene, **options) -> stages.Job:
    defaults = dict(precision="exact", samples=None, pattern=None, seed=0, resolve_filter="box", framebuffer=None,
                    clipping=None, texture_fixed_point=True, texture_filter=None, texture_bounds=None,
                    tie_rule="left_bottom")
    return stages.Job.of(scene, **{**defaults, **options})


def assert_same_samples(scene, what, **options):
    """The stages' and the exact kernel's sample buffers are equal, value
    for value (NaN where NaN); and so are the pictures `render_scene` makes."""
    job = exact_job(scene, **options)
    general, kernel = stages.render_samples(scene, job), exact.render_samples(scene, job)
    differ = ~((general == kernel) | (np.isnan(general) & np.isnan(kernel))).all(axis=-1)
    assert not differ.any(), (f"{what}: {int(differ.sum())} samples differ, first at row/col/sample "
                              f"{np.argwhere(differ)[0].tolist()}")
    assert np.array_equal(render_scene(scene, precision="exact", fast_path=False, **options),
                          render_scene(scene, precision="exact", **options), equal_nan=True), what


@pytest.mark.parametrize("samples", [None, 4])
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_gives_the_stages_samples(path, samples):
    assert_same_samples(softras.load_scene(path), f"{path.name} samples={samples}", samples=samples)


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_scenes_give_the_stages_samples(seed, samples):
    assert_same_samples(softras.load_scene(random_scene(seed)), f"random scene {seed}", samples=samples)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("shading", ["gouraud", "flat", "phong"])
@pytest.mark.parametrize("samples", [1, 4])
def test_random_lit_scenes_give_the_stages_samples(shading, seed, samples):
    """Lit draws (odd seeds: some textured, which take the stages between
    the kernel's draws)."""
    scene = softras.load_scene(lit_scene(seed, shading))
    assert all(d.material.shading == shading for d in scene.draws)
    assert_same_samples(scene, f"random {shading} scene {seed}", samples=samples)


@pytest.mark.parametrize("seed", range(4))
def test_random_alpha_tested_scenes_give_the_stages_samples(seed):
    """Alpha-tested draws; in the first node every vertex alpha is its
    cutoff, which a flat colour keeps exactly (kept: ``alpha >= cutoff``)."""
    shading = ["unlit", "gouraud", "flat", "phong"][seed]
    data = random_scene(400 + seed) if shading == "unlit" else lit_scene(400 + seed, shading)
    for k, node in enumerate(data["nodes"]):
        node["material"] = dict(node.get("material", {}), alpha_cutoff=[0.5, 0.3, 0.7, 0.0][k % 4])
    for color in data["nodes"][0]["mesh"]["colors"]:
        color[3] = 0.5
    assert_same_samples(softras.load_scene(data), f"alpha-tested {shading} scene", samples=4)


@pytest.mark.parametrize("seed", range(6))
def test_every_draw_leaves_the_stages_depths_and_colours(seed):
    """Draw by draw, the kernel leaves the depth buffer as the stages do as
    well (a depth one ulp off shows in the colours only where a later test
    compares it), on random lit scenes with every depth function."""
    data = lit_scene(seed, ["gouraud", "flat", "phong"][seed % 3])
    for node in data["nodes"]:
        node.pop("material", None) if seed % 2 else node["material"].pop("texture", None)
    scene = softras.load_scene(data)
    job = exact_job(scene, samples=4)
    inputs = stages.Pass.of(job, job.positions)
    general, kernel = stages.new_pass_framebuffer(scene, inputs), stages.new_pass_framebuffer(scene, inputs)
    for draw in softras.scene.ordered_draws(scene):
        assert exact.compiled(draw)
        stages.draw_triangles(scene, draw, inputs, *general)
        exact.draw_triangles(scene, draw, inputs, *kernel)
        for name, a, b in zip(("colour", "depth"), general, kernel):
            assert np.array_equal(a, b, equal_nan=True), f"{draw.path}: {name} differs"


@pytest.mark.parametrize("samples, pattern", [(2, "halton"), (9, "rotated_grid"), (16, "jittered"),
                                              (sampling.MAX_PASS_SAMPLES, "poisson"), (49, "grid")])
def test_any_sample_count_and_pattern_gives_the_stages_samples(samples, pattern):
    """Other counts and patterns, more than 32 samples in passes; lines and
    textured draws among the kernel's (the stages draw those)."""
    for data in (lit_scene(samples, "phong"), random_line_scene(samples), random_scene(samples, textured=True)):
        assert_same_samples(softras.load_scene(data), f"{samples} {pattern}", samples=samples, pattern=pattern)


@pytest.mark.parametrize("options", [{"tie_rule": "right_top"}, {"clipping": "llvmpipe"},
                                     {"framebuffer": "rgba32f"}, {"resolve_filter": "tent", "samples": 4},
                                     {"texture_bounds": "lo"}, {"texture_filter": "ewa"}])
def test_every_exact_option_gives_the_stages_samples(options):
    data = random_scene(7, textured=True)
    data["nodes"] += random_scene(8)["nodes"]
    data["front_face"] = "cw"
    assert_same_samples(softras.load_scene(data), f"options {options}", **options)


@pytest.mark.parametrize("band_rows", [1, 3, 1000])
def test_any_band_height_gives_the_same_samples(band_rows, monkeypatch):
    """Bands of one row, of three, and one band for the whole picture: each
    pixel sees the draw's fragments in draw order whatever the bands."""
    scene = softras.load_scene(lit_scene(3, "phong"))
    job = exact_job(scene, samples=4)
    expected = stages.render_samples(scene, job)
    monkeypatch.setattr(exact, "BAND_ROWS", band_rows)
    assert np.array_equal(exact.render_samples(scene, job), expected, equal_nan=True)


def test_only_untextured_triangle_draws_take_the_kernel(monkeypatch):
    """Lines, textures, normal and bump maps take the stages' per-draw
    functions; the rest the kernel."""
    data = random_line_scene(3)
    data["nodes"].append(random_scene(5, textured=True)["nodes"][0])
    data["textures"] = random_scene(5, textured=True)["textures"]
    scene = softras.load_scene(data)
    drawn = []
    monkeypatch.setattr(exact, "_DRAW", lambda *args: drawn.append("kernel"))
    monkeypatch.setattr(stages, "draw_lines", lambda *args: drawn.append("lines"))
    monkeypatch.setattr(stages, "draw_triangles", lambda *args: drawn.append("stages"))
    exact.render_samples(scene, exact_job(scene))
    expected = ["lines" if d.mesh.primitive == "lines" else "stages" if d.material.texture else "kernel"
                for d in softras.scene.ordered_draws(scene)]
    assert drawn == expected and "kernel" in drawn and "stages" in drawn and "lines" in drawn


def test_gl_precision_is_refused():
    scene = softras.load_scene(random_scene(0))
    with pytest.raises(ValueError, match="exact precision only"):
        exact.render_samples(scene, exact_job(scene, precision="gl"))
