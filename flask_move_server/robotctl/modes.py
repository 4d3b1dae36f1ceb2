"""``robotctl map start``, ``robotctl map use NAME``, ``robotctl pose``: the modes from a terminal.

A switch answers at once (``POST /mode``, 202); these commands then follow ``GET /mode`` with a
live line (``navigation on flat: starting, starting navigation on the map 'flat'``) until the
mode runs (exit 0) or fails (exit 6, the robot's reason on stderr), as ``goto --wait`` follows a
goal. ``--no-wait`` returns at once; ``--timeout S`` gives up waiting (exit 12; the switch goes on).
"""

import sys
import time

from flask_move_server.core.errors import ClientError
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.robotctl.text import LiveLine

POLL_PERIOD = 0.5  # s between GET /mode while a switch is followed


def cmd_map(client, args):
    """``map start``: start mapping; ``map use NAME``: navigate on the saved map NAME."""
    if args.action == "start":
        body = {"mode": "mapping"}
    else:
        body = {"mode": "navigation", "map": args.name}
        if args.at:
            body["pose"] = {"name": args.at}
    mode = client.post("/mode", body)
    if args.no_wait:
        _say("switching: {}.".format(_describe(mode)))
        return ExitStatus.OK
    return follow_mode(client, args.timeout)


def follow_mode(client, timeout=None):
    """Poll ``GET /mode`` with a live line until the switch runs or fails; its exit status."""
    deadline = None if timeout is None else time.monotonic() + timeout
    live = LiveLine(sys.stderr)
    while True:
        mode = client.get("/mode")
        state = mode.get("state")
        if state == "running":
            live.end()
            _say("{}: {}".format(_title(mode), mode.get("message") or "running"))
            return ExitStatus.OK
        if state == "failed":
            live.end()
            raise ClientError("{} failed: {}".format(_title(mode), mode.get("message")), ExitStatus.UNAVAILABLE)
        live.show(_describe(mode))
        if deadline is not None and time.monotonic() >= deadline:
            live.end()
            raise ClientError("{} is still {} after {:g} s; the switch goes on ('robotctl status' follows it)."
                              .format(_title(mode), state, timeout), ExitStatus.TIMEOUT)
        time.sleep(POLL_PERIOD)


def cmd_pose(client, args):
    """Tell localization where the robot is: at a waypoint, or at X Y YAW (map frame); or confirm it."""
    if args.confirm:
        return _confirm_pose(client, args.where)
    if len(args.where) == 1:
        body = {"name": args.where[0]}
    elif len(args.where) == 3:
        try:
            body = dict(zip(("x", "y", "yaw"), (float(v) for v in args.where)))
        except ValueError:
            raise ClientError("pose takes a waypoint NAME, or X Y YAW in metres and radians.", ExitStatus.USAGE)
    else:
        raise ClientError("pose takes a waypoint NAME, or X Y YAW in metres and radians.", ExitStatus.USAGE)
    answer = client.post("/pose", body)
    pose = answer.get("pose") or {}
    _say("the robot's pose is set to {}({:.2f}, {:.2f}, {:.2f}).".format(
        answer["name"] + " " if answer.get("name") else "", pose.get("x"), pose.get("y"), pose.get("yaw")))
    return ExitStatus.OK


def _confirm_pose(client, where):
    if where:
        raise ClientError("pose --confirm takes nothing else: it says the pose the robot holds is right.",
                          ExitStatus.USAGE)
    client.post("/pose", {"confirm": True})
    _say("the robot's pose is confirmed.")
    return ExitStatus.OK


def _title(mode):
    if mode.get("mode") == "navigation" and mode.get("map"):
        return "navigation on {}".format(mode["map"])
    return str(mode.get("mode"))


def _describe(mode):
    return "{}: {}, {}".format(_title(mode), mode.get("state"), mode.get("message") or "")


def add_map_actions(actions, positive):
    """``map start`` and ``map use`` on the ``map`` parser's actions; ``positive``: robotctl's seconds type."""
    start = actions.add_parser("start", help="start mapping (SLAM): drive around, then save the map")
    use = actions.add_parser("use", help="navigate on the saved map NAME")
    use.add_argument("name", metavar="NAME")
    use.add_argument("--at", metavar="WAYPOINT", help="the robot stands at this waypoint of the map (default: dock)")
    for action in (start, use):
        action.add_argument("--no-wait", action="store_true", help="return once the switch is accepted")
        action.add_argument("--timeout", type=positive, metavar="S", help="give up waiting after S seconds (exit 12)")


def add_pose_parser(sub):
    """``robotctl pose NAME|X Y YAW``, ``robotctl pose --confirm``."""
    p = sub.add_parser("pose", help="set the robot's pose: NAME (a waypoint) or X Y YAW; --confirm: it is right")
    p.add_argument("where", nargs="*", metavar="NAME|X Y YAW")
    p.add_argument("--confirm", action="store_true",
                   help="the robot is where it believes (the dock assumed after a switch): say so, set nothing")
    p.set_defaults(run=cmd_pose)


def _say(text, stream=None):
    print(text, file=stream or sys.stdout, flush=True)
