"""The compiled laws' dispatch is the registry's: generated, current, refusing a kernel that does not fit."""

import sys
import types
from dataclasses import replace
from pathlib import Path

import pytest

from pac_controller import law_dispatch, law_dispatch_source, passive_kernels
from pac_controller.laws import LAWS

pytestmark = pytest.mark.unit

SUFFIXES = [f.suffix for f in law_dispatch_source.FUNCTIONS]


def test_the_dispatch_in_use_is_what_the_registry_gives():
    """law_dispatch.py (the one imported: the installed copy) is written from laws.LAWS; a registry
    change without ``python -m pac_controller.law_dispatch_source --write`` fails here."""
    assert Path(law_dispatch.__file__).read_text() == law_dispatch_source.law_dispatch_source(LAWS)


def test_every_kernel_law_has_its_code_in_the_registry_order_and_no_other_law_has_one():
    kernel_laws = [name for name, entry in LAWS.items() if entry.kernel is not None]
    assert kernel_laws, "pac's own laws are kernel laws"
    assert law_dispatch.LAW_CODES == {name: code for code, name in enumerate(kernel_laws)}
    for name, entry in LAWS.items():
        if entry.kernel is None:
            assert name not in law_dispatch.LAW_CODES


def test_a_kernel_law_joins_the_dispatch_by_its_registry_line_alone():
    """A law added to the registry with a kernel module gets the next code and one branch in each
    of the four functions, calling its module's functions by its name."""
    passive = LAWS["passive"]
    laws = dict(LAWS, passive_again=replace(passive, kernel="tests_kernel_module_stand_in"))
    # the stand-in module: passive's functions under the new law's name
    stand_in = types.ModuleType("tests_kernel_module_stand_in")
    for fn in SUFFIXES:
        setattr(stand_in, f"passive_again_{fn}", getattr(passive_kernels, f"passive_{fn}"))
    sys.modules[stand_in.__name__] = stand_in
    try:
        text = law_dispatch_source.law_dispatch_source(laws)
    finally:
        del sys.modules[stand_in.__name__]
    code = len(law_dispatch.LAW_CODES)
    assert f'    "passive_again": {code},\n' in text
    for fn in SUFFIXES:
        assert f"tests_kernel_module_stand_in.passive_again_{fn}(" in text
    assert text.count(f"law == {code}:") == len(SUFFIXES)


@pytest.mark.parametrize(
    ("kernel", "message"),
    [
        ("pac_controller.no_such_module", "does not import"),
        ("pac_controller.pid_kernels", "lacks passive_again_restart, passive_again_output"),
    ],
)
def test_a_kernel_module_that_does_not_fit_is_refused_in_one_line(kernel, message):
    laws = dict(LAWS, passive_again=replace(LAWS["passive"], kernel=kernel))
    with pytest.raises(ValueError, match=message) as refused:
        law_dispatch_source.law_dispatch_source(laws)
    assert "\n" not in str(refused.value)


def test_the_command_writes_the_file_and_then_finds_it_current(tmp_path, capsys):
    """``python -m <kind>_dispatch_source`` checks (exit 1 and one line naming --write while the
    file differs), ``--write`` writes it; the check then passes."""
    from pac_common.dispatch_source import main

    source, target = tmp_path / "kind_source.py", tmp_path / "kind_dispatch.py"
    target.write_text("stale\n")
    assert main("pac_x.kind_source", str(source), target.name, lambda: "fresh\n", []) == 1
    assert "run python -m pac_x.kind_source --write" in capsys.readouterr().err
    assert main("pac_x.kind_source", str(source), target.name, lambda: "fresh\n", ["--write"]) == 0
    assert target.read_text() == "fresh\n"
    assert main("pac_x.kind_source", str(source), target.name, lambda: "fresh\n", []) == 0
