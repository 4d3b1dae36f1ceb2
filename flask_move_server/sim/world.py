"""The simulated world's ROS side: the robot's true motion, /scan, /initialpose, and an AMCL stand-in.

A thread moves the :class:`~flask_move_server.sim.body.RobotBody` by the
ground speeds the sim motor backend reports (``wheel_speeds()``: the duties
the real base controller applied), ``speed_factor`` times faster than real
time when asked; a tick that comes late on a loaded machine loses the time beyond two periods
(``sim/clock.py``: the world's clock, which the move_base stand-in's timers run on, then runs
slower than real time, and the world says so). The base controller's own odometry arrives on
``/odom``; for each message the world publishes what AMCL would: tf ``map → odom`` such that
``map → odom → base_link`` is the true pose at that message's stamp
(true pose ∘ odometry⁻¹), and ``/amcl_pose``, while ``localizing`` (navigation
mode; in mapping mode the simulated SLAM publishes ``map → odom`` instead, and in
idle nobody does). ``/scan`` is cast at ``scan_rate`` while someone listens.
The scan is in the lidar's own frame (``sim.laser_frame``), mounted as docs/deploy.md mounts
the A1 (motor backwards: the frame's +x points back, yaw π, 0.12 m up), with the static tf
``base_link → laser`` the launch files publish on the robot, so everything downstream (the
doctor's box test, RViz, a real AMCL or gmapping against this world) sees what the robot gives.
``/map`` is not the world's: the mode in force publishes it (``map_server.py``,
``mapping.py``).

A pose on ``/initialpose`` (RViz's 2D Pose Estimate, the server's ``POST /pose``, the dock
after a switch) changes what the AMCL stand-in *believes*, never where the robot is, as for
AMCL (``handleInitialPoseMessage``: the filter is set around the given pose, moved on by the
odometry since the message's stamp). ``belief.py`` keeps it: converging to the truth as the
robot moves when the truth lies within the estimate's spread, else kept, so a robot told it is
at the dock while it stands in the kitchen plans and drives from the dock, as a real one would.
"""

import collections
import logging
import math
import threading
import time

import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from flask_move_server.core.geometry import Pose2D, compose, interpolate, inverse
from flask_move_server.ros.convert import pose_from_msg, transform_message, write_pose
from flask_move_server.sim.belief import Belief
from flask_move_server.sim.clock import SimClock, overload_text

log = logging.getLogger(__name__)

LASER_MOUNT = (0.0, 0.0, 0.12, math.pi)  # x, y, z (m), yaw (rad) of the laser frame on base_link
KEPT_UP = 0.9  # below this share of real time over a report period, the world says the machine is overloaded
REPORT_PERIOD = 10.0  # real s between looks at how the world kept up
AMCL_COVARIANCE = [0.0025, 0, 0, 0, 0, 0, 0, 0.0025, 0, 0, 0, 0] + [0] * 23 + [0.0007]


