"""Parameter validation: every set's defaults are valid; bad values are named, shown and bounded."""

import math

import pytest

from pac_common.parameters import LoopParameters, ParameterError
from pac_controller.parameters import ControllerParameters, LawParameters, ReferenceParameters
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.parameters import ObserverParameters
from pac_plant.parameters import PlantOptions

pytestmark = pytest.mark.unit

ALL_SETS = [
    PantographParameters,
    TrackParameters,
    CatenaryParameters,
    PlantOptions,
    ObserverParameters,
    ControllerParameters,
    ReferenceParameters,
    LawParameters,
    LoopParameters,
]


@pytest.mark.parametrize("cls", ALL_SETS)
def test_defaults_are_valid_and_documented(cls):
    params = cls()
    for spec in cls.specs():
        assert spec.description, spec.name
        assert spec.check(getattr(params, spec.name)) == getattr(params, spec.name)


BAD = [
    (PantographParameters, "m1", -1.0, "(0, inf) kg"),
    (PantographParameters, "k1", 0.0, "(0, inf) N/m"),
    (CatenaryParameters, "k0", 0.0, "(0, inf) N/m"),
    (CatenaryParameters, "alpha", 1.0, "(-1, 1)"),
    (CatenaryParameters, "alpha", math.nan, "(-1, 1)"),
    (TrackParameters, "speed_kmh", 0.0, "(0, 600] km/h"),
    (PlantOptions, "contact_model", "sticky", "one of linear, unilateral"),
    (PlantOptions, "substeps", 0, "an integer in [1, 1000]"),
    (ObserverParameters, "rho_z", 10.0, "[27, 1000] 1/s"),
    (ObserverParameters, "sigma", (100.0,), "2 finite values"),
    (ObserverParameters, "theta_hat0", (1.0, math.inf, 0.0), "3 finite values"),
    (ControllerParameters, "c1", 0.0, "(0, 10000] 1/s"),
    (ControllerParameters, "mode", "manual", "one of active, passive"),
    (
        ControllerParameters,
        "law",
        "nope",
        "one of adaptive_backstepping, backstepping_known, pid, lqr, passive",
    ),
    (LawParameters, "pid_phase_margin", 5.0, "[10, 80] deg"),
    (LawParameters, "lqr_force_scale", 0.0, "(0, 10000] N"),
    (ReferenceParameters, "filter_bandwidth", -2.0, "[0.1, 500] rad/s"),
    (LoopParameters, "rate_hz", 0.0, "[1, 20000] Hz"),
]


@pytest.mark.parametrize(("cls", "name", "value", "allowed"), BAD)
def test_bad_value_is_refused_with_name_value_and_range(cls, name, value, allowed):
    with pytest.raises(ParameterError) as info:
        cls(**{name: value})
    message = str(info.value)
    assert "\n" not in message
    assert f"'{name}'" in message
    assert repr(value) in message or repr(tuple(value) if isinstance(value, tuple) else value) in message
    assert allowed in message


def test_cross_field_check():
    with pytest.raises(ParameterError, match="u_max"):
        ControllerParameters(u_min=10.0, u_max=-10.0)


def test_bool_is_not_a_number():
    with pytest.raises(ParameterError):
        PantographParameters(m1=True)


def test_from_mapping_ignores_other_sets_names():
    p = PantographParameters.from_mapping({"m1": 9.0, "k0": 1.0})
    assert p.m1 == 9.0


def test_a_refusal_crosses_a_process_boundary_as_itself():
    """A worker's ParameterError (and each kind of it) reaches the parent with its one line and
    fields, not a pickling error that breaks the pool."""
    import pickle

    from pac_common.data_file import DataFileError
    from pac_common.parameters import UnknownParameterError
    from pac_rig.composition import CompositionError

    for error in (
        ParameterError("speed_kmh", -1.0, "a number > 0"),
        UnknownParameterError("sped_kmh", 300.0, "simulate"),
        DataFileError("line.yaml", "spans", [], "a list of span lengths", ", line 3, column 1"),
        CompositionError("law", "pid", "pid needs F_hat: observer:=contact_force"),
    ):
        back = pickle.loads(pickle.dumps(error))
        assert type(back) is type(error)
        assert str(back) == str(error)
        assert (back.name, back.value, back.allowed) == (error.name, error.value, error.allowed)
