"""glref: the OpenGL reference renderer (moderngl on a headless EGL context).

The only code in the project that imports moderngl. It may import
`softras.scene` and nothing else from softras (tests/test_layers.py).

    render(scene, *, samples=None, framebuffer=None, mipmaps="generate")
                                                    -> np.ndarray (H, W, 4), row 0 = top
    generate_mipmaps(level0) -> list of levels      glGenerateMipmap's levels, read back
    info() -> dict                                  GL_RENDERER, GL_VERSION, capabilities ...
    unsupported(scene, *, samples=None) -> str|None why this context cannot draw it
    GLUnavailable                                   no GL context (one-line reason)
    NotSupported                                    the context lacks what a scene needs
"""

from .context import DEVICE_ENV, GLUnavailable, info
from .render import NotSupported, generate_mipmaps, render, unsupported

__all__ = ["render", "generate_mipmaps", "unsupported", "info", "GLUnavailable", "NotSupported", "DEVICE_ENV"]
