"""Planted bugs in softras's own code: does the default test suite catch each one?

A curated list of mutations (:data:`MUTATIONS`), each a named, exact source
edit -- file, old text, new text -- of one thing a renderer can get wrong:
the fill rule, snapping, the viewport's fused multiply-add, clipping order
and policy, perspective division, level of detail, wrapping, filter weights,
mip generation, depth rounding and functions, blend equations and rounding,
the MSAA resolve, lines' end pixels, the fast path's parallel set-up, binning
and buffer reuse, the scene model both renderers share, and glref's GL state
(blend, cull, depth, sampler) and shaders. Where softras computes a thing
twice (the readable stages and the compiled fast path) each copy has its own
mutation: a bug in one copy must be caught by the equality tests between
them or by a GL test. A bug in code both of softras's renderers run (the
scene model, the mip chain, a kernel the fast path imports from the stages;
``where="shared"``) is invisible to those equality tests by design: for it
the harness also runs the GL-facing tests alone (``pytest -m gl``) and counts
the mutation caught only when one of them fails too.

For each mutation the repository is copied to a work folder (``.git``
excluded; ``__pycache__`` included, so numba's compiled kernels stay warm),
the edit is applied there -- the old text must occur exactly as often as the
mutation says, else the harness stops: the list cannot rot silently -- and
the default test suite (the README's ``python -m pytest -q``) runs against
the copy (``PYTHONPATH`` and the working directory are the copy). A mutation
is *caught* when a test fails. The harness records the failing tests
(``-rfE``; the suite stops after ``--maxfail`` of them), the outcome and the
time. A timeout counts as not caught.

numba's on-disk cache does not know which kernels a kernel inlined: the
harness works out from the source which compiled kernels a mutation reaches
and recompiles exactly those in the copy (see "numba's cache" below); a work
folder is kept per mutation, so a second run of the harness finds them warm.
The first run of a mutation that reaches the fast path's tile kernels pays
their compilation (about 10 minutes on 2 busy cores); the others take about
as long as the suite. Run the suite once in the repository first, so that
its own caches are warm.

glref's shaders are the package ``glref.shaders`` (the repository's
``shaders/`` folder, mapped by the package metadata); in the copy
``glref/shaders`` is a link to the copy's ``shaders/``, so an installed
(editable) softras does not hand the tests the original shaders.

    python scripts/mutate.py                 # every mutation, the full default suite (the score)
    python scripts/mutate.py --quick         # each mutation against its declared test files only
    python scripts/mutate.py --only fill_rule_top_edges,depth_round_floor
    python scripts/mutate.py --list          # the mutations (and a check that every edit applies)
    python scripts/mutate.py --json results.json --markdown table.md

Options: ``--maxfail N`` (default 3: enough failing tests to name, without
running the whole suite for a mutation caught early), ``--timeout S`` per
suite run (default 1500 s), ``--jobs N`` mutations at once (default 1: the
suite is CPU bound), ``--workdir DIR`` (default: a folder under the system's
temporary directory, kept between runs), ``--no-baseline`` (skip the run of
the unmutated copy that checks the copy passes first), ``--no-gl-check``.
Prints a Markdown table; exit status 0 when every mutation is caught, 1 when
one is not, 2 when the harness cannot run (an edit that does not apply, a
baseline that fails).
"""

from __future__ import annotations

import argparse
import ast
import concurrent.futures
import hashlib
import json
import os
import pickle
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: Folders never copied (version control, caches of other tools, outputs).
SKIP_DIRS = {".git", ".pytest_cache", ".hypothesis", ".venv", "venv", "build", "dist", "out",
             ".mutants", "node_modules"}
#: The suite's command (the README's ``python -m pytest -q``), without the cache plugin
#: (no .pytest_cache written into the copy).
PYTEST = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rfE"]
#: numba's cache files: ``<module>.<function>-<line>.py311.nbi`` / ``...nbc``.
NUMBA_CACHE_SUFFIXES = (".nbi", ".nbc")


class HarnessError(RuntimeError):
    """The harness cannot run as asked (an edit that does not apply, a failing baseline)."""


@dataclass(frozen=True)
class Edit:
    """Replace ``old`` by ``new`` in ``path`` (relative to the repository);
    ``old`` must occur exactly ``count`` times (all are replaced)."""

    path: str
    old: str
    new: str
    count: int = 1


@dataclass(frozen=True)
class Mutation:
    """One planted bug.

    name : identifier (``--only``); stage : the pipeline stage or component;
    where : which code it lives in -- "stages" (the readable pipeline only),
    "fast path" (softras.kernels only), "shared" (code both of softras's
    renderers, or softras and glref, run: no equality test between them can
    see it, a test must ask GL or a hand-computed value), "glref" (the GL
    side); what : one line, what the bug does; edits : the source edits;
    quick : the test files (or node ids) most likely to catch it (``--quick``).
    """

    name: str
    stage: str
    where: str
    what: str
    edits: tuple[Edit, ...]
    quick: tuple[str, ...]


def _m(name, stage, where, what, edits, quick):
    if isinstance(edits, Edit):
        edits = (edits,)
    return Mutation(name, stage, where, what, tuple(edits), tuple(quick))


