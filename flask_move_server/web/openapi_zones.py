"""``/zones`` in the OpenAPI description (docs/zones.md): a map's no-go zones and virtual walls."""

from flask_move_server.web.openapi_schema import _json, _name, _object, _ok, _operation
from flask_move_server.zones import COORDINATE_LIMIT, MAX_POINTS


def _points(least, what):
    point = {"type": "array", "items": {"type": "number", "minimum": -COORDINATE_LIMIT, "maximum": COORDINATE_LIMIT},
             "minItems": 2, "maxItems": 2}
    return {"type": "array", "items": point, "minItems": least, "maxItems": MAX_POINTS,
            "description": what + ", [x, y] in metres in the map's frame"}


def zone_schema():
    """What ``GET /zones`` shows of one zone."""
    return _object({"name": {"type": "string"}, "kind": {"enum": ["keepout", "wall"]},
                    "polygon": _points(3, "keepout: the corners, in order around it"),
                    "line": _points(2, "wall: the points of its line"),
                    "enabled": {"type": "boolean"},
                    "waiting": {"type": "boolean", "description": "the robot stands in it: it keeps the robot out "
                                                                  "again once the robot has left"}},
                   ["name", "kind", "enabled", "waiting"])


def paths():
    name = {"name": "name", "in": "path", "required": True, "schema": _name("the zone's name")}
    enabled = {"type": "boolean", "description": "false: today the robot may go there (default true)"}
    keepout = _object({"kind": {"enum": ["keepout"]}, "polygon": _points(3, "the corners"), "enabled": enabled},
                      ["kind", "polygon"])
    wall = _object({"kind": {"enum": ["wall"]}, "line": _points(2, "the line it never crosses"), "enabled": enabled},
                   ["kind", "line"])
    saved = _ok({"created": {"type": "boolean"}, "zone": zone_schema()})
    item = {
        "get": _operation("One zone", None, {200: _json(zone_schema())}, errors=(400, 404)),
        "put": _operation("Create or replace a zone (saved before the answer; a zone over the dock is refused)",
                          {"oneOf": [keepout, wall]},
                          {200: dict(saved, description="replaced"), 201: dict(saved, description="created")},
                          errors=(409, 503)),
        "patch": _operation("Switch a zone on or off, or rename it", _object({"enabled": {"type": "boolean"},
                                                                              "name": _name("the new name")}),
                            {200: _ok({"zone": zone_schema()})}, errors=(404, 409, 503)),
        "delete": _operation("Delete a zone (saved before the answer)", None, {204: {"description": "deleted"}},
                             errors=(400, 404, 503)),
    }
    for operation in item.values():
        operation["parameters"] = [name]
    return {"/zones": {"get": _operation("The active map's no-go zones and virtual walls", None, {200: _json(_object(
        {"zones": {"type": "array", "items": zone_schema()}}))})},
            "/zones/{name}": item}
