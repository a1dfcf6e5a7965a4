"""Plant core: stepping accuracy against solve_ivp, static equilibrium, contact laws."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pac_common.parameters import RateParameters
from pac_model import model
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant

pytestmark = pytest.mark.unit

DT = RateParameters().sample_period  # the nodes' default rate
SCALE = np.array([0.03, 0.03, 0.5, 0.5])  # typical magnitudes of z at 100 N


def make_plant(**kw):
    return Plant(
        PantographParameters(),
        TrackParameters(),
        CatenaryParameters(**kw.pop("catenary", {})),
        PlantOptions(**kw),
        DT,
    )


@pytest.mark.parametrize(("substeps", "bound"), [(1, 5e-8), (2, 5e-9)])
def test_stepping_matches_solve_ivp(substeps, bound):
    """ZOH input, 2 s: scaled error against DOP853 at rtol 1e-12 stays below the documented bound."""
    plant = make_plant(substeps=substeps)
    z = np.zeros(4)
    worst = 0.0
    for k in range(2000):
        u = 100.0 + 30.0 * math.sin(7.0 * k * DT)
        sol = solve_ivp(
            lambda t, x, u=u: plant.derivative(t, x, u),
            (k * DT, (k + 1) * DT),
            z,
            method="DOP853",
            rtol=1e-12,
            atol=1e-15,
        )
        z = sol.y[:, -1]
        plant.advance(u)
        worst = max(worst, float(np.max(np.abs(plant.z - z) / SCALE)))
    assert worst < bound
    assert abs(z[0]) > 1e-3  # the run really moved


def test_static_equilibrium_contact_force_equals_uplift():
    """alpha = 0 (constant k): under a held u the head settles where F = u (eq. (3) at rest)."""
    plant = make_plant(catenary={"alpha": 0.0})
    for _ in range(20000):
        plant.advance(100.0)
    truth = plant.truth()
    assert truth.contact_force == pytest.approx(100.0, abs=1e-6)
    expected = model.static_equilibrium(100.0, 4000.0, PantographParameters())
    np.testing.assert_allclose(truth.z, expected, atol=1e-9)
    assert expected[0] == pytest.approx(0.025) and expected[1] == pytest.approx(0.035)


def test_truth_is_consistent_with_model():
    plant = make_plant()
    for _ in range(500):
        plant.advance(100.0)
    t = plant.truth()
    assert t.stiffness == pytest.approx(
        4000.0 * (1 + 0.5 * math.cos(TrackParameters().omega * 0.5 - math.pi / 4))
    )
    assert t.contact_force == pytest.approx(t.stiffness * t.z[0])
    assert t.u_applied == 100.0 and plant.measurement().actuator_force == 100.0
    assert plant.measurement().z1 == t.z[0]


def test_unilateral_contact_never_pulls():
    """A passive 100 N uplift loses contact at 360 km/h: linear F goes negative, unilateral stops at 0."""
    lin, uni = make_plant(), make_plant(contact_model="unilateral")
    f_lin, f_uni, lost = [], [], 0
    for _ in range(4000):
        lin.advance(100.0)
        uni.advance(100.0)
        f_lin.append(lin.truth().contact_force)
        f_uni.append(uni.truth().contact_force)
        lost += not uni.truth().in_contact
    assert min(f_lin) < -10.0
    assert min(f_uni) == 0.0
    assert lost > 0


def test_stiffness_regressor_derivatives_match_finite_differences():
    omega, t, h = 9.67, 0.37, 1e-5
    d = model.stiffness_regressor_derivatives(t, omega, 3)
    for n in range(1, 4):
        prev = model.stiffness_regressor_derivatives(t - h, omega, 3)[n - 1]
        nxt = model.stiffness_regressor_derivatives(t + h, omega, 3)[n - 1]
        np.testing.assert_allclose(d[n], (nxt - prev) / (2 * h), rtol=1e-6, atol=1e-6 * omega**n)


def test_non_finite_force_is_refused():
    with pytest.raises(ValueError, match="finite"):
        make_plant().advance(math.nan)


def test_measurement_noise_is_seeded_per_tick_and_quantised():
    opts = {"noise_std": (1e-4, 2e-4), "noise_seed": 3}
    a, b = make_plant(**opts), make_plant(**opts)
    other_seed = make_plant(noise_std=(1e-4, 2e-4), noise_seed=4)
    noise = []
    for _ in range(6000):
        ya, yb = a.measurement(), b.measurement()
        assert ya == yb and a.measurement() == ya  # same seed, same tick: the same sample, also re-sent
        noise.append((ya.z1 - a.z[0], ya.z2 - a.z[1]))
        for plant in (a, b, other_seed):
            plant.advance(100.0)
    noise = np.array(noise)
    np.testing.assert_allclose(noise.std(axis=0), (1e-4, 2e-4), rtol=0.05)
    assert abs(noise.mean(axis=0)).max() < 1e-5
    assert other_seed.measurement().z1 != a.measurement().z1
    assert a.truth().z[0] == a.z[0]  # the truth is never noisy
    q = make_plant(quantisation=1e-4)
    for _ in range(300):
        q.advance(100.0)
    y = q.measurement()
    assert y.z1 == pytest.approx(round(q.z[0] / 1e-4) * 1e-4, abs=1e-15) and y.z1 != q.z[0]


@pytest.mark.unit
def test_what_a_plant_can_do_is_read_from_the_registry_of_plants(monkeypatch):
    """Every catenary_model is a registry entry whose class is a Plant; the checks ask the entry, not
    the name: the lumped line refuses several pantographs until its entry says it carries them."""
    import dataclasses

    from pac_common.parameters import ParameterError
    from pac_plant import plants

    choices = next(spec.choices for spec in PlantOptions.specs() if spec.name == "catenary_model")
    assert tuple(choices) == tuple(plants.PLANTS)
    for name, kind in plants.PLANTS.items():
        assert kind.name == name and issubclass(kind.plant_class(), Plant)
    with pytest.raises(ParameterError, match="several need catenary_model fe"):
        PlantOptions(pantographs=(0.0, 200.0))
    lumped = plants.PLANTS["lumped"]
    monkeypatch.setitem(plants.PLANTS, "lumped", dataclasses.replace(lumped, several_pantographs=True))
    assert PlantOptions(pantographs=(0.0, 200.0)).pantographs == (0.0, 200.0)
