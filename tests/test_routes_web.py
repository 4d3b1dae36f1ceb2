"""Routes and runs over HTTP without ROS: validation, errors in words, the file untouched by bad input.

The app is the real one with the real waypoint store on a temporary file and the real run
executor; the robot behind it is tests/fake_robot.py (what a run does on a real robot is
tests/test_runs_sim.py's).
"""

import datetime
import time

import pytest

from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import make_route
from flask_move_server.web import create_app
from tests.conftest import wait_for
from tests.fake_robot import FakeRobot

ROUNDS = {"waypoints": ["kitchen", "office", "dock"], "loops": 2, "dwell": 5, "on_failure": "skip",
          "schedule": ["Mon-Fri 09:00", "21:30"]}


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def runs(robot, store, tmp_path):
    executor = RunExecutor(robot, store, RunHistory(str(tmp_path / "runs.json")))
    yield executor
    executor.close()


@pytest.fixture
def client(robot_config, robot, store, runs):
    return create_app(robot_config, robot, store, runs=runs).test_client()


def file_text(robot_config):
    with open(robot_config.waypoints.file, "rb") as f:
        return f.read()


def test_a_route_is_saved_in_the_waypoints_file_listed_and_read_back(client, robot_config):
    r = client.put("/routes/rounds", json=ROUNDS)
    assert r.status_code == 201 and r.get_json()["created"] is True
    route = r.get_json()["route"]
    next_run = datetime.datetime.fromisoformat(route.pop("next_run"))
    assert route == {"name": "rounds", "waypoints": ["kitchen", "office", "dock"], "loops": 2, "dwell": 5.0,
                     "on_failure": "skip", "schedule": ["mon-fri 09:00", "21:30"]}
    now = datetime.datetime.now().astimezone()
    assert now < next_run <= now + datetime.timedelta(days=1) and next_run.strftime("%H:%M") in ("09:00", "21:30")
    route["next_run"] = next_run.isoformat()
    assert client.get("/routes/rounds").get_json() == route
    assert client.get("/routes").get_json() == {"routes": [route]}
    text = file_text(robot_config).decode()
    assert "routes:\n  rounds: {waypoints: [kitchen, office, dock]" in text  # saved before the answer
    assert client.put("/routes/rounds", json={"waypoints": ["dock"], "schedule": []}).status_code == 200
    assert client.get("/routes/rounds").get_json()["waypoints"] == ["dock"]
    assert client.get("/routes/rounds").get_json()["next_run"] is None


def test_names_in_the_owners_language(client):
    r = client.put("/routes/Mum's Küche-Runde", json={"waypoints": ["kitchen"]})
    assert r.status_code == 201, r.get_json()
    assert client.get("/routes/Mum%27s%20K%C3%BCche-Runde").get_json()["name"] == "Mum's Küche-Runde"


BAD_ROUTES = [
    ({"waypoints": ["kitchen", "attic", "cellar"]}, ['"attic"', '"cellar"']),
    ({"waypoints": []}, ["'waypoints'"]),
    ({"waypoints": "kitchen"}, ["'waypoints'"]),
    ({}, ["'waypoints'"]),
    ({"waypoints": ["kitchen"], "dwell": -1}, ["'dwell'"]),
    ({"waypoints": ["kitchen"], "dwell": "5"}, ["'dwell'"]),
    ({"waypoints": ["kitchen"], "loops": -1}, ["'loops'"]),
    ({"waypoints": ["kitchen"], "loops": 1.5}, ["'loops'"]),
    ({"waypoints": ["kitchen"], "loops": True}, ["'loops'"]),
    ({"waypoints": ["kitchen"], "on_failure": "retry"}, ["'on_failure'"]),
    ({"waypoints": ["kitchen"], "schedule": ["25:00"]}, ["'schedule'", "25:00"]),
    ({"waypoints": ["kitchen"], "schedule": ["noon"]}, ["'schedule'", "noon"]),
    ({"waypoints": ["kitchen"], "schedule": ["someday 10:00"]}, ["'schedule'", "day"]),
    ({"waypoints": ["kitchen"], "schedule": "21:30"}, ["'schedule'"]),
    ({"waypoints": ["kitchen"], "stops": 3}, ["stops"]),
    ({"waypoints": ["kitchen", "a/b"]}, ["entry 2"]),
]


@pytest.mark.parametrize("body, said", BAD_ROUTES)
def test_a_bad_route_is_a_400_naming_the_field_and_nothing_is_written(client, robot_config, body, said):
    before = file_text(robot_config)
    r = client.put("/routes/rounds", json=body)
    assert r.status_code == 400, r.get_json()
    error = r.get_json()
    assert error["status"] == "error" and error["error"] in ("bad_route", "bad_request")
    for words in said:
        assert words in error["message"], error["message"]
    assert file_text(robot_config) == before


def test_a_waypoint_a_route_uses_cannot_be_deleted(client, robot_config):
    client.put("/routes/rounds", json=ROUNDS)
    before = file_text(robot_config)
    r = client.delete("/waypoints/office")
    assert r.status_code == 409 and r.get_json()["error"] == "waypoint_in_use"
    assert '"rounds"' in r.get_json()["message"]
    assert file_text(robot_config) == before
    assert client.delete("/routes/rounds").status_code == 204
    assert client.delete("/waypoints/office").status_code == 204


def test_a_renamed_waypoint_is_renamed_in_its_routes(client):
    client.put("/routes/rounds", json=ROUNDS)
    assert client.patch("/waypoints/kitchen", json={"name": "Küche"}).status_code == 200
    assert client.get("/routes/rounds").get_json()["waypoints"] == ["Küche", "office", "dock"]


