"""An rgba32f framebuffer on the compiled path gives the stages' float32 samples exactly.

In gl precision an rgba32f framebuffer keeps a float32 colour per sample
(`softras.pipeline.render.new_pass_framebuffer`), blended in float64 and
rounded on each store; the tile kernels and the line kernel draw it
(`softras.kernels.rgba32f`, `softras.kernels.lines`).  These tests compare
the sample buffers themselves (`softras.pipeline.render.render_samples`
against `softras.kernels.draw.render_samples`), bit for bit where a value is
not NaN (so -0.0 is not 0.0; a NaN's payload is not compared: x86 keeps the
first operand's, and LLVM may swap the operands of an addition), then the
pictures `render_scene` makes (`softras.kernels.rgba32f.resolve`).  An RGBA8
buffer rounds each colour to a byte, so its byte-equality
(tests/test_fastpath.py) leaves the last bits of the colour arithmetic
unchecked; here they count.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softras
from softras.bench_scenes import blended_scene
from softras.kernels import draw as fastpath
from softras.kernels import ops as kernel_ops
from softras.pipeline import ops, render as stages
from softras.pipeline import texture_beyond
from softras.renderer import render_scene
from test_fastpath import (OTHER_SAMPLES, lit_scene, mapped_scene, random_line_scene, random_scene,
                           stretched_uvs)

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.json"))


def float32_job(scene, **options) -> stages.Job:
    defaults = dict(precision="gl", samples=None, pattern=None, seed=0, resolve_filter="box",
                    framebuffer="rgba32f", clipping=None, texture_fixed_point=True, texture_filter=None,
                    texture_bounds=None, tie_rule="left_bottom")
    return stages.Job.of(scene, **{**defaults, **options})


def differing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Where two float32 arrays differ, over the last axis: bits unequal
    unless both are NaN."""
    nan = np.isnan(a) & np.isnan(b)
    return ((a.view(np.uint32) != b.view(np.uint32)) & ~nan).any(axis=-1)


def assert_same_floats(scene, what, **options):
    """The stages' and the kernels' float32 sample buffers are equal bit for
    bit (`differing`), and so are the pictures (the stages': `render_scene`'s
    without the fast path, `stages.resolve` of ``general``)."""
    assert fastpath.unsupported(scene, precision="gl", clipping=None) is None, what
    job = float32_job(scene, **options)
    general = stages.render_samples(scene, job)
    kernel = fastpath.render_samples(scene, job.positions, rgba8=False,
                                     texture_filter=options.get("texture_filter"))
    assert general.dtype == kernel.dtype == np.float32
    differ = differing(general, kernel)
    assert not differ.any(), (f"{what}: {int(differ.sum())} samples differ, first at row/col/sample "
                              f"{np.argwhere(differ)[0].tolist()}")
    pictures = [stages.resolve(job, general), render_scene(scene, framebuffer="rgba32f", **options)]
    assert not differing(*pictures).any(), f"{what}: the pictures differ"


@pytest.mark.parametrize("samples", [None, 4])
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_gives_the_stages_floats(path, samples):
    assert_same_floats(softras.load_scene(path), f"{path.name} samples={samples}", samples=samples)


def kind_scene(kind: str, seed: int) -> dict:
    """A seeded random scene of one kind of draw (tests/test_fastpath.py's
    generators): every depth function, blend equation and cull mode, and
    triangles crossing the clip planes in each."""
    if kind == "unlit":
        return random_scene(seed)
    if kind in ("gouraud", "flat", "phong"):
        return lit_scene(seed, kind)
    if kind == "textured":
        return random_scene(100 + seed, textured=True)
    if kind == "lane_filtered":
        return random_scene(200 + seed, vectorised=True)
    if kind == "mapped":
        return mapped_scene(seed)
    if kind == "alpha_tested":
        data = lit_scene(400 + seed, ["flat", "gouraud", "phong"][seed % 3])
        for k, node in enumerate(data["nodes"]):
            node["material"] = dict(node["material"], alpha_cutoff=[0.5, 0.3, 0.7, 0.0][k % 4])
        return data
    assert kind == "lines"
    return random_line_scene(seed)


