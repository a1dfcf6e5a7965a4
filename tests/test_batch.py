"""One compiled loop (pac_rig.loop) for every law: the batch, closed_loop.run and the core objects
stepped tick by tick (as the nodes step them) give the same numbers bit for bit, divergence included."""

import dataclasses
import math

import numpy as np
import pytest

from pac_controller.laws import LAWS
from pac_controller.parameters import COMPILED_LAW_NAMES, LAW_NAMES
from pac_experiments.reproduce import COMMON, PAPER_GAINS
from pac_observer.parameters import OBSERVER_GIVES
from pac_rig import composition
from pac_rig.batch import TRACES, _run_one, actuator_violation, batchable, prepare, run_batch
from pac_rig.closed_loop import DivergenceError, build_cores, run, run_cores
from pac_rig.loop import MAX_DELAY, TICK, compile_loop
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
                    rec.estimate.contact_force_hat,
                    rec.truth.contact_uplift,
                    rec.truth.contact_position,
                    rec.truth.u_applied,
                    rec.command.saturated,
                )
            )
    except DivergenceError as exc:
        reason = exc.reason
    return np.array(rows).reshape(-1, len(TRACES)).T, reason


def fields(rec):
    """Every number a tick's four records carry (NaN as "nan": equal to itself)."""
    out = []
    for part in (rec.measurement, rec.truth, rec.estimate, rec.command):
        for f in dataclasses.fields(part):
            value = getattr(part, f.name)
            out.extend(
                np.ravel(np.asarray(value, dtype=object)).tolist() if not isinstance(value, str) else [value]
            )
    return ["nan" if isinstance(v, float) and v != v else v for v in out]


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
def test_every_law_and_observer_is_batchable_on_both_lines():
    assert tuple(COMPILED_LAW_NAMES) == tuple(LAW_NAMES)
    for law in LAW_NAMES:
        for line in ("lumped", "fe"):
            for observer in ("adaptive", "contact_force"):
                flat = {"law": law, "catenary_model": line, "observer": observer, "duration": 0.01}
                s = scenario_from_flat(composition.derive(flat)[0])  # as a run composes it
                if LAWS[law].needs_of(s.laws.force_estimate) - OBSERVER_GIVES[observer]:
                    continue  # refused before any run (tests/test_composition.py)
                assert batchable(s)
                # told from the parameters: the same answer as compiling the cores
                assert compile_loop(*build_cores(s), s.loop.command_delay_ticks) is not None
    # The most delay a scenario can ask for.
    s = scenario_from_flat({"command_delay_ticks": MAX_DELAY, "duration": 0.01})
    assert batchable(s) and compile_loop(*build_cores(s), MAX_DELAY) is not None


#: Short FE runs (the line's set-up dominates): the compiled loop against the core objects.
FE_SCENARIOS = {
    "passive_static_wire": {"law": "passive", "observer": "contact_force", "fe_datum": "static_wire"},
    "line_adaptive_fixed": {
        "law": "line_adaptive", "observer": "contact_force", "fe_datum": "fixed", "noise_std": (1e-5, 1e-5),
        "command_delay_ticks": 2, "speed_kmh": 300.0,
    },
    "pid_adaptive_observer": {"law": "pid", "observer": "adaptive", "speed_kmh": 250.0},
    # the fixed-gain laws on the filter's own F_hat (force_estimate), as composition derives them
    "pid_force_filter": {
        "law": "pid", "observer": "contact_force", "force_estimate": "contact_force_hat", "speed_kmh": 300.0,
    },
    "lqr_force_filter": {
        "law": "lqr", "observer": "contact_force", "force_estimate": "contact_force_hat", "speed_kmh": 300.0,
        "lqr_force_scale": 3.0,
    },
}  # fmt: skip


@pytest.fixture(scope="module")
def fe_batch():
    scenarios = [
        scenario_from_flat({"catenary_model": "fe", "duration": 0.4, **flat})
        for flat in FE_SCENARIOS.values()
    ]
    return scenarios, run_batch(scenarios, threads=2)


@pytest.mark.parametrize("index", range(len(FE_SCENARIOS)), ids=list(FE_SCENARIOS))
def test_fe_line_compiled_equals_tick_by_tick_cores(fe_batch, index):
    """On the FE line: closed_loop.run (compiled) == the core objects, every field of every record;
    the batch's traces == the same."""
    scenarios, result = fe_batch
    s = scenarios[index]
    compiled = [fields(rec) for rec in run(s)]
    per_tick = [fields(rec) for rec in run_cores(s, *build_cores(s))]
    assert len(compiled) == len(per_tick) == s.loop.ticks
    # NaN-free on the FE line (the uplifts are numbers there), so == compares every value.
    assert compiled == per_tick
    want, reason = traces_of(run_cores(s, *build_cores(s)))
    assert reason is None and result.diverged[index] is None
    for j, name in enumerate(TRACES):
        np.testing.assert_array_equal(result.traces[name][index], want[j], err_msg=name)


