"""The ``softras`` command line.

::

    softras render SCENE -o OUT.png [--backend soft|gl] [--precision gl|exact] [--samples N]
                   [--pattern P] [--seed K] [--filter box|tent] [--framebuffer rgba8|rgba32f]
    softras compare A.png B.png [-o DIFF.png] [--json] [--threshold N]
                    [--max-bad-fraction F] [--min-ssim S]
    softras compare SCENE.json [-o DIFF.png] [--json] [--out-dir DIR]
                    [--precision gl|exact] [--samples N] [tolerance options]
    softras demo [--scene SCENE.json] [--out-dir DIR] [--json] [--precision gl|exact]
    softras golden [--update] [--golden-dir DIR] [--out-dir DIR] [PATH ...]
    softras conformance [PATH ...] [--report DIR] [-k PATTERN] [--shard I/N] [-j N]
                        [--profile auto|strict|spec] [--timeout S] [--retries K]
                        [--baseline FILE] [--resume DIR] [--max-memory SIZE]
    softras conformance --merge DIR [DIR ...] --report OUT [--baseline FILE]
    softras verify SCENE IMAGE REFERENCE [--profile spec|strict|auto] [--capabilities F]
                   [--json] [--out-dir DIR]
    softras info [--json]
    softras bench [--quick | --full] [--runs N] [--max-triangles N] [--max-side N]
                  [--json OUT.json] [--plot OUT.png]

``--gl-device N`` (before the command) picks the N-th EGL device for glref.

Exit status: 0 success or comparison passed, 1 comparison
failed, 2 bad input or environment error; ``conformance`` also 130 when
interrupted (SIGINT, SIGTERM), with the report of what finished written. On status 2 exactly one line,
``softras: error: <reason>``, goes to stderr, and no output file is created or
changed: inputs are read and output folders checked before anything is
written, and every file is written atomically (temporary file + rename).

Only expected failures are turned into status 2 (bad scenes, unreadable
images, missing OpenGL, unwritable outputs, images of different sizes);
anything else is a bug and keeps its traceback.

Heavy modules (the pipeline, glref, scikit-image) are imported inside the
commands, so ``softras --help`` stays fast.

Why one module of ~990 lines: the argparse definitions, each command's
handler and the shared error handling (one line, exit 2) are kept together
so every command's flags, help and exit codes can be read in one file; the
work itself is done by the layers below.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

__all__ = ["main", "CLIError", "DEFAULT_DEMO_SCENE"]

_PACKAGE = Path(__file__).resolve().parent
#: The demo scene of the README quick start: scenes/demo.json of the source
#: checkout, or the copy an installed wheel holds in the package
#: (softras/scenes/demo.json, pyproject.toml).
DEFAULT_DEMO_SCENE = next((path for path in (_PACKAGE.parent / "scenes" / "demo.json",
                                             _PACKAGE / "scenes" / "demo.json") if path.is_file()),
                          _PACKAGE.parent / "scenes" / "demo.json")

#: Where ``softras golden`` keeps the golden images: ``golden/`` of the current
#: directory (relative: the user's project, never the installed package).
DEFAULT_GOLDEN_DIR = Path("golden")

#: Tolerances used when comparing two PNG files (same as softras.compare).
DEFAULT_TOLERANCE = {"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99}

#: ``render --texture-filter``: `softras.pipeline.texture_beyond.FILTERS`, written
#: out so that ``--help`` imports no numpy (tests/test_cli.py checks they agree).
TEXTURE_FILTERS = ("ripmap", "ewa", "level0")

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_ERROR = 2


class CLIError(Exception):
    """An expected failure: bad input or environment. Exit status 2.

    ``str(error)`` is the one-line reason printed after ``softras: error:``.
    """


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line on stderr, status 2."""

    def error(self, message: str):  # noqa: D102 - argparse API
        self.exit(EXIT_ERROR, f"softras: error: {message} (see '{self.prog} --help')\n")


# ---------------------------------------------------------------------------
# Helpers shared by the commands


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _load_scene(path: str):
    """Load a scene file, turning a SceneError into a CLIError."""
    from softras.scene import SceneError, load_scene

    try:
        return load_scene(path)
    except SceneError as error:
        raise CLIError(_one_line(error)) from None


def _render(scene, backend: str, precision: str | None, samples: int | None, **extra):
    """Render ``scene`` with one backend; returns (image, seconds).

    ``extra``: more render options (pattern, seed, resolve_filter,
    framebuffer).  Expected failures (missing OpenGL, a scene the backend
    rejects) become CLIError.
    """
    import softras
    from softras.scene import SceneError

    options = dict(extra)
    if samples is not None:
        options["samples"] = samples
    if backend == "soft" and precision is not None:
        options["precision"] = precision

    gl_unavailable: tuple[type[BaseException], ...] = ()
    not_supported: tuple[type[BaseException], ...] = ()
    if backend == "gl":
        try:
            import glref
        except ModuleNotFoundError as error:
            if error.name not in ("moderngl", "glcontext"):
                raise
            raise CLIError(f"OpenGL reference renderer unavailable: {_one_line(error)}") from None
        gl_unavailable = (glref.GLUnavailable,)
        not_supported = (glref.NotSupported,)

    start = time.perf_counter()
    try:
        image = softras.render(scene, backend=backend, **options)
    except SceneError as error:
        raise CLIError(_one_line(error)) from None
    except gl_unavailable as error:
        raise CLIError(f"OpenGL unavailable: {_one_line(error)}") from None
    except not_supported as error:
        raise CLIError(f"not supported: {_one_line(error)}") from None
    return image, time.perf_counter() - start


def _gl_description() -> str | None:
    """One line naming the OpenGL implementation glref used, if known."""
    import glref

    try:
        info = glref.info()
    except glref.GLUnavailable:
        return None
    renderer = info.get("GL_RENDERER", "unknown renderer")
    version = info.get("GL_VERSION")
    return f"{renderer}, OpenGL {version}" if version else str(renderer)


def _check_output_file(path: str | os.PathLike) -> Path:
    """Check that an output PNG can be written, before anything is done: its
    name ends in .png (softras writes PNG only; PNG bytes under another name
    would mislead) and its folder is writable."""
    from softras.scene.imageio import check_writable

    if Path(path).suffix.lower() != ".png":
        raise CLIError(f"{path}: softras writes PNG pictures only; name the file .png")
    return check_writable(path)


