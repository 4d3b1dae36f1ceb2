"""robotctl map explore against a live server on port 0: the real app served by waitress, the fake
explorer (tests/fake_explorer.py) behind it, moved on by the test or on a timer."""

import io
import sys
import threading

import pytest

from flask_move_server.core.events import EventBus
from flask_move_server.robotctl import cli as client
from flask_move_server.robotctl import explore as client_explore
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.web import create_app
from tests.conftest import serve, wait_for
from tests.fake_explorer import FakeExplorer, a_whole_exploration
from tests.fake_robot import FakeRobot


@pytest.fixture
def live(robot_config, store, monkeypatch):
    monkeypatch.setattr(client_explore, "POLL_PERIOD", 0.02)
    robot, bus = FakeRobot(), EventBus()
    explorer = FakeExplorer(bus, maps=["flat"], estop=robot.estop)
    explorer.attach(robot)
    try:
        with serve(create_app(robot_config, robot, store, events=bus, explorer=explorer)) as url:
            yield type("Live", (), {"url": url, "explorer": explorer, "robot": robot})
    finally:
        explorer.close()
        bus.close()


def robotctl(url, *args):
    return client.main(["--url", url, "--request-timeout", "10", *args])


def one_line(err):
    return err.startswith("robotctl: ") and len(err.splitlines()) == 1 and "Traceback" not in err


def test_explore_starts_it_and_says_what_comes(live, capsys):
    assert robotctl(live.url, "map", "explore", "attic") == ExitStatus.OK
    assert capsys.readouterr().out == ("exploring: the robot maps by itself for up to 30 min, comes back, saves the "
                                       "map as attic, then navigates on it ('robotctl stop' ends it).\n")
    assert live.explorer.calls == [("start", {"save_as": "attic", "then": "navigation", "max_minutes": 30.0,
                                              "return_home": True, "overwrite": False})]


def test_each_option_is_sent(live, capsys):
    assert robotctl(live.url, "map", "explore", "flat", "--then", "idle", "--max-minutes", "12.5", "--overwrite",
                    "--no-return") == ExitStatus.OK
    assert live.explorer.calls == [("start", {"save_as": "flat", "then": "idle", "max_minutes": 12.5,
                                              "return_home": False, "overwrite": True})]
    out = capsys.readouterr().out
    assert "for up to 12.5 min" in out and "then stays idle" in out, out


def test_wait_follows_it_to_the_saved_map(live, capsys):
    live.explorer.play(a_whole_exploration("attic"), period=0.1)
    assert robotctl(live.url, "map", "explore", "attic", "--wait") == ExitStatus.OK
    captured = capsys.readouterr()
    assert captured.out.startswith("explored in 0:0")
    assert captured.out.endswith(": saved the map attic (61 m² known, 5 goals, 1 unreachable); navigating on it.\n")
    lines = captured.err.splitlines()  # not a terminal: a line per goal and per state, none rewritten
    assert lines[0] == "starting: mapping starts, 0:00"
    assert "exploring: 3 frontiers left, 42 m² known, 3 goals, 1 unreachable, 0:00" in lines
    assert [line.split(":")[0] for line in lines] == ["starting"] + ["exploring"] * 5 + ["returning", "saving"]
    assert lines[-2].startswith("returning: going back to where it started, 61 m² known, 5 goals, 1 unreachable")
    assert lines[-1] == "saving: saving the map as attic, 0:00"


def test_a_failed_exploration_exits_10_with_the_robots_reason(live, capsys):
    live.explorer.play([{"state": "exploring", "frontiers": 2, "goals": 1},
                        {"state": "failed", "message": "Mapping did not start: slam_gmapping died."}], period=0.1)
    assert robotctl(live.url, "map", "explore", "attic", "--wait") == ExitStatus.ABORTED
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == "robotctl: exploration failed after 0:00: Mapping did not start: slam_gmapping died."


def test_robotctl_stop_cancels_it_and_the_follower_exits_11(live, capsys):
    live.explorer.play([{"state": "exploring", "frontiers": 4, "goals": 1}], period=0.05)

    def stop_once_exploring():
        wait_for(lambda: (live.explorer.current() or {}).get("state") == "exploring", message="exploring")
        robotctl(live.url, "stop")

    stopper = threading.Thread(target=stop_once_exploring)
    stopper.start()
    try:
        assert robotctl(live.url, "map", "explore", "attic", "--wait", "--timeout", "20") == ExitStatus.CANCELED
    finally:
        stopper.join()
    last = capsys.readouterr().err.splitlines()[-1]
    assert last == ("robotctl: exploration canceled after 0:00: Stopped ('robotctl stop'). The map made so far stays "
                    "in mapping mode, unsaved: save it ('robotctl map save NAME') or explore again."), last


