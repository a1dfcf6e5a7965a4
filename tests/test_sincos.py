"""The car body's and the turbulence's sin and cos (pac_plant.hardware.sincos) against an
independent reference: the Taylor series in 50-digit decimal arithmetic, with pi to 60 digits."""

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest
from numba import njit

from pac_plant.hardware import sincos

pytestmark = pytest.mark.unit

PI = Decimal("3.141592653589793238462643383279502884197169399375105820974944592")
#: One unit in the last place of 1: the bound on the absolute error (the polynomials' truncation is
#: below 1e-17; the reduction and Horner's rounding stay within an ulp of the result, at most 1).
ULP_OF_ONE = 2.0**-52


def exact_sin_cos(x: float) -> tuple[float, float]:
    """sin x and cos x of the double x (exactly as given), rounded from 50 digits."""
    with localcontext() as ctx:
        ctx.prec = 50
        r = Decimal(x) % (2 * PI)  # exact x, reduced with pi to 60 digits
        s, c = Decimal(0), Decimal(0)
        # sum_k (-1)^k r^(2k+1) / (2k+1)!  and  sum_k (-1)^k r^(2k) / (2k)!
        sin_term, cos_term = r, Decimal(1)
        for k in range(60):
            s += sin_term
            c += cos_term
            sin_term *= -r * r / ((2 * k + 2) * (2 * k + 3))
            cos_term *= -r * r / ((2 * k + 1) * (2 * k + 2))
        return float(s), float(c)


@njit(cache=False)
def _both(x, s, c, s_only):
    for i in range(x.shape[0]):
        s[i], c[i] = sincos.sin_cos(x[i])
        s_only[i] = sincos.sin_of(x[i])


def _arguments() -> np.ndarray:
    rng = np.random.default_rng(7)
    quadrant_edges = np.arange(-40, 41) * (math.pi / 4)  # where the reduction picks a quadrant
    return np.concatenate(
        [
            rng.uniform(-1e5, 1e5, 600),  # an hour at 20 Hz is 4.5e5 rad; a 34 s run at 300 km/h ~1e4
            rng.uniform(-10.0, 10.0, 600),
            quadrant_edges,
            np.nextafter(quadrant_edges, np.inf),
            np.nextafter(quadrant_edges, -np.inf),
            [0.0, 1e-300, -1e-12, math.pi, 2 * math.pi, 1.0e5 * math.pi],
        ]
    )


def test_sin_and_cos_within_an_ulp_of_one_of_the_exact_values():
    """Absolute error at most one ulp of 1 on 1300 arguments over |x| <= 3.2e5, the quadrant edges
    and their neighbours among them; sin_of gives sin_cos's sine to the bit."""
    x = _arguments()
    s, c, s_only = np.empty_like(x), np.empty_like(x), np.empty_like(x)
    _both(x, s, c, s_only)
    exact = np.array([exact_sin_cos(float(v)) for v in x])
    err_sin, err_cos = np.abs(s - exact[:, 0]), np.abs(c - exact[:, 1])
    assert err_sin.max() <= ULP_OF_ONE, (x[np.argmax(err_sin)], err_sin.max())
    assert err_cos.max() <= ULP_OF_ONE, (x[np.argmax(err_cos)], err_cos.max())
    np.testing.assert_array_equal(s_only, s)


def test_the_library_agrees_to_an_ulp_of_one_too():
    """math.sin and math.cos (the C library, what the kernels called before) within the same
    bound of the same exact values: the reference is not what tells them apart."""
    for v in _arguments()[:200]:
        s, c = exact_sin_cos(float(v))
        assert abs(math.sin(v) - s) <= ULP_OF_ONE and abs(math.cos(v) - c) <= ULP_OF_ONE


def test_pi_over_two_in_three_parts():
    """PIO2_1 + PIO2_2 + PIO2_3 is pi/2 to 1e-32, and the first two parts have 33 significant bits
    (so that n times either is exact for |n| < 2^20)."""
    with localcontext() as ctx:
        ctx.prec = 60
        rest = PI / 2 - Decimal(sincos.PIO2_1) - Decimal(sincos.PIO2_2) - Decimal(sincos.PIO2_3)
        assert abs(rest) < Decimal("1e-32")
        assert abs(PI / 2 - Decimal(math.pi / 2) - Decimal(sincos.PIO2_TAIL)) < Decimal("1e-32")
    for part in (sincos.PIO2_1, sincos.PIO2_2):
        mantissa, _ = math.frexp(part)
        assert mantissa * 2.0**33 == math.floor(mantissa * 2.0**33)
