"""The software pipeline: a Scene through every stage to an image.

vertex -> clip -> setup -> rasterize -> interpolate -> fragment -> ops,
once per draw, in the scene's draw order.  Each stage is a module of pure
functions on arrays; this module only wires them together and keeps the
framebuffer.
"""

from __future__ import annotations

import numpy as np

from . import clip as clip_stage
from . import fragment, interpolate, lines, ops, rasterize, setup, texture, vertex
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
                 clipping: str | None = None, texture_fixed_point: bool = True) -> np.ndarray:
    """Render a loaded scene; returns (H, W, 4) uint8, row 0 = top.

    precision : "gl" (llvmpipe's fixed point, float32 vertex math, RGBA8 and
        24-bit depth rounding) or "exact" (float64 throughout, no snapping).
    samples : overrides ``scene.samples``.
    clipping : "llvmpipe" (default in gl) or "guard_band" (default in exact).
    texture_fixed_point : gl precision: filter RGBA8 textures with repeat /
        clamp_to_edge wrapping in llvmpipe's 8.8 fixed point, as llvmpipe does
        by default; False = float weights, as llvmpipe with
        ``GALLIVM_PERF=no_aos_sampling`` (see `softras.texture`).
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
        mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
        clip_pos = vertex.to_clip(mesh.positions, mvp, precision)
        vertex_colors = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
        if mesh.primitive == "lines":
            if draw.material.texture is not None or draw.material.shading != "unlit":
                raise NotImplementedError(f"{draw.path}: softras draws lines unlit and untextured only")
            lf = lines.line_fragments(clip_pos, mesh.indices, width, height, values=vertex_colors,
                                      precision=precision,
                                      sample_positions=positions, policy=policy)
            if len(lf):
                f = lf.fragments
                ops.apply_fragments(f.x, f.y, f.mask, ops.quantize_depth(lf.z) if gl else lf.z,
                                    fragment.shade_unlit(lf.values, draw.material.color), color, depth,
                                    ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                                    ops.BLEND_MODES[draw.blend], gl)
            continue
        clipped = clip_stage.clip_triangles(clip_pos, mesh.indices, precision=precision,
                                            policy=policy, width=width, height=height)
        tris = setup.setup_triangles(clipped.clip, width, height, precision=precision,
                                     cull=draw.cull, offsets=offsets, unit=unit,
                                     generated=clipped.generated)
        frags = rasterize.rasterize(tris, offsets, unit)
        if len(frags) == 0:
            continue

        # Per setup-vertex attributes: clip weights (reordered like the
        # corners) applied to the source triangle's vertex attributes.
        weights = np.take_along_axis(clipped.weights[tris.triangle], tris.corner[..., None], axis=1)
        source = mesh.indices[clipped.source[tris.triangle]]                # (T', 3)

        def corners(values: np.ndarray) -> np.ndarray:
            """(N, K) per-vertex values -> (T', 3, K) at the set-up triangles' corners."""
            return np.einsum("tkj,tjc->tkc", weights, values[source])

        material = draw.material
        base = vertex_colors * material.color                  # straight, per vertex
        shading = material.shading
        if shading != "unlit":
            world = vertex.world_positions(mesh.positions, draw.world)
            eye = np.linalg.inv(scene.camera.view)[:3, 3]
        if shading == "gouraud":
            lit = fragment.blinn_phong(base[:, :3], world, vertex.world_normals(mesh.normals, draw.world),
                                       eye, scene.lights, material)
            base = np.concatenate([lit, base[:, 3:]], axis=1)

        t = frags.tri
        centres = np.stack([frags.x + 0.5, frags.y + 0.5], axis=1)
        lam = interpolate.barycentric(tris.window[t, :, :2], centres)
        persp = interpolate.perspective_weights(lam, tris.inv_w[t])
        z = interpolate.depth_at_samples(tris.window[t], frags.x, frags.y, positions)
        if gl:
            z = ops.quantize_depth(z)
        if shading == "flat":
            # One colour per source triangle: face normal, centroid, provoking (last) vertex.
            normal = fragment.face_normals(world, source)
            centroid = world[source].mean(axis=1)
            face_base = base[source[:, 2]]
            lit = fragment.blinn_phong(face_base[:, :3], centroid, normal, eye, scene.lights, material)
            colors = np.concatenate([lit, face_base[:, 3:]], axis=1)[t]
        elif shading == "phong":
            colors = interpolate.interpolate(persp, corners(base)[t])
            position = interpolate.interpolate(persp, corners(world)[t])
            world_normals = vertex.world_normals(mesh.normals, draw.world, unit=False)
            normal = interpolate.interpolate(persp, corners(world_normals)[t])
            normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
            lit = fragment.blinn_phong(colors[:, :3], position, normal, eye, scene.lights, material)
            colors = np.concatenate([lit, colors[:, 3:]], axis=1)
        else:
            colors = interpolate.interpolate(persp, corners(base)[t])
        texel = None
        if material.texture is not None:
            tex = texture.prepare(scene.textures[material.texture])
            uvs = mesh.uvs.astype(np.float32).astype(np.float64) if gl else mesh.uvs
            corner_uv = corners(uvs)
            st = interpolate.interpolate(persp, corner_uv[t])
            if gl:
                ddx, ddy = interpolate.quad_derivatives(tris.window[t], tris.inv_w[t], frags.x, frags.y,
                                                        corner_uv[t])
            else:
                ddx, ddy = interpolate.analytic_derivatives(tris.window[t], tris.inv_w[t], centres,
                                                            corner_uv[t])
            texel = texture.sample(tex, st, ddx, ddy, precision, texture_fixed_point)
        rgba = fragment.shade_unlit(colors, np.ones(4), texel)
        ops.apply_fragments(frags.x, frags.y, frags.mask, z, rgba, color, depth,
                            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                            ops.BLEND_MODES[draw.blend], gl)
    return ops.resolve(color)
