"""``ros2 run pac_observer observer_node``: the adaptive observer (eq. (17)) on the ROS graph.

Subscribes ``measurement`` (FrameMeasurement), publishes ``estimate``
(ObserverEstimate) for the same tick.  A repeated tick (a lock-step re-send)
re-publishes the last estimate; a gap (lost samples) is bridged by the core.
"""

from __future__ import annotations

import math
import sys

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

from .observer import AdaptiveObserver, ObserverDivergedError
from .parameters import ObserverParameters

PARAMETER_SETS = [PantographParameters, TrackParameters, ObserverParameters, RateParameters, NodeOptions]


class ObserverNode(Node):
    def __init__(self) -> None:
        super().__init__("observer_node")
        panto, track, params, loop, node_opts = declare_parameter_sets(self, PARAMETER_SETS)
        refuse_runtime_changes(
            self,
            [n for n in self._parameters if n != "use_sim_time"],
            "the observer's model and tuning are fixed for a run: restart the node to change them",
        )
        self.loop: RateParameters = loop
        self.node_options: NodeOptions = node_opts
        set_realtime_priority(self, node_opts.realtime_priority)
        self.core = AdaptiveObserver(panto, track, params, loop.sample_period)
        self.factory = messages.RclpyFactory()
        self.estimate_pub = self.create_publisher(
            self.factory.cls(messages.OBSERVER_ESTIMATE), "estimate", LOOP_QOS
        )
        self.create_subscription(
            self.factory.cls(messages.FRAME_MEASUREMENT), "measurement", self.on_measurement, LOOP_QOS
        )
        self.last_message = None
        self.reinitialisations = 0
        self.rejected = 0
        self.waited = 0
        self.processed = 0
        self.bridged = 0  # samples never received, bridged by the core

    def ready(self) -> bool:
        return self.estimate_pub.get_subscription_count() >= 1 + int(self.node_options.wait_for_recorder)

    def on_measurement(self, msg) -> None:
        tick = int(msg.tick)
        if self.last_message is not None and tick <= self.core.tick:
            if tick == self.core.tick:
                self.estimate_pub.publish(self.last_message)  # lock-step re-send
            return
        if not self.ready():
            self.waited += 1  # nobody to tell yet; lock step re-sends, real time moves on
            return
        y = (float(msg.z1), float(msg.z2))
        if not all(math.isfinite(v) for v in (*y, float(msg.actuator_force))):
            self.rejected += 1
            self.get_logger().warning(f"tick {tick}: non-finite measurement ignored")
            return
        status = messages.STATUS_OK
        if self.core.tick >= 0:
            self.bridged += tick - self.core.tick - 1
        self.processed += 1
        try:
            est = self.core.update(tick, y, float(msg.actuator_force))
        except ObserverDivergedError as exc:
            self.reinitialisations += 1
            self.get_logger().error(f"{exc}; re-initialising")
            self.core.reset()
            est = self.core.update(tick, y, float(msg.actuator_force))
            status = messages.STATUS_REINITIALISED
        stamp = messages.tick_stamp_ns(tick, self.loop.rate_hz)
        self.last_message = self.factory.make(
            messages.OBSERVER_ESTIMATE,
            messages.estimate_fields(
                est, stamp, status=status, rejected=self.rejected, reinitialisations=self.reinitialisations
            ),
        )
        self.estimate_pub.publish(self.last_message)

    def close(self) -> None:
        print(
            f"observer_node: processed {self.processed} measurements; "
            f"{self.bridged} never arrived and were bridged; "
            f"{self.waited} before the loop was matched; {self.rejected} rejected; "
            f"{self.reinitialisations} re-initialisations",
            file=sys.stderr,
            flush=True,
        )


def main(args: list[str] | None = None) -> int:
    return run_node("observer_node", ObserverNode, args)


if __name__ == "__main__":
    sys.exit(main())
