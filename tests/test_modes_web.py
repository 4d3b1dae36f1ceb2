"""``GET/POST /mode`` and ``POST /pose`` over HTTP: the mode manager behind the routes, a stand-in stack.

The routes only validate and call the manager (modes/manager.py), so the stack under it is the
stand-in of tests/modes_standin.py and the robot the fake one; what the real stacks do is the
backends' tests'.
"""

import os

import pytest

from flask_move_server.core.events import EventBus
from flask_move_server.modes.goal_gate import GoalGate
from flask_move_server.modes.manager import ModeManager
from flask_move_server.web import create_app
from tests.fake_robot import FakeRobot
from tests.modes_standin import StandInStack, save_map


@pytest.fixture
def stack():
    return StandInStack()


@pytest.fixture
def poses():
    return []


@pytest.fixture
def modes(robot_config, stack, poses):
    manager = ModeManager(robot_config, stack, EventBus(), relocalize=poses.append)
    yield manager
    manager.close()


@pytest.fixture
def client(robot_config, store, modes):
    return create_app(robot_config, FakeRobot(), store, modes=modes).test_client()


def test_get_mode_is_the_managers_status(client, modes):
    r = client.get("/mode")
    assert r.status_code == 200 and r.get_json() == modes.status()
    assert set(r.get_json()) == {"mode", "map", "state", "since", "message", "localization"}


def test_post_mode_answers_202_switching_then_runs(client, modes, stack):
    r = client.post("/mode", json={"mode": "mapping"})
    assert r.status_code == 202
    assert r.get_json()["status"] == "ok" and r.get_json()["mode"] == "mapping"
    assert r.get_json()["state"] == "starting"
    assert modes.wait(5)
    assert client.get("/mode").get_json()["state"] == "running"
    assert stack.starts() == [("mapping", None)]


def test_post_mode_with_wait_answers_200_once_running(client, robot_config, stack):
    yaml_path = save_map(robot_config, "flat")
    r = client.post("/mode", json={"mode": "navigation", "map": "flat", "wait": 5})
    assert r.status_code == 200
    body = r.get_json()
    assert (body["mode"], body["map"], body["state"]) == ("navigation", "flat", "running")
    assert stack.starts() == [("navigation", yaml_path)]


def test_post_mode_with_wait_answers_202_while_still_starting(client, modes, stack):
    stack.gate.clear()
    r = client.post("/mode", json={"mode": "mapping", "wait": 0.05})
    assert r.status_code == 202 and r.get_json()["state"] == "starting"
    r = client.post("/mode", json={"mode": "idle"})
    assert r.status_code == 409 and r.get_json()["error"] == "mode_switching"
    stack.gate.set()
    assert modes.wait(5)


def test_a_failed_start_with_wait_is_503_with_the_stacks_message(client, stack):
    stack.failures.append("move_base did not come up within 60 s: see ~/.ros/log/latest")
    r = client.post("/mode", json={"mode": "mapping", "wait": 5})
    assert r.status_code == 503
    assert r.get_json()["error"] == "stack_failed" and "move_base did not come up" in r.get_json()["message"]
    assert client.get("/mode").get_json()["state"] == "failed"


@pytest.mark.parametrize("body, status, code", [
    ({"mode": "navigation", "map": "nowhere"}, 404, "unknown_map"),
    ({"mode": "navigation", "map": "../x"}, 400, "bad_map_name"),
    ({"mode": "flying"}, 400, "bad_request"),
    ({"mode": "mapping", "map": "flat"}, 400, "bad_request"),
    ({"map": "flat"}, 400, "bad_request"),
    ({"mode": "navigation", "wait": -1}, 400, "bad_request"),
    ({"mode": "navigation", "wait": 1e9}, 400, "bad_request"),
    ({"mode": "navigation", "pose": [1, 2]}, 400, "bad_request"),
    ({"mode": "navigation", "pose": {"x": 1}}, 400, "bad_request"),
    ({"mode": "navigation", "pose": {"name": "dock", "x": 1}}, 400, "bad_request"),
    ({"mode": "navigation", "pose": {"z": 1}}, 400, "bad_request"),
    ({"mode": "navigation", "pose": {"name": "nowhere"}}, 404, "unknown_waypoint"),
    ({"mode": "navigation", "speed": 1}, 400, "bad_request"),
])
def test_bad_switches_are_refused_and_nothing_stops(client, stack, body, status, code):
    r = client.post("/mode", json=body)
    assert (r.status_code, r.get_json()["error"]) == (status, code), r.get_json()
    assert stack.calls == []


