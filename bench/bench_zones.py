"""Zones: what the mask costs to make and send, and how soon a switch reaches the costmaps (issue 36).

    .venv/bin/python bench/bench_zones.py [--repeat 5] [--toggles 10]

1. The mask of ``--zones`` zones (a 2 x 2 m keepout square and a 3 m wall each, spread over the map)
   for maps of 260 x 180 (the demo flat), 1000 x 1000 and 4000 x 4000 cells (gmapping's whole
   canvas at 5 cm): the cells (``zones/mask.py``) and the message's bytes (``ros/keepout.py``), ms
   (median of ``--repeat``) and bytes sent. In this process: the server's own code, no ROS.
2. ``flask-move-server --sim`` (its own master): ``--toggles`` times ``PATCH /zones/<name>``
   ``{"enabled": ...}``, from the answer to a subscriber of ``keepout_map`` (another process, as
   move_base's costmaps are) holding the new mask, ms.

Prints markdown tables (docs/performance.md, section Zones).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.ros.keepout import serialized_mask  # noqa: E402
from flask_move_server.zones import make_zone  # noqa: E402
from flask_move_server.zones.mask import cells  # noqa: E402
from tests.conftest import stop_process  # noqa: E402
from tests.test_sim_e2e import SimServer  # noqa: E402

SIZES = [(260, 180), (1000, 1000), (4000, 4000)]
RESOLUTION = 0.05
HEADER = b"\x00" * 12 + (3).to_bytes(4, "little") + b"map" + b"\x00" * 76  # a map message's header and info


def zones_over(width, height, count):
    """``count`` keepout squares and walls spread over a map of that many cells."""
    zones = []
    w, h = width * RESOLUTION, height * RESOLUTION
    for i in range(count):
        x, y = (i + 0.5) / count * (w - 3.0) + 0.5, (i + 0.5) / count * (h - 3.0) + 0.5
        zones.append(make_zone("z{}".format(i), {"kind": "keepout", "polygon": [
            [x, y], [x + 2.0, y], [x + 2.0, y + 2.0], [x, y + 2.0]]}))
        zones.append(make_zone("w{}".format(i), {"kind": "wall", "line": [[x, y + 2.5], [x + 3.0, y + 2.5]]}))
    return zones


def measure_mask(repeat, count):
    print("| map (cells) | zones | cells ms | message ms | bytes sent |")
    print("|---|---:|---:|---:|---:|")
    for width, height in SIZES:
        zones = zones_over(width, height, count)
        made, sent, size = [], [], 0
        for _ in range(repeat):
            began = time.perf_counter()
            mask = cells(zones, width, height, RESOLUTION, 0.0, 0.0)
            middle = time.perf_counter()
            message = serialized_mask(HEADER, mask)
            made.append((middle - began) * 1e3)
            sent.append((time.perf_counter() - middle) * 1e3)
            size = len(message)
        print("| {} x {} | {} | {:.1f} | {:.1f} | {:,} |".format(width, height, len(zones), statistics.median(made),
                                                                 statistics.median(sent), size), flush=True)


def measure_toggles(toggles):
    folder = tempfile.mkdtemp(prefix="bench-zones-")
    from pathlib import Path

    server = SimServer(Path(folder))
    try:
        square = [[1.5, 0.0], [2.5, 0.0], [2.5, 1.3], [1.5, 1.3]]
        assert server.put("/zones/bench", {"kind": "keepout", "polygon": square}).status_code == 201
        env = dict(os.environ, ROS_MASTER_URI=server.master_uri, ROS_IP="127.0.0.1", PYTHONPATH=ROOT)
        reader = subprocess.Popen([sys.executable, "-m", "tests.mask_reader", str(toggles + 1)],
                                  stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
        json.loads(reader.stdout.readline())  # the latched one
        delays = []
        for i in range(toggles):
            enabled = i % 2 == 1
            began = time.perf_counter()
            assert server.patch("/zones/bench", {"enabled": enabled}).status_code == 200
            answered = time.perf_counter()
            heard = json.loads(reader.stdout.readline())
            delays.append(((time.perf_counter() - answered) * 1e3, (answered - began) * 1e3))
            assert bool(heard["mask"]["lethal"]) == enabled
        stop_process(reader)
        heard_ms = [d[0] for d in delays]
        print("\n| toggles | PATCH answered, median ms | answer to the mask heard: median ms | max ms |")
        print("|---:|---:|---:|---:|")
        print("| {} | {:.1f} | {:.0f} | {:.0f} |".format(toggles, statistics.median(d[1] for d in delays),
                                                       statistics.median(heard_ms), max(heard_ms)), flush=True)
    finally:
        stop_process(server.proc)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--zones", type=int, default=10, help="squares (and as many walls) on each map")
    parser.add_argument("--toggles", type=int, default=10)
    args = parser.parse_args()
    measure_mask(args.repeat, args.zones)
    measure_toggles(args.toggles)
    return 0


if __name__ == "__main__":
    sys.exit(main())
