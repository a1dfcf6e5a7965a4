"""``ros2 run pac_controller controller_relay``: ``controller_node`` with a core that does no work.

The same node (name, parameters, topics, QoS, watchdog, run end) answering each
estimate with a command of the same tick (u = 0): the floor that ``make bench``
reads pac's loop timing against (rclpy + Fast DDS, no control law).
"""

from __future__ import annotations

import functools
import math
import sys

import numpy as np

from pac_common.node import run_node

from .controller import Command, Controller
from .controller_node import ControllerNode
from .laws import make_controller


class RelayController(Controller):
    """A :class:`Controller` whose ``compute`` does no work (no law, no limits)."""

    def compute(
        self,
        tick: int,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,
        actuator_force: float = math.nan,
    ) -> Command:
        self.last_tick = tick
        return Command(tick, tick * self.sample_period, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), False, "active")


class ControllerRelay(ControllerNode):
    CORE = staticmethod(functools.partial(make_controller, controller_class=RelayController))


def main(args: list[str] | None = None) -> int:
    return run_node("controller_relay", ControllerRelay, args)


if __name__ == "__main__":
    sys.exit(main())
