"""Benchmark of the server core (issue 2): goal latency, /status throughput, RSS, idle CPU, start-up.

Run: ``.venv/bin/python bench/bench_server.py`` (starts its own ROS master). Prints markdown
tables for docs/performance.md. Compares against ``bench/bare_server.py``: one Flask route on
waitress publishing the same goal message with rospy, and the same app on werkzeug's
development server for the throughput baseline.
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


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100.0 * (len(values) - 1))))]


class GoalWatch:
    """A real actionlib move_base in this process, and the arrival time of every goal."""

    def __init__(self, action):
        import actionlib
        from move_base_msgs.msg import MoveBaseAction, MoveBaseResult

        self.arrivals = {}
        self._server = actionlib.SimpleActionServer(
            action, MoveBaseAction, execute_cb=lambda goal: self._server.set_succeeded(MoveBaseResult()),
            auto_start=False)
        import rospy
        from move_base_msgs.msg import MoveBaseActionGoal

        self._sub = rospy.Subscriber(action + "/goal", MoveBaseActionGoal, self._on_goal, tcp_nodelay=True)
        self._server.start()

    def _on_goal(self, msg):
        self.arrivals[round(msg.goal.target_pose.pose.position.x, 6)] = time.perf_counter()


def start_server(args, env):
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True)
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


def goal_latency(host, port, path, watch, count, offset):
    conn = http.client.HTTPConnection(host, port, timeout=10)
    latencies = []
    for i in range(count):
        x = offset + i * 0.001
        sent = time.perf_counter()
        status, _ = request(conn, "POST", path, json.dumps({"x": x, "y": 0.0, "yaw": 0.0}))
        assert status in (200, 202), status
        key = round(x, 6)
        wait_for(lambda key=key: key in watch.arrivals, timeout=10, interval=0.0005)
        latencies.append((watch.arrivals[key] - sent) * 1000)
        time.sleep(0.01)
    return latencies


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
    parser.add_argument("--goals", type=int, default=300)
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
        watch = GoalWatch("move_base")
        bare_watch = GoalWatch("bare/move_base")
        waypoints = os.path.join(home, "waypoints.yaml")
        ours, host, our_port, started = start_server(
            [sys.executable, "-m", "flask_move_server", "--host", "127.0.0.1", "--port", "0", "--no-mdns",
             "--waypoints", waypoints], env)
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
        time.sleep(2)  # let the bare publishers connect to the goal subscribers

        goal_latency(host, our_port, "/goto", watch, 20, 1000.0)  # warm-up
        ours_ms = goal_latency(host, our_port, "/goto", watch, opts.goals, 0.0)
        goal_latency(bhost, bport, "/goto", bare_watch, 20, 2000.0)
        bare_ms = goal_latency(bhost, bport, "/goto", bare_watch, opts.goals, 500.0)
        request(conn, "POST", "/stop")

        ours_rps = throughput(host, our_port, "/status", opts.seconds)
        bare_rps = throughput(bhost, bport, "/status", opts.seconds)
        dev_rps = throughput(dhost, dport, "/status", opts.seconds)

        time.sleep(2)
        rss = rss_mb(ours.pid)
        before = cpu_seconds(ours.pid)
        time.sleep(opts.idle)
        idle_pct = (cpu_seconds(ours.pid) - before) / opts.idle * 100

        print("| POST /goto until the goal reaches move_base ({} goals) | p50 ms | p99 ms |".format(opts.goals))
        print("|---|---|---|")
        print("| flask-move-server | {:.2f} | {:.2f} |".format(percentile(ours_ms, 50), percentile(ours_ms, 99)))
        print("| bare Flask + rospy on waitress | {:.2f} | {:.2f} |".format(
            percentile(bare_ms, 50), percentile(bare_ms, 99)))
        print()
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


if __name__ == "__main__":
    main()
