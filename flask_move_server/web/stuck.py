"""A stuck robot over HTTP: ``POST /stuck/back_out`` asks one that waits for its owner to back out.

The robot backs out by itself when a goal of its own got it stuck; pushed there by the joystick, or
with no room then, it says so (``/status`` ``stuck``) and waits. This is the owner's "let it back
out": 202 with ``stuck`` as ``/status`` shows it; 409 ``not_stuck`` when it is free or backing out
already, 409 ``estop_latched`` while the e-stop is on (docs/stuck.md).
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.web.body import json_object

stuck = Blueprint("stuck", __name__)


@stuck.route("/stuck/back_out", methods=["POST"])
def back_out():
    json_object((), required=False)
    state = current_app.extensions["flask_move_server"]["robot"].back_out()
    return jsonify({"status": "ok", "stuck": state}), 202
