"""A pixel's history: every stage of the pipeline, for one pixel.

``explain_pixel(scene, x, y)`` re-runs the software pipeline for one pixel
with the stage modules' own functions, in the order and with the arguments
`softras.renderer.render_scene` uses (its general path), and records what
each stage did there:

- every draw that reached the pixel, and in it every triangle (or line) that
  covered one of its samples -- and the triangles whose bounding box holds the
  pixel but that covered none of its samples, or that face culling removed;
- the triangle's source index, whether the clipper cut it, its vertices in
  clip, window and raster space, its three edge functions, and per sample the
  edge function values and the coverage decision (with the fill rule on a
  tie);
- barycentrics, perspective-correct weights, depth per sample;
- texture coordinates, derivatives, the level of detail, the mip level(s),
  the texels read and their filter weights;
- shading terms (ambient, diffuse and specular per light);
- the fragment colour (premultiplied), and per sample the depth test (value in
  the buffer before, function, passed, written) and the blend (source,
  destination, result as stored);
- the final resolved value, which is the value the renderer writes for this
  pixel (the tests assert that it equals the rendered image's pixel).

Only the rasterizer is restricted to the pixel: every triangle whose bounding
box holds the pixel is rasterized by `softras.pipeline.rasterize.rasterize` with its
box shrunk to that one pixel (the block tests are exact, so the coverage is
the same as in the full rendering).  The per-sample operations run
`softras.pipeline.ops.apply_fragments` on a 1 x 1 framebuffer that starts cleared to
the scene's background, one fragment at a time, so the values before and
after each fragment can be read.  Lines are rasterized whole with
`softras.pipeline.lines.rasterize_lines` and filtered to the pixel.

Coordinates.  The user's pixel (x, y) is in IMAGE coordinates, as the PNG is
seen: column x from the left, row y from the TOP.  GL's window coordinates
have y up: the same pixel is (x, H - 1 - y) there, with its centre at
(x + 0.5, H - 1 - y + 0.5).  Both are reported.

The history is a dict of plain Python values (JSON-able); `format_text`
turns it into the readable report printed by ``softras explain``.

Why one module of ~810 lines: it retraces every stage for one pixel and
formats each stage's record; one section per stage keeps the history in
pipeline order and next to the text that prints it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math

import numba
import numpy as np

from softras.pipeline import clip as clip_stage
from softras.pipeline import fragment, interpolate, lines, ops, render as pipeline, rasterize, setup, texture, vertex
from softras.scene import Scene, load_scene, ordered_draws

__all__ = ["explain_pixel", "check_pixel", "format_text", "gl_pixel", "parse_pixel"]

DEPTH_NAMES = {code: name for name, code in ops.DEPTH_FUNCS.items()}


# ----------------------------------------------------------------------------- helpers


def _py(value):
    """numpy scalars and arrays -> plain Python values (JSON-able)."""
    if isinstance(value, dict):
        return {str(k): _py(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_py(v) for v in value]
    if isinstance(value, np.ndarray):
        return _py(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def parse_pixel(text: str) -> tuple[int, int]:
    """"X,Y" -> (x, y) integers; ValueError with a one-line message otherwise."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        x, y = (int(p.strip()) for p in parts)
    except ValueError:
        raise ValueError(f"--pixel {text!r}: expected two integers X,Y "
                         "(image column, row from the top)") from None
    return x, y


@contextlib.contextmanager
def _one_thread():
    """Run numba's parallel kernels on one thread: for one pixel a parallel
    launch costs far more than the work (on a busy 2-core machine ~90 ms
    against 0.02 ms per `rasterize.rasterize` call).  The results do not
    depend on the thread count; the caller's setting is restored."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def check_pixel(scene: Scene, x: int, y: int) -> None:
    """ValueError (one line) unless image pixel (x, y) lies in the scene's image."""
    width, height = scene.width, scene.height
    if not (0 <= x < width and 0 <= y < height):
        raise ValueError(f"pixel ({x}, {y}) is outside the {width}x{height} image "
                         f"(x in 0..{width - 1}, y in 0..{height - 1}, row 0 = top)")


def _restrict(tris: setup.TriangleSetup, keep: np.ndarray, wx: int, wy: int) -> setup.TriangleSetup:
    """The set-up triangles ``keep`` (K,) with their bounding boxes shrunk to pixel (wx, wy)."""
    fields = {f.name: getattr(tris, f.name)[keep] for f in dataclasses.fields(tris)}
    fields["bbox"] = np.tile(np.array([wx, wx, wy, wy], np.int64), (len(keep), 1))
    return setup.TriangleSetup(**fields)


def _edge_kind(a, b) -> str:
    """Name an edge by the fill rule (GL's y-up window space)."""
    if a > 0:
        return "left"
    if a < 0:
        return "right"
    return "bottom" if b > 0 else "top"


def _coverage_decision(values, inclusive) -> tuple[bool, str]:
    """Coverage of one sample from its three edge function values, and why."""
    outside = [i for i in range(3) if values[i] < 0]
    if outside:
        return False, "outside edge " + ", ".join(f"e{i}" for i in outside)
    ties = [i for i in range(3) if values[i] == 0]
    if not ties:
        return True, "inside (every E > 0)"
    excluded = [i for i in ties if not inclusive[i]]
    names = ", ".join(f"e{i} ({'inclusive' if inclusive[i] else 'exclusive'})" for i in ties)
    if excluded:
        return False, f"tie: E = 0 on {names} -> fill rule says out"
    return True, f"tie: E = 0 on {names} -> fill rule says in"


