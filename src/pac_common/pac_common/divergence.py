"""Why a closed loop stopped: the status codes of the compiled steps, in one public table.

A compiled step (an observer's advance, the loop's tick) returns 0 or one of these codes and never
raises; the Python fronts (the observer classes, ``pac_rig.closed_loop``, the batch) turn a code
into its exception with :func:`reason`. One table, so that a code means the same thing wherever it
is read: in the observer node, the offline loop, the batch and a campaign's row.

The numba-compiled steps read these names as compile-time constants.
"""

from __future__ import annotations

import math

OK = 0
#: The paper's observer (pac_observer.observer, eq. (17)): its gain xi or Lambda is not finite.
OBSERVER_GAIN_NOT_FINITE = 1
#: The paper's observer: S_theta is not positive definite (its Cholesky factorisation failed).
COVARIANCE_NOT_POSITIVE = 2
#: The paper's observer: theta_hat is not finite.
THETA_NOT_FINITE = 3
#: The loop: |z1| or |z2| beyond DIVERGENCE_DISPLACEMENT (the value: y1).
DISPLACEMENT = 4
#: The loop: the law demanded more than DIVERGENCE_FORCE (the value: its demand).
FORCE = 5
#: The contact-force observer (pac_observer.contact_force): the selected filter's state is not finite.
CONTACT_FORCE_NOT_FINITE = 6
#: The loop: the pantograph ran off the FE line's end (the value: the contact point's x).
OFF_LINE = 7
#: The head-balance observer (pac_observer.head_balance): its estimate is not finite.
HEAD_BALANCE_NOT_FINITE = 8
#: The compiled loop: the observer's record names no compiled observer (OBSERVER_CONSTS.kind).
UNKNOWN_OBSERVER = 9
#: The compiled loop: the plant's record names no compiled plant (PLANT_PARAMS.kind).
UNKNOWN_PLANT = 10

#: |z1|, |z2| beyond this [m] is not a pantograph any more: the run is stopped as diverged.
DIVERGENCE_DISPLACEMENT = 1.0
#: A control law asking for more than this [N] has run away (Table 1's uplift is ~100 N).
DIVERGENCE_FORCE = 1e6

#: Every code but OK, and what it means (DISPLACEMENT, FORCE and OFF_LINE add the value: :func:`reason`).
REASONS: dict[int, str] = {
    OBSERVER_GAIN_NOT_FINITE: "xi or Lambda is not finite",
    COVARIANCE_NOT_POSITIVE: "S_theta not positive definite (Cholesky failed)",
    THETA_NOT_FINITE: "theta_hat is not finite",
    DISPLACEMENT: f"|z| exceeded {DIVERGENCE_DISPLACEMENT} m",
    FORCE: f"|u| demanded by the law exceeded {DIVERGENCE_FORCE:g} N",
    CONTACT_FORCE_NOT_FINITE: "the contact-force state is not finite",
    OFF_LINE: "the pantograph ran off the line",
    HEAD_BALANCE_NOT_FINITE: "the head-balance estimate is not finite (a head accelerometer reading NaN)",
    UNKNOWN_OBSERVER: "the observer's record names no compiled observer",
    UNKNOWN_PLANT: "the plant's record names no compiled plant",
}


def reason(code: int, value: float = math.nan) -> str:
    """The text of ``code`` (a key of :data:`REASONS`), with the value the step returned beside it."""
    if code == DISPLACEMENT:
        return f"{REASONS[code]} (z1={value:.3g})"
    if code == FORCE:
        return f"{REASONS[code]} ({value:.3g} N)"
    if code == OFF_LINE:
        return f"{REASONS[code]} at x = {value:.2f} m"
    return REASONS[code]