def test_an_unknown_route_is_a_404_with_close_names(client):
    client.put("/routes/rounds", json=ROUNDS)
    r = client.get("/routes/round")
    assert r.status_code == 404 and r.get_json()["error"] == "unknown_route" and "rounds" in r.get_json()["message"]
    assert client.delete("/routes/nope").status_code == 404
    assert client.post("/runs", json={"route": "nope"}).status_code == 404


BAD_RUNS = [
    ({"route": "rounds", "waypoints": ["kitchen"]}, 400, "bad_request"),
    ({"waypoints": []}, 400, "bad_route"),
    ({"waypoints": ["kitchen"], "schedule": ["21:30"]}, 400, "bad_request"),
    ({"waypoints": ["kitchen"], "dwell": -2}, 400, "bad_route"),
    ({"route": 5}, 400, "bad_request"),
    ({}, 400, "bad_route"),
    ({"waypoints": ["kitchen", "attic"]}, 404, "unknown_waypoint"),
    ({"waypoints": ["kitchen"], "valid_until": 1.0}, 409, "command_late"),
]


@pytest.mark.parametrize("body, status, code", BAD_RUNS)
def test_a_bad_run_is_refused_and_nothing_moves(client, robot, body, status, code):
    r = client.post("/runs", json=body)
    assert (r.status_code, r.get_json()["error"]) == (status, code), r.get_json()
    assert robot.moved() == []
    assert client.get("/runs").get_json() == {"runs": []}


def test_a_run_starts_and_is_listed_then_paused_resumed_and_canceled(client, robot):
    client.put("/routes/rounds", json=ROUNDS)
    r = client.post("/runs", json={"route": "rounds"})
    assert r.status_code == 202
    run = r.get_json()["run"]
    assert (run["route"], run["state"], run["trigger"], run["current"]["name"]) == ("rounds", "running", "api",
                                                                                   "kitchen")
    assert [r["id"] for r in client.get("/runs").get_json()["runs"]] == [run["id"]]
    second = client.post("/runs", json={"waypoints": ["dock"]})
    assert second.status_code == 409 and second.get_json()["error"] == "run_conflict"
    wait_for(lambda: [c[0] for c in robot.calls].count("run_goto") == 1, message="kitchen sent")
    assert client.post("/runs/{}/pause".format(run["id"])).get_json()["state"] == "paused"
    assert client.post("/runs/{}/pause".format(run["id"])).status_code == 409
    assert client.post("/runs/{}/resume".format(run["id"])).get_json()["state"] == "running"
    wait_for(lambda: [c[0] for c in robot.calls].count("run_goto") == 2, message="resume sending kitchen again")
    canceled = client.post("/runs/{}/cancel".format(run["id"])).get_json()
    assert canceled["state"] == "canceled" and canceled["ended"]
    assert robot.calls[-1] == ("halt",)


def test_runs_are_refused_while_the_e_stop_is_latched(client, robot):
    robot.engage_estop("api")
    r = client.post("/runs", json={"waypoints": ["kitchen"]})
    assert r.status_code == 409 and r.get_json()["error"] == "estop_latched"


def test_unknown_runs_are_404(client):
    for path in ("/runs/999", "/runs/999/pause", "/runs/999/resume", "/runs/999/skip", "/runs/999/cancel"):
        r = client.get(path) if path == "/runs/999" else client.post(path)
        assert r.status_code == 404 and r.get_json()["error"] == "unknown_run", path


def test_without_an_executor_runs_say_so(robot_config, robot, store):
    client = create_app(robot_config, robot, store).test_client()
    r = client.post("/runs", json={"waypoints": ["kitchen"]})
    assert r.status_code == 409 and "runs no routes" in r.get_json()["message"]


class SlowToSend(FakeRobot):
    """A robot whose goals take a moment to go out (a busy Wi-Fi to move_base, a loaded Pi)."""

    def __init__(self):
        super().__init__()
        import threading

        self.sending = threading.Event()

    def run_goto(self, goal):
        self.sending.set()
        time.sleep(0.3)
        return super().run_goto(goal)


@pytest.mark.parametrize("command", ["pause", "stop"])
def test_a_goal_sent_as_the_run_is_paused_or_stopped_does_not_drive(robot_config, store, tmp_path, command):
    robot = SlowToSend()
    runs = RunExecutor(robot, store, RunHistory(str(tmp_path / "runs.json")))
    try:
        run = runs.start(make_route(None, {"waypoints": ["kitchen"]}, scheduled=False))
        robot.sending.wait(5)
        if command == "pause":
            assert runs.pause(run["id"])["state"] == "paused"
        else:
            assert runs.end_by("Stopped (POST /stop).", wait_for_send=False)
        wait_for(lambda: robot.navigation_status()["state"] == "canceled", timeout=3,
                 message="the goal sent during the {} canceled".format(command))
    finally:
        runs.close()


def test_a_timetable_that_finds_the_robot_busy_keeps_a_skipped_run_saying_what_happened(runs, robot, store):
    from flask_move_server.missions.route import Route

    rounds = Route("rounds", ("kitchen", "dock"), schedule=("21:30",))
    robot.engage_estop("api")
    skipped = runs.scheduled(rounds)
    assert (skipped["state"], skipped["trigger"]) == ("skipped", "schedule")
    assert skipped["message"] == "Not run at its scheduled time: the e-stop was on."
    robot.release_estop()
    first = runs.scheduled(rounds)
    assert first["state"] == "running"
    second = runs.scheduled(Route("night", ("office",), schedule=("21:30",)))
    assert second["message"] == "Not run at its scheduled time: the robot was doing another round (rounds)."
    assert [r["state"] for r in runs.runs()] == ["skipped", "running", "skipped"]
