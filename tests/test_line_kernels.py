"""The compiled line_adaptive law and contact-force observer against the numpy code they replaced.

line_adaptive's outputs must not change when it is compiled: the shipped law (its compiled
functions, which the class and the compiled loop call) is driven side by side with the numpy
implementation it replaced (tests/line_adaptive_oracle.py) on random force estimates, with
and without the actuator clipping it: the same modes at every tick, and commands, errors and
learned harmonics that differ by rounding only (:func:`assert_same_law`), on any CPU.
"""

import math

import line_adaptive_oracle as oracle
import numpy as np
import pytest

from pac_controller.line_adaptive import LineAdaptiveLaw
from pac_controller.parameters import LawParameters
from pac_model.parameters import TrackParameters
from pac_observer.parameters import ObserverParameters

pytestmark = pytest.mark.offline

SPAN = 50.0


def drive(law, speed_seed: int, spans: int, u_max: float, gain_sign: float = 1.0, episode=None):
    """Outputs of ``law`` on a random span-periodic force (plus noise) that follows the command."""
    rng = np.random.default_rng(speed_seed)
    dt = 1e-3
    law.gain *= gain_sign
    n = law.period_ticks
    w = 2 * math.pi / (n * dt)
    amps = rng.uniform(5.0, 60.0, 6)
    phases = rng.uniform(0.0, 2 * math.pi, 6)
    f_r = 150.0
    out = []
    u_applied = f_r
    for k in range(spans * n):
        t = k * dt
        if episode is not None and episode[0] <= k < episode[1]:
            continue  # commands that were not the law's (a fallback episode, a lost estimate)
        if episode is not None and k == episode[1]:
            law.restart(u_applied)
        periodic = sum(
            a * math.cos((j + 1) * w * t + ph) for j, (a, ph) in enumerate(zip(amps, phases, strict=True))
        )
        f_hat = f_r + periodic + 0.7 * (u_applied - f_r) + rng.normal(0.0, 3.0)
        u, errors = law.output(k, t, np.array([f_r, 0.0, 0.0, 0.0]), np.zeros(4), np.zeros(3), f_hat)
        u_cmd = min(u, u_max)
        law.commit(k, u_cmd)
        out.append((u, *errors, law.mode))
        u_applied = u_cmd
    return out


#: Rounding between the compiled law and numpy's: the two sum and multiply in different orders (numpy's
#: pairwise sums and SIMD complex loops, which depend on the CPU; plain loops compiled), so one span's
#: sums differ by ~n eps relative (n = 166-300 ticks a span here), and the learning step, a contraction,
#: carries that into the next spans without growing it. Measured on this suite's cases: at most
#: 1.5e-15 of each column's largest value, also with numpy's SIMD loops narrowed to its x86-64-v2
#: baseline and numba compiling for a generic CPU; the bound leaves four orders of margin. A law that
#: is wrong by little differs by far more (the learning gain 1 % high: 5e-3).
LAW_RTOL = 1e-11


def assert_same_law(got: np.ndarray, want: np.ndarray) -> None:
    """Every column within LAW_RTOL of its largest value in ``want``."""
    scale = np.max(np.abs(want), axis=0) if want.ndim > 1 else np.max(np.abs(want))
    worst = np.max(np.abs(got - want), axis=0) if want.ndim > 1 else np.max(np.abs(got - want))
    assert np.all(worst <= LAW_RTOL * scale), (worst, scale)


@pytest.mark.parametrize("episode", [(4100, 4350), (4321, 4322)])
def test_compiled_law_resumes_after_a_fallback_as_the_numpy_law(episode):
    """A fallback episode mid-run (and a single lost tick): the restart, the tainted span and the
    span closed late as the numpy law does them, bit for bit."""
    track = TrackParameters(speed_kmh=300.0, span_length=SPAN)
    compiled, reference = (
        LineAdaptiveLaw(track, LawParameters(), 1e-3),
        oracle.LineAdaptiveLaw(track, LawParameters(), 1e-3),
    )
    a = drive(compiled, 9, 12, 220.0, episode=episode)
    b = drive(reference, 9, 12, 220.0, episode=episode)
    assert [row[-1] for row in a] == [row[-1] for row in b]
    assert_same_law(np.array([row[:-1] for row in a]), np.array([row[:-1] for row in b]))
    assert_same_law(np.asarray(compiled.u_ff), np.asarray(reference.u_ff))


