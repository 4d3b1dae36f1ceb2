"""The server's memory at rest per configuration (issue 32), and what each package it imports costs.

Run: ``.venv/bin/python bench/bench_rss.py [--repeat 3] [--settle 5] [--compare DIR ...] [--imports]``.
Each configuration is a real ``flask-move-server`` process, measured once it has settled
(``--settle`` s after it is ready) by its VmRSS:

- ``none``: ``--motor-backend none``, no MQTT, no mDNS, on a ROS master of the bench's: ready once
  ``/health`` says ROS ``connected`` (no move_base: nothing drives at rest);
- ``sim``: ``--sim`` (its own ROS master, the demo waypoints): ready once move_base is;
- ``sim + MQTT + VDA 5050``: the same with MQTT and VDA 5050 on, against a real mosquitto
  (``tests/mqtt_broker.py``): ready once the server says it is connected.

``--compare DIR`` (repeatable) runs the same servers from other checkouts (``git worktree add DIR
REV``) in the same run, interleaved (each round starts every checkout's server in turn), so the
machine's load falls on all alike; a configuration a checkout cannot start shows as "—". The table
has the median of ``--repeat`` rounds and the range. ``--imports`` adds the RSS each package costs
when imported alone into a fresh interpreter, and on top of the ones every configuration loads.
"""

import argparse
import http.client
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_server import rss_mb, start_server  # noqa: E402

from tests.conftest import free_port, start_master, stop_process, wait_for  # noqa: E402
from tests.mqtt_broker import Broker  # noqa: E402

CONFIGS = (("none", "`--motor-backend none`, no MQTT"), ("sim", "`--sim`"),
           ("vda", "`--sim` + MQTT + VDA 5050 (mosquitto)"))
TARGETS = {"none": 60.0, "sim": None, "vda": 70.0}  # MB, issue 32

# (imported first, package, what it is to the server): measured after "first", and on top of BASE
PACKAGES = (("", "numpy", "numpy (genpy imports it; the explorer uses it)"),
            ("", "rospy", "rospy (with genpy)"),
            ("flask_move_server.ros", "rospy", "rospy after flask_move_server.ros (genpy without numpy)"),
            ("", "flask", "Flask"), ("", "waitress", "waitress"), ("", "yaml", "PyYAML"),
            ("", "paho.mqtt.client", "paho-mqtt"), ("", "jsonschema", "jsonschema (the tests' VDA 5050 schemas only)"),
            ("", "zeroconf", "zeroconf (mDNS)"), ("", "actionlib", "actionlib"), ("", "tf2_ros", "tf2_ros"),
            ("", "flask_move_server.web", "the web app (flask_move_server.web)"),
            ("", "flask_move_server.explore.explorer", "the explorer"),
            ("", "flask_move_server.explore.frontiers", "the frontier search"),
            ("", "flask_move_server.sim.runner", "the sim"), ("", "flask_move_server.mqtt.link", "the MQTT link"),
            ("", "flask_move_server.vda5050.vehicle", "the VDA 5050 vehicle"))
BASE = "flask_move_server.ros,rospy,flask,waitress,yaml"  # what every configuration loads
IMPORT = r"""
import sys
def rss():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
for name in filter(None, sys.argv[1].split(",")):
    __import__(name)
before = rss()
__import__(sys.argv[2])
print(rss() - before, "numpy" in sys.modules)
"""


def get_json(host, port, path):
    conn = http.client.HTTPConnection(host, port, timeout=5)
    try:
        conn.request("GET", path)
        return json.loads(conn.getresponse().read())
    finally:
        conn.close()


