"""Sample patterns: where in a pixel the rasterizer tests coverage.

Every pattern is a function returning an (S, 2) float64 array of sample
positions ``(x, y)`` in [0, 1)^2, measured from the pixel's lower-left corner
in GL's y-up window space (sample s of pixel (i, j) is at window position
``(i + x_s, j + y_s)``).  The same pattern is used in every pixel, so a
pattern that should look "random" across pixel borders (jittered, Poisson)
is built on the torus: distances wrap around the pixel.

Patterns
--------
``"gl"``            GL's: 1 sample = the pixel centre, 4 = llvmpipe's MSAA
                    positions (.375,.125) (.875,.375) (.125,.625) (.625,.875).
``"grid"``          N x N regular grid, cell centres, S = N^2, N in 1..32.
``"rotated_grid"``  the N x N grid rotated by atan(1/N) about the pixel centre
                    and stretched by 1/cos(atan(1/N)) so that the S = N^2
                    samples fall in S distinct rows and S distinct columns
                    (an "N-rooks" pattern); N = 2 is exactly llvmpipe's 4x.
``"jittered"``      stratified: one uniform random sample per cell of the
                    N x N grid (seeded), S = N^2.
``"halton"``        the first S points (indices 1..S) of the Halton sequence
                    in bases 2 and 3; any S >= 1; deterministic.
``"poisson"``       Poisson-disk: seeded dart throwing on the unit torus with
                    a minimum distance that shrinks by 5 % whenever 1000
                    darts in a row are rejected; any S >= 1.

Use :func:`sample_positions` to pick one by name; the renderer's options are
``softras.render(scene, samples=S, pattern=NAME, seed=K)``.

Run ``python -m softras.pipeline.sampling`` to print a few patterns.
"""

from __future__ import annotations

import functools
import math

import numpy as np

PATTERNS = ("gl", "grid", "rotated_grid", "jittered", "halton", "poisson")
MAX_GRID_SIDE = 32                      # N x N grids: N in 1..32
MAX_SAMPLES = MAX_GRID_SIDE ** 2        # 1024 samples per pixel at most
MAX_PASS_SAMPLES = 32                   # samples per rasterizer pass (uint32 coverage masks)

# llvmpipe's 4x MSAA sample positions within a pixel (x, y), GL window space.
GL_MSAA4 = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
GL_CENTER = np.array([[0.5, 0.5]])


def _grid_side(samples: int, pattern: str) -> int:
    """N for an N x N pattern of ``samples`` samples; ValueError unless a square of 1..32."""
    side = math.isqrt(samples)
    if side * side != samples or not 1 <= side <= MAX_GRID_SIDE:
        raise ValueError(f"pattern {pattern!r} needs samples = N*N with N in 1..{MAX_GRID_SIDE} "
                         f"(1, 4, 9, ..., {MAX_SAMPLES}), not {samples}")
    return side


def gl_pattern(samples: int) -> np.ndarray:
    """GL's positions: (1, 2) pixel centre for 1 sample, llvmpipe's (4, 2) for 4."""
    if samples == 1:
        return GL_CENTER.copy()
    if samples == 4:
        return GL_MSAA4.copy()
    raise ValueError(f"pattern 'gl' has 1 or 4 samples (llvmpipe's), not {samples}; "
                     f"choose another pattern for {samples} samples")


def grid(side: int) -> np.ndarray:
    """(side^2, 2) cell centres of a side x side grid, row by row from the bottom.

    Sample ``k = j * side + i`` is at ``((i + 0.5) / side, (j + 0.5) / side)``.
    """
    i = np.arange(side)
    xs, ys = np.meshgrid((i + 0.5) / side, (i + 0.5) / side)     # ys[j, i], xs[j, i]
    return np.stack([xs.ravel(), ys.ravel()], axis=1)


def rotated_grid(side: int) -> np.ndarray:
    """(side^2, 2) the side x side grid rotated by atan(1/side) (RGSS).

    A grid point g (relative to the pixel centre) goes to
    ``(g_x - g_y / side, g_y + g_x / side)``: a rotation by atan(1/side)
    followed by a 1/cos stretch, which makes the x (and the y) coordinates of
    the S = side^2 samples exactly the S values (k + 0.5)/S -- every sample
    in its own row and column of the S x S sub-grid.  For side = 2 this is
    llvmpipe's 4x pattern, sample for sample.
    """
    g = grid(side) - 0.5
    rotated = np.stack([g[:, 0] - g[:, 1] / side, g[:, 1] + g[:, 0] / side], axis=1)
    return rotated + 0.5


def jittered(side: int, seed: int = 0) -> np.ndarray:
    """(side^2, 2) one uniform random sample in each cell of a side x side grid (seeded)."""
    rng = np.random.default_rng(seed)
    corner = grid(side) - 0.5 / side
    return corner + rng.uniform(0.0, 1.0 / side, size=corner.shape)


def radical_inverse(index: np.ndarray, base: int) -> np.ndarray:
    """Van der Corput radical inverse of non-negative integers in ``base``: digits mirrored
    about the radix point (e.g. base 2: 1 -> 0.5, 2 -> 0.25, 3 -> 0.75)."""
    index = np.asarray(index, np.int64).copy()
    result = np.zeros(index.shape)
    scale = 1.0 / base
    while (index > 0).any():
        result += (index % base) * scale
        index //= base
        scale /= base
    return result


