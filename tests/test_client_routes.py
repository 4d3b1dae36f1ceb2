"""robotctl route … and robotctl runs against a live server on port 0: the real Robot on the test ROS
master, the scripted move_base stand-in, the real run executor behind the real app served by waitress."""

import signal
import subprocess
import sys
import threading
import time
import unicodedata

import pytest

from flask_move_server.core.events import EventBus
from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.robotctl import cli as client
from flask_move_server.robotctl import routes as client_routes
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import ROOT, default_sigint, serve, stop_process, wait_for
from tests.standins.move_base import ABORT_X, HOLD_X

PLACES = ("waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n  office: [3.0, 4.0, -1.0]\n  dock: [0.0, 0.0, 0.0]\n"
          "  Küche: [2.0, 2.0, 0.0]\n  forever: [{}, 0.0, 0.0]\n  nowhere: [{}, 0.0, 0.0]\n"
          "routes:\n"
          "  rounds: {{waypoints: [kitchen, office, dock], loops: 2, dwell: 0.0, on_failure: skip,"
          " schedule: ['mon-fri 09:00', '21:30']}}\n"
          "  Küche-Runde: {{waypoints: [Küche, dock]}}\n"
          "  patrol: {{waypoints: [kitchen, forever, dock], loops: 0, dwell: 1.5}}\n"
          "  doomed: {{waypoints: [kitchen, nowhere, dock]}}\n").format(HOLD_X, ABORT_X)


@pytest.fixture
def live(robot_config, ready_robot, tmp_path, monkeypatch):
    monkeypatch.setattr(client_routes, "POLL_PERIOD", 0.05)
    with open(robot_config.waypoints.file, "w", encoding="utf-8") as f:
        f.write(PLACES)
    store = WaypointStore(robot_config.waypoints.file)
    runs = RunExecutor(ready_robot, store, RunHistory(str(tmp_path / "runs.json")), events=EventBus())
    ready_robot.runs = runs
    try:
        with serve(create_app(robot_config, ready_robot, store, runs=runs)) as url:
            yield type("Live", (), {"url": url, "runs": runs, "robot": ready_robot})
    finally:
        runs.close()


def robotctl(live, *args):
    return client.main(["--url", live.url, "--request-timeout", "10", *args])


def state_of(live, run_id):
    return live.runs.get(run_id)["state"]


def going_to(live, name):
    """Wait until the active run is on its way to ``name``; its id."""
    return wait_for(lambda: (live.runs.active() or {}).get("current", {}).get("name") == name
                    and live.runs.active()["id"], message="the run to head for {}".format(name))


def one_line(err):
    return err.startswith("robotctl: ") and len(err.splitlines()) == 1 and "Traceback" not in err


# route list, route show -----------------------------------------------------------------------


def test_route_list_is_a_table(live, capsys):
    assert robotctl(live, "route", "list") == ExitStatus.OK
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["NAME", "STOPS", "LOOPS", "DWELL", "ON", "FAILURE", "SCHEDULE"]
    rows = {line.split()[0]: line for line in lines[1:]}
    assert set(rows) == {"rounds", "Küche-Runde", "patrol", "doomed"}
    assert rows["rounds"].split() == ["rounds", "3", "2", "0", "s", "skip", "mon-fri", "09:00,", "21:30"]
    assert rows["patrol"].split()[1:6] == ["3", "until", "stopped", "1.5", "s"]
    assert rows["Küche-Runde"].split()[-2:] == ["stop", "-"]
    assert {len(line.split("  ON FAILURE")[0]) for line in lines[:1]} == {len(rows["rounds"].split("  skip")[0])}
    assert robotctl(live, "route") == ExitStatus.OK  # list is the default
    assert capsys.readouterr().out.splitlines() == lines


def test_route_show_says_the_route_in_full(live, capsys):
    assert robotctl(live, "route", "show", "rounds") == ExitStatus.OK
    assert capsys.readouterr().out.splitlines() == [
        "route:      rounds",
        "stops:      kitchen -> office -> dock (3 stops)",
        "loops:      2",
        "dwell:      0 s at each stop",
        "on failure: skip (a stop it cannot reach is noted as missed, the run goes on)",
        "schedule:   mon-fri 09:00, 21:30 (the robot's local time)",
    ]


def test_unicode_route_names_in_any_normal_form(live, capsys):
    decomposed = unicodedata.normalize("NFD", "Küche-Runde")
    assert robotctl(live, "route", "show", decomposed, "--json") == ExitStatus.OK
    assert '"name": "Küche-Runde"' in capsys.readouterr().out
    assert robotctl(live, "route", "run", decomposed, "--wait") == ExitStatus.OK
    assert capsys.readouterr().out.startswith("run 1 Küche-Runde succeeded: ")


