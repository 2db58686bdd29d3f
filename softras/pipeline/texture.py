"""Textures: texels, mip chains and the full texture sampling operation.

The lecture's sampling operation, one readable function per step::

    uv ──► derivatives ──► level of detail ──► mip level(s) ──► texel addresses
       ──► filter weights ──► texel fetch and blend ──► premultiplied RGBA

Texel data
----------
The premultiplied mip chain of a scene texture is scene data
(`softras.scene.texels`, read through ``softras.scene.Texture.levels``; glref uploads
level 0 and GL generates the rest, which `softras.scene.texels.mip_chain` reproduces
for llvmpipe byte for byte).  :func:`prepare` pairs it with the sampler state in a
:class:`MipTexture`.

Sampling (:func:`sample`)
-------------------------
Coordinates: texel (i, j) of a level of size W x H has its centre at
``((i + 0.5) / W, (j + 0.5) / H)``; ``u = s W`` and ``v = t H`` are texel-space
coordinates.

``precision="exact"`` follows the GL 4.5 specification (section 8.14) in
float64: analytic derivatives per sample, ``rho = max(|d(u,v)/dx|,
|d(u,v)/dy|)``, ``lambda = log2 rho``, magnification when ``lambda <= 0``
(c = 0), mipmap_nearest level ``ceil(lambda + 1/2) - 1``, mipmap_linear
levels ``floor(lambda)`` and ``floor(lambda) + 1`` blended by the fraction,
bilinear weights in float.

``precision="gl"`` reproduces what Mesa llvmpipe (gallivm, default
``GALLIVM_PERF``) computes, found in its source (lp_bld_sample.c,
lp_bld_sample_aos.c) and checked against it by experiment:

- derivatives per 2x2 quad (quads at even window x, y): ``ddx = TR - TL``,
  ``ddy = BL - TL`` of the interpolated (s, t), helper pixels included; one
  LOD per quad;
- ``rho^2 = max(ddx_s^2 W^2 + ddx_t^2 H^2, ddy_s^2 W^2 + ddy_t^2 H^2)`` in
  float32 (no square root: ``no_rho_approx`` is the default);
- mipmap_nearest: level ``(exponent(rho^2) + 1) >> 1`` = round(log2 rho),
  halves rounding up; mipmap_linear: ``lambda = 0.5 * fast_log2(rho^2)`` where
  ``fast_log2`` is llvmpipe's *piecewise-linear* log2 (exact at powers of two,
  up to 0.086 low between them), then floor and fraction;
- magnification when ``rho^2 <= 1``;
- for RGBA8 textures with repeat / clamp_to_edge wrapping llvmpipe filters in
  8.8 fixed point ("AoS sampling"): texel coordinates rounded to 1/256 texel,
  bilinear and mip blends as ``a + ((w (b - a) + 128) >> 8)`` on bytes (each
  lerp rounded to a byte), the mip weight truncated to ``floor(frac * 256)``;
  mirrored_repeat goes through the float ("SoA") path instead.

Why one module of ~640 lines: a texture lookup is one stage with one chain of
steps (derivatives, level of detail, levels, addresses, weights, fetch), and each
step's gl and exact forms sit side by side so their difference is visible; the
sections below follow the chain.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numba
import numpy as np

from softras.pipeline import libm
from softras.scene import MIPMAP_FILTERS, Texture
from softras.scene.texels import bilinear, linear_float_addresses, wrap  # noqa: F401  (wrap: texture.wrap)


@dataclass(frozen=True, eq=False)
class MipTexture:
    """A texture ready to sample: premultiplied RGBA8 levels and the sampler state.

    levels : (H_l, W_l, 4) uint8 premultiplied, row 0 = v 0; the full chain
        down to 1x1 (only level 0 is used unless the min filter is a mipmap one).
    """

    name: str
    levels: tuple
    wrap_s: str
    wrap_t: str
    min_filter: str
    mag_filter: str
    max_anisotropy: float

    @property
    def mipmapped(self) -> bool:
        return self.min_filter in MIPMAP_FILTERS

    @property
    def used_levels(self) -> tuple:
        """The levels a sampler can reach (those GL builds for glref)."""
        return self.levels if self.mipmapped else self.levels[:1]

    @property
    def size(self) -> tuple[int, int]:
        h, w = self.levels[0].shape[:2]
        return w, h


_cache: "weakref.WeakKeyDictionary[Texture, MipTexture]" = weakref.WeakKeyDictionary()


def prepare(texture: Texture) -> MipTexture:
    """A scene texture ready to sample: its levels (``Texture.levels``, the
    premultiplied mip chain) and sampler state (cached per Texture object)."""
    ready = _cache.get(texture)
    if ready is None:
        ready = MipTexture(texture.name, texture.levels, texture.wrap_s, texture.wrap_t,
                           texture.min_filter, texture.mag_filter, texture.max_anisotropy)
        _cache[texture] = ready
    return ready


# ----------------------------------------------------------------------------- wrap


# Wrap modes as integers for the compiled kernels.
WRAP_CODES = {"repeat": 0, "clamp_to_edge": 1, "mirrored_repeat": 2}


@numba.njit(cache=True, inline="always")
def wrap_index(i, size, mode):
    """`wrap` of one integer index in a compiled kernel (mode: WRAP_CODES).
    A power-of-two period takes a mask instead of a division (the same value
    for every i, negative ones included)."""
    if mode == 1:
        return min(max(i, 0), size - 1)
    period = size if mode == 0 else 2 * size
    m = i & (period - 1) if (period & (period - 1)) == 0 else i % period
    if mode == 0:
        return m
    return m if m < size else 2 * size - 1 - m


# ----------------------------------------------------------------------------- derivatives and LOD


def texel_derivatives(ddx: np.ndarray, ddy: np.ndarray, size: tuple[int, int], gl: bool):
    """(N, 2) derivatives of (s, t) -> (N, 2) derivatives of (u, v) = (s W, t H), in texels."""
    scale = np.array(size, np.float64)
    if gl:
        scale32 = scale.astype(np.float32)
        return (ddx.astype(np.float32) * scale32, ddy.astype(np.float32) * scale32)
    return ddx * scale, ddy * scale


def rho_squared(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """rho^2 = max(|du|^2, |dv|^2) for texel-space derivative vectors du = d(u,v)/dx,
    dv = d(u,v)/dy, (N, 2) each; computed in the arrays' dtype."""
    x = du[:, 0] * du[:, 0] + du[:, 1] * du[:, 1]
    y = dv[:, 0] * dv[:, 0] + dv[:, 1] * dv[:, 1]
    return np.maximum(x, y)


