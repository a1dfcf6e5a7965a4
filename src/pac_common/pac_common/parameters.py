"""Declarative, validated parameter sets shared by the cores and the nodes.

A parameter set is a frozen dataclass whose fields are declared with
:func:`parameter`.  The same declaration gives the default, the description,
the unit and the allowed range, so the pure cores, the ROS 2 nodes (which
declare one ROS parameter per field) and the command-line tools all validate a
value by the very same rule and report it the same way.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from .files import excerpt
from .registry import RegistryNames


class ParameterError(ValueError):
    """A parameter value is outside its allowed range.

    The message is one line naming the parameter, the value and the allowed range.
    """

    def __init__(self, name: str, value: Any, allowed: str) -> None:
        self.name = name
        self.value = value
        self.allowed = allowed
        super().__init__(f"invalid parameter '{name}' = {excerpt(value)}: allowed {allowed}")

    def __reduce__(self) -> tuple[Any, ...]:
        # A refusal raised in a worker process (a pool, a Dask cluster) must reach the parent as
        # itself: pickle rebuilds an exception from its args (the message alone), which no
        # subclass's __init__ takes, and the pool breaks instead of saying the one line.
        return (_rebuilt_error, (type(self), str(self), dict(self.__dict__)))


def _rebuilt_error(kind: type[ParameterError], message: str, fields: dict[str, Any]) -> ParameterError:
    """A pickled :class:`ParameterError` (or subclass) with its message and fields."""
    error = kind.__new__(kind)
    ValueError.__init__(error, message)
    error.__dict__.update(fields)
    return error


#: Names the rig takes as a whole but no node alone, and where they go instead.
RIG_ONLY = {
    "scenario": "a scenario is composed for the whole rig: `ros2 run pac_rig rig_params -p scenario:=NAME "
    "... -o rig.yaml`, then every node with --ros-args --params-file rig.yaml",
}


class UnknownParameterError(ParameterError):
    """A parameter name the program does not have (a typo): refused, never ignored."""

    def __init__(self, name: str, value: Any, program: str) -> None:
        self.name = name
        self.value = value
        self.allowed = f"a parameter of {program}"
        where = f"; {RIG_ONLY[name]}" if name in RIG_ONLY else " (--help lists them)"
        ValueError.__init__(
            self, f"unknown parameter '{name}' = {excerpt(value)}: {program} has no such parameter{where}"
        )


@dataclass(frozen=True)
class ParameterSpec:
    """What one parameter may be: type, bounds or choices, unit, meaning."""

    name: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: Sequence[str] | None = None
    length: int | None = None  # fixed-length float array when set
    runtime: bool = False  # may be changed while the node runs (validated like at start)
    max_length: int | None = None  # float array of 1 .. max_length values when set
    #: With ``choices``: a path ending in this suffix is allowed too (a user's file: ``law``'s ".py")
    or_file: str | None = None

    @property
    def kind(self) -> type:
        if self.length is not None or self.max_length is not None:
            return tuple
        return type(self.default)

    def allowed(self, registry_names: bool = True) -> str:
        """Human-readable allowed range, e.g. ``(0, inf) kg`` or ``one of linear, unilateral``.
        ``registry_names`` False: choices that are a registry's names (pac_common.registry) are
        not listed (a shipped file, which a variant joining its registry must not change)."""
        if self.choices is not None:
            files = f", or the path of a {self.or_file} file" if self.or_file else ""
            if not registry_names and isinstance(self.choices, RegistryNames):
                return "a name of its registry (--help lists them)" + files
            return "one of " + ", ".join(self.choices) + files
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            return "a string"
        lo = "-inf" if self.low is None else _fmt(self.low)
        hi = "inf" if self.high is None else _fmt(self.high)
        left = "(" if (self.low is None or self.low_open) else "["
        right = ")" if (self.high is None or self.high_open) else "]"
        rng = f"{left}{lo}, {hi}{right}"
        if self.length is not None:
            rng = f"{self.length} finite values, each in {rng}"
        elif self.max_length is not None:
            rng = f"1 to {self.max_length} finite values, each in {rng}"
        elif self.kind is int:
            rng = f"an integer in {rng}"
        elif self.kind is float:
            rng = f"a finite number in {rng}"
        return f"{rng} {self.unit}".rstrip()

    def check(self, value: Any) -> Any:
        """Return ``value`` normalised to the spec's type, or raise :class:`ParameterError`."""
        if self.choices is not None:
            if not isinstance(value, str) or not (value in self.choices or self.is_file(value)):
                raise ParameterError(self.name, value, self.allowed())
            return value
        if self.kind is bool:
            if not isinstance(value, bool):
                raise ParameterError(self.name, value, "true or false")
            return value
        if self.kind is tuple:
            # A string is no list of numbers ("00" is not (0, 0)), nor is a boolean a number.
            if not isinstance(value, list | tuple) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in value
            ):
                raise ParameterError(self.name, value, self.allowed())
            items = tuple(float(v) for v in value)
            if self.length is not None:
                count_ok = len(items) == self.length
            else:
                count_ok = 1 <= len(items) <= (self.max_length or 0)
            if not count_ok or not all(self._in_range(v) for v in items):
                raise ParameterError(self.name, value, self.allowed())
            return items
        if self.kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ParameterError(self.name, value, self.allowed())
            if not self._in_range(value):
                raise ParameterError(self.name, value, self.allowed())
            return value
        if self.kind is float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ParameterError(self.name, value, self.allowed())
            value = float(value)
            if not self._in_range(value):
                raise ParameterError(self.name, value, self.allowed())
            return value
        if not isinstance(value, self.kind):
            raise ParameterError(self.name, value, f"a {self.kind.__name__}")
        return value

    def is_file(self, value: str) -> bool:
        """``value`` names a file of the kind ``or_file`` allows (by its suffix: whether it exists and
        holds what it should is checked where it is loaded, e.g. ``pac_controller.user_law``)."""
        return self.or_file is not None and value.endswith(self.or_file) and len(value) > len(self.or_file)

    def _in_range(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        if self.low is not None and (v < self.low or (self.low_open and v == self.low)):
            return False
        if self.high is not None and (v > self.high or (self.high_open and v == self.high)):
            return False
        return True


def check_new_directory(name: str, path: Path) -> None:
    """A directory to be created (a bag): it must not exist and its parent must be a writable folder."""
    _check_path_text(name, path)
    if path.exists():
        raise ParameterError(name, str(path), "a path that does not exist yet")
    check_output_folder(name, path)


def check_output_folder(name: str, path: Path) -> None:
    """A folder to write into (it may exist already): it, or its nearest existing parent, must be a
    folder this process can create files in and write to (a full disk is refused here, before the
    work)."""
    _check_path_text(name, path)
    if path.exists() and not path.is_dir():
        raise ParameterError(name, str(path), "a folder (this is a file)")
    if path.is_dir():
        if not _can_create_in(path):
            raise ParameterError(name, str(path), "a folder this process can write in")
        return
    parent = path.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent  # missing folders are created: the nearest existing one decides
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK) or not _can_create_in(parent):
        raise ParameterError(
            name, str(path), f"a new directory under a writable folder ({parent} is not one)"
        )


