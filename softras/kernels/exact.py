"""The compiled path of exact precision: float64 throughout, no snapping.

`softras.pipeline.render` in ``precision="exact"`` shades a draw's fragments
as numpy arrays, ~300 bytes and a few dozen array passes a fragment.  Here
an untextured triangle draw (unlit, flat, Gouraud or Phong; alpha test,
every depth function and blend equation) is rasterized, shaded and applied
by one parallel kernel (`_draw`); its vertex, clip and set-up stages are the
stages' own functions (`softras.pipeline.render.set_up_draw`), and every
other draw (lines, textures, normal and bump maps) is the stages'
(`softras.pipeline.render.draw_lines`, `draw_triangles`) on the same
float64 buffers.  The bytes are the stages' (tests/test_exact_path.py):

- coverage: `softras.pipeline.rasterize._raster_triangle` itself, on the
  triangle's pixel box cut to a band of rows;
- per fragment: `softras.pipeline.interpolate.barycentric`,
  `perspective_weights` (`softras.kernels.interpolate._weights_at`),
  `interpolate` (`_mix`), `depth_at_samples` (`softras.kernels.setup._depth_slopes`), for Phong
  `softras.pipeline.render.phong_attributes` and
  `softras.pipeline.fragment.blinn_phong` (`softras.kernels.light._lit_point`),
  `shade_unlit`, `alpha_test`, each with the stages' operations in their
  order;
- per sample: `softras.pipeline.ops.apply_fragments` without quantizing
  (its own `_depth_pass` and `_blend`).

Bands of `BAND_ROWS` rows are drawn in parallel; each walks the draw's
triangles in order over its own rows, so every pixel sees the fragments in
draw order, as the stages apply them.
"""

from __future__ import annotations

import numba
import numpy as np

from softras.kernels.interpolate import Corners, _corner_colors, _mix, _weights_at
from softras.kernels.light import NO_LIGHTING, _lit_point, _unit, base_colors, flat_corner_colors, scene_lighting
from softras.kernels.setup import _depth_slopes
from softras.kernels.stamp import sources_stamp
from softras.pipeline import ops, rasterize, render as stages, sampling, vertex
from softras.pipeline.rasterize import _raster_triangle
from softras.scene import Scene

# Rows of the picture a thread draws at once.
BAND_ROWS = 16

# Shading codes of `_draw`.
UNLIT, FLAT, PHONG = 0, 1, 2          # (Gouraud is lit per vertex: UNLIT of its lit vertex colours)


def compiled(draw) -> bool:
    """Whether `_draw` draws ``draw``: triangles without texture, normal or
    bump map."""
    material = draw.material
    return (draw.mesh.primitive == "triangles" and material.texture is None and material.normal_map is None
            and material.bump_map is None)


def render_samples(scene: Scene, job: stages.Job) -> np.ndarray:
    """`softras.pipeline.render.render_samples` of an exact-precision job:
    the per-sample colour buffer (H, W, S, 4) float64, premultiplied, GL's
    y-up rows, in the stages' passes of at most 32 samples: the stages'
    `softras.pipeline.render.render_pass`, with `draw_triangles` for the
    triangle draws."""
    if job.precision != "exact":
        raise ValueError("softras.kernels.exact renders exact precision only")
    stages.check_sample_memory(scene, len(job.positions), stages.SAMPLE_BYTES)
    return sampling.in_passes(job.positions, lambda positions: stages.render_pass(
        scene, stages.Pass.of(job, positions), draw_triangles))


