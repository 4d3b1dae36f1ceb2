"""Benchmark of the server core (issue 2): /status throughput, RSS, idle CPU, start-up.

Run: ``.venv/bin/python bench/bench_server.py`` (starts its own ROS master). Prints markdown
tables for docs/performance.md. Compares against ``bench/bare_server.py`` on waitress and on
werkzeug's development server. Goal latency has its own benchmark: ``bench/bench_goals.py``.
"""

import argparse
import http.client
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import free_port, start_master, stop_process, wait_for  # noqa: E402

# This process runs move_base (an outside stack, as on a robot whose launch file starts it): without
# ``stack: none`` the server starts in its idle mode and never asks move_base for goals.
OUR_CONFIG = "modes: {stack: none}\n"


class MoveBase:
    """A real actionlib move_base in this process, so the server runs as it does on the robot."""

    def __init__(self, action):
        import actionlib
        from move_base_msgs.msg import MoveBaseAction, MoveBaseResult

        self._server = actionlib.SimpleActionServer(
            action, MoveBaseAction, execute_cb=lambda goal: self._server.set_succeeded(MoveBaseResult()),
            auto_start=False)
        self._server.start()


def start_server(args, env, cwd=None):
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True, cwd=cwd)
    started = time.perf_counter()
    for line in proc.stderr:
        if "serving the API on http://" in line or "bare server on http://" in line:
            url = line.split("http://")[1].split()[0]
            host, port = url.split(":")
            threading.Thread(target=lambda: [None for _ in proc.stderr], daemon=True).start()
            return proc, host, int(port), started
    raise RuntimeError("server did not start: exit {}".format(proc.wait()))


def request(conn, method, path, body=None):
    conn.request(method, path, body=body, headers={"Content-Type": "application/json"})
    response = conn.getresponse()
    data = response.read()
    return response.status, data


def throughput(host, port, path, seconds, connections=8):
    counts = [0] * connections
    stop = time.perf_counter() + seconds

    def worker(i):
        conn = http.client.HTTPConnection(host, port, timeout=10)
        while time.perf_counter() < stop:
            status, _ = request(conn, "GET", path)
            assert status == 200
            counts[i] += 1

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(connections)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return sum(counts) / seconds


def cpu_seconds(pid):
    with open("/proc/{}/stat".format(pid)) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def rss_mb(pid):
    with open("/proc/{}/status".format(pid)) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--idle", type=float, default=10.0)
    opts = parser.parse_args()

    home = tempfile.mkdtemp(prefix="bench-ros-")
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_HOME=home, ROS_IP="127.0.0.1")
    os.environ.update(env)
    master = start_master(port)
    procs = []
    try:
        import rospy

        rospy.init_node("bench", disable_signals=True)
        MoveBase("move_base")
        waypoints = os.path.join(home, "waypoints.yaml")
        config = os.path.join(home, "robot.yaml")
        with open(config, "w") as f:
            f.write(OUR_CONFIG)
        ours, host, our_port, started = start_server(
            [sys.executable, "-m", "flask_move_server", "--config", config, "--host", "127.0.0.1", "--port", "0",
             "--no-mdns", "--waypoints", waypoints], env)
        procs.append(ours)
        conn = http.client.HTTPConnection(host, our_port, timeout=10)
        wait_for(lambda: request(conn, "GET", "/health")[0] == 200, timeout=10, interval=0.005)
        health_after = time.perf_counter() - started
        wait_for(lambda: json.loads(request(conn, "GET", "/health")[1])["move_base"] == "ready", timeout=30)

        bare, bhost, bport, _ = start_server([sys.executable, os.path.join(ROOT, "bench", "bare_server.py")], env)
        procs.append(bare)
        dev, dhost, dport, _ = start_server(
            [sys.executable, os.path.join(ROOT, "bench", "bare_server.py"), "--werkzeug"], env)
        procs.append(dev)

        ours_rps = throughput(host, our_port, "/status", opts.seconds)
        bare_rps = throughput(bhost, bport, "/status", opts.seconds)
        dev_rps = throughput(dhost, dport, "/status", opts.seconds)

        time.sleep(2)
        rss = rss_mb(ours.pid)
        before = cpu_seconds(ours.pid)
        time.sleep(opts.idle)
        idle_pct = (cpu_seconds(ours.pid) - before) / opts.idle * 100

        print("| GET /status, 8 keep-alive connections, {:.0f} s | requests/s |".format(opts.seconds))
        print("|---|---|")
        print("| flask-move-server (waitress) | {:.0f} |".format(ours_rps))
        print("| bare Flask on waitress | {:.0f} |".format(bare_rps))
        print("| bare Flask on the development server | {:.0f} |".format(dev_rps))
        print()
        print("| process | value |")
        print("|---|---|")
        print("| RSS after the runs above | {:.1f} MB |".format(rss))
        print("| idle CPU (connected, no requests, {:.0f} s) | {:.2f} % of one core |".format(opts.idle, idle_pct))
        print("| /health answering after process start | {:.2f} s |".format(health_after))
    finally:
        for p in procs:
            stop_process(p)
        stop_process(master)
        if "rospy" in sys.modules:
            sys.modules["rospy"].signal_shutdown("benchmark done")  # else its threads keep this process


if __name__ == "__main__":
    main()
