"""The OpenAPI 3 vocabulary ``GET /openapi.json`` is written in: operations, answers, schemas.

An operation (``_operation``) carries the answers every operation can give (401 unless
``_open``, 403; 400 and 413 when it reads a body) as references to the shared error answers of
``_components`` (the one error shape, each status with the codes in ``ERROR_CODES``). The
helpers keep their short underscore names: they are web/openapi.py's vocabulary, used by it
alone, which holds the API's paths. Pure: no Flask.
"""

ERROR_CODES = {
    400: "bad_request, bad_waypoint, bad_map_name, bad_route: a malformed body, field, name, coordinate or route",
    401: "unauthorized: the token is missing or wrong (a token is configured)",
    403: "unknown_host, forbidden_origin: a name the robot does not have, or another site's web page",
    404: "unknown_waypoint (with suggestions), unknown_map, unknown_route, unknown_run, no_map, not_found: no such "
         "waypoint, map, route, run or endpoint",
    405: "method_not_allowed: the path takes other methods (the Allow header lists them)",
    409: "navigation_failed (with state), no_pose, command_late, estop_latched, estop_button_pressed, waypoints_file, "
         "wrong_mode, map_exists, map_in_use, map_configured, mode_switching, modes_off, waypoint_in_use, "
         "run_conflict, explore_conflict, not_stuck, pressed, map_full, no_dock, dock_failed, battery_critical",
    413: "body_too_large: the body is over server.max_body_bytes",
    503: "ros_unavailable, move_base_unavailable, drive_error, shutting_down, waypoints_locked, map_file, "
         "no_map_received, stack_failed, too_many_streams",
}


NO_FIELDS = {"type": "object", "maxProperties": 0}


def _operation(summary, body, answers, errors=(), body_optional=False):
    """One operation: its summary, JSON body schema (None: reads none), answers, the errors it can give.

    Every operation can answer 401 (a token is configured; :func:`_open` takes it away) and 403 (the
    Host/Origin guard); one that reads a body, 400 and 413. 405 belongs to the path, not an operation.
    """
    responses = {str(status): answer for status, answer in answers.items()}
    for status in sorted({401, 403, *errors} | ({400, 413} if body else set())):
        responses[str(status)] = {"$ref": "#/components/responses/E{}".format(status)}
    operation = {"summary": summary, "responses": responses}
    if body is not None:
        operation["requestBody"] = {"required": not body_optional,
                                    "content": {"application/json": {"schema": body}}}
    return operation


def _open(operation):
    """Served without a token, even when the robot has one."""
    operation["security"] = []
    operation["responses"].pop("401", None)
    return operation


def _components(max_body_bytes):
    error = _object({"status": {"enum": ["error"]}, "error": {"type": "string"}, "message": {"type": "string"},
                     "suggestions": {"type": "array", "items": {"type": "string"}},
                     "state": {"type": "string"}}, ["status", "error", "message"])
    responses = {"E{}".format(status): _json(_ref("Error"), text) for status, text in ERROR_CODES.items()}
    responses["E413"]["description"] += " ({} bytes here)".format(max_body_bytes)
    pose = _object({"x": {"type": "number"}, "y": {"type": "number"}, "yaw": {"type": "number"}}, ["x", "y", "yaw"])
    waypoint = _object(dict(pose["properties"], name={"type": "string"},
                            dock={"type": "boolean", "description": "present (true) on the map's dock"}),
                       ["name", "x", "y", "yaw"])
    estop = _object({"latched": {"type": "boolean"}, "source": {"type": "string", "nullable": True},
                     "since": {"type": "string", "nullable": True}})
    number = {"type": "number", "nullable": True}
    battery = _object({"percentage": dict(number, minimum=0, maximum=100, description="null: unknown"),
                       "voltage": dict(number, description="V; null: unknown"),
                       "charging": {"type": "boolean", "nullable": True,
                                    "description": "false when discharging, not charging or full; null: unknown"},
                       "age": {"type": "number", "minimum": 0, "description": "s since the reading was heard"}},
                      ["percentage", "voltage", "charging", "age"])
    stuck = _object({"state": {"enum": ["free", "stuck", "backing_out"]},
                     "message": {"type": "string", "nullable": True, "description": "where, what it does, what to do"},
                     "since": {"type": "string", "nullable": True}, "place": {"type": "string", "nullable": True},
                     "waiting": {"type": "boolean", "description": "stuck, and waiting for its owner: "
                                                                   "POST /stuck/back_out, or the joystick"},
                     "count": {"type": "integer", "description": "times it was stuck since the server started"},
                     "freed": {"type": "integer", "description": "times it backed out by itself and went on"}},
                    ["state", "message", "since", "place", "waiting", "count", "freed"])
    dock = _object({"state": {"enum": ["undocked", "going", "approaching", "docked", "charging", "undocking",
                                       "failed"]},
                    "place": {"type": "string", "nullable": True, "description": "the charger's place, while docking"},
                    "tries": {"type": "integer", "description": "tries onto the charger of this docking"},
                    "confirmed": {"type": "boolean", "description": "docked: the charger said it charges"},
                    "message": {"type": "string", "nullable": True, "description": "what it does, in words"}},
                   ["state", "place", "tries", "confirmed", "message"])
    return {
        "schemas": {"Error": error, "Pose": pose, "Waypoint": waypoint, "EStop": estop, "Battery": battery,
                    "Stuck": stuck, "Dock": dock},
        "responses": responses,
        "securitySchemes": {"bearer": {"type": "http", "scheme": "bearer",
                                       "description": "needed when the robot has a token"}},
    }


def _object(properties, required=()):
    schema = {"type": "object", "properties": properties, "additionalProperties": False}
    if required:
        schema["required"] = list(required)
    if not properties:  # an answer whose fields are described elsewhere (docs/api.md)
        schema["additionalProperties"] = True
    return schema


def _ok(fields):
    return _json(_object(dict({"status": {"enum": ["ok"]}}, **fields)))


def _json(schema, text="ok"):
    return {"description": text, "content": {"application/json": {"schema": schema}}}


def _name(text=None):
    """A name (flask_move_server.core.names): its ASCII characters exactly, any other as a letter, digit or '’' may be.

    A pattern cannot say "a letter of any language" everywhere (``\\p{L}`` is not in every regex
    dialect that reads it), so the description (names.RULE) says the rest, '..' and '.' alone too.
    """
    schema = {"type": "string", "pattern": r"^(?:[A-Za-z0-9_. '-]|[^\x00-\x7f]){1,64}$"}
    if text:
        schema["description"] = text
    return schema


def _coordinate(limit):
    return {"type": "number", "minimum": -limit, "maximum": limit}


def _ref(name):
    return {"$ref": "#/components/schemas/{}".format(name)}
