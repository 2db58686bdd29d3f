"""Lines on the compiled path: the per-fragment work of a GL_LINES draw.

Mirrors what `softras.pipeline.render._render_pass` does with a line draw's
fragments in gl precision, operation for operation:
`softras.pipeline.lines.depth_at_samples` (depth at each sample, linear in
the line's t) and `softras.pipeline.ops.quantize_depth`,
`softras.pipeline.lines.interpolate_lines` (the colour, perspective-correct
in t) and `softras.pipeline.fragment.shade_unlit` as
`softras.pipeline.ops.unorm8` converts it, then
`softras.pipeline.ops.apply_fragments`' depth test, blend and write into the
compiled path's byte framebuffer (`softras.kernels.ops`).  Clipping, set-up
and coverage are the stages' own (`softras.pipeline.lines.rasterized_lines`,
compiled there already): a line's fragments are few (about one per pixel of
its length), so their list is kept, and what this module saves is the
stages' float framebuffer and their per-fragment numpy arrays.

The fragments are applied one by one in the stages' order (line order,
rows within a line), so blending and equal depths resolve as there.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from softras.kernels.interpolate import RGBA, _color_word
from softras.kernels.ops import _depth_k, _depth_pass_k, _write_word
from softras.pipeline import lines as lines_stage
from softras.pipeline import ops, vertex
from softras.pipeline.render import vertex_colors


def draw_lines(scene, draw, fb, positions: np.ndarray) -> None:
    """One GL_LINES draw into the byte framebuffer `softras.kernels.ops.Framebuffer`
    fb at the sample positions (S, 2) in [0, 1) (GL's: S > 1 draws
    llvmpipe's rectangular lines, `softras.pipeline.lines`)."""
    mesh = draw.mesh
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    clip_pos = vertex.to_clip(mesh.positions, mvp, "gl")
    frags, t, window, inv_w, ends = lines_stage.rasterized_lines(
        clip_pos, mesh.indices, scene.width, scene.height, values=vertex_colors(mesh), precision="gl",
        sample_positions=positions, policy="llvmpipe")
    if len(frags) == 0:
        return
    rectangular = len(positions) > 1
    depth_func = ops.DEPTH_FUNCS[draw.depth_test]
    _apply_lines(frags.x, frags.y, frags.mask, frags.tri, t, np.ascontiguousarray(window), np.ascontiguousarray(inv_w),
                 np.ascontiguousarray(ends), np.asarray(draw.material.color, np.float64), positions,
                 lines_stage.attribute_shift("gl", rectangular), rectangular, fb.color32, fb.depth, depth_func,
                 bool(draw.depth_write) and depth_func != 0, ops.BLEND_MODES[draw.blend])


@numba.njit(cache=True, error_model="numpy")
def _apply_lines(x, y, mask, line, t, window, inv_w, ends, material, positions, shift, rectangular, color32, depth,
                 depth_func, write_z, blend):
    """Depth-test, shade and write line fragments in order.

    x, y, mask, line : (F,) the fragments (`softras.pipeline.rasterize.Fragments`,
    ``tri`` the clipped line); t : (F,) their attribute parameter; window
    (L, 2, 3) float32 values, inv_w (L, 2), ends (L, 2, 4) straight colours:
    per clipped line, its end points (`softras.pipeline.lines.rasterized_lines`);
    material (4,) its colour; positions (S, 2); shift :
    `softras.pipeline.lines.attribute_shift`; color32, depth : the byte
    framebuffer (`softras.kernels.ops`); the draw's depth function, depth
    write and blend codes."""
    n_samples = positions.shape[0]
    white = RGBA(1.0, 1.0, 1.0, 1.0)
    for f in range(x.shape[0]):
        i, px, py = line[f], x[f], y[f]
        # depth_at_samples: t at each sample (the projection onto the line,
        # or along the major axis in float32), not finite -> 0, z linear in t.
        x0, y0, z0 = window[i, 0, 0], window[i, 0, 1], window[i, 0, 2]
        dx, dy, dz = window[i, 1, 0] - x0, window[i, 1, 1] - y0, window[i, 1, 2] - z0
        x_major = abs(np.float32(dx)) >= abs(np.float32(dy))
        passed = 0
        for s in range(n_samples):
            if not (mask[f] >> s) & 1:
                continue
            sx = (px + positions[s, 0]) + shift
            sy = (py + positions[s, 1]) + shift
            if rectangular:
                ts = ((sx - x0) * dx + (sy - y0) * dy) / (dx * dx + dy * dy)
            elif x_major:
                ts = (sx - x0) / dx
            else:
                ts = (sy - y0) / dy
            k = _depth_k(z0 + (ts if math.isfinite(ts) else 0.0) * dz)
            stored = depth[py, px, s]
            if _depth_pass_k(depth_func, k, stored):
                if write_z:
                    depth[py, px, s] = k
                passed |= 1 << s
        if passed == 0:
            continue
        # interpolate_lines, then shade_unlit's (vertex x material), premultiplied, as bytes.
        q0 = (1.0 - t[f]) * inv_w[i, 0]
        q1 = t[f] * inv_w[i, 1]
        total = q0 + q1
        b0, b1 = q0 / total, q1 / total
        word = _color_word((b0 * ends[i, 0, 0] + b1 * ends[i, 1, 0]) * material[0],
                           (b0 * ends[i, 0, 1] + b1 * ends[i, 1, 1]) * material[1],
                           (b0 * ends[i, 0, 2] + b1 * ends[i, 1, 2]) * material[2],
                           (b0 * ends[i, 0, 3] + b1 * ends[i, 1, 3]) * material[3], white)
        _write_word(color32, py, px, passed, n_samples, blend, word)
