"""Image comparison: SSIM, per-pixel tolerances and a difference heat map.

:func:`compare` is how softras decides whether two renderings of the same scene
agree (docs/design.md section 7, tolerances). Two measures must both pass:

* **Per-pixel tolerance.** For each pixel, the largest absolute difference over
  its four channels (R, G, B, A, in 0..255) is taken. A pixel is *bad* when
  that difference exceeds ``threshold``; the comparison fails when the fraction
  of bad pixels exceeds ``max_bad_fraction``.
* **Structural similarity.** The mean SSIM (scikit-image's
  :func:`~skimage.metrics.structural_similarity`, Wang et al. 2004, 7x7
  uniform window, sample covariance, ``data_range=255``) over all four RGBA
  channels must be at least ``min_ssim``. Alpha is included because a
  framebuffer's alpha is part of the result (blending writes it).

Small images: the SSIM window is 7x7, which does not fit images smaller than
7 pixels in either direction. There the window shrinks to the largest odd size
that fits (5, 3 or 1). A 1-pixel window has no variance, so SSIM falls back to
population statistics and reduces to its luminance term. As with any SSIM
window, the mean excludes a border of ``(win_size - 1) // 2`` pixels, where
the window does not fit; :attr:`Comparison.ssim_map` covers every pixel.

The difference image (:attr:`Comparison.diff_image`) is an opaque heat map of
the per-pixel largest channel difference ``d``, scaled around the threshold
``T`` so that "within tolerance" and "out of tolerance" are told apart at a
glance:

* ``d == 0``: black.
* ``0 < d <= T`` (within tolerance): dark blue to medium blue, linear in
  ``d / T``.
* ``d > T`` (bad): dark red, red, yellow, white, on a log scale of the excess,
  ``s = log(1 + d - T) / log(1 + 255 - T)``: one level over the threshold is
  already clearly red, 255 is white.

Maps for the eye (:func:`error_map_image`): the SSIM map is shown as its
dissimilarity ``clip(1 - ssim, 0, 1)`` and the FLIP map as FLIP's per-pixel
error in [0, 1], both on the ramp black (no error), dark red, red, yellow,
white (the largest error), with a square root so small errors stay visible.

**FLIP** (:func:`flip`; Andersson et al. 2020, "FLIP: A Difference Evaluator
for Alternating Images", NVIDIA) is a perceptual error: what a viewer notices
when flipping between the two images. It is computed by the ``flip-evaluator``
package (imported only when asked for: ``compare(..., flip=True)``), LDR mode,
67 pixels per degree (FLIP's default viewing conditions), on the RGB channels
read as sRGB -- what a PNG viewer shows. Our RGB is premultiplied, i.e. the
image composited over black; alpha is not part of FLIP.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Comparison", "ShapeMismatch", "FlipUnavailable", "compare", "diff_heatmap",
           "error_map_image", "flip", "pixel_difference"]

_SSIM_WINDOW = 7

# Colour stops of the heat map (RGB, 0..255).
_WITHIN_LOW = np.array([0, 0, 80], dtype=np.float64)     # d just above 0
_WITHIN_HIGH = np.array([70, 90, 255], dtype=np.float64)  # d == threshold
# Stops of the "bad" ramp, positions s in [0, 1].
_BAD_STOPS = np.array([0.0, 0.3, 0.7, 1.0])
_BAD_COLOURS = np.array(
    [
        [150, 0, 0],      # just over the threshold: dark red
        [255, 0, 0],      # red
        [255, 255, 0],    # yellow
        [255, 255, 255],  # 255: white
    ],
    dtype=np.float64,
)


class ShapeMismatch(ValueError):
    """The two images given to :func:`compare` differ in shape."""


class FlipUnavailable(RuntimeError):
    """The ``flip-evaluator`` package (FLIP) is not installed; one-line message."""


@dataclass
class Comparison:
    """The result of :func:`compare`.

    Attributes
    ----------
    passed : bool
        ``bad_fraction <= max_bad_fraction and ssim >= min_ssim``.
    ssim : float
        Mean structural similarity over all four channels, in [-1, 1].
    max_diff : int or float
        Largest absolute per-channel difference over the image, 0..255
        (a float for float images: their exact difference in 1/255 units).
    bad_fraction : float
        Fraction of pixels whose largest channel difference exceeds
        ``threshold``.
    bad_pixels : int
        Number of such pixels.
    threshold : int
        The per-pixel tolerance used, in 1/255 units.
    min_ssim : float
        The SSIM bound used.
    max_bad_fraction : float
        The bad-pixel bound used.
    diff_image : numpy.ndarray
        ``uint8`` ``(H, W, 4)`` opaque heat map of the per-pixel largest
        channel difference (see the module docstring for the scale).
    ssim_map : numpy.ndarray
        ``float64`` ``(H, W)`` local SSIM, averaged over the channels.
    flip_mean : float or None
        Mean FLIP error in [0, 1] (0 = identical), when asked for
        (``compare(..., flip=True)``), else None.
    flip_map : numpy.ndarray or None
        ``float32`` ``(H, W)`` per-pixel FLIP error in [0, 1], or None.
    """

    passed: bool
    ssim: float
    max_diff: int
    bad_fraction: float
    bad_pixels: int
    threshold: int
    min_ssim: float
    max_bad_fraction: float
    diff_image: np.ndarray = field(repr=False)
    ssim_map: np.ndarray = field(repr=False)
    flip_mean: float | None = None
    flip_map: np.ndarray | None = field(default=None, repr=False)
    max_abs_diff: float | None = None   # float images only: largest channel difference, colour units

    def to_dict(self) -> dict:
        """Return the scalar results as a JSON-serialisable dict.

        Returns
        -------
        dict
            Keys ``passed``, ``ssim``, ``max_diff``, ``bad_fraction``,
            ``bad_pixels``, ``total_pixels``, ``width``, ``height``,
            ``threshold``, ``min_ssim``, ``max_bad_fraction``, and
            ``flip_mean`` when FLIP was computed. No arrays.
        """
        height, width = self.diff_image.shape[:2]
        result = {
            "passed": bool(self.passed),
            "ssim": float(self.ssim),
            "max_diff": self.max_diff if isinstance(self.max_diff, float) else int(self.max_diff),
            "bad_fraction": float(self.bad_fraction),
            "bad_pixels": int(self.bad_pixels),
            "total_pixels": int(width * height),
            "width": int(width),
            "height": int(height),
            "threshold": int(self.threshold),
            "min_ssim": float(self.min_ssim),
            "max_bad_fraction": float(self.max_bad_fraction),
        }
        if self.flip_mean is not None:
            result["flip_mean"] = float(self.flip_mean)
        if self.max_abs_diff is not None:
            result["max_abs_diff"] = float(self.max_abs_diff)
        return result

    def summary(self) -> str:
        """Return a short human-readable summary, one line.

        Returns
        -------
        str
            For example ``"PASS  SSIM 0.99876 (>= 0.99)  max diff 3/255
            bad pixels 12/12288 = 0.098% (> 2/255; allowed 0.100%)"``.
        """
        total = self.diff_image.shape[0] * self.diff_image.shape[1]
        verdict = "PASS" if self.passed else "FAIL"
        return (
            f"{verdict}  SSIM {self.ssim:.5f} (>= {self.min_ssim:g})  "
            f"max diff {self.max_diff:.3g}/255  "
            f"bad pixels {self.bad_pixels}/{total} = {100 * self.bad_fraction:.3f}% "
            f"(> {self.threshold}/255; allowed {100 * self.max_bad_fraction:.3f}%)"
            + ("" if self.flip_mean is None else f"  FLIP {self.flip_mean:.4f}")
        )


def _as_image(image, name: str) -> np.ndarray:
    """Return ``image`` as a uint8 (H, W, C) array, reading it if it is a path."""
    if isinstance(image, (str, os.PathLike)):
        from softras.scene.imageio import read_png

        image = read_png(image)
    array = np.asarray(image)
    if array.dtype != np.uint8:
        raise ValueError(f"compare: image {name} must be uint8 (0..255), got dtype {array.dtype}")
    if array.ndim == 2:
        array = array[..., None]
    if array.ndim != 3 or array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"compare: image {name} must have shape (H, W) or (H, W, C), got {array.shape}")
    return array


def _ssim(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """Mean SSIM and per-pixel SSIM map (averaged over channels)."""
    from skimage.metrics import structural_similarity

    smallest = min(a.shape[0], a.shape[1])
    win_size = min(_SSIM_WINDOW, smallest if smallest % 2 == 1 else smallest - 1)
    mean, full = structural_similarity(
        a,
        b,
        win_size=win_size,
        data_range=255,
        channel_axis=-1,
        full=True,
        # A 1x1 window has no sample variance (division by zero).
        use_sample_covariance=win_size > 1,
    )
    return float(mean), full.mean(axis=-1)


def diff_heatmap(diff: np.ndarray, threshold: int) -> np.ndarray:
    """Colour a per-pixel difference as an opaque heat map.

    Parameters
    ----------
    diff : numpy.ndarray
        Integer ``(H, W)`` per-pixel difference, 0..255.
    threshold : int
        The per-pixel tolerance ``T``; differences above it are drawn in the
        red-yellow-white ramp, those within it in blue.

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 4)``, alpha 255. See the module docstring for the
        colour scale.
    """
    d = np.asarray(diff, dtype=np.float64)
    out = np.zeros(d.shape + (3,), dtype=np.float64)

    within = (d > 0) & (d <= threshold)
    if threshold > 0 and within.any():
        u = (d[within] / threshold)[:, None]
        out[within] = _WITHIN_LOW + u * (_WITHIN_HIGH - _WITHIN_LOW)

    bad = d > threshold
    if bad.any():
        s = np.log1p(d[bad] - threshold) / np.log1p(255 - threshold)
        s = np.clip(s, 0.0, 1.0)
        out[bad] = np.stack(
            [np.interp(s, _BAD_STOPS, _BAD_COLOURS[:, c]) for c in range(3)], axis=-1
        )

    image = np.empty(d.shape + (4,), dtype=np.uint8)
    image[..., :3] = np.rint(out).astype(np.uint8)
    image[..., 3] = 255
    return image


def pixel_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel largest absolute channel difference of two uint8 images.

    Parameters
    ----------
    a, b : numpy.ndarray
        ``uint8`` ``(H, W, C)`` images of the same shape.

    Returns
    -------
    numpy.ndarray
        ``int16`` ``(H, W)``, 0..255.
    """
    return np.abs(a.astype(np.int16) - b.astype(np.int16)).max(axis=-1)


