"""The compiled batch closed loop (pac_rig.batch) equals closed_loop.run bit for bit, divergence included."""

import numpy as np
import pytest

from pac_experiments.reproduce import COMMON, PAPER_GAINS
from pac_rig.batch import TRACES, run_batch
from pac_rig.closed_loop import DivergenceError, run
from pac_rig.simulate import scenario_from_flat

pytestmark = pytest.mark.offline

SCENARIOS = {
    "square": {**COMMON, "shape": "square", "duration": 3.0},
    "paper_gains": {**COMMON, **PAPER_GAINS, "duration": 1.0},  # diverges at 0.234 s
    "noisy_delay3": {
        **COMMON,
        "noise_std": (1e-5, 1e-5),
        "quantisation": 1e-6,
        "command_delay_ticks": 3,
        "duration": 2.0,
    },
    "passive_unilateral": {**COMMON, "mode": "passive", "contact_model": "unilateral", "duration": 2.0},
    "delay0_step": {**COMMON, "shape": "step", "step_time": 0.5, "command_delay_ticks": 0, "duration": 1.0},
    # the plant's masses differ from the model the observer and controller use
    "mass_mismatch": {**COMMON, "plant_mass_scale": 1.3, "command_delay_ticks": 2, "duration": 1.0},
}


def per_tick(scenario):
    """The traces of TRACES from the per-tick generator, and its divergence reason."""
    rows, reason = [], None
    try:
        for rec in run(scenario):
            rows.append(
                (
                    rec.truth.contact_force,
                    rec.command.force_reference,
                    rec.command.u,
                    rec.truth.stiffness,
                    rec.estimate.stiffness_hat,
                    rec.truth.z[0],
                )
            )
    except DivergenceError as exc:
        reason = exc.reason
    return np.array(rows).T, reason


@pytest.fixture(scope="module")
def batch():
    scenarios = [scenario_from_flat(v) for v in SCENARIOS.values()]
    return scenarios, run_batch(scenarios, threads=2)


@pytest.mark.parametrize("index", range(len(SCENARIOS)), ids=list(SCENARIOS))
def test_batch_equals_per_tick_loop(batch, index):
    scenarios, result = batch
    want, reason = per_tick(scenarios[index])
    n = want.shape[1]
    assert result.ticks[index] == n
    assert result.diverged[index] == reason
    for j, name in enumerate(TRACES):
        got = result.traces[name][index]
        np.testing.assert_array_equal(got[:n], want[j], err_msg=name)
        assert np.isnan(got[n:]).all()


def test_paper_gains_diverge_in_batch_too(batch):
    _, result = batch
    i = list(SCENARIOS).index("paper_gains")
    assert result.ticks[i] == 234 and "exceeded" in result.diverged[i]


def test_empty_batch_is_refused():
    with pytest.raises(ValueError, match="at least one scenario"):
        run_batch([])
