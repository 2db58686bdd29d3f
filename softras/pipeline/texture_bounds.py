"""Texture lookup bounds: what ANY conformant GL implementation may return.

softras's own sampler (`softras.pipeline.texture`) reproduces one implementation
(llvmpipe) or the spec's formulas in exact arithmetic.  The spec leaves a
texture lookup room: how the scale factor rho is approximated, where the
derivatives are taken, the precision of lambda, of the texel coordinates and
of the filter arithmetic.  This module gives, per fragment, lower and upper
bounds ``(lo, hi)`` of the filtered value over that room, so that a picture
from another implementation (Mesa softpipe, a GPU) can be checked against
softras without reproducing its arithmetic.  It follows the model of dEQP's
texture lookup verifier (VK-GL-CTS ``framework/common/tcuTexLookupVerifier.cpp``
and ``tcuTexVerifierUtil.cpp``): a result is valid when it is the filtered
value for SOME level of detail in a lambda range and SOME coordinate in a
small box, within a colour threshold.  dEQP tests one value for membership;
here the range itself is computed (its per-channel min and max).

Coordinate spaces
-----------------
(s, t) : normalized texture coordinates, as in `softras.pipeline.texture`.
(u, v) : texel coordinates of a level, ``u = s W_l``, ``v = t H_l``; texel
    (i, j) has its centre at (i + 1/2, j + 1/2).  Level-0 texels for rho.
Derivatives : d(s, t)/dx and d(s, t)/dy per window pixel (GL window space).
Colours : premultiplied RGBA; texel arrays on the 0..255 scale (uint8 or
    float), results in [0, 1].

The room GL allows, and the figure used for each
------------------------------------------------
1. **Scale factor** (GL 4.6 core, section 8.14.1, equation 8.7 and the text
   after it): rho = max(|d(u,v)/dx|, |d(u,v)/dy|) may be replaced by any
   f(x, y) with ``max(m_u, m_v) <= f <= m_u + m_v``, ``m_u = max(|du/dx|,
   |du/dy|)``, ``m_v = max(|dv/dx|, |dv/dy|)``.  The exact rho lies in that
   range, so [max(m_u, m_v), m_u + m_v] is the range per derivative pair.
   (dEQP's ``computeLodBoundsFromDerivates`` uses the same m_u + m_v for GL
   and has a relaxed rule for Vulkan, ``LodPrecision::RULE_VULKAN``;
   ``LodPrecision.rho_max_factor`` widens the upper end, 1 here, the spec's
   figure. sqrt(2) would also admit the footprint's major axis, which an
   NVIDIA H200 uses: docs/verification.md, "On a GPU".)
2. **Derivatives** (GLSL 4.60 section 8.14.1: dFdx / dFdy may be "coarse"
   or "fine"; implicit derivatives of texture() are either): per 2x2 quad
   (quads at even window x, y, helper pixels included) the x difference of
   either row and the y difference of either column -- 4 pairs -- and the
   analytic derivative at the pixel centre (:func:`fragment_derivatives`).
   llvmpipe uses row 0 / column 0 (GL's lower-left pixel), softpipe the
   other row.  Each quad difference is known to within the coordinates'
   precision (2 coordErr of the larger value, ``LookupPrecision.coord_bits``:
   float32 cancellation), and rho to ``LodPrecision.derivative_bits``
   relative bits (dEQP ``LodPrecision.derivateBits`` = 18,
   es3fTextureFilteringTests).
3. **lambda** = log2(rho) to ``lod_bits`` fractional bits (dEQP
   ``LodPrecision.lodBits`` = 6: +-2^-6), and in addition *down* by
   ``log2_error`` = 0.0861: a piecewise-linear log2 (exponent + mantissa - 1,
   exact at powers of two; llvmpipe's ``lp_build_fast_log2``) under-estimates
   log2 by up to 1 - log2(e) + log2(log2 e) = 0.0861.  That is outside
   dEQP's high (6 bits) and low (4 bits) LOD precision but it is what the
   project's reference implementation does, so the bound admits it.
4. **Min / mag switch** (section 8.14.2, c = 0 for these filters): a
   fragment whose lambda range reaches lambda <= 0 may be magnified, one
   whose range reaches lambda > 0 may be minified; both are candidates when
   the range straddles 0 (dEQP: ``canBeMagnified = minLod <= 0``,
   ``canBeMinified = maxLod > 0``).
5. **Levels** (section 8.14.3): *_MIPMAP_LINEAR blends floor(lambda') and
   floor(lambda') + 1 by frac(lambda'), lambda' = clamp(lambda, 0, q); the
   blend is linear in frac, so its extremes over a lambda interval are at the
   interval's ends and at the integers inside (candidate lambdas).
   *_MIPMAP_NEAREST takes level ceil(lambda + 1/2) - 1; dEQP (after a
   Khronos decision) also accepts floor(lambda + 1/2), so every level from
   ``ceil(lo + 1/2) - 1`` to ``floor(hi + 1/2)`` is a candidate.  The two
   levels of a blend are bounded independently (dEQP's note in
   ``isLinearMipmapLinearSampleResultValid``: "any two valid bilinear quads").
6. **Texel coordinates** (section 8.14.2, dEQP
   ``computeNonNormalizedCoordBounds``): s known to ``coord_bits`` relative
   bits (dEQP 20), then u = s W to ``uvw_bits`` sub-texel bits (dEQP
   ``uvwBits`` = 7 for the GLES3 2-D filtering tests: +-2^-7 texel; llvmpipe
   rounds u to 1/256 texel).  NEAREST: every texel the box [u-e, u+e] x
   [v-e, v+e] touches (its corners, the box being narrower than a texel).
   LINEAR: the bilinear value is multilinear inside each cell between texel
   centres, so its extremes over the box are at the box corners and where
   the box crosses a texel-centre line: evaluated at those 3 x 3 points the
   bounds are exact, not approximations (the box is < 1 texel wide, so it
   crosses at most one centre line per axis).  A box 1 texel or wider (|s|
   near 2^20 / W) gets the whole level's range.  Wrap modes (repeat,
   clamp_to_edge, mirrored_repeat) as section 8.14.2, through
   `softras.pipeline.texture.wrap`.
7. **Filter arithmetic**: weights in exact arithmetic, then the result is
   widened by ``LookupPrecision.color_threshold`` = 1.5/255 and clipped to
   the range of the texels read.  The figure: llvmpipe's 8.8 fixed-point
   path rounds three lerps (bilinear in x, in y, the mip blend) to a byte,
   each within 1/2 of a byte, and a lerp of bytes never leaves its two ends;
   a float implementation is within both.  GL itself states no filter
   precision; dEQP's ``LookupPrecision.colorThreshold`` for RGBA8 filtering
   is ``computeFixedPointThreshold(8 - 2 bits)`` = 1/64 (about 4/255) for the
   whole pixel including the framebuffer rounding -- the verifier's own
   tolerance (t = 2/255) plus this 1.5/255 stays below it.
8. **Texel data**: ``levels_lo`` / ``levels_hi`` (per level, per texel
   bounds) are the envelope of mip chains built in different ways (GL
   leaves the reduction filter of glGenerateMipmap open: :func:`generated_levels`,
   which :func:`render_bound` uses); minima read ``levels_lo``, maxima
   ``levels_hi`` (filters have non-negative weights, so they are monotone
   in each texel).

Anisotropic textures (max_anisotropy > 1; GL 4.6 section 8.14.1 / the
EXT_texture_filter_anisotropic text: up to N probes along the major axis at
lambda' = log2(Pmax / N), the scheme "implementation dependent"): the bound
is the range of the texels in the footprint at every level a lambda between
log2(Pmin / 2) and the isotropic upper end permits -- the footprint being
the parallelogram of the FULL derivative vectors around the sample plus one
texel for the reconstruction filter (llvmpipe's EWA reads an ellipse of
exactly that bounding box; the spec's probes stay inside half of it).
Pmax / N >= Pmin / 2 for every N the spec allows, and llvmpipe's level
trunc(log2 Pmin) is inside too.  **Loose**: a weighted mean of a region's
texels is only bounded by their range, so on a checkerboard seen at a
grazing angle the bound is often [dark, light]; it still catches colours no
texel has, levels far off, and wrong wrap.

Normal and bump maps go through lighting, which is not monotone in the
texel, so their "bounds" are variants instead (:func:`variant_derivatives`):
the map sampled at the lowest / highest permitted lambda, and at its middle
and first / last whole level (`MAP_LODS`), an envelope by variants, not a
strict bound.

Cost: linear filters are evaluated at 3 x 3 points (9 taps) per candidate
level, typically 1-3 levels; with the 5 derivative candidates a bounds render
(`softras.renderer.render_scene(texture_bounds=...)`) takes 3-6x a stage
render of the textured scenes (up to 10x for the 15-level strip).

Why one module of ~670 lines: the bounds are one model (dEQP's lookup verifier)
whose parts -- derivative candidates, one level's bounds, the whole lookup,
anisotropy and the bound renders -- use each other's intermediate ranges; split,
the invariants tying them together would live in no file.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numba
import numpy as np

from softras.pipeline import interpolate, texture
from softras.pipeline.cache_key import sources_key
from softras.pipeline.texture import MipTexture

__all__ = [
    "LodPrecision", "LookupPrecision", "DerivativeCandidates", "LOG2_PIECEWISE_LINEAR_ERROR",
    "float_error", "fragment_derivatives", "single_derivatives", "lambda_range", "level_extremes",
    "lookup_bounds", "variant_derivatives", "generated_levels", "render_bound", "SIDES", "MAP_LODS",
    "BOUND_RENDERS", "bound_render",
]

SIDES = ("lo", "hi")

# Where a normal or bump map's variant render takes its level of detail in
# the permitted range [lam_lo, lam_hi] (:func:`variant_derivatives`): its
# two ends, its middle, or the first / last whole level inside it (a pure
# level: the trilinear blend's kinks).
MAP_LODS = ("lowest", "highest", "middle", "first_level", "last_level")

# The values of ``render_scene(texture_bounds=...)`` (:func:`bound_render`).
BOUND_RENDERS = SIDES + tuple(f"{side}/{where}" for side in SIDES for where in MAP_LODS[2:])


def bound_render(value: str) -> tuple[str, str]:
    """(side, map_lod) of a ``texture_bounds`` render option: colour textures
    return their lower or upper bound (side "lo" / "hi", :func:`render_bound`),
    normal and bump maps are sampled at one of `MAP_LODS`
    (:func:`variant_derivatives`).  "lo" is ("lo", "lowest"), "hi" ("hi",
    "highest"); "lo/middle", "hi/first_level" and so on pair a side with
    another of the map's levels of detail (`BOUND_RENDERS`)."""
    if value not in BOUND_RENDERS:
        raise ValueError(f"texture_bounds must be one of {BOUND_RENDERS}, not {value!r}")
    side, _, where = value.partition("/")
    return side, where or ("lowest" if side == "lo" else "highest")

