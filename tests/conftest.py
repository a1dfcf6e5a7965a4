"""Shared fixtures: every test that touches DDS gets its own ROS domain and cleans up its processes."""

import os

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # also for anything imported below


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
