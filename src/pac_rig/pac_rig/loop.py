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

Every plant, observer and law of pac's registries has its compiled form: each plant's
(``pac_plant.plants.PLANTS``: the lumped line and the FE line, ``plant_kernels``' protocol),
each observer's (``pac_observer.observers.OBSERVERS``) and each kernel law's
(``pac_controller.laws.LAWS``). Which one a tick runs is a field of the records
(``PLANT_PARAMS.kind``, ``OBSERVER_CONSTS.kind``, ``CONTROLLER_PARAMS.law``), so one compiled
function serves every combination; the branches on those codes are generated from the
registries (``plant_dispatch``, ``observer_dispatch``, ``law_dispatch``), never written here.

A plant, an observer or a law added later is its modules and one registry line, and the
dispatch written again (docs/design.md, "Adding to the loop"); nothing in this module changes.
A scenario whose cores have no compiled form (a core class this module does not know, more
command delay than :data:`MAX_DELAY`) returns None from :func:`compile_loop`;
``closed_loop.run`` then steps the core objects.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.divergence import DISPLACEMENT, DIVERGENCE_DISPLACEMENT, DIVERGENCE_FORCE, FORCE
from pac_controller.controller import Controller
from pac_controller.kernels import CONTROLLER_PARAMS, CONTROLLER_STATE, KernelLaw, controller_step, new_state
from pac_controller.user_law import UserLaw
from pac_observer.contact_force import ContactForceObserver
from pac_observer.head_balance import HeadBalanceObserver
from pac_observer.observer import AdaptiveObserver
from pac_observer.observer_dispatch import observer_update
from pac_observer.observers import compiled_observer_classes
from pac_plant.hardware.actuator_dispatch import actuator_apply
from pac_plant.hardware.actuators import ACTUATOR_PARAMS, ACTUATOR_STATE
from pac_plant.hardware.car_body import TERMS, cosines_at, held_force, roof_from, sines_at
from pac_plant.hardware.sensors import SENSOR_PARAMS, SENSOR_STATE, sensor_step
from pac_plant.parameters import MAX_PANTOGRAPHS
from pac_plant.plant import Plant, quantise
from pac_plant.plant_dispatch import plant_advance, plant_output
from pac_plant.plants import PLANT_CODES, compiled_plant

#: Most ticks of command delay the compiled loop holds (``command_delay_ticks``' upper bound).
MAX_DELAY = 100

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
        ("kind", "i8"),  # pac_plant.plants.PLANT_CODES: which plant the records are
        # FE line (fe_plant.FEPlant): the fixed datum, or the static wire under the contact point
        ("static_wire", "b1"),
        ("datum", "f8"),
        ("uplift", "f8"),  # the wind, acting with u (Plant.uplift; the own uplift is part of u)
        # Every pantograph's truth (``pantograph_truth``): how many (0: one pantograph, PlantTruth
        # is all, as the plant node publishes) and each one's contact in the simulation, in the
        # order of ``pantographs`` (``FEPlant.contact_of`` where ``fe_plant.several_pantographs``)
        ("pantographs", "i8"),
        ("contact_of", "i8", MAX_PANTOGRAPHS),
        (
            "actuator",
            ACTUATOR_PARAMS,
        ),  # the actuator's (Plant.actuator; step ideal: the command is the force)
        # The moving roof (Plant.roof; roof False: a fixed base): its cosines and the roof spring and
        # damper of the actuator's mass
        ("roof", "b1"),
        ("roof_k", "f8"),
        ("roof_c", "f8"),
        ("roof_amplitude", "f8", TERMS),
        ("roof_frequency", "f8", TERMS),
        ("roof_phase", "f8", TERMS),
        # The roof under each passive pantograph of an FE line (FEPlant.passive_roofs; 0 of them: a
        # fixed roof): its contact, spring and damper, and its cosines' phases (the amplitudes and
        # frequencies are the controlled one's: the same track under the same kind of car)
        ("passive_roofs", "i8"),
        ("passive_roof_contact", "i8", MAX_PANTOGRAPHS),
        ("passive_roof_k", "f8", MAX_PANTOGRAPHS),
        ("passive_roof_c", "f8", MAX_PANTOGRAPHS),
        ("passive_roof_phase", "f8", (MAX_PANTOGRAPHS, TERMS)),
        # The turbulent uplift (Plant.gusts; gusts False: none): its cosines [N]
        ("gusts", "b1"),
        ("gust_amplitude", "f8", TERMS),
        ("gust_frequency", "f8", TERMS),
        ("gust_phase", "f8", TERMS),
        # A train's sensor suite (Plant.sensors; suite False: the ground's, noise_std and
        # quantisation): its channels (sensors.sensor_records)
        ("suite", "b1"),
        ("sensors", SENSOR_PARAMS),
    ]
)

