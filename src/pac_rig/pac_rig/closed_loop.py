"""The offline closed loop: the three cores composed tick by tick exactly as the nodes run them.

At tick k the plant gives y_k (and the force it applied over (t_{k-1}, t_k]), the
observer updates, the controller computes u_k, and the plant applies u_k over
[t_{k+d}, t_{k+d+1}] with d = ``command_delay_ticks`` (1 by default: what three
processes over topics give in lock step; 0 is the ideal continuous-time case).
Before the first command arrives the actuator force is 0 (the loop starts at rest
with F_r(0) = 0).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from pac_common import divergence
from pac_common.divergence import DISPLACEMENT, DIVERGENCE_DISPLACEMENT, DIVERGENCE_FORCE, FORCE, OFF_LINE
from pac_common.parameters import ParameterError
from pac_controller.controller import Command, Controller
from pac_controller.kernels import MODES
from pac_controller.laws import make_controller
from pac_observer.contact_force import ContactForceObserver, make_observer
from pac_observer.observer import AdaptiveObserver, Estimate, ObserverDivergedError
from pac_plant.fe_plant import PantographTruth, several_pantographs
from pac_plant.plant import Measurement, Plant, Truth
from pac_plant.plants import make_plant

from . import composition
from .loop import TICK, CompiledLoop, compile_loop
from .scenario import Scenario


@dataclass(frozen=True)
class TickRecord:
    """One tick of a run: what each of the four topics carries, and every pantograph's truth where
    the plant reports them (``pantograph_truth``: an FE line with several; else empty)."""

    measurement: Measurement
    truth: Truth
    estimate: Estimate
    command: Command
    pantographs: tuple[PantographTruth, ...] = ()


class DivergenceError(RuntimeError):
    """The closed loop left the physically meaningful region; the run stops."""

    def __init__(self, tick: int, reason: str) -> None:
        self.tick = tick
        self.reason = reason
        super().__init__(f"closed loop diverged at tick {tick}: {reason}")


#: A scenario's plant, observer and controller (``build_cores``).
Cores = tuple[Plant, AdaptiveObserver | ContactForceObserver, Controller]


def build_cores(s: Scenario, pair_unit: bool = False) -> Cores:
    """The plant, observer and controller of ``s``; ParameterError (one line) for parts that do not
    fit together (pac_rig.composition) or a design the parameters do not allow (``pair_unit``: the
    cores of one unit of a pair loop, ``pac_rig.pair_loop``, where ``all_pantographs_active`` holds)."""
    composition.check_pair(
        s.controller.effective_law, s.observer.observer, s.laws.force_estimate, s.plant.sensors
    )
    dt = s.loop.sample_period
    if (s.plant.pantograph or s.pantograph.nominal_pantograph) and s.mismatch.plant_mass_scale != 1.0:
        raise ParameterError(
            "plant_mass_scale",
            s.mismatch.plant_mass_scale,
            "1 when a pantograph file is given (scale the masses in a copy of the file instead)",
        )
    plant = make_plant(
        s.mismatch.plant_pantograph(s.pantograph), s.track, s.catenary, s.plant, dt, pair_unit
    )  # lumped | fe
    speed = s.track.speed_kmh / 3.6
    if s.loop.duration * speed > plant.run_length:
        # Refused before the run, not when the pantograph runs off the line's end mid-run.
        raise ParameterError(
            "duration",
            s.loop.duration,
            f"at most {plant.run_length / speed:.3f} s at {s.track.speed_kmh:g} km/h: the line ends "
            f"{plant.run_length:.1f} m after the pantograph's start",
        )
    observer = make_observer(s.pantograph, s.track, s.observer, dt)  # observer: adaptive | contact_force
    # backstepping_known is told the plant's own catenary: the oracle.
    controller = make_controller(s.pantograph, s.track, s.controller, s.reference, dt, s.laws, s.catenary)
    return plant, observer, controller


def run(s: Scenario) -> Iterator[TickRecord]:
    """Yield one record per tick, ticks 0 .. loop.ticks - 1; raise DivergenceError on divergence.

    The compiled step (:func:`pac_rig.loop.loop_tick`) runs the ticks block by block (every line,
    observer and law); cores without a compiled form are stepped by :func:`run_cores`.  Both give
    the same records (``tests/test_batch.py``).
    """
    plant, observer, controller = build_cores(s)
    loop = compile_loop(plant, observer, controller, s.loop.command_delay_ticks)
    if loop is None:
        yield from run_cores(s, plant, observer, controller)
        return
    controlled = loop.controlled()
    for block in run_blocks(s, plant, loop):
        yield from tick_records(block, controlled)


def run_blocks(s: Scenario, plant: Plant, loop: CompiledLoop) -> Iterator[np.ndarray]:
    """The ticks of the run as TICK blocks of up to BLOCK ticks; raise DivergenceError on divergence."""
    ticks = s.loop.ticks
    for k0 in range(0, ticks, BLOCK):
        k1 = min(ticks, k0 + BLOCK)
        out = np.empty(k1 - k0, TICK)
        noise = plant.noise_rows(k0, k1)
        reached, code, value = loop.run(k0, k1, noise, out)
        yield out[: reached - k0]
        if code == OFF_LINE:  # as FEPlant.advance says it
            raise ValueError(divergence.reason(code, value))
        if code:
            raise DivergenceError(reached, divergence.reason(code, value))


def computed_ahead(blocks: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
    """``blocks`` (``run_blocks``), each next one computed in a thread while the caller handles
    the one it was given (writes it to a bag): the compiled loop releases the GIL, so on two cores
    the writing costs no wall time. The same blocks in the same order, an error where ``blocks``
    raises it (after the blocks before it). A caller that stops early waits for the block under
    way (at most BLOCK ticks), which is then dropped."""
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="pac-loop") as pool:
        pending = pool.submit(next, blocks, None)
        while (block := pending.result()) is not None:
            pending = pool.submit(next, blocks, None)
            yield block


#: Ticks per compiled call of :func:`run` (one noise block of the plant).
BLOCK = 4096


_RECORD_COLUMNS = (
    "tick", "time", "y", "actuator_force", "head_acceleration", "frame_acceleration", "head_force",
    "from_roof", "z", "stiffness", "contact_force", "in_contact", "u_applied",
    "contact_uplift", "support_uplift", "contact_position", "roof_height", "stiffness_hat",
    "contact_force_hat", "u", "u_unsaturated", "force_reference", "tracking_error", "saturated", "mode",
)  # fmt: skip


def pantograph_truths(block: np.ndarray, controlled: Sequence[bool]) -> list[tuple[PantographTruth, ...]]:
    """Every pantograph's truth at each row of a TICK block (what ``FEPlant.pantograph_truths`` gives
    at that tick); ``controlled``: of each pantograph reported (``CompiledLoop.controlled``), whether
    it is the controlled one (empty: none reported, an empty tuple per row)."""
    n = len(controlled)
    if not n:
        return [()] * block.size
    force, position, contact, support = (
        block[f"pantograph_{name}"][:, :n].tolist()  # Python floats, as the plant gives
        for name in ("contact_force", "contact_position", "contact_uplift", "support_uplift")
    )
    return [
        tuple(
            PantographTruth(
                contact_force=f, contact_position=x, contact_uplift=c, support_uplift=w, controlled=b
            )
            for f, x, c, w, b in zip(force[i], position[i], contact[i], support[i], controlled, strict=True)
        )
        for i in range(block.size)
    ]


def tick_records(block: np.ndarray, controlled: Sequence[bool] = ()) -> Iterator[TickRecord]:
    """The TickRecord of each row of a TICK block (the objects the per-tick cores return);
    ``controlled`` as :func:`pantograph_truths` takes it."""
    col = {name: block[name].tolist() for name in _RECORD_COLUMNS}  # Python numbers, as the cores give
    z_hat, theta_hat, innovation = block["z_hat"], block["theta_hat"], block["innovation"]
    pantographs = pantograph_truths(block, controlled)
    for i, (tick, t) in enumerate(zip(col["tick"], col["time"], strict=True)):
        y1, y2 = col["y"][i]
        z0, z1, z2, z3 = col["z"][i]
        e1, e2, e3 = col["tracking_error"][i]
        yield TickRecord(
            Measurement(
                tick, t, y1, y2, col["actuator_force"][i], col["head_acceleration"][i],
                col["frame_acceleration"][i], col["head_force"][i], col["from_roof"][i],
            ),
            Truth(
                tick, t, (z0, z1, z2, z3), col["stiffness"][i], col["contact_force"][i],
                col["in_contact"][i], col["u_applied"][i], col["contact_uplift"][i],
                col["support_uplift"][i], col["contact_position"][i], col["roof_height"][i],
            ),
            Estimate(
                tick, t, z_hat[i], theta_hat[i], col["stiffness_hat"][i], col["contact_force_hat"][i],
                innovation[i],
            ),
            Command(
                tick, t, col["u"][i], col["u_unsaturated"][i], col["force_reference"][i],
                (e1, e2, e3), col["saturated"][i], MODES[col["mode"][i]],
            ),
            pantographs[i],
        )  # fmt: skip


def run_cores(
    s: Scenario, plant: Plant, observer: AdaptiveObserver | ContactForceObserver, controller: Controller
) -> Iterator[TickRecord]:
    """The loop stepped through the core objects tick by tick, as the nodes step them (the
    reference the compiled loop is checked against, ``tests/test_batch.py``)."""
    delay = s.loop.command_delay_ticks
    pending: deque[float] = deque([0.0] * delay)
    several = several_pantographs(plant)
    for _ in range(s.loop.ticks):
        y = plant.measurement()
        truth = plant.truth()
        pantographs = tuple(several.pantograph_truths()) if several is not None else ()
        if not (abs(y.z1) < DIVERGENCE_DISPLACEMENT and abs(y.z2) < DIVERGENCE_DISPLACEMENT):
            raise DivergenceError(y.tick, divergence.reason(DISPLACEMENT, y.z1))
        try:
            est = observer.update(y.tick, (y.z1, y.z2), y.actuator_force, y.head_acceleration)
        except ObserverDivergedError as exc:
            raise DivergenceError(y.tick, exc.reason) from exc
        cmd = controller.compute(y.tick, est.z_hat, est.theta_hat, est.contact_force_hat, y.actuator_force)
        if not abs(cmd.u_unsaturated) < DIVERGENCE_FORCE:
            raise DivergenceError(y.tick, divergence.reason(FORCE, cmd.u_unsaturated))
        yield TickRecord(y, truth, est, cmd, pantographs)
        pending.append(cmd.u)
        plant.advance(pending.popleft())
