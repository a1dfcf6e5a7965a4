"""The pid law: PID on the estimated contact force, with anti-windup and a filtered derivative.

Measured variable F_hat = k_hat z_hat_1 (eq. (6) with k_hat = v(t)^T theta_hat, eq. (8)) on the
paper's observer, or the estimate's own F_hat (``force_estimate`` contact_force_hat: the
contact-force observer's state), error e = F_r - F_hat.  At tick k (h = the time since the
law's previous tick):

    P_k = Kp e_k
    D_k = Tf / (Tf + h) D_{k-1} + Kd / (Tf + h) (e_k - e_{k-1})    (Kd s / (1 + Tf s), backward Euler)
    u_k = F_r,k + P_k + I_k + D_k                                   (F_r: static balance u = F, eq. (3))
    I_{k+1} = I_k + h (Ki e_k + (u_applied,k - u_k) / Tt)           (back-calculation anti-windup)

with Kp, Ki = Kp / Ti, Kd = Kp Td, Tf = Td / N and the tracking time Tt = sqrt(Ti Td)
(Astrom & Hagglund).  u_applied is the force after the slew limit and saturation, so
the integrator stops growing while the actuator is at a limit.  A (re)start is
bumpless: I is set so that u equals the actuator's present force, and D starts at 0.

Gains (design_pid): the loop is the contact model of pac_controller.linear at
k = design_stiffness, with the command delay and the zero-order hold as a pure delay
tau = (design_delay_ticks + 1/2) dt.  With Ti = pid_integral_ratio Td and N fixed,
Td is the one value for which the phase of C(j wc) G(j wc) e^{-j wc tau} is
-180 deg + pid_phase_margin at wc = pid_bandwidth (the lower-Td branch), and Kp makes
the loop gain 1 there.  The sampled closed loop (plant, delay and this very
discretisation) is then checked to be stable; a spec a PID cannot meet is refused.
One phase margin at one crossover does not bound the loop's other resonances, so the
design also reports the maximum sensitivity Ms; the default crossover, 21 rad/s, is
the highest (in 1 rad/s steps) at 45 deg for which Ms <= 2 (docs/laws.md).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from pac_common.parameters import ParameterError
from pac_model.parameters import PantographParameters, TrackParameters

from .kernels import KernelLaw
from .linear import frequency_response, loop_with_output_feedback, spectral_radius, wrap_angle
from .parameters import LawParameters


@dataclass(frozen=True)
class PidGains:
    """Parallel-form gains, and what the design achieved."""

    kp: float  # [1] (N of force per N of error)
    ki: float  # [1/s]
    kd: float  # [s]
    tf: float  # derivative filter time constant [s]
    tt: float  # anti-windup tracking time [s]
    crossover: float  # [rad/s]
    phase_margin: float  # [deg]
    spectral_radius: float  # of the sampled closed loop at design_stiffness (< 1: stable)
    max_sensitivity: float  # Ms = max over w of |1 / (1 + L(j w))| (robustness; 1.4-2 is usual)


def _ideal_pid(w: float | np.ndarray, ti: float, td: float, n: float) -> complex | np.ndarray:
    """C(j w) / Kp of Kp (1 + 1 / (Ti s) + Td s / (1 + Td s / N))."""
    s = 1j * w
    return 1.0 + 1.0 / (ti * s) + td * s / (1.0 + td * s / n)


def discrete_pid(gains: PidGains, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(Ac, Bc, Cc, Dc) of the law above without limits and feedforward, state (I, D_prev, e_prev)."""
    a = gains.tf / (gains.tf + dt)
    b = gains.kd / (gains.tf + dt)
    ac = np.array([[1.0, 0.0, 0.0], [0.0, a, -b], [0.0, 0.0, 0.0]])
    bc = np.array([gains.ki * dt, b, 1.0])
    cc = np.array([1.0, a, -b])
    return ac, bc, cc, gains.kp + b


