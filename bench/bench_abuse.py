"""Benchmark of the stop path under abuse (issue 10): the numbers behind docs/performance.md.

Run: ``.venv/bin/python bench/bench_abuse.py`` (loopback only; each server is
``flask-move-server --sim`` as its own process, with its own ROS master and a token).
Measures:

1. ``POST /stop`` latency with 300 hostile connections held open by a client
   without a token (half idle, half slow-loris, reopened when the server closes
   them), while a goal drives;
2. motor-stop time after SIGTERM with a ``/goto`` ``wait`` in flight (the
   server logs how long after the signal the motors were at zero), and when the
   waiting client got its answer;
3. ``POST /stop`` latency while as many connections pipeline 50 requests each without a token
   (cheap 401s), read the answers and pipeline the next 50;
4. ``POST /stop`` latency during an 8-client ``PUT /waypoints/<name>`` storm, and
   how many queue lines the storm left in the log.

Every loop is bounded in count and time. Prints markdown tables.
"""

import argparse
import http.client
import json
import os
import re
import shutil
import signal
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import ServerProcess, free_port, wait_for  # noqa: E402
from tests.hostile import HostileClients, PipelineFlood  # noqa: E402

TOKEN = "bench-abuse-token"
HEADERS = {"Authorization": "Bearer " + TOKEN, "Content-Type": "application/json"}
FAR = {"x": 8.4, "y": 0.9, "yaw": 0.0}
START = {"x": 0.0, "y": 0.0, "yaw": 0.0}


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100.0 * (len(values) - 1))))]


class SimServer(ServerProcess):
    """``flask-move-server --sim`` with a token, as its own process (the tests' ServerProcess)."""

    def __init__(self, home):
        shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), os.path.join(home, "waypoints.yaml"))
        with open(os.path.join(home, "sim.yaml"), "w") as f:
            f.write("server:\n  token: {}\n".format(TOKEN))
        self.waypoints_file = os.path.join(home, "waypoints.yaml")
        self.master_uri = "http://127.0.0.1:{}".format(free_port())
        env = {"ROS_MASTER_URI": self.master_uri, "ROS_HOME": home,
               "ROS_LOG_DIR": os.path.join(home, "log"), "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--config", os.path.join(home, "sim.yaml"), "--port", "0", "--no-mdns",
                         "--waypoints", os.path.join(home, "waypoints.yaml"), env=env, start_timeout=60)
        self.port = int(self.url.rsplit(":", 1)[1])
        wait_for(lambda: self.call("GET", "/health")[1].get("move_base") == "ready", timeout=30)
        # move_base can be ready before the sim's first tf map -> base_link: no pose to drive from yet
        wait_for(lambda: self.call("GET", "/status")[1]["pose"] is not None, timeout=30,
                 message="a pose from tf map -> base_link")

    def call(self, method, path, body=None, timeout=10):
        """One request on a fresh connection (as curl or the phone would); (status, JSON, seconds)."""
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=timeout)
        started = time.perf_counter()
        try:
            conn.request(method, path, body=None if body is None else json.dumps(body), headers=HEADERS)
            response = conn.getresponse()
            data = response.read()
        finally:
            conn.close()
        return response.status, json.loads(data or b"{}"), time.perf_counter() - started

    def motors(self):
        motors = self.call("GET", "/status")[1]["motors"]
        return motors["left"], motors["right"]

    def drive_far(self):
        """A goal far from where the robot is (the far end or the start), and wait until it drives."""
        pose = self.call("GET", "/status")[1]["pose"]
        self.call("POST", "/goto", FAR if pose["x"] < FAR["x"] / 2 else START)
        wait_for(lambda: self.motors() != (0.0, 0.0), timeout=20, message="the robot to drive")

    def close(self):
        self.kill()


def stops_while_driving(server, rounds):
    """``rounds`` times: a goal far away, then ``POST /stop``; the latencies in ms (None: no answer)."""
    latencies = []
    for _ in range(rounds):
        try:
            server.drive_far()
            status, body, seconds = server.call("POST", "/stop", timeout=10)
        except (OSError, AssertionError):  # before issues 10 and 20: no answer at all
            latencies.append(None)
            break
        assert status == 200 and body["canceled_goal"], (status, body)
        latencies.append(seconds * 1000)
    return latencies


def stop_with_hostile_connections(server, count, rounds):
    """/stop latencies (ms) with ``count`` hostile connections open; and the reconnects they needed."""
    with HostileClients("127.0.0.1", server.port, count=count, max_seconds=30 + rounds) as hostile:
        time.sleep(2)  # all connected, slow-loris requests begun
        return stops_while_driving(server, rounds), hostile.reconnects


def stop_with_pipeline_flood(server, count, depth, rounds):
    """/stop latencies (ms) while ``count`` connections pipeline ``depth`` requests each without a
    token, read their 401s and send the next batch; and how many answers the flood got."""
    with PipelineFlood("127.0.0.1", server.port, count=count, depth=depth, max_seconds=60 + rounds) as flood:
        time.sleep(2)  # every connection open and pipelining
        return stops_while_driving(server, rounds), flood.answers


