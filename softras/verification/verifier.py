"""Verdicts on a picture of a scene: does it agree with GL's, up to what GL allows?

:func:`verify` judges an ``image`` (softras's, or any renderer's) against a
``reference`` (GL's picture of the same scene) under one of two profiles:

* **strict** -- softras's contract with the implementation it reproduces bit
  for bit (Mesa 22.3 llvmpipe): the scene's tolerance (per-pixel threshold,
  fraction of bad pixels, SSIM) over the whole image; where it fails only on
  the pixels of the ambiguity mask (:mod:`softras.verification.ambiguity`) the verdict is
  a quality warning. This is :func:`judge_strict`.
* **spec** -- per-pixel bounds of what *any* conformant GL implementation may
  draw (:func:`spec_bounds`), derived from the GL 4.6 core specification and
  the reference context's queried limits, never from one driver's choices.
  Both pictures must lie inside the bounds on every pixel (a bug in either
  one fails, however few pixels it touches); the verdict is a pass when they
  also agree within the scene's tolerance, a quality warning when they
  differ only in ways the bounds allow. This is :func:`judge_spec`.
* **auto** picks strict for the implementation softras reproduces and spec
  for every other (:func:`choose_profile`).

The bounds are the per-pixel, per-channel envelope (min and max) of softras
renders of the scene under each implementation choice the specification
leaves open, widened by the colour arithmetic it allows. Each variant and
allowance, with the section it comes from:

====================  =====================================================
coverage              GL 4.6 section 14.6.1 samples the polygon at the
                      snapped vertex positions of the implementation's
                      sub-pixel grid (GL_SUBPIXEL_BITS, table 23.53): the
                      picture moved by sqrt(2) * 2^-bits pixel left, right,
                      down and up (every edge moves by >= 2^-bits, the
                      largest snapping error), and softras's float64 "exact"
                      precision beside its llvmpipe-exact "gl" one.
sample positions      section 14.3.1: where the reference GL reports
                      (glGetMultisamplefv) positions other than softras's
                      GL pattern, every variant samples at the reference's.
tie rule              section 14.6.1 asks only that a sample exactly on an
                      edge shared by two polygons goes to exactly one: the
                      three other consistent rules beside llvmpipe's
                      left-bottom (softras.pipeline.setup.TIE_RULES).
depth ties            section 14.6.1 / 17.3.4: depth is interpolated and
                      rounded by the implementation: ties between surfaces
                      at equal depth may break either way (the scene with
                      less <-> lequal and greater <-> gequal swapped).
lines                 section 14.5.1, rule 1: each of a line's fragments may
                      deviate by one unit in x and in y from the diamond-exit
                      rule's (the line draws moved to each of the 8
                      neighbouring pixels, and removed: any one fragment may
                      have moved away).
textures              section 8.14 (LOD approximations, coordinate and filter
                      precision, mip generation): :mod:`softras.pipeline.texture_bounds`
                      via ``render_scene(texture_bounds="lo" | "hi")``;
                      normal and bump maps at five lambdas of the permitted
                      range (``"lo/middle"`` and the like: an envelope).
colour conversion     section 2.3.5.2: a float colour is converted to one of
                      the two nearest 8-bit values: 1/255.
blending              section 17.3.6: each blend reads the rounded 8-bit
                      destination and rounds again: +1/255 when the scene
                      blends.
texture filtering     filter weights of finite precision (dEQP's lookup
                      precision for 8-bit formats): +1/255 when textured.
lighting              sections 2.3.4.1 and GLSL 4.60 section 4.7.1: float
                      arithmetic, normalize / pow within a few ULP: +1/255
                      when lit.
====================  =====================================================

What the envelope does not bound tightly: where two variants disagree the
pixel may take any value between them (a coverage edge is "either colour,
or anything in between"), not only one of them; a line's pixel count
(section 14.5.1 rules 2 and 3) is not checked. A consistent swap of the tie
rule is conformant, so the spec profile does not fail it; a tie rule that
leaves gaps or double hits on shared edges is not, and fails.

Why one module of ~720 lines: the two profiles share the verdicts, the
tolerances and the reasons' wording; the spec profile's bounds and the strict
profile's judgement are kept together so that a verdict's text is written in
one place.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = [
    "PASS", "WARN", "FAIL", "NOT_SUPPORTED", "VERDICTS", "VERDICT_NAMES", "PROFILES",
    "FEATURE_TOLERANCES", "feature_tolerance", "scene_tolerance", "choose_profile", "reproduces",
    "Bounds", "spec_bounds", "colour_allowance", "judge_strict", "judge_spec", "Verification", "verify",
]

PASS, WARN, FAIL, NOT_SUPPORTED = "pass", "quality_warning", "fail", "not_supported"
VERDICTS = (PASS, WARN, FAIL, NOT_SUPPORTED)
#: How each verdict is written for people.
VERDICT_NAMES = {PASS: "PASS", WARN: "QUALITY WARNING", FAIL: "FAIL", NOT_SUPPORTED: "NOT SUPPORTED"}
PROFILES = ("strict", "spec", "auto")

#: Default tolerance by feature, for scenes that declare none; a scene with
#: several features gets the loosest threshold and bad fraction and the
#: lowest SSIM among them. The one set of defaults of every command
#: (``compare SCENE``, ``conformance``, ``verify``, the tests).
FEATURE_TOLERANCES = {
    # The scene format's default: 2/255 covers one rounding step of each of
    # interpolation and blending.
    "base": {"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99},
    # llvmpipe filters RGBA8 textures with 8-bit weights and a piecewise
    # linear log2 for the LOD (reproduced in gl precision).
    "texture": {"threshold": 3, "max_bad_fraction": 0.005, "min_ssim": 0.98},
    # Lighting: float32 normalize / pow in the shader.
    "lighting": {"threshold": 3, "max_bad_fraction": 0.005, "min_ssim": 0.98},
    # 4x MSAA: the resolve averages four rounded samples.
    "msaa": {"threshold": 2, "max_bad_fraction": 0.002, "min_ssim": 0.99},
}

#: The implementation whose arithmetic softras reproduces bit for bit in gl
#: precision (the strict contract): renderer prefix and version text.
REPRODUCED = ("llvmpipe", "Mesa 22.3")


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------------
# Tolerances and profiles


def feature_tolerance(scene) -> tuple[dict, list[str]]:
    """The default tolerance for the features a scene uses.

    Returns ``(tolerance, features)``: ``threshold``, ``max_bad_fraction``,
    ``min_ssim``, and the keys of :data:`FEATURE_TOLERANCES` that applied
    (``"base"`` first).
    """
    features = ["base"]
    if any(draw.material.texture is not None for draw in scene.draws):
        features.append("texture")
    if any(draw.material.shading != "unlit" for draw in scene.draws):
        features.append("lighting")
    if scene.samples > 1:
        features.append("msaa")
    chosen = [FEATURE_TOLERANCES[name] for name in features]
    tolerance = {"threshold": max(t["threshold"] for t in chosen),
                 "max_bad_fraction": max(t["max_bad_fraction"] for t in chosen),
                 "min_ssim": min(t["min_ssim"] for t in chosen)}
    return tolerance, features


def scene_tolerance(scene) -> tuple[dict, str]:
    """The tolerance a scene is judged by, and where it comes from.

    ``(scene.tolerance, "scene")`` when the scene file or dict declares
    ``"tolerance"`` (`softras.scene.Scene.declares_tolerance`, recorded by the
    loader; a glTF scene or one built in code has none), else ``(defaults,
    "defaults for base, texture, ...")`` (:func:`feature_tolerance`).
    """
    if scene.declares_tolerance:
        return dict(scene.tolerance), "scene"
    tolerance, features = feature_tolerance(scene)
    return tolerance, "defaults for " + ", ".join(features)


def reproduces(capabilities: dict | None) -> bool:
    """Whether softras's gl precision reproduces this GL bit for bit (llvmpipe 22.3)."""
    if not capabilities:
        return False
    renderer = str(capabilities.get("GL_RENDERER") or "")
    version = str(capabilities.get("GL_VERSION") or "")
    return renderer.startswith(REPRODUCED[0]) and REPRODUCED[1] in version


