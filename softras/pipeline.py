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


def _perspective_at(tris, t: np.ndarray, corner_values: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Perspective-correct attribute of triangles ``t`` at window points (F, 2),
    inside the triangle or not (the planes are simply extended)."""
    lam = interpolate.barycentric(tris.window[t, :, :2], points)
    return interpolate.interpolate(interpolate.perspective_weights(lam, tris.inv_w[t]), corner_values[t])


def quad_derivatives(tris, t: np.ndarray, x: np.ndarray, y: np.ndarray,
                     corner_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Screen-space derivatives per 2x2 quad, as GL implementations take them.

    The quad of pixel (x, y) has its top-left (in llvmpipe's view; GL's
    lower-left) pixel TL at (x & ~1, y & ~1).  The attribute is evaluated at
    the pixel centres of TL, TR = TL + (1, 0) and BL = TL + (0, 1) from the
    triangle's planes, whether those pixels are covered or not (helper
    pixels), rounded to float32 like a shader's values, and
    ``ddx = TR - TL``, ``ddy = BL - TL``.  Every pixel of a quad gets the same
    derivatives.  Returns (F, K) each.
    """
    qx = (x & ~1).astype(np.float64) + 0.5
    qy = (y & ~1).astype(np.float64) + 0.5
    tl = _perspective_at(tris, t, corner_values, np.stack([qx, qy], axis=1)).astype(np.float32)
    tr = _perspective_at(tris, t, corner_values, np.stack([qx + 1, qy], axis=1)).astype(np.float32)
    bl = _perspective_at(tris, t, corner_values, np.stack([qx, qy + 1], axis=1)).astype(np.float32)
    return (tr - tl).astype(np.float64), (bl - tl).astype(np.float64)


def analytic_derivatives(tris, t: np.ndarray, points: np.ndarray,
                         corner_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact screen-space derivatives of a perspective-correct attribute at points.

    With q_i = lam_i / w_i (lam the screen-space barycentrics, affine in x and
    y) and Q = sum q_i, the attribute is a = sum q_i a_i / Q, so
    ``da/dx = (sum dq_i/dx a_i - a dQ/dx) / Q``.  Returns (F, K) each.
    """
    vertices = tris.window[t, :, :2]
    inv_w = tris.inv_w[t]
    lam = interpolate.barycentric(vertices, points)
    q = lam * inv_w
    big_q = q.sum(axis=1, keepdims=True)
    values = corner_values[t]
    a = np.einsum("fi,fik->fk", q, values) / big_q
    out = []
    for step in ((1.0, 0.0), (0.0, 1.0)):
        dlam = interpolate.barycentric(vertices, points + np.array(step)) - lam   # affine: exact step
        dq = dlam * inv_w
        da = (np.einsum("fi,fik->fk", dq, values) - a * dq.sum(axis=1, keepdims=True)) / big_q
        out.append(da)
    return out[0], out[1]


def _world_positions(positions: np.ndarray, world: np.ndarray) -> np.ndarray:
    """(N, 3) model positions -> world positions."""
    return positions @ world[:3, :3].T + world[:3, 3]


def _world_normals(normals: np.ndarray, world: np.ndarray, unit: bool = True) -> np.ndarray:
    """(N, 3) model normals -> world normals by the inverse-transpose of the
    world matrix's 3x3 (normalised when ``unit``)."""
    n = normals @ np.linalg.inv(world[:3, :3])           # == (inv(M)^T @ n^T)^T
    return n / np.linalg.norm(n, axis=1, keepdims=True) if unit else n


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
        if mesh.primitive == "lines":
            if draw.material.texture is not None or draw.material.shading != "unlit":
                raise NotImplementedError(f"{draw.path}: softras draws lines unlit and untextured only")
            vertex_colors = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
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

        vertex_colors = mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))
        material = draw.material
        base = vertex_colors * material.color                  # straight, per vertex
        shading = material.shading
        if shading != "unlit":
            world = _world_positions(mesh.positions, draw.world)
            eye = np.linalg.inv(scene.camera.view)[:3, 3]
        if shading == "gouraud":
            lit = fragment.blinn_phong(base[:, :3], world, _world_normals(mesh.normals, draw.world),
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
            faces = mesh.indices[clipped.source[tris.triangle]]                      # (T', 3)
            normal = fragment.face_normals(world, faces)
            centroid = world[faces].mean(axis=1)
            face_base = base[faces[:, 2]]
            lit = fragment.blinn_phong(face_base[:, :3], centroid, normal, eye, scene.lights, material)
            colors = np.concatenate([lit, face_base[:, 3:]], axis=1)[t]
        elif shading == "phong":
            colors = interpolate.interpolate(persp, corners(base)[t])
            position = interpolate.interpolate(persp, corners(world)[t])
            normal = interpolate.interpolate(persp, corners(_world_normals(mesh.normals, draw.world, unit=False))[t])
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
                ddx, ddy = quad_derivatives(tris, t, frags.x, frags.y, corner_uv)
            else:
                ddx, ddy = analytic_derivatives(tris, t, centres, corner_uv)
            texel = texture.sample(tex, st, ddx, ddy, precision, texture_fixed_point)
        rgba = fragment.shade_unlit(colors, np.ones(4), texel)
        ops.apply_fragments(frags.x, frags.y, frags.mask, z, rgba, color, depth,
                            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                            ops.BLEND_MODES[draw.blend], gl)
    return ops.resolve(color)
