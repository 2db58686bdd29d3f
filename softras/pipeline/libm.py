"""pow and log2 for the stages and the kernels alike: the C library's.

A compiled kernel must give its stage's bits (tests/test_fastpath.py,
tests/test_exact_path.py).  IEEE 754 fixes the bits of +, -, *, / and
sqrt, but not of pow or log2, and numpy computes `np.power` and `np.log2`
(exp, sin, ... too) with SIMD code of its own where the CPU has AVX-512
(numpy's AVX512_SKX dispatch).  Its last bit differs from the C
library's, which numba's compiled code calls.  On a Cascade Lake Xeon
(numpy 2.4, numba 0.68): 389 of 400k log2 arguments, 17,953 of 400k
pow(x, 1.5).  So the stages take these two from here: compiled loops
around the same scalar functions that the kernels inline (`_power`,
`_log2`), so a kernel equals its stage on any CPU.  On a CPU without
AVX-512 numpy's loops call the C library too, and the values are numpy's.
(Were numba given Intel's SVML, with the icc_rt package, LLVM could
vectorise these loops with SVML's functions: set NUMBA_DISABLE_INTEL_SVML=1
there.)

Arrays are float64 of any shape; the results have the argument's shape.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy", inline="always")
def _power(x, y):
    """x ** y of float64 scalars: C's ``pow``, but for the exponents that
    numpy's own (non-SIMD) loop special-cases, with its results there (2:
    ``x * x``, 0.5: ``sqrt(x)``, -1: ``1 / x``), so that pictures are
    numpy's where numpy calls the C library."""
    if y == 2.0:
        return x * x
    if y == 0.5:
        return math.sqrt(x)
    if y == -1.0:
        return 1.0 / x
    return x ** y


@numba.njit(cache=True, error_model="numpy", inline="always")
def _log2(x):
    """log2 of a float64 scalar: C's ``log2`` (0: -inf, negative or NaN: NaN)."""
    return np.log2(x)


@numba.njit(cache=True, error_model="numpy")
def _power_loop(x, y, out):
    for i in range(x.size):
        out[i] = _power(x[i], y)


@numba.njit(cache=True, error_model="numpy")
def _log2_loop(x, out):
    for i in range(x.size):
        out[i] = _log2(x[i])


def power(x: np.ndarray, y: float) -> np.ndarray:
    """x ** y elementwise (`_power`) for float64 values x of any shape and
    one exponent y."""
    x = np.ascontiguousarray(x, np.float64)
    out = np.empty_like(x)
    _power_loop(x.reshape(-1), float(y), out.reshape(-1))
    return out


def log2(x: np.ndarray) -> np.ndarray:
    """log2 elementwise (`_log2`) of float64 values of any shape."""
    x = np.ascontiguousarray(x, np.float64)
    out = np.empty_like(x)
    _log2_loop(x.reshape(-1), out.reshape(-1))
    return out