def fast_log2(x: np.ndarray) -> np.ndarray:
    """llvmpipe's lp_build_fast_log2: ``exponent + mantissa - 1`` for
    x = mantissa * 2^exponent, mantissa in [1, 2) — piecewise linear, exact at
    powers of two.  float32 in, float32 out."""
    m, e = np.frexp(x.astype(np.float32))         # x = m 2^e, m in [0.5, 1)
    return ((e - 1).astype(np.float32) + (np.float32(2) * m - np.float32(1))).astype(np.float32)


@dataclass(frozen=True)
class LevelChoice:
    """Per fragment: which level(s) to sample and how.

    magnified : (N,) bool, use the mag filter on level 0.
    level0, level1 : (N,) int64 levels (equal when there is nothing to blend).
    frac : (N,) float64 blend weight of level1 in [0, 1).
    """

    magnified: np.ndarray
    level0: np.ndarray
    level1: np.ndarray
    frac: np.ndarray


def choose_levels(rho2: np.ndarray, min_filter: str, n_levels: int, gl: bool) -> LevelChoice:
    """Level of detail -> mip level(s), from rho^2 (N,) in texels^2.

    gl: llvmpipe's arithmetic (see the module docstring); exact: GL 4.5
    equations 8.x with lambda = log2(rho) = 0.5 log2(rho^2), c = 0.
    """
    last = n_levels - 1
    n = len(rho2)
    zeros = np.zeros(n, np.int64)
    magnified = ~(rho2 > 1)                       # lambda <= 0 (NaN: magnified)
    if min_filter not in MIPMAP_FILTERS:
        return LevelChoice(magnified, zeros, zeros, np.zeros(n))
    mip_nearest = min_filter.endswith("mipmap_nearest")
    if gl:
        r = rho2.astype(np.float32)
        if mip_nearest:
            _, e = np.frexp(r)                    # exponent(r) + 1 == e
            level = np.right_shift(e.astype(np.int64), 1)
            level = np.where(r > 0, level, 0)
            level = np.clip(level, 0, last)
            return LevelChoice(magnified, level, level, np.zeros(n))
        lod = (np.float32(0.5) * fast_log2(np.maximum(r, np.float32(np.finfo(np.float32).tiny))))
        ipart = np.floor(lod)
        frac = (lod - ipart).astype(np.float64)
        ipart = ipart.astype(np.int64)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            lod = 0.5 * libm.log2(rho2)
        lod = np.where(np.isnan(lod), -np.inf, lod)     # infinities kept: lambda = +inf is the last level
        if mip_nearest:
            # GL: d = ceil(lambda + 1/2) - 1 for lambda > 1/2, else 0 (halves round down).
            level = np.where(lod > 0.5, np.ceil(lod + 0.5) - 1, 0)
            level = np.clip(np.nan_to_num(level, posinf=last), 0, last).astype(np.int64)
            return LevelChoice(magnified, level, level, np.zeros(n))
        finite = np.isfinite(lod)
        ipart = np.where(finite, np.floor(np.where(finite, lod, 0)), np.where(lod > 0, last, -1))
        frac = np.where(finite, lod - np.floor(np.where(finite, lod, 0)), 0.0)
        ipart = ipart.astype(np.int64)
    below = ipart < 0
    above = ipart >= last
    level0 = np.clip(ipart, 0, last)
    level1 = np.clip(ipart + 1, 0, last)
    frac = np.where(below | above, 0.0, frac)
    return LevelChoice(magnified, level0, level1, frac)