#: The law on its identified responses alone (no line model).
OWN = {"line_model_below": 0.0}
#: The saturation back-off off: the clipping cases learn to the end (anti-windup compared throughout).
CLIPS = {"line_guard_saturation": 1.0}


@pytest.mark.parametrize(
    "speed, seed, u_max, gain_sign, laws",
    [
        (300.0, 1, math.inf, 1.0, OWN),
        (250.0, 2, 200.0, 1.0, {**OWN, **CLIPS}),  # the limits clip: anti-windup and the mean given back
        (360.0, 3, math.inf, -1.0, OWN),  # forced to harm: the guard trips
        (200.0, 4, 190.0, 1.0, {**OWN, **CLIPS, "line_max_frequency": 60.0, "design_delay_ticks": 2}),  # H>8
        (160.0, 6, math.inf, 1.0, {**OWN, "line_max_frequency": 200.0}),  # H > 128: numpy's sums recurse
        (330.0, 5, math.inf, 1.0, {**OWN, "line_response_min": 0.9, "line_forgetting": 0.3}),  # the floor
        # The line model is fitted every span (drive's force follows the command with one gain at
        # every harmonic, which no pantograph does: the fit finds no line, and stands in for none).
        (300.0, 7, math.inf, 1.0, {}),
        (220.0, 8, 180.0, 1.0, {"line_max_frequency": 60.0}),  # ... with H > 8 and the limits clipping
        # ... and the saturation back-offs, span after span, with no fallback (half of each span clipped)
        (250.0, 2, 175.0, 1.0, OWN),
    ],
)
def test_compiled_law_gives_the_numpy_laws_commands(speed, seed, u_max, gain_sign, laws):
    track = TrackParameters(speed_kmh=speed, span_length=SPAN)
    params = LawParameters(**laws)
    compiled, reference = LineAdaptiveLaw(track, params, 1e-3), oracle.LineAdaptiveLaw(track, params, 1e-3)
    assert compiled.harmonics == reference.harmonics and compiled.period_ticks == reference.period_ticks
    spans = 14
    a = drive(compiled, seed, spans, u_max, gain_sign)
    b = drive(reference, seed, spans, u_max, gain_sign)
    modes = [row[-1] for row in a]
    assert modes == [row[-1] for row in b]
    got, want = np.array([row[:-1] for row in a]), np.array([row[:-1] for row in b])
    assert_same_law(got, want)
    assert_same_law(np.asarray(compiled.u_ff), np.asarray(reference.u_ff))
    if gain_sign < 0:
        assert "passive" in modes  # the case did exercise the guard
    elif u_max < math.inf and "line_guard_saturation" not in laws:
        # it backed off more often than line_guard_strikes, and never fell back on that
        assert compiled.saturation_backoffs == reference.saturation_backoffs
        assert compiled.saturation_backoffs > LawParameters().line_guard_strikes
        assert not compiled.tripped and modes[-1] == "active"
    else:
        assert modes[-1] == "active"


def test_forget_forgets_what_was_learned():
    track = TrackParameters(speed_kmh=300.0, span_length=SPAN)
    law = LineAdaptiveLaw(track, LawParameters(), 1e-3)
    drive(law, 7, 8, math.inf)
    assert np.abs(law.u_ff).max() > 0.0
    law.forget()  # (restart(u) after the law's own commands resumes instead: the tests above)
    fresh = LineAdaptiveLaw(track, LawParameters(), 1e-3)
    np.testing.assert_array_equal(law.memory, fresh.memory)
    for name in law.state.dtype.names:  # the law's memory
        if name.startswith("line_"):
            assert law.state[0][name].tobytes() == fresh.state[0][name].tobytes(), name


def bank_step(xs, energy, selected, y, u, obs):
    """The bank's period as the observer computed it before it was compiled (numpy, loops)."""
    new_xs, new_energy, innovations, best = np.empty_like(xs), np.empty(len(xs)), np.empty((len(xs), 2)), 0
    for f in range(len(xs)):
        phi, gamma, gain, x = obs.phis[f], obs.gammas[f], obs.gains[f], xs[f]
        pred = np.empty(5)
        for i in range(5):
            s = gamma[i] * u
            for j in range(5):
                s += phi[i, j] * x[j]
            pred[i] = s
        nu = np.array([y[0] - pred[0], y[1] - pred[1]])
        new_xs[f] = [pred[i] + gain[i, 0] * nu[0] + gain[i, 1] * nu[1] for i in range(5)]
        innovations[f] = nu
        new_energy[f] = obs.forget * energy[f] + (nu[0] * nu[0] + nu[1] * nu[1]) * obs.inv_r2
        if new_energy[f] < new_energy[best]:
            best = f
    if new_energy[best] < 0.9 * new_energy[selected]:
        selected = best
    return new_xs, new_energy, selected, innovations[selected].copy()