def choose_profile(profile: str, capabilities: dict | None) -> str:
    """The profile a verdict uses: ``auto`` is strict for the implementation
    softras reproduces (:func:`reproduces`), spec for any other."""
    if profile not in PROFILES:
        raise ValueError(f"profile must be one of {', '.join(PROFILES)}, not {profile!r}")
    if profile != "auto":
        return profile
    return "strict" if reproduces(capabilities) else "spec"


# ---------------------------------------------------------------------------
# Spec bounds


@dataclass
class Bounds:
    """Per-pixel bounds of a conformant picture of a scene.

    ``lo``, ``hi``: float64 ``(H, W, 4)`` premultiplied colour in [0, 1]
    units (row 0 = top), the envelope of the variants *before* the colour
    allowance; ``allowance``: the colour arithmetic allowance added on both
    sides (same units); ``variants``: the names of the renders taken.
    """

    lo: np.ndarray
    hi: np.ndarray
    allowance: float
    variants: list[str] = field(default_factory=list)

    def low(self) -> np.ndarray:
        return self.lo - self.allowance

    def high(self) -> np.ndarray:
        return self.hi + self.allowance

    def images(self) -> dict[str, np.ndarray]:
        """``bound_lo``, ``bound_hi``: uint8 pictures of the widened bounds (for reports)."""
        def as_u8(x):
            return np.rint(np.clip(x, 0.0, 1.0) * 255.0).astype(np.uint8)
        return {"bound_lo": as_u8(self.low()), "bound_hi": as_u8(self.high())}