def _check_path_text(name: str, path: Path) -> None:
    """A path the OS can take: no NUL (``Path.exists`` raises ValueError on one)."""
    if "\0" in str(path):
        raise ParameterError(name, str(path), "a path without a NUL character")


def _can_create_in(folder: Path) -> bool:
    """Whether a file can be created in ``folder`` and written: ``os.access`` says yes to root on a
    read-only file system or /proc, where creating the bag then failed with a traceback; an empty
    file can still be created on a full disk, a block of data cannot."""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder) as probe:
            probe.write(bytes(WRITE_PROBE_BYTES))
            probe.flush()
            os.fsync(probe.fileno())
            return True
    except OSError:
        return False


#: Bytes written to tell a writable folder from a full disk (one file-system block).
WRITE_PROBE_BYTES = 4096


def _fmt(x: float) -> str:
    return f"{x:g}"


def parameter(
    default: Any,
    description: str,
    unit: str = "",
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    choices: Sequence[str] | None = None,
    length: int | None = None,
    runtime: bool = False,
    max_length: int | None = None,
    or_file: str | None = None,
) -> Any:
    """Declare a dataclass field as a validated parameter (see :class:`ParameterSpec`).

    ``runtime=True``: a node may change it while it runs (``ros2 param set``), validated by the
    same rule; every other parameter is fixed for a run. ``or_file`` (with ``choices``): the path of
    a file with this suffix is a value too.
    """
    meta = {
        "description": description,
        "unit": unit,
        "low": low,
        "high": high,
        "low_open": low_open,
        "high_open": high_open,
        "choices": choices,
        "length": length,
        "runtime": runtime,
        "max_length": max_length,
        "or_file": or_file,
    }
    return field(default=default, metadata={"pac_parameter": meta})


