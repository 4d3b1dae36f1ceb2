"""Stopping tells the truth and happens at once: the teleop deadman, /stop, and a lost ROS master.

Real rospy and actionlib on the session's master, the real base controller on
the sim motor backend (its applied commands recorded), a scripted move_base;
for the lost master, a whole ``--sim`` server on a master this test kills.
"""

import os
import shutil
import threading
import time

import pytest

from flask_move_server.app import cli
from flask_move_server.config import DriveConfig, FramesConfig
from flask_move_server.drive import make_drive
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import ROOT, ServerProcess, free_port, start_master, stop_process, wait_for
from tests.robot_fixtures import Recorder, no_drive
from tests.standins.move_base import HOLD_X

DEADMAN = 0.3
ACCEL = 0.1  # m/s²: a ramp from the speed reached below down to 0 takes well over a second


@pytest.fixture
def driven(robot_config, ros_node, unique_name):
    """A robot whose teleop drives the real base controller (sim motors) over /cmd_vel."""
    drive_config = DriveConfig(backend="sim", cmd_vel_topic=robot_config.teleop.topic, odom_topic=unique_name + "/odom",
                               max_linear_accel=ACCEL, cmd_vel_timeout=5.0)  # the watchdog stays out of the way
    robot_config.teleop.deadman = DEADMAN
    frames = FramesConfig(odom=unique_name + "_odom", base_link=unique_name + "_base_link")
    drive = make_drive(drive_config, ros_node, frames)
    robot = cli.build_robot(robot_config, ros_node, drive)
    wait_for(lambda: robot.teleop_control._pub is not None and robot.teleop_control._pub.get_num_connections(),
             message="teleop to reach the base controller")
    yield robot, create_app(robot_config, robot, WaypointStore(robot_config.waypoints.file)).test_client()
    robot.close()
    drive.close()


def _drive_up_to(robot, client, speed=0.1):
    """Hold /teleop like a joystick page (every 0.1 s) until the base ramped up to ``speed``.

    Returns when the last /teleop was answered; at ACCEL, a ramp back down takes speed / ACCEL s.
    """
    deadline = time.monotonic() + 30
    while robot.drive.motion.velocity[0] < speed:
        assert time.monotonic() < deadline, "the base never reached {} m/s".format(speed)
        assert client.post("/teleop", json={"linear": 0.4}).status_code == 200
        time.sleep(0.1)
    assert client.post("/teleop", json={"linear": 0.4}).status_code == 200
    return time.monotonic()


def _after(history, since):
    return [(t, left) for t, left, _ in list(history) if t >= since]


def test_deadman_expiry_stops_the_motors_at_once(driven):
    robot, client = driven
    motors = robot.drive.backend
    start = time.monotonic()
    last = _drive_up_to(robot, client)
    stopped = wait_for(lambda: motors.applied()[:2] == (0.0, 0.0) and motors.applied(), timeout=10,
                       message="the motors to stop after the deadman")
    assert stopped[2] - last < DEADMAN + 0.5  # a ramp down from 0.1 m/s would take 1 s more
    moving = [(t, left) for t, left in _after(motors.history, start) if t < stopped[2]]
    assert moving[-1][1] == max(left for _, left in moving), "full speed straight to 0, no ramp steps"
    assert robot.drive.status()["watchdog_tripped"] is False and not robot.teleop_control.status()["active"]


def test_a_zero_teleop_command_still_ramps_down(driven):
    robot, client = driven
    motors = robot.drive.backend
    _drive_up_to(robot, client)
    peak = motors.applied()[0]
    zero_sent = time.monotonic()
    assert client.post("/teleop", json={"linear": 0.0}).status_code == 200
    wait_for(lambda: motors.applied()[:2] == (0.0, 0.0), timeout=10, message="the ramp to reach 0")
    steps = [left for _, left in _after(motors.history, zero_sent)]
    assert len(set(left for left in steps if 0 < left < peak)) >= 3, "gentle steps down, not a halt"


# -- /stop is truthful ----------------------------------------------------------------------------


@pytest.fixture(params=["action", "topic"])
def nav_client(request, robot_config, ros_node, unique_name):
    from actionlib_msgs.msg import GoalID

    from tests.standins.move_base import ScriptedMoveBase

    robot_config.navigation.goal_interface = request.param
    stand_in = ScriptedMoveBase(robot_config.navigation.action)
    robot = cli.build_robot(robot_config, ros_node, no_drive())
    cancels = Recorder(robot_config.navigation.action + "/cancel", GoalID)
    try:
        wait_for(robot.navigator.server_ready, timeout=15, message="goals to be sendable")
        wait_for(lambda: cancels._sub.get_num_connections(), message="the cancel topic to connect")
        # and the robot's side knowing the recorder: a cancel published before it does is lost
        sender = robot.navigator._cancel_pub or robot.navigator._client.action_client.pub_cancel
        wait_for(lambda: sender.get_num_connections(), message="the cancel publisher to know the recorder")
        app = create_app(robot_config, robot, WaypointStore(robot_config.waypoints.file))
        yield request.param, app.test_client(), stand_in, cancels
    finally:
        cancels.close()
        robot.close()
        stand_in.shutdown()


