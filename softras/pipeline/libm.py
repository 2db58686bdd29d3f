"""pow and log2 for the stages and the kernels alike, one definition each.

A compiled kernel must give its stage's bits (tests/test_fastpath.py,
tests/test_exact_path.py).  IEEE 754 fixes the bits of +, -, *, / and
sqrt, but not of pow or log2, and numpy computes `np.power` and `np.log2`
(exp, sin, ... too) with SIMD code of its own where the CPU has AVX-512
(numpy's AVX512_SKX dispatch).  Its last bit differs from the C
library's, which numba's compiled code calls.  On a Cascade Lake Xeon
(numpy 2.4, numba 0.68): 389 of 400k log2 arguments, 17,953 of 400k
pow(x, 1.5).  So the stages take these two from here: compiled loops
around the same scalar functions that the kernels inline (`_power`,
`_log2`), so a kernel equals its stage on any CPU.

`_power` is softras's own: exp(y ln x) in IEEE arithmetic alone (+, -, *,
/, comparisons and bit moves, no library call), so its bits are the same
on every CPU and C library, and LLVM compiles a loop of it to SIMD (the
Phong lanes': 17 ns a value against 30 ns for C's pow on a Cascade Lake,
docs/speed.md).  Its error, measured against C's pow (docs/numerics.md):
at most 3 ulp where |y ln x| <= 1, and at most 3.5 ulp per unit of
|y ln x| beyond (the rounding of ln x, scaled by y).  A whole exponent
below 256 (Phong's usual shininess) takes `_whole_power` instead, binary
powering: within n - 1 ulp of x^n, at a tenth of the cost (`_power_by`
chooses).
`_log2` is C's
(exact precision's level of detail, not a hot loop).  (Were numba given
Intel's SVML, with the icc_rt package, LLVM could vectorise `_log2`'s
loop with SVML's function: set NUMBA_DISABLE_INTEL_SVML=1 there.)

Arrays are float64 of any shape; the results have the argument's shape.
"""

from __future__ import annotations

import math
import sys

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def _bits(typingctx, x):
    """The IEEE 754 bits of a float64 scalar as an int64 (a bitcast)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, b):
    """The float64 scalar of IEEE 754 bits held in an int64 (a bitcast)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


# ln 2 split (fdlibm's): _LN2_HI has 32 significant bits, so k _LN2_HI is
# exact for the whole numbers |k| < 2^21 that multiply it here.
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.0 / math.log(2.0)
_SQRT2 = math.sqrt(2.0)
_LEAST_NORMAL = sys.float_info.min
_TWO_64 = 2.0 ** 64
_MANTISSA, _EXPONENT_ONE = (1 << 52) - 1, 1023 << 52
# ln m = 2 atanh(s) = 2 (s + s^3/3 + ... + s^23/23), s = (m - 1)/(m + 1):
# for m in [sqrt(1/2), sqrt(2)), |s| < 0.172 and the first term left out
# is below 2^-60 of the sum.
_A1, _A2, _A3, _A4, _A5, _A6 = 1 / 3, 1 / 5, 1 / 7, 1 / 9, 1 / 11, 1 / 13
_A7, _A8, _A9, _A10, _A11 = 1 / 15, 1 / 17, 1 / 19, 1 / 21, 1 / 23
# exp r = sum of r^j / j!, j = 0..13: for |r| <= ln(2)/2 the first term
# left out is below 2^-57 of the sum.
_E2, _E3, _E4, _E5, _E6, _E7 = 1 / 2, 1 / 6, 1 / 24, 1 / 120, 1 / 720, 1 / 5040
_E8, _E9, _E10, _E11, _E12, _E13 = 1 / 40320, 1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 479001600, 1 / 6227020800


@numba.njit(cache=True, error_model="numpy", inline="always")
def _ln(x):
    """ln x of a finite float64 x > 0: x = m 2^e with m in [sqrt(1/2),
    sqrt(2)) from x's bits (a subnormal x scaled by 2^64 first), then
    e ln 2 + 2 atanh((m - 1)/(m + 1)), the series in Estrin's order (fewer
    dependent steps than Horner's: 17 ns a pow against 21)."""
    subnormal = x < _LEAST_NORMAL
    b = _bits(x * _TWO_64 if subnormal else x)
    e = ((b >> 52) - 1023) - (64 if subnormal else 0)
    m = _from_bits((b & _MANTISSA) | _EXPONENT_ONE)
    if m >= _SQRT2:
        m, e = m * 0.5, e + 1
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    q0 = (_A1 + z * _A2) + z2 * (_A3 + z * _A4)
    q1 = (_A5 + z * _A6) + z2 * (_A7 + z * _A8)
    q2 = (_A9 + z * _A10) + z2 * _A11
    series = z * ((q0 + z4 * q1) + z8 * q2)
    ef = float(e)
    return ef * _LN2_HI + (ef * _LN2_LO + (2.0 * s + (2.0 * s) * series))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _exp(t):
    """e^t of a float64 t in [-746, 710]: 2^k e^r with k the whole number
    nearest t / ln 2 and |r| <= ln(2)/2 (r = t - k ln 2 in two parts), e^r
    by its series in Estrin's order, 2^k from its bits (a result below
    2^-1000 made in two steps, so that it is rounded once, as a subnormal)."""
    kf = math.floor(t * _INV_LN2 + 0.5)
    r = (t - kf * _LN2_HI) - kf * _LN2_LO
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    g0 = (1.0 + r) + r2 * (_E2 + r * _E3)
    g1 = (_E4 + r * _E5) + r2 * (_E6 + r * _E7)
    g2 = (_E8 + r * _E9) + r2 * (_E10 + r * _E11)
    g3 = _E12 + r * _E13
    er = (g0 + r4 * g1) + r8 * (g2 + r4 * g3)
    k = np.int64(kf)
    after = 1.0
    if k < -1000:
        k, after = k + 64, 1.0 / _TWO_64
    elif k > 1000:
        k, after = k - 64, _TWO_64
    return (er * _from_bits((k + 1023) << 52)) * after


