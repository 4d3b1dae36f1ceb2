"""The waypoints file format: YAML text <-> ordered ``{name: Waypoint}`` and ``{name: Route}``.

The format is the mapping guide's, with the map's dock and routes (if any) beside the waypoints::

    waypoints:
      kitchen: [1.23, 4.56, 0.79]     # x [m], y [m], yaw [rad] in the map frame
      Ladestation: [0.0, 0.0, 0.0]
    dock: Ladestation                 # the waypoint where the robot charges (none: one named dock, if any)
    routes:
      rounds: {waypoints: [kitchen, dock], loops: 1, dwell: 5.0, on_failure: skip, schedule: ["21:30"]}
    zones:
      Katzenecke: {kind: keepout, polygon: [[2.0, 1.0], [3.0, 1.0], [3.0, 2.0]], enabled: true}

(``{x: .., y: .., yaw: ..}`` per entry loads too; each route is read by
:func:`~flask_move_server.missions.route.make_route`, each zone by
:func:`~flask_move_server.zones.make_zone`). The text is read by
:mod:`~flask_move_server.config.guarded_yaml` (a name given twice, anchors, aliases and deep
nesting refused); whatever makes a file unreadable is a :class:`WaypointFileError` saying the
line and what is wrong, never the file's text. :func:`dump` writes the seed format back, with
numbers PyYAML reads as floats, ``dock:`` only when one is marked, ``routes:`` only when there
are routes and ``zones:`` only when there are zones. Pure: PyYAML only.
"""

import collections
import json
import re

import yaml

from flask_move_server.config import guarded_yaml
from flask_move_server.core.errors import BadRoute, BadWaypoint, BadZone, WaypointFileError, shown
from flask_move_server.missions.route import make_route
from flask_move_server.waypoints import (
    NAME_RULE,
    POSITION_LIMIT,
    YAW_LIMIT,
    Waypoint,
    check_coordinate,
    check_name,
)
from flask_move_server.zones import make_zone

_PLAIN_KEY_RE = re.compile(r"[^\W\d][\w-]*")  # a letter (any script) or '_', then letters, digits, '_', '-'
_BOUNDS = (("x", POSITION_LIMIT), ("y", POSITION_LIMIT), ("yaw", YAW_LIMIT))


class Entries(dict):
    """The raw ``waypoints:`` mapping, knowing the line each name is on (for errors), whether the
    text ended open, right after a bare value (``guarded_yaml.Document.open_end``), and the raw
    ``routes:`` and ``zones:`` mappings beside it (``{}`` when the file has none) and the ``dock:`` name
    (None when none)."""

    def __init__(self, entries, lines, open_end=False, routes=None, dock=None, zones=None):
        super().__init__(entries)
        self.lines = lines
        self.open_end = open_end
        self.routes = routes or {}
        self.dock = dock
        self.zones = zones or {}

    def where(self, name, section="waypoints"):
        line = self.lines.get((section, name))
        return ", line {}".format(line) if line else ""


class Document(collections.namedtuple("Document", "waypoints routes dock zones")):
    """What a waypoints file holds: ordered ``{name: Waypoint}``, ordered ``{name: Route}``, the name
    of the waypoint marked as the dock (None when none is: see :func:`dock_of`) and ordered
    ``{name: Zone}``."""


DOCK = "dock"  # before a dock was marked, the waypoint of this name was the dock: it still is


def dock_of(waypoints, marked):
    """The name of the dock among ``waypoints``: the one ``marked``, else one named ``dock``; None when neither."""
    if marked is not None:
        return marked if marked in waypoints else None
    return DOCK if DOCK in waypoints else None


def parse(text, source="waypoints"):
    """Parse the waypoints file's text into an ordered ``{name: Waypoint}``."""
    return waypoints_of(entries_of(text, source), source)


def parse_document(text, source="waypoints"):
    """Parse the waypoints file's text into a :class:`Document`: its waypoints and its routes.

    A route may name a waypoint the file does not have (a hand edit): whether each exists is the
    store's question, not the format's.
    """
    entries = entries_of(text, source)
    return Document(waypoints_of(entries, source), routes_of(entries, source), marked_dock(entries, source),
                    zones_of(entries, source))


def entries_of(text, source="waypoints"):
    """The raw ``waypoints:`` mapping of the file's text (an :class:`Entries`); None when blank or not given."""
    try:
        data, lines, open_end = guarded_yaml.load(text)
    except guarded_yaml.Unreadable as exc:
        raise WaypointFileError("{} is not valid YAML: {}".format(source, exc))
    if data is None:
        return None
    if not isinstance(data, dict) or set(data) - {"waypoints", "routes", "dock", "zones"}:
        raise WaypointFileError("{} must hold one mapping, 'waypoints: {{name: [x, y, yaw]}}', and 'dock:', "
                                "'routes:' and 'zones:' beside it if the map has them".format(source))
    entries, routes, zones = data.get("waypoints"), data.get("routes"), data.get("zones")
    for section, value in (("routes", routes), ("zones", zones)):
        if entries is None and value is not None:
            raise WaypointFileError("{}, line {}: '{}' needs 'waypoints:' beside it (write 'waypoints: {{}}' "
                                    "for none)".format(source, lines.get((section,), 1), section))
    if entries is None:
        return None
    if not isinstance(entries, dict):
        raise WaypointFileError("{}, line {}: 'waypoints' must map names to [x, y, yaw]".format(
            source, lines.get(("waypoints",), 1)))
    if not isinstance(routes, (dict, type(None))):
        raise WaypointFileError("{}, line {}: 'routes' must map names to routes, 'name: {{waypoints: [names], "
                                "...}}'".format(source, lines.get(("routes",), 1)))
    if not isinstance(zones, (dict, type(None))):
        raise WaypointFileError("{}, line {}: 'zones' must map names to zones, 'name: {{kind: keepout, polygon: "
                                "[[x, y], ...]}}'".format(source, lines.get(("zones",), 1)))
    return Entries(entries, lines, open_end, routes, data.get("dock"), zones)


