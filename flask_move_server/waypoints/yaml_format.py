"""The waypoints file format: YAML text <-> ordered ``{name: Waypoint}``.

The format is the mapping guide's::

    waypoints:
      kitchen: [1.23, 4.56, 0.79]     # x [m], y [m], yaw [rad] in the map frame

(``{x: .., y: .., yaw: ..}`` per entry loads too). A name given twice is an error, and so are
anchors and aliases (a few hundred bytes could expand to megabytes) and nesting deeper than
:data:`MAX_DEPTH` (PyYAML composes recursively: 5,000 brackets were a RecursionError). Whatever
the parser raises on a hand-edited file is a :class:`WaypointFileError`, never another exception.
:func:`dump` writes the seed format back, with numbers PyYAML reads as floats. Pure: PyYAML only.
"""

import collections.abc
import json
import re

import yaml

from flask_move_server.errors import BadWaypoint, WaypointFileError
from flask_move_server.waypoints import make_waypoint

_PLAIN_KEY_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
MAX_QUOTED = 300  # characters of the file an error message may quote
MAX_DEPTH = 16  # levels of nesting: a waypoints file needs 4 (file, waypoints, entry, coordinate)


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a name given twice, any anchor or alias, and deep nesting.

    Aliases let a few hundred bytes expand to megabytes (in memory, in error
    messages, in /status); a waypoints file has no use for them. Nesting is
    refused before PyYAML's recursion could reach Python's limit.
    """

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise yaml.composer.ComposerError(
                None, None, "anchors and aliases ('&', '*') are not allowed in a waypoints file", event.start_mark
            )
        if self._depth >= MAX_DEPTH:
            raise yaml.composer.ComposerError(
                None, None, "nested more than {} levels deep".format(MAX_DEPTH), event.start_mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_object(self, node, deep=False):
        try:
            return super().construct_object(node, deep)
        except (ArithmeticError, LookupError, TypeError, ValueError):  # a date like 2001-13-45, say
            raise yaml.constructor.ConstructorError(None, None, "a value that cannot be read", node.start_mark)


def _construct_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if not isinstance(key, collections.abc.Hashable):
            raise yaml.constructor.ConstructorError(None, None, "a key must be a plain name", key_node.start_mark)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, "{!r} appears twice".format(key), key_node.start_mark
            )
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _shorten(text, limit=MAX_QUOTED):
    """``text`` cut to ``limit`` characters: an error quoting the file stays readable."""
    return text if len(text) <= limit else text[: limit - 1] + "\u2026"


def parse(text, source="waypoints"):
    """Parse the waypoints file's text into an ordered ``{name: Waypoint}``."""
    return waypoints_of(entries_of(text, source), source)


def entries_of(text, source="waypoints"):
    """The raw ``waypoints:`` mapping of the file's text; None when blank or not given."""
    data = _load_yaml(text, source)
    if data is None:
        return None
    if not isinstance(data, dict) or set(data) - {"waypoints"}:
        raise WaypointFileError("{} must hold one mapping, 'waypoints: {{name: [x, y, yaw]}}'".format(source))
    entries = data.get("waypoints")
    if entries is not None and not isinstance(entries, dict):
        raise WaypointFileError("{}: 'waypoints' must map names to [x, y, yaw]".format(source))
    return entries


def _load_yaml(text, source):
    """The YAML document of ``text``; WaypointFileError for whatever makes it unreadable."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise WaypointFileError("{} is not valid YAML: {}".format(source, _shorten(" ".join(str(exc).split()))))
    except Exception as exc:  # noqa: BLE001 - hostile text: whatever the parser raises, the file is broken
        raise WaypointFileError("{} cannot be read as YAML ({})".format(source, type(exc).__name__))


def waypoints_of(entries, source):
    """``{name: Waypoint}`` of a raw ``waypoints:`` mapping; WaypointFileError naming the bad entry."""
    waypoints = {}
    for name, entry in (entries or {}).items():
        try:
            waypoints[name] = _entry(name, entry)
        except BadWaypoint as exc:
            raise WaypointFileError(_shorten("{}: waypoint {!r}: {}".format(source, name, exc), 2 * MAX_QUOTED))
    return waypoints


def _entry(name, entry):
    if isinstance(entry, (list, tuple)) and len(entry) == 3:
        return make_waypoint(name, *entry)
    if isinstance(entry, dict) and set(entry) == {"x", "y", "yaw"}:
        return make_waypoint(name, entry["x"], entry["y"], entry["yaw"])
    got = _shorten(json.dumps(entry, default=repr))
    raise BadWaypoint("expected [x, y, yaw] or {x: .., y: .., yaw: ..}, got " + got)


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
    return json.dumps(name)  # a JSON string is a valid YAML double-quoted scalar


def _number(value):
    text = repr(float(value))
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:  # YAML 1.1 (PyYAML) reads 1e-05 as text, 1.0e-05 as a float
        text = "{}.0e{}".format(mantissa, exponent)
    return text
