# Two commands on a clean machine: `make run` and `make test`.
# Both create (or reuse) .venv from the pinned run-time set requirements.txt and install this
# package into it in editable mode; the stamp .venv/.installed is redone when the inputs
# change.  `make test` adds the test set requirements-test.txt (pytest, hypothesis, mujoco,
# colcon, the linters, the type checker mypy), stamped .venv/.installed-test.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
# The interface packages of interfaces/ (tf2_msgs for TF, simulation_interfaces for the
# standard simulation services) built into the venv where cmake and a C/C++ compiler exist.
# Their build tools (requirements-tf2.txt) go into a build venv of their own, not into .venv.
INTERFACES_STAMP := $(VENV)/.interfaces
INTERFACES_BUILD_VENV := build/interfaces-venv
INTERFACE_FILES := $(wildcard interfaces/*/package.xml interfaces/*/CMakeLists.txt \
	interfaces/*/msg/*.msg interfaces/*/srv/*.srv interfaces/*/action/*.action)
PYTEST_ARGS ?=
NODE_ARGS ?=

.PHONY: venv run test clean

venv: $(STAMP) $(INTERFACES_STAMP)

$(STAMP): requirements.txt setup.py setup.cfg package.xml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -r requirements.txt
	$(BIN)/python -m pip install --no-deps -e .
	touch $@

$(INTERFACES_STAMP): $(STAMP) requirements-tf2.txt interfaces/build_interfaces.sh \
		$(INTERFACE_FILES)
	interfaces/build_interfaces.sh $(VENV) $(INTERFACES_BUILD_VENV)
	touch $@

$(TEST_STAMP): $(STAMP) requirements-test.txt
	$(BIN)/python -m pip install -r requirements-test.txt
	touch $@

run: $(STAMP) $(INTERFACES_STAMP)
	@echo 'Starting rigid_body_node with the default scene: a T-handle spun near its unstable'
	@echo 'middle axis. It first flips over after ~7.2 s, then every ~14.4 s.'
	@echo 'Watch it live from another terminal in this directory (nothing else to install):'
	@echo '  .venv/bin/rigid-body-sim watch              a window: the body turning, its angular'
	@echo '                                              velocity, the drift, the node'"'"'s cost'
	@echo '  .venv/bin/rigid-body-sim watch --terminal   the same numbers, refreshed in place'
	@echo 'With ROS 2 Jazzy sourced, the ROS tools see it too:'
	@echo '  ros2 topic echo /odom --field twist.twist.angular   body angular velocity: y flips sign'
	@echo '  ros2 topic pub --once /torque geometry_msgs/msg/Vector3Stamped "{vector: {z: 0.5}}"'
	@echo '  rviz2 -d rviz/rigid_body_sim.rviz                   TF, the body, odometry (docs/launch.md);'
	@echo '  .venv/bin/angular_momentum_arrow                    and L as an arrow in it'
	@echo 'Other scenes: .venv/bin/rigid-body-sim scenes, then make run NODE_ARGS="--ros-args -p scene:=heavy_top"'
	@echo 'Ctrl-C stops it. The offline summary without DDS: .venv/bin/rigid-body-sim run'
	@echo 'On a machine that never compiled its numba kernels, the node starts with their source'
	@echo 'interpreted (the same steps, slower) and switches to them once a compile beside it'
	@echo 'is done (about a minute on 2 cores, once per machine: .venv/bin/rigid-body-sim compile).'
	$(BIN)/rigid_body_node $(NODE_ARGS)

test: export ROS_AUTOMATIC_DISCOVERY_RANGE = LOCALHOST
test: $(STAMP) $(INTERFACES_STAMP) $(TEST_STAMP)
	@# Every numba kernel, compiled once per machine and per version of the sources (about a
	@# minute on 2 cores; nothing when they are), so that no test waits for one.
	$(BIN)/rigid-body-sim compile
	$(BIN)/python -m pytest test -q -n 2 --dist loadgroup $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build install log .pytest_cache *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
