"""``ros2 run pac_controller controller_node``: backstepping (eq. (43)) on the ROS graph.

Subscribes ``estimate`` (ObserverEstimate), publishes ``command`` (ActuatorCommand)
for the same tick.  A repeated tick (a lock-step re-send) re-publishes the last
command; an estimate that is not finite never reaches the actuator.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from pac_common.node import (
    LOOP_QOS,
    Node,
    declare_parameter_sets,
    refuse_runtime_changes,
    run_node,
    set_realtime_priority,
)
from pac_common.parameters import NodeOptions, RateParameters
from pac_plant.parameters import PantographParameters, TrackParameters

from pac_common import messages

from .backstepping import BacksteppingController
from .parameters import ControllerParameters, ReferenceParameters

PARAMETER_SETS = [
    PantographParameters,
    TrackParameters,
    ControllerParameters,
    ReferenceParameters,
    RateParameters,
    NodeOptions,
]


class ControllerNode(Node):
    def __init__(self) -> None:
        super().__init__("controller_node")
        panto, track, params, reference, loop, node_opts = declare_parameter_sets(self, PARAMETER_SETS)
        refuse_runtime_changes(
            self,
            [n for n in self._parameters if n != "use_sim_time"],
            "runtime changes are not supported yet: restart the node to change them",
        )
        self.loop: RateParameters = loop
        self.node_options: NodeOptions = node_opts
        set_realtime_priority(self, node_opts.realtime_priority)
        self.core = BacksteppingController(panto, track, params, reference, loop.sample_period)
        self.factory = messages.RclpyFactory()
        self.command_pub = self.create_publisher(
            self.factory.cls(messages.ACTUATOR_COMMAND), "command", LOOP_QOS
        )
        self.create_subscription(
            self.factory.cls(messages.OBSERVER_ESTIMATE), "estimate", self.on_estimate, LOOP_QOS
        )
        self.last_tick = -1
        self.last_message = None
        self.sent = 0
        self.skipped = 0  # estimates that never arrived (tick gaps)

    def ready(self) -> bool:
        return self.command_pub.get_subscription_count() >= 1 + int(self.node_options.wait_for_recorder)

    def on_estimate(self, msg) -> None:
        tick = int(msg.tick)
        if tick <= self.last_tick:
            if tick == self.last_tick and self.last_message is not None:
                self.command_pub.publish(self.last_message)  # lock-step re-send
            return
        if not self.ready():
            return
        z_hat = np.asarray(msg.z_hat, dtype=float)
        theta_hat = np.asarray(msg.theta_hat, dtype=float)
        if not (np.all(np.isfinite(z_hat)) and np.all(np.isfinite(theta_hat))):
            self.get_logger().error(f"tick {tick}: non-finite estimate, no command sent")
            return
        try:
            cmd = self.core.compute(tick, z_hat, theta_hat)
        except ValueError as exc:
            self.get_logger().error(f"tick {tick}: {exc}; no command sent")
            return
        if not math.isfinite(cmd.u):
            return
        if self.last_tick >= 0:
            self.skipped += tick - self.last_tick - 1
        self.last_tick = tick
        self.sent += 1
        stamp = messages.tick_stamp_ns(tick, self.loop.rate_hz)
        self.last_message = self.factory.make(messages.ACTUATOR_COMMAND, messages.command_fields(cmd, stamp))
        self.command_pub.publish(self.last_message)

    def close(self) -> None:
        print(
            f"controller_node: sent {self.sent} commands; {self.skipped} estimates never arrived",
            file=sys.stderr,
            flush=True,
        )


def main(args: list[str] | None = None) -> int:
    return run_node("controller_node", ControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
