"""A law from another installed package: an entry point of the group ``pac.laws`` (``name = module``,
a module of the law-file protocol) joins the registry under its name, with no edit to pac.

The package is a real installed distribution as far as ``importlib.metadata`` is concerned: a
``.dist-info`` folder with its ``entry_points.txt`` on the path of a fresh interpreter (the
registry is built when pac_controller.laws is first imported, so each case runs in a process of
its own).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import simulate_refusal

from pac_bag.reader import read_bag

pytestmark = pytest.mark.offline

#: The installed package's laws: one that works (pac's skyhook module under another name), one
#: whose module does not exist, one that names an attribute, and one that takes a name pac has.
POINTS = {
    "damper": "pac_controller.skyhook",
    "missing": "pac_no_such_law_module",
    "attribute": "pac_controller.skyhook:output",
    "passive": "pac_controller.skyhook",
}


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A distribution ``pac-demo-laws`` with :data:`POINTS` as its ``pac.laws`` entry points, on the
    PYTHONPATH of every process the test starts."""
    site = tmp_path / "site"
    dist = site / "pac_demo_laws-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: pac-demo-laws\nVersion: 0.1\n")
    points = "".join(f"{name} = {value}\n" for name, value in POINTS.items())
    (dist / "entry_points.txt").write_text("[pac.laws]\n" + points)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    return site


PROBE = """
import json
from pac_common.parameters import ParameterError
from pac_controller import laws
from pac_controller.parameters import LAW_NAMES
out = {"names": list(LAW_NAMES), "sources": {n: e.source for n, e in laws.LAWS.items()}, "refused": {}}
for name in ("missing", "attribute"):
    try:
        laws.law_entry(name).build(None, None, None, None, None, None, 0.001)
    except ParameterError as exc:
        out["refused"][name] = str(exc)
print(json.dumps(out))
"""


def test_an_installed_packages_laws_join_the_registry_by_name(installed):
    run = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    # Every entry point is a choice of `law` (after pac's own, which keep their places) ...
    assert out["names"][-3:] == ["attribute", "damper", "missing"]
    assert "skyhook" in out["names"] and out["names"].count("passive") == 1
    # ... the working one is its module, and pac's own name stays pac's law.
    assert out["sources"]["damper"] == "pac_controller.skyhook"
    assert out["sources"]["passive"] is None
    # One that cannot be loaded is refused in one line when chosen, naming what is wrong.
    missing = out["refused"]["missing"]
    assert "'law' = 'pac_no_such_law_module'" in missing and "ModuleNotFoundError" in missing
    assert "\n" not in missing
    assert "names a module, not an attribute" in out["refused"]["attribute"]


def test_a_law_of_an_installed_package_runs_in_simulate_as_its_module_does(installed, tmp_path):
    """``law:=damper`` (the entry point) and ``law:=skyhook`` (pac's registry line) are the same
    module: the same commands, bit for bit, on the same machine."""
    u = {}
    for law in ("damper", "skyhook"):
        bag = tmp_path / law
        run = subprocess.run(
            [sys.executable, "-m", "pac_rig.simulate", str(bag), "-p", f"law:={law}", "-p", "duration:=0.5"],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert run.returncode == 0, run.stderr
        command = read_bag(bag).topics["command"]
        u[law], f_r = command["u"], command["force_reference"]
    assert u["damper"].size == 500
    assert np.array_equal(u["damper"], u["skyhook"])
    assert np.abs(u["damper"] - f_r).max() > 1.0  # the damper acted (passive commands F_r)


def test_choosing_an_entry_point_that_cannot_be_loaded_is_refused_in_one_line(installed, tmp_path):
    line = simulate_refusal(tmp_path / "bag", "law:=missing")
    assert "'law' = 'pac_no_such_law_module'" in line and "ModuleNotFoundError" in line