class Bench:
    """One master for ``none``, one broker for ``vda``, the servers started in turn."""

    def __init__(self, home):
        self.home = pathlib.Path(home)
        self.master_port = free_port()
        self.env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(self.master_port),
                        ROS_HOME=str(self.home), ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1")
        os.environ.update(self.env)
        self.master = start_master(self.master_port)
        self.broker = Broker(self.home)
        self.waypoints = self.home / "waypoints.yaml"
        shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), str(self.waypoints))

    def server(self, kind, checkout, run):
        """(args, env) of ``kind``'s server from ``checkout``; sim servers get a master of their own."""
        folder = self.home / "{}-{}".format(kind, run)
        folder.mkdir()
        env = dict(self.env, PYTHONPATH=checkout, ROS_HOME=str(folder), ROS_LOG_DIR=str(folder / "log"))
        args = [sys.executable, "-m", "flask_move_server", "--port", "0", "--no-mdns"]
        if kind == "none":
            return args + ["--host", "127.0.0.1", "--motor-backend", "none",
                           "--waypoints", str(folder / "waypoints.yaml")], env
        env["ROS_MASTER_URI"] = "http://127.0.0.1:{}".format(free_port())
        waypoints = folder / "waypoints.yaml"
        shutil.copy(str(self.waypoints), str(waypoints))
        args += ["--sim", "--waypoints", str(waypoints)]
        if kind == "vda":
            config = folder / "sim.yaml"
            config.write_text("mdns:\n  hostname: robot{}\nmqtt:\n  enabled: true\n  host: 127.0.0.1\n  port: {}\n"
                              "  vda5050:\n    enabled: true\n".format(run, self.broker.port))
            args += ["--config", str(config)]
        return args, env

    def measure(self, kind, checkout, run, settle):
        """VmRSS in MB of ``kind``'s server from ``checkout`` once ready and ``settle`` s on; None if it
        cannot start or get ready."""
        args, env = self.server(kind, checkout, run)
        try:
            proc, host, port, _ = start_server(args, env, cwd=checkout)
        except RuntimeError as exc:
            print("({} from {}: {})".format(kind, checkout, exc), file=sys.stderr)
            return None
        try:
            ready = ("ros", "connected") if kind == "none" else ("move_base", "ready")
            wait_for(lambda: get_json(host, port, "/health").get(ready[0]) == ready[1], timeout=90, message=ready[0])
            if kind == "vda":
                wait_for(lambda: (get_json(host, port, "/status").get("mqtt") or {}).get("state") == "connected",
                         timeout=30, message="MQTT")
            time.sleep(settle)
            return rss_mb(proc.pid)
        except (AssertionError, RuntimeError, OSError, ValueError) as exc:
            print("({} from {}: {}; /health {})".format(kind, checkout, exc, get_json(host, port, "/health")),
                  file=sys.stderr)
            return None
        finally:
            stop_process(proc, timeout=15)

    def close(self):
        self.broker.stop()
        stop_process(self.master)


def rss_table(bench, checkouts, repeat, settle, kinds):
    configs = [(kind, label) for kind, label in CONFIGS if kind in kinds]
    samples = {(kind, c): [] for kind, _ in configs for c in checkouts}
    run = 0
    for _ in range(repeat):
        for kind, _ in configs:
            for checkout in checkouts:
                run += 1
                value = bench.measure(kind, checkout, run, settle)
                if value is not None:
                    samples[(kind, checkout)].append(value)
    names = [os.path.basename(c.rstrip("/")) for c in checkouts]
    print("| RSS at rest, MB (median of {}, range; {} s after ready) | {} | target |".format(
        repeat, settle, " | ".join(names)))
    print("|---|" + "---:|" * (len(checkouts) + 1))
    for kind, label in configs:
        cells = [cell(samples[(kind, c)]) for c in checkouts]
        target = TARGETS[kind]
        print("| {} | {} | {} |".format(label, " | ".join(cells), "≤ {:.0f}".format(target) if target else ""))


def cell(values):
    if not values:
        return "—"
    if len(values) == 1:
        return "{:.1f}".format(values[0])
    return "**{:.1f}** ({:.1f}–{:.1f})".format(statistics.median(values), min(values), max(values))


def import_cost(first, name):
    """(MB, numpy loaded) of importing ``name`` after ``first`` in a fresh interpreter; median of 3."""
    runs = []
    for _ in range(3):
        done = subprocess.run([sys.executable, "-c", IMPORT, first, name], capture_output=True, text=True,
                              cwd=ROOT, env=dict(os.environ, PYTHONPATH=ROOT))
        if done.returncode:
            return None
        mb, numpy = done.stdout.split()
        runs.append((float(mb), numpy == "True"))
    return sorted(runs)[1]


def imports_table():
    print("| package | RSS alone, MB | on top of what all load, MB |")
    print("|---|---:|---:|")
    for first, name, label in PACKAGES:
        alone, on_top = import_cost(first, name), import_cost(BASE, name)
        print("| {} | {} | {} |".format(label, fmt(alone), fmt(on_top)))
    print("\n(\"what all load\": {}; * = numpy got loaded with it)".format(BASE.replace(",", ", ")))


def fmt(cost):
    return "—" if cost is None else "{:.1f}{}".format(cost[0], " *" if cost[1] else "")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--settle", type=float, default=5.0, help="s at rest after ready before reading RSS")
    parser.add_argument("--compare", metavar="DIR", action="append", default=[],
                        help="another checkout's server, measured in the same run (repeatable)")
    parser.add_argument("--configs", default="none,sim,vda", help="which configurations (default: all three)")
    parser.add_argument("--imports", action="store_true", help="also the RSS each package costs")
    opts = parser.parse_args()
    checkouts = [ROOT] + [os.path.abspath(c) for c in opts.compare]
    print("load average {:.1f} {:.1f} {:.1f}, {} cores\n".format(*os.getloadavg(), os.cpu_count()))
    home = tempfile.mkdtemp(prefix="bench-rss-")
    bench = Bench(home)
    try:
        rss_table(bench, checkouts, opts.repeat, opts.settle, opts.configs.split(","))
    finally:
        bench.close()
        shutil.rmtree(home, ignore_errors=True)
    if opts.imports:
        print()
        imports_table()
    print("\nload average {:.1f} {:.1f} {:.1f} at the end".format(*os.getloadavg()))


if __name__ == "__main__":
    main()
