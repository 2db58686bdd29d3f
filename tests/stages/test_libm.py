"""pow and log2 of the stages (`softras.pipeline.libm`), the ones the
compiled kernels inline: softras's own pow, within a stated bound of C's
(and C's results for the special values); C's log2 bit for bit (numpy's
own SIMD loops for both differ in the last bit on AVX-512 machines)."""

import math

import numba
import numpy as np
import pytest

from softras.kernels import light as k_light
from softras.pipeline import libm

RNG = np.random.default_rng(7)
# Bases in [0, 1] (N.H), tiny ones, the whole float64 range, and the special values.
BASES = np.concatenate([RNG.uniform(0, 1, 20000), np.exp(-RNG.uniform(0, 40, 5000)),
                        RNG.uniform(0.999, 1.0, 5000), np.exp(RNG.uniform(-745, 709, 5000)),
                        [0.0, -0.0, 1.0, 0.5, np.inf, np.nan, -1.0, 5e-324, 1e-310, 1.0 - 2**-53]])
EXPONENTS = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 7.3, 32.0, 100.0, 255.0, 256.0, 4096.0, -1.0, -2.5, np.inf, -np.inf,
             np.nan]
WHOLE = [1.0, 2.0, 3.0, 4.0, 32.0, 100.0, 255.0]       # binary powering (`libm._whole_power`)


def _c_pow(x: float, y: float) -> float:
    """math.pow is C's pow, with C's results where Python raises (0 ** -y:
    inf; overflow: inf; a negative base with a fractional exponent: NaN)."""
    try:
        return math.pow(x, y)
    except OverflowError:
        return math.inf
    except ValueError:
        return math.inf if x == 0 else math.nan


def bits(values) -> np.ndarray:
    return np.asarray(values, np.float64).view(np.int64)


@pytest.mark.parametrize("y", EXPONENTS)
def test_power_is_within_its_bound_of_the_c_librarys(y):
    """Where C's result is a normal float64: at most 3 + 4 |y ln x| ulp
    from it (the rounding of ln x, scaled by y: pipeline/libm.py), or for a
    whole y in [1, 256) (binary powering) y ulp (y - 1 roundings, and C's
    own half ulp); exactly C's for the special values and where C's is 0,
    inf or NaN.  A negative base is NaN (C's pow gives a value for a whole
    exponent; GLSL leaves it undefined)."""
    x = BASES[~(BASES < 0)]
    expected = np.array([_c_pow(float(v), y) for v in x])
    got = libm.power(x, y)
    normal = np.isfinite(expected) & (np.abs(expected) >= np.finfo(np.float64).tiny)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = 3 + 4 * np.nan_to_num(np.abs(y * np.log(x)), nan=0.0, posinf=np.inf)   # y = 0: 0 ln x
    if y in WHOLE:
        bound = np.full(x.shape, y)
    ulps = np.abs(bits(got) - bits(expected))
    near = ~normal | (ulps <= bound)
    assert near.all(), f"exponent {y}: {x[~near][:5]} -> {got[~near][:5]}, C {expected[~near][:5]}"
    exact = ~normal & (expected == 0) | np.isinf(expected) | np.isnan(expected)
    same = (bits(got) == bits(expected)) | (np.isnan(got) & np.isnan(expected)) | (got == expected)
    assert same[exact].all(), f"exponent {y}: {x[exact & ~same][:5]} -> {got[exact & ~same][:5]}"
    negative = libm.power(np.array([-1.0, -0.5, -np.inf]), y)
    assert (negative == 1.0).all() if y == 0 else np.isnan(negative).all()


def test_whole_exponents_take_binary_powering():
    """Whole exponents in [1, 256) are products of squares in the order of
    their bits (x^3 = x (x x), x^5 = x (x x)^2); others, 256 included, take
    exp(y ln x); and `libm.power` takes the same function as the kernels."""
    x = BASES[BASES >= 0]
    assert [libm._whole_exponent(y) for y in (1.0, 32.0, 255.0, 256.0, 0.0, 7.3, -2.0, np.nan)] == \
        [1, 32, 255, 0, 0, 0, 0, 0]
    with np.errstate(all="ignore"):
        assert np.array_equal(bits(libm.power(x, 3.0)), bits(x * (x * x)))
        assert np.array_equal(bits(libm.power(x, 5.0)), bits(x * ((x * x) * (x * x))))
        for n in WHOLE:                 # numpy's products in the documented order
            out, square = np.ones_like(x), x.copy()
            for bit in range(libm.WHOLE_BITS):
                if int(n) >> bit & 1:
                    out = out * square
                square = square * square
            assert np.array_equal(bits(libm.power(x, n)), bits(out)), n
        assert np.array_equal(bits(libm.power(x, 256.0)), bits([libm._power(v, 256.0) for v in x]))
        assert np.array_equal(bits(libm.power(x, 32.0)), bits([libm._power_by(v, 32.0, 32) for v in x]))


def test_power_is_close_where_shading_needs_it():
    """N.H in [0, 1] to the material's exponents: within 1e-13 of C's pow,
    relative (the bound above in the terms a colour reads it: a byte step
    is 1/255)."""
    x = RNG.uniform(0, 1, 100000)
    for y in (1.0, 8.0, 32.0, 128.0):
        expected = np.array([math.pow(v, y) for v in x])
        got = libm.power(x, y)
        ok = expected > np.finfo(np.float64).tiny
        assert np.allclose(got[ok], expected[ok], rtol=1e-13, atol=0)


def test_the_kernels_call_the_same_functions():
    """The kernels inline libm's scalars (no copy of their own to drift):
    the Phong kernels' pow (the exact kernel's log2 is `libm._log2` by name)."""
    assert k_light._power_by is libm._power_by and k_light._whole_exponent is libm._whole_exponent


def test_a_loop_of_power_compiles_to_simd():
    """`_power` has no call and no branch a loop cannot turn into selects:
    numba's loop of it (`libm._power_loop`, compiled afresh: a cached
    function keeps no IR) holds packed float64 arithmetic and calls no pow."""
    loop = numba.njit(error_model="numpy")(libm._power_loop.py_func)
    x = np.linspace(0, 1, 64)
    loop(x, 3.0, np.empty_like(x))
    llvm = next(iter(loop.inspect_llvm().values()))
    assert "vector.body" in llvm and " x double>" in llvm, "the loop was not vectorised"
    assert "@pow" not in llvm and "llvm.pow" not in llvm


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
