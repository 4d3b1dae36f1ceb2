# flask-move-server: the two commands a new user runs are `make demo` and `make test`.
# Each installs what it needs on a fresh Debian bookworm machine (apt for ROS 1, a venv for the rest).

SHELL := /bin/bash
SYSTEM_PYTHON ?= /usr/bin/python3
VENV ?= .venv
DEBIAN_VENV ?= .venv-debian
PY := $(VENV)/bin/python
PYTEST_ARGS ?=
# Two workers (pytest-xdist): the browser's modules in one lane, the other real-time modules (sims,
# roslaunch stacks, brokers) in another, every other module whole on whichever worker is free
# (tests/conftest.py). `make test XDIST=` runs in one process.
XDIST ?= -n 2 --dist loadscope

# ROS 1 from Debian (on Ubuntu 20.04 + Noetic these come from /opt/ros/noetic instead), and numpy
# (the explorer's frontier search: Debian's and Raspberry Pi OS's python3-numpy).
ROS_DEBS := python3-rospy python3-rosmaster python3-roslaunch python3-rosgraph python3-actionlib \
	python3-move-base-msgs python3-tf2-ros python3-geometry-msgs python3-nav-msgs \
	python3-sensor-msgs python3-visualization-msgs python3-std-msgs python3-venv iproute2 \
	python3-numpy python3-std-srvs
# systemd-analyze verify and rospack for the deployment tests (units, launch files).
# python3-wheel: pip's --no-build-isolation installs (installer tests, test-debian) on Debian's setuptools.
DEPLOY_TEST_DEBS := systemd rospack-tools python3-wheel
# A real MQTT broker for the Home Assistant and VDA 5050 tests (started by the tests on a free port).
MQTT_TEST_DEBS := mosquitto
# The VDA 5050 tests' master: npm's vda-5050-lib (its MasterController) run by node, installed from
# the lock file in tests/vda_master (tests/vda_master.py). Node and npm from Debian when npm is missing.
VDA_MASTER := tests/vda_master
VDA_MASTER_INSTALLED := $(VDA_MASTER)/node_modules/.installed
NODE_DEBS := nodejs npm
# The phone page's browser tests: Debian's chromium, driven by Playwright (no browser download).
BROWSER_TEST_DEBS := chromium
# Debian's own builds of our Python dependencies: what a Pi gets from apt (make test-debian).
DEBIAN_PY_DEBS := python3-flask python3-waitress python3-yaml python3-requests python3-zeroconf \
	python3-serial python3-paho-mqtt python3-pytest python3-pytest-timeout python3-pytest-xdist \
	python3-hypothesis python3-setuptools python3-jsonschema

.PHONY: setup test lint pytest test-debian run demo bench bench-smoke bench-guard clean

setup: $(VENV)/.installed

# What the server needs to run (make demo, make run): ROS 1 from Debian and the server in .venv.
# No test tools and no browser: those are make test's (below).
$(VENV)/.server: setup.py Makefile
	@echo "==> ROS 1 from Debian's packages (apt installs what is missing: a minute or two the first time)"
	@./scripts/apt-ensure $(ROS_DEBS)
	@echo "==> the server into $(VENV) (pip: Flask, waitress, zeroconf, ...)"
	@$(SYSTEM_PYTHON) -m venv --system-site-packages $(VENV)
	@$(PY) -m pip install -q --disable-pip-version-check -e .
	@touch $@

# Everything make test needs on top: systemd and rospack for the deployment tests, Debian's
# chromium for the phone page's browser tests, and the test tools (pytest, ruff, Playwright, ...).
$(VENV)/.installed: $(VENV)/.server
	@echo "==> the test toolchain: systemd, rospack, chromium (apt); pytest, ruff, playwright, ... (pip)"
	@./scripts/apt-ensure $(ROS_DEBS) $(DEPLOY_TEST_DEBS) $(MQTT_TEST_DEBS) $(BROWSER_TEST_DEBS)
	@$(PY) -m pip install -q --disable-pip-version-check --upgrade --upgrade-strategy eager -e '.[test]'
	@touch $@

lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/vermin --target=3.8- --no-tips --violations --eval-annotations --backport dataclasses \
		flask_move_server tests bench setup.py

pytest: setup $(VDA_MASTER_INSTALLED)
	$(PY) -m pytest $(XDIST) $(PYTEST_ARGS)

# npm ci: exactly the lock file's packages (vda-5050-lib 1.4.0 and its dependencies), again when it
# changes. A node that came with its own npm (NodeSource's nodejs provides npm) is used as it is:
# apt-ensure is asked for Debian's nodejs and npm only when there is no npm at all.
$(VDA_MASTER_INSTALLED): $(VDA_MASTER)/package.json $(VDA_MASTER)/package-lock.json
	@command -v npm >/dev/null || { echo "==> no npm: Debian's $(NODE_DEBS) (apt), for the VDA 5050 tests"; \
		./scripts/apt-ensure $(NODE_DEBS); }
	@command -v npm >/dev/null || { echo "npm is missing: install Node.js and npm ($(NODE_DEBS))" >&2; exit 1; }
	@echo "==> the VDA 5050 tests' master: vda-5050-lib from npm into $(VDA_MASTER)/node_modules (npm ci)"
	@cd $(VDA_MASTER) && npm ci --no-audit --no-fund --loglevel=error
	@touch $@

test: lint pytest

$(DEBIAN_VENV)/.installed: setup.py Makefile
	./scripts/apt-ensure $(ROS_DEBS) $(DEPLOY_TEST_DEBS) $(MQTT_TEST_DEBS) $(DEBIAN_PY_DEBS)
	$(SYSTEM_PYTHON) -m venv --system-site-packages $(DEBIAN_VENV)
	$(DEBIAN_VENV)/bin/python -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
	# The VDA 5050 schemas the tests check every message against (a test tool, not in Debian): the
	# files only, read with Debian's jsonschema.
	$(DEBIAN_VENV)/bin/python -m pip install -q --disable-pip-version-check --no-deps "vda5050-sdk==0.2.0"
	touch $@

