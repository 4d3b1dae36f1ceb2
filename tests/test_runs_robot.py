"""Runs on the real robot's parts (rospy, actionlib, the Robot facade) against a scripted move_base:
results matched to their own goals, so a late or stale result never advances a run.
"""

import time

import pytest

from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import make_route
from tests.conftest import wait_for
from tests.standins.move_base import ABORT_X

pytestmark = pytest.mark.usefixtures("ros_node")


@pytest.fixture
def runs(ready_robot, store, tmp_path):
    executor = RunExecutor(ready_robot, store, RunHistory(str(tmp_path / "runs.json")))
    ready_robot.runs = executor
    yield executor
    executor.close()


def route(*names, **fields):
    return make_route(None, dict({"waypoints": list(names)}, **fields), scheduled=False)


def ended(runs, run_id, timeout=15):
    return wait_for(lambda: runs.get(run_id) if runs.get(run_id)["state"] not in ("running", "paused") else None,
                    timeout=timeout, message="the run to end")


def test_each_waypoint_is_sent_in_order_and_reached(runs, move_base):
    run = runs.start(route("kitchen", "office", "dock", loops=2))
    done = ended(runs, run["id"])
    assert done["state"] == "succeeded"
    xs = [round(goal.target_pose.pose.position.x, 2) for _, goal in move_base.goals]
    assert xs == [1.23, 5.67, 0.0] * 2
    assert [v["name"] for v in done["visited"]] == ["kitchen", "office", "dock"] * 2


def test_a_late_success_of_a_goal_canceled_by_a_pause_does_not_count(runs, move_base):
    move_base.delay = 1.0
    move_base.ignore_cancels = True  # its cancel is never confirmed: the goal "succeeds" later, stale
    run = runs.start(route("kitchen", "office"))
    wait_for(lambda: len(move_base.goals) == 1, message="the first goal at move_base")
    assert runs.pause(run["id"])["state"] == "paused"
    time.sleep(1.5)  # the canceled goal's late SUCCEEDED comes meanwhile
    still = runs.get(run["id"])
    assert still["state"] == "paused" and still["visited"] == [] and still["current"]["name"] == "kitchen"
    move_base.ignore_cancels = False
    move_base.delay = 0.1
    runs.resume(run["id"])
    done = ended(runs, run["id"])
    assert [v["name"] for v in done["visited"]] == ["kitchen", "office"], done


def test_a_goal_replaced_under_the_run_ends_it_and_its_result_changes_nothing(runs, ready_robot, move_base, store):
    from flask_move_server.core.geometry import Goal, Pose2D

    move_base.delay = 0.5
    run = runs.start(route("kitchen", "office"))
    wait_for(lambda: len(move_base.goals) == 1, message="the run's goal at move_base")
    ready_robot.goto(Goal(Pose2D(2.0, 2.0, 0.0), None))
    done = runs.get(run["id"])
    assert done["state"] == "canceled" and "POST /goto" in done["message"]
    time.sleep(1.0)  # the replaced goal and the new one end meanwhile
    assert runs.get(run["id"])["visited"] == [] and len(move_base.goals) == 2


def test_on_failure_stop_and_skip_with_move_bases_reason(runs, move_base, store):
    from flask_move_server.waypoints import make_waypoint

    store.put(make_waypoint("pit", ABORT_X, 0.0, 0.0))
    failed = ended(runs, runs.start(route("kitchen", "pit", "dock"))["id"])
    assert failed["state"] == "failed" and failed["missed"][0]["name"] == "pit"
    assert "no path" in failed["missed"][0]["reason"] and "pit" in failed["message"]
    skipped = ended(runs, runs.start(route("pit", "dock", on_failure="skip"))["id"])
    assert skipped["state"] == "succeeded" and [v["name"] for v in skipped["visited"]] == ["dock"]
    assert "no path" in skipped["missed"][0]["reason"]


def test_runs_are_kept_across_a_restart_and_an_active_one_is_interrupted(ready_robot, store, move_base, tmp_path):
    path = str(tmp_path / "runs.json")
    move_base.delay = 30.0
    first = RunExecutor(ready_robot, store, RunHistory(path))
    run = first.start(route("kitchen", "dock"))
    wait_for(lambda: len(move_base.goals) == 1, message="the run's goal at move_base")
    first._history.close()  # as a SIGKILL: the file holds the run as running; no close() of the executor
    again = RunExecutor(ready_robot, store, RunHistory(path))
    try:
        kept = again.get(run["id"])
        assert kept["state"] == "interrupted" and kept["current"]["name"] == "kitchen"
        assert "resume" in kept["message"]
    finally:
        again.close()
        first.close()


def test_a_run_is_on_disk_when_its_start_is_answered(runs, move_base, monkeypatch, tmp_path):
    """An acknowledged run survives a kill -9 right after: the answer waits for its write (a writer thread
    starved on a loaded machine once lost one), here an SD card taking 0.3 s per write."""
    import json

    from flask_move_server.waypoints import locked_file

    slow_write = locked_file.atomic_write

    def sd_card(path, text):
        time.sleep(0.3)
        slow_write(path, text)
    monkeypatch.setattr(locked_file, "atomic_write", sd_card)
    move_base.delay = 5.0
    run = runs.start(route("kitchen"))
    on_disk = json.loads((tmp_path / "runs.json").read_text())
    assert on_disk[0]["id"] == run["id"] and on_disk[0]["state"] == "running"
