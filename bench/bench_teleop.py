"""Teleop latency and base-controller CPU; prints markdown tables for docs/performance.md.

1. ``POST /teleop`` → the Twist arrives on ``/cmd_vel`` → the base controller
   applies a new motor command (sim backend), p50/p99 over N requests, against
   a bare Flask app that only publishes the Twist with rospy (the floor).
2. CPU of the base controller alone (``python -m flask_move_server.drive``,
   sim backend) at 20 Hz and 50 Hz odometry, idle and driven at 10 Hz.

Run: ``.venv/bin/python bench/bench_teleop.py [--requests N] [--seconds S] [--rosbridge ws://HOST:PORT]``.
Starts its own ROS master on a free port. With ``--rosbridge`` it also publishes the
same Twists through a running rosbridge_websocket (ROS 1) into the same base
controller, and then uses the master of ``$ROS_MASTER_URI``, the one rosbridge is on.
"""

import argparse
import base64
import contextlib
import hashlib
import json
import os
import shutil
import socket
import statistics
import struct
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


def start_master(uri=None):
    """A new ROS master on a free port (its process), or None once the one at ``uri`` answers."""
    from flask_move_server.ros import master

    proc = None
    if uri is None:
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
        ends(t0, arrivals, backend, topic, motors)
        time.sleep(0.01)
    return http, topic, motors


def ends(t0, arrivals, backend, topic, motors):
    """Append the times from ``t0`` to the Twist's arrival and (with a backend) to the motor command."""
    arrived = arrivals.after(t0)
    if arrived is not None:
        topic.append(arrived - t0)
    if backend is not None:
        applied = applied_after(backend, t0)
        if applied is not None:
            motors.append(applied - t0)


def measure_rosbridge(url, topic_name, arrivals, backend, n):
    """As :func:`measure`, the same Twists published through rosbridge (no answer to wait for)."""
    sock = ws_connect(url)
    ws_send(sock, json.dumps({"op": "advertise", "topic": topic_name, "type": "geometry_msgs/Twist"}))
    time.sleep(1.0)  # let the subscribers connect to rosbridge's publisher
    topic, motors = [], []
    for i in range(n):
        text = json.dumps({"op": "publish", "topic": topic_name,
                           "msg": {"linear": {"x": 0.1 + 0.002 * (i % 50)}, "angular": {"z": 0.0}}})
        t0 = time.monotonic()
        ws_send(sock, text)
        ends(t0, arrivals, backend, topic, motors)
        time.sleep(0.01)
    ws_send(sock, "", opcode=0x8)  # close
    sock.close()
    return topic, motors


