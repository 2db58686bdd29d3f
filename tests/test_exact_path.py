"""The exact kernel (softras.kernels.exact) gives the stages' float64 samples exactly.

Exact precision keeps a float64 colour per sample, so these tests compare
the sample buffers themselves (`softras.pipeline.render.render_samples`
against `softras.kernels.exact.render_samples`), not only the pictures: a
one-ulp difference in any sum or product fails them.  The scenes are the
conformance scenes and the seeded random scenes of tests/test_fastpath.py
(every depth function and blend equation, culling, triangles crossing every
clip plane, lit with every shading, textured with every filter and wrap,
alpha-tested), with lines (the exact line kernel, `softras.kernels.exact_lines`,
also tests/test_exact_lines.py) and the draws the kernel leaves to the
stages between them (into the same buffers).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import softras
from softras.kernels import exact, exact_lines
from softras.pipeline import render as stages
from softras.pipeline import sampling, texture_beyond
from softras.renderer import render_scene
from test_fastpath import lit_scene, mapped_scene, random_line_scene, random_scene, stretched_uvs
from test_rgba32f_path import differing

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.json"))


def exact_job(scene, **options) -> stages.Job:
    defaults = dict(precision="exact", samples=None, pattern=None, seed=0, resolve_filter="box", framebuffer=None,
                    clipping=None, texture_fixed_point=True, texture_filter=None, texture_bounds=None,
                    tie_rule="left_bottom")
    return stages.Job.of(scene, **{**defaults, **options})


def assert_same_samples(scene, what, **options):
    """The stages' and the exact kernel's sample buffers are equal, value
    for value (NaN where NaN); and so are the pictures `render_scene` makes
    (without the fast path it resolves the stages' samples: `stages.resolve`
    of ``general``, not a second render of them)."""
    job = exact_job(scene, **options)
    general, kernel = stages.render_samples(scene, job), exact.render_samples(scene, job)
    differ = ~((general == kernel) | (np.isnan(general) & np.isnan(kernel))).all(axis=-1)
    assert not differ.any(), (f"{what}: {int(differ.sum())} samples differ, first at row/col/sample "
                              f"{np.argwhere(differ)[0].tolist()}")
    assert np.array_equal(stages.resolve(job, general), render_scene(scene, precision="exact", **options),
                          equal_nan=True), what


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


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_mapped_scenes_give_the_stages_samples(seed, samples):
    """Normal- and bump-mapped Phong draws (`exact._make_map_texels`: the map at
    the analytic derivatives, four taps for a bump map), textured (odd
    seeds) or not; the anisotropic map's draws take the stages between the
    kernel's."""
    scene = softras.load_scene(mapped_scene(seed))
    assert_same_samples(scene, f"random mapped scene {seed}", samples=samples)


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
    compares it), on random lit scenes with every depth function (odd
    seeds textured), and one unlit."""
    data = lit_scene(seed, ["gouraud", "flat", "phong"][seed % 3])
    for node in data["nodes"]:
        if seed == 5:
            node.pop("material", None)
    scene = softras.load_scene(data)
    job = exact_job(scene, samples=4)
    inputs = stages.Pass.of(job, job.positions)
    general, kernel = stages.new_pass_framebuffer(scene, inputs), stages.new_pass_framebuffer(scene, inputs)
    for draw in softras.scene.ordered_draws(scene):
        assert exact.compiled(scene, draw, inputs)
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
                                     {"texture_bounds": "lo"}, {"texture_filter": "ewa"},
                                     {"texture_filter": "ripmap"}, {"texture_filter": "level0"}])
def test_every_exact_option_gives_the_stages_samples(options):
    data = random_scene(7, textured=True)
    data["nodes"] += random_scene(8)["nodes"]
    data["front_face"] = "cw"
    assert_same_samples(softras.load_scene(data), f"options {options}", **options)


@pytest.mark.parametrize("name", texture_beyond.FILTERS)
def test_every_texture_filter_on_stretched_uvs_gives_the_stages_samples(name):
    """softras's filters in the exact kernel (`softras.kernels.texture_beyond._beyond_texel`
    at the analytic derivatives) on uvs scaled up to 20x along one axis: the
    ripmap's and EWA's levels, EWA's eccentricity cap and level blend;
    anisotropic textures too (a ``texture_filter`` ignores max_anisotropy)."""
    data = stretched_uvs(random_scene(9, textured=True))
    for k, tex in enumerate(data["textures"].values()):
        tex["max_anisotropy"] = [1, 8][k % 2]
    assert_same_samples(softras.load_scene(data), f"texture_filter {name}", samples=4, texture_filter=name)


@pytest.mark.parametrize("band_rows", [1, 3, 1000])
def test_any_band_height_gives_the_same_samples(band_rows, monkeypatch):
    """Bands of one row, of three, and one band for the whole picture: each
    pixel sees the draw's fragments in draw order whatever the bands."""
    scene = softras.load_scene(lit_scene(3, "phong"))
    job = exact_job(scene, samples=4)
    expected = stages.render_samples(scene, job)
    monkeypatch.setattr(exact, "BAND_ROWS", band_rows)
    assert np.array_equal(exact.render_samples(scene, job), expected, equal_nan=True)


