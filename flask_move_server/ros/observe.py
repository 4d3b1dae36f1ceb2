"""What the first-boot doctor sees of ROS: /scan and /odom for a short window, the tf chain, AMCL, move_base.

Listening costs a subscriber to /scan and /odom, so it happens only while someone asks
(``GET /diagnostics``, ``robotctl doctor``): ``observe(seconds)`` subscribes, counts and keeps the
last scan, then unsubscribes. The tf chain is read from the pose tracker's buffer, which listens
anyway. The result is plain values (``diagnostics.checks.RosObservations``) for the pure checks.
"""

import math
import threading
import time

import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from flask_move_server.core.errors import MoveServerError
from flask_move_server.core.geometry import Pose2D
from flask_move_server.diagnostics.checks import BOX_RANGE, RosObservations, ScanSample, TfLink, TopicSample
from flask_move_server.diagnostics.scan_match import match_share
from flask_move_server.ros.convert import TF_ERRORS, pose_from_transform


class _Counter:
    """Counts the messages of one topic and keeps the last; rate over first-to-last arrival."""

    def __init__(self, topic, kind):
        self.count, self.first, self.last_at, self.last = 0, None, None, None
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(topic, kind, self._on_message, queue_size=5)

    def _on_message(self, msg):
        now = time.monotonic()
        with self._lock:
            self.count += 1
            self.first = self.first if self.first is not None else now
            self.last_at, self.last = now, msg

    def close(self):
        self._sub.unregister()

    def sample(self, into):
        with self._lock:
            into.count = self.count
            if self.count > 1 and self.last_at > self.first:
                into.rate = (self.count - 1) / (self.last_at - self.first)
            if self.last is not None:
                into.age = rospy.get_time() - self.last.header.stamp.to_sec()
            return self.last


class RosObserver:
    """Observes the robot's ROS graph for the doctor, on the server's node."""

    def __init__(self, node, frames, topics, pose_tracker, navigator, map_source=None):
        self._map_source = map_source  # the map the laser is matched against (None: not matched)
        self._node = node
        self._frames = frames
        self._scan_topic, self._odom_topic, self._amcl_topic = topics
        self._pose = pose_tracker
        self._navigator = navigator

    def observe(self, seconds, mode=None):
        """Listen for ``seconds``, then report what was seen (``connected`` False without a master)."""
        if not self._node.connected:
            return RosObservations(False, mode, ScanSample(), TopicSample(), [], False, 0, None)
        scan_counter, odom_counter = _Counter(self._scan_topic, LaserScan), _Counter(self._odom_topic, Odometry)
        try:
            time.sleep(seconds)
        finally:
            scan_counter.close()
            odom_counter.close()
        scan, odom = ScanSample(), TopicSample()
        last_scan = scan_counter.sample(scan)
        odom_counter.sample(odom)
        if last_scan is not None:
            _describe_scan(last_scan, scan)
        return RosObservations(True, mode, scan, odom, self._links(scan.frame), self._navigator.server_ready(),
                               self._amcl_publishers(), self._pose.amcl_spread,
                               self._scan_match(last_scan, mode))

    def _scan_match(self, scan, mode):
        """``(share, points)`` of the last scan on the map at the localized pose, or None (``scan_match.py``)."""
        if scan is None or self._map_source is None or mode in ("idle", "mapping"):
            return None
        reading = self._pose.current()
        laser = self._laser_mount(scan.header.frame_id.lstrip("/"))
        try:
            _, grid = self._map_source.current()
        except MoveServerError:  # no map now
            return None
        if reading is None or laser is None:
            return None
        share, points = match_share(grid, reading.pose, laser, scan)
        return None if share is None else (share, points)

    def _laser_mount(self, frame):
        """Where the laser sits on the robot (Pose2D in base_link), or None when tf does not say."""
        if frame in ("", self._frames.base_link):
            return Pose2D(0.0, 0.0, 0.0)
        try:
            t = self._pose.buffer.lookup_transform(self._frames.base_link, frame, rospy.Time(0))
        except (TF_ERRORS + (AttributeError,)):
            return None
        return pose_from_transform(t.transform)

    def _links(self, scan_frame):
        f = self._frames
        pairs = [(f.map, f.odom), (f.odom, f.base_link)]
        if scan_frame and scan_frame.lstrip("/") != f.base_link:
            pairs.append((f.base_link, scan_frame.lstrip("/")))
        return [self._link(parent, child, moving=index < 2) for index, (parent, child) in enumerate(pairs)]

    def _link(self, parent, child, moving):
        buffer = self._pose.buffer
        try:
            t = buffer.lookup_transform(parent, child, rospy.Time(0))
        except (TF_ERRORS + (AttributeError,)):
            return TfLink(parent, child, False)
        age = max(0.0, rospy.get_time() - t.header.stamp.to_sec()) if moving else None
        return TfLink(parent, child, True, age, pose_from_transform(t.transform).yaw)

    def _amcl_publishers(self):
        try:
            _, _, (publishers, _, _) = rospy.get_master().getSystemState()
        except Exception:  # the master went away meanwhile: nobody publishes
            return 0
        topic = rospy.resolve_name(self._amcl_topic)
        return sum(len(nodes) for name, nodes in publishers if name == topic)


def _describe_scan(msg, into):
    """Frame, range_max and the nearest return within the box test's reach (range, angle in the scan's frame)."""
    into.frame = msg.header.frame_id
    into.range_max = msg.range_max
    low, high = BOX_RANGE
    best = None
    for index, distance in enumerate(msg.ranges):
        if low <= distance <= high and math.isfinite(distance) and (best is None or distance < best[0]):
            best = (distance, msg.angle_min + index * msg.angle_increment)
    into.nearest = best
