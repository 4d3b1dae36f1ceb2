"""``/explore`` over HTTP without ROS: each field checked before anything starts, the answers' shape,
the refusals, the token, and the ``explore`` events reaching ``GET /events``.

The app is the real one; the explorer behind it is tests/fake_explorer.py (what an exploration
does on a robot is the explorer's own tests' business).
"""

import time

import pytest

from flask_move_server.core.errors import ExploreConflict, ModesOff, ModeSwitching
from flask_move_server.web import create_app
from tests.conftest import hardened
from tests.fake_explorer import FakeExplorer
from tests.fake_robot import FakeRobot
from tests.sse import EventReader

TOKEN = "explore-token"
EXP_FIELDS = {"state", "frontiers", "known_m2", "goals", "unreachable", "elapsed", "map", "message", "save_as", "then",
              "max_minutes", "return_home", "started", "target"}


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def explorer(bus, robot):
    explorer = FakeExplorer(bus, maps=["flat"], estop=robot.estop)
    explorer.attach(robot)  # POST /stop and the e-stop cancel it, as the real facade's do
    yield explorer
    explorer.close()


@pytest.fixture
def client(robot_config, robot, store, bus, explorer):
    return create_app(robot_config, robot, store, events=bus, explorer=explorer).test_client()


def refusal(response, status, code):
    body = response.get_json()
    assert response.status_code == status and body["status"] == "error" and body["error"] == code, body
    return body["message"]


# the body, field by field ---------------------------------------------------------------------


@pytest.mark.parametrize("body, field", [
    ({}, "save_as"),
    ({"save_as": 7}, "save_as"),
    ({"save_as": None}, "save_as"),
    ({"save_as": "flat", "then": "mapping"}, "then"),
    ({"save_as": "flat", "then": None}, "then"),
    ({"save_as": "flat", "max_minutes": 0}, "max_minutes"),
    ({"save_as": "flat", "max_minutes": -5}, "max_minutes"),
    ({"save_as": "flat", "max_minutes": 240.5}, "max_minutes"),
    ({"save_as": "flat", "max_minutes": "30"}, "max_minutes"),
    ({"save_as": "flat", "max_minutes": True}, "max_minutes"),
    (b'{"save_as": "flat", "max_minutes": 1e400}', "max_minutes"),
    (b'{"save_as": "flat", "max_minutes": 1' + b"0" * 400 + b"}", "max_minutes"),
    ({"save_as": "flat", "return_home": "yes"}, "return_home"),
    ({"save_as": "flat", "return_home": 1}, "return_home"),
    ({"save_as": "flat", "overwrite": "true"}, "overwrite"),
    ({"save_as": "flat", "overwrite": None}, "overwrite"),
    ({"save_as": "flat", "valid_until": "soon"}, "valid_until"),
    ({"save_as": "flat", "speed": 2}, "speed"),
], ids=lambda value: repr(value)[:60] if isinstance(value, (dict, bytes)) else value)
def test_every_bad_field_is_a_400_naming_it_and_nothing_starts(client, explorer, body, field):
    sent = {"data": body} if isinstance(body, bytes) else {"json": body}
    message = refusal(client.post("/explore", **sent), 400, "bad_request")
    assert "'{}'".format(field) in message or '"{}"'.format(field) in message, message
    assert explorer.calls == []


@pytest.mark.parametrize("name", ["a/b", "", ".hidden", "x" * 65, "flat.waypoints", "a\u202eb"])
def test_a_name_no_map_can_have_is_a_400_bad_map_name(client, explorer, name):
    assert "map name" in refusal(client.post("/explore", json={"save_as": name}), 400, "bad_map_name")
    assert explorer.calls == []


@pytest.mark.parametrize("raw", [b"", b"[]", b"{", b'{"save_as": "a", "save_as": "b"}', b'{"save_as": NaN}'])
def test_a_malformed_body_is_a_400(client, explorer, raw):
    refusal(client.post("/explore", data=raw), 400, "bad_request")
    assert explorer.calls == []


def test_the_defaults_and_each_option_reach_the_explorer(client, explorer):
    assert client.post("/explore", data=b'{"save_as": "K\\u0075\\u0308che"}').status_code == 202  # curl's way, NFD
    assert explorer.calls[-1] == ("start", {"save_as": "Küche", "then": "navigation", "max_minutes": 30.0,
                                            "return_home": True, "overwrite": False})
    explorer.cancel("test")
    body = {"save_as": "flat", "then": "idle", "max_minutes": 240, "return_home": False, "overwrite": True}
    assert client.post("/explore", json=body).status_code == 202
    assert explorer.calls[-1] == ("start", dict(body, max_minutes=240.0))


def test_a_valid_until_passed_is_refused_as_late(client, explorer):
    refusal(client.post("/explore", json={"save_as": "new", "valid_until": time.monotonic() - 1}), 409,
            "command_late")
    assert client.post("/explore", json={"save_as": "new", "valid_until": time.monotonic() + 3}).status_code == 202


# the answers ----------------------------------------------------------------------------------


