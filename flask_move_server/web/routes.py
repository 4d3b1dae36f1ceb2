"""The HTTP API of docs/api.md: goals, stop, teleop, waypoints, status, health.

Routes parse and validate the request, call the Robot facade or the waypoint
store, and shape the JSON answer. They know nothing of rospy.
"""

from flask import Blueprint, current_app, jsonify
from werkzeug.routing import PathConverter

from flask_move_server.core.errors import BadRequest, InZone
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.waypoints import YAW_LIMIT, check_coordinate, check_name, make_waypoint
from flask_move_server.web.body import json_object, number, text
from flask_move_server.web.deadline import FIELD, check_deadline, robot_clock

api = Blueprint("api", __name__)

GOTO_FIELDS = ("name", "x", "y", "yaw", "wait", FIELD)
POSE_FIELDS = ("x", "y", "yaw")


def _robot():
    return current_app.extensions["flask_move_server"]["robot"]


def _store():
    return current_app.extensions["flask_move_server"]["store"]


def _config():
    return current_app.extensions["flask_move_server"]["config"]


@api.route("/goto", methods=["POST"])
def goto():
    data = json_object(GOTO_FIELDS)
    check_deadline(data, "This goal")
    goal = _goal_from(data)
    wait = number(data, "wait", 0, _config().navigation.max_wait) if "wait" in data else None
    seq = _robot().goto(goal)
    body = {"status": "ok", "target": goal.target, "goal": goal.pose.as_dict(), "goal_id": seq}
    if wait is None:
        return jsonify(body), 202
    reached = _robot().wait(seq, wait)
    body["navigation"] = _robot().navigation_status()
    return jsonify(body), 200 if reached else 202


def _goal_from(data):
    given_pose = not data.keys().isdisjoint(POSE_FIELDS)
    if "name" in data:
        if given_pose:
            raise BadRequest("Give either a waypoint 'name' or 'x', 'y', 'yaw', not both.")
        wp = _store().get(text(data, "name"))
        return Goal(Pose2D(wp.x, wp.y, wp.yaw), wp.name)
    if not given_pose:
        raise BadRequest('Say where to go: {"name": "kitchen"} or {"x": 1.0, "y": 2.0, "yaw": 0.0}.')
    yaw = check_coordinate("yaw", number(data, "yaw"), YAW_LIMIT) if "yaw" in data else 0.0
    return Goal(Pose2D(check_coordinate("x", number(data, "x")), check_coordinate("y", number(data, "y")), yaw))


@api.route("/stop", methods=["POST"])
def stop():
    json_object((), required=False)
    canceled = _robot().stop()
    return jsonify({"status": "ok", "canceled_goal": canceled})


@api.route("/teleop", methods=["POST"])
def teleop():
    data = json_object(("linear", "angular", FIELD))
    check_deadline(data, "This joystick command")
    linear = number(data, "linear") if "linear" in data else 0.0
    angular = number(data, "angular") if "angular" in data else 0.0
    result = _robot().teleop(linear, angular)
    result["status"] = "ok"
    return jsonify(result)


@api.route("/waypoints", methods=["GET"])
def list_waypoints():
    store = _store()
    waypoints, dock = store.all(), store.dock()
    return jsonify({"waypoints": [_shown_waypoint(wp, dock) for wp in waypoints]})


@api.route("/waypoints/<waypoint:name>", methods=["GET"])
def get_waypoint(name):
    store = _store()
    return jsonify(_shown_waypoint(store.get(name), store.dock()))


def _shown_waypoint(waypoint, dock):
    """The waypoint's JSON: ``"dock": true`` on the map's dock."""
    shown = waypoint.as_dict()
    if dock is not None and dock.name == waypoint.name:
        shown["dock"] = True
    return shown


@api.route("/waypoints/<waypoint:name>", methods=["PUT"])
def put_waypoint(name):
    check_name(name)
    data = json_object(("x", "y", "yaw", "from", "dock"))
    dock = data.pop("dock", None)
    if not isinstance(dock, (bool, type(None))):
        raise BadRequest("Field 'dock' must be true (this place is the robot's charger) or false.")
    if "from" in data:
        if data["from"] != "current" or len(data) > 1:
            raise BadRequest('Use {"from": "current"} alone to record the robot\'s pose now (and "dock": true '
                             'if it is the charger).')
        pose = _robot().current_pose()
        waypoint = make_waypoint(name, pose.x, pose.y, pose.yaw)
    elif not data and dock is not None:
        waypoint = _store().get(name)  # {"dock": true} alone: this place, where it is, is (or is not) the charger
    else:
        waypoint = make_waypoint(name, number(data, "x"), number(data, "y"), number(data, "yaw"))
    store = _store()
    created = store.put(waypoint, dock=dock)
    body = {"status": "ok", "created": created, "waypoint": _shown_waypoint(waypoint, store.dock())}
    warning = _zone_warning(waypoint)
    if warning:
        body["warning"] = warning
    return jsonify(body), 201 if created else 200


def _zone_warning(waypoint):
    """Why the robot cannot go to ``waypoint`` while a zone keeps it out (it is kept all the same), or None."""
    zones = getattr(_robot(), "zones", None)
    if zones is None:
        return None
    try:
        zones.check(Pose2D(waypoint.x, waypoint.y, waypoint.yaw), waypoint.name)
    except InZone as exc:
        return str(exc)
    return None


@api.route("/waypoints/<waypoint:name>", methods=["DELETE"])
def delete_waypoint(name):
    _store().delete(name)
    return "", 204


@api.route("/waypoints/<waypoint:name>", methods=["PATCH"])
def rename_waypoint(name):
    """Rename in one save (``PATCH /maps/<name>``'s twin): no moment with both names or neither."""
    data = json_object(("name", "overwrite"))
    overwrite = data.get("overwrite", False)
    if not isinstance(overwrite, bool):
        raise BadRequest("Field 'overwrite' must be true or false.")
    check_name(name)
    store = _store()
    waypoint = store.rename(name, text(data, "name"), overwrite=overwrite)
    return jsonify({"status": "ok", "waypoint": _shown_waypoint(waypoint, store.dock())})


class WaypointNameConverter(PathConverter):
    """``<waypoint:name>``: everything after ``/waypoints/``, line breaks and slashes included.

    Werkzeug's ``path`` stops at a newline (its regex uses ``.``), so ``/waypoints/a%0Ab`` matched
    no route and answered 404 "No such endpoint"; taking every character lets ``check_name``
    refuse it with a 400 that says what a name may hold.
    """

    regex = r"[\s\S]+?"
    part_isolating = False


@api.route("/status", methods=["GET"])
def status():
    body = _robot().status()
    body["clock"] = robot_clock()
    body["waypoints"] = {"file": _store().path, "problem": _store().problem}
    body["mode"] = current_app.extensions["flask_move_server"]["modes"].status()
    mqtt = current_app.extensions["flask_move_server"].get("mqtt")
    body["mqtt"] = mqtt.status() if mqtt is not None else {"state": "off"}
    return jsonify(body)


@api.route("/health", methods=["GET"])
def health():
    return jsonify(_robot().health())
