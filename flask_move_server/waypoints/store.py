"""The waypoints and routes of one YAML file, shared by the server's threads and by other processes.

:class:`WaypointStore` owns the file: every change is saved before it is acknowledged (temp
file in the same directory, fsync, rename, fsync of the directory, the previous version kept
as ``.bak``), an ``fcntl`` lock serialises writers across processes (the server and
``record-waypoints``), and a change made on disk by someone else (a text editor) is picked up
before the next read or write instead of being overwritten. A file that would silently lose
the last good waypoints (empty, cut short, no ``waypoints:``) is a problem to report, not a
deletion: only ``waypoints: {}`` clears them. A broken file, at start-up too, is served as the
last good set (none before one loaded) with :attr:`~WaypointStore.problem` saying why, logged
once per version of the file, and refuses changes until fixed. A save writes the seed format
afresh, so comments written by hand are dropped: the save that drops them leaves the file as
it was in ``.bak`` (as every save does) and says so in the log. The map's routes live in the
same file and share every guarantee; a route names only waypoints of the store when it is put,
and a waypoint a route goes through cannot be deleted (a rename follows into the routes). A hand
edit may still leave a route naming a waypoint the file lacks: it loads, with a warning, and a
run of it misses that stop. The file plumbing lives in
:mod:`flask_move_server.waypoints.locked_file`, the format in
:mod:`flask_move_server.waypoints.yaml_format`. Pure: no rospy, no Flask.
"""

import contextlib
import logging
import os
import shlex
import threading

from flask_move_server.core.errors import (
    BadRoute,
    BadWaypoint,
    MapFull,
    UnknownRoute,
    UnknownWaypoint,
    UnknownZone,
    WaypointExists,
    WaypointFileError,
    WaypointInUse,
    shown,
)
from flask_move_server.missions.route import check_route_name
from flask_move_server.waypoints import Waypoint, check_name, suggest
from flask_move_server.waypoints import locked_file as waypoints_file
from flask_move_server.waypoints.yaml_format import (
    Document,
    dock_of,
    dump,
    entries_of,
    marked_dock,
    parse,
    routes_of,
    waypoints_of,
    zones_of,
)
from flask_move_server.zones import MAX_ZONES, check_zone_name

log = logging.getLogger(__name__)

# What one map keeps: far beyond a flat or a lab, far below what a save on a Pi's SD card can take in
# a blink. A change past one of them is MapFull, nothing written; a hand-edited file beyond them
# still loads, and changes that do not add to it (a delete) still work.
MAX_WAYPOINTS = 1000
MAX_ROUTES = 100
# Characters the API writes: an eighth of what the reader takes (room for hand edits and comments), and a
# save and a re-read of pure-Python YAML at that size stay under a second on this machine (a Pi 4: ~3 s).
MAX_SAVED = 512 * 1024


