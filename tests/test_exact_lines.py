"""The exact line kernel (softras.kernels.exact_lines) gives the stages' float64 samples exactly.

Line draws in exact precision (`softras.kernels.exact.render_samples`,
which draws them with `softras.kernels.exact_lines.draw_lines`) against the
stages (`softras.pipeline.render.render_samples`, `draw_lines`): the
per-sample colour buffers value for value (NaN where NaN, and the sign of
every value), and draw by draw the depth buffer too.  Random line scenes
stress what the conformance scenes do not: lines crossing the near plane
and leaving the guard band, end points near w = 0, zero-length, horizontal,
vertical and diagonal lines, end points on pixel centres and borders,
vertex colours with alpha, every blend equation and depth function, depth
writes on and off, between triangle draws.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import softras
from softras.kernels import exact, exact_lines
from softras.pipeline import ops
from softras.pipeline import render as stages
from test_exact_path import exact_job
from test_fastpath import BLENDS, DEPTHS, random_scene

LINE_SCENES = sorted(p for p in (Path(__file__).resolve().parents[1] / "scenes").glob("*.json")
                     if '"primitive": "lines"' in p.read_text())
SEEDS = range(10)


def random_lines(rng, n: int) -> tuple[list, list]:
    """n random lines in the world of `random_scene`'s camera (eye at z 2.5,
    near 0.5, far 4): positions (2n, 3) and straight colours (2n, 4) with
    alpha.  Most inside or across the view volume; among them zero-length,
    horizontal, vertical and 45-degree diagonal ones, ones far outside the
    viewport (within the guard band and beyond it), ones with an end point
    near the eye (w near 0, and one at w = 0 exactly)."""
    xyz = rng.uniform([-2.5, -2.0, -2.5], [2.5, 2.0, 2.4], size=(2 * n, 3))
    kinds = rng.integers(0, 8, n)
    for line, kind in enumerate(kinds):
        a, b = 2 * line, 2 * line + 1
        if kind == 1:                                    # zero length
            xyz[b] = xyz[a]
        elif kind == 2:                                  # horizontal (same y and z)
            xyz[b, 1:] = xyz[a, 1:]
        elif kind == 3:                                  # vertical (same x and z)
            xyz[b, 0], xyz[b, 2] = xyz[a, 0], xyz[a, 2]
        elif kind == 4:                                  # 45 degrees in the window (same z)
            step = rng.uniform(-1.5, 1.5)
            xyz[b] = xyz[a] + [step, step * rng.choice([-1, 1]), 0.0]
        elif kind == 5:                                  # far outside: x, y up to 300x the view
            xyz[a, :2] *= rng.choice([20.0, 300.0])
            xyz[b, :2] *= rng.choice([1.0, 40.0])
        elif kind == 6:                                  # an end point near the eye: w near 0 (or 0)
            xyz[a] = [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 2.5 - rng.choice([0.0, 1e-9, 1e-3, 0.49])]
    colors = rng.uniform(0, 1, size=(2 * n, 4)).round(3)
    colors[rng.integers(0, 2 * n, n // 3), 3] = 0.0       # transparent ends
    return xyz.tolist(), colors.tolist()


def random_exact_line_scene(seed: int) -> dict:
    """`random_scene` with its odd nodes (and a seventh, after the last
    triangles) line draws of `random_lines`: each with its own depth test
    (seed and node chose it: the seeds together take every depth function),
    depth write, blend (every equation over the seeds) and material colour,
    so lines are drawn over, under and between triangles."""
    data = random_scene(seed)
    rng = np.random.default_rng(2000 + seed)
    data["nodes"].append(dict(random_scene(seed + 100)["nodes"][0], name="after"))
    for k, node in enumerate(data["nodes"]):
        if k % 2 == 0:
            continue
        n = int(rng.integers(1, 80))
        positions, colors = random_lines(rng, n)
        node["mesh"] = {"primitive": "lines", "positions": positions,
                        "indices": np.arange(2 * n).reshape(n, 2).tolist(), "colors": colors}
        node["material"] = {"color": rng.uniform(0.3, 1, 4).round(2).tolist()}
        node["depth_test"] = DEPTHS[(seed + 3 * k) % len(DEPTHS)]
        node["depth_write"] = bool((seed + k) % 3)
        node["blend"] = BLENDS[(3 * seed + k) % len(BLENDS)]
        node.pop("cull", None)
    return data


def grid_line_scene(seed: int) -> dict:
    """Lines in clip space (no camera: the positions are clip coordinates,
    w 1) on a 64 x 48 picture, whose end points lie on pixel centres, pixel
    borders and quarter pixels: the end-pixel rules' ties, exact axis-aligned
    and diagonal lines, lines along pixel borders; over a triangle, drawn
    "over" with a depth test."""
    rng = np.random.default_rng(3000 + seed)
    n = 200
    window = rng.integers(-8, 72 * 4, size=(2 * n, 2)) / 4.0            # quarter pixels
    window[1::2][:40] = window[0::2][:40] + rng.integers(-12, 13, size=(40, 1)) * [1, 0]     # horizontal
    window[1::2][40:80] = window[0::2][40:80] + rng.integers(-12, 13, size=(40, 1)) * [0, 1]  # vertical
    diagonal = rng.integers(-12, 13, size=(40, 1)) * [1, -1]
    window[1::2][80:120] = window[0::2][80:120] + diagonal
    ndc = np.column_stack([window[:, 0] / 32.0 - 1.0, window[:, 1] / 24.0 - 1.0, rng.uniform(-1, 1, 2 * n)])
    return {"softras_scene": 1, "width": 64, "height": 48, "background": [0.1, 0.2, 0.3, 1.0], "nodes": [
        {"name": "under", "mesh": {"positions": [[-1, -1, 0], [1, -1, 0], [0, 1, 0]], "indices": [[0, 1, 2]],
                                   "colors": [[1, 0, 0, 1], [0, 1, 0, 0.5], [0, 0, 1, 1]]}},
        {"name": "grid", "blend": "over", "depth_test": "lequal",
         "mesh": {"primitive": "lines", "positions": ndc.tolist(), "indices": np.arange(2 * n).reshape(n, 2).tolist(),
                  "colors": rng.uniform(0, 1, size=(2 * n, 4)).round(3).tolist()}}]}


def assert_same_buffers(a: np.ndarray, b: np.ndarray, what: str) -> None:
    """a and b are the same float64 values: equal, NaN where NaN, and the
    same sign bit everywhere (0.0 and -0.0 differ)."""
    same = ((a == b) | (np.isnan(a) & np.isnan(b))) & (np.signbit(a) == np.signbit(b))
    differ = ~same.reshape(a.shape[:3] + (-1,)).all(axis=-1)
    assert not differ.any(), (f"{what}: {int(differ.sum())} samples differ, first at row/col/sample "
                              f"{np.argwhere(differ)[0].tolist()}")


def assert_same_samples(scene, what: str, **options) -> None:
    job = exact_job(scene, **options)
    assert_same_buffers(stages.render_samples(scene, job), exact.render_samples(scene, job), what)


def test_the_random_scenes_take_every_depth_function_and_blend():
    scenes = [random_exact_line_scene(seed) for seed in SEEDS]
    line_nodes = [node for data in scenes for node in data["nodes"] if node["mesh"].get("primitive") == "lines"]
    assert {ops.DEPTH_FUNCS[node["depth_test"] or None] for node in line_nodes} == set(ops.DEPTH_FUNCS.values())
    assert {node["blend"] for node in line_nodes} == set(ops.BLEND_MODES)
    assert {node["depth_write"] for node in line_nodes} == {True, False}
    assert all(data["nodes"][0]["mesh"].get("primitive") is None and
               data["nodes"][-1]["mesh"].get("primitive") is None for data in scenes)


@pytest.mark.parametrize("samples, pattern", [(1, None), (4, None), (9, "rotated_grid"), (16, "halton")])
@pytest.mark.parametrize("seed", SEEDS)
def test_random_line_scenes_give_the_stages_samples(seed, samples, pattern):
    scene = softras.load_scene(random_exact_line_scene(seed))
    assert_same_samples(scene, f"random line scene {seed}, {samples} {pattern}", samples=samples, pattern=pattern)


@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("seed", range(3))
def test_lines_on_pixel_centres_and_borders_give_the_stages_samples(seed, samples):
    scene = softras.load_scene(grid_line_scene(seed))
    assert_same_samples(scene, f"grid line scene {seed}, {samples} samples", samples=samples)


@pytest.mark.parametrize("samples", [None, 4])
@pytest.mark.parametrize("path", LINE_SCENES, ids=[p.stem for p in LINE_SCENES])
def test_every_line_scene_gives_the_stages_samples(path, samples):
    assert_same_samples(softras.load_scene(path), f"{path.name} samples={samples}", samples=samples)


def test_there_are_line_scenes():
    assert LINE_SCENES


@pytest.mark.parametrize("seed", range(4))
def test_every_line_draw_leaves_the_stages_depths_and_colours(seed):
    """Draw by draw, both buffers (a depth one ulp off shows in the colours
    only where a later test compares it); the triangle draws are the stages'
    on both."""
    scene = softras.load_scene(random_exact_line_scene(seed))
    job = exact_job(scene, samples=4)
    inputs = stages.Pass.of(job, job.positions)
    general, kernel = stages.new_pass_framebuffer(scene, inputs), stages.new_pass_framebuffer(scene, inputs)
    for draw in softras.scene.ordered_draws(scene):
        if draw.mesh.primitive == "lines":
            stages.draw_lines(scene, draw, inputs, *general)
            exact_lines.draw_lines(scene, draw, inputs, *kernel)
        else:
            stages.draw_triangles(scene, draw, inputs, *general)
            stages.draw_triangles(scene, draw, inputs, *kernel)
        for name, a, b in zip(("colour", "depth"), general, kernel):
            assert_same_buffers(a, b, f"{draw.path}: {name}")


@pytest.mark.parametrize("band_rows", [1, 3, 1000])
def test_any_band_height_gives_the_same_samples(band_rows, monkeypatch):
    """Bands of one row, of three, and one band for the whole picture: each
    pixel sees the lines in draw order whatever the bands."""
    scene = softras.load_scene(random_exact_line_scene(1))
    job = exact_job(scene, samples=4)
    expected = stages.render_samples(scene, job)
    monkeypatch.setattr(exact_lines, "BAND_ROWS", band_rows)
    assert_same_buffers(exact.render_samples(scene, job), expected, f"bands of {band_rows} rows")


@pytest.mark.parametrize("options", [{"clipping": "llvmpipe"}, {"framebuffer": "rgba32f"},
                                     {"samples": 40, "pattern": "poisson"}])
def test_every_exact_option_gives_the_stages_samples(options):
    """The view volume's clipping, the float framebuffer and more than 32
    samples (in passes)."""
    assert_same_samples(softras.load_scene(random_exact_line_scene(5)), f"options {options}", **options)


def test_a_material_lines_cannot_have_is_refused_as_by_the_stages():
    """(The loader refuses it first: here the draw's material is replaced after loading.)"""
    scene = softras.load_scene(random_exact_line_scene(0))
    draw = next(d for d in scene.draws if d.mesh.primitive == "lines")
    object.__setattr__(draw, "material", dataclasses.replace(draw.material, shading="flat"))
    job = exact_job(scene)
    with pytest.raises(NotImplementedError) as by_stages:
        stages.render_samples(scene, job)
    with pytest.raises(NotImplementedError) as by_kernel:
        exact.render_samples(scene, job)
    assert str(by_kernel.value) == str(by_stages.value)