def draw_triangles(scene: Scene, draw, inputs: stages.Pass, color: np.ndarray, depth: np.ndarray) -> None:
    """`softras.pipeline.render.draw_triangles` in exact precision: a
    `compiled` draw by the stages' set-up, then `_draw`; any other by the
    stages.  The corner values are the stages'
    (`softras.pipeline.render.corner_values`); Gouraud's vertex lighting and
    flat shading's face colours are the compiled ones of
    `softras.kernels.light` (the same bits)."""
    if not compiled(draw):
        stages.draw_triangles(scene, draw, inputs, color, depth)
        return
    clipped, tris = stages.set_up_draw(scene, draw, inputs)
    if len(tris) == 0:
        return
    mesh, material = draw.mesh, draw.material
    _, corners = stages.corner_values(clipped, tris, mesh)
    base = base_colors(scene, draw)                                    # straight, Gouraud lit
    lit, lights, lighting = np.zeros((1, 3, 6)), *NO_LIGHTING[1:]
    shading = {"flat": FLAT, "phong": PHONG}.get(material.shading, UNLIT)
    if shading == FLAT:                                                # (T', 3, 4): the colour at corner 0
        colors = flat_corner_colors(scene, draw, base, clipped.source[tris.triangle])
    else:
        colors = corners(base)                                         # (T', 3, 4)
    if shading == PHONG:
        world = vertex.world_positions(mesh.positions, draw.world)
        normals = vertex.world_normals(mesh.normals, draw.world, unit=False)
        lit = np.concatenate([corners(world), corners(normals)], axis=2)           # (T', 3, 6)
        lights, lighting = scene_lighting(scene, material)
    cutoff = material.alpha_cutoff
    c = np.ascontiguousarray
    _DRAW(c(tris.window), c(tris.inv_w), c(tris.edge_a), c(tris.edge_b), c(tris.edge_x0), c(tris.edge_y0),
          c(tris.edge_inclusive), c(tris.bbox), c(inputs.offsets, np.float64), float(inputs.unit),
          c(inputs.positions, np.float64), shading, c(colors), c(lit), c(lights), tuple(lighting), color, depth,
          ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write, ops.BLEND_MODES[draw.blend],
          cutoff is not None, float(cutoff or 0.0), BAND_ROWS)


