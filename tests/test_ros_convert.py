"""ROS message conversions (ros/convert.py) with the real message classes and a real tf2 buffer.

Messages go through their wire format (serialize, deserialize) as a subscriber
would receive them; tf2's own chaining checks that ``geometry.compose`` is
the composition tf does.
"""

import io
import math

import pytest
import rospy
import tf2_ros
from geometry_msgs.msg import Pose, PoseStamped, TransformStamped, Twist
from hypothesis import given, settings
from hypothesis import strategies as st

from flask_move_server.core.geometry import Pose2D, compose, inverse, normalize_angle
from flask_move_server.ros.convert import (
    TF_ERRORS,
    pose_from_msg,
    pose_from_transform,
    pose_stamped,
    transform_message,
    twist,
    write_pose,
)

coordinates = st.floats(-50.0, 50.0)
poses = st.builds(Pose2D, coordinates, coordinates, st.floats(-math.pi, math.pi))
relaxed = settings(deadline=None, max_examples=50)
STAMP = rospy.Time(12, 500000000)


def over_the_wire(msg):
    """``msg`` as a subscriber receives it: serialized, then read back into a fresh message."""
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return type(msg)().deserialize(buffer.getvalue())


def near(a, b, tol=1e-9):
    return math.hypot(a.x - b.x, a.y - b.y) <= tol and abs(normalize_angle(a.yaw - b.yaw)) <= tol


def buffer_with(*transforms):
    """A tf2 buffer holding ``transforms``, as a TransformListener would fill it (no node needed)."""
    buffer = tf2_ros.Buffer(debug=False)
    for t in transforms:
        buffer.set_transform(t, "test")
    return buffer


@relaxed
@given(poses)
def test_a_pose_stamped_round_trips_with_its_frame_and_stamp(pose):
    msg = over_the_wire(pose_stamped(pose, "map", STAMP))
    assert near(pose_from_msg(msg.pose), pose)
    assert (msg.header.frame_id, msg.header.stamp) == ("map", STAMP)
    o = msg.pose.orientation
    assert (msg.pose.position.z, o.x, o.y) == (0.0, 0.0, 0.0)  # planar: a rotation about z only


@relaxed
@given(poses)
def test_a_transform_round_trips_with_its_frames(pose):
    msg = over_the_wire(transform_message(pose, STAMP, "map", "odom"))
    assert isinstance(msg, TransformStamped)
    assert near(pose_from_transform(msg.transform), pose)
    assert (msg.header.frame_id, msg.child_frame_id, msg.header.stamp) == ("map", "odom", STAMP)


def test_writing_a_pose_keeps_the_height_a_marker_was_given():
    msg = Pose()
    msg.position.z = 0.4
    write_pose(msg, Pose2D(1.0, -2.0, math.pi / 2))
    assert (msg.position.x, msg.position.y, msg.position.z) == (1.0, -2.0, 0.4)
    assert pose_from_msg(msg).yaw == pytest.approx(math.pi / 2)


@relaxed
@given(poses, poses)
def test_tf_chains_transforms_as_geometry_composes_them(map_to_odom, odom_to_base):
    buffer = buffer_with(transform_message(map_to_odom, STAMP, "map", "odom"),
                         transform_message(odom_to_base, STAMP, "odom", "base_link"))
    there = buffer.lookup_transform("map", "base_link", rospy.Time(0))
    back = buffer.lookup_transform("base_link", "map", rospy.Time(0))
    assert near(pose_from_transform(there.transform), compose(map_to_odom, odom_to_base), tol=1e-6)
    assert near(pose_from_transform(back.transform), inverse(compose(map_to_odom, odom_to_base)), tol=1e-6)


def test_every_way_a_tf_lookup_fails_is_one_of_the_tf_errors():
    buffer = buffer_with(transform_message(Pose2D(1.0, 0.0, 0.0), STAMP, "map", "odom"),
                         transform_message(Pose2D(0.0, 0.0, 0.0), STAMP, "laser_mount", "laser"))
    with pytest.raises(TF_ERRORS):  # LookupException: no such frame
        buffer.lookup_transform("map", "base_link", rospy.Time(0))
    with pytest.raises(TF_ERRORS):  # ConnectivityException: two trees
        buffer.lookup_transform("map", "laser", rospy.Time(0))
    with pytest.raises(TF_ERRORS):  # ExtrapolationException: no data that late
        buffer.lookup_transform("map", "odom", STAMP + rospy.Duration(5.0))


def test_a_twist_drives_along_x_and_turns_about_z():
    msg = over_the_wire(twist(0.25, -0.5))
    assert isinstance(msg, Twist)
    assert (msg.linear.x, msg.linear.y, msg.linear.z) == (0.25, 0.0, 0.0)
    assert (msg.angular.x, msg.angular.y, msg.angular.z) == (0.0, 0.0, -0.5)


def test_an_empty_message_reads_as_the_origin_facing_along_x():
    """A PoseStamped nobody filled (w = 0): yaw 0, not NaN, so a goal at the origin stays a number."""
    assert pose_from_msg(PoseStamped().pose) == Pose2D(0.0, 0.0, 0.0)
