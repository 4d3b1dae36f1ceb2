"""Where to tell localization the robot is after a switch: a waypoint of the map, or its dock.

After a switch to navigation on a named map the robot's pose is set for it (RViz's
"2D Pose Estimate"): the pose given with the switch, else the map's dock (the waypoint marked as
its charger, or one named ``dock``) when it has one, else the running message asks for
``POST /pose``. Navigation on the stack's own map (map null) is left as the stack sets it, as
before modes existed. After a restart of a crashed stack the robot has moved since, so nothing is
set and the message says to check. The dock set by the server is an assumption until the owner
confirms or sets the pose (``assumed_pose.py``). Waypoints are read with the waypoints file's own
loader. Pure: no rospy, no Flask.
"""

from flask_move_server.core.errors import UnknownWaypoint, WaypointFileError
from flask_move_server.core.geometry import Pose2D
from flask_move_server.waypoints import check_name, suggest
from flask_move_server.waypoints import locked_file as waypoints_file
from flask_move_server.waypoints import yaml_format as waypoints_format


def _waypoints(path):
    text = waypoints_file.read(path)
    return waypoints_format.parse(text or "", source=path)


def waypoint_pose(path, name, map_name=None):
    """The Pose2D of waypoint ``name`` in the waypoints file ``path``; UnknownWaypoint if it has none.

    ``map_name``: the map switched to, whose waypoints are not those ``/waypoints`` serves yet,
    so the error names that map and its waypoints (the served ones may well hold ``name``).
    """
    name = check_name(name)
    waypoints = _waypoints(path)
    if name not in waypoints:
        error = UnknownWaypoint(name, suggest(name, waypoints))
        if map_name is not None:
            error.args = (_not_on_map(name, map_name, sorted(waypoints), error.suggestions),)
        raise error
    wp = waypoints[name]
    return Pose2D(wp.x, wp.y, wp.yaw)


def _not_on_map(name, map_name, names, close):
    listed = ", ".join(repr(n) for n in names[:10]) + (", ..." if len(names) > 10 else "")
    return "The map {!r} has no waypoint named {!r}.{} A pose's name is one of the map's own waypoints ({}).".format(
        map_name, name, " Did you mean: {}?".format(", ".join(repr(s) for s in close)) if close else "",
        "it has " + listed if names else "it has none yet")


def dock_pose(path):
    """(name, Pose2D) of the dock in the waypoints file ``path``, or None (no file, no dock, or a broken file)."""
    try:
        document = waypoints_format.parse_document(waypoints_file.read(path) or "", source=path)
    except WaypointFileError:
        return None
    name = waypoints_format.dock_of(document.waypoints, document.dock)
    if name is None:
        return None
    wp = document.waypoints[name]
    return name, Pose2D(wp.x, wp.y, wp.yaw)


MAPPING = "running; drive the robot around the place, then save the map (POST /maps, robotctl map save NAME)"
OWN_MAP = "running on the map the navigation stack was configured with"
NO_DOCK = "running; set the robot's pose (POST /pose) \u2013 the map has no dock"


def after_start(target, waypoints_path, publish):
    """Set the robot's pose for a switch to ``target`` that now runs.

    ``waypoints_path(map_name)``: that map's waypoints file; ``publish(pose)``: the estimate out.
    Returns (the running message, the waypoint the pose was assumed at or None): the dock set
    by the server is an assumption (``assumed_pose.py``), a pose given with the switch is not.
    """
    if target.mode != "navigation":
        return target.note or MAPPING, None
    if target.pose is not None:
        return _publish_note(publish, target.pose, "the given pose")[0], None
    if target.map is None:
        return OWN_MAP, None
    found = dock_pose(waypoints_path(target.map))
    if found is None:
        return NO_DOCK, None
    name, pose = found
    note, published = _publish_note(publish, pose, "the dock, {}".format(name))
    return note, name if published else None


def _publish_note(publish, pose, what):
    """(the running message, whether the estimate went out)."""
    try:
        publish(pose)
    except Exception as exc:  # ROS down, no publisher: the stack runs, say the pose is not set
        return "running; the robot's pose could not be set ({}): POST /pose".format(exc), False
    return "running; the robot's pose was set to {} ({:.2f}, {:.2f}, {:.2f})".format(
        what, pose.x, pose.y, pose.yaw), True


def restarted_note(target, restarts):
    """The running message after ``restarts`` restarts of a crashed stack."""
    note = "running again after {} restart{}".format(restarts, "" if restarts == 1 else "s")
    if target.mode == "navigation":
        note += "; check the robot's pose (POST /pose sets it)"
    return note