def ws_connect(url):
    """A socket to ``ws://host:port[/path]`` after the RFC 6455 handshake (standard library only)."""
    from urllib.parse import urlsplit

    parts = urlsplit(url)
    sock = socket.create_connection((parts.hostname, parts.port or 80), timeout=5)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # as http.client's connection
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall("GET {} HTTP/1.1\r\nHost: {}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 "Sec-WebSocket-Key: {}\r\nSec-WebSocket-Version: 13\r\n\r\n"
                 .format(parts.path or "/", parts.netloc, key).encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = sock.recv(4096)
        if not chunk:
            break
        head += chunk
    accept = base64.b64encode(hashlib.sha1((key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11").encode()).digest())
    if not head.startswith(b"HTTP/1.1 101") or accept not in head:
        raise SystemExit("no websocket at {}: {!r}".format(url, head[:200]))
    return sock


def ws_send(sock, text, opcode=0x1):
    """One final, masked frame (a text frame unless ``opcode`` says otherwise), as a client must send it."""
    data, mask = text.encode(), os.urandom(4)
    n = len(data)
    length = bytes([0x80 | n]) if n < 126 else struct.pack("!BH", 0x80 | 126, n) if n < 65536 \
        else struct.pack("!BQ", 0x80 | 127, n)
    masked = (int.from_bytes(data, "big") ^ int.from_bytes((mask * (n // 4 + 1))[:n], "big")).to_bytes(n, "big")
    sock.sendall(bytes([0x80 | opcode]) + length + mask + masked)


def percentile(values, p):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(p / 100.0 * (len(ordered) - 1))))]


def row(name, values):
    if not values:
        return "| {} | - | - | - |".format(name)
    ms = [v * 1000 for v in values]
    return "| {} | {:.2f} | {:.2f} | {} |".format(name, statistics.median(ms), percentile(ms, 99), len(ms))


def our_server(n, tmp, rosbridge=None):
    from flask_move_server import config
    from flask_move_server.app import cli
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
    store = WaypointStore(cfg.waypoints.file)
    runs = _run_executor(robot, store, tmp)
    app = create_app(cfg, robot, store, runs=runs)
    arrivals = Arrivals("bench/cmd_vel")
    cfg.server.port = 0
    with serving(app, cfg.server) as url:
        time.sleep(1.0)  # let the subscribers connect
        results = measure(url, arrivals, backend, n)
    if runs is not None:
        runs.close()
    robot.close()  # teleop's publisher gone: rosbridge's Twists are the only ones on the topic
    bridged = measure_rosbridge(rosbridge, "/bench/cmd_vel", arrivals, backend, n) if rosbridge else ([], [])
    arrivals.sub.unregister()
    drive.close()
    return node, results, bridged


def _run_executor(robot, store, tmp):
    """The run executor the server has (issue 23): each teleop asks it to end a run under way, as in the
    real server. None for a checkout from before it (``--compare``-style runs with PYTHONPATH)."""
    try:
        from flask_move_server.missions.executor import RunExecutor
        from flask_move_server.missions.history import RunHistory
    except ImportError:
        return None
    runs = RunExecutor(robot, store, RunHistory(os.path.join(tmp, "runs.json")))
    robot.runs = runs
    return runs


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
def serving(app, server_config=None):
    """``app`` served in a thread: on the robot's hardened server (``server_config``), else plain waitress."""
    import waitress

    from flask_move_server.http.server import HttpServer

    if server_config is not None:
        server = HttpServer(app, server_config)
    else:
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
    parser.add_argument("--rosbridge", metavar="ws://HOST:PORT",
                        help="also publish through this rosbridge_websocket, on the master of $ROS_MASTER_URI")
    args = parser.parse_args(argv)
    if args.rosbridge and not os.environ.get("ROS_MASTER_URI"):
        parser.error("--rosbridge needs ROS_MASTER_URI: the master that rosbridge_websocket is registered with")
    master = start_master(os.environ["ROS_MASTER_URI"] if args.rosbridge else None)
    tmp = tempfile.mkdtemp(prefix="bench_teleop")
    try:
        node, (http, topic, motors), (bridged_topic, bridged_motors) = our_server(args.requests, tmp, args.rosbridge)
        bare_http, bare_topic, _ = bare_flask(args.requests)
        print("| POST /teleop ({} requests) | p50 ms | p99 ms | n |".format(args.requests))
        print("|---|---|---|---|")
        print(row("flask-move-server: HTTP response", http))
        print(row("flask-move-server: Twist on /cmd_vel", topic))
        print(row("flask-move-server: motor command applied (sim)", motors))
        print(row("bare Flask + rospy: HTTP response", bare_http))
        print(row("bare Flask + rospy: Twist on /cmd_vel", bare_topic))
        if args.rosbridge:
            print(row("rosbridge_websocket: Twist on /cmd_vel", bridged_topic))
            print(row("rosbridge_websocket: motor command applied (sim)", bridged_motors))
        print()
        print("| base controller alone (sim backend) | idle: % of one core | driven at 10 Hz: % of one core |")
        print("|---|---|---|")
        for rate in (20, 50):
            idle = cpu_of_base(rate, args.seconds, False, tmp)
            driven = cpu_of_base(rate, args.seconds, True, tmp)
            print("| odometry at {} Hz | {:.1f} | {:.1f} |".format(rate, idle, driven))
        node.close()
    finally:
        if master is not None:
            master.terminate()
            master.wait(10)
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
