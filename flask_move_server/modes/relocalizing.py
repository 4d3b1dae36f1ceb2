"""Where to tell localization the robot is: a waypoint of the map's waypoints file, or its dock.

After a switch to navigation on a named map the robot's pose is set for it (RViz's
"2D Pose Estimate"): the pose given with the switch, else the map's ``dock`` waypoint when it
has one. Read with the waypoints file's own loader. Pure: no rospy, no Flask.
"""

from flask_move_server import waypoints_file, waypoints_format
from flask_move_server.errors import UnknownWaypoint, WaypointFileError
from flask_move_server.geometry import Pose2D
from flask_move_server.waypoints import check_name, suggest

DOCK = "dock"


def _waypoints(path):
    text = waypoints_file.read(path)
    return waypoints_format.parse(text or "", source=path)


def waypoint_pose(path, name):
    """The Pose2D of waypoint ``name`` in the waypoints file ``path``; UnknownWaypoint if it has none."""
    check_name(name)
    waypoints = _waypoints(path)
    if name not in waypoints:
        raise UnknownWaypoint(name, suggest(name, waypoints))
    wp = waypoints[name]
    return Pose2D(wp.x, wp.y, wp.yaw)


def dock_pose(path):
    """The ``dock`` waypoint's Pose2D in ``path``, or None (no file, no dock, or a broken file)."""
    try:
        return waypoint_pose(path, DOCK)
    except (UnknownWaypoint, WaypointFileError):
        return None
