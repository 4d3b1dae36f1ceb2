"""``GET /openapi.json`` tells the truth: every route of the app is in it, nothing else is."""

import os
import re

import pytest

from flask_move_server.core import errors
from flask_move_server.waypoints import NAME_RULE
from flask_move_server.web import create_app
from tests.conftest import ROOT
from tests.fake_robot import FakeRobot

AUTOMATIC = {"HEAD", "OPTIONS"}  # werkzeug answers these on every route by itself


def _routes(app):
    """``{(path, method)}`` of the app's url_map, in OpenAPI's spelling: ``<waypoint:name>`` -> ``{name}``."""
    found = set()
    for rule in app.url_map.iter_rules():
        path = re.sub(r"<(?:[^:<>]+:)?([^<>]+)>", r"{\1}", rule.rule)
        found.update((path, method.lower()) for method in rule.methods - AUTOMATIC)
    return found


def _described(document):
    return {(path, method) for path, operations in document["paths"].items() for method in operations}


@pytest.mark.parametrize("static", [True, False], ids=["with the page", "without the page"])
def test_the_description_lists_exactly_the_apps_routes(robot_config, store, static):
    robot_config.server.static = static
    app = create_app(robot_config, FakeRobot(), store)
    document = app.test_client().get("/openapi.json").get_json()
    assert _described(document) == _routes(app)
    assert ("/", "get") in _described(document) if static else ("/", "get") not in _described(document)


def test_it_says_this_servers_limits(robot_config, store):
    robot_config.server.max_body_bytes = 1234
    robot_config.navigation.max_wait = 42.0
    document = create_app(robot_config, FakeRobot(), store).test_client().get("/openapi.json").get_json()
    assert document["openapi"] == "3.0.3"
    assert "1234 bytes" in document["components"]["responses"]["E413"]["description"]
    by_name = document["paths"]["/goto"]["post"]["requestBody"]["content"]["application/json"]["schema"]["oneOf"][0]
    assert by_name["properties"]["wait"]["maximum"] == 42.0
    name = document["paths"]["/waypoints/{name}"]["put"]["parameters"][0]
    assert name["description"] == NAME_RULE


def test_only_the_open_endpoints_are_described_as_open(robot_config, store):
    document = create_app(robot_config, FakeRobot(), store).test_client().get("/openapi.json").get_json()
    open_ones = {(path, method) for path, operations in document["paths"].items()
                 for method, operation in operations.items() if operation.get("security") == []}
    assert open_ones == {("/health", "get"), ("/openapi.json", "get"), ("/", "get"), ("/static/{filename}", "get")}


def test_a_route_missing_from_the_description_is_found(robot_config, store):
    app = create_app(robot_config, FakeRobot(), store)
    app.add_url_rule("/undocumented/<int:n>", "undocumented", lambda n: "", methods=["PATCH"])
    document = app.test_client().get("/openapi.json").get_json()
    assert _routes(app) - _described(document) == {("/undocumented/{n}", "patch")}


# Errors that never reach HTTP: bad config (exit status 2), robotctl's own, the simulator's planner.
NOT_ON_THE_WIRE = {"bad_config", "client_error", "planning_failed", "error"}


def _all_codes(cls=errors.MoveServerError):
    return {cls.code}.union(*(_all_codes(sub) for sub in cls.__subclasses__()))


def test_docs_api_md_names_every_endpoint_and_every_error_code(robot_config, store):
    with open(os.path.join(ROOT, "docs", "api.md"), encoding="utf-8") as f:
        reference = f.read()
    document = create_app(robot_config, FakeRobot(), store).test_client().get("/openapi.json").get_json()
    for path, method in _described(document):
        spelled = re.sub(r"{(\w+)}", r"<\1>", path).replace("<filename>", "<file>")
        assert "{} {}".format(method.upper(), spelled) in reference or spelled + "`" in reference, (method, path)
    missing = {code for code in _all_codes() - NOT_ON_THE_WIRE if "| `{}` |".format(code) not in reference}
    assert not missing, "error codes without a row in docs/api.md's table: {}".format(sorted(missing))