class WaypointStore:
    """The waypoints and routes of one YAML file, safe to share between threads and processes.

    Readers take only the in-process lock, never the cross-process file lock,
    so a stuck ``record-waypoints`` holding the file lock cannot block them.
    """

    def __init__(self, path, lock_timeout=3.0):
        self.path = os.path.abspath(path)
        self.lock_timeout = lock_timeout
        self._lock = threading.Lock()
        self._waypoints = {}  # the last good set
        self._routes = {}  # and its routes, {name: Route} in file order
        self._dock = None  # the name under dock: in its file (None: none marked)
        self._zones = {}  # {name: Zone} in file order
        self._good_text = None  # its file text: what .bak becomes on the next save
        self._loaded = False
        self._stamp = None
        self._problem = None
        self.version = 0  # counts the changes of the set served: saves, reloads, use_file
        self._announced = 0
        self._listeners = []
        waypoints_file.remove_leftovers(self.path, lock_timeout)
        with self._lock:
            self._refresh()  # a broken file is a problem to report, never a server that cannot start

    def use_file(self, path):
        """Serve the waypoints of ``path`` from now on (the active map's, or the single file).

        The same guarantees hold for the new file (lock, ``.bak``, reload on external edits). A
        missing file is an empty set, created by the first change; a broken one is reported as
        :attr:`problem` and refuses changes until fixed, as at start-up, but never stops the switch.
        """
        path = os.path.abspath(path)
        with self._lock:
            if path == self.path:
                return
            log.info("waypoints: now serving %s", path)
            self.path = path
            self._waypoints, self._routes, self._zones, self._good_text, self._loaded = {}, {}, {}, None, False
            self._stamp = self._problem = self._dock = None
            self.version += 1
            self._refresh()
        self._announce()

    def when_changed(self, callback):
        """Call ``callback(version)`` after the served set changed (outside the store's lock)."""
        self._listeners.append(callback)

    def _announce(self):
        """Tell the listeners about changes not told yet; called after the lock is released."""
        with self._lock:
            version = self.version
            if version == self._announced:
                return
            self._announced = version
        for callback in list(self._listeners):
            try:
                callback(version)
            except Exception:  # a listener's bug must not fail a save that succeeded
                log.exception("waypoints listener failed")

    # reading ---------------------------------------------------------------

    def all(self):
        """Every waypoint, in file order."""
        with self._lock:
            self._refresh()
            found = list(self._waypoints.values())
        self._announce()
        return found

    def get(self, name):
        """The waypoint called ``name`` (in any Unicode normal form); UnknownWaypoint with close names if none."""
        name = check_name(name)
        with self._lock:
            self._refresh()
            try:
                return self._waypoints[name]
            except KeyError:
                raise UnknownWaypoint(name, suggest(name, self._waypoints))

    def dock(self):
        """The map's dock (a Waypoint): the one marked, else one named ``dock``; None when the map has neither."""
        with self._lock:
            self._refresh()
            name = dock_of(self._waypoints, self._dock)
            return self._waypoints[name] if name is not None else None

    def routes(self):
        """Every route of the file, in file order."""
        with self._lock:
            self._refresh()
            found = list(self._routes.values())
        self._announce()
        return found

    def get_route(self, name):
        """The route called ``name`` (in any Unicode normal form); UnknownRoute with close names if none."""
        name = check_route_name(name)
        with self._lock:
            self._refresh()
            try:
                return self._routes[name]
            except KeyError:
                raise _unknown_route(name, self._routes)

    def zones(self):
        """Every zone of the map, in file order."""
        with self._lock:
            self._refresh()
            found = list(self._zones.values())
        self._announce()
        return found

    def get_zone(self, name):
        """The zone called ``name`` (in any Unicode normal form); UnknownZone with close names if none."""
        name = check_zone_name(name)
        with self._lock:
            self._refresh()
            try:
                return self._zones[name]
            except KeyError:
                raise _unknown_zone(name, self._zones)

    @property
    def problem(self):
        """Why the file on disk cannot be loaded now (shown by /status), or None."""
        with self._lock:
            self._refresh()
            return self._problem

    # writing ---------------------------------------------------------------

    def put(self, waypoint, dock=None):
        """Add or replace ``waypoint``; True when it is new. Saved before returning.

        ``dock``: True makes it the map's dock (the one before loses the role), False takes the role
        from it, None leaves the role as it is."""
        with self._edit() as draft:
            created = waypoint.name not in draft.waypoints
            draft.waypoints[waypoint.name] = waypoint
            if dock:
                draft.dock = waypoint.name
            elif dock is False and draft.dock == waypoint.name:
                draft.dock = None
            elif dock is False and dock_of(draft.waypoints, draft.dock) == waypoint.name:
                raise BadWaypoint("The waypoint named dock is the dock by its name: rename it, or mark another "
                                  "place as the dock with \"dock\": true.")
        return created

    def delete(self, name):
        """Remove the waypoint ``name``. Saved before returning.

        WaypointInUse naming the routes that go through it, nothing written: they would lose a stop.
        """
        name = check_name(name)
        with self._edit() as draft:
            waypoints = draft.waypoints
            if name not in waypoints:
                raise UnknownWaypoint(name, suggest(name, waypoints))
            users = [route.name for route in draft.routes.values() if name in route.waypoints]
            if users:
                raise WaypointInUse("The waypoint {} is used by {}: change or delete {} first.".format(
                    shown(name), _listed("route", users), "them" if len(users) > 1 else "it"))
            del waypoints[name]
            if draft.dock == name:
                draft.dock = None  # the dock's place is gone, and its role with it

    def put_route(self, route):
        """Add or replace ``route`` (a named Route); True when it is new. Saved before returning.

        Every waypoint it names must be one of the store's: else BadRoute naming each unknown one,
        nothing written (a run would miss them).
        """
        if route.name is None:
            raise BadRoute("A route kept in the waypoints file needs a name.")
        with self._edit() as draft:
            waypoints, routes = draft.waypoints, draft.routes
            unknown = list(dict.fromkeys(w for w in route.waypoints if w not in waypoints))
            if unknown:
                raise BadRoute("The route {} goes through {} this map does not have. GET /waypoints lists the "
                               "known names.".format(shown(route.name), _listed("waypoint", unknown)))
            created = route.name not in routes
            routes[route.name] = route
        return created

    def delete_route(self, name):
        """Remove the route ``name`` (its waypoints stay). Saved before returning."""
        name = check_route_name(name)
        with self._edit() as draft:
            routes = draft.routes
            if name not in routes:
                raise _unknown_route(name, routes)
            del routes[name]

    def put_zone(self, zone):
        """Add or replace ``zone`` (a Zone); True when it is new. Saved before returning."""
        with self._edit() as draft:
            created = zone.name not in draft.zones
            draft.zones[zone.name] = zone
        return created

    def switch_zone(self, name, enabled):
        """Enable or disable the zone ``name``; returns it as saved. Saved before returning."""
        name = check_zone_name(name)
        with self._edit() as draft:
            if name not in draft.zones:
                raise _unknown_zone(name, draft.zones)
            draft.zones[name] = draft.zones[name].switched(enabled)
            return draft.zones[name]

    def delete_zone(self, name):
        """Remove the zone ``name``. Saved before returning."""
        name = check_zone_name(name)
        with self._edit() as draft:
            if name not in draft.zones:
                raise _unknown_zone(name, draft.zones)
            del draft.zones[name]

    def rename(self, old, new, overwrite=False):
        """Give waypoint ``old`` the name ``new`` in one save, keeping its place in the file.

        A waypoint already called ``new`` is WaypointExists, unless ``overwrite``: then it goes,
        in the same save (never a moment with both or neither). Returns the renamed Waypoint.
        """
        old, new = check_name(old), check_name(new)
        with self._edit() as draft:
            waypoints, routes = draft.waypoints, draft.routes
            if old not in waypoints:
                raise UnknownWaypoint(old, suggest(old, waypoints))
            if new in waypoints and new != old and not overwrite:
                raise WaypointExists("A waypoint named {} exists already; pick another name, or ask to replace "
                                     "it.".format(shown(new)))
            was_dock = dock_of(waypoints, draft.dock)
            items = [(new if k == old else k, v) for k, v in waypoints.items() if k != new or new == old]
            waypoints.clear()
            for k, v in items:
                waypoints[k] = Waypoint(k, v.x, v.y, v.yaw)
            for k, route in routes.items():  # the routes go on through the same place, under its new name
                routes[k] = route.renamed_waypoint(old, new)
            if was_dock == old:
                draft.dock = new  # the dock keeps its role under its new name (one named dock, too)
            elif was_dock == new and draft.dock == new:
                draft.dock = None  # the dock it replaced is gone, and its role with it
            return waypoints[new]

    @contextlib.contextmanager
    def _edit(self):
        # The file lock first, with a timeout, and outside the in-process lock:
        # readers never wait behind a writer that waits for another process.
        with waypoints_file.file_lock(self.path + ".lock", self.lock_timeout), self._lock:
            self._refresh(strict=True)
            draft = _Draft(dict(self._waypoints), dict(self._routes), self._dock, dict(self._zones))
            yield draft
            waypoints, routes = draft.waypoints, draft.routes
            _check_room(waypoints, routes, self._waypoints, self._routes)
            _check_zone_room(draft.zones, self._zones)
            self._save(waypoints, routes, draft.dock, draft.zones)
            self._waypoints, self._routes, self._dock, self._zones = waypoints, routes, draft.dock, draft.zones
            self.version += 1
        self._announce()

    # the file ----------------------------------------------------------------

    def _refresh(self, strict=False):
        """Reload when the file changed on disk; with ``strict``, refuse a broken file."""
        stamp = waypoints_file.stamp(self.path)
        if stamp == self._stamp and not (strict and self._problem):
            return
        try:
            text = waypoints_file.read(self.path)
            waypoints, routes, dock, zones = self._load(text)
        except WaypointFileError as exc:
            self._broken(stamp, str(exc))
            if strict:
                raise WaypointFileError(
                    "{}; nothing was changed. Fix the file,{} or write 'waypoints: {{}}' to it to delete every "
                    "waypoint on purpose.".format(exc, _restore_hint(self.path))
                )
            return
        if self._stamp is not None:
            log.info("reloaded %s: it changed on disk (%d waypoints, %d routes)", self.path, len(waypoints),
                     len(routes))
            self.version += 1
        _warn_of_missing_stops(self.path, waypoints, routes)  # once per version of the file: loaded once
        if dock is not None and dock not in waypoints:
            log.warning("%s: its dock is %s, a waypoint it does not have: the map has no dock until one is marked "
                        "(PUT /waypoints/<name> with \"dock\": true)", self.path, shown(dock))
        self._waypoints, self._routes, self._good_text, self._loaded = waypoints, routes, text, True
        self._stamp, self._problem, self._dock, self._zones = stamp, None, dock, zones

    def _broken(self, stamp, problem):
        """Remember why the file cannot be loaded: logged once per version of the file, not per request."""
        if (stamp, problem) != (self._stamp, self._problem):
            serving = ("still serving the {} waypoints loaded before".format(len(self._waypoints)) if self._loaded
                       else "serving no waypoints until it is fixed")
            log.error("%s; %s", problem, serving)
        self._stamp, self._problem = stamp, problem

    def _load(self, text):
        """The Document (waypoints, routes) of ``text``; WaypointFileError when it is broken or would lose
        the last good set."""
        entries = entries_of(text, self.path) if text is not None else None
        known = len(self._waypoints) if self._loaded else _count_backup(self.path)
        loss = _why_lost(text, entries, self._loaded) if known else None
        if loss:
            raise WaypointFileError("{} {}, but the last good version had {} waypoints".format(self.path, loss, known))
        return Document(waypoints_of(entries, self.path), routes_of(entries, self.path),
                        marked_dock(entries, self.path), zones_of(entries, self.path))

    def _save(self, waypoints, routes, dock, zones):
        text = dump(waypoints.values(), routes.values(), dock, zones.values())
        if len(text) > MAX_SAVED and len(text) > len(self._good_text or ""):
            raise MapFull("This change would make the map's waypoints file {} characters long; it holds at most {} "
                          "(its waypoints and routes). Nothing was changed: delete routes or waypoints this map no "
                          "longer needs, or make long routes shorter.".format(len(text), MAX_SAVED))
        try:
            waypoints_file.atomic_write(self.path, text, backup_text=self._good_text)
        except OSError as exc:
            raise WaypointFileError("cannot save {}: {}; nothing was changed".format(self.path, exc.strerror or exc))
        if _has_comments(self._good_text):
            log.warning("saving %s dropped the comments written in it by hand (a save writes the seed format "
                        "afresh); the file as it was, comments and all, is %s.bak until the next change: copy "
                        "it to keep it", self.path, self.path)
        self._stamp, self._good_text = waypoints_file.stamp(self.path), text


