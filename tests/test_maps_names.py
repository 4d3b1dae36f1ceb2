"""Map names as a hostile or careless client sends them (issue 21): echoed back cut short, unique
whatever their case (FAT, exFAT and macOS folders would fold ``Base`` onto ``base``), a rename to
the same name a no-op. The real web app, maps folder and waypoint store on temporary files; the
mode manager and live map the stand-ins of tests/fake_maps.py, or the real manager over the
stand-in stack for ``/mode``.
"""

import os

import pytest

from flask_move_server.core.events import EventBus
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


def files(robot_config):
    folder = robot_config.maps_folder()
    return {f: os.stat(os.path.join(folder, f)).st_mtime_ns for f in sorted(os.listdir(folder))}


def test_renaming_a_map_to_its_own_name_is_a_no_op(client, robot_config, store):
    assert client.post("/maps", json={"name": "base"}).status_code == 201
    before = files(robot_config)
    answer = client.patch("/maps/base", json={"name": "base"})
    assert answer.status_code == 200 and answer.get_json()["map"]["name"] == "base", answer.get_json()
    assert files(robot_config) == before


@pytest.mark.parametrize("overwrite", [False, True])
def test_saving_a_name_that_differs_from_a_saved_one_only_in_case_is_refused(client, robot_config, overwrite):
    assert client.post("/maps", json={"name": "base"}).status_code == 201
    before = files(robot_config)
    answer = client.post("/maps", json={"name": "Base", "overwrite": overwrite})
    body = answer.get_json()
    assert answer.status_code == 409 and body["error"] == "map_exists" and "'base'" in body["message"], body
    assert files(robot_config) == before


@pytest.mark.parametrize("old, new", [("flat", "Base"), ("base", "BASE")])
def test_renaming_to_a_name_that_differs_from_a_saved_one_only_in_case_is_refused(client, robot_config, old, new):
    for name in ("base", "flat"):
        assert client.post("/maps", json={"name": name}).status_code == 201
    before = files(robot_config)
    answer = client.patch("/maps/" + old, json={"name": new})
    body = answer.get_json()
    assert answer.status_code == 409 and body["error"] == "map_exists" and "'base'" in body["message"], body
    assert files(robot_config) == before
    assert [m["name"] for m in client.get("/maps").get_json()["maps"]] == ["base", "flat"]


def test_renaming_the_map_in_use_to_its_own_name_is_a_no_op_too(tmp_path):
    from tests.test_maps import small_grid

    maps = MapCatalogue(str(tmp_path / "maps"))
    maps.save("base", small_grid())
    assert maps.rename("base", "base", active="base").name == "base"
