"""The FE experiment's judgement from campaign rows: each goal met or not with its numbers, the passive
reference of a row (same speed and pantograph), the robustness cases; synthetic rows, no runs."""

from __future__ import annotations

import pytest

from pac_experiments.catenary import experiment as fe_experiment

pytestmark = pytest.mark.unit

SPEEDS = [160.0, 200.0, 250.0, 300.0, 360.0, 400.0]


def row(law: str, speed: float, sigma: float, *, loss: float = 0.0, status: str = "ok", **values) -> dict:
    target = 0.00097 * speed**2 + 70.0
    return {
        "law": law,
        "speed_kmh": speed,
        "status": status,
        "reason": "",
        "force_amplitude": target,
        "en50318_contact_force_std": sigma,
        "en50318_contact_force_mean": values.pop("mean", target),
        "en50318_contact_loss_percent": loss,
        "noise_std": [0.0, 0.0],
        "command_delay_ticks": 1,
        "plant_mass_scale": 1.0,
        **values,
    }


def good_rows() -> list[dict]:
    rows = [row("passive", v, 50.0) for v in SPEEDS]
    rows += [row("line_adaptive", v, 15.0) for v in SPEEDS]  # -70 % everywhere
    for scale in (0.8, 1.2):
        rows.append(row("passive", 300.0, 60.0, plant_mass_scale=scale))
    for values in fe_experiment.CASES.values():
        rows.append(row("line_adaptive", 300.0, 30.0, **values))  # -40 % against 50, -50 % against 60
    return rows


def by_name(goals) -> dict[str, fe_experiment.Goal]:
    return {g.name: g for g in goals}


def test_every_goal_is_met_by_a_law_that_meets_them():
    goals = fe_experiment.goals(good_rows())
    assert all(g.met for g in goals), [g for g in goals if not g.met]
    assert len(goals) == 5 + len(fe_experiment.CASES)


def test_each_goal_fails_on_its_own_evidence():
    rows = good_rows()
    rows[SPEEDS.index(300.0) + len(SPEEDS)]["en50318_contact_force_std"] = 22.0  # -56 % at 300
    rows[SPEEDS.index(160.0) + len(SPEEDS)]["en50318_contact_force_std"] = 51.0  # worse at 160
    rows[SPEEDS.index(200.0) + len(SPEEDS)]["en50318_contact_force_mean"] *= 1.03  # mean 3 % off
    rows[SPEEDS.index(400.0) + len(SPEEDS)]["en50318_contact_loss_percent"] = 0.5
    rows[-1]["status"] = "diverged"  # the last robustness case is unstable
    goals = by_name(fe_experiment.goals(rows))
    assert not goals["sigma >= 60 % below passive at 300 km/h"].met
    assert "300: -56.0 %" in goals["sigma >= 60 % below passive at 300 km/h"].numbers
    assert goals["sigma >= 50 % below passive at every speed 250-360 km/h"].met
    assert not goals["never worse than passive at any speed 160-400 km/h"].met
    assert "+2.0 %" in goals["never worse than passive at any speed 160-400 km/h"].numbers
    assert not goals["mean contact force within 2 % of the target (every speed run)"].met
    assert not goals["no contact loss where passive has none"].met
    assert "400 (0.50 %)" in goals["no contact loss where passive has none"].numbers
    last = list(fe_experiment.CASES)[-1]
    assert not goals[f"robust, {last}: >= 30 % below passive, never unstable"].met
    assert goals[f"robust, {list(fe_experiment.CASES)[0]}: >= 30 % below passive, never unstable"].met


def test_a_row_is_compared_with_the_passive_run_of_its_own_pantograph():
    rows = good_rows()
    heavy = next(r for r in rows if r["law"] == "line_adaptive" and fe_experiment.case_of(r) == "masses x1.2")
    assert fe_experiment.passive_for(rows, heavy)["en50318_contact_force_std"] == 60.0
    assert fe_experiment.change_percent(rows, heavy) == pytest.approx(-50.0)
    noisy = next(r for r in rows if fe_experiment.case_of(r) == "noise 10 µm")
    assert fe_experiment.passive_for(rows, noisy)["en50318_contact_force_std"] == 50.0  # u = F_r: noise-free
    assert fe_experiment.case_of({"noise_std": [1e-5, 1e-5], "plant_mass_scale": 0.9}) is None


def test_the_live_run_gives_the_loop_nodes_the_points_values():
    """fe_live passes the campaign point to the three loop nodes: every value a node declares
    (the law, the observer, the FE line options), nothing the nodes do not know (duration)."""
    from pac_experiments.campaign.spec import Point
    from pac_experiments.catenary.live import loop_parameters

    values = {
        "law": "line_adaptive",
        "observer": "contact_force",
        "catenary_model": "fe",
        "fe_datum": "fixed",
        "speed_kmh": 300.0,
        "duration": 12.2,
        "not_a_parameter": 1.0,
    }
    given = loop_parameters(Point(key="k", values=values, grid=0))
    assert given == {k: v for k, v in values.items() if k not in ("duration", "not_a_parameter")}
    # A scenario goes through: the rig expands it into the nodes' values (the realistic live run).
    with_file = loop_parameters(Point(key="k", values={**values, "scenario": "realistic_pneumatic"}, grid=0))
    assert with_file["scenario"] == "realistic_pneumatic"