E = Edit
FAST = "tests/test_fastpath.py"
FAST_TILES = FAST + "::test_tiles_cleared_where_first_drawn_give_the_stages_bytes"
MUTATIONS: tuple[Mutation, ...] = (
    # ----------------------------------------------------------------- vertex
    _m("vertex_sum_order", "vertex", "shared",
       "u_mvp * p summed right to left in float32 (GLSL's order is column 0 first)",
       E("softras/pipeline/vertex.py", "out[v, r] = np.float64(((m[r, 0] * x + m[r, 1] * y) + m[r, 2] * z) + m[r, 3])",
         "out[v, r] = np.float64(m[r, 0] * x + (m[r, 1] * y + (m[r, 2] * z + m[r, 3])))"),
       ("tests/stages/test_vertex.py", "tests/test_random_triangles.py", "tests/test_mutations_caught.py")),
    # ------------------------------------------------------------------- clip
    _m("clip_near_first", "clip", "shared",
       "clip against near before right/left/top/bottom (llvmpipe clips x, y first, then near, far)",
       E("softras/pipeline/clip.py",
         "    [-1, 0, 0, 1],   # right   x <= w\n    [1, 0, 0, 1],    # left   -w <= x\n"
         "    [0, -1, 0, 1],   # top     y <= w\n    [0, 1, 0, 1],    # bottom -w <= y\n"
         "    [0, 0, 1, 1],    # near   -w <= z\n",
         "    [0, 0, 1, 1],    # near   -w <= z\n"
         "    [-1, 0, 0, 1],   # right   x <= w\n    [1, 0, 0, 1],    # left   -w <= x\n"
         "    [0, -1, 0, 1],   # top     y <= w\n    [0, 1, 0, 1],    # bottom -w <= y\n"),
       ("tests/stages/test_clip.py", "tests/test_extremes.py", "tests/test_mutations_caught.py")),
    _m("clip_from_outside_end", "clip", "shared",
       "the compiled clipper interpolates from the outside end, not from the end nearer the plane",
       E("softras/pipeline/clip.py", "if not -d[out_i] < d[in_i]:                         # start from the nearer end",
         "if False:                         # start from the nearer end"),
       ("tests/stages/test_clip.py", "tests/test_extremes.py")),
    _m("fast_clip_guard_band", "clip", "fast path",
       "the fast path's outcodes test near and far only: x and y pass unclipped (a guard band)",
       E("softras/pipeline/clip.py", "        for p in range(6):\n            d = np.float32(FRUSTUM_PLANES[p, 0] * x",
         "        for p in range(4, 6):\n            d = np.float32(FRUSTUM_PLANES[p, 0] * x"),
       (FAST, "tests/test_extremes.py")),
    # ------------------------------------------------------------------ setup
    _m("clip_pass_through_ignores_nan", "clip", "fast path",
       "a draw whose vertices are all inside the planes or not finite passes every triangle through, NaN ones too",
       E("softras/pipeline/clip.py", "    if not codes.any():", "    if not (codes & 63).any():"),
       ("tests/stages/test_clip.py", "tests/test_extremes.py", FAST)),
    _m("fill_rule_top_edges", "setup", "stages",
       "horizontal edges own their samples when they are top edges, not bottom edges",
       E("softras/pipeline/setup.py", "inclusive = (sign_a * a > 0) | ((a == 0) & (sign_b * b > 0))",
         "inclusive = (sign_a * a > 0) | ((a == 0) & (sign_b * b < 0))"),
       (FAST, "tests/stages/test_setup.py", "tests/stages/test_rasterize.py")),
    _m("fast_fill_rule_top_edges", "setup", "fast path",
       "the fast path's fill rule: horizontal top edges inclusive instead of bottom edges",
       E("softras/kernels/setup.py", "tri_i[t, _I_INC + i] = 1 if (a > 0 or (a == 0 and b > 0)) else 0",
         "tri_i[t, _I_INC + i] = 1 if (a > 0 or (a == 0 and b < 0)) else 0"),
       (FAST, "tests/test_random_triangles.py")),
    _m("raster_all_edges_inclusive", "rasterize", "stages",
       "no fill rule: a sample exactly on any edge is inside (shared edges draw twice)",
       E("softras/pipeline/rasterize.py", "return e > 0 or (e == 0 and inclusive)", "return e >= 0"),
       ("tests/stages/test_rasterize.py", FAST, "tests/test_extremes.py")),
    _m("snap_half_away", "setup", "stages",
       "subpixel snap rounds halves away from zero (llvmpipe's triangles round half to even)",
       E("softras/pipeline/setup.py", "return np.rint(shifted).astype(np.int64)",
         "return np.floor(shifted + np.float32(0.5)).astype(np.int64)"),
       (FAST, "tests/stages/test_setup.py", "tests/test_mutations_caught.py")),
    _m("fast_snap_truncate", "setup", "fast path",
       "the fast path truncates x to 1/256 pixel instead of rounding",
       E("softras/kernels/setup.py",
         "rx = np.int64(np.rint((np.float32(wx) - np.float32(0.5)) * np.float32(SUBPIXEL_ONE)))",
         "rx = np.int64(np.floor((np.float32(wx) - np.float32(0.5)) * np.float32(SUBPIXEL_ONE)))"),
       (FAST, "tests/test_random_triangles.py")),
    _m("viewport_unfused", "setup", "stages",
       "viewport transform x * W/2 + W/2 rounded twice (llvmpipe's vertex code fuses the multiply-add)",
       E("softras/pipeline/setup.py", "window = np.where(np.asarray(fused)[..., None], single, double)",
         "window = np.where(np.asarray(fused)[..., None], double, double)"),
       (FAST, "tests/stages/test_setup.py", "tests/test_mutations_caught.py")),
    _m("fast_viewport_unfused", "setup", "fast path",
       "the fast path's viewport transform unfused for the shader's vertices too",
       E("softras/kernels/setup.py", "    if fused:\n        wx = np.float64(np.float32(px * hx + hx))",
         "    if False:\n        wx = np.float64(np.float32(px * hx + hx))"),
       (FAST, "tests/test_random_triangles.py", "tests/test_mutations_caught.py")),
    _m("fast_setup_shares_list_from_row_0", "fast path binning", "fast path",
       "each share of a large draw's set-up lists the triangles it keeps from row 0, over the other shares' lists",
       E("softras/kernels/setup.py", "        listed[start + n_visible] = t\n", "        listed[n_visible] = t\n"),
       (FAST, "tests/test_random_triangles.py")),
    _m("fast_corner_colours_three_channels", "setup", "fast path",
       "the set-up copies three channels of a corner's colour: its alpha stays what the buffer held",
       E("softras/kernels/setup.py", "_corner_values(vertex_colors, corner_colors, t, clipped, swapped, 4)",
         "_corner_values(vertex_colors, corner_colors, t, clipped, swapped, 3)"),
       (FAST, "tests/test_random_triangles.py")),
    _m("fast_setup_box_y_from_x", "setup", "fast path",
       "the set-up's bounding box takes the samples' y extremes from their x offsets",
       E("softras/kernels/setup.py", "min_ox, max_ox, min_oy, max_oy = box[0], box[1], box[2], box[3]",
         "min_ox, max_ox, min_oy, max_oy = box[0], box[1], box[0], box[1]"),
       (FAST, "tests/test_random_triangles.py")),
    _m("fast_front_end_no_second_call", "clip", "fast path",
       "a small draw whose clipping makes more triangles than its mesh has is not set up again with room (dropped)",
       E("softras/kernels/draw.py", "            if n <= rows:\n                break",
         "            if True:\n                break"),
       (FAST, "tests/test_random_triangles.py")),
    # ------------------------------------------------------------ interpolate
    _m("perspective_off", "interpolate", "stages",
       "attributes interpolated affinely in screen space (no division by w)",
       E("softras/pipeline/interpolate.py", "    q = lam * inv_w\n    return q / q.sum(axis=1, keepdims=True)",
         "    q = lam * 1.0\n    return q / q.sum(axis=1, keepdims=True)"),
       ("tests/stages/test_interpolate.py", FAST)),
    _m("fast_perspective_off", "interpolate", "fast path",
       "the fast path's weights without 1/w (affine colours and uvs)",
       E("softras/kernels/interpolate.py",
         "    q0 = e0 * iw0\n    q1 = e1 * iw1\n    q2 = e2 * iw2\n",
         "    q0 = e0\n    q1 = e1\n    q2 = e2\n"),
       (FAST,)),
    _m("corner_values_kept_corners_summed", "interpolate", "shared",
       "a corner the clipper passed through takes the clip weights' sum too (-0 comes back +0, "
       "another vertex's infinity makes NaN)",
       E("softras/pipeline/render.py", "        out[passed] = values[own]\n", ""),
       ("tests/test_exact_path.py", FAST)),
    _m("line_ends_kept_summed", "lines", "shared",
       "a line end the clipper kept takes the clip weights' sum too (-0 comes back +0, the other end's "
       "infinity makes NaN)",
       E("softras/pipeline/lines.py",
         "    ends = np.where(clipped.generated[..., None], made, at)      # (end k of a kept line: vertex k)\n",
         "    ends = made\n"),
       (FAST, "tests/stages/test_lines.py")),
    _m("glref_noperspective", "interpolate", "glref",
       "glref's shaders interpolate the vertex colour with noperspective",
       (E("shaders/unlit.vert", "out vec4 v_color;", "noperspective out vec4 v_color;"),
        E("shaders/unlit.frag", "in vec4 v_color;", "noperspective in vec4 v_color;")),
       ("tests/test_glref.py", "tests/test_scenes.py")),
    # --------------------------------------------------------------- texture
    _m("lod_mip_nearest_down", "texture LOD", "stages",
       "mipmap_nearest level = floor(log2 rho) instead of round (halves up)",
       E("softras/pipeline/texture.py", "level = np.right_shift(e.astype(np.int64), 1)",
         "level = np.right_shift(e.astype(np.int64) - 1, 1)"),
       ("tests/stages/test_texture.py", "tests/test_texture_gl.py", FAST)),
    _m("fast_lod_magnify_threshold", "texture LOD", "fast path",
       "the fast path magnifies up to rho^2 = 2 (lambda 0.5) instead of rho^2 = 1",
       E("softras/kernels/texture.py", "magnified = not (rho2 > 1)", "magnified = not (rho2 > 2)"),
       (FAST, "tests/test_texture_gl.py")),
    _m("wrap_repeat_as_clamp", "texture wrap", "stages",
       "repeat wraps like clamp_to_edge",
       E("softras/scene/texels.py", 'if mode == "repeat":\n        return np.mod(i, size)',
         'if mode == "repeat":\n        return np.clip(i, 0, size - 1)'),
       ("tests/stages/test_texture.py", "tests/test_texture_gl.py")),
    _m("fast_wrap_select_swap", "texture wrap", "fast path",
       "the fast path's branch-free wrap swaps repeat and mirrored_repeat",
       E("softras/kernels/texture.py", "return clamped if mode == 1 else (repeat if mode == 0 else mirrored)",
         "return clamped if mode == 1 else (mirrored if mode == 0 else repeat)"),
       (FAST,)),
    _m("filter_lerp_truncates", "texture filter", "stages",
       "the 8.8 bilinear lerp truncates (no +128 before >> 8)",
       E("softras/pipeline/texture.py", "return a + ((weight * (b - a) + 128) >> 8)",
         "return a + ((weight * (b - a)) >> 8)"),
       ("tests/stages/test_texture.py", "tests/test_texture_gl.py", FAST)),
    _m("fast_filter_weight_offset", "texture filter", "fast path",
       "the fast path's 8.8 s coordinate is off by 1/256 texel (- 127 instead of - 128)",
       E("softras/kernels/texture.py",
         "fs = np.int64(np.rint(np.float32(np.float32(lf[_LF_S, l]) * scale_s))) - 128",
         "fs = np.int64(np.rint(np.float32(np.float32(lf[_LF_S, l]) * scale_s))) - 127"),
       (FAST,)),
    _m("filter_float_weights_swapped", "texture filter", "stages",
       "float bilinear weights of texels (1,0) and (0,1) swapped (mirrored_repeat, exact precision)",
       E("softras/scene/texels.py",
         "return (1 - a) * (1 - b) * t00 + a * (1 - b) * t10 + (1 - a) * b * t01 + a * b * t11",
         "return (1 - a) * (1 - b) * t00 + a * (1 - b) * t01 + (1 - a) * b * t10 + a * b * t11"),
       ("tests/stages/test_bump.py", "tests/stages/test_texture_beyond.py", "tests/test_bump_gl.py")),
    _m("mip_blend_weight_rounded", "texture filter", "stages",
       "the 8.8 mip blend weight rounded instead of truncated (floor(frac * 256))",
       E("softras/pipeline/texture.py", "w8 = np.floor(choice.frac * 256).astype(np.int64)[:, None]",
         "w8 = np.rint(choice.frac * 256).astype(np.int64)[:, None]"),
       ("tests/stages/test_texture.py", "tests/test_texture_gl.py", FAST)),
    _m("mipgen_round_down", "mip generation", "shared",
       "the mip chain's vertical lerp truncates (llvmpipe's glGenerateMipmap rounds)",
       E("softras/scene/texels.py", "out[j, i, c] = top + ((wy * (bottom - top) + 128) >> 8)",
         "out[j, i, c] = top + ((wy * (bottom - top)) >> 8)"),
       ("tests/test_mipmap_gl.py", "tests/stages/test_texture.py")),
    _m("mipgen_diagonal", "mip generation", "shared",
       "a destination texel centre on the blit's diagonal taken from the lower-left triangle",
       E("softras/scene/texels.py", "if (2 * j + 1) * nw <= (2 * i + 1) * nh:",
         "if (2 * j + 1) * nw < (2 * i + 1) * nh:"),
       ("tests/test_mipmap_gl.py", "tests/test_mutations_caught.py")),
    _m("premultiply_truncates", "texels", "shared",
       "texels premultiplied as floor(c a / 255) instead of round (glref uploads the same level 0)",
       E("softras/scene/texels.py", "np.arange(256)[:, None] * 2 + 255) // 510)",
         "np.arange(256)[:, None] * 2) // 510)"),
       ("tests/stages/test_texture.py", "tests/test_mutations_caught.py")),
    _m("glref_wrap_t_from_s", "texture wrap", "glref",
       "glref sets GL_TEXTURE_WRAP_T from the texture's wrap_s",
       E("glref/render.py", "parami(_GL_TEXTURE_2D, _GL_TEXTURE_WRAP_T, _GL_WRAP[texture.wrap_t])",
         "parami(_GL_TEXTURE_2D, _GL_TEXTURE_WRAP_T, _GL_WRAP[texture.wrap_s])"),
       ("tests/test_texture_gl.py", "tests/test_mutations_caught.py")),
    # -------------------------------------------------------------- fragment
    _m("fragment_not_premultiplied", "fragment", "stages",
       "unlit fragment colour not premultiplied by its alpha",
       E("softras/pipeline/fragment.py", "rgba = premultiply(vertex_color * material_color)",
         "rgba = vertex_color * material_color"),
       (FAST, "tests/test_blend.py")),
    # ------------------------------------------------------------------ depth
    _m("depth_round_floor", "depth", "stages",
       "depth rounded down to the 24-bit buffer's k / (2^24 - 1) (GL rounds to nearest)",
       E("softras/pipeline/ops.py", "return np.rint(np.clip(z, 0.0, 1.0) * scale) / scale",
         "return np.floor(np.clip(z, 0.0, 1.0) * scale) / scale"),
       (FAST, "tests/test_mutations_caught.py")),
    _m("fast_depth_round_floor", "depth", "fast path",
       "the fast path rounds depth down to 24 bits",
       E("softras/kernels/ops.py", "k = np.rint(min(max(z, 0.0), 1.0) * DEPTH_SCALE)",
         "k = np.floor(min(max(z, 0.0), 1.0) * DEPTH_SCALE)"),
       (FAST, "tests/test_mutations_caught.py")),
    _m("depth_lequal_as_less", "depth", "stages",
       "depth function lequal tests z < stored",
       E("softras/pipeline/ops.py", "    if func == 4:\n        return z <= stored", "    if func == 4:\n        return z < stored"),
       ("tests/stages/test_ops.py", FAST)),
    _m("fast_depth_greater_as_gequal", "depth", "fast path",
       "the fast path's integer depth function greater passes equal depths",
       E("softras/kernels/ops.py", '"greater": 0b0100', '"greater": 0b0110'),
       (FAST,)),
    _m("glref_depth_lequal_as_less", "depth", "glref",
       "glref maps depth_test lequal to GL_LESS",
       E("glref/render.py", '"lequal": "<=",', '"lequal": "<",'),
       ("tests/test_glref.py", "tests/test_scenes.py")),
    # ------------------------------------------------------------------ blend
    _m("blend_subtract_reversed", "blend", "stages",
       "the stages' byte blend's subtract computes dst - src",
       E("softras/pipeline/ops.py", "    if mode == 4:\n        return max(s - d, 0)",
         "    if mode == 4:\n        return max(d - s, 0)"),
       ("tests/stages/test_ops.py", "tests/test_blend_gl.py")),
    _m("fast_blend_over_factor", "blend", "fast path",
       "the fast path's 'over' multiplies dst by 256 - alpha instead of 255 - alpha",
       E("softras/kernels/ops.py", "second = dst if blend == 3 else _mul_lanes(dst, 255 - alpha)",
         "second = dst if blend == 3 else _mul_lanes(dst, 256 - alpha)"),
       (FAST, "tests/test_blend_gl.py")),
    _m("fast_blend_min_takes_max", "blend", "fast path",
       "the fast path's 'min' keeps the larger byte where the stored one is larger",
       E("softras/kernels/ops.py", "lanes = (dst & src_ge) | (src & ~src_ge)",
         "lanes = (dst & src_ge) | (dst & ~src_ge)"),
       (FAST,)),
    _m("fast_float_colour_rounded", "blend", "fast path",
       "the fast path's rgba32f write rounds the fragment colour to float32 before the float64 blend",
       E("softras/kernels/ops.py",
         "    for s in range(n_samples):\n        if not (p >> s) & 1:\n            continue\n"
         "        color_f[py, px, s, 0] = _blend(",
         "    r, g, b, a = np.float32(r), np.float32(g), np.float32(b), np.float32(a)\n"
         "    for s in range(n_samples):\n        if not (p >> s) & 1:\n            continue\n"
         "        color_f[py, px, s, 0] = _blend("),
       ("tests/test_rgba32f_path.py",)),
    _m("fast_float_rows_depth_always_written", "depth test", "fast path",
       "the rgba32f row loop of opaque depth-tested draws writes the depth where the test failed",
       E("softras/kernels/rgba32f.py", "        depths[i] = k if passed else stored\n", "        depths[i] = k\n"),
       (FAST, "tests/test_rgba32f_path.py")),
    _m("fast_float_rows_alpha_squared", "blend", "fast path",
       "the rgba32f row loop of opaque depth-tested draws premultiplies the alpha channel by itself",
       E("softras/kernels/rgba32f.py", "floats[j + np.uint64(3)] = a if passed",
         "floats[j + np.uint64(3)] = a * a if passed"),
       (FAST, "tests/test_rgba32f_path.py")),
    _m("blend_mul_exact_rounding", "blend", "stages",
       "the stages' a * b / 255 rounded exactly (llvmpipe's shift approximation differs on 24 pairs)",
       E("softras/pipeline/ops.py", "return (t + (t >> 8) + 0x80) >> 8", "return (2 * t + 255) // 510"),
       ("tests/stages/test_ops.py", "tests/test_blend_gl.py")),
    _m("unorm8_half_up", "blend", "shared",
       "fragment colour -> UNORM8 rounds halves up (llvmpipe rounds the float32 c * 255 half to even)",
       E("softras/pipeline/ops.py", "return np.int64(np.int32(np.rint(np.float64(np.float32(clamped * np.float32(255.0))))))",
         "return np.int64(np.int32(np.floor(np.float64(np.float32(clamped * np.float32(255.0))) + 0.5)))"),
       ("tests/stages/test_ops.py", "tests/test_mutations_caught.py")),
    _m("glref_blend_subtract", "blend", "glref",
       "glref's subtract uses GL_FUNC_REVERSE_SUBTRACT",
       E("glref/render.py", '"subtract": (one, mgl.FUNC_SUBTRACT),', '"subtract": (one, mgl.FUNC_REVERSE_SUBTRACT),'),
       ("tests/test_glref.py", "tests/test_blend_gl.py")),
    _m("glref_cull_swapped", "cull", "glref",
       "glref culls the opposite face",
       E("glref/render.py", "ctx.cull_face = draw.cull",
         'ctx.cull_face = "front" if draw.cull == "back" else "back"'),
       ("tests/test_glref.py", "tests/test_scenes.py")),
    # ---------------------------------------------------------------- resolve
    _m("resolve_half_up", "resolve", "shared",
       "the MSAA resolve rounds halves up (llvmpipe's blit rounds half to even)",
       E("softras/pipeline/ops.py", "top[j] = np.uint8(np.rint(value))",
         "top[j] = np.uint8(np.floor(value + np.float32(0.5)))"),
       ("tests/stages/test_resolve.py", "tests/test_mutations_caught.py")),
    _m("resolve_four_reassociated", "resolve", "shared",
       "the MSAA resolve of 4 samples sums a pixel's products as p0 + (p1 + p2) + p3 (llvmpipe adds in sample order)",
       E("softras/pipeline/ops.py", "(((products[16 * x + c] + products[16 * x + 4 + c])\n"
         "                                         + products[16 * x + 8 + c])",
         "((products[16 * x + c] + (products[16 * x + 4 + c]\n"
         "                                         + products[16 * x + 8 + c]))"),
       ("tests/stages/test_resolve.py",)),
    _m("resolve_exact_in_stages", "resolve", "stages",
       "the stages resolve GL's MSAA patterns with the exact float64 mean",
       E("softras/pipeline/render.py", "arithmetic=_arithmetic(job),", 'arithmetic="exact",'),
       ("tests/test_random_lines.py", "tests/stages/test_resolve.py", FAST)),
    # ------------------------------------------------------------------ lines
    _m("line_last_pixel_drawn", "lines", "stages",
       "x-major lines draw their last pixel when the end point lies inside its diamond",
       E("softras/pipeline/lines.py",
         "        if _r(abs(x2diff) + abs(y2diff), gl) < 0.5:\n            draw_end = False\n"
         "        elif (x2diff >= 0.0) != (-dx >= 0.0):",
         "        if _r(abs(x2diff) + abs(y2diff), gl) < 0.5:\n            draw_end = True\n"
         "        elif (x2diff >= 0.0) != (-dx >= 0.0):"),
       ("tests/stages/test_lines.py", "tests/test_random_lines.py")),
    _m("line_row_slice_far_corner", "lines", "stages",
       "a row's slice of a line's quad takes each edge's line through the edge's far corner",
       E("softras/pipeline/lines.py", "            x = qx[i] + (y - qy[i]) * ((qx[j] - qx[i]) / rise)",
         "            x = qx[j] + (y - qy[i]) * ((qx[j] - qx[i]) / rise)"),
       ("tests/stages/test_lines.py", "tests/test_random_lines.py")),
    _m("line_row_slice_off_by_a_subpixel", "lines", "stages",
       "a row's slice of a line's quad shifted right by one raster unit (1/256 pixel)",
       E("softras/pipeline/lines.py", "            x = qx[i] + (y - qy[i]) * ((qx[j] - qx[i]) / rise)",
         "            x = qx[i] + (y - qy[i]) * ((qx[j] - qx[i]) / rise) + 1.0"),
       ("tests/stages/test_lines.py", "tests/test_random_lines.py")),
    # -------------------------------------------------- fast path machinery
    _m("fast_parallel_setup_drops_a_chunk", "fast path set-up", "fast path",
       "the set-up in shares (>= PARALLEL_SETUP triangles) stops each share one triangle short",
       E("softras/kernels/setup.py", "_setup_range(start, (r + 1) * n // n_shares, *args,",
         "_setup_range(start, (r + 1) * n // n_shares - 1, *args,"),
       (FAST, "tests/test_mutations_caught.py")),
    _m("fast_bin_run_not_stored", "fast path binning", "fast path",
       "binning leaves a run's tile place in the register when another tile's run begins: "
       "that tile's later triangles overwrite the run's",
       E("softras/kernels/rasterize.py",
         "            if k != run_k:\n                if run_k >= 0:\n                    fill[run_k] = run_at\n",
         "            if k != run_k:\n                if run_k >= 0:\n                    pass\n"),
       (FAST, "tests/test_random_triangles.py")),
    _m("fast_tile_cleared_again", "fast path framebuffer clear", "fast path",
       "a tile drawn in one batch is cleared again by the next batch that draws there (its flag kept)",
       E("softras/kernels/draw.py", "                fb_r.fresh[tile] = 0\n", "                pass\n"),
       (FAST_TILES,)),
    _m("fast_no_clear_before_lines", "fast path framebuffer clear", "fast path",
       "a line draw draws into tiles no triangle draw has cleared yet",
       E("softras/kernels/draw.py", "            _clear_fresh(tuple(fb), not rgba8)\n            draw_lines(",
         "            draw_lines("),
       (FAST_TILES,)),
    _m("fast_tile_clear_short_row", "fast path framebuffer clear", "fast path",
       "a tile's clear and its copy into the picture leave the last pixel of each of its rows",
       E("softras/kernels/ops.py", "return x0, x_last + 1, y0, min(y0 + TILE, height)",
         "return x0, x_last, y0, min(y0 + TILE, height)"),
       (FAST_TILES,)),
    _m("fast_picture_drawn_tile_as_background", "fast path framebuffer clear", "fast path",
       "the one-sample picture takes the background for the tiles the last batch drew",
       E("softras/kernels/ops.py", "                if fresh[tile]:\n                    row[:] = word",
         "                if not fresh[tile]:\n                    row[:] = word"),
       (FAST_TILES,)),
    _m("exact_band_drawn_by_every_share", "exact path shares", "exact path",
       "every share of an exact draw draws every band (no band taken by one share alone)",
       E("softras/kernels/exact.py", "            if not _owns(owners, band, r):\n                continue\n", ""),
       ("tests/test_exact_path.py",)),
    _m("exact_lines_bands_of_share_0", "exact path shares", "exact path",
       "every share of an exact line draw's coverage takes share 0's bands (the others' are left undrawn)",
       E("softras/kernels/exact_lines.py", "first += (r - first) % n_threads",
         "first += (0 - first) % n_threads"),
       ("tests/test_exact_lines.py",)),
    _m("exact_resolve_box_truncates", "resolve", "exact path",
       "the exact kernels' box resolve to bytes truncates instead of rounding to nearest",
       E("softras/kernels/ops.py", "byte = np.uint8(np.rint(min(max(v, 0.0), 1.0) * 255.0))",
         "byte = np.uint8(np.floor(min(max(v, 0.0), 1.0) * 255.0))"),
       ("tests/test_exact_path.py",)),
    _m("rgba32f_resolve_box_mean_of_first", "resolve", "fast path",
       "the kernels' box resolve of float samples takes the first sample for the mean",
       E("softras/kernels/ops.py", "                        out[row, x, c] = _sample_mean(color, y, x, c)",
         "                        out[row, x, c] = color[y, x, 0, c]"),
       ("tests/test_rgba32f_path.py",)),
    _m("fast_bin_last_tile_column", "fast path binning", "fast path",
       "binning leaves out the last 64-pixel tile column of a triangle's box",
       (E("softras/kernels/setup.py", "for tx in range(b0 // TILE, b1 // TILE + 1):",
          "for tx in range(b0 // TILE, b1 // TILE):"),
        E("softras/kernels/rasterize.py", "bbox[t, 0] // TILE, bbox[t, 1] // TILE, bbox[t, 2] // TILE",
          "bbox[t, 0] // TILE, bbox[t, 1] // TILE - 1, bbox[t, 2] // TILE")),
       (FAST,)),
    _m("fast_row_run_right_end_short", "rasterize", "fast path",
       "a row's run of covered pixels (one sample) loses a pixel whose sample lies exactly on a right edge",
       E("softras/kernels/rasterize.py", "hi = min(hi, r // (-step))", "hi = min(hi, (r - 1) // (-step))"),
       ("tests/test_row_runs.py", FAST)),
    _m("fast_row_run_horizontal_edge", "rasterize", "fast path",
       "a row (one sample) whose samples lie exactly on an inclusive horizontal edge is dropped",
       E("softras/kernels/rasterize.py", "    elif r < 0:\n        hi = lo - 1",
         "    elif r <= 0:\n        hi = lo - 1"),
       ("tests/test_row_runs.py", FAST)),
    _m("fast_depth_less_ties_pass", "depth test", "fast path",
       "the one-sample \"less\" copy of the depth test lets a fragment at the stored depth pass",
       E("softras/kernels/ops.py", "_depth_pass_k(LESS, k, stored)",
         "_depth_pass_k(ops_stage.DEPTH_FUNCS[\"lequal\"], k, stored)"),
       (FAST,)),
    _m("fast_depth_notequal_fails_nan", "depth test", "fast path",
       "the fast path's \"notequal\" fails a NaN depth (unordered), which compares unequal to all",
       E("softras/kernels/ops.py", '"notequal": 0b1101', '"notequal": 0b0101'),
       (FAST,)),
    _m("fast_depth_less_no_write", "depth test", "fast path",
       "the one-sample \"less\" copy of the depth test writes no depth",
       E("softras/kernels/ops.py", "depths[i] = k if passed else stored", "depths[i] = stored"),
       (FAST,)),
    _m("fast_row_less_ties_pass", "depth test", "fast path",
       "the row loops' \"less\" copies (interpolated, flat at one sample) let a fragment at the stored depth pass",
       E("softras/kernels/draw.py", "width, True, LESS, True, 0,",
         "width, True, ops.DEPTH_FUNCS[\"lequal\"], True, 0,", count=2),
       (FAST,)),
    _m("fast_row_no_depth_write", "depth test", "fast path",
       "the row loops (1 and 4 samples) write no depth",
       E("softras/kernels/draw.py", "depths[i] = np.int32((k & written) | (stored & ~written))", "depths[i] = stored",
         count=2),
       (FAST,)),
    _m("fast_row_depth_written_without_depth_write", "depth test", "fast path",
       "the row loops write the depth of a passed sample where the draw's depth writes are off",
       E("softras/kernels/draw.py", "written = keep & -np.int64(write_z)", "written = keep", count=2),
       (FAST,)),
    _m("fast_row_trim_drops_first_passing_pixel", "depth test", "fast path",
       "the row loops' copy for any state shades a partly hidden run from its second passing pixel",
       E("softras/kernels/draw.py", "lo = min(lo, px if passed else end + 1)",
         "lo = min(lo, px + 1 if passed else end + 1)"),
       (FAST,)),
    _m("fast_row_over_not_blended", "blend", "fast path",
       "the row loops' copy for \"over\" without depth stores the fragment unblended",
       E("softras/kernels/draw.py", "width, False, 0, False, 1, False, n_samples)",
         "width, False, 0, False, 0, False, n_samples)"),
       (FAST,)),
    _m("fast_row_padding_written", "coverage", "fast path",
       "the row loop at one sample writes the pixels it adds to reach whole vectors (outside the run)",
       E("softras/kernels/draw.py", "keep = -np.int64((start <= px) & (px <= end))", "keep = np.int64(-1)"),
       (FAST,)),
    _m("fast_textured_last_lanes_unshaded", "coverage", "fast path",
       "the textured tile never shades the quads still listed at a triangle's last block (fewer than LANES)",
       E("softras/kernels/draw.py", "if listed == 0 or (listed < LANES and k < n_blocks - 1):",
         "if listed == 0 or (listed < LANES and k < n_blocks):"),
       (FAST,)),
    _m("fast_row_failed_pixel_written", "depth test", "fast path",
       "the row loops (1 and 4 samples) store the colour of a sample that failed the depth test",
       (E("softras/kernels/draw.py", "words[i] = np.uint32((out & keep) | (dst & ~keep))", "words[i] = np.uint32(out)"),
        E("softras/kernels/draw.py", "words[i] = np.uint32((word & keep) | (dst & ~keep))",
          "words[i] = np.uint32(word)")),
       (FAST,)),
    _m("fast_row_sample_run_open_right", "rasterize", "fast path",
       "the 4-sample row loop takes a sample as covered to the right of its run (the union's end)",
       E("softras/kernels/draw.py", "keep = -np.int64((runs[2 * s] <= px - x0) & (px - x0 <= runs[2 * s + 1]))",
         "keep = -np.int64(runs[2 * s] <= px - x0)"),
       (FAST,)),
    _m("fast_share_lost", "rasterize", "fast path",
       "the tile driver's last share never runs on a thread of its own (the others take its tiles)",
       E("softras/kernels/pool.py", "for r in range(1, n_threads)]", "for r in range(1, n_threads - 1)]"),
       (FAST, "tests/test_threads.py")),
    _m("pool_threads_beside_caller", "rasterize", "fast path",
       "the pool's threads may run on the calling thread's CPU (a woken share queues behind the caller's)",
       E("softras/kernels/pool.py", "    others = (allowed - {cpu}) or allowed\n", "    others = allowed\n"),
       ("tests/test_threads.py",)),
    _m("fast_tiles_taken_twice", "rasterize", "fast path",
       "every share of a batch draws every tile, taken by another share or not (blends twice)",
       E("softras/kernels/threads.py", "return owner == -1 or owner == r", "return True"),
       (FAST, "tests/test_threads.py")),
    _m("fast_lines_other_bands", "lines", "fast path",
       "a thread of the line kernel takes the lines that lie in the other threads' bands, not its own",
       E("softras/kernels/lines.py", "        if band % n_threads == r:", "        if band % n_threads != r:"),
       (FAST,)),
    _m("fast_lines_setup_share_short", "lines", "fast path",
       "each share of the line set-up stops one line short of its run (that line keeps its last render's row)",
       E("softras/kernels/lines.py", "range(r * n_lines // n_threads, (r + 1) * n_lines // n_threads)",
         "range(r * n_lines // n_threads, (r + 1) * n_lines // n_threads - 1)"),
       (FAST,)),
    _m("fast_lines_rgba32f_into_words", "lines", "fast path",
       "the line kernel's rgba32f copy of its loop writes RGBA8 words, as the other copy does",
       E("softras/kernels/lines.py", "color32, color_f, True,\n", "color32, color_f, False,\n"),
       ("tests/test_rgba32f_path.py", FAST)),
    _m("fast_vertex_lighting_light_colour", "shading", "fast path",
       "Gouraud's vertex lighting (in passes) gives the red term the light's green",
       E("softras/kernels/light.py", "out[v, 0] + _light_term(cr, diffuse", "out[v, 0] + _light_term(cg, diffuse"),
       (FAST,)),
    _m("fast_lighting_share_short", "shading", "fast path",
       "Gouraud's vertex lighting in shares (>= PARALLEL_LIGHTING vertices): the second share skips its last chunk",
       E("softras/kernels/light.py", "for chunk in range(r * chunks // n_shares, (r + 1) * chunks // n_shares):",
         "for chunk in range(r * chunks // n_shares, (r + 1) * chunks // n_shares - r):"),
       (FAST,)),
    _m("fast_lit_fan_rows_overlap", "shading", "fast path",
       "the lit rows of a fan triangle's corners that the clipper made overlap the next fan triangle's",
       E("softras/kernels/setup.py", "r = n_vertices + 3 * f + row", "r = n_vertices + f + row"),
       (FAST,)),
    _m("fast_lit_inputs_shared_by_a_batch", "buffer reuse", "fast path",
       "a Phong draw's lit attributes, read by row, live in the thread's reused buffer for every draw of a batch",
       E("softras/kernels/draw.py", "phong_inputs(scene, draw, take, view, fan_rows)",
         "phong_inputs(scene, draw, _scratch.take, view, fan_rows)"),
       (FAST,)),
    _m("aligned_stack_attribute_unwritten", "fast path machinery", "fast path",
       "the kernels' alignstack(64) is set but llvmlite never writes it (no named attribute beside it)",
       E("softras/kernels/threads.py", '        builder.function.attributes.add("nounwind")\n', ""),
       ("tests/test_threads.py",)),
    _m("fast_batch_past_lines", "render order", "fast path",
       "the triangle draws set up before a line draw are drawn after it (the batch is not drawn first)",
       E("softras/kernels/draw.py", "if batch and (lines or len(batch) == MAX_BATCH", "if batch and (len(batch) == MAX_BATCH"),
       (FAST, "tests/test_threads.py")),
    _m("fast_helper_lane_depth", "depth test", "fast path",
       "the depth test reads and writes back the depths of helper lanes (outside the picture at odd sizes)",
       (E("softras/kernels/ops.py", "            if li[_LI_COV, l] == 0:\n                li[_LI_PASS, l] = 0\n"
          "                continue\n", ""),
        E("softras/kernels/ops.py", "passed = _depth_pass_k(LESS, k, stored)",
          "passed = (li[_LI_COV, l] & 1 != 0) & _depth_pass_k(LESS, k, stored)"),
        E("softras/kernels/ops.py", "n_samples) if mask != 0 else 0)", "n_samples))")),
       ("tests/test_helper_lanes.py",)),
    _m("fast_corner_colours_unswapped", "setup", "fast path",
       "the set-up takes a clockwise triangle's corner colours in the mesh's order, not its swapped corners'",
       E("softras/kernels/setup.py", "_corner_values(vertex_colors, corner_colors, t, clipped, swapped, 4)",
         "_corner_values(vertex_colors, corner_colors, t, clipped, 0, 4)"),
       (FAST, "tests/test_mutations_caught.py")),
    _m("resolve_aliases_scratch", "buffer reuse", "fast path",
       "a 1-sample picture is a view of the fast path's reused colour buffer, not a copy",
       E("softras/pipeline/ops.py", "return stored[::-1, :, 0].copy()        # (a copy: the fast path's buffer is reused)",
         "return stored[::-1, :, 0]        # (a copy: the fast path's buffer is reused)"),
       (FAST,)),
    # ------------------------------------------------------- scene model, glue
    _m("projection_full_angle", "scene model", "shared",
       "gluPerspective's f = cot(fov_y) instead of cot(fov_y / 2) (both renderers take this matrix)",
       E("softras/scene/transforms.py", "f = 1.0 / math.tan(math.radians(fov_y) / 2.0)",
         "f = 1.0 / math.tan(math.radians(fov_y))"),
       ("tests/test_scene.py", "tests/test_extremes.py")),
    _m("sorted_front_to_back", "scene model", "shared",
       "transparent draws sorted front to back (both renderers take this order)",
       E("softras/scene/model.py", "back_to_front = sorted(transparent, key=distance, reverse=True)",
         "back_to_front = sorted(transparent, key=distance, reverse=False)"),
       ("tests/test_render_order.py",)),
    _m("dispatch_ignores_tie_rule", "pipeline glue", "stages",
       "render_scene sends another tie rule to the fast path (which knows only llvmpipe's)",
       E("softras/renderer.py", 'and texture_bounds is None and tie_rule == "left_bottom"',
         "and texture_bounds is None"),
       (FAST, "tests/test_texture_bounds.py", "tests/test_verifier.py", "tests/stages/test_setup.py",
        "tests/test_planted_bugs.py")),
    _m("call_typed_without_its_arguments", "compile", "stages",
       "numba's typing of a call kept once for the function, whatever its argument types",
       E("softras/pipeline/numba_fixes.py",
         "key = (self, context, tuple(args), tuple(kws.items()), stack.top_or_none())",
         "key = (self, context, tuple(kws.items()), stack.top_or_none())"),
       ("tests/test_numba_fixes.py",)),
)


