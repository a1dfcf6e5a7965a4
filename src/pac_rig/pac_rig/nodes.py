"""The rig's nodes, one registry: role -> package, executable, node class, relay.

The role (``plant``, ``observer``, ``controller``, ``recorder``) is the name the rig, the
launcher and the tests use; the executable (``plant_node``) is what ``ros2 run`` starts and
the ROS node's name; the class is the ``PacNode`` subclass whose ``PARAMETER_SETS`` give the
node's parameters (``config/<executable>.yaml``, ``--help``); the relay is the same node with
a core that does no work (the floor of ``make bench``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class RigNode:
    package: str
    executable: str
    node_class: str  # "module:PacNode subclass"
    relay_executable: str
    relay_class: str | None  # None: the node has no relay (the recorder is the same in the floor)

    def load(self, relay: bool = False) -> Any:
        """The node's class (``relay``: its relay's)."""
        path = self.relay_class if relay and self.relay_class else self.node_class
        module, _, name = path.partition(":")
        return getattr(importlib.import_module(module), name)

    def module(self, relay: bool = False) -> str:
        """The module whose ``python -m`` runs the node (its ``main``; ``relay``: its relay's)."""
        path = self.relay_class if relay and self.relay_class else self.node_class
        return path.partition(":")[0]

    def parameter_sets(self) -> list[Any]:
        """The parameter sets the node declares (its class's ``PARAMETER_SETS``)."""
        return list(self.load().PARAMETER_SETS)


NODES: dict[str, RigNode] = {
    "recorder": RigNode("pac_rig", "recorder", "pac_rig.recorder:RecorderNode", "recorder", None),
    "observer": RigNode(
        "pac_observer",
        "observer_node",
        "pac_observer.observer_node:ObserverNode",
        "observer_relay",
        "pac_observer.relay:ObserverRelay",
    ),
    "controller": RigNode(
        "pac_controller",
        "controller_node",
        "pac_controller.controller_node:ControllerNode",
        "controller_relay",
        "pac_controller.relay:ControllerRelay",
    ),
    "plant": RigNode(
        "pac_plant",
        "plant_node",
        "pac_plant.plant_node:PlantNode",
        "plant_relay",
        "pac_plant.relay:PlantRelay",
    ),
}
#: The closed loop's nodes, in the order they start (the plant last: it waits for the others).
LOOP_NODES = ("observer", "controller", "plant")