# ----------------------------------------------------------------------------- shading terms


def _lighting_terms(base_rgb, position, normal, eye, lights, material) -> dict:
    """The Blinn-Phong terms at one point, each computed by `fragment.blinn_phong`.

    base_rgb, position, normal : (3,) world space; the ambient term and each
    light's diffuse and specular terms are blinn_phong with the other
    coefficients set to zero and that light alone (so the terms are exactly
    what the full call adds up).
    """
    def term(light_list, **zeroed):
        changed = dataclasses.replace(material, **zeroed)
        return fragment.blinn_phong(base_rgb[None], position[None], normal[None], eye, light_list,
                                    changed)[0]

    ambient = term((), diffuse=0.0, specular=0.0)
    view = eye - position
    view = view / np.linalg.norm(view)
    per_light = []
    for index, (vector, light) in enumerate(zip(fragment.light_vectors(lights), lights)):
        to_light = vector[:3] - position * vector[3]
        to_light = to_light / np.linalg.norm(to_light)
        half = to_light + view
        half = half / np.linalg.norm(half)
        per_light.append({
            "light": index, "type": light.type, "color": light.color,
            "L": to_light, "H": half,
            "N_dot_L": float(normal @ to_light), "N_dot_H": float(normal @ half),
            "diffuse": term((light,), ambient=0.0, specular=0.0),
            "specular": term((light,), ambient=0.0, diffuse=0.0),
        })
    return {"position": position, "normal": normal, "eye": eye, "V": view, "base_rgb": base_rgb,
            "ambient_coefficient": material.ambient, "diffuse_coefficient": material.diffuse,
            "specular_coefficient": material.specular, "shininess": material.shininess,
            "ambient": ambient, "lights": per_light,
            "lit_rgb": fragment.blinn_phong(base_rgb[None], position[None], normal[None], eye,
                                            lights, material)[0]}


# ----------------------------------------------------------------------------- texture


def _texture_history(tex: texture.MipTexture, st, ddx, ddy, precision: str, fixed_point: bool,
                     texel) -> dict:
    """What `texture.sample` does for one fragment, step by step, with its helpers.

    st, ddx, ddy : (1, 2) as passed to `texture.sample`; texel : (4,) its result.
    """
    gl = precision == "gl"
    common = {"name": tex.name, "size": tex.size, "levels": len(tex.used_levels),
              "wrap": [tex.wrap_s, tex.wrap_t], "min_filter": tex.min_filter, "mag_filter": tex.mag_filter,
              "st": st[0], "ddx": ddx[0], "ddy": ddy[0], "result": texel}
    if texture.effective_anisotropy(tex.max_anisotropy, gl) > 1:
        # texture.sample hands over to the anisotropic filter: no per-texel breakdown here.
        return dict(common, anisotropic=tex.max_anisotropy, mip=[])
    du, dv = texture.texel_derivatives(ddx, ddy, tex.size, gl)
    rho2 = texture.rho_squared(du, dv)
    levels = tex.used_levels
    choice = texture.choose_levels(rho2, tex.min_filter, len(levels), gl)
    fixed8 = fixed_point and texture.uses_fixed_point(tex, gl)
    magnified = bool(choice.magnified[0])
    image_filter = tex.mag_filter if magnified else tex.min_filter.split("_")[0]
    level0 = 0 if magnified else int(choice.level0[0])
    blend = (not magnified) and int(choice.level1[0]) != int(choice.level0[0]) and choice.frac[0] > 0
    r2 = float(rho2[0])
    out = dict(common, **{
        "texel_ddx": np.asarray(du[0], np.float64), "texel_ddy": np.asarray(dv[0], np.float64),
        "rho2": r2, "lambda": 0.5 * math.log2(r2) if r2 > 0 else -math.inf,
        "magnified": magnified, "filter": image_filter, "fixed_point": fixed8,
    })
    if gl and tex.mipmapped and not tex.min_filter.endswith("mipmap_nearest"):
        # llvmpipe's piecewise-linear log2, which choose_levels uses in gl precision.
        out["lambda_llvmpipe"] = float(np.float32(0.5) * texture.fast_log2(
            np.maximum(rho2.astype(np.float32), np.float32(np.finfo(np.float32).tiny)))[0])
    steps = [(level0, None)]
    if blend:
        frac = float(choice.frac[0])
        mip_weight = math.floor(frac * 256) / 256 if fixed8 else frac
        steps = [(level0, 1.0 - mip_weight), (int(choice.level1[0]), mip_weight)]
    out["mip"] = []
    s, t = st[:, 0], st[:, 1]
    for lvl, weight in steps:
        level = levels[lvl]
        h, w = level.shape[:2]
        if image_filter == "nearest":
            i = int(texture.nearest_addresses(s, w, tex.wrap_s, gl)[0])
            j = int(texture.nearest_addresses(t, h, tex.wrap_t, gl)[0])
            taps = [{"i": i, "j": j, "texel": level[j, i], "weight": 1.0}]
        else:
            i0, i1, a = texture.linear_addresses(s, w, tex.wrap_s, fixed8)
            j0, j1, b = texture.linear_addresses(t, h, tex.wrap_t, fixed8)
            a, b = float(a[0]), float(b[0])
            if fixed8:
                a, b = a / 256.0, b / 256.0          # 8-bit weights; each lerp rounds to a byte
            taps = [{"i": int(i), "j": int(j), "texel": level[int(j), int(i)], "weight": wt}
                    for i, j, wt in ((i0[0], j0[0], (1 - a) * (1 - b)), (i1[0], j0[0], a * (1 - b)),
                                     (i0[0], j1[0], (1 - a) * b), (i1[0], j1[0], a * b))]
        value = texture.filter_level(level, s, t, image_filter, tex.wrap_s, tex.wrap_t, gl, fixed8)[0]
        out["mip"].append({"level": lvl, "size": (w, h), "weight": 1.0 if weight is None else weight,
                           "taps": taps, "filtered": np.asarray(value, np.float64)})
    return out


