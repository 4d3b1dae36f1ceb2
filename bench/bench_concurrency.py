"""Concurrent clients against the server: does it scale with them, and does /stop stay quick?

Run: ``.venv/bin/python bench/bench_concurrency.py [--seconds 5] [--clients 1,2,8] [--compare DIR]`` (starts its own
ROS master and ``flask-move-server --motor-backend none``, no move_base). Each client is a process
of its own (no shared GIL with the others) holding one keep-alive connection and polling
``GET /status`` as fast as the server answers. Prints markdown tables for docs/performance.md:

1. throughput and latency per number of clients, and the ratio of 8 clients to 1 (target ≥ 0.9);
2. ``POST /stop`` latency while 8 clients poll (target p99 ≤ 10 ms);
3. ``GET /health`` latency with move_base absent (target p50 ≤ 1 ms).

``--compare DIR`` runs the same against the server in another checkout (``git worktree add DIR REV``),
in the same run, so a change is measured against what it replaced.
"""

import argparse
import http.client
import multiprocessing
import os
import sys
import tempfile
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


def measure(label, env, cwd, args, counts):
    """Every table for the server in ``cwd``'s checkout."""
    tmp = tempfile.mkdtemp(prefix="bench-concurrency-")
    waypoints = os.path.join(tmp, "waypoints.yaml")
    with open(waypoints, "w") as f:
        f.write("waypoints:\n  dock: [0.0, 0.0, 0.0]\n")
    env = dict(env, PYTHONPATH=cwd, ROS_HOME=tmp, ROS_LOG_DIR=os.path.join(tmp, "log"))
    server, host, port, _ = start_server(
        [sys.executable, "-m", "flask_move_server", "--host", "127.0.0.1", "--port", "0", "--no-mdns",
         "--motor-backend", "none", "--waypoints", waypoints], env, cwd=cwd)
    try:
        time.sleep(2.0)  # the node connects to the master
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
        busy = multiprocessing.Process(target=run_clients, args=(host, port, "/status", 8, args.seconds))
        busy.start()
        time.sleep(1.0)
        stops = timed(host, port, "POST", "/stop", 100)
        busy.join()
        health = timed(host, port, "GET", "/health", 200, pause=0.005)
        print("\n| request | p50 ms | p99 ms | max ms |")
        print("|---|---:|---:|---:|")
        print("| POST /stop while 8 clients poll /status | {:.2f} | {:.2f} | {:.2f} |".format(
            pct(stops, 0.5), pct(stops, 0.99), max(stops) * 1e3))
        print("| GET /health, move_base absent | {:.2f} | {:.2f} | {:.2f} |\n".format(
            pct(health, 0.5), pct(health, 0.99), max(health) * 1e3))
    finally:
        stop_process(server)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--clients", default="1,2,4,8")
    parser.add_argument("--compare", metavar="DIR", help="another checkout's server, measured in the same run")
    args = parser.parse_args()
    counts = [int(c) for c in args.clients.split(",")]
    master_port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(master_port), ROS_IP="127.0.0.1")
    master = start_master(master_port, env)
    try:
        measure("this checkout", env, ROOT, args, counts)
        if args.compare:
            measure(os.path.basename(os.path.abspath(args.compare)), env, os.path.abspath(args.compare), args, counts)
    finally:
        stop_process(master)
    return 0


if __name__ == "__main__":
    sys.exit(main())
