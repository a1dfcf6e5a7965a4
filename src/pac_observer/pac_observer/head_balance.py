"""Head-balance observer: the contact force from the head's equation of motion and its accelerometer.

``observer:=head_balance``.  For a train's sensors (``sensors:=train`` or ``train_load_cell``):
positions measured from the roof and an accelerometer on the head.  The head's equation of
motion, eq. (3) of the paper with the contact force F on the head,

    m1 z1'' = k1 (z2 - z1) + b1 (z2' - z1') - F

gives F from what is measured, with no model of the line and no dynamics to integrate::

    F_raw,k = k1 (y2,k - y1,k) + b1 (y2,k - y1,k - y2,k-1 + y1,k-1) / dt - m1 a1,k

(y the roof-relative positions: their difference is the head's spring deflection, which the car
body's motion does not enter; a1 the head accelerometer, inertial).  The positions hold the
spring's deflection only up to its rest length, so the mean comes from the pantograph's momentum
balance instead: over seconds the mean contact force is the mean actuator force (the roof spring's
and the momentum's terms are a few N)::

    F_hat,k = F_raw,k + C_k,   C_k = C_{k-1} + w_k (F_a,k - F_raw,k - C_{k-1}),
    w_k = max(1 - exp(-dt / T), 1 / (k + 1))

(T = ``head_balance_window``): the plain mean of F_a - F_raw over the samples so far until it
has T's worth, then an exponential one over T.  (An exponential mean from the first sample
carried that sample's error for seconds: at tick 0 no force has been applied yet, F_a = 0 while
the head presses with its static uplift, and the guard of line_adaptive saw F_hat's mean 40 N off
F_a one span later and fell back.)
Above 1 / (2 pi T) F_hat is the head balance, below it the actuator's force: a complementary
split.  Why: the contact-force filter (``observer:=contact_force``) integrates the positions
twice through the nominal model; with a train's 0.1 mm position noise and the roof moving under
it, its F_hat had a raw sigma of ~2000 N and 54 N of error in the 20 Hz band on the realistic line at
300 km/h (true sigma 53 N), where the head balance had 17 N (docs/laws.md, measured).

z_hat is the measured positions with their differences as velocities (roof-relative); no theta_hat
(zeros, as the contact-force filter).  State: ``hb_`` fields of the OBSERVER_STATE record; the
arithmetic is the compiled :func:`head_balance_advance`, shared with the compiled loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pac_common import divergence
from pac_common.divergence import HEAD_BALANCE_NOT_FINITE
from pac_model.parameters import PantographParameters, TrackParameters, positive_period

from .observer import (
    OBSERVER_CONSTS,
    OBSERVER_STATE,
    AdaptiveObserver,
    Estimate,
    ObserverDivergedError,
    force_estimate,
)
from .observers import OBSERVER_CODES
from .parameters import ObserverParameters


@njit(cache=True, inline="always")
def _raw_force(c, y1: float, y2: float, v1: float, v2: float, a1: float) -> float:
    """F_raw = k1 (y2 - y1) + b1 (v2 - v1) - m1 a1: eq. (3) solved for F (module docstring)."""
    return c.hb_k1 * (y2 - y1) + c.hb_b1 * (v2 - v1) - c.m1 * a1


@njit(cache=True, error_model="numpy")
def head_balance_start(st, c, y1: float, y2: float, u: float, a1: float) -> int:
    """The first sample: F_hat = the actuator's force (C_0 = F_a - F_raw), velocities 0."""
    raw = _raw_force(c, y1, y2, 0.0, 0.0, a1)
    st.hb_offset = u - raw
    st.hb_samples = 1
    return _output(st, y1, y2, 0.0, 0.0, raw)


@njit(cache=True, error_model="numpy")
def head_balance_advance(st, c, y1: float, y2: float, gap: int, u: float, a1: float) -> int:
    """y_k after ``gap`` periods (velocities over the gap); 0, or HEAD_BALANCE_NOT_FINITE (state
    untouched)."""
    span = gap * c.dt
    v1, v2 = (y1 - st.y_prev[0]) / span, (y2 - st.y_prev[1]) / span
    raw = _raw_force(c, y1, y2, v1, v2, a1)
    weight = max(1.0 - c.hb_forget**gap, gap / (st.hb_samples + gap))
    offset = st.hb_offset + weight * (u - raw - st.hb_offset)
    if not (math.isfinite(raw) and math.isfinite(offset)):
        return HEAD_BALANCE_NOT_FINITE
    st.hb_offset = offset
    st.hb_samples += gap
    return _output(st, y1, y2, v1, v2, raw)


