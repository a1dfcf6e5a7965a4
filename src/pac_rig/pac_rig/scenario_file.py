"""The scenario file: a named composition of a run's parts, ``-p scenario:=NAME|PATH``.

A scenario file gives values of the run's parameters (the flat names ``simulate --list`` prints)
that together make one kind of rig: a line (its catenary file and layout seed), a vehicle (the
car body's motion), sensors, an actuator and the plant's and the nominal pantograph. The user's
own values win over the file's, so ``-p scenario:=realistic_electromechanical -p line_seed:=7``
is that scenario on another line. Presets live in ``config/scenarios/`` (``paper_rig``, the
default, names nothing: today's ideal rig). Format and presets: docs/scenarios.md.

Every entry point expands it the same way (:func:`expand`): ``simulate``, campaign points (a
grid may vary ``scenario``), the rig launcher (the nodes get the values that are theirs) and
:func:`pac_rig.composition.derive`. A bad file is refused before the run in one line naming
the file, the line and column, the key and what is allowed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from pac_common.data_file import DataFileError, Map, Presets, Reader
from pac_common.parameters import ParameterError

from .scenario import Scenario, from_flat, scenario_to_flat

#: The parameter that names a scenario file.
PARAMETER = "scenario"
DEFAULT = "paper_rig"
PRESETS = Presets(Path("config") / "scenarios", DEFAULT, PARAMETER, __file__, "docs/scenarios.md")
TOP_KEYS = ("name", "source", "parameters")


class ScenarioFileError(DataFileError):
    KIND = "scenario"


@dataclass(frozen=True)
class ScenarioFile:
    """A checked scenario file: its name, the source of its choices and the values it gives."""

    name: str
    source: str
    parameters: dict[str, Any]
    path: str


def load_scenario(value: str) -> ScenarioFile:
    """The scenario file ``value`` names (a path, or a preset's name); cached per file and mtime."""
    return _load(*PRESETS.read(value))


@lru_cache(maxsize=16)
def _load(path: str, mtime_ns: int, size: int) -> ScenarioFile:
    return parse_scenario(PRESETS.text(path), path)


def parse_scenario(text: str, source: str) -> ScenarioFile:
    """Check a scenario file's text: known top-level keys, a ``parameters`` mapping of run
    parameters (never ``scenario`` itself), each value valid by that parameter's own rule."""
    reader = Reader(source, ScenarioFileError)
    raw = reader.parse(text, TOP_KEYS)
    name = reader.text(raw, "name")
    about = reader.text(raw, "source")
    given = raw.get("parameters")
    if given is None:  # no key, or an empty mapping written as `parameters:`
        given = Map()
        given.marks, given.start = {}, raw.start
    if not isinstance(given, Map):
        mark = raw.marks.get("parameters", raw.start)
        raise reader.fail("parameters", given, "a mapping of run parameters to values", mark)
    known = set(scenario_to_flat(Scenario()))  # the names a run has
    for key in given:
        if key not in known:
            allowed = "a run parameter (`ros2 run pac_rig simulate --list`)"
            raise reader.fail(f"parameters.{key}", given[key], allowed, given.marks.get(key, given.start))
    values = {str(k): _plain(v) for k, v in given.items()}
    try:
        from_flat(values)
    except ParameterError as exc:
        key = str(exc.name) if exc.name in values else next(iter(values), "parameters")
        mark = given.marks.get(key, given.start)
        raise reader.fail(f"parameters.{key}", values.get(key), exc.allowed, mark) from None
    return ScenarioFile(name, about, values, source)


def _plain(value: Any) -> Any:
    """A YAML list as the tuple the parameter sets take."""
    return tuple(value) if isinstance(value, list) else value


def expand(values: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """``values`` without ``scenario``, with the named file's values where ``values`` gives none,
    and one line saying so (for a log); ``values`` unchanged (a copy) when it names none."""
    out = dict(values)
    named = out.pop(PARAMETER, None)
    if named is None or named == "":
        return out, []
    if not isinstance(named, str):
        raise ParameterError(
            PARAMETER, named, f"a scenario file or a preset: one of {', '.join(PRESETS.names())}"
        )
    scenario = load_scenario(named)
    taken = {k: v for k, v in scenario.parameters.items() if k not in out}
    kept = sorted(set(scenario.parameters) - set(taken))
    note = f"scenario:={named} ({len(taken)} values from {scenario.path}"
    note += f"; yours kept: {', '.join(kept)})" if kept else ")"
    return {**taken, **out}, [note]
