"""glref: render a `softras.scene.Scene` with real OpenGL (moderngl, headless EGL).

This is the reference the software pipeline is checked against, so it does the
plainest possible thing: one draw call per `Draw`, in `ordered_draws(scene)`
order (`softras.scene`: `scene.draws`, or the lecture's opaque-then-sorted
transparency order when the scene asks for it), with
the GL state the scene asks for and small shaders specialised per feature set
by `#define` (docs/design.md sections 2 and 4).

Spaces: positions are model space; `u_mvp` = P @ V @ world maps them to clip
space (computed in float64 on the CPU, uploaded as float32); GL does the rest
(clipping, perspective divide, viewport transform to window coordinates with y
up, rasterization, depth test, blending into an RGBA8 -- or, for a scene's
"framebuffer": "rgba32f", an RGBA32F -- renderbuffer). The
readback is flipped so the returned image has row 0 = top of the picture.

Textures: level 0 comes from `softras.scene.Texture.levels` (premultiplied
RGBA8, the bytes softras samples) and GL builds the other levels itself with
glGenerateMipmap (GL 4.6 section 8.14.4), so GL's mip generation is part of
what softras is compared with (softras.scene.texels.mip_chain reproduces llvmpipe's
byte for byte; ``mipmaps="upload"`` uploads softras's chain instead).  The
sampler state is set with glTexParameteri on the bound texture.  Lighting
(flat / gouraud / phong Blinn-Phong in world space) uses lit.vert / lit.frag
with lighting.glsl, and lit.geom.glsl for flat shading.  A Phong material's normal or bump map is a
second sampler (unit 1) with the scene model's per-vertex tangents
(``Mesh.tangents``) as the attribute ``in_tangent``; displaced meshes arrive already displaced in ``Draw.mesh``.
A material's ``alpha_cutoff`` is the ALPHA_TEST variant: the fragment shader
discards a fragment whose final alpha is below ``u_alpha_cutoff``. The
scene's ``front_face`` is glFrontFace.  llvmpipe's sampling depends on
GALLIVM_PERF, read once per process and recorded by `glref.info()`.
"""

from __future__ import annotations

import contextlib
from importlib import resources

import numpy as np

from .context import get_context, info

__all__ = ["render", "generate_mipmaps", "unsupported", "NotSupported"]


class NotSupported(ValueError):
    """The scene needs something this GL context does not offer (dEQP's
    NotSupported); str(e) is one line naming what."""

# The scene format's depth_test names (docs/scene_format.md) -> moderngl depth_func strings.
_DEPTH_FUNCS = {
    "never": "0", "less": "<", "equal": "==", "lequal": "<=",
    "greater": ">", "notequal": "!=", "gequal": ">=", "always": "1",
}

_CULL = ("none", "back", "front")

_BLEND_NAMES = ("none", "over", "over_straight", "add", "subtract",
                "reverse_subtract", "min", "max")

_SHADER_FILES = ("unlit.vert", "unlit.frag")

# Per-context cache: programs compiled for it, keyed by their sorted #defines,
# and a wrapper of framebuffer 0 to bind before a render's framebuffers are
# released (moderngl re-binds the "current" framebuffer when it creates the
# next one; if that is a deleted name GL raises GL_INVALID_OPERATION).
_programs: dict[tuple[str, ...], object] = {}
_cache_ctx = None
_framebuffer0 = None

# The diagnostic probe in force (`fragment_probe`): (shader, define,
# extensions, expression), or None.
_probe: tuple | None = None


def _blend_state(mgl, blend: str):
    """(blend_func (src, dst), blend_equation) for a scene blend mode, or None for "none".

    Factors apply to RGB and alpha alike (glBlendFunc / glBlendEquation). The
    fragment shader writes premultiplied colour, so "over" is src + (1-src.a)·dst.
    """
    one = (mgl.ONE, mgl.ONE)
    table = {
        "none": None,
        "over": ((mgl.ONE, mgl.ONE_MINUS_SRC_ALPHA), mgl.FUNC_ADD),
        "over_straight": ((mgl.SRC_ALPHA, mgl.ONE_MINUS_SRC_ALPHA), mgl.FUNC_ADD),
        "add": (one, mgl.FUNC_ADD),
        "subtract": (one, mgl.FUNC_SUBTRACT),                  # src - dst
        "reverse_subtract": (one, mgl.FUNC_REVERSE_SUBTRACT),  # dst - src
        "min": (one, mgl.MIN),                                 # factors ignored by GL
        "max": (one, mgl.MAX),
    }
    return table[blend]


