"""The e-stop latch: POST /estop stops everything and refuses motion until POST /estop/release.

Against the real robot (rospy, actionlib, a scripted move_base), the real base
controller on the sim motor backend, and the e-stop button on the RPi.GPIO stand-in.
"""

import datetime
import time

import pytest

from flask_move_server.app import cli
from flask_move_server.config import DriveConfig, FramesConfig
from flask_move_server.drive import make_drive
from flask_move_server.drive.estop import EStop
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import wait_for
from tests.standins.gpio import HIGH, LOW, RecordingGPIO
from tests.standins.move_base import HOLD_X

BUTTON = 26


@pytest.fixture
def sim_drive_config(unique_name):
    return DriveConfig(backend="sim", cmd_vel_topic=unique_name + "/cmd_vel", odom_topic=unique_name + "/odom")


@pytest.fixture
def moving_robot(robot_config, ros_node, sim_drive_config, unique_name):
    """A robot with the real base controller on the sim motors, sharing one e-stop latch."""
    estop = EStop()
    frames = FramesConfig(odom=unique_name + "_odom", base_link=unique_name + "_base_link")
    drive = make_drive(sim_drive_config, ros_node, frames, estop=estop)
    robot = cli.build_robot(robot_config, ros_node, drive, estop)
    yield robot
    robot.close()
    drive.close()


def _app(robot_config, robot):
    return create_app(robot_config, robot, WaypointStore(robot_config.waypoints.file)).test_client()


def _assert_refused_with_the_way_out(response):
    """A 409 naming both ways to release; ``response``: the test client's or requests'."""
    body = response.get_json() if hasattr(response, "get_json") else response.json()
    assert response.status_code == 409, body
    assert body["status"] == "error" and body["error"] == "estop_latched"
    assert "POST /estop/release" in body["message"] and "robotctl estop release" in body["message"]


def test_estop_cancels_the_goal_ends_teleop_and_refuses_both_until_released(client, ready_robot, move_base):
    client.post("/goto", json={"x": HOLD_X, "y": 0})
    wait_for(lambda: move_base.goals, message="the goal to reach move_base")
    client.post("/teleop", json={"linear": 0.1})
    before = datetime.datetime.now(datetime.timezone.utc)

    r = client.post("/estop")
    assert r.status_code == 200 and r.get_json()["estop"]["latched"] is True
    status = client.get("/status").get_json()
    assert status["estop"]["latched"] is True and status["estop"]["source"] == "api"
    since = datetime.datetime.fromisoformat(status["estop"]["since"])
    assert before - datetime.timedelta(seconds=1) <= since <= datetime.datetime.now(datetime.timezone.utc)
    assert status["navigation"]["state"] in ("canceling", "canceled") and status["teleop"]["active"] is False
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled",
             message="move_base to confirm the cancel")

    _assert_refused_with_the_way_out(client.post("/goto", json={"name": "dock"}))
    _assert_refused_with_the_way_out(client.post("/teleop", json={"linear": 0.1}))
    assert len(move_base.goals) == 1 and client.get("/status").get_json()["teleop"]["active"] is False

    r = client.post("/estop/release")
    assert r.status_code == 200 and r.get_json()["estop"] == {"latched": False, "source": None, "since": None}
    assert client.get("/status").get_json()["navigation"]["state"] == "canceled"  # releasing moves nothing
    assert client.post("/goto", json={"name": "dock", "wait": 30}).status_code == 200