@pytest.mark.parametrize("mass_scale", [1.0, 1.2])
def test_contact_force_observer_matches_the_numpy_bank(mass_scale):
    """The observer's compiled update (gaps included) equals the numpy bank period by period, on
    measurements of a pantograph whose frame mass is off (the bank then switches filters)."""
    from pac_rig.closed_loop import build_cores, run
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat({"observer": "contact_force", "law": "passive", "plant_mass_scale": mass_scale,
                            "duration": 1.0, "noise_std": (1e-6, 1e-6)})  # fmt: skip
    records = list(run(s))
    obs = build_cores(s)[1]
    xs = np.zeros((len(obs.frame_mass_scales), 5))
    xs[:, :4] = ObserverParameters().z_hat0
    energy, selected = np.zeros(len(xs)), obs.nominal
    tick, y_prev, switched = None, None, set()
    for step in range(len(records)):
        gap = 1 if step % 37 else 3
        tick = 0 if tick is None else tick + gap
        if tick >= len(records):
            break
        m = records[tick].measurement
        y, u = np.array([m.z1, m.z2]), m.actuator_force
        est = obs.update(tick, (y[0], y[1]), u)
        if y_prev is None:
            xs[:, 0], xs[:, 1] = y
            innovation = np.zeros(2)
        else:
            for j in range(1, gap + 1):
                y_j = y_prev + (j / gap) * (y - y_prev)
                xs, energy, selected, innovation = bank_step(xs, energy, selected, y_j, u, obs)
        y_prev = y
        switched.add(selected)
        assert obs.selected == selected
        np.testing.assert_array_equal(est.z_hat, xs[selected, :4])
        assert est.contact_force_hat == xs[selected, 4]
        np.testing.assert_array_equal(est.innovation, innovation)
    if mass_scale != 1.0:
        assert len(switched) > 1  # the case did exercise the selection


def test_the_line_model_is_the_pantograph_on_an_impedance_and_its_fit_recovers_the_line():
    """line_model_rows' F/u for a spring line equals an independent solve of eqs. (3)-(4); secant data
    made from a known impedance k_s + i c w give back k_s and c; a line of zero impedance is no model."""
    from numba import njit
    from test_line_response import spring_response

    from pac_controller import line_adaptive_kernels as kern
    from pac_controller.line_adaptive import line_model_rows
    from pac_model.parameters import PantographParameters

    pantograph = PantographParameters()
    omega = 2 * math.pi * np.linspace(1.5, 19.5, 12)
    c, b, det, hold, _ = line_model_rows(pantograph, omega, 1e-3)
    expected = spring_response(pantograph, 5000.0, omega)
    np.testing.assert_allclose(5000.0 * c / (5000.0 * b + det), expected, rtol=1e-12)

    @njit
    def fit(params, states, table, memory):
        kern._fit_line(params[0], states[0], table, memory)

    law = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), LawParameters(), 1e-3)
    n, h = law.period_ticks, law.harmonics
    w = law.table[n + kern.MODEL_OMEGA].real
    prior = law.params[0]["line_prior_weight"]
    for stiffness, damping, valid in ((1500.0, 270.0, True), (0.0, 0.0, False)):
        z = stiffness + 1j * damping * w
        rows = law.table[n + 1 :]
        response = -(z * rows[0] / (z * rows[1] + rows[2])) * rows[3].real  # dE/dU: E = F_r - F_hat
        law.memory[kern.S] = 1e4
        law.memory[kern.Z] = response * (1e4 + prior) + prior
        law.state[0]["line_stiffness"] = law.state[0]["line_damping"] = 0.0
        fit(law.params, law.state, law.table, law.memory)
        assert law.state[0]["line_stiffness"] == pytest.approx(stiffness, rel=1e-9, abs=1e-6)
        assert law.state[0]["line_damping"] == pytest.approx(damping, rel=1e-9, abs=1e-6)
        assert bool(law.state[0]["line_model_valid"]) is valid
        assert h == len(w)


