"""No phantom goals: a goal is taken only while a stack that runs it is up, and never hangs.

A ``/goto`` within ~200 ms of a switch answered 202 and stayed ``active`` for good: no stack ran
it, ``/stop`` left it ``canceling``, a waiting ``/goto`` waited its whole timeout. Real server
process (``--sim``) for the switches; a real actionlib server that never answers for the rest.
"""

import actionlib
import pytest
from move_base_msgs.msg import MoveBaseAction

from flask_move_server.app import cli
from flask_move_server.core.errors import NavigationFailed, WrongMode
from flask_move_server.core.events import EventBus
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.modes.goal_gate import GoalGate
from flask_move_server.modes.manager import ModeManager
from tests.conftest import stop_process, wait_for
from tests.modes_standin import StandInStack
from tests.robot_fixtures import no_drive
from tests.test_sim_e2e import SimServer


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("phantom"))
    yield server
    stop_process(server.proc)


def _running(sim):
    wait_for(lambda: sim.get("/mode").json()["state"] == "running", timeout=60, message="the mode running")


@pytest.mark.parametrize("switch, refusal", [
    ({"mode": "mapping"}, (503, "move_base_unavailable")),
    ({"mode": "idle"}, (409, "wrong_mode")),
    ({"mode": "navigation"}, (503, "move_base_unavailable")),
])
def test_a_goal_sent_as_a_switch_begins_is_refused_not_left_active(sim, switch, refusal):
    _running(sim)
    assert sim.post("/mode", switch).status_code == 202
    answer = sim.post("/goto", {"x": 3.0, "y": 0.5, "yaw": 0.0, "wait": 20}, timeout=30)
    assert (answer.status_code, answer.json()["error"]) == refusal, answer.text
    _running(sim)
    assert sim.get("/status").json()["navigation"]["state"] not in ("active", "canceling")


def test_a_goal_under_way_when_a_switch_begins_ends_with_the_reason(sim):
    _running(sim)
    if sim.get("/mode").json()["mode"] != "navigation":
        assert sim.post("/mode", {"mode": "navigation", "wait": 60}, timeout=90).status_code == 200
    assert sim.post("/goto", {"x": 8.4, "y": 0.9, "yaw": 0.0}).status_code == 202
    assert sim.post("/mode", {"mode": "mapping"}).status_code == 202
    navigation = wait_for(lambda: (lambda n: n if n["state"] not in ("active", "canceling") else None)(
        sim.get("/status").json()["navigation"]), timeout=10, message="the goal to end")
    assert navigation["state"] == "aborted"
    assert navigation["message"].startswith("The robot switched to mapping"), navigation


@pytest.fixture
def mute_robot(robot_config, ros_node, unique_name):
    """The real robot, its move_base one that hears goals and never answers them."""
    mute = actionlib.ActionServer(unique_name + "/move_base", MoveBaseAction, goal_cb=lambda handle: None,
                                  auto_start=False)
    mute.start()
    robot = cli.build_robot(robot_config, ros_node, no_drive())
    wait_for(robot.navigator.server_ready, timeout=15, message="the action client to see the mute move_base")
    yield robot
    robot.close()


def test_a_goal_no_move_base_acknowledges_is_given_up_with_the_reason(mute_robot):
    """A move_base that hears goals but never answers them (its stack going away): the goal is
    aborted after ``ack_patience``, a waiting client is told why, and /stop has nothing to cancel."""
    mute_robot.navigator.ack_patience = 0.5
    seq = mute_robot.goto(Goal(Pose2D(1.0, 0.0, 0.0)))
    with pytest.raises(NavigationFailed) as failed:
        mute_robot.wait(seq, 10)
    assert failed.value.state == "aborted"
    assert "move_base did not acknowledge the goal" in str(failed.value)
    assert mute_robot.navigation_status()["state"] == "aborted"
    assert mute_robot.stop() is False  # nothing left canceling


class _NotHeardYet(actionlib.ActionServer):
    """A move_base that, once ``deaf``, drops the goals and cancels it receives, as if still on their way. Its
    subscriptions stay: unsubscribing them (as this test did) let the client see the goal topic's
    connection drop, under load before the goal was sent, and refuse it as "move_base does not answer"."""

    deaf = False

    def internal_goal_callback(self, goal):
        if not self.deaf:
            super().internal_goal_callback(goal)

    def internal_cancel_callback(self, goal_id):
        if not self.deaf:
            super().internal_cancel_callback(goal_id)


@pytest.fixture
def slow_robot(robot_config, ros_node, unique_name):
    """The real robot, its move_base one that has not heard the goal yet (a busy move_base, a slow
    link): it publishes its status (without the goal), but the goal and its cancel are still on their way."""
    slow = _NotHeardYet(unique_name + "/move_base", MoveBaseAction, goal_cb=lambda handle: None, auto_start=False)
    slow.start()
    robot = cli.build_robot(robot_config, ros_node, no_drive())
    wait_for(robot.navigator.server_ready, timeout=15, message="the action client to see the slow move_base")
    slow.deaf = True  # from now on goals and cancels are on their way, never there
    yield robot
    robot.close()


def test_a_goal_stopped_before_move_base_heard_it_ends_canceled(slow_robot):
    """A Stop right after a goal (an MQTT flood beside /stop showed it): actionlib's client calls a goal
    canceled before move_base acknowledged it *lost* at move_base's next status without it. The goal
    was canceled (move_base keeps the cancel and recalls the goal when it comes), not aborted."""
    seq = slow_robot.goto(Goal(Pose2D(1.0, 0.0, 0.0)))
    assert slow_robot.stop() is True
    with pytest.raises(NavigationFailed) as ended:
        slow_robot.wait(seq, 10)
    assert ended.value.state == "canceled"
    assert slow_robot.navigation_status()["state"] == "canceled"


def test_a_move_base_this_server_did_not_start_is_named_while_idle(mute_robot, robot_config):
    """The seed guide's set-up: the owner's own launch files run move_base while this server's mode
    is idle. A goal used to be refused as if nothing ran; now the refusal and /health say why."""
    modes = ModeManager(robot_config, StandInStack(), EventBus())
    try:
        assert modes.status()["mode"] == "idle" and modes.status()["state"] == "running"
        mute_robot.goal_gate = GoalGate(modes, mute_robot.navigator)
        with pytest.raises(WrongMode) as refused:
            mute_robot.goto(Goal(Pose2D(1.0, 0.0, 0.0)))
        assert "move_base is running but was not started by this server" in str(refused.value)
        assert "modes.stack: none" in str(refused.value)
        health = mute_robot.health()
        assert health["move_base"] == "unavailable" and "modes.stack: none" in health["note"]
    finally:
        modes.close()
