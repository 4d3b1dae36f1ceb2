"""``GET /openapi.json``: the HTTP API as an OpenAPI 3 description, built from the code's own limits.

docs/api.md is the API for people; this is the same for programs (code generators, API
explorers, the fuzz test). It is built from the config the app serves with, so the numbers in it
(body size, longest ``wait``, coordinate bounds, the name rule) are the ones this server applies,
and tests/test_openapi.py keeps its paths and methods equal to the app's routes. It needs no token,
like ``/health``: it describes the software, the same on every robot, and nothing of this one's
waypoints or state.
"""

from flask import Blueprint, current_app, jsonify

from flask_move_server import __version__
from flask_move_server.explore import exploration
from flask_move_server.maps.catalogue import MAP_NAME_RULE
from flask_move_server.missions import route as routes
from flask_move_server.missions import run as runs
from flask_move_server.modes.targets import MODES
from flask_move_server.waypoints import NAME_RULE, POSITION_LIMIT, YAW_LIMIT
from flask_move_server.web import explore, openapi_zones
from flask_move_server.web.openapi_schema import (
    NO_FIELDS,
    _components,
    _coordinate,
    _json,
    _name,
    _object,
    _ok,
    _open,
    _operation,
    _ref,
)

description = Blueprint("openapi", __name__)


@description.route("/openapi.json", methods=["GET"])
def openapi():
    return jsonify(build(current_app.extensions["flask_move_server"]["config"]))


def build(config):
    """The OpenAPI 3.0 document for an app serving with ``config``."""
    paths = {
        "/goto": {"post": _goto(config.navigation.max_wait)},
        "/stop": {"post": _operation("Cancel the goal, end teleop, command zero velocity", NO_FIELDS,
                                     {200: _ok({"canceled_goal": {"type": "boolean"}})}, body_optional=True)},
        "/teleop": {"post": _teleop()},
        "/estop": {"post": _estop("Latch the e-stop: stop everything, refuse goals and teleop", "engaged",
                                  body=False)},
        "/estop/release": {"post": _estop("Release the e-stop (moves nothing)", "released", body=True)},
        "/stuck/back_out": {"post": _operation(
            "A robot that said it is stuck and waits for its owner backs out by itself (docs/stuck.md)", NO_FIELDS,
            {202: _ok({"stuck": _ref("Stuck")})}, errors=(409,), body_optional=True)},
        "/dock": {"post": _dock(config.navigation.max_wait)},
        "/undock": {"post": _operation(
            "Back straight off the charger to the staging pose (docs/docking.md)",
            _object({"valid_until": VALID_UNTIL}),
            {202: _ok({"dock": _ref("Dock")})}, errors=(409, 503), body_optional=True)},
        "/waypoints": {"get": _operation("List the waypoints", None, {200: _json(_object(
            {"waypoints": {"type": "array", "items": _ref("Waypoint")}}))})},
        "/waypoints/{name}": _waypoint_item(),
        "/status": {"get": _operation("Pose, navigation, teleop, motors, e-stop, battery, ROS, waypoints file, MQTT",
                                      None, {200: _json(_status())})},
        "/health": {"get": _open(_operation("Is the server up, ROS connected, move_base ready?", None, {
            200: _json(_object({"status": {"enum": ["ok"]}, "ros": {"type": "string"},
                                "move_base": {"enum": ["ready", "unavailable"]},
                                "note": {"type": "string"}}, ["status", "ros", "move_base"]))}))},
        "/events": {"get": _events()},
        "/openapi.json": {"get": _open(_operation("This description", None, {200: _json({"type": "object"})}))},
    }
    paths.update(_maps(config))
    paths.update(_static_files())
    paths.update(_mode_paths(config))
    paths.update(_diagnostics())
    paths.update(_missions())
    paths.update(_explore())
    paths.update(openapi_zones.paths())
    if config.server.static:
        paths.update(_page())
    return {
        "openapi": "3.0.3",
        "info": {"title": "flask-move-server", "version": __version__,
                 "description": "Send a ROS 1 robot to named waypoints over HTTP. Read docs/api.md."},
        "paths": paths,
        "components": _components(config.server.max_body_bytes),
        "security": [{"bearer": []}, {}],
    }


