"""robotctl against a live server on port 0 (real Robot on the test ROS master)."""

import contextlib
import io
import json
import os
import pty
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest
import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from flask_move_server.robotctl import cli as client
from flask_move_server.robotctl import text as client_text
from flask_move_server.robotctl.api import ExitStatus
from tests.conftest import ROOT, default_sigint, serve, stop_process, wait_for
from tests.standins.move_base import ABORT_X, HOLD_X, ScriptedMoveBase


class RecordedRequests:
    """WSGI middleware keeping (method, path, JSON body) of every request the app got."""

    def __init__(self, app):
        self.app = app
        self.calls = []

    def __call__(self, environ, start_response):
        length = int(environ.get("CONTENT_LENGTH") or 0)
        raw = environ["wsgi.input"].read(length) if length else b""
        environ["wsgi.input"] = io.BytesIO(raw)
        body = json.loads(raw) if raw else None
        self.calls.append((environ["REQUEST_METHOD"], environ["PATH_INFO"], body))
        return self.app(environ, start_response)


@contextlib.contextmanager
def robot_server(ros_node, prefix, waypoints_file, token=None, move_base=True):
    """A real Robot (navigator, pose, teleop) under a real app served by waitress on port 0."""
    from flask_move_server import config as config_mod
    from flask_move_server.core.robot import Robot
    from flask_move_server.drive import NoDrive
    from flask_move_server.ros.navigator import Navigator
    from flask_move_server.ros.pose import PoseTracker
    from flask_move_server.ros.teleop import Teleop
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.web import create_app

    cfg = config_mod.Config()
    cfg.navigation.action = "/{}/move_base".format(prefix)
    cfg.navigation.amcl_pose_topic = "/{}/amcl_pose".format(prefix)
    cfg.navigation.server_wait = 2.0
    cfg.teleop.topic = "/{}/cmd_vel".format(prefix)
    stand_in = ScriptedMoveBase(cfg.navigation.action, delay=0.3) if move_base else None
    pose = PoseTracker(cfg.ros.frames, cfg.navigation.amcl_pose_topic, ros_node)
    robot = Robot(ros_node, Navigator(cfg.navigation, cfg.ros.frames, ros_node, pose), pose,
                  Teleop(cfg.teleop, ros_node), NoDrive())
    store = WaypointStore(str(waypoints_file))
    app = RecordedRequests(create_app(cfg, robot, store, token=token))
    try:
        with serve(app) as url:
            yield type("Live", (), {"url": url, "store": store, "robot": robot, "calls": app.calls,
                                    "config": cfg, "move_base": stand_in})
    finally:
        robot.close()
        if stand_in is not None:
            stand_in.shutdown()


@pytest.fixture
def live(ros_node, unique_name, tmp_path):
    waypoints = tmp_path / "waypoints.yaml"
    waypoints.write_text("waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n  office: [3.0, 4.0, -1.0]\n"
                         "  nowhere: [{}, 0.0, 0.0]\n  forever: [{}, 0.0, 0.0]\n".format(ABORT_X, HOLD_X))
    with robot_server(ros_node, unique_name, waypoints) as server:
        yield server


def robotctl(live_or_url, *args):
    url = live_or_url if isinstance(live_or_url, str) else live_or_url.url
    return client.main(["--url", url, "--request-timeout", "10", *args])


# waypoints -------------------------------------------------------------------------


def test_waypoints_table_add_and_remove(live, capsys):
    assert robotctl(live, "waypoints") == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:4] == ["NAME", "X", "[m]", "Y"]
    assert out[1].split()[:4] == ["kitchen", "1.00", "2.00", "0.50"]

    assert robotctl(live, "waypoints", "add", "living room", "-1.5", "2", "3.1416") == 0
    assert "added living room" in capsys.readouterr().out
    assert live.store.get("living room").x == -1.5

    assert robotctl(live, "waypoints", "add", "living room", "0", "0", "0") == 0
    assert "moved living room" in capsys.readouterr().out

    assert robotctl(live, "waypoints", "rm", "living room") == 0
    assert "living room" not in [wp.name for wp in live.store.all()]