def halton(samples: int) -> np.ndarray:
    """(samples, 2) Halton points with indices 1..samples in bases 2 (x) and 3 (y).

    Index 0 (the pixel corner) is skipped.  Deterministic: no seed.
    """
    index = np.arange(1, samples + 1)
    return np.stack([radical_inverse(index, 2), radical_inverse(index, 3)], axis=1)


def poisson_disk(samples: int, seed: int = 0, max_rejections: int = 1000) -> np.ndarray:
    """(samples, 2) Poisson-disk points on the unit torus by seeded dart throwing.

    A dart (uniform random point) is kept when its wrap-around distance to
    every kept point is at least ``r``.  ``r`` starts at 0.9 x the densest
    packing distance for ``samples`` points (hexagonal: sqrt(2 / (sqrt(3) S)))
    and shrinks by 5 % after ``max_rejections`` rejected darts in a row, so
    the loop always ends with exactly ``samples`` points.  A new array
    each call, from the points of the first call with these arguments:
    the darts cost 7-56 ms for 4-64 points (a numpy call or three for each
    dart), and every render with the pattern asks again.
    """
    return _poisson_points(samples, seed, max_rejections).copy()


@functools.lru_cache(maxsize=32)
def _poisson_points(samples: int, seed: int, max_rejections: int) -> np.ndarray:
    """`poisson_disk`'s darts, kept per arguments: a read-only (samples, 2) array."""
    rng = np.random.default_rng(seed)
    radius = 0.9 * math.sqrt(2.0 / (math.sqrt(3.0) * samples))
    points = np.empty((samples, 2))
    count = 0
    rejected = 0
    while count < samples:
        dart = rng.uniform(0.0, 1.0, size=2)
        d = np.abs(points[:count] - dart)
        d = np.minimum(d, 1.0 - d)                     # distance on the torus
        if count == 0 or (d[:, 0] ** 2 + d[:, 1] ** 2).min() >= radius * radius:
            points[count] = dart
            count += 1
            rejected = 0
        else:
            rejected += 1
            if rejected >= max_rejections:
                radius *= 0.95
                rejected = 0
    points.flags.writeable = False
    return points


def sample_passes(samples: int) -> list[tuple[int, int]]:
    """Split S samples into near-equal passes of <= MAX_PASS_SAMPLES: [(start, stop), ...].

    The rasterizers keep a fragment's coverage in a uint32 bit mask, so one
    pass takes at most 32 samples.  Near-equal, so that every pass of a
    multisampled render has more than one sample (lines are rasterized by the
    MSAA rules only when S > 1).
    """
    count = -(-samples // MAX_PASS_SAMPLES)
    bounds = [round(k * samples / count) for k in range(count + 1)]
    return list(zip(bounds[:-1], bounds[1:]))


def in_passes(positions: np.ndarray, render_pass) -> np.ndarray:
    """A per-sample colour buffer (H, W, S, 4) rendered in the passes of
    `sample_passes`: ``render_pass(positions[start:stop])`` returns one
    pass's (H, W, stop - start, 4) buffer; a single pass's is returned as it
    is, several are copied into one buffer of their type."""
    passes = sample_passes(len(positions))
    if len(passes) == 1:
        return render_pass(positions)
    color = None
    for start, stop in passes:
        part = render_pass(positions[start:stop])
        if color is None:
            color = np.empty(part.shape[:2] + (len(positions), 4), part.dtype)
        color[:, :, start:stop] = part
    return color


def sample_positions(samples: int, pattern=None, seed: int = 0) -> np.ndarray:
    """(samples, 2) float64 positions in [0, 1)^2 for a pattern name (see the module docstring).

    pattern None means "gl"; an (samples, 2) array gives the positions
    themselves (e.g. a GL's own, from glGetMultisamplefv: y up, from the
    pixel's lower-left corner).  Raises ValueError, naming the problem, for an
    unknown pattern or a sample count the pattern cannot make.
    """
    pattern = "gl" if pattern is None else pattern
    if not isinstance(pattern, str):
        positions = np.asarray(pattern, dtype=np.float64)
        if positions.shape != (samples, 2) or not ((positions >= 0) & (positions < 1)).all():
            raise ValueError(f"sample positions must be a ({samples}, 2) array in [0, 1), "
                             f"not shape {positions.shape}")
        return positions
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)):
        raise ValueError(f"samples must be an integer, not {samples!r}")
    samples = int(samples)
    if not 1 <= samples <= MAX_SAMPLES:
        raise ValueError(f"samples must be in 1..{MAX_SAMPLES}, not {samples}")
    if pattern == "gl":
        return gl_pattern(samples)
    if pattern == "grid":
        return grid(_grid_side(samples, pattern))
    if pattern == "rotated_grid":
        return rotated_grid(_grid_side(samples, pattern))
    if pattern == "jittered":
        return jittered(_grid_side(samples, pattern), seed)
    if pattern == "halton":
        return halton(samples)
    if pattern == "poisson":
        return poisson_disk(samples, seed)
    raise ValueError(f"pattern must be one of {', '.join(PATTERNS)}; not {pattern!r}")


def _main() -> None:
    np.set_printoptions(precision=4, suppress=True)
    for pattern, samples in (("gl", 4), ("grid", 4), ("rotated_grid", 4), ("jittered", 4),
                             ("halton", 4), ("poisson", 4)):
        print(f"{pattern} x{samples}:\n{sample_positions(samples, pattern)}")


if __name__ == "__main__":
    _main()
