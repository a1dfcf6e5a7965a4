"""The pantograph as data: the file format and its refusals, the presets bit for bit against the
built-in chains, and per preset checks that fail on wrong physics: the static equilibrium against
hand algebra and the natural frequencies against closed forms written from the published values
(not from the model), with mutation checks (a mass or a stiffness moved by 10 % must fail them)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import simulate_refusal
from scipy.linalg import eigh

from pac_common.parameters import ParameterError
from pac_model.pantograph_file import (
    PantographFile,
    PantographFileError,
    load_pantograph_file,
    parse_pantograph,
    presets,
    table1_file,
)
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_plant.catenary.pantographs import (
    LumpedPantograph,
    head_first,
    load_pantograph,
    lumped,
    paper_pantograph,
    three_mass_pantograph,
)

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "pantographs" / "paper_2dof.yaml"
THREE = ROOT / "config" / "pantographs" / "three_mass.yaml"

#: The published values, written here from the sources (not read from the files): Table 1 of the
#: paper; docs/catenary_data.md section 2 (the 3-mass, roof -> frame -> upper frame -> head).
TABLE1 = {"m1": 8.0, "k1": 10000.0, "b1": 120.0, "m2": 12.0, "b2": 30.0}
THREE_MASS = {"masses": (6.0, 9.0, 7.5), "springs": (160.0, 15500.0, 7000.0), "roof_damper": 100.0}


# -- presets ------------------------------------------------------------------------------------------
@pytest.mark.unit
def test_the_presets_are_shipped_and_name_their_sources():
    assert {"paper_2dof", "three_mass"} <= set(presets())
    for name in presets():
        f = load_pantograph_file(name)
        assert f.name == name and len(f.source) > 80


@pytest.mark.unit
def test_the_presets_are_the_built_in_chains_bit_for_bit():
    for from_file, built_in in (
        (load_pantograph("paper_2dof")[0], paper_pantograph()),
        (load_pantograph("three_mass")[0], three_mass_pantograph()),
    ):
        for field in ("mass", "stiffness", "damping", "ground_stiffness"):
            a, b = getattr(from_file, field), getattr(built_in, field)
            assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), field
        assert (from_file.head, from_file.input) == (built_in.head, built_in.input)
    assert PantographParameters(**load_pantograph_file("paper_2dof").table1()) == PantographParameters()


@pytest.mark.unit
def test_the_reference_runs_uplift_is_the_en50367_target_bit_for_bit():
    from pac_common.contact_statistics import target_mean_force

    chain = load_pantograph_file("three_mass")
    for v in (0, 160, 250, 300, 320, 360, 250.0, 287.5):
        assert chain.uplift(v) == target_mean_force(v)  # exactly: the reference runs are unchanged
    paper = load_pantograph_file("paper_2dof")
    assert paper.uplift(300) == 0.0  # the paper's actuator gives the whole uplift


# -- static equilibrium against hand algebra ---------------------------------------------------------
@pytest.mark.unit
@pytest.mark.parametrize("name", ["paper_2dof", "three_mass"])
def test_static_equilibrium_is_the_hand_solution_of_the_published_chain(name):
    """Head held at h, the uplift F on the actuator's mass, the roof spring relaxed at that state:
    the series springs between the actuator's mass and the head each carry F, so each mass sits
    F / k above the next one towards the head, and the head is pressed by F."""
    chain, file = load_pantograph(name)
    h, force = 0.012, file.uplift(300.0) or 157.3
    z = chain.static_positions(h, force)
    if name == "paper_2dof":
        hand = {0: h, 1: h + force / TABLE1["k1"]}  # the frame F / k1 above the head
    else:
        _, k12, k23 = THREE_MASS["springs"]
        upper = h + force / k23
        hand = {2: h, 1: upper, 0: upper + force / k12}
    for dof, value in hand.items():
        assert z[dof] == pytest.approx(value, rel=1e-12, abs=1e-15)
    # The head's reaction: what the spring above it pushes with equals the uplift (Newton on the head).
    k = chain.stiffness
    assert -(k[chain.head] @ z) == pytest.approx(force, rel=1e-12)


# -- natural frequencies against closed forms ---------------------------------------------------------
def model_frequencies(chain: LumpedPantograph, head_fixed: bool) -> np.ndarray:
    """Undamped natural frequencies [Hz] of the model's matrices (roof springs included)."""
    k = chain.stiffness + np.diag(chain.ground_stiffness)
    m = np.diag(chain.mass)
    keep = [i for i in range(chain.n) if not (head_fixed and i == chain.head)]
    lam = eigh(k[np.ix_(keep, keep)], m[np.ix_(keep, keep)], eigvals_only=True)
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi)