KINDS = ["unlit", "gouraud", "flat", "phong", "textured", "lane_filtered", "mapped", "alpha_tested", "lines"]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("kind", KINDS)
def test_random_scenes_give_the_stages_floats(kind, samples, seed):
    """Every kind of draw, lit colours above 1 and below 0 included (an
    rgba32f buffer keeps them), at GL's counts."""
    scene = softras.load_scene(kind_scene(kind, seed))
    assert_same_floats(scene, f"{kind} scene seed {seed}, {samples} samples", samples=samples)


@pytest.mark.parametrize("samples, pattern, resolve", OTHER_SAMPLES)
@pytest.mark.parametrize("kind", ["unlit", "phong", "textured", "lines"])
def test_any_sample_count_and_pattern_gives_the_stages_floats(kind, samples, pattern, resolve):
    """Other counts and patterns (the driver of any count, passes of
    MAX_PASS_SAMPLES) and the tent resolve."""
    scene = softras.load_scene(kind_scene(kind, samples))
    assert_same_floats(scene, f"{kind} scene, {samples} samples {pattern}, {resolve} resolve",
                       samples=samples, pattern=pattern, resolve_filter=resolve)


@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("shading", ["unlit", "flat"])
@pytest.mark.parametrize("alphas", [(0.25, 0.75), (0.0, 1.0), (1.0, 0.1)])
def test_translucent_layers_give_the_stages_floats(alphas, shading, samples):
    """Tilted layers blended "over" without depth (`bench_scenes.blended_scene`,
    each with its own alphas from alphas[0] to alphas[1]), alphas of 0 and
    1 included: unlit, at one sample the rows of
    `softras.kernels.rgba32f._row_floats_over`, at 4 the lanes; flat-shaded
    (lit by a directional light), the lanes."""
    data = blended_scene(96, layers=4, cols=3)
    if shading == "flat":
        data["lights"] = [{"type": "directional", "direction": [0.3, -0.5, -1], "color": [1, 0.9, 0.8]}]
    for k, node in enumerate(data["nodes"]):
        a = alphas[0] + (alphas[1] - alphas[0]) * k / 3
        node["mesh"]["corner_colors"] = [[1, 0, 0, a], [0, 1, 0.25, 1 - a], [0, 0, 1, a], [1, 0.5, 1, alphas[0]]]
        node["material"] = {"shading": shading}
    scene = softras.load_scene(data)
    assert_same_floats(scene, f"{shading} layers with alphas {alphas}, {samples} samples", samples=samples)


@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("shading", ["unlit", "flat"])
def test_depth_tested_unblended_layers_with_alpha_give_the_stages_floats(shading, samples):
    """The same tilted layers, intersecting, drawn with a "less" depth test,
    depth writes and no blending, their alphas 0.2-0.9 (stored
    premultiplied, as they are: alpha is not multiplied by itself): unlit,
    at one sample the rows of `softras.kernels.rgba32f._row_floats_less`,
    at 4 the lanes; flat-shaded, the lanes.  (The scenes of the other tests
    draw opaque depth-tested triangles with alpha 1, where a wrong
    premultiplication shows nothing.)"""
    data = blended_scene(96, layers=4, cols=3)
    if shading == "flat":
        data["lights"] = [{"type": "directional", "direction": [0.3, -0.5, -1], "color": [1, 0.9, 0.8]}]
    for k, node in enumerate(data["nodes"]):
        a = 0.2 + 0.7 * k / 3
        node["mesh"]["corner_colors"] = [[1, 0, 0, a], [0, 1, 0.25, 1 - a], [0, 0, 1, a], [1, 0.5, 1, 0.5]]
        node["material"] = {"shading": shading}
        node["rotate"] = [-20 + 25 * k, 1, 0.3, 0]       # (crossing one another: the depth test decides)
        node["blend"], node["depth_test"] = "none", "less"
    scene = softras.load_scene(data)
    assert_same_floats(scene, f"{shading} depth-tested layers, {samples} samples", samples=samples)


