"""A run's goal reached until its next goal reaches move_base, dwell 0 (issue 23).

Three processes besides this script: a ROS master, ``flask-move-server`` (its own config, the
action ``move_base``, ``modes.stack: none``, no motors) and ``bench/move_base_standin.py
--succeed-after S``: a real actionlib server that accepts each goal and succeeds it ``S`` s after
it arrived, printing, on the clock every process shares (``time.monotonic``), when each goal
arrived and the moment just before it sent the goal's success. A leg is from that success to the
run's next goal arriving: the server's result callback, the run executor waking, noting the visit
(history, ``run`` event), the next waypoint looked up, the goal built and sent, and rospy's hop.

The route is written into the waypoints file before the server starts (``--waypoints`` stops,
``--loops`` loops, dwell 0, ``on_failure: stop``); a short run of the same route warms the server
up, then ``POST /runs`` starts the measured one and nothing else talks to the server until its
last goal succeeded. Two histories: ``runs.json`` empty, and full (the 50 runs kept, each with its
100 newest visits, as after weeks of patrols): every change of a run serializes the kept runs.

Run: ``.venv/bin/python bench/bench_runs.py [--loops N] [--waypoints N] [--succeed-after S]
[--repeat N] [--compare DIR] [--profile FILE]`` (``--compare``: also the server of another checkout,
``git archive REV | tar -x -C DIR``, in turns with this one; ``--profile``: py-spy's raw stacks of the
server during the measured runs). Starts its own ROS master. Prints one markdown table.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from bench.bench_goals import cpu_seconds, percentile, start_ours, start_profiler  # noqa: E402
from tests.conftest import free_port, start_master, stop_process, wait_for  # noqa: E402

KEPT_RUNS, KEPT_VISITS = 50, 100  # missions/history.py's KEPT, missions/run.py's KEPT_STOPS


class StandIn:
    """The move_base stand-in (``--succeed-after``) and its goal / success events, in order."""

    def __init__(self, env, succeed_after):
        args = [sys.executable, os.path.join(ROOT, "bench", "move_base_standin.py"), "--action", "move_base",
                "--succeed-after", repr(succeed_after)]
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, env=env, text=True)
        self._events = []  # (kind, x, monotonic time): kind "goal" (arrived) or "succeeded" (sent)
        self._cond = threading.Condition()
        if self.proc.stdout.readline().strip() != "ready":
            raise RuntimeError("the move_base stand-in did not start: exit {}".format(self.proc.wait()))
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            kind, _, x, at = line.split()
            with self._cond:
                self._events.append((kind, float(x), float(at)))
                self._cond.notify_all()

    def take(self, successes, timeout):
        """The events up to the ``successes``-th success from now on (then cleared)."""
        done = lambda: sum(1 for kind, _, _ in self._events if kind == "succeeded") >= successes  # noqa: E731
        with self._cond:
            if not self._cond.wait_for(done, timeout):
                raise RuntimeError("only {} of {} goals succeeded in {} s".format(
                    sum(1 for e in self._events if e[0] == "succeeded"), successes, timeout))
            events, self._events = self._events, []
        return events


def legs(events):
    """ms from each success to the next goal's arrival (the run's next waypoint).

    In time order: a success is printed after it was sent, so the next goal's line may come first.
    """
    events = sorted(events, key=lambda event: event[2])
    found = []
    for (kind, _, at), (next_kind, _, next_at) in zip(events, events[1:]):
        if kind == "succeeded":
            if next_kind != "goal":
                raise RuntimeError("a success was followed by {}, not the next goal".format(next_kind))
            found.append((next_at - at) * 1000)
    return found


def waypoints_file(path, stops, loops):
    names = ["stop{}".format(i + 1) for i in range(stops)]
    lines = ["waypoints:"] + ["  {}: [{}.0, 0.0, 0.0]".format(name, i + 1) for i, name in enumerate(names)]
    lines += ["routes:"]
    for route, n in (("warm-up", 5), ("legs", loops)):
        lines.append("  {}: {{waypoints: [{}], loops: {}, dwell: 0.0, on_failure: stop}}".format(
            route, ", ".join(names), n))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return names


def full_history(path, names):
    """``runs.json`` as after weeks of patrols: the 50 runs kept, each with its newest 100 visits."""
    runs = []
    for run_id in range(KEPT_RUNS, 0, -1):
        visited = [{"name": names[i % len(names)], "loop": i // len(names) + 1, "at": "2024-05-01T21:30:00+02:00"}
                   for i in range(KEPT_VISITS)]
        runs.append({"id": run_id, "route": "legs", "waypoints": names, "loops": 100, "dwell": 0.0,
                     "on_failure": "stop", "trigger": "schedule", "state": "succeeded", "loop": 100,
                     "index": len(names) - 1, "current": None, "visited": visited, "missed": [],
                     "started": "2024-05-01T21:30:00+02:00", "ended": "2024-05-01T22:30:00+02:00",
                     "message": "Visited every waypoint (100 loops)."})
    with open(path, "w") as f:
        json.dump(runs, f)


def drive_run(server, standin, route, goals, timeout):
    """POST /runs for ``route``; its events once its ``goals`` goals succeeded; the run as the server says."""
    status, body = server.request("POST", "/runs", json.dumps({"route": route}))
    if status != 202:
        raise RuntimeError("POST /runs answered {}: {}".format(status, body))
    run_id = json.loads(body)["run"]["id"]
    events = standin.take(goals, timeout)
    wait_for(lambda: json.loads(server.request("GET", "/runs/{}".format(run_id))[1])["state"] != "running",
             timeout=10, message="run {} to end".format(run_id))
    run = json.loads(server.request("GET", "/runs/{}".format(run_id))[1])
    if run["state"] != "succeeded":
        raise RuntimeError("run {} ended {}: {}".format(run_id, run["state"], run["message"]))
    return events


def measure(history, opts, env, standin):
    """(legs ms, server CPU ms per leg) of one measured run, on a server of its own with ``history``.

    The server is this checkout's, or the one ``env``'s PYTHONPATH names first."""
    home = tempfile.mkdtemp(prefix="bench-runs-")
    names = waypoints_file(os.path.join(home, "waypoints.yaml"), opts.waypoints, opts.loops)
    if history == "full":
        full_history(os.path.join(home, "runs.json"), names)
    server = start_ours(home, env, False)
    profiler = None
    try:
        drive_run(server, standin, "warm-up", 5 * opts.waypoints, 60)
        goals = opts.waypoints * opts.loops
        profiler = start_profiler(server.proc.pid, opts.profile + "." + history) if opts.profile else None
        cpu = cpu_seconds(server.proc.pid)
        events = drive_run(server, standin, "legs", goals, 60 + goals * 0.5)
        cpu_ms = (cpu_seconds(server.proc.pid) - cpu) * 1000
    finally:
        if profiler is not None:
            profiler.send_signal(2)
            profiler.wait(30)
        stop_process(server.proc)
    found = legs(events)
    if len(found) != goals - 1:
        raise RuntimeError("{} legs measured, {} expected".format(len(found), goals - 1))
    return found, cpu_ms / goals


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--waypoints", type=int, default=3, help="stops in the route")
    parser.add_argument("--loops", type=int, default=100, help="loops of the measured run")
    parser.add_argument("--succeed-after", type=float, default=0.02,
                        help="s after its arrival the stand-in succeeds each goal")
    parser.add_argument("--repeat", type=int, default=1, help="measured runs per history, alternating")
    parser.add_argument("--compare", metavar="DIR", help="also measure the server of another checkout")
    parser.add_argument("--profile", metavar="FILE", help="py-spy's raw stacks of the server, FILE.empty / FILE.full")
    opts = parser.parse_args(argv)

    home = tempfile.mkdtemp(prefix="bench-runs-ros-")
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_HOME=home, ROS_IP="127.0.0.1")
    checkouts = [("this checkout", ROOT)] + ([(os.path.basename(opts.compare.rstrip("/")), opts.compare)]
                                             if opts.compare else [])
    master = start_master(port, env)
    standin = None
    rows = []
    try:
        standin = StandIn(env, opts.succeed_after)
        for i in range(opts.repeat):
            for history in ("empty", "full"):
                for name, root in checkouts:  # the server of that checkout, not the venv's editable install
                    ours = dict(env, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
                    found, cpu = measure(history, opts, ours, standin)
                    rows.append((name, history, i + 1, found, cpu))
    finally:
        if standin is not None:
            stop_process(standin.proc)
        stop_process(master)
    print("| goal succeeded → next goal at move_base ({} stops × {} loops, dwell 0) | server | run | legs | p50 ms "
          "| p90 ms | p99 ms | max ms | server CPU per leg ms |".format(opts.waypoints, opts.loops))
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, history, run, found, cpu in rows:
        label = "runs.json empty" if history == "empty" else "runs.json full ({} runs × {} visits kept)".format(
            KEPT_RUNS, KEPT_VISITS)
        print("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |".format(
            label, name, run, len(found), percentile(found, 50), percentile(found, 90), percentile(found, 99),
            max(found), cpu))


if __name__ == "__main__":
    main()