# ----------------------------------------------------------------------------- per-sample ops


class _PixelBuffer:
    """The framebuffer of one pixel: (1, 1, S) samples, cleared like the real one
    (`pipeline.render_scene`): RGBA8 values k/255 in gl precision, float32 for an
    rgba32f framebuffer in gl precision, float64 in exact."""

    def __init__(self, scene: Scene, n_samples: int, gl: bool, rgba8: bool):
        self.quantize = gl and rgba8
        self.color, self.depth = ops.new_framebuffer(1, 1, n_samples, scene.background,
                                                     quantize=self.quantize)
        if gl and not rgba8:
            self.color = self.color.astype(np.float32)
        self._xy = np.zeros(1, np.int32)

    def apply(self, mask: int, z: np.ndarray, rgba: np.ndarray, draw) -> list[dict]:
        """Apply one fragment with `ops.apply_fragments`; per covered sample, what happened."""
        func = ops.DEPTH_FUNCS[draw.depth_test]
        before_c = self.color[0, 0].copy()
        before_z = self.depth[0, 0].copy()
        src = np.clip(rgba, 0.0, 1.0) if self.quantize else rgba
        ops.apply_fragments(self._xy, self._xy, np.array([mask], np.uint32),
                            np.ascontiguousarray(z[None], np.float64),
                            np.ascontiguousarray(rgba[None], np.float64), self.color, self.depth,
                            func, draw.depth_write, ops.BLEND_MODES[draw.blend], self.quantize)
        events = []
        for s in range(self.depth.shape[2]):
            if not (mask >> s) & 1:
                continue
            passed = bool(ops._depth_pass(func, float(z[s]), float(before_z[s])))
            events.append({
                "sample": s, "z": float(z[s]), "depth_before": float(before_z[s]),
                "depth_func": DEPTH_NAMES[func] if func else "disabled",
                "passed": passed,
                "depth_written": passed and draw.depth_write and func != 0,
                "depth_after": float(self.depth[0, 0, s]),
                "blend": draw.blend, "src": src, "dst": before_c[s],
                "out": self.color[0, 0, s].copy(),
            })
        return events


# ----------------------------------------------------------------------------- triangles