def _shader_text(name: str) -> str:
    return resources.files("glref.shaders").joinpath(name).read_text(encoding="utf-8")


def _shader_source(name: str, defines: tuple[str, ...], prelude: str = "") -> str:
    """Shader text with `#define` lines (and `prelude`, e.g. shared functions)
    inserted right after `#version`.  A define "NAME=VALUE" becomes
    `#define NAME VALUE`, a plain "NAME" `#define NAME 1`."""
    text = _shader_text(name)
    first, _, rest = text.partition("\n")
    if not first.startswith("#version"):
        raise RuntimeError(f"glref: shader {name} must start with a #version line")
    lines = "".join(f"#define {d.replace('=', ' ')}\n" if "=" in d else f"#define {d} 1\n"
                    for d in defines)
    if _probe is not None and _probe[0] == name and _probe[1] in defines:
        _, _, extensions, expression = _probe
        lines = "".join(f"#extension {e} : require\n" for e in extensions) + lines
        end = rest.rstrip().rfind("}")
        # (The shaded colour stays a vanishing term: no uniform glref sets is optimised away.)
        rest = rest[:end] + f"    f_color = ({expression}) + step(vec4(1e30), abs(f_color)) * 1e-30;\n}}\n"
    return f"{first}\n{lines}{prelude}#line 2\n{rest}"


@contextlib.contextmanager
def fragment_probe(expression: str, *, shader: str, when: str, extensions: tuple[str, ...] = ()):
    """Within the block, the fragment shader ``shader`` ("lit.frag" or
    "unlit.frag") in its variants with the #define ``when`` writes the GLSL
    vec4 ``expression`` (over the shader's own names) as its colour: a probe
    that asks the GL what it computed (scripts/lod_query.py: the texture's
    level of detail; scripts/msaa_shading.py: the samples an invocation
    covers).  ``extensions``: the GLSL extensions the expression requires.
    Programs compiled before or inside the block are dropped on entry and
    exit; render to an rgba32f framebuffer to read unclamped values."""
    global _probe
    if shader not in ("lit.frag", "unlit.frag"):
        raise ValueError(f"glref: a probe replaces lit.frag's or unlit.frag's output, not {shader!r}'s")
    _programs.clear()
    _probe = (shader, when, tuple(extensions), expression)
    try:
        yield
    finally:
        _probe = None
        _programs.clear()


def _reset_cache(ctx) -> None:
    """Forget objects cached for another context (e.g. one inherited by fork)."""
    global _cache_ctx, _framebuffer0
    if _cache_ctx is not ctx:
        _programs.clear()
        _framebuffer0 = ctx.detect_framebuffer(0)
        _cache_ctx = ctx


def _program(ctx, defines: tuple[str, ...]):
    """The compiled program for a feature set (cached for the process's context).

    Unlit materials use unlit.vert/.frag; lit ones lit.vert/.frag with
    lighting.glsl pasted in, and lit.geom.glsl for flat shading."""
    prog = _programs.get(defines)
    if prog is None:
        if any(d.startswith("SHADING_") for d in defines):
            prelude = _shader_text("lighting.glsl")
            vert, frag = (_shader_source(n, defines, prelude) for n in ("lit.vert", "lit.frag"))
            geom = (_shader_source("lit.geom.glsl", defines, prelude)
                    if "SHADING_FLAT" in defines else None)
            prog = ctx.program(vertex_shader=vert, fragment_shader=frag, geometry_shader=geom)
        else:
            vert, frag = (_shader_source(n, defines) for n in _SHADER_FILES)
            prog = ctx.program(vertex_shader=vert, fragment_shader=frag)
        _programs[defines] = prog
    return prog


