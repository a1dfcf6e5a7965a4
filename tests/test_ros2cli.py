"""The ros2 stand-in (pac_ros2cli) in-process, without DDS: dispatch, parsing and output shapes.

The same verbs against a live rig are in test_cli.py and test_suite.py.
"""

import pytest
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, ParameterType

from pac_ros2cli import bag, main, param, topic
from pac_ros2cli.common import CliError, plain, split_type
from pac_ros2cli.graph import Graph
from pac_ros2cli.interface import show_lines

pytestmark = pytest.mark.unit


def test_every_verb_and_sub_verb_resolves_to_its_own_function():
    functions = [f for table in main.COMMANDS.values() for f in table.values()]
    assert len(functions) == len(set(functions))  # one function per verb
    for verb, table in main.COMMANDS.items():
        for sub, function in table.items():
            resolved, got_sub, rest = main.resolve([verb, *([sub] if sub else []), "x"])
            assert (resolved, got_sub, rest) == (function, sub, ["x"])
    assert main.COMMANDS["param"]["describe"] is param.param_describe


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["frobnicate"], "unknown verb 'frobnicate'"),
        (["topic", "pub"], "'topic pub' is not provided here; only 'topic list|echo|hz|info'"),
        (["param"], "'param' needs arguments"),
    ],
)
def test_unknown_verbs_are_one_line_and_exit_2(argv, says, capsys):
    assert main.main(argv) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1


def test_help_and_no_arguments(capsys):
    assert main.main(["--help"]) == 0
    assert "ros2 param list <node>" in capsys.readouterr().out
    assert main.main(["param", "-h"]) == 0
    assert "describe <node> <name>" in capsys.readouterr().out
    assert main.main([]) == 2


@pytest.mark.parametrize(("argv", "code"), [(["get", "/n"], 2), (["set", "/n", "c1"], 2), (["list"], 2)])
def test_param_argument_counts_are_checked_before_any_discovery(argv, code, capsys):
    assert main.main(["param", *argv]) == code
    assert "expected param list|dump <node>" in capsys.readouterr().err


def test_an_out_of_range_domain_id_is_one_line_before_dds_starts(monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", "300")
    with pytest.raises(CliError) as refused:
        Graph()
    assert refused.value.code == 2
    assert "ROS_DOMAIN_ID='300' is out of range: allowed an integer in [0, 232]" in str(refused.value)


def test_dump_nests_dotted_names_in_the_params_file_layout():
    doc = param.dump_document("/controller_node", {"c1": 30.0, "qos.depth": 5, "qos.reliable": True})
    nested = {"c1": 30.0, "qos": {"depth": 5, "reliable": True}}
    assert doc == {"/controller_node": {"ros__parameters": nested}}


def test_describe_prints_type_range_and_read_only_as_ros2cli():
    d = ParameterDescriptor(
        name="c1",
        type=ParameterType.PARAMETER_DOUBLE,
        description="gain [1/s]",
        additional_constraints="allowed: a finite number in (0, 1000] 1/s",
        read_only=True,
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1000.0, step=0.0)],
    )
    assert param.describe_text(d).splitlines() == [
        "Parameter name: c1",
        "  Type: double",
        "  Description: gain [1/s]",
        "  Constraints:",
        "    Read only: true",
        "    Min value: 0.0",
        "    Max value: 1000.0",
        "    Additional constraints: allowed: a finite number in (0, 1000] 1/s",
    ]
    bare = ParameterDescriptor(name="flag", type=ParameterType.PARAMETER_BOOL)
    assert param.describe_text(bare) == "Parameter name: flag\n  Type: boolean"


def test_echo_output_shapes():
    data = {"tick": 3, "z": [1.5, 2.0], "header": {"frame_id": "x"}}
    assert topic.echo_text(data, csv=True) == "3,1.5,2.0,x\n"
    assert topic.echo_text(data, csv=False) == "tick: 3\nz:\n- 1.5\n- 2.0\nheader:\n  frame_id: x\n---\n"
    assert topic.select_field(data, "header.frame_id") == ("x", True)
    assert topic.select_field(data, "header.nothing") == (None, False)
    assert topic.select_field(data, None) == (data, True)


def test_rate_text_is_ros2cli_shaped():
    text = topic.rate_text([0.0, 0.001, 0.002, 0.003])
    assert text.splitlines()[0] == "average rate: 1000.000"
    assert text.splitlines()[1].strip().startswith("min: 0.001s max: 0.001s std dev: 0.00000s window: 3")


def test_plain_turns_messages_into_python_values():
    from pac_interfaces.msg import FrameMeasurement

    msg = FrameMeasurement()
    msg.tick = 7
    out = plain(msg)
    assert out["tick"] == 7 and isinstance(out["header"], dict)


def test_bag_verbs_become_the_project_tools_command_lines():
    assert bag.play_command(["b", "--topics", "/measurement", "-r", "0.5"]) == [
        "pac_rig",
        "replay",
        "b",
        "--topics",
        "measurement",
        "--rate",
        "0.5",
        "--wait-for",
        "0",
        "--timeout",
        "30.0",
    ]
    assert bag.record_command(["-o", "out", "measurement", "estimate"]) == [
        "pac_rig",
        "recorder",
        "--ros-args",
        "-p",
        "bag_path:=out",
        "-p",
        "topics:=measurement,estimate",
    ]
    assert bag.record_command(["-a", "--ros-args", "-p", "stop_after_run:=true"])[-2:] == [
        "-p",
        "stop_after_run:=true",
    ]
    with pytest.raises(CliError, match="give the topics to record"):
        bag.record_command([])


def test_interface_show_expands_nested_types():
    out: list[str] = []
    show_lines("pac_interfaces/msg/FrameMeasurement", 0, False, True, out)
    assert "std_msgs/Header header" in out
    assert any(line.startswith("\tbuiltin_interfaces/Time stamp") for line in out)
    with pytest.raises(CliError):
        split_type("no_slashes")
