"""``ros2 run pac_rig rig_params``: one ROS 2 parameter file for the rig's nodes started by hand.

A run's values (``-p name:=value``, ``--params-file``, a whole ``-p scenario:=NAME|PATH``) are
given once, for the whole rig, and composed as the launcher composes them (``pac_rig.launcher``):
the scenario file's values under yours, each value to the nodes that have it, and what the parts
derive from each other (the observer a law needs, the actuator's range, the line's span and its
map, the law's design for the actuator). The file has one section per node, by node name, so
every node takes the same file and reads its own section::

    ros2 run pac_rig rig_params -p scenario:=realistic_electromechanical -p law:=line_adaptive -o rig.yaml
    ros2 run pac_rig recorder --ros-args -p bag_path:=bags/run
    ros2 run pac_plant plant_node --ros-args --params-file rig.yaml
    ros2 run pac_observer observer_node --ros-args --params-file rig.yaml
    ros2 run pac_controller controller_node --ros-args --params-file rig.yaml

A node given ``-p scenario:=...`` itself is refused with one line naming this command: a node
alone cannot compose what depends on the others' parameters (docs/usage.md, "By hand").
Values that cannot be read, a scenario file that is not valid, or parts that do not fit are
refused in one line, exit 2, and no file is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import yaml

from pac_common.data_file import DataFileError
from pac_common.parameters import LoopParameters, ParameterError
from pac_plant.plant_node import PlantNodeOptions

from .cli import OverrideError, add_override_arguments, overrides_from_args, without_ros_args
from .launcher import node_parameters, params_file_sections
from .nodes import LOOP_NODES

#: The plant's run-control values the launcher takes as its own arguments.
RUN_CONTROL = ("duration", "timing_mode")


def rig_parameters(values: dict[str, Any], record: bool = False) -> dict[str, dict[str, Any]]:
    """Each loop node's parameters for a run of ``values`` (the rig's flat names, ``scenario``
    included), composed as the launcher composes them (:func:`~pac_rig.launcher.node_parameters`);
    ``record``: the plant waits for a recorder before its first tick."""
    values = dict(values)
    run = {name: values.pop(name) for name in RUN_CONTROL if name in values}
    params = node_parameters(
        {"all": values},
        duration=float(run.get("duration", LoopParameters().duration)),
        timing_mode=str(run.get("timing_mode", PlantNodeOptions().timing_mode)),
        record=record,
        priorities={},
    )
    return {name: params[name] for name in LOOP_NODES}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rig_params", description=__doc__.split("\n\n")[0])
    add_override_arguments(parser)
    parser.add_argument("-o", "--output", type=Path, help="the file to write (default: standard output)")
    parser.add_argument(
        "--record", action="store_true", help="the plant waits for a recorder before its first tick"
    )
    args = parser.parse_args(without_ros_args(list(sys.argv[1:] if argv is None else argv)))
    try:
        params = rig_parameters(overrides_from_args(args), record=args.record)
    except (OverrideError, ParameterError, DataFileError, ValueError) as exc:
        print(f"rig_params: {exc}", file=sys.stderr)
        return 2
    text = yaml.safe_dump(params_file_sections(params), sort_keys=True)
    if args.output is None:
        sys.stdout.write(text)
    else:
        try:
            args.output.write_text(text)
        except OSError as exc:
            print(f"rig_params: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
