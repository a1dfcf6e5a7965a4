"""``ros2 bag info | play | record``: the project's own tools (info, replay, recorder)."""

from __future__ import annotations

from .common import fail, parser
from .run import run


def bag_info(args: list[str]) -> int:
    return run(["pac_analysis", "info", *args])


def play_command(args: list[str]) -> list[str]:
    """``bag play`` arguments -> the `ros2 run pac_rig replay` command line."""
    p = parser("bag play")
    p.add_argument("bag")
    p.add_argument("-r", "--rate", type=float, default=1.0, help="time scale (0: as fast as possible)")
    p.add_argument("--topics", nargs="+", default=None, help="default: every pac topic in the bag")
    p.add_argument(
        "--wait-for", type=int, default=0, help="subscribers each topic needs before playing (default 0)"
    )
    p.add_argument("--timeout", type=float, default=30.0)
    a = p.parse_args(args)
    from pac_common.messages import TOPICS

    topics = [t.lstrip("/") for t in (a.topics or TOPICS)]
    return [
        "pac_rig",
        "replay",
        a.bag,
        "--topics",
        *topics,
        "--rate",
        repr(a.rate),
        "--wait-for",
        str(a.wait_for),
        "--timeout",
        repr(a.timeout),
    ]


def bag_play(args: list[str]) -> int:
    return run(play_command(args))


def record_command(args: list[str]) -> list[str]:
    """``bag record`` arguments -> the `ros2 run pac_rig recorder` command line."""
    p = parser("bag record")
    p.add_argument("topics", nargs="*", help="topics to record")
    p.add_argument("-a", "--all", action="store_true", help="every pac topic and /diagnostics")
    p.add_argument("-o", "--output", help="bag directory (must not exist; default bags/run_<date>_<time>)")
    p.add_argument("-s", "--storage", default="mcap", choices=["mcap"])
    # Everything after --ros-args is the recorder's (argparse would take `x:=y` for a topic).
    cut = args.index("--ros-args") if "--ros-args" in args else len(args)
    a = p.parse_args(args[:cut])
    ros_args = args[cut:]
    if not a.all and not a.topics:
        fail("bag record: give the topics to record, or -a for all", 2)
    params = []
    if a.output:
        params += ["-p", f"bag_path:={a.output}"]
    if not a.all:
        params += ["-p", "topics:=" + ",".join(t.lstrip("/") for t in a.topics)]
    extra = ros_args[1:] if ros_args else []
    return ["pac_rig", "recorder", "--ros-args", *params, *extra]


def bag_record(args: list[str]) -> int:
    return run(record_command(args))