def _triangle_draws(scene, draw, clip_pos, vertex_colors, wx, wy, precision, policy, positions,
                    offsets, unit, fixed_point, buffer):
    """Explain one draw of triangles at window pixel (wx, wy); returns (primitives, missed)."""
    gl = precision == "gl"
    width, height = scene.width, scene.height
    mesh = draw.mesh
    clipped = clip_stage.clip_triangles(clip_pos, mesh.indices, precision=precision,
                                        policy=policy, width=width, height=height)
    tris = setup.setup_triangles(clipped.clip, width, height, precision=precision,
                                 cull=draw.cull, offsets=offsets, unit=unit,
                                 generated=clipped.generated, front_face=scene.front_face)

    def in_box(ts):
        b = ts.bbox
        return np.nonzero((b[:, 0] <= wx) & (wx <= b[:, 1]) & (b[:, 2] <= wy) & (wy <= b[:, 3]))[0]

    near = in_box(tris)
    frags = rasterize.rasterize(_restrict(tris, near, wx, wy), offsets, unit)
    t = near[frags.tri]                                   # index into tris, draw order
    missed = [int(k) for k in near if k not in set(t.tolist())]

    # Triangles that face culling removed but that would have covered a sample.
    culled = []
    if draw.cull != "none":
        every = setup.setup_triangles(clipped.clip, width, height, precision=precision, cull="none",
                                      offsets=offsets, unit=unit, generated=clipped.generated,
                                      front_face=scene.front_face)
        kept = set(tris.triangle.tolist())
        cand = [k for k in in_box(every) if int(every.triangle[k]) not in kept]
        if cand:
            hit = rasterize.rasterize(_restrict(every, np.array(cand, np.int64), wx, wy), offsets, unit)
            culled = [_triangle_geometry(every, int(cand[i]), clipped, mesh, offsets, unit, wx, wy,
                                         gl, status=f"culled ({draw.cull}-facing)")
                      for i in hit.tri]

    # -- From here on, the pipeline's per-draw wiring (`pipeline.render_scene`,
    # its general path), line by line, for the fragments t of this pixel only;
    # the extra lines record the intermediates (lighting terms, texel reads).
    source, corners = pipeline.corner_values(clipped, tris, mesh)
    material = draw.material
    base = vertex_colors * material.color
    shading = material.shading
    if shading != "unlit":
        world = vertex.world_positions(mesh.positions, draw.world)
        eye = vertex.eye_position(scene.camera.view)
    if shading == "gouraud":
        unit_normals = vertex.world_normals(mesh.normals, draw.world)
        vertex_base = base
        lit = fragment.blinn_phong(base[:, :3], world, unit_normals, eye, scene.lights, material)
        base = np.concatenate([lit, base[:, 3:]], axis=1)
    centres = np.stack([frags.x + 0.5, frags.y + 0.5], axis=1)
    lam = interpolate.barycentric(tris.window[t, :, :2], centres)
    persp = interpolate.perspective_weights_at(tris.window[t], tris.inv_w[t], centres)
    z_raw = interpolate.depth_at_samples(tris.window[t], frags.x, frags.y, positions)
    z = ops.quantize_depth(z_raw) if gl else z_raw
    terms = [None] * len(t)
    if shading == "flat":
        face_colors, normal, centroid, face_base = pipeline.flat_colors(world, source, base, eye,
                                                                        scene.lights, material)
        colors = face_colors[t]
        terms = [dict(_lighting_terms(face_base[k, :3], centroid[k], normal[k], eye, scene.lights,
                                      material), model="flat", provoking_vertex=int(source[k, 2]))
                 for k in t]
    elif shading == "phong":
        colors, position, normal = pipeline.phong_attributes(persp, corners, t, base, world, draw)
        mapping = [None] * len(t)
        if material.normal_map is not None or material.bump_map is not None:
            interpolated_normal = normal
            normal = pipeline.mapped_normals(scene, draw, persp, corners, tris, t, frags, centres, normal,
                                              precision, fixed_point)
            mapping = [{"map": material.normal_map or material.bump_map,
                        "kind": "normal map" if material.normal_map is not None
                        else f"bump map (scale {material.bump_scale})",
                        "interpolated_normal": interpolated_normal[f], "mapped_normal": normal[f]}
                       for f in range(len(t))]
        lit = fragment.blinn_phong(colors[:, :3], position, normal, eye, scene.lights, material)
        terms = [dict(_lighting_terms(colors[f, :3], position[f], normal[f], eye, scene.lights, material),
                      model="phong", normal_mapping=mapping[f]) for f in range(len(t))]
        colors = np.concatenate([lit, colors[:, 3:]], axis=1)
    else:
        colors = interpolate.interpolate(persp, corners(base)[t])
        if shading == "gouraud":
            terms = [{"model": "gouraud", "vertices": [
                dict(_lighting_terms(vertex_base[v, :3], world[v], unit_normals[v], eye, scene.lights,
                                     material), vertex=int(v)) for v in source[k]]} for k in t]
    texel = None
    tex_history = [None] * len(t)
    if material.texture is not None:
        tex = texture.prepare(scene.textures[material.texture])
        corner_uv, st, ddx, ddy = pipeline.uv_at_fragments(mesh.uvs, corners, persp, tris, t, frags,
                                                           centres, gl)
        texel = texture.sample(tex, st, ddx, ddy, precision, fixed_point)
        tex_history = [dict(_texture_history(tex, st[f:f + 1], ddx[f:f + 1], ddy[f:f + 1], precision,
                                             fixed_point, texel[f]),
                            corner_uv=corner_uv[f],
                            derivatives="per 2x2 quad: ddx = TR - TL, ddy = BL - TL" if gl
                            else "analytic at the pixel centre")
                       for f in range(len(t))]
    rgba = fragment.shade_unlit(colors, np.ones(4), texel)
    kept = np.ones(len(t), bool)
    if material.alpha_cutoff is not None:      # discard: no depth or colour write for any sample
        kept = fragment.alpha_test(rgba[:, 3], material.alpha_cutoff, precision)

    primitives = []
    for f, k in enumerate(t):
        entry = _triangle_geometry(tris, int(k), clipped, mesh, offsets, unit, wx, wy, gl,
                                   status="covered", kernel_mask=int(frags.mask[f]))
        entry.update({
            "barycentric": lam[f], "perspective_weights": persp[f],
            "depth_unquantized": z_raw[f],
            "shading": terms[f] if terms[f] is not None else {"model": "unlit"},
            "vertex_color": colors[f] if shading in ("unlit", "gouraud") else None,
            "material_color": material.color,
            "texture": tex_history[f],
            "color": rgba[f],
            "alpha_test": (None if material.alpha_cutoff is None
                           else {"cutoff": material.alpha_cutoff, "kept": bool(kept[f])}),
            "samples_ops": buffer.apply(int(frags.mask[f]), z[f], rgba[f], draw) if kept[f] else [],
        })
        primitives.append(entry)
    missed = [_triangle_geometry(tris, k, clipped, mesh, offsets, unit, wx, wy, gl,
                                 status="not covering") for k in missed] + culled
    return primitives, missed


