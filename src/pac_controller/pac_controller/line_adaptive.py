"""``line_adaptive``: span-periodic learning feedforward with an on-line identified line response.

For a distributed line (docs/catenary.md, docs/laws.md).  What the law knows: the
contact-force estimate F_hat (from the estimate: ``observer:=contact_force`` gives one
that does not assume F = k z1), the force it commands, the train speed v and the
nominal span length L.  Nothing of the line's matrices or the wire height.

The span makes the line's excitation periodic in time with period T = L / v, sampled
as N = round(T / dt) ticks, w_s = 2 pi / (N dt).  The law is the constant uplift plus a
periodic feedforward over the harmonics h = 1 .. H of w_s up to ``line_max_frequency``::

    u_k = F_r(t_k) + U_0^j + Re sum_h U_h^j exp(i h w_s (t_k + (d + 1/2) dt))       (span j)

(advanced over the d = ``design_delay_ticks`` ticks of command delay and the half
period of the hold: a feedforward can be, exactly).  Over span j the law accumulates
the Fourier coefficients of the force error e = F_r - F_hat::

    E_h^j = (2 / N) sum_{k in span j} e_k exp(-i h w_s t_k)

At the end of span j (j >= ``line_runin_spans`` - 1) each harmonic takes a secant
(Newton) step on its own identified response D_h = dE_h / dU_h (complex)::

    S_h <- lam S_h + |dU_h|^2,   Z_h <- lam Z_h + conj(dU_h) dE_h       (dU, dE: last span's changes)
    D_h = (Z_h - s0) / (S_h + s0)                (prior D = -1: F = u at low frequency, weight s0)
    |D_h| floored at ``line_response_min``
    U_h^{j+1} = U_h^j - gamma E_h^j / D_h,   each step clipped to ``line_step_max`` in modulus
                                             (``line_probe_step`` until D_h has been identified)

(lam = ``line_forgetting``, s0 = ``line_prior_weight``, gamma = ``line_learning_gain``;
an update with |dU_h| < 0.5 N carries no information and is skipped.)

Anti-windup: U_h^j in the step and in the secant is the harmonic the actuator *applied*
over span j (the Fourier coefficients of the command ``commit`` reports, on the
feedforward's own phase), not the one asked for.  Where the limits (+-500 N, 100 kN/s)
clip, asking for more changes nothing applied: the identified response would shrink, the
steps grow and the clipped share of a span grow without end (it reached 28 % at 360 km/h
and pulled the mean force 6.5 % below its target).

The mean: U_0 += gamma E_0 (E_0 the span's mean of F_r - F_hat; the static response is
-1 exactly), plus C, the mean the limits took off the last span's command, measured
exactly on the applied command and given back (C^{j+1} = mean over span j of what the
limits removed; a fixed point that converges, the clipped share being below one).  In a
periodic steady state mean(F) = mean(u) (the pantograph's momentum balance), so U_0 stays
near 0 and C is what keeps the mean force on its target when the peaks clip.  (Scaling the
whole feedforward down to stay inside the limits was tried: sigma -59 % instead of -74 % at
300 km/h; clipping the few peaks costs less.  U_0 at gain 1 instead of C oscillated span to
span with the plant's masses x1.2.)

Why identified: the line's response u -> F at the span harmonics differs from any spring
model of it by up to ~90 deg in phase and a factor 5 in gain (docs/laws.md, measured), and
with a wrong phase beyond 90 deg a fixed learning filter diverges.

Do-no-harm guard: it judges sigma_b, the span-periodic part of F_hat in the learned band,
sigma_b^2 = (1/2) sum_h |E_h|^2 over a span (Parseval): what the law acts on and what the
EN 50318 statistics keep.  (The raw sigma of F_hat is blind under sensor noise: 10 um on
z1, z2 gave sigma(F_hat) ~210 N for sigma(F) ~35 N at 250 km/h, and the guard fell back
from a law that was lowering sigma(F) by 40 %.)  The spans 1 .. ``line_runin_spans`` - 1
run passive (u = F_r) and give the passive sigma_b,p.  At the end of every learning span
the RMS of sigma_b over the last ``GUARD_SPANS`` spans is compared with it: above
``line_guard_ratio`` sigma_b,p (judged once ``line_guard_spans`` spans have been learned:
the secant learning may rise above passive for its first spans; one span above
``GUARD_HARD_FACTOR`` times that trips at once: at 220 km/h a first span at 2.1x passive
was followed by -57 % once the responses were identified, so 2 was too tight), the law
falls back to passive for the rest of the run (U = 0, ``Command.mode`` "passive"; latched).

State: explicit numpy arrays (``u_ff``, ``u_prev``, ``e_acc``, ``a_acc``, ``e_prev``, ``s``,
``z``) and scalars; :meth:`forget` forgets them all, :meth:`restart` after a fallback episode
resumes (a new run forgets).
"""

from __future__ import annotations

import math

import numpy as np

from pac_model.parameters import TrackParameters

