"""``robotctl dock [--wait]`` and ``robotctl undock``: home onto the charger and off it (POST /dock, /undock).

``--wait`` follows ``GET /status`` ``dock`` with a live line until the robot is on its charger
(exit 0), gave up or was stopped (exit 10, the robot's words on stderr), or ``--timeout`` runs
out (exit 12; the docking goes on). Ctrl-C stops the robot (exit 130).
"""

import sys
import time

from flask_move_server.core.errors import ClientError
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.robotctl.text import LiveLine

POLL_PERIOD = 0.5
ON_IT = ("docked", "charging")
UNDER_WAY = ("going", "approaching")


def cmd_dock(client, args):
    """Home onto the map's charger; with --wait, follow it until it is on it."""
    dock = (client.post("/dock") or {}).get("dock") or {}
    print(dock.get("message") or "docking.")
    if not args.wait or dock.get("state") in ON_IT:
        return ExitStatus.OK
    return follow_docking(client, args.wait_timeout)


def follow_docking(client, timeout=None):
    """Poll /status with a live line until the docking ends; its exit status."""
    deadline = None if timeout is None else time.monotonic() + timeout
    live = LiveLine(sys.stderr)
    try:
        while True:
            dock = client.get("/status").get("dock") or {}
            state, message = dock.get("state"), dock.get("message") or ""
            if state in ON_IT:
                live.end()
                print(message)
                return ExitStatus.OK
            if state not in UNDER_WAY:
                live.end()
                raise ClientError(message or "the docking ended ({}).".format(state), ExitStatus.ABORTED)
            live.show(message)
            if deadline is not None and time.monotonic() >= deadline:
                live.end()
                raise ClientError("still docking after {:g} s; it goes on ('robotctl stop' stops it).".format(
                    timeout), ExitStatus.TIMEOUT)
            time.sleep(POLL_PERIOD)
    except KeyboardInterrupt:
        live.end()
        client.post("/stop")
        print("interrupted: the robot was stopped.", file=sys.stderr)
        return ExitStatus.INTERRUPTED


def cmd_undock(client, args):
    """Back straight off the charger."""
    dock = (client.post("/undock") or {}).get("dock") or {}
    print(dock.get("message") or "backing off the charger.")
    return ExitStatus.OK


def add_parsers(sub, positive):
    """``robotctl dock`` and ``robotctl undock`` on robotctl's subcommand parser ``sub``."""
    p = sub.add_parser("dock", help="home onto the map's charger")
    p.add_argument("--wait", action="store_true", help="follow it until it is on the charger (exit 0)")
    p.add_argument("--timeout", dest="wait_timeout", type=positive, metavar="S",
                   help="with --wait: give up waiting after S seconds (exit 12; the docking goes on)")
    p.set_defaults(run=cmd_dock)
    sub.add_parser("undock", help="back straight off the charger").set_defaults(run=cmd_undock)