# ----------------------------------------------------------------------------- applying edits


def apply_edits(mutation: Mutation, root: Path) -> list[Path]:
    """Apply a mutation's edits under ``root``; returns the files changed.
    Raises HarnessError when an old text is not found exactly ``count`` times."""
    texts: dict[Path, str] = {}
    for edit in mutation.edits:
        path = root / edit.path
        if path not in texts:
            if not path.is_file():
                raise HarnessError(f"{mutation.name}: no file {edit.path}")
            texts[path] = path.read_text(encoding="utf-8")
        found = texts[path].count(edit.old)
        if found != edit.count:
            raise HarnessError(f"{mutation.name}: {edit.path}: the old text occurs {found} times, "
                               f"expected {edit.count}: {edit.old[:80]!r}")
        texts[path] = texts[path].replace(edit.old, edit.new)
    for path, text in texts.items():
        path.write_text(text, encoding="utf-8")
    return list(texts)


def check_mutations(mutations=MUTATIONS) -> None:
    """Every edit applies to the repository as it is (in memory), and names are unique."""
    names = [m.name for m in mutations]
    duplicates = {n for n in names if names.count(n) > 1}
    if duplicates:
        raise HarnessError(f"duplicate mutation names: {sorted(duplicates)}")
    for mutation in mutations:
        texts: dict[str, str] = {}
        for edit in mutation.edits:
            path = REPO / edit.path
            if not path.is_file():
                raise HarnessError(f"{mutation.name}: no file {edit.path}")
            text = texts.setdefault(edit.path, path.read_text(encoding="utf-8"))
            found = text.count(edit.old)
            if found != edit.count:
                raise HarnessError(f"{mutation.name}: {edit.path}: the old text occurs {found} times, "
                                   f"expected {edit.count}: {edit.old[:80]!r}")
            if edit.old == edit.new:
                raise HarnessError(f"{mutation.name}: an edit that changes nothing")
            texts[edit.path] = text.replace(edit.old, edit.new)
        for test in mutation.quick:
            if not (REPO / test.split("::")[0]).exists() and "mutations_caught" not in test:
                raise HarnessError(f"{mutation.name}: quick test {test} does not exist")


