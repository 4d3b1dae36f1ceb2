"""Skid-steer kinematics, motor duty mapping and ramping. Pure.

Imports neither rospy nor RPi.GPIO, so the maths is tested on its own
(tests/test_drive_kinematics.py) and shared by the base controller, the
backends and the simulation. Integrating a pose along an arc is planar maths
and lives in :mod:`flask_move_server.core.geometry` (``along_arc``).

Conventions (REP-103): linear velocity ``v`` in m/s along x of ``base_link``,
angular velocity ``w`` in rad/s counter-clockwise; wheel (side) speeds in m/s,
positive forward; duties are signed fractions of full PWM, -1..1.
"""

import math
from dataclasses import dataclass

from flask_move_server.core.geometry import clamp


@dataclass(frozen=True)
class SkidSteer:
    """A skid-steer (or differential) base: one speed per side.

    A skid-steer base turns less than its geometric track width predicts,
    because the wheels slip sideways; ``track_multiplier`` (as
    diff_drive_controller's ``wheel_separation_multiplier``) scales the track
    to the effective one found by calibration (spin 360 degrees).
    """

    track_width: float
    track_multiplier: float = 1.0

    @property
    def effective_track(self):
        return self.track_width * self.track_multiplier

    def wheel_speeds(self, linear, angular):
        """(left, right) side speeds in m/s for a body velocity."""
        half = angular * self.effective_track / 2.0
        return linear - half, linear + half

    def body_velocity(self, left, right):
        """(linear, angular) body velocity for side speeds in m/s."""
        return (left + right) / 2.0, (right - left) / self.effective_track


@dataclass(frozen=True)
class DutyMap:
    """Side speed ↔ signed PWM duty for an open-loop DC motor.

    A DC motor does not start below ``min_duty`` (friction, the L298N's
    voltage drop), so any non-zero speed maps into ``[min_duty, max_duty]``
    linearly, ``max_wheel_speed`` being the ground speed at ``max_duty``.
    Exactly zero speed maps to zero duty. Speeds beyond the maximum saturate.
    With ``min_duty = 0`` this is the plain linear map closed-loop
    controllers (the serial backend's firmware PID) want.
    """

    max_wheel_speed: float
    min_duty: float = 0.0
    max_duty: float = 1.0

    def duty(self, speed):
        """Signed duty (-max_duty..max_duty) that drives a side at ``speed`` m/s."""
        if speed == 0 or not math.isfinite(speed):
            return 0.0
        fraction = min(abs(speed) / self.max_wheel_speed, 1.0)
        return math.copysign(self.min_duty + (self.max_duty - self.min_duty) * fraction, speed)

    def speed(self, duty):
        """Ground speed in m/s that a signed ``duty`` produces; 0 inside the deadband."""
        magnitude = min(abs(duty), self.max_duty)
        if magnitude < self.min_duty or magnitude == 0 or self.max_duty <= self.min_duty:
            return 0.0
        fraction = (magnitude - self.min_duty) / (self.max_duty - self.min_duty)
        return math.copysign(fraction * self.max_wheel_speed, duty)


def desaturate(left, right, max_speed):
    """Scale both sides down together so neither exceeds ``max_speed``.

    Keeps the ratio of the sides, so the robot follows the commanded arc, only
    slower, instead of turning a different curve when one side saturates.
    """
    biggest = max(abs(left), abs(right))
    if biggest <= max_speed or biggest == 0:
        return left, right
    scale = max_speed / biggest
    return left * scale, right * scale


@dataclass(frozen=True)
class Limits:
    """Velocity and acceleration limits of the base (acceleration 0: unlimited)."""

    max_linear: float
    max_angular: float
    max_linear_accel: float = 0.0
    max_angular_accel: float = 0.0

    def clamp(self, linear, angular):
        """The velocity limited to the maximum speeds."""
        return clamp(linear, self.max_linear), clamp(angular, self.max_angular)

    def ramp(self, current, target, dt):
        """One step of ``dt`` seconds from ``current`` (v, w) towards ``target``.

        Ramping keeps the motors' inrush current from browning out the Pi.
        """
        v = _approach(current[0], target[0], self.max_linear_accel * dt if self.max_linear_accel else None)
        w = _approach(current[1], target[1], self.max_angular_accel * dt if self.max_angular_accel else None)
        return v, w


def _approach(current, target, max_step):
    if max_step is None:
        return target
    return current + clamp(target - current, max_step)

