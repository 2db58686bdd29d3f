"""softras bench: the figures it prints are computed correctly (no timing asserted)."""

import functools
import itertools
import json

import numpy as np
import pytest

from softras import bench


def test_fit_exponent_recovers_power_laws():
    n = np.array([1e3, 1e4, 1e5])
    assert bench.fit_exponent(n, 2e-6 * n) == pytest.approx(1.0)
    assert bench.fit_exponent(n, 3e-9 * n ** 2) == pytest.approx(2.0)


def test_grid_scene_triangle_count():
    import softras
    scene = softras.load_scene(bench.grid_scene(10, 64))
    assert len(scene.draws[0].mesh.indices) == 200


def test_benchmark_set_covers_the_issue_and_scales():
    """Quick is a subset of full; full sweeps 1k..1M triangles and 256^2..2048^2 pixels."""
    import softras
    quick = {s.name for s in bench.scenes(full=False)}
    full = bench.scenes(full=True)
    assert quick < {s.name for s in full}
    kinds = {"many_small_24k_512", "few_large_512", "floor_trilinear_512", "msaa4_24k_512", "blended_8x128_512"}
    assert kinds <= quick
    tris = [s for s in full if s.series == "triangles"]
    pixels = [s for s in full if s.series == "pixels"]
    counts = [len(softras.load_scene(s.scene).draws[0].mesh.indices) for s in tris]
    assert counts[0] <= 1100 and counts[-1] >= 999_000
    assert [s.scene["width"] for s in pixels] == [256, 512, 1024, 2048]
    assert softras.load_scene(bench.floor_scene(64)).textures["checker"].min_filter == "linear_mipmap_linear"
    assert all(n["blend"] == "over" for n in bench.blended_scene(64)["nodes"])
    # Stand-ins for real content: what each one uses.
    loaded = {s.name: softras.load_scene(s.scene) for s in full if s.name in quick and not s.levels
              and not s.series}
    uses = {name: (sum(len(d.mesh.indices) for d in scene.draws), scene.width, scene.samples,
                   scene.draws[0].material.shading, scene.draws[0].material.texture is not None,
                   scene.draws[0].mesh.primitive) for name, scene in loaded.items()}
    assert uses == {"scan_phong_71k_512": (71168, 512, 1, "phong", False, "triangles"),
                    "scan_gouraud_71k_512": (71168, 512, 1, "gouraud", False, "triangles"),
                    "gouraud_msaa4_24k_512": (24064, 512, 4, "gouraud", False, "triangles"),
                    "flat_6k_512": (6016, 512, 1, "flat", False, "triangles"),
                    "textured_phong_8k_1024": (9024, 1024, 1, "phong", True, "triangles"),
                    "bump_mapped_8k_512": (9024, 512, 1, "phong", True, "triangles"),
                    "lines_8k_512": (8320, 512, 1, "unlit", False, "lines"),
                    "parts_64x128_512": (8192, 512, 1, "unlit", False, "triangles"),
                    "textured_parts_64x128_512": (8192, 512, 1, "phong", True, "triangles"),
                    "transparent_8x128_512": (1152, 512, 1, "unlit", False, "triangles")}, uses
    transparent = loaded["transparent_8x128_512"].draws
    assert transparent[0].blend == "none" and transparent[0].depth_write
    assert all(d.blend == "over" and d.depth_test == "less" and not d.depth_write for d in transparent[1:])
    assert loaded["bump_mapped_8k_512"].draws[0].material.bump_map is not None
    assert len(loaded["parts_64x128_512"].draws) == 64
    assert {d.material.texture for d in loaded["textured_parts_64x128_512"].draws} == {"checker"}


def test_level_table_one_line_per_level_and_applicability():
    import softras
    names = [level.name for level in bench.LEVELS]
    assert len(names) == len(set(names)) and names[:3] == ["gl", "exact", "gl_msaa4"]
    grid = softras.load_scene(bench.grid_scene(4, 32))
    floor = softras.load_scene(bench.floor_scene(32))
    ewa = next(level for level in bench.LEVELS if level.name == "gl_ewa")
    assert not bench.applicable(ewa, grid, full=False) and bench.applicable(ewa, floor, full=False)
    slow = next(level for level in bench.LEVELS if not level.quick)
    assert not bench.applicable(slow, grid, full=False) and bench.applicable(slow, grid, full=True)


