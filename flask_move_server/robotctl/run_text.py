"""What ``robotctl route`` and ``robotctl runs`` print: the routes table, a route in full, the runs
table, a run's live progress line and its last word. Pure text from the server's JSON (ROUTE, RUN).
"""

from flask_move_server.robotctl.text import columns, padded

MESSAGE_COLUMNS = 60  # a run's message in the runs table is cut to this many columns


# routes ------------------------------------------------------------------------------------


def route_table(routes):
    """Aligned rows: name, stops, loops, dwell, on failure, schedule."""
    header = ("NAME", "STOPS", "LOOPS", "DWELL", "ON FAILURE", "SCHEDULE")
    rows = [(r["name"], str(len(r["waypoints"])), _loops(r["loops"]), _seconds(r["dwell"]), r["on_failure"],
             ", ".join(r.get("schedule") or []) or "-") for r in routes]
    return _aligned(header, rows, right=(1, 2, 3))


def describe_route(route):
    """The lines of ``robotctl route show NAME``."""
    stops = route["waypoints"]
    return [
        "route:      {}".format(route["name"]),
        "stops:      {} ({})".format(" -> ".join(stops), _count(len(stops), "stop")),
        "loops:      {}".format(_loops(route["loops"]) if route["loops"] else "until stopped (0)"),
        "dwell:      {} at each stop".format(_seconds(route["dwell"])),
        "on failure: {}".format(_POLICY.get(route["on_failure"], route["on_failure"])),
        "schedule:   {}".format(", ".join(route.get("schedule") or []) + " (the robot's local time)"
                                if route.get("schedule") else "none (runs when started)"),
    ]


_POLICY = {"stop": "stop (the run ends failed at a stop it cannot reach)",
           "skip": "skip (a stop it cannot reach is noted as missed, the run goes on)"}


# runs ----------------------------------------------------------------------------------------


def runs_table(runs):
    """Aligned rows, one per run as given (newest first): id, route, trigger, state, visited, missed,
    started, the message cut to :data:`MESSAGE_COLUMNS`."""
    header = ("ID", "ROUTE", "TRIGGER", "STATE", "VISITED", "MISSED", "STARTED", "MESSAGE")
    rows = [(str(r["id"]), r["route"] or "(unnamed)", r["trigger"], r["state"], str(len(r["visited"])),
             str(len(r["missed"])), _when(r["started"]), _cut(r.get("message") or "", MESSAGE_COLUMNS))
            for r in runs]
    return _aligned(header, rows, right=(0, 4, 5))


def run_title(run):
    """``run 7 rounds`` (``run 7`` for an unnamed route)."""
    return "run {}".format(run["id"]) + (" " + run["route"] if run.get("route") else "")


def stop_of(run):
    """``office, 2 of 3`` (``, loop 1/2`` added when the route loops): where the run is or goes."""
    current = (run.get("current") or {}).get("name") or "?"
    return "{}, {} of {}{}".format(current, run["index"] + 1, len(run["waypoints"]), _loop_of(run, ", "))


def progress(run):
    """The live line while a run is under way: ``run 7 rounds: loop 1/2, 2 of 3 office, 1.42 m to go``."""
    current = run.get("current") or {}
    where = "{}{} of {} {}".format(_loop_of(run, "", ", "), run["index"] + 1, len(run["waypoints"]),
                                   current.get("name") or "?")
    if run["state"] == "paused":
        doing = "paused ('robotctl route resume' goes on)"
    elif _arrived(run):
        doing = "arrived, waiting {}".format(_seconds(run["dwell"]))
    elif current.get("distance_remaining") is not None:
        doing = "{:.2f} m to go".format(current["distance_remaining"])
    else:
        doing = "on the way"
    return "{}: {}, {}".format(run_title(run), where, doing)


def progress_key(run):
    """What makes a new line of progress when stderr is not a terminal: each stop, each state."""
    return run["state"], run["loop"], run["index"], _arrived(run)


def ended_line(run):
    """The last word on a run that ended: ``run 7 rounds succeeded: Visited every waypoint (2 loops).``"""
    message = run.get("message") or ""
    state = run["state"]
    if message.lower().startswith(state):  # "Canceled (POST /runs/7/cancel)." says the state already
        return "{} {}".format(run_title(run), message[0].lower() + message[1:])
    return "{} {}{}".format(run_title(run), state, ": " + message if message else ".")


def _arrived(run):
    """The run waits at its current stop (dwell): the last visit is of this stop in this loop."""
    last = (run.get("visited") or [None])[-1]
    current = (run.get("current") or {}).get("name")
    return bool(last) and run["state"] == "running" and last["name"] == current and last["loop"] == run["loop"]


# pieces --------------------------------------------------------------------------------------


def _loop_of(run, before="", after=""):
    """``loop 1/2`` (``loop 3, until stopped`` for an endless route); nothing for a route of one loop."""
    if run["loops"] == 1:
        return ""
    total = "/{}".format(run["loops"]) if run["loops"] else " (until stopped)"
    return "{}loop {}{}{}".format(before, run["loop"], total, after)


def _loops(loops):
    return str(loops) if loops else "until stopped"


def _seconds(value):
    return "{:g} s".format(value)


def _count(n, what):
    return "{} {}{}".format(n, what, "" if n == 1 else "s")


def _when(iso):
    """``2024-05-01 09:00:03`` of the robot's ISO time (its offset left out: the robot's local time)."""
    return (iso or "?")[:19].replace("T", " ")


def _cut(text, width):
    """``text`` in at most ``width`` columns: cut at a word's end where one is near, with ``...``."""
    if columns(text) <= width:
        return text
    while columns(text) > width - 3:
        text = text[:-1]
    words = text.rsplit(" ", 1)[0]
    return (words if columns(words) > width // 2 else text).rstrip(" ,.:;") + "..."


def _aligned(header, rows, right=()):
    """``header`` and ``rows`` in columns two spaces apart; the columns ``right`` right-aligned."""
    widths = [max(columns(row[i]) for row in [header] + rows) for i in range(len(header))]
    lines = []
    for row in [header] + rows:
        cells = [(" " * (w - columns(v)) + v) if i in right else padded(v, w)
                 for i, (v, w) in enumerate(zip(row, widths))]
        lines.append("  ".join(cells).rstrip())
    return lines