@functools.lru_cache(maxsize=16)  # pure; a retune of other parameters must not redesign in the loop
def design_pid(pantograph: PantographParameters, laws: LawParameters, dt: float) -> PidGains:
    """Gains from a crossover and a phase margin on the linear contact model (module docstring)."""
    wc, ratio, n = laws.pid_bandwidth, laws.pid_integral_ratio, laws.pid_derivative_filter
    tau = (laws.design_delay_ticks + 0.5) * dt
    g = complex(frequency_response(pantograph, laws.design_stiffness, wc, tau)[0])
    needed = wrap_angle(math.radians(-180.0 + laws.pid_phase_margin) - math.atan2(g.imag, g.real))

    def phase(x: float) -> float:  # x = wc Td
        c = _ideal_pid(wc, ratio * x / wc, x / wc, n)
        return math.atan2(c.imag, c.real)

    xs = np.logspace(-4, 4, 801)
    phases = np.array([phase(x) for x in xs])
    top = int(np.argmax(phases))
    if not phases[0] < needed < phases[top]:
        achievable = f"{math.degrees(phases[0]):.0f} to {math.degrees(phases[top]):.0f} deg"
        raise ParameterError(
            "pid_bandwidth",
            wc,
            f"a crossover where a PID can give the phase {math.degrees(needed):.0f} deg that "
            f"pid_phase_margin = {laws.pid_phase_margin:g} deg needs ({achievable} with "
            f"pid_integral_ratio = {ratio:g}, pid_derivative_filter = {n:g})",
        )
    import scipy.optimize  # here, not at import: a node starts without loading scipy

    x = float(scipy.optimize.brentq(lambda v: phase(v) - needed, xs[0], xs[top], xtol=1e-12))
    td = x / wc
    ti = ratio * td
    kp = 1.0 / abs(complex(_ideal_pid(wc, ti, td, n)) * g)
    gains = PidGains(
        kp=kp,
        ki=kp / ti,
        kd=kp * td,
        tf=td / n,
        tt=math.sqrt(ti * td),
        crossover=wc,
        phase_margin=laws.pid_phase_margin,
        spectral_radius=math.nan,
        max_sensitivity=math.nan,
    )
    rho = spectral_radius(
        loop_with_output_feedback(
            pantograph, laws.design_stiffness, dt, laws.design_delay_ticks, discrete_pid(gains, dt)
        )
    )
    if not rho < 1.0:
        raise ParameterError(
            "pid_bandwidth",
            wc,
            f"a crossover whose sampled closed loop is stable (spectral radius {rho:.4f})",
        )
    ws = np.logspace(-1, math.log10(math.pi / dt), 4000)
    loop = kp * _ideal_pid(ws, ti, td, n) * frequency_response(pantograph, laws.design_stiffness, ws, tau)
    ms = float(np.max(1.0 / np.abs(1.0 + loop)))
    return dataclasses.replace(gains, spectral_radius=rho, max_sensitivity=ms)


#: Step of pid_derivative_filter in :func:`least_derivative_filter`, from the parameter's floor.
DERIVATIVE_FILTER_STEP = 0.5


def least_derivative_filter(pantograph: PantographParameters, laws: LawParameters, dt: float) -> float | None:
    """The smallest derivative filter ratio N (in DERIVATIVE_FILTER_STEP steps from the parameter's
    floor up to ``laws.pid_derivative_filter``) for which :func:`design_pid` meets its crossover and
    phase margin; None if none does. The PID's gain far above the crossover is Kp (1 + N), and the
    smallest N that still gives the margin gives the smallest such gain (docs/laws.md, the FE line:
    what the loop cannot reduce, it should not pass to the actuator)."""
    floor = next(spec.low for spec in LawParameters.specs() if spec.name == "pid_derivative_filter")
    assert floor is not None, "pid_derivative_filter has a lower bound"
    for n in np.arange(floor, laws.pid_derivative_filter + 1e-9, DERIVATIVE_FILTER_STEP):
        try:
            design_pid(pantograph, dataclasses.replace(laws, pid_derivative_filter=float(n)), dt)
        except ParameterError:
            continue
        return float(n)
    return None


class PidLaw(KernelLaw):
    """The pid law core (module docstring). State (I, D, e and tick of the previous output) and
    arithmetic: ``kernels.CONTROLLER_STATE`` / ``pid_kernels``, shared with the compiled loop."""

    def __init__(
        self, gains: PidGains, track: TrackParameters, sample_period: float, force_estimate: str = "k_hat_z1"
    ) -> None:
        self.uses_contact_force = force_estimate == "contact_force_hat"  # F_hat: module docstring
        super().__init__("pid", sample_period)
        self.omega = track.omega
        self.sample_period = sample_period
        self.params[0]["omega"] = track.omega
        self.gains = gains

    @property
    def gains(self) -> PidGains:
        return self._gains

    @gains.setter
    def gains(self, gains: PidGains) -> None:
        """New gains, into the record the compiled law reads."""
        self._gains = gains
        p = self.params[0]
        p["kp"], p["ki"], p["kd"], p["tf"], p["tt"] = gains.kp, gains.ki, gains.kd, gains.tf, gains.tt