# ----------------------------------------------------------------------------- numba's cache
#
# numba caches each compiled kernel in __pycache__ next to its source, as an
# index ``<module>.<qualname>-<first line>.pyXY.nbi`` (the source's stamp --
# in numba 0.68 a SHA-256 of the file -- and the compiled signatures) and data
# files ``....N.nbc``. It does not know which other kernels a kernel inlined or
# which global values it froze: a kernel of softras/kernels/ that inlines
# ops.blend_byte would load its unmutated blend from the cache when only ops.py
# changes. So the harness works out, from the source (`KernelGraph`), which
# kernels a mutation reaches -- the kernel it edits, or the kernels that read
# the module-level value it edits, and every kernel that calls one of those,
# across modules -- and gives each module holding such a kernel a fresh stamp
# in the copy (the mutated module by its edit, the others by a marker comment
# appended at their end). The kernels it does not reach keep the repository's
# compiled code: their index files are copied and re-stamped (`_restamp`);
# the reached ones compile in the copy once and stay there for the next run of
# the same mutation. An edit in a plain Python function reaches no kernel. An
# edit that changes a file's line count moves every later kernel's cache file
# name, so all the module's kernels count as reached.


def _dotted(node) -> str:
    while isinstance(node, ast.Call):
        node = node.func
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
    return ".".join(reversed(parts))


