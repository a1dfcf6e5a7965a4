"""The offline closed loop, one compiled step: plant, observer and controller of one tick, on named records.

:func:`loop_tick` is the loop of ``closed_loop.run`` (docs/design.md, "Ticks and delays"):
at tick k the plant gives y_k and its truth, the observer updates, the controller computes
u_k, and the plant applies the command of tick k - d over [t_k, t_{k+1}].  It is written
once: ``closed_loop.run`` (the simulator, reproduce, the campaigns' per-run path) steps it
block by block, the batch (``pac_rig.batch``) runs it for many scenarios at once, and the
nodes run the same compiled functions through the core classes (``Plant``,
``AdaptiveObserver``, the laws of ``pac_controller.kernels``) — a lock-step run over DDS
gives the same numbers bit for bit (``tests/test_suite.py``).

Everything a tick reads or writes is a field of a numpy structured record
(:data:`PLANT_PARAMS`, :data:`PLANT_STATE`, ``pac_observer.observer.OBSERVER_CONSTS`` /
``OBSERVER_STATE``, ``pac_controller.kernels.CONTROLLER_PARAMS`` / ``CONTROLLER_STATE``) and
its output is one :data:`TICK` record (what the four topics carry), so a tick allocates
nothing (``tests/test_compiled.py`` counts numba's allocations over a run).

A plant, an observer or a law added later is added in one place: its record fields, its
compiled step, and the one call in :func:`loop_tick` (docs/design.md, "Adding to the loop").
A scenario whose cores have no compiled form (the FE line until its step is compiled)
returns None from :func:`compile_loop`; ``closed_loop.run`` then steps the core objects.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_controller.controller import Controller
from pac_controller.kernels import CONTROLLER_PARAMS, CONTROLLER_STATE, KernelLaw, controller_step, new_state
from pac_model import model
from pac_observer.contact_force import ContactForceObserver
from pac_observer.observer import AdaptiveObserver, observer_advance, observer_start
from pac_plant.plant import Plant, plant_advance_inplace, quantise

#: |z1|, |z2| beyond this [m] is not a pantograph any more: the run is stopped as diverged.
DIVERGENCE_DISPLACEMENT = 1.0
#: A control law asking for more than this [N] has run away (Table 1's uplift is ~100 N).
DIVERGENCE_FORCE = 1e6
#: Divergence codes of :func:`loop_tick` after the observer's (1-3, ``_DIVERGED_REASONS``).
DISPLACEMENT, FORCE = 4, 5
#: The fields of CONTROLLER_PARAMS that ``reference.reference_args`` gives, in its order.
REFERENCE_FIELDS = ("shape", "force_amplitude", "force_initial", "step_time", "period", "filter_bandwidth")
#: Most ticks of command delay the compiled loop holds.
MAX_DELAY = 64

PLANT_PARAMS = np.dtype(
    [
        ("dt", "f8"),
        ("omega", "f8"),
        ("m1", "f8"),  # the plant's own masses (they differ from the model's under a mismatch)
        ("m2", "f8"),
        ("quantisation", "f8"),
        ("noisy", "b1"),
        ("substeps", "i8"),
        ("unilateral", "b1"),
        ("a", "f8", (4, 4)),  # A of eq. (12) of the plant's pantograph
        ("theta", "f8", 3),  # the catenary's theta, eq. (9)
        ("delay", "i8"),  # command_delay_ticks
    ]
)

PLANT_STATE = np.dtype(
    [
        ("z", "f8", 4),
        ("u_applied", "f8"),  # force applied over the period that ends at this tick
        ("pending", "f8", MAX_DELAY),  # commands sent, not yet applied (a ring)
        ("head", "i8"),
    ]
)

#: One tick of a run: the fields of the four topics (closed_loop.TickRecord), plus the plant state.
TICK = np.dtype(
    [
        ("tick", "i8"),
        ("time", "f8"),
        # measurement
        ("y", "f8", 2),
        ("actuator_force", "f8"),
        # truth
        ("z", "f8", 4),
        ("stiffness", "f8"),
        ("contact_force", "f8"),
        ("in_contact", "b1"),
        ("u_applied", "f8"),
        # estimate
        ("z_hat", "f8", 4),
        ("theta_hat", "f8", 3),
        ("stiffness_hat", "f8"),
        ("contact_force_hat", "f8"),
        ("innovation", "f8", 2),
        # command
        ("u", "f8"),
        ("u_unsaturated", "f8"),
        ("force_reference", "f8"),
        ("tracking_error", "f8", 3),
        ("saturated", "b1"),
        ("mode", "i8"),  # index into pac_controller.kernels.MODES
    ]
)


@njit(cache=True, error_model="numpy")
def loop_tick(k, pp, ps, oc, os, cp, cs, n1, n2, out) -> tuple[int, float]:
    """Tick k of the closed loop, in place; ``out`` (a TICK record) gets what the topics carry.

    Returns (0, 0) or a divergence (code, value): 1-3 the observer's (the state is that of
    tick k - 1), DISPLACEMENT (value y1), FORCE (value: u demanded by the law).  n1, n2:
    this tick's sensor noise.  The order of operations is that of ``closed_loop.run_cores``
    and of the nodes.
    """
    t = k * pp.dt
    z = ps.z
    # Plant: measurement y_k (eq. (10), plus noise and quantisation) and truth.
    y1, y2 = z[0], z[1]
    if pp.noisy:
        y1, y2 = y1 + n1, y2 + n2
    y1, y2 = quantise(y1, pp.quantisation), quantise(y2, pp.quantisation)
    stiff = model.stiffness(t, pp.omega, pp.theta)
    force = model.contact_force(stiff, z[0], pp.unilateral)
    out.tick, out.time = k, t
    out.y[0], out.y[1] = y1, y2
    out.actuator_force = ps.u_applied
    out.z[:] = z
    out.stiffness, out.contact_force, out.in_contact, out.u_applied = stiff, force, force > 0.0, ps.u_applied
    if not (abs(y1) < DIVERGENCE_DISPLACEMENT and abs(y2) < DIVERGENCE_DISPLACEMENT):
        return DISPLACEMENT, y1
    # Observer, eq. (17).
    if k == 0:
        observer_start(os, y1, y2)
    else:
        status, _ = observer_advance(k - 1, os, y1, y2, 1, ps.u_applied, oc)
        if status:
            return status, np.nan
    out.z_hat[:] = os.z_hat
    out.theta_hat[:] = os.theta_hat
    k_hat = model.stiffness(t, oc.omega, os.theta_hat)
    out.stiffness_hat, out.contact_force_hat = k_hat, k_hat * y1
    out.innovation[:] = os.innovation
    # Controller: law and safety chain.
    u, u_law, f_r, e1, e2, e3, mode = controller_step(cp, cs, k, os.z_hat, os.theta_hat)
    if not abs(u_law) < DIVERGENCE_FORCE:
        return FORCE, u_law
    out.u, out.u_unsaturated, out.force_reference = u, u_law, f_r
    out.tracking_error[0], out.tracking_error[1], out.tracking_error[2] = e1, e2, e3
    out.saturated, out.mode = u != u_law, mode
    # Command delay, then the plant over [t_k, t_k+1] (zero-order hold).
    if pp.delay == 0:
        applied = u
    else:
        applied = ps.pending[ps.head]
        ps.pending[ps.head] = u
        ps.head = (ps.head + 1) % pp.delay
    plant_advance_inplace(
        z, t, pp.dt, pp.substeps, applied, pp.a, pp.theta, pp.omega, pp.m1, pp.m2, pp.unilateral
    )
    ps.u_applied = applied
    return 0, 0.0


@njit(cache=True, error_model="numpy")
def run_ticks(k0, k1, pp, ps, oc, os, cp, cs, noise, out) -> tuple[int, int, float]:
    """Ticks k0..k1-1 into ``out[k - k0]``; (ticks reached, divergence code, value).

    ``noise[k - k0]`` is tick k's sensor noise (a single row when the plant is noiseless).
    """
    for k in range(k0, k1):
        i = min(k - k0, noise.shape[0] - 1)
        code, value = loop_tick(k, pp, ps, oc, os, cp, cs, noise[i, 0], noise[i, 1], out[k - k0])
        if code:
            return k, code, value
    return k1, 0, 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def run_block(k0, k1, pp, ps, oc, os, cp, cs, noise, out) -> tuple[int, int, float]:
    """:func:`run_ticks` on the records of 1-element arrays (how Python hands them over)."""
    return run_ticks(k0, k1, pp[0], ps[0], oc[0], os[0], cp[0], cs[0], noise, out)


@dataclass
class CompiledLoop:
    """The records of one run: parameters and states, each a 1-element structured array."""

    plant_params: np.ndarray
    plant_state: np.ndarray
    observer_consts: np.ndarray
    observer_state: np.ndarray
    controller_params: np.ndarray
    controller_state: np.ndarray

    def run(self, k0: int, k1: int, noise: np.ndarray, out: np.ndarray) -> tuple[int, int, float]:
        """Ticks k0..k1-1 into ``out`` (a TICK array); (ticks reached, divergence code, value)."""
        return run_block(
            k0, k1, self.plant_params, self.plant_state, self.observer_consts, self.observer_state,
            self.controller_params, self.controller_state, noise, out,
        )  # fmt: skip


def compile_loop(
    plant: Plant, observer: AdaptiveObserver | ContactForceObserver, controller: Controller, delay: int
) -> CompiledLoop | None:
    """The records of the cores as built (``closed_loop.build_cores``), or None if the loop has no
    compiled form for them: a plant other than the lumped :class:`Plant` (the FE line), an observer
    other than :class:`AdaptiveObserver`, a law without kernel (not a :class:`KernelLaw`)."""
    if (
        type(plant) is not Plant
        or type(observer) is not AdaptiveObserver
        or type(controller) is not Controller
    ):
        return None
    if not isinstance(controller.law, KernelLaw) or not 0 <= delay <= MAX_DELAY:
        return None
    pp = np.zeros(1, PLANT_PARAMS)
    p = pp[0]
    p["dt"], p["omega"] = plant.sample_period, plant._omega
    p["m1"], p["m2"] = plant.pantograph.m1, plant.pantograph.m2
    p["quantisation"], p["noisy"] = plant.options.quantisation, plant._noisy
    p["substeps"], p["unilateral"] = plant.options.substeps, plant._unilateral
    p["a"], p["theta"], p["delay"] = plant._a, plant._theta, delay
    ps = np.zeros(1, PLANT_STATE)
    ps[0]["z"], ps[0]["u_applied"] = plant.z, plant.u_applied
    cp = controller.law.params.copy()
    c, chain = cp[0], controller.params
    c["dt"] = controller.sample_period
    c["slew_rate_max"], c["u_min"], c["u_max"] = chain.slew_rate_max, chain.u_min, chain.u_max
    c["fallback_force"] = chain.fallback_force
    for name, value in zip(REFERENCE_FIELDS, controller.reference.args, strict=True):
        c[name] = value
    cs = np.zeros(1, CONTROLLER_STATE)
    new_state(cs)
    return CompiledLoop(pp, ps, observer.consts.copy(), observer.state.copy(), cp, cs)


__all__ = ["CONTROLLER_PARAMS", "TICK", "CompiledLoop", "compile_loop", "loop_tick", "run_ticks"]
