"""The compiled (numba) cores against the numpy implementation they replaced (tests/oracle_cores.py)."""

import math

import numpy as np
import oracle_cores as oracle
import pytest

from pac_controller.parameters import LAW_NAMES, ReferenceParameters
from pac_controller.reference import ForceReference
from pac_experiments.bench.rig import allocations_per_tick, loop_allocations
from pac_experiments.reproduce import COMMON
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.contact_force import BANK_ARGS
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant
from pac_rig.closed_loop import run
from pac_rig.loop import FE_ARGS
from pac_rig.simulate import scenario_from_flat

pytestmark = pytest.mark.unit

DT = 1e-3


def rel_error(got: np.ndarray, want: np.ndarray) -> float:
    """Largest deviation over a trace, relative to the largest magnitude of the oracle's trace."""
    return float(np.max(np.abs(got - want)) / np.max(np.abs(want)))


@pytest.mark.parametrize("shape", ["constant", "square"])
@pytest.mark.slow
def test_closed_loop_agrees_with_numpy_oracle(shape):
    """10 s closed loop (plant, observer, controller): every trace within 1e-9 relative of the oracle."""
    scenario = scenario_from_flat({**COMMON, "shape": shape})
    ticks = scenario.loop.ticks
    assert ticks == 10000
    want = oracle.closed_loop(scenario, ticks)
    got = {"z": [], "z_hat": [], "theta_hat": [], "u": []}
    for rec in run(scenario):
        got["z"].append(rec.truth.z)
        got["z_hat"].append(rec.estimate.z_hat)
        got["theta_hat"].append(rec.estimate.theta_hat)
        got["u"].append(rec.command.u)
    for name, values in got.items():
        values = np.array(values)
        assert values.shape == want[name].shape
        for col in range(values.shape[1] if values.ndim == 2 else 1):
            g = values[:, col] if values.ndim == 2 else values
            w = want[name][:, col] if values.ndim == 2 else want[name]
            assert rel_error(g, w) <= 1e-9, (name, col, rel_error(g, w))
    # the run really converged (so the comparison covers the transient and the steady state)
    assert abs(got["theta_hat"][-1][0] - 4000.0) < 1.0


@pytest.mark.parametrize("contact_model", ["linear", "unilateral"])
def test_plant_agrees_with_numpy_oracle(contact_model):
    """Open loop, a force that lifts the head off the wire: compiled plant == numpy plant to 1e-12."""
    options = PlantOptions(contact_model=contact_model)
    plant = Plant(PantographParameters(), TrackParameters(), CatenaryParameters(), options, DT)
    ref = oracle.OraclePlant(
        PantographParameters(),
        TrackParameters(),
        CatenaryParameters(),
        options.substeps,
        DT,
        contact_model == "unilateral",
    )
    zs, refs = [], []
    for k in range(3000):
        u = 100.0 + 400.0 * math.sin(20.0 * k * DT)
        plant.advance(u)
        ref.advance(u)
        zs.append(plant.z)
        refs.append(ref.z)
    zs, refs = np.array(zs), np.array(refs)
    assert np.min(zs[:, 0]) < 0.0  # contact really lost
    for col in range(4):
        assert rel_error(zs[:, col], refs[:, col]) <= 1e-12


@pytest.mark.parametrize("shape", ["constant", "step", "square"])
def test_reference_agrees_with_numpy_oracle(shape):
    """F_r and derivatives, including long after many square-wave steps have been forgotten."""
    params = ReferenceParameters(shape=shape, period=0.5, step_time=1.5)
    ref = ForceReference(params)
    for t in [0.0, 1e-3, 0.25, 1.5, 1.5001, 3.7, 100.0, 1000.123]:
        np.testing.assert_array_equal(ref.at(t), oracle.reference_at(params, t))
        assert ref.steps_before(t) == oracle.reference_steps_before(params, t)


@pytest.mark.slow
def test_compiled_tick_allocates_nothing():
    """numba's own allocation counter (NRT statistics): a call of 9980 ticks allocates what a call of
    10 ticks does (the arrays handed over by Python, adopted once per call), for every law and with a
    train's sensor suite: 0 per tick."""
    counts = loop_allocations()  # in a fresh process with NUMBA_NRT_STATS=1
    assert set(LAW_NAMES) < set(counts)  # every law, line_adaptive included, and a sensor suite
    # The call's array arguments, not its ticks: the six records, noise and output, the FE line's
    # buffers (empty on the lumped line), the contact-force bank's (empty for the paper's observer)
    # and the law's two tables.
    arguments = 8 + len(FE_ARGS) + len(BANK_ARGS) + 2
    for law, calls in counts.items():
        assert calls["9980 ticks"] == calls["10 ticks"], (law, calls)
        assert calls["10 ticks"][0] <= arguments, (law, calls)
    assert allocations_per_tick(counts) == 0.0