#: max over x in [1, 2) of log2(x) - (x - 1), at x = 1 / ln 2: 0.08607.
LOG2_PIECEWISE_LINEAR_ERROR = math.log2(1.0 / math.log(2.0)) - (1.0 / math.log(2.0) - 1.0)


@dataclass(frozen=True)
class LodPrecision:
    """How far an implementation's lambda may be from the spec's (module
    docstring, items 1-3).

    derivative_bits : relative precision of rho (dEQP ``derivateBits``).
    lod_bits : fractional bits of lambda, +-2^-lod_bits (dEQP ``lodBits``).
    log2_error : lambda may also be this much LOWER (a piecewise-linear log2).
    rho_max_factor : f <= rho_max_factor (m_u + m_v); 1 = the spec, sqrt(2) also admits the
        footprint's major axis (the Jacobian's largest singular value).
    """

    derivative_bits: int = 18
    lod_bits: int = 6
    log2_error: float = LOG2_PIECEWISE_LINEAR_ERROR
    rho_max_factor: float = 1.0


@dataclass(frozen=True)
class LookupPrecision:
    """Precision of the texel coordinates and of the filter (items 6-7).

    coord_bits : relative bits of (s, t) (dEQP ``coordBits``).
    uvw_bits : sub-texel bits of u = s W (dEQP ``uvwBits``): +-2^-uvw_bits texel.
    color_threshold : the filtered value's arithmetic error, in [0, 1] units,
        clipped to the range of the texels read.
    """

    coord_bits: int = 20
    uvw_bits: int = 7
    color_threshold: float = 1.5 / 255.0


