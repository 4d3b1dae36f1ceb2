"""gmapping's stand-in for the simulation's mapping mode: /map grown from scans, and tf map → odom.

Given the server's node, a :class:`~flask_move_server.sim.slam.SlamMap` and the
world (``pose()``: the true pose now; ``pose_at(stamp)``: the true pose at a
ROS time), a thread integrates a scan from the true pose ``scan_rate`` times a
second once the robot has moved or turned a little since the last one (gmapping
too only processes scans after ``linearUpdate`` / ``angularUpdate``; a robot at
rest costs nothing), and publishes the grid latched on ``/map`` (and its
``MapMetaData`` on ``/map_metadata``, as gmapping does) at most every
``publish_period`` seconds and only when its version changed. For each
``/odom`` message it publishes tf ``map → odom`` = true pose ∘ odometry⁻¹ at
that stamp: the correction gmapping's scan matching would find, exactly.

``/map`` follows the map server stand-in's (``sim/map_server.py``) on the same
topic, so it is published with ``ros/own_topics.py`` as that one is.

``modes/simulated.py`` runs this in mapping mode, in place of the world's AMCL
stand-in, which publishes the same tf and is quiet meanwhile (``SimWorld.localizing``).
"""

import logging
import threading
from array import array

import rospy
import tf2_ros
from nav_msgs.msg import MapMetaData, OccupancyGrid, Odometry

from flask_move_server.core.geometry import compose, inverse, normalize_angle
from flask_move_server.ros import convert, own_topics
from flask_move_server.ros.convert import pose_from_msg, transform_message

log = logging.getLogger(__name__)


class SimMapping:
    """Publishes the growing SLAM map and the map → odom correction on the server's node."""

    def __init__(self, node, slam, world, frames, map_topic="map", odom_topic="odom", scan_rate=5.5,
                 publish_period=1.0, linear_update=0.02, angular_update=0.02):
        self.slam = slam
        self.world = world
        self.frames = frames
        self._topics = (map_topic, odom_topic)
        self._scan_period = 1.0 / scan_rate
        self.publish_period = publish_period
        self._gate = (linear_update, angular_update)
        self._last_scanned = None
        self._published_version = None
        self.published = 0
        self._stop = threading.Event()
        self._thread = None
        self._pubs = None
        node.when_ready(self._setup)

    def _setup(self):
        if self._stop.is_set():
            return
        map_topic, odom_topic = self._topics
        self._pubs = {
            "map": own_topics.publisher(map_topic, OccupancyGrid, queue_size=1, latch=True),
            "metadata": own_topics.publisher(map_topic + "_metadata", MapMetaData, queue_size=1, latch=True),
            "tf": tf2_ros.TransformBroadcaster(),
        }
        self._odom_sub = rospy.Subscriber(odom_topic, Odometry, self._on_odom, queue_size=5)
        self._thread = threading.Thread(target=self._run, name="sim-mapping", daemon=True)
        self._thread.start()
        log.info("simulated SLAM: mapping on a %d x %d canvas (%.3f m), publishing %s",
                 self.slam.width, self.slam.height, self.slam.resolution, rospy.resolve_name(map_topic))

    # scans and /map -------------------------------------------------------------------

    def _run(self):
        scans_per_publish = max(1, int(round(self.publish_period / self._scan_period)))
        tick = 0
        while True:
            self.scan_once()
            if tick % scans_per_publish == 0:
                self.publish_map()
            tick += 1
            if self._stop.wait(self._scan_period):
                return

    def scan_once(self):
        """Integrate a scan from the true pose if the robot moved or turned enough since the last one."""
        pose = self.world.pose()
        last = self._last_scanned
        if last is not None and pose.distance_to(last) < self._gate[0] and \
                abs(normalize_angle(pose.yaw - last.yaw)) < self._gate[1]:
            return False
        self._last_scanned = pose
        self.slam.integrate(pose)
        return True

    def publish_map(self):
        """Publish /map and /map_metadata if the map changed since the last time."""
        version = self.slam.version
        if self._pubs is None or version == self._published_version:
            return False
        msg = occupancy_grid(self.slam, self.frames.map, rospy.Time.now())
        self._pubs["map"].publish(msg)
        self._pubs["metadata"].publish(msg.info)
        self._published_version = version
        self.published += 1
        return True

    # tf map → odom ---------------------------------------------------------------------

    def _on_odom(self, msg):
        if self._stop.is_set() or self._pubs is None:
            return
        odom = pose_from_msg(msg.pose.pose)
        true = self.world.pose_at(msg.header.stamp.to_sec())
        self._pubs["tf"].sendTransform(transform_message(
            compose(true, inverse(odom)), msg.header.stamp, self.frames.map, msg.header.frame_id or self.frames.odom))

    def close(self):
        """Stop scanning and publishing. Idempotent."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2)
        if self._pubs is not None:
            self._odom_sub.unregister()
            self._pubs["map"].unregister()
            self._pubs["metadata"].unregister()
            self._pubs = None


def occupancy_grid(slam, frame, stamp):
    """The SLAM map as a nav_msgs/OccupancyGrid (data: one copy of the signed bytes)."""
    return convert.occupancy_grid(frame, stamp, slam.resolution, slam.width, slam.height,
                                  slam.origin_x, slam.origin_y, array("b", slam.grid_bytes()))
