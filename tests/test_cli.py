"""Tests for the softras command line (softras.cli) and PNG I/O (softras.scene.imageio).

Most tests run ``main([...])`` in-process. Exit statuses follow docs/design.md
section 6: 0 success/pass, 1 comparison failed, 2 bad input or environment
error with one line on stderr and no partial or clobbered output file.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import SCENES
from softras.cli import main
from softras.scene.imageio import ImageError, read_png, write_png_atomic

# A small valid scene (format version 1): one coloured triangle.
TRIANGLE_SCENE = {
    "softras_scene": 1,
    "width": 16,
    "height": 12,
    "background": [0, 0, 0, 1],
    "camera": {"projection": "orthographic", "left": -1, "right": 1, "bottom": -1, "top": 1,
               "near": -1, "far": 1},
    "nodes": [
        {
            "name": "triangle",
            "mesh": {
                "positions": [[-0.6, -0.5, 0], [0.7, -0.4, 0], [0.1, 0.6, 0]],
                "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]],
            },
        }
    ],
}


def image(height=12, width=16, seed=0):
    rng = np.random.default_rng(seed)
    out = rng.integers(0, 256, size=(height, width, 4), dtype=np.uint8)
    out[..., 3] = 255
    return out


def save(path, array):
    write_png_atomic(path, array)
    return str(path)


def error_line(capsys):
    """The captured stderr, which must be exactly one 'softras: error:' line."""
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("softras: error: ")
    assert "Traceback" not in err
    return lines[0]


def write_scene(tmp_path, scene=TRIANGLE_SCENE, name="scene.json"):
    path = tmp_path / name
    path.write_text(json.dumps(scene))
    return str(path)


# ---------------------------------------------------------------------------
# Help and usage


def test_the_command_line_renders_without_importing_scipy_linalg(tmp_path):
    """A ``softras render`` process loads numba's array code with BLAS
    hidden (`softras.cli._without_numba_blas`: scipy.linalg took 0.3 s of a
    first render) and draws the same bytes as a process that imported
    scipy.linalg first; scipy.linalg still imports after it."""
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(TRIANGLE_SCENE))
    program = f"""
