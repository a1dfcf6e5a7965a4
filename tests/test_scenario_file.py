"""Scenario files (``-p scenario:=NAME|PATH``): the presets, the user's values over the file's,
one line for a bad file, and the same expansion on every entry point (simulate, campaign points,
the rig launcher, composition.derive)."""

from __future__ import annotations

import pytest
from conftest import simulate_refusal

from pac_common.contact_statistics import target_mean_force
from pac_common.parameters import ParameterError
from pac_controller.laws import LAWS
from pac_model.parameters import TrackParameters
from pac_rig import composition
from pac_rig.launcher import Rig
from pac_rig.scenario_file import PRESETS, ScenarioFileError, expand, load_scenario
from pac_rig.simulate import scenario_from_flat, scenario_to_flat

REALISTIC = ("realistic_electromechanical", "realistic_pneumatic")


@pytest.mark.unit
def test_the_presets_load_and_paper_rig_is_todays_rig():
    assert set(PRESETS.names()) >= {"paper_rig", *REALISTIC}
    assert load_scenario("paper_rig").parameters == {}
    assert scenario_to_flat(scenario_from_flat({"scenario": "paper_rig"})) == scenario_to_flat(
        scenario_from_flat({})
    )
    for name in REALISTIC:
        flat = scenario_to_flat(scenario_from_flat({"scenario": name}))
        assert flat["catenary_model"] == "fe" and flat["pantograph"] == "three_mass"
        assert flat["nominal_pantograph"] == "three_mass_identified_2dof" and flat["sensors"] == "train"
        assert flat["actuator"] == name.removeprefix("realistic_") and flat["roof_motion"] == "german_low"


@pytest.mark.unit
def test_the_users_values_win_over_the_files():
    values, notes = expand({"scenario": "realistic_electromechanical", "line_seed": 7, "speed_kmh": 250.0})
    assert values["line_seed"] == 7 and values["actuator"] == "electromechanical" and "scenario" not in values
    assert values["speed_kmh"] == 250.0
    assert len(notes) == 1 and "yours kept: line_seed" in notes[0]
    assert expand({"law": "pid"}) == ({"law": "pid"}, [])


@pytest.mark.unit
def test_derive_sees_the_files_parts():
    """The actuator a scenario names works about the run's reference, and the FE line's span, its
    map, the law's observer (the head balance: the file's sensors have a head accelerometer) and the
    law's design for the actuator are derived from the file's values as from the user's."""
    values, _ = composition.derive(
        {"scenario": "realistic_electromechanical", "law": "line_adaptive", "force_amplitude": 157.3}
    )
    assert values["actuator_static_force"] == 157.3
    assert values["observer"] == "head_balance"
    assert 50.0 <= values["span_length"] <= 60.0  # the drawn line's mean span (50-60 m rule)
    assert len(values["line_supports"]) > 50
    design = LAWS["line_adaptive"].actuator_design
    assert design is not None
    span_time = values["span_length"] / (TrackParameters().speed_kmh / 3.6)
    expected = dict(design(0.025, span_time))  # the electromechanical actuator: 20 ms lag, 5 ms delay
    assert "line_support_before" in expected and {k: values[k] for k in expected} == expected


@pytest.mark.unit
@pytest.mark.parametrize("scenario", ["realistic_electromechanical", "realistic_pneumatic"])
def test_the_realistic_law_learns_only_below_the_plant_frames_first_anti_resonance(scenario):
    """line_adaptive's derived band on a realistic scenario (docs/laws.md, "On the realistic line",
    point 7) ends below the first anti-resonance of the plant pantograph's frame: the lowest local
    minimum of |actuator-mass height / actuator force| (head on the nominal's contact spring, roof
    fixed), computed here from the plant's file on a fine grid. Below it the identified nominal the
    head balance reads the head through matches the plant to a few % of each channel's peak
    (3.9 %, 4.2 % measured; 5 %: the fit's RMS over the whole band is 4.3 %), above it the misfit
    grows (17 % by 8 Hz), and with harmonics to 8 Hz the law's F_hat erred by as much as the force
    there. A band raised past the anti-resonance fails here."""
    import numpy as np

    from pac_model import identification
    from pac_model.pantograph_file import load_pantograph_file

    given, _ = expand({"scenario": scenario, "law": "line_adaptive"})
    values = {**given, **composition.derive({"scenario": scenario, "law": "line_adaptive"})[0]}
    plant = load_pantograph_file(str(values["pantograph"]))
    nominal = load_pantograph_file(str(values["nominal_pantograph"]))
    f = np.geomspace(0.5, 20.0, 4000)  # 0.1 % steps: the minimum to well under 0.1 Hz
    response = identification.frequency_response(plant, f, identification.CONTACT_STIFFNESS)
    frame = np.abs(response[:, 1])
    inner = np.flatnonzero((frame[1:-1] < frame[:-2]) & (frame[1:-1] < frame[2:])) + 1
    assert inner.size, "the 3-mass frame has an anti-resonance in the band"
    anti_resonance = f[inner[0]]
    band = values["line_max_frequency"]
    assert band < anti_resonance, (band, anti_resonance)
    fitted = identification.frequency_response(nominal, f, identification.CONTACT_STIFFNESS)
    # The fit's own measure (largest |fitted - response| over each channel's peak; the peaks, at
    # 1.8 Hz, lie inside both ranges).
    below, _ = identification.misfit(response[f <= band], fitted[f <= band])
    assert max(below) < 0.05
    up_to_8, _ = identification.misfit(response[f <= 8.0], fitted[f <= 8.0])
    assert max(up_to_8) > 0.1  # what the band leaves out: the nominal does not hold there