VALID_UNTIL = {"type": "number", "description": "optional: a time on the robot's clock (GET /status 'clock', the "
                                              "event stream's clock events); read later than this, the command "
                                              "is refused with 409 command_late and nothing moves"}


def _goto(max_wait):
    wait = {"type": "number", "minimum": 0, "maximum": max_wait,
            "description": "seconds to wait for arrival before answering (at most navigation.max_wait)"}
    by_name = _object({"name": _name("a waypoint's name"), "wait": wait, "valid_until": VALID_UNTIL}, ["name"])
    by_pose = _object({"x": _coordinate(POSITION_LIMIT), "y": _coordinate(POSITION_LIMIT),
                       "yaw": _coordinate(YAW_LIMIT), "wait": wait, "valid_until": VALID_UNTIL}, ["x", "y"])
    answer = _object({"status": {"enum": ["ok"]}, "target": {"type": "string", "nullable": True},
                      "goal": _ref("Pose"), "goal_id": {"type": "integer"},
                      "navigation": {"type": "object", "description": "with wait: the goal's state"}})
    return _operation("Send the robot to a waypoint or a pose", {"oneOf": [by_name, by_pose]},
                      {200: _json(answer, "arrived (with wait)"), 202: _json(answer, "on its way")},
                      errors=(404, 409, 503))


def _dock(max_wait):
    wait = {"type": "number", "minimum": 0, "maximum": max_wait,
            "description": "seconds to wait until it is on the charger before answering (at most navigation.max_wait)"}
    answer = _ok({"dock": _ref("Dock")})
    return _operation("Home onto the map's charger (docs/docking.md)",
                      _object({"wait": wait, "valid_until": VALID_UNTIL}),
                      {200: _json(answer["content"]["application/json"]["schema"], "on the charger (with wait)"),
                       202: _json(answer["content"]["application/json"]["schema"], "on its way")},
                      errors=(409, 503), body_optional=True)


def _teleop():
    speed = {"type": "number", "description": "clamped to the configured limit"}
    body = _object({"linear": dict(speed, description="m/s, clamped to teleop.max_linear"),
                    "angular": dict(speed, description="rad/s, clamped to teleop.max_angular"),
                    "valid_until": VALID_UNTIL})
    answer = _ok({"linear": {"type": "number"}, "angular": {"type": "number"}, "hold": {"type": "number"},
                  "canceled_goal": {"type": "boolean"}})
    return _operation("Drive at a velocity for the deadman time", body, {200: answer}, errors=(409, 503))


def _estop(summary, flag, body):
    answer = _ok({flag: {"type": "boolean"}, "estop": _ref("EStop")})
    if not body:  # no body check: a stop is never refused for what came with it
        return _operation(summary, None, {200: answer})
    return _operation(summary, NO_FIELDS, {200: answer}, errors=(409,), body_optional=True)


def _waypoint_item():
    name = {"name": "name", "in": "path", "required": True, "description": NAME_RULE, "schema": _name()}
    dock = {"type": "boolean", "description": "true: this place is the map's dock (the charger; the one before "
                                                 "loses the role); false: it is no longer"}
    by_pose = _object({"x": _coordinate(POSITION_LIMIT), "y": _coordinate(POSITION_LIMIT),
                       "yaw": _coordinate(YAW_LIMIT), "dock": dock}, ["x", "y", "yaw"])
    from_robot = _object({"from": {"enum": ["current"]}, "dock": dock}, ["from"])
    role_only = _object({"dock": dock}, ["dock"])
    saved = _ok({"created": {"type": "boolean"}, "waypoint": _ref("Waypoint"),
                 "warning": {"type": "string", "description": "the place lies in an enabled zone: kept, but goals "
                                                             "there are refused (docs/zones.md)"}})
    item = {
        "get": _operation("One waypoint", None, {200: _json(_ref("Waypoint"))}, errors=(400, 404)),
        "put": _operation("Create or replace a waypoint (saved before the answer)",
                          {"oneOf": [by_pose, from_robot, role_only]},
                          {200: dict(saved, description="replaced"), 201: dict(saved, description="created")},
                          errors=(404, 409, 503)),
        "delete": _operation("Delete a waypoint (saved before the answer)", None,
                             {204: {"description": "deleted"}}, errors=(400, 404, 409, 503)),
        "patch": _operation("Rename a waypoint in one save; onto another's name only with overwrite",
                            _object({"name": _name("the new name"), "overwrite": {"type": "boolean"}}, ["name"]),
                            {200: _ok({"waypoint": _ref("Waypoint")})}, errors=(404, 409, 503)),
    }
    for operation in item.values():
        operation["parameters"] = [name]
    return item