def test_wait_timeout_leaves_it_going(live, capsys):
    assert robotctl(live.url, "map", "explore", "attic", "--wait", "--timeout", "0.2") == ExitStatus.TIMEOUT
    err = capsys.readouterr().err
    assert err.endswith("robotctl: still starting after 0.2 s; the exploration goes on ('robotctl stop' ends it).\n")
    assert live.explorer.current()["state"] == "starting"


def test_a_saved_name_is_refused_in_robotctls_words(live, capsys):
    assert robotctl(live.url, "map", "explore", "flat") == ExitStatus.ERROR
    assert capsys.readouterr().err == ("robotctl: a map named flat is saved already: 'robotctl map explore flat "
                                       "--overwrite' replaces it, or pick another name\n")


def test_one_under_way_is_refused_in_one_line(live, capsys):
    assert robotctl(live.url, "map", "explore", "attic") == ExitStatus.OK
    assert robotctl(live.url, "map", "explore", "cellar") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert err == ("robotctl: The robot is already exploring (to save as 'attic'): stop it first ('robotctl stop'), "
                   "or wait until it is done.\n"), err


def test_while_e_stopped_it_is_refused(live, capsys):
    assert robotctl(live.url, "estop") == ExitStatus.OK
    assert robotctl(live.url, "map", "explore", "attic") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert one_line(err) and "e-stop" in err
    assert live.explorer.current() is None


@pytest.mark.parametrize("minutes", ["0", "-1", "240.5", "nan", "many"])
def test_max_minutes_out_of_range_is_a_usage_error(live, capsys, minutes):
    assert robotctl(live.url, "map", "explore", "attic", "--max-minutes", minutes) == ExitStatus.USAGE
    assert "--max-minutes" in capsys.readouterr().err
    assert live.explorer.calls == []


def test_a_server_without_an_explorer_says_how_to_map_instead(robot_config, store, capsys):
    with serve(create_app(robot_config, FakeRobot(), store)) as url:
        assert robotctl(url, "map", "explore", "attic") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert one_line(err) and err.startswith("robotctl: This server does not explore")
    assert "'robotctl map start', then 'robotctl map save NAME'" in err, err


@pytest.mark.parametrize("seconds, shown", [(0, "0:00"), (59.9, "0:59"), (130, "2:10"), (3730, "1:02:10"),
                                            (None, "0:00")])
def test_the_clock(seconds, shown):
    assert client_explore.clock(seconds) == shown


def test_the_progress_line_in_each_state():
    exp = {"state": "exploring", "frontiers": 3, "known_m2": 42.2, "goals": 5, "unreachable": 1, "elapsed": 130,
           "save_as": "flat"}
    assert client_explore.progress(exp) == "exploring: 3 frontiers left, 42 m² known, 5 goals, 1 unreachable, 2:10"
    assert client_explore.progress(dict(exp, frontiers=1, goals=1)) == \
        "exploring: 1 frontier left, 42 m² known, 1 goal, 1 unreachable, 2:10"
    assert client_explore.progress(dict(exp, state="saving")) == "saving: saving the map as flat, 2:10"


class _Terminal(io.StringIO):
    def isatty(self):
        return True


class _Answers:
    """A client answering GET /explore from a list, one a call."""

    def __init__(self, explorations):
        self.explorations = list(explorations)

    def get(self, path):
        assert path == "/explore"
        return {"exploration": self.explorations.pop(0)}


def test_on_a_terminal_the_progress_is_one_line_rewritten(monkeypatch, capsys):
    monkeypatch.setattr(client_explore, "POLL_PERIOD", 0)
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    exp = {"state": "exploring", "frontiers": 3, "known_m2": 42.0, "goals": 5, "unreachable": 1, "elapsed": 130,
           "save_as": "flat", "then": "navigation", "map": None}
    later = [dict(exp, frontiers=2, goals=6, elapsed=140), dict(exp, state="done", map="flat", elapsed=150)]
    assert client_explore.follow_exploration(_Answers(later), exp) == ExitStatus.OK
    shown = terminal.getvalue()
    assert shown == ("\r\033[Kexploring: 3 frontiers left, 42 m² known, 5 goals, 1 unreachable, 2:10"
                     "\r\033[Kexploring: 2 frontiers left, 42 m² known, 6 goals, 1 unreachable, 2:20\n")
    assert capsys.readouterr().out == ("explored in 2:30: saved the map flat (42 m² known, 5 goals, 1 unreachable); "
                                       "navigating on it.\n")
