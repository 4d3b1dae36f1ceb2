"""Cross-site requests and DNS rebinding: a web page the operator visits must not drive the robot.

The robot answers only to its own names (Host) and only to its own page or to clients that send
no Origin (curl, robotctl, requests), before any token check, so token-less robots are covered.
The guard is the web layer's, so the robot behind it is the fake (tests/fake_robot.py): a refused
request must not reach it at all.
"""

import http.client
import json
import socket

import pytest

from flask_move_server import config
from flask_move_server.core.errors import ConfigError
from flask_move_server.web import create_app
from tests.conftest import serve
from tests.fake_robot import FakeRobot
from tests.robot_fixtures import SEED

GOTO = '{"x": 1.0, "y": 2.0}'


@pytest.fixture
def robot():
    """The fake robot in place of the real one: the app and store fixtures build on it."""
    return FakeRobot()


@pytest.fixture
def guarded(robot_config, robot, store):
    """The app of a token-less robot known as robot.local, robot.lan and anything under .home."""
    robot_config.server.allowed_hosts = ["robot.lan", ".home"]
    return create_app(robot_config, robot, store)


def _machine():
    return socket.gethostname().split(".")[0]


@pytest.mark.parametrize("host", [
    "127.0.0.1:5000", "[::1]:5000", "192.168.1.20", "[fe80::1%eth0]:5000", "localhost:5000", "robot.local:5000",
    "ROBOT.local",
    "robot.local.", "robot-2.local:5000", "robot.lan", "kitchen.home", "home", "MACHINE", "MACHINE.local:5000",
])
def test_the_robots_own_names_and_addresses_are_answered(guarded, host):
    host = host.replace("MACHINE", _machine())
    r = guarded.test_client().get("/waypoints", headers={"Host": host})
    assert r.status_code == 200, r.get_json()


@pytest.mark.parametrize("host", [
    "evil.example", "evil.example:5000", "robot.local.evil.example", "robot-x.local", "localhost.evil.example",
    "robot.lan.evil.example", "myhome", "1.2.3.4.nip.io",
])
def test_any_other_name_is_refused_saying_how_to_allow_it(guarded, robot_config, host):
    client = guarded.test_client()
    for method, path, body in (("get", "/status", None), ("get", "/health", None), ("post", "/goto", GOTO),
                               ("put", "/waypoints/x", '{"x": 1, "y": 1, "yaw": 0}')):
        r = getattr(client, method)(path, data=body, headers={"Host": host}, content_type="text/plain")
        assert r.status_code == 403 and r.get_json()["error"] == "unknown_host", (method, path)
        assert "server.allowed_hosts" in r.get_json()["message"]
    assert open(robot_config.waypoints.file).read() == SEED


@pytest.mark.parametrize("origin", [
    "http://evil.example", "https://evil.example", "null", "http://robot.local:8080", "http://robot.local",
    "http://robot.local:5000.evil.example", "file://", "http://127.0.0.1:5000", "http://[", "robot.local:5000",
])
def test_a_text_plain_post_from_another_page_moves_nothing(guarded, robot, robot_config, origin):
    client = guarded.test_client()
    for path, body in (("/goto", GOTO), ("/teleop", '{"linear": 0.2}'),
                       ("/waypoints/x", '{"x": 1, "y": 1, "yaw": 0}')):
        method = client.put if path.startswith("/waypoints") else client.post
        r = method(path, data=body, content_type="text/plain",
                   headers={"Host": "robot.local:5000", "Origin": origin})
        assert r.status_code == 403 and r.get_json()["error"] == "forbidden_origin", path
        assert "cannot drive the robot" in r.get_json()["message"]
    status = client.get("/status", headers={"Host": "robot.local:5000"}).get_json()
    assert status["navigation"]["state"] == "idle" and status["teleop"]["active"] is False
    assert robot.moved() == []
    assert open(robot_config.waypoints.file).read() == SEED


def test_another_pages_reads_are_refused_too(guarded):
    client = guarded.test_client()
    r = client.get("/status", headers={"Host": "robot.local:5000", "Origin": "http://evil.example"})
    assert r.status_code == 403
    r = client.get("/status", headers={"Host": "robot.local:5000", "Sec-Fetch-Site": "cross-site",
                                       "Sec-Fetch-Mode": "no-cors"})
    assert r.status_code == 403 and "Sec-Fetch-Site" in r.get_json()["message"]


