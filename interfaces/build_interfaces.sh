#!/bin/bash
# Build the interface packages of interfaces/ into the venv $1, for a venv of the ROS 2 Jazzy
# PyPI wheels, which have neither of them:
#   tf2_msgs               TFMessage alone (the node's /tf, /tf_static);
#   simulation_interfaces  ROS 2's standard simulation services and the SimulateSteps
#                          action (the definitions of ros-simulation/simulation_interfaces,
#                          vendored: interfaces/simulation_interfaces/README.md).
# A package that can be imported already (a sourced ROS installation, or an earlier build) is
# not built; the others are built in one colcon call.  A build that cannot run (no cmake, no
# C/C++ compiler) is not an error: the node then runs without what the package gives and
# says so once in its log; this script says why in one line a package and exits 0.
#
# The build tools (colcon, ament_cmake, the rosidl generators: requirements-tf2.txt) go into
# a build venv of their own, $2 (default build/interfaces-venv, kept for the next build;
# `make clean` removes it), made from the same Python as $1: only the built packages (their
# libraries in lib/, their Python packages in site-packages, their share/ and include/) are
# copied into $1.  requirements-tf2.txt pins the ROS wheels both venvs share (the message
# packages they build on, the rosidl runtime, numpy) as requirements.txt does, so the copy
# finds in $1 the very libraries and numpy it was built against.
set -u
VENV=${1:-.venv}
VENV=$(cd "$VENV" && pwd)
PYTHON="$VENV/bin/python"
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(dirname "$HERE")
BUILD="$ROOT/build/interfaces"
BUILD_VENV=${2:-$ROOT/build/interfaces-venv}
# Each package (a directory of interfaces/) and what the node does without it.
PACKAGES=(tf2_msgs simulation_interfaces)
declare -A WITHOUT=(
    [tf2_msgs]='the node will run without TF (/tf, /tf_static)'
    [simulation_interfaces]='the node will run without the simulation services (simulation_interfaces)'
)

importable() {
    "$PYTHON" -c "import $1.msg" 2>/dev/null
}

# say_for_each PACKAGE... -- TEXT: one line a package, TEXT followed by what the node lacks.
say_for_each() {
    local packages=() package
    while [ "$1" != -- ]; do packages+=("$1"); shift; done
    shift
    for package in "${packages[@]}"; do
        echo "$package: $*: ${WITHOUT[$package]}"
    done
}

wanted=()
for package in "${PACKAGES[@]}"; do
    if importable "$package"; then
        echo "$package: already importable, not built"
    else
        wanted+=("$package")
    fi
done
[ ${#wanted[@]} -eq 0 ] && exit 0
for tool in cmake cc c++; do
    if ! command -v "$tool" >/dev/null; then
        say_for_each "${wanted[@]}" -- "not built, no $tool on PATH"
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
    say_for_each "${wanted[@]}" -- \
        "not built, the build wheels did not install in $BUILD_VENV (see $BUILD.pip.log)"
    exit 0
fi
# The message wheels' CMake exports name the include directories of the machine that built
# them (a manylinux image's /opt/python/cpXY-cpXY/...), which CMake refuses as missing: the
# build venv's interpreter has the same headers (Python.h, numpy's) at other paths.
python_include=$("$BUILD_VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
numpy_include=$("$BUILD_VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
foreign='/opt/python/cp[0-9]+-cp[0-9]+'
grep -rlE --include='*.cmake' "$foreign/" "$BUILD_VENV/share" | while read -r file; do
    sed -i -E \
        -e "s|$foreign/lib/python[0-9.]+/site-packages/numpy/_core/include|$numpy_include|g" \
        -e "s|$foreign/include/python[0-9.]+|$python_include|g" "$file"
done
rm -rf "$BUILD"
mkdir -p "$BUILD"
# The wheels' prefix is the build venv: CMake finds the packages there, ament_index its
# resources; its Python (with numpy) runs the generators and gives the headers.  The
# packages do not depend on each other: one that fails leaves the other built.
CMAKE_PREFIX_PATH="$BUILD_VENV" AMENT_PREFIX_PATH="$BUILD_VENV" "$BUILD_VENV/bin/colcon" \
    --log-base "$BUILD/log" build --base-paths "$HERE" --packages-select "${wanted[@]}" \
    --continue-on-error --build-base "$BUILD/build" --install-base "$BUILD/install" \
    --merge-install \
    --cmake-args "-DPython3_EXECUTABLE=$BUILD_VENV/bin/python" -DBUILD_TESTING=OFF \
    > "$BUILD/colcon.log" 2>&1
built=$?
if [ -d "$BUILD/install/share" ]; then
    # The build venv's path, recorded in the ament index (parent_prefix_path) and the CMake
    # exports (numpy's headers), becomes the run venv's: it holds the same pinned files.
    grep -rlF "$BUILD_VENV" "$BUILD/install/share" | while read -r file; do
        sed -i "s|$BUILD_VENV|$VENV|g" "$file"
    done
    # Laid out as the wheels are (libraries in lib/, the Python packages in site-packages),
    # so the venv's interpreter finds them as it finds geometry_msgs.
    for part in lib share include; do
        [ -d "$BUILD/install/$part" ] && cp -R "$BUILD/install/$part" "$VENV/"
    done
fi
for package in "${wanted[@]}"; do
    if importable "$package"; then
        echo "$package: built into $VENV in $(( $(date +%s) - started )) s"
    elif [ $built -ne 0 ]; then
        say_for_each "$package" -- "the build failed (see $BUILD/colcon.log)"
    else
        say_for_each "$package" -- "built but not importable (see $BUILD/colcon.log)"
    fi
done
exit 0