LOD = LodPrecision()
LOOKUP = LookupPrecision()


def float_error(x: np.ndarray, bits: int) -> np.ndarray:
    """An error of ``bits`` accurate mantissa bits on x: 2^(floor(log2|x|) - bits),
    0 where x == 0 (dEQP ``computeFloatingPointError``, rounded up to the
    power of two).  Same shape as x, float64."""
    x = np.abs(np.asarray(x, np.float64))
    _, e = np.frexp(x)                                       # x = m 2^e, m in [0.5, 1)
    return np.where(x > 0, np.ldexp(1.0, e - 1 - bits), 0.0)


# ----------------------------------------------------------------------------- derivatives


@dataclass(frozen=True)
class DerivativeCandidates:
    """Every derivative pair an implementation may use, per fragment.

    ddx, ddy : (K, F, 2) d(s,t)/dx and d(s,t)/dy in (s, t) per window pixel.
    error : (K, F, 2) absolute uncertainty of each component (quad
        differences of rounded values; 0 for analytic ones).
    """

    ddx: np.ndarray
    ddy: np.ndarray
    error: np.ndarray

    def __len__(self) -> int:
        return self.ddx.shape[1]


def fragment_derivatives(vertices: np.ndarray, inv_w: np.ndarray, x: np.ndarray, y: np.ndarray,
                         centres: np.ndarray, values: np.ndarray,
                         lookup: LookupPrecision = LOOKUP) -> DerivativeCandidates:
    """The derivative pairs GL permits for a draw's fragments (module docstring, item 2).

    vertices : (F, 3, >=2) window coordinates of each fragment's triangle;
    inv_w : (F, 3); x, y : (F,) pixels; centres : (F, 2) pixel centres;
    values : (F, 3, 2) (s, t) at the triangle's corners.  The attribute is
    evaluated at the quad's four pixel centres from the triangle's planes
    (helper pixels included, `softras.pipeline.interpolate.perspective_at`), in
    float64.  Candidates (K = 5): (row 0, column 0) -- llvmpipe's coarse
    TR - TL, BL - TL --, (row 1, column 1), (row 0, column 1), (row 1,
    column 0) and the analytic derivative at the pixel centre.  The quad
    differences carry an error of 2 coordErr(max |value| over the quad,
    coord_bits).
    """
    qx = (x & ~1).astype(np.float64) + 0.5
    qy = (y & ~1).astype(np.float64) + 0.5

    def at(dx, dy):
        return interpolate.perspective_at(vertices, inv_w, values, np.stack([qx + dx, qy + dy], axis=1))

    p00, p10, p01, p11 = at(0, 0), at(1, 0), at(0, 1), at(1, 1)     # TL, TR, BL, BR (GL: y up)
    row0, row1 = p10 - p00, p11 - p01
    col0, col1 = p01 - p00, p11 - p10
    big = np.maximum(np.maximum(np.abs(p00), np.abs(p10)), np.maximum(np.abs(p01), np.abs(p11)))
    quad_error = 2.0 * float_error(big, lookup.coord_bits)
    exact_x, exact_y = interpolate.analytic_derivatives(vertices, inv_w, centres, values)
    ddx = np.stack([row0, row1, row0, row1, exact_x])
    ddy = np.stack([col0, col1, col1, col0, exact_y])
    error = np.stack([quad_error] * 4 + [np.zeros_like(quad_error)])
    return DerivativeCandidates(ddx, ddy, error)


def single_derivatives(ddx: np.ndarray, ddy: np.ndarray,
                       error: float | np.ndarray = 0.0) -> DerivativeCandidates:
    """One derivative pair per fragment as candidates (K = 1): ddx, ddy
    (F, 2); error a scalar or (F, 2)."""
    ddx = np.asarray(ddx, np.float64)
    ddy = np.asarray(ddy, np.float64)
    error = np.broadcast_to(np.asarray(error, np.float64), ddx.shape)
    return DerivativeCandidates(ddx[None], ddy[None], error[None].copy())


