"""The web layer without ROS: validation, auth and error shapes, against a fake robot.

Every answer here comes from the Flask app (parsing, checks, the token, the JSON errors), so the
robot behind it is tests/fake_robot.py and these run in milliseconds; what ROS does with a
request is tests/test_api.py's, on the real robot. The waypoint store is the real one, on a
temporary file.
"""

import http.client

import pytest
import requests

from flask_move_server.web import create_app
from tests.conftest import serve
from tests.fake_robot import FakeRobot
from tests.robot_fixtures import SEED


@pytest.fixture
def robot():
    """The fake robot in place of the real one: the app, client and store fixtures build on it."""
    return FakeRobot()


# -- waypoints ---------------------------------------------------------------------------------


def test_waypoints_list_get_put_delete(client, robot_config):
    path = robot_config.waypoints.file
    assert [w["name"] for w in client.get("/waypoints").get_json()["waypoints"]] == ["kitchen", "office", "dock"]
    assert client.get("/waypoints/office").get_json() == {"name": "office", "x": 5.67, "y": 2.34, "yaw": -1.57}
    r = client.put("/waypoints/living room", json={"x": 1, "y": 2, "yaw": 0.5})
    assert r.status_code == 201 and r.get_json()["created"] is True
    assert '"living room": [1.0, 2.0, 0.5]' in open(path).read()  # saved before the response
    r = client.put("/waypoints/living room", json={"x": 3, "y": 2, "yaw": 0.5})
    assert r.status_code == 200 and r.get_json()["created"] is False
    assert client.delete("/waypoints/office").status_code == 204
    assert "office" not in open(path).read()
    assert client.get("/waypoints/office").status_code == 404


# -- bad input: always a 4xx JSON error, never a 500 or HTML, the file untouched ---------------

