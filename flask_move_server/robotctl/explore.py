"""``robotctl map explore NAME``: the robot maps the flat by itself, comes back and saves the map as NAME.

It sends ``POST /explore``. With ``--wait`` it follows ``GET /explore`` with a live line
(``exploring: 3 frontiers left, 42 m² known, 5 goals, 1 unreachable, 2:10``) until the exploration
ends, as ``route run --wait`` follows a run: exit 0 when the map was saved, 10 when the exploration
failed or the robot got stuck, 11 when it was canceled (``robotctl stop``, the e-stop); ``--timeout S`` gives up waiting
(exit 12, it goes on). Ctrl-C stops the robot, which ends the exploration (exit 130).
"""

import argparse
import re
import sys
import time

from flask_move_server.core.errors import ClientError
from flask_move_server.explore.exploration import MAX_MINUTES
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.robotctl.text import LiveLine, in_robotctl_words, rewritten

POLL_PERIOD = 0.5  # s between GET /explore while --wait follows an exploration
ACTIVE = ("starting", "exploring", "returning", "saving")
_EXITS = {"failed": ExitStatus.ABORTED, "stuck": ExitStatus.ABORTED, "canceled": ExitStatus.CANCELED}


def cmd_explore(client, args):
    """Start exploring, to save the map as NAME; with --wait, follow it until it ends."""
    body = {"save_as": args.name, "then": args.then}
    if args.max_minutes is not None:
        body["max_minutes"] = args.max_minutes
    if args.overwrite:
        body["overwrite"] = True
    if args.no_return:
        body["return_home"] = False
    with _in_robotctl_words(args.name):
        exploration = client.post("/explore", body)["exploration"]
    if not args.wait:
        _say(started_line(exploration))
        return ExitStatus.OK
    return follow_exploration(client, exploration, args.wait_timeout)


def follow_exploration(client, exploration, timeout=None):
    """Poll ``GET /explore`` with a live line until ``exploration`` ends; its exit status. Ctrl-C stops the robot."""
    deadline = None if timeout is None else time.monotonic() + timeout
    live = LiveLine(sys.stderr)
    try:
        while exploration["state"] in ACTIVE:
            live.show(progress(exploration), (exploration["state"], exploration.get("goals")))
            if deadline is not None and time.monotonic() >= deadline:
                live.end()
                raise ClientError("still {} after {:g} s; the exploration goes on ('robotctl stop' ends it)."
                                  .format(exploration["state"], timeout), ExitStatus.TIMEOUT)
            time.sleep(POLL_PERIOD)
            exploration = client.get("/explore")["exploration"] or exploration
    except KeyboardInterrupt:
        live.end()
        client.post("/stop")
        _say("interrupted: the robot was stopped, which ends the exploration; the map made so far is not saved "
             "('robotctl map save NAME' saves it while the robot is still mapping).", sys.stderr)
        return ExitStatus.INTERRUPTED
    live.end()
    if exploration["state"] == "done":
        _say(ended_line(exploration))
        return ExitStatus.OK
    raise ClientError(_robotctl_words(ended_line(exploration)), _EXITS.get(exploration["state"], ExitStatus.ERROR))


# what it prints ---------------------------------------------------------------------------------


def started_line(exploration):
    """What ``map explore NAME`` says once the robot took it."""
    then = "navigates on it" if exploration.get("then", "navigation") == "navigation" else "stays idle"
    return ("exploring: the robot maps by itself for up to {}, comes back, saves the map as {}, then {} "
            "('robotctl stop' ends it).".format(_minutes(exploration.get("max_minutes")), exploration["save_as"],
                                                then))


def progress(exploration):
    """The live line: ``exploring: 3 frontiers left, 42 m² known, 5 goals, 1 unreachable, 2:10``."""
    state = exploration["state"]
    counts = "{}, {}, {} unreachable".format(_known(exploration), _count(exploration.get("goals", 0), "goal"),
                                            exploration.get("unreachable", 0))
    if state == "exploring":
        doing = "{} left, {}".format(_count(exploration.get("frontiers", 0), "frontier"), counts)
    elif state == "returning":
        doing = "going back to where it started, " + counts
    elif state == "saving":
        doing = "saving the map as {}".format(exploration["save_as"])
    else:
        doing = "mapping starts"
    return "{}: {}, {}".format(state, doing, clock(exploration.get("elapsed")))