def paper_closed_form() -> dict[str, np.ndarray]:
    """The 2-DOF of Table 1: free, a rigid mode and the two-body mode w^2 = k1 (1/m1 + 1/m2); head
    fixed, the frame on k1 alone, w^2 = k1 / m2 (no spring to the body)."""
    m1, m2, k1 = TABLE1["m1"], TABLE1["m2"], TABLE1["k1"]
    two_pi = 2 * math.pi
    return {
        "free": np.array([0.0, math.sqrt(k1 * (1 / m1 + 1 / m2)) / two_pi]),
        "fixed": np.array([math.sqrt(k1 / m2) / two_pi]),
    }


def chain_polynomial_roots(masses: tuple[float, ...], springs: tuple[float, ...]) -> np.ndarray:
    """Frequencies [Hz] of the chain roof -k0- m0 -k1- m1 -k2- ... (one more spring than masses: the
    last one ties the last mass to a fixed head) from its characteristic polynomial in l = w^2,
    built by the continuant (three-term) recurrence of a tridiagonal determinant,
    p_i(l) = (k_i + k_i+1 - l m_i) p_i-1 - k_i^2 p_i-2: a formulation independent of the model's
    matrix assembly."""
    p_prev, p = np.poly1d([1.0]), np.poly1d([1.0])
    for i, m in enumerate(masses):
        diagonal = springs[i] + (springs[i + 1] if i + 1 < len(springs) else 0.0)
        coupling = springs[i] ** 2 if i > 0 else 0.0
        p_prev, p = p, np.poly1d([-m, diagonal]) * p - coupling * p_prev
    lam = np.sort(np.real(p.r))
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi)


def three_mass_closed_form() -> dict[str, np.ndarray]:
    masses, springs = THREE_MASS["masses"], THREE_MASS["springs"]
    return {
        # head fixed: frame and upper frame between the roof spring and the spring to the head
        "fixed": chain_polynomial_roots(masses[:2], springs),
        # free: all three masses, the roof spring the only tie to ground
        "free": chain_polynomial_roots(masses, springs),
    }


def check_frequencies(name: str, chain: LumpedPantograph) -> None:
    reference = paper_closed_form() if name == "paper_2dof" else three_mass_closed_form()
    for case, expected in reference.items():
        got = model_frequencies(chain, head_fixed=case == "fixed")
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9, err_msg=f"{name} {case}")


@pytest.mark.unit
@pytest.mark.parametrize("name", ["paper_2dof", "three_mass"])
def test_natural_frequencies_are_the_closed_form_of_the_published_values(name):
    chain, _ = load_pantograph(name)
    check_frequencies(name, chain)
    check_frequencies(name, head_first(chain))  # the FE plant's DOF order: the same chain


@pytest.mark.unit
def test_the_closed_forms_give_the_numbers_a_reader_can_check_by_hand():
    # Table 1: sqrt(10000 (1/8 + 1/12)) / 2 pi = 7.26 Hz; head fixed sqrt(10000 / 12) / 2 pi = 4.59 Hz.
    assert paper_closed_form()["free"][1] == pytest.approx(7.264, abs=1e-3)
    assert paper_closed_form()["fixed"][0] == pytest.approx(4.594, abs=1e-3)
    # 3-mass, head fixed: roof spring + frame + upper frame; its determinant by hand, l = w^2:
    # (15660 - 6 l)(22500 - 9 l) - 15500^2 = 0
    a, b, c = 54.0, -(6 * 22500 + 9 * 15660), 15660 * 22500 - 15500**2
    lam = np.sort(np.roots([a, b, c]))
    np.testing.assert_allclose(three_mass_closed_form()["fixed"], np.sqrt(lam) / (2 * math.pi), rtol=1e-12)


