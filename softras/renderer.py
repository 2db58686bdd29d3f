"""Which renderer draws a scene: the compiled kernels, the readable stages, or GL.

`render_scene` is softras's renderer: a gl-precision scene (RGBA8 or
rgba32f, any sample count and pattern) that uses only what `softras.kernels`
implements is drawn by their fused per-draw kernel, everything else by the
readable stages of `softras.pipeline`; the two give the same bytes
(tests/test_fastpath.py, tests/test_rgba32f_path.py).  In exact precision,
triangle draws take the exact kernel (`softras.kernels.exact`), line draws
`softras.kernels.exact_lines`, and the draws they leave out (textured or
mapped draws with ``texture_bounds``) the stages, into the same buffers
(tests/test_exact_path.py).  Kernels not compiled yet are compiled by a
background process while the stages draw (`softras.kernels.prepare`).
`render` adds the choice of backend ("soft" or "gl", i.e. glref) behind
`softras.render`.
"""

from __future__ import annotations

import numpy as np

from softras.kernels import draw as kernels
from softras.kernels import exact, prepare, rgba32f
from softras.pipeline import render as stages
from softras.scene import Scene, load_scene


def render_scene(scene: Scene, *, precision: str = "gl", samples: int | None = None,
                 pattern: str | None = None, seed: int = 0, resolve_filter: str = "box",
                 framebuffer: str | None = None, clipping: str | None = None,
                 texture_fixed_point: bool = True, fast_path: bool = True,
                 texture_filter=None, texture_bounds: str | None = None,
                 tie_rule: str = "left_bottom") -> np.ndarray:
    """Render a loaded scene; returns the picture (H, W, 4), row 0 = top.

    The options are `softras.pipeline.render.render_stages`' (precision,
    samples, pattern, seed, resolve_filter, framebuffer, clipping,
    texture_fixed_point, texture_filter, texture_bounds, tie_rule), plus
    fast_path : let `softras.kernels` render the scenes and draws they
    support (the same bytes, from one fused kernel per draw; in exact
    precision `softras.kernels.exact`); False: always the stages.
    While the kernels a scene needs are not compiled yet, the stages draw
    it and a background process compiles them, or they are compiled first
    with ``SOFTRAS_COMPILE=wait`` (`softras.kernels.prepare`).
    """
    job = stages.Job.of(scene, precision=precision, samples=samples, pattern=pattern, seed=seed,
                        resolve_filter=resolve_filter, framebuffer=framebuffer, clipping=clipping,
                        texture_fixed_point=texture_fixed_point, texture_filter=texture_filter,
                        texture_bounds=texture_bounds, tie_rule=tie_rule)
    if job.precision == "exact" and fast_path:
        # The exact kernels' memory is the stages' (the same float64 sample
        # buffers): until they are compiled, the stages draw the scene.
        if prepare.ensure([prepare.EXACT]):
            return exact.resolve(job, exact.render_samples(scene, job, reuse=True))
        return stages.resolve(job, stages.render_samples(scene, job))
    # A gl-precision scene that uses only what the kernels implement gets
    # the same bytes from their fused kernel (tests/test_fastpath.py).  A new
    # option must either send scenes that use it past this test or be
    # implemented there.
    fast = (fast_path and texture_bounds is None and tie_rule == "left_bottom"
            and kernels.unsupported(scene, precision=precision, clipping=clipping) is None)
    if fast:
        # Unless the kernels are ready (or compiled now), a background process
        # compiles them and the stages draw this scene (`softras.kernels.prepare`).
        try:
            stages.check_sample_memory(scene, len(job.positions), stages.SAMPLE_BYTES)
            stages_can_draw = True
        except ValueError:
            stages_can_draw = False
        fast = prepare.ensure(prepare.variants(scene, len(job.positions)), stages_can_draw)
    if not fast:
        return stages.resolve(job, stages.render_samples(scene, job))
    if job.rgba8 and len(job.positions) == 1 and job.resolve_filter == "box":    # (a sample's bytes its pixel's)
        return kernels.render_picture(scene, job.positions, texture_fixed_point=texture_fixed_point,
                                      texture_filter=texture_filter)
    stored = kernels.render_samples(scene, job.positions, texture_fixed_point=texture_fixed_point,
                                    reuse=True, texture_filter=texture_filter,
                                    rgba8=job.rgba8)           # (the resolve copies it)
    return stages.resolve_bytes(job, stored) if job.rgba8 else rgba32f.resolve(job, stored)


def render(scene, backend: str = "soft", **options) -> np.ndarray:
    """Render a scene (a Scene, a dict or a path) with softras or glref.

    backend : "soft" (`render_scene`, with its options) or "gl" (glref;
    options ``samples``, ``framebuffer``; any other option, e.g. the
    softras-only ``texture_filter``, is a ValueError, and a sample count the
    GL does not render exactly is `glref.NotSupported`).
    Returns (H, W, 4) premultiplied RGBA, row 0 = top of the picture: uint8
    for an "rgba8" framebuffer (the default), float32 for "rgba32f"
    (``framebuffer`` option or the scene's top-level "framebuffer" key).
    """
    scene = load_scene(scene)
    if backend == "soft":
        return render_scene(scene, **options)
    if backend == "gl":
        import glref
        unknown = {name for name, value in options.items()
                   if name not in ("samples", "framebuffer") and value is not None}
        if unknown:
            raise ValueError(f"backend 'gl' does not take {', '.join(sorted(unknown))} (softras-only options)")
        options = {name: value for name, value in options.items() if value is not None}
        return glref.render(scene, **options)
    raise ValueError(f"backend must be 'soft' or 'gl', not {backend!r}")
