#!/usr/bin/env bash
# scripts/with_env.sh CMD [ARGS...] — run CMD inside the workspace environment (env.sh).
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$ROOT/env.sh"
[ "$#" -gt 0 ] || { echo "usage: scripts/with_env.sh CMD [ARGS...]" >&2; exit 2; }
exec "$@"
