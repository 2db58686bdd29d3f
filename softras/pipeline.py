"""The software pipeline: a Scene through every stage to an image.

vertex -> clip -> setup -> rasterize -> interpolate -> fragment -> ops,
once per draw, in the scene's draw order.  Each stage is a module of pure
functions on arrays; this module only wires them together and keeps the
framebuffer.
"""

from __future__ import annotations

import numpy as np

from . import clip as clip_stage
from . import fragment, interpolate, ops, rasterize, setup, vertex
from .scene import Scene

PRECISIONS = ("gl", "exact")

# llvmpipe's 4x MSAA sample positions within a pixel (x, y), GL window space.
MSAA4_POSITIONS = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
CENTER_POSITION = np.array([[0.5, 0.5]])


def sample_positions(samples: int) -> np.ndarray:
    """(S, 2) sample positions in [0, 1)^2 for a GL sample count."""
    if samples == 1:
        return CENTER_POSITION
    if samples == 4:
        return MSAA4_POSITIONS
    raise ValueError(f"samples must be 1 or 4, not {samples}")


def render_scene(scene: Scene, *, precision: str = "gl", samples: int | None = None,
                 clipping: str | None = None) -> np.ndarray:
    """Render a loaded scene; returns (H, W, 4) uint8, row 0 = top.

    precision : "gl" (llvmpipe's fixed point, float32 vertex math, RGBA8 and
        24-bit depth rounding) or "exact" (float64 throughout, no snapping).
    samples : overrides ``scene.samples``.
    clipping : "llvmpipe" (default in gl) or "guard_band" (default in exact).
    """
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {PRECISIONS}, not {precision!r}")
    gl = precision == "gl"
    policy = clipping or ("llvmpipe" if gl else "guard_band")
    positions = sample_positions(samples or scene.samples)
    offsets, unit = setup.sample_offsets(positions, precision)
    width, height = scene.width, scene.height
    color, depth = ops.new_framebuffer(width, height, len(positions), scene.background, quantize=gl)

    for draw in scene.draws:
        mesh = draw.mesh
        if mesh.primitive != "triangles":
            raise NotImplementedError(f"{draw.path}: softras cannot draw {mesh.primitive!r} yet")
        mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
        clip_pos = vertex.to_clip(mesh.positions, mvp, precision)
        clipped = clip_stage.clip_triangles(clip_pos, mesh.indices, precision=precision,
                                            policy=policy, width=width, height=height)
        tris = setup.setup_triangles(clipped.clip, width, height, precision=precision,
                                     cull=draw.cull, offsets=offsets, unit=unit,
                                     generated=clipped.generated)
        frags = rasterize.rasterize(tris, offsets, unit)
        if len(frags) == 0:
            continue

        # Per setup-vertex colours: clip weights (reordered like the corners)
        # applied to the source triangle's vertex colours.
        weights = np.take_along_axis(clipped.weights[tris.triangle], tris.corner[..., None], axis=1)
        source = mesh.indices[clipped.source[tris.triangle]]                # (T', 3)
        vertex_colors = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
        corner_colors = np.einsum("tkj,tjc->tkc", weights, vertex_colors[source])

        t = frags.tri
        centres = np.stack([frags.x + 0.5, frags.y + 0.5], axis=1)
        lam = interpolate.barycentric(tris.window[t, :, :2], centres)
        persp = interpolate.perspective_weights(lam, tris.inv_w[t])
        colors = interpolate.interpolate(persp, corner_colors[t])
        z = interpolate.depth_at_samples(tris.window[t], frags.x, frags.y, positions)
        if gl:
            z = ops.quantize_depth(z)
        rgba = fragment.shade_unlit(colors, draw.material.color)
        ops.apply_fragments(frags.x, frags.y, frags.mask, z, rgba, color, depth,
                            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                            ops.BLEND_MODES[draw.blend], gl)
    return ops.resolve(color)
