"""glref: render a `softras.scene.Scene` with real OpenGL (moderngl, headless EGL).

This is the reference the software pipeline is checked against, so it does the
plainest possible thing: one draw call per `Draw`, in `scene.draws` order, with
the GL state the scene asks for and small shaders specialised per feature set
by `#define` (DESIGN.md sections 2 and 3).

Spaces: positions are model space; `u_mvp` = P @ V @ world maps them to clip
space (computed in float64 on the CPU, uploaded as float32); GL does the rest
(clipping, perspective divide, viewport transform to window coordinates with y
up, rasterization, depth test, blending into an RGBA8 framebuffer). The
readback is flipped so the returned image has row 0 = top of the picture.
"""

from __future__ import annotations

from importlib import resources

import numpy as np

from .context import get_context

__all__ = ["render"]

# DESIGN.md section 5 depth_test names -> moderngl depth_func strings.
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


def _shader_source(name: str, defines: tuple[str, ...]) -> str:
    """Shader text with `#define NAME` lines inserted right after `#version`."""
    text = resources.files("glref.shaders").joinpath(name).read_text(encoding="utf-8")
    first, _, rest = text.partition("\n")
    if not first.startswith("#version"):
        raise RuntimeError(f"glref: shader {name} must start with a #version line")
    lines = "".join(f"#define {d} 1\n" for d in defines)
    return f"{first}\n{lines}#line 2\n{rest}"


def _reset_cache(ctx) -> None:
    """Forget objects cached for another context (e.g. one inherited by fork)."""
    global _cache_ctx, _framebuffer0
    if _cache_ctx is not ctx:
        _programs.clear()
        _framebuffer0 = ctx.detect_framebuffer(0)
        _cache_ctx = ctx


def _program(ctx, defines: tuple[str, ...]):
    """The compiled program for a feature set (cached for the process's context)."""
    prog = _programs.get(defines)
    if prog is None:
        vert, frag = (_shader_source(n, defines) for n in _SHADER_FILES)
        prog = ctx.program(vertex_shader=vert, fragment_shader=frag)
        _programs[defines] = prog
    return prog


def _features(draw) -> tuple[str, ...]:
    """The sorted #defines a draw needs; raises for what glref cannot draw yet."""
    mat = draw.material
    if getattr(mat, "texture", None) is not None:
        raise NotImplementedError(
            f"glref: {draw.path}: textured materials are not supported by glref yet")
    if getattr(mat, "shading", "unlit") != "unlit":
        raise NotImplementedError(
            f"glref: {draw.path}: shading {mat.shading!r} is not supported by glref yet "
            "(only 'unlit')")
    defines = []
    if draw.mesh.colors is not None:
        defines.append("HAS_COLOR")
    return tuple(sorted(defines))


def _drain_errors(ctx) -> None:
    """Clear GL errors left by anything before this render."""
    for _ in range(32):
        if ctx.error == "GL_NO_ERROR":
            return


def render(scene, *, samples: int | None = None) -> np.ndarray:
    """Render `scene` with OpenGL and return the picture.

    scene:   a `softras.scene.Scene` (a dict or a path is loaded with
             `softras.scene.load_scene`).
    samples: 1 = single-sampled, N > 1 = N-sample MSAA (resolved to one
             sample per pixel by a framebuffer blit, i.e. the driver's box
             average); None = `scene.samples`.

    Returns uint8 (H, W, 4) RGBA, premultiplied, row 0 = top of the picture
    (GL's last row), column 0 = left.
    Raises `GLUnavailable` when there is no GL, `NotImplementedError` for
    scene features glref does not draw yet, RuntimeError on a GL error.
    """
    if not hasattr(scene, "draws"):
        from softras.scene import load_scene  # the one softras import glref may do
        scene = load_scene(scene)
    ctx = get_context()
    import moderngl as mgl

    width, height = int(scene.width), int(scene.height)
    n_samples = int(scene.samples if samples is None else samples)
    if n_samples < 1 or n_samples > ctx.max_samples:
        raise ValueError(f"glref: samples={n_samples} not in 1..{ctx.max_samples}")
    msaa = 0 if n_samples == 1 else n_samples
    size = (width, height)

    features = [_features(d) for d in scene.draws]  # fail before touching GL
    proj_view = np.asarray(scene.camera.projection, np.float64) @ np.asarray(
        scene.camera.view, np.float64)

    _reset_cache(ctx)
    _drain_errors(ctx)
    owned = []  # GL objects created by this render, released in `finally`

    def own(obj):
        owned.append(obj)
        return obj

    try:
        color_rb = own(ctx.renderbuffer(size, components=4, samples=msaa, dtype="f1"))
        depth_rb = own(ctx.depth_renderbuffer(size, samples=msaa))
        fbo = own(ctx.framebuffer(color_attachments=[color_rb], depth_attachment=depth_rb))
        fbo.viewport = (0, 0, width, height)
        fbo.use()

        bg = np.asarray(scene.background, np.float64)
        fbo.depth_mask = True
        fbo.color_mask = (True, True, True, True)
        fbo.clear(float(bg[0] * bg[3]), float(bg[1] * bg[3]), float(bg[2] * bg[3]),
                  float(bg[3]), depth=1.0)

        ctx.front_face = "ccw"
        ctx.line_width = 1.0
        ctx.multisample = True
        ctx.wireframe = False

        for draw, defines in zip(scene.draws, features):
            mesh = draw.mesh
            indices = np.ascontiguousarray(mesh.indices, dtype=np.int32).reshape(-1)
            if indices.size == 0 or len(mesh.positions) == 0:
                continue
            prog = _program(ctx, defines)
            mvp = proj_view @ np.asarray(draw.world, np.float64)
            # GLSL mat4 is column-major: upload the transpose's row-major bytes.
            prog["u_mvp"].write(np.ascontiguousarray(mvp.astype(np.float32).T).tobytes())
            prog["u_color"].value = tuple(float(c) for c in draw.material.color)

            content = [(own(ctx.buffer(np.ascontiguousarray(mesh.positions, np.float32))),
                        "3f", "in_position")]
            if "HAS_COLOR" in defines:
                content.append((own(ctx.buffer(np.ascontiguousarray(mesh.colors, np.float32))),
                                "4f", "in_color"))
            ibo = own(ctx.buffer(indices))
            vao = own(ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4))

            _apply_state(ctx, mgl, fbo, draw)
            mode = mgl.LINES if mesh.primitive == "lines" else mgl.TRIANGLES
            vao.render(mode)

        if msaa:
            resolved_rb = own(ctx.renderbuffer(size, components=4, dtype="f1"))
            resolved = own(ctx.framebuffer(color_attachments=[resolved_rb]))
            ctx.copy_framebuffer(resolved, fbo)
            read_fbo = resolved
        else:
            read_fbo = fbo
        data = read_fbo.read(viewport=(0, 0, width, height), components=4,
                             dtype="f1", alignment=1)
        err = ctx.error
        if err != "GL_NO_ERROR":
            raise RuntimeError(f"glref: OpenGL error {err} while rendering {scene.source}")
    finally:
        _framebuffer0.use()  # never leave a soon-deleted framebuffer bound
        for obj in reversed(owned):
            obj.release()

    image = np.frombuffer(data, dtype=np.uint8).reshape(height, width, 4)
    return np.ascontiguousarray(image[::-1])  # GL row 0 is the bottom


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
