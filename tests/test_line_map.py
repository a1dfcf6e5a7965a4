"""line_adaptive on a map learned on an earlier pass (pac_controller.line_map): each span of the
design layout starts from its own harmonics, the responses frozen at the map's, and the pass
records what the next map needs; a bad map file is one line, before anything runs.

The law is driven here through its class with an imposed estimate (an open loop), on a layout
whose spans are exactly N ticks long, so every expected number is computed in the test from the
map and the law's equations (docs/laws.md), not read from the law."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pac_controller.line_adaptive import LineAdaptiveLaw
from pac_controller.line_map import LineMap, LineMapError, read_line_map, write_line_map
from pac_controller.parameters import LawParameters
from pac_model.parameters import TrackParameters

DT = 1e-3
SPEED = 100.0  # m/s: 0.1 m per tick
SPAN = 50.0  # m: N = 500 ticks per span, every span of the layout
N = 500
SUPPORTS = tuple(SPAN * np.arange(7))  # six spans
F_R = 150.0
PRIOR = 25.0  # line_prior_weight's default
RESPONSE = -0.8  # D_h of every harmonic in the map
INFORMATION = 100.0  # S_h


def _map(harmonics: int, rng: np.random.Generator, supports=SUPPORTS, u_mean: float = 2.0) -> LineMap:
    shape = (len(supports) - 1, harmonics)
    w = 10.0 * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    w[0] = 0.0  # as a pass writes it: span 0 (the start's transient) is never learned from
    z = RESPONSE * (INFORMATION + PRIOR) + PRIOR  # D = (Z - s0) / (S + s0)
    return LineMap(
        supports=np.asarray(supports, dtype=float), period_ticks=N, harmonics=w,
        response_z=np.full(harmonics, z + 0j), response_s=np.full(harmonics, INFORMATION),
        passive_sigma=100.0, passive_loss=0.0, line_stiffness=0.0, line_damping=0.0, model_valid=False,
        u_mean=u_mean, passes=1,
    )  # fmt: skip


def _law(path: str | Path = "", supports=SUPPORTS, overlaps: tuple[float, ...] = (0.0,)) -> LineAdaptiveLaw:
    # x = 0.05 + 0.1 k: half a tick past each support, so span m is ticks 500 m .. 500 m + 499 and the
    # phase index is k mod 500 exactly (no position lands on a support).
    laws = LawParameters(
        line_supports=supports,
        line_position_start=0.05,
        design_delay_ticks=0,
        line_map=str(path),
        line_overlaps=overlaps,
    )
    return LineAdaptiveLaw(TrackParameters(speed_kmh=3.6 * SPEED, span_length=SPAN), laws, DT)


def _harmonics() -> int:
    return _law().harmonics


def _feedforward(w: np.ndarray, tick: int) -> float:
    """Re sum_h W_h exp(i h w_s (p + 1/2) dt), p = tick mod N: the module docstring's feedforward
    with no delay (the hold's half period ahead)."""
    h = np.arange(1, w.size + 1)
    return float(np.real(np.sum(w * np.exp(1j * h * 2.0 * math.pi * ((tick % N) + 0.5) / N))))


@pytest.mark.unit
def test_a_pass_on_a_map_starts_every_span_from_its_own_harmonics(tmp_path):
    """With the estimate on the target (no error), the command in span m is F_r + U_0 + span m's
    harmonics of the map, from the first span on (no passive run-in), to rounding."""
    learned = _map(_harmonics(), np.random.default_rng(1))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json")
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    for k in range(6 * N - 1):
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R)
        law.commit(k, u)
        expected = F_R + learned.u_mean + _feedforward(learned.harmonics[k // N], k)
        assert u == pytest.approx(expected, rel=0, abs=1e-9), k
    assert not law.tripped


@pytest.mark.unit
def test_a_pass_on_a_map_learns_the_mean_from_span_1_on_and_gives_back_what_the_limits_took(tmp_path):
    """On a map the mean is learned as on a first pass: an estimate 3 N under F_r in every tick adds
    gamma 3 N to U_0 at the end of each span from span 1 on (span 0 holds the start's transient);
    and what the limits took off span 0's commands (2 N each tick) is given back from span 1 on
    (C = -mean of what was taken)."""
    learned = _map(_harmonics(), np.random.default_rng(3))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json")
    gamma, f_r = LawParameters().line_learning_gain, np.array([F_R, 0.0, 0.0, 0.0])
    means, offsets = [], []
    for k in range(4 * N):
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R - 3.0)
        law.commit(k, u - 2.0 if k < N else u)
        if k % N == N - 1:  # the span's last tick: it has just ended
            means.append(float(law.state[0]["line_u_mean"]))
            offsets.append(float(law.state[0]["line_clip_offset"]))
    expected = [learned.u_mean + 3.0 * gamma * m for m in range(4)]
    np.testing.assert_allclose(means, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(offsets, [2.0, 0.0, 0.0, 0.0], rtol=0, atol=1e-9)
    assert not law.tripped


@pytest.mark.unit
def test_a_pass_on_a_map_that_backs_off_runs_every_later_span_on_its_own_harmonics_halved(tmp_path):
    """A learning span whose commands the limits all changed (2 N taken off each) backs off: the span
    after it ramps down, and from the one after that on every span runs its own harmonics of the map
    at the back-off's scale (0.5, docs/laws.md), not another span's. On a map the guard judges from
    span 2 on, so span 2 strikes, span 3 ramps, spans 4 and 5 run on 0.5 W_4 and 0.5 W_5. The
    estimate is on the target (no error), so what oscillates about each span's mean command is the
    feedforward alone."""
    learned = _map(_harmonics(), np.random.default_rng(5))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json")
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    commands = np.empty(6 * N - 1)
    for k in range(commands.size):
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R)
        law.commit(k, u - 2.0 if k // N == 2 else u)
        commands[k] = u
    assert not law.tripped
    assert float(law.state[0]["line_map_scale"]) == 0.5
    for m, ticks in ((4, range(4 * N, 5 * N)), (5, range(5 * N, 6 * N - 1))):
        u = commands[list(ticks)]
        ff = np.array([0.5 * _feedforward(learned.harmonics[m], k) for k in ticks])
        # what is left of the command once the feedforward is taken off is one constant (F_r, U_0
        # and what the limits took, given back) over the whole span
        rest = u - ff
        np.testing.assert_allclose(rest, np.full(u.size, rest.mean()), rtol=0, atol=1e-9, err_msg=f"span {m}")


@pytest.mark.unit
def test_the_next_map_is_the_laws_step_on_each_spans_own_error(tmp_path):
    """An error of 10 N on harmonic 2 in every span (imposed): each span the pass recorded takes
    W_m - gamma (conj(D) E_m + mu W_m) / (|D|^2 + mu) with the map's D; span 0 (the start) and the
    span the run ended in were not recorded and keep the map's harmonics."""
    h = _harmonics()
    learned = _map(h, np.random.default_rng(2))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json")
    laws = LawParameters()
    gamma, mu, a, h0 = laws.line_learning_gain, laws.line_effort_weight, 10.0, 2
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    for k in range(6 * N - 1):
        error = a * math.cos(h0 * 2.0 * math.pi * (k % N) / N)
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R - error)
        law.commit(k, u)
    following = law.next_map()
    e = np.zeros(h, dtype=complex)
    e[h0 - 1] = a
    for m in range(6):
        w = learned.harmonics[m]
        if m in (0, 5):
            expected = w
        else:
            expected = w - gamma * (np.conj(RESPONSE) * e + mu * w) / (RESPONSE**2 + mu)
        np.testing.assert_allclose(following.harmonics[m], expected, rtol=0, atol=1e-9)
    assert following.passes == 2
    np.testing.assert_allclose(following.response_z, learned.response_z, rtol=0, atol=0)  # frozen


#: Two tension sections overlapping over spans 2 and 3 (100..200 m): spans 1 to 4 are the overlap's
#: and those beside it, where a first pass fades its harmonics out and learns nothing.
OVERLAP = (100.0, 200.0)


@pytest.mark.unit
def test_a_pass_on_a_map_runs_an_overlaps_spans_on_their_own_harmonics(tmp_path):
    """On a map each span of an overlap and beside it runs its own harmonics of the map (learned
    there on an earlier pass), not the first pass's window of 0; over the overlap (spans 2 and 3)
    their positive part only: they raise the command, never lower it."""
    learned = _map(_harmonics(), np.random.default_rng(7))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json", overlaps=OVERLAP)
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    lowered: dict[int, bool] = {}
    for k in range(6 * N - 1):
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R)
        law.commit(k, u)
        ff = _feedforward(learned.harmonics[k // N], k)
        expected = F_R + learned.u_mean + (max(ff, 0.0) if k // N in (2, 3) else ff)
        assert u == pytest.approx(expected, rel=0, abs=1e-9), k
        lowered[k // N] = lowered.get(k // N, False) or ff < -1.0
    assert all(lowered[m] for m in range(1, 6))  # the map would lower the command in spans 1-5 (0: W = 0)
    assert not law.tripped


def _run_with_error(law: LineAdaptiveLaw, amplitude: float, harmonic: int, spans: int = 6) -> None:
    """``spans`` spans (the last one not closed) with F_hat = F_r - amplitude cos(harmonic phase)."""
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    for k in range(spans * N - 1):
        error = amplitude * math.cos(harmonic * 2.0 * math.pi * (k % N) / N)
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R - error)
        law.commit(k, u)


@pytest.mark.unit
def test_a_pass_on_a_map_records_an_overlaps_spans_for_the_next_map(tmp_path):
    """The spans of an overlap and beside it teach a pass nothing within the pass, but it records
    them: the next map takes the law's step on each one's own error there, as on any other span
    (an error of 10 N on harmonic 2, imposed), A_m - gamma (conj(D) E_m + mu A_m) / (|D|^2 + mu)
    from what it applied, A_m: W_m beside the overlap, over it the harmonics of W_m's positive part
    (computed here from the commands' formula by a discrete Fourier sum)."""
    h = _harmonics()
    learned = _map(h, np.random.default_rng(4))
    write_line_map(learned, tmp_path / "map.json")
    law = _law(tmp_path / "map.json", overlaps=OVERLAP)
    laws = LawParameters()
    gamma, mu, a, h0 = laws.line_learning_gain, laws.line_effort_weight, 10.0, 2
    _run_with_error(law, a, h0)
    following = law.next_map()
    e = np.zeros(h, dtype=complex)
    e[h0 - 1] = a
    phase = 2.0 * math.pi * (np.arange(N) + 0.5) / N
    for m in (1, 2, 3, 4):
        w = learned.harmonics[m]
        if m in (2, 3):  # over the overlap it applied the positive part of its harmonics: theirs
            ff = np.maximum([_feedforward(w, k) for k in range(N)], 0.0)
            w = np.array([2.0 / N * np.sum(ff * np.exp(-1j * j * phase)) for j in range(1, h + 1)])
        expected = w - gamma * (np.conj(RESPONSE) * e + mu * w) / (RESPONSE**2 + mu)
        np.testing.assert_allclose(following.harmonics[m], expected, rtol=0, atol=1e-9, err_msg=f"span {m}")
    assert not law.tripped


@pytest.mark.unit
def test_a_first_pass_records_an_overlaps_spans_for_the_next_map():
    """Nine spans, an overlap over spans 5 and 6 (after the run-in's passive spans 1 and 2): a first
    pass runs spans 4 to 7 without learning from them, yet records each: the map it writes steps
    there on the error seen (not 0, the map a first pass is given); span 0 (the start) and span 8
    (not closed) are not recorded and stay 0."""
    law = _law(supports=tuple(SPAN * np.arange(10)), overlaps=(250.0, 350.0))
    _run_with_error(law, 10.0, 2, spans=9)
    following = law.next_map()
    for m in (4, 5, 6, 7):
        assert np.abs(following.harmonics[m]).max() > 1.0, m
    assert np.abs(following.harmonics[[0, 8]]).max() == 0.0


@pytest.mark.unit
def test_a_first_pass_writes_a_map_that_reads_back_the_same(tmp_path):
    """A first pass (no map) records every span after the start; its map reads back equal, and a law
    given it takes it (the responses, the passive bar, U_0)."""
    law = _law()
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    for k in range(6 * N - 1):
        error = 10.0 * math.cos(2.0 * math.pi * (k % N) / N)
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R - error)
        law.commit(k, u)
    first = law.next_map()
    assert first.passes == 1
    assert np.all(first.harmonics[0] == 0) and np.all(first.harmonics[1:5] != 0)
    assert first.passive_sigma == pytest.approx(10.0 / math.sqrt(2.0), rel=1e-9)  # sigma_b of a 10 N cosine
    write_line_map(first, tmp_path / "first.json")
    back = read_line_map(tmp_path / "first.json")
    for field in ("supports", "harmonics", "response_z", "response_s"):
        np.testing.assert_array_equal(getattr(back, field), getattr(first, field))
    assert back.as_json() == first.as_json()
    follower = _law(tmp_path / "first.json")
    p = follower.params[0]
    assert p["line_map"] and p["line_map_passive_var"] == pytest.approx(first.passive_sigma**2, rel=1e-15)
    assert follower.map_passes == 1


def _valid(tmp_path: Path) -> dict:
    write_line_map(_map(_harmonics(), np.random.default_rng(3)), tmp_path / "ok.json")
    return json.loads((tmp_path / "ok.json").read_text())


@pytest.mark.unit
@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda d: d.update(format="something else"), "format"),
        (lambda d: d.update(supports=[0.0, 50.0, 40.0]), "supports"),
        (lambda d: d["harmonics"][1][0].__setitem__(0, float("nan")), "harmonics"),
        (lambda d: d["harmonics"].pop(), "harmonics"),
        (lambda d: d.update(period_ticks=1.5), "period_ticks"),
        (lambda d: d.update(passive_sigma=-1.0), "passive_sigma"),
        (lambda d: d.update(passive_sigma=0.0), "passive_sigma"),  # a guard that never judges
        (lambda d: d.update(response_s=[1.0]), "response_s"),
        (lambda d: d.update(model_valid="yes"), "model_valid"),
        (lambda d: d.update(passes=0), "passes"),
    ],
)
def test_a_bad_map_file_is_refused_in_one_line_naming_its_key(tmp_path, change, key):
    raw = _valid(tmp_path)
    change(raw)
    (tmp_path / "bad.json").write_text(json.dumps(raw))
    with pytest.raises(LineMapError) as info:
        _law(tmp_path / "bad.json")
    text = str(info.value)
    assert "\n" not in text and f"'{key}'" in text and "bad.json" in text, text


@pytest.mark.unit
def test_a_missing_or_unreadable_map_is_one_line(tmp_path):
    for path, content in ((tmp_path / "none.json", None), (tmp_path / "half.json", '{"format": "pac')):
        if content is not None:
            path.write_text(content)
        with pytest.raises(LineMapError) as info:
            _law(path)
        assert "\n" not in str(info.value) and path.name in str(info.value)


@pytest.mark.unit
def test_a_map_of_another_line_or_speed_is_refused(tmp_path):
    """A map is for the layout, N and H it was learned at: another layout, another speed (N) refused."""
    write_line_map(_map(_harmonics(), np.random.default_rng(4)), tmp_path / "map.json")
    with pytest.raises(LineMapError, match="supports"):
        _law(tmp_path / "map.json", supports=tuple(SPAN * np.arange(8)))
    other = LawParameters(
        line_supports=SUPPORTS, line_position_start=0.05, line_map=str(tmp_path / "map.json")
    )
    with pytest.raises(LineMapError, match="ticks per span"):
        LineAdaptiveLaw(TrackParameters(speed_kmh=300.0, span_length=SPAN), other, DT)
