"""Docking over HTTP: ``POST /dock`` sends the robot home onto its charger, ``POST /undock`` backs it off.

``POST /dock`` answers 202 with ``dock`` as ``/status`` shows it; with ``"wait": seconds`` (as
``/goto``) 200 once it is on the charger, 202 while still on its way, 409 ``dock_failed`` when it
gave up (the message says why). 409 ``no_dock`` when the map has no charger marked, 409
``estop_latched`` while the e-stop is on. ``POST /undock``: 202, or 409 ``dock_failed`` when the
robot is not on a charger (docs/docking.md).
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.web.body import json_object, number
from flask_move_server.web.deadline import FIELD, check_deadline

docking = Blueprint("docking", __name__)


def _robot():
    return current_app.extensions["flask_move_server"]["robot"]


@docking.route("/dock", methods=["POST"])
def dock():
    data = json_object(("wait", FIELD), required=False)
    check_deadline(data, "This dock command")
    config = current_app.extensions["flask_move_server"]["config"]
    wait = number(data, "wait", 0, config.navigation.max_wait) if "wait" in data else None
    robot = _robot()
    status = robot.dock()
    if wait is None:
        return jsonify({"status": "ok", "dock": status}), 202
    docked = robot.docking.wait(wait)
    return jsonify({"status": "ok", "dock": robot.dock_status()}), 200 if docked else 202


@docking.route("/undock", methods=["POST"])
def undock():
    data = json_object((FIELD,), required=False)
    check_deadline(data, "This undock command")
    return jsonify({"status": "ok", "dock": _robot().undock()}), 202