def test_waypoints_add_here_uses_the_robots_pose(live, capsys):
    assert robotctl(live, "waypoints", "add", "dock", "--here") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert err.startswith("robotctl: ") and "pose is not known" in err and len(err.splitlines()) == 1

    pub = rospy.Publisher(live.config.navigation.amcl_pose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True)
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "map"
    msg.header.stamp = rospy.Time.now()
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.orientation.w = 7.0, -2.0, 1.0
    pub.publish(msg)
    wait_for(lambda: live.robot.pose.current() is not None, message="the AMCL pose to arrive")
    assert robotctl(live, "waypoints", "add", "dock", "--here") == 0
    assert live.store.get("dock").x == 7.0 and live.store.get("dock").y == -2.0
    pub.unregister()


def test_bad_waypoint_input_is_a_usage_or_request_error(live, capsys):
    assert robotctl(live, "waypoints", "add", "dock", "1", "2") == ExitStatus.USAGE
    assert "NAME X Y YAW" in capsys.readouterr().err
    assert robotctl(live, "waypoints", "add", "dock", "--here", "1", "2", "3") == ExitStatus.USAGE
    assert robotctl(live, "waypoints", "add", "bad/name", "1", "2", "3") == ExitStatus.ERROR
    assert "Invalid waypoint name" in capsys.readouterr().err
    assert robotctl(live, "teleop", "fast", "0") == ExitStatus.USAGE
    assert "'fast' is not a number" in capsys.readouterr().err
    assert robotctl(live, "waypoints", "rm", "kichen") == ExitStatus.NOT_FOUND
    assert "Did you mean: 'kitchen'" in capsys.readouterr().err
    assert [wp.name for wp in live.store.all()][:2] == ["kitchen", "office"]


# goto ------------------------------------------------------------------------------


def test_goto_sends_the_goal_and_returns(live, capsys):
    assert robotctl(live, "goto", "kitchen") == 0
    assert "going to kitchen at (x 1.00, y 2.00" in capsys.readouterr().out
    wait_for(lambda: live.move_base.goals, message="move_base to get the goal")
    assert live.move_base.goals[0][1].target_pose.pose.position.x == 1.0


def test_goto_wait_follows_the_goal_until_it_arrives(live, capsys):
    assert robotctl(live, "goto", "office", "--wait") == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == "arrived at office."
    assert "office: active" in captured.err  # the live line


def test_goto_wait_exit_status_tells_how_the_goal_ended(live, capsys):
    assert robotctl(live, "goto", "nowhere", "--wait") == ExitStatus.ABORTED
    # the very sentence the server answers a failed /goto with wait
    assert capsys.readouterr().err.endswith("robotctl: move_base aborted the goal to 'nowhere': no path.\n")

    assert robotctl(live, "goto", "forever", "--wait", "--timeout", "1") == ExitStatus.TIMEOUT
    assert "still moving to forever after 1 s" in capsys.readouterr().err
    assert live.robot.navigator.active  # a timeout stops waiting, not the robot

    stopper = threading.Timer(1.0, lambda: client.main(["--url", live.url, "stop"]))
    stopper.start()
    try:
        assert robotctl(live, "goto", "forever", "--wait") == ExitStatus.CANCELED
    finally:
        stopper.join()
    assert "was canceled" in capsys.readouterr().err

    replacer = threading.Timer(1.0, lambda: client.main(["--url", live.url, "goto", "kitchen"]))
    replacer.start()
    try:
        assert robotctl(live, "goto", "forever", "--wait") == ExitStatus.CANCELED
    finally:
        replacer.join()
    # the server's words for a waiting /goto whose goal a newer one replaced
    assert capsys.readouterr().err.endswith(
        "robotctl: The goal to 'forever' was replaced by a newer goal.\n")


def test_goto_unknown_waypoint_suggests_close_names(live, capsys):
    assert robotctl(live, "goto", "kitchn") == ExitStatus.NOT_FOUND
    err = capsys.readouterr().err
    assert err == "robotctl: No waypoint named 'kitchn'. Did you mean: 'kitchen'?\n"
    assert live.move_base.goals == []


