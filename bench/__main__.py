"""Every benchmark, with short runs: ``make bench`` (or ``.venv/bin/python -m bench``).

Each benchmark runs as its own process (each starts its own ROS master and rospy node, and a
process has one node) and prints its markdown tables under a heading that names the command
behind it. The runs are shorter than the ones docs/performance.md reports, so the whole takes a
few minutes; run a benchmark's script with its documented options to reproduce a table there.
``python -m bench goals teleop`` runs only those.

``--smoke`` (``make bench-smoke``, run by CI) runs each benchmark with its smallest counts, seconds
each, two at a time (``--jobs``), and fails one that does not exit 0 within SMOKE_TIMEOUT or prints
no markdown table: a benchmark CI never ran rotted unseen (three of twenty failed at once, issue
32). Its numbers are not measurements.
"""

import argparse
import concurrent.futures
import os
import re
import signal
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 600  # s: a benchmark that hangs is killed (subprocess.call kills it) and reported failed
SMOKE_TIMEOUT = 180  # s: the same for a smoke run, which takes seconds

# (name, script, short-run options, smoke options): the order is cheapest first, so a broken setup
# fails early. The smoke options are each benchmark's smallest counts: every part of it runs, once.
BENCHMARKS = [
    ("server", "bench_server.py", ["--seconds", "2", "--idle", "3"], ["--seconds", "0.5", "--idle", "0.5"]),
    ("rss", "bench_rss.py", ["--repeat", "1", "--settle", "2"], ["--repeat", "1", "--settle", "0"]),
    ("concurrency", "bench_concurrency.py", ["--seconds", "2", "--clients", "1,8"],
     ["--seconds", "0.5", "--clients", "1,2"]),
    ("goals", "bench_goals.py", ["--goals", "30", "--burst", "100", "--stages"],
     ["--goals", "3", "--burst", "5", "--stages"]),
    ("runs", "bench_runs.py", ["--loops", "30"], ["--loops", "2"]),
    ("schedules", "bench_schedules.py", ["--seconds", "10", "--repeat", "2", "--settle", "3"],
     ["--seconds", "1", "--repeat", "1", "--settle", "0", "--routes", "2", "--times", "2"]),
    ("teleop", "bench_teleop.py", ["--requests", "100", "--seconds", "4"], ["--requests", "5", "--seconds", "0.5"]),
    ("maps", "bench_maps.py", ["--repeat", "3"], ["--repeat", "1"]),
    ("frontiers", "bench_frontiers.py", ["--repeat", "10"], ["--repeat", "1"]),
    ("slam", "bench_slam.py", [], []),
    ("sim", "bench_sim.py", ["--repeat", "3", "--drive-seconds", "8"], ["--repeat", "1", "--drive-seconds", "1"]),
    ("stack", "bench_stack.py", ["--repeat", "2"], ["--repeat", "1"]),
    ("dock", "bench_dock.py", ["--tries", "30", "--homes", "2"], ["--tries", "3", "--homes", "1"]),
    ("zones", "bench_zones.py", ["--repeat", "3", "--toggles", "6"], ["--repeat", "1", "--toggles", "2"]),
    ("abuse", "bench_abuse.py", ["--connections", "100", "--rounds", "10", "--signals", "2",
                                 "--storm-seconds", "4"],
     ["--connections", "5", "--depth", "2", "--rounds", "1", "--signals", "1", "--storm-seconds", "2"]),
    ("drive_gaps", "bench_drive_gaps.py", ["--seconds", "3"], ["--seconds", "0.5"]),
    ("sim_modes", "bench_sim_modes.py", ["--switches", "2", "--drive-seconds", "30"],
     ["--switches", "1", "--drive-seconds", "5"]),
    ("events", "bench_events.py", ["--rest-seconds", "3", "--drive-seconds", "5", "--stops", "3"],
     ["--rest-seconds", "0.5", "--drive-seconds", "1", "--stops", "1"]),
    ("mqtt", "bench_mqtt.py", ["--commands", "30", "--settle", "5", "--cpu-seconds", "10", "--cpu-repeat", "1",
                               "--floods", "2"],
     ["--commands", "2", "--settle", "0", "--cpu-seconds", "0.5", "--cpu-repeat", "1", "--floods", "1",
      "--flood", "10", "--flood-seconds", "0.2"]),
    ("vda5050", "bench_vda5050.py", ["--orders", "20", "--settle", "5", "--cpu-seconds", "10", "--cpu-repeat", "1"],
     ["--orders", "2", "--settle", "0", "--cpu-seconds", "0.5", "--cpu-repeat", "1"]),
    ("page", "bench_page.py", ["--loads", "3"], ["--loads", "1"]),
    ("page_silence", "bench_page_silence.py", ["--stalls", "2"], ["--stalls", "1"]),
    ("scan", "bench_scan.py", ["--seconds", "4", "--repeat", "500"], ["--seconds", "0.5", "--repeat", "5"]),
    ("webhooks", "bench_webhooks.py", ["--seconds", "10"], ["--seconds", "1"]),
    ("mqtt_floods", "bench_mqtt_floods.py", ["--window", "10"],
     ["--window", "1", "--only", "instant-long,goto-unknown,state-fake"]),
    ("map_file", "bench_map_file.py", ["--repeat", "1", "--served", "--window", "10"],
     ["--repeat", "1", "--served", "--window", "1"]),
    ("soak", "bench_soak.py", ["--requests", "20000", "--checkpoints", "5000"],
     ["--requests", "600", "--checkpoints", "300", "--warmup", "100"]),
]
# A markdown table's separator line: what every benchmark prints under its header row.
TABLE_RULE = re.compile(r"^\|\s*:?-{3}")


