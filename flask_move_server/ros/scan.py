"""The laser scan in the map frame as ``scan`` events, for the page to draw what the robot sees.

Owners of other robot apps (Vizanti, ROSboard) expect the scan on the map: while mapping it shows
what is still unseen, and on a saved map why a goal fails (a chair the map does not have). The
work is done on the robot and kept small for a phone on Wi-Fi:

- only while someone reads the events: ``/scan`` (``diagnostics.scan_topic``, the robot's laser)
  is subscribed when a stream opens and unsubscribed within ``check`` seconds after the last one
  closed; with no reader, a scan that still arrives is dropped before any transform;
- at most ``rate`` scans a second are told (the sim's lidar gives 5.5, an RPLIDAR A1 5-10);
- each scan decimated to at most ``max_points`` beams (every k-th), the echoes only, turned into
  the map frame through tf ``map <- laser frame`` at the scan's stamp (the latest transform when
  that stamp is not in the buffer yet) and rounded to the centimetre:
  ``{"frame": "map", "points": [[x, y], …]}``, about 2.5 KB.

``"points": []`` is told when the map frame is not there (idle: no map in use) and when the last
reader left, so a page opening later is never primed with an old scan.
"""

import logging
import math
import threading
import time

import rospy
from sensor_msgs.msg import LaserScan

from flask_move_server.ros.convert import TF_ERRORS

log = logging.getLogger(__name__)

RATE = 3.0  # scans told a second, at most
MAX_POINTS = 180  # points a scan, at most (a 360-beam lidar: every second beam, 2 degrees apart)
CHECK = 1.0  # s: how soon the subscription ends after the last reader left
LOOKUP_WAIT = 0.1  # s: how long a scan waits for tf to reach its stamp


class ScanRelay:
    """Relays the laser topic, in the map frame, to the event bus while someone reads the events."""

    def __init__(self, topic, map_frame, events, node, tf_buffer, rate=RATE, max_points=MAX_POINTS, check=CHECK):
        """``tf_buffer``: a callable giving the tf buffer to look up in (the pose tracker's), or None."""
        self._topic = topic
        self._map_frame = map_frame
        self._events = events
        self._tf_buffer = tf_buffer
        self._period = 1.0 / rate
        self._max_points = max_points
        self._check = check
        self._subscriber = None
        self._told_at = None
        self._shown = False  # the last scan told had points
        self._ready = threading.Event()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="scan-relay", daemon=True)
        events.when_subscribed(self._wake.set)
        node.when_ready(self._on_ready, part="ScanRelay")

    def start(self):
        """Start following the readers (a daemon thread); returns self."""
        self._thread.start()
        return self

    def _on_ready(self):
        self._ready.set()
        self._wake.set()

    def _run(self):
        while not self._stop.is_set():
            self._wake.clear()  # before looking: a reader coming meanwhile wakes the wait below
            try:
                self._follow_readers()
            except Exception:  # rospy refusing (shutting down): the pages go without a scan, the server goes on
                log.exception("following the event readers for the laser scan failed")
            self._wake.wait(self._check if self._subscriber is not None else None)

    def _follow_readers(self):
        """Subscribe to the laser while someone reads the events, unsubscribe once nobody does."""
        reading = self._events.subscribers > 0
        if reading and self._ready.is_set() and self._subscriber is None:
            self._subscriber = rospy.Subscriber(self._topic, LaserScan, self._on_scan, queue_size=1,
                                                buff_size=2 ** 16)
        elif not reading and self._subscriber is not None:
            self._unsubscribe()
            self._tell([])  # the bus keeps the latest: a page opening later must not get this old scan

    def _unsubscribe(self):
        subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            subscriber.unregister()

    def _on_scan(self, msg):
        if self._stop.is_set() or not self._events.subscribers:
            return
        now = time.monotonic()
        if self._told_at is not None and now - self._told_at < self._period:
            return
        self._told_at = now
        transform = self._transform(msg.header.frame_id.lstrip("/"), msg.header.stamp)
        if transform is None:
            if self._shown:
                self._tell([])  # no map frame (idle): the last scan must not stay drawn
            return
        self._tell(scan_points(msg, transform, self._max_points))

    def _transform(self, frame, stamp):
        """tf ``map <- frame`` at ``stamp`` (else the latest), as a planar rigid map; None when unknown."""
        buffer = self._tf_buffer()
        if buffer is None:
            return None
        try:
            t = buffer.lookup_transform(self._map_frame, frame, stamp, rospy.Duration(LOOKUP_WAIT))
        except TF_ERRORS:
            try:
                t = buffer.lookup_transform(self._map_frame, frame, rospy.Time(0))
            except TF_ERRORS:
                return None
        return PlanarTransform.of(t.transform)

    def _tell(self, points):
        self._shown = bool(points)
        self._events.publish("scan", {"frame": self._map_frame, "points": points})

    def close(self):
        """Stop relaying and unsubscribe. Idempotent."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self._unsubscribe()


class PlanarTransform:
    """A 3D rigid transform applied to points of a scan's plane (z = 0): x, y out.

    The whole rotation, not only the yaw, so a lidar mounted upside down (roll pi) is drawn right.
    """

    def __init__(self, tx, ty, rotation):
        self.tx, self.ty = tx, ty
        (self.xx, self.xy), (self.yx, self.yy) = rotation

    @classmethod
    def of(cls, transform):
        """From a geometry_msgs/Transform."""
        q, p = transform.rotation, transform.translation
        x, y, z, w = q.x, q.y, q.z, q.w
        rotation = ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w)),
                    (2 * (x * y + z * w), 1 - 2 * (x * x + z * z)))
        return cls(p.x, p.y, rotation)

    def apply(self, x, y):
        return self.tx + self.xx * x + self.xy * y, self.ty + self.yx * x + self.yy * y


def scan_points(msg, transform, max_points=MAX_POINTS):
    """The echoes of a sensor_msgs/LaserScan ``msg``, every k-th beam so at most ``max_points``,
    through ``transform`` (a :class:`PlanarTransform`), rounded to the cm: ``[[x, y], …]``."""
    ranges = msg.ranges
    step = max(1, int(math.ceil(len(ranges) / float(max_points))))
    low, high = max(msg.range_min, 0.0), msg.range_max
    points = []
    for index in range(0, len(ranges), step):
        distance = ranges[index]
        if not (low <= distance <= high):  # NaN, inf (no echo) and out-of-range fail this too
            continue
        angle = msg.angle_min + index * msg.angle_increment
        x, y = transform.apply(distance * math.cos(angle), distance * math.sin(angle))
        points.append([round(x, 2), round(y, 2)])
    return points
