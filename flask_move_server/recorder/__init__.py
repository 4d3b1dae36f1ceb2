"""``record-waypoints``: name places on the map beside RViz (phase 2).

Click a place with RViz's "Publish Point" (``/clicked_point``) or "2D Nav
Goal" set to our topic (``/waypoint_goal``, with heading) and type its name,
or drive the robot there and type a name to save its pose (tf ``map →
base_link``, else ``/amcl_pose``). Every waypoint shows in RViz as a latched
MarkerArray on ``/waypoint_markers``. Saves through the server's API when
``--server`` answers, else to the YAML file through the same locked, atomic
store.
"""

import argparse
import contextlib
import os
import signal
import sys
import time

from flask_move_server.core.errors import ClientError, MoveServerError, WaypointFileError
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.robotctl.text import tolerant_output

NODE_NAME = "record_waypoints"


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog="record-waypoints", description="Name places on the map, beside RViz (clicks or the robot's pose).")
    parser.add_argument("--waypoints", metavar="FILE", default="waypoints.yaml",
                        help="the waypoints file, used when no --server answers (default %(default)s)")
    parser.add_argument("--server", metavar="URL", help="save through this flask-move-server when it answers")
    parser.add_argument("--token", default=os.environ.get("ROBOT_TOKEN") or None,
                        help="the server's bearer token (env ROBOT_TOKEN)")
    parser.add_argument("--auto-names", action="store_true", help="name clicked places wp1, wp2, ... without asking")
    parser.add_argument("--map-frame", default="map", help="the map frame (default %(default)s)")
    parser.add_argument("--base-frame", default="base_link", help="the robot's frame (default %(default)s)")
    parser.add_argument("--amcl-topic", default="amcl_pose", help="AMCL's pose topic (default %(default)s)")
    parser.add_argument("--clicked-topic", default="/clicked_point", help="RViz Publish Point (default %(default)s)")
    parser.add_argument("--goal-topic", default="/waypoint_goal",
                        help="set RViz's 2D Nav Goal to this topic to mark places with a heading (default %(default)s)")
    parser.add_argument("--markers-topic", default="/waypoint_markers", help="MarkerArray topic (default %(default)s)")
    return parser.parse_args(argv)


def main(argv=None):
    """Run the recorder until quit, Ctrl-C or end of input; the exit status."""
    try:
        return _main(argv)
    except KeyboardInterrupt:  # Ctrl-C while starting: nothing was saved yet
        return _fail("interrupted.", ExitStatus.INTERRUPTED)


def _main(argv):
    from flask_move_server.app.launching import split_ros_args
    from flask_move_server.ros import master

    argv = sys.argv[1:] if argv is None else list(argv)
    tolerant_output()
    ours, _ = split_ros_args(argv)  # name:=value remaps are rospy's (it reads sys.argv)
    args = parse_args(ours)
    if master.identity("/" + NODE_NAME, timeout=2.0) is None:
        return _fail("no ROS master answers at {}: start roscore (or the robot's launch file), or point "
                     "ROS_MASTER_URI at the robot's master (http://robot.local:11311) and set ROS_IP to this "
                     "computer's address.".format(master.master_uri()), ExitStatus.UNREACHABLE)
    try:
        from flask_move_server.recorder.savers import choose_saver

        saver = choose_saver(args.waypoints, args.server, args.token, say=_say)
    except (ClientError, WaypointFileError) as exc:
        return _fail(str(exc), getattr(exc, "exit_status", ExitStatus.ERROR))
    with contextlib.ExitStack() as stack:
        stack.callback(saver.close)
        return _record(args, saver, stack)


def _record(args, saver, stack):
    from flask_move_server.recorder import prompt
    from flask_move_server.recorder.markers import MarkerPublisher
    from flask_move_server.recorder.ros_io import RosSide
    from flask_move_server.recorder.session import Session
    from flask_move_server.ros.node import RosNode

    node = RosNode(NODE_NAME, check_period=1.0, exit_on_new_master=False)
    node.start()
    stack.callback(node.close)
    if not node.wait_connected(15):
        return _fail("could not register with the ROS master at {}.".format(node.master_uri), ExitStatus.UNREACHABLE)
    ros = RosSide(args.map_frame, args.base_frame, args.amcl_topic, args.clicked_topic, args.goal_topic)
    stack.callback(ros.close)
    markers = MarkerPublisher(args.markers_topic, args.map_frame)
    stack.callback(markers.close)
    session = Session(saver, ros, markers, say=_say, auto_names=args.auto_names, goal_topic=args.goal_topic)
    _introduce(session, ros, args)
    previous = signal.signal(signal.SIGTERM, _interrupt)  # roslaunch and systemd stop with SIGTERM too
    try:
        prompt.run(session, sys.stdin.fileno())
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
    try:
        _say("Bye: {} waypoints in {}.".format(len(saver.all()), saver.where))
    except MoveServerError:
        _say("Bye.")
    return ExitStatus.OK


def _introduce(session, ros, args):
    try:
        session.refresh()
    except MoveServerError as exc:
        _say("Cannot read the waypoints: {}".format(exc))
    _say("Recording waypoints in {}; RViz shows them on {} (frame {}).".format(
        session.saver.where, args.markers_topic, args.map_frame))
    _say("Type a name to save the robot's pose, or click in RViz ({}); 'help' for more.".format(
        "named wp1, wp2, ... automatically" if args.auto_names else "then type its name"))
    deadline = time.monotonic() + 1.5
    while not ros.has_map_frame() and time.monotonic() < deadline:
        time.sleep(0.1)
    if not ros.has_map_frame():
        _say(ros.why_no_pose())


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def _say(text):
    print(text, flush=True)


def _fail(message, status):
    print("record-waypoints: {}".format(message), file=sys.stderr, flush=True)
    return status
