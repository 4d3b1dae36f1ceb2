"""Zones over HTTP: where the robot must not go on the active map (docs/zones.md).

``GET /zones`` lists them; ``PUT /zones/<name>`` adds or replaces one (``{"kind": "keepout",
"polygon": [[x, y], ...]}`` or ``{"kind": "wall", "line": [[x, y], ...]}``, ``"enabled"``
optional, true); ``PATCH /zones/<name>`` with ``{"enabled": false}`` switches it off (or on), and
``{"name": "new"}`` renames it; ``DELETE`` removes it. Each change is saved in the map's waypoints
file before it is answered and told as a ``zone`` event. A zone whose corners lie off the map
in use is refused (400 ``bad_zone``), as is one that would cover the map's dock.
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server.core.errors import BadRequest, BadZone, NoMap, WaypointExists, shown
from flask_move_server.web.body import json_object, text
from flask_move_server.zones import KINDS, check_zone_name, make_zone

zones_api = Blueprint("zones", __name__)

EDGE = 1.0  # m: a corner may lie this far past the map's edge (a zone drawn to the very border)


def _parts():
    return current_app.extensions["flask_move_server"]


@zones_api.route("/zones", methods=["GET"])
def list_zones():
    return jsonify({"zones": [_shown(zone) for zone in _parts()["store"].zones()]})


@zones_api.route("/zones/<waypoint:name>", methods=["GET"])
def get_zone(name):
    return jsonify(_shown(_parts()["store"].get_zone(name)))


@zones_api.route("/zones/<waypoint:name>", methods=["PUT"])
def put_zone(name):
    data = json_object(("kind", "polygon", "line", "enabled"))
    zone = make_zone(name, data)
    _check_on_map(zone)
    _check_dock(zone)
    created = _parts()["store"].put_zone(zone)
    _tell(zone.name, zone)
    return jsonify({"status": "ok", "created": created, "zone": _shown(zone)}), 201 if created else 200


@zones_api.route("/zones/<waypoint:name>", methods=["PATCH"])
def patch_zone(name):
    data = json_object(("enabled", "name"))
    if not data:
        raise BadRequest('Say what to change: {"enabled": false} (the robot may go there) or {"name": "new name"}.')
    store = _parts()["store"]
    zone = store.get_zone(name)
    if "enabled" in data:
        if not isinstance(data["enabled"], bool):
            raise BadZone("enabled must be true or false.")
        if data["enabled"]:
            _check_dock(zone.switched(True))
        zone = store.switch_zone(zone.name, data["enabled"])
    if "name" in data:
        zone = _rename(store, zone, check_zone_name(text(data, "name")))
    _tell(zone.name, zone)
    return jsonify({"status": "ok", "zone": _shown(zone)})


@zones_api.route("/zones/<waypoint:name>", methods=["DELETE"])
def delete_zone(name):
    store = _parts()["store"]
    zone = store.get_zone(name)
    store.delete_zone(zone.name)
    _tell(zone.name, None)
    return "", 204


def _rename(store, zone, new):
    if new == zone.name:
        return zone
    if new in {z.name for z in store.zones()}:
        raise WaypointExists("A zone named {} exists already; pick another name.".format(shown(new)))
    renamed = zone.renamed(new)
    store.put_zone(renamed)
    store.delete_zone(zone.name)
    _tell(zone.name, None)
    return renamed


def _shown(zone):
    """The zone's JSON; ``"waiting": true`` while the robot stands in it (kept out again once it has left)."""
    shown_zone = {"name": zone.name}
    shown_zone.update(zone.as_dict())
    guard = getattr(_parts()["robot"], "zones", None)
    shown_zone["waiting"] = guard is not None and zone.enabled and zone.name in guard.held
    return shown_zone


def _tell(name, zone):
    _parts()["events"].publish("zone", {"name": name, "zone": _shown(zone) if zone is not None else None})


def _check_on_map(zone):
    """BadZone when a corner of ``zone`` lies off the map in use (none published: nothing to check)."""
    source = getattr(_parts()["maps"], "source", None)
    if source is None:
        return
    try:
        _, grid = source.current()
    except NoMap:
        return
    low_x, low_y = grid.origin_x - EDGE, grid.origin_y - EDGE
    high_x = grid.origin_x + grid.width * grid.resolution + EDGE
    high_y = grid.origin_y + grid.height * grid.resolution + EDGE
    field = KINDS[zone.kind]
    for i, (x, y) in enumerate(zone.points):
        if not (low_x <= x <= high_x and low_y <= y <= high_y):
            raise BadZone("{}[{}] ({:.2f}, {:.2f}) lies off the map in use, which spans x {:.2f} to {:.2f} and y "
                          "{:.2f} to {:.2f}.".format(field, i, x, y, low_x + EDGE, high_x - EDGE, low_y + EDGE,
                                                      high_y - EDGE))


def _check_dock(zone):
    """BadZone when an enabled ``zone`` would keep the robot off its own charger."""
    robot = _parts()["robot"]
    dock = _parts()["store"].dock()
    if dock is None or not zone.enabled or getattr(robot, "zones", None) is None:
        return
    if robot.zones.blocks(zone, dock.x, dock.y):
        raise BadZone("The zone {} would cover the dock ({}): the robot could never go home. Draw it away from "
                      "the charger.".format(shown(zone.name), shown(dock.name)))
