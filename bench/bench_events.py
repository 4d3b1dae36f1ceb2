"""Benchmark of ``GET /events``: what open pages cost the robot, and how live they are.

    .venv/bin/python bench/bench_events.py [--rest-seconds 5] [--drive-seconds 10] [--stops 5]

One ``flask-move-server --sim`` process (speed factor 1, its own ROS master, default config:
6 workers, max_streams 8). With 0, 1 and 8 streams open (each drained by a thread here, as a
page would read it):

- the server's CPU (``/proc/<pid>/stat``) at rest and while driving, and its resident memory;
- pose events per second per stream while driving, the gaps between them, and how far the
  streamed pose lags behind ``/status`` (distance between the two / the robot's speed);
- the time from ``POST /estop`` to its ``estop`` event on every stream (the e-stop fast path);
- ``POST /stop`` round trips while driving.

Prints markdown tables (docs/performance.md, section "Live events").
"""

import argparse
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

TICKS = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")
FAR = {"x": 8.4, "y": 0.9, "yaw": 0.0}
DOCK = {"x": 0.0, "y": 0.0, "yaw": 0.0}


def cpu_seconds(pid):
    with open("/proc/{}/stat".format(pid)) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def cpu_share(pid, seconds):
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    return 100.0 * (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


def rss_mb(pid):
    with open("/proc/{}/statm".format(pid)) as f:
        return int(f.read().split()[1]) * PAGE / 1e6


class Page(threading.Thread):
    """One open stream, drained as a page would: remembers each event's kind and arrival."""

    def __init__(self, url):
        super().__init__(daemon=True)
        self.reader = wait_for(lambda: _opened(url), timeout=10, message="a free stream")  # a closed one's place
        self.poses = []  # (arrival, pose)
        self.estops = []  # (arrival, estop)
        self.start()

    def run(self):
        try:
            for kind, data in iter(self.reader.next, None):
                now = time.monotonic()
                if kind == "pose" and data:
                    self.poses.append((now, data))
                elif kind == "estop":
                    self.estops.append((now, data))
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


def drive(server, pages, seconds):
    """Drive towards the kitchen for ``seconds``: CPU, and the streamed pose's lag behind /status."""
    requests.post(server.url + "/goto", json=FAR, timeout=10)
    time.sleep(1.0)  # under way
    began = time.monotonic()
    lags = []
    c0 = cpu_seconds(server.proc.pid)
    while time.monotonic() - began < seconds:
        time.sleep(0.25)
        lag = pose_lag(server, pages)
        if lag is not None:
            lags.append(lag)
    cpu = 100.0 * (cpu_seconds(server.proc.pid) - c0) / (time.monotonic() - began)
    rates = [len([a for a, _ in p.poses if a >= began]) / (time.monotonic() - began) for p in pages]
    gaps = [b[0] - a[0] for p in pages for a, b in zip(p.poses, p.poses[1:]) if a[0] >= began]
    return cpu, rates, gaps, lags


def pose_lag(server, pages):
    """Seconds the first page's latest pose lags behind /status's, from the distance at the robot's speed."""
    status = requests.get(server.url + "/status", timeout=10).json()
    if not pages or not pages[0].poses or not status["pose"]:
        return None
    streamed = pages[0].poses[-1][1]
    speed = abs(status["motors"]["odom"]["linear"])
    if speed < 0.05:
        return None
    return math.hypot(status["pose"]["x"] - streamed["x"], status["pose"]["y"] - streamed["y"]) / speed


def stop_round_trips(server, count):
    """``POST /stop`` while driving, ``count`` times: round trips in ms."""
    times = []
    for _ in range(count):
        requests.post(server.url + "/goto", json=FAR, timeout=10)
        time.sleep(0.5)
        t = time.perf_counter()
        requests.post(server.url + "/stop", timeout=10)
        times.append((time.perf_counter() - t) * 1e3)
    return times


def estop_latencies(server, pages, count):
    """``POST /estop`` sent → its event read on every page, ``count`` times: ms (worst page each time)."""
    times = []
    for _ in range(count):
        seen = [len(p.estops) for p in pages]
        t = time.monotonic()
        requests.post(server.url + "/estop", timeout=10)
        wait_for(lambda seen=seen: all(len(p.estops) > n and p.estops[-1][1]["latched"] for p, n in zip(pages, seen)),
                 timeout=10, interval=0.001, message="the estop event on every page")
        times.append(max(p.estops[-1][0] - t for p in pages) * 1e3)
        requests.post(server.url + "/estop/release", timeout=10)
        time.sleep(0.3)
    return times


def back_to_dock(server):
    requests.post(server.url + "/goto", json=dict(DOCK, wait=120), timeout=130)


def measure(server, streams, args):
    rss0 = rss_mb(server.proc.pid)
    pages = [Page(server.url) for _ in range(streams)]
    try:
        time.sleep(1.0)
        rest = cpu_share(server.proc.pid, args.rest_seconds)
        rss = rss_mb(server.proc.pid)
        cpu, rates, gaps, lags = drive(server, pages, args.drive_seconds)
        stops = stop_round_trips(server, args.stops)
        estops = estop_latencies(server, pages, args.stops) if pages else []
        back_to_dock(server)
    finally:
        for page in pages:
            page.close()
    return dict(streams=streams, rest=rest, drive=cpu, rss=rss, rss0=rss0, rates=rates, gaps=gaps, lags=lags,
                stops=stops, estops=estops)


def _ms(values, fn=statistics.median):
    return "{:.0f}".format(fn(values) * 1e3) if values else "–"


def _p95(values):
    return sorted(values)[int(0.95 * (len(values) - 1))] if values else float("nan")


def print_tables(rows):
    print("| streams | CPU at rest | CPU driving | RSS MB (Δ per stream) | pose events/s per stream | "
          "gap median / p95 ms | pose lag median / p95 ms | /stop median / max ms | estop → event median / max ms |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        per = (r["rss"] - r["rss0"]) / r["streams"] if r["streams"] else 0.0
        rate = statistics.mean(r["rates"]) if r["rates"] else float("nan")
        estop = ("{:.1f} / {:.1f}".format(statistics.median(r["estops"]), max(r["estops"]))
                 if r["estops"] else "–")
        row = "| {} | {:.1f} % | {:.1f} % | {:.1f} ({:+.2f}) | {:.1f} | {} / {} | {} / {} | {:.1f} / {:.1f} | {} |"
        print(row.format(
            r["streams"], r["rest"], r["drive"], r["rss"], per, rate,
            _ms(r["gaps"]), _ms(r["gaps"], _p95), _ms(r["lags"]), _ms(r["lags"], _p95),
            statistics.median(r["stops"]), max(r["stops"]), estop))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rest-seconds", type=float, default=5.0)
    parser.add_argument("--drive-seconds", type=float, default=10.0)
    parser.add_argument("--stops", type=int, default=5)
    args = parser.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="bench_events_")
    server = start_server(tmp)
    try:
        rows = [measure(server, streams, args) for streams in (0, 1, 8)]
    finally:
        stop_process(server.proc)
        shutil.rmtree(tmp, ignore_errors=True)
    print("`flask-move-server --sim`, speed factor 1; CPU as % of one core; load average {:.1f}\n".format(
        os.getloadavg()[0]))
    print_tables(rows)


if __name__ == "__main__":
    main()
