"""softras: a reference software rasterizer, cross-checked against OpenGL.

Public API (docs/design.md):

- ``load_scene(path_or_dict) -> Scene``
- ``render(scene, backend="soft", **options) -> (H, W, 4) uint8``, row 0 = top
  (float32 for an rgba32f framebuffer)
- ``compare(a, b, **tolerance) -> Comparison``
- ``verify(scene, image, reference, *, profile="spec") -> Verification``: does
  ``image`` agree with GL's ``reference`` up to what GL allows
  (`softras.verification.verifier`)

The package's folders are the architecture (docs/architecture.md):
`softras.scene` (the scene model and its files) <- `softras.pipeline` (the
readable stages) <- `softras.kernels` (the compiled path) <- `softras.renderer`
<- `softras.verification` <- `softras.cli`, `softras.bench`; imports only go
down (tests/test_layers.py).
"""

from __future__ import annotations

__all__ = ["Scene", "SceneError", "load_scene", "render", "compare", "verify"]


def __getattr__(name: str):
    """``Scene``, ``SceneError`` and ``load_scene``, imported from
    `softras.scene` on first use: importing softras alone (as pytest does in
    every session for the plugin, `softras.pytest_plugin`) does not load
    numpy and numba."""
    if name in ("Scene", "SceneError", "load_scene"):
        from softras import scene
        return getattr(scene, name)
    raise AttributeError(f"module 'softras' has no attribute {name!r}")


def render(scene, backend: str = "soft", **options):
    """Render a scene (a Scene, a dict or a path) with softras or glref; see
    `softras.renderer.render` and `softras.renderer.render_scene`."""
    from softras.renderer import render as _render
    return _render(scene, backend, **options)


def compare(a, b, **tolerance):
    """Compare two (H, W, 4) uint8 images; see `softras.verification.metrics.compare`."""
    from softras.verification.metrics import compare as _compare
    return _compare(a, b, **tolerance)


def verify(scene, image, reference, *, profile: str = "spec", capabilities: dict | None = None,
           tolerance: dict | None = None, bounds=None):
    """Does ``image`` agree with GL's ``reference`` up to what GL lets conformant
    implementations differ? See `softras.verification.verifier.verify` (returns a Verification;
    ``bounds``: its `spec_bounds` of the scene, reused across pictures)."""
    from softras.verification.verifier import verify as _verify
    return _verify(scene, image, reference, profile=profile, capabilities=capabilities, tolerance=tolerance,
                   bounds=bounds)
