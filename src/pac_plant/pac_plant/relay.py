"""``ros2 run pac_plant plant_relay``: ``plant_node`` with a core that does no work.

The same node (name, parameters, timers, topics, QoS, message types, start-up
handshake, real-time and lock-step logic, run end) with the plant's integration
swapped out: what is left is the cost of rclpy and Fast DDS on this machine, the
floor that ``make bench`` reads pac's loop timing against.  Its physics is
meaningless (the state stays at rest); its ticks and timing are the real node's.
"""

from __future__ import annotations

import sys

from pac_common.node import run_node

from .plant import Plant, Truth
from .plant_node import PlantNode


class RelayPlant(Plant):
    """A :class:`Plant` whose ``advance`` only moves the tick (no RK4, no model evaluation)."""

    def advance(self, u: float) -> None:
        self.tick += 1
        self.u_applied = float(u)

    def truth(self) -> Truth:
        return Truth(self.tick, self.time, (0.0, 0.0, 0.0, 0.0), 0.0, 0.0, False, self.u_applied)


class PlantRelay(PlantNode):
    CORE = RelayPlant


def main(args: list[str] | None = None) -> int:
    return run_node("plant_relay", PlantRelay, args)


if __name__ == "__main__":
    sys.exit(main())
