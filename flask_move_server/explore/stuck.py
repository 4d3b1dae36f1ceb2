"""A robot that cannot move is not a flat that is mapped: the explorer's check. Pure.

On the real stack a robot wedged on a door jamb had every goal aborted within seconds, without
moving ("Rotate recovery can't rotate in place because there is a potential collision", then
"Failed to find a valid plan"); the explorer gave up every frontier that way and said "The whole
reachable flat is mapped" (issue 33). From goals alone a frontier move_base cannot plan to and a
robot that cannot move look the same: neither moves. So after :data:`STUCK_AFTER` frontiers given
up in a row with the robot standing where each goal began, the explorer asks the robot to go back
to a place it has been (:class:`Trail`), a place it could reach: if it gets nowhere there either,
the robot is stuck, and the exploration ends ``stuck`` without saving; else those frontiers were
out of reach and exploring goes on.
"""

import math

MOVED = 0.2          # m: a robot that came no farther than this from where a goal began did not move for it
STUCK_AFTER = 2      # frontiers given up in a row without moving, before the robot's motion is checked
BACK_AT_LEAST = 0.5  # m: the place to go back to lies at least this far from where the robot stands


def moved(before, after):
    """True when the robot came at least MOVED from ``before`` to ``after`` (Pose2D)."""
    return math.hypot(after.x - before.x, after.y - before.y) >= MOVED


class Trail:
    """Places the robot has been during an exploration (map frame), the latest last."""

    def __init__(self, start):
        self.places = [start]

    def add(self, pose):
        if not _within(pose, self.places[-1], BACK_AT_LEAST):
            self.places.append(pose)
            del self.places[:-50]  # the latest are the nearest to go back to

    def back_to(self, here):
        """The latest place at least BACK_AT_LEAST from ``here``, or None (the robot never went anywhere)."""
        return next((p for p in reversed(self.places) if not _within(p, here, BACK_AT_LEAST)), None)


def stuck_message(here, given_up, left, said=None):
    """What the owner reads when exploring ends ``stuck`` at ``here`` (Pose2D): what to do first (a
    phone shows two lines of it), then what was seen: ``said``, what the robot said of it (it noticed
    it is stuck, and could not back out), or else ``given_up`` goals in a row that got it nowhere."""
    seen = ("It said: {}".format(said) if said else "Its last {} goals were given up where it stood, and a goal "
            "back to where it had been got nowhere either.".format(given_up))
    return ("Stuck near x {:.1f}, y {:.1f}: drive the robot free with the joystick (or move it by hand), then "
            "explore again to go on with this map, or save it (Maps, Save as). {} Nothing was saved; mapping "
            "goes on. {} place{} left to look at."
            .format(here.x, here.y, seen, left, " was" if left == 1 else "s were"))


def _within(a, b, radius):
    return math.hypot(a.x - b.x, a.y - b.y) < radius
