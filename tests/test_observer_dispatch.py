"""The compiled observers' dispatch is the registry's: generated, current, its codes the records'."""

from pathlib import Path

import numpy as np
import pytest

from pac_common import divergence
from pac_model.parameters import PantographParameters, TrackParameters
from pac_observer import observer_dispatch, observer_dispatch_source
from pac_observer.observer import OBSERVER_CONSTS, OBSERVER_STATE
from pac_observer.observers import OBSERVER_CODES, OBSERVERS, core_class
from pac_observer.parameters import OBSERVER_GIVES, ObserverParameters
from pac_rig.loop import NO_BANK

pytestmark = pytest.mark.unit


def test_the_dispatch_in_use_is_what_the_registry_gives():
    """observer_dispatch.py (the installed copy, the one imported) is written from the registry; a
    registry change without ``python -m pac_observer.observer_dispatch_source --write`` fails here."""
    text = observer_dispatch_source.observer_dispatch_source(OBSERVERS)
    assert Path(observer_dispatch.__file__).read_text() == text


def test_each_core_writes_the_code_the_dispatch_branches_on():
    """The records a core class fills carry its registry code, and the generated table agrees."""
    assert observer_dispatch.OBSERVER_CODES == OBSERVER_CODES
    for name in OBSERVERS:
        params = ObserverParameters(observer=name)
        core = core_class(name)(PantographParameters(), TrackParameters(), params, 1e-3)
        assert core.consts[0]["kind"] == OBSERVER_CODES[name], name


def test_the_parameter_offers_every_registered_observer_and_what_it_gives():
    assert tuple(OBSERVER_GIVES) == tuple(OBSERVERS)
    (observer,) = (spec for spec in ObserverParameters.specs() if spec.name == "observer")
    assert tuple(observer.choices) == tuple(OBSERVERS)


def test_an_unknown_code_is_a_divergence_of_its_own():
    consts, state = np.zeros(1, OBSERVER_CONSTS), np.zeros(1, OBSERVER_STATE)
    consts[0]["kind"] = len(OBSERVER_CODES)
    status, _, _ = observer_dispatch.observer_update(1, 0.0, consts[0], state[0], NO_BANK, 0.0, 0.0, 0.0, 0.0)
    assert status == divergence.UNKNOWN_OBSERVER
    assert "no compiled observer" in divergence.reason(status)


def test_an_observer_module_without_its_update_is_refused_in_one_line():
    observers = dict(OBSERVERS, another=OBSERVERS["adaptive"])
    with pytest.raises(ValueError, match="lacks another_update") as refused:
        observer_dispatch_source.observer_dispatch_source(observers)
    assert "\n" not in str(refused.value)


def test_the_parameter_help_says_what_each_registered_observer_is():
    (observer,) = (spec for spec in ObserverParameters.specs() if spec.name == "observer")
    for name, entry in OBSERVERS.items():
        assert f"'{name}' {entry.description}" in observer.description
