"""The mode manager: one switch at a time, failures said, crashes restarted, the mode remembered."""

import json
import logging
import os

import pytest

from flask_move_server import config as config_mod
from flask_move_server.core.errors import (
    BadMapName,
    BadRequest,
    ModesOff,
    ModeSwitching,
    RosUnavailable,
    StackFailed,
    UnknownMap,
    UnknownWaypoint,
    WrongMode,
)
from flask_move_server.core.events import EventBus
from flask_move_server.core.geometry import Pose2D
from flask_move_server.modes.manager import ModeManager
from flask_move_server.modes.restarts import RestartBudget
from tests.conftest import wait_for
from tests.modes_standin import StandInStack, save_map


@pytest.fixture
def cfg(tmp_path):
    c = config_mod.Config()
    c.waypoints.file = str(tmp_path / "waypoints.yaml")
    (tmp_path / "waypoints.yaml").write_text("waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n")
    c.modes.stack = "roslaunch"
    return c


class Harness:
    """A manager over the stand-in stack, its events recorded, the poses it set kept."""

    def __init__(self, cfg, clock=None):
        self.stack = StandInStack()
        self.bus = EventBus()
        self.events = []
        self.bus.listen("mode", self.events.append)
        self.poses = []
        kw = {"clock": clock} if clock else {}
        self.modes = ModeManager(cfg, self.stack, self.bus, relocalize=self.poses.append, **kw)
        self.modes.restart_budget.BACKOFF = (0.01, 0.02, 0.04)

    def states(self):
        return [(e["mode"], e["state"]) for e in self.events]


@pytest.fixture
def harness(cfg):
    h = Harness(cfg)
    yield h
    h.modes.close()


def test_a_switch_answers_starting_at_once_then_runs_and_is_remembered(cfg, harness):
    answer = harness.modes.switch("mapping")
    assert answer["mode"] == "mapping" and answer["state"] == "starting" and answer["map"] is None
    assert harness.modes.wait(5) is True
    status = harness.modes.status()
    assert status["state"] == "running" and status["since"].endswith("+00:00")
    assert "save the map (POST /maps" in status["message"]  # what to do next
    assert harness.states()[0] == ("mapping", "starting") and harness.states()[-1] == ("mapping", "running")
    assert harness.bus.latest("mode") == status
    with open(cfg.mode_state_file()) as f:
        assert json.load(f) == {"mode": "mapping", "map": None}


def test_the_running_stack_is_stopped_before_the_next_starts(cfg, harness):
    yaml_path = save_map(cfg, "flat")
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    harness.modes.switch("navigation", "flat")
    assert harness.modes.wait(5)
    assert harness.stack.calls[-3:] == [("start", "mapping", None), ("stop",), ("start", "navigation", yaml_path)]
    assert ("navigation", "stopping") in harness.states()
    assert harness.modes.active_map == "flat"


def test_an_unknown_map_is_refused_before_anything_stops(cfg, harness):
    save_map(cfg, "flat")
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    calls = list(harness.stack.calls)
    with pytest.raises(UnknownMap, match="flta.*Did you mean: 'flat'"):
        harness.modes.switch("navigation", "flta")
    with pytest.raises(BadMapName):
        harness.modes.switch("navigation", "../etc/passwd")
    assert harness.stack.calls == calls
    assert harness.modes.status()["mode"] == "mapping"


@pytest.mark.parametrize("mode, map_name", [("flying", None), ("mapping", "flat"), ("idle", "flat")])
def test_bad_switches_are_refused(harness, mode, map_name):
    with pytest.raises(BadRequest):
        harness.modes.switch(mode, map_name)
    assert harness.stack.calls == []


def test_one_switch_at_a_time(harness):
    harness.stack.gate.clear()
    harness.modes.switch("mapping")
    assert harness.stack.starting.wait(5)
    with pytest.raises(ModeSwitching, match="mapping is under way"):
        harness.modes.switch("idle")
    assert harness.modes.wait(0.01) is False
    harness.stack.gate.set()
    assert harness.modes.wait(5)
    harness.modes.switch("idle")
    assert harness.modes.wait(5)
    assert harness.modes.status()["mode"] == "idle"


