"""glref: the OpenGL reference renderer (moderngl on a headless EGL context).

The only code in the project that imports moderngl. It may import
`softras.scene` and nothing else from softras (DESIGN.md section 1).

    render(scene, *, samples=None, framebuffer=None, mipmaps="generate")
                                                    -> np.ndarray (H, W, 4), row 0 = top
    generate_mipmaps(level0) -> list of levels      glGenerateMipmap's levels, read back
    info() -> dict                                  GL_RENDERER, GL_VERSION, ...
    GLUnavailable                                   no GL context (one-line reason)
"""

from .context import GLUnavailable, info
from .render import generate_mipmaps, render

__all__ = ["render", "generate_mipmaps", "info", "GLUnavailable"]