def mutated(path: Path, old: str, new: str, tmp_path: Path) -> LumpedPantograph:
    text = path.read_text()
    assert old in text
    out = tmp_path / path.name
    out.write_text(text.replace(old, new, 1))
    return load_pantograph(str(out))[0]


MUTATIONS = [
    (PAPER, "mass: 8.0", "mass: 8.8"),
    (PAPER, "mass: 12.0", "mass: 13.2"),
    (PAPER, "stiffness: 10000.0", "stiffness: 11000.0"),
    (THREE, "mass: 6.0", "mass: 6.6"),
    (THREE, "mass: 9.0", "mass: 9.9"),
    (THREE, "mass: 7.5", "mass: 8.25"),
    (THREE, "stiffness: 160.0", "stiffness: 176.0"),
    (THREE, "stiffness: 15500.0", "stiffness: 17050.0"),
    (THREE, "stiffness: 7000.0", "stiffness: 7700.0"),
]


@pytest.mark.unit
@pytest.mark.parametrize("path,old,new", MUTATIONS, ids=[f"{p.stem}:{o}" for p, o, _ in MUTATIONS])
def test_a_mass_or_stiffness_moved_by_ten_percent_fails_the_frequency_check(path, old, new, tmp_path):
    chain = mutated(path, old, new, tmp_path)
    with pytest.raises(AssertionError):
        check_frequencies(path.stem, chain)


@pytest.mark.unit
def test_a_stiffness_moved_by_ten_percent_fails_the_static_check(tmp_path):
    chain = mutated(THREE, "stiffness: 7000.0", "stiffness: 7700.0", tmp_path)
    z = chain.static_positions(0.0, 100.0)
    assert z[1] != pytest.approx(100.0 / THREE_MASS["springs"][2], rel=1e-3)


# -- the paper's shape: who can use which chain --------------------------------------------------------
@pytest.mark.unit
def test_the_nominal_pantograph_must_have_the_papers_shape_refused_in_one_line():
    p = PantographParameters(nominal_pantograph="paper_2dof")
    assert (p.m1, p.b1, p.k1, p.m2, p.b2) == (8.0, 120.0, 10000.0, 12.0, 30.0)
    with pytest.raises(ParameterError) as err:
        PantographParameters(nominal_pantograph="three_mass")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith("invalid parameter 'nominal_pantograph'")
    assert "the paper's 2-DOF chain (2 masses; this one has 3)" in message
    with pytest.raises(ParameterError, match=r"'m1' = 9.0: allowed 8 or unset"):
        PantographParameters(nominal_pantograph="paper_2dof", m1=9.0)


@pytest.mark.unit
def test_a_file_of_the_papers_shape_with_other_values_reaches_observer_and_controller(tmp_path):
    heavy = tmp_path / "heavy.yaml"
    heavy.write_text(PAPER.read_text().replace("mass: 12.0", "mass: 15.0"))
    p = PantographParameters(nominal_pantograph=str(heavy))
    assert p.m2 == 15.0 and p.m1 == 8.0
    assert PantographParameters(nominal_pantograph=str(heavy), m2=15.0).m2 == 15.0


