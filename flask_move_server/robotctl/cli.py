"""``robotctl``: command the robot from a terminal (phase 3), built on requests.

``main(argv) -> exit status`` so tests and scripts call it directly. Every
failure is one readable line on stderr and an exit status of its kind
(:class:`~flask_move_server.robotctl.api.ExitStatus`); tracebacks only with
``--debug``.
"""

import argparse
import math
import os
import sys
import time
import traceback

from flask_move_server import __version__
from flask_move_server.core.errors import ClientError
from flask_move_server.core.goal_endings import failure_sentence, replaced_sentence
from flask_move_server.robotctl import dock as client_dock
from flask_move_server.robotctl import doctor as client_doctor
from flask_move_server.robotctl import maps as client_maps
from flask_move_server.robotctl import modes as client_modes
from flask_move_server.robotctl import routes as client_routes
from flask_move_server.robotctl import zones as client_zones
from flask_move_server.robotctl.api import DEFAULT_TIMEOUT, DEFAULT_URL, ExitStatus, RobotClient, dumps, waypoint_path
from flask_move_server.robotctl.text import (
    LiveLine,
    describe_status,
    progress,
    tolerant_output,
    waypoint_table,
    xy_yaw,
)

POLL_PERIOD = 0.5  # s between GET /status while `goto --wait` follows a goal

# how a goal that ended without arriving exits (the sentence is goal_endings.failure_sentence)
_GOAL_EXITS = {"canceled": ExitStatus.CANCELED, "canceling": ExitStatus.CANCELED, "idle": ExitStatus.CANCELED,
               "rejected": ExitStatus.REJECTED}


# goto, stop -----------------------------------------------------------------------


def cmd_goto(client, args):
    """Send the robot to a waypoint; with --wait, follow it until it ends."""
    answer = client.post("/goto", {"name": args.name})
    goal = answer.get("goal") or {}
    if not args.wait:
        _say("going to {} at ({}).".format(args.name, xy_yaw(goal)))
        return ExitStatus.OK
    return follow_goal(client, answer.get("goal_id"), args.name, args.wait_timeout)


def follow_goal(client, goal_id, name, timeout=None):
    """Poll /status with a live line until goal ``goal_id`` ends; its exit status."""
    deadline = None if timeout is None else time.monotonic() + timeout
    live = LiveLine(sys.stderr)
    try:
        while True:
            status = client.get("/status")
            nav = status["navigation"]
            if goal_id is not None and nav.get("goal_id") not in (None, goal_id):
                nav = dict(nav, state="canceled", message=replaced_sentence(name))
            state = nav.get("state")
            if state == "stuck" and not (status.get("stuck") or {}).get("waiting", True):
                state = "active"  # held while the robot gets itself out: the goal goes on after
            if state == "succeeded":
                live.end()
                _say("arrived at {}.".format(name))
                return ExitStatus.OK
            if state != "active":
                live.end()
                said = nav.get("message") or failure_sentence(state, name)  # as the server's /goto with wait
                raise ClientError(said, _GOAL_EXITS.get(state, ExitStatus.ABORTED))
            live.show(progress(name, nav))
            if deadline is not None and time.monotonic() >= deadline:
                live.end()
                raise ClientError("still moving to {} after {:g} s; the goal goes on ('robotctl stop' "
                                  "stops it).".format(name, timeout), ExitStatus.TIMEOUT)
            time.sleep(POLL_PERIOD)
    except KeyboardInterrupt:
        live.end()
        client.post("/stop")
        _say("interrupted: the robot was stopped.", sys.stderr)
        return ExitStatus.INTERRUPTED


def cmd_stop(client, args):
    """Cancel the goal, end teleop, zero velocity."""
    answer = client.post("/stop") or {}
    _say("stopped" + (" (goal canceled)." if answer.get("canceled_goal") else "."))
    return ExitStatus.OK


def cmd_back_out(client, args):
    """A robot that said it is stuck, and waits, backs out by itself (POST /stuck/back_out)."""
    stuck = (client.post("/stuck/back_out") or {}).get("stuck") or {}
    _say("backing out: {}".format(stuck.get("message") or "see robotctl status."))
    return ExitStatus.OK