def ended_line(exploration):
    """The last word: ``explored in 3:02: saved the map flat (61 m² known, 5 goals, 1 unreachable); navigating
    on it.``, or why it ended otherwise."""
    took = clock(exploration.get("elapsed"))
    message = exploration.get("message") or ""
    if exploration["state"] == "done":
        then = "navigating on it" if exploration.get("then", "navigation") == "navigation" else "the robot is idle"
        return "explored in {}: saved the map {} ({}, {}, {} unreachable); {}.".format(
            took, exploration.get("map") or exploration["save_as"], _known(exploration),
            _count(exploration.get("goals", 0), "goal"), exploration.get("unreachable", 0), then)
    return "exploration {} after {}{}".format(exploration["state"], took, ": " + message if message else ".")


def clock(seconds):
    """``2:10``, ``1:02:10`` for over an hour: how long it has been going."""
    whole = int(seconds or 0)
    hours, rest = divmod(whole, 3600)
    return "{}:{:02d}:{:02d}".format(hours, *divmod(rest, 60)) if hours else "{}:{:02d}".format(*divmod(rest, 60))


def _known(exploration):
    return "{:.0f} m² known".format(exploration.get("known_m2") or 0.0)


def _minutes(value):
    return "{:g} min".format(value) if value is not None else "30 min"


def _count(n, what):
    return "{} {}{}".format(n, what, "" if n == 1 else "s")


# the server's words, said with robotctl's commands ---------------------------------------------

_HTTP_WORDS = (
    (re.compile(r"POST /mode \{\"mode\": \"mapping\"\}, then POST /maps \{\"name\": \.\.\.\}"),
     "'robotctl map start', then 'robotctl map save NAME'"),
    (re.compile(r"save it \(POST /maps(?:/save)?\)"), "save it ('robotctl map save NAME')"),
    (re.compile(r",? or wait until it is done \(GET /explore\)"), ", or wait until it is done"),
    (re.compile(r"\(POST /stop\)"), "('robotctl stop')"),
    (re.compile(r"POST /stop"), "'robotctl stop'"),
    (re.compile(r"cancel it first \(POST /runs/\d+/cancel\)"), "cancel it first ('robotctl route cancel')"),
)

_ADVICE = {
    "map_exists": "a map named {name} is saved already: 'robotctl map explore {name} --overwrite' replaces it, "
                  "or pick another name",
}


def _robotctl_words(text):
    return rewritten(text, _HTTP_WORDS)


def _in_robotctl_words(name):
    """Around ``POST /explore``: a refusal naming an HTTP call is told with robotctl's commands."""
    return in_robotctl_words(_robotctl_words, _ADVICE, name)


# the parser -------------------------------------------------------------------------------------


def add_action(actions, positive):
    """``map explore`` on the ``map`` parser's actions; ``positive``: robotctl's seconds type."""
    p = actions.add_parser("explore", help="map by itself, come back, save the map as NAME, then navigate on it")
    p.add_argument("name", metavar="NAME")
    p.add_argument("--then", choices=("navigation", "idle"), default="navigation",
                   help="once saved: navigate on the map (default) or idle")
    p.add_argument("--max-minutes", type=_max_minutes, metavar="N",
                   help="stop looking after N minutes, then come back and save (default 30, at most 240)")
    p.add_argument("--overwrite", action="store_true", help="replace a map saved under NAME")
    p.add_argument("--no-return", action="store_true", help="save where it ends, without coming back first")
    p.add_argument("--wait", action="store_true", help="follow it until it ends (exit 0 when the map is saved)")
    p.add_argument("--timeout", dest="wait_timeout", type=positive, metavar="S",
                   help="with --wait: give up waiting after S seconds (exit 12; it goes on)")
    return p


def _max_minutes(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError("{!r} is not a number".format(text))
    if not 0 < value <= MAX_MINUTES:
        raise argparse.ArgumentTypeError("{!r} must be more than 0 and at most {:g}".format(text, MAX_MINUTES))
    return value


def _say(text, stream=None):
    print(text, file=stream or sys.stdout, flush=True)
