"""The actuator as hardware: what force the pantograph gets for the force the controller commands.

The controller's command u_k is held over [t_k, t_k+1] (the loop's zero-order hold, after its
``command_delay_ticks``). A real actuator does not pass it on unchanged (docs/vehicle_and_hardware.md,
"The actuator"); the model here, per tick of length h:

* **transport delay** D = (n + phi) h (0 <= phi < 1): the demand over [t_k, t_k + phi h) is
  u_(k-n-1), over [t_k + phi h, t_k+1) it is u_(k-n) (the held commands shifted by D exactly,
  a fractional D included);
* **force range** about the static force F0 (the pneumatic uplift the fast actuator acts on top
  of): the demand is clipped to [F0 - R, F0 + R];
* **first-order lag** tau with a **rate limit** r: df/dt = clip((d - f) / tau, -r, r).

Over an interval of constant demand d that ODE has a closed form (a ramp at +-r while
|d - f| > r tau, then the exponential d - (d - f) exp(-t / tau)), so the step is exact, not an
integration: :func:`lag_rate` gives the force at the interval's end and its integral. The plant
gets the *mean* force over the tick (the impulse the actuator delivers, which the plant's
zero-order-hold step then applies), and that is ``u_applied``: what a load cell in the actuator
reads, averaged over the sample period.

The range holds by construction: f starts in it and moves towards demands inside it (a lag, or a
ramp that stops at the demand, never overshoots). The rate limit holds because |df/dt| <= r
everywhere.

Variants are entries of :data:`ACTUATORS` (name -> :class:`ActuatorModel`): parameters, which
compiled step (``kind``) and the sources of every number. ``ideal`` is today's actuator: the
command passes unchanged (its step is never called, so every run without an actuator is the same
bit for bit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError

#: ActuatorModel.kind: IDEAL passes the command through; LAG is the delay, range, rate and lag above.
IDEAL, LAG = 0, 1
#: Most ticks of transport delay the compiled state holds (256 ms at the default 1 kHz).
MAX_ACTUATOR_DELAY_TICKS = 256
_RING = MAX_ACTUATOR_DELAY_TICKS + 2  # u_(k-n-1) .. u_k

ACTUATOR_PARAMS = np.dtype(
    [
        ("kind", "i8"),
        ("dt", "f8"),
        ("low", "f8"),  # F0 - R [N]
        ("high", "f8"),  # F0 + R [N]
        ("rate", "f8"),  # r [N/s] (inf: none)
        ("tau", "f8"),  # [s]
        ("delay_ticks", "i8"),  # n
        ("delay_fraction", "f8"),  # phi in [0, 1)
    ]
)

ACTUATOR_STATE = np.dtype(
    [
        ("force", "f8"),  # f at the present tick [N]
        ("ring", "f8", _RING),  # commands, u_k at ``head``
        ("head", "i8"),
    ]
)


@dataclass(frozen=True)
class ActuatorModel:
    """One actuator variant: its compiled step (``kind``), its numbers and where they come from."""

    name: str
    kind: int
    #: R: the force it can add to or take from the static force F0 [N] (inf: unlimited).
    force_range: float
    #: r [N/s] (inf: unlimited).
    rate_limit: float
    #: tau of the first-order lag [s].
    time_constant: float
    #: D [s].
    delay: float
    #: Where each number comes from (docs/vehicle_and_hardware.md repeats it).
    sources: str


#: The actuator variants by name (the ``actuator`` parameter). A new one is a line here (and its
#: compiled step in :func:`actuator_apply` if it is not a lag with rate limit and delay).
ACTUATORS: dict[str, ActuatorModel] = {
    "ideal": ActuatorModel(
        "ideal",
        IDEAL,
        math.inf,
        math.inf,
        0.0,
        0.0,
        "today's rig: the command is the force (the controller's own u_min, u_max, slew_rate_max "
        "are the only limits)",
    ),
    "electromechanical": ActuatorModel(
        "electromechanical",
        LAG,
        100.0,
        5000.0,
        0.020,
        0.005,
        "a linear motor or ball screw on top of the pneumatic uplift; judgement (no published "
        "datasheet): +-100 N about the pneumatic force and 5-10 kN/s, lag 10-30 ms, delay 5-10 ms "
        "(the range HIL rigs prove real actuators in: Facchinetti, Gasparetto, Bruni, VSD 51(4) "
        "2013; Schirrer et al., Mechatronics 41, 2017). Taken: 100 N, the slow end of the rate "
        "(5 kN/s, the figure the ideal rig was measured with), tau 20 ms (the middle), delay 5 ms "
        "(the fast end: a drive on the roof, fibre link to the head sensors counted in the sensors)",
    ),
    "pneumatic": ActuatorModel(
        "pneumatic",
        LAG,
        100.0,
        500.0,
        0.200,
        0.020,
        "the pantograph's own air-spring uplift under a fast valve; judgement: lag 100-300 ms "
        "(docs/catenary_data.md section 9), taken 200 ms (the middle); +-100 N as the "
        "electromechanical one (a bellows can give more, the control question is the same); "
        "a 20 ms delay and 500 N/s are judgement for a valve feeding a bellows through a hose "
        "(the valve's switching, then air at the speed of sound, ~3 ms per metre of hose); the "
        "flow through the valve caps the rate: 500 N/s binds on errors above r tau = 100 N, half "
        "the range (at 1 kN/s the lag alone would never reach the limit within the range)",
    ),
}


def actuator_model(name: str) -> ActuatorModel:
    """The variant ``name`` of :data:`ACTUATORS`; a ParameterError (one line) for another name."""
    model = ACTUATORS.get(name)
    if model is None:
        raise ParameterError("actuator", name, "one of " + ", ".join(ACTUATORS))
    return model


def actuator_records(
    model: ActuatorModel, static_force: float, sample_period: float
) -> tuple[np.ndarray, np.ndarray]:
    """The parameter and state records (1-element arrays) of ``model`` at the static force
    F0 = ``static_force`` [N]: at rest, holding F0 (the pneumatic uplift is on before the run)."""
    name = model.name
    ticks = model.delay / sample_period
    n = math.floor(ticks + 1e-9)  # 5 ms at 1 kHz is 5 ticks, not 4 + 0.99999
    if n > MAX_ACTUATOR_DELAY_TICKS:
        raise ParameterError(
            "actuator", name, f"a transport delay of at most {MAX_ACTUATOR_DELAY_TICKS} sample periods"
        )
    params = np.zeros(1, ACTUATOR_PARAMS)
    p = params[0]
    p["kind"], p["dt"] = model.kind, sample_period
    p["low"], p["high"] = static_force - model.force_range, static_force + model.force_range
    p["rate"], p["tau"] = model.rate_limit, model.time_constant
    fraction = ticks - n
    p["delay_ticks"], p["delay_fraction"] = n, fraction if fraction > 1e-9 else 0.0
    state = np.zeros(1, ACTUATOR_STATE)
    state[0]["force"] = static_force
    state[0]["ring"][:] = static_force
    return params, state


@njit(cache=True, error_model="numpy")
def lag_rate(f0: float, d: float, h: float, tau: float, rate: float) -> tuple[float, float]:
    """(f(h), integral of f over [0, h]) for df/dt = clip((d - f) / tau, -rate, rate), f(0) = f0.

    While |d - f| > rate tau the rate limit binds (a ramp); from there the lag's own rate is below
    it and f = d - (d - f1) exp(-t / tau). tau = 0: a ramp to d, then d. rate = inf: no ramp.
    """
    e = d - f0
    sign = 1.0 if e >= 0.0 else -1.0
    knee = rate * tau if rate < np.inf else np.inf
    integral = 0.0
    rest = h
    f = f0
    if abs(e) > knee:
        ramp = (abs(e) - knee) / rate  # time until the lag takes over
        if ramp >= h:
            return f0 + sign * rate * h, f0 * h + 0.5 * sign * rate * h * h
        integral = f0 * ramp + 0.5 * sign * rate * ramp * ramp
        f = d - sign * knee
        rest = h - ramp
        e = d - f
    if tau > 0.0:
        g = math.exp(-rest / tau)
        return d - e * g, integral + d * rest - e * tau * (1.0 - g)
    return d, integral + d * rest


@njit(cache=True, error_model="numpy")
def actuator_apply(p, s, u: float) -> float:
    """The mean force over this tick for the command ``u`` held over it; advances ``s``.

    IDEAL returns ``u`` itself (not u * h / h): today's numbers, bit for bit.
    """
    if p.kind == IDEAL:
        return u
    ring = s.ring
    size = ring.shape[0]
    s.head = (s.head + 1) % size
    ring[s.head] = u
    n = p.delay_ticks
    h = p.dt
    late = min(max(ring[(s.head - n) % size], p.low), p.high)  # u_(k-n), clipped to the range
    f, total = s.force, 0.0
    if p.delay_fraction > 0.0:
        early = min(max(ring[(s.head - n - 1) % size], p.low), p.high)  # u_(k-n-1)
        h1 = p.delay_fraction * h
        f, part = lag_rate(f, early, h1, p.tau, p.rate)
        total += part
        h -= h1
    f, part = lag_rate(f, late, h, p.tau, p.rate)
    s.force = f
    return (total + part) / p.dt


@njit(cache=True, error_model="numpy")
def actuator_apply_one(params, state, u: float) -> float:
    """:func:`actuator_apply` on 1-element record arrays (how Python hands them over)."""
    return actuator_apply(params[0], state[0], u)


class Actuator:
    """The actuator of one plant: its records and the compiled step (``Plant.advance`` calls it)."""

    def __init__(self, model: ActuatorModel, static_force: float, sample_period: float) -> None:
        self.model = model
        self.params, self.state = actuator_records(model, static_force, sample_period)

    @property
    def ideal(self) -> bool:
        return int(self.params[0]["kind"]) == IDEAL

    @property
    def force(self) -> float:
        """The force at the present tick [N] (not the tick's mean)."""
        return float(self.state[0]["force"])

    def apply(self, u: float) -> float:
        """The mean force over this tick for the command ``u`` [N] held over it."""
        return float(actuator_apply_one(self.params, self.state, float(u)))
