"""``ros2 run pac_plant plant_node``: the simulated pantograph-catenary on the ROS graph.

Publishes ``measurement`` (FrameMeasurement: z1, z2 and the actuator force) and
``plant_truth`` (PlantTruth) each tick, applies the newest ``command``
(ActuatorCommand).  Two timing modes:

* ``realtime``: a wall-clock timer at ``rate_hz``.  The actuator is updated at the
  sample instants only (a DAC clocked with the loop): the force applied over
  [t_k, t_(k+1)] is the newest command received before the tick-k timer fires, so
  a command computed from y_(k-1) that arrives within one period is applied with
  exactly one tick of delay, and a later one waits for the next instant.  The
  round trip y_k -> u_k is measured on this node's clock.
* ``lockstep``: tick k+1 is taken only once the command for tick k is in; the
  force applied over [t_k, t_(k+1)] is the command of tick k - d
  (d = ``command_delay_ticks``), exactly as the offline simulator does.  A lost
  sample is recovered by re-sending the measurement after ``resend_timeout``.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rclpy.timer import Timer

from pac_common import diagnostics, messages
from pac_common.lifecycle import LifecycleOptions
from pac_common.node import LOOP_QOS, PUBLISH_QOS, RUN_STATUS_QOS, PacNode, run_node
from pac_common.parameters import LoopParameters, NodeOptions, ParameterSet, parameter
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

from .parameters import PlantOptions
from .plant import Plant
from .plants import make_plant, plant_kind

if TYPE_CHECKING:
    from .fe_plant import FEPlant


@dataclass(frozen=True)
class PlantNodeOptions(ParameterSet):
    timing_mode: str = parameter(
        "realtime",
        "'realtime': wall-clock loop at rate_hz; 'lockstep': advance when the command arrives",
        choices=("realtime", "lockstep"),
    )
    resend_timeout: float = parameter(
        0.01,
        "lockstep: re-send the measurement when no command came within this time",
        "s",
        low=0.001,
        high=10.0,
    )
    command_timeout_ticks: int = parameter(
        50,
        "realtime: hold the last command this many ticks, then apply passive_uplift",
        "ticks",
        low=1,
        high=1000000,
        runtime=True,
    )
    passive_uplift: float = parameter(
        100.0,
        "force applied after a command timeout (the static uplift of a passive pantograph)",
        "N",
        low=0.0,
        high=1000.0,
        runtime=True,
    )


class PlantNode(PacNode):
    PARAMETER_SETS = [
        PantographParameters,
        TrackParameters,
        CatenaryParameters,
        PlantOptions,
        LoopParameters,
        NodeOptions,
        PlantNodeOptions,
        LifecycleOptions,
    ]
    FROZEN_REASON = "the plant's model and timing are fixed for a run: restart the node to change it"
    #: The core; ``plant_relay`` swaps in one that does no work (the floor of ``make bench``).
    #: The plant's factory (lumped k(t) or the FE line, by catenary_model); ``plant_relay`` swaps in
    #: one that does no work (the floor of ``make bench``).
    CORE: Callable[..., Plant] = staticmethod(make_plant)
    HEALTH = "plant"

    def __init__(self) -> None:
        super().__init__("plant_node")

    def configure(self) -> None:
        loop = self.loop = self.parameters(LoopParameters)
        self.options = self.parameters(PlantNodeOptions)
        self.plant = self.CORE(  # catenary_model: lumped | fe
            self.parameters(PantographParameters),
            self.parameters(TrackParameters),
            self.parameters(CatenaryParameters),
            self.parameters(PlantOptions),
            loop.sample_period,
        )
        self.plant.warm_up()  # the compiled code loaded before the loop, not at its first tick
        self.measurement_pub = self.create_publisher(
            self.factory.cls(messages.FRAME_MEASUREMENT), "measurement", PUBLISH_QOS
        )
        self.truth_pub = self.create_publisher(
            self.factory.cls(messages.PLANT_TRUTH), "plant_truth", PUBLISH_QOS
        )
        # Every pantograph's truth, when the FE line carries several (docs/catenary.md).
        self.spacing = self.parameters(PlantOptions).pantographs
        self.fe_plant: FEPlant | None = None
        if (
            len(self.spacing) > 1
            and plant_kind(self.parameters(PlantOptions).catenary_model).several_pantographs
        ):
            from .fe_plant import several_pantographs  # here: a lumped plant node does not load the FE line

            # the rule the offline simulator records the topic by (a relay's plant reports nothing)
            self.fe_plant = several_pantographs(self.plant)
        self.pantographs_pub = (
            self.create_publisher(
                self.factory.cls(messages.PANTOGRAPH_TRUTH), "pantograph_truth", PUBLISH_QOS
            )
            if self.fe_plant is not None
            else None
        )
        self.run_status_pub = self.create_publisher(
            self.factory.cls(messages.RUN_STATUS), "run_status", RUN_STATUS_QOS
        )
        self.command_sub = self.create_subscription(
            self.factory.cls(messages.ACTUATOR_COMMAND), "command", self.on_command, LOOP_QOS
        )
        self.run_announced_end = False
        self.closing = False  # the last tick is out (real time: waiting for its command)
        self.closing_deadline = math.inf  # monotonic time after which closing gives up
        self.ticks_total = loop.ticks if loop.duration > 0 else math.inf
        # Command bookkeeping.
        self.latest: tuple[int, float] | None = None  # (tick, u) of the command received last
        self.latest_received_at = -1  # plant tick at which it arrived
        self.timeouts = 0
        self.timed_out = False
        self.pending: deque[tuple[int, float]] = deque([(-1, 0.0)] * loop.command_delay_ticks)
        self.applied_tick = -1  # command applied over the period that ends at the current tick
        self.applied_source = messages.COMMAND_PASSIVE
        self.sent_wall: dict[int, int] = {}  # tick -> wall ns of publishing its measurement
        self.latency: dict[int, float] = {}  # command tick -> round trip [s]
        self.last_sent = 0.0
        self.resends = 0
        self.tick_timer: Timer | None = None  # the real-time loop's (from tick 0's command)
        self.start_wall, self.start_tick = 0.0, 0
        self.late_ticks = 0  # ticks taken late, in a catch-up burst
        self.slips = 0  # times the schedule was reset because the loop fell too far behind
        self.timing = diagnostics.LoopTiming()  # tick wall times and applied round trips
        self.start_timer = self.create_timer(0.01, self.try_start)
        self.watch_start(self.missing)
        self.get_logger().info(
            f"{self.options.timing_mode} at {loop.rate_hz:g} Hz, {loop.duration:g} s "
            f"({'until stopped' if loop.duration == 0 else f'{loop.ticks} ticks'}); waiting for the loop"
        )

    def on_active_changed(self) -> None:
        if self.active and self.tick_timer is not None:
            # Re-activated mid-run: the schedule restarts now (no burst of the paused ticks).
            self.start_wall, self.start_tick = time.monotonic(), self.plant.tick

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        self.options = self.changed_or(changed, PlantNodeOptions, self.options)
        self.get_logger().info(
            f"command timeout {self.options.command_timeout_ticks} ticks, "
            f"passive uplift {self.options.passive_uplift:g} N"
        )

    # -- start-up: wait for the loop (and the recorder) to be matched, never a blind sleep ----------
    def missing(self) -> list[str]:
        """The peers the run still waits for, by name (empty: ready)."""
        recorder = int(self.waits_for_recorder)
        out = self.readers_missing(self.measurement_pub, "measurement", "an observer")
        if self.truth_pub.get_subscription_count() < recorder:
            out.append("a recorder subscribed to plant_truth (wait_for_recorder)")
        if self.command_sub.get_publisher_count() < 1:
            out.append("a controller publishing command")
        return out

    def ready(self) -> bool:
        return not self.missing()

    def try_start(self) -> None:
        if not self.active or not self.ready():
            return
        self.destroy_timer(self.start_timer)
        # Tick 0 is re-sent until its command comes back: that proves the whole loop (and, with
        # wait_for_recorder, every node's match with the recorder) is up. Then the run starts.
        self.get_logger().info("loop matched: closing it with tick 0")
        self.publish_run_status(messages.RUN_RUNNING)
        self.publish_tick()
        self.resend_timer = self.create_timer(self.options.resend_timeout / 2, self.on_resend_check)

    # -- publishing ----------------------------------------------------------------------------------
    def publish_tick(self) -> None:
        k = self.plant.tick
        stamp = messages.tick_stamp_ns(k, self.loop.rate_hz)
        now = time.time_ns()
        self.sent_wall[k] = now
        self.sent_wall.pop(k - 1000, None)
        self.measurement_pub.publish(
            self.factory.make(
                messages.FRAME_MEASUREMENT, messages.measurement_fields(self.plant.measurement(), stamp)
            )
        )
        self.last_sent = time.monotonic()
        round_trip = self.latency.pop(self.applied_tick, math.nan)
        self.timing.record(now, round_trip)
        self.truth_pub.publish(
            self.factory.make(
                messages.PLANT_TRUTH,
                messages.truth_fields(
                    self.plant.truth(),
                    stamp,
                    applied_command_tick=self.applied_tick,
                    command_source=self.applied_source,
                    command_timeouts=self.timeouts,
                    round_trip_latency=round_trip,
                    wall_stamp_ns=now,
                ),
            )
        )
        if self.pantographs_pub is not None and self.fe_plant is not None:
            self.pantographs_pub.publish(
                self.factory.make(
                    messages.PANTOGRAPH_TRUTH,
                    messages.pantograph_truth_fields(
                        self.fe_plant.pantograph_truths(), self.spacing, k, stamp
                    ),
                )
            )

    def publish_run_status(self, state: int) -> None:
        k = self.plant.tick
        model = self.parameters(PlantOptions).catenary_model
        data = getattr(self.plant, "data", None)  # the line file's data (its mean span)
        span = self.parameters(TrackParameters).span_length
        if plant_kind(model).line_from_file and data is not None:
            span = data.span
        fields = messages.run_status_fields(
            k, state, self.loop.duration, messages.tick_stamp_ns(k, self.loop.rate_hz), model, span
        )
        self.run_status_pub.publish(self.factory.make(messages.RUN_STATUS, fields))

    #: Real time: how long the plant keeps re-sending its last measurement for the last command.
    CLOSING_TIMEOUT = 1.0

    def end_run(self) -> None:
        """The last tick is out. Lock step: its command is in, done. Real time: close the loop first.

        In real time a best-effort sample can be lost; for the last tick nothing later would
        bridge it, so the plant re-sends it (as lock step does) until its command is back, at
        most CLOSING_TIMEOUT, and only then stops: the run's last command reaches the bag.
        """
        self.announce_end()
        self.closing = True
        if self.options.timing_mode == "lockstep" or self.tick_timer is None:
            self.finished = True
            return
        self.destroy_timer(self.tick_timer)
        self.closing_deadline = time.monotonic() + self.CLOSING_TIMEOUT
        self.create_timer(self.options.resend_timeout / 2, self.on_closing)

    def on_closing(self) -> None:
        if self.finished:
            return
        last = self.plant.tick
        if (self.latest is not None and self.latest[0] >= last) or time.monotonic() > self.closing_deadline:
            self.finished = True
        elif time.monotonic() - self.last_sent > self.options.resend_timeout:
            self.resend_measurement()

    def announce_end(self) -> None:
        """The run is over at the current tick (its last measurement is out): tell the followers."""
        if not self.run_announced_end:
            self.run_announced_end = True
            self.publish_run_status(messages.RUN_ENDED)

    def on_command(self, msg) -> None:
        if not self.active:
            return  # a managed plant, deactivated: the loop is paused
        tick, u = int(msg.tick), float(msg.u)
        if tick in self.sent_wall and tick not in self.latency:
            self.latency[tick] = (time.time_ns() - self.sent_wall[tick]) * 1e-9
        if not math.isfinite(u):
            self.get_logger().error(f"ignored a non-finite command for tick {tick}")
            return
        # The actuator applies what arrived last (fallback commands carry extrapolated ticks).
        self.latest = (tick, u)
        self.latest_received_at = self.plant.tick
        if tick != self.plant.tick or self.finished:
            return
        if self.options.timing_mode == "lockstep":
            self.pending.append((tick, u))
            applied_tick, applied_u = self.pending.popleft()
            self.advance(applied_tick, applied_u, messages.COMMAND_FRESH)
            if not self.finished:
                self.publish_tick()
        elif tick == 0 and self.tick_timer is None:
            # Real time starts now: over [t_0, t_1] nothing had arrived before t_0 (delay one tick).
            self.destroy_timer(self.resend_timer)
            self.latency.pop(0, None)  # tick 0's round trip includes the start-up handshake
            self.advance(-1, 0.0, messages.COMMAND_PASSIVE)
            self.start_wall, self.start_tick = time.monotonic(), self.plant.tick
            self.tick_timer = self.create_timer(self.loop.sample_period, self.on_realtime_tick)
            self.get_logger().info("real-time loop running")

    def advance(self, command_tick: int, u: float, source: int) -> None:
        """Apply u over [t_k, t_(k+1)]; finish after the last tick's command."""
        if self.plant.tick + 1 >= self.ticks_total:
            self.end_run()
            return
        self.plant.advance(u)
        self.applied_tick, self.applied_source = command_tick, source
        if len(self.latency) > 2000:  # round trips of commands never applied (overwritten)
            self.latency = {t: v for t, v in self.latency.items() if t >= command_tick - 100}

    def on_realtime_tick(self) -> None:
        """Take every tick that is due by the wall clock (a late wake-up catches up, as the
        physical plant would not have waited), at most MAX_CATCH_UP per wake-up."""
        if not self.active:
            return
        now = time.monotonic()
        due = self.start_wall + (self.plant.tick - self.start_tick) * self.loop.sample_period
        taken = 0
        while due <= now and not self.closing and taken < self.MAX_CATCH_UP:
            self.realtime_step()
            taken += 1
            due += self.loop.sample_period
        if taken > 1:
            self.late_ticks += taken - 1
        if taken == self.MAX_CATCH_UP:
            # Too far behind to catch up: slip the schedule rather than spin.
            self.start_wall, self.start_tick = time.monotonic(), self.plant.tick
            self.slips += 1

    MAX_CATCH_UP = 20

    def realtime_step(self) -> None:
        k = self.plant.tick
        if self.latest is None:
            command_tick, u, source = -1, 0.0, messages.COMMAND_PASSIVE
        elif k - self.latest_received_at > self.options.command_timeout_ticks:
            # Hold the last command for command_timeout_ticks, then the passive uplift.
            if not self.timed_out:
                self.timed_out = True
                self.timeouts += 1
                self.get_logger().warning(
                    f"tick {k}: no command for {k - self.latest_received_at} ticks: passive uplift "
                    f"{self.options.passive_uplift:g} N"
                )
            command_tick, u, source = -1, self.options.passive_uplift, messages.COMMAND_PASSIVE
        else:
            if self.timed_out:
                self.timed_out = False
                self.get_logger().info(f"tick {k}: commands again")
            command_tick, u = self.latest
            fresh = self.latest_received_at >= k - 1
            source = messages.COMMAND_FRESH if fresh else messages.COMMAND_HELD
        self.publish_tick()
        self.advance(command_tick, u, source)

    def on_resend_check(self) -> None:
        if self.tick_timer is not None or not self.active:
            return
        if not self.finished and time.monotonic() - self.last_sent > self.options.resend_timeout:
            self.resend_measurement()

    def resend_measurement(self) -> None:
        """The current tick's measurement again (the same sample: noise is a function of the tick)."""
        self.resends += 1
        k = self.plant.tick
        stamp = messages.tick_stamp_ns(k, self.loop.rate_hz)
        self.measurement_pub.publish(
            self.factory.make(
                messages.FRAME_MEASUREMENT, messages.measurement_fields(self.plant.measurement(), stamp)
            )
        )
        self.last_sent = time.monotonic()

    def health_counters(self) -> dict:
        if not self.sent_wall:
            state = "waiting"
        else:
            state = "ended" if self.run_announced_end else "running"
        return {
            "state": state,
            "waiting_for": "command subscribers and publishers"
            + (" and the recorder" if self.waits_for_recorder else ""),
            "last_tick": self.plant.tick,
            "timing_mode": self.options.timing_mode,
            "resends": self.resends,
            "late_ticks": self.late_ticks,
            "schedule_slips": self.slips,
            "command_timeouts": self.timeouts,
            "command_timed_out": self.timed_out,
            "command_age_ticks": self.plant.tick - self.latest_received_at if self.latest is not None else -1,
            **self.timing.summary(),
        }

    def close(self) -> None:
        if self.sent_wall:  # the run had started: a stop (SIGINT, SIGTERM) ends it too
            try:
                self.announce_end()
            except Exception:  # noqa: BLE001 - the context is already shut down: nothing to tell
                pass
        super().close()
        print(
            f"plant_node: stopped at tick {self.plant.tick} ({self.resends} measurement re-sends, "
            f"{self.late_ticks} ticks taken late, {self.slips} schedule slips, "
            f"{self.timeouts} command timeouts)",
            file=sys.stderr,
            flush=True,
        )


def main(args: list[str] | None = None) -> int:
    return run_node("plant_node", PlantNode, args)


if __name__ == "__main__":
    sys.exit(main())
