"""Did the robot move as its odometry says? The laser's answer. Pure.

The L298N drive has no encoders: its odometry counts the commands, so a robot pressed against a
door jamb goes on "driving" in ``/odom`` while it stands still, and its localized pose slides into
the wall (issue 33). The laser does not slide. Two scans taken while the odometry says the robot
moved by ``motion`` are compared under two hypotheses: *still*, the later scan's end points lie
where the earlier scan's did; *moved*, they lie where the earlier scan's would after ``motion``.
The share of end points within :data:`TOLERANCE` of the earlier scan's tells which is true. Where
neither clearly wins (a long corridor, whose side walls look the same either way, with its ends
out of range), nothing is said: a false "stuck" would stop a robot that drives well.
"""

import math

TOLERANCE = 0.05  # m: an end point this near one of the earlier scan's counts as the same
MIN_POINTS = 30  # fewer end points than this in either scan tell nothing
MIN_TRAVEL = 0.1  # m of odometry between the scans before they are compared
MIN_TURN = 0.25  # rad of odometry turn between the scans before they are compared
STILL_SHARE = 0.75  # "still" needs at least this share of end points where they were...
CLEAR_WIN = 0.2  # ...and this much more than "moved" explains
STILL, MOVED = "still", "moved"


def end_points(ranges, angle_min, increment, range_min, range_max, mount, step=2):
    """The echoes of a scan as (x, y) in the robot's frame: every ``step``-th beam, NaN, inf and the
    out-of-range left out; ``mount`` (Pose2D) is where the laser sits on base_link."""
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    points = []
    for index in range(0, len(ranges), step):
        r = ranges[index]
        if not (range_min < r < range_max):  # NaN fails this too
            continue
        a = angle_min + index * increment
        lx, ly = r * math.cos(a), r * math.sin(a)
        points.append((mount.x + c * lx - s * ly, mount.y + s * lx + c * ly))
    return points


def travelled(motion):
    """True when ``motion`` (Pose2D) is enough to compare two scans by."""
    return math.hypot(motion.x, motion.y) >= MIN_TRAVEL or abs(motion.yaw) >= MIN_TURN


def verdict(before, after, motion):
    """``STILL``, ``MOVED`` or None (cannot tell): ``after``'s end points against ``before``'s, when the
    odometry says the robot moved by ``motion`` (Pose2D, in the robot's frame at ``before``)."""
    if len(before) < MIN_POINTS or len(after) < MIN_POINTS or not travelled(motion):
        return None
    cells = _Cells(before)
    still = cells.share(after)
    moved = cells.share(_moved_by(after, motion))
    if still >= STILL_SHARE and still - moved >= CLEAR_WIN:
        return STILL
    if moved >= still:
        return MOVED
    return None


def _moved_by(points, motion):
    """``points`` seen from the robot after ``motion``, in the robot's frame before it."""
    c, s = math.cos(motion.yaw), math.sin(motion.yaw)
    return [(motion.x + c * x - s * y, motion.y + s * x + c * y) for x, y in points]


class _Cells:
    """The end points of one scan hashed into cells of TOLERANCE: is a point near one of them?"""

    def __init__(self, points):
        self._points = {}
        for x, y in points:
            self._points.setdefault(self._key(x, y), []).append((x, y))

    @staticmethod
    def _key(x, y):
        return int(math.floor(x / TOLERANCE)), int(math.floor(y / TOLERANCE))

    def near(self, x, y):
        kx, ky = self._key(x, y)
        limit = TOLERANCE * TOLERANCE
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for px, py in self._points.get((kx + dx, ky + dy), ()):
                    if (px - x) ** 2 + (py - y) ** 2 <= limit:
                        return True
        return False

    def share(self, points):
        return sum(1 for x, y in points if self.near(x, y)) / float(len(points))

