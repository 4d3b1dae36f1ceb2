"""A route: the waypoints to visit in order, how often, how long to wait at each, what a failure does.

Routes live in the active map's waypoints file under ``routes:`` (``waypoints/yaml_format.py``)
and are what ``PUT /routes/<name>`` and ``POST /runs`` take. Every field is checked here once,
for the API and the file alike; an error names the field. Whether each waypoint exists is the
store's question (it knows the map's waypoints). Pure: no rospy, no Flask, no YAML.
"""

import math
from dataclasses import dataclass, field

from flask_move_server.core import names
from flask_move_server.core.errors import BadRoute, shown
from flask_move_server.missions import schedule

FIELDS = ("waypoints", "loops", "dwell", "on_failure", "schedule")
ON_FAILURE = ("stop", "skip")
MAX_WAYPOINTS = 200  # stops in one route: a long patrol, not a way to make the robot do unbounded work
MAX_LOOPS = 10000  # 0 is "until stopped"
MAX_DWELL = 3600.0  # seconds at each waypoint
MAX_SCHEDULE = 20  # timetable entries per route


@dataclass(frozen=True)
class Route:
    """Waypoint names in order; ``loops`` 0 = until stopped; ``dwell`` s at each; ``on_failure`` stop | skip."""

    name: object  # str, or None for a run's unnamed route
    waypoints: tuple
    loops: int = 1
    dwell: float = 0.0
    on_failure: str = "stop"
    schedule: tuple = field(default=())

    def as_dict(self):
        return {"name": self.name, "waypoints": list(self.waypoints), "loops": self.loops, "dwell": self.dwell,
                "on_failure": self.on_failure, "schedule": list(self.schedule)}

    def fields(self):
        """The route without its name, as the waypoints file keeps it (defaults included)."""
        data = self.as_dict()
        del data["name"]
        return data

    def renamed_waypoint(self, old, new):
        """This route with waypoint ``old`` called ``new`` wherever it appears."""
        return Route(self.name, tuple(new if w == old else w for w in self.waypoints), self.loops, self.dwell,
                     self.on_failure, self.schedule)


def check_route_name(name):
    """``name`` in NFC when it is a valid route name, else BadRoute saying what is allowed."""
    return names.checked(name, "route name", BadRoute)


def make_route(name, data, scheduled=True):
    """A checked :class:`Route` from a mapping of its fields (a request body, a file's entry).

    ``scheduled``: whether ``schedule`` may be given (a run's unnamed route has no timetable).
    BadRoute names the field that is wrong and what it must be.
    """
    if not isinstance(data, dict):
        raise BadRoute("A route is an object: {\"waypoints\": [names], \"loops\": 1, \"dwell\": 0, "
                       "\"on_failure\": \"stop\", \"schedule\": []}.")
    allowed = FIELDS if scheduled else FIELDS[:-1]
    unknown = [k for k in data if k not in allowed]
    if unknown:
        raise BadRoute("Unknown field {} in a route; its fields are {}.".format(shown(str(unknown[0])),
                                                                              ", ".join(allowed)))
    return Route(
        check_route_name(name) if name is not None else None,
        _waypoints(data.get("waypoints")),
        _whole(data.get("loops", 1), "loops", MAX_LOOPS, "0 repeats until stopped"),
        _seconds(data.get("dwell", 0.0)),
        _policy(data.get("on_failure", "stop")),
        _schedule(data.get("schedule", [])),
    )


def _waypoints(value):
    if not isinstance(value, list) or not value:
        raise BadRoute("Field 'waypoints' must be a list of one or more waypoint names, in the order to visit them.")
    if len(value) > MAX_WAYPOINTS:
        raise BadRoute("Field 'waypoints' holds {} names; a route has at most {}.".format(len(value), MAX_WAYPOINTS))
    checked = []
    for i, name in enumerate(value):
        if not isinstance(name, str):
            raise BadRoute("Field 'waypoints', entry {}: a waypoint name (text), got {}.".format(i + 1, shown(name)))
        checked.append(names.checked(name, "waypoint name in 'waypoints' (entry {})".format(i + 1), BadRoute))
    return tuple(checked)


def _whole(value, label, limit, note):
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= limit:
        raise BadRoute("Field '{}' must be a whole number from 0 to {} ({}), got {}.".format(
            label, limit, note, shown(value)))
    return value


def _seconds(value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not 0 <= value <= MAX_DWELL:
        raise BadRoute("Field 'dwell' must be seconds to wait at each waypoint, from 0 to {:.0f}, got {}.".format(
            MAX_DWELL, shown(value)))
    return float(value)


def _policy(value):
    if value not in ON_FAILURE:
        raise BadRoute("Field 'on_failure' must be \"stop\" (end the run at a waypoint it cannot reach) or "
                       "\"skip\" (note it as missed and go on), got {}.".format(shown(value)))
    return value


def _schedule(value):
    if not isinstance(value, list):
        raise BadRoute("Field 'schedule' must be a list of times, e.g. [\"21:30\", \"mon-fri 09:00\"].")
    if len(value) > MAX_SCHEDULE:
        raise BadRoute("Field 'schedule' holds {} times; a route has at most {}.".format(len(value), MAX_SCHEDULE))
    return tuple(schedule.parse(entry).text for entry in value)
