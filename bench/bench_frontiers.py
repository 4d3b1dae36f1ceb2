"""Benchmark of the explorer's frontier search (explore/frontiers.py): one ``survey`` of a growing map.

    .venv/bin/python bench/bench_frontiers.py [--repeat 30]

A 20 x 15 m flat (a hallway, eight rooms off it through 0.9 m doors, furniture) is mapped by the
simulated SLAM (sim/slam.py: 360-beam, 8 m scans cast on the true flat) from a few poses, on
gmapping's default canvas (4000 x 4000 cells of 5 cm, 200 x 200 m, the flat in the middle) and on a
400 x 400 canvas (20 x 20 m, the flat filling its width). Three map states: the first scan from the
living room, half the flat (living room, hallway, kitchen: several frontiers, some seen through
doors), and the flat fully mapped (the true map: no frontier left, the largest free area to label).
Each ``survey`` (robot radius 0.15 m, the robot at the last scan's pose) is timed ``--repeat`` times
(wall clock, the bench process alone). Targets: <= 100 ms on 4000 x 4000, <= 10 ms on 400 x 400.
Then where the time goes, stage by stage, on the largest case.

Prints markdown tables (docs/performance.md, section "Exploration: frontiers and reachability").
"""

import argparse
import os
import platform
import statistics
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.core.geometry import Pose2D  # noqa: E402
from flask_move_server.explore import frontiers  # noqa: E402
from flask_move_server.maps.mapfile import Grid  # noqa: E402
from flask_move_server.sim.laser import Laser  # noqa: E402
from flask_move_server.sim.occupancy import OccupancyMap  # noqa: E402
from flask_move_server.sim.slam import SlamMap  # noqa: E402

RESOLUTION, RADIUS = 0.05, 0.15
SIZE = (20.0, 15.0)  # m, the flat's outer walls included; its bottom-left corner at (0, 0)
HALL = (6.5, 8.5)  # y range of the hallway across the whole flat
ROOMS_BELOW = [0.0, 8.0, 14.0, 17.0, 20.0]  # living room, kitchen, bathroom, utility: x boundaries
ROOMS_ABOVE = [0.0, 6.0, 12.0, 16.0, 20.0]  # three bedrooms and an office
FURNITURE = [(0.3, 0.3, 1.1, 3.0), (3.0, 1.5, 4.2, 2.3), (12.8, 0.2, 13.8, 6.0), (9.5, 2.0, 11.0, 3.5),
             (0.2, 13.0, 2.2, 14.8), (7.0, 12.5, 9.0, 14.8), (12.2, 14.0, 15.8, 14.8), (17.0, 12.0, 19.8, 14.8)]
STATES = [  # (name, scan poses): the robot surveys from the last one
    ("first scan (living room)", [(4.0, 3.5)]),
    ("half mapped (living room, hallway, kitchen)", [(4.0, 3.5), (4.0, 7.5), (10.0, 7.5), (10.0, 4.5)]),
]
CANVASES = [(4000, (-100.0, -100.0)), (400, (0.0, -2.5))]  # (cells a side, origin)


def true_flat():
    """The flat as an OccupancyMap: walls 0.1 m (outer 0.15 m), 0.9 m doors from the hallway."""
    width, height = int(round(SIZE[0] / RESOLUTION)), int(round(SIZE[1] / RESOLUTION))
    cells = np.zeros((height, width), dtype=np.int8)
    for rect in _walls() + FURNITURE:
        c0, r0, c1, r1 = (int(round(v / RESOLUTION)) for v in rect)
        cells[max(r0, 0):r1, max(c0, 0):c1] = 100
    return OccupancyMap(width, height, RESOLUTION, 0.0, 0.0, cells.ravel().tolist(), "bench flat")


def _walls():
    w, h = SIZE
    walls = [(0, 0, w, 0.15), (0, h - 0.15, w, h), (0, 0, 0.15, h), (w - 0.15, 0, w, h)]
    for y, xs, room_y in ((HALL[0], ROOMS_BELOW, (0, HALL[0])), (HALL[1], ROOMS_ABOVE, (HALL[1], h))):
        for left, right in zip(xs, xs[1:]):
            door = (left + right) / 2
            walls += [(left, y - 0.05, door - 0.45, y + 0.05), (door + 0.45, y - 0.05, right, y + 0.05)]
            if right < w:
                walls.append((right - 0.05, room_y[0], right + 0.05, room_y[1]))
    return walls


def mapped(truth, canvas, origin, poses):
    """(Grid, robot (x, y)) after SLAM scans from ``poses`` on a canvas x canvas map at ``origin``."""
    slam = SlamMap(Laser(truth), canvas, canvas, origin[0], origin[1])
    for x, y in poses:
        for yaw in (0.0, 1.6, 3.2, 4.8):  # turning on the spot: every wall in range seen twice
            slam.integrate(Pose2D(x, y, yaw))
    return Grid(canvas, canvas, RESOLUTION, origin[0], origin[1], slam.grid_bytes()), poses[-1]


