"""softras: a reference software rasterizer, cross-checked against OpenGL.

Public API (DESIGN.md section 6):

- ``load_scene(path_or_dict) -> Scene``
- ``render(scene, backend="soft", **options) -> (H, W, 4) uint8``, row 0 = top
  (float32 for an rgba32f framebuffer)
- ``compare(a, b, **tolerance) -> Comparison``
"""

from __future__ import annotations

from .scene import Scene, SceneError, load_scene

__all__ = ["Scene", "SceneError", "load_scene", "render", "compare"]


def render(scene, backend: str = "soft", **options):
    """Render a scene (a Scene, a dict or a path) with softras or glref.

    backend : "soft" (the software pipeline; options ``precision``,
    ``samples``, ``pattern``, ``seed``, ``resolve_filter``, ``framebuffer``,
    ``clipping``, ``texture_fixed_point``, ``texture_filter``: see
    `softras.pipeline.render_scene`) or "gl" (glref; options ``samples``,
    ``framebuffer``; ``texture_filter``, a softras-only filter choice, is
    ignored).
    Returns (H, W, 4) premultiplied RGBA, row 0 = top of the picture: uint8
    for an "rgba8" framebuffer (the default), float32 for "rgba32f"
    (``framebuffer`` option or the scene's top-level "framebuffer" key).
    """
    scene = load_scene(scene)
    if backend == "soft":
        from .pipeline import render_scene
        return render_scene(scene, **options)
    if backend == "gl":
        import glref
        options.pop("texture_filter", None)       # ripmap / EWA: softras only
        unknown = set(options) - {"samples", "framebuffer"}
        if unknown:
            raise TypeError(f"glref does not take options {sorted(unknown)}")
        return glref.render(scene, **options)
    raise ValueError(f"backend must be 'soft' or 'gl', not {backend!r}")


def compare(a, b, **tolerance):
    """Compare two (H, W, 4) uint8 images; see `softras.metrics.compare`."""
    from .metrics import compare as _compare
    return _compare(a, b, **tolerance)
