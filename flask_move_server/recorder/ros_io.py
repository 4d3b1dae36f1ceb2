"""The recorder's ROS side: the robot's pose, RViz clicks, and why a pose is missing.

Built on an already-initialised rospy node (the recorder's own, or a test's),
so it can run beside other parts in one process. Clicks arrive on rospy's
threads and are only queued here; the session saves them from its own thread.
"""

import queue

import rospy
from geometry_msgs.msg import PointStamped, PoseStamped

from flask_move_server.config import FramesConfig
from flask_move_server.core.geometry import Pose2D, compose
from flask_move_server.ros.convert import TF_ERRORS, pose_from_msg, pose_from_transform
from flask_move_server.ros.pose import PoseTracker


class Click:
    """A place marked in RViz: its pose in the map frame and which tool marked it."""

    def __init__(self, pose, tool):
        self.pose, self.tool = pose, tool


class RosSide:
    """tf, ``/amcl_pose`` and the RViz topics of one recorder."""

    def __init__(self, map_frame="map", base_frame="base_link", amcl_topic="amcl_pose",
                 clicked_topic="/clicked_point", goal_topic="/waypoint_goal"):
        self.map_frame, self.base_frame = map_frame, base_frame
        self.clicks = queue.Queue()
        self.problems = queue.Queue()  # clicks that could not be placed in the map, as sentences
        # The server's pose tracker: tf map → base_link, else /amcl_pose, stale poses refused.
        self.pose = PoseTracker(FramesConfig(map=map_frame, base_link=base_frame), amcl_topic)
        self._buffer = self.pose.buffer
        self._subs = [
            rospy.Subscriber(clicked_topic, PointStamped, self._on_point, queue_size=10),
            rospy.Subscriber(goal_topic, PoseStamped, self._on_goal, queue_size=10),
        ]

    # the robot's pose ------------------------------------------------------------

    def current_pose(self):
        """The robot's pose in the map frame (tf, else AMCL); NoPose saying why not."""
        return self.pose.fresh(self.why_no_pose())

    def has_map_frame(self):
        return self._buffer._frameExists(self.map_frame.lstrip("/"))

    def why_no_pose(self):
        """The sentence telling the user what to start or do."""
        if not self.has_map_frame():
            return ("No '{}' frame in tf yet: start the map and localization (map_server + AMCL, "
                    "roslaunch flask_move_server navigation.launch), then set the robot's pose in RViz "
                    "with '2D Pose Estimate'. RViz clicks work meanwhile.".format(self.map_frame))
        return ("tf has '{}' but no path to '{}', and no /amcl_pose came: is AMCL localised and the "
                "base driver publishing odom -> {}?".format(self.map_frame, self.base_frame, self.base_frame))


    # RViz ---------------------------------------------------------------------------

    def _on_point(self, msg):
        self._queue_click(msg.header.frame_id, msg.point.x, msg.point.y, None, "Publish Point")

    def _on_goal(self, msg):
        pose = pose_from_msg(msg.pose)
        self._queue_click(msg.header.frame_id, pose.x, pose.y, pose.yaw, "2D Nav Goal")

    def _queue_click(self, frame, x, y, yaw, tool):
        frame = (frame or self.map_frame).lstrip("/")
        try:
            pose = self._in_map(frame, x, y, yaw or 0.0)
        except TF_ERRORS:
            self.problems.put("A click in frame '{}' cannot be placed in '{}' (no tf between them): set "
                              "RViz's Fixed Frame to '{}'.".format(frame, self.map_frame, self.map_frame))
            return
        self.clicks.put(Click(pose, tool))

    def _in_map(self, frame, x, y, yaw):
        if frame == self.map_frame.lstrip("/"):
            return Pose2D(x, y, yaw)
        t = self._buffer.lookup_transform(self.map_frame, frame, rospy.Time(0))
        return compose(pose_from_transform(t.transform), Pose2D(x, y, yaw))

    def close(self):
        """Unsubscribe. Idempotent."""
        for sub in self._subs:
            sub.unregister()
        self._subs = []
        self.pose.close()
