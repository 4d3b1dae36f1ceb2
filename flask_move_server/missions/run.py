"""A run: one route being driven (or driven once), as data: where it is, what it visited, what it missed.

A run is what ``POST /runs`` starts and ``GET /runs/<id>`` shows; the executor changes it, the
history keeps it across restarts. Its states::

    running ──▶ paused ──▶ running          (pause / resume)
    running ──▶ stuck ──▶ running           (the robot got stuck on the way and could not get itself
                                             out: the stop is not missed; resume goes there again)
    running | paused | stuck ──▶ succeeded | failed | canceled
    running | paused ──▶ interrupted ──▶ running   (the server stopped under it; resume)
    skipped                                   (a schedule found the robot busy: never ran)

Pure: no rospy, no Flask.
"""

import datetime
from dataclasses import dataclass, field

from flask_move_server.missions.route import Route, check_route_name, make_route

RUNNING, PAUSED, STUCK, SUCCEEDED, FAILED, CANCELED, INTERRUPTED, SKIPPED = (
    "running", "paused", "stuck", "succeeded", "failed", "canceled", "interrupted", "skipped")
STATES = (RUNNING, PAUSED, STUCK, SUCCEEDED, FAILED, CANCELED, INTERRUPTED, SKIPPED)
ACTIVE = (RUNNING, PAUSED, STUCK)  # a run the robot is doing: at most one at a time
WAITING = (PAUSED, STUCK)  # a run waiting for a resume
TRIGGERS = ("api", "schedule", "mqtt", "vda5050")
KEPT_STOPS = 100  # visited / missed entries kept per run (a patrol "until stopped" must not grow for ever)


def now_text():
    """The robot's local time now, ISO 8601 with its offset, to the second."""
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


@dataclass
class Run:
    """One run of a route. ``loop`` counts from 1; ``index`` is the waypoint being gone to (or dwelt at)."""

    id: int
    route: object  # the route's name, or None for an unnamed one
    waypoints: list
    loops: int
    dwell: float
    on_failure: str
    trigger: str
    state: str = RUNNING
    loop: int = 1
    index: int = 0
    visited: list = field(default_factory=list)
    missed: list = field(default_factory=list)
    started: str = field(default_factory=now_text)
    ended: object = None
    message: object = None
    # A fleet manager's order (VDA 5050): not kept across restarts, never shown by the API.
    poses: object = field(default=None, repr=False, compare=False)  # per stop: Pose2D, or None (a waypoint)
    open_end: bool = field(default=False, repr=False, compare=False)  # more stops may come: wait at the last
    holding: bool = field(default=False, repr=False, compare=False)  # waiting at the last stop for more
    watch: object = field(default=None, repr=False, compare=False)  # watch(what, value) as it goes
    trimmed: int = field(default=0, repr=False, compare=False)  # stops passed and forgotten (extend)
    charges: int = field(default=0, repr=False, compare=False)  # times it was paused to go home and charge

    @classmethod
    def of_route(cls, run_id, route, trigger):
        return cls(run_id, route.name, list(route.waypoints), route.loops, route.dwell, route.on_failure, trigger)

    def pose_of(self, index):
        """The pose the stop at ``index`` names itself, or None (it names a waypoint)."""
        return self.poses[index] if self.poses is not None else None

    def extend(self, stops, poses, open_end):
        """More stops at the end (a fleet manager released more of its order); ``open_end``: still more to come.
        The stops already passed are forgotten (``trimmed`` counts them), so an order updated for days
        does not grow its run without end."""
        passed = self.index
        del self.waypoints[:passed]
        self.waypoints.extend(stops)
        if self.poses is not None:
            del self.poses[:passed]
            self.poses.extend(poses)
        self.index, self.trimmed = 0, self.trimmed + passed
        self.open_end = open_end

    @property
    def active(self):
        return self.state in ACTIVE

    @property
    def target(self):
        """The waypoint name the run is at or on its way to; None once ended."""
        return self.waypoints[self.index] if self.active or self.state == INTERRUPTED else None

    def visit(self):
        """The current waypoint was reached."""
        self._note(self.visited, {"name": self.target, "loop": self.loop, "at": now_text()})

    def miss(self, reason):
        """The current waypoint was not reached, for ``reason`` (move_base's, or who skipped it)."""
        self._note(self.missed, {"name": self.target, "loop": self.loop, "reason": reason})

    def _note(self, entries, entry):
        entries.append(entry)
        del entries[:-KEPT_STOPS]

    def advance(self):
        """On to the next waypoint (the next loop after the last); False when the run is through."""
        if self.index + 1 < len(self.waypoints):
            self.index += 1
            return True
        if self.loops and self.loop >= self.loops:
            return False
        self.loop, self.index = self.loop + 1, 0
        return True

    def end(self, state, message=None):
        self.state, self.message, self.ended = state, message, now_text()

    def as_dict(self, distance_remaining=None):
        """What the API shows; ``distance_remaining`` to the current waypoint, when known."""
        target = self.target
        current = {"name": target, "distance_remaining": distance_remaining} if target is not None else None
        return {"id": self.id, "route": self.route, "waypoints": list(self.waypoints), "loops": self.loops,
                "dwell": self.dwell, "on_failure": self.on_failure, "trigger": self.trigger, "state": self.state,
                "loop": self.loop, "index": self.index, "current": current, "visited": list(self.visited),
                "missed": list(self.missed), "started": self.started, "ended": self.ended, "message": self.message}

    @classmethod
    def from_dict(cls, data):
        """A run as the history file kept it, every value checked as the API checks it; ValueError (or
        TypeError, KeyError) saying what is wrong when it is not one (a hand edit, a file of another version)."""
        if not isinstance(data, dict):
            raise ValueError("not an object: {}".format(type(data).__name__))
        trigger = _one_of(data["trigger"], TRIGGERS, "trigger")
        route, waypoints = _route_of(data, trigger)
        run = cls(_whole(data["id"], "id", 1, 2 ** 53), route.name, list(waypoints), route.loops, route.dwell,
                  route.on_failure, trigger, _one_of(data["state"], STATES, "state"),
                  _whole(data["loop"], "loop", 1, 2 ** 53), _whole(data["index"], "index", 0, len(waypoints) - 1),
                  _notes(data["visited"], "visited"), _notes(data["missed"], "missed"),
                  _text(data["started"], "started", MAX_TIME_TEXT), _text(data.get("ended"), "ended", MAX_TIME_TEXT,
                                                                        none=True),
                  _text(data.get("message"), "message", MAX_NOTE_TEXT, none=True))
        return run