@numba.njit(cache=True, error_model="numpy", inline="always")
def _power(x, y):
    """x ** y of float64 scalars, softras's own: e^(y ln x) (`_ln`, `_exp`),
    with C's results for the special values (y = 0 or x = 1: 1; x = +-0:
    +0, or inf for y < 0; x = inf: inf, or 0 for y < 0; NaN in x or y:
    NaN), NaN for any x < 0 (GLSL leaves pow of x < 0 undefined), and inf
    and 0 for results beyond the float64 range.  No branch that a loop could
    not turn into selects, so that a loop of it compiles to SIMD."""
    special = x != x or y != y or x <= 0.0 or x == math.inf or y == 0.0 or x == 1.0
    t = y * _ln(1.0 if special else x)
    out = _exp(min(max(t, -746.0), 710.0))
    if t > 710.0:
        out = math.inf
    if t < -746.0:
        out = 0.0
    if special:
        if y == 0.0 or x == 1.0:
            out = 1.0
        elif x != x or y != y or x < 0.0:
            out = math.nan
        elif x == 0.0:
            out = 0.0 if y > 0.0 else math.inf
        else:
            out = math.inf if y > 0.0 else 0.0
    return out


# A whole exponent below 2^WHOLE_BITS takes `_whole_power`: Blinn-Phong's
# shininess is a whole number in most scenes (32, 64, ...).
WHOLE_BITS = 8


@numba.njit(cache=True, error_model="numpy", inline="always")
def _whole_exponent(y):
    """y as an int64 when it is a whole number in [1, 2^WHOLE_BITS), else 0
    (`_power_by` then takes `_power`)."""
    return np.int64(y) if (y >= 1.0 and y < 2.0 ** WHOLE_BITS and y == math.floor(y)) else np.int64(0)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _whole_power(x, n):
    """x ** n of a float64 scalar x and a whole n in [1, 2^WHOLE_BITS) by
    binary powering: x, x^2, x^4, ... by squaring, the product of those of
    n's set bits in order of the bits (IEEE products alone: the same bits on
    every CPU); NaN for x < 0, as `_power`.  Each of the n - 1 products
    rounds once, so the result is within (n - 1) u relative of x^n (u =
    2^-53: n - 1 ulp; 5.7e-14 relative at most) where it is a normal number,
    and x = 0, 1, inf and NaN give C's results.  A loop of it with one n
    compiles to SIMD (the bit tests are the same in every lane): 1.4 ns a
    value against `_power`'s 15 (docs/speed.md)."""
    out = 1.0
    p = x
    for bit in range(WHOLE_BITS):
        if (n >> bit) & 1:
            out = out * p
        p = p * p
    return math.nan if x < 0.0 else out


@numba.njit(cache=True, error_model="numpy", inline="always")
def _power_by(x, y, n):
    """x ** y (`_whole_power` for n = `_whole_exponent(y)` when it is not 0,
    else `_power`): the pow of the stages and the kernels alike.  A loop
    over x with one y computes n once (`_power_loop`,
    `softras.kernels.light._phong_colors`): LLVM then takes the test of n
    out of the loop, and the loop is SIMD (1.9 ns a value at n = 32, 1.6
    with a loop of its own for each side; 15 ns off whole exponents)."""
    return _whole_power(x, n) if n else _power(x, y)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _log2(x):
    """log2 of a float64 scalar: C's ``log2`` (0: -inf, negative or NaN: NaN)."""
    return np.log2(x)


@numba.njit(cache=True, error_model="numpy")
def _power_loop(x, y, out):
    n = _whole_exponent(y)
    for i in range(x.size):
        out[i] = _power_by(x[i], y, n)


@numba.njit(cache=True, error_model="numpy")
def _log2_loop(x, out):
    for i in range(x.size):
        out[i] = _log2(x[i])


def power(x: np.ndarray, y: float) -> np.ndarray:
    """x ** y elementwise (`_power_by`: `_whole_power` for a whole y in [1,
    2^WHOLE_BITS), else `_power`) for float64 values x of any shape and one
    exponent y."""
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
