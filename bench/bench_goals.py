"""POST /goto until the goal reaches move_base, the way a user meets it (issue 11).

Three processes besides this client: ``flask-move-server`` (its own config, the action
``move_base``), ``bench/bare_server.py`` (one Flask route on waitress that publishes the same
``MoveBaseActionGoal`` with rospy, the least a Flask + rospy server can do), and
``bench/move_base_standin.py`` (a real actionlib server per namespace that behaves towards its
client as move_base does: accepts, preempts, feedback at 10 Hz, status at 5 Hz). The stand-in
notes when each goal arrives, on the clock every process shares (``time.monotonic``), and this
client times it from just before it sends the request, on one keep-alive connection per server.

Rates: one goal every 0.6 s (someone tapping places on the phone page; the two servers take
turns, 0.3 s apart), then bursts of 10 and 35 goals per second (a script), one server at a time,
twice each in alternation so drift of the machine's load hits both alike.

Run: ``.venv/bin/python bench/bench_goals.py [--goals N] [--burst N]``; ``--profile FILE``
samples the server with py-spy (``pip install py-spy``) during the goals and writes its raw
(collapsed) stacks to FILE; ``--stages`` runs both servers under ``bench/stages.py`` and prints a
second table: where each goal's time goes, stage by stage (medians); ``--compare DIR`` runs the server
of another checkout (``git worktree add DIR REV``) as a third, in the same run and in turn with the
others, so a change is measured against what it replaced. Starts its own ROS master. Prints one
markdown table (two with ``--stages``).
"""

import argparse
import bisect
import http.client
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import free_port, start_master, stop_process, wait_for  # noqa: E402

OUR_CONFIG = """\
server: {{host: 127.0.0.1, port: 0}}
ros: {{node_name: {node}}}
waypoints: {{file: {waypoints}}}
navigation: {{goal_interface: action, action: {action}}}
drive: {{backend: none}}
modes: {{stack: none}}  # this bench runs move_base itself (the stand-in), as an outside stack
"""


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100.0 * (len(values) - 1))))]


class StandIn:
    """The move_base stand-in process and the arrival time of every goal it got."""

    def __init__(self, env, actions):
        args = [sys.executable, os.path.join(ROOT, "bench", "move_base_standin.py")]
        for action in actions:
            args += ["--action", action]
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, env=env, text=True)
        self._arrivals = {}
        self._cond = threading.Condition()
        if self.proc.stdout.readline().strip() != "ready":
            raise RuntimeError("the move_base stand-in did not start: exit {}".format(self.proc.wait()))
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            _, action, x, arrived = line.split()
            with self._cond:
                self._arrivals[(action, round(float(x), 6))] = float(arrived)
                self._cond.notify_all()

    def arrival(self, action, x, timeout=10.0):
        key = (action, round(x, 6))
        with self._cond:
            if not self._cond.wait_for(lambda: key in self._arrivals, timeout):
                raise RuntimeError("goal {} never reached the stand-in's {}".format(x, action))
            return self._arrivals.pop(key)


class Server:
    """One HTTP server under test: its process, a keep-alive connection, the action it feeds."""

    def __init__(self, name, args, env, action, log_path, cwd=None):
        self.name, self.action = name, action
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True,
                                     cwd=cwd)
        for line in self.proc.stderr:
            if "serving the API on http://" in line or "bare server on http://" in line:
                self.host, port = line.split("http://")[1].split()[0].split(":")
                self.port = int(port)
                threading.Thread(target=self._keep_log, args=(log_path,), daemon=True).start()
                break
        else:
            raise RuntimeError("{} did not start: exit {}".format(name, self.proc.wait()))
        self.conn = http.client.HTTPConnection(self.host, self.port, timeout=10)
        self.sent = []  # (x, monotonic time just before the request, HTTP answer ms)
        self.trips = []  # (sent, arrived at move_base) of each goal collected

    def _keep_log(self, path):
        """The rest of its stderr into ``path``: what its journal would show."""
        with open(path, "w") as log:
            for line in self.proc.stderr:
                log.write(line)

    def request(self, method, path, body=None):
        self.conn.request(method, path, body=body, headers={"Content-Type": "application/json"})
        response = self.conn.getresponse()
        return response.status, response.read()

    def goto(self, x):
        started = time.monotonic()
        status, body = self.request("POST", "/goto", json.dumps({"x": x, "y": 0.0, "yaw": 0.0}))
        if status not in (200, 202):
            raise RuntimeError("{}: POST /goto answered {}: {}".format(self.name, status, body))
        self.sent.append((x, started, (time.monotonic() - started) * 1000))


