"""Backend ``sim``: a simulated motor pair, used by ``--sim`` and the demo.

It keeps every applied command with its time, and tells the simulated world
how fast each side of the robot rolls for the duties applied (the same motor
model the base controller inverts: nothing below ``min_duty`` moves).
"""

import collections
import threading
import time

from flask_move_server.drive.backends import MotorBackend, register
from flask_move_server.drive.kinematics import DutyMap


@register("sim")
class SimBackend(MotorBackend):
    """Motors that exist only in the simulation."""

    def __init__(self, config, source="(config)", history=1000, clock=time.monotonic):
        self.motor = DutyMap(config.max_wheel_speed, config.min_duty, config.max_duty)
        self._clock = clock
        self._lock = threading.Lock()
        self._left = self._right = 0.0
        self._since = clock()
        self.history = collections.deque(maxlen=history)  # (monotonic time, left, right)
        self.closed = False

    def set(self, left, right):
        """Apply signed duties (-1..1); recorded with the time they were applied."""
        with self._lock:
            if self.closed:
                left = right = 0.0
            now = self._clock()
            self._left, self._right, self._since = float(left), float(right), now
            self.history.append((now, self._left, self._right))

    def applied(self):
        """(left, right, monotonic time applied) of the command in force."""
        with self._lock:
            return self._left, self._right, self._since

    def wheel_speeds(self):
        """(left, right) ground speeds in m/s that the applied duties produce.

        The simulated world (flask_move_server.sim) reads this to move the
        simulated robot: the inverse of the base controller's speed → duty
        mapping, 0 inside the ``min_duty`` deadband, capped at ``max_duty``.
        """
        with self._lock:
            return self.motor.speed(self._left), self.motor.speed(self._right)

    def close(self):
        """Stop the simulated motors. Idempotent."""
        self.set(0.0, 0.0)
        with self._lock:
            self.closed = True