def test_goto_without_move_base_says_so(ros_node, unique_name, tmp_path, capsys):
    waypoints = tmp_path / "w.yaml"
    waypoints.write_text("waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n")
    with robot_server(ros_node, unique_name, waypoints, move_base=False) as live:
        live.config.navigation.server_wait = 0.2
        assert robotctl(live, "goto", "kitchen", "--wait") == ExitStatus.UNAVAILABLE
    assert "move_base does not answer" in capsys.readouterr().err


# stop, teleop, status -----------------------------------------------------------------


def test_stop_and_teleop(live, capsys):
    assert robotctl(live, "teleop", "0.1", "-0.2") == 0
    assert "driving at 0.10 m/s, -0.20 rad/s for 0.5 s." in capsys.readouterr().out
    assert robotctl(live, "teleop", "5", "0") == 0
    assert "0.40 m/s" in capsys.readouterr().out
    assert robotctl(live, "stop") == 0
    assert capsys.readouterr().out == "stopped.\n"
    assert live.calls[-1][:2] == ("POST", "/stop")
    assert not live.robot.teleop_control.status()["active"]


def test_estop_latches_until_estop_release(live, capsys):
    assert robotctl(live, "estop") == 0
    assert "e-stop latched" in capsys.readouterr().out
    assert live.calls[-1][:2] == ("POST", "/estop") and live.robot.estop.latched
    assert robotctl(live, "teleop", "0.1", "0") == ExitStatus.ERROR
    err = capsys.readouterr().err
    assert "e-stop is latched" in err and "robotctl estop release" in err and len(err.splitlines()) == 1
    assert robotctl(live, "status") == 0
    assert "e-stop:     LATCHED by api since " in capsys.readouterr().out
    assert robotctl(live, "estop", "release") == 0
    assert capsys.readouterr().out == "e-stop released: goals and teleop are accepted again.\n"
    assert robotctl(live, "estop", "release") == 0
    assert capsys.readouterr().out == "the e-stop was not latched.\n"
    assert robotctl(live, "teleop", "0.1", "0") == 0
    assert robotctl(live, "status") == 0
    assert "e-stop:     off" in capsys.readouterr().out.splitlines()
    assert robotctl(live, "estop", "now") == ExitStatus.USAGE


@pytest.mark.parametrize("mode,line", [
    ({"mode": "idle", "map": None, "state": "running"}, "idle"),
    ({"mode": "navigation", "map": "flat", "state": "running"}, "navigation on flat"),
    ({"mode": "mapping", "map": None, "state": "starting"}, "mapping (starting)"),
    ({"mode": "mapping", "map": None, "state": "failed", "message": "gmapping is not installed"},
     "mapping FAILED: gmapping is not installed"),
])
def test_status_says_the_mode_and_map(mode, line):
    lines = client_text.describe_status({"ros": {"state": "connected"}, "mode": mode}, "http://robot.local:5000")
    assert lines[1] == "mode:       " + line


def test_a_pose_a_hair_below_zero_reads_as_zero():
    assert client_text.xy_yaw({"x": -0.001, "y": 2.0, "yaw": -0.0001}) == "x 0.00, y 2.00, yaw 0.00 rad (0 deg)"
    assert client_text.xy_yaw({"x": 1.0, "y": -2.5, "yaw": -1.5708}) == "x 1.00, y -2.50, yaw -1.57 rad (-90 deg)"


def test_status_summary_and_json(live, capsys):
    assert robotctl(live, "goto", "forever") == 0
    capsys.readouterr()
    assert robotctl(live, "status") == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "robot:      {} (ROS connected)".format(live.url)
    assert lines[1] == "mode:       navigation on the stack's own map"  # modes off: the stack runs outside
    assert lines[2].startswith("pose:       unknown")
    assert lines[3].startswith("navigation: active -> forever")
    assert robotctl(live, "status", "--json") == 0
    data = json.loads(capsys.readouterr().out)
    assert data["navigation"]["target"] == "forever"
    assert robotctl(live, "stop") == 0