def colour_allowance(scene) -> tuple[float, list[str]]:
    """The colour arithmetic GL allows beyond the variants, in [0, 1] units.

    One 8-bit step for the final conversion (GL 4.6 section 2.3.5.2; for a
    float framebuffer 2^-12 of float32 arithmetic, section 2.3.4.1), and one
    more for each of: blending (section 17.3.6, the destination is re-read
    rounded), texture filtering (finite weight precision), lighting (float
    normalize / pow, GLSL 4.60 section 4.7.1). Returns (allowance, the
    parts that applied).
    """
    rgba8 = scene.framebuffer == "rgba8"
    step = 1.0 / 255.0
    parts = ["conversion 1/255" if rgba8 else "float arithmetic 2^-12"]
    total = step if rgba8 else 2.0 ** -12
    extra = {
        "blending": any(d.blend != "none" for d in scene.draws),
        "texture filtering": any(d.material.texture is not None or getattr(d.material, "normal_map", None)
                                 or getattr(d.material, "bump_map", None) for d in scene.draws),
        "lighting": any(d.material.shading != "unlit" for d in scene.draws),
    }
    for name, used in extra.items():
        if used:
            total += step
            parts.append(f"{name} 1/255")
    return total, parts


_TIE_FLIP = {"less": "lequal", "lequal": "less", "greater": "gequal", "gequal": "greater"}


def _tie_flipped(scene):
    """The scene with every depth test's tie rule swapped (less <-> lequal, greater <-> gequal)."""
    draws = tuple(dataclasses.replace(d, depth_test=_TIE_FLIP.get(d.depth_test, d.depth_test))
                  for d in scene.draws)
    return dataclasses.replace(scene, draws=draws)


def _lines_moved(scene, dx: float, dy: float):
    """The scene with its line draws (only) moved by (dx, dy) window pixels.

    world' = (P V)^-1 T (P V) world, where T moves clip x by 2 dx / W * w
    (as :func:`softras.verification.ambiguity.shifted_scene` does for the whole picture).
    """
    move = np.identity(4)
    move[0, 3] = 2.0 * dx / scene.width
    move[1, 3] = 2.0 * dy / scene.height
    pv = np.asarray(scene.camera.projection, np.float64) @ np.asarray(scene.camera.view, np.float64)
    change = np.linalg.solve(pv, move @ pv)
    draws = tuple(dataclasses.replace(d, world=change @ np.asarray(d.world, np.float64))
                  if d.mesh.primitive == "lines" else d for d in scene.draws)
    return dataclasses.replace(scene, draws=draws)