# What Debian's Python packages cannot change is left to `make test`: the simulated robot's long
# drives (its physics, planner, SLAM and move_base stand-in are ours, over the same ROS from Debian
# in both passes) and the roslaunch stacks' process trees cost minutes and test nothing Flask,
# waitress, paho or PyYAML decide. Their HTTP, MQTT and client sides stay in this pass: the API and
# the event stream (test_api.py, test_events_sim.py, ...), runs (test_routes_web.py,
# test_client_routes.py, test_runs_robot.py), exploring (test_explore_web.py, test_client_explore.py,
# test_explorer.py), Home Assistant over paho 1.6 (test_home_assistant.py, test_mqtt_resilience.py),
# VDA 5050 over paho 1.6 driven by the npm master (test_vda5050_master.py; test_vda5050.py's many
# drives are make test's, and so is the sim battery's drive to the kitchen and back; so are the stuck robot's
# drives, test_stuck_ros.py and test_stuck_sim.py: rospy and the sim only).
DEBIAN_SKIPS := --ignore=tests/test_stack_launched.py --ignore=tests/test_modes_robot.py \
	--ignore=tests/test_sim_modes.py --ignore=tests/test_runs_sim.py --ignore=tests/test_explore_sim.py \
	--ignore=tests/test_sim_life.py --ignore=tests/test_sim_e2e.py --ignore=tests/test_launch.py \
	--ignore=tests/test_sim_real_stack.py --ignore=tests/test_sim_whereabouts.py --ignore=tests/test_vda5050.py \
	--ignore=tests/test_stuck_sim.py --ignore=tests/test_stuck_ros.py \
	--deselect tests/test_battery.py::test_the_sim_battery_drains_while_driving_and_charges_on_the_dock

# The servers roslaunch starts (scripts/flask_move_server_node) run on the same Debian packages, and
# need no .venv of make test's.
test-debian: $(DEBIAN_VENV)/.installed $(VDA_MASTER_INSTALLED)
	FLASK_MOVE_SERVER_PYTHON=$(abspath $(DEBIAN_VENV))/bin/python \
		$(DEBIAN_VENV)/bin/python -m pytest -p no:cacheprovider $(XDIST) $(DEBIAN_SKIPS) $(PYTEST_ARGS)

# The waypoints are copied once to build/run/, where the server also keeps mode.json and maps/.
RUN_WAYPOINTS ?= build/run/waypoints.yaml

run: $(VENV)/.server
	@mkdir -p $(dir $(RUN_WAYPOINTS))
	@test -f $(RUN_WAYPOINTS) || cp config/waypoints.example.yaml $(RUN_WAYPOINTS)
	$(VENV)/bin/flask-move-server --host 127.0.0.1 --waypoints $(RUN_WAYPOINTS)

# The simulated robot on the demo flat (make demo): its own ROS master, world and move_base stand-in.
# Waypoints are copied once to the demo's folder, so PUT /waypoints never edits the shipped file; the
# server keeps mode.json, maps/ and runs there too. Each port is its own robot: build/demo on 5000,
# build/demo-PORT on another, so a second demo beside the first (DEMO_PORT=5001) shares none of its state.
DEMO_PORT ?= 5000
DEMO_URL := http://127.0.0.1:$(DEMO_PORT)
DEMO_DIR ?= build/demo$(if $(filter 5000,$(DEMO_PORT)),,-$(DEMO_PORT))
DEMO_WAYPOINTS ?= $(DEMO_DIR)/waypoints.yaml

demo: $(VENV)/.server
	@mkdir -p $(dir $(DEMO_WAYPOINTS))
	@test -f $(DEMO_WAYPOINTS) || cp config/waypoints.demo.yaml $(DEMO_WAYPOINTS)
	@echo "Simulated robot on $(DEMO_URL) (Ctrl-C stops it), its state in $(dir $(DEMO_WAYPOINTS)). Open $(DEMO_URL)/ in a browser for the phone page."
	@echo "In another terminal, try:"
	@echo "  curl $(DEMO_URL)/waypoints"
	@echo "  curl -d '{\"name\": \"kitchen\"}' $(DEMO_URL)/goto"
	@echo "  curl -N $(DEMO_URL)/events"
	@echo "  curl -d '{\"name\": \"office\", \"wait\": 120}' $(DEMO_URL)/goto"
	@echo "  curl -X POST $(DEMO_URL)/stop"
	@echo "  curl -d '{\"linear\": 0.2, \"angular\": 0.5}' $(DEMO_URL)/teleop"
	@echo "  $(VENV)/bin/robotctl --url $(DEMO_URL) status"
	@$(VENV)/bin/flask-move-server --sim --port $(DEMO_PORT) --waypoints $(DEMO_WAYPOINTS) $(DEMO_ARGS)

bench: setup
	$(PY) -m bench

# CI's two looks at the benchmarks (docs/performance.md, "Benchmarks in CI"): every benchmark once
# with its smallest counts, failing one that does not finish or prints no table; and the
# concurrency guard, 8 clients against 1 in one run (a ratio, not a time) and /stop while they poll.
bench-smoke: setup
	$(PY) -m bench --smoke

bench-guard: setup
	$(PY) bench/bench_concurrency.py --guard

clean:
	rm -rf $(VENV) $(DEBIAN_VENV) build *.egg-info .pytest_cache .ruff_cache $(VDA_MASTER)/node_modules