def test_a_stack_that_cannot_start_fails_with_its_message_and_is_not_remembered(cfg, harness):
    harness.stack.failures.append("no laser scans on /scan within 60 s: is the lidar plugged in?")
    harness.modes.switch("mapping")
    with pytest.raises(StackFailed, match="is the lidar plugged in"):
        harness.modes.wait(5)
    assert harness.modes.status()["state"] == "failed"
    assert harness.states()[-1] == ("mapping", "failed")
    with pytest.raises(FileNotFoundError):
        open(cfg.mode_state_file())


def test_a_crashed_stack_is_restarted_then_given_up(cfg, harness):
    cfg.modes.restarts = 2
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    harness.stack.die("slam_gmapping died (exit code 1)")
    wait_for(lambda: harness.modes.status()["message"].startswith("running again"), 5)
    messages = [e["message"] for e in harness.events]
    assert "restarting (1 of 2) after: slam_gmapping died (exit code 1)" in messages
    harness.stack.die("slam_gmapping died again")
    wait_for(lambda: harness.modes.status()["message"] == "running again after 2 restarts", 5)
    harness.stack.die("slam_gmapping died a third time")
    wait_for(lambda: harness.modes.status()["state"] == "failed", 5)
    assert harness.modes.status()["message"] == "failed after 2 restarts: slam_gmapping died a third time"
    assert harness.stack.starts() == [("mapping", None)] * 3
    wait_for(lambda: harness.stack.calls[-1] == ("stop",), 5, message="the rest of the stack stopped")


def test_a_restart_that_cannot_start_counts_as_a_crash(cfg, harness):
    cfg.modes.restarts = 1
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    harness.stack.failures.append("roslaunch: cannot find mapping.launch")
    harness.stack.die("slam_gmapping died")
    wait_for(lambda: harness.modes.status()["state"] == "failed", 5)
    assert harness.modes.status()["message"] == "failed after 1 restart: roslaunch: cannot find mapping.launch"
    assert ("mapping", "failed") not in harness.states()[:-1]  # no flash of failed while restarting


def test_a_long_run_forgives_earlier_crashes(cfg):
    now = [1000.0]
    cfg.modes.restarts = 1
    h = Harness(cfg, clock=lambda: now[0])
    try:
        h.modes.switch("mapping")
        h.modes.wait(5)
        h.stack.die("crash 1")
        wait_for(lambda: h.modes.status()["message"].startswith("running again"), 5)
        now[0] += RestartBudget.STABLE_RUN
        h.stack.die("crash 2, a minute later")
        wait_for(lambda: h.modes.status()["message"] == "running again after 1 restart", 5)
        assert "restarting (1 of 1) after: crash 2, a minute later" in [e["message"] for e in h.events]
    finally:
        h.modes.close()


def test_an_exit_of_a_stack_being_stopped_is_not_a_crash(harness):
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    old_exit = harness.stack.on_exit
    harness.modes.switch("idle")
    harness.modes.wait(5)
    old_exit("killed by the switch")
    assert harness.modes.status()["mode"] == "idle" and harness.modes.status()["state"] == "running"
    assert harness.stack.starts() == [("mapping", None)]