def _widen_lines(lo: np.ndarray, hi: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Near lines, each pixel may take any value of its 3 x 3 neighbourhood's bounds.

    ``lines``: (H, W) bool, the pixels the line draws change; "near" is
    within two pixels of them.

    The moved variants give each fragment its neighbours' values; section
    14.5.1 rule 2 also lets a line gain or lose a fragment at an end, and the
    clipped end points of a line crossing the near plane or the viewport edge
    move with the clipper's precision (section 13.7), so the envelope is
    widened by one more pixel where the lines made it wide (hi > lo).
    """
    near = lines
    for _ in range(2):
        padded = np.pad(near, 1)
        near = np.any([padded[dy:dy + near.shape[0], dx:dx + near.shape[1]]
                       for dy in range(3) for dx in range(3)], axis=0)
    pad_lo = np.pad(lo, ((1, 1), (1, 1), (0, 0)), mode="edge")
    pad_hi = np.pad(hi, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = lo.shape[:2]
    wide_lo = np.min([pad_lo[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)
    wide_hi = np.max([pad_hi[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)
    return np.where(near[..., None], wide_lo, lo), np.where(near[..., None], wide_hi, hi)


def gl_positions(scene, capabilities: dict):
    """The reference GL's sample positions for the scene's sample count when
    they are not softras's GL pattern (llvmpipe's), else None.

    Section 14.3.1 leaves the positions to the implementation and
    glGetMultisamplefv reports them; the bounds sample where the reference does.
    """
    if scene.samples == 1:
        return None
    places = (capabilities.get("sample_positions") or {}).get(str(scene.samples))
    if places is None:
        return None
    from softras.pipeline.sampling import sample_positions

    try:
        own = sample_positions(scene.samples)
    except ValueError:
        own = None
    places = np.asarray(places, np.float64)
    return None if own is not None and np.array_equal(own, places) else places


def _without_lines(scene):
    """The scene without its line draws."""
    return dataclasses.replace(scene, draws=tuple(d for d in scene.draws if d.mesh.primitive != "lines"))


def _as_unit(image: np.ndarray) -> np.ndarray:
    """uint8 (k/255) or float pictures -> float64 colour units."""
    image = np.asarray(image)
    return image.astype(np.float64) / 255.0 if image.dtype == np.uint8 else image.astype(np.float64)


def _default_render(scene, **options) -> np.ndarray:
    from softras.renderer import render_scene

    return render_scene(scene, **options)


def spec_bounds(scene, capabilities: dict | None = None, *,
                render: Callable[..., np.ndarray] | None = None) -> Bounds:
    """Per-pixel bounds of what a conformant GL may draw for `scene`.

    Parameters
    ----------
    scene : softras.scene.Scene
    capabilities : dict, optional
        The reference context's capability record (`glref.info()`): its
        ``subpixel_bits`` set the snapping distance (default 4, the minimum
        GL_SUBPIXEL_BITS the specification allows, table 23.53).
    render : callable, optional
        ``render(scene, **options) -> (H, W, 4)`` picture; default
        :func:`softras.renderer.render_scene` (tests pass broken ones).

    Returns
    -------
    Bounds
        The envelope of the module docstring's variants (10 renders, 4
        more with textures, 6 more with normal or bump maps, 9 more with
        lines).
    """
    render = render or _default_render
    caps = capabilities or {}
    bits = int(caps.get("subpixel_bits") or 4)
    shift = np.sqrt(2.0) * 2.0 ** -bits
    mapped = any(getattr(d.material, "normal_map", None) or getattr(d.material, "bump_map", None)
                 for d in scene.draws)
    textured = mapped or any(d.material.texture is not None for d in scene.draws)
    from softras.pipeline import texture_bounds as texbounds
    from softras.verification.ambiguity import shifted_scene

    variants: list[tuple[str, object, dict]] = [
        ("gl", scene, {"precision": "gl"}),
        ("exact", scene, {"precision": "exact"}),
        ("depth ties flipped", _tie_flipped(scene), {"precision": "gl"}),
    ]
    for rule in ("right_bottom", "left_top", "right_top"):
        variants.append((f"tie rule {rule}", scene, {"precision": "gl", "tie_rule": rule}))
    for dx, dy in ((shift, 0.0), (-shift, 0.0), (0.0, shift), (0.0, -shift)):
        variants.append((f"moved ({dx:+.4f}, {dy:+.4f}) px", shifted_scene(scene, dx, dy), {"precision": "gl"}))
    if any(d.mesh.primitive == "lines" for d in scene.draws):
        # Rule 1 lets each fragment move on its own, so at any pixel of a
        # line the line may be absent, or present with a neighbour's value.
        variants.append(("lines removed", _without_lines(scene), {"precision": "gl"}))
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            variants.append((f"lines moved ({dx:+d}, {dy:+d}) px", _lines_moved(scene, dx, dy), {"precision": "gl"}))
    if textured:
        for precision in ("gl", "exact"):
            for side in texbounds.SIDES:
                variants.append((f"texture bounds {side} ({precision})", scene,
                                 {"precision": precision, "texture_bounds": side}))
    if mapped:
        # Lighting is not monotone in a map's level of detail: more lambdas
        # than the range's ends (`softras.pipeline.texture_bounds.MAP_LODS`).
        for value in texbounds.BOUND_RENDERS:
            if value not in texbounds.SIDES:       # (the ends, above)
                variants.append((f"texture bounds {value} (gl)", scene,
                                 {"precision": "gl", "texture_bounds": value}))
    pattern = gl_positions(scene, caps)
    lo = hi = None
    pictures = {}
    for name, variant, options in variants:
        if pattern is not None:
            options = options | {"pattern": pattern}
        picture = pictures[name] = _as_unit(render(variant, **options))
        lo = picture if lo is None else np.minimum(lo, picture)
        hi = picture if hi is None else np.maximum(hi, picture)
    if "lines removed" in pictures:
        lines = (pictures["lines removed"] != pictures["gl"]).any(axis=-1)
        lo, hi = _widen_lines(lo, hi, lines)
    allowance, _ = colour_allowance(scene)
    return Bounds(lo=lo, hi=hi, allowance=allowance, variants=[name for name, _, _ in variants])


# ---------------------------------------------------------------------------
# Judgements


def _bbox(selection: np.ndarray) -> str:
    rows, cols = np.nonzero(selection)
    return f"x {cols.min()}..{cols.max()}, y {rows.min()}..{rows.max()}"


def _outside(picture: np.ndarray, bounds: Bounds) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) bool: pixels with a channel outside the widened bounds, and
    (H, W) float: how far outside (colour units, 0 inside)."""
    value = _as_unit(picture)
    excess = np.maximum(bounds.low() - value, value - bounds.high()).max(axis=-1)
    excess = np.maximum(excess, 0.0)
    # A float comparison of k/255 values: ignore excess below 1e-9 (rounding of the division).
    outside = excess > 1e-9
    return outside, excess