def staged(args, out, root=ROOT):
    """``args`` (a Python script, or ``-m module``, and its arguments) under bench/stages.py writing to
    ``out``, the server's package from the checkout ``root``."""
    return [sys.executable, os.path.join(ROOT, "bench", "stages.py"), out, "--root", root] + args


def start_ours(home, env, stages, root=ROOT, name="flask-move-server", action="move_base", node="flask_move_server"):
    """flask-move-server from the checkout ``root`` as ROS node ``node``, its files in ``home``, feeding ``action``."""
    os.makedirs(home, exist_ok=True)
    config = os.path.join(home, "robot.yaml")
    with open(config, "w") as f:
        f.write(OUR_CONFIG.format(waypoints=os.path.join(home, "waypoints.yaml"), action=action,
                                  node=node))
    exe = os.path.join(os.path.dirname(sys.executable), "flask-move-server")
    mine = root == ROOT
    args = [exe] if os.path.exists(exe) and mine and not stages else [sys.executable, "-m", "flask_move_server"]
    stages_file = os.path.join(home, "stages-ours.json")
    if stages:
        args = staged(args[1:], stages_file, root)
    elif not mine:
        env = dict(env, PYTHONPATH=root)
    ours = Server(name, args + ["--config", config, "--no-mdns"], env, action,
                  os.path.join(home, "flask-move-server.log"), cwd=root)
    ours.stages = stages_file if stages else None
    wait_for(lambda: json.loads(ours.request("GET", "/health")[1]).get("move_base") == "ready", timeout=30,
             message="flask-move-server's /health to say move_base is ready")
    return ours


def drive(servers, period, count, first_x):
    """``count`` goals to each of ``servers`` every ``period`` s, the servers spread evenly in it."""
    start = time.monotonic() + 0.2
    for i in range(count):
        for j, server in enumerate(servers):
            due = start + (i + j / len(servers)) * period
            pause = due - time.monotonic()
            if pause > 0:
                time.sleep(pause)
            server.goto(first_x + i * 0.001)


def collect(server, standin):
    """Goal latencies (ms) of every goal ``server`` sent since the last collect, and its HTTP answers.

    Each goal's (sent, arrived) times go to ``server.trips``, for ``--stages``.
    """
    trips = [(sent, standin.arrival(server.action, x)) for x, sent, _ in server.sent]
    server.trips.extend(trips)
    answered = [ms for _, _, ms in server.sent]
    server.sent = []
    return [(arrived - sent) * 1000 for sent, arrived in trips], answered


