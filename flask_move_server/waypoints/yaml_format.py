"""The waypoints file format: YAML text <-> ordered ``{name: Waypoint}``.

The format is the mapping guide's::

    waypoints:
      kitchen: [1.23, 4.56, 0.79]     # x [m], y [m], yaw [rad] in the map frame

(``{x: .., y: .., yaw: ..}`` per entry loads too). The text is read by
:mod:`~flask_move_server.waypoints.safe_yaml` (a name given twice, anchors, aliases and deep
nesting refused); whatever makes a file unreadable is a :class:`WaypointFileError` saying the
line and what is wrong, never the file's text. :func:`dump` writes the seed format back, with
numbers PyYAML reads as floats. Pure: PyYAML only.
"""

import json
import re

import yaml

from flask_move_server.errors import BadWaypoint, WaypointFileError
from flask_move_server.waypoints import (
    NAME_RULE,
    POSITION_LIMIT,
    YAW_LIMIT,
    Waypoint,
    check_coordinate,
    check_name,
    safe_yaml,
)

_PLAIN_KEY_RE = re.compile(r"[^\W\d][\w-]*")  # a letter (any script) or '_', then letters, digits, '_', '-'
_BOUNDS = (("x", POSITION_LIMIT), ("y", POSITION_LIMIT), ("yaw", YAW_LIMIT))


class Entries(dict):
    """The raw ``waypoints:`` mapping, knowing the line each name is on (for errors) and whether the
    text ended open, right after a bare value (``safe_yaml.Document.open_end``)."""

    def __init__(self, entries, lines, open_end=False):
        super().__init__(entries)
        self.lines = lines
        self.open_end = open_end

    def where(self, name):
        line = self.lines.get(("waypoints", name))
        return ", line {}".format(line) if line else ""


def parse(text, source="waypoints"):
    """Parse the waypoints file's text into an ordered ``{name: Waypoint}``."""
    return waypoints_of(entries_of(text, source), source)


def entries_of(text, source="waypoints"):
    """The raw ``waypoints:`` mapping of the file's text (an :class:`Entries`); None when blank or not given."""
    try:
        data, lines, open_end = safe_yaml.load(text)
    except safe_yaml.Unreadable as exc:
        raise WaypointFileError("{} is not valid YAML: {}".format(source, exc))
    if data is None:
        return None
    if not isinstance(data, dict) or set(data) - {"waypoints"}:
        raise WaypointFileError("{} must hold one mapping, 'waypoints: {{name: [x, y, yaw]}}'".format(source))
    entries = data.get("waypoints")
    if entries is None:
        return None
    if not isinstance(entries, dict):
        raise WaypointFileError("{}, line {}: 'waypoints' must map names to [x, y, yaw]".format(
            source, lines.get(("waypoints",), 1)))
    return Entries(entries, lines, open_end)


def waypoints_of(entries, source):
    """``{name: Waypoint}`` of a raw ``waypoints:`` mapping; WaypointFileError saying the bad entry's line."""
    waypoints = {}
    for name, entry in (entries or {}).items():
        where = entries.where(name) if isinstance(entries, Entries) else ""
        try:
            waypoint = _entry(name, entry)
        except BadWaypoint as exc:
            raise WaypointFileError("{}{}: {}".format(source, where, exc))
        if waypoint.name in waypoints:  # "Küche" typed twice, composed two ways: one name in NFC
            raise WaypointFileError("{}{}: a name appears twice (written with its accents composed differently)"
                                    .format(source, where))
        waypoints[waypoint.name] = waypoint
    return waypoints


def _entry(name, entry):
    """The Waypoint of one entry; BadWaypoint saying what is wrong without quoting it (the file's text)."""
    try:
        name = check_name(name)
    except BadWaypoint:
        raise BadWaypoint("Invalid waypoint name: use {}.".format(NAME_RULE))
    if isinstance(entry, dict) and set(entry) == {"x", "y", "yaw"}:
        entry = [entry["x"], entry["y"], entry["yaw"]]
    if not isinstance(entry, list) or len(entry) != 3:
        raise BadWaypoint("expected [x, y, yaw] or {x: .., y: .., yaw: ..}")
    return Waypoint(name, *(_coordinate(label, limit, value) for (label, limit), value in zip(_BOUNDS, entry)))


def _coordinate(label, limit, value):
    try:
        return check_coordinate(label, value, limit)
    except BadWaypoint:
        raise BadWaypoint("{} must be a finite number between {:.0f} and {:.0f}".format(label, -limit, limit))


def dump(waypoints):
    """The file text for ``waypoints`` (an iterable of Waypoint), in the seed format."""
    lines = ["waypoints:" if waypoints else "waypoints: {}"]
    for wp in waypoints:
        coords = ", ".join(_number(v) for v in (wp.x, wp.y, wp.yaw))
        lines.append("  {}: [{}]".format(_key(wp.name), coords))
    return "\n".join(lines) + "\n"


def _key(name):
    if _PLAIN_KEY_RE.fullmatch(name) and yaml.safe_load(name) == name:
        return name
    return json.dumps(name, ensure_ascii=False)  # a JSON string is a valid YAML double-quoted scalar


def _number(value):
    text = repr(float(value))
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:  # YAML 1.1 (PyYAML) reads 1e-05 as text, 1.0e-05 as a float
        text = "{}.0e{}".format(mantissa, exponent)
    return text
