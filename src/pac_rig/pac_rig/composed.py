"""``ros2 run pac_rig composed [--relay] --ros-args --params-file FILE``: the loop in one process.

Runs ``observer_node``, ``controller_node`` and ``plant_node`` (``--relay``: the floor's relay
nodes) in one process with one executor, as a ROS 2 component container does: the same
nodes, topics, QoS and messages, delivered by Fast DDS within one participant, with no
process switch between plant, observer and controller.  Parameters go to each node by name
(one ``<node>:`` section per node in the params file); the process ends when every node has
finished (the plant its run; the observer and controller, with ``stop_after_run``, its last tick).
"""

from __future__ import annotations

import sys

from pac_common.node import run_nodes

from .nodes import LOOP_NODES, NODES


def main(args: list[str] | None = None) -> int:
    argv = list(sys.argv if args is None else args)
    end = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    relay = "--relay" in argv[1:end]
    if relay:
        argv.remove("--relay")
    if "--help" in argv[1:end] or "-h" in argv[1:end]:
        print(
            "usage: composed [--help] [--relay] [--ros-args --params-file FILE ...]\n\n"
            + (__doc__ or "").strip()
            + "\n\nThe nodes and their parameters:\n"
        )
    classes = [NODES[name].load(relay) for name in LOOP_NODES]
    return run_nodes("composed", classes, argv)


if __name__ == "__main__":
    sys.exit(main())