@pytest.mark.unit
def test_the_contact_force_observer_takes_a_nominal_pantograph_file(tmp_path):
    """observer:=contact_force with a nominal_pantograph: its filter bank is the file's 2-DOF with the
    bank's frame masses, the same bank as for the file's numbers given one by one (each member used
    to re-check its m2 against the file, so every file was refused: "'m2' = 8.4: allowed 12")."""
    from pac_observer.contact_force import ContactForceObserver
    from pac_observer.parameters import ObserverParameters

    heavy = tmp_path / "heavy.yaml"
    heavy.write_text(PAPER.read_text().replace("mass: 12.0", "mass: 15.0"))
    params = ObserverParameters(observer="contact_force")
    for named, plain in (("paper_2dof", PantographParameters()), (str(heavy), PantographParameters(m2=15.0))):
        got = ContactForceObserver(
            PantographParameters(nominal_pantograph=named), TrackParameters(), params, 1e-3
        )
        want = ContactForceObserver(plain, TrackParameters(), params, 1e-3)
        assert len(got.frame_mass_scales) > 1  # a bank, not the single filter
        for a, b in zip(got.bank, want.bank, strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.unit
def test_the_lumped_plant_refuses_a_chain_it_cannot_simulate_and_runs_one_it_can():
    from pac_plant.parameters import PlantOptions
    from pac_plant.plant import Plant

    with pytest.raises(ParameterError, match=r"'pantograph' = .*three_mass.yaml': allowed the paper's 2-DOF"):
        Plant(
            PantographParameters(),
            TrackParameters(),
            CatenaryParameters(),
            PlantOptions(pantograph="three_mass"),
            1e-3,
        )
    plant = Plant(
        PantographParameters(),
        TrackParameters(),
        CatenaryParameters(),
        PlantOptions(pantograph="paper_2dof"),
        1e-3,
    )
    assert plant.pantograph == PantographParameters() and plant.uplift == 0.0


@pytest.mark.unit
def test_wind_and_file_uplift_act_with_u_on_the_actuator_mass():
    from pac_plant.parameters import PlantOptions
    from pac_plant.plant import Plant

    args = (PantographParameters(), TrackParameters(), CatenaryParameters())
    windy = Plant(*args, PlantOptions(wind_uplift=25.0), 1e-3)
    calm = Plant(*args, PlantOptions(), 1e-3)
    for _ in range(50):
        windy.advance(100.0)
        calm.advance(125.0)
    assert np.array_equal(windy.z, calm.z)
    assert windy.truth().u_applied == 100.0  # the actuator's force, not the wind's


def table1_chain(path: Path) -> PantographFile:
    return parse_pantograph(path.read_text(), str(path))


@pytest.mark.unit
def test_the_table1_chain_of_parameters_is_the_preset():
    a, b = table1_file(PantographParameters()), table1_chain(PAPER)
    fields = ("mass_names", "masses", "springs", "dampers", "head", "actuator", "static_uplift")
    assert all(getattr(a, f) == getattr(b, f) for f in fields)
    assert np.array_equal(lumped(a).damping, lumped(b).damping)


# -- bad files ----------------------------------------------------------------------------------------
GOOD = THREE.read_text()
BAD = [
    ("name: three_mass", "name: ''", "'name' = ''", "a non-empty string"),
    ("source: >", "sauce: >", "'sauce'", "one of the keys"),
    ("masses:\n", "mass_list:\n", "'mass_list'", "one of the keys"),
    ("{name: frame, mass: 6.0}", "{name: frame, mass: 0.0}", "'masses[0].mass' = 0.0", "(0, 1000] kg"),
    ("{name: frame, mass: 6.0}", "{name: frame, mass: .nan}", "'masses[0].mass' = nan", "a finite number"),
    ("{name: frame, mass: 6.0}", "{name: frame, mass: true}", "'masses[0].mass' = True", "a finite number"),
    ("{name: frame, mass: 6.0}", "{name: frame, mass: '6'}", "'masses[0].mass' = '6'", "a finite number"),
    ("{name: frame, mass: 6.0}", "{name: frame}", "'masses[0].mass' = None", "(it is missing)"),
    ("{name: frame, mass: 6.0}", "{name: frame, mass: 6.0, colour: red}", "'masses[0].colour'", "one of"),
    ("{name: upper_frame,", "{name: frame,", "'masses[1].name' = 'frame'", "not given before"),
    ("{name: frame, mass: 6.0}", "{name: roof, mass: 6.0}", "'masses[0].name' = 'roof'", "not 'roof'"),
    ("stiffness: 160.0", "stiffness: -160.0", "'springs[0].stiffness' = -160.0", "(0, 1e+08] N/m"),
    ("stiffness: 160.0", "stiffness: 0.0", "'springs[0].stiffness' = 0.0", "(0, 1e+08] N/m"),
    ("damping: 100.0", "damping: -1.0", "'dampers[0].damping' = -1.0", "[0, 1e+06] N s/m"),
    ("between: [roof, frame], stiffness", "between: [roof, wheel], stiffness", "'springs[0].between'", "two"),
    (
        "between: [roof, frame], stiffness",
        "between: [frame, frame], stiffness",
        "'springs[0].between'",
        "different",
    ),
    ("between: [roof, frame], stiffness", "between: [roof], stiffness", "'springs[0].between'", "two"),
    (
        "  - {between: [upper_frame, head], stiffness: 7000.0}\n",
        "",
        "'springs' = 'head'",
        "springs that join the head to the actuator's mass (frame)",
    ),
    (
        "  - {name: head, mass: 7.5}\n",
        "  - {name: head, mass: 7.5}\n  - {name: horn, mass: 1.0}\n",
        "'springs' = 'horn'",
        "every mass is joined by springs to the head or the roof",
    ),
    ("head: head", "head: pan", "'head' = 'pan'", "one of the masses"),
    ("actuator: frame", "actuator: 3", "'actuator' = 3", "one of the masses"),
    ("static_uplift: 70.0", "static_uplift: -70.0", "'static_uplift' = -70.0", "[0, 1000] N"),
    ("c2: 0.00097", "c2: 0.5", "'aerodynamic_uplift.c2' = 0.5", "[-0.01, 0.01] N/(km/h)^2"),
    ("c2: 0.00097", "c3: 0.00097", "'aerodynamic_uplift.c3'", "one of the keys c0, c2"),
    ("c0: 0.0", "c0: .inf", "'aerodynamic_uplift.c0' = inf", "a finite number"),
    ("head: head", "head: head\nhead: frame", "'head' = 'given twice'", "each key once"),
    ("static_uplift: 70.0", "static_uplift: [70.0", "'(YAML)'", "valid YAML"),
    ("masses:\n", "masses: []\nunused:\n", "'unused'", "one of the keys"),
    ("masses:\n  -", "masses: []\nx:\n  -", "'x'", "one of the keys"),
]


@pytest.mark.unit
@pytest.mark.parametrize("old,new,key,allowed", BAD, ids=[f"{i}:{b[2]}" for i, b in enumerate(BAD)])
def test_a_bad_pantograph_file_is_refused_in_one_line_naming_key_value_and_what_is_allowed(
    old, new, key, allowed
):
    assert old in GOOD
    with pytest.raises(PantographFileError) as err:
        parse_pantograph(GOOD.replace(old, new, 1), "panto.yaml")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith("invalid pantograph file 'panto.yaml'")
    assert key in message and "allowed" in message and allowed in message, message


@pytest.mark.unit
def test_a_missing_file_or_preset_is_refused_by_name():
    with pytest.raises(ParameterError, match=r"'pantograph' = 'no_such': allowed .*paper_2dof"):
        load_pantograph_file("no_such")
    with pytest.raises(ParameterError, match=r"'nominal_pantograph' = 'no_such': allowed"):
        PantographParameters(nominal_pantograph="no_such")
    with pytest.raises(ParameterError, match="readable pantograph file"):
        load_pantograph_file("/nonexistent/panto.yaml")


@pytest.mark.unit
def test_the_fe_plant_reads_z1_at_the_head_and_z2_at_the_actuator_mass():
    chain = head_first(load_pantograph("three_mass")[0])
    assert (chain.head, chain.input) == (0, 1)
    assert list(chain.mass) == [7.5, 6.0, 9.0]
    assert chain.ground_stiffness.tolist() == [0.0, 160.0, 0.0]
    same = paper_pantograph()
    assert head_first(same) is same


@pytest.mark.slow
def test_simulate_refuses_a_bad_pantograph_file_with_one_line_exit_2_and_runs_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("stiffness: 15500.0", "stiffness: 0.0"))
    line = simulate_refusal(tmp_path / "bag", f"pantograph:={bad}", "duration:=0.01")
    assert "'springs[1].stiffness' = 0.0: allowed a finite number in (0, 1e+08] N/m" in line


