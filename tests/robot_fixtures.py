"""Fixtures that assemble the real robot (rospy, actionlib, tf2) on the session's node.

Every test gets its own ROS names (action, topics, frames), so tests sharing the
one rospy node of this process never hear each other.
"""

import threading

import pytest

from flask_move_server import config
from flask_move_server.app import cli
from flask_move_server.core.events import EventBus
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.conftest import wait_for

SEED = "waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office: [5.67, 2.34, -1.57]\n  dock: [0.0, 0.0, 0.0]\n"


def make_config(name, tmp_path):
    cfg = config.Config()
    cfg.server.host = "127.0.0.1"
    cfg.server.port = 0  # a free port: never a demo's 5000
    cfg.navigation.action = name + "/move_base"
    cfg.navigation.simple_goal_topic = name + "/move_base_simple/goal"
    cfg.navigation.amcl_pose_topic = name + "/amcl_pose"
    cfg.teleop.topic = name + "/cmd_vel"
    cfg.battery.topic = name + "/battery_state"
    cfg.ros.frames.map = name + "_map"
    cfg.ros.frames.base_link = name + "_base_link"
    cfg.waypoints.file = str(tmp_path / "waypoints.yaml")
    (tmp_path / "waypoints.yaml").write_text(SEED)
    return cfg


def no_drive():
    """The ``none`` motor backend: this process drives no motors."""
    from flask_move_server.drive import NoDrive

    return NoDrive()


@pytest.fixture
def bus():
    """An in-process event bus, closed after the test."""
    events = EventBus()
    yield events
    events.close()


@pytest.fixture
def robot_config(unique_name, tmp_path):
    return make_config(unique_name, tmp_path)


@pytest.fixture
def move_base(ros_node, unique_name):
    from tests.standins.move_base import ScriptedMoveBase

    server = ScriptedMoveBase(unique_name + "/move_base")
    yield server
    server.shutdown()


@pytest.fixture
def robot(robot_config, ros_node):
    r = cli.build_robot(robot_config, ros_node, no_drive())
    yield r
    r.close()


@pytest.fixture
def ready_robot(robot, move_base):
    wait_for(robot.navigator.server_ready, timeout=15, message="the action client to see move_base")
    return robot


@pytest.fixture
def store(robot_config):
    return WaypointStore(robot_config.waypoints.file)


@pytest.fixture
def app(robot_config, robot, store):
    return create_app(robot_config, robot, store)


@pytest.fixture
def client(app):
    return app.test_client()


class Recorder:
    """Keeps every message of one topic, with the time it arrived."""

    def __init__(self, topic, msg_class):
        import rospy

        self.messages = []
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(topic, msg_class, self._on_message, queue_size=100)

    def _on_message(self, msg):
        import time

        with self._lock:
            self.messages.append((time.monotonic(), msg))

    def snapshot(self):
        with self._lock:
            return list(self.messages)

    def close(self):
        self._sub.unregister()


def publish_pose(robot_config, x, y, yaw):
    """Broadcast tf map → base_link for the robot of ``robot_config`` (one message, stamped now)."""
    import rospy
    import tf2_ros
    from geometry_msgs.msg import TransformStamped

    from flask_move_server.core.geometry import yaw_to_quaternion

    if not hasattr(publish_pose, "broadcaster"):
        publish_pose.broadcaster = tf2_ros.TransformBroadcaster()
    t = TransformStamped()
    t.header.stamp = rospy.Time.now()
    t.header.frame_id = robot_config.ros.frames.map
    t.child_frame_id = robot_config.ros.frames.base_link
    t.transform.translation.x, t.transform.translation.y = x, y
    q = yaw_to_quaternion(yaw)
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = q
    publish_pose.broadcaster.sendTransform(t)
