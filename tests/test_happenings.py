"""Happenings (arrived, failed, run_done, estop, explore_done) from the real robot's parts: rospy and
actionlib against the scripted move_base, the Robot facade, the e-stop latch, the run executor, the
event bus. A canceled or replaced goal tells nothing; each end is told once.
"""

import datetime
import threading
import time

import pytest

from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.core.happenings import Happenings
from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import make_route
from flask_move_server.waypoints import make_waypoint
from tests.conftest import wait_for
from tests.standins.move_base import ABORT_X, HOLD_X

pytestmark = pytest.mark.usefixtures("ros_node")

QUIET = 0.5  # s to be sure nothing more comes after a goal's end was seen


class Heard:
    """Every happening told, in order, with the thread it was told in."""

    def __init__(self):
        self.items = []
        self._lock = threading.Lock()

    def __call__(self, name, data):
        with self._lock:
            self.items.append((name, data, threading.current_thread().name))

    def names(self):
        with self._lock:
            return [name for name, _, _ in self.items]

    def of(self, name):
        with self._lock:
            return [data for n, data, _ in self.items if n == name]


@pytest.fixture
def heard(ready_robot, bus):
    happenings = Happenings(ready_robot, bus)
    heard = Heard()
    happenings.listen(heard)
    heard.happenings = happenings
    yield heard
    happenings.close()


@pytest.fixture
def ends(ready_robot):
    """What Navigator.when_ended told: (seq, state, target, pose, why) per goal end."""
    told = []
    ready_robot.navigator.when_ended(lambda *end: told.append(end))
    return told


def _ended(robot, seq):
    """The navigation status once goal ``seq`` ended."""
    def ended():
        status = robot.navigator.status()
        return status if status["goal_id"] == seq and status["state"] not in ("active", "canceling") else None

    return wait_for(ended, message="goal {} to end".format(seq))


def test_a_goal_to_a_waypoint_that_arrives_is_told_arrived(client, ready_robot, heard, ends):
    answer = client.post("/goto", json={"name": "kitchen"})
    assert answer.status_code == 202, answer.get_json()
    seq = ready_robot.navigator.status()["goal_id"]
    arrived = wait_for(lambda: heard.of("arrived"), message="arrived")
    assert arrived == [{"target": "kitchen", "goal": {"x": 1.23, "y": 4.56, "yaw": 0.79}, "goal_id": seq}]
    time.sleep(QUIET)
    assert heard.names() == ["arrived"]
    (end,) = ends
    assert end[:3] == (seq, "succeeded", "kitchen") and end[3] == Pose2D(1.23, 4.56, 0.79) and end[4] is None
    reached = heard.happenings.last_reached
    assert reached["name"] == "kitchen"
    at = datetime.datetime.fromisoformat(reached["at"])
    assert at.utcoffset() == datetime.timedelta(0)
    assert abs((datetime.datetime.now(datetime.timezone.utc) - at).total_seconds()) < 10


def test_last_reached_is_none_before_any_arrival_and_a_pose_goal_leaves_it(ready_robot, heard):
    assert heard.happenings.last_reached is None
    ready_robot.goto(Goal(Pose2D(2.0, 1.0, 0.0), None))
    arrived = wait_for(lambda: heard.of("arrived"), message="arrived")
    assert arrived[0]["target"] is None and arrived[0]["goal"] == {"x": 2.0, "y": 1.0, "yaw": 0.0}
    assert heard.happenings.last_reached is None


def test_an_aborted_goal_is_told_failed_with_move_bases_sentence(client, ready_robot, store, heard, ends):
    store.put(make_waypoint("pit", ABORT_X, 0.0, 0.0))
    assert client.post("/goto", json={"name": "pit"}).status_code == 202
    seq = ready_robot.navigator.status()["goal_id"]
    (failed,) = wait_for(lambda: heard.of("failed"), message="failed")
    assert failed == {"target": "pit", "state": "aborted", "goal_id": seq,
                      "message": "move_base aborted the goal to 'pit': no path."}
    assert failed["message"] == ready_robot.navigator.status()["message"]
    time.sleep(QUIET)
    assert heard.names() == ["failed"] and heard.happenings.last_reached is None
    assert [end[1] for end in ends] == ["aborted"]