def _is_kernel(func: ast.AST) -> bool:
    return any(_dotted(d) in ("numba.njit", "numba.jit", "njit", "jit", "numba.vectorize", "numba.guvectorize",
                              "numba.stencil") for d in func.decorator_list)


@dataclass
class Kernel:
    module: str                   # its file under softras/, without .py: "pipeline/texture"
    qualname: str                 # as numba names it (``outer.<locals>.inner``)
    first: int                    # co_firstlineno: the first decorator's line
    last: int
    refs: set = field(default_factory=set)      # ("", name) or (alias, attr)

    @property
    def cache_base(self) -> str:
        name = f"{Path(self.module).name}.{self.qualname}".replace("<", "").replace(">", "")
        return f"{name}-{self.first}.py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"


class ModuleInfo:
    """The kernels, top-level statements and softras imports of one module's source."""

    def __init__(self, name: str, text: str, known: set[str]):
        self.name = name
        self.tree = ast.parse(text)
        self.kernels: list[Kernel] = []
        self.functions: list[tuple[int, int]] = []           # every def's line range
        self.imports: dict[str, tuple[str, str | None]] = {}   # local name -> (module, attribute or None)
        self._walk(self.tree.body, "", None)
        package = name.rsplit("/", 1)[0] if "/" in name else ""
        for node in ast.walk(self.tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:                                  # relative to this module's package
                    parts = package.split("/") if package else []
                    parts = parts[:len(parts) - node.level + 1]
                    base = "/".join(parts + ([node.module.replace(".", "/")] if node.module else []))
                elif (node.module or "").split(".")[0] == "softras":
                    base = "/".join(node.module.split(".")[1:])
                else:
                    continue
                for a in node.names:
                    child = f"{base}/{a.name}" if base else a.name
                    if child in known:                          # from softras.pipeline import texture
                        self.imports[a.asname or a.name] = (child, None)
                    else:                                       # from softras.pipeline.texture import wrap
                        module = base if base in known else f"{base}/__init__" if base else "__init__"
                        self.imports[a.asname or a.name] = (module, a.name)
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith("softras.") and a.asname:
                        self.imports[a.asname] = ("/".join(a.name.split(".")[1:]), None)

    def _walk(self, body, prefix: str, kernel: Kernel | None):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                self.functions.append((first, node.end_lineno))
                qualname = prefix + node.name
                inner = kernel
                if _is_kernel(node):
                    inner = Kernel(self.name, qualname, first, node.end_lineno, _references(node))
                    self.kernels.append(inner)
                self._walk(node.body, qualname + ".<locals>.", inner)
            elif isinstance(node, ast.ClassDef):
                self._walk(node.body, prefix + node.name + ".", kernel)

    def top_level(self):
        """(names assigned or defined, names read, first line, last line) per top-level statement."""
        for node in self.tree.body:
            targets = set()
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                targets.add(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
                for t in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                    targets |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
            first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
            reads = set() if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else _references(node)
            yield targets, reads, first, node.end_lineno


def _references(node) -> set:
    refs = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Name):
            refs.add(("", n.id))
        elif isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name):
            refs.add((n.value.id, n.attr))
    return refs


