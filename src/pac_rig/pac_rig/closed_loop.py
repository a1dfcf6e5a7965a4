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
from dataclasses import dataclass, field

from pac_common.parameters import LoopParameters
from pac_controller.backstepping import BacksteppingController, Command
from pac_controller.parameters import ControllerParameters, ReferenceParameters
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.observer import AdaptiveObserver, Estimate, ObserverDivergedError
from pac_observer.parameters import ObserverParameters
from pac_plant.fe_plant import make_plant
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Measurement, Plant, Truth


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
    loop: LoopParameters = field(default_factory=LoopParameters)


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


def build_cores(s: Scenario) -> tuple[Plant, AdaptiveObserver, BacksteppingController]:
    dt = s.loop.sample_period
    plant = make_plant(s.pantograph, s.track, s.catenary, s.plant, dt)  # catenary_model: lumped | fe
    observer = AdaptiveObserver(s.pantograph, s.track, s.observer, dt)
    controller = BacksteppingController(s.pantograph, s.track, s.controller, s.reference, dt)
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
        cmd = controller.compute(y.tick, est.z_hat, est.theta_hat)
        if not abs(cmd.u_unsaturated) < DIVERGENCE_FORCE:
            raise DivergenceError(
                y.tick, f"|u| demanded by the law exceeded {DIVERGENCE_FORCE:g} N ({cmd.u_unsaturated:.3g} N)"
            )
        yield TickRecord(y, truth, est, cmd)
        pending.append(cmd.u)
        plant.advance(pending.popleft())