# ----------------------------------------------------------------------------- filters on one level


def nearest_addresses(s: np.ndarray, size: int, mode: str, gl: bool) -> np.ndarray:
    """Nearest filter: texel index ``wrap(floor(s * size))`` per coordinate, (N,) int64."""
    if gl:
        u = s.astype(np.float32) * np.float32(size)
        return wrap(np.floor(u).astype(np.int64), size, mode)
    return wrap(np.floor(s * size).astype(np.int64), size, mode)


def linear_addresses(s: np.ndarray, size: int, mode: str, fixed8: bool):
    """Linear filter along one axis: (i0, i1, weight of i1).

    Float (GL spec): ``u = s size - 1/2``, i0 = floor(u), weight = frac(u).
    fixed8 (llvmpipe AoS): ``round(s * size * 256) - 128`` in 8.8 fixed
    point, i0 = that >> 8, weight = (that & 255) as an integer 0..255.
    """
    if not fixed8:
        return linear_float_addresses(s, size, mode)
    s32 = s.astype(np.float32)
    pot = size & (size - 1) == 0
    if mode == "repeat" and not pot:
        f = s32 - np.floor(s32)
        fixed = np.rint((f * np.float32(size)).astype(np.float32) * np.float32(256)).astype(np.int64) - 128
        weight = fixed & 255
        i0 = fixed >> 8
        i0 = np.where(i0 < 0, size - 1, i0)
        i0 = np.minimum(i0, size - 1)
        i1 = np.where(i0 != size - 1, i0 + 1, 0)
        return i0, i1, weight
    fixed = np.rint((s32 * np.float32(size * 256)).astype(np.float32)).astype(np.int64) - 128
    weight = fixed & 255
    i0 = fixed >> 8
    return wrap(i0, size, mode), wrap(i0 + 1, size, mode), weight