def test_estop_halts_the_motors_at_once_and_the_base_refuses_cmd_vel(moving_robot, robot_config, sim_drive_config):
    import rospy
    from geometry_msgs.msg import Twist

    drive, client = moving_robot.drive, _app(robot_config, moving_robot)
    pub = rospy.Publisher(sim_drive_config.cmd_vel_topic, Twist, queue_size=1)
    try:
        wait_for(lambda: pub.get_num_connections(), message="the base controller to subscribe")
        fast = Twist()
        fast.linear.x = 0.3
        wait_for(lambda: pub.publish(fast) or drive.status()["left"] > 0.5, interval=0.05,
                 message="the motors to turn")
        assert client.post("/estop").status_code == 200
        assert drive.backend.applied()[:2] == (0.0, 0.0)  # at once, not ramped

        for _ in range(10):  # whoever publishes /cmd_vel now (move_base, a joystick node) moves nothing
            pub.publish(fast)
            time.sleep(0.05)
        wait_for(lambda: drive.status()["estop_refused_commands"] > 0, message="a /cmd_vel to arrive and be refused")
        assert drive.status()["left"] == 0.0 and drive.backend.applied()[:2] == (0.0, 0.0)

        client.post("/estop/release")
        assert drive.status()["left"] == 0.0  # a release moves nothing by itself
        refused = drive.status()["estop_refused_commands"]
        for _ in range(10):  # ...nor does the node still streaming the command it sent before (IEC 60204-1)
            pub.publish(fast)
            time.sleep(0.05)
        wait_for(lambda: drive.status()["estop_refused_commands"] > refused, message="the stream refused")
        assert drive.status()["left"] == 0.0 and drive.status()["awaiting_zero"] is True
        wait_for(lambda: pub.publish(Twist()) or not drive.status()["awaiting_zero"], interval=0.05,
                 message="a zero command (the stick let go) to re-arm")
        wait_for(lambda: pub.publish(fast) or drive.status()["left"] > 0, interval=0.05,
                 message="commands to be obeyed again")
    finally:
        pub.unregister()


def test_after_a_release_a_new_teleop_from_the_api_moves_the_robot(moving_robot, robot_config):
    """A deliberate command after the release (teleop, a goal) re-arms at once: no zero needed first."""
    drive, client = moving_robot.drive, _app(robot_config, moving_robot)
    assert client.post("/estop").status_code == 200
    client.post("/estop/release")
    assert drive.status()["awaiting_zero"] is True
    wait_for(lambda: drive.status()["left"] > 0 or client.post("/teleop", json={"linear": 0.3}).status_code != 200
             and False, interval=0.1, message="the teleop command to drive the motors")
    assert drive.status()["awaiting_zero"] is False


def test_the_latch_and_the_watchdog_work_with_ros_down(robot_config, sim_drive_config):
    """No master ever answers: the latch still halts the motors and refuses teleop (409, not 503)."""
    from flask_move_server.ros.node import RosNode

    node = RosNode("never_connected")  # not started: ROS is down for this robot
    estop = EStop()
    sim_drive_config.cmd_vel_timeout = 0.3
    drive = make_drive(sim_drive_config, node, robot_config.ros.frames, estop=estop)
    robot = cli.build_robot(robot_config, node, drive, estop)
    client = _app(robot_config, robot)
    try:
        assert drive.command(0.3, 0.0)  # the last /cmd_vel before ROS went away
        wait_for(lambda: drive.status()["watchdog_tripped"], message="the watchdog with ROS down")
        assert drive.backend.applied()[:2] == (0.0, 0.0)
        assert drive.command(0.3, 0.0)
        assert client.post("/estop").status_code == 200
        assert drive.backend.applied()[:2] == (0.0, 0.0) and not drive.command(0.3, 0.0)
        _assert_refused_with_the_way_out(client.post("/teleop", json={"linear": 0.1}))
        assert client.get("/status").get_json()["estop"]["latched"] is True
        assert client.post("/estop/release").get_json()["estop"]["latched"] is False
        assert client.post("/teleop", json={"linear": 0.1}).status_code == 503  # now ROS is the reason
    finally:
        robot.close()
        drive.close()


def test_estop_takes_any_body_and_release_is_idempotent(client):
    assert client.post("/estop", data=b"{not json").status_code == 200
    assert client.post("/estop").get_json()["engaged"] is False  # already latched: still stops, stays latched
    assert client.post("/estop/release").get_json()["released"] is True
    r = client.post("/estop/release")
    assert r.status_code == 200 and r.get_json()["released"] is False
    assert client.get("/estop").status_code == 405


def test_estop_needs_the_token_like_every_route(robot_config, robot, store):
    token_client = create_app(robot_config, robot, store, token="s3cret").test_client()
    for path in ("/estop", "/estop/release"):
        assert token_client.post(path).status_code == 401
    assert robot.estop.latched is False
    assert token_client.post("/estop", headers={"Authorization": "Bearer s3cret"}).status_code == 200


