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
integration: ``actuator_steps.lag_rate`` gives the force at the interval's end and its integral. The plant
gets the *mean* force over the tick (the impulse the actuator delivers, which the plant's
zero-order-hold step then applies), and that is ``u_applied``: what a load cell in the actuator
reads, averaged over the sample period.

The range holds by construction: f starts in it and moves towards demands inside it (a lag, or a
ramp that stops at the demand, never overshoots). The rate limit holds because |df/dt| <= r
everywhere.

Variants are entries of :data:`ACTUATORS` (name -> :class:`ActuatorModel`): parameters, which
compiled step (``step``, an entry of :data:`ACTUATOR_STEPS`) and the sources of every number.
``ideal`` is today's actuator: its step passes the command unchanged, so every run without an
actuator is the same bit for bit. The steps are ``actuator_steps``; the branch on a record's step
is ``actuator_dispatch``, generated from :data:`ACTUATOR_STEPS` (``actuator_dispatch_source``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError

from .actuator_dispatch import actuator_apply

#: The compiled steps by name -> the module of their ``<step>_apply`` (actuator_steps): ideal passes
#: the command through; lag is the delay, range, rate and lag above. A new kind of actuator that is
#: not a lag is its step and one line here, then ``python -m
#: pac_plant.hardware.actuator_dispatch_source --write``.
ACTUATOR_STEPS: dict[str, str] = {
    "ideal": "pac_plant.hardware.actuator_steps",
    "lag": "pac_plant.hardware.actuator_steps",
}
#: Step name -> its code in ``ACTUATOR_PARAMS.kind`` (the registry's order).
ACTUATOR_STEP_CODES = {name: code for code, name in enumerate(ACTUATOR_STEPS)}
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
    """One actuator variant: its compiled step (an :data:`ACTUATOR_STEPS` name), its numbers and
    where they come from."""

    name: str
    step: str
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
#: step in :data:`ACTUATOR_STEPS` if it is not a lag with rate limit and delay).
ACTUATORS: dict[str, ActuatorModel] = {
    "ideal": ActuatorModel(
        "ideal",
        "ideal",
        math.inf,
        math.inf,
        0.0,
        0.0,
        "today's rig: the command is the force (the controller's own u_min, u_max, slew_rate_max "
        "are the only limits)",
    ),
    "electromechanical": ActuatorModel(
        "electromechanical",
        "lag",
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
        "lag",
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
    p["kind"], p["dt"] = ACTUATOR_STEP_CODES[model.step], sample_period
    p["low"], p["high"] = static_force - model.force_range, static_force + model.force_range
    p["rate"], p["tau"] = model.rate_limit, model.time_constant
    fraction = ticks - n
    p["delay_ticks"], p["delay_fraction"] = n, fraction if fraction > 1e-9 else 0.0
    state = np.zeros(1, ACTUATOR_STATE)
    state[0]["force"] = static_force
    state[0]["ring"][:] = static_force
    return params, state


@njit(cache=True, error_model="numpy")
def actuator_apply_one(params, state, u: float) -> float:
    """``actuator_apply`` (actuator_dispatch) on 1-element record arrays (how Python hands them over)."""
    return actuator_apply(params[0], state[0], u)


class Actuator:
    """The actuator of one plant: its records and the compiled step (``Plant.advance`` calls it)."""

    def __init__(self, model: ActuatorModel, static_force: float, sample_period: float) -> None:
        self.model = model
        self.params, self.state = actuator_records(model, static_force, sample_period)

    @property
    def ideal(self) -> bool:
        return self.model.step == "ideal"

    @property
    def force(self) -> float:
        """The force at the present tick [N] (not the tick's mean)."""
        return float(self.state[0]["force"])

    def apply(self, u: float) -> float:
        """The mean force over this tick for the command ``u`` [N] held over it."""
        return float(actuator_apply_one(self.params, self.state, float(u)))