def cpu_seconds(pid):
    """User + system CPU time of process ``pid`` so far, from /proc."""
    with open("/proc/{}/stat".format(pid)) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(servers, standin, opts):
    """Rows of (rate label, server name, goal latencies, HTTP answer times, server CPU ms per goal)."""
    rows = []
    for server in servers:
        drive([server], 0.05, 20, 9000.0)  # warm-up: connections, caches, the first goal's set-up
        collect(server, standin)
        server.trips = []
    cpu = [cpu_seconds(server.proc.pid) for server in servers]
    drive(servers, 0.6, opts.goals, 0.0)
    for server, before in zip(servers, cpu):
        per_goal = (cpu_seconds(server.proc.pid) - before) * 1000 / opts.goals
        rows.append(("1 every 0.6 s", server.name) + collect(server, standin) + (per_goal,))
        server.rate_trips = {"1 every 0.6 s": server.trips}
        server.trips = []
    x = 1000.0
    for rate in (10, 35):
        results = {server.name: ([], [], 0.0) for server in servers}
        for _ in range(2):
            for server in servers:
                before = cpu_seconds(server.proc.pid)
                drive([server], 1.0 / rate, opts.burst // 2, x)
                x += 1000.0
                reached, answered = collect(server, standin)
                so_far = results[server.name]
                results[server.name] = (so_far[0] + reached, so_far[1] + answered,
                                        so_far[2] + cpu_seconds(server.proc.pid) - before)
        for server in servers:
            reached, answered, cpu_s = results[server.name]
            rows.append(("{} per second".format(rate), server.name, reached, answered, cpu_s * 1000 / len(reached)))
            server.rate_trips["{} per second".format(rate)] = server.trips
            server.trips = []
    return rows


def print_table(rows):
    print("| POST /goto until the goal reaches move_base | server | goals | p50 ms | p99 ms | max ms "
          "| HTTP answer p50 ms | server CPU per goal ms |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for rate, name, reached, answered, cpu_ms in rows:
        print("| {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |".format(
            rate, name, len(reached), percentile(reached, 50), percentile(reached, 99), max(reached),
            percentile(answered, 50), cpu_ms))


STAGE_COLUMNS = ("sent → read", "read → worker", "worker → route", "route → publish", "publish → socket",
                 "socket → move_base")


def print_stages(servers):
    """Per rate and server, the median ms of each stage of a goal's way (records from bench/stages.py)."""
    from bench.stages import STAGES

    print("| where a goal's time goes (median ms) | server | goals | " + " | ".join(STAGE_COLUMNS) + " | total |")
    print("|---|---|---:|" + "---:|" * (len(STAGE_COLUMNS) + 1))
    for rate in servers[0].rate_trips:
        for server in servers:
            times = stage_times(server)
            ways = [way for way in (goal_way(times, STAGES, sent, arrived) for sent, arrived in server.rate_trips[rate])
                    if way is not None]
            if not ways:
                continue
            columns = [statistics.median(column) for column in zip(*ways)]
            cells = " | ".join("{:.3f}".format(c) for c in columns)
            print("| {} | {} | {} | {} |".format(rate, server.name, len(ways), cells))


def stage_times(server):
    """Each stage's record times, sorted, from the server's stages file (written on SIGUSR1)."""
    done = server.stages + ".done"
    if not os.path.exists(done):
        before = os.path.getmtime(server.stages) if os.path.exists(server.stages) else None
        server.proc.send_signal(signal.SIGUSR1)
        wait_for(lambda: os.path.exists(server.stages) and os.path.getmtime(server.stages) != before, timeout=10,
                 message="{}'s stage records".format(server.name))
        open(done, "w").close()
    times = {}
    with open(server.stages) as f:
        for stage, at in json.load(f):
            times.setdefault(stage, []).append(at)
    return {stage: sorted(ats) for stage, ats in times.items()}


def goal_way(times, stages, sent, arrived):
    """ms from ``sent`` to each stage's first record after the one before, then to ``arrived``, and the total.

    None when a stage has no record in between (a goal whose way was not recorded whole).
    """
    marks = [sent]
    for stage in stages:
        ats = times.get(stage, [])
        i = bisect.bisect_left(ats, marks[-1])
        if i == len(ats) or ats[i] > arrived:
            return None
        marks.append(ats[i])
    marks.append(arrived)
    return [(b - a) * 1000 for a, b in zip(marks, marks[1:])] + [(arrived - sent) * 1000]


def start_profiler(pid, path):
    """py-spy sampling the server (without pausing it) into ``path`` until it gets SIGINT."""
    exe = os.path.join(os.path.dirname(sys.executable), "py-spy")
    args = ["record", "--pid", str(pid), "--format", "raw", "--rate", "500", "--nonblocking", "--output", path]
    return subprocess.Popen([exe if os.path.exists(exe) else "py-spy"] + args,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goals", type=int, default=100, help="goals to each server at one per 0.6 s")
    parser.add_argument("--burst", type=int, default=200, help="goals to each server at each burst rate")
    parser.add_argument("--profile", metavar="FILE", help="py-spy's raw stacks of the server during the goals")
    parser.add_argument("--stages", action="store_true", help="also time each stage of a goal's way (bench/stages.py)")
    parser.add_argument("--compare", metavar="DIR", help="another checkout's server, measured in the same run")
    opts = parser.parse_args(argv)

    home = tempfile.mkdtemp(prefix="bench-goals-")
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_HOME=home, ROS_IP="127.0.0.1")
    master = start_master(port, env)
    procs = []
    try:
        standin = StandIn(env, ["move_base", "bare/move_base", "before/move_base"])
        procs.append(standin.proc)
        ours = start_ours(home, env, opts.stages)
        procs.append(ours.proc)
        servers = [ours]
        if opts.compare:
            root = os.path.abspath(opts.compare)
            before = start_ours(os.path.join(home, "compare"), env, opts.stages, root, os.path.basename(root),
                                "before/move_base", "flask_move_server_before")
            procs.append(before.proc)
            servers.append(before)
        bare_args = [os.path.join(ROOT, "bench", "bare_server.py")]
        bare_stages = os.path.join(home, "stages-bare.json")
        bare_command = staged(bare_args, bare_stages) if opts.stages else [sys.executable] + bare_args
        bare = Server("bare Flask + rospy", bare_command, env, "bare/move_base", os.path.join(home, "bare_server.log"))
        bare.stages = bare_stages if opts.stages else None
        procs.append(bare.proc)
        time.sleep(2)  # the bare publisher's connection to the stand-in's goal subscriber
        profiler = start_profiler(ours.proc.pid, opts.profile) if opts.profile else None
        servers.append(bare)
        rows = measure(servers, standin, opts)
        if profiler is not None:
            profiler.send_signal(2)
            profiler.wait(30)
        print_table(rows)
        if opts.stages:
            print()
            print_stages(servers)
        print("\n(the servers' stderr: {})".format(home), file=sys.stderr)
    finally:
        for proc in reversed(procs):
            stop_process(proc)
        stop_process(master)


if __name__ == "__main__":
    main()
