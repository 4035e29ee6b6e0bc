# Two commands on a clean machine: `make run` and `make test`.
# Both create (or reuse) .venv from the pinned requirements.txt and install this package
# into it in editable mode; the stamp .venv/.installed is redone when the inputs change.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# tf2_msgs (TF) built into the venv where cmake and a C/C++ compiler exist: interfaces/.
TF2_STAMP := $(VENV)/.tf2_msgs
PYTEST_ARGS ?=
NODE_ARGS ?=

.PHONY: venv run test clean

venv: $(STAMP) $(TF2_STAMP)

$(STAMP): requirements.txt setup.py setup.cfg package.xml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -r requirements.txt
	$(BIN)/python -m pip install --no-deps -e .
	touch $@

$(TF2_STAMP): $(STAMP) requirements-tf2.txt interfaces/build_tf2_msgs.sh \
		interfaces/tf2_msgs/package.xml interfaces/tf2_msgs/CMakeLists.txt \
		interfaces/tf2_msgs/msg/TFMessage.msg
	interfaces/build_tf2_msgs.sh $(VENV)
	touch $@

run: $(STAMP) $(TF2_STAMP)
	@echo 'Starting rigid_body_node with the default scene: a T-handle spun near its unstable'
	@echo 'middle axis. It first flips over after ~7.2 s, then every ~14.4 s. Look at it (and'
	@echo 'push it) from another terminal with ROS 2 Jazzy sourced:'
	@echo '  ros2 topic echo /odom --field twist.twist.angular   body angular velocity: y flips sign'
	@echo '  ros2 topic echo /angular_momentum                   world-frame L: stays constant'
	@echo '  rviz2 -f world                                      add a Marker display on /marker'
	@echo '  ros2 topic echo /diagnostics                        rate, step time, drift'
	@echo '  ros2 topic pub --once /torque geometry_msgs/msg/Vector3Stamped "{vector: {z: 0.5}}"'
	@echo 'Other scenes: .venv/bin/rigid-body-sim scenes, then make run NODE_ARGS="--ros-args -p scene:=heavy_top"'
	@echo 'Ctrl-C stops it. The offline summary without ROS: .venv/bin/rigid-body-sim run'
	$(BIN)/rigid_body_node $(NODE_ARGS)

test: export ROS_AUTOMATIC_DISCOVERY_RANGE = LOCALHOST
test: $(STAMP) $(TF2_STAMP)
	@# The numba kernels first (cached; ~40 s on a fresh clone, under 2 s after), so that
	@# no test's node spends its start-up compiling them.
	$(BIN)/rigid-body-sim compile
	$(BIN)/python -m pytest test -q -n 2 --dist loadgroup $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build install log .pytest_cache *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
