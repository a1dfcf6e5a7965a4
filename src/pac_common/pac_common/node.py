"""The names a pac node module needs, from the modules that hold them (one job each).

``from pac_common.node import PacNode, run_node, LOOP_QOS`` keeps working; new code may import
from the modules themselves:

- :mod:`pac_common.qos`: the QoS profiles of every topic;
- :mod:`pac_common.ros_parameters`: pac parameter sets as typed ROS parameters;
- :mod:`pac_common.pac_node`: the PacNode base and the run's start/end protocol;
- :mod:`pac_common.scheduling`: SCHED_FIFO for a node's process;
- :mod:`pac_common.executor`: the executor;
- :mod:`pac_common.command_line`: command line, params files and ROS_DOMAIN_ID checks;
- :mod:`pac_common.node_help`: ``--help``;
- :mod:`pac_common.process`: the process loop (start, spin, clean stop);
- :mod:`pac_common.discovery`: loopback-only discovery, set before rclpy starts.

Importing this module changes nothing in the environment.
"""

from __future__ import annotations

import rclpy

from .command_line import MAX_DOMAIN_ID, UsageError, check_domain_id, check_ros_arguments
from .discovery import loopback_only
from .executor import make_executor
from .node_help import node_help
from .pac_node import PacNode
from .process import run_node, run_nodes
from .qos import LOOP_QOS, PUBLISH_QOS, RECORD_QOS, RECORD_QOS_COMPATIBLE, RUN_STATUS_QOS
from .ros_parameters import declare_parameter_sets, given_parameter_names, parameter_names, validate_changes
from .scheduling import process_threads, set_realtime_priority

__all__ = [
    "LOOP_QOS",
    "MAX_DOMAIN_ID",
    "PUBLISH_QOS",
    "RECORD_QOS",
    "RECORD_QOS_COMPATIBLE",
    "RUN_STATUS_QOS",
    "PacNode",
    "UsageError",
    "check_domain_id",
    "check_ros_arguments",
    "declare_parameter_sets",
    "given_parameter_names",
    "loopback_only",
    "make_executor",
    "node_help",
    "parameter_names",
    "process_threads",
    "rclpy",
    "run_node",
    "run_nodes",
    "set_realtime_priority",
    "validate_changes",
]