P = TypeVar("P", bound="ParameterSet")


@dataclass(frozen=True)
class ParameterSet:
    """Base of every validated parameter set: fields checked on construction."""

    def __post_init__(self) -> None:
        for spec in self.specs():
            object.__setattr__(self, spec.name, spec.check(getattr(self, spec.name)))
        self.check_consistency()

    def check_consistency(self) -> None:
        """Checks between fields; override and raise :class:`ParameterError`."""

    @classmethod
    def specs(cls) -> tuple[ParameterSpec, ...]:
        out = []
        for f in dataclasses.fields(cls):
            meta = f.metadata.get("pac_parameter")
            if meta is not None:
                out.append(ParameterSpec(name=f.name, default=f.default, **meta))
        return tuple(out)

    @classmethod
    def from_mapping(cls: type[P], values: Mapping[str, Any]) -> P:
        """Build from a mapping that may hold other keys too (those are ignored)."""
        names = {s.name for s in cls.specs()}
        return cls(**{k: v for k, v in values.items() if k in names})

    @classmethod
    def has_runtime(cls) -> bool:
        """True when any of its parameters may change while a node runs."""
        return any(spec.runtime for spec in cls.specs())

    def as_dict(self) -> dict[str, Any]:
        return {s.name: getattr(self, s.name) for s in self.specs()}


@dataclass(frozen=True)
class RateParameters(ParameterSet):
    """The loop's sample rate: every node needs it (tick <-> simulated time)."""

    rate_hz: float = parameter(1000.0, "loop rate (sample frequency)", "Hz", low=1.0, high=20000.0)

    @property
    def sample_period(self) -> float:
        return 1.0 / self.rate_hz


@dataclass(frozen=True)
class LoopParameters(RateParameters):
    """Timing of a run: the plant node and the offline simulator."""

    command_delay_ticks: int = parameter(
        1, "lock step and offline: u_k is applied over [t_(k+d), t_(k+d+1)]", "ticks", low=0, high=100
    )
    duration: float = parameter(
        10.0, "run length in simulated time; 0 runs until stopped (nodes only)", "s", low=0.0, high=86400.0
    )

    @property
    def ticks(self) -> int:
        return int(round(self.duration * self.rate_hz))


@dataclass(frozen=True)
class SchedulingOptions(ParameterSet):
    """How the OS schedules a node's process (every thread of it): the loop nodes and the recorder."""

    realtime_priority: int = parameter(
        0,
        "SCHED_FIFO priority of this process (0: normal scheduling). Needs root or CAP_SYS_NICE; "
        "when refused the node warns and runs with normal scheduling",
        low=0,
        high=99,
    )


@dataclass(frozen=True)
class NodeOptions(SchedulingOptions):
    """Start-up behaviour shared by the loop nodes (and their scheduling)."""

    wait_for_recorder: bool = parameter(
        False, "do not start the loop until a recorder is subscribed to this node's outputs too"
    )
    start_timeout: float = parameter(
        60.0,
        "give up (exit 1, naming what is missing) when the peers this node waits for at start "
        "(and the recorder, with wait_for_recorder) are not all matched within this time; 0: wait forever",
        "s",
        low=0.0,
        high=86400.0,
    )


@dataclass(frozen=True)
class RunEndOptions(ParameterSet):
    """What a node that follows the plant's run (observer, controller, recorder) does at its end."""

    stop_after_run: bool = parameter(
        False,
        "exit (status 0) once the plant has announced the end of its run and this node has handled "
        "its last tick; false: stay idle until a new run starts",
    )
