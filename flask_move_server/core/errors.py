"""One exception hierarchy for the whole package.

Every error a user can cause or meet derives from :class:`MoveServerError` and
carries a short machine-readable ``code``. ``web/error_handlers.py`` maps each class to
an HTTP status in one place; the CLI maps :class:`ConfigError` to exit status 2.
A name or value a message quotes back goes through :func:`shown`, so it is never echoed whole.
"""

import json

SHOWN = 64  # characters of a name or value an error quotes back (the longest valid name)


def shown(value, limit=SHOWN):
    """``value`` as an error quotes it, in JSON (text quoted, invisible characters escaped), cut to
    ``limit`` characters and '…': a 100 KB name sent is not a 100 KB answer, nor log line."""
    if isinstance(value, str):
        return _readable_json(value[:limit]) + ("\u2026" if len(value) > limit else "")
    text = _readable_json(value, default=repr)
    return text if len(text) <= limit else text[:limit] + "\u2026"


def _readable_json(value, **options):
    """JSON with letters of every language as they are ("Küche", not "K\\u00fcche"), and only the
    characters that print nothing (controls, line separators, bidi overrides) escaped."""
    text = json.dumps(value, ensure_ascii=False, **options)
    return "".join(c if c.isprintable() else json.dumps(c)[1:-1] for c in text)


class MoveServerError(Exception):
    """Base class of every error raised on purpose by flask-move-server."""

    code = "error"


class ConfigError(MoveServerError, ValueError):
    """The configuration file or a command-line option is invalid."""

    code = "bad_config"

    def __init__(self, source, key, reason):
        self.source = str(source)
        self.key = key
        self.reason = reason
        where = "{}: {}".format(self.source, key) if key else self.source
        super().__init__("{}: {}".format(where, reason))


class BadRequest(MoveServerError, ValueError):
    """The request body or one of its fields is malformed."""

    code = "bad_request"


class BodyTooLarge(BadRequest):
    """The request body is larger than ``server.max_body_bytes``."""

    code = "body_too_large"


class BadWaypoint(BadRequest):
    """A waypoint name or coordinate is not valid."""

    code = "bad_waypoint"


class UnknownWaypoint(MoveServerError, KeyError):
    """No waypoint has the requested name."""

    code = "unknown_waypoint"

    def __init__(self, name, suggestions=()):
        self.name = name
        self.suggestions = list(suggestions)
        message = "No waypoint named {!r}{}.".format(str(name)[:SHOWN], "\u2026" if len(str(name)) > SHOWN else "")
        if self.suggestions:
            message += " Did you mean: {}?".format(", ".join(repr(s) for s in self.suggestions))
        else:
            message += " GET /waypoints lists the known names."
        super().__init__(message)

    def __str__(self):
        return self.args[0]


class WaypointExists(MoveServerError, FileExistsError):
    """A rename would take the name of another waypoint, and replacing it was not asked for."""

    code = "waypoint_exists"


class WaypointInUse(MoveServerError, RuntimeError):
    """A waypoint a route goes through cannot be deleted: the routes would lose a stop."""

    code = "waypoint_in_use"


class BadRoute(BadRequest):
    """A route's fields are not valid (its waypoints, loops, dwell, failure policy or schedule)."""

    code = "bad_route"


class UnknownRoute(MoveServerError, KeyError):
    """No route of the active map has the requested name."""

    code = "unknown_route"

    def __str__(self):
        return self.args[0]


class UnknownRun(MoveServerError, KeyError):
    """No run kept has the requested id."""

    code = "unknown_run"

    def __str__(self):
        return self.args[0]


class RunConflict(MoveServerError, RuntimeError):
    """The run cannot do that now: another run is active, or its state does not allow it."""

    code = "run_conflict"


class NotStuck(MoveServerError, RuntimeError):
    """A back-out asked of a robot that is not stuck (or backs out already)."""

    code = "not_stuck"


class NoDock(MoveServerError, RuntimeError):
    """The map has no dock: no waypoint is marked as the charger (and none is named dock)."""

    code = "no_dock"
    MESSAGE = ("This map has no dock. Drive the robot onto its charger and mark that place as the dock: "
               "PUT /waypoints/<name> with {\"from\": \"current\", \"dock\": true}.")

    def __init__(self, message=MESSAGE):
        super().__init__(message)


class DockFailed(MoveServerError, RuntimeError):
    """A docking that ended without the robot on its charger, or an undock of a robot not on one."""

    code = "dock_failed"


class BatteryCritical(MoveServerError, RuntimeError):
    """A goal other than home while the battery is below ``dock.critical_below``."""

    code = "battery_critical"


class BadZone(BadRequest):
    """A zone that cannot be kept: a wrong kind, too few or too many corners, a shape that crosses itself."""

    code = "bad_zone"


class UnknownZone(MoveServerError, KeyError):
    """No zone of that name on this map."""

    code = "unknown_zone"

    def __str__(self):
        return self.args[0] if self.args else ""


class InZone(MoveServerError, RuntimeError):
    """A goal, a route's stop or the dock inside (or too near) a zone the robot keeps out of."""

    code = "in_zone"


class Pressed(MoveServerError, RuntimeError):
    """A joystick command that would push the robot on against what it is pressed on."""

    code = "pressed"


class ExploreConflict(MoveServerError, RuntimeError):
    """No exploration can start or go on now: one is under way, or a run is active."""

    code = "explore_conflict"


class WaypointFileError(MoveServerError, OSError):
    """The waypoints file cannot be read, parsed or written."""

    code = "waypoints_file"