class KernelGraph:
    """Which kernels of softras a change reaches (see the comment above)."""

    def __init__(self, root: Path):
        paths = sorted((root / "softras").rglob("*.py"))
        known = {module_key(p, root) for p in paths}
        self.modules = {module_key(p, root): ModuleInfo(module_key(p, root), p.read_text(encoding="utf-8"), known)
                        for p in paths}

    def _resolve(self, module: str, ref) -> tuple[str, str] | None:
        info = self.modules[module]
        alias, name = ref
        if not alias:
            if name in info.imports and info.imports[name][1] is not None:
                return info.imports[name]
            return module, name
        if alias in info.imports and info.imports[alias][1] is None:
            return info.imports[alias][0], name
        return None

    def reached(self, module: str, first: int, last: int, whole_module: bool = False) -> list[Kernel]:
        """The kernels a change of ``module``'s lines first..last reaches."""
        info = self.modules[module]
        names: set[tuple[str, str]] = set()           # (module, top-level name) changed
        kernels: list[Kernel] = []
        if whole_module:
            kernels = list(info.kernels)
            names = {(module, t) for targets, _, _, _ in info.top_level() for t in targets}
        else:
            holders = [k for k in info.kernels if k.first <= first and last <= k.last]
            in_function = any(a <= first and last <= b for a, b in info.functions)
            if holders:
                kernels = [max(holders, key=lambda k: k.first)]
            elif not in_function:                     # module level: the values it assigns
                for targets, _, a, b in info.top_level():
                    if a <= last and first <= b:
                        names |= {(module, t) for t in targets}
        # Module-level values computed from changed names change too (any module).
        grown = True
        while grown:
            grown = False
            for other, oinfo in self.modules.items():
                for targets, reads, _, _ in oinfo.top_level():
                    if any(self._resolve(other, r) in names for r in reads):
                        new = {(other, t) for t in targets} - names
                        if new:
                            names |= new
                            grown = True
        reached = {(k.module, k.qualname) for k in kernels}
        names |= {(k.module, k.qualname) for k in kernels}
        grown = True
        while grown:
            grown = False
            for other, oinfo in self.modules.items():
                for k in oinfo.kernels:
                    if (other, k.qualname) in reached:
                        continue
                    if any(self._resolve(other, r) in names for r in k.refs):
                        reached.add((other, k.qualname))
                        names.add((other, k.qualname))
                        grown = True
        return [k for info in self.modules.values() for k in info.kernels if (k.module, k.qualname) in reached]


