"""How long a mode switch takes with the roslaunch stack backend: start until ready, and stop.

    .venv/bin/python bench/bench_stack.py [--repeat 5]

Runs the shipped launch files against the stand-in nodes of tests/stub_packages (tiny rospy
nodes) on a ROS master of its own, so what it measures is our part and roslaunch's: parsing the
launch file in the server, roslaunch starting, Python nodes registering, the readiness polling,
and the SIGINT stop of the whole tree. The real gmapping, AMCL and move_base add their own
start-up (seconds on a Pi) on top. Prints a markdown table (docs/performance.md, section Modes).
"""

import argparse
import os
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.config import ModesConfig  # noqa: E402
from flask_move_server.modes import readiness  # noqa: E402
from flask_move_server.modes.launched import LaunchedStack  # noqa: E402
from tests.conftest import free_port, start_master, stop_process  # noqa: E402

DEMO_MAP = os.path.join(ROOT, "config", "maps", "demo.yaml")


def ros_environment(home):
    os.environ.update(ROS_PACKAGE_PATH=os.pathsep.join([ROOT, os.path.join(ROOT, "tests", "stub_packages")]),
                      ROS_HOME=home, ROS_LOG_DIR=os.path.join(home, "log"), ROS_IP="127.0.0.1")
    os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:{}".format(free_port())


def measure(stack, repeat):
    rows = {"parse the launch file (navigation)": [], "start mapping until /map": [],
            "start navigation until /map and move_base/status": [], "stop (whole tree gone)": []}
    for _ in range(repeat):
        t = time.perf_counter()
        readiness.check_launch(stack.command("navigation", DEMO_MAP)[1:])
        rows["parse the launch file (navigation)"].append(time.perf_counter() - t)
        for mode, key in (("mapping", "start mapping until /map"),
                          ("navigation", "start navigation until /map and move_base/status")):
            t = time.perf_counter()
            stack.start(mode, DEMO_MAP if mode == "navigation" else None)
            rows[key].append(time.perf_counter() - t)
            t = time.perf_counter()
            stack.stop()
            rows["stop (whole tree gone)"].append(time.perf_counter() - t)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as home:
        ros_environment(home)
        master = start_master(int(os.environ["ROS_MASTER_URI"].rsplit(":", 1)[1]))
        stack = LaunchedStack(ModesConfig(start_timeout=60.0, stop_timeout=10.0))
        try:
            rows = measure(stack, args.repeat)
        finally:
            stack.close()
            stop_process(master)
    load = os.getloadavg()[0]
    print("{} runs each, load average {:.1f} on {} cores\n".format(args.repeat, load, os.cpu_count()))
    print("| measure | median s | max s |\n|---|---:|---:|")
    for name, times in rows.items():
        print("| {} | {:.2f} | {:.2f} |".format(name, statistics.median(times), max(times)))


if __name__ == "__main__":
    main()
