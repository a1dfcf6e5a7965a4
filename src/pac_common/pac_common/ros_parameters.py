"""pac parameter sets as ROS 2 parameters: typed descriptors, overrides checked by pac's rules.

Every field of a :class:`~pac_common.parameters.ParameterSet` becomes one ROS parameter with
its ROS type (no dynamic typing), its range as a ``floating_point_range`` / ``integer_range``
where it has one, and ``read_only`` when it is fixed for a run, so `ros2 param describe`
and rqt_reconfigure show (and rclpy enforces) what pac's own validation enforces. pac's
checks run first, so a refusal is pac's one line naming the parameter, the value and the
allowed range (see :meth:`pac_common.pac_node.PacNode.set_parameters_atomically`).
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterable, Sequence
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.node import Node
from rclpy.parameter import Parameter

from .parameters import ParameterError, ParameterSet, ParameterSpec

#: A bound the spec leaves open (``None``) is the largest finite value of the ROS type: ranges
#: are closed and must hold finite numbers for tools such as rqt_reconfigure.
DOUBLE_LIMIT = sys.float_info.max
INTEGER_LIMIT = 2**63 - 1


def ros_type(spec: ParameterSpec) -> int:
    """The ``rcl_interfaces/ParameterType`` of a pac parameter."""
    if spec.kind is tuple:
        return ParameterType.PARAMETER_DOUBLE_ARRAY
    return {
        bool: ParameterType.PARAMETER_BOOL,
        int: ParameterType.PARAMETER_INTEGER,
        float: ParameterType.PARAMETER_DOUBLE,
        str: ParameterType.PARAMETER_STRING,
    }[spec.kind]


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """The typed descriptor of ``spec``: type, range (ROS allows one), read_only, description.

    A ROS range is closed: an open bound of pac's (``(0, inf)``) is the bound itself in the
    range and the exclusion is in ``additional_constraints`` (pac refuses the bound itself).
    An array's range applies to each element (rclpy checks ranges of scalars only).
    """
    unit = f" [{spec.unit}]" if spec.unit else ""
    when = "may be changed at run time" if spec.runtime else "fixed for a run (read only)"
    out = ParameterDescriptor(
        name=spec.name,
        type=ros_type(spec),
        description=f"{spec.description}{unit}",
        additional_constraints=f"allowed: {spec.allowed()}; {when}",
        read_only=not spec.runtime,
    )
    if spec.choices is not None or spec.kind in (bool, str):
        return out
    if spec.kind is int and spec.length is None:
        low = -INTEGER_LIMIT if spec.low is None else int(spec.low)
        high = INTEGER_LIMIT if spec.high is None else int(spec.high)
        out.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    else:
        low_f = -DOUBLE_LIMIT if spec.low is None else float(spec.low)
        high_f = DOUBLE_LIMIT if spec.high is None else float(spec.high)
        out.floating_point_range = [FloatingPointRange(from_value=low_f, to_value=high_f, step=0.0)]
    return out


def ros_value(spec: ParameterSpec, value: Any) -> Any:
    """A checked pac value as rclpy stores it (tuples as lists, floats as floats)."""
    value = spec.check(value)
    return list(value) if isinstance(value, tuple) else value


def declare_parameter_sets(node: Node, classes: Sequence[type[ParameterSet]]) -> list[ParameterSet]:
    """Declare every field of ``classes`` as a typed ROS parameter; return validated instances.

    A value given on the command line or in a params file is checked by pac's rule first
    (:class:`ParameterError`: name, value, allowed range) and converted to the parameter's
    type (``-p m1:=8`` sets the double 8.0), so rclpy's type and range checks never refuse it
    with their own wording.
    """
    overrides = getattr(node, "_parameter_overrides", {})
    out = []
    for cls in classes:
        values = {}
        for spec in cls.specs():
            if spec.name in overrides:
                given = overrides[spec.name].value
                overrides[spec.name] = Parameter(spec.name, value=ros_value(spec, given))
            if not node.has_parameter(spec.name):
                node.declare_parameter(spec.name, ros_value(spec, spec.default), descriptor(spec))
            values[spec.name] = node.get_parameter(spec.name).value
        out.append(cls.from_mapping(values))
    return out


def given_parameter_names(node: Node) -> list[str]:
    """Names set for this node by ``--ros-args -p`` or ``--params-file``.

    rclpy has no public accessor for the overrides it parsed; ``_parameter_overrides`` is the
    dict it fills in ``Node.__init__`` (tests/test_suite.py checks a typo is still caught).
    """
    return list(getattr(node, "_parameter_overrides", {}))


def validate_changes(
    current: Iterable[ParameterSet], changes: Sequence[Parameter]
) -> tuple[list[ParameterSet], str]:
    """Apply parameter changes to copies of ``current``; return the new sets, or an error string."""
    updated = []
    by_name = {p.name: p.value for p in changes}
    try:
        for pset in current:
            names = {s.name for s in pset.specs()}
            mine = {k: v for k, v in by_name.items() if k in names}
            updated.append(dataclasses.replace(pset, **mine) if mine else pset)
    except ParameterError as exc:
        return list(current), str(exc)
    return updated, ""


def parameter_names(sets: Iterable[type[ParameterSet]]) -> list[str]:
    return [spec.name for cls in sets for spec in cls.specs()]
