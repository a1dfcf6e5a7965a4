"""Property-based fuzzing of the input readers: the YAML loader, ``-p`` values, params files,
parameter checks, campaign SPECs and ``runs.jsonl``. Whatever the input, a reader returns or
refuses it with its own one-line error; it never raises anything else.

Derandomized (a fixed sequence of examples, the same on every run). Longer by hand, e.g.
``PAC_FUZZ_EXAMPLES=20000 bash scripts/run_tests.sh tests/test_fuzz_inputs.py``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pac_common.command_line import ParamsFile, UsageError
from pac_common.files import FileInputError, load_yaml
from pac_common.parameters import ParameterError
from pac_experiments.campaign import results as campaign_results
from pac_experiments.campaign import spec as campaign_spec
from pac_rig.cli import OverrideError, load_params_file, parse_overrides
from pac_rig.closed_loop import Scenario
from pac_rig.simulate import scenario_from_flat, scenario_sets

#: Examples per property (the default keeps the file within seconds).
EXAMPLES = int(os.environ.get("PAC_FUZZ_EXAMPLES", "150"))
FUZZ = settings(
    max_examples=EXAMPLES,
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

#: Pieces YAML is made of, and the ones that went wrong before: aliases, tags, complex keys,
#: deep brackets, long digit runs, exponents without a dot.
YAML_TOKENS = st.sampled_from(
    [
        "[", "]", "{", "}", ":", ", ", "- ", "? ", "\n", "  ", "&a ", "*a", "&b ", "*b", "a", "b",
        "c1", "1", "1e4", "-0.5", "9" * 60, "'x'", '"y"', "~", "true", "!!python/object:os.system ",
        "!!binary ", "<<: ", "#", "/**:", "ros__parameters:", "\t", "\x00", "\ufeff", "é",
    ]
)  # fmt: skip
YAML_TEXT = st.one_of(st.text(max_size=200), st.lists(YAML_TOKENS, max_size=60).map("".join))
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True), st.text(max_size=20))
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


def one_line(exc: Exception) -> None:
    message = str(exc)
    assert message and "\n" not in message and len(message) < 2000, message[:300]


@pytest.mark.unit
@FUZZ
@given(YAML_TEXT)
def test_load_yaml_returns_or_refuses_in_one_line(text: str) -> None:
    try:
        load_yaml(text, "fuzz")
    except FileInputError as exc:
        one_line(exc)


@pytest.mark.unit
@FUZZ
@given(st.text(max_size=20), YAML_TEXT)
def test_overrides_return_or_refuse_in_one_line(name: str, value: str) -> None:
    try:
        parse_overrides([f"{name}:={value}"])
    except OverrideError as exc:
        one_line(exc)


@pytest.mark.unit
@FUZZ
@given(st.one_of(YAML_TEXT, VALUES.map(lambda v: yaml.safe_dump({"/**": {"ros__parameters": v}}))))
def test_params_files_return_or_refuse_in_one_line(
    tmp_path_factory: pytest.TempPathFactory, text: str
) -> None:
    path = tmp_path_factory.mktemp("params") / "params.yaml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))  # a lone surrogate: not UTF-8
    try:
        ParamsFile.read(str(path))
    except UsageError as exc:
        one_line(exc)
    try:
        load_params_file(path)
    except OverrideError as exc:
        one_line(exc)


def _specs() -> list[Any]:
    return [spec for pset in scenario_sets(Scenario()).values() for spec in pset.specs()]


@pytest.mark.unit
@FUZZ
@given(st.sampled_from(_specs()), VALUES)
def test_every_parameter_check_returns_its_type_or_refuses(spec: Any, value: Any) -> None:
    try:
        checked = spec.check(value)
    except ParameterError as exc:
        one_line(exc)
        return
    assert isinstance(checked, spec.kind), (spec.name, value, checked)


@pytest.mark.unit
@FUZZ
@given(st.dictionaries(st.sampled_from([s.name for s in _specs()]), VALUES, max_size=4))
def test_scenarios_from_any_values_build_or_refuse(values: dict[str, Any]) -> None:
    try:
        scenario_from_flat(values)
    except ParameterError as exc:
        one_line(exc)


SPEC_KEYS = st.sampled_from([*campaign_spec.KEYS, "other"])
SPEC_PARAMETERS = st.sampled_from(["c1", "c2", "speed_kmh", "duration", "law", "noise_std", "nope"])
SPECS = st.dictionaries(
    SPEC_KEYS,
    st.one_of(
        VALUES,
        st.dictionaries(SPEC_PARAMETERS, st.lists(SCALARS, min_size=1, max_size=3), max_size=3),
        st.lists(st.floats(0.0, 2.0) | st.none(), min_size=2, max_size=2),
    ),
    max_size=5,
)


@pytest.mark.slow
@pytest.mark.unit
@FUZZ
@given(st.one_of(YAML_TEXT, SPECS.map(yaml.safe_dump)))
def test_specs_load_or_refuse_with_lines(tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    path = tmp_path_factory.mktemp("spec") / "spec.yaml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        campaign_spec.load_points(path)
    except campaign_spec.SpecError as exc:
        assert exc.errors
        for line in exc.errors:
            assert "\n" not in line and len(line) < 2000, line[:300]


@pytest.mark.unit
@FUZZ
@given(
    st.lists(
        st.one_of(
            st.binary(max_size=40),
            VALUES.map(lambda v: json.dumps(v).encode()),
            st.fixed_dictionaries({"key": VALUES}).map(lambda v: json.dumps(v).encode()),
        ),
        max_size=8,
    )
)
def test_runs_file_lines_are_rows_or_skipped(
    tmp_path_factory: pytest.TempPathFactory, lines: list[bytes]
) -> None:
    out: Path = tmp_path_factory.mktemp("runs")
    (out / campaign_results.RUNS_FILE).write_bytes(b"\n".join(lines))
    done = campaign_results.read_done(out)
    assert all(isinstance(key, str) and isinstance(row, dict) for key, row in done.items())