def _fit_case(samples, information, last_fit, model_below=None, learn=False):
    """``_fit_line`` on secant data made from per-harmonic impedance samples ``samples`` (complex,
    one per harmonic; NaN: a harmonic whose response gives no impedance), with information
    ``information`` and the previous fit ``last_fit`` = (k_s, c); returns the law's state after it.
    ``learn``: a whole learning step (``_learn``, its first: no secant update) instead of the fit."""
    from numba import njit

    from pac_controller import line_adaptive_kernels as kern

    @njit
    def fit(params, states, table, memory):
        kern._fit_line(params[0], states[0], table, memory)

    @njit
    def learn_span(params, states, table, memory):
        kern._learn(params[0], states[0], table, memory, 5)

    laws = LawParameters() if model_below is None else LawParameters(line_model_below=model_below)
    law = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), laws, 1e-3)
    n, prior = law.period_ticks, law.params[0]["line_prior_weight"]
    rows = law.table[n + kern.MODEL_C : n + kern.MODEL_OMEGA + 1]
    c, b, det, hold = rows[0], rows[1], rows[2], rows[3].real
    with np.errstate(invalid="ignore"):  # a NaN sample stays NaN
        force = samples * c / (samples * b + det)  # the force's response on each sample's line
    law.memory[kern.S] = information
    law.memory[kern.Z] = -force * hold * (information + prior) + prior
    law.state[0]["line_stiffness"], law.state[0]["line_damping"] = last_fit
    (learn_span if learn else fit)(law.params, law.state, law.table, law.memory)
    return law, (c, b, det, rows[4].real)


@pytest.mark.parametrize("damping", [0.0, 50.0])
def test_the_model_response_is_the_pantograph_on_the_fitted_line_with_the_hold(damping):
    """_model_response with a fitted line Z = k + i c w (a spring, c = 0, and a damped one) equals an
    independent solve of eqs. (3)-(4) on that line, times the hold's gain
    (test_line_response.spring_response, whose k may be complex: Z at each w)."""
    from numba import njit
    from test_line_response import spring_response

    from pac_controller import line_adaptive_kernels as kern
    from pac_model.parameters import PantographParameters

    @njit
    def response(states, table, n, j):
        return kern._model_response(states[0], table, n, j)

    law = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), LawParameters(), 1e-3)
    law.state[0]["line_stiffness"], law.state[0]["line_damping"] = 3000.0, damping
    n = law.period_ticks
    w, hold = law.table[n + kern.MODEL_OMEGA].real, law.table[n + kern.MODEL_HOLD].real
    got = np.array([complex(*response(law.state, law.table, n, j)) for j in range(law.harmonics)])
    panto = PantographParameters()
    line = [spring_response(panto, 3000.0 + 1j * damping * wj, np.array([wj]))[0] for wj in w]
    np.testing.assert_allclose(got, np.array(line) * hold, rtol=1e-10)


