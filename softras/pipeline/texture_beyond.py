"""Texture filters beyond GL: ripmaps and EWA, and the cost of every filter.

OpenGL has no counterpart for these, so they are judged against a
supersampled ground truth (`softras.verification.ground_truth`) instead of glref.
They are selected per render with the option ``texture_filter`` (softras
only; glref ignores it)::

    softras.render(scene, texture_filter="ewa")                 # every texture
    softras.render(scene, texture_filter={"checker": "ripmap"})  # one texture
    softras render SCENE -o OUT.png --texture-filter ripmap

The chosen filter replaces the texture's min filter (and the anisotropic
filter); wrap modes stay.  Coordinates are as in `softras.pipeline.texture`: (s, t)
normalized, ``u = s W``, ``v = t H`` in texels of level 0, texel (i, j) of a
level of size W_l x H_l has its centre at ``((i + 0.5) / W_l, (j + 0.5) / H_l)``.

Ripmap (the lecture's anisotropic scheme)
    A 2-D array of pre-filtered images, level (i, j) of size (W >> i) x
    (H >> j), the axes halved separately (:func:`ripmap_levels`).  The
    footprint's extent along u, ``max(|du/dx|, |du/dy|)``, picks i; its
    extent along v picks j, so an axis-aligned long thin footprint gets a
    long thin pre-filtered texel instead of trilinear's square one.  Bilinear
    in each level; with a ``*_mipmap_linear`` min filter the four levels
    around (lambda_u, lambda_v) are blended bilinearly (16 reads), with
    ``*_mipmap_nearest`` the nearest one is used (4 reads).  It costs 4x the
    texels of level 0 (a mip chain: 4/3).

EWA (Heckbert 1989, elliptical weighted average)
    The pixel's footprint is the ellipse ``p^T S^-1 p <= 1`` with
    ``S = J J^T``, J = [d(u,v)/dx  d(u,v)/dy] the Jacobian in texels.  Every
    texel centre inside it is weighted by a Gaussian ``exp(-EWA_ALPHA Q)``,
    ``Q = p^T S_l^-1 p``, where ``S_l`` is S in the level's texels plus the
    identity (a one-texel reconstruction filter); the result is the weighted
    mean.  The level is chosen so that the minor semi-axis spans about
    ``EWA_MINOR_TEXELS`` texels (lambda = log2(b / 2)), and the two levels
    around lambda are blended like trilinear.  Eccentricity is capped at
    ``EWA_MAX_ECCENTRICITY`` (the minor axis grown) to bound the cost, and
    so is the size: a footprint wider than the last level takes is shrunk
    to a minor semi-axis of ``2 EWA_MINOR_TEXELS`` of its texels.
"""

from __future__ import annotations

import time
import weakref

import numba
import numpy as np

from softras.scene import texels
from softras.pipeline import libm, texture
from softras.pipeline.cache_key import sources_key
from softras.pipeline.texture import MipTexture

FILTERS = ("ripmap", "ewa", "level0")
"""Names `texture_filter` accepts.  "level0" is bilinear on level 0 whatever
the footprint: the ground truth's lookup at each of its sub-samples."""

EWA_MINOR_TEXELS = 2.0
EWA_MAX_ECCENTRICITY = 16.0
EWA_ALPHA = 4.0
"""Gaussian falloff ``exp(-EWA_ALPHA Q)``, Q = 1 on the footprint ellipse.  Heckbert
used 2; 4 (of 2, 4, 6) came closest to the box-filtered ground truth on
scenes/texture_anisotropic_floor.json (docs/textures_and_lighting.md)."""


# ----------------------------------------------------------------------------- the render option


def check_texture_filter(option, texture_names) -> None:
    """Validate a ``texture_filter`` option: None, a name in FILTERS, or a
    dict {texture name: name}; raises ValueError naming the bad part."""
    if option is None:
        return
    if isinstance(option, str):
        if option not in FILTERS:
            raise ValueError(f"texture_filter: unknown filter {option!r} (choose from {', '.join(FILTERS)})")
        return
    if isinstance(option, dict):
        for name, value in option.items():
            if name not in texture_names:
                raise ValueError(f"texture_filter[{name!r}]: the scene has no texture {name!r}")
            if value is not None and value not in FILTERS:
                raise ValueError(f"texture_filter[{name!r}]: unknown filter {value!r} "
                                 f"(choose from {', '.join(FILTERS)})")
        return
    raise ValueError(f"texture_filter: expected None, a filter name or a dict, not {type(option).__name__}")


