"""A part whose ROS set-up fails is reported, not hidden behind ``"ros": "connected"``.

A real ROS master and the process's rospy node: a second RosNode object (sharing rospy) sets up
a robot whose teleop topic is empty, so rospy refuses its publisher at set-up (ValueError), as
/teleop then answers 503 whatever /health says.
"""

import pytest
import requests

from flask_move_server.app import cli
from flask_move_server.ros.node import RosNode
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import serve, wait_for
from tests.robot_fixtures import no_drive


@pytest.fixture
def node(ros_node):
    node = RosNode("setup_failure_test", check_period=0.5)
    yield node
    node.close()


def test_a_part_that_failed_its_ros_set_up_is_named_and_health_is_degraded(node, robot_config):
    robot_config.teleop.topic = ""  # rospy.Publisher raises: "topic name is not a non-empty string"
    robot = cli.build_robot(robot_config, node, no_drive())
    app = create_app(robot_config, robot, WaypointStore(robot_config.waypoints.file))
    try:
        node.start()
        assert node.wait_connected(15)
        with serve(app) as url:
            health = wait_for(lambda: requests.get(url + "/health", timeout=5).json(), message="/health")
            assert health["ros"] == "degraded"
            status = requests.get(url + "/status", timeout=5).json()
            assert status["ros"]["state"] == "degraded"
            [failed] = status["ros"]["failed_parts"]
            assert failed["part"] == "Teleop" and "topic name" in failed["error"]
            r = requests.post(url + "/teleop", json={"linear": 0.1, "angular": 0.0}, timeout=5)
            assert r.status_code == 503
    finally:
        robot.close()


def test_parts_set_up_without_failure_say_connected(node, robot_config):
    robot = cli.build_robot(robot_config, node, no_drive())
    try:
        node.start()
        assert node.wait_connected(15)
        assert robot.health()["ros"] == "connected" and robot.status()["ros"]["failed_parts"] == []
    finally:
        robot.close()


class _NodeNotYetConnected:
    """A node as it is in its first second: registering (``waiting``) with the master at ``master_uri``."""

    name = "flask_move_server_tests_waiting"
    state = "waiting"
    connected = False

    def __init__(self, uri):
        self.master_uri = uri


@pytest.mark.parametrize("answers,said", [(True, "still connecting to its ROS master"),
                                          (False, "no master answers")])
def test_a_goal_before_the_node_connected_says_whether_a_master_answers(ros_master, answers, said):
    from types import SimpleNamespace

    from flask_move_server.ros.navigator import Navigator
    from tests.conftest import free_port

    uri = ros_master if answers else "http://127.0.0.1:{}".format(free_port())  # --sim's master, or none
    message = Navigator._why_not_connected(SimpleNamespace(_node=_NodeNotYetConnected(uri)))
    assert said in message and uri in message
