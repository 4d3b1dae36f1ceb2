"""Webhook receivers that misbehave, and the robot (issue 34): ``/stop``, the drive loop's worst gap, RSS.

For each receiver (one that answers 204 at once; one that answers 200 and then a body without end,
256 MB a connection at most; one that sends its answer a byte every 0.5 s and never finishes), a
``flask-move-server --sim`` (a token, its own master) whose three webhooks all go to it, for
``failed``: this bench sends a goal into a wall 10 times a second (each fails at once: a ``failed``
happening for each webhook), times ``POST /stop`` every 0.2 s, takes the worst gap between two
``/odom`` messages (the drive loop's), reads the server's VmRSS before and after and its peak, and counts the
POSTs the receiver was sent. ``--compare
DIR`` measures another checkout's server the same way, in the same run (``git worktree add DIR REV``).

Run: ``.venv/bin/python bench/bench_webhooks.py [--seconds S] [--compare DIR]``. Prints a markdown
table (``peak RSS``: the server's VmHWM, as a whole answer read in is freed again before "after"). Targets:
``/stop`` p99 <= 50 ms, gap <= 100 ms, RSS growth (peak too) <= 5 MB.
"""

import argparse
import http.client
import json
import os
import shutil
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_abuse import HEADERS, TOKEN, percentile  # noqa: E402
from bench_drive_gaps import OdomGaps  # noqa: E402

from tests.conftest import ServerProcess, free_port, start_master, stop_process, wait_for  # noqa: E402
from tests.hostile import HostileReceiver  # noqa: E402
from tests.test_webhooks import Receiver  # noqa: E402

IN_THE_WALL = {"x": -2.1, "y": 0.0, "yaw": 0.0}  # the living room's outer wall: a goal that fails at once


class WebhookServer(ServerProcess):
    """``flask-move-server --sim`` of the checkout ``root``, with three webhooks to ``url`` on ``failed``."""

    def __init__(self, home, url, master_port, root=ROOT):
        shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), os.path.join(home, "waypoints.yaml"))
        hooks = "".join("  - url: {}/{}\n    events: [failed]\n".format(url, n) for n in range(3))
        with open(os.path.join(home, "sim.yaml"), "w") as f:
            f.write("server:\n  token: {}\nwebhooks:\n{}".format(TOKEN, hooks))
        self.master_uri = "http://127.0.0.1:{}".format(master_port)
        env = {"ROS_MASTER_URI": self.master_uri, "ROS_HOME": home, "ROS_LOG_DIR": os.path.join(home, "log"),
               "ROS_IP": "127.0.0.1", "PYTHONPATH": root}
        super().__init__("--sim", "--config", os.path.join(home, "sim.yaml"), "--port", "0", "--no-mdns",
                         "--waypoints", os.path.join(home, "waypoints.yaml"), env=env, start_timeout=60, cwd=root)
        self.port = int(self.url.rsplit(":", 1)[1])
        wait_for(lambda: self.call("GET", "/health")[1].get("move_base") == "ready", timeout=30)

    def call(self, method, path, body=None, timeout=10):
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=timeout)
        started = time.perf_counter()
        try:
            conn.request(method, path, body=None if body is None else json.dumps(body), headers=HEADERS)
            response = conn.getresponse()
            data = response.read()
        finally:
            conn.close()
        return response.status, json.loads(data or b"{}"), time.perf_counter() - started

    def rss_mb(self, field="VmRSS:"):
        """The server's resident memory (``VmHWM:``: its peak so far), MB."""
        with open("/proc/{}/status".format(self.proc.pid)) as f:
            return next(int(line.split()[1]) for line in f if line.startswith(field)) / 1024.0


def measure(server, gaps, seconds):
    """(stop p99 ms, worst odom gap ms, RSS before, peak RSS, RSS after) while failing goals fire webhooks."""
    before = server.rss_mb()
    stops, done = [], threading.Event()

    def goals():
        while not done.wait(0.1):
            server.call("POST", "/goto", IN_THE_WALL)
    sender = threading.Thread(target=goals, daemon=True)
    since = time.monotonic()
    sender.start()
    try:
        end = since + seconds
        while time.monotonic() < end:
            stops.append(server.call("POST", "/stop")[2] * 1000)
            time.sleep(0.2)
    finally:
        done.set()
        sender.join(5)
    time.sleep(1.0)  # what the last goals queued is being sent
    worst, _ = gaps.worst(since)
    return percentile(stops, 99), worst, before, server.rss_mb("VmHWM:"), server.rss_mb()


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=15.0, help="how long each receiver is measured")
    parser.add_argument("--compare", metavar="DIR", action="append", default=[], help="another checkout's server")
    opts = parser.parse_args()
    import rospy

    master_port = free_port()  # one master for every server, so the /odom subscription follows each one
    master = start_master(master_port)
    os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:{}".format(master_port)
    rospy.init_node("bench_webhooks", anonymous=True, disable_signals=True)
    gaps = OdomGaps()
    try:
        rows = run_all(opts, master_port, gaps)
    finally:
        stop_process(master)
    print("| server | the receiver | POST /stop p99 ms | worst /odom gap ms | RSS before MB | peak RSS MB "
          "| RSS after MB | POSTs |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print("| {} | {} | {:.1f} | {:.0f} | {:.1f} | {:.1f} | {:.1f} | {} |".format(*row))


def tries(receiver):
    """How many webhook POSTs the receiver was sent (connections, for a hostile one)."""
    return len(receiver.requests) if hasattr(receiver, "requests") else receiver.connections


def run_all(opts, master_port, gaps):
    """One row per (checkout, receiver)."""
    rows = []
    receivers = [("answers 204 at once", lambda: Receiver(answers=(204,))),
                 ("answers an endless body", lambda: HostileReceiver(limit=256 * 2 ** 20)),
                 ("answers a byte every 0.5 s", lambda: HostileReceiver(trickle=0.5))]
    for root in [ROOT] + [os.path.abspath(d) for d in opts.compare]:
        for name, make in receivers:
            receiver = make()
            home = tempfile.mkdtemp(prefix="bench-webhooks-")
            server = WebhookServer(home, receiver.url, master_port, root)
            try:
                rows.append((os.path.basename(root) if root != ROOT else "this checkout", name)
                            + measure(server, gaps, opts.seconds) + (tries(receiver),))
            finally:
                server.call("POST", "/stop")
                stop_process(server.proc)
                receiver.close()
    return rows


if __name__ == "__main__":
    main()
