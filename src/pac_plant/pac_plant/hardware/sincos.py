"""sin and cos of a sum of cosines' angles: the same bits on every CPU, in vector lanes.

The car body's roof motion and the turbulent uplift are sums of 400 cosines each
(``car_body``, ``turbulence``), evaluated every tick: 1200 sines and cosines a tick on the realistic
scenario, about 15 us of a 66 us tick when they called the C library's ``cos`` and ``sin`` (one call
each, which the compiler cannot put into vector lanes). Here both come from one range reduction and
two polynomials in plain double arithmetic, which a loop over the cosines runs in vector lanes, and
which rounds the same on every x86-64 CPU (no library, no fused multiply-add: numba contracts none
without fastmath).

Range reduction (Cody and Waite): x = n pi/2 + r with n = round(2 x / pi) and pi/2 split into three
parts, the first two with 33 significant bits, so that n times either is exact for |n| < 2^20
(|x| < 1.6e6 rad; the angles here stay below ~1e5: 20 Hz over an hour's run is 4.5e5). Then
|r| <= pi/4 and

    sin r = r - r^3/3! + r^5/5! - ... - r^15/15! + r^17/17!   (next term < 9e-20 of 1)
    cos r = 1 - r^2/2! + r^4/4! - ... + r^16/16!              (next term < 2e-18 of 1)

(the Taylor series: exact coefficients 1/k!, no fitted ones), in Horner form. n mod 4 picks the
quadrant. ``tests/test_sincos.py`` bounds the error against ``math.sin`` and ``math.cos`` (within
2 ulp of 1 over |x| <= 1e5) and checks the quadrants and the symmetries.
"""

from __future__ import annotations

import math

from numba import njit

#: 2 / pi, and pi / 2 as PIO2_1 + PIO2_2 + PIO2_3 (each part rounded from what the previous ones
#: leave; the first two cut to 33 significant bits, so that n * part is exact for |n| < 2^20).
TWO_OVER_PI = 2.0 / math.pi


def _split(value: float, bits: int) -> float:
    """``value`` with its significand cut to ``bits`` bits (towards zero)."""
    mantissa, exponent = math.frexp(value)
    return math.ldexp(math.floor(mantissa * 2.0**bits), exponent - bits)


# pi/2 to ~3 x 53 bits: math.pi / 2 is pi/2 rounded, its error is pi/2 - math.pi/2 = 6.123e-17
# (pi's double is 1.2246e-16 below pi, halved: exactly representable as PIO2_TAIL below).
PIO2_TAIL = 6.123233995736766e-17  # pi/2 - float(pi/2), from pi to 40 digits (test_sincos.py)
PIO2_1 = _split(math.pi / 2, 33)
PIO2_2 = _split((math.pi / 2 - PIO2_1) + PIO2_TAIL, 33)
PIO2_3 = ((math.pi / 2 - PIO2_1) - PIO2_2) + PIO2_TAIL

#: 1/k! for the odd k of sin (3 .. 17) and the even k of cos (2 .. 16), signs included.
S3, S5, S7, S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
S11, S13, S15, S17 = -1.0 / 39916800.0, 1.0 / 6227020800.0, -1.0 / 1307674368000.0, 1.0 / 355687428096000.0
C2, C4, C6, C8 = -1.0 / 2.0, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0
C10, C12, C14, C16 = -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0, 1.0 / 20922789888000.0


@njit(cache=True, inline="always")
def _reduce(x: float) -> tuple[float, int]:
    """(r, n mod 4): x = n pi/2 + r, |r| <= pi/4 (to rounding)."""
    fn = math.floor(x * TWO_OVER_PI + 0.5)
    r = ((x - fn * PIO2_1) - fn * PIO2_2) - fn * PIO2_3
    return r, int(fn) & 3


@njit(cache=True, inline="always")
def _sin_poly(r: float) -> float:
    z = r * r
    p = S15 + z * S17
    p = S13 + z * p
    p = S11 + z * p
    p = S9 + z * p
    p = S7 + z * p
    p = S5 + z * p
    p = S3 + z * p
    return r + (r * z) * p


@njit(cache=True, inline="always")
def _cos_poly(r: float) -> float:
    z = r * r
    p = C14 + z * C16
    p = C12 + z * p
    p = C10 + z * p
    p = C8 + z * p
    p = C6 + z * p
    p = C4 + z * p
    p = C2 + z * p
    return 1.0 + z * p


@njit(cache=True, inline="always")
def sin_cos(x: float) -> tuple[float, float]:
    """(sin x, cos x) from one range reduction (|x| < 1.6e6 rad; see the module's docstring)."""
    r, q = _reduce(x)
    s, c = _sin_poly(r), _cos_poly(r)
    # Quadrant q: (sin, cos) = (s, c), (c, -s), (-s, -c), (-c, s); the signs as factors (exact).
    swap = q & 1
    sign_sin = float(1 - (q & 2))
    sign_cos = float(1 - ((q + 1) & 2))
    return sign_sin * (c if swap else s), sign_cos * (s if swap else c)


@njit(cache=True, inline="always")
def sin_of(x: float) -> float:
    """sin x: ``sin_cos``'s first value (both polynomials and a select, which vector lanes take
    better than a branch)."""
    return sin_cos(x)[0]
