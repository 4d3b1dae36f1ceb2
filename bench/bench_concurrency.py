"""Concurrent clients against the server: does it scale with them, and does /stop stay quick?

Run: ``.venv/bin/python bench/bench_concurrency.py [--seconds 5] [--clients 1,2,8] [--compare DIR]`` (starts its own
ROS master and ``flask-move-server --motor-backend none``, no move_base). Each client is a process
of its own (no shared GIL with the others) holding one keep-alive connection and polling
``GET /status`` as fast as the server answers. Prints markdown tables for docs/performance.md:

1. throughput and latency per number of clients, and the ratio of 8 clients to 1 (target ≥ 0.9);
2. ``POST /stop`` latency while 8 clients poll (target p99 ≤ 10 ms);
3. ``GET /health`` latency with move_base absent (target p50 ≤ 1 ms).

``--compare DIR`` (repeatable) runs the same against the server in another checkout (``git worktree add DIR REV``),
in the same run, so a change is measured against what it replaced.

``--guard`` (``make bench-guard``, run by CI) is a pass/fail check of one server: in one run it
alternates windows of 1 client and of 8 clients (``--rounds`` of each, ``--seconds`` long) and
compares their throughputs round by round (8 clients against the 1 just before: the machine's own
speed drifts from 900 to 500 req/s within a minute here, which a ratio of the medians over the
whole run took for a regression), then times ``POST /stop`` while 8 clients poll. It
passes when 8 clients get at least ``--min-ratio`` of one client's throughput and ``/stop``'s p99
is at most ``--max-stop-p99`` ms or, on a machine where the polls themselves are slower than that,
at most the p99 of the polls made while the stops were timed (``/stop`` not queued behind the
reads; the windows before vary 18-54 ms from one to the next here, so a limit from them failed a
/stop no slower than the polls beside it), and exits 1
otherwise: once, no second try (a guard that passes on its second try hides the regression it is
for). A ratio within one run, not a number of requests per second, so a slower or busier machine
moves both sides. ``--checkout DIR`` guards the server of another checkout (to see that the guard
catches a regression: ``git worktree add DIR REV``).
"""

import argparse
import http.client
import multiprocessing
import os
import statistics
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.bench_server import start_server  # noqa: E402
from tests.conftest import free_port, start_master, stop_process  # noqa: E402


def poll(host, port, path, seconds, start_at, results):
    """One client: keep-alive GETs of ``path`` for ``seconds`` from ``start_at``; its latencies (s)."""
    conn = http.client.HTTPConnection(host, port, timeout=10)
    while time.time() < start_at:
        time.sleep(0.001)
    latencies = []
    stop = start_at + seconds
    while time.time() < stop:
        began = time.perf_counter()
        conn.request("GET", path)
        conn.getresponse().read()
        latencies.append(time.perf_counter() - began)
    conn.close()
    results.put(latencies)


def run_clients(host, port, path, clients, seconds):
    """(requests per second, all latencies) of ``clients`` processes polling at once."""
    results = multiprocessing.Queue()
    start_at = time.time() + 0.5
    procs = [multiprocessing.Process(target=poll, args=(host, port, path, seconds, start_at, results))
             for _ in range(clients)]
    for p in procs:
        p.start()
    latencies = []
    for _ in procs:
        latencies += results.get(timeout=seconds + 30)
    for p in procs:
        p.join()
    return len(latencies) / seconds, latencies


def timed(host, port, method, path, count, pause=0.02):
    """Latencies (s) of ``count`` requests on one keep-alive connection, ``pause`` s apart."""
    conn = http.client.HTTPConnection(host, port, timeout=10)
    latencies = []
    for _ in range(count):
        began = time.perf_counter()
        conn.request(method, path, body=b"" if method == "POST" else None)
        conn.getresponse().read()
        latencies.append(time.perf_counter() - began)
        time.sleep(pause)
    conn.close()
    return latencies


def pct(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))] * 1e3


def serve(env, cwd):
    """``flask-move-server --motor-backend none`` of ``cwd``'s checkout: (process, host, port)."""
    tmp = tempfile.mkdtemp(prefix="bench-concurrency-")
    waypoints = os.path.join(tmp, "waypoints.yaml")
    with open(waypoints, "w") as f:
        f.write("waypoints:\n  dock: [0.0, 0.0, 0.0]\n")
    env = dict(env, PYTHONPATH=cwd, ROS_HOME=tmp, ROS_LOG_DIR=os.path.join(tmp, "log"))
    server, host, port, _ = start_server(
        [sys.executable, "-m", "flask_move_server", "--host", "127.0.0.1", "--port", "0", "--no-mdns",
         "--motor-backend", "none", "--waypoints", waypoints], env, cwd=cwd)
    time.sleep(2.0)  # the node connects to the master
    return server, host, port


def measure(label, env, cwd, args, counts):
    """Every table for the server in ``cwd``'s checkout."""
    server, host, port = serve(env, cwd)
    try:
        print("## {}: GET /status, keep-alive clients (each its own process), {:g} s each; load {:.1f}\n".format(
            label, args.seconds, os.getloadavg()[0]))
        print("| clients | req/s | p50 ms | p99 ms |")
        print("|---:|---:|---:|---:|")
        rates = {}
        for n in counts:
            rate, lat = run_clients(host, port, "/status", n, args.seconds)
            rates[n] = rate
            print("| {} | {:,.0f} | {:.2f} | {:.2f} |".format(n, rate, pct(lat, 0.5), pct(lat, 0.99)))
        if 1 in rates and max(counts) in rates:
            print("\n{} clients / 1 client throughput: {:.2f} (target >= 0.9)".format(
                max(counts), rates[max(counts)] / rates[1]))
        stops = stops_while_polled(host, port, 8, 100)
        health = timed(host, port, "GET", "/health", 200, pause=0.005)
        print("\n| request | p50 ms | p99 ms | max ms |")
        print("|---|---:|---:|---:|")
        print("| POST /stop while 8 clients poll /status | {:.2f} | {:.2f} | {:.2f} |".format(
            pct(stops, 0.5), pct(stops, 0.99), max(stops) * 1e3))
        print("| GET /health, move_base absent | {:.2f} | {:.2f} | {:.2f} |\n".format(
            pct(health, 0.5), pct(health, 0.99), max(health) * 1e3))
    finally:
        stop_process(server)