def test_get_says_null_before_the_first_exploration_then_the_current_one(client, explorer):
    assert client.get("/explore").get_json() == {"exploration": None}
    r = client.post("/explore", json={"save_as": "attic", "max_minutes": 12.5})
    assert r.status_code == 202
    body = r.get_json()
    assert body["status"] == "ok" and set(body["exploration"]) == EXP_FIELDS
    started = body["exploration"]
    assert started["state"] == "starting" and started["save_as"] == "attic" and started["max_minutes"] == 12.5
    explorer.advance(state="exploring", frontiers=3, known_m2=42.0, goals=5, unreachable=1, target=[1.5, 2.0])
    now = client.get("/explore").get_json()["exploration"]
    assert now["state"] == "exploring" and now["frontiers"] == 3 and now["target"] == [1.5, 2.0]
    explorer.advance(state="done", map="attic", target=None)
    assert client.get("/explore").get_json()["exploration"]["map"] == "attic"  # the last one, once ended


def test_without_an_explorer_post_is_refused_and_get_says_null(robot_config, store):
    client = create_app(robot_config, FakeRobot(), store).test_client()
    message = refusal(client.post("/explore", json={"save_as": "flat"}), 409, "explore_conflict")
    assert message.startswith("This server does not explore: ")
    assert client.get("/explore").get_json() == {"exploration": None}
    refusal(client.post("/explore", json={"save_as": 1}), 400, "bad_request")  # the body is still checked first


# refusals -------------------------------------------------------------------------------------


def test_a_saved_name_needs_overwrite(client, explorer):
    assert "flat" in refusal(client.post("/explore", json={"save_as": "flat"}), 409, "map_exists")
    assert client.post("/explore", json={"save_as": "flat", "overwrite": True}).status_code == 202


def test_one_at_a_time(client, explorer):
    assert client.post("/explore", json={"save_as": "one"}).status_code == 202
    assert "already exploring" in refusal(client.post("/explore", json={"save_as": "two"}), 409, "explore_conflict")
    assert client.get("/explore").get_json()["exploration"]["save_as"] == "one"


def test_while_e_stopped_it_is_refused(client, explorer):
    assert client.post("/explore", json={"save_as": "one"}).status_code == 202
    assert client.post("/estop").status_code == 200
    assert client.get("/explore").get_json()["exploration"]["state"] == "canceled"
    assert "e-stop" in refusal(client.post("/explore", json={"save_as": "two"}), 409, "estop_latched")
    client.post("/estop/release")
    assert client.post("/explore", json={"save_as": "two"}).status_code == 202
    assert client.post("/stop").status_code == 200
    assert client.get("/explore").get_json()["exploration"]["message"].startswith("Stopped (POST /stop). The map made")


@pytest.mark.parametrize("error, status, code", [
    (ExploreConflict("Run 3 (rounds) is running: cancel it first."), 409, "explore_conflict"),
    (ModesOff("This server does not switch modes."), 409, "modes_off"),
    (ModeSwitching("A switch is under way."), 409, "mode_switching"),
])
def test_the_explorers_refusals_keep_their_status(client, explorer, error, status, code):
    explorer.refusal = error
    assert refusal(client.post("/explore", json={"save_as": "new"}), status, code) == str(error)


# the token --------------------------------------------------------------------------------------


def test_both_need_the_token(robot_config, robot, store, explorer):
    client = create_app(robot_config, robot, store, token=TOKEN, explorer=explorer).test_client()
    refusal(client.post("/explore", json={"save_as": "new"}), 401, "unauthorized")
    refusal(client.get("/explore"), 401, "unauthorized")
    assert explorer.calls == []
    auth = {"Authorization": "Bearer " + TOKEN}
    assert client.post("/explore", json={"save_as": "new"}, headers=auth).status_code == 202
    assert client.get("/explore", headers=auth).status_code == 200


def test_a_cross_site_page_cannot_start_one(client, explorer):
    refusal(client.post("/explore", json={"save_as": "new"}, headers={"Origin": "http://evil.example"}), 403,
            "forbidden_origin")
    assert explorer.calls == []


# events -------------------------------------------------------------------------------------------


def test_each_change_is_an_explore_event_on_the_stream(robot_config, robot, store, bus, explorer):
    app = create_app(robot_config, robot, store, token=TOKEN, events=bus, explorer=explorer)
    auth = {"Authorization": "Bearer " + TOKEN}
    with hardened(app, robot_config.server, loop_timeout=60) as (_, url), \
            EventReader(url, headers=auth, kinds=("explore",)) as reader:
        app.test_client().post("/explore", json={"save_as": "new"}, headers=auth)
        kind, data = reader.next()
        assert kind == "explore" and data["state"] == "starting" and set(data) == EXP_FIELDS
        explorer.advance(state="exploring", frontiers=4, known_m2=20.5, goals=1, target=[2.0, 1.0])
        kind, data = reader.next()
        assert data["state"] == "exploring" and data["frontiers"] == 4 and data["target"] == [2.0, 1.0]
        explorer.advance(state="done", map="new")
        kind, data = reader.until(lambda kind, data: data["state"] == "done")
        assert data["map"] == "new"
    with hardened(app, robot_config.server, loop_timeout=60) as (_, url), \
            EventReader(url, headers=auth, kinds=("explore",)) as late:
        assert late.next()[1]["state"] == "done"  # a page opened later gets the last one at once