# -- the e-stop button (drive.estop_pin) on the RPi.GPIO stand-in ------------------------------------


@pytest.fixture
def gpio():
    return RecordingGPIO()


def _button(gpio, estop, debounce=0.05, pin=BUTTON, **drive):
    from flask_move_server.drive.estop_button import EStopButton

    return EStopButton(DriveConfig(estop_pin=pin, estop_debounce=debounce, **drive), estop, gpio=gpio)


def test_a_button_press_latches_and_release_waits_for_the_button(client, robot, gpio):
    button = _button(gpio, robot.estop)
    try:
        assert ("setup", BUTTON, gpio.IN, gpio.PUD_UP) in gpio.calls  # pull-up, so pressed = low
        gpio.drive_input(BUTTON, LOW)
        wait_for(lambda: robot.estop.latched, message="the press to latch the e-stop")
        assert client.get("/status").get_json()["estop"]["source"] == "button"
        _assert_refused_with_the_way_out(client.post("/teleop", json={"linear": 0.1}))

        r = client.post("/estop/release")
        assert r.status_code == 409 and r.get_json()["error"] == "estop_button_pressed"
        assert "still pressed" in r.get_json()["message"] and robot.estop.latched
        gpio.drive_input(BUTTON, HIGH)
        assert robot.estop.latched  # letting go of the button does not release the latch
        assert client.post("/estop/release").status_code == 200 and not robot.estop.latched
    finally:
        button.close()
    button.close()
    assert BUTTON in gpio.cleaned and BUTTON not in gpio.detects


def test_a_glitch_shorter_than_the_debounce_does_not_latch(gpio):
    estop = EStop()
    button = _button(gpio, estop, debounce=0.2)
    try:
        gpio.drive_input(BUTTON, LOW)  # a spike from the motor wires: low for a moment
        gpio.drive_input(BUTTON, HIGH)
        time.sleep(0.6)  # the callback has looked again after its debounce
        assert not estop.latched
        gpio.drive_input(BUTTON, LOW)  # a real press: held
        wait_for(lambda: estop.latched, message="the held press to latch")
    finally:
        button.close()


def test_a_button_held_at_start_up_latches_at_once(gpio):
    estop = EStop()
    gpio.drive_input(BUTTON, LOW)  # held down before the server starts
    button = _button(gpio, estop)
    try:
        assert estop.status()["latched"] and estop.status()["source"] == "button"
    finally:
        button.close()


def test_the_button_pin_is_checked(tmp_path, gpio):
    from flask_move_server import config
    from flask_move_server.core.errors import ConfigError

    path = tmp_path / "robot.yaml"
    path.write_text("drive:\n  estop_pin: 40\n")
    with pytest.raises(ConfigError) as err:
        config.load(str(path))
    assert err.value.key == "drive.estop_pin" and "0 to 27" in err.value.reason
    with pytest.raises(ConfigError) as err:
        _button(gpio, EStop(), backend="l298n", pin=17)
    assert err.value.key == "drive.estop_pin" and "drive.l298n.left[0].in1" in err.value.reason
    assert gpio.calls == []  # nothing touched


def test_the_server_process_wires_the_latch_to_the_motors(ros_master, tmp_path):
    from tests.conftest import ServerProcess

    env = {"ROS_MASTER_URI": ros_master, "ROS_HOME": str(tmp_path), "ROS_IP": "127.0.0.1"}
    server = ServerProcess("--host", "127.0.0.1", "--port", "0", "--no-mdns", "--motor-backend", "sim",
                           "--waypoints", str(tmp_path / "waypoints.yaml"), "__name:=estop_process_test",
                           "cmd_vel:=/estop_process_test/cmd_vel", env=env)
    try:
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30, message="ROS")
        wait_for(lambda: server.post("/teleop", {"linear": 0.3}).status_code == 200
                 and server.get("/status").json()["motors"]["left"] > 0, message="the motors to turn")
        assert server.post("/estop").json()["estop"]["source"] == "api"
        status = server.get("/status").json()
        assert status["motors"]["left"] == 0.0 and status["estop"]["latched"] is True
        _assert_refused_with_the_way_out(server.post("/teleop", {"linear": 0.3}))
        assert server.post("/estop/release").status_code == 200
    finally:
        assert server.stop() == 0