def test_a_switch_with_a_pose_sets_it_once_running(client, poses):
    r = client.post("/mode", json={"mode": "navigation", "pose": {"x": 1.5, "y": -2.0, "yaw": 0.3}, "wait": 5})
    assert r.status_code == 200 and "given pose" in r.get_json()["message"]
    assert [p.as_dict() for p in poses] == [{"x": 1.5, "y": -2.0, "yaw": 0.3}]


def test_post_pose_publishes_the_estimate(client, modes, poses):
    client.post("/mode", json={"mode": "navigation", "wait": 5})
    r = client.post("/pose", json={"x": 1.0, "y": 2.0, "yaw": -0.5})
    assert r.status_code == 200 and r.get_json()["pose"] == {"x": 1.0, "y": 2.0, "yaw": -0.5}
    r = client.post("/pose", json={"name": "kitchen"})  # from the waypoints /waypoints serves
    assert r.status_code == 200 and r.get_json()["name"] == "kitchen"
    assert [p.as_dict() for p in poses] == [{"x": 1.0, "y": 2.0, "yaw": -0.5}, {"x": 1.23, "y": 4.56, "yaw": 0.79}]


def test_post_pose_needs_a_map_in_use(client, poses):
    r = client.post("/pose", json={"x": 1.0, "y": 2.0, "yaw": 0.0})
    assert r.status_code == 409 and r.get_json()["error"] == "wrong_mode"
    assert poses == []


@pytest.mark.parametrize("body, code", [
    ({}, "bad_request"), ({"x": 1.0}, "bad_request"), ({"name": "nowhere"}, "unknown_waypoint"),
    ({"x": 2e6, "y": 0, "yaw": 0}, "bad_waypoint"), ({"name": "dock", "yaw": 1}, "bad_request"),
])
def test_bad_poses_are_refused(client, modes, poses, body, code):
    client.post("/mode", json={"mode": "navigation", "wait": 5})
    r = client.post("/pose", json=body)
    assert r.get_json()["error"] == code and 400 <= r.status_code < 500
    assert poses == []


