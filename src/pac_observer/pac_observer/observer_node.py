"""``ros2 run pac_observer observer_node``: the adaptive observer (eq. (17)) on the ROS graph.

``-p observer:=contact_force`` runs the contact-force Kalman filter instead
(pac_observer.contact_force: F as a state, no F = k z1; docs/laws.md).

Subscribes ``measurement`` (FrameMeasurement), publishes ``estimate``
(ObserverEstimate) for the same tick.  A repeated tick (a lock-step re-send)
re-publishes the last estimate; a gap (lost samples) is bridged by the core.
A non-finite or physically absurd measurement is refused (counted, flagged in
the next estimate's status, and bridged over like a lost sample); a diverged
update re-initialises the observer with a logged error and a status flag.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from pac_common import diagnostics, messages
from pac_common.lifecycle import LifecycleOptions
from pac_common.node import LOOP_QOS, PUBLISH_QOS, PacNode, run_node
from pac_common.parameters import NodeOptions, ParameterSet, RateParameters, RunEndOptions, parameter
from pac_model.parameters import PantographParameters, TrackParameters

from .contact_force import ContactForceObserver, make_observer
from .observer import AdaptiveObserver, Estimate, ObserverDivergedError
from .parameters import ObserverParameters


@dataclass(frozen=True)
class MeasurementLimits(ParameterSet):
    """What the observer accepts as a measurement at all."""

    position_limit: float = parameter(
        0.5,
        "a |z1| or |z2| beyond this is refused as physically absurd",
        "m",
        low=0.0,
        low_open=True,
        high=10.0,
        runtime=True,
    )
    max_tick_jump: int = parameter(
        10000,
        "a sample more than this many ticks ahead of the last one is refused",
        "ticks",
        low=1,
        runtime=True,
    )
    force_limit: float = parameter(
        1e5,
        "an |actuator force| beyond this is refused as physically absurd",
        "N",
        low=0.0,
        low_open=True,
        runtime=True,
    )


class ObserverNode(PacNode):
    PARAMETER_SETS = [
        PantographParameters,
        TrackParameters,
        ObserverParameters,
        RateParameters,
        NodeOptions,
        RunEndOptions,
        MeasurementLimits,
        LifecycleOptions,
    ]
    FROZEN_REASON = "the observer's model and tuning are fixed for a run: restart the node"
    #: The core's factory (``observer`` selects it); ``observer_relay`` swaps in one that does no
    #: work (the floor of ``make bench``).
    CORE: Callable[..., AdaptiveObserver | ContactForceObserver] = staticmethod(make_observer)
    HEALTH = "observer"

    def __init__(self) -> None:
        super().__init__("observer_node")

    def configure(self) -> None:
        self.limits = self.parameters(MeasurementLimits)
        self.loop = self.parameters(RateParameters)
        self.core = self.CORE(
            self.parameters(PantographParameters),
            self.parameters(TrackParameters),
            self.parameters(ObserverParameters),
            self.loop.sample_period,
        )
        warm_up = getattr(self.core, "warm_up", None)  # optional for a user's observer file
        if warm_up is not None:
            warm_up()  # the compiled code loaded before the loop, not at its first tick
        self.estimate_pub = self.create_publisher(
            self.factory.cls(messages.OBSERVER_ESTIMATE), "estimate", PUBLISH_QOS
        )
        self.create_subscription(
            self.factory.cls(messages.FRAME_MEASUREMENT), "measurement", self.on_measurement, LOOP_QOS
        )
        self.follow_run()
        self.watch_start(self.missing)
        # (estimate, status, rejected, reinitialisations) last published
        self.last_estimate: tuple[Estimate, int, int, int, float] | None = None
        self.last_seen_tick = -1
        self.reinitialisations = 0
        self.rejected = 0
        self.rejected_since_estimate = False
        self.waited = 0
        self.processed = 0
        self.answered_again = 0  # estimates re-published for a re-sent measurement (tick-0 handshake)
        self.bridged = 0  # samples never received (or refused), bridged by the core
        self.timing = diagnostics.LoopTiming()  # measurement arrivals and handling times

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        self.limits = self.changed_or(changed, MeasurementLimits, self.limits)

    def missing(self) -> list[str]:
        """The peers this node's output still waits for, by name (empty: ready)."""
        return self.readers_missing(self.estimate_pub, "estimate", "a controller")

    def ready(self) -> bool:
        return self.active and self.estimate_pub.get_subscription_count() >= 1 + int(self.waits_for_recorder)

    def acceptable(self, z1: float, z2: float, force: float) -> bool:
        finite = math.isfinite(z1) and math.isfinite(z2) and math.isfinite(force)
        return (
            finite
            and abs(z1) <= self.limits.position_limit
            and abs(z2) <= self.limits.position_limit
            and abs(force) <= self.limits.force_limit
        )

    def on_measurement(self, msg) -> None:
        start_ns = time.monotonic_ns()
        tick = int(msg.tick)
        z1, z2, force = float(msg.z1), float(msg.z2), float(msg.actuator_force)
        jump = self.last_seen_tick >= 0 and tick > self.last_seen_tick + self.limits.max_tick_jump
        if jump or not self.acceptable(z1, z2, force):
            # Refused before its tick is trusted: a garbage sample cannot move the tick tracking.
            self.rejected += 1
            self.rejected_since_estimate = True
            self.get_logger().warning(
                f"tick {tick}: measurement refused (z1={z1!r}, z2={z2!r}, force={force!r})",
                throttle_duration_sec=1.0,
            )
            return
        if tick == 0 and self.last_seen_tick > 0:
            self.get_logger().warning(
                f"tick went back from {self.last_seen_tick} to 0: plant restarted, "
                "re-initialising the observer"
            )
            self.core.reset()
            self.reinitialisations += 1
            self.last_seen_tick, self.last_estimate = -1, None
            self.run_new()
        if self.past_run_end(tick):
            return  # idle: the run is over (a new run starts again at tick 0)
        if tick <= self.last_seen_tick:
            if tick == self.core.tick and self.last_estimate is not None:
                self.answered_again += 1
                self.publish(*self.last_estimate)  # the answer to a re-sent sample, again
            return
        if not self.ready():
            self.waited += 1  # nobody to tell yet; lock step re-sends, real time moves on
            return
        self.last_seen_tick = tick
        status = messages.STATUS_MEASUREMENT_REJECTED if self.rejected_since_estimate else messages.STATUS_OK
        if self.core.tick >= 0:
            self.bridged += tick - self.core.tick - 1
        self.processed += 1
        try:
            est = self.core.update(tick, (z1, z2), force, float(msg.head_acceleration))
        except ObserverDivergedError as exc:
            self.reinitialisations += 1
            self.get_logger().error(f"{exc}; re-initialising")
            self.core.reset()
            est = self.core.update(tick, (z1, z2), force, float(msg.head_acceleration))
            status = messages.STATUS_REINITIALISED
        self.rejected_since_estimate = False
        self.last_estimate = (est, status, self.rejected, self.reinitialisations, force)
        self.publish(*self.last_estimate)
        self.timing.record(start_ns, (time.monotonic_ns() - start_ns) * 1e-9)
        self.handled_tick(tick)

    def publish(self, est, status: int, rejected: int, reinitialisations: int, actuator_force: float) -> None:
        # The factory refills one message object per type: never keep it, re-make it.
        stamp = messages.tick_stamp_ns(est.tick, self.loop.rate_hz)
        fields = messages.estimate_fields(
            est,
            stamp,
            status=status,
            rejected=rejected,
            reinitialisations=reinitialisations,
            actuator_force=actuator_force,
        )
        self.estimate_pub.publish(self.factory.make(messages.OBSERVER_ESTIMATE, fields))

    def health_counters(self) -> dict:
        last = self.timing.last_ns
        return {
            "state": self.loop_state(self.last_seen_tick),
            "last_tick": self.last_seen_tick,
            "processed": self.processed,
            "answered_again": self.answered_again,
            "bridged": self.bridged,
            "waited": self.waited,
            "refused": self.rejected,
            "reinitialisations": self.reinitialisations,
            "input_age_s": (time.monotonic_ns() - last) * 1e-9 if last is not None else None,
            **self.timing.summary(),
        }

    def close(self) -> None:
        super().close()
        print(
            f"observer_node: processed {self.processed} measurements "
            f"({self.answered_again} estimates again for a re-sent one); "
            f"{self.bridged} never arrived or were refused and were bridged; "
            f"{self.waited} before the loop was matched; {self.rejected} refused; "
            f"{self.reinitialisations} re-initialisations",
            file=sys.stderr,
            flush=True,
        )


def main(args: list[str] | None = None) -> int:
    return run_node("observer_node", ObserverNode, args)


if __name__ == "__main__":
    sys.exit(main())
