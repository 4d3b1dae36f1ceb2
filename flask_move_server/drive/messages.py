"""The base controller's ROS side: ``/cmd_vel`` in, ``/odom`` and tf ``odom → base_link`` out."""

import rospy
import tf2_ros
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry as OdometryMsg

from flask_move_server.ros.convert import transform_message, write_pose


class OdometryPublisher:
    """Subscribes ``cmd_vel`` (tcp_nodelay) and publishes odometry and, unless disabled, its tf."""

    def __init__(self, config, frames, on_cmd_vel):
        self.frames = frames
        self._odom = rospy.Publisher(config.odom_topic, OdometryMsg, queue_size=5)
        self._tf = tf2_ros.TransformBroadcaster() if config.publish_tf else None
        self._sub = rospy.Subscriber(config.cmd_vel_topic, Twist, on_cmd_vel, queue_size=1, tcp_nodelay=True)

    def publish(self, odometry):
        """Publish one odometry reading (and its transform) stamped now."""
        stamp = rospy.Time.now()
        self._odom.publish(odometry_message(odometry, stamp, self.frames))
        if self._tf is not None:
            self._tf.sendTransform(transform_message(odometry.pose, stamp, self.frames.odom, self.frames.base_link))

    def close(self):
        """Unsubscribe and unadvertise. Idempotent."""
        self._sub.unregister()
        self._odom.unregister()


def odometry_message(odometry, stamp, frames):
    """A nav_msgs/Odometry of ``odometry`` (pose in odom, twist in base_link)."""
    msg = OdometryMsg()
    msg.header.stamp = stamp
    msg.header.frame_id = frames.odom
    msg.child_frame_id = frames.base_link
    write_pose(msg.pose.pose, odometry.pose)
    msg.pose.covariance = odometry.pose_covariance()
    msg.twist.twist.linear.x = odometry.linear
    msg.twist.twist.angular.z = odometry.angular
    msg.twist.covariance = odometry.twist_covariance()
    return msg
