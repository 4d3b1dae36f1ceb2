"""The first-boot doctor over HTTP: ``GET /diagnostics`` (query: ``seconds``, ``box``).

Answers 200 with the report whatever it finds (a failing check is the answer, not an error):
``{"status": "pass|warn|fail", "mode", "window", "at", "checks": [{"name", "level", "summary",
"advice"}, ...]}``. ``seconds`` (0.5-10, default ``diagnostics.window``) is how long it listens
to /scan and /odom; ``box=1`` adds the box-ahead test of the laser's yaw.
"""

import math

from flask import Blueprint, current_app, jsonify, request

from flask_move_server.core.errors import BadRequest, shown

diagnostics_api = Blueprint("diagnostics", __name__)
SECONDS = (0.5, 10.0)
YES, NO = ("1", "true", "yes"), ("0", "false", "no", "")


@diagnostics_api.route("/diagnostics", methods=["GET"])
def get_diagnostics():
    unknown = sorted(set(request.args) - {"seconds", "box"})
    if unknown:
        raise BadRequest("Unknown query parameter {}: GET /diagnostics takes seconds and box.".format(
            shown(unknown[0])))
    doctor = current_app.extensions["flask_move_server"]["doctor"]
    if doctor is None:
        raise BadRequest("The doctor is not part of this server.")
    return jsonify(doctor.examine(_seconds(request.args.get("seconds")), _box(request.args.get("box", ""))))


def _seconds(raw):
    if raw is None:
        return None
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and SECONDS[0] <= value <= SECONDS[1]):
        raise BadRequest("seconds must be a number from {:g} to {:g}, got {!r}.".format(*SECONDS, raw[:20]))
    return value


def _box(raw):
    word = raw.strip().lower()
    if word not in YES + NO:
        raise BadRequest("box must be 1 or 0 (or true, false), got {!r}.".format(raw[:20]))
    return word in YES
