"""Parameters of the reference generator and the backstepping controller."""

from __future__ import annotations

from dataclasses import dataclass

from pac_common.parameters import ParameterError, ParameterSet, parameter


@dataclass(frozen=True)
class ReferenceParameters(ParameterSet):
    """Contact-force reference F_r: a piecewise-constant command through a 4th-order filter.

    Section 6 filters "a square sequence between 0 and F_N = 100 N" without giving
    the period or the filter; these are our documented choices (docs/design.md).
    """

    shape: str = parameter(
        "constant",
        "command before the filter: 'constant' (0 -> force_amplitude at t = 0), "
        "'step' (0 -> force_initial at t = 0, -> force_amplitude at step_time), "
        "'square' (force_amplitude / 0 alternating every period / 2, high first)",
        choices=("constant", "step", "square"),
        runtime=True,
    )
    force_amplitude: float = parameter(
        100.0, "F_N, the nominal contact force", "N", low=0.0, high=1000.0, runtime=True
    )
    force_initial: float = parameter(
        50.0, "first level of the 'step' shape", "N", low=0.0, high=1000.0, runtime=True
    )
    step_time: float = parameter(5.0, "time of the second level of 'step'", "s", low=0.0, runtime=True)
    period: float = parameter(4.0, "period of the 'square' shape", "s", low=0.01, high=3600.0, runtime=True)
    filter_bandwidth: float = parameter(
        20.0,
        "pole p of the critically damped filter p^4 / (s + p)^4",
        "rad/s",
        low=0.1,
        high=500.0,
        runtime=True,
    )


@dataclass(frozen=True)
class ControllerParameters(ParameterSet):
    """Backstepping gains (eqs. (28), (35), (43)), mode and actuator limits."""

    mode: str = parameter(
        "active",
        "'active': backstepping law eq. (43); 'passive': u = F_r (constant uplift, no feedback)",
        choices=("active", "passive"),
        runtime=True,
    )
    c1: float = parameter(
        40.0, "backstepping gain c1, eq. (28)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    c2: float = parameter(
        40.0, "backstepping gain c2, eq. (35)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    c3: float = parameter(
        50.0, "backstepping gain c3, eq. (43)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    u_min: float = parameter(-500.0, "actuator force lower limit", "N", low=-1e7, high=1e7, runtime=True)
    u_max: float = parameter(500.0, "actuator force upper limit", "N", low=-1e7, high=1e7, runtime=True)
    slew_rate_max: float = parameter(
        100000.0,
        "actuator force rate limit. The nominal loop needs <= 4.6 kN/s, but after a large transient "
        "(an observer restart) a limit below ~40 kN/s locks the loop in a rate-limit cycle "
        "(tests/test_offline.py::test_restart_transient_and_rate_limit)",
        "N/s",
        low=0.0,
        low_open=True,
        high=1e12,
        runtime=True,
    )
    fallback_force: float = parameter(
        100.0,
        "static uplift commanded in fallback (no fresh or no finite estimate)",
        "N",
        low=0.0,
        high=1000.0,
        runtime=True,
    )
    watchdog_ticks: int = parameter(
        20,
        "fallback after this many ticks without a fresh estimate (0: off, for lock-step runs)",
        "ticks",
        low=0,
        high=100000,
        runtime=True,
    )
    stiffness_hat_min: float = parameter(
        500.0,
        "k_hat is clamped below at this value in z1r = F_r / k_hat",
        "N/m",
        low=1.0,
        high=1e6,
        runtime=True,
    )

    def check_consistency(self) -> None:
        if self.u_max <= self.u_min:
            raise ParameterError("u_max", self.u_max, f"greater than u_min = {self.u_min:g} N")
        if not self.u_min <= self.fallback_force <= self.u_max:
            raise ParameterError(
                "fallback_force",
                self.fallback_force,
                f"within [u_min, u_max] = [{self.u_min:g}, {self.u_max:g}] N",
            )