def error_map_image(error: np.ndarray) -> np.ndarray:
    """Colour a per-pixel error in [0, 1] (0 = none) for the eye.

    Parameters
    ----------
    error : numpy.ndarray
        Float ``(H, W)``; values are clipped to [0, 1]. Use
        ``1 - ssim_map`` for SSIM and the FLIP map as it is.

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 4)``, opaque: black for 0, then dark red, red,
        yellow, white for 1, on ``sqrt(error)`` (small errors stay visible).
    """
    e = np.sqrt(np.clip(np.nan_to_num(np.asarray(error, dtype=np.float64)), 0.0, 1.0))
    stops = np.array([0.0, 0.15, 0.45, 0.8, 1.0])
    colours = np.array([[0, 0, 0], [110, 0, 0], [255, 0, 0], [255, 255, 0], [255, 255, 255]], dtype=np.float64)
    image = np.empty(e.shape + (4,), dtype=np.uint8)
    for c in range(3):
        image[..., c] = np.rint(np.interp(e, stops, colours[:, c])).astype(np.uint8)
    image[..., 3] = 255
    return image


def flip(reference, test) -> tuple[float, np.ndarray]:
    """FLIP perceptual error between two images (see the module docstring).

    Parameters
    ----------
    reference, test : numpy.ndarray
        ``uint8`` ``(H, W, 4)``, ``(H, W, 3)`` or ``(H, W)`` images of the
        same shape (float images: colour units, clamped to [0, 1]); the RGB
        channels are used, read as sRGB.

    Returns
    -------
    mean : float
        Mean FLIP error in [0, 1], 0 for identical images.
    error_map : numpy.ndarray
        ``float32`` ``(H, W)`` per-pixel FLIP error in [0, 1].

    Raises
    ------
    FlipUnavailable
        If the ``flip-evaluator`` package is not installed.
    """
    try:
        import flip_evaluator
    except ImportError:
        raise FlipUnavailable(
            "FLIP needs the Python package flip-evaluator: pip install flip-evaluator"
        ) from None
    def unit(image) -> np.ndarray:  # uint8 -> [0, 1]; float (colour units) clamped to [0, 1]
        array = np.asarray(image)
        rgb = array[..., :3] if array.ndim == 3 else array
        if array.dtype.kind == "f":
            return np.ascontiguousarray(np.clip(rgb, 0.0, 1.0), dtype=np.float32)
        return np.ascontiguousarray(rgb, dtype=np.float32) / np.float32(255)

    ref, tst = unit(reference), unit(test)
    if ref.ndim == 2:  # grey (H, W): FLIP wants colour channels
        ref, tst = (np.repeat(x[..., None], 3, axis=-1) for x in (ref, tst))
    if ref.shape[-1] == 1:
        ref, tst = (np.repeat(x, 3, axis=-1) for x in (ref, tst))
    error_map, mean, _ = flip_evaluator.evaluate(ref, tst, "LDR", applyMagma=False)
    return float(mean), np.asarray(error_map, dtype=np.float32).reshape(ref.shape[:2])