def _features(draw, n_lights: int) -> tuple[str, ...]:
    """The sorted #defines a draw needs; raises for what glref cannot draw."""
    mat = draw.material
    defines = []
    if mat.shading != "unlit":
        if draw.mesh.primitive != "triangles":
            raise NotImplementedError(f"glref: {draw.path}: lit {draw.mesh.primitive} are not supported")
        defines.append(f"SHADING_{mat.shading.upper()}")
        # No lights: one black light keeps the shader valid (ambient only).
        defines.append(f"NUM_LIGHTS={max(1, n_lights)}")
    if draw.mesh.colors is not None:
        defines.append("HAS_COLOR")
    if mat.texture is not None:
        defines.append("HAS_TEXTURE")
    if mat.normal_map is not None or mat.bump_map is not None:
        if mat.shading != "phong":
            raise NotImplementedError(f"glref: {draw.path}: normal and bump maps need phong shading")
        defines.append("NORMAL_MAP" if mat.normal_map is not None else "BUMP_MAP")
    if mat.alpha_cutoff is not None:
        if draw.mesh.primitive != "triangles":
            raise NotImplementedError(f"glref: {draw.path}: alpha test on {draw.mesh.primitive}")
        defines.append("ALPHA_TEST")
    return tuple(sorted(defines))


# GL enums for the sampler state (glTexParameteri on the bound texture).
_GL_TEXTURE_2D = 0x0DE1
_GL_TEXTURE_MAG_FILTER = 0x2800
_GL_TEXTURE_MIN_FILTER = 0x2801
_GL_TEXTURE_WRAP_S = 0x2802
_GL_TEXTURE_WRAP_T = 0x2803
_GL_TEXTURE_BASE_LEVEL = 0x813C
_GL_TEXTURE_MAX_LEVEL = 0x813D
_GL_TEXTURE_MAX_ANISOTROPY = 0x84FE
_GL_WRAP = {"repeat": 0x2901, "clamp_to_edge": 0x812F, "mirrored_repeat": 0x8370}
_GL_FILTER = {"nearest": 0x2600, "linear": 0x2601,
              "nearest_mipmap_nearest": 0x2700, "linear_mipmap_nearest": 0x2701,
              "nearest_mipmap_linear": 0x2702, "linear_mipmap_linear": 0x2703}
_gl_functions: dict = {}


def _gl_function(name: str, *argtypes):
    """A GL entry point through eglGetProcAddress (moderngl exposes no
    GL_MIRRORED_REPEAT and no GL_TEXTURE_MAX_LEVEL setter)."""
    fn = _gl_functions.get(name)
    if fn is None:
        import ctypes
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        address = egl.eglGetProcAddress(name.encode())
        if not address:
            raise RuntimeError(f"glref: no GL entry point {name}")
        fn = ctypes.CFUNCTYPE(None, *argtypes)(address)
        _gl_functions[name] = fn
    return fn


#: How glref fills a mipmapped texture's levels 1..n: "generate" (GL's own
#: glGenerateMipmap from level 0, the default) or "upload" (softras's chain,
#: `Texture.levels`, written level by level: for tests that give the levels
#: contents of their own).
MIPMAPS = ("generate", "upload")


def _check_mipmaps(mipmaps: str) -> None:
    if mipmaps not in MIPMAPS:
        raise ValueError(f"glref: mipmaps must be one of {MIPMAPS}, not {mipmaps!r}")


def _mip_texture(ctx, level0: np.ndarray, n_levels: int, levels=None):
    """A GL_RGBA8 texture of (H, W, 4) uint8 ``level0`` and levels 1..n_levels-1.

    Levels 1.. come from glGenerateMipmap (moderngl's ``build_mipmaps(0,
    n - 1)`` sets GL_TEXTURE_BASE_LEVEL 0 and GL_TEXTURE_MAX_LEVEL n - 1 and
    calls it; it also sets the filters to linear_mipmap_linear / linear), or,
    when ``levels`` is given (level 0 first), are overwritten with ``levels[1:]``.
    Row 0 of an array is the first row uploaded, GL's t = 0.
    """
    height, width = level0.shape[:2]
    tex = ctx.texture((width, height), 4, np.ascontiguousarray(level0, np.uint8).tobytes(), alignment=1)
    if n_levels > 1:
        tex.build_mipmaps(0, n_levels - 1)
        if levels is not None:
            for i, level in enumerate(levels[1:n_levels], start=1):
                tex.write(np.ascontiguousarray(level, np.uint8).tobytes(), level=i, alignment=1)
    return tex