BAD = [
    ("post", "/goto", b"{not json", 400),
    ("post", "/goto", b"", 400),
    ("post", "/goto", b"[1, 2]", 400),
    ("post", "/goto", b'"kitchen"', 400),
    ("post", "/goto", b'{"name": 5}', 400),
    ("post", "/goto", b'{"name": null}', 400),
    ("post", "/goto", b'{"x": NaN, "y": 0}', 400),
    ("post", "/goto", b'{"x": Infinity, "y": 0}', 400),
    ("post", "/goto", b'{"x": 1e999, "y": 0}', 400),
    ("post", "/goto", b'{"x": "1", "y": 0}', 400),
    ("post", "/goto", b'{"x": true, "y": 0}', 400),
    ("post", "/goto", b'{"x": 1}', 400),
    ("post", "/goto", b'{"name": "kitchen", "x": 1}', 400),
    ("post", "/goto", b'{"nmae": "kitchen"}', 400),
    ("post", "/goto", b'{"name": "kitchen", "wait": -1}', 400),
    ("post", "/goto", b'{"name": "a/b"}', 400),
    ("post", "/goto", b'{"name": ".."}', 400),
    ("post", "/goto", b'{"name": "bell\\u0007"}', 400),
    ("post", "/goto", ('{"name": "%s"}' % ("x" * 300)).encode(), 400),
    ("post", "/goto", b"\xff\xfe", 400),
    ("post", "/goto", b"[" * 5000 + b"]" * 5000, 400),
    ("post", "/goto", b'{"a":' * 2000 + b"1" + b"}" * 2000, 400),
    ("post", "/goto", b'{"name": "' + b"x" * 20000 + b'"}', 413),
    ("post", "/goto", b'{"x": 1e308, "y": 0}', 400),
    ("post", "/goto", b'{"x": 0, "y": -1000001}', 400),
    ("post", "/goto", b'{"x": 0, "y": 0, "yaw": 1e300}', 400),
    ("post", "/goto", b'{"x": 1' + b"0" * 400 + b', "y": 0}', 400),
    ("post", "/goto", b'{"name": "dock", "name": "kitchen"}', 400),
    ("post", "/teleop", b'{"linear": "fast"}', 400),
    ("post", "/teleop", b'{"linear": 0.1, "linear": 5}', 400),
    ("post", "/teleop", b'{"linear": NaN}', 400),
    ("post", "/teleop", b'{"speed": 1}', 400),
    ("post", "/stop", b"{oops", 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": NaN}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": -Infinity}', 400),
    ("put", "/waypoints/ok", b'{"x": [1], "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b'{"x": 1e308, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": -1001}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": 0, "x": 5}', 400),
    ("put", "/waypoints/ok", b'{"from": "yesterday"}', 400),
    ("put", "/waypoints/ok", b'{"from": "current", "x": 1}', 400),
    ("put", "/waypoints/a%2Fb", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/a/b", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/..", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/a..b", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/tab%09", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/nul%00", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/new%0Aline", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/.", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("get", "/waypoints/new%0Aline", None, 400),
    ("delete", "/waypoints/line%0A", None, 400),
    ("put", "/waypoints/" + "x" * 300, b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/%20lead", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b"[" * 5000 + b"]" * 5000, 400),
    ("delete", "/waypoints/nope", None, 404),
    ("delete", "/waypoints/a%2F..%2Fb", None, 400),
    ("get", "/waypoints/" + "y" * 65, None, 400),
    ("get", "/goto", None, 405),
    ("delete", "/status", None, 405),
    ("get", "/no/such/endpoint", None, 404),
]


def _case_id(case):
    method, path, body, status = case
    shown = (body or b"")[:24].decode("utf-8", "replace")
    return "{} {} {}{} -> {}".format(method, path[:30], shown, "..." if body and len(body) > 24 else "", status)


@pytest.mark.parametrize("method,path,body,status", BAD, ids=[_case_id(c) for c in BAD])
def test_bad_input_is_a_json_4xx_and_changes_nothing(client, robot, robot_config, method, path, body, status):
    r = getattr(client, method)(path, data=body, content_type="application/json")
    assert r.status_code == status, r.get_data(as_text=True)[:300]
    assert r.is_json, r.get_data(as_text=True)[:300]
    err = r.get_json()
    assert err["status"] == "error" and err["error"] and len(err["message"]) > 10
    assert open(robot_config.waypoints.file).read() == SEED
    assert client.get("/status").get_json()["navigation"]["state"] == "idle"
    assert robot.moved() == []


def test_an_unknown_path_answers_with_the_paths_the_api_has(client):
    message = client.get("/gooto").get_json()["message"]
    assert message.startswith("No such endpoint: /gooto. The API has ")
    for path in ("/goto", "/stop", "/waypoints", "/mode", "/maps", "/map", "/pose", "/estop", "/events"):
        assert path + "," in message or path + " (" in message
    assert "/static" not in message
    long = client.get("/" + "x" * 5000).get_json()["message"]
    assert len(long) < 400 and "/" + "x" * 79 + "…. " in long  # a long path is not echoed whole


def test_a_trailing_slash_is_pointed_out_and_changes_nothing(client, robot):
    answer = client.post("/goto/", json={"name": "kitchen"})
    assert answer.status_code == 404
    assert answer.get_json()["message"] == "No such endpoint: /goto/. Did you mean /goto (no slash at the end)?"
    assert robot.moved() == []
    assert "Did you mean /status " in client.get("/status//").get_json()["message"]
    assert "Did you mean" not in client.get("/goto/").get_json()["message"]  # /goto takes POST, not GET


def test_a_body_that_is_not_json_shows_what_to_send(client):
    message = client.post("/goto", data="name=kitchen").get_json()["message"]
    assert message.startswith("The body is not valid JSON (") and message.endswith('e.g. {"name": "kitchen"}.')


def test_a_control_character_in_a_url_name_is_a_bad_name_not_a_missing_endpoint(client):
    r = client.put("/waypoints/kitchen%0Adoor", json={"x": 1, "y": 2, "yaw": 0})
    assert r.status_code == 400 and r.get_json()["error"] == "bad_waypoint"
    assert "kitchen\\ndoor" in r.get_json()["message"] and "letters, digits" in r.get_json()["message"]


@pytest.mark.parametrize("method", ["GET", "PUT", "DELETE"])
def test_a_doubled_slash_is_a_bad_name_not_an_html_redirect(client, method):
    """/waypoints//kitchen: werkzeug would answer 308 with an HTML page, and a client following it re-sends."""
    r = client.open("/waypoints//kitchen", method=method, json={"x": 1.0, "y": 1.0, "yaw": 0.0})
    assert r.status_code == 400 and r.is_json, (r.status_code, r.get_data(as_text=True)[:80])
    assert r.get_json()["error"] == "bad_waypoint"


def test_a_field_an_endpoint_does_not_take_is_named_plainly(client):
    r = client.post("/stop", json={"a": 1})
    assert r.status_code == 400 and r.get_json()["message"] == 'Unknown field "a" (this endpoint takes no fields).'


def test_dot_is_not_a_name_a_client_could_delete(client):
    r = client.put("/waypoints/.", json={"x": 1, "y": 2, "yaw": 0})
    assert r.status_code == 400 and "not '.' alone" in r.get_json()["message"]
    assert client.post("/goto", json={"name": "."}).status_code == 400


def test_a_field_given_twice_is_refused_naming_it(client):
    r = client.put("/waypoints/ok", data=b'{"x": 1, "y": 2, "yaw": 0, "y": 2000}')
    assert r.status_code == 400 and r.get_json()["error"] == "bad_request"
    assert r.get_json()["message"] == 'The field "y" appears twice in the body; send each field once.'


def test_coordinates_beyond_the_bound_are_refused_saying_the_bound(client):
    r = client.post("/goto", json={"x": 1e308, "y": 0})
    assert r.status_code == 400
    assert r.get_json()["message"] == "x must be between -1000000 and 1000000, got 1e+308."
    r = client.put("/waypoints/far", json={"x": 0, "y": 0, "yaw": 5000})
    assert r.status_code == 400 and "between -1000 and 1000" in r.get_json()["message"]
    r = client.put("/waypoints/edge", json={"x": 1e6, "y": -1e6, "yaw": -1000})
    assert r.status_code == 201


def test_a_wrong_method_names_the_right_one(client):
    r = client.get("/goto")
    assert r.status_code == 405 and r.get_json()["message"] == "/goto takes POST, not GET."
    assert "POST" in r.headers["Allow"]


def test_any_content_type_is_read_as_json(client, robot):
    for ctype in (None, "application/x-www-form-urlencoded", "text/plain"):
        r = client.post("/goto", data='{"name":"dock"}', content_type=ctype)
        assert r.status_code == 202, ctype
    assert [call[1].target for call in robot.moved()] == ["dock"] * 3


# -- auth --------------------------------------------------------------------------------------

ROUTES = [
    ("post", "/goto", {"name": "dock"}),
    ("post", "/stop", None),
    ("post", "/teleop", {"linear": 0.1}),
    ("get", "/waypoints", None),
    ("get", "/waypoints/dock", None),
    ("put", "/waypoints/new", {"x": 1, "y": 1, "yaw": 0}),
    ("delete", "/waypoints/dock", None),
    ("get", "/status", None),
]


@pytest.fixture
def token_client(robot_config, robot, store):
    return create_app(robot_config, robot, store, token="s3cret").test_client()


@pytest.mark.parametrize("method,path,body", ROUTES)
def test_every_route_needs_the_token(token_client, robot_config, method, path, body):
    for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": "s3cret"},
                    {"Authorization": "Basic czNjcmV0"}):
        r = getattr(token_client, method)(path, json=body, headers=headers)
        assert r.status_code == 401 and r.get_json()["error"] == "unauthorized"
        assert r.headers["WWW-Authenticate"].startswith("Bearer")
    assert open(robot_config.waypoints.file).read() == SEED
    r = getattr(token_client, method)(path, json=body, headers={"Authorization": "Bearer s3cret"})
    assert r.status_code != 401


def test_the_scheme_is_any_case_spaces_around_the_token_do_not_count_the_token_itself_is_exact(token_client):
    """As docs/api.md says (issue 34, item 10): RFC 7235's schemes are case-insensitive; a client
    adding a space or a newline after the token (an `echo` into a file) is let in; a token that
    differs in one letter's case is not."""
    for header in ("bearer s3cret", "BEARER s3cret", "Bearer s3cret ", "Bearer  s3cret"):
        assert token_client.get("/status", headers={"Authorization": header}).status_code == 200, header
    for header in ("Bearer S3cret", "Bearer s3cret x", "Bearers3cret", "Bearer"):
        assert token_client.get("/status", headers={"Authorization": header}).status_code == 401, header


def test_health_the_page_and_the_api_description_need_no_token(token_client):
    assert token_client.get("/health").status_code == 200
    assert token_client.get("/").status_code == 200
    assert token_client.get("/openapi.json").get_json()["openapi"].startswith("3.")


def test_a_configured_token_with_a_trailing_newline_is_the_token_over_http(robot_config, robot, store):
    robot_config.server.token = "s3cret\n"  # as pasted from a file: the newline is not the secret
    app = create_app(robot_config, robot, store, token=robot_config.resolved_token())
    with serve(app) as url:
        assert requests.get(url + "/waypoints", headers={"Authorization": "Bearer s3cret"}, timeout=10).ok
        r = requests.get(url + "/waypoints", headers={"Authorization": "Bearer s3cre"}, timeout=10)
        assert r.status_code == 401


def test_empty_answers_carry_no_html_type(app):
    with serve(app) as url:
        for method, path in (("OPTIONS", "/goto"), ("OPTIONS", "/waypoints/dock"), ("DELETE", "/waypoints/dock")):
            conn = http.client.HTTPConnection(url[len("http://"):], timeout=10)
            conn.request(method, path)
            r = conn.getresponse()
            assert r.status in (200, 204) and r.read() == b""
            assert r.getheader("Content-Type") is None, (method, path, r.getheaders())
            conn.close()
