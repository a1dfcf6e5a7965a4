"""``ros2 run pac_observer observer_relay``: ``observer_node`` with a core that does no work.

The same node (name, parameters, topics, QoS, tick tracking, run end) answering each
measurement with an estimate of the same tick whose values are zero: the floor that
``make bench`` reads pac's loop timing against (rclpy + Fast DDS, no observer).
"""

from __future__ import annotations

import math
import sys

import numpy as np

from pac_common.node import run_node

from .observer import AdaptiveObserver, Estimate
from .observer_node import ObserverNode


class RelayObserver(AdaptiveObserver):
    """An :class:`AdaptiveObserver` whose ``update`` only records the tick (no eq. (17))."""

    _ZEROS2, _ZEROS3, _ZEROS4 = np.zeros(2), np.zeros(3), np.zeros(4)

    def update(
        self, tick: int, y: tuple[float, float], actuator_force: float, head_acceleration: float = math.nan
    ) -> Estimate:
        self.tick = tick
        return Estimate(tick, tick * self.sample_period, self._ZEROS4, self._ZEROS3, 0.0, 0.0, self._ZEROS2)


class ObserverRelay(ObserverNode):
    CORE = RelayObserver


def main(args: list[str] | None = None) -> int:
    return run_node("observer_relay", ObserverRelay, args)


if __name__ == "__main__":
    sys.exit(main())
