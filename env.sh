# env.sh — `source env.sh` (bash) to use this workspace: venv + ROS 2 overlay + DDS settings.
# Works from any directory and under `set -euo pipefail`. Run `make setup` first.
#
# What it sets up:
#   - activates .venv (ROS 2 Jazzy wheels, colcon, numpy, ...)
#   - AMENT_PREFIX_PATH / CMAKE_PREFIX_PATH include the venv prefix (the wheels' ament index
#     lives there; colcon's setup.bash does not add it), then sources install/setup.bash
#   - LD_LIBRARY_PATH gets the venv's lib/ and site-packages/ros_*.libs, and
#     _ROS_WHEELS_BOOTSTRAP_COMPLETE=1, which is exactly what the wheels' .pth hook would do by
#     re-executing every Python process once; install/<pkg>/lib (generated message libraries)
#     comes from install/setup.bash. Child processes inherit all of it.
#   - NUMBA_CACHE_DIR=<repo>/build/numba_cache (the compiled cores, warmed by `make setup`)
#   - OPENBLAS_NUM_THREADS=1 unless set (small LAPACK calls: threads only cost here)
#   - ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, RMW_IMPLEMENTATION=rmw_fastrtps_cpp,
#     FASTRTPS_DEFAULT_PROFILES_FILE=<repo>/config/fastdds_profile.xml
#   - <repo>/scripts/bin (a stand-in `ros2` with the daily verbs) appended to PATH, unless a real
#     ros2cli is already on PATH.
# ROS_DOMAIN_ID is left as it is: choose one per run (scripts/run_tests.sh reserves one).

_pac_opts="$-"
set +eu

_pac_env_main() {
    local root venv p libs
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
    venv="$root/.venv"

    if [ ! -x "$venv/bin/python" ]; then
        echo "env.sh: $venv is missing — run 'make setup' (or scripts/setup.sh) first" >&2
        return 1
    fi
    # shellcheck disable=SC1091
    . "$venv/bin/activate"

    _pac_prepend() {  # _pac_prepend VAR DIR: put DIR first in VAR unless already present
        case ":${!1}:" in
        *":$2:"*) ;;
        *) export "$1=$2${!1:+:${!1}}" ;;
        esac
    }
    _pac_append() {
        case ":${!1}:" in
        *":$2:"*) ;;
        *) export "$1=${!1:+${!1}:}$2" ;;
        esac
    }

    _pac_prepend AMENT_PREFIX_PATH "$venv"
    _pac_prepend CMAKE_PREFIX_PATH "$venv"

    # What the wheels' ros_wheels_bootstrapper.pth would otherwise do in every Python process.
    libs="$venv/lib"
    for p in "$venv"/lib/python3.11/site-packages/ros_*.libs; do
        [ -d "$p" ] && libs="$libs:$p"
    done
    local IFS=:
    for p in $libs; do _pac_prepend LD_LIBRARY_PATH "$p"; done
    unset IFS
    export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1

    if [ -f "$root/install/setup.bash" ]; then
        # colcon's script reads COLCON_TRACE & co. unguarded; nounset is off here.
        # shellcheck disable=SC1091
        . "$root/install/setup.bash"
    else
        echo "env.sh: $root/install/setup.bash not found — run 'make setup' to build src/" >&2
    fi

    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    # numba's on-disk cache of the compiled cores: outside install/ (colcon rewrites it), git-ignored
    # (build/), filled by `make setup` (python -m pac_rig.warm) so no process compiles at start.
    export NUMBA_CACHE_DIR="$root/build/numba_cache"
    # Whole lines' solved dropper lengths (pac_plant/catenary/line_cache.py): a later run of the same
    # drawn line reads them instead of solving them again (keyed by the line's data and the solver's
    # code). PAC_LINE_CACHE= (empty) turns it off.
    export PAC_LINE_CACHE="${PAC_LINE_CACHE-$root/build/line_cache}"
    export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
    # One OpenBLAS thread unless told otherwise: pac's LAPACK calls are small (observer and law
    # designs at a node's start, an FE line's static solve); with OpenBLAS's default threads
    # a 10x10 expm took 16 ms on this shared 2-core VM (its threads wait for a busy core),
    # 0.08 ms with one (docs/numerics.md, "Where the time goes").
    export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
    export FASTRTPS_DEFAULT_PROFILES_FILE="$root/config/fastdds_profile.xml"

    # The stand-in ros2 (scripts/bin/ros2) unless a real ros2cli is already on PATH.
    p="$(command -v ros2 2>/dev/null || true)"
    if [ -z "$p" ] || [ "$p" = "$root/scripts/bin/ros2" ]; then
        _pac_append PATH "$root/scripts/bin"
    fi
    hash -r 2>/dev/null
    unset -f _pac_prepend _pac_append
    return 0
}

_pac_env_main
_pac_rc=$?
unset -f _pac_env_main
case "$_pac_opts" in *e*) set -e ;; esac
case "$_pac_opts" in *u*) set -u ;; esac
unset _pac_opts
if [ "$_pac_rc" -eq 0 ]; then unset _pac_rc; true; else unset _pac_rc; false; fi
