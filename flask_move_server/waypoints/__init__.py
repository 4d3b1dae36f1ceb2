"""Named waypoints: the model, the naming rule and the bounds every pose is checked against.

A waypoint is a named pose in the map frame (x, y in metres, yaw in radians). Names and
coordinates are validated here once, for the HTTP API, the file and the recorder alike;
:mod:`~flask_move_server.waypoints.yaml_format` reads and writes the YAML file,
:mod:`~flask_move_server.waypoints.store` keeps it. Pure: no rospy, no Flask, no YAML.
"""

import difflib
import math
from dataclasses import dataclass

from flask_move_server.core import names
from flask_move_server.core.errors import BadWaypoint, shown

NAME_RULE = names.RULE  # one rule for every name a person gives: see flask_move_server.core.names
# Bounds far beyond any building, but small enough that every formula on a pose stays finite and
# exact (1e308 overflows distances): x, y in metres, yaw in radians.
POSITION_LIMIT = 1e6
YAW_LIMIT = 1e3


@dataclass(frozen=True)
class Waypoint:
    """A named pose in the map frame: x, y in metres, yaw in radians."""

    name: str
    x: float
    y: float
    yaw: float

    def as_dict(self):
        return {"name": self.name, "x": self.x, "y": self.y, "yaw": self.yaw}


def check_name(name):
    """``name`` in NFC (the form it is kept and compared in) if it is a valid waypoint name, else BadWaypoint."""
    return names.checked(name, "waypoint name", BadWaypoint)


def check_coordinate(label, value, limit=POSITION_LIMIT):
    """Return ``value`` as a float if it is a finite number within ±``limit``, else raise BadWaypoint."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadWaypoint("{} must be a number, got {}.".format(label, shown(value)))
    try:
        value = float(value)
    except OverflowError:  # an int too large for a float
        value = math.inf if value > 0 else -math.inf
    if not math.isfinite(value):
        raise BadWaypoint("{} must be a finite number, got {}.".format(label, value))
    if abs(value) > limit:
        raise BadWaypoint("{} must be between {:.0f} and {:.0f}, got {:g}.".format(label, -limit, limit, value))
    return value


def make_waypoint(name, x, y, yaw):
    """Build a validated :class:`Waypoint` (its name in NFC)."""
    return Waypoint(
        check_name(name),
        check_coordinate("x", x),
        check_coordinate("y", y),
        check_coordinate("yaw", yaw, YAW_LIMIT),
    )


def suggest(name, names_known, n=3):
    """Known names close to ``name``, best first (for 'did you mean'): one differing only in case first."""
    key = names.same_name_key(name) if isinstance(name, str) else None
    exact = [k for k in names_known if names.same_name_key(k) == key][:1]
    close = difflib.get_close_matches(str(name), list(names_known), n=n, cutoff=0.6)
    return list(dict.fromkeys(exact + close))[:n]