# -- the presets on the rig: bit for bit, aero follows the speed ---------------------------------------
def _records(**flat) -> list:
    from pac_rig.closed_loop import run
    from pac_rig.simulate import scenario_from_flat

    return list(run(scenario_from_flat({"duration": 0.3, **flat})))


@pytest.mark.slow
@pytest.mark.parametrize("model", ["lumped", "fe"])
def test_the_paper_preset_runs_bit_for_bit_as_the_default_pantograph(model):
    base = {"catenary_model": model, "speed_kmh": 300.0}
    default = _records(**base)
    for extra in ({"pantograph": "paper_2dof"}, {"nominal_pantograph": "paper_2dof"}):
        other = _records(**base, **extra)
        assert len(other) == len(default)
        for a, b in zip(default, other, strict=True):
            assert repr(a) == repr(b)  # repr: every float to the last bit, NaN equal to NaN


def three_mass_fe_plant(speed_kmh: float, wind_uplift: float):
    """The FE plant (benchmark_55m, endless) with the 3-mass preset at ``speed_kmh``."""
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    options = PlantOptions(catenary_model="fe", pantograph="three_mass", wind_uplift=wind_uplift)
    track = TrackParameters(speed_kmh=speed_kmh)
    return FEPlant(PantographParameters(), track, CatenaryParameters(), options, 1e-3)