def _log2(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.nan_to_num(np.log2(x), nan=-np.inf)


def lambda_range(candidates: DerivativeCandidates, size: tuple[int, int],
                 lod: LodPrecision = LOD) -> tuple[np.ndarray, np.ndarray]:
    """(lam_lo, lam_hi), (F,) each: the levels of detail an isotropic lookup
    may use (module docstring, items 1-3), before the clamp to [0, q].

    size : (W, H) of level 0.  ``lam_lo = log2(min_k max(m_u, m_v)) - 2^-lod_bits
    - log2_error``, ``lam_hi = log2(max_k rho_max_factor (m_u + m_v)) +
    2^-lod_bits``, the m's taken down / up by the candidates' errors and rho by
    2^-derivative_bits.  -inf where every derivative is 0.
    """
    scale = np.array(size, np.float64)
    ax = np.abs(candidates.ddx) * scale                      # (K, F, 2): |du/dx|, |dv/dx|
    ay = np.abs(candidates.ddy) * scale                      # |du/dy|, |dv/dy|
    err = candidates.error * scale
    m_lo = np.maximum(np.maximum(ax - err, ay - err), 0.0)   # (K, F, 2): m_u, m_v, lowest
    m_hi = np.maximum(ax, ay) + err
    rel = 2.0 ** -lod.derivative_bits
    rho_lo = np.min(np.max(m_lo, axis=2), axis=0) * (1.0 - rel)
    rho_hi = np.max(np.sum(m_hi, axis=2), axis=0) * lod.rho_max_factor * (1.0 + rel)
    lod_err = 2.0 ** -lod.lod_bits
    return _log2(rho_lo) - lod_err - lod.log2_error, _log2(rho_hi) + lod_err


def _anisotropic_lambda_low(candidates: DerivativeCandidates, size, lod: LodPrecision) -> np.ndarray:
    """The lowest lambda an anisotropic lookup may use: log2(Pmin / 2) with
    Pmin the shorter derivative vector's length in level-0 texels (lowest over
    the candidates, less their errors), less the LOD errors.  Pmax / N >=
    Pmin / 2 for every probe count N <= ceil(Pmax / Pmin)."""
    scale = np.array(size, np.float64)
    err = np.hypot(*(candidates.error * scale).transpose(2, 0, 1))             # (K, F)
    px = np.maximum(np.hypot(*(candidates.ddx * scale).transpose(2, 0, 1)) - err, 0.0)
    py = np.maximum(np.hypot(*(candidates.ddy * scale).transpose(2, 0, 1)) - err, 0.0)
    pmin = np.min(np.minimum(px, py), axis=0) * (1.0 - 2.0 ** -lod.derivative_bits)
    return _log2(pmin / 2.0) - 2.0 ** -lod.lod_bits - lod.log2_error


# ----------------------------------------------------------------------------- one level


def _axis_box(c: np.ndarray, size: int, lookup: LookupPrecision):
    """The coordinate box along one axis in a level's texels: (lo, hi), (N,)
    each, ``c size -+ (coordErr(c) size + 2^-uvw_bits)``."""
    err = float_error(c, lookup.coord_bits) * size + 2.0 ** -lookup.uvw_bits
    return c * size - err, c * size + err


def _gather(flat: np.ndarray, width: int, j: np.ndarray, i: np.ndarray) -> np.ndarray:
    """Texels (N, 4) float64 of a level flattened to (H W, 4) at wrapped (j, i)."""
    return flat[j * width + i].astype(np.float64)


def level_extremes(level_lo: np.ndarray, level_hi: np.ndarray, s: np.ndarray, t: np.ndarray,
                   image_filter: str, wrap_s: str, wrap_t: str, lookup: LookupPrecision = LOOKUP):
    """Range of one level's filter over the coordinate box (module docstring, item 6).

    level_lo, level_hi : (H, W, 4) texel lower / upper bounds on the 0..255
    scale (the same array for exact texels); s, t : (N,).  image_filter
    "nearest" or "linear".  Returns (mn, mx, hull_mn, hull_mx), (N, 4)
    float64 each, 0..255: the filtered value's min (from level_lo) and max
    (from level_hi) over the box, and the range of the texels read.

    NEAREST reads the texels under the box's corners.  LINEAR: along each
    axis the box [lo, hi] is narrower than a texel, so its taps are the three
    texels from ``floor(lo - 1/2)`` (the third only where the box crosses a
    texel-centre line) and the bilinear value is evaluated at lo, hi and that
    crossing -- 3 x 3 points, the exact extremes of a function multilinear
    between centre lines.
    """
    h, w = level_lo.shape[:2]
    u_lo, u_hi = _axis_box(s, w, lookup)
    v_lo, v_hi = _axis_box(t, h, lookup)
    flat_lo = level_lo.reshape(-1, 4)
    flat_hi = flat_lo if level_hi is level_lo else level_hi.reshape(-1, 4)
    if image_filter == "nearest":
        cols = [texture.wrap(np.floor(u).astype(np.int64), w, wrap_s) for u in (u_lo, u_hi)]
        rows = [texture.wrap(np.floor(v).astype(np.int64), h, wrap_t) for v in (v_lo, v_hi)]
        mn = np.minimum.reduce([_gather(flat_lo, w, j, i) for j in rows for i in cols])
        mx = np.maximum.reduce([_gather(flat_hi, w, j, i) for j in rows for i in cols])
        hull_mn, hull_mx = mn, mx
    else:
        mn, mx, hull_mn, hull_mx = _linear_extremes(flat_lo, flat_hi, w, h, u_lo, u_hi, v_lo, v_hi,
                                                    wrap_s, wrap_t)
    wide = np.nonzero((u_hi - u_lo >= 1.0) | (v_hi - v_lo >= 1.0))[0]
    if len(wide):                                          # coordinates too coarse: the whole level
        mn[wide] = hull_mn[wide] = flat_lo.min(axis=0)
        mx[wide] = hull_mx[wide] = flat_hi.max(axis=0)
    return mn, mx, hull_mn, hull_mx


def _linear_axis(lo: np.ndarray, hi: np.ndarray, size: int, mode: str):
    """One axis of the bilinear box: the three tap indices (wrapped; the
    third repeats the second where the box crosses no centre line) and, for
    the points lo, the crossing (or lo again) and hi, each point's first tap
    (0 or 1 of the three) and weight of its second tap."""
    base = np.floor(lo - 0.5)
    top = np.floor(hi - 0.5)
    crosses = top > base
    taps = [texture.wrap(base.astype(np.int64) + k, size, mode) for k in range(3)]
    taps[2] = np.where(crosses, taps[2], taps[1])
    points = [lo, np.where(crosses, top + 0.5, lo), hi]
    first = [np.floor(p - 0.5) - base for p in points]                  # 0.0 or 1.0
    weight = [p - 0.5 - np.floor(p - 0.5) for p in points]
    return taps, list(zip(first, weight))


def _linear_extremes(flat_lo, flat_hi, w, h, u_lo, u_hi, v_lo, v_hi, wrap_s, wrap_t):
    """(mn, mx, hull_mn, hull_mx) of the bilinear filter over the box (see
    `level_extremes`), (N, 4) each."""
    cols, u_points = _linear_axis(u_lo, u_hi, w, wrap_s)
    rows, v_points = _linear_axis(v_lo, v_hi, h, wrap_t)

    def evaluate(flat):
        """The 3 x 3 taps and the bilinear value at the 3 x 3 points, lists of (N, 4)."""
        grid = [[_gather(flat, w, j, i) for i in cols] for j in rows]
        values = []
        for first_u, a in u_points:
            a, at0 = a[:, None], (first_u == 0)[:, None]
            # every tap row lerped along u at this point: taps (0, 1) or (1, 2)
            lerped = [np.where(at0, (1 - a) * r[0] + a * r[1], (1 - a) * r[1] + a * r[2]) for r in grid]
            for first_v, b in v_points:
                b, bt0 = b[:, None], (first_v == 0)[:, None]
                values.append(np.where(bt0, (1 - b) * lerped[0] + b * lerped[1],
                                       (1 - b) * lerped[1] + b * lerped[2]))
        return [texel for row in grid for texel in row], values

    taps_lo, values_lo = evaluate(flat_lo)
    taps_hi, values_hi = (taps_lo, values_lo) if flat_hi is flat_lo else evaluate(flat_hi)
    return (np.minimum.reduce(values_lo), np.maximum.reduce(values_hi),
            np.minimum.reduce(taps_lo), np.maximum.reduce(taps_hi))


# ----------------------------------------------------------------------------- the whole lookup


class _Range:
    """Running per-fragment (F, 4) min / max of the filtered value and of the texels read."""

    def __init__(self, n: int):
        self.lo = np.full((n, 4), np.inf)
        self.hi = np.full((n, 4), -np.inf)
        self.hull_lo = np.full((n, 4), np.inf)
        self.hull_hi = np.full((n, 4), -np.inf)

    def value(self, idx, lo, hi):
        self.lo[idx] = np.minimum(self.lo[idx], lo)
        self.hi[idx] = np.maximum(self.hi[idx], hi)

    def hull(self, idx, lo, hi):
        self.hull_lo[idx] = np.minimum(self.hull_lo[idx], lo)
        self.hull_hi[idx] = np.maximum(self.hull_hi[idx], hi)

    def add(self, idx, extremes):
        mn, mx, hull_mn, hull_mx = extremes
        self.value(idx, mn, mx)
        self.hull(idx, hull_mn, hull_mx)


def _levels(tex: MipTexture, levels_lo, levels_hi):
    levels_lo = tuple(levels_lo) if levels_lo is not None else tex.used_levels
    levels_hi = tuple(levels_hi) if levels_hi is not None else levels_lo
    if len(levels_lo) < len(tex.used_levels) or len(levels_hi) < len(tex.used_levels):
        raise ValueError(f"{tex.name}: levels_lo / levels_hi need {len(tex.used_levels)} levels")
    return levels_lo[:len(tex.used_levels)], levels_hi[:len(tex.used_levels)]


def lookup_bounds(tex: MipTexture, st: np.ndarray, candidates: DerivativeCandidates, *,
                  lod: LodPrecision = LOD, lookup: LookupPrecision = LOOKUP,
                  levels_lo=None, levels_hi=None) -> tuple[np.ndarray, np.ndarray]:
    """Per-fragment bounds of the value a conformant GL may return for texture(tex, st).

    tex : the texture and its sampler state; st : (F, 2) (s, t);
    candidates : the derivative pairs (:func:`fragment_derivatives`, or
    :func:`single_derivatives` for one given pair); lod, lookup : the
    precisions (module docstring); levels_lo, levels_hi : per-level texel
    bounds, tuples of (H_l, W_l, 4) arrays on the 0..255 scale (default both
    ``tex.levels``).

    Returns (lo, hi), (F, 4) float64 premultiplied in [0, 1], lo <= hi.
    Anisotropic textures (max_anisotropy > 1): see the module docstring.
    """
    n = len(st)
    if n == 0:
        return np.zeros((0, 4)), np.zeros((0, 4))
    levels_lo, levels_hi = _levels(tex, levels_lo, levels_hi)
    lam_lo, lam_hi = lambda_range(candidates, tex.size, lod)
    if tex.max_anisotropy > 1:
        lam_lo = np.minimum(lam_lo, _anisotropic_lambda_low(candidates, tex.size, lod))
        lo, hi = _anisotropic_bounds(tex, st, candidates, lam_lo, lam_hi, levels_lo, levels_hi, lookup)
        return lo / 255.0, hi / 255.0
    s, t = st[:, 0], st[:, 1]
    acc = _Range(n)

    def extremes(level: int, idx, image_filter):
        return level_extremes(levels_lo[level], levels_hi[level], s[idx], t[idx], image_filter,
                              tex.wrap_s, tex.wrap_t, lookup)

    magnified = np.nonzero(lam_lo <= 0)[0]
    if len(magnified):
        acc.add(magnified, extremes(0, magnified, tex.mag_filter))
    minified = np.nonzero(lam_hi > 0)[0]
    if len(minified):
        min_image = tex.min_filter.split("_")[0]
        last = len(levels_lo) - 1
        low, high = lam_lo[minified], lam_hi[minified]
        if not tex.mipmapped:
            acc.add(minified, extremes(0, minified, min_image))
        elif tex.min_filter.endswith("mipmap_nearest"):
            first = np.clip(np.ceil(low + 0.5) - 1, 0, last).astype(np.int64)
            final = np.clip(np.floor(high + 0.5), 0, last).astype(np.int64)
            for level in range(int(first.min()), int(final.max()) + 1):
                idx = minified[(first <= level) & (level <= final)]
                if len(idx):
                    acc.add(idx, extremes(level, idx, min_image))
        else:
            _mipmap_linear(acc, minified, np.clip(low, 0, last), np.clip(high, 0, last), last,
                           lambda level, idx: extremes(level, idx, min_image))
    threshold = 255.0 * lookup.color_threshold
    lo = np.maximum(acc.lo - threshold, acc.hull_lo)
    hi = np.minimum(acc.hi + threshold, acc.hull_hi)
    return np.clip(lo / 255.0, 0.0, 1.0), np.clip(hi / 255.0, 0.0, 1.0)


def _mipmap_linear(acc: _Range, idx: np.ndarray, a: np.ndarray, b: np.ndarray, last: int, extremes) -> None:
    """Trilinear range over lambda' in [a, b] (clamped to [0, last]) for the
    fragments idx: the blends at a and at b and the levels at the integers
    strictly between (module docstring, item 5); levels read one at a time."""
    la = np.minimum(np.floor(a), last).astype(np.int64)
    lb = np.minimum(np.floor(b), last).astype(np.int64)
    fa = np.where(la < last, a - la, 0.0)[:, None]
    fb = np.where(lb < last, b - lb, 0.0)[:, None]
    n = len(idx)
    end_a, end_b = np.zeros((2, n, 4)), np.zeros((2, n, 4))     # [lo, hi] of the blends at a and b
    inner_lo, inner_hi = np.full((n, 4), np.inf), np.full((n, 4), -np.inf)
    top = lb + (fb[:, 0] > 0)
    for level in range(int(la.min()), min(int(top.max()), last) + 1):
        sel = np.nonzero((la <= level) & (level <= top))[0]
        if not len(sel):
            continue
        mn, mx, hull_mn, hull_mx = extremes(level, idx[sel])
        acc.hull(idx[sel], hull_mn, hull_mx)
        for end, lev, f in ((end_a, la, fa), (end_b, lb, fb)):
            weight = np.where((lev[sel] == level)[:, None], 1.0 - f[sel],
                              np.where((lev[sel] + 1 == level)[:, None], f[sel], 0.0))
            end[0, sel] += weight * mn
            end[1, sel] += weight * mx
        inside = ((a[sel] < level) & (level < b[sel]))[:, None]
        inner_lo[sel] = np.where(inside, np.minimum(inner_lo[sel], mn), inner_lo[sel])
        inner_hi[sel] = np.where(inside, np.maximum(inner_hi[sel], mx), inner_hi[sel])
    acc.value(idx, np.minimum(np.minimum(end_a[0], end_b[0]), inner_lo),
              np.maximum(np.maximum(end_a[1], end_b[1]), inner_hi))


# ----------------------------------------------------------------------------- anisotropic


def _make_rect_extremes(key: str):
    """`_rect_extremes`, cached under ``key`` (`softras.pipeline.cache_key`): it
    inlines `softras.pipeline.texture.wrap_index`."""

    @numba.njit(cache=True)
    def _rect_extremes(level_lo, level_hi, i0, i1, j0, j1, wrap_s, wrap_t, out_lo, out_hi):
        """Per fragment k, min of level_lo and max of level_hi over the texels
        (i, j), i0[k] <= i <= i1[k], j0[k] <= j <= j1[k], wrapped (WRAP_CODES).
        level_lo, level_hi : (H, W, 4) float64; writes out_lo, out_hi (N, 4)."""
        cache_key = key                     # noqa: F841  (in the cache key only)
        h, w = level_lo.shape[0], level_lo.shape[1]
        for k in range(len(i0)):
            a0, a1, b0, b1 = i0[k], i1[k], j0[k], j1[k]
            if wrap_s == 1:
                a0, a1 = min(max(a0, 0), w - 1), min(max(a1, 0), w - 1)
            elif a1 - a0 >= (w if wrap_s == 0 else 2 * w):
                a1 = a0 + (w if wrap_s == 0 else 2 * w) - 1
            if wrap_t == 1:
                b0, b1 = min(max(b0, 0), h - 1), min(max(b1, 0), h - 1)
            elif b1 - b0 >= (h if wrap_t == 0 else 2 * h):
                b1 = b0 + (h if wrap_t == 0 else 2 * h) - 1
            for c in range(4):
                out_lo[k, c] = np.inf
                out_hi[k, c] = -np.inf
            for j in range(b0, b1 + 1):
                jj = texture.wrap_index(j, h, wrap_t)
                for i in range(a0, a1 + 1):
                    ii = texture.wrap_index(i, w, wrap_s)
                    for c in range(4):
                        if level_lo[jj, ii, c] < out_lo[k, c]:
                            out_lo[k, c] = level_lo[jj, ii, c]
                        if level_hi[jj, ii, c] > out_hi[k, c]:
                            out_hi[k, c] = level_hi[jj, ii, c]

    return _rect_extremes


_rect_extremes = _make_rect_extremes(sources_key([texture.__file__]))


def _anisotropic_bounds(tex, st, candidates, lam_lo, lam_hi, levels_lo, levels_hi, lookup):
    """Range of the texels in the footprint at every permitted level (module
    docstring): per level l the texels whose linear taps or EWA ellipse can
    reach ``(s W_l, t H_l) +- (|du/dx| + |du/dy|, |dv/dx| + |dv/dy|) + 1``
    (largest candidate, level-l texels).  Returns (lo, hi) on 0..255."""
    n = len(st)
    last = len(levels_lo) - 1
    w0, h0 = tex.size
    ax = np.abs(candidates.ddx) + candidates.error
    ay = np.abs(candidates.ddy) + candidates.error
    extent = np.max(ax + ay, axis=0)                          # (F, 2) in (s, t) per pixel
    first = np.clip(np.floor(lam_lo), 0, last).astype(np.int64)
    final = np.clip(np.ceil(lam_hi), 0, last).astype(np.int64)
    out_lo, out_hi = np.full((n, 4), np.inf), np.full((n, 4), -np.inf)
    codes = texture.WRAP_CODES
    for level in range(int(first.min()), int(final.max()) + 1):
        idx = np.nonzero((first <= level) & (level <= final))[0]
        if not len(idx):
            continue
        lo_l = np.ascontiguousarray(levels_lo[level], np.float64)
        hi_l = (lo_l if levels_hi[level] is levels_lo[level]
                else np.ascontiguousarray(levels_hi[level], np.float64))
        h, w = lo_l.shape[:2]
        bounds = []
        for axis, size in ((0, w), (1, h)):
            c = st[idx, axis]
            centre = c * size - 0.5
            reach = extent[idx, axis] * size + 1.0 + float_error(c, lookup.coord_bits) * size \
                + 2.0 ** -lookup.uvw_bits
            bounds += [np.floor(centre - reach).astype(np.int64),
                       np.ceil(centre + reach).astype(np.int64) + 1]
        part_lo, part_hi = np.empty((len(idx), 4)), np.empty((len(idx), 4))
        _rect_extremes(lo_l, hi_l, bounds[0], bounds[1], bounds[2], bounds[3],
                       codes[tex.wrap_s], codes[tex.wrap_t], part_lo, part_hi)
        out_lo[idx] = np.minimum(out_lo[idx], part_lo)
        out_hi[idx] = np.maximum(out_hi[idx], part_hi)
    return out_lo, out_hi


# ----------------------------------------------------------------------------- renders


def variant_derivatives(tex: MipTexture, candidates: DerivativeCandidates, where: str,
                        precision: str = "exact", lod: LodPrecision = LOD):
    """Derivatives that make `softras.pipeline.texture.sample` use one
    permitted lambda, for normal and bump maps: ``where`` (`MAP_LODS`) the
    lowest or highest lambda of :func:`lambda_range`, its middle, or the
    first or last whole level inside it (``middle`` where there is none; the
    range's -inf end counts as level 0, as magnification reads it).  Their
    lighting is not monotone in the texel, nor in lambda, so the renders at
    these lambdas are an envelope by variants, not a bound: with the ends
    alone an NVIDIA H200's bump-mapped sphere was 22/255 outside where its
    lambda was inside (docs/verification.md, "On a GPU").

    Returns (tex', ddx, ddy): tex' the texture with anisotropy off (the
    variants are isotropic lookups), ddx (F, 2) = (rho / W, 0) and ddy = 0
    with rho chosen so that a lookup in ``precision`` computes that lambda:
    exact: rho = 2^lambda; gl: rho^2 = the inverse of llvmpipe's
    piecewise-linear log2 at 2 lambda (`softras.pipeline.texture.fast_log2`), so the
    variant also has llvmpipe's fixed-point filter arithmetic.
    lambda = -inf gives zero derivatives (magnification).
    """
    if where not in MAP_LODS:
        raise ValueError(f"a map's level of detail must be one of {MAP_LODS}, not {where!r}")
    lam_lo, lam_hi = lambda_range(candidates, tex.size, lod)
    if tex.max_anisotropy > 1:
        lam_lo = np.minimum(lam_lo, _anisotropic_lambda_low(candidates, tex.size, lod))
        tex = dataclasses.replace(tex, max_anisotropy=1.0)
    if where == "lowest":
        lam = lam_lo
    elif where == "highest":
        lam = lam_hi
    else:
        with np.errstate(invalid="ignore"):
            middle = np.where(np.isfinite(lam_lo), 0.5 * (lam_lo + lam_hi), lam_hi - 0.5)
            if where == "middle":
                lam = middle
            elif where == "first_level":
                first = np.maximum(np.ceil(lam_lo), 0.0)
                lam = np.where(first <= lam_hi, first, middle)
            else:
                last = np.floor(lam_hi)
                lam = np.where((last >= lam_lo) & (last >= 0.0), last, middle)
    lam = np.minimum(lam, 64.0)
    if precision == "gl":
        doubled = 2.0 * lam
        whole = np.floor(np.where(np.isfinite(doubled), doubled, 0.0))
        inverse = np.ldexp(1.0 + (doubled - whole), whole.astype(np.int64))    # fast_log2(inverse) = doubled
        rho = np.sqrt(np.where(np.isfinite(doubled), inverse, 0.0))
    else:
        rho = np.exp2(lam)
    ddx = np.zeros((len(lam), 2))
    ddx[:, 0] = rho / tex.size[0]
    return tex, ddx, np.zeros_like(ddx)


_generated: dict[int, tuple] = {}


def _footprints(n: int, m: int, grow: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The source texels under each texel of a level reduced from n to m
    texels along one axis, the footprint grown by ``grow`` texels on each
    side and clipped to the level: (first, last) inclusive, (m,) int. Texel
    i of the smaller level covers [i n / m, (i + 1) n / m) of the larger
    one: texels 2i and 2i + 1 when n is even, up to three when n is odd."""
    i = np.arange(m)
    first, last = (i * n) // m, -((-(i + 1) * n) // m) - 1
    return np.maximum(first - grow, 0), np.minimum(last + grow, n - 1)


def _footprint_range(lo: np.ndarray, hi: np.ndarray, size: tuple[int, int],
                     grow: int) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of any filter with non-negative weights that reduces a level
    with per-texel bounds lo, hi (H, W, 4) to the next level's size (w, h),
    reading only texels within ``grow`` of each footprint (:func:`_footprints`):
    the least lo and greatest hi over each grown footprint (a min or max over
    a rectangle is one over columns, then rows)."""
    def reduce_axis(values, axis, first, last, combine):
        result = np.take(values, first, axis=axis)
        for offset in range(1, int((last - first).max(initial=0)) + 1):
            result = combine(result, np.take(values, np.minimum(first + offset, last), axis=axis))
        return result

    w, h = size
    x0, x1 = _footprints(lo.shape[1], w, grow)
    y0, y1 = _footprints(lo.shape[0], h, grow)
    return tuple(reduce_axis(reduce_axis(values, 1, x0, x1, combine), 0, y0, y1, combine)
                 for values, combine in ((lo, np.minimum), (hi, np.maximum)))


#: How far (texels) beyond its footprint a generated NPOT level's filter may
#: read: 1, measured on an NVIDIA H200 (docs/verification.md), whose 7 x 6 ->
#: 3 x 3 reduction weighs rows 1 and 2 for the texel whose footprint is rows 2-3.
NPOT_FILTER_REACH = 1


def generated_levels(tex: MipTexture) -> tuple[tuple, tuple]:
    """Per-texel bounds of the mip chain a GL generates from ``tex``'s level 0.

    GL 4.6 section 8.14.4: the levels are "computed by repeated, filtered
    reduction of the level base array. [...] No particular filter algorithm
    is required, though a box filter is recommended." Where a level halves
    exactly (even sizes), the bound is the rounded 2x2 box chain and
    llvmpipe's linear-blit chain (`softras.scene.texels.mip_chain`, both
    reduced from level 0), widened by k/255: one rounding step per reduction
    (softpipe's float-weighted blit stays within 1/255 of llvmpipe's per
    step, measured in docs/textures_and_lighting.md). Once a reduction has
    an odd size, implementations filter differently (llvmpipe's blit samples
    between texel centres; an NVIDIA H200 weighs texels by the area of each
    footprint they cover on most sizes, and reads one texel beyond the
    footprint on some, differing from llvmpipe by up to 218/255): from that
    level on, each texel may also take any value a filter with non-negative
    weights gives over its footprint grown by :data:`NPOT_FILTER_REACH`
    texels in the level above, bounded from that level's own bounds
    (:func:`_footprint_range`; a rounded weighted mean of integers in
    [a, b] stays in [a, b]). A claim beyond the letter of 8.14.4, which
    bounds nothing; where it is loose (noise textures, deep levels) a
    wrong level or filter on an NPOT texture cannot be told from GL's
    freedom (docs/verification.md).

    Returns (levels_lo, levels_hi): tuples of (H_l, W_l, 4) float64 on the
    0..255 scale, level 0 exact. Cached per MipTexture.
    """
    from softras.scene.texels import mip_chain

    cached = _generated.get(id(tex))
    if cached is not None and cached[0] is tex:
        return cached[1]
    levels = tex.levels
    box = mip_chain(levels[0], method="box")
    lows, highs = [], []
    odd = False
    for k, (blit, boxed) in enumerate(zip(levels, box)):
        blit, boxed = blit.astype(np.float64), boxed.astype(np.float64)
        lo = np.clip(np.minimum(blit, boxed) - k, 0.0, 255.0)
        hi = np.clip(np.maximum(blit, boxed) + k, 0.0, 255.0)
        if k > 0:
            above = lows[-1].shape
            odd = odd or (above[0] % 2 == 1 and above[0] > 1) or (above[1] % 2 == 1 and above[1] > 1)
            if odd:
                f_lo, f_hi = _footprint_range(lows[-1], highs[-1], (blit.shape[1], blit.shape[0]),
                                               NPOT_FILTER_REACH)
                lo, hi = np.minimum(lo, f_lo), np.maximum(hi, f_hi)
        lows.append(lo)
        highs.append(hi)
    result = (tuple(lows), tuple(highs))
    _generated[id(tex)] = (tex, result)
    return result


def render_bound(tex: MipTexture, st: np.ndarray, candidates: DerivativeCandidates, side: str,
                 **precision) -> np.ndarray:
    """The pipeline's texel for ``render_scene(texture_bounds=side)``: the
    lower ("lo") or upper ("hi") bound of :func:`lookup_bounds`, (F, 4), with
    a mipmapped texture's levels bounded as GL may generate them
    (:func:`generated_levels`)."""
    if side not in SIDES:
        raise ValueError(f"a texture bound's side must be one of {SIDES}, not {side!r}")
    if len(tex.used_levels) > 1 and "levels_lo" not in precision:
        levels_lo, levels_hi = generated_levels(tex)
        precision = precision | {"levels_lo": levels_lo, "levels_hi": levels_hi}
    lo, hi = lookup_bounds(tex, st, candidates, **precision)
    return lo if side == "lo" else hi