def stops_while_polled(host, port, clients, count, polls=None):
    """``count`` POST /stop latencies (s), 20 ms apart, all while ``clients`` processes poll /status;
    ``polls`` (a list) gets those polls' latencies, the same stretch of time's."""
    told = []
    busy = threading.Thread(target=lambda: told.append(run_clients(host, port, "/status", clients,
                                                                     count * 0.05 + 1.5)))
    busy.start()
    time.sleep(1.0)  # the pollers started (run_clients starts them 0.5 s after it is called)
    stops = timed(host, port, "POST", "/stop", count)
    busy.join()
    if polls is not None and told:
        polls.extend(told[0][1])
    return stops


def guard(env, cwd, args):
    """The CI guard on ``cwd``'s server: True when it passes. Prints its table and verdict."""
    server, host, port = serve(env, cwd)
    try:
        run_clients(host, port, "/status", 1, 1.0)  # warm up: the first requests pay for imports and caches
        windows = {1: [], 8: []}
        p99s = {1: [], 8: []}
        for _ in range(args.rounds):
            for n in (1, 8):
                rate, lat = run_clients(host, port, "/status", n, args.seconds)
                windows[n].append(rate)
                p99s[n].append(pct(lat, 0.99))
        polls = []
        stops = stops_while_polled(host, port, 8, args.stops, polls)
    finally:
        stop_process(server)
    ratio = statistics.median(eight / one for one, eight in zip(windows[1], windows[8]))  # each round's own
    stop_p99, polls_p99 = pct(stops, 0.99), pct(polls, 0.99)
    stop_limit = max(args.max_stop_p99, polls_p99)
    print("## guard: {}; GET /status, {} rounds of {:g} s windows of 1 and of 8 client processes; "
          "load {:.1f}\n".format(cwd, args.rounds, args.seconds, os.getloadavg()[0]))
    print("| clients | req/s in each window | median req/s | p99 ms in each window |")
    print("|---:|---|---:|---|")
    for n in (1, 8):
        print("| {} | {} | {:,.0f} | {} |".format(
            n, ", ".join("{:,.0f}".format(r) for r in windows[n]), statistics.median(windows[n]),
            ", ".join("{:.1f}".format(p) for p in p99s[n])))
    print("\n| check | measured | target |")
    print("|---|---:|---:|")
    print("| 8 clients / 1 client, the median of each round's ratio | {:.2f} | >= {:g} |".format(ratio, args.min_ratio))
    print("| POST /stop p99 while 8 clients poll ({} stops) | {:.1f} ms | <= {:.1f} ms |".format(
        len(stops), stop_p99, stop_limit))
    print("\n/stop's target: {:g} ms, or the p99 of the 8 clients' polls while the stops were timed, when a "
          "poll itself is slower on this machine ({:.1f} ms).".format(args.max_stop_p99, polls_p99))
    passed = ratio >= args.min_ratio and stop_p99 <= stop_limit
    print("\n{}: 8 clients got {:.2f} of one client's throughput (target >= {:g}), POST /stop p99 {:.1f} ms "
          "while 8 clients poll (target <= {:.1f} ms).".format(
              "PASS" if passed else "FAIL", ratio, args.min_ratio, stop_p99, stop_limit), flush=True)
    return passed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, help="one window (default 5 s, --guard 2 s)")
    parser.add_argument("--clients", default="1,2,4,8")
    parser.add_argument("--compare", metavar="DIR", action="append", default=[],
                        help="another checkout's server, measured in the same run (repeatable)")
    parser.add_argument("--guard", action="store_true", help="pass/fail: 8 clients / 1 client and /stop's p99")
    parser.add_argument("--checkout", metavar="DIR", default=ROOT, help="--guard: the server of this checkout")
    parser.add_argument("--rounds", type=int, default=5, help="--guard: windows of 1 and of 8 clients")
    parser.add_argument("--stops", type=int, default=150, help="--guard: POST /stop timed while 8 clients poll")
    parser.add_argument("--min-ratio", type=float, default=0.8, help="--guard: 8 clients / 1 client at least")
    parser.add_argument("--max-stop-p99", type=float, default=25.0,
                        help="--guard: ms, /stop's p99 at most (or the polls' p99 if that is higher)")
    args = parser.parse_args()
    if args.seconds is None:
        args.seconds = 2.0 if args.guard else 5.0
    counts = [int(c) for c in args.clients.split(",")]
    master_port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(master_port), ROS_IP="127.0.0.1")
    master = start_master(master_port, env)
    try:
        if args.guard:
            return 0 if guard(env, os.path.abspath(args.checkout), args) else 1
        measure("this checkout", env, ROOT, args, counts)
        for other in args.compare:
            measure(os.path.basename(os.path.abspath(other)), env, os.path.abspath(other), args, counts)
    finally:
        stop_process(master)
    return 0


if __name__ == "__main__":
    sys.exit(main())
