"""A small world for the stuck tests on real ROS topics: a base whose wheels may turn without moving it.

It hears ``cmd_vel`` (teleop's, the back-out's) and publishes what a base with the L298N drive would:
``odom`` counting the commands (open loop), ``scan`` cast by the sim's laser on the demo flat from
where the robot really is (in base_link: the laser at its origin), and tf map → base_link where it
really is (a localization that does not slide). ``pushing`` stands for move_base
driving it forward (the stand-ins here send no velocity); ``blocked(linear)`` says whether the world
lets a motion at ``linear`` m/s through: a wedged robot's forward motion is not.
"""

import math
import os
import threading
import time

import rospy
import tf2_ros
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from flask_move_server.core.geometry import Pose2D, along_arc
from flask_move_server.maps import mapfile
from flask_move_server.ros.convert import transform_message, write_pose
from flask_move_server.sim.laser import Laser
from tests.conftest import ROOT

GRID = mapfile.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
RATE = 20.0  # odometry per second
SCAN_EVERY = 3  # an odometry tick in this many casts a scan (6.7 Hz)
DEADMAN = 0.5  # s a cmd_vel holds


class WedgedBase:
    """The robot at ``truth`` (Pose2D) on the demo flat, its ``odom``/``scan``/``cmd_vel`` under ``name``."""

    def __init__(self, name, truth, frame, map_frame, blocked=lambda linear: linear > 0):
        self.truth, self.odometry = truth, Pose2D(0.0, 0.0, truth.yaw)
        self.frame, self.map_frame, self.blocked = frame, map_frame, blocked
        self._tf = tf2_ros.TransformBroadcaster()
        self.pushing = 0.0  # m/s forward "move_base" commands while a goal is under way
        self.commands = []  # every cmd_vel heard: (linear, angular)
        self._command, self._command_at = (0.0, 0.0), 0.0
        self._laser = Laser(GRID)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._odom = rospy.Publisher(name + "/odom", Odometry, queue_size=5)
        self._scan = rospy.Publisher(name + "/scan", LaserScan, queue_size=1)
        self._sub = rospy.Subscriber(name + "/cmd_vel", Twist, self._on_cmd_vel, queue_size=10)
        self._thread = threading.Thread(target=self._run, name="wedged-base", daemon=True)
        self._thread.start()

    def _on_cmd_vel(self, msg):
        with self._lock:
            self.commands.append((msg.linear.x, msg.angular.z))
            self._command, self._command_at = (msg.linear.x, msg.angular.z), time.monotonic()

    def backed_out(self):
        """The negative linear commands heard (the back-out's)."""
        with self._lock:
            return [c for c in self.commands if c[0] < 0]

    def _velocity(self):
        with self._lock:
            if time.monotonic() - self._command_at <= DEADMAN and self._command != (0.0, 0.0):
                return self._command
        return (self.pushing, 0.0)

    def _run(self):
        period, tick = 1.0 / RATE, 0
        while not self._stop.wait(period):
            linear, angular = self._velocity()
            with self._lock:
                self.odometry = along_arc(self.odometry, linear * period, angular * period)
                if not self.blocked(linear):
                    self.truth = along_arc(self.truth, linear * period, angular * period)
                odometry, truth = self.odometry, self.truth
            stamp = rospy.Time.now()
            self._odom.publish(_odometry(odometry, linear, angular, stamp))
            self._tf.sendTransform(transform_message(truth, stamp, self.map_frame, self.frame))
            tick += 1
            if tick % SCAN_EVERY == 0:
                self._scan.publish(self._scan_of(truth, stamp))

    def _scan_of(self, truth, stamp):
        laser, msg = self._laser, LaserScan()
        msg.header.stamp, msg.header.frame_id = stamp, self.frame
        msg.angle_min, msg.angle_increment = laser.angle_min, laser.angle_increment
        msg.angle_max = laser.angle_min + laser.angle_increment * (laser.beams - 1)
        msg.range_min, msg.range_max = laser.range_min, laser.range_max
        msg.ranges = [r if math.isfinite(r) else float("inf") for r in laser.scan(truth)]
        return msg

    def close(self):
        self._stop.set()
        self._thread.join(2.0)
        for topic in (self._odom, self._scan, self._sub):
            topic.unregister()


def _odometry(pose, linear, angular, stamp):
    msg = Odometry()
    msg.header.stamp, msg.header.frame_id = stamp, "odom"
    write_pose(msg.pose.pose, pose)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = linear, angular
    return msg
