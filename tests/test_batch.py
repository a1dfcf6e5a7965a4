"""One compiled loop (pac_rig.loop) for every law: the batch, closed_loop.run and the core objects
stepped tick by tick (as the nodes step them) give the same numbers bit for bit, divergence included."""

import dataclasses

import numpy as np
import pytest

from pac_controller.parameters import COMPILED_LAW_NAMES, LAW_NAMES
from pac_experiments.reproduce import COMMON, PAPER_GAINS
from pac_rig.batch import TRACES, batchable, run_batch
from pac_rig.closed_loop import DivergenceError, build_cores, run, run_cores
from pac_rig.loop import compile_loop
from pac_rig.simulate import scenario_from_flat

pytestmark = pytest.mark.offline

SCENARIOS = {
    "square": {**COMMON, "shape": "square", "duration": 2.0},
    "paper_gains": {**COMMON, **PAPER_GAINS, "duration": 0.5},  # the backstepping laws diverge
    "noisy_delay3": {
        **COMMON,
        "noise_std": (1e-5, 1e-5),
        "quantisation": 1e-6,
        "command_delay_ticks": 3,
        "duration": 1.0,
    },
    "unilateral": {**COMMON, "contact_model": "unilateral", "duration": 1.0},
    "unilateral_lift": {
        **COMMON,
        "contact_model": "unilateral",
        "shape": "square",
        "period": 0.4,
        "force_amplitude": 150.0,
        "duration": 1.0,
    },
    "delay0_step": {**COMMON, "shape": "step", "step_time": 0.5, "command_delay_ticks": 0, "duration": 1.0},
    # the plant's masses differ from the model the observer and controller use
    "mass_mismatch": {**COMMON, "plant_mass_scale": 1.3, "command_delay_ticks": 2, "duration": 1.0},
    # slew limit and saturation active; the pid/lqr designs for 2 ticks of delay
    "limits": {
        **COMMON,
        "shape": "square",
        "slew_rate_max": 2000.0,
        "u_max": 120.0,
        "design_delay_ticks": 2,
        "duration": 1.0,
    },
}
CASES = [(name, law) for name in SCENARIOS for law in COMPILED_LAW_NAMES]


def scenario(name, law):
    return scenario_from_flat({**SCENARIOS[name], "law": law})


def traces_of(records):
    """The traces of TRACES from TickRecords, and the divergence reason."""
    rows, reason = [], None
    try:
        for rec in records:
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
    return np.array(rows).reshape(-1, len(TRACES)).T, reason


def fields(rec):
    """Every number a tick's four records carry."""
    out = []
    for part in (rec.measurement, rec.truth, rec.estimate, rec.command):
        for f in dataclasses.fields(part):
            value = getattr(part, f.name)
            out.extend(
                np.ravel(np.asarray(value, dtype=object)).tolist() if not isinstance(value, str) else [value]
            )
    return out


@pytest.fixture(scope="module")
def batch():
    scenarios = [scenario(name, law) for name, law in CASES]
    return scenarios, run_batch(scenarios, threads=2)


@pytest.mark.parametrize("index", range(len(CASES)), ids=[f"{n}-{law}" for n, law in CASES])
def test_batch_equals_tick_by_tick_cores(batch, index):
    """Batch traces == the core objects stepped tick by tick (the nodes' path), every law."""
    scenarios, result = batch
    s = scenarios[index]
    want, reason = traces_of(run_cores(s, *build_cores(s)))
    n = want.shape[1]
    assert result.ticks[index] == n
    assert result.diverged[index] == reason
    for j, name in enumerate(TRACES):
        got = result.traces[name][index]
        np.testing.assert_array_equal(got[:n], want[j], err_msg=name)
        assert np.isnan(got[n:]).all()


@pytest.mark.parametrize("law", LAW_NAMES)
@pytest.mark.parametrize("name", ["noisy_delay3", "limits", "paper_gains"])
def test_closed_loop_run_equals_tick_by_tick_cores(name, law):
    """closed_loop.run (compiled step, block by block) == the core objects: every field of every record."""
    s = scenario(name, law)
    compiled, per_tick = [], []
    reasons = []
    for records, into in ((run(s), compiled), (run_cores(s, *build_cores(s)), per_tick)):
        try:
            for rec in records:
                into.append(fields(rec))
            reasons.append(None)
        except DivergenceError as exc:
            reasons.append((exc.tick, exc.reason))
    assert reasons[0] == reasons[1]
    assert len(compiled) == len(per_tick) > 0
    assert compiled == per_tick


def test_paper_gains_diverge_in_batch_too(batch):
    _, result = batch
    i = CASES.index(("paper_gains", "adaptive_backstepping"))
    assert result.ticks[i] == 234 and "exceeded" in result.diverged[i]


@pytest.mark.slow
def test_every_law_is_batchable_on_the_lumped_line_only():
    for law in LAW_NAMES:
        for line, expected in (("lumped", law in COMPILED_LAW_NAMES), ("fe", False)):
            s = scenario_from_flat({"law": law, "catenary_model": line, "duration": 0.01})
            assert batchable(s) is expected
            # told from the parameters: the same answer as compiling the cores
            assert (compile_loop(*build_cores(s), s.loop.command_delay_ticks) is not None) is expected
    # No kernel yet for the learning law or the contact-force observer: they run tick by tick.
    assert set(LAW_NAMES) - set(COMPILED_LAW_NAMES) == {"line_adaptive"}
    s = scenario_from_flat({"observer": "contact_force", "duration": 0.01})
    assert not batchable(s) and compile_loop(*build_cores(s), s.loop.command_delay_ticks) is None
    with pytest.raises(ValueError, match="no form for catenary_model fe"):
        run_batch([scenario_from_flat({"catenary_model": "fe", "duration": 0.01})])


def test_empty_batch_is_refused():
    with pytest.raises(ValueError, match="at least one scenario"):
        run_batch([])
