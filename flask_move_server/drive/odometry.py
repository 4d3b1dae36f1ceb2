"""Dead reckoning of the base in the ``odom`` frame, with honest uncertainty. Pure.

Two sources: wheel encoders (closed loop: measured tick counts) or, without
encoders, the applied wheel speeds (open loop: what the motors were told,
which a skid-steer on carpet only roughly does). The covariances say so: they
grow with the distance and angle travelled, several times faster open loop,
so AMCL and robot_localization weigh this odometry for what it is.
"""

import math

from flask_move_server.core.geometry import Pose2D, along_arc

ENCODERS, OPEN_LOOP = "encoders", "open_loop"

# Error per metre driven / per radian turned (1 sigma), per source.
_DRIFT = {ENCODERS: (0.05, 0.1), OPEN_LOOP: (0.3, 0.5)}
# Velocity variances (vx, wz) per source.
_TWIST_VARIANCE = {ENCODERS: (0.0025, 0.01), OPEN_LOOP: (0.04, 0.25)}
# Variance of what a planar base cannot observe (z, roll, pitch; vy, vz, ...).
UNOBSERVED = 1e6


class Odometry:
    """Pose and velocity of ``base_link`` in ``odom``, integrated step by step."""

    def __init__(self, source=OPEN_LOOP):
        self.source = source
        self.pose = Pose2D(0.0, 0.0, 0.0)
        self.linear = self.angular = 0.0
        self.distance = 0.0  # metres travelled (path length), for the covariance
        self.rotation = 0.0  # radians turned (absolute), for the covariance

    def advance(self, linear, angular, dt):
        """Move at (linear, angular) for ``dt`` seconds (open loop)."""
        if dt <= 0:
            return
        self.pose = along_arc(self.pose, linear * dt, angular * dt)
        self.linear, self.angular = linear, angular
        self.distance += abs(linear) * dt
        self.rotation += abs(angular) * dt

    def advance_wheels(self, left_distance, right_distance, track, dt):
        """Move by the distances each side rolled (encoders) over ``dt`` seconds."""
        linear_distance = (left_distance + right_distance) / 2.0
        turn = (right_distance - left_distance) / track
        self.pose = along_arc(self.pose, linear_distance, turn)
        if dt > 0:
            self.linear, self.angular = linear_distance / dt, turn / dt
        self.distance += abs(linear_distance)
        self.rotation += abs(turn)

    @property
    def x(self):
        return self.pose.x

    @property
    def y(self):
        return self.pose.y

    @property
    def yaw(self):
        return self.pose.yaw

    def pose_covariance(self):
        """Row-major 6x6 covariance of (x, y, z, roll, pitch, yaw)."""
        per_metre, per_radian = _DRIFT[self.source]
        xy = 1e-4 + (per_metre * self.distance) ** 2
        yaw = 1e-4 + (per_radian * self.rotation) ** 2 + (per_metre * self.distance / 2.0) ** 2
        return _diagonal((xy, xy, UNOBSERVED, UNOBSERVED, UNOBSERVED, yaw))

    def twist_covariance(self):
        """Row-major 6x6 covariance of (vx, vy, vz, wx, wy, wz)."""
        vx, wz = _TWIST_VARIANCE[self.source]
        # A skid-steer does not slide sideways on its own: vy is known to be ~0.
        return _diagonal((vx, 1e-3, UNOBSERVED, UNOBSERVED, UNOBSERVED, wz))

    def as_dict(self):
        """The ``odom`` part of ``/status``."""
        return {
            "x": round(self.x, 4),
            "y": round(self.y, 4),
            "yaw": round(self.yaw, 4),
            "linear": round(self.linear, 4),
            "angular": round(self.angular, 4),
            "source": self.source,
        }


def _diagonal(values):
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[i * 7] = float(value)
    return matrix


def ticks_per_metre(ticks_per_rev, wheel_radius):
    """Encoder ticks per metre of ground travelled."""
    return ticks_per_rev / (2.0 * math.pi * wheel_radius)
