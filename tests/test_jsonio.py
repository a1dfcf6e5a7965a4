"""Every JSON pac writes parses with a strict parser: non-finite numbers become null."""

import json
import math

import numpy as np
import pytest

from pac_common import jsonio

pytestmark = pytest.mark.unit


def strict_loads(text: str):
    def refuse(constant: str):
        raise ValueError(f"non-standard JSON constant {constant}")

    return json.loads(text, parse_constant=refuse)


def test_non_finite_values_become_null_everywhere():
    value = {
        "nan": math.nan,
        "inf": -math.inf,
        "np": np.float64("nan"),
        "array": np.array([1.0, np.inf, 2.0]),
        "nested": [{"x": (math.nan, 3)}],
        "ok": 1.5,
    }
    parsed = strict_loads(jsonio.dumps(value))
    assert parsed == {
        "nan": None,
        "inf": None,
        "np": None,
        "array": [1.0, None, 2.0],
        "nested": [{"x": [None, 3]}],
        "ok": 1.5,
    }
    with pytest.raises(ValueError):  # the plain encoder writes what a strict parser refuses
        strict_loads(json.dumps(value["nan"]))


@pytest.mark.slow
def test_report_json_of_a_run_with_undefined_measures_is_strict(offline_bags_for_json, tmp_path):
    from pac_analysis.report import report

    report([offline_bags_for_json], tmp_path / "r", 3.0, None)
    parsed = strict_loads((tmp_path / "r" / "metrics.json").read_text())
    # no plant_truth: the contact-force measures are undefined (NaN in memory), null in the file
    assert parsed["runs"]["no_truth"]["metrics"]["contact_force_mean"] is None


@pytest.fixture
def offline_bags_for_json(tmp_path):
    """A bag without plant_truth: the contact-force measures are NaN in memory."""
    from pac_bag.writer import BagWriter
    from pac_common import messages

    path = tmp_path / "no_truth"
    with BagWriter(path, topics={"command": messages.ACTUATOR_COMMAND}) as bag:
        for k in range(4000):
            stamp = messages.tick_stamp_ns(k, 1000.0)
            fields = {
                "header": messages.header(stamp),
                "tick": k,
                "u": 100.0,
                "u_unsaturated": 100.0,
                "force_reference": 100.0,
                "tracking_error": np.zeros(3),
                "saturated": False,
                "mode": 0,
                "estimate_age_ticks": 0,
            }
            bag.write("command", fields, stamp)
    return path