def generate_mipmaps(level0: np.ndarray) -> list[np.ndarray]:
    """What this context's glGenerateMipmap makes of ``level0``: (H, W, 4)
    uint8 RGBA8 in, every level ``max(1, floor(size / 2))`` down to 1x1 read
    back, level 0 first, each (H_l, W_l, 4) uint8, row 0 = t 0.

    The call glref's textures get their levels from (`_upload_texture`); on
    llvmpipe `softras.scene.texels.mip_chain` reproduces it byte for byte.
    """
    ctx = get_context()
    level0 = np.ascontiguousarray(level0, np.uint8)
    height, width = level0.shape[:2]
    n_levels = max(width, height).bit_length()
    tex = _mip_texture(ctx, level0, n_levels)
    try:
        out, w, h = [], width, height
        for i in range(n_levels):
            out.append(np.frombuffer(tex.read(level=i, alignment=1), np.uint8).reshape(h, w, 4).copy())
            w, h = max(1, w // 2), max(1, h // 2)
        err = ctx.error
        if err != "GL_NO_ERROR":
            raise RuntimeError(f"glref: OpenGL error {err} while generating mipmaps")
    finally:
        tex.release()
    return out


def _upload_texture(ctx, texture, unit: int, mipmaps: str = "generate"):
    """A GL texture with softras's level 0 and the scene's sampler state.

    Level 0 is ``Texture.levels[0]`` of the scene model (premultiplied RGBA8,
    the bytes softras samples).  A mipmapped texture gets levels
    ``max(1, floor(size / 2))`` down to 1x1 (``max(W, H).bit_length()`` in
    all; GL_TEXTURE_MAX_LEVEL the last): with ``mipmaps="generate"`` from
    glGenerateMipmap, with "upload" from ``Texture.levels`` (`_mip_texture`).
    """
    import ctypes

    _check_mipmaps(mipmaps)
    level0 = texture.levels[0]
    height, width = level0.shape[:2]
    n_levels = max(width, height).bit_length() if texture.mipmapped else 1
    tex = _mip_texture(ctx, level0, n_levels, texture.levels if mipmaps == "upload" else None)
    # GL 3.3 has no direct state access: bind the texture (to the unit it is
    # sampled from), set its parameters.
    tex.use(unit)
    parami = _gl_function("glTexParameteri", ctypes.c_uint, ctypes.c_uint, ctypes.c_int)
    paramf = _gl_function("glTexParameterf", ctypes.c_uint, ctypes.c_uint, ctypes.c_float)
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_BASE_LEVEL, 0)
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_MAX_LEVEL, n_levels - 1)
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_MIN_FILTER, _GL_FILTER[texture.min_filter])
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_MAG_FILTER, _GL_FILTER[texture.mag_filter])
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_WRAP_S, _GL_WRAP[texture.wrap_s])
    parami(_GL_TEXTURE_2D, _GL_TEXTURE_WRAP_T, _GL_WRAP[texture.wrap_t])
    if has_anisotropy(ctx):
        paramf(_GL_TEXTURE_2D, _GL_TEXTURE_MAX_ANISOTROPY, float(texture.max_anisotropy))
    return tex


def has_anisotropy(ctx) -> bool:
    """Whether the context offers anisotropic filtering (core in GL 4.6, else
    GL_ARB_texture_filter_anisotropic or GL_EXT_texture_filter_anisotropic)."""
    return ctx.version_code >= 460 or bool(
        {"GL_ARB_texture_filter_anisotropic", "GL_EXT_texture_filter_anisotropic"} & set(ctx.extensions))


def _drain_errors(ctx) -> None:
    """Clear GL errors left by anything before this render."""
    for _ in range(32):
        if ctx.error == "GL_NO_ERROR":
            return