# failures --------------------------------------------------------------------------


def _closed_port():
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_no_robot_answering_suggests_discover(capsys):
    url = "http://127.0.0.1:{}".format(_closed_port())
    assert robotctl(url, "status") == ExitStatus.UNREACHABLE
    err = capsys.readouterr().err
    assert err.startswith("robotctl: no robot answers at {} (connection refused)".format(url))
    assert "robotctl discover" in err and "Traceback" not in err and len(err.splitlines()) == 1


def test_a_silent_server_times_out(capsys):
    with contextlib.closing(socket.socket()) as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)  # connections queue, nobody answers
        url = "http://127.0.0.1:{}".format(silent.getsockname()[1])
        assert client.main(["--url", url, "--request-timeout", "0.5", "stop"]) == ExitStatus.UNREACHABLE
    err = capsys.readouterr().err
    assert "did not answer within 0.5 s" in err and "robotctl discover" in err


def test_token_missing_or_wrong(ros_node, unique_name, tmp_path, capsys, monkeypatch):
    with robot_server(ros_node, unique_name, tmp_path / "w.yaml", token="s3cret", move_base=False) as live:
        assert robotctl(live, "waypoints") == ExitStatus.UNAUTHORIZED
        assert "needs a token: pass --token TOKEN or set ROBOT_TOKEN" in capsys.readouterr().err
        assert robotctl(live, "--token", "nope", "waypoints") == ExitStatus.UNAUTHORIZED
        assert "refused the token" in capsys.readouterr().err
        monkeypatch.setenv("ROBOT_TOKEN", "s3cret")
        monkeypatch.setenv("ROBOT_URL", live.url)
        assert client.main(["waypoints"]) == 0
        assert "no waypoints yet" in capsys.readouterr().out


def test_a_server_that_is_not_a_robot(capsys):
    def not_a_robot(environ, start_response):
        start_response("404 Not Found", [("Content-Type", "text/html")])
        return [b"<html>nope</html>"]

    with serve(not_a_robot) as url:
        assert robotctl(url, "goto", "kitchen") == ExitStatus.ERROR
    assert "not as a flask-move-server robot does: is --url right?" in capsys.readouterr().err


def test_debug_shows_the_traceback(capsys):
    url = "http://127.0.0.1:{}".format(_closed_port())
    assert client.main(["--url", url, "--debug", "stop"]) == ExitStatus.UNREACHABLE
    err = capsys.readouterr().err
    assert "Traceback" in err and err.rstrip().endswith("then pass --url or set ROBOT_URL.")


def test_usage_errors_exit_2_with_one_line(capsys):
    for argv, says in (([], "the following arguments are required: COMMAND"),
                       (["fly"], "invalid choice: 'fly'"),
                       (["--request-timeout", "0", "stop"], "'0' must be greater than 0"),
                       (["goto"], "robotctl goto: error: the following arguments are required: name")):
        assert client.main(argv) == ExitStatus.USAGE
        err = capsys.readouterr().err
        assert says in err and err.endswith("--help shows the usage)\n") and len(err.splitlines()) == 1


def test_goto_wait_polls_rather_than_blocking(live):
    start = len(live.calls)
    assert robotctl(live, "goto", "kitchen", "--wait") == 0
    calls = live.calls[start:]
    assert calls[0] == ("POST", "/goto", {"name": "kitchen"})
    assert all(c[:2] == ("GET", "/status") for c in calls[1:]) and len(calls) >= 2


# drive through a pty ---------------------------------------------------------------


