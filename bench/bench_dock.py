"""Docking: how often the approach touches the contacts, and how long Home takes (issue 35).

    .venv/bin/python bench/bench_dock.py [--tries 30] [--homes 3] [--seed 1]

1. The approach from ``--tries`` staging poses off by up to ±10 cm sideways, ±10 cm along and
   ±10° (move_base leaves the robot within 12 cm and 11°; uniform, seeded), driven on the sim's
   kinematics (``along_arc``, the shipped speed, the server's 0.1 s command period at speed factor 1
   and 4, whose steps are four times as coarse) onto the sim's contacts (``on_contacts``: 4 cm,
   5°). In this process: the controller and the charger's rule, not the server around them.
2. ``flask-move-server --sim`` (speed factor 4, its own master): ``--homes`` times, a goal to the
   kitchen, then ``POST /dock`` with ``wait``: the time from Home to charging (sim seconds: real ×
   4), the tries it took, and where the robot really stands on the charger.

Prints markdown tables (docs/performance.md, section Docking).
"""

import argparse
import math
import os
import random
import shutil
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.core.geometry import Pose2D, along_arc, compose  # noqa: E402
from flask_move_server.dock.approach import Approach, offset, staging_pose  # noqa: E402
from flask_move_server.sim.battery import on_contacts  # noqa: E402
from tests.conftest import stop_process  # noqa: E402
from tests.test_sim_e2e import SimServer  # noqa: E402

DOCK = Pose2D(0.0, 0.0, 0.0)
STAGING, SPEED, PERIOD = 0.4, 0.05, 0.1


def approach_once(start, factor):
    """Drive the approach from ``start`` with steps ``factor`` times as long: (on the contacts, end offset)."""
    approach, true = Approach(DOCK, SPEED), start
    for _ in range(2000):
        step = approach.step(true)
        if step is None:
            break
        true = along_arc(true, step[0] * PERIOD * factor, step[1] * PERIOD * factor)
    return on_contacts(DOCK, true), offset(DOCK, true)


def approaches(tries, seed, factor):
    rng = random.Random(seed)
    ends = []
    for _ in range(tries):
        error = Pose2D(rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), math.radians(rng.uniform(-10, 10)))
        ends.append(approach_once(compose(staging_pose(DOCK, STAGING), error), factor))
    return ends


def homes(count):
    tmp = tempfile.mkdtemp(prefix="bench_dock_")
    server = SimServer(__import__("pathlib").Path(tmp))
    rows = []
    try:
        for _ in range(count):
            server.post("/goto", {"name": "kitchen", "wait": 120}, timeout=130)
            started = time.monotonic()
            answer = server.post("/dock", {"wait": 170}, timeout=180).json()
            seconds = time.monotonic() - started
            true = server.status()["sim"]["true_pose"]
            rows.append((answer["dock"], seconds, offset(DOCK, Pose2D(true["x"], true["y"], true["yaw"]))))
    finally:
        stop_process(server.proc)
        shutil.rmtree(tmp, ignore_errors=True)
    return rows


def print_approaches(tries, results):
    print("| command steps | tries | on the contacts | worst beside | worst yaw | along (min … max) |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, ends in results:
        hits = sum(1 for hit, _ in ends if hit)
        offs = [off for _, off in ends]
        print("| {} | {} | {} ({:.0f} %) | {:.1f} cm | {:.1f}° | {:+.1f} … {:+.1f} cm |".format(
            label, tries, hits, 100.0 * hits / tries, max(abs(o.beside) for o in offs) * 100,
            max(abs(math.degrees(o.yaw)) for o in offs), min(o.along for o in offs) * 100,
            max(o.along for o in offs) * 100))


def print_homes(rows):
    print("\n| from | state | tries | Home → charging (real s) | sim s | beside | along | yaw |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for dock, seconds, off in rows:
        print("| kitchen | {} | {} | {:.1f} | {:.0f} | {:.1f} cm | {:+.1f} cm | {:.1f}° |".format(
            dock["state"], dock["tries"], seconds, seconds * 4, abs(off.beside) * 100, off.along * 100,
            abs(math.degrees(off.yaw))))
    times = [seconds for dock, seconds, _ in rows if dock["state"] == "charging"]
    if times:
        print("\ncharging {} of {}; Home → charging median {:.1f} s real ({:.0f} s of sim time)".format(
            len(times), len(rows), statistics.median(times), statistics.median(times) * 4))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tries", type=int, default=30)
    parser.add_argument("--homes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    results = [("0.1 s (speed factor 1)", approaches(args.tries, args.seed, 1.0)),
               ("0.4 s (speed factor 4)", approaches(args.tries, args.seed, 4.0))]
    print_approaches(args.tries, results)
    print_homes(homes(args.homes))


if __name__ == "__main__":
    main()
