#!/usr/bin/env bash
# One-time, idempotent set-up of StylePong on Debian/Ubuntu with Python 3.11 (called by `make setup`):
#   1. system build tools (cmake, g++, make) from apt, only where missing;
#   2. a virtual environment in .venv with the exact versions of requirements.lock (reinstalled only
#      when that file changes);
#   3. the venv made into a ROS 2 Jazzy underlay (what /opt/ros/jazzy would be);
#   4. a `ros2` command for the venv, unless a real ros2cli is present;
#   5. colcon build of ros2_ws.
# With ROS_UNDERLAY=/opt/ros/jazzy (a real Jazzy install) steps 2-4 are replaced by that underlay.
set -eo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
LOCK=$ROOT/requirements.lock
say() { printf '[setup] %s\n' "$*"; }

apt_install() {
  local sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
  say "installing from apt: $*"
  $sudo apt-get update -qq && $sudo apt-get install -y -qq "$@"
}

# 1. System tools -------------------------------------------------------------------------------
missing=()
command -v cmake >/dev/null || missing+=(cmake)
command -v g++ >/dev/null || missing+=(g++)
command -v make >/dev/null || missing+=(make)
[ ${#missing[@]} -eq 0 ] || apt_install "${missing[@]}"

if [ -n "${ROS_UNDERLAY:-}" ]; then
  say "using the ROS underlay $ROS_UNDERLAY instead of the PyPI wheels"
  # shellcheck disable=SC1091
  source "$ROS_UNDERLAY/setup.bash"
  PYTHON=python3
else
  # 2. Virtual environment ----------------------------------------------------------------------
  PY=${PYTHON311:-$(command -v python3.11 || true)}
  if [ -z "$PY" ]; then
    PY=$(command -v python3 || true)
    "$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null || {
      echo "[setup] Python 3.11 is required (the ROS 2 Jazzy wheels are cp311 only)." >&2
      echo "[setup] Install it (apt install python3.11 python3.11-venv) or set PYTHON311=/path/to/python3.11." >&2
      exit 1; }
  fi
  stamp=$VENV/.requirements.sha256
  want=$(sha256sum "$LOCK" | cut -d' ' -f1)
  if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    say "creating $VENV from requirements.lock (a few minutes the first time)"
    if [ ! -x "$VENV/bin/python" ]; then
      # Debian/Ubuntu ship venv's ensurepip separately.
      "$PY" -c 'import ensurepip' 2>/dev/null || apt_install "python3.11-venv"
      "$PY" -m venv "$VENV"
    fi
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$LOCK"
    rm -f "$VENV/.underlay-done"
    echo "$want" > "$stamp"
  fi
  PYTHON=$VENV/bin/python

  # 3. The venv as a ROS underlay ---------------------------------------------------------------
  underlay=$(sha256sum "$ROOT/tools/make_underlay.py" | cut -d' ' -f1)
  if [ "$(cat "$VENV/.underlay-done" 2>/dev/null)" != "$underlay" ]; then
    say "making $VENV a ROS 2 Jazzy underlay"
    "$PYTHON" "$ROOT/tools/make_underlay.py" "$VENV"
    echo "$underlay" > "$VENV/.underlay-done"
  fi
  # 4. ros2 command -----------------------------------------------------------------------------
  if ! "$PYTHON" -c 'import ros2cli' 2>/dev/null && [ ! -f "$VENV/bin/ros2" ]; then
    printf '#!/bin/sh\nexec "%s" "%s" "$@"\n' "$PYTHON" "$ROOT/tools/ros2" > "$VENV/bin/ros2"
    chmod +x "$VENV/bin/ros2"
  fi
  # shellcheck disable=SC1091
  source "$VENV/setup.bash"
fi

# 5. Workspace ----------------------------------------------------------------------------------
cd "$ROOT/ros2_ws"
say "colcon build"
# One build at a time: parallel `make setup` calls would write the same install tree.
exec 9>"$ROOT/ros2_ws/.build.lock"
flock 9
# A source file moved or deleted since the last build leaves a dangling link in the --symlink-install
# trees, which a package's setup.py then fails to copy (glob('config/*.yaml') still lists it): drop them.
find "$ROOT/ros2_ws/build" "$ROOT/ros2_ws/install" -xtype l -delete 2>/dev/null || true
# ros2_ws/src/tf2_msgs stands in for tf2_msgs where the underlay has none (the PyPI wheels); a real ROS
# underlay's own tf2_msgs (with its service and action) must not be shadowed.
skip=()
if [ -n "${ROS_UNDERLAY:-}" ] && [ -d "$ROS_UNDERLAY/share/tf2_msgs" ]; then skip=(--packages-skip tf2_msgs); fi
colcon --log-base log build --symlink-install --event-handlers console_cohesion- status- summary+ "${skip[@]}" \
  --cmake-args -DPython3_EXECUTABLE="$PYTHON" -DBUILD_TESTING=OFF
say "done: source ros2_ws/install/setup.bash"