@pytest.mark.parametrize("name", texture_beyond.FILTERS)
def test_softras_filters_give_the_stages_floats(name):
    """softras's own filters (ripmap, EWA, level 0, ...) on stretched uvs."""
    scene = softras.load_scene(stretched_uvs(random_scene(300, textured=True)))
    assert_same_floats(scene, f"texture_filter={name}", texture_filter=name)


def test_the_fast_path_draws_an_rgba32f_scene(monkeypatch):
    """`render_scene` takes the kernels for an rgba32f scene: with the
    stages' sample buffer out of reach it still renders, the stages'
    picture."""
    scene = softras.load_scene(lit_scene(1, "phong"))
    expected = render_scene(scene, framebuffer="rgba32f", fast_path=False)

    def refuse(*args, **kwargs):
        raise AssertionError("the stages drew an rgba32f scene")

    monkeypatch.setattr(stages, "render_samples", refuse)
    picture = render_scene(scene, framebuffer="rgba32f")
    assert picture.dtype == np.float32 and not differing(expected, picture).any()


def special_floats(shape, seed: int) -> np.ndarray:
    """Random float32 samples with NaN, infinities, -0.0, denormals and
    values far outside [0, 1]; pixel (0, 0) all -0.0."""
    rng = np.random.default_rng(seed)
    values = rng.normal(0.5, 2.0, size=shape).astype(np.float32)
    specials = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-45, 3e38, -3e38, 1.0], np.float32)
    pick = rng.random(shape) < 0.1
    values[pick] = rng.choice(specials, size=int(pick.sum()))
    values[0, 0] = -0.0
    return values


@pytest.mark.parametrize("samples", [1, 2, 4, 8, 16, 32, 49])
def test_float_resolve_equals_the_stages_resolve(samples):
    """`softras.kernels.ops._resolve_box` gives `softras.pipeline.ops.resolve`'s
    float32 box filter bit for bit (the sample means in float64, from 0.0 in
    sample order, so -0.0 samples give +0.0; NaN where NaN), rows flipped."""
    color = special_floats((13, 11, samples, 4), samples)
    with np.errstate(invalid="ignore"):                 # (inf - inf in the stages' sums)
        expected = ops.resolve(color, filter="box", arithmetic="llvmpipe", output="float32")
    out = np.empty((13, 11, 4), np.float32)
    kernel_ops._resolve_box(color, out)
    assert not differing(expected, out).any()


def test_clearing_every_tile_stores_the_stages_background():
    """`_clear_fresh` of a framebuffer no draw reached fills every sample with
    the premultiplied background as the stages' buffer holds it (rounded
    to float32 for rgba32f; its RGBA8 bytes otherwise), depth with 1.0,
    in tiles that do not divide the picture."""
    from softras.kernels.ops import _clear_fresh, new_framebuffer
    from softras.kernels.setup import TILE
    background = np.array([0.1, 0.7, 1.0 / 3.0, 0.3])
    height, width = TILE + 3, 2 * TILE + 5
    expected, _ = ops.new_framebuffer(width, height, 2, background, quantize=False)
    for dtype in (np.float32, np.uint8):
        color, depth = np.full((height, width, 2, 4), 7, dtype), np.zeros((height, width, 2), np.int32)
        fb = new_framebuffer(color, depth, ops.premultiplied(background))
        assert fb.fresh.tolist() == [1] * 6
        _clear_fresh(tuple(fb), dtype == np.float32)
        want = expected.astype(np.float32) if dtype == np.float32 else ops.unorm8_bytes(expected)
        assert not differing(want, color).any() and not fb.fresh.any()
        assert (depth == (1 << ops.DEPTH_BITS) - 1).all()