def _make_draw(sources: str):
    """The exact kernel `_draw`, with the cache key ``sources``
    (`softras.kernels.stamp.sources_stamp`) as a closure variable."""

    @numba.njit(cache=True, parallel=True, error_model="numpy")
    def _draw(window, inv_w, edge_a, edge_b, edge_x0, edge_y0, inclusive, bbox, offsets, unit, positions, shading,
              colors, lit, lights, lighting, color, depth, depth_func, depth_write, blend, alpha_test, cutoff,
              band_rows):
        """One `compiled` triangle draw into the float64 buffers color (H, W,
        S, 4) and depth (H, W, S), in bands of ``band_rows`` rows in parallel.

        window (T', 3, 3), inv_w (T', 3), edge_* (T', 3), inclusive (T', 3),
        bbox (T', 4): the `softras.pipeline.setup.TriangleSetup`'s arrays;
        offsets (S, 2) and unit: the raster sample offsets
        (`softras.pipeline.setup.sample_offsets`, exact); positions (S, 2) the
        sample positions in the pixel; shading: UNLIT, FLAT or PHONG; colors
        (T', 3, 4) straight corner colours (FLAT: the face's at corner 0, zeros
        at the others, `softras.kernels.light.flat_corner_colors`);
        lit (T', 3, 6) corner world positions and normals (PHONG); lights and
        lighting: `softras.kernels.light.scene_lighting`; the depth function,
        depth write, blend code, and whether the alpha test with ``cutoff``
        applies.  Fragments outside the triangle's box are never made; each
        covered pixel is shaded once (at its centre) and applied per covered
        sample in order (`softras.pipeline.ops.apply_fragments`)."""
        stamp = sources                 # noqa: F841  (the cache key, `softras.kernels.stamp`)
        height, width = color.shape[0], color.shape[1]
        n_samples = positions.shape[0]
        n_tris = window.shape[0]
        n_bands = (height + band_rows - 1) // band_rows
        write_z = depth_write and depth_func != 0
        for band in numba.prange(n_bands):
            top = band * band_rows
            bottom = min(top + band_rows, height) - 1
            out_x = np.empty(band_rows * width, np.int32)
            out_y = np.empty(band_rows * width, np.int32)
            out_mask = np.empty(band_rows * width, np.uint32)
            box = np.empty(4, np.int64)
            src = np.empty(4)
            out = np.empty(4)
            for t in range(n_tris):
                box[0], box[1] = bbox[t, 0], bbox[t, 1]
                box[2], box[3] = max(bbox[t, 2], top), min(bbox[t, 3], bottom)
                if box[2] > box[3]:
                    continue
                k = _raster_triangle(edge_a[t], edge_b[t], edge_x0[t], edge_y0[t], inclusive[t], box, offsets, unit,
                                     out_x, out_y, out_mask, 0, True)
                # The triangle's values as scalars: corners, depth plane, corner colours,
                # and for Phong its corners' world positions and normals.
                corners = Corners((window[t, 0, 0], window[t, 1, 0], window[t, 2, 0]),
                                  (window[t, 0, 1], window[t, 1, 1], window[t, 2, 1]),
                                  (inv_w[t, 0], inv_w[t, 1], inv_w[t, 2]))
                x0, y0, z0 = window[t, 0, 0], window[t, 0, 1], window[t, 0, 2]
                dzdx, dzdy = _depth_slopes(corners.x, corners.y, (z0, window[t, 1, 2], window[t, 2, 2]))
                cc = _corner_colors(colors, t)
                position = normal = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
                if shading == PHONG:
                    position = ((lit[t, 0, 0], lit[t, 1, 0], lit[t, 2, 0]), (lit[t, 0, 1], lit[t, 1, 1], lit[t, 2, 1]),
                                (lit[t, 0, 2], lit[t, 1, 2], lit[t, 2, 2]))
                    normal = ((lit[t, 0, 3], lit[t, 1, 3], lit[t, 2, 3]), (lit[t, 0, 4], lit[t, 1, 4], lit[t, 2, 4]),
                              (lit[t, 0, 5], lit[t, 1, 5], lit[t, 2, 5]))
                for f in range(k):
                    px, py, mask = out_x[f], out_y[f], out_mask[f]
                    # (A flat colour is corner 0's: 1 c + 0 0 + 0 0 is c.)
                    w = (1.0, 0.0, 0.0) if shading == FLAT else _weights_at(corners, px + 0.5, py + 0.5)
                    r, g, b, a = _mix(w, cc.r), _mix(w, cc.g), _mix(w, cc.b), _mix(w, cc.a)
                    if shading == PHONG:
                        nx, ny, nz = _unit(_mix(w, normal[0]), _mix(w, normal[1]), _mix(w, normal[2]))
                        r, g, b = _lit_point(r, g, b, _mix(w, position[0]), _mix(w, position[1]), _mix(w, position[2]),
                                             nx, ny, nz, lights, lighting)
                    # `softras.pipeline.fragment.shade_unlit`: premultiplied (the
                    # material colour it multiplies by is ones: the values stay).
                    src[0], src[1], src[2], src[3] = r * a, g * a, b * a, a
                    if alpha_test and a < cutoff:       # (`softras.pipeline.fragment.alpha_test`: NaN kept)
                        continue
                    for s in range(n_samples):
                        if not (mask >> s) & 1:
                            continue
                        # `softras.pipeline.interpolate.depth_at_samples`, from corner 0
                        z = z0 + dzdx * ((px + positions[s, 0]) - x0) + dzdy * ((py + positions[s, 1]) - y0)
                        if not ops._depth_pass(depth_func, z, depth[py, px, s]):
                            continue
                        if write_z:
                            depth[py, px, s] = z
                        ops._blend(blend, src, color[py, px, s], out)
                        for ch in range(4):
                            color[py, px, s, ch] = out[ch]

    return _draw


# The kernel, keyed on the kernels' sources and the stages' it calls.
_DRAW = _make_draw(sources_stamp(rasterize, ops))
