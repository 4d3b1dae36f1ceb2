"""Teleop latency and base-controller CPU; prints markdown tables for docs/performance.md.

1. ``POST /teleop`` → the Twist arrives on ``/cmd_vel`` → the base controller
   applies a new motor command (sim backend), p50/p99 over N requests, against
   a bare Flask app that only publishes the Twist with rospy (the floor).
2. CPU of the base controller alone (``python -m flask_move_server.drive``,
   sim backend) at 20 Hz and 50 Hz odometry, idle and driven at 10 Hz.

Run: ``.venv/bin/python bench/bench_teleop.py [--requests N] [--seconds S]``.
Starts its own ROS master on a free port.
"""

import argparse
import contextlib
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def free_port():
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_master():
    from flask_move_server.ros import master

    port = free_port()
    proc = subprocess.Popen([shutil.which("rosmaster") or "rosmaster", "--core", "-p", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    uri = "http://127.0.0.1:{}".format(port)
    deadline = time.monotonic() + 20
    while not master.identity("/bench", uri, timeout=0.5):
        if time.monotonic() > deadline:
            raise SystemExit("rosmaster did not start")
        time.sleep(0.1)
    os.environ["ROS_MASTER_URI"], os.environ["ROS_IP"] = uri, "127.0.0.1"
    return proc


class Arrivals:
    """Monotonic arrival times of /cmd_vel messages, waited on one at a time."""

    def __init__(self, topic):
        import rospy
        from geometry_msgs.msg import Twist

        self._cond = threading.Condition()
        self.times = []
        self.sub = rospy.Subscriber(topic, Twist, self._on, queue_size=100, tcp_nodelay=True)

    def _on(self, msg):
        with self._cond:
            self.times.append(time.monotonic())
            self._cond.notify_all()

    def after(self, t0, timeout=2.0):
        with self._cond:
            self._cond.wait_for(lambda: self.times and self.times[-1] > t0, timeout)
            return next((t for t in self.times if t > t0), None)


def applied_after(backend, t0, timeout=2.0):
    """Time the sim backend got a new command after ``t0`` (polled; the timestamp is the backend's)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        history = list(backend.history)
        for t, _, _ in reversed(history):
            if t > t0:
                return min(t2 for t2, _, _ in history if t2 > t0)
            break
        time.sleep(0.0002)
    return None


def measure(url, arrivals, backend, n):
    # http.client on one keep-alive connection: requests adds about a millisecond of its own
    # per call, which would be measured as the server's.
    import http.client
    import json
    from urllib.parse import urlsplit

    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=5)
    http, topic, motors = [], [], []
    for i in range(n):
        body = json.dumps({"linear": 0.1 + 0.002 * (i % 50), "angular": 0.0})
        t0 = time.monotonic()
        conn.request("POST", "/teleop", body=body, headers={"Content-Type": "application/json"})
        r = conn.getresponse()
        text = r.read()
        t1 = time.monotonic()
        assert r.status == 200, text
        http.append(t1 - t0)
        arrived = arrivals.after(t0)
        if arrived is not None:
            topic.append(arrived - t0)
        if backend is not None:
            applied = applied_after(backend, t0)
            if applied is not None:
                motors.append(applied - t0)
        time.sleep(0.01)
    return http, topic, motors


def percentile(values, p):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(p / 100.0 * (len(ordered) - 1))))]


def row(name, values):
    if not values:
        return "| {} | - | - | - |".format(name)
    ms = [v * 1000 for v in values]
    return "| {} | {:.2f} | {:.2f} | {} |".format(name, statistics.median(ms), percentile(ms, 99), len(ms))


def our_server(n, tmp):
    from flask_move_server import cli, config
    from flask_move_server.drive import make_drive
    from flask_move_server.drive.backends.sim import SimBackend
    from flask_move_server.ros.node import RosNode
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.web import create_app

    cfg = config.Config()
    cfg.server.host = "127.0.0.1"
    cfg.waypoints.file = os.path.join(tmp, "waypoints.yaml")
    cfg.drive.backend = "sim"
    cfg.teleop.topic = cfg.drive.cmd_vel_topic = "bench/cmd_vel"
    cfg.drive.odom_topic = "bench/odom"
    node = RosNode("bench_teleop", check_period=1.0)
    node.start()
    if not node.wait_connected(20):
        raise SystemExit("rospy could not connect")
    backend = SimBackend(cfg.drive)
    drive = make_drive(cfg.drive, node, cfg.ros.frames, backend=backend)
    robot = cli.build_robot(cfg, node, drive)
    app = create_app(cfg, robot, WaypointStore(cfg.waypoints.file))
    arrivals = Arrivals("bench/cmd_vel")
    with serving(app) as url:
        time.sleep(1.0)  # let the subscribers connect
        results = measure(url, arrivals, backend, n)
    arrivals.sub.unregister()
    robot.close()
    drive.close()
    return node, results


def bare_flask(n):
    import rospy
    from flask import Flask, request
    from geometry_msgs.msg import Twist

    pub = rospy.Publisher("bare/cmd_vel", Twist, queue_size=1, tcp_nodelay=True)
    app = Flask("bare")

    @app.post("/teleop")
    def teleop():
        body = request.get_json(force=True)
        msg = Twist()
        msg.linear.x, msg.angular.z = float(body.get("linear", 0)), float(body.get("angular", 0))
        pub.publish(msg)
        return {"status": "ok"}

    arrivals = Arrivals("bare/cmd_vel")
    with serving(app) as url:
        time.sleep(1.0)
        results = measure(url, arrivals, None, n)
    arrivals.sub.unregister()
    return results


@contextlib.contextmanager
def serving(app):
    import waitress

    server = waitress.create_server(app, host="127.0.0.1", port=0, threads=6, clear_untrusted_proxy_headers=True)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        yield "http://127.0.0.1:{}".format(server.effective_port)
    finally:
        server.close()
        thread.join(5)


def cpu_of_base(odom_rate, seconds, drive_it, tmp):
    """Percent of one core used by ``flask-move-base`` (sim) over ``seconds``."""
    import rospy
    from geometry_msgs.msg import Twist

    path = os.path.join(tmp, "base{}.yaml".format(odom_rate))
    with open(path, "w") as f:
        f.write("drive:\n  backend: sim\n  odom_rate: {}\n  cmd_vel_topic: cpu/cmd_vel\n"
                "  odom_topic: cpu/odom\n".format(odom_rate))
    proc = subprocess.Popen([sys.executable, "-m", "flask_move_server.drive", "--config", path,
                             "__name:=cpu_base_{}".format(odom_rate)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    pub = rospy.Publisher("cpu/cmd_vel", Twist, queue_size=1)
    try:
        time.sleep(3.0)  # start-up (imports, registration) is not the steady state
        msg = Twist()
        msg.linear.x = 0.2
        start_cpu, start = cpu_seconds(proc.pid), time.monotonic()
        while time.monotonic() - start < seconds:
            if drive_it:
                pub.publish(msg)
            time.sleep(0.1)
        used = cpu_seconds(proc.pid) - start_cpu
        return 100.0 * used / (time.monotonic() - start)
    finally:
        pub.unregister()
        proc.terminate()
        proc.wait(10)


def cpu_seconds(pid):
    with open("/proc/{}/stat".format(pid)) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=300)
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args(argv)
    master = start_master()
    tmp = tempfile.mkdtemp(prefix="bench_teleop")
    try:
        node, (http, topic, motors) = our_server(args.requests, tmp)
        bare_http, bare_topic, _ = bare_flask(args.requests)
        print("| POST /teleop ({} requests) | p50 ms | p99 ms | n |".format(args.requests))
        print("|---|---|---|---|")
        print(row("flask-move-server: HTTP response", http))
        print(row("flask-move-server: Twist on /cmd_vel", topic))
        print(row("flask-move-server: motor command applied (sim)", motors))
        print(row("bare Flask + rospy: HTTP response", bare_http))
        print(row("bare Flask + rospy: Twist on /cmd_vel", bare_topic))
        print()
        print("| base controller alone (sim backend) | idle: % of one core | driven at 10 Hz: % of one core |")
        print("|---|---|---|")
        for rate in (20, 50):
            idle = cpu_of_base(rate, args.seconds, False, tmp)
            driven = cpu_of_base(rate, args.seconds, True, tmp)
            print("| odometry at {} Hz | {:.1f} | {:.1f} |".format(rate, idle, driven))
        node.close()
    finally:
        master.terminate()
        master.wait(10)
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
