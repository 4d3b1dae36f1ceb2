"""Benchmark of the simulated SLAM (sim/slam.py): CPU at real time, and how long mapping the demo flat takes.

    .venv/bin/python bench/bench_slam.py

The robot drives a fixed tour of the demo flat (dock → kitchen → bedroom →
office → sofa → dock, paths planned on the true map) at the sim's 0.3 m/s,
facing along its path, and a 360-beam, 8 m scan is integrated every 1/5.5 s
of simulated time: every scan, no movement gate, so the CPU figure is the
worst case at real time. Target: <= 20 % of one core. Then the planner on the
growing map (costmap rebuild + plan), the /map message, and a gmapping-sized
4000 x 4000 canvas.

Prints markdown tables (docs/performance.md, section Simulated SLAM).
"""

import math
import os
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.core.geometry import Pose2D  # noqa: E402
from flask_move_server.sim import costmap, occupancy, planner  # noqa: E402
from flask_move_server.sim.laser import Laser  # noqa: E402
from flask_move_server.sim.slam import GrowingMapPlanner, SlamMap  # noqa: E402

DEMO_MAP = os.path.join(ROOT, "config", "maps", "demo.yaml")
TOUR = [(0.0, 0.0), (8.4, 0.9), (6.2, 4.5), (-0.8, 4.3), (-0.5, 1.0), (0.0, 0.0)]
SPEED, SCAN_RATE = 0.3, 5.5


def tour_poses(truth):
    """Poses 1/5.5 s apart along the tour at SPEED (turning on the spot takes no time: a lower bound)."""
    plan = planner.Planner(costmap.Costmap(truth, 0.15, 0.1)).plan
    step = SPEED / SCAN_RATE
    poses = []
    for start, goal in zip(TOUR, TOUR[1:]):
        path = plan(start, goal)
        for (ax, ay), (bx, by) in zip(path, path[1:]):
            length, yaw = math.hypot(bx - ax, by - ay), math.atan2(by - ay, bx - ax)
            for k in range(int(length / step)):
                f = k * step / length
                poses.append(Pose2D(ax + (bx - ax) * f, ay + (by - ay) * f, yaw))
    return poses


def coverage(slam, truth, free_cells):
    """Share of the true map's free cells the SLAM map shows free."""
    seen = sum(1 for p in free_cells if slam.value_at(*truth.center_of(p % truth.width, p // truth.width)) == 0)
    return seen / len(free_cells)


def tour_rows(truth):
    slam = SlamMap.around(Laser(truth), margin=2.0)
    free_cells = [p for p, v in enumerate(truth.cells) if v == 0]
    poses = tour_poses(truth)
    times, milestones, checkpoints = [], {}, range(0, len(poses), int(SCAN_RATE * 5))
    for i, pose in enumerate(poses):
        t = time.process_time()
        slam.integrate(pose)
        times.append(time.process_time() - t)
        if i in checkpoints:
            share = coverage(slam, truth, free_cells)
            for mark in (0.5, 0.9, 0.95):
                if mark not in milestones and share >= mark:
                    milestones[mark] = i / SCAN_RATE
    final = coverage(slam, truth, free_cells)
    return slam, times, milestones, final, len(poses) / SCAN_RATE


def planning_rows(slam):
    growing = GrowingMapPlanner(slam, 0.15, 0.1)
    t = time.perf_counter()
    growing.plan((0.0, 0.0), (6.2, 4.5))
    first = (time.perf_counter() - t) * 1e3
    t = time.perf_counter()
    growing.plan((0.0, 0.0), (6.2, 4.5))
    again = (time.perf_counter() - t) * 1e3
    return first, again


def publish_ms(slam):
    """Building and serializing the /map message as rospy does on publish (genpy packs int8[] per element)."""
    import io

    import rospy

    from flask_move_server.sim.mapping import occupancy_grid

    t = time.perf_counter()
    occupancy_grid(slam, "map", rospy.Time(0)).serialize(io.BytesIO())
    return (time.perf_counter() - t) * 1e3


def big_canvas_rows(truth):
    laser = Laser(truth)
    t = time.perf_counter()
    slam = SlamMap(laser, 4000, 4000, truth.origin_x - 95.0, truth.origin_y - 95.0)
    create = (time.perf_counter() - t) * 1e3
    scans = []
    for pose in (Pose2D(0.0, 0.0, 0.0), Pose2D(6.2, 1.2, 0.0), Pose2D(6.2, 4.5, 0.0)) * 3:
        t = time.perf_counter()
        slam.integrate(pose)
        scans.append((time.perf_counter() - t) * 1e3)
    t = time.perf_counter()
    for _ in range(10):
        slam.grid_bytes()
    copy = (time.perf_counter() - t) * 1e2
    t = time.perf_counter()
    GrowingMapPlanner(slam, 0.15, 0.1).plan((0.0, 0.0), (2.0, 1.0))
    rebuild = (time.perf_counter() - t) * 1e3
    return create, statistics.median(scans), copy, rebuild, publish_ms(slam)


def main():
    truth = occupancy.load(DEMO_MAP)
    slam, times, milestones, final, seconds = tour_rows(truth)
    ms = [t * 1e3 for t in times]
    cpu = sum(times) / seconds * 100
    print("## Simulated SLAM: the demo flat's tour ({} scans, {:.0f} s at {} m/s; canvas {} x {})\n".format(
        len(times), seconds, SPEED, slam.width, slam.height))
    print("| measure | value |")
    print("|---|---:|")
    print("| scan integration, median / p95 / max | {:.1f} / {:.1f} / {:.1f} ms |".format(
        statistics.median(ms), sorted(ms)[int(len(ms) * 0.95)], max(ms)))
    print("| CPU at real time (5.5 scans/s, every scan) | {:.1f} % of one core |".format(cpu))
    for mark in (0.5, 0.9, 0.95):
        reached = milestones.get(mark)
        print("| {:.0f} % of the flat's free cells mapped after | {} |".format(
            mark * 100, "not reached" if reached is None else "{:.0f} s".format(reached)))
    print("| mapped at the end of the tour | {:.1f} % (the locked store room is never seen) |".format(final * 100))
    print("| map versions / scans | {} / {} |".format(slam.version, slam.scans))
    first, again = planning_rows(slam)
    print("| plan dock → bedroom on the mapped flat: costmap rebuild + plan / plan again | {:.0f} / {:.0f} ms |".format(
        first, again))
    print("| /map message built and serialized (sim/mapping.py) | {:.1f} ms |".format(publish_ms(slam)))
    create, scan, copy, rebuild, publish = big_canvas_rows(truth)
    print("\n## A gmapping-sized canvas (4000 x 4000 cells, the flat in it)\n")
    print("| measure | value |")
    print("|---|---:|")
    print("| create (all unknown) | {:.0f} ms |".format(create))
    print("| scan integration, median | {:.1f} ms |".format(scan))
    print("| grid_bytes() (16 MB copy) | {:.1f} ms |".format(copy))
    print("| costmap rebuild + a short plan | {:.0f} ms |".format(rebuild))
    print("| /map message built and serialized | {:.0f} ms |".format(publish))


if __name__ == "__main__":
    main()
