"""softras bench: the figures it prints are computed correctly (no timing asserted)."""

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


@pytest.mark.gl
def test_measure_reports_every_level_with_zero_error_for_the_truth_level():
    rows = bench.measure("tiny", bench.grid_scene(4, 32), runs=1,
                         levels={"gl": {"precision": "gl"}, "truth": {"precision": "exact", "samples": 4}})
    assert [r.level for r in rows] == ["gl", "truth"]
    assert rows[1].mean_error == 0 and rows[1].bad_fraction == 0
    assert all(r.seconds > 0 and r.ratio == pytest.approx(r.seconds / r.glref_seconds) for r in rows)