def test_the_robots_own_page_and_plain_clients_still_drive_it(guarded, robot):
    client = guarded.test_client()
    for headers in ({"Host": "robot.local:5000", "Origin": "http://robot.local:5000", "Sec-Fetch-Site": "same-origin"},
                    {"Host": "192.168.1.20:5000", "Origin": "https://192.168.1.20:5000"},
                    {"Host": "127.0.0.1:5000"}):  # curl, robotctl: no Origin
        r = client.post("/goto", data=GOTO, content_type="text/plain", headers=headers)
        assert r.status_code == 202, (headers, r.get_json())
    assert len(robot.moved()) == 3


def test_following_a_link_to_the_page_from_another_site_works(guarded):
    r = guarded.test_client().get("/", headers={"Host": "robot.local:5000", "Sec-Fetch-Site": "cross-site",
                                                "Sec-Fetch-Mode": "navigate"})
    assert r.status_code == 200


def test_a_form_post_marked_as_navigation_from_another_site_moves_nothing(guarded, robot):
    """Only following a link (GET) is exempt; a cross-site form POST navigates too and must be refused."""
    r = guarded.test_client().post("/goto", data=GOTO, content_type="text/plain", headers={
        "Host": "robot.local:5000", "Sec-Fetch-Site": "cross-site", "Sec-Fetch-Mode": "navigate"})
    assert r.status_code == 403 and r.get_json()["error"] == "forbidden_origin"
    assert robot.moved() == []


def test_the_guard_runs_before_the_token(robot_config, robot, store):
    client = create_app(robot_config, robot, store, token="s3cret").test_client()
    auth = {"Authorization": "Bearer s3cret"}
    assert client.get("/status", headers=dict(auth, Host="evil.example")).status_code == 403
    assert client.get("/status", headers=dict(auth, Origin="http://evil.example")).status_code == 403
    assert client.get("/status", headers={"Host": "evil.example"}).status_code == 403
    assert client.get("/status", headers=dict(auth, Host="robot.local")).status_code == 200


def test_a_star_allows_any_name_but_not_another_origin(robot_config, robot, store):
    robot_config.server.allowed_hosts = ["*"]
    client = create_app(robot_config, robot, store).test_client()
    assert client.get("/status", headers={"Host": "robot.example.org"}).status_code == 200
    r = client.post("/goto", data=GOTO, headers={"Host": "robot.example.org", "Origin": "http://evil.example"})
    assert r.status_code == 403


@pytest.mark.parametrize("value", [["http://robot.lan"], ["robot lan"], ["robot.lan:5000"], [""]])
def test_allowed_hosts_must_be_names(tmp_path, value):
    path = tmp_path / "robot.yaml"
    path.write_text("server:\n  allowed_hosts: {}\n".format(json.dumps(value)))
    with pytest.raises(ConfigError) as err:
        config.load(str(path))
    assert err.value.key == "server.allowed_hosts" and "must list host names" in err.value.reason


def _raw(url, method, path, headers, body=None):
    conn = http.client.HTTPConnection(url[len("http://"):], timeout=10)
    try:
        conn.putrequest(method, path, skip_host=True)
        for name, value in headers.items():
            conn.putheader(name, value)
        conn.endheaders(body.encode() if body else None)
        r = conn.getresponse()
        return r.status, r.getheader("Content-Type"), r.read()
    finally:
        conn.close()


def test_over_real_http_rebinding_and_cross_site_posts_are_refused(guarded, robot):
    with serve(guarded) as url:
        port = url.rsplit(":", 1)[1]
        plain = {"Content-Type": "text/plain", "Content-Length": str(len(GOTO))}
        # DNS rebinding: the attacker's name now points at the robot; the browser sends that name.
        status, ctype, body = _raw(url, "GET", "/status", {"Host": "attacker.example:" + port})
        assert status == 403 and ctype == "application/json; charset=utf-8"
        assert json.loads(body)["error"] == "unknown_host"
        # A form-like text/plain POST from a page on another site: no preflight, but an Origin.
        headers = dict(plain, Host="127.0.0.1:" + port, Origin="http://attacker.example")
        status, _, body = _raw(url, "POST", "/goto", headers, GOTO)
        assert status == 403 and json.loads(body)["error"] == "forbidden_origin"
        assert robot.moved() == []
        # The robot's own page, and curl without an Origin, still drive it.
        headers = dict(plain, Host="robot.local:" + port, Origin="http://robot.local:" + port)
        assert _raw(url, "POST", "/goto", headers, GOTO)[0] == 202
        assert _raw(url, "POST", "/goto", dict(plain, Host="127.0.0.1:" + port), GOTO)[0] == 202
        assert len(robot.moved()) == 2
