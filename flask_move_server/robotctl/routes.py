"""``robotctl route list|show|run|pause|resume|skip|cancel`` and ``robotctl runs``: routes from a terminal.

``route run NAME`` starts a run (``POST /runs``); with ``--wait`` it follows ``GET /runs/<id>``
with a live line (``run 7 rounds: loop 1/2, 2 of 3 office, 1.42 m to go``) until the run ends, as
``goto --wait`` follows a goal: exit 0 when it succeeded, 10 when it failed, 11 when it was
canceled or cut short. ``pause``, ``resume``, ``skip`` and ``cancel`` act on the run under way
(the newest running or paused one of ``GET /runs``; ``resume`` also takes an interrupted one), or
on ``--run ID``. The words of the tables and lines are in :mod:`~flask_move_server.robotctl.run_text`.
"""

import re
import sys
import time

from flask_move_server.core.errors import ClientError
from flask_move_server.robotctl.api import ExitStatus, dumps, name_path
from flask_move_server.robotctl.run_text import (
    describe_route,
    ended_line,
    progress,
    progress_key,
    route_table,
    run_title,
    runs_table,
    stop_of,
)
from flask_move_server.robotctl.text import LiveLine, in_robotctl_words, rewritten

POLL_PERIOD = 0.5  # s between GET /runs/<id> while `route run --wait` follows a run

# how a run that ended otherwise than succeeded exits (goto --wait's statuses for the same endings)
_RUN_EXITS = {"failed": ExitStatus.ABORTED, "canceled": ExitStatus.CANCELED, "interrupted": ExitStatus.CANCELED,
              "skipped": ExitStatus.CANCELED}
ACTIVE = ("running", "paused")


def route_path(name):
    """The API path of route ``name`` (percent-encoded in NFC, as waypoint names are)."""
    return name_path("/routes/", name)


def run_path(run_id, action=None):
    return "/runs/{}".format(int(run_id)) + ("/" + action if action else "")


# route list, route show, runs ---------------------------------------------------------------


def cmd_list(client, args):
    routes = client.get("/routes")["routes"]
    if args.json:
        _say(dumps(routes))
    elif not routes:
        _say("no routes on this map yet: one is made with PUT /routes/NAME, or under 'routes:' in the map's "
             "waypoints file.")
    else:
        for line in route_table(routes):
            _say(line)
    return ExitStatus.OK


def cmd_show(client, args):
    with _in_robotctl_words():
        route = client.get(route_path(args.name))
    if args.json:
        _say(dumps(route))
        return ExitStatus.OK
    for line in describe_route(route):
        _say(line)
    return ExitStatus.OK


def cmd_runs(client, args):
    with _in_robotctl_words():
        runs = client.get("/runs")["runs"][:args.last]
    if args.json:
        _say(dumps(runs))
    elif not runs:
        _say("no runs yet: 'robotctl route run NAME' starts one.")
    else:
        for line in runs_table(runs):
            _say(line)
    return ExitStatus.OK


# route run ---------------------------------------------------------------------------------


def cmd_run(client, args):
    """Start a run of route NAME; with --wait, follow it until it ends."""
    with _in_robotctl_words():
        run = client.post("/runs", {"route": args.name})["run"]
    if not args.wait:
        _say("{} started: {}.".format(run_title(run), _going(run)))
        return ExitStatus.OK
    return follow_run(client, run, args.wait_timeout)


def follow_run(client, run, timeout=None):
    """Poll ``GET /runs/<id>`` with a live line until ``run`` ends; its exit status. Ctrl-C pauses it."""
    deadline = None if timeout is None else time.monotonic() + timeout
    live = LiveLine(sys.stderr)
    try:
        while run["state"] in ACTIVE:
            live.show(progress(run), progress_key(run))
            if deadline is not None and time.monotonic() >= deadline:
                live.end()
                raise ClientError("{} is still {} after {:g} s; it goes on ('robotctl route cancel' ends it)."
                                  .format(run_title(run), run["state"], timeout), ExitStatus.TIMEOUT)
            time.sleep(POLL_PERIOD)
            run = client.get(run_path(run["id"]))
    except KeyboardInterrupt:
        live.end()
        _pause_on_interrupt(client, run)
        return ExitStatus.INTERRUPTED
    live.end()
    said = _robotctl_words(ended_line(run))
    if run["state"] == "succeeded":
        _say(said)
        return ExitStatus.OK
    raise ClientError(said, _RUN_EXITS.get(run["state"], ExitStatus.ERROR))


def _pause_on_interrupt(client, run):
    """Ctrl-C while following: the robot stops where it is, the run kept (paused) to resume."""
    if run["state"] == "paused":
        _say("interrupted: {} stays paused ('robotctl route resume' goes on).".format(run_title(run)), sys.stderr)
        return
    try:
        client.post(run_path(run["id"], "pause"))
        _say("interrupted: {} is paused, the robot stopped ('robotctl route resume' goes on).".format(
            run_title(run)), sys.stderr)
    except ClientError:  # it ended meanwhile, or the pause did not get through: stop the robot regardless
        client.post("/stop")
        _say("interrupted: the robot was stopped.", sys.stderr)


