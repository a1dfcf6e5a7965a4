"""Helpers for tests that start a node as a real process (imported by the tests, not collected)."""

import signal
import subprocess
import time
from pathlib import Path


def assert_starts_and_stops_cleanly(cmd: list[str], ready_text: str, env: dict[str, str], log: Path) -> None:
    """Start ``cmd``, wait until its log shows ``ready_text``, SIGINT it: it must exit 0.

    The process is killed on any failure, so nothing outlives the test.
    """
    with open(log, "wb") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)
    try:
        deadline = time.monotonic() + 30
        while ready_text not in log.read_text() and time.monotonic() < deadline:
            assert proc.poll() is None, log.read_text()
            time.sleep(0.05)
        assert ready_text in log.read_text()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
