"""Named waypoints and the YAML file that keeps them.

The file format is the mapping guide's::

    waypoints:
      kitchen: [1.23, 4.56, 0.79]     # x [m], y [m], yaw [rad] in the map frame

(``{x: .., y: .., yaw: ..}`` per entry loads too). :class:`WaypointStore` owns
the file: every change is saved before it is acknowledged (temp file in the same
directory, fsync, rename, fsync of the directory, the previous version kept as
``.bak``), an ``fcntl`` lock serialises writers across processes (the server
and ``record-waypoints``), and a change made on disk by someone else (a text
editor) is picked up before the next read or write instead of being
overwritten. A file that would silently lose the last good waypoints (empty,
cut short, no ``waypoints:``) is a problem to report, not a deletion: only
``waypoints: {}`` clears them. Anchors and aliases are refused (a few hundred
bytes could expand to megabytes). The file plumbing lives in
:mod:`flask_move_server.waypoints_file`. Pure: no rospy, no Flask.
"""

import contextlib
import difflib
import json
import logging
import math
import os
import re
import threading
from dataclasses import dataclass

import yaml

from flask_move_server import waypoints_file
from flask_move_server.errors import BadWaypoint, UnknownWaypoint, WaypointFileError

log = logging.getLogger(__name__)

NAME_RULE = ("1 to 64 letters, digits, '_', '-', '.' or spaces, not starting or ending with a space, "
             "without '..' and not '.' alone")
# Bounds far beyond any building, but small enough that every formula on a pose stays finite and
# exact (1e308 overflows distances): x, y in metres, yaw in radians.
POSITION_LIMIT = 1e6
YAW_LIMIT = 1e3
_NAME_RE = re.compile(r"[A-Za-z0-9_. -]{1,64}")
_PLAIN_KEY_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
MAX_QUOTED = 300  # characters of the file an error message may quote


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
        raise BadWaypoint("A waypoint name must be text, got {!r}.".format(name))
    # "." and ".." are path segments: clients drop them from a URL, so they could not be deleted.
    if not _NAME_RE.fullmatch(name) or name != name.strip(" ") or ".." in name or name == ".":
        raise BadWaypoint("Invalid waypoint name {}: use {}.".format(json.dumps(name), NAME_RULE))
    return name


def check_coordinate(label, value, limit=POSITION_LIMIT):
    """Return ``value`` as a float if it is a finite number within ±``limit``, else raise BadWaypoint."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadWaypoint("{} must be a number, got {}.".format(label, json.dumps(value, default=repr)))
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


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a name given twice, and any anchor or alias.

    Aliases let a few hundred bytes expand to megabytes (in memory, in error
    messages, in /status); a waypoints file has no use for them.
    """

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise yaml.composer.ComposerError(
                None, None, "anchors and aliases ('&', '*') are not allowed in a waypoints file", event.start_mark
            )
        return super().compose_node(parent, index)


def _construct_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
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
    return _waypoints_of(entries_of(text, source), source)


def entries_of(text, source="waypoints"):
    """The raw ``waypoints:`` mapping of the file's text; None when blank or not given."""
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise WaypointFileError("{} is not valid YAML: {}".format(source, _shorten(" ".join(str(exc).split()))))
    if data is None:
        return None
    if not isinstance(data, dict) or set(data) - {"waypoints"}:
        raise WaypointFileError("{} must hold one mapping, 'waypoints: {{name: [x, y, yaw]}}'".format(source))
    entries = data.get("waypoints")
    if entries is not None and not isinstance(entries, dict):
        raise WaypointFileError("{}: 'waypoints' must map names to [x, y, yaw]".format(source))
    return entries


def _waypoints_of(entries, source):
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


def suggest(name, names, n=3):
    """Known names close to ``name``, best first (for 'did you mean')."""
    folded = {k.lower(): k for k in names}
    exact = [folded[name.lower()]] if isinstance(name, str) and name.lower() in folded else []
    close = difflib.get_close_matches(str(name), list(names), n=n, cutoff=0.6)
    return list(dict.fromkeys(exact + close))[:n]