def marked_dock(entries, source):
    """The waypoint name under ``dock:`` (NFC), None when there is none; WaypointFileError when it is no name.

    A name the file's waypoints do not have is kept: :func:`dock_of` finds no dock then, and the
    store says so, as of a route's missing stop."""
    raw = entries.dock if isinstance(entries, Entries) else None
    if raw is None:
        return None
    try:
        if not isinstance(raw, str):
            raise BadWaypoint("not a name")
        return check_name(raw)
    except BadWaypoint:
        raise WaypointFileError("{}, line {}: 'dock' must name one of the waypoints, 'dock: Ladestation'".format(
            source, entries.lines.get(("dock",), 1)))


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


def routes_of(entries, source):
    """``{name: Route}`` of the raw ``routes:`` beside ``entries``; WaypointFileError saying the bad entry's line."""
    routes = {}
    for name, entry in (entries.routes if isinstance(entries, Entries) else {}).items():
        where = entries.where(name, "routes")
        try:
            route = make_route(name, entry)
        except BadRoute as exc:
            raise WaypointFileError("{}{}: {}".format(source, where, _unquoted(str(exc), name, entry)))
        if route.name in routes:
            raise WaypointFileError("{}{}: a route name appears twice (written with its accents composed "
                                    "differently)".format(source, where))
        routes[route.name] = route
    return routes


def zones_of(entries, source):
    """``{name: Zone}`` of the raw ``zones:`` beside ``entries``; WaypointFileError saying the bad entry's line."""
    zones = {}
    for name, entry in (entries.zones if isinstance(entries, Entries) else {}).items():
        where = entries.where(name, "zones")
        try:
            zone = make_zone(name, entry)
        except BadZone as exc:
            raise WaypointFileError("{}{}: {}".format(source, where, _unquoted(str(exc), name, entry)))
        if zone.name in zones:
            raise WaypointFileError("{}{}: a zone name appears twice (written with its accents composed "
                                    "differently)".format(source, where))
        zones[zone.name] = zone
    return zones


def _unquoted(message, name, entry):
    """BadRoute's ``message`` without the text it quotes from the file: the file may be a link to
    anything, so its errors say where and what, never its words (numbers are no secret and stay)."""
    if not isinstance(entry, dict):  # "a route is an object": nothing of the file quoted
        return message
    texts = [name] + [str(key) for key in entry] + list(entry.values())  # an unknown field is quoted as text
    texts += [item for value in entry.values() if isinstance(value, list) for item in value]
    quoted = {shown(text) for text in texts if isinstance(text, (str, list, dict))}
    for text in sorted(quoted, key=len, reverse=True):  # "ab" before "a"
        message = message.replace(text, "(as written)")
    return message


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


def dump(waypoints, routes=(), dock=None, zones=()):
    """The file text for ``waypoints`` (Waypoints), ``routes`` (Routes) and ``zones`` (Zones), each an
    iterable in file order, and ``dock``, the name of the waypoint marked as the dock (None: none marked).

    The seed format, a ``dock:`` line after it only when one is marked, a ``routes:`` block only
    when there are routes and a ``zones:`` block only when there are zones (a file with none of
    them is written back as it was), one line per route and per zone.
    """
    waypoints, routes, zones = list(waypoints), list(routes), list(zones)
    lines = ["waypoints:" if waypoints else "waypoints: {}"]
    for wp in waypoints:
        coords = ", ".join(_number(v) for v in (wp.x, wp.y, wp.yaw))
        lines.append("  {}: [{}]".format(_key(wp.name), coords))
    if dock is not None:
        lines.append("dock: {}".format(_key(dock)))
    if routes:
        lines.append("routes:")
        lines.extend("  {}: {}".format(_key(route.name), _route_line(route)) for route in routes)
    if zones:
        lines.append("zones:")
        lines.extend("  {}: {}".format(_key(zone.name), _zone_line(zone)) for zone in zones)
    return "\n".join(lines) + "\n"


def _zone_line(zone):
    """One zone as a flow mapping: its kind, its points and whether it is enabled."""
    field = "polygon" if zone.kind == "keepout" else "line"
    points = ", ".join("[{}, {}]".format(_number(x), _number(y)) for x, y in zone.points)
    return "{{kind: {}, {}: [{}], enabled: {}}}".format(zone.kind, field, points, "true" if zone.enabled else "false")


def _route_line(route):
    """One route as a flow mapping: every field, defaults included, so the file says what a run does."""
    return "{{waypoints: [{}], loops: {:d}, dwell: {}, on_failure: {}, schedule: [{}]}}".format(
        ", ".join(_key(name) for name in route.waypoints), route.loops, _number(route.dwell), route.on_failure,
        ", ".join(json.dumps(entry, ensure_ascii=False) for entry in route.schedule))


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
