"""Every parameter of every node as ROS tools see it: typed, with its range and read-only flag.

Each node is started once; its descriptors (`describe_parameters`, what `ros2 param describe`
and rqt_reconfigure read) are checked against the parameter declarations. The descriptor
module itself is checked without DDS first.
"""

import subprocess

import pytest
from conftest import parameter_tester
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from pac_common.ros_parameters import DOUBLE_LIMIT, INTEGER_LIMIT, descriptor
from pac_rig.configs import parameter_sets
from pac_rig.launcher import node_env
from pac_rig.live_view import LiveViewParameters
from pac_rig.nodes import NODES as RIG_NODES

# The descriptor checks are unit tests; the live one is live (it uses domain_id: conftest).
pytestmark = pytest.mark.unit

#: node name -> (package, executable, extra --ros-args, its parameter sets); the plant runs until
#: stopped (its process would end with a 10 s run, before the calls are done on a loaded machine)
NODES = {
    **{
        n.executable: (
            n.package,
            n.executable,
            ["-p", "duration:=0.0"] if role == "plant" else [],
            parameter_sets(role),
        )
        for role, n in RIG_NODES.items()
    },
    "live_view": ("pac_rig", "live_view", ["-p", "port:=0"], [LiveViewParameters]),
}
TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER}


def expected(spec):
    """(type, range bounds or None, read_only) from the declaration alone."""
    if spec.length is not None or spec.kind is tuple:  # fixed or variable length (max_length)
        kind = ParameterType.PARAMETER_DOUBLE_ARRAY
    elif spec.kind is str:
        kind = ParameterType.PARAMETER_STRING
    elif spec.kind is float:
        kind = ParameterType.PARAMETER_DOUBLE
    else:
        kind = TYPES[spec.kind]
    if spec.choices is not None or spec.kind in (bool, str):
        bounds = None
    else:
        limit = INTEGER_LIMIT if spec.kind is int and spec.length is None else DOUBLE_LIMIT
        bounds = (-limit if spec.low is None else spec.low, limit if spec.high is None else spec.high)
    return kind, bounds, not spec.runtime


def seen(d):
    ranges = [*d.floating_point_range, *d.integer_range]
    assert len(ranges) <= 1, f"{d.name}: ROS allows one range"
    bounds = (ranges[0].from_value, ranges[0].to_value) if ranges else None
    if ranges:
        assert ranges[0].step == (1 if d.integer_range else 0.0)
    return d.type, bounds, d.read_only


ALL = [(node, spec) for node, (*_, sets) in NODES.items() for cls in sets for spec in cls.specs()]


@pytest.mark.parametrize(("node", "spec"), ALL, ids=[f"{n}.{s.name}" for n, s in ALL])
def test_descriptor_follows_the_declaration(node, spec):
    d = descriptor(spec)
    assert seen(d) == expected(spec)
    assert not d.dynamic_typing
    assert spec.allowed() in d.additional_constraints
    assert d.description.startswith(spec.description)


def test_every_live_node_describes_every_parameter_with_range_and_read_only(domain_id, tmp_path):
    env = node_env(domain_id)
    procs = {}
    for name, (pkg, exe, extra, _) in NODES.items():
        extra = [*extra, "-p", f"bag_path:={tmp_path / 'bag'}"] if name == "recorder" else extra
        procs[name] = subprocess.Popen(
            ["ros2", "run", pkg, exe, "--ros-args", *extra],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    with parameter_tester(domain_id, procs) as (tester, call):
        described = 0
        for name, (*_, sets) in NODES.items():
            client = AsyncParameterClient(tester, name)
            assert client.wait_for_services(timeout_sec=30), name
            specs = [s for cls in sets for s in cls.specs()]
            got = call(client.describe_parameters([s.name for s in specs])).descriptors
            for spec, d in zip(specs, got, strict=True):
                assert d.name == spec.name
                assert seen(d) == expected(spec), f"{name}.{spec.name}"
                described += 1
        controller = AsyncParameterClient(tester, "controller_node")
        # An integer for a double: accepted and kept a double (ROS would refuse the type).
        result = call(controller.set_parameters([Parameter("c1", value=30)])).results[0]
        assert result.successful, result.reason
        value = call(controller.get_parameters(["c1"])).values[0]
        assert (value.type, value.double_value) == (ParameterType.PARAMETER_DOUBLE, 30.0)
        # pac's one line comes first, not rclpy's "read-only" or "out of range" wording.
        frozen = call(controller.set_parameters([Parameter("speed_kmh", value=300.0)])).results[0]
        assert not frozen.successful and frozen.reason.startswith("speed_kmh: fixed for a run")
        bad = call(controller.set_parameters([Parameter("c1", value=-5.0)])).results[0]
        assert bad.reason.startswith("invalid parameter 'c1' = -5.0: allowed")
        print(f"\n{described} descriptors over {len(NODES)} live nodes match the declarations")


@pytest.mark.parametrize("node", sorted(NODES))
def test_no_two_parameter_sets_of_a_node_declare_the_same_name(node):
    """ROS has one parameter per name: a second declaration would silently take the first's value."""
    names = [spec.name for cls in NODES[node][3] for spec in cls.specs()]
    assert sorted({n for n in names if names.count(n) > 1}) == []