def module_key(path: Path, root: Path = REPO) -> str:
    """A module's key: its path under softras/ without .py ("pipeline/texture")."""
    return Path(path).relative_to(root / "softras").with_suffix("").as_posix()


def reached_kernels(mutation: Mutation, root: Path = REPO) -> list[Kernel]:
    """The kernels (in the repository's source) whose compiled code a mutation changes."""
    graph = KernelGraph(root)
    out: dict[tuple[str, str], Kernel] = {}
    for edit in mutation.edits:
        if not (edit.path.startswith("softras/") and edit.path.endswith(".py")):
            continue
        module = module_key(root / edit.path, root)
        text = (root / edit.path).read_text(encoding="utf-8")
        at = text.index(edit.old)
        first = text.count("\n", 0, at) + 1
        last = first + edit.old.count("\n")
        whole = edit.old.count("\n") != edit.new.count("\n")
        for k in graph.reached(module, first, last, whole_module=whole):
            out[(k.module, k.qualname)] = k
    return list(out.values())


def numba_source_stamp(path: Path):
    """What numba records as a source file's stamp (0.68: its SHA-256; older: mtime and size)."""
    from numba.core import caching
    st = os.stat(path)
    hasher = getattr(caching, "_hash_source_file", None)
    if hasher is not None:
        return hasher(str(path), st.st_mtime, st.st_size)
    return st.st_mtime, st.st_size


def _read_index(path: Path):
    with open(path, "rb") as f:
        version = pickle.load(f)
        data = f.read()
    stamp, overloads = pickle.loads(data)
    return version, stamp, overloads


def _restamp(path: Path, old_stamp, new_stamp) -> bool:
    """Give a copied index file the copy's source stamp, if it was fresh for
    the repository's source (``old_stamp``); False when it was not (numba then
    compiles that kernel again, as it would in the repository)."""
    try:
        from numba.core.serialize import dumps
        version, stamp, overloads = _read_index(path)
    except Exception:                                       # another format: let numba recompile
        return False
    if stamp != old_stamp:
        return False
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        pickle.dump(version, f, protocol=-1)
        f.write(dumps((new_stamp, overloads)))
    os.replace(tmp, path)
    return True


def _cache_files(directory: Path, base: str) -> list[Path]:
    return [p for p in directory.glob(base + ".*") if p.name.endswith(NUMBA_CACHE_SUFFIXES)]


def prepare_caches(tree: Path, modules: list[str], reached: list[Kernel], mutation_name: str) -> dict:
    """numba caches, in the copy, of ``modules`` (the mutated ones and those
    holding reached kernels; see the comment above)."""
    stats = {"kept": 0, "restamped": 0, "compile": 0}
    graph = KernelGraph(REPO)
    for module in modules:
        source = tree / "softras" / f"{module}.py"
        if source.read_bytes() == (REPO / "softras" / f"{module}.py").read_bytes():
            with open(source, "a", encoding="utf-8") as f:          # a fresh stamp for its kernels
                f.write(f"# mutate.py: kernels recompiled for the mutation {mutation_name}\n")
        old_stamp = numba_source_stamp(REPO / "softras" / f"{module}.py")
        new_stamp = numba_source_stamp(source)
        folder = Path(module).parent
        src_cache, dst_cache = REPO / "softras" / folder / "__pycache__", tree / "softras" / folder / "__pycache__"
        dst_cache.mkdir(exist_ok=True)
        hit = {k.cache_base for k in reached if k.module == module}
        for kernel in graph.modules[module].kernels:
            base = kernel.cache_base
            index = dst_cache / f"{base}.nbi"
            if base in hit:                               # compiled in the copy, for this mutation
                try:
                    fresh = index.exists() and _read_index(index)[1] == new_stamp
                except Exception:
                    fresh = False
                if fresh:
                    stats["kept"] += 1
                else:
                    for p in _cache_files(dst_cache, base):
                        p.unlink()
                    stats["compile"] += 1
                continue
            for p in _cache_files(dst_cache, base):
                p.unlink()
            for p in _cache_files(src_cache, base):
                shutil.copy2(p, dst_cache / p.name)
            if index.exists() and _restamp(index, old_stamp, new_stamp):
                stats["restamped"] += 1
    return stats


# ----------------------------------------------------------------------------- the copy


def _same(src: os.stat_result, dst: Path) -> bool:
    try:
        st = dst.lstat()
    except FileNotFoundError:
        return False
    return st.st_size == src.st_size and st.st_mtime_ns == src.st_mtime_ns


def sync_tree(repo: Path, dst: Path, own_caches: set[str]) -> None:
    """Make ``dst`` a copy of ``repo`` (files with their modification times,
    __pycache__ included); a file is copied only when its size or mtime
    differs, and files the repository no longer has are removed. numba cache
    files of the modules in ``own_caches`` are left to `prepare_caches`."""
    wanted: set[Path] = set()
    dst.mkdir(parents=True, exist_ok=True)
    for directory, dirs, files in os.walk(repo):
        here = Path(directory)
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and not d.endswith(".egg-info")
                   and not (here / d).resolve() == dst.resolve()]
        rel = here.relative_to(repo)
        pycache = here.name == "__pycache__"
        (dst / rel).mkdir(parents=True, exist_ok=True)
        for name in files:
            if (pycache and name.endswith(NUMBA_CACHE_SUFFIXES) and rel.parts[:1] == ("softras",)
                    and (Path(*rel.parts[1:-1]) / name.split(".", 1)[0]).as_posix() in own_caches):
                continue
            src = here / name
            st = src.stat()
            target = dst / rel / name
            wanted.add(rel / name)
            if not _same(st, target):
                if target.is_symlink() or target.exists():
                    target.unlink()
                shutil.copy2(src, target)
    for directory, dirs, files in os.walk(dst):
        here = Path(directory)
        rel = here.relative_to(dst)
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and d != "__pycache__"
                   and not (here / d).is_symlink()]
        for name in files:
            if (rel / name) not in wanted and not (here / name).is_symlink():
                (here / name).unlink()
    link = dst / "glref" / "shaders"
    if (dst / "glref").is_dir() and (dst / "shaders").is_dir() and not (repo / "glref" / "shaders").exists():
        if not link.is_symlink():
            if link.exists():
                shutil.rmtree(link)
            link.symlink_to(Path("..") / "shaders")


def prepare_copy(mutation: Mutation | None, workdir: Path) -> tuple[Path, dict]:
    """The work tree of a mutation (None: the unmutated baseline), synced and
    mutated, and what `prepare_caches` did."""
    tree = workdir / (mutation.name if mutation else "_baseline") / "tree"
    if mutation is None:
        sync_tree(REPO, tree, set())
        return tree, {}
    reached = reached_kernels(mutation)
    modules = {k.module for k in reached} | {module_key(REPO / e.path) for e in mutation.edits
                                             if e.path.startswith("softras/") and e.path.endswith(".py")}
    sync_tree(REPO, tree, modules)
    apply_edits(mutation, tree)
    stats = prepare_caches(tree, sorted(modules), reached, mutation.name)
    stats["kernels"] = sorted(f"{k.module}.{k.qualname}" for k in reached)
    return tree, stats