def _stage_at(scene, ids: np.ndarray | None, selection: np.ndarray) -> str:
    """Name the draws under the failing pixels (the stages that shape their colour)."""
    if ids is None or not selection.any():
        return ""
    from softras.verification.ambiguity import draw_features

    draws, counts = np.unique(ids[selection], return_counts=True)
    named = []
    for d, n in sorted(zip(draws, counts), key=lambda x: -x[1])[:3]:
        named.append("background" if d < 0 else f"{n} px on draw {draw_features(scene, int(d))}")
    return "; ".join(named)


def judge_spec(scene, image: np.ndarray, reference: np.ndarray, tolerance: dict, bounds: Bounds, *,
               draw_ids: np.ndarray | None = None) -> tuple[str, list[str], dict, dict]:
    """The spec profile's verdict on two pictures of a scene.

    Parameters
    ----------
    image, reference : numpy.ndarray
        ``(H, W, 4)`` pictures, row 0 = top: uint8 or float (colour units).
    tolerance : dict
        The scene's strict tolerance: agreement within it is a pass, any
        other in-bounds difference a quality warning.
    bounds : Bounds
        :func:`spec_bounds` of the scene.
    draw_ids : numpy.ndarray, optional
        ``(H, W)`` int: the draw visible at each pixel (-1 background), to
        name the stage of a failure.

    Returns
    -------
    (verdict, reasons, figures, images) as :func:`judge_strict`.
    """
    from softras.verification.metrics import compare

    out_image, excess_image = _outside(image, bounds)
    out_reference, excess_reference = _outside(reference, bounds)
    figures = {"profile": "spec", "allowance_255": round(255 * bounds.allowance, 3),
               "variants": len(bounds.variants),
               "ambiguous_pixels": int(((bounds.hi - bounds.lo) > 1e-9).any(axis=-1).sum()),
               "outside_image": int(out_image.sum()), "outside_reference": int(out_reference.sum())}
    reasons: list[str] = []
    for name, outside, excess in (("the image", out_image, excess_image),
                                  ("the reference", out_reference, excess_reference)):
        if outside.any():
            worst = np.unravel_index(np.argmax(excess), excess.shape)
            stage = _stage_at(scene, draw_ids, outside)
            reasons.append(f"{name}: {int(outside.sum())} px outside the spec bounds at {_bbox(outside)}, "
                           f"worst {255 * excess[worst]:.1f}/255 beyond at ({worst[1]}, {worst[0]})"
                           + (f" [{stage}]" if stage else ""))
    comparison = compare(image, reference, **tolerance)
    figures.update(max_diff=comparison.max_diff, bad_pixels=comparison.bad_pixels,
                   ssim=round(float(comparison.ssim), 6))
    if reasons:
        verdict = FAIL
    elif comparison.passed:
        verdict = PASS
        reasons.append("within the spec bounds on every pixel and within tolerance: "
                       f"max diff {comparison.max_diff:.3g}/255, SSIM {comparison.ssim:.5f}")
    else:
        verdict = WARN
        reasons.append(f"every pixel within the spec bounds, but {comparison.bad_pixels} px differ by more than "
                       f"{tolerance['threshold']}/255 (max {comparison.max_diff:.3g}/255, SSIM "
                       f"{comparison.ssim:.5f}): differences a conformant GL may make")
    images = bounds.images()
    images["diff"] = comparison.diff_image
    images["where"] = _where_outside(image, out_image, out_reference)
    return verdict, reasons, figures, images