@contextlib.contextmanager
def drive_in_pty(url):
    """``robotctl drive`` as a process whose terminal is a pty we type into."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "flask_move_server.robotctl.cli", "--url", url, "drive"],
                            stdin=slave, stdout=slave, stderr=slave, cwd=ROOT, start_new_session=True)
    os.close(slave)
    try:
        yield proc, master
    finally:
        stop_process(proc)
        with contextlib.suppress(OSError):
            os.close(master)


def _teleops(calls):
    return [c[2] for c in calls if c[:2] == ("POST", "/teleop")]


def _stops(calls):
    return [c for c in calls if c[:2] == ("POST", "/stop")]


def test_drive_keys_become_teleop_and_release_stops(live):
    with drive_in_pty(live.url) as (proc, keys):
        wait_for(lambda: os.read(keys, 1024), message="the drive help line")
        os.write(keys, b"w")
        wait_for(lambda: _teleops(live.calls), message="a /teleop call")
        first = _teleops(live.calls)[0]
        assert (first["linear"], first["angular"]) == (0.2, 0.0)
        assert abs(first["valid_until"] - (time.monotonic() + 1.0)) < 0.5, "refused by the robot if it arrives late"
        for _ in range(8):  # hold the key: auto-repeat
            os.write(keys, b"w")
            threading.Event().wait(0.1)
        assert len(_teleops(live.calls)) >= 2 and not _stops(live.calls)
        wait_for(lambda: _stops(live.calls), message="a /stop when the key is released")

        os.write(keys, b"\x1b[D")  # left arrow: turn on the spot
        wait_for(lambda: (_teleops(live.calls)[-1]["linear"], _teleops(live.calls)[-1]["angular"]) == (0.0, 0.8),
                 message="a left turn")
        stops = len(_stops(live.calls))
        os.write(keys, b" ")
        wait_for(lambda: len(_stops(live.calls)) > stops, message="space to stop")

        os.write(keys, b"dq")
        assert proc.wait(15) == 0
    assert live.calls[-1][:2] == ("POST", "/stop")  # quit stops the robot, whatever was held


def test_drive_stops_the_robot_when_the_terminal_closes(live):
    with drive_in_pty(live.url) as (proc, keys):
        wait_for(lambda: os.read(keys, 1024), message="the drive help line")
        os.write(keys, b"s")
        wait_for(lambda: _teleops(live.calls), message="a /teleop call")
        assert (_teleops(live.calls)[0]["linear"], _teleops(live.calls)[0]["angular"]) == (-0.2, 0.0)
        os.close(keys)
        assert proc.wait(15) == 0
    assert live.calls[-1][:2] == ("POST", "/stop")


def test_drive_needs_a_terminal(live, capsys):
    assert robotctl(live, "drive") == ExitStatus.USAGE  # pytest's stdin is not a tty
    assert "drive needs a terminal" in capsys.readouterr().err


def test_ctrl_c_while_waiting_stops_the_robot(live):
    proc = subprocess.Popen([sys.executable, "-m", "flask_move_server.robotctl.cli", "--url", live.url,
                             "goto", "forever", "--wait"], cwd=ROOT, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)
    try:
        assert proc.stderr.readline().startswith("forever: active")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == ExitStatus.INTERRUPTED
        assert proc.stderr.read() == "interrupted: the robot was stopped.\n"
    finally:
        stop_process(proc)
        proc.stderr.close()
    assert live.calls[-1][:2] == ("POST", "/stop")
    wait_for(lambda: live.robot.navigator.status()["state"] == "canceled", message="the goal canceled")


def test_drive_tells_a_late_command_and_keeps_driving(live, monkeypatch):
    """A joystick command the robot refused as late (a stalled Wi-Fi) is said, and drive goes on."""
    from flask_move_server.core.errors import ClientError
    from flask_move_server.robotctl.api import RobotClient
    from flask_move_server.robotctl.keyboard import KeyboardDriver

    driver = KeyboardDriver(RobotClient(live.url))
    assert driver.clock.sync() and driver.clock.deadline(1.0)["valid_until"] > time.monotonic()
    shown = []
    driver._show = shown.append
    driver.command = (0.2, 0.0)
    late = ClientError("This joystick command reached the robot 3.0 s after its deadline", ExitStatus.ERROR)
    late.body = {"status": "error", "error": "command_late"}
    monkeypatch.setattr(driver.client, "post", lambda path, body=None: (_ for _ in ()).throw(late))
    driver._send(time.monotonic())
    assert "dropped that command" in shown[-1]
    monkeypatch.undo()
    driver._send(time.monotonic())
    assert _teleops(live.calls)[-1]["linear"] == 0.2