def unsupported(scene, *, samples: int | None = None, capabilities: dict | None = None) -> str | None:
    """Why this GL context cannot draw `scene` as asked, or None when it can.

    Checked against the context's capability record (`glref.info()`, or
    `capabilities` when given): the sample count must be one GL gives exactly
    (a request it rounds up to more samples would be a different picture),
    the picture within GL_MAX_RENDERBUFFER_SIZE / GL_MAX_VIEWPORT_DIMS, every
    texture within GL_MAX_TEXTURE_SIZE, and anisotropic filtering present
    where a texture asks for max_anisotropy > 1.
    """
    caps = info() if capabilities is None else capabilities
    n = int(scene.samples if samples is None else samples)
    if n not in caps["sample_counts"]:
        offered = ", ".join(str(c) for c in caps["sample_counts"])
        return f"{n} samples per pixel (this GL renders {offered})"
    limit = min(caps["max_renderbuffer_size"], *caps["max_viewport_dims"])
    if max(scene.width, scene.height) > limit:
        return f"a {scene.width}x{scene.height} picture (largest framebuffer {limit})"
    for name, texture in getattr(scene, "textures", {}).items():
        height, width = texture.levels[0].shape[:2]
        if max(width, height) > caps["max_texture_size"]:
            return (f"texture {name!r} of {width}x{height} texels "
                    f"(GL_MAX_TEXTURE_SIZE {caps['max_texture_size']})")
        if texture.max_anisotropy > 1 and caps["max_anisotropy"] < 1:
            return f"texture {name!r}: anisotropic filtering (no GL_ARB_texture_filter_anisotropic)"
    return None