def compare(a, b, *, threshold: int = 2, max_bad_fraction: float = 0.001, min_ssim: float = 0.99,
            flip: bool = False) -> Comparison:
    """Compare two images with per-pixel tolerances and SSIM.

    Parameters
    ----------
    a, b : numpy.ndarray or str or os.PathLike
        ``uint8`` images of the same shape, usually ``(H, W, 4)`` RGBA as
        returned by :func:`softras.render`; ``(H, W, 3)`` and ``(H, W)`` are
        accepted too. A path is read with :func:`softras.scene.imageio.read_png`.
        Float images (an rgba32f render) are compared unrounded, in 1/255
        units (see :func:`_compare_float`).
    threshold : int, optional
        Per-pixel tolerance in 1/255 units: a pixel is bad when its largest
        channel difference exceeds it. 0..255, default 2.
    max_bad_fraction : float, optional
        Largest allowed fraction of bad pixels, 0..1, default 0.001.
    min_ssim : float, optional
        Smallest allowed mean SSIM, -1..1, default 0.99.
    flip : bool, optional
        Also compute FLIP (:attr:`Comparison.flip_mean`,
        :attr:`Comparison.flip_map`; ``b`` is the reference). Informative
        only: FLIP does not enter ``passed``. Needs ``flip-evaluator``.

    Returns
    -------
    Comparison
        The measures, the verdict and the difference heat map.

    Raises
    ------
    ShapeMismatch
        If the images differ in shape (a subclass of ValueError).
    ValueError
        If an image is not uint8, or a tolerance is out of range.
    FlipUnavailable
        If ``flip=True`` and ``flip-evaluator`` is not installed.
    softras.scene.imageio.ImageError
        If a path cannot be read as PNG (a subclass of ValueError).

    Notes
    -----
    See the module docstring for the SSIM parameters, the handling of images
    smaller than the 7x7 SSIM window, and the heat map's colour scale.
    """
    if isinstance(threshold, bool) or int(threshold) != threshold or not 0 <= threshold <= 255:
        raise ValueError(f"compare: threshold must be an integer in 0..255, got {threshold!r}")
    threshold = int(threshold)
    if not 0.0 <= float(max_bad_fraction) <= 1.0:
        raise ValueError(f"compare: max_bad_fraction must be in [0, 1], got {max_bad_fraction!r}")
    if not -1.0 <= float(min_ssim) <= 1.0:
        raise ValueError(f"compare: min_ssim must be in [-1, 1], got {min_ssim!r}")

    if _is_float_image(a) or _is_float_image(b):
        return _compare_float(a, b, threshold, max_bad_fraction, min_ssim)
    a = _as_image(a, "a")
    b = _as_image(b, "b")
    if a.shape != b.shape:
        raise ShapeMismatch(
            f"compare: images differ in shape: {a.shape[1]}x{a.shape[0]}x{a.shape[2]} "
            f"vs {b.shape[1]}x{b.shape[0]}x{b.shape[2]} (width x height x channels)"
        )

    pixel_diff = pixel_difference(a, b)
    max_diff = int(pixel_diff.max())
    bad_pixels = int(np.count_nonzero(pixel_diff > threshold))
    bad_fraction = bad_pixels / pixel_diff.size
    ssim, ssim_map = _ssim(a, b)
    flip_mean, flip_map = _flip(b, a) if flip else (None, None)

    passed = bad_fraction <= max_bad_fraction and ssim >= min_ssim
    return Comparison(
        passed=bool(passed),
        ssim=ssim,
        max_diff=max_diff,
        bad_fraction=float(bad_fraction),
        bad_pixels=bad_pixels,
        threshold=threshold,
        min_ssim=float(min_ssim),
        max_bad_fraction=float(max_bad_fraction),
        diff_image=diff_heatmap(pixel_diff, threshold),
        ssim_map=ssim_map,
        flip_mean=flip_mean,
        flip_map=flip_map,
    )


