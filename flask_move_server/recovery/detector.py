"""The signs of a stuck robot, each from what the robot can observe. Pure.

- *Blocked* (:class:`MotionWatch`): the odometry says the robot moves, the laser says it stands
  still (``scan_motion.py``), :data:`BLOCKED_AFTER` comparisons in a row. The wedged robot of
  issue 33, and any robot whose wheels spin or stall against something.
- *Cornered* (:class:`QuickAborts`): goals ending aborted soon after they were sent, without the
  robot moving, :data:`QUICK_ABORTS` in a row. On its own that may be goals nobody could reach, so
  it counts only when the footprint touches something too (``footprint.py``: the laser, or the
  map at the localized pose, where move_base can neither plan nor turn); ``recovery.py`` asks.
"""

import math

from flask_move_server.core.geometry import Pose2D, compose, inverse
from flask_move_server.recovery.scan_motion import MOVED, STILL, travelled, verdict

BLOCKED_AFTER = 2  # comparisons in a row saying "still" while the odometry moved
QUICK_ABORTS = 2  # quick aborts in a row without moving
SLIP_FORGOTTEN = 10  # comparisons in a row seeing the robot move, after which a slip is taken as made good
MOVED_AT_LEAST = 0.1  # m: a goal during which the robot came no farther did not move it
IDENTITY = Pose2D(0.0, 0.0, 0.0)
STANDING = (0.005, 0.01)  # m, rad of odometry: the robot stands; the newest scan is the best to compare with


class MotionWatch:
    """Scans and the odometry at each: says when the robot is blocked (the laser sees no motion)."""

    def __init__(self, after=BLOCKED_AFTER):
        self.after = after
        self._reference = None  # (end points, odometry Pose2D)
        self._still = 0
        self.last = None  # the last comparison's verdict (STILL, MOVED or None)
        self.slip = IDENTITY  # the odometry the laser did not see, until put back or driven off
        self._moved = 0  # comparisons in a row that saw the robot move

    def reset(self):
        """Forget what was seen (a new goal, a back-out begins): the next scan is the new reference.
        The slip is kept: the localization still carries it."""
        self._reference, self._still, self.last = None, 0, None

    def forget_slip(self):
        """The localization was put back (recovery.py): no slip is owed any more."""
        self.slip = IDENTITY

    def scan(self, points, odometry):
        """One scan's end points (robot frame) with the odometry pose at it: True once the robot is blocked."""
        if self._reference is None:
            self._reference = (points, odometry)
            return False
        before, at = self._reference
        motion = compose(inverse(at), odometry)
        if not travelled(motion):
            if math.hypot(motion.x, motion.y) < STANDING[0] and abs(motion.yaw) < STANDING[1]:
                self._reference = (points, odometry)
            return False
        self.last = verdict(before, points, motion)
        self._reference = (points, odometry)
        if self.last == STILL:
            self._still += 1
            self.slip = compose(self.slip, motion)
        elif self.last == MOVED:
            self._still = 0
            self._moved += 1
            if self._moved >= SLIP_FORGOTTEN:  # a metre or so driven well: AMCL's laser has caught up by now
                self.slip = IDENTITY
        if self.last == STILL:
            self._moved = 0
        return self._still >= self.after

    @property
    def moving(self):
        """True when the last comparison saw the robot move."""
        return self.last == MOVED


class QuickAborts:
    """Goals that end aborted within ``quick`` s of being sent, the robot moving less than MOVED_AT_LEAST."""

    def __init__(self, quick, after=QUICK_ABORTS):
        self.quick, self.after = quick, after
        self.in_a_row = 0

    def ended(self, state, seconds, moved):
        """A goal ended in ``state`` after ``seconds``, the robot ``moved`` m (None: not known, which counts
        for nothing): True when that makes enough in a row."""
        if state == "aborted" and None not in (seconds, moved) and seconds <= self.quick and moved < MOVED_AT_LEAST:
            self.in_a_row += 1
        elif state != "canceled":  # a goal the owner canceled says nothing either way
            self.in_a_row = 0
        return self.in_a_row >= self.after

    def reset(self):
        self.in_a_row = 0


def travel(start, end):
    """Metres between two Pose2D; None when either is unknown."""
    if start is None or end is None:
        return None
    return math.hypot(end.x - start.x, end.y - start.y)

