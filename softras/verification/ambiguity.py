"""The ambiguity mask: pixels whose right answer depends on implementation choices.

OpenGL does not pin every pixel down. The spec lets an implementation snap
vertices to its own sub-pixel grid, round texture coordinates and LOD its own
way, and break depth ties by its own arithmetic. Where a pixel sits on such a
boundary, two correct implementations may disagree; everywhere else the answer
is determined and a difference is a bug. This module finds those pixels with
softras itself, by asking "does the answer change when an implementation
choice that GL allows changes?" -- the idea behind dEQP's rasterization
verifier, which accepts either answer for samples within the sub-pixel
precision of an edge.

Three rules, each a few extra softras renders (precision "gl") compared with
softras's own picture. A pixel gets the first label that applies:

1. **coverage** -- the *visible primitive* at the pixel changes when

   * the whole picture moves by one step of GL's sub-pixel grid, 1/256 pixel,
     left, right, down or up (4 renders; this moves every edge by between
     1/362 and 1/256 pixel, about the precision the spec asks for), or
   * the scene is rendered at precision "exact" (float64, no snapping).

   The visible primitive is read from a *primitive-ID picture*: the same
   scene with every draw unlit, untextured, unblended, each triangle (line)
   in a flat colour that encodes its number (:func:`id_scene`,
   :func:`decode_ids`). Only geometry, clipping, the fill rule and the depth
   test shape it.

2. **depth** -- the visible primitive changes when depth ties are broken the other
   way: every ``less`` becomes ``lequal`` and back, every ``greater``
   ``gequal`` and back. Those pixels have two surfaces at equal 24-bit depth,
   so the winner depends on how the depth was rounded. (Only exact ties are
   found, not surfaces a few depth units apart.)

3. **sampling** -- the full-colour picture changes by more than 1/255 in some
   channel under the four 1/256-pixel moves of rule 1. A smooth gradient
   changes by far less than 1/255 over 1/256 pixel, so these are pixels where
   a texel, a mip level or a texture-coordinate wrap sits at a rounding
   boundary (nearest filtering at a texel edge, a level switch).

The mask is the union of the three. What it does not cover: differences of
arithmetic precision in smooth regions (interpolation, lighting, filter
weights), which the scene's per-pixel threshold is for. :mod:`softras.verification.conformance` applies the
scene's strict tolerance to the whole image; where it fails but holds once
the ambiguous pixels are excused, the verdict is a quality warning, not a
failure. The primitive-ID pictures of softras and GL, compared with each
other, also say which stage disagrees at a failing pixel
(:func:`classify_differences`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = [
    "SUBPIXEL_STEP", "SAMPLING_STEP", "SHIFTS", "Ambiguity", "ambiguity_mask", "id_scene",
    "primitive_offsets", "shifted_scene", "decode_ids", "classify_differences", "draw_features",
    "as_uint8",
]

#: One step of GL's sub-pixel grid in window pixels (llvmpipe snaps to 1/256).
SUBPIXEL_STEP = 1.0 / 256.0
#: A colour change larger than this (in 1/255 units) under a sub-pixel move
#: is a sampling ambiguity (rule 3).
SAMPLING_STEP = 1
#: The window-space moves (dx, dy) of rules 1 and 3, in pixels (y up, GL).
SHIFTS = ((SUBPIXEL_STEP, 0.0), (-SUBPIXEL_STEP, 0.0), (0.0, SUBPIXEL_STEP), (0.0, -SUBPIXEL_STEP))

#: less <-> lequal, greater <-> gequal (rule 2).
_TIE_FLIP = {"less": "lequal", "lequal": "less", "greater": "gequal", "gequal": "greater"}

#: Colours of the mask picture (RGB): coverage, depth, sampling.
MASK_COLOURS = {"coverage": (0, 220, 255), "depth": (255, 60, 255), "sampling": (255, 210, 0)}


# ---------------------------------------------------------------------------
# Scene variants


def shifted_scene(scene, dx: float, dy: float):
    """The scene with its whole picture moved by (dx, dy) window pixels.

    Parameters
    ----------
    scene : softras.scene.Scene
    dx, dy : float
        The move in window pixels, GL window space (y up).

    Returns
    -------
    softras.scene.Scene
        A copy whose projection is ``T @ P``, where ``T`` adds ``2·dx/W`` to
        x_ndc and ``2·dy/H`` to y_ndc (in clip space: ``x_c += (2·dx/W)·w_c``),
        so every vertex's window position moves by exactly (dx, dy) before
        snapping. Both renderers use ``P @ V @ M``, so both see the same move.
    """
    move = np.identity(4)
    move[0, 3] = 2.0 * dx / scene.width
    move[1, 3] = 2.0 * dy / scene.height
    camera = dataclasses.replace(scene.camera, projection=move @ scene.camera.projection)
    return dataclasses.replace(scene, camera=camera)


def _id_colours(k: np.ndarray) -> np.ndarray:
    """(N,) int primitive numbers >= 1 -> (N, 4) straight RGBA float64, exact in RGBA8."""
    k = np.asarray(k, dtype=np.int64)
    rgba = np.stack([k & 255, (k >> 8) & 255, (k >> 16) & 255, np.full_like(k, 255)], axis=-1)
    return rgba.astype(np.float64) / 255.0


def primitive_offsets(scene) -> np.ndarray:
    """``int64`` ``(n_draws + 1,)``: draw ``d``'s primitives are numbered
    ``offsets[d] + 1 .. offsets[d + 1]`` in the ID picture (0 = background)."""
    counts = [len(draw.mesh.indices) for draw in scene.draws]
    return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])


def _expand_mesh(mesh, colours: np.ndarray):
    """The mesh with unshared vertices (3 per triangle, 2 per line) in flat ``colours``."""
    flat = np.asarray(mesh.indices, dtype=np.int64).reshape(-1)
    corners = mesh.indices.shape[1]
    changes = {}
    for f in dataclasses.fields(mesh):
        value = getattr(mesh, f.name)
        if f.name != "indices" and isinstance(value, np.ndarray) and value.ndim >= 1 \
                and len(value) == len(mesh.positions):
            changes[f.name] = value[flat]
    changes["indices"] = np.arange(len(flat), dtype=np.int64).reshape(-1, corners)
    changes["colors"] = np.repeat(colours, corners, axis=0)
    return dataclasses.replace(mesh, **changes)


def id_scene(scene, *, flip_depth_ties: bool = False, depth_test: bool = True):
    """The scene as a primitive-ID picture: each triangle (line) in a flat colour naming it.

    Primitive ``t`` of draw ``d`` gets number ``k = offsets[d] + t + 1``
    (:func:`primitive_offsets`), encoded as the colour
    ``(k & 255, k >> 8 & 255, k >> 16 & 255, 255) / 255``; the background
    becomes (0, 0, 0, 0). Every draw becomes unlit, untextured (no normal or
    bump map either) and unblended; to give each primitive its own flat colour
    its vertices are unshared (same positions). Geometry, clipping, culling,
    depth test and depth writes stay as they are.

    Parameters
    ----------
    scene : softras.scene.Scene
    flip_depth_ties : bool
        Swap less <-> lequal and greater <-> gequal (rule 2).
    depth_test : bool
        False: every draw without depth test, so the picture shows the last
        primitive (in draw order) that covers each pixel, hidden or not.

    Returns
    -------
    softras.scene.Scene
    """
    offsets = primitive_offsets(scene)
    draws = []
    for d, draw in enumerate(scene.draws):
        fields = {f.name for f in dataclasses.fields(draw.material)}
        plain = {name: None for name in ("texture", "normal_map", "bump_map") if name in fields}
        material = dataclasses.replace(draw.material, color=np.ones(4), shading="unlit", **plain)
        numbers = np.arange(offsets[d] + 1, offsets[d + 1] + 1)
        test = draw.depth_test if depth_test else None
        if flip_depth_ties and test is not None:
            test = _TIE_FLIP.get(test, test)
        draws.append(dataclasses.replace(draw, material=material, mesh=_expand_mesh(draw.mesh, _id_colours(numbers)),
                                         blend="none", depth_test=test))
    return dataclasses.replace(scene, draws=tuple(draws), background=np.zeros(4))


def decode_ids(image: np.ndarray, scene) -> tuple[np.ndarray, np.ndarray]:
    """Which primitive, and which draw, is visible at each pixel of an ID picture.

    Parameters
    ----------
    image : numpy.ndarray
        ``uint8`` ``(H, W, 4)`` picture of :func:`id_scene` (either renderer).
    scene : softras.scene.Scene
        The original scene.

    Returns
    -------
    primitive : numpy.ndarray
        ``int64`` ``(H, W)``: 0 = background, ``k`` >= 1 = the primitive
        numbered ``k``, -1 = mixed (with MSAA, samples of different primitives
        were averaged: an edge pixel).
    draw : numpy.ndarray
        ``int64`` ``(H, W)``: 0 = background, ``d + 1`` = draw ``d``, -1 = mixed.
    """
    offsets = primitive_offsets(scene)
    rgba = image.astype(np.int64)
    k = rgba[..., 0] | (rgba[..., 1] << 8) | (rgba[..., 2] << 16)
    primitive = np.where((rgba[..., 3] == 255) & (k >= 1) & (k <= offsets[-1]), k, -1)
    primitive[(rgba[..., 3] == 0) & (k == 0)] = 0
    draw = np.where(primitive > 0, np.searchsorted(offsets, primitive, side="left"), primitive)
    return primitive, draw


# ---------------------------------------------------------------------------
# The mask


@dataclass
class Ambiguity:
    """The ambiguity mask of one scene, by rule. All arrays ``bool`` ``(H, W)``, row 0 = top."""

    coverage: np.ndarray
    depth: np.ndarray
    sampling: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        """Union of the three rules, ``bool`` ``(H, W)``."""
        return self.coverage | self.depth | self.sampling

    def counts(self) -> dict:
        """Pixels per rule and in all: ``{"coverage": n, "depth": n, "sampling": n, "total": n}``."""
        return {"coverage": int(self.coverage.sum()), "depth": int(self.depth.sum()),
                "sampling": int(self.sampling.sum()), "total": int(self.mask.sum())}

    def label(self, where: np.ndarray) -> dict:
        """Pixels of a ``bool`` ``(H, W)`` selection per rule: ``{"coverage": n, ...}``."""
        return {name: int((getattr(self, name) & where).sum()) for name in ("coverage", "depth", "sampling")}

    def image(self, background: np.ndarray | None = None) -> np.ndarray:
        """The mask for the eye, ``uint8`` ``(H, W, 4)`` opaque.

        Coverage cyan, depth magenta, sampling yellow (:data:`MASK_COLOURS`),
        over ``background`` (an RGBA picture, shown dimmed grey) or black.
        """
        height, width = self.coverage.shape
        out = np.zeros((height, width, 4), dtype=np.uint8)
        if background is not None:
            grey = background[..., :3].astype(np.float64).mean(axis=-1)
            out[..., :3] = np.rint(40 + 0.25 * grey).astype(np.uint8)[..., None]
        for name in ("sampling", "depth", "coverage"):  # coverage drawn last: it wins
            out[getattr(self, name), :3] = MASK_COLOURS[name]
        out[..., 3] = 255
        return out


def as_uint8(image: np.ndarray) -> np.ndarray:
    """A picture as ``uint8`` ``(H, W, 4)``: a float (rgba32f) render becomes the
    8-bit image an RGBA8 framebuffer would hold, ``round(clamp(v, 0, 1)·255)``."""
    array = np.asarray(image)
    if array.dtype.kind == "f":
        array = np.rint(np.clip(np.nan_to_num(array), 0.0, 1.0) * 255.0)
    return np.ascontiguousarray(array, dtype=np.uint8)


def _soft_render(scene, precision: str) -> np.ndarray:
    from softras.renderer import render_scene

    return as_uint8(render_scene(scene, precision=precision))


def ambiguity_mask(scene, reference: np.ndarray | None = None, *,
                   render: Callable[[object, str], np.ndarray] | None = None) -> Ambiguity:
    """Find the pixels whose answer depends on implementation choices.

    Parameters
    ----------
    scene : softras.scene.Scene
        A loaded scene.
    reference : numpy.ndarray, optional
        softras's own picture of the scene at precision "gl" (``uint8``
        ``(H, W, 4)``), if already rendered.
    render : callable, optional
        ``render(scene, precision) -> (H, W, 4) uint8``; default the softras
        pipeline. (Tests pass their own.)

    Returns
    -------
    Ambiguity
        The three rules of the module docstring. Costs 11 softras renders
        (4 colour, 7 draw-ID), or 12 without ``reference``.
    """
    render = render or _soft_render
    if render is not _soft_render:
        user_render = render
        render = lambda s, p: as_uint8(user_render(s, p))  # noqa: E731
    height, width = scene.height, scene.width
    if reference is None:
        reference = render(scene, "gl")
    nothing = np.zeros((height, width), dtype=bool)
    if not scene.draws:
        return Ambiguity(coverage=nothing, depth=nothing.copy(), sampling=nothing.copy())

    def changed(a: np.ndarray, b: np.ndarray, step: int = 0) -> np.ndarray:
        return (np.abs(a.astype(np.int16) - b.astype(np.int16)) > step).any(axis=-1)

    ids = id_scene(scene)
    id_picture = render(ids, "gl")
    coverage = changed(render(ids, "exact"), id_picture)
    sampling = nothing.copy()
    for dx, dy in SHIFTS:
        coverage |= changed(render(shifted_scene(ids, dx, dy), "gl"), id_picture)
        sampling |= changed(render(shifted_scene(scene, dx, dy), "gl"), reference, SAMPLING_STEP)
    depth = changed(render(id_scene(scene, flip_depth_ties=True), "gl"), id_picture) & ~coverage
    sampling &= ~(coverage | depth)
    return Ambiguity(coverage=coverage, depth=depth, sampling=sampling)


# ---------------------------------------------------------------------------
# Which stage disagrees


def draw_features(scene, index: int) -> str:
    """A short description of what draw ``index`` exercises past coverage.

    For example ``"'floor': texture 'checker' (min linear_mipmap_linear, mag
    linear), unlit"`` -- the stages that shape its colour.
    """
    draw = scene.draws[index]
    material = draw.material
    parts = []
    if draw.mesh.primitive == "lines":
        parts.append("lines")
    if material.texture is not None:
        tex = scene.textures.get(material.texture)
        if tex is not None:
            parts.append(f"texture '{material.texture}' (min {tex.min_filter}, mag {tex.mag_filter}"
                         + (f", anisotropy {tex.max_anisotropy:g}" if tex.max_anisotropy > 1 else "")
                         + f", wrap {tex.wrap_s}/{tex.wrap_t})")
    parts.append(f"{material.shading} shading" if material.shading != "unlit" else "unlit")
    for name in ("normal_map", "bump_map"):
        if getattr(material, name, None):
            parts.append(name.replace("_", " "))
    if draw.mesh.colors is not None:
        parts.append("vertex colours")
    if draw.blend != "none":
        parts.append(f"blend {draw.blend}")
    return f"'{draw.name or draw.path}': " + ", ".join(parts)


def _where(selection: np.ndarray) -> str:
    rows, cols = np.nonzero(selection)
    return f"x {cols.min()}..{cols.max()}, y {rows.min()}..{rows.max()}"


def classify_differences(pixels: np.ndarray, soft_ids: tuple[np.ndarray, np.ndarray],
                         gl_ids: tuple[np.ndarray, np.ndarray], pixel_diff: np.ndarray, scene, *,
                         where: str, soft_last: np.ndarray | None = None,
                         gl_last: np.ndarray | None = None) -> list[str]:
    """Say which stage disagrees at the selected pixels, one line per stage.

    Parameters
    ----------
    pixels : numpy.ndarray
        ``bool`` ``(H, W)``: the pixels to explain (e.g. differences beyond
        the tolerance outside the ambiguity mask).
    soft_ids, gl_ids : tuple of numpy.ndarray
        ``(primitive, draw)`` from :func:`decode_ids` of softras's and GL's
        primitive-ID pictures (:func:`id_scene`).
    pixel_diff : numpy.ndarray
        ``(H, W)`` largest channel difference of the colour pictures, 0..255.
    scene : softras.scene.Scene
    where : str
        How to name the selection, e.g. "outside the ambiguity mask".
    soft_last, gl_last : numpy.ndarray, optional
        The primitive numbers of both renderers' ID pictures without depth
        test (``id_scene(scene, depth_test=False)``): the last primitive
        that covers each pixel, hidden or not. Without them every
        disagreement on the visible primitive is called coverage.

    Returns
    -------
    list of str
        Lines such as ``"coverage: 12 px outside the ambiguity mask differ
        (softras and GL disagree which primitive covers the pixel; max diff
        255/255; at x 3..40, y 7..9)"`` (x, y: column and row from the top
        left). Stages:

        * ``coverage`` -- the visible primitive differs, and so does the last
          primitive covering the pixel without depth test (rasterization,
          clipping, fill rule);
        * ``depth`` -- the visible primitive differs although, without depth
          test, both renderers agree which primitives cover the pixel (depth
          values, the depth test);
        * ``colour`` -- the same primitive is visible: its colour differs
          (interpolation, shading, texture sampling, blending), one line per
          draw with what that draw exercises (:func:`draw_features`).
    """
    soft_primitive, soft_draw = soft_ids
    gl_primitive, _ = gl_ids
    lines = []
    differ = soft_primitive != gl_primitive
    if soft_last is not None and gl_last is not None:
        covered_alike = soft_last == gl_last
    else:
        covered_alike = np.zeros_like(differ)
    groups = [
        ("coverage", pixels & differ & ~covered_alike,
         "softras and GL disagree which primitive covers the pixel"),
        ("depth", pixels & differ & covered_alike,
         "both cover the pixel with the same primitives, but a different one is visible"),
    ]
    for stage, selection, what in groups:
        count = int(selection.sum())
        if count:
            lines.append(f"{stage}: {count} px {where} differ ({what}; max diff "
                         f"{int(pixel_diff[selection].max())}/255; at {_where(selection)})")
    same = pixels & ~differ
    for d in np.unique(soft_draw[same]):
        selection = same & (soft_draw == d)
        count = int(selection.sum())
        if d > 0:
            owner = "in draw " + draw_features(scene, int(d) - 1)
        elif d == 0:
            owner = "in the background"
        else:
            owner = "at edge pixels shared by several primitives"
        lines.append(f"colour: {count} px {where} differ {owner} (max diff "
                     f"{int(pixel_diff[selection].max())}/255; at {_where(selection)})")
    return lines