class _Draft:
    """A change being made (``WaypointStore._edit``): the waypoints, routes, dock and zones it will save."""

    def __init__(self, waypoints, routes, dock, zones):
        self.waypoints, self.routes, self.dock, self.zones = waypoints, routes, dock, zones


def _check_zone_room(zones, before):
    """MapFull when a change adds zones past what a map keeps."""
    if len(zones) > MAX_ZONES and len(zones) > len(before):
        raise MapFull("A map keeps at most {} zones, and this one has {}. Nothing was changed: delete zones it no "
                      "longer needs (DELETE /zones/<name>) first.".format(MAX_ZONES, len(before)))


def _unknown_zone(name, zones):
    """UnknownZone for ``name``, suggesting close zone names, else where to find them."""
    message = "No zone named {} on this map.".format(shown(name))
    close = suggest(name, zones)
    message += " Did you mean: {}?".format(", ".join(shown(c) for c in close)) if close else " GET /zones lists them."
    return UnknownZone(message)


def _check_room(waypoints, routes, before_waypoints, before_routes):
    """MapFull when a change adds waypoints or routes past what a map keeps (a shrinking change always passes)."""
    for what, now, before, limit, where in (("waypoints", waypoints, before_waypoints, MAX_WAYPOINTS, "/waypoints"),
                                            ("routes", routes, before_routes, MAX_ROUTES, "/routes")):
        if len(now) > limit and len(now) > len(before):
            raise MapFull("A map keeps at most {} {}, and this one has {}. Nothing was changed: delete {} it no longer "
                          "needs (DELETE {}/<name>) first.".format(limit, what, len(before), what, where))


