"""Where the robot is: tf ``map → base_link``, falling back to ``/amcl_pose``."""

import math
from dataclasses import dataclass

import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped

from flask_move_server.core.errors import NoPose
from flask_move_server.core.geometry import Pose2D
from flask_move_server.ros.convert import TF_ERRORS, pose_from_msg, pose_from_transform


@dataclass(frozen=True)
class PoseReading:
    """A pose, the frame it is in, when it was measured and where it came from."""

    pose: Pose2D
    frame: str
    stamp: float
    source: str

    def as_dict(self, now):
        data = self.pose.as_dict()
        data.update(frame=self.frame, age=round(max(0.0, now - self.stamp), 3), source=self.source)
        return data


class PoseTracker:
    """The robot's latest pose in the map frame, from tf or AMCL."""

    def __init__(self, frames, amcl_pose_topic, node=None, max_age=2.0):
        """``node``: set up once it is ready; None when rospy is initialised already."""
        self._frames = frames
        self.max_age = max_age
        self._amcl_topic = amcl_pose_topic
        self._amcl = None
        self.amcl_spread = None  # std dev of /amcl_pose's x (m), y (m), yaw (rad): how sure AMCL is
        self._buffer = None
        self._subscriptions = []
        if node is None:
            self._setup()
        else:
            node.when_ready(self._setup)

    def _setup(self):
        self._buffer = tf2_ros.Buffer(cache_time=rospy.Duration(10.0))
        listener = tf2_ros.TransformListener(self._buffer)
        amcl = rospy.Subscriber(self._amcl_topic, PoseWithCovarianceStamped, self._on_amcl, queue_size=1)
        self._subscriptions = [listener, amcl]

    def close(self):
        """Stop listening to tf and AMCL. Idempotent."""
        subscriptions, self._subscriptions = self._subscriptions, []
        for subscription in subscriptions:
            subscription.unregister()

    def current(self):
        """The latest :class:`PoseReading`, or None when neither tf nor AMCL gave one."""
        return self._from_tf() or self._amcl

    def age(self, reading):
        """Seconds since ``reading`` was measured."""
        return max(0.0, rospy.get_time() - reading.stamp)

    def fresh(self, why_missing):
        """The pose now, for recording it; NoPose (``why_missing``, or its age) when unknown or stale."""
        reading = self.current()
        if reading is None:
            raise NoPose(why_missing)
        age = self.age(reading)
        if age > self.max_age:
            raise NoPose(
                "The robot's last pose is {:.1f} s old (from {}), older than navigation.pose_max_age "
                "({:g} s): is localization still running?".format(age, reading.source, self.max_age)
            )
        return reading.pose

    def now(self):
        """ROS time now (s): what :meth:`at` takes."""
        return rospy.get_time()

    def at(self, stamp):
        """The pose (Pose2D, map frame) at ROS time ``stamp`` from tf's history (10 s kept), or None."""
        if self._buffer is None:
            return None
        try:
            t = self._buffer.lookup_transform(self._frames.map, self._frames.base_link, rospy.Time.from_sec(stamp))
        except TF_ERRORS:
            return None
        return pose_from_transform(t.transform)

    @property
    def buffer(self):
        """The tf buffer (None until set up), for other lookups in the same tree."""
        return self._buffer

    def _from_tf(self):
        if self._buffer is None:
            return None
        try:
            t = self._buffer.lookup_transform(self._frames.map, self._frames.base_link, rospy.Time(0))
        except TF_ERRORS:
            return None
        return PoseReading(pose_from_transform(t.transform), self._frames.map, t.header.stamp.to_sec(), "tf")

    def _on_amcl(self, msg):
        pose = pose_from_msg(msg.pose.pose)
        c = msg.pose.covariance
        self.amcl_spread = tuple(math.sqrt(max(0.0, v)) for v in (c[0], c[7], c[35]))
        self._amcl = PoseReading(pose, msg.header.frame_id or self._frames.map, msg.header.stamp.to_sec(), "amcl_pose")

    def as_dict(self, reading=None):
        """The ``pose`` of ``/status``: x, y, yaw, frame, age (s), or None; ``reading``: one taken already."""
        reading = reading or self.current()
        return None if reading is None else reading.as_dict(rospy.get_time())