def render(scene, *, samples: int | None = None, framebuffer: str | None = None,
           mipmaps: str = "generate") -> np.ndarray:
    """Render `scene` with OpenGL and return the picture.

    scene:   a `softras.scene.Scene` (a dict or a path is loaded with
             `softras.scene.load_scene`).
    samples: 1 = single-sampled, N > 1 = N-sample MSAA (resolved to one
             sample per pixel by a framebuffer blit, i.e. the driver's box
             average); None = `scene.samples`.
    framebuffer: "rgba8" (GL_RGBA8 renderbuffer) or "rgba32f" (GL_RGBA32F:
             no clamping, float32 blending); None = `scene.framebuffer`.
    mipmaps: how mipmapped textures get levels 1..n (`MIPMAPS`): "generate"
             = glGenerateMipmap from level 0, "upload" = softras's
             `Texture.levels`.

    Draws are issued in `softras.scene.ordered_draws` order (the scene's
    "render_order"), the same list softras draws.

    Returns (H, W, 4) RGBA, premultiplied, row 0 = top of the picture (GL's
    last row), column 0 = left: uint8 for rgba8, float32 for rgba32f.
    Raises `GLUnavailable` when there is no GL, `NotSupported` when the
    context lacks what the scene needs (`unsupported`), `NotImplementedError`
    for scene features glref does not draw yet, RuntimeError on a GL error.
    """
    from softras.scene import FRAMEBUFFERS, FRONT_FACES, load_scene, ordered_draws  # the softras module glref may import
    if not hasattr(scene, "draws"):
        scene = load_scene(scene)
    framebuffer = framebuffer or getattr(scene, "framebuffer", "rgba8")
    if framebuffer not in FRAMEBUFFERS:
        raise ValueError(f"glref: framebuffer must be one of {FRAMEBUFFERS}, not {framebuffer!r}")
    _check_mipmaps(mipmaps)
    dtype = "f1" if framebuffer == "rgba8" else "f4"
    draws = ordered_draws(scene)
    ctx = get_context()
    import moderngl as mgl

    width, height = int(scene.width), int(scene.height)
    n_samples = int(scene.samples if samples is None else samples)
    reason = unsupported(scene, samples=n_samples)
    if reason is not None:
        raise NotSupported(f"glref: this OpenGL cannot draw {reason}")
    msaa = 0 if n_samples == 1 else n_samples
    size = (width, height)

    features = [_features(d, len(scene.lights)) for d in draws]  # fail before touching GL
    proj_view = np.asarray(scene.camera.projection, np.float64) @ np.asarray(
        scene.camera.view, np.float64)

    _reset_cache(ctx)
    _drain_errors(ctx)
    owned = []  # GL objects created by this render, released in `finally`

    def own(obj):
        owned.append(obj)
        return obj

    uploaded = {}   # texture name -> its GL texture: uploaded (and mipmapped) once a render, as an app would

    def bind_texture(name: str, unit: int):
        tex = uploaded.get(name)
        if tex is None:
            tex = uploaded[name] = own(_upload_texture(ctx, scene.textures[name], unit, mipmaps))
        else:
            tex.use(unit)
        return tex

    try:
        color_rb = own(ctx.renderbuffer(size, components=4, samples=msaa, dtype=dtype))
        depth_rb = own(ctx.depth_renderbuffer(size, samples=msaa))
        fbo = own(ctx.framebuffer(color_attachments=[color_rb], depth_attachment=depth_rb))
        fbo.viewport = (0, 0, width, height)
        fbo.use()

        bg = np.asarray(scene.background, np.float64)
        fbo.depth_mask = True
        fbo.color_mask = (True, True, True, True)
        fbo.clear(float(bg[0] * bg[3]), float(bg[1] * bg[3]), float(bg[2] * bg[3]),
                  float(bg[3]), depth=1.0)

        front_face = scene.front_face
        if front_face not in FRONT_FACES:
            raise ValueError(f"glref: unknown front_face {front_face!r}")
        ctx.front_face = front_face             # glFrontFace: which winding culling calls front
        ctx.line_width = 1.0
        ctx.multisample = True
        ctx.wireframe = False

        for draw, defines in zip(draws, features):
            mesh = draw.mesh
            indices = np.ascontiguousarray(mesh.indices, dtype=np.int32).reshape(-1)
            if indices.size == 0 or len(mesh.positions) == 0:
                continue
            prog = _program(ctx, defines)
            mvp = proj_view @ np.asarray(draw.world, np.float64)
            # GLSL mat4 is column-major: upload the transpose's row-major bytes.
            prog["u_mvp"].write(np.ascontiguousarray(mvp.astype(np.float32).T).tobytes())
            prog["u_color"].value = tuple(float(c) for c in draw.material.color)
            if "ALPHA_TEST" in defines:
                prog["u_alpha_cutoff"].value = float(draw.material.alpha_cutoff)

            content = [(own(ctx.buffer(np.ascontiguousarray(mesh.positions, np.float32))),
                        "3f", "in_position")]
            if "HAS_COLOR" in defines:
                content.append((own(ctx.buffer(np.ascontiguousarray(mesh.colors, np.float32))),
                                "4f", "in_color"))
            if any(d.startswith("SHADING_") for d in defines):
                _set_lighting(prog, scene, draw)
                if "SHADING_FLAT" not in defines:
                    content.append((own(ctx.buffer(np.ascontiguousarray(mesh.normals, np.float32))),
                                    "3f", "in_normal"))
            mapped = "NORMAL_MAP" in defines or "BUMP_MAP" in defines
            if "HAS_TEXTURE" in defines or mapped:
                content.append((own(ctx.buffer(np.ascontiguousarray(mesh.uvs, np.float32))),
                                "2f", "in_uv"))
            if "HAS_TEXTURE" in defines:
                bind_texture(draw.material.texture, 0)
                prog["u_texture"].value = 0
            if mapped:
                content.append(_set_normal_mapping(ctx, prog, draw, own, bind_texture))
            ibo = own(ctx.buffer(indices))
            vao = own(ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4))

            _apply_state(ctx, mgl, fbo, draw)
            mode = mgl.LINES if mesh.primitive == "lines" else mgl.TRIANGLES
            vao.render(mode)

        if msaa:
            resolved_rb = own(ctx.renderbuffer(size, components=4, dtype=dtype))
            resolved = own(ctx.framebuffer(color_attachments=[resolved_rb]))
            ctx.copy_framebuffer(resolved, fbo)
            read_fbo = resolved
        else:
            read_fbo = fbo
        data = read_fbo.read(viewport=(0, 0, width, height), components=4,
                             dtype=dtype, alignment=1)
        err = ctx.error
        if err != "GL_NO_ERROR":
            raise RuntimeError(f"glref: OpenGL error {err} while rendering {scene.source}")
    finally:
        _framebuffer0.use()  # never leave a soon-deleted framebuffer bound
        for obj in reversed(owned):
            obj.release()

    image = np.frombuffer(data, dtype=np.uint8 if dtype == "f1" else np.float32).reshape(height, width, 4)
    return np.ascontiguousarray(image[::-1])  # GL row 0 is the bottom


