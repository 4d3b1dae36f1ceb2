"""``ros/initial_pose.py``: the robot's pose sent to localization as RViz's 2D Pose Estimate sends it."""

import math

from geometry_msgs.msg import PoseWithCovarianceStamped

from flask_move_server.core.geometry import Pose2D, quaternion_to_yaw
from flask_move_server.ros.initial_pose import InitialPose
from tests.conftest import wait_for
from tests.robot_fixtures import Recorder


def test_the_estimate_reaches_a_subscriber_with_rviz_covariance(ros_node, unique_name):
    topic = unique_name + "/initialpose"
    recorder = Recorder(topic, PoseWithCovarianceStamped)
    publisher = InitialPose(topic, unique_name + "_map", ros_node)
    try:
        heard = publisher.publish(Pose2D(1.5, -2.0, 0.75))  # waits for the subscriber to connect
        assert heard == 1
        wait_for(recorder.snapshot, 5, message="the estimate")
        msg = recorder.snapshot()[0][1]
    finally:
        publisher.close()
        publisher.close()
        recorder.close()
    assert msg.header.frame_id == unique_name + "_map" and msg.header.stamp.to_sec() > 0
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    assert (p.x, p.y) == (1.5, -2.0)
    assert math.isclose(quaternion_to_yaw(o.x, o.y, o.z, o.w), 0.75)
    covariance = list(msg.pose.covariance)
    assert covariance[0] == covariance[7] == 0.25
    assert math.isclose(covariance[35], 0.06853891945200942)
    assert sum(covariance) == 0.5 + covariance[35]