@pytest.mark.gl
def test_measure_reports_every_level_with_errors_against_the_supersampled_truth():
    rows = bench.measure("tiny", bench.grid_scene(4, 32), runs=1,
                         levels={"gl": {"precision": "gl"}, "exact_16": bench.EXACT_16,
                                 "gl_rgba32f": {"precision": "gl", "framebuffer": "rgba32f"}})
    assert [r.level for r in rows] == ["gl", "exact_16", "gl_rgba32f"]
    # 16 samples a pixel come closer to the 256-sample truth than one.
    assert 0 < rows[1].mean_error < rows[0].mean_error and rows[1].bad_fraction <= rows[0].bad_fraction
    # An rgba32f picture is judged on the bytes' scale: the same error as
    # RGBA8 but for the bytes' rounding (at most half a step a channel).
    assert abs(rows[2].mean_error - rows[0].mean_error) <= 0.5
    assert all(r.seconds > 0 and r.ratio == pytest.approx(r.seconds / r.glref_seconds) for r in rows)
    assert all(r.peak_mib > 0 and r.rss_mib > 0 for r in rows)
    assert rows[0].mtri_per_s == pytest.approx(32 / rows[0].seconds / 1e6)
    # The gl level is also timed from the scene file (loading included), the others not.
    assert rows[0].file_seconds > 0 and rows[0].glref_file_seconds > 0
    assert rows[0].file_ratio == pytest.approx(rows[0].file_seconds / rows[0].glref_file_seconds)
    assert rows[1].file_seconds is None and "from file" not in bench.format_row(rows[1])
    assert "from file" in bench.format_row(rows[0])


def test_glref_is_timed_at_the_levels_gl_sample_count(monkeypatch):
    """gl_msaa4 on a 1-sample scene is compared with glref's 4x MSAA; a
    level at a pattern GL does not have, with glref at the scene's count;
    gl_rgba32f with glref's rgba32f framebuffer."""
    import softras
    calls = []
    real = softras.render

    def render(scene, backend="soft", **options):
        if backend == "gl":
            calls.append((options.get("samples"), options.get("framebuffer")))
        return real(scene, backend=backend, **options)
    monkeypatch.setattr(softras, "render", render)
    rows = bench.measure("tiny", bench.grid_scene(2, 16), runs=1, errors=False, memory=False,
                         levels={"gl": {"precision": "gl"}, "gl_msaa4": {"precision": "gl", "samples": 4},
                                 "gl_16": {"precision": "gl", "samples": 16, "pattern": "rotated_grid"},
                                 "gl_rgba32f": {"precision": "gl", "framebuffer": "rgba32f"}})
    # (16: GL has no such pattern; rgba32f: glref's own rgba32f framebuffer.)
    # Each level's glref renders are its own, interleaved with its softras
    # renders (the gl level's include those from the scene file).
    assert [key for key, _ in itertools.groupby(calls)] == [(None, None), (4, None), (None, None),
                                                           (None, "rgba32f")], calls
    assert all(r.glref_seconds > 0 for r in rows)


def test_paired_times_interleave_at_least_the_minimum_of_pairs(monkeypatch):
    """softras and glref alternately, a warm-up pair first; at least
    MIN_PAIRS pairs while the budget lasts, only ``runs`` once it is spent;
    the medians are each renderer's own, and the result is softras's."""
    calls = []
    clock = iter(range(10_000))
    monkeypatch.setattr(bench.time, "perf_counter", lambda: next(clock) * 0.001)

    def soft():
        calls.append("soft")
        next(clock)                   # (softras takes one more tick than glref)
        return "picture"
    soft_s, gl_s, result = bench._paired_times(soft, lambda: calls.append("gl"), runs=3)
    assert calls == ["soft", "gl"] * (1 + bench.MIN_PAIRS)
    assert (soft_s, gl_s, result) == (pytest.approx(0.002), pytest.approx(0.001), "picture")
    calls.clear()
    monkeypatch.setattr(bench, "PAIR_BUDGET", 0.0)
    bench._paired_times(soft, lambda: calls.append("gl"), runs=3)
    assert calls == ["soft", "gl"] * (1 + 3)


