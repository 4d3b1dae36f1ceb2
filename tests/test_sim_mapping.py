"""The simulated SLAM on ROS: /map grows as gmapping's does, and tf map → odom corrects the odometry."""

import math
import os
import threading
from array import array

import pytest
import rospy
from nav_msgs.msg import OccupancyGrid, Odometry
from tf2_msgs.msg import TFMessage

from flask_move_server.config import FramesConfig
from flask_move_server.core.geometry import Pose2D
from flask_move_server.ros.convert import pose_from_transform, write_pose
from flask_move_server.sim import occupancy
from flask_move_server.sim.laser import Laser
from flask_move_server.sim.mapping import SimMapping
from flask_move_server.sim.slam import SlamMap
from tests.conftest import ROOT, wait_for

DEMO_MAP = os.path.join(ROOT, "config", "maps", "demo.yaml")


class StillWorld:
    """The world as SimMapping reads it: the robot's true pose, now and at any stamp."""

    def __init__(self, pose):
        self.true_pose = pose

    def pose(self):
        return self.true_pose

    def pose_at(self, stamp):
        return self.true_pose


@pytest.fixture
def mapping(ros_node, unique_name):
    slam = SlamMap.around(Laser(occupancy.load(DEMO_MAP)), margin=1.0)
    world = StillWorld(Pose2D(0.0, 0.0, 0.0))
    frames = FramesConfig(map=unique_name + "_map", odom=unique_name + "_odom", base_link=unique_name + "_base")
    part = SimMapping(ros_node, slam, world, frames, map_topic=unique_name + "/map",
                      odom_topic=unique_name + "/odom", publish_period=0.2)
    yield part, world, unique_name
    part.close()


def listen(topic, msg_type):
    got, lock = [], threading.Lock()

    def hear(msg):
        with lock:
            got.append(msg)

    return got, rospy.Subscriber(topic, msg_type, hear, queue_size=10)


def test_the_map_is_published_latched_as_the_robot_sees_it(mapping):
    part, world, name = mapping
    wait_for(lambda: part.published >= 1, message="the first /map")
    got, sub = listen(name + "/map", OccupancyGrid)   # subscribed after publishing: latched
    try:
        msg = wait_for(lambda: got and got[-1], message="/map to a late subscriber")
        slam = part.slam
        assert (msg.info.width, msg.info.height, msg.header.frame_id) == (slam.width, slam.height, name + "_map")
        assert msg.info.origin.position.x == pytest.approx(slam.origin_x)
        assert bytes(array("b", msg.data)) == slam.grid_bytes()
        assert slam.value_at(0.5, 0.5) == 0 and slam.value_at(3.97, 2.0) == 100 and slam.value_at(6.0, 4.5) == -1
    finally:
        sub.unregister()


def test_the_map_grows_as_the_robot_moves_and_is_not_rescanned_at_rest(mapping):
    part, world, name = mapping
    wait_for(lambda: part.slam.scans == 1 and part.published == 1, message="the first scan")
    assert not part.scan_once()                       # at rest: nothing to add
    world.true_pose = Pose2D(6.5, 1.2, 0.0)           # into the kitchen
    wait_for(lambda: part.slam.value_at(8.0, 1.2) == 0, message="the kitchen mapped")
    wait_for(lambda: part.published == 2, message="the grown map published")


def test_map_to_odom_makes_the_odometry_the_true_pose(mapping):
    part, world, name = mapping
    world.true_pose = Pose2D(1.0, 0.5, math.pi / 2)
    got, sub = listen("/tf", TFMessage)
    odom_pub = rospy.Publisher(name + "/odom", Odometry, queue_size=1)
    try:
        odom = Odometry()
        odom.header.frame_id = name + "_odom"
        write_pose(odom.pose.pose, Pose2D(0.5, 0.0, 0.0))   # odometry drifted: it thinks x 0.5, facing +x

        def correction():
            odom.header.stamp = rospy.Time.now()
            odom_pub.publish(odom)
            return [t for m in list(got) for t in m.transforms if t.child_frame_id == name + "_odom"]

        sent = wait_for(correction, interval=0.1, message="tf map -> odom")[-1]
        assert sent.header.frame_id == name + "_map"
        map_to_odom = pose_from_transform(sent.transform)
        # map → odom ∘ odom → base_link = the true pose
        x = map_to_odom.x + math.cos(map_to_odom.yaw) * 0.5
        y = map_to_odom.y + math.sin(map_to_odom.yaw) * 0.5
        assert (x, y, map_to_odom.yaw) == pytest.approx((1.0, 0.5, math.pi / 2), abs=1e-6)
    finally:
        sub.unregister()
        odom_pub.unregister()
