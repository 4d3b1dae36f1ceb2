"""Benchmark of the ``scan`` events: what the laser overlay costs a page's link and the robot's CPU.

    .venv/bin/python bench/bench_scan.py [--seconds 10] [--repeat 2000]

One ``flask-move-server --sim`` process (speed factor 1, its own ROS master, default config) on
the demo flat, the robot at rest on its dock. With 0, 1 and 8 streams open (each drained by a
thread here, as a page reads it):

- the server process's CPU (``/proc/<pid>/stat``), % of one core. In ``--sim`` it includes the
  simulated lidar, which casts its 360 beams only while someone subscribes ``/scan`` (the relay,
  while a page looks): on a robot the scan comes from the lidar driver, another process;
- ``scan`` events per second per page, their size (points, bytes as sent), and the bytes per
  second per page, of scan events and of the whole stream.

Then the relay's own work per scan, out of any process noise: decimating a 360-beam scan to 180
points, turning them into the map frame and encoding the event, ``--repeat`` times.

Prints markdown tables (docs/performance.md, section "Laser scan overlay").
"""

import argparse
import json
import math
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time

import requests

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import ServerProcess, free_port, stop_process, wait_for  # noqa: E402
from tests.sse import EventReader  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sim import cpu_seconds  # noqa: E402  (a process's CPU from /proc, as bench_sim reads it)


class Page(threading.Thread):
    """One open stream, drained as a page would: counts the bytes of every event and of the scans."""

    def __init__(self, url):
        super().__init__(daemon=True)
        self.reader = wait_for(lambda: _opened(url), timeout=10, message="a free stream")
        self.scans = []  # (arrival, points, bytes)
        self.bytes = 0
        self.counting = False
        self.start()

    def run(self):
        try:
            for kind, data in iter(self.reader.next, None):
                if not self.counting:
                    continue
                size = len("event: {}\ndata: {}\n\n".format(kind, json.dumps(data, separators=(",", ":"))))
                self.bytes += size
                if kind == "scan":
                    self.scans.append((time.monotonic(), len(data["points"]), size))
        except (requests.RequestException, ValueError, AttributeError):
            pass  # closed by the bench

    def close(self):
        self.reader.close()


def _opened(url):
    reader = EventReader(url)
    if reader.status_code == 200:
        return reader
    reader.close()
    return None


def start_server(tmp):
    waypoints = os.path.join(tmp, "waypoints.yaml")
    shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), waypoints)
    env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(free_port()), "ROS_HOME": tmp,
           "ROS_LOG_DIR": os.path.join(tmp, "log"), "ROS_IP": "127.0.0.1"}
    server = ServerProcess("--sim", "--port", "0", "--no-mdns", "--waypoints", waypoints, env=env, start_timeout=60)
    wait_for(lambda: server.get("/health").json().get("move_base") == "ready", timeout=60, message="move_base")
    return server


def measure(server, streams, seconds):
    pages = [Page(server.url) for _ in range(streams)]
    try:
        time.sleep(3.0)  # the relay subscribes, the sim's lidar starts casting
        for page in pages:
            page.counting = True
        c0, t0 = cpu_seconds(server.proc.pid), time.monotonic()
        time.sleep(seconds)
        elapsed = time.monotonic() - t0
        cpu = 100.0 * (cpu_seconds(server.proc.pid) - c0) / elapsed
        for page in pages:
            page.counting = False
    finally:
        for page in pages:
            page.close()
    scans = [s for p in pages for s in p.scans]
    return dict(streams=streams, cpu=cpu,
                rate=statistics.mean(len(p.scans) / elapsed for p in pages) if pages else None,
                points=statistics.median(s[1] for s in scans) if scans else None,
                size=statistics.median(s[2] for s in scans) if scans else None,
                scan_bps=statistics.mean(sum(s[2] for s in p.scans) / elapsed for p in pages) if pages else None,
                all_bps=statistics.mean(p.bytes / elapsed for p in pages) if pages else None)


def relay_work(repeat):
    """µs per scan of the relay's own work: decimate, transform, encode (a 360-beam scan, 4 m round)."""
    from sensor_msgs.msg import LaserScan

    from flask_move_server.ros.scan import PlanarTransform, scan_points

    msg = LaserScan()
    msg.angle_min, msg.angle_increment = -math.pi, 2 * math.pi / 360
    msg.range_min, msg.range_max = 0.15, 8.0
    msg.ranges = [4.0] * 360
    transform = PlanarTransform(1.0, 2.0, ((0.0, -1.0), (1.0, 0.0)))
    started = time.perf_counter()
    for _ in range(repeat):
        json.dumps({"frame": "map", "points": scan_points(msg, transform)}, separators=(",", ":"))
    return (time.perf_counter() - started) / repeat * 1e6


def _or_dash(value, form):
    return "–" if value is None else form.format(value)


def print_tables(rows, work_us):
    print("| pages | server CPU | scan events/s per page | points per scan | bytes per scan event | "
          "scan bytes/s per page | all events bytes/s per page |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print("| {} | {:.1f} % | {} | {} | {} | {} | {} |".format(
            r["streams"], r["cpu"], _or_dash(r["rate"], "{:.2f}"), _or_dash(r["points"], "{:.0f}"),
            _or_dash(r["size"], "{:.0f}"), _or_dash(r["scan_bps"], "{:.0f}"), _or_dash(r["all_bps"], "{:.0f}")))
    print("\nThe relay's own work per scan (360 beams → 180 points in the map frame, JSON): {:.0f} µs, "
          "{:.2f} % of one core at 3 scans a second.".format(work_us, work_us * 3 / 1e4))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeat", type=int, default=2000)
    args = parser.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="bench_scan_")
    server = start_server(tmp)
    try:
        rows = [measure(server, streams, args.seconds) for streams in (0, 1, 8)]
    finally:
        stop_process(server.proc)
        shutil.rmtree(tmp, ignore_errors=True)
    print("`flask-move-server --sim`, speed factor 1, the robot at rest; CPU as % of one core; "
          "load average {:.1f}\n".format(os.getloadavg()[0]))
    print_tables(rows, relay_work(args.repeat))


if __name__ == "__main__":
    main()