def _mode_paths(config):
    """``/mode`` (read, switch) and ``/pose`` (set the robot's pose): docs/api.md "Maps and modes"."""
    localization = _object({"assumed": {"type": "boolean"},
                            "from": {"type": "string", "nullable": True, "description": "the waypoint (dock)"},
                            "since": {"type": "string", "format": "date-time", "nullable": True}},
                           ["assumed", "from", "since"])
    mode = _object({"mode": {"enum": list(MODES)}, "map": {"type": "string", "nullable": True},
                    "state": {"enum": ["starting", "running", "stopping", "failed"]},
                    "since": {"type": "string", "format": "date-time"}, "message": {"type": "string"},
                    "localization": dict(localization, description="the pose set by the server, unconfirmed")},
                   ["mode", "map", "state", "since", "message", "localization"])
    pose = _object({"x": _coordinate(POSITION_LIMIT), "y": _coordinate(POSITION_LIMIT),
                    "yaw": _coordinate(YAW_LIMIT)}, ["x", "y"])
    by_name = _object({"name": _name("a waypoint's name")}, ["name"])
    confirm = _object({"confirm": {"enum": [True], "description": "the pose localization holds is right"}},
                      ["confirm"])
    wait = {"type": "number", "minimum": 0, "maximum": config.modes.stop_timeout + config.modes.start_timeout,
            "description": "seconds to wait for the mode to run before answering"}
    switch = _object({"mode": {"enum": list(MODES)},
                      "map": _name("navigation: a saved map's name, or the configured map's (GET /maps "
                                   "\"source\": \"configured\"; none: that map too)"),
                      "pose": {"oneOf": [pose, by_name], "description": "navigation: where the robot is"},
                      "wait": wait}, ["mode"])
    switched = _json(dict(mode, properties=dict(mode["properties"], status={"enum": ["ok"]})))
    return {
        "/mode": {
            "get": _operation("The mode (idle, mapping, navigation), its map and its state", None,
                              {200: _json(mode)}),
            "post": _operation("Switch the mode: stop the running stack, start the mode's", switch,
                               {200: dict(switched, description="running (with wait)"),
                                202: dict(switched, description="switching")}, errors=(404, 409, 503)),
        },
        "/pose": {"post": _operation("Set the robot's pose for localization (RViz's 2D Pose Estimate), or confirm it",
                                     {"oneOf": [pose, by_name, confirm]},
                                     {200: _ok({"pose": _ref("Pose"), "name": {"type": "string"},
                                                "confirmed": {"enum": [True]}, "localization": localization})},
                                     errors=(404, 409, 503))},
    }


def _diagnostics():
    """``/diagnostics``: the first-boot doctor (docs/api.md, "Diagnostics")."""
    line = _object({"name": {"type": "string"}, "level": {"enum": ["pass", "warn", "fail", "skip"]},
                    "summary": {"type": "string"}, "advice": {"type": "string"}},
                   ["name", "level", "summary", "advice"])
    report = _object({"status": {"enum": ["pass", "warn", "fail"]}, "mode": {"type": "string", "nullable": True},
                      "window": {"type": "number"}, "at": {"type": "string"},
                      "checks": {"type": "array", "items": line}}, ["status", "checks"])
    operation = _operation("First-boot checks: lidar, tf, odometry, move_base, AMCL, the Pi's power, heat, "
                           "load, disk and clock", None, {200: _json(report)}, errors=(400, 409))
    operation["parameters"] = [
        {"name": "seconds", "in": "query", "required": False, "schema": {"type": "number", "minimum": 0.5,
         "maximum": 10}, "description": "how long to listen to /scan and /odom (default diagnostics.window)"},
        {"name": "box", "in": "query", "required": False, "schema": {"enum": ["0", "1"]},
         "description": "1: also the box-ahead test of the laser's yaw (a box about 1 m ahead, nothing nearer)"}]
    return {"/diagnostics": {"get": operation}}