class SimWorld:
    """Moves the simulated robot and publishes what its sensors and localization would."""

    def __init__(self, config, node, body, laser, wheel_speeds, stand_ins=True):
        """``stand_ins`` False: the world only (physics, /scan, the laser's tf), for the real stack to run on."""
        sim_config = config.sim
        self.stand_ins = stand_ins
        self.config = sim_config
        self._amcl_topic = config.navigation.amcl_pose_topic
        self._initial_pose_topic = config.modes.initial_pose_topic
        self.frames = config.ros.frames
        self.body = body
        self.laser = laser
        self._odom_topic = config.drive.odom_topic
        self._wheel_speeds = wheel_speeds
        self._history = collections.deque(maxlen=max(10, int(sim_config.rate * 3)))
        self._stop = threading.Event()
        self.localizing = threading.Event()  # set: publish map → odom and /amcl_pose (the navigation mode sets it)
        self.belief = Belief()  # what the AMCL stand-in believes, beside the truth
        self._last_odom = None  # (odometry, true pose) at the last /odom message
        self._thread = None
        self._pubs = None
        self._subs = ()
        self.clock = SimClock(sim_config.rate, sim_config.speed_factor)  # the time the world advanced
        self.steps = 0  # world updates so far, and the longest gap between two (real time kept?)
        self.started = None
        self.longest_step = 0.0
        node.when_ready(self._setup)

    def _setup(self):
        if self._stop.is_set():
            return
        self._pubs = {
            "scan": rospy.Publisher(self.config.scan_topic, LaserScan, queue_size=1),
            "tf_static": tf2_ros.StaticTransformBroadcaster(),
        }
        self._pubs["tf_static"].sendTransform(laser_mount_message(self.frames.base_link, self.config.laser_frame))
        if self.stand_ins:  # the AMCL stand-in and the pose estimates it takes
            self._pubs["amcl"] = rospy.Publisher(self._amcl_topic, PoseWithCovarianceStamped, queue_size=1)
            self._pubs["tf"] = tf2_ros.TransformBroadcaster()
            self._subs = (rospy.Subscriber(self._odom_topic, Odometry, self._on_odom, queue_size=5),
                          rospy.Subscriber(self._initial_pose_topic, PoseWithCovarianceStamped,
                                           self._on_initial_pose, queue_size=1))
        self._thread = threading.Thread(target=self._run, name="sim-world", daemon=True)
        self._thread.start()
        log.info("simulated world: map %s (%d x %d cells, %.3f m), robot at %s, speed factor %s",
                 self.body.costmap.grid.source, self.body.costmap.grid.width, self.body.costmap.grid.height,
                 self.body.costmap.resolution, self.body.pose.as_dict(), self.config.speed_factor)

    def pose(self):
        """The robot's true pose in the world (the map frame of a map drawn true)."""
        return self.body.pose

    def believed_pose(self):
        """Where localization believes the robot is (tf map → base_link): what move_base plans and drives from.

        In navigation the AMCL stand-in's belief; otherwise the truth (mapping: SLAM knows the
        pose it built the map around).
        """
        true = self.body.pose
        return self.belief.of(true) if self.localizing.is_set() else true

    # the world's clock -----------------------------------------------------------

    def _run(self):
        period = 1.0 / self.config.rate
        scan_period = 1.0 / self.config.scan_rate if self.config.scan_rate > 0 else None
        last = next_scan = next_step = self.started = time.monotonic()
        next_report = last + REPORT_PERIOD
        self._history.append((rospy.get_time(), self.body.pose))
        while not self._stop.wait(max(0.0, next_step + period - time.monotonic())):
            now = time.monotonic()
            next_step = max(next_step + period, now - period)  # behind by more than a step: do not catch up
            left, right = self._wheel_speeds()
            pose = self.body.step(left, right, self.clock.tick(now - last))  # a late tick loses time
            self.longest_step = max(self.longest_step, now - last)
            last = now
            self.steps += 1
            self._history.append((rospy.get_time(), pose))
            if scan_period is not None and now >= next_scan:
                next_scan = max(next_scan + scan_period, now)
                self._publish_scan(pose)
            if now >= next_report:
                next_report = now + REPORT_PERIOD
                self._report_overload()

    def _report_overload(self):
        """Say so when the world fell behind real time: the robot and the stand-in's watchdogs slowed with it."""
        achieved, share = self.clock.report()
        if share < KEPT_UP:
            log.warning("simulated world: over the last %.0f s %s; goals take longer, the move_base stand-in's "
                        "timeouts count simulated time", REPORT_PERIOD,
                        overload_text(achieved, self.config.rate, share))

    def _publish_scan(self, pose):
        pub = self._pubs["scan"]
        if pub.get_num_connections() == 0:
            return
        ranges = self.laser.scan(pose)
        half = len(ranges) // 2  # beam 0 points back in base_link; in the laser frame (yaw pi) it points ahead
        pub.publish(scan_message(self.laser, ranges[half:] + ranges[:half], self.config.laser_frame,
                                 self.config.scan_rate))

    # the AMCL stand-in -------------------------------------------------------------

    def _on_odom(self, msg):
        if self._stop.is_set() or not self.localizing.is_set():
            return
        odom = pose_from_msg(msg.pose.pose)
        true = self.pose_at(msg.header.stamp.to_sec())
        last, self._last_odom = self._last_odom, (odom, true)
        if last is not None and self.body.bumped:  # the wheels turn, the robot does not: the belief slides
            self.belief.slid(self.belief.of(last[1]), compose(inverse(last[0]), odom), true)
        else:
            self.belief.moved(true)
        belief = self.belief.of(true)
        map_to_odom = compose(belief, inverse(odom))
        self._pubs["tf"].sendTransform(
            transform_message(map_to_odom, msg.header.stamp, self.frames.map, msg.header.frame_id or self.frames.odom))
        self._pubs["amcl"].publish(amcl_pose_message(belief, msg.header.stamp, self.frames.map))

    def _on_initial_pose(self, msg):
        frame = msg.header.frame_id.lstrip("/")
        if frame not in ("", self.frames.map):
            log.warning("simulated world: ignoring /initialpose in frame %r (the sim takes %r)", frame, self.frames.map)
            return
        if not self.localizing.is_set():
            log.info("simulated world: ignoring /initialpose: no localization runs (not navigating)")
            return
        stamp = msg.header.stamp.to_sec() or rospy.get_time()
        covariance = msg.pose.covariance
        self.believe(pose_from_msg(msg.pose.pose), stamp, math.sqrt(max(covariance[0], covariance[7], 0.0)),
                     math.sqrt(max(covariance[35], 0.0)))

    def believe(self, estimate, stamp=None, sigma_xy=0.0, sigma_yaw=0.0):
        """Localization is told the robot was at ``estimate`` at ROS time ``stamp`` (None: now).

        The true robot stays where it is; the belief moves with it from there on, and converges to
        it if the truth lies within the estimate's spread (``sigma_xy`` m, ``sigma_yaw`` rad).
        """
        true = self.body.pose if stamp is None else self.pose_at(stamp)
        inside = self.belief.estimate(estimate, true, sigma_xy, sigma_yaw)
        log.info("simulated world: localization now believes the robot is at %s (it really is at %s; %s)",
                 estimate.as_dict(), true.as_dict(), "converging as it moves" if inside else "too far to converge")

    def pose_at(self, stamp):
        """The true pose at ROS time ``stamp`` (seconds), interpolated from the recent history."""
        history = list(self._history)
        if not history or stamp >= history[-1][0]:
            return self.body.pose
        if stamp <= history[0][0]:
            return history[0][1]
        for (t0, a), (t1, b) in zip(reversed(history[:-1]), reversed(history[1:])):
            if t0 <= stamp:
                return interpolate(a, b, (stamp - t0) / (t1 - t0) if t1 > t0 else 1.0)
        return history[0][1]

    def close(self):
        """Stop moving the robot and publishing. Idempotent."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2)
        if self.started is not None:
            elapsed = time.monotonic() - self.started
            log.info("simulated world: %d updates in %.1f s (%.1f Hz, target %.0f Hz), longest gap %.0f ms, "
                     "%.1f simulated s", self.steps, elapsed, self.steps / max(elapsed, 1e-9), self.config.rate,
                     self.longest_step * 1e3, self.clock.now())
        if self._pubs is not None:
            for sub in self._subs:
                sub.unregister()
            for name in ("scan", "amcl"):
                if name in self._pubs:
                    self._pubs[name].unregister()
            self._pubs = None


def scan_message(laser, ranges, frame, rate):
    """A sensor_msgs/LaserScan of ``ranges`` as the laser casts them."""
    msg = LaserScan()
    msg.header.stamp = rospy.Time.now()
    msg.header.frame_id = frame
    msg.angle_min = laser.angle_min
    msg.angle_increment = laser.angle_increment
    msg.angle_max = laser.angle_min + laser.angle_increment * (laser.beams - 1)
    msg.scan_time = 1.0 / rate
    msg.range_min, msg.range_max = laser.range_min, laser.range_max
    msg.ranges = ranges
    return msg


def laser_mount_message(base_link, laser_frame):
    """The static tf base_link -> laser of the simulated robot's lidar (``LASER_MOUNT``)."""
    x, y, z, yaw = LASER_MOUNT
    msg = transform_message(Pose2D(x, y, yaw), rospy.Time.now(), base_link, laser_frame)
    msg.transform.translation.z = z
    return msg


def amcl_pose_message(pose, stamp, frame):
    """/amcl_pose: the localized pose with AMCL's typical small covariance."""
    msg = PoseWithCovarianceStamped()
    msg.header.stamp, msg.header.frame_id = stamp, frame
    write_pose(msg.pose.pose, pose)
    msg.pose.covariance = AMCL_COVARIANCE
    return msg
