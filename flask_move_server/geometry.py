"""Planar poses and goals in the map frame (REP-103 units: m, rad). Pure."""

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
