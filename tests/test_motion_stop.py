"""Stopping tells the truth: /stop, and a lost ROS master.

Real rospy and actionlib on the session's master, a scripted move_base; for
the lost master, a whole ``--sim`` server on a master this test kills.
"""

import os
import shutil
import threading
import time

import pytest

from flask_move_server import cli
from flask_move_server.waypoints import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import ROOT, ServerProcess, free_port, start_master, stop_process, wait_for
from tests.robot_fixtures import Recorder, no_drive
from tests.standins.move_base import HOLD_X


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
    assert state == ("canceling" if interface == "action" else "canceled")
    r = client.post("/teleop", json={"linear": 0.1})
    assert r.status_code == 200 and "canceled_goal" not in r.get_json()
    assert client.post("/stop").get_json()["canceled_goal"] is False
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled",
             message="move_base to confirm the cancel")
    wait_for(lambda: cancels.snapshot(), message="the cancel on the wire")
    time.sleep(0.3)  # a second cancel, if any were sent, has arrived by now
    assert len(cancels.snapshot()) == 1


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
