"""Setup stage: clip space -> window space, snapping, face culling, edge equations.

Window coordinates follow GL (docs/design.md section 3): ``x_w = (x_ndc + 1) W/2``,
``y_w = (y_ndc + 1) H/2`` (y grows upward), ``z_w = (z_ndc + 1)/2``; pixel
(i, j) has its centre at (i + 0.5, j + 0.5).

Raster coordinates are what the rasterizer's edge functions are evaluated in:

``precision="gl"``
    llvmpipe's fixed point: ``X = round_half_even((x_w - 0.5) * 256)`` with the
    subtraction and product in float32 (lp_setup_tri.c, calc_fixed_position),
    so pixel centres lie on multiples of 256 and all edge arithmetic is exact
    in int64.
``precision="exact"``
    float64 window coordinates, unsnapped.

Edge i runs from vertex i to vertex i+1 of a counter-clockwise triangle (in
GL's y-up window space); ``E_i(X, Y) = A_i (X - X0_i) + B_i (Y - Y0_i)`` is
positive on the inside.  A sample exactly on an edge (E_i == 0) belongs to the triangle
when the edge is a left edge (A_i > 0) or a bottom edge (A_i == 0, B_i > 0):
the rule llvmpipe applies to GL framebuffers (its "top-left" rule in its
y-down view of a framebuffer whose row 0 is GL's bottom row).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softras.scene.model import FRONT_FACES

SUBPIXEL_BITS = 8
SUBPIXEL_ONE = 1 << SUBPIXEL_BITS   # 256 raster units per pixel in gl precision


@dataclass(frozen=True)
class TriangleSetup:
    """Everything the rasterizer and interpolator need, for T' surviving triangles.

    triangle : (T',) int64 index into the clipped triangles.
    corner : (T', 3) int64; setup vertex k is corner ``corner[t, k]`` of the
        clipped triangle (clockwise triangles get two corners swapped).
    window : (T', 3, 3) float64 unsnapped window coordinates (x_w, y_w, z_w).
    inv_w : (T', 3) float64 1 / w_clip per vertex.
    raster : (T', 3, 2) int64 (gl) or float64 (exact) raster coordinates.
    edge_a, edge_b, edge_x0, edge_y0 : (T', 3) edge functions in raster units,
        ``E = A (X - X0) + B (Y - Y0)`` (see `edge_equations`).
    edge_inclusive : (T', 3) bool, fill rule per edge.
    bbox : (T', 4) int64 pixel bounds x0, x1, y0, y1 (inclusive, clamped).
    front_facing : (T',) bool (counter-clockwise in window space, or clockwise
        with ``front_face="cw"``).
    """

    triangle: np.ndarray
    corner: np.ndarray
    window: np.ndarray
    inv_w: np.ndarray
    raster: np.ndarray
    edge_a: np.ndarray
    edge_b: np.ndarray
    edge_x0: np.ndarray
    edge_y0: np.ndarray
    edge_inclusive: np.ndarray
    bbox: np.ndarray
    front_facing: np.ndarray

    def __len__(self) -> int:
        return len(self.triangle)


def viewport_transform(clip: np.ndarray, width: int, height: int, precision: str = "gl",
                       fused: np.ndarray | bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Perspective divide and viewport transform.

    clip : (..., 4) float64 clip coordinates with w > 0.
    fused : bool or (...,) bool, gl precision only.  llvmpipe's generated
        vertex code computes ``x_w = fma(x * oow, W/2, W/2)`` in float32 with
        one rounding (found by experiment: the unfused form mismatches
        llvmpipe on ties, the fused one never did); vertices made by the
        clipper go through Mesa's C code, which rounds the product and the
        sum separately (``fused=False``).
    Returns (window (..., 3) float64, inv_w (...,) float64).  In "gl"
    precision every value is a float32.
    """
    scale = np.array([width / 2.0, height / 2.0, 0.5])
    if precision == "gl":
        c = clip.astype(np.float32)
        oow = np.float32(1.0) / c[..., 3]
        projected = (c[..., :3] * oow[..., None]).astype(np.float64)       # NDC, float32 values
        single = (projected * scale + scale).astype(np.float32)            # fma: one rounding
        double = ((projected * scale).astype(np.float32) + scale.astype(np.float32))
        window = np.where(np.asarray(fused)[..., None], single, double)
        return window.astype(np.float64), oow.astype(np.float64)
    oow = 1.0 / clip[..., 3]
    return clip[..., :3] * oow[..., None] * scale + scale, oow


def snap(window_xy: np.ndarray) -> np.ndarray:
    """llvmpipe's subpixel snap: (..., 2) float window x, y -> int64 raster units.

    ``round_half_even((v - 0.5) * 256)`` computed in float32 (SSE cvtps2dq).
    """
    v = window_xy.astype(np.float32)
    shifted = (v - np.float32(0.5)) * np.float32(SUBPIXEL_ONE)
    return np.rint(shifted).astype(np.int64)


def sample_offsets(positions: np.ndarray, precision: str) -> tuple[np.ndarray, float]:
    """Sample positions within a pixel -> (offsets (S, 2) in raster units, unit).

    positions : (S, 2) float in [0, 1), measured from the pixel's lower-left
    corner.  Sample s of pixel (i, j) is at raster ``(i*unit + off[s, 0],
    j*unit + off[s, 1])``.
    """
    if precision == "gl":
        return np.rint((positions - 0.5) * SUBPIXEL_ONE).astype(np.int64), float(SUBPIXEL_ONE)
    return positions.astype(np.float64), 1.0


def edge_equations(xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """Edge functions of counter-clockwise triangles, (T, 3) raster x, y -> A, B, X0, Y0.

    ``E_i(X, Y) = A_i (X - X0_i) + B_i (Y - Y0_i)`` for the edge from vertex
    i to i+1, where (X0, Y0) is one of its endpoints.  Each edge is computed
    from its endpoints in a canonical (lexicographic) order and then negated
    if needed, so the two triangles sharing an edge get exactly opposite
    values E at every sample even in float64, and E is exactly 0 at both
    endpoints: no sample on a shared edge or vertex is lost or counted twice,
    even where rounding decides it (the watertightness test).
    """
    nxt = [1, 2, 0]
    x0, y0, x1, y1 = xs, ys, xs[:, nxt], ys[:, nxt]
    swap = (x0 > x1) | ((x0 == x1) & (y0 > y1))
    px, py = np.where(swap, x1, x0), np.where(swap, y1, y0)
    qx, qy = np.where(swap, x0, x1), np.where(swap, y0, y1)
    sign = np.where(swap, -1, 1).astype(xs.dtype)
    return (py - qy) * sign, (qx - px) * sign, px, py


#: The consistent tie rules: which edges own a sample exactly on them, in GL's
#: y-up window space. GL 4.6 section 14.6.1 asks only that a sample on an edge
#: shared by two polygons goes to exactly one of them; each rule here does
#: that (two triangles sharing an edge see it with opposite (A, B)).
#: "left_bottom" is llvmpipe's (D3D's top-left rule seen with y up).
TIE_RULES = {"left_bottom": (1, 1), "right_bottom": (-1, 1), "left_top": (1, -1), "right_top": (-1, -1)}


def window_cull(cull: str, front_face: str = "ccw") -> str:
    """The cull mode in counter-clockwise terms: ``cull`` ("none", "back",
    "front") under glFrontFace ``front_face`` ("ccw" or "cw") culls the same
    triangles as the returned mode under "ccw" (with "cw" front and back
    swap).  For the kernels, which know only counter-clockwise fronts."""
    if front_face not in FRONT_FACES:
        raise ValueError(f"unknown front_face {front_face!r}")
    if front_face == "cw" and cull != "none":
        return "front" if cull == "back" else "back"
    return cull


def setup_triangles(clip: np.ndarray, width: int, height: int, *, precision: str = "gl",
                    cull: str = "none", offsets: np.ndarray, unit: float,
                    generated: np.ndarray | None = None, tie_rule: str = "left_bottom",
                    front_face: str = "ccw") -> TriangleSetup:
    """Set up clipped triangles for rasterization.

    clip : (T, 3, 4) float64 clip-space triangles (after the clip stage).
    cull : "none", "back" or "front".
    front_face : "ccw" (GL's default) or "cw": the winding in window space
        (y up) of front-facing triangles (glFrontFace, GL 4.6 section 14.6.1).
        It decides only facing and culling: the corners are reordered
        counter-clockwise for the edge functions either way.
    offsets, unit : from `sample_offsets`.
    generated : (T, 3) bool, vertices made by the clipper (see `viewport_transform`).
    tie_rule : one of `TIE_RULES`: the edges that own a sample exactly on them.
    """
    fused = True if generated is None else ~generated
    window, inv_w = viewport_transform(clip, width, height, precision, fused)
    if precision == "gl":
        raster = snap(window[..., :2])
    else:
        raster = window[..., :2].copy()

    x, y = raster[..., 0], raster[..., 1]
    # Twice the signed area, counter-clockwise positive (exact in int64 for gl).
    area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    counter_clockwise = area > 0
    keep = area != 0
    ccw_cull = window_cull(cull, front_face)        # (the kernels' cull mode too)
    if ccw_cull == "back":
        keep &= counter_clockwise
    elif ccw_cull == "front":
        keep &= ~counter_clockwise
    elif ccw_cull != "none":
        raise ValueError(f"unknown cull mode {cull!r}")
    front = counter_clockwise if front_face == "ccw" else area < 0

    index = np.nonzero(keep)[0]
    corner = np.tile(np.arange(3), (len(index), 1))
    clockwise = ~counter_clockwise[index]
    corner[clockwise] = [1, 0, 2]           # swap corners 0 and 1 -> counter-clockwise
    window = np.take_along_axis(window[index], corner[..., None], axis=1)
    inv_w = np.take_along_axis(inv_w[index], corner, axis=1)
    raster = np.take_along_axis(raster[index], corner[..., None], axis=1)

    xs, ys = raster[..., 0], raster[..., 1]
    a, b, x0, y0 = edge_equations(xs, ys)
    sign_a, sign_b = TIE_RULES[tie_rule]
    inclusive = (sign_a * a > 0) | ((a == 0) & (sign_b * b > 0))

    bbox = np.stack([
        np.ceil((xs.min(axis=1) - offsets[:, 0].max()) / unit),
        np.floor((xs.max(axis=1) - offsets[:, 0].min()) / unit),
        np.ceil((ys.min(axis=1) - offsets[:, 1].max()) / unit),
        np.floor((ys.max(axis=1) - offsets[:, 1].min()) / unit),
    ], axis=1)
    bbox[:, 0:2] = np.clip(bbox[:, 0:2], -1, width)
    bbox[:, 2:4] = np.clip(bbox[:, 2:4], -1, height)
    bbox = bbox.astype(np.int64)
    bbox[:, 0] = np.maximum(bbox[:, 0], 0)
    bbox[:, 1] = np.minimum(bbox[:, 1], width - 1)
    bbox[:, 2] = np.maximum(bbox[:, 2], 0)
    bbox[:, 3] = np.minimum(bbox[:, 3], height - 1)
    visible = (bbox[:, 0] <= bbox[:, 1]) & (bbox[:, 2] <= bbox[:, 3])

    return TriangleSetup(
        triangle=index[visible],
        corner=corner[visible],
        window=window[visible],
        inv_w=inv_w[visible],
        raster=raster[visible],
        edge_a=a[visible],
        edge_b=b[visible],
        edge_x0=x0[visible],
        edge_y0=y0[visible],
        edge_inclusive=inclusive[visible],
        bbox=bbox[visible],
        front_facing=front[index][visible],
    )
