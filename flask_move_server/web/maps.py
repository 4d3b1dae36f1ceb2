"""Maps over HTTP: the map in use (``/map``, ``/map/image``) and the maps folder (``/maps``).

Routes validate, call the :class:`~flask_move_server.maps.service.MapService`
found in ``app.extensions["flask_move_server"]["maps"]`` and shape the answer;
they know nothing of rospy. Images are PNGs with an ``ETag`` (the map's version)
and ``Cache-Control: no-cache``: a browser asks again each time and gets a 304
without a byte of image while the map is unchanged.
"""

from flask import Blueprint, Response, current_app, jsonify, request

from flask_move_server.core.errors import BadRequest, NoMap, NoPose, StackFailed
from flask_move_server.web.body import json_object, number, text
from flask_move_server.web.modes import longest_wait

maps_api = Blueprint("maps", __name__)

THEN = ("navigation",)


def _maps():
    service = current_app.extensions["flask_move_server"].get("maps")
    if service is None:
        raise NoMap("This server has no maps folder configured.")
    return service


def _png(etag, make_image):
    """The image answer: 304 when the client has ``etag`` already (nothing rendered), else the PNG."""
    if request.if_none_match.contains_weak(etag):  # If-None-Match compares weakly (RFC 9110)
        response = Response(status=304)
    else:
        response = Response(make_image().png, mimetype="image/png")
    response.set_etag(etag)
    response.headers["Cache-Control"] = "no-cache"
    return response


@maps_api.route("/map", methods=["GET"])
def live_map():
    return jsonify(_maps().live_metadata())


@maps_api.route("/map/image", methods=["GET"])
def live_image():
    service = _maps()
    return _png(service.live_etag(), lambda: service.live_image()[1])


@maps_api.route("/maps", methods=["GET"])
def list_maps():
    return jsonify(_maps().list())


@maps_api.route("/maps", methods=["POST"])
def save_map():
    data = json_object(("name", "overwrite", "then", "wait"))
    name = text(data, "name")
    overwrite = data.get("overwrite", False)
    if not isinstance(overwrite, bool):
        raise BadRequest("Field 'overwrite' must be true or false.")
    then = data.get("then")
    if then is not None and then not in THEN:
        raise BadRequest("Field 'then' can only be \"navigation\" (switch to the saved map).")
    wait = _switch_wait(data, then)
    body = _maps().save(name, overwrite=overwrite, then=then, here=_pose_if_known() if then else None)
    if wait is not None and "mode" in body:
        body["mode"] = _switched(wait)
    return jsonify(body), 201


def _switch_wait(data, then):
    """The seconds ``wait`` gives the switch to the saved map to run (None: answer at once)."""
    if "wait" not in data:
        return None
    if then is None:
        raise BadRequest("Field 'wait' waits for the switch to the saved map: send it with \"then\": \"navigation\".")
    return number(data, "wait", 0, longest_wait(current_app.extensions["flask_move_server"]["config"]))


def _switched(wait):
    """The mode once the switch runs, failed, or ``wait`` seconds passed (the map is saved whatever it says)."""
    modes = _maps().modes
    try:
        modes.wait(wait)
    except StackFailed:
        pass  # the mode says failed, and why
    return modes.status()


def _pose_if_known():
    """The robot's pose now, or None when it is not known (the switch then uses the map's dock)."""
    try:
        return current_app.extensions["flask_move_server"]["robot"].current_pose()
    except NoPose:
        return None


@maps_api.route("/maps/<waypoint:name>", methods=["GET"])
def describe_map(name):
    return jsonify(_maps().describe(name))


@maps_api.route("/maps/<waypoint:name>", methods=["DELETE"])
def delete_map(name):
    _maps().delete(name)
    return "", 204


@maps_api.route("/maps/<waypoint:name>", methods=["PATCH"])
def rename_map(name):
    data = json_object(("name",))
    return jsonify({"status": "ok", "map": _maps().rename(name, text(data, "name"))})


@maps_api.route("/maps/<waypoint:name>/image", methods=["GET"])
def saved_image(name):
    service = _maps()
    return _png(service.saved_etag(name), lambda: service.saved_image(name)[1])