def test_status_right_after_stop_is_not_active_and_teleop_does_not_cancel_again(nav_client):
    interface, client, move_base, cancels = nav_client
    client.post("/goto", json={"x": HOLD_X, "y": 0})
    if interface == "action":
        wait_for(lambda: move_base.goals, message="move_base to take the goal")
    assert client.post("/stop").get_json()["canceled_goal"] is True

    state = client.get("/status").get_json()["navigation"]["state"]
    assert state in ("canceling", "canceled")  # action: canceling until move_base's word (or just after it)
    if interface == "topic":
        assert state == "canceled"  # no word comes in topic mode
    r = client.post("/teleop", json={"linear": 0.1})
    assert r.status_code == 200 and "canceled_goal" not in r.get_json()
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled",
             message="move_base to confirm the cancel")
    wait_for(lambda: cancels.snapshot(), message="the cancel on the wire")
    time.sleep(0.3)  # a second cancel, if the teleop had sent one, has arrived by now
    assert len(cancels.snapshot()) == 1
    assert client.post("/stop").get_json()["canceled_goal"] is False


def test_a_stop_racing_a_goto_cancels_that_goal(client, ready_robot, move_base):
    """/stop arriving while /goto is still handing its goal to move_base must cancel that goal.

    Sending a goal is slowed here (the real actionlib client, 0.3 s late) so the stop lands in
    between, as it did now and then when both came at once from two clients.
    """
    navigator = ready_robot.navigator
    real_send = navigator._client.send_goal

    def slow_send(*args, **kwargs):
        time.sleep(0.3)
        return real_send(*args, **kwargs)

    navigator._client.send_goal = slow_send
    goto = threading.Thread(target=lambda: client.post("/goto", json={"x": HOLD_X, "y": 0}))
    goto.start()
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "active", message="the goal")
    stopped = client.post("/stop").get_json()
    goto.join(10)
    assert stopped["canceled_goal"] is True
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled", timeout=5,
             message="move_base to preempt the goal the stop raced")
    # The cancel and the goal travel on two topics: move_base either preempts the goal or, when
    # the cancel comes first, recalls it unexecuted. Either way nothing is left driving.
    time.sleep(0.3)
    assert len(move_base.goals) <= 1 and not move_base.executing


def test_a_goal_sent_as_the_last_one_ends_is_heard_to_its_own_end(client, ready_robot, move_base):
    """A /goto woken by the end of the last goal sends the next while actionlib is still finishing it.

    actionlib calls the done callback before it marks the goal DONE; the next goal sent in between
    got that DONE, its own end was never heard, and /status said "active" for ever. Held open here
    (the callback lingers 0.3 s) so the next goal lands in that gap every time.
    """
    navigator = ready_robot.navigator
    real_done, ended = navigator._done, threading.Event()

    def lingering_done(seq, status):
        real_done(seq, status)
        ended.set()
        time.sleep(0.3)  # actionlib's thread, between the callback and marking the goal DONE

    navigator._done = lingering_done
    assert client.post("/goto", json={"x": 1.0, "y": 0}).status_code == 202
    assert ended.wait(10), "the first goal to end"
    navigator._done = real_done
    assert client.post("/goto", json={"x": 2.0, "y": 0}).status_code == 202
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "succeeded", timeout=10,
             message="the second goal's end")


def test_a_cancel_move_base_never_confirms_stays_canceling_and_says_why(client, ready_robot, move_base):
    ready_robot.navigator.cancel_patience = 0.5
    client.post("/goto", json={"x": HOLD_X, "y": 0})
    wait_for(lambda: move_base.goals, message="move_base to take the goal")
    move_base.ignore_cancels = True  # a hung move_base: no word on the cancel will come
    assert client.post("/stop").get_json()["canceled_goal"] is True
    nav = wait_for(lambda: client.get("/status").get_json()["navigation"]["message"]
                   and client.get("/status").get_json()["navigation"], message="the question in /status")
    assert nav["state"] == "canceling" and "has not confirmed the cancel" in nav["message"]


def test_losing_the_master_ends_a_goal_under_way(tmp_path):
    """The master dies mid-goal: /status says aborted (not active forever) and a waiting /goto answers."""
    port = free_port()
    master = start_master(port)
    uri = "http://127.0.0.1:{}".format(port)
    waypoints = tmp_path / "waypoints.yaml"
    shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), str(waypoints))
    config = tmp_path / "robot.yaml"
    config.write_text("ros:\n  master_check_period: 0.2\n  exit_on_new_master: false\n"
                      "sim:\n  stuck_timeout: 600\n")  # the sim's move_base must not end the goal itself
    env = {"ROS_MASTER_URI": uri, "ROS_HOME": str(tmp_path), "ROS_LOG_DIR": str(tmp_path / "log"),
           "ROS_IP": "127.0.0.1"}
    server = ServerProcess("--sim", "--config", str(config), "--host", "127.0.0.1", "--port", "0", "--no-mdns",
                           "--waypoints", str(waypoints), env=env, start_timeout=60)
    answers = []
    waiting = threading.Thread(target=lambda: answers.append(server.post("/goto", {"name": "kitchen", "wait": 120},
                                                                         timeout=130)))
    try:
        wait_for(lambda: server.get("/health").json()["move_base"] == "ready", timeout=30, message="move_base")
        waiting.start()
        wait_for(lambda: server.get("/status").json()["navigation"]["state"] == "active", message="the goal")
        stop_process(master)
        nav = wait_for(lambda: server.get("/status").json()["navigation"]["state"] != "active"
                       and server.get("/status").json()["navigation"], timeout=20, message="the goal to end")
        assert nav["state"] == "aborted" and "ROS master" in nav["message"]
        waiting.join(20)
        assert answers and answers[0].status_code == 409, "the waiting /goto answered"
        assert answers[0].json()["state"] == "aborted" and "ROS master" in answers[0].json()["message"]
        assert server.get("/health").json()["ros"] == "lost"
    finally:
        assert server.stop() == 0
        waiting.join(5)
        stop_process(master)