def _triangle_geometry(tris, k, clipped, mesh, offsets, unit, wx, wy, gl, *, status,
                       kernel_mask=None) -> dict:
    """Set-up triangle k: source, vertices, edges, and the coverage of each sample of the pixel."""
    ct = int(tris.triangle[k])
    src = int(clipped.source[ct])
    pieces = int(np.count_nonzero(clipped.source == src))
    corner = tris.corner[k]
    generated = clipped.generated[ct]
    vertices = []
    for v in range(3):
        c = int(corner[v])
        w = clipped.weights[ct, c]
        vertices.append({
            "corner": c, "mesh_index": int(mesh.indices[src, c]) if not generated[c] else None,
            "clip_weights": w if generated[c] else None,
            "clip": clipped.clip[ct, c], "window": tris.window[k, v], "inv_w": float(tris.inv_w[k, v]),
            "raster": tris.raster[k, v],
        })
    a, b, x0, y0 = tris.edge_a[k], tris.edge_b[k], tris.edge_x0[k], tris.edge_y0[k]
    inclusive = tris.edge_inclusive[k]
    edges = [{"edge": i, "from": i, "to": (i + 1) % 3, "A": a[i], "B": b[i], "X0": x0[i], "Y0": y0[i],
              "kind": _edge_kind(a[i], b[i]), "inclusive": bool(inclusive[i])} for i in range(3)]
    samples, mask = [], 0
    for s in range(len(offsets)):
        sx = wx * (int(unit) if gl else unit) + offsets[s, 0]
        sy = wy * (int(unit) if gl else unit) + offsets[s, 1]
        # The rasterizer kernel's own edge function and inside test.
        values = [rasterize._edge(a[i], b[i], x0[i], y0[i], sx, sy) for i in range(3)]
        inside = all(rasterize._inside(values[i], bool(inclusive[i])) for i in range(3))
        covered, why = _coverage_decision(values, inclusive)
        if covered != inside:                       # the two readings of the rule disagree
            raise RuntimeError(f"explain: coverage decision {why!r} contradicts the rasterizer")
        mask |= int(inside) << s
        samples.append({"sample": s, "raster": (sx, sy), "E": values, "covered": inside, "why": why})
    if kernel_mask is not None and kernel_mask != mask:
        raise RuntimeError(f"explain: edge functions give mask {mask:#x}, the rasterizer {kernel_mask:#x}")
    return {
        "kind": "triangle", "status": status, "source_triangle": src,
        "source_vertices": mesh.indices[src], "clipped": bool(generated.any()), "clip_pieces": pieces,
        "front_facing": bool(tris.front_facing[k]), "corner_order": corner,
        "vertices": vertices, "edges": edges, "coverage": samples, "mask": mask,
    }


# ----------------------------------------------------------------------------- lines


def _line_draws(scene, draw, clip_pos, vertex_colors, wx, wy, precision, policy, positions, buffer):
    """Explain one draw of lines at (wx, wy), as `lines.line_fragments` computes it."""
    if draw.material.line_problems():
        raise NotImplementedError(f"{draw.path}: softras draws lines unlit and untextured only, "
                                  f"this material has {', '.join(draw.material.line_problems())}")
    width, height = scene.width, scene.height
    mesh = draw.mesh
    clipped = lines.clip_lines(clip_pos, mesh.indices, precision=precision, policy=policy,
                               width=width, height=height)
    fused = True if precision != "gl" else ~clipped.generated
    window, inv_w = setup.viewport_transform(clipped.clip, width, height, precision, fused)
    rectangular = len(positions) > 1
    frags, t_all = lines.rasterize_lines(window, width, height, precision, sample_positions=positions)
    here = np.nonzero((frags.x == wx) & (frags.y == wy))[0]
    line = frags.tri[here]
    z_raw = lines.depth_at_samples(window[line], frags.x[here], frags.y[here], positions, precision,
                                   rectangular)
    z = ops.quantize_depth(z_raw) if precision == "gl" else z_raw
    indices = np.asarray(mesh.indices, np.int64).reshape(-1, 2)
    values_at_source = np.asarray(vertex_colors, np.float64)[indices[clipped.source]]      # (L, 2, 4)
    ends = np.einsum("lkj,ljc->lkc", clipped.weights, values_at_source)
    values = lines.interpolate_lines(t_all[here], inv_w[line], ends[line])
    rgba = fragment.shade_unlit(values, draw.material.color)
    out = []
    for f, l in enumerate(line):
        src = int(clipped.source[l])
        d = window[l, 1, :2] - window[l, 0, :2]
        mask = int(frags.mask[here[f]])
        out.append({
            "kind": "line", "status": "covered", "source_line": src, "source_vertices": indices[src],
            "clipped": bool(clipped.generated[l].any()),
            "rule": "rectangular (MSAA)" if rectangular else "diamond exit",
            "major_axis": "x" if abs(d[0]) >= abs(d[1]) else "y",
            "ends": [{"clip": clipped.clip[l, e], "window": window[l, e], "inv_w": float(inv_w[l, e]),
                      "generated": bool(clipped.generated[l, e])} for e in range(2)],
            "mask": mask, "t": float(t_all[here[f]]), "depth_unquantized": z_raw[f],
            "shading": {"model": "unlit"}, "vertex_color": values[f],
            "material_color": draw.material.color, "texture": None, "color": rgba[f],
            "samples_ops": buffer.apply(mask, z[f], rgba[f], draw),
        })
    return out, []


# ----------------------------------------------------------------------------- the whole history


def _explain_draws(scene, wx, wy, precision, policy, positions, offsets, unit, fixed_point, buffer):
    """Every draw in render order, as `pipeline.render_scene` wires the stages; the
    entries of the draws that reached window pixel (wx, wy)."""
    draws = []
    for index, draw in enumerate(ordered_draws(scene)):
        mesh = draw.mesh
        mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
        clip_pos = vertex.to_clip(mesh.positions, mvp, precision)
        vertex_colors = pipeline.vertex_colors(mesh)
        if mesh.primitive == "lines":
            covered, near = _line_draws(scene, draw, clip_pos, vertex_colors, wx, wy, precision, policy,
                                        positions, buffer)
        else:
            covered, near = _triangle_draws(scene, draw, clip_pos, vertex_colors, wx, wy, precision,
                                            policy, positions, offsets, unit, fixed_point, buffer)
        if covered or near:
            m = draw.material
            draws.append({
                "draw": index, "path": draw.path, "name": draw.name, "primitive": mesh.primitive,
                "shading": m.shading, "texture": m.texture, "depth_test": draw.depth_test,
                "depth_write": draw.depth_write, "cull": draw.cull, "blend": draw.blend,
                "primitives": covered, "near_misses": near,
            })
    return draws


