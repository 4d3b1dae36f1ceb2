"""The web layer reaches the robot only through the Robot facade's public methods.

A robot that offers exactly those methods, and no parts (no ``navigator``, ``estop``, ...), must
serve every route: a route that reaches through the facade into a part would answer 500 here,
and would tie the HTTP layer to one way of building the robot.
"""

import inspect

import pytest

from flask_move_server import config
from flask_move_server.core.robot import Robot
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app

FACADE = {name for name, _ in inspect.getmembers(Robot, inspect.isfunction) if not name.startswith("_")}


class FacadeOnly:
    """Answers the Robot facade's public methods with fixed values; any other attribute fails."""

    def __getattr__(self, name):
        if name not in FACADE:
            raise AttributeError("the web layer asked the robot for {!r}, not a Robot method".format(name))
        answers = {
            "goto": 7, "wait": True, "stop": False, "engage_estop": True, "release_estop": True,
            "navigation_status": {"state": "succeeded", "goal_id": 7},
            "estop_status": {"latched": False}, "health": {"status": "ok"},
            "teleop": {"linear": 0.1, "angular": 0.0, "hold": 0.5},
        }

        def method(*args):
            return answers.get(name, {})

        return method


@pytest.fixture
def client(tmp_path):
    cfg = config.Config()
    cfg.server.host = "127.0.0.1"
    return create_app(cfg, FacadeOnly(), WaypointStore(str(tmp_path / "waypoints.yaml"))).test_client()


def test_goto_with_wait_answers_the_goal_state_from_the_facade(client):
    r = client.post("/goto", json={"x": 1.0, "y": 2.0, "yaw": 0.0, "wait": 5})
    assert r.status_code == 200, r.get_data(as_text=True)
    assert r.get_json()["navigation"] == {"state": "succeeded", "goal_id": 7}


@pytest.mark.parametrize("path, key", [("/estop", "engaged"), ("/estop/release", "released")])
def test_estop_routes_use_the_facade(client, path, key):
    r = client.post(path)
    assert r.status_code == 200, r.get_data(as_text=True)
    assert r.get_json() == {"status": "ok", key: True, "estop": {"latched": False}}


def test_the_other_motion_routes_use_the_facade(client):
    assert client.post("/stop").status_code == 200
    assert client.post("/teleop", json={"linear": 0.1}).status_code == 200
    assert client.get("/health").get_json() == {"status": "ok"}
    assert client.get("/status").status_code == 200
