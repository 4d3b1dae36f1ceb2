"""Every benchmark, with short runs: ``make bench`` (or ``.venv/bin/python -m bench``).

Each benchmark runs as its own process (each starts its own ROS master and rospy node, and a
process has one node) and prints its markdown tables under a heading that names the command
behind it. The runs are shorter than the ones docs/performance.md reports, so the whole takes a
few minutes; run a benchmark's script with its documented options to reproduce a table there.
``python -m bench goals teleop`` runs only those.
"""

import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 600  # s: a benchmark that hangs is killed (subprocess.call kills it) and reported failed

# (name, script, short-run options): the order is cheapest first, so a broken setup fails early.
BENCHMARKS = [
    ("server", "bench_server.py", ["--seconds", "2", "--idle", "3"]),
    ("rss", "bench_rss.py", ["--repeat", "1", "--settle", "2"]),
    ("concurrency", "bench_concurrency.py", ["--seconds", "2", "--clients", "1,8"]),
    ("goals", "bench_goals.py", ["--goals", "30", "--burst", "100", "--stages"]),
    ("runs", "bench_runs.py", ["--loops", "30"]),
    ("schedules", "bench_schedules.py", ["--seconds", "10", "--repeat", "2", "--settle", "3"]),
    ("teleop", "bench_teleop.py", ["--requests", "100", "--seconds", "4"]),
    ("maps", "bench_maps.py", ["--repeat", "3"]),
    ("frontiers", "bench_frontiers.py", ["--repeat", "10"]),
    ("slam", "bench_slam.py", []),
    ("sim", "bench_sim.py", ["--repeat", "3", "--drive-seconds", "8"]),
    ("stack", "bench_stack.py", ["--repeat", "2"]),
    ("abuse", "bench_abuse.py", ["--connections", "100", "--rounds", "10", "--signals", "2",
                                 "--storm-seconds", "4"]),
    ("drive_gaps", "bench_drive_gaps.py", ["--seconds", "3"]),
    ("sim_modes", "bench_sim_modes.py", ["--switches", "2", "--drive-seconds", "30"]),
    ("events", "bench_events.py", ["--rest-seconds", "3", "--drive-seconds", "5", "--stops", "3"]),
    ("mqtt", "bench_mqtt.py", ["--commands", "30", "--settle", "5", "--cpu-seconds", "10", "--cpu-repeat", "1",
                               "--floods", "2"]),
    ("vda5050", "bench_vda5050.py", ["--orders", "20", "--settle", "5", "--cpu-seconds", "10", "--cpu-repeat", "1"]),
    ("page", "bench_page.py", ["--loads", "3"]),
    ("page_silence", "bench_page_silence.py", ["--stalls", "2"]),
    ("scan", "bench_scan.py", ["--seconds", "4", "--repeat", "500"]),
]


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


def main(argv):
    chosen = [b for b in BENCHMARKS if not argv or b[0] in argv]
    unknown = set(argv) - {b[0] for b in BENCHMARKS}
    if unknown:
        sys.exit("unknown benchmark(s): {}; choose from {}".format(
            ", ".join(sorted(unknown)), ", ".join(b[0] for b in BENCHMARKS)))
    failed = [name for name, script, options in chosen if not run(name, script, options)]
    if failed:
        sys.exit("failed: " + ", ".join(failed))


if __name__ == "__main__":
    main(sys.argv[1:])
