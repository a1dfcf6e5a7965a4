"""Two pantographs on the live rig: plant_node publishes every pantograph's truth on
``pantograph_truth``, the recorder records it, an independent MCAP reader reads it back, and the
analysis reports every pantograph's EN 50318 statistics."""

from __future__ import annotations

import numpy as np

from pac_analysis.metrics import pantograph_statistics
from pac_bag.reader import read_bag


def test_the_rig_records_and_reports_every_pantograph(rigs):
    from mcap_ros2.reader import read_ros2_messages

    duration = 1.6  # s: 133 m at 300 km/h, at least one whole span for each pantograph
    fe = {"catenary_model": "fe", "speed_kmh": 300.0, "span_length": 55.0}
    params = {"all": fe, "plant": {"pantographs": [0.0, 200.0], "controlled_pantograph": 1}}
    rig = rigs("two", duration=duration, timing_mode="lockstep", params=params)
    rig.start()
    rig.wait_finished(timeout=240)
    assert set(rig.exit_codes().values()) == {0}, {n: p.log()[-500:] for n, p in rig.processes.items()}
    # An independent reader (mcap-ros2), not the project's: every tick of both topics.
    forces: dict[str, dict[int, object]] = {"/plant_truth": {}, "/pantograph_truth": {}}
    files = sorted(rig.bag_path.glob("*.mcap"))
    for m in read_ros2_messages(str(files[0]), topics=list(forces)):
        forces[m.channel.topic][int(m.ros_msg.tick)] = m.ros_msg
    ticks = sorted(forces["/plant_truth"])
    assert ticks == sorted(forces["/pantograph_truth"]) and len(ticks) == round(duration * 1000)
    for k in ticks:
        one, every = forces["/plant_truth"][k], forces["/pantograph_truth"][k]
        assert every.controlled == 1 and list(every.spacing) == [0.0, 200.0]
        assert every.contact_force[1] == one.contact_force  # the controlled one is PlantTruth's
        assert every.contact_position[0] - every.contact_position[1] == 200.0
    lead = np.array([forces["/pantograph_truth"][k].contact_force[0] for k in ticks])
    assert lead.max() > 100.0  # the passive leading pantograph presses with its uplift (157 N)
    rows = pantograph_statistics(read_bag(rig.bag_path), window_from=0.0)
    assert [r["controlled"] for r in rows] == [False, True]
    assert all(r["x_to"] - r["x_from"] >= 55.0 for r in rows)
    assert rows[0]["contact_force_mean"] > 50.0
