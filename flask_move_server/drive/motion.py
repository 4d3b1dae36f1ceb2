"""From a commanded body velocity to the two motor commands, step by step. Pure.

:class:`Motion` is the base controller's arithmetic without threads or ROS:
clamp the command to the limits, ramp towards it at the acceleration limits,
split it into side speeds, keep the ratio when a side saturates, and map each
side to a motor command. It also says what the motors really do with that
command (nothing inside the deadband), which open-loop odometry integrates.
"""

import math

from flask_move_server.drive.kinematics import DutyMap, Limits, SkidSteer, desaturate


class Motion:
    """Target and ramped velocity of the base, and the motor commands they give."""

    def __init__(self, kinematics, motor, limits):
        self.kinematics = kinematics
        self.motor = motor
        self.limits = limits
        self.target = (0.0, 0.0)
        self.velocity = (0.0, 0.0)
        self.commands = (0.0, 0.0)

    @classmethod
    def from_config(cls, config, closed_loop=False):
        """Built from a DriveConfig; closed-loop motors get a linear map without deadband."""
        kinematics = SkidSteer(config.track_width, config.track_multiplier)
        if closed_loop:
            motor = DutyMap(config.max_wheel_speed, 0.0, 1.0)
        else:
            motor = DutyMap(config.max_wheel_speed, config.min_duty, config.max_duty)
        limits = Limits(config.max_linear, config.max_angular, config.max_linear_accel, config.max_angular_accel)
        return cls(kinematics, motor, limits)

    def command(self, linear, angular):
        """Set a new target; False (nothing changed) unless both are finite numbers."""
        if not (math.isfinite(linear) and math.isfinite(angular)):
            return False
        self.target = self.limits.clamp(linear, angular)
        return True

    @property
    def settled(self):
        """True when the ramp has reached the target."""
        return self.velocity == self.target

    def step(self, dt):
        """Ramp ``dt`` seconds towards the target; the (left, right) motor commands."""
        self.velocity = self.limits.ramp(self.velocity, self.target, dt)
        left, right = self.kinematics.wheel_speeds(*self.velocity)
        left, right = desaturate(left, right, self.motor.max_wheel_speed)
        self.commands = (self.motor.duty(left), self.motor.duty(right))
        return self.commands

    def halt(self):
        """Stop at once, without ramping (watchdog, ``/stop``)."""
        self.target = self.velocity = (0.0, 0.0)
        self.commands = (0.0, 0.0)

    def actual_velocity(self):
        """The (linear, angular) velocity the applied commands produce (open-loop model)."""
        left, right = (self.motor.speed(c) for c in self.commands)
        return self.kinematics.body_velocity(left, right)
