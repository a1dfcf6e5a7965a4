"""Shared fixtures: every test that touches DDS gets its own ROS domain and cleans up its processes."""

import os

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # also for anything imported below


def node_stats(log: str, node: str) -> dict:
    """A node's end-of-run counters: its ``pac-stats {json}`` line in ``log`` (the process's output).

    Tests read the counters from this line, never from the nodes' prose (which may be reworded)."""
    from pac_common.diagnostics import parse_stats

    stats = parse_stats(log)
    assert node in stats, f"no pac-stats line of {node} in:\n{log[-2000:]}"
    return stats[node]


@pytest.fixture
def domain_id():
    """A ROS_DOMAIN_ID no other test (or test run) on this machine holds."""
    import domain_coordinator

    with domain_coordinator.domain_id() as did:
        yield did


@pytest.fixture
def rigs(domain_id, tmp_path):
    """Factory of rigs in this test's domain; every process is stopped at teardown, pass or fail."""
    from pac_rig.launcher import Rig

    made = []

    def make(name="run", **kwargs):
        rig = Rig(tmp_path / name, domain_id=domain_id, log_dir=tmp_path / f"{name}_logs", **kwargs)
        made.append(rig)
        return rig

    yield make
    for rig in made:
        rig.stop(grace=5.0)
        assert all(p.poll() is not None for p in rig.processes.values())
