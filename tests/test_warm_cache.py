"""`make setup` leaves a warm numba cache: no process compiles the cores at start."""

import os
import re
import subprocess
import sys

import pytest

from pac_rig.launcher import NODES

pytestmark = pytest.mark.live

LOOP_NODES = ("plant", "observer", "controller")


def test_warm_cache_holds_every_specialisation_the_rig_uses():
    """`python -m pac_rig.warm --check` drives the cores as nodes, simulate and batch do: nothing compiles."""
    assert os.environ.get("NUMBA_CACHE_DIR", "").endswith("build/numba_cache")
    proc = subprocess.run(
        [sys.executable, "-m", "pac_rig.warm", "--check"], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # "warm: N compiled functions, L specialisations loaded from the cache, C compiled, T s": read
    # the numbers (a substring test took "30 specialisations loaded" for "0 ... loaded").
    counts = re.search(r"(\d+) specialisations loaded from the cache, (\d+) compiled", proc.stdout)
    assert counts is not None, proc.stdout
    loaded, compiled = (int(v) for v in counts.groups())
    assert loaded > 0 and compiled == 0, proc.stdout


def test_loop_nodes_load_the_cores_from_the_cache(rigs, monkeypatch):
    """A lock-step rig with numba's cache log on: every loop node loads compiled code, none saves any."""
    monkeypatch.setenv("NUMBA_DEBUG_CACHE", "1")  # inherited by the node processes
    rig = rigs("warm", duration=0.3, timing_mode="lockstep")
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), {n: p.log()[-500:] for n, p in rig.processes.items()}
    for name in LOOP_NODES:
        log = rig.processes[name].log()
        assert "[cache] data loaded from" in log, (name, log[-1000:])
        assert "[cache] data saved to" not in log, (name, log[-2000:])
