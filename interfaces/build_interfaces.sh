#!/bin/bash
# Build tf2_msgs (TFMessage only, interfaces/tf2_msgs) into the venv $1, for a venv of the
# ROS 2 Jazzy PyPI wheels, which have no tf2_msgs.  Where a tf2_msgs can be imported already
# (a sourced ROS installation, or an earlier build) nothing is done.  A build that cannot
# run (no cmake, no C/C++ compiler) is not an error: the node then runs without TF and says
# so once in its log; this script says why in one line and exits 0.
#
# The build tools (colcon, ament_cmake, the rosidl generators: requirements-tf2.txt) go into
# a build venv of their own, $2 (default build/tf2_msgs-venv, kept for the next build;
# `make clean` removes it), made from the same Python as $1: only the built tf2_msgs (its
# libraries in lib/, its Python package in site-packages, its share/ and include/) is copied
# into $1.  requirements-tf2.txt pins the ROS wheels both venvs share (geometry_msgs, the
# rosidl runtime, numpy) as requirements.txt does, so the copy finds in $1 the very
# libraries and numpy it was built against.
set -u
VENV=${1:-.venv}
VENV=$(cd "$VENV" && pwd)
PYTHON="$VENV/bin/python"
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(dirname "$HERE")
BUILD="$ROOT/build/tf2_msgs"
BUILD_VENV=${2:-$ROOT/build/tf2_msgs-venv}

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
mkdir -p "$(dirname "$BUILD_VENV")" "$ROOT/build"
BUILD_VENV="$(cd "$(dirname "$BUILD_VENV")" && pwd)/$(basename "$BUILD_VENV")"
# The build venv's Python is the run venv's own interpreter (python -m venv from a venv
# makes a venv of its base Python), so the extension modules built get the same ABI tag; a
# build venv left by another Python is made again.
which_python='import sys; print(sys.base_prefix, sys.version)'
if [ -x "$BUILD_VENV/bin/python" ] && [ "$("$BUILD_VENV/bin/python" -c "$which_python")" \
        != "$("$PYTHON" -c "$which_python")" ]; then
    rm -rf "$BUILD_VENV"
fi
if ! { { [ -x "$BUILD_VENV/bin/python" ] || "$PYTHON" -m venv "$BUILD_VENV"; } \
        && "$BUILD_VENV/bin/python" -m pip install --quiet -r "$ROOT/requirements-tf2.txt"; } \
        > "$BUILD.pip.log" 2>&1; then
    echo "tf2_msgs: not built, the build wheels did not install in $BUILD_VENV (see $BUILD.pip.log): the node will run without TF"
    exit 0
fi
rm -rf "$BUILD"
mkdir -p "$BUILD"
# The wheels' prefix is the build venv: CMake finds the packages there, ament_index its
# resources; its Python (with numpy) runs the generators and gives the headers.
if ! CMAKE_PREFIX_PATH="$BUILD_VENV" AMENT_PREFIX_PATH="$BUILD_VENV" "$BUILD_VENV/bin/colcon" \
        --log-base "$BUILD/log" build --base-paths "$HERE" \
        --build-base "$BUILD/build" --install-base "$BUILD/install" --merge-install \
        --cmake-args "-DPython3_EXECUTABLE=$BUILD_VENV/bin/python" -DBUILD_TESTING=OFF \
        > "$BUILD/colcon.log" 2>&1; then
    echo "tf2_msgs: the build failed (see $BUILD/colcon.log): the node will run without TF"
    exit 0
fi
# The build venv's path, recorded in the ament index (parent_prefix_path) and the CMake
# exports (numpy's headers), becomes the run venv's: it holds the same pinned files.
grep -rlF "$BUILD_VENV" "$BUILD/install/share" | while read -r file; do
    sed -i "s|$BUILD_VENV|$VENV|g" "$file"
done
# Laid out as the wheels are (libraries in lib/, the Python package in site-packages), so
# the venv's interpreter finds it as it finds geometry_msgs.
cp -R "$BUILD/install/lib" "$BUILD/install/share" "$BUILD/install/include" "$VENV/"
if "$PYTHON" -c 'import tf2_msgs.msg' 2>/dev/null; then
    echo "tf2_msgs: built into $VENV in $(( $(date +%s) - started )) s"
else
    echo "tf2_msgs: built but not importable (see $BUILD/colcon.log): the node will run without TF"
fi
exit 0