# ----------------------------------------------------------------------------- running the suite


@dataclass
class Result:
    name: str
    stage: str
    where: str
    what: str
    outcome: str                  # caught, NOT CAUGHT, timeout, error (collection / crash), baseline
    returncode: int | None
    failing: list[str] = field(default_factory=list)
    seconds: float = 0.0
    tests: str = "full"
    tail: str = ""
    caches: dict = field(default_factory=dict)   # kernels recompiled for it, cache files restamped
    gl_outcome: str | None = None                # shared code: the outcome of the GL-facing tests alone
    gl_failing: list[str] = field(default_factory=list)

    @property
    def caught(self) -> bool:
        """A test fails; for code both renderers share, a GL-facing test (``-m gl``) too."""
        return self.outcome in ("caught", "error") and self.gl_outcome in (None, "caught", "error")


_FAILED_RE = re.compile(r"^(FAILED|ERROR) (\S+)", re.MULTILINE)


def run_suite(tree: Path, tests: list[str], maxfail: int, timeout: float) -> tuple[int | None, str, float]:
    """pytest in ``tree`` with ``tree`` first on the path; (returncode or None on
    timeout, output, seconds)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env.pop("NUMBA_CACHE_DIR", None)            # numba's caches in the copy's __pycache__
    env.pop("NUMBA_DISABLE_JIT", None)
    command = PYTEST + [f"--maxfail={maxfail}"] + tests
    start = time.monotonic()
    proc = subprocess.Popen(command, cwd=tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)     # the pytest we started and its children
        out, _ = proc.communicate()
        code = None
    return code, out, time.monotonic() - start


def _outcome(code: int | None, failing: list[str]) -> str:
    if code is None:
        return "timeout"
    if code == 0:
        return "NOT CAUGHT"
    if code == 1 and failing:
        return "caught"
    return "error"                              # interrupted, collection error, crash (a catch too)


def run_mutation(mutation: Mutation | None, workdir: Path, quick: bool, maxfail: int, timeout: float,
                 gl_check: bool = True) -> Result:
    """Copy, mutate, run the suite (or the declared tests); for a mutation of
    shared code also the GL-facing tests alone (``-m gl``, the ``gl`` marker)."""
    tree, caches = prepare_copy(mutation, workdir)
    tests = list(mutation.quick) if (quick and mutation) else []
    tests = [t for t in tests if (tree / t.split("::")[0]).exists()]
    code, out, seconds = run_suite(tree, tests, maxfail, timeout)
    failing = list(dict.fromkeys(m[1] for m in _FAILED_RE.findall(out)))
    outcome = _outcome(code, failing)
    gl_outcome, gl_failing = None, []
    if mutation is not None and mutation.where == "shared" and gl_check:
        gl_code, gl_out, gl_seconds = run_suite(tree, ["-m", "gl"] + tests, maxfail, timeout)
        gl_failing = list(dict.fromkeys(m[1] for m in _FAILED_RE.findall(gl_out)))
        gl_outcome = _outcome(gl_code, gl_failing)
        seconds += gl_seconds
    if mutation is None:
        name, stage, where, what = "(baseline)", "-", "-", "the unmutated copy"
    else:
        name, stage, where, what = mutation.name, mutation.stage, mutation.where, mutation.what
    summary = [line for line in out.splitlines() if line.strip()]
    return Result(name, stage, where, what, outcome, code, failing, round(seconds, 1),
                  "quick" if tests else "full", "\n".join(summary[-15:]), caches, gl_outcome, gl_failing)


# ----------------------------------------------------------------------------- reporting


def _short(test_id: str) -> str:
    return test_id.replace("tests/", "", 1)


def _names(failing: list[str], n_names: int) -> str:
    names = ", ".join(f"`{_short(t)}`" for t in failing[:n_names])
    if len(failing) > n_names:
        names += f" (+{len(failing) - n_names})"
    return names


def markdown_table(results: list[Result], n_names: int = 3) -> str:
    """One row per mutation: the failing tests (up to ``--maxfail`` are run)
    and, for shared code, the first GL-facing test that fails (``-m gl``)."""
    lines = ["| mutation | stage | code | what it changes | result | caught by (first failing tests) "
             "| GL-facing catch (shared code) | time |",
             "|---|---|---|---|---|---|---|---|"]
    for r in results:
        names = _names(r.failing, n_names)
        if r.outcome == "error" and not names:
            names = f"(exit status {r.returncode})"
        gl = "-" if r.gl_outcome is None else (
            _names(r.gl_failing, 1) if r.gl_outcome == "caught" else r.gl_outcome)
        result = r.outcome if r.caught or r.outcome != "caught" else "caught, not by GL"
        lines.append(f"| `{r.name}` | {r.stage} | {r.where} | {r.what} | {result} | {names} | {gl} | "
                     f"{r.seconds:.0f} s |")
    return "\n".join(lines)


def default_workdir() -> Path:
    tag = hashlib.sha256(str(REPO).encode()).hexdigest()[:10]
    return Path(tempfile.gettempdir()) / f"softras-mutants-{tag}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", help="comma-separated mutation names")
    parser.add_argument("--list", action="store_true", help="list the mutations (after checking every edit applies)")
    parser.add_argument("--quick", action="store_true", help="run each mutation's declared test files only")
    parser.add_argument("--json", type=Path, help="write the results as JSON")
    parser.add_argument("--markdown", type=Path, help="write the Markdown table")
    parser.add_argument("--jobs", type=int, default=1, help="mutations run at once (default 1)")
    parser.add_argument("--maxfail", type=int, default=3, help="stop a mutation's suite after N failing tests")
    parser.add_argument("--timeout", type=float, default=1500.0, help="seconds per suite run (default 1500)")
    parser.add_argument("--workdir", type=Path, default=None, help="where the copies live (kept between runs)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the run of the unmutated copy")
    parser.add_argument("--no-gl-check", action="store_true",
                        help="do not run the GL-facing tests alone for mutations of shared code")
    args = parser.parse_args(argv)

    try:
        check_mutations()
    except HarnessError as exc:
        print(f"mutate: {exc}", file=sys.stderr)
        return 2
    mutations = list(MUTATIONS)
    if args.only:
        wanted = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = sorted(set(wanted) - {m.name for m in mutations})
        if unknown:
            print(f"mutate: unknown mutation(s) {', '.join(unknown)}", file=sys.stderr)
            return 2
        mutations = [m for m in mutations if m.name in wanted]
    if args.list:
        for m in mutations:
            files = ", ".join(sorted({e.path for e in m.edits}))
            print(f"{m.name:36s} {m.stage:18s} {m.where:10s} {files}: {m.what}")
        print(f"{len(mutations)} mutations, every edit applies")
        return 0

    workdir = (args.workdir or default_workdir()).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    print(f"mutate: {len(mutations)} mutations, work folder {workdir}, "
          f"{'quick (declared tests)' if args.quick else 'the full default suite'}", flush=True)
    start = time.monotonic()
    results: list[Result] = []
    if not args.no_baseline:
        baseline = run_mutation(None, workdir, False, args.maxfail, args.timeout)
        print(f"  baseline: {baseline.outcome} in {baseline.seconds:.0f} s", flush=True)
        if baseline.outcome != "NOT CAUGHT":
            print(f"mutate: the unmutated copy does not pass ({baseline.outcome}):\n{baseline.tail}", file=sys.stderr)
            return 2
        baseline.outcome = "passes"
        results.append(baseline)

    def one(mutation):
        result = run_mutation(mutation, workdir, args.quick, args.maxfail, args.timeout, not args.no_gl_check)
        first = _short(result.failing[0]) if result.failing else ""
        gl = "" if result.gl_outcome is None else (
            f"; GL-facing: {_short(result.gl_failing[0]) if result.gl_failing else result.gl_outcome}")
        print(f"  {mutation.name}: {result.outcome} in {result.seconds:.0f} s {first}{gl}", flush=True)
        return result

    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results += list(pool.map(one, mutations))

    table = markdown_table(results)
    missed = [r for r in results if r.name != "(baseline)" and not r.caught]
    caught = sum(1 for r in results if r.name != "(baseline)" and r.caught)
    print()
    print(table)
    print()
    print(f"{caught} of {len(mutations)} mutations caught"
          + (f"; NOT caught: {', '.join(r.name for r in missed)}" if missed else "")
          + f" ({time.monotonic() - start:.0f} s)")
    if args.markdown:
        args.markdown.write_text(table + "\n", encoding="utf-8")
    if args.json:
        args.json.write_text(json.dumps({"mode": "quick" if args.quick else "full",
                                         "seconds": round(time.monotonic() - start, 1),
                                         "results": [asdict(r) for r in results]}, indent=2) + "\n",
                             encoding="utf-8")
    return 0 if not missed else 1


if __name__ == "__main__":
    sys.exit(main())
