#!/usr/bin/env bash
# Set up everything `make test` and `make demo` need, idempotently:
#   1. a venv under .venv with ROS 2 Jazzy wheels pinned by constraints.txt;
#   2. the include paths of the wheels' build host rewritten in their CMake exports;
#   3. extended_tracker_msgs built with ament_cmake + rosidl and installed into the venv,
#      and tf2_msgs's TFMessage (tools/tf2_msgs) where the venv has no tf2_msgs;
#   4. this package installed with its `ros2 run` executable under
#      .venv/lib/extended_tracker.
# A step whose stamp file is newer than its inputs is skipped, so a second run takes seconds.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
venv=${EXTENDED_TRACKER_VENV:-$root/.venv}
python=${PYTHON:-}
stamps=$venv/.stamps
msgs_src=$root/interfaces/extended_tracker_msgs

log() { printf '[bootstrap] %s\n' "$*"; }
# pip warns once per package about absent local mirror folders in this machine's pip.conf.
quiet_pip() { grep -v "^WARNING: Location 'file://" || true; }

# Stay on loopback whatever happens below.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY

newer() {  # newer STAMP FILE...: true when STAMP is missing or older than a FILE
  local stamp=$1; shift
  [ -f "$stamp" ] || return 0
  local f
  for f in "$@"; do
    [ "$f" -nt "$stamp" ] && return 0
  done
  return 1
}

# The ROS wheels are cp311, and the message build needs the interpreter's headers. Among
# the 3.11 interpreters that have them, the distribution's comes first: its executable has
# the interpreter linked in, where a --enable-shared build (pyenv's, for one) calls it
# through libpython.so; the filter step ran 8-10 % faster on it (README, Performance).
# PYTHON=... overrides the choice; BOOTSTRAP_PYTHONS="a b ..." replaces the candidates (tests).
usable() {
  "$1" -c 'import ensurepip, os, sys, sysconfig, venv
sys.exit(sys.version_info[:2] != (3, 11)
         or not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
    2>/dev/null
}
if [ ! -x "$venv/bin/python" ]; then
  # an existing venv is kept: the interpreter is chosen only when one is made
  if [ -z "$python" ]; then
    for candidate in ${BOOTSTRAP_PYTHONS:-/usr/bin/python3.11 python3.11 python3}; do
      if command -v "$candidate" >/dev/null && usable "$candidate"; then
        python=$candidate
        break
      fi
    done
    if [ -z "$python" ]; then
      log 'no Python 3.11 with its headers (python3.11-dev) and venv/ensurepip found;' \
          'install one or name it with PYTHON=/path/to/python3.11'
      exit 1
    fi
  fi
  log "creating venv at $venv with $python ($("$python" -c 'import sys; print(sys.version.split()[0])'))"
  "$python" -m venv "$venv"
fi
mkdir -p "$stamps"
vpy=$venv/bin/python

if newer "$stamps/wheels" "$root/constraints.txt" "$root/requirements.txt"; then
  log 'installing pinned wheels (ROS 2 Jazzy, numpy, scipy, rosbags, test tools)'
  "$vpy" -m pip install --quiet -c "$root/constraints.txt" setuptools wheel 2> >(quiet_pip >&2)
  "$vpy" -m pip install --quiet -c "$root/constraints.txt" -r "$root/requirements.txt" 2> >(quiet_pip >&2)
  rm -f "$stamps/cmake-paths" "$stamps/msgs"
  touch "$stamps/wheels"
fi

if [ ! -f "$stamps/cmake-paths" ]; then
  # The wheels were built under /opt/python/cp311-cp311; point their exports at this host.
  log 'rewriting build-host include paths in the wheels CMake exports'
  py_inc=$("$vpy" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  np_inc=$("$vpy" -c 'import numpy; print(numpy.get_include())')
  grep -rl --include='*.cmake' '/opt/python/cp311-cp311' "$venv/share" 2>/dev/null \
    | while read -r f; do
        sed -i \
          -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_inc#g" \
          -e "s#/opt/python/cp311-cp311/include/python3.11#$py_inc#g" "$f"
      done
  touch "$stamps/cmake-paths"
fi

build_interfaces() {  # build_interfaces NAME SOURCE: ament_cmake + rosidl into the venv
  local name=$1 src=$2 dir=$root/build/$1
  log "building $name (ament_cmake + rosidl)"
  rm -rf "$dir"
  mkdir -p "$dir"
  (
    export AMENT_PREFIX_PATH=$venv
    export CMAKE_PREFIX_PATH=$venv
    export PATH=$venv/bin:$PATH
    cmake -S "$src" -B "$dir" -DCMAKE_INSTALL_PREFIX="$venv" \
      -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$vpy" \
      > "$dir/configure.log" 2>&1 || { tail -40 "$dir/configure.log"; exit 1; }
    cmake --build "$dir" -j "$(nproc)" > "$dir/build.log" 2>&1 \
      || { tail -40 "$dir/build.log"; exit 1; }
    cmake --install "$dir" > "$dir/install.log" 2>&1 \
      || { tail -40 "$dir/install.log"; exit 1; }
  )
}

if newer "$stamps/msgs" "$msgs_src"/msg/*.msg "$msgs_src/CMakeLists.txt" "$msgs_src/package.xml"; then
  build_interfaces extended_tracker_msgs "$msgs_src"
  touch "$stamps/msgs"
fi

# No tf2_msgs wheel exists: build its TFMessage only where the venv lacks the package
# (a venv on a ROS install's Python, or a later wheel, has it).
tf_src=$root/tools/tf2_msgs
if [ -f "$stamps/tf2_msgs" ] && newer "$stamps/tf2_msgs" "$tf_src"/msg/*.msg "$tf_src/CMakeLists.txt"; then
  rm -f "$stamps/tf2_msgs"
fi
if [ ! -f "$stamps/tf2_msgs" ] && ! "$vpy" -c 'import tf2_msgs.msg' 2>/dev/null; then
  build_interfaces tf2_msgs "$tf_src"
  touch "$stamps/tf2_msgs"
fi

# A regular (not editable) install, so that data_files (ament index marker, package.xml,
# config, launch, rviz) land in the prefix as on a colcon install; re-run whenever a package file changes.
mapfile -t package_files < <(find "$root/extended_tracker" "$root/config" "$root/launch" "$root/rviz" \
  -type f \( -name '*.py' -o -name '*.yaml' -o -name '*.rviz' -o -name 'py.typed' \))
if newer "$stamps/package" "$root/setup.py" "$root/setup.cfg" "$root/package.xml" \
    "$root/resource/extended_tracker" "${package_files[@]}"; then
  log 'installing extended_tracker'
  "$vpy" -m pip install --quiet --no-deps --no-build-isolation "$root" 2> >(quiet_pip >&2)
  # `ros2 run PKG EXE` runs <prefix>/lib/PKG/EXE; colcon puts console scripts there via
  # setup.cfg, a pip install puts them in bin/, so link the same script into place.
  mkdir -p "$venv/lib/extended_tracker"
  ln -sf "$venv/bin/tracker_node" "$venv/lib/extended_tracker/tracker_node"
  touch "$stamps/package"
fi
log "ready: $venv"
