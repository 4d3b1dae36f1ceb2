"""What one change of a map's waypoints and routes costs as the map fills up (issue 34, items 4 and 7).

Run: ``.venv/bin/python bench/bench_map_file.py [--repeat 5] [--compare DIR ...]``.

A ``PUT /routes/<name>`` re-writes the whole waypoints file (the seed format, fsynced, the last good
version kept as ``.bak``), and a restart reads it back. Each row is a map's file of that size, made
of routes of long names (200 stops of 64 characters: the biggest a route can be); the bench times
``WaypointStore.put_route`` of one more route (the median of ``--repeat``, each on a fresh copy)
and the load a restart does, in this process, on a real file in a temporary folder. What the store
refuses is shown as its error code. ``--compare DIR`` runs the same in other checkouts (``git
worktree add DIR REV``), one after the other in the same run.

``--served`` then measures it on a running robot, as the issue's probe did: a ``--sim`` server with
MQTT and Home Assistant's discovery on (a real mosquitto: each change re-publishes the Route
select), whose map's file is the biggest that checkout's API lets it write (this checkout: just
under its 512 Ki-character limit; a checkout without the limit: just under the 4 Mi characters the
reader takes). Over ``--window`` s, a client PUTs that route again and again (each PUT re-writes
the whole file) while a process of its own POSTs ``/stop`` every 0.2 s and a subscriber here takes
the drive loop's worst gap between two ``/odom`` messages (bench_mqtt_floods' way).
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STOPS = 200
NAME = 60  # characters before a 4-digit number: 64, the longest a name can be
SIZES = ((5, "5 routes"), (36, "36 routes (about 500 KB)"), (100, "100 routes (about 1.3 MB)"),
         (300, "300 routes (about 4 MB)"))


def measure(root, repeat):
    """{label: (text length, put seconds or error code, load seconds)} with the code of checkout ``root``."""
    sys.path.insert(0, root)
    from flask_move_server.core.errors import MoveServerError
    from flask_move_server.missions.route import make_route
    from flask_move_server.waypoints import make_waypoint
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.waypoints.yaml_format import dump

    stops = [make_waypoint("{}{:04d}".format("a" * NAME, i), i * 0.01, 0.0, 0.0) for i in range(STOPS)]
    names = [w.name for w in stops]
    results = {}
    for count, label in SIZES:
        routes = [make_route("r{:04d}".format(i), {"waypoints": [names[(i + j) % STOPS] for j in range(STOPS)]})
                  for i in range(count)]
        text = dump(stops, routes[:-1])
        puts, loads = [], []
        for _ in range(repeat):
            folder = tempfile.mkdtemp(prefix="bench-map-file-")
            try:
                path = os.path.join(folder, "waypoints.yaml")
                with open(path, "w", encoding="utf-8") as f:
                    f.write(text)
                store = WaypointStore(path)
                started = time.perf_counter()
                try:
                    store.put_route(routes[-1])
                    puts.append(time.perf_counter() - started)
                except MoveServerError as exc:
                    puts.append(exc.code)
                started = time.perf_counter()
                WaypointStore(path).all()
                loads.append(time.perf_counter() - started)
            finally:
                shutil.rmtree(folder)
        put = puts[0] if isinstance(puts[0], str) else statistics.median(puts)
        results[label] = (len(text), put, statistics.median(loads))
    return results


def served(roots, window):
    """[(checkout, file characters, PUTs, PUT median s, PUT max s, /stop p99 ms, worst /odom gap ms, peak RSS)]."""
    import pathlib

    sys.path.insert(0, os.path.join(ROOT, "bench"))
    sys.path.insert(0, ROOT)
    from bench_drive_gaps import OdomGaps
    from bench_mqtt import Sim, Stopper, percentile
    from bench_mqtt_floods import rss_mb

    from tests.conftest import free_port, start_master, stop_process
    from tests.mqtt_broker import Broker

    folder = pathlib.Path(tempfile.mkdtemp(prefix="bench-map-file-served-"))
    broker, port = Broker(folder), free_port()
    master = start_master(port)
    os.environ.update(ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_IP="127.0.0.1")
    import rospy

    rospy.init_node("bench_map_file", anonymous=True, disable_signals=True)
    gaps, rows = OdomGaps(), []
    try:
        for root in roots:
            sim = Sim(folder / str(len(rows)), broker, root=root, master_uri=os.environ["ROS_MASTER_URI"])
            try:
                rows.append((_label(root),) + _put_storm(sim, root, gaps, window, Stopper, percentile, rss_mb))
            finally:
                stop_process(sim.proc)
    finally:
        stop_process(master)
        broker.stop()
    return rows


def _put_storm(sim, root, gaps, window, Stopper, percentile, rss_mb):
    """Fill ``sim``'s map as far as its API lets it, then PUT its last route again and again for ``window`` s."""
    from flask_move_server.missions.route import make_route
    from flask_move_server.waypoints import make_waypoint
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.waypoints.yaml_format import dump

    with open(os.path.join(root, "flask_move_server", "waypoints", "store.py"), encoding="utf-8") as f:
        capped = "MAX_SAVED" in f.read()  # this checkout's limit, or none (the code before it)
    path = sim.proc.args[sim.proc.args.index("--waypoints") + 1]
    long_names = ["{}{:04d}".format("a" * NAME, i) for i in range(STOPS)]
    places = WaypointStore(path).all() + [make_waypoint(n, 0.0, 0.0, 0.0) for n in long_names]
    body = {"waypoints": long_names}
    routes = [make_route("r{:04d}".format(i), body) for i in range(34 if capped else 300)]
    with open(path, "w", encoding="utf-8") as f:  # what that checkout's API would have written, route by route
        f.write(dump(places, routes))
    size = os.path.getsize(path)
    _call(sim, "GET", "/routes", None)  # the server reads it once, before the window
    times, stop_at = [], [False]
    start = time.monotonic() + 0.5
    stopper = Stopper(sim, 0.2, start, start + window)

    def storm():
        while not stop_at[0]:
            began = time.monotonic()
            _call(sim, "PUT", "/routes/r0000", body)
            times.append(time.monotonic() - began)

    time.sleep(max(0.0, start - time.monotonic()))
    thread = threading_thread(storm)
    time.sleep(max(0.0, start + window - time.monotonic()))
    stop_at[0] = True
    stopper.join()
    thread.join(120)
    worst, _ = gaps.worst(start)
    return (size, len(times), statistics.median(times) if times else float("nan"), max(times, default=float("nan")),
            percentile(stopper.times, 99), worst, rss_mb(sim.proc.pid, "VmHWM:"))


