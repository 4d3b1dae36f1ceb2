"""Where the server's memory goes over a long day: RSS and Python's own allocations across 300,000 requests.

Run: ``.venv/bin/python bench/bench_soak.py [--requests 300000] [--checkpoints 30000,150000] [--top 8]``.

Issue 34's probe saw RSS grow 6.8 MB over 300,000 requests with 4 event streams and MQTT, and
level off: the allocator warming up, or a slow leak? One ``--sim`` server with MQTT and VDA 5050 on
(a real mosquitto, a listener subscribed to everything, as Home Assistant is), 4 ``GET /events``
streams drained as pages drain them, and two client processes sending the requests on keep-alive
connections, round-robin over ``GET /status``, ``/waypoints``, ``/routes``, ``/runs``, ``/mode``,
``/health`` and ``POST /stop``. At each checkpoint the clients pause and the server's VmRSS is read.

Two passes: the first as the robot runs (RSS only); the second with ``tracemalloc`` on from the
server's start (bench/soak_probe/sitecustomize.py, on its PYTHONPATH only): the Python memory
traced at each checkpoint, and the source lines whose traced memory grew most from the first
checkpoint to the last. Traced memory that levels while RSS grows is the allocator (arenas, glibc's
heaps) not a leak; traced memory growing line by line is a leak, and names its line.
"""

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_mqtt import Sim  # noqa: E402
from bench_mqtt_floods import rss_mb  # noqa: E402

from tests.conftest import stop_process, wait_for  # noqa: E402
from tests.mqtt_broker import Broker, Listener  # noqa: E402
from tests.sse import EventReader  # noqa: E402

PROBE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "soak_probe")
STREAMS = 4
CLIENTS = 2
VDA_ON = "  vda5050:\n    enabled: true\n"

CLIENT = r"""
import http.client, sys
host, port = sys.argv[1], int(sys.argv[2])
paths = [("GET", "/status"), ("GET", "/waypoints"), ("GET", "/routes"), ("GET", "/runs"), ("GET", "/mode"),
         ("GET", "/health"), ("POST", "/stop")]
conn = http.client.HTTPConnection(host, port, timeout=30)
done = 0
for line in sys.stdin:
    target = int(line)
    while done < target:
        method, path = paths[done % len(paths)]
        conn.request(method, path, headers={"Content-Type": "application/json"} if method == "POST" else {})
        response = conn.getresponse()
        response.read()
        if response.status >= 500:
            print("error", response.status, path, flush=True)
        done += 1
    print(done, flush=True)
"""


class Stream(threading.Thread):
    """One open ``/events`` stream, drained as the page drains it."""

    def __init__(self, url):
        super().__init__(daemon=True)
        self.reader = EventReader(url)
        self.events = 0
        self.start()

    def run(self):
        try:
            while self.reader.next() is not None:
                self.events += 1
        except Exception:  # closed by the bench
            pass