def explain_pixel(scene, x: int, y: int, *, precision: str = "gl", samples: int | None = None,
                  pattern: str | None = None, seed: int = 0, framebuffer: str | None = None,
                  clipping: str | None = None, texture_fixed_point: bool = True) -> dict:
    """The history of image pixel (x, y) through softras's pipeline.

    scene : a Scene, dict or path.  x, y : IMAGE coordinates (column from the
    left, row from the top, as the PNG is seen).  The other options are
    `softras.renderer.render_scene`'s (its default box resolve; at most 32
    samples, one rasterizer pass).

    Returns a JSON-able dict: ``pixel`` (image and window coordinates),
    ``setup`` (precision, samples, positions, clear values), ``draws`` (one
    entry per draw that reached the pixel, in render order, with the
    primitives that covered it and the ones that came near), ``final`` (each
    sample's stored value and the resolved value, premultiplied: what softras
    renders there, RGBA8 as 0..255 integers or rgba32f as floats).
    Raises ValueError for a pixel outside the image or a bad option,
    SceneError for a bad scene.
    """
    scene = load_scene(scene)
    if precision not in pipeline.PRECISIONS:
        raise ValueError(f"precision must be one of {pipeline.PRECISIONS}, not {precision!r}")
    framebuffer = framebuffer or scene.framebuffer
    if framebuffer not in pipeline.FRAMEBUFFERS:
        raise ValueError(f"framebuffer must be one of {pipeline.FRAMEBUFFERS}, not {framebuffer!r}")
    check_pixel(scene, x, y)
    width, height = scene.width, scene.height
    gl = precision == "gl"
    wx, wy = int(x), int(height - 1 - y)                 # GL window pixel, y up
    policy = clipping or ("llvmpipe" if gl else "guard_band")
    positions = pipeline.sample_positions(samples or scene.samples, pattern, seed)
    if len(positions) > pipeline.MAX_PASS_SAMPLES:
        raise ValueError(f"explain follows one rasterizer pass: at most {pipeline.MAX_PASS_SAMPLES} "
                         f"samples per pixel, not {len(positions)}")
    offsets, unit = setup.sample_offsets(positions, precision)
    rgba8 = framebuffer == "rgba8"
    buffer = _PixelBuffer(scene, len(positions), gl, rgba8)
    clear = buffer.color[0, 0, 0].copy()

    with _one_thread():
        draws = _explain_draws(scene, wx, wy, precision, policy, positions, offsets, unit,
                               texture_fixed_point, buffer)
    # The pipeline's resolve: llvmpipe's float32 arithmetic for GL's patterns in gl precision.
    arithmetic = "llvmpipe" if gl and pattern in (None, "gl") else "exact"
    resolved = ops.resolve(buffer.color, positions, filter="box", arithmetic=arithmetic,
                           output="uint8" if rgba8 else "float32")[0, 0]
    history = {
        "scene": scene.source, "size": (width, height),
        "pixel": {"image": (int(x), int(y)), "window": (wx, wy),
                  "window_centre": (wx + 0.5, wy + 0.5)},
        "setup": {"precision": precision, "samples": len(positions),
                  "sample_positions": positions, "clipping": policy,
                  "framebuffer": framebuffer, "render_order": scene.render_order,
                  "storage": ("RGBA8 UNORM" if rgba8 else "RGBA32F") + ", 24-bit depth" if gl
                  else "float64 colour and depth",
                  "clear_color": clear, "clear_depth": 1.0},
        "draws_total": len(scene.draws), "draws": draws,
        "final": {"samples": buffer.color[0, 0], "depth": buffer.depth[0, 0], "resolved": resolved,
                  "resolve": "box (llvmpipe's float32 arithmetic)" if arithmetic == "llvmpipe" else "box"},
    }
    return _py(history)


def gl_pixel(scene, x: int, y: int, *, samples: int | None = None) -> tuple[list, str]:
    """glref's value of image pixel (x, y) (RGBA8 as 0..255 integers, rgba32f
    as floats) and a line naming the GL renderer.

    Raises glref.GLUnavailable (or ModuleNotFoundError for moderngl) when
    there is no OpenGL.
    """
    import glref

    scene = load_scene(scene)
    image = glref.render(scene, samples=samples)
    info = glref.info()
    renderer = info.get("GL_RENDERER", "unknown renderer")
    version = info.get("GL_VERSION")
    return _py(image[y, x]), f"{renderer}, OpenGL {version}" if version else str(renderer)


# ----------------------------------------------------------------------------- text


def _f(v, digits: int = 4) -> str:
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_f(e, digits) for e in v) + ")"
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int):
        return str(v)
    if math.isinf(v):
        return "-inf" if v < 0 else "inf"
    return f"{v:.{digits}f}"


def _u8(c) -> str:
    """A stored colour (0..1) on the 0..255 scale: integers when it is k/255."""
    vals = [v * 255.0 for v in c]
    if all(abs(v - round(v)) < 1e-9 for v in vals):
        return "(" + ", ".join(str(int(round(v))) for v in vals) + ")"
    return "(" + ", ".join(f"{v:.2f}" for v in vals) + ")"


