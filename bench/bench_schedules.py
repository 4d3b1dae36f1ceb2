"""What schedules cost a server at rest (issue 23): CPU without routes and with 20 scheduled routes.

Two ``flask-move-server`` processes side by side on one ROS master, the same config (no motors,
``modes.stack: none``, no move_base, no clients): one with waypoints and no routes, one with the
same waypoints and ``--routes`` routes of ``--times`` timetable entries each (the most a route
takes), none due while the bench runs (the nearest is hours away). Both are measured over the same
windows, so the machine's load falls on both alike: user + system CPU from ``/proc/<pid>/stat``
over ``--seconds``, ``--repeat`` times, after ``--settle`` s for start-up to pass. The plain server
rather than ``--sim``: at rest it costs ~0.3-0.8 % of a core, where the simulation's 50 Hz world
and its laser cost ~5 % ± 0.5, which would hide a difference of 0.1 %.

The scheduler wakes once a minute (just after it begins) and checks every route's timetable; the
second table times that check alone, in this process, on the same waypoints file through the
server's own WaypointStore and Scheduler, a minute apart by an injected clock.

Run: ``.venv/bin/python bench/bench_schedules.py [--seconds S] [--repeat N] [--routes N]
[--times N]``. Starts its own ROS master. Prints two markdown tables.
"""

import argparse
import datetime
import os
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.bench_goals import Server, cpu_seconds  # noqa: E402
from tests.conftest import free_port, start_master, stop_process  # noqa: E402

CONFIG = """\
server: {{host: 127.0.0.1, port: 0}}
ros: {{node_name: {node}}}
waypoints: {{file: {waypoints}}}
navigation: {{goal_interface: action, action: move_base}}
drive: {{backend: none}}
modes: {{stack: none}}
"""
DAYS = ("", "mon-fri ", "sat,sun ", "tue,thu ", "mon,wed,fri ")


def timetable(count, away_hours=6):
    """``count`` entries, all at least ``away_hours`` h from now (so none is due while the bench runs)."""
    first = datetime.datetime.now() + datetime.timedelta(hours=away_hours)
    entries = []
    for i in range(count):
        at = first + datetime.timedelta(minutes=7 * i)  # ≤ 20 entries: within 2.3 h, never wrapping to now
        entries.append("{}{:02d}:{:02d}".format(DAYS[i % len(DAYS)], at.hour, at.minute))
    return entries


def waypoints_text(routes, times):
    lines = ["waypoints:", "  dock: [0.0, 0.0, 0.0]", "  kitchen: [3.2, 1.5, 1.57]", "  hall: [5.0, -1.0, 3.14]"]
    if routes:
        lines.append("routes:")
        for i in range(routes):
            schedule = ", ".join('"{}"'.format(entry) for entry in timetable(times))
            lines.append("  patrol{}: {{waypoints: [kitchen, hall, dock], loops: 2, dwell: 5.0, on_failure: skip, "
                         "schedule: [{}]}}".format(i + 1, schedule))
    return "\n".join(lines) + "\n"


def start(name, routes, times, env):
    home = tempfile.mkdtemp(prefix="bench-schedules-")
    waypoints = os.path.join(home, "waypoints.yaml")
    with open(waypoints, "w") as f:
        f.write(waypoints_text(routes, times))
    config = os.path.join(home, "robot.yaml")
    with open(config, "w") as f:
        f.write(CONFIG.format(node="bench_" + name.replace(" ", "_"), waypoints=waypoints))
    args = [sys.executable, "-m", "flask_move_server", "--config", config, "--no-mdns"]
    server = Server(name, args, env, "move_base", os.path.join(home, "server.log"))
    server.waypoints = waypoints
    return server


def idle_windows(servers, seconds, repeat):
    """Per window, each server's CPU over it, % of one core."""
    windows = []
    for _ in range(repeat):
        before = [cpu_seconds(s.proc.pid) for s in servers]
        started = time.monotonic()
        time.sleep(seconds)
        passed = time.monotonic() - started
        windows.append([(cpu_seconds(s.proc.pid) - b) / passed * 100 for s, b in zip(servers, before)])
    return windows


def check_cost(waypoints, checks=200):
    """ms of one scheduler check (every route's timetable, one minute apart), median and max."""
    from flask_move_server.missions.scheduler import Scheduler
    from flask_move_server.waypoints.store import WaypointStore

    store = WaypointStore(waypoints)
    started = []
    clock = [time.time()]
    scheduler = Scheduler(store.routes, started.append, wall=lambda: clock[0], monotonic=lambda: clock[0])
    routes = len(store.routes())  # the file loaded once, as the server has it
    times = []
    for _ in range(checks):
        clock[0] += 60.0
        t = time.perf_counter()
        scheduler.check()
        times.append((time.perf_counter() - t) * 1000)
    if started:
        raise RuntimeError("a route was due during the bench: {}".format(started[0].name))
    return routes, statistics.median(times), max(times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="length of one measured window")
    parser.add_argument("--repeat", type=int, default=3, help="windows")
    parser.add_argument("--settle", type=float, default=10.0, help="s after start-up before measuring")
    parser.add_argument("--routes", type=int, default=20, help="scheduled routes of the second server")
    parser.add_argument("--times", type=int, default=20, help="timetable entries per route (at most 20)")
    opts = parser.parse_args(argv)

    home = tempfile.mkdtemp(prefix="bench-schedules-ros-")
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_HOME=home, ROS_IP="127.0.0.1",
               PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))  # this checkout's server
    master = start_master(port, env)
    servers = []
    try:
        servers.append(start("no routes", 0, 0, env))
        servers.append(start("{} routes".format(opts.routes), opts.routes, opts.times, env))
        time.sleep(opts.settle)
        windows = idle_windows(servers, opts.seconds, opts.repeat)
        routes, median_ms, max_ms = check_cost(servers[1].waypoints)
    finally:
        for server in reversed(servers):
            stop_process(server.proc)
        stop_process(master)

    print("| server at rest, CPU over {:.0f} s (% of one core) | no routes | {} routes × {} times "
          "| difference |".format(opts.seconds, opts.routes, opts.times))
    print("|---|---:|---:|---:|")
    for i, (plain, scheduled) in enumerate(windows):
        print("| window {} | {:.2f} | {:.2f} | {:+.2f} |".format(i + 1, plain, scheduled, scheduled - plain))
    plain = statistics.mean(w[0] for w in windows)
    scheduled = statistics.mean(w[1] for w in windows)
    print("| mean | {:.2f} | {:.2f} | {:+.2f} |".format(plain, scheduled, scheduled - plain))
    print()
    print("| one schedule check ({} routes × {} times, every minute) | median ms | max ms | % of one core |".format(
        routes, opts.times))
    print("|---|---:|---:|---:|")
    print("| Scheduler.check() | {:.3f} | {:.3f} | {:.4f} |".format(median_ms, max_ms, median_ms / 60000 * 100))


if __name__ == "__main__":
    main()
