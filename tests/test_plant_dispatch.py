"""The compiled plants' dispatch is the registry's: generated, current, its codes the records'."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pac_common import divergence
from pac_plant import plant_dispatch, plant_dispatch_source
from pac_plant.plant_kernels import NO_FE
from pac_plant.plants import PLANT_CODES, PLANTS, compiled_plant
from pac_rig.closed_loop import build_cores
from pac_rig.loop import PLANT_PARAMS, PLANT_STATE, TICK, compile_loop
from pac_rig.scenario import from_flat

pytestmark = pytest.mark.unit


def test_the_dispatch_in_use_is_what_the_registry_gives():
    """plant_dispatch.py (the installed copy, the one imported) is written from the registry; a
    registry change without ``python -m pac_plant.plant_dispatch_source --write`` fails here."""
    assert Path(plant_dispatch.__file__).read_text() == plant_dispatch_source.plant_dispatch_source(PLANTS)
    assert plant_dispatch.PLANT_CODES == PLANT_CODES


@pytest.mark.parametrize("catenary_model", list(PLANTS))
def test_each_plant_is_compiled_under_its_registry_code(catenary_model):
    """The loop's records of a scenario on each plant carry that plant's code (its ``<name>_pack``)."""
    plant, observer, controller = build_cores(from_flat({"catenary_model": catenary_model, "duration": 0.01}))
    assert compiled_plant(plant) is PLANTS[catenary_model]
    loop = compile_loop(plant, observer, controller, 0)
    assert loop is not None
    assert loop.plant_params[0]["kind"] == PLANT_CODES[catenary_model]


def test_an_unknown_code_is_a_divergence_of_its_own():
    pp, ps, out = np.zeros(1, PLANT_PARAMS), np.zeros(1, PLANT_STATE), np.zeros(1, TICK)
    pp[0]["kind"] = len(PLANT_CODES)
    assert plant_dispatch.plant_advance(0, pp[0], ps[0], NO_FE, 0.0) == divergence.UNKNOWN_PLANT
    assert "no compiled plant" in divergence.reason(divergence.UNKNOWN_PLANT)
    stiffness, force, _, _ = plant_dispatch.plant_output(0, 0.0, pp[0], ps[0], NO_FE, out[0])
    assert np.isnan(stiffness) and np.isnan(force)


def test_a_plant_module_without_its_functions_is_refused_in_one_line():
    plants = dict(PLANTS, another=replace(PLANTS["lumped"], name="another"))
    with pytest.raises(ValueError, match="lacks another_pack") as refused:
        plant_dispatch_source.plant_dispatch_source(plants)
    assert "\n" not in str(refused.value)


def test_the_parameter_help_says_what_each_registered_plant_is():
    from pac_plant.parameters import PlantOptions

    (model,) = (spec for spec in PlantOptions.specs() if spec.name == "catenary_model")
    assert tuple(model.choices) == tuple(PLANTS)
    for name, kind in PLANTS.items():
        assert f"'{name}' {kind.description}" in model.description