def threading_thread(target):
    import threading

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    return thread


def _call(sim, method, path, body):
    import http.client
    import urllib.parse

    host, port = sim.url.rsplit("/", 1)[1].split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=120)
    try:
        conn.request(method, urllib.parse.quote(path), body=None if body is None else json.dumps(body),
                     headers={"Content-Type": "application/json"})
        response = conn.getresponse()
        response.read()
        return response.status
    finally:
        conn.close()


def _label(root):
    return "this checkout" if root == ROOT else os.path.basename(root)


def cell(value):
    return "{:.2f}".format(value) if isinstance(value, float) else "refused: `{}`".format(value)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--compare", action="append", default=[], help="another checkout (git worktree)")
    parser.add_argument("--served", action="store_true", help="also on a running --sim server (minutes)")
    parser.add_argument("--window", type=float, default=20.0, help="--served: seconds of PUTs measured")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)  # one checkout's, for --compare
    args = parser.parse_args(argv)
    if args.json:
        print(json.dumps(measure(os.getcwd(), args.repeat)))
        return
    checkouts = [("this checkout", ROOT)] + [(os.path.basename(os.path.abspath(d)), os.path.abspath(d))
                                             for d in args.compare]
    rows = []
    for name, root in checkouts:
        command = [sys.executable, os.path.abspath(__file__), "--json", "--repeat", str(args.repeat)]
        out = subprocess.run(command, cwd=root, capture_output=True, text=True, check=True,
                             env=dict(os.environ, PYTHONPATH=root))
        rows.append((name, json.loads(out.stdout)))
    print("| the map's file before the change | checkout | characters | PUT of one more route (s) | "
          "load at restart (s) |")
    print("|---|---|---:|---:|---:|")
    for _count, label in SIZES:
        for name, results in rows:
            length, put, load = results[label]
            print("| {} | {} | {:,} | {} | {:.2f} |".format(label, name, length, cell(put), load))
    if args.served:
        rows = served([root for _name, root in checkouts], args.window)
        print("\n| server | its map's file (bytes) | PUTs in the window | PUT median s | PUT max s | POST /stop p99 ms "
              "| worst /odom gap ms | peak RSS MB |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
        for row in rows:
            print("| {} | {:,} | {} | {:.2f} | {:.2f} | {:.1f} | {:.0f} | {:.1f} |".format(*row))


if __name__ == "__main__":
    main()
