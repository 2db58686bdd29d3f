"""Line stage: clipping, setup and rasterization of width-1 lines (GL_LINES).

A line goes through the same spaces as a triangle (docs/design.md section 3):
clip space -> `clip_lines` -> `softras.pipeline.setup.viewport_transform` (fused for
the shader's vertices, unfused for the clipper's) -> window space ->
`rasterize_lines` -> fragments, with a parameter ``t`` per fragment for
depth (`depth_at_samples`) and attributes (`interpolate_lines`).
`line_fragments` does all of it for one draw.

In gl precision rasterization reproduces Mesa 22.3.6 llvmpipe
(lp_setup_line.c) bit for bit, checked on tens of thousands of random lines
against glref:

1. Diamond-exit rule.  A pixel is drawn when the segment *exits* the pixel's
   diamond ``|x - x_c| + |y - y_c| < 1/2``.  In the line's interior that is
   the pixel the line crosses in each column (x-major, ``|dx| >= |dy|``) or
   row (y-major); only the two end pixels need a decision: the first pixel
   is drawn when the start point lies inside its diamond or the segment
   leaves the diamond (``draw_start``), the last one only when the segment
   leaves its diamond before the end point (``draw_end``).  llvmpipe decides
   these with sign tests and one intersection test in float32.
2. A thin quad.  The segment becomes a parallelogram one pixel thick along
   the minor axis (x-major: y +- 1/2 with vertical ends; y-major: x +- 1/2
   with horizontal ends).  Where the quad alone would get an end pixel wrong
   ("will_draw" != "draw"), that end is moved along the line to the pixel's
   border.  Mesa 22.3's "will_draw" tests are the original sign tests, which
   are wrong for y-major lines running down (in GL's y-up window space) from
   an end point whose y is exactly a pixel centre: that first pixel is not
   drawn (later Mesa rewrote these tests).
3. Fixed point.  The quad corners are snapped to 1/256 pixel with
   ``subpixel_snap`` = ``util_iround(256 * (v - 0.5))``, which on x86-64 is
   ``(int)(f + 0.5f)``: round half *away from zero*, in float32 (triangles
   use SSE's round-half-even).
4. Four half-planes.  A sample is inside when all four plane functions
   ``E = dcdx (x_i - X) + dcdy (Y - y_i)`` (integers) are > 0, or == 0 on a
   left edge (``dcdx < 0``) or a horizontal edge with ``dcdy > 0`` (GL
   framebuffers: ``bottom_edge_rule = 0``): the triangles' fill rule.
5. Binning.  llvmpipe rasterizes the planes only over the tiles (or 16x16
   block) its bounding box touches and culls a line whose box is empty or
   off the framebuffer; for diamond lines this never removes a pixel, for
   MSAA lines it does (see `_binned_region`).

With MSAA, Mesa asks for "rectangular" lines instead: a 1-pixel-wide
rectangle around the segment (pixel corners at integers), no end rule,
covered per sample (``rectangular=True``, the default when there is more than
one sample).

Attributes follow llvmpipe's line coefficients.  Diamond lines vary along
the *major axis only* (the "preferred wide-lines formula"): for an x-major
line ``t = (x_c - x0) / (x1 - x0)`` at the pixel centre, whatever the pixel's
y; rectangular lines use the projection onto the line.  t is not clamped
(end pixels can lie slightly beyond an end point).  Depth is linear in t;
other attributes are perspective-correct (a/w and 1/w linear in t).  In gl
precision MSAA lines are evaluated half a pixel up and right of where they
should be, as llvmpipe does (`attribute_shift`).

`clip_lines` is Mesa's draw-module line clipper (draw_pipe_clip.c,
do_clip_line): parametric t0/t1 clipping against the six frustum planes in
float32, each new end point interpolated from the vertex it replaces.

``precision="exact"`` runs the same rules in float64 without snapping or
binning, with later Mesa's corrected end-pixel tests.

`bresenham` is the lecture's integer algorithm, for teaching; GL does not
use it (it differs from the diamond rule at end points and on ties).

Why one module of ~810 lines: lines are a pipeline of their own (clip, setup,
rasterization by the diamond-exit rule, interpolation) that shares nothing
with triangles below the viewport transform; its sections follow that order,
and llvmpipe's line setup is kept in one place as the Mesa source it mirrors.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numba
import numpy as np

from softras.pipeline.clip import _plane_distances, clip_planes
from softras.pipeline.rasterize import Fragments, _sample_box
from softras.pipeline.setup import viewport_transform

FIXED_ORDER = 8
FIXED_ONE = 1 << FIXED_ORDER        # llvmpipe's subpixel grid: 1/256 pixel

__all__ = ["bresenham", "ClippedLines", "clip_lines", "line_quads", "rasterize_lines",
           "depth_at_samples", "interpolate_lines", "LineFragments", "line_fragments"]


# --------------------------------------------------------------------------- Bresenham (teaching)


def bresenham(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """The lecture's Bresenham line from pixel (x0, y0) to pixel (x1, y1), both included.

    Integer arithmetic only.  The line is walked along its major axis, one
    pixel per step; the decision variable ``d`` is 2 * dmajor times the
    signed distance (along the minor axis) from the ideal line to the
    midpoint between the two candidate pixels of the next step.  When the
    line passes above that midpoint (``d > 0``) the minor coordinate steps
    too.  On an exact tie (``d == 0``) it does not, so a line and its
    reverse can differ on ties.  All eight octants: walk from (x0, y0)
    with step signs sx, sy, swapping the roles of x and y for steep lines.
    Returns max(|dx|, |dy|) + 1 pixels in order from the first end point.
    """
    for v in (x0, y0, x1, y1):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"bresenham takes integer pixel coordinates, not {v!r}")
    x0, y0, x1, y1 = int(x0), int(y0), int(x1), int(y1)
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    sx = 1 if x1 >= x0 else -1
    sy = 1 if y1 >= y0 else -1
    steep = dy > dx
    if steep:                       # walk along y: the roles of x and y swap
        dx, dy = dy, dx
    pixels = []
    x, y = x0, y0
    d = 2 * dy - dx                 # decision at the first midpoint
    for _ in range(dx + 1):
        pixels.append((x, y))
        if d > 0:                   # the ideal line passes the midpoint: minor step
            if steep:
                x += sx
            else:
                y += sy
            d -= 2 * dx
        d += 2 * dy
        if steep:                   # major step
            y += sy
        else:
            x += sx
    return pixels


# --------------------------------------------------------------------------- clipping


@dataclass(frozen=True)
class ClippedLines:
    """Lines after clipping, in clip space.

    clip : (L, 2, 4) float64 clip-space end points.
    source : (L,) int64 index of the input line each one came from.
    weights : (L, 2, 2) float64; ``weights[l, k]`` are the weights of end
        point k with respect to the source line's two vertices, so an
        attribute is ``weights[l] @ attribute[indices[source[l]]]``.
    generated : (L, 2) bool, end points made by the clipper (their window
        coordinates are computed by Mesa's C code, unfused: see
        `softras.pipeline.setup.viewport_transform`).
    """

    clip: np.ndarray
    source: np.ndarray
    weights: np.ndarray
    generated: np.ndarray

    def __len__(self) -> int:
        return len(self.source)


def clip_lines(clip: np.ndarray, indices: np.ndarray, *, precision: str = "gl",
               policy: str = "llvmpipe", width: int = 1, height: int = 1) -> ClippedLines:
    """Clip indexed lines against the six frustum planes (Mesa's do_clip_line).

    clip : (N, 4) float64 clip-space vertex positions; indices : (M, 2).
    policy : "llvmpipe" (the view volume; what Mesa does for desktop GL
        lines) or "guard_band" (x and y against `softras.pipeline.clip`'s guard band,
        z against the view volume); width, height size the guard band.
    A line with both end points inside every plane passes unchanged; one with
    both end points outside the same plane is dropped; otherwise, for every
    plane (right, left, top, bottom, near, far) that either end point is
    outside of, ``t0`` (from v0) and ``t1`` (from v1) grow to
    ``d0 / (d0 - d1)`` and ``d1 / (d1 - d0)``; the line is dropped when
    ``t0 + t1 >= 1``, and an end point that was outside any plane is
    replaced by ``v0 + t0 (v1 - v0)`` (``v1 + t1 (v0 - v1)``).  In gl
    precision all of this is float32, as in the draw module.  Lines with a
    non-finite end point are dropped.  Order is preserved (draw order).
    """
    indices = np.ascontiguousarray(np.asarray(indices, np.int64).reshape(-1, 2))
    c, finite, planes = clip_inputs(clip, precision, policy, width, height)
    n = len(indices)
    out = ClippedLines(np.empty((n, 2, 4)), np.empty(n, np.int64), np.empty((n, 2, 2)), np.empty((n, 2), bool))
    count = _clip_all(c, finite, indices, _plane_distances(c, planes), c.dtype.type(0), out.clip, out.weights,
                      out.generated, out.source)
    return ClippedLines(out.clip[:count], out.source[:count], out.weights[:count], out.generated[:count])


def clip_inputs(clip: np.ndarray, precision: str, policy: str, width: int,
                height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the line clipper (`_clip_line`) reads: the clip positions c (N, 4)
    in the draw module's type (float32 in gl precision, inf beyond its
    range; float64 in exact), whether the float64 positions are finite
    (N,), and the policy's planes (6, 4) in c's type."""
    clip = np.asarray(clip, np.float64)
    ftype = np.float32 if precision == "gl" else np.float64
    with np.errstate(over="ignore"):            # (beyond float32: inf, as in the draw module)
        c = np.ascontiguousarray(clip.astype(ftype))
    planes = np.ascontiguousarray(clip_planes(policy, width, height).astype(ftype))
    return c, np.isfinite(clip).all(axis=1), planes


@numba.njit(cache=True)
def _clip_all(c, finite, indices, dist, zero, out_clip, out_weights, out_generated, source):
    """`clip_lines` of every line of indices (M, 2) (`_clip_line`, in order):
    the survivors written to rows 0 .. count - 1 of out_clip (M, 2, 4),
    out_weights (M, 2, 2), out_generated (M, 2) and source (M,) (the input
    line).  c (N, 4): the clip positions in the draw module's type, finite
    (N,) whether the float64 positions are finite, dist (N, 6) their
    distances to the policy's planes (`softras.pipeline.clip._plane_distances`,
    computed by the caller: another module's compiled code, whose edits this
    function's cache entry would not see, `softras.pipeline.cache_key`), zero
    c's 0.  Returns count."""
    count = 0
    for line in range(indices.shape[0]):
        i0, i1 = indices[line, 0], indices[line, 1]
        if finite[i0] and finite[i1] and _clip_line(c, dist, i0, i1, zero, out_clip, out_weights,
                                                    out_generated, count):
            source[count] = line
            count += 1
    return count


@numba.njit(cache=True, inline="always")
def _clip_line(c, dist, i0, i1, zero, out_clip, out_weights, out_generated, k):
    """Mesa's do_clip_line of the line from vertex i0 to vertex i1, written
    to row k of out_clip, out_weights and out_generated (see `clip_lines`).
    dist (N, 6): the vertices' plane distances (`_plane_distances`), c and
    zero as `_clip_all`'s; every operation in c's type (Python's ``max(t,
    x)`` written out: x only when x > t).  Returns False when the line is
    dropped: both end points outside one plane, or t0 + t1 >= 1."""
    outside0, outside1 = False, False
    for plane in range(dist.shape[1]):
        o0, o1 = dist[i0, plane] < 0, dist[i1, plane] < 0
        if o0 and o1:
            return False
        outside0 |= o0
        outside1 |= o1
    t0 = zero
    t1 = zero
    if outside0 or outside1:
        for plane in range(dist.shape[1]):
            d0 = dist[i0, plane]
            d1 = dist[i1, plane]
            if not (d0 < 0 or d1 < 0):
                continue
            if d1 < 0:
                x1 = d1 / (d1 - d0)
                t1 = x1 if x1 > t1 else t1
            if d0 < 0:
                x0 = d0 / (d0 - d1)
                t0 = x0 if x0 > t0 else t0
            if t0 + t1 >= 1:
                return False
    for j in range(4):
        out_clip[k, 0, j] = c[i0, j] + t0 * (c[i1, j] - c[i0, j]) if outside0 else c[i0, j]
        out_clip[k, 1, j] = c[i1, j] + t1 * (c[i0, j] - c[i1, j]) if outside1 else c[i1, j]
    out_weights[k, 0, 0] = 1.0 - np.float64(t0) if outside0 else 1.0
    out_weights[k, 0, 1] = np.float64(t0) if outside0 else 0.0
    out_weights[k, 1, 0] = np.float64(t1) if outside1 else 0.0
    out_weights[k, 1, 1] = 1.0 - np.float64(t1) if outside1 else 1.0
    out_generated[k, 0] = outside0
    out_generated[k, 1] = outside1
    return True


# --------------------------------------------------------------------------- setup (numba)


# `_r` and `_snap` are left to LLVM to inline: numba's own inlining of their
# 85 call sites in `_setup_line` took 4 s of its compile time.
@numba.njit(cache=True)
def _r(v, gl):
    """Round to float32 in gl precision (each float op of lp_setup_line.c is float32)."""
    if gl:
        return np.float64(np.float32(v))
    return v


@numba.njit(cache=True)
def _snap(a, gl):
    """llvmpipe subpixel_snap: util_iround(256 * a), float32, half away from zero."""
    f = _r(FIXED_ONE * a, gl)
    if not gl:
        return f
    if f >= 0.0:
        return np.float64(math.trunc(_r(f + 0.5, gl)))
    return np.float64(math.trunc(_r(f - 0.5, gl)))


@numba.njit(cache=True)
def _setup_line(x1, y1, x2, y2, rectangular, pixel_offset, gl, qx, qy):
    """lp_setup_line.c try_setup_line: the quad (qx, qy) (4,) in raster units.

    Returns False when the line is culled (zero length).  Raster units: 256
    per pixel in gl precision (integers), pixel centre (or, with
    pixel_offset 0, pixel corner) of pixel i at i * 256.
    """
    dx = _r(x1 - x2, gl)
    dy = _r(y1 - y2, gl)
    area = _r(_r(dx * dx, gl) + _r(dy * dy, gl), gl)
    if area == 0.0:
        return False
    if rectangular:
        # Mesa: scale = (line_width * 0.5f) / sqrtf(area), width 1.
        scale = _r(0.5 / _r(math.sqrt(area), gl), gl)
        tx = _snap(_r(-dy * scale, gl), gl)
        ty = _snap(_r(dx * scale, gl), gl)
        ax = _snap(_r(x1 - pixel_offset, gl), gl)
        bx = _snap(_r(x2 - pixel_offset, gl), gl)
        ay = _snap(_r(y1 - pixel_offset, gl), gl)
        by = _snap(_r(y2 - pixel_offset, gl), gl)
        qx[0] = ax - tx
        qx[1] = bx - tx
        qx[2] = bx + tx
        qx[3] = ax + tx
        qy[0] = ay - ty
        qy[1] = by - ty
        qy[2] = by + ty
        qy[3] = ay + ty
        return True

    half = FIXED_ONE / 2.0          # fixed_width / 2 for width 1
    x_offset = 0.0
    y_offset = 0.0
    x_offset_end = 0.0
    y_offset_end = 0.0
    # "FIXME: not taking into account setup->pixel_offset here is wrong."
    x1diff = _r(_r(x1 - math.floor(x1), gl) - 0.5, gl)
    y1diff = _r(_r(y1 - math.floor(y1), gl) - 0.5, gl)
    x2diff = _r(_r(x2 - math.floor(x2), gl) - 0.5, gl)
    y2diff = _r(_r(y2 - math.floor(y2), gl) - 0.5, gl)

    if abs(dx) >= abs(dy):
        # X-MAJOR LINE
        dydx = _r(dy / dx, gl)
        if y2diff == -0.5 and dy < 0.0:
            y2diff = 0.5
        # Diamond exit rule test for the starting point.  sign(v) is v >= 0.
        if _r(abs(x1diff) + abs(y1diff), gl) < 0.5:
            draw_start = True
        elif (x1diff >= 0.0) == (-dx >= 0.0):
            draw_start = False
        elif (-y1diff >= 0.0) != (dy >= 0.0):
            draw_start = True
        else:
            yintersect = _r(_r(y1 - math.floor(y1), gl) + _r(x1diff * dydx, gl), gl)
            draw_start = yintersect < 1.0 and yintersect > 0.0
        # ... and for the ending point.
        if _r(abs(x2diff) + abs(y2diff), gl) < 0.5:
            draw_end = False
        elif (x2diff >= 0.0) != (-dx >= 0.0):
            draw_end = False
        elif (-y2diff >= 0.0) == (dy >= 0.0):
            draw_end = True
        else:
            yintersect = _r(_r(y2 - math.floor(y2), gl) + _r(x2diff * dydx, gl), gl)
            draw_end = yintersect < 1.0 and yintersect > 0.0

        # Are we already drawing start/end?  gl: Mesa 22.3's sign tests;
        # exact: the corrected tests of later Mesa (they differ on ties).
        if gl:
            will_draw_start = (-x1diff >= 0.0) != (dx >= 0.0)
            will_draw_end = ((x2diff >= 0.0) == (-dx >= 0.0)) or x2diff == 0.0
        elif dx < 0.0:
            will_draw_start = x1diff <= 0.0
            will_draw_end = x2diff > 0.0
        else:
            will_draw_start = x1diff > 0.0
            will_draw_end = x2diff <= 0.0
        if dx < 0.0:
            # v1 becomes the right end: swap.
            x1, y1, x2, y2 = x2, y2, x1, y1
            if will_draw_start != draw_start:
                x_offset_end = _r(-x1diff - 0.5, gl)
                y_offset_end = _r(x_offset_end * dydx, gl)
            if will_draw_end != draw_end:
                x_offset = _r(-x2diff - 0.5, gl)
                y_offset = _r(x_offset * dydx, gl)
        else:
            if will_draw_start != draw_start:
                x_offset = _r(-x1diff + 0.5, gl)
                y_offset = _r(x_offset * dydx, gl)
            if will_draw_end != draw_end:
                x_offset_end = _r(-x2diff + 0.5, gl)
                y_offset_end = _r(x_offset_end * dydx, gl)

        ax = _snap(_r(_r(x1 + x_offset, gl) - pixel_offset, gl), gl)
        bx = _snap(_r(_r(x2 + x_offset_end, gl) - pixel_offset, gl), gl)
        ay = _snap(_r(_r(y1 + y_offset, gl) - pixel_offset, gl), gl)
        by = _snap(_r(_r(y2 + y_offset_end, gl) - pixel_offset, gl), gl)
        qx[0] = ax
        qx[1] = bx
        qx[2] = bx
        qx[3] = ax
        qy[0] = ay - half
        qy[1] = by - half
        qy[2] = by + half
        qy[3] = ay + half
    else:
        # Y-MAJOR LINE
        dxdy = _r(dx / dy, gl)
        if x2diff == -0.5 and dx < 0.0:
            x2diff = 0.5
        if _r(abs(x1diff) + abs(y1diff), gl) < 0.5:
            draw_start = True
        elif (-y1diff >= 0.0) == (dy >= 0.0):
            draw_start = False
        elif (x1diff >= 0.0) != (-dx >= 0.0):
            draw_start = True
        else:
            xintersect = _r(_r(x1 - math.floor(x1), gl) + _r(y1diff * dxdy, gl), gl)
            draw_start = xintersect < 1.0 and xintersect > 0.0
        if _r(abs(x2diff) + abs(y2diff), gl) < 0.5:
            draw_end = False
        elif (-y2diff >= 0.0) != (dy >= 0.0):
            draw_end = False
        elif (x2diff >= 0.0) == (-dx >= 0.0):
            draw_end = True
        else:
            xintersect = _r(_r(x2 - math.floor(x2), gl) + _r(y2diff * dxdy, gl), gl)
            draw_end = xintersect < 1.0 and xintersect >= 0.0

        if gl:
            will_draw_start = (y1diff >= 0.0) == (dy >= 0.0)
            will_draw_end = ((-y2diff >= 0.0) == (dy >= 0.0)) or y2diff == 0.0
        elif dy > 0.0:
            will_draw_start = y1diff > 0.0
            will_draw_end = y2diff <= 0.0
        else:
            will_draw_start = y1diff <= 0.0
            will_draw_end = y2diff > 0.0
        if dy > 0.0:
            # v1 becomes the upper end: swap.
            x1, y1, x2, y2 = x2, y2, x1, y1
            if will_draw_start != draw_start:        # bottom edge
                y_offset_end = _r(-y1diff + 0.5, gl)
                x_offset_end = _r(y_offset_end * dxdy, gl)
            if will_draw_end != draw_end:            # top edge
                y_offset = _r(-y2diff + 0.5, gl)
                x_offset = _r(y_offset * dxdy, gl)
        else:
            if will_draw_start != draw_start:        # top edge
                y_offset = _r(-y1diff - 0.5, gl)
                x_offset = _r(y_offset * dxdy, gl)
            if will_draw_end != draw_end:            # bottom edge
                y_offset_end = _r(-y2diff - 0.5, gl)
                x_offset_end = _r(y_offset_end * dxdy, gl)

        ax = _snap(_r(_r(x1 + x_offset, gl) - pixel_offset, gl), gl)
        bx = _snap(_r(_r(x2 + x_offset_end, gl) - pixel_offset, gl), gl)
        ay = _snap(_r(_r(y1 + y_offset, gl) - pixel_offset, gl), gl)
        by = _snap(_r(_r(y2 + y_offset_end, gl) - pixel_offset, gl), gl)
        qx[0] = ax - half
        qx[1] = bx - half
        qx[2] = bx + half
        qx[3] = ax + half
        qy[0] = ay
        qy[1] = by
        qy[2] = by
        qy[3] = ay
    return True


# --------------------------------------------------------------------------- rasterization (numba)


# A quad's edge i as a plane function E = dcdx (x - X) + dcdy (Y - y) of
# the raster point (X, Y), from its corner (x, y) = (qx[i], qy[i]) to the
# next, with adj whether E == 0 is inside (`_quad_planes`).  A record of
# scalars: compiled code keeps it in registers.
Plane = namedtuple("Plane", ["dcdx", "dcdy", "x", "y", "adj"])


@numba.njit(cache=True, inline="always")
def _inside_all(planes, X, Y):
    """All four plane functions E_i = dcdx (x_i - X) + dcdy (Y - y_i) > 0 (>= 0 where adj)."""
    for p in planes:
        e = p.dcdx * (p.x - X) + p.dcdy * (Y - p.y)
        if not (e > 0.0 or (e == 0.0 and p.adj)):
            return False
    return True


@numba.njit(cache=True, inline="always")
def _floor_pot(n):
    """Mesa's floor_pot on an int: 1 << bsr((unsigned) n) as an int (0 for 0)."""
    u = n & 0xFFFFFFFF
    if u == 0:
        return 0
    p = 1
    while u > 1:
        u >>= 1
        p <<= 1
    return p - (1 << 32) if p >= (1 << 31) else p


@numba.njit(cache=True)
def _binned_region(qx, qy, bottom_edge_rule, multisample, width, height, region):
    """The pixels llvmpipe rasterizes the quad's planes over (lp_setup_line.c bbox +
    lp_setup_bin_triangle), gl precision.  Writes region = x0, x1, y0, y1
    (inclusive, inside the framebuffer); returns False when the line is culled.

    The bounding box is ``ceil(min / 256) .. ceil(max / 256) - 1`` (pixel
    centres, or corners with MSAA, in [min, max)); an empty box or one
    outside the framebuffer culls the line.  A box that crosses no 64-pixel tile border
    and spans less than 16 pixels is rasterized over one 16x16 block, one
    that crosses no tile border over its tile, others over the tiles they
    touch (with MSAA, llvmpipe's 16x16-block commands rasterize the whole
    tile).  For diamond lines every covered pixel is inside the box anyway;
    for MSAA lines, samples of the pixel left of (or below) the box are
    covered only when that pixel is inside the same tile.
    """
    adj = 1 if bottom_edge_rule else 0
    minx = int(min(min(qx[0], qx[1]), min(qx[2], qx[3])))
    maxx = int(max(max(qx[0], qx[1]), max(qx[2], qx[3])))
    miny = int(min(min(qy[0], qy[1]), min(qy[2], qy[3])))
    maxy = int(max(max(qy[0], qy[1]), max(qy[2], qy[3])))
    x0 = (minx + FIXED_ONE - 1) >> FIXED_ORDER
    x1 = ((maxx + FIXED_ONE - 1) >> FIXED_ORDER) - 1
    y0 = (miny + FIXED_ONE - 1 + adj) >> FIXED_ORDER
    y1 = ((maxy + FIXED_ONE - 1 + adj) >> FIXED_ORDER) - 1
    if x1 < x0 or y1 < y0:
        return False        # "empty bounding box" (culled; MSAA lines lose their samples)
    # u_rect_test_intersection with the framebuffer
    if x0 > width - 1 or x1 < 0 or y0 > height - 1 or y1 < 0:
        return False
    x0 = max(x0, 0)
    y0 = max(y0, 0)
    nr_planes = 4 + (1 if x1 > width - 1 else 0) + (1 if y1 > height - 1 else 0)
    dx = _floor_pot((x0 ^ x1) | (y0 ^ y1))
    sz = _floor_pot((x1 - (x0 & ~3)) | (y1 - (y0 & ~3)))
    tile = 64
    if dx < tile:
        tx = (x0 // tile) * tile
        ty = (y0 // tile) * tile
        if nr_planes == 4 and sz < 16 and not multisample:
            px = tx + min(x0 & 63 & ~3, tile - 16)
            py = ty + min(y0 & 63 & ~3, tile - 16)
            region[0], region[1], region[2], region[3] = px, px + 15, py, py + 15
        else:
            region[0], region[1], region[2], region[3] = tx, tx + tile - 1, ty, ty + tile - 1
    else:
        tx0 = x0 // tile
        tx1 = min(x1, width - 1) // tile
        ty0 = y0 // tile
        ty1 = min(y1, height - 1) // tile
        region[0], region[1], region[2], region[3] = tx0 * tile, tx1 * tile + tile - 1, ty0 * tile, ty1 * tile + tile - 1
    region[0] = max(region[0], 0)
    region[1] = min(region[1], width - 1)
    region[2] = max(region[2], 0)
    region[3] = min(region[3], height - 1)
    return region[0] <= region[1] and region[2] <= region[3]


@numba.njit(cache=True)
def _raster_quad(qx, qy, bottom_edge_rule, gl, offsets, box, unit, width, height,
                 out_x, out_y, out_mask, start, write):
    """Cover one line quad; write fragments from `start` when `write`.  Returns the count.

    Candidates are found per pixel row from the quad's extent in that row's
    sample band (a superset, `_row_span`); the four exact plane tests decide
    (`_pixel_mask`).  (`softras.kernels.lines` walks the same rows and
    columns.)  box: the offsets' extremes
    (`softras.pipeline.rasterize._sample_box`, computed by the caller, as
    `_clip_all`'s distances are).
    """
    planes = _quad_planes(qx, qy, bottom_edge_rule)
    region = np.array([0, width - 1, 0, height - 1])
    if gl and not _binned_region(qx, qy, bottom_edge_rule, offsets.shape[0] > 1, width, height, region):
        return 0
    py0, py1 = _quad_rows(qy, unit, box, region)
    count = 0
    for py in range(py0, py1 + 1):
        px0, px1 = _row_span(qx, qy, py, unit, box, region)
        for px in range(px0, px1 + 1):
            mask = _pixel_mask(planes, px, py, offsets, unit)
            if mask != 0:
                if write:
                    out_x[start + count] = px
                    out_y[start + count] = py
                    out_mask[start + count] = mask
                count += 1
    return count


@numba.njit(cache=True, inline="always")
def _quad_planes(qx, qy, bottom_edge_rule):
    """The quad's four edges as `Plane`s: edge i from corner i to corner i + 1
    (mod 4), dcdx = qy[i] - qy[i + 1], dcdy = qx[i] - qx[i + 1]; E == 0 is
    inside on left edges (dcdx < 0) and, by the fill convention, on
    horizontal edges with dcdy > 0 (bottom_edge_rule 0) or < 0."""
    return (_quad_plane(qx, qy, 0, bottom_edge_rule), _quad_plane(qx, qy, 1, bottom_edge_rule),
            _quad_plane(qx, qy, 2, bottom_edge_rule), _quad_plane(qx, qy, 3, bottom_edge_rule))


@numba.njit(cache=True, inline="always")
def _quad_plane(qx, qy, i, bottom_edge_rule):
    j = (i + 1) & 3
    dcdx = qy[i] - qy[j]
    dcdy = qx[i] - qx[j]
    adj = dcdx < 0.0 or (dcdx == 0.0 and ((dcdy > 0.0) if bottom_edge_rule == 0 else (dcdy < 0.0)))
    return Plane(dcdx, dcdy, qx[i], qy[i], adj)


# The candidate search's margin, in pixels, for the rounding of its bounds:
# they are quotients with relative errors ~1e-16, off by less than 1e-6
# pixel for positions below 2^40 raster units (clipped lines lie within the
# view volume, or the guard band's 8192 pixels in exact precision), so no
# pixel that holds a covered sample is missed (tests/stages/test_lines.py
# tests every sample of the binned region).  A one-row slice's bound (a
# corner plus a quotient times a difference) errs as little where it
# bounds anything: a term it adds to a corner there is below the same
# 2^40.
_MARGIN = 1e-6


@numba.njit(cache=True, inline="always")
def _quad_rows(qy, unit, box, region):
    """The candidate pixel rows (py0, py1) of a quad: those whose sample band
    (box: `_sample_box`) can meet its y extent, ceil((ymin - max oy) / unit)
    .. floor((ymax - min oy) / unit), widened by _MARGIN, within region (x0,
    x1, y0, y1)."""
    ymin = min(min(qy[0], qy[1]), min(qy[2], qy[3]))
    ymax = max(max(qy[0], qy[1]), max(qy[2], qy[3]))
    return (max(int(math.ceil((ymin - box[3]) / unit - _MARGIN)), region[2]),
            min(int(math.floor((ymax - box[2]) / unit + _MARGIN)), region[3]))


@numba.njit(cache=True, inline="always")
def _row_span(qx, qy, py, unit, box, region):
    """The candidate pixel columns (px0, px1) of row py (px0 > px1: none):
    the quad's x extent within the row's sample band, widened by the sample
    offsets (box: `_sample_box`) and _MARGIN, within region.

    One row of samples (every sample at the same y, as at one sample a
    pixel) meets the quad in one slice, bounded on the left by the lines of
    the edges whose inside lies to their right (qy rising along the edge)
    and on the right by the others (`_quad_plane`: E >= 0 is x >= or <= the
    edge's line at that y): the largest left and the smallest right bound
    within the quad's x extent, with no branch on where the edges end.  A band of samples at several y
    is `_band_span`'s, called: inlined beside this, it slowed the one-row
    case by as much as its branches did (lines_8k_512's coverage on one
    thread, in a copy of the line kernel's loop without its rgba32f
    writes: 1.43 ms with the band's search for every row, 1.30 with it
    inlined here, 1.14 called; docs/speed.md, "Forty-seventh round")."""
    if box[2] != box[3]:
        return _band_span(qx, qy, py, unit, box, region)
    y = py * unit + box[2]
    lo = min(min(qx[0], qx[1]), min(qx[2], qx[3]))
    hi = max(max(qx[0], qx[1]), max(qx[2], qx[3]))
    for i in range(4):
        j = (i + 1) & 3
        rise = qy[j] - qy[i]
        if rise != 0.0:                 # (a level edge bounds no x)
            x = qx[i] + (y - qy[i]) * ((qx[j] - qx[i]) / rise)
            if rise > 0.0:
                lo = max(lo, x)
            else:
                hi = min(hi, x)
    return _columns(lo, hi, unit, box, region)


@numba.njit(cache=True)
def _band_span(qx, qy, py, unit, box, region):
    """`_row_span` for a row whose samples lie at several y (box[2] <
    box[3]): the quad's corners inside the row's band and its edges'
    crossings of the band's borders (the quad is a parallelogram, convex, so
    nothing of it in the band lies beyond these)."""
    lo_y = py * unit + box[2]
    hi_y = py * unit + box[3]
    lo = np.inf
    hi = -np.inf
    for i in range(4):
        j = (i + 1) & 3
        if lo_y <= qy[i] <= hi_y:
            lo = min(lo, qx[i])
            hi = max(hi, qx[i])
        for k in range(2):
            b = hi_y if k else lo_y
            da = qy[i] - b
            db = qy[j] - b
            if (da < 0.0 and db > 0.0) or (da > 0.0 and db < 0.0):
                xb = qx[i] + (b - qy[i]) * (qx[j] - qx[i]) / (qy[j] - qy[i])
                lo = min(lo, xb)
                hi = max(hi, xb)
    return _columns(lo, hi, unit, box, region)


@numba.njit(cache=True, inline="always")
def _columns(lo, hi, unit, box, region):
    """The pixel columns (px0, px1) whose samples (box: `_sample_box`) can
    lie in the raster x range lo .. hi, widened by _MARGIN, within region;
    (0, -1) when lo > hi."""
    if lo > hi:
        return 0, -1
    return (max(int(math.ceil((lo - box[1]) / unit - _MARGIN)), region[0]),
            min(int(math.floor((hi - box[0]) / unit + _MARGIN)), region[1]))


@numba.njit(cache=True, inline="always")
def _pixel_mask(planes, px, py, offsets, unit):
    """The coverage mask (uint32) of pixel (px, py): bit s set where sample s
    is inside all four `Plane`s (`_inside_all`)."""
    mask = np.uint32(0)
    for s in range(offsets.shape[0]):
        if _inside_all(planes, px * unit + offsets[s, 0], py * unit + offsets[s, 1]):
            mask |= np.uint32(1) << np.uint32(s)
    return mask


@numba.njit(cache=True)
def _quads(window, rectangular, pixel_offset, gl):
    n = window.shape[0]
    qx = np.zeros((n, 4))
    qy = np.zeros((n, 4))
    ok = np.zeros(n, np.bool_)
    for i in range(n):
        ok[i] = _setup_line(window[i, 0, 0], window[i, 0, 1], window[i, 1, 0], window[i, 1, 1],
                            rectangular, pixel_offset, gl, qx[i], qy[i])
    return qx, qy, ok


@numba.njit(cache=True)
def _line_t(x0, y0, x1, y1, x, y, rectangular, gl):
    """Parameter t of the point (x, y) for a line's attribute coefficients.

    Diamond lines (llvmpipe's "preferred wide-lines formula"): along the
    major axis only, the axis chosen as in the setup (float32 in gl).
    Rectangular (MSAA) lines: the projection onto the line,
    ``(p - p0) . (p1 - p0) / |p1 - p0|^2``.
    """
    dx = x1 - x0
    dy = y1 - y0
    if rectangular:
        return ((x - x0) * dx + (y - y0) * dy) / (dx * dx + dy * dy)
    if abs(_r(dx, gl)) >= abs(_r(dy, gl)):
        return (x - x0) / dx
    return (y - y0) / dy


@numba.njit(cache=True, parallel=True)
def _cover(qx, qy, ok, bottom_edge_rule, gl, rectangular, centre, offsets, box, unit, width, height,
           starts, window, out_x, out_y, out_mask, out_line, out_t, write):
    """Every line's coverage (`_raster_quad`), lines in parallel: counted
    (write False; the out arrays may be empty) or written from ``starts``
    with each fragment's line and t (`_line_t`, write True).  Returns (L,)
    int64 fragments per line.  One kernel for both passes, so numba compiles
    it and `_raster_quad` once."""
    n = qx.shape[0]
    counts = np.zeros(n, np.int64)
    for i in numba.prange(n):
        if ok[i]:
            start = starts[i] if write else 0
            k = _raster_quad(qx[i], qy[i], bottom_edge_rule, gl, offsets, box, unit, width, height,
                             out_x, out_y, out_mask, start, write)
            counts[i] = k
            if write:
                x0, y0 = window[i, 0, 0], window[i, 0, 1]
                x1, y1 = window[i, 1, 0], window[i, 1, 1]
                for j in range(start, start + k):
                    out_line[j] = i
                    out_t[j] = _line_t(x0, y0, x1, y1, out_x[j] + centre, out_y[j] + centre, rectangular, gl)
    return counts


def line_quads(window: np.ndarray, *, precision: str = "gl",
               rectangular: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The set-up quad of each line: (qx (L, 4), qy (L, 4), ok (L,) bool).

    Raster units: in gl precision integers, 256 per pixel, pixel i's centre
    at i * 256 (diamond lines) or its corner (rectangular lines, llvmpipe's
    multisample mode); in exact precision the same positions in float64,
    unsnapped.  ``ok`` is False for zero-length lines (culled).
    """
    window = np.ascontiguousarray(np.asarray(window, np.float64)[..., :2])
    gl = precision == "gl"
    if gl:
        window = window.astype(np.float32).astype(np.float64)
    pixel_offset = 0.0 if rectangular else 0.5
    return _quads(window, rectangular, pixel_offset, gl)


def sample_offsets(positions: np.ndarray, rectangular: bool, gl: bool) -> np.ndarray:
    """The sample positions (S, 2) in [0, 1) as raster offsets (S, 2) float64
    from where a line quad puts pixel i (its centre, or its corner for
    rectangular lines), rounded to 1/256 pixel in gl precision."""
    offsets = (np.asarray(positions, np.float64) - (0.0 if rectangular else 0.5)) * FIXED_ONE
    return np.ascontiguousarray(np.rint(offsets) if gl else offsets)


def rasterize_lines(window: np.ndarray, width: int, height: int, precision: str = "gl", *,
                    sample_positions: np.ndarray | None = None, rectangular: bool | None = None,
                    bottom_edge_rule: int = 0) -> tuple[Fragments, np.ndarray]:
    """Rasterize width-1 lines given in window coordinates.

    window : (L, 2, 2 or 3) float64 window coordinates of the end points
        (x_w, y_w[, z_w]); in gl precision float32 values (from
        `softras.pipeline.setup.viewport_transform`).
    sample_positions : (S, 2) positions in [0, 1) within the pixel (default:
        the centre).  Coverage is per sample.
    rectangular : llvmpipe's rectangular lines (default: S > 1, which is what
        Mesa asks for under MSAA); otherwise diamond-exit lines.
    bottom_edge_rule : llvmpipe's fill convention; 0 for GL framebuffers.
    Returns (fragments, t): fragments in line order, within a line in
    row-major order (``fragments.tri`` is the line index); t : (F,) float64,
    where the fragment's attributes are taken between end point 0 (t = 0)
    and end point 1 (t = 1), see the module docstring.
    """
    if precision not in ("gl", "exact"):
        raise ValueError(f"precision must be 'gl' or 'exact', not {precision!r}")
    window = np.asarray(window, np.float64)
    if window.ndim != 3 or window.shape[1] != 2 or window.shape[2] < 2:
        raise ValueError("window must have shape (L, 2, 2 or 3)")
    positions = np.array([[0.5, 0.5]]) if sample_positions is None else np.asarray(sample_positions, float)
    if len(positions) > 32:
        raise ValueError("at most 32 samples per pixel per pass")
    if rectangular is None:
        rectangular = len(positions) > 1
    gl = precision == "gl"
    unit = float(FIXED_ONE)
    offsets = sample_offsets(positions, rectangular, gl)
    if len(window) == 0:
        return Fragments.allocate(np.zeros(0, np.int64))[0], np.zeros(0)
    qx, qy, ok = line_quads(window, precision=precision, rectangular=rectangular)
    ends = np.ascontiguousarray(window[..., :2])
    if gl:
        ends = ends.astype(np.float32).astype(np.float64)
    centre = 0.5 + attribute_shift(precision, rectangular)
    args = (qx, qy, ok, bottom_edge_rule, gl, rectangular, centre, offsets, _sample_box(offsets), unit,
            int(width), int(height))
    empty, none = Fragments.allocate(np.zeros(0, np.int64))      # (the count pass writes nothing)
    frags, starts = Fragments.allocate(_cover(*args, none, ends, empty.x, empty.y, empty.mask, empty.tri,
                                              np.zeros(0), False))
    out_t = np.empty(len(frags), np.float64)
    _cover(*args, starts, ends, frags.x, frags.y, frags.mask, frags.tri, out_t, True)
    return frags, out_t


# --------------------------------------------------------------------------- interpolation


def attribute_shift(precision: str, rectangular: bool) -> float:
    """Where llvmpipe evaluates line attributes, relative to where it should.

    MSAA (rectangular) lines are set up with pixel_offset 0 (pixel corners at
    integers) but their attribute coefficients with the usual 0.5, so in gl
    precision colours are evaluated at (x + 1, y + 1) instead of the pixel
    centre and depth at each sample + (0.5, 0.5) (found by experiment,
    Mesa 22.3.6).  Exact precision evaluates where GL says: 0.
    """
    return 0.5 if (precision == "gl" and rectangular) else 0.0


def depth_at_samples(ends: np.ndarray, x: np.ndarray, y: np.ndarray,
                     sample_positions: np.ndarray, precision: str = "gl",
                     rectangular: bool | None = None) -> np.ndarray:
    """Window depth z_w of line fragments at each sample.

    ends : (F, 2, 3) window x, y, z_w of each fragment's line; x, y : (F,)
    pixels; sample_positions : (S, 2) in [0, 1).  z_w is linear in the same
    t as the other attributes (see `rasterize_lines`): along the major axis
    for diamond lines, the projection onto the line for rectangular (MSAA,
    the default when S > 1) lines, evaluated at each sample.  Returns (F, S).
    """
    if rectangular is None:
        rectangular = len(sample_positions) > 1
    ends = np.asarray(ends, np.float64)
    if precision == "gl":
        ends = ends.astype(np.float32).astype(np.float64)
    d = ends[:, 1] - ends[:, 0]
    dxy = d[:, :2].astype(np.float32) if precision == "gl" else d[:, :2]
    xmajor = (np.abs(dxy[:, 0]) >= np.abs(dxy[:, 1]))[:, None]
    shift = attribute_shift(precision, rectangular)
    sx = x[:, None] + sample_positions[None, :, 0] + shift
    sy = y[:, None] + sample_positions[None, :, 1] + shift
    with np.errstate(divide="ignore", invalid="ignore"):
        if rectangular:
            t = (((sx - ends[:, 0:1, 0]) * d[:, 0:1] + (sy - ends[:, 0:1, 1]) * d[:, 1:2])
                 / (d[:, 0:1] ** 2 + d[:, 1:2] ** 2))
        else:
            t = np.where(xmajor, (sx - ends[:, 0:1, 0]) / d[:, 0:1], (sy - ends[:, 0:1, 1]) / d[:, 1:2])
    t = np.where(np.isfinite(t), t, 0.0)
    return ends[:, 0:1, 2] + t * d[:, 2:3]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _sample_t(sx, sy, x0, y0, dx, dy, rectangular, x_major):
    """`depth_at_samples`' t at one sample (sx, sy) of a line from (x0, y0)
    along (dx, dy), for the compiled line kernels: the projection onto the
    line for a rectangular line, else along the major axis (x_major: |dx| >=
    |dy|, compared in the precision's type); 0 where it is not finite."""
    if rectangular:
        t = ((sx - x0) * dx + (sy - y0) * dy) / (dx * dx + dy * dy)
    elif x_major:
        t = (sx - x0) / dx
    else:
        t = (sy - y0) / dy
    return t if math.isfinite(t) else 0.0


def interpolate_lines(t: np.ndarray, inv_w: np.ndarray, values: np.ndarray,
                      perspective: bool = True) -> np.ndarray:
    """Attributes of line fragments.

    t : (F,); inv_w : (F, 2) 1/w_clip of the end points; values : (F, 2, K).
    Perspective-correct: a/w and 1/w are linear in t (screen space), as in
    llvmpipe's perspective_coef; ``perspective=False`` is noperspective.
    Returns (F, K).
    """
    if perspective:
        q0 = (1.0 - t) * inv_w[:, 0]
        q1 = t * inv_w[:, 1]
        total = q0 + q1
        b0, b1 = q0 / total, q1 / total
    else:
        b0, b1 = 1.0 - t, t
    return b0[:, None] * values[:, 0] + b1[:, None] * values[:, 1]


@dataclass(frozen=True)
class LineFragments:
    """What the per-sample operations need for one draw of lines.

    fragments : `softras.pipeline.rasterize.Fragments` (``tri`` indexes the clipped lines).
    z : (F, S) window depth per sample (unquantized).
    values : (F, K) the interpolated per-vertex values (e.g. colours).
    """

    fragments: Fragments
    z: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return len(self.fragments)


@numba.njit(cache=True, inline="always")
def _end_values(values, i0, i1, e, weights, generated, out):
    """`rasterized_lines`' values at end e of a clipped line into out[e]
    (out (2, K)): an end the clipper kept (not ``generated[0, e]``) vertex
    e's values (of i0, i1) as they are, an end it made the clip weights
    (weights[0, e]) x the two vertices' values.  For the line kernels
    (`softras.kernels.lines`, `softras.kernels.exact_lines`)."""
    for k in range(out.shape[1]):
        if generated[0, e]:
            out[e, k] = weights[0, e, 0] * values[i0, k] + weights[0, e, 1] * values[i1, k]
        else:
            out[e, k] = values[i0 if e == 0 else i1, k]


def rasterized_lines(clip: np.ndarray, indices: np.ndarray, width: int, height: int, *,
                     values: np.ndarray, precision: str = "gl", sample_positions: np.ndarray,
                     policy: str | None = None):
    """`line_fragments` up to the fragments: clip, viewport, rasterize.

    Returns (fragments, t, window (L, 2, 3), inv_w (L, 2), ends (L, 2, K)):
    `rasterize_lines`' fragments and t, then per clipped line its end
    points' window coordinates and 1/w and the values at its end points:
    an end the clipper kept its vertex's values as they are, an end it
    made the clip weights x the source vertices' values (as a triangle's
    corners, `softras.pipeline.render.corner_values`).  Arguments as
    `line_fragments`.
    """
    policy = policy or ("llvmpipe" if precision == "gl" else "guard_band")
    clipped = clip_lines(clip, indices, precision=precision, policy=policy, width=width, height=height)
    fused = True if precision != "gl" else ~clipped.generated
    window, inv_w = viewport_transform(clipped.clip, width, height, precision, fused)
    frags, t = rasterize_lines(window, width, height, precision, sample_positions=sample_positions)
    source = np.asarray(indices, np.int64).reshape(-1, 2)[clipped.source]          # (L, 2)
    at = np.asarray(values, np.float64)[source]                                    # (L, 2, K)
    made = clipped.weights[..., 0:1] * at[:, None, 0] + clipped.weights[..., 1:2] * at[:, None, 1]
    ends = np.where(clipped.generated[..., None], made, at)      # (end k of a kept line: vertex k)
    return frags, t, window, inv_w, ends


def line_fragments(clip: np.ndarray, indices: np.ndarray, width: int, height: int, *,
                   values: np.ndarray, precision: str = "gl",
                   sample_positions: np.ndarray | None = None,
                   policy: str | None = None) -> LineFragments:
    """One draw of GL_LINES, clip space to fragments: clip, viewport, rasterize, interpolate.

    clip : (N, 4) clip-space positions; indices : (M, 2); values : (N, K)
    per-vertex values (colours) interpolated perspective-correctly;
    sample_positions : (S, 2) (default: the pixel centre; S > 1 gives
    llvmpipe's MSAA rectangular lines); policy : clipping policy (default
    "llvmpipe" in gl, "guard_band" in exact).
    """
    positions = np.array([[0.5, 0.5]]) if sample_positions is None else np.asarray(sample_positions, float)
    frags, t, window, inv_w, ends = rasterized_lines(clip, indices, width, height, values=values,
                                                     precision=precision, sample_positions=positions,
                                                     policy=policy)
    line = frags.tri
    z = depth_at_samples(window[line], frags.x, frags.y, positions, precision, len(positions) > 1)
    interpolated = interpolate_lines(t, inv_w[line], ends[line])
    return LineFragments(frags, z, interpolated)
