"""Routes and runs over HTTP (docs/routes.md): ``/routes`` kept in the active map's waypoints file,
``/runs`` driven by the one executor (``missions/executor.py``).

Routes validate, call the store or the executor found in ``app.extensions["flask_move_server"]``,
and shape the answer; they know nothing of rospy.
"""

import datetime

from flask import Blueprint, current_app, jsonify

from flask_move_server.core.errors import BadRequest, RunConflict
from flask_move_server.missions import schedule
from flask_move_server.missions.route import FIELDS, check_route_name, make_route
from flask_move_server.web.body import json_object, text
from flask_move_server.web.deadline import FIELD, check_deadline

missions_api = Blueprint("missions", __name__)

RUN_FIELDS = ("route",) + FIELDS[:-1] + (FIELD,)  # a named route, or an unnamed one (no timetable)


def _extension(name):
    return current_app.extensions["flask_move_server"][name]


def _runs():
    runs = _extension("runs")
    if runs is None:
        raise RunConflict("This server runs no routes (it has no run executor).")
    return runs


def _shown(route):
    """A route as the API shows it: its fields, and ``next_run``, when its timetable starts it next."""
    body = route.as_dict()
    after = datetime.datetime.now().astimezone()
    due = schedule.next_due([schedule.parse(entry) for entry in route.schedule], after)
    body["next_run"] = due.isoformat(timespec="seconds") if due is not None else None
    return body


@missions_api.route("/routes", methods=["GET"])
def list_routes():
    return jsonify({"routes": [_shown(r) for r in _extension("store").routes()]})


@missions_api.route("/routes/<waypoint:name>", methods=["GET"])
def get_route(name):
    return jsonify(_shown(_extension("store").get_route(check_route_name(name))))


@missions_api.route("/routes/<waypoint:name>", methods=["PUT"])
def put_route(name):
    route = make_route(check_route_name(name), json_object(FIELDS))
    created = _extension("store").put_route(route)
    return jsonify({"status": "ok", "created": created, "route": _shown(route)}), 201 if created else 200


@missions_api.route("/routes/<waypoint:name>", methods=["DELETE"])
def delete_route(name):
    _extension("store").delete_route(check_route_name(name))
    return "", 204


@missions_api.route("/runs", methods=["POST"])
def start_run():
    data = json_object(RUN_FIELDS)
    check_deadline(data, "This run")
    data.pop(FIELD, None)
    if "route" in data:
        if len(data) > 1:
            raise BadRequest("Give either a route's name, {\"route\": \"rounds\"}, or an unnamed route's "
                             "\"waypoints\" (with \"loops\", \"dwell\", \"on_failure\"), not both.")
        route = _extension("store").get_route(check_route_name(text(data, "route")))
    else:
        route = make_route(None, data, scheduled=False)
    return jsonify({"status": "ok", "run": _runs().start(route, "api")}), 202


@missions_api.route("/runs", methods=["GET"])
def list_runs():
    return jsonify({"runs": _runs().runs()})


@missions_api.route("/runs/<int:run_id>", methods=["GET"])
def get_run(run_id):
    return jsonify(_runs().get(run_id))


def _run_action(action):
    def view(run_id):
        json_object((), required=False)
        return jsonify(getattr(_runs(), action)(run_id))

    view.__name__ = action + "_run"
    return view


for _action in ("pause", "resume", "skip", "cancel"):
    missions_api.add_url_rule("/runs/<int:run_id>/" + _action, view_func=_run_action(_action), methods=["POST"])
