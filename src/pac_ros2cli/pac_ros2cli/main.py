"""``ros2 <verb> [<sub>] ...``: the dispatch table and the process's exit status.

Output shapes follow ros2cli's. Graph verbs wait for discovery a bounded, short time (see
:mod:`pac_ros2cli.graph`). `run` and `bag play|record|info` exec the program in place.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable

from . import bag, interface, lifecycle, node, param, pkg, run, topic
from .common import CliError

Command = Callable[[list[str]], int]

#: verb -> sub-verb -> function (``run`` takes no sub-verb: key ``""``). A branch adding a verb
#: adds its module and one entry here.
COMMANDS: dict[str, dict[str, Command]] = {
    "run": {"": run.run},
    "pkg": {"list": pkg.pkg_list, "executables": pkg.pkg_executables, "prefix": pkg.pkg_prefix},
    "topic": {
        "list": topic.topic_list,
        "echo": topic.topic_echo,
        "hz": topic.topic_hz,
        "info": topic.topic_info,
    },
    "node": {"list": node.node_list, "info": node.node_info},
    "param": {
        "list": param.param_list,
        "get": param.param_get,
        "set": param.param_set,
        "dump": param.param_dump,
        "describe": param.param_describe,
    },
    "interface": {
        "list": interface.interface_list,
        "package": interface.interface_package,
        "show": interface.interface_show,
    },
    "bag": {"info": bag.bag_info, "play": bag.bag_play, "record": bag.bag_record},
    "lifecycle": {
        "nodes": lifecycle.lifecycle_nodes,
        "get": lifecycle.lifecycle_get,
        "list": lifecycle.lifecycle_list,
        "set": lifecycle.lifecycle_set,
    },
}
#: Sub-verbs that stream until Ctrl-C: that is how they end (exit 0), as in ros2cli.
STREAMING = {("topic", "echo"), ("topic", "hz")}

USAGE = (
    "usage: ros2 run [--prefix CMD] <package> <executable> [args...]\n"
    "       ros2 pkg list | executables [<package>] | prefix <package>\n"
    "       ros2 topic list [-t] | echo <topic> [type] [--once] [--csv] | hz <topic> | info <topic> [-v]\n"
    "       ros2 node list [-a] | info <node>\n"
    "       ros2 param list <node> | get <node> <name> | set <node> <name> <value> | dump <node>\n"
    "                  | describe <node> <name>...\n"
    "       ros2 interface list | package <pkg> | show <pkg/msg/Name>\n"
    "       ros2 bag info <bag> | play <bag> [replay options] | record [-o <bag>] [-a | topics...]\n"
    "       ros2 lifecycle nodes | get [<node>] | list <node> | set <node> <transition>\n"
    "(minimal ros2 from scripts/bin: ros2cli is not installed here; <verb> -h for each verb's options)"
)


def resolve(argv: list[str]) -> tuple[Command, str, list[str]]:
    """(function, sub-verb, its arguments) for a command line; :class:`CliError` when none fits."""
    verb, rest = argv[0], argv[1:]
    table = COMMANDS.get(verb)
    if table is None:
        raise CliError(f"unknown verb '{verb}': this minimal ros2 provides {', '.join(COMMANDS)}", 2)
    if "" in table:
        return table[""], "", rest
    if not rest:
        raise CliError(f"'{verb}' needs arguments (ros2 {verb} -h for usage)", 2)
    sub = rest[0]
    if sub not in table:
        raise CliError(f"'{verb} {sub}' is not provided here; only '{verb} {'|'.join(table)}'", 2)
    return table[sub], sub, rest[1:]


def main(argv: list[str]) -> int:
    if not argv:
        print(USAGE, file=sys.stderr)
        return 2
    if argv[0] in ("-h", "--help") or (len(argv) > 1 and argv[1] in ("-h", "--help")):
        print(USAGE)
        return 0
    try:
        function, sub, rest = resolve(argv)
    except CliError as exc:
        print(f"ros2: {exc}", file=sys.stderr)
        return exc.code
    if argv[0] == "run" and not rest:
        print("ros2: 'run' needs arguments (ros2 run -h for usage)", file=sys.stderr)
        return 2
    # SIGTERM stops a streaming verb like Ctrl-C does (exit 0).
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        return function(rest)
    except CliError as exc:
        print(f"ros2: {exc}", file=sys.stderr)
        return exc.code
    except KeyboardInterrupt:  # Ctrl-C is how a streaming verb ends; anything else was cut short
        return 0 if (argv[0], sub) in STREAMING else 130
    except BrokenPipeError:  # `ros2 topic echo ... | head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