def cmd_estop(client, args):
    """Latch the e-stop (everything stops; goals and teleop refused), or release it."""
    if args.action == "release":
        answer = client.post("/estop/release") or {}
        _say("e-stop released: goals and teleop are accepted again." if answer.get("released")
             else "the e-stop was not latched.")
        return ExitStatus.OK
    client.post("/estop")
    _say("e-stop latched: the robot is stopped and refuses goals and teleop until "
         "'robotctl estop release'.")
    return ExitStatus.OK


def cmd_teleop(client, args):
    """One velocity command, held for the server's deadman time."""
    answer = client.post("/teleop", {"linear": args.linear, "angular": args.angular})
    _say("driving at {:.2f} m/s, {:.2f} rad/s for {:g} s{}.".format(
        answer["linear"], answer["angular"], answer["hold"],
        " (clamped to the robot's limits)" if (answer["linear"], answer["angular"]) != (args.linear, args.angular)
        else ""))
    return ExitStatus.OK


def cmd_drive(client, args):
    """Keyboard teleop in this terminal."""
    from flask_move_server.robotctl.keyboard import KeyboardDriver

    return KeyboardDriver(client, args.linear, args.angular).run(sys.stdin, sys.stdout)


# status -----------------------------------------------------------------------------


def cmd_status(client, args):
    """A readable summary of GET /status (or the JSON with --json)."""
    data = client.get("/status")
    if args.json:
        _say(dumps(data))
        return ExitStatus.OK
    for line in describe_status(data, client.url):
        _say(line)
    return ExitStatus.OK


# waypoints -------------------------------------------------------------------------


def cmd_waypoints(client, args):
    """List, add or remove waypoints."""
    if args.action == "add":
        return _add_waypoint(client, args)
    if args.action == "rm":
        client.delete(waypoint_path(args.name))
        _say("removed {}.".format(args.name))
        return ExitStatus.OK
    waypoints = client.get("/waypoints")["waypoints"]
    if not waypoints:
        _say("no waypoints yet: 'robotctl waypoints add NAME --here' records the robot's pose.")
        return ExitStatus.OK
    for line in waypoint_table(waypoints):
        _say(line)
    return ExitStatus.OK


def _add_waypoint(client, args):
    if args.here == bool(args.coords) or (args.coords and len(args.coords) != 3):
        raise ClientError("waypoints add takes NAME --here, or NAME X Y YAW (metres, radians).", ExitStatus.USAGE)
    body = {"from": "current"} if args.here else dict(zip(("x", "y", "yaw"), args.coords))
    answer = client.put(waypoint_path(args.name), body)
    _say("{} {} at ({}).".format("added" if answer.get("created") else "moved", args.name,
                                 xy_yaw(answer.get("waypoint"))))
    return ExitStatus.OK


# discover ---------------------------------------------------------------------------


def cmd_discover(client, args):
    """List the robots advertising themselves over mDNS on this network."""
    from flask_move_server.lan import discovery

    robots = discovery.discover(timeout=args.wait)
    if not robots:
        raise ClientError("no robot answered over mDNS within {:g} s: is this computer on the robot's network "
                          "(some guest Wi-Fi blocks mDNS)?".format(args.wait), ExitStatus.NOT_FOUND)
    rows = [("NAME", "URL", "TOKEN", "VERSION")]
    for robot in robots:
        host = _field(robot, "host") or (_field(robot, "addresses") or ["?"])[0]
        rows.append((_field(robot, "name"), "http://{}:{}".format(host, _field(robot, "port")),
                     "required" if _field(robot, "token_required") else "no", _field(robot, "version") or "?"))
    widths = [max(len(str(r[i])) for r in rows) for i in range(4)]
    for row in rows:
        _say("  ".join(str(v).ljust(w) for v, w in zip(row, widths)).rstrip())
    return ExitStatus.OK


def _field(robot, name):
    return robot.get(name) if isinstance(robot, dict) else getattr(robot, name, None)


# the command line ------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line (the full usage is one --help away)."""

    def error(self, message):
        self.exit(ExitStatus.USAGE, "{}: error: {} ({} --help shows the usage)\n".format(self.prog, message, self.prog))


