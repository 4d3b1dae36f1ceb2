"""robotctl map start|use and pose, against a live app on port 0 over the mode manager and a stand-in stack."""

import pytest

from flask_move_server.core.events import EventBus
from flask_move_server.modes.manager import ModeManager
from flask_move_server.robotctl import cli as client
from flask_move_server.robotctl import modes as client_modes
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.web import create_app
from tests.conftest import serve
from tests.fake_robot import FakeRobot
from tests.modes_standin import StandInStack, save_map


@pytest.fixture
def live(robot_config, store, monkeypatch):
    monkeypatch.setattr(client_modes, "POLL_PERIOD", 0.02)
    stack, poses = StandInStack(), []
    modes = ModeManager(robot_config, stack, EventBus(), relocalize=poses.append)
    try:
        with serve(create_app(robot_config, FakeRobot(), store, modes=modes)) as url:
            yield type("Live", (), {"url": url, "stack": stack, "poses": poses, "modes": modes,
                                    "config": robot_config})
    finally:
        modes.close()


def robotctl(live, *args):
    return client.main(["--url", live.url, "--request-timeout", "10", *args])


def test_map_start_follows_the_switch_until_mapping_runs(live, capsys):
    assert robotctl(live, "map", "start") == ExitStatus.OK
    assert live.stack.starts() == [("mapping", None)]
    assert capsys.readouterr().out.startswith("mapping: ")


def test_map_use_navigates_on_the_map_and_sets_the_pose_at_a_waypoint(live, capsys):
    yaml_path = save_map(live.config, "flat", "waypoints:\n  hall: [2.0, 1.0, 0.0]\n")
    assert robotctl(live, "map", "use", "flat", "--at", "hall") == ExitStatus.OK
    assert live.stack.starts() == [("navigation", yaml_path)]
    assert [p.as_dict() for p in live.poses] == [{"x": 2.0, "y": 1.0, "yaw": 0.0}]
    assert "navigation on flat: running; the robot's pose was set" in capsys.readouterr().out


def test_map_use_of_an_unknown_map_exits_5_naming_close_ones(live, capsys):
    save_map(live.config, "flat")
    assert robotctl(live, "map", "use", "flta") == ExitStatus.NOT_FOUND
    assert "Did you mean: 'flat'" in capsys.readouterr().err


def test_a_stack_that_fails_exits_6_with_the_reason(live, capsys):
    live.stack.failures.append("no scans on /scan: is the lidar plugged in?")
    assert robotctl(live, "map", "start") == ExitStatus.UNAVAILABLE
    assert capsys.readouterr().err.strip() == "robotctl: mapping failed: no scans on /scan: is the lidar plugged in?"


def test_no_wait_returns_at_once_and_timeout_gives_up_waiting(live, capsys):
    live.stack.gate.clear()
    try:
        assert robotctl(live, "map", "start", "--timeout", "0.1") == ExitStatus.TIMEOUT
        assert "mapping is still starting after 0.1 s" in capsys.readouterr().err
        assert robotctl(live, "map", "start", "--no-wait") == ExitStatus.ERROR  # one switch at a time
        assert "under way" in capsys.readouterr().err
    finally:
        live.stack.gate.set()
    assert live.modes.wait(5)


def test_pose_by_name_or_coordinates(live, capsys):
    assert robotctl(live, "pose", "kitchen") == ExitStatus.ERROR  # idle: no map in use
    assert "No map is in use" in capsys.readouterr().err
    live.modes.switch("navigation")
    live.modes.wait(5)
    assert robotctl(live, "pose", "kitchen") == ExitStatus.OK
    assert robotctl(live, "pose", "1.5", "-2", "0.25") == ExitStatus.OK
    assert [p.as_dict() for p in live.poses] == [{"x": 1.23, "y": 4.56, "yaw": 0.79},
                                                 {"x": 1.5, "y": -2.0, "yaw": 0.25}]
    assert "set to kitchen (1.23, 4.56, 0.79)" in capsys.readouterr().out
    assert robotctl(live, "pose", "1", "2") == ExitStatus.USAGE
    assert robotctl(live, "pose", "kitchn") == ExitStatus.NOT_FOUND


def test_pose_confirm_settles_the_dock_assumed_after_a_switch(live, capsys):
    save_map(live.config, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    assert robotctl(live, "map", "use", "flat") == ExitStatus.OK
    assert live.modes.status()["localization"]["assumed"] is True
    assert robotctl(live, "pose", "--confirm", "kitchen") == ExitStatus.USAGE
    assert robotctl(live, "pose", "--confirm") == ExitStatus.OK
    assert live.modes.status()["localization"]["assumed"] is False
    assert len(live.poses) == 1  # the dock only
    assert "confirmed" in capsys.readouterr().out
