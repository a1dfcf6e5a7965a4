"""``ros2 run pac_controller controller_node``: the force controller on the ROS graph.

``-p law:=<name>`` selects the control law (adaptive_backstepping, the default, eq. (43);
backstepping_known; pid; lqr; passive; line_adaptive: pac_controller.laws, docs/laws.md), or
``-p law:=path/to/my_law.py`` a user's law file (pac_controller.user_law); the law is fixed for a
run.  ``mode:=passive`` is deprecated (law:=passive), still honoured with a warning.

Subscribes ``estimate`` (ObserverEstimate), publishes ``command`` (ActuatorCommand)
for the same tick.  Safety: a non-finite estimate never reaches the actuator (the
core answers it with the fallback command), and a watchdog publishes the fallback
command (the static uplift ``fallback_force``, within the slew limit; mode
FALLBACK) when no fresh estimate came for ``watchdog_ticks`` ticks; the first
fresh estimate returns the loop to active control.  Gains, reference, limits and
mode may be changed at run time (validated like at start).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from pac_common import diagnostics, messages
from pac_common.lifecycle import LifecycleOptions
from pac_common.node import LOOP_QOS, PUBLISH_QOS, PacNode, run_node
from pac_common.parameters import NodeOptions, ParameterSet, RateParameters, RunEndOptions, parameter
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

from .controller import Command, Controller, watchdog_fallback_tick
from .laws import NEEDS_CATENARY, make_controller
from .parameters import ControllerParameters, LawParameters, ReferenceParameters


@dataclass(frozen=True)
class EstimateLimits(ParameterSet):
    """What the controller accepts as an estimate at all (else: the fallback command)."""

    estimate_position_limit: float = parameter(
        0.5,
        "|z_hat_1|, |z_hat_2| beyond this is implausible",
        "m",
        low=0.0,
        low_open=True,
        high=10.0,
        runtime=True,
    )
    estimate_velocity_limit: float = parameter(
        20.0,
        "|z_hat_3|, |z_hat_4| beyond this is implausible",
        "m/s",
        low=0.0,
        low_open=True,
        high=1000.0,
        runtime=True,
    )
    estimate_stiffness_limit: float = parameter(
        1e6, "|theta_hat_i| beyond this is implausible", "N/m", low=0.0, low_open=True, runtime=True
    )
    max_tick_jump: int = parameter(
        10000,
        "an estimate more than this many ticks ahead of the last one, beyond the ticks the wall "
        "clock has let pass since that one, is implausible",
        "ticks",
        low=1,
        runtime=True,
    )


class ControllerNode(PacNode):
    PARAMETER_SETS = [
        PantographParameters,
        TrackParameters,
        ControllerParameters,
        ReferenceParameters,
        LawParameters,
        # Read by law:=backstepping_known only (the oracle is told the true catenary).
        CatenaryParameters,
        RateParameters,
        NodeOptions,
        RunEndOptions,
        EstimateLimits,
        LifecycleOptions,
    ]
    FROZEN_REASON = "fixed for a run (model, speed, rate, control law): restart the node to change it"
    #: The core's factory; ``controller_relay`` swaps in one that does no work (the floor of
    #: ``make bench``).
    CORE: Callable[..., Controller] = staticmethod(make_controller)
    HEALTH = "controller"

    def __init__(self) -> None:
        super().__init__("controller_node")

    def configure(self) -> None:
        params = self.parameters(ControllerParameters)
        if params.mode == "passive":
            self.get_logger().warning("parameter 'mode' is deprecated: use law:=passive")
        self.laws = self.parameters(LawParameters)
        self.limits = self.parameters(EstimateLimits)
        self.loop = self.parameters(RateParameters)
        self.pantograph, self.track = self.parameters(PantographParameters), self.parameters(TrackParameters)
        # Only the oracle law is told the catenary.
        self.catenary = (
            self.parameters(CatenaryParameters) if params.effective_law in NEEDS_CATENARY else None
        )
        self.core = self.CORE(
            self.pantograph,
            self.track,
            params,
            self.parameters(ReferenceParameters),
            self.loop.sample_period,
            self.laws,
            self.catenary,
        )
        self.core.warm_up()  # the compiled code loaded before the loop, not at its first tick
        self.get_logger().info(f"control law: {self.core.name}")
        self.command_pub = self.create_publisher(
            self.factory.cls(messages.ACTUATOR_COMMAND), "command", PUBLISH_QOS
        )
        self.create_subscription(
            self.factory.cls(messages.OBSERVER_ESTIMATE), "estimate", self.on_estimate, LOOP_QOS
        )
        self.follow_run()
        self.watch_start(self.missing)
        self.last_estimate_tick = -1
        self.last_estimate_wall: float | None = None
        self.last_accepted_wall: float | None = None  # when the last accepted estimate arrived
        self.last_answer: Command | None = None  # the command that answered the last fresh estimate
        self.in_fallback = False
        self.sent = 0
        self.answered_again = 0  # answers re-published for a re-sent estimate (the tick-0 handshake)
        self.skipped = 0  # estimates that never arrived (tick gaps)
        self.fallback_commands = 0
        self.fallback_episodes = 0
        self.nonfinite = 0
        self.timing = diagnostics.LoopTiming()  # estimate arrivals and handling times
        period = self.loop.sample_period * max(1, self.core.params.watchdog_ticks // 4)
        self.create_timer(period, self.on_watchdog)

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        params = self.changed_or(changed, ControllerParameters, self.core.params)
        reference = self.changed_or(changed, ReferenceParameters, self.core.reference.params)
        state = (self.core.last_u, self.core.last_tick)
        # Built first: a law that cannot be built again (a user's law file edited since the start,
        # user_law.load_law_file) refuses the whole change and the running core stays.
        core = self.CORE(
            self.pantograph, self.track, params, reference, self.loop.sample_period, self.laws, self.catenary
        )
        self.core, self.limits = core, self.changed_or(changed, EstimateLimits, self.limits)
        # The actuator does not jump on a retune; a law with state restarts bumplessly from it.
        self.core.last_u, self.core.last_tick = state
        self.get_logger().info(
            f"parameters changed: law {self.core.name}, c = ({params.c1:g}, {params.c2:g}, "
            f"{params.c3:g}), reference {reference.shape} {reference.force_amplitude:g} N"
        )

    def missing(self) -> list[str]:
        """The peers this node's output still waits for, by name (empty: ready)."""
        return self.readers_missing(self.command_pub, "command", "a plant")

    def ready(self) -> bool:
        return self.active and self.command_pub.get_subscription_count() >= 1 + int(self.waits_for_recorder)

    def publish(self, cmd, estimate_age_ticks: int) -> None:
        stamp = messages.tick_stamp_ns(cmd.tick, self.loop.rate_hz)
        # The factory refills one message object per type: never keep it, re-make it.
        self.command_pub.publish(
            self.factory.make(
                messages.ACTUATOR_COMMAND,
                messages.command_fields(cmd, stamp, estimate_age_ticks=estimate_age_ticks),
            )
        )

    def plausible_tick(self, tick: int) -> bool:
        """Not further ahead of the last accepted estimate than the loop can have gone."""
        # The wall-clock allowance only where the plain limit is passed (not on every 1 kHz tick).
        ahead = tick - self.last_estimate_tick
        if self.last_estimate_tick < 0 or ahead <= self.limits.max_tick_jump:
            return True
        return ahead <= self.allowed_tick_jump()

    def plausible(self, tick: int, z_hat: np.ndarray, theta_hat: np.ndarray) -> bool:
        lim = self.limits
        if not (np.isfinite(z_hat).all() and np.isfinite(theta_hat).all()):
            return False
        if not self.plausible_tick(tick):
            return False
        return bool(
            np.all(np.abs(z_hat[:2]) <= lim.estimate_position_limit)
            and np.all(np.abs(z_hat[2:]) <= lim.estimate_velocity_limit)
            and np.all(np.abs(theta_hat) <= lim.estimate_stiffness_limit)
        )

    def allowed_tick_jump(self) -> int:
        """How far ahead of the last accepted estimate a new one may be: max_tick_jump, plus the
        ticks a real-time plant can have advanced since that estimate arrived. Without the
        wall-clock part, an observer restarted after more than max_tick_jump ticks (a slow
        process start on a loaded machine) would be refused for ever: its ticks are the plant's."""
        return self.limits.max_tick_jump + int(math.ceil(1.05 * self.ticks_since_accepted()))

    def ticks_since_accepted(self) -> float:
        """Periods of wall time since the last accepted estimate arrived (0 before the first)."""
        since = 0.0 if self.last_accepted_wall is None else time.monotonic() - self.last_accepted_wall
        return since / self.loop.sample_period

    def on_estimate(self, msg) -> None:
        start_ns = time.monotonic_ns()
        tick = int(msg.tick)
        z_hat, theta_hat = np.asarray(msg.z_hat, dtype=float), np.asarray(msg.theta_hat, dtype=float)
        if not self.plausible(tick, z_hat, theta_hat):
            # Never reaches the law; answered with the fallback command. Not a fresh estimate:
            # it moves neither the tick tracking nor the watchdog.
            self.nonfinite += 1
            self.get_logger().error(
                f"tick {tick}: non-finite or implausible estimate: fallback command",
                throttle_duration_sec=1.0,
            )
            # Its tick only where that tick is plausible: a garbage tick far ahead would let the
            # slew limit allow any jump (the limit is per tick) and stamp the command with it.
            if not self.plausible_tick(tick):
                tick = self.last_estimate_tick + int(self.ticks_since_accepted())
            self.publish(self.core.fallback(max(tick, self.core.last_tick + 1)), 0)
            return
        if tick == 0 and self.last_estimate_tick > 0:
            self.get_logger().warning(f"estimate tick went back from {self.last_estimate_tick} to 0: new run")
            self.last_estimate_tick, self.last_answer = -1, None
            self.run_new()
        if self.past_run_end(tick):
            return  # idle: the run is over (a new run starts again at tick 0)
        if tick <= self.last_estimate_tick:
            if tick == self.last_estimate_tick and self.last_answer is not None:
                self.answered_again += 1
                self.publish(self.last_answer, 0)  # the answer to a re-sent sample, again
            return
        if not self.ready():
            return
        if self.last_estimate_tick >= 0:
            self.skipped += tick - self.last_estimate_tick - 1
        self.last_estimate_tick = tick
        self.last_accepted_wall = time.monotonic()
        # Tick 0 is the plant's start-up handshake (re-sent until answered, the real-time loop
        # starts after it): the watchdog arms with the loop itself, from tick 1.
        self.last_estimate_wall = time.monotonic() if tick > 0 else None
        cmd = self.core.compute(
            tick, z_hat, theta_hat, float(msg.contact_force_hat), float(msg.actuator_force)
        )
        if self.in_fallback:
            self.in_fallback = False
            self.get_logger().info(f"tick {tick}: fresh estimates again: back to {cmd.mode} control")
        self.sent += 1
        self.last_answer = cmd
        self.publish(cmd, 0)
        self.timing.record(start_ns, (time.monotonic_ns() - start_ns) * 1e-9)
        self.handled_tick(tick)

    def on_watchdog(self) -> None:
        if (
            not self.active
            or self.last_estimate_wall is None
            or self.core.params.watchdog_ticks == 0
            or self.run_ended
        ):
            return  # the loop has not started yet, the watchdog is off, or the run is over
        age, tick = watchdog_fallback_tick(
            time.monotonic() - self.last_estimate_wall,
            self.loop.sample_period,
            self.core.params.watchdog_ticks,
            self.last_estimate_tick,
            self.core.last_tick,
        )
        if tick is None:
            return
        if not self.in_fallback:
            self.in_fallback = True
            self.fallback_episodes += 1
            self.get_logger().warning(
                f"no fresh estimate for {age} ticks: fallback to "
                f"{self.core.params.fallback_force:g} N static uplift"
            )
        self.fallback_commands += 1
        self.publish(self.core.fallback(tick), age)

    def health_counters(self) -> dict:
        last = self.timing.last_ns
        wall = self.last_estimate_wall
        age = int((time.monotonic() - wall) / self.loop.sample_period) if wall is not None else 0
        return {
            "state": self.loop_state(self.last_estimate_tick),
            "last_tick": self.last_estimate_tick,
            "law": self.core.name,
            "sent": self.sent,
            "answered_again": self.answered_again,
            "skipped": self.skipped,
            "fallback_active": self.in_fallback,
            "estimate_age_ticks": age,
            "fallback_force": self.core.params.fallback_force,
            "fallback_commands": self.fallback_commands,
            "fallback_episodes": self.fallback_episodes,
            "refused": self.nonfinite,
            "input_age_s": (time.monotonic_ns() - last) * 1e-9 if last is not None else None,
            **self.timing.summary(),
        }

    def close(self) -> None:
        super().close()
        print(
            f"controller_node: sent {self.sent} commands ({self.answered_again} answers again to a "
            f"re-sent estimate); {self.skipped} estimates never arrived; "
            f"{self.fallback_commands} fallback commands in {self.fallback_episodes} episodes; "
            f"{self.nonfinite} non-finite or implausible estimates refused",
            file=sys.stderr,
            flush=True,
        )


def main(args: list[str] | None = None) -> int:
    return run_node("controller_node", ControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
