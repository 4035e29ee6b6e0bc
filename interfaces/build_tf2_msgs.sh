#!/bin/bash
# Build tf2_msgs (TFMessage only, interfaces/tf2_msgs) into the venv $1, for a venv of the
# ROS 2 Jazzy PyPI wheels, which have no tf2_msgs.  Where a tf2_msgs can be imported already
# (a sourced ROS installation, or an earlier build) nothing is done.  A build that cannot
# run (no cmake, no C/C++ compiler) is not an error: the node then runs without TF and says
# so once in its log; this script says why in one line and exits 0.
set -u
VENV=${1:-.venv}
VENV=$(cd "$VENV" && pwd)
PYTHON="$VENV/bin/python"
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(dirname "$HERE")
BUILD="$ROOT/build/tf2_msgs"

if "$PYTHON" -c 'import tf2_msgs.msg' 2>/dev/null; then
    echo "tf2_msgs: already importable, not built"
    exit 0
fi
for tool in cmake cc c++; do
    if ! command -v "$tool" >/dev/null; then
        echo "tf2_msgs: not built, no $tool on PATH: the node will run without TF (/tf, /tf_static)"
        exit 0
    fi
done
started=$(date +%s)
mkdir -p "$ROOT/build"
if ! "$PYTHON" -m pip install --quiet -r "$ROOT/requirements-tf2.txt" > "$BUILD.pip.log" 2>&1; then
    echo "tf2_msgs: not built, the build wheels did not install (see $BUILD.pip.log): the node will run without TF"
    exit 0
fi
rm -rf "$BUILD"
mkdir -p "$BUILD"
# The wheels' prefix is the venv: CMake finds the packages there, ament_index its resources.
if ! CMAKE_PREFIX_PATH="$VENV" AMENT_PREFIX_PATH="$VENV" "$VENV/bin/colcon" \
        --log-base "$BUILD/log" build --base-paths "$HERE" \
        --build-base "$BUILD/build" --install-base "$BUILD/install" --merge-install \
        --cmake-args "-DPython3_EXECUTABLE=$PYTHON" -DBUILD_TESTING=OFF \
        > "$BUILD/colcon.log" 2>&1; then
    echo "tf2_msgs: the build failed (see $BUILD/colcon.log): the node will run without TF"
    exit 0
fi
# Laid out as the wheels are (libraries in lib/, the Python package in site-packages), so
# the venv's interpreter finds it as it finds geometry_msgs.
cp -R "$BUILD/install/lib" "$BUILD/install/share" "$BUILD/install/include" "$VENV/"
if "$PYTHON" -c 'import tf2_msgs.msg' 2>/dev/null; then
    echo "tf2_msgs: built into $VENV in $(( $(date +%s) - started )) s"
else
    echo "tf2_msgs: built but not importable (see $BUILD/colcon.log): the node will run without TF"
fi
exit 0