def sigterm_with_waiting_client(home):
    """(ms after the signal the motors were at zero, ms until the waiting client's answer, its status)."""
    server = SimServer(home)
    answer = {}
    try:
        server.drive_far()

        def wait():
            try:
                answer["status"] = server.call("POST", "/goto", dict(FAR, wait=60), timeout=30)[0]
            except (OSError, http.client.HTTPException) as exc:
                answer["status"] = type(exc).__name__
            answer["at"] = time.perf_counter()

        waiter = threading.Thread(target=wait)
        waiter.start()
        wait_for(lambda: len([ln for ln in server.lines if re.search(r"goal \d+: pose", ln)]) >= 2, timeout=10)
        sent = time.perf_counter()
        server.proc.send_signal(signal.SIGTERM)
        waiter.join(30)
        exit_status = server.proc.wait(30)
        time.sleep(0.5)  # the log reader has the last lines
        stopped = server.find(r"robot stopped ([\d.]+) ms after the signal")
        motors_ms = float(stopped.group(1)) if stopped else None  # before issue 10: not logged
        return motors_ms, (answer["at"] - sent) * 1000, answer["status"], exit_status
    finally:
        server.close()


def stop_during_put_storm(server, clients, seconds, rounds):
    """/stop latencies (ms) while ``clients`` threads PUT waypoints; PUTs done; queue lines logged."""
    done = [0] * clients
    end = time.perf_counter() + seconds
    lines_before = len(server.lines)

    def storm(i):
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
        n = 0
        while time.perf_counter() < end:
            body = json.dumps({"x": float(n % 50), "y": float(i), "yaw": 0.0})
            conn.request("PUT", "/waypoints/storm{}_{}".format(i, n % 5), body=body, headers=HEADERS)
            response = conn.getresponse()
            response.read()
            assert response.status in (200, 201), response.status
            n += 1
        done[i] = n

    threads = [threading.Thread(target=storm, args=(i,)) for i in range(clients)]
    for t in threads:
        t.start()
    latencies = []
    time.sleep(0.5)
    for _ in range(rounds):
        if time.perf_counter() > end - 0.5:
            break
        status, _, took = server.call("POST", "/stop", timeout=10)
        assert status == 200, status
        latencies.append(took * 1000)
        time.sleep(max(0.0, (seconds - 1.0) / rounds - took))
    for t in threads:
        t.join(seconds + 30)
    queue_lines = [ln for ln in server.lines[lines_before:] if "waitress.queue" in ln]
    return latencies, sum(done), len(queue_lines)


def row(name, values):
    answered = [v for v in values if v is not None]
    if not values:  # a storm too short for one /stop
        return "| {} | 0 | – | – | – |".format(name)
    if len(answered) < len(values):
        return "| {} | {} | no answer within 10 s | | |".format(name, len(values))
    return "| {} | {} | {:.1f} | {:.1f} | {:.1f} |".format(
        name, len(values), percentile(answered, 50), percentile(answered, 95), max(answered))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connections", type=int, default=300)
    parser.add_argument("--depth", type=int, default=50, help="pipelined requests per flooding connection")
    parser.add_argument("--rounds", type=int, default=20, help="/stop requests per scenario")
    parser.add_argument("--signals", type=int, default=3, help="SIGTERM runs (a server start each)")
    parser.add_argument("--storm-seconds", type=float, default=10.0)
    opts = parser.parse_args()

    home = tempfile.mkdtemp(prefix="bench-abuse-")
    os.makedirs(os.path.join(home, "main"))
    server = SimServer(os.path.join(home, "main"))
    try:
        server.drive_far()
        quiet = []
        for _ in range(opts.rounds):
            server.drive_far()
            quiet.append(server.call("POST", "/stop")[2] * 1000)
        hostile, reconnects = stop_with_hostile_connections(server, opts.connections, opts.rounds)
        flood, flood_answers = stop_with_pipeline_flood(server, opts.connections, opts.depth, opts.rounds)
        storm, puts, queue_lines = stop_during_put_storm(server, 8, opts.storm_seconds, opts.rounds)
    finally:
        server.close()

    signals = []
    for i in range(opts.signals):
        run_home = os.path.join(home, "sig{}".format(i))
        os.makedirs(run_home)
        signals.append(sigterm_with_waiting_client(run_home))
    shutil.rmtree(home, ignore_errors=True)

    print("| POST /stop, fresh connection each, while a goal drives | n | p50 ms | p95 ms | max ms |")
    print("|---|---|---|---|---|")
    print(row("quiet server", quiet))
    print(row("{} hostile connections open ({} reopened after the server closed them)".format(
        opts.connections, reconnects), hostile))
    print(row("{} connections pipelining {} requests each ({} answers)".format(
        opts.connections, opts.depth, flood_answers), flood))
    print(row("8 clients PUT /waypoints/<name> ({} PUTs in {:.0f} s)".format(puts, opts.storm_seconds), storm))
    print()
    print("| SIGTERM with a /goto wait in flight | motors at zero after the signal, ms | "
          "waiting client answered after, ms | its answer | exit status |")
    print("|---|---|---|---|---|")
    for i, (motors_ms, answer_ms, status, code) in enumerate(signals, 1):
        motors = "not logged" if motors_ms is None else "{:.1f}".format(motors_ms)
        print("| run {} | {} | {:.1f} | {} | {} |".format(i, motors, answer_ms, status, code))
    print()
    print("Queue lines in the log during the PUT storm: {}".format(queue_lines))


if __name__ == "__main__":
    main()