class Clients:
    """The request senders: :meth:`to` runs them until they sent ``total`` requests between them."""

    def __init__(self, sim):
        host, port = sim.url.rsplit("/", 1)[1].split(":")
        self.procs = [subprocess.Popen([sys.executable, "-c", CLIENT, host, port], stdin=subprocess.PIPE,
                                       stdout=subprocess.PIPE, text=True) for _ in range(CLIENTS)]

    def to(self, total):
        for proc in self.procs:
            proc.stdin.write("{}\n".format(total // CLIENTS))
            proc.stdin.flush()
        for proc in self.procs:
            line = proc.stdout.readline()
            if line.startswith("error"):
                raise SystemExit("the server answered {}".format(line.strip()))

    def close(self):
        for proc in self.procs:
            proc.stdin.close()
            proc.wait(10)


def memory(pid):
    """(VmRSS, VmHWM) of ``pid`` in MB."""
    return rss_mb(pid), rss_mb(pid, "VmHWM:")


def snapshot(folder, stem):
    """Ask the traced server for a snapshot and wait for it."""
    want = folder / (stem + ".want")
    want.write_text("")
    path = folder / (stem + ".snap")
    wait_for(path.exists, timeout=120, message="the server's snapshot {}".format(stem))
    return tracemalloc.Snapshot.load(str(path))


def soak(folder, broker, counts, traced, root=ROOT):
    """[(requests, RSS, HWM, traced MB or None, snapshot or None)] at each of ``counts``, the server of
    checkout ``root``."""
    env = {}
    snaps = folder / "snapshots"
    if traced:
        snaps.mkdir(parents=True)
        env = {"PYTHONPATH": PROBE, "SOAK_SNAPSHOTS": str(snaps), "SOAK_FRAMES": "1"}
    sim = Sim(folder / "sim", broker, extra=VDA_ON, env=env, root=root)
    listener = Listener(broker)
    streams = [Stream(sim.url) for _ in range(STREAMS)]
    clients = Clients(sim)
    rows = []
    try:
        for count in counts:
            clients.to(count)
            time.sleep(1.0)  # what the requests set going (events, MQTT) settles
            rss, hwm = memory(sim.proc.pid)
            snap = snapshot(snaps, str(count)) if traced else None
            total = sum(stat.size for stat in snap.statistics("filename")) / 1e6 if snap else None
            rows.append((count, rss, hwm, total, snap))
            print("  {} requests: RSS {:.1f} MB{}".format(count, rss, "" if total is None else
                                                         ", traced {:.2f} MB".format(total)), file=sys.stderr)
        if min(s.events for s in streams) == 0:
            raise SystemExit("an event stream got nothing")
    finally:
        clients.close()
        for stream in streams:
            stream.reader.close()
        listener.close()
        stop_process(sim.proc)
    return rows


def print_tables(plain, traced, top):
    """``plain``: [(checkout, rows)]; ``traced``: this checkout's rows with tracemalloc on, or None."""
    print("| server | requests | RSS (MB) | peak RSS (MB) |")
    print("|---|---:|---:|---:|")
    for name, rows in plain:
        for count, rss, hwm, _, _ in rows:
            print("| {} | {:,} | {:.1f} | {:.1f} |".format(name, count, rss, hwm))
    if not traced:
        return
    print("\nThis checkout with tracemalloc on (its RSS is higher by what tracemalloc keeps):\n")
    print("| requests | RSS (MB) | Python traced (MB) |")
    print("|---:|---:|---:|")
    for count, rss, _, total, _ in traced:
        print("| {:,} | {:.1f} | {:.2f} |".format(count, rss, total))
    first, last = traced[min(1, len(traced) - 1)][4], traced[-1][4]  # from the first checkpoint past the warm-up
    print("\nThe source lines whose traced memory grew most from {:,} to {:,} requests:\n".format(
        traced[min(1, len(traced) - 1)][0], traced[-1][0]))
    print("| line | grew (KB) | now (KB) | blocks now |")
    print("|---|---:|---:|---:|")
    for stat in last.compare_to(first, "lineno")[:top]:
        frame = stat.traceback[0]
        where = "{}:{}".format(_short(frame.filename), frame.lineno)
        print("| `{}` | {:+.1f} | {:.1f} | {} |".format(where, stat.size_diff / 1e3, stat.size / 1e3, stat.count))


def _short(filename):
    for marker in ("site-packages/", "dist-packages/", "/work/", "lib/python3"):
        if marker in filename:
            return filename.split(marker, 1)[1]
    return filename


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--requests", type=int, default=300000)
    parser.add_argument("--checkpoints", default="30000,150000", help="request counts to measure at too")
    parser.add_argument("--warmup", type=int, default=2000, help="requests before the first measurement")
    parser.add_argument("--top", type=int, default=8)
    parser.add_argument("--compare", action="append", default=[], help="another checkout's server, RSS only")
    parser.add_argument("--no-traced", action="store_true", help="skip the pass with tracemalloc")
    parser.add_argument("--traced-only", action="store_true", help="only the pass with tracemalloc")
    args = parser.parse_args(argv)
    counts = sorted({args.warmup, args.requests, *(int(c) for c in args.checkpoints.split(",") if c)})
    counts = [c for c in counts if c <= args.requests]
    with tempfile.TemporaryDirectory(prefix="bench-soak-") as tmp:
        folder = pathlib.Path(tmp)
        (folder / "broker").mkdir()
        broker = Broker(folder / "broker")
        try:
            plain = []
            for root in [] if args.traced_only else [ROOT] + [os.path.abspath(d) for d in args.compare]:
                name = "this checkout" if root == ROOT else os.path.basename(root)
                print("{}: the server as it runs".format(name), file=sys.stderr)
                plain.append((name, soak(folder / "plain-{}".format(len(plain)), broker, counts, False, root)))
            traced = None
            if not args.no_traced:
                print("the server with tracemalloc on", file=sys.stderr)
                traced = soak(folder / "traced", broker, counts, traced=True)
        finally:
            broker.stop()
    print_tables(plain, traced, args.top)


if __name__ == "__main__":
    main()