_flip = flip  # compare()'s keyword ``flip`` shadows the function


def _is_float_image(image) -> bool:
    return isinstance(image, np.ndarray) and image.dtype.kind == "f"


def _compare_float(a, b, threshold: int, max_bad_fraction: float, min_ssim: float) -> Comparison:
    """:func:`compare` for float images (an rgba32f framebuffer: float32 (H, W, 4)).

    Float values are colour units (1.0 = 255/255) and are neither clamped nor
    rounded; a uint8 image compared with a float one is read as k/255.  The
    per-pixel difference is the largest channel difference in 1/255 units, a
    float, so ``threshold`` keeps its meaning; ``max_diff`` is that
    difference as a float (a 2.2e-16 difference is 5.6e-14/255, not 1/255)
    and ``max_abs_diff`` the largest difference in colour units.  SSIM is computed on the values
    x 255 with ``data_range=255``, as for uint8 images.
    """
    def as_float(image, name):
        array = np.asarray(image)
        if array.dtype == np.uint8:
            array = array / 255.0
        elif array.dtype.kind != "f":
            raise ValueError(f"compare: image {name} must be uint8 or float, got dtype {array.dtype}")
        if array.ndim == 2:
            array = array[..., None]
        if array.ndim != 3 or array.shape[0] == 0 or array.shape[1] == 0:
            raise ValueError(f"compare: image {name} must have shape (H, W) or (H, W, C), got {array.shape}")
        if not np.isfinite(array).all():
            raise ValueError(f"compare: image {name} has NaN or infinite values")
        return array.astype(np.float64)

    a, b = as_float(a, "a"), as_float(b, "b")
    if a.shape != b.shape:
        raise ShapeMismatch(
            f"compare: images differ in shape: {a.shape[1]}x{a.shape[0]}x{a.shape[2]} "
            f"vs {b.shape[1]}x{b.shape[0]}x{b.shape[2]} (width x height x channels)"
        )
    pixel_diff = np.abs(a - b).max(axis=-1) * 255.0
    bad_pixels = int(np.count_nonzero(pixel_diff > threshold))
    bad_fraction = bad_pixels / pixel_diff.size
    ssim, ssim_map = _ssim(a * 255.0, b * 255.0)
    return Comparison(
        passed=bool(bad_fraction <= max_bad_fraction and ssim >= min_ssim),
        ssim=ssim,
        max_diff=float(pixel_diff.max()),
        bad_fraction=float(bad_fraction),
        bad_pixels=bad_pixels,
        threshold=threshold,
        min_ssim=float(min_ssim),
        max_bad_fraction=float(max_bad_fraction),
        diff_image=diff_heatmap(np.minimum(pixel_diff, 255.0), threshold),
        ssim_map=ssim_map,
        max_abs_diff=float(pixel_diff.max() / 255.0),
    )