def run(name, script, options):
    """Run one benchmark; its tables go to stdout as it prints them. True when it succeeded."""
    command = [sys.executable, os.path.join(HERE, script)] + options
    print("## {}: `python bench/{} {}`\n".format(name, script, " ".join(options)), flush=True)
    started = time.monotonic()
    try:
        code = subprocess.call(command, cwd=os.path.dirname(HERE), timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        code = "timeout after {} s".format(TIMEOUT)
    print("\n({} took {:.0f} s{})\n".format(
        name, time.monotonic() - started, "" if code == 0 else ", FAILED: {}".format(code)),
        flush=True)
    return code == 0


class Smoke:
    """The smoke runs: each benchmark with its smoke options, ``jobs`` at a time (most of a
    benchmark's time is waiting: servers starting, a simulated robot driving at real time)."""

    def __init__(self, jobs):
        self.jobs = jobs
        self._lock = threading.Lock()  # one benchmark's output at a time, whole
        self._running = set()

    def all(self, chosen):
        """Every chosen benchmark's smoke run, then a table of their times; the names of those that failed."""
        started = time.monotonic()
        try:
            with concurrent.futures.ThreadPoolExecutor(self.jobs) as pool:
                runs = [pool.submit(self.one, name, script, options) for name, script, _, options in chosen]
                results = [(name,) + run.result() for (name, _, _, _), run in zip(chosen, runs)]
        except BaseException:  # Ctrl-C: no benchmark outlives us
            for proc in list(self._running):
                kill_group(proc)
            raise
        print("| smoke, {} at a time | seconds | result |".format(self.jobs))
        print("|---|---:|---|")
        for name, took, problem in results:
            print("| {} | {:.0f} | {} |".format(name, took, problem or "ok"))
        print("| all, one after the other | {:.0f} | |".format(sum(took for _, took, _ in results)))
        print("| all, as run | {:.0f} | |".format(time.monotonic() - started), flush=True)
        return [name for name, _, problem in results if problem]

    def one(self, name, script, options):
        """(seconds it took, what failed or None): it fails unless it exits 0 and printed a table."""
        command = [sys.executable, os.path.join(HERE, script)] + options
        started = time.monotonic()
        # A session of its own, so a hung benchmark is killed with the servers and masters it
        # started (which would hold the pipe open).
        proc = subprocess.Popen(command, cwd=os.path.dirname(HERE), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True)
        self._running.add(proc)
        killer = threading.Timer(SMOKE_TIMEOUT, kill_group, args=(proc,))
        killer.start()
        try:
            output = proc.stdout.read()
            code = proc.wait()
        finally:
            killer.cancel()
            self._running.discard(proc)
        took = time.monotonic() - started
        if took >= SMOKE_TIMEOUT:
            problem = "killed after {} s".format(SMOKE_TIMEOUT)
        elif code != 0:
            problem = "exit status {}".format(code)
        elif not any(TABLE_RULE.match(line) for line in output.splitlines()):
            problem = "printed no markdown table"
        else:
            problem = None
        with self._lock:
            print("## smoke {}: `python bench/{} {}`\n\n{}\n(smoke {} took {:.0f} s: {})\n".format(
                name, script, " ".join(options), output, name, took, problem or "ok"), flush=True)
        return took, problem


def kill_group(proc):
    """SIGKILL to the benchmark's process group: it and every process it started."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def main(argv):
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__.split("\n")[0])
    parser.add_argument("names", nargs="*", metavar="NAME", help="only these benchmarks: " + ", ".join(
        b[0] for b in BENCHMARKS))
    parser.add_argument("--smoke", action="store_true", help="each with its smallest counts, checked (CI)")
    parser.add_argument("--jobs", type=int, default=2, help="--smoke: benchmarks run at once (default 2)")
    args = parser.parse_args(argv)
    unknown = set(args.names) - {b[0] for b in BENCHMARKS}
    if unknown:
        parser.error("unknown benchmark(s): {}".format(", ".join(sorted(unknown))))
    chosen = [b for b in BENCHMARKS if not args.names or b[0] in args.names]
    if args.smoke:
        failed = Smoke(args.jobs).all(chosen)
    else:
        failed = [name for name, script, options, _ in chosen if not run(name, script, options)]
    if failed:
        sys.exit("failed: " + ", ".join(failed))


if __name__ == "__main__":
    main(sys.argv[1:])
