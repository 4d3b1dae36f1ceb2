"""Benchmark of the simulation's modes (modes/simulated.py): switch times, and mapping's CPU at real time.

    .venv/bin/python bench/bench_sim_modes.py [--switches 5] [--drive-seconds 60]

Starts its own ROS master; the sim is built in this process as ``cli`` builds it
(node, sim motor backend under the real base controller, ``Simulation``) at speed
factor 1. Then:

1. Switch times: each switch is ``stop()`` then ``start()`` of the stack backend, as
   the mode manager calls them, with an action client there as the server's navigator
   (``start()`` returns once it is connected) (idle → navigation on the sim's own map → mapping →
   navigation on a saved map → idle), ``--switches`` rounds; the saved map is the
   SLAM map of the demo flat's living room. Target: well under a second.
2. Mapping at real time: the robot explores the demo flat in mapping mode, sent by
   actionlib goals into the unknown (kitchen, bedroom, office, sofa, dock) for at
   most ``--drive-seconds``; the CPU of the simulated SLAM's thread (scans and
   /map), of the stand-in's goal thread (following, replanning on the grown map)
   and of the whole process, as shares of one core; and the map's coverage.
   Target: SLAM <= 20 % of one core.

Prints markdown tables (docs/performance.md, section "Simulated modes").
"""

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import free_port, start_master, stop_process, wait_for  # noqa: E402

TICKS = os.sysconf("SC_CLK_TCK")
TOUR = [(8.4, 0.9), (6.2, 4.5), (-0.8, 4.3), (-0.5, 1.0), (0.0, 0.0)]


def thread_cpu(thread):
    """CPU seconds a live thread has used so far (Linux: /proc/self/task/TID/stat)."""
    try:
        with open("/proc/self/task/{}/stat".format(thread.native_id)) as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except (OSError, AttributeError):
        return 0.0
    return (int(fields[11]) + int(fields[12])) / TICKS


def build(node, tmp):
    """The sim as cli builds it: config, drive, Simulation (not started)."""
    from flask_move_server import config
    from flask_move_server.drive import make_drive
    from flask_move_server.sim.runner import Simulation

    cfg = config.Config()
    cfg.sim.enabled, cfg.drive.backend = True, "sim"
    cfg.waypoints.file = os.path.join(tmp, "waypoints.yaml")
    drive = make_drive(cfg.drive, node, cfg.ros.frames)
    return drive, Simulation(cfg, node, drive, autostart=False)


def saved_living_room(sim, tmp):
    """Map the living room from the dock and save it: the map 'navigation on a saved map' loads."""
    from flask_move_server.maps import mapfile

    sim.stacks.start("mapping")
    slam = wait_for(lambda: sim.stacks.slam if sim.stacks.slam.scans else None, message="a first scan")
    grid = mapfile.Grid(slam.width, slam.height, slam.resolution, slam.origin_x, slam.origin_y, slam.grid_bytes())
    return mapfile.save(tmp, "living_room", grid)


def switch_rows(sim, saved, rounds):
    """Switch times with an action client present, as the server's navigator is: start() waits for it."""
    import actionlib
    from move_base_msgs.msg import MoveBaseAction

    client = actionlib.SimpleActionClient("move_base", MoveBaseAction)  # noqa: F841 (kept alive: a client)
    stacks = sim.stacks
    steps = [("idle → navigation (the sim's own map)", "navigation", None), ("navigation → mapping", "mapping", None),
             ("mapping → navigation on a saved map", "navigation", saved), ("navigation → idle", "idle", None)]
    times = {label: [] for label, _, _ in steps}
    stacks.stop()
    for _ in range(rounds):
        for label, mode, map_yaml in steps:
            t = time.perf_counter()
            stacks.stop()
            stacks.start(mode, map_yaml)
            times[label].append((time.perf_counter() - t) * 1e3)
            time.sleep(0.3)
    return [(label, statistics.median(v), max(v)) for label, v in times.items()]