def filter_for(option, texture_name: str) -> str | None:
    """The override for one texture under a ``texture_filter`` option, or None."""
    if isinstance(option, dict):
        return option.get(texture_name)
    return option


def sample_texture(tex: MipTexture, st: np.ndarray, ddx: np.ndarray, ddy: np.ndarray,
                   precision: str = "gl", fixed_point: bool = True, texture_filter=None) -> np.ndarray:
    """`softras.pipeline.texture.sample`, or the filter ``texture_filter`` names for
    this texture.  Arguments and result as `softras.pipeline.texture.sample`."""
    name = filter_for(texture_filter, tex.name)
    if name is None:
        return texture.sample(tex, st, ddx, ddy, precision, fixed_point)
    return sample_beyond(name, tex, st, ddx, ddy)[0]


def sample_beyond(name: str, tex: MipTexture, st: np.ndarray, ddx: np.ndarray,
                  ddy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample with one of FILTERS (float64 whatever the precision).
    Returns ((N, 4) premultiplied RGBA in [0, 1], (N,) int64 texel reads)."""
    if len(st) == 0:
        return np.zeros((0, 4)), np.zeros(0, np.int64)
    if name == "ripmap":
        return sample_ripmap(tex, st, ddx, ddy)
    if name == "ewa":
        return sample_ewa(tex, st, ddx, ddy)
    if name == "level0":
        out = texture.filter_level(tex.levels[0], st[:, 0], st[:, 1], "linear", tex.wrap_s,
                                   tex.wrap_t, gl=False, fixed8=False)
        return out / 255.0, np.full(len(st), 4, np.int64)
    raise ValueError(f"texture_filter: unknown filter {name!r}")


# ----------------------------------------------------------------------------- ripmap


def downsample_axis(level: np.ndarray, axis: int) -> np.ndarray:
    """Halve one axis of a (H, W, 4) uint8 level with a 2-texel box, rounded
    (halves up); size ``floor(n / 2)``, an odd last texel skipped, a size of 1
    kept.  axis 1 = u (width), axis 0 = v (height)."""
    n = level.shape[axis]
    if n == 1:
        return level
    half = n // 2
    x = level.astype(np.int32)
    a = np.take(x, np.arange(0, 2 * half, 2), axis=axis)
    b = np.take(x, np.arange(1, 2 * half, 2), axis=axis)
    return ((a + b + 1) // 2).astype(np.uint8)


def ripmap_levels(level0: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    """The ripmap of a (H, W, 4) uint8 level 0: ``rip[j][i]`` has size
    ``(max(1, H >> j), max(1, W >> i))``: i halvings along u, j along v, for
    i < floor(log2 W) + 1 and j < floor(log2 H) + 1."""
    rows = []
    column = level0
    while True:
        row = [column]
        while row[-1].shape[1] > 1:
            row.append(downsample_axis(row[-1], 1))
        rows.append(tuple(row))
        if column.shape[0] == 1:
            break
        column = downsample_axis(column, 0)
    return tuple(rows)


_ripmap_cache: "weakref.WeakKeyDictionary[MipTexture, tuple]" = weakref.WeakKeyDictionary()


def ripmap(tex: MipTexture) -> tuple[tuple[np.ndarray, ...], ...]:
    """:func:`ripmap_levels` of a texture's level 0 (cached)."""
    rip = _ripmap_cache.get(tex)
    if rip is None:
        rip = ripmap_levels(tex.levels[0])
        _ripmap_cache[tex] = rip
    return rip


def ripmap_lods(du: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lambda_u, lambda_v), (N,) each: log2 of the footprint's extent along
    u and along v in level-0 texels, from du = d(u,v)/dx, dv = d(u,v)/dy (N, 2)."""
    extent_u = np.maximum(np.abs(du[:, 0]), np.abs(dv[:, 0]))
    extent_v = np.maximum(np.abs(du[:, 1]), np.abs(dv[:, 1]))
    return libm.log2(extent_u), libm.log2(extent_v)     # (C's log2: the compiled ripmap's, bit for bit)


def sample_ripmap(tex: MipTexture, st: np.ndarray, ddx: np.ndarray,
                  ddy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ripmap filtering (see the module docstring).  st, ddx, ddy : (N, 2)
    in (s, t) units.  Returns ((N, 4) RGBA in [0, 1], (N,) texel reads).

    Magnified (both lambdas <= 0): the mag filter on level 0.
    """
    rip = ripmap(tex)
    n_u, n_v = len(rip[0]), len(rip)
    du, dv = texture.texel_derivatives(ddx, ddy, tex.size, gl=False)
    lam_u, lam_v = ripmap_lods(du, dv)
    magnified = ~((lam_u > 0) | (lam_v > 0))
    nearest_level = tex.min_filter.endswith("mipmap_nearest")
    lam_u = np.nan_to_num(np.maximum(lam_u, 0.0), posinf=n_u - 1)
    lam_v = np.nan_to_num(np.maximum(lam_v, 0.0), posinf=n_v - 1)
    if nearest_level:                    # GL's mipmap_nearest rounding, per axis
        corners = [(np.clip(np.ceil(lam_u - 0.5), 0, n_u - 1).astype(np.int64),
                    np.clip(np.ceil(lam_v - 0.5), 0, n_v - 1).astype(np.int64), np.ones(len(st)))]
    else:
        i0 = np.clip(np.floor(lam_u), 0, n_u - 1).astype(np.int64)
        j0 = np.clip(np.floor(lam_v), 0, n_v - 1).astype(np.int64)
        fu = np.where(i0 < n_u - 1, lam_u - i0, 0.0)
        fv = np.where(j0 < n_v - 1, lam_v - j0, 0.0)
        i1, j1 = np.minimum(i0 + 1, n_u - 1), np.minimum(j0 + 1, n_v - 1)
        corners = [(i0, j0, (1 - fu) * (1 - fv)), (i1, j0, fu * (1 - fv)),
                   (i0, j1, (1 - fu) * fv), (i1, j1, fu * fv)]
    out = np.zeros((len(st), 4))
    reads = np.zeros(len(st), np.int64)
    for i, j, weight in corners:
        use = (weight > 0) & ~magnified
        for (a, b) in set(zip(i[use].tolist(), j[use].tolist())):
            idx = np.nonzero(use & (i == a) & (j == b))[0]
            out[idx] += weight[idx, None] * texture.filter_level(
                rip[b][a], st[idx, 0], st[idx, 1], "linear", tex.wrap_s, tex.wrap_t, gl=False, fixed8=False)
            reads[idx] += 4
    mag = np.nonzero(magnified)[0]
    if len(mag):
        out[mag] = texture.filter_level(tex.levels[0], st[mag, 0], st[mag, 1], tex.mag_filter,
                                        tex.wrap_s, tex.wrap_t, gl=False, fixed8=False)
        reads[mag] = 4 if tex.mag_filter == "linear" else 1
    return out / 255.0, reads


def ripmap_texel_count(rip) -> int:
    """Texels stored in a ripmap (all levels)."""
    return sum(level.shape[0] * level.shape[1] for row in rip for level in row)


# ----------------------------------------------------------------------------- EWA


def footprint_covariance(du: np.ndarray, dv: np.ndarray, max_eccentricity: float = EWA_MAX_ECCENTRICITY):
    """The pixel footprint's ellipse in level-0 texels.

    du, dv : (N, 2) d(u,v)/dx and d(u,v)/dy.  Returns (S, minor) with S
    (N, 2, 2) = J J^T (the ellipse ``p^T S^-1 p <= 1``), its minor semi-axis
    grown where needed so that major / minor <= max_eccentricity, and minor
    (N,) that semi-axis length.
    """
    s00 = du[:, 0] ** 2 + dv[:, 0] ** 2
    s01 = du[:, 0] * du[:, 1] + dv[:, 0] * dv[:, 1]
    s11 = du[:, 1] ** 2 + dv[:, 1] ** 2
    mean = 0.5 * (s00 + s11)
    spread = np.sqrt(0.25 * (s00 - s11) ** 2 + s01 ** 2)
    major2, minor2 = mean + spread, np.maximum(mean - spread, 0.0)
    wanted = major2 / max_eccentricity ** 2
    grow = np.where(minor2 < wanted, wanted - minor2, 0.0)
    # S + grow e e^T with e the minor eigenvector; e e^T = (major2 I - S) / (major2 - minor2).
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(spread > 0, grow / (2 * spread), 0.0)
    s00 = s00 + k * (major2 - s00)
    s01 = s01 - k * s01
    s11 = s11 + k * (major2 - s11)
    S = np.stack([np.stack([s00, s01], -1), np.stack([s01, s11], -1)], -2)
    return S, np.sqrt(np.maximum(minor2, wanted))


@numba.njit(cache=True, error_model="numpy", inline="always")
def ewa_ellipse(texels, base, wl, hl, s, t, s00, s01, s11, wrap_s, wrap_t, alpha):
    """Gaussian-weighted mean of one level's texels inside one ellipse.

    texels : the levels' RGBA8 bytes (N,) uint8, this level's first at byte
    ``base``, wl x hl texels; (s, t) the sample, (s00, s01, s11) the ellipse
    S_l in this level's texels (reconstruction filter included); wrap_s,
    wrap_t : WRAP_CODES.  Returns (r, g, b, a, reads): the mean on the 0..255
    scale and the texels with weight > 0, or NaN and 0 where no texel gets
    weight or the ellipse or (s, t) is not finite (infinite or NaN
    derivatives: `ewa_level` filters those bilinearly).  Shared by the stage
    (`_ewa_kernel`) and the compiled paths
    (`softras.kernels.texture_beyond._ewa_level`).
    """
    if not (np.isfinite(s00) and np.isfinite(s01) and np.isfinite(s11) and np.isfinite(s) and np.isfinite(t)):
        return np.nan, np.nan, np.nan, np.nan, 0
    det = s00 * s11 - s01 * s01
    m00, m01, m11 = s11 / det, -s01 / det, s00 / det              # S_l^-1
    cu = s * wl - 0.5                                             # centre, level texels
    cv = t * hl - 0.5
    hu, hv = np.sqrt(s00), np.sqrt(s11)                           # bounding box half sizes
    r = g = b = a = den = 0.0
    reads = 0
    i_first, i_last = int(np.floor(cu - hu)), int(np.ceil(cu + hu))
    for j in range(int(np.floor(cv - hv)), int(np.ceil(cv + hv)) + 1):
        dv = j - cv
        jj = texture.wrap_index(j, hl, wrap_t)
        # The row's span of the ellipse (q(du) = 1 solved for du), one texel
        # wider each side, within the bounding box: every texel with q < 1 is
        # visited, in the same order, and the span skips the box's corners
        # (most of the box when the ellipse is long and turned).
        mid = -m01 * dv / m00
        half = np.sqrt(max(mid * mid - (m11 * dv * dv - 1.0) / m00, 0.0))
        for i in range(max(i_first, int(np.floor(cu + mid - half)) - 1),
                       min(i_last, int(np.ceil(cu + mid + half)) + 1) + 1):
            du = i - cu
            q = m00 * du * du + 2.0 * m01 * du * dv + m11 * dv * dv
            if q < 1.0:
                ii = texture.wrap_index(i, wl, wrap_s)
                w = np.exp(-alpha * q)
                at = base + (jj * wl + ii) * 4
                r += w * texels[at]
                g += w * texels[at + 1]
                b += w * texels[at + 2]
                a += w * texels[at + 3]
                den += w
                reads += 1
    if not den > 0.0:
        return np.nan, np.nan, np.nan, np.nan, 0
    return r / den, g / den, b / den, a / den, reads


def _make_ewa_kernel(key: str):
    """`_ewa_kernel`, cached under ``key`` (`softras.pipeline.cache_key`): it
    inlines `softras.pipeline.texture.wrap_index` (and this module's
    `ewa_ellipse`, which numba's own check of this file covers)."""

    @numba.njit(cache=True, error_model="numpy")
    def _ewa_kernel(texels, offsets, widths, heights, level, s, t, s00, s01, s11, wrap_s, wrap_t,
                    alpha, out, reads):
        """`ewa_ellipse` of each sample on its level.

        texels : the levels' bytes (N,) uint8, offsets (L,) each level's first
        texel; level, s, t : (N,); s00, s01, s11 : (N,) the ellipse S_l in
        that level's texels (reconstruction filter included).  Writes out
        (N, 4) float64 in [0, 255] and reads (N,) texels with weight > 0; NaN
        and 0 where `ewa_ellipse` takes no texel.
        """
        cache_key = key                     # noqa: F841  (in the cache key only)
        for k in range(len(s)):
            lvl = level[k]
            out[k, 0], out[k, 1], out[k, 2], out[k, 3], reads[k] = ewa_ellipse(
                texels, 4 * offsets[lvl], widths[lvl], heights[lvl], s[k], t[k], s00[k], s01[k], s11[k],
                wrap_s, wrap_t, alpha)

    return _ewa_kernel


_ewa_kernel = _make_ewa_kernel(sources_key([texture.__file__]))


def ewa_level(tex: MipTexture, flat, S: np.ndarray, st: np.ndarray, level: np.ndarray):
    """EWA on one level per sample: (N, 4) in [0, 255] and (N,) reads.  A
    sample whose ellipse takes no texel (infinite or NaN derivatives) gets
    the bilinear filter of its level at (s, t) instead, as llvmpipe's
    anisotropic filter falls back to bilinear
    (`softras.pipeline.texture.sample_anisotropic_llvmpipe`)."""
    w0, h0 = tex.size
    su = flat.widths[level] / w0                  # level texels per level-0 texel
    sv = flat.heights[level] / h0
    out = np.empty((len(st), 4))
    reads = np.zeros(len(st), np.int64)
    codes = texture.WRAP_CODES
    _ewa_kernel(flat.texels.reshape(-1), flat.offsets, flat.widths, flat.heights, level,
                np.ascontiguousarray(st[:, 0]), np.ascontiguousarray(st[:, 1]),
                S[:, 0, 0] * su * su + 1.0, S[:, 0, 1] * su * sv, S[:, 1, 1] * sv * sv + 1.0,
                codes[tex.wrap_s], codes[tex.wrap_t], EWA_ALPHA, out, reads)
    empty = np.flatnonzero(np.isnan(out[:, 0]))
    for lvl in np.unique(level[empty]):
        at = empty[level[empty] == lvl]
        out[at] = texture.bilinear(tex.levels[lvl], np.nan_to_num(st[at, 0]), np.nan_to_num(st[at, 1]),
                                   tex.wrap_s, tex.wrap_t)
    return out, reads


def sample_ewa(tex: MipTexture, st: np.ndarray, ddx: np.ndarray,
               ddy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """EWA filtering over the mip chain (see the module docstring).
    Returns ((N, 4) RGBA in [0, 1], (N,) texel reads)."""
    du, dv = texture.texel_derivatives(ddx, ddy, tex.size, gl=False)
    last = len(tex.levels) - 1
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):    # (non-finite: ewa_level)
        S, minor = footprint_covariance(du, dv)
        lam = np.clip(np.nan_to_num(libm.log2(minor / EWA_MINOR_TEXELS), nan=0.0, neginf=0.0), 0, last)
        # A footprint wider than the last level takes (a minor semi-axis of
        # over 2 EWA_MINOR_TEXELS of its texels, where lambda was clipped) is
        # shrunk to that, its shape kept: the cost stays bounded (a
        # near-singular view gave ellipses of 1e9 texels) and on a 1 x 1 last
        # level the value is its texel either way.
        widest = 2 * EWA_MINOR_TEXELS * float(1 << last)
        S = S * np.where(minor > widest, (widest / minor) ** 2, 1.0)[:, None, None]
    flat = texture.flatten_levels(tex.levels)
    level0 = np.floor(lam).astype(np.int64)
    frac = lam - level0
    out, reads = ewa_level(tex, flat, S, st, level0)
    blend = np.nonzero((frac > 0) & (level0 < last))[0]
    if len(blend):
        upper, more = ewa_level(tex, flat, S[blend], st[blend], level0[blend] + 1)
        out[blend] += frac[blend, None] * (upper - out[blend])
        reads[blend] += more
    return out / 255.0, reads


# ----------------------------------------------------------------------------- cost


def synthetic_footprints(n: int, size: int = 256, seed: int = 0):
    """n seeded sample points with grazing-floor-like footprints on a
    size x size texture: minor axis 2^U(-2, 4) texels, anisotropy 2^U(0, 4),
    random orientation.  Returns (st, ddx, ddy), (n, 2) each, in (s, t) units."""
    rng = np.random.default_rng(seed)
    st = rng.uniform(0, 4, size=(n, 2))
    minor = 2.0 ** rng.uniform(-2, 4, n)
    major = minor * 2.0 ** rng.uniform(0, 4, n)
    angle = rng.uniform(0, np.pi, n)
    c, s = np.cos(angle), np.sin(angle)
    ddx = np.stack([c * major, s * major], 1) / size
    ddy = np.stack([-s * minor, c * minor], 1) / size
    return st, ddx, ddy


def texel_reads(tex: MipTexture, st, ddx, ddy, precision: str) -> np.ndarray:
    """Texels a GL filter reads per sample (N,), from the level choice it
    makes: nearest 1, linear 4, per level, times 2 where two levels are
    blended; anisotropic: the probes' reads (exact) or the EWA texels with a
    non-zero weight (gl)."""
    gl = precision == "gl"
    if texture.effective_anisotropy(tex.max_anisotropy, gl) > 1:
        if gl:
            return texture.sample_anisotropic_llvmpipe(tex, st, ddx, ddy)[1]
        du, dv = texture.texel_derivatives(ddx, ddy, tex.size, gl=False)
        px, py = np.hypot(du[:, 0], du[:, 1]), np.hypot(dv[:, 0], dv[:, 1])
        count, rho2 = texture.anisotropic_probes(px, py, tex.max_anisotropy)
        return count * _gl_reads(tex, rho2, False)
    du, dv = texture.texel_derivatives(ddx, ddy, tex.size, gl)
    return _gl_reads(tex, texture.rho_squared(du, dv), gl)


def _gl_reads(tex: MipTexture, rho2: np.ndarray, gl: bool) -> np.ndarray:
    choice = texture.choose_levels(rho2, tex.min_filter, len(tex.used_levels), gl)
    per_level = np.where(choice.magnified, 4 if tex.mag_filter == "linear" else 1,
                         4 if tex.min_filter.startswith("linear") else 1)
    blended = ~choice.magnified & (choice.level1 != choice.level0) & (choice.frac > 0)
    return per_level * np.where(blended, 2, 1)


COST_FILTERS = (("nearest", "nearest", 1, None), ("linear", "linear", 1, None),
                ("nearest_mipmap_nearest", "nearest_mipmap_nearest", 1, None),
                ("linear_mipmap_nearest", "linear_mipmap_nearest", 1, None),
                ("nearest_mipmap_linear", "nearest_mipmap_linear", 1, None),
                ("linear_mipmap_linear (trilinear)", "linear_mipmap_linear", 1, None),
                ("anisotropic 16", "linear_mipmap_linear", 16, None),
                ("ripmap", "linear_mipmap_linear", 1, "ripmap"),
                ("EWA", "linear_mipmap_linear", 1, "ewa"))


def filter_costs(n: int = 200_000, runs: int = 5, size: int = 256, seed: int = 0) -> list[dict]:
    """Texel reads per sample and seconds per million samples of every
    filter, on :func:`synthetic_footprints` (a size^2 noise texture).

    Returns one dict per (filter, precision): name, precision, reads (mean
    per sample), seconds_per_million (median of ``runs`` timed runs after a
    warm-up run).  GL filters are timed in both precisions; ripmap and EWA
    have one (float64).
    """
    level0 = texels.premultiply_rgba8(texels.procedural_texels("noise", (size, size), {"seed": seed}))
    chain = texels.mip_chain(level0)
    st, ddx, ddy = synthetic_footprints(n, size, seed)
    rows = []
    for label, min_filter, aniso, beyond in COST_FILTERS:
        mag_filter = min_filter.split("_")[0]                # nearest reads 1 texel magnified too
        tex = texture.MipTexture(label, chain, "repeat", "repeat", min_filter, mag_filter, float(aniso))
        for precision in (("exact",) if beyond else ("gl", "exact")):
            if beyond:
                def run():
                    return sample_beyond(beyond, tex, st, ddx, ddy)[0]
                reads = sample_beyond(beyond, tex, st, ddx, ddy)[1]
            else:
                def run():
                    return texture.sample(tex, st, ddx, ddy, precision)
                reads = texel_reads(tex, st, ddx, ddy, precision)
            run()                                           # warm-up (numba compilation)
            times = []
            for _ in range(runs):
                start = time.perf_counter()
                run()
                times.append(time.perf_counter() - start)
            rows.append({"name": label, "precision": precision, "reads": float(reads.mean()),
                         "seconds_per_million": float(np.median(times)) * 1e6 / n})
    return rows


LECTURE_READS = {"nearest": "1", "linear": "4", "linear_mipmap_linear (trilinear)": "8",
                 "anisotropic 16": "16+"}


def format_costs(rows: list[dict]) -> str:
    """The cost table as Markdown, beside the lecture's read counts."""
    lines = ["| filter | precision | lecture | texel reads / sample (mean) | s per million samples (median) |",
             "|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['name']} | {row['precision']} | {LECTURE_READS.get(row['name'], '')} | "
                     f"{row['reads']:.1f} | {row['seconds_per_million']:.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":      # python -m softras.pipeline.texture_beyond: print the cost table
    print(format_costs(filter_costs()))