def test_file_times_load_the_file_for_each_render(monkeypatch):
    """From the file: softras and glref alternately (`bench._paired_times`),
    each from a fresh load of the written scene."""
    import softras
    calls = []
    monkeypatch.setattr(softras, "render", lambda scene, **options: calls.append(options.get("backend", "soft")))
    monkeypatch.setattr(softras, "load_scene", lambda path: calls.append("load"))
    monkeypatch.setattr(bench, "PAIR_BUDGET", 0.0)
    bench._file_times(bench.grid_scene(2, 16), {"precision": "gl"}, runs=3)
    assert calls == ["load", "soft", "load", "gl"] * (1 + 3)


@pytest.mark.gl
def test_unknown_option_makes_a_level_not_applicable_instead_of_failing():
    rows = bench.measure("tiny", bench.grid_scene(2, 16), runs=1, errors=False,
                         levels={"bogus": {"precision": "gl", "no_such_option": 1}})
    assert rows[0].seconds is None and rows[0].note.startswith("n/a")


@pytest.mark.gl
def test_run_writes_json_and_plot(tmp_path, monkeypatch):
    small = [bench.BenchScene("grid", bench.grid_scene(4, 32)),
             bench.BenchScene("t1", bench.grid_scene(4, 32), levels=False, series="triangles"),
             bench.BenchScene("t2", bench.grid_scene(8, 32), levels=False, series="triangles")]
    monkeypatch.setattr(bench, "scenes", lambda *args, **kwargs: small)
    monkeypatch.setattr(bench, "LEVELS", [bench.Level("gl", {"precision": "gl"}, "gl")])
    monkeypatch.setattr(bench, "LOADER_GRIDS", (4,))
    # What is checked here is the report, not the timing
    # (test_paired_times_interleave_at_least_the_minimum_of_pairs): one timed
    # pair a figure, one timed load.  (The loader's nine runs collect the
    # garbage before each call, slow in a test worker that has run hundreds
    # of tests: this test took 10 s in the suite, 1.8 s alone.)
    monkeypatch.setattr(bench, "PAIR_BUDGET", 0.0)
    monkeypatch.setattr(bench, "loader_times", functools.partial(bench.loader_times, runs=1))
    lines = []
    report = bench.run(runs=1, out_json=str(tmp_path / "b.json"), out_plot=str(tmp_path / "b.png"),
                       echo=lines.append)
    saved = json.loads((tmp_path / "b.json").read_text())
    assert saved["fits"] == report["fits"] and "triangles_exponent" in saved["fits"]
    assert [r["scene"] for r in saved["rows"]] == ["grid", "t1", "t2"]
    assert (tmp_path / "b.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert lines[0] == bench.HEADER and lines[-3].startswith("cost fits")
    assert lines[-2].startswith("loader: 32 triangles as explicit arrays") and "ratio" in lines[-2]
    assert saved["loader"][0]["triangles"] == 32 and saved["loader"][0]["ratio"] > 0
    # The run's wall and CPU time (all its threads), as printed and saved.
    run_time = saved["run_time"]
    assert 0 < run_time["wall_seconds"] and 0 < run_time["cpu_seconds"] and run_time["cores"] >= 1
    assert lines[-1] == (f"this run: {run_time['wall_seconds']:.1f} s of wall time, "
                         f"{run_time['cpu_seconds']:.1f} s of CPU in this process (all its threads) on "
                         f"{run_time['cores']} cores")


@pytest.mark.gl
def test_the_truth_favours_no_texture_filter():
    """The error figures' truth is level-0 texels densely supersampled, not a
    level's own filter: on the receding floor EWA and ripmap, which follow
    the footprint, come closer to it than trilinear (as
    docs/textures_and_lighting.md measures); a truth rendered with trilinear
    filtering ranked them the other way."""
    rows = bench.measure("floor", bench.floor_scene(64), runs=1, memory=False,
                         levels={"gl": {"precision": "gl"}, "gl_ripmap": {"precision": "gl", "texture_filter": "ripmap"},
                                 "gl_ewa": {"precision": "gl", "texture_filter": "ewa"}})
    error = {r.level: r.mean_error for r in rows}
    assert error["gl_ewa"] < error["gl"] and error["gl_ripmap"] < error["gl"], error


def test_truth_factor_keeps_the_supersampled_picture_bounded():
    from types import SimpleNamespace
    factors = [bench.truth_factor(SimpleNamespace(width=w, height=h))
               for w, h in ((32, 32), (128, 96), (512, 512), (1024, 768), (2048, 2048))]
    assert factors == [16, 16, 4, 2, 1]