def test_an_unknown_route_exits_5_naming_close_ones(live, capsys):
    assert robotctl(live, "route", "show", "rouns") == ExitStatus.NOT_FOUND
    err = capsys.readouterr().err
    assert err == "robotctl: No route named \"rouns\". Did you mean: \"rounds\"?\n"
    assert robotctl(live, "route", "run", "zzz") == ExitStatus.NOT_FOUND
    err = capsys.readouterr().err
    assert one_line(err) and "'robotctl route list' lists them" in err
    assert live.runs.runs() == []


# route run ------------------------------------------------------------------------------------


def test_route_run_says_the_run_and_its_first_stop(live, capsys):
    assert robotctl(live, "route", "run", "rounds") == ExitStatus.OK
    assert capsys.readouterr().out == "run 1 rounds started: going to kitchen, 1 of 3, loop 1/2.\n"
    wait_for(lambda: state_of(live, 1) == "succeeded", message="the run to succeed")


def test_route_run_wait_follows_the_run_to_success(live, capsys):
    assert robotctl(live, "route", "run", "rounds", "--wait") == ExitStatus.OK
    captured = capsys.readouterr()
    assert captured.out == "run 1 rounds succeeded: Visited every waypoint (2 loops).\n"
    progress = captured.err.splitlines()  # not a terminal: a line per stop
    assert progress[0] == "run 1 rounds: loop 1/2, 1 of 3 kitchen, on the way" or \
        progress[0].startswith("run 1 rounds: loop 1/2, 1 of 3 kitchen, ")
    assert any(line.startswith("run 1 rounds: loop 2/2, 3 of 3 dock, ") for line in progress)


def test_a_run_that_fails_exits_10_with_the_servers_reason(live, capsys):
    assert robotctl(live, "route", "run", "doomed", "--wait") == ExitStatus.ABORTED
    err = capsys.readouterr().err
    assert err.endswith("robotctl: run 1 doomed failed: Could not reach nowhere: move_base aborted the goal to "
                        "'nowhere': no path.\n")


def test_a_run_canceled_while_followed_exits_11(live, capsys):
    def cancel_at_forever():
        going_to(live, "forever")
        time.sleep(0.3)  # the follower (polling every 0.05 s) shows it first
        robotctl(live, "route", "cancel")

    canceler = threading.Thread(target=cancel_at_forever)
    canceler.start()
    try:
        assert robotctl(live, "route", "run", "patrol", "--wait", "--timeout", "30") == ExitStatus.CANCELED
    finally:
        canceler.join()
    captured = capsys.readouterr()
    assert captured.out == "run 1 patrol canceled (POST /runs/1/cancel).\n"  # the cancel's own line
    assert captured.err.endswith("robotctl: run 1 patrol canceled (POST /runs/1/cancel).\n")
    assert "run 1 patrol: loop 1 (until stopped), 2 of 3 forever, " in captured.err


def test_wait_timeout_leaves_the_run_going(live, capsys):
    assert robotctl(live, "route", "run", "patrol", "--wait", "--timeout", "0.5") == ExitStatus.TIMEOUT
    assert "run 1 patrol is still running after 0.5 s; it goes on ('robotctl route cancel' ends it)." \
        in capsys.readouterr().err
    assert state_of(live, 1) == "running"


def test_a_run_while_another_is_active_is_refused_in_one_line(live, capsys):
    assert robotctl(live, "route", "run", "patrol") == ExitStatus.OK
    assert robotctl(live, "route", "run", "rounds") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert err == ("robotctl: Run 1 (patrol) is running: cancel it first ('robotctl route cancel'), "
                   "or wait until it ends.\n")


def test_a_run_while_e_stopped_is_refused(live, capsys):
    assert robotctl(live, "estop") == ExitStatus.OK
    assert robotctl(live, "route", "run", "rounds") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert one_line(err) and "e-stop" in err


# pause, resume, skip, cancel ------------------------------------------------------------------


