"""pow and log2 of the stages (`softras.pipeline.libm`): the C library's
bits, which the compiled kernels' code computes, on any CPU (numpy's own
SIMD loops for them differ in the last bit on AVX-512 machines)."""

import math

import numpy as np
import pytest

from softras.kernels import light as k_light
from softras.pipeline import libm

RNG = np.random.default_rng(7)
# Bases in [0, 1] (N.H), tiny ones, and the special values.
BASES = np.concatenate([RNG.uniform(0, 1, 20000), np.exp(-RNG.uniform(0, 40, 5000)),
                        [0.0, -0.0, 1.0, 0.5, np.inf, np.nan, -1.0, 5e-324]])
EXPONENTS = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 7.3, 32.0, 100.0, 4096.0, -1.0, -2.5]
SPECIAL = {2.0: lambda x: x * x, 0.5: math.sqrt, -1.0: lambda x: 1.0 / x if x else math.copysign(math.inf, x)}


def _c_pow(x: float, y: float) -> float:
    """math.pow is C's pow, with C's results where Python raises (0 ** -y:
    inf; overflow: inf; a negative base with a fractional exponent: NaN)."""
    if y in SPECIAL:
        return math.nan if x != x else (SPECIAL[y](x) if x >= 0 or y != 0.5 else math.nan)
    try:
        return math.pow(x, y)
    except OverflowError:
        return math.inf
    except ValueError:
        return math.inf if x == 0 else math.nan


def bits(values) -> np.ndarray:
    return np.asarray(values, np.float64).view(np.int64)


@pytest.mark.parametrize("y", EXPONENTS)
def test_power_is_the_c_librarys(y):
    expected = np.array([_c_pow(float(x), y) for x in BASES])
    got = libm.power(BASES, y)
    same = (bits(got) == bits(expected)) | (np.isnan(got) & np.isnan(expected))
    assert same.all(), f"exponent {y}: {BASES[~same][:5]} -> {got[~same][:5]}, C {expected[~same][:5]}"


def test_log2_is_the_c_librarys():
    x = np.concatenate([BASES, np.exp(RNG.uniform(-700, 700, 20000)), [-np.inf]])
    with np.errstate(all="ignore"):
        got = libm.log2(x)
    expected = np.array([math.log2(v) if v > 0 else (-math.inf if v == 0 else math.nan) for v in x])
    same = (bits(got) == bits(expected)) | (np.isnan(got) & np.isnan(expected))
    assert same.all(), f"{x[~same][:5]} -> {got[~same][:5]}, C {expected[~same][:5]}"


def test_shapes_are_kept():
    x = RNG.uniform(0, 1, (3, 4, 5))
    assert libm.power(x, 1.5).shape == x.shape and libm.log2(x[:, ::2]).shape == (3, 2, 5)
    assert np.array_equal(libm.power(x, 1.5)[1, 2], libm.power(x[1, 2], 1.5))


def test_the_kernels_call_the_same_functions():
    """The kernels inline libm's scalars (no copy of their own to drift):
    the Phong kernels' pow (the exact kernel's log2 is `libm._log2` by name)."""
    assert k_light._power is libm._power