def test_navigation_on_a_map_sets_the_pose_to_its_dock(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    harness.modes.switch("navigation", "flat")
    harness.modes.wait(5)
    assert harness.poses == [Pose2D(0.5, -1.0, 1.57)]
    assert "dock" in harness.modes.status()["message"]


def test_a_map_without_a_dock_says_to_set_the_pose(cfg, harness):
    save_map(cfg, "flat")
    harness.modes.switch("navigation", "flat")
    harness.modes.wait(5)
    assert harness.poses == []
    assert harness.modes.status()["message"] == (
        "running; set the robot's pose (POST /pose) \u2013 the map has no dock")


def test_the_pose_given_or_named_with_the_switch_is_set(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n  hall: [3.0, 4.0, 0.0]\n")
    harness.modes.switch("navigation", "flat", Pose2D(1.0, 1.0, 0.0))
    harness.modes.wait(5)
    harness.modes.switch("navigation", "flat", "hall")
    harness.modes.wait(5)
    assert harness.poses == [Pose2D(1.0, 1.0, 0.0), Pose2D(3.0, 4.0, 0.0)]
    with pytest.raises(UnknownWaypoint, match="Did you mean: 'hall'"):
        harness.modes.switch("navigation", "flat", "hal")


def test_set_pose_needs_navigation_on_a_map(harness):
    with pytest.raises(WrongMode, match="idle"):
        harness.modes.set_pose(Pose2D(1.0, 2.0, 0.0))
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    with pytest.raises(WrongMode, match="While mapping.*SLAM takes no pose"):  # gmapping ignores /initialpose
        harness.modes.set_pose(Pose2D(1.0, 2.0, 0.0))
    assert harness.poses == []
    harness.modes.switch("navigation")
    harness.modes.wait(5)
    harness.modes.set_pose(Pose2D(1.0, 2.0, 0.0))
    assert harness.poses == [Pose2D(1.0, 2.0, 0.0)]


def _restored(cfg, state_text=None):
    if state_text is not None:
        with open(cfg.mode_state_file(), "w") as f:
            f.write(state_text)
    h = Harness(cfg)
    h.modes.restore()
    h.modes.wait(5)
    h.modes.close()
    return h.modes.status(), h.stack.starts()


def test_restore_comes_back_to_the_remembered_mode(cfg):
    yaml_path = save_map(cfg, "flat")
    status, starts = _restored(cfg, '{"mode": "navigation", "map": "flat"}')
    assert (status["mode"], status["map"], status["state"]) == ("navigation", "flat", "running")
    assert starts == [("navigation", yaml_path)]


@pytest.mark.parametrize("kind, expected", [("sim", ("navigation", None)), ("roslaunch", ("idle", None))])
@pytest.mark.parametrize("state_text", [None, "{not json", '{"mode": "dancing"}', '["idle"]', "[" * 5000 + "]" * 5000,
                                        '{"mode": ' * 3000 + "1" + "}" * 3000],
                         ids=["missing", "broken", "unknown mode", "not an object", "deep list", "deep object"])
def test_restore_without_a_usable_state_file_starts_the_default(cfg, kind, expected, state_text, caplog):
    cfg.modes.stack = kind
    with caplog.at_level(logging.INFO, logger="flask_move_server.modes"):
        status, starts = _restored(cfg, state_text)
    assert (status["mode"], status["map"]) == expected and status["state"] == "running"
    if kind == "roslaunch":
        assert "mapping" in status["message"] and starts == []
    said = [r for r in caplog.records if "starting the default" in r.getMessage()]
    assert len(said) == 1 and len(said[0].getMessage()) < 500
    if state_text is not None:  # broken: a warning naming the file and why
        assert said[0].levelno == logging.WARNING and cfg.mode_state_file() in said[0].getMessage()


def test_a_robot_upgraded_with_its_map_saved_as_map_navigates_on_it(cfg):
    """Before the server ran the stack, operators saved maps/map.yaml for navigation.launch: a robot
    upgraded with nothing remembered navigates on it (and its dock), not idle with its map unused."""
    yaml_path = save_map(cfg, "map")
    status, starts = _restored(cfg)
    assert (status["mode"], status["map"], status["state"]) == ("navigation", "map", "running")
    assert starts == [("navigation", yaml_path)]


def test_restore_of_a_map_that_is_gone_is_idle_saying_so(cfg):
    status, starts = _restored(cfg, '{"mode": "navigation", "map": "flat"}')
    assert status["mode"] == "idle" and "'flat'" in status["message"] and "gone" in status["message"]
    assert starts == []


def test_restore_of_a_map_name_no_map_can_have_is_idle_saying_so(cfg):
    status, starts = _restored(cfg, '{"mode": "navigation", "map": "../flat"}')
    assert status["mode"] == "idle" and "bad name" in status["message"] and starts == []


def test_a_pose_that_cannot_be_published_leaves_navigation_running_and_says_so(cfg):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")

    def ros_down(pose):
        raise RosUnavailable("ROS is not reachable at http://localhost:11311")

    modes = ModeManager(cfg, StandInStack(), relocalize=ros_down)
    try:
        modes.switch("navigation", "flat")
        assert modes.wait(5)
        assert modes.status()["message"] == (
            "running; the robot's pose could not be set (ROS is not reachable at http://localhost:11311): POST /pose")
    finally:
        modes.close()


def test_without_a_backend_modes_are_off(cfg):
    modes = ModeManager(cfg, None)
    modes.restore()
    assert modes.status()["mode"] == "navigation" and modes.status()["map"] is None
    assert modes.status()["message"] == "the navigation stack is started outside this server (modes.stack: none)"
    with pytest.raises(ModesOff):
        modes.switch("mapping")
    modes.close()


def test_close_stops_the_stack_once(harness):
    harness.modes.switch("mapping")
    harness.modes.wait(5)
    harness.modes.close()
    harness.modes.close()
    assert harness.stack.calls[-2:] == [("stop",), ("close",)]


def test_running_waits_until_goals_reach_the_new_move_base(cfg):
    answers = iter([False, False, True])
    modes = ModeManager(cfg, StandInStack(), goals_ready=lambda: next(answers))
    try:
        modes.switch("mapping")
        assert modes.wait(5)
        assert next(answers, "asked until ready") == "asked until ready"
        assert "move_base" not in modes.status()["message"]
    finally:
        modes.close()


def test_a_mode_whose_stack_has_no_move_base_runs_without_waiting_for_it(cfg):
    stack = StandInStack()
    stack.serves_goals = lambda mode: mode == "navigation"  # as LaunchedStack on a mapping launch without move_base
    asked = []
    modes = ModeManager(cfg, stack, goals_ready=lambda: asked.append(1))
    try:
        modes.switch("mapping")
        assert modes.wait(5)
        assert "move_base" not in modes.status()["message"] and asked == []
    finally:
        modes.close()


def test_a_move_base_that_does_not_answer_is_said_in_the_message(cfg):
    modes = ModeManager(cfg, StandInStack(), goals_ready=lambda: False)
    modes.READY_WAIT = 0.1
    try:
        modes.switch("mapping")
        assert modes.wait(5)
        assert modes.status()["message"].endswith("; move_base does not answer this server's goals yet (GET /health)")
    finally:
        modes.close()


def test_a_pose_name_missing_from_the_map_switched_to_names_that_map_and_its_waypoints(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n  hall: [3.0, 4.0, 0.0]\n")
    # /waypoints serves the single file now, which may well hold a "kitchen": the error must say whose it is not
    with pytest.raises(UnknownWaypoint) as error:
        harness.modes.switch("navigation", "flat", "kitchen")
    assert str(error.value) == ("The map 'flat' has no waypoint named 'kitchen'. A pose's name is one of the "
                                "map's own waypoints (it has 'dock', 'hall').")


def test_a_pose_sent_while_a_switch_is_under_way_is_refused_not_lost(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    harness.stack.gate.clear()
    harness.modes.switch("navigation", "flat")
    assert harness.stack.starting.wait(5)
    with pytest.raises(ModeSwitching, match="give the pose with the switch"):
        harness.modes.set_pose(Pose2D(2.0, 1.0, 0.0))
    harness.stack.gate.set()
    assert harness.modes.wait(5)
    assert harness.poses == [Pose2D(0.5, -1.0, 1.57)]  # the dock, as the running message says
    harness.modes.set_pose(Pose2D(2.0, 1.0, 0.0))
    assert harness.poses[-1] == Pose2D(2.0, 1.0, 0.0)


def test_a_failure_quoting_a_huge_value_is_cut_in_every_status(robot_config):
    """A failed start quoted a hostile map's value whole: /status, /mode and every event carried 36 MB."""
    from flask_move_server.core.events import EventBus
    from flask_move_server.modes.manager import MESSAGE_LIMIT, ModeManager
    from tests.modes_standin import StandInStack, save_map

    stack = StandInStack()
    stack.failures.append("origin: must be [x, y, yaw], got " + "[x, " * 1_000_000)
    save_map(robot_config, "flat")
    manager = ModeManager(robot_config, stack, EventBus())
    try:
        manager.switch("navigation", "flat")
        wait_for(lambda: manager.status()["state"] == "failed", message="the start to fail")
        status = manager.status()
    finally:
        manager.close()
    assert status["message"].startswith("origin: must be") and len(status["message"]) <= MESSAGE_LIMIT


def test_a_mode_that_cannot_be_remembered_says_so_until_one_is(cfg, harness):
    os.mkdir(cfg.mode_state_file())  # a folder where mode.json goes: it cannot be written, even as root
    harness.modes.switch("mapping")
    assert harness.modes.wait(5)
    running = harness.modes.status()["message"]
    assert "not remembered for the next start: cannot write {}".format(cfg.mode_state_file()) in running
    assert running.startswith("running")  # what the mode says first, the problem after it
    assert "not remembered" in harness.modes.switch("idle")["message"]  # the next switch's 202 says it too
    assert harness.modes.wait(5)
    os.rmdir(cfg.mode_state_file())
    harness.modes.switch("mapping")
    assert harness.modes.wait(5)
    assert "not remembered" not in harness.modes.status()["message"]
    assert json.load(open(cfg.mode_state_file())) == {"mode": "mapping", "map": None}


NOT_ASSUMED = {"assumed": False, "from": None, "since": None}


def test_the_dock_set_after_a_switch_is_an_assumption_until_the_pose_is_set(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    assert harness.modes.status()["localization"] == NOT_ASSUMED
    harness.modes.switch("navigation", "flat")
    harness.modes.wait(5)
    assumed = harness.modes.status()["localization"]
    assert assumed["assumed"] is True and assumed["from"] == "dock" and assumed["since"]
    assert harness.events[-1]["localization"] == assumed  # the running event says it
    harness.modes.set_pose(Pose2D(3.0, 1.0, 0.0))
    assert harness.modes.status()["localization"] == NOT_ASSUMED
    assert harness.events[-1]["localization"] == NOT_ASSUMED and harness.events[-1]["state"] == "running"


def test_confirming_the_assumed_pose_settles_it_without_setting_one(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    harness.modes.switch("navigation", "flat")
    harness.modes.wait(5)
    events = len(harness.events)
    assert harness.modes.confirm_pose() == NOT_ASSUMED
    assert harness.modes.status()["localization"] == NOT_ASSUMED
    assert harness.poses == [Pose2D(0.5, -1.0, 1.57)]  # only the dock: confirming publishes nothing
    assert len(harness.events) == events + 1
    assert harness.modes.confirm_pose() == NOT_ASSUMED  # again: nothing to do, no event
    assert len(harness.events) == events + 1


def test_a_pose_given_with_the_switch_is_not_assumed_and_a_new_switch_forgets_the_dock(cfg, harness):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    harness.modes.switch("navigation", "flat", Pose2D(1.0, 1.0, 0.0))
    harness.modes.wait(5)
    assert harness.modes.status()["localization"] == NOT_ASSUMED
    harness.modes.switch("navigation", "flat")
    harness.modes.wait(5)
    assert harness.modes.status()["localization"]["assumed"] is True
    harness.modes.switch("mapping")
    assert harness.modes.status()["localization"] == NOT_ASSUMED  # from the switch's first status on
    harness.modes.wait(5)
    harness.stack.gate.clear()
    harness.modes.switch("navigation", "flat")
    with pytest.raises(ModeSwitching, match="confirm the robot's pose once"):
        harness.modes.confirm_pose()  # the dock the new stack will be told is not known yet
    harness.stack.gate.set()
    assert harness.modes.wait(5) and harness.modes.status()["localization"]["assumed"] is True


def test_after_a_restart_the_dock_is_assumed_again(cfg):
    save_map(cfg, "flat", "waypoints:\n  dock: [0.5, -1.0, 1.57]\n")
    state_file = '{"mode": "navigation", "map": "flat"}'
    status, starts = _restored(cfg, state_file)
    assert starts == [("navigation", os.path.join(cfg.maps_folder(), "flat.yaml"))]
    assert status["localization"]["assumed"] is True and status["localization"]["from"] == "dock"
