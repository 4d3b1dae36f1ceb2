"""The last 40 cm onto the charger: where to stand before it, and how to drive onto it straight. Pure.

The dock is the pose the robot stands in on its charger, facing the contacts (marked ``from:
current`` while it charges). The **staging pose** lies ``staging_distance`` straight behind it,
facing it: move_base brings the robot there (within its goal tolerance, 12 cm and 0.2 rad with the
shipped DWA config). From there :class:`Approach` drives it on by itself, slowly, onto the dock's
line: it aims at a point on that line a little ahead (pure pursuit), so a robot left beside the
line by move_base's tolerance comes onto it before it touches; it turns on the spot first when
it faces too far off. Everything is in the map frame, as localization believes it: a wrong belief
drives onto the wrong line and misses, as a real robot would (the charger then says nothing).

:func:`offset` says where a pose stands from the dock: ``along`` (negative before it), ``beside``
(left positive) and ``yaw``; :func:`within` is the tolerance of a dock that cannot say it charges.
"""

import math
from dataclasses import dataclass

from flask_move_server.core.geometry import Pose2D, compose, inverse, normalize_angle

LOOKAHEAD = 0.1  # m ahead on the dock's line the approach aims at
STEER = 1.5  # rad/s of turn per rad of heading off that point
MAX_TURN = 0.4  # rad/s at most while approaching
TURN_FIRST = 0.35  # rad: facing farther off the aim point than this, turn on the spot first
ARRIVED = 0.01  # m before the dock: the approach is over
STRAIGHT = 0.03  # m before the dock: no more steering (the aim point is the dock itself), half the speed
TOLERANCE = (0.05, 0.05, 0.1)  # m along, m beside, rad: standing on the dock, as far as localization can say


@dataclass(frozen=True)
class Offset:
    """Where a pose stands from the dock, in the dock's frame."""

    along: float  # m, negative before the dock (the staging pose: -staging_distance)
    beside: float  # m, left of the dock's line positive
    yaw: float  # rad the pose faces off the dock's heading


def staging_pose(dock, distance):
    """The pose ``distance`` m straight behind ``dock`` (a Pose2D), facing it."""
    return compose(dock, Pose2D(-distance, 0.0, 0.0))


def offset(dock, pose):
    """Where ``pose`` stands from ``dock``."""
    relative = compose(inverse(dock), pose)
    return Offset(relative.x, relative.y, normalize_angle(relative.yaw))


def within(dock, pose, tolerance=TOLERANCE):
    """True when ``pose`` stands on ``dock`` within ``tolerance`` (along, beside, yaw)."""
    off = offset(dock, pose)
    return abs(off.along) <= tolerance[0] and abs(off.beside) <= tolerance[1] and abs(off.yaw) <= tolerance[2]


class Approach:
    """Onto ``dock`` at ``speed`` m/s: :meth:`step` gives the velocity for the pose localization believes."""

    def __init__(self, dock, speed):
        self.dock, self.speed = dock, speed

    def remaining(self, pose):
        """Metres still to go along the dock's line (negative: past it)."""
        return -offset(self.dock, pose).along

    def step(self, pose):
        """``(linear, angular)`` m/s, rad/s to command at ``pose``, or None once on the dock."""
        off = offset(self.dock, pose)
        to_go = -off.along
        if to_go <= ARRIVED:
            return None
        if to_go <= STRAIGHT:
            return self.speed / 2.0, 0.0  # the last centimetres slower: it stops on the contacts, not past them
        aim = min(off.along + LOOKAHEAD, 0.0)  # on the dock's line, ahead, never past the dock
        bearing = math.atan2(-off.beside, aim - off.along)  # to the aim point, in the dock's frame
        turn = normalize_angle(bearing - off.yaw)
        angular = max(-MAX_TURN, min(MAX_TURN, STEER * turn))
        if abs(turn) > TURN_FIRST:
            return 0.0, angular
        return self.speed * math.cos(turn), angular