def _missions():
    """``/routes`` and ``/runs`` (docs/routes.md): routes of the active map, runs of them."""
    fields = _route_fields()
    next_run = {"type": "string", "nullable": True, "description": "when the schedule starts a run next (local time)"}
    route = _object(dict(fields, name={"type": "string"}, next_run=next_run),
                    ["name", "waypoints", "loops", "dwell", "on_failure", "schedule", "next_run"])
    put = _object(fields, ["waypoints"])
    unnamed = _object({k: v for k, v in fields.items() if k != "schedule"}, ["waypoints"])
    unnamed["properties"]["valid_until"] = VALID_UNTIL
    named = _object({"route": _name("a route's name"), "valid_until": VALID_UNTIL}, ["route"])
    run = _run_schema()
    started = _ok({"run": run})
    action = {name: _with_run_id(_operation(summary, NO_FIELDS, {200: _json(run)}, errors=(404, 409),
                                            body_optional=True))
              for name, summary in (("pause", "Pause: the robot stops where it is"),
                                    ("resume", "Resume: the current waypoint is sent again"),
                                    ("skip", "Skip the current waypoint (noted as missed)"),
                                    ("cancel", "Cancel the run"))}
    paths = {
        "/routes": {"get": _operation("The active map's routes", None, {200: _json(_object(
            {"routes": {"type": "array", "items": route}}))})},
        "/routes/{name}": _route_item(route, put),
        "/runs": {"get": _operation("The runs kept, newest first (the last {})".format(50), None, {200: _json(
                      _object({"runs": {"type": "array", "items": run}}))}),
                  "post": _operation("Start a run of a route, or of an unnamed one", {"oneOf": [named, unnamed]},
                                     {202: started}, errors=(404, 409, 503))},
        "/runs/{run_id}": {"get": _with_run_id(_operation("One run", None, {200: _json(run)}, errors=(404,)))},
    }
    paths.update({"/runs/{run_id}/" + name: {"post": operation} for name, operation in action.items()})
    return paths


def _explore():
    """``/explore`` (docs/api.md, "Exploration"): map the flat by itself, come back, save the map."""
    exp = _object({
        "state": {"enum": [exploration.STARTING, exploration.EXPLORING, exploration.RETURNING, exploration.SAVING,
                           *exploration.ENDED]},
        "frontiers": {"type": "integer", "description": "reachable frontiers left"},
        "known_m2": {"type": "number", "description": "square metres of the map known (free or occupied)"},
        "goals": {"type": "integer", "description": "goals sent"},
        "unreachable": {"type": "integer", "description": "frontiers seen but unreachable"},
        "elapsed": {"type": "number", "description": "seconds since it started"},
        "map": {"type": "string", "nullable": True, "description": "the map's name once saved"},
        "message": {"type": "string"}, "save_as": {"type": "string"},
        "then": {"enum": list(exploration.THEN)}, "max_minutes": {"type": "number"},
        "return_home": {"type": "boolean"},
        "started": {"type": "string", "description": "when it started, the robot's local time (ISO 8601)"},
        "target": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2, "nullable": True,
                   "description": "[x, y] in the map frame: the frontier being driven to"}},
        ["state", "frontiers", "known_m2", "goals", "unreachable", "elapsed", "map", "message"])
    exp["additionalProperties"] = True  # more fields may come; docs/api.md lists those promised
    start = _object({"save_as": _name("the name to save the map as: " + MAP_NAME_RULE),
                     "then": {"enum": list(exploration.THEN), "description": "once saved: navigate on the map "
                                                                         "(default) or idle"},
                     "max_minutes": {"type": "number", "exclusiveMinimum": True, "minimum": 0,
                                     "maximum": exploration.MAX_MINUTES,
                                     "description": "stop looking after this long, then come back and save "
                                                    "(default {:g})".format(explore.DEFAULT_MINUTES)},
                     "return_home": {"type": "boolean", "description": "come back to where it started before "
                                                                       "saving (default true)"},
                     "overwrite": {"type": "boolean", "description": "replace a map saved as save_as"},
                     "valid_until": VALID_UNTIL}, ["save_as"])
    return {"/explore": {
        "get": _operation("The exploration under way, or the last one (null before the first)", None,
                          {200: _json(_object({"exploration": dict(exp, nullable=True)}))}),
        "post": _operation("Explore: map by itself (starting mapping if needed), come back, save the map, then "
                           "navigate on it", start, {202: _ok({"exploration": exp})},
                           errors=(409, 503)),
    }}