def routes(monkeypatch) -> list:
    """The list that each draw of a render appends its route to: "kernel"
    (`exact.set_up_draw`, for `exact._DRAW`), "lines" (`exact_lines.draw_lines`),
    "stages" or "stage lines" (their per-draw functions; none of them draws)."""
    drawn = []
    set_up = exact.set_up_draw
    monkeypatch.setattr(exact, "set_up_draw", lambda *args: (drawn.append("kernel"), set_up(*args))[1])
    monkeypatch.setattr(exact, "_DRAW", lambda *args: None)
    monkeypatch.setattr(exact_lines, "draw_lines", lambda *args: drawn.append("lines"))
    monkeypatch.setattr(stages, "draw_lines", lambda *args: drawn.append("stage lines"))
    monkeypatch.setattr(stages, "draw_triangles", lambda *args: drawn.append("stages"))
    return drawn


@pytest.mark.parametrize("options", [{}, {"texture_filter": "ewa"}, {"texture_bounds": "hi"}, {"anisotropy": 4},
                                     {"texture_filter": "ripmap", "anisotropy": 4}])
def test_which_draws_take_the_kernel(options, monkeypatch):
    """Lines take the exact line kernel; textured draws under texture bounds
    the stages' per-draw functions; the rest, textured or not, with any
    filter (anisotropic, softras's own), the kernel."""
    data = random_line_scene(3)
    textured = random_scene(5, textured=True)
    data["nodes"] += textured["nodes"][:2]
    data["textures"] = textured["textures"]
    for tex in data["textures"].values():
        tex["max_anisotropy"] = options.get("anisotropy", 1)
    scene = softras.load_scene(data)
    job = exact_job(scene, **{k: v for k, v in options.items() if k != "anisotropy"})
    drawn = routes(monkeypatch)
    exact.render_samples(scene, job)
    textures_compiled = "texture_bounds" not in options
    expected = ["lines" if d.mesh.primitive == "lines" else
                "stages" if d.material.texture and not textures_compiled else "kernel"
                for d in softras.scene.ordered_draws(scene)]
    assert drawn == expected and "kernel" in drawn and "lines" in drawn
    assert any(d.material.texture for d in scene.draws)


@pytest.mark.parametrize("options", [{}, {"texture_bounds": "hi"}, {"anisotropy": 4}])
@pytest.mark.parametrize("map_key", ["bump_map", "normal_map"])
def test_normal_and_bump_mapped_draws_take_the_kernel(map_key, options, monkeypatch):
    """A mapped draw takes the kernel, its map filtered anisotropically too,
    unless the render asks for texture bounds (the stages)."""
    data = mapped_plane(map_key)
    for tex in data["textures"].values():
        tex["max_anisotropy"] = options.get("anisotropy", 1)
    data["nodes"].append(dict(data["nodes"][0], name="plain", material={"shading": "phong"}))
    scene = softras.load_scene(data)
    drawn = routes(monkeypatch)
    exact.render_samples(scene, exact_job(scene, **{k: v for k, v in options.items() if k != "anisotropy"}))
    assert drawn == ["stages" if "texture_bounds" in options else "kernel", "kernel"]