from .controller import Errors
from .parameters import LawParameters

#: An update smaller than this [N] in a harmonic says nothing about its response.
MIN_INFORMATIVE_STEP = 0.5
#: The guard judges the RMS of the last this many spans' sigma_b (learning is not monotone span by span).
GUARD_SPANS = 3
#: One span's sigma_b above this multiple of line_guard_ratio * sigma_b,passive trips the guard at once.
GUARD_HARD_FACTOR = 3.0


class LineAdaptiveLaw:
    uses_estimate = True
    uses_contact_force = True

    def __init__(
        self,
        track: TrackParameters,
        laws: LawParameters,
        sample_period: float,
    ) -> None:
        dt = sample_period
        self.dt = dt
        self.delay = laws.design_delay_ticks
        speed = track.speed_kmh / 3.6
        self.period_ticks = n = max(2, round(track.span_length / speed / dt))
        self.omega_span = w = 2.0 * math.pi / (n * dt)
        self.harmonics = h = max(1, min(int(laws.line_max_frequency * 2.0 * math.pi / w), n // 2 - 1))
        orders = np.arange(1, h + 1)
        # basis[p, h-1] = exp(i h w p dt): one span of every harmonic, by phase index p = tick mod N.
        self.basis = np.exp(1j * np.outer(np.arange(n), orders) * w * dt)
        self.ahead = np.exp(1j * orders * w * 0.5 * dt)  # the hold's half period
        self.gain = laws.line_learning_gain
        self.step_max = laws.line_step_max
        self.probe_step = min(laws.line_probe_step, laws.line_step_max)
        self.forgetting = laws.line_forgetting
        self.prior_weight = laws.line_prior_weight
        self.response_min = laws.line_response_min
        self.runin_spans = laws.line_runin_spans
        self.guard_ratio = laws.line_guard_ratio
        self.guard_after = max(laws.line_guard_spans, GUARD_SPANS)
        self._pending_error = 0.0
        self._pending_reference = 0.0
        self.restart(None)

    # -- state -----------------------------------------------------------------------
    def restart(self, u_applied: float | None) -> None:
        """Before the first command, or after commands that were not the law's (a fallback episode).

        What was learned is the line's, not the episode's: after a fallback the law resumes with it
        (the span the episode touched is not learned from, nor judged). The ticks tell a new run
        (they start again): then it forgets everything and runs in again from u = F_r.
        """
        if u_applied is None or self.last_commit_tick is None:
            self.forget()
        else:
            self.restart_pending = True

    def forget(self) -> None:
        """Forget everything learned: the next span starts a new run-in (u = F_r, bumpless from rest)."""
        h = self.harmonics
        self.u_ff = np.zeros(h, dtype=np.complex128)  # U_h of the current span
        self.u_mean = 0.0  # U_0: the mean correction (D_0 = -1 exactly: statics)
        self.clip_offset = 0.0  # C: what the limits took off the last span's mean, added back
        self.a_mean = 0.0  # mean of (applied - F_r - U_0 - C) over the current span: minus the loss
        self.e_mean = 0.0  # E_0 accumulating over the current span
        self.u_prev = np.zeros(h, dtype=np.complex128)
        self.e_acc = np.zeros(h, dtype=np.complex128)  # E_h accumulating over the current span
        self.a_acc = np.zeros(h, dtype=np.complex128)  # A_h: the applied command's harmonics, accumulating
        self.e_prev = np.zeros(h, dtype=np.complex128)
        self.has_prev = False
        self.s = np.zeros(h)
        self.z = np.zeros(h, dtype=np.complex128)
        self.start_tick: int | None = None  # the tick the law's spans count from
        self.open_span: int | None = None  # the span whose sums are accumulating
        self.last_commit_tick: int | None = None
        self.restart_pending = False  # restarted after a fallback: resume or, on a new run, forget
        self.tainted_span: int | None = None  # a span a fallback episode touched: neither learned nor judged
        self.passive_var = 0.0
        self.passive_spans = 0
        self.recent_var = np.zeros(GUARD_SPANS)  # band variance of F_hat over the last learning spans
        self.last_sigma_ratio = 0.0
        self.tripped = False

    @property
    def mode(self) -> str:
        return "passive" if self.tripped else "active"

    def feedforward(self, tick: int) -> float:
        """U_0 + C + Re sum_h U_h exp(i h w_s (t + (d + 1/2) dt)) for the command of ``tick``."""
        phase = (tick + self.delay) % self.period_ticks
        return (
            self.u_mean
            + self.clip_offset
            + float(np.real(np.sum(self.u_ff * self.ahead * self.basis[phase])))
        )

    # -- the law -------------------------------------------------------------------
    def output(
        self,
        tick: int,
        t: float,
        f_r: np.ndarray,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,
    ) -> tuple[float, Errors]:
        error = float(f_r[0]) - contact_force_hat
        # The sample commit() accumulates (output itself changes nothing).
        self._pending_error = error
        self._pending_reference = float(f_r[0])
        new_run = self.restart_pending and self.last_commit_tick is not None and tick <= self.last_commit_tick
        u_ff = 0.0 if self.tripped or new_run else self.feedforward(tick)
        return float(f_r[0]) + u_ff, (error, u_ff, self.last_sigma_ratio)

    def commit(self, tick: int, u_applied: float) -> None:
        n = self.period_ticks
        if self.restart_pending:
            self.restart_pending = False
            if self.last_commit_tick is not None and tick <= self.last_commit_tick:
                self.forget()  # a new run
            elif self.start_tick is not None:  # resume: the episode's spans teach nothing
                self._clear_sums()
                self.open_span = None
                self.tainted_span = (tick - self.start_tick) // n
        self.last_commit_tick = tick
        if self.start_tick is None:
            self.start_tick = tick
        k = tick - self.start_tick
        if self.open_span is not None and k // n != self.open_span:
            # The open span's last tick never came (no estimate for it, live): close it now, or its
            # sums would run on into the next span and the next step be taken on two spans' worth.
            self._end_of_span(self.open_span)
        self.open_span = k // n
        phase = tick % n
        e = self._pending_error
        self.e_acc += (2.0 / n) * e * np.conj(self.basis[phase])
        # The command as the actuator's limits let it through, on the feedforward's own phase.
        applied = u_applied - self._pending_reference - self.u_mean - self.clip_offset
        self.a_acc += (2.0 / n) * applied * np.conj(self.basis[(tick + self.delay) % n])
        self.a_mean += applied / n
        self.e_mean += e / n
        if k % n == n - 1:
            self._end_of_span(k // n)
            self.open_span = None

    def _clear_sums(self) -> None:
        self.e_acc[:] = 0.0
        self.a_acc[:] = 0.0
        self.a_mean = 0.0
        self.e_mean = 0.0

    def _end_of_span(self, span: int) -> None:
        if span == self.tainted_span:
            self.tainted_span = None
            self._clear_sums()
            return
        # The guard's variance: the span-periodic part of F_hat in the learned band (Parseval on
        # E_h), what the law acts on and the EN 50318 statistics keep. The raw variance of F_hat
        # is blind under sensor noise: 10 um on z1, z2 gave sigma(F_hat) ~210 N for sigma(F) ~35 N.
        var = 0.5 * float(np.sum(np.abs(self.e_acc) ** 2))
        if 1 <= span < self.runin_spans:  # span 0 holds the start transient
            self.passive_var += var
            self.passive_spans += 1
        elif span >= self.runin_spans and self.passive_spans and not self.tripped:
            sigma_p = math.sqrt(self.passive_var / self.passive_spans)
            self.recent_var[span % GUARD_SPANS] = var
            learned = span - self.runin_spans + 1  # learning spans so far
            window = self.recent_var[: min(learned, GUARD_SPANS)]
            self.last_sigma_ratio = math.sqrt(float(np.mean(window))) / sigma_p if sigma_p > 0.0 else 0.0
            span_ratio = math.sqrt(var) / sigma_p if sigma_p > 0.0 else 0.0
            judged = learned >= self.guard_after and not self.last_sigma_ratio <= self.guard_ratio
            if judged or not span_ratio <= GUARD_HARD_FACTOR * self.guard_ratio:
                self.tripped = True
                self.u_ff[:] = 0.0
                self.u_mean = 0.0
                self.clip_offset = 0.0
        if span >= self.runin_spans - 1 and not self.tripped:
            self._learn()
        self._clear_sums()

    def _learn(self) -> None:
        """One secant step per harmonic (module docstring)."""
        # Anti-windup: step from, and identify on, the harmonics applied (module docstring).
        realized = self.a_acc / self.ahead
        if self.has_prev:
            d_u = realized - self.u_prev
            d_e = self.e_acc - self.e_prev
            informative = np.abs(d_u) > MIN_INFORMATIVE_STEP
            lam = self.forgetting
            self.s = np.where(informative, lam * self.s + np.abs(d_u) ** 2, self.s)
            self.z = np.where(informative, lam * self.z + np.conj(d_u) * d_e, self.z)
        response = (self.z - self.prior_weight) / (self.s + self.prior_weight)
        modulus = np.abs(response)
        response = np.where(
            modulus < self.response_min, self.response_min * np.exp(1j * np.angle(response)), response
        )
        step = -self.gain * self.e_acc / response
        # A harmonic whose response has not been identified yet (only the prior F = u, which can be
        # off by 180 deg) takes a probing step of at most probe_step: it identifies more than it risks.
        limit = np.where(self.s > 0.0, self.step_max, self.probe_step)
        step /= np.maximum(1.0, np.abs(step) / limit)
        self.u_prev = realized
        self.e_prev = self.e_acc.copy()
        self.has_prev = True
        self.u_mean += self.gain * self.e_mean
        # C: the mean the limits took off is known exactly from the applied command (module docstring).
        self.clip_offset = -self.a_mean
        self.u_ff = realized + step