def _route_fields():
    return {"waypoints": {"type": "array", "minItems": 1, "maxItems": routes.MAX_WAYPOINTS, "items": _name(),
                          "description": "waypoint names of the active map, in the order to visit them"},
            "loops": {"type": "integer", "minimum": 0, "maximum": routes.MAX_LOOPS,
                      "description": "how many times to go round; 0: until stopped"},
            "dwell": {"type": "number", "minimum": 0, "maximum": routes.MAX_DWELL,
                      "description": "seconds to wait at each waypoint"},
            "on_failure": {"enum": list(routes.ON_FAILURE), "description": "a waypoint not reached: end the run "
                                                                          "(stop) or note it and go on (skip)"},
            "schedule": {"type": "array", "maxItems": routes.MAX_SCHEDULE, "items": {"type": "string"},
                         "description": "times to start a run, the robot's local time: \"21:30\", "
                                        "\"mon-fri 09:00\", \"sat,sun 10:15\""}}


def _route_item(route, put):
    name = {"name": "name", "in": "path", "required": True, "description": NAME_RULE, "schema": _name()}
    saved = _ok({"created": {"type": "boolean"}, "route": route})
    item = {
        "get": _operation("One route", None, {200: _json(route)}, errors=(400, 404)),
        "put": _operation("Create or replace a route (saved before the answer)", put,
                          {200: dict(saved, description="replaced"), 201: dict(saved, description="created")},
                          errors=(404, 409, 503)),
        "delete": _operation("Delete a route (saved before the answer)", None, {204: {"description": "deleted"}},
                             errors=(400, 404, 409, 503)),
    }
    for operation in item.values():
        operation["parameters"] = [name]
    return item


def _run_schema():
    stop = {"type": "object", "additionalProperties": True}
    return _object({"id": {"type": "integer"}, "route": {"type": "string", "nullable": True},
                    "waypoints": {"type": "array", "items": {"type": "string"}}, "loops": {"type": "integer"},
                    "dwell": {"type": "number"}, "on_failure": {"enum": list(routes.ON_FAILURE)},
                    "trigger": {"enum": list(runs.TRIGGERS)}, "state": {"enum": list(runs.STATES)},
                    "loop": {"type": "integer"}, "index": {"type": "integer"},
                    "current": {"type": "object", "nullable": True, "additionalProperties": True},
                    "visited": {"type": "array", "items": stop}, "missed": {"type": "array", "items": stop},
                    "started": {"type": "string"}, "ended": {"type": "string", "nullable": True},
                    "message": {"type": "string", "nullable": True}},
                   ["id", "route", "waypoints", "state", "loop", "index", "current", "visited", "missed"])


def _with_run_id(operation):
    operation["parameters"] = [{"name": "run_id", "in": "path", "required": True, "schema": {"type": "integer",
                                "minimum": 0}, "description": "the run's id (GET /runs)"}]
    return operation