def _listed(kind, names):
    """'the route "a"' or 'the routes "a", "b"': names quoted as errors quote them."""
    return "the {}{} {}".format(kind, "s" if len(names) > 1 else "", ", ".join(shown(n) for n in names))


def _unknown_route(name, routes):
    """UnknownRoute for ``name``, suggesting close route names, else where to find them."""
    message = "No route named {}.".format(shown(name))
    close = suggest(name, routes)
    if close:
        message += " Did you mean: {}?".format(", ".join(shown(c) for c in close))
    else:
        message += " GET /routes lists them."
    return UnknownRoute(message)


def _warn_of_missing_stops(path, waypoints, routes):
    """Log each route of a (hand-edited) file naming waypoints the file lacks: a run of it will miss them."""
    for route in routes.values():
        missing = [w for w in dict.fromkeys(route.waypoints) if w not in waypoints]
        if missing:
            log.warning("%s: the route %s names waypoints the file does not have (%s); a run of it will miss "
                        "them", path, shown(route.name), ", ".join(shown(w) for w in missing))


def _why_lost(text, entries, loaded):
    """Why a file holding no or cut-short waypoints is not a deliberate deletion, or None.

    Only ``waypoints: {}`` deletes everything on purpose. An empty file, one
    without ``waypoints:``, or one stopping right after a bare number (which
    could be cut mid-number) is what an in-place write in progress (or a failed
    ``printf > file``) looks like. Truncation is judged by the structure, not by
    a final newline, which some editors (VS Code, Notepad) do not write: a file
    that parses and ends with a closed entry (``[x, y, yaw]``) is whole. A
    missing file counts once one was loaded: some editors remove the file for a
    moment while saving.
    """
    if text is None:
        return "is missing" if loaded else None
    if not text.strip():
        return "is empty"
    if entries is None:
        return "holds no waypoints and does not say 'waypoints: {}'"
    if entries.open_end:
        return ("stops right after a number with no newline, so it looks cut short (a write in progress or "
                "interrupted); end the file with a newline")
    return None


def _has_comments(text):
    """Whether a loaded file's ``text`` holds comments: no name or number may hold '#', so each starts one."""
    return text is not None and "#" in text


def _restore_hint(path):
    """The shell command putting back ``path.bak``, quoted (a map's name may hold spaces); "" with no backup."""
    if not os.path.isfile(path + ".bak"):
        return ""
    return " or put back the version before the last change ({}),".format(
        " ".join(["cp", shlex.quote(path + ".bak"), shlex.quote(path)]))


def _count_backup(path):
    """How many waypoints ``path.bak`` holds (0 if none or unreadable): the reference at start-up."""
    try:
        return len(parse(waypoints_file.read(path + ".bak") or "", path + ".bak"))
    except WaypointFileError:
        return 0
