"""The simulated robot's true motion: wheel speeds in, pose in the map frame out, walls in the way.

A round skid-steer robot: its ground speeds ``left`` and ``right`` (m/s) give
``v = (left + right) / 2`` and ``w = (right - left) / track``, integrated
along the exact arc. Long steps are cut into pieces shorter than half a cell,
so the robot cannot tunnel through a thin wall; a piece that would put the
body (a disk of the sim's ``robot_radius``, exactly: ``Costmap.touches``) into
an obstacle is not taken (the robot turns but does not move, as a
bumper-stopped base would). Pure: no rospy.
"""

import math
import threading

from flask_move_server.core.geometry import Pose2D, along_arc


class RobotBody:
    """Where the simulated robot really is, and whether it is pressed against something."""

    def __init__(self, costmap, track, pose=None):
        self.costmap = costmap
        self.track = track
        self._pose = pose or Pose2D(0.0, 0.0, 0.0)
        self._lock = threading.Lock()
        self.bumped = False

    @property
    def pose(self):
        with self._lock:
            return self._pose

    def step(self, left, right, dt):
        """Move for ``dt`` seconds at wheel ground speeds ``left``, ``right``; returns the new pose."""
        v = (left + right) / 2.0
        w = (right - left) / self.track
        pieces = max(1, int(math.ceil(abs(v * dt) / (self.costmap.resolution / 2.0))))
        h = dt / pieces
        with self._lock:
            pose = self._pose
            bumped = False
            for _ in range(pieces):
                moved = along_arc(pose, v * h, w * h)
                if self.costmap.touches(moved.x, moved.y):
                    bumped = True
                    moved = Pose2D(pose.x, pose.y, moved.yaw)
                pose = moved
            self._pose, self.bumped = pose, bumped
            return pose