def lerp8(weight: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """llvmpipe's 8-bit lerp: ``a + ((w (b - a) + 128) >> 8)``, w in 0..255,
    a and b bytes (as int64).  (pmulhrsw of w and (b - a) << 7.)"""
    return a + ((weight * (b - a) + 128) >> 8)


def filter_level(level: np.ndarray, s: np.ndarray, t: np.ndarray, image_filter: str,
                 wrap_s: str, wrap_t: str, gl: bool, fixed8: bool) -> np.ndarray:
    """Filter one mip level at (s, t): (N,) each -> (N, 4) texel values on the
    0..255 scale (integers in fixed8 mode, floats otherwise)."""
    h, w = level.shape[:2]
    if image_filter == "nearest":
        i = nearest_addresses(s, w, wrap_s, gl)
        j = nearest_addresses(t, h, wrap_t, gl)
        return level[j, i].astype(np.int64 if fixed8 else np.float64)
    if not fixed8:
        return bilinear(level, s, t, wrap_s, wrap_t)
    i0, i1, a = linear_addresses(s, w, wrap_s, fixed8)
    j0, j1, b = linear_addresses(t, h, wrap_t, fixed8)
    t00, t10 = level[j0, i0].astype(np.int64), level[j0, i1].astype(np.int64)
    t01, t11 = level[j1, i0].astype(np.int64), level[j1, i1].astype(np.int64)
    a, b = a[:, None], b[:, None]
    return lerp8(b, lerp8(a, t00, t10), lerp8(a, t01, t11))


def uses_fixed_point(texture: MipTexture, gl: bool) -> bool:
    """Whether llvmpipe filters this texture in 8.8 fixed point (its AoS path):
    RGBA8 with repeat / clamp_to_edge on both axes and no anisotropy."""
    simple = ("repeat", "clamp_to_edge")
    return (gl and texture.wrap_s in simple and texture.wrap_t in simple
            and effective_anisotropy(texture.max_anisotropy, gl) <= 1)


# ----------------------------------------------------------------------------- the whole operation


def sample(texture: MipTexture, st: np.ndarray, ddx: np.ndarray, ddy: np.ndarray,
           precision: str = "gl", fixed_point: bool = True) -> np.ndarray:
    """The full texture sampling operation.

    st : (N, 2) texture coordinates (s, t) at the sample.
    ddx, ddy : (N, 2) their screen-space derivatives d(s,t)/dx and d(s,t)/dy
        (per quad in gl precision, analytic in exact).
    fixed_point : gl precision only: filter in 8.8 fixed point where llvmpipe
        does by default (see :func:`uses_fixed_point`); False reproduces
        llvmpipe run with ``GALLIVM_PERF=no_aos_sampling`` (float weights).
    Returns (N, 4) float64 premultiplied RGBA in [0, 1].

    With ``max_anisotropy > 1`` the anisotropic filter takes over
    (:func:`sample_anisotropic`).
    """
    gl = precision == "gl"
    n = len(st)
    if n == 0:
        return np.zeros((0, 4))
    if effective_anisotropy(texture.max_anisotropy, gl) > 1:
        return sample_anisotropic(texture, st, ddx, ddy, precision)
    du, dv = texel_derivatives(ddx, ddy, texture.size, gl)
    rho2 = rho_squared(du, dv)
    fixed8 = fixed_point and uses_fixed_point(texture, gl)
    return filter_at_lod(texture, st, rho2, gl, fixed8)


def filter_at_lod(texture: MipTexture, st: np.ndarray, rho2: np.ndarray, gl: bool,
                  fixed8: bool) -> np.ndarray:
    """Filter at a given footprint: level choice from rho^2 (N,) in level-0
    texels^2, then the min / mag filter on the chosen level(s) and the mip
    blend.  st : (N, 2).  Returns (N, 4) float64 premultiplied RGBA in [0, 1]."""
    n = len(st)
    levels = texture.used_levels
    choice = choose_levels(rho2, texture.min_filter, len(levels), gl)
    min_image = texture.min_filter.split("_")[0]          # "nearest" or "linear"
    s, t = st[:, 0], st[:, 1]

    def filtered(level_index: np.ndarray) -> np.ndarray:
        out = np.zeros((n, 4), np.int64 if fixed8 else np.float64)
        filters = np.where(choice.magnified, texture.mag_filter, min_image)
        for lvl in np.unique(level_index):
            for image_filter in ("nearest", "linear"):
                idx = np.nonzero((level_index == lvl) & (filters == image_filter))[0]
                if len(idx):
                    out[idx] = filter_level(levels[lvl], s[idx], t[idx], image_filter,
                                            texture.wrap_s, texture.wrap_t, gl, fixed8)
        return out

    level0 = np.where(choice.magnified, 0, choice.level0)
    c0 = filtered(level0)
    blend = ~choice.magnified & (choice.level1 != choice.level0) & (choice.frac > 0)
    if np.any(blend):
        level1 = np.where(blend, choice.level1, level0)
        c1 = filtered(level1)
        if fixed8:
            w8 = np.floor(choice.frac * 256).astype(np.int64)[:, None]
            c0 = np.where(blend[:, None], lerp8(w8, c0, c1), c0)
        else:
            f = np.where(blend, choice.frac, 0.0)[:, None]
            c0 = c0 + f * (c1 - c0)
    return c0.astype(np.float64) / 255.0


# ----------------------------------------------------------------------------- anisotropic filtering
#
# EXT_texture_filter_anisotropic (core in GL 4.6).  The spec's footprint: the
# pixel's texel-space derivative vectors Px = |d(u,v)/dx|, Py = |d(u,v)/dy|,
# Pmax / Pmin their longer / shorter length,
#
#     N = min(ceil(Pmax / Pmin), maxAniso)      probes along the longer axis,
#     lambda' = log2(Pmax / N)                  the level of detail of each probe,
#
# and the result the mean of N ordinary (e.g. trilinear) lookups at lambda',
# spread over the pixel along its longer axis at offsets i / (N + 1) - 1/2
# pixel, i = 1 .. N.  That is precision="exact".
#
# Mesa 22.3 llvmpipe (gallivm lp_bld_sample.c: lp_build_pmin,
# lp_build_lod_selector; lp_bld_sample_soa.c: lp_build_sample_aniso) does
# something else, reproduced in precision="gl":
#
# - Mesa's state tracker hands the driver ``(unsigned) max_anisotropy`` (1.0
#   becomes 0), so 1.5 is 1: no anisotropic filtering at all; the sampler is
#   "aniso" when that integer is > 1.
# - LOD: ``pmin2 = min(|Px|^2, |Py|^2)`` per 2x2 quad in float32, meant to be
#   clamped to ``pmax2 / maxAniso^2`` where ``pmax2 > pmin2 maxAniso^2``; the
#   22.3 code compares ``pmin2 > pmin2 * maxAniso^2`` instead, which never
#   holds, so the clamp never fires and **the result does not depend on
#   maxAniso at all** (2, 3, 8 and 16 render the same bytes).
#   ``lod = 0.5 fast_log2(pmin2)`` and ONE level, ``clamp(trunc(lod), 0,
#   last)``: no mip blend whatever the mip filter, no min/mag switch.
# - Filter: Heckbert's EWA on that level (not GL's probes): the ellipse
#   ``A U^2 + B U V + C V^2 <= F`` with A = vx^2 + vy^2 + 1,
#   B = -2 (ux vx + uy vy), C = ux^2 + uy^2 + 1, F = A C - B^2 / 4 from the
#   quad's derivatives in that level's texels (the +1 adds a one-texel
#   reconstruction filter), scaled so that F = 1023; every texel centre of
#   the ellipse's bounding box is fetched (nearest) and weighted by
#   ``table[trunc(q)]``, ``table[i] = exp(-2 i / 1023)``, q evaluated
#   incrementally in float32; texels with q > 1023 get no weight.  The sum is
#   divided by the sum of weights (bilinear on the level if that is 0).


def effective_anisotropy(max_anisotropy: float, gl: bool) -> float:
    """The anisotropy limit a sampler works with.

    gl: llvmpipe's, the integer part (Mesa's state tracker truncates); exact:
    the scene's value.
    """
    return float(int(max_anisotropy)) if gl else float(max_anisotropy)


def anisotropic_probes(px: np.ndarray, py: np.ndarray, max_anisotropy: float):
    """EXT_texture_filter_anisotropic's probe count and level of detail.

    px, py : (N,) lengths |d(u,v)/dx| and |d(u,v)/dy| in level-0 texels.
    Returns (count (N,) int64 >= 1, rho2 (N,) float64) with
    ``count = min(ceil(Pmax / Pmin), floor(max_anisotropy))`` (a whole number
    of probes; ``Pmin = 0`` counts as infinitely anisotropic) and
    ``rho2 = (Pmax / count)^2``, i.e. ``lambda' = log2(Pmax / count)``.
    """
    pmax = np.maximum(px, py)
    pmin = np.minimum(px, py)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(pmin > 0, pmax / np.where(pmin > 0, pmin, 1.0), np.inf)
    ratio = np.where(pmax > 0, ratio, 1.0)
    limit = max(1, math.floor(max_anisotropy))
    count = np.minimum(np.ceil(np.minimum(ratio, limit)), limit).astype(np.int64)
    count = np.maximum(count, 1)
    return count, (pmax / count) ** 2


def sample_anisotropic(texture: MipTexture, st: np.ndarray, ddx: np.ndarray, ddy: np.ndarray,
                       precision: str = "gl") -> np.ndarray:
    """Anisotropic filtering; arguments and result as :func:`sample`.

    exact: the EXT spec's N probes at lambda' (the probes' own min / mag
    filter and mip blend as the texture says), float64; the probe positions
    step along the longer derivative vector (``st + (i / (N + 1) - 1/2) ddx``
    when ``Px > Py``, else ``ddy``), the spec's u(x - 1/2 + i/(N+1), y) to
    first order.  gl: :func:`sample_anisotropic_llvmpipe`.
    """
    if precision == "gl":
        return sample_anisotropic_llvmpipe(texture, st, ddx, ddy)[0]
    du, dv = texel_derivatives(ddx, ddy, texture.size, gl=False)
    px, py = np.hypot(du[:, 0], du[:, 1]), np.hypot(dv[:, 0], dv[:, 1])
    count, rho2 = anisotropic_probes(px, py, texture.max_anisotropy)
    axis = np.where((px > py)[:, None], ddx, ddy)                 # (N, 2) in (s, t) per pixel
    total = np.zeros((len(st), 4))
    for i in range(1, int(count.max()) + 1):
        active = np.nonzero(count >= i)[0]
        offset = i / (count[active] + 1.0) - 0.5
        probe = st[active] + offset[:, None] * axis[active]
        total[active] += filter_at_lod(texture, probe, rho2[active], gl=False, fixed8=False)
    return total / count[:, None]


def llvmpipe_ewa_table() -> np.ndarray:
    """llvmpipe's EWA weight table: (1024,) float32, ``exp(-2 i / 1023)``."""
    r2 = np.arange(1024, dtype=np.float32) / np.float32(1023)
    return np.exp(np.float32(-2) * r2).astype(np.float32)


def llvmpipe_aniso_levels(du: np.ndarray, dv: np.ndarray, n_levels: int) -> np.ndarray:
    """llvmpipe's level for anisotropic sampling, (N,) int64.

    du, dv : (N, 2) float32 texel-space derivative vectors d(u,v)/dx and
    d(u,v)/dy of level 0 (per quad).  ``pmin2 = min(|du|^2, |dv|^2)`` (the
    maxAniso clamp never fires in 22.3, see above), ``lod = 0.5
    fast_log2(pmin2)``, level ``clamp(trunc(lod), 0, n_levels - 1)``.
    """
    px2 = du[:, 0] * du[:, 0] + du[:, 1] * du[:, 1]
    py2 = dv[:, 0] * dv[:, 0] + dv[:, 1] * dv[:, 1]
    pmin2 = np.minimum(px2, py2).astype(np.float32)
    lod = np.float32(0.5) * fast_log2(pmin2)
    lod = np.nan_to_num(lod, nan=0.0, posinf=n_levels, neginf=0.0)
    return np.clip(np.trunc(lod), 0, n_levels - 1).astype(np.int64)


@dataclass(frozen=True)
class FlatLevels:
    """Mip levels packed into one array for the compiled kernels.

    texels : (sum of W_l H_l, 4) uint8, level l's texel (i, j) at
        ``offsets[l] + j * widths[l] + i``.
    offsets, widths, heights : (L,) int64.
    """

    texels: np.ndarray
    offsets: np.ndarray
    widths: np.ndarray
    heights: np.ndarray


def flatten_levels(levels) -> FlatLevels:
    """Pack (H_l, W_l, 4) uint8 levels into a :class:`FlatLevels`."""
    sizes = np.array([lvl.shape[0] * lvl.shape[1] for lvl in levels], np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    texels = np.concatenate([lvl.reshape(-1, 4) for lvl in levels])
    return FlatLevels(np.ascontiguousarray(texels), offsets,
                      np.array([lvl.shape[1] for lvl in levels], np.int64),
                      np.array([lvl.shape[0] for lvl in levels], np.int64))


@numba.njit(cache=True)
def _nearest_index_f32(c, size, mode):
    """llvmpipe's nearest texel index of a normalized float32 coordinate c."""
    if mode == 0:                                   # repeat
        if size & (size - 1) == 0:
            return np.int64(np.floor(c * np.float32(size))) & (size - 1)
        f = c - np.floor(c)
        i = np.int64(f * np.float32(size))
        return min(max(i, 0), size - 1)
    if mode == 1:                                   # clamp_to_edge
        i = np.int64(np.floor(c * np.float32(size)))
        return min(max(i, 0), size - 1)
    # mirrored_repeat, lp_build_coord_mirror: |2 (c/2 - round(c/2))| scaled and
    # truncated (so -1/size maps to texel 1, where the spec's mirror gives 0).
    half = c * np.float32(0.5)
    fraction = half - np.rint(half)
    m = np.abs(fraction + fraction)
    return min(np.int64(m * np.float32(size)), size - 1)


@numba.njit(cache=True)
def _llvmpipe_ewa_kernel(texels, offsets, widths, heights, level, s, t, dsdx, dsdy, dtdx, dtdy,
                         width0, height0, wrap_s, wrap_t, table, out, reads):
    """lp_build_sample_aniso, one sample at a time, in float32 (`ewa_texel`).

    level, s, t, dsdx, dsdy, dtdx, dtdy : (N,) — the level, the normalized
    coordinates and their per-quad derivatives (float32).  Writes out (N, 4)
    float32 filtered RGBA in [0, 1] (NaN where no texel got weight) and
    reads (N,) the number of texels fetched with a non-zero weight.
    """
    flat = texels.reshape(-1)
    for k in range(len(s)):
        lvl = level[k]
        r, g, b, a, n_reads = ewa_texel(flat, offsets[lvl], widths[lvl], heights[lvl], lvl, s[k], t[k], dsdx[k],
                                        dsdy[k], dtdx[k], dtdy[k], width0, height0, wrap_s, wrap_t, table)
        out[k, 0] = r
        out[k, 1] = g
        out[k, 2] = b
        out[k, 3] = a
        reads[k] = n_reads


@numba.njit(cache=True, inline="always")
def ewa_texel(texels, base, wl, hl, lvl, s, t, dsdx, dsdy, dtdx, dtdy, width0, height0, wrap_s, wrap_t, table):
    """lp_build_sample_aniso of one sample in float32 (see the notes above):
    level lvl, wl x hl texels from texel ``base`` of the levels' bytes
    ``texels`` (4 a texel); s, t and the quad's derivatives dsdx, dsdy, dtdx,
    dtdy float32; level 0 width0 x height0; wraps as WRAP_CODES; table the
    EWA weights (`llvmpipe_ewa_table`).  Returns (r, g, b, a, reads): the
    float32 filtered RGBA in [0, 1] (NaN where no texel got weight) and the
    number of texels fetched with a non-zero weight.  The compiled path's
    lanes call it too (`softras.kernels.texture._aniso_lane`)."""
    f0 = np.float32(0.0)
    f1 = np.float32(1.0)
    f2 = np.float32(2.0)
    f4 = np.float32(4.0)
    half = np.float32(0.5)
    lut_max = np.float32(1023.0)
    inv255 = np.float32(1.0 / 255.0)
    fw0 = np.float32(width0)
    fh0 = np.float32(height0)
    scaling = f1 / np.float32(1 << lvl)
    ux = dsdx * fw0 * scaling                    # level-l texels per pixel
    uy = dsdy * fw0 * scaling
    vx = dtdx * fh0 * scaling
    vy = dtdy * fh0 * scaling
    a = vx * vx + vy * vy + f1
    b = (ux * vx + uy * vy) * np.float32(-2.0)
    c = ux * ux + uy * uy + f1
    f = a * c - b * b / f4
    d = (f0 - b * b) + a * c * f4
    box_u = f2 / d * np.sqrt(d * c * f)
    box_v = f2 / d * np.sqrt(a * d * f)
    scale = lut_max / f
    a = a * scale
    b = b * scale
    c = c * scale
    ddq = a * f2
    tex_u = s * (fw0 * scaling) - half           # level-l texel space, centres at integers
    tex_v = t * (fh0 * scaling) - half
    u0 = np.int64(np.floor(tex_u - box_u))
    u1 = np.int64(np.ceil(tex_u + box_u))
    v0 = np.int64(np.floor(tex_v - box_v))
    v1 = np.int64(np.ceil(tex_v + box_v))
    big_u = np.float32(u0) - tex_u
    dq_base = (big_u * f2 + f1) * a
    q_base = big_u * big_u * a
    acc0 = f0
    acc1 = f0
    acc2 = f0
    acc3 = f0
    den = f0
    n_reads = 0
    fwl = np.float32(wl)
    fhl = np.float32(hl)
    for v in range(v0, v1 + 1):
        big_v = np.float32(v) - tex_v
        dq = big_v * b + dq_base
        q = (c * big_v + b * big_u) * big_v + q_base
        cv = np.float32(v) / fhl
        j = _nearest_index_f32(cv, hl, wrap_t)
        for u in range(u0, u1 + 1):
            if q < np.float32(1024.0):               # trunc(q) <= 1023
                qi = np.int64(q) if q > f0 else 0
                w = table[qi & 1023]
                if w != f0:
                    i = _nearest_index_f32(np.float32(u) / fwl, wl, wrap_s)
                    at = (base + j * wl + i) * 4
                    acc0 += np.float32(texels[at]) * inv255 * w
                    acc1 += np.float32(texels[at + 1]) * inv255 * w
                    acc2 += np.float32(texels[at + 2]) * inv255 * w
                    acc3 += np.float32(texels[at + 3]) * inv255 * w
                    den += w
                    n_reads += 1
            q = q + dq
            dq = dq + ddq
    if den == f0:
        nan = np.float32(np.nan)
        return nan, nan, nan, nan, n_reads
    return acc0 / den, acc1 / den, acc2 / den, acc3 / den, n_reads


_flat_cache: "weakref.WeakKeyDictionary[MipTexture, FlatLevels]" = weakref.WeakKeyDictionary()


def flat_levels(texture: MipTexture) -> FlatLevels:
    """The texture's reachable levels packed for the kernels (cached)."""
    flat = _flat_cache.get(texture)
    if flat is None:
        flat = flatten_levels(texture.used_levels)
        _flat_cache[texture] = flat
    return flat


def sample_anisotropic_llvmpipe(texture: MipTexture, st: np.ndarray, ddx: np.ndarray,
                                ddy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What Mesa 22.3 llvmpipe computes for an "aniso" sampler (see the notes
    above): returns ((N, 4) float64 RGBA in [0, 1], (N,) int64 texel reads)."""
    n = len(st)
    du, dv = texel_derivatives(ddx, ddy, texture.size, gl=True)
    level = llvmpipe_aniso_levels(du, dv, len(texture.used_levels))
    st32 = st.astype(np.float32)
    d32x, d32y = ddx.astype(np.float32), ddy.astype(np.float32)
    flat = flat_levels(texture)
    out = np.empty((n, 4), np.float32)
    reads = np.zeros(n, np.int64)
    width0, height0 = texture.size
    _llvmpipe_ewa_kernel(flat.texels, flat.offsets, flat.widths, flat.heights, level,
                         st32[:, 0].copy(), st32[:, 1].copy(), d32x[:, 0].copy(), d32y[:, 0].copy(),
                         d32x[:, 1].copy(), d32y[:, 1].copy(), width0, height0,
                         WRAP_CODES[texture.wrap_s], WRAP_CODES[texture.wrap_t],
                         llvmpipe_ewa_table(), out, reads)
    result = out.astype(np.float64)
    empty = np.nonzero(np.isnan(result[:, 0]))[0]
    for lvl in np.unique(level[empty]):
        idx = empty[level[empty] == lvl]
        result[idx] = filter_level(texture.used_levels[lvl], st[idx, 0], st[idx, 1], "linear",
                                   texture.wrap_s, texture.wrap_t, gl=True, fixed8=False) / 255.0
        reads[idx] = 4
    return result, reads