@njit(cache=True, error_model="numpy")
def head_balance_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration) -> tuple[int, float, float]:
    """Tick k of the compiled loop (observers.py): the head balance on y_k and the head's
    acceleration (k = 0: its first sample); (status, 0, F_hat)."""
    if k == 0:
        status = head_balance_start(os, oc, y1, y2, u_applied, head_acceleration)
    else:
        status = head_balance_advance(os, oc, y1, y2, 1, u_applied, head_acceleration)
    if status:
        return status, 0.0, 0.0
    return 0, 0.0, os.cf_force


@njit(cache=True, error_model="numpy")
def _output(st, y1: float, y2: float, v1: float, v2: float, raw: float) -> int:
    force = raw + st.hb_offset
    if not math.isfinite(force):
        return HEAD_BALANCE_NOT_FINITE
    st.z_hat[0], st.z_hat[1], st.z_hat[2], st.z_hat[3] = y1, y2, v1, v2
    st.y_prev[0], st.y_prev[1] = y1, y2
    st.cf_force = force
    st.innovation[:] = 0.0
    return 0


@njit(cache=True, error_model="numpy")
def _start_one(states, consts, y1, y2, u, a1) -> int:
    return head_balance_start(states[0], consts[0], y1, y2, u, a1)


@njit(cache=True, error_model="numpy")
def _advance_one(states, consts, y1, y2, gap, u, a1) -> int:
    return head_balance_advance(states[0], consts[0], y1, y2, gap, u, a1)


class HeadBalanceObserver:
    """The estimate of the module docstring with explicit state (``state``: an OBSERVER_STATE
    record); same interface as ``AdaptiveObserver`` (update, reset, tick, consts, state)."""

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        params: ObserverParameters,
        sample_period: float,
    ) -> None:
        positive_period(sample_period)
        self.pantograph = pantograph
        self.params = params
        self.sample_period = sample_period
        #: What the compiled functions take as constants: one OBSERVER_CONSTS record.
        self.consts = np.zeros(1, OBSERVER_CONSTS)
        c = self.consts[0]
        c["kind"] = OBSERVER_CODES["head_balance"]
        c["dt"], c["m1"], c["m2"] = sample_period, pantograph.m1, pantograph.m2
        c["hb_k1"], c["hb_b1"] = pantograph.k1, pantograph.b1
        c["hb_forget"] = math.exp(-sample_period / params.head_balance_window)
        self._st = np.zeros(1, OBSERVER_STATE)
        self.reset()

    def reset(self) -> None:
        """Back to rest: the first sample starts the estimate at the actuator's force."""
        self.tick = -1
        self._st[0] = 0
        self._st[0]["z_hat"] = self.params.z_hat0

    @property
    def state(self) -> np.ndarray:
        """The OBSERVER_STATE record (a 1-element array): what the compiled loop starts from."""
        return self._st

    @property
    def z_hat(self) -> np.ndarray:
        return self._st["z_hat"][0].copy()

    @property
    def bank(self) -> tuple[np.ndarray, ...]:
        """No bank (the compiled loop's contact-force arrays are empty for this observer)."""
        return ()

    #: Updates on a copy (first sample, a tick, a gap): the compiled step loaded before the loop.
    warm_up = AdaptiveObserver.warm_up

    def update(
        self, tick: int, y: tuple[float, float], actuator_force: float, head_acceleration: float = math.nan
    ) -> Estimate:
        """Process y_k of ``tick``, the actuator's force and the head accelerometer's reading.
        Raises :class:`ObserverDivergedError` (state untouched) when the estimate is not finite
        (a suite without a head accelerometer reads NaN: refused before a run, pac_rig.composition)."""
        y1, y2, u, a1 = float(y[0]), float(y[1]), float(actuator_force), float(head_acceleration)
        if self.tick < 0:
            saved = self._st.copy()
            if _start_one(self._st, self.consts, y1, y2, u, a1):
                self._st[:] = saved
                raise ObserverDivergedError(tick, divergence.reason(HEAD_BALANCE_NOT_FINITE))
            self.tick = tick
            return self._estimate()
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        if _advance_one(self._st, self.consts, y1, y2, gap, u, a1):
            raise ObserverDivergedError(tick, divergence.reason(HEAD_BALANCE_NOT_FINITE))
        self.tick = tick
        return self._estimate()

    def _estimate(self) -> Estimate:
        return force_estimate(self.tick, self.sample_period, self._st)