def test_a_harmonic_the_line_model_calls_weak_steps_on_the_models_response_the_others_on_their_own():
    """_step with a valid line model (a fitted spring): where the model's response |M_h| is below
    line_model_below the step takes D_h = -M_h (M_h here from an independent solve of eqs. (3)-(4),
    times the hold), elsewhere the harmonic's own identified D_h; the step itself is the module
    docstring's U_h <- A_h - gamma (conj(D_h) E_h + mu A_h) / (|D_h|^2 + mu), written here in numpy
    (no step here reaches the clip, line_step_max)."""
    from numba import njit
    from test_line_response import spring_response

    from pac_controller import line_adaptive_kernels as kern
    from pac_model.parameters import PantographParameters

    @njit
    def step(params, states, table, memory, j):
        kern._step(params[0], states[0], table, memory, j)

    track = TrackParameters(speed_kmh=300.0, span_length=SPAN)
    probe = LineAdaptiveLaw(track, LawParameters(), 1e-3)
    n, h = probe.period_ticks, probe.harmonics
    w, hold = probe.table[n + kern.MODEL_OMEGA].real, probe.table[n + kern.MODEL_HOLD].real
    model = spring_response(PantographParameters(), 3000.0, w) * hold
    # The weaker half of the harmonics under it, the threshold midway to the next: a threshold on one
    # harmonic's own |M_h| would leave it to the last bit of two computations of it (the kernel's and
    # this independent one's), which another CPU's BLAS kernels changed.
    ordered = np.sort(np.abs(model))
    below = float(0.5 * (ordered[h // 2 - 1] + ordered[h // 2]))
    weak = np.abs(model) < below
    assert 0 < weak.sum() < h
    law = LineAdaptiveLaw(track, LawParameters(line_model_below=below, line_step_max=1000.0), 1e-3)
    law.state[0]["line_stiffness"], law.state[0]["line_damping"] = 3000.0, 0.0
    law.state[0]["line_model_valid"] = True
    rng = np.random.default_rng(9)
    own = -1.3 * np.exp(1j * rng.uniform(-1.0, 1.0, h))  # identified dE/dU, off the model's
    prior = law.params[0]["line_prior_weight"]
    law.memory[kern.S] = 1e4
    law.memory[kern.Z] = own * (1e4 + prior) + prior
    errors = 20.0 * np.exp(1j * rng.uniform(-math.pi, math.pi, h))
    applied = 30.0 * np.exp(1j * rng.uniform(-math.pi, math.pi, h))
    law.memory[kern.E_ACC], law.memory[kern.REAL] = errors, applied
    for j in range(h):
        step(law.params, law.state, law.table, law.memory, j)
    d = np.where(weak, -model, own)
    gain, mu = law.params[0]["line_gain"], law.params[0]["line_effort_weight"]
    expected = applied - gain * (np.conj(d) * errors + mu * applied) / (np.abs(d) ** 2 + mu)
    assert np.abs(expected - applied).max() < 1000.0  # no step clipped
    np.testing.assert_allclose(law.memory[kern.U_FF], expected, rtol=1e-10)


def test_a_harmonic_with_any_information_steps_up_to_step_max_one_with_none_probes():
    """The step's clip: line_probe_step for a harmonic never identified (S_h = 0), line_step_max
    once it has any information (here S_h = 0.5 N^2, one informative update of 0.7 N)."""
    from numba import njit

    from pac_controller import line_adaptive_kernels as kern

    @njit
    def step(params, states, table, memory, j):
        kern._step(params[0], states[0], table, memory, j)

    laws = LawParameters(line_model_below=0.0, line_probe_step=5.0, line_step_max=50.0)
    law = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), laws, 1e-3)
    prior = law.params[0]["line_prior_weight"]
    information = np.array([0.0, 0.5])
    law.memory[kern.S, :2] = information
    law.memory[kern.Z, :2] = -1.0 * (information + prior) + prior  # D_h = -1 for both
    law.memory[kern.E_ACC, :2], law.memory[kern.REAL, :2] = 40.0, 0.0
    for j in range(2):
        step(law.params, law.state, law.table, law.memory, j)
    gain, mu = law.params[0]["line_gain"], law.params[0]["line_effort_weight"]
    free = gain * 40.0 / (1.0 + mu)  # |-gamma conj(D) E / (|D|^2 + mu)| with D = -1, A = 0
    assert 5.0 < free < 50.0
    assert abs(law.memory[kern.U_FF, 0]) == pytest.approx(5.0, rel=1e-12)
    assert abs(law.memory[kern.U_FF, 1]) == pytest.approx(free, rel=1e-12)


#: The previous fit the cases below start from (k_s [N/m], c [N s/m]).
LAST_FIT = (1200.0, 300.0)


def _disagreeing_samples(seed: int):
    """Per-harmonic impedance samples that disagree (each harmonic its own line, k_s and c drawn
    about 1500 N/m and 270 N s/m), their information (1e2..1e5) and the model's rows (C, B, det, w)."""
    rng = np.random.default_rng(seed)
    h = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), LawParameters(), 1e-3).harmonics
    _, rows = _fit_case(np.full(h, 1000.0 + 0j), np.ones(h), (0.0, 0.0))
    w = rows[3]
    samples = (1500.0 + 600.0 * rng.standard_normal(h)) + 1j * w * (270.0 + 120.0 * rng.standard_normal(h))
    return samples, 10.0 ** rng.uniform(2.0, 5.0, h), rows


