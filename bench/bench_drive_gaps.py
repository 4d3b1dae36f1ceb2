"""The drive loop under hostile loads (issue 21): the worst gap in ``/odom`` while each load runs.

The base controller's control thread publishes ``/odom`` at ``drive.odom_rate`` (20 Hz: 50 ms
apart) and its watchdog stops the motors when ``/cmd_vel`` stops for ``cmd_vel_timeout``; both
share the server's process (and its GIL) with every request. This bench subscribes to ``/odom``
from its own process while the robot drives and each load runs for ``--seconds``, and prints the
largest gap between two messages (the time the drive loop, or its publishing, stood still).

Run: ``.venv/bin/python bench/bench_drive_gaps.py [--seconds S]`` (a ``flask-move-server --sim``
with a token, its own master; loopback only). Prints a markdown table.
"""

import argparse
import http.client
import json
import os
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_abuse import HEADERS, SimServer  # noqa: E402

from tests.hostile import HostileClients, PipelineFlood  # noqa: E402


class OdomGaps:
    """Arrival times of ``/odom`` messages, from a subscriber in this process."""

    def __init__(self, topic="/odom"):
        import rospy
        from nav_msgs.msg import Odometry

        self.times = []
        self._sub = rospy.Subscriber(topic, Odometry, lambda msg: self.times.append(time.monotonic()),
                                     queue_size=100, tcp_nodelay=True)

    def worst(self, since):
        """(largest gap in ms, messages) among the messages after ``since``."""
        times = [t for t in self.times if t >= since]
        gaps = [b - a for a, b in zip(times, times[1:])]
        return (max(gaps) * 1000 if gaps else float("nan")), len(times)


def quiet(server, seconds):
    time.sleep(seconds)


def hostile(server, seconds):
    with HostileClients("127.0.0.1", server.port, count=300, max_seconds=seconds + 5):
        time.sleep(seconds)


def pipelining(server, seconds):
    with PipelineFlood("127.0.0.1", server.port, count=300, depth=50, max_seconds=seconds + 5):
        time.sleep(seconds)


def storm(server, seconds, path="/waypoints/storm", method="PUT", clients=8):
    end = time.monotonic() + seconds

    def client(i):
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
        n = 0
        while time.monotonic() < end:
            body = json.dumps({"x": float(n % 50), "y": float(i), "yaw": 0.0}) if method == "PUT" else None
            conn.request(method, path + ("{}_{}".format(i, n % 5) if method == "PUT" else ""), body=body,
                         headers=HEADERS)
            conn.getresponse().read()
            n += 1

    threads = [threading.Thread(target=client, args=(i,)) for i in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(seconds + 30)


def goal_storm(server, seconds):
    end = time.monotonic() + seconds
    n = 0
    while time.monotonic() < end:
        server.call("POST", "/goto", {"x": 8.4 - (n % 2) * 8.0, "y": 0.9, "yaw": 0.0})
        n += 1


def deep_waypoints(server, seconds):
    """The owner's editor saving a waypoints file of 5,000 nested brackets, read back each time."""
    path, good = server.waypoints_file, open(server.waypoints_file).read()
    end, n = time.monotonic() + seconds, 0
    try:
        while time.monotonic() < end:
            with open(path, "w") as f:
                f.write("waypoints:\n  k: " + "[" * 5000 + "]" * 5000 + "\n# {}\n".format(n))
            server.call("GET", "/waypoints")
            n += 1
            time.sleep(0.2)
    finally:
        with open(path, "w") as f:
            f.write(good)


def maps_listing(server, seconds):
    storm(server, seconds, path="/maps", method="GET", clients=4)


LOADS = [
    ("quiet (the robot driving, nothing else)", quiet),
    ("300 idle and slow-loris connections", hostile),
    ("300 connections pipelining 50 requests each", pipelining),
    ("8 clients PUT /waypoints/<name>", storm),
    ("a goal storm (one client, back to back)", goal_storm),
    ("4 clients GET /maps (the maps folder: {maps})", maps_listing),
    ("the waypoints file saved with 5,000 nested brackets, 5 times a second", deep_waypoints),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="how long each load runs")
    parser.add_argument("--maps", help="a folder whose files are copied into the maps folder (hostile maps)")
    opts = parser.parse_args()

    home = tempfile.mkdtemp(prefix="bench-gaps-")
    server = SimServer(home)
    if opts.maps:
        import shutil

        folder = os.path.join(home, "maps")
        os.makedirs(folder, exist_ok=True)
        for name in os.listdir(opts.maps):
            shutil.copy(os.path.join(opts.maps, name), folder)
    os.environ["ROS_MASTER_URI"] = server.master_uri
    import rospy

    rospy.init_node("bench_drive_gaps", anonymous=True, disable_signals=True)
    gaps = OdomGaps()
    rows = []
    try:
        for name, load in LOADS:
            server.drive_far()
            since = time.monotonic()
            load(server, opts.seconds)
            worst, count = gaps.worst(since)
            server.call("POST", "/stop")
            rows.append((name.format(maps=opts.maps or "empty"), count, worst))
    finally:
        server.close()
        rospy.signal_shutdown("done")
    print("| load, {:.0f} s each, the robot driving | /odom messages | worst gap ms |".format(opts.seconds))
    print("|---|---:|---:|")
    for name, count, worst in rows:
        print("| {} | {} | {:.0f} |".format(name, count, worst))


if __name__ == "__main__":
    main()