def _marked(picture: np.ndarray, *layers: tuple[np.ndarray, tuple[int, int, int]]) -> np.ndarray:
    """The picture dimmed to grey, with each (mask, RGB) layer painted over it in order (uint8 (H, W, 4))."""
    grey = np.rint(np.clip(_as_unit(picture), 0, 1) * 255)[..., :3].mean(axis=-1)
    out = np.empty(picture.shape[:2] + (4,), dtype=np.uint8)
    out[..., :3] = np.rint(30 + 0.3 * grey).astype(np.uint8)[..., None]
    for mask, colour in layers:
        out[mask, :3] = colour
    out[..., 3] = 255
    return out


def _where_outside(image: np.ndarray, out_image: np.ndarray, out_reference: np.ndarray) -> np.ndarray:
    """Pixels outside the bounds: red in the image, magenta in the reference, over the image dimmed."""
    return _marked(image, (out_reference, (255, 0, 255)), (out_image, (255, 30, 30)))


def _where_image(soft: np.ndarray, outside: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Differences beyond the tolerance: red outside the mask, cyan inside, over soft dimmed."""
    return _marked(soft, (inside, (0, 220, 255)), (outside, (255, 30, 30)))


def _tolerance_text(tolerance: dict) -> str:
    return (f"threshold {tolerance['threshold']}/255, bad pixels <= {100 * tolerance['max_bad_fraction']:.2f}%, "
            f"SSIM >= {tolerance['min_ssim']:g}")


def judge_strict(scene, soft: np.ndarray, gl: np.ndarray, tolerance: dict, *, soft_ids=None, gl_ids=None,
                 soft_last=None, gl_last=None, ambiguity=None) -> tuple[str, list[str], dict, dict]:
    """The strict profile's verdict on two pictures of a scene.

    Parameters
    ----------
    scene : softras.scene.Scene
    soft, gl : numpy.ndarray
        ``uint8`` ``(H, W, 4)`` pictures by softras and GL.
    tolerance : dict
        ``threshold``, ``max_bad_fraction``, ``min_ssim``.
    soft_ids, gl_ids : tuple, optional
        :func:`softras.verification.ambiguity.decode_ids` of both renderers' primitive-ID
        pictures (for the stage of a failure).
    soft_last, gl_last : numpy.ndarray, optional
        Primitive numbers of both renderers' ID pictures without depth test
        (tell coverage from depth; :func:`softras.verification.ambiguity.classify_differences`).
    ambiguity : softras.verification.ambiguity.Ambiguity, optional
        The mask; without it nothing is excused.

    Returns
    -------
    verdict : str
        PASS, WARN or FAIL.
    reasons : list of str
    figures : dict
        JSON-able numbers.
    images : dict
        ``diff``, ``ssim``, ``flip``, ``where`` pictures.
    """
    from softras.verification.ambiguity import classify_differences
    from softras.verification.metrics import compare, error_map_image, pixel_difference

    strict = compare(soft, gl, flip=True, **tolerance)
    pixel_diff = pixel_difference(soft, gl)
    bad = pixel_diff > tolerance["threshold"]
    mask = ambiguity.mask if ambiguity is not None else np.zeros_like(bad)
    outside, inside = bad & ~mask, bad & mask
    figures = strict.to_dict()
    figures.pop("passed")
    figures.update(profile="strict", bad_outside_mask=int(outside.sum()), bad_inside_mask=int(inside.sum()),
                   differing_pixels=int((pixel_diff > 0).sum()))
    if ambiguity is not None:
        figures["ambiguous_pixels"] = ambiguity.counts()
    if soft_ids is not None and gl_ids is not None:
        figures["coverage_mismatch_pixels"] = int((soft_ids[0] != gl_ids[0]).sum())

    reasons: list[str] = []
    if strict.passed:
        verdict = PASS
        reasons.append("identical to GL" if strict.max_diff == 0 else
                       f"within tolerance: max diff {strict.max_diff:.3g}/255, {strict.bad_pixels} px beyond "
                       f"{tolerance['threshold']}/255, SSIM {strict.ssim:.5f}")
    else:
        # Second tier: ambiguous pixels count as agreeing (GL's value replaced by softras's).
        excused = np.where(mask[..., None], soft, gl)
        relaxed = compare(soft, excused, **tolerance)
        figures["ssim_excused"] = float(relaxed.ssim)
        strict_why = (f"{strict.bad_pixels} px ({100 * strict.bad_fraction:.3f}%) differ by more than "
                      f"{tolerance['threshold']}/255 (max {strict.max_diff:.3g}/255), SSIM {strict.ssim:.5f}")
        if relaxed.passed:
            verdict = WARN
            where = ambiguity.label(inside) if ambiguity is not None else {}
            labels = ", ".join(f"{name} {count}" for name, count in where.items() if count)
            reasons.append(f"{strict_why}: not within the strict tolerance, but "
                           + (f"all {int(inside.sum())} are in the ambiguity mask ({labels})"
                              if inside.any() else "only SSIM fails")
                           + f"; with them excused: {relaxed.bad_pixels} px beyond, SSIM {relaxed.ssim:.5f}")
        else:
            verdict = FAIL
            reasons.append(f"{strict_why}; {int(outside.sum())} of them outside the ambiguity mask"
                           + (f" at {_bbox(outside)}" if outside.any() else "")
                           + f"; with the ambiguous pixels excused: {relaxed.bad_pixels} px "
                             f"({100 * relaxed.bad_fraction:.3f}%) beyond, SSIM {relaxed.ssim:.5f} "
                             f"(needs {_tolerance_text(tolerance)})")
        if soft_ids is not None and gl_ids is not None:
            selection, where = (outside, "outside the ambiguity mask") if verdict == FAIL else \
                (inside, "inside the ambiguity mask")
            reasons.extend(classify_differences(selection, soft_ids, gl_ids, pixel_diff, scene, where=where,
                                                soft_last=soft_last, gl_last=gl_last))

    images = {"diff": strict.diff_image, "ssim": error_map_image(1.0 - strict.ssim_map),
              "flip": error_map_image(strict.flip_map), "where": _where_image(soft, outside, inside)}
    return verdict, reasons, figures, images


def draw_ids(scene, render: Callable[..., np.ndarray] | None = None, *,
             capabilities: dict | None = None) -> np.ndarray:
    """(H, W) int: the draw softras sees at each pixel (-1: background), row 0 = top,
    sampled where the reference GL samples (:func:`gl_positions`)."""
    from softras.verification.ambiguity import decode_ids, id_scene, primitive_offsets

    render = render or _default_render
    options = {"precision": "gl"}
    pattern = gl_positions(scene, capabilities or {})
    if pattern is not None:
        options["pattern"] = pattern
    numbers = decode_ids(np.asarray(render(id_scene(scene), **options)), scene)[0]
    offsets = primitive_offsets(scene)
    draws = np.searchsorted(offsets, numbers - 1, side="right") - 1
    return np.where(numbers > 0, draws, -1)


# ---------------------------------------------------------------------------
# The public verifier


@dataclass
class Verification:
    """The result of :func:`verify`.

    ``verdict``: one of :data:`VERDICTS`; ``profile``: the profile used
    ("strict" or "spec"); ``reasons``: lines for people, naming the stage
    and place of a failure; ``figures``: JSON-able numbers; ``images``:
    uint8 ``(H, W, 4)`` pictures (``bound_lo`` / ``bound_hi`` in spec,
    ``diff``, ``where``); ``bounds``: the spec :class:`Bounds` (None in strict).
    """

    verdict: str
    profile: str
    reasons: list[str]
    figures: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict, repr=False)
    bounds: Bounds | None = field(default=None, repr=False)

    @property
    def passed(self) -> bool:
        """True for PASS and QUALITY WARNING (no failure)."""
        return self.verdict in (PASS, WARN)

    def summary(self) -> str:
        return f"{VERDICT_NAMES[self.verdict]} ({self.profile}): " + "; ".join(self.reasons)

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "verdict_name": VERDICT_NAMES[self.verdict], "profile": self.profile,
                "reasons": list(self.reasons), "figures": dict(self.figures)}


def _picture(value, name: str, shape: tuple[int, int]) -> np.ndarray:
    """A picture argument: an (H, W, 4) array, or a path to a PNG / .npy."""
    if isinstance(value, (str, os.PathLike)):
        path = Path(value)
        if path.suffix == ".npy":
            value = np.load(path, allow_pickle=False)
        else:
            from softras.scene.imageio import read_png

            value = read_png(path)
    value = np.asarray(value)
    if value.ndim != 3 or value.shape[2] != 4:
        raise ValueError(f"{name} must be an (H, W, 4) RGBA picture, not shape {value.shape}")
    if value.shape[:2] != shape:
        raise ValueError(f"{name} is {value.shape[1]}x{value.shape[0]} but the scene is {shape[1]}x{shape[0]}")
    if value.dtype != np.uint8 and not np.issubdtype(value.dtype, np.floating):
        raise ValueError(f"{name} must be uint8 or float, not {value.dtype}")
    return value


def verify(scene, image, reference, *, profile: str = "spec", capabilities: dict | None = None,
           tolerance: dict | None = None, bounds: Bounds | None = None) -> Verification:
    """Judge whether `image` and `reference` agree up to what GL lets conformant implementations differ.

    Parameters
    ----------
    scene : softras.scene.Scene or path
        The scene both pictures show (a path is loaded).
    image, reference : numpy.ndarray or path
        ``(H, W, 4)`` RGBA, premultiplied, row 0 = top: ``uint8`` or float
        (rgba32f pictures are compared as floats); or a PNG / .npy path.
        ``image`` is the picture under test (softras's or any renderer's),
        ``reference`` GL's. Both are checked.
    profile : "spec", "strict" or "auto"
        See the module docstring; "auto" needs ``capabilities`` (else spec).
    capabilities : dict, optional
        The reference context's capability record (`glref.info()`); its
        sub-pixel bits set the coverage bounds.
    tolerance : dict, optional
        The strict tolerance; default the scene's (:func:`scene_tolerance`).
    bounds : Bounds, optional
        ``spec_bounds(scene, capabilities)`` computed before, to judge several
        pictures of one scene against one GL without rendering the bounds'
        variants again (they depend on the scene and the capabilities only);
        it must be of this scene and these capabilities.  Used by the spec
        profile only.

    Returns
    -------
    Verification
    """
    from softras.scene import Scene, load_scene

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    shape = (scene.height, scene.width)
    image = _picture(image, "image", shape)
    reference = _picture(reference, "reference", shape)
    chosen = choose_profile(profile, capabilities)
    if tolerance is None:
        tolerance, _ = scene_tolerance(scene)
    if chosen == "spec":
        if bounds is None:
            bounds = spec_bounds(scene, capabilities)
        elif bounds.lo.shape[:2] != shape:
            raise ValueError(f"bounds are {bounds.lo.shape[1]}x{bounds.lo.shape[0]} "
                             f"but the scene is {shape[1]}x{shape[0]}")
        verdict, reasons, figures, images = judge_spec(scene, image, reference, tolerance, bounds,
                                                       draw_ids=draw_ids(scene, capabilities=capabilities))
        return Verification(verdict, chosen, reasons, figures, images, bounds)
    from softras.verification.ambiguity import ambiguity_mask, as_uint8

    soft, gl = as_uint8(image), as_uint8(reference)
    verdict, reasons, figures, images = judge_strict(scene, soft, gl, tolerance,
                                                     ambiguity=ambiguity_mask(scene))
    return Verification(verdict, chosen, reasons, figures, images)