def _triangle_lines(p: dict, gl: bool) -> list[str]:
    out = []
    clip = f"clipped, one of {p['clip_pieces']} pieces" if p["clipped"] else "not clipped"
    face = "front-facing" if p["front_facing"] else "back-facing"
    out.append(f"triangle {p['source_triangle']} (vertices {' '.join(map(str, p['source_vertices']))}), "
               f"{clip}, {face}: {p['status']}")
    out.append("  vertices (setup order, counter-clockwise; window x, y, z_w; raster = "
               + ("round((x - 0.5) * 256)" if gl else "window x, y unsnapped") + "):")
    for k, v in enumerate(p["vertices"]):
        name = f"mesh {v['mesh_index']}" if v["mesh_index"] is not None else \
            f"clipper {_f(v['clip_weights'], 3)}"
        out.append(f"    v{k} [{name}]  clip {_f(v['clip'])}  window {_f(v['window'])}  "
                   f"1/w {v['inv_w']:.6g}  raster {_f(v['raster'], 3)}")
    out.append("  edges E = A (X - X0) + B (Y - Y0), > 0 inside:")
    for e in p["edges"]:
        out.append(f"    e{e['edge']} v{e['from']}->v{e['to']}  A {_f(e['A'], 3)}  B {_f(e['B'], 3)}  "
                   f"{e['kind']} edge ({'inclusive' if e['inclusive'] else 'exclusive'} on a tie)")
    for s in p["coverage"]:
        out.append(f"  sample {s['sample']} at raster {_f(s['raster'], 3)}: E = {_f(s['E'], 3)} -> "
                   f"{'covered' if s['covered'] else 'not covered'}: {s['why']}")
    return out


def _texture_lines(tex: dict, what: str) -> list[str]:
    out = [f"  {what} {tex['name']!r} {tex['size'][0]}x{tex['size'][1]} ({tex['levels']} levels), "
           f"wrap {tex['wrap'][0]}/{tex['wrap'][1]}, min {tex['min_filter']}, mag {tex['mag_filter']}",
           f"    (s, t) {_f(tex['st'], 6)}; derivatives {tex.get('derivatives', '')}: "
           f"d/dx {_f(tex['ddx'], 6)}, d/dy {_f(tex['ddy'], 6)}"]
    if "anisotropic" in tex:
        out.append(f"    anisotropic filtering (max_anisotropy {tex['anisotropic']}): "
                   "see softras.pipeline.texture.sample_anisotropic; no per-texel breakdown")
    else:
        lam = f"lambda = log2 rho {_f(tex['lambda'])}"
        if "lambda_llvmpipe" in tex:
            lam += f" (llvmpipe's fast log2: {tex['lambda_llvmpipe']:.4f})"
        out.append(f"    in texels: d/dx {_f(tex['texel_ddx'])}, d/dy {_f(tex['texel_ddy'])}; "
                   f"rho^2 {tex['rho2']:.6g}; {lam}; "
                   + ("magnified" if tex["magnified"] else "minified") + f", filter {tex['filter']}"
                   + (", 8.8 fixed point" if tex["fixed_point"] else ""))
        for m in tex["mip"]:
            taps = "; ".join(f"[{t['i']},{t['j']}] {tuple(t['texel'])} x {t['weight']:.4f}"
                             for t in m["taps"])
            out.append(f"    level {m['level']} ({m['size'][0]}x{m['size'][1]}) weight {m['weight']:.4f}: "
                       f"{taps} -> {_f(m['filtered'], 2)} (0..255)")
    out.append(f"    texel (premultiplied) {_f(tex['result'])}")
    return out


def _fragment_lines(p: dict, gl: bool) -> list[str]:
    out = []
    if "barycentric" in p:
        out.append(f"  barycentric (screen, at the pixel centre) {_f(p['barycentric'], 6)}; "
                   f"perspective-correct {_f(p['perspective_weights'], 6)}")
        if min(p["barycentric"]) < 0:
            out.append("  (the pixel is shaded once, at its centre, which lies outside this triangle: "
                       "its attribute planes are extended there)")
    else:
        out.append(f"  line parameter t {p['t']:.6f} (0 at end 0, 1 at end 1)")
    tex = p["texture"]
    if tex is not None:
        out.extend(_texture_lines(tex, "texture"))
    sh = p["shading"]
    if sh["model"] == "unlit" or sh["model"] == "gouraud":
        lit = " (Gouraud-lit at the vertices)" if sh["model"] == "gouraud" else ""
        out.append(f"  colour: vertex colour{lit} "
                   f"{_f(p['vertex_color'])} x material {_f(p['material_color'])}"
                   + (" x texel" if tex is not None else ""))
        if sh["model"] == "gouraud":
            for v in sh["vertices"]:
                out.extend(_light_lines(v, f"vertex {v['vertex']}"))
    else:
        where = f"face normal at the centroid, provoking vertex {sh['provoking_vertex']}" \
            if sh["model"] == "flat" else "interpolated position and normal"
        out.append(f"  shading {sh['model']} ({where}):")
        mapping = sh.get("normal_mapping")
        if mapping:
            out.append(f"    {mapping['kind']} {mapping['map']!r}: interpolated normal "
                       f"{_f(mapping['interpolated_normal'])} -> mapped {_f(mapping['mapped_normal'])}")
        out.extend(_light_lines(sh, "fragment"))
    out.append(f"  fragment colour (premultiplied) {_f(p['color'])}")
    alpha_test = p.get("alpha_test")
    if alpha_test is not None:
        out.append(f"  alpha test: alpha {p['color'][3]:.6f} " + (">=" if alpha_test["kept"] else "<")
                   + f" cutoff {alpha_test['cutoff']:g} -> "
                   + ("kept" if alpha_test["kept"] else "DISCARDED (no sample written)"))
    for e in p["samples_ops"]:
        if e["depth_func"] == "disabled":
            depth = "depth test disabled"
        else:
            depth = (f"depth {e['z']:.7f} {e['depth_func']} {e['depth_before']:.7f} -> "
                     + ("pass" if e["passed"] else "FAIL")
                     + (", written" if e["depth_written"] else ", not written"))
        if e["passed"]:
            blend = f"blend {e['blend']}: src {_u8(e['src'])} dst {_u8(e['dst'])} -> {_u8(e['out'])}"
        else:
            blend = f"colour kept {_u8(e['out'])}"
        out.append(f"  sample {e['sample']}: {depth}; {blend}")
    return out