class MapFull(MoveServerError, RuntimeError):
    """A change would take a map past what it keeps (waypoints, routes, the file's size); nothing was changed."""

    code = "map_full"


class WaypointsLocked(WaypointFileError):
    """Another process held the waypoints file's lock too long; nothing was changed (retry)."""

    code = "waypoints_locked"

    def __init__(self, lock_path, timeout, holder=None):
        self.lock_path = lock_path
        self.holder = holder
        super().__init__(
            "The waypoints file's lock {} has been held for over {:g} s by {}; nothing was changed. "
            "A record-waypoints saving to the file, stuck or suspended (Ctrl-Z), holds it so. Try again; "
            "if it persists, resume or stop that process ('fuser -v {}' shows it).".format(
                lock_path, timeout, holder or "another process", lock_path))

    def __str__(self):
        return self.args[0]


class Unauthorized(MoveServerError, PermissionError):
    """The request lacks the configured bearer token, or has a wrong one."""

    code = "unauthorized"


class UnknownHost(MoveServerError, PermissionError):
    """The request calls the robot by a name it does not have (a web page's DNS rebinding, say)."""

    code = "unknown_host"


class ForbiddenOrigin(MoveServerError, PermissionError):
    """The request comes from a web page of another site, which must not drive the robot."""

    code = "forbidden_origin"


class RosUnavailable(MoveServerError, ConnectionError):
    """The ROS master is not reachable (yet), so nothing can be sent."""

    code = "ros_unavailable"


class NavigationUnavailable(MoveServerError, ConnectionError):
    """move_base (the navigation action server) does not answer."""

    code = "move_base_unavailable"


class NavigationFailed(MoveServerError, RuntimeError):
    """A goal ended without reaching its target (aborted, rejected, canceled)."""

    code = "navigation_failed"

    def __init__(self, state, message):
        self.state = state
        super().__init__(message)


class NoPose(MoveServerError, LookupError):
    """The robot's pose in the map frame is not known (no tf, no AMCL pose)."""

    code = "no_pose"


class ShuttingDown(MoveServerError, ConnectionError):
    """The server is stopping (SIGTERM/SIGINT): the robot was stopped and takes no new motion."""

    code = "shutting_down"


class DriveError(MoveServerError, RuntimeError):
    """The motor backend cannot be set up or commanded."""

    code = "drive_error"


class EStopLatched(MoveServerError, RuntimeError):
    """The e-stop is latched: goals and teleop are refused until it is released."""

    code = "estop_latched"


class EStopHeld(MoveServerError, RuntimeError):
    """The e-stop cannot be released: its button is still pressed."""

    code = "estop_button_pressed"


class ClientError(MoveServerError, RuntimeError):
    """A robotctl or record-waypoints request failed; ``exit_status`` says how."""

    code = "client_error"

    def __init__(self, message, exit_status=1):
        self.exit_status = exit_status
        super().__init__(message)


class PlanningFailed(MoveServerError, RuntimeError):
    """The simulated move_base found no path to a goal (outside the map, occupied or walled off)."""

    code = "planning_failed"

    def __init__(self, reason, message):
        self.reason = reason
        super().__init__(message)


class BadMapName(BadRequest):
    """A map name breaks the naming rule (it becomes a file name in the maps folder)."""

    code = "bad_map_name"


class UnknownMap(MoveServerError, KeyError):
    """No map in the maps folder has the requested name."""

    code = "unknown_map"

    def __str__(self):
        return self.args[0]


class MapExists(MoveServerError, FileExistsError):
    """A map with that name is already saved, and overwriting it was not asked for."""

    code = "map_exists"


class MapInUse(MoveServerError, RuntimeError):
    """The map is the one in use now: it cannot be deleted or renamed under the running stack."""

    code = "map_in_use"


class MapConfigured(MoveServerError, RuntimeError):
    """The map is the one the stack was configured with: its files are the configuration's, not the folder's."""

    code = "map_configured"


class MapFileError(MoveServerError, OSError):
    """A map's files cannot be read or written (folder read-only or full, a broken file)."""

    code = "map_file"


class ModeSwitching(MoveServerError, RuntimeError):
    """A mode switch is already under way; one runs at a time."""

    code = "mode_switching"


class ModesOff(MoveServerError, RuntimeError):
    """This server does not own the navigation stack (``modes.stack: none``), so it cannot switch modes."""

    code = "modes_off"


class WrongMode(MoveServerError, RuntimeError):
    """The request needs another mode (saving a map needs mapping, relocalizing needs a map)."""

    code = "wrong_mode"


class StackFailed(MoveServerError, RuntimeError):
    """The navigation stack of a mode did not come up, or died (the message says which part and why)."""

    code = "stack_failed"


class NoMap(MoveServerError, LookupError):
    """No map is published on the map topic (nothing is mapping or serving a map)."""

    code = "no_map"


class MapNotReceived(MoveServerError, TimeoutError):
    """No map arrived on the map topic in time to save it (is mapping running?)."""

    code = "no_map_received"


class CommandLate(MoveServerError, RuntimeError):
    """A motion command reached the robot after its ``valid_until``: it was not carried out."""

    code = "command_late"


class TooManyStreams(MoveServerError, RuntimeError):
    """Every ``GET /events`` stream the server allows (``server.max_streams``) is open already."""

    code = "too_many_streams"


class DiagnosticsBusy(MoveServerError, RuntimeError):
    """The doctor is already examining the robot with other settings: one examination at a time."""

    code = "diagnostics_busy"