def test_the_line_fit_weighs_each_harmonic_by_its_information_and_its_sensitivity_to_the_line():
    """Samples that disagree (each harmonic its own impedance): the fit is the weighted least-squares
    line Z = k_s + i c w, each harmonic weighted by its information S_h times |dD/dZ|^2 at the last
    fit, dD/dZ taken here by a central difference of D(Z) = Z C / (Z B + det) (module docstring)."""
    samples, information, (c, b, det, w) = _disagreeing_samples(5)
    h, last = samples.size, LAST_FIT
    law, _ = _fit_case(samples, information, last)

    def response(z):
        return z * c / (z * b + det)

    z_last = last[0] + 1j * last[1] * w
    step = 1e-4 * np.abs(z_last)
    slope = (response(z_last + step) - response(z_last - step)) / (2 * step)
    weight = information * np.abs(slope) ** 2
    # Weighted least squares, as a linear system: rows sqrt(w) [1, 0; 0, w] (k_s, c) = sqrt(w) (Re, Im).
    a = np.zeros((2 * h, 2))
    a[:h, 0], a[h:, 1] = np.sqrt(weight), np.sqrt(weight) * w
    rhs = np.concatenate([np.sqrt(weight) * samples.real, np.sqrt(weight) * samples.imag])
    (k_s, damping), *_ = np.linalg.lstsq(a, rhs, rcond=None)
    # The central difference's error is O(step^2) relative (1e-8 here), far below rel 1e-6.
    assert law.state[0]["line_stiffness"] == pytest.approx(k_s, rel=1e-6)
    assert law.state[0]["line_damping"] == pytest.approx(damping, rel=1e-6)
    unweighted = np.mean(samples.real)
    assert abs(k_s - unweighted) > 20.0  # the weighting matters in this case


def test_a_harmonic_without_an_impedance_drops_out_of_the_fit_and_none_keeps_the_last_fit():
    """A harmonic whose sample is not finite weighs nothing (the fit is that of the others); when
    no harmonic gives one the fit keeps its last values."""
    samples, information, _ = _disagreeing_samples(6)
    h, last = samples.size, LAST_FIT
    broken = samples.copy()
    broken[2] = complex(math.nan, 0.0)
    law, _ = _fit_case(broken, information, last)
    without = information.copy()
    without[2] = 0.0
    reference, _ = _fit_case(samples, without, last)
    for name in ("line_stiffness", "line_damping"):
        assert math.isfinite(law.state[0][name])
        assert law.state[0][name] == pytest.approx(reference.state[0][name], rel=1e-12)
    with_all, _ = _fit_case(samples, information, last)
    assert abs(law.state[0]["line_stiffness"] - with_all.state[0]["line_stiffness"]) > 1.0  # it did weigh
    none, _ = _fit_case(np.full(h, complex(math.nan, 0.0)), information, last)
    assert (none.state[0]["line_stiffness"], none.state[0]["line_damping"]) == last


def test_every_learning_step_fits_the_line_model_unless_there_is_none():
    """_learn fits the line model to the identified responses when line_model_below > 0 (here a
    spring-and-damper line it recovers); with 0 there is no model and the fit is not made."""
    _, _, (_, _, _, w) = _disagreeing_samples(0)  # the harmonics' frequencies
    line = 1500.0 + 1j * 270.0 * w
    for below, want in ((0.1, (1500.0, 270.0)), (1.0, (1500.0, 270.0)), (0.0, (0.0, 0.0))):
        law, _ = _fit_case(line, np.full(w.size, 1e4), (0.0, 0.0), below, learn=True)
        got = (law.state[0]["line_stiffness"], law.state[0]["line_damping"])
        assert got == pytest.approx(want, rel=1e-9, abs=1e-9), below


def test_the_line_model_is_valid_when_its_first_harmonic_is_not_weak():
    """line_model_valid judges the first harmonic's response on the fitted model: a limit between
    the first and the second harmonic's |M| gives valid or not as the first one's side says."""
    from pac_controller import line_adaptive_kernels as kern

    h = LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), LawParameters(), 1e-3).harmonics
    _, (c, b, det, w) = _fit_case(np.full(h, 1000.0 + 0j), np.ones(h), (0.0, 0.0))
    samples, information = 1500.0 + 1j * 270.0 * w, np.full(h, 1e4)
    law, _ = _fit_case(samples, information, (0.0, 0.0))
    z = law.state[0]["line_stiffness"] + 1j * law.state[0]["line_damping"] * w
    m = np.abs(z * c / (z * b + det) * law.table[law.period_ticks + kern.MODEL_HOLD].real)
    assert abs(m[0] - m[1]) > 1e-3 * m[0]
    between = 0.5 * (m[0] + m[1])
    judged, _ = _fit_case(samples, information, (0.0, 0.0), between)
    assert bool(judged.state[0]["line_model_valid"]) is bool(m[0] >= between)
