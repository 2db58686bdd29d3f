"""The software pipeline: a Scene through every stage to an image.

vertex -> clip -> setup -> rasterize -> interpolate -> fragment -> ops,
once per draw, in the scene's draw order.  Each stage is a module of pure
functions on arrays; this module only wires them together and keeps the
framebuffer.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from softras.pipeline import clip as clip_stage
from softras.pipeline import fragment, interpolate, lines, ops, rasterize, sampling, setup, texture, vertex
from softras.pipeline import texture_beyond
from softras.pipeline import texture_bounds as texbounds
from softras.scene import Scene, ordered_draws

PRECISIONS = ("gl", "exact")

# llvmpipe's 4x MSAA sample positions within a pixel (x, y), GL window space.
MSAA4_POSITIONS = sampling.GL_MSAA4
CENTER_POSITION = sampling.GL_CENTER

# The rasterizers keep a fragment's coverage in a uint32 bit mask, so a pass
# renders at most 32 samples; more samples are rendered in several passes
# (each through every stage) into slices of the per-sample colour buffer.
MAX_PASS_SAMPLES = sampling.MAX_PASS_SAMPLES
sample_passes = sampling.sample_passes
# Largest per-sample buffers a render makes (`check_sample_memory`).
MAX_SAMPLE_BYTES = 1 << 30
SAMPLE_BYTES = 4 * 8        # the stages' per-sample colour: RGBA float64 (`render_samples`)
FRAMEBUFFERS = ("rgba8", "rgba32f")


def sample_positions(samples: int, pattern: str | None = None, seed: int = 0) -> np.ndarray:
    """(S, 2) sample positions in [0, 1)^2 (see `softras.pipeline.sampling`).

    pattern None = GL's: 1 sample = the pixel centre, 4 = llvmpipe's MSAA
    positions; "grid", "rotated_grid", "jittered", "halton", "poisson" are
    softras's own (seeded where random).
    """
    return sampling.sample_positions(samples, pattern, seed)


def uv_at_fragments(uvs, corners, persp, tris, t, frags, centres, gl: bool):
    """Texture coordinates of a draw's fragments and their screen derivatives.

    uvs : (N, 2) the mesh's per-vertex uvs (rounded to float32 in gl precision,
    as GL's vertex attributes); corners : the draw's (N, K) -> (T', 3, K)
    corner function; persp : (F, 3) perspective weights; t : (F,) set-up
    triangle per fragment.  Returns corner_uv (F, 3, 2), st (F, 2) and the
    derivatives ddx, ddy (F, 2) in uv per window pixel: per 2x2 quad in gl
    precision (llvmpipe's TR - TL, BL - TL), analytic at the pixel centre in
    exact precision.
    """
    uvs = uvs.astype(np.float32).astype(np.float64) if gl else uvs
    corner_uv = corners(uvs)[t]
    st = interpolate.interpolate(persp, corner_uv)
    if gl:
        ddx, ddy = interpolate.quad_derivatives(tris.window[t], tris.inv_w[t], frags.x, frags.y, corner_uv)
    else:
        ddx, ddy = interpolate.analytic_derivatives(tris.window[t], tris.inv_w[t], centres, corner_uv)
    return corner_uv, st, ddx, ddy


def corner_values(clipped, tris, mesh):
    """Attributes at the set-up triangles' corners.

    Returns source (T', 3): the mesh vertex indices of each set-up
    triangle's source triangle, and corners(values): (N, K) per-vertex values
    -> (T', 3, K) at the corners.  A corner the clipper passed through (a
    clip weight exactly 1, `softras.pipeline.clip.ClippedTriangles.generated`)
    takes its vertex's values as they are; a corner the clipper made, the
    clip weights (reordered like the corners) applied to the source
    triangle's vertex values (GL 4.5 core, section 13.5.1: the clipper
    interpolates the outputs of the vertices it makes, and only those; a
    weighted sum for every corner would turn a vertex's -0 into +0, and
    another vertex's infinity into NaN, through the zero weights).
    """
    weights = np.take_along_axis(clipped.weights[tris.triangle], tris.corner[..., None], axis=1)
    source = mesh.indices[clipped.source[tris.triangle]]                # (T', 3)
    passed = ~np.take_along_axis(clipped.generated[tris.triangle], tris.corner, axis=1)    # (T', 3)
    own = np.take_along_axis(source, weights.argmax(axis=2), axis=1)[passed]

    def corners(values: np.ndarray) -> np.ndarray:
        out = np.einsum("tkj,tjc->tkc", weights, values[source])
        out[passed] = values[own]
        return out

    return source, corners


def flat_colors(world, source, base, eye, lights, material):
    """Flat shading: one colour per set-up triangle from its source triangle's
    face normal, centroid and provoking (last) vertex colour, all world space.

    world : (N, 3) vertex positions; source : (T', 3); base : (N, 4) straight
    vertex colours.  Returns colors (T', 4), normal (T', 3), centroid
    (T', 3) and the provoking vertex colours (T', 4).
    """
    normal = fragment.face_normals(world, source)
    centroid = world[source].mean(axis=1)
    face_base = base[source[:, 2]]
    lit = fragment.blinn_phong(face_base[:, :3], centroid, normal, eye, lights, material)
    return np.concatenate([lit, face_base[:, 3:]], axis=1), normal, centroid, face_base


def phong_attributes(persp, corners, t, base, world, draw):
    """Per-fragment inputs of Phong shading, perspective-correct: colours
    (F, 4) straight, world positions (F, 3) and unit world normals (F, 3)."""
    colors = interpolate.interpolate(persp, corners(base)[t])
    position = interpolate.interpolate(persp, corners(world)[t])
    world_normals = vertex.world_normals(draw.mesh.normals, draw.world, unit=False)
    normal = interpolate.interpolate(persp, corners(world_normals)[t])
    return colors, position, normal / np.linalg.norm(normal, axis=1, keepdims=True)


def mapped_normals(scene, draw, persp, corners, tris, t, frags, centres, normal, precision,
                    texture_fixed_point, texture_bounds=None):
    """Phong shading with a normal or bump map: (F, 3) world normals perturbed
    per fragment (softras.pipeline.fragment: tangent frames from Mesh.tangents,
    the map sampled like any texture, with the uv's derivatives).

    texture_bounds (`softras.pipeline.texture_bounds.BOUND_RENDERS`): the map
    sampled at one level of detail GL permits, the lowest for "lo", the
    highest for "hi", else the one named after the "/"
    (`softras.pipeline.texture_bounds.variant_derivatives`): the normal goes
    through lighting, so these are an envelope by variants, not a bound."""
    mesh, material = draw.mesh, draw.material
    gl = precision == "gl"
    tangents = vertex.world_tangents(mesh.tangents, draw.world)
    tangent = interpolate.interpolate(persp, corners(tangents)[t])
    corner_uv, st, ddx, ddy = uv_at_fragments(mesh.uvs, corners, persp, tris, t, frags, centres, gl)
    tex = texture.prepare(scene.textures[material.normal_map if material.normal_map is not None
                                         else material.bump_map])
    if texture_bounds is not None:
        candidates = texbounds.fragment_derivatives(tris.window[t], tris.inv_w[t], frags.x, frags.y,
                                                    centres, corner_uv)
        _, where = texbounds.bound_render(texture_bounds)
        tex, ddx, ddy = texbounds.variant_derivatives(tex, candidates, where, precision)
    if material.normal_map is not None:
        mapped = fragment.normal_map_normals(texture.sample(tex, st, ddx, ddy, precision, texture_fixed_point))
    else:
        mapped = fragment.bump_normals(tex, st, ddx, ddy, material.bump_scale, precision, texture_fixed_point)
    return fragment.perturb_normals(normal, tangent, mapped)


def render_stages(scene: Scene, *, precision: str = "gl", samples: int | None = None,
                  pattern: str | None = None, seed: int = 0, resolve_filter: str = "box",
                  framebuffer: str | None = None, clipping: str | None = None,
                  texture_fixed_point: bool = True, texture_filter=None,
                  texture_bounds: str | None = None, tie_rule: str = "left_bottom") -> np.ndarray:
    """Render a loaded scene; returns the picture, row 0 = top.

    precision : "gl" (llvmpipe's fixed point, float32 vertex math, RGBA8 and
        24-bit depth rounding) or "exact" (float64 throughout, no snapping).
    samples : samples per pixel, overrides ``scene.samples``; 1..1024.
    pattern : sample pattern (`softras.pipeline.sampling`); None = GL's (1 or 4 samples);
        or an (S, 2) array of positions (a GL's own, y up).
    seed : seed of the random patterns ("jittered", "poisson").
    resolve_filter : "box" (the pixel's own samples) or "tent" (a 2-pixel-wide
        tent over the 3 x 3 neighbourhood's samples), see `softras.pipeline.ops.resolve`.
    framebuffer : "rgba8" or "rgba32f", overrides ``scene.framebuffer``.
    clipping : "llvmpipe" (default in gl) or "guard_band" (default in exact).
    texture_fixed_point : gl precision: filter RGBA8 textures with repeat /
        clamp_to_edge wrapping in llvmpipe's 8.8 fixed point, as llvmpipe does
        by default; False = float weights, as llvmpipe with
        ``GALLIVM_PERF=no_aos_sampling`` (see `softras.pipeline.texture`).
    texture_filter : None, "ripmap", "ewa", "level0" or a dict {texture name:
        filter}: replaces the min filter of every (or the named) texture with
        a softras-only filter (see `softras.pipeline.texture_beyond`); glref ignores it.
    texture_bounds : None, "lo" or "hi": every texture lookup returns the
        lower / upper bound of what a conformant GL implementation may return
        (`softras.pipeline.texture_bounds.lookup_bounds`; stages only, no texture_filter);
        normal and bump maps are sampled at the lowest / highest permitted
        level of detail instead (an envelope by variants, not a bound);
        "lo/middle", "hi/last_level" and the like sample the maps at another
        permitted level of detail (`softras.pipeline.texture_bounds.BOUND_RENDERS`).
    tie_rule : which edges own a sample exactly on them (`softras.pipeline.setup.TIE_RULES`):
        "left_bottom" (llvmpipe's, default) or another rule GL allows (stages only).

    Returns (H, W, 4) premultiplied RGBA: uint8 for an rgba8 framebuffer,
    float32 (unclamped, as GL reads back a float buffer) for rgba32f.
    More than 32 samples are rendered in passes of <= 32 (`sample_passes`);
    a per-sample colour buffer over MAX_SAMPLE_BYTES is refused (ValueError).
    """
    job = Job.of(scene, precision=precision, samples=samples, pattern=pattern, seed=seed,
                 resolve_filter=resolve_filter, framebuffer=framebuffer, clipping=clipping,
                 texture_fixed_point=texture_fixed_point, texture_filter=texture_filter,
                 texture_bounds=texture_bounds, tie_rule=tie_rule)
    return resolve(job, render_samples(scene, job))


@dataclass(frozen=True)
class Job:
    """A render's options, checked, and the sample positions they give.

    positions : (S, 2) sample positions in [0, 1)^2 of a pixel (GL window
    space, y up); gl_pattern : whether they are GL's own (1 or 4 samples);
    rgba8 : the framebuffer is RGBA8 (else rgba32f).  The other fields are
    `render_stages`' options of the same names.
    """
    precision: str
    positions: np.ndarray
    gl_pattern: bool
    rgba8: bool
    resolve_filter: str
    clipping: str | None
    texture_fixed_point: bool
    texture_filter: object
    texture_bounds: str | None
    tie_rule: str

    @classmethod
    def of(cls, scene: Scene, *, precision, samples, pattern, seed, resolve_filter, framebuffer, clipping,
           texture_fixed_point, texture_filter, texture_bounds, tie_rule) -> "Job":
        """Check the options against the scene (ValueError with the reason)."""
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, not {precision!r}")
        framebuffer = framebuffer or scene.framebuffer
        if framebuffer not in FRAMEBUFFERS:
            raise ValueError(f"framebuffer must be one of {FRAMEBUFFERS}, not {framebuffer!r}")
        if resolve_filter not in ops.RESOLVE_FILTERS:
            raise ValueError(f"resolve_filter must be one of {ops.RESOLVE_FILTERS}, not {resolve_filter!r}")
        texture_beyond.check_texture_filter(texture_filter, scene.textures)
        if texture_bounds not in (None,) + texbounds.BOUND_RENDERS:
            raise ValueError(f"texture_bounds must be None or one of {texbounds.BOUND_RENDERS}, "
                             f"not {texture_bounds!r}")
        if tie_rule not in setup.TIE_RULES:
            raise ValueError(f"tie_rule must be one of {', '.join(setup.TIE_RULES)}, not {tie_rule!r}")
        if texture_bounds is not None and texture_filter is not None:
            raise ValueError("texture_bounds bounds GL's filters: it cannot be combined with texture_filter")
        positions = sample_positions(samples or scene.samples, pattern, seed)
        return cls(precision=precision, positions=positions,
                   gl_pattern=pattern is None or (isinstance(pattern, str) and pattern == "gl"),
                   rgba8=framebuffer == "rgba8", resolve_filter=resolve_filter, clipping=clipping,
                   texture_fixed_point=texture_fixed_point, texture_filter=texture_filter,
                   texture_bounds=texture_bounds, tie_rule=tie_rule)


# Pixel samples a band of rows holds at most when a draw is rasterized in
# bands (`row_bands`), and fragments a draw shades at once (`fragment_chunks`).
BAND_SAMPLES = 1 << 21
FRAGMENT_CHUNK = 1 << 18


def row_bands(bbox: np.ndarray, width: int, n_samples: int, limit: int | None = None):
    """A draw's set-up triangles' pixel boxes bbox (T', 4) (x0, x1, y0, y1,
    `softras.pipeline.setup.TriangleSetup`) as those of consecutive bands of
    rows, each box cut to the band's rows (empty, y0 > y1, outside it): bands
    of ``limit`` (default BAND_SAMPLES) pixel samples of the picture's width,
    or the boxes as they are when all of them hold fewer samples together."""
    limit = limit or BAND_SAMPLES
    pixels = np.maximum(bbox[:, 1] - bbox[:, 0] + 1, 0) * np.maximum(bbox[:, 3] - bbox[:, 2] + 1, 0)
    if len(bbox) == 0 or int(pixels.sum()) * n_samples <= limit:
        yield bbox
        return
    rows = max(1, limit // (width * n_samples))
    for top in range(int(bbox[:, 2].min()), int(bbox[:, 3].max()) + 1, rows):
        band = bbox.copy()
        band[:, 2] = np.maximum(bbox[:, 2], top)
        band[:, 3] = np.minimum(bbox[:, 3], top + rows - 1)
        yield band


def fragment_chunks(frags: rasterize.Fragments, size: int | None = None):
    """A draw's fragments (`softras.pipeline.rasterize.Fragments`) as
    consecutive slices of at most ``size`` (default FRAGMENT_CHUNK), in order."""
    size = size or FRAGMENT_CHUNK
    for start in range(0, len(frags), size):
        stop = start + size
        yield rasterize.Fragments(frags.tri[start:stop], frags.x[start:stop], frags.y[start:stop],
                                  frags.mask[start:stop])


def check_sample_memory(scene: Scene, n_samples: int, bytes_per_sample: int) -> None:
    """Refuse (ValueError, one line) a render whose per-sample buffers,
    ``bytes_per_sample`` for each of the picture's samples, would exceed
    MAX_SAMPLE_BYTES: `SAMPLE_BYTES` for the stages' float64 colour, far less
    for the compiled path's bytes (`softras.kernels.draw.SAMPLE_BYTES`)."""
    size = scene.width * scene.height * n_samples * bytes_per_sample
    if size > MAX_SAMPLE_BYTES:
        raise ValueError(f"{scene.width}x{scene.height} pixels x {n_samples} samples need "
                         f"{size / 2**30:.1f} GiB of sample colour (limit "
                         f"{MAX_SAMPLE_BYTES / 2**30:.0f} GiB): use fewer samples or a smaller image")


def render_samples(scene: Scene, job: Job, triangles=None, framebuffer=None, lines=None) -> np.ndarray:
    """The per-sample colour buffer (H, W, S, 4) of every draw, GL's y-up rows,
    premultiplied: float64 k/255 values for rgba8 in gl precision, float32 for
    rgba32f in gl precision, float64 in exact (`render_pass`, in passes of
    at most MAX_PASS_SAMPLES samples; triangles, framebuffer and lines as
    `render_pass`')."""
    check_sample_memory(scene, len(job.positions), SAMPLE_BYTES)
    return sampling.in_passes(job.positions, lambda positions: render_pass(scene, Pass.of(job, positions),
                                                                           triangles, framebuffer, lines))


def resolve(job: Job, color: np.ndarray) -> np.ndarray:
    """The picture (H, W, 4), row 0 = top, from the per-sample colours
    (H, W, S, 4) of `render_samples`: GL's MSAA resolve (llvmpipe's float32
    arithmetic) for GL's patterns in gl precision, the exact float64 mean
    otherwise (`softras.pipeline.ops.resolve`)."""
    return ops.resolve(color, job.positions, filter=job.resolve_filter, arithmetic=_arithmetic(job),
                       output="uint8" if job.rgba8 else "float32")


def resolve_bytes(job: Job, stored: np.ndarray) -> np.ndarray:
    """`resolve` of an RGBA8 job's samples given as their bytes, (H, W, S, 4)
    uint8, byte k for the stages' k/255 (the compiled path's buffer), with no
    float copy of the buffer: the box filter by `ops.resolve_llvmpipe_bytes`
    or `ops.resolve_exact_bytes`, the tent by `ops.resolve`, which reads the
    bytes as k/255 itself.  The same picture as ``resolve(job, stored /
    255.0)``."""
    if job.resolve_filter == "box":
        llvmpipe = _arithmetic(job) == "llvmpipe"
        return ops.resolve_llvmpipe_bytes(stored) if llvmpipe else ops.resolve_exact_bytes(stored)
    return resolve(job, stored)


def _arithmetic(job: Job) -> str:
    """The resolve's arithmetic: llvmpipe's float32 for GL's patterns in gl
    precision, the exact float64 mean otherwise."""
    return "llvmpipe" if job.precision == "gl" and job.gl_pattern else "exact"


def vertex_colors(mesh) -> np.ndarray:
    """A mesh's straight vertex colours (V, 4): its own, or opaque white."""
    return mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))


def vertex_base_colors(scene: Scene, draw) -> np.ndarray:
    """The straight colours (V, 4) a triangle draw carries per vertex: vertex
    colour x material colour, and for Gouraud shading that lit at each vertex
    (`softras.pipeline.fragment.blinn_phong` in world space, alpha kept),
    which the rasterizer then interpolates like any vertex colour (the fast
    path takes these as its vertex colours).  Flat and Phong shading light
    later, from these unlit colours."""
    base = vertex_colors(draw.mesh) * draw.material.color
    if draw.material.shading != "gouraud":
        return base
    world = vertex.world_positions(draw.mesh.positions, draw.world)
    eye = vertex.eye_position(scene.camera.view)
    lit = fragment.blinn_phong(base[:, :3], world, vertex.world_normals(draw.mesh.normals, draw.world),
                               eye, scene.lights, draw.material)
    return np.concatenate([lit, base[:, 3:]], axis=1)


def render_pass(scene: Scene, inputs: "Pass", triangles=None, framebuffer=None, lines=None) -> np.ndarray:
    """Render every draw at the pass's <= 32 sample positions (`Pass`).

    Returns the per-sample colour buffer (H, W, S, 4) premultiplied, GL's
    y-up rows: float64 k/255 values for rgba8 in gl precision, float32 for
    rgba32f in gl precision (float32 storage, as GL's), float64 in exact.
    triangles : the function that draws a triangle draw, with
    `draw_triangles`' arguments (default `draw_triangles`; the exact
    kernel's `softras.kernels.exact.draw_triangles`).
    framebuffer : the function that makes the pass's cleared buffers, with
    `new_pass_framebuffer`'s arguments and result (its default; the exact
    kernel's reused ones, `softras.kernels.exact.reused_framebuffer`).
    lines : the function that draws a line draw, with `draw_lines`'
    arguments (default `draw_lines`).
    """
    color, depth = (framebuffer or new_pass_framebuffer)(scene, inputs)
    for draw in ordered_draws(scene):
        if draw.mesh.primitive == "lines":
            (lines or draw_lines)(scene, draw, inputs, color, depth)
        else:
            (triangles or draw_triangles)(scene, draw, inputs, color, depth)
    return color


@dataclass(frozen=True)
class Pass:
    """What every draw of one pass reads: the `Job`'s options (precision,
    rgba8, texture_fixed_point, texture_filter, texture_bounds, tie_rule),
    the pass's sample positions (S, 2) and their raster offsets and unit
    (`softras.pipeline.setup.sample_offsets`), quantize (an RGBA8 buffer in
    gl precision: bytes as k/255) and the clipping policy."""
    precision: str
    positions: np.ndarray
    offsets: np.ndarray
    unit: float
    rgba8: bool
    quantize: bool
    policy: str
    texture_fixed_point: bool
    texture_filter: object
    texture_bounds: str | None
    tie_rule: str

    @classmethod
    def of(cls, job: Job, positions: np.ndarray) -> "Pass":
        """The pass of ``job`` at ``positions`` (S, 2), some of job.positions."""
        gl = job.precision == "gl"
        offsets, unit = setup.sample_offsets(positions, job.precision)
        return cls(precision=job.precision, positions=positions, offsets=offsets, unit=unit, rgba8=job.rgba8,
                   quantize=gl and job.rgba8, policy=job.clipping or ("llvmpipe" if gl else "guard_band"),
                   texture_fixed_point=job.texture_fixed_point, texture_filter=job.texture_filter,
                   texture_bounds=job.texture_bounds, tie_rule=job.tie_rule)


def new_pass_framebuffer(scene: Scene, inputs: Pass) -> tuple[np.ndarray, np.ndarray]:
    """The pass's cleared (colour (H, W, S, 4), depth (H, W, S)) buffers
    (`softras.pipeline.ops.new_framebuffer`; float32 colour for rgba32f in
    gl precision)."""
    color, depth = ops.new_framebuffer(scene.width, scene.height, len(inputs.positions), scene.background,
                                       quantize=inputs.quantize)
    if inputs.precision == "gl" and not inputs.rgba8:
        color = color.astype(np.float32)
    return color, depth


def draw_clip_positions(scene: Scene, draw, precision: str) -> np.ndarray:
    """A draw's vertices in clip space (V, 4) (`softras.pipeline.vertex.to_clip`)."""
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    return vertex.to_clip(draw.mesh.positions, mvp, precision)


def draw_lines(scene: Scene, draw, inputs: Pass, color: np.ndarray, depth: np.ndarray) -> None:
    """One line draw into the pass's buffers: clipped, rasterized
    (`softras.pipeline.lines`), shaded unlit and applied."""
    mesh = draw.mesh
    gl = inputs.precision == "gl"
    if draw.material.line_problems():
        raise NotImplementedError(f"{draw.path}: softras draws lines unlit and untextured only, "
                                  f"this material has {', '.join(draw.material.line_problems())}")
    lf = lines.line_fragments(draw_clip_positions(scene, draw, inputs.precision), mesh.indices, scene.width,
                              scene.height, values=vertex_colors(mesh), precision=inputs.precision,
                              sample_positions=inputs.positions, policy=inputs.policy)
    if len(lf):
        f = lf.fragments
        ops.apply_fragments(f.x, f.y, f.mask, ops.quantize_depth(lf.z) if gl else lf.z,
                            fragment.shade_unlit(lf.values, draw.material.color), color, depth,
                            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                            ops.BLEND_MODES[draw.blend], inputs.quantize)


def clip_draw(scene: Scene, draw, inputs: Pass):
    """A triangle draw through the vertex and clip stages: its
    `softras.pipeline.clip.ClippedTriangles`."""
    return clip_stage.clip_triangles(draw_clip_positions(scene, draw, inputs.precision), draw.mesh.indices,
                                     precision=inputs.precision, policy=inputs.policy, width=scene.width,
                                     height=scene.height)


def set_up_draw(scene: Scene, draw, inputs: Pass):
    """A triangle draw through the vertex, clip and setup stages: its
    `softras.pipeline.clip.ClippedTriangles` and
    `softras.pipeline.setup.TriangleSetup` (possibly empty)."""
    clipped = clip_draw(scene, draw, inputs)
    tris = setup.setup_triangles(clipped.clip, scene.width, scene.height, precision=inputs.precision,
                                 cull=draw.cull, offsets=inputs.offsets, unit=inputs.unit,
                                 generated=clipped.generated, tie_rule=inputs.tie_rule,
                                 front_face=scene.front_face)
    return clipped, tris


def draw_triangles(scene: Scene, draw, inputs: Pass, color: np.ndarray, depth: np.ndarray) -> None:
    """One triangle draw into the pass's buffers: set up (`set_up_draw`),
    rasterized, interpolated, shaded (unlit, flat, Gouraud or Phong;
    textured, normal or bump mapped) and applied, fragment by fragment in
    draw order."""
    precision, positions, texture_fixed_point = inputs.precision, inputs.positions, inputs.texture_fixed_point
    texture_filter, texture_bounds = inputs.texture_filter, inputs.texture_bounds
    gl = precision == "gl"
    mesh = draw.mesh
    width = scene.width
    clipped, tris = set_up_draw(scene, draw, inputs)
    if len(tris) == 0:
        return

    source, corners = corner_values(clipped, tris, mesh)
    material = draw.material
    base = vertex_base_colors(scene, draw)                 # straight, per vertex
    shading = material.shading
    if shading in ("flat", "phong"):                       # (Gouraud is lit already)
        world = vertex.world_positions(mesh.positions, draw.world)
        eye = vertex.eye_position(scene.camera.view)
    if shading == "flat":
        face_colors = flat_colors(world, source, base, eye, scene.lights, material)[0]
    tex = texture.prepare(scene.textures[material.texture]) if material.texture is not None else None

    # The draw rasterized by bands of rows and its fragments shaded in
    # chunks, in order: a pixel sees the triangles in draw order within
    # its band, and each fragment's work reads only its own triangle and
    # position (texture derivatives included), so the picture is the
    # same, and the fragment list (20 bytes a fragment) and the
    # per-fragment arrays (~300 bytes in exact precision) are bounded by
    # the band and the chunk, not by the draw.
    for bbox in row_bands(tris.bbox, width, len(positions)):
        frags = rasterize.rasterize(dataclasses.replace(tris, bbox=bbox), inputs.offsets, inputs.unit)
        for chunk in fragment_chunks(frags):
            t = chunk.tri
            centres = np.stack([chunk.x + 0.5, chunk.y + 0.5], axis=1)
            persp = interpolate.perspective_weights_at(tris.window[t], tris.inv_w[t], centres)
            z = interpolate.depth_at_samples(tris.window[t], chunk.x, chunk.y, positions)
            if gl:
                z = ops.quantize_depth(z)
            if shading == "flat":
                colors = face_colors[t]
            elif shading == "phong":
                colors, position, normal = phong_attributes(persp, corners, t, base, world, draw)
                if material.normal_map is not None or material.bump_map is not None:
                    normal = mapped_normals(scene, draw, persp, corners, tris, t, chunk, centres, normal,
                                            precision, texture_fixed_point, texture_bounds)
                lit = fragment.blinn_phong(colors[:, :3], position, normal, eye, scene.lights, material)
                colors = np.concatenate([lit, colors[:, 3:]], axis=1)
            else:
                colors = interpolate.interpolate(persp, corners(base)[t])
            texel = None
            if tex is not None:
                corner_uv, st, ddx, ddy = uv_at_fragments(mesh.uvs, corners, persp, tris, t, chunk, centres, gl)
                if texture_bounds is None:
                    texel = texture_beyond.sample_texture(tex, st, ddx, ddy, precision, texture_fixed_point,
                                                          texture_filter)
                else:       # every derivative GL permits: quad differences and analytic
                    candidates = texbounds.fragment_derivatives(tris.window[t], tris.inv_w[t], chunk.x,
                                                                chunk.y, centres, corner_uv)
                    texel = texbounds.render_bound(tex, st, candidates, texbounds.bound_render(texture_bounds)[0])
            rgba = fragment.shade_unlit(colors, np.ones(4), texel)
            x, y, mask = chunk.x, chunk.y, chunk.mask
            if material.alpha_cutoff is not None:      # discard: no depth or colour write for any sample
                passed = fragment.alpha_test(rgba[:, 3], material.alpha_cutoff, precision)
                x, y, mask, z, rgba = x[passed], y[passed], mask[passed], z[passed], rgba[passed]
            ops.apply_fragments(x, y, mask, z, rgba, color, depth,
                                ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                                ops.BLEND_MODES[draw.blend], inputs.quantize)