def _maps(config):
    """``/map``, ``/map/image``, ``/maps`` and ``/maps/{name}`` (docs/api.md, "Maps")."""
    info = _map_info()
    live = _object({"version": {"type": "integer"}, "resolution": {"type": "number"},
                    "origin": {"type": "array", "items": {"type": "number"}}, "width": {"type": "integer"},
                    "height": {"type": "integer"}, "empty": {"type": "boolean"},
                    "mode": {"type": "string", "nullable": True}, "map": {"type": "string", "nullable": True}})
    save = _object({"name": _name("the new map's name"), "overwrite": {"type": "boolean"},
                    "then": {"enum": ["navigation"]},
                    "wait": {"type": "number", "minimum": 0,
                             "maximum": config.modes.stop_timeout + config.modes.start_timeout,
                             "description": "with then: seconds to wait for navigation on the map to run"}}, ["name"])
    saved = _json(_object({"status": {"enum": ["ok"]}, "map": info, "adopted_waypoints": {"type": "boolean"},
                           "mode": {"type": "object"}, "mode_error": {"type": "object"}}), "saved")
    listed = _object({"maps": {"type": "array", "items": info}, "active": {"type": "string", "nullable": True}})
    return {
        "/map": {"get": _operation("The map in use now: version, and the crop /map/image serves", None,
                                   {200: _json(live)}, errors=(404,))},
        "/map/image": {"get": _operation("The map in use now as a PNG (ETag; If-None-Match answers 304)", None,
                                         _PNG, errors=(404,))},
        "/maps": {"get": _operation("The saved maps, and the one in use", None, {200: _json(listed)}),
                  "post": _operation("Save the map being made (mapping mode only)", save, {201: saved},
                                     errors=(409, 503))},
        "/maps/{name}": _map_item(info),
        "/maps/{name}/image": {"get": _with_map_name(_operation(
            "A saved map's image, cropped to what is known", None, _PNG, errors=(400, 404, 503)))},
    }


def _map_info():
    return _object({"name": {"type": "string"}, "width": {"type": "integer", "nullable": True},
                    "height": {"type": "integer", "nullable": True},
                    "resolution": {"type": "number", "nullable": True},
                    "origin": {"type": "array", "items": {"type": "number"}, "nullable": True},
                    "modified": {"type": "string"}, "waypoints": {"type": "integer"},
                    "source": {"enum": ["saved", "configured"]},
                    "active": {"type": "boolean"}, "problem": {"type": "string"}})


def _map_item(info):
    item = {
        "get": _operation("One saved map", None, {200: _json(info)}, errors=(400, 404, 503)),
        "delete": _operation("Delete a saved map, its image and waypoints (not the one in use)", None,
                             {204: {"description": "deleted"}}, errors=(400, 404, 409, 503)),
        "patch": _operation("Rename a saved map with its waypoints (not the one in use)",
                            _object({"name": _name("the new name")}, ["name"]),
                            {200: _ok({"map": info})}, errors=(404, 409, 503)),
    }
    return {method: _with_map_name(operation) for method, operation in item.items()}


def _with_map_name(operation):
    operation["parameters"] = [{"name": "name", "in": "path", "required": True, "schema": _name(),
                                "description": "a map's name: " + MAP_NAME_RULE}]
    return operation


_PNG = {200: {"description": "a greyscale PNG, ETag = the map's version",
              "content": {"image/png": {"schema": {"type": "string", "format": "binary"}}}},
        304: {"description": "not modified: the If-None-Match ETag is the map's version"}}


def _status():
    """``GET /status``: the battery and the stuck state described here, the other fields in docs/api.md."""
    schema = _object({}, ["pose", "navigation", "teleop", "motors", "estop", "battery"])
    schema["properties"] = {"battery": {"allOf": [_ref("Battery")], "nullable": True,
                                        "description": "null until a sensor_msgs/BatteryState was heard"},
                            "stuck": {"allOf": [_ref("Stuck")], "nullable": True,
                                      "description": "null with stuck.enabled false"},
                            "dock": _ref("Dock")}
    return schema


def _events():
    stream = {"description": "Server-Sent Events: 'event: <kind>' (pose, status, estop, battery, stuck, dock, plan, "
                             "scan, mode, map, waypoints, run, explore, clock) and 'data: <one JSON object>', the "
                             "latest of each kind first; a clock event every 2 s. docs/api.md lists each kind's "
                             "fields.",
              "content": {"text/event-stream": {"schema": {"type": "string"}}}}
    return _operation("The robot's state as it changes (Server-Sent Events)", None, {200: stream}, errors=(503,))


def _page():
    html = {200: {"description": "the phone page", "content": {"text/html": {"schema": {"type": "string"}}}}}
    return {"/": {"get": _open(_operation("The phone page", None, html))}}


def _static_files():
    """Flask serves the package's static folder whether or not ``server.static`` adds the page at ``/``."""
    filename = {"name": "filename", "in": "path", "required": True, "schema": {"type": "string"}}
    static = _operation("The phone page's files", None, {200: {"description": "the file"}}, errors=(404,))
    static["parameters"] = [filename]
    return {"/static/{filename}": {"get": _open(static)}}




















