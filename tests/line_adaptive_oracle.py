"""line_adaptive as it was before it was compiled (numpy array expressions, commit 2519b0b).

A test oracle only: ``tests/test_line_kernels.py`` checks the shipped law (compiled) against it,
so a change to what the law computes shows up as a disagreement.
"""

from __future__ import annotations

import math

import numpy as np

from pac_controller.controller import Errors
from pac_controller.line_adaptive import line_model_rows
from pac_controller.parameters import LawParameters
from pac_model.parameters import PantographParameters, TrackParameters

#: An update smaller than this [N] in a harmonic says nothing about its response.
MIN_INFORMATIVE_STEP = 0.5
#: The guard judges the RMS of the last this many spans' sigma_b (learning is not monotone span by span).
GUARD_SPANS = 3
#: One span's sigma_b above this multiple of line_guard_ratio * sigma_b,passive trips the guard at once.
GUARD_HARD_FACTOR = 3.0
#: A back-off scales the learned harmonics by this.
GUARD_BACKOFF = 0.5


class LineAdaptiveLaw:
    uses_estimate = True
    uses_contact_force = True

    def __init__(
        self,
        track: TrackParameters,
        laws: LawParameters,
        sample_period: float,
        pantograph: PantographParameters | None = None,
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
        self.effort_weight = laws.line_effort_weight
        self.model_below = laws.line_model_below
        self.model_c, self.model_b, self.model_det, hold, omega = line_model_rows(
            pantograph or PantographParameters(), orders * w, dt
        )
        self.model_hold, self.model_omega = hold.real, omega.real
        self.runin_spans = laws.line_runin_spans
        self.guard_ratio = laws.line_guard_ratio
        self.guard_after = max(laws.line_guard_spans, GUARD_SPANS)
        self.guard_bias, self.guard_loss = laws.line_guard_bias, laws.line_guard_loss
        self.loss_margin = laws.line_guard_loss_margin
        self.guard_saturation, self.guard_strikes = laws.line_guard_saturation, laws.line_guard_strikes
        self.guard_loss_after = laws.line_guard_loss_spans
        self._pending_measured = math.nan
        self._pending_law = 0.0
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
        self.line_stiffness = 0.0  # the line model Z = k_s + i c w
        self.line_damping = 0.0
        self.model_valid = False
        self.passive_loss = 0.0  # the largest share of F_hat nearly lost over the passive spans
        self.strikes = 0  # back-offs on contact loss (the trip counts them)
        self.saturation_backoffs = 0
        self.last_bias = 0.0  # mean of F_hat - F_applied over the last judged span
        self.trip_reason = ""
        self.fade_from = -1  # the tick the guard tripped: the feedforward fades out over one span
        self.backoff_from = -1  # the tick a back-off's ramp started
        self._clear_sums()

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
        actuator_force: float = math.nan,
    ) -> tuple[float, Errors]:
        error = float(f_r[0]) - contact_force_hat
        # The sample commit() accumulates (output itself changes nothing).
        self._pending_error = error
        self._pending_reference = float(f_r[0])
        self._pending_measured = actuator_force
        new_run = self.restart_pending and self.last_commit_tick is not None and tick <= self.last_commit_tick
        fade = max(0.0, 1.0 - (tick - self.fade_from) / self.period_ticks) if self.tripped else 1.0
        if self.backoff_from >= 0:
            ramp = min(1.0, max(0.0, (tick - self.backoff_from) / self.period_ticks))
            fade *= 1.0 - (1.0 - GUARD_BACKOFF) * ramp
        u_ff = 0.0 if fade <= 0.0 or new_run else fade * self.feedforward(tick)
        self._pending_law = float(f_r[0]) + u_ff
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
        told = math.isfinite(self._pending_measured)
        self.e_mean += (self._pending_reference - self._pending_measured if told else e) / n
        f_hat = self._pending_reference - e
        measured = self._pending_measured if told else u_applied
        self.span_ticks += 1
        self.bias_sum += f_hat - measured
        self.reference_sum += self._pending_reference
        self.loss_ticks += f_hat - self.last_bias <= self.loss_margin * self._pending_reference
        self.clip_ticks += u_applied != self._pending_law
        if k % n == n - 1:
            self._end_of_span(k // n)
            self.open_span = None

    def _clear_sums(self) -> None:
        self.e_acc[:] = 0.0
        self.a_acc[:] = 0.0
        self.a_mean = 0.0
        self.e_mean = 0.0
        self.span_ticks, self.bias_sum, self.reference_sum = 0, 0.0, 0.0
        self.loss_ticks, self.clip_ticks = 0, 0

    def _trip(self, reason: str) -> None:
        self.tripped, self.trip_reason, self.fade_from = True, reason, self.last_commit_tick

    def _end_of_span(self, span: int) -> None:
        if span == self.tainted_span:
            self.tainted_span = None
            self._clear_sums()
            return
        # The guard's variance: the span-periodic part of F_hat in the learned band (Parseval on
        # E_h), what the law acts on and the EN 50318 statistics keep. The raw variance of F_hat
        # is blind under sensor noise: 10 um on z1, z2 gave sigma(F_hat) ~210 N for sigma(F) ~35 N.
        var = 0.5 * float(np.sum(np.abs(self.e_acc) ** 2))
        ticks = max(self.span_ticks, 1)
        loss, bias = self.loss_ticks / ticks, self.bias_sum / ticks
        reference = self.reference_sum / ticks
        if span >= 2 and not self.tripped and not abs(bias) <= self.guard_bias * abs(reference):
            self._trip("bias")  # the momentum balance: mean F_hat against the mean actuator force
        self.last_bias = bias if span >= 1 else 0.0
        back_off = False
        if 1 <= span < self.runin_spans:  # span 0 holds the start transient
            self.passive_var += var
            self.passive_spans += 1
            self.passive_loss = max(self.passive_loss, loss)
        elif span >= self.runin_spans and self.passive_spans and not self.tripped:
            sigma_p = math.sqrt(self.passive_var / self.passive_spans)
            self.recent_var[span % GUARD_SPANS] = var
            learned = span - self.runin_spans + 1  # learning spans so far
            window = self.recent_var[: min(learned, GUARD_SPANS)]
            self.last_sigma_ratio = math.sqrt(float(np.mean(window))) / sigma_p if sigma_p > 0.0 else 0.0
            span_ratio = math.sqrt(var) / sigma_p if sigma_p > 0.0 else 0.0
            judged = learned >= self.guard_after and not self.last_sigma_ratio <= self.guard_ratio
            if judged or not span_ratio <= GUARD_HARD_FACTOR * self.guard_ratio:
                self._trip("harm")
            else:
                early = learned < self.guard_loss_after  # the learning's first spans: the hard bar
                if loss > self.passive_loss + (GUARD_HARD_FACTOR if early else 1.0) * self.guard_loss:
                    self.strikes += 1
                    if self.strikes >= self.guard_strikes:
                        self._trip("loss")
                    else:
                        back_off = True
                elif self.clip_ticks / ticks > self.guard_saturation:  # backs off, never trips
                    self.saturation_backoffs += 1
                    back_off = True
        if self.backoff_from >= 0:  # the span that ramped a back-off down: halved, nothing learned
            self.backoff_from = -1
            self.u_ff = GUARD_BACKOFF * self.u_ff
        elif span >= self.runin_spans - 1 and not self.tripped:
            self._learn()
            if back_off:
                self.backoff_from = self.last_commit_tick + 1
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
        identified = (self.z - self.prior_weight) / (self.s + self.prior_weight)
        modulus = np.abs(identified)
        response = np.where(
            modulus < self.response_min, self.response_min * np.exp(1j * np.angle(identified)), identified
        )
        if self.model_below > 0.0:
            c, b, det, omega = self.model_c, self.model_b, self.model_det, self.model_omega
            d = -identified / self.model_hold
            samples = d * det / (c - d * b)
            q = (self.line_stiffness + 1j * (self.line_damping * omega)) * b + det
            g = np.abs(c * det / (q * q))
            weight = self.s * (g * g)
            finite = np.isfinite(samples) & np.isfinite(weight)
            weight, samples = np.where(finite, weight, 0.0), np.where(finite, samples, 0.0)
            total = np.sum(weight)
            if total > 0.0:
                stiffness = np.sum(weight * samples.real) / total
                damping = np.sum(weight * omega * samples.imag) / np.sum(weight * (omega * omega))
                self.line_stiffness, self.line_damping = max(stiffness, 0.0), max(damping, 0.0)
            z = self.line_stiffness + 1j * (self.line_damping * omega)
            model = z * c / (z * b + det) * self.model_hold
            if total > 0.0:
                self.model_valid = bool(np.abs(model[0]) >= self.model_below)
            if self.model_valid:
                response = np.where(np.abs(model) < self.model_below, -model, response)
        mu = self.effort_weight
        step = -self.gain * (np.conj(response) * self.e_acc + mu * realized) / (np.abs(response) ** 2 + mu)
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