MAX_TIME_TEXT = 40  # characters of a kept time ("2026-12-01T22:33:28+00:00")
MAX_NOTE_TEXT = 2000  # characters of a kept message or a note's value (move_base's reasons are shorter)
MAX_FOREIGN_NAME = 200  # characters of a fleet manager's order id or node id (the VDA 5050 factsheet's)
MAX_FOREIGN_STOPS = 2000  # stops of a fleet manager's run: its orders are extended, the passed ones forgotten


def _route_of(data, trigger):
    """(the checked Route of a kept run, its stops): the API's checks; a fleet manager's names are its own ids."""
    fields = {k: data[k] for k in ("loops", "dwell", "on_failure")}
    if trigger != "vda5050":
        route = make_route(None, dict(fields, waypoints=data["waypoints"]), scheduled=False)
        name = data["route"]
        return Route(None if name is None else check_route_name(name), route.waypoints, route.loops, route.dwell,
                     route.on_failure), route.waypoints
    stops = data["waypoints"]
    if not isinstance(stops, list) or not 1 <= len(stops) <= MAX_FOREIGN_STOPS:
        raise ValueError("'waypoints' must be a list of 1 to {} node ids".format(MAX_FOREIGN_STOPS))
    stops = [_text(stop, "a node id", MAX_FOREIGN_NAME) for stop in stops]
    route = make_route(None, dict(fields, waypoints=["stop"]), scheduled=False)
    return Route(_text(data["route"], "route", MAX_FOREIGN_NAME + 20), (), route.loops, route.dwell,
                 route.on_failure), stops


def _whole(value, label, low, high):
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ValueError("'{}' must be a whole number from {} to {}, got {!r}".format(label, low, high, value))
    return value


def _one_of(value, allowed, label):
    if value not in allowed:
        raise ValueError("'{}' must be one of {}, got {!r}".format(label, ", ".join(allowed), value))
    return value


def _text(value, label, longest, none=False):
    if value is None and none:
        return None
    if not isinstance(value, str) or len(value) > longest:
        raise ValueError("'{}' must be text of at most {} characters".format(label, longest))
    return value


def _notes(value, label):
    """A kept run's visited or missed stops: the newest :data:`KEPT_STOPS` objects of short plain values."""
    if not isinstance(value, list):
        raise ValueError("'{}' must be a list".format(label))
    notes = value[-KEPT_STOPS:]
    for note in notes:
        if not isinstance(note, dict) or len(note) > 8 or not all(
                isinstance(v, (str, int, float, type(None))) and not isinstance(v, bool) and
                (not isinstance(v, str) or len(v) <= MAX_NOTE_TEXT) for v in note.values()):
            raise ValueError("'{}' holds an entry that is not a stop's note".format(label))
    return list(notes)
