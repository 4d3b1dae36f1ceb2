"""The laser scan reaches the event bus as ``scan`` events in the map frame (real rospy, real tf, real topic).

Only while someone reads the events: no subscription to the laser topic otherwise. A scan is
decimated to at most MAX_POINTS points and told at most RATE times a second.
"""

import math
import time

import rospy
import tf2_ros
from geometry_msgs.msg import TransformStamped
from sensor_msgs.msg import LaserScan

from flask_move_server.core.events import EventBus
from flask_move_server.core.geometry import yaw_to_quaternion
from flask_move_server.ros.scan import MAX_POINTS, RATE, ScanRelay
from tests.conftest import wait_for


def _mount(parent, child, x, y, yaw):
    """A static tf ``parent -> child``."""
    t = TransformStamped()
    t.header.stamp = rospy.Time.now()
    t.header.frame_id, t.child_frame_id = parent, child
    t.transform.translation.x, t.transform.translation.y = x, y
    q = t.transform.rotation
    q.x, q.y, q.z, q.w = yaw_to_quaternion(yaw)
    return t


def _wall_scan(frame, beams=360, distance=2.0):
    """A scan of a round room of ``distance`` m radius, beam 0 straight back, as the sim's lidar casts."""
    msg = LaserScan()
    msg.header.stamp = rospy.Time.now()
    msg.header.frame_id = frame
    msg.angle_min, msg.angle_increment = -math.pi, 2 * math.pi / beams
    msg.angle_max = msg.angle_min + msg.angle_increment * (beams - 1)
    msg.range_min, msg.range_max = 0.15, 8.0
    msg.ranges = [float("inf") if i % 10 == 4 else distance for i in range(beams)]  # some beams: no echo
    return msg


class _Rig:
    """A relay on its own topic and frames, a tf buffer that hears map -> <laser>, a scan publisher."""

    def __init__(self, ros_node, unique_name, check=0.2):
        self.topic, self.map, self.laser = unique_name + "/scan", unique_name + "_map", unique_name + "_laser"
        self.buffer = tf2_ros.Buffer()
        self.listener = tf2_ros.TransformListener(self.buffer)
        self.broadcaster = tf2_ros.StaticTransformBroadcaster()
        self.broadcaster.sendTransform(_mount(self.map, self.laser, 3.0, 1.0, math.pi / 2))
        self.bus = EventBus()
        self.relay = ScanRelay(self.topic, self.map, self.bus, ros_node, lambda: self.buffer, check=check).start()
        self.publisher = rospy.Publisher(self.topic, LaserScan, queue_size=1)

    def scan(self):
        self.publisher.publish(_wall_scan(self.laser))

    def close(self):
        self.relay.close()
        self.relay.close()
        self.publisher.unregister()
        self.listener.unregister()


def test_scans_are_told_in_the_map_frame_decimated_only_while_someone_reads(ros_node, unique_name):
    rig = _Rig(ros_node, unique_name)
    heard = []
    rig.bus.listen("scan", heard.append)
    try:
        for _ in range(5):
            rig.scan()
            time.sleep(0.05)
        assert rig.publisher.get_num_connections() == 0, "nobody reads the events: the laser is not subscribed"
        assert heard == []

        sub = rig.bus.subscribe(["scan"])
        wait_for(lambda: rig.publisher.get_num_connections() == 1, timeout=10, message="the relay subscribing")
        scan = wait_for(lambda: rig.scan() or sub.next(0.3), timeout=10, message="a scan event")
        kind, data = scan
        assert kind == "scan" and data["frame"] == rig.map
        points = data["points"]
        assert 0 < len(points) <= MAX_POINTS
        for x, y in points:  # the room's wall, 2 m around the laser at (3, 1) of the map frame
            assert abs(math.hypot(x - 3.0, y - 1.0) - 2.0) < 0.02
            assert (x, y) == (round(x, 2), round(y, 2))
        assert [3.0, -1.0] in points  # beam 0 points back in the laser frame: -y in the map (laser yaw 90 deg)

        sub.close()
        wait_for(lambda: rig.publisher.get_num_connections() == 0, timeout=10, message="the relay unsubscribing")
        assert rig.bus.latest("scan")["points"] == []  # a page opening later is not shown this old scan
    finally:
        rig.close()


def test_scans_are_told_at_most_rate_times_a_second(ros_node, unique_name):
    rig = _Rig(ros_node, unique_name)
    told = []
    rig.bus.listen("scan", lambda data: told.append(time.monotonic()))
    sub = rig.bus.subscribe(["scan"])
    try:
        wait_for(lambda: rig.publisher.get_num_connections() == 1, timeout=10, message="the relay subscribing")
        published = 0
        while len(told) < 4:  # a lidar far faster than the page needs: 40 scans a second
            rig.scan()
            published += 1
            time.sleep(0.025)
        gaps = [b - a for a, b in zip(told, told[1:])]
        assert min(gaps) >= 1.0 / RATE * 0.99, gaps
        assert published > 2 * len(told)
    finally:
        sub.close()
        rig.close()


def test_no_map_frame_clears_the_scan(ros_node, unique_name):
    rig = _Rig(ros_node, unique_name)
    sub = rig.bus.subscribe(["scan"])
    try:
        wait_for(lambda: rig.scan() or (rig.bus.latest("scan") or {}).get("points"), timeout=10,
                 message="a scan with points")
        elsewhere = unique_name + "_elsewhere"  # no tf to the map frame (idle: no map in use)
        wait_for(lambda: rig.publisher.publish(_wall_scan(elsewhere)) or rig.bus.latest("scan")["points"] == [],
                 timeout=10, message="the scan cleared")
    finally:
        sub.close()
        rig.close()
