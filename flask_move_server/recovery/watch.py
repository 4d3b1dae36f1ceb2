"""The stuck watch's ROS side: ``/odom`` and the laser, while the robot is told to move.

Listening costs two subscribers, so they are up only while something drives the robot (a goal
under way or held, the joystick, a back-out) and ``linger`` s after; a thread looks every
``period`` s. Each scan's end points, in base_link through the laser's static tf, go with the
odometry at the scan's stamp to the :class:`~flask_move_server.recovery.detector.MotionWatch`: when
it says the robot is blocked the recovery hears ``blocked()`` (and the watch starts afresh), when
it saw the robot move, ``moving()``. The recovery reads the latest scan and odometry here too.
"""

import collections
import logging
import threading
import time

import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from flask_move_server.core.geometry import Pose2D, interpolate
from flask_move_server.recovery.detector import MotionWatch, travel
from flask_move_server.recovery.scan_motion import end_points
from flask_move_server.ros.convert import TF_ERRORS, pose_from_msg, pose_from_transform

log = logging.getLogger(__name__)

PERIOD = 0.5  # s between looks at whether the robot is told to move
LINGER = 3.0  # s the subscribers stay after the last motion was told
ODOMETRY_KEPT = 100  # /odom samples kept (5 s at the drive's 20 Hz)
DRIVING = 0.02  # m/s: a linear velocity in /odom at least this fast says which way the robot drives


class StuckWatch:
    """Watches the laser against the odometry for ``recovery`` (recovery.py), on the server's node."""

    def __init__(self, recovery, node, robot, scan_topic, odom_topic, base_frame, period=PERIOD, linger=LINGER):
        self._recovery = recovery
        self._robot = robot
        self._topics = (scan_topic, odom_topic)
        self._base_frame = base_frame
        self._period, self._linger = period, linger
        self._lock = threading.Lock()
        self._motion = MotionWatch()
        self._odometry = collections.deque(maxlen=ODOMETRY_KEPT)  # (stamp s, monotonic s, Pose2D)
        self._scan = None  # (monotonic s, end points) of the latest scan
        self._came = None  # +1 forward, -1 backward: how the robot last drove (None: not seen)
        self._mounts = {}  # laser frame -> Pose2D on base_link
        self._subscribers = None
        self._wanted_at = None
        self._ready = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stuck-watch", daemon=True)
        recovery.sensing = self
        node.when_ready(self._ready.set, part="StuckWatch")

    def start(self):
        self._thread.start()
        return self

    # following the robot's motion --------------------------------------------------------------

    def _run(self):
        while not self._stop.wait(self._period):
            try:
                self._follow()
            except Exception:  # rospy refusing (shutting down): the robot goes on without the watch
                log.exception("the stuck watch failed to follow the robot's motion")

    def _follow(self):
        now = time.monotonic()
        if self._told_to_move():
            self._wanted_at = now
        wanted = self._wanted_at is not None and now - self._wanted_at <= self._linger
        if wanted and self._ready.is_set() and self._subscribers is None:
            scan_topic, odom_topic = self._topics
            self._subscribers = (rospy.Subscriber(odom_topic, Odometry, self._on_odom, queue_size=5),
                                 rospy.Subscriber(scan_topic, LaserScan, self._on_scan, queue_size=1,
                                                  buff_size=2 ** 16))
        elif not wanted and self._subscribers is not None:
            self._unsubscribe()

    def _told_to_move(self):
        robot = self._robot
        return (robot.navigator.active or robot.teleop_control.status()["active"]
                or self._recovery.status()["state"] != "free")

    def _unsubscribe(self):
        subscribers, self._subscribers = self._subscribers, None
        for subscriber in subscribers or ():
            subscriber.unregister()
        with self._lock:
            self._odometry.clear()
            self._scan = None
            self._motion.reset()

    # what comes in --------------------------------------------------------------------------------

    def _on_odom(self, msg):
        linear = msg.twist.twist.linear.x
        with self._lock:
            self._odometry.append((msg.header.stamp.to_sec(), time.monotonic(), pose_from_msg(msg.pose.pose)))
            if abs(linear) >= DRIVING:
                self._came = 1 if linear > 0 else -1

    def _on_scan(self, msg):
        mount = self._mount(msg.header.frame_id.lstrip("/"))
        if mount is None:
            return
        points = end_points(msg.ranges, msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max, mount)
        with self._lock:
            self._scan = (time.monotonic(), points)
            odometry = self._odometry_at(msg.header.stamp.to_sec())
            blocked = odometry is not None and self._motion.scan(points, odometry)
            if blocked:
                self._motion.reset()
            moving = self._motion.moving
        if blocked:
            self._recovery.blocked()
        elif moving:
            self._recovery.moving()

    def _odometry_at(self, stamp):
        """Lock held: the odometry pose at ROS time ``stamp``, between the samples around it; None when none."""
        samples = self._odometry
        if not samples or stamp > samples[-1][0] + 0.2:
            return None  # the odometry stopped: no claim of motion to check
        before = None
        for sample in samples:
            if sample[0] >= stamp:
                if before is None:
                    return sample[2]
                span = sample[0] - before[0]
                return interpolate(before[2], sample[2], (stamp - before[0]) / span if span > 0 else 1.0)
            before = sample
        return samples[-1][2]

    def _mount(self, frame):
        """Where the laser sits on base_link (Pose2D), from tf once per frame; None while tf does not say."""
        if frame in ("", self._base_frame):
            return Pose2D(0.0, 0.0, 0.0)
        mount = self._mounts.get(frame)
        if mount is None:
            buffer = self._robot.pose.buffer
            try:
                t = buffer.lookup_transform(self._base_frame, frame, rospy.Time(0))
            except (TF_ERRORS + (AttributeError,)):
                return None
            mount = self._mounts[frame] = pose_from_transform(t.transform)
        return mount

    # what the recovery asks -------------------------------------------------------------------------

    def points(self, max_age):
        """The latest scan's end points (robot frame), or None when there is none younger than ``max_age`` s."""
        with self._lock:
            scan = self._scan
        if scan is None or time.monotonic() - scan[0] > max_age:
            return None
        return scan[1]

    def came(self):
        """+1 when the robot last drove forward, -1 backward, None when not seen: the way it came."""
        with self._lock:
            return self._came

    def odometry(self):
        """The latest odometry pose (Pose2D, odom frame), or None."""
        with self._lock:
            return self._odometry[-1][2] if self._odometry else None

    def travel_from(self, origin):
        """Metres the odometry came from ``origin`` (Pose2D), or None."""
        return travel(origin, self.odometry())

    def travel_since(self, monotonic):
        """Metres the odometry came since monotonic time ``monotonic`` (from the first sample after it), or None."""
        with self._lock:
            first = next((pose for _, at, pose in self._odometry if at >= monotonic), None)
            last = self._odometry[-1][2] if self._odometry else None
        if first is None and last is not None:
            return 0.0  # no sample since: the odometry did not move
        return travel(first, last)

    def slip(self):
        """The odometry the laser did not see (Pose2D, in the robot's frame), since it last saw the robot move."""
        with self._lock:
            return self._motion.slip

    def forget_slip(self):
        with self._lock:
            self._motion.forget_slip()

    def restart_motion(self):
        """Compare from the next scan on (a back-out begins)."""
        with self._lock:
            self._motion.reset()

    def close(self):
        """Stop watching. Idempotent."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        self._unsubscribe()

