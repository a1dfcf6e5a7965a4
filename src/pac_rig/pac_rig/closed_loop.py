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
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

from pac_common.parameters import LoopParameters, ParameterSet, parameter
from pac_controller.controller import Command, Controller
from pac_controller.laws import make_controller
from pac_controller.parameters import ControllerParameters, LawParameters, ReferenceParameters
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.contact_force import ContactForceObserver, make_observer
from pac_observer.observer import AdaptiveObserver, Estimate, ObserverDivergedError
from pac_observer.parameters import ObserverParameters
from pac_plant.fe_plant import make_plant
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Measurement, Plant, Truth


@dataclass(frozen=True)
class ModelMismatch(ParameterSet):
    """Offline only: how the simulated pantograph differs from the one the observer and controller assume."""

    plant_mass_scale: float = parameter(
        1.0, "plant's m1 and m2 scaled by this (observer and controller keep Table 1's)", low=0.1, high=10.0
    )

    def plant_pantograph(self, nominal: PantographParameters) -> PantographParameters:
        return replace(nominal, m1=nominal.m1 * self.plant_mass_scale, m2=nominal.m2 * self.plant_mass_scale)


@dataclass(frozen=True)
class Scenario:
    """Everything that defines a run."""

    pantograph: PantographParameters = field(default_factory=PantographParameters)
    track: TrackParameters = field(default_factory=TrackParameters)
    catenary: CatenaryParameters = field(default_factory=CatenaryParameters)
    plant: PlantOptions = field(default_factory=PlantOptions)
    observer: ObserverParameters = field(default_factory=ObserverParameters)
    controller: ControllerParameters = field(default_factory=ControllerParameters)
    reference: ReferenceParameters = field(default_factory=ReferenceParameters)
    laws: LawParameters = field(default_factory=LawParameters)  # pid / lqr design (controller.law)
    loop: LoopParameters = field(default_factory=LoopParameters)
    mismatch: ModelMismatch = field(default_factory=ModelMismatch)


@dataclass(frozen=True)
class TickRecord:
    """One tick of a run: what each of the four topics carries."""

    measurement: Measurement
    truth: Truth
    estimate: Estimate
    command: Command


class DivergenceError(RuntimeError):
    """The closed loop left the physically meaningful region; the run stops."""

    def __init__(self, tick: int, reason: str) -> None:
        self.tick = tick
        self.reason = reason
        super().__init__(f"closed loop diverged at tick {tick}: {reason}")


#: |z1|, |z2| beyond this [m] is not a pantograph any more: the run is stopped as diverged.
DIVERGENCE_DISPLACEMENT = 1.0
#: A control law asking for more than this [N] has run away (Table 1's uplift is ~100 N).
DIVERGENCE_FORCE = 1e6


def build_cores(s: Scenario) -> tuple[Plant, AdaptiveObserver | ContactForceObserver, Controller]:
    dt = s.loop.sample_period
    plant = make_plant(
        s.mismatch.plant_pantograph(s.pantograph), s.track, s.catenary, s.plant, dt
    )  # lumped | fe
    observer = make_observer(s.pantograph, s.track, s.observer, dt)  # observer: adaptive | contact_force
    # backstepping_known is told the plant's own catenary: the oracle.
    controller = make_controller(s.pantograph, s.track, s.controller, s.reference, dt, s.laws, s.catenary)
    return plant, observer, controller


def run(s: Scenario) -> Iterator[TickRecord]:
    """Yield one record per tick, ticks 0 .. loop.ticks - 1; raise DivergenceError on divergence."""
    plant, observer, controller = build_cores(s)
    delay = s.loop.command_delay_ticks
    pending: deque[float] = deque([0.0] * delay)
    for _ in range(s.loop.ticks):
        y = plant.measurement()
        truth = plant.truth()
        if not (abs(y.z1) < DIVERGENCE_DISPLACEMENT and abs(y.z2) < DIVERGENCE_DISPLACEMENT):
            raise DivergenceError(y.tick, f"|z| exceeded {DIVERGENCE_DISPLACEMENT} m (z1={y.z1:.3g})")
        try:
            est = observer.update(y.tick, (y.z1, y.z2), y.actuator_force)
        except ObserverDivergedError as exc:
            raise DivergenceError(y.tick, exc.reason) from exc
        cmd = controller.compute(y.tick, est.z_hat, est.theta_hat, est.contact_force_hat)
        if not abs(cmd.u_unsaturated) < DIVERGENCE_FORCE:
            raise DivergenceError(
                y.tick, f"|u| demanded by the law exceeded {DIVERGENCE_FORCE:g} N ({cmd.u_unsaturated:.3g} N)"
            )
        yield TickRecord(y, truth, est, cmd)
        pending.append(cmd.u)
        plant.advance(pending.popleft())
