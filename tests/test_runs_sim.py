"""Runs of routes end to end: ``flask-move-server --sim`` as a user runs it, real HTTP, real ROS and
actionlib, the sim's move_base stand-in obeying the robot's own navigation config.

The waypoints are a metre or two apart in the demo flat's living room, so a leg takes seconds at
the raised speed factor. The last tests stop the server (SIGTERM, SIGKILL) under a run and start it
again on the same state folder: the run is ``interrupted`` and resumes.
"""

import datetime
import math
import signal
import time

import pytest
import requests

from tests.conftest import stop_process, wait_for
from tests.sse import EventLog
from tests.test_sim_e2e import SimServer

ROOM = ("waypoints:\n  a: [1.0, 0.0, 0.0]\n  b: [1.5, 1.0, 1.57]\n  c: [0.5, 1.2, 3.14]\n"
        "  wall: [4.0, -1.5, 0.0]\n  dock: [0.0, 0.0, 0.0]\n")


@pytest.fixture(scope="module")
def state(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


@pytest.fixture(scope="module")
def sim(state):
    server = SimServer(state, waypoints_text=ROOM)
    yield server
    stop_process(server.proc)


@pytest.fixture(autouse=True)
def at_rest(sim):
    """Each test starts with no run under way, the e-stop released."""
    yield
    if sim.proc.poll() is None:
        sim.post("/estop/release")
        sim.post("/stop")


def start(sim, body):
    r = sim.post("/runs", body)
    assert r.status_code == 202, r.text
    return r.json()["run"]


def run_of(sim, run_id):
    return sim.get("/runs/{}".format(run_id)).json()


def ended(sim, run_id, timeout=90):
    return wait_for(lambda: _if_ended(run_of(sim, run_id)), timeout=timeout, interval=0.2,
                    message="run {} to end".format(run_id))


def _if_ended(run):
    return run if run["state"] not in ("running", "paused") else None


def under_way(sim, run_id, farther_than=0.0):
    """Wait until the run's goal is at move_base (its distance known), more than ``farther_than`` m away."""
    def distance():
        current = run_of(sim, run_id)["current"] or {}
        left = current.get("distance_remaining")
        return left is not None and left > farther_than

    wait_for(distance, timeout=30, interval=0.05, message="run {} under way".format(run_id))


def moved(sim, seconds):
    """How far the robot moved (m) over ``seconds``."""
    a = sim.pose()
    time.sleep(seconds)
    b = sim.pose()
    return math.hypot(a["x"] - b["x"], a["y"] - b["y"])


def test_a_route_of_three_with_two_loops_visits_six_in_order_and_says_so_as_events(sim):
    with EventLog(sim.url, kinds={"run"}, timeout=120) as events:  # read all along: the run takes minutes
        run = start(sim, {"waypoints": ["a", "b", "c"], "loops": 2})
        assert run["state"] == "running" and run["current"]["name"] == "a" and run["trigger"] == "api"
        done = ended(sim, run["id"])
        assert done["state"] == "succeeded", done
        assert [(v["name"], v["loop"]) for v in done["visited"]] == [
            ("a", 1), ("b", 1), ("c", 1), ("a", 2), ("b", 2), ("c", 2)]
        assert done["missed"] == [] and done["current"] is None and done["ended"]
        kind, last = events.until(lambda k, d: d["id"] == run["id"] and d["state"] == "succeeded", timeout=10)
        assert len(last["visited"]) == 6


def test_pause_stops_the_robot_where_it_is_and_resume_drives_on(sim):
    run = start(sim, {"waypoints": ["b", "a"]})
    under_way(sim, run["id"], farther_than=0.3)
    time.sleep(0.5)
    paused = sim.post("/runs/{}/pause".format(run["id"])).json()
    assert paused["state"] == "paused"
    time.sleep(0.5)  # the base ramps down
    assert moved(sim, 1.5) < 0.02
    assert run_of(sim, run["id"])["state"] == "paused"
    assert sim.post("/runs/{}/resume".format(run["id"])).json()["state"] == "running"
    done = ended(sim, run["id"])
    assert done["state"] == "succeeded" and [v["name"] for v in done["visited"]] == ["b", "a"]


def test_skip_notes_the_waypoint_as_missed_and_goes_on(sim):
    sim.post("/goto", {"name": "a", "wait": 60}, timeout=70)
    run = start(sim, {"waypoints": ["c", "b"]})
    under_way(sim, run["id"])
    skipped = sim.post("/runs/{}/skip".format(run["id"])).json()
    assert skipped["current"]["name"] == "b", skipped
    done = ended(sim, run["id"])
    assert done["state"] == "succeeded"
    assert [(m["name"], m["reason"]) for m in done["missed"]] == [("c", "skipped (POST /runs/{}/skip)".format(
        run["id"]))]
    assert [v["name"] for v in done["visited"]] == ["b"]


def test_cancel_ends_the_run_and_the_robot_stops(sim):
    run = start(sim, {"waypoints": ["b", "c"], "loops": 0})
    under_way(sim, run["id"])
    time.sleep(0.5)
    canceled = sim.post("/runs/{}/cancel".format(run["id"])).json()
    assert canceled["state"] == "canceled" and canceled["ended"]
    time.sleep(0.5)
    assert moved(sim, 1.0) < 0.02
    assert sim.status()["navigation"]["state"] in ("canceled", "idle")
    again = sim.post("/runs/{}/resume".format(run["id"]))
    assert again.status_code == 409 and again.json()["error"] == "run_conflict"


@pytest.mark.parametrize("command, reason", [
    (("/stop", None), "Stopped (POST /stop)."),
    (("/goto", {"name": "dock"}), "A goal to dock (POST /goto) took the robot elsewhere."),
    (("/teleop", {"linear": 0.0, "angular": 0.0}), "Driven by joystick (POST /teleop)."),
    (("/estop", None), "The e-stop was engaged (POST /estop)."),
])
def test_another_command_ends_the_run_saying_which(sim, command, reason):
    run = start(sim, {"waypoints": ["a", "b"]})
    under_way(sim, run["id"])
    assert sim.post(*command).status_code in (200, 202)
    done = run_of(sim, run["id"])
    assert done["state"] == "canceled" and done["message"] == reason


def test_a_run_while_the_e_stop_is_latched_is_refused(sim):
    sim.post("/estop")
    r = sim.post("/runs", {"waypoints": ["a"]})
    assert r.status_code == 409 and r.json()["error"] == "estop_latched"


def test_a_second_run_while_one_is_active_is_refused(sim):
    run = start(sim, {"waypoints": ["b", "c"]})
    r = sim.post("/runs", {"waypoints": ["a"]})
    assert r.status_code == 409 and r.json()["error"] == "run_conflict"
    assert "Run {}".format(run["id"]) in r.json()["message"]


def test_on_failure_skip_notes_move_bases_reason_and_goes_on(sim):
    run = start(sim, {"waypoints": ["wall", "a"], "on_failure": "skip"})
    done = ended(sim, run["id"])
    assert done["state"] == "succeeded", done
    assert [m["name"] for m in done["missed"]] == ["wall"] and done["missed"][0]["reason"]
    assert [v["name"] for v in done["visited"]] == ["a"]


def test_on_failure_stop_ends_the_run_failed_with_the_reason(sim):
    run = start(sim, {"waypoints": ["a", "wall", "b"], "on_failure": "stop"})
    done = ended(sim, run["id"])
    assert done["state"] == "failed", done
    assert [v["name"] for v in done["visited"]] == ["a"] and [m["name"] for m in done["missed"]] == ["wall"]
    assert "wall" in done["message"]


def test_runs_are_listed_newest_first(sim):
    runs = sim.get("/runs").json()["runs"]
    ids = [r["id"] for r in runs]
    assert ids == sorted(ids, reverse=True) and len(ids) >= 5


def test_a_route_scheduled_for_the_next_minute_starts_by_itself_and_a_busy_one_is_skipped(sim):
    now = datetime.datetime.now()
    if now.second > 50:  # too close to the minute for the PUTs to land before it
        time.sleep(61 - now.second)
        now = datetime.datetime.now()
    minute = (now + datetime.timedelta(minutes=1)).strftime("%H:%M")
    for name, waypoints in (("first", ["a", "dock"]), ("second", ["b"])):
        r = requests.put(sim.url + "/routes/" + name, json={"waypoints": waypoints, "schedule": [minute]}, timeout=10)
        assert r.status_code == 201, r.text
    before = {r["id"] for r in sim.get("/runs").json()["runs"]}
    new = wait_for(lambda: _two_new(sim, before), timeout=75, interval=0.5, message="the scheduled runs")
    by_route = {r["route"]: r for r in new}
    assert {r["trigger"] for r in new} == {"schedule"}
    started, skipped = (by_route["first"], by_route["second"]) if by_route["second"]["state"] == "skipped" else (
        by_route["second"], by_route["first"])
    assert skipped["state"] == "skipped"
    assert skipped["message"] == "Not run at its scheduled time: the robot was doing another round ({}).".format(
        started["route"])
    assert ended(sim, started["id"])["state"] == "succeeded"


def _two_new(sim, before):
    new = [r for r in sim.get("/runs").json()["runs"] if r["id"] not in before]
    return new if len(new) >= 2 else None


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_a_run_cut_short_by_a_server_stop_is_interrupted_after_the_restart_and_resumes(sim, state, sig):
    run = start(sim, {"waypoints": ["c", "a"]})
    under_way(sim, run["id"])
    time.sleep(0.5)
    sim.proc.send_signal(sig)
    sim.proc.wait(15)
    again = SimServer(state, waypoints_text="")
    sim.__dict__.update(again.__dict__)  # the module's server is the new one from here on
    interrupted = run_of(sim, run["id"])
    assert interrupted["state"] == "interrupted" and interrupted["current"]["name"] == "c", interrupted
    assert moved(sim, 1.0) < 0.01  # the robot never drives off by itself after a restart
    assert sim.post("/runs/{}/resume".format(run["id"])).json()["state"] == "running"
    done = ended(sim, run["id"])
    assert done["state"] == "succeeded" and [v["name"] for v in done["visited"]] == ["c", "a"]
