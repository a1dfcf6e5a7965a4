#!/usr/bin/env bash
# scripts/run_tests.sh [PYTEST ARGS...] — run the test suite (tests/, or the test paths given) in the
# workspace env.
#
# - Sources env.sh (venv, install/ overlay, LOCALHOST discovery, Fast DDS profile).
# - Reserves a free ROS_DOMAIN_ID with domain_coordinator (shipped with the wheels: it binds TCP
#   port 32768+id, ids 1..100) and holds it for the whole run; exported as ROS_DOMAIN_ID and
#   PAC_ROS_DOMAIN_ID_BASE. Tests that need more ids should take them from
#   domain_coordinator.domain_id() as well; the reserved one is then never handed out twice.
# - pytest runs in its own process group; after PAC_TEST_WALL_TIMEOUT seconds (default 2700)
#   the whole group (pytest and any node it started) gets SIGTERM, then SIGKILL 10 s later.
# - pytest's exit 5 (no tests collected) is reported as a failure.
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck disable=SC1091
source "$ROOT/env.sh"

set +e
python - "$@" <<'PY'
import os
import signal
import subprocess
import sys

import domain_coordinator

wall = float(os.environ.get('PAC_TEST_WALL_TIMEOUT', '2700'))
args = sys.argv[1:]
# Test paths given (e.g. tests/test_plant.py or tests/test_x.py::test_y): run those, else tests/.
paths = [] if any(not a.startswith('-') for a in args) else ['tests']
cmd = [sys.executable, '-m', 'pytest', *paths, '-q', '-p', 'no:cacheprovider', *args]

with domain_coordinator.domain_id() as did:
    env = dict(os.environ, ROS_DOMAIN_ID=str(did), PAC_ROS_DOMAIN_ID_BASE=str(did),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    print(f'run_tests: ROS_DOMAIN_ID={did} (reserved for this run), '
          f'RMW_IMPLEMENTATION={env.get("RMW_IMPLEMENTATION")}', flush=True)
    proc = subprocess.Popen(cmd, env=env, start_new_session=True)

    def _forward(signum, _frame):
        try:
            os.killpg(proc.pid, signum)
        except ProcessLookupError:
            pass

    signal.signal(signal.SIGINT, _forward)
    signal.signal(signal.SIGTERM, _forward)
    try:
        rc = proc.wait(timeout=wall)
    except subprocess.TimeoutExpired:
        print(f'run_tests: test run exceeded {wall:.0f} s; terminating it', file=sys.stderr)
        _forward(signal.SIGTERM, None)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            _forward(signal.SIGKILL, None)
            proc.wait()
        rc = 124
sys.exit(rc)
PY
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
    echo "run_tests: FAILED: pytest collected no tests (exit 5) — a run that tests nothing fails" >&2
elif [ "$rc" -ne 0 ]; then
    echo "run_tests: FAILED (pytest exit $rc)" >&2
fi
exit "$rc"
