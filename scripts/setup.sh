#!/usr/bin/env bash
# scripts/setup.sh — make the workspace usable: .venv with ROS 2 Jazzy from PyPI, then colcon build.
#
# Idempotent; safe to run any number of times from any directory.
#   1. .venv at the repo root from Python 3.11 (PAC_PYTHON overrides the interpreter).
#   2. pip install -r requirements.lock, skipped while .venv/.pac-installed holds the lock's hash.
#      A changed lock recreates the venv from scratch, so removed pins do not linger.
#   3. The ros-jazzy-* wheels were built in a manylinux container: ~20 *.cmake files under
#      .venv/share name /opt/python/cp311-cp311/include/python3.11 and .../numpy/_core/include.
#      CMake rejects those paths, so they are rewritten to this venv's Python include dir and
#      numpy include dir. (The 88 files in share/ament_index/resource_index/parent_prefix_path/
#      also say /opt/python/cp311-cp311; nothing in a colcon isolated workspace reads them, so
#      they are left alone.) Checked on every run (a grep, well under 0.3 s).
#   4. colcon build of every package under src/ into build/ install/ log/ at the repo root,
#      skipped while build/.pac-build-stamp matches a signature of src/ (every file's path,
#      size and mtime), requirements.lock and this script. Any added, removed or edited file
#      under src/ (.py, .msg, ...) triggers the (incremental) colcon build.
#
# Timings measured on the 2-core Debian 12 machine (warm pip cache; a cold cache adds the
# wheel downloads):
#   from scratch (no .venv build install log): 54-63 s = venv+pip 32-38 s, colcon 21-24 s
#                                               (pac_interfaces alone 14-17 s)
#   second run, nothing changed:                0.05-0.1 s
#   after touching a file under src/:           6-7 s (colcon re-runs all 6 packages; the
#                                               ament_python ones take ~1.5-2.5 s each)
set -eo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
LOCK="$ROOT/requirements.lock"
INSTALL_STAMP="$VENV/.pac-installed"
BUILD_STAMP="$ROOT/build/.pac-build-stamp"
MANYLINUX_PREFIX="/opt/python/cp311-cp311"
cd "$ROOT"

log() { printf 'setup: %s\n' "$*" >&2; }
die() { printf 'setup: ERROR: %s\n' "$*" >&2; exit 1; }
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f s", b - a }'; }
T0="$(now)"

[ -f "$LOCK" ] || die "missing $LOCK"

# ---------------------------------------------------------------- 1. interpreter + venv
pick_python() {
    local c
    for c in ${PAC_PYTHON:-} python3.11 python3; do
        if command -v "$c" >/dev/null 2>&1 &&
            "$c" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
            command -v "$c"
            return 0
        fi
    done
    return 1
}

venv_ok() {
    # No Python start-up here: this is the fast path of a no-op run.
    [ -x "$VENV/bin/python" ] && [ -f "$VENV/pyvenv.cfg" ] &&
        grep -Eq '^version(_info)? *= *3\.11\.' "$VENV/pyvenv.cfg"
}

lock_hash="$(sha256sum "$LOCK" | cut -d' ' -f1)"
want_stamp="lock=$lock_hash"

if ! venv_ok || [ "$(cat "$INSTALL_STAMP" 2>/dev/null)" != "$want_stamp" ]; then
    t="$(now)"
    PY="$(pick_python)" || die "need Python 3.11 (python3.11 or python3 on PATH, or PAC_PYTHON=...)"
    log "creating .venv from $PY ($("$PY" --version 2>&1))"
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
    pip_pin="$(grep -E '^pip==' "$LOCK" || true)"
    if [ -n "$pip_pin" ]; then
        "$VENV/bin/python" -m pip install -q --disable-pip-version-check "$pip_pin"
    fi
    log "installing requirements.lock (ros-jazzy-* wheels, colcon, numpy, ...)"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$LOCK"
    log "venv + install: $(since "$t")"
    FRESH_INSTALL=1
else
    FRESH_INSTALL=0
fi

# ---------------------------------------------------------------- 2. manylinux path fix
fix_manylinux_paths() {
    local files=() left=() py_inc np_inc
    mapfile -t files < <(grep -rlF "$MANYLINUX_PREFIX" "$VENV/share" "$VENV/lib/cmake" \
        --exclude-dir=parent_prefix_path 2>/dev/null || true)
    [ "${#files[@]}" -gt 0 ] || return 0
    py_inc="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
    np_inc="$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
    [ -f "$py_inc/Python.h" ] ||
        die "no Python.h in $py_inc (install the Python 3.11 headers, e.g. apt-get install python3.11-dev)"
    [ -d "$np_inc/numpy" ] || die "numpy include dir $np_inc not found"
    sed -i \
        -e "s|$MANYLINUX_PREFIX/include/python3\.11|$py_inc|g" \
        -e "s|$MANYLINUX_PREFIX/lib/python3\.11/site-packages/numpy/_core/include|$np_inc|g" \
        "${files[@]}"
    mapfile -t left < <(grep -lF "$MANYLINUX_PREFIX" "${files[@]}" || true)
    [ "${#left[@]}" -eq 0 ] || die "unhandled $MANYLINUX_PREFIX paths remain in: ${left[*]}"
    log "rewrote manylinux paths in ${#files[@]} files -> $py_inc, $np_inc"
}
fix_manylinux_paths

