"""Both pantographs of a pair active (``pac_rig.pair_loop``): one line, two chains.

The second unit is the rig that would control the trailing pantograph, run on the first unit's
line. Checked against the FE line's own passive pantograph (an independent path: the force its
file holds on the actuator's mass): the leading pantograph's force is that of the rig whose
trailing pantograph is passive until the trailing one's different start can have reached it along
the wire (at c - v), and the trailing pantograph's mean contact force follows its own unit's
command by the momentum balance. Refusals: rigs that are not one train.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pac_common.parameters import ParameterError
from pac_controller.line_adaptive import DESIGN_AHEAD_OF_ACTIVE
from pac_model.pantograph_file import load_pantograph_file
from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.hardware.car_body import roof_attachment
from pac_rig.closed_loop import build_cores, run_blocks
from pac_rig.loop import compile_loop
from pac_rig.pair_loop import pair_loop, run_pair_blocks
from pac_rig.simulate import scenario_from_flat

pytestmark = pytest.mark.offline

SPEED = 300.0
DURATION = 6.0
RAISED = 20.0  # N, the trailing unit's reference above its file's uplift


def _rig(controlled: int, law: str, pair_unit: bool | None = None, **given):
    """The cores and compiled loop of the realistic pair's rig controlling ``controlled`` (a pair
    loop's unit where ``all_pantographs_active`` is given, unless ``pair_unit`` says)."""
    from pac_rig import composition

    values, _ = composition.derive(
        {
            "scenario": "realistic_electromechanical",
            "line_seed": 0,
            "speed_kmh": SPEED,
            "pantographs": (0.0, 200.0),
            "controlled_pantograph": controlled,
            "law": law,
            "duration": DURATION,
            **given,
        }
    )
    s = scenario_from_flat(values)
    unit = bool(given.get("all_pantographs_active")) if pair_unit is None else pair_unit
    plant, observer, controller = build_cores(s, pair_unit=unit)
    loop = compile_loop(plant, observer, controller, s.loop.command_delay_ticks)
    assert loop is not None
    return s, plant, loop


def _pair(trailing_force: float):
    """Both units' ticks: the leading one line_adaptive, the trailing one passive at ``trailing_force``."""
    s, plant, loop = _rig(0, "line_adaptive", all_pantographs_active=True)
    _, plant2, loop2 = _rig(1, "passive", all_pantographs_active=True, force_amplitude=trailing_force)
    blocks = list(run_pair_blocks(s.loop.ticks, plant, plant2, pair_loop(plant, loop, plant2, loop2)))
    return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks]), plant


@pytest.fixture(scope="module")
def runs():
    # The lone rig's leader with the design a pair's leader derives (ahead of an active one).
    s, plant, loop = _rig(0, "line_adaptive", **dict(DESIGN_AHEAD_OF_ACTIVE))
    single = np.concatenate(list(run_blocks(s, plant, loop)))
    uplift = plant.sim.constants.p_uplift[1]  # the trailing pantograph's file's uplift
    return single, _pair(uplift), _pair(uplift + RAISED), uplift


def test_the_leading_pantograph_is_the_lone_rigs_until_the_trailing_ones_start_can_reach_it(runs):
    """The trailing unit starts from rest with its actuator's force rising (the FE's passive one
    holds its uplift from the first tick): that difference runs forward along the wire at c - v and
    reaches the leading pantograph 200 / (c - v) after the start (4.5 s at 300 km/h): before, the
    two agree to rounding (1 uN, as a lone pantograph and a pair's leading one: test_two_pantographs);
    after, by the wave the trailing one's start sent (0.87 N by 6 s; more than 0.1 N asked).
    """
    single, (pair, _, _), _, _ = runs
    line = load_catenary("realistic_3km").data
    c, v = math.sqrt(line.contact.tension / line.contact.rho), SPEED / 3.6
    arrival = int(200.0 / (c - v) / 1e-3)
    lead, lone = pair["pantograph_contact_force"][:, 0], single["pantograph_contact_force"][:, 0]
    assert np.max(np.abs(lead[:arrival] - lone[:arrival])) < 1e-6
    assert np.max(np.abs(lead[arrival:] - lone[arrival:])) > 0.1


def _momentum_rate(run: np.ndarray) -> float:
    """The trailing pantograph's change of momentum over ``run`` over its length [N]: the head's and
    the two frames' (the upper frame taken at the lower one's velocity: the 15500 N/m between them
    is the chain's stiffest spring), masses of the pantograph file."""
    z = run["z"]
    p = 7.5 * z[:, 2] + (6.0 + 9.0) * z[:, 3]
    return float((p[-1] - p[0]) / (z.shape[0] * 1e-3))


def test_the_trailing_pantograph_presses_with_its_own_units_force(runs):
    """Over the run's second half (the start's transient gone) the trailing pantograph's mean
    contact force follows its unit's command by the momentum balance: commanded RAISED more, it
    presses RAISED more, less what the roof spring takes back as the frame rises (k_roof, the file's
    160 N/m, times the frame's mean rise: 1.6 N of the 20) and less the change of its momentum over
    the stretch (0.05 N). Left out, within 0.1 N: the roof damper, the upper frame's own velocity.
    A unit whose force did not reach the line would give 0, one that left the file's uplift on it
    as well RAISED + 157 N."""
    single, (_, same, _), (_, raised, _), uplift = runs
    half = slice(single.size // 2, None)
    k_roof, _ = roof_attachment(load_pantograph_file("three_mass"))
    rise = raised["z"][half, 1].mean() - same["z"][half, 1].mean()
    expected = RAISED - k_roof * rise - (_momentum_rate(raised[half]) - _momentum_rate(same[half]))
    pressed = raised["contact_force"][half].mean() - same["contact_force"][half].mean()
    assert pressed == pytest.approx(expected, abs=0.1)
    assert np.all(same["u"][half] == pytest.approx(uplift))
    assert np.all(raised["u"][half] == pytest.approx(uplift + RAISED))


def test_a_rig_of_one_unit_refuses_all_pantographs_active_in_one_line():
    """A rig runs one unit: the other pantograph would be passive whatever the law was told."""
    with pytest.raises(ParameterError) as info:
        _rig(1, "line_adaptive", all_pantographs_active=True, pair_unit=False)
    message = str(info.value)
    assert info.value.name == "all_pantographs_active" and "a rig of one unit" in message
    assert "\n" not in message


def test_rigs_that_are_not_one_train_are_refused():
    s, plant, loop = _rig(0, "line_adaptive", all_pantographs_active=True)
    _, plant2, loop2 = _rig(1, "passive")
    with pytest.raises(ValueError, match="all_pantographs_active"):
        pair_loop(plant, loop, plant2, loop2)
    _, plant3, loop3 = _rig(0, "passive", all_pantographs_active=True)
    with pytest.raises(ValueError, match="leading pantograph"):
        pair_loop(plant, loop, plant3, loop3)
