"""Named waypoints: the model, the naming rule and the bounds every pose is checked against.

A waypoint is a named pose in the map frame (x, y in metres, yaw in radians). Names and
coordinates are validated here once, for the HTTP API, the file and the recorder alike;
:mod:`~flask_move_server.waypoints.yaml_format` reads and writes the YAML file,
:mod:`~flask_move_server.waypoints.store` keeps it. Pure: no rospy, no Flask, no YAML.
"""

import difflib
import math
import re
from dataclasses import dataclass

from flask_move_server.errors import BadWaypoint, shown

NAME_RULE = ("1 to 64 letters, digits, '_', '-', '.' or spaces, not starting or ending with a space, "
             "without '..' and not '.' alone")
# Bounds far beyond any building, but small enough that every formula on a pose stays finite and
# exact (1e308 overflows distances): x, y in metres, yaw in radians.
POSITION_LIMIT = 1e6
YAW_LIMIT = 1e3
_NAME_RE = re.compile(r"[A-Za-z0-9_. -]{1,64}")


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
    """Return ``name`` if it is a valid waypoint name, else raise BadWaypoint."""
    if not isinstance(name, str):
        raise BadWaypoint("A waypoint name must be text, got {}.".format(shown(name)))
    # "." and ".." are path segments: clients drop them from a URL, so they could not be deleted.
    if not _NAME_RE.fullmatch(name) or name != name.strip(" ") or ".." in name or name == ".":
        raise BadWaypoint("Invalid waypoint name {}: use {}.".format(shown(name), NAME_RULE))
    return name


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
    """Build a validated :class:`Waypoint`."""
    check_name(name)
    return Waypoint(
        name,
        check_coordinate("x", x),
        check_coordinate("y", y),
        check_coordinate("yaw", yaw, YAW_LIMIT),
    )


def suggest(name, names, n=3):
    """Known names close to ``name``, best first (for 'did you mean')."""
    folded = {k.lower(): k for k in names}
    exact = [folded[name.lower()]] if isinstance(name, str) and name.lower() in folded else []
    close = difflib.get_close_matches(str(name), list(names), n=n, cutoff=0.6)
    return list(dict.fromkeys(exact + close))[:n]