import sys
from softras.cli import main
assert main(["render", {str(scene)!r}, "-o", sys.argv[1]]) == 0
print("scipy.linalg" in sys.modules)
import scipy.linalg
"""
    runs = []
    for first in ("", "import scipy.linalg; "):
        out = tmp_path / f"out{len(runs)}.png"
        done = subprocess.run([sys.executable, "-c", first + program, str(out)], capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append((done.stdout.split()[-1], read_png(out)))
    assert [loaded for loaded, _ in runs] == ["False", "True"]
    assert np.array_equal(runs[0][1], runs[1][1])


@pytest.mark.parametrize("command", ["compare", "info", "conformance"])
def test_commands_that_run_no_compiled_code_import_no_numba(tmp_path, command):
    """`softras compare`, `softras info` and the `softras conformance`
    supervisor (its workers, processes of their own, render) run no
    compiled code: they neither install the compile notice nor load numba's
    array implementations, and do not import numba at all (the import 0.16
    s; a supervisor's CPU 0.47 -> 0.30 s without both): reading a scene
    compiles nothing (`softras.scene.texels._compiled`)."""
    image = tmp_path / "a.png"
    write_png_atomic(image, np.zeros((8, 8, 4), np.uint8))
    argv = {"compare": ["compare", str(image), str(image)], "info": ["info"],
            "conformance": ["conformance", str(SCENES / "texture_wrap_modes.json"), "--report",
                            str(tmp_path / "report")]}[command]
    program = f"""
import sys
from softras.cli import main
assert main({argv!r}) == 0
print("numba" in sys.modules)
"""
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == "False"


def test_python_m_softras_help():
    done = subprocess.run([sys.executable, "-m", "softras", "--help"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    for command in ("render", "compare", "demo"):
        assert command in done.stdout


def test_usage_error_is_one_line(capsys):
    assert main(["compare"]) == 2
    error_line(capsys)
    assert main(["render", "scene.json"]) == 2  # -o missing
    error_line(capsys)
    assert main(["compare", "a.png", "b.png", "--threshold", "300"]) == 2
    error_line(capsys)
    assert main(["render", "scene.json", "-o", "x.png", "--samples", "3"]) == 2
    error_line(capsys)


def test_no_command_is_an_error(capsys):
    assert main([]) == 2
    assert "usage" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# compare A B


def test_compare_identical_pngs_pass(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    b = save(tmp_path / "b.png", image())
    assert main(["compare", a, b]) == 0
    out = capsys.readouterr().out
    assert "PASS" in out and "SSIM" in out


def test_compare_different_pngs_fail_and_write_diff(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    b = save(tmp_path / "b.png", image(seed=1))
    diff = tmp_path / "diff.png"
    assert main(["compare", a, b, "-o", str(diff)]) == 1
    assert "FAIL" in capsys.readouterr().out
    written = read_png(diff)
    assert written.shape == (12, 16, 4)
    assert np.all(written[..., 3] == 255)
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind


def test_compare_json(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    changed = image()
    changed[3, 4, 0] ^= 0x40
    b = save(tmp_path / "b.png", changed)
    assert main(["compare", a, b, "--json", "--max-bad-fraction", "0.01", "--min-ssim", "0.5"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is True
    assert data["max_diff"] == 64
    assert data["bad_pixels"] == 1
    assert data["max_bad_fraction"] == 0.01
    assert data["a"] == a and data["b"] == b


def test_compare_tolerance_options(tmp_path):
    a = save(tmp_path / "a.png", image())
    changed = image()
    changed[..., 1] = np.where(changed[..., 1] < 250, changed[..., 1] + 5, changed[..., 1] - 5)
    b = save(tmp_path / "b.png", changed)
    assert main(["compare", a, b]) == 1
    assert main(["compare", a, b, "--threshold", "5", "--min-ssim", "0.9"]) == 0


def test_compare_missing_input(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    diff = tmp_path / "diff.png"
    assert main(["compare", a, str(tmp_path / "missing.png"), "-o", str(diff)]) == 2
    line = error_line(capsys)
    assert "missing.png" in line
    assert not diff.exists()


def test_compare_error_leaves_existing_output_untouched(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    diff = tmp_path / "diff.png"
    diff.write_bytes(b"precious")
    assert main(["compare", a, str(tmp_path / "missing.png"), "-o", str(diff)]) == 2
    error_line(capsys)
    assert diff.read_bytes() == b"precious"
    # Shape mismatch: also bad input, also nothing written.
    small = save(tmp_path / "small.png", image(8, 8))
    assert main(["compare", a, small, "-o", str(diff)]) == 2
    assert "differ in shape" in error_line(capsys)
    assert diff.read_bytes() == b"precious"


def test_compare_not_a_png(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    fake = tmp_path / "fake.png"
    fake.write_text("not an image\n")
    assert main(["compare", a, str(fake)]) == 2
    assert "fake.png" in error_line(capsys)


@pytest.mark.parametrize("where", ["missing_folder", "parent_is_file", "is_a_folder"])
def test_compare_unwritable_output(tmp_path, capsys, where):
    a = save(tmp_path / "a.png", image())
    b = save(tmp_path / "b.png", image(seed=1))
    if where == "missing_folder":
        target = tmp_path / "no" / "such" / "diff.png"
    elif where == "parent_is_file":
        (tmp_path / "file").write_text("x")
        target = tmp_path / "file" / "diff.png"
    else:
        target = tmp_path / "folder"
        target.mkdir()
    assert main(["compare", a, b, "-o", str(target)]) == 2
    error_line(capsys)
    assert not (tmp_path / "no").exists()
    assert target.is_dir() if where == "is_a_folder" else not target.exists()


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs file permissions (not root)")
def test_compare_read_only_folder(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    b = save(tmp_path / "b.png", image(seed=1))
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert main(["compare", a, b, "-o", str(folder / "diff.png")]) == 2
        error_line(capsys)
        assert not list(folder.iterdir())
    finally:
        folder.chmod(0o755)


def test_compare_reports_flip_and_writes_ssim_and_flip_maps(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    assert main(["compare", a, save(tmp_path / "same.png", image()), "--json"]) == 0   # identical: 0
    same = json.loads(capsys.readouterr().out)
    assert same["flip_mean"] == 0.0 and same["max_diff"] == 0 and same["ssim"] == pytest.approx(1.0)

    changed = image()
    changed[2:6, 3:9, :3] = 255 - changed[2:6, 3:9, :3]
    b = save(tmp_path / "b.png", changed)
    maps = {name: tmp_path / f"{name}.png" for name in ("diff", "ssim", "flip")}
    assert main(["compare", a, b, "-o", str(maps["diff"]), "--ssim-map", str(maps["ssim"]),
                 "--flip-map", str(maps["flip"]), "--json"]) == 1                     # differing: 1
    data = json.loads(capsys.readouterr().out)
    assert 0.0 < data["flip_mean"] <= 1.0 and data["bad_pixels"] == 24
    assert sorted(data["outputs"]) == sorted(str(path) for path in maps.values())
    for name, path in maps.items():
        written = read_png(path).astype(int)
        assert written.shape == (12, 16, 4)
        # Bright inside the edit, dark far from it (FLIP's filters spread a few pixels).
        assert written[4, 5, :3].sum() > 200 and written[11, 15, :3].sum() < 100, name
    assert not read_png(maps["diff"])[11, 15, :3].any()
    assert main(["compare", a, b]) == 1
    assert "FLIP" in capsys.readouterr().out


def test_compare_unreadable_input_writes_no_map(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    maps = [tmp_path / "diff.png", tmp_path / "ssim.png", tmp_path / "flip.png"]
    for other in (str(broken), str(tmp_path / "missing.png")):
        assert main(["compare", a, other, "-o", str(maps[0]), "--ssim-map", str(maps[1]),
                     "--flip-map", str(maps[2])]) == 2
        assert Path(other).name in error_line(capsys)
        assert not any(path.exists() for path in maps)


def test_compare_without_flip_evaluator_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)  # import fails
    a = save(tmp_path / "a.png", image())
    diff = tmp_path / "diff.png"
    assert main(["compare", a, a, "-o", str(diff)]) == 2
    assert "pip install flip-evaluator" in error_line(capsys)
    assert not diff.exists()


def test_compare_options_for_scene_only(tmp_path, capsys):
    a = save(tmp_path / "a.png", image())
    assert main(["compare", a, a, "--out-dir", str(tmp_path / "o")]) == 2
    error_line(capsys)
    assert main(["compare", a]) == 2  # one PNG: neither form
    error_line(capsys)
    assert main(["compare", a, a, a]) == 2
    error_line(capsys)


# ---------------------------------------------------------------------------
# Scenes (need softras.scene / softras.render)


def test_render_malformed_scene(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"softras_scene": 1, "width": 16,,}')
    out = tmp_path / "out.png"
    assert main(["render", str(bad), "-o", str(out)]) == 2
    error_line(capsys)
    assert not out.exists()


def test_render_invalid_scene(tmp_path, capsys):
    scene = dict(TRIANGLE_SCENE, no_such_key=1)  # unknown keys are an error
    path = write_scene(tmp_path, scene)
    out = tmp_path / "out.png"
    out.write_bytes(b"precious")
    assert main(["render", path, "-o", str(out)]) == 2
    error_line(capsys)
    assert out.read_bytes() == b"precious"


def test_compare_malformed_scene(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2")
    out_dir = tmp_path / "out"
    assert main(["compare", str(bad), "--out-dir", str(out_dir)]) == 2
    error_line(capsys)
    assert not out_dir.exists()


def test_render_soft(tmp_path, capsys):
    path = write_scene(tmp_path)
    out = tmp_path / "soft.png"
    assert main(["render", path, "-o", str(out)]) == 0
    picture = read_png(out)
    assert picture.shape == (12, 16, 4)
    assert picture[..., :3].any()  # the triangle is there
    assert "soft" in capsys.readouterr().out


def test_render_to_missing_folder(tmp_path, capsys):
    path = write_scene(tmp_path)
    assert main(["render", path, "-o", str(tmp_path / "nope" / "soft.png")]) == 2
    error_line(capsys)
    assert not (tmp_path / "nope").exists()


def test_render_precision_needs_soft(tmp_path, capsys):
    path = write_scene(tmp_path)
    assert main(["render", path, "-o", str(tmp_path / "x.png"), "--backend", "gl", "--precision", "exact"]) == 2
    error_line(capsys)


def test_gl_unavailable_is_exit_2(tmp_path, capsys, monkeypatch):
    import glref

    def no_gl(*args, **kwargs):
        raise glref.GLUnavailable("no EGL display (simulated)")

    monkeypatch.setattr(glref, "render", no_gl)
    path = write_scene(tmp_path)
    assert main(["render", path, "-o", str(tmp_path / "gl.png"), "--backend", "gl"]) == 2
    assert "simulated" in error_line(capsys)
    assert main(["compare", path, "--out-dir", str(tmp_path / "out"), "-o", str(tmp_path / "d.png")]) == 2
    error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json"]


@pytest.mark.gl
def test_render_gl(tmp_path):
    path = write_scene(tmp_path)
    out = tmp_path / "gl.png"
    assert main(["render", path, "-o", str(out), "--backend", "gl"]) == 0
    assert read_png(out).shape == (12, 16, 4)


@pytest.mark.gl
def test_compare_scene_writes_three_images(tmp_path, capsys):
    path = write_scene(tmp_path)
    out_dir = tmp_path / "out" / "sub"
    diff = tmp_path / "diff.png"
    status = main(["compare", path, "--out-dir", str(out_dir), "-o", str(diff), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert status == (0 if data["passed"] else 1)
    for name in ("soft.png", "gl.png", "diff.png"):
        assert read_png(out_dir / name).shape == (12, 16, 4)
    assert diff.exists()
    assert data["threshold"] == 2  # the scene's default tolerance


@pytest.mark.gl
def test_demo(tmp_path, capsys):
    scene = Path(__file__).resolve().parents[1] / "scenes" / "demo.json"
    if not scene.exists():
        pytest.fail(f"{scene} is missing")
    status = main(["demo", "--out-dir", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert status in (0, 1)
    assert ("PASS" in out) == (status == 0)
    for name in ("soft.png", "gl.png", "diff.png"):
        assert (tmp_path / "out" / name).exists()


def test_demo_missing_scene(tmp_path, capsys):
    assert main(["demo", "--scene", str(tmp_path / "none.json"), "--out-dir", str(tmp_path / "out")]) == 2
    assert "none.json" in error_line(capsys)
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------
# softras.scene.imageio


def test_read_png_expands_rgb_and_grey(tmp_path):
    rgb = image()[..., :3]
    Image.fromarray(rgb).save(tmp_path / "rgb.png")
    read = read_png(tmp_path / "rgb.png")
    assert read.shape == (12, 16, 4) and read.dtype == np.uint8
    assert np.array_equal(read[..., :3], rgb)
    assert np.all(read[..., 3] == 255)

    grey = image()[..., 0]
    Image.fromarray(grey).save(tmp_path / "grey.png")
    read = read_png(tmp_path / "grey.png")
    assert read.shape == (12, 16, 4)
    for channel in range(3):
        assert np.array_equal(read[..., channel], grey)
    assert np.all(read[..., 3] == 255)

    grey16 = (grey.astype(np.uint16) * 257)
    Image.fromarray(grey16).save(tmp_path / "grey16.png")
    assert np.array_equal(read_png(tmp_path / "grey16.png")[..., 0], grey)


def test_png_round_trip_rgba(tmp_path):
    picture = image()
    picture[..., 3] = np.arange(16, dtype=np.uint8)[None, :] * 16
    write_png_atomic(tmp_path / "x.png", picture)
    assert np.array_equal(read_png(tmp_path / "x.png"), picture)


def test_read_png_errors_are_one_line(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    Image.fromarray(image()[..., :3]).save(tmp_path / "x.jpg")
    for path in (tmp_path / "missing.png", tmp_path / "bad.png", tmp_path / "x.jpg", tmp_path):
        with pytest.raises(ImageError) as info:
            read_png(path)
        message = str(info.value)
        assert message.startswith(str(path) + ": ") and "\n" not in message


def test_atomic_write_keeps_old_file_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "x.png"
    target.write_bytes(b"precious")

    def broken_save(self, *args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(ImageError, match="No space left"):
        write_png_atomic(target, image())
    assert target.read_bytes() == b"precious"
    assert [p.name for p in tmp_path.iterdir()] == ["x.png"]


def test_atomic_write_rejects_bad_images(tmp_path):
    for bad in (image().astype(np.float32), np.zeros((4, 4, 2), np.uint8), np.zeros((0, 4, 4), np.uint8)):
        with pytest.raises(ImageError):
            write_png_atomic(tmp_path / "x.png", bad)
    assert not list(tmp_path.iterdir())


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("softras 0.")


@pytest.mark.parametrize("name", ["picture.jpg", "picture.JPEG", "picture", "diff.tiff"])
def test_an_output_that_is_not_png_is_refused(tmp_path, capsys, name):
    """PNG bytes under another name would mislead: refused up front, nothing written."""
    output = tmp_path / name
    status = main(["render", str(Path(__file__).resolve().parents[1] / "scenes" / "demo.json"), "-o", str(output)])
    assert status == 2
    assert capsys.readouterr().err == f"softras: error: {output}: softras writes PNG pictures only; name the file .png\n"
    assert list(tmp_path.iterdir()) == []


def test_render_offers_every_texture_filter_and_draws_what_the_api_draws(tmp_path):
    """``render --texture-filter`` takes each of `texture_beyond.FILTERS` (level0
    was missing) and writes the picture `softras.render` gives for it."""
    import softras
    from softras.cli import TEXTURE_FILTERS
    from softras.pipeline.texture_beyond import FILTERS

    assert TEXTURE_FILTERS == FILTERS
    scene = Path(__file__).resolve().parent.parent / "scenes" / "texture_npot.json"
    for name in FILTERS:
        out = tmp_path / f"{name}.png"
        assert main(["render", str(scene), "-o", str(out), "--texture-filter", name]) == 0
        expected = softras.render(softras.load_scene(scene), texture_filter=name)
        assert np.array_equal(read_png(out), expected), name