@pytest.mark.slow
def test_the_three_mass_preset_runs_on_the_fe_plant_and_its_aero_uplift_follows_the_speed():
    uplifts = {}
    for v in (200.0, 300.0):
        plant = three_mass_fe_plant(v, 5.0)
        uplifts[v] = plant.own_uplift
        assert plant.uplift == 5.0  # only the wind acts with u: the own uplift is part of u
        assert plant.sim.panto.mass.tolist() == [7.5, 6.0, 9.0]  # z1 head, z2 frame
    assert uplifts[200.0] == 70.0 + 0.00097 * 200.0**2
    assert uplifts[300.0] == 70.0 + 0.00097 * 300.0**2


@pytest.mark.slow
def test_a_pantograph_commanded_with_its_own_uplift_presses_the_wire_with_it_on_average():
    """Momentum balance of the whole pantograph over whole periods of the line: the mean contact
    force is the mean of the other forces on it, the command (its own uplift, as a passive law
    commands it) + wind, the roof springs carrying nothing at the pressed static state (a roof
    spring relaxed at the touching start would take k_roof x the wire's rise, ~7 N here, off the
    mean)."""
    from pac_common.contact_statistics import contact_statistics

    v, span = 250.0, 55.0
    plant = three_mass_fe_plant(v, 10.0)
    start = plant.truth().contact_position
    force, position = [], []
    uplift = load_pantograph_file("three_mass").uplift(v)
    while plant.truth().contact_position < start + 8.5 * span:
        plant.advance(uplift)  # passive: the command is the pantograph's own uplift
        truth = plant.truth()
        force.append(truth.contact_force)
        position.append(truth.contact_position)
    stats = contact_statistics(np.array(force), np.array(position), 1e-3, start + 4 * span, start + 8 * span)
    assert stats.contact_force_mean == pytest.approx(uplift + 10.0, rel=0.01)
    assert stats.contact_force_std > 10.0  # the line's stiffness varies: the force is not constant


@pytest.mark.slow
def test_the_reference_run_with_the_preset_is_the_committed_one():
    import json

    from pac_experiments.catenary.line_runs import passive_reference

    committed = json.loads((ROOT / "reports" / "catenary" / "metrics.json").read_text())["reference_runs"][
        "250"
    ]
    run = passive_reference(250)
    for key in (
        "static_force",
        "contact_force_mean",
        "contact_force_std",
        "contact_force_max",
        "support_uplift_mm",
    ):
        assert run[key] == pytest.approx(committed[key], rel=1e-12, abs=1e-12), key


@pytest.mark.live
def test_the_nodes_refuse_a_pantograph_they_cannot_use_in_one_line(domain_id, tmp_path):
    from test_node_cli import one_line_refusal, run_node

    from pac_rig.launcher import node_env

    env = node_env(domain_id)
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("mass: 9.0", "mass: -9.0"))
    one_line_refusal(
        run_node("plant", "--ros-args", "-p", "catenary_model:=fe", "-p", f"pantograph:={bad}", env=env),
        "invalid pantograph file",
        "'masses[1].mass' = -9.0",
    )
    one_line_refusal(
        run_node("plant", "--ros-args", "-p", "pantograph:=three_mass", env=env),
        "'pantograph'",
        "the paper's 2-DOF chain (2 masses; this one has 3)",
    )
    for node in ("observer", "controller"):
        one_line_refusal(
            run_node(node, "--ros-args", "-p", "nominal_pantograph:=three_mass", env=env),
            "'nominal_pantograph'",
            "every observer and law are built on",
        )