def explore(sim, seconds):
    """Mapping mode, goals into the unknown at real time: (CPU shares, coverage, goals reached, seconds)."""
    import actionlib
    import rospy
    from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal

    from flask_move_server.core.geometry import Pose2D
    from flask_move_server.ros.convert import pose_stamped

    sim.stacks.stop()
    sim.stacks.start("mapping")
    client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
    assert client.wait_for_server(rospy.Duration(10)), "the move_base stand-in does not answer"
    slam_thread = wait_for(lambda: _thread_named("sim-mapping"), message="the SLAM thread")
    start_cpu, start_slam, started = time.process_time(), thread_cpu(slam_thread), time.monotonic()
    goal_cpu, reached = 0.0, 0
    for x, y in TOUR:
        left = seconds - (time.monotonic() - started)
        if left <= 0:
            break
        goal = MoveBaseGoal(target_pose=pose_stamped(Pose2D(x, y, 0.0), "map", rospy.Time.now()))
        client.send_goal(goal)
        goal_thread = wait_for(lambda: _goal_thread(sim), message="the goal thread")
        before = thread_cpu(goal_thread)
        client.wait_for_result(rospy.Duration(left))
        goal_cpu += thread_cpu(goal_thread) - before
        reached += client.get_state() == actionlib.GoalStatus.SUCCEEDED
    client.cancel_all_goals()
    elapsed = time.monotonic() - started
    shares = ((thread_cpu(slam_thread) - start_slam) / elapsed, goal_cpu / elapsed,
              (time.process_time() - start_cpu) / elapsed)
    return shares, coverage(sim.stacks.slam), reached, elapsed


def _thread_named(name):
    return next((t for t in threading.enumerate() if t.name == name), None)


def _goal_thread(sim):
    endpoint = sim.move_base._endpoint
    return endpoint.server.execute_thread if endpoint is not None else None


def coverage(slam):
    from flask_move_server.sim import occupancy

    truth = occupancy.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
    free = [truth.center_of(i % truth.width, i // truth.width) for i, v in enumerate(truth.cells) if v == 0]
    return sum(1 for x, y in free if slam.value_at(x, y) == 0) / len(free)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--switches", type=int, default=5, help="rounds of the four switches")
    parser.add_argument("--drive-seconds", type=float, default=120.0, help="longest exploration at real time")
    opts = parser.parse_args(argv)
    port = free_port()
    os.environ.update(ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_IP="127.0.0.1")
    master = start_master(port)
    from flask_move_server.ros.node import RosNode

    node = RosNode("bench_sim_modes", check_period=1.0)
    node.start()
    assert node.wait_connected(15), "no ROS master"
    try:
        with tempfile.TemporaryDirectory() as tmp:
            drive, sim = build(node, tmp)
            try:
                saved = saved_living_room(sim, tmp)
                print_switches(switch_rows(sim, saved, opts.switches), opts.switches)
                print_mapping(*explore(sim, opts.drive_seconds))
            finally:
                sim.close()
                drive.close()
    finally:
        node.close()
        stop_process(master)


def print_switches(rows, rounds):
    print("### Simulated modes: switch times (stop + start, {} rounds)\n".format(rounds))
    print("| switch | median ms | max ms |\n|---|---:|---:|")
    for label, median, most in rows:
        print("| {} | {:.0f} | {:.0f} |".format(label, median, most))
    print()


def print_mapping(shares, covered, reached, elapsed):
    slam, goal, process = shares
    print("### Simulated modes: exploring the demo flat in mapping mode at real time\n")
    print("| measure | value |\n|---|---:|")
    print("| goals into the unknown reached | {} of {} in {:.0f} s |".format(reached, len(TOUR), elapsed))
    print("| free space of the flat mapped | {:.1%} |".format(covered))
    print("| SLAM thread (scans, /map) | {:.1%} of one core |".format(slam))
    print("| move_base stand-in's goal thread (following, replanning) | {:.1%} of one core |".format(goal))
    print("| whole process (world, base controller, SLAM, stand-in, rospy) | {:.1%} of one core |".format(process))
    print()


if __name__ == "__main__":
    main()