def build_parser():
    """robotctl's argparse parser."""
    parser = _Parser(prog="robotctl", description="Command a flask-move-server robot.")
    parser.add_argument("--url", default=os.environ.get("ROBOT_URL") or DEFAULT_URL,
                        help="the robot's address (env ROBOT_URL; default %(default)s)")
    parser.add_argument("--token", default=os.environ.get("ROBOT_TOKEN") or None,
                        help="the robot's bearer token (env ROBOT_TOKEN)")
    parser.add_argument("--request-timeout", type=_positive, default=DEFAULT_TIMEOUT, metavar="S",
                        help="give up on a request after S seconds (default %(default)s)")
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--version", action="version", version="%(prog)s " + __version__)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("goto", help="send the robot to a waypoint")
    p.add_argument("name")
    p.add_argument("--wait", action="store_true", help="follow the goal until it ends (exit 0 when reached)")
    p.add_argument("--timeout", dest="wait_timeout", type=_positive, metavar="S",
                   help="with --wait: give up waiting after S seconds (exit 12)")
    p.set_defaults(run=cmd_goto)
    sub.add_parser("stop", help="cancel the goal and stop").set_defaults(run=cmd_stop)
    client_dock.add_parsers(sub, _positive)
    client_zones.add_parsers(sub)
    sub.add_parser("back-out", help="a robot that says it is stuck backs out by itself").set_defaults(
        run=cmd_back_out)
    p = sub.add_parser("estop", help="latch the e-stop ('estop release' lifts it)")
    p.add_argument("action", nargs="?", choices=["release"], help="release the latched e-stop")
    p.set_defaults(run=cmd_estop)
    p = sub.add_parser("status", help="where the robot is and what it does")
    p.add_argument("--json", action="store_true", help="the raw JSON of GET /status")
    p.set_defaults(run=cmd_status)
    _waypoints_parser(sub)
    client_maps.add_parser(sub, _positive)
    client_modes.add_pose_parser(sub)
    client_routes.add_parsers(sub, _positive, _whole)
    p = sub.add_parser("teleop", help="drive at LIN m/s and ANG rad/s for the deadman time")
    p.add_argument("linear", type=_finite, metavar="LIN")
    p.add_argument("angular", type=_finite, metavar="ANG")
    p.set_defaults(run=cmd_teleop)
    p = sub.add_parser("drive", help="keyboard teleop: arrows/WASD, space stops, q quits")
    p.add_argument("--linear", type=_positive, default=0.2, help="forward speed, m/s (default %(default)s)")
    p.add_argument("--angular", type=_positive, default=0.8, help="turn rate, rad/s (default %(default)s)")
    p.set_defaults(run=cmd_drive)
    client_doctor.add_parser(sub, _positive)
    p = sub.add_parser("discover", help="find robots on this network (mDNS)")
    p.add_argument("--wait", type=_positive, default=3.0, metavar="S", help="listen S seconds (default 3)")
    p.set_defaults(run=cmd_discover)
    return parser


def _waypoints_parser(sub):
    p = sub.add_parser("waypoints", help="list waypoints; 'add' or 'rm' one")
    p.set_defaults(run=cmd_waypoints, action="list")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    add = actions.add_parser("add", help="NAME --here, or NAME X Y YAW")
    add.add_argument("name")
    add.add_argument("coords", nargs="*", type=_finite, metavar="X Y YAW")
    add.add_argument("--here", action="store_true", help="record the robot's current pose")
    rm = actions.add_parser("rm", help="remove waypoint NAME")
    rm.add_argument("name")


def _finite(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError("{!r} is not a number".format(text))
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError("{!r} is not a finite number".format(text))
    return value


def _positive(text):
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError("{!r} must be greater than 0".format(text))
    return value


def _whole(text):
    """A whole number from 1 (a run's id, a count)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("{!r} is not a whole number".format(text))
    if value < 1:
        raise argparse.ArgumentTypeError("{!r} must be 1 or more".format(text))
    return value


def _say(text, stream=None):
    print(text, file=stream or sys.stdout, flush=True)


def main(argv=None):
    """Run one robotctl command; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    tolerant_output()
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code
    client = RobotClient(args.url, args.token, args.request_timeout)
    try:
        return args.run(client, args)
    except ClientError as exc:
        if args.debug:
            traceback.print_exc()
        _say("robotctl: {}".format(exc), sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        _say("robotctl: interrupted.", sys.stderr)
        return ExitStatus.INTERRUPTED
    except Exception as exc:  # a bug or an odd answer: one line unless --debug
        if args.debug:
            raise
        _say("robotctl: unexpected {}: {} (run with --debug for details).".format(type(exc).__name__, exc),
             sys.stderr)
        return ExitStatus.ERROR
    finally:
        client.close()


if __name__ == "__main__":
    sys.exit(main())
