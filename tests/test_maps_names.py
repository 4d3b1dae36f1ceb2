"""Map names as a hostile or careless client sends them (issue 21): echoed back cut short, unique
whatever their case (FAT, exFAT and macOS folders would fold ``Base`` onto ``base``), a rename to
the same name a no-op. The real web app, maps folder and waypoint store on temporary files; the
mode manager and live map the stand-ins of tests/fake_maps.py, or the real manager over the
stand-in stack for ``/mode``.
"""

import pytest

from flask_move_server.events import EventBus
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.service import MapService
from flask_move_server.modes.manager import ModeManager
from flask_move_server.web import create_app
from tests.fake_maps import FakeMapSource, FakeModes
from tests.fake_robot import FakeRobot
from tests.modes_standin import StandInStack
from tests.test_maps_web import room

LONG = "x" * 10000 + "/"  # a name far past the rule, with a character no name may have


@pytest.fixture
def client(robot_config, store):
    events = EventBus()
    service = MapService(MapCatalogue(robot_config.maps_folder()), store, FakeMapSource(room()),
                         modes=FakeModes(events, mode="mapping"), events=events, save_timeout=0.2)
    return create_app(robot_config, FakeRobot(), store, events=events, maps=service).test_client()


@pytest.fixture
def mode_client(robot_config, store):
    modes = ModeManager(robot_config, StandInStack(), EventBus())
    yield create_app(robot_config, FakeRobot(), store, modes=modes).test_client()
    modes.close()


def short_400(answer, code):
    body = answer.get_json()
    assert answer.status_code == 400 and body["error"] == code, body
    assert len(body["message"]) < 400 and "x" * 100 not in body["message"], len(body["message"])
    return body["message"]


@pytest.mark.parametrize("method, path, body", [
    ("POST", "/maps", {"name": LONG}),
    ("PATCH", "/maps/flat", {"name": LONG}),
    ("GET", "/maps/" + "x" * 10000 + "%0A", None),
    ("DELETE", "/maps/." + "x" * 10000, None),
])
def test_a_long_bad_map_name_is_echoed_in_a_short_excerpt(client, method, path, body):
    assert client.post("/maps", json={"name": "flat"}).status_code == 201
    message = short_400(client.open(path, method=method, json=body), "bad_map_name")
    assert message.startswith('Invalid map name "') and "\u2026" in message


@pytest.mark.parametrize("body, code", [
    ({"mode": "navigation", "map": LONG}, "bad_map_name"),
    ({"mode": "y" * 10000}, "bad_request"),
    ({"mode": "navigation", "pose": {"z" * 10000: 1}}, "bad_request"),
    ({"mode": "idle", "w" * 10000: 1}, "bad_request"),
])
def test_long_names_in_a_mode_request_are_echoed_short(mode_client, body, code):
    message = short_400(mode_client.post("/mode", json=body), code)
    assert "y" * 100 not in message and "z" * 100 not in message and "w" * 100 not in message
