"""Planar poses to and from ROS messages, written once for every part that speaks ROS.

The server's navigator and pose tracker, the base controller, the simulated
world and move_base, and the recorder all meet the same few messages
(geometry_msgs Pose, PoseStamped, Transform, TransformStamped, Twist; the sim's
stand-ins for gmapping, map_server and move_base, a nav_msgs/OccupancyGrid and Path). A
planar pose keeps x, y and the rotation about z; z, roll and pitch are zero
on the way out and ignored on the way in. The maths itself is in
:mod:`flask_move_server.core.geometry`.
"""

import math
import time

import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, TransformStamped, Twist
from nav_msgs.msg import OccupancyGrid, Path

from flask_move_server.core.geometry import Pose2D, quaternion_to_yaw, yaw_to_quaternion

# What a tf lookup raises when the frames are not (yet) connected at that time.
TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException)


def stamp_now(stamp):
    """Set the genpy Time ``stamp`` to rospy's now (ROS time under /use_sim_time, else the wall
    clock, as ``rospy.Time.now()``), in place; returns it. A /goto stamps a message built ahead for
    it: the first ``rospy.Time`` a request built cost ~0.02-0.03 ms (bench/bench_goals.py --stages)."""
    if rospy.rostime.is_wallclock():
        now = time.time()
        stamp.secs = int(now)
        stamp.nsecs = int((now - stamp.secs) * 1000000000)
    else:
        now = rospy.get_rostime()
        stamp.secs, stamp.nsecs = now.secs, now.nsecs
    return stamp


def pose_from_msg(msg):
    """The :class:`Pose2D` of a geometry_msgs/Pose: its position and the yaw of its orientation."""
    p, o = msg.position, msg.orientation
    return Pose2D(p.x, p.y, quaternion_to_yaw(o.x, o.y, o.z, o.w))


def pose_from_transform(msg):
    """The :class:`Pose2D` of a geometry_msgs/Transform: the child frame's origin and heading in the parent."""
    p, r = msg.translation, msg.rotation
    return Pose2D(p.x, p.y, quaternion_to_yaw(r.x, r.y, r.z, r.w))


def write_pose(msg, pose):
    """Set the geometry_msgs/Pose ``msg`` to the planar ``pose`` (x, y, yaw; z left as it is); returns ``msg``."""
    msg.position.x, msg.position.y = pose.x, pose.y
    o = msg.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(pose.yaw)
    return msg


def pose_stamped(pose, frame, stamp):
    """A geometry_msgs/PoseStamped of ``pose`` in ``frame`` at ``stamp`` (a rospy.Time)."""
    msg = PoseStamped()
    msg.header.frame_id, msg.header.stamp = frame, stamp
    write_pose(msg.pose, pose)
    return msg


def transform_message(pose, stamp, parent, child):
    """The tf ``parent`` → ``child`` (geometry_msgs/TransformStamped) that places ``child`` at ``pose``."""
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id, t.child_frame_id = parent, child
    t.transform.translation.x, t.transform.translation.y = pose.x, pose.y
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = yaw_to_quaternion(pose.yaw)
    return t


def twist(linear, angular):
    """A geometry_msgs/Twist for a planar base: ``linear`` m/s along x, ``angular`` rad/s about z."""
    msg = Twist()
    msg.linear.x, msg.angular.z = linear, angular
    return msg


def occupancy_grid(frame, stamp, resolution, width, height, origin_x, origin_y, data):
    """A nav_msgs/OccupancyGrid of ``data`` (row-major cells, -1 unknown, 0..100), its origin unrotated."""
    msg = OccupancyGrid()
    msg.header.frame_id = frame
    msg.header.stamp = stamp
    info = msg.info
    info.map_load_time = stamp
    info.resolution = resolution
    info.width, info.height = width, height
    info.origin.position.x, info.origin.position.y = origin_x, origin_y
    info.origin.orientation.w = 1.0
    msg.data = data
    return msg


def path_message(points, frame, stamp):
    """A nav_msgs/Path through ``points`` (x, y), each pose facing the next point."""
    msg = Path()
    msg.header.frame_id, msg.header.stamp = frame, stamp
    for i, (x, y) in enumerate(points):
        a, b = (points[i], points[i + 1]) if i + 1 < len(points) else (points[max(0, i - 1)], points[i])
        yaw = math.atan2(b[1] - a[1], b[0] - a[0]) if a != b else 0.0
        msg.poses.append(pose_stamped(Pose2D(x, y, yaw), frame, stamp))
    return msg
