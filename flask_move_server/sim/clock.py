"""The simulated world's clock: the time the world really advanced, which a loaded machine slows. Pure.

The world thread ticks at ``sim.rate`` (50 Hz) and moves the robot by the real time since its last
tick, times ``speed_factor``; a tick later than :data:`LATE_TICKS` periods moves it by that much
only, and the rest of the gap is lost, as Gazebo's real-time factor drops below 1 on a machine that
cannot keep up. :class:`SimClock` counts the simulated seconds the world advanced. The move_base
stand-in's timers (no progress, ``controller_patience``, settling, replanning) run on it, as the
real move_base's run on ROS time, which is the simulator's ``/clock`` under ``use_sim_time``: an
overloaded machine slows the robot and its watchdogs alike, and a goal takes longer instead of
being aborted for "no progress".

:meth:`SimClock.report` tells how the world kept up over the last stretch of real time: the tick
rate it achieved against the one asked for, and the share of real time the sim ran at.
"""

import threading
import time

LATE_TICKS = 2  # a tick later than this many periods moves the world by this many only


class SimClock:
    """Simulated seconds since the world started, and how well the world has kept real time."""

    def __init__(self, rate, speed_factor=1.0, clock=time.monotonic):
        self.rate = rate
        self.speed_factor = speed_factor
        self._clock = clock
        self._lock = threading.Lock()
        self._now = 0.0
        self._mark = (clock(), 0, 0.0)  # real time, ticks, simulated time at the start of the stretch
        self.ticks = 0

    def now(self):
        """Simulated seconds since the world started."""
        with self._lock:
            return self._now

    def tick(self, real_gap):
        """The world ticked ``real_gap`` real seconds after its last tick: the simulated seconds it advances."""
        step = min(real_gap, LATE_TICKS / self.rate) * self.speed_factor
        with self._lock:
            self._now += step
            self.ticks += 1
        return step

    def report(self):
        """(achieved tick rate in Hz, simulated / real time over speed_factor) since the last report; restarts."""
        real = self._clock()
        with self._lock:
            since, ticks, sim = self._mark
            self._mark = (real, self.ticks, self._now)
            elapsed = real - since
            if elapsed <= 0:
                return float(self.rate), 1.0
            return (self.ticks - ticks) / elapsed, (self._now - sim) / (elapsed * self.speed_factor)


def overload_text(achieved, wanted, share):
    """What a world that fell behind says: "the sim ran at 45 Hz instead of 50 (0.86 of real time)"."""
    return "the sim ran at {:.0f} Hz instead of {:.0f} ({:.2f} of real time): machine overloaded".format(
        achieved, wanted, share)
