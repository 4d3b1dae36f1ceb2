"""Benchmarks of the simulation: planning time, and the CPU the simulated robot costs.

    .venv/bin/python bench/bench_sim.py [--drive-seconds 20]

1. Planning (pure, in this process): A* + shortcuts across the demo flat, and
   across 400 x 400 cell maps (an open hall with pillars, and a serpentine of
   corridors that makes A* visit most of the map). Targets: <= 100 ms on the
   demo map, <= 500 ms on 400 x 400.
2. The whole ``flask-move-server --sim`` process (server, base controller, world,
   move_base stand-in; its own ROS master) at speed factor 1, with a /scan
   subscriber in another process as RViz would be: CPU share of one core at
   rest and while driving, and the world's update rate (does it keep real
   time?). Target: <= 30 % of one core.

Prints markdown tables (docs/performance.md, section Simulation).
"""

import argparse
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.sim import costmap, occupancy, planner  # noqa: E402

TICKS = os.sysconf("SC_CLK_TCK")


# 1. planning ------------------------------------------------------------------------------

def timed_plans(plan, start, goal, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        path = plan(start, goal)
        times.append((time.perf_counter() - t) * 1e3)
    return times, path


def synthetic_map(tmp, name, width, height, walls):
    """A map_server map of ``width`` x ``height`` cells (0.05 m) with rectangular obstacles (in cells)."""
    pixels = bytearray([254]) * (width * height)
    for c0, r0, c1, r1 in walls:
        for r in range(r0, r1):
            pixels[r * width + c0:r * width + c1] = bytes([0]) * (c1 - c0)
    occupancy.write_pgm(os.path.join(tmp, name + ".pgm"), width, height, pixels)
    path = os.path.join(tmp, name + ".yaml")
    with open(path, "w") as f:
        f.write("image: {}.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n".format(name))
    return path


def hall_walls(n=400):
    """Outer walls and a grid of 0.5 m pillars every 2 m."""
    walls = [(0, 0, n, 2), (0, n - 2, n, n), (0, 0, 2, n), (n - 2, 0, n, n)]
    walls += [(c, r, c + 10, r + 10) for c in range(30, n - 30, 40) for r in range(30, n - 30, 40)]
    return walls


def serpentine_walls(n=400):
    """Outer walls and 9 long walls, each with its 1 m door at the opposite end from the last."""
    walls = [(0, 0, n, 2), (0, n - 2, n, n), (0, 0, 2, n), (n - 2, 0, n, n)]
    for i, r in enumerate(range(40, n - 20, 40)):
        walls.append((2, r, n - 22, r + 2) if i % 2 == 0 else (22, r, n - 2, r + 2))
    return walls


def planning_rows(repeat):
    rows = []
    grid = occupancy.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
    cases = [("demo flat {}x{}: dock → bedroom".format(grid.width, grid.height), grid, (0.0, 0.0), (6.2, 4.5)),
             ("demo flat: office desk → kitchen counter", grid, (-1.5, 4.6), (8.9, -1.5))]
    with tempfile.TemporaryDirectory() as tmp:
        for name, walls in (("hall", hall_walls()), ("serpentine", serpentine_walls())):
            big = occupancy.load(synthetic_map(tmp, name, 400, 400, walls))
            cases.append(("400x400 {}: corner → corner".format(name), big, (0.5, 0.5), (19.5, 19.5)))
    for name, g, start, goal in cases:
        t = time.perf_counter()
        cm = costmap.Costmap(g, 0.15, 0.1)
        inflate_ms = (time.perf_counter() - t) * 1e3
        times, path = timed_plans(planner.Planner(cm).plan, start, goal, repeat)
        rows.append((name, statistics.median(times), max(times), inflate_ms, planner.path_length(path), len(path)))
    return rows


# 2. the sim process ------------------------------------------------------------------------

def dwa_step_rows(repeat=2000):
    """One control step of the move_base stand-in's local planner: DWA's window, samples, the nearest."""
    from flask_move_server.sim import dwa

    limits = dwa.load(os.path.join(ROOT, "config"))
    cases = [("from rest", (0.0, 0.0)), ("cruising 0.3 m/s", (0.3, 0.2)), ("turning 1.0 rad/s", (0.0, 1.0))]
    rows = []
    for name, current in cases:
        start = time.perf_counter()
        for _ in range(repeat):
            dwa.nearest(limits, (0.25, 0.4), current)
        rows.append((name, len(dwa.samples(limits, *current)), (time.perf_counter() - start) / repeat * 1e6))
    return rows, limits.move_base_frequency


def cpu_seconds(pid):
    with open("/proc/{}/stat".format(pid)) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def cpu_share(pid, seconds):
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    return 100.0 * (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


SCAN_LISTENER = """
import rospy, sys
from sensor_msgs.msg import LaserScan
rospy.init_node("bench_scan_listener", anonymous=True)
count = [0]
rospy.Subscriber("/scan", LaserScan, lambda m: count.__setitem__(0, count[0] + 1))
rospy.sleep(float(sys.argv[1]))
print(count[0])
"""


def sim_rows(drive_seconds):
    import requests

    from tests.conftest import free_port, wait_for

    tmp = tempfile.mkdtemp()
    waypoints = os.path.join(tmp, "waypoints.yaml")  # a copy: the server keeps mode.json and maps/ beside it
    shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), waypoints)
    master = "http://127.0.0.1:{}".format(free_port())
    env = dict(os.environ, ROS_MASTER_URI=master, ROS_HOME=tmp, ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1")
    server = subprocess.Popen(
        [sys.executable, "-m", "flask_move_server", "--sim", "--port", "0", "--no-mdns",
         "--waypoints", waypoints],
        env=env, cwd=tmp, stderr=subprocess.PIPE, text=True)
    lines = []
    threading.Thread(target=lambda: lines.extend(server.stderr), daemon=True).start()
    try:
        url = wait_for(lambda: _match(lines, r"serving the API on (http://\S+)"), 60, message="server").group(1)
        wait_for(lambda: requests.get(url + "/health").json()["move_base"] == "ready", 30, message="move_base")
        listen_for = 6 + drive_seconds
        listener = subprocess.Popen([sys.executable, "-c", SCAN_LISTENER, str(listen_for)], env=env,
                                    stdout=subprocess.PIPE, text=True)
        time.sleep(2)
        idle = cpu_share(server.pid, 4)
        requests.post(url + "/goto", json={"name": "bedroom"}, timeout=10)
        driving = cpu_share(server.pid, drive_seconds)
        moved = requests.get(url + "/status").json()["pose"]
        scans = int(listener.communicate(timeout=60)[0].strip() or 0)
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(30)
    stats = _match(lines, r"(\d+) updates in ([\d.]+) s \(([\d.]+) Hz, target (\d+) Hz\), longest gap (\d+) ms")
    return idle, driving, moved, scans / listen_for, stats


def _match(lines, pattern):
    for line in list(lines):
        m = re.search(pattern, line)
        if m:
            return m
    return None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--drive-seconds", type=float, default=20.0)
    args = parser.parse_args(argv)
    print("## Planning (A* + shortcuts, robot radius 0.15 m + 0.1 m margin)\n")
    print("| map | median ms | max ms | costmap build ms | path m | corners |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, med, worst, inflate, length, corners in planning_rows(args.repeat):
        print("| {} | {:.1f} | {:.1f} | {:.0f} | {:.1f} | {} |".format(name, med, worst, inflate, length, corners))
    idle, driving, pose, scan_hz, stats = sim_rows(args.drive_seconds)
    rows, hz = dwa_step_rows()
    print("\n## The move_base stand-in's DWA step (config/, at {:g} Hz)\n".format(hz))
    print("| current velocity | valid samples | µs per step |")
    print("|---|---:|---:|")
    for name, count, micros in rows:
        print("| {} | {} | {:.0f} |".format(name, count, micros))
    print("\n## `flask-move-server --sim` (speed factor 1, /scan subscribed)\n")
    print("| measure | value |")
    print("|---|---:|")
    print("| CPU, robot at rest | {:.1f} % of one core |".format(idle))
    print("| CPU, driving to the bedroom ({:.0f} s) | {:.1f} % of one core |".format(args.drive_seconds, driving))
    print("| pose after driving | x {:.2f}, y {:.2f} |".format(pose["x"], pose["y"]) if pose else "| pose | none |")
    print("| /scan received | {:.1f} Hz |".format(scan_hz))
    if stats:
        print("| world updates | {} in {} s = {} Hz (target {} Hz) |".format(*stats.groups()[:4]))
        print("| longest gap between updates | {} ms |".format(stats.group(5)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