def _check_output_dir(folder: str | os.PathLike) -> Path:
    """Check that ``folder`` exists and is writable, or can be created."""
    folder = Path(folder)
    if folder.exists():
        if not folder.is_dir():
            raise CLIError(f"{folder}: not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise CLIError(f"{folder}: folder is not writable")
        return folder
    ancestor = folder.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir() or not os.access(ancestor, os.W_OK | os.X_OK):
        raise CLIError(f"{folder}: cannot create folder ({ancestor} is not a writable folder)")
    return folder


def _compare(a, b, tolerance: dict):
    """softras.compare with FLIP (b is the reference); a shape mismatch or a
    missing flip-evaluator becomes a CLIError."""
    from softras.verification.metrics import FlipUnavailable, ShapeMismatch, compare

    try:
        return compare(a, b, flip=True, **tolerance)
    except (ShapeMismatch, FlipUnavailable) as error:
        raise CLIError(_one_line(error)) from None


def _map_outputs(args: argparse.Namespace) -> dict:
    """The picture files asked for (-o, --ssim-map, --flip-map), checked writable before any work."""
    wanted = {"diff": getattr(args, "output", None), "ssim": getattr(args, "ssim_map", None),
              "flip": getattr(args, "flip_map", None)}
    return {name: _check_output_file(path) for name, path in wanted.items() if path}


def _write_maps(result, targets: dict) -> list[Path]:
    """Write the difference heat map, SSIM map and FLIP map asked for; returns the paths."""
    from softras.scene.imageio import write_png_atomic
    from softras.verification.metrics import error_map_image

    pictures = {"diff": lambda: result.diff_image, "ssim": lambda: error_map_image(1.0 - result.ssim_map),
                "flip": lambda: error_map_image(result.flip_map)}
    for name, path in targets.items():
        write_png_atomic(path, pictures[name]())
    return list(targets.values())


def _tolerance(args: argparse.Namespace, base: dict) -> dict:
    """``base`` tolerance overridden by the options given on the command line."""
    tolerance = {key: base[key] for key in ("threshold", "max_bad_fraction", "min_ssim") if key in base}
    for key in ("threshold", "max_bad_fraction", "min_ssim"):
        value = getattr(args, key, None)
        if value is not None:
            tolerance[key] = value
    return tolerance


def _report(result, *, as_json: bool, header: list[str], extra: dict, outputs: list[Path]) -> int:
    """Print the comparison (human summary or JSON) and return the exit status."""
    if as_json:
        payload = result.to_dict()
        payload.update(extra)
        payload["outputs"] = [str(path) for path in outputs]
        print(json.dumps(payload, indent=2))
    else:
        for line in header:
            print(line)
        print(result.summary())
        if outputs:
            print("wrote " + ", ".join(str(path) for path in outputs))
    return EXIT_OK if result.passed else EXIT_FAILED


# ---------------------------------------------------------------------------
# Commands


def cmd_render(args: argparse.Namespace) -> int:
    """``softras render SCENE -o OUT.png``: render one scene with one backend."""
    from softras.scene.imageio import to_uint8, write_png_atomic

    if args.backend == "gl" and args.precision is not None:
        raise CLIError("--precision applies to --backend soft only")
    extra = {name: value for name, value in (("pattern", args.pattern), ("seed", args.seed),
                                             ("resolve_filter", args.filter)) if value is not None}
    if args.backend == "gl" and extra:
        raise CLIError("--pattern, --seed and --filter apply to --backend soft only")
    if args.framebuffer is not None:
        extra["framebuffer"] = args.framebuffer
    if args.texture_filter is not None:
        if args.backend == "gl":
            raise CLIError("--texture-filter applies to --backend soft only (GL has no ripmap, EWA or level-0 filter)")
        extra["texture_filter"] = args.texture_filter
    scene = _load_scene(args.scene)
    output = _check_output_file(args.output)
    try:
        image, seconds = _render(scene, args.backend, args.precision, args.samples, **extra)
    except ValueError as error:      # an option the renderer refuses (sample count, pattern, memory)
        raise CLIError(_one_line(error)) from None
    write_png_atomic(output, to_uint8(image))     # PNG is 8 bits: rgba32f is quantised
    height, width = image.shape[:2]
    note = " (rgba32f, 8 bits in the PNG)" if image.dtype.kind == "f" else ""
    print(f"{args.backend}: {width}x{height} in {seconds:.2f} s -> {output}{note}")
    return EXIT_OK


def _compare_scene(scene_path: str, args: argparse.Namespace, out_dir: str | None) -> int:
    """Render a scene with both backends and compare (compare SCENE, demo)."""
    from softras.scene.imageio import to_uint8, write_png_atomic

    scene = _load_scene(scene_path)
    targets = _map_outputs(args)
    folder = _check_output_dir(out_dir) if out_dir is not None else None

    # GL first: a missing OpenGL context is found before the slow soft render.
    gl, gl_seconds = _render(scene, "gl", None, args.samples)
    soft, soft_seconds = _render(scene, "soft", args.precision, args.samples)
    gl_name = _gl_description()
    from softras.verification.verifier import scene_tolerance

    result = _compare(soft, gl, _tolerance(args, scene_tolerance(scene)[0]))

    outputs: list[Path] = _write_maps(result, targets)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        for name, image in (("soft.png", soft), ("gl.png", gl), ("diff.png", result.diff_image)):
            write_png_atomic(folder / name, to_uint8(image))    # rgba32f renders: 8 bits in the PNG
            outputs.append(folder / name)

    height, width = soft.shape[:2]
    precision = args.precision or "gl"
    header = [
        f"scene {scene_path} ({width}x{height}): soft (precision {precision}) vs gl",
        f"soft {soft_seconds:.2f} s, gl {gl_seconds:.2f} s" + (f" ({gl_name})" if gl_name else ""),
    ]
    extra = {
        "scene": str(scene_path),
        "precision": precision,
        "soft_seconds": soft_seconds,
        "gl_seconds": gl_seconds,
        "gl_renderer": gl_name,
    }
    return _report(result, as_json=args.json, header=header, extra=extra, outputs=outputs)


def _compare_files(path_a: str, path_b: str, args: argparse.Namespace) -> int:
    """Compare two PNG files (compare A B)."""
    from softras.scene.imageio import read_png

    if args.out_dir is not None:
        raise CLIError("--out-dir applies to 'softras compare SCENE' only")
    if args.precision is not None or args.samples is not None:
        raise CLIError("--precision and --samples apply to 'softras compare SCENE' only")
    a = read_png(path_a)
    b = read_png(path_b)
    targets = _map_outputs(args)
    result = _compare(a, b, _tolerance(args, DEFAULT_TOLERANCE))
    outputs = _write_maps(result, targets)
    height, width = a.shape[:2]
    header = [f"{path_a} vs {path_b} ({width}x{height})"]
    extra = {"a": str(path_a), "b": str(path_b)}
    return _report(result, as_json=args.json, header=header, extra=extra, outputs=outputs)


def cmd_compare(args: argparse.Namespace) -> int:
    """``softras compare A B`` or ``softras compare SCENE``."""
    inputs = args.inputs
    if len(inputs) == 2:
        return _compare_files(inputs[0], inputs[1], args)
    if len(inputs) == 1:
        if inputs[0].lower().endswith(".png"):
            raise CLIError("compare needs two PNG files, or one scene file")
        return _compare_scene(inputs[0], args, args.out_dir)
    raise CLIError(f"compare takes two PNG files or one scene file, got {len(inputs)} arguments")


def cmd_demo(args: argparse.Namespace) -> int:
    """``softras demo``: render the demo scene with both backends and compare."""
    scene = Path(args.scene)
    if not scene.is_file():
        raise CLIError(f"{scene}: demo scene not found (pass --scene)")
    args.output = None
    return _compare_scene(str(scene), args, args.out_dir)


def _write_golden_failure(folder: Path, result) -> Path:
    """Write golden / gl / soft images and diff heat maps of a failed scene
    (`softras.verification.golden.failure_images`)."""
    from softras.scene.imageio import write_png_atomic
    from softras.verification.golden import failure_images

    target = folder / Path(result.golden).stem
    target.mkdir(parents=True, exist_ok=True)
    for name, image in failure_images(result).items():
        write_png_atomic(target / f"{name}.png", image)
    return target


def cmd_golden(args: argparse.Namespace) -> int:
    """``softras golden [--update] [PATH ...]``: verify or rewrite the golden images."""
    from softras.verification import golden

    start = time.perf_counter()
    if args.update and args.out_dir is not None:
        raise CLIError("--out-dir applies to verification only, not --update")
    if args.paths:
        from softras.scene import scene_files

        try:
            paths = [Path(path) for path in scene_files(args.paths)]
        except (OSError, ValueError) as error:
            raise CLIError(str(error)) from None
    else:
        paths = golden.default_scenes()
        if not paths:
            raise CLIError(f"no PATH given and no scene files in ./{golden.SCENES_DIR} "
                           f"({golden.SCENES_DIR.absolute()}): name scene files or folders")
    golden_dir = Path(args.golden_dir)
    out_dir = _check_output_dir(args.out_dir) if args.out_dir is not None else None

    def show(item) -> None:
        print(item.line(), flush=True)

    try:
        if args.update:
            changes = golden.update(paths, golden_dir, prune=not args.paths, on_change=show)
        else:
            results = golden.verify(paths, golden_dir, orphans=not args.paths,
                                    keep_images=out_dir is not None, on_result=show)
    except golden.GoldenError as error:
        raise CLIError(_one_line(error)) from None
    seconds = time.perf_counter() - start

    if args.update:
        counts = {status: sum(change.status == status for change in changes)
                  for status in ("added", "changed", "unchanged", "removed")}
        summary = ", ".join(f"{count} {status}" for status, count in counts.items())
        written = "" if counts["added"] + counts["changed"] + counts["removed"] else " (nothing written)"
        print(f"golden update {golden_dir}: {len(paths)} scene{'s' if len(paths) != 1 else ''}, "
              f"{summary}{written} in {seconds:.1f} s")
        return EXIT_OK

    failed = [result for result in results if not result.passed]
    if out_dir is not None and failed:
        written = [_write_golden_failure(out_dir, result) for result in failed if result.images]
        if written:
            print(f"wrote images of {len(written)} failed scene{'s' if len(written) != 1 else ''} under {out_dir}")
    print(f"golden verify {golden_dir}: {len(results)} checked, {len(results) - len(failed)} passed, "
          f"{len(failed)} failed in {seconds:.1f} s")
    return EXIT_FAILED if failed else EXIT_OK


# ---------------------------------------------------------------------------
# Parser


def _threshold(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer 0..255, got {text!r}") from None
    if not 0 <= value <= 255:
        raise argparse.ArgumentTypeError(f"expected an integer 0..255, got {text!r}")
    return value


def _fraction(low: float, high: float):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number in [{low:g}, {high:g}], got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a number in [{low:g}, {high:g}], got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


def _add_render_options(parser: argparse.ArgumentParser, *, backend: bool, sampling: bool = False) -> None:
    if sampling:
        # softras render: any sample count and pattern of softras.pipeline.sampling.
        parser.add_argument("--samples", type=int, default=None, metavar="N",
                            help="samples per pixel (default: the scene's); 1 or 4 with GL's pattern, "
                                 "up to 1024 with --pattern")
        parser.add_argument("--pattern", default=None,
                            choices=("gl", "grid", "rotated_grid", "jittered", "halton", "poisson"),
                            help="sample pattern (soft only; default gl: centre or llvmpipe's 4x); "
                                 "grid, rotated_grid and jittered take N*N samples")
        parser.add_argument("--seed", type=int, default=None, metavar="K",
                            help="seed of the jittered and poisson patterns (default 0)")
        parser.add_argument("--filter", choices=("box", "tent"), default=None,
                            help="resolve filter (soft only): box (default) or a 2-pixel tent")
        parser.add_argument("--framebuffer", choices=("rgba8", "rgba32f"), default=None,
                            help="colour buffer (default: the scene's); rgba32f is written to the "
                                 "PNG quantised to 8 bits")
    if backend:
        parser.add_argument("--backend", choices=("soft", "gl"), default="soft",
                            help="renderer: softras's pipeline or OpenGL through glref (default soft)")
    parser.add_argument("--precision", choices=("gl", "exact"), default=None,
                        help="softras precision: 'gl' reproduces OpenGL's snapping (default), "
                             "'exact' is float64 ground truth")
    if not sampling:
        # Both renderers take 1 or 4 (4x MSAA at llvmpipe's positions).
        parser.add_argument("--samples", type=int, choices=(1, 4), default=None, metavar="N",
                            help="samples per pixel, 1 or 4 (default: the scene's)")


def _add_output_options(parser: argparse.ArgumentParser, *, out_dir_default: str | None, out_dir_help: str) -> None:
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--out-dir", default=out_dir_default, metavar="DIR", help=out_dir_help)


def _add_tolerance_options(parser: argparse.ArgumentParser, defaults: str) -> None:
    group = parser.add_argument_group("tolerance", f"pass/fail thresholds (default: {defaults})")
    group.add_argument("--threshold", type=_threshold, default=None, metavar="N",
                       help="a pixel is bad when a channel differs by more than N/255 (default 2)")
    group.add_argument("--max-bad-fraction", type=_fraction(0.0, 1.0), default=None, metavar="F",
                       help="largest allowed fraction of bad pixels (default 0.001)")
    group.add_argument("--min-ssim", type=_fraction(-1.0, 1.0), default=None, metavar="S",
                       help="smallest allowed mean SSIM (default 0.99)")


def cmd_bench(args: argparse.Namespace) -> int:
    """``softras bench``: print speed and error figures (exit 0)."""
    from softras import bench

    if args.runs < 1 or args.max_triangles < 1000 or not 256 <= args.max_side <= 2048:
        raise CLIError("bench: need --runs >= 1, --max-triangles >= 1000, 256 <= --max-side <= 2048")
    for path in (args.json_path, args.plot_path):
        if path:
            from softras.scene.imageio import check_writable
            check_writable(path)
    description = _gl_description()
    if description is None:
        raise CLIError("OpenGL unavailable: bench measures softras against glref")
    print(f"glref: {description}")
    bench.run(runs=args.runs, full=args.full, max_triangles=args.max_triangles, max_side=args.max_side,
              out_json=args.json_path, out_plot=args.plot_path)
    return EXIT_OK


def _pixel(text: str) -> tuple[int, int]:
    """argparse type for ``--pixel X,Y`` (image coordinates, row 0 = top)."""
    from softras.verification.explain import parse_pixel

    try:
        return parse_pixel(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def cmd_explain(args: argparse.Namespace) -> int:
    """``softras explain SCENE --pixel X,Y``: one pixel's history, beside glref's value."""
    from softras.verification import explain
    from softras.renderer import render_scene

    scene = _load_scene(args.scene)
    x, y = args.pixel
    options = {"precision": args.precision or "gl", "samples": args.samples}
    try:
        explain.check_pixel(scene, x, y)
        history = explain.explain_pixel(scene, x, y, **options)
        rendered = render_scene(scene, **options)
    except ValueError as error:      # the pixel, or an option the renderer refuses
        raise CLIError(str(error)) from None
    value = rendered[y, x]
    rendered_value = [float(v) for v in value] if value.dtype.kind == "f" else [int(v) for v in value]
    import glref

    try:
        gl_value, gl_note = explain.gl_pixel(scene, x, y, samples=args.samples)
        gl = {"value": gl_value, "renderer": gl_note}
    except (glref.GLUnavailable, ModuleNotFoundError) as error:   # no context, or no moderngl
        gl_value, gl_note = None, f"OpenGL unavailable ({_one_line(error)})"
        gl = {"value": None, "unavailable": _one_line(error)}
    if args.json:
        history["softras_image"] = rendered_value
        history["gl"] = gl
        print(json.dumps(history, indent=2))
    else:
        print(explain.format_text(history, gl_value=gl_value, gl_note=gl_note, rendered=rendered_value))
    return EXIT_OK


def cmd_conformance(args: argparse.Namespace) -> int:
    """``softras conformance [PATH ...]``: every scene through both renderers, a verdict each.

    The scenes run in supervised worker processes (:mod:`softras.verification.runner`).
    Exit 0 when every scene passes, has a quality warning or is not
    supported by the GL (with --baseline: when the results match it), 1 when
    any fails, crashes or times out (with --baseline: a new failure or an
    unexpected verdict), 2 for bad input (a missing path, a bad scene, no
    scene matching -k, a bad --shard, -j, --timeout, --retries or
    --max-memory, an unwritable --report folder, a missing or malformed
    baseline, a --resume folder without a run or with other options) or no
    OpenGL -- found before anything is rendered or written -- and 130 when
    interrupted.
    """
    from datetime import datetime, timezone

    from softras.verification import conformance, golden, runner
    from softras.scene import SceneError, load_scene

    if args.merge is not None:
        return _merge_reports(args)
    if args.jobs < 1:
        raise CLIError(f"-j {args.jobs}: need at least 1 process")
    if args.timeout < 0 or not args.timeout == args.timeout:
        raise CLIError(f"--timeout {args.timeout}: must be >= 0 seconds (0 = no limit)")
    if args.retries < 0:
        raise CLIError(f"--retries {args.retries}: must be >= 0")
    try:
        paths = conformance.select(args.paths or [str(golden.SCENES_DIR)], patterns=args.patterns or (),
                                   shard_spec=args.shard)
    except conformance.ConformanceError as error:
        raise CLIError(_one_line(error)) from None
    for path in paths:  # bad scenes are bad input: exit 2 before any work
        try:
            load_scene(path)
        except SceneError as error:
            message = _one_line(error)
            raise CLIError(message if str(path) in message else f"{path}: {message}") from None
    if args.resume is not None and args.report is not None and \
            Path(args.report).resolve() != Path(args.resume).resolve():
        raise CLIError(f"--resume {args.resume} writes its report there: leave out --report {args.report}")
    report = _check_output_dir(args.report or args.resume) if (args.report or args.resume) else None
    try:
        max_memory = runner.parse_size(args.max_memory) if args.max_memory else runner.default_max_memory()
        baseline = runner.load_baseline(args.baseline) if args.baseline is not None else None
        options = runner.run_options(paths, profile=args.profile, timeout=args.timeout, retries=args.retries,
                                     max_memory=max_memory)
        done, previous = runner.load_resume(args.resume, paths, options) if args.resume else ({}, {})
    except runner.RunnerError as error:
        raise CLIError(_one_line(error)) from None
    try:
        import glref
    except ModuleNotFoundError as error:
        if error.name not in ("moderngl", "glcontext"):
            raise
        raise CLIError(f"OpenGL reference renderer unavailable: {_one_line(error)}") from None
    gl_name = _gl_description()
    if gl_name is None:
        try:
            glref.info()
        except glref.GLUnavailable as error:
            raise CLIError(f"OpenGL unavailable: {_one_line(error)}") from None
    try:
        import flip_evaluator  # noqa: F401 - FLIP is part of every scene's figures
    except ImportError:
        raise CLIError("FLIP needs the Python package flip-evaluator: pip install flip-evaluator") from None

    if previous and previous.get("gl_renderer") not in (None, gl_name):
        raise CLIError(f"--resume {args.resume}: that run rendered with {previous['gl_renderer']}, "
                       f"this one with {gl_name}")

    jobs = min(args.jobs, max(len(paths) - len(done), 1))
    shard_text = f", shard {args.shard}" if args.shard else ""
    capabilities = glref.info()
    from softras.verification.verifier import choose_profile

    profile_text = args.profile if args.profile != "auto" else f"auto: {choose_profile('auto', capabilities)}"
    resumed = f", {len(done)} done before (--resume)" if args.resume else ""
    limit = f"{args.timeout:g} s" if args.timeout else "none"
    print(f"conformance: {len(paths)} scene{'s' if len(paths) != 1 else ''}{shard_text}{resumed}, "
          f"{jobs} worker process{'es' if jobs != 1 else ''}, profile {profile_text}, timeout {limit}, "
          f"GL: {gl_name}", flush=True)
    meta = {"jobs": jobs, "gl_renderer": gl_name, "profile": profile_text, "gl": capabilities,
            "shard": args.shard, "patterns": args.patterns or [], "paths": [str(path) for path in paths],
            "date": datetime.now(timezone.utc).isoformat(timespec="seconds"), "options": options}
    again = " ".join(["softras conformance", *(args.paths or []), *(f"-k {p}" for p in args.patterns or []),
                      *([f"--shard {args.shard}"] if args.shard else []), f"--resume {report}"])
    try:
        return runner.conformance_command(
            paths, jobs=jobs, profile=args.profile, profile_text=profile_text, timeout=args.timeout,
            retries=args.retries, max_memory=max_memory, meta=meta, report=report, done=done,
            seconds_before=float(previous.get("summary", {}).get("seconds") or 0.0), baseline=baseline,
            resume_hint=f"resume with: {again} (and the same options)")
    except runner.RunnerError as error:
        raise CLIError(_one_line(error)) from None


def _merge_reports(args: argparse.Namespace) -> int:
    """``softras conformance --merge DIR... --report OUT``: the shards' reports as one (no GL needed).

    Exit as a run with the merged verdicts (and ``--baseline``); 2 when the
    folders are not the complete shards of one run
    (:mod:`softras.verification.merge`), with nothing written.
    """
    from softras.verification import merge, runner

    parser = args.conformance_parser              # (its defaults: an option left alone is not "given")
    given = (["PATH"] if args.paths else []) + [
        flag for flag, dest in (("-k", "patterns"), ("--shard", "shard"), ("--resume", "resume"), ("-j", "jobs"),
                                ("--timeout", "timeout"), ("--retries", "retries"),
                                ("--max-memory", "max_memory"), ("--profile", "profile"))
        if getattr(args, dest) != parser.get_default(dest)]
    if given:
        raise CLIError(f"--merge combines finished reports: it takes only --report and --baseline, not "
                       f"{', '.join(given)}")
    if args.report is None:
        raise CLIError("--merge needs --report OUT, the folder of the merged report")
    report = _check_output_dir(args.report)
    try:
        baseline = runner.load_baseline(args.baseline) if args.baseline is not None else None
        merged = merge.merge(args.merge, report, baseline=baseline)
    except (runner.RunnerError, merge.MergeError) as error:
        raise CLIError(_one_line(error)) from None
    return merge.print_merged(merged, sys.stdout)


def _import_glref():
    """glref, with a missing moderngl turned into CLIError."""
    try:
        import glref
    except ModuleNotFoundError as error:
        if error.name not in ("moderngl", "glcontext"):
            raise
        raise CLIError(f"OpenGL reference renderer unavailable: {_one_line(error)}") from None
    return glref


def cmd_info(args: argparse.Namespace) -> int:
    """``softras info``: the GL glref renders with and its capability record (exit 2 without GL)."""
    glref = _import_glref()
    try:
        info = glref.info()
    except glref.GLUnavailable as error:
        raise CLIError(f"OpenGL unavailable: {_one_line(error)}") from None
    from softras.verification.verifier import choose_profile

    info = info | {"profile_auto": choose_profile("auto", info)}
    if args.json:
        print(json.dumps(info, indent=2))
        return EXIT_OK
    for key, value in info.items():
        if key == "sample_positions":
            for count, places in value.items():
                print(f"{'sample positions ' + count:<28} "
                      + " ".join(f"({x:g}, {y:g})" for x, y in places))
        elif isinstance(value, dict):
            print(f"{key:<28} " + ", ".join(f"{k}={v}" for k, v in value.items()))
        else:
            print(f"{key:<28} {value}")
    return EXIT_OK


def _read_picture(path: str, name: str):
    """A PNG or .npy picture for verify, bad input as CLIError."""
    from softras.scene.imageio import read_png

    if path.endswith(".npy"):
        try:
            import numpy as np

            return np.load(path, allow_pickle=False)
        except (OSError, ValueError) as error:
            raise CLIError(f"{path}: cannot read the {name}: {_one_line(error)}") from None
    return read_png(path)


def cmd_verify(args: argparse.Namespace) -> int:
    """``softras verify SCENE IMAGE REFERENCE``: judge a picture against GL's (exit 0 pass/warning, 1 fail)."""
    from softras.verification import verifier
    from softras.scene.imageio import write_png_atomic

    scene = _load_scene(args.scene)
    image = _read_picture(args.image, "image")
    reference = _read_picture(args.reference, "reference")
    folder = _check_output_dir(args.out_dir) if args.out_dir is not None else None
    capabilities = None
    if args.capabilities is not None:
        try:
            data = json.loads(Path(args.capabilities).read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise CLIError(f"{args.capabilities}: not a capability record: {_one_line(error)}") from None
        capabilities = data.get("gl", data) if isinstance(data, dict) else None
        if not isinstance(capabilities, dict) or "GL_RENDERER" not in capabilities:
            raise CLIError(f"{args.capabilities}: not a capability record (softras info --json, "
                           "or a conformance results.json)")
    elif args.profile != "strict":
        glref = _import_glref()
        try:
            capabilities = glref.info()
        except glref.GLUnavailable:
            capabilities = None     # the spec's minimum sub-pixel precision
    try:
        result = verifier.verify(scene, image, reference, profile=args.profile, capabilities=capabilities)
    except ValueError as error:
        raise CLIError(_one_line(error)) from None
    outputs = []
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        for name, picture in result.images.items():
            write_png_atomic(folder / f"{name}.png", picture)
            outputs.append(str(folder / f"{name}.png"))
    if args.json:
        print(json.dumps(result.to_dict() | {"outputs": outputs}, indent=2))
    else:
        print(f"{verifier.VERDICT_NAMES[result.verdict]} ({result.profile} profile): {args.scene}")
        for reason in result.reasons:
            print(f"  {reason}")
        for path in outputs:
            print(f"  wrote {path}")
    return EXIT_OK if result.passed else EXIT_FAILED


def _device(text: str) -> str:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"not a device index (0, 1, ...): {text!r}")
    return str(value)


def _version() -> str:
    """The installed distribution's version (pyproject.toml's, for a source checkout)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("softras")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """Build the ``softras`` argument parser.

    Returns
    -------
    argparse.ArgumentParser
        The parser; each subcommand stores its handler in ``func``.
    """
    parser = _Parser(
        prog="softras",
        description="A reference software rasterizer, cross-checked image by image against OpenGL.",
        epilog="Exit status: 0 success or pass, 1 comparison failed, 2 bad input or environment error.",
    )
    parser.add_argument("--version", action="version", version=f"softras {_version()}")
    parser.add_argument("--gl-device", type=_device, default=None, metavar="N",
                        help="glref renders on the N-th EGL device (machines with several GPUs); "
                             "Mesa's driver is chosen with GALLIUM_DRIVER (llvmpipe, softpipe, zink)")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    render = commands.add_parser("render", help="render a scene to a PNG file",
                                 description="Render a scene file to a PNG image (RGBA, row 0 = top).")
    render.add_argument("scene", metavar="SCENE", help="scene file (JSON, format version 1)")
    render.add_argument("-o", "--output", required=True, metavar="OUT.png", help="the PNG file to write")
    _add_render_options(render, backend=True, sampling=True)
    render.add_argument("--texture-filter", choices=TEXTURE_FILTERS, default=None,
                        help="soft only: filter every texture with a ripmap, EWA (Heckbert) or level 0's "
                             "bilinear instead of its min filter (softras.pipeline.texture_beyond)")
    render.set_defaults(func=cmd_render)

    compare = commands.add_parser(
        "compare", help="compare two PNG files, or a scene's soft and gl renderings",
        usage="softras compare (A.png B.png | SCENE) [-o DIFF.png] [--ssim-map SSIM.png]\n"
              "                       [--flip-map FLIP.png] [--json] [--out-dir DIR]\n"
              "                       [--precision {gl,exact}] [--samples N] [--threshold N]\n"
              "                       [--max-bad-fraction F] [--min-ssim S]",
        description="Compare two PNG files (A B; B is the reference), or render one scene file with "
                    "both backends and compare the images with the scene's tolerance. Prints the largest "
                    "difference, the fraction of bad pixels, the mean SSIM and the mean FLIP error "
                    "(flip-evaluator). Exit 0 on pass, 1 on fail, 2 on missing or unreadable input "
                    "(nothing written).",
    )
    compare.add_argument("inputs", nargs="+", metavar="INPUT",
                         help="two PNG files, or one scene file")
    compare.add_argument("-o", "--output", metavar="DIFF.png",
                         help="write the difference heat map to this PNG file")
    compare.add_argument("--ssim-map", metavar="SSIM.png",
                         help="write the SSIM map (1 - local SSIM; black = same structure) to this PNG file")
    compare.add_argument("--flip-map", metavar="FLIP.png",
                         help="write the FLIP error map (black = no visible difference) to this PNG file")
    _add_output_options(compare, out_dir_default=None,
                        out_dir_help="SCENE only: write soft.png, gl.png and diff.png into DIR")
    _add_render_options(compare, backend=False)
    _add_tolerance_options(compare, "the scene's tolerance for SCENE, else the values below")
    compare.set_defaults(func=cmd_compare)

    demo = commands.add_parser(
        "demo", help="render the demo scene with both backends and compare",
        description="Render the demo scene with softras and OpenGL, compare the two images, and "
                    "write soft.png, gl.png and diff.png into DIR.",
    )
    demo.add_argument("--scene", default=str(DEFAULT_DEMO_SCENE), metavar="SCENE",
                      help=f"scene file to use (default {DEFAULT_DEMO_SCENE})")
    _add_output_options(demo, out_dir_default="out", out_dir_help="output folder (default ./out)")
    _add_render_options(demo, backend=False)
    _add_tolerance_options(demo, "the scene's tolerance")
    demo.set_defaults(func=cmd_demo)

    golden = commands.add_parser(
        "golden", help="verify the golden images (or rewrite them with --update)",
        description="Verify the golden images of the scenes: each golden PNG must match the hash in "
                    "manifest.json, glref must reproduce it exactly (same OpenGL; other OpenGL: the "
                    "scene's tolerance), and softras must match it within the scene's tolerance. "
                    "Exit 0 when all pass, 1 when any fails. With --update, render the scenes with "
                    "glref and replace the golden images, all or nothing.",
    )
    golden.add_argument("paths", nargs="*", metavar="PATH",
                        help="scene files or folders of them (default: all of ./scenes of the current "
                             "directory; a full --update also removes golden images whose scene is gone)")
    golden.add_argument("--update", action="store_true",
                        help="render the scenes with glref and rewrite their golden images and manifest")
    golden.add_argument("--golden-dir", default=str(DEFAULT_GOLDEN_DIR), metavar="DIR",
                        help=f"golden image folder (default ./{DEFAULT_GOLDEN_DIR} of the current directory)")
    golden.add_argument("--out-dir", default=None, metavar="DIR",
                        help="verification: write golden, gl, soft and diff images of failed scenes "
                             "into DIR/<scene>/")
    golden.set_defaults(func=cmd_golden)

    conformance = commands.add_parser(
        "conformance", help="run every scene through both renderers: pass, quality warning or fail",
        description="Render each scene with softras and OpenGL and judge it with the scene's tolerance "
                    "(else defaults for its features): PASS within tolerance on every pixel, QUALITY "
                    "WARNING when only pixels of the ambiguity mask (answers that depend on implementation "
                    "choices) break it, FAIL otherwise, with the stage that disagrees. Each scene is checked "
                    "in a worker process: one that dies gives its scene CRASH, one over --timeout TIMEOUT, "
                    "and the run goes on. Exit 0 when nothing fails (with --baseline: the results match "
                    "it), 1 when a scene fails, crashes or times out (with --baseline: a new failure or "
                    "unexpected verdict), 2 on bad input or no OpenGL, 130 when interrupted (the report of "
                    "what finished is written; --resume finishes it).",
    )
    conformance.add_argument("paths", nargs="*", metavar="PATH",
                             help="scene files or folders of them (default: all of ./scenes of the current "
                                  "directory)")
    conformance.add_argument("--profile", choices=("auto", "strict", "spec"), default="auto",
                             help="strict: the scene's tolerance, bit-exact where softras reproduces the "
                                  "GL (llvmpipe 22.3); spec: per-pixel bounds of what any conformant GL "
                                  "may draw; auto (default): strict on the GL softras reproduces, else spec")
    conformance.add_argument("--report", default=None, metavar="DIR",
                             help="write index.html, results.json, junit.xml and per-scene pictures into DIR")
    conformance.add_argument("-k", dest="patterns", action="append", default=None, metavar="PATTERN",
                             help="only scenes whose name contains PATTERN, or matches it as a glob "
                                  "(*, ?, [..]); repeat for several")
    conformance.add_argument("--shard", default=None, metavar="I/N",
                             help="only shard I of N (1-based; round robin over the sorted names)")
    conformance.add_argument("-j", "--jobs", type=int, default=1, metavar="N",
                             help="worker processes (each with its own GL context; default 1)")
    conformance.add_argument("--timeout", type=float, default=300.0, metavar="SECONDS",
                             help="per-scene time limit: the scene gets TIMEOUT and its worker is killed "
                                  "(default 300; 0 = none; numba's one-time kernel compilation does not count)")
    conformance.add_argument("--retries", type=int, default=0, metavar="K",
                             help="re-run a scene that gets CRASH, TIMEOUT or FAIL up to K times; one whose "
                                  "verdict changes between attempts is FLAKY (default 0)")
    conformance.add_argument("--baseline", default=None, metavar="FILE",
                             help="expected non-passing scenes of this GL, 'scene,VERDICT' per line (a report's "
                                  "failures.csv is one): exit 0 when the results match, 1 on a new failure or "
                                  "an unexpected verdict")
    conformance.add_argument("--resume", default=None, metavar="DIR",
                             help="finish the interrupted run whose report is in DIR (same paths and options), "
                                  "without checking its finished scenes again")
    conformance.add_argument("--merge", nargs="+", default=None, metavar="DIR",
                             help="merge the reports of the shards of one run (--shard I/N, all N of them, "
                                  "same GL) into the --report folder, pictures included; no scene is run "
                                  "(exit as the merged verdicts)")
    conformance.add_argument("--max-memory", default=None, metavar="SIZE",
                             help="memory budget, e.g. 8G or 50%%: a scene whose estimated need (plus its "
                                  "worker's) is over it is NOT SUPPORTED, refused up front (default 50%% of "
                                  "this machine's memory)")
    conformance.set_defaults(func=cmd_conformance, conformance_parser=conformance)

    bench = commands.add_parser(
        "bench", help="measure softras's quality levels against glref (time, ratio, error)",
        description="Render generated benchmark scenes with glref and with each softras quality level "
                    "in one process, warm, and print median times, ratios to glref, throughput and "
                    "error against one filter-independent truth (exact precision, bilinear level-0 "
                    "texels, dense supersampling), peak memory, plus how cost grows.",
    )
    bench.add_argument("--runs", type=int, default=3,
                       help="timed (softras, glref) pairs per figure, at least (medians; default 3)")
    size = bench.add_mutually_exclusive_group()
    size.add_argument("--quick", dest="full", action="store_false", default=False,
                      help="the default subset: 512^2 scenes, sweeps to 100k triangles and 1024^2 (minutes)")
    size.add_argument("--full", dest="full", action="store_true",
                      help="every scene and level: sweeps to 1M triangles and 2048^2")
    bench.add_argument("--max-triangles", type=int, default=1_000_000,
                       help="cap of the triangle sweep (default 1000000)")
    bench.add_argument("--max-side", type=int, default=2048,
                       help="cap of the image-side sweep (default 2048)")
    bench.add_argument("--json", dest="json_path", default=None, metavar="OUT.json",
                       help="also write the figures as JSON")
    bench.add_argument("--plot", dest="plot_path", default=None, metavar="OUT.png",
                       help="also write a PNG plot of time (relative to glref) against error")
    bench.set_defaults(func=cmd_bench)

    explain = commands.add_parser(
        "explain", help="the history of one pixel through every stage, beside glref's value",
        description="Explain one pixel: every draw and triangle (or line) that reached it, its "
                    "window-space vertices, edge functions and coverage per sample (fill rule on "
                    "ties), barycentrics, depth test, texture lookups, shading terms, blending per "
                    "sample and the resolved value, beside softras's rendered value and glref's.",
    )
    explain.add_argument("scene", metavar="SCENE", help="scene file (JSON, format version 1)")
    explain.add_argument("--pixel", required=True, type=_pixel, metavar="X,Y",
                         help="the pixel in image coordinates: column X from the left, row Y from "
                              "the top, as the PNG is seen (GL window y = height - 1 - Y)")
    explain.add_argument("--precision", choices=("gl", "exact"), default=None,
                         help="softras precision (default gl)")
    explain.add_argument("--samples", type=int, default=None, metavar="N",
                         help="samples per pixel (default: the scene's)")
    explain.add_argument("--json", action="store_true", help="print the history as JSON")
    explain.set_defaults(func=cmd_explain)

    verify = commands.add_parser(
        "verify", help="judge a picture of a scene against GL's: could a conformant GL draw it?",
        description="Judge IMAGE (softras's or any renderer's picture of SCENE) against REFERENCE (GL's), "
                    "both PNG (RGBA, row 0 = top) or .npy (uint8 or float32, (H, W, 4)). spec (default): "
                    "both must lie within the per-pixel bounds of what the GL specification lets a "
                    "conformant implementation draw; strict: the scene's tolerance. Exit 0 on PASS or "
                    "QUALITY WARNING, 1 on FAIL, 2 on bad input.",
    )
    verify.add_argument("scene", metavar="SCENE", help="scene file")
    verify.add_argument("image", metavar="IMAGE", help="the picture under test (PNG or .npy)")
    verify.add_argument("reference", metavar="REFERENCE", help="GL's picture (PNG or .npy)")
    verify.add_argument("--profile", choices=("spec", "strict", "auto"), default="spec",
                        help="verification profile (default spec)")
    verify.add_argument("--capabilities", default=None, metavar="FILE.json",
                        help="the reference GL's capability record (softras info --json, or a "
                             "conformance results.json); default: this machine's GL, else the spec's minimums")
    _add_output_options(verify, out_dir_default=None,
                        out_dir_help="write the bound images (bound_lo, bound_hi), diff and where into DIR")
    verify.set_defaults(func=cmd_verify)

    info = commands.add_parser(
        "info", help="the OpenGL glref renders with, and its capability record",
        description="Print the GL implementation glref uses (renderer, version, driver environment) and "
                    "its capability record: GL_SUBPIXEL_BITS, sample counts and positions, anisotropy, "
                    "size limits, and the profile 'auto' picks. Exit 2 without OpenGL.",
    )
    info.add_argument("--json", action="store_true", help="print the record as JSON")
    info.set_defaults(func=cmd_info)
    return parser


COMPILE_NOTICE = ("softras: compiling the rendering kernels for this machine (the first run only: "
                  "numba keeps them in its cache; this can take a few minutes)...")
_compile_notice_installed = False


def announce_compilation(stream=None, *, only_on_terminal: bool = True) -> None:
    """Say once per process, on ``stream`` (default stderr), that kernels are
    being compiled, so the first run on a machine does not sit silent:
    `softras.kernels.prepare.NOTICE` when a render leaves the compiled
    kernels to a background process, else `COMPILE_NOTICE` the first time
    numba compiles a kernel in this process -- a cache miss: a fresh clone,
    an edited kernel, a new numba (numba's ``numba:compile`` event, which
    numba triggers only when it compiles, not when it loads).  A run that
    loads every kernel from the cache prints nothing.  With
    ``only_on_terminal`` it prints only when the stream is a terminal, so
    captured output (tests, pipes, CI logs parsed by tools) is never
    changed."""
    global _compile_notice_installed
    if _compile_notice_installed:
        return
    from numba.core import event

    from softras.kernels import prepare

    said = []

    def say(text):
        out = stream if stream is not None else sys.stderr
        if not said and (not only_on_terminal or out.isatty()):
            print(text, file=out, flush=True)
        said.append(text)

    class _Notice(event.Listener):
        def on_start(self, ev):
            say(COMPILE_NOTICE)

        def on_end(self, ev):
            pass

    event.register("numba:compile", _Notice())
    prepare.announce = say
    _compile_notice_installed = True


def _without_numba_blas() -> None:
    """Load numba's array implementations now, telling them there is no BLAS.

    A process's first compiled call (a cache load included) imports
    numba.np.arraymath, whose probe for a BLAS (for ``np.dot`` and
    ``np.linalg`` in compiled code) imports scipy.linalg: 0.3 s of a 1.7 s
    first render in a new process.  softras's kernels call no BLAS (they
    must not: its threads fight numba's for the cores, docs/speed.md), and
    this process runs no one else's compiled code, so the probe may fail:
    ``scipy.linalg`` is hidden while numba looks.  A process that imported
    either already is left alone, and so is one that uses softras as a
    library (this is the command line's)."""
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return
    sys.modules["scipy.linalg"] = None          # (an import of it raises ImportError)
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules["scipy.linalg"]


def main(argv: list[str] | None = None) -> int:
    """Run the ``softras`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status: 0 success or pass, 1 comparison failed, 2 bad input or
        environment error (one line on stderr).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # argparse: --help (0) or a usage error (2)
        return exit_.code if isinstance(exit_.code, int) else EXIT_ERROR
    if getattr(args, "func", None) is None:
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    if args.gl_device is not None:
        os.environ["SOFTRAS_GL_DEVICE"] = args.gl_device   # glref.DEVICE_ENV; workers inherit it

    from softras.scene.imageio import ImageError

    # The commands that run compiled code in this process (not conformance:
    # its workers, processes of their own, render; without numba its
    # supervisor took 0.30 s of CPU instead of 0.47, docs/speed.md).
    if args.func not in (cmd_compare, cmd_info, cmd_conformance):
        announce_compilation()
        _without_numba_blas()
    try:
        return args.func(args)
    except (CLIError, ImageError) as error:
        message = _one_line(error)
    except OSError as error:
        # Environment failures on files and folders (e.g. creating --out-dir).
        where = f"{error.filename}: " if error.filename else ""
        message = f"{where}{error.strerror or _one_line(error)}"
    print(f"softras: error: {message}", file=sys.stderr)
    return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
