"""The exit guard ends a process with its status even while a C call holds the GIL.

The hang it exists for (rclpy's destroy_node stuck with the GIL held) is stood in for by
``ctypes.PyDLL``'s ``sleep``: PyDLL calls keep the GIL, so no Python thread runs meanwhile.
"""

import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.unit

HOLD = 8  # s the stand-in hang holds the GIL


def run(guard: str, status: int) -> tuple[int, float, str]:
    script = (
        "import ctypes, os, threading\n"
        "from pac_common.exit_guard import exit_after\n"
        f"{guard}\n"
        f"ctypes.PyDLL(None).sleep({HOLD})\n"
        "print('the hang ended first', flush=True)\n"
    )
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=HOLD + 30)
    return done.returncode, time.monotonic() - started, done.stdout


@pytest.mark.parametrize("status", [0, 1, 3])
def test_the_guard_ends_a_process_whose_gil_is_held_with_its_status(status):
    code, seconds, out = run(f"exit_after(0.5, {status})", status)
    print(f"\nended with {code} after {seconds:.2f} s (the hang holds the GIL for {HOLD} s)")
    assert code == status and "the hang ended first" not in out
    assert seconds < HOLD / 2


@pytest.mark.slow
def test_a_python_timer_thread_cannot_end_that_hang():
    # Why the guard is not a threading.Timer: this is what the node processes had before.
    code, seconds, out = run("t = threading.Timer(0.5, lambda: os._exit(7)); t.daemon = True; t.start()", 7)
    assert seconds >= HOLD  # it ran only once the hang let the GIL go