@pytest.mark.parametrize("anisotropy", [1.5, 4, 16])
@pytest.mark.parametrize("map_key", [None, "bump_map", "normal_map"])
def test_anisotropic_filtering_gives_the_stages_samples(anisotropy, map_key):
    """The EXT spec's probes in the exact kernel (`exact._anisotropic`: the
    probe count min(ceil(Pmax / Pmin), floor(limit)), lambda' = log2(Pmax /
    N), the probes along the longer derivative vector) give the stages'
    samples (`softras.pipeline.texture.sample_anisotropic`): every min
    filter on uvs stretched up to 20x along one axis, a limit below 2 (one
    probe at the longer axis' lambda); a normal or bump map (the bump-mapped
    plane in perspective) filtered so too."""
    if map_key is None:
        data = stretched_uvs(random_scene(11, textured=True))
    else:
        data = mapped_plane(map_key)
    for tex in data["textures"].values():
        tex["max_anisotropy"] = anisotropy
    assert_same_samples(softras.load_scene(data), f"anisotropy {anisotropy} {map_key}", samples=4)


def mapped_plane(map_key: str) -> dict:
    """scenes/bump_mapped_plane.json with its map as ``map_key`` ("bump_map" or "normal_map")."""
    import json
    data = json.loads((Path(__file__).resolve().parents[1] / "scenes" / "bump_mapped_plane.json").read_text())
    material = data["nodes"][0]["material"]
    material[map_key] = material.pop("bump_map")
    if map_key == "normal_map":
        del material["bump_scale"]
    return data


def test_gl_precision_is_refused():
    scene = softras.load_scene(random_scene(0))
    with pytest.raises(ValueError, match="exact precision only"):
        exact.render_samples(scene, exact_job(scene, precision="gl"))


@pytest.mark.parametrize("samples", [1, 2, 4, 9, 16, 49])
def test_the_compiled_resolve_gives_the_stages_bytes(samples):
    """`exact.resolve` (box, RGBA8) = the stages' resolve, byte for byte, on
    sample values around every byte's rounding boundary ((k + 1/2) / 255 and
    the next doubles either side), out of [0, 1], infinite, NaN and -0."""
    rng = np.random.default_rng(samples)
    height, width = 37, 23
    boundary = (rng.integers(0, 255, (height, width, samples, 4)) + 0.5) / 255.0
    nudged = np.nextafter(boundary, rng.choice([-np.inf, np.inf], boundary.shape))
    color = np.where(rng.random(boundary.shape) < 0.5, boundary, nudged)
    special = [np.nan, np.inf, -np.inf, -0.0, -0.25, 1.5, 1.0, 0.0]
    pick = rng.random(color.shape) < 0.05
    color[pick] = rng.choice(special, int(pick.sum()))
    scene = softras.load_scene(random_scene(0))
    job = exact_job(scene, samples=samples, pattern="halton" if samples not in (1, 4) else None)
    with np.errstate(invalid="ignore"):            # (numpy's NaN to byte conversion warns)
        expected = stages.resolve(job, color)
    assert np.array_equal(exact.resolve(job, color), expected)


def test_the_compiled_resolve_leaves_the_tent_to_the_stages():
    scene = softras.load_scene(random_scene(0))
    color = np.random.default_rng(0).random((scene.height, scene.width, 4, 4))
    for options in ({"resolve_filter": "tent", "samples": 4}, {"resolve_filter": "tent", "samples": 4,
                                                              "framebuffer": "rgba32f"}):
        job = exact_job(scene, **options)
        out, expected = exact.resolve(job, color), stages.resolve(job, color)
        assert out.dtype == expected.dtype and np.array_equal(out, expected), options


@pytest.mark.parametrize("samples", [1, 4, 9, 32])
def test_the_compiled_rgba32f_resolve_gives_the_stages_floats(samples):
    """An rgba32f picture's box filter from the float64 samples
    (`softras.kernels.rgba32f.resolve`): the stages' float32 means
    bit for bit (NaN where NaN; -0.0 samples give +0.0, as numpy's mean
    from 0.0 does), infinities, NaN and values far out of [0, 1] among them."""
    rng = np.random.default_rng(samples)
    color = rng.normal(0.5, 2.0, (37, 23, samples, 4))
    special = [np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-320, 1e300, -1e300]
    pick = rng.random(color.shape) < 0.1
    color[pick] = rng.choice(special, int(pick.sum()))
    color[0, 0] = -0.0
    scene = softras.load_scene(random_scene(0))
    job = exact_job(scene, samples=samples, pattern="halton" if samples not in (1, 4) else None,
                    framebuffer="rgba32f")
    with np.errstate(invalid="ignore", over="ignore"):
        expected = stages.resolve(job, color)
    out = exact.resolve(job, color)
    assert out.dtype == np.float32 and not differing(expected, out).any()


