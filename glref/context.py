"""The one place that creates glref's headless OpenGL context.

`get_context()` returns a moderngl standalone context (EGL, OpenGL >= 3.3 core),
created once per process and cached; `info()` describes it. On a CPU machine
the GL is Mesa llvmpipe, on a GPU machine the vendor driver.

Everything that can be missing (the moderngl module, libEGL, a GL 3.3 driver)
is reported as `GLUnavailable` with a one-line message.
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["GLUnavailable", "get_context", "info"]

#: Environment variables that change what llvmpipe does (accuracy/speed
#: trade-offs and threading); recorded in `info()` as seen at context creation.
PERF_ENV_VARS = ("GALLIVM_PERF", "LP_PERF", "LP_NUM_THREADS")

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
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=_REQUIRE)
    except Exception as exc:  # moderngl raises its own Error / generic exceptions
        _error = ("glref: no OpenGL 3.3 core context via EGL (libEGL / Mesa not "
                  f"installed?): {_one_line(exc)}")
        raise GLUnavailable(_error) from None
    _ctx = ctx
    _info = {
        "GL_RENDERER": ctx.info.get("GL_RENDERER"),
        "GL_VERSION": ctx.info.get("GL_VERSION"),
        "GL_VENDOR": ctx.info.get("GL_VENDOR"),
        "moderngl": moderngl.__version__,
        "env": env,
        "depth_format": _probe_depth_format(ctx),
        "max_samples": ctx.max_samples,
    }
    return ctx


def info() -> dict:
    """Describe the GL that glref renders with (creates the context if needed).

    Keys: GL_RENDERER, GL_VERSION, GL_VENDOR (strings from glGetString),
    moderngl (module version), env ({GALLIVM_PERF, LP_PERF, LP_NUM_THREADS}:
    value or None, as seen when the context was created), depth_format (the
    internal format GL chose for glref's depth renderbuffer, e.g.
    "GL_DEPTH_COMPONENT24 (24 depth bits, 0 stencil bits)", or "unknown"),
    max_samples (GL_MAX_SAMPLES).
    """
    get_context()
    return {k: (dict(v) if isinstance(v, dict) else v) for k, v in _info.items()}


_GL_RENDERBUFFER = 0x8D41

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
