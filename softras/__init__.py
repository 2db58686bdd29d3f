"""softras: a reference software rasterizer, cross-checked against OpenGL.

Public API (DESIGN.md section 6):

- ``load_scene(path_or_dict) -> Scene``
- ``render(scene, backend="soft", **options) -> (H, W, 4) uint8``, row 0 = top
  (float32 for an rgba32f framebuffer)
- ``compare(a, b, **tolerance) -> Comparison``
- ``verify(scene, image, reference, *, profile="spec") -> Verification``: does
  ``image`` agree with GL's ``reference`` up to what GL allows
  (`softras.verifier`)
"""

from __future__ import annotations

from .scene import Scene, SceneError, load_scene

__all__ = ["Scene", "SceneError", "load_scene", "render", "compare", "verify"]


def render(scene, backend: str = "soft", **options):
    """Render a scene (a Scene, a dict or a path) with softras or glref.

    backend : "soft" (the software pipeline; options ``precision``,
    ``samples``, ``pattern``, ``seed``, ``resolve_filter``, ``framebuffer``,
    ``clipping``, ``texture_fixed_point``, ``texture_filter``: see
    `softras.pipeline.render_scene`) or "gl" (glref; options ``samples``,
    ``framebuffer``; any other option, e.g. the softras-only
    ``texture_filter``, is a ValueError, and a sample count the GL does not
    render exactly is `glref.NotSupported`).
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
        unknown = {name for name, value in options.items()
                   if name not in ("samples", "framebuffer") and value is not None}
        if unknown:
            raise ValueError(f"backend 'gl' does not take {', '.join(sorted(unknown))} (softras-only options)")
        options = {name: value for name, value in options.items() if value is not None}
        return glref.render(scene, **options)
    raise ValueError(f"backend must be 'soft' or 'gl', not {backend!r}")


def compare(a, b, **tolerance):
    """Compare two (H, W, 4) uint8 images; see `softras.metrics.compare`."""
    from .metrics import compare as _compare
    return _compare(a, b, **tolerance)


def verify(scene, image, reference, *, profile: str = "spec", capabilities: dict | None = None,
           tolerance: dict | None = None):
    """Does ``image`` agree with GL's ``reference`` up to what GL lets conformant
    implementations differ? See `softras.verifier.verify` (returns a Verification)."""
    from .verifier import verify as _verify
    return _verify(scene, image, reference, profile=profile, capabilities=capabilities, tolerance=tolerance)
