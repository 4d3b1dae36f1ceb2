"""The e-stop latch over HTTP: ``POST /estop`` engages it, ``POST /estop/release`` lifts it.

Both answer 200 with the latch's state (as ``/status`` shows it under
``estop``). While latched, ``/goto`` and ``/teleop`` answer 409 saying how to
release; a release while the physical button is still pressed answers 409.
Auth applies as to every route: anyone who may drive the robot may stop it.
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.web.body import json_object

estop = Blueprint("estop", __name__)


def _robot():
    return current_app.extensions["flask_move_server"]["robot"]


@estop.route("/estop", methods=["POST"])
def engage():
    # No body check: a stop is never refused for what came with it.
    newly = _robot().engage_estop("api")
    return jsonify({"status": "ok", "engaged": newly, "estop": _robot().estop_status()})


@estop.route("/estop/release", methods=["POST"])
def release():
    json_object((), required=False)
    was = _robot().release_estop()
    return jsonify({"status": "ok", "released": was, "estop": _robot().estop_status()})
