"""Setting the robot's pose for localization: RViz's "2D Pose Estimate", from the server.

Publishes ``geometry_msgs/PoseWithCovarianceStamped`` on ``modes.initial_pose_topic`` in
the map frame, with the covariance RViz's tool sends (0.5 m standard deviation in x and y,
pi/12 in yaw), so AMCL spreads its particles exactly as after a click in RViz. The sim
takes the estimate as the truth and puts the robot there.

A stack that has just started may not have connected to our publisher yet (a message
published before that is lost, and a latched one would be replayed to every later AMCL,
long after the robot moved), so :meth:`InitialPose.publish` waits briefly for a subscriber.
"""

import math
import time

import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from flask_move_server.core.errors import RosUnavailable
from flask_move_server.ros.convert import write_pose

XY_VARIANCE = 0.5 * 0.5
YAW_VARIANCE = (math.pi / 12.0) ** 2  # 0.0685


def estimate(pose, frame, stamp, xy_variance=XY_VARIANCE, yaw_variance=YAW_VARIANCE):
    """The PoseWithCovarianceStamped RViz's 2D Pose Estimate would send for ``pose`` in ``frame`` (its
    covariance, unless given: the stuck watch, which knows the pose better, gives a tighter one)."""
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id, msg.header.stamp = frame, stamp
    write_pose(msg.pose.pose, pose)
    covariance = [0.0] * 36
    covariance[0] = covariance[7] = xy_variance  # x, y
    covariance[35] = yaw_variance  # rotation about z
    msg.pose.covariance = covariance
    return msg


class InitialPose:
    """The publisher of pose estimates on ``topic`` (created once the node is ready)."""

    SUBSCRIBER_WAIT = 2.0  # seconds to wait for localization to connect before publishing anyway
    POLL = 0.05

    def __init__(self, topic, frame, node):
        self._topic = topic
        self._frame = frame
        self._node = node
        self._pub = None
        node.when_ready(self._setup)

    def _setup(self):
        self._pub = rospy.Publisher(self._topic, PoseWithCovarianceStamped, queue_size=1)

    def publish(self, pose, sigma=None):
        """Publish ``pose`` as the robot's estimate; returns how many subscribers heard it. ``sigma``:
        ``(m, rad)`` standard deviations, for an estimate surer than a click in RViz; published at once
        then, only to a localization already listening (none while mapping: nothing to wait for)."""
        pub = self._pub
        if pub is None or not self._node.connected:
            raise RosUnavailable("ROS is not reachable at {}: cannot publish the robot's pose on {}.".format(
                self._node.master_uri, self._topic))
        deadline = time.monotonic() + (0.0 if sigma else self.SUBSCRIBER_WAIT)
        while pub.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(self.POLL)
        variances = (sigma[0] ** 2, sigma[1] ** 2) if sigma else (XY_VARIANCE, YAW_VARIANCE)
        pub.publish(estimate(pose, self._frame, rospy.Time.now(), *variances))
        return pub.get_num_connections()

    def close(self):
        """Unregister the publisher. Idempotent."""
        pub, self._pub = self._pub, None
        if pub is not None:
            pub.unregister()