@pytest.mark.unit
def test_the_rig_gives_each_node_the_files_values(tmp_path):
    rig = Rig(
        tmp_path / "bag",
        duration=1.0,
        params={"all": {"scenario": "realistic_pneumatic", "force_amplitude": 140.0}},
        record=False,
    )
    plant, observer, controller = (rig.params[n] for n in ("plant", "observer", "controller"))
    assert plant["actuator"] == "pneumatic" and plant["catenary"] == "realistic_3km"
    assert plant["actuator_static_force"] == 140.0
    assert observer["nominal_pantograph"] == controller["nominal_pantograph"] == "three_mass_identified_2dof"
    assert "actuator" not in controller and "scenario" not in plant


@pytest.mark.unit
def test_a_campaign_point_expands_its_scenario_and_centres_the_actuator_on_the_target(tmp_path):
    from pac_experiments.campaign.spec import load_points

    spec = tmp_path / "spec.yaml"
    spec.write_text(
        "grid:\n  scenario: [paper_rig, realistic_electromechanical]\n  law: [passive]\n"
        "fixed:\n  speed_kmh: 300.0\n  duration: 4.0\nforce_target: en50367\n"
    )
    _, points = load_points(spec)
    by_scenario = {p.values["scenario"]: scenario_from_flat(p.values) for p in points}
    realistic = by_scenario["realistic_electromechanical"]
    assert realistic.plant.actuator == "electromechanical" and realistic.plant.catenary == "realistic_3km"
    assert realistic.plant.actuator_static_force == pytest.approx(target_mean_force(300.0))
    assert by_scenario["paper_rig"].plant.actuator == "ideal"


BAD_FILES = [
    ("name: x\nsource: y\nparameters:\n  actuator: hydraulic\n", "'parameters.actuator' = 'hydraulic'", "4"),
    ("name: x\nsource: y\nparameters:\n  actuatr: ideal\n", "'parameters.actuatr'", "4"),
    ("name: x\nsource: y\nparameters: [1, 2]\n", "'parameters'", None),
    ("source: y\nparameters: {}\n", "'name'", None),
    ("name: x\nsource: y\nparameters: {}\nextra: 1\n", "'extra'", None),
    ("name: x\nsource: y\nparameters:\n  scenario: paper_rig\n", "'parameters.scenario'", "4"),
    ("name: x\nsource: y\nparameters:\n  line_seed: 1\n  line_seed: 2\n", "given twice", "5"),
]


@pytest.mark.unit
@pytest.mark.parametrize(("text", "names", "line"), BAD_FILES)
def test_a_bad_scenario_file_is_refused_in_one_line(tmp_path, text, names, line):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioFileError) as info:
        load_scenario(str(path))
    message = str(info.value)
    assert "\n" not in message and f"invalid scenario file '{path}'" in message and names in message
    if line is not None:
        assert f"line {line}," in message


@pytest.mark.unit
def test_an_unknown_preset_or_a_missing_file_is_refused_naming_the_presets(tmp_path):
    with pytest.raises(ParameterError, match="invalid parameter 'scenario' = 'realistc'.*paper_rig"):
        expand({"scenario": "realistc"})
    with pytest.raises(ParameterError, match="a readable scenario file"):
        expand({"scenario": str(tmp_path / "none.yaml")})


@pytest.mark.offline
def test_simulate_refuses_a_bad_scenario_in_one_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\nsource: y\nparameters:\n  actuator: hydraulic\n")
    line = simulate_refusal(tmp_path / "bag", f"scenario:={path}")
    assert "invalid scenario file" in line and "'parameters.actuator' = 'hydraulic'" in line


@pytest.mark.unit
def test_a_campaigns_results_name_the_scenario_of_each_row(tmp_path):
    """A run's record holds its scenario expanded (no ``scenario``); results.csv takes the axes a
    SPEC names from the point, so rows of two scenarios stay apart in the table and the summary."""
    import csv

    from pac_experiments.campaign.results import write_results
    from pac_experiments.campaign.spec import load_points

    spec_path = tmp_path / "spec.yaml"
    spec_path.write_text(
        "grid:\n  scenario: [paper_rig, realistic_electromechanical]\n  law: [passive]\n"
        "fixed:\n  duration: 4.0\n"
    )
    spec, points = load_points(spec_path)
    done = {p.key: {"key": p.key, "status": "ok", "law": "passive"} for p in points}
    write_results(spec, points, done, tmp_path)
    with (tmp_path / "results.csv").open(newline="") as f:
        assert [r["scenario"] for r in csv.DictReader(f)] == ["paper_rig", "realistic_electromechanical"]


@pytest.mark.unit
def test_the_rig_derives_from_the_plants_parts_as_simulate_does(tmp_path):
    """The launcher derives with the plant's parts in view (its sensors, line, actuator): the same
    observer, line map, actuator range and law design as ``composition.derive`` gives offline."""
    given = {"scenario": "realistic_electromechanical", "law": "line_adaptive", "line_seed": 101}
    rig = Rig(tmp_path / "bag", duration=1.0, params={"all": {**given, "force_amplitude": 157.3}})
    offline, _ = composition.derive({**given, "force_amplitude": 157.3})
    assert rig.params["observer"]["observer"] == offline["observer"] == "head_balance"
    for name in ("line_supports", "line_position_start", "line_effort_weight", "u_min", "u_max"):
        assert rig.params["controller"][name] == offline[name], name