def test_the_dock_assumed_after_a_switch_is_said_until_confirmed(client, robot_config, poses):
    save_map(robot_config, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    client.post("/mode", json={"mode": "navigation", "map": "flat", "wait": 5})
    assumed = client.get("/status").get_json()["mode"]["localization"]
    assert assumed["assumed"] is True and assumed["from"] == "dock"
    r = client.post("/pose", json={"confirm": True})
    assert r.status_code == 200, r.get_json()
    assert r.get_json()["localization"] == {"assumed": False, "from": None, "since": None}
    assert client.get("/mode").get_json()["localization"]["assumed"] is False
    assert len(poses) == 1  # the dock; confirming publishes nothing


def test_setting_the_pose_ends_the_assumption(client, robot_config):
    save_map(robot_config, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    client.post("/mode", json={"mode": "navigation", "map": "flat", "wait": 5})
    r = client.post("/pose", json={"x": 1.0, "y": 2.0, "yaw": 0.0})
    assert r.status_code == 200 and r.get_json()["localization"]["assumed"] is False


@pytest.mark.parametrize("body", [{"confirm": False}, {"confirm": "yes"}, {"confirm": True, "x": 1.0}])
def test_a_confirm_that_is_not_true_alone_is_refused(client, robot_config, poses, body):
    save_map(robot_config, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    client.post("/mode", json={"mode": "navigation", "map": "flat", "wait": 5})
    r = client.post("/pose", json=body)
    assert r.status_code == 400 and r.get_json()["error"] == "bad_request"
    assert "confirm" in r.get_json()["message"]
    assert client.get("/mode").get_json()["localization"]["assumed"] is True  # nothing changed
    assert len(poses) == 1


def test_status_shows_the_mode(client, modes):
    assert client.get("/status").get_json()["mode"] == modes.status()


def test_a_server_without_a_stack_says_so_and_refuses_switches(robot_config, store):
    client = create_app(robot_config, FakeRobot(), store).test_client()
    mode = client.get("/mode").get_json()
    assert (mode["mode"], mode["map"], mode["state"]) == ("navigation", None, "running")
    assert "modes.stack: none" in mode["message"]
    r = client.post("/mode", json={"mode": "mapping"})
    assert r.status_code == 409 and r.get_json()["error"] == "modes_off"


def test_a_goal_while_idle_says_to_start_navigation_not_roslaunch(robot_config, store, modes):
    robot = FakeRobot()
    robot.move_base_ready = False  # idle: no move_base runs
    robot.goal_gate = GoalGate(modes, robot._navigation)
    client = create_app(robot_config, robot, store, modes=modes).test_client()
    r = client.post("/goto", json={"name": "kitchen"})
    assert r.status_code == 409 and r.get_json()["error"] == "wrong_mode"  # the owner's choice, not an outage
    assert r.get_json()["message"].startswith("The robot is idle") and "robotctl map use" in r.get_json()["message"]
    assert "roslaunch" not in r.get_json()["message"]



def test_a_mode_that_cannot_be_remembered_is_said_by_post_and_get_mode(client, robot_config):
    os.mkdir(robot_config.mode_state_file())  # mode.json cannot be written (a folder in its place)
    body = client.post("/mode", json={"mode": "mapping", "wait": 5}).get_json()
    assert body["state"] == "running" and "not remembered for the next start" in body["message"]
    assert "not remembered for the next start" in client.get("/mode").get_json()["message"]



class SimLike:
    """A ``--sim``-configured app: the real mode manager on the stand-in stack, and the real map service."""

    def __init__(self, robot_config, store, stack, poses, source=None):
        from flask_move_server.maps import configured
        from flask_move_server.maps.catalogue import MapCatalogue
        from flask_move_server.maps.service import MapService

        robot_config.sim.enabled, robot_config.modes.stack = True, "sim"
        self.events = events = EventBus()
        self.modes = ModeManager(robot_config, stack, events, relocalize=poses.append)
        maps = MapService(MapCatalogue(robot_config.maps_folder()), store, source, modes=self.modes, events=events,
                          configured=configured.of_config(robot_config))
        self.client = create_app(robot_config, FakeRobot(), store, events=events, modes=self.modes,
                                 maps=maps).test_client()
        self.modes.restore()
        assert self.modes.wait(5)

    def said(self):
        """What GET /mode and GET /maps (robotctl map list) say: mode, its map, the active map."""
        mode = self.client.get("/mode").get_json()
        return mode["mode"], mode["map"], self.client.get("/maps").get_json()["active"]


@pytest.fixture
def sim_like(robot_config, store, stack, poses):
    from flask_move_server.maps.mapfile import Grid
    from tests.fake_maps import FakeMapSource

    app = SimLike(robot_config, store, stack, poses, FakeMapSource(Grid(4, 3, 0.05, -0.1, -0.1, bytes(12))))
    yield app
    app.modes.close()


def test_mode_and_the_maps_list_name_the_configured_map_alike(sim_like, stack):
    """``--sim`` navigates on its demo map: ``GET /mode`` names it as ``GET /maps`` (``robotctl map list``) does,
    and its places are the waypoints file's, whether the robot started on it or came back to it."""
    client = sim_like.client
    assert sim_like.said() == ("navigation", "demo", "demo")
    assert sim_like.events.latest("waypoints")["map"] == "demo"  # as a stream opened now is told
    places = client.get("/waypoints").get_json()["waypoints"]
    assert places and stack.starts() == [("navigation", None)]  # the stack's own map, as always
    assert client.post("/mode", json={"mode": "mapping", "wait": 5}).status_code == 200
    assert sim_like.said() == ("mapping", None, None)
    assert client.post("/mode", json={"mode": "navigation", "map": "demo", "wait": 5}).status_code == 200
    assert sim_like.said() == ("navigation", "demo", "demo")
    assert client.get("/waypoints").get_json()["waypoints"] == places
    assert stack.starts()[-1] == ("navigation", None)


def test_saving_with_then_and_wait_answers_once_navigation_runs_on_the_new_map(sim_like, stack):
    """The README's mapping block pasted whole: the next line's /goto must find navigation running."""
    client = sim_like.client
    assert client.post("/mode", json={"mode": "mapping", "wait": 5}).status_code == 200
    r = client.post("/maps", json={"name": "flat", "then": "navigation", "wait": 5})
    assert r.status_code == 201
    assert (r.get_json()["mode"]["map"], r.get_json()["mode"]["state"]) == ("flat", "running")
    assert sim_like.said() == ("navigation", "flat", "flat")
    assert client.post("/mode", json={"mode": "mapping", "wait": 5}).status_code == 200
    stack.gate.clear()  # the next start hangs: the wait ends first, the map is saved all the same
    try:
        r = client.post("/maps", json={"name": "flat2", "then": "navigation", "wait": 0.1})
        assert r.status_code == 201 and r.get_json()["mode"]["state"] == "starting"
    finally:
        stack.gate.set()
    assert client.get("/maps/flat2").status_code == 200


def test_a_save_waits_only_for_the_switch_it_asks_for(sim_like):
    client = sim_like.client
    assert client.post("/mode", json={"mode": "mapping", "wait": 5}).status_code == 200
    for body in ({"name": "flat", "wait": 5}, {"name": "flat", "then": "navigation", "wait": -1},
                 {"name": "flat", "then": "navigation", "wait": "soon"}):
        r = client.post("/maps", json=body)
        assert r.status_code == 400 and "'wait'" in r.get_json()["message"], body
    assert client.get("/maps").get_json()["maps"][1:] == []  # nothing saved