def test_a_goal_canceled_by_stop_tells_nothing(client, ready_robot, store, move_base, heard, ends):
    store.put(make_waypoint("far", HOLD_X, 0.0, 0.0))
    assert client.post("/goto", json={"name": "far"}).status_code == 202
    seq = ready_robot.navigator.status()["goal_id"]
    wait_for(lambda: move_base.executing, message="move_base driving the goal")
    assert client.post("/stop").status_code == 200
    assert _ended(ready_robot, seq)["state"] == "canceled"
    wait_for(lambda: ends, message="the navigator to tell the goal's end")
    time.sleep(QUIET)
    assert heard.names() == []
    (end,) = ends
    assert end[:3] == (seq, "canceled", "far") and "canceled" in end[4]


def test_a_goal_replaced_by_a_newer_one_tells_nothing_for_it(client, ready_robot, store, move_base, heard, ends):
    store.put(make_waypoint("far", HOLD_X, 0.0, 0.0))
    assert client.post("/goto", json={"name": "far"}).status_code == 202
    first = ready_robot.navigator.status()["goal_id"]
    wait_for(lambda: move_base.executing, message="move_base driving the first goal")
    assert client.post("/goto", json={"name": "kitchen"}).status_code == 202
    second = ready_robot.navigator.status()["goal_id"]
    arrived = wait_for(lambda: heard.of("arrived"), message="the second goal to arrive")
    time.sleep(QUIET)  # the first goal's late PREEMPTED comes meanwhile
    assert heard.names() == ["arrived"] and arrived[0]["goal_id"] == second and arrived[0]["target"] == "kitchen"
    assert [(end[0], end[1], end[2]) for end in ends] == [(first, "canceled", "far"), (second, "succeeded", "kitchen")]
    assert ends[0][4] == "The goal to 'far' was replaced by a newer goal."


def test_the_estop_is_told_once_per_engagement_and_the_goal_it_stops_is_not_a_failure(
        client, ready_robot, store, move_base, heard):
    store.put(make_waypoint("far", HOLD_X, 0.0, 0.0))
    assert client.post("/goto", json={"name": "far"}).status_code == 202
    seq = ready_robot.navigator.status()["goal_id"]
    wait_for(lambda: move_base.executing, message="move_base driving the goal")
    assert client.post("/estop").status_code == 200
    assert heard.of("estop") == [{"source": "api"}]
    assert client.post("/estop").status_code == 200  # pressed again while latched: no new engagement
    _ended(ready_robot, seq)
    time.sleep(QUIET)
    assert heard.names() == ["estop"]
    ready_robot.release_estop()
    ready_robot.engage_estop("button")
    assert heard.of("estop") == [{"source": "api"}, {"source": "button"}]
    ready_robot.release_estop()


@pytest.fixture
def runs(ready_robot, store, bus, tmp_path):
    executor = RunExecutor(ready_robot, store, RunHistory(str(tmp_path / "runs.json")), events=bus)
    ready_robot.runs = executor
    yield executor
    executor.close()


def test_a_run_tells_each_arrival_and_run_done_once(runs, bus, heard):
    run = runs.start(make_route(None, {"waypoints": ["kitchen", "office"]}, scheduled=False))
    done = wait_for(lambda: heard.of("run_done"), timeout=15, message="run_done")
    time.sleep(QUIET)
    assert heard.names() == ["arrived", "arrived", "run_done"]
    assert [a["target"] for a in heard.of("arrived")] == ["kitchen", "office"]
    assert done[0]["id"] == run["id"] and done[0]["state"] == "succeeded"
    assert [v["name"] for v in done[0]["visited"]] == ["kitchen", "office"]
    assert heard.happenings.last_reached["name"] == "office"
    bus.publish("run", runs.get(run["id"]))  # the same ended run told again (a late repeat): not a new end
    assert len(heard.of("run_done")) == 1