def test_a_command_the_safety_chain_cannot_give_is_found(batch):
    """run_batch checks every run with actuator_violation (a BatchFault if one fails): the
    "limits" runs keep it while saturated and slew limited; a garbage command written into one is
    found at its tick (a step), and a slew-limited climb past u_max at the first tick beyond it."""
    scenarios, result = batch
    limited = []  # the "limits" runs in which saturation and the slew limit both bind
    for i, (name, _) in enumerate(CASES):
        s, u = scenarios[i], result.traces["u"][i, : result.ticks[i]]
        step = s.controller.slew_rate_max * s.loop.sample_period
        if name == "limits" and u.max() == s.controller.u_max and np.isclose(np.abs(np.diff(u)).max(), step):
            limited.append((s, u, step))
    assert limited
    for s, u, _ in limited:
        assert actuator_violation(u, s) is None
    s, u, step = limited[0]
    garbage = u.copy()
    garbage[300] = 4.09e-98  # what an overwritten record gave (docs/numerics.md)
    assert actuator_violation(garbage, s)[0] == 300
    assert "stepped" in actuator_violation(garbage, s)[1]
    climb = u.copy()
    climb[500:] = u[499] + 0.5 * step * np.arange(1, u.size - 499)
    beyond = int(np.argmax(climb > s.controller.u_max))
    assert beyond > 500 and actuator_violation(climb, s) == (
        beyond,
        f"u = {climb[beyond]:.6g} N outside [{s.controller.u_min:g}, {s.controller.u_max:g}] N",
    )


def test_each_tick_is_written_into_the_record_the_caller_holds():
    """The compiled loop writes every tick's record into the caller's array, which lives as long
    as the call: the last tick's values are there afterwards. (A record made inside the compiled
    loop from a temporary array pointed into freed memory: numba's records do not keep their
    array alive, and runs in threads were overwritten; docs/numerics.md, "The batch's threads".)"""
    s = scenario_from_flat({**COMMON, "duration": 0.2})
    loop, noise = prepare(0, s)
    out = np.full((len(TRACES), s.loop.ticks), np.nan)
    record = np.zeros(1, TICK)
    assert _run_one(s.loop.ticks, *loop.args(), noise, out, record) == (s.loop.ticks, 0, 0.0)
    last = record[0]
    assert last["force_reference"] > 0.0 and last["u"] != 0.0  # a tick was written, not zeros
    for j, name in enumerate(TRACES):
        value = last["z"][0] if name == "z1" else last[name]
        np.testing.assert_equal(value, out[j, -1], err_msg=name)  # NaN where the line has none


def test_empty_batch_is_refused():
    with pytest.raises(ValueError, match="at least one scenario"):
        run_batch([])


#: A train's sensor suites (positions from the moving roof, accelerometers, a load cell) on both
#: lines: the suite's low-pass, latency ring and noise run inside the compiled loop.
SENSOR_SCENARIOS = {
    "lumped_train_roof": {
        **COMMON, "sensors": "train", "roof_motion": "german_high", "shape": "square", "period": 0.4,
        "duration": 1.0,
    },
    "lumped_load_cell_turbulence_lqr": {
        **COMMON, "sensors": "train_load_cell", "nominal_pantograph": "three_mass_identified_2dof",
        "aero_turbulence": 0.1, "law": "lqr", "command_delay_ticks": 3, "noise_seed": 7, "duration": 1.0,
    },
    # the backstepping law with the paper's gains diverges: the compiled loop stops where the cores do
    "lumped_train_diverges": {**COMMON, **PAPER_GAINS, "sensors": "train", "duration": 0.5},
    "fe_load_cell_roof": {
        "catenary_model": "fe", "pantograph": "three_mass", "roof_motion": "german_low",
        "sensors": "train_load_cell", "law": "line_adaptive", "observer": "contact_force",
        "speed_kmh": 300.0, "duration": 0.3,
    },
    "fe_train_static_wire": {
        "catenary_model": "fe", "sensors": "train", "fe_datum": "static_wire", "law": "pid",
        "command_delay_ticks": 2, "duration": 0.3,
    },
}  # fmt: skip


@pytest.fixture(scope="module")
def sensor_batch():
    scenarios = [scenario_from_flat(flat) for flat in SENSOR_SCENARIOS.values()]
    return scenarios, run_batch(scenarios, threads=2)


@pytest.mark.parametrize("index", range(len(SENSOR_SCENARIOS)), ids=list(SENSOR_SCENARIOS))
def test_a_trains_sensors_compiled_equal_tick_by_tick_cores(sensor_batch, index):
    """With a train's sensor suite: closed_loop.run (compiled) == the core objects stepped tick by
    tick, every field of every record (the measurement's accelerations, load cell and from_roof
    included), divergence included; the batch's traces == the same."""
    scenarios, result = sensor_batch
    s = scenarios[index]
    assert batchable(s) and compile_loop(*build_cores(s), s.loop.command_delay_ticks) is not None
    compiled, per_tick, reasons = [], [], []
    for records, into in ((run(s), compiled), (run_cores(s, *build_cores(s)), per_tick)):
        try:
            for rec in records:
                into.append((rec.measurement, fields(rec)))
            reasons.append(None)
        except DivergenceError as exc:
            reasons.append((exc.tick, exc.reason))
    assert reasons[0] == reasons[1]
    assert len(compiled) == len(per_tick) > 0
    assert [f for _, f in compiled] == [f for _, f in per_tick]
    # The suite measured (not the ground's): from the roof, its accelerometers, its load cell or none.
    load_cell = s.plant.sensors == "train_load_cell"
    for m, _ in compiled:
        assert m.from_roof and math.isfinite(m.head_acceleration) and math.isfinite(m.frame_acceleration)
        assert math.isfinite(m.head_force) == load_cell
    want, reason = traces_of(run_cores(s, *build_cores(s)))
    n = want.shape[1]
    assert result.ticks[index] == n and result.diverged[index] == reason
    for j, name in enumerate(TRACES):
        np.testing.assert_array_equal(result.traces[name][index][:n], want[j], err_msg=name)