PLANT_STATE = np.dtype(
    [
        ("z", "f8", 4),
        ("u_applied", "f8"),  # force applied over the period that ends at this tick
        ("pending", "f8", MAX_DELAY),  # commands sent, not yet applied (a ring)
        ("head", "i8"),
        ("readings", "f8", 5),  # scratch: step.readings_at one pantograph's contact point
        ("actuator", ACTUATOR_STATE),
        ("roof", "f8", 3),  # scratch: the roof's height, velocity, acceleration (car_body.roof_at)
        ("gust", "f8", 3),  # scratch: the turbulent uplift and its rates (car_body.roof_at)
        # The roof's and the turbulent uplift's angles at tick ``angles_tick`` (-1: none yet), and at
        # the tick after it (scratch): a tick's end is the next one's start (car_body.held_force).
        ("angles_tick", "i8"),
        ("roof_cos", "f8", TERMS),
        ("roof_sin", "f8", TERMS),
        ("gust_sin", "f8", TERMS),
        ("roof_cos_next", "f8", TERMS),
        ("roof_sin_next", "f8", TERMS),
        ("gust_sin_next", "f8", TERMS),
        ("sensors", SENSOR_STATE),  # a train's suite: its low-passes and latency rings
        ("sensed", "f8", 5),  # scratch: the suite's readings of the tick (sensors.CHANNELS)
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
        ("head_acceleration", "f8"),  # a train's suite (NaN: not fitted, and on the ground's)
        ("frame_acceleration", "f8"),
        ("head_force", "f8"),
        ("from_roof", "b1"),
        # truth
        ("z", "f8", 4),
        ("stiffness", "f8"),
        ("contact_force", "f8"),
        ("in_contact", "b1"),
        ("u_applied", "f8"),
        ("contact_uplift", "f8"),  # FE line only (NaN on the lumped one), as plant.Truth
        ("support_uplift", "f8"),
        ("contact_position", "f8"),
        ("roof_height", "f8"),  # the roof under the pantograph from its rest (0: a fixed base)
        # every pantograph (PLANT_PARAMS.pantographs of them, in the order of ``pantographs``; NaN
        # beyond, and everywhere with one pantograph): fe_plant.PantographTruth's fields
        ("pantograph_contact_force", "f8", MAX_PANTOGRAPHS),
        ("pantograph_contact_position", "f8", MAX_PANTOGRAPHS),
        ("pantograph_contact_uplift", "f8", MAX_PANTOGRAPHS),
        ("pantograph_support_uplift", "f8", MAX_PANTOGRAPHS),
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


#: The FE line's arguments of :func:`loop_tick` (``FE_ARGS``): the packed constants and state of its
#: ``ContactSimulation`` (``packing.pack``), the element flexibilities and the contact readings.
FE_ARGS = ("cf", "ci", "cl", "sf", "si", "sl", "flexibility", "readings")


@njit(cache=True, error_model="numpy")
def _angles_at(k, pp, ps) -> None:
    """The roof's and the turbulent uplift's angles at t_k = k dt into ``ps`` (unless there)."""
    if ps.angles_tick == k:
        return
    t = k * pp.dt
    if pp.roof:
        cosines_at(pp.roof_frequency, pp.roof_phase, t, ps.roof_cos, ps.roof_sin)
    if pp.gusts:
        sines_at(pp.gust_frequency, pp.gust_phase, t, ps.gust_sin)
    ps.angles_tick = k


@njit(cache=True, error_model="numpy")
def _with_roof(k, pp, ps, force: float) -> float:
    """``force`` plus the moving roof's force, then plus the turbulent uplift, each its mean over
    [t_k, t_k+1] (Plant._with_roof, in its order of additions; car_body.roof_force, with the angles
    at t_k kept from the tick before); leaves the angles at t_k+1 in ``ps`` for the next tick."""
    _angles_at(k, pp, ps)
    t0, t1 = k * pp.dt, (k + 1) * pp.dt
    if pp.roof:
        cosines_at(pp.roof_frequency, pp.roof_phase, t1, ps.roof_cos_next, ps.roof_sin_next)
        force += held_force(
            pp.roof_amplitude, pp.roof_frequency, pp.roof_k, pp.roof_c, t1 - t0,
            ps.roof_sin, ps.roof_sin_next, ps.roof_cos, ps.roof_cos_next,
        )  # fmt: skip
        ps.roof_cos[:], ps.roof_sin[:] = ps.roof_cos_next, ps.roof_sin_next
    if pp.gusts:  # (k = 1, c = 0: the cosines' own mean; their cos unread)
        sines_at(pp.gust_frequency, pp.gust_phase, t1, ps.gust_sin_next)
        force += held_force(
            pp.gust_amplitude, pp.gust_frequency, 1.0, 0.0, t1 - t0,
            ps.gust_sin, ps.gust_sin_next, ps.gust_sin, ps.gust_sin_next,
        )  # fmt: skip
        ps.gust_sin[:] = ps.gust_sin_next
    ps.angles_tick = k + 1
    return force


@njit(cache=True, error_model="numpy")
def measure(pp, ps, z, a1, a2, force, noise, out) -> tuple[float, float]:
    """The measurement y_k of the truth ``z`` (eq. (10), plus noise and quantisation; or a train
    suite's readings of z, the accelerations a1, a2, the contact force and ``out.roof_height``:
    ``Plant.measurement``), the suite's other channels into ``out``."""
    if pp.suite:  # Plant._sense: the suite's readings of the truth, once a tick
        r = ps.sensed
        sensor_step(pp.sensors, ps.sensors, z[0], z[1], a1, a2, out.roof_height, force, noise, r)
        out.head_acceleration, out.frame_acceleration, out.head_force = r[2], r[3], r[4]
        out.from_roof = pp.sensors.roof_datum
        return r[0], r[1]
    y1, y2 = z[0], z[1]
    if pp.noisy:
        y1, y2 = y1 + noise[0], y2 + noise[1]
    out.head_acceleration, out.frame_acceleration, out.head_force = np.nan, np.nan, np.nan
    out.from_roof = False
    return quantise(y1, pp.quantisation), quantise(y2, pp.quantisation)


@njit(cache=True, error_model="numpy")
def _plant_output(k, pp, ps, fe_args, noise, out) -> tuple[float, float]:
    """The plant at tick k: truth into ``out`` and ``ps.z``, and the measurement y_k (eq. (10),
    plus noise and quantisation; or a train suite's readings, ``Plant.measurement``)."""
    t = k * pp.dt
    out.roof_height = 0.0
    if pp.roof:
        _angles_at(k, pp, ps)
        roof_from(pp.roof_amplitude, pp.roof_frequency, ps.roof_cos, ps.roof_sin, ps.roof)
        out.roof_height = ps.roof[0]
    # The plant's own truth (plant_dispatch, generated from the plant registry).
    stiff, force, a1, a2 = plant_output(k, t, pp, ps, fe_args, out)
    z = ps.z
    y1, y2 = measure(pp, ps, z, a1, a2, force, noise, out)
    out.tick, out.time = k, t
    out.y[0], out.y[1] = y1, y2
    out.actuator_force = ps.u_applied
    out.z[:] = z
    out.stiffness, out.contact_force, out.in_contact, out.u_applied = stiff, force, force > 0.0, ps.u_applied
    return y1, y2


@njit(cache=True, error_model="numpy")
def _plant_advance(k, pp, ps, fe_args, applied) -> int:
    """The plant over [t_k, t_k+1] with ``applied`` held (zero-order hold); 0 or a divergence code
    (OFF_LINE: past the FE line's end)."""
    force = applied + pp.uplift  # the wind acts with u
    if pp.roof or pp.gusts:  # the moving roof's force and the turbulent uplift (Plant._with_roof)
        force = _with_roof(k, pp, ps, force)
    status = plant_advance(k, pp, ps, fe_args, force)  # plant_dispatch
    if status:
        return status
    ps.u_applied = applied
    return 0


@njit(cache=True, error_model="numpy")
def _observer_update(k, t, oc, os, bank, y1, y2, u_applied, out) -> int:
    """The observer of the records at tick k (``observer_dispatch``, generated from the observer
    registry); the estimate into ``out``."""
    status, stiffness_hat, contact_force_hat = observer_update(
        k, t, oc, os, bank, y1, y2, u_applied, out.head_acceleration
    )
    if status:
        return status
    out.stiffness_hat, out.contact_force_hat = stiffness_hat, contact_force_hat
    out.z_hat[:] = os.z_hat
    out.theta_hat[:] = os.theta_hat
    out.innovation[:] = os.innovation
    return 0


def closed_loop_for(step):
    """The compiled tick and tick loop around controller ``step`` (``kernels.controller_step`` for
    pac's laws: :func:`loop_tick`, :func:`run_ticks`; a user's compiled law file: its own, through
    :func:`block_for`), and the unit's chain they run (:func:`unit_chain`). Closures, so numba calls
    ``step`` statically and the cached functions that call them (:func:`run_block`, the batch's)
    stay cached (``kernels.safety_chain``)."""

    @njit(error_model="numpy")
    def unit_chain(k, pp, ps, oc, os, bank, cp, cs, table, memory, y1, y2, out) -> tuple[int, float, float]:
        """One unit from its measurement y_k to the force its actuator holds over [t_k, t_k+1]: the
        observer, the law and its safety chain, the command delay, the actuator; the estimate and
        the command into ``out``. Returns (0, 0, that force) or a divergence (code, value, 0):
        DISPLACEMENT (value y1), the observer's (the state is that of tick k - 1), FORCE (value: u
        demanded by the law)."""
        if not (abs(y1) < DIVERGENCE_DISPLACEMENT and abs(y2) < DIVERGENCE_DISPLACEMENT):
            return DISPLACEMENT, y1, 0.0
        status = _observer_update(k, out.time, oc, os, bank, y1, y2, ps.u_applied, out)
        if status:
            return status, np.nan, 0.0
        # Controller: law and safety chain.
        u, u_law, f_r, e1, e2, e3, mode = step(
            cp, cs, table, memory, k, os.z_hat, os.theta_hat, out.contact_force_hat, out.actuator_force
        )
        if not abs(u_law) < DIVERGENCE_FORCE:
            return FORCE, u_law, 0.0
        out.u, out.u_unsaturated, out.force_reference = u, u_law, f_r
        out.tracking_error[0], out.tracking_error[1], out.tracking_error[2] = e1, e2, e3
        out.saturated, out.mode = u != u_law, mode
        # Command delay, then the actuator's dynamics (Plant._actuate): its mean force over the tick.
        if pp.delay == 0:
            applied = u
        else:
            applied = ps.pending[ps.head]
            ps.pending[ps.head] = u
            ps.head = (ps.head + 1) % pp.delay
        return 0, 0.0, actuator_apply(pp.actuator, ps.actuator, applied)

    @njit(error_model="numpy")
    def loop_tick(k, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out) -> tuple[int, float]:
        """Tick k of the closed loop, in place; ``out`` (a TICK record) gets what the topics carry.

        Returns (0, 0) or a divergence (code, value): 1-3, 6 the observer's (the state is that of
        tick k - 1), DISPLACEMENT (value y1), FORCE (value: u demanded by the law), OFF_LINE.
        ``fe_args``: the FE line's buffers (:data:`FE_ARGS`; empty arrays for the lumped line);
        ``bank``: the contact-force filters' arrays (``contact_force.BANK_ARGS``; empty for the paper's);
        ``table``, ``memory``: the law's arrays (``KernelLaw.table`` / ``memory``; a user's compiled
        law: its constants and memory), for ``step``.  ``noise``: this tick's sensor noise
        (``Plant.noise_rows``' row: the ground's two, a train suite's five).  The order of
        operations is that of ``closed_loop.run_cores`` and of the nodes.
        """
        y1, y2 = _plant_output(k, pp, ps, fe_args, noise, out)
        code, value, applied = unit_chain(k, pp, ps, oc, os, bank, cp, cs, table, memory, y1, y2, out)
        if code:
            return code, value
        # The plant over [t_k, t_k+1] (zero-order hold).
        status = _plant_advance(k, pp, ps, fe_args, applied)
        if status:
            return status, out.contact_position
        return 0, 0.0

    @njit(error_model="numpy")
    def run_ticks(
        k0, k1, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out
    ) -> tuple[int, int, float]:
        """Ticks k0..k1-1 into ``out[k - k0]``; (ticks reached, divergence code, value).

        ``noise[k - k0]`` is tick k's sensor noise (``Plant.noise_rows``; a single row when the
        plant is noiseless).
        """
        for k in range(k0, k1):
            i = min(k - k0, noise.shape[0] - 1)
            code, value = loop_tick(
                k, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise[i], out[k - k0]
            )
            if code:
                return k, code, value
        return k1, 0, 0.0

    return loop_tick, run_ticks, unit_chain


#: The closed loop of pac's laws (:func:`closed_loop_for` ``kernels.controller_step``).
loop_tick, run_ticks, unit_chain = closed_loop_for(controller_step)


@njit(cache=True, nogil=True, error_model="numpy")
def run_block(
    k0, k1, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out
) -> tuple[int, int, float]:
    """:func:`run_ticks` on the records of 1-element arrays (how Python hands them over)."""
    return run_ticks(
        k0, k1, pp[0], ps[0], fe_args, oc[0], os[0], bank, cp[0], cs[0], table, memory, noise, out
    )


def block_for(step):
    """:func:`run_block` around controller ``step`` (a user's compiled law file: ``user_law``);
    compiled once per law and process, not cached on disk (a closure of the user's functions)."""
    run = closed_loop_for(step)[1]

    @njit(nogil=True, error_model="numpy")
    def block(
        k0, k1, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out
    ) -> tuple[int, int, float]:
        return run(k0, k1, pp[0], ps[0], fe_args, oc[0], os[0], bank, cp[0], cs[0], table, memory, noise, out)

    return block


#: The loop of each user's compiled law this process ran, by its chain (``LawFile.step``).
_USER_BLOCKS: dict[Callable, Callable] = {}


def _user_block(law: UserLaw) -> Callable[..., tuple[int, int, float]]:
    """The loop around a user's compiled law (:func:`block_for`), made once per law file."""
    step = law.file.step
    assert step is not None, "a law file at Python speed has no compiled loop"
    if step not in _USER_BLOCKS:
        _USER_BLOCKS[step] = block_for(step)
    return _USER_BLOCKS[step]


#: The bank of the paper's observer (it has none): empty arrays of the contact-force bank's types.
NO_BANK = (
    np.zeros((0, 5, 5)), np.zeros((0, 5)), np.zeros((0, 5, 2)), np.zeros((0, 5)), np.zeros(0),
    np.zeros((0, 2)),
)  # fmt: skip


@dataclass
class CompiledLoop:
    """The records of one run: parameters and states (each a 1-element structured array), the FE
    line's buffers (:data:`FE_ARGS`, ``plant_kernels.NO_FE`` for the lumped line) and the law's tables."""

    plant_params: np.ndarray
    plant_state: np.ndarray
    fe_args: tuple
    observer_consts: np.ndarray
    observer_state: np.ndarray
    bank: tuple
    controller_params: np.ndarray
    controller_state: np.ndarray
    table: np.ndarray  # a user's compiled law: its constants (user_law.UserLaw.consts)
    memory: np.ndarray  # a user's compiled law: its memory (UserLaw.state, a copy)
    #: A user's compiled law: the loop around its chain (:func:`block_for`); None: :func:`run_block`.
    block: Callable[..., tuple[int, int, float]] | None = None

    def args(self) -> tuple:
        """The records and arrays in the order :func:`loop_tick` takes them (after the tick)."""
        return (
            self.plant_params, self.plant_state, self.fe_args, self.observer_consts, self.observer_state,
            self.bank, self.controller_params, self.controller_state, self.table, self.memory,
        )  # fmt: skip

    def controlled(self) -> list[bool]:
        """Of each pantograph the ticks report (``TICK``'s pantograph fields, in the order of
        ``pantographs``), whether it is the controlled one (contact 0); empty: none reported."""
        p = self.plant_params[0]
        return [int(k) == 0 for k in p["contact_of"][: p["pantographs"]]]

    def run(self, k0: int, k1: int, noise: np.ndarray, out: np.ndarray) -> tuple[int, int, float]:
        """Ticks k0..k1-1 into ``out`` (a TICK array); (ticks reached, divergence code, value)."""
        return (self.block or run_block)(k0, k1, *self.args(), noise, out)


def compile_loop(
    plant: Plant,
    observer: AdaptiveObserver | ContactForceObserver | HeadBalanceObserver,
    controller: Controller,
    delay: int,
) -> CompiledLoop | None:
    """The records of the cores as built (``closed_loop.build_cores``; copies: the cores are not
    changed by running them), or None if the loop has no compiled form for them: a plant or an
    observer whose registry gives it no compiled parts (``pac_plant.plants``,
    ``pac_observer.observers``), a law without kernel
    (not a :class:`KernelLaw`, nor a user's law file with njit functions), more delay than
    :data:`MAX_DELAY`."""
    plant_kind = compiled_plant(plant)
    if (
        plant_kind is None
        or type(observer) not in compiled_observer_classes()
        or type(controller) is not Controller
    ):
        return None
    law = controller.law
    compiled_user = isinstance(law, UserLaw) and law.file.compiled
    if not (isinstance(law, KernelLaw) or compiled_user) or not 0 <= delay <= MAX_DELAY:
        return None
    pp = np.zeros(1, PLANT_PARAMS)
    p = pp[0]
    p["dt"] = plant.sample_period
    p["m1"], p["m2"] = plant.pantograph.m1, plant.pantograph.m2
    p["quantisation"], p["noisy"] = plant.options.quantisation, plant.noisy
    p["substeps"], p["delay"], p["uplift"] = plant.options.substeps, delay, plant.uplift
    ps = np.zeros(1, PLANT_STATE)
    ps[0]["z"], ps[0]["u_applied"], ps[0]["angles_tick"] = plant.z, plant.u_applied, -1
    p["actuator"], ps[0]["actuator"] = plant.actuator.params[0], plant.actuator.state[0]  # copies
    if plant.roof is not None:
        p["roof"], (p["roof_k"], p["roof_c"]) = True, plant.roof_attachment
        p["roof_amplitude"], p["roof_frequency"] = plant.roof.amplitude, plant.roof.frequency
        p["roof_phase"] = plant.roof.phase
    if plant.gusts is not None:
        p["gusts"], p["gust_amplitude"] = True, plant.gusts.amplitude
        p["gust_frequency"], p["gust_phase"] = plant.gusts.frequency, plant.gusts.phase
    if plant.sensors is not None:  # a train's suite: its records as they stand (copies)
        p["suite"], p["sensors"], ps[0]["sensors"] = True, plant.sensors.params[0], plant.sensors.state[0]
    # The plant's own fields and arrays (its kernel module's ``<name>_pack``; plant_kernels).
    p["kind"] = PLANT_CODES[plant_kind.name]
    assert plant_kind.kernel is not None  # compiled_plant gives only plants with compiled parts
    pack = getattr(importlib.import_module(plant_kind.kernel), f"{plant_kind.name}_pack")
    fe_args = pack(plant, p)
    cp = controller.record.copy()  # the law's design and the safety chain's fields
    cs = np.zeros(1, CONTROLLER_STATE)
    new_state(cs)
    table: np.ndarray
    memory: np.ndarray
    if isinstance(law, KernelLaw):
        table, memory, block = law.table, law.memory.copy(), None
    else:  # a user's compiled law (checked above)
        assert isinstance(law, UserLaw)
        table, memory, block = law.consts, law.state.copy(), _user_block(law)
    # The contact-force filters' arrays (contact_force.BANK_ARGS' types); the others have none.
    own_bank = getattr(observer, "bank", ())
    bank = tuple(np.ascontiguousarray(a).copy() for a in own_bank) if own_bank else NO_BANK
    return CompiledLoop(
        pp, ps, fe_args, observer.consts.copy(), observer.state.copy(), bank, cp, cs, table, memory, block
    )


__all__ = ["CONTROLLER_PARAMS", "FE_ARGS", "TICK", "CompiledLoop", "compile_loop", "loop_tick", "run_ticks"]
