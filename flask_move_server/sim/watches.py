"""When the move_base stand-in replans or gives up on a goal: two small watches. Pure.

Both count the time they are given (``now``): the stand-in gives them the simulated world's
(``sim/clock.py``), so a machine too loaded to keep real time slows them with the robot.

:class:`ReplanWatch` asks a growing map's planner, now and then, whether the map grew an
obstacle across the path still to drive (move_base replans on its growing costmap);
:class:`ProgressWatch` tells when the robot has stopped making progress (move_base aborts).
"""

from flask_move_server.core.geometry import normalize_angle


class ReplanWatch:
    """Asks a growing map's planner, every ``period`` s and only when the map changed, whether the path is blocked."""

    def __init__(self, planner, period, now):
        self.planner = planner
        self.period = period
        self._blocked = getattr(planner, "path_blocked", None)
        self._version = self._map_version()
        self._next_check = now + period

    def _map_version(self):
        slam = getattr(self.planner, "slam", None)
        return None if slam is None else slam.version

    def due(self, remaining, now):
        """True when the map grew an obstacle across ``remaining`` (the points still to drive)."""
        if self._blocked is None or now < self._next_check:
            return False
        self._next_check = now + self.period
        version = self._map_version()
        if version == self._version:
            return False
        self._version = version
        return self._blocked(remaining)


class ProgressWatch:
    """Tells when the robot has not moved (1 cm or 3 degrees) for ``timeout`` seconds."""

    def __init__(self, timeout):
        self.timeout = timeout
        self._anchor = None
        self._since = None

    def stalled(self, pose, now):
        if self._anchor is None or (
            pose.distance_to(self._anchor) > 0.01 or abs(normalize_angle(pose.yaw - self._anchor.yaw)) > 0.05
        ):
            self._anchor, self._since = pose, now
            return False
        return now - self._since > self.timeout
