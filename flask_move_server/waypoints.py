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
overwritten. Pure: no rospy, no Flask.
"""

import contextlib
import difflib
import fcntl
import json
import logging
import math
import os
import re
import tempfile
import threading
from dataclasses import dataclass

import yaml

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
    """SafeLoader that rejects a name given twice instead of keeping the last."""


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


def parse(text, source="waypoints"):
    """Parse the waypoints file's text into an ordered ``{name: Waypoint}``."""
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise WaypointFileError("{} is not valid YAML: {}".format(source, " ".join(str(exc).split())))
    if data is None:
        return {}
    if not isinstance(data, dict) or set(data) - {"waypoints"}:
        raise WaypointFileError("{} must hold one mapping, 'waypoints: {{name: [x, y, yaw]}}'".format(source))
    entries = data.get("waypoints") or {}
    if not isinstance(entries, dict):
        raise WaypointFileError("{}: 'waypoints' must map names to [x, y, yaw]".format(source))
    waypoints = {}
    for name, entry in entries.items():
        try:
            waypoints[name] = _entry(name, entry)
        except BadWaypoint as exc:
            raise WaypointFileError("{}: waypoint {!r}: {}".format(source, name, exc))
    return waypoints


def _entry(name, entry):
    if isinstance(entry, (list, tuple)) and len(entry) == 3:
        return make_waypoint(name, *entry)
    if isinstance(entry, dict) and set(entry) == {"x", "y", "yaw"}:
        return make_waypoint(name, entry["x"], entry["y"], entry["yaw"])
    raise BadWaypoint("expected [x, y, yaw] or {x: .., y: .., yaw: ..}, got " + json.dumps(entry, default=repr))


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
    """The waypoints of one YAML file, safe to share between threads and processes."""

    def __init__(self, path):
        self.path = os.path.abspath(path)
        self._lock = threading.Lock()
        self._waypoints = {}
        self._stamp = None
        self.problem = None  # why the file on disk could not be loaded, if it could not
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

    def replace_all(self, new_waypoints):
        """Replace every waypoint at once (undo in the recorder)."""
        with self._edit() as waypoints:
            waypoints.clear()
            for wp in new_waypoints:
                waypoints[wp.name] = wp

    @contextlib.contextmanager
    def _edit(self):
        with self._lock, _file_lock(self.path + ".lock"):
            self._refresh(strict=True)
            waypoints = dict(self._waypoints)
            yield waypoints
            self._save(waypoints)
            self._waypoints = waypoints

    # the file ----------------------------------------------------------------

    def _refresh(self, strict=False):
        """Reload when the file changed on disk; with ``strict``, refuse a broken file."""
        stamp = _stamp(self.path)
        if stamp == self._stamp and not (strict and self.problem):
            return
        try:
            text = _read(self.path)
            self._waypoints = parse(text, self.path) if text is not None else {}
        except WaypointFileError as exc:
            self._stamp, self.problem = stamp, str(exc)
            log.error("%s; still using the %d waypoints loaded before", exc, len(self._waypoints))
            if strict:
                raise WaypointFileError(
                    "{}. Fix the file (the last good version is {}.bak); "
                    "nothing was changed.".format(exc, self.path)
                )
            return
        if self._stamp is not None:
            log.info("reloaded %s: it changed on disk (%d waypoints)", self.path, len(self._waypoints))
        self._stamp, self.problem = stamp, None

    def _save(self, waypoints):
        text = dump(waypoints.values())
        try:
            _atomic_write(self.path, text)
        except OSError as exc:
            raise WaypointFileError("cannot save {}: {}; nothing was changed".format(self.path, exc.strerror or exc))
        self._stamp = _stamp(self.path)


def _stamp(path):
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _read(path):
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise WaypointFileError("cannot read {}: {}".format(path, exc))


@contextlib.contextmanager
def _file_lock(lock_path):
    """An exclusive ``flock`` on a lock file beside the data (the data file is replaced)."""
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise WaypointFileError("cannot lock {}: {}".format(lock_path, exc.strerror))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _atomic_write(path, text):
    """Write ``text`` to ``path`` so that a crash leaves the old or the new file, whole."""
    directory = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(prefix=".{}.".format(os.path.basename(path)), suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        if os.path.exists(path):
            os.chmod(tmp, os.stat(path).st_mode & 0o7777)
            _keep_backup(path)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_dir(directory)


def _keep_backup(path):
    """Make ``path.bak`` the current version, atomically (hard link, else copy)."""
    bak, tmp = path + ".bak", path + ".bak.tmp"
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)
    try:
        os.link(path, tmp)
    except OSError:
        with open(path, "rb") as src, open(tmp, "wb") as dst:
            dst.write(src.read())
            dst.flush()
            os.fsync(dst.fileno())
    os.replace(tmp, bak)


def _fsync_dir(directory):
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