def _light_lines(t: dict, where: str) -> list[str]:
    out = [f"    {where}: P {_f(t['position'])} N {_f(t['normal'])} base {_f(t['base_rgb'])}",
           f"    ambient {t['ambient_coefficient']} x base = {_f(t['ambient'])}"]
    for light in t["lights"]:
        lit = "" if light["N_dot_L"] > 0 else " (N.L <= 0: no contribution)"
        out.append(f"    light {light['light']} ({light['type']}): N.L {light['N_dot_L']:.4f} "
                   f"N.H {light['N_dot_H']:.4f}; diffuse {_f(light['diffuse'])} "
                   f"specular {_f(light['specular'])}{lit}")
    out.append(f"    lit rgb {_f(t['lit_rgb'])}")
    return out


def format_text(history: dict, gl_value: list[int] | None = None, gl_note: str | None = None,
                rendered: list[int] | None = None) -> str:
    """The readable report: one section per draw that reached the pixel."""
    px, st = history["pixel"], history["setup"]
    gl = st["precision"] == "gl"
    (x, y), (wx, wy) = px["image"], px["window"]
    lines_ = [
        f"pixel ({x}, {y}) in the image (column, row from the top) = window pixel ({wx}, {wy}) in GL "
        f"(y up; centre {_f(px['window_centre'], 1)}) of {history['scene']} "
        f"({history['size'][0]}x{history['size'][1]})",
        f"precision {st['precision']}, {st['samples']} sample(s) at "
        + ", ".join(_f(p, 3) for p in st["sample_positions"])
        + f" within the pixel; clipping {st['clipping']}; {st['storage']}",
        f"cleared to {_u8(st['clear_color'])} (premultiplied, 0..255), depth {st['clear_depth']}",
    ]
    reached = {d["draw"] for d in history["draws"]}
    for d in history["draws"]:
        depth = "depth test off" if d["depth_test"] is None else \
            f"depth {d['depth_test']}{'' if d['depth_write'] else ' (no write)'}"
        lines_.append("")
        lines_.append(f"draw {d['draw']} {d['path']} {d['name']!r}: {d['primitive']}, {d['shading']}"
                      + (f", texture {d['texture']!r}" if d["texture"] else "")
                      + f", {depth}, blend {d['blend']}, cull {d['cull']}")
        for p in d["primitives"]:
            if p["kind"] == "triangle":
                body = _triangle_lines(p, gl) + _fragment_lines(p, gl)
            else:
                e0, e1 = p["ends"]
                body = [f"line {p['source_line']} (vertices {' '.join(map(str, p['source_vertices']))}), "
                        f"{'clipped' if p['clipped'] else 'not clipped'}, {p['rule']}, "
                        f"{p['major_axis']}-major",
                        f"  ends (window x, y, z_w): {_f(e0['window'])} -> {_f(e1['window'])}",
                        f"  coverage mask {p['mask']:#b}"] + _fragment_lines(p, gl)
            lines_.extend("  " + s for s in body)
        if d["near_misses"]:
            lines_.append(f"  in the bounding box but covering no sample ({len(d['near_misses'])}):")
            for p in d["near_misses"][:8]:
                lines_.append(f"    triangle {p['source_triangle']} (vertices "
                              f"{' '.join(map(str, p['source_vertices']))}): {p['status']}")
                lines_.extend(f"      sample {s['sample']}: E = {_f(s['E'], 3)} -> {s['why']}"
                              for s in p["coverage"])
            if len(d["near_misses"]) > 8:
                lines_.append(f"    ... and {len(d['near_misses']) - 8} more")
            lines_.append("    (their vertices and edges: --json, draws[].near_misses)")
    unreached = history["draws_total"] - len(reached)
    lines_.append("")
    if unreached:
        lines_.append(f"{unreached} other draw(s) did not reach this pixel")
    fin = history["final"]
    per_sample = "; ".join(f"s{k} {_u8(c)}" for k, c in enumerate(fin["samples"]))
    lines_.append(f"final samples (premultiplied, 0..255): {per_sample}")
    lines_.append(f"softras: {tuple(fin['resolved'])} ({st['framebuffer']}, premultiplied; "
                  f"{fin['resolve']} resolve of the samples)")
    if rendered is not None:
        same = list(rendered) == list(fin["resolved"])
        lines_.append(f"softras image: {tuple(rendered)}"
                      + (" (same)" if same else " MISMATCH: the explanation does not follow the renderer"))
    if gl_value is not None:
        diff = max(abs(a - b) for a, b in zip(gl_value, fin["resolved"]))
        lines_.append(f"glref:   {tuple(gl_value)}"
                      + (" (same)" if diff == 0 else f" (differs by up to {diff}/255)")
                      + (f"  [{gl_note}]" if gl_note else ""))
    elif gl_note:
        lines_.append(f"glref: {gl_note}")
    return "\n".join(lines_)