# route pause|resume|skip|cancel ------------------------------------------------------------


def cmd_act(client, args):
    """Pause, resume, skip or cancel the run under way (or ``--run ID``)."""
    before = _target_run(client, args.action, args.run_id)
    with _in_robotctl_words():
        run = client.post(run_path(before["id"], args.action))
    _say(_acted(args.action, before, run))
    return ExitStatus.OK


def _target_run(client, action, run_id):
    """The run ``action`` applies to: ``run_id``'s, or the newest active one (resume: or interrupted)."""
    with _in_robotctl_words():
        if run_id is not None:
            return client.get(run_path(run_id))
        runs = client.get("/runs")["runs"]
    states = ACTIVE + (("interrupted",) if action == "resume" else ())
    for run in runs:
        if run["state"] in states:
            return run
    what = "paused or interrupted" if action == "resume" else "under way"
    raise ClientError("no run is {} to {}: 'robotctl runs' lists the last ones, 'robotctl route run NAME' starts "
                      "one.".format(what, action), ExitStatus.NOT_FOUND)


def _acted(action, before, run):
    """The line saying what ``action`` did to the run (``before``: as it was, ``run``: as answered)."""
    title = run_title(run)
    if run["state"] not in ACTIVE:
        return _robotctl_words(ended_line(run))
    if action == "pause":
        return "{} paused at {}: 'robotctl route resume' goes on.".format(title, stop_of(run))
    next_stop = _going(run) if run["state"] == "running" else "paused before {}: 'robotctl route resume' goes " \
        "there".format(stop_of(run))
    if action == "skip":
        return "{}: skipped {}; {}.".format(title, (before.get("current") or {}).get("name"), next_stop)
    return "{} resumed: {}.".format(title, next_stop)


def _going(run):
    return "going to {}".format(stop_of(run))


# The server's advice names HTTP calls; robotctl says its own commands instead. (What a run's message
# records, "Canceled (POST /runs/7/cancel).", stays: any client may have sent it.)
_HTTP_WORDS = (
    (re.compile(r"cancel it first \(POST /runs/\d+/cancel\)"), "cancel it first ('robotctl route cancel')"),
    (re.compile(r"GET /runs lists them"), "'robotctl runs' lists them"),
    (re.compile(r"GET /routes lists them"), "'robotctl route list' lists them"),
    (re.compile(r"\(POST /mode \{.*?\}; (robotctl map use NAME)\)"), r"('\1')"),
)


def _robotctl_words(text):
    return rewritten(text, _HTTP_WORDS)


def _in_robotctl_words():
    """Around a request: a refusal naming an HTTP call is told with robotctl's command."""
    return in_robotctl_words(_robotctl_words)


# the parser ---------------------------------------------------------------------------------


def add_parsers(sub, positive, whole):
    """``robotctl route …`` and ``robotctl runs`` on robotctl's subcommand parser ``sub``."""
    p = sub.add_parser("route", help="routes: list, show NAME, run NAME [--wait]; pause, resume, skip, cancel a run")
    p.set_defaults(run=cmd_route, action="list", json=False)
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    listing = actions.add_parser("list", help="the active map's routes")
    listing.add_argument("--json", action="store_true", help="the raw JSON of GET /routes")
    show = actions.add_parser("show", help="route NAME in full")
    show.add_argument("name", metavar="NAME")
    show.add_argument("--json", action="store_true", help="the raw JSON of GET /routes/NAME")
    run = actions.add_parser("run", help="start a run of route NAME")
    run.add_argument("name", metavar="NAME")
    run.add_argument("--wait", action="store_true", help="follow the run until it ends (exit 0 when it succeeded)")
    run.add_argument("--timeout", dest="wait_timeout", type=positive, metavar="S",
                     help="with --wait: give up waiting after S seconds (exit 12; the run goes on)")
    for action, says in (("pause", "stop the robot where it is, keeping the run"),
                         ("resume", "go on with a paused or interrupted run"),
                         ("skip", "leave the current stop out and go on to the next"),
                         ("cancel", "end the run")):
        act = actions.add_parser(action, help=says + " (the run under way, or --run ID)")
        act.add_argument("--run", dest="run_id", type=whole, metavar="ID",
                         help="the run's id ('robotctl runs' lists them)")
    p = sub.add_parser("runs", help="the last runs of routes, newest first")
    p.add_argument("--last", type=whole, default=10, metavar="N", help="how many (default %(default)s; the robot "
                                                                       "keeps 50)")
    p.add_argument("--json", action="store_true", help="the raw JSON of GET /runs")
    p.set_defaults(run=cmd_runs)


ACTIONS = {"list": cmd_list, "show": cmd_show, "run": cmd_run}


def cmd_route(client, args):
    """Dispatch ``robotctl route ACTION``."""
    return ACTIONS.get(args.action or "list", cmd_act)(client, args)


def _say(text, stream=None):
    print(text, file=stream or sys.stdout, flush=True)