class WaypointStore:
    """The waypoints of one YAML file, safe to share between threads and processes.

    Readers take only the in-process lock, never the cross-process file lock,
    so a stuck ``record-waypoints`` holding the file lock cannot block them.
    """

    def __init__(self, path, lock_timeout=3.0):
        self.path = os.path.abspath(path)
        self.lock_timeout = lock_timeout
        self._lock = threading.Lock()
        self._waypoints = {}  # the last good set
        self._good_text = None  # its file text: what .bak becomes on the next save
        self._loaded = False
        self._stamp = None
        self._problem = None
        waypoints_file.remove_leftovers(self.path, lock_timeout)
        with self._lock:
            self._refresh(strict=True)

    # reading ---------------------------------------------------------------

    def all(self):
        """Every waypoint, in file order."""
        with self._lock:
            self._refresh()
            return list(self._waypoints.values())

    def get(self, name):
        """The waypoint called ``name``; UnknownWaypoint with close names if none."""
        check_name(name)
        with self._lock:
            self._refresh()
            try:
                return self._waypoints[name]
            except KeyError:
                raise UnknownWaypoint(name, suggest(name, self._waypoints))

    @property
    def problem(self):
        """Why the file on disk cannot be loaded now (shown by /status), or None."""
        with self._lock:
            self._refresh()
            return self._problem

    # writing ---------------------------------------------------------------

    def put(self, waypoint):
        """Add or replace ``waypoint``; True when it is new. Saved before returning."""
        with self._edit() as waypoints:
            created = waypoint.name not in waypoints
            waypoints[waypoint.name] = waypoint
        return created

    def delete(self, name):
        """Remove the waypoint ``name``. Saved before returning."""
        check_name(name)
        with self._edit() as waypoints:
            if name not in waypoints:
                raise UnknownWaypoint(name, suggest(name, waypoints))
            del waypoints[name]

    def rename(self, old, new):
        """Give waypoint ``old`` the name ``new``, keeping its place in the file."""
        check_name(new)
        with self._edit() as waypoints:
            if old not in waypoints:
                raise UnknownWaypoint(old, suggest(old, waypoints))
            if new in waypoints and new != old:
                raise BadWaypoint("A waypoint named {!r} exists already.".format(new))
            items = [(new if k == old else k, v) for k, v in waypoints.items()]
            waypoints.clear()
            for k, v in items:
                waypoints[k] = Waypoint(k, v.x, v.y, v.yaw)

    @contextlib.contextmanager
    def _edit(self):
        # The file lock first, with a timeout, and outside the in-process lock:
        # readers never wait behind a writer that waits for another process.
        with waypoints_file.file_lock(self.path + ".lock", self.lock_timeout), self._lock:
            self._refresh(strict=True)
            waypoints = dict(self._waypoints)
            yield waypoints
            self._save(waypoints)
            self._waypoints = waypoints

    # the file ----------------------------------------------------------------

    def _refresh(self, strict=False):
        """Reload when the file changed on disk; with ``strict``, refuse a broken file."""
        stamp = waypoints_file.stamp(self.path)
        if stamp == self._stamp and not (strict and self._problem):
            return
        try:
            text = waypoints_file.read(self.path)
            waypoints = self._load(text)
        except WaypointFileError as exc:
            self._stamp, self._problem = stamp, str(exc)
            log.error("%s; still using the %d waypoints loaded before", exc, len(self._waypoints))
            if strict:
                raise WaypointFileError(
                    "{}; nothing was changed. Fix the file, or put back the version before the last change "
                    "(cp {p}.bak {p}), or write 'waypoints: {{}}' to it to delete every waypoint on "
                    "purpose.".format(exc, p=self.path)
                )
            return
        if self._stamp is not None:
            log.info("reloaded %s: it changed on disk (%d waypoints)", self.path, len(waypoints))
        self._waypoints, self._good_text, self._loaded = waypoints, text, True
        self._stamp, self._problem = stamp, None

    def _load(self, text):
        """The waypoints of ``text``, or WaypointFileError when it is broken or would lose the last good set."""
        entries = entries_of(text, self.path) if text is not None else None
        known = len(self._waypoints) if self._loaded else _count_backup(self.path)
        loss = _why_lost(text, entries, self._loaded) if known else None
        if loss:
            raise WaypointFileError("{} {}, but the last good version had {} waypoints".format(self.path, loss, known))
        return _waypoints_of(entries, self.path)

    def _save(self, waypoints):
        text = dump(waypoints.values())
        try:
            waypoints_file.atomic_write(self.path, text, backup_text=self._good_text)
        except OSError as exc:
            raise WaypointFileError("cannot save {}: {}; nothing was changed".format(self.path, exc.strerror or exc))
        self._stamp, self._good_text = waypoints_file.stamp(self.path), text


def _why_lost(text, entries, loaded):
    """Why a file holding no or cut-short waypoints is not a deliberate deletion, or None.

    Only ``waypoints: {}`` deletes everything on purpose. An empty file, one
    without ``waypoints:`` or one not ending with the newline every save and
    editor writes is what an in-place write in progress (or a failed
    ``printf > file``) looks like. A missing file counts once one was loaded:
    some editors remove the file for a moment while saving.
    """
    if text is None:
        return "is missing" if loaded else None
    if not text.strip():
        return "is empty"
    if not text.endswith("\n"):
        return "does not end with a newline, so it looks cut short (a write in progress or interrupted)"
    if entries is None:
        return "holds no waypoints and does not say 'waypoints: {}'"
    return None


def _count_backup(path):
    """How many waypoints ``path.bak`` holds (0 if none or unreadable): the reference at start-up."""
    try:
        return len(parse(waypoints_file.read(path + ".bak") or "", path + ".bak"))
    except WaypointFileError:
        return 0
