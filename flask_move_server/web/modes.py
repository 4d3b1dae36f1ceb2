"""Modes over HTTP: ``GET /mode``, ``POST /mode`` (switch), ``POST /pose`` (set or confirm the robot's pose).

The routes validate the body and call the mode manager (``modes/manager.py``), never rospy.
A switch answers 202 at once (the stack starts in the background; ``GET /mode`` and the
``mode`` events follow it); with ``wait`` it answers 200 once running, 202 if still starting,
or the stack's error (503 ``stack_failed``) when it failed.
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.core.errors import BadRequest, shown
from flask_move_server.core.geometry import Pose2D
from flask_move_server.waypoints import YAW_LIMIT, check_coordinate
from flask_move_server.web.body import json_object, number, text

modes = Blueprint("modes", __name__)

MODE_FIELDS = ("mode", "map", "pose", "wait")
POSE_FIELDS = ("x", "y", "yaw", "name")
CONFIRM_ONLY = 'To confirm the robot\'s pose, send {"confirm": true} alone.'


def _modes():
    return current_app.extensions["flask_move_server"]["modes"]


def _store():
    return current_app.extensions["flask_move_server"]["store"]


def longest_wait(config):
    """The longest ``wait`` a switch takes: stopping the old stack plus starting the new one."""
    return config.modes.stop_timeout + config.modes.start_timeout


@modes.route("/mode", methods=["GET"])
def get_mode():
    return jsonify(_modes().status())


@modes.route("/mode", methods=["POST"])
def post_mode():
    data = json_object(MODE_FIELDS)
    mode = text(data, "mode")
    map_name = text(data, "map") if data.get("map") is not None else None
    pose = _switch_pose(data["pose"]) if data.get("pose") is not None else None
    config = current_app.extensions["flask_move_server"]["config"]
    wait = number(data, "wait", 0, longest_wait(config)) if "wait" in data else None
    body = _modes().switch(mode, map_name, pose)
    if wait is None:
        return jsonify(dict(body, status="ok")), 202
    running = _modes().wait(wait)
    return jsonify(dict(_modes().status(), status="ok")), 200 if running else 202


def _switch_pose(value):
    """The ``pose`` of a switch: a Pose2D, or a waypoint's name (looked up on the map being started)."""
    if not isinstance(value, dict):
        raise BadRequest('Field \'pose\' must be {"x": 1.0, "y": 2.0, "yaw": 0.0} or {"name": "dock"}.')
    return _pose_of(value, lambda name: name)


def _pose_of(data, by_name):
    unknown = sorted(set(data) - set(POSE_FIELDS))
    if unknown:
        raise BadRequest("Unknown pose field {}: give x, y, yaw or a waypoint's name.".format(shown(unknown[0])))
    if "name" in data:
        if any(k in data for k in ("x", "y", "yaw")):
            raise BadRequest("Give either a waypoint 'name' or 'x', 'y', 'yaw', not both.")
        return by_name(text(data, "name"))
    yaw = check_coordinate("yaw", number(data, "yaw"), YAW_LIMIT) if "yaw" in data else 0.0
    return Pose2D(check_coordinate("x", number(data, "x")), check_coordinate("y", number(data, "y")), yaw)


def _waypoint_pose(name):
    wp = _store().get(name)
    return Pose2D(wp.x, wp.y, wp.yaw)


@modes.route("/pose", methods=["POST"])
def post_pose():
    data = json_object(POSE_FIELDS + ("confirm",))
    if "confirm" in data:
        return _confirm(data)
    if not data:
        raise BadRequest('Say where the robot is: {"x": 1.0, "y": 2.0, "yaw": 0.0} or {"name": "dock"}; '
                         'or {"confirm": true} when it is where the robot believes.')
    pose = _pose_of(data, _waypoint_pose)
    _modes().set_pose(pose)
    body = {"status": "ok", "pose": pose.as_dict(), "localization": _modes().status()["localization"]}
    if "name" in data:
        body["name"] = data["name"]
    return jsonify(body)


def _confirm(data):
    """``{"confirm": true}``: the pose localization holds is right (the dock it was assumed at, say)."""
    if data["confirm"] is not True or len(data) > 1:
        raise BadRequest(CONFIRM_ONLY)
    return jsonify({"status": "ok", "confirmed": True, "localization": _modes().confirm_pose()})