def _write_matrix(uniform, matrix: np.ndarray) -> None:
    """Upload a float64 matrix to a GLSL matN (column-major)."""
    uniform.write(np.ascontiguousarray(np.asarray(matrix, np.float64).astype(np.float32).T).tobytes())


def _set_lighting(prog, scene, draw) -> None:
    """Uniforms of lighting.glsl and lit.vert (world space, float64 on the CPU)."""
    world = np.asarray(draw.world, np.float64)
    _write_matrix(prog["u_world"], world)
    if "u_normal_matrix" in prog:
        _write_matrix(prog["u_normal_matrix"], np.linalg.inv(world[:3, :3]).T)
    eye = np.linalg.inv(np.asarray(scene.camera.view, np.float64))[:3, 3]
    prog["u_eye"].value = tuple(float(v) for v in eye)
    lights = np.zeros((max(1, len(scene.lights)), 4), np.float32)
    colors = np.zeros((len(lights), 3), np.float32)
    for i, light in enumerate(scene.lights):
        if light.type == "point":
            lights[i] = (*light.position, 1.0)
        else:
            lights[i] = (*(-np.asarray(light.direction)), 0.0)
        colors[i] = light.color
    prog["u_light"].write(lights.tobytes())
    prog["u_light_color"].write(colors.tobytes())
    mat = draw.material
    for name in ("ambient", "diffuse", "specular", "shininess"):
        prog[f"u_{name}"].value = float(getattr(mat, name))


def _set_normal_mapping(ctx, prog, draw, own, bind_texture):
    """Normal / bump map of a Phong draw: the map on texture unit 1
    (``bind_texture(name, unit)``: the render's GL texture of it), its
    uniforms, and the vertex buffer of the mesh's tangents (``Mesh.tangents``:
    the same values softras interpolates).  Returns the (buffer, format, name) VAO entry."""
    mesh, mat = draw.mesh, draw.material
    name = mat.normal_map if mat.normal_map is not None else mat.bump_map
    tex = bind_texture(name, 1)
    if mat.normal_map is not None:
        prog["u_normal_map"].value = 1
    else:
        prog["u_bump_map"].value = 1
        width, height = tex.size
        prog["u_bump_texel"].value = (1.0 / width, 1.0 / height)
        prog["u_bump_scale"].value = float(mat.bump_scale)
    prog["u_handedness"].value = -1.0 if np.linalg.det(np.asarray(draw.world)[:3, :3]) < 0 else 1.0
    return (own(ctx.buffer(np.ascontiguousarray(mesh.tangents, np.float32))), "4f", "in_tangent")


def _apply_state(ctx, mgl, fbo, draw) -> None:
    """Set depth, cull and blend state for one draw (all of it, every time)."""
    flags = 0
    if draw.depth_test is not None:
        if draw.depth_test not in _DEPTH_FUNCS:
            raise ValueError(f"glref: {draw.path}: unknown depth_test {draw.depth_test!r}")
        flags |= mgl.DEPTH_TEST
        ctx.depth_func = _DEPTH_FUNCS[draw.depth_test]
    # With GL_DEPTH_TEST disabled GL writes no depth whatever the mask says.
    fbo.depth_mask = bool(draw.depth_write)

    if draw.cull not in _CULL:
        raise ValueError(f"glref: {draw.path}: unknown cull {draw.cull!r}")
    if draw.cull != "none":
        flags |= mgl.CULL_FACE
        ctx.cull_face = draw.cull

    if draw.blend not in _BLEND_NAMES:
        raise ValueError(f"glref: {draw.path}: unknown blend {draw.blend!r}")
    state = _blend_state(mgl, draw.blend)
    if state is not None:
        flags |= mgl.BLEND
        ctx.blend_func, ctx.blend_equation = state

    ctx.enable_only(flags)
