"""The one place that creates glref's headless OpenGL context.

`get_context()` returns a moderngl standalone context (EGL, OpenGL >= 3.3 core),
created once per process and cached; `info()` describes it, with the
capability record the verifiers read (sub-pixel bits, sample counts and
positions, anisotropy, size limits). On a CPU machine the GL is Mesa
llvmpipe (or softpipe with ``GALLIUM_DRIVER=softpipe``), on a GPU machine the
vendor driver; ``SOFTRAS_GL_DEVICE=N`` (``--gl-device N``) picks the N-th EGL
device on a machine with several.

Everything that can be missing (the moderngl module, libEGL, a GL 3.3 driver)
is reported as `GLUnavailable` with a one-line message.
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["GLUnavailable", "get_context", "info"]

#: Environment variables that change what llvmpipe does (accuracy/speed
#: trade-offs and threading); recorded in `info()` as seen at context creation.
PERF_ENV_VARS = ("GALLIUM_DRIVER", "GALLIVM_PERF", "LP_PERF", "LP_NUM_THREADS")

#: Environment variable holding the EGL device index glref opens (unset: EGL's
#: default display). Worker processes inherit it.
DEVICE_ENV = "SOFTRAS_GL_DEVICE"

_REQUIRE = 330  # OpenGL 3.3 core: the oldest desktop GL glref draws with

# Cache keyed by process id: a context inherited through fork() is not usable
# in the child, so a forked worker creates its own.
_pid: int | None = None
_ctx = None
_info: dict | None = None
_error: str | None = None


class GLUnavailable(RuntimeError):
    """No headless OpenGL 3.3 core context can be created; str(e) is one line saying why."""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def get_context():
    """The process's cached `moderngl.Context` (created on first use).

    Raises `GLUnavailable` when moderngl is not importable or no OpenGL 3.3
    context can be created through EGL. A failure is cached too, so repeated
    calls fail fast with the same message.
    """
    global _pid, _ctx, _info, _error
    if _pid != os.getpid():
        _pid, _ctx, _info, _error = os.getpid(), None, None, None
    if _ctx is not None:
        return _ctx
    if _error is not None:
        raise GLUnavailable(_error)
    try:
        import moderngl
    except ImportError as exc:
        _error = f"glref: the Python module moderngl is not installed ({_one_line(exc)})"
        raise GLUnavailable(_error) from None
    env = {name: os.environ.get(name) for name in PERF_ENV_VARS}
    device = device_index()
    options = {} if device is None else {"device_index": device}
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=_REQUIRE, **options)
    except Exception as exc:  # moderngl raises its own Error / generic exceptions
        where = f"on EGL device {device}" if device is not None else "via EGL (libEGL / Mesa not installed?)"
        _error = f"glref: no OpenGL 3.3 core context {where}: {_one_line(exc)}"
        raise GLUnavailable(_error) from None
    _ctx = ctx
    _info = {
        "GL_RENDERER": ctx.info.get("GL_RENDERER"),
        "GL_VERSION": ctx.info.get("GL_VERSION"),
        "GL_VENDOR": ctx.info.get("GL_VENDOR"),
        "moderngl": moderngl.__version__,
        "env": env,
        "device_index": device,
        "depth_format": _probe_depth_format(ctx),
        **_capabilities(ctx),
    }
    return ctx


def device_index() -> int | None:
    """The EGL device index from ``SOFTRAS_GL_DEVICE`` (None when unset).

    Raises `GLUnavailable` when it is not a non-negative integer."""
    text = os.environ.get(DEVICE_ENV)
    if text is None or text == "":
        return None
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise GLUnavailable(f"glref: {DEVICE_ENV}={text!r} is not a device index (0, 1, ...)")
    return value


def info() -> dict:
    """Describe the GL that glref renders with (creates the context if needed).

    Keys: GL_RENDERER, GL_VERSION, GL_VENDOR (strings from glGetString),
    moderngl (module version), env ({GALLIUM_DRIVER, GALLIVM_PERF, LP_PERF,
    LP_NUM_THREADS}: value or None, as seen when the context was created),
    device_index (the EGL device, None = default), depth_format (the
    internal format GL chose for glref's depth renderbuffer, e.g.
    "GL_DEPTH_COMPONENT24 (24 depth bits, 0 stencil bits)", or "unknown"),
    and the capability record (`_capabilities`): GL_SHADING_LANGUAGE_VERSION,
    version [major, minor], subpixel_bits (GL_SUBPIXEL_BITS), max_samples
    (GL_MAX_SAMPLES), sample_counts (the sample counts a renderbuffer gets
    exactly: [1, 2, 4, ...]), sample_positions ({"N": [[x, y], ...]} from
    glGetMultisamplefv, in [0, 1)^2 of the pixel, y up), max_anisotropy
    (0.0 when the context has no anisotropic filtering), max_texture_size,
    max_renderbuffer_size, max_viewport_dims [w, h].
    """
    get_context()
    return {k: (dict(v) if isinstance(v, dict) else v) for k, v in _info.items()}


_GL_RENDERBUFFER = 0x8D41
_GL_SAMPLES = 0x80A9
_GL_SAMPLE_POSITION = 0x8E50
_GL_SHADING_LANGUAGE_VERSION = 0x8B8C


def _egl_function(name: str, restype, *argtypes):
    """A GL entry point through eglGetProcAddress (None when missing)."""
    egl = ctypes.CDLL("libEGL.so.1")
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    address = egl.eglGetProcAddress(name.encode())
    return ctypes.CFUNCTYPE(restype, *argtypes)(address) if address else None


def _capabilities(ctx) -> dict:
    """The limits and choices of this GL that decide what a verdict may allow.

    Everything here is queried, never assumed from the renderer's name: the
    spec profile derives its bounds from these numbers (GL 4.6 core, table
    23.53 ff. "Implementation-dependent values").
    """
    gl_info = ctx.info
    aniso = {"GL_ARB_texture_filter_anisotropic", "GL_EXT_texture_filter_anisotropic"}
    has_aniso = ctx.version_code >= 460 or bool(aniso & set(ctx.extensions))
    get_string = _egl_function("glGetString", ctypes.c_char_p, ctypes.c_uint)
    glsl = get_string(_GL_SHADING_LANGUAGE_VERSION) if get_string else None
    counts, positions = _sample_positions(ctx)
    return {
        "GL_SHADING_LANGUAGE_VERSION": glsl.decode() if glsl else None,
        "version": [int(gl_info.get("GL_MAJOR_VERSION", 0)), int(gl_info.get("GL_MINOR_VERSION", 0))],
        "subpixel_bits": int(gl_info.get("GL_SUBPIXEL_BITS", 0)),
        "max_samples": int(ctx.max_samples),
        "sample_counts": counts,
        "sample_positions": positions,
        "max_anisotropy": float(ctx.max_anisotropy) if has_aniso else 0.0,
        "max_texture_size": int(gl_info.get("GL_MAX_TEXTURE_SIZE", 0)),
        "max_renderbuffer_size": int(gl_info.get("GL_MAX_RENDERBUFFER_SIZE", 0)),
        "max_viewport_dims": [int(v) for v in gl_info.get("GL_MAX_VIEWPORT_DIMS", (0, 0))],
    }


def _sample_positions(ctx) -> tuple[list[int], dict[str, list[list[float]]]]:
    """The sample counts a multisample renderbuffer really gets, and their positions.

    For each power of two up to GL_MAX_SAMPLES a renderbuffer of that many
    samples is made and bound; GL_SAMPLES says how many it got (GL may round a
    request up, GL 4.6 section 9.2.4), and glGetMultisamplefv(GL_SAMPLE_POSITION)
    gives each sample's position in the pixel (section 14.3.1; [0, 1)^2, y
    up). Counts GL rounds up are not listed: a scene asking for one of them
    cannot be drawn as asked.
    """
    get_integer = _egl_function("glGetIntegerv", None, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))
    get_position = _egl_function("glGetMultisamplefv", None, ctypes.c_uint, ctypes.c_uint,
                                 ctypes.POINTER(ctypes.c_float))
    counts, positions = [1], {"1": [[0.5, 0.5]]}
    if get_integer is None or get_position is None:
        return counts, positions
    default = ctx.detect_framebuffer(0)
    requested = 2
    while requested <= ctx.max_samples:
        rb = fbo = None
        try:
            rb = ctx.renderbuffer((4, 4), components=4, samples=requested)
            fbo = ctx.framebuffer(color_attachments=[rb])
            fbo.use()
            got = ctypes.c_int(0)
            get_integer(_GL_SAMPLES, ctypes.byref(got))
            if got.value == requested:
                xy = (ctypes.c_float * 2)()
                places = []
                for index in range(requested):
                    get_position(_GL_SAMPLE_POSITION, index, xy)
                    places.append([float(xy[0]), float(xy[1])])
                counts.append(requested)
                positions[str(requested)] = places
        finally:
            default.use()  # never leave a soon-deleted framebuffer bound
            for obj in (fbo, rb):
                if obj is not None:
                    obj.release()
            ctx.error  # clear anything a refused sample count raised
        requested *= 2
    return counts, positions

_DEPTH_FORMAT_NAMES = {
    0x1902: "GL_DEPTH_COMPONENT",
    0x81A5: "GL_DEPTH_COMPONENT16",
    0x81A6: "GL_DEPTH_COMPONENT24",
    0x81A7: "GL_DEPTH_COMPONENT32",
    0x8CAC: "GL_DEPTH_COMPONENT32F",
    0x88F0: "GL_DEPTH24_STENCIL8",
    0x8CAD: "GL_DEPTH32F_STENCIL8",
}


def _probe_depth_format(ctx) -> str:
    """Ask GL which internal format a moderngl depth renderbuffer really has.

    moderngl does not expose glGetRenderbufferParameteriv, so this binds the
    renderbuffer and calls it through eglGetProcAddress (GL 3.0, no direct
    state access). Best effort: returns "unknown" if anything fails.
    """
    rb = None
    try:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        bind_addr = egl.eglGetProcAddress(b"glBindRenderbuffer")
        get_addr = egl.eglGetProcAddress(b"glGetRenderbufferParameteriv")
        if not bind_addr or not get_addr:
            return "unknown"
        bind = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint)(bind_addr)
        get = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint,
                               ctypes.POINTER(ctypes.c_int))(get_addr)
        rb = ctx.depth_renderbuffer((1, 1))
        bind(_GL_RENDERBUFFER, rb.glo)
        values = []
        for pname in (0x8D44, 0x8D54, 0x8D55):  # INTERNAL_FORMAT, DEPTH_SIZE, STENCIL_SIZE
            v = ctypes.c_int(0)
            get(_GL_RENDERBUFFER, pname, ctypes.byref(v))
            values.append(v.value)
        bind(_GL_RENDERBUFFER, 0)
        fmt, depth_bits, stencil_bits = values
        name = _DEPTH_FORMAT_NAMES.get(fmt, hex(fmt))
        return f"{name} ({depth_bits} depth bits, {stencil_bits} stencil bits)"
    except Exception:
        return "unknown"
    finally:
        if rb is not None:
            rb.release()
        ctx.error  # reading GL_ERROR clears anything the probe may have raised