def fully_mapped(truth, canvas, origin):
    """The true flat placed on the canvas, unknown around it: the whole flat known."""
    cells = np.full((canvas, canvas), -1, dtype=np.int8)
    row, col = int(round(-origin[1] / RESOLUTION)), int(round(-origin[0] / RESOLUTION))
    cells[row:row + truth.height, col:col + truth.width] = np.array(truth.cells, dtype=np.int8).reshape(
        truth.height, truth.width)
    return Grid(canvas, canvas, RESOLUTION, origin[0], origin[1], cells.tobytes()), (4.0, 3.5)


def timed(repeat, call, *args):
    """Milliseconds of ``repeat`` calls ``call(*args)`` (after one warm-up), and the last result."""
    result = call(*args)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        result = call(*args)
        times.append((time.perf_counter() - t) * 1e3)
    return times, result


def survey_rows(truth, repeat):
    print("| canvas | map state | known m² | reachable m² | frontiers (unreachable) | median ms | p95 ms | max ms |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    worst = None
    for canvas, origin in CANVASES:
        cases = [(name, mapped(truth, canvas, origin, poses)) for name, poses in STATES]
        cases.append(("fully mapped (the true flat)", fully_mapped(truth, canvas, origin)))
        for name, (grid, robot) in cases:
            times, found = timed(repeat, frontiers.survey, grid, robot, RADIUS)
            times.sort()
            print("| {0} x {0} | {1} | {2:.0f} | {3:.0f} | {4} ({5}) | {6:.1f} | {7:.1f} | {8:.1f} |".format(
                canvas, name, found.known_m2, found.free_m2, len(found.frontiers), len(found.unreachable),
                statistics.median(times), times[int(len(times) * 0.95)], times[-1]))
            if canvas == CANVASES[0][0] and (worst is None or statistics.median(times) > worst[0]):
                worst = (statistics.median(times), name, grid, robot)
    return worst


def stage_rows(worst, repeat):
    """The survey's stages timed one by one (its private steps, in its order) on one map."""
    _, name, grid, robot = worst
    reach = RADIUS / RESOLUTION + 0.5
    window = frontiers._Window.of(grid)
    standable = window.free & ~frontiers._dilate(window.occupied, reach) & window.clear_of_edge(reach)
    reachable = frontiers._reachable(window, robot, RADIUS)[0]
    groups = frontiers._groups(window, 0.3 / RESOLUTION)
    stages = [
        ("known cells' bounding box, window copied out (16 MB scanned)", frontiers._Window.of, grid),
        ("inflation: disk dilation of the occupied cells, the canvas edge",
         lambda: frontiers._dilate(window.occupied, reach) & window.clear_of_edge(reach)),
        ("reachable cells: label(standable, 4)", frontiers.label, standable, 4),
        ("frontier cells and their groups: label(frontier, 8)", frontiers._groups, window, 0.3 / RESOLUTION),
        ("{} targets and costs".format(len(groups)),
         lambda: [frontiers._frontier(window, reachable, rows, cols, robot, RADIUS, 1.0) for rows, cols in groups]),
        ("the whole survey", frontiers.survey, grid, robot, RADIUS),
    ]
    box = window.free.shape
    print("\n## Where one survey's time goes: {0} x {0} canvas, {1} (window {2} x {3} cells)\n".format(
        grid.width, name, box[1], box[0]))
    print("| stage | median ms |")
    print("|---|---:|")
    for label, call, *args in stages:
        print("| {} | {:.2f} |".format(label, statistics.median(timed(repeat, call, *args)[0])))
    whole = frontiers._Window(grid, frontiers.as_array(grid), (0, grid.height - 1), (0, grid.width - 1))
    t = time.perf_counter()
    frontiers._reachable(whole, robot, RADIUS)
    frontiers._groups(whole, 0.3 / RESOLUTION)
    print("| for comparison, once: the same steps on the whole canvas, no bounding box | {:.0f} |".format(
        (time.perf_counter() - t) * 1e3))


def machine():
    model = "?"
    try:
        with open("/proc/cpuinfo") as f:
            model = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), "?")
    except OSError:
        pass
    return "{}, {} cores, load average {:.1f}; Python {}, numpy {}".format(
        model, os.cpu_count(), os.getloadavg()[0], platform.python_version(), np.__version__)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30, help="surveys timed per map (default 30)")
    options = parser.parse_args()
    truth = true_flat()
    print("## Exploration: one frontiers.survey (robot radius {} m; {})\n".format(RADIUS, machine()))
    worst = survey_rows(truth, options.repeat)
    stage_rows(worst, options.repeat)


if __name__ == "__main__":
    main()