def test_the_reused_framebuffer_is_the_stages_cleared_one():
    """`exact.reused_framebuffer` gives `new_pass_framebuffer`'s values after
    a render has written its scratch arrays, for scenes of other sizes,
    backgrounds and sample counts in turn; and renders that reuse them give
    the stages' pictures in any order (a render of one scene between two of
    another)."""
    a = softras.load_scene(random_scene(1))
    b = softras.load_scene(dict(random_scene(2, width=40, height=61), background=[0.2, 0.4, 0.6, 0.5]))
    for scene, samples in ((a, 4), (b, 1), (a, 1), (b, 9), (a, 4)):
        pattern = "halton" if samples == 9 else None
        job = exact_job(scene, samples=samples, pattern=pattern)
        inputs = stages.Pass.of(job, job.positions)
        exact.render_samples(scene, job, reuse=True)                 # (dirty the scratch)
        for made, expected in zip(exact.reused_framebuffer(scene, inputs), stages.new_pass_framebuffer(scene, inputs)):
            assert made.shape == expected.shape and made.dtype == expected.dtype
            assert np.array_equal(made, expected)
        assert np.array_equal(render_scene(scene, precision="exact", samples=samples, pattern=pattern),
                              render_scene(scene, precision="exact", samples=samples, pattern=pattern,
                                           fast_path=False))


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_setup_gives_the_stages_triangles(seed):
    """`exact.setup_triangles` = `softras.pipeline.setup.setup_triangles`
    (exact) field for field, on random clip-space triangles (w from the
    smallest double to 10: window coordinates infinite or NaN, areas that
    overflow or are NaN, degenerate triangles) with every cull mode, front
    face, tie rule and sample offsets of 1, 4 and 16 samples."""
    from softras.pipeline import setup
    rng = np.random.default_rng(seed)
    clip = rng.uniform(-3, 3, (3000, 3, 4))
    clip[..., 3] = 10.0 ** rng.uniform(-3, 1, (3000, 3))
    clip[::50, :, 3] = 5e-324                               # 1 / w = inf: window coordinates inf
    clip[::100, 0, 0] = 0.0                                  # ... and NaN (0 inf)
    clip[1::40, 1] = clip[1::40, 0]                          # degenerate: two corners equal
    clip[2::30, :, :2] = np.round(clip[2::30, :, :2], 1)     # shared coordinates, edges on samples
    for cull in ("none", "back", "front"):
        for front_face in ("ccw", "cw"):
            for tie_rule in setup.TIE_RULES:
                for samples in (1, 4, 16):
                    offsets, unit = setup.sample_offsets(sampling.sample_positions(samples, "halton"), "exact")
                    options = dict(cull=cull, offsets=offsets, unit=unit, tie_rule=tie_rule, front_face=front_face)
                    with np.errstate(all="ignore"):
                        expected = setup.setup_triangles(clip, 61, 47, precision="exact", **options)
                        got = exact.setup_triangles(clip, 61, 47, **options)
                    for name in expected.__dataclass_fields__:
                        a, b = getattr(expected, name), getattr(got, name)
                        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True), (name, options)


def test_the_compiled_corner_values_give_the_stages_values():
    """`exact.corner_values` = `softras.pipeline.render.corner_values`
    (a vertex's own values at a corner the clipper passed through, -0
    kept; at a corner it made numpy's einsum, summed from 0: a -0 sum
    comes back +0) on clipped random triangles, values with -0,
    infinities and NaN."""
    scene = softras.load_scene(random_scene(3))
    job = exact_job(scene, samples=4)
    inputs = stages.Pass.of(job, job.positions)
    rng = np.random.default_rng(3)
    for draw in scene.draws:
        clipped, tris = exact.set_up_draw(scene, draw, inputs)
        values = rng.normal(size=(len(draw.mesh.positions), 5))
        values[::5] = -0.0
        values[1::7, 1] = np.inf
        values[2::11, 2] = np.nan
        with np.errstate(invalid="ignore"):
            expected = stages.corner_values(clipped, tris, draw.mesh)[1](values)
            got = exact.corner_values(clipped, tris, draw.mesh)(values)
        assert np.array_equal(expected, got, equal_nan=True)
        assert np.array_equal(np.signbit(expected), np.signbit(got))
