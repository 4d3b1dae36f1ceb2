"""Exploration over HTTP (docs/api.md, "Exploration"): ``POST /explore`` maps the flat in one go,
``GET /explore`` tells the exploration under way, or the last one.

The explorer (``explore/explorer.py``) is found in ``app.extensions["flask_move_server"]["explorer"]``;
this module checks the body, every field before anything starts, and shapes the answer. A server
built without an explorer answers ``POST /explore`` with 409 ``explore_conflict`` and ``GET /explore``
with null. Progress is told as ``explore`` events on ``GET /events`` by the explorer itself.
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.core.errors import BadRequest, ExploreConflict, shown
from flask_move_server.explore.exploration import MAX_MINUTES, THEN
from flask_move_server.maps.catalogue import check_map_name
from flask_move_server.web.body import json_object, number, text
from flask_move_server.web.deadline import FIELD, check_deadline

explore_api = Blueprint("explore", __name__)

DEFAULT_MINUTES = 30.0
FIELDS = ("save_as", "then", "max_minutes", "return_home", "overwrite", FIELD)


def _explorer():
    """The explorer, or None when this server runs without one."""
    return current_app.extensions["flask_move_server"].get("explorer")


@explore_api.route("/explore", methods=["POST"])
def start():
    options = read_options(json_object(FIELDS))
    explorer = _explorer()
    if explorer is None:
        raise ExploreConflict("This server does not explore: it was started without an explorer. Map by driving "
                              "instead: POST /mode {\"mode\": \"mapping\"}, then POST /maps {\"name\": ...}.")
    return jsonify({"status": "ok", "exploration": explorer.start(**options)}), 202


@explore_api.route("/explore", methods=["GET"])
def current():
    explorer = _explorer()
    return jsonify({"exploration": explorer.current() if explorer is not None else None})


def read_options(data):
    """The body's fields as :meth:`Explorer.start` takes them, each checked (a 400 naming the field)."""
    check_deadline(data, "This exploration")
    then = data.get("then", "navigation")
    if then not in THEN:
        raise BadRequest("Field 'then' must be \"navigation\" (navigate on the saved map) or \"idle\", got {}."
                         .format(shown(then)))
    return {"save_as": check_map_name(text(data, "save_as")), "then": then,
            "max_minutes": _minutes(data), "return_home": _flag(data, "return_home", True),
            "overwrite": _flag(data, "overwrite", False)}


def _minutes(data):
    if "max_minutes" not in data:
        return DEFAULT_MINUTES
    minutes = number(data, "max_minutes")
    if not 0 < minutes <= MAX_MINUTES:
        raise BadRequest("Field 'max_minutes' must be more than 0 and at most {:g} (minutes), got {:g}."
                         .format(MAX_MINUTES, minutes))
    return minutes


def _flag(data, key, default):
    value = data.get(key, default)
    if not isinstance(value, bool):
        raise BadRequest("Field {!r} must be true or false, got {}.".format(key, shown(value)))
    return value
