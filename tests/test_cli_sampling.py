"""`softras render` sampling and framebuffer options: --samples, --pattern, --seed,
--filter, --framebuffer (exit 2 with one line and nothing written on refusal)."""

import json

import numpy as np
import pytest

import softras
from softras.cli import main
from softras.scene.imageio import read_png

SCENE = {
    "softras_scene": 1, "width": 16, "height": 12, "background": [0, 0, 0, 1],
    "nodes": [{"name": "t", "depth_test": False,
               "mesh": {"positions": [[-0.83, -0.61, 0], [0.71, -0.37, 0], [0.07, 0.77, 0]]}}],
}


@pytest.fixture
def scene_path(tmp_path):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(SCENE))
    return path


def test_render_with_a_pattern_writes_what_the_api_renders(scene_path, tmp_path):
    out = tmp_path / "out.png"
    args = ["render", str(scene_path), "-o", str(out), "--samples", "36", "--pattern", "jittered",
            "--seed", "7", "--filter", "tent"]
    assert main(args) == 0
    expected = softras.render(SCENE, samples=36, pattern="jittered", seed=7, resolve_filter="tent")
    np.testing.assert_array_equal(read_png(out), expected)
    assert 0 < np.count_nonzero((expected[..., 0] > 0) & (expected[..., 0] < 255))   # smooth edges


@pytest.mark.parametrize("extra, message", [
    (["--samples", "5", "--pattern", "grid"], "N*N"),
    (["--samples", "8"], "1 or 4"),
    (["--samples", "4096", "--pattern", "halton"], "1..1024"),
    (["--backend", "gl", "--pattern", "halton"], "--backend soft only"),
])
def test_refused_sampling_options_exit_2_and_write_nothing(scene_path, tmp_path, capsys, extra, message):
    out = tmp_path / "out.png"
    assert main(["render", str(scene_path), "-o", str(out)] + extra) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not out.exists()


def test_rgba32f_render_is_written_quantised(scene_path, tmp_path, capsys):
    out = tmp_path / "out.png"
    assert main(["render", str(scene_path), "-o", str(out), "--framebuffer", "rgba32f"]) == 0
    assert "rgba32f" in capsys.readouterr().out
    image = softras.render(SCENE, framebuffer="rgba32f")
    assert image.dtype == np.float32
    np.testing.assert_array_equal(read_png(out), np.rint(np.clip(image, 0, 1) * 255).astype(np.uint8))