if [ "$FRESH_INSTALL" = 1 ]; then
    printf '%s\n' "$want_stamp" >"$INSTALL_STAMP"
fi

# ---------------------------------------------------------------- 3. colcon build
src_signature() {
    {
        printf 'lock=%s\n' "$lock_hash"
        sha256sum "$ROOT/scripts/setup.sh"
        if [ -d "$ROOT/src" ]; then
            find "$ROOT/src" \( -name __pycache__ -o -name '*.egg-info' -o -name .pytest_cache \) \
                -prune -o -type f -printf '%P\t%s\t%T@\n' | LC_ALL=C sort
        fi
    } | sha256sum | cut -d' ' -f1
}

# Drop this workspace's install/ entries (left by a sourced env.sh) from a path-like variable,
# then put the venv prefix in front.
with_venv_prefix() {
    local IFS=: out="$VENV" p
    for p in ${!1:-}; do
        case "$p" in "" | "$VENV" | "$ROOT/install" | "$ROOT/install/"*) continue ;; esac
        out="$out:$p"
    done
    printf '%s' "$out"
}
without_install() {
    local IFS=: out="" p
    for p in ${!1:-}; do
        case "$p" in "" | "$ROOT/install" | "$ROOT/install/"*) continue ;; esac
        out="${out:+$out:}$p"
    done
    printf '%s' "$out"
}

# 5. numba cache of the compiled cores (build/numba_cache, NUMBA_CACHE_DIR in env.sh): emptied and
#    refilled by `python -m pac_rig.warm` whenever the build signature changes. Emptied first
#    because numba keys a cached function on its own file only: a changed callee in another file
#    (e.g. pac_model/model.py) would otherwise leave its callers' cached code stale.
WARM_DIR="$ROOT/build/numba_cache"
WARM_STAMP="$WARM_DIR/.pac-warm-stamp"
warm_numba_cache() {
    local t
    [ "$(cat "$WARM_STAMP" 2>/dev/null)" = "$1" ] && return 0
    t="$(now)"
    rm -rf "$WARM_DIR"
    mkdir -p "$WARM_DIR"
    log "compiling the cores into $WARM_DIR (numba; ~1 min, longer on a busy machine)"
    "$ROOT/scripts/with_env.sh" python -m pac_rig.warm >&2 || die "python -m pac_rig.warm failed"
    printf '%s\n' "$1" >"$WARM_STAMP"
    log "numba cache: $(since "$t")"
}

sig="$(src_signature)"
if [ -f "$ROOT/install/setup.bash" ] && [ "$(cat "$BUILD_STAMP" 2>/dev/null)" = "$sig" ]; then
    warm_numba_cache "$sig"
    log "up to date (nothing under src/ changed) — $(since "$T0")"
    exit 0
fi

if [ ! -d "$ROOT/src" ] || [ -z "$(find "$ROOT/src" -name package.xml -print -quit)" ]; then
    log "no packages under src/ — nothing to build"
    exit 0
fi

t="$(now)"
export AMENT_PREFIX_PATH CMAKE_PREFIX_PATH COLCON_PREFIX_PATH PYTHONPATH PATH
AMENT_PREFIX_PATH="$(with_venv_prefix AMENT_PREFIX_PATH)"
CMAKE_PREFIX_PATH="$(with_venv_prefix CMAKE_PREFIX_PATH)"
COLCON_PREFIX_PATH="$(without_install COLCON_PREFIX_PATH)"
PYTHONPATH="$(without_install PYTHONPATH)"
PATH="$VENV/bin:$PATH"
[ -n "$COLCON_PREFIX_PATH" ] || unset COLCON_PREFIX_PATH
[ -n "$PYTHONPATH" ] || unset PYTHONPATH

log "colcon build (src/ -> build/ install/ log/)"
# PYTHONDONTWRITEBYTECODE (set in some shells) only makes setuptools warn on every package.
env -u PYTHONDONTWRITEBYTECODE "$VENV/bin/colcon" --log-base "$ROOT/log" build \
    --base-paths "$ROOT/src" \
    --build-base "$ROOT/build" \
    --install-base "$ROOT/install" \
    --event-handlers desktop_notification- status- \
    --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF
printf '%s\n' "$sig" >"$BUILD_STAMP"
log "colcon build: $(since "$t")"
warm_numba_cache "$sig"
log "total $(since "$T0")"