def test_a_run_ended_by_stop_is_done_canceled_and_its_goal_is_not_a_failure(client, runs, store, move_base, heard):
    store.put(make_waypoint("far", HOLD_X, 0.0, 0.0))
    run = runs.start(make_route(None, {"waypoints": ["far", "kitchen"]}, scheduled=False))
    wait_for(lambda: move_base.executing, message="move_base driving the run's goal")
    assert client.post("/stop").status_code == 200
    (done,) = wait_for(lambda: heard.of("run_done"), message="run_done")
    assert done["id"] == run["id"] and done["state"] == "canceled" and "POST /stop" in done["message"]
    time.sleep(QUIET)
    assert heard.names() == ["run_done"]


def test_run_states_that_are_not_an_end_tell_nothing(bus, heard):
    for state in ("running", "paused", "interrupted"):
        bus.publish("run", {"id": 7, "state": state})
    assert heard.names() == []
    bus.publish("run", {"id": 7, "state": "failed", "message": "Could not reach pit"})
    bus.publish("run", {"id": 8, "state": "skipped"})
    assert [(d["id"], d["state"]) for d in heard.of("run_done")] == [(7, "failed"), (8, "skipped")]


def _exploration(state, started="2024-05-01T10:00:00+02:00", save_as="flat"):
    return {"state": state, "message": state, "save_as": save_as, "started": started, "map": None}


def test_an_exploration_is_done_once_and_its_own_goals_are_not_told(ready_robot, bus, heard):
    bus.publish("explore", _exploration("starting"))
    bus.publish("explore", _exploration("exploring"))
    seq = ready_robot.run_goto(Goal(Pose2D(ABORT_X, 0.0, 0.0), None))  # a frontier move_base gives up on
    _ended(ready_robot, seq)
    seq = ready_robot.run_goto(Goal(Pose2D(0.0, 0.0, 0.0), "dock"))  # home
    _ended(ready_robot, seq)
    time.sleep(QUIET)
    assert heard.names() == []
    assert heard.happenings.last_reached["name"] == "dock"  # it was reached, all the same
    bus.publish("explore", _exploration("done"))
    bus.publish("explore", _exploration("done"))  # the same end again: told once
    assert [d["state"] for d in heard.of("explore_done")] == ["done"]
    bus.publish("explore", _exploration("failed", started="2024-05-01T11:00:00+02:00"))  # another one
    assert [d["state"] for d in heard.of("explore_done")] == ["done", "failed"]
    ready_robot.goto(Goal(Pose2D(ABORT_X, 0.0, 0.0), "pit"))  # exploring is over: failures are told again
    wait_for(lambda: heard.of("failed"), message="failed after the exploration")


def test_a_failing_listener_is_logged_and_the_others_still_hear(ready_robot, heard, caplog):
    def broken(name, data):
        raise RuntimeError("listener bug")

    later = Heard()
    heard.happenings.listen(broken)
    heard.happenings.listen(later)
    ready_robot.engage_estop("api")
    ready_robot.release_estop()
    assert heard.names() == ["estop"] and later.names() == ["estop"]
    assert "listener bug" in caplog.text


def test_nothing_is_told_after_close(ready_robot, heard):
    heard.happenings.close()
    ready_robot.engage_estop("api")
    ready_robot.release_estop()
    assert heard.names() == []


def test_a_navigator_end_listener_that_fails_does_not_lose_the_end(ready_robot, heard, caplog):
    def broken(*end):
        raise RuntimeError("end listener bug")

    ready_robot.navigator.when_ended(broken)  # after the happenings': they still hear
    ready_robot.goto(Goal(Pose2D(1.0, 1.0, 0.0), None))
    wait_for(lambda: heard.of("arrived"), message="arrived")
    wait_for(lambda: "end listener bug" in caplog.text, message="the failing listener logged")
    assert ready_robot.navigator.status()["state"] == "succeeded"