def test_pause_resume_skip_and_cancel_act_on_the_run_under_way(live, capsys):
    assert robotctl(live, "route", "run", "patrol") == ExitStatus.OK
    going_to(live, "forever")
    capsys.readouterr()

    assert robotctl(live, "route", "pause") == ExitStatus.OK
    assert capsys.readouterr().out == ("run 1 patrol paused at forever, 2 of 3, loop 1 (until stopped): "
                                       "'robotctl route resume' goes on.\n")
    assert state_of(live, 1) == "paused"
    assert robotctl(live, "route", "pause") == ExitStatus.ERROR  # paused already: the server's refusal
    assert capsys.readouterr().err == "robotctl: Run 1 is paused: it cannot be paused now.\n"

    assert robotctl(live, "route", "skip") == ExitStatus.OK  # while paused: it stays paused, one stop on
    assert capsys.readouterr().out == ("run 1 patrol: skipped forever; paused before dock, 3 of 3, loop 1 (until "
                                       "stopped): 'robotctl route resume' goes there.\n")
    assert robotctl(live, "route", "resume") == ExitStatus.OK
    assert capsys.readouterr().out == "run 1 patrol resumed: going to dock, 3 of 3, loop 1 (until stopped).\n"
    assert state_of(live, 1) == "running"

    going_to(live, "forever")  # the next loop
    assert robotctl(live, "route", "skip") == ExitStatus.OK
    assert capsys.readouterr().out == "run 1 patrol: skipped forever; going to dock, 3 of 3, loop 2 (until stopped).\n"
    assert [(m["name"], m["loop"]) for m in live.runs.get(1)["missed"]] == [("forever", 1), ("forever", 2)]

    assert robotctl(live, "route", "cancel", "--run", "1") == ExitStatus.OK
    assert capsys.readouterr().out == "run 1 patrol canceled (POST /runs/1/cancel).\n"
    assert state_of(live, 1) == "canceled"
    wait_for(lambda: live.robot.navigation_status()["state"] != "active", message="the goal canceled")


def test_acting_without_a_run_under_way_exits_5(live, capsys):
    assert robotctl(live, "route", "pause") == ExitStatus.NOT_FOUND
    assert capsys.readouterr().err == ("robotctl: no run is under way to pause: 'robotctl runs' lists the last "
                                       "ones, 'robotctl route run NAME' starts one.\n")
    assert robotctl(live, "route", "cancel", "--run", "9") == ExitStatus.NOT_FOUND
    assert capsys.readouterr().err == ("robotctl: No run 9 is kept (the newest 50 are; 'robotctl runs' lists "
                                       "them).\n")
    assert robotctl(live, "route", "skip", "--run", "x") == ExitStatus.USAGE


def test_ctrl_c_while_following_pauses_the_run(live):
    proc = subprocess.Popen([sys.executable, "-m", "flask_move_server.robotctl.cli", "--url", live.url,
                             "route", "run", "patrol", "--wait"], cwd=ROOT, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)
    try:
        assert proc.stderr.readline().startswith("run 1 patrol: loop 1 (until stopped), 1 of 3 kitchen")
        going_to(live, "forever")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == ExitStatus.INTERRUPTED
        assert proc.stderr.read().endswith("interrupted: run 1 patrol is paused, the robot stopped "
                                           "('robotctl route resume' goes on).\n")
    finally:
        stop_process(proc)
        proc.stderr.close()
    assert state_of(live, 1) == "paused"


# runs -----------------------------------------------------------------------------------------


def test_runs_lists_the_last_runs_newest_first(live, capsys):
    assert robotctl(live, "runs") == ExitStatus.OK
    assert capsys.readouterr().out == "no runs yet: 'robotctl route run NAME' starts one.\n"
    assert robotctl(live, "route", "run", "doomed", "--wait") == ExitStatus.ABORTED
    assert robotctl(live, "route", "run", "Küche-Runde", "--wait") == ExitStatus.OK
    capsys.readouterr()

    assert robotctl(live, "runs") == ExitStatus.OK
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["ID", "ROUTE", "TRIGGER", "STATE", "VISITED", "MISSED", "STARTED", "MESSAGE"]
    newest, oldest = lines[1].split(), lines[2].split()
    assert newest[:6] == ["2", "Küche-Runde", "api", "succeeded", "2", "0"]
    assert oldest[:6] == ["1", "doomed", "api", "failed", "1", "1"]
    message = lines[2][lines[0].index("MESSAGE"):]
    assert message == "Could not reach nowhere: move_base aborted the goal to..."  # cut to 60 columns
    assert lines[1].index("Visited") == lines[0].index("MESSAGE")  # aligned
    assert robotctl(live, "runs", "--last", "1") == ExitStatus.OK
    assert len(capsys.readouterr().out.splitlines()) == 2



def test_the_servers_advice_is_said_in_robotctl_commands():
    from flask_move_server.missions.executor import NOT_NAVIGATING

    said = client_routes._robotctl_words(NOT_NAVIGATING.format("idle"))
    assert said.endswith("Choose a map to navigate on first ('robotctl map use NAME').") and "POST" not in said
    recorded = "Canceled (POST /runs/7/cancel)."  # what happened, said by whoever sent it: kept
    assert client_routes._robotctl_words(recorded) == recorded
