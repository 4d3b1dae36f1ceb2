"""Planar poses and goals, and every planar formula once (REP-103 units: m, rad). Pure.

The drive, the simulation, the recorder and the ROS adapters all work with
these; ROS messages are converted to and from :class:`Pose2D` in
``ros/convert.py``.
"""

import math
from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class Pose2D:
    """A position and heading in one frame."""

    x: float
    y: float
    yaw: float

    def distance_to(self, other):
        return math.hypot(other.x - self.x, other.y - self.y)

    def as_dict(self):
        return {"x": self.x, "y": self.y, "yaw": self.yaw}


@dataclass(frozen=True)
class Goal:
    """Where a ``/goto`` sends the robot; ``target`` is the waypoint name, if any."""

    pose: Pose2D
    target: Optional[str] = None


def yaw_to_quaternion(yaw):
    """(x, y, z, w) of a rotation by ``yaw`` about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x, y, z, w):
    """The rotation about z of a quaternion, in (-pi, pi]."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def normalize_angle(angle):
    """``angle`` wrapped to (-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def clamp(value, limit):
    """``value`` limited to ``[-limit, limit]``: a speed held within what the base may do."""
    return max(-limit, min(limit, value))


def along_arc(pose, distance, turn):
    """``pose`` after travelling ``distance`` metres while turning ``turn`` radians at constant rates.

    What a differential base does in one step at constant (v, w): exact along
    the arc; when the turn is near zero, the heading at the midpoint (second
    order Runge-Kutta), which is exact for straight lines and avoids dividing
    by a tiny turn (as diff_drive_controller does). The yaw is normalized.
    """
    if abs(turn) < 1e-6:
        mid = pose.yaw + turn / 2.0
        x, y = pose.x + distance * math.cos(mid), pose.y + distance * math.sin(mid)
    else:
        radius = distance / turn
        x = pose.x + radius * (math.sin(pose.yaw + turn) - math.sin(pose.yaw))
        y = pose.y - radius * (math.cos(pose.yaw + turn) - math.cos(pose.yaw))
    return Pose2D(x, y, normalize_angle(pose.yaw + turn))


def compose(a, b):
    """The pose ``b`` (given in ``a``'s frame) in ``a``'s parent frame: a ∘ b.

    As tf chains transforms: map → odom composed with odom → base_link is
    map → base_link.
    """
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return Pose2D(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, normalize_angle(a.yaw + b.yaw))


def inverse(a):
    """The inverse transform of pose ``a``: a ∘ inverse(a) is the identity."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return Pose2D(-c * a.x - s * a.y, s * a.x - c * a.y, normalize_angle(-a.yaw))


def interpolate(a, b, t):
    """The pose a fraction ``t`` (0..1) of the way from ``a`` to ``b``, turning the shorter way."""
    dyaw = normalize_angle(b.yaw - a.yaw)
    return Pose2D(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, normalize_angle(a.yaw + dyaw * t))
